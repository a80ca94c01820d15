//! 2-D sweeps over (K_e, K_c) (issue 16 item 3): config errors naming `k_c`, the grid and
//! its seeds, thread-count independence, resume, a different K_c grid refused naming it,
//! and the `rho_lin` column against `iss_certificate::linear` at each (K_e, K_c).

use std::fs;
use std::path::{Path, PathBuf};

use closed_loop::scenario::{ControllerChoice, LoopOptions};
use iss_certificate::linear::linear_stability;
use qp_iter::Method;
use xtask::sweep_engine::{
    IterationCost, NoProgress, RunOptions, Sweep, SweepConfig, SweepError, Table, pair_thresholds,
    point_file_name, run_seed,
};

const SCENARIO: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/cart-pendulum.toml"
);

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("sweep2d-tests")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// The unstable cart-pendulum with the sub-optimal MPC (PG): 2 K_e × 2 K_c × 2 solvers,
/// 3 seeds, T = 60 (ADMM at K_e = 1 diverges, FISTA does not: both kinds of rows). Without
/// K_reg (`certificate = false`; the joint certificate of a 2-D sweep is computed anyway):
/// the K_reg column of a 2-D sweep is tested in `regional.rs` and by the smoke-2d golden files.
fn text(extra: &str) -> String {
    format!(
        "name = \"grid\"\nscenario = \"{SCENARIO}\"\nk = [1, 10]\nk_c = [1, 5]\n\
         solvers = [\"admm\", \"fista\"]\nseeds = 3\nsteps = 60\nbase_seed = 4\n\
         controller = {{ kind = \"suboptimal-mpc\", solver = \"pg\" }}\ncertificate = false\n{extra}"
    )
}

fn config(extra: &str) -> SweepConfig {
    SweepConfig::from_toml_str(&text(extra), Path::new(".")).unwrap()
}

fn key_of(toml: &str) -> (String, String) {
    match SweepConfig::from_toml_str(toml, Path::new(".")) {
        Err(SweepError::Config { key, problem }) => (key, problem),
        other => panic!("not a config error: {other:?}\n{toml}"),
    }
}

fn run(sweep: &Sweep, out: &Path, threads: usize) -> xtask::sweep_engine::SweepReport {
    sweep
        .run(
            &RunOptions {
                out_dir: out.to_path_buf(),
                threads,
                shard: None,
            },
            &NoProgress,
        )
        .unwrap()
}

fn table(path: &Path) -> Table {
    Table::parse(&fs::read_to_string(path).unwrap()).unwrap()
}

fn outputs(dir: &Path) -> (String, String) {
    (
        table(&dir.join("runs.csv")).without_timing(),
        table(&dir.join("points.csv")).without_timing(),
    )
}

#[test]
fn k_c_config_errors_name_the_key_and_the_fix() {
    let base = "name = 'x'\nscenario = 's'\nk = [1]\nsolvers = ['pg']\nseeds = 1\n";
    let sub = "controller = { kind = 'suboptimal-mpc', solver = 'pg' }\n";
    for (extra, key, needle) in [
        // K_c without the sub-optimal MPC.
        ("k_c = [1, 5]", "k_c", "needs the sub-optimal MPC"),
        ("k_c = [1]\ncontroller = 'exact-mpc'", "k_c", "exact-mpc"),
        (
            "k_c = [1]\ncontroller = 'saturated-lqr'",
            "k_c",
            "saturated-lqr",
        ),
        // The controller's own budget conflicts with the grid.
        (
            "k_c = [1, 5]\ncontroller = { kind = 'suboptimal-mpc', iterations = 5 }",
            "controller.iterations",
            "conflicts with k_c",
        ),
        // The grid itself, like `k`.
        (&format!("k_c = []\n{sub}"), "k_c", "K_c grid is empty"),
        (
            &format!("k_c = [1, 0]\n{sub}"),
            "k_c[1]",
            "1 ≤ K_c ≤ 10000000",
        ),
        (
            &format!("k_c = [20000000]\n{sub}"),
            "k_c[0]",
            "out of range",
        ),
        (&format!("k_c = [1, 'a']\n{sub}"), "k_c[1]", "line"),
        (
            &format!("k_c = {{ from = 0, to = 5, points = 3 }}\n{sub}"),
            "k_c.from",
            "≥ 1",
        ),
        (
            &format!("k_c = {{ from = 9, to = 5, points = 3 }}\n{sub}"),
            "k_c.to",
            "k_c.from",
        ),
        (
            &format!("k_c = {{ from = 1, to = 5 }}\n{sub}"),
            "k_c.points",
            "missing",
        ),
        (
            &format!("k_c = {{ from = 1, to = 5, points = 2, by = 1 }}\n{sub}"),
            "k_c.by",
            "unknown",
        ),
        (&format!("k_c = 5\n{sub}"), "k_c", "a list of integers"),
        (
            "k_c = [1]\ncontroller = { kind = 'suboptimal-mpc', solver = 'newton' }",
            "controller.solver",
            "newton",
        ),
        // The cost weights: only in 2-D, finite, ≥ 0, not both 0, known keys.
        ("cost = { t_e = 1.0 }", "cost", "needs a 2-D sweep"),
        (
            &format!("k_c = [1]\n{sub}cost = {{ t_e = -1.0 }}"),
            "cost.t_e",
            "≥ 0",
        ),
        (
            &format!("k_c = [1]\n{sub}cost = {{ t_c = inf }}"),
            "cost.t_c",
            "finite",
        ),
        (
            &format!("k_c = [1]\n{sub}cost = {{ t_e = 0.0, t_c = 0.0 }}"),
            "cost",
            "every pair free",
        ),
        (
            &format!("k_c = [1]\n{sub}cost = {{ t_x = 1.0 }}"),
            "cost.t_x",
            "unknown",
        ),
        // A 1-D sub-optimal MPC without its budget is pointed to k_c.
        (
            "controller = { kind = 'suboptimal-mpc' }",
            "controller.iterations",
            "k_c",
        ),
    ] {
        let (k, problem) = key_of(&format!("{base}{extra}"));
        assert_eq!(k, key, "{extra}: {problem}");
        assert!(
            problem.contains(needle),
            "{extra}: `{problem}` lacks `{needle}`"
        );
    }
    valid_k_c_configs(base, sub);
}

