//! One rotor's encoder: speed from counts, the angle from the index pulse, and the
//! checks that the counts and the index agree with a turning rotor.
//!
//! # Speed
//!
//! The counts travelled in a tick, `delta = now.wrapping_sub(before) as i32` (right
//! across the counter's wrap at `2^32`), give the mean speed over the tick,
//!
//! ```text
//!   w_raw = 2 pi delta / (N dt)                  rad/s, driven sense
//! ```
//!
//! filtered by a first-order low-pass of time constant `tau` (backward Euler, which
//! is unconditionally stable and has the exact input as its fixed point):
//!
//! ```text
//!   w += dt / (tau + dt) (w_raw - w)
//! ```
//!
//! At a constant count rate the estimate converges to the exact speed; with a
//! fractional number of counts per tick `w_raw` alternates between two neighbours
//! one count apart and the filter averages them.
//!
//! # Angle
//!
//! The index pulse fires at `theta = 0` (`theta = s (phi - index_angle)`:
//! docs/machine-file.md, "Conventions"), so with the count `c0` latched at the last
//! index pulse,
//!
//! ```text
//!   theta = 2 pi ((count - c0) mod N) / N
//! ```
//!
//! kept as the integer `(count - c0) mod N` so that the phase offset is exact.

use super::angle::TURN_RAD;

/// A first-order low-pass speed estimate from encoder counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedEstimator {
    /// Counts per revolution `N`.
    counts_per_rev: u32,
    /// Filter time constant, s.
    tau_s: f32,
    /// The previous count, `None` before the first sample.
    last_count: Option<u32>,
    /// The filtered speed, rad/s.
    speed_rad_s: f32,
    /// The filter's per-`dt` constants, `(dt, N dt, dt / (tau + dt))`: computed
    /// for the `dt` of a tick and reused while the next ticks pass the same `dt`
    /// (recomputed when it changes), which saves a division every tick. `None`
    /// until the first usable `dt`.
    coefficients: Option<(f32, f32, f32)>,
}

impl SpeedEstimator {
    /// An estimator for `counts_per_rev` counts per turn (>= 1) with filter time
    /// constant `tau_s` (>= 0 s), at rest.
    pub fn new(counts_per_rev: u32, tau_s: f32) -> Self {
        SpeedEstimator {
            counts_per_rev: counts_per_rev.max(1),
            tau_s: if tau_s >= 0.0 { tau_s } else { 0.0 },
            last_count: None,
            speed_rad_s: 0.0,
            coefficients: None,
        }
    }

    /// The counts travelled since the previous sample (`wrapping_sub` read as
    /// `i32`); 0 for the first sample.
    pub fn delta(&self, count: u32) -> i32 {
        match self.last_count {
            Some(last) => count.wrapping_sub(last) as i32,
            None => 0,
        }
    }

    /// Take the count sampled `dt` (> 0) s after the previous one; returns the
    /// filtered speed, rad/s. The first sample only sets the reference count.
    pub fn update(&mut self, count: u32, dt: f32) -> f32 {
        if let Some(last) = self.last_count {
            let delta = count.wrapping_sub(last) as i32;
            self.feed(delta, dt);
        }
        self.last_count = Some(count);
        self.speed_rad_s
    }

    /// Take a count without using its travel for the speed (after a jump the
    /// encoder check has flagged): the speed estimate holds.
    pub fn skip(&mut self, count: u32) {
        self.last_count = Some(count);
    }

    /// The filter step on `delta` counts over `dt` s; a `dt` that is not finite
    /// and > 0 changes nothing.
    fn feed(&mut self, delta: i32, dt: f32) {
        let (n_dt, alpha) = match self.coefficients {
            Some((kept, n_dt, alpha)) if kept == dt => (n_dt, alpha),
            _ => {
                // A new `dt`: checked, then `N dt` and `alpha = dt / (tau + dt)`
                // for it (module documentation), kept until `dt` changes. Only a
                // usable `dt` is kept, so one equal to the kept one needs no check.
                if !(dt > 0.0 && dt.is_finite()) {
                    return;
                }
                let n_dt = self.counts_per_rev as f32 * dt;
                let alpha = dt / (self.tau_s + dt);
                self.coefficients = Some((dt, n_dt, alpha));
                (n_dt, alpha)
            }
        };
        let raw = TURN_RAD * delta as f32 / n_dt;
        self.speed_rad_s += alpha * (raw - self.speed_rad_s);
    }

