//! Scenario files: refused with a named key, bad values never accepted, accepted files
//! satisfy the documented invariants, LMI (2) independent of the units of q and r.

use std::time::Instant;

use closed_loop::scenario::{ResolvedScenario, Scenario};
use faer::MatRef;
use toml::Value;

use crate::generate::{
    Bad, Base, Edit, SCENARIO_KEYS, ScenarioCase, WEIGHT_KEYS, chain, names_user_key,
    scenario_case, scenario_table, to_text,
};
use crate::{Tally, draw, runner};

/// Longest a scenario case may take (parse, resolve with LMI (2) on n_x ≤ 3): far above
/// what a tiny plant needs, far below what a large allocation or a long solve takes.
const CASE_SECONDS: f64 = 2.0;

/// Factors by which q and r are scaled together (the LMI (2) verdict must not change).
const UNITS: [f64; 8] = [1e-12, 1e-9, 1e-6, 1e-3, 1e3, 1e6, 1e9, 1e12];

pub fn survey(seed: u64, n: usize) -> Tally {
    let mut tally = Tally::default();
    let mut rn = runner(seed, 1);
    let strategy = scenario_case();
    for i in 0..n {
        let case = draw(&mut rn, &strategy);
        let text = String::from_utf8_lossy(&case.bytes()).into_owned();
        let t0 = Instant::now();
        let outcome = check(&case, &text, i);
        let took = t0.elapsed().as_secs_f64();
        tally.cases += 1;
        match outcome {
            Ok(true) => tally.refused += 1,
            Ok(false) => tally.accepted += 1,
            Err(why) => tally.finding(format!("{why}\n--- case {case:?}\n--- file:\n{text:.1500}")),
        }
        if took > CASE_SECONDS {
            tally.finding(format!(
                "took {took:.2} s (refused late or a large computation)\n--- file:\n{text:.1500}"
            ));
        }
    }
    tally
}

/// `Ok(true)`: refused with a named key; `Ok(false)`: accepted and honest; `Err`: why not.
fn check(case: &ScenarioCase, text: &str, i: usize) -> Result<bool, String> {
    let named = |stage: &str, msg: String| -> Result<bool, String> {
        if names_user_key(&msg, &[]) {
            Ok(true)
        } else {
            Err(format!("{stage}: the refusal names no user key: {msg}"))
        }
    };
    let scenario = match Scenario::from_toml_str(text) {
        Ok(s) => s,
        Err(e) => return named("parse", chain(&e)),
    };
    let resolved = match scenario.resolve() {
        Ok(r) => r,
        Err(e) => return named("resolve", chain(&e)),
    };
    if let Some(why) = must_refuse(case) {
        return Err(format!("accepted-bad: {why} was accepted"));
    }
    invariants(&resolved)?;
    lmi_wording(&resolved)?;
    if let ScenarioCase::Valid(b) = case {
        units(b, &resolved, i)?;
    }
    Ok(false)
}

/// Why the generator's edit must be refused, if it must.
fn must_refuse(case: &ScenarioCase) -> Option<String> {
    let ScenarioCase::AlmostValid(b, edit) = case else {
        return None;
    };
    match edit {
        Edit::Eta(v) if !(0.0..1.0).contains(v) => Some(format!("mhe.eta = {v}")),
        Edit::NonPd(k, form) => {
            let key = WEIGHT_KEYS[*k];
            let n = match key {
                "mhe.q" | "noise.covariance" => b.nx + b.ny,
                "mhe.r" => b.ny,
                "mpc.r" => b.nu,
                _ => b.nx,
            };
            // Form 3 is the asymmetric one only for n ≥ 2 (else the singular diagonal).
            let form = if *form == 3 && n < 2 { 4 } else { *form };
            // Q_c and a noise covariance may be semidefinite (zero, a singular diagonal).
            let semidefinite_ok = matches!(key, "mpc.q" | "noise.covariance");
            let what = [
                "a negative scalar",
                "zero",
                "indefinite",
                "asymmetric",
                "singular",
            ][form as usize];
            (!(semidefinite_ok && matches!(form, 1 | 4))).then(|| format!("{key} {what}"))
        }
        Edit::BadBox(kind @ 1..=3) => Some(format!(
            "sets.disturbance {}",
            [
                "",
                "lower > upper",
                "infinite lower and upper",
                "a NaN bound"
            ][*kind as usize]
        )),
        Edit::Count(k, v) if *v <= 0 => Some(format!(
            "{} = {v}",
            [
                "mhe.horizon",
                "mpc.horizon",
                "mhe.iterations",
                "simulation.steps"
            ][*k]
        )),
        Edit::BadMethod(kind, v) => {
            let bad = match kind {
                // pg's step and ADMM's ρ: positive and finite.
                0 | 1 => !(v.is_finite() && *v > 0.0),
                // ADMM's relaxation α ∈ (0, 2).
                2 => !(*v > 0.0 && *v < 2.0),
                _ => true,
            };
            bad.then(|| format!("mhe.method {edit:?}"))
        }
        Edit::Replace(k, bad) => {
            let key = SCENARIO_KEYS[*k];
            let value = match bad {
                Bad::Float(v) | Bad::Entry(_, v) => *v,
                _ => return None,
            };
            // An infinite bound of a set is "unbounded"; NaN never means anything.
            let bad_value = value.is_nan() || (value.is_infinite() && !key.starts_with("sets"));
            // A section (a table) replaced by a number is a type error; `name` and
            // `description` are text.
            bad_value.then(|| format!("{key} = {value}"))
        }
        Edit::Unknown(k, name) => Some(format!(
            "an unknown key `{name}` beside `{}`",
            SCENARIO_KEYS[*k]
        )),
        _ => None,
    }
}

