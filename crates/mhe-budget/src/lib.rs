//! The sample period as a budget: does one step of the exported estimator (push +
//! estimate, the full window) fit the sample period T_s on a Cortex-M target?
//!
//! **The instruction model** is calibrated, never guessed: `bash scripts/cortex-m.sh
//! calibrate` measures the max instructions per step of the exported C under
//! `qemu-system-arm -icount shift=0` for every exportable method on both boards at several
//! sizes n_z and K, in f64 and f32 (`data/cortex-m-points.csv`), and
//! `scripts/fit-instructions.py` fits per (target, method, scalar)
//!
//! ```text
//! instructions(K) = c0 + c_fixed·F + K·(c_quad·n² + c_lin·n)
//! ```
//!
//! with n = n_z and F = n·n_θ + M·n_x·(2n_x + n_u) (+ 2n² for ADMM), the multiply-adds
//! outside the K iterations counted from the portable kernel's loops (q = q₀ + Fθ, the
//! propagation of x̂₀ through the window, ADMM's two products at the warm start); n² are an
//! iteration's matrix-vector product and n its vector update (`data/cortex-m-model.csv`,
//! with each row's worst relative error on held-out K and on all points).
//!
//! **Instructions, not cycles.** The time is instructions / f_clk, i.e. one instruction per
//! cycle; a real board adds flash wait states and multi-cycle instructions (and the M7 can
//! dual-issue). The verdict uses the prediction raised by the model's worst relative error
//! over all its calibration points, and says when n_z lies outside the calibrated sizes
//! ("extrapolated").
//!
//! **f32 is a measurement of the f32 export**, its own rows of the model: the instructions
//! of the K given, which the certificate does not cover in f32 unless it says so (the
//! f32 certificate is void on the shipped scenarios, docs/theory.md "Certified f32"); the
//! caller says which.
//!
//! ```
//! use mhe_budget::{Scalar, Target, StepDims, Verdict, fits};
//! // The cart-pendulum's window (n_z = 58, n_θ = 31, M = 9, n_x = 4, n_u = 1) at T_s = 20 ms.
//! let dims = StepDims { n: 58, n_theta: 31, horizon: 9, nx: 4, nu: 1 };
//! let b = fits(Target::CortexM7, 480.0, "admm-pr", Scalar::F64, dims, 10, Some(0.02)).unwrap();
//! assert!(matches!(b.verdict, Verdict::Fits { .. }));
//! assert!(fits(Target::CortexM7, 0.0, "admm-pr", Scalar::F64, dims, 10, Some(0.02)).is_err());
//! ```

use std::fmt;

/// The measured points (`bash scripts/cortex-m.sh calibrate`).
pub const POINTS_CSV: &str = include_str!("../data/cortex-m-points.csv");
/// The fitted coefficients (`python3 scripts/fit-instructions.py`).
pub const MODEL_CSV: &str = include_str!("../data/cortex-m-model.csv");

/// The scalar of the export (`export --scalar`): each has its own rows of the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// f64.
    F64,
    /// f32.
    F32,
}

impl Scalar {
    /// The name of `--scalar` and of the data files' `scalar` column.
    pub fn name(self) -> &'static str {
        match self {
            Scalar::F64 => "f64",
            Scalar::F32 => "f32",
        }
    }

    fn parse(name: &str) -> Option<Scalar> {
        match name.trim() {
            "f64" => Some(Scalar::F64),
            "f32" => Some(Scalar::F32),
            _ => None,
        }
    }
}

/// A Cortex-M target of `export --target`, as emulated by `scripts/cortex-m.sh`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// Cortex-M4F (QEMU `mps2-an386`): single-precision FPU, f64 in software.
    CortexM4F,
    /// Cortex-M7 (QEMU `mps2-an500`): double-precision FPU.
    CortexM7,
}

impl Target {
    /// Both targets, in the order of the tables.
    pub const ALL: [Target; 2] = [Target::CortexM4F, Target::CortexM7];

