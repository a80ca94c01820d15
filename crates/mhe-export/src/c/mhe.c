/* The estimator step; see mhe.h. Mirrors crates/mhe-embedded/src/{qp,estimator}.rs. */
/* Bit identity needs IEEE operations as written: no fused multiply-add (GCC's default GNU
 * mode contracts a*b + c into an FMA where the target has one, e.g. the Cortex-M4F's
 * vfma.f32), no fast-math. The pragmas turn contraction off for this file (ISO C; GCC
 * ignores the STDC one, hence its own); mhe_self_test catches what they cannot. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")
#else
#pragma STDC FP_CONTRACT OFF
#endif
#if defined(__FAST_MATH__)
#error "mhe.c: compiled with -ffast-math/-Ofast: the estimator's bits (and the certified iteration) would change; remove it"
#endif
#include <math.h>
#include <string.h>
#include "mhe.h"

#define P (&mhe_exported_problem)

static mhe_real clampr(mhe_real v, mhe_real l, mhe_real u) {
    mhe_real w = (l > v) ? l : v;
    return (u < w) ? u : w;
}

/* y[..n] = H x, H by columns, each row summed from 0 in column order. */
static void matvec(const mhe_real *h, int n, const mhe_real *x, mhe_real *y) {
    int i, j;
    for (i = 0; i < n; i++) y[i] = (mhe_real)0;
    for (j = 0; j < n; j++) {
        const mhe_real *col = h + (long)j * n;
        mhe_real xj = x[j];
        for (i = 0; i < n; i++) y[i] = y[i] + col[i] * xj;
    }
}

/* out[..r] = (out when acc) + B x (B(i, k) = b[i*rs + k*cs], x of c entries) in the std
 * fixed-size product's order: per row the even columns in s0 (from the accumulated term,
 * else from column 0), the odd ones in s1 (from column 1), then s0 + s1. */
static void gemv_fixed(const mhe_real *b, long rs, long cs, int r, const mhe_real *x, int c,
                       mhe_real *out, int acc) {
    int i, k;
    for (i = 0; i < r; i++) {
        mhe_real s0 = acc ? out[i] : (mhe_real)0, s1 = (mhe_real)0;
        for (k = 0; k < c; k++) {
            mhe_real p = b[i * rs + k * cs] * x[k];
            if (k % 2 == 0) {
                s0 = (k == 0 && !acc) ? p : p + s0;
            } else if (k == 1) {
                s1 = p;
            } else {
                s1 = p + s1;
            }
        }
        out[i] = (c > 1) ? s0 + s1 : s0;
    }
}

/* out[..r] += B x in column order (the std run-time-size product). */
static void gemv_seq(const mhe_real *b, long rs, long cs, int r, const mhe_real *x, int c,
                     mhe_real *out) {
    int i, k;
    for (k = 0; k < c; k++)
        for (i = 0; i < r; i++) out[i] = out[i] + b[i * rs + k * cs] * x[k];
}

/* B x into out (fresh when !acc) in the window's order. */
static void gemv_st(int fixed, const mhe_real *b, long rs, long cs, int r, const mhe_real *x,
                    int c, mhe_real *out, int acc) {
    int i;
    if (fixed) {
        gemv_fixed(b, rs, cs, r, x, c, out, acc);
    } else {
        if (!acc)
            for (i = 0; i < r; i++) out[i] = (mhe_real)0;
        gemv_seq(b, rs, cs, r, x, c, out);
    }
}

/* dst = d .* src (d NULL: a copy). */
static void load_scaled(mhe_real *dst, const mhe_real *src, const mhe_real *d, int n) {
    int i;
    for (i = 0; i < n; i++) dst[i] = d ? d[i] * src[i] : src[i];
}

/* out[..n] = H_c z (d non-NULL: D H_c D z) through the window's factors: mhe-embedded's
 * Structured::apply, operation for operation. wa: m*ny scalars (g_y per stage); wb:
 * 4nx + ny + 2nw. */
