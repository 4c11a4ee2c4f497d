/* Kinematics.fmu: IK of the commanded point, FK of the actual joints (pkmbench kins/). */
#ifndef KINEMATICS_CONFIG_H
#define KINEMATICS_CONFIG_H

#include <stdbool.h>

#define MODEL_IDENTIFIER "Kinematics"
#define INSTANTIATION_TOKEN "{6b0c3f5e-9a51-4c6e-8d1f-4b8e2a7c1d01}"

typedef enum {
    /* Real parameters: geometry of every family (keops | lineardelta | pn101) */
    vr_alpha_deg = 1, vr_L, vr_x_ref, vr_y_ref, vr_eo, vr_R,
    vr_c1, vr_c2, vr_c3, vr_c4, vr_d, vr_z_p2, vr_x_p3, vr_z_p3, vr_y_o3, vr_z_o3,
    vr_x_TP, vr_y_TP, vr_z_TP, vr_q_min, vr_q_max,
    /* Real inputs */
    vr_x_cmd = 30, vr_y_cmd, vr_z_cmd, vr_q1_act, vr_q2_act, vr_q3_act,
    /* Real outputs */
    vr_q1_cmd = 40, vr_q2_cmd, vr_q3_cmd, vr_x_act, vr_y_act, vr_z_act, vr_cond_J,
    /* String parameter */
    vr_machine = 100,
    /* Booleans */
    vr_stop_on_workspace_error = 200, vr_workspace_ok = 201
} ValueReference;

typedef enum { FAMILY_KEOPS = 1, FAMILY_LINEARDELTA, FAMILY_PN101 } Family;

#define N_GEOMETRY (vr_q_max - vr_alpha_deg + 1)

typedef struct {
    double geometry[N_GEOMETRY];     /* indexed by vr - vr_alpha_deg */
    char machine[1024];
    bool stop_on_workspace_error;
    double p_cmd[3], q_act[3];       /* inputs */
    double q_cmd[3], p_act[3];       /* outputs (last valid values) */
    double cond_J;
    bool workspace_ok;
    bool dirty;                      /* inputs changed since the outputs were computed */
    /* derived at initialisation */
    Family family;
    double axis[3][3], offset[3][3]; /* keops: a_i, d_i */
    double tower[3][2];              /* linear delta: (X_i, Y_i) */
} ModelData;

#endif
