//! trace.csv: one row per simulated step of every run, for spreadsheets and plotting tools
//! (columns: docs/reproduce-output.md).

use lti_model::ConvexSet;

use super::numfmt::csv;
use super::*;

/// The header: `k,t,x1..x{n_x},xhat1..,u1..,y1..,w1..w{n_w},e_norm,x_norm,eps,status,mpc,
/// xkf1..xkf{n_x},ekf_norm,w_outside` (the Kalman baseline's estimate and error; whether
/// w_t ∉ 𝒲).
pub(super) fn header(nx: usize, nu: usize, ny: usize, nw: usize) -> String {
    let mut cols: Vec<String> = vec!["k".into(), "t".into()];
    for (name, n) in [("x", nx), ("xhat", nx), ("u", nu), ("y", ny), ("w", nw)] {
        cols.extend((1..=n).map(|i| format!("{name}{i}")));
    }
    cols.extend(["e_norm", "x_norm", "eps", "status", "mpc"].map(String::from));
    cols.extend((1..=nx).map(|i| format!("xkf{i}")));
    cols.extend(["ekf_norm", "w_outside"].map(String::from));
    cols.join(",")
}

/// The CSV text of `runs` (header and one line per step; a run that stopped early has its
/// completed steps only).
pub(super) fn trace_csv(runs: &[Run], w_set: &BoxSet) -> String {
    let Some(first) = runs.first() else {
        return String::new();
    };
    let (nx, nu, ny, nw) = first.trace.dims();
    let mut out = header(nx, nu, ny, nw);
    out.push('\n');
    for r in runs {
        let tr = &r.trace;
        for t in 0..tr.len() {
            let mut row: Vec<String> = vec![r.summary.k.to_string(), t.to_string()];
            for v in [tr.x(t), tr.x_hat(t), tr.u(t), tr.y(t), tr.w(t)] {
                row.extend(v.unwrap_or(&[]).iter().map(|&v| csv(v)));
            }
            row.push(csv(tr.e_norms()[t]));
            row.push(csv(tr.x_norms()[t]));
            let step = tr.mhe_step(t);
            // Missing (no exact MHE solve, no MHE record): an empty field.
            row.push(step.and_then(|s| s.epsilon()).map_or_else(String::new, csv));
            row.push(step.map_or_else(String::new, |s| status_name(s.status())));
            row.push(match tr.control_status(t) {
                Some(mpc_core::ControlStatus::Infeasible { fallback, .. }) => {
                    format!("infeasible:{}", fallback.name())
                }
                Some(_) => "applied".into(),
                None => String::new(),
            });
            // The Kalman baseline (empty fields where it has no estimate).
            let kf = r.kalman.as_ref();
            match kf.and_then(|k| k.x_hat.get(t)) {
                Some(x) => row.extend(x.iter().map(|&v| csv(v))),
                None => row.extend((0..nx).map(|_| String::new())),
            }
            row.push(
                kf.and_then(|k| k.e_norms.get(t))
                    .map_or_else(String::new, |&v| csv(v)),
            );
            row.push(
                tr.w(t)
                    .map(|w| u8::from(!(w_set.violation(w) <= 0.0)).to_string())
                    .unwrap_or_default(),
            );
            out.push_str(&row.join(","));
            out.push('\n');
        }
    }
    out
}

/// The status as in trace.json (`completed`, `converged`, `max_iterations`, `non_finite`, …).
fn status_name(s: qp_iter::RunStatus) -> String {
    s.name().to_owned()
}
