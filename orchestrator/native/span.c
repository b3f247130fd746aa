/* The orchestrator's hot loop: steps FMI 2.0 co-simulation units over a span of communication
 * steps with no Python in between. Python resolves value references, connection slots and unit
 * conversions once and hands this loop flat arrays; the loop calls the FMUs' own
 * fmi2SetReal/fmi2DoStep/fmi2GetReal directly.
 *
 * All exchanged values live in one array `slots` (SI units, role names). An input of a unit is
 * read from a slot and converted to the unit's own unit (value = scale * slot + shift); an
 * output is converted back to SI and written to its slot. */
#include <math.h>
#include <stddef.h>

typedef int (*SetRealFn)(void *, const unsigned *, size_t, const double *);
typedef int (*GetRealFn)(void *, const unsigned *, size_t, double *);
typedef int (*SetIntFn)(void *, const unsigned *, size_t, const int *);
typedef int (*GetIntFn)(void *, const unsigned *, size_t, int *);
typedef int (*SetDerFn)(void *, const unsigned *, size_t, const int *, const double *);
typedef int (*DoStepFn)(void *, double, double, int);

typedef struct {
    void *component;
    DoStepFn do_step;
    SetRealFn set_real;
    GetRealFn get_real;
    SetIntFn set_int;
    GetIntFn get_int;
    SetDerFn set_der;
    long multiple; /* the unit steps when step % multiple == 0, over multiple * h */

    long n_rin; /* Real inputs */
    const unsigned *rin_vr;
    const long *rin_slot;
    const double *rin_scale, *rin_shift;
    double *rin_buf;

    long n_iin; /* Integer inputs */
    const unsigned *iin_vr;
    const long *iin_slot;
    int *iin_buf;

    long n_der; /* first-order input derivatives, from slots (FMI 2 setRealInputDerivatives) */
    const unsigned *der_vr;
    const long *der_slot;
    const double *der_scale;
    const int *der_order;
    double *der_buf;

    long n_rout; /* Real outputs */
    const unsigned *rout_vr;
    const long *rout_slot;
    const double *rout_scale, *rout_shift;
    double *rout_buf;

    long n_iout; /* Integer outputs */
    const unsigned *iout_vr;
    const long *iout_slot;
    int *iout_buf;
} UnitPlan;

/* What went wrong, for the Python side to turn into one message. */
typedef struct {
    long step;    /* base step index at which it happened */
    long unit;    /* index into the plan */
    long call;    /* 1 setReal, 2 setInteger, 3 setRealInputDerivatives, 4 doStep, 5 getReal,
                     6 getInteger, 7 non-finite output */
    long status;  /* FMI status returned */
    long index;   /* variable index within the unit's list (outputs: which one) */
    long warned;  /* number of calls that returned fmi2Warning (counted, not fatal) */
} SpanError;

enum { CALL_SET_REAL = 1, CALL_SET_INT, CALL_SET_DER, CALL_DO_STEP, CALL_GET_REAL, CALL_GET_INT,
       CALL_NONFINITE };

#define FAIL(call_, status_, index_)                                                        \
    do {                                                                                    \
        err->step = step;                                                                   \
        err->unit = u;                                                                      \
        err->call = (call_);                                                                \
        err->status = (status_);                                                            \
        err->index = (index_);                                                              \
        return -1;                                                                          \
    } while (0)

/* fmi2Warning (1) is tolerated and counted; anything else but OK stops the span. */
static int bad(int status, SpanError *err) {
    if (status == 1) {
        err->warned++;
        return 0;
    }
    return status != 0;
}

