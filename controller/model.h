/* The controller FMUs (native): u = K x+_s + KI z of Eq. (22) on either axis, with sensing
 * delay, sampling and integral action (dronefly/controller/delay.py). */
#ifndef DRONEFLY_MODEL_H
#define DRONEFLY_MODEL_H
#define CTRL_NX 4
#define CTRL_MAX_U 4
/* samples taken and not yet in effect that one instance holds (the pythonfmu FMUs: 100000) */
#define CTRL_LINE 512

typedef struct {
    double ts;            /* the (first) sample instant [s] */
    double x[CTRL_NX];    /* the dimensional state sampled */
    int multi;            /* several instants in one step: first ts, last, period */
    double last, period;
} Sample;

typedef struct {           /* dronefly.controller.delay.Sensor */
    double t0;
    Sample line[CTRL_LINE]; /* a ring: head, count */
    int head, count;
    double held[CTRL_NX], z0[CTRL_NX], x_plus[CTRL_NX], scale[CTRL_NX];
    int has_scale;
    double t_base, n;
    int integrating;
    int has_k;            /* last_k is not None */
    double last_k, last_period;
    double h, drift, t_effect;
    int has_current;
    Sample current;
    int off_grid;         /* 0 None, 1 pending (what, instant, t, h below), 2 reported */
    int off_grid_effect;  /* 1: "an effect instant", 0: "a sample instant" */
    double og_instant, og_t, og_h;
} Sensor;

typedef struct {
    int valid;                      /* the law below is the current parameters' */
    double Kd[CTRL_MAX_U][CTRL_NX]; /* K with the non-dimensionalisation folded in */
    int active[CTRL_MAX_U];         /* a row with a non-zero gain */
    double KI[CTRL_MAX_U][CTRL_NX];
    int has_integral;
    double scale[CTRL_NX], n;
    int limit;
    double u_max, delay, period;
    Sensor sensor;
} ModelState;
#endif
