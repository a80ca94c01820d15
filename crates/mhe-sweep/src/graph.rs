//! The theory of a sweep as a graph of small tasks for the pool (`pool.rs`): the
//! certificate's two long enumerations split into independent mask chunks, a task becoming
//! ready when its inputs are done, everything computed once per sweep and shared by the
//! solvers.
//!
//! | task | inputs | computes |
//! | --- | --- | --- |
//! | `gamma13_plan` | — | γ₁,₃'s families, candidate metrics and S-procedure figures ([`Gamma13Plan::start`]) |
//! | `gamma13_enumeration` × ≤ 64 | the plan | one mask chunk of γ₁,₃'s free-set enumeration ([`Gamma13Plan::chunk`]) |
//! | `l_pi_enumeration` × ≤ 32 | — | one mask chunk of L_π's free-set enumeration ([`CondensedMpc::lipschitz_enumerated_in`]) |
//! | `linear` × solvers (× K_c) | — | ρ_lin on the K grid ([`solver_linear`]) |
//! | `certificate` | every chunk and the plan | the scenario's certificate from the pieces ([`certify_closed_loop_with`]): L_Φ, Theorem 1 per solver |
//! | `solver` × solvers | the certificate | the certificate covering the solver ([`theory_of`]) and, in a 2-D sweep, its (K_e, K_c) staircase |
//! | `regional` × solvers (× distinct uncertainty of the scales) | the solver's task (its K_min caps the search) | K_reg ([`RegionalPlan::run`]) |
//!
//! The chunks are fixed by 2^s (not by the thread count) and reduced in chunk order by a
//! maximum, so the certificate equals [`super::solver_theory`]'s bit for bit
//! (`xtask/tests/cli/engine/sweep.rs`, `long_theory_tasks_equal_the_sequential_certificate`).

use std::ops::Range;
use std::sync::{OnceLock, PoisonError, RwLock};

use mpc_core::{CondensedMpc, ENUMERATION_MAX_VARS, MpcError};

use closed_loop::scenario::ResolvedScenario;
use iss_certificate::certificate::{
    ClosedLoopCertificate, ComputedParts, certify_closed_loop_with,
};
use iss_certificate::coverage::covering;
use iss_certificate::gamma13::{
    GAMMA13_PATTERN_FAMILIES, Gamma13Chunk, Gamma13Plan, Gamma13Source, Gamma13Stage,
};

use super::config::SweepConfig;
use super::region::Staircase;
use super::regional::{RegionalPlan, RegionalSide, theorem1_k_min};
use super::schedule::TaskKind;
use super::theory::{
    LinearEntry, LinearSide, SolverTheory, certificate_options, joint_staircase, solver_linear,
    theory_of,
};
use super::{ControllerChoice, Method};

/// L_π's free-set enumeration runs in at most this many mask chunks.
pub const L_PI_CHUNKS: u64 = 32;

/// One theory task.
#[derive(Debug, Clone, Copy)]
pub(super) enum TheoryJob {
    /// γ₁,₃'s plan.
    Gamma13Plan,
    /// Chunk `i` of γ₁,₃'s enumeration.
    Gamma13(usize),
    /// Chunk `i` of L_π's enumeration.
    LPi(usize),
    /// ρ_lin for entry `i` of the (solver, K_c) pairs.
    Linear(usize, Method, Option<usize>, ControllerChoice),
    /// The certificate from its pieces.
    Certificate,
    /// The theory (and 2-D staircase) of `solvers[i]`.
    Solver(usize),
    /// Search `i` of the K_reg plan.
    Regional(usize),
}

/// Where a K_reg search takes the K_min that caps it.
#[derive(Debug, Clone, Copy)]
enum KMin {
    /// Known when the graph is built (no certificate covers the configuration, or the
    /// theory was computed before).
    Known(Option<usize>),
    /// From the `Solver` task of `solvers[i]`.
    Solver(usize),
}

impl TheoryJob {
    pub(super) fn kind(self) -> TaskKind {
        match self {
            TheoryJob::Gamma13Plan => TaskKind::Gamma13Plan,
            TheoryJob::Gamma13(_) => TaskKind::Gamma13Enumeration,
            TheoryJob::LPi(_) => TaskKind::LPiEnumeration,
            TheoryJob::Linear(..) => TaskKind::Linear,
            TheoryJob::Certificate => TaskKind::Certificate,
            TheoryJob::Solver(_) => TaskKind::Solver,
            TheoryJob::Regional(_) => TaskKind::Regional,
        }
    }
}

/// What the graph computed, for [`super::Sweep`]'s caches.
#[derive(Debug, Default)]
pub(super) struct TheoryResults {
    pub theory: Option<Vec<(Method, SolverTheory)>>,
    pub linear: Option<LinearSide>,
    pub boundaries: Option<Vec<(Method, Staircase)>>,
    pub regional: Option<RegionalSide>,
}

