//! One window ℙ_m of the MHE problem: the paper's maps, the condensed QP, its box and
//! general rows, and the certified L_Φ of Lemma 1.

use super::*;

pub(super) fn build_window(
    sys: &LtiSystem,
    d: Dims,
    m: usize,
    w: &MheWeights,
    sets: &MheSets,
) -> Result<MheWindow> {
    let layout = WindowLayout { dims: d, m };
    let (nz, nth) = (layout.nz(), layout.n_theta());
    let (a, c, e, f) = (sys.a(), sys.c(), sys.e(), sys.f());
    let maps = paper_maps(sys, layout, w, sets);
    let (h_c, f_c) = condense(&maps);
    let (lo, hi) = sym_extreme_eigenvalues("H_c", h_c.as_ref())?;
    if !(lo > STRONG_CONVEXITY_TOL * hi) || !hi.is_finite() {
        return Err(MheError::NotStronglyConvex {
            window: m,
            min_eigenvalue: lo,
            max_eigenvalue: hi,
        });
    }

    let zset = window_box(sets, m, nz)?;
    let (mut lipschitz_certified, lipschitz_unconstrained) = lipschitz(&h_c, &f_c, m, lo, hi)?;
    // Lemma 1's bound is an H_c-weighted projection onto a FIXED set; rows whose bounds move
    // with θ (E ≠ 0: the states depend on the inputs in θ) break it.
    let lipschitz_void = maps.rows.moves_with_theta();
    if lipschitz_void {
        lipschitz_certified = f64::INFINITY;
    }

    // The structured product H_c z (forward + adjoint pass) for long windows.
    let op = crate::structured::MheHessian::new(
        layout,
        a,
        c,
        e,
        f,
        w.eta,
        w.p.as_ref(),
        w.q.as_ref(),
        w.r.as_ref(),
    );
    let mut qp =
        ParametricQp::new(h_c, vec![0.0; nz], f_c, zset)?.with_operator(std::sync::Arc::new(op))?;
    let PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xz,
        xth,
        rows,
    } = maps;
    if let Some(gc) = rows.build(nz, nth)? {
        qp = qp.with_general(gc)?;
    }
    Ok(MheWindow {
        layout,
        qp,
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xend_z: xz,
        xend_theta: xth,
        weight_min: 0.5 * lo,
        weight_max: 0.5 * hi,
        lipschitz_certified,
        lipschitz_unconstrained,
        lipschitz_void,
    })
}

/// One window's maps in the paper's variables (eq. (9)): the stacked residuals
/// T z + S θ − z̃ with z̃ = Z̃ θ, their weight H, the end state x̂_m = X_z z + X_θ θ, and the
/// general rows x̂_j ∈ 𝒳, ŷ_j ∈ 𝒴.
struct PaperMaps {
    t_map: Mat<f64>,
    s_map: Mat<f64>,
    ztilde_map: Mat<f64>,
    h_paper: Mat<f64>,
    xz: Mat<f64>,
    xth: Mat<f64>,
    rows: GeneralRows,
}

fn paper_maps(sys: &LtiSystem, layout: WindowLayout, w: &MheWeights, sets: &MheSets) -> PaperMaps {
    let (d, m) = (layout.dims, layout.m);
    let (nx, ny, nw, nw1) = (d.nx, d.ny, d.nw(), d.nw1);
    let (nz, nth, np) = (layout.nz(), layout.n_theta(), layout.n_paper());
    let (a, b, c, e, f) = (sys.a(), sys.b(), sys.c(), sys.e(), sys.f());
    let mut t_map = Mat::<f64>::zeros(np, nz);
    let mut s_map = Mat::<f64>::zeros(np, nth);
    let mut ztilde_map = Mat::<f64>::zeros(np, nth);
    let mut h_paper = Mat::<f64>::zeros(np, np);

    // x̂₀ block: z_t starts with x̂₀, z̃_t with the prior; weight 2η^m P.
    let eta_m = w.eta.powi(pow_i32(m));
    for i in 0..nx {
        t_map[(i, i)] = 1.0;
        ztilde_map[(i, i)] = 1.0;
        for j in 0..nx {
            h_paper[(i, j)] = 2.0 * eta_m * w.p[(i, j)];
        }
    }
    // x̂_j = X_z z + X_θ θ, propagated stage by stage.
    let mut xz = Mat::<f64>::zeros(nx, nz);
    let mut xth = Mat::<f64>::zeros(nx, nth);
    for i in 0..nx {
        xz[(i, i)] = 1.0;
    }
    // General rows (G, E, l₀, u₀): x̂_j ∈ 𝒳 for j = 1..m, ŷ_j ∈ 𝒴 for j = 0..m−1.
    let mut rows = GeneralRows::default();
    for j in 0..m {
        let pw = layout.paper_w_offset(j);
        let py = layout.paper_y_offset(j);
        let zw = layout.w_offset(j);
        // Stage j is time t − m + j, i.e. i = m − j in eq. (9): weight η^{m−1−j}.
        let decay = w.eta.powi(pow_i32(m - 1 - j));
        for i in 0..nw {
            t_map[(pw + i, zw + i)] = 1.0;
            for k in 0..nw {
                h_paper[(pw + i, pw + k)] = 2.0 * decay * w.q[(i, k)];
            }
        }
        // ŷ_j = C x̂_j + F ŵ²_j.
        let cxz = c * &xz;
        let cxth = c * &xth;
        for i in 0..ny {
            for k in 0..nz {
                t_map[(py + i, k)] = cxz[(i, k)];
            }
            for k in 0..d.nw2 {
                t_map[(py + i, zw + nw1 + k)] += f[(i, k)];
            }
            for k in 0..nth {
                s_map[(py + i, k)] = cxth[(i, k)];
            }
            ztilde_map[(py + i, layout.y_offset(j) + i)] = 1.0;
            for k in 0..ny {
                h_paper[(py + i, py + k)] = decay * w.r[(i, k)];
            }
        }
        // x̂_{j+1} = A x̂_j + B u_j + E ŵ¹_j.
        let mut xz_next = a * &xz;
        let mut xth_next = a * &xth;
        for i in 0..nx {
            for k in 0..nw1 {
                xz_next[(i, zw + k)] += e[(i, k)];
            }
            for k in 0..d.nu {
                xth_next[(i, layout.u_offset(j) + k)] += b[(i, k)];
            }
        }
        xz = xz_next;
        xth = xth_next;
        rows.push_finite(&xz, &xth, sets.state.lower(), sets.state.upper());
    }
    // ŷ_j = T_y z + S_y θ: the rows of T and S at the output offsets.
    for j in 0..m {
        let py = layout.paper_y_offset(j);
        let gy = t_map.subrows(py, ny).to_owned();
        let ey = s_map.subrows(py, ny).to_owned();
        rows.push_finite(&gy, &ey, sets.output.lower(), sets.output.upper());
    }
    PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xz,
        xth,
        rows,
    }
}

