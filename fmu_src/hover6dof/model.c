/* DroneFlyHover6DOF (native): the rigid body of dronefly/models/rigid_body.py with the paper's
 * linear aerodynamics: the same floats, operation for operation (_RHS, _STAGES and _RESULT
 * written out in the order the Python evaluates them; _dot's sums left to right; Python's
 * min() and max() as they are). The aerodynamic rows are the linear plants' own A and B:
 * their model.c files, shipped as lateral_plant.inc and longitudinal_plant.inc, are included
 * here under other names. */
#include "exact.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "fmu.h"

#define PLANT_NU 3
#define plant_matrices lateral_matrices
#define PARAMS LATERAL_PARAMS
#define STABILITY LATERAL_STABILITY
#define CONTROL LATERAL_CONTROL
#include "lateral_plant.inc"
#undef PLANT_NU
#undef plant_matrices
#undef PARAMS
#undef STABILITY
#undef CONTROL
#define PLANT_NU 4
#define plant_matrices longitudinal_matrices
#define PARAMS LONGITUDINAL_PARAMS
#define STABILITY LONGITUDINAL_STABILITY
#define CONTROL LONGITUDINAL_CONTROL
#include "longitudinal_plant.inc"
#undef PLANT_NU
#undef plant_matrices
#undef PARAMS
#undef STABILITY
#undef CONTROL

#define MAX_SUBSTEP_WB 0.2          /* rigid_body.MAX_SUBSTEP_WB */
#define MAX_TURN_PER_SUBSTEP_RAD 0.05 /* rigid_body.MAX_TURN_PER_SUBSTEP_RAD */
#define MAX_SUBSTEPS 10000000.0

/* the seven controls (lateral, then longitudinal), the outputs (models/hover6dof.py
 * OUTPUT_NAMES) and the start values (slave._STARTS), each consecutive in the table */
static const int CONTROLS[7] = {VR_delta_Phi_a, VR_delta_alpha_1a, VR_delta_alpha_2a,
    VR_delta_Phi, VR_delta_alpha_1, VR_delta_phibar, VR_delta_alpha_2};
static const int OUTPUTS[17] = {VR_delta_v, VR_delta_p, VR_delta_r, VR_delta_gamma, VR_delta_u,
    VR_delta_w, VR_delta_q, VR_delta_theta, VR_phi, VR_theta, VR_psi, VR_x_earth, VR_y_earth,
    VR_z_earth, VR_vx_earth, VR_vy_earth, VR_vz_earth};
static const int STARTS[12] = {VR_delta_v_start, VR_delta_p_start, VR_delta_r_start,
    VR_delta_gamma_start, VR_delta_u_start, VR_delta_w_start, VR_delta_q_start,
    VR_delta_theta_start, VR_psi_start, VR_x_earth_start, VR_y_earth_start, VR_z_earth_start};

/* Python's min(a, b) and max(a, b): the first argument unless the second is smaller (larger) */
static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }

static void list_repr(char *buf, size_t size, const double *x, int n) {
    char v[32];
    snprintf(buf, size, "[");
    for (int k = 0; k < n; k++) {
        size_t len = strlen(buf);
        fmu_repr(v, sizeof v, x[k]);
        snprintf(buf + len, size - len, "%s%s", k ? ", " : "", v);
    }
    size_t len = strlen(buf);
    snprintf(buf + len, size - len, "]");
}

void model_reset(Instance *c) {
    HoverState *m = &c->s.model;
    memset(m, 0, sizeof *m);
    m->x[6] = 1.0; /* the unit quaternion of no rotation */
    m->U = VAR_START[VR_U];
    m->n = VAR_START[VR_n];
}

