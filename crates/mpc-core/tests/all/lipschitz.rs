//! L_π: certified ≥ (active-set enumeration) ≥ sampled; sampled = unconstrained gain
//! where no constraint is active; determinism; the scenario report.

use faer::{Mat, Side};
use lti_model::BoxSet;
use mpc_core::{CondensedMpc, ExactMpc, lipschitz_report_for, lipschitz_sampled};

use crate::common::*;

/// max over all free sets f ⊆ {0..n} of ‖E₀J_f‖₂ with J_f = −H_ff⁻¹F_f on f and 0 off f:
/// the Jacobians of every affine piece π can have. π is continuous and piecewise affine,
/// so its exact Lipschitz constant is at most this (brute force, small n only).
fn enumerated_bound(mpc: &CondensedMpc) -> f64 {
    let qp = mpc.qp();
    let (n, nx, nu) = (qp.n(), mpc.nx(), mpc.nu());
    assert!(n <= 12);
    let (h, f) = (qp.h(), qp.f());
    let mut best = 0.0_f64;
    for mask in 1u32..(1 << n) {
        let free: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
        if !free.iter().any(|&i| i < nu) {
            continue;
        }
        let nf = free.len();
        let hff = Mat::from_fn(nf, nf, |a, b| h[(free[a], free[b])]);
        let ff = Mat::from_fn(nf, nx, |a, j| f[(free[a], j)]);
        let llt = hff.llt(Side::Lower).unwrap();
        let jf = faer::linalg::solvers::Solve::solve(&llt, ff);
        let rows: Vec<usize> = (0..nf).filter(|&a| free[a] < nu).collect();
        let e0j = Mat::from_fn(rows.len(), nx, |a, j| jf[(rows[a], j)]);
        best = best.max(lti_model::matrix::spectral_norm(e0j.as_ref()));
    }
    best
}

#[test]
fn case_study_certified_at_least_sampled() {
    let mpc = case_study_mpc();
    let c = mpc.lipschitz_certified().unwrap();
    let s = mpc.lipschitz_sampled(400, 2304, 40.0).unwrap();
    assert!(
        s.estimate <= c.l_pi() * (1.0 + 1e-9),
        "sampled {} > certified {}",
        s.estimate,
        c.l_pi()
    );
    assert!(c.first_block <= c.sequence * (1.0 + 1e-12));
    assert!(c.origin_interior);
    // The sampled maximum is at least the unconstrained gain (attained near 0 by
    // directed pairs) up to finite-difference error; the certificate is not vacuous.
    assert!(
        s.estimate >= 0.5 * c.unconstrained_gain,
        "{} vs {}",
        s.estimate,
        c.unconstrained_gain
    );
    assert!(
        s.switches_located > 10,
        "only {} switches located",
        s.switches_located
    );
    // Bound (b) from its definition with an independent H^{-1/2} (eigendecomposition).
    let h = mpc.qp().h().to_owned();
    let e = h.self_adjoint_eigen(Side::Lower).unwrap();
    let n = h.nrows();
    let d = Mat::from_fn(
        n,
        n,
        |i, j| if i == j { 1.0 / e.S()[i].sqrt() } else { 0.0 },
    );
    let h_is = e.U() * &d * e.U().transpose();
    let c_ref = lti_model::matrix::spectral_norm((&h_is * mpc.qp().f()).as_ref());
    let e0_ref = lti_model::matrix::spectral_norm(h_is.as_ref().submatrix(0, 0, 2, n));
    assert!((c.h_inv_sqrt_f - c_ref).abs() <= 1e-9 * c_ref);
    assert!((c.e0_h_inv_sqrt - e0_ref).abs() <= 1e-9 * e0_ref);
    assert!((c.sequence - c_ref / e.S()[0].sqrt()).abs() <= 1e-9 * c.sequence);
}

#[test]
fn random_systems_certified_enumerated_sampled_sandwich() {
    let mut checked = 0;
    for seed in 0..40 {
        let (sys, cfg) = random_problem(4000 + seed);
        if cfg.horizon * sys.nu() > 8 {
            continue;
        }
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        let c = mpc.lipschitz_certified().unwrap();
        let enumerated = enumerated_bound(&mpc);
        let s = mpc.lipschitz_sampled(120, seed, 5.0).unwrap();
        assert!(
            enumerated <= c.l_pi() * (1.0 + 1e-9),
            "seed {seed}: enumerated {enumerated} > certified {}",
            c.l_pi()
        );
        assert!(
            s.estimate <= enumerated * (1.0 + 1e-6) + 1e-9,
            "seed {seed}: sampled {} > enumerated {enumerated}",
            s.estimate
        );
        assert!(s.estimate <= c.l_pi() * (1.0 + 1e-9));
        // The library's allocation-free enumeration agrees with this faer-based one.
        let fast = mpc.lipschitz_enumerated(8).unwrap().unwrap();
        assert!(
            (fast - enumerated).abs() <= 1e-10 * enumerated.max(1e-300),
            "seed {seed}: {fast} vs {enumerated}"
        );
        checked += 1;
    }
    assert!(checked >= 15, "only {checked} small random problems");
}

