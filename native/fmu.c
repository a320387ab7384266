/* The FMI 2.0 and 3.0 Co-Simulation interface of a dronefly-fmu native FMU: the plumbing,
 * written once from the standards (FMI 2.0.4 chapters 2 and 4, FMI 3.0 chapters 2 and 4) for
 * every model (fmu.h). Compiled with -DFMI_VERSION=2 or 3; the two versions share every function
 * below the FMI wrappers. The behaviour follows the pythonfmu FMUs (dronefly/fmi/): the same
 * call-sequence table, the same refusals with the same messages, a step refused for a bad
 * value (a NaN input) is Discard and changes nothing, and no call can crash the host: every
 * argument is checked before it is used.
 */
#include "exact.h"
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef FMI_VERSION
#define FMI_VERSION 2
#endif
#if FMI_VERSION == 3
#include "fmi3Functions.h"
#else
#include "fmi2Functions.h"
#endif
#include "fmu.h"

enum { ST_OK = 0, ST_WARNING = 1, ST_DISCARD = 2, ST_ERROR = 3, ST_FATAL = 4 };
#define BATCH_LIMIT 256

#if FMI_VERSION == 3
#define FMI "fmi3"
#define FMI_TEXT "FMI 3.0"
#define STATE_API "FMUState"
#define ILLEGAL ST_ERROR /* FMI 3.0 2.2.4: an illegal call or argument is fmi3Error */
#define T_REAL "Float64"
#define T_INTEGER "Int32"
#else
#define FMI "fmi2"
#define FMI_TEXT "FMI 2.0"
#define STATE_API "FMUstate"
#define ILLEGAL ST_DISCARD /* as the pythonfmu FMUs (the instance is unchanged either way) */
#define T_REAL "Real"
#define T_INTEGER "Integer"
#endif

static const char *const MODE_NAMES[] = {"instantiated", "initialization", "stepping",
                                         "terminated"};

/* ---- messages ---------------------------------------------------------------------- */
void fmu_repr(char *buf, size_t n, double x) {
    /* Python's repr: the shortest digits that read back; positional where the decimal
     * exponent is in [-4, 16), with a point (1000.0, 0.0001), else 1e+16 and 1e-05 */
    if (n == 0) return;
    if (isnan(x)) { snprintf(buf, n, "nan"); return; }
    if (isinf(x)) { snprintf(buf, n, x > 0 ? "inf" : "-inf"); return; }
    char e_form[40];
    int digits = 1;
    for (; digits <= 17; digits++) {
        snprintf(e_form, sizeof e_form, "%.*e", digits - 1, x);
        if (strtod(e_form, NULL) == x) break;
    }
    if (digits > 17) digits = 17;
    int exponent = atoi(strchr(e_form, 'e') + 1);
    if (exponent < -4 || exponent >= 16) {
        snprintf(buf, n, "%s", e_form);
        return;
    }
    int decimals = digits - 1 - exponent;
    snprintf(buf, n, "%.*f", decimals > 0 ? decimals : 0, x);
    if (!strchr(buf, '.')) {
        size_t len = strlen(buf);
        if (len + 2 < n) { buf[len] = '.'; buf[len + 1] = '0'; buf[len + 2] = '\0'; }
    }
}

static void log_message(Instance *c, int status, const char *category, const char *msg) {
    if (c == NULL || c->logger == NULL) return;
    /* "<instance>: <message>"; FMI 2.0's logger reads it as a printf format: % escaped */
    char text[4 * FMU_WHY];
    size_t k = 0;
    const char *parts[3] = {c->name, ": ", msg};
    for (int p = 0; p < 3; p++)
        for (const char *s = parts[p]; *s && k + 2 < sizeof text; s++) {
            if (*s == '%' && FMI_VERSION == 2) text[k++] = '%';
            text[k++] = *s;
        }
    text[k] = '\0';
#if FMI_VERSION == 3
    ((fmi3LogMessageCallback)c->logger)(c->env, (fmi3Status)status, category, text);
#else
    ((fmi2CallbackLogger)c->logger)(c->env, c->name, (fmi2Status)status, category, text);
#endif
}

static const char *category_of(int status) {
    return status == ST_WARNING ? "logStatusWarning"
         : status == ST_DISCARD ? "logStatusDiscard" : "logStatusError";
}

static void report(Instance *c, int status, const char *msg) {
    log_message(c, status, category_of(status), msg);
}

void fmu_warn(Instance *c, const char *msg) { report(c, ST_WARNING, msg); }

static void add_pending(Instance *c, const char *msg) {
    size_t len = strlen(c->s.pending);
    if (len == 0) {
        snprintf(c->s.pending, sizeof c->s.pending, "%s", msg);
    } else if (len + 3 < sizeof c->s.pending) {
        snprintf(c->s.pending + len, sizeof c->s.pending - len, "; %s", msg);
    }
}

int fmu_check_finite(const Instance *c, const int *rows, int n, char *why) {
    for (int i = 0; i < n; i++) {
        double x = c->s.r[rows[i]];
        if (!isfinite(x)) {
            char v[32];
            fmu_repr(v, sizeof v, x);
            snprintf(why, FMU_WHY, "%s = %s is not finite", VAR_NAME[rows[i]], v);
            return 1;
        }
    }
    return 0;
}

/* ---- the call-sequence table (dronefly/fmi/calls.py ALLOWED) ------------------------ */
enum { CALL_SETUP, CALL_ENTER_INIT, CALL_EXIT_INIT, CALL_TERMINATE, CALL_DO_STEP, CALL_GET };
static const char *const CALL_NAMES[] = {"SetupExperiment", "EnterInitializationMode",
    "ExitInitializationMode", "Terminate", "DoStep", "Get"};