static void structured_apply(const mhe_structured *st, const mhe_real *d, const mhe_real *z,
                             mhe_real *out, mhe_real *wa, mhe_real *wb) {
    int nx = st->nx, ny = st->ny, nw1 = st->nw1, nw2 = st->nw2, nw = nw1 + nw2, m = st->m;
    int fx = st->fixed_order, i, j;
    mhe_real *x = wb, *xn = wb + nx, *lam = wb + 2 * nx, *lamn = wb + 3 * nx;
    mhe_real *y = wb + 4 * nx, *wd = y + ny, *v = wd + nw;
    const mhe_real *zw = z + nx;
    mhe_real *ow = out + nx;
    load_scaled(x, z, d, nx);
    for (j = 0; j < m; j++) {
        mhe_real eta = st->decay[j];
        mhe_real *gy = wa + (long)j * ny, *o = ow + (long)j * nw;
        const mhe_real *dj = d ? d + nx + (long)j * nw : 0;
        load_scaled(wd, zw + (long)j * nw, dj, nw);
        for (i = 0; i < nw; i++) v[i] = eta * wd[i];
        if (fx) {
            gemv_fixed(st->f, 1, ny, ny, wd + nw1, nw2, y, 0);
            gemv_fixed(st->c, 1, ny, ny, x, nx, y, 1);
            gemv_fixed(st->r, 1, ny, ny, y, ny, gy, 0);
            for (i = 0; i < ny; i++) gy[i] = eta * gy[i];
            gemv_fixed(st->q + (long)nw1 * nw, 1, nw, nw1, v + nw1, nw2, o, 0);
            gemv_fixed(st->q, 1, nw, nw1, v, nw1, o, 1);
            gemv_fixed(st->f, ny, 1, nw2, gy, ny, o + nw1, 0);
            gemv_fixed(st->q + (long)nw1 * nw + nw1, 1, nw, nw2, v + nw1, nw2, o + nw1, 1);
            gemv_fixed(st->q + nw1, 1, nw, nw2, v, nw1, o + nw1, 1);
            gemv_fixed(st->e, 1, nx, nx, wd, nw1, xn, 0);
            gemv_fixed(st->a, 1, nx, nx, x, nx, xn, 1);
        } else {
            for (i = 0; i < ny; i++) y[i] = (mhe_real)0;
            gemv_seq(st->f, 1, ny, ny, wd + nw1, nw2, y);
            gemv_seq(st->c, 1, ny, ny, x, nx, y);
            for (i = 0; i < ny; i++) gy[i] = (mhe_real)0;
            gemv_seq(st->r, 1, ny, ny, y, ny, gy);
            for (i = 0; i < ny; i++) gy[i] = gy[i] * eta;
            for (i = 0; i < nw; i++) o[i] = (mhe_real)0;
            gemv_seq(st->q, 1, nw, nw, v, nw, o);
            gemv_seq(st->f, ny, 1, nw2, gy, ny, o + nw1);
            for (i = 0; i < nx; i++) xn[i] = (mhe_real)0;
            gemv_seq(st->e, 1, nx, nx, wd, nw1, xn);
            gemv_seq(st->a, 1, nx, nx, x, nx, xn);
        }
        for (i = 0; i < nx; i++) x[i] = xn[i];
    }
    for (i = 0; i < nx; i++) lam[i] = (mhe_real)0;
    for (j = m - 1; j >= 0; j--) {
        mhe_real *o = ow + (long)j * nw;
        const mhe_real *gy = wa + (long)j * ny;
        gemv_st(fx, st->e, nx, 1, nw1, lam, nx, o, 1);
        if (d)
            for (i = 0; i < nw; i++) o[i] = o[i] * d[nx + (long)j * nw + i];
        gemv_st(fx, st->c, ny, 1, nx, gy, ny, lamn, 0);
        gemv_st(fx, st->a, nx, 1, nx, lam, nx, lamn, 1);
        for (i = 0; i < nx; i++) lam[i] = lamn[i];
    }
    load_scaled(x, z, d, nx);
    for (i = 0; i < nx; i++) out[i] = lam[i];
    gemv_st(fx, st->p, 1, nx, nx, x, nx, out, 1);
    if (d)
        for (i = 0; i < nx; i++) out[i] = d[i] * out[i];
}

/* y[..n] = H x: the dense h, or the window's structured product (on the scaled problem
 * D H_c D) with wa, wb as its workspaces. */
static void hessian(const mhe_window *w, const mhe_real *x, mhe_real *y, mhe_real *wa,
                    mhe_real *wb) {
    if (w->structured)
        structured_apply(w->structured, w->scaling, x, y, wa, wb);
    else
        matvec(w->h, w->n, x, y);
}

/* q = q0 + F theta, each row summed from q0_i in theta order. */
static void linear_term(const mhe_window *w, const mhe_real *theta, mhe_real *q) {
    int i, k, nt = w->n_theta;
    for (i = 0; i < w->n; i++) {
        const mhe_real *row = w->f + (long)i * nt;
        mhe_real acc = w->q0[i];
        for (k = 0; k < nt; k++) acc = acc + row[k] * theta[k];
        q[i] = acc;
    }
}

