/* Private state of the segv_imu test model (a copy of supplier_imu's): a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_SEGV_IMU_MODEL_STATE_H
#define TEST_SEGV_IMU_MODEL_STATE_H

typedef struct {
    double prev[6]; /* previous input knot (supplier_imu); unused elsewhere */
    long steps;     /* doStep calls so far */
} ModelPrivate;

#endif
