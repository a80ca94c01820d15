//! `cargo xtask export`: the certified estimator as a self-contained artefact for a
//! microcontroller (docs/embedded.md).
//!
//! 1. Reads the scenario and checks every argument (`--k`, `--kc`, `--method`,
//!    `--mpc-method`, `--out`) before any work; computes the closed-loop certificate with the
//!    options every command uses (`iss_certificate::coverage::verdict_options`: the user's
//!    γ₁,₃ and the sample that can refute it) and decides K: `--k certified` (the default) is
//!    K_min of Theorem 1. The verdict on (method, K, the MPC's K_c, scalar, the scenario's
//!    warm start) is `iss_certificate::coverage::verdict`'s — the one `reproduce` and the
//!    sweep print; a configuration it does not certify is refused unless
//!    `--allow-uncertified`, which the artefact then says in its README, its headers and
//!    `certificate.json`.
//! 2. Builds the std `MheEstimator` with that method and K on the portable kernel and copies
//!    its numbers out ([`extract`]).
//! 3. Writes the artefact into a temporary sibling of `--out` and replaces `--out` with it
//!    as a whole (no file of an earlier export survives beside the new certificate): the
//!    data (a Rust module or `.c`/`.h`), the estimator source (vendored `mhe-embedded`, or
//!    `mhe.c`/`mhe.h`), the build files, the replay program, `certificate.json` and a README.

mod c_gen;
mod out;
pub(crate) use out::{EXPORT_FORMAT, check_out, replace_artefact};
pub(crate) mod extract;
mod rust_gen;
mod sha256;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_capi;
#[cfg(test)]
mod tests_firmware;
#[cfg(test)]
mod tests_mpc;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use closed_loop::scenario::{ControllerChoice, ResolvedScenario, Scenario};
use iss_certificate::certificate::{ClosedLoopCertificate, SolverCertificate, certify_closed_loop};
/// What an f32 artefact's certificate covers when its verdict is certified.
pub(crate) const F32_COVERED: &str = "covered: Theorem 1 with the f32 rounding of the \
    portable kernel folded in (docs/theory.md, \"Certified f32\") certifies this K";
/// What an f64 artefact says about f32.
const F32_DECIDED_BY: &str = "an f32 export is certified where Theorem 1 with the f32 \
    rounding folded in certifies its K (iss_certificate::coverage::verdict)";
use iss_certificate::coverage::{Configuration, PairVerdict, Scalar, verdict_options};
use iss_certificate::joint::{JointCertificate, JointOptions, certify_joint};
use iss_certificate::outcome::VoidReason;
use qp_iter::Method;
use serde_json::json;

use crate::provenance::Provenance;
use extract::{OwnedMpc, OwnedProblem, portable_estimator, portable_mpc};

/// The scalar of the exported code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScalarKind {
    /// Double precision: bit for bit the std build on the portable kernel.
    F64,
    /// Single precision (data rounded to f32 once; not covered by the certificate).
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
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The method (`pg`, `fista`, `admm`, `admm-pr`, `pg-jacobi`, …) [default: the
    /// scenario's `mhe.method`].
    #[arg(long)]
    pub method: Option<String>,
    /// Iterations K per step: a number, or `certified` for K_min of Theorem 1.
    #[arg(long, default_value = "certified")]
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
    #[arg(long, value_name = "K_C")]
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
}

/// What the generated files say about the exported MPC.
#[derive(Debug, Clone)]
pub(crate) struct MpcArtefact {
    pub method: String,
    pub k_c: usize,
    /// The joint certificate's floor K_c at the exported K (None: no K_c is certified).
    pub k_c_min: Option<usize>,
    /// (K, K_c) certified by the joint certificate ([`iss_certificate::coverage::verdict`]).
    pub certified: bool,
    /// Why not (None when certified).
    pub reason: Option<String>,
}

