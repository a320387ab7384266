/* The controller FMUs (native): u = K x+_s + KI z (Eq. 22) for either axis, with a sensing
 * delay, sampling and integral action, as dronefly/models/feedback.py (FeedbackLaw),
 * dronefly/controller/delay.py (Sensor), dronefly/controller/timing.py (Timing) and
 * dronefly/controller/slave.py compute them, operation for operation. The variable table
 * (vars.h) says which axis and whether the FMU declares direct feedthrough.
 */
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
#define NX CTRL_NX

/* dronefly.controller.timing */
#define TOLERANCE 1e-9
#define DRIFT 2.220446049250313e-16 /* 2**-52 */
#define DRIFT_CAP 5e-5
#define GRID_STEPS 2000
/* Python's math.ceil, math.floor and round return integers, which have no negative zero */
#define ICEIL(x) (ceil(x) + 0.0)
#define IFLOOR(x) (floor(x) + 0.0)
#define IROUND(x) (nearbyint(x) + 0.0)

static int text(char *why, const char *name, double v, const char *what) {
    char t[32];
    fmu_repr(t, sizeof t, v);
    snprintf(why, FMU_WHY, "%s = %s %s", name, t, what);
    return 1;
}

/* ---- the sensor (delay.py) ----------------------------------------------------------------- */
static void sensor_init(Sensor *s, double t0) {
    int off = s->off_grid == 2 ? 2 : 0; /* the warning belongs to the instance */
    memset(s, 0, sizeof *s);
    s->t0 = t0;
    s->t_base = t0;
    s->t_effect = t0;
    s->off_grid = off;
}

static int same(const double *a, const double *b) {
    for (int j = 0; j < NX; j++)
        if (a[j] != b[j]) return 0;
    return 1;
}

static void integral(const Sensor *s, double t, double *z) {
    if (t == s->t_base || !s->integrating) {
        memcpy(z, s->z0, sizeof s->z0);
        return;
    }
    double dt = (t - s->t_base) * s->n;
    for (int j = 0; j < NX; j++) z[j] = s->z0[j] + s->x_plus[j] * dt;
}

static int switch_to(Sensor *s, double t, const double *x, const double *scale, double n,
                     char *why) {
    double xs[NX];
    memcpy(xs, x, sizeof xs);
    if (!s->integrating) {
        memcpy(s->held, xs, sizeof xs);
        return 0;
    }
    double z[NX];
    integral(s, t, z);
    for (int j = 0; j < NX; j++)
        if (!isfinite(z[j])) {
            char v[32], tt[32];
            fmu_repr(v, sizeof v, z[j]);
            fmu_repr(tt, sizeof tt, t);
            snprintf(why, FMU_WHY, "the integral state z%d = %s (of x+%d) overflows at t = %s s: "
                     "the sensed state is far outside the linear range", j + 1, v, j + 1, tt);
            return 1;
        }
    memcpy(s->z0, z, sizeof z);
    s->t_base = t;
    memcpy(s->held, xs, sizeof xs);
    memcpy(s->scale, scale, sizeof s->scale);
    s->has_scale = 1;
    s->n = n;
    for (int j = 0; j < NX; j++) s->x_plus[j] = xs[j] / scale[j];
    return 0;
}

static Sample *front(Sensor *s) { return &s->line[s->head]; }

static int push(Sensor *s, const Sample *e) {
    if (s->count >= CTRL_LINE) return 1;
    s->line[(s->head + s->count) % CTRL_LINE] = *e;
    s->count++;
    return 0;
}

static void pop(Sensor *s) {
    s->head = (s->head + 1) % CTRL_LINE;
    s->count--;
}

static void too_long(char *why, double d, double period, double h, int samples) {
    char a[32], b[32], c[32];
    fmu_repr(a, sizeof a, d);
    fmu_repr(b, sizeof b, period);
    fmu_repr(c, sizeof c, h);
    snprintf(why, FMU_WHY, "sensing_delay = %s s with sample_period = %s s and a communication "
             "step of %s s needs a delay line of more than %d samples (memory bound): use a "
             "longer sample_period or communication step", a, b, c, samples);
}

static void mark_off_grid(Sensor *s, int effect, double instant, double t, double h) {
    if (s->off_grid != 0) return;
    s->off_grid = 1;
    s->off_grid_effect = effect;
    s->og_instant = instant;
    s->og_t = t;
    s->og_h = h;
}

/* The first sample instant in [t, end) not taken yet: 1 and *ts; 0 none (or several, appended
 * to the line here); -1 the line is full (the caller refuses the step). */
