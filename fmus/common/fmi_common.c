/* The FMI-version-neutral half of the FMI layers: see fmi_common.h. The layers have checked the
 * handle and the mode (fmi_allowed) before they call any of these, so f is never NULL here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi_common.h"

/* ------------------------------------------------------------------ state machine */

static const char *mode_name(FmiMode mode) {
    switch (mode) {
    case MODE_INSTANTIATED:
        return "Instantiated";
    case MODE_INITIALIZATION:
        return "Initialization Mode";
    case MODE_STEP:
        return "Step Mode";
    case MODE_TERMINATED:
        return "Terminated";
    }
    return "an unknown mode";
}

void fmi_instantiated(FmiCore *f, const FmiVersion *version, const char *name, ModelLogFn log_fn,
                      void *env, int logging_on) {
    f->version = version;
    strncpy(f->m.instance_name, name, sizeof f->m.instance_name - 1);
    f->m.log_fn = log_fn;
    f->m.env = env;
    f->m.logging_on = logging_on ? 1 : 0;
    fmi_reset(f);
}

int fmi_allowed(FmiCore *f, unsigned mask, const char *fn) {
    if (!f) return 0;
    if (mask & (unsigned)f->mode) return 1;
    model_log(&f->m, MS_ERROR, "%s is not allowed in %s", fn, mode_name(f->mode));
    return 0;
}

ModelStatus fmi_refuse(FmiCore *f, const char *why) {
    if (f) model_log(&f->m, MS_ERROR, "%s", why);
    return MS_ERROR;
}

ModelStatus fmi_no_variables(FmiCore *f, size_t nvr, const char *type) {
    if (!nvr) return MS_OK;
    model_log(&f->m, MS_ERROR, "this FMU has no %s variables", type);
    return MS_ERROR;
}

ModelStatus fmi_set_debug_logging(FmiCore *f, int on) {
    f->m.logging_on = on ? 1 : 0;
    return MS_OK;
}

ModelStatus fmi_reset(FmiCore *f) {
    memset(&f->m.s, 0, sizeof f->m.s);
    memcpy(f->m.s.r, REAL_START, sizeof REAL_START);
    memcpy(f->m.s.i, INTEGER_START, sizeof INTEGER_START);
    f->mode = MODE_INSTANTIATED;
    f->failed = 0;
    return MS_OK;
}

ModelStatus fmi_set_start_time(FmiCore *f, double t) {
    if (!isfinite(t)) {
        model_log(&f->m, MS_ERROR, "start time %g: expected a finite value", t);
        return MS_ERROR;
    }
    f->m.s.time = t;
    f->m.s.start_time = t;
    return MS_OK;
}

ModelStatus fmi_enter_initialization(FmiCore *f) {
    f->mode = MODE_INITIALIZATION;
    return MS_OK;
}

ModelStatus fmi_exit_initialization(FmiCore *f) {
    ModelStatus st = model_initialize(&f->m);
    /* a refused parameter leaves the instance in Initialization Mode: the master may correct it
     * and exit again, which is then a fresh start */
    if (st >= MS_ERROR) {
        f->failed = 1;
        return st;
    }
    f->failed = 0;
    f->mode = MODE_STEP;
    return st;
}

ModelStatus fmi_terminate(FmiCore *f) {
    f->mode = MODE_TERMINATED;
    return MS_OK;
}

/* ------------------------------------------------------------------ get / set */

/* Has the model been initialised (parameters derived, fixed ones frozen)? */
static int initialized(const FmiCore *f) { return (f->mode & (MODE_STEP | MODE_TERMINATED)) != 0; }

static int real_index(FmiCore *f, unsigned vr) {
    if (vr >= N_REAL) {
        model_log(&f->m, MS_ERROR, "value reference %u is not a %s variable", vr,
                  f->version->real_type);
        return -1;
    }
    return (int)vr;
}

