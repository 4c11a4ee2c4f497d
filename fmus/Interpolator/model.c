/* Interpolator.fmu — the real-time part of the planner: each period T it advances the arc
 * length by the feed profile (row k at t = k·T) and evaluates the toolpath there (NURBS by
 * rational de Boor + arc-length Newton, lines/arcs exactly; interp_path.c). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu.h"
#include "interp_path.h"

void model_set_start_values(ModelInstance *comp) {
    ModelData *m = &comp->data;
    m->T = 250e-6;
    strcpy(m->path_file, "resource:default_path.json");
    strcpy(m->profile_file, "resource:default_profile.csv");
}

static void evaluate(ModelInstance *comp) {
    ModelData *m = &comp->data;
    const Track *tr = m->track;
    long k = m->row < tr->nrows ? m->row : tr->nrows - 1;
    double p[3], res;
    double prev_s = m->s, prev_res = m->residual;
    track_point(tr, tr->ps[k], p, &m->u, &m->hint, &res);
    m->x = p[0], m->y = p[1], m->z = p[2];
    m->s = tr->ps[k];
    m->residual = res;
    m->feed = m->row < tr->nrows ? tr->psd[k] : 0.0;
    double ds = m->s - prev_s;   /* relative error of the arc length travelled this step */
    m->feed_error = ds > 0 ? (fabs(res) + fabs(prev_res)) / ds : 0.0;
    m->done = m->row >= tr->nrows - 1;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelData *m = &comp->data;
    char path[1024], prof[1024], err[1024];
    if (!(m->T > 0) || !isfinite(m->T)) {
        model_error(comp, "parameter T = %g s must be > 0", m->T);
        return fmi2Error;
    }
    model_resolve_path(comp, m->path_file, path, sizeof path);
    model_resolve_path(comp, m->profile_file, prof, sizeof prof);
    track_free(m->track);
    m->track = track_load(path, prof, m->T, err, sizeof err);
    if (!m->track) {
        model_error(comp, "%s", err);
        return fmi2Error;
    }
    comp->fixed_step = m->T;
    m->row = 0, m->hint = 0, m->s = 0, m->residual = 0;
    evaluate(comp);
    model_log(comp, "logEvents", "path %s: %.6f mm; profile %s: %ld rows at T = %g s", path, m->track->length, prof,
              m->track->nrows, m->T);
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    (void)h;
    comp->data.row++;
    evaluate(comp);
    return fmi2OK;
}

fmi2Status model_terminate(ModelInstance *comp) {
    (void)comp;
    return fmi2OK;
}

void model_free(ModelInstance *comp) {
    track_free(comp->data.track);
    comp->data.track = NULL;
}

fmi2Status model_get_real(ModelInstance *comp, fmi2ValueReference vr, double *v) {
    ModelData *m = &comp->data;
    switch (vr) {
        case vr_T: *v = m->T; break;
        case vr_x: *v = m->x; break;
        case vr_y: *v = m->y; break;
        case vr_z: *v = m->z; break;
        case vr_s: *v = m->s; break;
        case vr_u: *v = m->u; break;
        case vr_feed: *v = m->feed; break;
        case vr_feed_error: *v = m->feed_error; break;
        default: return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_set_real(ModelInstance *comp, fmi2ValueReference vr, double v) {
    if (vr != vr_T || comp->phase == PKM_STEP_COMPLETE) return fmi2Error;
    comp->data.T = v;
    return fmi2OK;
}

fmi2Status model_get_integer(ModelInstance *comp, fmi2ValueReference vr, int *v) {
    (void)comp, (void)vr, (void)v;
    return fmi2Error;
}

fmi2Status model_set_integer(ModelInstance *comp, fmi2ValueReference vr, int v) {
    (void)comp, (void)vr, (void)v;
    return fmi2Error;
}

fmi2Status model_get_boolean(ModelInstance *comp, fmi2ValueReference vr, bool *v) {
    if (vr != vr_done) return fmi2Error;
    *v = comp->data.done;
    return fmi2OK;
}

fmi2Status model_set_boolean(ModelInstance *comp, fmi2ValueReference vr, bool v) {
    (void)comp, (void)vr, (void)v;
    return fmi2Error;
}

fmi2Status model_get_string(ModelInstance *comp, fmi2ValueReference vr, const char **v) {
    if (vr == vr_path_file) *v = comp->data.path_file;
    else if (vr == vr_profile_file) *v = comp->data.profile_file;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_string(ModelInstance *comp, fmi2ValueReference vr, const char *v) {
    if (comp->phase == PKM_STEP_COMPLETE) return fmi2Error;
    if (vr == vr_path_file) return model_copy_string(comp, comp->data.path_file, v, "path_file");
    if (vr == vr_profile_file) return model_copy_string(comp, comp->data.profile_file, v, "profile_file");
    return fmi2Error;
}