/// What the generated files say about themselves.
#[derive(Debug, Clone)]
pub(crate) struct Artefact<'a> {
    pub scenario: &'a str,
    pub method: String,
    pub k: usize,
    pub k_min: Option<usize>,
    pub scalar: ScalarKind,
    /// The verdict on (method, K, scalar, warm start) with Theorem 1
    /// ([`iss_certificate::coverage::verdict`]).
    pub certified: bool,
    /// Why not (None when certified).
    pub reason: Option<String>,
    pub prior: Vec<f64>,
    pub sha256: String,
    /// The exported MPC, if any.
    pub mpc: Option<MpcArtefact>,
}

impl Artefact<'_> {
    /// The certificate that covers the exported loop holds: Theorem 1 for K (estimator
    /// only), and the joint certificate at (K, K_c) when the MPC is exported.
    pub(crate) fn loop_certified(&self) -> bool {
        self.certified && self.mpc.as_ref().is_none_or(|m| m.certified)
    }

    /// The banner of every generated file, each line starting with `prefix`.
    pub(crate) fn banner(&self, prefix: &str) -> String {
        let mut lines = vec![format!(
            "Scenario `{}` (SHA-256 {}), method {}, K = {}, scalar {}.",
            self.scenario,
            self.sha256,
            self.method,
            self.k,
            scalar_name(self.scalar)
        )];
        match (self.certified, self.k_min) {
            (true, Some(k)) => lines.push(format!(
                "Certified: K = {} ≥ K_min = {k} of Theorem 1 (certificate.json), in {}.",
                self.k,
                scalar_name(self.scalar)
            )),
            _ => lines.push(format!(
                "UNCERTIFIED: {}; exported with --allow-uncertified.",
                self.reason
                    .as_deref()
                    .unwrap_or("see certificate.json `uncertified_reason`")
            )),
        }
        if let Some(m) = &self.mpc {
            lines.push(match (m.certified, m.k_c_min) {
                (true, _) => format!(
                    "MPC: {}, K_c = {}; the loop (K, K_c) is certified by the joint certificate \
                     (certificate.json `mpc.joint`), in f64.",
                    m.method, m.k_c
                ),
                (false, Some(f)) if m.k_c < f => format!(
                    "MPC: {}, K_c = {}: UNCERTIFIED, the joint certificate needs K_c ≥ {f} at \
                     K = {}; exported with --allow-uncertified.",
                    m.method, m.k_c, self.k
                ),
                (false, None) if m.reason.is_none() => format!(
                    "MPC: {}, K_c = {}: UNCERTIFIED, no K_c is certified with K = {} by the joint \
                     certificate; exported with --allow-uncertified.",
                    m.method, m.k_c, self.k
                ),
                (false, _) => format!(
                    "MPC: {}, K_c = {}: UNCERTIFIED, {}; exported with --allow-uncertified.",
                    m.method,
                    m.k_c,
                    m.reason.as_deref().unwrap_or("not certified")
                ),
            });
        }
        if self.scalar == ScalarKind::F32 && self.certified {
            lines.push(format!("f32: {F32_COVERED}."));
        }
        lines
            .iter()
            .map(|l| format!("{prefix}{l}"))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

fn scalar_name(s: ScalarKind) -> &'static str {
    match s {
        ScalarKind::F64 => "f64",
        ScalarKind::F32 => "f32",
    }
}

/// The closed-loop certificate of one MHE method for a resolved scenario, with the options
/// that decide every command's verdict ([`verdict_options`]: a user γ₁,₃ is tested by the
/// same sample as in `reproduce`).
pub(crate) fn closed_loop_certificate(
    resolved: &ResolvedScenario,
    method: Method,
) -> Result<ClosedLoopCertificate> {
    let sc = resolved.scenario();
    let opts = verdict_options(sc, vec![method], None);
    certify_closed_loop(resolved, &opts)
        .with_context(|| format!("cannot compute the certificate of `{}`", sc.name))
}

fn solver_entry(cert: &ClosedLoopCertificate, method: Method) -> Result<SolverCertificate> {
    cert.solver(method)
        .cloned()
        .with_context(|| format!("the certificate has no entry for {}", method.name()))
}

