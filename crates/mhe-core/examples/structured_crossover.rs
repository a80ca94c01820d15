//! Per-iteration time of projected gradient on the stand-in's MHE QP, dense kernel against
//! the structured H_c z (forward + adjoint pass), for M = 2 … 50: the measured crossover
//! behind `qp_iter::operator::STRUCTURED_MIN_N`. Ratios are from one run (shared machine).
//! Run: `cargo run --release -p mhe-core --example structured_crossover`.

use std::time::Instant;

use faer::Mat;
use lti_model::BoxSet;
use mhe_core::{MheProblem, MheSets, MheWeights};
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp};

/// Seconds per step of `map`, best of 5 rounds of `steps` steps.
fn per_step(map: &ProjectedGradient, theta: &[f64], steps: usize) -> f64 {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    let z0 = vec![0.0; map.problem().n()];
    (0..5)
        .map(|_| {
            map.warm_start(&mut s, &z0, None);
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
    let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&[0.1; 5])?);
    let weights = MheWeights {
        eta: 0.8,
        p: cert.p,
        q,
        r,
    };
    println!("    M    n_z   dense (µs/step)   structured (µs/step)   structured/dense");
    for m in [2, 5, 10, 15, 20, 25, 30, 40, 50] {
        let prob = MheProblem::new(&sys, m, &weights, &sets)?;
        let qp = prob.window(m).ok_or("window")?.qp().clone();
        let dense_qp = ParametricQp::new(
            qp.h().to_owned(),
            qp.q0().to_vec(),
            qp.f().to_owned(),
            qp.zset().clone(),
        )?;
        let theta = vec![0.5; qp.n_theta()];
        let dense = ProjectedGradient::new(dense_qp, StepRule::Optimal)?;
        // Force the structured path whatever the crossover constant says.
        let structured = ProjectedGradient::new_structured(qp.clone(), StepRule::Optimal)?;
        let steps = 200_000 / qp.n().max(1);
        let (td, ts) = (
            per_step(&dense, &theta, steps),
            per_step(&structured, &theta, steps),
        );
        println!(
            "{m:>5} {:>6} {:>17.3} {:>22.3} {:>18.2}",
            qp.n(),
            td * 1e6,
            ts * 1e6,
            ts / td
        );
    }
    Ok(())
}
