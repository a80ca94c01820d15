//! Small-gain conditions for interconnections whose ISS estimates are sums of linear gains.
//!
//! Every subsystem estimate of the paper has the *sum* form
//! ‖x_i‖ ≤ β_i + Σ_j γ_{i,j}‖x_j‖ + (external terms), with sup-norms over [0, t] and linear
//! gains. Write Γ = (γ_{i,j}) ≥ 0 (row i: the gains *into* node i). Taking sups over [0, T]
//! gives s ≤ Γs + b for the vector s of sup-norms, and the interconnection is ISS when
//! **ρ(Γ) < 1**, i.e. when I − Γ is a nonsingular M-matrix (all leading principal minors
//! positive): then s ≤ (I − Γ)⁻¹b uniformly in T (Dashkovskiy, Rüffer & Wirth, Math. Control
//! Signals Syst. 19, 2007: Γ ∘ D ≱ id, which for linear gains is ρ(Γ) < 1).
//!
//! The *cycle* condition (the product of the gains around every simple cycle below 1) is the
//! small-gain theorem for estimates of the *max* form ‖x_i‖ ≤ max(β_i, γ_{i,j}‖x_j‖, …). It
//! is necessary for ρ(Γ) < 1 but not sufficient once two cycles share a node: with cycles
//! 1–3 and 2–3 of gain 0.6 each, ρ(Γ)² = 1.2 (see the test
//! `cycle_conditions_alone_are_not_sufficient`). The paper's Theorem 1 states the cycle
//! conditions (sg1)–(sg3) for sum-form estimates; we report them and certify with ρ(Γ) < 1.

#[cfg(feature = "serde")]
use serde::Serialize;

/// Largest interconnection handled (the cycle enumeration is exponential in it).
pub const MAX_NODES: usize = 8;

/// A nonnegative gain matrix Γ: `get(i, j)` = γ_{i,j}, the gain from node j into node i.
///
/// ```
/// use iss_certificate::small_gain::GainMatrix;
/// let mut g = GainMatrix::new(2);
/// g.set(0, 1, 0.5);
/// g.set(1, 0, 1.5);
/// let c = g.cycles();
/// assert_eq!(c.len(), 1);
/// assert!((c[0].gain - 0.75).abs() < 1e-15);
/// assert!(g.is_contracting());
/// assert!((g.spectral_radius() - 0.75f64.sqrt()).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct GainMatrix {
    n: usize,
    g: Vec<f64>,
}

/// One simple cycle of the gain graph and the product of its gains.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Cycle {
    /// Nodes i₀, i₁, …, i_{L−1}: i₀ takes input from i₁, i₁ from i₂, …, i_{L−1} from i₀
    /// (the smallest node first).
    pub nodes: Vec<usize>,
    /// γ_{i₀,i₁}·γ_{i₁,i₂}·…·γ_{i_{L−1},i₀}.
    pub gain: f64,
}

impl GainMatrix {
    /// The zero matrix on `n` nodes (`n` is capped at [`MAX_NODES`]).
    pub fn new(n: usize) -> Self {
        let n = n.min(MAX_NODES);
        Self {
            n,
            g: vec![0.0; n * n],
        }
    }

    /// Number of nodes.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Sets γ_{i,j} (gain from node j into node i). Out-of-range indices are ignored.
    pub fn set(&mut self, i: usize, j: usize, gain: f64) {
        if i < self.n && j < self.n {
            self.g[i * self.n + j] = gain;
        }
    }