/// The valid counterparts of [`k_c_config_errors_name_the_key_and_the_fix`]'s configs.
fn valid_k_c_configs(base: &str, sub: &str) {
    // The name alone also selects the sub-optimal MPC in a 2-D sweep, with the scenario's
    // default Φ (`mpc.method`'s default, FISTA: one default for the file and the sweep).
    let c = SweepConfig::from_toml_str(
        &format!("{base}k_c = [3, 1, 3]\ncontroller = 'suboptimal-mpc'\ncost = {{ t_c = 0.25 }}"),
        Path::new("."),
    )
    .unwrap();
    assert_eq!(c.k_c_grid, Some(vec![1, 3]));
    assert_eq!(
        c.cost,
        IterationCost {
            t_e: 1.0,
            t_c: 0.25
        }
    );
    assert_eq!(
        c.controller,
        ControllerChoice::suboptimal(1, Method::FISTA).unwrap()
    );
    let c = SweepConfig::from_toml_str(
        &format!("{base}k_c = {{ from = 1, to = 100, points = 3 }}\n{sub}"),
        Path::new("."),
    )
    .unwrap();
    assert_eq!(c.k_c_grid, Some(vec![1, 10, 100]));
}

#[test]
fn grid_points_carry_k_c_and_their_own_seeds() {
    let c = config("scales = [0.5, 1.0]");
    assert!(c.is_2d());
    let p = c.points();
    assert_eq!(p.len(), 2 * 2 * 2 * 2, "scales × solvers × K_c × K_e");
    // Order: scale, solver, K_c, K.
    let ids: Vec<(usize, Option<usize>)> = p.iter().take(4).map(|q| (q.k, q.k_c)).collect();
    assert_eq!(
        ids,
        vec![(1, Some(1)), (10, Some(1)), (1, Some(5)), (10, Some(5))]
    );
    assert!(p.iter().enumerate().all(|(i, q)| q.index == i));
    assert_eq!(
        c.controller_at(&p[2]).unwrap(),
        ControllerChoice::suboptimal(5, Method::PG).unwrap()
    );
    assert!(p[2].to_string().contains("K_c = 5"), "{}", p[2]);
    // Common random numbers: run r's seed is a function of (base seed, r) only; otherwise
    // K_c enters the point's stream.
    assert_eq!(run_seed(4, &p[0], 2, true), run_seed(4, &p[2], 2, true));
    assert_ne!(run_seed(4, &p[0], 2, false), run_seed(4, &p[2], 2, false));
    // A 1-D config is unchanged: no K_c.
    let one = SweepConfig::from_toml_str(
        &format!("name = 'x'\nscenario = '{SCENARIO}'\nk = [1, 10]\nsolvers = ['pg']\nseeds = 1"),
        Path::new("."),
    )
    .unwrap();
    assert!(!one.is_2d() && one.points().iter().all(|q| q.k_c.is_none()));
}

