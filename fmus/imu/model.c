/* IMU sensor physics: a gyro triad and an accelerometer triad with the error effects of
 * domain.md §4, noise, and increment / rate / count outputs.
 *
 * CONVENTIONS
 * - Axes: everything in mounting (plate) axes. Inputs omega = inertial rate [rad/s], f = specific
 *   force at the plate reference point [m/s2], alpha = d omega/dt [rad/s2].
 * - Time: "sensor time" s runs with the FMU clock. The motion seen at sensor time s is the
 *   motion of the table at tau = s + imu.time_offset (dt): the sample labelled t holds the motion
 *   of (t - h + dt, t + dt]. |dt| < h is required (checked at every step). Bias drift and
 *   temperature use sensor time; drift is drift_i * (s - t0), t0 = start time; temperature mode
 *   1 is T(s) = temperature.start + temperature.rate * (s - t0).
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
 * - Sensor model on axis i (x = omega for the gyro, x = f'(i) for accelerometer i):
 *     y_i = (1 + sf_i + sf_temp_i dT) x_i + sf_asym_i |x_i| + sum_{j!=i} mis_ij x_j
 *           + bias_i + temp_i dT + drift_i (s - t0)
 *   gyro adds  sum_j gsens_ij f_j + sum_{jk in xx,yy,zz,xy,xz,yz} g2sens_i,jk f_j f_k
 *   (f at the plate point); the accelerometer adds k2_i x_i^2 + k3_i x_i^3
 *   + sum_{j!=i} cross_ij x_i x_j. dT = T(s) - temperature.ref.
 *   Size effect: accelerometer i senses f'(i) = f + alpha x r_i + omega x (omega x r_i),
 *   r_i = acc.lever.i.{x,y,z}; ALL components of f'(i) used for axis i (its own component and the
 *   ones entering mis_ij and cross_ij) are taken at r_i, i.e. axis i is a point sensor at r_i.
 * - Integration: the model is integrated over sensor time [t, t+h] with composite Gauss-Legendre
 *   quadrature (the interval is first split where the shifted window crosses a knot, then each
 *   piece into NSUB sub-intervals of 4 points): exact for polynomials of degree 7 per piece, so
 *   every linear and quadratic term of the cubic interpolant is exact; k3 f^3 and the |x| kink
 *   at a zero crossing are approximate (error O(h^8) resp. second order in the crossing).
 *   With input_integrals 1 the pieces are quartics: linear terms have degree 4 (5 with the
 *   temperature ramp), quadratic ones (k2, cross, g2sens, omega x (omega x r)) degree 8, so the
 *   rule is 5 points (exact to degree 9) and the same statements hold. Not exact in either case:
 *   k2 / cross products with the lever-arm's centripetal term (degree 12 resp. 16).
 * - Noise, per sensor and axis, added to the increment over [t, t+h]:
 *     white: N sqrt(h) w1                           (N = gyro.noise.arw / acc.noise.vrw)
 *     bias instability: first-order Gauss-Markov x, correlation time T = bi_tau, standard
 *       deviation sigma = B * 0.664282 / 0.617364. Derivation: the Allan variance of such a
 *       process is sigma^2 [2/u - (3 - 4 e^-u + e^-2u)/u^2], u = tau/T, whose square root peaks
 *       at 0.617364 sigma for u = 1.89262; the flicker floor of bias instability B is
 *       sqrt(2 ln 2 / pi) B = 0.664282 B. Exact propagation x1 = phi x0 + sigma sqrt(1-phi^2) w2,
 *       phi = exp(-h/T); contribution (x0 + x1)/2 h (trapezoid). x starts stationary (sigma w).
 *     random walk: b1 = b0 + K sqrt(h) w3; its integral over the step, exactly,
 *       b0 h + K h^1.5 (w3/2 + w4/(2 sqrt 3))  (Var h^3/3, Cov with W(h) h^2/2).
 *   Generator: xoshiro256** per sensor; the gyro state is four splitmix64 outputs from
 *   (uint64)(int64)seed, the accelerometer state is the gyro state after one xoshiro jump
 *   (2^128 draws apart: non-overlapping streams). Standard normals by the Marsaglia polar method
 *   (uniforms (x >> 11) 2^-53 mapped to [-1, 1); the second normal of a pair is discarded) with
 *   our own log and exp built only from frexp/ldexp/floor and + - * / sqrt, which IEEE 754 rounds
 *   correctly: the same seed gives the same bits on every platform (built with
 *   -ffp-contract=off). Draw order per step and sensor: for axis x, y, z: w1, w2, w3, w4; all are
 *   drawn even when a density is zero, so one density never changes another's realisation. At
 *   initialisation: per sensor, per axis, one draw for the Gauss-Markov start.
 * - Outputs over the interval just ended: kind 0 increment (rad, m/s), 1 mean rate (increment/h),
 *   2 integer counts: r += increment; n = floor(r/w + 0.5) (round half up); r -= n w; output n
 *   (a Real holding an integer); |r| <= w/2 always, so the summed counts times w track the summed
 *   increments within half a count. w = count_weight, must be > 0 in counts mode.
 * - temperature output: T at the end of the interval (mode 0 constant, 1 ramp, 2 the input
 *   temperature_env, linear between knots in timing 0, held in timing 1).
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "model_instance.h"
#include "vec3.h"

enum { GYRO = 0, ACC = 1 };
#define NSUB 4 /* Gauss-Legendre sub-intervals per piece */

