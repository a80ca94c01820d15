//! The trace of Alg. 1: the order of eq. (1), the captured MHE records and the statistics.

use crate::build;
use crate::sim::{case_study, lqr, norm, options};
use closed_loop::sim::ClosedLoop;
use lti_model::disturbance::UniformBox;
use mhe_core::Estimator;
use mpc_core::Controller;

/// An estimator that returns x̂_t = (0.1 t, …) and logs the protocol.
#[derive(Debug, Default)]
struct Spy {
    nx: usize,
    x: Vec<f64>,
    pushes: Vec<(Vec<f64>, Vec<f64>)>,
    /// Number of pushes seen by each `estimate` call.
    seen: Vec<usize>,
}

impl Estimator for Spy {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        self.seen.push(self.pushes.len());
        let t = self.pushes.len() as f64;
        self.x = vec![0.1 * t; self.nx];
        Ok(&self.x)
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> mhe_core::Result<()> {
        self.pushes.push((u.to_vec(), y.to_vec()));
        Ok(())
    }
    fn nx(&self) -> usize {
        self.nx
    }
}

/// The order of Alg. 1 and eq. (1), recomputed from the trace with the matrices alone:
/// x̂_t from t pushes, u_t = π(x̂_t), y_t = C x_t + w²_t pushed after the estimate,
/// x_{t+1} = A x_t + B u_t + w¹_t, e_t = x̂_t − x_t, and the norms.
#[test]
fn trace_follows_alg1_and_eq1() {
    let s = case_study();
    let spy = Spy {
        nx: 4,
        ..Spy::default()
    };
    let w = UniformBox::from_box(&s.sets.disturbance, 3).unwrap();
    let mut cl = ClosedLoop::new(s.plant.clone(), spy, lqr(&s), w, &s.simulation.x0, 12).unwrap();
    cl.run().unwrap();
    let tr = cl.trace();
    let (a, b, c) = (s.plant.a(), s.plant.b(), s.plant.c());
    let mut pi = lqr(&s);
    let spy = cl.estimator();
    assert_eq!(spy.seen, (0..12).collect::<Vec<_>>());
    for t in 0..12 {
        let x = tr.x(t).unwrap();
        let u = tr.u(t).unwrap();
        let xh = tr.x_hat(t).unwrap();
        assert_eq!(xh, &[0.1 * t as f64; 4][..]);
        let mut u_ref = [0.0; 2];
        pi.control(xh, &mut u_ref).unwrap();
        assert_eq!(u, &u_ref[..]);
        let (w1, w2) = (tr.w1(t).unwrap(), tr.w2(t).unwrap());
        assert_eq!((w1.len(), w2.len()), (4, 1));
        assert!(tr.w(t).unwrap().iter().all(|v| v.abs() <= 0.1));
        let y_ref: f64 = (0..4).map(|j| c[(0, j)] * x[j]).sum::<f64>() + w2[0];
        assert!((tr.y(t).unwrap()[0] - y_ref).abs() <= 1e-14);
        let x_next = tr.x(t + 1).unwrap();
        for i in 0..4 {
            let r = (0..4).map(|j| a[(i, j)] * x[j]).sum::<f64>()
                + (0..2).map(|j| b[(i, j)] * u[j]).sum::<f64>()
                + w1[i];
            assert!((x_next[i] - r).abs() <= 1e-13, "t = {t}, i = {i}");
        }
        let e: Vec<f64> = xh.iter().zip(x).map(|(p, q)| p - q).collect();
        assert_eq!(tr.e(t).unwrap(), &e[..]);
        assert_eq!(tr.e_norms()[t], norm(&e));
        assert_eq!(tr.x_norms()[t], norm(x));
        assert_eq!(spy.pushes[t].0, u);
        assert_eq!(spy.pushes[t].1, tr.y(t).unwrap());
    }
    assert_eq!(cl.state(), tr.x(12).unwrap());
    assert!(tr.mhe().is_none() && tr.mhe_step(0).is_none());
    assert!(tr.epsilons().all(|e| e.is_none()));
}

