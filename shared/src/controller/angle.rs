//! Angles and speeds: wrapping on the circle, circular interpolation, unit changes.
//!
//! Offsets are in degrees, as docs/machine-file.md ("Conventions") gives them: a
//! phase offset lives in [0, 360), a phase error in (-180, 180]. Everything here is
//! linear arithmetic and `floor` (libm, exact): no trigonometry, so nothing depends on
//! micromath's approximations.

/// Degrees in a turn.
pub const TURN_DEG: f32 = 360.0;
/// Radians in a turn, `2 pi`.
pub const TURN_RAD: f32 = core::f32::consts::TAU;
/// rpm per rad/s: `60 / (2 pi)`.
pub const RPM_PER_RAD_S: f32 = 60.0 / core::f32::consts::TAU;
/// Degrees per radian: `180 / pi`.
pub const DEG_PER_RAD: f32 = 180.0 / core::f32::consts::PI;

/// `x` wrapped to [0, 360) degrees: `x - 360 floor(x / 360)`.
///
/// Rounding can give exactly 360 for a tiny negative `x`; that is returned as 0 so
/// the result is always inside the interval. A non-finite `x` gives 0.
#[inline]
pub fn wrap_deg(x: f32) -> f32 {
    // The usual cases, without the formula's division and floor but with its
    // result: inside already (an offset, or an offset plus one tick's step),
    // `floor(x / 360) = 0` and `r = x`; zero (the change of an error that did not
    // move), `r = +0` for either sign of zero; a turn below (a negative difference
    // of offsets), `floor(x / 360) = -1` and `r = x + 360` (then checked as below;
    // a tiny negative `x` rounds to 360 and gives 0, as the formula does).
    if x > 0.0 && x < TURN_DEG {
        return x;
    }
    if x == 0.0 {
        return 0.0;
    }
    if (-TURN_DEG..0.0).contains(&x) {
        let r = x + TURN_DEG;
        return if r < TURN_DEG { r } else { 0.0 };
    }
    wrap_deg_formula(x)
}

/// [`wrap_deg`] by its formula, for every `x`.
#[inline(never)]
fn wrap_deg_formula(x: f32) -> f32 {
    if !x.is_finite() {
        return 0.0;
    }
    let r = x - TURN_DEG * floor(x / TURN_DEG);
    if (0.0..TURN_DEG).contains(&r) {
        r
    } else {
        0.0
    }
}

/// `floor(y)`, the same value as `libm::floorf` (signed zeros and NaN included)
/// without its call: the Cortex-M4F has no rounding instruction, so `libm::floorf`
/// is a software routine of a few dozen instructions, run several times a control
/// tick. For `|y| < 2^23` the conversion to `i32` truncates exactly (one `vcvt`)
/// and a negative non-integer is then one too high; every `|y| >= 2^23` (and an
/// infinity) is already an integer, and NaN stays NaN.
fn floor(y: f32) -> f32 {
    if libm::fabsf(y) < 8_388_608.0 {
        let t = y as i32 as f32;
        if t > y {
            t - 1.0
        } else {
            // `t` has the sign of `y` except for a zero: floor(-0.0) = -0.0.
            libm::copysignf(t, y)
        }
    } else {
        y
    }
}

/// `x` wrapped to (-180, 180] degrees: the signed angle of the shorter arc, with an
/// exact half turn counted as +180. A non-finite `x` gives 0.
#[inline]
pub fn wrap_deg_signed(x: f32) -> f32 {
    let r = wrap_deg(x);
    if r > 180.0 {
        r - TURN_DEG
    } else {
        r
    }
}

/// [`wrap_deg`] in `f64`, for the host's measurements and summaries: `x`
/// wrapped to [0, 360) degrees as `x mod 360` (`%`, exact), a remainder that
/// rounds up to 360 (a tiny negative `x`) given as 0; `NaN` and the infinities
/// give `NaN`, so a number that is none is not mistaken for an offset. The
/// controller's `f32` one trades that for a path of few instructions.
pub fn wrap_deg_f64(x: f64) -> f64 {
    let r = x % 360.0;
    let r = if r < 0.0 { r + 360.0 } else { r };
    if r >= 360.0 {
        0.0
    } else {
        r
    }
}

/// [`wrap_deg_signed`] in `f64`: `x` wrapped to (-180, 180] degrees, from
/// [`wrap_deg_f64`] (`180 - wrap(180 - x)`, in [0, 360) mirrored).
pub fn wrap_deg_signed_f64(x: f64) -> f64 {
    180.0 - wrap_deg_f64(180.0 - x)
}

/// Circular interpolation between offsets `a` and `b` (degrees) at `t` in [0, 1],
/// along the shorter arc:
///
/// ```text
///   o(t) = wrap(a + t wrap_signed(b - a))
/// ```
///
/// e.g. 350 and 10 give 0 at `t = 0.5`, not 180. Offsets exactly opposite (a half
/// turn apart) go the increasing way (`wrap_signed` gives +180). The result is in
/// [0, 360).
pub fn lerp_deg(a: f32, b: f32, t: f32) -> f32 {
    wrap_deg(a + t * wrap_deg_signed(b - a))
}