    /// The name of `--target` and of the data files.
    pub fn name(self) -> &'static str {
        match self {
            Target::CortexM4F => "cortex-m4f",
            Target::CortexM7 => "cortex-m7",
        }
    }

    /// The default clock in MHz: an STM32F405 (168 MHz) and an STM32H7 (480 MHz).
    pub fn default_clock_mhz(self) -> f64 {
        match self {
            Target::CortexM4F => 168.0,
            Target::CortexM7 => 480.0,
        }
    }

    /// Parses `cortex-m4f` or `cortex-m7`.
    pub fn parse(name: &str) -> Result<Target, BudgetError> {
        Target::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or_else(|| BudgetError {
                key: "--target",
                problem: format!("is `{name}`; use `cortex-m4f` or `cortex-m7`"),
            })
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The sizes of the full window that the model reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepDims {
    /// n = n_z = n_x + M·n_w, the window's decision variables.
    pub n: usize,
    /// n_θ = n_x + M·(n_u + n_y), the window's parameter.
    pub n_theta: usize,
    /// M, the horizon.
    pub horizon: usize,
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
}

impl StepDims {
    /// The full window of a plant (n_x, n_u, n_y, n_w = n_w1 + n_w2) at horizon M:
    /// n_z = n_x + M·n_w, n_θ = n_x + M·(n_u + n_y).
    pub fn of(nx: usize, nu: usize, ny: usize, nw: usize, horizon: usize) -> StepDims {
        StepDims {
            n: nx + horizon * nw,
            n_theta: nx + horizon * (nu + ny),
            horizon,
            nx,
            nu,
        }
    }
}

/// A bad input of the budget, naming the user's key and the fix.
#[derive(Debug, Clone, PartialEq)]
pub struct BudgetError {
    /// The key or flag (`plant.sample_time`, `--clock-mhz`, `--target`, `K`).
    pub key: &'static str,
    /// What is wrong and how to fix it.
    pub problem: String,
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` {}", self.key, self.problem)
    }
}

impl std::error::Error for BudgetError {}

/// One row of the fitted model: a (target, method).
#[derive(Debug, Clone, PartialEq)]
pub struct InstructionModel {
    /// The target.
    pub target: Target,
    /// The method (`export --method` name).
    pub method: String,
    /// The scalar of the calibrated exports.
    pub scalar: Scalar,
    /// Instructions of the step that do not scale with the sizes.
    pub c0: f64,
    /// Instructions per multiply-add outside the iterations.
    pub c_fixed: f64,
    /// Instructions per n² term of one iteration.
    pub c_quad: f64,
    /// Instructions per n term of one iteration.
    pub c_lin: f64,
    /// The calibrated sizes n_z (inclusive range).
    pub n_range: (usize, usize),
    /// The calibrated K (inclusive range).
    pub k_range: (usize, usize),
    /// Worst relative error on the held-out points (the K not fitted).
    pub held_out_rel_err: f64,
    /// Worst relative error on every calibration point of this row.
    pub max_rel_err: f64,
}

impl InstructionModel {
    /// Every row of the stored model.
    pub fn all() -> Result<Vec<InstructionModel>, String> {
        let mut rows = Vec::new();
        for (line_no, line) in data_lines(MODEL_CSV).skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let bad = || format!("data/cortex-m-model.csv line {line_no}: `{line}` is malformed");
            if f.len() != 15 {
                return Err(bad());
            }
            let num = |i: usize| f[i].trim().parse::<f64>().map_err(|_| bad());
            let int = |i: usize| f[i].trim().parse::<usize>().map_err(|_| bad());
            rows.push(InstructionModel {
                target: Target::parse(f[0]).map_err(|_| bad())?,
                method: f[1].to_string(),
                scalar: Scalar::parse(f[14]).ok_or_else(bad)?,
                c0: num(2)?,
                c_fixed: num(3)?,
                c_quad: num(4)?,
                c_lin: num(5)?,
                n_range: (int(6)?, int(7)?),
                k_range: (int(8)?, int(9)?),
                held_out_rel_err: num(12)?,
                max_rel_err: num(13)?,
            });
        }
        Ok(rows)
    }

    /// The row of (target, method, scalar), `None` when it was not calibrated.
    pub fn find(
        target: Target,
        method: &str,
        scalar: Scalar,
    ) -> Result<Option<InstructionModel>, String> {
        Ok(Self::all()?
            .into_iter()
            .find(|m| m.target == target && m.method == method && m.scalar == scalar))
    }

    /// The multiply-adds F outside the K iterations (see the crate docs).
    pub fn fixed_ops(method: &str, d: StepDims) -> f64 {
        let mut f = (d.n * d.n_theta + d.horizon * d.nx * (2 * d.nx + d.nu)) as f64;
        if method.starts_with("admm") {
            f += 2.0 * (d.n * d.n) as f64;
        }
        f
    }

    /// Predicted instructions of the step outside the iterations.
    pub fn fixed(&self, d: StepDims) -> f64 {
        self.c0 + self.c_fixed * Self::fixed_ops(&self.method, d)
    }

    /// Predicted instructions of one iteration.
    pub fn per_iteration(&self, d: StepDims) -> f64 {
        let n = d.n as f64;
        self.c_quad * n * n + self.c_lin * n
    }

    /// Predicted max instructions of one step at K iterations.
    pub fn instructions(&self, d: StepDims, k: usize) -> f64 {
        self.fixed(d) + k as f64 * self.per_iteration(d)
    }

    /// The prediction raised by the row's worst relative error e (|pred − meas| ≤ e·meas,
    /// so meas ≤ pred / (1 − e)): what the verdict uses.
    pub fn upper(&self, d: StepDims, k: usize) -> f64 {
        self.instructions(d, k) * self.raise()
    }

    /// 1 / (1 − e), the factor of [`InstructionModel::upper`].
    fn raise(&self) -> f64 {
        1.0 / (1.0 - self.max_rel_err.clamp(0.0, 0.5))
    }

    /// Whether n_z lies outside the calibrated sizes.
    pub fn extrapolated(&self, d: StepDims) -> bool {
        d.n < self.n_range.0 || d.n > self.n_range.1
    }
}

/// Non-comment lines with their 1-based line numbers.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// One measured point of `data/cortex-m-points.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// The target.
    pub target: Target,
    /// The method.
    pub method: String,
    /// The scalar of the export.
    pub scalar: Scalar,
    /// The scenario file the size came from.
    pub scenario: String,
    /// The window's sizes.
    pub dims: StepDims,
    /// K.
    pub k: usize,
    /// Max instructions per step over the replay (the full window).
    pub max: f64,
}

/// Every stored measurement.
pub fn points() -> Result<Vec<Point>, String> {
    let mut out = Vec::new();
    for (line_no, line) in data_lines(POINTS_CSV).skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let bad = || format!("data/cortex-m-points.csv line {line_no}: `{line}` is malformed");
        if f.len() != 13 {
            return Err(bad());
        }
        let int = |i: usize| f[i].trim().parse::<usize>().map_err(|_| bad());
        out.push(Point {
            target: Target::parse(f[0]).map_err(|_| bad())?,
            method: f[1].to_string(),
            scalar: Scalar::parse(f[12]).ok_or_else(bad)?,
            scenario: f[2].to_string(),
            dims: StepDims {
                horizon: int(3)?,
                n: int(4)?,
                n_theta: int(5)?,
                nx: int(6)?,
                nu: int(7)?,
            },
            k: int(9)?,
            max: f[11].trim().parse::<f64>().map_err(|_| bad())?,
        });
    }
    Ok(out)
}

