/* The native stepping loop of the pkmbench harness (loaded with ctypes by harness/master.py).
 *
 * Python instantiates and initialises the FMUs (fmpy); this loop only steps, routes values
 * along the connections and records into a preallocated array, so a macro step costs the
 * models' own compute plus a few indirect calls — not ~20 µs of Python per step.
 * Semantics are those of master.py's reference loop (tests compare them to 1e-12).
 */
#include <stdbool.h>
#include <stddef.h>

/* FMI 2.0 (fmi2DoStep, fmi2GetReal, …) and FMI 3.0 (fmi3DoStep, fmi3GetFloat64, …) signatures;
 * a component holds its functions as AnyFn (the one pointer type any function pointer may be
 * cast to and from without -Wcast-function-type) and is called through its version's types. */
typedef void (*AnyFn)(void);
typedef int (*DoStepFn)(void *, double, double, int);
typedef int (*GetRealFn)(void *, const unsigned *, size_t, double *);
typedef int (*SetRealFn)(void *, const unsigned *, size_t, const double *);
typedef int (*GetIntFn)(void *, const unsigned *, size_t, int *);
typedef int (*SetIntFn)(void *, const unsigned *, size_t, const int *);
typedef int (*DoStep3Fn)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*GetFloat64Fn)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*SetFloat64Fn)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*GetInt32Fn)(void *, const unsigned *, size_t, int *, size_t);
typedef int (*SetInt32Fn)(void *, const unsigned *, size_t, const int *, size_t);
typedef int (*GetBool3Fn)(void *, const unsigned *, size_t, bool *, size_t);
typedef int (*SetBool3Fn)(void *, const unsigned *, size_t, const bool *, size_t);

enum { T_REAL = 0, T_INT = 1, T_BOOL = 2 };

typedef struct {
    void *c;
    AnyFn do_step, get_real, set_real, get_int, get_bool, set_int, set_bool;   /* Float64, Int32 in FMI 3.0 */
    int period;           /* stepped every period-th macro step */
    int fmi3;             /* 1: the functions are FMI 3.0's */
} Comp;

static double get_value3(const Comp *c, int type, unsigned vr) {
    double d = 0;
    int i = 0;
    bool b = false;
    if (type == T_REAL) ((GetFloat64Fn)c->get_real)(c->c, &vr, 1, &d, 1);
    else if (type == T_INT) ((GetInt32Fn)c->get_int)(c->c, &vr, 1, &i, 1), d = i;
    else ((GetBool3Fn)c->get_bool)(c->c, &vr, 1, &b, 1), d = b ? 1.0 : 0.0;
    return d;
}

static double get_value(const Comp *c, int type, unsigned vr) {
    double d = 0;
    int i = 0;
    if (c->fmi3) return get_value3(c, type, vr);
    if (type == T_REAL) ((GetRealFn)c->get_real)(c->c, &vr, 1, &d);
    else if (type == T_INT) ((GetIntFn)c->get_int)(c->c, &vr, 1, &i), d = i;
    else ((GetIntFn)c->get_bool)(c->c, &vr, 1, &i), d = i ? 1.0 : 0.0;
    return d;
}

static int set_value(const Comp *c, int type, unsigned vr, double d) {
    int i = (int)d;
    bool b = d != 0.0;
    if (c->fmi3) {
        if (type == T_REAL) return ((SetFloat64Fn)c->set_real)(c->c, &vr, 1, &d, 1);
        if (type == T_INT) return ((SetInt32Fn)c->set_int)(c->c, &vr, 1, &i, 1);
        return ((SetBool3Fn)c->set_bool)(c->c, &vr, 1, &b, 1);
    }
    if (type == T_REAL) return ((SetRealFn)c->set_real)(c->c, &vr, 1, &d);
    if (type == T_INT) return ((SetIntFn)c->set_int)(c->c, &vr, 1, &i);
    i = b;
    return ((SetIntFn)c->set_bool)(c->c, &vr, 1, &i);
}

/* One step of h from t; the status (FMI 2.0 and 3.0 alike: > 1 is Discard, Error or Fatal).
 * FMI 3.0's event, terminate and early-return flags are ignored, as by master.py's loop. */
static int do_step(const Comp *c, double t, double h) {
    if (c->fmi3) {
        bool event = false, terminate = false, early = false;
        double last = t;
        return ((DoStep3Fn)c->do_step)(c->c, t, h, true, &event, &terminate, &early, &last);
    }
    return ((DoStepFn)c->do_step)(c->c, t, h, 1);
}

/* conn: 5 ints per connection (type, src comp, src vr, dst comp, dst vr)
 * rec:  3 ints per recorded variable (type, comp, vr); out: (nsteps + 1) × nrec, row 0 = t0
 * Returns 0, or the 1-based index of the component whose fmi2DoStep/fmi3DoStep failed (step in *fail_step),
 * or -(component + 1) if setting an input failed. */
int pkm_run(int ncomp, Comp *comps, int nconn, const int *conn, int nrec, const int *rec,
            double t0, double h, long nsteps, int jacobi, double *out, double *buf, long *fail_step) {
    for (int r = 0; r < nrec; r++) out[r] = get_value(&comps[rec[3 * r + 1]], rec[3 * r], (unsigned)rec[3 * r + 2]);
    for (long k = 0; k < nsteps; k++) {
        double t = t0 + k * h;
        if (jacobi) {   /* every input from the outputs at the start of the step */
            for (int j = 0; j < nconn; j++) {
                const int *cj = conn + 5 * j;
                buf[j] = get_value(&comps[cj[1]], cj[0], (unsigned)cj[2]);
            }
            for (int j = 0; j < nconn; j++) {
                const int *cj = conn + 5 * j;
                if (k % comps[cj[3]].period == 0 && set_value(&comps[cj[3]], cj[0], (unsigned)cj[4], buf[j]) > 1) {
                    *fail_step = k;
                    return -(cj[3] + 1);
                }
            }
        }
        for (int i = 0; i < ncomp; i++) {
            Comp *c = &comps[i];
            if (k % c->period) continue;
            if (!jacobi)   /* Gauss–Seidel: inputs from the components already stepped */
                for (int j = 0; j < nconn; j++) {
                    const int *cj = conn + 5 * j;
                    if (cj[3] != i) continue;
                    if (set_value(c, cj[0], (unsigned)cj[4], get_value(&comps[cj[1]], cj[0], (unsigned)cj[2])) > 1) {
                        *fail_step = k;
                        return -(i + 1);
                    }
                }
            if (do_step(c, t, h * c->period) > 1) {   /* > fmi2Warning, fmi3Warning */
                *fail_step = k;
                return i + 1;
            }
        }
        double *row = out + (size_t)(k + 1) * nrec;
        for (int r = 0; r < nrec; r++) row[r] = get_value(&comps[rec[3 * r + 1]], rec[3 * r], (unsigned)rec[3 * r + 2]);
    }
    return 0;
}
