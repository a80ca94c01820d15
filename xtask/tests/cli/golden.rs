#![allow(clippy::unwrap_used)]
//! Golden outputs: `reproduce` (both presets) and the smoke sweep must keep producing the
//! numbers they produced before the architecture refactor (issue 10), bit for bit; the 2-D
//! smoke sweep those it produced when it was added (issue 16).
//!
//! The golden files under `tests/golden/` are gzip'd copies of `certificate.json` and
//! `trace.json` of both presets and of `points.csv` / `runs.csv` of `sweeps/smoke.toml` and
//! `sweeps/smoke-2d.toml`.
//! Provenance and host records and every `wall_*` value (timings) are excluded from the
//! comparison; every other number must be identical.
//!
//! A change that is meant to change outputs regenerates them deliberately:
//! `UPDATE_GOLDEN=1 cargo test --release -p xtask --test cli golden:: -- --include-ignored`
//! rewrites the files from this run (the reproduce and 2-D comparisons are `long_` runs,
//! outside the README's test command; `.ci/run` runs them), and the commit says why the
//! numbers moved.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn out_dir(name: &str) -> PathBuf {
    let dir = crate::test_dir::test_dir("golden", name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn read_gz(path: &Path) -> String {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut text = String::new();
    flate2::read::GzDecoder::new(&bytes[..])
        .read_to_string(&mut text)
        .unwrap();
    text
}

fn write_gz(path: &Path, text: &str) {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    enc.write_all(text.as_bytes()).unwrap();
    std::fs::write(path, enc.finish().unwrap()).unwrap();
}

/// Keys whose values depend on the machine or the moment, not on the computation.
fn excluded(key: &str) -> bool {
    matches!(key, "provenance" | "host") || key.starts_with("wall_")
}

/// Every difference between `golden` and `new` at `path`, numbers compared bit for bit.
fn diff_json(path: &str, golden: &Value, new: &Value, out: &mut Vec<String>) {
    if out.len() > 20 {
        return;
    }
    match (golden, new) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, va) in a {
                if excluded(k) {
                    continue;
                }
                match b.get(k) {
                    Some(vb) => diff_json(&format!("{path}.{k}"), va, vb, out),
                    None => out.push(format!("{path}.{k}: missing in the new output")),
                }
            }
            for k in b.keys() {
                if !excluded(k) && !a.contains_key(k) {
                    out.push(format!("{path}.{k}: new key"));
                }
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            if a.len() != b.len() {
                out.push(format!("{path}: length {} → {}", a.len(), b.len()));
            }
            for (i, (va, vb)) in a.iter().zip(b).enumerate() {
                diff_json(&format!("{path}[{i}]"), va, vb, out);
            }
        }
        (Value::Number(a), Value::Number(b)) => {
            let (x, y) = (a.as_f64(), b.as_f64());
            let same = match (x, y) {
                (Some(x), Some(y)) => x.to_bits() == y.to_bits(),
                _ => a == b,
            };
            if !same {
                out.push(format!("{path}: {a} → {b}"));
            }
        }
        (a, b) if a == b => {}
        (a, b) => out.push(format!("{path}: {a} → {b}")),
    }
}

/// Every differing cell of two CSV texts, `wall_*` columns excluded.
fn diff_csv(name: &str, golden: &str, new: &str, out: &mut Vec<String>) {
    let (ga, na): (Vec<&str>, Vec<&str>) = (golden.lines().collect(), new.lines().collect());
    if ga.first() != na.first() {
        out.push(format!("{name}: header changed"));
        return;
    }
    let header: Vec<&str> = ga[0].split(',').collect();
    if ga.len() != na.len() {
        out.push(format!("{name}: {} rows → {}", ga.len(), na.len()));
    }
    for (r, (a, b)) in ga.iter().zip(&na).enumerate().skip(1) {
        for (c, (x, y)) in a.split(',').zip(b.split(',')).enumerate() {
            let col = header.get(c).copied().unwrap_or("?");
            if x != y && !col.starts_with("wall_") && out.len() <= 20 {
                out.push(format!("{name} row {r} `{col}`: {x} → {y}"));
            }
        }
    }
}

fn check(files: &[(&str, PathBuf)]) {
    let update = std::env::var_os("UPDATE_GOLDEN").is_some();
    let mut diffs = Vec::new();
    for (golden_name, new_path) in files {
        let new = std::fs::read_to_string(new_path)
            .unwrap_or_else(|e| panic!("{}: {e}", new_path.display()));
        let golden_path = golden_dir().join(format!("{golden_name}.gz"));
        if update {
            write_gz(&golden_path, &new);
            continue;
        }
        let golden = read_gz(&golden_path);
        if golden_name.ends_with(".json") {
            let (g, n): (Value, Value) = (
                serde_json::from_str(&golden).unwrap(),
                serde_json::from_str(&new).unwrap(),
            );
            diff_json(golden_name, &g, &n, &mut diffs);
        } else {
            diff_csv(golden_name, &golden, &new, &mut diffs);
        }
    }
    assert!(
        diffs.is_empty(),
        "outputs differ from the golden files (UPDATE_GOLDEN=1 regenerates them, if the \
         change is meant):\n{}",
        diffs.join("\n")
    );
}

