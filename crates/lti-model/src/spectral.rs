//! Stability of x⁺ = Ax decided from the exact structure of A, not from the moduli of
//! floating-point eigenvalues (issue 25, item 2).
//!
//! The eigenvalues of a defective A are ill-conditioned: a Jordan chain of length k at λ
//! is computed as k eigenvalues spread over a circle of radius ≈ (u·‖A‖)^{1/k} about λ
//! (u = 2⁻⁵³), so a double integrator or a quadrotor (eigenvalue exactly 1 in chains of
//! length 3) shows |λ| = 1 + 10⁻⁵ and looks unstable. [`classify`] avoids this in three
//! steps:
//!
//! 1. **Block structure.** The strongly connected components of the graph of the exact
//!    nonzero entries of A give a symmetric permutation to block upper-triangular form;
//!    the spectrum of A is the union of the spectra of the diagonal blocks. A 1 × 1 block
//!    is its eigenvalue exactly (triangular plants, chains of integrators, the quadrotor),
//!    a 2 × 2 block its eigenvalues in closed form.
//! 2. **Clusters.** In a larger block, eigenvalues within δ_k = (c·u·‖A_b‖)^{1/k} of one
//!    another, k the size of the cluster, are one perturbed eigenvalue of multiplicity k;
//!    the *mean* of a cluster is well conditioned (its error is O(u·‖A_b‖), not
//!    O(u^{1/k})), so it decides where the eigenvalue lies.
//! 3. **Decision.** An eigenvalue (or cluster mean) λ is on the unit circle when
//!    ||λ| − 1| ≤ k·c·u·max(1, ‖A_b‖); below that band it is stable.
//! 4. **Unstable only beyond the data's precision.** An eigenvalue with |λ| > 1 beyond the
//!    band of 3 is still counted on the circle when A_b is within a relative perturbation
//!    [`DATA_PRECISION`] = 1e-10 of a matrix with an eigenvalue on the circle
//!    (σ_min(A_b − zI) ≤ δ_A·‖A_b‖₂ for z on the circle near λ: |λ| − 1 is below the
//!    eigenvalue's perturbation bound κ(λ)·δ_A·‖A_b‖₂). The verdict then follows the
//!    spectrum, not the last digits of A (issue 37, item 5). For simple eigenvalues only:
//!    a cluster (a Jordan chain) is moved onto the circle by a tiny perturbation with its
//!    other members still outside, so its well-conditioned mean decides by step 3.
//!
//! The result says Stable (ρ(A) < 1), Marginal (ρ(A) = 1: the largest eigenvalues lie on
//! the unit circle; [`SpectralFacts::longest_chain`] says whether they are semisimple) or
//! Unstable (an eigenvalue with |λ| > 1).

use faer::{Mat, MatRef};
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::error::{ModelError, Result};

/// c of the tolerances above: a multiple of the backward error n·u of the eigensolver.
const TOL_FACTOR: f64 = 64.0;

/// δ_A of step 4: A is taken to be known to a relative (2-norm) perturbation of 1e-10.
/// Why this size: it is ≥ 10⁵ times the eigensolver's backward error n·u (so rounding alone
/// never decides), above the accuracy of a plant produced by a ZOH discretisation (expm,
/// ≈ 1e-13 relative) or printed with 12 to 17 digits, and a mode with |λ| − 1 of that order
/// needs ≳ 1e10 steps to grow by a factor e — an instability no simulation or horizon of this
/// project can tell from a marginal mode. Issue 37, item 5: an undamped mass chain whose A
/// differs from the shipped one by 5e-13 must get the same verdict.
pub const DATA_PRECISION: f64 = 1e-10;

