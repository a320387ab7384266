/* The hooks of a linear plant FMU (fmu.h), as dronefly/fmu_src/linear_slave.py and
 * dronefly/models/linear.py compute them: the same floats, operation for operation. */
#include "exact.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "fmu.h"
#include "expm.h"

#define NX PLANT_NX
#define NU PLANT_NU
static const int SCALE_KIND[NX] = PLANT_SCALES;

void model_reset(Instance *c) {
    memset(&c->s.model, 0, sizeof c->s.model);
    for (int i = 0; i < NX; i++) c->s.model.scale[i] = 1.0;
    c->s.model.n = 1.0;
}

static int check_rows(const Instance *c, int first, int n, char *why) {
    int rows[8];
    for (int i = 0; i < n; i++) rows[i] = first + i;
    return fmu_check_finite(c, rows, n, why);
}

int model_refresh(Instance *c, char *why) {
    PlantState *m = &c->s.model;
    double A[NX][NX], B[NX][NU];
    if (plant_matrices(c->s.r, A, B, why)) return 1;
    const int ref[2] = {VR_n, VR_U};
    const char *names[2] = {"n", "U"};
    for (int k = 0; k < 2; k++) {
        double v = c->s.r[ref[k]];
        if (!(isfinite(v) && v > 0.0)) {
            char t[32];
            fmu_repr(t, sizeof t, v);
            snprintf(why, FMU_WHY, "%s = %s must be finite and > 0", names[k], t);
            return 1;
        }
    }
    double n = c->s.r[VR_n], U = c->s.r[VR_U];
    memcpy(m->A, A, sizeof A);
    memcpy(m->B, B, sizeof B);
    m->n = n;
    for (int i = 0; i < NX; i++)
        m->scale[i] = SCALE_KIND[i] == SCALE_U ? U : SCALE_KIND[i] == SCALE_N ? n : 1.0;
    m->has_step = 0;
    for (int i = 0; i < NX; i++)
        for (int j = 0; j < NX; j++) c->s.r[PLANT_A0 + i * NX + j] = A[i][j];
    for (int i = 0; i < NX; i++)
        for (int j = 0; j < NU; j++) c->s.r[PLANT_B0 + i * NU + j] = B[i][j];
    return 0;
}

static int starts_to_outputs(Instance *c, char *why) {
    if (check_rows(c, PLANT_START0, NX, why)) return 1;
    for (int i = 0; i < NX; i++) c->s.r[PLANT_X0 + i] = c->s.r[PLANT_START0 + i];
    return 0;
}

int model_update_outputs(Instance *c, char *why) {
    /* before initialization ends the initial unknowns follow the start values and
     * parameters; afterwards only doStep changes the outputs (no direct feedthrough) */
    if (c->s.initialized) return 0;
    if (starts_to_outputs(c, why)) return 1;
    return model_refresh(c, why);
}

int model_initialize(Instance *c, char *why) {
    if (starts_to_outputs(c, why)) return 1;
    if (model_refresh(c, why)) return 1;
    for (int i = 0; i < NX; i++)
        c->s.model.x[i] = c->s.r[PLANT_START0 + i] / c->s.model.scale[i];
    return 0;
}

/* [Phi, Gamma] of a step of h wing beats: the blocks of exp([[A h, B h], [0, 0]]) */
static int make_step(PlantState *m, double h, char *why) {
    double ah[NX * NX], bh[NX * NU], phi[NX * NX], gamma[NX * NU];
    int finite = 1;
    for (int i = 0; i < NX; i++) {
        for (int j = 0; j < NX; j++) {
            ah[i * NX + j] = m->A[i][j] * h;
            if (!isfinite(ah[i * NX + j])) finite = 0;
        }
        for (int j = 0; j < NU; j++) {
            bh[i * NU + j] = m->B[i][j] * h;
            if (!isfinite(bh[i * NU + j])) finite = 0;
        }
    }
    if (!finite) {
        snprintf(why, FMU_WHY, "expm needs finite entries");
        return 1;
    }
    fmu_expm_hold(ah, bh, NX, NU, phi, gamma);
    m->step_finite = 1;
    m->phi_finite = 1;
    for (int i = 0; i < NX; i++)
        for (int j = 0; j < NX + NU; j++) {
            m->M[i][j] = j < NX ? phi[i * NX + j] : gamma[i * NU + j - NX];
            if (!isfinite(m->M[i][j])) {
                m->step_finite = 0;
                if (j < NX) m->phi_finite = 0;
            }
        }
    m->h_wb = h;
    m->has_step = 1;
    return 0;
}

