//! The three thresholds of a sweep per solver and scale (and per K_c in a 2-D sweep: each
//! K_c is a curve over K_e), read from `points.csv`:
//! K_lin (ρ_lin < 1: necessary for local asymptotic stability of the origin when no
//! constraint is active there; a saturated loop can stay bounded below it), K_reg (the regional certificate: sufficient inside a
//! region that contains the scenario's uncertainty), K_emp (what the runs show) and K_cert
//! (Theorem 1, sufficient globally), with the ratios K_reg/K_lin, K_cert/K_lin,
//! K_cert/K_emp and K_emp/K_lin.
//!
//! K_emp is the smallest grid K from which *every* grid K above has every run bounded
//! (bounded covers x and e, and a diverged or failed run is never bounded): the bounded
//! fraction need not be monotone in K, so a K with fraction 1 below an unbounded one does
//! not count. K_emp depends on the grid, the seeds, T and the noise; it can lie below K_lin
//! when the constraints (a saturating 𝒲) hold a linearly unstable loop in, or when T is
//! too short for a slow linear divergence to pass the bounded threshold.
//!
//! Bounded is a coarse test (a factor 1000 by default): a linearly unstable loop held in by
//! a saturating 𝒲 stays bounded with an error many times its large-K level. K_settle shows
//! that: the smallest grid K from which the median last-quarter error (`tail_mean_e_q50`)
//! is within [`SETTLE_TOLERANCE`] of its value at the largest grid K, at every larger K.

use std::fmt::Write as _;

#[cfg(feature = "serde")]
use serde::Serialize;

use super::format::Table;

/// K_settle's tolerance: the median last-quarter ‖e‖ within 10 % of its largest-K level.
pub const SETTLE_TOLERANCE: f64 = 0.1;

/// The thresholds of one solver at one disturbance scale.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Thresholds {
    /// Φ of the MHE (its name in `points.csv`).
    pub solver: String,
    /// The disturbance scale (as written in `points.csv`).
    pub scale: String,
    /// K_c of the curve in a 2-D sweep (absent in a 1-D sweep).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub k_c: Option<usize>,
    /// The largest K of the grid.
    pub k_max: usize,
    /// K_lin of the linear analysis on the grid (None: ρ_lin ≥ 1 at the largest K, or no
    /// analysis).
    pub k_lin: Option<usize>,
    /// K_reg: the smallest K whose regional certificate contains the scenario's uncertainty
    /// at this scale (None: `regional_note` says why; it may lie beyond the grid).
    pub k_reg: Option<usize>,
    /// Why there is no K_reg (empty otherwise, and for files without the column).
    pub regional_note: String,
    /// K_emp: the smallest grid K from which every run at every larger grid K is bounded
    /// (None: not even at the largest K).
    pub k_emp: Option<usize>,
    /// K_settle: the smallest grid K from which the median last-quarter ‖e‖ is within
    /// [`SETTLE_TOLERANCE`] of its largest-K level at every larger grid K (None without the
    /// `tail_mean_e` metric or a finite largest-K level).
    pub k_settle: Option<usize>,
    /// K_cert: the smallest K the one verdict certifies (Theorem 1, Theorem L3's K_glob, the
    /// iteration chain at the K it checked, or the joint certificate; None: void or beyond
    /// the search range; it may lie beyond the grid). Not a threshold: the chain certifies
    /// the K it checked only (the points' `certified` column says which).
    pub k_cert: Option<usize>,
    /// Why the certificate is void (empty otherwise).
    pub void_reason: String,
}

impl Thresholds {
    /// K_cert / K_emp (conservatism of the certificate against the runs).
    pub fn cert_over_emp(&self) -> Option<f64> {
        Some(self.k_cert? as f64 / self.k_emp? as f64)
    }
    /// K_emp / K_lin (what the nonlinear runs need beyond linear stability).
    pub fn emp_over_lin(&self) -> Option<f64> {
        Some(self.k_emp? as f64 / self.k_lin? as f64)
    }
    /// K_reg / K_lin (the regional certificate against the necessary bound).
    pub fn reg_over_lin(&self) -> Option<f64> {
        Some(self.k_reg? as f64 / self.k_lin? as f64)
    }
    /// K_cert / K_lin (the global certificate against the necessary bound).
    pub fn cert_over_lin(&self) -> Option<f64> {
        Some(self.k_cert? as f64 / self.k_lin? as f64)
    }
}

/// One grid K of a (solver, scale) curve: (K, bounded fraction, median tail error).
type GridPoint = (usize, f64, Option<f64>);