/// An iteration count from the command line: `certified` or a number ≥ 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Iterations {
    /// The certified floor (K_min, or the joint certificate's K_c at the exported K).
    Certified,
    /// A given count.
    Given(usize),
}

/// Parses `--k` / `--kc` (`flag`) before any work.
pub(crate) fn parse_iterations(flag: &str, arg: &str) -> Result<Iterations> {
    if arg == "certified" {
        return Ok(Iterations::Certified);
    }
    arg.parse()
        .ok()
        .filter(|k| *k >= 1)
        .map(Iterations::Given)
        .with_context(|| format!("{flag} {arg}: expected an integer ≥ 1 or `certified`"))
}

fn coverage_scalar(s: ScalarKind) -> Scalar {
    match s {
        ScalarKind::F64 => Scalar::F64,
        ScalarKind::F32 => Scalar::F32,
    }
}

/// Why a verdict is not "certified" (None when it is), in the artefact's words.
fn uncertified_reason(v: &PairVerdict, what: &str) -> Option<String> {
    // Decided by the library's methods: any other verdict (void, not computed, or one this
    // tool does not know) is refused with its reason.
    if v.certified.is_certified() {
        None
    } else if v.certified.is_below_floor() {
        Some(match v.k_min {
            Some(k_min) => format!("{what} is below the certified floor {k_min}"),
            None => format!("{what} is not certified"),
        })
    } else {
        Some(v.reason_text())
    }
}

/// K from `--k` and the verdict on (method, K, the exact MPC, `scalar`) of
/// [`iss_certificate::coverage::verdict`]: K and the verdict. `--k certified` is K_min of
/// Theorem 1; a configuration the verdict does not certify is refused unless
/// `allow_uncertified`.
pub(crate) fn decide_k(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    method: Method,
    k_arg: Iterations,
    scalar: ScalarKind,
    allow_uncertified: bool,
) -> Result<(usize, PairVerdict)> {
    let sc = solver_entry(cert, method)?;
    let name = method.name();
    let k = match (k_arg, sc.k_min) {
        (Iterations::Given(k), _) => k,
        (Iterations::Certified, Some(k)) => k,
        (Iterations::Certified, None) => bail!(
            "--k certified: the certificate of Theorem 1 is void for {name} ({}); give --k K \
             with --allow-uncertified to export anyway",
            VoidReason::join(&sc.void_reasons)
        ),
    };
    let config = Configuration {
        method,
        k_e: k,
        controller: ControllerChoice::ExactMpc,
        scalar: coverage_scalar(scalar),
    };
    let v = iss_certificate::coverage::verdict(resolved, cert, &config);
    let flag = match k_arg {
        Iterations::Certified => format!("--k certified (K = {k})"),
        Iterations::Given(_) => format!("--k {k}"),
    };
    if v.certified.is_certified() || allow_uncertified {
        return Ok((k, v));
    }
    if v.certified.is_below_floor() {
        match v.k_min {
            Some(k_min) => bail!(
                "{flag}: below the certified K_min = {k_min} of Theorem 1 for {name}; use \
                 --k certified (or K ≥ {k_min}), or --allow-uncertified to export an uncertified \
                 estimator"
            ),
            None => bail!(
                "{flag}: not certified for {name}; --allow-uncertified exports an uncertified \
                 estimator"
            ),
        }
    }
    bail!(
        "{flag}: NOT CERTIFIED for {name} (the verdict `reproduce` gives): {}; \
         --allow-uncertified exports anyway, and the artefact says so",
        v.reason_text()
    )
}

/// The joint certificate (MHE `mhe` + MPC `mpc_method`, shift-and-repeat warm start) of a
/// resolved scenario from its closed-loop certificate `cert` (which has `mhe`).
pub(crate) fn joint_certificate(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    mhe: Method,
    mpc_method: Method,
) -> Result<JointCertificate> {
    let sc = resolved.scenario();
    let mpc = resolved.mpc()?;
    let (nx, ny) = (sc.plant.nx(), sc.plant.ny());
    let n_e = nx + cert.horizon * (nx + ny);
    certify_joint(cert, mpc, n_e, mhe, mpc_method, &JointOptions::default())
        .context("cannot compute the joint MPC + MHE certificate")
}

