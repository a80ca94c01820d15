//! The regions of a 2-D sweep over (K_e, K_c), read from `points.csv`: where the runs are
//! bounded, where the lifted loop is linearly stable, and the cheapest pair of each by the
//! cost K_e·t_e + K_c·t_c.
//!
//! A region is taken as an *up-set* of the grid, the 2-D form of K_emp and K_lin: a pair
//! (K_e, K_c) belongs to the empirical region when every run is bounded at every grid pair
//! (K_e′, K_c′) with K_e′ ≥ K_e and K_c′ ≥ K_c, and to the linear region when ρ_lin < 1 at
//! every such pair. Neither the bounded fraction nor ρ_lin need be monotone (PG's ρ_lin
//! alternates with the parity of K_c), so a pair that passes alone, below one that fails,
//! does not count. An up-set is described by its boundary, a staircase: for each grid K_e
//! the smallest K_c of the region (None when the region has no pair at that K_e); it is
//! non-increasing in K_e. The joint certificate's region (issue 16) has the same form
//! ([`super::certified_boundary`]).
//!
//! Because the cost is increasing in both budgets, the cheapest pair of an up-set lies on
//! its staircase. Ties are broken by the smaller K_e, then the smaller K_c.

use std::fmt::Write as _;

#[cfg(feature = "serde")]
use serde::Serialize;

use super::format::Table;

/// The weights of the cost K_e·t_e + K_c·t_c of a pair: the time of one MHE iteration and
/// of one MPC iteration, or any proportional numbers (`cost = { t_e, t_c }` in the config;
/// default 1:1, i.e. the cost is K_e + K_c).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct IterationCost {
    /// Cost of one iteration of the MHE's Φ (per time step).
    pub t_e: f64,
    /// Cost of one iteration of the MPC's Φ (per time step).
    pub t_c: f64,
}

impl Default for IterationCost {
    fn default() -> Self {
        Self { t_e: 1.0, t_c: 1.0 }
    }
}

impl IterationCost {
    /// K_e·t_e + K_c·t_c.
    pub fn of(&self, k_e: usize, k_c: usize) -> f64 {
        k_e as f64 * self.t_e + k_c as f64 * self.t_c
    }
}

/// A staircase: for each K_e (ascending), the smallest K_c of a region at that K_e, or None
/// when no K_c is in the region there.
pub type Staircase = Vec<(usize, Option<usize>)>;

/// One pair (K_e, K_c) with its cost.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Pair {
    /// Iterations of the MHE.
    pub k_e: usize,
    /// Iterations of the MPC.
    pub k_c: usize,
    /// K_e·t_e + K_c·t_c.
    pub cost: f64,
}

/// The 2-D thresholds of one MHE solver at one disturbance scale.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct PairThresholds {
    /// Φ of the MHE (its name in `points.csv`).
    pub solver: String,
    /// The disturbance scale (as written in `points.csv`).
    pub scale: String,
    /// The K_e grid (ascending).
    pub k_e_grid: Vec<usize>,
    /// The K_c grid (ascending).
    pub k_c_grid: Vec<usize>,
    /// The weights of the cost.
    pub cost: IterationCost,
    /// The empirical region's staircase: every run bounded at every grid pair above.
    pub empirical_boundary: Staircase,
    /// The cheapest pair of the empirical region (None: the region is empty).
    pub cheapest_empirical: Option<Pair>,
    /// The linear region's staircase: ρ_lin < 1 at every grid pair above (None: ρ_lin is
    /// missing at some grid pair, e.g. `linear = false`).
    pub linear_boundary: Option<Staircase>,
    /// The cheapest pair of the linear region (None: empty or not available).
    pub cheapest_linear: Option<Pair>,
    /// The joint certificate's staircase as given (empty: not computed).
    pub certified_boundary: Staircase,
    /// The cheapest certified pair (None: not computed, or nothing certified).
    pub cheapest_certified: Option<Pair>,
    /// Per grid K_c, K_reg: the smallest K_e whose regional certificate (with this K_c-iteration
    /// MPC) contains the scenario's uncertainty (the `k_reg` column; None: none, see
    /// `regional_note`). K_reg need not lie on the K_e grid: the certificate is evaluated there.
    pub regional: Vec<(usize, Option<usize>)>,
    /// The cheapest (K_reg, K_c) pair (None: no K_c with a K_reg). Regional: it holds for the
    /// scenario's own uncertainty, not for every initial condition.
    pub cheapest_regional: Option<Pair>,
}