static const int ALLOWED[][3] = {
    {MODE_INSTANTIATED, -1, -1}, {MODE_INSTANTIATED, -1, -1}, {MODE_INITIALIZATION, -1, -1},
    {MODE_STEPPING, -1, -1}, {MODE_STEPPING, -1, -1},
    {MODE_INITIALIZATION, MODE_STEPPING, MODE_TERMINATED}};

static int in_state(Instance *c, int call, const char *name) {
    const int *ok = ALLOWED[call];
    char msg[FMU_WHY], list[96] = "";
    for (int k = 0; k < 3; k++) {
        if (ok[k] == c->s.mode) return 1;
        if (ok[k] >= 0) {
            size_t len = strlen(list);
            snprintf(list + len, sizeof list - len, "%s%s", len ? ", " : "", MODE_NAMES[ok[k]]);
        }
    }
    if (name == NULL) name = CALL_NAMES[call];
    snprintf(msg, sizeof msg, "%s%s is not allowed in state '%s' (%s co-simulation call "
             "sequence: only in %s); ignored", name == CALL_NAMES[call] ? FMI : "", name,
             MODE_NAMES[c->s.mode], FMI_TEXT, list);
    if (call != CALL_DO_STEP && call != CALL_GET) add_pending(c, msg);
    report(c, ST_ERROR, msg);
    return 0;
}

/* ---- lifecycle ---------------------------------------------------------------------- */
static void fresh_state(Instance *c) {
    memcpy(c->s.r, VAR_START, sizeof c->s.r);
    c->s.mode = MODE_INSTANTIATED;
    c->s.time = 0.0;
    c->s.has_stop = 0;
    c->s.stop_time = 0.0;
    c->s.initialized = 0;
    c->s.pending[0] = '\0';
    c->dirty = 1;
    c->stale = 1;
    model_reset(c);
}

static void free_states(Instance *c);

static Instance *instantiate(const char *name, const char *token, void *logger, void *env,
                             int logging_on) {
    if (name == NULL) name = "";
    Instance *c = (Instance *)calloc(1, sizeof(Instance));
    if (c == NULL) return NULL;
    c->name = (char *)malloc(strlen(name) + 1);
    if (c->name == NULL) { free(c); return NULL; }
    strcpy(c->name, name);
    c->logger = logger;
    c->env = env;
    c->logging_on = logging_on;
    if (token == NULL || strcmp(token, MODEL_TOKEN) != 0) {
        char msg[FMU_WHY];
        snprintf(msg, sizeof msg, "%sInstantiate: the %s %s is not this build's %s (%s)", FMI,
                 FMI_VERSION == 3 ? "instantiationToken" : "GUID", token ? token : "(null)",
                 MODEL_TOKEN, MODEL_NAME);
        report(c, ST_ERROR, msg);
        free(c->name);
        free(c);
        return NULL;
    }
    fresh_state(c);
    return c;
}

static void free_instance(Instance *c) {
    if (c == NULL) return;
    free_states(c);
    free(c->name);
    free(c);
}

static int setup_experiment(Instance *c, int has_stop, double start, double stop) {
    if (!in_state(c, CALL_SETUP, NULL)) return ST_ERROR;
    char msg[FMU_WHY], a[32], b[32];
    fmu_repr(a, sizeof a, start);
    fmu_repr(b, sizeof b, stop);
    if (!isfinite(start) || (has_stop && !isfinite(stop))) {
        if (!isfinite(start) && has_stop && !isfinite(stop))
            snprintf(msg, sizeof msg, "%sSetupExperiment: startTime = %s, stopTime = %s refused; "
                     "times must be finite", FMI, a, b);
        else if (!isfinite(start))
            snprintf(msg, sizeof msg, "%sSetupExperiment: startTime = %s refused; times must be "
                     "finite", FMI, a);
        else
            snprintf(msg, sizeof msg, "%sSetupExperiment: stopTime = %s refused; times must be "
                     "finite", FMI, b);
    } else if (has_stop && stop < start) {
        snprintf(msg, sizeof msg, "%sSetupExperiment: stopTime = %s < startTime = %s refused; "
                 "times must be finite", FMI, b, a);
    } else {
        c->s.time = start;
        c->s.has_stop = has_stop;
        c->s.stop_time = has_stop ? stop : 0.0;
        return ST_OK;
    }
    add_pending(c, msg);
    report(c, ST_ERROR, msg);
    return ST_ERROR;
}

static int enter(Instance *c, int call, int mode) {
    if (!in_state(c, call, NULL)) return ST_ERROR;
    c->s.mode = mode;
    return ST_OK;
}

static int exit_initialization(Instance *c) {
    char why[FMU_WHY], msg[FMU_WHY + 32];
    if (!in_state(c, CALL_EXIT_INIT, NULL)) return ST_ERROR;
    c->s.mode = MODE_STEPPING;
    if (model_initialize(c, why) != 0) { /* retried, and reported, by every doStep */
        snprintf(msg, sizeof msg, "initialization: %s", why);
        report(c, ST_ERROR, msg);
        return ST_OK;
    }
    c->s.initialized = 1;
    c->dirty = 0;
    c->stale = 0;
    return ST_OK;
}

static int refuse(Instance *c, int status, const char *msg) {
    report(c, status, msg);
    return status;
}

