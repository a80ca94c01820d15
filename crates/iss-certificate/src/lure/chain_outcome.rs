//! The iteration chain (Theorem L3b, docs/theory.md §4b, §4c) as one budgeted outcome per
//! (scenario, method) for the projected-gradient family and FISTA: what the one verdict
//! ([`crate::coverage::with_global`]), `reproduce`, certificate.json, `certify --loop` and
//! `export` read.
//!
//! The chain's certified set is not monotone in K, so the outcome is a list of the K checked,
//! each with its own answer, and nothing is said about a K that was not checked. Two kinds of
//! K are checked, both under the method's budget (half of `certificate.phase_seconds`: pg
//! with pg-jacobi take one phase, fista with fista-jacobi another): first the scan
//! K = 1, 2, … that stops at the first certified K (K_chain), at K_glob − 1 (every K ≥ K_glob
//! is Theorem L3's), at [`CHAIN_SCAN_MAX`], or when the budget runs out — each stop is
//! recorded ([`ChainScanEnd`]) — then, with what is left, the scenario's own K
//! (`mhe.iterations`, unless the scan checked it or Theorem L3 covers it).
//!
//! The budget is in estimated CPU seconds, deterministic (no clock): each K's search gets
//! the Riccati solves its LMI size affords from what is left ([`chain_solve_seconds`]); a
//! search that spends them all without a certificate is [`ChainCheck::NotComputed`], naming
//! `certificate.phase_seconds`, never "none".

use closed_loop::scenario::{LoopOptions, ResolvedScenario};
use qp_iter::Method;

use super::global::{ChainOptions, IterationChain, iteration_chain};
use super::global_outcome::{GlobalOutcome, PrecisionOutcome};
use crate::budget::DENSE_RATE;

/// The scan's last K when Theorem L3 gives no K_glob to stop below (a documented cap, not a
/// budget: the chain's LMI grows by n_B per iteration, and beyond ≈ 10 iterations its search
/// costs minutes on the shipped scenarios; docs/theory.md §4b).
pub const CHAIN_SCAN_MAX: usize = 10;

/// The fewest Riccati solves worth starting a K's search with (Theorem L3's 5 × 5 grid of
/// multipliers; below it the K is not computed).
const MIN_SOLVES: usize = 25;

/// A checked chain certificate at one K (the numbers of its independent check).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ChainK {
    /// K.
    pub k: usize,
    /// −λ_max(LMI)/Σ scale in the independent check.
    pub margin: f64,
    /// ρ: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖² for t ≥ M.
    pub rho: f64,
    /// γ of the certificate.
    pub gamma: f64,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄.
    pub gain_x: f64,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄.
    pub gain_e: f64,
}

/// The chain's answer at one K.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ChainCheck {
    /// Certified at this K (only this K: the chain is not monotone).
    #[error(
        "certified at K = {} (ρ = {:.4}, LMI margin {:.2e})",
        .0.k,
        .0.rho,
        .0.margin
    )]
    Certified(ChainK),
    /// The multiplier search ended without a checked certificate (not a proof of absence).
    #[error("K = {k}: the multiplier search found no checked certificate{}", reached(.rho_reached))]
    NotCertified {
        /// K.
        k: usize,
        /// The smallest ρ the ascent reached (unchecked; a distance, not a certificate).
        rho_reached: Option<f64>,
    },
    /// ρ_lin(K) ≥ 1: the loop with every clamp inactive is not stable at this K, so the
    /// chain certifies nothing there (Theorem L3b (ii), a proof of absence; no search run).
    #[error(
        "K = {k}: ρ_lin(K) = {rho_lin:.4} ≥ 1, so no certificate can exist at this K \
         (Theorem L3b (ii); L3c (ii) for FISTA)"
    )]
    LinearlyUnstable {
        /// K.
        k: usize,
        /// ρ_lin(K) of the method's lifted linear loop.
        rho_lin: f64,
    },
    /// The budget stopped (or did not allow) the search at this K.
    #[error(
        "K = {k}: not computed within the budget ({solves} solves of ≈ {per_solve:.2e} s \
         each, {budget_seconds} s per method); raise certificate.phase_seconds"
    )]
    NotComputed {
        /// K.
        k: usize,
        /// Solves spent before the budget stopped it (0: not started).
        solves: usize,
        /// The estimate of one solve at this K's size.
        per_solve: f64,
        /// The method's budget.
        budget_seconds: f64,
    },
    /// The chain refuses this K (its LMI is above the size limit: the sentence names
    /// `mhe.iterations`).
    #[error("{reason}")]
    Refused {
        /// K.
        k: usize,
        /// [`ChainError`](super::global::ChainError)'s sentence.
        reason: String,
    },
}

