/*
 * The physical limit of a closed-loop step: the arithmetic of the lateral pair and nothing else.
 * Per step the plant's zero-order hold x <- [Phi Gamma] (x; u) (a 4 x 7 matrix times a vector:
 * 28 multiplications, 24 additions) and the law u <- K x (3 x 4: 12 multiplications, 9
 * additions), on the paper's matrices at 0.1 wing beat, no FMI, no calls, no checks.
 *
 *   native_limit N_STEPS     prints "loop_s=<seconds> steps=<n> check=<x[3]>" on stdout
 *
 * Built by benchmarks/native_bench.py with the project's toolchain (harness/builder/toolchain.py) and
 * the same flags as the native FMUs; the printed state keeps the compiler from dropping work.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
    /* a [Phi Gamma] and a K of the right magnitudes: the arithmetic, not the trajectory, is
       what is timed; the state is set back to x0 every 4096 steps (one branch per step), so
       that it never grows to infinity or decays to subnormal numbers, which would change the
       arithmetic's cost */
    static const double M[4][7] = {
        {0.99906, -0.00011, 0.0, 0.00158, -0.0000528, 0.000551, 0.0000712},
        {0.01741, 0.97504, 0.0293, 0.0, 0.049874, 0.075153, 0.072488},
        {-0.01117, 0.01551, 0.965, 0.0, -0.032911, -0.048556, -0.08654},
        {0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0}};
    static const double K[3][4] = {
        {-0.3192, -0.2879, -0.1969, -0.0643}, {0.0, 0.0, 0.0, 0.0}, {0.0, 0.0, 0.0, 0.0}};
    volatile long n_arg = argc > 1 ? strtol(argv[1], NULL, 10) : 1000000;
    long n = n_arg;
    double x[4] = {0.0, 0.0, 0.0, 0.1}, u[3] = {0.0, 0.0, 0.0}, z[7];
    double t0 = now_s();
    for (long k = 0; k < n; ++k) {
        if ((k & 4095) == 0) { x[0] = 0.0; x[1] = 0.0; x[2] = 0.0; x[3] = 0.1; }
        for (int i = 0; i < 3; ++i) u[i] = K[i][0] * x[0] + K[i][1] * x[1] + K[i][2] * x[2] + K[i][3] * x[3];
        z[0] = x[0]; z[1] = x[1]; z[2] = x[2]; z[3] = x[3]; z[4] = u[0]; z[5] = u[1]; z[6] = u[2];
        for (int i = 0; i < 4; ++i) {
            double s = 0.0;
            for (int j = 0; j < 7; ++j) s += M[i][j] * z[j];
            x[i] = s;
        }
    }
    printf("loop_s=%.9g steps=%ld check=%.17g\n", now_s() - t0, n, x[3]);
    return 0;
}