static int do_step(Instance *c, double t, double h) {
    char msg[2 * FMU_WHY], why[FMU_WHY], a[32], b[32], d[32];
    /* the step's time and size as text, for a refusal only (formatting costs more than the
     * step itself) */
#define TEXTS() (fmu_repr(a, sizeof a, t), fmu_repr(b, sizeof b, h))
    if (c->s.mode != MODE_STEPPING) {
        snprintf(msg, sizeof msg, "%sDoStep is not allowed in state '%s' (%s co-simulation call "
                 "sequence: only after %sExitInitializationMode and before %sTerminate)", FMI,
                 MODE_NAMES[c->s.mode], FMI_TEXT, FMI, FMI);
        return refuse(c, ILLEGAL, msg);
    }
    if (c->s.pending[0]) {
        TEXTS();
        snprintf(msg, sizeof msg, "step refused at t = %s s: %s", a, c->s.pending);
        c->s.pending[0] = '\0';
        return refuse(c, ILLEGAL, msg);
    }
    double end = t + h;
    if (!(isfinite(t) && isfinite(end) && h > 0.0)) {
        TEXTS();
        if (!isfinite(t))
            snprintf(msg, sizeof msg, "currentCommunicationPoint = %s s must be finite", a);
        else
            snprintf(msg, sizeof msg, "communicationStepSize = %s s must be finite and > 0, "
                     "with a finite end (from %s s)", b, a);
        return refuse(c, ILLEGAL, msg);
    }
    double last = c->s.time;
    if (t != last || c->s.has_stop) {
        /* float accumulation of the master's time: relative to the times, never the step */
        double tol = 1e-9 * (fabs(t) + fabs(last)) + 1e-300;
        if (!(fabs(t - last) <= tol)) {
            TEXTS();
            fmu_repr(d, sizeof d, last);
            snprintf(msg, sizeof msg, "currentCommunicationPoint = %s s does not continue from "
                     "the last communication point %s s", a, d);
            return refuse(c, ILLEGAL, msg);
        }
        if (c->s.has_stop && end > c->s.stop_time + tol) {
            TEXTS();
            fmu_repr(d, sizeof d, c->s.stop_time);
            snprintf(msg, sizeof msg, "a step of %s s from %s s goes past stopTime = %s s "
                     "(%s)", b, a, d, FMI_VERSION == 3 ? "fmi3EnterInitializationMode"
                                                        : "fmi2SetupExperiment");
            return refuse(c, ILLEGAL, msg);
        }
    }
    if (!c->s.initialized) {
        if (model_initialize(c, why) != 0) goto refused;
        c->s.initialized = 1;
        c->dirty = 0;
    } else if (c->dirty) {
        if (model_refresh(c, why) != 0) goto refused;
        c->dirty = 0;
    }
    {
        int warned = 0;
        if (model_advance(c, t, h, why, &warned) != 0) goto refused;
        c->s.time = end;
        c->stale = 0;
        return ST_OK;
    }
refused:
    TEXTS();
    snprintf(msg, sizeof msg, "step refused at t = %s s: %s", a, why);
    return refuse(c, ST_DISCARD, msg);
#undef TEXTS
}

static void update_if_stale(Instance *c) {
    char why[FMU_WHY], msg[FMU_WHY + 64];
    if (!c->stale) return;
    c->stale = 0;
    if (model_update_outputs(c, why) != 0) {
        snprintf(msg, sizeof msg, "outputs keep their last valid values: %s", why);
        report(c, ST_ERROR, msg);
    }
}

/* ---- values -------------------------------------------------------------------------- */
enum { KIND_REAL = VT_REAL, KIND_BOOLEAN = VT_BOOLEAN, KIND_INTEGER = VT_INTEGER };
static const char *type_name(int kind) {
    return kind == KIND_REAL ? T_REAL : kind == KIND_BOOLEAN ? "Boolean" : T_INTEGER;
}

static int may_set(int row, int mode) {
    switch (VAR_SET[row]) {
    case VS_INPUT:
    case VS_TUNABLE: return mode != MODE_TERMINATED;
    case VS_FIXED: return mode == MODE_INSTANTIATED || mode == MODE_INITIALIZATION;
    default: return 0;
    }
}

/* the scalar rows of one value reference: FMI 2.0 one row; FMI 3.0 an array's rows */
static int rows_of(unsigned vr, const int **rows) {
#if FMI_VERSION == 3
    if (vr >= (unsigned)N_VARS3) return -1;
    *rows = VAR3_ROWS + VAR3_FIRST[vr];
    return VAR3_COUNT[vr];
#else
    static const int identity = 0;
    (void)identity;
    if (vr >= (unsigned)N_VARS) return -1;
    *rows = NULL;
    return 1;
#endif
}
#if FMI_VERSION == 3
#define ROW(vr, rows, k) ((rows)[k])
#else
#define ROW(vr, rows, k) ((int)(vr))
#endif

static const char *vr_name(unsigned vr, char *buf, size_t n) {
#if FMI_VERSION == 3
    if (vr < (unsigned)N_VARS3) return VAR3_NAME[vr];
#else
    if (vr < (unsigned)N_VARS) return VAR_NAME[vr];
#endif
    snprintf(buf, n, "valueReference %u", vr);
    return buf;
}

