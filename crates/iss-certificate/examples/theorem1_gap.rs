//! Why Theorem 1's K_min stays above 10·K_lin (issue 27, item 2's measured alternative): for
//! every method of a scenario, K_lin (the exact linear boundary, a floor for any sound
//! certificate), K_min (Theorem 1), and at K = 10·K_lin the small-gain sum sg1 + sg2 + sg3 with
//! the share of the binding product and the constants it multiplies — so the factor by which
//! those constants would have to shrink for Theorem 1 to certify 10·K_lin is printed, measured.
//!
//! ```text
//! cargo run --release -p iss-certificate --example theorem1_gap -- SCENARIO.toml [...]
//! ```

use closed_loop::scenario::{LoopOptions, Scenario};
use iss_certificate::certificate::{CertificateOptions, certify_closed_loop};
use iss_certificate::linear::{linear_stability, log_spaced};
use lti_model::numfmt::sig4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: theorem1_gap SCENARIO.toml [...]".into());
    }
    println!(
        "| scenario | method | K_lin | K_φ | K_min | K_min/K_lin | φ(10·K_lin) | sg1 + sg2 + sg3 \
         at 10·K_lin | binding | γ₁,₃ | L_Φ | L_π | √(2Λ^H̄_P) | 1/(1 − √ρ^M) | M(‖C‖ + L_π) |"
    );
    println!(
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for path in &paths {
        let scenario = Scenario::from_file(path)?;
        let opts = CertificateOptions {
            phase_seconds: scenario.certificate.phase_seconds(),
            ..CertificateOptions::default()
        };
        let resolved = scenario.resolve()?;
        let cert = certify_closed_loop(&resolved, &opts)?;
        let name = &resolved.scenario().name;
        for s in &cert.solvers {
            let Some(k_min) = s.k_min else {
                println!(
                    "| {name} | {} | | | void | | | | {} | | | | | | |",
                    s.solver,
                    s.void_reasons
                        .first()
                        .map_or(String::new(), |r| r.to_string().replace('|', "\\|"))
                );
                continue;
            };
            let mut o = LoopOptions::from_scenario(resolved.scenario())?;
            o.method = s.solver;
            let grid = log_spaced(1, k_min.max(2), 40);
            let k_lin = match linear_stability(&resolved, &o, &grid, faer::Par::Seq) {
                Ok(r) => r.k_lin.ok_or_else(|| format!("none ≤ {k_min}")),
                Err(e) => Err(format!(
                    "not defined: {}",
                    e.to_string().replace('|', "\\|")
                )),
            };
            let a = &s.analysis;
            let i = &a.inputs;
            // K_φ: the first K whose certified contraction φ(K) (Assumption 5) is below 1 —
            // below it no constant of Theorem 1 matters.
            let k_phi = {
                let (mut lo, mut hi) = (0usize, 1usize);
                while a.phi(hi) >= 1.0 && hi < 1 << 40 {
                    lo = hi;
                    hi *= 2;
                }
                while hi - lo > 1 {
                    let mid = lo + (hi - lo) / 2;
                    if a.phi(mid) < 1.0 { hi = mid } else { lo = mid }
                }
                hi
            };
            let m = i.horizon as f64;
            let consts = format!(
                "{} | {} | {} | {} | {} | {}",
                sig4(i.gamma13),
                sig4(a.l_phi_used),
                sig4(i.l_pi),
                sig4((2.0 * a.lambda_hp).sqrt()),
                sig4(1.0 / (1.0 - a.rho.powi(i.horizon as i32).sqrt())),
                sig4(m * (i.c_norm + i.l_pi)),
            );
            let k_lin = match k_lin {
                Ok(k) => k,
                Err(why) => {
                    println!(
                        "| {name} | {} | {why} | {k_phi} | {k_min} | | | | | {consts} |",
                        s.solver
                    );
                    continue;
                }
            };
            let g = a.at(10 * k_lin);
            let total = g.sg1 + g.sg2 + g.sg3;
            let (which, part) = [("sg1", g.sg1), ("sg2", g.sg2), ("sg3", g.sg3)]
                .into_iter()
                .fold(
                    ("", f64::NEG_INFINITY),
                    |b, c| if c.1 > b.1 { c } else { b },
                );
            let binding = if g.phi >= 1.0 {
                "φ ≥ 1".to_string()
            } else if g.certified {
                "certified".to_string()
            } else {
                format!("{which} ({:.0} %)", 100.0 * part / total)
            };
            println!(
                "| {name} | {} | {k_lin} | {k_phi} | {k_min} | {} | {} | {} | {binding} | {consts} |",
                s.solver,
                sig4(k_min as f64 / k_lin as f64),
                sig4(g.phi),
                if g.phi < 1.0 {
                    sig4(total)
                } else {
                    "—".into()
                },
            );
        }
    }
    Ok(())
}