static int integer_index(FmiCore *f, unsigned vr) {
    if (vr < INTEGER_VR_BASE || vr >= INTEGER_VR_BASE + N_INTEGER_USED) {
        model_log(&f->m, MS_ERROR, "value reference %u is not an %s variable", vr,
                  f->version->integer_type);
        return -1;
    }
    return (int)(vr - INTEGER_VR_BASE);
}

/* May the master set a variable of this causality/variability now? */
static int settable(FmiCore *f, unsigned char caus, unsigned char var, const char *name) {
    if (caus == CAUS_INPUT) return 1;
    if (caus == CAUS_PARAMETER && (!initialized(f) || var == VAR_TUNABLE)) return 1;
    model_log(&f->m, MS_ERROR, "variable %s cannot be set %s", name,
              caus == CAUS_PARAMETER ? "after initialisation (fixed parameter)"
                                     : "(it is not an input or parameter)");
    return 0;
}

ModelStatus fmi_get_reals(FmiCore *f, const unsigned vr[], size_t nvr, double value[]) {
    size_t k;
    if (nvr && (!vr || !value)) return MS_ERROR;
    if (f->mode == MODE_INITIALIZATION && nvr) {
        /* outputs are "calculated" from the parameters and inputs set so far, so a master that
         * propagates initial values (libcosim) sees real ones */
        ModelStatus st = model_initialize(&f->m);
        if (st >= MS_ERROR) return st;
    }
    for (k = 0; k < nvr; k++) {
        int j;
        if (f->version->time_is_variable && vr[k] == TIME_VR) {
            value[k] = f->m.s.time;
            continue;
        }
        j = real_index(f, vr[k]);
        if (j < 0) return MS_ERROR;
        value[k] = f->m.s.r[j];
    }
    return MS_OK;
}

ModelStatus fmi_set_reals(FmiCore *f, const unsigned vr[], size_t nvr, const double value[]) {
    size_t k;
    int changed = 0;
    if (nvr && (!vr || !value)) return MS_ERROR;
    for (k = 0; k < nvr; k++) {
        int j;
        if (f->version->time_is_variable && vr[k] == TIME_VR)
            return fmi_refuse(f, "variable time is the independent variable and cannot be set");
        j = real_index(f, vr[k]);
        if (j < 0) return MS_ERROR;
        if (!settable(f, REAL_CAUSALITY[j], REAL_VARIABILITY[j], REAL_NAME[j])) return MS_ERROR;
        f->m.s.r[j] = value[k];
        memset(f->m.s.rder[j], 0, sizeof f->m.s.rder[j]);
        changed = 1;
    }
    if (changed && initialized(f)) return model_inputs_changed(&f->m);
    return MS_OK;
}

ModelStatus fmi_get_integers(FmiCore *f, const unsigned vr[], size_t nvr, int value[]) {
    size_t k;
    if (nvr && (!vr || !value)) return MS_ERROR;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(f, vr[k]);
        if (j < 0) return MS_ERROR;
        value[k] = f->m.s.i[j];
    }
    return MS_OK;
}

ModelStatus fmi_set_integers(FmiCore *f, const unsigned vr[], size_t nvr, const int value[]) {
    size_t k;
    int changed = 0;
    if (nvr && (!vr || !value)) return MS_ERROR;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(f, vr[k]);
        if (j < 0) return MS_ERROR;
        if (!settable(f, INTEGER_CAUSALITY[j], INTEGER_VARIABILITY[j], INTEGER_NAME[j]))
            return MS_ERROR;
        f->m.s.i[j] = value[k];
        changed = 1;
    }
    if (changed && initialized(f)) return model_inputs_changed(&f->m);
    return MS_OK;
}