/// The captured MHE record is the estimate's own, with the window and prior of Alg. 1
/// (trap 1: prior x̄₀ for t ≤ M, x̂_{t−M} after; trap 2: the window holds u, y of
/// t − M_t … t − 1), and ε_t is recorded when the exact solve is on.
#[test]
fn mhe_records_are_captured_with_alg1_window_and_prior() {
    let s = case_study();
    let mut cl = build(&s, &options(&s, 5, true)).unwrap();
    let tr = cl.run().unwrap();
    let big_m = 5;
    let mhe = tr.mhe().unwrap();
    assert_eq!((mhe.len(), mhe.max_window()), (tr.len(), big_m));
    for t in 0..tr.len() {
        let r = tr.mhe_step(t).unwrap();
        let m = t.min(big_m);
        assert_eq!((r.t(), r.window(), r.iterations()), (t, m, 5));
        assert_eq!(r.x_hat(), tr.x_hat(t).unwrap());
        let prior = if t <= big_m {
            &s.simulation.prior[..]
        } else {
            tr.x_hat(t - big_m).unwrap()
        };
        assert_eq!(r.prior(), prior, "t = {t}");
        for j in 0..m {
            assert_eq!(r.u(j).unwrap(), tr.u(t - m + j).unwrap());
            assert_eq!(r.y(j).unwrap(), tr.y(t - m + j).unwrap());
            assert!(r.w2_k(j).unwrap()[0].abs() <= 0.1);
        }
        assert!(r.u(m).is_none());
        let eps = r.epsilon().unwrap();
        assert!(eps <= r.initial_error().unwrap() + 1e-12);
        let xs = r.x_hat_exact().unwrap();
        assert_eq!(r.w_exact_flat().unwrap().len(), m * 5);
        assert!(xs.iter().all(|v| v.is_finite()));
    }
    // ε_t > 0 somewhere for K = 5 (it is the point of the record).
    assert!(tr.epsilons().flatten().any(|e| e > 1e-6));

    let v: serde_json::Value = serde_json::from_str(&tr.to_json().unwrap()).unwrap();
    let recs = v["records"].as_array().unwrap();
    assert_eq!(recs.len(), tr.len());
    assert_eq!(v["dims"]["nw1"], 4);
    let r6 = &recs[6];
    assert_eq!(r6["mhe"]["window"], 5);
    assert_eq!(r6["mhe"]["w_k"].as_array().unwrap().len(), 5);
    assert_eq!(
        r6["mhe"]["epsilon"].as_f64(),
        tr.mhe_step(6).unwrap().epsilon()
    );
    assert_eq!(r6["x_hat"][0].as_f64(), Some(tr.x_hat(6).unwrap()[0]));
    assert_eq!(v["summary"]["sup_norm_e"].as_f64(), Some(tr.sup_norm_e()));
}

/// The helpers against brute force over the accessors.
#[test]
fn trace_statistics_match_brute_force() {
    let s = case_study();
    let mut cl = build(&s, &options(&s, 20, false)).unwrap();
    let tr = cl.run().unwrap();
    let n = tr.len();
    let max = |f: &dyn Fn(usize) -> f64, r: std::ops::Range<usize>| r.map(f).fold(0.0, f64::max);
    assert_eq!(tr.sup_norm_e(), max(&|t| norm(tr.e(t).unwrap()), 0..n));
    assert_eq!(tr.sup_norm_x(), max(&|t| norm(tr.x(t).unwrap()), 0..n + 1));
    assert_eq!(tr.sup_norm_w(), max(&|t| norm(tr.w(t).unwrap()), 0..n));
    assert!(tr.sup_norm_w() <= 0.1 * 5f64.sqrt());
    // Last quarter of 40 steps: t = 30..39.
    let mean = |f: &dyn Fn(usize) -> f64| (30..40).map(f).sum::<f64>() / 10.0;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1e-300);
    assert!(close(
        tr.tail_mean_e().unwrap(),
        mean(&|t| norm(tr.e(t).unwrap()))
    ));
    assert!(close(
        tr.tail_mean_x().unwrap(),
        mean(&|t| norm(tr.x(t).unwrap()))
    ));
    assert!(close(
        tr.tail_mean_w().unwrap(),
        mean(&|t| norm(tr.w(t).unwrap()))
    ));
    assert_eq!(tr.tail_mean_epsilon(), None); // exact solve off
    assert_eq!(tr.x(n + 1), None);
    assert_eq!(tr.u(n), None);
}
