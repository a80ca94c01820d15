//! δ-IOSS certificate (Assumption 2) of the shipped case-study stand-in, and the smallest
//! feasible η. Run: `cargo run -p lti-model --example ioss_case_study`.

use faer::Mat;
use lti_model::ioss;

fn main() -> Result<(), lti_model::ModelError> {
    let sys = lti_model::presets::case_study_plant();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    for eta in [0.8, 0.7, 0.6, 0.5] {
        match ioss::certify(&sys, eta, q.as_ref(), r.as_ref()) {
            Ok(c) => println!(
                "η = {eta}: λ(P) ∈ [{:.6}, {:.6}], Λ^P_P = {:.4}, max eig(LMI) = {:.2e}, {} iterations",
                c.p_min_eigenvalue,
                c.p_max_eigenvalue,
                c.lambda_pp(),
                c.lmi_max_eigenvalue,
                c.iterations
            ),
            Err(e) => println!("η = {eta}: {e}"),
        }
    }
    let b = ioss::min_feasible_eta(&sys, q.as_ref(), r.as_ref(), 1e-4)?;
    println!(
        "smallest feasible η ≈ {:.4} (infeasible at {:.4}), {} bisection steps",
        b.certificate.eta, b.infeasible_below, b.steps
    );
    Ok(())
}
