/* The loop program (docs/embedded.md, "Loop format") over the C ABI of the static library:
 * estimator + K_c-iteration MPC. cc -std=c99 -ffp-contract=off loop_capi.c
 * target/release/libmhe_export_capi.a */
#include <stdio.h>
#include <stdlib.h>
#include "mhe_capi.h"
#include "parse.h"

static void print_row(int nx, int nu, const mhe_real *x, const mhe_real *u) {
    int i;
    for (i = 0; i < nx; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    for (i = 0; i < nu; i++) printf(",%.17g", (double)u[i]);
    printf("\n");
}

int main(void) {
    static char line[MHE_LINE_MAX];
    double vals[64];
    long lineno = 0;
    int rc;
    int32_t nx, nu, ny;
    mhe_real x[64], u[64], y[64];
    mhe_capi_dims(&nx, &nu, &ny);
    if (nx > 64 || nu > 64 || ny > 64 || !mhe_capi_has_mpc()) {
        fprintf(stderr, "loop: this export has no MPC\n");
        return 1;
    }
    if (mhe_capi_reset(NULL) != 0 || mhe_capi_mpc_reset() != 0) return 1;
    if (mhe_capi_estimate(x) != 0 || mhe_capi_mpc_control(x, u) != 0) return 1;
    print_row(nx, nu, x, u);
    while ((rc = mhe_read_line("loop", line, ++lineno)) == 1) {
        int i;
        if (mhe_blank(line)) continue;
        if (mhe_parse_line("loop", line, lineno, (int)ny, "y", vals) != 0) return 1;
        for (i = 0; i < ny; i++) y[i] = (mhe_real)vals[i];
        if (mhe_capi_push(u, y) != 0 || mhe_capi_estimate(x) != 0) {
            fprintf(stderr, "loop: line %ld: refused by mhe_capi_push\n", lineno);
            return 1;
        }
        if (mhe_capi_mpc_control(x, u) != 0) {
            fprintf(stderr, "loop: line %ld: the MPC failed\n", lineno);
            return 1;
        }
        print_row(nx, nu, x, u);
    }
    return rc < 0;
}
