//! ρ_lin(K) on a log-spaced K grid for every MHE solver of a scenario (exact MPC), with
//! K_lin and every K where ρ_lin ≥ 1.
//!
//! ```text
//! cargo run -p iss-certificate --example linear_stability -- SCENARIO.toml [FROM TO POINTS]
//! ```
//! (default grid 1…2000, 25 points).

use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
use iss_certificate::linear::linear_stability;
use iss_certificate::linear::log_spaced;
use qp_iter::Method;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: linear_stability SCENARIO.toml [FROM TO POINTS]")?;
    let num = |i: usize, default: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let grid = log_spaced(num(1, 1)?, num(2, 2000)?, num(3, 25)?);
    let resolved = Scenario::from_file(path)?.resolve()?;
    let scenario = resolved.scenario();
    let mut reports = Vec::new();
    for method in Method::PRESETS {
        let mut o = LoopOptions::from_scenario(scenario)?;
        o.method = method;
        o.controller = ControllerChoice::ExactMpc;
        reports.push(linear_stability(&resolved, &o, &grid, faer::Par::Seq)?);
    }
    println!(
        "# {} ({path}), exact MPC, dim X = {}",
        scenario.name, reports[0].dim
    );
    print!("{:>6}", "K");
    for r in &reports {
        print!(" {:>10}", r.solver.name());
    }
    println!();
    for (i, k) in grid.iter().enumerate() {
        print!("{k:>6}");
        for r in &reports {
            print!(" {:>10.6}", r.rho_lin[i].1);
        }
        println!();
    }
    for r in &reports {
        println!(
            "{:>8}: K_lin = {}, ρ_lin ≥ 1 at K = {:?}",
            r.solver.name(),
            r.k_lin.map_or("none on the grid".into(), |k| k.to_string()),
            r.unstable_ks
        );
    }
    Ok(())
}
