//! The sweep's draws outside 𝒲 (`w_outside` in runs.csv, its per-point summary in
//! points.csv, carried through point files) and the Kalman baseline of a sharded sweep
//! (each shard's part of kalman.csv, assembled by a merge), issue 25.

use std::fs;
use std::path::{Path, PathBuf};

use super::build;
use closed_loop::scenario::{LoopOptions, Scenario};
use xtask::sweep_engine::{
    NoProgress, RunOptions, Shard, Sweep, SweepConfig, SweepError, Table, kalman_part_name,
    merge_point_dirs, point_file_name,
};

const CASE_STUDY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/case-study.toml");

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("sweep-io-tests")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// The case study with its simulated noise a normal of standard deviation 0.1 per entry
/// truncated to ±0.3, three times 𝒲 = [−0.1, 0.1]⁵: about a third of the entries fall
/// outside 𝒲, so most steps have a draw outside it. 𝒲 itself is unchanged.
fn wide_noise_scenario(dir: &Path) -> PathBuf {
    let text = fs::read_to_string(CASE_STUDY).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("kind = \"uniform\""))
        .unwrap();
    let row = |i: usize| {
        let mut r = ["0.0"; 5];
        r[i] = "0.01";
        format!("[{}]", r.join(", "))
    };
    let cov: Vec<String> = (0..5).map(row).collect();
    let wide = format!(
        "kind = \"truncated-normal\"\ncovariance = [{}]\ntruncate = {{ lower = [-0.3, -0.3, -0.3, -0.3, -0.3], upper = [0.3, 0.3, 0.3, 0.3, 0.3] }}",
        cov.join(", ")
    );
    let path = dir.join("wide-noise.toml");
    fs::write(&path, text.replace(line, &wide)).unwrap();
    path
}

/// 2 K × 1 solver × the given scales, 4 seeds, T = 12; no certificate (seconds).
fn config(scenario: &Path, extra: &str) -> SweepConfig {
    let text = format!(
        "name = \"io\"\nscenario = \"{}\"\nk = [1, 6]\nsolvers = [\"pg\"]\nseeds = 4\nsteps = 12\n\
         base_seed = 3\ncertificate = false\nlinear = false\n{extra}",
        scenario.display()
    );
    SweepConfig::from_toml_str(&text, Path::new(".")).unwrap()
}

fn opts(d: &Path, shard: Option<Shard>) -> RunOptions {
    RunOptions {
        out_dir: d.to_path_buf(),
        threads: 2,
        shard,
    }
}

fn table(path: &Path) -> Table {
    Table::parse(&fs::read_to_string(path).unwrap()).unwrap()
}

/// Steps of a fresh loop's trace whose w_t has an entry outside [lower, upper], counted
/// entry by entry (not with `draws_outside`).
fn brute_outside(s: &Scenario, seed: u64, k: usize) -> usize {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = qp_iter::Method::PG;
    o = o.with_iterations(k).expect("K is in range");
    o.seed = seed;
    o.steps = 12;
    let mut lp = build(s, &o).unwrap();
    let _ = lp.run(); // a stopped run counts its steps so far, like the sweep
    let tr = lp.trace();
    let (lo, hi) = (s.sets.disturbance.lower(), s.sets.disturbance.upper());
    (0..tr.len())
        .filter(|&t| {
            let w = tr.w(t).unwrap();
            (0..w.len()).any(|i| w[i] < lo[i] || w[i] > hi[i])
        })
        .count()
}