int model_refresh(Instance *c, char *why) {
    HoverState *m = &c->s.model;
    const double *r = c->s.r;
    double aero = r[VR_aerodynamics];
    if (aero == 2.0) {
        snprintf(why, FMU_WHY, "aerodynamics = 2 (quasi_steady) needs the quasi-steady wing "
                 "model, which runs in Python only: use the pythonfmu DroneFlyHover6DOF, or "
                 "aerodynamics = 1 (linear) here");
        return 1;
    }
    if (aero != 1.0) {
        snprintf(why, FMU_WHY, "aerodynamics = %.0f: expected 1 (linear) or 2 (quasi_steady)",
                 aero);
        return 1;
    }
    double A1[PLANT_NX][PLANT_NX], B1[PLANT_NX][3], A[PLANT_NX][PLANT_NX], B[PLANT_NX][4];
    if (lateral_matrices(r, A1, B1, why) || longitudinal_matrices(r, A, B, why)) return 1;
    const int ref[2] = {VR_n, VR_U};
    for (int k = 0; k < 2; k++) {
        double v = r[ref[k]];
        if (!(isfinite(v) && v > 0.0)) {
            char t[32];
            fmu_repr(t, sizeof t, v);
            snprintf(why, FMU_WHY, "%s = %s must be finite and > 0", VAR_NAME[ref[k]], t);
            return 1;
        }
    }
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            m->la[i][j] = A1[i][j];
            m->lb[i][j] = B1[i][j];
            m->na[i][j] = A[i][j];
        }
        for (int j = 0; j < 4; j++) m->nb[i][j] = B[i][j];
    }
    /* rigid_body._gyroscopic */
    double Ix = r[VR_Ix_plus], Iy = r[VR_Iy_plus], Iz = r[VR_Iz_plus], Ixz = r[VR_Ixz_plus];
    double det = Ix * Iz - pow(Ixz, 2.0); /* (Python: Ixz ** 2, libm's pow) */
    m->G[0] = (Iz * (Iz - Iy) + Ixz * Ixz) / det;
    m->G[1] = Ixz * (Iy - Ix - Iz) / det;
    m->G[2] = (Ix - Iz) / Iy;
    m->G[3] = Ixz / Iy;
    m->G[4] = Ixz * (Iz - Iy + Ix) / det;
    m->G[5] = (Ix * (Iy - Ix) - Ixz * Ixz) / det;
    m->g = r[VR_g_plus];
    m->n = r[VR_n];
    m->U = r[VR_U];
    return 0;
}

/* rigid_body.initial_state: the non-dimensional state of the start values */
static int initial_state(Instance *c, double *x, char *why) {
    const double *r = c->s.r;
    double theta = r[VR_delta_theta_start], gamma = r[VR_delta_gamma_start];
    double sg = sin(gamma), ct = cos(theta);
    if (fabs(sg) > fabs(ct) + 1e-15) {
        char a[32], b[32];
        fmu_repr(a, sizeof a, gamma);
        fmu_repr(b, sizeof b, theta);
        snprintf(why, FMU_WHY, "delta_gamma_start = %s rad and delta_theta_start = %s rad: no "
                 "attitude has both (|sin gamma| must not exceed cos theta)", a, b);
        return 1;
    }
    double phi = sg == 0.0 ? 0.0 : asin(py_max(-1.0, py_min(1.0, sg / ct)));
    double psi = r[VR_psi_start];
    double cr = cos(phi / 2), sr = sin(phi / 2), cp = cos(theta / 2), sp = sin(theta / 2);
    double cy = cos(psi / 2), sy = sin(psi / 2);
    double U = c->s.model.U, n = c->s.model.n, k = n / U;
    x[0] = r[VR_delta_u_start] / U;
    x[1] = r[VR_delta_v_start] / U;
    x[2] = r[VR_delta_w_start] / U;
    x[3] = r[VR_delta_p_start] / n;
    x[4] = r[VR_delta_q_start] / n;
    x[5] = r[VR_delta_r_start] / n;
    x[6] = cy * cp * cr + sy * sp * sr;
    x[7] = cy * cp * sr - sy * sp * cr;
    x[8] = cy * sp * cr + sy * cp * sr;
    x[9] = sy * cp * cr - cy * sp * sr;
    x[10] = r[VR_x_earth_start] * k;
    x[11] = r[VR_y_earth_start] * k;
    x[12] = r[VR_z_earth_start] * k;
    return 0;
}

/* rigid_body.outputs, into the value table */
static void write_outputs(Instance *c, const double *x) {
    double U = c->s.model.U, n = c->s.model.n;
    double u = x[0], v = x[1], w = x[2], p = x[3], q = x[4], r = x[5];
    double e0 = x[6], e1 = x[7], e2 = x[8], e3 = x[9];
    double phi = atan2(2.0 * (e2 * e3 + e0 * e1), 1.0 - 2.0 * (e1 * e1 + e2 * e2));
    double theta = asin(py_max(-1.0, py_min(1.0, -2.0 * (e1 * e3 - e0 * e2))));
    double psi = atan2(2.0 * (e1 * e2 + e0 * e3), 1.0 - 2.0 * (e2 * e2 + e3 * e3));
    double R[3][3] = {
        {1.0 - 2.0 * (e2 * e2 + e3 * e3), 2.0 * (e1 * e2 - e0 * e3), 2.0 * (e1 * e3 + e0 * e2)},
        {2.0 * (e1 * e2 + e0 * e3), 1.0 - 2.0 * (e1 * e1 + e3 * e3), 2.0 * (e2 * e3 - e0 * e1)},
        {2.0 * (e1 * e3 - e0 * e2), 2.0 * (e2 * e3 + e0 * e1), 1.0 - 2.0 * (e1 * e1 + e2 * e2)}};
    double gamma = asin(py_max(-1.0, py_min(1.0, 2.0 * (e2 * e3 + e0 * e1))));
    double L = U / n;
    double y[17] = {v * U, p * n, r * n, gamma, u * U, w * U, q * n, theta, phi, theta, psi,
                    x[10] * L, x[11] * L, x[12] * L, 0.0, 0.0, 0.0};
    for (int i = 0; i < 3; i++) y[14 + i] = (R[i][0] * u + R[i][1] * v + R[i][2] * w) * U;
    for (int i = 0; i < 17; i++) c->s.r[OUTPUTS[i]] = y[i];
}

