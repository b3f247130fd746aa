/* The contract between one model (physics) and the shared FMI layers (fmi2_layer.c,
 * fmi3_layer.c, on top of fmi_common.c). A model provides "model_state.h" (its private state, a plain struct with no
 * pointers) and the four functions declared at the bottom; the layers do everything FMI.
 *
 * Variable values live in s.r[] (Real) and s.i[] (Integer), indexed by value reference
 * (Integer index = vr - INTEGER_VR_BASE). The whole ModelState is one flat struct, so an FMU
 * state snapshot is a memcpy and several instances never share anything. */
#ifndef CALBENCH_MODEL_INSTANCE_H
#define CALBENCH_MODEL_INSTANCE_H

#include <stddef.h>
#include "config.h"
#include "model_state.h"

/* Same numeric values as fmi2Status and fmi3Status. */
typedef enum {
    MS_OK = 0,
    MS_WARNING = 1,
    MS_DISCARD = 2,
    MS_ERROR = 3,
    MS_FATAL = 4
} ModelStatus;

/* Highest order of input derivatives a master may pass (FMI 2 setRealInputDerivatives). */
#define MAX_INPUT_DERIVATIVE_ORDER 3

typedef struct {
    double r[N_REAL];
    int i[N_INTEGER];
    /* rder[vr][k-1]: k-th time derivative of Real input vr at the current communication point,
     * as last set by the master; reset to 0 when the input value itself is set without it. */
    double rder[N_REAL][MAX_INPUT_DERIVATIVE_ORDER];
    double time;
    double start_time;
    ModelPrivate p;
} ModelState;

typedef struct ModelInstance ModelInstance;
typedef void (*ModelLogFn)(ModelInstance *m, ModelStatus status, const char *category,
                           const char *message);

struct ModelInstance {
    ModelState s;
    /* environment: not part of an FMU state snapshot */
    char instance_name[128];
    ModelLogFn log_fn;
    void *env;
    int logging_on;
};

/* printf-style logging through the master's callback; defined in model_support.c */
void model_log(ModelInstance *m, ModelStatus status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Validate one Real parameter: finite, and within [lo, hi] when the bound is finite.
 * Logs "parameter <name> = <value>: expected <what>" and returns MS_ERROR when it is not. */
ModelStatus model_check_real(ModelInstance *m, int vr, double lo, double hi, const char *expected);

/* --- implemented by each model ---------------------------------------------------------- */

/* Called at exitInitializationMode. Check every parameter (log the offending one by name and
 * return MS_ERROR on a bad value), derive the private state, and set the initial outputs. */
ModelStatus model_initialize(ModelInstance *m);

/* Advance from m->s.time to m->s.time + h; inputs in m->s.r / m->s.i (and m->s.rder) are those
 * the master set before the call. Set the outputs for the end of the step. */
ModelStatus model_do_step(ModelInstance *m, double h);

/* Called when a tunable parameter or an input changed between steps (may be a no-op). */
ModelStatus model_inputs_changed(ModelInstance *m);

#endif