/// runs.csv counts each run's draws outside 𝒲 — equal to a brute-force count on a fresh
/// loop, and to kalman.csv's count on the same draws — zero where the noise stays in 𝒲
/// (uniform on 𝒲, scale 1) and nonzero where it does not (a truncated normal wider than 𝒲,
/// the uniform law at scale 2); points.csv sums them per point.
#[test]
fn runs_count_the_draws_outside_w() {
    let d = scratch("outside");
    let wide = wide_noise_scenario(&d);
    for (scenario, scales, any_outside) in [
        (PathBuf::from(CASE_STUDY), "[1.0]", false),
        (wide.clone(), "[1.0]", true),
        (PathBuf::from(CASE_STUDY), "[2.0]", true),
    ] {
        let cfg = config(
            &scenario,
            &format!("scales = {scales}\nestimators = [\"mhe\", \"kalman\"]"),
        );
        let sweep = Sweep::new(cfg).unwrap();
        let out = d.join(format!("out-{}-{scales}", any_outside));
        sweep.run(&opts(&out, None), &NoProgress).unwrap();
        let runs = table(&out.join("runs.csv"));
        let kalman = table(&out.join("kalman.csv"));
        let s = {
            let mut s = Scenario::from_file(&scenario).unwrap();
            s.noise.scale = sweep.points()[0].scale;
            s
        };
        let mut total = 0;
        for row in 0..runs.rows.len() {
            let n: usize = runs.text(row, "w_outside").unwrap().parse().unwrap();
            let seed: u64 = runs.text(row, "seed").unwrap().parse().unwrap();
            let k: usize = runs.text(row, "k").unwrap().parse().unwrap();
            assert_eq!(n, brute_outside(&s, seed, k), "{scenario:?} row {row}");
            assert!(n <= 12);
            // The Kalman filter's run on the same draws counts the same.
            let r: usize = runs.text(row, "run").unwrap().parse().unwrap();
            assert_eq!(kalman.text(r, "w_outside"), runs.text(row, "w_outside"));
            total += n;
        }
        assert_eq!(total > 0, any_outside, "{scenario:?} at {scales}: {total}");
        let points = table(&out.join("points.csv"));
        let mut sum = 0;
        for p in 0..points.rows.len() {
            let idx = points.text(p, "point").unwrap();
            let counts: Vec<usize> = (0..runs.rows.len())
                .filter(|&r| runs.text(r, "point") == Some(idx))
                .map(|r| runs.text(r, "w_outside").unwrap().parse().unwrap())
                .collect();
            let want_total: usize = counts.iter().sum();
            let want_runs = counts.iter().filter(|&&n| n > 0).count();
            assert_eq!(
                points.text(p, "w_outside_total"),
                Some(&*want_total.to_string())
            );
            assert_eq!(
                points.text(p, "w_outside_runs"),
                Some(&*want_runs.to_string())
            );
            sum += want_total;
        }
        assert_eq!(sum, total);
        // The timing column stays last.
        assert_eq!(runs.header.last().map(String::as_str), Some("wall_ms"));
        assert_eq!(points.header.last().map(String::as_str), Some("wall_ms"));
    }
}

