//! The sweep's `k_reg` column (issue 27 item 4): the library's K_reg search per solver and
//! scale, capped at the solver's K_min, identical at 1 and 3 threads and after shards +
//! `sweep-merge`; a missing K_reg carries its reason.

use std::fs;
use std::path::{Path, PathBuf};

use closed_loop::scenario::{ControllerChoice, LoopOptions};
use iss_certificate::linear::linear_stability;
use iss_certificate::regional::{RegionalOptions, k_reg};
use qp_iter::Method;
use xtask::sweep_engine::{
    NoProgress, Shard, Sweep, SweepConfig, Table, TaskKind, merge_point_dirs, theorem1_k_min,
    thresholds, thresholds_markdown,
};

const CERTIFIED: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/case-study-certified.toml"
);

const BOTH: &str = "\"admm\", \"fista\"";

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("regional-tests")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// The certified stand-in with N = 5 (2^10 free sets: the certificate in a moment); `small`:
/// x₀ = 10⁻⁴·1 and the prior at x₀ (the sweep's scales 10⁻⁴ and 5·10⁻⁵ make w̄ = 2.2·10⁻⁵
/// and half that), so a region contains the uncertainty; else the file's own
/// (x₀ = (12, −10, 10, −10)), which none does.
fn scenario(dir: &Path, small: bool) -> PathBuf {
    let mut text = fs::read_to_string(CERTIFIED)
        .unwrap()
        .replace("horizon = 10       # N", "horizon = 5");
    if small {
        text = text
            .replace(
                "x0 = [12.0, -10.0, 10.0, -10.0]",
                "x0 = [1e-4, 1e-4, 1e-4, 1e-4]",
            )
            .replace(
                "prior = [7.0, -7.0, 3.0, -5.0]",
                "prior = [1e-4, 1e-4, 1e-4, 1e-4]",
            )
            .replace("scale = 1.0", "scale = 1e-4");
    }
    let path = dir.join("scenario.toml");
    fs::write(&path, text).unwrap();
    path
}

fn config(scenario: &Path, solvers: &str, extra: &str) -> SweepConfig {
    let text = format!(
        "name = \"kreg\"\nscenario = \"{}\"\nk = [1, 10, 100]\nsolvers = [{solvers}]\n\
         seeds = 2\nsteps = 3\nbase_seed = 5\n{extra}",
        scenario.display()
    );
    SweepConfig::from_toml_str(&text, Path::new(".")).unwrap()
}

use super::run_sweep as run;

/// The library's K_reg for one solver and scale, and K_lin when K_reg exists.
type Direct = (Option<usize>, Option<usize>);

fn points(dir: &Path) -> Table {
    Table::parse(&fs::read_to_string(dir.join("points.csv")).unwrap()).unwrap()
}