static int set_inputs(const UnitPlan *p, const double *slots, long u, long step, SpanError *err) {
    long k;
    int st;
    if (p->n_rin) {
        for (k = 0; k < p->n_rin; k++)
            p->rin_buf[k] = p->rin_scale[k] * slots[p->rin_slot[k]] + p->rin_shift[k];
        st = p->set_real(p->component, p->rin_vr, (size_t)p->n_rin, p->rin_buf);
        if (bad(st, err)) FAIL(CALL_SET_REAL, st, -1);
    }
    if (p->n_iin) {
        for (k = 0; k < p->n_iin; k++) p->iin_buf[k] = (int)lround(slots[p->iin_slot[k]]);
        st = p->set_int(p->component, p->iin_vr, (size_t)p->n_iin, p->iin_buf);
        if (bad(st, err)) FAIL(CALL_SET_INT, st, -1);
    }
    if (p->n_der) {
        for (k = 0; k < p->n_der; k++) p->der_buf[k] = p->der_scale[k] * slots[p->der_slot[k]];
        st = p->set_der(p->component, p->der_vr, (size_t)p->n_der, p->der_order, p->der_buf);
        if (bad(st, err)) FAIL(CALL_SET_DER, st, -1);
    }
    return 0;
}

static int get_outputs(const UnitPlan *p, double *slots, long u, long step, SpanError *err) {
    long k;
    int st;
    if (p->n_rout) {
        st = p->get_real(p->component, p->rout_vr, (size_t)p->n_rout, p->rout_buf);
        if (bad(st, err)) FAIL(CALL_GET_REAL, st, -1);
        for (k = 0; k < p->n_rout; k++) {
            double v = p->rout_buf[k];
            if (!isfinite(v)) FAIL(CALL_NONFINITE, 0, k);
            slots[p->rout_slot[k]] = p->rout_scale[k] * v + p->rout_shift[k];
        }
    }
    if (p->n_iout) {
        st = p->get_int(p->component, p->iout_vr, (size_t)p->n_iout, p->iout_buf);
        if (bad(st, err)) FAIL(CALL_GET_INT, st, -1);
        for (k = 0; k < p->n_iout; k++) slots[p->iout_slot[k]] = (double)p->iout_buf[k];
    }
    return 0;
}

/* Advance units [first, last) of the plan over base steps [step0, step0 + n_steps).
 * jacobi = 0: Gauss-Seidel (each unit sees the outputs of the units before it at the end of
 * the step); 1: Jacobi (every unit sees the values at the start of the step).
 * After each base step, the slots rec_slot[] are copied into row (step + 1 - rec_row0) of rec
 * when (step + 1) is a multiple of rec_every. Returns 0, or -1 with *err filled in. */
__attribute__((visibility("default"))) int calbench_run_span(
    const UnitPlan *plan, long first, long last, double *slots, double t0, double h, long step0,
    long n_steps, int jacobi, double *rec, long n_rec, const long *rec_slot, long rec_every,
    long rec_row0, long rec_rows, SpanError *err) {
    long step, u, k;
    for (step = step0; step < step0 + n_steps; step++) {
        double t = t0 + (double)step * h;
        if (jacobi) {
            for (u = first; u < last; u++)
                if (step % plan[u].multiple == 0 && set_inputs(&plan[u], slots, u, step, err))
                    return -1;
            for (u = first; u < last; u++) {
                const UnitPlan *p = &plan[u];
                int st;
                if (step % p->multiple) continue;
                st = p->do_step(p->component, t, (double)p->multiple * h, 1);
                if (bad(st, err)) FAIL(CALL_DO_STEP, st, -1);
            }
            for (u = first; u < last; u++)
                if (step % plan[u].multiple == 0 && get_outputs(&plan[u], slots, u, step, err))
                    return -1;
        } else {
            for (u = first; u < last; u++) {
                const UnitPlan *p = &plan[u];
                int st;
                if (step % p->multiple) continue;
                if (set_inputs(p, slots, u, step, err)) return -1;
                st = p->do_step(p->component, t, (double)p->multiple * h, 1);
                if (bad(st, err)) FAIL(CALL_DO_STEP, st, -1);
                if (get_outputs(p, slots, u, step, err)) return -1;
            }
        }
        if (rec && (step + 1) % rec_every == 0) {
            long row = (step + 1) / rec_every - rec_row0;
            if (row >= 0 && row < rec_rows)
                for (k = 0; k < n_rec; k++) rec[row * n_rec + k] = slots[rec_slot[k]];
        }
    }
    return 0;
}
