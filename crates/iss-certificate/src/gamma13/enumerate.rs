//! Exact vertex figures for small problems: max over the 2^s free sets 𝔽 of
//! ‖A + BK_𝔽‖_S and ‖S^{½}BK_𝔽‖₂ for a list of metrics (the cross-check of the polynomial
//! bound, and the tighter value when 2^s is affordable).
//!
//! The enumeration runs in fixed mask chunks (run by the caller: on the rayon pool, or as
//! tasks of the sweep's pool) with a deterministic reduction, so the result does not depend
//! on the thread count. A metric is dropped once
//! its contraction factor reaches 1 (it can no longer certify; its reported λ is then a lower
//! bound ≥ 1 on the vertex maximum).

use lti_model::matrix::sym_lambda_max_above;
use mpc_core::{CondensedMpc, MpcError};

use super::metrics::Metric;

/// Vertex maxima per metric: (λ_S, g_S).
#[derive(Debug, Clone)]
pub(crate) struct VertexMax {
    pub contraction: Vec<f64>,
    pub input_gain: Vec<f64>,
    pub free_sets: u64,
}

/// Per mask chunk: (enumerated, masks visited, max λ per metric, max g per metric).
type ChunkMax = (bool, u64, Vec<f64>, Vec<f64>);

/// Frobenius norm: an upper bound on the spectral norm. The exact norm can only raise a
/// running maximum when the Frobenius norm exceeds it, so most masks skip the eigenproblem
/// and the maxima are unchanged.
fn frobenius(m: &[f64]) -> f64 {
    m.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// max(`running`, ‖M‖₂) of a small square row-major matrix, ‖M‖₂ via λ_max(MᵀM) with
/// scratch `g` (n²); the eigenproblem stops as soon as it cannot raise `running`
/// ([`sym_lambda_max_above`]: the same maximum, bit for bit).
fn raise_norm2(running: f64, m: &[f64], n: usize, g: &mut [f64]) -> f64 {
    for i in 0..n {
        for j in 0..n {
            g[i * n + j] = (0..n).map(|k| m[k * n + i] * m[k * n + j]).sum();
        }
    }
    match sym_lambda_max_above(g, n, running * running) {
        Some(top) => running.max(top.max(0.0).sqrt()),
        None => running,
    }
}

/// Mask chunks of the enumeration: fixed by 2^s alone (not by the thread count), so the
/// per-chunk maxima and their reduction are the same however the chunks are run.
pub(crate) const VERTEX_CHUNKS: u64 = 64;

/// The free-set enumeration for a list of metrics, in [`VERTEX_CHUNKS`] independent mask
/// chunks ([`VertexEnumeration::chunk`]) and their reduction ([`VertexEnumeration::reduce`]).
#[derive(Debug, Clone)]
pub(crate) struct VertexEnumeration {
    a: Vec<f64>,
    b: Vec<f64>,
    halves: Vec<(Vec<f64>, Vec<f64>)>,
    ranges: Vec<std::ops::Range<u64>>,
    max_vars: usize,
}

/// One chunk's figures (opaque outside this module).
#[derive(Debug, Clone)]
pub struct VertexChunk(ChunkMax);

impl VertexEnumeration {
    pub(crate) fn new(mpc: &CondensedMpc, metrics: &[&Metric], max_vars: usize) -> Self {
        let sys = mpc.system();
        let (nx, nu) = (mpc.nx(), mpc.nu());
        let a: Vec<f64> = (0..nx * nx).map(|k| sys.a()[(k / nx, k % nx)]).collect();
        let b: Vec<f64> = (0..nx * nu).map(|k| sys.b()[(k / nu, k % nu)]).collect();
        let row_major = |m: &faer::Mat<f64>| -> Vec<f64> {
            (0..nx * nx).map(|k| m[(k / nx, k % nx)]).collect()
        };
        let halves: Vec<(Vec<f64>, Vec<f64>)> = metrics
            .iter()
            .map(|m| (row_major(&m.half), row_major(&m.neg_half)))
            .collect();
        let total = mpc.free_set_count();
        let step = total.div_ceil(VERTEX_CHUNKS).max(1);
        let ranges: Vec<std::ops::Range<u64>> = (0..VERTEX_CHUNKS)
            .map(|c| (c.saturating_mul(step)).min(total)..(c + 1).saturating_mul(step).min(total))
            .filter(|r| !r.is_empty())
            .collect();
        Self {
            a,
            b,
            halves,
            ranges,
            max_vars,
        }
    }

    /// Number of chunks.
    pub(crate) fn chunks(&self) -> usize {
        self.ranges.len()
    }

    /// The maxima over the free sets of chunk `i` (< [`VertexEnumeration::chunks`]).
    pub(crate) fn chunk(&self, mpc: &CondensedMpc, i: usize) -> Result<VertexChunk, MpcError> {
        let (nx, nu) = (mpc.nx(), mpc.nu());
        let (a, b, halves) = (&self.a, &self.b, &self.halves);
        let n_metrics = halves.len();
        let range = self.ranges[i].clone();
        let mut lam = vec![0.0_f64; n_metrics];
        let mut gin = vec![0.0_f64; n_metrics];
        let (mut bk, mut j, mut t1, mut t2, mut g) = (
            vec![0.0; nx * nx],
            vec![0.0; nx * nx],
            vec![0.0; nx * nx],
            vec![0.0; nx * nx],
            vec![0.0; nx * nx],
        );
        let mut count = 0u64;
        let mul = |x: &[f64], y: &[f64], out: &mut [f64]| {
            for i in 0..nx {
                for c in 0..nx {
                    out[i * nx + c] = (0..nx).map(|k| x[i * nx + k] * y[k * nx + c]).sum();
                }
            }
        };
        let ran = mpc.for_each_free_set_in(self.max_vars, range, |_, kf, _| {
            count += 1;
            for i in 0..nx {
                for c in 0..nx {
                    let v: f64 = (0..nu).map(|p| b[i * nu + p] * kf[p * nx + c]).sum();
                    bk[i * nx + c] = v;
                    j[i * nx + c] = a[i * nx + c] + v;
                }
            }
            for (mi, (h, nh)) in halves.iter().enumerate() {
                if lam[mi] >= 1.0 {
                    continue;
                }
                mul(h, &j, &mut t1);
                mul(&t1, nh, &mut t2);
                if frobenius(&t2) > lam[mi] {
                    lam[mi] = raise_norm2(lam[mi], &t2, nx, &mut g);
                }
                mul(h, &bk, &mut t1);
                if frobenius(&t1) > gin[mi] {
                    gin[mi] = raise_norm2(gin[mi], &t1, nx, &mut g);
                }
            }
        })?;
        Ok(VertexChunk((ran, count, lam, gin)))
    }

    /// The vertex maxima from every chunk's figures, in chunk order; `Ok(None)` when
    /// s > `max_vars`.
    pub(crate) fn reduce(
        &self,
        per_chunk: Vec<Result<VertexChunk, MpcError>>,
    ) -> Result<Option<VertexMax>, MpcError> {
        let n_metrics = self.halves.len();
        let mut lam = vec![0.0_f64; n_metrics];
        let mut gin = vec![0.0_f64; n_metrics];
        let mut count = 0u64;
        for r in per_chunk {
            let VertexChunk((ran, c, l, g)) = r?;
            if !ran {
                return Ok(None);
            }
            count += c;
            for i in 0..n_metrics {
                lam[i] = lam[i].max(l[i]);
                gin[i] = gin[i].max(g[i]);
            }
        }
        Ok(Some(VertexMax {
            contraction: lam,
            input_gain: gin,
            free_sets: count,
        }))
    }
}