fn reached(r: &Option<f64>) -> String {
    r.map_or_else(String::new, |r| format!(" (ρ reached {r:.4})"))
}

impl ChainCheck {
    /// The K this answer is about.
    pub fn k(&self) -> usize {
        match self {
            Self::Certified(c) => c.k,
            Self::NotCertified { k, .. }
            | Self::LinearlyUnstable { k, .. }
            | Self::NotComputed { k, .. }
            | Self::Refused { k, .. } => *k,
        }
    }

    /// The certificate, if certified.
    pub fn certified(&self) -> Option<&ChainK> {
        match self {
            Self::Certified(c) => Some(c),
            _ => None,
        }
    }
}

/// Why the scan K = 1, 2, … stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum ChainScanEnd {
    /// At its first certified K (K_chain).
    Certified {
        /// K_chain.
        k: usize,
    },
    /// Every K up to `k` was checked without a certificate: K_glob − 1, or [`CHAIN_SCAN_MAX`].
    Cap {
        /// The last K of the scan.
        k: usize,
    },
    /// The budget (or the size limit) stopped it after `last_k` (0: no K).
    Stopped {
        /// The last K checked.
        last_k: usize,
    },
}

/// The chain of one method: every K checked with its answer.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MethodChain {
    /// The answers, one per K checked (in the order checked).
    pub checks: Vec<ChainCheck>,
    /// How the scan ended.
    pub scan: ChainScanEnd,
    /// The method's budget (estimated single-core seconds).
    pub budget_seconds: f64,
}

impl MethodChain {
    /// The answer at `k`, None where the chain was not checked at `k`.
    pub fn at(&self, k: usize) -> Option<&ChainCheck> {
        self.checks.iter().find(|c| c.k() == k)
    }

    /// Whether the chain certified `k` (checked there and certified).
    pub fn certifies(&self, k: usize) -> bool {
        self.at(k).is_some_and(|c| c.certified().is_some())
    }

    /// K_chain: the smallest K the chain certified (None: none of the K checked).
    pub fn k_chain(&self) -> Option<usize> {
        self.checks
            .iter()
            .filter_map(|c| c.certified().map(|c| c.k))
            .min()
    }

    /// The K checked, ascending.
    pub fn checked(&self) -> Vec<usize> {
        let mut ks: Vec<usize> = self.checks.iter().map(ChainCheck::k).collect();
        ks.sort_unstable();
        ks
    }
}

/// The chain's outcome for one method the chain models ([`chain_models`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ChainOutcome {
    /// The chain was built; what each K checked says.
    Checked(MethodChain),
    /// The chain does not model this loop (the sentence names the key).
    Unsupported {
        /// [`ChainError`](super::global::ChainError)'s sentence.
        reason: String,
    },
    /// No global certificate can exist on this loop (the global outcome says why, e.g.
    /// [`GlobalOutcome::UnstableWithBoundedInput`]): nothing is scanned.
    Impossible(GlobalOutcome),
}

