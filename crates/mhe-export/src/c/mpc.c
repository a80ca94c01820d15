/* The K_c-iteration MPC; see mpc.h. Mirrors crates/mhe-embedded/src/mpc.rs. */
#include <math.h>
#include "mpc.h"

#if MHE_HAS_MPC
void mpc_reset(mpc_state *s) { s->has_previous = 0; }

const mhe_real *mpc_input_sequence(const mpc_state *s) { return s->seq; }

int mpc_control(mpc_state *s, const mhe_real *x_hat, mhe_real *u) {
    const mpc_problem *p = &mhe_exported_mpc;
    mhe_real *const v[6] = {s->work[0], s->work[1], s->work[2],
                            s->work[3], s->work[4], s->work[5]};
    const mhe_real *start = 0;
    int i;
    for (i = 0; i < MHE_NX; i++)
        if (!isfinite(x_hat[i])) return -1;
    if (s->has_previous) {
        /* Shift by one block and repeat the last. */
        for (i = 0; i < MPC_NSEQ - MHE_NU; i++) s->warm[i] = s->seq[i + MHE_NU];
        for (i = MPC_NSEQ - MHE_NU; i < MPC_NSEQ; i++) s->warm[i] = s->seq[i];
        start = s->warm;
    }
    mhe_run_window(&p->qp, p->method, x_hat, start, p->iterations, v, s->seq);
    for (i = 0; i < MPC_NSEQ; i++) {
        if (!isfinite(s->seq[i])) {
            s->has_previous = 0;
            return -2;
        }
    }
    s->has_previous = 1;
    for (i = 0; i < MHE_NU; i++) u[i] = s->seq[i];
    return 0;
}
#else
/* This export has no MPC (export with --kc); ISO C wants a declaration here. */
typedef int mpc_not_exported;
#endif
