use shared::impact::*;
fn main() {
    let body = PlanarBody {
        mass: 2.0,
        inertia: 7.3e-3,
        position: [0.0, 0.03],
        velocity: [0.4, -1.0],
        angular_velocity: 0.5,
    };
    let feet = [
        (-0.1, 0.3, 0.5),
        (-0.03, 0.4, 0.4),
        (0.03, 0.5, 0.3),
        (0.1, 0.6, 0.5),
    ];
    let contacts = feet.map(|(x, r, mu)| BodyContact {
        point: [x, 0.0],
        normal: [0.0, 1.0],
        law: ContactLaw {
            restitution: r,
            friction: mu,
            weight: 1.0,
        },
    });
    let p: ImpactProblem<f64, 8> = body_problem(&body, None, &contacts, ImpactLaw::Poisson);
    let mut s = 0.0;
    for _ in 0..2000 {
        s += solve(std::hint::black_box(&p)).unwrap().energy_change;
    }
    println!("{s}");
}
