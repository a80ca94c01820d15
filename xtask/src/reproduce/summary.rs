//! The text summary of a reproduce job and its verdict.

use super::numfmt::{num, opt, rate};
use super::*;
use iss_certificate::outcome::VoidReason;

fn fmt_opt(v: Option<usize>) -> String {
    v.map_or_else(|| "none".to_string(), |k| k.to_string())
}

fn status(holds: bool) -> &'static str {
    if holds { "pass" } else { "FAIL" }
}

/// One sentence: what the certificate says about the simulated solver and whether the
/// simulation agrees.
pub(super) fn verdict(d: &CertificateDocument) -> String {
    let runs: Vec<RunOutcome<'_>> = d
        .runs
        .iter()
        .map(|r| RunOutcome::new(r.k, r.completed, r.error.as_deref(), r.divergence))
        .collect();
    let lead = iss_certificate::plan::divergence_lead(&runs);
    if let Some(r) = &d.not_covered {
        return format!(
            "{lead}NOT CERTIFIED: {r}. The constants and K_min are reported for reference \
             only; no certificate covers this configuration."
        );
    }
    if let Some(j) = &d.joint {
        let c = &j.certificate;
        return lead
            + &match (c.region.cheapest, d.trajectory_check.passed) {
                (Some(p), passed) => format!(
                    "the joint certificate (ρ(Γ) < 1 over plant, ε, e, δ) certifies ISS of the loop with \
                 MHE {} at K_e and MPC {} at K_c for every pair on or above the staircase through \
                 ({}, {}) (the cheapest); {}.",
                    c.mhe_method,
                    c.mpc_method,
                    p.k_e,
                    p.k_c,
                    match passed {
                        Some(true) =>
                            "every inequality of the proof holds at every step of the run there",
                        Some(false) =>
                            "the run there VIOLATES an inequality of the proof (see above)",
                        None => "the trajectory check did not run",
                    }
                ),
                (None, _) => format!(
                    "the joint certificate is void: {}",
                    VoidReason::join(&c.region.void_reasons)
                ),
            };
    }
    // The global loop certificate or the iteration chain decides where Theorem 1 does not
    // (the one verdict, `at_scenario`, of `iss_certificate::coverage`).
    if let Some(line) = global_verdict(d) {
        return lead + &line;
    }
    let own = d
        .certificate
        .solvers
        .iter()
        .find(|s| s.solver.name() == d.solver);
    let theorem1 = iss_certificate::plan::verdict(own, d.trajectory_check.passed, &runs);
    match lower_floor(d, own.and_then(|s| s.k_min), "Theorem 1's K_min") {
        Some(floor) => format!("{theorem1} {floor}"),
        None => theorem1,
    }
}

/// The sentence naming the smallest certified K of the scenario's method when another
/// certificate sets it below the floor the verdict's first sentence quotes (`quoted`: Theorem
/// 1's K_min or K_glob, named `name`; None otherwise): the verdict's floor is
/// `at_scenario.k_min`, the one of `iss_certificate::coverage::with_global`.
fn lower_floor(d: &CertificateDocument, quoted: Option<usize>, name: &str) -> Option<String> {
    let floor = d.at_scenario.k_min?;
    if quoted.is_some_and(|k| k <= floor) {
        return None;
    }
    let sv = d.solvers.iter().find(|s| s.solver.name() == d.solver)?;
    let by = if sv.k_glob == Some(floor) {
        format!(
            "the global loop certificate (Theorem L3, docs/theory.md §4) certifies every K ≥ \
             K_glob = {floor}"
        )
    } else if sv.k_chain == Some(floor) {
        format!(
            "the iteration chain ({}) certified K = {floor} (that K only: the chain is not \
             monotone in K)",
            iss_certificate::lure::chain_outcome::theorem(sv.solver)
        )
    } else {
        format!("{} certifies it", d.at_scenario.certificate?.title())
    };
    let relative = match quoted {
        Some(k) => format!("below {name} = {k}"),
        None => format!("where {name} is none"),
    };
    Some(format!(
        "The smallest certified K for {} is {floor}, {relative}: {by}.",
        d.solver
    ))
}

