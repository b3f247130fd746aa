/* The IMU's input signal between communication points: the knots the master's inputs make, and
 * the motion and temperature at any instant from them (see model.c for the other files).
 *
 * - Input signal between communication points. The inputs are stored as knots (value and
 *   derivatives at a communication point, last IMU_MAX_KNOTS kept).
 *     input_timing 0 (default): the inputs set before doStep(t, h) are the values at t + h; the
 *       inputs present at exitInitializationMode are the knot at the start time. Between two
 *       knots the signal is the cubic Hermite interpolant; beyond the newest knot the last cubic
 *       is extrapolated, before the oldest the first one.
 *     input_integrals 1 (either timing): omega_int and f_int set with a knot are the integrals
 *       of omega and f over the interval [previous knot, this knot] (the communication step just
 *       ended, computed by the motion source: the turntable's plate.omega_int / plate.f_int).
 *       Between the two knots the signal is then the quartic
 *         p(u) = H(u) + c u^2 (1 - u)^2,  u = (tau - t_a) / (t_b - t_a) in [0, 1],
 *       H the cubic Hermite above: the bump has zero value and slope at both knots, so the
 *       quartic keeps both end values and derivatives (C1 across knots) and, since the integral
 *       of u^2 (1 - u)^2 over [0, 1] is 1/30, c = 30 (I / dt - (y_a + y_b) / 2 - dt (y'_a - y'_b)
 *       / 12) makes its integral exactly I. Every effect linear in the motion therefore gets the
 *       exact increment however the motion moved inside the step (servo transients: the torque
 *       is piecewise constant at 2 kHz, not a cubic over 5 ms), the others a better interpolant.
 *       alpha inside the interval is the quartic's derivative (its integral is still exactly
 *       omega_b - omega_a). Outside [t_a, t_b] (extrapolation with imu.time_offset) the bump is
 *       left out: the cubic extension continues C1 and does not amplify u^4. An IMU late by dt
 *       (input_timing 0) extrapolates the motion over the last dt of each window; the next step
 *       integrates that piece again on its knot and adds the difference to its sample, so the
 *       sums of samples are the interpolant's (the error does not pile up over a move). The first knot has
 *       no interval, so no bump. The integrals must cover exactly the IMU's own step: a source
 *       stepping with a different h (multi-rate) must not be connected to them.
 *     input_timing 1: the inputs set before doStep(t, h) are the values at t; beyond the newest
 *       knot the signal is its Taylor polynomial (orders 1..3).
 *   Knot derivatives: omega' = alpha input, unless the master set an FMI input derivative of
 *   omega (then that, per vector: any non-zero component of rder means "set"); omega'' and
 *   omega''' from rder only. f' = rder of f if set, else the kinematics of a constant vector
 *   seen in the rotating frame, f' = -omega x f (the Earth-rate part of omega makes this wrong
 *   by |omega_ie| g ~ 7e-4 m/s3 at rest; its integral over a step cancels exactly); f'' = rder
 *   if set else -alpha x f - omega x f'; f''' = rder or 0. The angular acceleration inside a
 *   step is the derivative of the omega interpolant, so alpha and omega stay consistent.
 */
#include <math.h>
#include <string.h>

#include "imu.h"
#include "vec3.h"

/* ================================================================ input signal */

static int any_nonzero(const double *d0, const double *d1, const double *d2) {
    return *d0 != 0.0 || *d1 != 0.0 || *d2 != 0.0;
}

/* The knot of the current inputs at time t (derivative rules: see the top comment). */
void knot_from_inputs(const ModelInstance *m, double t, ImuKnot *k) {
    const double(*rd)[MAX_INPUT_DERIVATIVE_ORDER] = m->s.rder;
    memset(k, 0, sizeof *k);
    k->t = t;
    k->tenv = R(VR_temperature_env);
    for (int i = 0; i < 3; i++) {
        k->w[i] = R(VR_omega_x + i);
        k->f[i] = R(VR_f_x + i);
    }
    for (int o = 0; o < 3; o++) {
        int w_set = any_nonzero(&rd[VR_omega_x][o], &rd[VR_omega_y][o], &rd[VR_omega_z][o]);
        int f_set = any_nonzero(&rd[VR_f_x][o], &rd[VR_f_y][o], &rd[VR_f_z][o]);
        for (int i = 0; i < 3; i++) {
            if (w_set) k->wd[o][i] = rd[VR_omega_x + i][o];
            else if (o == 0) k->wd[o][i] = R(VR_alpha_x + i);
            if (f_set) k->fd[o][i] = rd[VR_f_x + i][o];
        }
        if (!f_set && o == 0) {
            double wxf[3];
            cross3(k->w, k->f, wxf);
            for (int i = 0; i < 3; i++) k->fd[0][i] = -wxf[i];
        } else if (!f_set && o == 1) {
            double axf[3], wxfd[3];
            cross3(k->wd[0], k->f, axf);
            cross3(k->w, k->fd[0], wxfd);
            for (int i = 0; i < 3; i++) k->fd[1][i] = -axf[i] - wxfd[i];
        }
    }
}

