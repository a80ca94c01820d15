//! Exactly K projected-gradient steps on a parametric QP, checked against the exact solution
//! and the certified contraction φ(K) = rateᴷ. The example of this crate's README.
//! Run: `cargo run -p qp-iter --example fixed_iterations`.

use faer::mat;
use qp_iter::BoxSet;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp, active_set::ExactSolver, run_fixed};

fn main() -> Result<(), qp_iter::QpError> {
    // min ½zᵀHz + (q₀ + Fθ)ᵀz over −1 ≤ z ≤ 1.
    let (h, f) = (mat![[4.0, 1.0], [1.0, 3.0]], mat![[1.0, 0.0], [0.0, 2.0]]);
    let qp = ParametricQp::new(h, vec![0.0, 0.0], f, BoxSet::symmetric(&[1.0, 1.0])?)?;
    let theta = [3.0, -1.0];
    let pg = ProjectedGradient::new(qp.clone(), StepRule::Optimal)?;
    let z_star = ExactSolver::new(&qp)?.solve(&theta)?.to_vec();
    let dist = |z: &[f64]| {
        z.iter()
            .zip(&z_star)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let mut state = pg.new_state();
    println!("z* = {z_star:?}, rate = {:.4}", pg.certificate().rate);
    println!("{:>3} {:>12} {:>12}", "K", "‖zᴷ − z*‖", "φ(K)‖z⁰ − z*‖");
    for k in [0, 1, 5, 10, 20] {
        pg.load(&mut state, &theta); // q = q₀ + Fθ
        pg.cold_start(&mut state); // z⁰ = the projection of 0 onto the box = 0
        run_fixed(&pg, &mut state, k);
        let (error, bound) = (
            dist(pg.iterate(&state)),
            pg.certificate().phi(k) * dist(&[0.0, 0.0]),
        );
        // Equal up to rounding here: with the optimal step on a 2 × 2 H, I − αH is the rate
        // times a reflection, so the bound is tight while no constraint is active.
        assert!(
            error <= bound * (1.0 + 1e-9),
            "the certificate failed at K = {k}"
        );
        println!("{k:>3} {error:>12.3e} {bound:>12.3e}");
    }
    Ok(())
}
