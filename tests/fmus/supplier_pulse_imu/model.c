/* Supplier pulse IMU: the integral of the linear interpolation between the previous and the
 * current input knot, plus a bias, counted in whole pulses of the supplier's weights (arcsec,
 * mm/s); the interval's output is the pulses that became whole in it, so nothing accumulates. */
#include <math.h>

#include "model_instance.h"

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

static const double G0 = 9.80665;

ModelStatus model_initialize(ModelInstance *m) {
    if (model_check_real(m, VR_GyroPulseWeight, 1e-12, INFINITY, "a pulse weight > 0 [arcsec]") != MS_OK ||
        model_check_real(m, VR_AccPulseWeight, 1e-12, INFINITY, "a pulse weight > 0 [mm/s]") != MS_OK)
        return MS_ERROR;
    for (int k = 0; k < 6; k++) {
        m->s.p.prev[k] = R(VR_AngularRate_X + k);
        m->s.p.integral[k] = 0.0;
        m->s.p.pulses[k] = 0.0;
    }
    for (int i = 0; i < 3; i++) I(VR_GyroPulses_X + i) = I(VR_AccPulses_X + i) = 0;
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    for (int k = 0; k < 6; k++) {
        double mean = 0.5 * (m->s.p.prev[k] + R(VR_AngularRate_X + k));
        double add, w;
        if (k < 3) { /* deg/s and deg/h -> arcsec */
            add = (mean + R(VR_GyroBias_X + k) / 3600.0) * 3600.0 * h;
            w = R(VR_GyroPulseWeight);
        } else {     /* g and mg -> mm/s */
            add = (mean + R(VR_AccBias_X + k - 3) * 1e-3) * G0 * 1e3 * h;
            w = R(VR_AccPulseWeight);
        }
        m->s.p.integral[k] += add;
        double whole = floor(m->s.p.integral[k] / w);
        int n = (int)(whole - m->s.p.pulses[k]);
        m->s.p.pulses[k] = whole;
        if (k < 3) I(VR_GyroPulses_X + k) = n; else I(VR_AccPulses_X + k - 3) = n;
    }
    for (int k = 0; k < 6; k++) m->s.p.prev[k] = R(VR_AngularRate_X + k);
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
