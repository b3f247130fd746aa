/* The turntable's servo loops and the motion of each axis (see model.c for the other files).
 *
 * Servo (per axis, controller period T = 1 / servo.rate; time is an integer tick count):
 *   tick k at t_k: (1) the reference generator holds (th_ref, w_ref) at t_k and chooses the
 *   constant acceleration a_ref over [t_k, t_k+T] (rate and acceleration limited, time-optimal
 *   braking curve, exact snap onto the target when within one tick's reach); (2) the encoder
 *   reads the true angle (harmonic errors, then quantisation to 2 pi / 2^bits, round to nearest);
 *   (3) e = th_ref - th_meas (0 when the reading is the count nearest th_ref: the servo compares
 *   counts), u = D(z) e + ff (J a_ref + B w_mid + Tc sign(w_mid)), w_mid the reference rate at
 *   the middle of the tick (the mean rate over the tick, which is what a constant torque has to
 *   overcome for viscous friction; the Coulomb term is the usual model-based friction
 *   compensation: without it the integrator carries +-Tc into every stop, where stiction turns
 *   it into a one-count overshoot that takes ~5 s to work off), saturated at +-torque_max;
 *   (4) the plant moves with the torque held (ZOH) under stick-slip (Karnopp) friction:
 *   sliding, J th'' = u - B th' - Tc sign(th'), solved in closed form over the tick (linear with
 *   constant coefficients while the direction is fixed); an axis at rest, or slower than
 *   servo.stick_velocity, sticks (th' = th'' = 0 exactly, angle unchanged) while the applied
 *   torque |u - B th'| <= Fs = max(static_friction, coulomb), else breaks away in the direction
 *   of u; when the rate reaches zero inside a tick (located exactly) the axis sticks for the
 *   rest of it if |u| <= Fs, else reverses. A pure step in position mode appears in th_ref one
 *   tick later (th_ref(t_k) was committed at the previous tick), like any discrete reference.
 *   Why stick-slip: the former smoothed law Tc tanh(th'/w_s) has no static state; a held axis
 *   crept (3e-8 rad/s after a 90 deg index, a navigation-grade gyro bias, under a dwell that a
 *   calibration takes as static). Default Fs = Tc: no friction drop at breakaway, so the integral
 *   action cannot hunt (measured: Fs = 1.5 Tc on the middle axis hunts +-7 counts for > 15 s).
 *   stick_velocity (default 1e-6 rad/s = 0.2 deg/h) only absorbs rates that would stop within
 *   a fraction of a tick anyway (zero crossings are located exactly); stopping at once moves the
 *   axis by < stick_velocity * T = 5e-10 rad, 1/700 of a 24-bit count.
 * Position mode target: p(t) = angle_cmd + rate_cmd (t - t_comm), t_comm = start of the doStep.
 */
#include <math.h>
#include "turntable.h"

/* ------------------------------------------------------------------ closed-form axis motion */

/* phi1(t) = (1 - exp(-beta t)) / beta and phi2(t) = (t - phi1(t)) / beta, the rate and angle
 * gained per unit initial acceleration under a constant torque and viscous friction (t and
 * t^2 / 2 for beta = 0). Below beta t = 1e-3 the Taylor series: t - phi1 would cancel. */
void phi12(double beta, double t, double *p1, double *p2) {
    double z = beta * t;
    if (z < 1e-3) {
        *p1 = t * (1.0 - z / 2.0 * (1.0 - z / 3.0 * (1.0 - z / 4.0 * (1.0 - z / 5.0 * (1.0 - z / 6.0)))));
        *p2 = t * t / 2.0 * (1.0 - z / 3.0 * (1.0 - z / 4.0 * (1.0 - z / 5.0 * (1.0 - z / 6.0 * (1.0 - z / 7.0)))));
    } else {
        *p1 = -expm1(-z) / beta;
        *p2 = (t - *p1) / beta;
    }
}

/* Angle and rate of the axis at time t in [0, T] of the tick (closed form). */
void motion_at(const TTAxis *x, const TickMotion *mo, double t, double *th, double *thd) {
    double p1, p2;
    if (t <= mo->te) {
        phi12(x->beta, t, &p1, &p2);
        *th = mo->th0 + (mo->v0 * t + mo->a0 * p2);
        *thd = mo->v0 + mo->a0 * p1;
    } else {
        phi12(x->beta, t - mo->te, &p1, &p2);
        *th = mo->th_e + mo->a1 * p2;
        *thd = mo->a1 * p1;
    }
}

/* ------------------------------------------------------------------ servo */

static double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* Encoder reading of a true (multi-turn) angle: harmonic errors, then quantisation to
 * 2 pi / 2^bits rounded to the nearest count (bits = 0: no quantisation). A zero amplitude
 * skips its sine (the same value: y + 0 = y), which is most of the cost at rest. */