#[test]
fn two_d_sweep_is_thread_count_independent_and_resumes() {
    let sweep = Sweep::new(config("")).unwrap();
    let (a, b) = (scratch("threads-1"), scratch("threads-2"));
    let ra = run(&sweep, &a, 1);
    let rb = run(&sweep, &b, 2);
    assert_eq!((ra.computed, rb.computed), (8, 8));
    assert_eq!(outputs(&a), outputs(&b));
    // The k_c column, after k, in both files.
    let points = table(&a.join("points.csv"));
    assert_eq!(points.header[..5], ["point", "k", "k_c", "solver", "scale"]);
    assert_eq!(table(&a.join("runs.csv")).header[2], "k_c");
    let k_c: Vec<&str> = (0..8).map(|r| points.text(r, "k_c").unwrap()).collect();
    assert_eq!(k_c, ["1", "1", "5", "5", "1", "1", "5", "5"]);
    // Both kinds of runs: ADMM at K_e = 1 is not bounded, FISTA at K_e = 10, K_c = 5 is.
    assert!(points.number(0, "bounded_fraction").unwrap() < 1.0);
    assert_eq!(points.number(7, "bounded_fraction"), Some(1.0));
    // Resume: two points lost (one per K_c), recomputed with another thread count.
    for i in [2, 5] {
        fs::remove_file(a.join("points").join(point_file_name(i))).unwrap();
    }
    let r = run(&sweep, &a, 2);
    assert_eq!((r.computed, r.skipped), (2, 6));
    assert_eq!(outputs(&a), outputs(&b));
    // A point file whose rows claim another K_c is refused, naming the k_c column.
    let path = a.join("points").join(point_file_name(2));
    let edited: String = fs::read_to_string(&path)
        .unwrap()
        .lines()
        .map(|l| {
            let mut cells: Vec<&str> = l.split(',').collect();
            if cells.len() > 5 {
                cells[2] = "1";
            }
            cells.join(",") + "\n"
        })
        .collect();
    fs::write(&path, edited).unwrap();
    let e = sweep.finished_points(&a).unwrap_err().to_string();
    assert!(
        e.contains("(point,k,k_c,solver,scale)") && e.contains("column `k_c` should be `5`"),
        "{e}"
    );
}

