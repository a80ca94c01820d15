//! Time budgets of the analysis phases (issue 25 item 4, issue 23 item 3): every phase of
//! the certificate has an estimate (multiply-adds from the dimensions alone, converted to
//! seconds of one core at a rate per kind of kernel) before it starts, and one budget per
//! phase, `certificate.phase_seconds` (default [`DEFAULT_PHASE_SECONDS`]), decides what
//! happens to a phase beyond it:
//!
//! | phase | beyond the budget |
//! | --- | --- |
//! | γ₁,₃ free-set enumeration | skipped: the polynomial (S-procedure) bound alone is used, and the skip says so; a Theorem 1 verdict with no K_min that the enumeration could change is [`NotComputed`] ("not computed within the budget", with the estimate to raise the key to), never void |
//! | ρ_lin (the linear stability boundary, `reproduce`) | skipped with the estimate, the budget and the key |
//! | L_Φ sampling (a lower estimate; no certificate depends on it) | fewer pairs, and `l_phi.pairs_reduced` says so |
//! | the regional certificate (`crate::regional`: its two stages at one K, or a whole K_reg search) | not computed: the void reason names the stage, its estimate, what is left and the key |
//! | δ-IOSS P, MHE constants (H̄, L_Φ, φ(K)), L_π, γ₁,₃ family bounds | run (every certificate needs them), the estimate printed first; beyond [`REQUIRED_PHASE_FACTOR`] × the budget the certificate is refused before it starts ([`check_required_phases`]), naming the phase, its estimate and the key |
//!
//! The estimates are deterministic formulas of the dimensions (so the certificate does not
//! depend on the machine), right to within a factor of a few: dense factorisations n³/3,
//! eigenvalues ≈ 10n³, products mnk multiply-adds. Blocked dense kernels (faer) run at about
//! [`DENSE_RATE`] multiply-adds per second on one core of the project's machine, the scalar
//! loops over small matrices (the free-set enumerations) at about [`SCALAR_RATE`]; the
//! calibration is in docs/limits.md.

use crate::certificate::CertificateOptions;
use closed_loop::scenario::Scenario;
use mpc_core::CondensedMpc;
#[cfg(feature = "serde")]
use serde::Serialize;

/// The budget's default and limit are defined where `certificate.phase_seconds` is read.
pub use closed_loop::scenario::{DEFAULT_PHASE_SECONDS, MAX_PHASE_SECONDS};

/// Multiply-adds per second of one core in blocked dense kernels (products, factorisations,
/// eigenvalues of faer): measured 3·10¹⁰ on ρ_lin of the thermal rod (M = 10), rounded down.
pub const DENSE_RATE: f64 = 2e10;

/// Multiply-adds per second of one core in the scalar loops over small matrices (the
/// free-set enumerations): measured ≈ 1.2·10⁹ on the γ₁,₃ enumeration of the thermal rod.
pub const SCALAR_RATE: f64 = 1e9;

/// One analysis phase with its estimated work.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct PhaseEstimate {
    /// The phase (`"δ-IOSS P"`, `"γ₁,₃ free-set enumeration"`, …).
    pub phase: String,
    /// Estimated multiply-adds.
    pub work: f64,
    /// Estimated seconds of one core (`work` at the kernel's rate).
    pub seconds: f64,
    /// Whether the phase runs within the budget (false: skipped, `detail` says what is used
    /// instead).
    pub runs: bool,
    /// What the estimate counts, and what happens beyond the limit.
    pub detail: String,
    /// Every certificate needs the phase (it is never skipped; beyond
    /// [`REQUIRED_PHASE_FACTOR`] × the budget the certificate is refused).
    pub required: bool,
}

/// A phase every certificate needs may take up to this many times `certificate.phase_seconds`
/// (estimated): 300 s of one core at the default budget. Beyond, [`check_required_phases`]
/// refuses the certificate before anything long starts.
pub const REQUIRED_PHASE_FACTOR: f64 = 30.0;