double encoder(ModelInstance *m, const AxisVR *vr, double th) {
    int bits = I(vr->bits);
    double y = th, q;
    if (R(vr->h1_amp) != 0.0) y += R(vr->h1_amp) * sin(th + R(vr->h1_phase));
    if (R(vr->h2_amp) != 0.0) y += R(vr->h2_amp) * sin(2.0 * th + R(vr->h2_phase));
    if (bits == 0) return y;
    q = ldexp(2.0 * M_PI, -bits);
    return round(y / q) * q;
}

/* What the axis's encoder reads: the plate's angle less the play of a backlash of width
 * `encoder.reversal` between the plate and the encoder (a play operator: the plate moves the
 * play until it reaches +-reversal / 2, then takes the encoder with it). After a move longer
 * than the reversal the servo holds the reading with the plate half the reversal past it, on
 * the side it came from; the reading does not change while the play is taken up. A negative
 * reversal puts the plate short of the reading instead (a servo that stops before the count). */
double reading(ModelInstance *m, const AxisVR *vr, const TTAxis *x) {
    return encoder(m, vr, R(vr->reversal) < 0.0 ? x->th + x->play : x->th - x->play);
}

/* Breakaway torque: static_friction, not below the Coulomb torque (a static friction below it
 * would make an axis that reaches zero rate with Fs < |u| < Tc chatter; the default 0 thus
 * means Fs = Tc). */
static double static_friction(ModelInstance *m, const AxisVR *vr) {
    return fmax(R(vr->static_friction), R(vr->coulomb));
}

static double sgn(double x) { return x > 0.0 ? 1.0 : -1.0; }

/* Move the axis over one controller tick under the held torque u with stick-slip (Karnopp)
 * friction, in closed form, and describe the motion in *mo for the step integrals.
 * Sliding (rate of sign s): J th'' = u - s Tc - B th', linear with constant coefficients, so
 *   th'(t) = v0 + a0 phi1(t),  th(t) = th0 + v0 t + a0 phi2(t),  a0 = (u - s Tc - B v0) / J.
 * When the rate reaches zero at te inside the tick the axis sticks for the rest of it if
 * |u| <= Fs, else it slides on in the direction of u from rest. At rest (or within the Karnopp
 * band |th'| < stick_velocity) it stays stuck, rate and acceleration exactly 0, while the applied
 * torque |u - B th'| <= Fs. No integrator error: the friction's switching instants are located
 * exactly instead of being smoothed (the former tanh law made the held axis creep). */
static void axis_tick(ModelInstance *m, const AxisVR *vr, TTAxis *x, double u, TickMotion *mo) {
    double T = m->s.p.T, J = R(vr->inertia), B = R(vr->viscous), Tc = R(vr->coulomb);
    double Fs = static_friction(m, vr), v0 = x->thd, s, v1, p1, p2;
    if (v0 != 0.0 && fabs(v0) < R(VR_servo_stick_velocity) && fabs(u - B * v0) <= Fs) v0 = 0.0;
    mo->th0 = mo->th_e = x->th;
    mo->v0 = v0;
    mo->te = T;
    mo->a1 = 0.0;
    mo->stuck = v0 == 0.0 && fabs(u) <= Fs;
    if (mo->stuck) {
        mo->a0 = 0.0;
        x->thd = x->thdd = 0.0;
        return;
    }
    s = v0 != 0.0 ? sgn(v0) : sgn(u); /* from rest: breakaway in the direction of u */
    mo->a0 = (u - s * Tc - B * v0) / J;
    v1 = v0 + mo->a0 * x->phi1_T;
    if (v0 == 0.0 || s * v1 > 0.0) { /* slides through the whole tick */
        x->th = mo->th0 + (v0 * T + mo->a0 * x->phi2_T);
        x->thd = v1;
        x->thdd = (u - s * Tc - B * v1) / J;
        return;
    }
    /* the rate reaches zero at te: phi1(te) = -v0 / a0 */
    {
        double r = -v0 / mo->a0, te = x->beta > 0.0 ? -log1p(-x->beta * r) / x->beta : r;
        mo->te = te >= 0.0 && te <= T ? te : T; /* also catches NaN from rounding */
    }
    phi12(x->beta, mo->te, &p1, &p2);
    mo->th_e = mo->th0 + (v0 * mo->te + mo->a0 * p2);
    if (fabs(u) <= Fs) { /* sticks */
        x->th = mo->th_e;
        x->thd = x->thdd = 0.0;
        return;
    }
    s = sgn(u); /* reverses */
    mo->a1 = (u - s * Tc) / J;
    phi12(x->beta, T - mo->te, &p1, &p2);
    x->th = mo->th_e + mo->a1 * p2;
    x->thd = mo->a1 * p1;
    x->thdd = (u - s * Tc - B * x->thd) / J;
}

