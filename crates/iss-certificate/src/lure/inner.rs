//! The inner level: one iteration of a method on the window's QP as a Lur'e system in
//! error coordinates, its rate from a small LMI (Lessard–Recht–Packard), and the
//! independent check of the LMI's solution (docs/theory.md, "One certificate for the whole
//! loop: a Lur'e system (issue 35)").
//!
//! Every nonlinearity of one step is a *sector* channel π = Φ(v) with
//! (π − a·v)ᵀ(b·v − π) ≥ 0 in error coordinates (v, π measured from the fixed point):
//! the gradient H·v (sector [μ, L]), ADMM's ρ(H + ρI)⁻¹ (sector [ρ/(ρ+L), ρ/(ρ+μ)]) and
//! the projection (firmly non-expansive: sector [0, 1], the dead-zone's complement). The
//! storage matrix is P̃ ⊗ I and every multiplier a scalar, so the LMI has the size of the
//! method's *block* state (1 or 2), not of n_z.

use super::sdp::{AffineBlock, Sym, maximise_last, sym_eigenvalues};

/// One sector channel: v = cᵀξ + dᵀπ, (π_j − lo·v)(hi·v − π_j) ≥ 0.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Sector {
    pub c: Vec<f64>,
    pub d: Vec<f64>,
    pub lo: f64,
    pub hi: f64,
}

/// ξ⁺ = Aξ + Bπ with m block states and p sector channels (row-major A: m × m, B: m × p).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LureStep {
    pub m: usize,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub sectors: Vec<Sector>,
}

/// A checked solution of the rate LMI at rate ρ.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RateCertificate {
    pub rho: f64,
    pub p: Sym,
    pub lambda: Vec<f64>,
    /// −λ_max(M)/scale(M): the LMI's relative margin in the independent check.
    pub margin: f64,
}

impl LureStep {
    fn p(&self) -> usize {
        self.sectors.len()
    }

    /// The quadratic forms of the LMI in ζ = (ξ, π): for a symmetric P and multipliers λ,
    /// M = [A B]ᵀP[A B] − ρ²[I 0]ᵀP[I 0] + Σ λ_j S_j, and the scale Σ|terms| for rounding.
    fn lmi_matrix(&self, rho: f64, p_mat: &Sym, lambda: &[f64]) -> (Sym, f64) {
        let (m, np) = (self.m, self.p());
        let nz = m + np;
        // E⁺ = [A B] (m × nz).
        let eplus = |r: usize, c: usize| {
            if c < m {
                self.a[r * m + c]
            } else {
                self.b[r * np + (c - m)]
            }
        };
        let mut out = Sym::zeros(nz);
        let mut scale = Sym::zeros(nz);
        for i in 0..nz {
            for j in 0..nz {
                let mut v = 0.0;
                let mut s = 0.0;
                for r in 0..m {
                    for c in 0..m {
                        let t = eplus(r, i) * p_mat.at(r, c) * eplus(c, j);
                        v += t;
                        s += t.abs();
                    }
                }
                if i < m && j < m {
                    let t = rho * rho * p_mat.at(i, j);
                    v -= t;
                    s += t.abs();
                }
                out.add(i, j, v);
                scale.add(i, j, s);
            }
        }
        for (k, (sec, lam)) in self.sectors.iter().zip(lambda).enumerate() {
            let s = sector_form(sec, m, np, k);
            out.axpy(*lam, &s);
            scale.axpy(
                lam.abs(),
                &Sym {
                    n: nz,
                    a: s.a.iter().map(|x| x.abs()).collect(),
                },
            );
        }
        (out, scale.abs_sum())
    }

