//! The MHE on your own plant with the certified prior weight P, using `lti-model` and
//! `mhe-core` only (`faer` and `qp-iter` come re-exported): a double integrator measured in
//! position, bounded disturbances, K = 20 ADMM iterations per step.
//! Run: `cargo run -p mhe-core --example own_plant`.

use lti_model::disturbance::{Disturbance, UniformBox};
use lti_model::faer::{Mat, mat};
use lti_model::{LtiSystem, ioss};
use mhe_core::qp_iter::Method;
use mhe_core::{MheConfig, MheEstimator, MheSets, WarmStart};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. Your plant x⁺ = Ax + Bu + w¹, y = Cx + w².
    let sys = LtiSystem::new(
        mat![[1.0, 0.1], [0.0, 1.0]],
        mat![[0.005], [0.1]],
        mat![[1.0, 0.0]],
    )?;
    // 2. Cost weights η, Q, R of eq. (9), and P of LMI (2) for them (Assumption 2).
    let (eta, q, r) = (
        0.8,
        Mat::identity(sys.nw(), sys.nw()),
        Mat::identity(sys.ny(), sys.ny()),
    );
    let p = ioss::certify(&sys, eta, q.as_ref(), r.as_ref())?.p;
    // 3. The MHE: horizon M = 10, K = 20 iterations of Φ per step, prior x̄₀ = 0.
    let config = MheConfig {
        horizon: 10,
        eta,
        p,
        q,
        r,
        iterations: 20,
        warm_start: WarmStart::Paper,
        exact_solve: true, // also solve exactly, to report ε_t
    };
    let sets = MheSets::unconstrained(&sys);
    let mut mhe = MheEstimator::new(&sys, &sets, &config, &[0.0, 0.0], |qp| {
        Method::ADMM.build(qp) // or Method::PG, Method::FISTA, …
    })?;

    // The plant, simulated with seeded disturbances |w| ≤ 0.01.
    let mut noise = UniformBox::new(vec![-0.01; sys.nw()], vec![0.01; sys.nw()], 7)?;
    let (mut x, mut x_next, mut y, mut w) = (
        vec![1.0, -0.5],
        vec![0.0; 2],
        vec![0.0],
        vec![0.0; sys.nw()],
    );
    println!(" t   ‖x̂ − x‖       ε_t");
    for t in 0..60 {
        let x_hat = mhe.estimate()?; // x̂_{t|t}, from u and y up to t − 1
        let error = x_hat
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        if t % 10 == 0 {
            let eps = mhe.last_record().epsilon.unwrap_or(0.0);
            println!("{t:>2}  {error:.3e}  {eps:.3e}");
        }
        let u = [(0.3 * t as f64).sin()];
        noise.sample(&mut w);
        sys.step(&x, &u, &w, &mut x_next, &mut y); // y_t = Cx_t + w²_t, x_{t+1}
        mhe.push(&u, &y)?;
        std::mem::swap(&mut x, &mut x_next);
    }
    Ok(())
}