/// K_c from `--kc` and the verdict on the loop (method, K_e = `k_e`, the K_c-iteration MPC
/// with `mpc_method`, `scalar`) of [`iss_certificate::coverage::verdict`]: K_c and the
/// verdict. `--kc certified` is the joint certificate's floor at K_e; a pair the verdict does
/// not certify is refused unless `allow_uncertified`.
pub(crate) fn decide_kc(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    joint: &JointCertificate,
    kc_arg: Iterations,
    k_e: usize,
    scalar: ScalarKind,
    allow_uncertified: bool,
) -> Result<(usize, PairVerdict)> {
    let region = &joint.region;
    let floor = joint.analysis.k_c_min(k_e, region.k_max);
    let none_reason = || {
        if !region.void_reasons.is_empty() {
            format!(
                "the joint certificate is void ({})",
                VoidReason::join(&region.void_reasons)
            )
        } else {
            format!(
                "no K_c is certified with K = {k_e} by the joint certificate (its smallest K is \
                 {}{})",
                region
                    .k_e_floor
                    .map_or_else(|| "none".to_string(), |k| k.to_string()),
                region.cheapest.map_or_else(String::new, |p| format!(
                    "; the cheapest certified pair is K = {}, K_c = {}",
                    p.k_e, p.k_c
                ))
            )
        }
    };
    let k_c = match (kc_arg, floor) {
        (Iterations::Given(k), _) => k,
        (Iterations::Certified, Some(k)) => k,
        (Iterations::Certified, None) => bail!(
            "--kc certified: {}; give a larger --k, or --kc K with --allow-uncertified",
            none_reason()
        ),
    };
    let config = Configuration {
        method: joint.mhe_method,
        k_e,
        controller: ControllerChoice::SuboptimalMpc {
            iterations: k_c,
            method: joint.mpc_method,
        },
        scalar: coverage_scalar(scalar),
    };
    let v = iss_certificate::coverage::verdict(resolved, cert, &config);
    if v.certified.is_certified() || allow_uncertified {
        return Ok((k_c, v));
    }
    if v.certified.is_below_floor() {
        match floor {
            Some(f) => bail!(
                "--kc {k_c}: below the joint certificate's floor K_c = {f} at K = {k_e} (MHE {}, MPC \
             {}); use --kc certified (or K_c ≥ {f}), or --allow-uncertified to export an \
             uncertified loop",
                joint.mhe_method,
                joint.mpc_method
            ),
            None => bail!(
                "--kc {k_c}: {}; --allow-uncertified exports anyway",
                none_reason()
            ),
        }
    }
    bail!(
        "--kc {k_c}: NOT CERTIFIED (the verdict `reproduce` gives): {}; \
         --allow-uncertified exports anyway, and the artefact says so",
        v.reason_text()
    )
}

/// Writes `text` to `dir/name` through a temporary file and a rename (no half-written file
/// under the final name), creating parent directories.
fn write_file(dir: &Path, name: &str, text: &str) -> Result<()> {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create directory `{}`", parent.display()))?;
    }
    let tmp = path.with_extension("export-tmp");
    std::fs::write(&tmp, text).with_context(|| format!("cannot write `{}`", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("cannot write `{}`", path.display()))
}

