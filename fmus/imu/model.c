/* IMU sensor physics: a gyro triad and an accelerometer triad with the error effects of
 * domain.md §4, noise, and increment / rate / count outputs.
 *
 * CONVENTIONS
 * - Axes: everything in mounting (plate) axes. Inputs omega = inertial rate [rad/s], f = specific
 *   force at the plate reference point [m/s2], alpha = d omega/dt [rad/s2].
 * - Time: "sensor time" s runs with the FMU clock. The motion the gyros see at sensor time s is
 *   the motion of the table at tau = s + imu.time_offset (dt): the sample labelled t holds the
 *   motion of (t - h + dt, t + dt]. The accelerometers see it at s + dt + acc.time_offset (dta,
 *   the gyro-accelerometer asynchrony, PSINS's tGA): their samples hold (t - h + dt + dta,
 *   t + dt + dta]; with dta != 0 the step is integrated twice, once per shift. |dt| < h and
 *   |dt + dta| < h are required (checked at every step). Bias drift and
 *   temperature use sensor time; drift is drift_i * (s - t0), t0 = start time; temperature mode
 *   1 is T(s) = temperature.start + temperature.rate * (s - t0).
 * - Input signal between communication points: signal.c.
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
 * - Noise: noise.c.
 * - Outputs over the interval just ended: kind 0 increment (rad, m/s), 1 mean rate (increment/h),
 *   2 integer counts: r += increment; n = floor(r/w + 0.5) (round half up); r -= n w; output n
 *   (a Real holding an integer); |r| <= w/2 always, so the summed counts times w track the summed
 *   increments within half a count. w = count_weight, must be > 0 in counts mode.
 * - temperature output: T at the end of the interval (mode 0 constant, 1 ramp, 2 the input
 *   temperature_env, linear between knots in timing 0, held in timing 1).
 */
#include <math.h>
#include <string.h>

#include "imu.h"
#include "vec3.h"

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

