//! `From<&GlobalOutcome>` for the global loop record.

use super::super::*;
use iss_certificate::lure::global_outcome::GlobalOutcome as G;

impl From<&G> for GlobalLoopOutcome {
    fn from(l: &G) -> Self {
        let mut r = Self {
            verdict: String::new(),
            reason: l.to_string(),
            k_glob: None,
            phi_star: None,
            phi_at_k: None,
            k_max: None,
            margin: None,
            rho: None,
            gamma: None,
            gain_x: None,
            gain_e: None,
            rho_lin: None,
            estimate_seconds: None,
            budget_seconds: None,
        };
        r.verdict = match l {
            G::Certified(c) => {
                r.k_glob = Some(c.k_glob);
                r.phi_star = num(c.phi_star);
                r.phi_at_k = num(c.phi_at_k);
                r.margin = num(c.margin);
                r.rho = num(c.rho);
                r.gamma = num(c.gamma);
                r.gain_x = num(c.gain_x);
                r.gain_e = num(c.gain_e);
                "certified"
            }
            G::PhiBallBinds {
                phi_star,
                k_max,
                phi_at_k_max,
            } => {
                r.phi_star = num(*phi_star);
                r.k_max = Some(*k_max);
                r.phi_at_k = num(*phi_at_k_max);
                "phi_ball_binds"
            }
            G::OptimumBinds {
                margin_without_boxes,
            } => {
                r.margin = num(*margin_without_boxes);
                "optimum_binds"
            }
            G::LinearUnstable { rho_lin } => {
                r.rho_lin = num(*rho_lin);
                "linear_unstable"
            }
            // A mode with |λ| > 1 only bounded inputs reach: the sentence gives |λ|.
            G::UnstableWithBoundedInput { .. } => "impossible",
            G::SearchFailed { rho_lin } => {
                r.rho_lin = num(*rho_lin);
                "search_failed"
            }
            G::NotComputed {
                estimate_seconds,
                budget_seconds,
                ..
            } => {
                r.estimate_seconds = num(*estimate_seconds);
                r.budget_seconds = num(*budget_seconds);
                "not_computed"
            }
            // `Unsupported` and any later variant: its sentence says why.
            _ => "not_applicable",
        }
        .to_string();
        r
    }
}
