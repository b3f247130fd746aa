/* calbench turntable: gimbal chain, base, Earth, and one discrete servo loop per axis.
 *
 * This file is the model's side of model_instance.h: the parameters and their checks, the
 * initialisation, and the step, a loop over controller ticks. The physics is in
 *   gimbal.c  frames, base, Earth, the gimbal chain; the plate outputs and their integrals over
 *             a step,
 *   servo.c   per axis the reference generator, encoder and controller, and the closed-form
 *             motion of the axis under stick-slip friction over one controller tick,
 * each with its conventions at the top.
 */
#include <math.h>
#include <string.h>
#include "turntable.h"

/* ------------------------------------------------------------------ value references */

#define AXIS_VR(n)                                                                              \
    {{VR_##n##_axis_x, VR_##n##_axis_y, VR_##n##_axis_z},                                       \
     {VR_##n##_nonorth_x, VR_##n##_nonorth_y, VR_##n##_nonorth_z},                              \
     VR_##n##_inertia, VR_##n##_viscous, VR_##n##_coulomb, VR_##n##_static_friction,            \
     VR_##n##_torque_max,                                                                       \
     VR_##n##_rate_max, VR_##n##_acc_max, VR_##n##_angle0,                                      \
     VR_##n##_ctrl_b0, VR_##n##_ctrl_b1, VR_##n##_ctrl_b2, VR_##n##_ctrl_a1, VR_##n##_ctrl_a2,  \
     VR_##n##_encoder_bits,                                                                     \
     VR_##n##_encoder_h1_amp, VR_##n##_encoder_h1_phase, VR_##n##_encoder_h2_amp,               \
     VR_##n##_encoder_h2_phase, VR_##n##_encoder_reversal, VR_##n##_wobble_amp,                 \
     VR_##n##_wobble_phase,                                                                     \
     VR_##n##_mode, VR_##n##_angle_cmd, VR_##n##_rate_cmd,                                      \
     VR_##n##_angle, VR_##n##_rate, VR_##n##_angle_true, VR_##n##_angle_ref, VR_##n##_torque}

const AxisVR AXVR[TT_MAX_AXES] = {AXIS_VR(outer), AXIS_VR(middle), AXIS_VR(inner)};

/* The code indexes the integrals' components from .x. */
_Static_assert(VR_plate_omega_int_z == VR_plate_omega_int_x + 2 &&
                   VR_plate_f_int_z == VR_plate_f_int_x + 2, "integral outputs consecutive");

/* ------------------------------------------------------------------ outputs, checks */

static void axis_outputs(ModelInstance *m) {
    int k;
    for (k = 0; k < TT_MAX_AXES; k++) {
        const AxisVR *vr = &AXVR[k];
        const TTAxis *x = &m->s.p.ax[k];
        int used = k < m->s.p.n_axes;
        R(vr->angle) = used ? reading(m, vr, x) : 0.0;
        R(vr->rate) = x->thd;
        R(vr->angle_true) = x->th;
        R(vr->angle_ref) = x->th_ref;
        R(vr->torque) = x->torque;
    }
}

static ModelStatus check_positive(ModelInstance *m, int vr) {
    if (!(R(vr) > 0.0)) {
        model_log(m, MS_ERROR, "parameter %s = %g: expected > 0", REAL_NAME[vr], R(vr));
        return MS_ERROR;
    }
    return MS_OK;
}

static ModelStatus check_mode(ModelInstance *m, const AxisVR *vr) {
    int mode = I(vr->mode);
    if (mode != 0 && mode != 1) {
        model_log(m, MS_ERROR, "input %s = %d: expected 0 (position) or 1 (rate)",
                  INTEGER_NAME[vr->mode - INTEGER_VR_BASE], mode);
        return MS_ERROR;
    }
    return MS_OK;
}

static ModelStatus check_axis(ModelInstance *m, const AxisVR *vr) {
    int bits = I(vr->bits);
    if (check_positive(m, vr->inertia) || check_positive(m, vr->torque_max) ||
        check_positive(m, vr->rate_max) || check_positive(m, vr->acc_max) ||
        model_check_real(m, vr->viscous, 0.0, INFINITY, ">= 0") ||
        model_check_real(m, vr->coulomb, 0.0, INFINITY, ">= 0") ||
        model_check_real(m, vr->static_friction, 0.0, INFINITY, ">= 0"))
        return MS_ERROR;
    if (bits < 0 || bits > 32) {
        model_log(m, MS_ERROR, "parameter %s = %d: expected 0 (no quantisation) to 32",
                  INTEGER_NAME[vr->bits - INTEGER_VR_BASE], bits);
        return MS_ERROR;
    }
    return check_mode(m, vr);
}

static ModelStatus check_parameters(ModelInstance *m) {
    int vr, k, n = I(VR_n_axes);
    for (vr = 0; vr < N_REAL; vr++)
        if (REAL_CAUSALITY[vr] == CAUS_PARAMETER &&
            model_check_real(m, vr, -INFINITY, INFINITY, "a finite value"))
            return MS_ERROR;
    if (n < 1 || n > TT_MAX_AXES) {
        model_log(m, MS_ERROR, "parameter n_axes = %d: expected 1, 2 or 3", n);
        return MS_ERROR;
    }
    if (check_positive(m, VR_servo_rate) || model_check_real(m, VR_servo_stick_velocity, 0.0, INFINITY, ">= 0") ||
        model_check_real(m, VR_site_gravity, 0.0, INFINITY, ">= 0 (0: WGS-84 normal gravity)") ||
        model_check_real(m, VR_site_latitude, -M_PI / 2, M_PI / 2, "in [-pi/2, pi/2]"))
        return MS_ERROR;
    for (k = 0; k < n; k++)
        if (check_axis(m, &AXVR[k])) return MS_ERROR;
    return MS_OK;
}

/* Constants of the closed-form tick motion of each used axis (B, J and T are fixed). */
static void init_motion(ModelInstance *m) {
    ModelPrivate *p = &m->s.p;
    int k, q;
    for (k = 0; k < p->n_axes; k++) {
        TTAxis *x = &p->ax[k];
        x->beta = R(AXVR[k].viscous) / R(AXVR[k].inertia);
        phi12(x->beta, p->T, &x->phi1_T, &x->phi2_T);
        for (q = 0; q < 2; q++) phi12(x->beta, GL2_S[q] * p->T, &x->phi1_g[q], &x->phi2_g[q]);
    }
}

ModelStatus model_initialize(ModelInstance *m) {
    ModelPrivate *p = &m->s.p;
    double Rx[3][3], Ry[3][3], Rz[3][3];
    const double ex[3] = {1, 0, 0}, ey[3] = {0, 1, 0}, ez[3] = {0, 0, 1};
    double lat = R(VR_site_latitude), Om = R(VR_site_earth_rate);
    int k;
    memset(p, 0, sizeof *p);
    if (check_parameters(m)) return MS_ERROR;
    p->n_axes = I(VR_n_axes);
    p->T = 1.0 / R(VR_servo_rate);
    init_motion(m);
    rodrigues(ex, R(VR_base_tilt_x), Rx);
    rodrigues(ey, R(VR_base_tilt_y), Ry);
    rodrigues(ez, R(VR_base_azimuth), Rz);
    mat_mul(Rx, Ry, p->C_b0n);
    mat_mul(p->C_b0n, Rz, p->C_b0n);
    p->w_ie_n[0] = 0.0;
    p->w_ie_n[1] = Om * cos(lat);
    p->w_ie_n[2] = Om * sin(lat);
    mat_tvec(p->C_b0n, p->w_ie_n, p->w_ie_b0);
    p->g = R(VR_site_gravity) > 0.0 ? R(VR_site_gravity) : normal_gravity(lat, R(VR_site_height));
    for (k = 0; k < p->n_axes; k++) {
        TTAxis *x = &p->ax[k];
        if (!stage_geometry(m, &AXVR[k], x)) {
            model_log(m, MS_ERROR,
                      "parameter %s.axis = (%g, %g, %g): expected a non-zero axis vector",
                      k == 0 ? "outer" : (k == 1 ? "middle" : "inner"), R(AXVR[k].axis[0]),
                      R(AXVR[k].axis[1]), R(AXVR[k].axis[2]));
            return MS_ERROR;
        }
        x->th = x->th_ref = R(AXVR[k].angle0);
    }
    axis_outputs(m);
    plate_outputs(m);
    for (k = 0; k < 3; k++) R(VR_plate_omega_int_x + k) = R(VR_plate_f_int_x + k) = 0.0;
    return MS_OK;
}

static ModelStatus check_inputs(ModelInstance *m) {
    int k;
    for (k = 0; k < m->s.p.n_axes; k++) {
        const AxisVR *vr = &AXVR[k];
        int in[2] = {vr->angle_cmd, vr->rate_cmd}, i;
        for (i = 0; i < 2; i++)
            if (!isfinite(R(in[i]))) {
                model_log(m, MS_ERROR, "input %s = %g: expected a finite value",
                          REAL_NAME[in[i]], R(in[i]));
                return MS_ERROR;
            }
        if (check_mode(m, vr)) return MS_ERROR;
    }
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    ModelPrivate *p = &m->s.p;
    double ratio = h / p->T, n = round(ratio);
    long long j;
    int k;
    if (n < 1.0 || fabs(h - n * p->T) > 1e-9 * h || n > 1e12) {
        model_log(m, MS_ERROR,
                  "communication step %.12g s: expected an integer multiple of the controller "
                  "period T = %.12g s (servo.rate = %g Hz)", h, p->T, R(VR_servo_rate));
        return MS_ERROR;
    }
    double wi[3] = {0.0, 0.0, 0.0}, fi[3] = {0.0, 0.0, 0.0};
    long long nrest = 0; /* ticks of the current run with every axis stuck */
    if (check_inputs(m)) return MS_ERROR;
    for (j = 0; j < (long long)n; j++) {
        TickMotion mo[TT_MAX_AXES];
        double th0[TT_MAX_AXES];
        int rest = 1;
        for (k = 0; k < p->n_axes; k++) {
            servo_tick(m, k, j, &mo[k]);
            rest = rest && mo[k].stuck;
            th0[k] = mo[k].th0;
        }
        if (rest) { /* the whole table at rest: integrate the run of such ticks at its end */
            nrest++;
            continue;
        }
        rest_integrals(p, th0, nrest, wi, fi); /* th0: where the table rested */
        nrest = 0;
        tick_integrals(p, mo, wi, fi);
    }
    {
        double th[TT_MAX_AXES];
        for (k = 0; k < p->n_axes; k++) th[k] = p->ax[k].th;
        rest_integrals(p, th, nrest, wi, fi);
    }
    p->tick += (long long)n;
    axis_outputs(m);
    plate_outputs(m);
    for (k = 0; k < 3; k++) {
        R(VR_plate_omega_int_x + k) = wi[k];
        R(VR_plate_f_int_x + k) = fi[k];
    }
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m;
    return MS_OK;
}
