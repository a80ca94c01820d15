//! The model against the stored measurements, the verdict's boundary, the bad inputs.

use super::*;

/// The names of the eight methods (`qp_iter::Method::ALL`, the one list).
fn methods() -> Vec<String> {
    qp_iter::Method::ALL
        .iter()
        .map(ToString::to_string)
        .collect()
}

/// The bound the stored model must meet on every measurement (and on the held-out K).
const REL_BOUND: f64 = 0.08;

fn cart() -> StepDims {
    StepDims {
        n: 58,
        n_theta: 31,
        horizon: 9,
        nx: 4,
        nu: 1,
    }
}

#[test]
fn every_method_is_calibrated_on_both_targets_in_both_scalars() {
    let rows = InstructionModel::all().expect("the stored model parses");
    for t in Target::ALL {
        for m in &methods() {
            for s in [Scalar::F64, Scalar::F32] {
                assert!(
                    rows.iter()
                        .any(|r| r.target == t && r.method == *m && r.scalar == s),
                    "no {} calibration for {m} on {t}",
                    s.name()
                );
            }
        }
    }
}

/// f32 answers from its own rows (it said "not computed" before its calibration): on the
/// M4F (single-precision FPU, f64 in software) every method's f32 step is far cheaper than
/// its f64 one; on the M7 (double-precision FPU) within a factor of 2 of it.
#[test]
fn f32_is_computed_from_its_own_rows() {
    for m in &methods() {
        for t in Target::ALL {
            let at = |s| {
                let b =
                    fits(t, t.default_clock_mhz(), m, s, cart(), 10, Some(0.02)).expect("valid");
                assert!(!matches!(b.verdict, Verdict::NotComputed { .. }), "{m} {t}");
                b.instructions.expect("computed")
            };
            let (f64_, f32_) = (at(Scalar::F64), at(Scalar::F32));
            match t {
                Target::CortexM4F => assert!(f32_ < 0.5 * f64_, "{m} {t}: {f32_} vs {f64_}"),
                Target::CortexM7 => {
                    assert!(
                        f32_ < 2.0 * f64_ && f64_ < 2.0 * f32_,
                        "{m} {t}: {f32_} vs {f64_}"
                    );
                }
            }
        }
    }
}

#[test]
fn model_predicts_the_stored_measurements() {
    let rows = InstructionModel::all().expect("the stored model parses");
    let pts = points().expect("the stored points parse");
    assert!(pts.len() >= rows.len() * 4, "too few points");
    let mut worst: f64 = 0.0;
    for p in &pts {
        let m = rows
            .iter()
            .find(|r| r.target == p.target && r.method == p.method && r.scalar == p.scalar)
            .expect("a row per measured (target, method)");
        let rel = (m.instructions(p.dims, p.k) - p.max).abs() / p.max;
        worst = worst.max(rel);
        assert!(
            rel <= m.max_rel_err + 1e-4 && rel <= REL_BOUND,
            "{} {} n = {} K = {}: predicted {:.0}, measured {:.0} ({:.2} %)",
            p.target,
            p.method,
            p.dims.n,
            p.k,
            m.instructions(p.dims, p.k),
            p.max,
            rel * 100.0
        );
        // The verdict's instructions bound the measurement.
        assert!(m.upper(p.dims, p.k) >= p.max * (1.0 - 1e-9));
    }
    for r in &rows {
        assert!(r.held_out_rel_err <= REL_BOUND, "{r:?}");
    }
    assert!(
        worst > 0.0,
        "a model that is exact on soft-float counts is suspicious"
    );
}

#[test]
fn verdict_boundary_fits_at_k_max_not_one_above() {
    for t in Target::ALL {
        let m = InstructionModel::find(t, "admm-pr", Scalar::F64)
            .expect("parses")
            .expect("admm-pr calibrated");
        // T_s such that K* = 100 is the boundary: the time of K = 100 plus half an iteration.
        let k_star = 100;
        let clock = t.default_clock_mhz();
        let ts = (m.upper(cart(), k_star) + 0.5 * m.per_iteration(cart())) / (clock * 1e6);
        let at = fits(t, clock, "admm-pr", Scalar::F64, cart(), k_star, Some(ts)).expect("valid");
        match at.verdict {
            Verdict::Fits { k_max, margin } => {
                assert_eq!(k_max, k_star);
                assert!(margin > 0.0 && margin < 0.01);
            }
            v => panic!("expected fits at K* on {t}, got {v:?}"),
        }
        let above = fits(
            t,
            clock,
            "admm-pr",
            Scalar::F64,
            cart(),
            k_star + 1,
            Some(ts),
        )
        .expect("valid");
        assert_eq!(
            above.verdict,
            Verdict::DoesNotFit {
                k_max: Some(k_star)
            }
        );
        assert!(
            above.summary().contains("needs K ≤ 100"),
            "{}",
            above.summary()
        );
        // A period shorter than the fixed part: not even K = 1.
        let none = fits(t, clock, "admm-pr", Scalar::F64, cart(), 1, Some(1e-9)).expect("valid");
        assert_eq!(none.verdict, Verdict::DoesNotFit { k_max: None });
    }
}

#[test]
fn not_computed_without_period_or_calibration() {
    let b = fits(
        Target::CortexM4F,
        168.0,
        "pg",
        Scalar::F64,
        cart(),
        10,
        None,
    )
    .expect("valid");
    assert!(matches!(b.verdict, Verdict::NotComputed { .. }));
    assert!(
        b.instructions.is_some(),
        "the instructions are still predicted"
    );
    let b = fits(
        Target::CortexM4F,
        168.0,
        "newton",
        Scalar::F64,
        cart(),
        10,
        Some(0.02),
    )
    .expect("valid");
    assert!(
        b.summary().starts_with("not computed: method `newton`"),
        "{}",
        b.summary()
    );
}

#[test]
fn extrapolated_outside_the_calibrated_sizes() {
    let big = StepDims {
        n: 400,
        n_theta: 100,
        horizon: 30,
        nx: 10,
        nu: 2,
    };
    let b = fits(
        Target::CortexM7,
        480.0,
        "pg",
        Scalar::F64,
        big,
        10,
        Some(0.02),
    )
    .expect("valid");
    assert!(b.extrapolated);
    assert!(b.summary().contains("(extrapolated)"), "{}", b.summary());
    assert!(
        !fits(
            Target::CortexM7,
            480.0,
            "pg",
            Scalar::F64,
            cart(),
            10,
            Some(0.02)
        )
        .expect("valid")
        .extrapolated
    );
}

#[test]
fn bad_inputs_name_the_key() {
    let t = Target::CortexM4F;
    for ts in [0.0, -0.02, f64::NAN, f64::INFINITY] {
        let e = fits(t, 168.0, "pg", Scalar::F64, cart(), 10, Some(ts)).expect_err("bad T_s");
        assert_eq!(e.key, "plant.sample_time", "{ts}");
    }
    for c in [0.0, -1.0, f64::NAN] {
        let e = fits(t, c, "pg", Scalar::F64, cart(), 10, Some(0.02)).expect_err("bad clock");
        assert_eq!(e.key, "--clock-mhz", "{c}");
    }
    assert_eq!(
        fits(t, 168.0, "pg", Scalar::F64, cart(), 0, Some(0.02))
            .expect_err("K = 0")
            .key,
        "K"
    );
    assert_eq!(
        Target::parse("cortex-m3").expect_err("unknown").key,
        "--target"
    );
    assert_eq!(Target::parse("cortex-m7"), Ok(Target::CortexM7));
}