/* Read nvr value references of type kind into out (nout values); 0 OK, else an error. */
static int get_values(Instance *c, const unsigned *vr, size_t nvr, int kind, double *out,
                      size_t nout) {
    char msg[FMU_WHY], nb[48];
    if (c->s.mode == MODE_INSTANTIATED) {
        char name[64];
        snprintf(name, sizeof name, "%sGet%s", FMI, type_name(kind));
        in_state(c, CALL_GET, name);
        return ST_ERROR;
    }
    if (nvr > 0 && (vr == NULL || out == NULL)) return ST_ERROR;
    update_if_stale(c);
    size_t k = 0;
    int status = ST_OK;
    for (size_t i = 0; i < nvr; i++) {
        const int *rows;
#if FMI_VERSION == 3
        if (vr[i] == 0 && kind == KIND_REAL) { /* time */
            if (k >= nout) goto too_few;
            out[k++] = c->s.time;
            continue;
        }
#endif
        int n = rows_of(vr[i], &rows);
        int type = n < 0 ? -1 : VAR_TYPE[ROW(vr[i], rows, 0)];
#if FMI_VERSION == 3
        if (vr[i] == 0) type = KIND_REAL;
#endif
        if (n < 0 || type != kind) { /* answered NaN / false / 0 with a logged error */
            if (n < 0)
                snprintf(msg, sizeof msg, "%sGet%s of %s: not a %s variable of this FMU", FMI,
                         type_name(kind), vr_name(vr[i], nb, sizeof nb), type_name(kind));
            else
                snprintf(msg, sizeof msg, "%sGet%s of %s (a %s variable): not a %s variable of "
                         "this FMU", FMI, type_name(kind), vr_name(vr[i], nb, sizeof nb),
                         type_name(type), type_name(kind));
            report(c, ST_ERROR, msg);
            int count = n < 0 ? 1 : n;
            if (k + (size_t)count > nout) goto too_few;
            for (int j = 0; j < count; j++) out[k++] = kind == KIND_REAL ? NAN : 0.0;
            continue;
        }
        if (k + (size_t)n > nout) goto too_few;
        for (int j = 0; j < n; j++) out[k++] = c->s.r[ROW(vr[i], rows, j)];
    }
    if (k != nout) {
        snprintf(msg, sizeof msg, "%sGet%s: %zu values asked for, the value references hold %zu",
                 FMI, type_name(kind), nout, k);
        report(c, ST_ERROR, msg);
        return ST_ERROR;
    }
    return status;
too_few: /* the host's buffer is shorter than the variables asked for: nothing written past it */
    snprintf(msg, sizeof msg, "%sGet%s: nValues = %zu is fewer than the values of the %zu value "
             "references asked for (an array counts all its elements)", FMI, type_name(kind), nout,
             nvr);
    report(c, ST_ERROR, msg);
    return ST_ERROR;
}

static void reject(Instance *c, int kind, unsigned vr, double value, const char *why) {
    char msg[FMU_WHY], v[40], nb[48];
    if (kind == KIND_BOOLEAN) snprintf(v, sizeof v, "%s", value != 0.0 ? "True" : "False");
    else if (kind == KIND_INTEGER) snprintf(v, sizeof v, "%.0f", value);
    else fmu_repr(v, sizeof v, value);
    snprintf(msg, sizeof msg, "%sSet%s: %s = %s rejected: %s", FMI, type_name(kind),
             vr_name(vr, nb, sizeof nb), v, why);
    add_pending(c, msg);
    report(c, ST_ERROR, msg);
}

/* Set values; every value reference is checked before any is set. */
static int set_values(Instance *c, const unsigned *vr, size_t nvr, int kind, const double *in,
                      size_t nin) {
    if (nvr > 0 && (vr == NULL || in == NULL)) return ST_ERROR;
    size_t k = 0;
    int bad = 0;
    for (size_t i = 0; i < nvr; i++) {
        const int *rows;
        int n = rows_of(vr[i], &rows);
        double first = k < nin ? in[k] : 0.0;
        if (n < 0) { reject(c, kind, vr[i], first, "no such variable"); bad = 1; continue; }
#if FMI_VERSION == 3
        if (vr[i] == 0) {
            reject(c, kind, vr[i], first, "not settable (the independent variable)");
            bad = 1; k += 1; continue;
        }
#endif
        int row0 = ROW(vr[i], rows, 0);
        if (VAR_TYPE[row0] != kind) {
            char why[96];
            snprintf(why, sizeof why, "is a %s variable, not %s", type_name(VAR_TYPE[row0]),
                     type_name(kind));
            reject(c, kind, vr[i], first, why);
            bad = 1;
        } else if (!may_set(row0, c->s.mode)) {
            char why[96];
            snprintf(why, sizeof why, "not settable in state '%s'", MODE_NAMES[c->s.mode]);
            reject(c, kind, vr[i], first, why);
            bad = 1;
        }
        k += (size_t)n;
    }
    if (k != nin) {
        char msg[FMU_WHY];
        snprintf(msg, sizeof msg, "%sSet%s: %zu values given, the value references hold %zu",
                 FMI, type_name(kind), nin, k);
        add_pending(c, msg);
        report(c, ST_ERROR, msg);
        return ST_ERROR;
    }
    /* as the pythonfmu FMUs: a value that may not be set is logged (status Error), changes
     * nothing, and the next doStep is refused naming it (the call itself returns OK) */
    if (bad) return ST_OK;
    k = 0;
    for (size_t i = 0; i < nvr; i++) {
        const int *rows;
        int n = rows_of(vr[i], &rows);
        for (int j = 0; j < n; j++) {
            int row = ROW(vr[i], rows, j);
            c->s.r[row] = kind == KIND_BOOLEAN ? (in[k] != 0.0 ? 1.0 : 0.0) : in[k];
            k++;
            if (VAR_SET[row] != VS_INPUT) c->dirty = 1;
        }
    }
    if (DIRECT_FEEDTHROUGH || !c->s.initialized) c->stale = 1;
    return ST_OK;
}

/* ---- FMU states ---------------------------------------------------------------------- */
#define STATE_MAGIC 0x44464c59u /* "DFLY" */
#define STATE_FORMAT 1u
typedef struct StateNode {
    uint32_t magic;
    struct StateNode *next;
    char rejected[FMU_WHY]; /* not empty: bytes that are no state of this FMU, and why */
    Saved saved;
} StateNode;

static uint64_t fnv1a(const unsigned char *p, size_t n) {
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++) { h ^= p[i]; h *= 1099511628211ull; }
    return h;
}

static int owns(Instance *c, const void *state) {
    for (StateNode *s = (StateNode *)c->states; s != NULL; s = s->next)
        if ((const void *)s == state) return 1;
    return 0;
}

static void free_states(Instance *c) {
    StateNode *s = (StateNode *)c->states;
    while (s != NULL) { StateNode *next = s->next; free(s); s = next; }
    c->states = NULL;
}

