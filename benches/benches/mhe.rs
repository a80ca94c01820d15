//! PG, FISTA, ADMM and Clarabel on the real case-study MHE QPs (`mhe-core`), per preset
//! (paper M = 5, certified M = 9), all timed interleaved in one run
//! ([`benches::interleave`]): ratios between rows are the robust figures.
//!
//! Methods: PG (step 2/(L + μ)), V-FISTA, ADMM (ρ = √(μL), α = 1: the crate default and
//! the case study's `admm`) and `admm_pr`, the same ADMM with relaxation α = 2
//! (Peaceman–Rachford; certified rate δ instead of (1 + δ)/2).
//!
//! Rows per preset (instances: [`benches::case_study`], t = M … T of one closed-loop run):
//! - `ref`: the fixed-size reference kernel y = Hx (compile-time n, AVX2 + FMA by run-time
//!   detection) on the window-M Hessian; `matvec_padded`: our product on it
//!   (`Kernel::matvec_padded`, the padded layout the methods use).
//! - `step/<method>`: one iteration.
//! - `to_eps/<method>`: load θ_t + warm start z⁰_t + K_t steps, K_t the smallest count with
//!   ‖z − z*‖ ≤ 1e-6‖z⁰ − z*‖ on that instance; mean over the instances.
//! - `cert/<method>`: the same with K = the certificate's K for φ(K) ≤ 1e-6 (every
//!   instance reaches 1e-6 by the certificate); mean over the instances.
//! - `mhe/<method>`: one full MHE step (`MheEstimator::estimate`: θ assembly, load, warm
//!   start, K = certificate's K iterations, cost and propagation) at t = T.
//! - `clarabel`: Clarabel's interior-point solve (tol 1e-8, no polish, set up once, q
//!   updated), mean over the instances.
//!
//! Peers (DAQP, OSQP, ProxQP) are timed by `benches/peers/run.sh` on the same instances
//! (exported by `export_qps`); if `target/peers/results.json` exists and matches these
//! instances, their rows are added to the table (their own solver timers; a separate
//! process run just before this one).
//!
//! Output: a markdown table per preset on stdout, JSON in `target/bench-results/mhe.json`.
//! Run: `cargo bench -p benches --bench mhe` (≈ 1 min).

use std::collections::BTreeMap;
use std::hint::black_box;

use benches::case_study::{CaseStudyQps, EPS, MheInstance, PRESETS, certified_k};
use benches::{FixedLayout, FixedMatVec, Timing, Variant, dist, interleave};
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{IterationMap, ParametricQp, RunStatus, run_fixed, run_until};
use serde_json::{Value, json};

const ROUNDS: usize = 200;
/// Row names of the methods: PG (step 2/(L + μ)), V-FISTA, ADMM (ρ = √(μL), α = 1, the
/// crate default and the case study's), ADMM with α = 2 (Peaceman–Rachford).
const METHODS: [&str; 4] = ["pg", "fista", "admm", "admm_pr"];
/// Relaxed ADMM at α = 2 (Peaceman–Rachford splitting), ρ = √(μL).
const PEACEMAN_RACHFORD: AdmmParams = AdmmParams {
    penalty: qp_iter::admm::Penalty::Optimal,
    relaxation: 2.0,
};
/// Calls per batch of the per-iteration rows.
const STEP_BATCH: usize = 2000;
/// Calls per batch of the MHE-step rows.
const MHE_BATCH: usize = 20;

fn main() {
    let kernel = Kernel::detect().path().name();
    let peers = read_peers();
    let mut all = serde_json::Map::new();
    println!("kernel path: {kernel}; rounds: {ROUNDS}; accuracy: {EPS:e} relative\n");
    for preset in PRESETS {
        let qps = match CaseStudyQps::load(preset) {
            Ok(q) => q,
            Err(e) => {
                eprintln!("{}: cannot build the case-study QPs: {e}", preset.name);
                std::process::exit(1);
            }
        };
        match run_preset(&qps) {
            Ok(mut v) => {
                if let Some(p) = peers.as_ref().and_then(|p| p.get(preset.name)) {
                    let (a, b) = (p["fingerprint"].as_f64(), v["fingerprint"].as_f64());
                    match (a, b) {
                        (Some(a), Some(b)) if (a - b).abs() <= 1e-9 * (1.0 + b.abs()) => {
                            v["peers"] = p.clone();
                        }
                        _ => eprintln!(
                            "{}: target/peers/results.json is for other instances \
                             (fingerprint {a:?} vs {b:?}); rerun benches/peers/run.sh",
                            preset.name
                        ),
                    }
                }
                print_table(&qps, &v);
                all.insert(preset.name.into(), v);
            }
            Err(e) => {
                eprintln!("{}: {e}", preset.name);
                std::process::exit(1);
            }
        }
    }
    let out = json!({ "kernel_path": kernel, "eps": EPS, "rounds": ROUNDS, "presets": all });
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench-results");
    let text = serde_json::to_string_pretty(&out).unwrap_or_default();
    if let Err(e) =
        std::fs::create_dir_all(&dir).and_then(|_| std::fs::write(dir.join("mhe.json"), text))
    {
        eprintln!("could not write target/bench-results/mhe.json: {e}");
    }
}

