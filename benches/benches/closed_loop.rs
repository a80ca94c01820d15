//! Where a closed-loop run's time goes, all timed interleaved in one run
//! ([`benches::interleave`]), per case-study preset (paper: M = 5, K = 652; certified:
//! M = 9, K = 239; PG, T = 40, exact MHE solve off — the scenario files' own settings):
//!
//! - `run/exact-mpc`: one whole run of Alg. 1 (`reseed` + `run`: MHE with K iterations,
//!   the exact MPC, plant, disturbance, trace) — what `cargo xtask sweep` times per run;
//! - `run/saturated-lqr`: the same run with the saturated LQR as controller;
//! - `iterations`: T·K steps of the same PG map on the preset's window-M MHE QP (T loads +
//!   warm starts + K steps each) — the budget "T·K·(per-iteration time)" of issue 6;
//! - `mpc/active-set`: one exact MPC call, warm-started (the default backend), mean over
//!   the run's x̂_t; `mpc/active-set-cold`: the same after `reset()` each call;
//!   `mpc/clarabel`: the Clarabel backend on the same x̂_t.
//!
//! Output: a markdown table per preset, JSON in `target/bench-results/closed_loop.json`.
//! Run: `cargo bench -p benches --bench closed_loop` (≈ 1 min).

use std::hint::black_box;

use benches::case_study::{CaseStudyQps, PRESETS};
use benches::{Variant, interleave};
use closed_loop::scenario::{ControllerChoice, LoopOptions};
use mpc_core::{Controller, ExactMpc};
use qp_iter::IterationMap;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::ReferenceSettings;
use serde_json::json;

const ROUNDS: usize = 150;

