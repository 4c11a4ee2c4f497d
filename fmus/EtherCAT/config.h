/* EtherCAT.fmu: master cycle and bus for three CSP drives (pkmbench issue 4).
 * Bus logic in ethercat_bus.c. */
#ifndef ETHERCAT_CONFIG_H
#define ETHERCAT_CONFIG_H

#include <stdbool.h>
#include "ethercat_bus.h"

#define MODEL_IDENTIFIER "EtherCAT"
#define INSTANTIATION_TOKEN "{a8e41c27-5b93-4f0d-b6a2-71c9e3d05f18}"

typedef enum {
    /* Real parameters */
    vr_cycle_s = 1, vr_sigma_s, vr_tail_probability, vr_tail_scale_s, vr_tail_shape, vr_cap_s,
    vr_startup_lateness_s, vr_sync0_shift_s, vr_forward_delay_s, vr_loss_probability,
    vr_histogram_bin_s,
    /* Real inputs / outputs */
    vr_q1_cmd = 20, vr_q2_cmd, vr_q3_cmd,
    vr_q1_target = 30, vr_q2_target, vr_q3_target, vr_lateness, vr_lateness_max_abs,
    /* Integers */
    vr_frame_bytes = 40, vr_slaves, vr_extrapolate_cycles, vr_delay_cycles, vr_sync_error_limit,
    vr_seed, vr_lost_frames,
    /* Booleans (outputs) */
    vr_lost = 50, vr_sync_ok1, vr_sync_ok2, vr_sync_ok3,
    /* Strings */
    vr_preset = 60, vr_distribution, vr_histogram_file, vr_on_lost, vr_forced_late_cycles,
    vr_histogram_out
} ValueReference;

#define N_REAL_PARAMS (vr_histogram_bin_s - vr_cycle_s + 1)
#define N_INT_PARAMS (vr_seed - vr_frame_bytes + 1)
#define N_STRINGS (vr_histogram_out - vr_preset + 1)

typedef struct {
    double par[N_REAL_PARAMS];          /* indexed by vr - vr_cycle_s */
    int ipar[N_INT_PARAMS];             /* indexed by vr - vr_frame_bytes */
    char str[N_STRINGS][1024];          /* indexed by vr - vr_preset */
    double q_cmd[ECAT_DRIVES];          /* inputs */
    EcatState bus;                      /* everything that changes; its histogram tables are
                                           read-only after initialisation */
    bool initialized;
} ModelData;

#endif
