/* EtherCAT master cycle and bus for three CSP drives, independent of FMI (pkmbench issue 4).
 * Times in seconds, positions in whatever unit the caller uses (mm in the FMU). */
#ifndef ETHERCAT_BUS_H
#define ETHERCAT_BUS_H

#include <stdint.h>

#define ECAT_DRIVES 3
#define ECAT_MAX_DELAY 64
#define ECAT_MAX_FORCED 256
#define ECAT_HIST_BINS 8192   /* output histogram bins (kept inside the state: FMU state copies stay flat) */

enum EcatDist { DIST_NONE = 0, DIST_NORMAL = 1, DIST_MIXTURE = 2, DIST_HISTOGRAM = 3 };
enum EcatOnLost { LOST_HOLD = 0, LOST_EXTRAPOLATE = 1 };

typedef struct { uint64_t s[4]; int has_spare; double spare; } EcatRng;

typedef struct {
    double cycle_s;            /* nominal master cycle T */
    int dist;                  /* enum EcatDist */
    double sigma_s;            /* normal body standard deviation */
    double tail_probability;   /* mixture: share of draws from the tail */
    double tail_scale_s;       /* mixture: Pareto scale x_m (smallest tail magnitude) */
    double tail_shape;         /* mixture: Pareto shape alpha */
    double cap_s;              /* |lateness| is capped here (all distributions) */
    double startup_lateness_s; /* lateness of cycle 0 (thread start); 0 = a normal draw */
    double sync0_shift_s;      /* SYNC0 fires this long before the next cycle start */
    int frame_bytes;           /* frame length on the wire */
    int slaves;                /* slaves the frame passes */
    double forward_delay_s;    /* per-slave forwarding delay */
    int on_lost;               /* enum EcatOnLost */
    int extrapolate_cycles;    /* N: extrapolate at most N consecutive lost cycles, then hold */
    double loss_probability;   /* random loss of a whole frame */
    int delay_cycles;          /* transport delay n: targets are q_cmd of n cycles ago */
    int sync_error_limit;      /* ETG.1020 0x10F1:02, fault when the counter exceeds it */
    uint64_t seed;
    int n_forced;
    long forced[ECAT_MAX_FORCED];  /* cycle indices forced late by a full cycle */
    /* histogram replay (bins in s) */
    int hist_n;
    double *hist_lo, *hist_hi, *hist_cdf;
} EcatParams;

typedef struct {
    EcatParams p;
    EcatRng rng;
    long cycle;
    double sent[ECAT_MAX_DELAY + 1][ECAT_DRIVES];  /* ring of commanded values */
    double target[ECAT_DRIVES], last_good[ECAT_DRIVES], prev_good[ECAT_DRIVES];
    int have_good;
    int consecutive_lost;
    int counter[ECAT_DRIVES];
    int sync_ok[ECAT_DRIVES];
    long lost_frames;
    int lost_now;
    double lateness;
    double lateness_max_abs;   /* max |lateness| so far */
    /* lateness histogram for the output file */
    double out_bin_s, out_range_s;
    int out_n;
    long out_counts[ECAT_HIST_BINS];
} EcatState;

void ecat_rng_seed(EcatRng *r, uint64_t seed);
double ecat_rng_uniform(EcatRng *r);   /* [0, 1) */
double ecat_rng_normal(EcatRng *r);    /* standard normal, Box-Muller */

const char *ecat_check_params(const EcatParams *p);
/* Presets by name; returns 0 if known (fills the distribution fields), -1 otherwise. */
int ecat_apply_preset(EcatParams *p, const char *name);
/* Read a histogram file (CSV bin_lo_us,bin_hi_us,count). On error returns -1 and writes
 * a message naming the file and line into msg. */
int ecat_load_histogram(EcatParams *p, const char *path, char *msg, int msg_len);
/* Parse "3,17,250" into p->forced. Returns -1 and a message on bad input. */
int ecat_parse_forced(EcatParams *p, const char *list, char *msg, int msg_len);

/* out_bin_s: bin width of the written histogram. Returns 0, or -1 if 2·max(T, cap)/out_bin_s
 * exceeds ECAT_HIST_BINS. */
int ecat_init(EcatState *s, const EcatParams *p, const double q0[ECAT_DRIVES], double out_bin_s);
double ecat_frame_time(const EcatParams *p);
double ecat_draw_lateness(EcatState *s);
/* One master cycle: commanded joint values in, targets and flags in the state. */
void ecat_cycle(EcatState *s, const double q_cmd[ECAT_DRIVES]);
int ecat_write_histogram(const EcatState *s, const char *path, char *msg, int msg_len);
/* Frees the histogram tables (owned by s->p after ecat_init). */
void ecat_free(EcatState *s);
void ecat_free_params(EcatParams *p);

#endif