    /// The block structure for [`maximise_last`] at rate ρ: unknowns (P̃ upper triangle,
    /// λ, t); blocks −M − tI ≻ 0, P̃ − tI ≻ 0, λ_j > 0, 1 − tr P̃ − Σλ > 0.
    fn blocks(&self, rho: f64) -> (Vec<AffineBlock>, Vec<f64>) {
        let (m, np) = (self.m, self.p());
        let nz = m + np;
        let pairs: Vec<(usize, usize)> = (0..m).flat_map(|i| (i..m).map(move |j| (i, j))).collect();
        let np_vars = pairs.len();
        let d = np_vars + np + 1;
        let unit_p = |(i, j): (usize, usize)| {
            let mut e = Sym::zeros(m);
            e.add(i, j, 1.0);
            if i != j {
                e.add(j, i, 1.0);
            }
            e
        };
        let neg = |s: Sym| Sym {
            n: s.n,
            a: s.a.iter().map(|x| -x).collect(),
        };
        // Block 1: −M(x) − tI.
        let mut f1 = Vec::with_capacity(d);
        let zero_lambda = vec![0.0; np];
        for &pr in &pairs {
            f1.push(neg(self.lmi_matrix(rho, &unit_p(pr), &zero_lambda).0));
        }
        for k in 0..np {
            f1.push(neg(sector_form(&self.sectors[k], m, np, k)));
        }
        f1.push(neg(Sym::identity(nz)));
        // Block 2: P̃ − tI.
        let mut f2: Vec<Sym> = pairs.iter().map(|&pr| unit_p(pr)).collect();
        f2.extend((0..np).map(|_| Sym::zeros(m)));
        f2.push(neg(Sym::identity(m)));
        let mut blocks = vec![
            AffineBlock {
                f0: Sym::zeros(nz),
                fi: f1,
            },
            AffineBlock {
                f0: Sym::zeros(m),
                fi: f2,
            },
        ];
        // λ_j > 0.
        for k in 0..np {
            let mut fi = vec![Sym::zeros(1); d];
            fi[np_vars + k] = Sym::identity(1);
            blocks.push(AffineBlock {
                f0: Sym::zeros(1),
                fi,
            });
        }
        // 1 − tr P̃ − Σλ > 0.
        let mut fi = vec![Sym::zeros(1); d];
        for (v, &(i, j)) in pairs.iter().enumerate() {
            if i == j {
                fi[v] = Sym {
                    n: 1,
                    a: vec![-1.0],
                };
            }
        }
        for k in 0..np {
            fi[np_vars + k] = Sym {
                n: 1,
                a: vec![-1.0],
            };
        }
        blocks.push(AffineBlock {
            f0: Sym::identity(1),
            fi,
        });
        // A strictly feasible start: P̃ = I/(2(m + p)), λ = 1/(2(m + p)), t below both.
        let w = 1.0 / (2.0 * (m + np) as f64);
        let mut y0 = vec![0.0; d];
        for (v, &(i, j)) in pairs.iter().enumerate() {
            if i == j {
                y0[v] = w;
            }
        }
        for k in 0..np {
            y0[np_vars + k] = w;
        }
        let (p0, l0) = self.unpack(&y0);
        let (m0, _) = self.lmi_matrix(rho, &p0, &l0);
        let top = sym_eigenvalues(&m0).last().copied().unwrap_or(0.0);
        y0[d - 1] = (-top).min(w) - 1.0;
        (blocks, y0)
    }

    fn unpack(&self, y: &[f64]) -> (Sym, Vec<f64>) {
        let m = self.m;
        let mut p = Sym::zeros(m);
        let mut v = 0;
        for i in 0..m {
            for j in i..m {
                p.add(i, j, y[v]);
                if i != j {
                    p.add(j, i, y[v]);
                }
                v += 1;
            }
        }
        (p, y[v..v + self.p()].to_vec())
    }

    /// Solves the LMI at rate ρ and checks the answer independently.
    pub(crate) fn certify_at(&self, rho: f64) -> Option<RateCertificate> {
        let (blocks, y0) = self.blocks(rho);
        // Stop at the first centred point whose (P̃, λ) passes the independent check.
        let passes = |y: &[f64]| {
            y[y.len() - 1] > 0.0 && {
                let (p, lambda) = self.unpack(y);
                self.check(rho, p, lambda).is_some()
            }
        };
        let y = maximise_last(&blocks, y0, 1e-11, passes)?;
        if !(y[y.len() - 1] > 0.0) {
            return None;
        }
        let (p, lambda) = self.unpack(&y);
        self.check(rho, p, lambda)
    }

    /// The independent check: P̃ ≻ 0 and M ≺ 0 by Jacobi eigenvalues, each with a margin
    /// of 10³·n·ε times the scale of the terms that formed it; λ ≥ 0.
    pub(crate) fn check(&self, rho: f64, p: Sym, lambda: Vec<f64>) -> Option<RateCertificate> {
        if lambda.iter().any(|l| !(*l >= 0.0)) || !(rho.is_finite()) {
            return None;
        }
        let eps = f64::EPSILON;
        let p_ev = sym_eigenvalues(&p);
        let p_tol = 1e3 * p.n as f64 * eps * p.abs_sum();
        if !(p_ev[0] > p_tol) {
            return None;
        }
        let (mm, scale) = self.lmi_matrix(rho, &p, &lambda);
        let top = sym_eigenvalues(&mm).last().copied()?;
        let tol = 1e3 * mm.n as f64 * eps * scale;
        if !(top < -tol) {
            return None;
        }
        Some(RateCertificate {
            rho,
            p,
            lambda,
            margin: -top / scale,
        })
    }

