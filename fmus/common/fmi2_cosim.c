/* The FMI 2.0 co-simulation API, written once for every pkmbench model (see fmu.h).
 * Models implement only the model_* functions; this file owns the state machine, the
 * fixed internal step, variable access dispatch, FMU state copies and logging. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu.h"

/* ---- logging ------------------------------------------------------------------------ */
static void vlog(ModelInstance *comp, fmi2Status status, const char *category, const char *fmt, va_list ap) {
    char msg[2048], esc[4096];
    size_t k = 0;
    if (!comp || comp->quiet || !comp->functions || !comp->functions->logger) return;
    vsnprintf(msg, sizeof msg, fmt, ap);
    /* The formatted text is passed as the format itself (as the Reference-FMUs do), so an
     * importer that does not expand variadic arguments (fmpy) still shows the message; '%'
     * is doubled for importers that do. */
    for (const char *p = msg; *p && k + 2 < sizeof esc; p++) {
        if (*p == '%') esc[k++] = '%';
        esc[k++] = *p;
    }
    esc[k] = 0;
    comp->functions->logger(comp->functions->componentEnvironment, comp->instance_name, status, category, esc);
}

void model_log(ModelInstance *comp, const char *category, const char *fmt, ...) {
    va_list ap;
    if (!comp || !comp->logging_on) return;
    va_start(ap, fmt);
    vlog(comp, fmi2OK, category, fmt, ap);
    va_end(ap);
}

void model_error(ModelInstance *comp, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlog(comp, fmi2Error, "logStatusError", fmt, ap);
    va_end(ap);
}

fmi2Status model_copy_string(ModelInstance *comp, char *dst, const char *src, const char *what) {
    if (!src) src = "";
    if (strlen(src) >= PKM_STRING_MAX) {
        model_error(comp, "%s is longer than %d characters", what, PKM_STRING_MAX - 1);
        return fmi2Error;
    }
    strcpy(dst, src);
    return fmi2OK;
}

void model_resolve_path(ModelInstance *comp, const char *name, char *out, size_t out_size) {
    if (strncmp(name, "resource:", 9) == 0)
        snprintf(out, out_size, "%s/%s", comp->resource_dir, name + 9);
    else
        snprintf(out, out_size, "%s", name);
}

/* ---- helpers ------------------------------------------------------------------------ */
#define PKM_ALLOWED(comp, fname, mask)                                                         \
    do {                                                                                       \
        if (!(comp)) return fmi2Error;                                                         \
        if (!((1u << (comp)->phase) & (mask))) {                                               \
            model_error((comp), "%s is not allowed in phase %d", fname, (int)(comp)->phase);   \
            return fmi2Error;                                                                  \
        }                                                                                      \
    } while (0)
#define P_INST (1u << PKM_INSTANTIATED)
#define P_INIT (1u << PKM_INITIALIZATION)
#define P_STEP (1u << PKM_STEP_COMPLETE)
#define P_TERM (1u << PKM_TERMINATED)
#define P_ERR (1u << PKM_ERROR)
#define P_ANY (P_INST | P_INIT | P_STEP | P_TERM | P_ERR)

static fmi2Status fail(ModelInstance *comp) {
    comp->phase = PKM_ERROR;
    return fmi2Error;
}

/* FMI 2.0 lets a master read outputs in Initialization Mode, after setting inputs, and a master
 * that propagates initial values that way (OSP libcosim: every FMU in Initialization Mode, values
 * passed along the connections, then all leave it) must see outputs that follow their inputs, as
 * fmi2ExitInitializationMode would compute them. So a read after a change initialises the model
 * provisionally, without logging (its inputs may not have arrived yet); fmi2ExitInitializationMode
 * initialises it again and reports any error. */
static void provisional_init(ModelInstance *comp) {
    if (comp->phase != PKM_INITIALIZATION || !comp->init_dirty) return;
    comp->init_dirty = false;
    comp->quiet = true;
    model_free(comp);
    (void)model_initialize(comp);
    comp->quiet = false;
}

static void uri_to_path(const char *uri, char *out, size_t n) {
    const char *p = uri ? uri : "";
    if (strncmp(p, "file://localhost/", 17) == 0) p += 16;
    else if (strncmp(p, "file:///", 8) == 0) p += 7;
    else if (strncmp(p, "file:/", 6) == 0) p += 5;
    size_t k = 0;
    for (; *p && k + 1 < n; p++) {  /* decode %XX escapes (spaces in temp dirs) */
        if (p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            out[k++] = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            out[k++] = *p;
        }
    }
    out[k] = 0;
    if (k > 0 && out[k - 1] == '/') out[k - 1] = 0;
}

