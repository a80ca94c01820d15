//! The export from Rust values: [`ExportOptions`] in, an [`Artefact`] out, written by
//! [`Artefact::write_to`]. `cargo xtask export` maps its flags onto these fields one to one
//! (`--kc` is `k_c`) and prints what [`export_with_progress`] reports.

use std::fmt;
use std::path::{Path, PathBuf};

use closed_loop::scenario::{ResolvedScenario, Scenario};
use iss_certificate::certificate::SolverCertificate;
use iss_certificate::joint::JointCertificate;
use qp_iter::Method;
use serde_json::json;

use crate::extract::{OwnedMpc, OwnedProblem, portable_estimator, portable_mpc};
use crate::{
    ExportError, Header, MpcArtefact, c_gen, closed_loop_certificate, coverage_scalar, decide_k,
    decide_kc, joint_certificate, replace_artefact, solver_entry, uncertified_reason,
    write_artefact,
};

/// The scalar of the exported code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScalarKind {
    /// Double precision: bit for bit the std build on the portable kernel.
    #[default]
    F64,
    /// Single precision (data rounded to f32 once; certified where Theorem 1 with the f32
    /// rounding folded in certifies K).
    F32,
}

/// The language of the artefact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Lang {
    /// A Cargo package (no_std library + std replay binary + a C ABI).
    Rust,
    /// C99 sources, a Makefile and Cortex-M start-up files.
    #[default]
    C,
}

/// An iteration count: the certified floor or a given count ≥ 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Iterations {
    /// The certified floor (the smallest K the one verdict certifies: Theorem 1's K_min,
    /// Theorem L3's K_glob or the iteration chain's K; or the joint certificate's K_c at the
    /// exported K).
    #[default]
    Certified,
    /// A given count (≥ 1; 0 is refused by [`ExportOptions::validate`]).
    Given(usize),
}

impl Iterations {
    /// Parses a command-line value of `flag` (`--k`, `--kc`): `certified` or an integer ≥ 1.
    ///
    /// # Errors
    /// [`ExportError::InvalidOption`] naming `flag`.
    pub fn parse(flag: &str, arg: &str) -> Result<Self, ExportError> {
        if arg == "certified" {
            return Ok(Self::Certified);
        }
        // Above the one iteration limit every command refuses (found by the survey: `--kc 10⁸`
        // was exported, `--k 10⁸` refused only after the certificate).
        arg.parse()
            .ok()
            .filter(|k| (1..=qp_iter::MAX_ITERATIONS).contains(k))
            .map(Self::Given)
            .ok_or_else(|| ExportError::InvalidOption {
                option: field_of(flag),
                message: format!(
                    "{flag} {arg}: expected an integer from 1 to {} or `certified`",
                    qp_iter::MAX_ITERATIONS
                ),
            })
    }
}

/// The [`ExportOptions`] field of a CLI flag.
fn field_of(flag: &str) -> &'static str {
    match flag {
        "--kc" => "k_c",
        _ => "k",
    }
}

/// Where the scenario came from, recorded in the artefact (banner, README,
/// `certificate.json`'s `scenario.path` and `scenario.sha256`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Source {
    /// The scenario file's path as the user gave it.
    pub path: String,
    /// The SHA-256 of the file's bytes (lower-case hex).
    pub sha256: String,
}

impl Source {
    /// The source of a scenario file read as `bytes` from `path`.
    pub fn from_bytes(path: impl Into<String>, bytes: &[u8]) -> Self {
        Self {
            path: path.into(),
            sha256: crate::sha256_hex(bytes),
        }
    }
}

impl Default for Source {
    /// A scenario built from values: no file, no hash (the artefact says so).
    fn default() -> Self {
        Self {
            path: "(built from values)".into(),
            sha256: "none (no scenario file)".into(),
        }
    }
}

