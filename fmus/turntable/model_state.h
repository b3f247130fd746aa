/* Private state of the turntable model. A plain struct without pointers: an FMU state snapshot
 * is a memcpy of it (see fmus/common/model_instance.h). */
#ifndef TURNTABLE_MODEL_STATE_H
#define TURNTABLE_MODEL_STATE_H

#define TT_MAX_AXES 3

/* One stage of the gimbal chain with its servo loop. */
typedef struct {
    /* geometry, derived from the parameters at initialisation */
    double a[3];      /* rotation axis (non-orthogonality applied), previous stage's frame */
    double b[3];      /* constant axis of the stage's relative rate, in the stage's own frame */
    double u[3], v[3]; /* wobble basis, perpendicular to a */
    double wob_amp, wob_phase;
    /* plant (true motion) */
    double th, thd, thdd; /* angle, rate, acceleration (left limit at the last tick) */
    double play;          /* plate angle - encoder-side angle, within +-reversal / 2 (servo.c) */
    /* closed-form motion over a tick: beta = B / J and phi1(t), phi2(t) (see servo.c) at the
     * tick length and at the two Gauss nodes, fixed at initialisation */
    double beta, phi1_T, phi2_T, phi1_g[2], phi2_g[2];
    double torque;        /* motor torque held over the current controller tick */
    /* reference generator */
    double th_ref, w_ref, a_ref;
    /* controller memory: e[k-1], e[k-2], u[k-1], u[k-2] (u after saturation) */
    double e1, e2, u1, u2;
} TTAxis;

typedef struct {
    int n_axes;
    double T;             /* controller period [s] */
    long long tick;       /* controller ticks since the start time: time without drift */
    double C_b0n[3][3];   /* C_b0^n: base frame -> ENU */
    double w_ie_n[3];     /* Earth rate in ENU */
    double w_ie_b0[3];    /* Earth rate in base axes */
    double g;             /* gravity magnitude [m/s2] */
    TTAxis ax[TT_MAX_AXES];
} ModelPrivate;

#endif
