/* Drive.fmu — FMI glue for drive_model.c: parameters in the units of the machine files
 * (mm, mm/s², SI for the rest), positions converted mm <-> m, CiA 402 outputs.
 * pkmbench issue 4; the physics and its integration are documented in drive_model.c. */
#include <math.h>
#include <string.h>

#include "fmu.h"

#define P(comp, name) ((comp)->data.par[vr_##name - vr_inner_period_s])

void model_set_start_values(ModelInstance *comp) {
    ModelData *m = &comp->data;
    /* defaults: the keops axis of benchmarks/machines/keops.toml [drive] (Tecnotion UXA3S on
     * a Beckhoff AX8206 channel); stepper data: the kossel values */
    static const double keops[N_REAL_PARAMS] = {
        62.5e-6, 3.0, 27.0, 0.167,                 /* inner_period_s mass_kg force_constant torque_constant */
        8.2e-6, 31.416, 0.001, 7.8,                /* rotor_inertia pulley encoder_resolution resistance */
        2.7e-3, 10.0, 5.0, 480.0 / 27.0, 565.0,    /* inductance viscous coulomb current_max voltage_max */
        100.0, 70.0, 11000.0, 17.0, 49000.0,       /* kp_pos kp_vel ki_vel kp_cur ki_cur */
        1.0, 0.0, 2e-4, 1.0, 50000.0};             /* vff aff vel_filter_tau following_error_max quickstop */
    memcpy(m->par, keops, sizeof keops);
    m->encoder_increments_per_rev = 16000;
    m->ideal = false;
    strcpy(m->motor, "linear");
    strcpy(m->interpolation, "linear");
    m->target = 0.0;
    m->sync_ok = true;
    memset(&m->drive, 0, sizeof m->drive);
    m->drive.state = CIA_OPERATION_ENABLED;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelData *m = &comp->data;
    DriveParams p;
    memset(&p, 0, sizeof p);
    p.ideal = m->ideal;
    if (strcmp(m->motor, "linear") == 0) p.motor = MOTOR_LINEAR;
    else if (strcmp(m->motor, "stepper_belt") == 0) p.motor = MOTOR_STEPPER_BELT;
    else if (!m->ideal) {
        model_error(comp, "parameter motor = '%s' is unknown; valid: linear, stepper_belt", m->motor);
        return fmi2Error;
    }
    if (strcmp(m->interpolation, "linear") == 0) p.interpolation = INTERP_LINEAR;
    else if (strcmp(m->interpolation, "cubic") == 0) p.interpolation = INTERP_CUBIC;
    else {
        model_error(comp, "parameter interpolation = '%s' is unknown; valid: linear, cubic", m->interpolation);
        return fmi2Error;
    }
    p.mass_kg = P(comp, mass_kg);
    p.force_constant = P(comp, force_constant_N_per_A);
    p.torque_constant = P(comp, torque_constant_Nm_per_A);
    p.rotor_inertia = P(comp, rotor_inertia_kgm2);
    p.pulley_m_per_rev = P(comp, pulley_mm_per_rev) * 1e-3;
    p.resistance_ohm = P(comp, resistance_ohm);
    p.inductance_h = P(comp, inductance_H);
    p.viscous_n_s_per_m = P(comp, viscous_N_s_per_m);
    p.coulomb_n = P(comp, coulomb_N);
    p.current_max_a = P(comp, current_max_A);
    p.voltage_max_v = P(comp, voltage_max_V);
    if (p.motor == MOTOR_STEPPER_BELT) {
        if (m->encoder_increments_per_rev < 0) {
            model_error(comp, "parameter encoder_increments_per_rev = %d must be >= 0 (0 = no quantisation)",
                        m->encoder_increments_per_rev);
            return fmi2Error;
        }
        p.encoder_res_m = m->encoder_increments_per_rev > 0 ? p.pulley_m_per_rev / m->encoder_increments_per_rev : 0.0;
    } else {
        p.encoder_res_m = P(comp, encoder_resolution_mm) * 1e-3;
    }
    p.kp_pos = P(comp, kp_pos);
    p.kp_vel = P(comp, kp_vel);
    p.ki_vel = P(comp, ki_vel);
    p.kp_cur = P(comp, kp_cur);
    p.ki_cur = P(comp, ki_cur);
    p.vff = P(comp, vff);
    p.aff = P(comp, aff);
    p.vel_filter_tau_s = P(comp, vel_filter_tau_s);
    p.inner_period_s = P(comp, inner_period_s);
    p.following_error_max_m = P(comp, following_error_max_mm) * 1e-3;
    p.quickstop_decel = P(comp, quickstop_decel_mm_s2) * 1e-3;
    for (int i = 0; i < N_REAL_PARAMS; i++)
        if (!isfinite(m->par[i])) {
            model_error(comp, "a Real parameter (value reference %d) is not finite", i + vr_inner_period_s);
            return fmi2Error;
        }
    if (!isfinite(m->target)) {
        model_error(comp, "input target = %g at initialisation is not finite", m->target);
        return fmi2Error;
    }
    const char *why = drive_check_params(&p);
    if (why) {
        model_error(comp, "%s", why);
        return fmi2Error;
    }
    drive_init(&m->drive, &p, m->target * 1e-3);  /* the start position is the initial target */
    m->ideal_pos = m->target;
    m->ideal_vel = 0.0;
    comp->fixed_step = 0.0;                       /* one bus cycle per communication step */
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelData *m = &comp->data;
    if (m->ideal) {  /* kept in mm so that position == target bit for bit */
        if (!isfinite(m->target)) {
            model_error(comp, "t = %.9g s: input target is not finite", comp->time);
            return fmi2Error;
        }
        m->ideal_vel = (m->target - m->ideal_pos) / h;
        m->ideal_pos = m->target;
        return fmi2OK;
    }
    const char *why = drive_cycle(&m->drive, m->target * 1e-3, m->sync_ok, h);
    if (why) {
        model_error(comp, "t = %.9g s, step %.9g s: %s (%.9g s)", comp->time, h, why, m->drive.p.inner_period_s);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_terminate(ModelInstance *comp) {
    (void)comp;
    return fmi2OK;
}

void model_free(ModelInstance *comp) { (void)comp; }

fmi2Status model_get_real(ModelInstance *comp, fmi2ValueReference vr, double *v) {
    ModelData *m = &comp->data;
    const DriveState *s = &m->drive;
    if (vr >= vr_inner_period_s && vr <= vr_quickstop_decel_mm_s2) *v = m->par[vr - vr_inner_period_s];
    else if (vr == vr_target) *v = m->target;
    else if (vr == vr_position) *v = m->ideal ? m->ideal_pos : s->x_meas * 1e3;
    else if (vr == vr_velocity) *v = m->ideal ? m->ideal_vel : s->v_filt * 1e3;
    else if (vr == vr_current) *v = s->i;
    else if (vr == vr_force) *v = drive_force(s);
    else if (vr == vr_following_error) *v = s->following_error * 1e3;
    else if (vr == vr_load_position) *v = m->ideal ? m->ideal_pos : s->x * 1e3;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_real(ModelInstance *comp, fmi2ValueReference vr, double v) {
    ModelData *m = &comp->data;
    if (vr >= vr_inner_period_s && vr <= vr_quickstop_decel_mm_s2) {
        if (comp->phase != PKM_INSTANTIATED && comp->phase != PKM_INITIALIZATION) return fmi2Error;
        m->par[vr - vr_inner_period_s] = v;
    } else if (vr == vr_target) {
        m->target = v;
    } else {
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_get_integer(ModelInstance *comp, fmi2ValueReference vr, int *v) {
    if (vr == vr_encoder_increments_per_rev) *v = comp->data.encoder_increments_per_rev;
    else if (vr == vr_state) *v = comp->data.drive.state;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_integer(ModelInstance *comp, fmi2ValueReference vr, int v) {
    if (vr != vr_encoder_increments_per_rev) return fmi2Error;
    if (comp->phase != PKM_INSTANTIATED && comp->phase != PKM_INITIALIZATION) return fmi2Error;
    comp->data.encoder_increments_per_rev = v;
    return fmi2OK;
}

fmi2Status model_get_boolean(ModelInstance *comp, fmi2ValueReference vr, bool *v) {
    const ModelData *m = &comp->data;
    if (vr == vr_ideal) *v = m->ideal;
    else if (vr == vr_sync_ok) *v = m->sync_ok;
    else if (vr == vr_fault) *v = m->drive.state == CIA_FAULT_REACTION_ACTIVE || m->drive.state == CIA_FAULT;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_boolean(ModelInstance *comp, fmi2ValueReference vr, bool v) {
    if (vr == vr_sync_ok) {
        comp->data.sync_ok = v;
    } else if (vr == vr_ideal) {
        if (comp->phase != PKM_INSTANTIATED && comp->phase != PKM_INITIALIZATION) return fmi2Error;
        comp->data.ideal = v;
    } else {
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_get_string(ModelInstance *comp, fmi2ValueReference vr, const char **v) {
    if (vr == vr_motor) *v = comp->data.motor;
    else if (vr == vr_interpolation) *v = comp->data.interpolation;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_string(ModelInstance *comp, fmi2ValueReference vr, const char *v) {
    if (comp->phase != PKM_INSTANTIATED && comp->phase != PKM_INITIALIZATION) return fmi2Error;
    if (vr == vr_motor) return model_copy_string(comp, comp->data.motor, v, "motor");
    if (vr == vr_interpolation) return model_copy_string(comp, comp->data.interpolation, v, "interpolation");
    return fmi2Error;
}
