/* Kinematics.fmu — the equations of kins/ (keops.py, lineardelta.py, pn101.py) in C.
 * Sources: KEOPS: Erwinski et al. 2022 with the consistent forms of DESIGN.md; linear delta:
 * LinuxCNC lineardeltakins; pn101: Dimić et al. 2018 eqs (5)-(11). Must agree with kins to
 * 1e-9 mm (tests/test_fmu_kinematics.py). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu.h"

#define G(comp, name) ((comp)->data.geometry[vr_##name - vr_alpha_deg])
#define COND_SINGULAR 1e300   /* cond(J) reported for a singular Jacobian (no inf in results) */

void model_set_start_values(ModelInstance *comp) {
    ModelData *m = &comp->data;
    /* defaults: the keops machine of DESIGN.md (benchmarks/machines/keops.toml) */
    static const double keops[N_GEOMETRY] = {
        45.0, 350.0, 500.0, 0.0, 60.0, 100.0,                       /* alpha_deg L x_ref y_ref eo R */
        850.0, 600.0, 550.0, 150.0, -350.0, 150.0, 100.0, -50.0, 0.0, 250.0, /* pn101 (assumed) */
        0.0, 0.0, 0.0, 0.0, 580.0};                                  /* x_TP y_TP z_TP q_min q_max */
    memcpy(m->geometry, keops, sizeof keops);
    strcpy(m->machine, "keops");
    m->stop_on_workspace_error = true;
    m->p_cmd[0] = 0.0, m->p_cmd[1] = 0.0, m->p_cmd[2] = -400.0;
    m->workspace_ok = true;
    m->dirty = true;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double a[3], const double b[3], double out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Lower intersection (smaller z) of three spheres of radius L about C[i]; as kins.machine. */
static bool three_sphere_lower(const double C[3][3], double L, double p[3]) {
    double ex[3], d13[3], ey[3], ez[3];
    for (int k = 0; k < 3; k++) ex[k] = C[1][k] - C[0][k], d13[k] = C[2][k] - C[0][k];
    double d = sqrt(dot3(ex, ex));
    if (!(d > 0)) return false;
    for (int k = 0; k < 3; k++) ex[k] /= d;
    double i = dot3(ex, d13);
    for (int k = 0; k < 3; k++) ey[k] = d13[k] - i * ex[k];
    double jn = sqrt(dot3(ey, ey));
    if (!(jn > 0)) return false;
    for (int k = 0; k < 3; k++) ey[k] /= jn;
    cross3(ex, ey, ez);
    double x = d / 2.0;
    double y = (i * i + jn * jn - 2.0 * i * x) / (2.0 * jn);
    double rad = L * L - x * x - y * y;
    if (rad < 0) return false;
    double z = sqrt(rad) * (ez[2] > 0 ? -1.0 : 1.0);
    for (int k = 0; k < 3; k++) p[k] = C[0][k] + x * ex[k] + y * ey[k] + z * ez[k];
    return true;
}

/* IK and Jacobian rows at p. Returns the 1-based leg whose rod cannot reach p, else 0. */
static int inverse(const ModelData *m, const double p[3], double q[3], double J[3][3]) {
    const double *g = m->geometry;
#define GG(name) g[vr_##name - vr_alpha_deg]
    if (m->family == FAMILY_KEOPS) {
        for (int i = 0; i < 3; i++) {
            double w[3] = {p[0] + m->offset[i][0], p[1] + m->offset[i][1], p[2] + m->offset[i][2]};
            double E = dot3(m->axis[i], w), F = dot3(w, w) - GG(L) * GG(L), D = E * E - F;
            if (D < 0) return i + 1;
            double r = sqrt(D);
            q[i] = E - r;
            for (int k = 0; k < 3; k++) J[i][k] = m->axis[i][k] - (E * m->axis[i][k] - w[k]) / r;
        }
    } else if (m->family == FAMILY_LINEARDELTA) {
        for (int i = 0; i < 3; i++) {
            double dx = m->tower[i][0] - p[0], dy = m->tower[i][1] - p[1];
            double rad = GG(L) * GG(L) - dx * dx - dy * dy;
            if (rad < 0) return i + 1;
            double r = sqrt(rad);
            q[i] = p[2] + r;
            J[i][0] = dx / r, J[i][1] = dy / r, J[i][2] = 1.0;
        }
    } else {   /* pn101 */
        double X = p[0] - GG(x_TP), Y = p[1] - GG(y_TP), Z = p[2] - GG(z_TP);
        double yd = Y + GG(d), zz = Z + GG(z_p2), z3 = Z + GG(z_p3) - GG(z_o3);
        double r12 = yd * yd + zz * zz;
        double rad[3] = {GG(c1) * GG(c1) - r12, GG(c2) * GG(c2) - r12, GG(c3) * GG(c3) - z3 * z3};
        for (int i = 0; i < 3; i++)
            if (rad[i] < 0 || (i < 2 && yd > 0)) return i + 1;   /* yd > 0: the other branch (kins) */
        double s1 = sqrt(rad[0]), s2 = sqrt(rad[1]), s3 = sqrt(rad[2]);
        q[0] = X + GG(c4) - s1, q[1] = X - s2, q[2] = X + GG(x_p3) - s3;
        J[0][0] = 1, J[0][1] = yd / s1, J[0][2] = zz / s1;
        J[1][0] = 1, J[1][1] = yd / s2, J[1][2] = zz / s2;
        J[2][0] = 1, J[2][1] = 0, J[2][2] = z3 / s3;
    }
    return 0;
}

static bool forward(const ModelData *m, const double q[3], double p[3]) {
    const double *g = m->geometry;
    if (m->family == FAMILY_KEOPS) {
        double C[3][3];
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) C[i][k] = q[i] * m->axis[i][k] - m->offset[i][k];
        return three_sphere_lower(C, GG(L), p);
    }
    if (m->family == FAMILY_LINEARDELTA) {
        double C[3][3];
        for (int i = 0; i < 3; i++) C[i][0] = m->tower[i][0], C[i][1] = m->tower[i][1], C[i][2] = q[i];
        return three_sphere_lower(C, GG(L), p);
    }
    double den = 2.0 * (q[1] - q[0] + GG(c4));
    if (den == 0) return false;
    double X = (q[1] * q[1] + GG(c1) * GG(c1) - GG(c2) * GG(c2) - (q[0] - GG(c4)) * (q[0] - GG(c4))) / den;
    double rz = GG(c3) * GG(c3) - (q[2] - (X + GG(x_p3))) * (q[2] - (X + GG(x_p3)));
    if (rz < 0) return false;
    double Z = GG(z_o3) - GG(z_p3) - sqrt(rz);
    double ry = GG(c2) * GG(c2) - (q[1] - X) * (q[1] - X) - (Z + GG(z_p2)) * (Z + GG(z_p2));
    if (ry < 0) return false;
    double Y = -GG(d) - sqrt(ry);
    p[0] = X + GG(x_TP), p[1] = Y + GG(y_TP), p[2] = Z + GG(z_TP);
    return true;
#undef GG
}