/// The verdict on one (target, clock, method, sizes, K, T_s).
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// The step fits T_s; `margin` is the fraction of T_s left, `k_max` the largest K
    /// that still fits.
    Fits {
        /// (T_s − t_step) / T_s.
        margin: f64,
        /// The largest K that fits.
        k_max: usize,
    },
    /// The step does not fit; `k_max` the largest K that does (`None`: not even K = 1).
    DoesNotFit {
        /// The largest K that fits, if any.
        k_max: Option<usize>,
    },
    /// Not computed (no sample period, no calibration of the method): the reason.
    NotComputed {
        /// Why.
        reason: String,
    },
}

/// The budget of one step: the prediction and the verdict, with what they rest on.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// The target.
    pub target: Target,
    /// The scalar of the export.
    pub scalar: Scalar,
    /// Its clock in MHz.
    pub clock_mhz: f64,
    /// K.
    pub k: usize,
    /// T_s in seconds, if given.
    pub sample_time: Option<f64>,
    /// Predicted max instructions per step (`None`: method not calibrated).
    pub instructions: Option<f64>,
    /// The instructions the verdict uses: the prediction raised by the model's worst
    /// relative error.
    pub instructions_upper: Option<f64>,
    /// µs per step at the clock, one instruction per cycle, from `instructions_upper`.
    pub micros: Option<f64>,
    /// n_z outside the calibrated sizes.
    pub extrapolated: bool,
    /// The verdict.
    pub verdict: Verdict,
}

