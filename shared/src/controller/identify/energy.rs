//! The spin-up's energy balance, for the inertia: from rest to a whole number of
//! turns later, where the eccentric's weight has done no net work.
//!
//! Between two instants at the same rotor angle the weight of the eccentric does
//! no net work (its potential energy depends on the angle alone), so the work of
//! the motor's torque less friction equals the change of kinetic energy:
//!
//! ```text
//!   J w_B^2 / 2 - J w_A^2 / 2 = integral (k i - T_c - b w) dtheta
//!                             = k S_i - T_c S_1 - b S_w
//!   S_i = sum i_n dtheta_n,  S_1 = sum dtheta_n,  S_w = sum w_n dtheta_n
//! ```
//!
//! with `i_n` the mean current of tick `n`, `dtheta_n` its travel, rad, and
//! `w_n = dtheta_n / dt` its mean speed. From rest (`w_A = 0`),
//! `J = 2 (k S_i - T_c S_1 - b S_w) / w_B^2`. The sums are kept for every whole
//! turn the spin-up makes (a [`Snapshot`] each), so that `k`, `T_c` and `b`, which
//! the speed levels measure afterwards, can be put in at the end. The turn ends at
//! the tick boundary nearest to it: its angle misses the start's by at most half
//! a tick's travel, and the weight's work over that is bounded in the standard
//! error ([`super::assemble`]).
//!
//! The speed at a boundary `b` is the central difference of the counts
//! `(c_(b+h) - c_(b-h)) / (2 h dt)` ([`HALF_WINDOW`] ticks each side): second-order
//! in the tick, and one count of quantization over `2 h` ticks.

use core::f64::consts::TAU;

/// Ticks each side of a boundary in its speed's central difference.
pub const HALF_WINDOW: usize = 4;
/// The counts kept: `2 h + 1` ticks.
const RING: usize = 2 * HALF_WINDOW + 1;
/// Whole turns recorded in a spin-up.
pub const MAX_SNAPSHOTS: usize = 8;

/// The sums of the energy balance at the end of a whole turn.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// `S_i`, A rad.
    pub s_i: f64,
    /// `S_1`, rad.
    pub s_1: f64,
    /// `S_w`, rad^2/s.
    pub s_w: f64,
    /// The speed at the boundary, rad/s (valid once `resolved`).
    pub speed: f64,
    /// How far the boundary is from the whole turn, rad (signed).
    pub miss_rad: f64,
    /// The speed has been measured (`h` ticks after the boundary).
    resolved: bool,
    /// The tick of the boundary.
    tick: u32,
}

impl Snapshot {
    /// Whether its speed is known.
    pub fn resolved(&self) -> bool {
        self.resolved
    }
}

/// The counts of the last `2 h + 1` ticks of the rotor under test, by tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    ring: [u32; RING],
    /// Ticks recorded.
    ticks: u32,
}

impl Counts {
    /// Records the count of the tick just sampled; returns its tick number (from 0).
    pub fn push(&mut self, count: u32) -> u32 {
        let t = self.ticks;
        self.ring[t as usize % RING] = count;
        self.ticks = t.wrapping_add(1);
        t
    }

    /// The count of tick `t`, if still kept.
    fn at(&self, t: u32) -> Option<u32> {
        let newest = self.ticks.checked_sub(1)?;
        (newest.wrapping_sub(t) < RING as u32 && t <= newest).then(|| self.ring[t as usize % RING])
    }

    /// The speed at the boundary of tick `b`, rad/s, once tick `b + h` is in:
    /// `2 pi (c_(b+h) - c_(b-h)) / (N 2 h dt)`.
    fn speed_at(&self, b: u32, counts_per_rev: u32, dt: f32) -> Option<f64> {
        let after = self.at(b.checked_add(HALF_WINDOW as u32)?)?;
        let before = self.at(b.checked_sub(HALF_WINDOW as u32)?)?;
        let travel = f64::from(after.wrapping_sub(before) as i32);
        Some(TAU * travel / (f64::from(counts_per_rev) * 2.0 * HALF_WINDOW as f64 * f64::from(dt)))
    }
}

/// A spin-up from rest in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpinUp {
    /// The count at rest, where it started.
    start: u32,
    /// The count at the previous tick.
    last: u32,
    /// The running sums.
    now: Snapshot,
    /// One per whole turn so far.
    snapshots: [Snapshot; MAX_SNAPSHOTS],
    /// Snapshots taken.
    taken: usize,
    /// Still taking snapshots (the spin-up's level runs).
    taking: bool,
}

