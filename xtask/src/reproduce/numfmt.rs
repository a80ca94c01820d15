//! Numbers for reading (the terminal summary) and for machines (trace.csv).
//!
//! - [`num`]: at most 4 significant digits; plain between 10⁻³ and 10⁴, scientific outside
//!   (`1.435`, `0.0738`, `2.14e-5`, `1.2e48`); `inf`, `-inf`, `nan` spelled out.
//! - [`rate`]: a contraction rate close to 1 as `(1 − 1.47e-4)`, so that four digits still
//!   tell it from 1.
//! - [`csv`]: every digit (shortest round-trip form), `nan`/`inf`/`-inf` explicitly.

/// `v` with at most 4 significant digits (module docs): [`lti_model::numfmt::sig4`], the one
/// formatter of terminal numbers in every crate.
pub(crate) fn num(v: f64) -> String {
    lti_model::numfmt::sig4(v)
}

/// A rate in (0, 1): [`num`], or `(1 − d)` when 1 − rate < 0.01 (then 4 digits of the rate
/// itself would hide how close to 1 it is).
pub(crate) fn rate(r: f64) -> String {
    if r.is_finite() && r < 1.0 && 1.0 - r < 0.01 {
        format!("(1 − {})", num(1.0 - r))
    } else {
        num(r)
    }
}

/// An optional number: [`num`] or `-`.
pub(crate) fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), num)
}

/// A CSV field: the shortest text that parses back to the same `f64` (`0.1`, `1e-7`,
/// `1.5e300`), and `nan`, `inf`, `-inf` for the non-finite values.
pub(crate) fn csv(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        // Debug of f64 is the shortest round-trip form and switches to an exponent for very
        // large or small magnitudes (Display would print 300 zeros).
        format!("{v:?}")
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn terminal_numbers_have_at_most_four_significant_digits() {
        for (v, s) in [
            (0.7380, "0.738"),
            (1.43512, "1.435"),
            (31.377838, "31.38"),
            (1234.56, "1235"),
            (9999.7, "1e4"),
            (0.023772, "0.02377"),
            (0.001167, "0.001167"),
            (0.000999, "9.99e-4"),
            (2.140e-5, "2.14e-5"),
            (4.154e-11, "4.154e-11"),
            (-0.5, "-0.5"),
            (40.0, "40"),
            (0.0, "0"),
            (1e4, "1e4"),
            (123_456.0, "1.235e5"),
            // The 49-digit sup‖e‖ of a diverged run.
            (1.2345678e48, "1.235e48"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
            (f64::NAN, "nan"),
        ] {
            assert_eq!(num(v), s, "{v:e}");
        }
        // Never more than 4 significant digits, never longer than 10 characters.
        let mut x = 1.234_567_890_123e-300;
        while x < 1e300 {
            let s = num(x);
            let digits = s
                .split('e')
                .next()
                .unwrap_or("")
                .chars()
                .filter(char::is_ascii_digit)
                .collect::<String>();
            let significant = digits.trim_start_matches('0').len();
            assert!(significant <= 4 && s.len() <= 10, "{x:e} → {s}");
            x *= 7.3;
        }
    }

    #[test]
    fn rates_near_one_show_their_distance_to_one() {
        assert_eq!(rate(0.999853), "(1 − 1.47e-4)");
        assert_eq!(rate(0.995703), "(1 − 0.004297)");
        assert_eq!(rate(0.98), "0.98");
        assert_eq!(rate(1.0), "1");
        assert_eq!(opt(None), "-");
        assert_eq!(opt(Some(0.5)), "0.5");
    }

    #[test]
    fn csv_fields_round_trip_and_spell_out_non_finite_values() {
        for v in [0.1, -3.0, 1e-7, 1.5e300, 5e-324, 0.0, 123.456, f64::MAX] {
            let s = csv(v);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
            assert!(s.len() < 30, "{s}");
        }
        assert_eq!(csv(f64::NAN), "nan");
        assert_eq!(csv(f64::INFINITY), "inf");
        assert_eq!(csv(f64::NEG_INFINITY), "-inf");
    }
}