/// `cargo xtask export`.
pub fn export(args: &ExportArgs) -> Result<()> {
    // Every argument is checked before the certificate (seconds to minutes).
    let k_arg = parse_iterations("--k", &args.k)?;
    let kc_flag = args
        .kc
        .as_deref()
        .map(|a| parse_iterations("--kc", a))
        .transpose()?;
    let method_flag: Option<Method> = args
        .method
        .as_deref()
        .map(|m| m.parse().map_err(|e| anyhow::anyhow!("--method {m}: {e}")))
        .transpose()?;
    let mpc_method_flag: Option<Method> = args
        .mpc_method
        .as_deref()
        .map(|m| {
            m.parse()
                .map_err(|e| anyhow::anyhow!("--mpc-method {m}: {e}"))
        })
        .transpose()?;
    check_out(&args.out)?;
    c_gen::check_prefix(&args.prefix)?;
    let text = std::fs::read(&args.scenario)
        .with_context(|| format!("cannot read `{}`", args.scenario.display()))?;
    let sha256 = sha256::sha256_hex(&text);
    let scenario = Scenario::from_file(&args.scenario)
        .with_context(|| format!("cannot load `{}`", args.scenario.display()))?;
    let mhe = scenario
        .mhe
        .as_ref()
        .context("the scenario has no [mhe] section: nothing to export")?;
    let method = method_flag.unwrap_or(mhe.method);
    // The MPC: asked for with --kc, or the scenario's controller (mpc.iterations).
    let mpc_spec = scenario.mpc.as_ref();
    let kc_arg = match kc_flag {
        Some(k) => {
            mpc_spec.context("--kc: the scenario has no [mpc] section: no MPC to export")?;
            Some(k)
        }
        None => mpc_spec.and_then(|m| m.iterations).map(Iterations::Given),
    };
    let mpc_method = match (&kc_arg, mpc_method_flag, mpc_spec) {
        (None, Some(m), _) => bail!(
            "--mpc-method {}: no MPC is exported (give --kc K_C or --kc certified, or set \
             mpc.iterations in the scenario), so the flag would be ignored",
            m.name()
        ),
        (None, None, _) => None,
        (Some(_), Some(m), _) => Some(m),
        (Some(_), None, Some(spec)) => Some(spec.method),
        (Some(_), None, None) => bail!("--kc: the scenario has no [mpc] section: no MPC to export"),
    };
    let resolved = scenario
        .clone()
        .resolve()
        .with_context(|| format!("cannot set up `{}`", args.scenario.display()))?;
    outln!(
        "computing the certificate of Theorem 1 for {} …",
        method.name()
    );
    let loop_cert = closed_loop_certificate(&resolved, method)?;
    let cert = solver_entry(&loop_cert, method)?;
    let (k, k_verdict) = decide_k(
        &resolved,
        &loop_cert,
        method,
        k_arg,
        args.scalar,
        args.allow_uncertified,
    )?;
    let mut est = portable_estimator(&resolved, method, k)?;
    let mut problem = OwnedProblem::from_estimator(&est, &scenario.plant)?;
    // The C self-test's stored steps (f64: the std estimator's bits; M + 2 steps).
    if args.scalar == ScalarKind::F64 {
        let steps = problem.horizon + 2;
        problem.record_self_test(&mut est, &scenario.plant, &scenario.simulation.prior, steps)?;
    }
    let mut mpc_export = None;
    if let (Some(kc_arg), Some(mpc_method)) = (kc_arg, mpc_method) {
        outln!(
            "computing the joint certificate for MHE {} + MPC {} …",
            method.name(),
            mpc_method.name()
        );
        let joint = joint_certificate(&resolved, &loop_cert, method, mpc_method)?;
        let (k_c, v) = decide_kc(
            &resolved,
            &loop_cert,
            &joint,
            kc_arg,
            k,
            args.scalar,
            args.allow_uncertified,
        )?;
        let ctrl = portable_mpc(&resolved, mpc_method, k_c)?;
        let data = OwnedMpc::from_controller(&ctrl, resolved.mpc()?)?;
        let art = MpcArtefact {
            method: mpc_method.name().into_owned(),
            k_c,
            k_c_min: joint.analysis.k_c_min(k, joint.region.k_max),
            certified: v.certified.is_certified(),
            reason: uncertified_reason(&v, &format!("K_c = {k_c}")),
        };
        mpc_export = Some((data, art, joint));
    }
    let art = Artefact {
        scenario: &scenario.name,
        method: method.name().into_owned(),
        k,
        k_min: k_verdict.k_min.or(cert.k_min),
        scalar: args.scalar,
        certified: k_verdict.certified.is_certified(),
        reason: uncertified_reason(&k_verdict, &format!("K = {k}")),
        prior: scenario.simulation.prior.clone(),
        sha256,
        mpc: mpc_export.as_ref().map(|m| m.1.clone()),
    };
    let mpc = mpc_export.as_ref().map(|(d, _, j)| (d, j));
    replace_artefact(&args.out, |dir| {
        write_artefact(dir, args.lang, &problem, mpc, &art, &cert, &args.scenario)?;
        if args.lang == Lang::C && args.prefix != "mhe" {
            c_gen::apply_prefix(dir, &args.prefix)?;
        }
        Ok(())
    })?;
    outln!(
        "wrote the {} artefact for `{}` ({}, K = {k}{}) to {}",
        match args.lang {
            Lang::Rust => "Rust",
            Lang::C => "C",
        },
        scenario.name,
        art.method,
        if art.loop_certified() {
            ", certified".to_string()
        } else {
            format!(
                ", UNCERTIFIED ({})",
                art.reason
                    .as_deref()
                    .or(art.mpc.as_ref().and_then(|m| m.reason.as_deref()))
                    .unwrap_or("not certified")
            )
        } + &art.mpc.as_ref().map_or_else(String::new, |m| format!(
            ", MPC {} with K_c = {}",
            m.method, m.k_c
        )),
        args.out.display()
    );
    Ok(())
}