/// Rewrites cell `column` of line `line` (1-based) of a point file.
fn edit_cell(path: &Path, line: usize, column: usize, value: &str) {
    let text = fs::read_to_string(path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<&str> = lines[line - 1].split(',').collect();
    cells[column] = value;
    lines[line - 1] = cells.join(",");
    fs::write(path, lines.join("\n") + "\n").unwrap();
}

/// An edited count in a point file — out of its domain, above the run's steps, or not the
/// sum the summary row records — is refused on resume, naming the file, the line and the
/// column; the outputs are untouched.
#[test]
fn an_edited_count_is_refused_naming_file_row_and_cell() {
    let d = scratch("edited");
    let wide = wide_noise_scenario(&d);
    let sweep = Sweep::new(config(&wide, "")).unwrap();
    let out = d.join("out");
    sweep.run(&opts(&out, None), &NoProgress).unwrap();
    let file = out.join("points").join(point_file_name(1));
    let original = fs::read_to_string(&file).unwrap();
    let runs = table(&out.join("runs.csv"));
    let points = table(&out.join("points.csv"));
    let c_run = runs.column("w_outside").unwrap();
    let c_total = points.column("w_outside_total").unwrap();
    let c_runs = points.column("w_outside_runs").unwrap();
    let c_steps = runs.column("steps").unwrap();
    let summary = 4 + 2; // magic line, 4 run rows, separator, summary row
    let run0: usize = original
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(c_run)
        .unwrap()
        .parse()
        .unwrap();
    assert!(run0 > 0, "the wide noise leaves 𝒲 in run 0");
    let before = fs::read(out.join("runs.csv")).unwrap();
    for (line, col, value, needle) in [
        (
            2,
            c_run,
            "13",
            "line 2 (run 0), column `w_outside`: `13` is not an integer from 0 to 12",
        ),
        (2, c_run, "-1", "column `w_outside`: `-1` is not an integer"),
        (2, c_run, "1.5", "column `w_outside`: `1.5`"),
        (3, c_run, "", "line 3 (run 1), column `w_outside`"),
        (
            summary + 1,
            c_total,
            "49",
            "column `w_outside_total`: `49` is not an integer from 0 to 48",
        ),
        (
            summary + 1,
            c_runs,
            "5",
            "column `w_outside_runs`: `5` is not an integer from 0 to 4",
        ),
        // More draws outside than steps.
        (2, c_steps, "0", "line 2 (run 0), column `w_outside`"),
    ] {
        fs::write(&file, &original).unwrap();
        edit_cell(&file, line, col, value);
        let e = sweep.run(&opts(&out, None), &NoProgress).unwrap_err();
        let text = e.to_string();
        match &e {
            SweepError::PointFile { path, problem } => {
                assert!(
                    path.ends_with(format!("points/{}", point_file_name(1))),
                    "{text}"
                );
                assert!(problem.contains(needle), "`{needle}` not in {text}");
            }
            other => panic!("not a point-file error: {other}"),
        }
        assert!(text.contains("delete it and rerun"), "{text}");
        assert_eq!(fs::read(out.join("runs.csv")).unwrap(), before);
    }
    // The summary's total checked against the run rows even when the runs' column is in
    // its domain: run 0's count moved by one is refused at the summary row.
    fs::write(&file, &original).unwrap();
    edit_cell(&file, 2, c_run, &(run0 - 1).to_string());
    let e = sweep
        .run(&opts(&out, None), &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!(
            "line {} (summary row), column `w_outside_",
            summary + 1
        )),
        "{e}"
    );
    fs::write(&file, &original).unwrap();
    sweep.run(&opts(&out, None), &NoProgress).unwrap();
}

/// The sweep of [`sharded_sweep_merges_kalman_csv`], whole and in three shards in `d`, each
/// shard's Kalman part and the merge checked: (the sweep, the whole run's directory, the
/// shards' directories).
fn kalman_shards_merged(d: &Path) -> (Sweep, PathBuf, Vec<PathBuf>) {
    let cfg = config(
        Path::new(CASE_STUDY),
        "scales = [0.5, 2.0]\nestimators = [\"mhe\", \"kalman\"]",
    );
    let sweep = Sweep::new(cfg).unwrap();
    let whole = d.join("whole");
    sweep.run(&opts(&whole, None), &NoProgress).unwrap();
    let shards: Vec<PathBuf> = (1..=3).map(|i| d.join(format!("shard-{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let shard = Shard {
            index: i + 1,
            count: 3,
        };
        sweep.run(&opts(s, Some(shard)), &NoProgress).unwrap();
        assert!(!s.join("kalman.csv").exists());
        let part = s.join("points").join(kalman_part_name(shard));
        let text = fs::read_to_string(&part).unwrap();
        // Rows j = s·seeds + r with j mod 3 = i (8 rows: j = 0..8).
        let rows = text.lines().count() - 2;
        assert_eq!(rows, (0..8).filter(|j| j % 3 == i).count(), "{text}");
    }
    let dirs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let merged = d.join("merged");
    assert_eq!(
        merge_point_dirs(&sweep, &dirs, &merged, &NoProgress).unwrap(),
        4
    );
    let bytes = |p: &Path, f: &str| fs::read(p.join(f)).unwrap();
    assert_eq!(bytes(&merged, "kalman.csv"), bytes(&whole, "kalman.csv"));
    assert_eq!(table(&whole.join("kalman.csv")).rows.len(), 8);
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(
            table(&merged.join(f)).without_timing(),
            table(&whole.join(f)).without_timing(),
            "{f}"
        );
    }
    // The merged directory holds every part: merged again on its own, the same kalman.csv.
    fs::remove_file(merged.join("kalman.csv")).unwrap();
    merge_point_dirs(&sweep, &[merged.as_path()], &merged, &NoProgress).unwrap();
    assert_eq!(bytes(&merged, "kalman.csv"), bytes(&whole, "kalman.csv"));
    (sweep, whole, shards)
}

