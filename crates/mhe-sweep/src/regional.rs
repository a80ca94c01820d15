//! K_reg of one method as `reproduce` and the sweep report it (issue 27): the search of
//! [`iss_certificate::regional::k_reg`] under the library's cap ([`search_max`], re-exported
//! here; the bench uses the same), and the text that says why there is no K_reg — which
//! constraint limits the region, by how much.
//!
//! The search tries K = 1, 2, 4, … then bisects, up to [`search_max`]: the method's K_min
//! when Theorem 1 gives one (a K_reg above K_min adds nothing: the global certificate
//! already holds there), else [`REGIONAL_SEARCH_CAP`]; and never beyond K·n_z =
//! [`REGIONAL_MAX_K_NZ`] (the region's rows grow with K·n_z).

use closed_loop::scenario::ResolvedScenario;
use iss_certificate::regional::{
    KFreeLimits, Limit, RegionalCertificate, RegionalOptions, RegionalVoid, RowKind, k_reg_probing,
};
use lti_model::numfmt::sig4;
use qp_iter::Method;
#[cfg(feature = "serde")]
use serde::Serialize;

pub use iss_certificate::regional::{REGIONAL_MAX_K_NZ, REGIONAL_SEARCH_CAP, search_max};

/// K_reg of one method with the certificate behind it.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct KRegOutcome {
    /// K_reg: the smallest K the search found whose region contains the scenario's
    /// uncertainty (null: none up to `search_max`, or void; `note` says which).
    pub k_reg: Option<usize>,
    /// The largest K the search could try ([`search_max`]).
    pub search_max: usize,
    /// Why `search_max` is that K.
    pub search_max_reason: String,
    /// The K of `certificate`: K_reg, or the largest K tried when there is none.
    pub k: Option<usize>,
    /// The regional certificate at `k` (null when it could not be evaluated there).
    pub certificate: Option<RegionalCertificate>,
    /// Every K evaluated with its margin (the scale of the user's set that is certified;
    /// ≥ 1 iff the region contains it; null = void there), ascending.
    pub tried: Vec<(usize, f64)>,
    /// Why there is no K_reg (null when there is one): the void reason, or the constraint
    /// that limits the region at the largest K tried and by how much.
    pub note: Option<String>,
    /// Why the search stopped early: its next evaluation was estimated beyond what was left of
    /// `certificate.phase_seconds` (or the memory limit). With a K_reg, the bisection below it
    /// was cut short (K_reg is certified, possibly not the smallest).
    pub stopped: Option<String>,
    /// A row of step t = 0 that an admissible realization drives past its bound: step 0 does
    /// not depend on K, so no K has a region (checked before the search; `note` says so).
    pub refuted_every_k: Option<iss_certificate::regional::Limit>,
    /// What the rows free of K allow at any K (null: the search did not run): no K's region
    /// contains a set beyond it.
    pub k_free: Option<iss_certificate::regional::KFreeLimits>,
    /// The certificate at the probe K (`reproduce`: 2·K_lin) when the search evaluated it.
    pub probe: Option<ProbeNote>,
}

/// What the regional certificate says at one K the caller asked about (`reproduce` asks
/// about 2·K_lin, the target): whether its region contains the scenario's set, and
/// which row limits it there and by how much.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct ProbeNote {
    /// The K.
    pub k: usize,
    /// The region at K contains the scenario's uncertainty.
    pub contains: bool,
    /// The largest certified scale of the scenario's set at K (null: void there).
    pub margin: Option<f64>,
    /// The limiting row(s) and the certified scale, or the void reason.
    pub note: String,
}