static int get_state(Instance *c, void **state) {
    if (state == NULL) return ST_ERROR;
    StateNode *s = NULL;
    if (*state != NULL && owns(c, *state)) s = (StateNode *)*state; /* overwrite in place */
    if (s == NULL) {
        s = (StateNode *)calloc(1, sizeof(StateNode));
        if (s == NULL) {
            report(c, ST_ERROR, FMI "Get" STATE_API " failed: out of memory");
            return ST_ERROR;
        }
        s->magic = STATE_MAGIC;
        s->next = (StateNode *)c->states;
        c->states = s;
    }
    s->saved = c->s;
    s->rejected[0] = '\0';
    *state = s;
    return ST_OK;
}

static int set_state(Instance *c, const void *state) {
    if (state == NULL || !owns(c, state)) {
        report(c, ST_ERROR, FMI "Set" STATE_API " refused, the instance is unchanged: not an FMU "
               "state of this instance (never made by it, or freed with " FMI "Free" STATE_API ")");
        return ST_ERROR;
    }
    const StateNode *node = (const StateNode *)state;
    if (node->rejected[0]) {
        char msg[2 * FMU_WHY];
        snprintf(msg, sizeof msg, FMI "Set" STATE_API " refused, the instance is unchanged: %s",
                 node->rejected);
        report(c, ST_ERROR, msg);
        return ST_ERROR;
    }
    c->s = node->saved;
    c->dirty = 1; /* the next doStep rebuilds from the restored values */
    c->stale = 1;
    return ST_OK;
}

static int free_state(Instance *c, void **state) {
    if (state == NULL || *state == NULL) return ST_OK;
    StateNode **p = (StateNode **)&c->states;
    while (*p != NULL && (void *)*p != *state) p = &(*p)->next;
    if (*p == NULL) {
        report(c, ST_ERROR, FMI "Free" STATE_API ": not an FMU state of this instance (already "
               "freed, or made by another)");
        return ST_ERROR;
    }
    StateNode *s = *p;
    *p = s->next;
    free(s);
    *state = NULL;
    return ST_OK;
}

/* serialized: magic, format, size of Saved, FNV-1a of the token, the bytes, their FNV-1a */
#define HEADER_WORDS 4
static size_t serialized_size(void) { return HEADER_WORDS * 8 + sizeof(Saved) + 8; }

static void put64(unsigned char *p, uint64_t v) {
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static uint64_t get64(const unsigned char *p) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = (v << 8) | p[i];
    return v;
}

static int serialize(Instance *c, const void *state, unsigned char *out, size_t size) {
    if (state == NULL || !owns(c, state) || out == NULL || size < serialized_size()) {
        report(c, ST_ERROR, FMI "Serialize" STATE_API ": not an FMU state of this instance, or "
               "the buffer is smaller than " FMI "Serialized" STATE_API "Size");
        return ST_ERROR;
    }
    if (((const StateNode *)state)->rejected[0]) {
        report(c, ST_ERROR, FMI "Serialize" STATE_API ": the state was refused when it was "
               "deserialized");
        return ST_ERROR;
    }
    const Saved *saved = &((const StateNode *)state)->saved;
    put64(out, STATE_MAGIC);
    put64(out + 8, STATE_FORMAT);
    put64(out + 16, sizeof(Saved));
    put64(out + 24, fnv1a((const unsigned char *)MODEL_TOKEN, strlen(MODEL_TOKEN)));
    memcpy(out + HEADER_WORDS * 8, saved, sizeof(Saved));
    put64(out + HEADER_WORDS * 8 + sizeof(Saved),
          fnv1a(out + HEADER_WORDS * 8, sizeof(Saved)));
    return ST_OK;
}

static int deserialize(Instance *c, const unsigned char *in, size_t size, void **state) {
    const char *why = NULL;
    if (state == NULL) return ST_ERROR;
    if (in == NULL || size == 0) why = "0 bytes";
    else if (size != serialized_size() || get64(in) != STATE_MAGIC) why = "not a state of this FMU";
    else if (get64(in + 8) != STATE_FORMAT) why = "another format";
    else if (get64(in + 16) != sizeof(Saved) ||
             get64(in + 24) != fnv1a((const unsigned char *)MODEL_TOKEN, strlen(MODEL_TOKEN)))
        why = "it was saved by another FMU or build";
    else if (get64(in + HEADER_WORDS * 8 + sizeof(Saved)) != fnv1a(in + HEADER_WORDS * 8,
                                                                    sizeof(Saved)))
        why = "the checksum does not match (corrupt bytes)";
    if (why == NULL) {
        Saved saved;
        memcpy(&saved, in + HEADER_WORDS * 8, sizeof(Saved));
        if (saved.mode < MODE_INSTANTIATED || saved.mode > MODE_TERMINATED ||
            !isfinite(saved.time) || saved.pending[FMU_WHY - 1] != '\0') {
            why = "the state's content is not valid";
        } else {
            void *fresh = NULL;
            int st = get_state(c, &fresh);
            if (st != ST_OK) return st;
            ((StateNode *)fresh)->saved = saved;
            *state = fresh;
            return ST_OK;
        }
    }
    /* as the pythonfmu FMUs: a handle that fmi2SetFMUstate refuses, saying why */
    void *handle = NULL;
    int st = get_state(c, &handle);
    if (st != ST_OK) return st;
    snprintf(((StateNode *)handle)->rejected, FMU_WHY, "serialized state refused: %s", why);
    *state = handle;
    return ST_OK;
}

static int reset(Instance *c) {
    fresh_state(c);
    return ST_OK;
}