impl Budget {
    /// One short line: `12.3 M instr, 73.2 µs: fits 20 ms (margin 99 %, K ≤ 5400)`.
    pub fn summary(&self) -> String {
        let (Some(i), Some(us)) = (self.instructions_upper, self.micros) else {
            if let Verdict::NotComputed { reason } = &self.verdict {
                return format!("not computed: {reason}");
            }
            return "not computed".into();
        };
        let ex = if self.extrapolated {
            " (extrapolated)"
        } else {
            ""
        };
        let head = format!("{} instr, {}{ex}", si(i), micros_text(us));
        match &self.verdict {
            Verdict::Fits { margin, k_max } => format!(
                "{head}: fits {} (margin {:.0} %, K ≤ {k_max})",
                seconds_text(self.sample_time.unwrap_or(0.0)),
                margin * 100.0
            ),
            Verdict::DoesNotFit { k_max: Some(k) } => format!(
                "{head}: does not fit {}: needs K ≤ {k}",
                seconds_text(self.sample_time.unwrap_or(0.0))
            ),
            Verdict::DoesNotFit { k_max: None } => format!(
                "{head}: does not fit {} even at K = 1",
                seconds_text(self.sample_time.unwrap_or(0.0))
            ),
            Verdict::NotComputed { reason } => format!("{head}; fits T_s not computed: {reason}"),
        }
    }
}

/// `12.35 M`, `456.2 k`, `789`: at most 4 significant digits (what the terminal prints;
/// certificate.json keeps every digit).
pub fn si(v: f64) -> String {
    if v >= 1e9 {
        format!("{} G", sig4(v / 1e9))
    } else if v >= 1e6 {
        format!("{} M", sig4(v / 1e6))
    } else if v >= 1e3 {
        format!("{} k", sig4(v / 1e3))
    } else {
        format!("{v:.0}")
    }
}

/// `x` (≥ 0) with at most 4 significant digits and no exponent: 2394, 402.2, 24.72, 1.005.
fn sig4(x: f64) -> String {
    // Thresholds at the rounding boundary, so 999.97 prints as 1000, not 1000.0.
    let decimals = if x >= 999.95 {
        0
    } else if x >= 99.995 {
        1
    } else if x >= 9.9995 {
        2
    } else {
        3
    };
    format!("{x:.decimals$}")
}

fn micros_text(us: f64) -> String {
    if us >= 1e6 {
        format!("{} s", sig4(us / 1e6))
    } else if us >= 1e3 {
        format!("{} ms", sig4(us / 1e3))
    } else {
        format!("{} µs", sig4(us))
    }
}

fn seconds_text(s: f64) -> String {
    micros_text(s * 1e6)
}