    /// The filtered speed, rad/s.
    pub fn speed_rad_s(&self) -> f32 {
        self.speed_rad_s
    }
}

/// An inconsistency between the counts, the index pulse and a turning rotor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncoderAnomaly {
    /// More counts in a tick than the rotor can turn (`encoder_max_speed_rpm`).
    Jump,
    /// An index pulse away from a whole number of turns after the previous one, or
    /// latched at a count outside the counts travelled this tick (beyond the
    /// tolerance).
    IndexMisplaced,
    /// More than a turn (plus the tolerance) travelled since the last index pulse,
    /// or since the start before the first one.
    IndexMissing,
}

/// One rotor's encoder: speed, angle from the index, consistency checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderTracker {
    /// Counts per revolution `N` (validated: 4 ..= 2^24).
    counts_per_rev: u32,
    /// Index tolerance, counts.
    tolerance: u32,
    /// `N + tolerance`, saturated at `u32::MAX` (a travel since the index never
    /// exceeds `2^31`, so saturating changes no comparison): more counts than this
    /// without an index pulse is [`EncoderAnomaly::IndexMissing`].
    missing_limit: u32,
    /// The speed estimate.
    speed: SpeedEstimator,
    /// The count latched at the last index pulse.
    index_count: Option<u32>,
    /// The first count seen: the reference for "a turn without an index" until the
    /// first index pulse.
    origin: Option<u32>,
}

/// What one tick's reading of an encoder gave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderSample {
    /// Filtered speed, rad/s, driven sense.
    pub speed_rad_s: f32,
    /// `(count - index_count) mod N`, counts: the angle `theta` from the index, once
    /// an index pulse has been seen.
    pub angle_counts: Option<u32>,
    /// An inconsistency found this tick.
    pub anomaly: Option<EncoderAnomaly>,
}

impl EncoderTracker {
    /// A tracker for `counts_per_rev` counts per turn, index tolerance
    /// `tolerance_counts`, speed filter time constant `tau_s`. `counts_per_rev` is
    /// taken in [1, 2^31 - 1] (the controller's are validated to at most 2^24), so
    /// that the angle is computed in `i32`.
    pub fn new(counts_per_rev: u32, tolerance_counts: u32, tau_s: f32) -> Self {
        let n = counts_per_rev.clamp(1, i32::MAX as u32);
        EncoderTracker {
            counts_per_rev: n,
            tolerance: tolerance_counts,
            missing_limit: n.saturating_add(tolerance_counts),
            speed: SpeedEstimator::new(n, tau_s),
            index_count: None,
            origin: None,
        }
    }

    /// The filtered speed of the last update, rad/s (0 before the first).
    pub fn speed_rad_s(&self) -> f32 {
        self.speed.speed_rad_s()
    }

    /// The count latched at the last index pulse, `None` before the first.
    pub fn index_count(&self) -> Option<u32> {
        self.index_count
    }

    /// Whether an index pulse has been seen.
    pub fn index_seen(&self) -> bool {
        self.index_count.is_some()
    }

    /// The distance of `d` counts from the nearest whole number of turns, counts.
    fn off_turn(&self, d: i32) -> u32 {
        let r = self.angle(d);
        r.min(self.counts_per_rev - r)
    }

    /// `d mod N`, in [0, N): in 32 bits, which the Cortex-M4 divides in hardware
    /// (a 64-bit remainder is a library call of about a hundred instructions);
    /// `N` is in [1, 2^31 - 1] here ([`EncoderTracker::new`]), so it fits an
    /// `i32`. Within the turn already (the angle since the last index pulse,
    /// turning forward), `d` is the remainder itself and no division is needed.
    #[inline]
    fn angle(&self, d: i32) -> u32 {
        if (d as u32) < self.counts_per_rev {
            d as u32
        } else {
            d.rem_euclid(self.counts_per_rev as i32) as u32
        }
    }

