/* The loop program (docs/embedded.md, "Loop format") over the C ABI of the static library:
 * estimator + K_c-iteration MPC. cc -std=c99 -ffp-contract=off loop_capi.c
 * target/release/libmhe_export_capi.a */
#include <stdio.h>
#include <stdlib.h>
#include "mhe_capi.h"

static void print_row(int nx, int nu, const mhe_real *x, const mhe_real *u) {
    int i;
    for (i = 0; i < nx; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    for (i = 0; i < nu; i++) printf(",%.17g", (double)u[i]);
    printf("\n");
}

int main(void) {
    static char line[8192];
    int32_t nx, nu, ny;
    mhe_real x[64], u[64], y[64];
    long row = 0;
    mhe_capi_dims(&nx, &nu, &ny);
    if (nx > 64 || nu > 64 || ny > 64 || !mhe_capi_has_mpc()) {
        fprintf(stderr, "loop: this export has no MPC\n");
        return 1;
    }
    if (mhe_capi_reset(NULL) != 0 || mhe_capi_mpc_reset() != 0) return 1;
    if (mhe_capi_estimate(x) != 0 || mhe_capi_mpc_control(x, u) != 0) return 1;
    print_row(nx, nu, x, u);
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *end;
        int i;
        if (line[0] == '\n') continue;
        for (i = 0; i < ny; i++) {
            double v = strtod(p, &end);
            if (end == p) {
                fprintf(stderr, "loop: line %ld: expected %d numbers\n", row + 1, (int)ny);
                return 1;
            }
            y[i] = (mhe_real)v;
            p = (*end == ',') ? end + 1 : end;
        }
        if (mhe_capi_push(u, y) != 0 || mhe_capi_estimate(x) != 0) return 1;
        if (mhe_capi_mpc_control(x, u) != 0) {
            fprintf(stderr, "loop: step %ld: the MPC failed\n", row + 1);
            return 1;
        }
        print_row(nx, nu, x, u);
        row++;
    }
    return 0;
}
