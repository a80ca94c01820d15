//! A trial method, compiled in test builds only: it shows that a method is its own file
//! and one line of the list in `method.rs` (`docs/architecture.md`, "Adding a method").
//!
//! Damped Richardson projection: z⁺ = Π_Z(z − (ω/L)(Hz + q)), ω ∈ (0, 1]. For ω = 1 it is
//! projected gradient with step 1/L, so its certificate is (1 − ωμ/L)ᴷ (the contraction
//! argument of [`crate::pg`]).

use faer::Mat;

use crate::IterationMap;
use crate::certificate::{BoundedQuantity, CertNorm, Certificate};
use crate::error::{QpError, Result};
use crate::linearise::Linearise;
use crate::method::{Family, MethodMap};
use crate::problem::ParametricQp;

/// The map: the problem, H row-major, the step ω/L and the certificate.
#[derive(Debug, Clone)]
pub struct Richardson {
    qp: ParametricQp,
    h: Vec<f64>,
    step: f64,
    cert: Certificate,
}

/// Iterate, scratch and loaded linear term.
#[derive(Debug, Clone)]
pub struct RichardsonState {
    z: Vec<f64>,
    hz: Vec<f64>,
    q: Vec<f64>,
}

impl Richardson {
    fn new(qp: ParametricQp, omega: f64) -> Self {
        let n = qp.n();
        let h = (0..n * n).map(|k| qp.h()[(k / n, k % n)]).collect();
        let step = omega / qp.l();
        let rate = 1.0 - step * qp.mu();
        let cert = Certificate {
            rate,
            prefactor: 1.0,
            quantity: BoundedQuantity::IterateDistance,
            norm: CertNorm::Euclidean,
            fits_eq11: rate < 1.0,
            premise: format!("H ≻ 0, step ω/L = {step:.6e}; exact projection onto a box"),
            source: "Nesterov (2018) Thm 2.1.15".into(),
        };
        Self { qp, h, step, cert }
    }
}

impl IterationMap for Richardson {
    type State = RichardsonState;
    fn name(&self) -> &'static str {
        "richardson"
    }
    fn problem(&self) -> &ParametricQp {
        &self.qp
    }
    fn new_state(&self) -> RichardsonState {
        let n = self.qp.n();
        let mut s = RichardsonState {
            z: vec![0.0; n],
            hz: vec![0.0; n],
            q: self.qp.q0().to_vec(),
        };
        self.cold_start(&mut s);
        s
    }
    fn load(&self, s: &mut RichardsonState, theta: &[f64]) {
        self.qp.linear_term(theta, &mut s.q);
    }
    fn warm_start(&self, s: &mut RichardsonState, z0: &[f64], _dual: Option<&[f64]>) {
        s.z.copy_from_slice(z0);
    }
    fn cold_start(&self, s: &mut RichardsonState) {
        s.z.fill(0.0);
        self.qp.project(&mut s.z);
    }
    fn step(&self, s: &mut RichardsonState) {
        let n = self.qp.n();
        for i in 0..n {
            s.hz[i] = (0..n).map(|j| self.h[i * n + j] * s.z[j]).sum();
        }
        for i in 0..n {
            s.z[i] -= self.step * (s.hz[i] + s.q[i]);
        }
        self.qp.project(&mut s.z);
    }
    fn iterate<'s>(&self, s: &'s RichardsonState) -> &'s [f64] {
        &s.z
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
}

impl Linearise for Richardson {
    fn lift_dim(&self) -> usize {
        self.qp.n()
    }
    fn start_probe(&self, st: &mut RichardsonState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, z0, None);
        xi.copy_from_slice(&st.z);
    }
    fn step_probe(&self, st: &mut RichardsonState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, xi, None);
        self.step(st);
        out.copy_from_slice(&st.z);
    }
    fn readout(&self) -> Mat<f64> {
        Mat::identity(self.qp.n(), self.qp.n())
    }
}

