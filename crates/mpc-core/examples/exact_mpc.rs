//! The exact MPC on your own plant: a closed-loop run without noise from x₀ = (2, 0) with
//! |u| ≤ 1, and the certified Lipschitz constant L_π of the law. The example of this crate's
//! README. Run: `cargo run -p mpc-core --example exact_mpc`.

use faer::{Mat, mat};
use lti_model::{BoxSet, LtiSystem};
use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcConfig};

fn main() -> Result<(), mpc_core::MpcError> {
    // A double integrator (position, velocity), sampled at 0.1 s.
    let sys = LtiSystem::new(
        mat![[1.0, 0.1], [0.0, 1.0]],
        mat![[0.005], [0.1]],
        mat![[1.0, 0.0]],
    )?;
    let input_set = BoxSet::symmetric(&[1.0])?; // |u| ≤ 1
    let config = MpcConfig::new(10, Mat::identity(2, 2), mat![[0.1]], input_set);
    let mpc = CondensedMpc::new(&sys, config)?;
    let mut pi = ExactMpc::new(&mpc)?;
    println!("certified L_π ≤ {:.3}", mpc.lipschitz_certified()?.l_pi());
    let (mut x, mut next, mut y, mut u) = (vec![2.0, 0.0], vec![0.0; 2], vec![0.0], [0.0]);
    let w = vec![0.0; sys.nw()]; // no disturbance
    for t in 0..60 {
        pi.control(&x, &mut u)?; // the state is measured here: x̂ = x
        assert!(u[0].abs() <= 1.0 + 1e-12);
        if t % 10 == 0 {
            println!(
                "t = {t:>2}: x = ({:+.4}, {:+.4}), u = {:+.4}",
                x[0], x[1], u[0]
            );
        }
        sys.step(&x, &u, &w, &mut next, &mut y);
        std::mem::swap(&mut x, &mut next);
    }
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    println!("‖x₆₀‖ = {norm:.2e}");
    Ok(())
}