/// What to export; every field is checked by [`ExportOptions::validate`] before any work.
/// The CLI flag of each field is `--` + its name with `-` (`k_c` is `--kc`).
#[derive(Debug, Clone, Default)]
#[non_exhaustive]
pub struct ExportOptions {
    /// The MHE method [None: the scenario's `mhe.method`].
    pub method: Option<Method>,
    /// Iterations K per step [`Iterations::Certified`: the smallest K the one verdict
    /// certifies (Theorem 1, Theorem L3 or the iteration chain); with `kc`, the joint
    /// certificate's smallest K for that K_c].
    pub k: Iterations,
    /// Also export the K_c-iteration MPC (the whole certified loop) [None: the scenario's
    /// `mpc.iterations` when set, else no MPC].
    pub k_c: Option<Iterations>,
    /// The MPC's method [None: the scenario's `mpc.method`]; only with an exported MPC.
    pub mpc_method: Option<Method>,
    /// The scalar of the exported code.
    pub scalar: ScalarKind,
    /// The language of the artefact.
    pub lang: Lang,
    /// C only: the prefix of every generated name (`{prefix}_reset`, `{PREFIX}_NX`, files
    /// `{prefix}.h`, …) so several estimators link into one firmware ["" or `mhe`: none].
    pub prefix: String,
    /// Export even when K (or K_c) is below its certified floor or the certificate is void
    /// (the artefact says so).
    pub allow_uncertified: bool,
    /// The scenario file (recorded in the artefact).
    pub source: Source,
    /// The caller's provenance record (`certificate.json`'s `provenance`) [None: this
    /// crate's name and version].
    pub provenance: Option<serde_json::Value>,
    /// The targets and clocks (MHz) of the sample-period budget (`--target`,
    /// `--clock-mhz`) [None: [`crate::budget::default_targets`], both at their default
    /// clocks].
    pub budget_targets: Option<Vec<(mhe_budget::Target, f64)>>,
}

impl ExportOptions {
    /// The options' own checks (no scenario needed): K and K_c ≥ 1, the prefix a C
    /// identifier.
    ///
    /// # Errors
    /// [`ExportError::InvalidOption`] naming the field and its CLI flag.
    pub fn validate(&self) -> Result<(), ExportError> {
        for (flag, k) in [("--k", Some(self.k)), ("--kc", self.k_c)] {
            if k == Some(Iterations::Given(0)) {
                Iterations::parse(flag, "0")?;
            }
        }
        c_gen::check_prefix(self.prefix()).map_err(|e| ExportError::option("prefix", &e))?;
        crate::budget::check_targets(&self.targets())
    }

    /// The budget's targets ([`ExportOptions::budget_targets`] or both at their defaults).
    pub(crate) fn targets(&self) -> Vec<(mhe_budget::Target, f64)> {
        self.budget_targets
            .clone()
            .unwrap_or_else(crate::budget::default_targets)
    }

    /// The options against the scenario, before anything is computed: an `[mhe]` section,
    /// an `[mpc]` section for `k_c`, `mpc_method` only with an exported MPC.
    ///
    /// # Errors
    /// [`ExportError::Scenario`] or [`ExportError::InvalidOption`].
    pub fn check_scenario(&self, scenario: &Scenario) -> Result<(), ExportError> {
        Plan::new(scenario, self).map(drop)
    }

    fn prefix(&self) -> &str {
        if self.prefix.is_empty() {
            "mhe"
        } else {
            &self.prefix
        }
    }
}

/// A long step of [`export_with_progress`], reported before it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Stage {
    /// The closed-loop certificates of the MHE method (Theorem 1, Theorem L3, the chain).
    Theorem1 {
        /// The MHE method.
        method: Method,
    },
    /// The joint MPC + MHE certificate.
    Joint {
        /// The MHE method.
        mhe: Method,
        /// The MPC method.
        mpc: Method,
    },
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Theorem1 { method } => write!(
                f,
                "computing the certificates (Theorem 1, the global loop certificate, the iteration chain) for {} …",
                method.name()
            ),
            Self::Joint { mhe, mpc } => write!(
                f,
                "computing the joint certificate for MHE {} + MPC {} …",
                mhe.name(),
                mpc.name()
            ),
        }
    }
}