/// The up-set of `pass` on a grid (`pass[i][j]`: K_e index i, K_c index j): (i, j) is in it
/// when `pass` holds at every (i′ ≥ i, j′ ≥ j).
///
/// ```
/// use mhe_sweep::up_set;
/// // K_c index 1 passes at K_e index 0 alone, but fails at K_e index 1: not in the up-set.
/// let pass = vec![vec![false, true, true], vec![true, false, true]];
/// assert_eq!(up_set(&pass), vec![vec![false, false, true], vec![false, false, true]]);
/// ```
pub fn up_set(pass: &[Vec<bool>]) -> Vec<Vec<bool>> {
    let mut r: Vec<Vec<bool>> = pass.to_vec();
    for i in (0..r.len()).rev() {
        for j in (0..r[i].len()).rev() {
            let right = r.get(i + 1).and_then(|row| row.get(j)).copied();
            let up = r[i].get(j + 1).copied();
            r[i][j] = r[i][j] && right.unwrap_or(true) && up.unwrap_or(true);
        }
    }
    r
}

/// The staircase of a region on the grid: for each K_e, the smallest K_c with
/// `region[i][j]`.
pub fn staircase(k_e: &[usize], k_c: &[usize], region: &[Vec<bool>]) -> Staircase {
    k_e.iter()
        .enumerate()
        .map(|(i, &ke)| {
            let j = region
                .get(i)
                .and_then(|row| row.iter().position(|&b| b))
                .and_then(|j| k_c.get(j).copied());
            (ke, j)
        })
        .collect()
}

/// The cheapest pair on a staircase (the cheapest of its up-set, for a cost increasing in
/// both budgets); ties go to the smaller K_e, then the smaller K_c.
///
/// ```
/// use mhe_sweep::{IterationCost, cheapest_pair};
/// let stairs = [(1, None), (10, Some(20)), (100, Some(2))];
/// let p = cheapest_pair(&stairs, IterationCost::default()).unwrap();
/// assert_eq!((p.k_e, p.k_c, p.cost), (10, 20, 30.0));
/// let p = cheapest_pair(&stairs, IterationCost { t_e: 0.01, t_c: 1.0 }).unwrap();
/// assert_eq!((p.k_e, p.k_c), (100, 2));
/// ```
pub fn cheapest_pair(stairs: &[(usize, Option<usize>)], cost: IterationCost) -> Option<Pair> {
    stairs
        .iter()
        .filter_map(|&(k_e, k_c)| {
            k_c.map(|k_c| Pair {
                k_e,
                k_c,
                cost: cost.of(k_e, k_c),
            })
        })
        .min_by(|a, b| {
            a.cost
                .total_cmp(&b.cost)
                .then(a.k_e.cmp(&b.k_e))
                .then(a.k_c.cmp(&b.k_c))
        })
}

/// One grid pair of `points.csv`: (K_e, K_c, bounded fraction, ρ_lin).
type GridCell = (usize, usize, f64, Option<f64>);

/// One (solver, scale) grid of `points.csv`.
struct Grid {
    solver: String,
    scale: String,
    cells: Vec<GridCell>,
    /// (K_c, K_reg) as the points give it.
    regional: Vec<(usize, Option<usize>)>,
}

/// The 2-D thresholds per (scale, solver), in the order of `points.csv` (a table without a
/// `k_c` column, a 1-D sweep, gives none). `certified` holds the joint certificate's
/// staircase per solver name (missing or empty: not computed).
///
/// ```
/// use mhe_sweep::{IterationCost, Table, pair_thresholds};
/// let csv = "point,k,k_c,solver,scale,bounded_fraction,rho_lin\n\
///            0,1,1,pg,1,0.5,1.2\n1,10,1,pg,1,1,1.1\n2,1,5,pg,1,1,0.9\n3,10,5,pg,1,1,0.8\n";
/// let t = pair_thresholds(&Table::parse(csv).unwrap(), IterationCost::default(), &[]);
/// assert_eq!(t[0].empirical_boundary, vec![(1, Some(5)), (10, Some(1))]);
/// assert_eq!(t[0].linear_boundary, Some(vec![(1, Some(5)), (10, Some(5))]));
/// let e = t[0].cheapest_empirical.unwrap();
/// assert_eq!((e.k_e, e.k_c), (1, 5));
/// assert!(t[0].cheapest_certified.is_none());
/// ```
pub fn pair_thresholds(
    table: &Table,
    cost: IterationCost,
    certified: &[(String, Staircase)],
) -> Vec<PairThresholds> {
    if table.column("k_c").is_none() {
        return Vec::new();
    }
    let mut grids: Vec<Grid> = Vec::new();
    for row in 0..table.rows.len() {
        let int = |name| table.text(row, name).and_then(|v| v.parse::<usize>().ok());
        let (Some(solver), Some(scale), Some(k_e), Some(k_c)) = (
            table.text(row, "solver"),
            table.text(row, "scale"),
            int("k"),
            int("k_c"),
        ) else {
            continue;
        };
        let fraction = table.number(row, "bounded_fraction").unwrap_or(0.0);
        let rho = table.number(row, "rho_lin");
        let i = match grids
            .iter()
            .position(|g| g.solver == solver && g.scale == scale)
        {
            Some(i) => i,
            None => {
                grids.push(Grid {
                    solver: solver.to_string(),
                    scale: scale.to_string(),
                    cells: Vec::new(),
                    regional: Vec::new(),
                });
                grids.len() - 1
            }
        };
        grids[i].cells.push((k_e, k_c, fraction, rho));
        if !grids[i].regional.iter().any(|r| r.0 == k_c) {
            grids[i].regional.push((k_c, int("k_reg")));
        }
    }
    grids
        .into_iter()
        .map(|g| thresholds_of(g, cost, certified))
        .collect()
}

