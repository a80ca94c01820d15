#![doc = include_str!("../README.md")]
//!
//! # Modules
//!
//! - [`chart`]: line charts and small multiples (the figures of `cargo xtask reproduce`).
//! - [`band`]: a metric over K per solver as a 5–95 % band with its median line, with the
//!   thresholds K_min, K_reg and K_lin as vertical lines (the plots of a 1-D sweep).
//! - [`heatmap`]: a value over the (K_e, K_c) grid of a 2-D sweep with the three region
//!   boundaries as staircases (the heat maps of a 2-D sweep).
//!
//! Every renderer is a pure function of its data: the same data give the same bytes, so the
//! output can be compared with a file (`tests/expected.rs`).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod band;
pub mod chart;
pub mod heatmap;

use std::fmt;

/// Why a figure was not drawn.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum PlotError {
    /// Every value of the figure is missing, non-finite, or ≤ 0 on a log axis.
    NoDrawablePoint {
        /// `chart` or `grid`.
        kind: &'static str,
        /// The figure's title.
        title: String,
    },
    /// A grid of small multiples with no panel or more than [`chart::MAX_PANELS`].
    PanelCount {
        /// The grid's title.
        title: String,
        /// How many panels it was given.
        panels: usize,
    },
    /// The drawing backend failed (it writes into a `String`, so this is not expected).
    Drawing {
        /// Which figure (e.g. "heat map `h.svg`").
        context: String,
        /// The backend's message.
        message: String,
    },
}

impl PlotError {
    /// A backend error of the figure named by `context`.
    pub(crate) fn drawing(context: &str, e: impl fmt::Display) -> Self {
        PlotError::Drawing {
            context: context.to_string(),
            message: e.to_string(),
        }
    }
}

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlotError::NoDrawablePoint { kind, title } => write!(
                f,
                "{kind} `{title}` has no drawable point (every value is missing, non-finite, or ≤ 0 on a log axis)"
            ),
            PlotError::PanelCount { title, panels } => write!(
                f,
                "grid `{title}` has {panels} panels (1 to {} can be drawn)",
                chart::MAX_PANELS
            ),
            PlotError::Drawing { context, message } => write!(f, "{context}: {message}"),
        }
    }
}

impl std::error::Error for PlotError {}

/// `s` cut to its first `n` characters with `…` appended when it is longer (legend entries,
/// notes under a chart, table cells).
pub fn shorten(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        s.chars().take(n).collect::<String>() + "…"
    }
}

/// A tick or cell label with at most 3 significant digits and no float noise (0.6, 1000,
/// 2.5e-5); zero and non-finite values as Rust prints them.
pub(crate) fn three_digits(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let digits = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_digit_labels() {
        assert_eq!(three_digits(0.6000000000000001), "0.6");
        assert_eq!(three_digits(1000.0), "1000");
        assert_eq!(three_digits(10.0), "10");
        assert_eq!(three_digits(0.125), "0.125");
        assert_eq!(three_digits(0.1234), "0.123");
        assert_eq!(three_digits(2.5e-5), "2.5e-5");
        assert_eq!(three_digits(0.0), "0");
    }

    #[test]
    fn shorten_counts_characters() {
        assert_eq!(shorten("ρ_lin ≥ 1", 9), "ρ_lin ≥ 1");
        assert_eq!(shorten("ρ_lin ≥ 1", 3), "ρ_l…");
    }
}