impl ChainOutcome {
    /// The checked chain, if built.
    pub fn chain(&self) -> Option<&MethodChain> {
        match self {
            Self::Checked(c) => Some(c),
            Self::Unsupported { .. } | Self::Impossible(_) => None,
        }
    }

    /// K_chain, if any.
    pub fn k_chain(&self) -> Option<usize> {
        self.chain().and_then(MethodChain::k_chain)
    }

    /// Whether the chain certified `k`.
    pub fn certifies(&self, k: usize) -> bool {
        self.chain().is_some_and(|c| c.certifies(k))
    }
}

/// One line: K_chain with the K checked, or why the chain does not apply (`certify --loop`).
impl std::fmt::Display for ChainOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = match self {
            Self::Unsupported { reason } => return write!(f, "not applicable: {reason}"),
            Self::Impossible(why) => return write!(f, "{why}"),
            Self::Checked(c) => c,
        };
        match c.k_chain() {
            Some(k) => write!(f, "K_chain = {k}")?,
            None => f.write_str("no K certified")?,
        }
        let ks: Vec<String> = c.checked().iter().map(ToString::to_string).collect();
        write!(f, " (K tried: {}", ks.join(", "))?;
        // The K answered without a search: say so, not only in the per-K sentences.
        let mut unstable: Vec<usize> = (c.checks.iter())
            .filter_map(|ch| match ch {
                ChainCheck::LinearlyUnstable { k, .. } => Some(*k),
                _ => None,
            })
            .collect();
        unstable.sort_unstable();
        if !unstable.is_empty() {
            write!(
                f,
                "; ρ_lin(K) ≥ 1 at K = {}: no certificate can exist there (Theorem L3b (ii); \
                 L3c (ii) for FISTA)",
                k_ranges(&unstable)
            )?;
        }
        match c.scan {
            ChainScanEnd::Certified { .. } => f.write_str(")"),
            ChainScanEnd::Cap { k } => write!(f, "; the scan ends at K = {k})"),
            ChainScanEnd::Stopped { last_k } => {
                let at = c
                    .at(last_k + 1)
                    .map(ToString::to_string)
                    .unwrap_or_default();
                write!(f, "; the scan stopped: {at})")
            }
        }
    }
}

/// Sorted K as ranges: `[1, 2, 3, 5]` → `"1–3, 5"`.
fn k_ranges(ks: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < ks.len() {
        let mut j = i;
        while j + 1 < ks.len() && ks[j + 1] == ks[j] + 1 {
            j += 1;
        }
        out.push(if j > i {
            format!("{}–{}", ks[i], ks[j])
        } else {
            ks[i].to_string()
        });
        i = j + 1;
    }
    out.join(", ")
}

/// Whether the chain models `method` (pg, pg-jacobi, fista, fista-jacobi: a projected
/// gradient or FISTA on a box, docs/theory.md §4b, §4c).
pub fn chain_models(method: Method) -> bool {
    [
        Method::PG,
        Method::JACOBI_PRESETS[0],
        Method::FISTA,
        Method::JACOBI_PRESETS[1],
    ]
    .contains(&method)
}

/// The theorem of the chain for `method`: `"Theorem L3b"` for the projected gradient and
/// its Jacobi variant, `"Theorem L3c"` for FISTA and FISTA-Jacobi (docs/theory.md §4b, §4c).
///
/// ```
/// use iss_certificate::lure::chain_outcome::theorem;
/// use qp_iter::Method;
/// assert_eq!(theorem(Method::PG), "Theorem L3b");
/// assert_eq!(theorem(Method::JACOBI_PRESETS[1]), "Theorem L3c");
/// ```
pub fn theorem(method: Method) -> &'static str {
    if method.family() == Method::FISTA.family() {
        "Theorem L3c"
    } else {
        "Theorem L3b"
    }
}