/// The thresholds per (scale, solver), and per K_c when the table has a `k_c` column, in
/// the order of `points.csv`.
///
/// ```
/// use mhe_sweep::{Table, thresholds};
/// let csv = "point,k,solver,scale,bounded_fraction,k_min_cert,void_reason,k_lin\n\
///            0,1,pg,1,0.5,40,,3\n1,3,pg,1,1,40,,3\n2,10,pg,1,0.9,40,,3\n3,30,pg,1,1,40,,3\n";
/// let t = thresholds(&Table::parse(csv).unwrap());
/// assert_eq!((t[0].k_lin, t[0].k_emp, t[0].k_cert), (Some(3), Some(30), Some(40)));
/// ```
pub fn thresholds(table: &Table) -> Vec<Thresholds> {
    let mut out: Vec<(Thresholds, Vec<GridPoint>)> = Vec::new();
    for row in 0..table.rows.len() {
        let (Some(solver), Some(scale), Some(k)) = (
            table.text(row, "solver"),
            table.text(row, "scale"),
            table.text(row, "k").and_then(|k| k.parse::<usize>().ok()),
        ) else {
            continue;
        };
        let k_c = table.text(row, "k_c").and_then(|k| k.parse::<usize>().ok());
        let fraction = table.number(row, "bounded_fraction").unwrap_or(0.0);
        let i = match out
            .iter()
            .position(|(t, _)| t.solver == solver && t.scale == scale && t.k_c == k_c)
        {
            Some(i) => i,
            None => {
                let int = |name| table.text(row, name).and_then(|v| v.parse::<usize>().ok());
                let void = table.text(row, "certified") == Some("void");
                out.push((
                    Thresholds {
                        solver: solver.to_string(),
                        scale: scale.to_string(),
                        k_c,
                        k_max: 0,
                        k_lin: int("k_lin"),
                        k_reg: int("k_reg"),
                        regional_note: table.text(row, "regional_note").unwrap_or("").to_string(),
                        k_emp: None,
                        k_settle: None,
                        k_cert: if void { None } else { int("k_min_cert") },
                        void_reason: if void {
                            table.text(row, "void_reason").unwrap_or("").to_string()
                        } else {
                            String::new()
                        },
                    },
                    Vec::new(),
                ));
                out.len() - 1
            }
        };
        out[i]
            .1
            .push((k, fraction, table.number(row, "tail_mean_e_q50")));
    }
    out.into_iter()
        .map(|(mut t, mut grid)| {
            grid.sort_by_key(|p| p.0);
            t.k_max = grid.last().map_or(0, |p| p.0);
            // The first K of the all-bounded tail of the grid.
            let tail = grid.iter().rev().take_while(|p| p.1 >= 1.0).count();
            t.k_emp = (tail > 0).then(|| grid[grid.len() - tail].0);
            if let Some(level) = grid.last().and_then(|p| p.2).filter(|l| l.is_finite()) {
                let settled = |e: Option<f64>| {
                    e.is_some_and(|e| (e - level).abs() <= SETTLE_TOLERANCE * level.abs())
                };
                let tail = grid.iter().rev().take_while(|p| settled(p.2)).count();
                t.k_settle = (tail > 0).then(|| grid[grid.len() - tail].0);
            }
            t
        })
        .collect()
}

