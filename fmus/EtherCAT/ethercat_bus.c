/* EtherCAT master cycle and bus (see ethercat_bus.h). pkmbench issue 4.
 *
 * Each master cycle k the real-time thread wakes `lateness` after its nominal time
 * (a seeded draw), builds the frame and sends it. The frame reaches the drives
 * before SYNC0 if  max(lateness, 0) < T - sync0_shift - frame_time,  with
 * frame_time = 80 ns/byte (100 Mbit/s) * bytes + slaves * forwarding delay.
 * A master that wakes early (negative lateness, as the ± LinuxCNC latency
 * histogram reports) still sends within its own cycle: it counts as on time.
 * Otherwise the cycle is lost for the drives: they hold the last target (CiA 402
 * default) or extrapolate it linearly for up to N cycles. ETG.1020 sync-error
 * counter: +3 per missed cycle, -1 per good one (not below 0); when it exceeds
 * the limit (0x10F1:02, 4 by default) the drive leaves OP with a sync error, which
 * latches: sync_ok stays false.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "ethercat_bus.h"

#define ECAT_PI 3.14159265358979323846  /* M_PI is not strict C11 */

/* splitmix64 (Steele, Lea, Flood 2014) expands the seed; xoshiro256** (Blackman,
 * Vigna 2018) draws. Both are pure 64-bit integer arithmetic: identical on every platform. */
static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t v, int k) { return (v << k) | (v >> (64 - k)); }

static uint64_t xoshiro_next(EcatRng *r)
{
    uint64_t *s = r->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0]; s[3] ^= s[1]; s[1] ^= s[2]; s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

void ecat_rng_seed(EcatRng *r, uint64_t seed)
{
    uint64_t x = seed;
    for (int i = 0; i < 4; i++) r->s[i] = splitmix64(&x);
    r->has_spare = 0;
    r->spare = 0.0;
}

double ecat_rng_uniform(EcatRng *r) { return (double)(xoshiro_next(r) >> 11) * 0x1.0p-53; }

double ecat_rng_normal(EcatRng *r)
{
    if (r->has_spare) { r->has_spare = 0; return r->spare; }
    double u1 = 1.0 - ecat_rng_uniform(r);  /* (0, 1]: log is finite */
    double u2 = ecat_rng_uniform(r);
    double rad = sqrt(-2.0 * log(u1));
    r->spare = rad * sin(2.0 * ECAT_PI * u2);
    r->has_spare = 1;
    return rad * cos(2.0 * ECAT_PI * u2);
}

const char *ecat_check_params(const EcatParams *p)
{
    if (!(p->cycle_s > 0)) return "parameter cycle_s (T) must be > 0";
    if (p->dist < DIST_NONE || p->dist > DIST_HISTOGRAM) return "parameter distribution is unknown (none | normal | mixture | histogram)";
    if (!(p->sigma_s >= 0)) return "parameter sigma_s must be >= 0";
    if (p->dist == DIST_MIXTURE) {
        if (!(p->tail_probability >= 0 && p->tail_probability <= 1)) return "parameter tail_probability must be within 0..1";
        if (!(p->tail_scale_s > 0)) return "parameter tail_scale_s must be > 0";
        if (!(p->tail_shape > 0)) return "parameter tail_shape must be > 0";
    }
    if (p->dist == DIST_HISTOGRAM && p->hist_n <= 0) return "distribution histogram needs parameter histogram_file";
    if (!(p->cap_s > 0)) return "parameter cap_s must be > 0";
    if (!(p->sync0_shift_s >= 0 && p->sync0_shift_s < p->cycle_s)) return "parameter sync0_shift_s must be within 0..cycle_s";
    if (p->frame_bytes < 0) return "parameter frame_bytes must be >= 0";
    if (p->slaves < 0) return "parameter slaves must be >= 0";
    if (!(p->forward_delay_s >= 0)) return "parameter forward_delay_s must be >= 0";
    if (p->on_lost != LOST_HOLD && p->on_lost != LOST_EXTRAPOLATE) return "parameter on_lost must be hold or extrapolate";
    if (p->extrapolate_cycles < 0) return "parameter extrapolate_cycles must be >= 0";
    if (!(p->loss_probability >= 0 && p->loss_probability <= 1)) return "parameter loss_probability must be within 0..1";
    if (p->delay_cycles < 0 || p->delay_cycles > ECAT_MAX_DELAY) return "parameter delay_cycles must be within 0..64";
    if (p->sync_error_limit < 0) return "parameter sync_error_limit must be >= 0";
    return 0;
}