fn thresholds_of(
    g: Grid,
    cost: IterationCost,
    certified: &[(String, Staircase)],
) -> PairThresholds {
    let axis = |f: fn(&GridCell) -> usize| {
        let mut v: Vec<usize> = g.cells.iter().map(f).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let (k_e, k_c) = (axis(|c| c.0), axis(|c| c.1));
    let cell = |i: usize, j: usize| {
        g.cells
            .iter()
            .find(|c| c.0 == k_e[i] && c.1 == k_c[j])
            .map(|c| (c.2, c.3))
    };
    let table = |f: &dyn Fn(Option<(f64, Option<f64>)>) -> bool| -> Vec<Vec<bool>> {
        (0..k_e.len())
            .map(|i| (0..k_c.len()).map(|j| f(cell(i, j))).collect())
            .collect()
    };
    let bounded = table(&|c| c.is_some_and(|(f, _)| f >= 1.0));
    let empirical_boundary = staircase(&k_e, &k_c, &up_set(&bounded));
    let linear_known = (0..k_e.len())
        .all(|i| (0..k_c.len()).all(|j| cell(i, j).is_some_and(|(_, rho)| rho.is_some())));
    let linear_boundary = linear_known.then(|| {
        let stable = table(&|c| c.is_some_and(|(_, rho)| rho.is_some_and(|r| r < 1.0)));
        staircase(&k_e, &k_c, &up_set(&stable))
    });
    let certified_boundary = certified
        .iter()
        .find(|(s, _)| *s == g.solver)
        .map(|(_, st)| st.clone())
        .unwrap_or_default();
    let mut regional = g.regional;
    regional.sort_unstable();
    // (K_reg, K_c) pairs in the staircase form (K_e, K_c) of `cheapest_pair`.
    let regional_pairs: Vec<(usize, Option<usize>)> = regional
        .iter()
        .filter_map(|&(k_c, k_reg)| k_reg.map(|k_e| (k_e, Some(k_c))))
        .collect();
    let cheapest_regional = cheapest_pair(&regional_pairs, cost);
    PairThresholds {
        regional,
        cheapest_regional,
        cheapest_empirical: cheapest_pair(&empirical_boundary, cost),
        cheapest_linear: linear_boundary
            .as_ref()
            .and_then(|st| cheapest_pair(st, cost)),
        cheapest_certified: cheapest_pair(&certified_boundary, cost),
        solver: g.solver,
        scale: g.scale,
        k_e_grid: k_e,
        k_c_grid: k_c,
        cost,
        empirical_boundary,
        linear_boundary,
        certified_boundary,
    }
}

/// A staircase as text: `K_e→K_c` per grid K_e, `—` where the region has no K_c.
pub fn staircase_text(st: &[(usize, Option<usize>)]) -> String {
    st.iter()
        .map(|(ke, kc)| match kc {
            Some(kc) => format!("{ke}→{kc}"),
            None => format!("{ke}→—"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The 2-D thresholds as a Markdown table, one row per solver and scale: each region's
/// staircase and cheapest pair.
pub fn pair_thresholds_markdown(rows: &[PairThresholds]) -> String {
    let pair = |p: Option<Pair>, missing: &str| match p {
        Some(p) => format!("({}, {}), cost {}", p.k_e, p.k_c, p.cost),
        None => missing.to_string(),
    };
    let mut s = String::from(
        "| solver | scale | cheapest empirical (K_e, K_c) | cheapest linear | cheapest certified | cheapest regional (K_reg, K_c) | empirical region K_e→K_c | linear region K_e→K_c |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for t in rows {
        let certified = if t.certified_boundary.is_empty() {
            "certificate: not computed"
        } else {
            "none certified on its grid"
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            t.solver,
            t.scale,
            pair(t.cheapest_empirical, "— (no all-bounded region)"),
            pair(
                t.cheapest_linear,
                if t.linear_boundary.is_some() {
                    "— (ρ_lin ≥ 1 at the largest pair)"
                } else {
                    "— (no linear analysis)"
                }
            ),
            pair(t.cheapest_certified, certified),
            pair(
                t.cheapest_regional,
                "— (no K_c with a K_reg: see `regional_note`)"
            ),
            staircase_text(&t.empirical_boundary),
            t.linear_boundary
                .as_deref()
                .map_or("—".to_string(), staircase_text),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// 3 K_e × 3 K_c with a hole: (K_e = 10, K_c = 5) is unbounded, so nothing at or below
    /// it in both budgets counts; ρ_lin alternates with K_c (parity), so only K_c = 20 is
    /// linearly stable at every larger pair.
    fn table(rho_missing: bool) -> Table {
        let mut csv = String::from("point,k,k_c,solver,scale,bounded_fraction,rho_lin\n");
        let mut i = 0;
        for (k_c, rho) in [(1, 1.3), (5, 0.9), (20, 0.95)] {
            for k_e in [1, 10, 100] {
                let f = if (k_e, k_c) == (10, 5) || k_c == 1 && k_e < 100 {
                    0.75
                } else {
                    1.0
                };
                let rho = if rho_missing && i == 4 {
                    String::new()
                } else if k_c == 5 && k_e == 100 {
                    "1.01".to_string()
                } else {
                    format!("{rho}")
                };
                csv.push_str(&format!("{i},{k_e},{k_c},admm,1,{f},{rho}\n"));
                i += 1;
            }
        }
        Table::parse(&csv).unwrap()
    }

    #[test]
    fn regions_are_up_sets_and_the_cheapest_pair_follows_the_weights() {
        let t = pair_thresholds(&table(false), IterationCost::default(), &[]);
        assert_eq!(t.len(), 1);
        let t = &t[0];
        assert_eq!(
            (t.k_e_grid.clone(), t.k_c_grid.clone()),
            (vec![1, 10, 100], vec![1, 5, 20])
        );
        assert_eq!(
            t.empirical_boundary,
            vec![(1, Some(20)), (10, Some(20)), (100, Some(1))]
        );
        assert_eq!(
            t.linear_boundary,
            Some(vec![(1, Some(20)), (10, Some(20)), (100, Some(20))])
        );
        let e = t.cheapest_empirical.unwrap();
        assert_eq!((e.k_e, e.k_c, e.cost), (1, 20, 21.0));
        let l = t.cheapest_linear.unwrap();
        assert_eq!((l.k_e, l.k_c), (1, 20));
        // MPC iterations ten times as expensive: K_e = 100, K_c = 1 (cost 110) beats 1 + 200.
        let heavy = IterationCost {
            t_e: 1.0,
            t_c: 10.0,
        };
        let t2 = pair_thresholds(&table(false), heavy, &[]);
        let e = t2[0].cheapest_empirical.unwrap();
        assert_eq!((e.k_e, e.k_c, e.cost), (100, 1, 110.0));
        // The certificate's staircase is taken as given; its cheapest pair by the same cost.
        let cert = vec![(
            "admm".to_string(),
            vec![(1, None), (10, Some(50)), (100, Some(5))],
        )];
        let t3 = pair_thresholds(&table(false), IterationCost::default(), &cert);
        let c = t3[0].cheapest_certified.unwrap();
        assert_eq!((c.k_e, c.k_c), (10, 50));
        let md = pair_thresholds_markdown(&t3);
        assert!(md.contains("| admm | 1 | (1, 20), cost 21 |"), "{md}");
        assert!(md.contains("(10, 50), cost 60"), "{md}");
        assert!(
            pair_thresholds_markdown(std::slice::from_ref(t)).contains("certificate: not computed")
        );
    }

    #[test]
    fn missing_rho_lin_leaves_the_linear_region_unknown() {
        let t = pair_thresholds(&table(true), IterationCost::default(), &[]);
        assert_eq!(t[0].linear_boundary, None);
        assert_eq!(t[0].cheapest_linear, None);
        assert!(pair_thresholds_markdown(&t).contains("no linear analysis"));
        // A 1-D table has no 2-D thresholds.
        let one_d = Table::parse("point,k,solver,scale,bounded_fraction\n0,1,pg,1,1\n").unwrap();
        assert!(pair_thresholds(&one_d, IterationCost::default(), &[]).is_empty());
    }
}
