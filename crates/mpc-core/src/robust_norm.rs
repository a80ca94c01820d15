//! Worst-case spectral norm of a norm-bounded matrix family, sup_{‖Δ‖₂ ≤ 1} ‖M₀ + UΔV‖₂,
//! by the S-procedure: one scalar search and small symmetric eigenvalue problems, no SDP.
//!
//! ## Derivation (docs/theory.md, "The certificate on any plant")
//!
//! Let M₀ ∈ ℝ^{p×q}, U ∈ ℝ^{p×r}, V ∈ ℝ^{r'×q}, Δ ∈ ℝ^{r×r'}. Then ‖M₀ + UΔV‖₂ ≤ γ for every
//! ‖Δ‖₂ ≤ 1 iff ‖M₀x + Up‖² ≤ γ²‖x‖² for every (x, p) with ‖p‖ ≤ ‖Vx‖, because
//! {(x, ΔVx) : ‖Δ‖₂ ≤ 1} = {(x, p) : ‖p‖ ≤ ‖Vx‖} (take the rank-one Δ = p(Vx)ᵀ/‖Vx‖²).
//! Both sides are quadratic forms in (x, p) and the constraint is strictly feasible when
//! V ≠ 0, so the S-lemma (Yakubovich; Pólik & Terlaky, SIAM Review 49(3), 2007) is lossless:
//! the bound holds iff some τ ≥ 0 gives
//!
//! [M₀ᵀM₀ − γ²I + τVᵀV, M₀ᵀU; UᵀM₀, UᵀU − τI] ⪯ 0.
//!
//! For τ > λ_max(UᵀU) the Schur complement reads M₀ᵀM₀ + M₀ᵀU(τI − UᵀU)⁻¹UᵀM₀ + τVᵀV ⪯ γ²I,
//! and with I + U(τI − UᵀU)⁻¹Uᵀ = τ(τI − UUᵀ)⁻¹ (push-through identity)
//!
//! γ²(τ) = τ·λ_max(M₀ᵀ(τI − UUᵀ)⁻¹M₀ + VᵀV),  sup_Δ ‖M₀ + UΔV‖₂² = inf_{τ > λ_max(UUᵀ)} γ²(τ).
//!
//! **Every** τ > λ_max(UUᵀ) gives a valid upper bound, so the search only affects
//! tightness, never soundness. With UUᵀ = QΛQᵀ, τ(τI − UUᵀ)⁻¹ = Σᵢ (1 + λᵢ/(τ − λᵢ)) qᵢqᵢᵀ is
//! a sum of fixed PSD matrices with convex scalar weights, so γ²(τ) is the largest eigenvalue
//! of an operator-convex function of τ and hence convex: a log-spaced scan followed by golden
//! section on t = τ − λ_max(UUᵀ) (γ² is quasiconvex in log t) finds its minimum.
//!
//! The bound depends on U and V only through UUᵀ and VᵀV.

use faer::{Mat, MatRef, Side};
use lti_model::matrix::sym_lambda_max;
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::error::{MpcError, Result};

/// Relative safety margin applied to every bound (round-off of the eigenvalue problems).
pub const ROUND_OFF_MARGIN: f64 = 1e-10;

/// Result of [`worst_case_norm`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct WorstCaseNorm {
    /// An upper bound on sup_{‖Δ‖₂ ≤ 1} ‖M₀ + UΔV‖₂ (equal to it up to the scalar search
    /// and [`ROUND_OFF_MARGIN`]).
    pub bound: f64,
    /// The S-procedure multiplier τ that attains it (0 when U = 0 or V = 0).
    pub tau: f64,
    /// Evaluations of γ²(τ).
    pub evaluations: usize,
}

fn numerical(routine: &str, reason: String) -> MpcError {
    MpcError::Model(lti_model::ModelError::Numerical {
        routine: routine.into(),
        reason,
    })
}

