/* calbench turntable: gimbal chain, base, Earth, and one discrete servo loop per axis.
 *
 * Conventions (see also /work/shared/design/domain.md §1-§5)
 * -----------------------------------------------------------
 * Frames: n = ENU (x east, y north, z up); b0 = turntable base; stage k = frame carried by the
 *   k-th axis (1 outer, 2 middle, 3 inner); p = plate = frame of the innermost used stage.
 * C_x^y maps vectors given in frame x to frame y.
 * Rotations are active and right-handed. R(a, t) is the Rodrigues matrix
 *   R = I + sin t [a]x + (1 - cos t) [a]x^2;  Rot(w) = R(w/|w|, |w|) for a rotation vector w.
 * Base: C_b0^n = R(x, base.tilt.x) R(y, base.tilt.y) R(z, base.azimuth).
 * Axis k: a_k = Rot(delta_k) normalize(<a>.axis), delta_k = <a>.nonorth (rotation vector in
 *   the previous stage's frame; exact Rodrigues rotation of the axis vector, not linearised).
 * Wobble of axis k (amplitude A, phase phi): the stage transform is
 *   T_k = C_k^{k-1} = Rot(w_k) R(a_k, t_k),  w_k = A [cos(t_k + phi) u + sin(t_k + phi) v],
 *   u = normalize(e_j x a_k), e_j the basis vector (x, then y, then z on ties) with the smallest
 *   |a_k . e_j|, v = a_k x u.  Because w_k = R(a_k, t_k + phi) (A u), the same transform is
 *   T_k = R(a_k, t_k + phi) Rot(A u) R(a_k, -phi): a rigid rotation about a_k of a body mounted
 *   with a fixed tilt. Its relative angular rate in stage-k axes is therefore EXACTLY
 *   rho_k = t'_k b_k with the constant unit vector b_k = R(a_k, phi) Rot(-A u) a_k
 *   (= a_k when A = 0). This is the "rate contribution of the wobble", exact rather than only to
 *   first order, and it keeps plate.omega the true derivative of the attitude.
 * Chain: C_p^b0 = T_1 T_2 T_3 (only the n_axes used stages); C_p^n = C_b0^n C_p^b0.
 * Rates (plate axes, Earth rate included), recursion from the base outwards:
 *   omega_0 = C_n^b0 omega_ie^n,  omega_k = T_k^T omega_{k-1} + t'_k b_k
 *   alpha_0 = 0,  alpha_k = T_k^T alpha_{k-1} + t''_k b_k + (T_k^T omega_{k-1}) x (t'_k b_k)
 *   (the last term is d/dt T_k^T applied to omega_{k-1}).
 * Earth: omega_ie^n = [0, Omega cos L, Omega sin L]; gravity g = site.gravity if > 0, else WGS-84
 *   normal gravity (Somigliana) with the second-order height correction. Specific force at rest
 *   f^n = [0, 0, +g]; plate.f = C_n^p f^n at the axes' intersection (no lever arm).
 * plate.q: quaternion of C_p^n, scalar first, w >= 0.
 * Outputs are computed from the TRUE angles, rates and accelerations; the acceleration at the
 *   end of a step is the left limit (torque of the last controller tick).
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
 *
 * Integrals over the communication step (plate.omega_int, plate.f_int): the integrals of
 *   plate.omega and plate.f over the step just ended, for a consumer (the IMU) that must get the
 *   increments right although the motion inside a step is not a polynomial (the torque is
 *   piecewise constant at the controller rate, so the acceleration jumps at every tick). Per tick
 *   each axis moves in closed form, smooth between the instants where a rate reaches zero; the
 *   tick is split there (rare: ~2 ticks per index) and the kinematics (omega, f of the angles and
 *   rates of every used stage, the axes evaluated exactly) are integrated over each piece with
 *   2-point Gauss-Legendre (error piece^5/4320 times the 4th derivative of the integrand). Measured
 *   (tests/test_coupling.py): during a 90 deg index of all three axes the per-tick integral of
 *   omega agrees with an independent 64-substep RK4 + Simpson integral of the same ODE to 2e-17
 *   rad, 2e-13 in the two ticks with a friction switch; a navigation-grade gyro's per-sample
 *   noise at 5 ms is 4e-8 rad. Fast path: ticks in which every axis is stuck have constant omega
 *   and f; a run of them is integrated as value * (ticks * T), the kinematics evaluated once per
 *   run (normally once per step) instead of twice per tick.
 *   In Initialization Mode both are 0 (an empty interval).
 */
