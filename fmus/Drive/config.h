/* Drive.fmu: one CiA 402 CSP servo axis (pkmbench issue 4). Physics in drive_model.c. */
#ifndef DRIVE_CONFIG_H
#define DRIVE_CONFIG_H

#include <stdbool.h>
#include "drive_model.h"

#define MODEL_IDENTIFIER "Drive"
#define INSTANTIATION_TOKEN "{3f6d2a91-7c4e-4b8a-9e15-2d7c5a0b4e42}"

typedef enum {
    /* Real parameters (units as in modelDescription.xml) */
    vr_inner_period_s = 1, vr_mass_kg, vr_force_constant_N_per_A, vr_torque_constant_Nm_per_A,
    vr_rotor_inertia_kgm2, vr_pulley_mm_per_rev, vr_encoder_resolution_mm, vr_resistance_ohm,
    vr_inductance_H, vr_viscous_N_s_per_m, vr_coulomb_N, vr_current_max_A, vr_voltage_max_V,
    vr_kp_pos, vr_kp_vel, vr_ki_vel, vr_kp_cur, vr_ki_cur, vr_vff, vr_aff, vr_vel_filter_tau_s,
    vr_following_error_max_mm, vr_quickstop_decel_mm_s2,
    /* Real input / outputs */
    vr_target = 30,
    vr_position = 40, vr_velocity, vr_current, vr_force, vr_following_error, vr_load_position,
    /* Integers */
    vr_encoder_increments_per_rev = 50, vr_state = 51,
    /* Booleans */
    vr_ideal = 60, vr_sync_ok = 61, vr_fault = 62,
    /* Strings */
    vr_motor = 70, vr_interpolation = 71
} ValueReference;

#define N_REAL_PARAMS (vr_quickstop_decel_mm_s2 - vr_inner_period_s + 1)

typedef struct {
    double par[N_REAL_PARAMS];      /* indexed by vr - vr_inner_period_s */
    int encoder_increments_per_rev;
    bool ideal;
    char motor[1024];
    char interpolation[1024];
    double target;                  /* input, mm */
    bool sync_ok;                   /* input */
    double ideal_pos, ideal_vel;    /* ideal drive, in mm and mm/s (bit-exact copy of target) */
    DriveState drive;               /* everything that changes (SI inside) */
} ModelData;

#endif
