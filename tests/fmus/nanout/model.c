/* y = time at the end of the step; NaN once that time reaches nan_time. */
#include <math.h>
#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])

ModelStatus model_initialize(ModelInstance *m) {
    R(VR_y) = m->s.time;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    double t1 = m->s.time + h;
    if (t1 >= R(VR_nan_time) - 1e-9 * h) {
        model_log(m, MS_WARNING, "output y is NaN from t = %.9g (nan_time = %.9g)", t1,
                  R(VR_nan_time));
        R(VR_y) = NAN;
    } else {
        R(VR_y) = t1;
    }
    m->s.p.steps++;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