/// `k_reg` at every point is `iss_certificate::regional::k_reg` of the solver at the point's
/// scale with the search capped at Theorem 1's K_min; K_lin (exact, every K) ≤ K_reg ≤
/// K_min; the column is the same at 1 and 3 threads and after 2 shards + merge; the
/// thresholds table carries it with K_reg/K_lin; it is one `regional` task per solver and
/// scale.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_k_reg_column_is_the_library_search_and_survives_shards_and_merge() {
    let d = scratch("small");
    let sc = scenario(&d, true);
    let sweep = Sweep::new(config(&sc, BOTH, "scales = [1e-4, 5e-5]")).unwrap();
    let whole = d.join("t1");
    let report = run(&sweep, &whole, 1, None);
    let regional = report
        .schedule
        .tasks
        .iter()
        .filter(|t| t.kind == TaskKind::Regional)
        .count();
    assert_eq!(regional, 4, "2 solvers × 2 scales of different w̄");
    let table = points(&whole);
    let mut found = 0;
    // The library's answer per solver and scale (the points of one pair differ only in K,
    // which the K_reg search does not read).
    let mut direct_by_pair: Vec<((Method, u64), Direct)> = Vec::new();
    for (row, p) in sweep.points().iter().enumerate() {
        let k_min = sweep
            .theory()
            .iter()
            .find(|(s, _)| *s == p.solver)
            .and_then(|(_, t)| theorem1_k_min(t))
            .unwrap();
        let pair = (p.solver, p.scale.to_bits());
        let (direct, k_lin) = match direct_by_pair.iter().find(|(q, _)| *q == pair) {
            Some((_, answer)) => *answer,
            None => {
                let mut res = sweep.resolved().clone();
                res.set_noise_scale(p.scale);
                let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
                let direct = k_reg(&res, p.solver, &o, k_min).unwrap().k_reg;
                let k_lin = direct.map(|k| {
                    let mut lo = LoopOptions::from_scenario(res.scenario()).unwrap();
                    lo.method = p.solver;
                    lo.controller = ControllerChoice::ExactMpc;
                    let grid: Vec<usize> = (1..=k).collect();
                    linear_stability(&res, &lo, &grid, faer::Par::Seq)
                        .unwrap()
                        .k_lin
                        .unwrap()
                });
                direct_by_pair.push((pair, (direct, k_lin)));
                (direct, k_lin)
            }
        };
        let col = table.text(row, "k_reg").unwrap();
        assert_eq!(
            col,
            direct.map(|k| k.to_string()).unwrap_or_default(),
            "{p}"
        );
        if let Some(k) = direct {
            found += 1;
            assert_eq!(table.text(row, "regional_note"), Some(""));
            assert!(k <= k_min, "{p}: K_reg = {k} > K_min = {k_min}");
            let k_lin = k_lin.expect("K_lin computed with K_reg");
            assert!(k_lin <= k, "{p}: K_lin = {k_lin} > K_reg = {k}");
        } else {
            assert!(!table.text(row, "regional_note").unwrap().is_empty());
        }
    }
    assert!(
        found > 0,
        "no K_reg in the small-uncertainty sweep: {:?}",
        table.text(0, "regional_note")
    );
    // 3 threads, and 2 shards merged: the same points.csv (timing aside).
    let three = d.join("t3");
    run(&sweep, &three, 3, None);
    assert_eq!(points(&three).without_timing(), table.without_timing());
    let shards: Vec<PathBuf> = (1..=2).map(|i| d.join(format!("shard-{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let fresh = Sweep::new(config(&sc, BOTH, "scales = [1e-4, 5e-5]")).unwrap();
        run(
            &fresh,
            s,
            1,
            Some(Shard {
                index: i + 1,
                count: 2,
            }),
        );
    }
    let merged = d.join("merged");
    let dirs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let fresh = Sweep::new(config(&sc, BOTH, "scales = [1e-4, 5e-5]")).unwrap();
    merge_point_dirs(&fresh, &dirs, &merged, &NoProgress).unwrap();
    assert_eq!(points(&merged).without_timing(), table.without_timing());
    // The thresholds table: K_reg with its ratio to K_lin.
    let th = thresholds(&table);
    assert!(th.iter().any(|t| t.k_reg.is_some()));
    let md = thresholds_markdown(&th);
    assert!(
        md.contains("| K_lin | K_reg |") && md.contains("K_reg/K_lin"),
        "{md}"
    );
}

/// No K_reg, with the reason: the stand-in's own uncertainty (the limiting constraint and
/// by how much), `certificate = false`, and Gaussian noise without `certificate.w_bar`.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_a_missing_k_reg_carries_its_reason() {
    let d = scratch("own");
    let sc = scenario(&d, false);
    let sweep = Sweep::new(config(&sc, "\"admm-pr\"", "")).unwrap();
    let t = sweep.theory_at(&sweep.points()[0]);
    assert_eq!(t.k_reg, None);
    assert!(
        t.regional_note.contains("whose region contains")
            && t.regional_note.contains("reaches")
            && t.regional_note.contains("against its bound"),
        "{}",
        t.regional_note
    );
    let off = Sweep::new(config(&sc, BOTH, "certificate = false")).unwrap();
    let t = off.theory_at(&off.points()[0]);
    assert_eq!(t.k_reg, None);
    assert!(
        t.regional_note.contains("certificate = false"),
        "{}",
        t.regional_note
    );

    let text = fs::read_to_string(&sc).unwrap().replace(
        "kind = \"uniform\"",
        "kind = \"gaussian\"\ncovariance = 1e-4",
    );
    let gauss = d.join("gauss.toml");
    fs::write(&gauss, text).unwrap();
    let g = Sweep::new(config(&gauss, BOTH, "linear = false")).unwrap();
    let t = g.theory_at(&g.points()[0]);
    assert_eq!(t.k_reg, None);
    assert!(
        t.regional_note.contains("certificate.w_bar"),
        "{}",
        t.regional_note
    );
}