/// Writes every file of the artefact into `out` (`mpc`: the MPC's data and its joint
/// certificate, when exported).
pub(crate) fn write_artefact(
    out: &Path,
    lang: Lang,
    problem: &OwnedProblem,
    mpc: Option<(&OwnedMpc, &JointCertificate)>,
    art: &Artefact<'_>,
    cert: &SolverCertificate,
    scenario_path: &Path,
) -> Result<()> {
    write_code(out, lang, problem, mpc.map(|m| m.0), art)?;
    let json = certificate_json(art, cert, mpc.map(|m| m.1), scenario_path);
    write_file(
        out,
        "certificate.json",
        &(serde_json::to_string_pretty(&json)? + "\n"),
    )?;
    let firmware = c_gen::firmware_readme(problem, mpc.map(|m| m.0), art, lang);
    write_file(out, "README.md", &(readme(art, lang) + &firmware))?;
    Ok(())
}

/// The code files of the artefact (everything but `certificate.json` and the README).
pub(crate) fn write_code(
    out: &Path,
    lang: Lang,
    problem: &OwnedProblem,
    mpc: Option<&OwnedMpc>,
    art: &Artefact<'_>,
) -> Result<()> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create directory `{}`", out.display()))?;
    match lang {
        Lang::C => {
            write_file(out, "mhe.h", c_gen::MHE_H)?;
            write_file(out, "mhe.c", c_gen::MHE_C)?;
            write_file(out, "replay.c", c_gen::REPLAY_C)?;
            write_file(out, "mpc.h", c_gen::MPC_H)?;
            write_file(out, "mpc.c", c_gen::MPC_C)?;
            write_file(out, "loop.c", c_gen::LOOP_C)?;
            write_file(out, "count.h", c_gen::COUNT_H)?;
            write_file(out, "parse.h", c_gen::PARSE_H)?;
            write_file(out, "mhe_data.h", &c_gen::data_h(problem, mpc, art))?;
            write_file(out, "mhe_data.c", &c_gen::data_c(problem, mpc, art))?;
            write_file(out, "Makefile", c_gen::MAKEFILE)?;
            write_file(out, "cortex-m/startup.c", c_gen::STARTUP_C)?;
            write_file(out, "cortex-m/link.ld", c_gen::LINK_LD)?;
        }
        Lang::Rust => {
            let package = "mhe-export";
            for (path, text) in rust_gen::VENDORED {
                write_file(out, path, text)?;
            }
            write_file(out, "Cargo.toml", &rust_gen::cargo_toml(package))?;
            write_file(out, "src/lib.rs", &rust_gen::lib_rs(art))?;
            write_file(out, "src/data.rs", &rust_gen::data_rs(problem, mpc, art))?;
            write_file(out, "src/bin/replay.rs", &rust_gen::replay_rs(package))?;
            write_file(out, "src/bin/loop.rs", &rust_gen::loop_rs(package))?;
            write_file(out, "capi/Cargo.toml", &rust_gen::capi_cargo_toml(package))?;
            write_file(out, "capi/src/lib.rs", &rust_gen::capi_lib_rs(art.scalar))?;
            write_file(out, "capi/mhe_capi.h", &rust_gen::capi_header(art.scalar))?;
            write_file(out, "capi/replay_capi.c", rust_gen::CAPI_REPLAY_C)?;
            write_file(out, "capi/loop_capi.c", rust_gen::CAPI_LOOP_C)?;
            write_file(out, "capi/parse.h", c_gen::PARSE_H)?;
        }
    }
    Ok(())
}

