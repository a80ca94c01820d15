//! PG, FISTA, ADMM (α = 1 and 2), each plain and Jacobi-scaled, and Clarabel on the real
//! case-study MHE QPs (`mhe-core`), per preset (paper M = 5, certified M = 9, m50 = the
//! certified file at M = 50, cart-pendulum M = 9), all timed interleaved in one run per preset
//! ([`benches::interleave`]): ratios between rows are the robust figures.
//!
//! Methods ([`METHODS`], built as the scenario runs build them: [`Method::build`], a
//! [`qp_iter::MethodMap`] that dispatches once per K-step run): PG (step 2/(L + μ)),
//! V-FISTA, ADMM (ρ = √(μL), α = 1: the crate default and the case study's `admm`),
//! `admm_pr`, the same ADMM with relaxation α = 2 (Peaceman–Rachford; certified rate δ
//! instead of (1 + δ)/2), and the same four on the Jacobi-scaled problem (`*_jacobi`:
//! the map runs on DHD, D = diag(H)^−½, and reports z = Dy; `qp_iter::scaled`).
//!
//! Rows per preset (instances: [`benches::case_study`], t = M … T of one closed-loop run):
//! - `ref`: the fixed-size reference kernel y = Hx (compile-time n, AVX2 + FMA by run-time
//!   detection) on the window-M Hessian (n = 29 and 49 only); `matvec_padded`: our product
//!   on it (`Kernel::matvec_padded`, the padded layout the methods use).
//! - `step/<method>`: one iteration inside a run: `run_steps` of a batch of steps, per step
//!   (a scaled map maps y back to z once per run, not per step).
//! - `to_eps/<method>`: load θ_t + warm start z⁰_t + K_t steps, K_t the smallest count with
//!   ‖z − z*‖ ≤ 1e-6‖z⁰ − z*‖ on that instance; mean over the instances.
//! - `cert/<method>`: the same with K = the certificate's K for φ(K) ≤ 1e-6 (every
//!   instance reaches 1e-6 by the certificate); mean over the instances.
//! - `mhe/<method>`: one full MHE step (`MheEstimator::estimate`: θ assembly, load, warm
//!   start, K = certificate's K iterations, cost and propagation) at t = T.
//! - `mhe_kmin/<method>`: the same at K = K_min of Theorem 1 (the closed-loop certificate,
//!   `iss_certificate::certificate` with its certified constants only, as the sweeps compute
//!   it), when it differs from the certificate's K for 1e-6 and the per-instance rows are
//!   affordable.
//! - `mhe_kreg/<method>`: the same at K = K_reg, the smallest K whose regional certificate
//!   contains the scenario's own uncertainty (`iss_certificate::regional::k_reg`, searched
//!   as `cargo xtask reproduce` searches it: [`k_reg_search`]), on the presets that ask for
//!   it ([`benches::case_study::Preset::k_reg`]); where a method has none, the search's
//!   reason is printed under the table.
//! - `clarabel`: Clarabel's interior-point solve (tol 1e-8, no polish, set up once, q
//!   updated), mean over the instances.
//!
//! A method whose certificate K makes a row unaffordable is left out of it, with the
//! reason in the table: the per-instance rows (`to_eps`, `cert`, the worst error at the
//! certificate K) need K·n² ≤ [`INSTANCE_WORK`], the MHE step K·n² ≤ [`MHE_WORK`] — at
//! M = 50 the plain maps' certificates ask for 10⁴–10⁶ iterations.
//!
//! Peers (DAQP, OSQP condensed and uncondensed, ProxQP) are timed by
//! `benches/peers/run.sh` on the same instances (exported by `export_qps`); if
//! `target/peers/results.json` exists and matches these instances, their rows are added
//! to the table (their own solver timers; a separate process run just before this one).
//!
//! Output: a markdown table per preset on stdout, JSON in `target/bench-results/mhe.json`.
//! Run: `cargo bench -p benches --bench mhe` (≈ 2.2 min; the cart-pendulum's K_reg searches
//! take 40–50 s of it).

use std::collections::BTreeMap;
use std::hint::black_box;

