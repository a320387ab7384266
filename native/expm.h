/* Dense linear algebra of the native plants: the matrix exponential, as the Python FMUs
 * compute it (dronefly/models/linear_algebra.py), operation for operation. */
#ifndef DRONEFLY_EXPM_H
#define DRONEFLY_EXPM_H
#include <stddef.h>

#define EXPM_MAX 8 /* the largest matrix: [[A h, B h], [0, 0]] of 4 states and 4 controls */

double fmu_fsum(const double *x, size_t n);
/* exp(a) of the n x n matrix a (row-major, n <= EXPM_MAX, finite entries) into e */
void fmu_expm(const double *a, int n, double *e);
/* Phi (n x n) and Gamma (n x m) of exp([[A h, B h], [0, 0]]) from A h and B h (row-major,
 * finite entries, n + m <= EXPM_MAX), with B h scaled so that it takes no more squarings than
 * A h needs (models/linear_algebra.py, hold_exponential) */
void fmu_expm_hold(const double *ah, const double *bh, int n, int m, double *phi,
                   double *gamma);
#endif