/// The verdict's sentence where the global loop certificate or the iteration chain decides
/// at the scenario's K (None: Theorem 1 or nothing).
fn global_verdict(d: &CertificateDocument) -> Option<String> {
    use iss_certificate::coverage::CertificateKind;
    let kind = d.at_scenario.certificate?;
    if kind != CertificateKind::Global && kind != CertificateKind::Chain {
        return None;
    }
    let k = d.scenario_iterations;
    let sv = d.solvers.iter().find(|s| s.solver.name() == d.solver);
    let kg = fmt_opt(sv.and_then(|s| s.k_glob));
    let floor = fmt_opt(d.at_scenario.k_min);
    let yes = d.at_scenario.certified.is_certified();
    Some(match (kind, yes) {
        (CertificateKind::Chain, true) => format!(
            "the iteration chain ({}, docs/theory.md §4b, §4c) certifies ISS of the loop \
             with {} at the scenario's K = {k} (checked at this K; Theorem L3 needs K ≥ \
             K_glob = {kg}); Theorem 1 does not cover it (K_min above).",
            sv.map_or("Theorem L3b", |s| {
                iss_certificate::lure::chain_outcome::theorem(s.solver)
            }),
            d.solver
        ),
        (CertificateKind::Global, true) => {
            let floor = lower_floor(d, sv.and_then(|s| s.k_glob), "K_glob")
                .map_or_else(String::new, |f| format!(" {f}"));
            format!(
                "the global loop certificate (Theorem L3, docs/theory.md §4) certifies ISS of \
                 the loop with {} at the scenario's K = {k} (every K ≥ K_glob = {kg}); \
                 Theorem 1 does not cover it (K_min above).{floor}",
                d.solver
            )
        }
        // The chain's floor holds at that K alone (its certified set is not monotone).
        (CertificateKind::Chain, false) => format!(
            "NOT CERTIFIED at the scenario's K = {k}: the smallest certified K is {floor} \
             ({}, at that K only; {}).",
            kind.title(),
            match sv.and_then(|s| s.k_glob) {
                Some(g) => format!("every K ≥ K_glob = {g} by Theorem L3"),
                None => "Theorem L3 gives no K_glob".to_string(),
            }
        ),
        _ => format!(
            "NOT CERTIFIED at the scenario's K = {k}: the smallest certified K is {floor} \
             ({}; K_glob = {kg}).",
            kind.title()
        ),
    })
}

/// ", N step(s) within the rounding floor (≤ …)" when the floor was needed (empty otherwise).
fn floor_note(c: &TrajectoryCheck) -> String {
    let n = c.prop1.within_rounding_floor + c.prop3.within_rounding_floor;
    if n == 0 {
        return String::new();
    }
    format!(
        "; {n} step(s) within the rounding floor (≤ {}: the measured side is rounding there, \
         docs/reproduce-output.md)",
        num(c.prop1.max_rounding_floor.max(c.prop3.max_rounding_floor))
    )
}

/// The text summary of one job: the sections in order, then the verdict and the files.
pub(super) fn summarize(d: &CertificateDocument, files: &[PathBuf], notes: &[String]) -> String {
    let mut s = String::new();
    header(&mut s, d);
    premises(&mut s, d);
    smallest_k(&mut s, d);
    s.push_str(&super::gains::methods_section(&d.asymptotic_gains));
    constants(&mut s, d);
    closed_loop(&mut s, d);
    linear(&mut s, d);
    s.push_str(&super::regional::summary(&d.regional));
    trajectory(&mut s, d);
    if let Some(j) = &d.joint {
        s.push_str(&super::joint::summary(j));
    }
    let _ = writeln!(s, "\nVerdict: {}", verdict(d));
    let _ = writeln!(s, "\nFiles");
    for f in files {
        let _ = writeln!(s, "  {}", f.display());
    }
    for n in notes {
        let _ = writeln!(s, "  note: {n}");
    }
    s
}

/// The title, the stand-in note of the presets, M, η and ρ, and a failed LMI (2).
fn header(s: &mut String, d: &CertificateDocument) {
    let c = &d.certificate;
    let _ = writeln!(
        s,
        "== reproduce `{}`: scenario `{}` ({}) ==",
        d.label, d.scenario.name, d.scenario.path
    );
    if d.preset.is_some() {
        let _ = writeln!(
            s,
            "Stand-in plant: A, B are a common 4-state benchmark (the paper does not print its A, B);\n\
             C, the sets, the noise, the MHE/MPC settings, x₀ and the prior are the paper's."
        );
    }
    let _ = writeln!(
        s,
        "M = {}, η = {}: 6·η^M = {}, ρ = 6^(1/M)·η = {}",
        c.horizon,
        num(c.eta),
        num(6.0 * c.eta.powi(i32::try_from(c.horizon).unwrap_or(i32::MAX))),
        num(c.rho)
    );
    if let Some(f) = &c.ioss_failure {
        let _ = writeln!(s, "δ-IOSS (LMI (2)) FAILS: {f}");
    }
}

