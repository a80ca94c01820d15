//! The random-plant sweep: per plant the typed outcome of the eight methods, and on every
//! certified pair the independent check, random runs, the optimised adversary and a long
//! run at K_glob; the teeth at K = 1 where ρ_lin(1) ≥ 1.

use std::collections::BTreeMap;
use std::time::Instant;

use closed_loop::scenario::{ResolvedScenario, Scenario};
use faer::Par;
use iss_certificate::lure::global::{GlobalCertificate, GlobalLoop, GlobalOptions, global_loop};
use iss_certificate::lure::global_outcome::{GlobalOutcome, GlobalSettings, global_outcomes};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::plants::{Class, Inputs, RandomPlant, random_plant_within};
use super::{Budget, Checked, METHODS, RunStats, adversary, independent_margin, options};

/// The sweep's budgets.
#[derive(Debug, Clone, Copy)]
pub struct SweepConfig {
    /// K scanned up to (beyond: the typed `PhiBallBinds`).
    pub k_max: usize,
    /// The φ* searches' budget per plant (beyond: the typed `NotComputed`).
    pub phase_seconds: f64,
    /// Multipliers per τ (`GlobalOptions::tau_points`; `certify` uses 5).
    pub tau_points: usize,
    /// φ*'s relative bisection tolerance (`certify` uses 0.02): coarser only lowers φ*.
    pub phi_tol: f64,
    /// Random admissible runs per certified pair.
    pub random_runs: usize,
    /// Steps after the window fills, for random runs and the adversary.
    pub steps_after: usize,
    /// The adversary per certified pair.
    pub adversary: Budget,
    /// Steps of the long run (the lim-sup gains) per certified pair.
    pub long_steps: usize,
    /// The adversary at K = 1 where ρ_lin(1) ≥ 1 (once per plant).
    pub teeth: Budget,
    /// dim X of the plants at most (`plants::random_plant_within`).
    pub max_dim: usize,
}

impl SweepConfig {
    /// The ≥ 1 000-plant run's budgets.
    pub fn full() -> Self {
        Self {
            k_max: 5_000,
            phase_seconds: 60.0,
            tau_points: 3,
            phi_tol: 0.1,
            random_runs: 2,
            steps_after: 20,
            adversary: Budget {
                restarts: 2,
                moves: 10,
                horizon: 20,
            },
            long_steps: 150,
            max_dim: 64,
            teeth: Budget {
                restarts: 4,
                moves: 15,
                horizon: 40,
            },
        }
    }
    /// The CI-sized run's.
    pub fn small() -> Self {
        Self {
            k_max: 2_000,
            phase_seconds: 10.0,
            tau_points: 3,
            phi_tol: 0.1,
            random_runs: 2,
            steps_after: 15,
            adversary: Budget {
                restarts: 2,
                moves: 6,
                horizon: 15,
            },
            long_steps: 80,
            max_dim: 28,
            teeth: Budget {
                restarts: 3,
                moves: 10,
                horizon: 30,
            },
        }
    }
}

/// What a sweep saw.
#[derive(Debug, Default)]
pub struct Sweep {
    /// Plants drawn, and those with n_x ≥ 10.
    pub plants: usize,
    /// With n_x ≥ 10.
    pub big: usize,
    /// Plants per (class, inputs).
    pub kinds: BTreeMap<(Class, Inputs), usize>,
    /// Plants the scenario check refused, per message.
    pub refused: BTreeMap<String, usize>,
    /// (plant, method) pairs per typed outcome.
    pub outcomes: BTreeMap<String, usize>,
    /// Certified pairs per (class, inputs).
    pub certified: BTreeMap<(Class, Inputs), usize>,
    /// Certificates re-checked independently, and the smallest margin.
    pub checks: usize,
    /// The smallest independent margin.
    pub min_margin: f64,
    /// Certified pairs attacked, closed-loop runs, worst ratios.
    pub pairs: usize,
    /// Closed-loop runs.
    pub runs: usize,
    /// The worst ratios over every certified pair.
    pub worst: RunStats,
    /// K_glob of every certified pair.
    pub k_glob: Vec<usize>,
    /// Certificates attacked at K = 1 where ρ_lin(1) ≥ 1, and those refuted there.
    pub teeth: (usize, usize),
    /// Everything that must not happen (refutations, failed checks, impossible certificates).
    pub failures: Vec<String>,
    /// Wall seconds.
    pub seconds: f64,
}

fn outcome_name(o: &GlobalOutcome) -> String {
    match o {
        GlobalOutcome::Certified(_) => "Certified".into(),
        GlobalOutcome::PhiBallBinds { .. } => "PhiBallBinds (φ(k_max) > φ*)".into(),
        GlobalOutcome::OptimumBinds { .. } => "OptimumBinds (even φ = 0 not certified)".into(),
        GlobalOutcome::LinearUnstable { .. } => "LinearUnstable (ρ_lin ≥ 1)".into(),
        GlobalOutcome::UnstableWithBoundedInput { .. } => {
            "UnstableWithBoundedInput (A unstable, 𝒰 bounded)".into()
        }
        GlobalOutcome::SearchFailed { .. } => "SearchFailed".into(),
        GlobalOutcome::NotComputed { .. } => "NotComputed (budget)".into(),
        GlobalOutcome::Unsupported { reason } => format!("Unsupported: {reason}"),
        other => format!("other: {other}"),
    }
}

