//! The certified set of (K_e, K_c): its staircase boundary (= the Pareto front) and the
//! cheapest pair for a per-iteration cost.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::gains::{JointAnalysis, first_true};

/// One pair (K_e, K_c).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct RegionPoint {
    /// MHE iterations per step.
    pub k_e: usize,
    /// MPC iterations per step.
    pub k_c: usize,
}

/// The certified region {(K_e, K_c) : certified} (an up-set: every larger pair is certified).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct JointRegion {
    /// Largest K_e and K_c searched.
    pub k_max: usize,
    /// Smallest K_e certified with some K_c ≤ `k_max` (the limit of an exact MPC).
    pub k_e_floor: Option<usize>,
    /// Smallest K_c certified with some K_e ≤ `k_max` (the limit of an exact MHE).
    pub k_c_floor: Option<usize>,
    /// The corners of the staircase boundary, K_e increasing, K_c decreasing: (K_e, K_c) is
    /// certified, (K_e − 1, K_c) and (K_e, K_c − 1) are not. These are the Pareto-optimal
    /// pairs.
    pub pareto: Vec<RegionPoint>,
    /// Cost per MHE iteration t_e and per MPC iteration t_c used for `cheapest`.
    pub cost_per_iteration: (f64, f64),
    /// The pair minimising K_e·t_e + K_c·t_c (a Pareto corner; the smallest K_e on ties).
    pub cheapest: Option<RegionPoint>,
    /// Why the region is empty (empty when it is not).
    pub void_reasons: Vec<crate::outcome::VoidReason>,
}

/// Most staircase corners listed (the boundary of a region this jagged is reported cut).
pub const MAX_CORNERS: usize = 4096;

impl JointAnalysis {
    /// The certified region up to `k_max` iterations on either side, with the cheapest pair
    /// for costs `t_e`, `t_c` per iteration (both > 0).
    ///
    /// Cost: O(corners · log k_max) evaluations of [`JointAnalysis::at`].
    pub fn region(&self, k_max: usize, t_e: f64, t_c: f64) -> JointRegion {
        let mut region = JointRegion {
            k_max,
            k_e_floor: None,
            k_c_floor: None,
            pareto: Vec::new(),
            cost_per_iteration: (t_e, t_c),
            cheapest: None,
            void_reasons: Vec::new(),
        };
        if !self.premises_hold() {
            region.void_reasons = self.violated().iter().map(|p| p.void_reason()).collect();
            return region;
        }
        let Some(k_e_floor) = self.k_e_min(k_max, k_max) else {
            region
                .void_reasons
                .push(crate::outcome::VoidReason::NoPair {
                    k_max,
                    spectral_radius: self.at(k_max, k_max).spectral_radius,
                });
            return region;
        };
        let k_c_floor = self.k_c_min(k_max, k_max);
        region.k_e_floor = Some(k_e_floor);
        region.k_c_floor = k_c_floor;
        // Walk the staircase: at each corner K_e, the next corner is the first K_e with a
        // smaller K_c_min.
        let mut k_e = k_e_floor;
        while let Some(k_c) = self.k_c_min(k_e, k_max) {
            region.pareto.push(RegionPoint { k_e, k_c });
            if k_c == 0 || Some(k_c) == k_c_floor || region.pareto.len() >= MAX_CORNERS {
                break;
            }
            match first_true(k_e + 1, k_max, |k| self.at(k, k_c - 1).certified) {
                Some(next) => k_e = next,
                None => break,
            }
        }
        if region.pareto.len() >= MAX_CORNERS {
            region
                .void_reasons
                .push(crate::outcome::VoidReason::BoundaryCut {
                    max_corners: MAX_CORNERS,
                });
        }
        region.cheapest = region.pareto.iter().copied().min_by(|a, b| {
            let ca = a.k_e as f64 * t_e + a.k_c as f64 * t_c;
            let cb = b.k_e as f64 * t_e + b.k_c as f64 * t_c;
            ca.total_cmp(&cb).then(a.k_e.cmp(&b.k_e))
        });
        region
    }

    /// The boundary on a grid of K_e: for each, the smallest certified K_c ≤ `k_c_max`
    /// (None: not certified at that K_e), the input the sweep's heat maps draw.
    pub fn boundary(&self, k_e_grid: &[usize], k_c_max: usize) -> Vec<(usize, Option<usize>)> {
        k_e_grid
            .iter()
            .map(|&k| (k, self.k_c_min(k, k_c_max)))
            .collect()
    }
}