#include <math.h>
#include <string.h>
#include "model_instance.h"
#include "vec3.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ------------------------------------------------------------------ value references */

typedef struct {
    int axis[3], nonorth[3];
    int inertia, viscous, coulomb, static_friction, torque_max, rate_max, acc_max, angle0;
    int b0, b1, b2, a1, a2;
    int bits; /* Integer */
    int h1_amp, h1_phase, h2_amp, h2_phase, wob_amp, wob_phase;
    int mode; /* Integer */
    int angle_cmd, rate_cmd;
    int angle, rate, angle_true, angle_ref, torque;
} AxisVR;

#define AXIS_VR(n)                                                                              \
    {{VR_##n##_axis_x, VR_##n##_axis_y, VR_##n##_axis_z},                                       \
     {VR_##n##_nonorth_x, VR_##n##_nonorth_y, VR_##n##_nonorth_z},                              \
     VR_##n##_inertia, VR_##n##_viscous, VR_##n##_coulomb, VR_##n##_static_friction,            \
     VR_##n##_torque_max,                                                                       \
     VR_##n##_rate_max, VR_##n##_acc_max, VR_##n##_angle0,                                      \
     VR_##n##_ctrl_b0, VR_##n##_ctrl_b1, VR_##n##_ctrl_b2, VR_##n##_ctrl_a1, VR_##n##_ctrl_a2,  \
     VR_##n##_encoder_bits,                                                                     \
     VR_##n##_encoder_h1_amp, VR_##n##_encoder_h1_phase, VR_##n##_encoder_h2_amp,               \
     VR_##n##_encoder_h2_phase, VR_##n##_wobble_amp, VR_##n##_wobble_phase,                     \
     VR_##n##_mode, VR_##n##_angle_cmd, VR_##n##_rate_cmd,                                      \
     VR_##n##_angle, VR_##n##_rate, VR_##n##_angle_true, VR_##n##_angle_ref, VR_##n##_torque}

static const AxisVR AXVR[TT_MAX_AXES] = {AXIS_VR(outer), AXIS_VR(middle), AXIS_VR(inner)};

/* The code indexes the integrals' components from .x. */
_Static_assert(VR_plate_omega_int_z == VR_plate_omega_int_x + 2 &&
                   VR_plate_f_int_z == VR_plate_f_int_x + 2, "integral outputs consecutive");

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

static double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* ------------------------------------------------------------------ Earth */

/* WGS-84 normal gravity (Somigliana) with the second-order free-air height correction. */
static double normal_gravity(double lat, double h) {
    const double a = 6378137.0, f = 1.0 / 298.257223563, mm = 0.00344978650684;
    double s2 = sin(lat) * sin(lat);
    double g0 = 9.7803253359 * (1.0 + 0.00193185265241 * s2) / sqrt(1.0 - 0.00669437999013 * s2);
    return g0 * (1.0 - 2.0 / a * (1.0 + f + mm - 2.0 * f * s2) * h + 3.0 * h * h / (a * a));
}

/* ------------------------------------------------------------------ gimbal geometry */

/* Stage transform T = C_k^{k-1} = Rot(w) R(a, th) with the wobble tilt w of the convention. */
static void stage_matrix(const TTAxis *x, double th, double T[3][3]) {
    double Ra[3][3], W[3][3], w[3];
    int i;
    rodrigues(x->a, th, Ra);
    if (x->wob_amp == 0.0) {
        memcpy(T, Ra, sizeof Ra);
        return;
    }
    for (i = 0; i < 3; i++)
        w[i] = x->wob_amp * (cos(th + x->wob_phase) * x->u[i] + sin(th + x->wob_phase) * x->v[i]);
    rot_vec(w, W);
    mat_mul(W, Ra, T);
}

/* Set a (non-orthogonality applied), the wobble basis u, v and the rate axis b of one stage
 * from its parameters. Returns 0 when the axis vector is zero. */
static int stage_geometry(ModelInstance *m, const AxisVR *vr, TTAxis *x) {
    double a0[3], d[3], D[3][3], W0[3][3], Rp[3][3], tilt[3], n, best;
    int k, j = 0;
    for (k = 0; k < 3; k++) {
        a0[k] = R(vr->axis[k]);
        d[k] = R(vr->nonorth[k]);
    }
    n = norm3(a0);
    if (!(n > 0.0)) return 0;
    scale3(a0, 1.0 / n);
    rot_vec(d, D);
    mat_vec(D, a0, x->a);
    scale3(x->a, 1.0 / norm3(x->a)); /* remove rounding: a stays a unit vector */
    /* u: basis vector least aligned with a (x, then y, then z on ties), crossed with a */
    best = fabs(x->a[0]);
    for (k = 1; k < 3; k++)
        if (fabs(x->a[k]) < best) {
            best = fabs(x->a[k]);
            j = k;
        }
    {
        double e[3] = {0.0, 0.0, 0.0};
        e[j] = 1.0;
        cross3(e, x->a, x->u);
    }
    scale3(x->u, 1.0 / norm3(x->u));
    cross3(x->a, x->u, x->v);
    x->wob_amp = R(vr->wob_amp);
    x->wob_phase = R(vr->wob_phase);
    /* b = R(a, phi) Rot(-A u) a: see the header comment */
    for (k = 0; k < 3; k++) tilt[k] = -x->wob_amp * x->u[k];
    rot_vec(tilt, W0);
    rodrigues(x->a, x->wob_phase, Rp);
    mat_vec(W0, x->a, x->b);
    mat_vec(Rp, x->b, x->b);
    return 1;
}

/* Plate outputs (attitude, inertial rate and acceleration, specific force) from the true
 * angles, rates and accelerations of the used stages. */
static void plate_outputs(ModelInstance *m) {
    ModelPrivate *p = &m->s.p;
    double C[3][3], T[3][3], w[3], al[3], wc[3], rho[3], t[3], fn[3] = {0.0, 0.0, p->g}, f[3];
    double q[4];
    int k, i;
    memcpy(C, p->C_b0n, sizeof C);
    memcpy(w, p->w_ie_b0, sizeof w);
    memset(al, 0, sizeof al);
    for (k = 0; k < p->n_axes; k++) {
        const TTAxis *x = &p->ax[k];
        stage_matrix(x, x->th, T);
        mat_mul(C, T, C);
        mat_tvec(T, w, wc);   /* previous stage's rate in this stage's axes */
        mat_tvec(T, al, al);
        for (i = 0; i < 3; i++) rho[i] = x->thd * x->b[i];
        cross3(wc, rho, t);   /* transport term d/dt(T^T) omega_{k-1} */
        for (i = 0; i < 3; i++) {
            al[i] += x->thdd * x->b[i] + t[i];
            w[i] = wc[i] + rho[i];
        }
    }
    mat_tvec(C, fn, f);
    dcm_to_quat(C, q);
    R(VR_plate_omega_x) = w[0];
    R(VR_plate_omega_y) = w[1];
    R(VR_plate_omega_z) = w[2];
    R(VR_plate_alpha_x) = al[0];
    R(VR_plate_alpha_y) = al[1];
    R(VR_plate_alpha_z) = al[2];
    R(VR_plate_f_x) = f[0];
    R(VR_plate_f_y) = f[1];
    R(VR_plate_f_z) = f[2];
    R(VR_plate_q_w) = q[0];
    R(VR_plate_q_x) = q[1];
    R(VR_plate_q_y) = q[2];
    R(VR_plate_q_z) = q[3];
}

/* Inertial rate and specific force of the plate (plate axes) for the angles th[] and rates
 * thd[] of the used stages: the rate recursion of plate_outputs without the acceleration and the
 * attitude, and f carried through the same stage transforms (f_k = T_k^T f_{k-1}). */
static void plate_rate_force(const ModelPrivate *p, const double th[], const double thd[],
                             double w[3], double f[3]) {
    double T[3][3], fn[3] = {0.0, 0.0, p->g};
    int k, i;
    memcpy(w, p->w_ie_b0, 3 * sizeof(double));
    mat_tvec(p->C_b0n, fn, f);
    for (k = 0; k < p->n_axes; k++) {
        const TTAxis *x = &p->ax[k];
        if (x->wob_amp == 0.0) { /* T = R(a, th): rotate the two vectors without the matrix */
            double c = cos(th[k]), s = sin(th[k]);
            rodrigues_tvec(x->a, c, s, w);
            rodrigues_tvec(x->a, c, s, f);
        } else {
            stage_matrix(x, th[k], T);
            mat_tvec(T, w, w);
            mat_tvec(T, f, f);
        }
        for (i = 0; i < 3; i++) w[i] += thd[k] * x->b[i];
    }
}

/* 2-point Gauss-Legendre on [0, 1]: nodes (3 -+ sqrt 3) / 6, weights 1/2 */
static const double GL2_S[2] = {0.21132486540518711775, 0.78867513459481288225};

/* phi1(t) = (1 - exp(-beta t)) / beta and phi2(t) = (t - phi1(t)) / beta, the rate and angle
 * gained per unit initial acceleration under a constant torque and viscous friction (t and
 * t^2 / 2 for beta = 0). Below beta t = 1e-3 the Taylor series: t - phi1 would cancel. */
static void phi12(double beta, double t, double *p1, double *p2) {
    double z = beta * t;
    if (z < 1e-3) {
        *p1 = t * (1.0 - z / 2.0 * (1.0 - z / 3.0 * (1.0 - z / 4.0 * (1.0 - z / 5.0 * (1.0 - z / 6.0)))));
        *p2 = t * t / 2.0 * (1.0 - z / 3.0 * (1.0 - z / 4.0 * (1.0 - z / 5.0 * (1.0 - z / 6.0 * (1.0 - z / 7.0)))));
    } else {
        *p1 = -expm1(-z) / beta;
        *p2 = (t - *p1) / beta;
    }
}

/* Motion of one axis over one controller tick (torque held): the sliding piece from the tick's
 * start (angle th0, rate v0, constant-direction acceleration a0 at the start) up to te, then,
 * when te < T (the rate reached zero inside the tick), a piece from rest at angle th_e with
 * acceleration a1 at its start (0: stuck for the rest of the tick). */
typedef struct {
    double th0, v0, a0, te, th_e, a1;
    int stuck; /* at rest over the whole tick */
} TickMotion;

/* Angle and rate of the axis at time t in [0, T] of the tick (closed form). */
static void motion_at(const TTAxis *x, const TickMotion *mo, double t, double *th, double *thd) {
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

/* Add the integrals of plate.omega and plate.f over a tick in which some axis moves. The motion
 * of each axis is smooth between the instants where a rate reaches zero (friction switches
 * there), so the tick is split at them and each piece gets 2-point Gauss-Legendre with the axes
 * evaluated in closed form (error: piece^5 / 4320 times the integrand's 4th derivative). Ticks
 * without such an instant (nearly all) use the nodes' precomputed phi1, phi2. */
static void tick_integrals(const ModelPrivate *p, const TickMotion mo[], double wi[3],
                           double fi[3]) {
    double cut[TT_MAX_AXES + 2], th[TT_MAX_AXES], thd[TT_MAX_AXES], w[3], f[3];
    int nc = 0, k, i, q, c;
    cut[nc++] = 0.0;
    for (k = 0; k < p->n_axes; k++) /* insertion sort of the switching instants */
        if (mo[k].te > 0.0 && mo[k].te < p->T) {
            for (i = nc; i > 1 && cut[i - 1] > mo[k].te; i--) cut[i] = cut[i - 1];
            cut[i] = mo[k].te;
            nc++;
        }
    cut[nc++] = p->T;
    for (c = 0; c + 1 < nc; c++) {
        double len = cut[c + 1] - cut[c];
        if (!(len > 0.0)) continue;
        for (q = 0; q < 2; q++) {
            double t = cut[c] + GL2_S[q] * len;
            for (k = 0; k < p->n_axes; k++) {
                const TTAxis *x = &p->ax[k];
                if (nc == 2) { /* one smooth piece: the precomputed node values */
                    th[k] = mo[k].th0 + (mo[k].v0 * t + mo[k].a0 * x->phi2_g[q]);
                    thd[k] = mo[k].v0 + mo[k].a0 * x->phi1_g[q];
                } else {
                    motion_at(x, &mo[k], t, &th[k], &thd[k]);
                }
            }
            plate_rate_force(p, th, thd, w, f);
            for (i = 0; i < 3; i++) {
                wi[i] += 0.5 * len * w[i];
                fi[i] += 0.5 * len * f[i];
            }
        }
    }
}

/* Integrals over a run of n ticks in which every axis stuck at the angles th[]: omega and f are
 * constant, so the integral is value * n T, the kinematics evaluated once per run (normally once
 * per step) instead of twice per tick. */
static void rest_integrals(const ModelPrivate *p, const double th[], long long n, double wi[3],
                           double fi[3]) {
    static const double zero[TT_MAX_AXES] = {0.0, 0.0, 0.0};
    double w[3], f[3], len = (double)n * p->T;
    int i;
    if (n == 0) return;
    plate_rate_force(p, th, zero, w, f);
    for (i = 0; i < 3; i++) {
        wi[i] += len * w[i];
        fi[i] += len * f[i];
    }
}

/* ------------------------------------------------------------------ servo */

/* Encoder reading of a true (multi-turn) angle: harmonic errors, then quantisation to
 * 2 pi / 2^bits rounded to the nearest count (bits = 0: no quantisation). A zero amplitude
 * skips its sine (the same value: y + 0 = y), which is most of the cost at rest. */
static double encoder(ModelInstance *m, const AxisVR *vr, double th) {
    int bits = I(vr->bits);
    double y = th, q;
    if (R(vr->h1_amp) != 0.0) y += R(vr->h1_amp) * sin(th + R(vr->h1_phase));
    if (R(vr->h2_amp) != 0.0) y += R(vr->h2_amp) * sin(2.0 * th + R(vr->h2_phase));
    if (bits == 0) return y;
    q = ldexp(2.0 * M_PI, -bits);
    return round(y / q) * q;
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
static void servo_tick(ModelInstance *m, int k, long long j, TickMotion *mo) {
    ModelPrivate *p = &m->s.p;
    const AxisVR *vr = &AXVR[k];
    TTAxis *x = &p->ax[k];
    double T = p->T, amax = R(vr->acc_max), wmax = R(vr->rate_max);
    double J = R(vr->inertia), B = R(vr->viscous), umax = R(vr->torque_max);
    double th1, w1, acc, e, ufb, uff, u, wm;
    /* (1) reference over [t_k, t_k + T] */
    if (I(vr->mode) == 0) {
        double p1 = R(vr->angle_cmd) + R(vr->rate_cmd) * ((double)(j + 1) * T);
        ref_position(x, p1, R(vr->rate_cmd), amax, wmax, T, &th1, &w1, &acc);
    } else {
        ref_rate(x, R(vr->rate_cmd), amax, wmax, T, &th1, &w1, &acc);
    }
    /* (2) measurement, (3) control law */
    e = x->th_ref - encoder(m, vr, x->th);
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
    axis_tick(m, vr, x, u, mo);
    x->th_ref = th1;
    x->w_ref = w1;
    x->a_ref = acc;
}

/* ------------------------------------------------------------------ outputs, checks */

static void axis_outputs(ModelInstance *m) {
    int k;
    for (k = 0; k < TT_MAX_AXES; k++) {
        const AxisVR *vr = &AXVR[k];
        const TTAxis *x = &m->s.p.ax[k];
        int used = k < m->s.p.n_axes;
        R(vr->angle) = used ? encoder(m, vr, x->th) : 0.0;
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
