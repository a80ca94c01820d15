//! Theorem 1 arithmetic checked against constants derived by hand.

use iss_certificate::analysis::{
    IssAnalysis, IssInputError, IssInputs, eta_sup_for_horizon, min_horizon_for_eta,
};

/// Inputs chosen so that every constant has a short closed form:
/// M = 1, η = 1/24 ⇒ ρ = 6^{1/1}·η = 1/4, √ρ = 1/2, ρ^M = 1/4, √(ρ^M) = 1/2;
/// λ(P) = 1, λ_max(Q) = 1, H̄ = 1 ⇒ Λ^P_P = Λ^Q_P = Λ^H̄_P = 1;
/// L_Φ = 2, L_π = 1, ‖C‖ = 1, γ₁,₃ = 1, φ(K) = 0.5ᴷ.
pub fn hand_inputs() -> IssInputs {
    IssInputs {
        horizon: 1,
        eta: 1.0 / 24.0,
        p_min: 1.0,
        p_max: 1.0,
        q_max: 1.0,
        h_bar: 1.0,
        l_phi: 2.0,
        l_pi: 1.0,
        c_norm: 1.0,
        f_norm: 1.0,
        gamma13: 1.0,
        phi_rate: 0.5,
        phi_prefactor: 1.0,
        phi_fits_eq11: true,
        lmi_certified: true,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1.0)
}

#[test]
fn every_constant_matches_the_hand_derivation() {
    let an = IssAnalysis::new(hand_inputs());
    assert!(close(an.rho, 0.25));
    assert!(an.premises_hold());
    let (s2, s3, s6) = (2f64.sqrt(), 3f64.sqrt(), 6f64.sqrt());
    for k in [3usize, 5, 6] {
        let f = 0.5f64.powi(k as i32);
        let g = an.at(k);
        assert!(close(g.phi, f));
        // C₁ = 2φL_Φ(1 + M(‖C‖ + L_π)) = 2φ·2·(1 + 2) = 12φ
        assert!(close(g.c1, 12.0 * f));
        // C₂ = 2φL_Φ(1 + M L_π) = 2φ·2·2 = 8φ
        assert!(close(g.c2, 8.0 * f));
        // C₃ = 2φL_Φ M = 4φ
        assert!(close(g.c3, 4.0 * f));
        // C_e = 2√3·φ·2·(√ρ^{-1} + L_π√ρ^{-1}) + 0 (empty sum for M = 1) + √6
        //       + 2√3·φ·2·(L_π + 1)·√ρ^{-2} = 16√3φ + √6 + 32√3φ
        assert!(close(g.c_e, 48.0 * s3 * f + s6));
        // C_w = √2·C₃ + √6/(1 − √ρ) + 4√3·φ·2·(L_π M + 1)/(1 − √ρ) = 4√2φ + 2√6 + 32√3φ
        assert!(close(g.c_w, 4.0 * s2 * f + 2.0 * s6 + 32.0 * s3 * f));
        // C_ε = √2φ + √2/(1 − √ρ^M) + 4·1·φ·2·(L_π M + 1)/(1 − √ρ^M) = √2φ + 2√2 + 32φ
        let c_eps = s2 * f + 2.0 * s2 + 32.0 * f;
        assert!(close(g.c_eps, c_eps));
        // Prop. 1 gains: C_i/(1 − φ); Prop. 3: γ₃,₁ = √(2Λ^H̄_P)C₁ = 12√2φ, γ₃,₂ = C_ε.
        assert!(close(g.gamma21, 12.0 * f / (1.0 - f)));
        assert!(close(g.gamma23, 8.0 * f / (1.0 - f)));
        assert!(close(g.gamma2w, 4.0 * f / (1.0 - f)));
        assert!(close(g.gamma2sigma, 2.0 * f / (1.0 - f)));
        assert!(close(g.gamma31, 12.0 * s2 * f));
        assert!(close(g.gamma3sigma, s2 * f * 2.0));
        // (sg1) γ₁,₃·γ₃,₁ = 12√2φ; (sg2) γ₂,₃·γ₃,₂; (sg3) γ₁,₃·γ₃,₂·γ₂,₁.
        assert!(close(g.sg1, 12.0 * s2 * f));
        assert!(close(g.sg2, 8.0 * f / (1.0 - f) * c_eps));
        assert!(close(g.sg3, c_eps * 12.0 * f / (1.0 - f)));
    }
    // By hand: sg3(K=5) = 1.4991 > 1. At K = 6 (φ = 1/64): sg1 = 12√2/64 = 0.2652,
    // sg2 = (8/63)(√2/64 + 2√2 + 1/2) = 0.4255, sg3 = (12/63)·3.3505 = 0.6382 — each below 1
    // (the paper's conditions hold), but their sum 1.3289 > 1: det(I − Γ) < 0, ρ(Γ) > 1.
    // At K = 7 (φ = 1/128): 0.1326 + 0.1946 + 0.2919 = 0.6191 < 1.
    assert!(!an.at(5).certified && !an.at(5).paper_conditions);
    let g6 = an.at(6);
    assert!(g6.paper_conditions && !g6.certified);
    assert!((g6.margin - (1.0 - 1.3289)).abs() < 1e-4, "{}", g6.margin);
    let g7 = an.at(7);
    assert!(g7.certified && (g7.margin - (1.0 - 0.6191)).abs() < 1e-4);
    assert_eq!(an.k_min(1_000_000), Some(7));
}

