/* The part of the FMI layers that does not depend on the FMI version: the state machine, the
 * lookup of value references, the checks on the master's arguments, moving values in and out
 * of the flat ModelState, and FMU state snapshots. fmi2_layer.c and fmi3_layer.c only map their
 * version's signatures and types onto these functions, so that a rule (what may be set when,
 * at which time a step may start, what a serialised state must look like) is written once and
 * both versions obey it alike.
 *
 * Every function returns a ModelStatus, whose values are those of fmi2Status and fmi3Status. */
#ifndef CALBENCH_FMI_COMMON_H
#define CALBENCH_FMI_COMMON_H

#include <stddef.h>
#include "model_instance.h"

/* One bit per mode, so that the modes an FMI function may be called in are a mask. FMI 2 does
 * not name them, but its co-simulation state machine walks the same path: instantiated ->
 * (setupExperiment) enterInitializationMode -> exitInitializationMode -> steps -> terminate,
 * and reset leads back to the start from anywhere. */
typedef enum {
    MODE_INSTANTIATED = 1 << 0,   /* after instantiate or reset */
    MODE_INITIALIZATION = 1 << 1, /* between enter and exit initialization mode */
    MODE_STEP = 1 << 2,           /* after a successful exitInitializationMode */
    MODE_TERMINATED = 1 << 3
} FmiMode;

/* The modes each FMI function may be called in, from the state tables of FMI 2.0 and 3.0 for
 * co-simulation without event mode; every layer function checks its mask on entry
 * (fmi_allowed). The functions of what a calbench FMU does not offer have no mask: they
 * refuse in every mode. */
#define MODES_ANY (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED)
#define MASK_SET_DEBUG_LOGGING MODES_ANY
#define MASK_RESET MODES_ANY
#define MASK_SETUP_EXPERIMENT MODE_INSTANTIATED
#define MASK_ENTER_INITIALIZATION MODE_INSTANTIATED
#define MASK_EXIT_INITIALIZATION MODE_INITIALIZATION
/* wider than the standards: a master cleaning up after a failed initialisation, or twice,
 * should not get an error on top of the one it is handling */
#define MASK_TERMINATE (MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED)
/* outputs exist once initialisation has begun and stay readable after terminate; start values
 * are set before initialisation, nothing after terminate */
#define MASK_GET (MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED)
#define MASK_SET (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP)
#define MASK_SET_INPUT_DERIVATIVES (MODE_INITIALIZATION | MODE_STEP)
#define MASK_DO_STEP MODE_STEP
#define MASK_GET_STATUS (MODE_STEP | MODE_TERMINATED)
#define MASK_FMU_STATE MODES_ANY

/* The little the common code must know about the version it serves. */
typedef struct {
    const char *real_type, *integer_type; /* the standard's type names, for messages */
    int time_is_variable;                 /* FMI 3 declares the independent variable (TIME_VR) */
} FmiVersion;

typedef struct {
    ModelInstance m; /* first member: the model's ModelInstance* is this FmiCore* */
    const FmiVersion *version;
    FmiMode mode;
    int failed; /* a step or the initialisation returned error/fatal */
} FmiCore;

/* Each layer's instance struct has its FmiCore as first member, so the master's handle is one;
 * a NULL handle stays NULL. */
#define CORE(c) ((FmiCore *)(c))

/* The first statement of an FMI function: return error unless the handle c exists and is in
 * one of the modes of mask (__func__ names the function in the message). */
#define FMI_ALLOW(c, mask, error)                                                             \
    do {                                                                                      \
        if (!fmi_allowed(CORE(c), (mask), __func__)) return (error);                          \
    } while (0)

/* Fill in a freshly allocated (zeroed) instance and put it into MODE_INSTANTIATED. */
void fmi_instantiated(FmiCore *f, const FmiVersion *version, const char *name, ModelLogFn log_fn,
                      void *env, int logging_on);

/* May function fn be called now (f non-NULL and its mode in mask)? Logs and returns 0 if not. */
int fmi_allowed(FmiCore *f, unsigned mask, const char *fn);

/* Log why a call is refused and return MS_ERROR (f may be NULL). */
ModelStatus fmi_refuse(FmiCore *f, const char *why);

/* A getter or setter of a type the FMU has no variables of: only an empty call succeeds. */
ModelStatus fmi_no_variables(FmiCore *f, size_t nvr, const char *type);

ModelStatus fmi_set_debug_logging(FmiCore *f, int on);
ModelStatus fmi_reset(FmiCore *f);
ModelStatus fmi_set_start_time(FmiCore *f, double t);
ModelStatus fmi_enter_initialization(FmiCore *f);
ModelStatus fmi_exit_initialization(FmiCore *f);
ModelStatus fmi_terminate(FmiCore *f);

ModelStatus fmi_get_reals(FmiCore *f, const unsigned vr[], size_t nvr, double value[]);
ModelStatus fmi_set_reals(FmiCore *f, const unsigned vr[], size_t nvr, const double value[]);
ModelStatus fmi_get_integers(FmiCore *f, const unsigned vr[], size_t nvr, int value[]);
ModelStatus fmi_set_integers(FmiCore *f, const unsigned vr[], size_t nvr, const int value[]);
ModelStatus fmi_set_input_derivatives(FmiCore *f, const unsigned vr[], size_t nvr,
                                      const int order[], const double value[]);

/* Step from t to t + h; fn names the caller in messages. */
ModelStatus fmi_do_step(FmiCore *f, double t, double h, const char *fn);

ModelStatus fmi_get_state(FmiCore *f, void **state);
ModelStatus fmi_set_state(FmiCore *f, const void *state);
ModelStatus fmi_free_state(FmiCore *f, void **state);
ModelStatus fmi_serialized_state_size(FmiCore *f, size_t *size);
ModelStatus fmi_serialize_state(FmiCore *f, const void *state, void *bytes, size_t size);
ModelStatus fmi_deserialize_state(FmiCore *f, const void *bytes, size_t size, void **state);

#endif