/// The thresholds as a Markdown table (the one `docs/sweeps.md` shows), one row per solver
/// and scale (and K_c, in a column after the scale, for a 2-D sweep); `—` where a threshold
/// does not exist on the grid. Below the table, one line per row without K_reg says why
/// (the void reason, or the constraint that limits the region and by how much).
pub fn thresholds_markdown(rows: &[Thresholds]) -> String {
    let two_d = rows.iter().any(|t| t.k_c.is_some());
    let k = |v: Option<usize>, missing: String| v.map_or(missing, |k| k.to_string());
    let ratio = |v: Option<f64>| match v {
        None => "—".to_string(),
        Some(r) => lti_model::numfmt::sig4(r),
    };
    let mut s = if two_d {
        String::from(
            "| solver | scale | K_c | K_lin | K_reg | K_emp | K_settle | K_cert | K_reg/K_lin | K_cert/K_lin | K_cert/K_emp | K_emp/K_lin |\n\
             |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        )
    } else {
        String::from(
            "| solver | scale | K_lin | K_reg | K_emp | K_settle | K_cert | K_reg/K_lin | K_cert/K_lin | K_cert/K_emp | K_emp/K_lin |\n\
             |---|---|---|---|---|---|---|---|---|---|---|\n",
        )
    };
    let mut notes = String::new();
    for t in rows {
        if t.k_reg.is_none() && !t.regional_note.is_empty() {
            let _ = writeln!(
                notes,
                "- K_reg of {} at scale {}{}: {}",
                t.solver,
                t.scale,
                t.k_c.map_or_else(String::new, |k| format!(", K_c = {k}")),
                t.regional_note
            );
        }
        let cert = match (t.k_cert, t.void_reason.is_empty()) {
            (Some(k), _) => k.to_string(),
            (None, false) => format!("void: {}", t.void_reason),
            (None, true) => "none in the search range".to_string(),
        };
        let k_c = match (two_d, t.k_c) {
            (false, _) => String::new(),
            (true, Some(k_c)) => format!(" {k_c} |"),
            (true, None) => " — |".to_string(),
        };
        let _ = writeln!(
            s,
            "| {} | {} |{k_c} {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            t.solver,
            t.scale,
            k(t.k_lin, format!("— (ρ_lin ≥ 1 or n/a at K = {})", t.k_max)),
            k(t.k_reg, "—".to_string()),
            k(t.k_emp, format!("— (unbounded runs at K = {})", t.k_max)),
            k(t.k_settle, "—".to_string()),
            cert,
            ratio(t.reg_over_lin()),
            ratio(t.cert_over_lin()),
            ratio(t.cert_over_emp()),
            ratio(t.emp_over_lin()),
        );
    }
    if !notes.is_empty() {
        s.push('\n');
        s.push_str(&notes);
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn table(rows: &[(&str, usize, f64, &str, &str, &str)]) -> Table {
        let mut csv = String::from(
            "point,k,solver,scale,bounded_fraction,certified,k_min_cert,void_reason,k_lin,tail_mean_e_q50\n",
        );
        for (i, (s, k, f, cert, kmin, klin)) in rows.iter().enumerate() {
            let reason = if *cert == "void" { "A unstable" } else { "" };
            // A median tail error that settles at K = 30 (within 10 % of the K = 100 level).
            let e = [(1, 9.0), (3, 1.05), (10, 2.0), (30, 1.09), (100, 1.0)]
                .iter()
                .find(|p| p.0 == *k)
                .map_or(1.0, |p| p.1);
            csv.push_str(&format!(
                "{i},{k},{s},1,{f},{cert},{kmin},{reason},{klin},{e}\n"
            ));
        }
        Table::parse(&csv).unwrap()
    }

    #[test]
    fn k_emp_is_the_start_of_the_all_bounded_tail() {
        // Not monotone: fraction 1 at K = 3 does not count, 0.45 at K = 10 follows it.
        let t = table(&[
            ("pg", 1, 0.0, "no", "500", "30"),
            ("pg", 3, 1.0, "no", "500", "30"),
            ("pg", 10, 0.45, "no", "500", "30"),
            ("pg", 30, 1.0, "no", "500", "30"),
            ("pg", 100, 1.0, "yes", "500", "30"),
            ("fista", 1, 1.0, "void", "", ""),
            ("fista", 3, 0.5, "void", "", ""),
        ]);
        let th = thresholds(&t);
        assert_eq!(th.len(), 2);
        assert_eq!(th[0].k_emp, Some(30));
        assert_eq!(th[0].k_lin, Some(30));
        assert_eq!(th[0].k_cert, Some(500));
        assert_eq!(th[0].k_max, 100);
        assert_eq!(
            th[0].k_settle,
            Some(30),
            "1.05 at K = 3 is followed by 2.0 at K = 10"
        );
        assert!((th[0].cert_over_emp().unwrap() - 500.0 / 30.0).abs() < 1e-12);
        assert_eq!(th[0].emp_over_lin(), Some(1.0));
        // Unbounded at the largest K: no K_emp; void: no K_cert, the reason kept.
        assert_eq!(th[1].k_emp, None);
        assert_eq!(th[1].k_cert, None);
        assert_eq!(th[1].void_reason, "A unstable");
        let md = thresholds_markdown(&th);
        assert!(
            md.contains("| pg | 1 | 30 | — | 30 | 30 | 500 | — | 16.67 | 16.67 | 1 |"),
            "{md}"
        );
        assert!(md.contains("— (unbounded runs at K = 3)"), "{md}");
        assert!(md.contains("void: A unstable"), "{md}");
    }
}