/* ==== FMI 2.0 ============================================================================ */
#if FMI_VERSION == 2
#define INST ((Instance *)c)
#define CHECK(c) do { if ((c) == NULL) return fmi2Error; } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String categories[]) {
    CHECK(c);
    (void)n; (void)categories;
    INST->logging_on = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)resources; (void)visible;
    void *logger = functions ? (void *)functions->logger : NULL;
    void *env = functions ? functions->componentEnvironment : NULL;
    if (type != fmi2CoSimulation) {
        Instance tmp;
        memset(&tmp, 0, sizeof tmp);
        tmp.name = (char *)(name ? name : "");
        tmp.logger = logger;
        tmp.env = env;
        report(&tmp, ST_ERROR, "fmi2Instantiate: this FMU is for Co-Simulation only");
        return NULL;
    }
    return (fmi2Component)instantiate(name, guid, logger, env, loggingOn);
}

void fmi2FreeInstance(fmi2Component c) { free_instance(INST); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK(c);
    (void)toleranceDefined; (void)tolerance;
    return (fmi2Status)setup_experiment(INST, stopTimeDefined, startTime, stopTime);
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(c);
    return (fmi2Status)enter(INST, CALL_ENTER_INIT, MODE_INITIALIZATION);
}
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(c);
    return (fmi2Status)exit_initialization(INST);
}
fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(c);
    return (fmi2Status)enter(INST, CALL_TERMINATE, MODE_TERMINATED);
}
fmi2Status fmi2Reset(fmi2Component c) { CHECK(c); return (fmi2Status)reset(INST); }

#define BATCH 64
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    CHECK(c);
    return (fmi2Status)get_values(INST, vr, nvr, KIND_REAL, value, nvr);
}
static fmi2Status get_converted(Instance *c, const fmi2ValueReference vr[], size_t nvr,
                                int kind, void *out) {
    if (nvr > 0 && (vr == NULL || out == NULL)) return fmi2Error;
    for (size_t i = 0; i < nvr; i += BATCH) {
        double tmp[BATCH];
        size_t n = nvr - i < BATCH ? nvr - i : BATCH;
        int st = get_values(c, vr + i, n, kind, tmp, n);
        if (st != ST_OK) return (fmi2Status)st;
        for (size_t j = 0; j < n; j++) {
            if (kind == KIND_BOOLEAN) ((fmi2Boolean *)out)[i + j] = tmp[j] != 0.0;
            else ((fmi2Integer *)out)[i + j] = (fmi2Integer)tmp[j];
        }
    }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    CHECK(c);
    return get_converted(INST, vr, nvr, KIND_INTEGER, value);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    CHECK(c);
    return get_converted(INST, vr, nvr, KIND_BOOLEAN, value);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    CHECK(c);
    (void)value;
    if (nvr == 0) return fmi2OK;
    char msg[FMU_WHY], nb[48];
    snprintf(msg, sizeof msg, "fmi2GetString of %s: not a String variable of this FMU",
             vr ? vr_name(vr[0], nb, sizeof nb) : "(null)");
    report(INST, ST_ERROR, msg);
    return fmi2Error;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    CHECK(c);
    return (fmi2Status)set_values(INST, vr, nvr, KIND_REAL, value, nvr);
}
static fmi2Status set_converted(Instance *c, const fmi2ValueReference vr[], size_t nvr,
                                int kind, const void *in) {
    if (nvr > 0 && (vr == NULL || in == NULL)) return fmi2Error;
    double *tmp = (double *)malloc((nvr ? nvr : 1) * sizeof(double));
    if (tmp == NULL) return fmi2Error;
    for (size_t j = 0; j < nvr; j++)
        tmp[j] = kind == KIND_BOOLEAN ? (((const fmi2Boolean *)in)[j] ? 1.0 : 0.0)
                                      : (double)((const fmi2Integer *)in)[j];
    int st = set_values(c, vr, nvr, kind, tmp, nvr);
    free(tmp);
    return (fmi2Status)st;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    CHECK(c);
    return set_converted(INST, vr, nvr, KIND_INTEGER, value);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    CHECK(c);
    return set_converted(INST, vr, nvr, KIND_BOOLEAN, value);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    CHECK(c);
    (void)value;
    if (nvr == 0) return fmi2OK;
    char msg[FMU_WHY], nb[48];
    snprintf(msg, sizeof msg, "fmi2SetString: %s rejected: not a String variable of this FMU",
             vr ? vr_name(vr[0], nb, sizeof nb) : "(null)");
    add_pending(INST, msg);
    report(INST, ST_ERROR, msg);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    CHECK(c);
    return (fmi2Status)get_state(INST, state);
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    CHECK(c);
    return (fmi2Status)set_state(INST, state);
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    CHECK(c);
    return (fmi2Status)free_state(INST, state);
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    CHECK(c);
    if (size == NULL || !owns(INST, state)) return fmi2Error;
    *size = serialized_size();
    return fmi2OK;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte out[],
                                 size_t size) {
    CHECK(c);
    return (fmi2Status)serialize(INST, state, (unsigned char *)out, size);
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in[], size_t size,
                                   fmi2FMUstate *state) {
    CHECK(c);
    return (fmi2Status)deserialize(INST, (const unsigned char *)in, size, state);
}