/// K_reg of `method` ([`k_reg_probing`] up to [`search_max`]`(k_min, n_z)`), with the reason
/// when there is none. `options` is the scenario's uncertainty (or why it has none); `probe`
/// a K to explain (2·K_lin in `reproduce`; None: the plain search).
pub fn k_reg_outcome(
    resolved: &ResolvedScenario,
    method: Method,
    options: &Result<RegionalOptions, RegionalVoid>,
    k_min: Option<usize>,
    n_z: usize,
    probe: Option<usize>,
) -> KRegOutcome {
    let (search_max, search_max_reason) = search_max(k_min, n_z);
    let mut out = KRegOutcome {
        k_reg: None,
        search_max,
        search_max_reason,
        k: None,
        certificate: None,
        tried: Vec::new(),
        note: None,
        stopped: None,
        refuted_every_k: None,
        k_free: None,
        probe: None,
    };
    let o = match options {
        Ok(o) => o,
        Err(e) => {
            out.note = Some(e.to_string());
            return out;
        }
    };
    match k_reg_probing(resolved, method, o, search_max, probe) {
        Err(e) => out.note = Some(e.to_string()),
        Ok(kr) => {
            out.k_reg = kr.k_reg;
            out.k = kr
                .certificate
                .as_ref()
                .map(|c| c.k)
                .or_else(|| kr.tried.last().map(|t| t.0));
            out.tried = kr.tried;
            out.stopped = kr.stopped.as_ref().map(ToString::to_string);
            out.note = match (kr.k_reg, &kr.certificate, kr.void) {
                (Some(_), _, _) => None,
                (None, _, _) if kr.refuted_every_k.is_some() => kr
                    .refuted_every_k
                    .as_ref()
                    .map(|l| k_free_line(l, &kr.k_free, o)),
                (None, c, _) if kr.stopped.is_some() => Some(format!(
                    "the search stopped before a K whose region contains the scenario's \
                     uncertainty{}: {}{}",
                    out.k
                        .map_or(String::new(), |k| format!(" (largest K evaluated: {k})")),
                    kr.stopped
                        .as_ref()
                        .map(ToString::to_string)
                        .unwrap_or_default(),
                    // What the last certificate computed says about the set.
                    c.as_ref().map_or(String::new(), |c| format!(
                        "; at K = {}: {}",
                        c.k,
                        limit_text(c)
                    ))
                )),
                (None, _, Some(v)) => Some(format!(
                    "void at the largest K tried (K = {}): {v}",
                    out.k.unwrap_or(search_max)
                )),
                (None, Some(c), None) => Some(format!(
                    "no K ≤ {search_max} ({}) whose region contains the scenario's uncertainty; \
                     at K = {}: {}",
                    out.search_max_reason,
                    c.k,
                    limit_text(c)
                )),
                (None, None, None) => Some("no K was evaluated".into()),
            };
            out.certificate = kr.certificate;
            out.refuted_every_k = kr.refuted_every_k;
            out.k_free = Some(kr.k_free);
            out.probe = kr.probe.map(|p| match (&p.certificate, p.void) {
                (Some(c), _) => ProbeNote {
                    k: p.k,
                    contains: c.contains,
                    margin: Some(c.margin),
                    note: if c.contains {
                        format!(
                            "the region contains the scenario's uncertainty ({}× of it is \
                             certified)",
                            sig4(c.margin)
                        )
                    } else {
                        probe_text(c)
                    },
                },
                (None, v) => ProbeNote {
                    k: p.k,
                    contains: false,
                    margin: None,
                    note: format!("void: {}", v.map(|v| v.to_string()).unwrap_or_default()),
                },
            });
        }
    }
    out
}

/// A constraint row in words.
pub fn row_text(row: &iss_certificate::regional::RowLabel) -> String {
    let when = match row.step {
        Some(t) => format!("start-up step t = {t}"),
        None => "full window".into(),
    };
    match row.kind {
        RowKind::MheBox => format!(
            "MHE box Z = 𝒳 × 𝒲^M: component {} of inner iterate {} ({when})",
            row.index, row.iterate
        ),
        RowKind::MheGeneral => format!(
            "MHE general 𝒳/𝒴 row {} of inner iterate {} ({when})",
            row.index, row.iterate
        ),
        RowKind::Input => format!("MPC input/state row {} ({when})", row.index),
        // A kind added later (`RowKind` is non-exhaustive): its index and step.
        _ => format!("row {} ({when})", row.index),
    }
}

