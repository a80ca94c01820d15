//! A first certified MHE on your own plant, from Rust values: the plant, 𝒰 and 𝒲, the MHE
//! (M, η, K) and the exact MPC; then K_min per method and the verdict at your K.
//! Run: `cargo run --release -p iss-certificate --example first_certificate`.

use iss_certificate::{CertifyOptions, LoopModel, MheSettings, certify};
use lti_model::{LtiSystem, faer::mat};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // x⁺ = Ax + Bu + w¹, y = Cx + w²: a stable plant measured in its first state.
    let a = mat![[0.95, 0.1], [0.0, 0.9]];
    let plant = LtiSystem::new(a, mat![[0.005], [0.1]], mat![[1.0, 0.0]])?;
    let model = LoopModel::builder(plant)
        .input_box(&[-1.0], &[1.0]) // 𝒰
        .disturbance_box(&[-0.01; 3], &[0.01; 3]) // 𝒲 ∋ w = (w¹, w²)
        .mhe(MheSettings::builder().horizon(10).eta(0.8).iterations(200)) // M, η, K
        .mpc_horizon(10) // the exact MPC, N = 10
        .build()?;
    let cert = certify(&model, &CertifyOptions::default())?;
    for (method, k_min) in cert.k_mins() {
        let v = cert.verdict(method, model.iterations()).certified; // is my K = 200 certified?
        println!("{method}: K_min = {k_min:?}, K = 200: {}", v.as_str());
    }
    Ok(())
}
