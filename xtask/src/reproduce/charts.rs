//! The SVG figures of a reproduce job (Fig. 2 analogues, norms).

use super::*;

/// The figures of one job: (file name, chart). Colour i+1 is run i; the true state is black.
pub(super) fn charts(scenario: &Scenario, runs: &[Run]) -> Vec<(&'static str, Chart)> {
    let steps = |tr: &Trace| 0..tr.len();
    let multi = runs.len() > 1;
    let pattern = |i: usize| {
        if i == 0 {
            Pattern::Solid
        } else {
            Pattern::Dashed
        }
    };
    let mut out = Vec::new();

    // Fig. 2(a): x₁ and x̂₁.
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let tr = &r.trace;
        let suffix = if multi {
            format!(", K = {}", r.summary.k)
        } else {
            String::new()
        };
        series.push(Series {
            label: format!("x₁{suffix}"),
            points: steps(tr)
                .filter_map(|t| tr.x(t).map(|x| (t as f64, x[0])))
                .collect(),
            color: 0,
            pattern: pattern(i),
            markers: false,
        });
        series.push(Series {
            label: format!("x̂₁, K = {}", r.summary.k),
            points: steps(tr)
                .filter_map(|t| tr.x_hat(t).map(|x| (t as f64, x[0])))
                .collect(),
            color: i + 1,
            pattern: pattern(i),
            markers: false,
        });
    }
    out.push((
        "fig2a_x1.svg",
        Chart {
            title: "Fig. 2(a): true state x₁ and sub-optimal estimate x̂₁".into(),
            x_label: "time step t".into(),
            y_label: "x₁".into(),
            log_y: false,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::UpperRight,
        },
    ));

    // Fig. 2(b): ε_t (log).
    let series = runs
        .iter()
        .enumerate()
        .map(|(i, r)| Series {
            label: format!("ε_t, K = {}", r.summary.k),
            points: r
                .trace
                .epsilons()
                .enumerate()
                .filter_map(|(t, e)| e.map(|e| (t as f64, e)))
                .collect(),
            color: i + 1,
            pattern: Pattern::Solid,
            markers: true,
        })
        .collect();
    out.push((
        "fig2b_epsilon.svg",
        Chart {
            title: "Fig. 2(b): sub-optimality ε_t = ‖zᴷ_t − z*_t‖".into(),
            x_label: "time step t".into(),
            y_label: "ε_t".into(),
            log_y: true,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::MiddleRight,
        },
    ));

    // Fig. 2(c): ŵ² at t = 6, K-th iterate and exact optimum, with the bounds of 𝒲.
    let nw1 = scenario.plant.nw1();
    let nw2 = scenario.plant.nw2();
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let Some(rec) = r.trace.mhe_step(FIG2C_T) else {
            continue;
        };
        let start = FIG2C_T.saturating_sub(rec.window());
        for c in 0..nw2 {
            let comp = if nw2 > 1 {
                format!("[{}]", c + 1)
            } else {
                String::new()
            };
            let k_pts: Vec<(f64, f64)> = (0..rec.window())
                .filter_map(|j| rec.w2_k(j).map(|w| ((start + j) as f64, w[c])))
                .collect();
            series.push(Series {
                label: format!("ŵ²{comp}, K = {} iterate", r.summary.k),
                points: k_pts,
                color: i + 1,
                pattern: Pattern::Solid,
                markers: true,
            });
            let exact: Vec<(f64, f64)> = (0..rec.window())
                .filter_map(|j| rec.w_exact(j).map(|w| ((start + j) as f64, w[nw1 + c])))
                .collect();
            if !exact.is_empty() {
                series.push(Series {
                    label: format!("ŵ²{comp}, exact optimum (K = {} run)", r.summary.k),
                    points: exact,
                    color: i + 1,
                    pattern: Pattern::Dashed,
                    markers: true,
                });
            }
        }
    }
    let d = &scenario.sets.disturbance;
    let mut hlines = Vec::new();
    for c in 0..nw2 {
        for b in [d.lower()[nw1 + c], d.upper()[nw1 + c]] {
            if b.is_finite() {
                hlines.push(HLine {
                    label: "bounds of 𝒲 (w²)".into(),
                    y: b,
                });
            }
        }
    }
    if !series.is_empty() {
        out.push((
            "fig2c_w2_t6.svg",
            Chart {
                title: format!("Fig. 2(c): estimated measurement noise ŵ² at t = {FIG2C_T}"),
                x_label: "window stage (time index)".into(),
                y_label: "ŵ²".into(),
                log_y: false,
                integer_x: true,
                series,
                hlines,
                legend: Legend::LowerLeft,
            },
        ));
    }

    // ‖e_t‖ and ‖x_t‖ (log).
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let tr = &r.trace;
        series.push(Series {
            label: format!("‖x_t‖, K = {}", r.summary.k),
            points: tr
                .x_norms()
                .iter()
                .enumerate()
                .map(|(t, v)| (t as f64, *v))
                .collect(),
            color: i + 1,
            pattern: Pattern::Solid,
            markers: false,
        });
        series.push(Series {
            label: format!("‖e_t‖, K = {}", r.summary.k),
            points: tr
                .e_norms()
                .iter()
                .enumerate()
                .map(|(t, v)| (t as f64, *v))
                .collect(),
            color: i + 1,
            pattern: Pattern::Dashed,
            markers: false,
        });
    }
    out.push((
        "norms.svg",
        Chart {
            title: "State norm ‖x_t‖ and estimation error ‖e_t‖".into(),
            x_label: "time step t".into(),
            y_label: "norm".into(),
            log_y: true,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::UpperRight,
        },
    ));
    out
}