/* Reference generator: from (th_ref, w_ref) at t_k choose the acceleration a_ref held over the
 * tick, aiming at position p1 and rate v at t_k + T (position mode) and return the state at
 * t_k + T through th1 / w1. Near-time-optimal: the desired rate at the end of the tick is the
 * target rate plus the braking-curve rate sqrt(2 a_max |e|) for the error left after coasting
 * one tick (evaluating the curve one tick ahead is what removes the discrete overshoot); when
 * the target is reachable within one tick's acceleration the reference snaps exactly onto it, so
 * it rests on the target without chatter. */
static void ref_position(const TTAxis *x, double p1, double v, double amax, double wmax, double T,
                         double *th1, double *w1, double *acc) {
    double e1, vd;
    v = clamp(v, -wmax, wmax);
    if (fabs(v - x->w_ref) <= amax * T &&
        fabs(p1 - (x->th_ref + 0.5 * (x->w_ref + v) * T)) <= 0.5 * amax * T * T) {
        *th1 = p1;
        *w1 = v;
        *acc = (v - x->w_ref) / T;
        return;
    }
    /* e1: the error left if the rate went to v over the tick; the end-of-tick rate vd solves
     * (vd - v)^2 = 2 amax (error left at the end of the tick) consistently, so a reference on
     * the braking curve stays on it exactly (a trapezoidal braking covers w^2 / 2 amax) and
     * arrives without overshooting */
    e1 = p1 - (x->th_ref + 0.5 * (x->w_ref + v) * T);
    vd = clamp(v + copysign(0.5 * (sqrt(amax * amax * T * T + 8.0 * amax * fabs(e1)) - amax * T),
                            e1), -wmax, wmax);
    *acc = clamp((vd - x->w_ref) / T, -amax, amax);
    *th1 = x->th_ref + x->w_ref * T + 0.5 * *acc * T * T;
    *w1 = x->w_ref + *acc * T;
}

/* Rate mode: the reference rate approaches rate_cmd at the acceleration limit; the angle
 * integrates it exactly (constant acceleration over the tick). */
static void ref_rate(const TTAxis *x, double v, double amax, double wmax, double T, double *th1,
                     double *w1, double *acc) {
    v = clamp(v, -wmax, wmax);
    *acc = clamp((v - x->w_ref) / T, -amax, amax);
    *w1 = fabs(v - x->w_ref) <= amax * T ? v : x->w_ref + *acc * T;
    *th1 = x->th_ref + 0.5 * (x->w_ref + *w1) * T;
}

/* One controller tick of one axis; j = ticks since the start of the current doStep. */
void servo_tick(ModelInstance *m, int k, long long j, TickMotion *mo) {
    ModelPrivate *p = &m->s.p;
    const AxisVR *vr = &AXVR[k];
    TTAxis *x = &p->ax[k];
    double T = p->T, amax = R(vr->acc_max), wmax = R(vr->rate_max);
    double J = R(vr->inertia), B = R(vr->viscous), umax = R(vr->torque_max);
    double th1, w1, acc, e, ufb, uff, u, wm, th_before;
    /* (1) reference over [t_k, t_k + T] */
    if (I(vr->mode) == 0) {
        double p1 = R(vr->angle_cmd) + R(vr->rate_cmd) * ((double)(j + 1) * T);
        ref_position(x, p1, R(vr->rate_cmd), amax, wmax, T, &th1, &w1, &acc);
    } else {
        ref_rate(x, R(vr->rate_cmd), amax, wmax, T, &th1, &w1, &acc);
    }
    /* (2) measurement, (3) control law */
    e = x->th_ref - reading(m, vr, x);
    /* A digital servo compares counts: when the reading is the count nearest the reference the
     * error is zero, so a stuck axis holds with a constant integrator instead of winding it up
     * against static friction until it breaks away and hunts between two counts (a reference
     * that is not on a count would otherwise never be met). */
    if (I(vr->bits) > 0 && fabs(e) < 0.5 * ldexp(2.0 * M_PI, -I(vr->bits))) e = 0.0;
    ufb = R(vr->b0) * e + R(vr->b1) * x->e1 + R(vr->b2) * x->e2 - R(vr->a1) * x->u1 -
          R(vr->a2) * x->u2;
    wm = 0.5 * (x->w_ref + w1);
    uff = R(VR_servo_feedforward) *
          (J * acc + B * wm + (wm != 0.0 ? R(vr->coulomb) * sgn(wm) : 0.0));
    u = clamp(ufb + uff, -umax, umax);
    /* the controller remembers the feedback torque actually applied: when the motor saturates
     * its integrator stops winding up (anti-windup of the direct-form filter) */
    x->e2 = x->e1;
    x->e1 = e;
    x->u2 = x->u1;
    x->u1 = u - uff;
    x->torque = u;
    /* (4) plant */
    th_before = x->th;
    axis_tick(m, vr, x, u, mo);
    x->play = clamp(x->play + (x->th - th_before), -0.5 * fabs(R(vr->reversal)), 0.5 * fabs(R(vr->reversal)));
    x->th_ref = th1;
    x->w_ref = w1;
    x->a_ref = acc;
}