fn certificate_json(
    art: &Artefact<'_>,
    cert: &SolverCertificate,
    joint: Option<&JointCertificate>,
    scenario_path: &Path,
) -> serde_json::Value {
    let mpc = match (&art.mpc, joint) {
        (Some(m), Some(j)) => json!({
            "method": m.method,
            "iterations": m.k_c,
            "warm_start": j.warm_start,
            "k_c_min": m.k_c_min,
            "certified": m.certified,
            "uncertified_reason": m.reason,
            "covers": "the exported f64 MPC performs the certified K_c iterations bit for bit as \
                the std SuboptimalMpc on the portable kernel; the joint certificate holds at \
                (K, K_c) iff `certified`",
            "at_pair": j.analysis.at(art.k, m.k_c),
            "joint": j,
        }),
        _ => serde_json::Value::Null,
    };
    json!({
        "format": EXPORT_FORMAT,
        "format_version": 1,
        "scenario": {
            "name": art.scenario,
            "path": scenario_path.display().to_string(),
            "sha256": art.sha256,
        },
        "method": art.method,
        "iterations": art.k,
        "k_min": art.k_min,
        "scalar": scalar_name(art.scalar),
        "certified": art.certified,
        "loop_certified": art.loop_certified(),
        "artefact_covered": art.loop_certified() && art.scalar == ScalarKind::F64,
        "mpc": mpc,
        "uncertified_reason": art.reason.as_ref().map(|r| format!("{r}; exported with --allow-uncertified")),
        "covers": {
            "method": art.method,
            "iterations": art.k,
            "f64": if art.certified {
                "covered: the exported f64 code performs the certified iteration bit for bit as the std estimator on the portable kernel"
            } else {
                "not covered: this configuration is not certified (`uncertified_reason`)"
            },
            "f32": match (art.scalar, art.certified) {
                (ScalarKind::F32, true) => F32_COVERED,
                (ScalarKind::F32, false) => "not covered: this configuration is not certified in f32 (`uncertified_reason`)",
                (ScalarKind::F64, _) => F32_DECIDED_BY,
            },
        },
        "theorem1": cert,
        "provenance": Provenance::collect(),
    })
}

