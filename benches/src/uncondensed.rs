//! The uncondensed (sparse) form of a case-study MHE QP, for the sparse peer (OSQP):
//! the states of the window are variables and the dynamics equality constraints.
//!
//! Variables, stage by stage: v = (x̂₀, ŵ₀, x̂₁, ŵ₁, …, x̂_{M−1}, ŵ_{M−1}) (window time j is
//! absolute time t − M + j), length M(n_x + n_w). The condensed z = (x̂₀, ŵ₀, …, ŵ_{M−1}) of
//! [`mhe_core::problem::WindowLayout`] is the sub-vector [`Uncondensed::z_index`].
//!
//! The cost is V_MHE of eq. (10) written in v (minus its constant):
//!
//! V = 2η^M‖x̂₀ − x̄‖²_P + Σ_j η^{M−1−j}(2‖ŵ_j‖²_Q + ‖C x̂_j + F ŵ²_j − y_j‖²_R),
//!
//! so ½vᵀP_u v + q_uᵀv with P_u block diagonal per stage (4η^M P on x̂₀; 4d_jQ on ŵ_j;
//! 2d_jG_jᵀRG_j on (x̂_j, ŵ_j) with G_j = [C, 0, F]) and q_u = −4η^M P x̄ on x̂₀,
//! −2d_jG_jᵀR y_j on stage j. Constraints: x̂_{j+1} − A x̂_j − E ŵ¹_j = B u_j
//! (j = 0 … M − 2) and the box of the condensed problem on x̂₀ and ŵ_j (states j ≥ 1 free:
//! 𝒳 is the whole space). Only q_u and the right-hand side b depend on θ.
//!
//! [`Uncondensed::lift`] maps a condensed z to v (propagating the states), so minimising
//! over v is minimising the condensed QP: the test checks LᵀP_uL = H_c and
//! Lᵀ(P_u l(θ) + q_u(θ)) = F_cθ for the lifting v = Lz + l(θ).

use crate::case_study::CaseStudyQps;

/// Sparse matrix as (row, column, value) triplets.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Triplets {
    /// Row indices.
    pub rows: Vec<usize>,
    /// Column indices.
    pub cols: Vec<usize>,
    /// Values.
    pub vals: Vec<f64>,
}

impl Triplets {
    fn push(&mut self, i: usize, j: usize, v: f64) {
        if v != 0.0 {
            self.rows.push(i);
            self.cols.push(j);
            self.vals.push(v);
        }
    }
}

/// The uncondensed QP min ½vᵀP_u v + q_u(θ)ᵀv s.t. A_eq v = b(θ), lower ≤ v ≤ upper.
#[derive(Debug, Clone)]
pub struct Uncondensed {
    /// Number of variables M(n_x + n_w).
    pub n: usize,
    /// P_u, upper triangle (i ≤ j) as triplets.
    pub p_upper: Triplets,
    /// A_eq, (M − 1)n_x × n.
    pub a_eq: Triplets,
    /// Rows of A_eq.
    pub m_eq: usize,
    /// Bounds on v (±∞ = unbounded).
    pub lower: Vec<f64>,
    /// Bounds on v.
    pub upper: Vec<f64>,
    /// `v[z_index[i]] = z[i]`.
    pub z_index: Vec<usize>,
    /// Dense P_u (row-major n × n), for the lifting checks and q_u.
    p_dense: Vec<f64>,
    m: usize,
    dims: (usize, usize, usize, usize, usize),
    eta_m: f64,
    p: Vec<f64>,
    r: Vec<f64>,
    c: Vec<f64>,
    f: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    e: Vec<f64>,
    decay: Vec<f64>,
    u_off: Vec<usize>,
    y_off: Vec<usize>,
}

fn row_major(m: faer::MatRef<'_, f64>) -> Vec<f64> {
    (0..m.nrows())
        .flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)]))
        .collect()
}