#[test]
fn sampled_equals_unconstrained_gain_inside_the_unconstrained_ball() {
    // For ‖x‖ ≤ r₀ = min_i b_i/‖row_i(H⁻¹F)‖ no bound is active, π(x) = −E₀H⁻¹Fx, and the
    // directed pairs attain ‖E₀H⁻¹F‖₂.
    let mpc = case_study_mpc();
    let c = mpc.lipschitz_certified().unwrap();
    let qp = mpc.qp();
    let llt = qp.h().to_owned().llt(Side::Lower).unwrap();
    let g = faer::linalg::solvers::Solve::solve(&llt, qp.f());
    let r0 = (0..qp.n())
        .map(|i| {
            let row = (0..4).map(|j| g[(i, j)] * g[(i, j)]).sum::<f64>().sqrt();
            1.0 / row // bounds are ±1
        })
        .fold(f64::INFINITY, f64::min);
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let s = lipschitz_sampled(&mut exact, 40, 5, 0.5 * r0, None).unwrap();
    assert!(
        (s.estimate - c.unconstrained_gain).abs() <= 1e-6 * c.unconstrained_gain,
        "{} vs {}",
        s.estimate,
        c.unconstrained_gain
    );
}

#[test]
fn sampling_is_deterministic_and_validates_parameters() {
    let (sys, cfg) = random_problem(4001);
    let mpc = CondensedMpc::new(&sys, cfg).unwrap();
    let a = mpc.lipschitz_sampled(40, 3, 2.0).unwrap();
    let b = mpc.lipschitz_sampled(40, 3, 2.0).unwrap();
    assert_eq!(a, b);
    assert!(matches!(
        mpc.lipschitz_sampled(0, 3, 2.0),
        Err(mpc_core::MpcError::Parameter {
            name: "n_pairs",
            ..
        })
    ));
    for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            mpc.lipschitz_sampled(4, 3, r),
            Err(mpc_core::MpcError::Parameter { name: "radius", .. })
        ));
    }
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let wrong = BoxSet::whole(sys.nx() + 1);
    assert!(matches!(
        lipschitz_sampled(&mut exact, 4, 3, 1.0, Some(&wrong)),
        Err(mpc_core::MpcError::Dimension { name: "domain", .. })
    ));
}

#[test]
fn domain_box_keeps_samples_inside() {
    let mpc = case_study_mpc();
    let dom = BoxSet::new(vec![0.0, -1.0, -1.0, -1.0], vec![2.0, 1.0, 1.0, 1.0]).unwrap();
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let s = lipschitz_sampled(&mut exact, 20, 8, 5.0, Some(&dom)).unwrap();
    use lti_model::ConvexSet;
    assert!(dom.contains(&s.worst_x, 0.0) && dom.contains(&s.worst_x_prime, 0.0));
}

#[test]
fn report_for_the_case_study_scenario() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/case-study.toml"
    );
    // The [mpc] section of the scenario file, with its input set.
    let text = std::fs::read_to_string(path).unwrap();
    let section = text
        .split("[mpc]")
        .nth(1)
        .unwrap()
        .split("\n[")
        .next()
        .unwrap();
    let raw: mpc_core::RawMpc = lti_model::spec::format::parse(section).unwrap();
    let plant = lti_model::presets::case_study_plant();
    let settings = mpc_core::MpcSettings::from_raw(&raw, &plant).unwrap();
    let sets = lti_model::spec::ScenarioSets {
        state: lti_model::BoxSet::whole(4),
        input: lti_model::BoxSet::symmetric(&[1.0, 1.0]).unwrap(),
        output: lti_model::BoxSet::whole(1),
        disturbance: lti_model::BoxSet::whole(5),
    };
    let mpc = CondensedMpc::new(&plant, settings.config(&sets)).unwrap();
    let report = lipschitz_report_for(&mpc, 100, 1, 2.0 * 444f64.sqrt()).unwrap();
    assert!(report.consistent());
    // Case study: N·n_u = 20, so the enumerated bound is computed and sandwiched.
    let e = report.enumerated.unwrap();
    assert!(
        report.sampled.estimate <= e * (1.0 + 1e-9)
            && e <= report.certified.first_block * (1.0 + 1e-12)
    );
    assert!(e >= report.certified.unconstrained_gain * (1.0 - 1e-12));
    // The scenario's MPC is the case-study one.
    let c = case_study_mpc().lipschitz_certified().unwrap();
    assert!((report.certified.l_pi() - c.l_pi()).abs() <= 1e-12 * c.l_pi());
    // radius = 2·max(‖x₀‖, ‖prior‖) = 2·‖(12, −10, 10, −10)‖.
    assert!((report.sampled.radius - 2.0 * 444f64.sqrt()).abs() < 1e-12);
    let text = report.to_string();
    println!("{text}");
    assert!(
        text.contains("certified L_π")
            && text.contains("sampled")
            && text.contains("L_enum")
            && text.contains(": yes"),
        "{text}"
    );
}
