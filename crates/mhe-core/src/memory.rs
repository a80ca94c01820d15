//! The memory of the MHE setup, estimated from the same sizes the code allocates by, before
//! anything is built (docs/limits.md, key `mhe.horizon`).
//!
//! [`MheEstimator::new`](crate::MheEstimator::new) builds one condensed QP per window
//! length m = 0..M ([`MheProblem::new`](crate::MheProblem::new), `build_window`), one
//! iteration map Φ per window (each owns a copy of its QP), and with `exact_solve` one exact
//! solver per window. With n_z = n_x + m·n_w variables, n_θ = n_x + m(n_u + n_y) parameters,
//! n_p = n_x + m(n_w + n_y) rows of the paper's variables and r_m general rows (finite state
//! and output bounds), window m holds, in f64 entries:
//!
//! - the window: T (n_p × n_z), S and the z̃ map (n_p × n_θ each), the paper's Hessian
//!   (n_p²), the end-state maps (n_x(n_z + n_θ)), H_c and F_c twice (column- and row-major:
//!   2(n_z² + n_z n_θ)), the general rows G, E (r_m(n_z + n_θ));
//! - Φ: a copy of the QP (2(n_z² + n_z n_θ)); ADMM adds (H + ρI)⁻¹ and its factor (2n_z²); a Jacobi-scaled
//!   method runs on a scaled copy (another 2(n_z² + n_z n_θ));
//! - the exact solver: its own copy of the QP and a factorisation (3 n_z² + 2 n_z n_θ);
//! - with general rows, Φ and the exact solver each keep row products and factors, about
//!   5(r_m² + r_m n_z) (calibrated against the measured peak, not derived line by line).
//!
//! The peak adds the temporaries of the last window built (products and the Cholesky
//! factor, about 3 n_p² + 4 n_z n_θ). The test `long_setup_memory_estimate_is_within_2x_of_the_peak`
//! (mhe-core `tests/alloc.rs`) compares this estimate with the heap high-water mark of
//! `MheEstimator::new` on a grid of sizes and methods.

use qp_iter::Method;
use qp_iter::method::{MethodKind, Scaling};

/// What the setup's size depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetupShape {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// n_w = n_w1 + n_w2.
    pub nw: usize,
    /// Components of x with a finite bound (a general row per window stage each).
    pub state_rows: usize,
    /// Components of y with a finite bound.
    pub output_rows: usize,
    /// M.
    pub horizon: usize,
    /// The method Φ.
    pub method: Method,
    /// Whether an exact solver is built per window (ε_t).
    pub exact_solve: bool,
}

/// f64 entries of window m's matrices (see the module docs), and of its temporaries.
fn window_entries(s: &SetupShape, m: f64) -> (f64, f64) {
    let nx = s.nx as f64;
    let nz = nx + m * s.nw as f64;
    let nth = nx + m * (s.nu + s.ny) as f64;
    let np = nx + m * (s.nw + s.ny) as f64;
    let rows = m * (s.state_rows + s.output_rows) as f64;
    let qp = 2.0 * (nz * nz + nz * nth);
    let window = np * nz + 2.0 * np * nth + np * np + nx * (nz + nth) + qp + rows * (nz + nth);
    let mut map = qp;
    if matches!(s.method.kind, MethodKind::Admm(_)) {
        map += 2.0 * nz * nz;
    }
    if s.method.scaling != Scaling::None {
        map += qp;
    }
    // General rows: Φ projects onto them (or splits them, ADMM) and the exact solver is a
    // dual active set over them; each keeps row products and factors of about
    // 5(r_m² + r_m n_z) entries (measured; tests/alloc.rs).
    let general = 5.0 * (rows * rows + rows * nz);
    map += general;
    let exact = if s.exact_solve {
        3.0 * nz * nz + 2.0 * nz * nth + general
    } else {
        0.0
    };
    let temporaries = 3.0 * np * np + 4.0 * nz * nth;
    (window + map + exact, temporaries)
}

/// Estimated peak heap bytes of [`MheEstimator::new`](crate::MheEstimator::new) for
/// `shape`: the sum over m = 0..M of every window's matrices, plus the temporaries of the
/// last. Every window's kept entries are a quadratic in m (products of sizes linear in m),
/// so the sum is computed in closed form, for any M in O(1): the estimate printed is the
/// estimate, not the limit (issue 37 item 9: M = 200 and M = 600 both printed "about 2.0 GiB").
pub fn setup_bytes(shape: &SetupShape) -> f64 {
    // f(m) = a + b·m + c·m², from f(0), f(1), f(2).
    let f = |m: f64| window_entries(shape, m).0;
    let (f0, f1, f2) = (f(0.0), f(1.0), f(2.0));
    let c = 0.5 * (f2 - 2.0 * f1 + f0);
    let b = f1 - f0 - c;
    let a = f0;
    let m = shape.horizon as f64;
    // Σ_{m=0}^{M} 1, m, m².
    let (s0, s1, s2) = (
        m + 1.0,
        m * (m + 1.0) / 2.0,
        m * (m + 1.0) * (2.0 * m + 1.0) / 6.0,
    );
    let entries = a * s0 + b * s1 + c * s2;
    let last_temp = window_entries(shape, m).1;
    8.0 * (entries + last_temp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_state(horizon: usize) -> SetupShape {
        SetupShape {
            nx: 1,
            nu: 1,
            ny: 1,
            nw: 2,
            state_rows: 1,
            output_rows: 1,
            horizon,
            method: Method::default(),
            exact_solve: true,
        }
    }

    /// Issue 23: a one-state plant with M = 300 aborted at 4.6 GB under a 1 GiB limit (the
    /// old estimate counted H_c and F_c once); it is now beyond the limit, M = 100 within.
    #[test]
    fn the_one_state_plant_at_m_300_is_beyond_the_limit() {
        let limit = lti_model::spec::format::MAX_DENSE_BYTES;
        assert!(setup_bytes(&one_state(300)) > limit);
        assert!(setup_bytes(&one_state(100)) < limit);
        // Monotone in M.
        assert!(setup_bytes(&one_state(50)) < setup_bytes(&one_state(51)));
    }

    /// The closed form equals the window-by-window sum (the definition), and beyond the
    /// limit it is still the estimate: M = 600 needs about 8× M = 300 (cubic in M), where
    /// the summation that stopped at the limit gave ≈ 2 GiB for both (issue 37 item 9).
    #[test]
    fn the_estimate_is_the_sum_of_the_windows_beyond_the_limit_too() {
        for shape in [one_state(0), one_state(1), one_state(7), one_state(300)] {
            let (mut kept, mut temp) = (0.0, 0.0);
            for m in 0..=shape.horizon {
                let (k, t) = window_entries(&shape, m as f64);
                kept += k;
                temp = t;
            }
            let direct = 8.0 * (kept + temp);
            let closed = setup_bytes(&shape);
            assert!(
                (closed - direct).abs() <= 1e-12 * direct,
                "M = {}: {closed} vs {direct}",
                shape.horizon
            );
        }
        let limit = lti_model::spec::format::MAX_DENSE_BYTES;
        let (b200, b300, b600) = (
            setup_bytes(&one_state(200)),
            setup_bytes(&one_state(300)),
            setup_bytes(&one_state(600)),
        );
        assert!(b300 > limit && b600 > 7.0 * b300, "{b300} {b600}");
        assert!(b200 < b300, "{b200} {b300}");
    }
}
