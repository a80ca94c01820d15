//! `cargo xtask export`: the flags of the crate `mhe-export` (docs/embedded.md). This file
//! parses them into [`mhe_export::ExportOptions`] (checked before any work: `--k`, `--kc`,
//! `--method`, `--mpc-method`, `--out`, `--prefix`, then the scenario's sections), reads
//! the scenario, prints the library's progress and the one-line result; the certificate,
//! the verdict and every file are the library's.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use closed_loop::scenario::Scenario;
use mhe_export::{ExportOptions, Iterations, Source, check_output_dir};
use qp_iter::Method;

use crate::provenance::Provenance;

/// The scalar of the exported code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScalarKind {
    /// Double precision: bit for bit the std build on the portable kernel.
    F64,
    /// Single precision (data rounded to f32 once): certified where the method's rounding
    /// model (every method; FISTA and FISTA-Jacobi only where V-FISTA's incremental rate
    /// exists on the (scaled) window)
    /// leaves Theorem 1 or Theorem L3 a K with the rounding as an input, else refused
    /// unless --allow-uncertified.
    F32,
}

/// The language of the artefact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Lang {
    /// A Cargo package (no_std library + std replay binary).
    Rust,
    /// C99 sources, a Makefile and Cortex-M start-up files.
    C,
}

/// `cargo xtask export` arguments.
#[derive(Debug, Clone, Args)]
pub struct ExportArgs {
    /// Scenario file (TOML, docs/scenario-format.md) with [mhe] and [mpc].
    #[arg(long)]
    pub scenario: PathBuf,
    /// Output directory: created, or replaced as a whole when it holds an earlier export
    /// (its `certificate.json`); any other existing path is refused.
    #[arg(long, value_name = "DIR", required_unless_present = "survey")]
    pub out: Option<PathBuf>,
    /// The method (`pg`, `fista`, `admm`, `admm-pr`, `pg-jacobi`, …) [default: the
    /// scenario's `mhe.method`].
    #[arg(long)]
    pub method: Option<String>,
    /// Iterations K per step: a number, or `certified` for the smallest K the one verdict
    /// certifies in the exported scalar (Theorem 1's K_min, Theorem L3's K_glob or the
    /// iteration chain's K; with --kc, the joint certificate's K for that K_c).
    #[arg(long, default_value = "certified", allow_hyphen_values = true)]
    pub k: String,
    /// The scalar of the exported code.
    #[arg(long, value_enum, default_value = "f64")]
    pub scalar: ScalarKind,
    /// The language of the artefact.
    #[arg(long, value_enum, default_value = "c")]
    pub lang: Lang,
    /// Also export the K_c-iteration MPC (the whole certified loop): K_c iterations, or
    /// `certified` for the joint certificate's floor at the exported K [default: the
    /// scenario's `mpc.iterations` when set, else no MPC].
    #[arg(long, value_name = "K_C", allow_hyphen_values = true)]
    pub kc: Option<String>,
    /// The MPC's method [default: the scenario's `mpc.method`]; only with an exported MPC.
    #[arg(long)]
    pub mpc_method: Option<String>,
    /// Export even when K (or K_c) is below its certified floor or the certificate is void
    /// (the artefact says so).
    #[arg(long)]
    pub allow_uncertified: bool,
    /// C only: the prefix of every generated name (`{prefix}_reset`, `{PREFIX}_NX`, files
    /// `{prefix}.h`, …), so several estimators link into one firmware.
    #[arg(long, default_value = "mhe")]
    pub prefix: String,
    /// The target of the "fits T_s" verdict (`cortex-m4f`, `cortex-m7`) [default: both].
    #[arg(long)]
    pub target: Option<String>,
    /// The target's clock in MHz [default: 168 for cortex-m4f, 480 for cortex-m7].
    #[arg(long, value_name = "MHZ")]
    pub clock_mhz: Option<f64>,
    /// Write no artefact: print JSON with, per method (`--method`, default all), the
    /// smallest K the verdict certifies in f64 and in f32 and the budget there
    /// (`scripts/cortex-m.sh table` picks docs/embedded.md's rows from it).
    #[arg(long, conflicts_with_all = ["out", "k", "kc", "mpc_method", "scalar", "allow_uncertified"])]
    pub survey: bool,
}

impl From<ScalarKind> for mhe_export::ScalarKind {
    fn from(s: ScalarKind) -> Self {
        match s {
            ScalarKind::F64 => Self::F64,
            ScalarKind::F32 => Self::F32,
        }
    }
}