/// The method and the MPC to export, decided from the options and the scenario.
struct Plan {
    method: Method,
    /// K_c and the MPC's method, when the MPC is exported.
    mpc: Option<(Iterations, Method)>,
}

impl Plan {
    fn new(scenario: &Scenario, o: &ExportOptions) -> Result<Self, ExportError> {
        let mhe = scenario.mhe.as_ref().ok_or_else(|| ExportError::Scenario {
            message: "the scenario has no [mhe] section: nothing to export".into(),
        })?;
        let method = o.method.unwrap_or(mhe.method());
        let no_mpc = || ExportError::Scenario {
            message: "--kc: the scenario has no [mpc] section: no MPC to export".into(),
        };
        // The MPC: asked for with k_c, or the scenario's controller (mpc.iterations).
        let mpc_spec = scenario.mpc.as_ref();
        let kc_arg = match o.k_c {
            Some(k) => {
                mpc_spec.ok_or_else(no_mpc)?;
                Some(k)
            }
            None => mpc_spec
                .and_then(|m| m.iterations())
                .map(|k| Iterations::Given(k.get())),
        };
        let mpc_method = match (kc_arg, o.mpc_method, mpc_spec) {
            (None, Some(m), _) => {
                return Err(ExportError::InvalidOption {
                    option: "mpc_method",
                    message: format!(
                        "--mpc-method {}: no MPC is exported (give --kc K_C or --kc certified, \
                         or set mpc.iterations in the scenario), so the flag would be ignored",
                        m.name()
                    ),
                });
            }
            (None, None, _) => None,
            (Some(_), Some(m), _) => Some(m),
            (Some(_), None, Some(spec)) => Some(spec.method()),
            (Some(_), None, None) => return Err(no_mpc()),
        };
        // Before the certificate: a window of thousands of unknowns would take minutes to
        // certify and hundreds of MB to write.
        crate::survey::check_size(scenario, method, o.scalar)?;
        Ok(Self {
            method,
            mpc: kc_arg.zip(mpc_method),
        })
    }
}

/// A computed artefact: the exported numbers, the verdicts and what the files say; written
/// by [`Artefact::write_to`].
#[derive(Debug, Clone)]
pub struct Artefact {
    header: Header,
    lang: Lang,
    prefix: String,
    problem: OwnedProblem,
    mpc: Option<(OwnedMpc, JointCertificate)>,
    theorem1: SolverCertificate,
    source_path: PathBuf,
    provenance: serde_json::Value,
    budgets: Vec<mhe_budget::Budget>,
    budget_note: Option<&'static str>,
}

impl Artefact {
    /// Writes the artefact into `dir`, replacing an earlier export there as a whole (through
    /// a temporary sibling directory and a rename: a failed write leaves `dir` as it was).
    ///
    /// # Errors
    /// [`ExportError::Output`] when `dir` is refused ([`crate::check_output_dir`]) or cannot
    /// be written.
    pub fn write_to(&self, dir: &Path) -> Result<(), ExportError> {
        self.write_to_then(dir, |_| Ok(()))
    }

    /// [`Artefact::write_to`], with `then(stage)` run on the staged directory before it
    /// replaces `dir`: a caller's additions (the CLI's sample-period budget) are part of the
    /// set, replaced with it or not at all.
    ///
    /// # Errors
    /// As [`Artefact::write_to`]; an error of `then` leaves `dir` as it was.
    pub fn write_to_then(
        &self,
        dir: &Path,
        then: impl FnOnce(&Path) -> std::io::Result<()>,
    ) -> Result<(), ExportError> {
        let mpc = self.mpc.as_ref().map(|(d, j)| (d, j));
        replace_artefact(dir, |stage| {
            write_artefact(
                stage,
                self.lang,
                &self.problem,
                mpc,
                &self.header,
                &self.theorem1,
                &self.source_path,
                &self.provenance,
            )?;
            if self.lang == Lang::C && self.prefix != "mhe" {
                c_gen::apply_prefix(stage, &self.prefix)?;
            }
            crate::budget::annotate(stage, &self.budgets, self.budget_note)?;
            then(stage)?;
            Ok(())
        })
        .map_err(|e| ExportError::output(dir, &e))
    }

