//! Lemma CS of `docs/theory.md` ("A comparison system of Theorem 1's one-step inequalities"):
//! a nonnegative comparison system with memory, v_t ≤ Σ_{k=1}^{L} G_k v_{t−k} + d_t, is
//! stable iff ρ(G) < 1 for G = Σ_k G_k, whatever the lags; with D = diag G and N = G − D,
//! ρ(G) < 1 iff every D_ii < 1 and ρ((I − D)⁻¹N) < 1 — the sum-form small gain on the
//! steady-state gains that Theorem 1 checks. So keeping the M-step memory explicit certifies
//! the same K as Theorem 1; checked here on 2 000 random systems on both sides of ρ(G) = 1.

use iss_certificate::small_gain::GainMatrix;

/// xorshift64*: deterministic, no dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn perron(n: usize, g: &[f64]) -> f64 {
    let mut m = GainMatrix::new(n);
    for i in 0..n {
        for j in 0..n {
            m.set(i, j, g[i * n + j]);
        }
    }
    m.spectral_radius()
}

/// One random system: n nodes, lags 1..=L, some entries zero, scaled so that ρ(ΣG_k) = target.
fn system(rng: &mut Rng, n: usize, lags: usize, target: f64) -> Vec<Vec<f64>> {
    let mut gs: Vec<Vec<f64>> = (0..lags)
        .map(|_| {
            (0..n * n)
                .map(|_| {
                    let v = rng.next();
                    if v < 0.4 { 0.0 } else { v }
                })
                .collect()
        })
        .collect();
    // Every node on a cycle through the next (irreducible), so the Perron root is simple.
    for i in 0..n {
        gs[0][i * n + (i + 1) % n] += 0.1;
    }
    let sum: Vec<f64> = (0..n * n).map(|e| gs.iter().map(|g| g[e]).sum()).collect();
    let s = target / perron(n, &sum);
    for g in &mut gs {
        for v in g.iter_mut() {
            *v *= s;
        }
    }
    gs
}

#[test]
fn a_comparison_system_with_memory_is_stable_iff_the_sum_of_its_matrices_contracts() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let targets = [0.3, 0.7, 0.9, 0.97, 1.03, 1.1, 1.5];
    let mut counted = [0usize; 2];
    for case in 0..2000 {
        let n = 2 + case % 4;
        let lags = 1 + (case / 4) % 10;
        let target = targets[case % targets.len()];
        let gs = system(&mut rng, n, lags, target);
        let sum: Vec<f64> = (0..n * n).map(|e| gs.iter().map(|g| g[e]).sum()).collect();
        let rho = perron(n, &sum);
        assert!(
            (rho - target).abs() <= 1e-9 * target,
            "{rho} against {target}"
        );

        // The splitting: ρ(G) < 1 ⇔ D_ii < 1 ∀i and ρ((I − D)⁻¹N) < 1 (Theorem 1's Γ).
        let d: Vec<f64> = (0..n).map(|i| sum[i * n + i]).collect();
        let split = d.iter().all(|&v| v < 1.0) && {
            let gamma: Vec<f64> = (0..n * n)
                .map(|e| {
                    let (i, j) = (e / n, e % n);
                    if i == j { 0.0 } else { sum[e] / (1.0 - d[i]) }
                })
                .collect();
            perron(n, &gamma) < 1.0
        };
        assert_eq!(split, rho < 1.0, "case {case}: ρ(G) = {rho}, d = {d:?}");

        // The system itself, with equality and a bounded input d_t ∈ [0, 1]: from a unit
        // memory, sup v ≤ (I − G)⁻¹(v₀ + 1) when ρ(G) < 1 (Lemma CS (i)), and v grows
        // without the input when ρ(G) > 1 (the Perron direction does not decay).
        let steps = 4000;
        let mut hist: Vec<Vec<f64>> = vec![vec![1.0; n]; lags];
        let with_input = rho < 1.0;
        let mut sup = vec![1.0f64; n];
        for _ in 0..steps {
            let mut v = vec![0.0; n];
            for (k, g) in gs.iter().enumerate() {
                let past = &hist[hist.len() - 1 - k];
                for i in 0..n {
                    v[i] += (0..n).map(|j| g[i * n + j] * past[j]).sum::<f64>();
                }
            }
            if with_input {
                for vi in &mut v {
                    *vi += rng.next();
                }
            }
            for i in 0..n {
                sup[i] = sup[i].max(v[i]);
            }
            hist.remove(0);
            let grown = !with_input && v.iter().sum::<f64>() > 1e6;
            hist.push(v);
            if grown {
                break;
            }
        }
        if rho < 1.0 {
            // (I − G)x = 2·1 solved by the Neumann series (ρ(G) < 1).
            let mut x = vec![0.0; n];
            let mut term = vec![2.0; n];
            for _ in 0..100_000 {
                for i in 0..n {
                    x[i] += term[i];
                }
                let next: Vec<f64> = (0..n)
                    .map(|i| (0..n).map(|j| sum[i * n + j] * term[j]).sum())
                    .collect();
                term = next;
                if term.iter().all(|&t| t < 1e-12) {
                    break;
                }
            }
            for i in 0..n {
                assert!(
                    sup[i] <= x[i] * (1.0 + 1e-9),
                    "case {case}: {sup:?} > {x:?}"
                );
            }
            counted[0] += 1;
        } else {
            let last = hist.last().unwrap();
            assert!(
                last.iter().sum::<f64>() > n as f64,
                "case {case}: ρ(G) = {rho} but v decayed to {last:?}"
            );
            counted[1] += 1;
        }
    }
    assert!(counted[0] > 800 && counted[1] > 500, "{counted:?}");
}
