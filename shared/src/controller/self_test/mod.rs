//! The first-run self-test: per rotor, motor and encoder polarity, the
//! index pulse, the counts per revolution and the index offset, as a pure state
//! machine ([`SelfTestRun`]) the controller steps in [`super::State::SelfTest`]. The
//! result is a [`SelfTest`] (`result`), which the device stores with the tuning
//! table and reports over the link.
//!
//! # Procedure
//!
//! Rotor 1, then rotor 2, one at a time; the rotor not under test gets duty 0 (its
//! winding shorted by the bridge: it is held back by its own back-EMF). Per rotor:
//!
//! 1. **Settle**: both rotors at rest, `|speed| <= REST_RPM` for [`REST_TIME_S`]
//!    (or [`SETTLE_TIMEOUT_S`] passed: the test goes on, it never waits for ever).
//!    The count of the tick that ends the settle is the start position `c0`: the
//!    rotor at rest, its eccentric hanging down (within the friction band).
//! 2. **Drive** with a constant gentle duty `d > 0` (below), open loop:
//!    - *direction*: once the counts have moved [`SelfTestConfig::direction_counts`]
//!      from `c0`, either way, the flags are decided (below). Counts running the
//!      wrong way (down under a positive duty) end the drive in that very tick
//!      (duty 0). No such motion within [`SelfTestConfig::move_timeout_s`]: the
//!      rotor did not turn, it fails (every flag false) and the test goes on;
//!    - *index*: the count latched at the first index pulse `c1` gives the index
//!      offset `(c1 - c0) mod n` (`n` the measured counts per revolution, the
//!      configured ones until it is measured); two consecutive pulses `c_a, c_b`
//!      with `c_b - c_a > 0` give `counts_per_rev = c_b - c_a`, which ends the
//!      drive. A pulse crossed back (`c_b - c_a <= 0`, the rotor rocking over the
//!      index) only restarts the pair. The counts latched at the index are those of
//!      the index position whichever way it is crossed, so the offset does not
//!      depend on how the rotor reached it;
//!    - *limits*: the drive ends after [`MAX_TURNS`] configured turns of travel
//!      without a second pulse (`index_seen` may then still be true, with
//!      `counts_per_rev = 0`), after [`DRIVE_TIMEOUT_S`], or when the counts fall
//!      back [`SelfTestConfig::direction_counts`] from their furthest point (the
//!      rotor reversed).
//! 3. The next rotor's settle lets this one coast to rest.
//!
//! After rotor 2's settle the test is done; on a one-rotor machine
//! ([`super::RotorCount::One`]) after rotor 1's: rotor 2 is neither driven nor
//! measured, and its result stays all zero (not run). On the reference machine in host-sim
//! (`tests/tests/self_test.rs`): settle 0.2 s, about 20 ms to decide the direction,
//! the first index within a turn and the second a turn later at about 190 rpm mean
//! (0.41 and 0.54 s of drive from rest), 0.7 s to come to rest and settle again:
//! 2.17 s for both rotors. At most, with every timeout, three settles of 3 s and
//! two drives of 4 s: 17 s.
//!
//! # The duty
//!
//! An unbalance rotor at rest hangs its eccentric down; to go over the top the
//! motor must beat the largest load torque `T_L = m e g + T_c` (the weight torque
//! with the eccentric horizontal plus Coulomb friction,
//! [`super::RotorModel::load_torque_nm`]). The motor's torque at speed `w` under a
//! duty `d` is `k (d V - k w) / R`, largest at rest. The duty gives twice the load
//! at rest,
//!
//! ```text
//!   d = max(TORQUE_MARGIN T_L R / (k V),  k w_min / V),  at most MAX_DUTY
//! ```
//!
//! so the motor beats the worst load as long as `w < d V / (2 k)`, half its no-load
//! speed: the rotor cannot stop anywhere on the turn, and it runs at most at the
//! no-load speed `d V / k`. `w_min` ([`MIN_NO_LOAD_RPM`]) is a floor for a machine
//! without a known load. Reference machine: `d = 2 x 2.962e-3 x 2 / (0.02 x 12) =
//! 0.049`, a stall torque of 5.9e-3 N m (three times `m e g`), a stall current of
//! `d V / R = 0.30 A` (a seventh of the driver's 2 A: a jammed rotor takes no harm),
//! a no-load speed of 283 rpm (about 190 rpm mean over a drive from rest, measured).
//!
//! That is below the stall checks' `stall_duty` (0.25), so the controller's
//! stall and "driven but not turning" checks do not apply (they need
//! `|duty| >= stall_duty`); the test's own motion checks take their place. A
//! machine whose load needs a duty at or above `stall_duty` keeps those checks, and
//! the move timeout is then cut to half of `stall_time_s` so that a jammed rotor
//! fails the test before it trips a stall fault.
//!
//! # What the flags measure
//!
//! With only an encoder, a positive duty turning the counts down cannot tell a
//! motor wired backwards from an encoder counting backwards. The winding current
//! ([`super::Inputs::current`], positive when driving forward) is a second,
//! electrical reference. Its mean `i_m` over the drive's ticks until the direction
//! is decided (the rotor still slow, the current near the stall current `d V / R`)
//! counts when `|i_m| >= CURRENT_FRACTION d V / R`:
//!
//! - `motor_polarity_ok`: the rotor moved and the current followed the duty (`i_m`
//!   counts and is positive). It checks the electrical chain duty -> bridge ->
//!   winding -> current sense: a motor whose leads are swapped between the bridge
//!   and the current sense, or a current sense wired backwards, fails it.
//! - `encoder_polarity_ok`: the rotor moved and the counts went the way the current
//!   pushed (`i_m` counts and has the sign of the travel). It checks the encoder
//!   against the current sense: channels A and B swapped fail it.
//! - `index_seen`: an index pulse came while the rotor was driven.
//! - `counts_per_rev`: `c_b - c_a` above, 0 without two pulses.
//! - `index_offset_counts`: `(c1 - c0) mod n` above, 0 without a pulse.
//!
//! What no sensor tells: which way the rotor really turned. Motor leads swapped at
//! the motor itself (after the current sense) read as a good motor with a bad
//! encoder; swapped there *and* an encoder swapped read as all good while the rotor
//! turns against its machine file's `sense` (the pair would then turn the same
//! way, and the exciting forces never add up as designed). **The mechanical sense
//! must be checked by eye** during the test: rotor 1 turns first, then rotor 2, each
//! in its driven sense (the machine file's `sense`).
//!
//! # Faults
//!
//! The controller's fault checks keep running (E-stop, over-current, supply, count
//! jumps, and the stall checks at a duty at or above `stall_duty`); any fault, or a
//! stop command, aborts the test with the motors off in the same tick
//! ([`super::Controller`]). Only the index checks are left to the test itself,
//! whose job is to measure the index: a wrong configured `encoder_counts` or a dead
//! index shows as `counts_per_rev` or `index_seen` instead of an `ENCODER` fault.