/// Peer results of `benches/peers/run.sh`, by preset (None if absent or unreadable).
fn read_peers() -> Option<serde_json::Map<String, Value>> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/peers/results.json");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    v.get("presets")?.as_object().cloned()
}

/// Sum of every entry of every q_t: the instance fingerprint the peer export also writes.
fn fingerprint(instances: &[MheInstance]) -> f64 {
    instances.iter().flat_map(|i| &i.q).sum()
}

struct Methods {
    pg: ProjectedGradient,
    fista: Fista,
    admm: Admm,
    /// ADMM with relaxation α = 2 (Peaceman–Rachford): certified rate δ instead of (1 + δ)/2.
    admm_pr: Admm,
}

fn methods(qp: &ParametricQp) -> Result<Methods, qp_iter::QpError> {
    Ok(Methods {
        pg: ProjectedGradient::new(qp.clone(), StepRule::Optimal)?,
        fista: Fista::new(qp.clone()),
        admm: Admm::new(qp.clone(), AdmmParams::default())?,
        admm_pr: Admm::new(qp.clone(), PEACEMAN_RACHFORD)?,
    })
}

/// Smallest K with ‖z^K − z*‖ ≤ EPS‖z⁰ − z*‖ from the instance's warm start.
fn iterations_to_eps<M: IterationMap>(map: &M, inst: &MheInstance) -> Result<usize, String> {
    let mut s = map.new_state();
    map.load(&mut s, &inst.theta);
    map.warm_start(&mut s, &inst.z0, None);
    let e0 = dist(&inst.z0, &inst.z_star);
    let r = run_until(map, &mut s, 1_000_000, |_, z| {
        (dist(z, &inst.z_star) <= EPS * e0).then_some(true)
    });
    if r.status == RunStatus::Converged {
        Ok(r.iterations)
    } else {
        Err(format!(
            "{} did not reach {EPS:e} at t = {}",
            map.name(),
            inst.t
        ))
    }
}

/// Largest ‖z^K − z*‖/‖z⁰ − z*‖ over the instances after K steps from the warm start.
fn worst_error_at<M: IterationMap>(map: &M, instances: &[MheInstance], k: usize) -> f64 {
    let mut s = map.new_state();
    instances
        .iter()
        .map(|inst| {
            map.load(&mut s, &inst.theta);
            map.warm_start(&mut s, &inst.z0, None);
            run_fixed(map, &mut s, k);
            dist(map.iterate(&s), &inst.z_star) / dist(&inst.z0, &inst.z_star)
        })
        .fold(0.0, f64::max)
}

/// Batch: one step of `map`, STEP_BATCH times, from the first instance.
fn step_variant<'a, M: IterationMap>(name: &str, map: &'a M, inst: &MheInstance) -> Variant<'a> {
    let mut s = map.new_state();
    map.load(&mut s, &inst.theta);
    map.warm_start(&mut s, &inst.z0, None);
    Variant {
        name: name.into(),
        per_call: STEP_BATCH as f64,
        run: Box::new(move || {
            for _ in 0..STEP_BATCH {
                map.step(black_box(&mut s));
            }
        }),
    }
}

/// Batch: every instance solved by load + warm start + `ks[i]` steps.
fn solve_variant<'a, M: IterationMap>(
    name: String,
    map: &'a M,
    instances: &'a [MheInstance],
    ks: Vec<usize>,
) -> Variant<'a> {
    let mut s = map.new_state();
    Variant {
        name,
        per_call: instances.len() as f64,
        run: Box::new(move || {
            for (inst, &k) in instances.iter().zip(&ks) {
                map.load(&mut s, black_box(&inst.theta));
                map.warm_start(&mut s, &inst.z0, None);
                black_box(run_fixed(map, &mut s, k));
            }
        }),
    }
}

