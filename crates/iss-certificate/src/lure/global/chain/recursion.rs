//! The linear recursion a method runs between two clamps (PG, FISTA, ADMM and their Jacobi
//! variants), read off and checked against the probed K-step map (docs/theory.md §4b, §4c).

use faer::Mat;
use faer::linalg::solvers::Solve;
use qp_iter::{IterationMap, MethodMap};

use crate::linear::IterationLinearisation;

/// The recursion a method runs between two clamps: PG (β = 0), FISTA (its momentum β), or
/// ADMM (its H, ρ, α, in the coordinates it runs in).
#[derive(Debug, Clone)]
pub(super) enum Recursion {
    Pg,
    Fista(f64),
    Admm { h: Mat<f64>, rho: f64, alpha: f64 },
}

/// The recursion of `map` (through one Jacobi scaling), None for other methods.
pub(super) fn recursion(map: &MethodMap) -> Option<Recursion> {
    let inner = match map {
        MethodMap::Scaled(s) => s.inner(),
        m => m,
    };
    match inner {
        MethodMap::Pg(_) => Some(Recursion::Pg),
        MethodMap::Fista(f) => Some(Recursion::Fista(f.momentum())),
        MethodMap::Admm(a) => Some(Recursion::Admm {
            h: a.problem().h().to_owned(),
            rho: a.rho(),
            alpha: a.relaxation(),
        }),
        _ => None,
    }
}

/// The linear recursion between clamps in z coordinates (docs/theory.md §4b, §4c).
#[derive(Debug, Clone)]
pub(super) enum Step {
    /// PG (β = 0) and FISTA: the clamp of iteration k + 1 reads
    /// pᵏ = S_z(eᵏ + β_k(eᵏ − eᵏ⁻¹)) and gives e^{k+1}; K clamps, d = eᴷ.
    Gradient { s_z: Mat<f64>, beta: f64 },
    /// ADMM (Douglas–Rachford on s): ε⁰ = E e⁰, δᵏ = clamp(εᵏ),
    /// ε^{k+1} = A εᵏ + B δᵏ; K + 1 clamps, d = δᴷ.
    Splitting {
        e: Mat<f64>,
        a: Mat<f64>,
        b: Mat<f64>,
    },
}

/// S_z = D S_y D⁻¹ from the probed lifted form, after checking that the form is the
/// recursion's: R = [D 0] with D diagonal positive; PG: ξ = y, start ξ⁰ = D⁻¹z⁰; FISTA:
/// ξ = (x, y), step x⁺ = S_y y, y⁺ = (1 + β)S_y y − βx, and a start of one plain step
/// x₀ = y₀ = S_y D⁻¹z⁰ + S_θθ (β₀ = β₁ = 0); ADMM: ξ = s, step A + B, start E D⁻¹ (from
/// H, ρ, α, [`splitting`]). None: another form (the chain would be wrong).
pub(super) fn step_of(lin: &IterationLinearisation, rec: &Recursion) -> Option<Step> {
    let n = lin.n;
    let (lift, k0) = match rec {
        Recursion::Pg | Recursion::Admm { .. } => (n, 0),
        Recursion::Fista(_) => (2 * n, 1),
    };
    if lin.lift_dim() != lift || lin.start_steps != k0 || lin.readout.nrows() != n {
        return None;
    }
    let r = &lin.readout;
    let d: Vec<f64> = (0..n).map(|i| r[(i, i)]).collect();
    let diagonal = (0..n).all(|i| d[i] > 0.0 && (0..lift).all(|j| j == i || r[(i, j)] == 0.0));
    if !diagonal {
        return None;
    }
    // S_y: the response of the iterate rows to ξ's last block (PG: y; FISTA: x⁺ = T(y)).
    let o = lift - n;
    let s_y = Mat::from_fn(n, n, |i, j| lin.step[(i, o + j)]);
    let scale = s_y
        .col_iter()
        .flat_map(|c| c.iter().copied())
        .fold(1.0_f64, |a, v| a.max(v.abs()));
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * scale;
    let nt = lin.n_theta;
    let to_z = |m: &Mat<f64>| Mat::from_fn(n, n, |i, j| d[i] * m[(i, j)] / d[j]);
    let ok = match rec {
        Recursion::Admm { h, rho, alpha } => {
            let (e, a, b) = splitting(h, *rho, *alpha)?;
            let ok = (0..n).all(|i| {
                (0..n).all(|j| {
                    close(lin.step[(i, j)], a[(i, j)] + b[(i, j)])
                        && close(lin.start[(i, j)], e[(i, j)] / d[j])
                })
            });
            return ok.then(|| Step::Splitting {
                e: to_z(&e),
                a: to_z(&a),
                b: to_z(&b),
            });
        }
        Recursion::Pg => (0..n).all(|i| {
            (0..n + nt).all(|j| close(lin.start[(i, j)], if j == i { 1.0 / d[i] } else { 0.0 }))
        }),
        Recursion::Fista(beta) => (0..lift).all(|row| {
            let i = row % n;
            let steps = (0..lift).all(|c| {
                let (j, same) = (c % n, c % n == i);
                let want = match (row < n, c < n) {
                    (true, true) => 0.0,
                    (true, false) => s_y[(i, j)],
                    (false, true) => f64::from(u8::from(same)) * -*beta,
                    (false, false) => (1.0 + *beta) * s_y[(i, j)],
                };
                close(lin.step[(row, c)], want)
            });
            // ξ₀ = (T(y⁰), T(y⁰)): one plain step from y⁰ = D⁻¹z⁰, θ as in the step.
            let start = (0..n).all(|j| close(lin.start[(row, j)], s_y[(i, j)] / d[j]))
                && (0..nt).all(|t| close(lin.start[(row, n + t)], lin.step[(i, lift + t)]));
            steps && start
        }),
    };
    let beta = match rec {
        Recursion::Fista(b) => *b,
        _ => 0.0,
    };
    ok.then(|| Step::Gradient {
        s_z: to_z(&s_y),
        beta,
    })
}

/// ADMM's (E, A, B) in its own coordinates: ε⁰ = (I − H/ρ)e⁰ (the warm start's gradient
/// dual), ε⁺ = (I − αρM)ε + α(2ρM − I)δ with M = (H + ρI)⁻¹. None: H + ρI not SPD.
fn splitting(h: &Mat<f64>, rho: f64, alpha: f64) -> Option<(Mat<f64>, Mat<f64>, Mat<f64>)> {
    let n = h.nrows();
    let eye = |i: usize, j: usize| f64::from(u8::from(i == j));
    let hr = Mat::from_fn(n, n, |i, j| h[(i, j)] + rho * eye(i, j));
    let m = hr
        .llt(faer::Side::Lower)
        .ok()?
        .solve(Mat::<f64>::identity(n, n));
    let e = Mat::from_fn(n, n, |i, j| eye(i, j) - h[(i, j)] / rho);
    let a = Mat::from_fn(n, n, |i, j| eye(i, j) - alpha * rho * m[(i, j)]);
    let b = Mat::from_fn(n, n, |i, j| alpha * (2.0 * rho * m[(i, j)] - eye(i, j)));
    Some((e, a, b))
}