type Stage<'a> = Option<Result<Gamma13Stage<'a>, MpcError>>;

/// The theory tasks of one sweep and their results as they arrive.
pub(super) struct TheoryGraph<'a> {
    resolved: &'a ResolvedScenario,
    config: &'a SweepConfig,
    mpc: Option<&'a CondensedMpc>,
    /// Each task and its inputs (indices in this list, all earlier).
    pub jobs: Vec<(TheoryJob, Vec<usize>)>,
    l_pi_ranges: Vec<Range<u64>>,
    l_pi: Vec<OnceLock<Result<Option<f64>, MpcError>>>,
    /// Whether γ₁,₃ is computed by the plan's tasks (else by the certificate task).
    gamma13_tasks: bool,
    stage: RwLock<Stage<'a>>,
    g13: Vec<OnceLock<Result<Gamma13Chunk, MpcError>>>,
    certificate: OnceLock<Result<ClosedLoopCertificate, String>>,
    solvers: Vec<OnceLock<(SolverTheory, Staircase)>>,
    linear: Vec<OnceLock<LinearEntry>>,
    regional_plan: Option<RegionalPlan>,
    regional_k_min: Vec<KMin>,
    regional: Vec<OnceLock<(Option<usize>, String)>>,
    theory_wanted: bool,
    linear_wanted: bool,
    boundaries_wanted: bool,
}

impl<'a> TheoryGraph<'a> {
    /// The tasks for what is wanted: the certificate's pieces and the per-solver theory
    /// when `theory` (or, in a 2-D sweep, `boundaries`) is wanted, ρ_lin when `linear` is,
    /// the K_reg searches when `regional` is (`Some(known)`: `known` is the theory computed
    /// before, if any, else the searches wait for the solvers' tasks).
    /// A configuration no certificate covers needs no task: its theory is returned in
    /// `ready` at once.
    pub(super) fn new(
        resolved: &'a ResolvedScenario,
        config: &'a SweepConfig,
        theory: bool,
        linear: bool,
        boundaries: bool,
        regional: Option<Option<&[(Method, SolverTheory)]>>,
    ) -> (Self, TheoryResults) {
        let mut ready = TheoryResults::default();
        let mut g = TheoryGraph {
            resolved,
            config,
            mpc: resolved.mpc().ok(),
            jobs: Vec::new(),
            l_pi_ranges: Vec::new(),
            l_pi: Vec::new(),
            gamma13_tasks: false,
            stage: RwLock::new(None),
            g13: Vec::new(),
            certificate: OnceLock::new(),
            solvers: Vec::new(),
            linear: Vec::new(),
            regional_plan: None,
            regional_k_min: Vec::new(),
            regional: Vec::new(),
            theory_wanted: false,
            linear_wanted: false,
            boundaries_wanted: false,
        };
        let solvers = &config.solvers;
        let uncovered = solvers.first().and_then(|&first| {
            covering(resolved.scenario(), first, config.controller)
                .uncovered_reason()
                .map(ToString::to_string)
        });
        if let (Some(reason), true) = (&uncovered, theory || boundaries) {
            let t: Vec<(Method, SolverTheory)> = solvers
                .iter()
                .map(|&s| (s, SolverTheory::Unavailable(reason.clone())))
                .collect();
            if boundaries {
                ready.boundaries = Some(
                    t.iter()
                        .map(|(s, th)| (*s, joint_staircase(th, &config.k_grid)))
                        .collect(),
                );
            }
            if theory {
                ready.theory = Some(t);
            }
        } else if theory || boundaries {
            g.theory_wanted = theory;
            g.boundaries_wanted = boundaries;
            g.certificate_jobs();
        }
        if linear {
            g.linear_wanted = true;
            let controllers = config.grid_controllers();
            // Before the certificate's assembly in the list: ready at once.
            let at = g
                .jobs
                .iter()
                .position(|(j, _)| matches!(j, TheoryJob::Certificate))
                .unwrap_or(g.jobs.len());
            let mut lin = Vec::new();
            for &s in solvers {
                for &(k_c, c) in &controllers {
                    lin.push((TheoryJob::Linear(g.linear.len(), s, k_c, c), Vec::new()));
                    g.linear.push(OnceLock::new());
                }
            }
            let n = lin.len();
            // Shift the inputs of the tasks after the insertion point.
            for (_, deps) in g.jobs.iter_mut().skip(at) {
                for d in deps.iter_mut().filter(|d| **d >= at) {
                    *d += n;
                }
            }
            g.jobs.splice(at..at, lin);
        }
        if let Some(known) = regional {
            g.regional_jobs(known, ready.theory.as_deref());
        }
        (g, ready)
    }

