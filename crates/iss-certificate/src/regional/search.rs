//! K_reg: the smallest K whose regional certificate contains the user's set, by doubling
//! then bisection, under one budget for the whole search; and the cap on K that `reproduce`,
//! the sweep and the bench put on it ([`search_max`]), defined once here.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::{Budget, RegionalCertificate, RegionalOptions, RegionalVoid, certify_at, model};
use closed_loop::scenario::ResolvedScenario;

/// Largest K·n_z the K_reg search of `reproduce`, the sweep and the bench evaluates: the
/// region's rows (every pre-projection point of all K inner iterates of every window) grow
/// with K·n_z, and the cart-pendulum's PG at K_min = 140 227 needed more than 24 GB.
pub const REGIONAL_MAX_K_NZ: usize = 200_000;

/// Largest K the K_reg search tries when Theorem 1 gives no K_min: the top of the linear
/// analysis' default grid (`reproduce` computes ρ_lin on 1 … max(2000, K_min)).
pub const REGIONAL_SEARCH_CAP: usize = 2000;

/// The largest K the search of a method tries, and why that K: min(K_min or
/// [`REGIONAL_SEARCH_CAP`], ⌊[`REGIONAL_MAX_K_NZ`]/n_z⌋), at least 1. A K_reg above K_min
/// adds nothing: Theorem 1 already holds there.
///
/// ```
/// use iss_certificate::regional::search_max;
/// assert_eq!(search_max(Some(243), 49).0, 243);
/// assert_eq!(search_max(None, 49).0, 2000);
/// assert_eq!(search_max(Some(140_227), 58).0, 200_000 / 58);
/// ```
pub fn search_max(k_min: Option<usize>, n_z: usize) -> (usize, String) {
    let by_cost = (REGIONAL_MAX_K_NZ / n_z.max(1)).max(1);
    let (base, why) = match k_min {
        Some(k) => (k.max(1), format!("K_min = {k}")),
        None => (
            REGIONAL_SEARCH_CAP,
            format!("the search cap {REGIONAL_SEARCH_CAP} (Theorem 1 gives no K_min)"),
        ),
    };
    if by_cost < base {
        (
            by_cost,
            format!(
                "K·n_z ≤ {REGIONAL_MAX_K_NZ} with n_z = {n_z} (below {why}: the region's rows \
                 grow with K·n_z)"
            ),
        )
    } else {
        (base, why)
    }
}

/// K_reg: the smallest K at which the regional certificate contains the user's set.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct KReg {
    /// K_reg (None: no K up to `k_max` on the search, or the budget ended it first).
    pub k_reg: Option<usize>,
    /// The certificate at K_reg, or at the largest K evaluated when none contains the set.
    pub certificate: Option<RegionalCertificate>,
    /// Every K evaluated with its margin (−∞ / NaN: void), ascending.
    pub tried: Vec<(usize, f64)>,
    /// The void reason at the largest K tried, if it is void.
    pub void: Option<RegionalVoid>,
    /// Why the search stopped before it was complete: the next evaluation's estimate is beyond
    /// what is left of `certificate.phase_seconds` (or the memory limit). With a K_reg this
    /// means the bisection below it was cut short (K_reg is still certified, possibly not the
    /// smallest); without, that no K beyond the last one tried was evaluated.
    pub stopped: Option<RegionalVoid>,
    /// A row that does not depend on K — of step 0, or of the MHE's first inner iterates at
    /// step 1 — that an admissible realization drives past its bound: no K has a region. These
    /// rows are checked once, before any K (then `certificate` is `None` and `tried` empty); a
    /// step-0 witness found later inside a K's certificate
    /// ([`RegionalCertificate::refuted_at_start`]) ends the search the same way.
    pub refuted_every_k: Option<super::Limit>,
    /// What the rows free of K allow at any K: no K's region contains a set beyond it.
    pub k_free: super::KFreeLimits,
    /// Estimated single-core seconds the search spent (the sum of the estimates of the stages
    /// it ran): a caller running several searches under one budget subtracts it.
    pub spent_seconds: f64,
    /// The outcome at the probe K of [`k_reg_probing`] (say 2·K_lin) when the search
    /// evaluated it: the certificate there says which row limits the region at that K and by
    /// how much, which is why K_reg is above it when the set is not contained.
    pub probe: Option<Probe>,
}

/// The regional certificate at a K the caller asked about ([`k_reg_probing`]).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Probe {
    /// The K.
    pub k: usize,
    /// The certificate at K (None: void there, `void` says why).
    pub certificate: Option<RegionalCertificate>,
    /// Why there is no certificate at K.
    pub void: Option<RegionalVoid>,
}

/// K_reg of `method` (module docs). The rows that do not depend on K first (step 0, and the
/// MHE's first inner iterates at step 1): a witness among them (`refuted_every_k`) ends the
/// search before any K is evaluated (no certificate, nothing tried). Then K = 1, 2, 4, … up to `k_max` until the certificate
/// contains the user's set, then bisection between the last failing and the first passing
/// K. The margin need not be monotone in K: K_reg is certified (evaluated exactly there) and
/// is the smallest K found by this search, not a claim about every K above it.
///
/// The whole search shares one budget, `options.phase_seconds`: each evaluation's stages are
/// estimated before they run, and the first that does not fit ends the search (`stopped`).
pub fn k_reg(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    options: &RegionalOptions,
    k_max: usize,
) -> Result<KReg, RegionalVoid> {
    k_reg_probing(resolved, method, options, k_max, None)
}

