/*
 * A minimal FMI 2.0 co-simulation host in C: no Python, no FMPy, no FMI Library.
 *
 * It loads the binaries of two extracted FMUs (plant and controller), instantiates both,
 * and runs the closed loop with a Gauss-Seidel master, printing one CSV line per
 * communication point: t, plant outputs, controller outputs (%.17g).
 *
 *   fmi2_host [-q] [-t] [-m MAPS_FILE] N_STEPS STEP \
 *             PLANT_DIR PLANT_ID PLANT_GUID  CTRL_DIR CTRL_ID CTRL_GUID \
 *             Y_VRS S_VRS UC_VRS UP_VRS [VR=VALUE,...]
 *
 * *_DIR: the extracted FMU; *_ID: modelIdentifier (binaries/linux64/<ID>.so, or
 * binaries/win64/<ID>.dll in the Windows build); Y_VRS: plant outputs; S_VRS: the controller
 * inputs they feed, in the same order; UC_VRS: controller outputs; UP_VRS: the plant inputs
 * they feed (comma-separated value references; "" for none). The last argument sets plant
 * parameters in initialization mode.
 *
 * Options: -q prints the last line only; -t writes "loop_s=<seconds> steps=<n>" to stderr,
 * the wall time of the loop alone (monotonic clock); -m copies /proc/self/maps (the libraries
 * this process has loaded, taken after both FMUs are initialized) to MAPS_FILE (Linux only).
 *
 * Exit codes: 0 ok, 1 usage, 2 cannot load a binary (the loader's message on stderr), 3 an FMI
 * call failed.
 *
 * Compiled by the tests (tests/test_interop.py, tests/test_native_hosts.py) against fmpy's
 * copy of the FMI 2.0 headers (fmpy/c-code/fmi2FunctionTypes.h, fmi2TypesPlatform.h), for
 * Linux with gcc or zig cc and for Windows with zig cc (run under Wine).
 */
#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#include <time.h>
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"

#define MAXV 64

#ifdef _WIN32
#define PLATFORM "win64"
#define SUFFIX ".dll"
#else
#define PLATFORM "linux64"
#define SUFFIX ".so"
#endif

typedef struct {
#ifdef _WIN32
    HMODULE lib;
#else
    void *lib;
#endif
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

static double now_s(void) {
#ifdef _WIN32
    LARGE_INTEGER f, c;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&c);
    return (double)c.QuadPart / (double)f.QuadPart;
#else
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
#endif
}

static void *sym(Fmu *f, const char *name) {
#ifdef _WIN32
    void *p = (void *)GetProcAddress(f->lib, name);
#else
    void *p = dlsym(f->lib, name);
#endif
    if (!p) {
        fprintf(stderr, "%s: missing symbol %s\n", f->name, name);
        exit(2);
    }
    return p;
}

static void load(Fmu *f, const char *dir, const char *id, const char *guid, const char *name) {
    char path[4096], uri[4096];
    static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    snprintf(path, sizeof path, "%s/binaries/" PLATFORM "/%s" SUFFIX, dir, id);
    f->name = name;
#ifdef _WIN32
    f->lib = LoadLibraryA(path);
    if (!f->lib) {
        fprintf(stderr, "cannot load %s: error %lu\n", path, (unsigned long)GetLastError());
        exit(2);
    }
#else
    f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->lib) {
        fprintf(stderr, "cannot load %s: %s\n", path, dlerror());
        exit(2);
    }
#endif
    f->instantiate = (fmi2InstantiateTYPE *)sym(f, "fmi2Instantiate");
    f->freeInstance = (fmi2FreeInstanceTYPE *)sym(f, "fmi2FreeInstance");
    f->setupExperiment = (fmi2SetupExperimentTYPE *)sym(f, "fmi2SetupExperiment");
    f->enterInit = (fmi2EnterInitializationModeTYPE *)sym(f, "fmi2EnterInitializationMode");
    f->exitInit = (fmi2ExitInitializationModeTYPE *)sym(f, "fmi2ExitInitializationMode");
    f->terminate = (fmi2TerminateTYPE *)sym(f, "fmi2Terminate");
    f->getReal = (fmi2GetRealTYPE *)sym(f, "fmi2GetReal");
    f->setReal = (fmi2SetRealTYPE *)sym(f, "fmi2SetReal");
    f->doStep = (fmi2DoStepTYPE *)sym(f, "fmi2DoStep");
    /* file:///C:/x/resources on Windows, file:///x/resources elsewhere */
    snprintf(uri, sizeof uri, "file://%s%s/resources", dir[0] == '/' ? "" : "/", dir);
    for (char *s = uri; *s; ++s)
        if (*s == '\\') *s = '/';
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

