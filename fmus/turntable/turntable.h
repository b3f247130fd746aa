/* What the turntable's C files share (model.c, gimbal.c, servo.c): the value references of
 * an axis, the description of an axis's motion over one controller tick, and the functions one
 * file calls in another. */
#ifndef TURNTABLE_H
#define TURNTABLE_H

#include "model_instance.h"
#include "vec3.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Value references of one axis's variables. */
typedef struct {
    int axis[3], nonorth[3];
    int inertia, viscous, coulomb, static_friction, torque_max, rate_max, acc_max, angle0;
    int b0, b1, b2, a1, a2;
    int bits; /* Integer */
    int h1_amp, h1_phase, h2_amp, h2_phase, reversal, wob_amp, wob_phase;
    int mode; /* Integer */
    int angle_cmd, rate_cmd;
    int angle, rate, angle_true, angle_ref, torque;
} AxisVR;

/* outer, middle, inner (model.c) */
extern const AxisVR AXVR[TT_MAX_AXES];

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

/* Motion of one axis over one controller tick (torque held): the sliding piece from the tick's
 * start (angle th0, rate v0, constant-direction acceleration a0 at the start) up to te, then,
 * when te < T (the rate reached zero inside the tick), a piece from rest at angle th_e with
 * acceleration a1 at its start (0: stuck for the rest of the tick). */
typedef struct {
    double th0, v0, a0, te, th_e, a1;
    int stuck; /* at rest over the whole tick */
} TickMotion;

/* gimbal.c */
double normal_gravity(double lat, double h);
int stage_geometry(ModelInstance *m, const AxisVR *vr, TTAxis *x);
void plate_outputs(ModelInstance *m);
extern const double GL2_S[2];
void tick_integrals(const ModelPrivate *p, const TickMotion mo[], double wi[3], double fi[3]);
void rest_integrals(const ModelPrivate *p, const double th[], long long n, double wi[3],
                    double fi[3]);

/* servo.c */
void phi12(double beta, double t, double *p1, double *p2);
void motion_at(const TTAxis *x, const TickMotion *mo, double t, double *th, double *thd);
double encoder(ModelInstance *m, const AxisVR *vr, double th);
double reading(ModelInstance *m, const AxisVR *vr, const TTAxis *x);
void servo_tick(ModelInstance *m, int k, long long j, TickMotion *mo);

#endif