impl Uncondensed {
    /// The uncondensed form of the preset's window-M QP.
    pub fn new(qps: &CaseStudyQps) -> Self {
        let sys = qps.problem.system();
        let w = qps.problem.weights();
        let m = qps.horizon();
        let (nx, nu, ny, nw1, nw2) = (sys.nx(), sys.nu(), sys.ny(), sys.nw1(), sys.nw2());
        let nw = nw1 + nw2;
        let st = nx + nw;
        let n = m * st;
        let eta_m = w.eta.powi(i32::try_from(m).unwrap_or(i32::MAX));
        let decay: Vec<f64> = (0..m)
            .map(|j| w.eta.powi(i32::try_from(m - 1 - j).unwrap_or(i32::MAX)))
            .collect();
        let (c, f) = (sys.c(), sys.f());
        // Dense P_u, then its upper triangle as triplets.
        let mut pd = vec![0.0; n * n];
        let mut add = |i: usize, j: usize, v: f64| pd[i * n + j] += v;
        for i in 0..nx {
            for k in 0..nx {
                add(i, k, 4.0 * eta_m * w.p[(i, k)]);
            }
        }
        for (j, &d) in decay.iter().enumerate() {
            let o = j * st;
            for i in 0..nw {
                for k in 0..nw {
                    add(o + nx + i, o + nx + k, 4.0 * d * w.q[(i, k)]);
                }
            }
            // G_j = [C, 0 (ŵ¹), F (ŵ²)] on stage j's block (x̂_j, ŵ¹_j, ŵ²_j).
            let g = |r: usize, col: usize| -> f64 {
                if col < nx {
                    c[(r, col)]
                } else if col < nx + nw1 {
                    0.0
                } else {
                    f[(r, col - nx - nw1)]
                }
            };
            for a in 0..st {
                for b in 0..st {
                    let mut s = 0.0;
                    for r1 in 0..ny {
                        for r2 in 0..ny {
                            s += g(r1, a) * w.r[(r1, r2)] * g(r2, b);
                        }
                    }
                    add(o + a, o + b, 2.0 * d * s);
                }
            }
        }
        let mut p_upper = Triplets::default();
        for i in 0..n {
            for j in i..n {
                p_upper.push(i, j, pd[i * n + j]);
            }
        }
        let (a, e) = (sys.a(), sys.e());
        let mut a_eq = Triplets::default();
        for j in 0..m.saturating_sub(1) {
            let (o, o1) = (j * st, (j + 1) * st);
            for i in 0..nx {
                a_eq.push(j * nx + i, o1 + i, 1.0);
                for k in 0..nx {
                    a_eq.push(j * nx + i, o + k, -a[(i, k)]);
                }
                for k in 0..nw1 {
                    a_eq.push(j * nx + i, o + nx + k, -e[(i, k)]);
                }
            }
        }
        let (lo, hi) = (qps.qp.zset().lower(), qps.qp.zset().upper());
        let z_index: Vec<usize> = (0..nx)
            .chain((0..m).flat_map(|j| (0..nw).map(move |i| j * st + nx + i)))
            .collect();
        let (mut lower, mut upper) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
        for (zi, &vi) in z_index.iter().enumerate() {
            lower[vi] = lo[zi];
            upper[vi] = hi[zi];
        }
        let layout = match qps.problem.window(m) {
            Some(win) => win.layout(),
            None => unreachable!("CaseStudyQps::load checked the window-M problem"),
        };
        Self {
            n,
            p_upper,
            a_eq,
            m_eq: m.saturating_sub(1) * nx,
            lower,
            upper,
            z_index,
            p_dense: pd,
            m,
            dims: (nx, nu, ny, nw1, nw2),
            eta_m,
            p: row_major(w.p.as_ref()),
            r: row_major(w.r.as_ref()),
            c: row_major(c),
            f: row_major(f),
            a: row_major(a),
            b: row_major(sys.b()),
            e: row_major(e),
            decay,
            u_off: (0..m).map(|j| layout.u_offset(j)).collect(),
            y_off: (0..m).map(|j| layout.y_offset(j)).collect(),
        }
    }

    /// q_u(θ).
    pub fn linear_term(&self, theta: &[f64]) -> Vec<f64> {
        let (nx, _, ny, nw1, nw2) = self.dims;
        let st = nx + nw1 + nw2;
        let mut q = vec![0.0; self.n];
        for i in 0..nx {
            q[i] -= 4.0 * self.eta_m * (0..nx).map(|k| self.p[i * nx + k] * theta[k]).sum::<f64>();
        }
        for (j, &d) in self.decay.iter().enumerate() {
            let o = j * st;
            let y = &theta[self.y_off[j]..self.y_off[j] + ny];
            // R y_j, then −2d G_jᵀ(R y_j).
            let ry: Vec<f64> = (0..ny)
                .map(|r| (0..ny).map(|k| self.r[r * ny + k] * y[k]).sum())
                .collect();
            for col in 0..nx {
                q[o + col] -= 2.0 * d * (0..ny).map(|r| self.c[r * nx + col] * ry[r]).sum::<f64>();
            }
            for col in 0..nw2 {
                q[o + nx + nw1 + col] -=
                    2.0 * d * (0..ny).map(|r| self.f[r * nw2 + col] * ry[r]).sum::<f64>();
            }
        }
        q
    }

