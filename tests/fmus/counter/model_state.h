/* Private state of the counter test model: a plain struct (an FMU state is a memcpy of it). */
#ifndef TEST_COUNTER_MODEL_STATE_H
#define TEST_COUNTER_MODEL_STATE_H

typedef struct {
    long steps; /* doStep calls so far */
} ModelPrivate;

#endif