    /// The K_reg searches (after every other theory task), each after its solver's task
    /// when the theory is computed here.
    fn regional_jobs(
        &mut self,
        known: Option<&[(Method, SolverTheory)]>,
        ready: Option<&[(Method, SolverTheory)]>,
    ) {
        let scales = self
            .config
            .scales
            .clone()
            .unwrap_or_else(|| vec![self.resolved.scenario().noise.scale]);
        let plan = RegionalPlan::new(
            self.resolved,
            &self.config.solvers,
            &scales,
            self.config.controller,
            self.config.k_c_grid.as_deref(),
        );
        for (i, search) in plan.searches.iter().enumerate() {
            let slot = self.config.solvers.iter().position(|&s| s == search.solver);
            let task = self
                .jobs
                .iter()
                .position(|(j, _)| matches!(j, TheoryJob::Solver(k) if Some(*k) == slot));
            let from = |t: Option<&[(Method, SolverTheory)]>| {
                t.and_then(|t| t.iter().find(|(s, _)| *s == search.solver))
                    .and_then(|(_, th)| theorem1_k_min(th))
            };
            let (k_min, deps) = match (task, slot) {
                (Some(t), Some(k)) => (KMin::Solver(k), vec![t]),
                _ => (KMin::Known(from(known).or_else(|| from(ready))), Vec::new()),
            };
            self.regional_k_min.push(k_min);
            self.regional.push(OnceLock::new());
            self.jobs.push((TheoryJob::Regional(i), deps));
        }
        self.regional_plan = Some(plan);
    }

    /// The certificate's tasks: γ₁,₃'s plan and chunks and L_π's chunks (when the
    /// enumerations apply: the certified γ₁,₃, no state constraints in the MPC), the
    /// assembly, one task per solver.
    fn certificate_jobs(&mut self) {
        let opts = certificate_options(self.resolved.scenario(), &self.config.solvers);
        let mut inputs = Vec::new();
        if let Some(mpc) = self.mpc.filter(|m| m.certificate_void_reason().is_none()) {
            if opts.gamma13 == Gamma13Source::Certified {
                self.gamma13_tasks = true;
                let plan = self.jobs.len();
                self.jobs.push((TheoryJob::Gamma13Plan, Vec::new()));
                inputs.push(plan);
                for i in 0..Gamma13Plan::max_chunks(mpc) {
                    inputs.push(self.jobs.len());
                    self.jobs.push((TheoryJob::Gamma13(i), vec![plan]));
                    self.g13.push(OnceLock::new());
                }
            }
            let s = mpc.saturable().len();
            if s <= ENUMERATION_MAX_VARS.min(30) {
                let total = mpc.free_set_count();
                let step = total.div_ceil(L_PI_CHUNKS).max(1);
                self.l_pi_ranges = (0..L_PI_CHUNKS)
                    .map(|c| (c * step).min(total)..((c + 1) * step).min(total))
                    .filter(|r| !r.is_empty())
                    .collect();
                for i in 0..self.l_pi_ranges.len() {
                    inputs.push(self.jobs.len());
                    self.jobs.push((TheoryJob::LPi(i), Vec::new()));
                    self.l_pi.push(OnceLock::new());
                }
            }
        }
        let cert = self.jobs.len();
        self.jobs.push((TheoryJob::Certificate, inputs));
        for i in 0..self.config.solvers.len() {
            self.jobs.push((TheoryJob::Solver(i), vec![cert]));
            self.solvers.push(OnceLock::new());
        }
    }

