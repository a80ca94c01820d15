//! What a reason says: its sentence (`Display`, the JSON's and the reports' form) and its
//! few words ([`PairReason::short`], what a table cell holds).

use super::{F32Void, PairReason};
use crate::certificate::precision::ScalarVoid;
use crate::outcome::VoidReason;

impl PairReason {
    /// The named reason in a few words (the whole sentence is its `Display`): what a table
    /// cell can hold — the export's survey, `reproduce`'s K_f32 column.
    ///
    /// ```
    /// use iss_certificate::coverage::{F32Void, PairReason};
    /// let r = PairReason::F32 { why: F32Void::NoK, then: None };
    /// assert_eq!(r.short(), "f32: no K with the rounding");
    /// ```
    pub fn short(&self) -> String {
        match self {
            PairReason::F32 { why, .. } => match why {
                F32Void::JointNoPair { k_c, .. } => {
                    format!("f32: no K_e at K_c = {k_c} with the rounding")
                }
                F32Void::NotCovered => "f32: the f64 certificate is void".into(),
                // Theorem 1's f32 arm (every method's K-step model); the global arm follows as
                // "; no global K" when it certifies none.
                F32Void::RoundingModel { .. } => "f32: the rounding model failed".into(),
                F32Void::Void(v) => match v {
                    // V-FISTA (plain or Jacobi) without its incremental rate, the structured
                    // product, general rows: the sentence names which.
                    ScalarVoid::NotCovered { .. } => "f32: no rounding model here".into(),
                    ScalarVoid::ContractionBroken { window, .. } => {
                        format!("f32: the rounding breaks the contraction (window m = {window})")
                    }
                    ScalarVoid::NoK { .. } => "f32: the rounding leaves Theorem 1 no room".into(),
                    ScalarVoid::ShiftedWarmStart => "f32: the shifted warm start".into(),
                    ScalarVoid::Theorem1 { .. } | ScalarVoid::VoidInF64 { .. } => {
                        "f32: void in f64".into()
                    }
                    _ => "f32: void".into(),
                },
                F32Void::NoK => "f32: no K with the rounding".into(),
            },
            PairReason::Global { then, global } => {
                // The global outcome's sentence names the budget when the budget cut it.
                let g = global.to_string();
                let g = if g.contains("not computed") {
                    "the global certificate not computed within the budget"
                } else {
                    "no global K"
                };
                then.as_ref()
                    .map_or_else(|| g.to_string(), |t| format!("{}; {g}", t.short()))
            }
            PairReason::Void(_) | PairReason::Violated(_) => "Theorem 1 void".into(),
            PairReason::NotComputed(_) => "not computed within the budget".into(),
            PairReason::Uncovered(_) => "no certificate covers the configuration".into(),
            PairReason::BelowF32KMin { k_min, .. } => format!("below the f32 K_min = {k_min}"),
            _ => "not certified".into(),
        }
    }
}

impl std::fmt::Display for PairReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Uncovered(why) => why.fmt(f),
            Self::Void(reasons) => f.write_str(&VoidReason::join(reasons)),
            Self::NotComputed(nc) => nc.fmt(f),
            Self::Violated(premises) => {
                for (i, p) in premises.iter().enumerate() {
                    if i > 0 {
                        f.write_str("; ")?;
                    }
                    write!(
                        f,
                        "{} fails (value {})",
                        p.premise,
                        lti_model::numfmt::sig4(p.value)
                    )?;
                }
                Ok(())
            }
            Self::NeedsKc => f.write_str("the joint certificate needs K_c"),
            Self::F32 { why, then: None } => write!(f, "f32: {why}"),
            Self::F32 {
                why,
                then: Some(then),
            } => write!(f, "f32: {why}; {then}"),
            Self::Global { then: None, global } => {
                write!(f, "the global loop certificate: {global}")
            }
            Self::Global {
                then: Some(then),
                global,
            } => write!(f, "{then}; the global loop certificate: {global}"),
            Self::Chain(why) => why.fmt(f),
            Self::BelowF32KMin { k, k_min } => write!(
                f,
                "f32: K = {k} is below the f32 K_min = {k_min} (Theorem 1 with the f32 rounding \
                 folded in)"
            ),
        }
    }
}
