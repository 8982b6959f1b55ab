//! The fuzzers' run length and seeds, on the tests' generator ([`Rng`]).
//!
//! A run is `VIBRO_FUZZ_ITERS` cases (each test's default when unset), case `i`
//! generated from the seed `VIBRO_FUZZ_SEED + i` (default seed [`DEFAULT_SEED`]), so
//! a failing case, which the test names with its seed, replays alone with
//! `VIBRO_FUZZ_SEED=<seed> VIBRO_FUZZ_ITERS=1`.

/// The seed of case 0 when `VIBRO_FUZZ_SEED` is unset.
pub const DEFAULT_SEED: u64 = 0x5eed_f0e2;

pub use super::rng::Rng;

/// The value of environment variable `name`, if set and a number.
fn env_u64(name: &str) -> Option<u64> {
    std::env::var(name).ok()?.trim().parse().ok()
}

/// The cases of a run: `VIBRO_FUZZ_ITERS`, else `default`.
pub fn iterations(default: u64) -> u64 {
    env_u64("VIBRO_FUZZ_ITERS").unwrap_or(default)
}

/// The seed of case 0: `VIBRO_FUZZ_SEED`, else [`DEFAULT_SEED`].
pub fn first_seed() -> u64 {
    env_u64("VIBRO_FUZZ_SEED").unwrap_or(DEFAULT_SEED)
}

/// Run `case` on the generator of every case's seed in turn; a panicking case is
/// named with its seed.
pub fn run(default_iterations: u64, mut case: impl FnMut(&mut Rng)) {
    let first = first_seed();
    for i in 0..iterations(default_iterations) {
        let seed = first.wrapping_add(i);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            case(&mut Rng::new(seed));
        }));
        if let Err(panic) = outcome {
            eprintln!("fuzz case failed: replay with VIBRO_FUZZ_SEED={seed} VIBRO_FUZZ_ITERS=1");
            std::panic::resume_unwind(panic);
        }
    }
}

/// A random valid tuning table: 1 to 32 rows, speeds rising by 1 to 300 rpm from
/// up to 300 rpm, offsets in `[0, 360)` degrees.
pub fn table(rng: &mut Rng) -> shared::controller::TuningTable {
    let mut speed = 0.0;
    let rows: Vec<(f32, f32, f32)> = (0..rng.range(1, 32))
        .map(|_| {
            speed += rng.uniform(1.0, 300.0);
            (speed, rng.uniform(0.0, 360.0), rng.uniform(0.0, 360.0))
        })
        .collect();
    shared::controller::TuningTable::from_rows(&rows).expect("rows make a table")
}
