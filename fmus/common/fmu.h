/* pkmbench FMI 2.0 co-simulation layer: what a model sees.
 *
 * The FMI boilerplate (fmi2Instantiate … fmi2FreeInstance, state machine, fixed internal
 * step, FMU state copies, logging) lives once in fmi2_cosim.c. A model is a folder
 * fmus/<Name>/ with
 *   config.h               MODEL_IDENTIFIER, INSTANTIATION_TOKEN, the value references and
 *                          `typedef struct {...} ModelData;` (all state, parameters, I/O)
 *   model.c (+ more .c)    the model_* functions below: its physics only
 *   modelDescription.xml   the variables; <SourceFiles> is filled in by fmus/build.py
 * (the layout of the Modelica Reference-FMUs).
 *
 * FMU state (fmi2GetFMUstate) is a byte copy of ModelData: a model keeps everything that
 * changes during a simulation inside ModelData; heap memory it owns (e.g. a parsed path) must
 * be read-only after model_initialize, so copies can share it.
 */
#ifndef PKM_FMU_H
#define PKM_FMU_H

#include <stdbool.h>
#include <stddef.h>

#include "fmi2Functions.h"
#include "config.h"

#define PKM_PI 3.14159265358979323846   /* M_PI is not strict C11 */
#define PKM_STRING_MAX 1024   /* String variables are held in fixed buffers (state copies stay flat) */

typedef enum {
    PKM_INSTANTIATED, PKM_INITIALIZATION, PKM_STEP_COMPLETE, PKM_TERMINATED, PKM_ERROR
} PkmPhase;

typedef struct ModelInstance {
    char instance_name[256];
    char resource_dir[PKM_STRING_MAX];      /* local path of resources/, "" if unknown */
    const fmi2CallbackFunctions *functions;
    bool logging_on;
    PkmPhase phase;
    double time;              /* current communication point */
    double start_time;
    double stop_time;         /* +inf if not defined */
    double fixed_step;        /* internal step set by the model in model_initialize; 0 = the
                                 communication step itself is the model's step */
    long long steps;          /* internal steps taken since initialisation */
    bool init_dirty;          /* Initialization Mode: an input or parameter changed since the
                                 outputs were last computed (fmi2_cosim.c, provisional_init) */
    bool quiet;               /* no log messages (during a provisional initialisation) */
    ModelData data;
} ModelInstance;

/* ---- implemented by each model ------------------------------------------------------- */
void model_set_start_values(ModelInstance *comp);
/* At fmi2ExitInitializationMode: validate parameters, load files, compute initial outputs,
 * set comp->fixed_step. Return fmi2Error after model_error(...) on bad input. */
fmi2Status model_initialize(ModelInstance *comp);
/* One internal step of size h (comp->time is its start). */
fmi2Status model_step(ModelInstance *comp, double h);
/* At fmi2Terminate (e.g. write a result file). */
fmi2Status model_terminate(ModelInstance *comp);
/* Free heap memory owned by comp->data (at fmi2FreeInstance and fmi2Reset). */
void model_free(ModelInstance *comp);

/* Typed access by value reference; return fmi2Error for an unknown vr (the layer logs it). */
fmi2Status model_get_real(ModelInstance *comp, fmi2ValueReference vr, double *value);
fmi2Status model_set_real(ModelInstance *comp, fmi2ValueReference vr, double value);
fmi2Status model_get_integer(ModelInstance *comp, fmi2ValueReference vr, int *value);
fmi2Status model_set_integer(ModelInstance *comp, fmi2ValueReference vr, int value);
fmi2Status model_get_boolean(ModelInstance *comp, fmi2ValueReference vr, bool *value);
fmi2Status model_set_boolean(ModelInstance *comp, fmi2ValueReference vr, bool value);
fmi2Status model_get_string(ModelInstance *comp, fmi2ValueReference vr, const char **value);
fmi2Status model_set_string(ModelInstance *comp, fmi2ValueReference vr, const char *value);

/* ---- provided by the layer ------------------------------------------------------------ */
/* Log through the importer's callback. Categories: "logEvents", "logStatusWarning",
 * "logStatusError". model_error always logs (errors are never filtered). */
void model_log(ModelInstance *comp, const char *category, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
void model_error(ModelInstance *comp, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Copy src into a fixed String buffer; fmi2Error (logged) if it does not fit. */
fmi2Status model_copy_string(ModelInstance *comp, char *dst, const char *src, const char *what);
/* Resolve a file name: absolute as is, "resource:NAME" inside the FMU's resources/. */
void model_resolve_path(ModelInstance *comp, const char *name, char *out, size_t out_size);

#endif
