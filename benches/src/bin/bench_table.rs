//! Prints the markdown tables of docs/benchmarks.md from one `cargo bench -p benches` run.
//!
//! Reads criterion's raw samples `target/criterion/<group>/<id>/new/sample.json` and
//! reports, per benchmark, the 10th percentile of the per-iteration sample times (time /
//! iterations of each sample): on a shared 2-core machine a sample that overlapped another
//! process's time slice is slower, never faster, so a low quantile is the estimate least
//! affected by the neighbours; the median is printed next to it for the n = 30 table.
//! Also reads `target/criterion/iteration-meta.json` (iteration counts, kernel paths, run
//! start). Results older than the run start are reported as missing, so stale numbers
//! from an earlier run never enter a table.
//!
//! Run: `cargo run -p benches --bin bench_table` after `cargo bench -p benches`.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use serde_json::Value;

struct Results {
    dir: PathBuf,
    started: Option<SystemTime>,
}

impl Results {
    /// Per-iteration times (ns) of the samples of benchmark `id`
    /// (`group/function[/parameter]`), sorted, if it ran in this run.
    fn samples(&self, id: &str) -> Option<Vec<f64>> {
        let path = self.dir.join(id).join("new/sample.json");
        let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
        if self.started.is_some_and(|s| modified < s) {
            return None;
        }
        let v: Value = serde_json::from_str(&std::fs::read_to_string(&path).ok()?).ok()?;
        let (iters, times) = (v["iters"].as_array()?, v["times"].as_array()?);
        let mut t: Vec<f64> = iters
            .iter()
            .zip(times)
            .filter_map(|(i, t)| Some(t.as_f64()? / i.as_f64()?))
            .collect();
        t.sort_by(f64::total_cmp);
        (!t.is_empty()).then_some(t)
    }

    /// Quantile `p` ∈ [0, 1] of the per-iteration sample times of `id` (nearest rank).
    fn quantile(&self, id: &str, p: f64) -> Option<f64> {
        let t = self.samples(id)?;
        let k = ((t.len() - 1) as f64 * p).round() as usize;
        t.get(k).copied()
    }

    /// The headline statistic: 10th percentile.
    fn ns(&self, id: &str) -> Option<f64> {
        self.quantile(id, 0.1)
    }
}

fn fmt_time(ns: Option<f64>) -> String {
    match ns {
        None => "—".into(),
        Some(t) if t < 1e3 => format!("{t:.1} ns"),
        Some(t) if t < 1e6 => format!("{:.2} µs", t / 1e3),
        Some(t) => format!("{:.2} ms", t / 1e6),
    }
}

fn ratio(a: Option<f64>, b: Option<f64>) -> String {
    match (a, b) {
        (Some(a), Some(b)) => format!("{:.2}×", a / b),
        _ => "—".into(),
    }
}