    /// γ_{i,j} (0 out of range).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        if i < self.n && j < self.n {
            self.g[i * self.n + j]
        } else {
            0.0
        }
    }

    /// Every simple cycle with nonzero gains, each listed once (smallest node first), in a
    /// deterministic order.
    pub fn cycles(&self) -> Vec<Cycle> {
        let mut out = Vec::new();
        let mut path = Vec::with_capacity(self.n);
        for start in 0..self.n {
            path.clear();
            path.push(start);
            self.extend(start, &mut path, &mut out);
        }
        out
    }

    fn extend(&self, start: usize, path: &mut Vec<usize>, out: &mut Vec<Cycle>) {
        let Some(&last) = path.last() else {
            return;
        };
        for next in start..self.n {
            if self.get(last, next) == 0.0 {
                continue;
            }
            if next == start {
                let gain = path
                    .iter()
                    .zip(path.iter().skip(1).chain(std::iter::once(&start)))
                    .map(|(&i, &j)| self.get(i, j))
                    .product();
                out.push(Cycle {
                    nodes: path.clone(),
                    gain,
                });
            } else if !path.contains(&next) {
                path.push(next);
                self.extend(start, path, out);
                path.pop();
            }
        }
    }

    /// Whether λI − Γ is a nonsingular M-matrix, i.e. ρ(Γ) < λ: Gaussian elimination without
    /// pivoting on the Z-matrix λI − Γ, whose k-th pivot is the ratio of its k-th and
    /// (k−1)-th leading principal minors, so every pivot is positive exactly when every
    /// leading minor is. Non-finite or negative gains: false.
    fn below(&self, lambda: f64) -> bool {
        let n = self.n;
        if self.g.iter().any(|v| !v.is_finite() || *v < 0.0) || !lambda.is_finite() {
            return false;
        }
        let mut m: Vec<f64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                f64::from(u8::from(i == j)) * lambda - self.g[k]
            })
            .collect();
        for p in 0..n {
            let piv = m[p * n + p];
            if !(piv > 0.0) {
                return false;
            }
            for i in p + 1..n {
                let f = m[i * n + p] / piv;
                if f != 0.0 {
                    for j in p..n {
                        m[i * n + j] -= f * m[p * n + j];
                    }
                }
            }
        }
        true
    }

    /// The small-gain condition for sum-form estimates: ρ(Γ) < 1 (module docs).
    pub fn is_contracting(&self) -> bool {
        self.below(1.0)
    }

    /// det(I − Γ) by Gaussian elimination with partial pivoting (for display and tests:
    /// on the paper's three-node graph it is 1 − sg1 − sg2 − sg3).
    pub fn det_i_minus(&self) -> f64 {
        let n = self.n;
        let mut m: Vec<f64> = (0..n * n)
            .map(|k| f64::from(u8::from(k / n == k % n)) - self.g[k])
            .collect();
        let mut det = 1.0;
        for p in 0..n {
            let Some(r) = (p..n).max_by(|&a, &b| m[a * n + p].abs().total_cmp(&m[b * n + p].abs()))
            else {
                return f64::NAN;
            };
            if r != p {
                for j in 0..n {
                    m.swap(p * n + j, r * n + j);
                }
                det = -det;
            }
            let piv = m[p * n + p];
            if piv == 0.0 {
                return 0.0;
            }
            det *= piv;
            for i in p + 1..n {
                let f = m[i * n + p] / piv;
                for j in p..n {
                    m[i * n + j] -= f * m[p * n + j];
                }
            }
        }
        det
    }

    /// The Perron root ρ(Γ), by bisection on λ with the M-matrix test (relative accuracy
    /// 1e-14; NaN if a gain is negative or NaN, ∞ if one is infinite).
    pub fn spectral_radius(&self) -> f64 {
        if self.g.iter().any(|v| v.is_nan() || *v < 0.0) {
            return f64::NAN;
        }
        if self.g.iter().any(|v| v.is_infinite()) {
            return f64::INFINITY;
        }
        // ρ(Γ) ≤ max row sum.
        let hi0 = (0..self.n)
            .map(|i| (0..self.n).map(|j| self.get(i, j)).sum::<f64>())
            .fold(0.0, f64::max);
        if hi0 == 0.0 {
            return 0.0;
        }
        let (mut lo, mut hi) = (0.0, hi0 * (1.0 + 1e-12) + f64::MIN_POSITIVE);
        // Bounded: a nilpotent Γ (ρ = 0) would otherwise halve hi down to the subnormals.
        for _ in 0..200 {
            if hi - lo <= 1e-14 * hi || hi < 1e-40 * hi0 {
                break;
            }
            let mid = 0.5 * (lo + hi);
            if self.below(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        if hi < 1e-40 * hi0 { 0.0 } else { hi }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's three-node graph (x = 0, ε = 1, e = 2): γ₁,₃, γ₂,₁, γ₂,₃, γ₃,₁, γ₃,₂.
    fn theorem1_graph(g13: f64, g21: f64, g23: f64, g31: f64, g32: f64) -> GainMatrix {
        let mut g = GainMatrix::new(3);
        g.set(0, 2, g13);
        g.set(1, 0, g21);
        g.set(1, 2, g23);
        g.set(2, 0, g31);
        g.set(2, 1, g32);
        g
    }

    #[test]
    fn three_node_cycles_and_determinant() {
        let g = theorem1_graph(2.0, 0.1, 0.3, 0.2, 0.5);
        let c = g.cycles();
        let gains: Vec<(Vec<usize>, f64)> = c.iter().map(|c| (c.nodes.clone(), c.gain)).collect();
        // sg1 = γ₁,₃γ₃,₁ = 0.4; sg3 = γ₁,₃γ₃,₂γ₂,₁ = 0.1; sg2 = γ₂,₃γ₃,₂ = 0.15.
        let want = [(vec![0, 2], 0.4), (vec![0, 2, 1], 0.1), (vec![1, 2], 0.15)];
        assert_eq!(gains.len(), 3, "{gains:?}");
        for (nodes, v) in want {
            assert!(
                gains
                    .iter()
                    .any(|(n, x)| *n == nodes && (x - v).abs() < 1e-15),
                "{nodes:?} missing in {gains:?}"
            );
        }
        // Every cycle passes through node 2, so det(I − Γ) = 1 − Σ cycle gains.
        assert!((g.det_i_minus() - (1.0 - 0.65)).abs() < 1e-14);
        assert!(g.is_contracting());
    }

    #[test]
    fn cycle_conditions_alone_are_not_sufficient() {
        // Two cycles through node 2 with gain 0.6 each: each below 1, ρ(Γ)² = 1.2.
        let s = 0.6f64.sqrt();
        let g = theorem1_graph(s, 0.0, s, s, s);
        assert!(g.cycles().iter().all(|c| c.gain < 1.0));
        assert!(!g.is_contracting());
        assert!((g.spectral_radius() - 1.2f64.sqrt()).abs() < 1e-12);
        // The positive linear system s(t+1) = Γ s(t) meets the sum-form estimates with these
        // gains and diverges.
        let mut x = [1.0, 1.0, 1.0];
        for _ in 0..200 {
            let y: Vec<f64> = (0..3)
                .map(|i| (0..3).map(|j| g.get(i, j) * x[j]).sum())
                .collect();
            x.copy_from_slice(&y);
        }
        assert!(x.iter().all(|v| *v > 1e7), "{x:?}");
    }

    #[test]
    fn spectral_radius_matches_power_iteration_on_random_matrices() {
        use rand::{Rng, SeedableRng};
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..500 {
            let n = r.random_range(1..=5);
            let mut g = GainMatrix::new(n);
            for i in 0..n {
                for j in 0..n {
                    if i != j && r.random_bool(0.6) {
                        g.set(i, j, r.random_range(0.0..1.5));
                    }
                }
            }
            // Power iteration on Γ + I (primitive when irreducible; the shift keeps the
            // Perron root dominant): ρ(Γ) = ρ(Γ + I) − 1.
            let mut v = vec![1.0; n];
            let mut lam = 0.0;
            for _ in 0..5_000 {
                let w: Vec<f64> = (0..n)
                    .map(|i| v[i] + (0..n).map(|j| g.get(i, j) * v[j]).sum::<f64>())
                    .collect();
                let s = w.iter().cloned().fold(0.0, f64::max);
                lam = s;
                v = w.iter().map(|x| x / s).collect();
            }
            let rho = g.spectral_radius();
            if g.cycles().is_empty() {
                // An acyclic graph: Γ is nilpotent, ρ = 0 (power iteration converges only
                // like 1/k on its Jordan blocks).
                assert!(rho < 1e-30, "{rho} for {g:?}");
                assert!(g.is_contracting());
                continue;
            }
            assert!(
                (rho - (lam - 1.0)).abs() <= 1e-6 * (1.0 + rho),
                "{rho} vs {} for {g:?}",
                lam - 1.0
            );
            assert_eq!(g.is_contracting(), rho < 1.0 || (rho - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_gains_are_not_contracting() {
        let mut g = GainMatrix::new(2);
        g.set(0, 1, f64::NAN);
        assert!(!g.is_contracting() && g.spectral_radius().is_nan());
        g.set(0, 1, f64::INFINITY);
        g.set(1, 0, 1.0);
        assert!(!g.is_contracting() && g.spectral_radius().is_infinite());
        assert!(GainMatrix::new(3).is_contracting());
        assert_eq!(GainMatrix::new(3).spectral_radius(), 0.0);
    }
}
