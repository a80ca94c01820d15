//! The free sets of the box-constrained condensed MPC and its local gains, as a list
//! (enumeration, small problems) and as one affine matrix family (any size).
//!
//! ## What can saturate
//!
//! U*(x) = Π^H_{𝒰^N}(−H⁻¹Fx) (see [`crate::lipschitz`]). A variable Uᵢ whose bounds are both
//! infinite is never at a bound: it is in every free set. Only the **saturable** variables
//! 𝒮 = {i : lᵢ > −∞ or uᵢ < ∞}, s = |𝒮|, can leave it, so there are 2^s free sets
//! 𝔽 = 𝒮ᶜ ∪ f, f ⊆ 𝒮, not 2^{N·n_u}. With 𝒰 = ℝ^{n_u}, s = 0: one free set, the law is linear.
//!
//! ## Local gains as one family (docs/theory.md, "The certificate on any plant")
//!
//! On the region where 𝔽 is free, with 𝒜 = 𝒮 \ f the saturated variables,
//! dU/dx = J_𝔽 = −E_𝔽(E_𝔽ᵀHE_𝔽)⁻¹E_𝔽ᵀF. In the coordinates V = H^{½}U, J_𝔽Δ is the orthogonal
//! projection of −H^{−½}FΔ onto {V : E_𝒜ᵀH^{−½}V = 0}, i.e.
//!
//! K_𝔽 = E₀J_𝔽 = −E₀H^{−½}(I − P_𝒜)H^{−½}F,  P_𝒜 = orthogonal projector onto range(H^{−½}E_𝒜).
//!
//! range(H^{−½}E_𝒜) ⊆ 𝒲 = range(H^{−½}E_𝒮). With Γ = (H⁻¹)_{𝒮𝒮} = LLᵀ, W = H^{−½}E_𝒮L^{−T}
//! is an orthonormal basis of 𝒲, and P_𝒜 = WM_𝒜Wᵀ with M_𝒜 the orthogonal projector onto
//! range(LᵀE_{𝒜|𝒮}) in ℝ^s. Hence every local gain is
//!
//! K(M) = K_lin + G·M·R,  K_lin = −E₀H⁻¹F,  G = E₀H^{−½}W = (H⁻¹)_{0𝒮}L^{−T},  R = WᵀH^{−½}F = L⁻¹(H⁻¹F)_𝒮,
//!
//! at M = M_𝒜, and the convex hull of the local gains lies in {K(M) : 0 ⪯ M ⪯ I_s} (the convex
//! hull of all orthogonal projectors of ℝ^s). M = 0 is the unconstrained law, M = I the law
//! with every saturable variable saturated. With M = ½(I + Δ), ‖Δ‖₂ ≤ 1:
//!
//! K(M) = K_mid + ½G·Δ·R,  K_mid = K_lin + ½GR,
//!
//! the norm-bounded form [`crate::robust_norm::worst_case_norm`] takes.
//!
//! ## Partial enumeration
//!
//! Fix which variables of a subset 𝒫 ⊆ 𝒮 are saturated (𝒜₀ ⊆ 𝒫; the rest of 𝒫 free). The
//! local gains with 𝒜 ∩ 𝒫 = 𝒜₀ are those of the reduced QP over 𝒩 = [N·n_u] \ 𝒜₀ (the
//! variables of 𝒜₀ do not move: ΔU_{𝒜₀} = 0), whose saturable set is 𝒮 \ 𝒫. The same
//! argument gives a family K_{𝒜₀}(M) = K_lin^{𝒜₀} + G^{𝒜₀}·M·R^{𝒜₀}, 0 ⪯ M ⪯ I_{|𝒮\𝒫|}
//! ([`CondensedMpc::local_gains_with`]). Every local gain lies in one of the 2^{|𝒫|}
//! families, so a norm bound over all of them is the maximum of the per-family bounds. 𝒫 = ∅
//! is the single family, 𝒫 = 𝒮 the full enumeration; 𝒫 = the first k input blocks keeps the
//! saturation pattern of u₀, …, u_{k−1} exact and relaxes only the later ones.

use faer::{Mat, MatRef, Side};
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::condensed::CondensedMpc;
use crate::error::{MpcError, Result};

fn numerical(routine: &str, reason: String) -> MpcError {
    MpcError::Model(lti_model::ModelError::Numerical {
        routine: routine.into(),
        reason,
    })
}

