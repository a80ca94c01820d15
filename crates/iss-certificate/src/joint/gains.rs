//! The gains of the four-subsystem interconnection at (K_e, K_c) and its premises.

#[cfg(feature = "serde")]
use serde::Serialize;

use crate::analysis::{GainsAtK, IssAnalysis, IssInputs, Premise, PremiseFix};
use crate::small_gain::{Cycle, GainMatrix};

/// Node names of the gain graph, in the order of [`JointGains::matrix`].
pub const NODE_NAMES: [&str; 4] = ["x", "epsilon", "e", "delta"];

/// Constants of the sub-optimal MPC (node 4).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct MpcMapInputs {
    /// L_U: Lipschitz constant of x ↦ U*(x), the whole optimal input sequence.
    pub l_u: f64,
    /// φ_c(K) = prefactor · rateᴷ of the MPC's iteration map.
    pub phi_rate: f64,
    /// Prefactor of φ_c.
    pub phi_prefactor: f64,
    /// φ_c bounds ‖Uᴷ − U*‖ in the Euclidean norm with a feasible iterate (eq. (11) for the
    /// MPC's QP).
    pub phi_fits_eq11: bool,
    /// ω = ‖W‖₂ of the warm start U⁰_t = W Uᴷᶜ_{t−1}.
    pub warm_gain: f64,
    /// The warm start rule, for display.
    pub warm_start: String,
    /// U*(0) = 0 (0 ∈ 𝒰^N and the MPC's QP has no constant linear term).
    pub origin_fixed: bool,
}

/// Inputs of the joint certificate.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct JointInputs {
    /// Theorem 1's inputs for the MHE side (φ_e of the MHE's map).
    pub mhe: IssInputs,
    /// γ₁,₄: gain from the MPC's input error d to x, from the same estimate as γ₁,₃.
    pub gamma14: f64,
    /// The MPC side.
    pub mpc: MpcMapInputs,
}

/// The four-node small-gain analysis (module docs of [`crate::joint`]).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct JointAnalysis {
    /// The inputs.
    pub inputs: JointInputs,
    /// Theorem 1's analysis of the MHE side (constants of Props. 1 and 3).
    pub theorem1: IssAnalysis,
    /// Every K-independent premise: Theorem 1's and the MPC side's.
    pub premises: Vec<Premise>,
    /// Both maps' rounding in a given precision (None: exact arithmetic, the f64 certificate
    /// as computed): [`JointAnalysis::with_rounding`].
    #[cfg_attr(feature = "serde", serde(skip))]
    rounding: Option<JointRounding>,
}

/// The rounding of the loop run in unit round-off u (docs/theory.md, "The joint certificate
/// in f32"): the MHE's K-step models folded into Theorem 1's constants, and the MPC's K-step
/// model on its QP, ‖Uᴷ − U*‖ ≤ Φ_u(K)‖U⁰ − U*‖ + B_z‖U*‖ + B_θ‖x̂‖ + C_d (Euclidean).
#[derive(Debug, Clone, PartialEq)]
pub struct JointRounding {
    pub(crate) u: f64,
    pub(crate) mhe: crate::certificate::precision::Fold,
    /// The MPC's K-step model in its norm (‖D⁻¹·‖ for a Jacobi method).
    pub(crate) mpc: crate::lure::global::StepRounding,
    /// κ(D) and d_max of the MPC's scaling (1, 1 without one).
    pub(crate) mpc_kappa: f64,
    pub(crate) mpc_d_max: f64,
}

impl JointRounding {
    /// Φ_u(K_c) in the Euclidean norm from the exact φ_c(K_c), non-increasing in K_c (the
    /// model's envelope over every K' ≥ K_c).
    fn mpc_phi(&self, phi_c: f64, k_c: usize) -> f64 {
        self.mpc_kappa * self.mpc.phi_u(phi_c / self.mpc_kappa, k_c)
    }

