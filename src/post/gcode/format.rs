//! Writing numbers into G-code words.
//!
//! A coordinate is written with just enough decimals that the rounding stays below the
//! share of the error budget Δ the caller gives it ([`decimals_for`]), because every
//! extra digit costs line length and, on grbl-family controllers, digits past the
//! ninth are dropped by the controller's number reader. Numbers are written the way
//! both LinuxCNC and grbl read them: an optional `-`, digits, an optional `.` and
//! digits; no exponent, no trailing zeros, no `-0`.

use thiserror::Error;

/// The most decimals a coordinate is written with: 10⁻⁶ mm is a nanometre, far below
/// what any whirling machine resolves, and more digits only lengthen lines.
pub const MAX_DECIMALS: u32 = 6;

/// Why no number of decimals fits a rounding bound.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum FormatError {
    /// The bound is zero, negative or not finite.
    #[error("rounding bound {bound} is not a positive finite number")]
    InvalidBound {
        /// The bound given.
        bound: f64,
    },
    /// Even [`MAX_DECIMALS`] decimals round by more than the bound.
    #[error(
        "rounding bound {bound} is too fine: {MAX_DECIMALS} decimals (the most written) \
         round by up to 0.5e-{MAX_DECIMALS}"
    )]
    TooFine {
        /// The bound given.
        bound: f64,
    },
}

/// The smallest number of decimals `d` whose rounding error 0.5·10⁻ᵈ is strictly below
/// `max_rounding_error` (in the unit of the numbers: mm for X and Z, degrees for C).
///
/// Errors if the bound is not positive and finite, or if it would need more than
/// [`MAX_DECIMALS`].
pub fn decimals_for(max_rounding_error: f64) -> Result<u32, FormatError> {
    if !(max_rounding_error.is_finite() && max_rounding_error > 0.0) {
        return Err(FormatError::InvalidBound {
            bound: max_rounding_error,
        });
    }
    // 10^d is exact in f64 for these d and the division is correctly rounded, so
    // 0.5 / 10^d is the f64 nearest to 0.5·10⁻ᵈ: the comparison is as exact as the
    // bound itself.
    (0..=MAX_DECIMALS)
        .find(|&d| 0.5 / 10f64.powi(d as i32) < max_rounding_error)
        .ok_or(FormatError::TooFine {
            bound: max_rounding_error,
        })
}

/// `value` rounded to `decimals` decimals (to nearest, as Rust's formatter does it on the
/// exact binary value), without trailing zeros and without a sign on zero:
/// `12.5`, `-0.0031`, `0`.
///
/// `value` must be finite; writers check that first (a non-finite value comes out as
/// Rust spells it, which no controller reads).
pub fn format_number(value: f64, decimals: u32) -> String {
    let mut text = format!("{:.*}", decimals as usize, value);
    if text.contains('.') {
        let trimmed = text.trim_end_matches('0').trim_end_matches('.').len();
        text.truncate(trimmed);
    }
    if text == "-0" {
        text = "0".to_owned();
    }
    text
}

/// Like [`format_number`], but the number written never exceeds `value` once read back:
/// it is `value` rounded down to `decimals` decimals. Used where the written number is a
/// bound that must hold (a blend tolerance, a feed rate that must not make a move faster).
pub fn format_number_down(value: f64, decimals: u32) -> String {
    let text = format_number(value, decimals);
    match text.parse::<f64>() {
        Ok(read) if read > value => format_number(read - 10f64.powi(-(decimals as i32)), decimals),
        _ => text,
    }
}

