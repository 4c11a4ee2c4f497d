/* EtherCAT.fmu — FMI glue for ethercat_bus.c: parameters, presets, the histogram files.
 * One internal step = one master cycle (comp->fixed_step = cycle_s), so a communication
 * step of k·T runs k cycles. pkmbench issue 4; the bus rules are documented in
 * ethercat_bus.c and README.md. */
#include <math.h>
#include <string.h>

#include "fmu.h"

#define P(comp, name) ((comp)->data.par[vr_##name - vr_cycle_s])
#define IP(comp, name) ((comp)->data.ipar[vr_##name - vr_frame_bytes])
#define S(comp, name) ((comp)->data.str[vr_##name - vr_preset])

void model_set_start_values(ModelInstance *comp) {
    ModelData *m = &comp->data;
    /* defaults: a keops-like bus (250 µs, SYNC0 shift T/2) with no jitter */
    static const double real_defaults[N_REAL_PARAMS] = {
        250e-6, 0.0, 0.0, 15e-6, 1.5, 1e-3,      /* cycle sigma tail_p tail_scale tail_shape cap */
        0.0, 125e-6, 1e-6, 0.0, 1e-6};           /* startup shift forward loss bin */
    static const int int_defaults[N_INT_PARAMS] = {100, 3, 0, 0, 4, 1};
    memcpy(m->par, real_defaults, sizeof real_defaults);
    memcpy(m->ipar, int_defaults, sizeof int_defaults);
    for (int i = 0; i < N_STRINGS; i++) m->str[i][0] = 0;
    strcpy(S(comp, distribution), "none");
    strcpy(S(comp, on_lost), "hold");
    for (int d = 0; d < ECAT_DRIVES; d++) m->q_cmd[d] = 0.0;
    memset(&m->bus, 0, sizeof m->bus);
    for (int d = 0; d < ECAT_DRIVES; d++) m->bus.sync_ok[d] = 1;
    m->initialized = false;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelData *m = &comp->data;
    EcatParams p;
    char msg[1400];
    memset(&p, 0, sizeof p);
    for (int i = 0; i < N_REAL_PARAMS; i++)
        if (!isfinite(m->par[i])) {
            model_error(comp, "a Real parameter (value reference %d) is not finite", i + vr_cycle_s);
            return fmi2Error;
        }
    p.cycle_s = P(comp, cycle_s);
    p.sigma_s = P(comp, sigma_s);
    p.tail_probability = P(comp, tail_probability);
    p.tail_scale_s = P(comp, tail_scale_s);
    p.tail_shape = P(comp, tail_shape);
    p.cap_s = P(comp, cap_s);
    p.startup_lateness_s = P(comp, startup_lateness_s);
    p.sync0_shift_s = P(comp, sync0_shift_s);
    p.forward_delay_s = P(comp, forward_delay_s);
    p.loss_probability = P(comp, loss_probability);
    p.frame_bytes = IP(comp, frame_bytes);
    p.slaves = IP(comp, slaves);
    p.extrapolate_cycles = IP(comp, extrapolate_cycles);
    p.delay_cycles = IP(comp, delay_cycles);
    p.sync_error_limit = IP(comp, sync_error_limit);
    p.seed = (uint64_t)(uint32_t)IP(comp, seed);
    const char *dist = S(comp, distribution);
    if (strcmp(dist, "none") == 0) p.dist = DIST_NONE;
    else if (strcmp(dist, "normal") == 0) p.dist = DIST_NORMAL;
    else if (strcmp(dist, "mixture") == 0) p.dist = DIST_MIXTURE;
    else if (strcmp(dist, "histogram") == 0) p.dist = DIST_HISTOGRAM;
    else {
        model_error(comp, "parameter distribution = '%s' is unknown; valid: none, normal, mixture, histogram", dist);
        return fmi2Error;
    }
    if (ecat_apply_preset(&p, S(comp, preset)) != 0) {
        model_error(comp, "parameter preset = '%s' is unknown; valid: \"\", linuxcnc_rt_preempt, tuned_rt", S(comp, preset));
        return fmi2Error;
    }
    const char *on_lost = S(comp, on_lost);
    if (strcmp(on_lost, "hold") == 0) p.on_lost = LOST_HOLD;
    else if (strcmp(on_lost, "extrapolate") == 0) p.on_lost = LOST_EXTRAPOLATE;
    else {
        model_error(comp, "parameter on_lost = '%s' is unknown; valid: hold, extrapolate", on_lost);
        return fmi2Error;
    }
    if (ecat_parse_forced(&p, S(comp, forced_late_cycles), msg, sizeof msg) != 0) {
        model_error(comp, "parameter %s", msg);
        return fmi2Error;
    }
    if (p.dist == DIST_HISTOGRAM) {
        if (!S(comp, histogram_file)[0]) {
            model_error(comp, "distribution histogram needs parameter histogram_file");
            return fmi2Error;
        }
        char path[PKM_STRING_MAX];
        model_resolve_path(comp, S(comp, histogram_file), path, sizeof path);
        if (ecat_load_histogram(&p, path, msg, sizeof msg) != 0) {
            model_error(comp, "%s", msg);
            return fmi2Error;
        }
    }
    const char *why = ecat_check_params(&p);
    if (why) {
        ecat_free_params(&p);
        model_error(comp, "%s", why);
        return fmi2Error;
    }
    if (!(P(comp, histogram_bin_s) > 0)) {
        ecat_free_params(&p);
        model_error(comp, "parameter histogram_bin_s = %g must be > 0", P(comp, histogram_bin_s));
        return fmi2Error;
    }
    if (ecat_init(&m->bus, &p, m->q_cmd, P(comp, histogram_bin_s)) != 0) {
        ecat_free_params(&p);
        model_error(comp, "parameter histogram_bin_s = %g s is too fine: 2·max(cycle_s, cap_s)/bin needs more than %d bins",
                    P(comp, histogram_bin_s), ECAT_HIST_BINS);
        return fmi2Error;
    }
    m->initialized = true;
    comp->fixed_step = p.cycle_s;   /* the layer runs H / T cycles per communication step */
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    (void)h;
    ModelData *m = &comp->data;
    for (int d = 0; d < ECAT_DRIVES; d++)
        if (!isfinite(m->q_cmd[d])) {
            model_error(comp, "t = %.9g s: input q%d_cmd is not finite", comp->time, d + 1);
            return fmi2Error;
        }
    ecat_cycle(&m->bus, m->q_cmd);
    return fmi2OK;
}