/// Batch: MHE_BATCH full MHE steps at t = T (idempotent `estimate`).
fn mhe_variant<'a, M: IterationMap + 'a>(
    name: &str,
    mut est: mhe_core::MheEstimator<M>,
) -> Variant<'a> {
    Variant {
        name: name.into(),
        per_call: MHE_BATCH as f64,
        run: Box::new(move || {
            for _ in 0..MHE_BATCH {
                let _ = black_box(est.estimate());
            }
        }),
    }
}

/// The reference kernel at the preset's size (compile-time n: 29 and 49 are instantiated).
fn reference_variant<'a>(h: &[f64], n: usize) -> Option<Variant<'a>> {
    fn make<'a, const N: usize>(h: &[f64]) -> Option<Variant<'a>> {
        let k = FixedMatVec::<N>::new(h, FixedLayout::ColumnAxpy)?;
        let x: [f64; N] = std::array::from_fn(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5);
        let mut y = [0.0; N];
        Some(Variant {
            name: "ref".into(),
            per_call: STEP_BATCH as f64,
            run: Box::new(move || {
                for _ in 0..STEP_BATCH {
                    k.apply(black_box(&x), &mut y);
                    black_box(&mut y);
                }
            }),
        })
    }
    match n {
        29 => make::<29>(h),
        49 => make::<49>(h),
        _ => None,
    }
}

