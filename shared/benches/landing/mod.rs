//! The benchmark impact, shared by the benchmark and the instruction-count example:
//! a free platform landing with spin and sideways speed on four frictional feet.
use shared::impact::{body_problem, BodyContact, ContactLaw, ImpactLaw, ImpactProblem, PlanarBody};
use shared::Real;

/// The landing as an impact problem in `T`, under Poisson's law.
pub fn problem<T: Real>() -> ImpactProblem<T, 8> {
    let f = T::from_f64;
    let body = PlanarBody {
        mass: f(2.0),
        inertia: f(7.3e-3),
        position: [f(0.0), f(0.03)],
        velocity: [f(0.4), f(-1.0)],
        angular_velocity: f(0.5),
    };
    let feet = [
        (-0.1, 0.3, 0.5),
        (-0.03, 0.4, 0.4),
        (0.03, 0.5, 0.3),
        (0.1, 0.6, 0.5),
    ];
    let contacts = feet.map(|(x, r, mu)| BodyContact {
        point: [f(x), f(0.0)],
        normal: [f(0.0), f(1.0)],
        law: ContactLaw {
            restitution: f(r),
            friction: f(mu),
            weight: f(1.0),
        },
    });
    body_problem(&body, None, &contacts, ImpactLaw::Poisson)
}