/// A positive `value` with `significant` significant digits, rounded down (see
/// [`format_number_down`]), so the relative rounding error is below 10^(1 − significant).
/// Numbers of `significant` or more integer digits are written as integers.
pub fn format_significant_down(value: f64, significant: u32) -> String {
    // `{:e}` gives the decimal exponent of the exact value: "1.25e-3" → -3.
    let scientific = format!("{value:e}");
    let exponent = scientific
        .rsplit_once('e')
        .and_then(|(_, e)| e.parse::<i32>().ok())
        .unwrap_or(0);
    let decimals = (significant as i32 - 1 - exponent).max(0) as u32;
    format_number_down(value, decimals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimals_are_the_smallest_whose_half_unit_is_strictly_below_the_bound() {
        // 0.5·10⁻³ = 0.0005 equals the bound, which is not strictly below: 4 decimals.
        assert_eq!(decimals_for(0.0005), Ok(4));
        assert_eq!(decimals_for(0.00051), Ok(3));
        assert_eq!(decimals_for(0.001), Ok(3));
        assert_eq!(decimals_for(0.01), Ok(2));
        assert_eq!(decimals_for(0.5), Ok(1));
        assert_eq!(decimals_for(0.6), Ok(0));
        assert_eq!(decimals_for(1e9), Ok(0));
        // A 10 µm budget with 5 µm for interpolation leaves 1 µm for rounding.
        assert_eq!(decimals_for(0.001), Ok(3));
        assert_eq!(decimals_for(0.000_000_6), Ok(6));
    }

    #[test]
    fn decimals_bound_is_checked() {
        assert_eq!(
            decimals_for(0.000_000_5),
            Err(FormatError::TooFine { bound: 0.000_000_5 })
        );
        assert!(matches!(
            decimals_for(0.0),
            Err(FormatError::InvalidBound { .. })
        ));
        assert!(matches!(
            decimals_for(-1.0),
            Err(FormatError::InvalidBound { .. })
        ));
        assert!(matches!(
            decimals_for(f64::NAN),
            Err(FormatError::InvalidBound { .. })
        ));
        assert!(matches!(
            decimals_for(f64::INFINITY),
            Err(FormatError::InvalidBound { .. })
        ));
    }

    #[test]
    fn decimals_for_keeps_the_rounding_below_the_bound() {
        for bound in [3e-6, 1e-5, 7e-5, 2e-4, 0.0049, 0.05, 0.3] {
            let d = decimals_for(bound).unwrap();
            for i in 0..1000 {
                let value = -50.0 + i as f64 * 0.1234567;
                let read: f64 = format_number(value, d).parse().unwrap();
                assert!((read - value).abs() < bound, "{value} at {d} decimals");
            }
        }
    }

    #[test]
    fn numbers_have_no_trailing_zeros_and_no_negative_zero() {
        assert_eq!(format_number(12.5, 3), "12.5");
        assert_eq!(format_number(-0.0031, 4), "-0.0031");
        assert_eq!(format_number(0.0, 3), "0");
        assert_eq!(format_number(-0.0, 3), "0");
        assert_eq!(format_number(-0.00004, 4), "0");
        assert_eq!(format_number(100.0, 3), "100");
        assert_eq!(format_number(100.0, 0), "100");
        assert_eq!(format_number(2.9996, 3), "3");
        assert_eq!(format_number(-7.25, 1), "-7.2"); // 7.25 is exact: ties go to even
        assert_eq!(format_number(1.0 / 3.0, 6), "0.333333");
    }

    #[test]
    fn rounding_down_never_exceeds_the_value() {
        assert_eq!(format_number_down(0.0015, 3), "0.001");
        assert_eq!(format_number_down(0.00199, 3), "0.001");
        assert_eq!(format_number_down(0.001, 3), "0.001");
        assert_eq!(format_number_down(2.0, 6), "2");
        for i in 1..2000 {
            let value = i as f64 * 0.000_731;
            let read: f64 = format_number_down(value, 4).parse().unwrap();
            assert!(read <= value && value - read < 1e-4, "{value}");
        }
    }

    #[test]
    fn significant_digits_bound_the_relative_error() {
        assert_eq!(format_significant_down(1234.5678, 6), "1234.56");
        assert_eq!(format_significant_down(0.000123456789, 6), "0.000123456");
        assert_eq!(format_significant_down(98765432.1, 6), "98765432");
        assert_eq!(format_significant_down(20.0, 6), "20");
        for i in 1..5000 {
            let value = 1.0 / (i as f64 * 0.0137);
            let read: f64 = format_significant_down(value, 6).parse().unwrap();
            assert!(read <= value, "{value}");
            assert!((value - read) / value < 1e-5, "{value}");
        }
    }
}