#[test]
fn another_k_c_grid_is_refused_naming_it() {
    let sweep = Sweep::new(config("")).unwrap();
    let d = scratch("other-grid");
    run(&sweep, &d, 2);
    let other = Sweep::new(
        SweepConfig::from_toml_str(
            &text("").replace("k_c = [1, 5]", "k_c = [1, 2]"),
            Path::new("."),
        )
        .unwrap(),
    )
    .unwrap();
    assert_ne!(other.fingerprint(), sweep.fingerprint());
    let e = other
        .run(
            &RunOptions {
                out_dir: d.clone(),
                threads: 1,
                shard: None,
            },
            &NoProgress,
        )
        .unwrap_err();
    assert!(matches!(e, SweepError::Fingerprint { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("settings that differ: k_c = [1, 5] there, [1, 2] here"),
        "{msg}"
    );
    // The same grid with another cost weight is the same sweep (the cost only weighs).
    let cheap_c = Sweep::new(config("cost = { t_c = 0.1 }")).unwrap();
    assert_eq!(cheap_c.fingerprint(), sweep.fingerprint());
    // A 1-D sweep's directory is refused by a 2-D sweep and the other way round.
    let one_d = Sweep::new(
        SweepConfig::from_toml_str(
            &text("")
                .replace("k_c = [1, 5]\n", "")
                .replace("solver = \"pg\" }", "solver = \"pg\", iterations = 5 }"),
            Path::new("."),
        )
        .unwrap(),
    )
    .unwrap();
    let e = one_d.finished_points(&d).unwrap_err().to_string();
    assert!(e.contains("k_c = [1, 5] there, (none) here"), "{e}");
}

#[test]
fn rho_lin_column_is_the_linear_analysis_at_each_k_c() {
    let sweep = Sweep::new(config("")).unwrap();
    let d = scratch("rho-lin");
    run(&sweep, &d, 2);
    let t = table(&d.join("points.csv"));
    let resolved = sweep.resolved();
    for solver in [Method::ADMM, Method::FISTA] {
        for k_c in [1, 5] {
            let mut o = LoopOptions::from_scenario(resolved.scenario()).unwrap();
            o.method = solver;
            o.controller = ControllerChoice::suboptimal(k_c, Method::PG).unwrap();
            let report = linear_stability(resolved, &o, &[1, 10], faer::Par::Seq).unwrap();
            let rows: Vec<usize> = (0..t.rows.len())
                .filter(|&r| {
                    t.text(r, "solver") == Some(solver.name().as_ref())
                        && t.text(r, "k_c") == Some(k_c.to_string().as_str())
                })
                .collect();
            assert_eq!(rows.len(), 2);
            for r in rows {
                let k: usize = t.text(r, "k").unwrap().parse().unwrap();
                let want = report.rho_lin.iter().find(|p| p.0 == k).unwrap().1;
                assert_eq!(
                    t.number(r, "rho_lin"),
                    Some(want),
                    "{solver} K = {k} K_c = {k_c}"
                );
                assert_eq!(
                    t.text(r, "k_lin").unwrap(),
                    report.k_lin.map(|k| k.to_string()).unwrap_or_default()
                );
                // The joint certificate's verdict at (K_e, K_c) (iss_certificate::coverage):
                // the same one the certified staircase is drawn from.
                let st = &sweep
                    .certified_boundaries()
                    .iter()
                    .find(|(m, _)| *m == solver)
                    .unwrap()
                    .1;
                let in_up_set = st
                    .iter()
                    .find(|(ke, _)| *ke == k)
                    .and_then(|(_, first)| *first)
                    .is_some_and(|f| k_c >= f);
                let cert = t.text(r, "certified").unwrap();
                assert_eq!(cert == "yes", in_up_set, "{solver} ({k}, {k_c}): {cert}");
                assert!(!t.text(r, "void_reason").unwrap().contains("exact MPC"));
            }
        }
    }
    // The 2-D thresholds read from the same file: the linear region holds exactly the pairs
    // whose ρ_lin is < 1 at every pair above them; the certificate is not computed.
    let th = pair_thresholds(&t, IterationCost::default(), &[]);
    assert_eq!(th.len(), 2);
    // The certified boundary is the joint certificate's, K_e by K_e (computed, nothing
    // certified on this small grid).
    for (m, st) in sweep.certified_boundaries() {
        assert_eq!(st.len(), sweep.config().k_grid.len(), "{m}");
        let direct = xtask::sweep_engine::certified_boundary(
            sweep.resolved(),
            *m,
            sweep.config().controller,
            &sweep.config().k_grid,
        );
        assert_eq!(&direct, st, "{m}");
    }
    for p in &th {
        let rho = |k: usize, k_c: usize| {
            (0..t.rows.len())
                .find(|&r| {
                    t.text(r, "solver") == Some(p.solver.as_str())
                        && t.text(r, "k") == Some(k.to_string().as_str())
                        && t.text(r, "k_c") == Some(k_c.to_string().as_str())
                })
                .and_then(|r| t.number(r, "rho_lin"))
                .unwrap()
        };
        for &(k_e, first) in p.linear_boundary.as_ref().unwrap() {
            for k_c in [1, 5] {
                let above = [1usize, 10].iter().filter(|&&ke| ke >= k_e).all(|&ke| {
                    [1usize, 5]
                        .iter()
                        .filter(|&&kc| kc >= k_c)
                        .all(|&kc| rho(ke, kc) < 1.0)
                });
                assert_eq!(
                    first.is_some_and(|f| k_c >= f),
                    above,
                    "{} ({k_e}, {k_c})",
                    p.solver
                );
            }
        }
        assert!(p.cheapest_certified.is_none() && p.certified_boundary.is_empty());
    }
}

#[test]
fn two_d_shards_merge_to_the_unsharded_sweep() {
    use xtask::sweep_engine::{Shard, merge_point_dirs};
    let sweep = Sweep::new(config("")).unwrap();
    let whole = scratch("shard-whole");
    run(&sweep, &whole, 2);
    let shards: Vec<PathBuf> = (1..=3).map(|i| scratch(&format!("shard-{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        let r = sweep
            .run(
                &RunOptions {
                    out_dir: d.clone(),
                    threads: 1,
                    shard: Some(Shard {
                        index: i + 1,
                        count: 3,
                    }),
                },
                &NoProgress,
            )
            .unwrap();
        assert!(!r.assembled);
    }
    let merged = scratch("shard-merged");
    let dirs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    assert_eq!(
        merge_point_dirs(&sweep, &dirs, &merged, &NoProgress).unwrap(),
        8
    );
    assert_eq!(outputs(&merged), outputs(&whole));
    // The merged directory records its settings: a rerun there computes nothing.
    assert!(merged.join("points").join("settings.txt").is_file());
    let r = run(&sweep, &merged, 2);
    assert_eq!((r.computed, r.skipped), (0, 8));
}