/* 2-norm condition number of J from the eigenvalues of the symmetric JᵀJ (closed form). */
static double condition_number(const double J[3][3]) {
    double A[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) A[i][j] = J[0][i] * J[0][j] + J[1][i] * J[1][j] + J[2][i] * J[2][j];
    double p1 = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
    double tr = (A[0][0] + A[1][1] + A[2][2]) / 3.0;
    double p2 = (A[0][0] - tr) * (A[0][0] - tr) + (A[1][1] - tr) * (A[1][1] - tr) + (A[2][2] - tr) * (A[2][2] - tr) + 2 * p1;
    double lmax, lmin;
    if (p2 <= 1e-300) {
        lmax = lmin = tr;
    } else {
        double p = sqrt(p2 / 6.0), B[3][3];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) B[i][j] = (A[i][j] - (i == j ? tr : 0.0)) / p;
        double detB = B[0][0] * (B[1][1] * B[2][2] - B[1][2] * B[2][1]) - B[0][1] * (B[1][0] * B[2][2] - B[1][2] * B[2][0]) +
                      B[0][2] * (B[1][0] * B[2][1] - B[1][1] * B[2][0]);
        double r = fmax(-1.0, fmin(1.0, detB / 2.0));
        double phi = acos(r) / 3.0;
        lmax = tr + 2 * p * cos(phi);
        lmin = tr + 2 * p * cos(phi + 2.0 * PKM_PI / 3.0);
    }
    if (!(lmin > 0)) return COND_SINGULAR;
    double c = sqrt(lmax / lmin);
    return isfinite(c) ? c : COND_SINGULAR;
}

