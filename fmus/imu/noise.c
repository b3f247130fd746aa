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
 *     flicker bias instability (bi_tau_max > bi_tau): real bias instability is flicker noise, an
 *       Allan-deviation floor over decades of tau, which one Gauss-Markov process has at one tau
 *       only. Then the process above is replaced (its draws w2 are still made) by the sum of M
 *       Gauss-Markov terms, the construction components/model/flicker.py restates:
 *       T_lo = bi_tau, T_hi = bi_tau_max, extended range a = T_lo/2, b = 2 T_hi, r = b/a;
 *       M = ceil(2 log10 r) + 1, evaluated as M - 1 = the smallest k >= 0 with r*r <= 10^k, at
 *       most 16 (T_hi/T_lo <= sqrt(1e15)/4 = 7.9e6, else the parameters are refused);
 *       T_j = a exp(j/(M-1) ln r), j = 0..M-1; one standard deviation s for all terms,
 *       s^2 = 0.4412712 B^2 / mean_i sum_j g(tau_i/T_j), tau_i = T_lo exp(i/63 ln(T_hi/T_lo)),
 *       i = 0..63, g(u) = 2/u - (3 - 4 e^-u + e^-2u)/u^2 the Allan variance of a unit-variance
 *       Gauss-Markov process (by its Taylor series for u < 0.5, where that form cancels;
 *       0.4412712 = 2 ln 2 / pi, the flicker floor 0.664282 B squared). The Allan deviation of
 *       the sum stays within -16 % .. +4 % of 0.664282 B over [T_lo, T_hi] (the low edge rolls
 *       off: within +-12 % from 1.35 T_lo). Each term is propagated and integrated as the single
 *       process: x1 = phi x0 + s sqrt(1-phi^2) v, phi = exp(-h/T_j), contribution (x0 + x1)/2 h,
 *       started stationary (s v). The normals v come from a stream of their own per sensor, so
 *       turning the flicker on leaves every other draw's realisation as it was.
 *     random walk: b1 = b0 + K sqrt(h) w3; its integral over the step, exactly,
 *       b0 h + K h^1.5 (w3/2 + w4/(2 sqrt 3))  (Var h^3/3, Cov with W(h) h^2/2).
 *   Generator: xoshiro256** per sensor; the gyro state is four splitmix64 outputs from
 *   (uint64)(int64)seed, the accelerometer state is the gyro state after one xoshiro jump
 *   (2^128 draws apart: non-overlapping streams); the flicker streams are the gyro state after
 *   two jumps (gyro) and three jumps (accelerometer). Standard normals by the Marsaglia polar
 *   method (uniforms (x >> 11) 2^-53 mapped to [-1, 1); the second normal of a pair is discarded) with
 *   our own log and exp built only from frexp/ldexp/floor and + - * / sqrt, which IEEE 754 rounds
 *   correctly: the same seed gives the same bits on every platform (built with
 *   -ffp-contract=off). Draw order per step and sensor: for axis x, y, z: w1, w2, w3, w4; all are
 *   drawn even when a density is zero, so one density never changes another's realisation. At
 *   initialisation: per sensor, per axis, one draw for the Gauss-Markov start. Flicker streams,
 *   per step and sensor: for axis x, y, z: for term j: one v; at initialisation: per sensor,
 *   per axis, per term one v for the start.
 */
#include <math.h>
#include <stdint.h>

#include "imu.h"

/* Allan-deviation peak of a Gauss-Markov process per sigma, and the flicker floor per B. */
#define GM_PEAK 0.617364
#define FLICKER_FLOOR 0.664282
/* The flicker construction: its floor squared (2 ln 2 / pi), the points tau_i of the fit. */
#define FLICKER_FLOOR_SQ 0.4412712
#define FLICKER_FIT_POINTS 64

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
    m->s.p.frng[GYRO] = m->s.p.rng[ACC];
    xoshiro_jump(&m->s.p.frng[GYRO]);
    m->s.p.frng[ACC] = m->s.p.frng[GYRO];
    xoshiro_jump(&m->s.p.frng[ACC]);
}

/* ================================================================ noise */

double gm_sigma(const ModelInstance *m, int sensor) {
    return R(SENSOR_VR[sensor].bi) * (FLICKER_FLOOR / GM_PEAK);
}

/* Allan variance of a unit-variance Gauss-Markov process at u = tau/T,
 * g(u) = 2/u - (3 - 4 e^-u + e^-2u)/u^2; for u < 0.5 its Taylor series
 * sum_{n>=3} (-1)^(n+1) (2^n - 4) u^(n-2) / n! to n = 20 (the rest < 1e-17 of g), where the
 * closed form cancels (3 % off at u = 1e-5). */
