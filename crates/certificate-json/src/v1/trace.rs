//! `trace.json` of `cargo xtask reproduce` (docs/reproduce-output.md): the scenario's data as
//! the estimator used it (plant, sets, the MHE problem with its P, the MPC) and every
//! simulation with its per-step records ([`TraceRecord`], filled from `closed_loop::Trace`)
//! and the Kalman baseline on the same data.

use closed_loop::ClosedLoopError;
use closed_loop::scenario::ResolvedScenario;
use lti_model::BoxSet;
use lti_model::matrix::to_rows;
use serde::Serialize;

use super::*;

/// `format` of trace.json.
pub const TRACE_FORMAT: &str = "suboptimal-mhe/closed-loop-trace";

/// The cost (9) as the MHE minimises it, written into trace.json (`mhe.cost`;
/// docs/reproduce-output.md repeats it).
pub const MHE_COST: &str = "V = 2·η^{M_t}·‖x̂_{t−M_t} − prior‖²_P + Σ_{i=1}^{M_t} η^{i−1}·(2‖ŵ_{t−i}‖²_Q + \
     ‖C x̂_{t−i} + F ŵ²_{t−i} − y_{t−i}‖²_R), x̂_{j+1} = A x̂_j + B u_j + E ŵ¹_j, ŵ_j ∈ 𝒲, \
     M_t = min(M, t); variables z = (x̂_{t−M_t}, ŵ_{t−M_t}, …, ŵ_{t−1})";

/// A box with ±∞ bounds written as null.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoxRecord {
    /// Lower bounds (null = −∞).
    pub lower: Vec<Option<f64>>,
    /// Upper bounds (null = +∞).
    pub upper: Vec<Option<f64>>,
}

impl From<&BoxSet> for BoxRecord {
    fn from(b: &BoxSet) -> Self {
        let f = |v: &[f64]| v.iter().map(|a| num(*a)).collect();
        Self {
            lower: f(b.lower()),
            upper: f(b.upper()),
        }
    }
}

/// Plant of eq. (1).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelRecord {
    /// n_x, n_u, n_y, dim w¹, dim w².
    #[serde(flatten)]
    pub dims: PlantDims,
    /// A.
    pub a: Vec<Vec<f64>>,
    /// B.
    pub b: Vec<Vec<f64>>,
    /// C.
    pub c: Vec<Vec<f64>>,
    /// E (w¹ → x⁺).
    pub e: Vec<Vec<f64>>,
    /// F (w² → y).
    pub f: Vec<Vec<f64>>,
}

/// 𝒳, 𝒰, 𝒴, 𝒲.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetsRecord {
    /// 𝒳.
    pub state: BoxRecord,
    /// 𝒰.
    pub input: BoxRecord,
    /// 𝒴.
    pub output: BoxRecord,
    /// 𝒲 (w = (w¹, w²)).
    pub disturbance: BoxRecord,
}

/// The MHE problem's data (cost (9)).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MheInfo {
    /// M.
    pub horizon: usize,
    /// η.
    pub eta: f64,
    /// P (computed from LMI (2) unless the scenario gives it).
    pub p: Vec<Vec<f64>>,
    /// Q.
    pub q: Vec<Vec<f64>>,
    /// R.
    pub r: Vec<Vec<f64>>,
    /// `"computed from LMI (2)"` or `"scenario mhe.p"`.
    pub p_source: String,
    /// Warm start rule.
    pub warm_start: String,
    /// The cost, written out ([`MHE_COST`]).
    pub cost: String,
}

/// The MPC's data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MpcInfo {
    /// N.
    pub horizon: usize,
    /// Q_c.
    pub q_c: Vec<Vec<f64>>,
    /// R_c.
    pub r_c: Vec<Vec<f64>>,
    /// P_f (DARE).
    pub terminal_weight: Vec<Vec<f64>>,
}

/// One simulation in trace.json.
#[derive(Debug, Serialize)]
pub struct TraceRun<'a> {
    /// Summary (same as in certificate.json).
    #[serde(flatten)]
    pub summary: RunSummary,
    /// Per step records.
    pub trace: TraceRecord<'a>,
    /// The Kalman baseline's estimates x̂^KF_t and error norms on the same data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kalman: Option<KalmanRecord<'a>>,
}

/// The Kalman baseline's run in trace.json (`closed_loop::baseline::BaselineRun`'s fields,
/// in this schema's own type so the library's can grow).
#[derive(Debug, Serialize)]
pub struct KalmanRecord<'a> {
    /// x̂^KF_t per step.
    pub x_hat: &'a [Vec<f64>],
    /// ‖x_t − x̂^KF_t‖ per step (null where not finite).
    pub e_norms: Vec<Option<f64>>,
    /// The estimator's error, if an estimate or an update failed (the run stops there).
    pub error: Option<&'a str>,
    /// Where the bounded rule (signal e) failed first, if it did.
    pub divergence: Option<Divergence>,
}

impl<'a> From<&'a closed_loop::baseline::BaselineRun> for KalmanRecord<'a> {
    fn from(l: &'a closed_loop::baseline::BaselineRun) -> Self {
        Self {
            x_hat: &l.x_hat,
            e_norms: l.e_norms.iter().map(|e| num(*e)).collect(),
            error: l.error.as_deref(),
            divergence: l.divergence.as_ref().map(Divergence::from),
        }
    }
}

