/* Outputs stay zero: this model exists to be refused by the role check. */
#include "model_instance.h"

ModelStatus model_initialize(ModelInstance *m) {
    (void)m;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    (void)h;
    m->s.p.steps++;
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