use benches::case_study::{CaseStudyQps, EPS, MHE_PRESETS, MheInstance, certified_k};
use benches::{FixedLayout, FixedMatVec, Timing, Variant, dist, interleave};
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use iss_certificate::certificate::{CertificateOptions, certify_closed_loop};
use iss_certificate::regional::{Limit, RegionalOptions, k_reg, search_max};
use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
use qp_iter::method::{Method, MethodMap, Scaling};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{IterationMap, RunStatus, run_fixed, run_until};
use serde_json::{Value, json};

/// Jacobi-scaled counterpart of a method.
const fn jacobi(m: Method) -> Method {
    m.with_scaling(Scaling::Jacobi)
}

/// Row names and methods: the four plain maps, then the same four Jacobi-scaled.
const METHODS: [(&str, Method); 8] = [
    ("pg", Method::PG),
    ("fista", Method::FISTA),
    ("admm", Method::ADMM),
    ("admm_pr", Method::ADMM_PR),
    ("pg_jacobi", jacobi(Method::PG)),
    ("fista_jacobi", jacobi(Method::FISTA)),
    ("admm_jacobi", jacobi(Method::ADMM)),
    ("admm_pr_jacobi", jacobi(Method::ADMM_PR)),
];

/// Largest K·n² (multiply-adds per instance) for the per-instance rows of a method.
const INSTANCE_WORK: f64 = 1e8;
/// Largest K·n² for the MHE-step row of a method (≈ 1 s at n = 254).
const MHE_WORK: f64 = 5e9;
/// Multiply-adds per batch of the per-iteration rows (2000 steps at n = 29).
const STEP_WORK: f64 = 2000.0 * 29.0 * 29.0;
/// Multiply-adds per batch of the MHE-step rows, at least one step per batch.
const MHE_BATCH_WORK: f64 = 20.0 * 130.0 * 29.0 * 29.0;

/// Rounds of the interleaved timing: 200 for the small presets; at n > 100 (M = 50, where
/// a round takes seconds) fewer.
fn rounds(n: usize) -> usize {
    if n > 100 { 40 } else { 200 }
}

/// Calls per batch for `work` multiply-adds per batch at `per_call` multiply-adds per call.
fn batch(work: f64, per_call: f64) -> usize {
    ((work / per_call).round() as usize).max(1)
}

