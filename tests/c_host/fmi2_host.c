/*
 * A minimal FMI 2.0 co-simulation host in C: no Python, no FMPy, no FMI Library.
 *
 * It dlopens the binaries of two extracted FMUs (plant and controller), instantiates both,
 * and runs the closed loop with a Gauss-Seidel master, printing one CSV line per
 * communication point: t, plant outputs, controller outputs (%.17g).
 *
 *   fmi2_host N_STEPS STEP \
 *             PLANT_DIR PLANT_ID PLANT_GUID  CTRL_DIR CTRL_ID CTRL_GUID \
 *             Y_VRS S_VRS UC_VRS UP_VRS [VR=VALUE,...]
 *
 * *_DIR: the extracted FMU; *_ID: modelIdentifier (binaries/linux64/<ID>.so); Y_VRS: plant
 * outputs; S_VRS: the controller inputs they feed, in the same order; UC_VRS: controller
 * outputs; UP_VRS: the plant inputs they feed (comma-separated value references). The last
 * argument sets plant parameters in initialization mode.
 *
 * Exit codes: 0 ok, 1 usage, 2 cannot load a binary (dlerror() on stderr), 3 an FMI call failed.
 *
 * Compiled by tests/test_interop.py against fmpy's copy of the FMI 2.0 headers
 * (fmpy/c-code/fmi2FunctionTypes.h, fmi2TypesPlatform.h).
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"

#define MAXV 64

typedef struct {
    void *lib;
    fmi2Component c;
    const char *name;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInit;
    fmi2ExitInitializationModeTYPE *exitInit;
    fmi2TerminateTYPE *terminate;
    fmi2GetRealTYPE *getReal;
    fmi2SetRealTYPE *setReal;
    fmi2DoStepTYPE *doStep;
} Fmu;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list ap;
    (void)env;
    fprintf(stderr, "[%s] status %d %s: ", instance ? instance : "?", (int)status,
            category ? category : "");
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

static void *sym(Fmu *f, const char *name) {
    void *p = dlsym(f->lib, name);
    if (!p) {
        fprintf(stderr, "%s: missing symbol %s\n", f->name, name);
        exit(2);
    }
    return p;
}

static void load(Fmu *f, const char *dir, const char *id, const char *guid, const char *name) {
    char path[4096], uri[4096];
    static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    f->name = name;
    f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->lib) {
        fprintf(stderr, "cannot load %s: %s\n", path, dlerror());
        exit(2);
    }
    f->instantiate = (fmi2InstantiateTYPE *)sym(f, "fmi2Instantiate");
    f->freeInstance = (fmi2FreeInstanceTYPE *)sym(f, "fmi2FreeInstance");
    f->setupExperiment = (fmi2SetupExperimentTYPE *)sym(f, "fmi2SetupExperiment");
    f->enterInit = (fmi2EnterInitializationModeTYPE *)sym(f, "fmi2EnterInitializationMode");
    f->exitInit = (fmi2ExitInitializationModeTYPE *)sym(f, "fmi2ExitInitializationMode");
    f->terminate = (fmi2TerminateTYPE *)sym(f, "fmi2Terminate");
    f->getReal = (fmi2GetRealTYPE *)sym(f, "fmi2GetReal");
    f->setReal = (fmi2SetRealTYPE *)sym(f, "fmi2SetReal");
    f->doStep = (fmi2DoStepTYPE *)sym(f, "fmi2DoStep");
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    f->c = f->instantiate(name, fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    if (!f->c) {
        fprintf(stderr, "%s: fmi2Instantiate failed\n", name);
        exit(3);
    }
}

static void check(fmi2Status s, const Fmu *f, const char *call, double t) {
    if (s > fmi2Warning) {
        fprintf(stderr, "%s: %s at t = %.17g returned %d\n", f->name, call, t, (int)s);
        exit(3);
    }
}

static size_t parse_vrs(const char *text, fmi2ValueReference *out) {
    size_t n = 0;
    char *copy = strdup(text), *save = NULL;
    for (char *tok = strtok_r(copy, ",", &save); tok && n < MAXV;
         tok = strtok_r(NULL, ",", &save))
        out[n++] = (fmi2ValueReference)strtoul(tok, NULL, 10);
    free(copy);
    return n;
}

int main(int argc, char **argv) {
    Fmu p, c;
    fmi2ValueReference y_vr[MAXV], s_vr[MAXV], uc_vr[MAXV], up_vr[MAXV];
    fmi2Real y[MAXV], u[MAXV];
    size_t ny, ns, nuc, nup;
    long n_steps;
    double h;

    if (argc < 13) {
        fprintf(stderr, "usage: %s N_STEPS STEP PLANT_DIR PLANT_ID PLANT_GUID CTRL_DIR CTRL_ID "
                        "CTRL_GUID Y_VRS S_VRS UC_VRS UP_VRS [VR=VALUE,...]\n", argv[0]);
        return 1;
    }
    n_steps = strtol(argv[1], NULL, 10);
    h = strtod(argv[2], NULL);
    ny = parse_vrs(argv[9], y_vr);
    ns = parse_vrs(argv[10], s_vr);
    nuc = parse_vrs(argv[11], uc_vr);
    nup = parse_vrs(argv[12], up_vr);
    if (ny != ns || nuc != nup || n_steps < 1 || !(h > 0)) {
        fprintf(stderr, "bad arguments\n");
        return 1;
    }
    load(&p, argv[3], argv[4], argv[5], "plant");
    load(&c, argv[6], argv[7], argv[8], "controller");
    check(p.setupExperiment(p.c, fmi2False, 0.0, 0.0, fmi2True, n_steps * h), &p, "setup", 0);
    check(c.setupExperiment(c.c, fmi2False, 0.0, 0.0, fmi2True, n_steps * h), &c, "setup", 0);
    check(p.enterInit(p.c), &p, "fmi2EnterInitializationMode", 0);
    check(c.enterInit(c.c), &c, "fmi2EnterInitializationMode", 0);
    if (argc > 13) {
        char *copy = strdup(argv[13]), *save = NULL;
        for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
            char *eq = strchr(tok, '=');
            fmi2ValueReference vr;
            fmi2Real v;
            if (!eq) {
                fprintf(stderr, "bad start value %s\n", tok);
                return 1;
            }
            vr = (fmi2ValueReference)strtoul(tok, NULL, 10);
            v = strtod(eq + 1, NULL);
            check(p.setReal(p.c, &vr, 1, &v), &p, "fmi2SetReal", 0);
        }
        free(copy);
    }
    check(p.exitInit(p.c), &p, "fmi2ExitInitializationMode", 0);
    check(p.getReal(p.c, y_vr, ny, y), &p, "fmi2GetReal", 0);
    check(c.setReal(c.c, s_vr, ns, y), &c, "fmi2SetReal", 0);
    check(c.exitInit(c.c), &c, "fmi2ExitInitializationMode", 0);
    for (long k = 0; k <= n_steps; ++k) {
        double t = k * h;
        check(p.getReal(p.c, y_vr, ny, y), &p, "fmi2GetReal", t);
        check(c.setReal(c.c, s_vr, ns, y), &c, "fmi2SetReal", t);
        check(c.getReal(c.c, uc_vr, nuc, u), &c, "fmi2GetReal", t);
        printf("%.17g", t);
        for (size_t i = 0; i < ny; ++i) printf(",%.17g", y[i]);
        for (size_t i = 0; i < nuc; ++i) printf(",%.17g", u[i]);
        printf("\n");
        if (k == n_steps) break;
        check(p.setReal(p.c, up_vr, nup, u), &p, "fmi2SetReal", t);
        check(p.doStep(p.c, t, h, fmi2True), &p, "fmi2DoStep", t);
        check(c.doStep(c.c, t, h, fmi2True), &c, "fmi2DoStep", t);
    }
    check(p.terminate(p.c), &p, "fmi2Terminate", n_steps * h);
    check(c.terminate(c.c), &c, "fmi2Terminate", n_steps * h);
    p.freeInstance(p.c);
    c.freeInstance(c.c);
    fflush(stdout);
    return 0;
}
