/* The shared part of the linear plant FMUs (DroneFlyLateral, DroneFlyLongitudinal), as
 * dronefly/fmu_src/linear_slave.py: x+' = A x+ + B u in wing beats, stepped exactly for
 * controls held over the step (zero-order hold), the state kept non-dimensional.
 * The model's model.h defines PLANT_NU, the first rows of the controls, states, start values
 * and of A and B (consecutive, as the variable table lists them), and the kinds of the
 * states' reference scales; its model.c computes A and B from the parameters. */
#ifndef DRONEFLY_LINEAR_PLANT_H
#define DRONEFLY_LINEAR_PLANT_H

#define PLANT_NX 4
#define SCALE_ONE 0
#define SCALE_U 1
#define SCALE_N 2

typedef struct {
    double x[PLANT_NX];                  /* x+, non-dimensional */
    double A[PLANT_NX][PLANT_NX];
    double B[PLANT_NX][PLANT_NU];
    double n, scale[PLANT_NX];
    int has_step;                        /* M holds the step of h_wb wing beats */
    double h_wb;
    int step_finite;                     /* M is finite (Phi and Gamma do not overflow) */
    int phi_finite;                      /* Phi = exp(A h) is finite (else Gamma alone is not) */
    double M[PLANT_NX][PLANT_NX + PLANT_NU]; /* [Phi, Gamma] */
} PlantState;

/* A and B of the parameters in r; 0, or 1 with a message naming the bad value */
int plant_matrices(const double *r, double A[PLANT_NX][PLANT_NX],
                   double B[PLANT_NX][PLANT_NU], char *why);
#endif
