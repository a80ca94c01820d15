//! The loop step (MHE + the K_c-iteration MPC): the MPC's rows against the stored loop
//! measurements (held out: K_c = 16), the sum against the whole measured loop step, the
//! verdict counting K_c and refusing when K + K_c does not fit.

use super::*;

/// The MPC methods calibrated (`bash scripts/cortex-m.sh calibrate`, CALIB_MPC_METHODS).
const MPC_METHODS: [&str; 4] = ["pg", "fista", "admm", "admm-pr"];

/// The bound the MPC's rows must meet on every loop measurement (docs/embedded.md).
const MPC_REL_BOUND: f64 = 0.08;

/// The bound of MHE + MPC against the whole measured loop step.
const LOOP_REL_BOUND: f64 = 0.08;

/// Instructions the calibration's own counting adds inside a measured loop step: the
/// copy's loop.c reads SysTick around `mpc_control` and sums in `double`, in software on the
/// M4F (≈ 300 instructions; ≈ 5 on the M7). Only the f32 M4F rows, whose error bound is
/// 0.06 %, are tight enough to see it (at K = K_c = 1: 292 of 34 439).
const COUNTING: f64 = 400.0;

/// The K_c the fit did not see (scripts/fit-instructions.py: FIT_KS = {1, 256}).
const HELD_OUT_KC: usize = 16;

/// The cart-pendulum's window (M = 9) and its MPC (N = 10, n_u = 1).
fn cart() -> (StepDims, StepDims) {
    (StepDims::of(4, 1, 2, 6, 9), StepDims::mpc(4, 1, 10))
}

fn mpc_row(p: &Point) -> InstructionModel {
    InstructionModel::find_part(Part::Mpc, p.target, &p.method, p.scalar)
        .expect("the stored MPC model parses")
        .expect("a row per measured (target, method, scalar)")
}

#[test]
fn every_mpc_method_is_calibrated_on_both_targets_in_both_scalars() {
    let rows = InstructionModel::parse(Part::Mpc).expect("the stored MPC model parses");
    for t in Target::ALL {
        for m in MPC_METHODS {
            for s in [Scalar::F64, Scalar::F32] {
                assert!(
                    rows.iter().any(|r| r.part == Part::Mpc
                        && r.target == t
                        && r.method == m
                        && r.scalar == s),
                    "no {} MPC calibration for {m} on {t}",
                    s.name()
                );
            }
        }
    }
}

/// The MPC's rows predict its control part on the points they were not fitted on (K_c =
/// 16) within the stated bound, and every point within the row's stored error.
#[test]
fn mpc_model_predicts_held_out_loop_points() {
    let pts = loop_points().expect("the stored loop points parse");
    let held: Vec<&LoopPoint> = pts.iter().filter(|p| p.mpc.k == HELD_OUT_KC).collect();
    assert!(held.len() >= 24, "too few held-out points: {}", held.len());
    let mut worst: f64 = 0.0;
    for p in &pts {
        let m = mpc_row(&p.mpc);
        let pred = m.instructions(p.mpc.dims, p.mpc.k);
        let rel = (pred - p.mpc.max).abs() / p.mpc.max;
        if p.mpc.k == HELD_OUT_KC {
            worst = worst.max(rel);
            assert!(
                rel <= MPC_REL_BOUND,
                "{p:?}: predicted {pred:.0} ({:.2} %)",
                rel * 100.0
            );
        }
        assert!(rel <= m.max_rel_err + 1e-4, "{p:?}: {:.2} %", rel * 100.0);
        assert!(m.upper(p.mpc.dims, p.mpc.k) >= p.mpc.max * (1.0 - 1e-9));
    }
    assert!(worst > 0.0, "an exact fit on held-out points is suspicious");
}

/// The loop step's bound (MHE's + MPC's, each raised by its own error) covers every
/// measured loop step, and the prediction of the sum is within the stated bound of it.
#[test]
fn loop_prediction_covers_the_measured_loop_steps() {
    for p in loop_points().expect("the stored loop points parse") {
        let mpc = Step {
            method: &p.mpc.method,
            dims: p.mpc.dims,
            k: p.mpc.k,
        };
        let mhe = Step {
            method: &p.mhe_method,
            dims: p.mhe_dims,
            k: p.mhe_k,
        };
        let b =
            fits_loop(p.mpc.target, 168.0, p.mpc.scalar, mhe, Some(mpc), Some(1.0)).expect("valid");
        let (pred, upper) = (
            b.instructions.expect("calibrated"),
            b.instructions_upper.expect("calibrated"),
        );
        let rel = (pred - p.loop_max).abs() / p.loop_max;
        assert!(
            rel <= LOOP_REL_BOUND,
            "{p:?}: predicted {pred:.0} ({:.2} %)",
            rel * 100.0
        );
        assert!(upper + COUNTING >= p.loop_max, "{p:?}: bound {upper:.0}");
    }
}