    /// The scenario's name.
    pub fn scenario(&self) -> &str {
        &self.header.scenario
    }

    /// The MHE method's name.
    pub fn method(&self) -> &str {
        &self.header.method
    }

    /// Iterations K per step.
    pub fn k(&self) -> usize {
        self.header.k
    }

    /// The smallest K the one verdict certifies in the exported scalar (Theorem 1's K_min,
    /// Theorem L3's K_glob or the iteration chain's K; None: void or not computed).
    pub fn k_min(&self) -> Option<usize> {
        self.header.k_min
    }

    /// The language.
    pub fn lang(&self) -> Lang {
        self.lang
    }

    /// The scalar.
    pub fn scalar(&self) -> ScalarKind {
        self.header.scalar
    }

    /// The estimator's verdict (method, K, scalar) is "certified".
    pub fn certified(&self) -> bool {
        self.header.certified
    }

    /// The certificate covering the exported loop holds: Theorem 1 for K, and the joint
    /// certificate at (K, K_c) when the MPC is exported.
    pub fn loop_certified(&self) -> bool {
        self.header.loop_certified()
    }

    /// Why the loop is not certified (the estimator's reason first), None when it is.
    pub fn uncertified_reason(&self) -> Option<&str> {
        self.header
            .reason
            .as_deref()
            .or(self.header.mpc.as_ref().and_then(|m| m.reason.as_deref()))
    }

    /// The sample-period budget per target of the exported loop step (the MHE at K and,
    /// with the MPC, its K_c iterations): README's section and certificate.json's `budget`.
    pub fn budgets(&self) -> &[mhe_budget::Budget] {
        &self.budgets
    }

    /// An f32 export's line on what the certificate covers of its budget
    /// ([`crate::budget::f32_note`]; None for f64).
    pub fn budget_note(&self) -> Option<&'static str> {
        self.budget_note
    }

    /// The exported MPC's method name and K_c (None: no MPC exported).
    pub fn mpc(&self) -> Option<(&str, usize)> {
        self.header.mpc.as_ref().map(|m| (m.method.as_str(), m.k_c))
    }
}

/// [`export_with_progress`] without progress reports.
///
/// # Errors
/// See [`export_with_progress`].
pub fn export(
    resolved: &ResolvedScenario,
    options: &ExportOptions,
) -> Result<Artefact, ExportError> {
    export_with_progress(resolved, options, &mut |_| {})
}

