//! LMI (2) verdicts that do not depend on units (issue 37, item 4).

use faer::Mat;
use lti_model::ioss;

#[test]
fn scratch_repro() {
    let sys = lti_model::presets::case_study_plant();
    let q1 = Mat::<f64>::identity(5, 5);
    let r1 = Mat::<f64>::identity(1, 1);
    let p1 = ioss::certify(&sys, 0.8, q1.as_ref(), r1.as_ref()).unwrap().p;
    for (q, r) in [(1.0, 1e9), (1.0, 1e10), (1.0, 1e12), (1e-10, 1.0), (1e-12, 1.0), (1e-12, 1e12), (1e12, 1e-12)] {
        let qm = &q1 * q;
        let rm = &r1 * r;
        let c = ioss::certify(&sys, 0.8, qm.as_ref(), rm.as_ref());
        let pq = &p1 * q;
        let a = ioss::assess(&sys, 0.8, qm.as_ref(), rm.as_ref(), pq.as_ref(), &Default::default()).unwrap();
        eprintln!("q={q} r={r}: certify {:?} | assess(P1·q) {} {}", c.as_ref().map(|c| c.lmi_relative_violation).map_err(|e| e.to_string()), a.relative_violation, a.relative_violation_original_units);
    }
}
