//! The certified γ₁,₃ of [`super::gamma13_certified_budgeted`] in three stages, so that a
//! caller can schedule them itself (the sweep's pool runs each as a task): the plan
//! ([`Gamma13Plan::start`]: the families, the candidate metrics and their S-procedure
//! figures, the choice of the metrics to enumerate), the free-set enumeration in
//! independent mask chunks ([`Gamma13Plan::chunk`]), and the result
//! ([`Gamma13Plan::finish`]). The chunks are fixed by 2^s, not by who runs them, and
//! their reduction is a maximum in chunk order: the certificate is the same bit for bit
//! however the chunks are run.

use crate::outcome::SkipReason;
use mpc_core::{CondensedMpc, MpcError};
use rayon::prelude::*;

use super::enumerate::{VertexChunk, VertexEnumeration};
use super::metrics::{self, Family, Metric};
use super::*;

/// What [`Gamma13Plan::start`] gives: the certificate already (void before any enumeration),
/// or the plan of the rest.
#[derive(Debug)]
pub enum Gamma13Stage<'a> {
    /// The certificate (void: 0 ∉ 𝒰, or the saturated dynamics do not contract).
    Done(Box<Gamma13Certificate>),
    /// The enumeration and the result still to compute.
    Plan(Box<Gamma13Plan<'a>>),
}

/// The γ₁,₃ certificate after its first stage (module docs).
#[derive(Debug)]
pub struct Gamma13Plan<'a> {
    mpc: &'a CondensedMpc,
    max_vars: usize,
    phase_seconds: f64,
    fam: Family,
    depth: usize,
    pattern_families: usize,
    metrics: Vec<Metric>,
    candidates: Vec<MetricResult>,
    noise_gains: Vec<f64>,
    gamma13_polynomial: f64,
    order: Vec<usize>,
    chosen: Vec<usize>,
    n_refs: usize,
    work: f64,
    seconds: f64,
    s: usize,
    variables: usize,
    skipped: Vec<SkippedComputation>,
    enumeration: Option<VertexEnumeration>,
}

/// The figures of one chunk of the free-set enumeration ([`Gamma13Plan::chunk`]).
pub type Gamma13Chunk = VertexChunk;

/// Folds the free-set enumeration's figures `v` into the chosen metrics' candidates (a
/// smaller γ₁,₃ replaces the family's, with its γ₁ʷ); the best enumerated γ₁,₃.
fn fold_enumerated(
    candidates: &mut [MetricResult],
    chosen: &[usize],
    v: &super::enumerate::VertexMax,
    metrics: &[Metric],
    noise_gains: &[f64],
) -> f64 {
    let mut best = f64::INFINITY;
    for (k, &i) in chosen.iter().enumerate() {
        let (lam, gin) = (v.contraction[k], v.input_gain[k]);
        let (g13, g1w) = gammas(lam, gin, &metrics[i], noise_gains[i]);
        let c = &mut candidates[i];
        c.contraction_enumerated = Some(lam);
        // The enumeration drops a metric once λ reaches 1: its g is then a partial maximum
        // (possibly 0), not a figure.
        c.input_gain_enumerated = (lam < 1.0).then_some(gin);
        c.gamma13_enumerated = Some(g13);
        if g13 < c.gamma13 {
            c.gamma13 = g13;
            c.gamma1w = g1w;
        }
        best = best.min(g13);
    }
    best
}

/// Each candidate's reason for figures not computed, and its γ₁,₄ with the λ_S its γ₁,₃
/// used (when it contracts).
fn finish_candidates(candidates: &mut [MetricResult], metrics: &[Metric]) {
    for (c, m) in candidates.iter_mut().zip(metrics) {
        c.not_computed = NoContraction::of(c);
        let lam = used_contraction(c);
        if lam < 1.0 {
            c.gamma14 = c.input_matrix_gain / (m.lmin.sqrt() * (1.0 - lam));
        }
    }
}

/// Which bound gave a candidate's γ₁,₃: the enumeration when it is no larger than the
/// family's.
fn bound_of(c: &MetricResult) -> Gamma13Method {
    if c.gamma13_enumerated
        .is_some_and(|e| e <= c.gamma13_polynomial)
    {
        Gamma13Method::Enumerated
    } else {
        Gamma13Method::Polynomial
    }
}

