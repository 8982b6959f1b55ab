//! Reference ramps: the rotor speed (soft start, hurried through the resonance
//! band) and the phase offset (bounded rate, direction changes through the
//! vertical-force offset).

use super::angle::{leans_right, wrap_deg, wrap_deg_signed};

/// The vertical-force offset, degrees (the force acts along `offset / 2`:
/// docs/machine-file.md, "Conventions").
pub const VERTICAL_OFFSET_DEG: f32 = 180.0;

/// Rates and band of the speed ramp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedRampRates {
    /// Rate outside the band, rpm/s, > 0.
    pub normal_rpm_s: f32,
    /// Rate inside the band, rpm/s, > 0.
    pub resonance_rpm_s: f32,
    /// The band, rpm, `[low, high]`.
    pub band_rpm: [f32; 2],
}

/// Move `current` (rpm) towards `target` (rpm) by at most one tick's worth of the
/// rate that applies where `current` is: `resonance_rpm_s` inside `[low, high)`
/// when moving up and `(low, high]` when moving down, `normal_rpm_s` elsewhere.
/// Returns the new value and the acceleration of the reference, rpm/s (for the
/// feedforward). A non-finite target leaves `current` where it is.
pub fn ramp_speed(current: f32, target: f32, rates: &SpeedRampRates, dt: f32) -> (f32, f32) {
    // At the target (the steady state) first: equal values are never NaN.
    if current == target || !target.is_finite() || !current.is_finite() {
        return (if current.is_finite() { current } else { 0.0 }, 0.0);
    }
    let [lo, hi] = rates.band_rpm;
    let up = target > current;
    let in_band = if up {
        current >= lo && current < hi
    } else {
        current > lo && current <= hi
    };
    let rate = if in_band {
        rates.resonance_rpm_s
    } else {
        rates.normal_rpm_s
    };
    let step = rate * dt;
    // min(current + step, target) going up, max(current - step, target) going
    // down, written out (`f32::min` and `max` are library calls on the
    // Cortex-M4F); a NaN step gives the target, as they would.
    let next = if up {
        let x = current + step;
        if x < target {
            x
        } else {
            target
        }
    } else {
        let x = current - step;
        if x > target {
            x
        } else {
            target
        }
    };
    (next, (next - current) / dt)
}

/// The offset reference: where it is, where it goes, and whether it must pass the
/// vertical-force offset first.
///
/// A new command whose offset lies on the other side of the vertical line than the
/// reference (one in (0, 180), the other in (180, 360): a direction change) goes
/// first to 180 degrees along the shorter arc and then on to the target, so the
/// force turns through the vertical (the platform hops in place) and never through
/// the horizontal (0 degrees, where the pair pushes the platform sideways). Every
/// other change follows the shorter arc, e.g. the table's offset moving with the
/// speed. The rate is bounded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetRamp {
    /// The reference, degrees in [0, 360).
    reference_deg: f32,
    /// Where it is going, degrees in [0, 360).
    target_deg: f32,
    /// Heading for 180 degrees first.
    via_vertical: bool,
}

impl OffsetRamp {
    /// A ramp resting at `offset_deg`.
    pub fn new(offset_deg: f32) -> Self {
        let o = wrap_deg(offset_deg);
        OffsetRamp {
            reference_deg: o,
            target_deg: o,
            via_vertical: false,
        }
    }

    /// The reference, degrees in [0, 360).
    pub fn reference_deg(&self) -> f32 {
        self.reference_deg
    }

    /// The target, degrees in [0, 360).
    pub fn target_deg(&self) -> f32 {
        self.target_deg
    }

    /// A new command's target, degrees: the ramp passes the vertical-force offset
    /// first when the target lies on the other side of the vertical line than the
    /// reference (a direction change), otherwise it takes the shorter arc.
    pub fn command(&mut self, target_deg: f32) {
        self.target_deg = wrap_deg(target_deg);
        self.via_vertical = match (
            leans_right(self.reference_deg),
            leans_right(self.target_deg),
        ) {
            (Some(a), Some(b)) => a != b,
            _ => false,
        };
    }

    /// The same command's target, moved, degrees (the tuning table's offset
    /// following the ramped speed): the way there, through the vertical or not,
    /// stays as the command decided it.
    pub fn follow(&mut self, target_deg: f32) {
        self.target_deg = wrap_deg(target_deg);
    }

    /// Move by at most `max_step_deg` (>= 0) towards the waypoint or the target;
    /// returns the signed change, degrees. Inlined into the controller's tick,
    /// which calls it every tick the phase loop is closed.
    #[inline]
    pub fn step(&mut self, max_step_deg: f32) -> f32 {
        let goal = if self.via_vertical {
            VERTICAL_OFFSET_DEG
        } else {
            self.target_deg
        };
        let d = wrap_deg_signed(goal - self.reference_deg);
        let step = if max_step_deg >= 0.0 {
            max_step_deg
        } else {
            0.0
        };
        if libm::fabsf(d) <= step {
            self.reference_deg = goal;
            if self.via_vertical {
                self.via_vertical = false;
            }
            d
        } else {
            let s = if d > 0.0 { step } else { -step };
            self.reference_deg = wrap_deg(self.reference_deg + s);
            s
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(ramp: &mut OffsetRamp, steps: usize, step: f32) -> (f32, f32) {
        // The smallest distance to 0 and to 180 along the way.
        let mut near0 = f32::MAX;
        let mut near180 = f32::MAX;
        for _ in 0..steps {
            ramp.step(step);
            let o = ramp.reference_deg();
            near0 = near0.min(o.min(360.0 - o));
            near180 = near180.min((o - 180.0).abs());
        }
        (near0, near180)
    }

    #[test]
    fn right_to_left_passes_180() {
        for (from, to) in [(90.0, 270.0), (10.0, 350.0), (60.0, 300.0), (170.0, 190.0)] {
            let mut r = OffsetRamp::new(from);
            r.command(to);
            let (near0, near180) = run(&mut r, 2000, 0.5);
            assert_eq!(r.reference_deg(), to);
            assert!(near180 < 0.5, "{from} -> {to}");
            assert!(near0 >= from.min(360.0 - to) - 1e-3, "{from} -> {to}");
            // And back.
            r.command(from);
            let (_, near180) = run(&mut r, 2000, 0.5);
            assert_eq!(r.reference_deg(), from);
            assert!(near180 < 0.5);
        }
    }

    #[test]
    fn same_side_takes_the_short_arc() {
        let mut r = OffsetRamp::new(80.0);
        r.command(100.0);
        let (_, near180) = run(&mut r, 100, 0.5);
        assert_eq!(r.reference_deg(), 100.0);
        assert!(near180 > 79.0);
    }

    #[test]
    fn speed_ramp_hurries_through_the_band() {
        let rates = SpeedRampRates {
            normal_rpm_s: 1000.0,
            resonance_rpm_s: 10_000.0,
            band_rpm: [1000.0, 2000.0],
        };
        let mut s = 0.0;
        let mut t = 0.0;
        while s < 3000.0 {
            s = ramp_speed(s, 3000.0, &rates, 0.001).0;
            t += 0.001;
        }
        // 1 s + 0.1 s + 1 s.
        assert!((t - 2.1f32).abs() < 0.01, "{t}");
    }
}
