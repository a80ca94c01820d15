//! Per-iteration cost of the exact projection onto Z ∩ {l ≤ Gz ≤ u} (issue 15): PG and FISTA
//! on the stand-in's MHE QP with 𝒳 and 𝒴 bounded (the rows of every later state and every
//! ŷ, Goldfarb–Idnani with H = I each step) against the same QP with the rows dropped (the
//! box clamp), for M = 5, 9, 20. Two θ: one where no row is active at the iterates (bounds
//! loose), one where rows are active (bounds tight around the data). Best of 5 rounds.
//! Run: `cargo run --release -p mhe-core --example projection_cost`.

use std::time::Instant;

use faer::Mat;
use lti_model::BoxSet;
use mhe_core::{MheProblem, MheSets, MheWeights};
use qp_iter::method::Method;
use qp_iter::{IterationMap, MethodMap};

/// Seconds per step, and the projection's Goldfarb–Idnani steps per projection.
fn per_step(map: &MethodMap, theta: &[f64], z0: &[f64], steps: usize) -> f64 {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    (0..5)
        .map(|_| {
            map.warm_start(&mut s, z0, None);
            let t = Instant::now();
            map.run_steps(&mut s, steps);
            std::hint::black_box(map.iterate(&s));
            t.elapsed().as_secs_f64() / steps as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sys = lti_model::presets::case_study_plant();
    let q = Mat::<f64>::identity(5, 5);
    let r = Mat::<f64>::identity(1, 1);
    let cert = lti_model::ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())?;
    let weights = MheWeights {
        eta: 0.8,
        p: cert.p,
        q,
        r,
    };
    println!("| M | n | rows m | θ | method | box only (ns/step) | with rows (ns/step) | ratio |");
    println!("|---|---|---|---|---|---|---|---|");
    for big_m in [5usize, 9, 20] {
        for (label, xb, yb) in [("loose", 100.0, 100.0), ("tight", 1.0, 0.5)] {
            let sets = MheSets {
                state: BoxSet::symmetric(&[xb; 4])?,
                output: BoxSet::symmetric(&[yb])?,
                disturbance: BoxSet::symmetric(&[0.1; 5])?,
            };
            let prob = MheProblem::new(&sys, big_m, &weights, &sets)?;
            let win = prob.window(big_m).ok_or("window")?;
            let qp = win.qp().clone();
            let n = qp.n();
            let m = qp.general().map_or(0, |g| g.m());
            // θ: prior 0, inputs ±0.3, outputs alternating 1.5 (pulls ŷ onto the tight 𝒴).
            let lay = win.layout();
            let mut theta = vec![0.0; lay.n_theta()];
            for j in 0..big_m {
                theta[lay.u_offset(j)] = if j % 2 == 0 { 0.3 } else { -0.3 };
                theta[lay.y_offset(j)] = if j % 2 == 0 { 1.5 } else { -1.5 };
            }
            let z0 = vec![0.0; n];
            for method in [Method::PG, Method::FISTA] {
                let with = method.build(qp.clone())?;
                let without = method.build(qp.without_general())?;
                let steps = 20_000 / big_m.max(1);
                let a = per_step(&without, &theta, &z0, steps);
                let b = per_step(&with, &theta, &z0, steps);
                println!(
                    "| {big_m} | {n} | {m} | {label} | {method} | {:.0} | {:.0} | {:.1} |",
                    a * 1e9,
                    b * 1e9,
                    b / a
                );
            }
        }
    }
    Ok(())
}