fn xtask(args: &[&str], out: &Path) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let status = Command::new(crate::shared::xtask_bin())
        // The golden files hold the portable kernel's bits (the AVX2 path rounds differently).
        .env("QP_ITER_KERNEL", "portable")
        .current_dir(&root)
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "xtask {args:?}: {}",
        String::from_utf8_lossy(&status.stderr)
    );
}

/// The key paths of a JSON document, array indices written `[]` (`/solvers/[]/k_min`).
fn key_paths(v: &Value, prefix: &str, out: &mut std::collections::BTreeSet<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{prefix}/{k}");
                out.insert(p.clone());
                key_paths(x, &p, out);
            }
        }
        Value::Array(a) => {
            for x in a {
                key_paths(x, &format!("{prefix}/[]"), out);
            }
        }
        _ => {}
    }
}

/// The key paths of `docs` (their union) match the schema's checked-in list
/// `crates/certificate-json/keys/<name>.txt`: the documents are `certificate_json::v1`'s, and a
/// key appears or disappears only with a reviewed diff of that list (`UPDATE_GOLDEN=1`
/// rewrites it). The library's types are not the schema (docs/certificate-json.md).
fn check_keys(name: &str, docs: &[PathBuf]) {
    let mut keys = std::collections::BTreeSet::new();
    for d in docs {
        let text = std::fs::read_to_string(d).unwrap_or_else(|e| panic!("{}: {e}", d.display()));
        key_paths(&serde_json::from_str(&text).unwrap(), "", &mut keys);
    }
    let text: String = keys.iter().map(|k| format!("{k}\n")).collect();
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../crates/certificate-json/keys")
        .join(format!("{name}.txt"));
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &text).unwrap();
        return;
    }
    let old = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (old, new): (
        std::collections::BTreeSet<&str>,
        std::collections::BTreeSet<&str>,
    ) = (old.lines().collect(), text.lines().collect());
    let gone: Vec<_> = old.difference(&new).collect();
    let added: Vec<_> = new.difference(&old).collect();
    assert!(
        gone.is_empty() && added.is_empty(),
        "the keys of {name} changed (a schema change: certificate_json::v1, \
         docs/certificate-json.md; UPDATE_GOLDEN=1 rewrites {}):\n- {gone:?}\n+ {added:?}",
        path.display()
    );
}

#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_reproduce_outputs_match_the_golden_files() {
    // `xtask reproduce` on the portable kernel, shared with the export test that replays the
    // certified preset's trace.csv (`crate::shared::reproduce`: the same command, once per
    // test binary).
    let out = crate::shared::reproduce();
    let mut files = Vec::new();
    for preset in ["paper", "certified"] {
        for file in ["certificate", "trace"] {
            files.push((
                Box::leak(format!("{preset}-{file}.json").into_boxed_str()) as &str,
                out.join(preset).join(format!("{file}.json")),
            ));
        }
    }
    check(&files);
    check_keys(
        "certificate",
        &["paper", "certified"].map(|p| out.join(p).join("certificate.json")),
    );
}

/// `certify`'s JSON has the keys of `certificate_json::v1::IossCertificate` (a scenario that
/// passes with an MPC, one whose controller's L_π is skipped, and one with `--loop`).
#[test]
fn certify_json_keys_match_the_schema() {
    let out = out_dir("certify");
    std::fs::create_dir_all(&out).unwrap();
    let mut docs = Vec::new();
    // The double integrator with `--loop` (a global budget too small to search: the
    // section's keys are the same for every verdict) brings `loop_methods`' keys.
    let loop_flags: &[&str] = &["--loop", "--global-seconds", "0.001"];
    for (s, flags) in [
        ("case-study", &[][..]),
        ("mass-chain-state-box", &[][..]),
        ("double-integrator", loop_flags),
    ] {
        let json = out.join(format!("{s}.json"));
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
        let status = Command::new(crate::shared::xtask_bin())
            .current_dir(&root)
            .args([
                "certify",
                "--scenario",
                &format!("scenarios/{s}.toml"),
                "--json",
            ])
            .arg(&json)
            .args(flags)
            .output()
            .unwrap();
        assert!(
            json.exists(),
            "certify {s}: {}",
            String::from_utf8_lossy(&status.stderr)
        );
        docs.push(json);
    }
    check_keys("ioss-certificate", &docs);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn smoke_sweep_outputs_match_the_golden_files() {
    let out = out_dir("smoke");
    xtask(&["sweep", "--config", "sweeps/smoke.toml"], &out);
    check(&[
        ("smoke-points.csv", out.join("points.csv")),
        ("smoke-runs.csv", out.join("runs.csv")),
    ]);
    let _ = std::fs::remove_dir_all(&out);
}

/// The 2-D smoke sweep over (K_e, K_c) (`sweeps/smoke-2d.toml`): the `k_c` column, the
/// sub-optimal MPC at each K_c and ρ_lin(K_e, K_c) pinned like the 1-D smoke sweep. The run
/// is shared with `sweep_cli::long_two_d_sweep_writes_heat_maps_and_pair_thresholds` (same
/// command, portable kernel, `--threads 2`: the tables do not depend on the thread count).
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_smoke_2d_sweep_outputs_match_the_golden_files() {
    let run = crate::shared::smoke_2d();
    check(&[
        ("smoke-2d-points.csv", run.points.clone()),
        ("smoke-2d-runs.csv", run.runs.clone()),
    ]);
}
