/* The IMU's noise: portable random numbers and the noise processes they drive (see model.c
 * for the other files).
 *
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
 */
#include <math.h>
#include <stdint.h>

#include "imu.h"

/* Allan-deviation peak of a Gauss-Markov process per sigma, and the flicker floor per B. */
#define GM_PEAK 0.617364
#define FLICKER_FLOOR 0.664282

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
double gauss(ImuRng *g) {
    for (;;) {
        double u = (double)(xoshiro_next(g) >> 11) * 0x1.0p-52 - 1.0;
        double v = (double)(xoshiro_next(g) >> 11) * 0x1.0p-52 - 1.0;
        double q = u * u + v * v;
        if (q > 0.0 && q < 1.0) return u * sqrt(-2.0 * portable_log(q) / q);
    }
}

void seed_streams(ModelInstance *m) {
    uint64_t x = (uint64_t)(int64_t)I(VR_seed);
    for (int k = 0; k < 4; k++) m->s.p.rng[GYRO].s[k] = splitmix64(&x);
    m->s.p.rng[ACC] = m->s.p.rng[GYRO];
    xoshiro_jump(&m->s.p.rng[ACC]);
}

/* ================================================================ noise */

double gm_sigma(const ModelInstance *m, int sensor) {
    return R(SENSOR_VR[sensor].bi) * (FLICKER_FLOOR / GM_PEAK);
}

/* Noise increment of one axis over a step of length h; advances the processes. */
double noise_increment(ModelInstance *m, int sensor, int i, double h) {
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
