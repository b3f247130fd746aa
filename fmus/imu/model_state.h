/* Private state of the IMU model (see model.c for the conventions). A plain struct without
 * pointers: saving an FMU state is a memcpy, and instances share nothing. */
#ifndef IMU_MODEL_STATE_H
#define IMU_MODEL_STATE_H

#include <stdint.h>

/* Input knots kept for the interpolation inside a step and for the time offset (|dt| < h needs
 * the knot one step back; one spare for a shorter previous step). */
#define IMU_MAX_KNOTS 4

/* The motion at one communication point: values and time derivatives (orders 1..3). */
typedef struct {
    double t;
    double w[3];     /* omega, rad/s */
    double wd[3][3]; /* wd[k][i]: (k+1)-th derivative of omega_i (wd[0] = alpha) */
    double f[3];     /* specific force at the plate point, m/s2 */
    double fd[3][3]; /* fd[k][i]: (k+1)-th derivative of f_i */
    double tenv;     /* temperature_env, degC */
    /* input_integrals 1: the interpolant of the interval ending here is the cubic Hermite plus
     * cw u^2 (1 - u)^2 (omega) and cf u^2 (1 - u)^2 (f), u in [0, 1] over the interval */
    int bump;        /* 1 when cw, cf are set (a previous knot and the integrals exist) */
    double cw[3], cf[3];
} ImuKnot;

/* Most Gauss-Markov terms of the flicker bias instability (noise.c) */
#define IMU_FLICKER_MAX 16

/* xoshiro256** state */
typedef struct {
    uint64_t s[4];
} ImuRng;

typedef struct {
    ImuKnot knot[IMU_MAX_KNOTS]; /* oldest first */
    int nknots;
    ImuRng rng[2];      /* [0] gyro stream, [1] accelerometer stream */
    double gm[2][3];    /* Gauss-Markov bias-instability state at the current time */
    double rw[2][3];    /* rate / acceleration random-walk bias at the current time */
    /* flicker bias instability (bi_tau_max > bi_tau): nflick Gauss-Markov terms per sensor
     * (0: off, the single process gm above), common standard deviation fsigma, correlation
     * times ftau, states fx[sensor][axis][term]; fphi and fq = fsigma sqrt(1 - fphi^2) are
     * those of the step length fh (0 before the first step) */
    ImuRng frng[2];     /* flicker streams: the gyro stream after 2 jumps (gyro), 3 (acc) */
    int nflick[2];
    double fsigma[2];
    double ftau[2][IMU_FLICKER_MAX];
    double fx[2][3][IMU_FLICKER_MAX];
    double fh[2];
    double fphi[2][IMU_FLICKER_MAX], fq[2][IMU_FLICKER_MAX];
    double resid[2][3]; /* count residual carried to the next sample (output kind 2) */
    int nsub;           /* Gauss-Legendre sub-intervals per piece (1 when the model is exact
                           with one: see integrate_piece) */
    int npts;           /* Gauss-Legendre points: 4 (cubic pieces) or 5 (quartic pieces) */
    /* a positive time offset (input_timing 0): the last step's integral over the sensor times
     * (ahead_a, ahead_b] whose motion lay past the newest knot (extrapolated); the next step
     * integrates that piece again on the knot that has arrived and adds the difference. Per
     * pass: [0] at imu.time_offset (both sensors, or the gyros when acc.time_offset != 0),
     * [1] at imu.time_offset + acc.time_offset (the accelerometers) */
    int ahead_set[2];
    double ahead_a[2], ahead_b[2];
    double ahead[2][2][3]; /* [pass][sensor][axis] */
} ModelPrivate;

#endif
