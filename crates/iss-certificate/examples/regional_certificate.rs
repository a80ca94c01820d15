//! The regional certificate (issue 27) of a scenario for PG, FISTA, ADMM and ADMM α = 2
//! with the exact MPC: K_lin (necessary), K_reg (the smallest K whose certified region
//! contains the scenario's own uncertainty), and the region at K_reg — or, when no K up to
//! K_MAX contains it, the limiting constraint and by how much.
//!
//! ```text
//! cargo run --release -p iss-certificate --example regional_certificate -- SCENARIO.toml [K_MAX]
//! ```
//! The uncertainty is `certificate.x0_radius` / `prior_error` / `w_bar` of the file
//! (defaults: 0, ‖prior − x₀‖, the largest ‖w‖ of the uniform noise).

use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
use iss_certificate::linear::linear_stability;
use iss_certificate::linear::log_spaced;
use iss_certificate::regional::{RegionalOptions, k_reg_probing, regional_certificate};
use qp_iter::Method;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: regional_certificate SCENARIO.toml [K_MAX]")?;
    let k_max: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(4096);
    let resolved = Scenario::from_file(path)?.resolve()?;
    let scenario = resolved.scenario();
    let ro = RegionalOptions::from_scenario(&resolved, ControllerChoice::ExactMpc)?;
    println!(
        "# {} ({path}): x0 = {:?} ± {}, prior error ≤ {:.4}, w̄ = {:.4}",
        scenario.name, ro.x0_nominal, ro.x0_radius, ro.prior_error, ro.w_bar
    );
    let grid = log_spaced(1, 2000, 25);
    for method in Method::PRESETS {
        let t0 = std::time::Instant::now();
        let mut o = LoopOptions::from_scenario(scenario)?;
        o.method = method;
        o.controller = ControllerChoice::ExactMpc;
        let k_lin = linear_stability(&resolved, &o, &grid, faer::Par::Seq)
            .ok()
            .and_then(|r| r.k_lin);
        let kr = k_reg_probing(&resolved, method, &ro, k_max, k_lin.map(|k| 2 * k))?;
        let dt = t0.elapsed().as_secs_f64();
        println!(
            "\n## {method}: K_lin = {k_lin:?}, K_reg = {:?} ({dt:.1} s)",
            kr.k_reg
        );
        if let (Some(a), Some(b)) = (kr.k_reg, k_lin) {
            println!("K_reg / K_lin = {:.2}", a as f64 / b as f64);
        }
        if let Some(v) = &kr.void {
            println!("void at the largest K tried: {v}");
        }
        if let Some(p) = &kr.probe {
            match &p.certificate {
                Some(c) => println!(
                    "at 2·K_lin = {}: contains = {}, margin = {:.4e}, witness: {:?}",
                    p.k, c.contains, c.margin, c.witness
                ),
                None => println!("at 2·K_lin = {}: void: {:?}", p.k, p.void),
            }
        }
        let tried: Vec<String> = kr
            .tried
            .iter()
            .map(|(k, m)| format!("{k}:{m:.3e}"))
            .collect();
        println!("margins tried: {}", tried.join(" "));
        let shown = match (&kr.certificate, kr.k_reg) {
            (Some(c), _) => Some(c.clone()),
            (None, _) => {
                k_lin.and_then(|k| regional_certificate(&resolved, method, k.max(1), &ro).ok())
            }
        };
        if let Some(c) = shown {
            println!(
                "at K = {}: ρ_lin = {:.6}, rate λ = {:.6} ({}), dim X = {}, rows {} + {} (start-up)",
                c.k, c.rho_lin, c.rate, c.metric, c.dim, c.rows.0, c.rows.1
            );
            println!(
                "  radius r_max = {:.4e}, ‖X_M‖_P ≤ {:.4e}, invariant radius bw̄/(1−λ) = {:.4e}, contains = {}, margin = {:.4e}",
                c.radius, c.initial_radius, c.invariant_radius, c.contains, c.margin
            );
            println!("  limiting full-window row: {:?}", c.radius_limit);
            println!(
                "  start-up holds = {}, tightest start-up row: {:?}",
                c.startup_holds, c.startup_limit
            );
            println!(
                "  largest certified: x0_radius {:.4e}, prior_error {:.4e}, w̄ {:.4e}",
                c.max_x0_radius, c.max_prior_error, c.max_w_bar
            );
            println!(
                "  certified asymptotic gains: sup‖x‖ ≤ {:.4e}·w̄, sup‖e‖ ≤ {:.4e}·w̄",
                c.gain_x, c.gain_e
            );
        }
    }
    Ok(())
}
