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
//! **The MPC** (an export with `--kc`): a loop step is the MHE step plus the MPC's control,
//! K_c iterations on its condensed QP (n = N·n_u, θ = x̂). Its rows
//! (`data/cortex-m-mpc-model.csv`) are fitted the same way on the control part of the loop
//! program measured under QEMU (`data/cortex-m-mpc-points.csv`, F = n·n_x, + 2n² for
//! ADMM); [`fits_loop`] adds the two bounds, each raised by its own row's error.
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
/// The MPC's measured points: its `mpc_control` inside the loop program, and the whole loop
/// step (`bash scripts/cortex-m.sh calibrate`).
pub const MPC_POINTS_CSV: &str = include_str!("../data/cortex-m-mpc-points.csv");
/// The MPC's fitted coefficients (`python3 scripts/fit-instructions.py`).
pub const MPC_MODEL_CSV: &str = include_str!("../data/cortex-m-mpc-model.csv");

/// Which part of a loop step a model row predicts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The MHE step: push + estimate on the full window (`data/cortex-m-model.csv`).
    Mhe,
    /// The MPC's control: K_c iterations on its condensed QP (`data/cortex-m-mpc-model.csv`).
    Mpc,
}

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

    /// The MPC's condensed QP at horizon N: n = N·n_u inputs, θ = x̂ (n_θ = n_x).
    pub fn mpc(nx: usize, nu: usize, horizon: usize) -> StepDims {
        StepDims {
            n: horizon * nu,
            n_theta: nx,
            horizon,
            nx,
            nu,
        }
    }
}

/// A bad input of the budget, naming the user's key and the fix.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
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

/// One row of the fitted model: a (part, target, method, scalar).
#[derive(Debug, Clone, PartialEq)]
pub struct InstructionModel {
    /// The MHE step or the MPC's control.
    pub part: Part,
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
    /// Every row of the stored MHE model.
    pub fn all() -> Result<Vec<InstructionModel>, String> {
        Self::parse(Part::Mhe)
    }