/// Step 4: is the block `a` within DATA_PRECISION·‖a‖₂ (a complex perturbation) of a
/// matrix with an eigenvalue on the unit circle near λ = re + i·im? The distance from `a` to
/// the matrices with eigenvalue z is σ_min(a − zI) exactly; it is evaluated at the radial
/// projection z = λ/|λ| and at nearby angles (±κ·δ scales, where the minimum over the circle
/// lies for an eigenvalue close to it). To first order σ_min(a − zI) ≈ |λ − z|/κ(λ), κ the
/// eigenvalue's condition number, so the test reads "|λ| − 1 ≤ κ(λ)·δ_A·‖a‖₂": the
/// eigenvalue's perturbation bound, Jordan chains included (their κ is unbounded, and the
/// backward-error form needs no eigenvectors).
fn within_data_precision_of_circle(a: &Mat<f64>, re: f64, im: f64) -> bool {
    let n = a.nrows();
    let Ok(norm_sv) = a.singular_values() else {
        return false;
    };
    let norm = norm_sv.iter().copied().fold(0.0, f64::max);
    let bound = DATA_PRECISION * norm.max(f64::MIN_POSITIVE);
    let theta = im.atan2(re);
    let gap = re.hypot(im) - 1.0;
    // angles: the radial projection, and offsets of the order of the distance to the circle
    let offsets = [0.0, gap, -gap, 4.0 * gap, -4.0 * gap];
    offsets.iter().any(|&dt| {
        let (zr, zi) = ((theta + dt).cos(), (theta + dt).sin());
        // σ_min of the complex a − zI as the real 2n × 2n [[a − zr·I, zi·I], [−zi·I, a − zr·I]]
        // (its singular values are those of a − zI, each twice).
        let m = Mat::from_fn(2 * n, 2 * n, |i, j| {
            let (bi, bj) = (i / n, j / n);
            let (ii, jj) = (i % n, j % n);
            let diag = if ii == jj { 1.0 } else { 0.0 };
            match (bi, bj) {
                (0, 0) | (1, 1) => a[(ii, jj)] - zr * diag,
                (0, 1) => zi * diag,
                _ => -zi * diag,
            }
        });
        m.singular_values()
            .is_ok_and(|sv| sv.iter().copied().fold(f64::INFINITY, f64::min) <= bound)
    })
}

/// How x⁺ = Ax behaves.
///
/// Exhaustive on purpose: max |λ| is below, at or above 1, and nothing else.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Stability {
    /// Every eigenvalue has |λ| < 1.
    Stable,
    /// No eigenvalue has |λ| > 1 and some has |λ| = 1.
    Marginal,
    /// Some eigenvalue has |λ| > 1 by more than its perturbation bound for a relative
    /// change [`DATA_PRECISION`] of A.
    Unstable,
}

/// What [`classify`] found.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct SpectralFacts {
    /// Stable, marginal or unstable.
    pub stability: Stability,
    /// ρ(A): exactly 1 when marginal; otherwise the largest |λ| (of cluster means).
    pub spectral_radius: f64,
    /// Eigenvalues on the unit circle, with algebraic multiplicity.
    pub unit_circle_multiplicity: usize,
    /// Longest Jordan chain at a real eigenvalue ±1 on the unit circle (1: semisimple; 0:
    /// none on the circle, or only complex ones).
    pub longest_chain: usize,
    /// Sizes of the diagonal blocks of the block-triangular form (ascending).
    pub block_sizes: Vec<usize>,
}