/// The condensed QP's H_c = 2TᵀHT and F_c = 2TᵀH(S − Z̃).
fn condense(maps: &PaperMaps) -> (Mat<f64>, Mat<f64>) {
    let PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        ..
    } = maps;
    let (nz, nth) = (t_map.ncols(), s_map.ncols());
    let ht = h_paper * t_map;
    let h_c = lti_model::matrix::symmetrize((t_map.transpose() * &ht).as_ref());
    let h_c = Mat::from_fn(nz, nz, |i, j| 2.0 * h_c[(i, j)]);
    let s_minus = s_map - ztilde_map;
    let f_c = t_map.transpose() * (h_paper * &s_minus);
    let f_c = Mat::from_fn(nz, nth, |i, j| 2.0 * f_c[(i, j)]);
    (h_c, f_c)
}

/// Z = 𝒳 × 𝒲^m.
fn window_box(sets: &MheSets, m: usize, nz: usize) -> Result<BoxSet> {
    let (mut lower, mut upper) = (Vec::with_capacity(nz), Vec::with_capacity(nz));
    lower.extend_from_slice(sets.state.lower());
    upper.extend_from_slice(sets.state.upper());
    for _ in 0..m {
        lower.extend_from_slice(sets.disturbance.lower());
        upper.extend_from_slice(sets.disturbance.upper());
    }
    let zset = BoxSet::named("Z", lower, upper).map_err(lti_model::ModelError::from)?;
    Ok(zset)
}

/// L_Φ of Lemma 1 and the unconstrained ‖H_c⁻¹F_c‖₂: ‖H^{-1/2}F‖₂² = λ_max(Fᵀ H⁻¹ F),
/// ‖H⁻¹F‖₂ directly (lo, hi: H_c's extreme eigenvalues).
fn lipschitz(h_c: &Mat<f64>, f_c: &Mat<f64>, m: usize, lo: f64, hi: f64) -> Result<(f64, f64)> {
    let llt = h_c
        .llt(Side::Lower)
        .map_err(|_| MheError::NotStronglyConvex {
            window: m,
            min_eigenvalue: lo,
            max_eigenvalue: hi,
        })?;
    let hinv_f = llt.solve(f_c);
    let ft_hinv_f = lti_model::matrix::symmetrize((f_c.transpose() * &hinv_f).as_ref());
    let (_, top) = sym_extreme_eigenvalues("F_cᵀH_c⁻¹F_c", ft_hinv_f.as_ref())?;
    Ok((
        top.max(0.0).sqrt() / lo.sqrt(),
        lti_model::matrix::spectral_norm(hinv_f.as_ref()),
    ))
}

/// The general rows of one window, gathered stage by stage.
#[derive(Default)]
struct GeneralRows {
    g: Vec<Vec<f64>>,
    e: Vec<Vec<f64>>,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl GeneralRows {
    /// One row per component with a finite bound: lo_i ≤ (G_i z + E_i θ) ≤ hi_i, stored as
    /// lo_i − E_iθ ≤ G_i z ≤ hi_i − E_iθ.
    fn push_finite(&mut self, g: &Mat<f64>, e: &Mat<f64>, lo: &[f64], hi: &[f64]) {
        for i in 0..g.nrows() {
            if lo[i].is_finite() || hi[i].is_finite() {
                self.g.push((0..g.ncols()).map(|k| g[(i, k)]).collect());
                self.e.push((0..e.ncols()).map(|k| e[(i, k)]).collect());
                self.lo.push(lo[i]);
                self.hi.push(hi[i]);
            }
        }
    }

    fn moves_with_theta(&self) -> bool {
        self.e.iter().any(|r| r.iter().any(|v| *v != 0.0))
    }

    fn build(self, nz: usize, nth: usize) -> Result<Option<qp_iter::GeneralConstraints>> {
        if self.g.is_empty() {
            return Ok(None);
        }
        let m = self.g.len();
        let g = Mat::from_fn(m, nz, |i, k| self.g[i][k]);
        let e = Mat::from_fn(m, nth, |i, k| self.e[i][k]);
        Ok(Some(qp_iter::GeneralConstraints::new(
            g, e, self.lo, self.hi,
        )?))
    }
}