int ecat_apply_preset(EcatParams *p, const char *name)
{
    if (!name || !*name) return 0;
    if (strcmp(name, "linuxcnc_rt_preempt") == 0) {
        /* Kossel thesis Fig. 29 (shared/SOURCES.md §C): LinuxCNC 2.8 servo thread on
         * Debian 11 PREEMPT_RT under glxgears load, nearly all samples within ±20 us,
         * the worst below ±400 us, largest at thread start. Body sigma 5 us (assumed,
         * so that the body alone stays within ±20 us = 4 sigma), tail 0.5 % Pareto from
         * 15 us with shape 1.5 (assumed: puts ~0.35 % beyond ±20 us), capped at 400 us,
         * and the thread start itself late by the cap. */
        p->dist = DIST_MIXTURE;
        p->sigma_s = 5e-6;
        p->tail_probability = 0.005;
        p->tail_scale_s = 15e-6;
        p->tail_shape = 1.5;
        p->cap_s = 400e-6;
        p->startup_lateness_s = 400e-6;
        return 0;
    }
    if (strcmp(name, "tuned_rt") == 0) {
        /* Tuned IgH master + PREEMPT_RT: 2-6 us jitter (SOURCES.md §D); sigma 4 us
         * (middle of the range), cap 50 us (assumed). */
        p->dist = DIST_NORMAL;
        p->sigma_s = 4e-6;
        p->cap_s = 50e-6;
        p->startup_lateness_s = 0.0;
        return 0;
    }
    return -1;
}

int ecat_parse_forced(EcatParams *p, const char *list, char *msg, int msg_len)
{
    p->n_forced = 0;
    if (!list) return 0;
    const char *c = list;
    while (*c) {
        while (*c == ' ' || *c == ',') c++;
        if (!*c) break;
        char *end;
        errno = 0;
        long v = strtol(c, &end, 10);
        if (end == c || errno || v < 0) {
            snprintf(msg, msg_len, "forced_late_cycles: '%s' is not a list of cycle indices >= 0 (at '%s')", list, c);
            return -1;
        }
        if (p->n_forced >= ECAT_MAX_FORCED) {
            snprintf(msg, msg_len, "forced_late_cycles: more than %d entries", ECAT_MAX_FORCED);
            return -1;
        }
        p->forced[p->n_forced++] = v;
        c = end;
        while (*c == ' ') c++;
        if (*c && *c != ',') {
            snprintf(msg, msg_len, "forced_late_cycles: '%s' is not a list of cycle indices >= 0 (at '%s')", list, c);
            return -1;
        }
    }
    return 0;
}

static int parse_double(const char *txt, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(txt, &end);
    if (end == txt || errno) return -1;
    while (isspace((unsigned char)*end)) end++;
    if (*end) return -1;
    if (!isfinite(v)) return -1;
    *out = v;
    return 0;
}