ModelStatus fmi_set_input_derivatives(FmiCore *f, const unsigned vr[], size_t nvr,
                                      const int order[], const double value[]) {
    size_t k;
    if (nvr && (!vr || !order || !value)) return MS_ERROR;
    for (k = 0; k < nvr; k++) {
        int j = real_index(f, vr[k]);
        if (j < 0) return MS_ERROR;
        if (REAL_CAUSALITY[j] != CAUS_INPUT) {
            model_log(&f->m, MS_ERROR, "derivative set for %s, which is not an input",
                      REAL_NAME[j]);
            return MS_ERROR;
        }
        if (order[k] < 1 || order[k] > MAX_INPUT_DERIVATIVE_ORDER) {
            model_log(&f->m, MS_ERROR, "derivative order %d for %s: expected 1..%d", order[k],
                      REAL_NAME[j], MAX_INPUT_DERIVATIVE_ORDER);
            return MS_ERROR;
        }
        f->m.s.rder[j][order[k] - 1] = value[k];
    }
    return MS_OK;
}

/* ------------------------------------------------------------------ step */

ModelStatus fmi_do_step(FmiCore *f, double t, double h, const char *fn) {
    ModelStatus st;
    if (f->failed) {
        model_log(&f->m, MS_ERROR, "%s after a failed step; reset or restore a state", fn);
        return MS_ERROR;
    }
    if (!(h > 0.0) || !isfinite(h)) {
        model_log(&f->m, MS_ERROR, "communication step size %g: expected > 0", h);
        return MS_ERROR;
    }
    if (fabs(t - f->m.s.time) > 1e-9 * (1.0 + fabs(t))) {
        model_log(&f->m, MS_ERROR, "doStep at t = %.12g but the FMU is at t = %.12g", t,
                  f->m.s.time);
        return MS_ERROR;
    }
    st = model_do_step(&f->m, h);
    if (st >= MS_ERROR) {
        f->failed = 1;
        return st;
    }
    if (st != MS_DISCARD) f->m.s.time = t + h;
    return st;
}

/* ------------------------------------------------------------------ FMU state */

/* Leads every serialised state, so that bytes from another model or build are recognised. */
#define STATE_MAGIC "calbench-state:" MODEL_IDENTIFIER_STRING

ModelStatus fmi_get_state(FmiCore *f, void **state) {
    ModelState *copy;
    if (!state) return MS_ERROR;
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return fmi_refuse(f, "out of memory saving the FMU state");
    memcpy(copy, &f->m.s, sizeof *copy);
    *state = copy;
    return MS_OK;
}

ModelStatus fmi_set_state(FmiCore *f, const void *state) {
    if (!state) return MS_ERROR;
    memcpy(&f->m.s, state, sizeof f->m.s);
    f->failed = 0;
    return MS_OK;
}

ModelStatus fmi_free_state(FmiCore *f, void **state) {
    (void)f;
    if (!state) return MS_ERROR;
    free(*state);
    *state = NULL;
    return MS_OK;
}

ModelStatus fmi_serialized_state_size(FmiCore *f, size_t *size) {
    (void)f;
    if (!size) return MS_ERROR;
    *size = sizeof STATE_MAGIC + sizeof(ModelState);
    return MS_OK;
}

ModelStatus fmi_serialize_state(FmiCore *f, const void *state, void *bytes, size_t size) {
    if (!state || !bytes) return MS_ERROR;
    if (size < sizeof STATE_MAGIC + sizeof(ModelState))
        return fmi_refuse(f, "buffer too small to serialise the FMU state");
    memcpy(bytes, STATE_MAGIC, sizeof STATE_MAGIC);
    memcpy((unsigned char *)bytes + sizeof STATE_MAGIC, state, sizeof(ModelState));
    return MS_OK;
}

ModelStatus fmi_deserialize_state(FmiCore *f, const void *bytes, size_t size, void **state) {
    ModelState *copy;
    if (!bytes || !state) return MS_ERROR;
    if (size != sizeof STATE_MAGIC + sizeof(ModelState) ||
        memcmp(bytes, STATE_MAGIC, sizeof STATE_MAGIC) != 0)
        return fmi_refuse(f, "serialised state is not from this model and build");
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return fmi_refuse(f, "out of memory restoring the FMU state");
    memcpy(copy, (const unsigned char *)bytes + sizeof STATE_MAGIC, sizeof *copy);
    *state = copy;
    return MS_OK;
}
