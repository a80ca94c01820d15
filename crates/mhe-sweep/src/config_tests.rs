//! Unit tests of the sweep config (validation messages, grids, fingerprints).

#![allow(clippy::unwrap_used)]
use super::*;

fn cfg(extra: &str) -> Result<SweepConfig> {
    SweepConfig::from_toml_str(
        &format!("name = 'x'\nscenario = 's.toml'\nsolvers = ['pg']\nseeds = 2\n{extra}"),
        Path::new("/base"),
    )
}

fn key_of(e: SweepError) -> String {
    match e {
        SweepError::Config { key, .. } => key,
        other => panic!("not a config error: {other}"),
    }
}

#[test]
fn config_errors_name_the_key() {
    assert_eq!(key_of(cfg("k = []").unwrap_err()), "k");
    assert_eq!(key_of(cfg("k = [1, 0]").unwrap_err()), "k[1]");
    assert_eq!(
        key_of(cfg("k = { from = 0, to = 5, points = 3 }").unwrap_err()),
        "k.from"
    );
    assert_eq!(
        key_of(cfg("k = { from = 9, to = 5, points = 3 }").unwrap_err()),
        "k.to"
    );
    assert_eq!(
        key_of(cfg("k = { from = 1, to = 5 }").unwrap_err()),
        "k.points"
    );
    assert_eq!(key_of(cfg("k = [1]\nseeds2 = 3").unwrap_err()), "seeds2");
    let e = SweepConfig::from_toml_str(
        "name='x'\nscenario='s'\nk=[1]\nsolvers=['pg','newton']\nseeds=1",
        Path::new("."),
    )
    .unwrap_err();
    assert_eq!(key_of(e), "solvers[1]");
    let e = SweepConfig::from_toml_str(
        "name='x'\nscenario='s'\nk=[1]\nsolvers=['pg']\nseeds=-4",
        Path::new("."),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("`seeds`") && e.to_string().contains("-4"),
        "{e}"
    );
    assert_eq!(
        key_of(cfg("k = [1]\nscales = [-1.0]").unwrap_err()),
        "scales[0]"
    );
    assert_eq!(
        key_of(cfg("k = [1]\nmetrics = ['sup_eps']").unwrap_err()),
        "metrics[0]"
    );
    assert_eq!(
        key_of(cfg("k = [1]\ncontroller = 'pid'").unwrap_err()),
        "controller"
    );
    assert_eq!(
        key_of(
            cfg("k = [1]\ncontroller = { kind = 'suboptimal-mpc', iterations = 0 }").unwrap_err()
        ),
        "controller.iterations"
    );
    assert_eq!(
        key_of(cfg("k = [1]\nbounded_factor = 0").unwrap_err()),
        "bounded_factor"
    );
    assert_eq!(key_of(cfg("k = [1]\nsteps = 100001").unwrap_err()), "steps");
    assert_eq!(
        key_of(cfg("k = [1]\ncertificate = 1").unwrap_err()),
        "certificate"
    );
    assert_eq!(
        key_of(cfg("k = [1]\nbase_seed = -1").unwrap_err()),
        "base_seed"
    );
    assert_eq!(key_of(cfg("k = 5").unwrap_err()), "k");
    assert_eq!(key_of(cfg("k = [1]\nscales = []").unwrap_err()), "scales");
    assert!(matches!(cfg("k = [1").unwrap_err(), SweepError::Toml(_)));
}

#[test]
fn config_defaults_and_resolution() {
    let c = cfg("k = [20, 1, 5, 5]").unwrap();
    assert_eq!(c.k_grid, vec![1, 5, 20]);
    assert_eq!(c.scenario, Path::new("/base/s.toml"));
    assert!(!c.exact_mhe_solve);
    assert!(!c.metrics.contains(&Metric::SupEps));
    assert_eq!(c.controller, ControllerChoice::ExactMpc);
    let c = cfg("k = [1]\nexact_mhe_solve = true\ncontroller = { kind = 'suboptimal-mpc', iterations = 7, solver = 'fista' }").unwrap();
    assert!(c.metrics.contains(&Metric::SupEps));
    assert_eq!(
        c.controller,
        ControllerChoice::suboptimal(7, Method::FISTA).unwrap()
    );
    let c = cfg("k = [1, 2]\nscales = [0.5, 1]").unwrap();
    let pts = c.points();
    assert_eq!(pts.len(), 4);
    assert_eq!((pts[2].k, pts[2].scale, pts[2].scale_index), (1, 1.0, 1));
    assert!(pts.iter().enumerate().all(|(i, p)| p.index == i));
}

#[test]
fn type_errors_and_unknown_keys_name_the_full_path() {
    for (extra, key) in [
        ("k = [1, 'a']", "k[1]"),
        ("k = { from = 1, to = 5, points = 'x' }", "k.points"),
        ("k = { from = 1, to = 5, points = 3, step = 2 }", "k.step"),
        ("k = [1]\nscales = [1, 'a']", "scales[1]"),
        ("k = [1]\nsteps = 'many'", "steps"),
        ("k = [1]\nmetrics = ['sup_e', 4]", "metrics[1]"),
        (
            "k = [1]\ncontroller = { kind = 'suboptimal-mpc', iterations = 'x' }",
            "controller.iterations",
        ),
        (
            "k = [1]\ncontroller = { kind = 'suboptimal-mpc', iterations = 3, extra = 1 }",
            "controller.extra",
        ),
        ("k = [1]\ncontroller = 7", "controller"),
        ("k = [1]\nexact_mhe_solve = 'yes'", "exact_mhe_solve"),
    ] {
        let e = cfg(extra).unwrap_err();
        let text = e.to_string();
        assert_eq!(key_of(e), key, "{extra}: {text}");
        assert!(text.contains("line "), "{extra}: no line in {text}");
    }
    // An unknown key says how to fix it; a syntax error gives the line.
    let e = cfg("k = [1]\nseedz = 2").unwrap_err().to_string();
    assert!(
        e.contains("`seedz`") && e.contains("correct its spelling"),
        "{e}"
    );
    let e = cfg("k = [1]\nsteps = = 3").unwrap_err();
    assert!(
        matches!(&e, SweepError::Toml(m) if m.contains("line 6")),
        "{e}"
    );
}