/// Why no metric gives a finite γ₁,₃: not computed within the budget when the enumeration
/// the budget skipped could find one, else no contracting metric (the least bad named).
fn why_void(
    candidates: &[MetricResult],
    over_budget: Option<&crate::budget::NotComputed>,
    enumerated: bool,
    depth: usize,
) -> Gamma13Void {
    let worst = |c: &MetricResult| c.contraction_enumerated.unwrap_or(c.contraction);
    let b = candidates
        .iter()
        .min_by(|x, y| worst(x).total_cmp(&worst(y)));
    let best_contraction = b.map_or(f64::INFINITY, worst);
    match over_budget {
        Some(nc) => Gamma13Void::NotComputedWithinBudget {
            best_contraction,
            not_computed: nc.clone(),
        },
        None => Gamma13Void::NoContractingMetric {
            best_contraction,
            metric: b.map_or_else(|| "none".into(), |c| c.metric.clone()),
            enumerated,
            pattern_blocks: depth,
        },
    }
}

/// Why γ₁,₃ cannot exist with saturable inputs (s > 0): the saturated dynamics are not
/// stable. Stable / marginal / unstable from the exact structure (a defective A, e.g.
/// integrator chains, has rounded eigenvalues off the unit circle). With 𝒰 bounded A_sat = A
/// exactly (K_sat = K_lin + GR vanishes; its computed value is rounding, which a Jordan chain
/// of length 3 amplifies to 1e-5 in |λ|), so A itself is classified; otherwise A_sat as
/// computed.
fn saturated_dynamics_void(
    mpc: &CondensedMpc,
    fam: &Family,
) -> Result<Option<Gamma13Void>, MpcError> {
    if fam.saturable == 0 {
        return Ok(None);
    }
    let us = mpc.input_set();
    let bounded = us.lower().iter().chain(us.upper()).all(|b| b.is_finite());
    let facts = if bounded {
        lti_model::spectral::classify(mpc.system().a())?
    } else {
        lti_model::spectral::classify(fam.a_sat.as_ref())?
    };
    let rho = facts.spectral_radius;
    let marginal = match facts.stability {
        Stability::Unstable => Some(false),
        Stability::Marginal => Some(true),
        Stability::Stable if !(rho < 1.0 - 1e-10) => Some(true),
        Stability::Stable => None,
    };
    Ok(
        marginal.map(|marginal| Gamma13Void::SaturatedDynamicsNotStable {
            spectral_radius: rho,
            input_bounded: bounded,
            marginal,
        }),
    )
}

/// A metric's candidate from its family figures λ_S, g_S and ‖S^{½}E‖₂ (`noise_gain`): the
/// enumerated figures and γ₁,₄ come later.
fn family_candidate(
    mpc: &CondensedMpc,
    m: &Metric,
    lam: f64,
    gin: f64,
    noise_gain: f64,
) -> MetricResult {
    let (g13, g1w) = gammas(lam, gin, m, noise_gain);
    MetricResult {
        metric: m.name.clone(),
        contraction: lam,
        input_gain: gin,
        contraction_enumerated: None,
        input_gain_enumerated: None,
        condition_sqrt: (m.lmax / m.lmin).sqrt(),
        gamma13_polynomial: g13,
        gamma13_enumerated: None,
        gamma13: g13,
        gamma1w: g1w,
        input_matrix_gain: spectral_norm((&m.half * mpc.system().b()).as_ref()),
        gamma14: f64::INFINITY,
        not_computed: None,
    }
}