/// `"richardson"` (ω = 1) or `{ method = "richardson", omega = ω }`.
impl Family for Richardson {
    type Params = f64;
    const NAME: &'static str = "richardson";
    const PRESETS: &'static [(&'static str, f64)] = &[("richardson", 1.0)];
    const KEYS: &'static [&'static str] = &["omega"];
    fn with_keys(base: f64, key: &dyn Fn(&str) -> Option<f64>) -> f64 {
        key("omega").unwrap_or(base)
    }
    fn keys_of(p: &f64) -> Vec<(&'static str, f64)> {
        vec![("omega", *p)]
    }
    fn validate(p: &f64) -> Result<()> {
        if *p > 0.0 && *p <= 1.0 {
            Ok(())
        } else {
            Err(QpError::Parameter {
                name: "omega".into(),
                value: *p,
                reason: "the damping must lie in (0, 1]".into(),
            })
        }
    }
    fn build(p: &f64, qp: ParametricQp) -> Result<MethodMap> {
        Ok(MethodMap::Trial(Richardson::new(qp, *p)))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use crate::BoxSet;
    use faer::mat;

    use crate::method::Method;
    use crate::pg::StepRule;
    use crate::{IterationMap, Linearise, MethodMap, ParametricQp, run_fixed};

    fn qp() -> ParametricQp {
        ParametricQp::new(
            mat![[3.0, 0.5], [0.5, 1.0]],
            vec![-1.0, 2.0],
            mat![[1.0], [0.5]],
            BoxSet::symmetric(&[5.0, 5.0]).unwrap(),
        )
        .unwrap()
    }

    /// Named, parsed from a file's table, validated, built, run and linearised with no
    /// code outside its file and its line of the list.
    #[test]
    fn the_trial_method_is_reachable_everywhere_from_its_line_in_the_list() {
        let m: Method = "richardson".parse().unwrap();
        assert_eq!(m.to_string(), "richardson");
        // A file's table (feature `serde`: the workspace's tests enable it).
        #[cfg(feature = "serde")]
        {
            let damped: Method =
                serde_json::from_str(r#"{"method":"richardson","omega":0.5}"#).unwrap();
            assert_eq!(damped.to_string(), "richardson(omega=0.5)");
            let back: Method =
                serde_json::from_str(&serde_json::to_string(&damped).unwrap()).unwrap();
            assert_eq!(back, damped);
            let bad = serde_json::from_str::<Method>(r#"{"method":"richardson","omega":2}"#);
            assert!(bad.unwrap_err().to_string().contains("omega"));
        }
        let jacobi: Method = "richardson-jacobi".parse().unwrap();
        assert!(matches!(jacobi.build(qp()).unwrap(), MethodMap::Scaled(_)));

        // ω = 1 is projected gradient with step 1/L: the same iterates.
        let map = m.build(qp()).unwrap();
        let mut pg = Method::PG;
        pg.kind = crate::MethodKind::Pg(StepRule::InverseL);
        let pg = pg.build(qp()).unwrap();
        let (mut s, mut t) = (map.new_state(), pg.new_state());
        map.load(&mut s, &[0.3]);
        pg.load(&mut t, &[0.3]);
        run_fixed(&map, &mut s, 50);
        run_fixed(&pg, &mut t, 50);
        for (a, b) in map.iterate(&s).iter().zip(pg.iterate(&t)) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        assert!((map.certificate().rate - pg.certificate().rate).abs() < 1e-15);

        // Its lifted form: ξ = z, one step z − (1/L)(Hz + Fθ) away from the bounds.
        assert_eq!(map.lift_dim(), 2);
        let mut st = map.new_state();
        let mut out = [0.0; 2];
        map.step_probe(&mut st, &[0.1, -0.2], &[0.0], &mut out);
        let l = map.problem().l();
        let (h, q0) = (map.problem().h(), map.problem().q0().to_vec());
        for i in 0..2 {
            let hz = h[(i, 0)] * 0.1 + h[(i, 1)] * -0.2;
            let want = [0.1, -0.2][i] - (hz + q0[i]) / l;
            assert!((out[i] - want).abs() < 1e-14);
        }
    }
}
