//! `cargo xtask`: the project's task runner (argument parsing and file output only; the
//! numerics live in the library crates).
//!
//! - `cargo xtask certify --scenario FILE [--json OUT] [--eta X] [--p-file P.json] [--loop [--global-seconds S]]`
//! - `cargo xtask sweep --config FILE.toml [--out DIR] [--threads N] [--shard I/N]`,
//!   `cargo xtask sweep-merge --config FILE.toml --out DIR [SHARD_DIR...]` (docs/sweeps.md)
//! - `cargo xtask export --scenario FILE --out DIR [--method M] [--k K|certified]
//!   [--kc K_C|certified] [--mpc-method M] [--scalar f64|f32] [--lang rust|c]
//!   [--allow-uncertified]` (docs/embedded.md)
//! - `cargo xtask reproduce [--preset paper|certified] [--scenario FILE] [--out DIR]
//!   [--gamma13 G] [--fig2c-t T] [--sim-k-cap K] [-v]`
//!
//! Exit codes (docs/limits.md): 0 success, 1 error (bad input, I/O), 2 usage error, 3 a
//! certificate check failed (certify: LMI (2) infeasible or a supplied P rejected;
//! reproduce: an inequality of Props. 1–3 is violated beyond the rounding floor with the
//! certificate's constants — nothing else), 4 reproduce: a simulated run diverged (the
//! bounded rule of `closed_loop::bounded`) or stopped early and no inequality was violated,
//! 5 the work completed and its files were written but stdout or stderr could not be
//! written (closed, closed pipe, full device — `--help` included; [`console`]).

#[macro_use]
mod console;
mod output;

mod budget;
mod certify;
mod export;
mod kernel_env;
mod provenance;
mod reproduce;
mod sweep;
#[cfg(test)]
mod test_dir;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

use crate::certify::{CertifyRequest, Outcome, certify, write_json};

/// Exit code when the certificate check fails.
const EXIT_FAIL: u8 = 3;

#[derive(Debug, Parser)]
#[command(
    name = "cargo xtask",
    version,
    about = "Task runner of the suboptimal-mhe workspace"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Monte-Carlo sweep over the iteration budget K (docs/sweeps.md).
    Sweep(sweep::SweepArgs),
    /// Export the certified estimator (and with --kc the K_c-iteration MPC) for a
    /// microcontroller: no_std Rust or C, with certificate.json, a replay and a loop program
    /// (docs/embedded.md).
    Export(export::ExportArgs),
    /// Assemble the point files of sharded sweep runs into runs.csv, points.csv and plots.
    SweepMerge(sweep::MergeArgs),
    /// Compute (or verify) the δ-IOSS certificate P of LMI (2) for a scenario.
    Certify {
        /// Scenario file (TOML, docs/scenario-format.md).
        #[arg(long)]
        scenario: PathBuf,
        /// Write the certificate as JSON here (docs/certificate-json.md).
        #[arg(long, value_name = "OUT.json")]
        json: Option<PathBuf>,
        /// Decay rate η ∈ [0, 1); overrides `mhe.eta` of the scenario.
        #[arg(long, allow_negative_numbers = true)]
        eta: Option<f64>,
        /// Verify this P instead of computing one: JSON array of rows, `{"p": ...}`, or a
        /// certificate written by `--json`.
        #[arg(long, value_name = "P.json")]
        p_file: Option<PathBuf>,
        /// Also per method: the linear boundary K_lin, Theorem 1's K_min and the global loop
        /// certificate's K_glob (docs/theory.md §4), each phase budgeted.
        #[arg(long = "loop")]
        loop_methods: bool,
        /// Budget (estimated seconds of one core) of the global loop certificate's φ*
        /// searches [default: the scenario's certificate.phase_seconds]; beyond it: "not
        /// computed within the budget".
        #[arg(long, value_name = "S", requires = "loop_methods")]
        global_seconds: Option<f64>,
    },
    /// The case study: Theorem 1's certificate per solver, the closed loop of Alg. 1, the
    /// Prop. 1/3 trajectory check, certificate.json, trace.json and SVG figures
    /// (docs/reproduce-output.md). Without --preset/--scenario: both presets.
    Reproduce {
        /// Run one preset only (`paper`: M = 5, η = 0.8, K = 652, certificate void;
        /// `certified`: M = 9, simulated at the computed K_min).
        #[arg(long, value_enum, conflicts_with = "scenario")]
        preset: Option<reproduce::Preset>,
        /// Run your own scenario (needs [mhe] and [mpc]) into DIR/<file stem>.
        #[arg(long, value_name = "FILE")]
        scenario: Option<PathBuf>,
        /// Output directory [default: target/reproduce in the workspace].
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Use this γ₁,₃ (Assumption 4) instead of computing it: reported as user-supplied,
        /// not verified, and refused when the sampled lower estimate exceeds it. Overrides
        /// the scenario's `certificate.gamma13`.
        #[arg(long, value_name = "G")]
        gamma13: Option<f64>,
        /// Time step of Fig. 2(c) (ŵ² of the MHE window at t), 0 ≤ t < simulation.steps
        /// [default: 6 for the presets, M + 1 for a scenario].
        #[arg(long = "fig2c-t", value_name = "T")]
        fig2c_t: Option<usize>,
        /// Simulate at the computed K_min only if K_min ≤ K (a long horizon's unscaled
        /// method can need millions); a K_min above it is reported as skipped, with the cap.
        #[arg(long = "sim-k-cap", value_name = "K")]
        sim_k_cap: Option<usize>,
        /// Also print each phase with its work and timing, the premises, the paper's
        /// constants, the trajectory check and the long reasons (all in summary.md anyway).
        #[arg(short, long)]
        verbose: bool,
    },
}

