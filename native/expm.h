/* Dense linear algebra of the native plants: the matrix exponential, as the Python FMUs
 * compute it (dronefly/models/linear_algebra.py), operation for operation. */
#ifndef DRONEFLY_EXPM_H
#define DRONEFLY_EXPM_H
#include <stddef.h>

#define EXPM_MAX 8 /* the largest matrix: [[A h, B h], [0, 0]] of 4 states and 4 controls */

double fmu_fsum(const double *x, size_t n);
/* exp(a) of the n x n matrix a (row-major, n <= EXPM_MAX, finite entries) into e */
void fmu_expm(const double *a, int n, double *e);
#endif