/* comma-separated unsigned integers; "" is an empty list */
static size_t parse_vrs(const char *text, fmi2ValueReference *out) {
    size_t n = 0;
    const char *s = text;
    while (*s && n < MAXV) {
        char *end;
        out[n++] = (fmi2ValueReference)strtoul(s, &end, 10);
        if (end == s) break;
        s = (*end == ',') ? end + 1 : end;
    }
    return n;
}

static void copy_maps(const char *to) {
#ifdef _WIN32
    (void)to;
    fprintf(stderr, "-m: no /proc/self/maps on Windows\n");
    exit(1);
#else
    char buf[4096];
    size_t n;
    FILE *in = fopen("/proc/self/maps", "r"), *out = fopen(to, "w");
    if (!in || !out) {
        fprintf(stderr, "-m: cannot copy /proc/self/maps to %s\n", to);
        exit(1);
    }
    while ((n = fread(buf, 1, sizeof buf, in)) > 0) fwrite(buf, 1, n, out);
    fclose(in);
    fclose(out);
#endif
}

static void print_row(double t, const fmi2Real *y, size_t ny, const fmi2Real *u, size_t nu) {
    printf("%.17g", t);
    for (size_t i = 0; i < ny; ++i) printf(",%.17g", y[i]);
    for (size_t i = 0; i < nu; ++i) printf(",%.17g", u[i]);
    printf("\n");
}

int main(int argc, char **argv) {
    Fmu p, c;
    fmi2ValueReference y_vr[MAXV], s_vr[MAXV], uc_vr[MAXV], up_vr[MAXV];
    fmi2Real y[MAXV], u[MAXV];
    size_t ny, ns, nuc, nup;
    long n_steps;
    double h, t0 = 0.0;
    int quiet = 0, timed = 0, a = 1;
    const char *maps = NULL;

    for (; a < argc && argv[a][0] == '-' && argv[a][1] && !argv[a][2]; ++a) {
        if (argv[a][1] == 'q') quiet = 1;
        else if (argv[a][1] == 't') timed = 1;
        else if (argv[a][1] == 'm' && a + 1 < argc) maps = argv[++a];
        else break;
    }
    argv += a - 1;
    argc -= a - 1;
    if (argc < 13) {
        fprintf(stderr, "usage: fmi2_host [-q] [-t] [-m MAPS_FILE] N_STEPS STEP PLANT_DIR "
                        "PLANT_ID PLANT_GUID CTRL_DIR CTRL_ID CTRL_GUID Y_VRS S_VRS UC_VRS "
                        "UP_VRS [VR=VALUE,...]\n");
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
        const char *s = argv[13];
        while (*s) {
            char *end;
            fmi2ValueReference vr = (fmi2ValueReference)strtoul(s, &end, 10);
            fmi2Real v;
            if (end == s || *end != '=') {
                fprintf(stderr, "bad start value %s\n", s);
                return 1;
            }
            v = strtod(end + 1, &end);
            check(p.setReal(p.c, &vr, 1, &v), &p, "fmi2SetReal", 0);
            s = (*end == ',') ? end + 1 : end;
        }
    }
    check(p.exitInit(p.c), &p, "fmi2ExitInitializationMode", 0);
    check(p.getReal(p.c, y_vr, ny, y), &p, "fmi2GetReal", 0);
    check(c.setReal(c.c, s_vr, ns, y), &c, "fmi2SetReal", 0);
    check(c.exitInit(c.c), &c, "fmi2ExitInitializationMode", 0);
    if (maps) copy_maps(maps);
    if (timed) t0 = now_s();
    for (long k = 0; k <= n_steps; ++k) {
        double t = k * h;
        check(p.getReal(p.c, y_vr, ny, y), &p, "fmi2GetReal", t);
        check(c.setReal(c.c, s_vr, ns, y), &c, "fmi2SetReal", t);
        check(c.getReal(c.c, uc_vr, nuc, u), &c, "fmi2GetReal", t);
        if (!quiet || k == n_steps) print_row(t, y, ny, u, nuc);
        if (k == n_steps) break;
        check(p.setReal(p.c, up_vr, nup, u), &p, "fmi2SetReal", t);
        check(p.doStep(p.c, t, h, fmi2True), &p, "fmi2DoStep", t);
        check(c.doStep(c.c, t, h, fmi2True), &c, "fmi2DoStep", t);
    }
    if (timed) fprintf(stderr, "loop_s=%.9g steps=%ld\n", now_s() - t0, n_steps);
    check(p.terminate(p.c), &p, "fmi2Terminate", n_steps * h);
    check(c.terminate(c.c), &c, "fmi2Terminate", n_steps * h);
    p.freeInstance(p.c);
    c.freeInstance(c.c);
    fflush(stdout);
    return 0;
}
