/* Drive physics and control (see drive_model.h). pkmbench issue 4.
 *
 * Integration: the electrical and mechanical parts are linear,
 *   L di/dt = u - R i - ke v,   m dv/dt = kf i - b v + f,   dx/dt = v,
 * with the voltage u (controller output) and the friction force f held constant
 * over one inner period Ts (zero-order hold, as the PWM holds its duty cycle).
 * We discretise them exactly: [Phi Gam] = expm([A B; 0 0] Ts), computed once at
 * initialisation by scaling and squaring. That is exact for any Ts (no step-size
 * stability limit even with L/R = 10 us) and costs 15 multiply-adds per substep.
 * Only the Coulomb friction is nonlinear: its sign is taken at the start of each
 * substep, and a velocity that would cross zero under friction alone is clamped
 * to zero (stiction).
 */
#include <math.h>
#include <string.h>
#include "drive_model.h"

#define N_AUG 5
#define DRIVE_PI 3.14159265358979323846  /* M_PI is not strict C11 */

static void mat_mul(int n, const double *a, const double *b, double *c)
{
    for (int r = 0; r < n; r++)
        for (int k = 0; k < n; k++) {
            double acc = 0.0;
            for (int j = 0; j < n; j++) acc += a[r * n + j] * b[j * n + k];
            c[r * n + k] = acc;
        }
}

/* expm(M) for a small dense matrix: scale to norm < 0.5, Taylor to order 18, square back. */
static void expm_small(int n, const double *m, double *out)
{
    double norm = 0.0;
    for (int r = 0; r < n; r++) {
        double row = 0.0;
        for (int k = 0; k < n; k++) row += fabs(m[r * n + k]);
        if (row > norm) norm = row;
    }
    int squarings = 0;
    double scale = 1.0;
    while (norm * scale > 0.5) { scale *= 0.5; squarings++; }
    double a[N_AUG * N_AUG], term[N_AUG * N_AUG], tmp[N_AUG * N_AUG];
    for (int q = 0; q < n * n; q++) a[q] = m[q] * scale;
    for (int q = 0; q < n * n; q++) { out[q] = 0.0; term[q] = 0.0; }
    for (int r = 0; r < n; r++) { out[r * n + r] = 1.0; term[r * n + r] = 1.0; }
    for (int order = 1; order <= 18; order++) {
        mat_mul(n, term, a, tmp);
        for (int q = 0; q < n * n; q++) { term[q] = tmp[q] / order; out[q] += term[q]; }
    }
    for (int s = 0; s < squarings; s++) {
        mat_mul(n, out, out, tmp);
        memcpy(out, tmp, sizeof(double) * n * n);
    }
}

const char *drive_check_params(const DriveParams *p)
{
    if (p->ideal) return 0;  /* an ideal drive needs no physics */
    if (p->motor != MOTOR_LINEAR && p->motor != MOTOR_STEPPER_BELT) return "parameter motor is unknown (linear | stepper_belt)";
    if (!(p->mass_kg > 0)) return "parameter mass_kg must be > 0";
    if (p->motor == MOTOR_LINEAR && !(p->force_constant > 0)) return "parameter force_constant_N_per_A must be > 0";
    if (p->motor == MOTOR_STEPPER_BELT) {
        if (!(p->torque_constant > 0)) return "parameter torque_constant_Nm_per_A must be > 0";
        if (!(p->rotor_inertia >= 0)) return "parameter rotor_inertia_kgm2 must be >= 0";
        if (!(p->pulley_m_per_rev > 0)) return "parameter pulley_mm_per_rev must be > 0";
    }
    if (!(p->resistance_ohm > 0)) return "parameter resistance_ohm must be > 0";
    if (!(p->inductance_h > 0)) return "parameter inductance_H must be > 0";
    if (!(p->viscous_n_s_per_m >= 0)) return "parameter viscous_N_s_per_m must be >= 0";
    if (!(p->coulomb_n >= 0)) return "parameter coulomb_N must be >= 0";
    if (!(p->current_max_a > 0)) return "parameter current_max_A must be > 0";
    if (!(p->voltage_max_v > 0)) return "parameter voltage_max_V must be > 0";
    if (!(p->encoder_res_m >= 0)) return "parameter encoder_resolution_mm (or encoder_increments_per_rev) must be >= 0";
    if (!(p->kp_pos > 0)) return "parameter kp_pos (position gain) must be > 0";
    if (!(p->kp_vel > 0)) return "parameter kp_vel (velocity gain) must be > 0";
    if (!(p->ki_vel >= 0)) return "parameter ki_vel (velocity integral gain) must be >= 0";
    if (!(p->kp_cur > 0)) return "parameter kp_cur (current gain) must be > 0";
    if (!(p->ki_cur >= 0)) return "parameter ki_cur (current integral gain) must be >= 0";
    if (!(p->vff >= 0 && p->vff <= 2)) return "parameter vff (velocity feed-forward) must be within 0..2";
    if (!(p->aff >= 0 && p->aff <= 2)) return "parameter aff (acceleration feed-forward) must be within 0..2";
    if (!(p->vel_filter_tau_s >= 0)) return "parameter vel_filter_tau_s must be >= 0";
    if (!(p->inner_period_s > 0)) return "parameter inner_period_s (inner loop period) must be > 0";
    if (p->interpolation != INTERP_LINEAR && p->interpolation != INTERP_CUBIC)
        return "parameter interpolation is unknown (linear | cubic)";
    if (!(p->quickstop_decel > 0)) return "parameter quickstop_decel_mm_s2 must be > 0";
    return 0;
}

