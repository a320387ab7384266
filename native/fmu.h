/* The FMI plumbing shared by every native FMU of dronefly-fmu, FMI 2.0 and 3.0.
 *
 * One instance holds the value table r[] (one double per scalar variable of the FMU's
 * interface table, in the order of the FMI 2.0 value references; Booleans as 0/1), the
 * co-simulation state machine, and the model's own state (ModelState, declared by the
 * model's model.h). The model implements the hooks declared at the end of this file; the glue
 * (fmu.c) maps both FMI versions onto them. vars.h is generated at build time from the same
 * variable table as the pythonfmu FMUs (dronefly.harness.builder.native).
 */
#ifndef DRONEFLY_FMU_H
#define DRONEFLY_FMU_H

#include <stddef.h>
#include "vars.h"
#include "model.h"

#define FMU_WHY 640 /* room for one message naming a value */

typedef enum { MODE_INSTANTIATED = 0, MODE_INITIALIZATION, MODE_STEPPING, MODE_TERMINATED } Mode;

/* what a state saves: everything but the host's callbacks and names */
typedef struct {
    double r[N_VARS];
    int mode;
    double time;
    int has_stop;
    double stop_time;
    int initialized;
    char pending[FMU_WHY];
    ModelState model;
} Saved;

typedef struct Instance Instance;
struct Instance {
    Saved s;
    int dirty;   /* a parameter was set since the model was last refreshed */
    int stale;   /* a value was set since the outputs were last updated */
    int logging_on;
    char *name;
    void *env;
    void *logger; /* fmi2CallbackLogger or fmi3LogMessageCallback */
    void *states; /* the FMU states this instance handed out and has not freed */
};

/* hooks each model implements: 0 on success; else a message naming the bad value in why */
int model_refresh(Instance *c, char *why);             /* after parameters changed */
int model_initialize(Instance *c, char *why);          /* leaving initialization mode */
int model_update_outputs(Instance *c, char *why);      /* a get after a set (stale) */
int model_advance(Instance *c, double t, double h, char *why, int *warned); /* one step */
void model_reset(Instance *c);                          /* a fresh model state */

/* helpers for the models */
void fmu_repr(char *buf, size_t n, double x);          /* as Python's repr of a float */
int fmu_check_finite(const Instance *c, const int *rows, int n, char *why);
void fmu_warn(Instance *c, const char *msg);             /* log with status Warning */

#endif