void mhe_run_window(const mhe_window *w, int method, const mhe_real *theta,
                    const mhe_real *z0, int iterations, mhe_real *const v[6], mhe_real *out) {
    int n = w->n, i, k;
    const mhe_real *lo = w->lower, *hi = w->upper;
    mhe_real *z = v[0], *q = v[2];
    if (n == 0) return;
    linear_term(w, theta, q);
    if (z0 == 0) {
        for (i = 0; i < n; i++) z[i] = clampr((mhe_real)0, lo[i], hi[i]);
    } else if (w->scaling == 0) {
        for (i = 0; i < n; i++) z[i] = z0[i];
    } else {
        for (i = 0; i < n; i++) z[i] = z0[i] / w->scaling[i];
    }
    if (method == MHE_PG) {
        mhe_real *hz = v[4];
        for (k = 0; k < iterations; k++) {
            hessian(w, z, hz, v[1], v[3]);
            for (i = 0; i < n; i++) {
                mhe_real x = z[i] - w->step * (hz[i] + q[i]);
                z[i] = clampr(x, lo[i], hi[i]);
            }
        }
    } else if (method == MHE_FISTA) {
        mhe_real *y = v[1], *hy = v[4];
        for (i = 0; i < n; i++) y[i] = z[i];
        for (k = 0; k < iterations; k++) {
            mhe_real b = (k == 0) ? (mhe_real)0 : w->momentum;
            hessian(w, y, hy, v[3], v[5]);
            if (w->structured) {
                /* The std structured branch: y+ = (1 + b) x+ - b x. */
                mhe_real b1 = (mhe_real)1 + b;
                for (i = 0; i < n; i++) {
                    mhe_real x = clampr(y[i] - w->step * (hy[i] + q[i]), lo[i], hi[i]);
                    y[i] = b1 * x - b * z[i];
                    z[i] = x;
                }
            } else {
                for (i = 0; i < n; i++) {
                    mhe_real x = clampr(y[i] - w->step * (hy[i] + q[i]), lo[i], hi[i]);
                    y[i] = x + b * (x - z[i]);
                    z[i] = x;
                }
            }
        }
    } else {
        mhe_real *s = v[1], *mq = v[3], *t = v[4], *y = v[5];
        mhe_real a = w->relaxation;
        matvec(w->m_inv, n, q, mq);
        matvec(w->h, n, z, y);
        for (i = 0; i < n; i++) y[i] = -(y[i] + q[i]);
        for (i = 0; i < n; i++) {
            s[i] = z[i] + w->inv_rho * y[i];
            t[i] = (mhe_real)2 * clampr(s[i], lo[i], hi[i]) - s[i];
        }
        for (k = 0; k < iterations; k++) {
            matvec(w->m_rho, n, t, z);
            for (i = 0; i < n; i++) {
                mhe_real vv, ww;
                z[i] = z[i] - mq[i];
                vv = clampr(s[i], lo[i], hi[i]);
                ww = a * z[i] + (s[i] - a * vv);
                t[i] = (mhe_real)2 * clampr(ww, lo[i], hi[i]) - ww;
                s[i] = ww;
            }
        }
        for (i = 0; i < n; i++) z[i] = clampr(s[i], lo[i], hi[i]);
    }
    if (w->scaling == 0) {
        for (i = 0; i < n; i++) out[i] = z[i];
    } else {
        for (i = 0; i < n; i++) out[i] = w->scaling[i] * z[i];
    }
}

/* y[..rows] += M x (row-major), each row summed from 0 first. */
static void mul_add(const mhe_real *m, int rows, int cols, const mhe_real *x, mhe_real *y) {
    int i, j;
    for (i = 0; i < rows; i++) {
        mhe_real acc = (mhe_real)0;
        for (j = 0; j < cols; j++) acc = acc + m[(long)i * cols + j] * x[j];
        y[i] = y[i] + acc;
    }
}

/* out = A x + B u + E w1. */
static void step_model(const mhe_real *x, const mhe_real *u, const mhe_real *w1, mhe_real *out) {
    int i;
    for (i = 0; i < MHE_NX; i++) out[i] = (mhe_real)0;
    mul_add(P->a, MHE_NX, MHE_NX, x, out);
    mul_add(P->b, MHE_NX, MHE_NU, u, out);
    mul_add(P->e, MHE_NX, P->nw1, w1, out);
}

static void ring_push(mhe_real *data, int width, int next, const mhe_real *v) {
    memcpy(data + (long)next * width, v, sizeof(mhe_real) * (size_t)width);
}

/* The k-th newest entry (k = 1 newest) of a ring of MHE_M rows of `width`. */
static const mhe_real *ring_back(const mhe_real *data, int width, int next, int k) {
    return data + (long)((next + MHE_M - k) % MHE_M) * width;
}

void mhe_reset(mhe_state *s, const mhe_real *prior) {
    int i;
    for (i = 0; i < MHE_NX; i++) s->prior[i] = prior[i];
    s->t = 0;
    s->estimated = 0;
    s->ring_len = 0;
    s->ring_next = 0;
    for (i = 0; i < MHE_NZ; i++) s->z0[i] = (mhe_real)0;
    for (i = 0; i < MHE_NX; i++) s->z0[i] = prior[i];
}