/// A witness on a row that does not depend on K (step 0, or the MHE's first inner iterates
/// at step 1) in words: it refutes every K.
fn k_free_line(l: &Limit, k_free: &KFreeLimits, o: &RegionalOptions) -> String {
    // One radius at a time, the others at the user's; a radius the user left at 0 that stays
    // at 0 says nothing and is left out.
    let radii: Vec<String> = [
        (k_free.max_prior_error, o.prior_error, "prior error"),
        (k_free.max_x0_radius, o.x0_radius, "x₀ radius"),
        (k_free.max_w_bar, o.w_bar, "w̄"),
    ]
    .into_iter()
    .filter(|&(v, yours, _)| yours > 0.0 || v > 0.0)
    .map(|(v, yours, what)| {
        if v.is_finite() {
            format!("{what} ≤ {} (yours {})", sig4(v), sig4(yours))
        } else {
            format!("any {what}")
        }
    })
    .collect();
    let admits = if k_free.scale > 0.0 {
        format!(
            "The rows free of K admit your set scaled by {} at most{}",
            sig4(k_free.scale),
            if radii.is_empty() {
                String::new()
            } else {
                format!(
                    ", or one radius at a time with the others at yours: {}",
                    radii.join(", ")
                )
            }
        )
    } else {
        "The nominal point alone (x₀ nominal, the prior exact, w = 0) takes a row free of K past \
         its bound: no smaller uncertainty helps"
            .to_string()
    };
    format!(
        "no K whose region contains the scenario's uncertainty exists: {} reaches {} against its \
         bound {} (×{}) for an admissible realization of the set, so a constraint activates at \
         t = {}; this row does not depend on K (at t = 0 the MHE's window-0 problem is solved by \
         its warm start, the prior, at every K; at t = 1 the MHE's first inner iterates start \
         from that prior with the data of t = 0), so this holds at every K (checked once, \
         before the search). {admits}",
        row_text(&l.row),
        sig4(l.attained),
        sig4(l.bound),
        sig4(l.attained / l.bound),
        l.attained_at,
    )
}

fn limit_line(l: &Limit) -> String {
    let by = if l.bound > 0.0 {
        format!(" (×{})", sig4(l.reach / l.bound))
    } else {
        String::new()
    };
    // The certified reach is an upper bound; `attained` a value an admissible realization
    // reaches. Above the bound it proves activation.
    let witness = if l.attained > l.bound {
        format!(
            "; an admissible realization of the set reaches {} at t = {} (×{}): a constraint \
             activates, so no region without active constraints contains the set at this K",
            sig4(l.attained),
            l.attained_at,
            sig4(l.attained / l.bound)
        )
    } else if l.attained > 0.0 && l.attained < l.reach {
        format!(
            "; its true worst case lies in [{}, {}] (the lower end reached by an admissible \
             realization at t = {})",
            sig4(l.attained),
            sig4(l.reach),
            l.attained_at
        )
    } else {
        String::new()
    };
    format!(
        "{} reaches {} against its bound {}{by}{witness}",
        row_text(&l.row),
        sig4(l.reach),
        sig4(l.bound)
    )
}

/// Why the region at a probed K does not contain the set, shortest first: the witness (a
/// constraint an admissible realization activates), else [`limit_text`].
fn probe_text(c: &RegionalCertificate) -> String {
    match &c.witness {
        Some(w) if w.bound > 0.0 => format!(
            "an admissible realization of the set drives a row past its bound: {} reaches {} \
             at t = {} against its bound {} (×{}), so a constraint activates and no region \
             without active constraints contains the set at K = {}",
            row_text(&w.row),
            sig4(w.attained),
            w.attained_at,
            sig4(w.bound),
            sig4(w.attained / w.bound),
            c.k
        ),
        _ => limit_text(c),
    }
}