/// Estimated single-core seconds of one Riccati solve of the chain search at dim ζ' =
/// `dim`, dim X = `n_x`: the doubling Riccati (≈ 25 doublings of ≈ 8·n_X³), forming the
/// supply and its Cholesky check (`CHAIN_DIM_FACTOR`·dim³) — an upper figure: measured in
/// release, idle (`chain::calibrate_chain_solve_seconds`, 40 solves per K at K = 1 and 3 on
/// five shipped scenarios), 0.6–25·10⁻³ s per solve against 7.8–124·10⁻³ estimated before
/// session 22 (factor 50) and 6.4–30·10⁻³ now (the cart-pendulum's PG at K = 1: 25·10⁻³
/// measured, 23·10⁻³ estimated; a solve whose Riccati fails early costs less).
pub fn chain_solve_seconds(dim: usize, n_x: usize) -> f64 {
    let (d, nx) = (dim as f64, n_x as f64);
    (200.0 * nx.powi(3) + CHAIN_DIM_FACTOR * d.powi(3)) / DENSE_RATE
}

/// The dim³ factor of [`chain_solve_seconds`] (measured, [`chain_solve_seconds`]).
const CHAIN_DIM_FACTOR: f64 = 5.0;

/// The chain of `method` on `resolved` (the scenario's loop with `method`), scanned from
/// K = 1 up to min(`k_glob` − 1, [`CHAIN_SCAN_MAX`]) and then checked at the scenario's K
/// (unless `k_glob` ≤ it), under `budget_seconds` of estimated CPU. None when the chain does
/// not model `method`.
pub fn method_chain(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    k_glob: Option<usize>,
    budget_seconds: f64,
) -> Option<ChainOutcome> {
    if !chain_models(options.method) {
        return None;
    }
    let ch = match iteration_chain(resolved, options) {
        Ok(ch) => ch,
        Err(e) => {
            return Some(ChainOutcome::Unsupported {
                reason: e.to_string(),
            });
        }
    };
    let opts = ChainOptions::default();
    let mut left = budget_seconds;
    let mut checks = Vec::new();
    let cap = k_glob.map_or(CHAIN_SCAN_MAX, |kg| {
        kg.saturating_sub(1).min(CHAIN_SCAN_MAX)
    });
    let mut scan = ChainScanEnd::Cap { k: cap };
    for k in 1..=cap {
        let c = check(&ch, k, &opts, &mut left, budget_seconds);
        checks.push(c.clone());
        match c {
            ChainCheck::Certified(_) => {
                scan = ChainScanEnd::Certified { k };
                break;
            }
            ChainCheck::NotCertified { .. } | ChainCheck::LinearlyUnstable { .. } => {}
            ChainCheck::NotComputed { .. } | ChainCheck::Refused { .. } => {
                scan = ChainScanEnd::Stopped { last_k: k - 1 };
                break;
            }
        }
    }
    // The scenario's own K with what is left, unless the scan checked it or Theorem L3
    // covers it.
    let k_own = options.iterations.get();
    let fresh = checks.iter().all(|c| c.k() != k_own);
    if fresh && k_glob.is_none_or(|kg| k_own < kg) {
        checks.push(check(&ch, k_own, &opts, &mut left, budget_seconds));
    }
    Some(ChainOutcome::Checked(MethodChain {
        checks,
        scan,
        budget_seconds,
    }))
}

