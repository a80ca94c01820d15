/* C ABI of the exported estimator: the static library built from capi/ (cargo build
 * --release in capi/: target/release/libmhe_export_capi.a). One instance, no allocation,
 * not reentrant. mhe_real is double (f64 export) or float (f32 export): define
 * MHE_CAPI_F32 before including this header for an f32 export. */
#ifndef MHE_CAPI_H
#define MHE_CAPI_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifdef MHE_CAPI_F32
typedef float mhe_real;
#else
typedef double mhe_real;
#endif

/* Restarts at t = 0 with prior[0..NX] (NULL: the exported prior). 0, or -1. */
int32_t mhe_capi_reset(const mhe_real *prior);
/* Appends (u_t, y_t) (NU and NY values) and advances t. 0, or -1 on NULL. */
int32_t mhe_capi_push(const mhe_real *u, const mhe_real *y);
/* Writes x_hat_{t|t} to x_hat[0..NX]. 0, or -1 on NULL. */
int32_t mhe_capi_estimate(mhe_real *x_hat);
/* n_x, n_u, n_y (NULL pointers are skipped). */
void mhe_capi_dims(int32_t *nx, int32_t *nu, int32_t *ny);

#ifdef __cplusplus
}
#endif
#endif