static int instant(Sensor *s, double t, double h, double end, double tol, double period,
                   const double *x, double *ts) {
    if (period <= tol) {
        s->has_k = 0;
        *ts = t;
        return 1;
    }
    double k_end = ICEIL((end - tol - s->t0) / period), k;
    if (!isfinite(k_end)) { s->has_k = 0; *ts = t; return 1; } /* beyond float range */
    if (!s->has_k || s->last_period != period) {
        k = ICEIL((t - tol - s->t0) / period);
    } else {
        double wide = tol > TOLERANCE * s->h + s->drift ? tol : TOLERANCE * s->h + s->drift;
        double k2 = ICEIL((t - wide - s->t0) / period);
        k = s->last_k + 1.0 > k2 ? s->last_k + 1.0 : k2;
    }
    if (!isfinite(k)) { s->has_k = 0; *ts = t; return 1; }
    if (k_end - k != 1.0) {
        if (k >= k_end) return 0;
        double first = s->t0 + k * period; /* several instants: the second inside the step */
        s->has_k = 1;
        s->last_k = k_end - 1.0;
        s->last_period = period;
        mark_off_grid(s, 0, first > t + tol ? first : first + period, t, h);
        if (s->count >= CTRL_LINE) { *ts = first; return -1; }
        Sample e;
        memset(&e, 0, sizeof e);
        e.ts = first;
        memcpy(e.x, x, sizeof e.x);
        e.multi = 1;
        e.last = s->t0 + (k_end - 1.0) * period;
        e.period = period;
        push(s, &e);
        return 0;
    }
    *ts = s->t0 + k * period;
    s->has_k = 1;
    s->last_k = k;
    s->last_period = period;
    if (*ts > t + tol) mark_off_grid(s, 0, *ts, t, h);
    return 1;
}

/* One communication step [t, t + h) with the input x held (Sensor.advance); on an error
 * the caller restores the sensor. */
static int advance(Sensor *s, double t, double h, const double *x, const double *scale,
                   double n, double d, double period, int integrate, char *why) {
    double at = t > 0.0 ? t : -t;
    double drift = DRIFT * at * (t - s->t0) / h;
    if (drift > DRIFT_CAP * h) drift = DRIFT_CAP * h;
    double tol = TOLERANCE * h + drift, end = t + h;
    if (integrate != s->integrating) {
        double held[NX];
        memcpy(held, s->held, sizeof held);
        if (s->integrating && switch_to(s, t, held, scale, n, why)) return 1;
        s->integrating = integrate;
        s->t_base = t;
        if (integrate && switch_to(s, t, held, scale, n, why)) return 1;
    } else if (integrate) {
        int changed = !s->has_scale || s->n != n;
        for (int j = 0; j < NX && !changed; j++) changed = s->scale[j] != scale[j];
        if (changed) {
            double held[NX];
            memcpy(held, s->held, sizeof held);
            if (switch_to(s, t, held, scale, n, why)) return 1;
        }
    }
    if (s->count == 0 && d <= tol && period <= tol) { /* the sample at t in effect at t */
        if (!same(x, s->held) && switch_to(s, t, x, scale, n, why)) return 1;
        s->has_k = 0;
        s->h = h;
        s->drift = drift;
        s->t_effect = t;
        s->has_current = 0;
        return 0;
    }
    double ts;
    int got = instant(s, t, h, end, tol, period, x, &ts);
    if (got < 0) { too_long(why, d, period, h, CTRL_LINE); return 1; }
    if (got > 0) {
        Sample e;
        memset(&e, 0, sizeof e);
        e.ts = ts;
        memcpy(e.x, x, sizeof e.x);
        if (push(s, &e)) { too_long(why, d, period, h, CTRL_LINE); return 1; }
    }
    while (s->count > 0) {
        Sample entry = *front(s);
        double e = entry.ts + d;
        if (e > end + tol) break;
        if (e < t + tol) e = t;
        else if (e > end - tol) e = end;
        else mark_off_grid(s, 1, e, t, h);
        pop(s);
        if (!same(entry.x, s->held) && switch_to(s, e, entry.x, scale, n, why)) return 1;
        s->t_effect = e;
        s->current = entry;
        s->has_current = 1;
    }
    s->h = h;
    s->drift = drift;
    return 0;
}

static int is_instant(const Sensor *s, double t, double period) {
    double tol = TOLERANCE * s->h + s->drift;
    if (period <= tol) return 1;
    double q = (t - s->t0) / period;
    if (!isfinite(q)) return 1;
    double k = IROUND(q); /* Python's round: half to even */
    return fabs(s->t0 + k * period - t) <= tol;
}

static int sample_now(const Sensor *s, double t, double d, double period) {
    return DIRECT_FEEDTHROUGH && d <= TOLERANCE * s->h + s->drift && is_instant(s, t, period);
}