mod result;

pub use result::{RotorSelfTest, SelfTest, SelfTestReport, SelfTestStatus};

use super::angle::rpm_to_rad_s;
use super::params::{Params, RotorCount};

/// The duty's stall torque over the rotor's largest load torque.
pub const TORQUE_MARGIN: f32 = 2.0;
/// The duty's no-load speed is at least this, rpm (a floor when the load torque is
/// unknown).
pub const MIN_NO_LOAD_RPM: f32 = 120.0;
/// The test never drives harder than this duty.
pub const MAX_DUTY: f32 = 0.5;
/// The mean current counts (for the polarity flags) from this fraction of the
/// stall current `d V / R`.
pub const CURRENT_FRACTION: f32 = 0.25;
/// A rotor is at rest below this speed, rpm (as [`super::WRITE_MAX_SPEED_RPM`]).
pub const REST_RPM: f32 = 10.0;
/// Both rotors at rest this long end a settle, s.
pub const REST_TIME_S: f32 = 0.2;
/// A settle ends after this long whatever the rotors do, s.
pub const SETTLE_TIMEOUT_S: f32 = 3.0;
/// A rotor that has not moved [`SelfTestConfig::direction_counts`] after this long
/// did not turn, s (twelve times what the reference machine takes: 20 ms).
pub const MOVE_TIMEOUT_S: f32 = 0.25;
/// A drive ends after this long, s.
pub const DRIVE_TIMEOUT_S: f32 = 4.0;
/// A drive ends after this many configured turns of travel: two index pulses
/// arrive within that for an encoder of up to 1.5 times the configured counts.
pub const MAX_TURNS: u32 = 3;

