/* The controller FMUs (native): u = K x+ (Eq. 22) for either axis, as
 * dronefly/models/feedback.py (FeedbackLaw) and dronefly/controller/slave.py compute it: x+
 * from the measured dimensional state (x+_j = x_j / scale_j), each control the row's product
 * summed left to right, an optional limit. The variable table (vars.h) says which axis:
 * CTRL_NU controls, the states and controls' rows, and their reference scales.
 *
 * The sensing delay, sampling and integral action of the pythonfmu controllers
 * (controller/delay.py) are not in the native FMUs: a parameter set that needs them
 * (sensing_delay, sample_period or an integral gain not 0) is refused, naming the value. */
#include "exact.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "fmu.h"

#ifdef VR_delta_Phi_a  /* the lateral axis: x+ = (dv/U, dp/n, dr/n, dgamma) */
#define CTRL_NU 3
#define U0 VR_delta_Phi_a
#define X0 VR_delta_v
static const int SCALE_IS[CTRL_NX] = {1, 2, 2, 0};
#else                  /* the longitudinal axis: x+ = (du/U, dw/U, dq/n, dtheta) */
#define CTRL_NU 4
#define U0 VR_delta_Phi
#define X0 VR_delta_u
static const int SCALE_IS[CTRL_NX] = {1, 1, 2, 0};
#endif
#define K0 VR_K_1_1
#define KI0 VR_KI_1_1

void model_reset(Instance *c) { memset(&c->s.model, 0, sizeof c->s.model); }

static int bad(char *why, const char *name, double v, const char *what) {
    char t[32];
    fmu_repr(t, sizeof t, v);
    snprintf(why, FMU_WHY, "%s = %s %s", name, t, what);
    return 1;
}

int model_refresh(Instance *c, char *why) {
    const double *r = c->s.r;
    ModelState *m = &c->s.model;
    m->valid = 0;
    for (int k = 0; k < CTRL_NU * CTRL_NX; k++) {
        if (!isfinite(r[K0 + k])) return bad(why, VAR_NAME[K0 + k], r[K0 + k], "is not finite");
    }
    for (int k = 0; k < CTRL_NU * CTRL_NX; k++) {
        if (!isfinite(r[KI0 + k]))
            return bad(why, VAR_NAME[KI0 + k], r[KI0 + k], "is not finite");
    }
    const int scales[3] = {VR_n, VR_U, VR_u_max};
    for (int k = 0; k < 3; k++) {
        double v = r[scales[k]];
        if (!(isfinite(v) && v > 0.0))
            return bad(why, VAR_NAME[scales[k]], v, "must be finite and > 0");
    }
    const int timing[2] = {VR_sensing_delay, VR_sample_period};
    for (int k = 0; k < 2; k++) {
        double v = r[timing[k]];
        if (!(isfinite(v) && v >= 0.0))
            return bad(why, VAR_NAME[timing[k]], v, "s must be finite and >= 0");
    }
    if (!DIRECT_FEEDTHROUGH)
        return bad(why, "sensing_delay", r[VR_sensing_delay], "s: the native FMU has no "
                   "sensing delay; use the pythonfmu FMU (docs/native.md)");
    for (int k = 0; k < 2; k++)
        if (r[timing[k]] != 0.0)
            return bad(why, VAR_NAME[timing[k]], r[timing[k]], "s: the native FMU has no "
                       "sensing delay or sampling (0 only); use the pythonfmu FMU "
                       "(docs/native.md)");
    for (int k = 0; k < CTRL_NU * CTRL_NX; k++)
        if (r[KI0 + k] != 0.0)
            return bad(why, VAR_NAME[KI0 + k], r[KI0 + k], "is not 0: the native FMU has no "
                       "integral action; use the pythonfmu FMU (docs/native.md)");
    double n = r[VR_n], U = r[VR_U], scale[CTRL_NX];
    for (int j = 0; j < CTRL_NX; j++)
        scale[j] = SCALE_IS[j] == 1 ? U : SCALE_IS[j] == 2 ? n : 1.0;
    for (int i = 0; i < CTRL_NU; i++) {
        m->active[i] = 0;
        for (int j = 0; j < CTRL_NX; j++) {
            m->Kd[i][j] = r[K0 + i * CTRL_NX + j] / scale[j];
            if (m->Kd[i][j] != 0.0) m->active[i] = 1;
        }
    }
    m->limit = r[VR_limit_enabled] != 0.0;
    m->u_max = r[VR_u_max];
    m->valid = 1;
    return 0;
}

/* the outputs of the inputs now; nothing written if a value is not finite */
static int outputs(Instance *c, char *why) {
    ModelState *m = &c->s.model;
    double *r = c->s.r, u[CTRL_NU];
    int rows[CTRL_NX];
    for (int j = 0; j < CTRL_NX; j++) rows[j] = X0 + j;
    if (fmu_check_finite(c, rows, CTRL_NX, why)) return 1;
    const double *x = r + X0;
    for (int i = 0; i < CTRL_NU; i++) {
        const double *k = m->Kd[i];
        u[i] = m->active[i] ? k[0] * x[0] + k[1] * x[1] + k[2] * x[2] + k[3] * x[3] : 0.0;
        if (!isfinite(u[i]))
            return bad(why, VAR_NAME[U0 + i], u[i], "is not finite (K x+ overflows)");
    }
    int saturated = 0;
    if (m->limit)
        for (int i = 0; i < CTRL_NU; i++) {
            if (u[i] > m->u_max) { u[i] = m->u_max; saturated = 1; }
            else if (u[i] < -m->u_max) { u[i] = -m->u_max; saturated = 1; }
        }
    for (int i = 0; i < CTRL_NU; i++) r[U0 + i] = u[i];
    r[VR_saturated] = saturated ? 1.0 : 0.0;
    return 0;
}

int model_update_outputs(Instance *c, char *why) {
    if (c->dirty || !c->s.model.valid) {
        if (model_refresh(c, why)) return 1;
    }
    return outputs(c, why);
}

int model_initialize(Instance *c, char *why) {
    if (model_refresh(c, why)) return 1;
    return outputs(c, why);
}

int model_advance(Instance *c, double t, double h, char *why, int *warned) {
    (void)t; (void)h; (void)warned;
    return outputs(c, why);  /* the sample at t + h in effect at once: u = K x+ */
}
