//! Numbers in messages: plain where that is short, in exponent form otherwise, so that a
//! value such as `1e-300` is not printed as 300 digits (or as `0.0000`).

use std::fmt;

/// A number as messages print it: plain where that is short (1e-3 <= |v| < 1e7, and
/// zero, infinities and NaN), in exponent form otherwise. A precision applies to either
/// form: `format!("{:.3}", Number(v))` gives `0.123` or `1.235e-7`.
#[derive(Clone, Copy, Debug)]
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        let plain = v == 0.0 || !v.is_finite() || (1e-3..1e7).contains(&v.abs());
        match (plain, f.precision()) {
            (true, None) => write!(f, "{v}"),
            (true, Some(p)) => write!(f, "{v:.p$}"),
            (false, None) => write!(f, "{v:e}"),
            (false, Some(p)) => write!(f, "{v:.p$e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Number;

    #[test]
    fn short_numbers_are_plain_and_extreme_ones_in_exponent_form() {
        let text = |v: f64| Number(v).to_string();
        assert_eq!(text(0.0), "0");
        assert_eq!(text(0.5), "0.5");
        assert_eq!(text(-2650.0), "-2650");
        assert_eq!(text(1e-3), "0.001");
        assert_eq!(text(9.99e-4), "9.99e-4");
        assert_eq!(text(1e7), "1e7");
        assert_eq!(text(1e-300), "1e-300");
        assert_eq!(text(-1.7e308), "-1.7e308");
        assert_eq!(text(f64::MIN_POSITIVE / 4.0), "5.562684646268003e-309");
        assert_eq!(text(f64::INFINITY), "inf");
        assert_eq!(text(f64::NAN), "NaN");
        assert!(text(f64::MAX).len() < 30);
    }

    #[test]
    fn a_precision_applies_to_either_form() {
        assert_eq!(format!("{:.3}", Number(0.12345)), "0.123");
        assert_eq!(format!("{:.3}", Number(1.23456e-7)), "1.235e-7");
        assert_eq!(format!("{:.1}", Number(1e300)), "1.0e300");
        assert_eq!(format!("{:.2}", Number(0.0)), "0.00");
    }
}