    /// Every row of the stored model of `part`.
    pub fn parse(part: Part) -> Result<Vec<InstructionModel>, String> {
        let (text, file) = match part {
            Part::Mhe => (MODEL_CSV, "data/cortex-m-model.csv"),
            Part::Mpc => (MPC_MODEL_CSV, "data/cortex-m-mpc-model.csv"),
        };
        let mut rows = Vec::new();
        for (line_no, line) in data_lines(text).skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let bad = || format!("{file} line {line_no}: `{line}` is malformed");
            if f.len() != 15 {
                return Err(bad());
            }
            let num = |i: usize| f[i].trim().parse::<f64>().map_err(|_| bad());
            let int = |i: usize| f[i].trim().parse::<usize>().map_err(|_| bad());
            rows.push(InstructionModel {
                part,
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

    /// The MHE row of (target, method, scalar), `None` when it was not calibrated.
    pub fn find(
        target: Target,
        method: &str,
        scalar: Scalar,
    ) -> Result<Option<InstructionModel>, String> {
        Self::find_part(Part::Mhe, target, method, scalar)
    }

    /// The row of (part, target, method, scalar), `None` when it was not calibrated.
    pub fn find_part(
        part: Part,
        target: Target,
        method: &str,
        scalar: Scalar,
    ) -> Result<Option<InstructionModel>, String> {
        Ok(Self::parse(part)?
            .into_iter()
            .find(|m| m.target == target && m.method == method && m.scalar == scalar))
    }

    /// The multiply-adds F outside the K iterations of the MHE step (see the crate docs).
    pub fn fixed_ops(method: &str, d: StepDims) -> f64 {
        let mut f = (d.n * d.n_theta + d.horizon * d.nx * (2 * d.nx + d.nu)) as f64;
        if method.starts_with("admm") {
            f += 2.0 * (d.n * d.n) as f64;
        }
        f
    }

    /// The multiply-adds F outside the K_c iterations of the MPC's control: q = F·x̂
    /// (n·n_x; no window to propagate), + 2n² for ADMM's warm start.
    pub fn mpc_fixed_ops(method: &str, d: StepDims) -> f64 {
        let mut f = (d.n * d.n_theta) as f64;
        if method.starts_with("admm") {
            f += 2.0 * (d.n * d.n) as f64;
        }
        f
    }

    /// Predicted instructions of the step outside the iterations.
    pub fn fixed(&self, d: StepDims) -> f64 {
        let ops = match self.part {
            Part::Mhe => Self::fixed_ops(&self.method, d),
            Part::Mpc => Self::mpc_fixed_ops(&self.method, d),
        };
        self.c0 + self.c_fixed * ops
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
    pub fn raise(&self) -> f64 {
        1.0 / (1.0 - self.max_rel_err.clamp(0.0, 0.5))
    }

    /// Whether n lies outside the calibrated sizes.
    pub fn extrapolated(&self, d: StepDims) -> bool {
        d.n < self.n_range.0 || d.n > self.n_range.1
    }
}

/// Non-comment lines with their 1-based line numbers.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// One measured point of `data/cortex-m-points.csv`.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
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
    /// The MPC's share when the step is a loop step (MHE + the K_c-iteration MPC; `None`:
    /// the estimator alone). `instructions` and `instructions_upper` above are then the sums.
    pub mpc: Option<MpcShare>,
    /// The verdict.
    pub verdict: Verdict,
}

/// The MPC's part of a loop step's budget.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MpcShare {
    /// The MPC's method.
    pub method: String,
    /// K_c.
    pub k_c: usize,
    /// Predicted max instructions of its control (`None`: not calibrated).
    pub instructions: Option<f64>,
    /// The prediction raised by its row's worst relative error.
    pub instructions_upper: Option<f64>,
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
        let mpc = match &self.mpc {
            Some(MpcShare {
                k_c,
                instructions_upper: Some(c),
                ..
            }) => format!(" (MPC K_c = {k_c}: {})", si(*c)),
            _ => String::new(),
        };
        let head = format!("{} instr{mpc}, {}{ex}", si(i), micros_text(us));
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

/// The verdict, computed here only, for the estimator alone: does the step of `method` at K
/// on a window of `dims` fit T_s on `target` at `clock_mhz` in `scalar`? `sample_time =
/// None` (the scenario gives none) or a method without calibration gives
/// [`Verdict::NotComputed`] with the reason; a bad clock, T_s or K = 0 is an error naming
/// the key. [`fits_loop`] counts the MPC too.
pub fn fits(
    target: Target,
    clock_mhz: f64,
    method: &str,
    scalar: Scalar,
    dims: StepDims,
    k: usize,
    sample_time: Option<f64>,
) -> Result<Budget, BudgetError> {
    let mhe = Step { method, dims, k };
    fits_loop(target, clock_mhz, scalar, mhe, None, sample_time)
}

/// One part of a loop step: a method at its iterations on a QP of `dims`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Step<'a> {
    /// The method (`export --method` / `--mpc-method` name).
    pub method: &'a str,
    /// The QP's sizes: [`StepDims::of`] for the MHE, [`StepDims::mpc`] for the MPC.
    pub dims: StepDims,
    /// K (the MHE) or K_c (the MPC).
    pub k: usize,
}

/// The verdict on a loop step: push + estimate (`mhe`) and, with `mpc`, the K_c-iteration
/// control, each predicted by its own calibrated rows and raised by its own worst relative
/// error; the sum is what must fit T_s, and `k_max` is the largest MHE K that fits with the
/// MPC's K_c kept. A part without calibration gives [`Verdict::NotComputed`]; a bad clock,
/// T_s, K = 0 or K_c = 0 is an error naming the key.
pub fn fits_loop(
    target: Target,
    clock_mhz: f64,
    scalar: Scalar,
    mhe: Step<'_>,
    mpc: Option<Step<'_>>,
    sample_time: Option<f64>,
) -> Result<Budget, BudgetError> {
    check_clock(clock_mhz)?;
    if let Some(ts) = sample_time {
        check_sample_time(ts)?;
    }
    for (key, k) in [("K", Some(mhe.k)), ("K_c", mpc.map(|m| m.k))] {
        if k == Some(0) {
            return Err(BudgetError {
                key,
                problem: "is 0; the solver runs at least one iteration per step".into(),
            });
        }
    }
    let mut budget = Budget {
        target,
        scalar,
        clock_mhz,
        k: mhe.k,
        sample_time,
        instructions: None,
        instructions_upper: None,
        micros: None,
        extrapolated: false,
        mpc: mpc.map(|m| MpcShare {
            method: m.method.to_string(),
            k_c: m.k,
            instructions: None,
            instructions_upper: None,
        }),
        verdict: Verdict::NotComputed {
            reason: String::new(),
        },
    };
    let not_computed = |mut b: Budget, reason: String| {
        b.verdict = Verdict::NotComputed { reason };
        Ok(b)
    };
    let model = match row(Part::Mhe, target, mhe.method, scalar) {
        Ok(m) => m,
        Err(reason) => return not_computed(budget, reason),
    };
    // The MPC's predicted upper bound (0 without the MPC).
    let mut mpc_upper = 0.0;
    if let (Some(step), Some(share)) = (mpc, budget.mpc.as_mut()) {
        let m = match row(Part::Mpc, target, step.method, scalar) {
            Ok(m) => m,
            Err(reason) => return not_computed(budget, format!("the MPC: {reason}")),
        };
        mpc_upper = m.upper(step.dims, step.k);
        share.instructions = Some(m.instructions(step.dims, step.k));
        share.instructions_upper = Some(mpc_upper);
        budget.extrapolated |= m.extrapolated(step.dims);
    }
    let upper = model.upper(mhe.dims, mhe.k) + mpc_upper;
    let mpc_pred = budget
        .mpc
        .as_ref()
        .and_then(|m| m.instructions)
        .unwrap_or(0.0);
    budget.instructions = Some(model.instructions(mhe.dims, mhe.k) + mpc_pred);
    budget.instructions_upper = Some(upper);
    budget.micros = Some(upper / clock_mhz);
    budget.extrapolated |= model.extrapolated(mhe.dims);
    let Some(ts) = sample_time else {
        return not_computed(
            budget,
            "the scenario gives no sample period (plant.sample_time)".into(),
        );
    };
    let available = ts * clock_mhz * 1e6;
    let k_max = largest_k(&model, mhe.dims, mpc_upper, available);
    budget.verdict = if upper <= available {
        Verdict::Fits {
            margin: (available - upper) / available,
            k_max: k_max.unwrap_or(mhe.k).max(mhe.k),
        }
    } else {
        Verdict::DoesNotFit { k_max }
    };
    Ok(budget)
}

/// The calibrated row of (part, target, method, scalar), or why there is none.
fn row(
    part: Part,
    target: Target,
    method: &str,
    scalar: Scalar,
) -> Result<InstructionModel, String> {
    match InstructionModel::find_part(part, target, method, scalar)? {
        Some(m) => Ok(m),
        None => Err(format!(
            "method `{method}` has no {} calibration on {target}",
            scalar.name()
        )),
    }
}

/// The largest K ≥ 1 with `model.upper(dims, K) + extra ≤ available` (`extra`: the MPC's
/// bound), decided by the same comparison as the verdict (so K fits and K + 1 does not).
fn largest_k(
    model: &InstructionModel,
    dims: StepDims,
    extra: f64,
    available: f64,
) -> Option<usize> {
    let fits = |k: usize| model.upper(dims, k) + extra <= available;
    if !fits(1) {
        return None;
    }
    let per = model.per_iteration(dims) * model.raise();
    if per <= 0.0 {
        return Some(usize::MAX);
    }
    let guess = ((available - extra - model.fixed(dims) * model.raise()) / per).floor();
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

mod loop_points;
pub use loop_points::{LoopPoint, loop_points};

#[cfg(test)]
mod tests;

#[cfg(test)]
mod tests_loop;
