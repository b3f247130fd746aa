/* y = time; the step starting at fail_time (within 1e-9 h) returns MS_ERROR and logs why. */
#include <math.h>
#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])

ModelStatus model_initialize(ModelInstance *m) {
    R(VR_y) = m->s.time;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    if (m->s.time >= R(VR_fail_time) - 1e-9 * h) {
        model_log(m, MS_ERROR, "deliberate failure: step from t = %.9g reached fail_time = %.9g",
                  m->s.time, R(VR_fail_time));
        return MS_ERROR;
    }
    R(VR_y) = m->s.time + h;
    m->s.p.steps++;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