static void integral_in_effect(const Sensor *s, double t, double d, double period, double *z) {
    if (sample_now(s, t, d, period)) {
        integral(s, t, z);
        return;
    }
    double te = s->t_effect;
    if (s->has_current && s->current.multi) {
        double first = s->current.ts, last = s->current.last, p = s->current.period;
        double tol = TOLERANCE * s->h + s->drift;
        double j1 = IROUND((last - first) / p), j2 = IFLOOR((t + tol - d - first) / p);
        double j = j1 < j2 ? j1 : j2;
        double e = first + j * p + d;
        double cand = e > t - tol ? t : e;
        if (cand > te) te = cand;
    }
    integral(s, te > s->t_base ? te : s->t_base, z);
}

/* ---- the law (feedback.py) ------------------------------------------------------------ */
void model_reset(Instance *c) { memset(&c->s.model, 0, sizeof c->s.model); }

int model_refresh(Instance *c, char *why) {
    const double *r = c->s.r;
    ModelState *m = &c->s.model;
    m->valid = 0;
    for (int k = 0; k < CTRL_NU * NX; k++)
        if (!isfinite(r[K0 + k])) return text(why, VAR_NAME[K0 + k], r[K0 + k], "is not finite");
    for (int k = 0; k < CTRL_NU * NX; k++)
        if (!isfinite(r[KI0 + k]))
            return text(why, VAR_NAME[KI0 + k], r[KI0 + k], "is not finite");
    const int scales[3] = {VR_n, VR_U, VR_u_max};
    for (int k = 0; k < 3; k++) {
        double v = r[scales[k]];
        if (!(isfinite(v) && v > 0.0))
            return text(why, VAR_NAME[scales[k]], v, "must be finite and > 0");
    }
    const int timing[2] = {VR_sensing_delay, VR_sample_period};
    for (int k = 0; k < 2; k++) {
        double v = r[timing[k]];
        if (!(isfinite(v) && v >= 0.0))
            return text(why, VAR_NAME[timing[k]], v, "s must be finite and >= 0");
    }
    if (!DIRECT_FEEDTHROUGH && !(r[VR_sensing_delay] > 0.0))
        return text(why, "sensing_delay", r[VR_sensing_delay], "s must be > 0 in this FMU (it "
                    "declares no direct feedthrough; the FMU of the same name without "
                    "'Delayed' takes 0)");
    double n = r[VR_n], U = r[VR_U];
    for (int j = 0; j < NX; j++)
        m->scale[j] = SCALE_IS[j] == 1 ? U : SCALE_IS[j] == 2 ? n : 1.0;
    m->n = n;
    m->has_integral = 0;
    for (int i = 0; i < CTRL_NU; i++) {
        m->active[i] = 0;
        for (int j = 0; j < NX; j++) {
            m->Kd[i][j] = r[K0 + i * NX + j] / m->scale[j];
            if (m->Kd[i][j] != 0.0) m->active[i] = 1;
            m->KI[i][j] = r[KI0 + i * NX + j];
            if (m->KI[i][j] != 0.0) m->has_integral = 1;
        }
    }
    m->limit = r[VR_limit_enabled] != 0.0;
    m->u_max = r[VR_u_max];
    m->delay = r[VR_sensing_delay];
    m->period = r[VR_sample_period];
    m->valid = 1;
    return 0;
}

static int immediate(const ModelState *m) { return m->delay == 0.0 && m->period == 0.0; }

/* the outputs at the communication point t; nothing written on an error */
static int outputs_at(Instance *c, double t, char *why) {
    ModelState *m = &c->s.model;
    Sensor *s = &m->sensor;
    double *r = c->s.r, u[CTRL_NU];
    const double *live = r + X0;
    const double *x = (immediate(m) && DIRECT_FEEDTHROUGH) || sample_now(s, t, m->delay, m->period)
                      ? live : s->held;
    int rows[NX];
    for (int j = 0; j < NX; j++) rows[j] = X0 + j;
    if (x == live && fmu_check_finite(c, rows, NX, why)) return 1;
    for (int i = 0; i < CTRL_NU; i++) {
        const double *k = m->Kd[i];
        u[i] = m->active[i] ? k[0] * x[0] + k[1] * x[1] + k[2] * x[2] + k[3] * x[3] : 0.0;
    }
    if (m->has_integral) {
        double z[NX];
        integral_in_effect(s, t, m->delay, m->period, z);
        for (int i = 0; i < CTRL_NU; i++) {
            double acc = m->KI[i][0] * z[0]; /* sum(map(mul, KI row, z)), left to right */
            for (int j = 1; j < NX; j++) acc = acc + m->KI[i][j] * z[j];
            u[i] = u[i] + acc;
        }
    }
    for (int i = 0; i < CTRL_NU; i++)
        if (!isfinite(u[i]))
            return text(why, VAR_NAME[U0 + i], u[i], m->has_integral
                        ? "is not finite (K x+ + KI z overflows)" : "is not finite (K x+ overflows)");
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
    return outputs_at(c, c->s.time, why);
}

