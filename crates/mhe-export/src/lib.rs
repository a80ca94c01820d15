//! The certified estimator (and, on request, the certified loop with its K_c-iteration MPC)
//! as a self-contained artefact for a microcontroller: C99 sources or a `no_std` Rust
//! package, the problem data, a replay program, `certificate.json` and a README
//! (docs/embedded.md). `cargo xtask export` is argument parsing around this crate.
//!
//! 1. [`export`] checks every option ([`ExportOptions::validate`]) before any work, computes
//!    the closed-loop certificate with the options every command uses
//!    (`iss_certificate::coverage::verdict_options`: the user's γ₁,₃ and the sample that can
//!    refute it) and decides K: [`Iterations::Certified`] (the default) is the smallest K
//!    the one verdict certifies (Theorem 1's K_min, Theorem L3's K_glob or the iteration
//!    chain's K, in the exported scalar). The verdict on (method, K, the MPC's K_c, scalar, the scenario's warm start)
//!    is `iss_certificate::coverage::verdict`'s — the one `reproduce` and the sweep print; a
//!    configuration it does not certify is refused ([`ExportError::NotCertified`]) unless
//!    `allow_uncertified`, which the artefact then says in its README, its headers and
//!    `certificate.json`.
//! 2. Builds the std `MheEstimator` with that method and K on the portable kernel and copies
//!    its numbers out.
//! 3. [`Artefact::write_to`] writes the artefact into a temporary sibling of the directory
//!    and replaces the directory with it as a whole (no file of an earlier export survives
//!    beside the new certificate): the data (a Rust module or `.c`/`.h`), the estimator
//!    source (vendored `mhe-embedded`, or `mhe.c`/`mhe.h`), the build files, the replay
//!    program, `certificate.json` and a README.
//!
//! ```no_run
//! use closed_loop::scenario::Scenario;
//! use mhe_export::{ExportOptions, Lang, Source, export};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let path = "scenarios/case-study-certified.toml";
//! let resolved = Scenario::from_file(path)?.resolve()?;
//! let mut options = ExportOptions::default(); // K = the certified floor, f64, C
//! options.lang = Lang::C;
//! options.source = Source::from_bytes(path, &std::fs::read(path)?);
//! let artefact = export(&resolved, &options)?; // refused unless certified
//! assert!(artefact.loop_certified());
//! artefact.write_to(std::path::Path::new("target/mhe-c"))?;
//! # Ok(())
//! # }
//! ```

mod api;
pub mod budget;
mod c_gen;
mod error;
pub(crate) mod extract;
mod out;
mod rust_gen;
mod sha256;
pub mod survey;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_api;
#[cfg(test)]
mod tests_capi;
#[cfg(test)]
mod tests_firmware;
#[cfg(test)]
mod tests_global;
#[cfg(test)]
mod tests_mpc;
#[cfg(test)]
mod tests_structured;
#[cfg(test)]
mod tests_survey;

pub use api::{
    Artefact, ExportOptions, Iterations, Lang, ScalarKind, Source, Stage, export,
    export_with_progress,
};
pub use error::ExportError;
pub use out::{EXPORT_FORMAT, check_output_dir};
pub use sha256::sha256_hex;
pub use survey::{MethodSurvey, ScalarSurvey, survey};

use std::path::Path;

use anyhow::{Context, Result, bail};
use closed_loop::scenario::{ControllerChoice, ResolvedScenario};
use iss_certificate::certificate::{ClosedLoopCertificate, SolverCertificate, certify_closed_loop};
/// What an f32 artefact's certificate covers when its verdict is certified.
pub(crate) const F32_COVERED: &str = "covered: Theorem 1 with the f32 rounding of the \
    portable kernel folded in (docs/theory.md, \"Certified f32\") certifies this K";
/// What an f64 artefact says about f32.
const F32_DECIDED_BY: &str = "an f32 export is certified where Theorem 1 with the f32 \
    rounding folded in, or the global loop certificate in f32 (Theorem L3u), certifies its K \
    (iss_certificate::coverage::verdict)";
/// What an f32 artefact's certificate covers when the global loop certificate covers it.
const F32_GLOBAL: &str = "covered: the global loop certificate in f32 (Theorem L3u, \
    docs/theory.md \"The global loop certificate in a given precision\") certifies this K, for \
    the loop with the exact MPC: ISS with the rounding's offset (`covered_by.offset`) as an \
    input beside w";
use iss_certificate::coverage::{
    CertificateKind, Configuration, PairVerdict, Scalar, verdict_options,
};
use iss_certificate::joint::{JointCertificate, JointOptions, certify_joint};
use iss_certificate::outcome::VoidReason;
use qp_iter::Method;
use serde_json::json;

