/* The replay program (docs/embedded.md, "Replay format") over the C ABI of the static
 * library: cc -std=c99 -ffp-contract=off replay_capi.c target/release/libmhe_export_capi.a */
#include <stdio.h>
#include <stdlib.h>
#include "mhe_capi.h"
#include "parse.h"

static void print_estimate(int nx) {
    mhe_real x[64];
    int i;
    if (mhe_capi_estimate(x) != 0) exit(1);
    for (i = 0; i < nx; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}

int main(void) {
    static char line[MHE_LINE_MAX];
    int32_t nx, nu, ny;
    mhe_real u[64], y[64];
    double vals[128];
    long lineno = 0;
    int rc;
    mhe_capi_dims(&nx, &nu, &ny);
    if (nx > 64 || nu > 64 || ny > 64 || mhe_capi_reset(NULL) != 0) return 1;
    print_estimate(nx);
    while ((rc = mhe_read_line("replay", line, ++lineno)) == 1) {
        int i;
        if (mhe_blank(line)) continue;
        if (mhe_parse_line("replay", line, lineno, (int)(nu + ny), "u then y", vals) != 0) return 1;
        for (i = 0; i < nu + ny; i++) {
            if (i < nu) u[i] = (mhe_real)vals[i]; else y[i - nu] = (mhe_real)vals[i];
        }
        if (mhe_capi_push(u, y) != 0) {
            fprintf(stderr, "replay: line %ld: refused by mhe_capi_push\n", lineno);
            return 1;
        }
        print_estimate(nx);
    }
    return rc < 0;
}
