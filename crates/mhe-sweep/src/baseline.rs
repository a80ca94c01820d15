//! The Kalman baseline of a sweep (`estimators = ["mhe", "kalman"]`): the closed loop with
//! the standard Kalman filter of the MHE's weights ([`closed_loop::baseline::kalman_for_mhe`]) in
//! place of the MHE, the sweep's controller, and for run r at each scale the disturbance
//! seed of the MHE's run r (with `common_random_numbers`, the default, the very same draws
//! as every MHE point's run r). The filter has no K and no solver, so it is not a point of
//! the grid: its runs go to `kalman.csv`, one row per (scale, run), with the metrics and the
//! bounded rule of `runs.csv` and the count of draws outside 𝒲.
//!
//! Row j = s·seeds + r (scale index s, run r) belongs to shard I of N when j mod N = I − 1:
//! a shard writes its rows to a part file (`kalman_parts.rs`), `sweep-merge` assembles them.

use std::fmt::Write as _;

use rayon::prelude::*;

use super::error::{Result, SweepError, config_err};
use super::format::csv_text;
use super::run::Sweep;
use super::seeds::run_seed;
use closed_loop::metrics::{Metric, run_metrics};
use closed_loop::scenario::{draws_outside, scenario_disturbance};
use closed_loop::sim::ClosedLoop;

/// `estimators`: a list of `"mhe"` and `"kalman"`; returns whether the Kalman baseline
/// runs. The MHE is always swept (the grid is its).
pub(super) fn parse_estimators(raw: Option<&[String]>) -> Result<bool> {
    let Some(list) = raw else { return Ok(false) };
    let mut kalman = false;
    for (i, e) in list.iter().enumerate() {
        match e.as_str() {
            "mhe" => {}
            "kalman" => kalman = true,
            other => {
                return Err(config_err(
                    format!("estimators[{i}]"),
                    format!(
                        "is \"{other}\"; the estimators are \"mhe\" (the sweep's grid) and \
                         \"kalman\" (the Kalman filter of the MHE's weights, written to kalman.csv)"
                    ),
                ));
            }
        }
    }
    if !list.iter().any(|e| e == "mhe") {
        return Err(config_err(
            "estimators",
            "must contain \"mhe\": the K grid and the solvers are the MHE's; add \"kalman\" beside it",
        ));
    }
    Ok(kalman)
}

/// The header of `kalman.csv`.
pub fn kalman_header() -> String {
    let mut cols = vec!["estimator", "scale", "run", "seed", "steps", "bounded"];
    cols.extend(Metric::ALL.iter().map(|m| m.name()));
    cols.extend(["w_outside", "error"]);
    cols.join(",")
}

/// The text of `kalman.csv`: its header and every row of the Kalman baseline of `sweep`
/// (every scale × `seeds` runs, on the current rayon pool).
pub(super) fn kalman_text(sweep: &Sweep) -> Result<String> {
    Ok(kalman_csv(&kalman_rows(sweep, &|_| true)?))
}

/// `kalman.csv` from rows sorted by (scale index, run).
pub(super) fn kalman_csv(rows: &[KalmanRow]) -> String {
    let mut text = kalman_header();
    text.push('\n');
    for (_, _, row) in rows {
        text.push_str(row);
        text.push('\n');
    }
    text
}

/// A row of `kalman.csv` with its scale index and run.
pub(super) type KalmanRow = (usize, usize, String);

/// The first point of every scale (its run r's seed is the Kalman run r's), in scale order.
pub(super) fn scale_points(sweep: &Sweep) -> Vec<&super::Point> {
    let mut firsts: Vec<&super::Point> = Vec::new();
    for p in sweep.points() {
        if !firsts.iter().any(|q| q.scale_index == p.scale_index) {
            firsts.push(p);
        }
    }
    firsts.sort_by_key(|p| p.scale_index);
    firsts
}

/// The rows of the Kalman baseline whose row index j = s·seeds + r (scale index s, run r)
/// `keep` accepts, sorted by (s, r).
pub(super) fn kalman_rows(
    sweep: &Sweep,
    keep: &(dyn Fn(usize) -> bool + Sync),
) -> Result<Vec<KalmanRow>> {
    let config = sweep.config();
    let setup = |e: String| SweepError::Setup {
        point: "kalman".into(),
        source: closed_loop::sim::ClosedLoopError::Model(lti_model::ModelError::Scenario {
            key: "estimators".into(),
            problem: e,
        }),
    };
    // One MHE point per scale gives the seeds (its run r's draw).
    let firsts = scale_points(sweep);
    let seeds = config.seeds;
    let mut rows: Vec<KalmanRow> = firsts
        .par_iter()
        .flat_map(|p| (0..seeds).into_par_iter().map(move |r| (*p, r)))
        .filter(|(p, r)| keep(p.scale_index * seeds + r))
        .map(|(p, r)| -> Result<KalmanRow> {
            let mut resolved = sweep.resolved().clone();
            resolved.set_noise_scale(p.scale);
            let sc = resolved.scenario();
            let cfg = resolved.mhe_config().map_err(|e| setup(e.to_string()))?;
            let kf = closed_loop::baseline::kalman_for_mhe(
                &sc.plant,
                &sc.simulation.prior,
                &cfg.p,
                &cfg.q,
                &cfg.r,
            )
            .map_err(|e| setup(e.to_string()))?;
            let seed = run_seed(sweep.base_seed(), p, r, config.common_random_numbers);
            let controller = resolved
                .controller(config.controller_at(p).map_err(|e| setup(e.to_string()))?)
                .map_err(|e| setup(e.to_string()))?;
            let noise = scenario_disturbance(sc, seed).map_err(|e| setup(e.to_string()))?;
            let mut lp = ClosedLoop::new(
                sc.plant.clone(),
                kf,
                controller,
                noise,
                &sc.simulation.x0,
                sweep.steps(),
            )
            .map_err(|e| setup(e.to_string()))?;
            let stop = lp.run().err();
            let trace = lp.trace();
            let input = (sc.sets.input.lower(), sc.sets.input.upper());
            let (values, bounded) = run_metrics(
                trace,
                &sc.simulation.x0,
                input,
                config.bounded_factor,
                stop.as_ref(),
            );
            let mut row = String::new();
            let _ = write!(
                row,
                "kalman,{},{r},{seed},{},{}",
                p.scale,
                trace.len(),
                u8::from(bounded)
            );
            for v in values {
                row.push(',');
                if let Some(v) = v {
                    let _ = write!(row, "{v}");
                }
            }
            let _ = write!(
                row,
                ",{},{}",
                draws_outside(trace, &sc.sets.disturbance).len(),
                stop.map(|e| csv_text(&e.to_string())).unwrap_or_default()
            );
            Ok((p.scale_index, r, row))
        })
        .collect::<Result<Vec<_>>>()?;
    rows.sort_by_key(|(s, r, _)| (*s, *r));
    Ok(rows)
}