impl From<Lang> for mhe_export::Lang {
    fn from(l: Lang) -> Self {
        match l {
            Lang::Rust => Self::Rust,
            Lang::C => Self::C,
        }
    }
}

/// A method flag (`flag` = `--method`, `--mpc-method`) parsed before any work.
fn parse_method(flag: &str, arg: Option<&str>) -> Result<Option<Method>> {
    arg.map(|m| m.parse().map_err(|e| anyhow::anyhow!("{flag} {m}: {e}")))
        .transpose()
}

/// The library's options from the flags; every flag is checked here, before any work.
fn options(args: &ExportArgs) -> Result<ExportOptions> {
    let mut o = ExportOptions::default();
    o.k = Iterations::parse("--k", &args.k)?;
    o.k_c = args
        .kc
        .as_deref()
        .map(|a| Iterations::parse("--kc", a))
        .transpose()?;
    o.method = parse_method("--method", args.method.as_deref())?;
    o.mpc_method = parse_method("--mpc-method", args.mpc_method.as_deref())?;
    if let Some(out) = &args.out {
        check_output_dir(out)?;
    }
    // The library reads an empty prefix as `mhe`; on the command line it is a mistake.
    anyhow::ensure!(
        !args.prefix.trim().is_empty(),
        "--prefix ``: empty; give a C identifier (letters, digits, `_`; not starting with a \
         digit), e.g. `--prefix mhe`"
    );
    o.prefix.clone_from(&args.prefix);
    o.validate()?;
    o.scalar = args.scalar.into();
    o.lang = args.lang.into();
    o.allow_uncertified = args.allow_uncertified;
    Ok(o)
}

/// `cargo xtask export`.
pub fn export(args: &ExportArgs) -> Result<()> {
    let mut opts = options(args)?;
    opts.budget_targets = Some(crate::budget::targets(
        args.target.as_deref(),
        args.clock_mhz,
    )?);
    let text = std::fs::read(&args.scenario)
        .with_context(|| format!("cannot read `{}`", args.scenario.display()))?;
    opts.source = Source::from_bytes(args.scenario.display().to_string(), &text);
    opts.provenance = Some(serde_json::to_value(Provenance::collect())?);
    let scenario = Scenario::from_file(&args.scenario)
        .with_context(|| format!("cannot load `{}`", args.scenario.display()))?;
    if args.survey {
        return survey(args, &opts, scenario);
    }
    let out = args.out.as_ref().context("--out DIR is required")?;
    opts.check_scenario(&scenario)?;
    let resolved = scenario
        .resolve()
        .with_context(|| format!("cannot set up `{}`", args.scenario.display()))?;
    let art = mhe_export::export_with_progress(&resolved, &opts, &mut |stage| {
        outln!("{stage}");
    })?;
    art.write_to(out)?;
    let verdict = if art.loop_certified() {
        ", certified".to_string()
    } else {
        format!(
            ", UNCERTIFIED ({})",
            art.uncertified_reason().unwrap_or("not certified")
        )
    };
    let mpc = art.mpc().map_or_else(String::new, |(m, k_c)| {
        format!(", MPC {m} with K_c = {k_c}")
    });
    outln!(
        "wrote the {} artefact for `{}` ({}, K = {}{verdict}{mpc}) to {}",
        match args.lang {
            Lang::Rust => "Rust",
            Lang::C => "C",
        },
        art.scenario(),
        art.method(),
        art.k(),
        out.display()
    );
    for b in art.budgets() {
        outln!("  {} at {} MHz: {}", b.target, b.clock_mhz, b.summary());
    }
    if let Some(note) = art.budget_note() {
        outln!("  {note}");
    }
    Ok(())
}

/// `cargo xtask export --survey`: the library's survey as JSON on stdout.
fn survey(args: &ExportArgs, opts: &ExportOptions, scenario: Scenario) -> Result<()> {
    let methods: Vec<Method> = parse_method("--method", args.method.as_deref())?
        .into_iter()
        .collect();
    let resolved = scenario
        .resolve()
        .with_context(|| format!("cannot set up `{}`", args.scenario.display()))?;
    let methods = mhe_export::survey(&resolved, opts, &methods)?;
    let doc = serde_json::json!({
        "scenario": resolved.scenario().name,
        "sample_time": resolved.scenario().sample_time,
        "methods": methods,
    });
    outln!("{}", serde_json::to_string_pretty(&doc)?);
    Ok(())
}