    /// (B_zL_U + B_θ, C_d): the MPC rounding's gain from ‖x̂_t‖ into δ_t and its constant.
    fn mpc_input(&self, l_u: f64) -> (f64, f64) {
        let d = self.mpc_d_max;
        (
            d * (self.mpc.beta_z() * l_u + self.mpc.beta_theta()),
            d * self.mpc.offset_d(),
        )
    }
}

/// Gains, cycles and the verdict at one pair (K_e, K_c).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct JointGains {
    /// MHE iterations per step.
    pub k_e: usize,
    /// MPC iterations per step.
    pub k_c: usize,
    /// Props. 1 and 3 at K_e (C₁…C₆, γ₂,·, γ₃,·; its `margin` is Theorem 1's, not this one).
    pub mhe: GainsAtK,
    /// φ_c(K_c).
    pub phi_c: f64,
    /// φ_c(K_c)·ω: the contraction of δ_t (must be < 1).
    pub delta_rate: f64,
    /// γ₁,₃ (e → x).
    pub gamma13: f64,
    /// γ₁,₄ (δ → x).
    pub gamma14: f64,
    /// γ₂,₄ = C₃/(1 − φ_e) (δ → ε).
    pub gamma24: f64,
    /// γ₃,₄ = √(2Λ^H̄_P)·C₃ (δ → e).
    pub gamma34: f64,
    /// γ₄,₁ = φ_c L_U (1 + ω)/(1 − φ_c ω) (x → δ).
    pub gamma41: f64,
    /// γ₄,₃ = γ₄,₁ (e → δ).
    pub gamma43: f64,
    /// The rounding's self-loop on e (x̂'s propagation; 0 in exact arithmetic).
    pub self_loop: f64,
    /// The constant the rounding adds to δ_t's bound: C_d/(1 − Φ_u ω) (0 in exact
    /// arithmetic); the certificate is then ISS up to an offset.
    pub delta_offset: f64,
    /// Γ row-major (4 × 4, row i: gains into node i; nodes [`NODE_NAMES`]).
    pub matrix: [f64; 16],
    /// Every simple cycle and its gain.
    pub cycles: Vec<Cycle>,
    /// Every cycle gain < 1 (the max-form condition; necessary).
    pub cycles_hold: bool,
    /// ρ(Γ).
    pub spectral_radius: f64,
    /// 1 − ρ(Γ): the certified margin (> 0 iff certified, premises holding).
    pub margin: f64,
    /// Premises hold, φ_e(K_e) < 1, φ_c ω < 1 and ρ(Γ) < 1.
    pub certified: bool,
}

fn premise(name: &str, needed_by: &str, holds: bool, value: f64, fix: PremiseFix) -> Premise {
    Premise {
        name: name.into(),
        needed_by: needed_by.into(),
        holds,
        value,
        margin: Some(if holds { 1.0 } else { -1.0 }),
        fix: (!holds).then_some(fix),
        not_evaluated: None,
    }
}