/// Checks T_s (`plant.sample_time`): finite and > 0.
pub fn check_sample_time(ts: f64) -> Result<(), BudgetError> {
    if ts.is_finite() && ts > 0.0 {
        Ok(())
    } else {
        Err(BudgetError {
            key: "plant.sample_time",
            problem: format!("is {ts}; give the sample period in seconds, finite and > 0"),
        })
    }
}

/// Checks the clock (`--clock-mhz`): finite and > 0.
pub fn check_clock(clock_mhz: f64) -> Result<(), BudgetError> {
    if clock_mhz.is_finite() && clock_mhz > 0.0 {
        Ok(())
    } else {
        Err(BudgetError {
            key: "--clock-mhz",
            problem: format!(
                "is {clock_mhz}; give the core clock in MHz, finite and > 0 (e.g. 168)"
            ),
        })
    }
}

/// The verdict, computed here only: does the step of `method` at K on a window of `dims`
/// fit T_s on `target` at `clock_mhz` in `scalar`? `sample_time = None` (the scenario gives none) or
/// a method without calibration gives [`Verdict::NotComputed`] with the reason; a bad
/// clock, T_s or K = 0 is an error naming the key.
pub fn fits(
    target: Target,
    clock_mhz: f64,
    method: &str,
    scalar: Scalar,
    dims: StepDims,
    k: usize,
    sample_time: Option<f64>,
) -> Result<Budget, BudgetError> {
    check_clock(clock_mhz)?;
    if let Some(ts) = sample_time {
        check_sample_time(ts)?;
    }
    if k == 0 {
        return Err(BudgetError {
            key: "K",
            problem: "is 0; the estimator runs at least one iteration per step".into(),
        });
    }
    let mut budget = Budget {
        target,
        scalar,
        clock_mhz,
        k,
        sample_time,
        instructions: None,
        instructions_upper: None,
        micros: None,
        extrapolated: false,
        verdict: Verdict::NotComputed {
            reason: String::new(),
        },
    };
    let model = match InstructionModel::find(target, method, scalar) {
        Ok(Some(m)) => m,
        Ok(None) => {
            budget.verdict = Verdict::NotComputed {
                reason: format!(
                    "method `{method}` has no {} calibration on {target}",
                    scalar.name()
                ),
            };
            return Ok(budget);
        }
        Err(e) => {
            budget.verdict = Verdict::NotComputed { reason: e };
            return Ok(budget);
        }
    };
    let upper = model.upper(dims, k);
    budget.instructions = Some(model.instructions(dims, k));
    budget.instructions_upper = Some(upper);
    budget.micros = Some(upper / clock_mhz);
    budget.extrapolated = model.extrapolated(dims);
    let Some(ts) = sample_time else {
        budget.verdict = Verdict::NotComputed {
            reason: "the scenario gives no sample period (plant.sample_time)".into(),
        };
        return Ok(budget);
    };
    let available = ts * clock_mhz * 1e6;
    let k_max = largest_k(&model, dims, available);
    budget.verdict = if upper <= available {
        Verdict::Fits {
            margin: (available - upper) / available,
            k_max: k_max.unwrap_or(k).max(k),
        }
    } else {
        Verdict::DoesNotFit { k_max }
    };
    Ok(budget)
}

/// The largest K ≥ 1 with `model.upper(dims, K) ≤ available`, decided by the same
/// comparison as the verdict (so K fits and K + 1 does not).
fn largest_k(model: &InstructionModel, dims: StepDims, available: f64) -> Option<usize> {
    let fits = |k: usize| model.upper(dims, k) <= available;
    if !fits(1) {
        return None;
    }
    let per = model.per_iteration(dims) * model.raise();
    if per <= 0.0 {
        return Some(usize::MAX);
    }
    let guess = ((available - model.fixed(dims) * model.raise()) / per).floor();
    let mut k = if guess.is_finite() && guess >= 1.0 {
        guess.min(1e15) as usize
    } else {
        1
    };
    while k > 1 && !fits(k) {
        k -= 1;
    }
    while fits(k + 1) {
        k += 1;
    }
    Some(k)
}

#[cfg(test)]
mod tests;
