//! A seeded generator of random scenarios for the global certificate's soundness tests
//! (issue 35, "Soundness, tested"): unstable, marginal and stable plants of 2–12 states
//! (≥ 20 % with ≥ 10), free / partly constrained / boxed inputs, noise entering some states
//! only, M = 2–10 (shorter windows on the larger plants, so one φ* search stays cheap).

use faer::Mat;
use faer::linalg::solvers::Solve;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Where the plant's eigenvalues lie.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Class {
    /// Spectral radius in (1.02, 1.2].
    Unstable,
    /// One mode on the unit circle (an integrator's Jordan block, λ = ±1 or a rotation), the
    /// others inside.
    Marginal,
    /// Spectral radius in [0.3, 0.95].
    Stable,
}

/// The input set 𝒰.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Inputs {
    /// 𝒰 = ℝ^{n_u}.
    Free,
    /// Some components bounded, the others free (n_u ≥ 2).
    Partly,
    /// Every component bounded.
    Boxed,
}

/// One random scenario, as the TOML text a user would write.
#[derive(Debug, Clone)]
pub struct RandomPlant {
    /// The seed it was drawn from.
    pub seed: u64,
    /// n_x.
    pub nx: usize,
    /// The eigenvalue class.
    pub class: Class,
    /// The input set.
    pub inputs: Inputs,
    /// The MHE horizon M.
    pub horizon: usize,
    /// The scenario file.
    pub toml: String,
}

fn uniform(rng: &mut ChaCha8Rng, r: usize, c: usize, a: f64) -> Mat<f64> {
    Mat::from_fn(r, c, |_, _| a * rng.random_range(-1.0..1.0))
}

/// A real block-diagonal Λ with the class's spectrum: 1 × 1 blocks ±r and 2 × 2 rotations.
fn spectrum(rng: &mut ChaCha8Rng, n: usize, class: Class) -> Mat<f64> {
    let mut l = Mat::<f64>::zeros(n, n);
    let mut i = 0;
    // The first block carries the class's extreme mode.
    let mut first = true;
    while i < n {
        let r = match (class, first) {
            (Class::Unstable, true) => rng.random_range(1.02..1.2),
            (Class::Unstable, false) => rng.random_range(0.3..1.1),
            (Class::Marginal, true) => 1.0,
            _ => rng.random_range(0.3..0.95),
        };
        let kind = rng.random_range(0..3);
        if i + 1 < n && kind == 0 {
            // A rotation r·R(θ).
            let th = rng.random_range(0.1..3.0_f64);
            l[(i, i)] = r * th.cos();
            l[(i, i + 1)] = -r * th.sin();
            l[(i + 1, i)] = r * th.sin();
            l[(i + 1, i + 1)] = r * th.cos();
            i += 2;
        } else if i + 1 < n && kind == 1 && class == Class::Marginal && first {
            // An integrator chain: the Jordan block [[1, h], [0, 1]] (a double integrator).
            l[(i, i)] = 1.0;
            l[(i, i + 1)] = rng.random_range(0.05..0.5);
            l[(i + 1, i + 1)] = 1.0;
            i += 2;
        } else {
            l[(i, i)] = if rng.random_bool(0.25) { -r } else { r };
            i += 1;
        }
        first = false;
    }
    l
}

/// A = TΛT⁻¹ with T = I + a well-conditioned perturbation.
fn plant_matrix(rng: &mut ChaCha8Rng, n: usize, class: Class) -> Mat<f64> {
    let l = spectrum(rng, n, class);
    let mut t = uniform(rng, n, n, 0.5 / (n as f64).sqrt());
    for i in 0..n {
        t[(i, i)] += 1.0;
    }
    let tl = &t * &l;
    // A = TΛT⁻¹: Aᵀ solves Tᵀ Aᵀ = (TΛ)ᵀ.
    let lu = t.transpose().to_owned().partial_piv_lu();
    lu.solve(tl.transpose().to_owned()).transpose().to_owned()
}

fn rows(m: &Mat<f64>) -> String {
    let r: Vec<String> = (0..m.nrows())
        .map(|i| {
            let v: Vec<String> = (0..m.ncols()).map(|j| format!("{:?}", m[(i, j)])).collect();
            format!("[{}]", v.join(", "))
        })
        .collect();
    format!("[{}]", r.join(", "))
}

fn vector(v: &[f64]) -> String {
    let s: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", s.join(", "))
}