const SensorVr SENSOR_VR[2] = {
    {VR_gyro_sf_x, VR_gyro_sf_asym_x, VR_gyro_mis_xy, VR_gyro_bias_x, VR_gyro_temp_x,
     VR_gyro_sf_temp_x, VR_gyro_drift_x, VR_gyro_noise_arw, VR_gyro_noise_bi,
     VR_gyro_noise_bi_tau, VR_gyro_noise_bi_tau_max, VR_gyro_noise_rrw, VR_gyro_output,
     VR_gyro_count_weight, VR_gyro_x},
    {VR_acc_sf_x, VR_acc_sf_asym_x, VR_acc_mis_xy, VR_acc_bias_x, VR_acc_temp_x,
     VR_acc_sf_temp_x, VR_acc_drift_x, VR_acc_noise_vrw, VR_acc_noise_bi, VR_acc_noise_bi_tau,
     VR_acc_noise_bi_tau_max, VR_acc_noise_rrw, VR_acc_output, VR_acc_count_weight, VR_acc_x},
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

/* Instantaneous sensor outputs (rad/s, m/s2) at sensor time s, seeing the motion at s + shift. */
static void sensor_outputs(const ModelInstance *m, double s, double shift, double gyro[3], double acc[3]) {
    Motion mo;
    motion_at(m, s + shift, &mo);
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
static void integrate_piece(const ModelInstance *m, double a, double b, double shift, double g[3],
                            double f[3]) {
    const int nsub = m->s.p.nsub, npts = m->s.p.npts;
    const double *gx = npts == 5 ? GL5_X : GL_X, *gw = npts == 5 ? GL5_W : GL_W;
    double hs = (b - a) / nsub;
    for (int k = 0; k < nsub; k++) {
        double c = a + (k + 0.5) * hs;
        for (int q = 0; q < npts; q++) {
            double yg[3], ya[3], w = gw[q] * hs / 2;
            sensor_outputs(m, c + gx[q] * hs / 2, shift, yg, ya);
            for (int i = 0; i < 3; i++) {
                g[i] += w * yg[i];
                f[i] += w * ya[i];
            }
        }
    }
}

/* Deterministic increments over [t, t+h] seeing the motion shifted by dt: split where the
 * shifted window crosses a knot, where the interpolant has a kink in its higher derivatives. A
 * piece whose motion lies past the newest knot (dt > 0) is also returned in ahead (g, f), with
 * its bounds; else *ahead_a = *ahead_b. */
static void integrate_step(const ModelInstance *m, double t, double h, double dt, double g[3], double f[3],
                           double ahead[2][3], double *ahead_a, double *ahead_b) {
    const ModelPrivate *p = &m->s.p;
    double tol = 1e-9 * h, a = t;
    for (int i = 0; i < 3; i++) g[i] = f[i] = ahead[0][i] = ahead[1][i] = 0.0;
    for (int k = 0; k < p->nknots; k++) {
        double bp = p->knot[k].t - dt;
        if (bp > a + tol && bp < t + h - tol) {
            integrate_piece(m, a, bp, dt, g, f);
            a = bp;
        }
    }
    *ahead_a = *ahead_b = t + h;
    if (a + dt >= p->knot[p->nknots - 1].t - tol) { /* the last piece is extrapolated */
        integrate_piece(m, a, t + h, dt, ahead[0], ahead[1]);
        for (int i = 0; i < 3; i++) {
            g[i] += ahead[0][i];
            f[i] += ahead[1][i];
        }
        *ahead_a = a;
    } else {
        integrate_piece(m, a, t + h, dt, g, f);
    }
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
        } else if (R(v->bi_tau_max) > R(v->bi_tau) &&
                   flicker_count(R(v->bi_tau), R(v->bi_tau_max)) == 0) {
            model_log(m, MS_ERROR,
                      "parameter %s = %g: flicker range too wide: expected %s / %s <= %.7g "
                      "(ceil(2 log10(4 bi_tau_max / bi_tau)) + 1 <= %d Gauss-Markov terms), "
                      "got %g",
                      REAL_NAME[v->bi_tau_max], R(v->bi_tau_max), REAL_NAME[v->bi_tau_max],
                      REAL_NAME[v->bi_tau], sqrt(1e15) / 4.0, IMU_FLICKER_MAX,
                      R(v->bi_tau_max) / R(v->bi_tau));
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
    flicker_init(m);
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
    /* the accelerometers' shift; equal to the gyros' (one pass, the same bits as without the
     * parameter) unless acc.time_offset != 0 */
    const double shift[2] = {R(VR_imu_time_offset), R(VR_imu_time_offset) + R(VR_acc_time_offset)};
    const int passes = shift[1] != shift[0] ? 2 : 1;
    if (!(fabs(shift[1]) < h)) {
        model_log(m, MS_ERROR,
                  "parameters imu.time_offset + acc.time_offset = %g: expected |sum| < the "
                  "communication step %g (the accelerometers' shift)",
                  shift[1], h);
        return MS_ERROR;
    }
    ImuKnot k;
    int timing1 = I(VR_input_timing) == 1;
    knot_from_inputs(m, timing1 ? t : t + h, &k);
    push_knot(&m->s.p, &k, 1e-9 * h);
    set_bump(m, &m->s.p);

    double inc[2][3];
    ModelPrivate *p = &m->s.p;
    for (int q = 0; q < passes; q++) {
        double part[2][3], ahead[2][3], a0, a1;
        integrate_step(m, t, h, shift[q], part[GYRO], part[ACC], ahead, &a0, &a1);
        if (p->ahead_set[q]) {
            /* what the last step extrapolated, now interpolated: the difference joins this
             * sample, so the samples' sums (angle, velocity) stay the true motion's and the
             * extrapolation error does not pile up index after index (at 10 cm off the centre,
             * 0.2 ms late: 2e-5 m/s per index) */
            double again[2][3] = {{0.0}};
            integrate_piece(m, p->ahead_a[q], p->ahead_b[q], shift[q], again[GYRO], again[ACC]);
            for (int s = 0; s < 2; s++)
                for (int i = 0; i < 3; i++) part[s][i] += again[s][i] - p->ahead[q][s][i];
        }
        p->ahead_set[q] = !timing1 && a1 > a0;
        if (p->ahead_set[q]) {
            p->ahead_a[q] = a0;
            p->ahead_b[q] = a1;
            memcpy(p->ahead[q], ahead, sizeof ahead);
        }
        /* pass 0 gives the gyros (and the accelerometers when there is one pass), pass 1 the
         * accelerometers at their own shift */
        for (int s = 0; s < 2; s++)
            if (passes == 1 || (q == 0) == (s == GYRO))
                for (int i = 0; i < 3; i++) inc[s][i] = part[s][i];
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