/// Theorem 1's premises: scenario-wide ones once, solver-specific ones per solver.
fn premises(s: &mut String, d: &CertificateDocument) {
    let _ = writeln!(s, "\nPremises of Theorem 1");
    let _ = writeln!(
        s,
        "  {:<20} {:<14} {:>12} {:>12}  status",
        "premise", "solver", "value", "margin"
    );
    if let Some(first) = d.solvers.first() {
        for (i, p) in first.premises.iter().enumerate() {
            let same = d.solvers.iter().all(|o| {
                o.premises
                    .get(i)
                    .is_some_and(|q| q.holds == p.holds && q.value.to_bits() == p.value.to_bits())
            });
            let rows: Vec<(std::borrow::Cow<'_, str>, &Premise)> = if same {
                vec![("all".into(), p)]
            } else {
                d.solvers
                    .iter()
                    .filter_map(|o| o.premises.get(i).map(|q| (o.solver.name(), q)))
                    .collect()
            };
            for (who, q) in rows {
                let _ = writeln!(
                    s,
                    "  {:<20} {:<14} {:>12} {:>12}  {}",
                    q.name,
                    who,
                    num(q.value),
                    num(q.margin.unwrap_or(f64::NAN)),
                    if q.not_evaluated.is_some() {
                        "not evaluated"
                    } else {
                        status(q.holds)
                    }
                );
                match &q.not_evaluated {
                    Some(why) => {
                        let _ = writeln!(s, "      because {why}");
                    }
                    None if !q.holds => {
                        let fix = q.fix.as_ref().map(ToString::to_string);
                        let _ = writeln!(s, "      fix: {}", fix.unwrap_or_default());
                    }
                    None => {}
                }
            }
        }
    }
}

/// K_min per solver (or why there is none), the embedded budget, the scenario's K.
fn smallest_k(s: &mut String, d: &CertificateDocument) {
    let _ = writeln!(
        s,
        "\nSmallest certified K (Theorem 1 with sum-form small gain: sg1 + sg2 + sg3 < 1)"
    );
    for sv in &d.solvers {
        let mark = if sv.simulated { " (simulated)" } else { "" };
        match sv.k_min {
            Some(k) => {
                let _ = writeln!(
                    s,
                    "  {:<14} K_min = {k:<6} φ(K) = {}·{}^K, margin 1 − Σsg = {}; with sampled L_Φ: {}{mark}",
                    sv.solver.name(),
                    num(sv.phi_prefactor),
                    rate(sv.phi_rate),
                    opt(sv.margin_at_k_min),
                    fmt_opt(sv.k_min_with_sampled_l_phi)
                );
            }
            // Cut by the analysis budget: not void (the sentence names the key and value).
            None if sv.not_computed.is_some() => {
                let nc = sv
                    .not_computed
                    .as_ref()
                    .map_or_else(String::new, ToString::to_string);
                let _ = writeln!(s, "  {:<14} {nc}{mark}", sv.solver.name());
            }
            None => {
                // The fixes are printed with the premises above; here the names only.
                let failed: Vec<&str> = sv
                    .premises
                    .iter()
                    .filter(|p| !p.holds)
                    .map(|p| p.name.as_str())
                    .collect();
                let why = if failed.is_empty() {
                    VoidReason::join(&sv.void_reasons)
                } else {
                    format!("{} fails (see the fix above)", failed.join(", "))
                };
                let _ = writeln!(s, "  {:<14} void: {why}{mark}", sv.solver.name());
            }
        }
    }
    if let Some(b) = &d.budget {
        s.push_str(&b.block());
    }
    if let Some(false) = d.scenario_iterations_match_k_min {
        let _ = writeln!(
            s,
            "  note: the scenario's mhe.iterations = {} differs from the computed K_min; the runs use K_min",
            d.scenario_iterations
        );
    }
}

