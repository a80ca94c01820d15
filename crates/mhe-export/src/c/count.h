/* Instructions per step on Cortex-M under QEMU -icount (compile with -DMHE_COUNT_SYSTICK;
 * cortex-m/startup.c counts the SysTick wraps): ticks of SysTick times the instructions per
 * tick of a calibration loop of known length. Emulated instructions, not cycles. */
#ifndef MHE_COUNT_H
#define MHE_COUNT_H
#ifdef MHE_COUNT_SYSTICK
#define SYST_CSR (*(volatile unsigned long *)0xE000E010u)
#define SYST_RVR (*(volatile unsigned long *)0xE000E014u)
#define SYST_CVR (*(volatile unsigned long *)0xE000E018u)
/* Counted by the SysTick interrupt (cortex-m/startup.c) at every wrap of the 24-bit timer. */
extern volatile unsigned long mhe_systick_wraps;
/* Ticks since start-up (the down-counter and its wraps, read consistently). */
static double ticks_now(void) {
    unsigned long w, c;
    do {
        w = mhe_systick_wraps;
        c = SYST_CVR & 0xFFFFFFu;
    } while (w != mhe_systick_wraps);
    return (double)w * 16777216.0 + (double)(0xFFFFFFu - c);
}
static double ticks_since(double before) { return ticks_now() - before; }
/* Instructions per SysTick tick: a loop of a known instruction count (2 per pass). */
static double calibrate(void) {
    double before = ticks_now();
    unsigned long n = 1000000u;
    __asm volatile("1: subs %0, %0, #1\n bne 1b" : "+r"(n) : : "cc");
    return 2000000.0 / ticks_since(before);
}
/* Starts SysTick and returns the instructions per tick. */
static double count_init(void) {
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* enable, interrupt at each wrap, processor clock */
    while ((SYST_CVR & 0xFFFFFFu) == 0u) {
        /* the write of CVR cleared it; the first tick reloads it */
    }
    return calibrate();
}
#endif
#endif
