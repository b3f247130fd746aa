/* Helpers shared by every model and both FMI layers. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include "model_instance.h"

void model_log(ModelInstance *m, ModelStatus status, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    if (!m || !m->log_fn) return;
    /* errors are always reported; chatter only when the master asked for it */
    if (status < MS_WARNING && !m->logging_on) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    m->log_fn(m, status, status >= MS_ERROR ? "logStatusError" : "logAll", buf);
}

ModelStatus model_check_real(ModelInstance *m, int vr, double lo, double hi, const char *expected) {
    double v = m->s.r[vr];
    if (!isfinite(v) || (isfinite(lo) && v < lo) || (isfinite(hi) && v > hi)) {
        model_log(m, MS_ERROR, "parameter %s = %g: expected %s", REAL_NAME[vr], v, expected);
        return MS_ERROR;
    }
    return MS_OK;
}