/// One K's search with the solves `left` seconds afford (spent from `left`).
fn check(
    ch: &IterationChain,
    k: usize,
    opts: &ChainOptions,
    left: &mut f64,
    budget_seconds: f64,
) -> ChainCheck {
    let per_solve = chain_solve_seconds(ch.dim(k), ch.global.n_x());
    let not_computed = |solves| ChainCheck::NotComputed {
        k,
        solves,
        per_solve,
        budget_seconds,
    };
    if ch.dim(k) > opts.max_dim {
        return ChainCheck::Refused {
            k,
            reason: ch.too_large(k, opts.max_dim).to_string(),
        };
    }
    // Theorem L3b (ii): where the linear loop is unstable nothing can be certified; its
    // spectral radius costs one eigenvalue problem of the lifted loop's size, far less than
    // the search's first solve.
    if let Ok(rho_lin) = ch.global.lifted.spectral_radius(k, faer::Par::Seq) {
        if rho_lin >= 1.0 {
            return ChainCheck::LinearlyUnstable { k, rho_lin };
        }
    }
    let afford = (*left / per_solve).floor();
    if !(afford >= MIN_SOLVES as f64) {
        return not_computed(0);
    }
    let max_solves = if afford >= 1e9 {
        1_000_000_000
    } else {
        afford as usize
    };
    match ch.certify_chain_within(k, opts, max_solves) {
        Ok(a) => {
            *left -= a.solves as f64 * per_solve;
            match a.cert {
                Some(c) => ChainCheck::Certified(ChainK {
                    k,
                    margin: c.cert.margin,
                    rho: c.cert.rho,
                    gamma: c.cert.gamma,
                    gain_x: c.cert.gain_x,
                    gain_e: c.cert.gain_e,
                }),
                None if a.solves >= max_solves => not_computed(a.solves),
                None => ChainCheck::NotCertified {
                    k,
                    rho_reached: a.rho_reached,
                },
            }
        }
        Err(e) => ChainCheck::Refused {
            k,
            reason: e.to_string(),
        },
    }
}

/// The chain's outcome where even K = 1 cannot get the search's first solves within
/// `budget_seconds`, known from Theorem L3's loop alone (before building the chain, which
/// costs a second global loop on the largest plants): ζ holds the warm start inside X and d
/// (n_z each), so n_ζ ≥ 2·n_z and the chain's dim ζ' = n_ζ − n_z + n_B ≥ n_ζ/2 at K = 1; a
/// solve costs at least [`chain_solve_seconds`] of that. None: build and search.
fn over_budget_at_one(exact: &GlobalOutcome, budget_seconds: f64) -> Option<ChainOutcome> {
    let GlobalOutcome::NotComputed { n_zeta, .. } = exact else {
        return None;
    };
    let per_solve = chain_solve_seconds(n_zeta / 2, 0);
    (per_solve * MIN_SOLVES as f64 > budget_seconds).then(|| {
        ChainOutcome::Checked(MethodChain {
            checks: vec![ChainCheck::NotComputed {
                k: 1,
                solves: 0,
                per_solve,
                budget_seconds,
            }],
            scan: ChainScanEnd::Stopped { last_k: 0 },
            budget_seconds,
        })
    })
}

/// The chain of every loop in `options` (one per method) from its Theorem L3 outcome in
/// `global` (its K_glob bounds the scan), each method under its own `budget_seconds`, one
/// thread per method the chain models: what [`super::global_outcome::global_section`]
/// stores beside K_glob. Deterministic: no answer depends on the threads' order.
pub fn chains(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    global: &[(GlobalOutcome, PrecisionOutcome)],
    budget_seconds: f64,
) -> Vec<Option<ChainOutcome>> {
    std::thread::scope(|s| {
        let handles: Vec<_> = options
            .iter()
            .zip(global)
            .map(|(o, (exact, _))| {
                let k_glob = exact.k_glob();
                let skip = match exact {
                    GlobalOutcome::UnstableWithBoundedInput { .. } => {
                        Some(ChainOutcome::Impossible(exact.clone()))
                    }
                    _ => over_budget_at_one(exact, budget_seconds),
                };
                chain_models(o.method).then(|| {
                    s.spawn(move || match skip {
                        Some(out) => Some(out),
                        None => method_chain(resolved, o, k_glob, budget_seconds),
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.and_then(|h| {
                    h.join().unwrap_or_else(|_| {
                        Some(ChainOutcome::Unsupported {
                            reason: "internal: the chain's thread panicked".into(),
                        })
                    })
                })
            })
            .collect()
    })
}