    /// b(θ) = (B u₀, …, B u_{M−2}).
    pub fn rhs(&self, theta: &[f64]) -> Vec<f64> {
        let (nx, nu, ..) = self.dims;
        (0..self.m.saturating_sub(1))
            .flat_map(|j| {
                let u = &theta[self.u_off[j]..self.u_off[j] + nu];
                (0..nx).map(move |i| (0..nu).map(|k| self.b[i * nu + k] * u[k]).sum::<f64>())
            })
            .collect()
    }

    /// v of a condensed z: x̂₀ and ŵ from z, x̂_{j+1} = A x̂_j + B u_j + E ŵ¹_j.
    pub fn lift(&self, z: &[f64], theta: &[f64]) -> Vec<f64> {
        let (nx, nu, _, nw1, nw2) = self.dims;
        let st = nx + nw1 + nw2;
        let mut v = vec![0.0; self.n];
        for (zi, &vi) in self.z_index.iter().enumerate() {
            v[vi] = z[zi];
        }
        for j in 0..self.m.saturating_sub(1) {
            let (o, o1) = (j * st, (j + 1) * st);
            let u = &theta[self.u_off[j]..self.u_off[j] + nu];
            for i in 0..nx {
                v[o1 + i] = (0..nx).map(|k| self.a[i * nx + k] * v[o + k]).sum::<f64>()
                    + (0..nu).map(|k| self.b[i * nu + k] * u[k]).sum::<f64>()
                    + (0..nw1)
                        .map(|k| self.e[i * nw1 + k] * v[o + nx + k])
                        .sum::<f64>();
            }
        }
        v
    }

    /// ∇ of the uncondensed objective at v: P_u v + q_u(θ).
    pub fn gradient(&self, v: &[f64], theta: &[f64]) -> Vec<f64> {
        let q = self.linear_term(theta);
        (0..self.n)
            .map(|i| {
                (0..self.n)
                    .map(|j| self.p_dense[i * self.n + j] * v[j])
                    .sum::<f64>()
                    + q[i]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::case_study::{CART_PENDULUM, CaseStudyQps, PRESETS};

    /// The lifting v(z) = Lz + l(θ) turns the uncondensed objective into the condensed one:
    /// its gradient pulled back through L is H_c z + F_cθ, for any z (checked at z*, z⁰ and
    /// a perturbed point of every instance), and v(z) satisfies A_eq v = b(θ).
    /// On the certified preset (n_w1 = 4, n_w2 = 1) and the cart-pendulum (n_w1 = 4,
    /// n_w2 = 2).
    #[test]
    fn lifted_uncondensed_objective_is_the_condensed_one() {
        for preset in [PRESETS[1], CART_PENDULUM] {
            check_lifting(&CaseStudyQps::load(preset).unwrap());
        }
    }

    fn check_lifting(qps: &CaseStudyQps) {
        let u = Uncondensed::new(qps);
        let qp = &qps.qp;
        let n = qp.n();
        let h = qp.h_row_major();
        for inst in qps.instances.iter().step_by(7) {
            let zp: Vec<f64> = inst
                .z0
                .iter()
                .enumerate()
                .map(|(i, v)| v + 0.1 * (i % 3) as f64)
                .collect();
            for z in [&inst.z_star, &inst.z0, &zp] {
                let v = u.lift(z, &inst.theta);
                // A_eq v = b.
                let mut av = vec![0.0; u.m_eq];
                for ((&i, &j), &x) in u.a_eq.rows.iter().zip(&u.a_eq.cols).zip(&u.a_eq.vals) {
                    av[i] += x * v[j];
                }
                for (a, b) in av.iter().zip(u.rhs(&inst.theta)) {
                    assert!((a - b).abs() <= 1e-10 * (1.0 + b.abs()));
                }
                // Lᵀ∇_v = ∇_z: L is the derivative of lift in z (linear), columns by unit z.
                let g = u.gradient(&v, &inst.theta);
                let base = u.lift(&vec![0.0; n], &inst.theta);
                let scale = 1.0 + g.iter().fold(0.0f64, |a, x| a.max(x.abs()));
                for i in 0..n {
                    let mut ei = vec![0.0; n];
                    ei[i] = 1.0;
                    let col: Vec<f64> = u
                        .lift(&ei, &inst.theta)
                        .iter()
                        .zip(&base)
                        .map(|(a, b)| a - b)
                        .collect();
                    let pulled: f64 = col.iter().zip(&g).map(|(a, b)| a * b).sum();
                    let cond: f64 = (0..n).map(|j| h[i * n + j] * z[j]).sum::<f64>() + inst.q[i];
                    assert!(
                        (pulled - cond).abs() <= 1e-9 * scale,
                        "component {i}: {pulled} vs {cond}"
                    );
                }
            }
        }
    }
}