    /// Runs task `i` (its inputs are done).
    pub(super) fn run(&self, i: usize) {
        let (job, _) = self.jobs[i];
        match job {
            TheoryJob::Gamma13Plan => {
                let opts = certificate_options(self.resolved.scenario(), &self.config.solvers);
                if let Some(mpc) = self.mpc {
                    let stage = Gamma13Plan::start(
                        mpc,
                        opts.enumeration_max_vars,
                        GAMMA13_PATTERN_FAMILIES,
                        opts.phase_seconds,
                    );
                    *self.stage.write().unwrap_or_else(PoisonError::into_inner) = Some(stage);
                }
            }
            TheoryJob::Gamma13(c) => {
                let stage = self.stage.read().unwrap_or_else(PoisonError::into_inner);
                if let Some(Ok(Gamma13Stage::Plan(plan))) = stage.as_ref() {
                    if c < plan.chunks() {
                        let _ = self.g13[c].set(plan.chunk(c));
                    }
                }
            }
            TheoryJob::LPi(c) => {
                if let Some(mpc) = self.mpc {
                    let r = mpc
                        .lipschitz_enumerated_in(ENUMERATION_MAX_VARS, self.l_pi_ranges[c].clone());
                    let _ = self.l_pi[c].set(r);
                }
            }
            TheoryJob::Linear(e, s, k_c, c) => {
                let grid = self.config.k_grid.clone();
                if let Some(entry) =
                    solver_linear(self.resolved, &[s], &[(k_c, c)], |_| grid.clone())
                        .0
                        .into_iter()
                        .next()
                {
                    let _ = self.linear[e].set(entry);
                }
            }
            TheoryJob::Certificate => {
                let mut parts = ComputedParts::default();
                parts.l_pi_enumerated = self.l_pi_enumerated();
                parts.gamma13_certified = self.gamma13_certified();
                let opts = certificate_options(self.resolved.scenario(), &self.config.solvers);
                let cert = certify_closed_loop_with(self.resolved, &opts, parts)
                    .map(|(c, _)| c)
                    .map_err(|e| format!("no certificate: {e}"));
                let _ = self.certificate.set(cert);
            }
            TheoryJob::Solver(k) => {
                let s = self.config.solvers[k];
                let theory = match self.certificate.get() {
                    Some(Ok(cert)) => theory_of(self.resolved, cert, s, self.config.controller),
                    Some(Err(reason)) => SolverTheory::Unavailable(reason.clone()),
                    None => SolverTheory::Unavailable("no certificate: not computed".into()),
                };
                let staircase = if self.boundaries_wanted {
                    joint_staircase(&theory, &self.config.k_grid)
                } else {
                    Vec::new()
                };
                let _ = self.solvers[k].set((theory, staircase));
            }
            TheoryJob::Regional(i) => {
                let Some(plan) = &self.regional_plan else {
                    return;
                };
                let k_min = match self.regional_k_min[i] {
                    KMin::Known(k) => k,
                    KMin::Solver(k) => self.solvers[k].get().and_then(|(t, _)| theorem1_k_min(t)),
                };
                let _ = self.regional[i].set(plan.run(self.resolved, i, k_min));
            }
        }
    }

    /// L_enum from the chunks (None: no chunk tasks, the certificate computes it): the
    /// first error in chunk order, None when the enumeration was not run, else the maximum
    /// — what the sequential enumeration returns.
    fn l_pi_enumerated(&self) -> Option<Result<Option<f64>, MpcError>> {
        if self.l_pi.is_empty() {
            return None;
        }
        let mut best = 0.0_f64;
        for cell in &self.l_pi {
            match cell.get() {
                Some(Ok(Some(v))) => best = best.max(*v),
                Some(Ok(None)) => return Some(Ok(None)),
                Some(Err(e)) => return Some(Err(e.clone())),
                None => return None,
            }
        }
        Some(Ok(Some(best)))
    }

    /// The certified γ₁,₃ from the plan and its chunks (None: no plan task, the certificate
    /// computes it).
    fn gamma13_certified(
        &self,
    ) -> Option<Result<iss_certificate::gamma13::Gamma13Certificate, MpcError>> {
        if !self.gamma13_tasks {
            return None;
        }
        let stage = self
            .stage
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .take()?;
        Some(match stage {
            Err(e) => Err(e),
            Ok(Gamma13Stage::Done(c)) => Ok(*c),
            Ok(Gamma13Stage::Plan(plan)) => {
                let chunks = (0..plan.chunks())
                    .map(|c| match self.g13[c].get() {
                        Some(r) => r.clone(),
                        None => Err(MpcError::Parameter {
                            name: "γ₁,₃ enumeration chunk",
                            value: c as f64,
                            reason: "not computed",
                        }),
                    })
                    .collect();
                plan.finish(chunks)
            }
        })
    }

    /// Everything computed, once every task is done.
    pub(super) fn results(&self) -> TheoryResults {
        let solvers = || {
            self.config
                .solvers
                .iter()
                .zip(&self.solvers)
                .filter_map(|(&s, cell)| cell.get().map(|(t, b)| (s, t.clone(), b.clone())))
                .collect::<Vec<_>>()
        };
        TheoryResults {
            theory: self
                .theory_wanted
                .then(|| solvers().into_iter().map(|(s, t, _)| (s, t)).collect()),
            linear: self.linear_wanted.then(|| {
                LinearSide(
                    self.linear
                        .iter()
                        .filter_map(|c| c.get().cloned())
                        .collect(),
                )
            }),
            boundaries: self
                .boundaries_wanted
                .then(|| solvers().into_iter().map(|(s, _, b)| (s, b)).collect()),
            regional: self
                .regional_plan
                .as_ref()
                .map(|p| p.side(|i| self.regional[i].get().cloned())),
        }
    }
}