int ecat_load_histogram(EcatParams *p, const char *path, char *msg, int msg_len)
{
    FILE *f = fopen(path, "r");
    if (!f) { snprintf(msg, msg_len, "histogram_file '%s': cannot open (%s)", path, strerror(errno)); return -1; }
    int cap = 256, n = 0, lineno = 0, seen_data = 0;
    double *lo = malloc(cap * sizeof *lo), *hi = malloc(cap * sizeof *hi), *cnt = malloc(cap * sizeof *cnt);
    char line[1024];
    int rc = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *c = line;
        while (isspace((unsigned char)*c)) c++;
        if (!*c || *c == '#') continue;
        c[strcspn(c, "\r\n")] = 0;
        char *f1 = c, *f2 = strchr(f1, ',');
        char *f3 = f2 ? strchr(f2 + 1, ',') : 0;
        if (!f2 || !f3 || strchr(f3 + 1, ',')) {
            snprintf(msg, msg_len, "histogram_file '%s' line %d: expected 3 fields bin_lo_us,bin_hi_us,count, got '%s'", path, lineno, c);
            rc = -1; break;
        }
        *f2 = 0; *f3 = 0;
        double a, b, k;
        if (parse_double(f1, &a) || parse_double(f2 + 1, &b) || parse_double(f3 + 1, &k)) {
            if (!seen_data && n == 0 && strstr(f1, "lo")) { seen_data = 1; continue; }  /* header line */
            snprintf(msg, msg_len, "histogram_file '%s' line %d: fields are not numbers", path, lineno);
            rc = -1; break;
        }
        seen_data = 1;
        if (!(a < b)) { snprintf(msg, msg_len, "histogram_file '%s' line %d: bin_lo_us %g must be < bin_hi_us %g", path, lineno, a, b); rc = -1; break; }
        if (!(k >= 0)) { snprintf(msg, msg_len, "histogram_file '%s' line %d: count %g must be >= 0", path, lineno, k); rc = -1; break; }
        if (n == cap) {
            cap *= 2;
            lo = realloc(lo, cap * sizeof *lo); hi = realloc(hi, cap * sizeof *hi); cnt = realloc(cnt, cap * sizeof *cnt);
        }
        lo[n] = a * 1e-6; hi[n] = b * 1e-6; cnt[n] = k; n++;
    }
    fclose(f);
    double total = 0;
    if (rc == 0) {
        for (int i = 0; i < n; i++) total += cnt[i];
        if (n == 0 || !(total > 0)) { snprintf(msg, msg_len, "histogram_file '%s': no bins with a positive count", path); rc = -1; }
    }
    if (rc) { free(lo); free(hi); free(cnt); return -1; }
    double acc = 0;
    for (int i = 0; i < n; i++) { acc += cnt[i]; cnt[i] = acc / total; }
    cnt[n - 1] = 1.0;
    ecat_free_params(p);
    p->hist_lo = lo; p->hist_hi = hi; p->hist_cdf = cnt; p->hist_n = n;
    return 0;
}

double ecat_frame_time(const EcatParams *p)
{
    return p->frame_bytes * 80e-9 + p->slaves * p->forward_delay_s;  /* 100 Mbit/s: 80 ns per byte */
}

int ecat_init(EcatState *s, const EcatParams *p, const double q0[ECAT_DRIVES], double out_bin_s)
{
    memset(s, 0, sizeof *s);
    s->p = *p;
    ecat_rng_seed(&s->rng, p->seed);
    for (int k = 0; k <= ECAT_MAX_DELAY; k++)
        for (int d = 0; d < ECAT_DRIVES; d++) s->sent[k][d] = q0[d];
    for (int d = 0; d < ECAT_DRIVES; d++) {
        s->target[d] = s->last_good[d] = s->prev_good[d] = q0[d];
        s->sync_ok[d] = 1;
    }
    s->out_bin_s = out_bin_s > 0 ? out_bin_s : 1e-6;
    s->out_range_s = fmax(p->cycle_s, p->cap_s);
    s->out_n = (int)ceil(2 * s->out_range_s / s->out_bin_s);
    return s->out_n <= ECAT_HIST_BINS ? 0 : -1;
}

double ecat_draw_lateness(EcatState *s)
{
    const EcatParams *p = &s->p;
    double l = 0.0;
    switch (p->dist) {
    case DIST_NONE: l = 0.0; break;
    case DIST_NORMAL: l = p->sigma_s * ecat_rng_normal(&s->rng); break;
    case DIST_MIXTURE:
        if (ecat_rng_uniform(&s->rng) < p->tail_probability) {
            /* Pareto magnitude x_m U^(-1/alpha), either sign */
            double u = 1.0 - ecat_rng_uniform(&s->rng);
            double mag = p->tail_scale_s * pow(u, -1.0 / p->tail_shape);
            l = ecat_rng_uniform(&s->rng) < 0.5 ? -mag : mag;
        } else {
            l = p->sigma_s * ecat_rng_normal(&s->rng);
        }
        break;
    case DIST_HISTOGRAM: {
        double u = ecat_rng_uniform(&s->rng);
        int a = 0, b = p->hist_n - 1;  /* first bin with cdf > u */
        while (a < b) { int m = (a + b) / 2; if (p->hist_cdf[m] > u) b = m; else a = m + 1; }
        l = p->hist_lo[a] + (p->hist_hi[a] - p->hist_lo[a]) * ecat_rng_uniform(&s->rng);
        break;
    }
    }
    if (l > p->cap_s) l = p->cap_s;
    if (l < -p->cap_s) l = -p->cap_s;
    return l;
}

