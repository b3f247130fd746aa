/* What the IMU's C files share (model.c, signal.c, noise.c): the two sensors' value
 * references, the motion at one instant, and the functions one file calls in another. */
#ifndef IMU_H
#define IMU_H

#include "model_instance.h"

enum { GYRO = 0, ACC = 1 };

/* Parameters shared in form by both sensors, by first value reference. */
typedef struct {
    int sf, sf_asym, mis, bias, temp, sf_temp, drift;
    int white, bi, bi_tau, bi_tau_max, rrw, output, count_weight, out;
} SensorVr;

/* gyro, accelerometer (model.c) */
extern const SensorVr SENSOR_VR[2];

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

/* The motion at one instant of table time: rate, angular acceleration, specific force. */
typedef struct {
    double w[3], a[3], f[3];
} Motion;

/* signal.c */
void knot_from_inputs(const ModelInstance *m, double t, ImuKnot *k);
void push_knot(ModelPrivate *p, const ImuKnot *k, double tol);
void set_bump(const ModelInstance *m, ModelPrivate *p);
void motion_at(const ModelInstance *m, double tau, Motion *mo);
double temperature_at(const ModelInstance *m, double s);

/* noise.c */
void seed_streams(ModelInstance *m);
double gauss(ImuRng *g);
double gm_sigma(const ModelInstance *m, int sensor);
int flicker_count(double t_lo, double t_hi);
void flicker_init(ModelInstance *m);
double noise_increment(ModelInstance *m, int sensor, int i, double h);

#endif
