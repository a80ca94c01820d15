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

#[cfg(test)]
mod tests {
    use super::*;

    /// The records write mhe-sweep's fields in their declaration order with the keys of the
    /// former `#[derive(Serialize)]` (meta.json unchanged): `k_c` absent in 1-D, null for
    /// `None`, staircases as `[K_e, K_c]` pairs.
    #[test]
    fn records_keep_the_keys_and_order_of_meta_json() {
        let t = Thresholds {
            solver: "pg".into(),
            scale: "1".into(),
            k_c: None,
            k_max: 30,
            k_lin: Some(4),
            k_reg: None,
            regional_note: "outside".into(),
            k_emp: Some(5),
            k_settle: None,
            k_cert: Some(12),
            void_reason: String::new(),
        };
        let json = serde_json::to_string(&thresholds(std::slice::from_ref(&t)))
            .expect("the record serialises");
        assert_eq!(
            json,
            r#"[{"solver":"pg","scale":"1","k_max":30,"k_lin":4,"k_reg":null,"regional_note":"outside","k_emp":5,"k_settle":null,"k_cert":12,"void_reason":""}]"#
        );
        let with_kc = Thresholds { k_c: Some(5), ..t };
        let json = serde_json::to_string(&ThresholdsRecord::from(&with_kc)).expect("serialises");
        assert!(
            json.starts_with(r#"{"solver":"pg","scale":"1","k_c":5,"k_max":30,"#),
            "{json}"
        );

        let pair = Pair {
            k_e: 3,
            k_c: 5,
            cost: 8.0,
        };
        let p = PairThresholds {
            solver: "fista".into(),
            scale: "0.5".into(),
            k_e_grid: vec![1, 3],
            k_c_grid: vec![5],
            cost: IterationCost { t_e: 1.0, t_c: 2.0 },
            empirical_boundary: vec![(1, None), (3, Some(5))],
            cheapest_empirical: Some(pair),
            linear_boundary: None,
            cheapest_linear: None,
            certified_boundary: Vec::new(),
            cheapest_certified: None,
            regional: vec![(5, Some(3))],
            cheapest_regional: Some(pair),
        };
        let json = serde_json::to_string(&pair_thresholds(std::slice::from_ref(&p)))
            .expect("the record serialises");
        assert_eq!(
            json,
            r#"[{"solver":"fista","scale":"0.5","k_e_grid":[1,3],"k_c_grid":[5],"cost":{"t_e":1.0,"t_c":2.0},"empirical_boundary":[[1,null],[3,5]],"cheapest_empirical":{"k_e":3,"k_c":5,"cost":8.0},"linear_boundary":null,"cheapest_linear":null,"certified_boundary":[],"cheapest_certified":null,"regional":[[5,3]],"cheapest_regional":{"k_e":3,"k_c":5,"cost":8.0}}]"#
        );
    }
}
