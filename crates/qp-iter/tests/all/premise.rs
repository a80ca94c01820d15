//! The soundness check can fail: with a step beyond 2/L (premise broken) the rate claimed by
//! the 1 − αμ formula is violated and unconstrained instances diverge; with 1.9/L (premise
//! kept) the same checker passes.

use qp_iter::IterationMap;
use qp_iter::pg::{ProjectedGradient, StepRule};

use crate::certificates::{K_MAX, iterate_errors};
use crate::common::{Gen, Tally, check_sequence, dist, random_instance, reference};

fn instances() -> impl Iterator<Item = crate::common::Instance> {
    (40_000..40_400u64)
        .map(|seed| {
            random_instance(
                seed,
                Gen {
                    log10_kappa_max: 2.0,
                    p_finite: 0.3,
                    ..Gen::default()
                },
            )
        })
        .filter(|i| i.qp.kappa() >= 10.0)
}

#[test]
fn claimed_rate_fails_for_step_beyond_two_over_l() {
    let (mut t, mut count, mut whole, mut diverged) = (Tally::default(), 0, 0, 0);
    for inst in instances() {
        let r = reference(&inst);
        let (mu, l) = (inst.qp.mu(), inst.qp.l());
        let alpha = 2.5 / l;
        let pg = ProjectedGradient::new(inst.qp.clone(), StepRule::Fixed(alpha)).unwrap();
        // The crate itself certifies nothing for this step ...
        assert!(pg.certificate().rate >= 1.0 && !pg.certificate().fits_eq11);
        // ... but the "1 − αμ" formula (valid for α ≤ 2/(L+μ)) would claim a rate < 1.
        let claimed = 1.0 - alpha * mu;
        assert!(claimed < 1.0);
        let errs = iterate_errors(&pg, &inst, &r.sol.z, None);
        let e0 = dist(&inst.z0, &r.sol.z);
        check_sequence(e0, &errs, |k| claimed.powi(k as i32), r.err, &mut t);
        count += 1;
        if inst.qp.zset().is_whole() {
            whole += 1;
            if errs[K_MAX] > 1e6 * e0 {
                diverged += 1;
            }
        }
    }
    println!(
        "step 2.5/L, claimed 1 − αμ: {t:?} over {count} instances; {diverged}/{whole} unconstrained diverged"
    );
    assert!(count >= 150, "{count}");
    assert!(
        t.instances_violated as f64 >= 0.8 * count as f64,
        "{t:?} of {count}"
    );
    assert!(whole > 0 && diverged == whole, "{diverged}/{whole}");
}

#[test]
fn same_checker_passes_when_the_premise_holds() {
    let mut t = Tally::default();
    for inst in instances() {
        let r = reference(&inst);
        let pg =
            ProjectedGradient::new(inst.qp.clone(), StepRule::Fixed(1.9 / inst.qp.l())).unwrap();
        let c = pg.certificate();
        assert!(c.fits_eq11 && c.rate < 1.0);
        let errs = iterate_errors(&pg, &inst, &r.sol.z, None);
        let e0 = dist(&inst.z0, &r.sol.z);
        check_sequence(e0, &errs, |k| c.phi(k), r.err, &mut t);
    }
    println!("step 1.9/L, own certificate: {t:?}");
    assert_eq!(t.violations, 0, "{t:?}");
}