fn report(outcome: &Outcome, json: Option<&Path>) -> Result<()> {
    outln!("{}", outcome.summary);
    if let Some(path) = json {
        write_json(&outcome.document, path)?;
        outln!("wrote {}", path.display());
    }
    Ok(())
}

fn run(cli: Cli) -> Result<ExitCode> {
    kernel_env::set_from_env()?;
    match cli.command {
        Command::Sweep(args) => sweep::sweep(&args).map(|()| ExitCode::SUCCESS),
        Command::SweepMerge(args) => sweep::merge(&args).map(|()| ExitCode::SUCCESS),
        Command::Export(args) => export::export(&args).map(|()| ExitCode::SUCCESS),
        Command::Certify {
            scenario,
            json,
            eta,
            p_file,
            loop_methods,
            global_seconds,
        } => {
            if let Some(path) = &json {
                output::check_out_file(path, "--json")?;
            }
            let outcome = certify(&CertifyRequest {
                scenario,
                eta,
                p_file,
                loop_methods,
                global_seconds,
            })?;
            report(&outcome, json.as_deref())?;
            Ok(if outcome.document.passed {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(EXIT_FAIL)
            })
        }
        Command::Reproduce {
            preset,
            scenario,
            out,
            gamma13,
            fig2c_t,
            sim_k_cap,
            verbose,
        } => reproduce::main(preset, scenario, out, gamma13, fig2c_t, sim_k_cap, verbose),
    }
}

/// Set it (to anything) to have the command print, on stderr at exit, how often it solved
/// LMI (2), validated `[mhe]`, built ℙ_t and the MPC, and built an estimator
/// (`lti_model::work_count`).
const WORK_COUNT_ENV: &str = "SUBOPTIMAL_MHE_COUNT_WORK";

fn main() -> ExitCode {
    console::check_streams_at_start();
    // Not `Cli::parse()`: clap would print the help and exit 0 even when stdout is full.
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return console::exit_code(console::clap_message(&e)),
    };
    let code = match run(cli) {
        Ok(code) => code,
        Err(e) => {
            errln!("error: {e:#}");
            ExitCode::FAILURE
        }
    };
    // The once-per-scenario computations of this process (P, the [mhe] settings, ℙ_t, the
    // MPC, the estimators built): the evidence a test compares with the scenarios and runs.
    if std::env::var_os(WORK_COUNT_ENV).is_some() {
        errln!("work: {}", lti_model::work_count::summary());
    }
    console::exit_code(code)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn parses_certify_arguments() {
        let cli = Cli::try_parse_from([
            "xtask",
            "certify",
            "--scenario",
            "s.toml",
            "--json",
            "o.json",
            "--eta",
            "0.9",
            "--p-file",
            "p.json",
        ])
        .unwrap();
        match cli.command {
            Command::Certify {
                scenario,
                json,
                eta,
                p_file,
                loop_methods,
                ..
            } => {
                assert!(!loop_methods);
                assert_eq!(scenario, PathBuf::from("s.toml"));
                assert_eq!(json, Some(PathBuf::from("o.json")));
                assert_eq!(eta, Some(0.9));
                assert_eq!(p_file, Some(PathBuf::from("p.json")));
            }
            other => panic!("{other:?}"),
        }
        // --scenario is required; a negative η parses (and is rejected later with a message).
        assert!(Cli::try_parse_from(["xtask", "certify"]).is_err());
        assert!(
            Cli::try_parse_from(["xtask", "certify", "--scenario", "s", "--eta", "-0.1"]).is_ok()
        );
        assert!(
            Cli::try_parse_from(["xtask", "certify", "--scenario", "s", "--eta", "x"]).is_err()
        );
    }
}