impl<'a> From<&'a mhe_report::Run> for TraceRun<'a> {
    fn from(r: &'a mhe_report::Run) -> Self {
        Self {
            summary: RunSummary::from(&r.summary),
            trace: TraceRecord::from(&r.trace),
            kalman: r.kalman.as_ref().map(KalmanRecord::from),
        }
    }
}

/// trace.json (docs/reproduce-output.md).
#[derive(Debug, Serialize)]
pub struct TraceDocument<'a> {
    /// [`TRACE_FORMAT`].
    pub format: &'static str,
    /// [`CERTIFICATE_FORMAT_VERSION`] (both files share it).
    pub format_version: u32,
    /// The preset, if any.
    pub preset: Option<Preset>,
    /// The job label.
    pub label: &'a str,
    /// The scenario.
    pub scenario: &'a ScenarioRecord,
    /// Provenance.
    pub provenance: &'a Provenance,
    /// Plant.
    pub model: ModelRecord,
    /// Sets.
    pub sets: SetsRecord,
    /// MHE data.
    pub mhe: MheInfo,
    /// MPC data.
    pub mpc: MpcInfo,
    /// x₀.
    pub x0: &'a [f64],
    /// x̄₀.
    pub prior: &'a [f64],
    /// The runs.
    pub runs: Vec<TraceRun<'a>>,
}

/// What a trace document records beside the scenario and the runs: who wrote it, for which
/// preset and job.
#[derive(Debug, Clone)]
pub struct TraceHeader<'a> {
    /// The preset, if any.
    pub preset: Option<Preset>,
    /// The job label.
    pub label: &'a str,
    /// The scenario as read.
    pub scenario: &'a ScenarioRecord,
    /// Provenance.
    pub provenance: &'a Provenance,
}

impl<'a> TraceDocument<'a> {
    /// trace.json of the runs of `resolved`: the plant, the sets, the MHE's data with the P
    /// it used (the scenario's `mhe.p`, or the maximal solution of LMI (2)), the MPC's.
    ///
    /// Errors: a scenario without `[mhe]` or `[mpc]`, or whose P could not be computed.
    ///
    /// ```no_run
    /// use certificate_json::v1;
    /// # use closed_loop::scenario::Scenario;
    /// let scenario = Scenario::from_file("scenarios/case-study-certified.toml")?;
    /// let report = mhe_report::report(scenario, &mhe_report::Options::default(), &mhe_report::Quiet)?;
    /// let record = v1::ScenarioRecord {
    ///     name: report.scenario.name.clone(),
    ///     description: None,
    ///     path: "scenarios/case-study-certified.toml".into(),
    ///     text: None,
    /// };
    /// let provenance = v1::Provenance {
    ///     tool: "my-program".into(),
    ///     tool_version: "1.0.0".into(),
    ///     git_revision: "unknown".into(),
    ///     git_dirty: None,
    ///     rustc: None,
    ///     created_unix: 0,
    /// };
    /// let header = v1::TraceHeader { preset: None, label: "mine", scenario: &record, provenance: &provenance };
    /// let doc = v1::TraceDocument::new(header, &report.resolved, &report.runs)?;
    /// std::fs::write("trace.json", serde_json::to_string(&doc)?)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        header: TraceHeader<'a>,
        resolved: &'a ResolvedScenario,
        runs: &'a [mhe_report::Run],
    ) -> Result<Self, ClosedLoopError> {
        let scenario = resolved.scenario();
        let sys = &scenario.plant;
        let spec =
            (scenario.mhe.as_ref()).ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
        let mpc = resolved.mpc()?;
        let cfg = resolved.mhe_config()?;
        let m = to_rows;
        let p_source = if spec.p().is_some() {
            "scenario mhe.p"
        } else {
            "computed from LMI (2)"
        };
        Ok(Self {
            format: TRACE_FORMAT,
            format_version: CERTIFICATE_FORMAT_VERSION,
            preset: header.preset,
            label: header.label,
            scenario: header.scenario,
            provenance: header.provenance,
            model: ModelRecord {
                dims: PlantDims::from(sys),
                a: m(sys.a()),
                b: m(sys.b()),
                c: m(sys.c()),
                e: m(sys.e()),
                f: m(sys.f()),
            },
            sets: SetsRecord {
                state: BoxRecord::from(&scenario.sets.state),
                input: BoxRecord::from(&scenario.sets.input),
                output: BoxRecord::from(&scenario.sets.output),
                disturbance: BoxRecord::from(&scenario.sets.disturbance),
            },
            mhe: MheInfo {
                horizon: cfg.horizon,
                eta: cfg.eta,
                p: m(cfg.p.as_ref()),
                q: m(cfg.q.as_ref()),
                r: m(cfg.r.as_ref()),
                p_source: p_source.into(),
                warm_start: format!("{:?}", cfg.warm_start).to_lowercase(),
                cost: MHE_COST.into(),
            },
            mpc: MpcInfo {
                horizon: mpc.horizon(),
                q_c: m(mpc.q_c().as_ref()),
                r_c: m(mpc.r_c().as_ref()),
                terminal_weight: m(mpc.terminal_weight().as_ref()),
            },
            x0: &scenario.simulation.x0,
            prior: &scenario.simulation.prior,
            runs: runs.iter().map(TraceRun::from).collect(),
        })
    }
}