/// The local gains of the box-constrained MPC law as the family K(M) = K_lin + G·M·R,
/// 0 ⪯ M ⪯ I_s (module docs); built by [`CondensedMpc::local_gains`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LocalGains {
    /// K_lin = −E₀H⁻¹F (n_u × n_x): the gain with every relaxed variable free (M = 0).
    pub k_lin: Mat<f64>,
    /// G = (H⁻¹)_{0𝒮}L^{−T} (n_u × s).
    pub g: Mat<f64>,
    /// R = L⁻¹(H⁻¹F)_𝒮 (s × n_x).
    pub r: Mat<f64>,
    /// The variables relaxed by M (the saturable ones, or those not fixed by a pattern;
    /// indices into U = (u₀, …, u_{N−1})).
    pub saturable: Vec<usize>,
    /// The variables held saturated (empty for [`CondensedMpc::local_gains`]).
    pub saturated: Vec<usize>,
}

impl LocalGains {
    /// A law with no saturable variable left: the single linear gain K_lin, an empty family.
    fn linear(k_lin: Mat<f64>, saturated: &[usize]) -> Self {
        let (nu, nx) = (k_lin.nrows(), k_lin.ncols());
        Self {
            k_lin,
            g: Mat::zeros(nu, 0),
            r: Mat::zeros(0, nx),
            saturable: Vec::new(),
            saturated: saturated.to_vec(),
        }
    }
}

/// PSD square root of a symmetric PSD matrix (negative round-off eigenvalues clamped to 0).
pub(crate) fn psd_sqrt(m: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let n = m.nrows();
    if n == 0 {
        return Ok(Mat::zeros(0, 0));
    }
    let evd = lti_model::matrix::symmetrize(m)
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| numerical("eigen-decomposition (PSD square root)", format!("{e:?}")))?;
    let (u, d) = (evd.U(), evd.S().column_vector());
    Ok(Mat::from_fn(n, n, |i, j| {
        (0..n)
            .map(|k| u[(i, k)] * d[k].max(0.0).sqrt() * u[(j, k)])
            .sum()
    }))
}

impl LocalGains {
    /// s = |𝒮|.
    pub fn s(&self) -> usize {
        self.saturable.len()
    }

    /// K(M) = K_lin + G·M·R for an s × s matrix M.
    pub fn gain(&self, m: MatRef<'_, f64>) -> Result<Mat<f64>> {
        let s = self.s();
        if m.nrows() != s || m.ncols() != s {
            return Err(MpcError::Dimension {
                name: "M (s × s)",
                expected: s,
                actual: m.nrows().max(m.ncols()),
            });
        }
        Ok(&self.k_lin + &self.g * m * &self.r)
    }

    /// K_mid = K(I/2) = K_lin + ½GR, the centre of the family.
    pub fn k_mid(&self) -> Mat<f64> {
        &self.k_lin + (&self.g * &self.r) * 0.5
    }

    /// K_sat = K(I) = K_lin + GR: every saturable variable saturated (0 when 𝒰 is bounded).
    pub fn k_sat(&self) -> Mat<f64> {
        &self.k_lin + &self.g * &self.r
    }

    /// Reduced factors (L̂, R̂) of the spread ½G·Δ·R: L̂ = (¼GGᵀ)^{½} (n_u × n_u) and
    /// R̂ = (RᵀR)^{½} (n_x × n_x). The worst-case norm depends on the spread only through
    /// L̂L̂ᵀ = ¼GGᵀ and R̂ᵀR̂ = RᵀR ([`crate::robust_norm`]), so {K_mid + L̂Δ'R̂ : ‖Δ'‖₂ ≤ 1}
    /// gives the same bounds as the family with small matrices.
    pub fn spread(&self) -> Result<(Mat<f64>, Mat<f64>)> {
        let ggt = (&self.g * self.g.transpose()) * 0.25;
        let rtr = self.r.transpose() * &self.r;
        Ok((psd_sqrt(ggt.as_ref())?, psd_sqrt(rtr.as_ref())?))
    }

    /// sup over 0 ⪯ M ⪯ I of ‖K(M)‖₂: a certified L_π valid for any s (docs/theory.md).
    pub fn lipschitz_bound(&self) -> Result<f64> {
        let (l, r) = self.spread()?;
        Ok(
            crate::robust_norm::worst_case_norm(self.k_mid().as_ref(), l.as_ref(), r.as_ref())?
                .bound,
        )
    }
}

