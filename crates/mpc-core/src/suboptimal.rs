//! The sub-optimal MPC: exactly K iterations of an iteration map Φ per control call,
//! warm-started from the time-shifted previous input sequence.

use lti_model::Projection;
use qp_iter::{IterationMap, RunResult, RunStatus, run_fixed};

use crate::condensed::CondensedMpc;
use crate::error::{MpcError, Result};
use crate::{ControlStatus, Controller, MpcFallback, check_io};

/// Warm start of [`SuboptimalMpc`] from the previous K-th iterate Uᴷ = (u₀, …, u_{N−1}).
///
/// Every choice starts from a point of 𝒰^N, so the iterates of PG/FISTA stay feasible.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WarmStart {
    /// (u₁, …, u_{N−1}, u_{N−1}): shift by one stage and repeat the last block (the
    /// default). The repeated block is in 𝒰 and continues the predicted tail, which near
    /// the origin is close to the LQR continuation the DARE terminal cost encodes.
    #[default]
    ShiftRepeatLast,
    /// (u₁, …, u_{N−1}, Π_𝒰(0)): shift and append the projection of 0 onto 𝒰.
    ShiftZero,
    /// The previous sequence unchanged (no shift).
    Previous,
    /// Cold start every call: Π_{𝒰^N}(0).
    Cold,
}

/// K iterations of Φ on the condensed MPC QP per call; u = first block of Uᴷ.
///
/// The first call (and the first call after [`SuboptimalMpc::reset`] or a non-finite
/// iterate) cold-starts from Π_{𝒰^N}(0). Allocation-free per call after construction.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{CondensedMpc, Controller, MpcConfig, SuboptimalMpc, WarmStart};
/// use qp_iter::fista::Fista;
/// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// let mut ctrl = SuboptimalMpc::new(&mpc, Fista::new(mpc.qp().clone()), 50, WarmStart::default()).unwrap();
/// let mut u = [0.0];
/// ctrl.control(&[1.0, 0.0], &mut u).unwrap();
/// assert!(u[0] < 0.0 && u[0] >= -1.0);
/// ```
#[derive(Debug)]
pub struct SuboptimalMpc<M: IterationMap> {
    map: M,
    state: M::State,
    iterations: usize,
    warm: WarmStart,
    nx: usize,
    nu: usize,
    /// Π_𝒰(0), appended by [`WarmStart::ShiftZero`].
    zero_block: Vec<f64>,
    warm_buf: Vec<f64>,
    has_previous: bool,
    last: Option<RunResult>,
    /// With state constraints: an infeasible projection (NaN iterate) applies the shifted
    /// plan (see [`Controller::control`]).
    state_constrained: bool,
    status: ControlStatus,
}

/// Largest |a − b| over two equally long sequences of values (∞ = ∞ counts as equal).
fn max_diff(a: impl Iterator<Item = f64>, b: impl Iterator<Item = f64>) -> f64 {
    a.zip(b)
        .map(|(x, y)| if x == y { 0.0 } else { (x - y).abs() })
        .fold(0.0, f64::max)
}

impl<M: IterationMap> SuboptimalMpc<M> {
    /// Wraps `map` (built on `mpc.qp()`, e.g. `Fista::new(mpc.qp().clone())`) with
    /// `iterations` = K steps per call.
    ///
    /// Errors: [`MpcError::MapMismatch`] if the map's QP differs from `mpc.qp()`
    /// (dimensions, H, F or 𝒰^N, compared to 1e-12 relative).
    pub fn new(mpc: &CondensedMpc, map: M, iterations: usize, warm: WarmStart) -> Result<Self> {
        let mine = mpc.qp();
        let theirs = map.problem();
        if theirs.n() != mine.n() || theirs.n_theta() != mine.n_theta() {
            return Err(MpcError::MapMismatch {
                what: format!(
                    "map QP has n = {}, n_θ = {}; the MPC needs n = N·n_u = {}, n_θ = n_x = {}",
                    theirs.n(),
                    theirs.n_theta(),
                    mine.n(),
                    mine.n_theta()
                ),
            });
        }
        let (n, nt) = (mine.n(), mine.n_theta());
        let scale_h = mine.h().norm_max().max(1.0);
        let dh = max_diff(
            (0..n * n).map(|k| mine.h()[(k / n, k % n)]),
            (0..n * n).map(|k| theirs.h()[(k / n, k % n)]),
        );
        let scale_f = mine.f().norm_max().max(1.0);
        let df = max_diff(
            (0..n * nt).map(|k| mine.f()[(k / nt, k % nt)]),
            (0..n * nt).map(|k| theirs.f()[(k / nt, k % nt)]),
        );
        let dq = max_diff(mine.q0().iter().copied(), theirs.q0().iter().copied());
        let dz = max_diff(
            mine.zset().lower().iter().copied(),
            theirs.zset().lower().iter().copied(),
        )
        .max(max_diff(
            mine.zset().upper().iter().copied(),
            theirs.zset().upper().iter().copied(),
        ));
        for (what, d, s) in [
            ("H", dh, scale_h),
            ("F", df, scale_f),
            ("q0", dq, scale_f),
            ("Z = 𝒰^N", dz, 1.0),
        ] {
            if !(d <= 1e-12 * s) {
                return Err(MpcError::MapMismatch {
                    what: format!("{what} differs by {d:e}"),
                });
            }
        }
        let nu = mpc.nu();
        let mut zero_block = vec![0.0; nu];
        mpc.input_set().project(&mut zero_block);
        let state = map.new_state();
        Ok(Self {
            map,
            state,
            iterations,
            warm,
            nx: mpc.nx(),
            nu,
            zero_block,
            warm_buf: vec![0.0; n],
            has_previous: false,
            last: None,
            state_constrained: mpc.has_general_rows(),
            status: ControlStatus::Applied { violation: 0.0 },
        })
    }