/// The test's settings, derived from the controller's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfTestConfig {
    /// The drive duty per rotor, in (0, [`MAX_DUTY`]].
    pub duty: [f32; 2],
    /// The least mean |current| that counts for the polarity flags, A.
    pub current_min_a: [f32; 2],
    /// Configured counts per revolution `N`.
    pub counts_per_rev: u32,
    /// Travel that decides the direction, counts: `max(N / 64, 2 tol, 1)` [64, 5.6
    /// degrees: far above the rocking of a rotor at rest].
    pub direction_counts: u32,
    /// See [`MOVE_TIMEOUT_S`], s.
    pub move_timeout_s: f32,
    /// See [`DRIVE_TIMEOUT_S`], s.
    pub drive_timeout_s: f32,
    /// See [`MAX_TURNS`], counts.
    pub max_travel_counts: u32,
    /// The rotors tested: rotor 1, then rotor 2 if the machine has one.
    pub rotor_count: RotorCount,
}

impl SelfTestConfig {
    /// The settings for `p` (module documentation, "The duty").
    pub fn from_params(p: &Params) -> Self {
        let v = p.supply_nominal_v;
        let duty = p.rotors.map(|r| {
            let torque =
                TORQUE_MARGIN * r.load_torque_nm * r.resistance_ohm / (r.torque_constant * v);
            let speed = r.torque_constant * rpm_to_rad_s(MIN_NO_LOAD_RPM) / v;
            let d = torque.max(speed);
            if d.is_finite() {
                d.clamp(0.0, MAX_DUTY)
            } else {
                MAX_DUTY
            }
        });
        let current_min_a =
            [0, 1].map(|k| CURRENT_FRACTION * duty[k] * v / p.rotors[k].resistance_ohm);
        let n = p.encoder_counts.max(1);
        let direction_counts = (n / 64).max(2 * p.limits.index_tolerance_counts).max(1);
        let strong = duty.iter().any(|d| *d >= p.limits.stall_duty);
        let move_timeout_s = if strong {
            MOVE_TIMEOUT_S.min(0.5 * p.limits.stall_time_s)
        } else {
            MOVE_TIMEOUT_S
        };
        SelfTestConfig {
            duty,
            current_min_a,
            counts_per_rev: n,
            direction_counts,
            move_timeout_s,
            drive_timeout_s: DRIVE_TIMEOUT_S,
            max_travel_counts: n.saturating_mul(MAX_TURNS),
            rotor_count: p.rotor_count,
        }
    }
}

/// What the test reads each tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfTestSample {
    /// Encoder counters ([`super::Inputs::encoder`]).
    pub encoder: [u32; 2],
    /// Index latches ([`super::Inputs::index`]).
    pub index: [Option<u32>; 2],
    /// Winding currents, A ([`super::Inputs::current`]).
    pub current: [f32; 2],
    /// Filtered speeds, rpm.
    pub speed_rpm: [f32; 2],
}

/// One rotor's drive.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Drive {
    /// The start position `c0`.
    start: u32,
    /// Ticks since the drive started (0 in the start tick).
    ticks: u32,
    /// Time since the start tick, s.
    elapsed_s: f32,
    /// Sum and number of the current samples until the direction is decided.
    current_sum: f32,
    current_n: u32,
    /// The direction is decided and forward.
    forward: bool,
    /// Furthest travel, counts.
    max_travel: i32,
    /// The first and the last index count.
    first_index: Option<u32>,
    last_index: Option<u32>,
}

/// Where the test stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Waiting for rest before driving `rotor` (the rotor count: before
    /// finishing).
    Settle {
        /// Time both rotors have been at rest, s.
        rest_s: f32,
        /// Time in this settle, s.
        elapsed_s: f32,
    },
    /// Driving `rotor`.
    Drive(Drive),
    /// Finished (or aborted).
    Done,
}

/// The self-test in progress. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfTestRun {
    config: SelfTestConfig,
    /// The rotor settled for or driven (the rotor count after the last).
    rotor: usize,
    phase: Phase,
    result: SelfTest,
}

/// What one tick of the test gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfTestStep {
    /// Duties for this tick, rotor 1 and 2.
    pub duty: [f32; 2],
    /// The test has finished (the duties are 0).
    pub done: bool,
}