/// Summary of the free-set structure for reports.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct FreeSetSummary {
    /// N·n_u, the number of QP variables.
    pub variables: usize,
    /// s, the number of saturable variables (a finite bound on at least one side).
    pub saturable: usize,
    /// 2^s (saturating at u64::MAX).
    pub free_sets: u64,
}

impl CondensedMpc {
    /// The saturable variables 𝒮 = {i : Uᵢ has a finite bound} (module docs).
    pub fn saturable(&self) -> Vec<usize> {
        let z = self.qp().zset();
        (0..self.qp().n())
            .filter(|&i| z.lower()[i].is_finite() || z.upper()[i].is_finite())
            .collect()
    }

    /// Variables, saturable variables and free sets.
    pub fn free_set_summary(&self) -> FreeSetSummary {
        FreeSetSummary {
            variables: self.qp().n(),
            saturable: self.saturable().len(),
            free_sets: self.free_set_count(),
        }
    }

    /// Number of free sets, 2^s with s the number of saturable variables (saturating at
    /// u64::MAX for s ≥ 64). 1 when 𝒰 = ℝ^{n_u}.
    pub fn free_set_count(&self) -> u64 {
        1u64.checked_shl(u32::try_from(self.saturable().len()).unwrap_or(u32::MAX))
            .unwrap_or(u64::MAX)
    }

    /// The family K(M) = K_lin + G·M·R containing every local gain (module docs).
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use lti_model::{BoxSet, LtiSystem};
    /// use mpc_core::{CondensedMpc, MpcConfig};
    /// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
    /// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
    ///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
    /// let g = mpc.local_gains().unwrap();
    /// // Every input bounded: with all of them saturated the gain is 0.
    /// assert!(g.k_sat().norm_max() < 1e-9 * g.k_lin.norm_max());
    /// ```
    pub fn local_gains(&self) -> Result<LocalGains> {
        self.local_gains_with(&[], &self.saturable())
    }

    /// The family of the local gains whose saturated set contains `saturated` and lies in
    /// `saturated ∪ relaxed`: the variables in `saturated` are held at their bound
    /// (ΔUᵢ = 0), those in `relaxed` may be free or saturated (relaxed to 0 ⪯ M ⪯ I), every
    /// other variable is free. This is the family of the reduced QP over the variables not in
    /// `saturated` (module docs, "Partial enumeration"). Both lists hold distinct variable
    /// indices < N·n_u and must not overlap.
    pub fn local_gains_with(&self, saturated: &[usize], relaxed: &[usize]) -> Result<LocalGains> {
        let qp = self.qp();
        let (n, nx, nu) = (qp.n(), self.nx(), self.nu());
        let mut role = vec![0u8; n]; // 0 free, 1 saturated, 2 relaxed
        for (list, tag) in [(saturated, 1u8), (relaxed, 2u8)] {
            for &i in list {
                if i >= n || role[i] != 0 {
                    return Err(MpcError::Parameter {
                        name: "free-set pattern",
                        value: i as f64,
                        reason: "variable indices must be < N·n_u and appear once",
                    });
                }
                role[i] = tag;
            }
        }
        // Reduced QP over 𝒩 = variables not held saturated.
        let keep: Vec<usize> = (0..n).filter(|&i| role[i] != 1).collect();
        let m = keep.len();
        let h = qp.h();
        let mut k_lin = Mat::<f64>::zeros(nu, nx);
        if m == 0 {
            return Ok(LocalGains::linear(k_lin, saturated));
        }
        let h_n = Mat::from_fn(m, m, |a, b| h[(keep[a], keep[b])]);
        let f_n = Mat::from_fn(m, nx, |a, j| qp.f()[(keep[a], j)]);
        let llt = h_n
            .llt(Side::Lower)
            .map_err(|e| numerical("Cholesky of H (local gains)", format!("{e:?}")))?;
        let h_inv = faer::linalg::solvers::Solve::solve(&llt, Mat::<f64>::identity(m, m));
        let h_inv = lti_model::matrix::symmetrize(h_inv.as_ref());
        let y = &h_inv * &f_n; // H_𝒩⁻¹F_𝒩 (m × n_x)
        // Positions in 𝒩 of the first-block inputs that are not held saturated.
        let first: Vec<(usize, usize)> = keep
            .iter()
            .enumerate()
            .filter(|(_, i)| **i < nu)
            .map(|(a, &i)| (a, i))
            .collect();
        for &(a, i) in &first {
            for j in 0..nx {
                k_lin[(i, j)] = -y[(a, j)];
            }
        }
        let rel: Vec<usize> = (0..m).filter(|&a| role[keep[a]] == 2).collect();
        let s = rel.len();
        if s == 0 {
            return Ok(LocalGains::linear(k_lin, saturated));
        }
        let gamma = Mat::from_fn(s, s, |a, b| h_inv[(rel[a], rel[b])]);
        let l = gamma
            .llt(Side::Lower)
            .map_err(|e| numerical("Cholesky of (H⁻¹)_𝒮𝒮 (local gains)", format!("{e:?}")))?;
        let l = l.L().to_owned();
        // R = L⁻¹Y_𝒮 and Gᵀ = L⁻¹(H⁻¹)_{𝒮0}: forward substitutions.
        let y_s = Mat::from_fn(s, nx, |a, j| y[(rel[a], j)]);
        let mut hs0 = Mat::<f64>::zeros(s, nu);
        for a in 0..s {
            for &(b, i) in &first {
                hs0[(a, i)] = h_inv[(rel[a], b)];
            }
        }
        let forward = |rhs: &Mat<f64>| -> Mat<f64> {
            let mut x = rhs.clone();
            for j in 0..x.ncols() {
                for a in 0..s {
                    let mut acc = x[(a, j)];
                    for c in 0..a {
                        acc -= l[(a, c)] * x[(c, j)];
                    }
                    x[(a, j)] = acc / l[(a, a)];
                }
            }
            x
        };
        let r = forward(&y_s);
        let g = forward(&hs0).transpose().to_owned();
        Ok(LocalGains {
            k_lin,
            g,
            r,
            saturable: rel.iter().map(|&a| keep[a]).collect(),
            saturated: saturated.to_vec(),
        })
    }