/// Computes the artefact of `resolved` under `options`: checks the options, computes the
/// certificate (reporting each long [`Stage`] to `progress` first), decides K (and K_c),
/// refuses an uncertified configuration unless `allow_uncertified`, and copies the std
/// estimator's (and MPC's) numbers out on the portable kernel.
///
/// # Errors
/// [`ExportError::InvalidOption`] / [`ExportError::Scenario`] before any work,
/// [`ExportError::Certificate`], [`ExportError::NotCertified`], [`ExportError::Unsupported`].
pub fn export_with_progress(
    resolved: &ResolvedScenario,
    options: &ExportOptions,
    progress: &mut dyn FnMut(&Stage),
) -> Result<Artefact, ExportError> {
    options.validate()?;
    let scenario = resolved.scenario();
    let plan = Plan::new(scenario, options)?;
    let method = plan.method;
    progress(&Stage::Theorem1 { method });
    let loop_cert =
        closed_loop_certificate(resolved, method).map_err(|e| ExportError::certificate(&e))?;
    // With an MPC the artefact runs the K_c-iteration MPC, which only the joint certificate
    // covers: `--k certified` is then its smallest K for that K_c, not the exact MPC's floor.
    let joint = match plan.mpc {
        Some((kc_arg, mpc_method)) => {
            progress(&Stage::Joint {
                mhe: method,
                mpc: mpc_method,
            });
            let joint = joint_certificate(resolved, &loop_cert, method, mpc_method)
                .map_err(|e| ExportError::certificate(&e))?;
            // In f32 the floors are the joint certificate's with both maps' rounding folded
            // in; without a model they stay f64's and the f32 verdict refuses with its reason.
            let joint = match options.scalar {
                ScalarKind::F64 => joint,
                ScalarKind::F32 => match iss_certificate::joint::joint_rounding(
                    resolved,
                    &loop_cert,
                    method,
                    mpc_method,
                    coverage_scalar(options.scalar).unit_roundoff(),
                )
                .map_err(|e| ExportError::certificate(&anyhow::Error::from(e)))?
                {
                    Ok(r) => joint.with_rounding(r),
                    Err(_) => joint,
                },
            };
            Some((joint, kc_arg))
        }
        None => None,
    };
    let joint_floor = joint.as_ref().and_then(|(j, kc_arg)| match kc_arg {
        Iterations::Given(k_c) => j
            .analysis
            .k_e_min(*k_c, j.region.k_max)
            .or(j.region.k_e_floor),
        Iterations::Certified => j.region.k_e_floor,
    });
    let est = export_estimator(resolved, options, method, loop_cert, joint_floor)?;
    let mpc = match joint {
        Some((joint, kc_arg)) => Some(export_mpc(resolved, options, &est, kc_arg, joint)?),
        None => None,
    };
    let header = Header {
        scenario: scenario.name.clone(),
        method: method.name().into_owned(),
        k: est.k,
        k_min: est.k_min,
        scalar: options.scalar,
        certified: est.certified,
        reason: est.reason,
        prior: scenario.simulation.prior.clone(),
        sha256: options.source.sha256.clone(),
        mpc: mpc.as_ref().map(|m| m.artefact.clone()),
        global: est.global,
        chain_f64_only: est.chain_f64_only,
    };
    let mpc_data = mpc.as_ref().map(|m| &m.data);
    let (budgets, budget_note) =
        artefact_budgets(scenario, options, &header, &est.problem, mpc_data)?;
    Ok(Artefact {
        budgets,
        budget_note,
        header,
        lang: options.lang,
        prefix: options.prefix().to_string(),
        problem: est.problem,
        mpc: mpc.map(|m| (m.data, m.joint)),
        theorem1: est.theorem1,
        source_path: PathBuf::from(&options.source.path),
        provenance: options.provenance.clone().unwrap_or_else(
            || json!({"tool": env!("CARGO_PKG_NAME"), "tool_version": env!("CARGO_PKG_VERSION")}),
        ),
    })
}

/// The sample-period budget of the exported loop step on every target of the options, and
/// an f32 export's note on what the certificate covers.
fn artefact_budgets(
    scenario: &Scenario,
    options: &ExportOptions,
    header: &Header,
    problem: &OwnedProblem,
    mpc: Option<&OwnedMpc>,
) -> Result<(Vec<mhe_budget::Budget>, Option<&'static str>), ExportError> {
    let scalar = match options.scalar {
        ScalarKind::F64 => mhe_budget::Scalar::F64,
        ScalarKind::F32 => mhe_budget::Scalar::F32,
    };
    let mhe = mhe_budget::Step {
        method: &header.method,
        dims: crate::budget::dims(scenario, problem.horizon),
        k: header.k,
    };
    let mpc_method = header.mpc.as_ref().map(|m| m.method.as_str());
    let mpc = mpc.zip(mpc_method).map(|(m, method)| mhe_budget::Step {
        method,
        dims: mhe_budget::StepDims::mpc(m.nx, m.nu, m.horizon),
        k: m.iterations,
    });
    let budgets =
        crate::budget::budgets(&options.targets(), scalar, mhe, mpc, scenario.sample_time)?;
    let note =
        (options.scalar == ScalarKind::F32).then(|| crate::budget::f32_note(header.certified));
    Ok((budgets, note))
}

