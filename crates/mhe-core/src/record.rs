//! The per-step record of the MHE: what traces and plots are made of.

use qp_iter::RunStatus;
#[cfg(feature = "serde")]
use serde::ser::{SerializeSeq, SerializeStruct};
#[cfg(feature = "serde")]
use serde::{Serialize, Serializer};

use crate::problem::Dims;

/// Everything one MHE step produced, filled in place by
/// [`crate::MheEstimator::estimate`] (no allocation per step: every vector is preallocated
/// for the longest window and reused).
///
/// Sequences are stored flat, oldest first; the accessors return one stage at a time and
/// serialisation writes nested arrays (`u[j]`, `w_k[j]`, …, stage j is time t − M_t + j).
/// Clone it out with `clone()` (allocates) or [`MheRecord::copy_into`] (reuses the target's
/// buffers).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MheRecord {
    dims: Dims,
    /// Time step t (number of (u, y) pairs pushed before this estimate).
    pub t: usize,
    /// Window length M_t = min(M, t).
    pub window: usize,
    /// Iterations of Φ run (K).
    pub iterations: usize,
    /// Status of the K iterations (`NonFinite` if the iterate overflowed).
    pub status: RunStatus,
    /// V_MHE (eq. 9) at the K-th iterate.
    pub cost_k: f64,
    /// V_MHE at the exact optimum (if the exact solve is on).
    pub cost_exact: Option<f64>,
    /// ε_t = ‖zᴷ_t − z*_t‖₂ in condensed coordinates (if the exact solve is on).
    pub epsilon: Option<f64>,
    /// ‖z⁰_t − z*_t‖₂ in condensed coordinates (if the exact solve is on).
    pub initial_error: Option<f64>,
    /// Largest violation by zᴷ_t of Z and, with bounded 𝒳 / 𝒴, of the rows x̂_i ∈ 𝒳,
    /// ŷ_i ∈ 𝒴 for this θ ([`qp_iter::IterationMap::violation`]): 0 for PG/FISTA up to
    /// rounding; for ADMM split on the rows the measured premise failure (trap 7).
    pub violation: f64,
    prior: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
    x_start_k: Vec<f64>,
    w_k: Vec<f64>,
    x_hat: Vec<f64>,
    has_exact: bool,
    x_start_exact: Vec<f64>,
    w_exact: Vec<f64>,
    x_hat_exact: Vec<f64>,
}

impl MheRecord {
    /// An empty record with capacity for windows up to `horizon`.
    pub(crate) fn with_capacity(dims: Dims, horizon: usize) -> Self {
        let (nx, nw) = (dims.nx, dims.nw());
        Self {
            dims,
            t: 0,
            window: 0,
            iterations: 0,
            status: RunStatus::Completed,
            cost_k: 0.0,
            cost_exact: None,
            epsilon: None,
            initial_error: None,
            violation: 0.0,
            prior: vec![0.0; nx],
            u: Vec::with_capacity(horizon * dims.nu),
            y: Vec::with_capacity(horizon * dims.ny),
            x_start_k: vec![0.0; nx],
            w_k: Vec::with_capacity(horizon * nw),
            x_hat: vec![0.0; nx],
            has_exact: false,
            x_start_exact: vec![0.0; nx],
            w_exact: Vec::with_capacity(horizon * nw),
            x_hat_exact: vec![0.0; nx],
        }
    }