/// The constants next to the paper's published values (presets), or this scenario's.
fn constants(s: &mut String, d: &CertificateDocument) {
    let preset = !d.paper_comparison.is_empty();
    if preset {
        let _ = writeln!(
            s,
            "\nConstants: ours are for the STAND-IN plant; the paper's are for ITS OWN plant (not printed),\n\
             so the two columns are not expected to agree."
        );
        let _ = writeln!(
            s,
            "  {:<16} {:<48} paper (published)",
            "quantity", "ours (stand-in)"
        );
        for row in &d.paper_comparison {
            let _ = writeln!(s, "  {:<16} {:<48} {}", row.quantity, row.ours, row.paper);
        }
    } else if let Some(own) = d
        .certificate
        .solvers
        .iter()
        .find(|c| c.solver.name() == d.solver)
    {
        let _ = writeln!(s, "\nConstants of this scenario");
        for row in comparison(&d.certificate, own.solver) {
            let _ = writeln!(s, "  {:<16} {}", row.quantity, row.ours);
        }
    }
}

/// The simulations: one row per run with its notes, then the runs not simulated.
fn closed_loop(s: &mut String, d: &CertificateDocument) {
    let controller = if d.joint.is_some() {
        "K-iteration MPC (K_c per row)"
    } else {
        "exact MPC"
    };
    // Seed and T only of runs that happened (nothing simulated: no "seed 0, T = 0").
    match d.runs.first() {
        Some(first) => {
            let _ = writeln!(
                s,
                "\nClosed loop (Alg. 1, {} MHE, {controller}, seed {}, T = {})",
                d.solver, first.seed, first.steps
            );
            let _ = writeln!(
                s,
                "  {:<8} {:<10} {:>10} {:>10} {:>12} {:>12} {:>12}",
                "K", "why", "sup‖e‖", "sup‖x‖", "tail ‖e‖", "tail ‖x‖", "tail ε_t"
            );
        }
        None => {
            let _ = writeln!(s, "\nClosed loop (Alg. 1, {} MHE, {controller})", d.solver);
        }
    }
    for (i, r) in d.runs.iter().enumerate() {
        run_row(s, d, i, r);
    }
    for r in &d.skipped_runs {
        let _ = writeln!(s, "  {:<8} not simulated: {}", r.k, r.reason);
    }
    if d.runs.is_empty() && d.skipped_runs.is_empty() {
        let _ = writeln!(s, "  not simulated: the MHE needs a P and LMI (2) has none");
    }
}

/// One run's row and the lines under it (MPC fallbacks, a stop, a divergence, the Kalman
/// baseline, the gains, draws outside 𝒲).
fn run_row(s: &mut String, d: &CertificateDocument, i: usize, r: &RunSummary) {
    let why = match (r.k_source, d.joint.is_some()) {
        // The joint certificate's K_min is its cheapest pair.
        (KSource::ComputedKMin, true) => "cheapest",
        (source, _) => source.label(),
    };
    let _ = writeln!(
        s,
        "  {:<8} {:<10} {:>10} {:>10} {:>12} {:>12} {:>12}",
        r.k,
        why,
        num(r.sup_norm_e),
        num(r.sup_norm_x),
        opt(r.tail_mean_e),
        opt(r.tail_mean_x),
        opt(r.tail_mean_epsilon)
    );
    if d.joint.is_some() {
        let _ = writeln!(s, "      {}", r.controller);
    }
    if r.mpc_infeasible_steps > 0 {
        let _ = writeln!(
            s,
            "      the MPC was infeasible at {} of {} steps (state constraints) and applied its fallback",
            r.mpc_infeasible_steps, r.completed
        );
    }
    if let Some(e) = &r.error {
        let _ = writeln!(s, "      stopped after {} steps: {e}", r.completed);
    }
    if let Some(d) = r.divergence.filter(|_| r.error.is_none()) {
        let _ = writeln!(s, "      the MHE run DIVERGED: {d}");
    }
    if let Some(kf) = &r.kalman {
        let _ = writeln!(s, "      {}", kalman_line(kf, r.steps));
    }
    if let Some(g) = d.asymptotic_gains.runs.get(i) {
        let _ = writeln!(s, "      {}", super::gains::run_line(g));
    }
    if let Some(first) = r.w_outside_first {
        let _ = writeln!(
            s,
            "      w_t ∉ 𝒲 at {} of {} steps (first t = {first}): the certificate assumes w_t ∈ 𝒲 \
             (sets.disturbance), so its ISS bound is not claimed from t = {first} on",
            r.w_outside, r.completed
        );
    }
}

