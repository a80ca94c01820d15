//! A first certified MHE on your own plant, from Rust values: the plant, 𝒰, the MHE (M, η,
//! K) and the exact MPC; then K_min per method and the verdict at your K. 15 lines of Rust
//! and two crates (a test of iss-certificate, `first_certificate_fits_15_lines`, counts them
//! and checks the copy in the crate's README).
//! Run: `cargo run --release -p iss-certificate --example first_certificate`.

use iss_certificate::{CertifyOptions, LoopModel, MheSettings, certify};
use lti_model::{LtiSystem, faer::mat};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // x⁺ = Ax + Bu + w¹, y = Cx + w²: a stable plant measured in its first state.
    let a = mat![[0.95, 0.1], [0.0, 0.9]];
    let plant = LtiSystem::new(a, mat![[0.005], [0.1]], mat![[1.0, 0.0]])?;
    let model = LoopModel::builder(plant)
        .input_box(&[-1.0], &[1.0]) // 𝒰 (𝒳, 𝒴 and 𝒲 default to the whole space)
        .mhe(MheSettings::builder().horizon(10).eta(0.8).iterations(200)) // M, η, K
        .mpc_horizon(10) // the exact MPC, N = 10
        .build()?; // validated (errors name the method, `MheBuilder::eta`); P of LMI (2)
    // Is my K = 200 certified? yes, no, void (a premise fails) or not_computed (budget).
    for (method, k_min, v) in certify(&model, &CertifyOptions::default())?.verdicts(200) {
        println!("{method}: K_min = {k_min:?}, K = 200: {}", v.certified);
    }
    Ok(())
}