    /// K, the iterations per call.
    pub fn iterations(&self) -> usize {
        self.iterations
    }
    /// Changes K (takes effect at the next call).
    pub fn set_iterations(&mut self, k: usize) {
        self.iterations = k;
    }
    /// The warm-start rule.
    pub fn warm_start_rule(&self) -> WarmStart {
        self.warm
    }
    /// The iteration map Φ (its certificate is `map().certificate()`).
    pub fn map(&self) -> &M {
        &self.map
    }
    /// The full K-th iterate Uᴷ of the last call (the cold start before the first call).
    pub fn input_sequence(&self) -> &[f64] {
        self.map.iterate(&self.state)
    }
    /// Outcome of the last call's run (None before the first call).
    pub fn last_run(&self) -> Option<RunResult> {
        self.last
    }
    /// Forgets the previous sequence: the next call cold-starts.
    pub fn reset(&mut self) {
        self.has_previous = false;
    }

    /// Writes the warm start for this call into the map state.
    fn start(&mut self) {
        let n = self.warm_buf.len();
        let nu = self.nu;
        if !self.has_previous || self.warm == WarmStart::Cold {
            self.map.cold_start(&mut self.state);
            return;
        }
        let prev = self.map.iterate(&self.state);
        match self.warm {
            WarmStart::Previous => self.warm_buf.copy_from_slice(prev),
            WarmStart::ShiftRepeatLast | WarmStart::ShiftZero => {
                self.warm_buf[..n - nu].copy_from_slice(&prev[nu..]);
                if self.warm == WarmStart::ShiftZero {
                    self.warm_buf[n - nu..].copy_from_slice(&self.zero_block);
                } else {
                    self.warm_buf[n - nu..].copy_from_slice(&prev[n - nu..]);
                }
            }
            WarmStart::Cold => {}
        }
        self.map.warm_start(&mut self.state, &self.warm_buf, None);
    }
}

impl<M: IterationMap> Controller for SuboptimalMpc<M> {
    type Error = MpcError;
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> Result<()> {
        check_io(x_hat, u, self.nx, self.nu)?;
        self.map.load(&mut self.state, x_hat);
        let warm = self.has_previous && self.warm != WarmStart::Cold;
        self.start();
        let run = run_fixed(&self.map, &mut self.state, self.iterations);
        self.last = Some(run);
        if run.status == RunStatus::NonFinite {
            self.has_previous = false;
            if self.state_constrained {
                // PG / FISTA project exactly onto 𝒰^N ∩ {state rows}: a NaN iterate from
                // finite data means that set is empty at this x̂. Apply the first block of
                // the warm start (for the shifting rules the previous plan's next input;
                // Π_𝒰(0) after a cold start), which lies in 𝒰.
                let nu = self.nu;
                if warm {
                    u.copy_from_slice(&self.warm_buf[..nu]);
                } else {
                    u.copy_from_slice(&self.zero_block);
                }
                self.status = ControlStatus::Infeasible {
                    constraint: None,
                    fallback: MpcFallback::ShiftedPlan,
                };
                return Ok(());
            }
            return Err(MpcError::NonFiniteIterate);
        }
        u.copy_from_slice(&self.map.iterate(&self.state)[..self.nu]);
        self.status = ControlStatus::Applied {
            violation: self.map.violation(&self.state),
        };
        self.has_previous = true;
        Ok(())
    }
    fn status(&self) -> ControlStatus {
        self.status
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nx(&self) -> usize {
        self.nx
    }
}