/// rpm to rad/s.
pub fn rpm_to_rad_s(rpm: f32) -> f32 {
    rpm / RPM_PER_RAD_S
}

/// rad/s to rpm.
pub fn rad_s_to_rpm(rad_s: f32) -> f32 {
    rad_s * RPM_PER_RAD_S
}

/// Which side of the vertical line an offset lies on: `Some(true)` in (0, 180) (the
/// force leans right, as for rightward travel), `Some(false)` in (180, 360), `None`
/// on the line itself (0 or 180: a horizontal or vertical force).
pub fn leans_right(offset_deg: f32) -> Option<bool> {
    let o = wrap_deg(offset_deg);
    if o > 0.0 && o < 180.0 {
        Some(true)
    } else if o > 180.0 {
        Some(false)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `f64` wraps against the definition `x - 360 floor(x / 360)` (exact
    /// for these), at the ends of the intervals and far from them; what is no
    /// number stays none.
    #[test]
    fn the_f64_wraps_keep_their_intervals() {
        for (x, w) in [
            (0.0, 0.0),
            (360.0, 0.0),
            (-90.0, 270.0),
            (725.5, 5.5),
            (-1.0e-20, 0.0),
            (-720.0, 0.0),
            (1.0e6 + 0.25, 280.25),
        ] {
            assert_eq!(wrap_deg_f64(x), w, "{x}");
        }
        for (x, w) in [
            (180.0, 180.0),
            (-180.0, 180.0),
            (190.0, -170.0),
            (-190.0, 170.0),
            (540.0, 180.0),
        ] {
            assert_eq!(wrap_deg_signed_f64(x), w, "{x}");
        }
        assert!(wrap_deg_f64(f64::NAN).is_nan());
        assert!(wrap_deg_f64(f64::INFINITY).is_nan());
        let mut x = -1.0e4;
        while x < 1.0e4 {
            let w = wrap_deg_f64(x);
            assert!((0.0..360.0).contains(&w), "{x}: {w}");
            let s = wrap_deg_signed_f64(x);
            assert!(s > -180.0 && s <= 180.0, "{x}: {s}");
            x += 7.3;
        }
    }

    #[test]
    fn wrap_stays_in_range() {
        assert_eq!(wrap_deg(360.0), 0.0);
        assert_eq!(wrap_deg(-90.0), 270.0);
        assert_eq!(wrap_deg(725.0), 5.0);
        assert_eq!(wrap_deg(-1.0e-9), 0.0);
        assert_eq!(wrap_deg(f32::NAN), 0.0);
        assert_eq!(wrap_deg_signed(270.0), -90.0);
        assert_eq!(wrap_deg_signed(180.0), 180.0);
        assert_eq!(wrap_deg_signed(-180.0), 180.0);
    }

    #[test]
    fn floor_is_libm_floor() {
        let check = |y: f32| assert_eq!(floor(y).to_bits(), libm::floorf(y).to_bits(), "{y:e}");
        for y in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0e-9,
            1.0e-40,
            -1.0e-40,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            3.0e9,
            -3.0e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            check(y);
        }
        // A sweep of bit patterns across the magnitudes, both signs.
        let mut bits = 0x0000_0001u32;
        while bits < 0x7f80_0000 {
            check(f32::from_bits(bits));
            check(-f32::from_bits(bits));
            bits += 0x0000_0f31;
        }
        assert!(floor(f32::NAN).is_nan());
    }

    #[test]
    fn wrap_is_the_floor_formula() {
        let reference = |x: f32| {
            if !x.is_finite() {
                return 0.0;
            }
            let r = x - TURN_DEG * libm::floorf(x / TURN_DEG);
            if (0.0..TURN_DEG).contains(&r) {
                r
            } else {
                0.0
            }
        };
        let mut x = -2000.0f32;
        while x < 2000.0 {
            for y in [x, x.next_up(), x.next_down()] {
                assert_eq!(wrap_deg(y).to_bits(), reference(y).to_bits(), "{y}");
            }
            x += 0.37;
        }
        for y in [
            0.0, -0.0, 360.0, -360.0, 1.0e-40, -1.0e-40, 1.0e30, -1.0e30, 359.99997,
        ] {
            assert_eq!(wrap_deg(y).to_bits(), reference(y).to_bits(), "{y}");
        }
    }

    #[test]
    fn lerp_takes_the_shorter_arc() {
        assert!((lerp_deg(350.0, 10.0, 0.5) - 0.0).abs() < 1e-4);
        assert!((lerp_deg(10.0, 350.0, 0.25) - 5.0).abs() < 1e-4);
        assert!((lerp_deg(80.0, 100.0, 0.5) - 90.0).abs() < 1e-4);
    }
}