/// sup_{‖Δ‖₂ ≤ 1} ‖M₀ + UΔV‖₂ by the S-procedure (module docs). M₀ is p × q, U is p × r and
/// V is r' × q (Δ is r × r').
///
/// Errors: `Dimension` for mismatched shapes, `NonFinite` for a NaN or ±∞ entry,
/// `Model(Numerical)` if an eigensolver fails.
///
/// ```
/// use faer::mat;
/// // Scalars: sup_{|δ| ≤ 1} |m + uδv| = |m| + |uv| = 2 + 3.
/// let b = mpc_core::robust_norm::worst_case_norm(
///     mat![[2.0]].as_ref(), mat![[1.5]].as_ref(), mat![[2.0]].as_ref()).unwrap();
/// assert!((b.bound - 5.0).abs() < 1e-8 && b.bound >= 5.0);
/// ```
pub fn worst_case_norm(
    m0: MatRef<'_, f64>,
    u: MatRef<'_, f64>,
    v: MatRef<'_, f64>,
) -> Result<WorstCaseNorm> {
    check_inputs(m0, u, v)?;
    let (p, q) = (m0.nrows(), m0.ncols());
    if p == 0 || q == 0 {
        return Ok(WorstCaseNorm {
            bound: 0.0,
            tau: 0.0,
            evaluations: 0,
        });
    }
    let (u_f, v_f) = (u.norm_l2(), v.norm_l2());
    if u_f == 0.0 || v_f == 0.0 || u.ncols() == 0 || v.nrows() == 0 {
        // No uncertainty: the family is the single matrix M₀.
        let n = lti_model::matrix::spectral_norm(m0);
        return Ok(WorstCaseNorm {
            bound: n * (1.0 + ROUND_OFF_MARGIN),
            tau: 0.0,
            evaluations: 0,
        });
    }
    let uut = u * u.transpose();
    let evd = lti_model::matrix::symmetrize(uut.as_ref())
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| numerical("eigen-decomposition of UUᵀ (S-procedure)", format!("{e:?}")))?;
    let lam: Vec<f64> = (0..p).map(|i| evd.S()[i].max(0.0)).collect();
    let tau0 = lam.iter().copied().fold(0.0, f64::max);
    let z: Mat<f64> = evd.U().transpose() * m0; // p × q, rows zᵢ = qᵢᵀM₀
    let vtv = v.transpose() * v; // q × q
    let mut family = Family::new(z, vtv, lam, tau0);
    let t_lo = 1e-10 * tau0;
    // Scalar case: t* = |u·m|/|v|; use its matrix analogue as the centre of the scan.
    let m_f = m0.norm_l2();
    let centre = (tau0.sqrt() * m_f / v_f).max(t_lo);
    let (s_lo, s_hi) = ((centre.ln() - 35.0).max(t_lo.ln()), centre.ln() + 35.0);
    let best = minimise_in_log(|t| family.gamma2(t), s_lo, s_hi);
    if !best.0.is_finite() {
        return Err(numerical(
            "S-procedure scalar search",
            format!("γ²(τ) is not finite (best {})", best.0),
        ));
    }
    Ok(WorstCaseNorm {
        bound: best.0.sqrt() * (1.0 + ROUND_OFF_MARGIN),
        tau: tau0 + best.1.exp(),
        evaluations: family.evaluations,
    })
}

/// M₀ p × q, U with p rows, V with q columns, every entry finite.
fn check_inputs(m0: MatRef<'_, f64>, u: MatRef<'_, f64>, v: MatRef<'_, f64>) -> Result<()> {
    let (p, q) = (m0.nrows(), m0.ncols());
    if u.nrows() != p {
        return Err(MpcError::Dimension {
            name: "U (rows of M₀)",
            expected: p,
            actual: u.nrows(),
        });
    }
    if v.ncols() != q {
        return Err(MpcError::Dimension {
            name: "V (columns of M₀)",
            expected: q,
            actual: v.ncols(),
        });
    }
    for (name, m) in [("M₀", m0), ("U", u), ("V", v)] {
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                if !m[(i, j)].is_finite() {
                    return Err(MpcError::NonFinite {
                        name,
                        index: i + j * m.nrows(),
                        value: m[(i, j)],
                    });
                }
            }
        }
    }
    Ok(())
}