/// dim X of the lifted loop: x, the M-windows of u, y, x̂, and the warm start z (n_z =
/// n_x + M·n_w).
fn lifted_dim(nx: usize, nu: usize, ny: usize, nw: usize, m: usize) -> usize {
    nx + m * (nu + ny + nx) + nx + m * nw
}

/// The plant of seed `seed` (deterministic), dim X ≤ 64 (M shortened to fit).
pub fn random_plant(seed: u64) -> RandomPlant {
    random_plant_within(seed, 64)
}

/// As [`random_plant`] with dim X ≤ `max_dim`; below 64 the plants have 2–5 states (the
/// CI-sized run).
pub fn random_plant_within(seed: u64, max_dim: usize) -> RandomPlant {
    use rand::SeedableRng;
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0035 ^ seed.wrapping_mul(0x9e37_79b9));
    let nx = if max_dim < 64 {
        rng.random_range(2..=5)
    } else if rng.random_bool(0.25) {
        rng.random_range(10..=12)
    } else {
        rng.random_range(2..=9)
    };
    let class = match rng.random_range(0..3) {
        0 => Class::Unstable,
        1 => Class::Marginal,
        _ => Class::Stable,
    };
    let ny = rng.random_range(1..=3.min(nx));
    let inputs = match rng.random_range(0..3) {
        0 => Inputs::Free,
        1 => Inputs::Partly,
        _ => Inputs::Boxed,
    };
    let nu = match inputs {
        Inputs::Partly => rng.random_range(2..=3),
        _ => rng.random_range(1..=3.min(nx)),
    };
    let a = plant_matrix(&mut rng, nx, class);
    let b = uniform(&mut rng, nx, nu, 1.0);
    let c = uniform(&mut rng, ny, nx, 1.0);
    // Noise entering some states only (half the plants), else every state (E = I).
    let noisy: Vec<usize> = if rng.random_bool(0.5) {
        let k = rng.random_range(1..=nx.div_ceil(2));
        let mut s: Vec<usize> = (0..nx).collect();
        for i in 0..k {
            let j = rng.random_range(i..nx);
            s.swap(i, j);
        }
        let mut s = s[..k].to_vec();
        s.sort_unstable();
        s
    } else {
        (0..nx).collect()
    };
    let nw = noisy.len() + ny;
    let mut horizon = rng.random_range(2..=10);
    while horizon > 2 && lifted_dim(nx, nu, ny, nw, horizon) > max_dim {
        horizon -= 1;
    }
    let wbar = 10f64.powf(rng.random_range(-3.0..-1.0));
    let ubar: Vec<String> = (0..nu)
        .map(|i| {
            let bounded = match inputs {
                Inputs::Free => false,
                Inputs::Boxed => true,
                Inputs::Partly => i == 0 || rng.random_bool(0.4) && i + 1 < nu,
            };
            if bounded {
                format!("{:?}", rng.random_range(0.5..5.0_f64))
            } else {
                "inf".into()
            }
        })
        .collect();
    let mut toml = format!(
        "name = \"random-{seed}\"\n[plant]\na = {}\nb = {}\nc = {}\n",
        rows(&a),
        rows(&b),
        rows(&c)
    );
    if noisy.len() < nx {
        let e = Mat::from_fn(nx, noisy.len(), |i, j| f64::from(u8::from(noisy[j] == i)));
        toml += &format!("e = {}\n", rows(&e));
    }
    toml += &format!("[sets]\ndisturbance = {{ lower = -{wbar:?}, upper = {wbar:?} }}\n");
    if inputs != Inputs::Free {
        let lower: Vec<String> = ubar.iter().map(|u| format!("-{u}")).collect();
        toml += &format!(
            "input = {{ lower = [{}], upper = [{}] }}\n",
            lower.join(", "),
            ubar.join(", ")
        );
    }
    let x0: Vec<f64> = (0..nx).map(|_| rng.random_range(-1.0..1.0)).collect();
    toml += &format!(
        "[noise]\nkind = \"uniform\"\nscale = 1.0\nseed = {seed}\n[simulation]\nx0 = {}\n\
         prior = {}\nsteps = 40\n[mhe]\nhorizon = {horizon}\neta = 0.8\nq = 1.0\nr = 1.0\n\
         iterations = 10\nmethod = \"pg\"\nwarm_start = \"paper\"\n[mpc]\nhorizon = {}\n\
         q = 1.0\nr = 1.0\nterminal = \"dare\"\n",
        vector(&x0),
        vector(&vec![0.0; nx]),
        rng.random_range(3..=8)
    );
    RandomPlant {
        seed,
        nx,
        class,
        inputs,
        horizon,
        toml,
    }
}