fn readme(art: &Artefact<'_>, lang: Lang) -> String {
    let status = if art.certified {
        format!(
            "**Certified**: K = {} ≥ K_min = {} of Theorem 1 for {} (`certificate.json`), for the \
             f64 build.",
            art.k,
            art.k_min.unwrap_or(art.k),
            art.method
        )
    } else {
        "**UNCERTIFIED** (exported with `--allow-uncertified`): see `uncertified_reason` in \
         `certificate.json`. No stability guarantee comes with this K."
            .to_string()
    };
    let f32_note = if art.scalar == ScalarKind::F32 {
        format!(
            "\n\nThis is an **f32** build; the certificate's cover of f32: {}.\n",
            if art.certified {
                F32_COVERED
            } else {
                "not covered (see `uncertified_reason`)"
            }
        )
    } else {
        String::new()
    };
    let mpc_note = art.mpc.as_ref().map_or_else(String::new, |m| {
        let status = if m.certified {
            format!(
                "**certified** with K = {} by the joint MPC + MHE certificate (`mpc.joint` in \
                 `certificate.json`; its floor at this K is K_c = {})",
                art.k,
                m.k_c_min.unwrap_or(m.k_c)
            )
        } else {
            "**UNCERTIFIED** (exported with `--allow-uncertified`; `mpc.k_c_min` in \
             `certificate.json` is the joint certificate's floor at this K)"
                .to_string()
        };
        format!(
            "\n\nThe K_c-iteration MPC is exported too: {}, K_c = {}, shift-and-repeat warm \
             start; the loop (K, K_c) is {status}.",
            m.method, m.k_c
        )
    });
    let loop_section = if art.mpc.is_some() {
        "\n\n## Loop format\n\nThe loop program (`loop`: estimator + MPC) prints x̂_{0|0} and \
         u_0 = π(x̂_{0|0}) on one line; then, for each input line t = 0, 1, … holding y_t (the \
         `y*` columns of `trace.csv` row t), it pushes (u_t, y_t), estimates x̂_{t+1|t+1}, computes \
         u_{t+1} and prints them, comma-separated with 17 significant digits: output line t is row \
         t of `trace.csv`'s `xhat*` and `u*` columns for a run of this loop.\n"
    } else {
        ""
    };
    let build = match lang {
        Lang::C => "```sh\nmake                      # host: ./replay\nmake replay-m4.elf        # Cortex-M4F (arm-none-eabi-gcc)\nmake replay-m7.elf        # Cortex-M7\nmake loop                 # with the MPC: ./loop (also loop-m4.elf, loop-m7.elf)\nqemu-system-arm -M mps2-an386 -nographic -monitor none -serial none \\\n  -semihosting-config enable=on,target=native -icount shift=0 -kernel replay-m4.elf < inputs.csv\n```\n\nFiles: `mhe.h`/`mhe.c` (the estimator: `mhe_reset`, `mhe_estimate`, `mhe_push`; no allocation), `mpc.h`/`mpc.c` (the MPC: `mpc_reset`, `mpc_control`; with `MHE_HAS_MPC`), `mhe_data.h`/`mhe_data.c` (the problem data, generated), `replay.c`, `loop.c`, `count.h` (instruction counting on Cortex-M), `Makefile` (`-ffp-contract=off`, no fast-math: needed for bit identity), `cortex-m/` (start-up code and linker script for QEMU's mps2 boards; adapt the memory map for a real board).".to_string(),
        Lang::Rust => "```sh\ncargo build --release\ncargo run --release --bin replay < inputs.csv\ncargo run --release --bin loop < y.csv   # with the MPC\n```\n\nFiles: `src/data.rs` (the problem data as `static` arrays, generated), `src/lib.rs` (`#![no_std]`: `estimator()`, the `Estimator` type, `controller()`, the `Controller` type), `mhe-embedded/` (the crate, vendored: no dependencies, no allocation), `src/bin/replay.rs`, `src/bin/loop.rs`, `capi/` (the C ABI: a `no_std` static library and its cbindgen header).".to_string(),
    };
    format!(
        "# Exported estimator: `{scenario}`, {method}, K = {k}\n\n\
         Generated by `cargo xtask export` (docs/embedded.md of suboptimal-mhe). Scenario SHA-256 \
         `{sha}`, scalar {scalar}.\n\n{status}{mpc_note}{f32_note}\n\n## Build and run\n\n{build}\n\n\
         ## Replay format\n\nThe replay program prints x̂_{{0|0}} first; then, for each input line \
         t = 0, 1, … holding u_t and then y_t (comma-separated, the `u*` and `y*` columns of \
         `trace.csv` row t of `cargo xtask reproduce`), it pushes the pair and prints \
         x̂_{{t+1|t+1}}, comma-separated with 17 significant digits, so output line t is row t of \
         `trace.csv`'s `xhat*` columns (bit for bit for an f64 build when `reproduce` ran with \
         `QP_ITER_KERNEL=portable`).\n{loop_section}",
        scenario = art.scenario,
        method = art.method,
        k = art.k,
        sha = art.sha256,
        scalar = scalar_name(art.scalar),
    )
}