static fmi2Status unsupported(fmi2Component c, const char *call) {
    char msg[FMU_WHY];
    CHECK(c);
    snprintf(msg, sizeof msg, "%s is not supported by this FMU (see its modelDescription)", call);
    report(INST, ST_ERROR, msg);
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                        size_t nu, const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real dv[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    CHECK(c);
    (void)noSetPrior;
    return (fmi2Status)do_step(INST, t, h);
}
fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStatus");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK(c);
    if (s == fmi2LastSuccessfulTime && value != NULL) { *value = INST->s.time; return fmi2OK; }
    return unsupported(c, "fmi2GetRealStatus");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK(c);
    /* the FMU never ends the simulation itself */
    if (s == fmi2Terminated && value != NULL) { *value = fmi2False; return fmi2OK; }
    return unsupported(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}
#endif /* FMI 2.0 */

/* ==== FMI 3.0 ============================================================================ */
#if FMI_VERSION == 3
#define INST ((Instance *)c)
#define CHECK(c) do { if ((c) == NULL) return fmi3Error; } while (0)

static fmi3Status unsupported(fmi3Instance c, const char *call) {
    char msg[FMU_WHY];
    CHECK(c);
    snprintf(msg, sizeof msg, "%s is not supported by this Co-Simulation FMU", call);
    report(INST, ST_ERROR, msg);
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n,
                               const fmi3String categories[]) {
    CHECK(c);
    (void)n; (void)categories;
    INST->logging_on = on;
    return fmi3OK;
}
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String res,
                                          fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback logger) {
    (void)name; (void)token; (void)res; (void)visible; (void)loggingOn; (void)env; (void)logger;
    return NULL;
}
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String res,
                                         fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturn,
                                         const fmi3ValueReference required[], size_t nrequired,
                                         fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logger,
                                         fmi3IntermediateUpdateCallback update) {
    (void)res; (void)visible; (void)eventModeUsed; (void)earlyReturn; (void)required;
    (void)nrequired; (void)update;
    return (fmi3Instance)instantiate(name, token, (void *)logger, env, loggingOn);
}
fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token,
                                               fmi3String res, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment env,
                                               fmi3LogMessageCallback logger,
                                               fmi3ClockUpdateCallback clock,
                                               fmi3LockPreemptionCallback lock,
                                               fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)res; (void)visible; (void)loggingOn; (void)env;
    (void)logger; (void)clock; (void)lock; (void)unlock;
    return NULL;
}
void fmi3FreeInstance(fmi3Instance c) { free_instance(INST); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK(c);
    (void)toleranceDefined; (void)tolerance;
    if (INST->s.mode == MODE_INSTANTIATED &&
        setup_experiment(INST, stopTimeDefined, startTime, stopTime) != ST_OK)
        return fmi3Error;
    return (fmi3Status)enter(INST, CALL_ENTER_INIT, MODE_INITIALIZATION);
}
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    CHECK(c);
    return (fmi3Status)exit_initialization(INST);
}
fmi3Status fmi3EnterEventMode(fmi3Instance c) { return unsupported(c, "fmi3EnterEventMode"); }
fmi3Status fmi3Terminate(fmi3Instance c) {
    CHECK(c);
    return (fmi3Status)enter(INST, CALL_TERMINATE, MODE_TERMINATED);
}
fmi3Status fmi3Reset(fmi3Instance c) { CHECK(c); return (fmi3Status)reset(INST); }

static fmi3Status get_typed(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                            int kind, void *out, size_t nout, int ctype) {
    CHECK(c);
    if (nout > 0 && out == NULL) return fmi3Error;
    double stack[BATCH_LIMIT];
    double *tmp = nout <= BATCH_LIMIT ? stack : (double *)malloc(nout * sizeof(double));
    if (tmp == NULL) return fmi3Error;
    int st = get_values(INST, vr, nvr, kind, tmp, nout);
    if (st == ST_OK) {
        for (size_t j = 0; j < nout; j++) {
            if (ctype == 0) ((fmi3Float64 *)out)[j] = tmp[j];
            else if (ctype == 1) ((fmi3Boolean *)out)[j] = tmp[j] != 0.0;
            else ((fmi3Int32 *)out)[j] = (fmi3Int32)tmp[j];
        }
    }
    if (tmp != stack) free(tmp);
    return (fmi3Status)st;
}
static fmi3Status set_typed(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                            int kind, const void *in, size_t nin, int ctype) {
    CHECK(c);
    if (nin > 0 && in == NULL) return fmi3Error;
    double stack[BATCH_LIMIT];
    double *tmp = nin <= BATCH_LIMIT ? stack : (double *)malloc(nin * sizeof(double));
    if (tmp == NULL) return fmi3Error;
    for (size_t j = 0; j < nin; j++)
        tmp[j] = ctype == 0 ? ((const fmi3Float64 *)in)[j]
               : ctype == 1 ? (((const fmi3Boolean *)in)[j] ? 1.0 : 0.0)
                            : (double)((const fmi3Int32 *)in)[j];
    int st = set_values(INST, vr, nvr, kind, tmp, nin);
    if (tmp != stack) free(tmp);
    return (fmi3Status)st;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 values[], size_t n) {
    return get_typed(c, vr, nvr, KIND_REAL, values, n, 0);
}
fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Boolean values[], size_t n) {
    return get_typed(c, vr, nvr, KIND_BOOLEAN, values, n, 1);
}
fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Int32 values[], size_t n) {
    return get_typed(c, vr, nvr, KIND_INTEGER, values, n, 2);
}
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t n) {
    return set_typed(c, vr, nvr, KIND_REAL, values, n, 0);
}
fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t n) {
    return set_typed(c, vr, nvr, KIND_BOOLEAN, values, n, 1);
}
fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 values[], size_t n) {
    return set_typed(c, vr, nvr, KIND_INTEGER, values, n, 2);
}