/// γ²(τ) = τ·λ_max(Zᵀdiag(1/(τ − λᵢ))Z + VᵀV) of the S-procedure, with its workspace and a
/// count of evaluations.
struct Family {
    /// Rows zᵢ = qᵢᵀM₀ (qᵢ the eigenvectors of UUᵀ), p × q.
    z: Mat<f64>,
    vtv: Mat<f64>,
    /// The eigenvalues λᵢ of UUᵀ, clamped at 0.
    lam: Vec<f64>,
    tau0: f64,
    /// Wide families (q above the Jacobi size): Zᵀdiag(1/(τ − λ))Z as one blocked product of
    /// the scaled rows, VᵀV added, and the dense eigenvalues; narrow ones keep the scalar
    /// loop (bit for bit the earlier results).
    wide: bool,
    g: Vec<f64>,
    zs: Mat<f64>,
    gm: Mat<f64>,
    evaluations: usize,
}

impl Family {
    fn new(z: Mat<f64>, vtv: Mat<f64>, lam: Vec<f64>, tau0: f64) -> Self {
        let (p, q) = (z.nrows(), z.ncols());
        let wide = q > lti_model::matrix::JACOBI_MAX_DIM;
        let (zs, gm) = if wide {
            (Mat::<f64>::zeros(p, q), Mat::<f64>::zeros(q, q))
        } else {
            (Mat::new(), Mat::new())
        };
        Self {
            z,
            vtv,
            lam,
            tau0,
            wide,
            g: vec![0.0; q * q],
            zs,
            gm,
            evaluations: 0,
        }
    }

    /// γ²(τ₀ + t); t is kept ≥ 1e-10·τ₀, far above the round-off of the λᵢ.
    fn gamma2(&mut self, t: f64) -> f64 {
        let Self {
            z,
            vtv,
            lam,
            tau0,
            wide,
            g,
            zs,
            gm,
            evaluations,
        } = self;
        let (p, q) = (z.nrows(), z.ncols());
        *evaluations += 1;
        let tau = *tau0 + t;
        if *wide {
            for i in 0..p {
                // τ − λᵢ ≥ t > 0.
                let w = (tau - lam[i]).recip().sqrt();
                for a in 0..q {
                    zs[(i, a)] = z[(i, a)] * w;
                }
            }
            faer::linalg::matmul::matmul(
                gm.as_mut(),
                faer::Accum::Replace,
                zs.transpose(),
                zs.as_ref(),
                1.0,
                faer::Par::Seq,
            );
            for a in 0..q {
                for b in 0..q {
                    g[a * q + b] = gm[(a, b)] + vtv[(a, b)];
                }
            }
            return tau * sym_lambda_max(g, q).max(0.0);
        }
        for a in 0..q {
            for b in 0..=a {
                let mut acc = vtv[(a, b)];
                for i in 0..p {
                    acc += z[(i, a)] * z[(i, b)] / (tau - lam[i]);
                }
                g[a * q + b] = acc;
                g[b * q + a] = acc;
            }
        }
        tau * sym_lambda_max(g, q).max(0.0)
    }
}

/// The minimum of the quasiconvex s ↦ γ²(eˢ) on [s_lo, s_hi]: a 25-point grid, then golden
/// section on the grid minimum's neighbours. Returns (γ², s, grid index) of the best point.
fn minimise_in_log(mut gamma2: impl FnMut(f64) -> f64, s_lo: f64, s_hi: f64) -> (f64, f64, usize) {
    // Quasiconvex in s: any grid minimum brackets the minimiser between its neighbours.
    let points = 25;
    let mut best = (f64::INFINITY, s_lo, 0usize);
    let grid: Vec<f64> = (0..points)
        .map(|k| s_lo + (s_hi - s_lo) * k as f64 / (points - 1) as f64)
        .collect();
    for (k, &s) in grid.iter().enumerate() {
        let val = gamma2(s.exp());
        if val < best.0 {
            best = (val, s, k);
        }
    }
    // Golden section on [s_{k−1}, s_{k+1}] (γ² is quasiconvex in s = ln t).
    let (mut a, mut b) = (
        grid[best.2.saturating_sub(1)],
        grid[(best.2 + 1).min(points - 1)],
    );
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - r * (b - a), a + r * (b - a));
    let (mut fc, mut fd) = (gamma2(c.exp()), gamma2(d.exp()));
    // The bracket (≤ 6 e-folds of t) shrinks by 0.618 per step: 45 steps reach 1e-9.
    for _ in 0..45 {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = gamma2(c.exp());
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = gamma2(d.exp());
        }
        if fc < best.0 {
            best = (fc, c, best.2);
        }
        if fd < best.0 {
            best = (fd, d, best.2);
        }
    }
    best
}