    /// The leading-block depth of the partial enumeration for a budget of `max_families`
    /// families: the largest k ≤ N such that 2^{|𝒫_k|} ≤ `max_families`, 𝒫_k the saturable
    /// variables of u₀, …, u_{k−1}.
    pub fn pattern_depth(&self, max_families: u64) -> usize {
        let sat = self.saturable();
        let nu = self.nu();
        (0..=self.horizon())
            .take_while(|&k| {
                let p = sat.iter().filter(|&&i| i < k * nu).count();
                1u64.checked_shl(u32::try_from(p).unwrap_or(u32::MAX))
                    .is_some_and(|c| c <= max_families.max(1))
            })
            .last()
            .unwrap_or(0)
    }

    /// The 2^{|𝒫_k|} families of the partial enumeration over the first `k` input blocks
    /// (module docs, "Partial enumeration"): one per saturation pattern of 𝒫_k, each relaxing
    /// the saturable variables of the later blocks. `k` is capped at N; at most 2³⁰ families.
    pub fn pattern_gains(&self, k: usize) -> Result<Vec<LocalGains>> {
        self.pattern_gains_iter(k)?.collect()
    }

    /// [`CondensedMpc::pattern_gains`] one family at a time (pattern order: bit j of the
    /// pattern index set = the j-th saturable variable of the first k blocks saturated), so
    /// callers can stop early.
    pub fn pattern_gains_iter(
        &self,
        k: usize,
    ) -> Result<impl Iterator<Item = Result<LocalGains>> + '_> {
        let nu = self.nu();
        let k = k.min(self.horizon());
        let sat = self.saturable();
        let lead: Vec<usize> = sat.iter().copied().filter(|&i| i < k * nu).collect();
        let rest: Vec<usize> = sat.iter().copied().filter(|&i| i >= k * nu).collect();
        if lead.len() > 30 {
            return Err(MpcError::Parameter {
                name: "pattern depth k",
                value: k as f64,
                reason: "more than 2^30 saturation patterns; use a smaller k",
            });
        }
        Ok((0..(1u64 << lead.len())).map(move |mask| {
            let saturated: Vec<usize> = lead
                .iter()
                .enumerate()
                .filter(|(j, _)| mask & (1 << j) != 0)
                .map(|(_, &i)| i)
                .collect();
            self.local_gains_with(&saturated, &rest)
        }))
    }

    /// Visits every free set 𝔽 of the box-constrained QP (every always-free variable is in
    /// every 𝔽; the saturable ones are enumerated) with the local gain of the first input
    /// block, K_𝔽 = −E₀ E_𝔽(E_𝔽ᵀHE_𝔽)⁻¹E_𝔽ᵀF (n_u × n_x, row-major; rows of saturated
    /// first-block inputs are zero). On the region where exactly 𝔽 is free, π(x) is affine
    /// with Jacobian K_𝔽, so along any segment π(x) − π(x') is a convex combination of
    /// K_𝔽(x − x') (the law is continuous and piecewise affine).
    ///
    /// `visit(mask, k_f, n_x)`, where bit j of `mask` set means the j-th saturable variable
    /// ([`CondensedMpc::saturable`]) is free. Returns `Ok(false)` without visiting when
    /// s > `max_vars` (at most 30): the enumeration costs 2^s small Cholesky solves.
    /// Buffers are allocated once, before the loop.
    pub fn for_each_free_set<V>(&self, max_vars: usize, visit: V) -> Result<bool>
    where
        V: FnMut(u64, &[f64], usize),
    {
        self.for_each_free_set_in(max_vars, 0..self.free_set_count(), visit)
    }

    /// [`CondensedMpc::for_each_free_set`] restricted to the masks in `masks`, so callers can
    /// split the enumeration into ranges and run them in parallel; the union of the ranges
    /// 0..2^s visits every free set once.
    pub fn for_each_free_set_in<V>(
        &self,
        max_vars: usize,
        masks: std::ops::Range<u64>,
        mut visit: V,
    ) -> Result<bool>
    where
        V: FnMut(u64, &[f64], usize),
    {
        let qp = self.qp();
        let (n, nx, nu) = (qp.n(), self.nx(), self.nu());
        let sat = self.saturable();
        let s = sat.len();
        if s > max_vars.min(30) {
            return Ok(false);
        }
        let always: Vec<usize> = (0..n).filter(|i| !sat.contains(i)).collect();
        let end = masks.end.min(1u64 << s);
        let h = qp.h_row_major();
        let f: Vec<f64> = (0..n * nx).map(|k| qp.f()[(k / nx, k % nx)]).collect();
        let mut free = vec![0usize; n];
        let mut l = vec![0.0; n * n];
        let mut y = vec![0.0; n * nx];
        let mut kf = vec![0.0; nu * nx];
        for mask in masks.start..end {
            // Free set in increasing variable order: always-free ∪ {saturable j : bit j set}.
            let (mut nf, mut ia, mut js) = (0, 0, 0);
            while ia < always.len() || js < s {
                let take_always = js >= s || (ia < always.len() && always[ia] < sat[js]);
                if take_always {
                    free[nf] = always[ia];
                    nf += 1;
                    ia += 1;
                } else {
                    if mask & (1 << js) != 0 {
                        free[nf] = sat[js];
                        nf += 1;
                    }
                    js += 1;
                }
            }
            kf.fill(0.0);
            if nf == 0 {
                visit(mask, &kf, nx);
                continue;
            }
            // Cholesky H_ff = LLᵀ (lower, row-major nf × nf).
            for a in 0..nf {
                for b in 0..=a {
                    let mut acc = h[free[a] * n + free[b]];
                    for c in 0..b {
                        acc -= l[a * nf + c] * l[b * nf + c];
                    }
                    if a == b {
                        if !(acc > 0.0) {
                            return Err(numerical(
                                "Cholesky of a principal submatrix of H (free-set enumeration)",
                                format!("pivot {acc:e} ≤ 0; H is numerically singular"),
                            ));
                        }
                        l[a * nf + a] = acc.sqrt();
                    } else {
                        l[a * nf + b] = acc / l[b * nf + b];
                    }
                }
            }
            // Y = H_ff⁻¹F_f (nf × nx, row-major): forward then backward substitution.
            for j in 0..nx {
                for a in 0..nf {
                    let mut acc = f[free[a] * nx + j];
                    for c in 0..a {
                        acc -= l[a * nf + c] * y[c * nx + j];
                    }
                    y[a * nx + j] = acc / l[a * nf + a];
                }
                for a in (0..nf).rev() {
                    let mut acc = y[a * nx + j];
                    for c in a + 1..nf {
                        acc -= l[c * nf + a] * y[c * nx + j];
                    }
                    y[a * nx + j] = acc / l[a * nf + a];
                }
            }
            // K_𝔽 = −(rows of Y of free first-block inputs), placed at their input index.
            for (a, &i) in free[..nf].iter().enumerate().take_while(|(_, i)| **i < nu) {
                for j in 0..nx {
                    kf[i * nx + j] = -y[a * nx + j];
                }
            }
            visit(mask, &kf, nx);
        }
        Ok(true)
    }
}