void drive_init(DriveState *s, const DriveParams *p, double x0)
{
    memset(s, 0, sizeof *s);
    s->p = *p;
    if (p->motor == MOTOR_STEPPER_BELT) {
        /* reflect the rotor to the belt: r = feed / 2 pi; F = kt i / r; J/r^2 adds to mass */
        double r = p->pulley_m_per_rev / (2.0 * DRIVE_PI);
        s->kf = p->torque_constant / r;
        s->m_eff = p->mass_kg + p->rotor_inertia / (r * r);
    } else {
        s->kf = p->force_constant;
        s->m_eff = p->mass_kg;
    }
    s->ke = s->kf;  /* SI: back-EMF constant (V per m/s) = force constant (N/A) */
    if (!p->ideal) {
        double M[N_AUG * N_AUG] = {0}, E[N_AUG * N_AUG];
        double L = p->inductance_h, R = p->resistance_ohm, m = s->m_eff, h = p->inner_period_s;
        /* states i, v, x; inputs u, f */
        M[0 * 5 + 0] = -R / L * h;  M[0 * 5 + 1] = -s->ke / L * h;  M[0 * 5 + 3] = 1.0 / L * h;
        M[1 * 5 + 0] = s->kf / m * h; M[1 * 5 + 1] = -p->viscous_n_s_per_m / m * h;
        M[1 * 5 + 4] = 1.0 / m * h;
        M[2 * 5 + 1] = h;
        expm_small(N_AUG, M, E);
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) s->Phi[r][c] = E[r * 5 + c];
            for (int c = 0; c < 2; c++) s->Gam[r][c] = E[r * 5 + 3 + c];
        }
    }
    s->x = x0;
    s->demand = x0;
    for (int k = 0; k < 4; k++) s->hist[k] = x0;
    s->x_meas = s->x_meas_prev = x0;
    if (p->encoder_res_m > 0) s->x_meas = s->x_meas_prev = floor(x0 / p->encoder_res_m + 0.5) * p->encoder_res_m;
    s->state = CIA_OPERATION_ENABLED;  /* the harness starts with the drive enabled */
}

double drive_force(const DriveState *s) { return s->kf * s->i; }

/* Demand position, velocity and acceleration at fraction lam of the cycle. */
static void interpolate(const DriveState *s, double lam, double T, double *pos, double *vel, double *acc)
{
    const double *h = s->hist;
    if (s->p.interpolation == INTERP_CUBIC) {
        /* Catmull-Rom between hist[2] and hist[1], tangents from central differences:
         * C1-continuous demand, one cycle later than linear. */
        double p1 = h[2], p2 = h[1], m1 = 0.5 * (h[1] - h[3]), m2 = 0.5 * (h[0] - h[2]);
        double l2 = lam * lam, l3 = l2 * lam;
        *pos = (2 * l3 - 3 * l2 + 1) * p1 + (l3 - 2 * l2 + lam) * m1 + (-2 * l3 + 3 * l2) * p2 + (l3 - l2) * m2;
        *vel = ((6 * l2 - 6 * lam) * p1 + (3 * l2 - 4 * lam + 1) * m1 + (-6 * l2 + 6 * lam) * p2 + (3 * l2 - 2 * lam) * m2) / T;
        *acc = ((12 * lam - 6) * p1 + (6 * lam - 4) * m1 + (-12 * lam + 6) * p2 + (6 * lam - 2) * m2) / (T * T);
    } else {
        *pos = h[1] + lam * (h[0] - h[1]);
        *vel = (h[0] - h[1]) / T;
        *acc = (*vel - s->v_ff_prev) / T;
    }
}

static void enter_fault_reaction(DriveState *s, int cause)
{
    if (s->state == CIA_FAULT_REACTION_ACTIVE || s->state == CIA_FAULT) { s->fault_cause |= cause; return; }
    s->fault_cause |= cause;
    s->state = CIA_FAULT_REACTION_ACTIVE;
    /* quick stop from where the axis is and how fast it moves (not from a demand that may
     * have run away, e.g. after a following error) */
    s->demand = s->x_meas;
    s->qs_v = s->v_filt;
}

