/* The controller FMUs (native): u = K x+ of Eq. (22) on either axis. */
#ifndef DRONEFLY_MODEL_H
#define DRONEFLY_MODEL_H
#define CTRL_NX 4
#define CTRL_MAX_U 4
typedef struct {
    int valid;                     /* the law below is the current parameters' */
    double Kd[CTRL_MAX_U][CTRL_NX]; /* K with the non-dimensionalisation folded in */
    int active[CTRL_MAX_U];         /* a row with a non-zero gain */
    int limit;
    double u_max;
} ModelState;
#endif
