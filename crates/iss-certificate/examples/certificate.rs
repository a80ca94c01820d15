//! Theorem 1 certificate of a scenario, per solver, for several horizons M.
//! Run: `cargo run --release -p iss-certificate --example certificate -- scenarios/case-study.toml 5 9 12`.
//! Prints the wall time of each part of the certificate (the issue-11 target: ≤ 5 s for
//! n_x = 12, N·n_u = 90 — `scenarios/mass-chain.toml`).

use closed_loop::scenario::Scenario;
use iss_certificate::certificate::{CertificateOptions, certify_closed_loop_timed};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .unwrap_or_else(|| "scenarios/case-study.toml".into());
    let base = Scenario::from_file(&path)?;
    let horizons: Vec<usize> = args.filter_map(|a| a.parse().ok()).collect();
    // The defaults `reproduce` uses (sampled γ₁,₃ estimate included), for the four methods
    // on the problem as given and on the Jacobi-scaled problem.
    let opts = CertificateOptions {
        solvers: qp_iter::Method::ALL.to_vec(),
        ..CertificateOptions::default()
    };
    for m in if horizons.is_empty() {
        vec![0]
    } else {
        horizons
    } {
        let mut s = base.clone();
        if m > 0 {
            if let Some(spec) = s.mhe.as_mut() {
                *spec = spec.to_builder().horizon(m).build(&s.plant)?;
            }
        }
        let t0 = std::time::Instant::now();
        let resolved = s.clone().resolve()?;
        let resolve_s = t0.elapsed().as_secs_f64();
        let (c, times) = certify_closed_loop_timed(&resolved, &opts)?;
        println!(
            "M = {}, η = {}: ρ = {:.4}, λ(P) ∈ [{:.4}, {:.4}], H̄ = {:.4}, L_Φ = {:.4} (sampled {:.4}), L_π = {:.4}, γ₁,₃ = {:.4}  [{:.1?}]",
            c.horizon,
            c.eta,
            c.rho,
            c.p_min.unwrap_or(f64::NAN),
            c.p_max.unwrap_or(f64::NAN),
            c.h_bar.unwrap_or(f64::NAN),
            c.l_phi.certified.unwrap_or(f64::NAN),
            c.l_phi.sampled.unwrap_or(f64::NAN),
            c.l_pi_used,
            c.gamma13.used,
            t0.elapsed()
        );
        println!(
            "  time: resolve (P of LMI (2), MHE, MPC) {resolve_s:.2} s; certificate {:.2} s = MHE windows + certified L_Φ {:.2} + sampled L_Φ {:.2} + L_π {:.2} + γ₁,₃ {:.2} + Theorem 1 {:.2}",
            times.total_s,
            times.mhe_constants_s,
            times.l_phi_sampling_s,
            times.l_pi_s,
            times.gamma13_s,
            times.theorem1_s
        );
        for sc in &c.solvers {
            match sc.k_min {
                Some(k) => {
                    let g = sc.at_k_min.as_ref().map_or(f64::NAN, |g| g.margin);
                    println!(
                        "  {:<5} φ = {:.3e}·{:.6}^K  K_min = {k}  (margin {g:.3e}; with sampled L_Φ: {:?})",
                        sc.solver.name(),
                        sc.phi_prefactor,
                        sc.phi_rate,
                        sc.k_min_with_sampled_l_phi
                    );
                }
                None => println!(
                    "  {:<5} void: {}",
                    sc.solver.name(),
                    iss_certificate::outcome::VoidReason::join(&sc.void_reasons)
                ),
            }
        }
    }
    Ok(())
}