    /// Plant dimensions.
    pub fn dims(&self) -> Dims {
        self.dims
    }
    /// The prior x^prior_{t−M_t} used (x̄₀ for t ≤ M, x̂ᴷ_{t−M|t−M} after).
    pub fn prior(&self) -> &[f64] {
        &self.prior
    }
    /// u_{t−M_t+j}, j = 0..M_t.
    pub fn u(&self, j: usize) -> Option<&[f64]> {
        stage(&self.u, self.dims.nu, self.window, j)
    }
    /// y_{t−M_t+j}, j = 0..M_t.
    pub fn y(&self, j: usize) -> Option<&[f64]> {
        stage(&self.y, self.dims.ny, self.window, j)
    }
    /// All window inputs, flat, oldest first.
    pub fn u_flat(&self) -> &[f64] {
        &self.u
    }
    /// All window measurements, flat, oldest first.
    pub fn y_flat(&self) -> &[f64] {
        &self.y
    }
    /// x̂ᴷ_{t−M_t|t}: first state of the K-th iterate.
    pub fn x_start_k(&self) -> &[f64] {
        &self.x_start_k
    }
    /// ŵᴷ_{t−M_t+j|t} = (ŵ¹, ŵ²) of the K-th iterate.
    pub fn w_k(&self, j: usize) -> Option<&[f64]> {
        stage(&self.w_k, self.dims.nw(), self.window, j)
    }
    /// ŵ²ᴷ_{t−M_t+j|t}: the estimated measurement noise (Fig. 2(c)).
    pub fn w2_k(&self, j: usize) -> Option<&[f64]> {
        self.w_k(j).map(|w| &w[self.dims.nw1..])
    }
    /// The ŵ sequence of the K-th iterate, flat, oldest first.
    pub fn w_k_flat(&self) -> &[f64] {
        &self.w_k
    }
    /// x̂ᴷ_{t|t}: the estimate returned.
    pub fn x_hat(&self) -> &[f64] {
        &self.x_hat
    }
    /// x̂*_{t−M_t|t} of the exact optimum (None unless the exact solve is on).
    pub fn x_start_exact(&self) -> Option<&[f64]> {
        self.has_exact.then_some(&self.x_start_exact[..])
    }
    /// ŵ*_{t−M_t+j|t} of the exact optimum.
    pub fn w_exact(&self, j: usize) -> Option<&[f64]> {
        if self.has_exact {
            stage(&self.w_exact, self.dims.nw(), self.window, j)
        } else {
            None
        }
    }
    /// ŵ²*_{t−M_t+j|t}: the exact optimum's estimated measurement noise.
    pub fn w2_exact(&self, j: usize) -> Option<&[f64]> {
        self.w_exact(j).map(|w| &w[self.dims.nw1..])
    }
    /// The exact ŵ sequence, flat, oldest first.
    pub fn w_exact_flat(&self) -> Option<&[f64]> {
        self.has_exact.then_some(&self.w_exact[..])
    }
    /// x̂*_{t|t}: the estimate of the exact MHE.
    pub fn x_hat_exact(&self) -> Option<&[f64]> {
        self.has_exact.then_some(&self.x_hat_exact[..])
    }

    /// Copies `self` into `out`, reusing `out`'s buffers (no allocation once `out` has
    /// seen a window as long as this one).
    pub fn copy_into(&self, out: &mut Self) {
        out.dims = self.dims;
        out.t = self.t;
        out.window = self.window;
        out.iterations = self.iterations;
        out.status = self.status;
        out.cost_k = self.cost_k;
        out.cost_exact = self.cost_exact;
        out.epsilon = self.epsilon;
        out.initial_error = self.initial_error;
        out.violation = self.violation;
        out.has_exact = self.has_exact;
        // `Vec::clone_from` reuses the target's allocation when it is large enough.
        out.prior.clone_from(&self.prior);
        out.u.clone_from(&self.u);
        out.y.clone_from(&self.y);
        out.x_start_k.clone_from(&self.x_start_k);
        out.w_k.clone_from(&self.w_k);
        out.x_hat.clone_from(&self.x_hat);
        out.x_start_exact.clone_from(&self.x_start_exact);
        out.w_exact.clone_from(&self.w_exact);
        out.x_hat_exact.clone_from(&self.x_hat_exact);
    }

    // ---- filling (crate-internal, allocation-free) ----