/// What keeps a certificate's region from containing the user's set: every limiting row
/// (full window, start-up) that the set drives past its bound, with reach, bound and their
/// ratio, and the certified scale of the set (`margin`).
pub fn limit_text(c: &RegionalCertificate) -> String {
    let mut parts = Vec::new();
    for l in [&c.radius_limit, &c.startup_limit].into_iter().flatten() {
        if l.reach > l.bound {
            parts.push(limit_line(l));
        }
    }
    if parts.is_empty() {
        parts.extend(
            [&c.radius_limit, &c.startup_limit]
                .into_iter()
                .flatten()
                .map(limit_line),
        );
    }
    if let Some(w) = &c.witness {
        let shown = [&c.radius_limit, &c.startup_limit]
            .into_iter()
            .flatten()
            .any(|l| l.row == w.row && l.attained > l.bound);
        if !shown {
            parts.push(limit_line(w));
        }
    }
    let scale = if c.margin == f64::NEG_INFINITY {
        "the certified scale of (x0_radius, prior_error, w̄) is −∞: the bound on the nominal \
         x₀'s reach alone exceeds a row's bound"
            .to_string()
    } else {
        format!(
            "the largest certified scale of (x0_radius, prior_error, w̄) is {}× the scenario's",
            sig4(c.margin.max(0.0))
        )
    };
    if parts.is_empty() {
        scale
    } else {
        format!("{}; {scale}", parts.join("; "))
    }
}

// ---------------------------------------------------------------------------------------
// The sweep's K_reg: per solver and disturbance scale
// ---------------------------------------------------------------------------------------

/// n_z = n_x + M·n_w of the scenario's MHE (n_x when it has none).
pub fn window_size(resolved: &ResolvedScenario) -> usize {
    let plant = &resolved.scenario().plant;
    let horizon = resolved.mhe_config().map_or(0, |c| c.horizon);
    plant.nx() + horizon * plant.nw()
}

/// K_reg of one solver at one disturbance scale (and one K_c of a 2-D sweep) of a sweep, as
/// `points.csv` writes it.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RegionalEntry {
    /// Φ of the MHE.
    pub solver: Method,
    /// The disturbance scale (the scenario's uncertainty w̄ scales with it unless
    /// `certificate.w_bar` is given).
    pub scale: f64,
    /// K_c of the MPC in a 2-D sweep (None: the sweep's one controller; an entry without K_c
    /// answers every K_c).
    pub k_c: Option<usize>,
    /// K_reg (None: see `note`).
    pub k_reg: Option<usize>,
    /// Why there is no K_reg (empty when there is one), CSV-safe.
    pub note: String,
}

/// The sweep's K_reg per solver and scale (the `k_reg` and `regional_note` columns).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RegionalSide(pub Vec<RegionalEntry>);

impl RegionalSide {
    /// Adds K_reg of `solver` at `scale` and `k_c` (or why there is none) to `theory`.
    pub fn fill(
        &self,
        solver: Method,
        scale: f64,
        k_c: Option<usize>,
        theory: &mut super::TheoryAtK,
    ) {
        match self.0.iter().find(|e| {
            e.solver == solver
                && e.scale.to_bits() == scale.to_bits()
                && (e.k_c.is_none() || e.k_c == k_c)
        }) {
            Some(e) => {
                theory.k_reg = e.k_reg;
                theory.regional_note = e.note.clone();
            }
            None => theory.regional_note = "no regional certificate for this point".into(),
        }
    }

    /// Every (solver, scale) with the same note (nothing computed).
    pub fn unavailable(solvers: &[Method], scales: &[f64], note: &str) -> Self {
        RegionalSide(
            solvers
                .iter()
                .flat_map(|&solver| {
                    scales.iter().map(move |&scale| RegionalEntry {
                        solver,
                        scale,
                        k_c: None,
                        k_reg: None,
                        note: super::format::csv_text(note),
                    })
                })
                .collect(),
        )
    }
}

/// One K_reg search of a sweep: a solver with the uncertainty of one or more scales.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RegionalSearch {
    /// Φ of the MHE.
    pub solver: Method,
    /// The uncertainty (or why there is none).
    pub options: Result<RegionalOptions, RegionalVoid>,
}