/// [`k_reg`] that also answers "why not at K = `probe`?" (the issue's question is K_reg ≤
/// 2·K_lin). After the search, a probe below K_reg (or up to `k_max` when there is none) that
/// was not tried is evaluated on a budget of its own, `options.phase_seconds` again (so a
/// probed search may spend up to twice it): one evaluation more than [`k_reg`], which runs
/// first and unchanged. The margin need not be monotone in K, so the
/// probe can contain the set where larger K's did not; below a K_reg it then becomes K_reg
/// and the bisection runs again below it. The certificate at the probe, whenever the search
/// evaluated it (also as a power of two or a midpoint), is kept in [`KReg::probe`].
///
/// ```no_run
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use iss_certificate::regional::{RegionalOptions, k_reg_probing};
/// let resolved = closed_loop::scenario::Scenario::from_file("scenarios/cart-pendulum-regional.toml")?
///     .resolve()?;
/// let ctrl = closed_loop::scenario::ControllerChoice::ExactMpc;
/// let options = RegionalOptions::from_scenario(&resolved, ctrl)?;
/// let k_lin = 19; // K_lin of FISTA on this plant (reproduce's `linear[]`)
/// let kr = k_reg_probing(&resolved, qp_iter::Method::FISTA, &options, 5896, Some(2 * k_lin))?;
/// if let Some(p) = &kr.probe {
///     let contains = p.certificate.as_ref().is_some_and(|c| c.contains);
///     println!("at K = {}: contains the set: {contains}", p.k);
/// }
/// # Ok(())
/// # }
/// ```
pub fn k_reg_probing(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    options: &RegionalOptions,
    k_max: usize,
    probe: Option<usize>,
) -> Result<KReg, RegionalVoid> {
    let start_of = |p: &model::Pieces| {
        p.windows
            .iter()
            .map(|w| w.lin.start_steps)
            .max()
            .unwrap_or(1)
            .max(1)
    };
    // The rows that do not depend on K first (step 0, and the MHE's first inner iterates at
    // step 1), from the windows of length 0..=2 alone: two steps' rows (not charged to the
    // budget), so a witness there ends the search before any K is evaluated.
    let first = model::pieces_upto(resolved, method, options.controller, 2)?;
    let (witness, k_free) = super::k_free_check(&first, start_of(&first), options)?;
    let none = |void: Option<RegionalVoid>, stopped: Option<RegionalVoid>, every_k| KReg {
        k_reg: None,
        certificate: None,
        tried: Vec::new(),
        void,
        stopped,
        refuted_every_k: every_k,
        k_free: k_free.clone(),
        spent_seconds: 0.0,
        probe: None,
    };
    if let Some(l) = witness {
        return Ok(none(None, None, Some(l)));
    }
    if let Err(e) = Budget::new(options.phase_seconds).check_floor(resolved, 1, options) {
        return Ok(none(Some(e.clone()), Some(e), None));
    }
    let pieces = model::pieces(resolved, method, options.controller)?;
    let mut search = Search {
        pieces: &pieces,
        method,
        options,
        probe,
        start: start_of(&pieces),
        budget: Budget::new(options.phase_seconds),
        // The probe's own budget (the search's is not shared with it: its results are as
        // without a probe).
        probe_budget: Budget::new(options.phase_seconds),
        tried: Vec::new(),
        at_probe: None,
    };
    let Doubling {
        mut found,
        last,
        mut stopped,
        refuted_every_k,
    } = search.double(k_max);
    // The probe, when the bracketing skipped it: the margin need not be monotone, so a K
    // below the last failing one is not known to fail. It runs after the search on its own
    // budget (also when the search's budget ran out); over it, it is left out (`KReg::probe`
    // stays None).
    if found.is_none() && refuted_every_k.is_none() {
        // No K of the doubling contains the set: the probe may (then the bisection below
        // runs under it).
        if let Some(p) = search.unprobed(k_max + 1) {
            if let Ok(r) = search.eval(p, true) {
                if r.as_ref().is_ok_and(|c| c.contains) {
                    found = Some((p, r));
                }
            }
        }
    }
    let Some((hi, best)) = found else {
        let (certificate, void) = match last {
            Some(Ok(c)) => (Some(c), None),
            Some(Err(e)) => (None, Some(e)),
            None => (None, stopped.clone()),
        };
        return Ok(search.finish(KReg {
            k_reg: None,
            certificate,
            tried: Vec::new(),
            void,
            stopped,
            refuted_every_k,
            k_free: k_free.clone(),
            spent_seconds: 0.0,
            probe: None,
        }));
    };
    let (hi, best) = search.bisect(hi, best, &mut stopped);
    Ok(search.finish(KReg {
        k_reg: Some(hi),
        certificate: best.ok(),
        tried: Vec::new(),
        void: None,
        stopped,
        refuted_every_k: None,
        k_free: k_free.clone(),
        spent_seconds: 0.0,
        probe: None,
    }))
}