/// Stability of A decided from its structure (module doc).
///
/// ```
/// use faer::mat;
/// use lti_model::spectral::{Stability, classify};
/// // the double integrator: a Jordan block at 1 → marginal, chain 2
/// let f = classify(mat![[1.0, 0.1], [0.0, 1.0]].as_ref()).unwrap();
/// assert_eq!((f.stability, f.spectral_radius, f.longest_chain), (Stability::Marginal, 1.0, 2));
/// ```
pub fn classify(a: MatRef<'_, f64>) -> Result<SpectralFacts> {
    let n = a.nrows();
    crate::matrix::check_shape("A", a, n, n)?;
    crate::matrix::check_finite("A", a)?;
    let blocks = strongly_connected_blocks(a);
    let mut block_sizes: Vec<usize> = blocks.iter().map(Vec::len).collect();
    block_sizes.sort_unstable();
    // (modulus of the eigenvalue or cluster mean, multiplicity, tolerance, real ±1 value)
    let mut radius = 0.0_f64;
    let mut on_circle = 0usize;
    let mut unstable = false;
    let mut real_unit: Vec<f64> = Vec::new();
    for idx in &blocks {
        let k = idx.len();
        let sub = Mat::from_fn(k, k, |i, j| a[(idx[i], idx[j])]);
        let norm = sub.norm_max() * k as f64;
        let eig = block_eigenvalues(&sub)?;
        for (re, im, mult) in clusters(&eig, norm) {
            let modulus = re.hypot(im);
            let tol = mult as f64 * TOL_FACTOR * f64::EPSILON * norm.max(1.0);
            if (modulus - 1.0).abs() <= tol {
                on_circle += mult;
                if im.abs() <= tol {
                    let v = if re > 0.0 { 1.0 } else { -1.0 };
                    if !real_unit.contains(&v) {
                        real_unit.push(v);
                    }
                }
            } else if modulus > 1.0 && mult == 1 && within_data_precision_of_circle(&sub, re, im) {
                // |λ| − 1 is below the perturbation bound of λ for a relative change of A
                // of DATA_PRECISION (step 4): on the circle as far as the data can tell.
                on_circle += mult;
                if im.abs() <= DATA_PRECISION.sqrt() * modulus {
                    let v = if re > 0.0 { 1.0 } else { -1.0 };
                    if !real_unit.contains(&v) {
                        real_unit.push(v);
                    }
                }
            } else if modulus > 1.0 {
                unstable = true;
                radius = radius.max(modulus);
            } else if !unstable {
                radius = radius.max(modulus);
            }
        }
    }
    let stability = if unstable {
        Stability::Unstable
    } else if on_circle > 0 {
        radius = 1.0;
        Stability::Marginal
    } else {
        Stability::Stable
    };
    let longest_chain = real_unit
        .iter()
        .map(|&v| longest_chain(a, v))
        .max()
        .unwrap_or(0);
    Ok(SpectralFacts {
        stability,
        spectral_radius: radius,
        unit_circle_multiplicity: on_circle,
        longest_chain,
        block_sizes,
    })
}

/// Eigenvalues (re, im) of a diagonal block: exact for 1 × 1, closed form for 2 × 2.
fn block_eigenvalues(m: &Mat<f64>) -> Result<Vec<(f64, f64)>> {
    match m.nrows() {
        1 => Ok(vec![(m[(0, 0)], 0.0)]),
        2 => {
            let (p, q, r, s) = (m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)]);
            let half_tr = 0.5 * (p + s);
            let half_diff = 0.5 * (p - s);
            let disc = half_diff * half_diff + q * r;
            if disc >= 0.0 {
                let root = disc.sqrt();
                Ok(vec![(half_tr + root, 0.0), (half_tr - root, 0.0)])
            } else {
                let root = (-disc).sqrt();
                Ok(vec![(half_tr, root), (half_tr, -root)])
            }
        }
        _ => {
            let ev = m.eigenvalues().map_err(|e| ModelError::Numerical {
                routine: "eigenvalues".into(),
                reason: format!("{e:?}"),
            })?;
            Ok(ev.iter().map(|z| (z.re, z.im)).collect())
        }
    }
}

/// Groups eigenvalues into clusters (module doc, step 2): returns (mean re, mean im, size).
///
/// For each eigenvalue not yet grouped, with d₁ = 0 ≤ d₂ ≤ … the distances of the
/// ungrouped eigenvalues to it, a cluster of size k ≥ 2 is admissible when d_k ≤ δ_k =
/// 2(c·u·‖A_b‖)^{1/k} (a chain of length ≤ k perturbed by rounding); among admissible k
/// the one with the clearest gap d_{k+1}/d_k (d_{m+1} = max(1, ‖A_b‖)) is taken if that gap
/// exceeds 10, else the eigenvalue stands alone.
fn clusters(eig: &[(f64, f64)], norm: f64) -> Vec<(f64, f64, usize)> {
    let base = TOL_FACTOR * f64::EPSILON * norm.max(f64::MIN_POSITIVE);
    let dist = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1);
    let mut used = vec![false; eig.len()];
    let mut out = Vec::new();
    for i in 0..eig.len() {
        if used[i] {
            continue;
        }
        let mut near: Vec<(f64, usize)> = (0..eig.len())
            .filter(|&j| !used[j])
            .map(|j| (dist(eig[j], eig[i]), j))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        let m = near.len();
        let mut best = (1usize, 10.0_f64);
        for k in 2..=m {
            let dk = near[k - 1].0;
            if dk > 2.0 * base.powf(1.0 / k as f64) {
                continue;
            }
            let next = if k < m { near[k].0 } else { norm.max(1.0) };
            let gap = next / dk.max(base);
            if gap > best.1 {
                best = (k, gap);
            }
        }
        let members: Vec<usize> = near[..best.0].iter().map(|&(_, j)| j).collect();
        for &j in &members {
            used[j] = true;
        }
        let (re, im) = mean(eig, &members);
        out.push((re, im, members.len()));
    }
    out
}