mod cover;
pub(crate) use cover::GlobalCover;
use extract::{OwnedMpc, OwnedProblem};
use out::replace_artefact;

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
pub(crate) struct Header {
    pub scenario: String,
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
    /// The global loop certificate, when it (not Theorem 1) certifies K.
    pub global: Option<GlobalCover>,
    /// f32 only: the K the iteration chain certifies in f64 (it does not cover f32: no
    /// rounding input), said beside the f32 verdict.
    pub chain_f64_only: Option<usize>,
}

impl Header {
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
            (true, _) if self.global.is_some() => {
                if let Some(g) = &self.global {
                    lines.push(format!(
                        "Certified: {} (certificate.json `covered_by`), in {}.",
                        g.sentence(self.k),
                        scalar_name(self.scalar)
                    ));
                }
            }
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
            let cover = if self.global.is_some() {
                F32_GLOBAL
            } else {
                F32_COVERED
            };
            lines.push(format!("f32: {cover}."));
        }
        if let Some(kc) = self.chain_f64_only {
            lines.push(format!("f32: {}.", chain_f64_only(kc)));
        }
        lines
            .iter()
            .map(|l| format!("{prefix}{l}"))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// What the artefacts say where the iteration chain certifies a K in f64 and the export is
/// f32.
fn chain_f64_only(k_chain: usize) -> String {
    format!(
        "the iteration chain (Theorem L3b) certifies K = {k_chain} in f64 only (it has no \
         rounding input); in f32 the floor is the global certificate's K_glob(u) (Theorem L3u) \
         or Theorem 1's"
    )
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

fn coverage_scalar(s: ScalarKind) -> Scalar {
    match s {
        ScalarKind::F64 => Scalar::F64,
        ScalarKind::F32 => Scalar::F32,
    }
}

/// Why a verdict is not "certified" (None when it is), in the artefact's words.
fn uncertified_reason(v: &PairVerdict, what: &str) -> Option<String> {
    // Decided by the library's methods: any other verdict (void, not computed, or one this
    // crate does not know) is refused with its reason.
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
/// [`iss_certificate::coverage::verdict`]: K and the verdict. `--k certified` is the smallest
/// K the verdict certifies — or `joint_floor` when given (an exported K_c-iteration MPC: the
/// joint certificate's smallest K for its K_c); a configuration the verdict does not certify
/// is refused unless `allow_uncertified`.
pub(crate) fn decide_k(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    method: Method,
    (k_arg, joint_floor): (Iterations, Option<usize>),
    scalar: ScalarKind,
    allow_uncertified: bool,
) -> Result<(usize, PairVerdict)> {
    let sc = solver_entry(cert, method)?;
    let name = method.name();
    let config = |k_e| Configuration {
        method,
        k_e,
        controller: ControllerChoice::ExactMpc,
        scalar: coverage_scalar(scalar),
    };
    // `--k certified`: the smallest K the one verdict certifies in this scalar (Theorem 1's
    // K_min, the global K_glob or the chain's K, whichever is smallest).
    let k = match (k_arg, joint_floor) {
        (Iterations::Given(k), _) => k,
        (Iterations::Certified, Some(k)) => k,
        (Iterations::Certified, None) => {
            let probe = iss_certificate::coverage::verdict(resolved, cert, &config(1));
            match (probe.certified.is_certified(), probe.k_min) {
                (true, _) => 1,
                (false, Some(k)) => k,
                (false, None) if sc.k_min.is_none() => {
                    // The verdict's reason names Theorem 1's void reasons where it has them:
                    // say them once.
                    let why = probe.reason_text();
                    let theorem1 = VoidReason::join(&sc.void_reasons);
                    let why = if why.contains(&theorem1) {
                        why
                    } else {
                        format!("Theorem 1: {theorem1}; {why}")
                    };
                    bail!(
                        "--k certified: no certificate certifies a K for {name} in {} ({why}); \
                         give --k K with --allow-uncertified to export anyway",
                        scalar_name(scalar),
                    )
                }
                (false, None) => bail!(
                    "--k certified: no K is certified for {name} in {} ({}); give --k K with \
                     --allow-uncertified to export anyway",
                    scalar_name(scalar),
                    probe.reason_text()
                ),
            }
        }
    };
    let v = iss_certificate::coverage::verdict(resolved, cert, &config(k));
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
                "{flag}: below the certified K_min = {k_min} of {} for {name} in {}; use \
                 --k certified (or K ≥ {k_min}), or --allow-uncertified to export an uncertified \
                 estimator",
                v.certificate
                    .map_or("the certificate", CertificateKind::title),
                scalar_name(scalar)
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
        // A larger --k helps only where the certificate is not void (its floor is above K).
        (Iterations::Certified, None) => bail!(
            "--kc certified: {}; {}--kc K with --allow-uncertified to export anyway",
            none_reason(),
            if region.void_reasons.is_empty() {
                "give a larger --k, or "
            } else {
                "no K helps; "
            }
        ),
    };
    let config = Configuration {
        method: joint.mhe_method,
        k_e,
        controller: ControllerChoice::suboptimal(k_c, joint.mpc_method)
            .map_err(|e| anyhow::anyhow!("--kc {k_c}: {e}"))?,
        scalar: coverage_scalar(scalar),
    };
    let v = iss_certificate::coverage::verdict(resolved, cert, &config);
    if v.certified.is_certified() || allow_uncertified {
        return Ok((k_c, v));
    }
    if v.certified.is_below_floor() {
        match floor {
            Some(f) => bail!(
                "--kc {k_c}: below the joint certificate's floor K_c = {f} at K = {k_e} (MHE {}, \
                 MPC {}); use --kc certified (or K_c ≥ {f}), or --allow-uncertified to export an \
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

/// Writes every file of the artefact into `out` (`mpc`: the MPC's data and its joint
/// certificate, when exported; `provenance`: the caller's record in `certificate.json`).
pub(crate) fn write_artefact(
    out: &Path,
    lang: Lang,
    problem: &OwnedProblem,
    mpc: Option<(&OwnedMpc, &JointCertificate)>,
    art: &Header,
    cert: &SolverCertificate,
    scenario_path: &Path,
    provenance: &serde_json::Value,
) -> Result<()> {
    write_code(out, lang, problem, mpc.map(|m| m.0), art)?;
    let json = certificate_json(art, cert, mpc.map(|m| m.1), scenario_path, provenance);
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
    art: &Header,
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
    art: &Header,
    cert: &SolverCertificate,
    joint: Option<&JointCertificate>,
    scenario_path: &Path,
    provenance: &serde_json::Value,
) -> serde_json::Value {
    let mpc = match (&art.mpc, joint) {
        (Some(m), Some(j)) => json!({
            "method": m.method,
            "iterations": m.k_c,
            "warm_start": j.warm_start,
            "k_c_min": m.k_c_min,
            "certified": m.certified,
            "uncertified_reason": m.reason,
            "covers": match art.scalar {
                ScalarKind::F64 => "the exported f64 MPC performs the certified K_c iterations \
                    bit for bit as the std SuboptimalMpc on the portable kernel; the joint \
                    certificate holds at (K, K_c) iff `certified`",
                ScalarKind::F32 => "the exported f32 MPC and estimator are covered by the joint \
                    certificate with both maps' f32 rounding folded in (docs/theory.md, \"The \
                    joint certificate in f32\"): it holds at (K, K_c) iff `certified`",
            },
            // The library outcomes in the certificate schema (`certificate_json::v1`).
            "at_pair": certificate_json::v1::JointGains::from(&j.analysis.at(art.k, m.k_c)),
            "joint": certificate_json::v1::JointCertificate::from(j),
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
        // `certified` is the verdict in the exported scalar (f32 has its own rounding models),
        // so the artefact is covered exactly when the loop is: one truth with the header's
        // MHE_CERTIFIED / MPC_CERTIFIED.
        "artefact_covered": art.loop_certified(),
        "mpc": mpc,
        "f32_chain": art.chain_f64_only.map(chain_f64_only),
        "covered_by": match (&art.global, art.certified) {
            (Some(g), true) => g.json(),
            (None, true) => json!({"certificate": "theorem1", "k_min": art.k_min}),
            (_, false) => serde_json::Value::Null,
        },
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
                (ScalarKind::F32, true) if art.global.is_some() => F32_GLOBAL,
                (ScalarKind::F32, true) => F32_COVERED,
                (ScalarKind::F32, false) => "not covered: this configuration is not certified in f32 (`uncertified_reason`)",
                (ScalarKind::F64, _) => F32_DECIDED_BY,
            },
        },
        "theorem1": certificate_json::v1::SolverCertificate::from(cert),
        "provenance": provenance,
    })
}

fn readme(art: &Header, lang: Lang) -> String {
    let status = if let (Some(g), true) = (&art.global, art.certified) {
        let offset = g.offset().map_or_else(String::new, |o| {
            format!(
                " The f32 rounding enters as an input beside w: the lim-sup bounds hold with \
                 √(w̄² + o²), ISS offset o = {o:.3e}."
            )
        });
        format!(
            "**Certified**: {} for {} in {} (`covered_by` in `certificate.json`). Theorem 1 \
             does not cover this K; this certificate covers the loop with the exact MPC and the \
             paper's warm start.{offset}",
            g.sentence(art.k),
            art.method,
            scalar_name(art.scalar),
        )
    } else if art.certified {
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
            "\n\nThis is an **f32** build; the certificate's cover of f32: {}.{}\n",
            if art.certified && art.global.is_some() {
                F32_GLOBAL
            } else if art.certified {
                F32_COVERED
            } else {
                "not covered (see `uncertified_reason`)"
            },
            art.chain_f64_only
                .map_or_else(String::new, |k| format!(" Note: {}.", chain_f64_only(k)))
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