/* Recompute the outputs from the inputs. Returns false (and holds the last valid outputs)
 * when the commanded point is outside the workspace; *why describes it. */
static bool compute(ModelInstance *comp, char *why, size_t n) {
    ModelData *m = &comp->data;
    double q[3], J[3][3], p[3];
    m->dirty = false;
    int leg = inverse(m, m->p_cmd, q, J);
    bool ok = true;
    if (leg) {
        snprintf(why, n, "rod %d cannot reach (%.9g, %.9g, %.9g) mm", leg, m->p_cmd[0], m->p_cmd[1], m->p_cmd[2]);
        ok = false;
    } else {
        double qmin = G(comp, q_min), qmax = G(comp, q_max);
        for (int i = 0; i < 3 && ok; i++)
            if (q[i] < qmin - 1e-9 || q[i] > qmax + 1e-9) {
                snprintf(why, n, "point (%.9g, %.9g, %.9g) mm puts joint %d at %.9g mm, beyond its stroke [%g, %g] mm",
                         m->p_cmd[0], m->p_cmd[1], m->p_cmd[2], i + 1, q[i], qmin, qmax);
                ok = false;
            }
    }
    if (ok) {
        memcpy(m->q_cmd, q, sizeof q);
        m->cond_J = condition_number(J);
    }
    m->workspace_ok = ok;
    if (forward(m, m->q_act, p)) memcpy(m->p_act, p, sizeof p);   /* else hold the last FK */
    return ok;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelData *m = &comp->data;
    double *g = m->geometry;
    if (strcmp(m->machine, "keops") == 0) m->family = FAMILY_KEOPS;
    else if (strcmp(m->machine, "lineardelta") == 0) m->family = FAMILY_LINEARDELTA;
    else if (strcmp(m->machine, "pn101") == 0) m->family = FAMILY_PN101;
    else {
        model_error(comp, "parameter machine = '%s' is unknown; valid: keops, lineardelta, pn101", m->machine);
        return fmi2Error;
    }
    static const char *lengths[] = {"L", "x_ref", "R", "c1", "c2", "c3"};
    static const int lvr[] = {vr_L, vr_x_ref, vr_R, vr_c1, vr_c2, vr_c3};
    for (int i = 0; i < 6; i++)
        if (!(g[lvr[i] - vr_alpha_deg] > 0)) {
            model_error(comp, "parameter %s = %g must be > 0", lengths[i], g[lvr[i] - vr_alpha_deg]);
            return fmi2Error;
        }
    if (!(G(comp, q_min) < G(comp, q_max))) {
        model_error(comp, "parameter q_min = %g must be < q_max = %g", G(comp, q_min), G(comp, q_max));
        return fmi2Error;
    }
    if (m->family == FAMILY_PN101 && G(comp, c1) == G(comp, c2)) {
        model_error(comp, "pn101 with c1 = c2 is singular everywhere");
        return fmi2Error;
    }
    /* keops: a1 = [-cos a, 0, -sin a], d1 = [-(x_ref - eo), 0, y_ref], both rotated by 0/120/240° */
    double a = G(comp, alpha_deg) * PKM_PI / 180.0;
    for (int i = 0; i < 3; i++) {
        double th = i * 2.0 * PKM_PI / 3.0, c = cos(th), s = sin(th);
        double a1[2] = {-cos(a), 0.0}, d1[2] = {-(G(comp, x_ref) - G(comp, eo)), 0.0};
        m->axis[i][0] = c * a1[0] - s * a1[1], m->axis[i][1] = s * a1[0] + c * a1[1], m->axis[i][2] = -sin(a);
        m->offset[i][0] = c * d1[0] - s * d1[1], m->offset[i][1] = s * d1[0] + c * d1[1], m->offset[i][2] = G(comp, y_ref);
    }
    /* linear delta towers A = (0, R), B = (-R sin60, -R cos60), C = (R sin60, -R cos60) */
    double R = G(comp, R), s60 = sin(PKM_PI / 3.0), c60 = cos(PKM_PI / 3.0);
    m->tower[0][0] = 0.0, m->tower[0][1] = R;
    m->tower[1][0] = -R * s60, m->tower[1][1] = -R * c60;
    m->tower[2][0] = R * s60, m->tower[2][1] = -R * c60;
    /* the actual joints start where the command is, so FK is defined from t = 0 */
    char why[512];
    double q[3], J[3][3];
    bool unset = m->q_act[0] == 0.0 && m->q_act[1] == 0.0 && m->q_act[2] == 0.0;
    if (unset && inverse(m, m->p_cmd, q, J) == 0) memcpy(m->q_act, q, sizeof q);
    if (!compute(comp, why, sizeof why)) {
        model_error(comp, "at initialisation: %s", why);
        if (m->stop_on_workspace_error) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    (void)h;
    char why[512];
    if (!compute(comp, why, sizeof why)) {
        model_error(comp, "t = %.9g s: %s", comp->time + h, why);
        if (comp->data.stop_on_workspace_error) return fmi2Error;
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
    /* feed-through once initialised (the geometry is derived in model_initialize) */
    if (vr >= vr_q1_cmd && vr <= vr_cond_J && m->dirty && comp->phase == PKM_STEP_COMPLETE) {
        char why[512];
        compute(comp, why, sizeof why);   /* feed-through: outputs follow inputs at once */
    }
    if (vr >= vr_alpha_deg && vr <= vr_q_max) *v = m->geometry[vr - vr_alpha_deg];
    else if (vr >= vr_x_cmd && vr <= vr_z_cmd) *v = m->p_cmd[vr - vr_x_cmd];
    else if (vr >= vr_q1_act && vr <= vr_q3_act) *v = m->q_act[vr - vr_q1_act];
    else if (vr >= vr_q1_cmd && vr <= vr_q3_cmd) *v = m->q_cmd[vr - vr_q1_cmd];
    else if (vr >= vr_x_act && vr <= vr_z_act) *v = m->p_act[vr - vr_x_act];
    else if (vr == vr_cond_J) *v = m->cond_J;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_real(ModelInstance *comp, fmi2ValueReference vr, double v) {
    ModelData *m = &comp->data;
    if (vr >= vr_alpha_deg && vr <= vr_q_max) {
        if (comp->phase == PKM_STEP_COMPLETE) return fmi2Error;   /* fixed parameters */
        m->geometry[vr - vr_alpha_deg] = v;
    } else if (vr >= vr_x_cmd && vr <= vr_z_cmd) m->p_cmd[vr - vr_x_cmd] = v;
    else if (vr >= vr_q1_act && vr <= vr_q3_act) m->q_act[vr - vr_q1_act] = v;
    else return fmi2Error;
    m->dirty = true;
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
    if (vr == vr_stop_on_workspace_error) *v = comp->data.stop_on_workspace_error;
    else if (vr == vr_workspace_ok) *v = comp->data.workspace_ok;
    else return fmi2Error;
    return fmi2OK;
}

fmi2Status model_set_boolean(ModelInstance *comp, fmi2ValueReference vr, bool v) {
    if (vr != vr_stop_on_workspace_error || comp->phase == PKM_STEP_COMPLETE) return fmi2Error;
    comp->data.stop_on_workspace_error = v;
    return fmi2OK;
}

fmi2Status model_get_string(ModelInstance *comp, fmi2ValueReference vr, const char **v) {
    if (vr != vr_machine) return fmi2Error;
    *v = comp->data.machine;
    return fmi2OK;
}

fmi2Status model_set_string(ModelInstance *comp, fmi2ValueReference vr, const char *v) {
    if (vr != vr_machine || comp->phase == PKM_STEP_COMPLETE) return fmi2Error;
    return model_copy_string(comp, comp->data.machine, v, "machine");
}