static double gm_avar_unit(double u) {
    if (u < 0.5) {
        double fact[21];
        fact[0] = 1.0;
        for (int n = 1; n <= 20; n++) fact[n] = fact[n - 1] * n; /* exact up to 20! */
        double p = 0.0;
        for (int n = 20; n >= 3; n--) {
            double c = (ldexp(1.0, n) - 4.0) / fact[n];
            p = p * u + (n % 2 ? c : -c);
        }
        return p * u;
    }
    return 2.0 / u - (3.0 - 4.0 * portable_exp(-u) + portable_exp(-2.0 * u)) / (u * u);
}

/* Flicker terms M for [t_lo, t_hi], 0 < t_lo < t_hi: the smallest k >= 0 with r*r <= 10^k,
 * r = 4 t_hi/t_lo, plus one (= ceil(2 log10 r) + 1); 0 when more than IMU_FLICKER_MAX. */
int flicker_count(double t_lo, double t_hi) {
    double r = (2.0 * t_hi) / (0.5 * t_lo), rr = r * r, p = 1.0;
    for (int k = 0; k < IMU_FLICKER_MAX; k++) {
        if (rr <= p) return k + 1;
        p *= 10.0; /* 10^k, exact */
    }
    return 0;
}

/* The flicker terms of both sensors (see the top comment) and their stationary start; nflick 0
 * where bi_tau_max <= bi_tau. The parameters have been checked (M <= IMU_FLICKER_MAX). */
void flicker_init(ModelInstance *m) {
    ModelPrivate *p = &m->s.p;
    for (int s = 0; s < 2; s++) {
        const SensorVr *v = &SENSOR_VR[s];
        double t_lo = R(v->bi_tau), t_hi = R(v->bi_tau_max), B = R(v->bi);
        p->nflick[s] = 0;
        if (!(t_hi > t_lo)) continue;
        int M = flicker_count(t_lo, t_hi); /* >= 3: r > 4 */
        double a = 0.5 * t_lo, lr = portable_log((2.0 * t_hi) / a), lt = portable_log(t_hi / t_lo);
        for (int j = 0; j < M; j++) p->ftau[s][j] = a * portable_exp((double)j / (M - 1) * lr);
        double total = 0.0;
        for (int i = 0; i < FLICKER_FIT_POINTS; i++) {
            double tau = t_lo * portable_exp((double)i / (FLICKER_FIT_POINTS - 1) * lt);
            for (int j = 0; j < M; j++) total += gm_avar_unit(tau / p->ftau[s][j]);
        }
        p->fsigma[s] = sqrt(FLICKER_FLOOR_SQ * B * B / (total / FLICKER_FIT_POINTS));
        p->nflick[s] = M;
        p->fh[s] = 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < M; j++) p->fx[s][i][j] = p->fsigma[s] * gauss(&p->frng[s]);
    }
}

/* Flicker bias-instability increment of one axis over a step of length h; advances its terms
 * (phi and s sqrt(1 - phi^2) kept for the last step length). */
static double flicker_increment(ModelInstance *m, int sensor, int i, double h) {
    ModelPrivate *p = &m->s.p;
    const int M = p->nflick[sensor];
    if (h != p->fh[sensor]) {
        for (int j = 0; j < M; j++) {
            double phi2 = portable_exp(-2.0 * h / p->ftau[sensor][j]);
            p->fphi[sensor][j] = sqrt(phi2);
            p->fq[sensor][j] = p->fsigma[sensor] * sqrt(1.0 - phi2);
        }
        p->fh[sensor] = h;
    }
    double sum = 0.0;
    for (int j = 0; j < M; j++) {
        double x0 = p->fx[sensor][i][j];
        double x1 = p->fphi[sensor][j] * x0 + p->fq[sensor][j] * gauss(&p->frng[sensor]);
        p->fx[sensor][i][j] = x1;
        sum += 0.5 * (x0 + x1) * h;
    }
    return sum;
}

/* Noise increment of one axis over a step of length h; advances the processes. */
double noise_increment(ModelInstance *m, int sensor, int i, double h) {
    const SensorVr *v = &SENSOR_VR[sensor];
    ImuRng *g = &m->s.p.rng[sensor];
    double w1 = gauss(g), w2 = gauss(g), w3 = gauss(g), w4 = gauss(g);
    double sh = sqrt(h);
    double white = R(v->white) * sh * w1;

    double gm;
    if (m->s.p.nflick[sensor] > 0) {
        gm = flicker_increment(m, sensor, i, h); /* w2 unused */
    } else {
        double sigma = gm_sigma(m, sensor);
        double phi2 = portable_exp(-2.0 * h / R(v->bi_tau));
        double phi = sqrt(phi2);
        double x0 = m->s.p.gm[sensor][i];
        double x1 = phi * x0 + sigma * sqrt(1.0 - phi2) * w2;
        m->s.p.gm[sensor][i] = x1;
        gm = 0.5 * (x0 + x1) * h;
    }

    double K = R(v->rrw), b0 = m->s.p.rw[sensor][i];
    double rw = b0 * h + K * h * sh * (0.5 * w3 + w4 / (2.0 * sqrt(3.0)));
    m->s.p.rw[sensor][i] = b0 + K * sh * w3;
    return white + gm + rw;
}
