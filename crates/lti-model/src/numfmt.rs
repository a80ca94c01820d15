//! Numbers for people: [`sig4`], at most 4 significant digits, the one formatter of every
//! number a terminal message shows (issue 23 item 5; `xtask`'s summaries call it too). Files
//! (CSV, JSON) keep every digit.

/// `v` with at most 4 significant digits: plain between 10⁻³ and 10⁴, scientific outside
/// (`1.435`, `0.0738`, `2.14e-5`, `1.2e48`); trailing zeros dropped; `inf`, `-inf`, `nan`
/// spelled out.
///
/// ```
/// use lti_model::numfmt::sig4;
/// assert_eq!(sig4(0.942655), "0.9427");
/// assert_eq!(sig4(31.377838), "31.38");
/// assert_eq!(sig4(9999.7), "1e4");
/// assert_eq!(sig4(2.14e-5), "2.14e-5");
/// ```
pub fn sig4(v: f64) -> String {
    if v.is_nan() {
        return "nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf" } else { "-inf" }.into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        // Digits after the point for 4 significant ones; rounding can carry into a fifth
        // (9999.7 → 10000), which goes to the scientific form.
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        let rounded: f64 = s.parse().unwrap_or(v);
        if rounded.abs() < 1e4 {
            return trim_zeros(&s).to_string();
        }
    }
    let s = format!("{v:.3e}");
    match s.split_once('e') {
        Some((mantissa, exp)) => format!("{}e{exp}", trim_zeros(mantissa)),
        None => s,
    }
}

/// [`sig4`] rounded toward −∞ so that the number shown is strictly below `v`: for a hint
/// "lower η below X", X must itself be below the bound (`sig4(0.16667)` is `0.1667`, above
/// 1/6; `sig4_below(1.0 / 6.0)` is `0.1666`). At most 4 significant digits; `v` itself
/// when it is not finite.
///
/// ```
/// use lti_model::numfmt::sig4_below;
/// assert_eq!(sig4_below(1.0 / 6.0), "0.1666");
/// assert_eq!(sig4_below(0.6988), "0.6987");
/// assert_eq!(sig4_below(1.0), "0.999");
/// assert_eq!(sig4_below(-2.5e-7), "-2.501e-7");
/// ```
pub fn sig4_below(v: f64) -> String {
    if !v.is_finite() {
        return sig4(v);
    }
    let shown = sig4(v);
    if shown.parse::<f64>().is_ok_and(|x| x < v) {
        return shown;
    }
    // One unit of the 4th significant digit at v, then down the grid until below v.
    let step = if v == 0.0 {
        1e-3
    } else {
        10f64.powi(v.abs().log10().floor() as i32 - 3)
    };
    let mut x = (v / step).floor() * step;
    for _ in 0..4 {
        let t = sig4(x);
        if t.parse::<f64>().is_ok_and(|y| y < v) {
            return t;
        }
        x -= step;
    }
    sig4(x)
}

fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}