fmi2Status model_terminate(ModelInstance *comp) {
    ModelData *m = &comp->data;
    if (m->initialized && S(comp, histogram_out)[0]) {
        char msg[1400];
        if (ecat_write_histogram(&m->bus, S(comp, histogram_out), msg, sizeof msg) != 0) {
            model_error(comp, "%s", msg);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

void model_free(ModelInstance *comp) {
    /* the histogram tables are owned by the instance (FMU state copies only borrow them) */
    ecat_free(&comp->data.bus);
    comp->data.initialized = false;
}

fmi2Status model_get_real(ModelInstance *comp, fmi2ValueReference vr, double *v) {
    ModelData *m = &comp->data;
    if (vr >= vr_cycle_s && vr <= vr_histogram_bin_s) *v = m->par[vr - vr_cycle_s];
    else if (vr >= vr_q1_cmd && vr <= vr_q3_cmd) *v = m->q_cmd[vr - vr_q1_cmd];
    else if (vr >= vr_q1_target && vr <= vr_q3_target)
        *v = m->initialized ? m->bus.target[vr - vr_q1_target] : m->q_cmd[vr - vr_q1_target];
    else if (vr == vr_lateness) *v = m->bus.lateness;
    else if (vr == vr_lateness_max_abs) *v = m->bus.lateness_max_abs;
    else return fmi2Error;
    return fmi2OK;
}

static bool settable(const ModelInstance *comp) {
    return comp->phase == PKM_INSTANTIATED || comp->phase == PKM_INITIALIZATION;
}

fmi2Status model_set_real(ModelInstance *comp, fmi2ValueReference vr, double v) {
    ModelData *m = &comp->data;
    if (vr >= vr_cycle_s && vr <= vr_histogram_bin_s) {
        if (!settable(comp)) return fmi2Error;
        m->par[vr - vr_cycle_s] = v;
    } else if (vr >= vr_q1_cmd && vr <= vr_q3_cmd) {
        m->q_cmd[vr - vr_q1_cmd] = v;
    } else {
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_get_integer(ModelInstance *comp, fmi2ValueReference vr, int *v) {
    ModelData *m = &comp->data;
    if (vr >= vr_frame_bytes && vr <= vr_seed) *v = m->ipar[vr - vr_frame_bytes];
    else if (vr == vr_lost_frames) *v = (int)m->bus.lost_frames;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_integer(ModelInstance *comp, fmi2ValueReference vr, int v) {
    if (vr < vr_frame_bytes || vr > vr_seed || !settable(comp)) return fmi2Error;
    comp->data.ipar[vr - vr_frame_bytes] = v;
    return fmi2OK;
}

fmi2Status model_get_boolean(ModelInstance *comp, fmi2ValueReference vr, bool *v) {
    ModelData *m = &comp->data;
    if (vr == vr_lost) *v = m->bus.lost_now;
    else if (vr >= vr_sync_ok1 && vr <= vr_sync_ok3) *v = m->bus.sync_ok[vr - vr_sync_ok1];
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_boolean(ModelInstance *comp, fmi2ValueReference vr, bool v) {
    (void)comp; (void)vr; (void)v;
    return fmi2Error;   /* no Boolean inputs or parameters */
}

fmi2Status model_get_string(ModelInstance *comp, fmi2ValueReference vr, const char **v) {
    if (vr < vr_preset || vr > vr_histogram_out) return fmi2Error;
    *v = comp->data.str[vr - vr_preset];
    return fmi2OK;
}

fmi2Status model_set_string(ModelInstance *comp, fmi2ValueReference vr, const char *v) {
    static const char *names[N_STRINGS] = {"preset", "distribution", "histogram_file", "on_lost",
                                           "forced_late_cycles", "histogram_out"};
    if (vr < vr_preset || vr > vr_histogram_out || !settable(comp)) return fmi2Error;
    return model_copy_string(comp, comp->data.str[vr - vr_preset], v ? v : "", names[vr - vr_preset]);
}
