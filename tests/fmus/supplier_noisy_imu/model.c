/* Supplier IMU with noise: mean of the linear interpolation between the previous and the current
 * input knot, a bias per axis, one misalignment, white gyro noise of density GyroARW seeded by
 * RandomSeed, in the supplier's own units (deg/s, g, deg/h, mg, urad, deg/sqrt(h)). */
#include <math.h>

#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

static double uniform(uint64_t *s) { /* xorshift64*, (0, 1) */
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return ((double)((*s * 2685821657736338717ULL) >> 11) + 0.5) / 9007199254740992.0;
}

static double gauss(uint64_t *s) { /* Box-Muller, one of the pair */
    double u = uniform(s), v = uniform(s);
    return sqrt(-2.0 * log(u)) * cos(6.283185307179586 * v);
}

ModelStatus model_initialize(ModelInstance *m) {
    for (int k = 0; k < 6; k++) m->s.p.prev[k] = R(VR_AngularRate_X + k);
    for (int i = 0; i < 3; i++) R(VR_GyroRate_X + i) = R(VR_Accel_Out_X + i) = 0.0;
    m->s.p.rng = 0x9E3779B97F4A7C15ULL ^ ((uint64_t)(unsigned)I(VR_RandomSeed) * 0xBF58476D1CE4E5B9ULL);
    if (m->s.p.rng == 0) m->s.p.rng = 1;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    /* white rate noise over the interval: density [deg/sqrt(h)] -> deg/s per sqrt(s) -> mean over h */
    const double density = R(VR_GyroARW) * 60.0 / 3600.0;
    double wm[3];
    for (int i = 0; i < 3; i++) wm[i] = 0.5 * (m->s.p.prev[i] + R(VR_AngularRate_X + i));
    for (int i = 0; i < 3; i++) {
        double fm = 0.5 * (m->s.p.prev[3 + i] + R(VR_Accel_X + i));
        double g = wm[i] + R(VR_GyroBias_X + i) / 3600.0 + density / sqrt(h) * gauss(&m->s.p.rng);
        if (i == 0) g += R(VR_GyroMis_XY) * 1e-6 * wm[1];
        R(VR_GyroRate_X + i) = g;
        R(VR_Accel_Out_X + i) = fm + R(VR_AccBias_X + i) * 1e-3;
    }
    for (int k = 0; k < 6; k++) m->s.p.prev[k] = R(VR_AngularRate_X + k);
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
