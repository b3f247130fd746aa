#include "model_instance.h"
ModelStatus model_initialize(ModelInstance *m) { return model_check_real(m, VR_gyro_bias_x, -1, 1, "|x|<1"); }
ModelStatus model_do_step(ModelInstance *m, double h) { m->s.r[VR_gyro_x] = m->s.r[VR_omega_x]*h; return MS_OK; }
ModelStatus model_inputs_changed(ModelInstance *m) { (void)m; return MS_OK; }
