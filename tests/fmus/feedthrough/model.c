/* y = u: the output follows the input at once (also between steps). */
#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])

ModelStatus model_initialize(ModelInstance *m) {
    R(VR_y) = R(VR_u);
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    (void)h;
    R(VR_y) = R(VR_u);
    m->s.p.steps++;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    R(VR_y) = R(VR_u);
    return MS_OK;
}