/* ---- common API --------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[]) {
    ModelInstance *comp = (ModelInstance *)c;
    (void)n;
    (void)categories;
    if (!comp) return fmi2Error;
    comp->logging_on = loggingOn ? true : false;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    if (!functions || !functions->logger) return NULL;
    if (!instanceName || !*instanceName) {
        functions->logger(functions->componentEnvironment, "?", fmi2Error, "logStatusError", "missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "%s supports co-simulation only", MODEL_IDENTIFIER);
        return NULL;
    }
    if (!guid || strcmp(guid, INSTANTIATION_TOKEN) != 0) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "GUID '%s' does not match '%s' of %s", guid ? guid : "", INSTANTIATION_TOKEN, MODEL_IDENTIFIER);
        return NULL;
    }
    ModelInstance *comp = (ModelInstance *)calloc(1, sizeof(ModelInstance));
    if (!comp) return NULL;
    snprintf(comp->instance_name, sizeof comp->instance_name, "%s", instanceName);
    uri_to_path(resourceLocation, comp->resource_dir, sizeof comp->resource_dir);
    comp->functions = functions;
    comp->logging_on = loggingOn ? true : false;
    comp->phase = PKM_INSTANTIATED;
    comp->stop_time = INFINITY;
    model_set_start_values(comp);
    return comp;
}

void fmi2FreeInstance(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!comp) return;
    model_free(comp);
    free(comp);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    ModelInstance *comp = (ModelInstance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    PKM_ALLOWED(comp, "fmi2SetupExperiment", P_INST);
    comp->start_time = comp->time = startTime;
    comp->stop_time = stopTimeDefined ? stopTime : INFINITY;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2EnterInitializationMode", P_INST);
    comp->phase = PKM_INITIALIZATION;
    comp->init_dirty = true;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2ExitInitializationMode", P_INIT);
    comp->fixed_step = 0.0;
    comp->steps = 0;
    model_free(comp);   /* what a provisional initialisation allocated */
    if (model_initialize(comp) > fmi2Warning) return fail(comp);
    comp->phase = PKM_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2Terminate", P_STEP | P_ERR);
    fmi2Status s = comp->phase == PKM_STEP_COMPLETE ? model_terminate(comp) : fmi2OK;
    comp->phase = PKM_TERMINATED;
    return s;
}

fmi2Status fmi2Reset(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2Reset", P_ANY);
    model_free(comp);
    memset(&comp->data, 0, sizeof comp->data);
    comp->phase = PKM_INSTANTIATED;
    comp->time = comp->start_time = 0.0;
    comp->stop_time = INFINITY;
    model_set_start_values(comp);
    return fmi2OK;
}