/// A symmetric positive definite matrix (Cholesky with a relative floor), else why not.
fn spd(m: MatRef<'_, f64>) -> Result<(), String> {
    let n = m.nrows();
    if m.ncols() != n || n == 0 {
        return Err(format!("{}×{} (not square)", m.nrows(), m.ncols()));
    }
    let scale = (0..n).map(|i| m[(i, i)].abs()).fold(0.0f64, f64::max);
    for i in 0..n {
        for j in 0..n {
            let (a, b) = (m[(i, j)], m[(j, i)]);
            if !a.is_finite() || (a - b).abs() > 1e-12 * scale.max(f64::MIN_POSITIVE) {
                return Err(format!("entry ({i}, {j}) = {a}, ({j}, {i}) = {b}"));
            }
        }
    }
    let mut l = vec![0.0f64; n * n];
    for j in 0..n {
        let mut d = m[(j, j)];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if !(d > 1e-14 * scale) {
            return Err(format!("pivot {j} = {d:e} (not positive definite)"));
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut s = m[(i, j)];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / d;
        }
    }
    Ok(())
}

fn finite(name: &str, m: MatRef<'_, f64>) -> Result<(), String> {
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            if !m[(i, j)].is_finite() {
                return Err(format!("accepted-bad: {name}[{i}, {j}] = {}", m[(i, j)]));
            }
        }
    }
    Ok(())
}

/// The documented ranges of an accepted scenario, checked independently of the parser.
fn invariants(resolved: &ResolvedScenario) -> Result<(), String> {
    let sc = resolved.scenario();
    let plant = &sc.plant;
    finite("plant.a", plant.a())?;
    finite("plant.b", plant.b())?;
    finite("plant.c", plant.c())?;
    finite("plant.e", plant.e())?;
    finite("plant.f", plant.f())?;
    if let Some(m) = &sc.mhe {
        if !(0.0..1.0).contains(&m.eta()) {
            return Err(format!("accepted-bad: mhe.eta = {}", m.eta()));
        }
        if m.horizon() == 0 || m.iterations().get() == 0 {
            return Err(format!(
                "accepted-bad: mhe.horizon = {}, mhe.iterations = {}",
                m.horizon(),
                m.iterations()
            ));
        }
        spd(m.q().as_ref()).map_err(|e| format!("accepted-bad: mhe.q: {e}"))?;
        spd(m.r().as_ref()).map_err(|e| format!("accepted-bad: mhe.r: {e}"))?;
        if let Some(p) = m.p() {
            spd(p.as_ref()).map_err(|e| format!("accepted-bad: mhe.p: {e}"))?;
        }
    }
    if let Some(c) = &sc.mpc {
        if c.horizon() == 0 {
            return Err("accepted-bad: mpc.horizon = 0".into());
        }
        spd(c.r().as_ref()).map_err(|e| format!("accepted-bad: mpc.r: {e}"))?;
        finite("mpc.q", c.q().as_ref())?;
    }
    Ok(())
}

/// "infeasible" never beside a smallest feasible η at or below the user's.
fn lmi_wording(resolved: &ResolvedScenario) -> Result<(), String> {
    let (Some(Err(e)), Some(m)) = (resolved.ioss(), &resolved.scenario().mhe) else {
        return Ok(());
    };
    let msg = chain(e);
    if let Some(rest) = msg.split("smallest feasible η ≈ ").nth(1) {
        let num: String = rest
            .chars()
            .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | '-'))
            .collect();
        if let Ok(v) = num.trim_end_matches('.').parse::<f64>() {
            if v <= m.eta() {
                return Err(format!(
                    "dishonest: LMI (2) refused at η = {} with a smallest feasible η ≈ {v}: {msg}",
                    m.eta()
                ));
            }
        }
    }
    Ok(())
}

/// LMI (2) with q and r scaled together by a factor of [`UNITS`] (P scales with them): the
/// same verdict.
fn units(b: &Base, resolved: &ResolvedScenario, i: usize) -> Result<(), String> {
    let factor = UNITS[i % UNITS.len()];
    let q0 = b.mhe_q.unwrap_or(1.0);
    let with = |f: f64| -> Result<Option<bool>, String> {
        let mut t = scenario_table(b);
        let mhe = t
            .get_mut("mhe")
            .and_then(Value::as_table_mut)
            .ok_or("no [mhe] in a valid case")?;
        mhe.insert("q".into(), Value::Float(q0 * f));
        mhe.insert("r".into(), Value::Float(f));
        let refused = |e: String| format!("refused with q, r × {f:e}: {e}");
        let r = Scenario::from_toml_str(&to_text(&t))
            .map_err(|e| refused(chain(&e)))?
            .resolve()
            .map_err(|e| refused(chain(&e)))?;
        Ok(r.ioss().map(Result::is_ok))
    };
    let base = resolved.ioss().map(Result::is_ok);
    let explicit = with(1.0)?;
    let scaled = with(factor)?;
    if explicit != base || scaled != explicit {
        return Err(format!(
            "dishonest: LMI (2) feasible = {base:?} as written, {explicit:?} with q, r explicit, \
             {scaled:?} with q and r × {factor:e} (the units of q and r decide nothing)"
        ));
    }
    Ok(())
}