fn main() {
    let kernel = Kernel::detect().path().name();
    let peers = read_peers();
    let mut all = serde_json::Map::new();
    println!("kernel path: {kernel}; accuracy: {EPS:e} relative\n");
    for preset in MHE_PRESETS {
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
    let out = json!({ "kernel_path": kernel, "eps": EPS, "presets": all });
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

/// Batch: `batch` iterations of `map` in one `run_steps`, from the first instance.
fn step_variant<'a, M: IterationMap>(
    name: String,
    map: &'a M,
    inst: &MheInstance,
    batch: usize,
) -> Variant<'a> {
    let mut s = map.new_state();
    map.load(&mut s, &inst.theta);
    map.warm_start(&mut s, &inst.z0, None);
    Variant {
        name,
        per_call: batch as f64,
        run: Box::new(move || {
            map.run_steps(black_box(&mut s), batch);
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

/// Batch: `batch` full MHE steps at t = T (idempotent `estimate`).
fn mhe_variant<'a, M: IterationMap + 'a>(
    name: String,
    mut est: mhe_core::MheEstimator<M>,
    batch: usize,
) -> Variant<'a> {
    Variant {
        name,
        per_call: batch as f64,
        run: Box::new(move || {
            for _ in 0..batch {
                let _ = black_box(est.estimate());
            }
        }),
    }
}

/// The reference kernel at the preset's size (compile-time n: 29, 49 and 58 are instantiated).
fn reference_variant<'a>(h: &[f64], n: usize, batch: usize) -> Option<Variant<'a>> {
    fn make<'a, const N: usize>(h: &[f64], batch: usize) -> Option<Variant<'a>> {
        let k = FixedMatVec::<N>::new(h, FixedLayout::ColumnAxpy)?;
        let x: [f64; N] = std::array::from_fn(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5);
        let mut y = [0.0; N];
        Some(Variant {
            name: "ref".into(),
            per_call: batch as f64,
            run: Box::new(move || {
                for _ in 0..batch {
                    k.apply(black_box(&x), &mut y);
                    black_box(&mut y);
                }
            }),
        })
    }
    match n {
        29 => make::<29>(h, batch),
        49 => make::<49>(h, batch),
        58 => make::<58>(h, batch),
        _ => None,
    }
}

/// One method of the bench on one preset: its map, certificate K and what is affordable.
struct Row {
    name: &'static str,
    method: Method,
    map: MethodMap,
    k_cert: usize,
    /// K_min of Theorem 1 (None: the certificate is void for this method).
    k_min: Option<usize>,
    /// The K_reg search (None: not asked for on this preset).
    k_reg: Option<KRegSearch>,
    /// The per-instance rows run (K·n² ≤ INSTANCE_WORK).
    per_instance: bool,
    /// The MHE-step row runs (K·n² ≤ MHE_WORK).
    mhe: bool,
}

/// One method's K_reg search.
struct KRegSearch {
    /// K_reg (None: `note` says why).
    k_reg: Option<usize>,
    /// The largest K the search could try.
    k_max: usize,
    /// Every K evaluated with its margin (≥ 1: the region contains the uncertainty).
    tried: Vec<(usize, f64)>,
    /// Why there is no K_reg: the search's void or stop text.
    note: Option<String>,
    /// Why the search stopped early (with a K_reg: certified, possibly not the smallest).
    stopped: Option<String>,
    /// Wall seconds of the search.
    seconds: f64,
}

/// A witness row in words: an admissible realization drives it past its bound.
fn witness_text(w: &Limit) -> String {
    format!(
        "; a witness (an admissible realization) takes {:?} row {} of inner iterate {} at {} to \
         {:.4} against its bound {}",
        w.row.kind,
        w.row.index,
        w.row.iterate,
        w.row
            .step
            .map_or("the full window".into(), |t| format!("t = {t}")),
        w.attained,
        w.bound
    )
}

/// K_reg of `method` as `reproduce` searches it, so the bench times the K it reports: the
/// scenario's own uncertainty and controller, `certificate.phase_seconds` split evenly over
/// `share` methods, K up to `iss_certificate::regional::search_max` (the cap `reproduce` uses).
fn k_reg_search(
    resolved: &ResolvedScenario,
    method: Method,
    k_min: Option<usize>,
    n_z: usize,
    share: usize,
) -> KRegSearch {
    let k_max = search_max(k_min, n_z).0;
    let started = std::time::Instant::now();
    let controller = LoopOptions::from_scenario(resolved.scenario())
        .map_or(ControllerChoice::ExactMpc, |o| o.controller);
    let result = RegionalOptions::from_scenario(resolved, controller).and_then(|o| {
        let o = RegionalOptions {
            phase_seconds: o.phase_seconds / share as f64,
            ..o
        };
        k_reg(resolved, method, &o, k_max)
    });
    let mut out = KRegSearch {
        k_reg: None,
        k_max,
        tried: Vec::new(),
        note: None,
        stopped: None,
        seconds: 0.0,
    };
    match result {
        Err(e) => out.note = Some(e.to_string()),
        Ok(kr) => {
            let last = kr
                .certificate
                .as_ref()
                .map(|c| c.k)
                .or_else(|| kr.tried.last().map(|t| t.0));
            let at = last.map_or(String::new(), |k| format!(" (largest K evaluated: {k})"));
            out.note = match (kr.k_reg, &kr.stopped, &kr.void, &kr.certificate) {
                (Some(_), ..) => None,
                (None, ..) if kr.refuted_every_k.is_some() => Some(format!(
                    "a witness on a row free of K (t = 0, or the MHE's first inner iterates at \
                     t = 1) refutes every K{}",
                    kr.refuted_every_k
                        .as_ref()
                        .map_or(String::new(), witness_text)
                )),
                (None, Some(why), ..) => Some(format!("the search stopped{at}: {why}")),
                (None, None, Some(why), _) => Some(format!("void{at}: {why}")),
                (None, None, None, Some(c)) => Some(format!(
                    "no K ≤ {k_max} whose region contains the scenario's uncertainty; at K = {}: \
                     certified scale {:.3}× the scenario's{}",
                    c.k,
                    c.margin.max(0.0),
                    c.witness.as_ref().map_or(String::new(), witness_text)
                )),
                (None, None, None, None) => Some("no K was evaluated".into()),
            };
            out.k_reg = kr.k_reg;
            out.tried = kr.tried;
            out.stopped = kr.stopped.as_ref().map(ToString::to_string);
        }
    }
    out.seconds = started.elapsed().as_secs_f64();
    out
}

/// [`k_reg_search`] of every `(method, K_min)` in `jobs`, in that order, on as many threads
/// as the machine has: the searches are independent and take tens of seconds each.
fn k_reg_searches(
    resolved: &ResolvedScenario,
    jobs: &[(Method, Option<usize>)],
    n_z: usize,
) -> Vec<KRegSearch> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, KRegSearch)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.min(jobs.len()))
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(&(method, k_min)) = jobs.get(i) else {
                            break;
                        };
                        mine.push((i, k_reg_search(resolved, method, k_min, n_z, jobs.len())));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    done.sort_by_key(|d| d.0);
    done.into_iter().map(|d| d.1).collect()
}

