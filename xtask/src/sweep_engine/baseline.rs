//! The Kalman baseline of a sweep (`estimators = ["mhe", "kalman"]`): the closed loop with
//! the standard Kalman filter of the MHE's weights ([`closed_loop::baseline::kalman_for_mhe`]) in
//! place of the MHE, the sweep's controller, and for run r at each scale the disturbance
//! seed of the MHE's run r (with `common_random_numbers`, the default, the very same draws
//! as every MHE point's run r). The filter has no K and no solver, so it is not a point of
//! the grid: its runs go to `kalman.csv`, one row per (scale, run), with the metrics and the
//! bounded rule of `runs.csv` and the count of draws outside 𝒲.

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

/// Runs the Kalman baseline of `sweep` (every scale × `seeds` runs, on the current rayon
/// pool) and writes `kalman.csv` into `out`. Returns the number of runs.
pub(super) fn kalman_text(sweep: &Sweep) -> Result<String> {
    let config = sweep.config();
    let setup = |e: String| SweepError::Setup {
        point: "kalman".into(),
        source: closed_loop::sim::ClosedLoopError::Model(lti_model::ModelError::Scenario {
            key: "estimators".into(),
            problem: e,
        }),
    };
    // One MHE point per scale gives the seeds (its run r's draw).
    let mut firsts = Vec::new();
    for p in sweep.points() {
        if !firsts
            .iter()
            .any(|q: &&super::Point| q.scale_index == p.scale_index)
        {
            firsts.push(p);
        }
    }
    let mut rows: Vec<(usize, usize, String)> = firsts
        .par_iter()
        .flat_map(|p| (0..config.seeds).into_par_iter().map(move |r| (*p, r)))
        .map(|(p, r)| -> Result<(usize, usize, String)> {
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
                .controller(config.controller_at(p))
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
    let mut text = kalman_header();
    text.push('\n');
    for (_, _, row) in &rows {
        text.push_str(row);
        text.push('\n');
    }
    Ok(text)
}
