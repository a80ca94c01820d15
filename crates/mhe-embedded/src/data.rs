//! The problem data the estimator runs on (normally `static` arrays written by
//! `cargo xtask export`), and its validation.

use crate::scalar::Scalar;
use crate::structured::Structured;

/// The iteration map Φ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Projected gradient z⁺ = Π(z − α(Hz + q)).
    Pg,
    /// V-FISTA (step 1/L, constant momentum β, a plain PG step after every warm start).
    Fista,
    /// ADMM on the Douglas–Rachford variable with ρ(H + ρI)⁻¹, penalty ρ, relaxation α;
    /// the gradient dual −(Hz⁰ + q) at every warm start; the iterate is Π(s).
    Admm,
}

/// The warm-start rule Σ_t once the window is full (while it grows: keep, zero-fill).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WarmStart {
    /// The paper's Σ_t: z⁰_{t+1} = zᴷ_t.
    Paper,
    /// Shift by one stage: x̂₀ ← A x̂₀ + B u + E ŵ¹, drop the oldest ŵ, zero the newest.
    Shifted,
}

/// ℙ_t for one window length m: min ½yᵀHy + (q₀ + Fθ)ᵀy over the box, with z = D y when
/// `scaling` holds d (Jacobi), z = y otherwise. Everything is the data of the problem the
/// method runs on (the scaled one when scaled).
#[derive(Debug, Clone, Copy)]
pub struct Window<'a, T> {
    /// n = n_x + m n_w.
    pub n: usize,
    /// n_θ = n_x + m (n_u + n_y).
    pub n_theta: usize,
    /// H (n × n, symmetric), entry (i, j) at j·n + i; empty when `structured` holds the
    /// window's factors instead.
    pub h: &'a [T],
    /// ADMM: ρ(H + ρI)⁻¹ (n × n, j·n + i); empty for the other methods.
    pub m_rho: &'a [T],
    /// ADMM: (H + ρI)⁻¹ (n × n, j·n + i); empty for the other methods.
    pub m_inv: &'a [T],
    /// q₀ (n).
    pub q0: &'a [T],
    /// F (n × n_θ), entry (i, k) at i·n_θ + k.
    pub f: &'a [T],
    /// Lower bounds of the box (n, −∞ allowed).
    pub lower: &'a [T],
    /// Upper bounds of the box (n, +∞ allowed).
    pub upper: &'a [T],
    /// The Jacobi scaling d (n entries, z = D y) or empty.
    pub scaling: &'a [T],
    /// PG: α; FISTA: 1/L.
    pub step: T,
    /// FISTA: β.
    pub momentum: T,
    /// ADMM: 1/ρ.
    pub inv_rho: T,
    /// ADMM: the relaxation α.
    pub relaxation: T,
    /// PG and FISTA on a long window: H's factors, the product run instead of the dense H
    /// (as the std estimator from n ≥ its crossover); `None`: the dense H.
    pub structured: Option<&'a Structured<'a, T>>,
}

/// Everything the estimator needs: the model, M, K, the method and ℙ_t for m = 0..M.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a, T> {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// n_w1 (disturbance of the dynamics).
    pub nw1: usize,
    /// n_w2 (disturbance of the output).
    pub nw2: usize,
    /// M ≥ 1.
    pub horizon: usize,
    /// K ≥ 1 iterations per step.
    pub iterations: usize,
    /// Φ.
    pub method: Method,
    /// Σ_t once the window is full.
    pub warm_start: WarmStart,
    /// A (n_x × n_x, row-major).
    pub a: &'a [T],
    /// B (n_x × n_u, row-major).
    pub b: &'a [T],
    /// E (n_x × n_w1, row-major).
    pub e: &'a [T],
    /// ℙ_t for m = 0..M (M + 1 windows).
    pub windows: &'a [Window<'a, T>],
}

/// Why [`crate::Mhe::new`] refused a problem: a buffer size or a data length that does
/// not match (the field and the expected and actual values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct DataError {
    /// The field or const parameter.
    pub what: &'static str,
    /// What it should be.
    pub expected: usize,
    /// What it is.
    pub actual: usize,
}

impl core::fmt::Display for DataError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}: expected {}, found {}",
            self.what, self.expected, self.actual
        )
    }
}

pub(crate) fn check(what: &'static str, expected: usize, actual: usize) -> Result<(), DataError> {
    if expected == actual {
        Ok(())
    } else {
        Err(DataError {
            what,
            expected,
            actual,
        })
    }
}

/// `Ok` when a count that must be positive is (`what` names it, e.g. `"iterations (≥ 1)"`).
pub(crate) fn at_least_one(what: &'static str, actual: usize) -> Result<(), DataError> {
    if actual >= 1 {
        Ok(())
    } else {
        Err(DataError {
            what,
            expected: 1,
            actual,
        })
    }
}

impl<T: Scalar> Problem<'_, T> {
    /// n_w = n_w1 + n_w2.
    pub fn nw(&self) -> usize {
        self.nw1 + self.nw2
    }

    /// Checks every length against the dimensions and the const buffer sizes of the
    /// estimator (NX, NU, NY, M, NZ = NX + M n_w, NTH = NX + M (NU + NY)).
    pub(crate) fn validate(
        &self,
        nx: usize,
        nu: usize,
        ny: usize,
        m: usize,
        nz: usize,
        nth: usize,
    ) -> Result<(), DataError> {
        check("NX (n_x)", self.nx, nx)?;
        check("NU (n_u)", self.nu, nu)?;
        check("NY (n_y)", self.ny, ny)?;
        check("M (horizon)", self.horizon, m)?;
        check("NZ (n_x + M n_w)", self.nx + m * self.nw(), nz)?;
        check("NTH (n_x + M (n_u + n_y))", self.nx + m * (nu + ny), nth)?;
        at_least_one("horizon (≥ 1)", self.horizon)?;
        at_least_one("iterations (≥ 1)", self.iterations)?;
        check("a length", nx * nx, self.a.len())?;
        check("b length", nx * nu, self.b.len())?;
        check("e length", nx * self.nw1, self.e.len())?;
        check("windows (M + 1)", m + 1, self.windows.len())?;
        for (k, w) in self.windows.iter().enumerate() {
            let n = self.nx + k * self.nw();
            check("window n", n, w.n)?;
            check("window n_theta", self.nx + k * (nu + ny), w.n_theta)?;
            match w.structured {
                Some(st) => {
                    if self.method == Method::Admm {
                        return Err(DataError {
                            what: "window structured (PG and FISTA only; ADMM needs h)",
                            expected: 0,
                            actual: 1,
                        });
                    }
                    st.validate(self.nx, ny, self.nw1, self.nw2, k)?;
                    if !w.h.is_empty() {
                        check("window h length (structured)", n * n, w.h.len())?;
                    }
                }
                None => check("window h length", n * n, w.h.len())?,
            }
            check("window q0 length", n, w.q0.len())?;
            check("window f length", n * w.n_theta, w.f.len())?;
            check("window lower length", n, w.lower.len())?;
            check("window upper length", n, w.upper.len())?;
            if !w.scaling.is_empty() {
                check("window scaling length", n, w.scaling.len())?;
            }
            if self.method == Method::Admm {
                check("window m_rho length", n * n, w.m_rho.len())?;
                check("window m_inv length", n * n, w.m_inv.len())?;
            }
        }
        Ok(())
    }
}