impl Sweep {
    /// Runs the sweep over `seeds`.
    pub fn run(seeds: std::ops::Range<u64>, cfg: &SweepConfig) -> Self {
        Self::run_for(seeds, cfg, f64::INFINITY)
    }

    /// As [`Sweep::run`], drawing no new plant after `seconds` of wall time (the table then
    /// says how many plants were run).
    pub fn run_for(seeds: std::ops::Range<u64>, cfg: &SweepConfig, seconds: f64) -> Self {
        let t0 = Instant::now();
        let mut s = Sweep {
            min_margin: f64::INFINITY,
            ..Sweep::default()
        };
        for seed in seeds {
            if t0.elapsed().as_secs_f64() > seconds {
                break;
            }
            let nf = s.failures.len();
            s.plant(random_plant_within(seed, cfg.max_dim), cfg);
            for f in &s.failures[nf..] {
                eprintln!("FAILURE {f}");
            }
            if s.plants % 10 == 0 {
                s.seconds = t0.elapsed().as_secs_f64();
                s.print();
            }
        }
        s.seconds = t0.elapsed().as_secs_f64();
        s
    }

    fn plant(&mut self, p: RandomPlant, cfg: &SweepConfig) {
        self.plants += 1;
        self.big += usize::from(p.nx >= 10);
        *self.kinds.entry((p.class, p.inputs)).or_default() += 1;
        let r = match Scenario::from_toml_str(&p.toml)
            .map_err(|e| e.to_string())
            .and_then(|s| s.resolve().map_err(|e| e.to_string()))
        {
            Ok(r) => r,
            Err(e) => {
                let msg: String = e.chars().take(90).collect();
                *self.refused.entry(msg).or_default() += 1;
                return;
            }
        };
        let settings = GlobalSettings {
            search: GlobalOptions {
                tau_points: cfg.tau_points,
                phi_tol: cfg.phi_tol,
                k_max: cfg.k_max,
                ..GlobalOptions::default()
            },
            phase_seconds: cfg.phase_seconds,
        };
        let opts: Vec<_> = METHODS.iter().map(|&m| options(&r, m)).collect();
        let t0 = Instant::now();
        let out = global_outcomes(&r, &opts, &settings);
        let t_search = t0.elapsed().as_secs_f64();
        let runs0 = self.runs;
        for o in &out {
            *self.outcomes.entry(outcome_name(o)).or_default() += 1;
        }
        let impossible = p.inputs == Inputs::Boxed && p.class != Class::Stable;
        // One certificate per norm (plain: methods 0–3, Jacobi: 4–7): the LMI sees the
        // method only through the norm of φ.
        let mut teeth_done = false;
        for norm in [0..4, 4..8] {
            let certified: Vec<(usize, usize, f64)> = norm
                .filter_map(|i| match &out[i] {
                    GlobalOutcome::Certified(k) => Some((i, k.k_glob, k.phi_star)),
                    _ => None,
                })
                .collect();
            let Some(&(first, _, phi_star)) = certified.first() else {
                continue;
            };
            if impossible {
                self.failures.push(format!(
                    "seed {}: a {:?} plant with every input boxed certified ({})",
                    p.seed,
                    p.class,
                    METHODS[first].name()
                ));
            }
            *self.certified.entry((p.class, p.inputs)).or_default() += certified.len();
            let gl = global_loop(&r, &opts[first]).expect("a certified loop builds");
            let Some(c) = gl.certify_phi(phi_star, &settings.search) else {
                self.failures.push(format!(
                    "seed {}: φ* = {phi_star:e} does not re-certify",
                    p.seed
                ));
                continue;
            };
            self.check(&p, &r, &gl, &c);
            let mut rng = ChaCha8Rng::seed_from_u64(p.seed ^ 0xad5e);
            for &(i, k, _) in &certified {
                self.attack(&p, &r, (i, k), Checked { gl: &gl, c: &c }, cfg, &mut rng);
            }
            if !teeth_done && certified[0].1 > 1 {
                teeth_done = self.teeth(&r, first, Checked { gl: &gl, c: &c }, cfg, &mut rng);
            }
        }
        if std::env::var_os("SOUND_VERBOSE").is_some() {
            eprintln!(
                "seed {} n_x {} M {} {:?}/{:?}: search {t_search:.1} s, then {:.1} s, {} runs; {}",
                p.seed,
                p.nx,
                p.horizon,
                p.class,
                p.inputs,
                t0.elapsed().as_secs_f64() - t_search,
                self.runs - runs0,
                outcome_name(&out[0])
            );
        }
    }

