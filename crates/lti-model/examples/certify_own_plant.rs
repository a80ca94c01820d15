//! δ-IOSS (Assumption 2) for your own plant: P of LMI (2) for η = 0.8 and Q = I, R = I.
//! The example of this crate's README. Run: `cargo run -p lti-model --example certify_own_plant`.

use lti_model::faer::{Mat, mat};
use lti_model::{LtiSystem, ioss};

fn main() -> Result<(), lti_model::ModelError> {
    // x⁺ = Ax + Bu + w¹, y = Cx + w² (E = I, F = I): a double integrator measured in position.
    let sys = LtiSystem::new(
        mat![[1.0, 0.1], [0.0, 1.0]],
        mat![[0.005], [0.1]],
        mat![[1.0, 0.0]],
    )?;
    let (q, r) = (
        Mat::<f64>::identity(sys.nw(), sys.nw()),
        Mat::<f64>::identity(sys.ny(), sys.ny()),
    );
    let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())?;
    assert!(cert.lmi_relative_violation <= cert.lmi_relative_tolerance); // P passes LMI (2)
    println!(
        "P = {:?}, λ(P) ∈ [{:.3}, {:.3}]",
        cert.p, cert.p_min_eigenvalue, cert.p_max_eigenvalue
    );
    Ok(())
}
