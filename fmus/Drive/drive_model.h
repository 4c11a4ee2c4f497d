/* Drive physics and control, independent of FMI (pkmbench issue 4).
 *
 * One axis of a CiA 402 drive in cyclic synchronous position (CSP) mode:
 * fine interpolation of the bus targets, cascade position P (+ velocity and
 * acceleration feed-forward) -> velocity PI -> current PI with saturation and
 * anti-windup, all inner loops at the same rate Ts (62.5 us on Beckhoff AX8000),
 * a motor + load reduced to one linear axis, encoder quantisation, and the
 * CiA 402 fault reaction (quick stop on the fast ramp).
 *
 * Everything here is SI (m, s, N, A, V); the FMI wrapper converts mm <-> m.
 */
#ifndef DRIVE_MODEL_H
#define DRIVE_MODEL_H

enum DriveMotor { MOTOR_LINEAR = 1, MOTOR_STEPPER_BELT = 2 };
enum DriveInterp { INTERP_LINEAR = 1, INTERP_CUBIC = 2 };

/* CiA 402 power state machine states reported by the `state` output. */
enum Cia402State {
    CIA_SWITCH_ON_DISABLED = 1,
    CIA_READY_TO_SWITCH_ON = 2,
    CIA_SWITCHED_ON = 3,
    CIA_OPERATION_ENABLED = 4,
    CIA_QUICK_STOP_ACTIVE = 5,
    CIA_FAULT_REACTION_ACTIVE = 6,
    CIA_FAULT = 7
};

/* Fault causes (bit mask in DriveState.fault_cause). */
#define DRIVE_FAULT_SYNC 1
#define DRIVE_FAULT_FOLLOWING 2

typedef struct {
    int motor;                 /* enum DriveMotor */
    /* motor + load as given by the data sheet */
    double mass_kg;            /* moving mass (linear) or carriage mass (belt) */
    double force_constant;     /* linear: N/A */
    double torque_constant;    /* stepper: N m/A (q-axis under FOC) */
    double rotor_inertia;      /* stepper: kg m^2 */
    double pulley_m_per_rev;   /* stepper: feed constant, m/rev */
    double resistance_ohm;     /* winding (phase) resistance */
    double inductance_h;       /* winding (phase) inductance */
    double viscous_n_s_per_m;  /* viscous friction at the load, N/(m/s) */
    double coulomb_n;          /* Coulomb friction at the load, N */
    double current_max_a;      /* peak current = current command saturation */
    double voltage_max_v;      /* bus voltage = current controller output saturation */
    double encoder_res_m;      /* one encoder increment in m at the load; 0 = no quantisation */
    /* controller, SI */
    double kp_pos;             /* 1/s */
    double kp_vel;             /* A/(m/s) */
    double ki_vel;             /* A/(m/s)/s */
    double kp_cur;             /* V/A */
    double ki_cur;             /* V/(A s) */
    double vff;                /* velocity feed-forward factor, 1 = 100 % */
    double aff;                /* acceleration feed-forward factor, 1 = 100 % */
    double vel_filter_tau_s;   /* first-order filter on the encoder velocity; 0 = none */
    double inner_period_s;     /* Ts, 62.5e-6 */
    int interpolation;         /* enum DriveInterp */
    double following_error_max_m;  /* fault when |FE| exceeds it; <= 0 disables */
    double quickstop_decel;    /* m/s^2, the fast ramp of the fault reaction */
    int ideal;                 /* position = target exactly, no dynamics */
} DriveParams;

typedef struct {
    DriveParams p;
    /* derived */
    double m_eff, kf, ke;      /* reflected mass, force constant N/A, back-EMF V/(m/s) */
    double Phi[3][3], Gam[3][2];  /* exact ZOH discretisation of [i v x] over Ts */
    /* plant */
    double i, v, x;
    /* controller */
    double int_vel, int_cur, v_filt, x_meas_prev, x_meas;
    double i_cmd, demand, v_ff, a_ff;
    double hist[4];            /* last targets, hist[0] newest */
    double v_ff_prev;
    /* CiA 402 */
    int state, fault_cause;
    double qs_v;               /* quick-stop ramp velocity */
    double following_error;
    double cycle_s;
    int substeps;
} DriveState;

/* Returns NULL on success, else a static message naming the bad parameter. */
const char *drive_check_params(const DriveParams *p);
/* Derive the reduced model and its discretisation; call after drive_check_params. */
void drive_init(DriveState *s, const DriveParams *p, double x0_m);
/* One bus cycle of length cycle_s: new target (m), sync flag. Returns NULL or an error. */
const char *drive_cycle(DriveState *s, double target_m, int sync_ok, double cycle_s);
double drive_force(const DriveState *s);

#endif
