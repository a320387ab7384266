/* DroneFlyHover6DOF (native): the nonlinear rigid body in six degrees of freedom with the
 * paper's linear aerodynamics (aerodynamics = 1), as dronefly/models/rigid_body.py computes it.
 * The quasi-steady aerodynamics (aerodynamics = 2) are pythonfmu-only: docs/native.md. */
#ifndef DRONEFLY_MODEL_H
#define DRONEFLY_MODEL_H
#define PLANT_NX 4   /* the linear plants' state size, for their A and B (the .inc files) */
#define HOVER_NX 13  /* u, v, w, p, q, r, e0..e3, the earth-axis position (non-dimensional) */

typedef struct {
    double x[HOVER_NX];
    double la[3][3], lb[3][3];  /* the lateral rows (v, p, r) of A1 (columns v, p, r), B1 */
    double na[3][3], nb[3][4];  /* the longitudinal rows (u, w, q) of A (columns u, w, q), B */
    double G[6], g;             /* the gyroscopic coefficients, g+ */
    double U, n;
} HoverState;
typedef HoverState ModelState;
#endif