    /// Take one tick's counter and index latch, `dt` s after the previous tick;
    /// `max_counts` is the most counts the rotor can travel in `dt` (more is a
    /// [`EncoderAnomaly::Jump`]).
    pub fn update(
        &mut self,
        count: u32,
        index: Option<u32>,
        dt: f32,
        max_counts: f32,
    ) -> EncoderSample {
        let mut anomaly = None;
        let first = self.origin.is_none();
        let delta = self.speed.delta(count);
        let tol = self.tolerance as i64;

        // Speed: a jump beyond what the rotor can turn is not used for the speed.
        if (delta.unsigned_abs() as f32) > max_counts {
            anomaly = Some(EncoderAnomaly::Jump);
            self.speed.skip(count);
        } else {
            // `self.speed.update(count, dt)` with the `delta` already worked out.
            if self.speed.last_count.is_some() {
                self.speed.feed(delta, dt);
            }
            self.speed.last_count = Some(count);
        }
        let origin = *self.origin.get_or_insert(count);

        // Index pulse: inside the counts travelled this tick (the previous count to
        // this one, plus the tolerance; unknown at the first sample) and a whole
        // number of turns after the last.
        if let Some(c) = index {
            let before = count.wrapping_sub(delta as u32);
            let at = c.wrapping_sub(before) as i32 as i64;
            let (lo, hi) = if delta >= 0 {
                (0, delta as i64)
            } else {
                (delta as i64, 0)
            };
            let inside = first || (at >= lo - tol && at <= hi + tol);
            let whole_turns = match self.index_count {
                Some(last) => self.off_turn(c.wrapping_sub(last) as i32) <= self.tolerance,
                None => true,
            };
            if !(inside && whole_turns) {
                anomaly = Some(EncoderAnomaly::IndexMisplaced);
            }
            self.index_count = Some(c);
        }

        // A turn and more without an index pulse.
        let reference = self.index_count.unwrap_or(origin);
        let travel = count.wrapping_sub(reference) as i32;
        if travel.unsigned_abs() > self.missing_limit {
            anomaly.get_or_insert(EncoderAnomaly::IndexMissing);
        }

        let angle_counts = self
            .index_count
            .map(|c| self.angle(count.wrapping_sub(c) as i32));
        EncoderSample {
            speed_rad_s: self.speed.speed_rad_s(),
            angle_counts,
            anomaly,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_whole_turns_pass_and_half_turns_fail() {
        let mut e = EncoderTracker::new(4096, 4, 0.005);
        let mut count = 0u32;
        for k in 0..200u32 {
            count = count.wrapping_add(100);
            // The index at each multiple of 4096 crossed this tick.
            let turns_before = (count - 100) / 4096;
            let idx = (count / 4096 > turns_before).then(|| (count / 4096) * 4096);
            let s = e.update(count, idx, 0.001, 1000.0);
            assert_eq!(s.anomaly, None, "tick {k}");
        }
        // An index half a turn off.
        let c = e.index_count.unwrap().wrapping_add(2048);
        let s = e.update(count.wrapping_add(100), Some(c), 0.001, 1000.0);
        assert_eq!(s.anomaly, Some(EncoderAnomaly::IndexMisplaced));
    }

    #[test]
    fn a_turn_without_index_is_missing() {
        let mut e = EncoderTracker::new(4096, 4, 0.005);
        let mut count = 7u32;
        let mut found = None;
        for _ in 0..100 {
            let s = e.update(count, None, 0.001, 1000.0);
            if s.anomaly.is_some() {
                found = s.anomaly;
                break;
            }
            count = count.wrapping_add(100);
        }
        assert_eq!(found, Some(EncoderAnomaly::IndexMissing));
    }
}