fn run_preset(qps: &CaseStudyQps) -> Result<Value, String> {
    let qp = &qps.qp;
    let n = qp.n();
    let n2 = (n * n) as f64;
    let inst = &qps.instances;
    let fixture = |e: benches::case_study::FixtureError| e.to_string();
    // K_min of Theorem 1 from the certified constants (the sampled estimates are skipped:
    // they do not enter K_min).
    let opts = CertificateOptions {
        solvers: METHODS.iter().map(|(_, m)| *m).collect(),
        gamma13_sequences: 0,
        lipschitz_pairs: 0,
        ..CertificateOptions::default()
    };
    let closed_loop_cert = certify_closed_loop(&qps.resolved, &opts).map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    for (name, method) in METHODS {
        let map = method.build(qp.clone()).map_err(|e| e.to_string())?;
        let k_cert = certified_k(&map).map_err(fixture)?;
        let work = k_cert as f64 * n2;
        let k_min = closed_loop_cert
            .solvers
            .iter()
            .find(|c| c.solver == method)
            .and_then(|c| c.k_min);
        rows.push(Row {
            name,
            method,
            map,
            k_cert,
            k_min,
            k_reg: None,
            per_instance: work <= INSTANCE_WORK,
            mhe: work <= MHE_WORK,
        });
    }
    let mut k_reg_s = None;
    if qps.preset.k_reg {
        let started = std::time::Instant::now();
        let jobs: Vec<_> = rows.iter().map(|r| (r.method, r.k_min)).collect();
        for (r, s) in rows.iter_mut().zip(k_reg_searches(&qps.resolved, &jobs, n)) {
            r.k_reg = Some(s);
        }
        k_reg_s = Some(started.elapsed().as_secs_f64());
    }
    let mut ks: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    let mut worst_at_cert = BTreeMap::new();
    for r in rows.iter().filter(|r| r.per_instance) {
        let k: Result<Vec<usize>, String> =
            inst.iter().map(|i| iterations_to_eps(&r.map, i)).collect();
        ks.insert(r.name, k?);
        worst_at_cert.insert(r.name, worst_error_at(&r.map, inst, r.k_cert));
    }
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
    let mut estimators = Vec::new();
    for r in rows.iter().filter(|r| r.mhe) {
        let method = r.method;
        let est = qps
            .estimator_at_end(r.k_cert, |q| method.build(q))
            .map_err(fixture)?;
        let b = batch(MHE_BATCH_WORK, r.k_cert as f64 * n2);
        estimators.push((format!("mhe/{}", r.name), est, b));
    }
    for r in rows.iter().filter(|r| r.per_instance) {
        if let Some(k) = r.k_min.filter(|&k| k != r.k_cert) {
            let method = r.method;
            let est = qps
                .estimator_at_end(k, |q| method.build(q))
                .map_err(fixture)?;
            let b = batch(MHE_BATCH_WORK, k as f64 * n2);
            estimators.push((format!("mhe_kmin/{}", r.name), est, b));
        }
    }
    for r in &rows {
        let Some(k) = r.k_reg.as_ref().and_then(|s| s.k_reg) else {
            continue;
        };
        if k as f64 * n2 <= MHE_WORK {
            let method = r.method;
            let est = qps
                .estimator_at_end(k, |q| method.build(q))
                .map_err(fixture)?;
            let b = batch(MHE_BATCH_WORK, k as f64 * n2);
            estimators.push((format!("mhe_kreg/{}", r.name), est, b));
        }
    }

    let step_batch = batch(STEP_WORK, n2);
    let h = qp.h_row_major().to_vec();
    let mut variants = Vec::new();
    if let Some(v) = reference_variant(&h, n, step_batch) {
        variants.push(v);
    }
    {
        let hp = PaddedSymmetric::from_row_major(&h, n).ok_or("H is n × n")?;
        let (x, mut y) = (AlignedVec::padded(&inst[0].z0), AlignedVec::zeros(hp.ld()));
        let k = Kernel::detect();
        variants.push(Variant {
            name: "matvec_padded".into(),
            per_call: step_batch as f64,
            run: Box::new(move || {
                for _ in 0..step_batch {
                    k.matvec_padded(&hp, black_box(&x), &mut y);
                    black_box(&mut y);
                }
            }),
        });
    }
    for r in &rows {
        variants.push(step_variant(
            format!("step/{}", r.name),
            &r.map,
            &inst[0],
            step_batch,
        ));
    }
    for r in rows.iter().filter(|r| r.per_instance) {
        variants.push(solve_variant(
            format!("to_eps/{}", r.name),
            &r.map,
            inst,
            ks[r.name].clone(),
        ));
    }
    for r in rows.iter().filter(|r| r.per_instance) {
        variants.push(solve_variant(
            format!("cert/{}", r.name),
            &r.map,
            inst,
            vec![r.k_cert; inst.len()],
        ));
    }
    for (name, est, b) in estimators {
        variants.push(mhe_variant(name, est, b));
    }
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
    let rounds = rounds(n);
    let started = std::time::Instant::now();
    let times = interleave(&mut variants, rounds);
    let elapsed_s = started.elapsed().as_secs_f64();
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
    let methods: serde_json::Map<String, Value> = rows
        .iter()
        .map(|r| {
            let work = r.k_cert as f64 * n2;
            (
                r.name.to_string(),
                json!({
                    "method": r.method.name(),
                    "k_cert": r.k_cert,
                    "k_min_theorem1": r.k_min,
                    "k_reg": r.k_reg.as_ref().and_then(|s| s.k_reg),
                    "k_reg_search": r.k_reg.as_ref().map(|s| json!({
                        "k_max": s.k_max,
                        "tried": s.tried,
                        "note": s.note,
                        "stopped": s.stopped,
                        "seconds": s.seconds,
                    })),
                    "k_to_eps": ks.get(r.name).map(|k| stats(k)),
                    "worst_rel_error_at_k_cert": worst_at_cert.get(r.name),
                    "per_instance_rows": r.per_instance,
                    "mhe_row": r.mhe,
                    "work_k_n2": work,
                    "mhe_batch": r.mhe.then(|| batch(MHE_BATCH_WORK, work)),
                }),
            )
        })
        .collect();
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
        "rounds": rounds,
        "step_batch": step_batch,
        "timing_s": elapsed_s,
        "k_reg_search_s": k_reg_s,
        "methods": methods,
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
        "### Preset `{name}` ({}{}): M = {}, n = {}, n_θ = {}, κ = {:.3e}, {} instances (t = {}…{}), {} rounds in {:.0} s\n",
        qps.preset.file,
        qps.preset
            .horizon
            .map_or(String::new(), |m| format!(" with M = {m}")),
        v["horizon"],
        v["n"],
        v["n_theta"],
        v["kappa"].as_f64().unwrap_or(f64::NAN),
        v["instances"],
        v["t_range"][0],
        v["t_range"][1],
        v["rounds"],
        v["timing_s"].as_f64().unwrap_or(f64::NAN),
    );
    let r = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => format!("{:.2}×", a / b),
        _ => "—".into(),
    };
    let base_row = if t("ref").is_some() {
        "ref"
    } else {
        "matvec_padded"
    };
    println!(
        "Per iteration (`run_steps` of {} steps, fastest batch of {}):\n",
        v["step_batch"], v["rounds"]
    );
    println!("| variant | time | ratio to `{base_row}` | Jacobi-scaled / plain |");
    println!("| --- | ---: | ---: | ---: |");
    for row in ["ref", "matvec_padded"] {
        if let Some(x) = t(row) {
            println!(
                "| `{row}` | {} | {} | |",
                fmt_ns(x),
                r(Some(x), t(base_row))
            );
        }
    }
    for (m, _) in METHODS {
        let row = format!("step/{m}");
        if let Some(x) = t(&row) {
            let plain = m.strip_suffix("_jacobi").map(|p| t(&format!("step/{p}")));
            println!(
                "| `{row}` | {} | {} | {} |",
                fmt_ns(x),
                r(Some(x), t(base_row)),
                plain.map_or(String::new(), |p| r(Some(x), p)),
            );
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
    // K_reg columns only where the preset searched it.
    let with_kreg = v["k_reg_search_s"].is_number();
    let (kreg_head, kreg_align, kreg_blank) = if with_kreg {
        (
            format!(" K_reg | MHE step at K_reg | / {base_name} |"),
            " ---: | ---: | ---: |",
            " | | |",
        )
    } else {
        (String::new(), "", "")
    };
    println!(
        "| method | K to 1e-6 (median / max) | time to 1e-6 | certificate K | QP at certificate K | MHE step at certificate K | MHE step / {base_name} | Theorem 1 K_min | MHE step at K_min | / {base_name} |{kreg_head}"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |{kreg_align}");
    let mut skipped = Vec::new();
    let mut kreg_notes = Vec::new();
    for (m, _) in METHODS {
        let d = &v["methods"][m];
        let k = &d["k_to_eps"];
        let kk = if k.is_null() {
            "—".to_string()
        } else {
            format!("{} / {}", k["median"], k["max"])
        };
        let mhe = t(&format!("mhe/{m}"));
        // At K_min: its own row, or the certificate-K row when the two K agree.
        let kmin = d["k_min_theorem1"].as_u64();
        let mhe_kmin =
            t(&format!("mhe_kmin/{m}")).or_else(|| mhe.filter(|_| kmin == d["k_cert"].as_u64()));
        let kreg = if with_kreg {
            let x = t(&format!("mhe_kreg/{m}"));
            format!(
                " {} | {} | {} |",
                d["k_reg"].as_u64().map_or("none".into(), |k| k.to_string()),
                x.map_or("—".into(), fmt_ns),
                r(x, base)
            )
        } else {
            String::new()
        };
        println!(
            "| {m} | {kk} | {} | {} | {} | {} | {} | {} | {} | {} |{kreg}",
            t(&format!("to_eps/{m}")).map_or("—".into(), fmt_ns),
            d["k_cert"],
            t(&format!("cert/{m}")).map_or("—".into(), fmt_ns),
            mhe.map_or("—".into(), fmt_ns),
            r(mhe, base),
            kmin.map_or("void".into(), |k| k.to_string()),
            mhe_kmin.map_or("—".into(), fmt_ns),
            r(mhe_kmin, base),
        );
        let search = &d["k_reg_search"];
        if let Some(note) = search["note"].as_str() {
            kreg_notes.push(format!(
                "- {m} (searched up to K = {}): {note}",
                search["k_max"]
            ));
        } else if let Some(why) = search["stopped"].as_str() {
            kreg_notes.push(format!(
                "- {m}: K_reg = {} is certified, possibly not the smallest (the bisection below \
                 it stopped: {why})",
                d["k_reg"]
            ));
        }
        if d["per_instance_rows"] == false {
            skipped.push(format!(
                "{m} (K·n² = {:.1e}{})",
                d["work_k_n2"].as_f64().unwrap_or(f64::NAN),
                if d["mhe_row"] == false {
                    ": no row timed"
                } else {
                    ": MHE step only"
                }
            ));
        }
    }
    let c = &v["clarabel"];
    println!(
        "| Clarabel (IPM, tol 1e-8) | {} / {} IPM it. | {} | — | — | — | {} | | | |{kreg_blank}",
        c["ipm_iterations"]["median"],
        c["ipm_iterations"]["max"],
        t("clarabel").map_or("—".into(), fmt_ns),
        r(t("clarabel"), base),
    );
    for (key, label) in [
        ("daqp", "DAQP (cold)"),
        ("osqp", "OSQP (warm)"),
        ("osqp_sparse", "OSQP (warm, uncondensed)"),
        ("proxqp", "ProxQP (warm)"),
    ] {
        let p = &peers[key];
        if let Some(s) = p["solve_ns"]["min"].as_f64() {
            let label = match p["tolerance"].as_f64() {
                Some(tol) => format!("{label}, tol {tol:.0e}"),
                None => label.to_string(),
            };
            println!(
                "| {label} | {} / {} it. | {} (error {:.0e}) | — | — | — | {} | | | |{kreg_blank}",
                p["iterations"]["median"],
                p["iterations"]["max"],
                fmt_ns(s),
                p["worst_rel_error"].as_f64().unwrap_or(f64::NAN),
                r(Some(s), base),
            );
        }
    }
    if !skipped.is_empty() {
        println!(
            "\nLeft out of the per-instance rows (K·n² > {INSTANCE_WORK:.0e}; MHE step only if ≤ {MHE_WORK:.0e}): {}.",
            skipped.join(", ")
        );
    }
    if with_kreg {
        println!(
            "\nK_reg: the smallest K whose regional certificate contains the scenario's own \
             uncertainty (`iss_certificate::regional::k_reg` as `reproduce` runs it: the scenario's controller, \
             `certificate.phase_seconds` split over the {} methods, K up to K_min; searched in \
             {:.0} s).",
            METHODS.len(),
            v["k_reg_search_s"].as_f64().unwrap_or(f64::NAN)
        );
        if !kreg_notes.is_empty() {
            println!("\nThe search's notes:\n\n{}", kreg_notes.join("\n"));
        }
    }
    if let Some(d) = daqp {
        for (prefix, what) in [
            ("mhe", "its certificate K for 1e-6"),
            ("mhe_kmin", "its Theorem 1 K_min"),
        ] {
            let best = METHODS
                .into_iter()
                .filter_map(|(m, _)| {
                    let own = t(&format!("{prefix}/{m}"));
                    // K_min equal to the certificate K: the `mhe` row is the K_min row.
                    let same = (prefix == "mhe_kmin"
                        && v["methods"][m]["k_min_theorem1"] == v["methods"][m]["k_cert"])
                        .then(|| t(&format!("mhe/{m}")))
                        .flatten();
                    Some((m, own.or(same)?))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((m, x)) = best {
                println!(
                    "\nTarget (one MHE step of the fastest method at {what} ≤ DAQP's exact solve): {} — {m} {} vs DAQP {} ({:.2}×).",
                    if x <= d { "met" } else { "missed" },
                    fmt_ns(x),
                    fmt_ns(d),
                    x / d
                );
            }
        }
        let best = METHODS
            .into_iter()
            .filter_map(|(m, _)| Some((m, t(&format!("mhe_kreg/{m}"))?)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((m, x)) = best {
            println!(
                "\nFastest MHE step at K_reg (no target): {m} (K_reg = {}) {} vs DAQP {} ({:.2}×).",
                v["methods"][m]["k_reg"],
                fmt_ns(x),
                fmt_ns(d),
                x / d
            );
        }
    }
    let worst: Vec<String> = METHODS
        .into_iter()
        .filter_map(|(m, _)| {
            let w = v["methods"][m]["worst_rel_error_at_k_cert"].as_f64()?;
            Some(format!("{m} {w:.1e}"))
        })
        .collect();
    println!(
        "\nWorst ‖zᴷ − z*‖/‖z⁰ − z*‖ over the instances at the certificate K: {}; Clarabel {:.1e}.\n",
        worst.join(", "),
        c["worst_rel_error"].as_f64().unwrap_or(f64::NAN),
    );
}