/// Refuses, before it starts, a certificate with a required phase estimated beyond
/// [`REQUIRED_PHASE_FACTOR`] × `opts.phase_seconds`, naming the phase, its estimate and the key
/// that raises the limit (`certificate.phase_seconds`).
pub fn check_required_phases(
    scenario: &Scenario,
    mpc: Option<&CondensedMpc>,
    opts: &CertificateOptions,
) -> Result<(), lti_model::ModelError> {
    let limit = REQUIRED_PHASE_FACTOR * opts.phase_seconds;
    let phases = estimate_phases(scenario, mpc, opts, 1);
    // The advice must suffice for every required phase, not only the first one refused.
    let needed = phases
        .iter()
        .filter(|p| p.required)
        .map(|p| p.seconds / REQUIRED_PHASE_FACTOR)
        .fold(0.0, f64::max);
    for p in phases {
        if p.required && p.seconds > limit {
            return Err(lti_model::spec::format::key_error(
                "certificate.phase_seconds",
                format!(
                    "the certificate's phase \"{}\" is estimated at ≈ {} s of one core ({} \
                     multiply-adds: {}), above the limit of {} s for a phase every certificate \
                     needs ({REQUIRED_PHASE_FACTOR} × `certificate.phase_seconds`, which is {} s); raise \
                     `certificate.phase_seconds` to at least {} to compute it, or reduce the \
                     plant's size or the horizons",
                    p.phase,
                    secs(p.seconds),
                    sci(p.work),
                    p.detail,
                    secs(limit),
                    secs(opts.phase_seconds),
                    secs_at_least(needed)
                ),
            ));
        }
    }
    Ok(())
}

/// A result the analysis budget stopped (issue 37 item 6): *not computed within the
/// budget*, never "void" — a void certificate is a proof that no K works, this is not. The
/// estimate is the one the phase was skipped by (its plan, before it ran), so raising
/// `certificate.phase_seconds` to [`NotComputed::raise_to`] runs it.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct NotComputed {
    /// The phase that was not run (`"γ₁,₃ free-set enumeration"`).
    pub phase: String,
    /// Its estimated seconds of one core (from the dimensions, before it ran).
    pub needed_seconds: f64,
    /// The budget it exceeded (`certificate.phase_seconds`).
    pub budget_seconds: f64,
}

impl NotComputed {
    /// The phase `phase`, estimated at `needed_seconds` of one core, skipped under a budget
    /// of `budget_seconds`.
    pub fn new(phase: impl Into<String>, needed_seconds: f64, budget_seconds: f64) -> Self {
        Self {
            phase: phase.into(),
            needed_seconds,
            budget_seconds,
        }
    }

    /// The value of `certificate.phase_seconds` that runs the phase: its estimate rounded up
    /// to two significant digits (the estimates are right to within a factor of a few, so more
    /// digits would be noise).
    pub fn raise_to(&self) -> f64 {
        let x = self.needed_seconds;
        if !(x.is_finite() && x > 0.0) {
            return x;
        }
        let scale = 10f64.powf(x.log10().floor() - 1.0);
        (x / scale).ceil() * scale
    }
}

impl std::fmt::Display for NotComputed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "not computed within the budget: the {} is estimated at ≈ {} s of one core, above \
             `certificate.phase_seconds` = {} s (raise `certificate.phase_seconds` to ≈ {})",
            self.phase,
            secs(self.needed_seconds),
            secs(self.budget_seconds),
            secs(self.raise_to())
        )
    }
}

/// `x` with 3 significant digits in scientific notation (`2.00e10`), or `inf`.
pub fn sci(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.2e}")
    } else {
        "inf".into()
    }
}

/// Seconds with at most 3 significant digits (`0.012`, `7.5`, `672`, `1.2e4`).
pub fn secs(x: f64) -> String {
    if !x.is_finite() {
        "inf".into()
    } else if x >= 1e4 {
        format!("{x:.1e}")
    } else if x >= 100.0 {
        format!("{x:.0}")
    } else if x >= 10.0 {
        format!("{x:.1}")
    } else if x >= 1.0 {
        format!("{x:.2}")
    } else {
        format!("{x:.2e}")
    }
}

/// [`secs`] of the smallest number ≥ `x` it can print: the printed value, read back, is never
/// below `x` (a budget advised this way suffices; issue 37 item 9: `phase_seconds = 1e-9`
/// was advised "at least 1.00", whatever the phases needed).
pub fn secs_at_least(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return secs(x);
    }
    // Round up at 3 significant digits, then by one unit of the printed digit until the
    // text reads back ≥ x (at most a few steps: `secs` prints 2 or 3 digits).
    let unit = 10f64.powf(x.log10().floor() - 2.0);
    let mut v = (x / unit).ceil() * unit;
    for _ in 0..200 {
        let text = secs(v);
        if text.parse::<f64>().is_ok_and(|r| r >= x) {
            return text;
        }
        v += unit;
    }
    secs(v)
}

/// Estimated multiply-adds of one exact solve of every MHE window (the active set of the
/// sampled L_Φ): Σ_m n_z,m³/3 (scalar loops).
fn window_solves_work(nzs: impl Iterator<Item = usize>) -> f64 {
    nzs.map(|n| (n as f64).powi(3) / 3.0).sum()
}