fn run_preset(qps: &CaseStudyQps) -> Result<Value, String> {
    let qp = &qps.qp;
    let n = qp.n();
    let inst = &qps.instances;
    let m = methods(qp).map_err(|e| e.to_string())?;
    let err = |e: benches::case_study::FixtureError| e.to_string();
    let k_cert = [
        certified_k(&m.pg).map_err(err)?,
        certified_k(&m.fista).map_err(err)?,
        certified_k(&m.admm).map_err(err)?,
        certified_k(&m.admm_pr).map_err(err)?,
    ];
    let mut ks: [Vec<usize>; 4] = Default::default();
    for i in inst {
        ks[0].push(iterations_to_eps(&m.pg, i)?);
        ks[1].push(iterations_to_eps(&m.fista, i)?);
        ks[2].push(iterations_to_eps(&m.admm, i)?);
        ks[3].push(iterations_to_eps(&m.admm_pr, i)?);
    }
    let worst_at_cert = [
        worst_error_at(&m.pg, inst, k_cert[0]),
        worst_error_at(&m.fista, inst, k_cert[1]),
        worst_error_at(&m.admm, inst, k_cert[2]),
        worst_error_at(&m.admm_pr, inst, k_cert[3]),
    ];
    // Clarabel as a user would run it: tol 1e-8, no polish, set up once, q updated.
    let settings = ReferenceSettings {
        tol: 1e-8,
        polish: false,
        ..ReferenceSettings::default()
    };
    let mut ipm = ReferenceSolver::new(qp, settings).map_err(|e| e.to_string())?;
    let mut ipm_iters = Vec::new();
    let mut ipm_err: f64 = 0.0;
    for i in inst {
        let sol = ipm.solve(&i.theta).map_err(|e| e.to_string())?;
        ipm_iters.push(sol.iterations as usize);
        ipm_err = ipm_err.max(dist(&sol.z, &i.z_star) / dist(&i.z0, &i.z_star));
    }
    let fixture = |e: benches::case_study::FixtureError| e.to_string();
    let est_pg = qps
        .estimator_at_end(k_cert[0], |q| ProjectedGradient::new(q, StepRule::Optimal))
        .map_err(fixture)?;
    let est_fista = qps
        .estimator_at_end(k_cert[1], |q| Ok(Fista::new(q)))
        .map_err(fixture)?;
    let est_admm = qps
        .estimator_at_end(k_cert[2], |q| Admm::new(q, AdmmParams::default()))
        .map_err(fixture)?;
    let est_admm_pr = qps
        .estimator_at_end(k_cert[3], |q| Admm::new(q, PEACEMAN_RACHFORD))
        .map_err(fixture)?;

    let h = qp.h_row_major().to_vec();
    let mut variants = Vec::new();
    if let Some(v) = reference_variant(&h, n) {
        variants.push(v);
    }
    {
        let hp = PaddedSymmetric::from_row_major(&h, n).ok_or("H is n × n")?;
        let (x, mut y) = (AlignedVec::padded(&inst[0].z0), AlignedVec::zeros(hp.ld()));
        let k = Kernel::detect();
        variants.push(Variant {
            name: "matvec_padded".into(),
            per_call: STEP_BATCH as f64,
            run: Box::new(move || {
                for _ in 0..STEP_BATCH {
                    k.matvec_padded(&hp, black_box(&x), &mut y);
                    black_box(&mut y);
                }
            }),
        });
    }
    variants.push(step_variant("step/pg", &m.pg, &inst[0]));
    variants.push(step_variant("step/fista", &m.fista, &inst[0]));
    variants.push(step_variant("step/admm", &m.admm, &inst[0]));
    variants.push(step_variant("step/admm_pr", &m.admm_pr, &inst[0]));
    variants.push(solve_variant(
        "to_eps/pg".into(),
        &m.pg,
        inst,
        ks[0].clone(),
    ));
    variants.push(solve_variant(
        "to_eps/fista".into(),
        &m.fista,
        inst,
        ks[1].clone(),
    ));
    variants.push(solve_variant(
        "to_eps/admm".into(),
        &m.admm,
        inst,
        ks[2].clone(),
    ));
    variants.push(solve_variant(
        "to_eps/admm_pr".into(),
        &m.admm_pr,
        inst,
        ks[3].clone(),
    ));
    let cert = |k: usize| vec![k; inst.len()];
    variants.push(solve_variant(
        "cert/pg".into(),
        &m.pg,
        inst,
        cert(k_cert[0]),
    ));
    variants.push(solve_variant(
        "cert/fista".into(),
        &m.fista,
        inst,
        cert(k_cert[1]),
    ));
    variants.push(solve_variant(
        "cert/admm".into(),
        &m.admm,
        inst,
        cert(k_cert[2]),
    ));
    variants.push(solve_variant(
        "cert/admm_pr".into(),
        &m.admm_pr,
        inst,
        cert(k_cert[3]),
    ));
    variants.push(mhe_variant("mhe/pg", est_pg));
    variants.push(mhe_variant("mhe/fista", est_fista));
    variants.push(mhe_variant("mhe/admm", est_admm));
    variants.push(mhe_variant("mhe/admm_pr", est_admm_pr));
    {
        let inst = inst.as_slice();
        variants.push(Variant {
            name: "clarabel".into(),
            per_call: inst.len() as f64,
            run: Box::new(move || {
                for i in inst {
                    let _ = black_box(ipm.solve(black_box(&i.theta)));
                }
            }),
        });
    }
    let times = interleave(&mut variants, ROUNDS);
    let timing: BTreeMap<String, Value> = variants
        .iter()
        .zip(&times)
        .map(|(v, t): (&Variant<'_>, &Timing)| {
            (
                v.name.clone(),
                json!({ "min_ns": t.min_ns, "median_ns": t.median_ns }),
            )
        })
        .collect();
    let stats = |k: &[usize]| {
        let mut s = k.to_vec();
        s.sort_unstable();
        json!({ "min": s[0], "median": s[s.len() / 2], "max": s[s.len() - 1],
                "mean": s.iter().sum::<usize>() as f64 / s.len() as f64 })
    };
    Ok(json!({
        "preset": qps.preset.name,
        "scenario": qps.preset.file,
        "horizon": qps.horizon(),
        "n": n,
        "n_theta": qp.n_theta(),
        "kappa": qp.kappa(),
        "instances": inst.len(),
        "t_range": [inst[0].t, inst[inst.len() - 1].t],
        "fingerprint": fingerprint(inst),
        "k_cert": { "pg": k_cert[0], "fista": k_cert[1], "admm": k_cert[2], "admm_pr": k_cert[3] },
        "worst_rel_error_at_k_cert": { "pg": worst_at_cert[0], "fista": worst_at_cert[1],
                                       "admm": worst_at_cert[2], "admm_pr": worst_at_cert[3] },
        "k_to_eps": { "pg": stats(&ks[0]), "fista": stats(&ks[1]), "admm": stats(&ks[2]),
                      "admm_pr": stats(&ks[3]) },
        "clarabel": { "ipm_iterations": stats(&ipm_iters), "worst_rel_error": ipm_err },
        "timing": timing,
    }))
}

fn fmt_ns(t: f64) -> String {
    if t < 1e3 {
        format!("{t:.1} ns")
    } else if t < 1e6 {
        format!("{:.2} µs", t / 1e3)
    } else {
        format!("{:.2} ms", t / 1e6)
    }
}