/* Append a knot (dropping the oldest when full), or replace the newest one at the same time. */
void push_knot(ModelPrivate *p, const ImuKnot *k, double tol) {
    if (p->nknots > 0 && fabs(p->knot[p->nknots - 1].t - k->t) <= tol) {
        p->knot[p->nknots - 1] = *k;
        return;
    }
    if (p->nknots == IMU_MAX_KNOTS) {
        memmove(&p->knot[0], &p->knot[1], (IMU_MAX_KNOTS - 1) * sizeof p->knot[0]);
        p->nknots--;
    }
    p->knot[p->nknots++] = *k;
}

/* input_integrals 1: the bump coefficients of the interval ending at the newest knot, from the
 * integral inputs (see the top comment). */
void set_bump(const ModelInstance *m, ModelPrivate *p) {
    ImuKnot *kb = &p->knot[p->nknots - 1];
    kb->bump = 0;
    if (I(VR_input_integrals) != 1 || p->nknots < 2) return;
    const ImuKnot *ka = &p->knot[p->nknots - 2];
    double dt = kb->t - ka->t;
    for (int i = 0; i < 3; i++) {
        kb->cw[i] = 30.0 * (R(VR_omega_int_x + i) / dt - 0.5 * (ka->w[i] + kb->w[i]) -
                            dt * (ka->wd[0][i] - kb->wd[0][i]) / 12.0);
        kb->cf[i] = 30.0 * (R(VR_f_int_x + i) / dt - 0.5 * (ka->f[i] + kb->f[i]) -
                            dt * (ka->fd[0][i] - kb->fd[0][i]) / 12.0);
    }
    kb->bump = 1;
}

/* Cubic Hermite through knots a, b, evaluated at tau (also outside [a.t, b.t]), plus the
 * integral-matching bump of knot b inside [a.t, b.t] (input_integrals 1). */
static void hermite(const ImuKnot *ka, const ImuKnot *kb, double tau, Motion *mo) {
    double dt = kb->t - ka->t;
    double u = (tau - ka->t) / dt, u2 = u * u, u3 = u2 * u;
    double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
    double d00 = 6 * u2 - 6 * u, d10 = 3 * u2 - 4 * u + 1, d01 = -d00, d11 = 3 * u2 - 2 * u;
    for (int i = 0; i < 3; i++) {
        mo->w[i] = h00 * ka->w[i] + h10 * dt * ka->wd[0][i] + h01 * kb->w[i] + h11 * dt * kb->wd[0][i];
        mo->a[i] = (d00 * ka->w[i] + d01 * kb->w[i]) / dt + d10 * ka->wd[0][i] + d11 * kb->wd[0][i];
        mo->f[i] = h00 * ka->f[i] + h10 * dt * ka->fd[0][i] + h01 * kb->f[i] + h11 * dt * kb->fd[0][i];
    }
    if (kb->bump && u >= 0.0 && u <= 1.0) {
        double b = u2 * (1.0 - u) * (1.0 - u), db = (2.0 * u - 6.0 * u2 + 4.0 * u3) / dt;
        for (int i = 0; i < 3; i++) {
            mo->w[i] += kb->cw[i] * b;
            mo->a[i] += kb->cw[i] * db;
            mo->f[i] += kb->cf[i] * b;
        }
    }
}

/* Taylor polynomial (orders 1..3) of the knot, at tau. */
static void taylor(const ImuKnot *k, double tau, Motion *mo) {
    double d = tau - k->t, d2 = d * d / 2, d3 = d * d * d / 6;
    for (int i = 0; i < 3; i++) {
        mo->w[i] = k->w[i] + d * k->wd[0][i] + d2 * k->wd[1][i] + d3 * k->wd[2][i];
        mo->a[i] = k->wd[0][i] + d * k->wd[1][i] + d2 * k->wd[2][i];
        mo->f[i] = k->f[i] + d * k->fd[0][i] + d2 * k->fd[1][i] + d3 * k->fd[2][i];
    }
}

/* The motion at table time tau from the knot history. */
void motion_at(const ModelInstance *m, double tau, Motion *mo) {
    const ModelPrivate *p = &m->s.p;
    int n = p->nknots;
    if (n == 1 || (tau > p->knot[n - 1].t && I(VR_input_timing) == 1)) {
        taylor(&p->knot[n - 1], tau, mo);
        return;
    }
    int k = 0; /* segment [knot k, knot k+1]; outside the history: the end segments */
    while (k < n - 2 && tau > p->knot[k + 1].t) k++;
    hermite(&p->knot[k], &p->knot[k + 1], tau, mo);
}

/* Temperature at sensor time s. */
double temperature_at(const ModelInstance *m, double s) {
    const ModelPrivate *p = &m->s.p;
    switch (I(VR_temperature_mode)) {
    case 1:
        return R(VR_temperature_start) + R(VR_temperature_rate) * (s - m->s.start_time);
    case 2: {
        int n = p->nknots;
        if (n == 1 || s >= p->knot[n - 1].t) return p->knot[n - 1].tenv;
        if (s <= p->knot[0].t) return p->knot[0].tenv;
        int k = 0;
        while (k < n - 2 && s > p->knot[k + 1].t) k++;
        double u = (s - p->knot[k].t) / (p->knot[k + 1].t - p->knot[k].t);
        return p->knot[k].tenv + u * (p->knot[k + 1].tenv - p->knot[k].tenv);
    }
    default:
        return R(VR_temperature_start);
    }
}
