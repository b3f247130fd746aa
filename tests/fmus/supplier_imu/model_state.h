/* Private state of the supplier_imu test model: a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_SUPPLIER_IMU_MODEL_STATE_H
#define TEST_SUPPLIER_IMU_MODEL_STATE_H

typedef struct {
    double prev[6]; /* previous input knot (supplier_imu); unused elsewhere */
    long steps;     /* doStep calls so far */
} ModelPrivate;

#endif