impl SelfTestRun {
    /// A test about to settle before rotor 1, nothing measured.
    pub fn new(config: SelfTestConfig) -> Self {
        SelfTestRun {
            config,
            rotor: 0,
            phase: Phase::Settle {
                rest_s: 0.0,
                elapsed_s: 0.0,
            },
            result: SelfTest::default(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &SelfTestConfig {
        &self.config
    }

    /// What has been measured so far.
    pub fn result(&self) -> SelfTest {
        self.result
    }

    /// Finished (or aborted).
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// The rotor being driven, if one is.
    pub fn driving(&self) -> Option<usize> {
        match self.phase {
            Phase::Drive(_) => Some(self.rotor),
            _ => None,
        }
    }

    /// Stop where it stands (the measurements so far are kept).
    pub fn abort(&mut self) {
        self.phase = Phase::Done;
    }

    /// One tick, `dt` s after the previous one (> 0): the duties to write now.
    pub fn step(&mut self, s: &SelfTestSample, dt: f32) -> SelfTestStep {
        let mut duty = [0.0; 2];
        match self.phase {
            Phase::Done => {}
            Phase::Settle { rest_s, elapsed_s } => {
                let at_rest = s.speed_rpm.iter().all(|w| libm::fabsf(*w) <= REST_RPM);
                let rest_s = if at_rest { rest_s + dt } else { 0.0 };
                let elapsed_s = elapsed_s + dt;
                if rest_s >= REST_TIME_S - 0.5 * dt || elapsed_s >= SETTLE_TIMEOUT_S {
                    if self.rotor >= self.config.rotor_count.count() {
                        self.phase = Phase::Done;
                    } else {
                        // The drive starts in this tick, from this count.
                        self.phase = Phase::Drive(Drive {
                            start: s.encoder[self.rotor],
                            ticks: 0,
                            elapsed_s: 0.0,
                            current_sum: 0.0,
                            current_n: 0,
                            forward: false,
                            max_travel: 0,
                            first_index: None,
                            last_index: None,
                        });
                        duty[self.rotor] = self.config.duty[self.rotor];
                    }
                } else {
                    self.phase = Phase::Settle { rest_s, elapsed_s };
                }
            }
            Phase::Drive(mut d) => {
                let k = self.rotor.min(1);
                d.ticks += 1;
                d.elapsed_s += dt;
                if self.drive(&mut d, k, s) {
                    duty[k] = self.config.duty[k];
                    self.phase = Phase::Drive(d);
                } else {
                    self.rotor += 1;
                    self.phase = Phase::Settle {
                        rest_s: 0.0,
                        elapsed_s: 0.0,
                    };
                }
            }
        }
        SelfTestStep {
            duty,
            done: self.phase == Phase::Done,
        }
    }

    /// A drive tick (not the start tick) of rotor `k`: measure; true to keep
    /// driving.
    fn drive(&mut self, d: &mut Drive, k: usize, s: &SelfTestSample) -> bool {
        let c = &self.config;
        let r = &mut self.result.rotors[k];
        let travel = s.encoder[k].wrapping_sub(d.start) as i32;
        let w = c.direction_counts as i32;
        let mut keep = true;

        // Index pulses.
        if let Some(ic) = s.index[k] {
            r.index_seen = true;
            if d.first_index.is_none() {
                d.first_index = Some(ic);
            }
            if let Some(last) = d.last_index {
                let n = ic.wrapping_sub(last) as i32;
                if n > 0 && d.forward {
                    r.counts_per_rev = n as u32;
                    keep = false;
                }
            }
            d.last_index = Some(ic);
        }
        if let Some(first) = d.first_index {
            let n = if r.counts_per_rev > 0 {
                r.counts_per_rev
            } else {
                c.counts_per_rev
            };
            let off = first.wrapping_sub(d.start) as i32 as i64;
            r.index_offset_counts = off.rem_euclid(i64::from(n)) as u32;
        }

        if !d.forward {
            // The current of the last tick's drive, until the direction is decided.
            d.current_sum += s.current[k];
            d.current_n += 1;
            if travel >= w || travel <= -w {
                let mean = d.current_sum / d.current_n as f32;
                let counts = libm::fabsf(mean) >= c.current_min_a[k];
                r.motor_polarity_ok = counts && mean > 0.0;
                r.encoder_polarity_ok = counts && (mean > 0.0) == (travel > 0);
                d.forward = travel > 0;
                if !d.forward {
                    // Counts running the wrong way: stop driving at once.
                    return false;
                }
            } else if d.elapsed_s >= c.move_timeout_s {
                // It did not turn.
                return false;
            }
        }
        if d.forward {
            d.max_travel = d.max_travel.max(travel);
            let reversed = travel <= d.max_travel.saturating_sub(w);
            let far = travel.unsigned_abs() >= c.max_travel_counts;
            if reversed || far || d.elapsed_s >= c.drive_timeout_s {
                keep = false;
            }
        }
        keep
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::Params;

    /// A synthetic rotor: counts and index as an ideal encoder of `n` counts whose
    /// index sits at count 0 (mod n), turning `rate` counts a tick while driven.
    struct Synthetic {
        run: SelfTestRun,
        count: [i64; 2],
        n: i64,
    }

    impl Synthetic {
        fn new(start: [i64; 2]) -> Self {
            let p = Params::reference();
            Synthetic {
                run: SelfTestRun::new(SelfTestConfig::from_params(&p)),
                count: start,
                n: 4096,
            }
        }

        /// Runs until done or `max` ticks; `motion(k, duty)` gives counts per tick
        /// and the current for the duty written in the previous tick.
        fn run(&mut self, max: u32, motion: impl Fn(usize, f32) -> (i64, f32)) -> u32 {
            let mut duty = [0.0f32; 2];
            for tick in 0..max {
                let mut index = [None; 2];
                let mut current = [0.0; 2];
                let mut speed = [0.0; 2];
                for k in 0..2 {
                    let (rate, i) = motion(k, duty[k]);
                    let before = self.count[k];
                    self.count[k] += rate;
                    current[k] = i;
                    speed[k] = rate as f32 * 60.0 * 1000.0 / self.n as f32;
                    let (a, b) = (before.div_euclid(self.n), self.count[k].div_euclid(self.n));
                    if b > a {
                        index[k] = Some((b * self.n) as u32);
                    } else if b < a {
                        index[k] = Some((a * self.n) as u32);
                    }
                }
                let sample = SelfTestSample {
                    encoder: self.count.map(|c| c as u32),
                    index,
                    current,
                    speed_rpm: speed,
                };
                let step = self.run.step(&sample, 0.001);
                duty = step.duty;
                assert!(
                    duty.iter().filter(|d| **d != 0.0).count() <= 1,
                    "one rotor at a time"
                );
                if step.done {
                    return tick;
                }
            }
            panic!("not done in {max} ticks");
        }
    }

    #[test]
    fn reference_duty_is_twice_the_load_and_below_the_stall_duty() {
        let p = Params::reference();
        let c = SelfTestConfig::from_params(&p);
        // 2 x 2.962e-3 N m x 2 ohm / (0.02 N m/A x 12 V) = 0.04937.
        assert!((c.duty[0] - 0.049367).abs() < 1e-5, "{}", c.duty[0]);
        assert!(c.duty[0] < p.limits.stall_duty);
        assert_eq!(c.direction_counts, 64);
        assert_eq!(c.max_travel_counts, 3 * 4096);
        assert_eq!(c.move_timeout_s, MOVE_TIMEOUT_S);
    }

    #[test]
    fn a_good_rotor_pair_measures_everything() {
        // Rotor 1 starts 1000 counts before an index, rotor 2 3000 before one.
        let mut t = Synthetic::new([4096 * 5 - 1000, -3000]);
        let ticks = t.run(20_000, |_, d| if d > 0.0 { (16, 0.3) } else { (0, 0.0) });
        let r = t.run.result();
        for (k, want) in [(0, 1000), (1, 3000)] {
            let r = r.rotors[k];
            assert!(
                r.motor_polarity_ok && r.encoder_polarity_ok && r.index_seen,
                "{r:?}"
            );
            assert_eq!(r.counts_per_rev, 4096);
            assert_eq!(r.index_offset_counts, want);
        }
        assert!(r.passed());
        // Settle 200 ticks, (1000 + 4096) / 16 = 319 driven, settle 200,
        // (3000 + 4096) / 16 = 444 driven, settle 200: 1363.
        assert!((1360..=1366).contains(&ticks), "{ticks}");
    }

    #[test]
    fn counts_against_the_current_fail_the_encoder_and_stop_at_once() {
        let mut t = Synthetic::new([0, 0]);
        // Rotor 1's counts run down (encoder swapped).
        let driven = core::cell::Cell::new(0u32);
        t.run(20_000, |k, d| match (k, d > 0.0) {
            (0, true) => {
                driven.set(driven.get() + 1);
                (-16, 0.3)
            }
            (_, true) => (16, 0.3),
            _ => (0, 0.0),
        });
        let driven_ticks = driven.get();
        let r = t.run.result().rotors[0];
        assert!(r.motor_polarity_ok && !r.encoder_polarity_ok, "{r:?}");
        assert!(!r.index_seen || r.counts_per_rev == 0);
        // 64 counts at 16 a tick: the fourth driven tick sees -64 and stops.
        assert!(driven_ticks <= 5, "{driven_ticks} ticks driven");
        assert!(t.run.result().rotors[1].passed());
    }

    #[test]
    fn a_reversed_current_fails_the_motor_flag() {
        // Motor leads swapped before the current sense: the current and the
        // motion both go backwards.
        let mut t = Synthetic::new([0, 0]);
        t.run(20_000, |k, d| match (k, d > 0.0) {
            (0, true) => (-16, -0.3),
            (_, true) => (16, 0.3),
            _ => (0, 0.0),
        });
        let r = t.run.result().rotors[0];
        assert!(!r.motor_polarity_ok && r.encoder_polarity_ok, "{r:?}");
        assert_eq!(r.counts_per_rev, 0);
    }

    #[test]
    fn no_motion_fails_the_rotor_and_the_test_goes_on() {
        let mut t = Synthetic::new([0, 0]);
        let ticks = t.run(20_000, |k, d| match (k, d > 0.0) {
            (1, true) => (16, 0.3),
            (_, true) => (0, 0.3),
            _ => (0, 0.0),
        });
        let r = t.run.result();
        assert_eq!(r.rotors[0], RotorSelfTest::default());
        assert!(r.rotors[1].passed());
        // Settle 200, no motion 250, settle 200, drive ~260, settle 200.
        assert!(ticks < 1500, "{ticks}");
    }

    #[test]
    fn a_missing_current_fails_both_polarities_but_measures_the_index() {
        let mut t = Synthetic::new([0, 0]);
        t.run(20_000, |_, d| if d > 0.0 { (16, 0.0) } else { (0, 0.0) });
        let r = t.run.result().rotors[0];
        assert!(!r.motor_polarity_ok && !r.encoder_polarity_ok);
        assert!(r.index_seen);
        assert_eq!(r.counts_per_rev, 4096);
    }

    #[test]
    fn a_dead_index_ends_the_drive_after_max_turns() {
        let n = 4096i64;
        let mut run = Synthetic::new([0, 0]).run;
        let mut count = 1i64;
        let mut duty = [0.0f32; 2];
        let mut driven = 0;
        for _ in 0..20_000 {
            if duty[0] > 0.0 {
                count += 16;
                driven += 1;
            }
            let s = SelfTestSample {
                encoder: [count as u32, 0],
                index: [None; 2],
                current: [if duty[0] > 0.0 { 0.3 } else { 0.0 }, 0.0],
                speed_rpm: [0.0; 2],
            };
            let step = run.step(&s, 0.001);
            duty = step.duty;
            if run.rotor > 0 {
                break;
            }
        }
        let r = run.result().rotors[0];
        assert!(!r.index_seen && r.counts_per_rev == 0 && r.motor_polarity_ok);
        assert_eq!(driven, (3 * n / 16) as u32);
    }

    #[test]
    fn aborting_stops_the_drive() {
        let mut run = Synthetic::new([0, 0]).run;
        let s = SelfTestSample {
            encoder: [0; 2],
            index: [None; 2],
            current: [0.0; 2],
            speed_rpm: [0.0; 2],
        };
        let mut driving = false;
        for _ in 0..1000 {
            if run.step(&s, 0.001).duty[0] > 0.0 {
                driving = true;
                break;
            }
        }
        assert!(driving && run.driving() == Some(0));
        run.abort();
        let step = run.step(&s, 0.001);
        assert_eq!(step.duty, [0.0; 2]);
        assert!(step.done && run.is_done());
    }
}