/// The margin is det(I − Γ) of the three-node gain matrix and its sign is ρ(Γ) < 1.
#[test]
fn margin_is_the_m_matrix_test_of_the_gain_matrix() {
    use iss_certificate::small_gain::GainMatrix;
    let an = IssAnalysis::new(hand_inputs());
    for k in 3..12 {
        let g = an.at(k);
        let mut m = GainMatrix::new(3);
        m.set(0, 2, 1.0); // γ₁,₃
        m.set(1, 0, g.gamma21);
        m.set(1, 2, g.gamma23);
        m.set(2, 0, g.gamma31);
        m.set(2, 1, g.gamma32);
        assert!((m.det_i_minus() - g.margin).abs() < 1e-12 * (1.0 + g.margin.abs()));
        assert_eq!(m.is_contracting(), g.certified, "K = {k}");
        let cycles: f64 = m.cycles().iter().map(|c| c.gain).sum();
        assert!((cycles - (g.sg1 + g.sg2 + g.sg3)).abs() < 1e-12 * cycles);
    }
}

#[test]
fn paper_parameters_void_the_certificate() {
    // The paper's case study: M = 5, η = 0.8 ⇒ 6η^M = 6·0.8⁵ = 1.966 ≥ 1, ρ = 6^{1/5}·0.8 ≈ 1.1448.
    let mut inp = hand_inputs();
    inp.horizon = 5;
    inp.eta = 0.8;
    inp.phi_rate = 0.98;
    let an = IssAnalysis::new(inp);
    assert!(!an.premises_hold());
    let bad = an.violated();
    assert_eq!(bad.len(), 1);
    assert_eq!(bad[0].name, "rho < 1");
    assert!((an.rho - 6f64.powf(0.2) * 0.8).abs() < 1e-12);
    // The fix is typed: the horizon and η it is computed from, and its sentence.
    let fix = bad[0].fix.as_ref().expect("rho < 1 fails with advice");
    assert_eq!(
        fix,
        &iss_certificate::analysis::PremiseFix::RhoAtLeastOne {
            eta: 0.8,
            horizon: 5
        }
    );
    assert!(fix.to_string().contains("M ≥ 9"), "{fix}");
    // Never a K from a void bound, however large.
    assert_eq!(an.k_min(usize::MAX / 4), None);
    assert!(!an.at(652).certified);
}

