//! Numbers and counts written for people and files: significant digits, fixed
//! decimals, explicit signs, counted nouns. Every command's text, the plant's and
//! the simulation's messages use these, so one number reads the same everywhere.

/// `x` to 6 significant digits, trailing zeros dropped: `0.982143`, `-1.88571`,
/// `1.5e-9`, `0`. Plain notation from 1e-4 to 1e6, scientific outside.
pub fn sig(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let magnitude = x.abs().log10().floor() as i32;
    if (-4..6).contains(&magnitude) {
        decimals(x, (5 - magnitude).max(0) as usize)
    } else {
        let s = format!("{x:.5e}");
        match s.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim_zeros(mantissa)),
            None => s,
        }
    }
}

/// The value of the last of the 6 significant digits [`sig`] writes of `x`
/// (`1e-7` for 0.0229999): the step of the numbers it can write there; 0 for 0
/// or a number not finite.
pub fn last_digit(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return 0.0;
    }
    10f64.powi(x.abs().log10().floor() as i32 - 5)
}

/// `x` with `places` decimals, for people (`12.00 V`, `0.0 rpm`): what rounds to
/// zero has no sign (`0.0`, never `-0.0`); `NaN`, `inf` as they are.
pub fn fixed(x: f64, places: usize) -> String {
    let s = format!("{x:.places$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => s,
    }
}

/// `x` rounded to `places` decimals and written as the shortest decimal of that
/// (trailing zeros dropped), for files: `0.03217` (not `0.032170000000000004`),
/// `3000`, `0` (a subnormal or `-0.0` too, never `-0`); `NaN`, `inf` as they are.
pub fn decimals(x: f64, places: usize) -> String {
    trim_zeros(&fixed(x, places))
}

/// `x` rounded to `places` decimals, as a number, for a quantity that is known
/// no finer (then shown with [`sig`]): `rounded(2.5e-19, 9)` is `0` (never `-0`),
/// `rounded(1.234567891e-7, 9)` is `1.23e-7`; a number too large to hold `places`
/// decimals (beyond 2^52 units of the last), `NaN` and `inf` as they are.
pub fn rounded(x: f64, places: i32) -> f64 {
    let scale = 10f64.powi(places);
    let units = x * scale;
    if !units.is_finite() || units.abs() >= 2f64.powi(52) {
        return x;
    }
    // `+ 0.0` turns a `-0.0` into `0.0`.
    units.round() / scale + 0.0
}

/// [`sig`] with an explicit sign: `+0.0123`, `-1.5`.
pub fn signed(x: f64) -> String {
    let s = sig(x);
    if x > 0.0 {
        format!("+{s}")
    } else {
        s
    }
}

/// `n` things for people: `1 row`, `5 rows` (`noun` the singular; the plural
/// adds an `s`).
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// `, 2 warnings` for the summary line on stderr, empty without warnings.
pub fn warning_count(warnings: &[String]) -> String {
    if warnings.is_empty() {
        String::new()
    } else {
        format!(", {}", count(warnings.len(), "warning"))
    }
}

/// [`fixed`] with an explicit sign where it is not zero: `+0.0123`, `-1.5000`,
/// `0.0000` (a travel that rounds to nothing has no sign).
pub fn fixed_signed(x: f64, places: usize) -> String {
    let s = fixed(x, places);
    if s.starts_with('-') || s.bytes().all(|b| b == b'0' || b == b'.') {
        s
    } else {
        format!("+{s}")
    }
}

/// A plane vector as `[x, y]` with [`sig`] numbers.
pub fn pair(v: [f64; 2]) -> String {
    format!("[{}, {}]", sig(v[0]), sig(v[1]))
}

/// Drops trailing zeros after a decimal point, and the point itself if bare.
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounded_drops_what_is_below_its_decimals() {
        assert_eq!(rounded(2.53331e-19, 9), 0.0);
        assert_eq!(rounded(-7.51015e-18, 9).to_bits(), 0f64.to_bits(), "no -0");
        assert_eq!(sig(rounded(1.234567891e-7, 9)), "1.23e-7");
        assert_eq!(sig(rounded(-0.0853493123456, 9)), "-0.0853493");
        assert_eq!(rounded(1e300, 9), 1e300);
        assert!(rounded(f64::NAN, 9).is_nan());
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.0), "0");
        assert_eq!(sig(0.98214285714), "0.982143");
        assert_eq!(sig(-1.885714285), "-1.88571");
        assert_eq!(sig(5.0), "5");
        assert_eq!(sig(123456.7), "123457");
        assert_eq!(sig(1234567.0), "1.23457e6");
        assert_eq!(sig(1.5e-9), "1.5e-9");
        assert_eq!(sig(-1e-20), "-1e-20");
        assert_eq!(sig(0.0001), "0.0001");
        assert_eq!(signed(0.0123), "+0.0123");
        assert_eq!(sig(-1e-7), "-1e-7");
        assert_eq!(sig(-0.0000001234567), "-1.23457e-7");
    }

    #[test]
    fn the_last_of_six_digits() {
        assert_eq!(last_digit(0.0229999), 1e-7);
        assert_eq!(last_digit(-123456.7), 1.0);
        assert_eq!(last_digit(7.5e-6), 1e-11);
        assert_eq!(last_digit(0.0), 0.0);
        assert_eq!(last_digit(f64::NAN), 0.0);
    }

    /// `device-sim` printed `-0.0000 m` for a travel of -3e-6 m, and `table read`
    /// "1 rows".
    #[test]
    fn signed_fixed_and_counts() {
        assert_eq!(fixed_signed(-3e-6, 4), "0.0000");
        assert_eq!(fixed_signed(0.0, 4), "0.0000");
        assert_eq!(fixed_signed(0.01234, 4), "+0.0123");
        assert_eq!(fixed_signed(-1.5, 4), "-1.5000");
        assert_eq!(count(1, "row"), "1 row");
        assert_eq!(count(0, "row"), "0 rows");
        assert_eq!(count(5, "row"), "5 rows");
    }

    #[test]
    fn fixed_decimals_never_print_a_negative_zero() {
        assert_eq!(fixed(-0.0, 1), "0.0");
        assert_eq!(fixed(-0.04, 1), "0.0");
        assert_eq!(fixed(-0.05001, 1), "-0.1");
        assert_eq!(fixed(2999.96, 1), "3000.0");
        assert_eq!(fixed(f64::NAN, 3), "NaN");
    }

    #[test]
    fn decimals_are_the_shortest_form_of_the_rounded_value() {
        // 128.68 mm in 4 s.
        assert_eq!(decimals(128.68 * 1e-3 / 4.0, 6), "0.03217");
        assert_eq!(decimals(f64::from(2.7e-44_f32), 3), "0");
        assert_eq!(decimals(-1e-300, 3), "0");
        assert_eq!(decimals(3000.0, 3), "3000");
        assert_eq!(decimals(f64::from(3000.0913_f32), 3), "3000.091");
        assert_eq!(decimals(-0.0230407715, 3), "-0.023");
        assert_eq!(decimals(f64::NAN, 3), "NaN");
    }
}
