//! `disturbance`: reproducibility of seeded streams, sample statistics against the
//! distributions' moments, and validation.

use faer::{Mat, mat};
use lti_model::disturbance::{Disturbance, Gaussian, UniformBox, Zero};
use lti_model::{BoxSet, ConvexSet, ModelError};

const N: usize = 20_000;

#[test]
fn same_seed_same_sequence_different_seed_different_sequence() {
    let make_u = |seed| UniformBox::new(vec![-0.1, 0.0, 2.0], vec![0.1, 1.0, 5.0], seed).unwrap();
    let make_g = |seed| Gaussian::new(vec![0.0, 1.0], mat![[1.0, 0.3], [0.3, 0.5]], seed).unwrap();

    let (a, b, c) = (
        make_u(7).sequence(50),
        make_u(7).sequence(50),
        make_u(8).sequence(50),
    );
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert!(
        a.iter().zip(&c).all(|(x, y)| x != y),
        "seeds 7 and 8 share a draw"
    );
    let (a, b, c) = (
        make_g(7).sequence(50),
        make_g(7).sequence(50),
        make_g(8).sequence(50),
    );
    assert_eq!(a, b);
    assert_ne!(a, c);

    // reseed restarts the stream as if freshly constructed.
    let mut u = make_u(1);
    let _ = u.sequence(13);
    u.reseed(7);
    assert_eq!(u.sequence(50), make_u(7).sequence(50));
    let mut g = make_g(1);
    let _ = g.sequence(13);
    g.reseed(7);
    assert_eq!(g.sequence(50), make_g(7).sequence(50));

    // The stream does not depend on the thread that draws it.
    let here = make_g(99).sequence(20);
    let there = std::thread::spawn(move || make_g(99).sequence(20))
        .join()
        .unwrap();
    assert_eq!(here, there);

    // sample() and sequence() draw the same stream; Box<dyn Disturbance> forwards.
    let mut boxed: Box<dyn Disturbance> = Box::new(make_u(5));
    let mut out = [0.0; 3];
    boxed.sample(&mut out);
    assert_eq!(boxed.dim(), 3);
    assert_eq!(out.to_vec(), make_u(5).sequence(1)[0]);
}

fn mean_and_cov(samples: &[Vec<f64>]) -> (Vec<f64>, Mat<f64>) {
    let n = samples[0].len();
    let k = samples.len() as f64;
    let mean: Vec<f64> = (0..n)
        .map(|i| samples.iter().map(|s| s[i]).sum::<f64>() / k)
        .collect();
    let cov = Mat::from_fn(n, n, |i, j| {
        samples
            .iter()
            .map(|s| (s[i] - mean[i]) * (s[j] - mean[j]))
            .sum::<f64>()
            / (k - 1.0)
    });
    (mean, cov)
}

#[test]
fn uniform_box_samples_lie_in_the_box_with_the_right_moments() {
    let lower = vec![-0.1, 0.0, 2.0, -1e3, 4.0];
    let upper = vec![0.1, 1.0, 5.0, 1e3, 4.0];
    let mut w = UniformBox::new(lower.clone(), upper.clone(), 2024).unwrap();
    assert_eq!(w.dim(), 5);
    let set = BoxSet::new(lower.clone(), upper.clone()).unwrap();
    assert_eq!(w.set(), &set);
    let samples = w.sequence(N);
    assert!(samples.iter().all(|s| set.contains(s, 0.0)));
    let (mean, cov) = mean_and_cov(&samples);
    for i in 0..5 {
        let width = upper[i] - lower[i];
        let var = width * width / 12.0;
        // Standard error of the mean σ/√N; of the variance √((μ₄ − σ⁴)/N) with μ₄ = w⁴/80.
        let se_mean = (var / N as f64).sqrt();
        let se_var = ((width.powi(4) / 80.0 - var * var) / N as f64).sqrt();
        let mid = 0.5 * (lower[i] + upper[i]);
        assert!(
            (mean[i] - mid).abs() <= 5.0 * se_mean + 1e-12,
            "coord {i}: mean {} vs {mid}",
            mean[i]
        );
        assert!(
            (cov[(i, i)] - var).abs() <= 5.0 * se_var + 1e-12,
            "coord {i}: var {} vs {var}",
            cov[(i, i)]
        );
    }
    // Independent coordinates: off-diagonal correlations ~ N(0, 1/N).
    for i in 0..4 {
        for j in (i + 1)..4 {
            let corr = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
            assert!(
                corr.abs() <= 5.0 / (N as f64).sqrt(),
                "corr({i},{j}) = {corr}"
            );
        }
    }
}

