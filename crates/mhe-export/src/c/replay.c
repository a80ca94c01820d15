/* Replay: prints x_hat_{0|0}, then for every input line "u_1,...,u_nu,y_1,...,y_ny" (a row
 * of trace.csv's u and y columns) pushes (u_t, y_t) and prints x_hat_{t+1|t+1}: output line
 * t is row t of trace.csv's xhat columns. 17 significant digits, comma-separated.
 * With -DMHE_COUNT_SYSTICK (Cortex-M under QEMU -icount) it also reports the instructions
 * per step (push + estimate) on stderr, measured with SysTick. It runs mhe_self_test first
 * and exits 1 if the build does not reproduce the stored bits; any malformed line (not
 * exactly n_u + n_y finite numbers, or longer than 8191 bytes) exits 1 naming the line. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "mhe.h"
#include "count.h"
#include "parse.h"

static mhe_state state;

static void print_estimate(const mhe_real *x) {
    int i;
    for (i = 0; i < MHE_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}


int main(void) {
    static char line[MHE_LINE_MAX];
    double vals[MHE_NU + MHE_NY];
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    long row = 0, lineno = 0;
    int rc;
#ifdef MHE_COUNT_SYSTICK
    double per_tick = count_init(), total = 0.0, worst = 0.0;
#endif
    rc = mhe_self_test(&state);
    if (rc != 0) {
        fprintf(stderr, "replay: self-test failed at step %d: this build does not reproduce the "
                        "exported estimator bit for bit (fused multiply-add or fast-math?)\n", rc);
        return 1;
    }
    mhe_reset(&state, mhe_exported_prior);
    print_estimate(mhe_estimate(&state));
    while ((rc = mhe_read_line("replay", line, ++lineno)) == 1) {
        int i;
        if (mhe_blank(line)) continue;
        if (mhe_parse_line("replay", line, lineno, MHE_NU + MHE_NY, "u then y", vals) != 0)
            return 1;
        for (i = 0; i < MHE_NU + MHE_NY; i++) {
            if (i < MHE_NU) u[i] = (mhe_real)vals[i]; else y[i - MHE_NU] = (mhe_real)vals[i];
        }
        {
#ifdef MHE_COUNT_SYSTICK
            double before = ticks_now();
            double n;
#endif
            const mhe_real *x;
            if (mhe_push(&state, u, y) != MHE_OK) {
                fprintf(stderr, "replay: line %ld: refused by mhe_push (a value is not finite "
                                "in the scalar of this export)\n", lineno);
                return 1;
            }
            x = mhe_estimate(&state);
#ifdef MHE_COUNT_SYSTICK
            n = (double)ticks_since(before) * per_tick;
            total += n;
            if (n > worst) worst = n;
#endif
            print_estimate(x);
        }
        row++;
    }
    if (rc < 0) return 1;
#ifdef MHE_COUNT_SYSTICK
    if (row > 0)
        fprintf(stderr, "instructions per step (push + estimate): mean %.0f, max %.0f over %ld steps\n",
                total / (double)row, worst, row);
#endif
    return 0;
}
