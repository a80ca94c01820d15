/* Replay: prints x_hat_{0|0}, then for every input line "u_1,...,u_nu,y_1,...,y_ny" (a row
 * of trace.csv's u and y columns) pushes (u_t, y_t) and prints x_hat_{t+1|t+1}: output line
 * t is row t of trace.csv's xhat columns. 17 significant digits, comma-separated.
 * With -DMHE_COUNT_SYSTICK (Cortex-M under QEMU -icount) it also reports the instructions
 * per step (push + estimate) on stderr, measured with SysTick. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "mhe.h"
#include "count.h"

static mhe_state state;

static void print_estimate(const mhe_real *x) {
    int i;
    for (i = 0; i < MHE_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}


int main(void) {
    static char line[8192];
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    long row = 0;
#ifdef MHE_COUNT_SYSTICK
    double per_tick = count_init(), total = 0.0, worst = 0.0;
#endif
    mhe_reset(&state, mhe_exported_prior);
    print_estimate(mhe_estimate(&state));
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *end;
        int i;
        if (line[0] == '\n' || line[0] == '\0') continue;
        for (i = 0; i < MHE_NU + MHE_NY; i++) {
            double v = strtod(p, &end);
            if (end == p) {
                fprintf(stderr, "replay: line %ld: expected %d numbers (u then y), comma-separated\n",
                        row + 1, MHE_NU + MHE_NY);
                return 1;
            }
            if (i < MHE_NU) u[i] = (mhe_real)v; else y[i - MHE_NU] = (mhe_real)v;
            p = end;
            while (*p == ' ' || *p == '\t') p++;
            if (i + 1 < MHE_NU + MHE_NY) {
                if (*p != ',') {
                    fprintf(stderr, "replay: line %ld: expected %d numbers (u then y), comma-separated\n",
                            row + 1, MHE_NU + MHE_NY);
                    return 1;
                }
                p++;
            }
        }
        {
#ifdef MHE_COUNT_SYSTICK
            double before = ticks_now();
            double n;
#endif
            const mhe_real *x;
            mhe_push(&state, u, y);
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
#ifdef MHE_COUNT_SYSTICK
    if (row > 0)
        fprintf(stderr, "instructions per step (push + estimate): mean %.0f, max %.0f over %ld steps\n",
                total / (double)row, worst, row);
#endif
    return 0;
}
