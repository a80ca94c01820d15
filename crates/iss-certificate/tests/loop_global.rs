//! The global loop certificate (`iss_certificate::lure::global`, docs/theory.md
//! "One certificate for the whole loop" §4): exact lifted dynamics, the window's optimum and
//! the iteration error as quadratic constraints.

use closed_loop::scenario::{LoopOptions, ResolvedScenario, Scenario};
use iss_certificate::lure::global::{GlobalOptions, global_loop};
use qp_iter::Method;

fn resolved(file: &str) -> ResolvedScenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    Scenario::from_file(&path)
        .expect("scenario parses")
        .resolve()
        .expect("scenario resolves")
}

fn options(r: &ResolvedScenario, method: Method) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    o
}

#[test]
#[ignore = "measurement"]
fn probe_double_integrator() {
    let r = resolved("double-integrator.toml");
    let t0 = std::time::Instant::now();
    let gl = global_loop(&r, &options(&r, Method::PG)).expect("builds");
    eprintln!("built in {:?}, n_zeta = {}", t0.elapsed(), gl.n_zeta());
    let opts = GlobalOptions::default();
    let t0 = std::time::Instant::now();
    let c = gl.certify_phi(0.0, &opts);
    eprintln!("phi=0: {:?} in {:?}", c.as_ref().map(|c| (c.rho, c.margin, c.tau)), t0.elapsed());
    let t0 = std::time::Instant::now();
    let k = gl.k_glob(&opts);
    eprintln!("k_glob: {:?} in {:?}", k.as_ref().map(|(k, c)| (*k, c.phi, c.margin, c.tau)), t0.elapsed());
}