impl SpinUp {
    /// A spin-up from rest at count `start`.
    pub fn new(start: u32) -> Self {
        SpinUp {
            start,
            last: start,
            now: Snapshot::default(),
            snapshots: [Snapshot::default(); MAX_SNAPSHOTS],
            taken: 0,
            taking: true,
        }
    }

    /// No more snapshots (the spin-up's level is over); those taken still get
    /// their speeds.
    pub fn stop_taking(&mut self) {
        self.taking = false;
    }

    /// The whole turns recorded, in order.
    pub fn snapshots(&self) -> &[Snapshot] {
        &self.snapshots[..self.taken]
    }

    /// One tick: the count `count` at tick `tick` (of [`Counts`]), the mean
    /// current `amps` over the tick just ended, A, and `dt`, s. `counts` holds the
    /// ticks so far, this one included.
    pub fn step(&mut self, tick: u32, count: u32, amps: f32, counts: &Counts, n: u32, dt: f32) {
        let before = self.last.wrapping_sub(self.start) as i32;
        let after = count.wrapping_sub(self.start) as i32;
        self.last = count;
        let d_theta = TAU * f64::from(after - before) / f64::from(n);
        let w = d_theta / f64::from(dt);
        let sums_before = self.now;
        self.now.s_i += f64::from(amps) * d_theta;
        self.now.s_1 += d_theta;
        self.now.s_w += w * d_theta;
        // A whole turn `m N` passed in this tick: keep the sums at the nearer
        // boundary.
        if self.taking && self.taken < MAX_SNAPSHOTS && after > before {
            let target = (self.taken as i64 + 1) * i64::from(n);
            if i64::from(before) < target && target <= i64::from(after) {
                let nearer_before = target - i64::from(before) < i64::from(after) - target;
                let (mut s, boundary, at) = if nearer_before {
                    (sums_before, tick.wrapping_sub(1), before)
                } else {
                    (self.now, tick, after)
                };
                s.miss_rad = TAU * (i64::from(at) - target) as f64 / f64::from(n);
                s.tick = boundary;
                s.resolved = false;
                self.snapshots[self.taken] = s;
                self.taken += 1;
            }
        }
        for s in self.snapshots[..self.taken]
            .iter_mut()
            .filter(|s| !s.resolved)
        {
            if let Some(w) = counts.speed_at(s.tick, n, dt) {
                s.speed = w;
                s.resolved = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotor turning at a constant 50 rad/s from rest at tick 0 (a step of
    /// speed): the sums are those of the closed forms, a snapshot per whole
    /// turn, each with its speed and a miss below half a tick's travel.
    #[test]
    fn a_constant_speed_gives_the_closed_forms() {
        let n = 4096u32;
        let dt = 1e-3f32;
        let w = 50.0f64;
        let counts_per_tick = w * f64::from(dt) * f64::from(n) / TAU;
        let mut counts = Counts::default();
        for _ in 0..RING {
            counts.push(1000);
        }
        let mut spin = SpinUp::new(1000);
        let amps = 0.5f32;
        let mut ticks = 0u32;
        while spin.snapshots().len() < 3 || !spin.snapshots()[2].resolved() {
            ticks += 1;
            let count = 1000 + (f64::from(ticks) * counts_per_tick).round() as u32;
            let t = counts.push(count);
            spin.step(t, count, amps, &counts, n, dt);
            assert!(ticks < 10_000);
        }
        for (m, s) in spin.snapshots().iter().enumerate() {
            let turns = (m + 1) as f64;
            assert!(s.miss_rad.abs() <= 0.5 * w * f64::from(dt) + 1e-9, "{s:?}");
            let theta = TAU * turns + s.miss_rad;
            assert!((s.s_1 - theta).abs() < 1e-9, "{s:?}");
            assert!((s.s_i - 0.5 * theta).abs() < 1e-6, "{s:?}");
            // Each tick's speed is its rounded travel over dt: within a count.
            let one_count = TAU / f64::from(n) / f64::from(dt);
            assert!((s.s_w - w * theta).abs() < one_count * theta, "{s:?}");
            assert!((s.speed - w).abs() < one_count / 4.0, "{s:?}");
        }
    }
}
