/* Private state of the supplier_pulse_imu test model: a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_SUPPLIER_PULSE_IMU_MODEL_STATE_H
#define TEST_SUPPLIER_PULSE_IMU_MODEL_STATE_H

typedef struct {
    double prev[6];   /* previous input knot: deg/s, g */
    double integral[6]; /* since the start: arcsec (gyro), mm/s (accelerometer) */
    double pulses[6]; /* whole pulses given so far (a double holds them exactly up to 2^53) */
} ModelPrivate;

#endif
