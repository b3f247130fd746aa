/* Supplier IMU: mean of the linear interpolation between the previous and the current input
 * knot, scale factor and bias per axis, all in the supplier's own units (deg/s, g).
 * SegfaultAt / HangAt: a broken supplier FMU for the campaign tests (default never). */
#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])

_Static_assert(VR_AngularRate_Z == VR_AngularRate_X + 2 && VR_Accel_X == VR_AngularRate_X + 3 &&
                   VR_Accel_Z == VR_AngularRate_X + 5,
               "inputs consecutive: rates then accelerations");

ModelStatus model_initialize(ModelInstance *m) {
    for (int k = 0; k < 6; k++) m->s.p.prev[k] = R(VR_AngularRate_X + k);
    for (int i = 0; i < 3; i++) R(VR_GyroRate_X + i) = R(VR_Accel_Out_X + i) = 0.0;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    if (m->s.time >= R(VR_SegfaultAt) - 1e-9 * h) {
        volatile double *null = (volatile double *)0;
        *null = m->s.time; /* deliberate: SIGSEGV */
    }
    if (m->s.time >= R(VR_HangAt) - 1e-9 * h) {
        volatile long spin = 0;
        for (;;) spin++; /* deliberate: never returns */
    }
    for (int i = 0; i < 3; i++) {
        double wm = 0.5 * (m->s.p.prev[i] + R(VR_AngularRate_X + i));
        double fm = 0.5 * (m->s.p.prev[3 + i] + R(VR_Accel_X + i));
        R(VR_GyroRate_X + i) = (1.0 + R(VR_GyroSF_X + i)) * wm + R(VR_GyroBias_X + i);
        R(VR_Accel_Out_X + i) = (1.0 + R(VR_AccSF_X + i)) * fm + R(VR_AccBias_X + i);
    }
    for (int k = 0; k < 6; k++) m->s.p.prev[k] = R(VR_AngularRate_X + k);
    m->s.p.steps++;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