int model_advance(Instance *c, double t, double h_s, char *why, int *warned) {
    PlantState *m = &c->s.model;
    double *r = c->s.r;
    double h = h_s * m->n;
    (void)t; (void)warned;
    if (!m->has_step || m->h_wb != h) {
        if (make_step(m, h, why)) return 1;
    }
    double u[NU], xn[NX], y[NX];
    for (int j = 0; j < NU; j++) u[j] = r[PLANT_U0 + j];
    if (check_rows(c, PLANT_U0, NU, why)) return 1;
    if (!m->step_finite) {
        int zero = 1;
        for (int i = 0; i < NX; i++) zero = zero && m->x[i] == 0.0;
        for (int j = 0; j < NU; j++) zero = zero && u[j] == 0.0;
        if (zero) { /* only the zero solution is representable, and it stays zero */
            for (int i = 0; i < NX; i++) r[PLANT_X0 + i] = 0.0 * m->scale[i];
            return 0;
        }
        char hb[32];
        fmu_repr(hb, sizeof hb, h);
        if (m->phi_finite)
            snprintf(why, FMU_WHY, "a step of %s wing beats overflows the hold of the controls "
                     "(Gamma = the integral of exp(%s s) over the step, times %s; exp(%s h) is "
                     "finite, %s h too large for the float range), so only the zero state has a "
                     "representable result; take shorter steps or smaller control derivatives",
                     hb, PLANT_A_NAME, PLANT_B_NAME, PLANT_A_NAME, PLANT_B_NAME);
        else
            snprintf(why, FMU_WHY, "a step of %s wing beats overflows exp(%s h), so only the "
                     "zero state has a representable result; take shorter steps", hb,
                     PLANT_A_NAME);
        return 1;
    }
    for (int i = 0; i < NX; i++) {
        const double *a = m->M[i];
        double s = a[0] * m->x[0];  /* left to right, as written out in the Python */
        for (int j = 1; j < NX; j++) s = s + a[j] * m->x[j];
        for (int j = 0; j < NU; j++) s = s + a[NX + j] * u[j];
        xn[i] = s;
        y[i] = s * m->scale[i];
    }
    for (int i = 0; i < NX; i++) {
        if (!isfinite(y[i])) {
            char list[256] = "[", v[32], hb[32];
            for (int k = 0; k < NX; k++) {
                fmu_repr(v, sizeof v, y[k]);
                size_t len = strlen(list);
                snprintf(list + len, sizeof list - len, "%s%s", k ? ", " : "", v);
            }
            size_t len = strlen(list);
            snprintf(list + len, sizeof list - len, "]");
            fmu_repr(hb, sizeof hb, h_s);
            char inputs[256] = "";
            for (int j = 0; j < NU; j++) {
                fmu_repr(v, sizeof v, u[j]);
                len = strlen(inputs);
                snprintf(inputs + len, sizeof inputs - len, "%s%s = %s", j ? ", " : "",
                         VAR_NAME[PLANT_U0 + j], v);
            }
            snprintf(why, FMU_WHY, "state overflow: outputs %s after a step of %s s with %s "
                     "(the linear model is far outside its range)", list, hb, inputs);
            return 1;
        }
    }
    for (int i = 0; i < NX; i++) {
        m->x[i] = xn[i];
        r[PLANT_X0 + i] = y[i];
    }
    return 0;
}