/* The table must lay out each vector's components consecutively: the code indexes from .x. */
_Static_assert(VR_gyro_bias_z == VR_gyro_bias_x + 2, "vector parameters must be consecutive");
_Static_assert(VR_gyro_mis_zy == VR_gyro_mis_xy + 5, "mis: xy xz yx yz zx zy");
_Static_assert(VR_acc_mis_zy == VR_acc_mis_xy + 5, "mis: xy xz yx yz zx zy");
_Static_assert(VR_acc_cross_zy == VR_acc_cross_xy + 5, "cross: xy xz yx yz zx zy");
_Static_assert(VR_gyro_gsens_zz == VR_gyro_gsens_xx + 8, "gsens: row-major");
_Static_assert(VR_gyro_g2sens_z_yz == VR_gyro_g2sens_x_xx + 17, "g2sens: axis-major, 6 pairs");
_Static_assert(VR_acc_lever_z_z == VR_acc_lever_x_x + 8, "lever: accelerometer-major");
_Static_assert(VR_omega_z == VR_omega_x + 2 && VR_f_z == VR_f_x + 2 && VR_alpha_z == VR_alpha_x + 2,
               "inputs consecutive");
_Static_assert(VR_gyro_z == VR_gyro_x + 2 && VR_acc_z == VR_acc_x + 2, "outputs consecutive");
_Static_assert(VR_omega_int_z == VR_omega_int_x + 2 && VR_f_int_z == VR_f_int_x + 2,
               "integral inputs consecutive");

/* Parameters shared in form by both sensors, by first value reference. */
typedef struct {
    int sf, sf_asym, mis, bias, temp, sf_temp, drift;
    int white, bi, bi_tau, rrw, output, count_weight, out;
} SensorVr;

static const SensorVr SENSOR_VR[2] = {
    {VR_gyro_sf_x, VR_gyro_sf_asym_x, VR_gyro_mis_xy, VR_gyro_bias_x, VR_gyro_temp_x,
     VR_gyro_sf_temp_x, VR_gyro_drift_x, VR_gyro_noise_arw, VR_gyro_noise_bi,
     VR_gyro_noise_bi_tau, VR_gyro_noise_rrw, VR_gyro_output, VR_gyro_count_weight, VR_gyro_x},
    {VR_acc_sf_x, VR_acc_sf_asym_x, VR_acc_mis_xy, VR_acc_bias_x, VR_acc_temp_x,
     VR_acc_sf_temp_x, VR_acc_drift_x, VR_acc_noise_vrw, VR_acc_noise_bi, VR_acc_noise_bi_tau,
     VR_acc_noise_rrw, VR_acc_output, VR_acc_count_weight, VR_acc_x},
};