#[test]
fn gaussian_sample_mean_and_covariance_match() {
    let mean = vec![1.0, -2.0, 0.0];
    let sigma = mat![[2.0, 0.6, -0.3], [0.6, 1.0, 0.2], [-0.3, 0.2, 0.5]];
    let mut g = Gaussian::new(mean.clone(), sigma.clone(), 17).unwrap();
    // Σ = LLᵀ with L lower triangular.
    let l = g.cholesky_factor().to_owned();
    assert!((&l * l.transpose() - &sigma).norm_max() < 1e-14);
    assert!((0..3).all(|i| ((i + 1)..3).all(|j| l[(i, j)] == 0.0)));
    let samples = g.sequence(N);
    let (m, c) = mean_and_cov(&samples);
    let k = N as f64;
    for i in 0..3 {
        assert!(
            (m[i] - mean[i]).abs() <= 5.0 * (sigma[(i, i)] / k).sqrt(),
            "mean {i}: {} vs {}",
            m[i],
            mean[i]
        );
        for j in 0..3 {
            // Var of a Gaussian sample covariance entry: (Σ_ii Σ_jj + Σ_ij²)/N.
            let se = ((sigma[(i, i)] * sigma[(j, j)] + sigma[(i, j)] * sigma[(i, j)]) / k).sqrt();
            assert!(
                (c[(i, j)] - sigma[(i, j)]).abs() <= 5.0 * se,
                "cov({i},{j}) = {} vs {}",
                c[(i, j)],
                sigma[(i, j)]
            );
        }
    }
    // Diagonal constructor: Σ = diag(σ²).
    let d = Gaussian::diagonal(vec![0.0, 0.0], &[0.1, 2.0], 3).unwrap();
    assert!((d.covariance() - mat![[0.01, 0.0], [0.0, 4.0]]).norm_max() <= 1e-17);
    assert_eq!(d.mean(), &[0.0, 0.0]);
}

#[test]
fn zero_disturbance_is_zero() {
    let mut z = Zero(4);
    assert_eq!(z.dim(), 4);
    let mut out = [1.0; 4];
    z.sample(&mut out);
    assert_eq!(out, [0.0; 4]);
    z.reseed(3);
    assert_eq!(z.sequence(2), vec![vec![0.0; 4]; 2]);
}

#[test]
fn bad_input_gives_typed_errors() {
    let invalid = |r: lti_model::Result<UniformBox>, has: &str| match r.unwrap_err() {
        ModelError::InvalidSet { name, reason } => {
            assert_eq!(name, "W");
            assert!(reason.contains(has), "`{reason}` lacks `{has}`");
        }
        other => panic!("{other:?}"),
    };
    invalid(UniformBox::new(vec![1.0], vec![0.0], 0), "empty");
    invalid(
        UniformBox::new(vec![0.0, f64::NAN], vec![1.0, 1.0], 0),
        "NaN",
    );
    invalid(UniformBox::new(vec![0.0], vec![1.0, 2.0], 0), "entries");
    invalid(
        UniformBox::new(vec![f64::NEG_INFINITY], vec![0.0], 0),
        "finite",
    );
    invalid(UniformBox::new(vec![0.0], vec![f64::INFINITY], 0), "finite");
    invalid(
        UniformBox::new(vec![-f64::MAX], vec![f64::MAX], 0),
        "finite width",
    );
    invalid(UniformBox::from_box(&BoxSet::whole(2), 0), "finite");

    let sigma = mat![[1.0, 0.0], [0.0, 1.0]];
    match Gaussian::new(vec![0.0; 3], sigma.clone(), 0).unwrap_err() {
        ModelError::Shape { name, .. } => assert_eq!(name, "covariance"),
        other => panic!("{other:?}"),
    }
    match Gaussian::new(vec![0.0, f64::NAN], sigma.clone(), 0).unwrap_err() {
        ModelError::NonFinite { name, row, .. } => assert_eq!((name.as_str(), row), ("mean", 1)),
        other => panic!("{other:?}"),
    }
    match Gaussian::new(vec![0.0; 2], mat![[1.0, 1.0], [1.0, 1.0]], 0).unwrap_err() {
        ModelError::NotPositiveDefinite { name, .. } => assert_eq!(name, "covariance"),
        other => panic!("{other:?}"),
    }
    match Gaussian::new(vec![0.0; 2], mat![[1.0, 0.5], [0.0, 1.0]], 0).unwrap_err() {
        ModelError::NotSymmetric { name, .. } => assert_eq!(name, "covariance"),
        other => panic!("{other:?}"),
    }
    match Gaussian::new(vec![0.0; 2], mat![[1.0, 0.0], [0.0, f64::INFINITY]], 0).unwrap_err() {
        ModelError::NonFinite { name, .. } => assert_eq!(name, "covariance"),
        other => panic!("{other:?}"),
    }
    match Gaussian::diagonal(vec![0.0; 2], &[1.0, 0.0], 0).unwrap_err() {
        ModelError::NotPositiveDefinite { name, .. } => assert_eq!(name, "std"),
        other => panic!("{other:?}"),
    }
    match Gaussian::diagonal(vec![0.0; 2], &[1.0], 0).unwrap_err() {
        ModelError::Shape { name, .. } => assert_eq!(name, "std"),
        other => panic!("{other:?}"),
    }
}