/* ---- variable access ------------------------------------------------------------------ */
#define GETTER(fname, ctype, mfun, mtype)                                                         \
    fmi2Status fname(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, ctype value[]) { \
        ModelInstance *comp = (ModelInstance *)c;                                                 \
        PKM_ALLOWED(comp, #fname, P_INST | P_INIT | P_STEP | P_TERM | P_ERR);                     \
        provisional_init(comp);                                                                   \
        for (size_t i = 0; i < nvr; i++) {                                                        \
            mtype v;                                                                              \
            if (mfun(comp, vr[i], &v) != fmi2OK) {                                                \
                model_error(comp, "%s: unknown value reference %u", #fname, (unsigned)vr[i]);     \
                return fmi2Error;                                                                 \
            }                                                                                     \
            value[i] = (ctype)v;                                                                  \
        }                                                                                         \
        return fmi2OK;                                                                            \
    }
GETTER(fmi2GetReal, fmi2Real, model_get_real, double)
GETTER(fmi2GetInteger, fmi2Integer, model_get_integer, int)
GETTER(fmi2GetBoolean, fmi2Boolean, model_get_boolean, bool)
GETTER(fmi2GetString, fmi2String, model_get_string, const char *)

#define SETTER(fname, ctype, mfun, mtype)                                                               \
    fmi2Status fname(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const ctype value[]) { \
        ModelInstance *comp = (ModelInstance *)c;                                                       \
        PKM_ALLOWED(comp, #fname, P_INST | P_INIT | P_STEP);                                            \
        for (size_t i = 0; i < nvr; i++) {                                                              \
            fmi2Status s = mfun(comp, vr[i], (mtype)value[i]);                                          \
            if (s != fmi2OK) {                                                                          \
                model_error(comp, "%s: cannot set value reference %u", #fname, (unsigned)vr[i]);        \
                return s;                                                                               \
            }                                                                                           \
        }                                                                                               \
        if (comp->phase == PKM_INITIALIZATION) comp->init_dirty = true;                                 \
        return fmi2OK;                                                                                  \
    }
SETTER(fmi2SetReal, fmi2Real, model_set_real, double)
SETTER(fmi2SetInteger, fmi2Integer, model_set_integer, int)
SETTER(fmi2SetBoolean, fmi2Boolean, model_set_boolean, bool)
SETTER(fmi2SetString, fmi2String, model_set_string, const char *)

/* ---- FMU state: a byte copy of the instance (see fmu.h) --------------------------------- */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2GetFMUstate", P_INST | P_INIT | P_STEP | P_TERM);
    ModelInstance *copy = *state ? (ModelInstance *)*state : (ModelInstance *)malloc(sizeof(ModelInstance));
    if (!copy) {
        model_error(comp, "out of memory for an FMU state");
        return fmi2Error;
    }
    memcpy(copy, comp, sizeof(ModelInstance));
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    ModelInstance *comp = (ModelInstance *)c;
    PKM_ALLOWED(comp, "fmi2SetFMUstate", P_INST | P_INIT | P_STEP | P_TERM | P_ERR);
    if (!state) {
        model_error(comp, "fmi2SetFMUstate: state is NULL");
        return fmi2Error;
    }
    const ModelInstance *s = (const ModelInstance *)state;
    /* keep this instance's identity and callbacks, restore the simulation state */
    comp->phase = s->phase;
    comp->time = s->time;
    comp->start_time = s->start_time;
    comp->stop_time = s->stop_time;
    comp->fixed_step = s->fixed_step;
    comp->steps = s->steps;
    comp->data = s->data;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    if (state && *state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)c;
    (void)state;
    *size = sizeof(ModelInstance);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!comp || !state || size != sizeof(ModelInstance)) return fmi2Error;
    memcpy(bytes, state, size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!comp || size != sizeof(ModelInstance)) {
        if (comp) model_error(comp, "serialized FMU state has %zu bytes, expected %zu", size, sizeof(ModelInstance));
        return fmi2Error;
    }
    /* Heap pointers inside ModelData are only valid within the process that made them. */
    ModelInstance *copy = (ModelInstance *)malloc(sizeof(ModelInstance));
    if (!copy) return fmi2Error;
    memcpy(copy, bytes, size);
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real du[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz;
    model_error((ModelInstance *)c, "fmi2GetDirectionalDerivative is not provided");
    return fmi2Error;
}

/* ---- co-simulation -------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    model_error((ModelInstance *)c, "input derivatives are not supported");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    model_error((ModelInstance *)c, "output derivatives are not supported");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    ModelInstance *comp = (ModelInstance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    PKM_ALLOWED(comp, "fmi2DoStep", P_STEP);
    if (!(h > 0.0)) {
        model_error(comp, "fmi2DoStep: communication step %g must be > 0", h);
        return fail(comp);
    }
    if (fabs(t - comp->time) > 1e-9 * fmax(1.0, fabs(t))) {
        model_error(comp, "fmi2DoStep: current time %.17g differs from the FMU time %.17g", t, comp->time);
        return fail(comp);
    }
    long long n = 1;
    double dt = h;
    if (comp->fixed_step > 0.0) {
        /* the internal step must divide the communication step exactly */
        n = llround(h / comp->fixed_step);
        if (n < 1 || fabs(n * comp->fixed_step - h) > 1e-9 * h) {
            model_error(comp, "fmi2DoStep: communication step %.17g s is not a multiple of the internal step %.17g s",
                        h, comp->fixed_step);
            return fail(comp);
        }
        dt = comp->fixed_step;
    }
    for (long long k = 0; k < n; k++) {
        fmi2Status s = model_step(comp, dt);
        comp->steps++;
        comp->time = t + (k + 1 == n ? h : (k + 1) * dt);   /* no drift across many steps */
        if (s > fmi2Warning) return fail(comp);
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    model_error((ModelInstance *)c, "fmi2CancelStep: steps are synchronous");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c; (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!comp || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = comp->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