/// The exported estimator: K, its verdict and its numbers.
struct EstimatorExport {
    loop_cert: iss_certificate::certificate::ClosedLoopCertificate,
    theorem1: SolverCertificate,
    k: usize,
    k_min: Option<usize>,
    certified: bool,
    reason: Option<String>,
    /// The global loop certificate, when it (not Theorem 1) certifies K.
    global: Option<crate::GlobalCover>,
    /// f32: the K the iteration chain certifies in f64 only.
    chain_f64_only: Option<usize>,
    problem: OwnedProblem,
}

/// Certificate, K and verdict ([`decide_k`]), then the std estimator's numbers with the
/// C self-test's stored steps (f64: the std estimator's bits; M + 2 steps).
/// `joint_floor`: with an MPC, the joint certificate's smallest K for the exported K_c (what
/// `--k certified` means then).
fn export_estimator(
    resolved: &ResolvedScenario,
    o: &ExportOptions,
    method: Method,
    loop_cert: iss_certificate::certificate::ClosedLoopCertificate,
    joint_floor: Option<usize>,
) -> Result<EstimatorExport, ExportError> {
    let scenario = resolved.scenario();
    let theorem1 = solver_entry(&loop_cert, method).map_err(|e| ExportError::certificate(&e))?;
    let (k, v) = decide_k(
        resolved,
        &loop_cert,
        method,
        (o.k, joint_floor),
        o.scalar,
        o.allow_uncertified,
    )
    .map_err(|e| ExportError::not_certified("k", &e))?;
    let problem = (|| {
        let mut est = portable_estimator(resolved, method, k)?;
        let mut problem = OwnedProblem::from_estimator(&est, &scenario.plant)?;
        if o.scalar == ScalarKind::F64 {
            let steps = problem.horizon + 2;
            let prior = &scenario.simulation.prior;
            problem.record_self_test(&mut est, &scenario.plant, prior, steps)?;
        }
        anyhow::Ok(problem)
    })()
    .map_err(|e| ExportError::unsupported(&e))?;
    Ok(EstimatorExport {
        k,
        k_min: v.k_min.or(theorem1.k_min),
        certified: v.certified.is_certified(),
        reason: uncertified_reason(&v, &format!("K = {k}")),
        global: crate::GlobalCover::of(&loop_cert, method, o.scalar, &v, k),
        chain_f64_only: if o.scalar == ScalarKind::F32 {
            iss_certificate::coverage::global_of(
                &loop_cert,
                method,
                closed_loop::scenario::ControllerChoice::ExactMpc,
            )
            .and_then(|g| g.chain.as_ref())
            .and_then(|c| c.k_chain())
        } else {
            None
        },
        loop_cert,
        theorem1,
        problem,
    })
}

/// The exported MPC: its numbers, what the files say about it, its joint certificate.
struct MpcExport {
    data: OwnedMpc,
    artefact: MpcArtefact,
    joint: JointCertificate,
}

/// The joint certificate, K_c and the loop's verdict ([`decide_kc`]), then the std MPC's
/// numbers.
fn export_mpc(
    resolved: &ResolvedScenario,
    o: &ExportOptions,
    est: &EstimatorExport,
    kc_arg: Iterations,
    joint: JointCertificate,
) -> Result<MpcExport, ExportError> {
    let mpc_method = joint.mpc_method;
    let (k_c, v) = decide_kc(
        resolved,
        &est.loop_cert,
        &joint,
        kc_arg,
        est.k,
        o.scalar,
        o.allow_uncertified,
    )
    .map_err(|e| ExportError::not_certified("k_c", &e))?;
    let data = (|| {
        let ctrl = portable_mpc(resolved, mpc_method, k_c)?;
        OwnedMpc::from_controller(&ctrl, resolved.mpc()?)
    })()
    .map_err(|e| ExportError::unsupported(&e))?;
    let artefact = MpcArtefact {
        method: mpc_method.name().into_owned(),
        k_c,
        k_c_min: joint.analysis.k_c_min(est.k, joint.region.k_max),
        certified: v.certified.is_certified(),
        reason: uncertified_reason(&v, &format!("K_c = {k_c}")),
    };
    Ok(MpcExport {
        data,
        artefact,
        joint,
    })
}