/// The K_reg searches of a sweep: one per solver, distinct uncertainty (the scales whose
/// uncertainty is the same share one search) and, in a 2-D sweep, K_c of the grid (the
/// regional certificate of the K_c-iteration MPC), and which search answers each (solver,
/// scale, K_c).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RegionalPlan {
    /// The searches.
    pub searches: Vec<RegionalSearch>,
    /// (solver, scale, K_c, index in `searches`).
    pub entries: Vec<(Method, f64, Option<usize>, usize)>,
}

impl RegionalPlan {
    /// The plan for `solvers` × `scales` (× `k_c_grid` with the sweep's K_c-iteration MPC)
    /// with `controller` (the scenario's uncertainty at each scale,
    /// [`RegionalOptions::from_scenario`]).
    pub fn new(
        resolved: &ResolvedScenario,
        solvers: &[Method],
        scales: &[f64],
        controller: closed_loop::scenario::ControllerChoice,
        k_c_grid: Option<&[usize]>,
    ) -> Self {
        use closed_loop::scenario::ControllerChoice;
        let controllers: Vec<(Option<usize>, ControllerChoice)> = match (controller, k_c_grid) {
            (ControllerChoice::SuboptimalMpc { method, .. }, Some(grid)) => grid
                .iter()
                .filter_map(|&k_c| {
                    Some((Some(k_c), ControllerChoice::suboptimal(k_c, method).ok()?))
                })
                .collect(),
            _ => vec![(None, controller)],
        };
        let options: Vec<(f64, Option<usize>, Result<RegionalOptions, RegionalVoid>)> = controllers
            .iter()
            .flat_map(|&(k_c, c)| {
                scales.iter().map(move |&scale| {
                    let mut r = resolved.clone();
                    r.set_noise_scale(scale);
                    (scale, k_c, RegionalOptions::from_scenario(&r, c))
                })
            })
            .collect();
        let mut searches: Vec<RegionalSearch> = Vec::new();
        let mut entries = Vec::new();
        for &solver in solvers {
            for (scale, k_c, o) in &options {
                let i = match searches
                    .iter()
                    .position(|s| s.solver == solver && s.options == *o)
                {
                    Some(i) => i,
                    None => {
                        searches.push(RegionalSearch {
                            solver,
                            options: o.clone(),
                        });
                        searches.len() - 1
                    }
                };
                entries.push((solver, *scale, *k_c, i));
            }
        }
        Self { searches, entries }
    }

    /// Search `i` with the solver's K_min (None: Theorem 1 gives none), as the columns
    /// write it: K_reg, or the reason there is none.
    pub fn run(
        &self,
        resolved: &ResolvedScenario,
        i: usize,
        k_min: Option<usize>,
    ) -> (Option<usize>, String) {
        let s = &self.searches[i];
        let out = k_reg_outcome(
            resolved,
            s.solver,
            &s.options,
            k_min,
            window_size(resolved),
            None,
        );
        (
            out.k_reg,
            super::format::csv_text(out.note.as_deref().unwrap_or("")),
        )
    }

    /// The side from the searches' results (`result(i)`, None: not computed).
    pub fn side(&self, result: impl Fn(usize) -> Option<(Option<usize>, String)>) -> RegionalSide {
        RegionalSide(
            self.entries
                .iter()
                .map(|&(solver, scale, k_c, i)| {
                    let (k_reg, note) =
                        result(i).unwrap_or_else(|| (None, "K_reg not computed".into()));
                    RegionalEntry {
                        solver,
                        scale,
                        k_c,
                        k_reg,
                        note,
                    }
                })
                .collect(),
        )
    }
}

/// The K_min that caps a solver's K_reg search: Theorem 1's, when it holds.
pub fn theorem1_k_min(theory: &super::SolverTheory) -> Option<usize> {
    match theory {
        super::SolverTheory::Analysis {
            k_min,
            void_reasons,
            ..
        } if void_reasons.is_empty() => *k_min,
        _ => None,
    }
}
