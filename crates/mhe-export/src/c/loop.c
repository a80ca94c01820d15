/* The certified loop (docs/embedded.md, "Loop format"): the estimator and the K_c-iteration
 * MPC together, as on the board. Prints x_hat_{0|0} and u_0 = pi(x_hat_{0|0}) on one line;
 * then for every input line "y_1,...,y_ny" (the measurement y_t, a row of trace.csv's y
 * columns) pushes (u_t, y_t), estimates x_hat_{t+1|t+1}, computes u_{t+1} and prints
 * "x_hat...,u...": output line t is row t of trace.csv's xhat and u columns. 17 significant
 * digits, comma-separated. With -DMHE_COUNT_SYSTICK it reports the instructions per step
 * (push + estimate + control) on stderr. */
#include <stdio.h>
#include <stdlib.h>
#include "mpc.h"
#include "count.h"
#include "parse.h"

#if MHE_HAS_MPC
static mhe_state state;
static mpc_state ctrl;

static void print_row(const mhe_real *x, const mhe_real *u) {
    int i;
    for (i = 0; i < MHE_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    for (i = 0; i < MHE_NU; i++) printf(",%.17g", (double)u[i]);
    printf("\n");
}

static int control(const mhe_real *x, mhe_real *u, long row) {
    int rc = mpc_control(&ctrl, x, u);
    if (rc != 0) {
        fprintf(stderr, "loop: step %ld: %s\n", row,
                rc == -1 ? "the state estimate is not finite"
                         : "the MPC's K_c-th iterate is not finite");
    }
    return rc;
}

int main(void) {
    static char line[MHE_LINE_MAX];
    double vals[MHE_NY];
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    const mhe_real *x;
    long row = 0, lineno = 0;
    int rc;
#ifdef MHE_COUNT_SYSTICK
    double per_tick = count_init(), total = 0.0, worst = 0.0;
#endif
    rc = mhe_self_test(&state);
    if (rc != 0) {
        fprintf(stderr, "loop: self-test failed at step %d: this build does not reproduce the "
                        "exported estimator bit for bit (fused multiply-add or fast-math?)\n", rc);
        return 1;
    }
    mhe_reset(&state, mhe_exported_prior);
    mpc_reset(&ctrl);
    x = mhe_estimate(&state);
    if (control(x, u, 0) != 0) return 1;
    print_row(x, u);
    while ((rc = mhe_read_line("loop", line, ++lineno)) == 1) {
        int i;
        if (mhe_blank(line)) continue;
        if (mhe_parse_line("loop", line, lineno, MHE_NY, "y", vals) != 0) return 1;
        for (i = 0; i < MHE_NY; i++) y[i] = (mhe_real)vals[i];
        {
#ifdef MHE_COUNT_SYSTICK
            double before = ticks_now();
            double n;
#endif
            if (mhe_push(&state, u, y) != MHE_OK) {
                fprintf(stderr, "loop: line %ld: refused by mhe_push (a value is not finite in "
                                "the scalar of this export)\n", lineno);
                return 1;
            }
            x = mhe_estimate(&state);
            if (control(x, u, row + 1) != 0) return 1;
#ifdef MHE_COUNT_SYSTICK
            n = (double)ticks_since(before) * per_tick;
            total += n;
            if (n > worst) worst = n;
#endif
            print_row(x, u);
        }
        row++;
    }
    if (rc < 0) return 1;
#ifdef MHE_COUNT_SYSTICK
    if (row > 0)
        fprintf(stderr, "instructions per step (push + estimate + control): mean %.0f, max %.0f over %ld steps\n",
                total / (double)row, worst, row);
#endif
    return 0;
}
#else
int main(void) {
    fprintf(stderr, "loop: this export has no MPC (cargo xtask export --kc K|certified)\n");
    return 1;
}
#endif
