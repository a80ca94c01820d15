//! The case study of a double integrator as a library call: Theorem 1's K_min per method,
//! the simulations it decides, and the trajectory check (README of mhe-report); with the
//! feature `figures`, the paper's figures of the runs as SVG files too
//! (`cargo run -p mhe-report --features figures --example first_report`).

use closed_loop::scenario::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scenario = Scenario::from_toml_str(
        r#"name = "double-integrator"
        plant = { a = [[1.0, 0.1], [0.0, 1.0]], b = [[0.005], [0.1]], c = [[1.0, 0.0]] }
        sets = { input = { lower = -1, upper = 1 }, disturbance = { lower = -0.01, upper = 0.01 } }
        simulation = { x0 = [1.0, 0.0], steps = 60 }
        mhe = { horizon = 10, eta = 0.8, iterations = 20 }
        mpc = { horizon = 10 }"#,
    )?;
    let report = mhe_report::report(
        scenario,
        &mhe_report::Options::default(),
        &mhe_report::Quiet,
    )?;
    for s in &report.certificate.solvers {
        println!("{:<14} K_min = {:?}", s.solver.name(), s.k_min);
    }
    for run in &report.runs {
        println!(
            "simulated K = {}: sup‖e‖ = {:.3e}",
            run.summary.k, run.summary.sup_norm_e
        );
    }
    println!(
        "Props. 1 and 3 hold on the K_min run: {:?}",
        report.trajectory_check.passed
    );
    #[cfg(feature = "figures")]
    {
        // Fig. 2(a)–(c), the norms and the component grids, as `cargo xtask reproduce` draws
        // them (Fig. 2(c) shows the MHE window at t = 6, as in the paper).
        let drawn = mhe_report::figures::render(&report.scenario, &report.runs, 6);
        let dir = std::env::temp_dir().join(format!("mhe-report-example-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        for (name, svg) in &drawn.files {
            std::fs::write(dir.join(name), svg)?;
        }
        let names: Vec<&str> = drawn.files.iter().map(|(n, _)| n.as_str()).collect();
        println!("figures: {}", names.join(", "));
        assert!(names.contains(&"fig2a_x1.svg"), "Fig. 2(a) is drawn");
        for note in &drawn.notes {
            println!("note: {note}");
        }
        std::fs::remove_dir_all(&dir)?;
    }
    Ok(())
}