impl<'a> Gamma13Plan<'a> {
    /// The first stage of [`super::gamma13_certified_budgeted`] (same arguments).
    pub fn start(
        mpc: &'a CondensedMpc,
        max_vars: usize,
        pattern_families: u64,
        phase_seconds: f64,
    ) -> Result<Gamma13Stage<'a>, MpcError> {
        let variables = mpc.qp().n();
        let us = mpc.input_set();
        let skipped = Vec::new();
        let fam = Family::new(mpc)?;
        let s = fam.saturable;
        if !(us.lower().iter().all(|l| *l <= 0.0) && us.upper().iter().all(|u| *u >= 0.0)) {
            return Ok(Gamma13Stage::Done(Box::new(void_certificate(
                variables,
                s,
                Gamma13Void::OriginOutsideInputSet,
                skipped,
            ))));
        }
        if let Some(void) = saturated_dynamics_void(mpc, &fam)? {
            return Ok(Gamma13Stage::Done(Box::new(void_certificate(
                variables, s, void, skipped,
            ))));
        }
        let depth = if s > 0 {
            mpc.pattern_depth(pattern_families)
        } else {
            0
        };
        let patterns: Vec<Family> = if depth > 0 {
            mpc.pattern_gains(depth)?
                .iter()
                .map(|g| Family::from_gains(mpc, g))
                .collect::<Result<_, _>>()?
        } else {
            Vec::new()
        };
        let metrics = metrics::candidates(mpc, &fam);
        // One metric per task (in order), so the result does not depend on the thread count.
        let figures: Vec<Result<(f64, f64), MpcError>> = metrics
            .par_iter()
            .map(|m| metric_figures(&fam, &patterns, m))
            .collect();
        let mut candidates = Vec::with_capacity(metrics.len());
        // ‖S^{½}E‖₂ per metric: how w¹ enters (x⁺ = … + Ew¹).
        let noise_gains: Vec<f64> = metrics
            .iter()
            .map(|m| spectral_norm((&m.half * mpc.system().e()).as_ref()))
            .collect();
        for ((m, fig), &ng) in metrics.iter().zip(figures).zip(&noise_gains) {
            let (lam, gin) = fig?;
            candidates.push(family_candidate(mpc, m, lam, gin, ng));
        }
        let gamma13_polynomial = candidates
            .iter()
            .map(|c| c.gamma13_polynomial)
            .fold(f64::INFINITY, f64::min);