/// The hint "lower η below 6^(-1/M) = X" shows an X that is itself below the bound (rounded
/// down, never up): at M = 1, 6^(-1) = 0.16667 shows as 0.1666 (rounded to nearest it would
/// be 0.1667, above the bound), and η = X then satisfies 6η^M < 1.
#[test]
fn the_eta_hint_is_below_the_bound_it_names() {
    for m in 1..=40 {
        let mut inp = hand_inputs();
        inp.horizon = m;
        inp.eta = 0.99;
        let an = IssAnalysis::new(inp);
        let fix = an.violated()[0].fix.as_ref().expect("advice").to_string();
        let shown = fix
            .split("6^(-1/M) = ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .unwrap_or_else(|| panic!("no bound in {fix}"));
        let x: f64 = shown.parse().unwrap_or_else(|_| panic!("{shown} in {fix}"));
        let bound = eta_sup_for_horizon(m);
        assert!(x < bound, "M = {m}: shown {shown} ≥ 6^(-1/M) = {bound}");
        assert!(6.0 * x.powi(m as i32) < 1.0, "M = {m}: η = {shown}");
        // Still the bound to 4 significant digits (one unit of the last digit below).
        assert!(bound - x <= 1e-3 * bound, "M = {m}: {shown} vs {bound}");
        let digits = shown.trim_start_matches(['0', '.']).replace('.', "");
        assert!(digits.len() <= 4, "{shown}");
    }
    let mut inp = hand_inputs();
    inp.eta = 0.5;
    let an = IssAnalysis::new(inp);
    let fix = an.violated()[0].fix.as_ref().expect("advice").to_string();
    assert!(fix.contains("6^(-1/M) = 0.1666 at M = 1"), "{fix}");
}

#[test]
fn nearest_parameters_for_rho_below_one() {
    // 6·0.8⁸ = 1.0066 ≥ 1, 6·0.8⁹ = 0.8053 < 1.
    assert_eq!(min_horizon_for_eta(0.8), Some(9));
    assert_eq!(min_horizon_for_eta(1.0), None);
    // At M = 5: η < 6^{-1/5} = 0.69883.
    assert!((eta_sup_for_horizon(5) - 0.698_827).abs() < 1e-6);
}

#[test]
fn each_premise_voids_the_certificate() {
    let base = hand_inputs();
    let cases: Vec<(&str, IssInputs)> = vec![
        (
            "phi rate < 1",
            IssInputs {
                phi_rate: 1.0,
                ..base.clone()
            },
        ),
        (
            "phi fits eq. (11)",
            IssInputs {
                phi_fits_eq11: false,
                ..base.clone()
            },
        ),
        (
            "LMI (2) feasible",
            IssInputs {
                lmi_certified: false,
                ..base.clone()
            },
        ),
        (
            "gamma13 finite",
            IssInputs {
                gamma13: f64::INFINITY,
                ..base.clone()
            },
        ),
        (
            "L_Phi finite",
            IssInputs {
                l_phi: f64::NAN,
                ..base.clone()
            },
        ),
    ];
    for (name, inp) in cases {
        let an = IssAnalysis::new(inp);
        assert!(
            an.violated().iter().any(|p| p.name == name),
            "{name} not reported"
        );
        assert_eq!(an.k_min(1 << 30), None, "{name}");
    }
}

/// Mend (b) of issue 27: the measurement noise enters the data as y = Cx + Fw², so the
/// w-gains through the window data carry ‖F‖. With ‖F‖ = 3 the paper's C₃ = 2φL_ΦM (which
/// assumes F = I) understates γ₂ʷ and C_w three-fold in their C₃ part; the other constants and
/// the small-gain slopes do not depend on F.
#[test]
fn the_w_gains_carry_the_norm_of_f() {
    let one = IssAnalysis::new(hand_inputs());
    let three = IssAnalysis::new(IssInputs {
        f_norm: 3.0,
        ..hand_inputs()
    });
    let s2 = 2f64.sqrt();
    for k in [3usize, 6] {
        let (a, b) = (one.at(k), three.at(k));
        let f = a.phi;
        assert!(
            close(b.c3, 4.0 * f),
            "C₃ itself (the u/y-data coefficient) is unchanged"
        );
        assert!(close(b.c3w, 12.0 * f));
        assert!(close(b.gamma2w, 12.0 * f / (1.0 - f)));
        // The old form: γ₂ʷ = C₃/(1 − φ) without ‖F‖ — three times too small here.
        assert!(b.gamma2w > 2.9 * a.gamma2w);
        // C_w = √2·C₃‖F‖ + (terms without F).
        assert!(close(b.c_w - a.c_w, s2 * (12.0 - 4.0) * f));
        assert_eq!((a.sg1, a.sg2, a.sg3), (b.sg1, b.sg2, b.sg3));
    }
    let bad = IssAnalysis::new(IssInputs {
        f_norm: f64::NAN,
        ..hand_inputs()
    });
    assert!(!bad.premises_hold());
}

#[test]
fn l_phi_below_one_is_raised_to_one() {
    let an = IssAnalysis::new(IssInputs {
        l_phi: 0.3,
        ..hand_inputs()
    });
    assert_eq!(an.l_phi_used, 1.0);
}

#[test]
fn k_min_is_the_first_certified_k() {
    // Monotonicity of the search against a linear scan, on a grid of inputs.
    for &rate in &[0.5, 0.9, 0.98, 0.995] {
        for &g13 in &[0.1, 1.0, 28.8] {
            let an = IssAnalysis::new(IssInputs {
                phi_rate: rate,
                gamma13: g13,
                ..hand_inputs()
            });
            let k = an.k_min(1 << 20).unwrap();
            assert!(an.at(k).certified);
            assert!(k == 0 || !an.at(k - 1).certified);
            let scan = (0..=k).find(|&j| an.at(j).certified);
            assert_eq!(scan, Some(k));
        }
    }
}

/// Issue 38: `try_new` refuses a NaN in any field, and M = 0, naming the field; the valid
/// hand inputs give the analysis `new` gives.
#[test]
fn try_new_names_a_nan_field() {
    let ok = IssAnalysis::try_new(hand_inputs()).expect("valid inputs");
    assert_eq!(ok, IssAnalysis::new(hand_inputs()));
    let nan = f64::NAN;
    type Set = fn(&mut IssInputs, f64);
    let cases: [(&str, Set); 12] = [
        ("eta", |i, v| i.eta = v),
        ("p_min", |i, v| i.p_min = v),
        ("p_max", |i, v| i.p_max = v),
        ("q_max", |i, v| i.q_max = v),
        ("h_bar", |i, v| i.h_bar = v),
        ("l_phi", |i, v| i.l_phi = v),
        ("l_pi", |i, v| i.l_pi = v),
        ("c_norm", |i, v| i.c_norm = v),
        ("f_norm", |i, v| i.f_norm = v),
        ("gamma13", |i, v| i.gamma13 = v),
        ("phi_rate", |i, v| i.phi_rate = v),
        ("phi_prefactor", |i, v| i.phi_prefactor = v),
    ];
    for (field, set) in cases {
        let mut inputs = hand_inputs();
        set(&mut inputs, nan);
        let e = IssAnalysis::try_new(inputs).expect_err("NaN refused");
        assert_eq!(e, IssInputError::NaN { field });
        assert!(
            e.to_string()
                .starts_with(&format!("IssInputs::{field} is NaN"))
        );
    }
    // ±∞ is a value the premises read (an unbounded γ₁,₃ fails "gamma13 finite").
    let mut inputs = hand_inputs();
    inputs.gamma13 = f64::INFINITY;
    let an = IssAnalysis::try_new(inputs).expect("∞ is read by a premise");
    assert!(!an.premises_hold());
    let mut inputs = hand_inputs();
    inputs.horizon = 0;
    assert_eq!(
        IssAnalysis::try_new(inputs),
        Err(IssInputError::ZeroHorizon)
    );
}