static int is_forced(const EcatParams *p, long k)
{
    for (int i = 0; i < p->n_forced; i++) if (p->forced[i] == k) return 1;
    return 0;
}

void ecat_cycle(EcatState *s, const double q_cmd[ECAT_DRIVES])
{
    const EcatParams *p = &s->p;
    long k = s->cycle++;
    /* draws happen every cycle in a fixed order, so a forced cycle does not shift the
     * random sequence of the others */
    double l = ecat_draw_lateness(s);
    double u_loss = p->loss_probability > 0 ? ecat_rng_uniform(&s->rng) : 1.0;
    if (k == 0 && p->startup_lateness_s != 0.0) l = p->startup_lateness_s;
    if (is_forced(p, k)) l = p->cycle_s;  /* woke a whole cycle late */
    s->lateness = l;
    if (fabs(l) > s->lateness_max_abs) s->lateness_max_abs = fabs(l);
    /* histogram of the draws, out-of-range values folded into the edge bins */
    int bin = (int)floor((l + s->out_range_s) / s->out_bin_s);
    if (bin < 0) bin = 0;
    if (bin >= s->out_n) bin = s->out_n - 1;
    s->out_counts[bin]++;
    /* transport delay: the frame carries the command of delay_cycles ago */
    int slot = (int)(k % (ECAT_MAX_DELAY + 1));
    for (int d = 0; d < ECAT_DRIVES; d++) s->sent[slot][d] = q_cmd[d];
    int src = (int)((k - p->delay_cycles) % (ECAT_MAX_DELAY + 1));
    if (k < p->delay_cycles) src = -1;  /* nothing sent yet: the initial value */
    double effective = l > 0 ? l : 0.0;  /* early wake still sends on its own cycle */
    int ok = effective < p->cycle_s - p->sync0_shift_s - ecat_frame_time(p) && u_loss >= p->loss_probability;
    s->lost_now = !ok;
    if (ok) {
        s->consecutive_lost = 0;
        for (int d = 0; d < ECAT_DRIVES; d++) {
            double v = src >= 0 ? s->sent[src][d] : s->last_good[d];
            if (src < 0 && !s->have_good) v = s->target[d];
            s->prev_good[d] = s->have_good ? s->last_good[d] : v;
            s->last_good[d] = v;
            s->target[d] = v;
            if (s->counter[d] > 0) s->counter[d]--;
        }
        s->have_good = 1;
    } else {
        s->lost_frames++;
        s->consecutive_lost++;
        for (int d = 0; d < ECAT_DRIVES; d++) {
            if (p->on_lost == LOST_EXTRAPOLATE && s->consecutive_lost <= p->extrapolate_cycles)
                s->target[d] += s->last_good[d] - s->prev_good[d];
            s->counter[d] += 3;
        }
    }
    for (int d = 0; d < ECAT_DRIVES; d++)
        if (s->counter[d] > p->sync_error_limit) s->sync_ok[d] = 0;  /* latched */
}

int ecat_write_histogram(const EcatState *s, const char *path, char *msg, int msg_len)
{
    FILE *f = fopen(path, "w");
    if (!f) { snprintf(msg, msg_len, "histogram_out '%s': cannot write (%s)", path, strerror(errno)); return -1; }
    int first = -1, last = -1;
    for (int i = 0; i < s->out_n; i++) if (s->out_counts[i]) { if (first < 0) first = i; last = i; }
    fprintf(f, "# lateness histogram of the EtherCAT master, %ld cycles; bins in microseconds\n", s->cycle);
    fprintf(f, "bin_lo_us,bin_hi_us,count\n");
    for (int i = first; i >= 0 && i <= last; i++) {
        double lo = (i * s->out_bin_s - s->out_range_s) * 1e6, hi = ((i + 1) * s->out_bin_s - s->out_range_s) * 1e6;
        fprintf(f, "%.6f,%.6f,%ld\n", lo, hi, s->out_counts[i]);
    }
    fclose(f);
    return 0;
}

void ecat_free_params(EcatParams *p)
{
    free(p->hist_lo); free(p->hist_hi); free(p->hist_cdf);
    p->hist_lo = p->hist_hi = p->hist_cdf = 0;
    p->hist_n = 0;
}

void ecat_free(EcatState *s)
{
    ecat_free_params(&s->p);
}