static int start_state(Instance *c, double *x, char *why) {
    if (fmu_check_finite(c, STARTS, 12, why)) return 1;
    if (model_refresh(c, why)) return 1;
    return initial_state(c, x, why);
}

int model_update_outputs(Instance *c, char *why) {
    double x[HOVER_NX];
    if (c->s.initialized) return 0; /* the initial unknowns follow the starts until then */
    if (start_state(c, x, why)) return 1;
    write_outputs(c, x);
    return 0;
}

int model_initialize(Instance *c, char *why) {
    double x[HOVER_NX];
    if (start_state(c, x, why)) return 1;
    memcpy(c->s.model.x, x, sizeof x);
    write_outputs(c, x);
    return 0;
}

/* dx/dt+ (rigid_body._RHS with every term and the linear aerodynamics): d[0..9], and the
 * positions d[10..12] if positions */
static void rhs(const HoverState *m, const double *x, const double *bl, const double *bn,
                double *d, int positions) {
    double u = x[0], v = x[1], w = x[2], p = x[3], q = x[4], r = x[5];
    double e0 = x[6], e1 = x[7], e2 = x[8], e3 = x[9];
    const double (*l)[3] = m->la, (*k)[3] = m->na;
    double g = m->g;
    const double *G = m->G;
    double a_v = l[0][0] * v + l[0][1] * p + l[0][2] * r + bl[0];
    double a_p = l[1][0] * v + l[1][1] * p + l[1][2] * r + bl[1];
    double a_r = l[2][0] * v + l[2][1] * p + l[2][2] * r + bl[2];
    double a_u = k[0][0] * u + k[0][1] * w + k[0][2] * q + bn[0];
    double a_w = k[1][0] * u + k[1][1] * w + k[1][2] * q + bn[1];
    double a_q = k[2][0] * u + k[2][1] * w + k[2][2] * q + bn[2];
    double t0 = e0 + e0, t1 = e1 + e1, t2 = e2 + e2;
    double s13 = t1 * e3, s02 = t0 * e2, s23 = t2 * e3, s01 = t0 * e1, s11 = t1 * e1,
           s22 = t2 * e2;
    double R20 = s13 - s02, R21 = s23 + s01, R22 = 1.0 - (s11 + s22);
    a_u = a_u + g * R20;
    a_v = a_v + g * R21;
    a_w = a_w + g * (R22 - 1.0);
    a_u = a_u - (q * w - r * v);
    a_v = a_v - (r * u - p * w);
    a_w = a_w - (p * v - q * u);
    double pq = p * q, qr = q * r;
    a_p -= G[0] * qr + G[1] * pq;
    a_q -= G[2] * (p * r) + G[3] * (p * p - r * r);
    a_r -= G[4] * qr + G[5] * pq;
    d[0] = a_u;
    d[1] = a_v;
    d[2] = a_w;
    d[3] = a_p;
    d[4] = a_q;
    d[5] = a_r;
    d[6] = 0.5 * (-e1 * p - e2 * q - e3 * r);
    d[7] = 0.5 * (e0 * p + e2 * r - e3 * q);
    d[8] = 0.5 * (e0 * q - e1 * r + e3 * p);
    d[9] = 0.5 * (e0 * r + e1 * q - e2 * p);
    if (!positions) return;
    double s33 = (e3 + e3) * e3, s12 = t1 * e2, s03 = t0 * e3;
    d[10] = (1.0 - (s22 + s33)) * u + (s12 - s03) * v + (s13 + s02) * w;
    d[11] = (s12 + s03) * u + (1.0 - (s11 + s33)) * v + (s23 - s01) * w;
    d[12] = R20 * u + R21 * v + R22 * w;
}