    fn check(
        &mut self,
        p: &RandomPlant,
        r: &ResolvedScenario,
        gl: &GlobalLoop,
        c: &GlobalCertificate,
    ) {
        self.checks += 1;
        match independent_margin(gl, c, r.scenario().plant.nw()) {
            Ok(m) => self.min_margin = self.min_margin.min(m),
            Err(e) => self
                .failures
                .push(format!("seed {}: independent check: {e}", p.seed)),
        }
    }

    /// Random runs, the adversary and a long run at K_glob of method `i`.
    fn attack(
        &mut self,
        p: &RandomPlant,
        r: &ResolvedScenario,
        (i, k): (usize, usize),
        ck: Checked<'_>,
        cfg: &SweepConfig,
        rng: &mut ChaCha8Rng,
    ) {
        self.pairs += 1;
        self.k_glob.push(k);
        let mut o = options(r, METHODS[i]);
        o = o.with_iterations(k).expect("K is in range");
        let a = super::random_runs(r, &o, ck, cfg.random_runs, cfg.steps_after, rng);
        let (b, n) = adversary(r, &o, ck, cfg.adversary, rng);
        let (lo, hi) = super::w_box(r);
        let nw = lo.len();
        let nx = p.nx;
        let steps = ck.gl.lifted.layout().horizon + cfg.long_steps;
        let w: Vec<f64> = (0..steps * nw)
            .map(|j| {
                if rng.random_bool(0.5) {
                    hi[j % nw]
                } else {
                    lo[j % nw]
                }
            })
            .collect();
        let x0: Vec<f64> = (0..nx).map(|_| rng.random_range(-1.0..1.0)).collect();
        let c = super::run(r, &o, ck, &x0, &vec![0.0; nx], &w, steps);
        self.runs += cfg.random_runs + n + 1;
        for st in [a, b, c] {
            if st.worst() > 1.0 {
                self.failures.push(format!(
                    "REFUTED: seed {} {} K_glob = {k}: {st:?}",
                    p.seed,
                    METHODS[i].name()
                ));
            }
            self.worst.one_step = self.worst.one_step.max(st.one_step);
            self.worst.multi = self.worst.multi.max(st.multi);
            self.worst.gain = self.worst.gain.max(st.gain);
        }
    }

    /// The adversary at K = 1 (outside the certified K) where ρ_lin(1) ≥ 1: a refutation
    /// there shows the checks have teeth. Returns whether it was tried.
    fn teeth(
        &mut self,
        r: &ResolvedScenario,
        i: usize,
        ck: Checked<'_>,
        cfg: &SweepConfig,
        rng: &mut ChaCha8Rng,
    ) -> bool {
        match ck.gl.lifted.spectral_radius(1, Par::Seq) {
            Ok(rho) if rho >= 1.0 => {}
            _ => return false,
        }
        let mut o = options(r, METHODS[i]);
        o = o.with_iterations(1).expect("K is in range");
        let (st, n) = adversary(r, &o, ck, cfg.teeth, rng);
        self.runs += n;
        self.teeth.0 += 1;
        self.teeth.1 += usize::from(st.worst() > 1.0);
        true
    }

    /// The outcome table.
    pub fn print(&self) {
        eprintln!(
            "{} plants ({} with n_x ≥ 10) in {:.0} s",
            self.plants, self.big, self.seconds
        );
        eprintln!("| class | inputs | plants | certified (plant, method) pairs |");
        for (k, n) in &self.kinds {
            let c = self.certified.get(k).copied().unwrap_or(0);
            eprintln!("| {:?} | {:?} | {n} | {c} |", k.0, k.1);
        }
        eprintln!("| scenario refused | plants |");
        for (k, n) in &self.refused {
            eprintln!("| {k} | {n} |");
        }
        eprintln!("| outcome of (plant, method) | pairs |");
        for (k, n) in &self.outcomes {
            eprintln!("| {k} | {n} |");
        }
        let mut ks = self.k_glob.clone();
        ks.sort_unstable();
        let med = ks.get(ks.len() / 2).copied().unwrap_or(0);
        eprintln!(
            "{} certificates re-checked independently (smallest margin {:.2e}); {} certified \
             pairs attacked ({} runs; K_glob median {med}, max {}): worst one-step {:.4}, \
             multi-step {:.4}, gain {:.4}; teeth at K = 1 (ρ_lin(1) ≥ 1): {} of {} refuted",
            self.checks,
            self.min_margin,
            self.pairs,
            self.runs,
            ks.last().copied().unwrap_or(0),
            self.worst.one_step,
            self.worst.multi,
            self.worst.gain,
            self.teeth.1,
            self.teeth.0
        );
        for f in &self.failures {
            eprintln!("{f}");
        }
    }

    /// No refutation, every check passed, certificates only where one can exist.
    pub fn assert_sound(&self) {
        assert!(
            self.failures.is_empty(),
            "{} failures: {:?}",
            self.failures.len(),
            self.failures
        );
        assert!(
            self.pairs > 0,
            "no certified pair: the sweep tested nothing"
        );
        assert!(
            self.teeth.0 == 0 || self.teeth.1 > 0,
            "the adversary never refuted at K = 1"
        );
    }
}
