/* First-order lag: y(t+h) = u + (y(t) - u) exp(-h/tau), u the input set before doStep. */
#include <math.h>
#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])

ModelStatus model_initialize(ModelInstance *m) {
    if (model_check_real(m, VR_tau, 0.0, INFINITY, "a time constant > 0") != MS_OK ||
        !(R(VR_tau) > 0.0)) {
        model_log(m, MS_ERROR, "parameter tau = %g: expected > 0", R(VR_tau));
        return MS_ERROR;
    }
    R(VR_y) = R(VR_y0);
    R(VR_steps) = 0.0;
    R(VR_h_last) = 0.0;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    double u = R(VR_u);
    R(VR_y) = u + (R(VR_y) - u) * exp(-h / R(VR_tau));
    R(VR_steps) += 1.0;
    R(VR_h_last) = h;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
