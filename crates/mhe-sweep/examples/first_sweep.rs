//! A first sweep: the closed loop of Alg. 1 on a double integrator at K = 1, 3, 10, 30
//! with projected gradient, 4 seeds per K; then the thresholds (K_lin, K_reg, K_emp,
//! K_cert, or why there is none) from `points.csv`; with the feature `plots`, its band
//! charts over K as SVG text.
//!
//! `cargo run --release -p mhe-sweep --features plots --example first_sweep`

use mhe_sweep::{
    NoProgress, RunOptions, Sweep, SweepConfig, Table, thresholds, thresholds_markdown,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::temp_dir().join(format!("mhe-sweep-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    std::fs::write(
        dir.join("plant.toml"),
        r#"name = "double-integrator"
        plant = { a = [[1.0, 0.1], [0.0, 1.0]], b = [[0.005], [0.1]], c = [[1.0, 0.0]] }
        sets = { input = { lower = -1, upper = 1 }, disturbance = { lower = -0.01, upper = 0.01 } }
        simulation = { x0 = [1.0, 0.0], steps = 60 }
        mhe = { horizon = 10, eta = 0.8, iterations = 20 }
        mpc = { horizon = 10 }"#,
    )?;
    let config = SweepConfig::from_toml_str(
        r#"name = "first"
        scenario = "plant.toml"
        k = [1, 3, 10, 30]
        solvers = ["pg"]
        seeds = 4"#,
        &dir,
    )?;
    let sweep = Sweep::new(config)?;
    let options = RunOptions {
        out_dir: dir.join("out"),
        threads: 2,
        shard: None,
    };
    let report = sweep.run(&options, &NoProgress)?;
    println!(
        "{} points, {} steps simulated",
        report.computed, report.steps_simulated
    );

    let points = Table::parse(&std::fs::read_to_string(dir.join("out/points.csv"))?)?;
    let rows = thresholds(&points);
    assert!(rows[0].k_emp.is_some(), "K = 30 keeps every run bounded");
    print!("{}", thresholds_markdown(&rows));
    #[cfg(feature = "plots")]
    {
        // A 1-D sweep: no (K_e, K_c) pairs, so band charts over K (`cargo xtask sweep`'s).
        let plots = mhe_sweep::plots::draw(&sweep, &points, &[])?;
        let names: Vec<&str> = plots.iter().map(|(n, _)| n.as_str()).collect();
        println!("plots: {}", names.join(", "));
        assert!(
            names.contains(&"bounded.svg"),
            "the bounded fraction is drawn"
        );
    }
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}
