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
use shared::impact::solve;

#[path = "../benches/landing/mod.rs"]
mod landing;

fn main() {
    let runs: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2000);
    let problem = landing::problem::<f64>();
    let mut energy = 0.0;
    for _ in 0..runs {
        energy += solve(std::hint::black_box(&problem)).map_or(0.0, |o| o.energy_change);
    }
    println!(
        "{runs} impacts, energy change {:.6} J each",
        energy / f64::from(runs)
    );
}
