/* The native stepping loop of the pkmbench harness (loaded with ctypes by harness/master.py).
 *
 * Python instantiates and initialises the FMUs (fmpy); this loop only steps, routes values
 * along the connections and records into a preallocated array, so a macro step costs the
 * models' own compute plus a few indirect calls — not ~20 µs of Python per step.
 * Semantics are those of master.py's reference loop (tests compare them to 1e-12).
 */
#include <stddef.h>

typedef int (*DoStepFn)(void *, double, double, int);
typedef int (*GetRealFn)(void *, const unsigned *, size_t, double *);
typedef int (*SetRealFn)(void *, const unsigned *, size_t, const double *);
typedef int (*GetIntFn)(void *, const unsigned *, size_t, int *);
typedef int (*SetIntFn)(void *, const unsigned *, size_t, const int *);

enum { T_REAL = 0, T_INT = 1, T_BOOL = 2 };

typedef struct {
    void *c;
    DoStepFn do_step;
    GetRealFn get_real;
    SetRealFn set_real;
    GetIntFn get_int, get_bool;
    SetIntFn set_int, set_bool;
    int period;           /* stepped every period-th macro step */
} Comp;

static double get_value(const Comp *c, int type, unsigned vr) {
    double d = 0;
    int i = 0;
    if (type == T_REAL) c->get_real(c->c, &vr, 1, &d);
    else if (type == T_INT) c->get_int(c->c, &vr, 1, &i), d = i;
    else c->get_bool(c->c, &vr, 1, &i), d = i ? 1.0 : 0.0;
    return d;
}

static int set_value(const Comp *c, int type, unsigned vr, double d) {
    int i = (int)d;
    if (type == T_REAL) return c->set_real(c->c, &vr, 1, &d);
    if (type == T_INT) return c->set_int(c->c, &vr, 1, &i);
    i = d != 0.0;
    return c->set_bool(c->c, &vr, 1, &i);
}

/* conn: 5 ints per connection (type, src comp, src vr, dst comp, dst vr)
 * rec:  3 ints per recorded variable (type, comp, vr); out: (nsteps + 1) × nrec, row 0 = t0
 * Returns 0, or the 1-based index of the component whose fmi2DoStep failed (step in *fail_step),
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
            if (c->do_step(c->c, t, h * c->period, 1) > 1) {   /* > fmi2Warning */
                *fail_step = k;
                return i + 1;
            }
        }
        double *row = out + (size_t)(k + 1) * nrec;
        for (int r = 0; r < nrec; r++) row[r] = get_value(&comps[rec[3 * r + 1]], rec[3 * r], (unsigned)rec[3 * r + 2]);
    }
    return 0;
}