/// The pairs of the sampled L_Φ within the budget: `requested`, or fewer (at least 1) when
/// 2·`requested` exact solves of every window are estimated beyond `phase_seconds`, with the
/// sentence that says so (the sampled L_Φ is a lower estimate reported beside the certified
/// bound; no certificate depends on it).
pub fn l_phi_sampling_pairs(
    problem: &mhe_core::MheProblem,
    requested: usize,
    phase_seconds: f64,
) -> (usize, Option<PairsReduced>) {
    let per_pair =
        2.0 * window_solves_work(problem.windows().iter().map(|w| w.qp().n())) / SCALAR_RATE;
    let total = per_pair * requested as f64;
    if requested == 0 || total <= phase_seconds {
        return (requested, None);
    }
    let fit = ((phase_seconds / per_pair).floor() as usize).clamp(1, requested);
    (
        fit,
        Some(PairsReduced::Budget {
            requested,
            estimated_seconds: total,
            windows: problem.windows().len(),
            phase_seconds,
            sampled: fit,
        }),
    )
}

/// Why the sampled L_Φ used fewer pairs than asked ([`l_phi_sampling_pairs`]); its
/// `Display` is the sentence the certificate prints.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PairsReduced {
    /// 2·`requested` exact solves of every window were estimated beyond the analysis budget.
    Budget {
        /// Pairs asked for (`lipschitz_pairs`).
        requested: usize,
        /// Estimated seconds of one core for them.
        estimated_seconds: f64,
        /// Windows of the MHE (m = 0..M).
        windows: usize,
        /// The analysis budget (`certificate.phase_seconds`).
        phase_seconds: f64,
        /// Pairs sampled (≥ 1).
        sampled: usize,
    },
}

impl std::fmt::Display for PairsReduced {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Budget {
                requested,
                estimated_seconds,
                windows,
                phase_seconds,
                sampled,
            } => write!(
                f,
                "{requested} pairs are estimated at ≈ {} s of one core (2 exact solves of each \
                 of the {windows} windows per pair) > the analysis budget of {} s (scenario key \
                 `certificate.phase_seconds`): {sampled} pair(s) sampled",
                secs(*estimated_seconds),
                secs(*phase_seconds)
            ),
        }
    }
}