fn print_table(qps: &CaseStudyQps, v: &Value) {
    let t = |name: &str| v["timing"][name]["min_ns"].as_f64();
    let name = qps.preset.name;
    println!(
        "### Preset `{name}` ({}): M = {}, n = {}, n_θ = {}, κ = {:.1}, {} instances (t = {}…{})\n",
        qps.preset.file,
        v["horizon"],
        v["n"],
        v["n_theta"],
        v["kappa"].as_f64().unwrap_or(f64::NAN),
        v["instances"],
        v["t_range"][0],
        v["t_range"][1],
    );
    let r = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => format!("{:.2}×", a / b),
        _ => "—".into(),
    };
    println!("Per iteration (fastest batch of {ROUNDS}):\n");
    println!("| variant | time | ratio to `ref` |");
    println!("| --- | ---: | ---: |");
    for row in [
        "ref",
        "matvec_padded",
        "step/pg",
        "step/fista",
        "step/admm",
        "step/admm_pr",
    ] {
        if let Some(x) = t(row) {
            println!("| `{row}` | {} | {} |", fmt_ns(x), r(Some(x), t("ref")));
        }
    }
    // The exact solve a user would otherwise pick: DAQP when it ran, else Clarabel.
    let peers = &v["peers"];
    let daqp = peers["daqp"]["solve_ns"]["min"].as_f64();
    let base_name = if daqp.is_some() { "DAQP" } else { "Clarabel" };
    let base = daqp.or(t("clarabel"));
    println!(
        "\nPer instance, warm start z⁰_t, accuracy ‖z − z*‖ ≤ 1e-6‖z⁰ − z*‖ (ratios to {base_name}):\n"
    );
    println!(
        "| method | K to 1e-6 (median / max) | time to 1e-6 | certificate K | QP at certificate K | MHE step at certificate K | MHE step / {base_name} |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: |");
    for m in METHODS {
        let k = &v["k_to_eps"][m];
        println!(
            "| {m} | {} / {} | {} | {} | {} | {} | {} |",
            k["median"],
            k["max"],
            t(&format!("to_eps/{m}")).map_or("—".into(), fmt_ns),
            v["k_cert"][m],
            t(&format!("cert/{m}")).map_or("—".into(), fmt_ns),
            t(&format!("mhe/{m}")).map_or("—".into(), fmt_ns),
            r(t(&format!("mhe/{m}")), base),
        );
    }
    let c = &v["clarabel"];
    println!(
        "| Clarabel (IPM, tol 1e-8) | {} / {} IPM it. | {} | — | — | — | {} |",
        c["ipm_iterations"]["median"],
        c["ipm_iterations"]["max"],
        t("clarabel").map_or("—".into(), fmt_ns),
        r(t("clarabel"), base),
    );
    for (key, label) in [
        ("daqp", "DAQP (cold)"),
        ("osqp", "OSQP (warm)"),
        ("proxqp", "ProxQP (warm)"),
    ] {
        let p = &peers[key];
        if let Some(s) = p["solve_ns"]["min"].as_f64() {
            println!(
                "| {label} | {} / {} it. | {} (error {:.0e}) | — | — | — | {} |",
                p["iterations"]["median"],
                p["iterations"]["max"],
                fmt_ns(s),
                p["worst_rel_error"].as_f64().unwrap_or(f64::NAN),
                r(Some(s), base),
            );
        }
    }
    if let Some(d) = daqp {
        let best = METHODS
            .into_iter()
            .filter_map(|m| Some((m, t(&format!("mhe/{m}"))?)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((m, x)) = best {
            println!(
                "\nTarget (one MHE step of the fastest method at its certificate K ≤ DAQP's exact solve): {} — {m} {} vs DAQP {} ({:.2}×).",
                if x <= d { "met" } else { "missed" },
                fmt_ns(x),
                fmt_ns(d),
                x / d
            );
        }
    }
    println!(
        "\nWorst ‖zᴷ − z*‖/‖z⁰ − z*‖ over the instances at the certificate K: PG {:.1e}, FISTA {:.1e}, ADMM {:.1e}, ADMM α = 2 {:.1e}; Clarabel {:.1e}.\n",
        v["worst_rel_error_at_k_cert"]["pg"]
            .as_f64()
            .unwrap_or(f64::NAN),
        v["worst_rel_error_at_k_cert"]["fista"]
            .as_f64()
            .unwrap_or(f64::NAN),
        v["worst_rel_error_at_k_cert"]["admm"]
            .as_f64()
            .unwrap_or(f64::NAN),
        v["worst_rel_error_at_k_cert"]["admm_pr"]
            .as_f64()
            .unwrap_or(f64::NAN),
        c["worst_rel_error"].as_f64().unwrap_or(f64::NAN),
    );
}