int model_initialize(Instance *c, char *why) {
    sensor_init(&c->s.model.sensor, c->s.time);
    if (model_refresh(c, why)) return 1;
    return outputs_at(c, c->s.time, why);
}

/* the latency the importer sees (Timing.seen_latency): the shortest and longest */
static void seen_latency(double d, double period, double h, double *lo, double *hi) {
    double tol = TOLERANCE * h;
    *lo = INFINITY;
    *hi = -INFINITY;
    int any = 0;
    for (int m = 0; m < GRID_STEPS; m++) {
        double t = m * h, v;
        if (!isfinite(t + h)) break;
        double ts = period <= tol ? t : ICEIL((t - tol) / period) * period;
        if (!isfinite(ts)) { v = INFINITY; }
        else if (ts < t + h - tol) {
            double q = ICEIL((ts + d - tol) / h);
            v = isfinite(q) ? q * h - t : INFINITY;
        } else continue;
        any = 1;
        if (v < *lo) *lo = v;
        if (v > *hi) *hi = v;
    }
    if (!any) *lo = *hi = INFINITY;
}

static void warn_off_grid(Instance *c) {
    ModelState *m = &c->s.model;
    Sensor *s = &m->sensor;
    char msg[2 * FMU_WHY], seen[160], a[32], b[32], hh[32], in[32], tt[32];
    double h = s->og_h, lo, hi;
    s->off_grid = 2;
    seen_latency(m->delay, m->period, h, &lo, &hi);
    if (!isfinite(lo))
        snprintf(seen, sizeof seen, "more than %d steps later (or beyond float range)",
                 GRID_STEPS);
    else if (!isfinite(hi))
        snprintf(seen, sizeof seen, "%.4g steps (%.6g s) or more later", lo / h, lo);
    else if (hi - lo <= TOLERANCE * h)
        snprintf(seen, sizeof seen, "%.4g step(s) (%.6g s) later", lo / h, lo);
    else
        snprintf(seen, sizeof seen, "%.4g to %.4g steps (%.6g to %.6g s) later", lo / h,
                 hi / h, lo, hi);
    fmu_repr(a, sizeof a, m->delay);
    fmu_repr(b, sizeof b, m->period);
    fmu_repr(hh, sizeof hh, h);
    fmu_repr(in, sizeof in, s->og_instant);
    fmu_repr(tt, sizeof tt, s->og_t);
    snprintf(msg, sizeof msg, "sensing_delay = %s s and sample_period = %s s on a communication "
             "step of %s s: %s (t = %s s) falls inside the step from %s s. Inputs are constant "
             "over a communication step (%s co-simulation), so the FMU samples the input held "
             "since the start of the step, and a control that takes effect inside a step is "
             "visible from the next communication point on: at this step size the importer sees "
             "the control of an input set at a communication point %s, instead of sensing_delay. "
             "Values are computed this way, not refused; make both whole numbers of steps to get "
             "them exactly (warned once per instance)", a, b, hh,
             s->off_grid_effect ? "an effect instant" : "a sample instant", in, tt,
             FMI_VERSION == 3 ? "FMI 3.0" : "FMI 2.0", seen);
    fmu_warn(c, msg);
}

int model_advance(Instance *c, double t, double h, char *why, int *warned) {
    ModelState *m = &c->s.model;
    Sensor *s = &m->sensor;
    double x[NX];
    memcpy(x, c->s.r + X0, sizeof x);
    (void)warned;
    if (immediate(m) && !m->has_integral && !s->integrating && s->count == 0) {
        /* the sample at t in effect at once: u = K x+ of the inputs (Eq. 22) */
        double held[NX], oh = s->h;
        int ok = s->has_k;
        memcpy(held, s->held, sizeof held);
        memcpy(s->held, x, sizeof x);
        s->h = h;
        s->has_k = 0;
        if (outputs_at(c, t + h, why)) { /* a refused step changes nothing */
            memcpy(s->held, held, sizeof held);
            s->h = oh;
            s->has_k = ok;
            return 1;
        }
        return 0;
    }
    int rows[NX];
    for (int j = 0; j < NX; j++) rows[j] = X0 + j;
    if (fmu_check_finite(c, rows, NX, why)) return 1;
    if (m->delay > (double)100000 * (h > m->period ? h : m->period)) {
        too_long(why, m->delay, m->period, h, 100000);
        return 1;
    }
    Sensor before = *s;
    if (advance(s, t, h, x, m->scale, m->n, m->delay, m->period, m->has_integral, why) ||
        outputs_at(c, t + h, why)) {
        *s = before; /* a refused step changes nothing */
        return 1;
    }
    if (s->off_grid == 1) warn_off_grid(c);
    return 0;
}