/// The sentence, as before the type (the JSON value is unchanged).
#[cfg(feature = "serde")]
impl serde::Serialize for PairsReduced {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

fn phase(name: &str, work: f64, rate: f64, runs: bool, detail: String) -> PhaseEstimate {
    PhaseEstimate {
        phase: name.into(),
        work,
        seconds: work / rate,
        runs,
        detail,
        required: false,
    }
}

/// A phase every certificate needs (never skipped).
fn required(name: &str, work: f64, rate: f64, detail: String) -> PhaseEstimate {
    PhaseEstimate {
        required: true,
        ..phase(name, work, rate, true, detail)
    }
}

/// Estimated work of the certificate's phases for `scenario` (needs `[mhe]`; `mpc` is the
/// scenario's condensed MPC, for the number of saturable variables) under `opts`. The
/// estimate of ρ_lin is the one of [`crate::linear::LiftedDims::grid_work`] from the dimensions,
/// for the four preset methods on reproduce's 25-point K grid up to `k_top`.
pub fn estimate_phases(
    scenario: &Scenario,
    mpc: Option<&CondensedMpc>,
    opts: &CertificateOptions,
    k_top: usize,
) -> Vec<PhaseEstimate> {
    let mut out = mhe_phases(scenario, opts);
    if let Some(mpc) = mpc {
        out.extend(mpc_phases(scenario, mpc, opts));
        out.push(rho_lin_phase(scenario, opts, k_top));
    }
    out
}

/// The plant's n_x and the MHE's horizon M (0 without `[mhe]`), and n_z(m) = n_x + m·n_w of
/// window m.
fn mhe_dims(scenario: &Scenario) -> (f64, usize, impl Fn(usize) -> f64) {
    let sys = &scenario.plant;
    let (nx, nw) = (sys.nx() as f64, (sys.nw1() + sys.nw2()) as f64);
    let m = scenario.mhe.as_ref().map_or(0, |s| s.horizon());
    (nx, m, move |w: usize| nx + w as f64 * nw)
}

/// The MHE's phases: P of LMI (2), the constants of its windows, the L_Φ sampling.
fn mhe_phases(scenario: &Scenario, opts: &CertificateOptions) -> Vec<PhaseEstimate> {
    let (nx, m, nz) = mhe_dims(scenario);
    let solvers = opts.solvers.len() as f64;
    let mut out = Vec::new();
    out.push(required(
        "δ-IOSS P (LMI (2))",
        10.0 * nx.powi(3) * 300.0,
        DENSE_RATE,
        format!(
            "≈ 10 n_x³ per iteration of the maximal-P iteration, ~300 iterations (at most \
             200 000); n_x = {nx}"
        ),
    ));
    // Per window m = 0..M: the condensed Hessian (nz²·nx), its eigenvalues per solver (10 nz³)
    // and the certified L_Φ (10 nz³).
    let windows: f64 = (0..=m)
        .map(|w| {
            let n = nz(w);
            n * n * nx + (solvers + 1.0) * 10.0 * n.powi(3)
        })
        .sum();
    out.push(required(
        "MHE constants (H̄, L_Φ, φ(K))",
        windows,
        DENSE_RATE,
        format!(
            "{} windows m = 0..M of n_z = n_x + m·n_w ≤ {} variables: eigenvalues per solver \
             and the certified L_Φ (≈ 10 n_z³ each)",
            m + 1,
            nz(m)
        ),
    ));
    let sampling =
        opts.lipschitz_pairs as f64 * 2.0 * window_solves_work((0..=m).map(|w| nz(w) as usize));
    let within = sampling / SCALAR_RATE <= opts.phase_seconds;
    out.push(phase(
        "L_Φ sampling",
        sampling,
        SCALAR_RATE,
        within,
        if within {
            format!(
                "{} pairs × 2 exact solves per window (active set, ≈ n_z³/3 each)",
                opts.lipschitz_pairs
            )
        } else {
            format!(
                "{} pairs × 2 exact solves per window (active set, ≈ n_z³/3 each): beyond the \
                 budget of {} s (`certificate.phase_seconds`), fewer pairs are sampled",
                opts.lipschitz_pairs,
                secs(opts.phase_seconds)
            )
        },
    ));
    out
}

/// The MPC's phases: L_π, the γ₁,₃ family bounds and its free-set enumeration.
fn mpc_phases(
    scenario: &Scenario,
    mpc: &CondensedMpc,
    opts: &CertificateOptions,
) -> Vec<PhaseEstimate> {
    let (nx, _, _) = mhe_dims(scenario);
    let mut out = Vec::new();
    let n = mpc.qp().n() as f64;
    let s = mpc.saturable().len();
    let enumerate_l_pi = s <= mpc_core::ENUMERATION_MAX_VARS;
    let l_pi = if enumerate_l_pi {
        (1u64 << s) as f64 * (n.powi(3) / 6.0 + 2.0 * n * n * nx)
    } else {
        0.0
    } + opts.lipschitz_pairs as f64 * 40.0 * n * n * (n + nx);
    out.push(required(
        "L_π",
        l_pi,
        SCALAR_RATE,
        if enumerate_l_pi {
            format!("2^{s} free sets (Cholesky of ≤ {n} variables) and the sampled estimate")
        } else {
            format!(
                "polynomial bound (s = {s} > {}) and the sampled estimate",
                mpc_core::ENUMERATION_MAX_VARS
            )
        },
    ));
    let fams = crate::gamma13::GAMMA13_PATTERN_FAMILIES as f64;
    out.push(required(
        "γ₁,₃ family bounds",
        20.0 * (fams + 1.0) * 2.0 * 30.0 * (nx.powi(3) + n * nx * nx),
        SCALAR_RATE,
        "≈ 20 metrics × ≤ 17 families × 2 S-procedure searches (≈ 30 n_x × n_x eigenvalue \
         problems each, and the family's N·n_u columns: n_x³ + N·n_u·n_x²); measured 0.7–1.5× \
         on the thermal rod, the mass chain, the quadrotor and a 150-state plant"
            .into(),
    ));
    let enum_work = crate::gamma13::enumeration_work(mpc, 3);
    let allowed = s <= opts.enumeration_max_vars.min(30);
    let within = enum_work / SCALAR_RATE <= opts.phase_seconds;
    out.push(phase(
        "γ₁,₃ free-set enumeration",
        if allowed { enum_work } else { 0.0 },
        SCALAR_RATE,
        allowed && within,
        if !allowed {
            format!(
                "not run: s = {s} saturable variables > cap {}",
                opts.enumeration_max_vars.min(30)
            )
        } else if within {
            format!("2^{s} free sets × 3 metrics at n_x = {nx}")
        } else {
            format!(
                "2^{s} free sets × 3 metrics at n_x = {nx}: beyond the budget of {} s \
                 (`certificate.phase_seconds`), the polynomial bound is used instead",
                secs(opts.phase_seconds)
            )
        },
    ));
    out
}

/// ρ_lin as `reproduce` computes it, estimated from the dimensions.
fn rho_lin_phase(scenario: &Scenario, opts: &CertificateOptions, k_top: usize) -> PhaseEstimate {
    let sys = &scenario.plant;
    let (_, m, nz) = mhe_dims(scenario);
    let dims = crate::linear::LiftedDims {
        nx: sys.nx(),
        nu: sys.nu(),
        ny: sys.ny(),
        horizon: m,
        nz: nz(m) as usize,
        n_controller: 0,
        n_theta: sys.nx() + m * (sys.nu() + sys.ny()),
    };
    let grid = crate::linear::log_spaced(1, k_top.max(2000), 25);
    // What `reproduce` computes: the four preset families when n_z ≤
    // [`crate::linear::ALL_METHODS_MAX_NZ`], else the scenario's own method only.
    let own_lift = match scenario.mhe.as_ref().map(|s| s.method().family()) {
        Some("fista") => 2usize,
        _ => 1,
    };
    let lifts: Vec<usize> = if nz(m) as usize <= crate::linear::ALL_METHODS_MAX_NZ {
        vec![1, 2, 1, 1]
    } else {
        vec![own_lift]
    };
    let per_method: Vec<f64> = lifts
        .iter()
        .map(|&lift| dims.grid_work(nz(m) as usize * lift, &grid))
        .collect();
    let total: f64 = per_method.iter().sum();
    let runs = total / DENSE_RATE <= opts.phase_seconds;
    phase(
        "ρ_lin (reproduce)",
        total,
        DENSE_RATE,
        runs,
        format!(
            "{} method(s) × {} K: the K-step map and the spectral radius of the {} × {} lifted \
             matrix{}",
            per_method.len(),
            grid.len(),
            dims.dim(),
            dims.dim(),
            if runs {
                String::new()
            } else {
                format!(
                    "; beyond the budget of {} s (`certificate.phase_seconds`): not computed",
                    secs(opts.phase_seconds)
                )
            }
        ),
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn pairs_reduced_prints_the_sentence_of_before_the_type() {
        let r = PairsReduced::Budget {
            requested: 200,
            estimated_seconds: 1234.5,
            windows: 10,
            phase_seconds: 60.0,
            sampled: 9,
        };
        assert_eq!(
            r.to_string(),
            "200 pairs are estimated at ≈ 1234 s of one core (2 exact solves of each of the 10 \
             windows per pair) > the analysis budget of 60.0 s (scenario key \
             `certificate.phase_seconds`): 9 pair(s) sampled"
        );
    }

    #[test]
    fn secs_at_least_reads_back_at_least_its_argument() {
        for x in [
            4.0e-8, 1.234_5e-6, 0.999_9, 1.0, 1.234_5, 9.999, 12.345, 999.4, 1234.5, 9_999.5,
            12_345.0, 1.04e6,
        ] {
            let t = secs_at_least(x);
            let r: f64 = t.parse().unwrap();
            assert!(r >= x && r <= 1.11 * x, "{x} → {t}");
        }
    }

    /// Issue 37 item 9: `phase_seconds = 1e-9` advised "at least 1.00" (the ceiling of the
    /// first refused phase). The advice is now the smallest printed value that lets every
    /// required phase run, and it does.
    #[test]
    fn the_advised_phase_seconds_suffices_and_is_computed_from_the_estimate() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenarios/case-study-certified.toml"
        );
        let s = Scenario::from_file(path).unwrap();
        let r = s.clone().resolve().unwrap();
        let tiny = CertificateOptions {
            phase_seconds: 1e-9,
            ..CertificateOptions::default()
        };
        let e = check_required_phases(&s, r.mpc().ok(), &tiny)
            .unwrap_err()
            .to_string();
        let advice: f64 = e
            .split("to at least ")
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .unwrap()
            .parse()
            .unwrap();
        let needed = estimate_phases(&s, r.mpc().ok(), &tiny, 1)
            .iter()
            .filter(|p| p.required)
            .map(|p| p.seconds / REQUIRED_PHASE_FACTOR)
            .fold(0.0, f64::max);
        assert!(
            advice >= needed && advice <= 1.02 * needed,
            "{advice} vs {needed}: {e}"
        );
        let advised = CertificateOptions {
            phase_seconds: advice,
            ..CertificateOptions::default()
        };
        assert!(
            check_required_phases(&s, r.mpc().ok(), &advised).is_ok(),
            "{e}"
        );
    }
}
