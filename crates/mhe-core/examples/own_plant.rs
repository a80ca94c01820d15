//! The MHE on your own plant with the certified prior weight P, using `lti-model` and
//! `mhe-core` only (`faer` and `qp-iter` come re-exported): a double integrator measured in
//! position, bounded disturbances, K = 20 ADMM iterations per step.
//! Run: `cargo run -p mhe-core --example own_plant`.

use lti_model::LtiSystem;
use lti_model::disturbance::{Disturbance, UniformBox};
use lti_model::faer::mat;
use mhe_core::{Method, MheSets, MheSettings};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. Your plant x⁺ = Ax + Bu + w¹, y = Cx + w².
    let sys = LtiSystem::new(
        mat![[1.0, 0.1], [0.0, 1.0]],
        mat![[0.005], [0.1]],
        mat![[1.0, 0.0]],
    )?;
    // 2. The MHE: horizon M = 10, η = 0.8, K = 20 ADMM iterations per step; Q = I, R = I
    //    and P of LMI (2) computed for them (Assumption 2: the certified prior weight).
    let settings = MheSettings::builder()
        .horizon(10)
        .eta(0.8)
        .iterations(20)
        .method(Method::ADMM) // or Method::PG, Method::FISTA, …
        .build(&sys)?;
    let mut mhe = settings.estimator(&sys, &MheSets::unconstrained(&sys), &[0.0, 0.0])?;

    // The plant, simulated with seeded disturbances |w| ≤ 0.01.
    let mut noise = UniformBox::new(vec![-0.01; sys.nw()], vec![0.01; sys.nw()], 7)?;
    let (mut x, mut x_next, mut y, mut w) = (
        vec![1.0, -0.5],
        vec![0.0; 2],
        vec![0.0],
        vec![0.0; sys.nw()],
    );
    println!(" t   ‖x̂ − x‖");
    for t in 0..60 {
        let x_hat = mhe.estimate()?; // x̂_{t|t}, from u and y up to t − 1
        let error = x_hat
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        if t % 10 == 0 {
            println!("{t:>2}  {error:.3e}");
        }
        let u = [(0.3 * t as f64).sin()];
        noise.sample(&mut w);
        sys.step(&x, &u, &w, &mut x_next, &mut y); // y_t = Cx_t + w²_t, x_{t+1}
        mhe.push(&u, &y)?;
        std::mem::swap(&mut x, &mut x_next);
    }
    Ok(())
}
