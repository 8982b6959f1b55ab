//! Instruction count of the benchmark impact, for callgrind (repeatable whatever
//! the machine's load, unlike wall time):
//!
//! ```text
//! cargo build --release -p shared --example impact_instructions
//! valgrind --tool=callgrind target/release/examples/impact_instructions 2000
//! ```
//!
//! Solves the 4-contact frictional landing of `benches/impact.rs` N times (argument,
//! default 2000); divide callgrind's total by N.
use shared::impact::{body_problem, solve, BodyContact, ContactLaw, ImpactLaw, PlanarBody};

fn main() {
    let runs: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2000);
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
    let problem = body_problem::<f64, 8>(&body, None, &contacts, ImpactLaw::Poisson);
    let mut energy = 0.0;
    for _ in 0..runs {
        energy += solve(std::hint::black_box(&problem)).map_or(0.0, |o| o.energy_change);
    }
    println!(
        "{runs} impacts, energy change {:.6} J each",
        energy / f64::from(runs)
    );
}
