//! meta.json's records of the thresholds (`thresholds`, `pair_thresholds`): the file's own
//! serialisation types, converted from mhe-sweep's, so the library's types can grow without
//! changing meta.json (mhe-sweep builds without its `serde` feature here).

use mhe_sweep::{IterationCost, Pair, PairThresholds, Staircase, Thresholds};
use serde::Serialize;

/// One solver and scale of `thresholds` ([`Thresholds`]' fields, in its order).
#[derive(Debug, Serialize)]
pub(super) struct ThresholdsRecord<'a> {
    solver: &'a str,
    scale: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    k_c: Option<usize>,
    k_max: usize,
    k_lin: Option<usize>,
    k_reg: Option<usize>,
    regional_note: &'a str,
    k_emp: Option<usize>,
    k_settle: Option<usize>,
    k_cert: Option<usize>,
    void_reason: &'a str,
}

impl<'a> From<&'a Thresholds> for ThresholdsRecord<'a> {
    fn from(t: &'a Thresholds) -> Self {
        Self {
            solver: &t.solver,
            scale: &t.scale,
            k_c: t.k_c,
            k_max: t.k_max,
            k_lin: t.k_lin,
            k_reg: t.k_reg,
            regional_note: &t.regional_note,
            k_emp: t.k_emp,
            k_settle: t.k_settle,
            k_cert: t.k_cert,
            void_reason: &t.void_reason,
        }
    }
}

/// The weights of the cost K_e·t_e + K_c·t_c.
#[derive(Debug, Serialize)]
struct CostRecord {
    t_e: f64,
    t_c: f64,
}

impl From<&IterationCost> for CostRecord {
    fn from(c: &IterationCost) -> Self {
        Self {
            t_e: c.t_e,
            t_c: c.t_c,
        }
    }
}

/// A pair (K_e, K_c) with its cost.
#[derive(Debug, Serialize)]
struct PairRecord {
    k_e: usize,
    k_c: usize,
    cost: f64,
}

impl From<&Pair> for PairRecord {
    fn from(p: &Pair) -> Self {
        Self {
            k_e: p.k_e,
            k_c: p.k_c,
            cost: p.cost,
        }
    }
}

fn pair(p: Option<&Pair>) -> Option<PairRecord> {
    p.map(PairRecord::from)
}

/// One solver and scale of `pair_thresholds` ([`PairThresholds`]' fields, in its order).
#[derive(Debug, Serialize)]
pub(super) struct PairThresholdsRecord<'a> {
    solver: &'a str,
    scale: &'a str,
    k_e_grid: &'a [usize],
    k_c_grid: &'a [usize],
    cost: CostRecord,
    empirical_boundary: &'a Staircase,
    cheapest_empirical: Option<PairRecord>,
    linear_boundary: Option<&'a Staircase>,
    cheapest_linear: Option<PairRecord>,
    certified_boundary: &'a Staircase,
    cheapest_certified: Option<PairRecord>,
    regional: &'a [(usize, Option<usize>)],
    cheapest_regional: Option<PairRecord>,
}

impl<'a> From<&'a PairThresholds> for PairThresholdsRecord<'a> {
    fn from(t: &'a PairThresholds) -> Self {
        Self {
            solver: &t.solver,
            scale: &t.scale,
            k_e_grid: &t.k_e_grid,
            k_c_grid: &t.k_c_grid,
            cost: CostRecord::from(&t.cost),
            empirical_boundary: &t.empirical_boundary,
            cheapest_empirical: pair(t.cheapest_empirical.as_ref()),
            linear_boundary: t.linear_boundary.as_ref(),
            cheapest_linear: pair(t.cheapest_linear.as_ref()),
            certified_boundary: &t.certified_boundary,
            cheapest_certified: pair(t.cheapest_certified.as_ref()),
            regional: &t.regional,
            cheapest_regional: pair(t.cheapest_regional.as_ref()),
        }
    }
}

/// `thresholds` of meta.json.
pub(super) fn thresholds(v: &[Thresholds]) -> Vec<ThresholdsRecord<'_>> {
    v.iter().map(ThresholdsRecord::from).collect()
}

/// `pair_thresholds` of meta.json.
pub(super) fn pair_thresholds(v: &[PairThresholds]) -> Vec<PairThresholdsRecord<'_>> {
    v.iter().map(PairThresholdsRecord::from).collect()
}