/* n sub-steps of h wing beats of Butcher's order-6 method (rigid_body._STAGES, _RESULT) */
static void substeps(const HoverState *m, double *y, double n, double h, const double *bl,
                     const double *bn) {
    double h3 = h / 3, h8 = h / 8, h12 = h / 12, h16 = h / 16, h44 = h / 44, h120 = h / 120;
    double h23 = 2.0 * h3;
    double K[8][HOVER_NX], z[HOVER_NX];
    for (double s = 0; s < n; s += 1.0) {
        rhs(m, y, bl, bn, K[1], 1);
        for (int j = 0; j < 10; j++) z[j] = y[j] + h3 * K[1][j];
        rhs(m, z, bl, bn, K[2], 0);
        for (int j = 0; j < 10; j++) z[j] = y[j] + h23 * K[2][j];
        rhs(m, z, bl, bn, K[3], 1);
        for (int j = 0; j < 10; j++) z[j] = y[j] + h12 * (K[1][j] - K[3][j]) + h3 * K[2][j];
        rhs(m, z, bl, bn, K[4], 1);
        for (int j = 0; j < 10; j++)
            z[j] = y[j] + h16 * (18.0 * K[2][j] - K[1][j] - 3.0 * K[3][j] - 6.0 * K[4][j]);
        rhs(m, z, bl, bn, K[5], 1);
        for (int j = 0; j < 10; j++)
            z[j] = y[j] + h8 * (9.0 * K[2][j] - 3.0 * K[3][j] - 6.0 * K[4][j] + 4.0 * K[5][j]);
        rhs(m, z, bl, bn, K[6], 1);
        for (int j = 0; j < 10; j++)
            z[j] = y[j] + h44 * (9.0 * K[1][j] - 36.0 * K[2][j] + 63.0 * K[3][j]
                                 + 72.0 * K[4][j] - 64.0 * K[6][j]);
        rhs(m, z, bl, bn, K[7], 1);
        for (int j = 0; j < HOVER_NX; j++)
            y[j] = y[j] + h120 * (11.0 * (K[1][j] + K[7][j]) + 81.0 * (K[3][j] + K[4][j])
                                  - 32.0 * (K[5][j] + K[6][j]));
    }
}

/* "state overflow: <why>, with <the controls>" (the pythonfmu slave's wording) */
static void overflow(const Instance *c, const char *what, char *why) {
    char inputs[320] = "", v[32];
    for (int j = 0; j < 7; j++) {
        size_t len = strlen(inputs);
        fmu_repr(v, sizeof v, c->s.r[CONTROLS[j]]);
        snprintf(inputs + len, sizeof inputs - len, "%s%s = %s", j ? ", " : "",
                 VAR_NAME[CONTROLS[j]], v);
    }
    snprintf(why, FMU_WHY, "state overflow: %s, with %s", what, inputs);
}

int model_advance(Instance *c, double t, double h_s, char *why, int *warned) {
    HoverState *m = &c->s.model;
    const double *r = c->s.r;
    char what[FMU_WHY], hb[32], a[32], list[256];
    (void)t; (void)warned;
    if (fmu_check_finite(c, CONTROLS, 7, why)) return 1;
    double h_wb = h_s * m->n;
    fmu_repr(hb, sizeof hb, h_wb);
    if (!(isfinite(h_wb) && h_wb > 0.0)) {
        snprintf(what, sizeof what, "step = %s wing beats must be finite and > 0", hb);
        overflow(c, what, why);
        return 1;
    }
    double bl[3], bn[3];
    for (int i = 0; i < 3; i++) { /* rigid_body._dot: from 0.0, left to right */
        double s = 0.0;
        for (int j = 0; j < 3; j++) s = s + m->lb[i][j] * r[CONTROLS[j]];
        bl[i] = s;
        s = 0.0;
        for (int j = 0; j < 4; j++) s = s + m->nb[i][j] * r[CONTROLS[3 + j]];
        bn[i] = s;
    }
    const double *x = m->x;
    double rate = sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5]);
    double hmax = rate > 0 ? py_min(MAX_SUBSTEP_WB, MAX_TURN_PER_SUBSTEP_RAD / rate)
                           : MAX_SUBSTEP_WB;
    double n = ceil(h_wb / hmax - 1e-9);
    if (!(n <= MAX_SUBSTEPS)) {
        fmu_repr(a, sizeof a, rate);
        snprintf(what, sizeof what, "a step of %s wing beats at a rate of %s rad per wing beat "
                 "needs %.0f sub-steps; take shorter steps", hb, a, n);
        overflow(c, what, why);
        return 1;
    }
    n = py_max(1.0, n);
    double y[HOVER_NX];
    memcpy(y, x, sizeof y);
    substeps(m, y, n, h_wb / n, bl, bn);
    double norm = sqrt(y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9]);
    int finite = 1;
    for (int j = 0; j < HOVER_NX; j++) finite = finite && isfinite(y[j]);
    if (!finite || !(norm > 0.0)) {
        list_repr(list, sizeof list, x, 6);
        snprintf(what, sizeof what, "the state is not finite after a step of %s wing beats "
                 "(from u, v, w, p, q, r = %s)", hb, list);
        overflow(c, what, why);
        return 1;
    }
    for (int j = 6; j < 10; j++) y[j] = y[j] / norm;
    memcpy(m->x, y, sizeof y);
    write_outputs(c, y);
    return 0;
}