fn main() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/criterion");
    let meta: Value = std::fs::read_to_string(dir.join("iteration-meta.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(Value::Null);
    let started = meta["run_started_unix"]
        .as_u64()
        .map(|s| SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(s));
    let r = Results { dir, started };

    println!(
        "Kernel path: `{}`; reference kernel SIMD: {}; time = 10th percentile of criterion's \
         per-iteration samples (median in brackets where shown).\n",
        meta["kernel_path"].as_str().unwrap_or("?"),
        meta["reference_simd"]
    );

    // n = 30, interleaved (the robust ratios).
    let inter = &meta["interleaved_n30"];
    let iv = |k: &str, stat: &str| inter[k][stat].as_f64();
    println!("### One iteration at n = 30, interleaved batches (fastest batch of 300)\n");
    println!("| variant | fastest batch | median batch | ratio to reference (fastest) | target |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    let targets = [
        ("ref_column_axpy", "—"),
        ("matvec_padded", ""),
        ("step/pg", "≤ 1.3×"),
        ("step/fista", "≤ 1.3×"),
        ("step/admm", "≤ 1.3× (1 matvec/step)"),
        ("step/admm_pr", "≤ 1.3× (1 matvec/step)"),
        ("fused_kernel/pg", ""),
        ("fused_kernel/fista", ""),
        ("fused_kernel/admm", ""),
    ];
    let ref_min = iv("ref_column_axpy", "min_ns");
    for (k, target) in targets {
        let (mn, md) = (iv(k, "min_ns"), iv(k, "median_ns"));
        println!(
            "| `{k}` | {} | {} | {} | {target} |",
            fmt_time(mn),
            fmt_time(md),
            ratio(mn, ref_min)
        );
    }
    println!();
    // The same steps at four memory placements (maps and states allocated elsewhere).
    println!(
        "Step at four memory placements of H and the state (fastest batch each):
"
    );
    println!("| method | placements (ns) | ratio to reference: best – worst |");
    println!("| --- | --- | ---: |");
    for m in ["pg", "fista", "admm"] {
        let all: Vec<f64> = std::iter::once(format!("step/{m}"))
            .chain((1..=3).map(|p| format!("step/{m}@{p}")))
            .filter_map(|k| iv(&k, "min_ns"))
            .collect();
        let (lo, hi) = all
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        let list: Vec<String> = all.iter().map(|x| format!("{x:.1}")).collect();
        println!(
            "| {m} | {} | {} – {} |",
            list.join(", "),
            ratio(Some(lo), ref_min),
            ratio(Some(hi), ref_min)
        );
    }
    println!();

    // n = 30, criterion.
    let reference = r.ns("n30/ref_column_axpy");
    println!("### One iteration at n = 30, criterion\n");
    let ref_median = r.quantile("n30/ref_column_axpy", 0.5);
    println!("| benchmark | what | time (median) | ratio to reference (of medians) | target |");
    println!("| --- | --- | ---: | ---: | ---: |");
    let rows: &[(&str, &str, &str)] = &[
        (
            "n30/ref_column_axpy",
            "**reference**: const 30×30 y = Hx, column form, AVX2+FMA (runtime detection)",
            "",
        ),
        (
            "n30/ref_row_dot",
            "const 30×30, row dot products, AVX2+FMA",
            "",
        ),
        (
            "n30/ref_column_axpy_chained",
            "reference, x ← (H/L)x chained (latency)",
            "",
        ),
        (
            "n30/matvec_padded",
            "`Kernel::matvec_padded` (dispatched)",
            "",
        ),
        ("n30/matvec_padded_chained", "same, chained", ""),
        (
            "n30/matvec_padded_portable",
            "`matvec_padded`, portable path (SSE2)",
            "",
        ),
        (
            "n30/faer_matmul_seq",
            "faer `matmul`, Par::Seq, preallocated",
            "",
        ),
        ("n30/step/pg", "PG step (`pg.rs`)", "≤ 1.3×"),
        ("n30/step/fista", "FISTA step (`fista.rs`)", "≤ 1.3×"),
        (
            "n30/step/admm",
            "ADMM step (`admm.rs`, 1 matvec/step)",
            "≤ 1.3×",
        ),
        (
            "n30/fused_kernel/fista",
            "`Kernel::fista_step_padded` (one pass)",
            "",
        ),
        (
            "n30/fused_kernel/admm",
            "`Kernel::admm_dr_step_padded` (one pass)",
            "",
        ),
    ];
    for (id, what, target) in rows {
        let (t, tm) = (r.ns(id), r.quantile(id, 0.5));
        println!(
            "| `{id}` | {what} | {} ({}) | {} ({}) | {target} |",
            fmt_time(t),
            fmt_time(tm),
            ratio(t, reference),
            ratio(tm, ref_median)
        );
    }

    // Size grid.
    println!("\n### One iteration, size grid\n");
    println!(
        "| n | `matvec_padded` | PG step | FISTA step | ADMM step | PG / matvec | FISTA / matvec | ADMM / matvec |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for n in [10, 20, 50, 100, 200, 400] {
        let mv = r.ns(&format!("grid/matvec_padded/{n}"));
        let [pg, fista, admm] = ["pg", "fista", "admm"].map(|m| r.ns(&format!("grid/{m}/{n}")));
        println!(
            "| {n} | {} | {} | {} | {} | {} | {} | {} |",
            fmt_time(mv),
            fmt_time(pg),
            fmt_time(fista),
            fmt_time(admm),
            ratio(pg, mv),
            ratio(fista, mv),
            ratio(admm, mv)
        );
    }

    // Time to accuracy.
    let eps = meta["eps"].as_f64().unwrap_or(f64::NAN);
    println!(
        "\n### Time to ‖z − z*‖ ≤ {eps:e}·‖z⁰ − z*‖ (load θ + cold start + K steps) and Clarabel's solve\n"
    );
    println!(
        "| n | PG: K, time | FISTA: K, time | ADMM: K, time | Clarabel: IPM iterations, time | Clarabel / fastest |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: |");
    for n in [10, 20, 30, 50, 100, 200, 400] {
        let it = &meta["iterations"][n.to_string()];
        let cell = |m: &str, key: &str| {
            let t = r.ns(&format!("accuracy/{m}/{n}"));
            (
                t,
                format!(
                    "{}, {}",
                    it[key].as_u64().map_or("?".into(), |k| k.to_string()),
                    fmt_time(t)
                ),
            )
        };
        let (pg, pg_s) = cell("pg", "pg");
        let (fi, fi_s) = cell("fista", "fista");
        let (ad, ad_s) = cell("admm", "admm");
        let (cl, cl_s) = cell("clarabel", "clarabel_ipm_iterations");
        let fastest = [pg, fi, ad].into_iter().flatten().reduce(f64::min);
        println!(
            "| {n} | {pg_s} | {fi_s} | {ad_s} | {cl_s} | {} |",
            ratio(cl, fastest)
        );
    }
}