fn mean(eig: &[(f64, f64)], members: &[usize]) -> (f64, f64) {
    let k = members.len() as f64;
    let re = members.iter().map(|&j| eig[j].0).sum::<f64>() / k;
    let im = members.iter().map(|&j| eig[j].1).sum::<f64>() / k;
    (re, im)
}

/// Longest Jordan chain at the real eigenvalue v: the smallest j with
/// rank((A − vI)^j) = rank((A − vI)^{j+1}) (numerical rank by SVD, relative tolerance
/// n·c·u).
fn longest_chain(a: MatRef<'_, f64>, v: f64) -> usize {
    let n = a.nrows();
    let shifted = Mat::from_fn(n, n, |i, j| a[(i, j)] - if i == j { v } else { 0.0 });
    let mut power = shifted.clone();
    let mut prev_rank = n;
    for j in 1..=n {
        let r = numerical_rank(power.as_ref());
        if r == prev_rank {
            return j - 1;
        }
        prev_rank = r;
        power = &power * &shifted;
    }
    n
}

fn numerical_rank(m: MatRef<'_, f64>) -> usize {
    let n = m.nrows();
    let Ok(s) = m.to_owned().singular_values() else {
        return n;
    };
    let smax = s.iter().copied().fold(0.0, f64::max);
    let tol = TOL_FACTOR * f64::EPSILON * n as f64 * smax.max(1.0);
    s.iter().filter(|&&x| x > tol).count()
}

/// Index sets of the strongly connected components of the graph i → j for A[i][j] ≠ 0
/// (Tarjan, iterative). Every eigenvalue of A is an eigenvalue of one diagonal block
/// A[c, c], c a component.
fn strongly_connected_blocks(a: MatRef<'_, f64>) -> Vec<Vec<usize>> {
    let n = a.nrows();
    let adj: Vec<Vec<usize>> = (0..n)
        .map(|i| (0..n).filter(|&j| j != i && a[(i, j)] != 0.0).collect())
        .collect();
    let mut index = vec![usize::MAX; n];
    let mut low = vec![0usize; n];
    let mut on_stack = vec![false; n];
    let mut stack = Vec::new();
    let mut out = Vec::new();
    let mut next = 0usize;
    for root in 0..n {
        if index[root] != usize::MAX {
            continue;
        }
        // (node, position in its adjacency list)
        let mut call = vec![(root, 0usize)];
        index[root] = next;
        low[root] = next;
        next += 1;
        stack.push(root);
        on_stack[root] = true;
        while let Some(&mut (v, ref mut pos)) = call.last_mut() {
            if *pos < adj[v].len() {
                let w = adj[v][*pos];
                *pos += 1;
                if index[w] == usize::MAX {
                    index[w] = next;
                    low[w] = next;
                    next += 1;
                    stack.push(w);
                    on_stack[w] = true;
                    call.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
            } else {
                call.pop();
                if let Some(&(parent, _)) = call.last() {
                    low[parent] = low[parent].min(low[v]);
                }
                if low[v] == index[v] {
                    let mut comp = Vec::new();
                    while let Some(w) = stack.pop() {
                        on_stack[w] = false;
                        comp.push(w);
                        if w == v {
                            break;
                        }
                    }
                    comp.sort_unstable();
                    out.push(comp);
                }
            }
        }
    }
    out
}