impl JointAnalysis {
    /// Checks the premises of both sides.
    pub fn new(inputs: JointInputs) -> Self {
        let theorem1 = IssAnalysis::new(inputs.mhe.clone());
        let mut premises = theorem1.premises.clone();
        let m = &inputs.mpc;
        premises.push(premise(
            "gamma14 finite",
            "subsystem 1 under the applied input π(x̂) + d (Assumption 4 with d)",
            inputs.gamma14.is_finite() && inputs.gamma14 >= 0.0,
            inputs.gamma14,
            PremiseFix::Gamma14Unknown,
        ));
        premises.push(premise(
            "MPC phi fits eq. (11)",
            "subsystem 4 (‖Uᴷᶜ − U*‖ ≤ φ_c(K_c)‖U⁰ − U*‖, feasible Uᴷᶜ)",
            m.phi_fits_eq11,
            f64::from(u8::from(m.phi_fits_eq11)),
            PremiseFix::MpcPhiNotEq11,
        ));
        premises.push(premise(
            "MPC phi rate < 1",
            "subsystem 4 (φ_c ∈ 𝓛)",
            m.phi_rate >= 0.0 && m.phi_rate < 1.0 && m.phi_prefactor.is_finite(),
            m.phi_rate,
            PremiseFix::MpcPhiRateAtLeastOne,
        ));
        premises.push(premise(
            "U*(0) = 0",
            "subsystem 4 (‖U*(x̂)‖ ≤ L_U‖x̂‖)",
            m.origin_fixed,
            f64::from(u8::from(m.origin_fixed)),
            PremiseFix::MpcOriginNotFixed,
        ));
        premises.push(premise(
            "L_U finite",
            "subsystem 4 (Lipschitz constant of x ↦ U*(x))",
            m.l_u.is_finite() && m.l_u >= 0.0,
            m.l_u,
            PremiseFix::NotFinite { name: "L_U".into() },
        ));
        premises.push(premise(
            "warm-start gain finite",
            "subsystem 4 (‖W‖₂ of the warm start)",
            m.warm_gain.is_finite() && m.warm_gain >= 0.0,
            m.warm_gain,
            PremiseFix::WarmGainNotFinite,
        ));
        Self {
            inputs,
            theorem1,
            premises,
            rounding: None,
        }
    }

    /// The same analysis for the loop run in a rounded scalar ([`JointRounding`]): every
    /// verdict, floor and region then holds for the computed iterations.
    pub fn with_rounding(self, rounding: JointRounding) -> Self {
        Self {
            rounding: Some(rounding),
            ..self
        }
    }

    /// The rounding this analysis carries (None: exact arithmetic).
    pub fn rounding(&self) -> Option<&JointRounding> {
        self.rounding.as_ref()
    }

    /// Whether every K-independent premise holds.
    pub fn premises_hold(&self) -> bool {
        self.premises.iter().all(|p| p.holds)
    }

    /// The premises that fail.
    pub fn violated(&self) -> Vec<&Premise> {
        self.premises.iter().filter(|p| !p.holds).collect()
    }

    /// φ_c(K_c).
    pub fn phi_c(&self, k_c: usize) -> f64 {
        let m = &self.inputs.mpc;
        m.phi_prefactor * m.phi_rate.powi(i32::try_from(k_c).unwrap_or(i32::MAX))
    }

