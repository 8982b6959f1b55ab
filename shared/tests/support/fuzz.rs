//! The fuzzers' deterministic generator and run length.
//!
//! A run is `VIBRO_FUZZ_ITERS` cases (each test's default when unset), case `i`
//! generated from the seed `VIBRO_FUZZ_SEED + i` (default seed [`DEFAULT_SEED`]), so
//! a failing case, which the test names with its seed, replays alone with
//! `VIBRO_FUZZ_SEED=<seed> VIBRO_FUZZ_ITERS=1`.

/// The seed of case 0 when `VIBRO_FUZZ_SEED` is unset.
pub const DEFAULT_SEED: u64 = 0x5eed_f0e2;

/// SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number
/// generators", OOPSLA 2014): a 64-bit counter stepped by the golden ratio and
/// mixed, so that consecutive seeds give unrelated streams.
pub struct Rng(u64);

impl Rng {
    /// The generator of seed `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (0 when `n` is 0); the bias of the modulo is below
    /// `n / 2^64`.
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next_u64() % n as u64) as usize
        }
    }

    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi.saturating_sub(lo) + 1)
    }

    /// True with probability `1 / n`.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }

    /// A random byte.
    pub fn byte(&mut self) -> u8 {
        self.next_u64() as u8
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }
}

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
