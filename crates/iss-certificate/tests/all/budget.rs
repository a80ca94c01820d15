//! Issue 25 item 4: every analysis phase has an estimate before it starts, and the optional
//! ones (the γ₁,₃ free-set enumeration, ρ_lin) are skipped beyond `certificate.phase_seconds`
//! with the estimate, the budget and the key — on the 20-node thermal rod, whose 2²⁰ free
//! sets took ~9 minutes before.

use closed_loop::scenario::Scenario;
use iss_certificate::budget::{DEFAULT_PHASE_SECONDS, estimate_phases};
use iss_certificate::certificate::CertificateOptions;
use iss_certificate::gamma13::{
    GAMMA13_PATTERN_FAMILIES, enumeration_work, gamma13_certified_budgeted,
};

fn scenario(file: &str) -> Scenario {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenarios/");
    Scenario::from_file(format!("{path}{file}")).unwrap()
}

/// The thermal rod's enumeration (2²⁰ sets × 3 metrics at n_x = 20) is estimated beyond the
/// default budget: the polynomial bound is used, and the skip says why and which key raises
/// it. The certificate is still finite (the S-procedure bound certifies γ₁,₃).
#[test]
fn thermal_rod_enumeration_switches_to_the_polynomial_bound_and_says_so() {
    let s = scenario("thermal-rod-m10.toml");
    let r = s.clone().resolve().unwrap();
    let mpc = r.mpc().unwrap();
    assert_eq!(mpc.saturable().len(), 20);
    let work = enumeration_work(mpc, 3);
    assert!(
        work / iss_certificate::budget::SCALAR_RATE > DEFAULT_PHASE_SECONDS,
        "{work:e}"
    );
    let t0 = std::time::Instant::now();
    let c = gamma13_certified_budgeted(mpc, 20, GAMMA13_PATTERN_FAMILIES, DEFAULT_PHASE_SECONDS)
        .unwrap();
    assert!(t0.elapsed().as_secs_f64() < 120.0, "{:?}", t0.elapsed());
    assert!(!c.enumerated && c.free_sets == 0);
    assert!(c.gamma13.is_finite() && c.void.is_none(), "{:?}", c.void);
    let skip = c
        .skipped
        .iter()
        .find(|k| k.computation == "free-set enumeration")
        .expect("the skip is reported");
    for part in [
        "2^20 free sets",
        "certificate.phase_seconds",
        "S-procedure",
        "> the analysis budget of 10",
    ] {
        assert!(
            skip.reason.contains(part),
            "{part:?} not in {}",
            skip.reason
        );
    }
}

/// A small enumeration (the stand-in) is within the budget and runs exactly as before; the
/// budgeted and unbudgeted certificates are equal.
#[test]
fn an_affordable_enumeration_is_unchanged_by_the_budget() {
    let s = scenario("case-study-certified.toml");
    let r = s.clone().resolve().unwrap();
    let mpc = r.mpc().unwrap();
    let budgeted =
        gamma13_certified_budgeted(mpc, 20, GAMMA13_PATTERN_FAMILIES, DEFAULT_PHASE_SECONDS)
            .unwrap();
    let plain = iss_certificate::gamma13::gamma13_certified(mpc, 20).unwrap();
    assert!(budgeted.enumerated);
    assert_eq!(budgeted, plain);
}

/// Every phase is estimated before anything runs, and the estimate says which optional phase
/// is skipped at the scenario's budget; `certificate.phase_seconds` raises it.
#[test]
fn phase_estimates_name_every_phase_and_follow_the_key() {
    let s = scenario("thermal-rod-m30.toml");
    let r = s.clone().resolve().unwrap();
    let opts = CertificateOptions::default();
    let phases = estimate_phases(&s, r.mpc().ok(), &opts, 2000);
    let names: Vec<&str> = phases.iter().map(|p| p.phase.as_str()).collect();
    for n in [
        "δ-IOSS P (LMI (2))",
        "MHE constants (H̄, L_Φ, φ(K))",
        "L_Φ sampling",
        "L_π",
        "γ₁,₃ family bounds",
        "γ₁,₃ free-set enumeration",
        "ρ_lin (reproduce)",
    ] {
        assert!(names.contains(&n), "{n} missing from {names:?}");
    }
    for p in &phases {
        assert!(
            p.work.is_finite() && p.work >= 0.0 && p.seconds >= 0.0,
            "{p:?}"
        );
    }
    let skipped: Vec<&str> = phases
        .iter()
        .filter(|p| !p.runs)
        .map(|p| p.phase.as_str())
        .collect();
    // ρ_lin of the scenario's method alone (n_z = 710 > 128) by Arnoldi's method fits the
    // default budget.
    assert_eq!(skipped, ["L_Φ sampling", "γ₁,₃ free-set enumeration"]);
    // The key: parsed, validated, and raising it lets both run.
    let text = format!(
        "{}\n[certificate]\nphase_seconds = 1e5\n",
        s.to_toml_string().unwrap()
    );
    let raised = Scenario::from_toml_str(&text).unwrap();
    assert_eq!(raised.certificate.phase_seconds(), 1e5);
    let opts = CertificateOptions {
        phase_seconds: raised.certificate.phase_seconds(),
        ..CertificateOptions::default()
    };
    assert!(
        estimate_phases(&raised, r.mpc().ok(), &opts, 2000)
            .iter()
            .all(|p| p.runs)
    );
    for bad in ["0.0", "-1.0", "1e7", "nan", "inf"] {
        let text = format!(
            "{}\n[certificate]\nphase_seconds = {bad}\n",
            s.to_toml_string().unwrap()
        );
        let e = Scenario::from_toml_str(&text).unwrap_err().to_string();
        assert!(e.contains("certificate.phase_seconds"), "{bad}: {e}");
    }
}

/// A phase every certificate needs, estimated beyond `REQUIRED_PHASE_FACTOR` × the budget, is
/// refused before the certificate starts, naming the phase, its estimate and the key; within
/// the limit the same scenario certifies.
#[test]
fn a_required_phase_beyond_its_limit_refuses_the_certificate_before_it_starts() {
    use iss_certificate::budget::{REQUIRED_PHASE_FACTOR, check_required_phases};
    use iss_certificate::certificate::certify_closed_loop;
    let s = scenario("case-study-certified.toml");
    let r = s.clone().resolve().unwrap();
    let opts = CertificateOptions::default();
    let phases = estimate_phases(&s, r.mpc().ok(), &opts, 1);
    let largest = phases
        .iter()
        .filter(|p| p.required)
        .map(|p| p.seconds)
        .fold(0.0, f64::max);
    assert!(largest > 0.0);
    assert!(check_required_phases(&s, r.mpc().ok(), &opts).is_ok());
    // A budget whose limit lies just below the largest required phase.
    let tight = CertificateOptions {
        phase_seconds: 0.9 * largest / REQUIRED_PHASE_FACTOR,
        ..CertificateOptions::default()
    };
    let started = std::time::Instant::now();
    let e = certify_closed_loop(&r, &tight).unwrap_err().to_string();
    assert!(started.elapsed().as_secs_f64() < 5.0);
    assert!(e.contains("certificate.phase_seconds"), "{e}");
    assert!(e.contains("every certificate"), "{e}");
    // Just above it: computed.
    let enough = CertificateOptions {
        phase_seconds: 1.1 * largest / REQUIRED_PHASE_FACTOR,
        ..CertificateOptions::default()
    };
    assert!(check_required_phases(&s, r.mpc().ok(), &enough).is_ok());
}