    /// Gains, cycles and verdict at (K_e, K_c) (computed even when premises fail).
    pub fn at(&self, k_e: usize, k_c: usize) -> JointGains {
        let m = &self.inputs.mpc;
        let omega = m.warm_gain;
        // Exact arithmetic, or (docs/theory.md, "The joint certificate in f32") the MHE's
        // fold — φ_u, φL_Φ → φ_uL_Φ + g_d in every data gain (C₃ with it: δ enters θ through
        // the u window), x̂'s propagation into e (γ₃,₁, γ₃,₂, a self-loop s, and its θ gain
        // on the M inputs of the window into γ₃,₄) — and the MPC's model: δ_t ≤ Φ_uωδ_{t−1}
        // + Φ_uωL_U‖x̂_{t−1}‖ + (Φ_uL_U + B_zL_U + B_θ)‖x̂_t‖ + C_d.
        let (g, gamma31, gamma32, self_loop, theta_m, phi_c, mpc_gain, mpc_offset) =
            match &self.rounding {
                None => {
                    let g = self.theorem1.at(k_e);
                    let (g31, g32) = (g.gamma31, g.gamma32);
                    (g, g31, g32, 0.0, 0.0, self.phi_c(k_c), 0.0, 0.0)
                }
                Some(r) => {
                    let f = r.mhe.at(&self.theorem1, k_e, r.u);
                    let (gain, offset) = r.mpc_input(m.l_u);
                    let theta_m = f.theta_gain * self.inputs.mhe.horizon as f64;
                    let phi_c = r.mpc_phi(self.phi_c(k_c), k_c);
                    let mut g = f.gains;
                    g.phi = f.phi;
                    (
                        g,
                        f.gamma31,
                        f.gamma32,
                        f.self_loop,
                        theta_m,
                        phi_c,
                        gain,
                        offset,
                    )
                }
            };
        let delta_rate = phi_c * omega;
        let gamma13 = self.inputs.mhe.gamma13;
        let gamma14 = self.inputs.gamma14;
        let gamma24 = g.c3 / (1.0 - g.phi);
        let gamma34 = (2.0 * self.theorem1.lambda_hp).sqrt() * g.c3 + theta_m;
        let gamma41 = if delta_rate < 1.0 {
            (phi_c * m.l_u * (1.0 + omega) + mpc_gain) / (1.0 - delta_rate)
        } else {
            f64::INFINITY
        };
        let delta_offset = if delta_rate < 1.0 {
            mpc_offset / (1.0 - delta_rate)
        } else {
            f64::INFINITY
        };
        let gamma43 = gamma41;
        let mut gm = GainMatrix::new(4);
        gm.set(0, 2, gamma13);
        gm.set(0, 3, gamma14);
        gm.set(1, 0, g.gamma21);
        gm.set(1, 2, g.gamma23);
        gm.set(1, 3, gamma24);
        gm.set(2, 0, gamma31);
        gm.set(2, 1, gamma32);
        gm.set(2, 2, self_loop);
        gm.set(2, 3, gamma34);
        gm.set(3, 0, gamma41);
        gm.set(3, 2, gamma43);
        let mut matrix = [0.0; 16];
        for (k, v) in matrix.iter_mut().enumerate() {
            *v = gm.get(k / 4, k % 4);
        }
        let cycles = gm.cycles();
        let cycles_hold = cycles.iter().all(|c| c.gain < 1.0);
        let spectral_radius = gm.spectral_radius();
        let certified = self.premises_hold()
            && (0.0..1.0).contains(&g.phi)
            && (0.0..1.0).contains(&delta_rate)
            && gm.is_contracting();
        JointGains {
            k_e,
            k_c,
            mhe: g,
            phi_c,
            delta_rate,
            gamma13,
            gamma14,
            gamma24,
            gamma34,
            gamma41,
            gamma43,
            self_loop,
            delta_offset,
            matrix,
            cycles,
            cycles_hold,
            spectral_radius,
            margin: 1.0 - spectral_radius,
            certified,
        }
    }

    /// Smallest K_c ≤ `k_c_max` certified together with K_e (None if none is). Exact: the
    /// verdict is monotone in K_c (every gain is non-decreasing in φ_c).
    pub fn k_c_min(&self, k_e: usize, k_c_max: usize) -> Option<usize> {
        first_true(0, k_c_max, |k| self.at(k_e, k).certified)
    }

    /// Smallest K_e ≤ `k_e_max` certified together with K_c (None if none is).
    pub fn k_e_min(&self, k_c: usize, k_e_max: usize) -> Option<usize> {
        first_true(0, k_e_max, |k| self.at(k, k_c).certified)
    }
}

/// Smallest k in [lo, hi] with `f(k)` for a monotone (false…false true…true) predicate.
pub(crate) fn first_true(lo: usize, hi: usize, f: impl Fn(usize) -> bool) -> Option<usize> {
    if lo > hi || !f(hi) {
        return None;
    }
    if f(lo) {
        return Some(lo);
    }
    // Doubling from lo keeps the evaluations near small answers cheap and exact.
    let (mut a, mut b) = (lo, hi); // f(a) false, f(b) true
    let mut step = 1usize;
    while a.saturating_add(step) < b {
        let probe = a + step;
        if f(probe) {
            b = probe;
            break;
        }
        a = probe;
        step = step.saturating_mul(2);
    }
    while b - a > 1 {
        let mid = a + (b - a) / 2;
        if f(mid) {
            b = mid;
        } else {
            a = mid;
        }
    }
    Some(b)
}
