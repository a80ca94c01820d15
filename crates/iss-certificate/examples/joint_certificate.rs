//! The joint MPC + MHE certificate (issue 16) of a scenario for every pair of methods, and
//! the trajectory checks of every inequality at the cheapest certified pair.
//!
//! Run: `cargo run --release -p iss-certificate --example joint_certificate -- \
//!        scenarios/case-study-certified.toml 200`
//! (arguments: the scenario, the number of seeds of the trajectory checks (0 skips them),
//! optionally the MHE and MPC methods, default every pair of pg / fista).

use closed_loop::scenario::Scenario;
use iss_certificate::certificate::{CertificateOptions, certify_closed_loop};
use iss_certificate::joint::{JointOptions, certify_joint, check_on_seeds};
use qp_iter::Method;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .unwrap_or_else(|| "scenarios/case-study-certified.toml".into());
    let seeds: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let methods: Vec<Method> = args.filter_map(|a| a.parse().ok()).collect();
    let pairs: Vec<(Method, Method)> = if methods.len() >= 2 {
        vec![(methods[0], methods[1])]
    } else {
        let m = [Method::PG, Method::FISTA];
        m.iter()
            .flat_map(|&e| m.iter().map(move |&c| (e, c)))
            .collect()
    };
    let scenario = Scenario::from_file(&path)?;
    let resolved = scenario.clone().resolve()?;
    let mhe_methods: Vec<Method> = pairs.iter().map(|p| p.0).collect();
    let cert = certify_closed_loop(
        &resolved,
        &CertificateOptions {
            solvers: mhe_methods,
            lipschitz_pairs: 0,
            gamma13_sequences: 0,
            ..CertificateOptions::default()
        },
    )?;
    let mpc = resolved.mpc()?;
    let (nx, ny) = (scenario.plant.nx(), scenario.plant.ny());
    let m = cert.horizon;
    let n_e = nx + m * (nx + ny);
    println!(
        "{}: γ₁,₃ = {:.4}, γ₁,₄ = {:.4}, L_π = {:.4}, L_U = {:.4}",
        scenario.name,
        cert.gamma13.used,
        cert.gamma13
            .certified
            .as_ref()
            .map_or(f64::NAN, |c| c.gamma14),
        cert.l_pi_used,
        cert.l_pi.certified.sequence
    );
    for (e, c) in pairs {
        let t0 = std::time::Instant::now();
        let j = certify_joint(&cert, mpc, n_e, e, c, &JointOptions::default())?;
        let r = &j.region;
        println!(
            "MHE {e} + MPC {c} (warm start {}, ω = {:.4}): K_e floor {:?} (exact MPC), K_c floor {:?} (exact MHE), {} Pareto corners, cheapest {:?} by {}  [{:.2?}]",
            j.warm_start,
            j.analysis.inputs.mpc.warm_gain,
            r.k_e_floor,
            r.k_c_floor,
            r.pareto.len(),
            r.cheapest.map(|p| (p.k_e, p.k_c)),
            j.cost_model,
            t0.elapsed()
        );
        for v in &r.void_reasons {
            println!("  void: {v}");
        }
        let show: Vec<String> = r
            .pareto
            .iter()
            .step_by((r.pareto.len() / 8).max(1))
            .map(|p| format!("({}, {})", p.k_e, p.k_c))
            .collect();
        if !show.is_empty() {
            println!(
                "  Pareto (every {}th): {}",
                (r.pareto.len() / 8).max(1),
                show.join(" ")
            );
        }
        if let Some(g) = &j.at_cheapest {
            println!(
                "  at the cheapest pair: ρ(Γ) = {:.4}, φ_e = {:.3e}, φ_c = {:.3e}, γ₁,₄ = {:.3}, γ₂,₄ = {:.3e}, γ₃,₄ = {:.3e}, γ₄,₁ = γ₄,₃ = {:.3e}; largest cycle {:.4}",
                g.spectral_radius,
                g.mhe.phi,
                g.phi_c,
                g.gamma14,
                g.gamma24,
                g.gamma34,
                g.gamma41,
                g.cycles.iter().map(|c| c.gain).fold(0.0, f64::max)
            );
        }
        let Some(p) = r.cheapest else { continue };
        if seeds == 0 {
            continue;
        }
        let t1 = std::time::Instant::now();
        let c = check_on_seeds(&resolved, &cert, &j, p, seeds)?;
        let w = c.worst;
        println!(
            "  trajectory checks at ({}, {}) on {seeds} seeds: {} failed; worst lhs/rhs plant {:.3e}, Prop. 1 {:.3e}, Prop. 3 {:.3e}, δ step {:.3e}, δ {:.3e}, ‖u − π(x̂)‖/δ {:.3e}; replay mismatch {:.1e}  [{:.1?}]",
            p.k_e,
            p.k_c,
            c.failed.len(),
            w[0],
            w[1],
            w[2],
            w[3],
            w[4],
            w[5],
            c.replay_mismatch,
            t1.elapsed()
        );
    }
    Ok(())
}