/// Truncated normal: sample mean and variance against the closed form
/// m = (φ(α) − φ(β))/Z, v = 1 + (αφ(α) − βφ(β))/Z − m² (Z = Φ(β) − Φ(α); the numbers from
/// Python's math.erfc), on every branch of the sampler: half line, far tail, short
/// interval, interval in the tail, left tail (mirrored), wide interval holding 0.
#[test]
fn truncated_normal_matches_the_closed_form_moments_on_every_branch() {
    use lti_model::disturbance::TruncatedNormal;
    let inf = f64::INFINITY;
    let cases = [
        (0.0, inf, 0.7978845608028654, 0.3633802276324186),
        (2.0, inf, 2.373215532822841, 0.1142791004140804),
        (-0.5, 0.5, 0.0, 0.08058915460081162),
        (1.0, 1.3, 1.1414177632217875, 0.007433478187414577),
        (-3.0, -2.5, -2.6948722621772854, 0.01887083042921578),
        (-1.0, 4.0, 0.287451724607027, 0.629124416229106),
    ];
    let n = 200_000;
    for (k, &(a, b, m, v)) in cases.iter().enumerate() {
        // Location 1, scale 2: w = 1 + 2z with z on [a, b].
        let (mu, s) = (1.0, 2.0);
        let mut w = TruncatedNormal::new(
            vec![mu],
            vec![s],
            vec![mu + s * a],
            vec![mu + s * b],
            17 + k as u64,
        )
        .unwrap();
        let (mut sum, mut sq) = (0.0, 0.0);
        let mut out = [0.0];
        for _ in 0..n {
            w.sample(&mut out);
            let z = (out[0] - mu) / s;
            assert!(
                z >= a - 1e-12 && z <= b + 1e-12,
                "case {k}: {z} outside [{a}, {b}]"
            );
            sum += z;
            sq += z * z;
        }
        let mean = sum / n as f64;
        let var = sq / n as f64 - mean * mean;
        // 5 standard errors of the mean; 5% on the variance.
        let se = (v / n as f64).sqrt();
        assert!(
            (mean - m).abs() < 5.0 * se,
            "case {k}: mean {mean} vs {m} (se {se:e})"
        );
        assert!((var - v).abs() < 0.05 * v, "case {k}: var {var} vs {v}");
    }
}

#[test]
fn truncated_normal_is_seeded_and_refuses_empty_laws() {
    use lti_model::disturbance::TruncatedNormal;
    let make = |seed| {
        TruncatedNormal::new(
            vec![0.0, 0.5],
            vec![1.0, 0.0],
            vec![0.0, 0.0],
            vec![f64::INFINITY, 1.0],
            seed,
        )
        .unwrap()
    };
    let (mut a, mut b) = (make(3), make(3));
    assert_eq!(a.sequence(50), b.sequence(50));
    let mut c = make(4);
    a.reseed(4);
    assert_eq!(a.sequence(10), c.sequence(10));
    // σ = 0: the location itself.
    assert!(make(1).sequence(5).iter().all(|w| w[1] == 0.5));
    // σ = 0 with the location outside the box; a one-point interval with σ > 0.
    assert!(TruncatedNormal::new(vec![2.0], vec![0.0], vec![0.0], vec![1.0], 0).is_err());
    assert!(TruncatedNormal::new(vec![0.0], vec![1.0], vec![1.0], vec![1.0], 0).is_err());
    assert!(TruncatedNormal::new(vec![0.0], vec![-1.0], vec![0.0], vec![1.0], 0).is_err());
}