    pub(crate) fn begin(&mut self, t: usize, window: usize, theta: &[f64], iterations: usize) {
        let (nx, nu, ny) = (self.dims.nx, self.dims.nu, self.dims.ny);
        self.t = t;
        self.window = window;
        self.iterations = iterations;
        self.prior.copy_from_slice(&theta[..nx]);
        let u_end = nx + window * nu;
        self.u.clear();
        self.u.extend_from_slice(&theta[nx..u_end]);
        self.y.clear();
        self.y.extend_from_slice(&theta[u_end..u_end + window * ny]);
        self.has_exact = false;
        self.cost_exact = None;
        self.epsilon = None;
        self.initial_error = None;
    }

    pub(crate) fn set_iterate(
        &mut self,
        z: &[f64],
        x_hat: &[f64],
        status: RunStatus,
        cost: f64,
        violation: f64,
    ) {
        let nx = self.dims.nx;
        self.x_start_k.copy_from_slice(&z[..nx]);
        self.w_k.clear();
        self.w_k.extend_from_slice(&z[nx..]);
        self.x_hat.copy_from_slice(x_hat);
        self.status = status;
        self.cost_k = cost;
        self.violation = violation;
    }

    pub(crate) fn set_exact(&mut self, z: &[f64], x_hat: &[f64], cost: f64, eps: f64, eps0: f64) {
        let nx = self.dims.nx;
        self.x_start_exact.copy_from_slice(&z[..nx]);
        self.w_exact.clear();
        self.w_exact.extend_from_slice(&z[nx..]);
        self.x_hat_exact.copy_from_slice(x_hat);
        self.has_exact = true;
        self.cost_exact = Some(cost);
        self.epsilon = Some(eps);
        self.initial_error = Some(eps0);
    }
}

fn stage(v: &[f64], width: usize, count: usize, j: usize) -> Option<&[f64]> {
    if j >= count {
        return None;
    }
    v.get(j * width..(j + 1) * width)
}

/// A flat sequence serialised as an array of stages.
#[cfg(feature = "serde")]
struct Stages<'a>(&'a [f64], usize, usize);

#[cfg(feature = "serde")]
impl Serialize for Stages<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let Stages(v, width, count) = *self;
        let mut seq = s.serialize_seq(Some(count))?;
        for j in 0..count {
            seq.serialize_element(stage(v, width, count, j).unwrap_or(&[]))?;
        }
        seq.end()
    }
}

/// The MHE part of a closed-loop trace (closed-loop's `Trace::to_json`, feature `serde`).
#[cfg(feature = "serde")]
impl Serialize for MheRecord {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let nw = self.dims.nw();
        let mut st = s.serialize_struct("MheRecord", 18)?;
        st.serialize_field("t", &self.t)?;
        st.serialize_field("window", &self.window)?;
        st.serialize_field("prior", &self.prior)?;
        st.serialize_field("u", &Stages(&self.u, self.dims.nu, self.window))?;
        st.serialize_field("y", &Stages(&self.y, self.dims.ny, self.window))?;
        st.serialize_field("x_start_k", &self.x_start_k)?;
        st.serialize_field("w_k", &Stages(&self.w_k, nw, self.window))?;
        st.serialize_field("x_hat", &self.x_hat)?;
        st.serialize_field("x_start_exact", &self.x_start_exact())?;
        st.serialize_field(
            "w_exact",
            &self.w_exact_flat().map(|w| Stages(w, nw, self.window)),
        )?;
        st.serialize_field("x_hat_exact", &self.x_hat_exact())?;
        st.serialize_field("epsilon", &self.epsilon)?;
        st.serialize_field("initial_error", &self.initial_error)?;
        st.serialize_field("cost_k", &self.cost_k)?;
        st.serialize_field("cost_exact", &self.cost_exact)?;
        st.serialize_field("violation", &self.violation)?;
        st.serialize_field("iterations", &self.iterations)?;
        st.serialize_field("status", &self.status)?;
        st.end()
    }
}