    /// The smallest rate in (0, 1) the LMI certifies (bisection on ρ, every accepted ρ
    /// checked), None when even ρ → 1 fails.
    pub(crate) fn best_rate(&self) -> Option<RateCertificate> {
        let mut best = self.certify_at(1.0 - 1e-13)?;
        let (mut lo, mut hi) = (0.0_f64, best.rho);
        for _ in 0..60 {
            if hi - lo <= 1e-13 * hi.max(1e-300) + 1e-15 {
                break;
            }
            let mid = 0.5 * (lo + hi);
            match self.certify_at(mid) {
                Some(c) => {
                    hi = mid;
                    best = c;
                }
                None => lo = mid,
            }
        }
        Some(best)
    }
}

/// S_k: the quadratic form (π_k − lo·v)(hi·v − π_k) in ζ = (ξ, π), symmetrised.
fn sector_form(sec: &Sector, m: usize, np: usize, k: usize) -> Sym {
    let nz = m + np;
    // r: v = rᵀζ; e: π_k = eᵀζ.
    let mut r = vec![0.0; nz];
    r[..m].copy_from_slice(&sec.c);
    r[m..].copy_from_slice(&sec.d);
    let mut e = vec![0.0; nz];
    e[m + k] = 1.0;
    let a: Vec<f64> = (0..nz).map(|i| e[i] - sec.lo * r[i]).collect();
    let b: Vec<f64> = (0..nz).map(|i| sec.hi * r[i] - e[i]).collect();
    let mut s = Sym::zeros(nz);
    for i in 0..nz {
        for j in 0..nz {
            s.add(i, j, 0.5 * (a[i] * b[j] + b[i] * a[j]));
        }
    }
    s
}

/// Projected gradient z⁺ = Π(z − α∇f(z)): ξ = e, π = (He, Δ).
pub(crate) fn pg_step(alpha: f64, mu: f64, l: f64) -> LureStep {
    LureStep {
        m: 1,
        a: vec![0.0],
        b: vec![0.0, 1.0],
        sectors: vec![
            Sector {
                c: vec![1.0],
                d: vec![0.0, 0.0],
                lo: mu,
                hi: l,
            },
            Sector {
                c: vec![1.0],
                d: vec![-alpha, 0.0],
                lo: 0.0,
                hi: 1.0,
            },
        ],
    }
}

/// V-FISTA x⁺ = Π(y − ∇f(y)/L), y = (1 + β)x − βx₋: ξ = (e_x, e_x₋), π = (He_y, Δ).
pub(crate) fn fista_step(beta: f64, step: f64, mu: f64, l: f64) -> LureStep {
    LureStep {
        m: 2,
        a: vec![0.0, 0.0, 1.0, 0.0],
        b: vec![0.0, 1.0, 0.0, 0.0],
        sectors: vec![
            Sector {
                c: vec![1.0 + beta, -beta],
                d: vec![0.0, 0.0],
                lo: mu,
                hi: l,
            },
            Sector {
                c: vec![1.0 + beta, -beta],
                d: vec![-step, 0.0],
                lo: 0.0,
                hi: 1.0,
            },
        ],
    }
}

/// ADMM as relaxed Douglas–Rachford on s: v = Π(s), z⁺ = G(2v − s) (+ const),
/// s⁺ = s + α(z⁺ − v), G = ρ(H + ρI)⁻¹: ξ = e_s, π = (Δv, G(2Δv − e_s)).
pub(crate) fn admm_step(rho: f64, alpha: f64, mu: f64, l: f64) -> LureStep {
    LureStep {
        m: 1,
        a: vec![1.0],
        b: vec![-alpha, alpha],
        sectors: vec![
            Sector {
                c: vec![1.0],
                d: vec![0.0, 0.0],
                lo: 0.0,
                hi: 1.0,
            },
            Sector {
                c: vec![-1.0],
                d: vec![2.0, 0.0],
                lo: rho / (rho + l),
                hi: rho / (rho + mu),
            },
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The independent check refuses what the LMI does not prove: a storage and multipliers
    /// accepted at the certified rate are refused below the attained rate, and with a
    /// negative multiplier.
    #[test]
    fn the_check_refuses_below_the_attained_rate() {
        // PG with step 2/(L + μ) on [0.1, 1]: attained rate 0.9/1.1.
        let step = pg_step(2.0 / 1.1, 0.1, 1.0);
        let c = step.best_rate().expect("PG has a rate");
        let exact = 0.9 / 1.1;
        assert!((c.rho - exact).abs() < 1e-9, "{}", c.rho);
        assert!(step.check(c.rho, c.p.clone(), c.lambda.clone()).is_some());
        assert!(
            step.check(exact * 0.999, c.p.clone(), c.lambda.clone())
                .is_none()
        );
        assert!(step.certify_at(exact * 0.999).is_none());
        let mut bad = c.lambda.clone();
        bad[0] = -1e-3;
        assert!(step.check(c.rho, c.p, bad).is_none());
    }
}
