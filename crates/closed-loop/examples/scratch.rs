#![allow(clippy::unwrap_used)]
#[path = "../tests/all/plants.rs"]
mod plants;
use closed_loop::certificate::{certify_closed_loop, CertificateOptions};
use closed_loop::gamma13::gamma13_certified;
fn main() {
    for d in [0.02, 0.05, 0.1, 0.2] {
        let mpc = plants::mass_chain_mpc(d, 10);
        let c = gamma13_certified(&mpc, 14).unwrap();
        println!("c={d}: γ {:.3} void {:?}", c.gamma13, c.void.map(|v| v.to_string()));
    }
    let opts = CertificateOptions { lipschitz_pairs: 50, gamma13_sequences: 6, ..Default::default() };
    let cases = [
        ("pend-free", plants::scenario("pend", &plants::cart_pendulum(0.02), None, 10, 0.1, &[0.1, 0.0, 0.05, 0.0])),
        ("pend-5", plants::scenario("pend", &plants::cart_pendulum(0.02), Some(5.0), 10, 0.1, &[0.1, 0.0, 0.05, 0.0])),
        ("chain30", plants::scenario("chain", &plants::mass_chain(0.5), Some(0.5), 30, 1.0, &[1.0; 12])),
    ];
    for (name, sc) in cases {
        let t = std::time::Instant::now();
        let c = certify_closed_loop(&sc, &opts).unwrap();
        println!("{name}: {:.2?} γ used {} L_π {} ioss {:?}", t.elapsed(), c.gamma13.used, c.l_pi_used, c.ioss_failure);
        for s in &c.solvers { println!("   {:?} k_min {:?} {:?}", s.solver, s.k_min, s.void_reasons); }
    }
}