const char *drive_cycle(DriveState *s, double target, int sync_ok, double T)
{
    const DriveParams *p = &s->p;
    if (!(T > 0)) return "communication step size must be > 0";
    if (!isfinite(target)) return "target is not finite";
    if (p->ideal) {
        s->v = (target - s->x) / T;
        s->x = s->x_meas = s->demand = target;
        s->following_error = 0.0;
        return 0;
    }
    int n = (int)floor(T / p->inner_period_s + 0.5);
    if (n < 1 || fabs(n * p->inner_period_s - T) > 1e-9 * T)
        return "the communication step must be a whole multiple of inner_period_s";
    s->cycle_s = T;
    s->substeps = n;
    if (!sync_ok) enter_fault_reaction(s, DRIVE_FAULT_SYNC);
    int running = (s->state == CIA_OPERATION_ENABLED);
    if (running) {
        s->v_ff_prev = s->v_ff;
        for (int k = 3; k > 0; k--) s->hist[k] = s->hist[k - 1];
        s->hist[0] = target;
    }
    const double Ts = p->inner_period_s;
    for (int j = 0; j < n; j++) {
        double lam = (double)(j + 1) / n;
        double pos_d, vel_d, acc_d;
        if (running) {
            interpolate(s, lam, T, &pos_d, &vel_d, &acc_d);
        } else {
            /* fault reaction: quick stop on the fast ramp, then hold */
            double dv = p->quickstop_decel * Ts;
            double v0 = s->qs_v;
            double v1 = (fabs(v0) <= dv) ? 0.0 : v0 - copysign(dv, v0);
            pos_d = s->demand + 0.5 * (v0 + v1) * Ts;
            vel_d = v1;
            acc_d = (v1 - v0) / Ts;
            s->qs_v = v1;
            if (v1 == 0.0 && s->state == CIA_FAULT_REACTION_ACTIVE) s->state = CIA_FAULT;
        }
        s->demand = pos_d;
        s->v_ff = vel_d;
        s->a_ff = acc_d;
        /* encoder and velocity estimate */
        double xm = s->x;
        if (p->encoder_res_m > 0) xm = floor(s->x / p->encoder_res_m + 0.5) * p->encoder_res_m;
        double v_raw = (xm - s->x_meas_prev) / Ts;
        s->x_meas_prev = xm;
        s->x_meas = xm;
        if (p->vel_filter_tau_s > 0) {
            double alpha = Ts / (p->vel_filter_tau_s + Ts);
            s->v_filt += alpha * (v_raw - s->v_filt);
        } else {
            s->v_filt = v_raw;
        }
        /* position P with feed-forward */
        double e_pos = pos_d - xm;
        double v_cmd = p->vff * vel_d + p->kp_pos * e_pos;
        /* velocity PI, conditional integration (anti-windup) */
        double e_vel = v_cmd - s->v_filt;
        double i_ff = p->aff * s->m_eff * acc_d / s->kf;
        double i_unsat = p->kp_vel * e_vel + s->int_vel + i_ff;
        double i_cmd = i_unsat;
        if (i_cmd > p->current_max_a) i_cmd = p->current_max_a;
        if (i_cmd < -p->current_max_a) i_cmd = -p->current_max_a;
        if (i_cmd == i_unsat || (i_unsat > i_cmd) != (e_vel > 0))
            s->int_vel += p->ki_vel * e_vel * Ts;
        s->i_cmd = i_cmd;
        /* current PI (q axis), conditional integration */
        double e_cur = i_cmd - s->i;
        double u_unsat = p->kp_cur * e_cur + s->int_cur;
        double u = u_unsat;
        if (u > p->voltage_max_v) u = p->voltage_max_v;
        if (u < -p->voltage_max_v) u = -p->voltage_max_v;
        if (u == u_unsat || (u_unsat > u) != (e_cur > 0))
            s->int_cur += p->ki_cur * e_cur * Ts;
        /* plant over Ts, friction held */
        double f;
        double v0 = s->v;
        if (v0 != 0.0) {
            f = -copysign(p->coulomb_n, v0);
        } else {
            double fd = s->kf * s->i;
            f = (fabs(fd) <= p->coulomb_n) ? -fd : -copysign(p->coulomb_n, fd);
        }
        double i0 = s->i, x0 = s->x;
        s->i = s->Phi[0][0] * i0 + s->Phi[0][1] * v0 + s->Phi[0][2] * x0 + s->Gam[0][0] * u + s->Gam[0][1] * f;
        s->v = s->Phi[1][0] * i0 + s->Phi[1][1] * v0 + s->Phi[1][2] * x0 + s->Gam[1][0] * u + s->Gam[1][1] * f;
        s->x = s->Phi[2][0] * i0 + s->Phi[2][1] * v0 + s->Phi[2][2] * x0 + s->Gam[2][0] * u + s->Gam[2][1] * f;
        if (p->coulomb_n > 0 && ((v0 > 0 && s->v < 0) || (v0 < 0 && s->v > 0) ||
                                 (v0 == 0 && fabs(s->kf * i0) <= p->coulomb_n))) {
            /* friction alone cannot reverse the motion: stick */
            if (v0 == 0) s->x = x0;
            s->v = 0.0;
        }
    }
    /* CiA 402 following error actual value (60F4h) = demand - actual, at the cycle end */
    s->following_error = s->demand - s->x_meas;
    if (p->following_error_max_m > 0 && fabs(s->following_error) > p->following_error_max_m &&
        s->state == CIA_OPERATION_ENABLED)
        enter_fault_reaction(s, DRIVE_FAULT_FOLLOWING);
    return 0;
}
