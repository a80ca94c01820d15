//! The work of ρ_lin, estimated from the dimensions before anything is computed
//! ([`crate::budget`]): per K, the K-step map of the MHE's iteration (repeated squaring of the
//! augmented step matrix of n_ξ + n_θ rows), the products that assemble 𝔸(K), and the
//! spectral radius of the dim X × dim X lifted matrix ([`eigen_work`]: ≈ 10 dim³ for the dense
//! eigenvalues, far less for Arnoldi's method above [`super::KRYLOV_MIN_DIM`]).

/// The dimensions that set the cost of ρ_lin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct LiftedDims {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// M.
    pub horizon: usize,
    /// n_z = n_x + M n_w.
    pub nz: usize,
    /// N n_u for the sub-optimal MPC, 0 for a static law.
    pub n_controller: usize,
    /// n_θ = n_x + M(n_u + n_y).
    pub n_theta: usize,
}

impl LiftedDims {
    /// dim X = n_x + M(n_u + n_y + n_x) + n_z (+ N n_u).
    pub fn dim(&self) -> usize {
        self.nx + self.horizon * (self.nu + self.ny + self.nx) + self.nz + self.n_controller
    }

    /// Estimated multiply-adds of ρ_lin on an ascending `grid` (as computed by
    /// [`super::LiftedLoop::spectral_radii`]) for an iteration map whose state has `lift`
    /// entries (n_ξ: n_z for PG and ADMM, 2n_z for FISTA): the binary powers of the step
    /// matrix once, one product per set bit of each advance along the grid, the readout, the
    /// assembly of 𝔸(K) and its spectral radius ([`eigen_work`]) per K.
    pub fn grid_work(&self, lift: usize, grid: &[usize]) -> f64 {
        let (xi, nz, nt, dim) = (
            lift as f64,
            self.nz as f64,
            self.n_theta as f64,
            self.dim() as f64,
        );
        let top = grid.iter().copied().max().unwrap_or(0);
        let bits = f64::from(usize::BITS - top.leading_zeros());
        let mut work = bits * (xi.powi(3) + xi * xi * nt);
        let mut prev = 0usize;
        let mut sorted = grid.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        for k in sorted {
            let advances = f64::from((k - prev.min(k)).count_ones());
            prev = k;
            work += advances * xi * xi * (nz + nt)
                + nz * xi * (nz + nt)
                + nz * nt * dim
                + 2.0 * self.nx as f64 * nz * dim
                + eigen_work(self.dim());
        }
        work
    }
}

/// Estimated multiply-adds of one spectral radius of a dim × dim lifted matrix
/// ([`super::spectral_radius`]): the dense eigenvalues (≈ 10 dim³) below
/// [`super::KRYLOV_MIN_DIM`]; above, Arnoldi with a subspace of m ≈ min(dim, 300) (measured
/// 50–363 on the thermal rod at M = 30): m products of dim², 2m²·dim for the
/// orthogonalisation and ≈ 75m³ for the Ritz values at the checkpoints.
pub fn eigen_work(dim: usize) -> f64 {
    let d = dim as f64;
    if dim < super::KRYLOV_MIN_DIM {
        return 10.0 * d.powi(3);
    }
    let m = dim.min(300) as f64;
    m * d * d + 2.0 * m * m * d + 75.0 * m.powi(3)
}