/* the types this FMU has no variable of */
static fmi3Status no_such_type(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               const char *call) {
    char msg[FMU_WHY], nb[48];
    CHECK(c);
    if (nvr == 0) return fmi3OK;
    snprintf(msg, sizeof msg, "%s of %s: the FMU has no variable of this type", call,
             vr ? vr_name(vr[0], nb, sizeof nb) : "(null)");
    if (strncmp(call, "fmi3Set", 7) == 0) add_pending(INST, msg);
    report(INST, ST_ERROR, msg);
    return fmi3Error;
}
#define NO_GET(T, CT) \
    fmi3Status fmi3Get##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, \
                          CT values[], size_t n) { \
        (void)values; (void)n; return no_such_type(c, vr, nvr, "fmi3Get" #T); }
#define NO_SET(T, CT) \
    fmi3Status fmi3Set##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, \
                          const CT values[], size_t n) { \
        (void)values; (void)n; return no_such_type(c, vr, nvr, "fmi3Set" #T); }
NO_GET(Float32, fmi3Float32) NO_GET(Int8, fmi3Int8) NO_GET(UInt8, fmi3UInt8)
NO_GET(Int16, fmi3Int16) NO_GET(UInt16, fmi3UInt16) NO_GET(UInt32, fmi3UInt32)
NO_GET(Int64, fmi3Int64) NO_GET(UInt64, fmi3UInt64) NO_GET(String, fmi3String)
NO_SET(Float32, fmi3Float32) NO_SET(Int8, fmi3Int8) NO_SET(UInt8, fmi3UInt8)
NO_SET(Int16, fmi3Int16) NO_SET(UInt16, fmi3UInt16) NO_SET(UInt32, fmi3UInt32)
NO_SET(Int64, fmi3Int64) NO_SET(UInt64, fmi3UInt64) NO_SET(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         size_t sizes[], fmi3Binary values[], size_t n) {
    (void)sizes; (void)values; (void)n;
    return no_such_type(c, vr, nvr, "fmi3GetBinary");
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         const size_t sizes[], const fmi3Binary values[], size_t n) {
    (void)sizes; (void)values; (void)n;
    return no_such_type(c, vr, nvr, "fmi3SetBinary");
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock values[]) {
    (void)values;
    return no_such_type(c, vr, nvr, "fmi3GetClock");
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock values[]) {
    (void)values;
    return no_such_type(c, vr, nvr, "fmi3SetClock");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr,
                                               size_t *n) {
    (void)vr; (void)n;
    return unsupported(c, "fmi3GetNumberOfVariableDependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t elements[], fmi3ValueReference independents[],
                                       size_t independentElements[],
                                       fmi3DependencyKind kinds[], size_t n) {
    (void)dependent; (void)elements; (void)independents; (void)independentElements;
    (void)kinds; (void)n;
    return unsupported(c, "fmi3GetVariableDependencies");
}

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    CHECK(c);
    return (fmi3Status)get_state(INST, state);
}
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    CHECK(c);
    return (fmi3Status)set_state(INST, state);
}
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    CHECK(c);
    return (fmi3Status)free_state(INST, state);
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    CHECK(c);
    if (size == NULL || !owns(INST, state)) return fmi3Error;
    *size = serialized_size();
    return fmi3OK;
}
fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte out[],
                                 size_t size) {
    CHECK(c);
    return (fmi3Status)serialize(INST, state, (unsigned char *)out, size);
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte in[], size_t size,
                                   fmi3FMUState *state) {
    CHECK(c);
    return (fmi3Status)deserialize(INST, (const unsigned char *)in, size, state);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[],
                                        size_t nu, const fmi3ValueReference k[], size_t nk,
                                        const fmi3Float64 seed[], size_t ns,
                                        fmi3Float64 sens[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return unsupported(c, "fmi3GetDirectionalDerivative");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk,
                                    const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return unsupported(c, "fmi3GetAdjointDerivative");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3EnterConfigurationMode");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3ExitConfigurationMode");
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier q[]) {
    (void)intervals; (void)q;
    return no_such_type(c, vr, nvr, "fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier q[]) {
    (void)counters; (void)resolutions; (void)q;
    return no_such_type(c, vr, nvr, "fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)shifts;
    return no_such_type(c, vr, nvr, "fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return no_such_type(c, vr, nvr, "fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)intervals;
    return no_such_type(c, vr, nvr, "fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return no_such_type(c, vr, nvr, "fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)shifts;
    return no_such_type(c, vr, nvr, "fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)counters; (void)resolutions;
    return no_such_type(c, vr, nvr, "fmi3SetShiftFraction");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return unsupported(c, "fmi3EvaluateDiscreteStates");
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *a, fmi3Boolean *b,
                                    fmi3Boolean *d, fmi3Boolean *e, fmi3Boolean *f,
                                    fmi3Float64 *g) {
    (void)a; (void)b; (void)d; (void)e; (void)f; (void)g;
    return unsupported(c, "fmi3UpdateDiscreteStates");
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return unsupported(c, "fmi3EnterContinuousTimeMode");
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSet, fmi3Boolean *enter,
                                       fmi3Boolean *terminate) {
    (void)noSet; (void)enter; (void)terminate;
    return unsupported(c, "fmi3CompletedIntegratorStep");
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    return unsupported(c, "fmi3SetTime");
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return unsupported(c, "fmi3SetContinuousStates");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 d[], size_t n) {
    (void)d; (void)n;
    return unsupported(c, "fmi3GetContinuousStateDerivatives");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 e[], size_t n) {
    (void)e; (void)n;
    return unsupported(c, "fmi3GetEventIndicators");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return unsupported(c, "fmi3GetContinuousStates");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x; (void)n;
    return unsupported(c, "fmi3GetNominalsOfContinuousStates");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    return unsupported(c, "fmi3GetNumberOfEventIndicators");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    return unsupported(c, "fmi3GetNumberOfContinuousStates");
}
fmi3Status fmi3EnterStepMode(fmi3Instance c) { return unsupported(c, "fmi3EnterStepMode"); }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t n) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)n;
    return unsupported(c, "fmi3GetOutputDerivatives");
}
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    CHECK(c);
    (void)noSetPrior;
    int st = do_step(INST, t, h);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = INST->s.time;
    return (fmi3Status)st;
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock,
                                      fmi3Float64 t) {
    (void)clock; (void)t;
    return unsupported(c, "fmi3ActivateModelPartition");
}
#endif /* FMI 3.0 */