/// A certificate at one K, or why there is none.
type Outcome = Result<RegionalCertificate, RegionalVoid>;

/// The state one K_reg search carries across its evaluations: both budgets, every K tried
/// with its margin, and the outcome at the probe.
struct Search<'a> {
    pieces: &'a model::Pieces,
    method: qp_iter::Method,
    options: &'a RegionalOptions,
    probe: Option<usize>,
    /// The smallest K with a certificate (the windows' start steps).
    start: usize,
    budget: Budget,
    probe_budget: Budget,
    tried: Vec<(usize, f64)>,
    at_probe: Option<Probe>,
}

/// How the doubling K = start, 2·start, … ended.
struct Doubling {
    /// The first K whose certificate contains the set.
    found: Option<(usize, Outcome)>,
    /// The outcome at the last K tried when none contains it.
    last: Option<Outcome>,
    stopped: Option<RegionalVoid>,
    refuted_every_k: Option<super::Limit>,
}

impl Search<'_> {
    /// The outcome at K on the search's budget (`on_probe_budget`: the probe's). Err only
    /// when the budget or the memory limit stops the evaluation; the K is then not tried.
    fn eval(&mut self, k: usize, on_probe_budget: bool) -> Result<Outcome, RegionalVoid> {
        let budget = if on_probe_budget {
            &mut self.probe_budget
        } else {
            &mut self.budget
        };
        let r = certify_at(self.pieces, self.method, k, self.options, budget).map(|r| r.0);
        if let Err(e @ (RegionalVoid::OverBudget { .. } | RegionalVoid::OverMemory { .. })) = r {
            return Err(e);
        }
        if self.probe == Some(k) {
            self.at_probe = Some(Probe {
                k,
                certificate: r.as_ref().ok().cloned(),
                void: r.as_ref().err().cloned(),
            });
        }
        self.tried.push((
            k,
            r.as_ref().map_or(f64::NAN, |c| {
                if c.contains {
                    c.margin
                } else {
                    c.margin.min(0.999_999)
                }
            }),
        ));
        Ok(r)
    }

    /// The probe, if it is in [start, `upper`) and was not tried.
    fn unprobed(&self, upper: usize) -> Option<usize> {
        self.probe
            .filter(|&p| p >= self.start && p < upper && !self.tried.iter().any(|t| t.0 == p))
    }

    /// K = start, 2·start, … up to `k_max` until the certificate contains the set.
    fn double(&mut self, k_max: usize) -> Doubling {
        let mut k = self.start;
        let mut out = Doubling {
            found: None,
            last: None,
            stopped: None,
            refuted_every_k: None,
        };
        loop {
            let r = match self.eval(k, false) {
                Ok(r) => r,
                Err(why) => {
                    out.stopped = Some(why);
                    break;
                }
            };
            if r.as_ref().is_ok_and(|c| c.contains) {
                out.found = Some((k, r));
                break;
            }
            let every_k = r.as_ref().ok().and_then(|c| c.refuted_at_start.clone());
            out.last = Some(r);
            if let Some(l) = every_k {
                out.refuted_every_k = Some(l);
                break;
            }
            if k >= k_max {
                break;
            }
            k = (k * 2).min(k_max);
        }
        out
    }

    /// Bisection below the passing `hi` (and the probe below it, on its own budget): the
    /// smallest passing K found and its certificate.
    fn bisect(
        &mut self,
        mut hi: usize,
        mut best: Outcome,
        stopped: &mut Option<RegionalVoid>,
    ) -> (usize, Outcome) {
        loop {
            // Every K tried below the bracket top failed (the probe may sit below the last one).
            let mut lo = self
                .tried
                .iter()
                .map(|t| t.0)
                .filter(|&t| t < hi)
                .max()
                .unwrap_or(self.start - 1);
            while hi - lo > 1 && stopped.is_none() {
                let mid = lo + (hi - lo) / 2;
                match self.eval(mid, false) {
                    Ok(r) if r.as_ref().is_ok_and(|c| c.contains) => {
                        hi = mid;
                        best = r;
                    }
                    Ok(_) => lo = mid,
                    Err(why) => *stopped = Some(why),
                }
            }
            let Some(p) = self.unprobed(hi) else {
                break;
            };
            match self.eval(p, true) {
                Ok(r) if r.as_ref().is_ok_and(|c| c.contains) => {
                    hi = p;
                    best = r;
                }
                _ => break,
            }
        }
        (hi, best)
    }

    /// `out` with what the search carries filled in: K's tried (ascending), the seconds spent
    /// on both budgets, the probe's outcome.
    fn finish(mut self, mut out: KReg) -> KReg {
        self.tried.sort_by_key(|t| t.0);
        out.tried = self.tried;
        out.spent_seconds =
            self.budget.total - self.budget.left + self.probe_budget.total - self.probe_budget.left;
        out.probe = self.at_probe;
        out
    }
}
