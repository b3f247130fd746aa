/* Private state of the supplier_noisy_imu test model: a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_SUPPLIER_NOISY_IMU_MODEL_STATE_H
#define TEST_SUPPLIER_NOISY_IMU_MODEL_STATE_H

#include <stdint.h>

typedef struct {
    double prev[6];  /* previous input knot */
    uint64_t rng;    /* xorshift64* state */
} ModelPrivate;

#endif
