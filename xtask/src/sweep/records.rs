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
        // The outcome types are #[non_exhaustive]: start from mhe-sweep's own results and set
        // every field the record writes.
        let csv = "point,k,solver,scale,bounded_fraction\n0,1,pg,1,0.5\n";
        let mut t = mhe_sweep::thresholds(&mhe_sweep::Table::parse(csv).expect("csv"))[0].clone();
        t.solver = "pg".into();
        t.scale = "1".into();
        t.k_c = None;
        t.k_max = 30;
        t.k_lin = Some(4);
        t.k_reg = None;
        t.regional_note = "outside".into();
        t.k_emp = Some(5);
        t.k_settle = None;
        t.k_cert = Some(12);
        t.void_reason = String::new();
        let json = serde_json::to_string(&thresholds(std::slice::from_ref(&t)))
            .expect("the record serialises");
        assert_eq!(
            json,
            r#"[{"solver":"pg","scale":"1","k_max":30,"k_lin":4,"k_reg":null,"regional_note":"outside","k_emp":5,"k_settle":null,"k_cert":12,"void_reason":""}]"#
        );
        let mut with_kc = t.clone();
        with_kc.k_c = Some(5);
        let json = serde_json::to_string(&ThresholdsRecord::from(&with_kc)).expect("serialises");
        assert!(
            json.starts_with(r#"{"solver":"pg","scale":"1","k_c":5,"k_max":30,"#),
            "{json}"
        );

        let cost = IterationCost { t_e: 1.0, t_c: 1.0 };
        let pair = mhe_sweep::cheapest_pair(&[(3, Some(5))], cost).expect("a pair");
        let csv = "point,k,k_c,solver,scale,bounded_fraction\n0,1,5,fista,0.5,1\n";
        let table = mhe_sweep::Table::parse(csv).expect("csv");
        let mut p = mhe_sweep::pair_thresholds(&table, cost, &[])[0].clone();
        p.k_e_grid = vec![1, 3];
        p.k_c_grid = vec![5];
        p.cost = IterationCost { t_e: 1.0, t_c: 2.0 };
        p.empirical_boundary = vec![(1, None), (3, Some(5))];
        p.cheapest_empirical = Some(pair);
        p.linear_boundary = None;
        p.cheapest_linear = None;
        p.certified_boundary = Vec::new();
        p.cheapest_certified = None;
        p.regional = vec![(5, Some(3))];
        p.cheapest_regional = Some(pair);
        let json = serde_json::to_string(&pair_thresholds(std::slice::from_ref(&p)))
            .expect("the record serialises");
        assert_eq!(
            json,
            r#"[{"solver":"fista","scale":"0.5","k_e_grid":[1,3],"k_c_grid":[5],"cost":{"t_e":1.0,"t_c":2.0},"empirical_boundary":[[1,null],[3,5]],"cheapest_empirical":{"k_e":3,"k_c":5,"cost":8.0},"linear_boundary":null,"cheapest_linear":null,"certified_boundary":[],"cheapest_certified":null,"regional":[[5,3]],"cheapest_regional":{"k_e":3,"k_c":5,"cost":8.0}}]"#
        );
    }
}