/* 4-point Gauss-Legendre on [-1, 1] (cubic pieces) */
static const double GL_X[4] = {-0.86113631159405257522, -0.33998104358485626480,
                               0.33998104358485626480, 0.86113631159405257522};
static const double GL_W[4] = {0.34785484513745385737, 0.65214515486254614263,
                               0.65214515486254614263, 0.34785484513745385737};
/* 5-point Gauss-Legendre on [-1, 1] (quartic pieces, input_integrals 1) */
static const double GL5_X[5] = {-0.90617984593866399280, -0.53846931010568309104, 0.0,
                                0.53846931010568309104, 0.90617984593866399280};
static const double GL5_W[5] = {0.23692688505618908751, 0.47862867049936646804,
                                0.56888888888888888889, 0.47862867049936646804,
                                0.23692688505618908751};

/* Allan-deviation peak of a Gauss-Markov process per sigma, and the flicker floor per B. */
#define GM_PEAK 0.617364
#define FLICKER_FLOOR 0.664282

#define R(vr) (m->s.r[(vr)])
#define I(vr) (m->s.i[(vr) - INTEGER_VR_BASE])

/* ================================================================ portable random numbers */

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t xoshiro_next(ImuRng *g) {
    uint64_t *s = g->s;
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

/* Advance by 2^128 draws (reference jump polynomial): gives a non-overlapping second stream. */
static void xoshiro_jump(ImuRng *g) {
    static const uint64_t JUMP[] = {0x180ec6d33cfd0abaULL, 0xd5a61266f0c9392cULL,
                                    0xa9582618e03fc9aaULL, 0x39abdc4529b1661cULL};
    uint64_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    for (int i = 0; i < 4; i++)
        for (int b = 0; b < 64; b++) {
            if (JUMP[i] & (UINT64_C(1) << b)) {
                s0 ^= g->s[0];
                s1 ^= g->s[1];
                s2 ^= g->s[2];
                s3 ^= g->s[3];
            }
            xoshiro_next(g);
        }
    g->s[0] = s0;
    g->s[1] = s1;
    g->s[2] = s2;
    g->s[3] = s3;
}

static const double LN2_HI = 6.93147180369123816490e-01; /* ln 2 with 21 trailing zero bits */
static const double LN2_LO = 1.90821492927058770002e-10; /* ln 2 - LN2_HI */

/* ln x for x > 0 from frexp and arithmetic only (libm log is not bit-identical across
 * platforms). x = m 2^e with m in [sqrt(1/2), sqrt(2)); ln m = 2 atanh(z), z = (m-1)/(m+1),
 * |z| < 0.1716, series to z^25 (relative error < 1e-17). */
static double portable_log(double x) {
    int e;
    double mant = frexp(x, &e);
    if (mant < 0.70710678118654752440) {
        mant *= 2.0;
        e -= 1;
    }
    double z = (mant - 1.0) / (mant + 1.0);
    double z2 = z * z;
    double sum = 0.0;
    for (int k = 25; k >= 3; k -= 2) sum = (sum + 1.0 / k) * z2;
    double lnm = 2.0 * (z + z * sum);
    return (double)e * LN2_HI + ((double)e * LN2_LO + lnm);
}

/* exp x from ldexp/floor and arithmetic only: x = k ln2 + r, |r| <= ln2/2, Taylor to r^17. */
static double portable_exp(double x) {
    if (x < -745.0) return 0.0;
    if (x > 709.0) return HUGE_VAL;
    double k = floor(x / 0.69314718055994530942 + 0.5);
    double r = (x - k * LN2_HI) - k * LN2_LO;
    double p = 1.0;
    for (int n = 17; n >= 1; n--) p = 1.0 + p * r / n;
    return ldexp(p, (int)k);
}

/* Standard normal by the Marsaglia polar method (second value of the pair discarded). */
static double gauss(ImuRng *g) {
    for (;;) {
        double u = (double)(xoshiro_next(g) >> 11) * 0x1.0p-52 - 1.0;
        double v = (double)(xoshiro_next(g) >> 11) * 0x1.0p-52 - 1.0;
        double q = u * u + v * v;
        if (q > 0.0 && q < 1.0) return u * sqrt(-2.0 * portable_log(q) / q);
    }
}

static void seed_streams(ModelInstance *m) {
    uint64_t x = (uint64_t)(int64_t)I(VR_seed);
    for (int k = 0; k < 4; k++) m->s.p.rng[GYRO].s[k] = splitmix64(&x);
    m->s.p.rng[ACC] = m->s.p.rng[GYRO];
    xoshiro_jump(&m->s.p.rng[ACC]);
}

/* ================================================================ input signal */

static int any_nonzero(const double *d0, const double *d1, const double *d2) {
    return *d0 != 0.0 || *d1 != 0.0 || *d2 != 0.0;
}

/* The knot of the current inputs at time t (derivative rules: see the top comment). */
static void knot_from_inputs(const ModelInstance *m, double t, ImuKnot *k) {
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
static void push_knot(ModelPrivate *p, const ImuKnot *k, double tol) {
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
static void set_bump(const ModelInstance *m, ModelPrivate *p) {
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

typedef struct {
    double w[3], a[3], f[3];
} Motion;

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
static void motion_at(const ModelInstance *m, double tau, Motion *mo) {
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
static double temperature_at(const ModelInstance *m, double s) {
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

/* ================================================================ sensor model */

static int mis_index(int i, int j) { return 2 * i + (j > i ? j - 1 : j); }

/* Terms common to both sensors on axis i for the sensed vector x (see the top comment). */
static double common_terms(const ModelInstance *m, int sensor, int i, const double x[3],
                           double dT, double tt) {
    const SensorVr *v = &SENSOR_VR[sensor];
    double y = (1.0 + R(v->sf + i) + R(v->sf_temp + i) * dT) * x[i] + R(v->sf_asym + i) * fabs(x[i]);
    for (int j = 0; j < 3; j++)
        if (j != i) y += R(v->mis + mis_index(i, j)) * x[j];
    return y + R(v->bias + i) + R(v->temp + i) * dT + R(v->drift + i) * tt;
}

static const int PAIR[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};

/* Instantaneous sensor outputs (rad/s, m/s2) at sensor time s. */
static void sensor_outputs(const ModelInstance *m, double s, double gyro[3], double acc[3]) {
    Motion mo;
    motion_at(m, s + R(VR_imu_time_offset), &mo);
    double dT = temperature_at(m, s) - R(VR_temperature_ref);
    double tt = s - m->s.start_time;
    for (int i = 0; i < 3; i++) {
        double y = common_terms(m, GYRO, i, mo.w, dT, tt);
        for (int j = 0; j < 3; j++) y += R(VR_gyro_gsens_xx + 3 * i + j) * mo.f[j];
        for (int q = 0; q < 6; q++)
            y += R(VR_gyro_g2sens_x_xx + 6 * i + q) * mo.f[PAIR[q][0]] * mo.f[PAIR[q][1]];
        gyro[i] = y;
    }
    for (int i = 0; i < 3; i++) {
        /* specific force at accelerometer i: f + alpha x r + omega x (omega x r) */
        const double *r = &R(VR_acc_lever_x_x + 3 * i);
        double axr[3], wxr[3], wwxr[3], fp[3];
        cross3(mo.a, r, axr);
        cross3(mo.w, r, wxr);
        cross3(mo.w, wxr, wwxr);
        for (int k = 0; k < 3; k++) fp[k] = mo.f[k] + axr[k] + wwxr[k];
        double y = common_terms(m, ACC, i, fp, dT, tt);
        y += R(VR_acc_k2_x + i) * fp[i] * fp[i] + R(VR_acc_k3_x + i) * fp[i] * fp[i] * fp[i];
        for (int j = 0; j < 3; j++)
            if (j != i) y += R(VR_acc_cross_xy + mis_index(i, j)) * fp[i] * fp[j];
        acc[i] = y;
    }
}

/* Add the integral over sensor time [a, b] (composite 4- or 5-point Gauss-Legendre). Within a
 * piece the signals are cubics (quartics with input_integrals 1) and every term of the model is
 * a polynomial of degree <= 6 (<= 8) in them except k3 (degree 9, 12) and the asymmetry's |x|:
 * without those one 4-point (5-point) rule, exact to degree 7 (9), is already exact, so the
 * sub-division is only paid when they are present. */
static void integrate_piece(const ModelInstance *m, double a, double b, double g[3], double f[3]) {
    const int nsub = m->s.p.nsub, npts = m->s.p.npts;
    const double *gx = npts == 5 ? GL5_X : GL_X, *gw = npts == 5 ? GL5_W : GL_W;
    double hs = (b - a) / nsub;
    for (int k = 0; k < nsub; k++) {
        double c = a + (k + 0.5) * hs;
        for (int q = 0; q < npts; q++) {
            double yg[3], ya[3], w = gw[q] * hs / 2;
            sensor_outputs(m, c + gx[q] * hs / 2, yg, ya);
            for (int i = 0; i < 3; i++) {
                g[i] += w * yg[i];
                f[i] += w * ya[i];
            }
        }
    }
}

/* Deterministic increments over [t, t+h]: split where the shifted window crosses a knot, where
 * the interpolant has a kink in its higher derivatives. A piece whose motion lies past the newest
 * knot (imu.time_offset > 0) is also returned in ahead (g, f), with its bounds; else *ahead_a =
 * *ahead_b. */
static void integrate_step(const ModelInstance *m, double t, double h, double g[3], double f[3],
                           double ahead[2][3], double *ahead_a, double *ahead_b) {
    const ModelPrivate *p = &m->s.p;
    double dt = R(VR_imu_time_offset), tol = 1e-9 * h, a = t;
    for (int i = 0; i < 3; i++) g[i] = f[i] = ahead[0][i] = ahead[1][i] = 0.0;
    for (int k = 0; k < p->nknots; k++) {
        double bp = p->knot[k].t - dt;
        if (bp > a + tol && bp < t + h - tol) {
            integrate_piece(m, a, bp, g, f);
            a = bp;
        }
    }
    *ahead_a = *ahead_b = t + h;
    if (a + dt >= p->knot[p->nknots - 1].t - tol) { /* the last piece is extrapolated */
        integrate_piece(m, a, t + h, ahead[0], ahead[1]);
        for (int i = 0; i < 3; i++) {
            g[i] += ahead[0][i];
            f[i] += ahead[1][i];
        }
        *ahead_a = a;
    } else {
        integrate_piece(m, a, t + h, g, f);
    }
}

/* ================================================================ noise */

static double gm_sigma(const ModelInstance *m, int sensor) {
    return R(SENSOR_VR[sensor].bi) * (FLICKER_FLOOR / GM_PEAK);
}

/* Noise increment of one axis over a step of length h; advances the processes. */
static double noise_increment(ModelInstance *m, int sensor, int i, double h) {
    const SensorVr *v = &SENSOR_VR[sensor];
    ImuRng *g = &m->s.p.rng[sensor];
    double w1 = gauss(g), w2 = gauss(g), w3 = gauss(g), w4 = gauss(g);
    double sh = sqrt(h);
    double white = R(v->white) * sh * w1;

    double sigma = gm_sigma(m, sensor);
    double phi2 = portable_exp(-2.0 * h / R(v->bi_tau));
    double phi = sqrt(phi2);
    double x0 = m->s.p.gm[sensor][i];
    double x1 = phi * x0 + sigma * sqrt(1.0 - phi2) * w2;
    m->s.p.gm[sensor][i] = x1;
    double gm = 0.5 * (x0 + x1) * h;

    double K = R(v->rrw), b0 = m->s.p.rw[sensor][i];
    double rw = b0 * h + K * h * sh * (0.5 * w3 + w4 / (2.0 * sqrt(3.0)));
    m->s.p.rw[sensor][i] = b0 + K * sh * w3;
    return white + gm + rw;
}

/* ================================================================ checks */

static ModelStatus check_integer(ModelInstance *m, int vr, int lo, int hi, const char *expected) {
    int v = I(vr);
    if (v < lo || v > hi) {
        model_log(m, MS_ERROR, "parameter %s = %d: expected %s", INTEGER_NAME[vr - INTEGER_VR_BASE],
                  v, expected);
        return MS_ERROR;
    }
    return MS_OK;
}

static ModelStatus worst(ModelStatus a, ModelStatus b) { return a > b ? a : b; }

static ModelStatus check_parameters(ModelInstance *m) {
    ModelStatus st = MS_OK;
    for (int vr = 0; vr < N_REAL; vr++)
        if (REAL_CAUSALITY[vr] == CAUS_PARAMETER)
            st = worst(st, model_check_real(m, vr, -INFINITY, INFINITY, "a finite value"));
    if (st != MS_OK) return st; /* the range checks below would repeat the message */
    for (int s = 0; s < 2; s++) {
        const SensorVr *v = &SENSOR_VR[s];
        st = worst(st, model_check_real(m, v->white, 0.0, INFINITY, "a noise density >= 0"));
        st = worst(st, model_check_real(m, v->bi, 0.0, INFINITY, "a bias instability >= 0"));
        st = worst(st, model_check_real(m, v->rrw, 0.0, INFINITY, "a random-walk density >= 0"));
        if (!(R(v->bi_tau) > 0.0)) {
            model_log(m, MS_ERROR, "parameter %s = %g: expected a correlation time > 0",
                      REAL_NAME[v->bi_tau], R(v->bi_tau));
            st = MS_ERROR;
        }
        st = worst(st, check_integer(m, v->output, 0, 2,
                                     "0 (increment), 1 (rate) or 2 (counts)"));
        if (I(v->output) == 2 && !(R(v->count_weight) > 0.0)) {
            model_log(m, MS_ERROR, "parameter %s = %g: expected a count weight > 0 (counts output)",
                      REAL_NAME[v->count_weight], R(v->count_weight));
            st = MS_ERROR;
        }
    }
    st = worst(st, check_integer(m, VR_input_timing, 0, 1,
                                 "0 (inputs at the end of the step) or 1 (at its start)"));
    st = worst(st, check_integer(m, VR_input_integrals, 0, 1,
                                 "0 (ignore omega_int, f_int) or 1 (match the integrals)"));
    st = worst(st, check_integer(m, VR_temperature_mode, 0, 2,
                                 "0 (constant), 1 (ramp) or 2 (input temperature_env)"));
    return st;
}

static ModelStatus check_inputs(ModelInstance *m) {
    ModelStatus st = MS_OK;
    for (int vr = 0; vr < N_REAL; vr++) {
        if (REAL_CAUSALITY[vr] != CAUS_INPUT) continue;
        if (!isfinite(R(vr))) {
            model_log(m, MS_ERROR, "input %s = %g: expected a finite value", REAL_NAME[vr], R(vr));
            st = MS_ERROR;
        }
        for (int o = 0; o < MAX_INPUT_DERIVATIVE_ORDER; o++)
            if (!isfinite(m->s.rder[vr][o])) {
                model_log(m, MS_ERROR, "input derivative of order %d of %s = %g: expected a finite value",
                          o + 1, REAL_NAME[vr], m->s.rder[vr][o]);
                st = MS_ERROR;
            }
    }
    return st;
}

/* ================================================================ FMI model interface */

ModelStatus model_initialize(ModelInstance *m) {
    ModelStatus st = worst(check_parameters(m), check_inputs(m));
    if (st >= MS_ERROR) return st;
    ModelPrivate *p = &m->s.p;
    memset(p, 0, sizeof *p);
    seed_streams(m);
    p->nsub = 1;
    p->npts = I(VR_input_integrals) == 1 ? 5 : 4;
    for (int i = 0; i < 3; i++)
        if (R(VR_gyro_sf_asym_x + i) != 0.0 || R(VR_acc_sf_asym_x + i) != 0.0 ||
            R(VR_acc_k3_x + i) != 0.0)
            p->nsub = NSUB;
    for (int s = 0; s < 2; s++)
        for (int i = 0; i < 3; i++) p->gm[s][i] = gm_sigma(m, s) * gauss(&p->rng[s]);
    ImuKnot k;
    knot_from_inputs(m, m->s.time, &k);
    push_knot(p, &k, 0.0);
    for (int i = 0; i < 3; i++) R(VR_gyro_x + i) = R(VR_acc_x + i) = 0.0;
    R(VR_temperature) = temperature_at(m, m->s.time);
    return MS_OK;
}

ModelStatus model_do_step(ModelInstance *m, double h) {
    double t = m->s.time;
    if (check_inputs(m) >= MS_ERROR) return MS_ERROR;
    if (!(fabs(R(VR_imu_time_offset)) < h)) {
        model_log(m, MS_ERROR,
                  "parameter imu.time_offset = %g: expected |time_offset| < the communication "
                  "step %g",
                  R(VR_imu_time_offset), h);
        return MS_ERROR;
    }
    ImuKnot k;
    int timing1 = I(VR_input_timing) == 1;
    knot_from_inputs(m, timing1 ? t : t + h, &k);
    push_knot(&m->s.p, &k, 1e-9 * h);
    set_bump(m, &m->s.p);

    double inc[2][3], ahead[2][3], a0, a1;
    ModelPrivate *p = &m->s.p;
    integrate_step(m, t, h, inc[GYRO], inc[ACC], ahead, &a0, &a1);
    if (p->ahead_set) {
        /* what the last step extrapolated, now interpolated: the difference joins this sample,
         * so the samples' sums (angle, velocity) stay the true motion's and the extrapolation
         * error does not pile up index after index (at 10 cm off the centre, 0.2 ms late:
         * 2e-5 m/s per index) */
        double again[2][3] = {{0.0}};
        integrate_piece(m, p->ahead_a, p->ahead_b, again[GYRO], again[ACC]);
        for (int s = 0; s < 2; s++)
            for (int i = 0; i < 3; i++) inc[s][i] += again[s][i] - p->ahead[s][i];
    }
    p->ahead_set = !timing1 && a1 > a0;
    if (p->ahead_set) {
        p->ahead_a = a0;
        p->ahead_b = a1;
        memcpy(p->ahead, ahead, sizeof ahead);
    }
    for (int s = 0; s < 2; s++) {
        const SensorVr *v = &SENSOR_VR[s];
        for (int i = 0; i < 3; i++) {
            double d = inc[s][i] + noise_increment(m, s, i, h), out;
            switch (I(v->output)) {
            case 1:
                out = d / h;
                break;
            case 2: {
                double w = R(v->count_weight), *r = &m->s.p.resid[s][i];
                *r += d;
                out = floor(*r / w + 0.5);
                *r -= out * w;
                break;
            }
            default:
                out = d;
            }
            R(v->out + i) = out;
        }
    }
    R(VR_temperature) = temperature_at(m, t + h);
    return MS_OK;
}

ModelStatus model_inputs_changed(ModelInstance *m) {
    (void)m; /* inputs are read at the next step */
    return MS_OK;
}