/// A loop step counts the MPC: its instructions are the MHE's plus the MPC's at K_c, grow
/// with K_c, and the summary names K_c.
#[test]
fn loop_budget_counts_k_c() {
    let (mhe_dims, mpc_dims) = cart();
    for t in Target::ALL {
        for s in [Scalar::F64, Scalar::F32] {
            let mhe = Step {
                method: "admm-pr",
                dims: mhe_dims,
                k: 10,
            };
            let alone = fits(t, 168.0, "admm-pr", s, mhe_dims, 10, Some(0.02)).expect("valid");
            let at = |k_c| {
                let mpc = Step {
                    method: "fista",
                    dims: mpc_dims,
                    k: k_c,
                };
                fits_loop(t, 168.0, s, mhe, Some(mpc), Some(0.02)).expect("valid")
            };
            let (b10, b100) = (at(10), at(100));
            let row = InstructionModel::find_part(Part::Mpc, t, "fista", s)
                .expect("parses")
                .expect("fista calibrated");
            let share = b10.mpc.as_ref().expect("an MPC share");
            assert_eq!(share.k_c, 10);
            assert_eq!(share.instructions_upper, Some(row.upper(mpc_dims, 10)));
            let sum = alone.instructions_upper.expect("computed") + row.upper(mpc_dims, 10);
            assert_eq!(b10.instructions_upper, Some(sum));
            assert!(b100.instructions_upper > b10.instructions_upper);
            assert!(b10.summary().contains("MPC K_c = 10"), "{}", b10.summary());
            assert!(alone.mpc.is_none() && !alone.summary().contains("MPC"));
        }
    }
}

/// T_s that the MHE alone fits at K but MHE + MPC does not: refused (does not fit), the
/// largest K that fits with the MPC named; at the boundary K* fits and K* + 1 does not.
#[test]
fn refused_when_k_plus_k_c_does_not_fit() {
    let (mhe_dims, mpc_dims) = cart();
    for t in Target::ALL {
        let clock = t.default_clock_mhz();
        let m = InstructionModel::find(t, "admm-pr", Scalar::F64)
            .expect("parses")
            .expect("calibrated");
        let c = InstructionModel::find_part(Part::Mpc, t, "fista", Scalar::F64)
            .expect("parses")
            .expect("calibrated");
        let (k, k_c) = (100, 200);
        let mhe = Step {
            method: "admm-pr",
            dims: mhe_dims,
            k,
        };
        let mpc = Step {
            method: "fista",
            dims: mpc_dims,
            k: k_c,
        };
        // Room for the MHE at K plus half the MPC: fits alone, not with the MPC.
        let ts = (m.upper(mhe_dims, k) + 0.5 * c.upper(mpc_dims, k_c)) / (clock * 1e6);
        let alone = fits(t, clock, "admm-pr", Scalar::F64, mhe_dims, k, Some(ts)).expect("valid");
        assert!(
            matches!(alone.verdict, Verdict::Fits { .. }),
            "{t}: {alone:?}"
        );
        let both = fits_loop(t, clock, Scalar::F64, mhe, Some(mpc), Some(ts)).expect("valid");
        let Verdict::DoesNotFit {
            k_max: Some(k_star),
        } = both.verdict
        else {
            panic!(
                "{t}: expected does not fit with a smaller K, got {:?}",
                both.verdict
            );
        };
        assert!(k_star < k, "{t}: {k_star}");
        assert!(
            both.summary().contains(&format!("needs K ≤ {k_star}")),
            "{}",
            both.summary()
        );
        let at = |k| {
            fits_loop(
                t,
                clock,
                Scalar::F64,
                Step { k, ..mhe },
                Some(mpc),
                Some(ts),
            )
        };
        assert!(
            matches!(at(k_star).expect("valid").verdict, Verdict::Fits { k_max, .. } if k_max == k_star)
        );
        assert!(matches!(
            at(k_star + 1).expect("valid").verdict,
            Verdict::DoesNotFit { .. }
        ));
        // The MPC alone over T_s: not even K = 1.
        let short = c.upper(mpc_dims, k_c) / (clock * 1e6);
        let none = fits_loop(t, clock, Scalar::F64, mhe, Some(mpc), Some(short)).expect("valid");
        assert_eq!(none.verdict, Verdict::DoesNotFit { k_max: None });
    }
}

#[test]
fn k_c_zero_and_uncalibrated_mpc_methods() {
    let (mhe_dims, mpc_dims) = cart();
    let mhe = Step {
        method: "pg",
        dims: mhe_dims,
        k: 10,
    };
    let mpc = |method, k| Step {
        method,
        dims: mpc_dims,
        k,
    };
    let t = Target::CortexM4F;
    let e = fits_loop(
        t,
        168.0,
        Scalar::F64,
        mhe,
        Some(mpc("fista", 0)),
        Some(0.02),
    )
    .expect_err("K_c = 0");
    assert_eq!(e.key, "K_c");
    let b = fits_loop(
        t,
        168.0,
        Scalar::F64,
        mhe,
        Some(mpc("newton", 5)),
        Some(0.02),
    )
    .expect("valid");
    assert!(
        b.summary()
            .starts_with("not computed: the MPC: method `newton`"),
        "{}",
        b.summary()
    );
}
