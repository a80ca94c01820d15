//! The K_c-iteration MPC (`mpc_core::SuboptimalMpc` with the shift-and-repeat warm start)
//! with every buffer sized at compile time.

use crate::data::{DataError, Method, Window, at_least_one, check};
use crate::qp::{self, SLOTS};
use crate::scalar::Scalar;

/// The condensed MPC's data: K_c iterations of `method` on min ½UᵀHU + (q₀ + F x̂)ᵀU over
/// the box 𝒰^N, U = (u₀, …, u_{N−1}).
///
/// `qp` is the QP as the std map holds it (the Jacobi-scaled one when scaled): n = N·n_u,
/// n_θ = n_x (θ = x̂), H, F, q₀ (zero), the box 𝒰^N and the method's constants, exactly as
/// a [`Window`] of the estimator.
#[derive(Debug, Clone, Copy)]
pub struct MpcProblem<'a, T> {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// N ≥ 1.
    pub horizon: usize,
    /// K_c ≥ 1 iterations per call.
    pub iterations: usize,
    /// Φ_c.
    pub method: Method,
    /// The QP.
    pub qp: Window<'a, T>,
}

/// Why [`Mpc::control`] gave no input.
///
/// Exhaustive on purpose, unlike the crate's other errors: the exported C ABI
/// (`mhe_capi_f64_mpc_control`) gives each variant its own return code, so a new variant
/// must fail to compile there until it has one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MpcError {
    /// x̂ has a NaN or infinite entry (nothing was run; the warm start is kept).
    NonFiniteState,
    /// The K_c-th iterate is not finite (the next call cold-starts), as
    /// `mpc_core::MpcError::NonFiniteIterate`.
    NonFiniteIterate,
}

impl core::fmt::Display for MpcError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            MpcError::NonFiniteState => "the state estimate is not finite",
            MpcError::NonFiniteIterate => "the MPC's K_c-th iterate is not finite",
        })
    }
}

impl<T: Scalar> MpcProblem<'_, T> {
    /// Checks every length against the dimensions and the const buffer sizes.
    fn validate(&self, nx: usize, nu: usize, nseq: usize) -> Result<(), DataError> {
        check("NX (n_x)", self.nx, nx)?;
        check("NU (n_u)", self.nu, nu)?;
        check("NSEQ (N n_u)", self.horizon * self.nu, nseq)?;
        at_least_one("horizon and n_u (≥ 1)", self.horizon.min(nu))?;
        at_least_one("iterations (≥ 1)", self.iterations)?;
        let w = &self.qp;
        check("qp n", nseq, w.n)?;
        check("qp n_theta", nx, w.n_theta)?;
        check("qp h length", nseq * nseq, w.h.len())?;
        // The structured product is the MHE window's; the MPC's QP runs on its dense H.
        check(
            "qp structured (none for the MPC)",
            0,
            usize::from(w.structured.is_some()),
        )?;
        check("qp q0 length", nseq, w.q0.len())?;
        check("qp f length", nseq * nx, w.f.len())?;
        check("qp lower length", nseq, w.lower.len())?;
        check("qp upper length", nseq, w.upper.len())?;
        if !w.scaling.is_empty() {
            check("qp scaling length", nseq, w.scaling.len())?;
        }
        if self.method == Method::Admm {
            check("qp m_rho length", nseq * nseq, w.m_rho.len())?;
            check("qp m_inv length", nseq * nseq, w.m_inv.len())?;
        }
        Ok(())
    }
}

/// The sub-optimal MPC on borrowed data, allocation-free: per call, θ = x̂, K_c iterations
/// of the method from the warm start, u = the first block of Uᴷ.
///
/// The warm start is `mpc_core::WarmStart::ShiftRepeatLast` (the scenario's and the joint
/// certificate's default): (u₁, …, u_{N−1}, u_{N−1}) of the previous Uᴷ; the first call,
/// and the first after [`Mpc::reset`] or a non-finite iterate, cold-starts from Π_{𝒰^N}(0).
///
/// Const parameters (checked by [`Mpc::new`]): `NX` = n_x, `NU` = n_u, `NSEQ` = N n_u.
#[derive(Debug, Clone)]
pub struct Mpc<'a, T: Scalar, const NX: usize, const NU: usize, const NSEQ: usize> {
    p: &'a MpcProblem<'a, T>,
    work: [[T; NSEQ]; SLOTS],
    seq: [T; NSEQ],
    warm: [T; NSEQ],
    u: [T; NU],
    has_previous: bool,
}

impl<'a, T: Scalar, const NX: usize, const NU: usize, const NSEQ: usize> Mpc<'a, T, NX, NU, NSEQ> {
    /// A controller that cold-starts at its first call; errors if a const parameter or a
    /// data length does not match the problem.
    pub fn new(problem: &'a MpcProblem<'a, T>) -> Result<Self, DataError> {
        problem.validate(NX, NU, NSEQ)?;
        Ok(Self {
            p: problem,
            work: [[T::ZERO; NSEQ]; SLOTS],
            seq: [T::ZERO; NSEQ],
            warm: [T::ZERO; NSEQ],
            u: [T::ZERO; NU],
            has_previous: false,
        })
    }

    /// Forgets the previous sequence: the next call cold-starts.
    pub fn reset(&mut self) {
        self.has_previous = false;
    }

    /// The problem data.
    pub fn problem(&self) -> &'a MpcProblem<'a, T> {
        self.p
    }

    /// Uᴷ of the last call.
    pub fn input_sequence(&self) -> &[T; NSEQ] {
        &self.seq
    }

    /// u = π_{K_c}(x̂): K_c iterations from the warm start, the first block of Uᴷ.
    pub fn control(&mut self, x_hat: &[T; NX]) -> Result<&[T; NU], MpcError> {
        if !x_hat.iter().all(|v| v.is_finite()) {
            return Err(MpcError::NonFiniteState);
        }
        let p = self.p;
        let start = if self.has_previous {
            // Shift by one block and repeat the last.
            self.warm[..NSEQ - NU].copy_from_slice(&self.seq[NU..]);
            self.warm[NSEQ - NU..].copy_from_slice(&self.seq[NSEQ - NU..]);
            Some(&self.warm[..])
        } else {
            None
        };
        qp::run(
            p.method,
            &p.qp,
            x_hat,
            start,
            p.iterations,
            self.work.each_mut().map(|w| w.as_mut_slice()),
            &mut self.seq,
        );
        if !self.seq.iter().all(|v| v.is_finite()) {
            self.has_previous = false;
            return Err(MpcError::NonFiniteIterate);
        }
        self.has_previous = true;
        self.u.copy_from_slice(&self.seq[..NU]);
        Ok(&self.u)
    }
}
