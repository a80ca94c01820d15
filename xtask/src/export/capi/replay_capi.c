/* The replay program (docs/embedded.md, "Replay format") over the C ABI of the static
 * library: cc -std=c99 -ffp-contract=off replay_capi.c target/release/libmhe_export_capi.a */
#include <stdio.h>
#include <stdlib.h>
#include "mhe_capi.h"

static void print_estimate(int nx) {
    mhe_real x[64];
    int i;
    if (mhe_capi_estimate(x) != 0) exit(1);
    for (i = 0; i < nx; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}

int main(void) {
    static char line[8192];
    int32_t nx, nu, ny;
    mhe_real u[64], y[64];
    long row = 0;
    mhe_capi_dims(&nx, &nu, &ny);
    if (nx > 64 || nu > 64 || ny > 64 || mhe_capi_reset(NULL) != 0) return 1;
    print_estimate(nx);
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *end;
        int i;
        if (line[0] == '\n') continue;
        for (i = 0; i < nu + ny; i++) {
            double v = strtod(p, &end);
            if (end == p) {
                fprintf(stderr, "replay: line %ld: expected %d numbers\n", row + 1, (int)(nu + ny));
                return 1;
            }
            if (i < nu) u[i] = (mhe_real)v; else y[i - nu] = (mhe_real)v;
            p = (*end == ',') ? end + 1 : end;
        }
        if (mhe_capi_push(u, y) != 0) return 1;
        print_estimate(nx);
        row++;
    }
    return 0;
}