        // Enumeration: the three best metrics by the family bound (so the enumerated minimum never
        // exceeds the polynomial one); every metric if none certifies.
        let mut order: Vec<usize> = (0..metrics.len()).collect();
        order.sort_by(|&i, &j| {
            candidates[i]
                .gamma13_polynomial
                .total_cmp(&candidates[j].gamma13_polynomial)
        });
        let chosen: Vec<usize> = if gamma13_polynomial.is_finite() {
            let mut c: Vec<usize> = order.iter().copied().take(3).collect();
            c.sort_unstable();
            c
        } else {
            (0..metrics.len()).collect()
        };
        let refs: Vec<&Metric> = chosen.iter().map(|&i| &metrics[i]).collect();
        let n_refs = refs.len();
        let work = enumeration_work(mpc, refs.len());
        let seconds = work / crate::budget::SCALAR_RATE;
        let affordable = s <= max_vars.min(30) && seconds <= phase_seconds;
        let enumeration = affordable.then(|| VertexEnumeration::new(mpc, &refs, max_vars));
        Ok(Gamma13Stage::Plan(Box::new(Gamma13Plan {
            mpc,
            max_vars,
            phase_seconds,
            fam,
            depth,
            pattern_families: patterns.len(),
            metrics,
            candidates,
            noise_gains,
            gamma13_polynomial,
            order,
            chosen,
            n_refs,
            work,
            seconds,
            s,
            variables,
            skipped,
            enumeration,
        })))
    }

    /// An upper bound on [`Gamma13Plan::chunks`] for any plan of `mpc`, known before the
    /// plan: min(64, 2^s) (the chunks are fixed by 2^s).
    pub fn max_chunks(mpc: &CondensedMpc) -> usize {
        usize::try_from(super::enumerate::VERTEX_CHUNKS.min(mpc.free_set_count()))
            .unwrap_or(usize::MAX)
    }

    /// Chunks of the free-set enumeration (0 when it is not run: too many saturable
    /// variables, or over the budget).
    pub fn chunks(&self) -> usize {
        self.enumeration
            .as_ref()
            .map_or(0, VertexEnumeration::chunks)
    }

    /// Chunk `i` (< [`Gamma13Plan::chunks`]) of the free-set enumeration.
    pub fn chunk(&self, i: usize) -> Result<Gamma13Chunk, MpcError> {
        match &self.enumeration {
            Some(e) if i < e.chunks() => e.chunk(self.mpc, i),
            _ => Err(MpcError::Parameter {
                name: "γ₁,₃ enumeration chunk",
                value: i as f64,
                reason: "below the plan's number of chunks",
            }),
        }
    }

    /// Why the free sets are not enumerated when they are not: over the cap on s, or over
    /// the analysis budget (then also the budget's cut, "not computed within the budget").
    fn enumeration_skip(&self) -> (SkippedComputation, Option<crate::budget::NotComputed>) {
        let (s, depth) = (self.s, self.depth);
        let cap = self.max_vars.min(30);
        if s > cap {
            let reason = SkipReason::OverVariableCap {
                saturable: s,
                cap,
                depth,
            };
            let skip = SkippedComputation {
                computation: "free-set enumeration".into(),
                reason,
            };
            return (skip, None);
        }
        let cut = crate::budget::NotComputed {
            phase: "γ₁,₃ free-set enumeration".into(),
            needed_seconds: self.seconds,
            budget_seconds: self.phase_seconds,
        };
        let reason = SkipReason::OverBudget {
            saturable: s,
            metrics: self.n_refs,
            n_x: self.mpc.nx(),
            work: self.work,
            seconds: self.seconds,
            budget_seconds: self.phase_seconds,
            depth,
        };
        let skip = SkippedComputation {
            computation: "free-set enumeration".into(),
            reason,
        };
        (skip, Some(cut))
    }

    /// The certificate from every chunk's figures, in chunk order (all
    /// [`Gamma13Plan::chunks`] of them).
    pub fn finish(
        self,
        chunks: Vec<Result<Gamma13Chunk, MpcError>>,
    ) -> Result<Gamma13Certificate, MpcError> {
        let (skip, cut) = self.enumeration_skip();
        let Gamma13Plan {
            mpc,
            fam,
            depth,
            pattern_families,
            metrics,
            mut candidates,
            noise_gains,
            gamma13_polynomial,
            order,
            chosen,
            s,
            variables,
            mut skipped,
            enumeration,
            ..
        } = self;
        let vertex = match &enumeration {
            Some(e) if chunks.len() == e.chunks() => e.reduce(chunks)?,
            Some(e) => {
                return Err(MpcError::Parameter {
                    name: "γ₁,₃ enumeration chunks",
                    value: chunks.len() as f64,
                    reason: if e.chunks() > chunks.len() {
                        "fewer than the plan's number of chunks"
                    } else {
                        "more than the plan's number of chunks"
                    },
                });
            }
            None => None,
        };
        let mut over_budget = None;
        let (enumerated, free_sets) = match &vertex {
            Some(v) => (true, v.free_sets),
            None => {
                skipped.push(skip);
                over_budget = cut;
                (false, 0)
            }
        };
        let gamma13_enumerated = vertex
            .as_ref()
            .map(|v| fold_enumerated(&mut candidates, &chosen, v, &metrics, &noise_gains));

        // The linear law: impulse-response sum with the best contracting metric's tail bound.
        let mut gamma13_linear = None;
        if s == 0 {
            if let Some(i) = order
                .first()
                .copied()
                .filter(|&i| candidates[i].gamma13.is_finite())
            {
                gamma13_linear = impulse_response_gain(
                    &fam,
                    &fam.bk_lin,
                    &metrics[i],
                    candidates[i].contraction,
                );
            }
        }

        finish_candidates(&mut candidates, &metrics);
        let best = candidates
            .iter()
            .filter(|c| c.gamma13.is_finite())
            .min_by(|x, y| x.gamma13.total_cmp(&y.gamma13));
        let mut gamma13 = best.map_or(f64::INFINITY, |c| c.gamma13);
        let mut metric = best.map(|c| c.metric.clone());
        let mut method = best.map(bound_of);
        // γ₁,₄, γ₁ʷ and β₁ of the same estimate as γ₁,₃.
        let mut gamma14 = best.map_or(f64::INFINITY, |c| c.gamma14);
        let gamma1w = best.map_or(f64::INFINITY, |c| c.gamma1w);
        let (beta_prefactor, beta_rate) = best.map_or((None, None), |c| {
            (Some(c.condition_sqrt), Some(used_contraction(c)))
        });
        if let Some(l) = gamma13_linear.filter(|l| *l < gamma13) {
            gamma13 = l;
            method = Some(Gamma13Method::Linear);
            metric = Some("impulse response (tail from the best metric)".into());
            // The linear law: superposition bounds each input's term separately, so the
            // homogeneous and w terms may keep the metric's figures.
            if let Some(i) = order.first().copied() {
                let b = mpc.system().b().to_owned();
                gamma14 = impulse_response_gain(&fam, &b, &metrics[i], candidates[i].contraction)
                    .unwrap_or(gamma14);
            }
        }
        let void = (!gamma13.is_finite())
            .then(|| why_void(&candidates, over_budget.as_ref(), enumerated, depth));
        Ok(Gamma13Certificate {
            gamma13,
            method,
            metric,
            pattern_blocks: depth,
            pattern_families,
            gamma13_polynomial,
            gamma13_enumerated,
            gamma13_linear,
            gamma14,
            gamma1w,
            beta_prefactor,
            beta_rate,
            candidates,
            variables,
            saturable: s,
            free_sets,
            enumerated,
            void,
            skipped,
            over_budget,
        })
    }
}
