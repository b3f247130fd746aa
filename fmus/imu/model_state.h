#ifndef IMU_MODEL_STATE_H
#define IMU_MODEL_STATE_H
typedef struct { double dummy; } ModelPrivate;
#endif