/// Every shard of a sweep with the Kalman baseline writes its part of kalman.csv
/// (`points/kalman.shard-I-of-N.csv`); the merge assembles kalman.csv byte for byte equal
/// to the unsharded sweep's (runs.csv and points.csv too, timing aside), copies the parts
/// so the merged directory merges again, and refuses a missing, corrupt or conflicting
/// part naming the file.
#[test]
fn sharded_sweep_merges_kalman_csv() {
    let d = scratch("kalman-shards");
    let (sweep, whole, shards) = kalman_shards_merged(&d);
    let dirs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let bytes = |p: &Path, f: &str| fs::read(p.join(f)).unwrap();
    let part2 = shards[1]
        .join("points")
        .join(kalman_part_name(Shard { index: 2, count: 3 }));
    let original = fs::read_to_string(&part2).unwrap();
    let refused = |what: &str, needles: &[&str]| {
        let out = d.join(format!("merged-{what}"));
        let e = merge_point_dirs(&sweep, &dirs, &out, &NoProgress).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, SweepError::KalmanPart { .. }), "{what}: {text}");
        for n in needles {
            assert!(text.contains(n), "{what}: `{n}` not in {text}");
        }
        assert!(!out.join("kalman.csv").exists() && !out.join("runs.csv").exists());
    };
    // Missing: named by the file that should hold the rows, with the shard to rerun.
    fs::remove_file(&part2).unwrap();
    refused(
        "missing",
        &["kalman.shard-2-of-3.csv", "missing", "--shard 2/3"],
    );
    // Corrupt: a cell out of its domain, a cut file, another header.
    let header = original.lines().nth(1).unwrap().to_string();
    let c_outside = header.split(',').position(|c| c == "w_outside").unwrap();
    let c_bounded = header.split(',').position(|c| c == "bounded").unwrap();
    let row = original.lines().nth(2).unwrap().to_string();
    let with = |col: usize, v: &str| {
        let mut cells: Vec<&str> = row.split(',').collect();
        cells[col] = v;
        original.replace(&row, &cells.join(","))
    };
    for (what, text, needle) in [
        (
            "outside",
            with(c_outside, "13"),
            "line 3: column `w_outside`: `13`",
        ),
        (
            "bounded",
            with(c_bounded, "2"),
            "line 3: column `bounded`: `2`",
        ),
        (
            "cut",
            original[..original.len() - 5].to_string(),
            "truncated",
        ),
        (
            "header",
            original.replace(&header, "estimator,scale"),
            "line 2",
        ),
    ] {
        fs::write(&part2, text).unwrap();
        refused(
            what,
            &["kalman.shard-2-of-3.csv", needle, "rerun that shard"],
        );
    }
    // Conflict: shard 1's part copied into shard 2's directory with one number changed.
    fs::write(&part2, &original).unwrap();
    let p1 = kalman_part_name(Shard { index: 1, count: 3 });
    let text1 = fs::read_to_string(shards[0].join("points").join(&p1)).unwrap();
    let row1 = text1.lines().nth(2).unwrap();
    let c_sup_w = header.split(',').position(|c| c == "sup_w").unwrap();
    let mut cells: Vec<String> = row1.split(',').map(str::to_string).collect();
    let v: f64 = cells[c_sup_w].parse().unwrap();
    cells[c_sup_w] = (v * 1.5).to_string();
    fs::write(
        shards[1].join("points").join(&p1),
        text1.replace(row1, &cells.join(",")),
    )
    .unwrap();
    refused("conflict", &[&p1, "differs from the one in"]);
    fs::remove_file(shards[1].join("points").join(&p1)).unwrap();
    let again = d.join("merged-again");
    merge_point_dirs(&sweep, &dirs, &again, &NoProgress).unwrap();
    assert_eq!(bytes(&again, "kalman.csv"), bytes(&whole, "kalman.csv"));
}
