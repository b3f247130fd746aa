/* Private state of the lag test model: a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_LAG_MODEL_STATE_H
#define TEST_LAG_MODEL_STATE_H

typedef struct {
    double prev[6]; /* previous input knot (supplier_imu); unused elsewhere */
    long steps;     /* doStep calls so far */
} ModelPrivate;

#endif
