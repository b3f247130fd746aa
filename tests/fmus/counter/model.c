/* n = n_in + mode * steps, recomputed whenever an input changes. */
#include "model_instance.h"

#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

static void update(ModelInstance *m) {
    I(VR_n) = I(VR_n_in) + I(VR_mode) * (int)m->s.p.steps;
    m->s.r[VR_y] = (double)I(VR_n);
}

ModelStatus model_initialize(ModelInstance *m) {
    update(m);
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    (void)h;
    m->s.p.steps++;
    update(m);
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    update(m);
    return MS_OK;
}