/// K_lin per method (the linear stability boundary).
fn linear(s: &mut String, d: &CertificateDocument) {
    if !d.linear.is_empty() {
        let _ = writeln!(
            s,
            "\nLinear stability boundary (no constraint active, exact MPC): K_lin = smallest K from\n\
             which ρ_lin(K) < 1 on the grid (necessary for local asymptotic stability of the origin when no\n\
             constraint is active there; not sufficient; a saturated loop can stay bounded at K < K_lin)"
        );
        for l in &d.linear {
            let line = match (&l.report, &l.error) {
                (Some(r), _) => format!(
                    "K_lin = {}{}",
                    r.k_lin
                        .map_or_else(|| "none on the grid".into(), |k| k.to_string()),
                    if r.unstable_ks.is_empty() {
                        String::new()
                    } else {
                        format!("; ρ_lin ≥ 1 at K = {:?}", r.unstable_ks)
                    }
                ),
                (None, Some(e)) => format!("not applicable: {e}"),
                (None, None) => "not computed".into(),
            };
            let _ = writeln!(s, "  {:<14} {line}", l.solver);
        }
    }
}

/// The trajectory check of Props. 1 and 3 on the K_min run, or why it did not run.
fn trajectory(s: &mut String, d: &CertificateDocument) {
    let tc = &d.trajectory_check;
    let _ = writeln!(
        s,
        "\nTrajectory check of Props. 1 (ε_t) and 3 (e_t), both sides from the trace"
    );
    if tc.ran {
        let line = |name: &str, c: &Option<TrajectoryCheck>| -> String {
            match c {
                Some(c) => {
                    format!(
                        "  {name:<16} Prop. 1: {} (max lhs/rhs {} at t = {}), Prop. 3: {} (max lhs/rhs {} at t = {})",
                        if c.prop1.holds {
                            "holds at every t"
                        } else {
                            "VIOLATED"
                        },
                        num(c.prop1.worst_ratio),
                        c.prop1.worst_t,
                        if c.prop3.holds {
                            "holds at every t"
                        } else {
                            "VIOLATED"
                        },
                        num(c.prop3.worst_ratio),
                        c.prop3.worst_t
                    ) + &floor_note(c)
                }
                None => format!("  {name:<16} not evaluated"),
            }
        };
        let _ = writeln!(
            s,
            "  {} at K = {}, seed {}, {} steps",
            tc.solver,
            tc.k.unwrap_or(0),
            tc.seed,
            tc.steps
        );
        let _ = writeln!(s, "{}", line("certified L_Φ", &tc.certified_l_phi));
        let _ = writeln!(s, "{}", line("sampled L_Φ", &tc.sampled_l_phi));
    } else {
        let _ = writeln!(
            s,
            "  not run: {}",
            tc.reason.as_deref().unwrap_or("no reason recorded")
        );
    }
}

/// The Kalman baseline's line under a run of `steps` planned steps: its error statistics, or
/// that it diverged. A filter that ran fewer steps (the MHE run stopped early) has no tail:
/// the line says where it stopped instead of printing a tail mean (issue 37 item 9).
pub(super) fn kalman_line(kf: &KalmanSummary, steps: usize) -> String {
    let head = "Kalman filter of the same weights on the same draws:";
    match (&kf.divergence, &kf.error) {
        (_, Some(e)) if kf.completed == 0 => format!("{head} {e}"),
        (Some(d), _) => format!(
            "{head} DIVERGED ({d}) after {} steps{}",
            kf.completed,
            kf.error
                .as_ref()
                .map_or_else(String::new, |e| format!(": {e}"))
        ),
        (None, _) if kf.completed < steps => format!(
            "{head} sup‖e‖ = {} over the {} step(s) filtered; tail ‖e‖ not available (the run \
             stopped at t = {} of {steps})",
            opt(kf.sup_norm_e),
            kf.completed,
            kf.completed
        ),
        (None, _) => format!(
            "{head} sup‖e‖ = {}, tail ‖e‖ = {}",
            opt(kf.sup_norm_e),
            opt(kf.tail_mean_e)
        ),
    }
}