fn main() {
    let mut all = serde_json::Map::new();
    for preset in PRESETS {
        let qps = match CaseStudyQps::load(preset) {
            Ok(q) => q,
            Err(e) => {
                eprintln!("closed_loop bench: preset {}: {e}", preset.name);
                std::process::exit(1);
            }
        };
        let r = &qps.resolved;
        let base = match LoopOptions::from_scenario(r.scenario()) {
            Ok(o) => o,
            Err(e) => {
                eprintln!("closed_loop bench: {e}");
                std::process::exit(1);
            }
        };
        let (t_steps, k) = (base.steps, base.iterations.get());
        let build = |controller| {
            let mut o = base;
            o.controller = controller;
            r.build_loop(&o).unwrap_or_else(|e| {
                eprintln!("closed_loop bench: {e}");
                std::process::exit(1)
            })
        };
        let mut run_exact = build(ControllerChoice::ExactMpc);
        let mut run_lqr = build(ControllerChoice::SaturatedLqr);
        let x_hats: Vec<Vec<f64>> = {
            let trace = run_exact.run().expect("case-study run");
            (0..trace.len())
                .filter_map(|t| trace.x_hat(t).map(<[f64]>::to_vec))
                .collect()
        };
        let mpc = r.mpc().expect("the scenario's MPC").clone();
        let mut warm = ExactMpc::new(&mpc).expect("active-set MPC");
        let mut cold = ExactMpc::new(&mpc).expect("active-set MPC");
        let mut clarabel =
            ExactMpc::with_settings(&mpc, ReferenceSettings::default()).expect("Clarabel MPC");
        let pg = ProjectedGradient::new(qps.qp.clone(), StepRule::Optimal).expect("PG map");
        let mut state = pg.new_state();
        let instances = &qps.instances;
        let seed = base.seed;
        let nu = mpc.nu();
        let n_calls = x_hats.len() as f64;

        let mut variants = vec![
            Variant {
                name: "run/exact-mpc".into(),
                per_call: 1.0,
                run: Box::new(|| {
                    run_exact.reseed(seed).expect("reseed");
                    black_box(run_exact.run().expect("run").sup_norm_e());
                }),
            },
            Variant {
                name: "run/saturated-lqr".into(),
                per_call: 1.0,
                run: Box::new(|| {
                    run_lqr.reseed(seed).expect("reseed");
                    black_box(run_lqr.run().expect("run").sup_norm_e());
                }),
            },
            Variant {
                name: "iterations".into(),
                per_call: 1.0,
                run: Box::new(|| {
                    for t in 0..t_steps {
                        let inst = &instances[t % instances.len()];
                        pg.load(&mut state, &inst.theta);
                        pg.warm_start(&mut state, &inst.z0, None);
                        for _ in 0..k {
                            pg.step(&mut state);
                        }
                    }
                    black_box(pg.iterate(&state));
                }),
            },
            Variant {
                name: "mpc/active-set".into(),
                per_call: n_calls,
                run: Box::new(|| {
                    let mut u = vec![0.0; nu];
                    for x in &x_hats {
                        warm.control(x, &mut u).expect("active set");
                    }
                    black_box(&u);
                }),
            },
            Variant {
                name: "mpc/active-set-cold".into(),
                per_call: n_calls,
                run: Box::new(|| {
                    let mut u = vec![0.0; nu];
                    for x in &x_hats {
                        cold.reset();
                        cold.control(x, &mut u).expect("active set");
                    }
                    black_box(&u);
                }),
            },
            Variant {
                name: "mpc/clarabel".into(),
                per_call: n_calls,
                run: Box::new(|| {
                    let mut u = vec![0.0; nu];
                    for x in &x_hats {
                        clarabel.control(x, &mut u).expect("Clarabel");
                    }
                    black_box(&u);
                }),
            },
        ];
        let times = interleave(&mut variants, ROUNDS);
        let names: Vec<String> = variants.iter().map(|v| v.name.clone()).collect();
        drop(variants);
        let get = |name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .map(|i| times[i])
                .expect("variant")
        };
        let budget = get("iterations").min_ns;
        let t_iter = budget / (t_steps * k) as f64;
        let as_warm = get("mpc/active-set").min_ns;
        println!(
            "\n### Preset `{}`: M = {}, n = {}, PG, K = {k}, T = {t_steps}, exact MPC N·n_u = {} \
             (fastest batch of {ROUNDS}; fallbacks to Clarabel: {})\n",
            preset.name,
            qps.config.horizon,
            qps.qp.n(),
            mpc.qp().n(),
            warm.fallbacks() + cold.fallbacks()
        );
        println!("| row | fastest batch | median batch | ratio |");
        println!("| --- | ---: | ---: | --- |");
        let mut rows = serde_json::Map::new();
        for (name, t) in names.iter().zip(&times) {
            let ratio = match name.as_str() {
                n if n.starts_with("run/") => {
                    format!("{:.2}× T·K·t_iter", t.min_ns / budget)
                }
                "iterations" => format!("T·K·t_iter, t_iter = {t_iter:.1} ns"),
                n if n.starts_with("mpc/") => format!("{:.1}× active set", t.min_ns / as_warm),
                _ => String::new(),
            };
            println!(
                "| `{name}` | {} | {} | {ratio} |",
                fmt_ns(t.min_ns),
                fmt_ns(t.median_ns)
            );
            rows.insert(
                name.clone(),
                json!({ "min_ns": t.min_ns, "median_ns": t.median_ns }),
            );
        }
        all.insert(
            preset.name.into(),
            json!({
                "k": k, "steps": t_steps, "n": qps.qp.n(), "t_iter_ns": t_iter,
                "run_exact_over_budget": get("run/exact-mpc").min_ns / budget,
                "run_lqr_over_budget": get("run/saturated-lqr").min_ns / budget,
                "clarabel_over_active_set": get("mpc/clarabel").min_ns / as_warm,
                "rows": rows,
            }),
        );
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench-results");
    let out = dir.join("closed_loop.json");
    let text = serde_json::to_string_pretty(&serde_json::Value::Object(all)).unwrap_or_default();
    if let Err(e) = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&out, text)) {
        eprintln!("closed_loop bench: could not write {}: {e}", out.display());
    } else {
        println!("\nJSON: {}", out.display());
    }
}

fn fmt_ns(ns: f64) -> String {
    if ns >= 1e6 {
        format!("{:.3} ms", ns / 1e6)
    } else if ns >= 1e3 {
        format!("{:.2} µs", ns / 1e3)
    } else {
        format!("{ns:.1} ns")
    }
}