/// A 2-D sweep has K_reg per K_c: at every point, `k_reg` is the library's search with the
/// point's K_c-iteration MPC (capped as `search_max` caps it), and the cheapest regional pair
/// of the 2-D thresholds is the cheapest (K_reg, K_c) over the K_c grid.
#[test]
fn a_2d_sweep_has_k_reg_per_k_c_and_the_cheapest_regional_pair() {
    use xtask::sweep_engine::{IterationCost, pair_thresholds, search_max, window_size};
    let d = scratch("two-d");
    let sc = scenario(&d, true);
    let two_d = format!(
        "name = \"kreg2d\"\nscenario = \"{}\"\nk = [1, 10]\nk_c = [2, 5]\nsolvers = [\"fista\"]\n\
         seeds = 1\nsteps = 3\nscales = [1e-4]\n\
         controller = {{ kind = \"suboptimal-mpc\", solver = \"pg\" }}\n",
        sc.display()
    );
    let s2 = Sweep::new(SweepConfig::from_toml_str(&two_d, Path::new(".")).unwrap()).unwrap();
    let out = d.join("two-d");
    run(&s2, &out, 2, None);
    let table = points(&out);
    let res = closed_loop::scenario::Scenario::from_file(&sc)
        .unwrap()
        .resolve()
        .unwrap();
    let cap = search_max(None, window_size(&res)).0;
    let mut direct = Vec::new();
    for k_c in [2, 5] {
        let controller = ControllerChoice::suboptimal(k_c, qp_iter::Method::PG).unwrap();
        let o = RegionalOptions::from_scenario(&res, controller).unwrap();
        direct.push((
            k_c,
            k_reg(&res, qp_iter::Method::FISTA, &o, cap).unwrap().k_reg,
        ));
    }
    assert!(
        direct.iter().any(|d| d.1.is_some()),
        "the small set has a region at some K_c: {direct:?}"
    );
    for row in 0..table.rows.len() {
        let k_c: usize = table.text(row, "k_c").unwrap().parse().unwrap();
        let want = direct.iter().find(|d| d.0 == k_c).unwrap().1;
        assert_eq!(
            table.text(row, "k_reg").unwrap(),
            want.map(|k| k.to_string()).unwrap_or_default(),
            "row {row}, K_c = {k_c}"
        );
        assert_eq!(
            table.text(row, "regional_note").unwrap().is_empty(),
            want.is_some(),
            "row {row}"
        );
    }
    let pairs = pair_thresholds(&table, IterationCost::default(), &[]);
    let best = direct
        .iter()
        .filter_map(|&(k_c, k)| k.map(|k| (k + k_c, k, k_c)))
        .min()
        .unwrap();
    let p = pairs[0].cheapest_regional.unwrap();
    assert_eq!((p.k_e, p.k_c, p.cost), (best.1, best.2, best.0 as f64));
    assert_eq!(pairs[0].regional, direct);
}
