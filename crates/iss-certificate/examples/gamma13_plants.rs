//! γ₁,₃ and L_π on the test plants of issue 11 (the builders of `tests/all/plants.rs`):
//! certified (family bound, enumeration, linear), sampled, and the time each takes.
//! Run: `cargo run --release -p iss-certificate --example gamma13_plants`.
#![allow(clippy::unwrap_used)]

#[path = "../tests/all/plants.rs"]
mod plants;

use std::time::Instant;

use iss_certificate::certificate::{CertificateOptions, certify_closed_loop};
use iss_certificate::gamma13::{gamma13_certified, gamma13_sampled};
use lti_model::BoxSet;
use mpc_core::{CondensedMpc, ExactMpc};

fn show(name: &str, mpc: &CondensedMpc, steps: usize) {
    let t0 = Instant::now();
    let c = gamma13_certified(mpc, 14).unwrap();
    let t_cert = t0.elapsed();
    let t0 = Instant::now();
    let l = mpc.lipschitz_certified().unwrap();
    let l_enum = mpc.lipschitz_enumerated(14).unwrap();
    let t_l = t0.elapsed();
    let t0 = Instant::now();
    let mut exact = ExactMpc::new(mpc).unwrap();
    let s = gamma13_sampled(
        &mut exact,
        mpc.system(),
        &[0.01, 0.1, 1.0, 10.0],
        12,
        steps,
        1,
    )
    .unwrap();
    let t_s = t0.elapsed();
    println!(
        "== {name}: N·n_u = {}, s = {}, pattern blocks {} ({} families)",
        c.variables, c.saturable, c.pattern_blocks, c.pattern_families
    );
    println!(
        "  γ₁,₃ certified {:.4} ({:?}, {:?}); family {:.4}; enumerated {:?}; linear {:?}; sampled ≥ {:.4}",
        c.gamma13,
        c.method,
        c.metric,
        c.gamma13_polynomial,
        c.gamma13_enumerated,
        c.gamma13_linear,
        s.gamma13_lower
    );
    if let Some(v) = &c.void {
        println!("  void: {v}");
    }
    for sk in &c.skipped {
        println!("  {sk}");
    }
    for m in &c.candidates {
        println!(
            "    {:<28} λ_S {:.4} (enum {:?})  g_S {:.4}  √cond {:.3}  γ {:.4}",
            m.metric,
            m.contraction,
            m.contraction_enumerated,
            m.input_gain,
            m.condition_sqrt,
            m.gamma13
        );
    }
    println!(
        "  L_π: family {:.4}, enumerated {:?}, bound (b) {:.4}, unconstrained ‖E₀H⁻¹F‖ {:.4}",
        l.polynomial, l_enum, l.first_block, l.unconstrained_gain
    );
    println!(
        "  time: γ₁,₃ certified {t_cert:.2?}, L_π {t_l:.2?}, sampled ({} seq × {steps}) {t_s:.2?}",
        s.sequences
    );
}

fn main() {
    let whole = BoxSet::whole(1);
    let mpc = plants::cart_pendulum_mpc(0.02, whole.clone());
    println!(
        "pendulum open-loop ρ(A) = {:.4}",
        lti_model::system::spectral_radius(mpc.system().a()).unwrap()
    );
    show("cart-pendulum Ts=0.02, 𝒰 = ℝ", &mpc, 400);
    show(
        "cart-pendulum Ts=0.1, 𝒰 = ℝ",
        &plants::cart_pendulum_mpc(0.1, whole),
        200,
    );
    show(
        "cart-pendulum Ts=0.02, |u| ≤ 5",
        &plants::cart_pendulum_mpc(0.02, BoxSet::symmetric(&[5.0]).unwrap()),
        40,
    );
    let sc = closed_loop::scenario::Scenario::from_file("scenarios/case-study.toml").unwrap();
    show(
        "case study",
        &CondensedMpc::new(&sc.plant, sc.mpc.as_ref().unwrap().config(&sc.sets)).unwrap(),
        40,
    );
    for d in [0.0, 0.1, 0.5] {
        for n in [10, 30] {
            show(
                &format!("mass chain c={d}, N={n}"),
                &plants::mass_chain_mpc(d, n),
                40,
            );
        }
    }
    // The whole certificate (default options) for n_x = 12, N·n_u = 90.
    let sc = plants::scenario(
        "chain",
        &plants::mass_chain(0.5),
        Some(0.5),
        30,
        1.0,
        &[1.0; 12],
    );
    let t0 = Instant::now();
    let c = certify_closed_loop(
        &sc.clone().resolve().unwrap(),
        &CertificateOptions::default(),
    )
    .unwrap();
    println!(
        "certify_closed_loop, mass chain c=0.5, N=30 (default options): {:.2?}; γ₁,₃ {:.4}, L_π {:.4}, K_min {:?}",
        t0.elapsed(),
        c.gamma13.used,
        c.l_pi_used,
        c.solvers
            .iter()
            .map(|s| (s.solver, s.k_min))
            .collect::<Vec<_>>()
    );
    println!("{}", c.gamma13);
}