const mhe_real *mhe_estimate(mhe_state *s) {
    long t = s->t;
    int m = (t < MHE_M) ? (int)t : MHE_M;
    int nw = P->nw1 + P->nw2, j, i;
    const mhe_window *w = &P->windows[m];
    int u_off = MHE_NX, y_off = MHE_NX + m * MHE_NU;
    if (t <= MHE_M) {
        for (i = 0; i < MHE_NX; i++) s->theta[i] = s->prior[i];
    } else {
        const mhe_real *e = ring_back(&s->est_ring[0][0], MHE_NX, s->ring_next, MHE_M);
        for (i = 0; i < MHE_NX; i++) s->theta[i] = e[i];
    }
    for (j = 0; j < m; j++) {
        const mhe_real *u = ring_back(&s->u_ring[0][0], MHE_NU_BUF, s->ring_next, m - j);
        const mhe_real *y = ring_back(&s->y_ring[0][0], MHE_NY, s->ring_next, m - j);
        for (i = 0; i < MHE_NU; i++) s->theta[u_off + j * MHE_NU + i] = u[i];
        for (i = 0; i < MHE_NY; i++) s->theta[y_off + j * MHE_NY + i] = y[i];
    }
    {
        mhe_real *const v[6] = {s->work[0], s->work[1], s->work[2],
                                s->work[3], s->work[4], s->work[5]};
        mhe_run_window(w, P->method, s->theta, s->z0, P->iterations, v, s->zk);
    }
    for (i = 0; i < MHE_NX; i++) s->x_hat[i] = s->zk[i];
    for (j = 0; j < m; j++) {
        step_model(s->x_hat, s->theta + u_off + j * MHE_NU, s->zk + MHE_NX + j * nw, s->x_tmp);
        for (i = 0; i < MHE_NX; i++) s->x_hat[i] = s->x_tmp[i];
    }
    s->estimated = 1;
    return s->x_hat;
}

int mhe_push(mhe_state *s, const mhe_real *u, const mhe_real *y) {
    long t;
    int m, nw = P->nw1 + P->nw2, nz, i;
    for (i = 0; i < MHE_NU; i++)
        if (!isfinite(u[i])) return MHE_E_NONFINITE;
    for (i = 0; i < MHE_NY; i++)
        if (!isfinite(y[i])) return MHE_E_NONFINITE;
    if (!s->estimated) mhe_estimate(s);
    t = s->t;
    m = (t < MHE_M) ? (int)t : MHE_M;
    nz = MHE_NX + m * nw;
    if (t < MHE_M) {
        for (i = 0; i < nz; i++) s->z0[i] = s->zk[i];
        for (i = nz; i < nz + nw; i++) s->z0[i] = (mhe_real)0;
    } else if (P->warm_start == MHE_WARM_PAPER) {
        for (i = 0; i < nz; i++) s->z0[i] = s->zk[i];
    } else {
        step_model(s->zk, s->theta + MHE_NX, s->zk + MHE_NX, s->x_tmp);
        for (i = 0; i < MHE_NX; i++) s->z0[i] = s->x_tmp[i];
        for (i = MHE_NX; i < nz - nw; i++) s->z0[i] = s->zk[i + nw];
        for (i = nz - nw; i < nz; i++) s->z0[i] = (mhe_real)0;
    }
    ring_push(&s->est_ring[0][0], MHE_NX, s->ring_next, s->x_hat);
    if (MHE_NU > 0) ring_push(&s->u_ring[0][0], MHE_NU_BUF, s->ring_next, u);
    ring_push(&s->y_ring[0][0], MHE_NY, s->ring_next, y);
    s->ring_next = (s->ring_next + 1) % MHE_M;
    if (s->ring_len < MHE_M) s->ring_len++;
    /* Saturate: beyond M + 1 only "the window is full" matters, and a free-running counter
     * would overflow (2^31 steps of a 32-bit long are 25 days at 1 kHz). */
    if (t <= MHE_M) s->t = t + 1;
    s->estimated = 0;
    return MHE_OK;
}

int mhe_self_test(mhe_state *scratch) {
#if MHE_SELF_TEST_STEPS > 0
    int k;
    mhe_reset(scratch, mhe_exported_prior);
    for (k = 0; k < MHE_SELF_TEST_STEPS; k++) {
        const mhe_real *x;
        if (mhe_push(scratch, mhe_self_test_u[k], mhe_self_test_y[k]) != MHE_OK) return k + 1;
        x = mhe_estimate(scratch);
        if (memcmp(x, mhe_self_test_x[k], sizeof(mhe_real) * MHE_NX) != 0) return k + 1;
    }
    return 0;
#else
    (void)scratch;
    return 0;
#endif
}
