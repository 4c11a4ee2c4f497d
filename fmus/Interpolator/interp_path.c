/* Toolpath and profile files for Interpolator.fmu.
 *
 * Path file (planners/path.py writes it): NURBS JSON {"type": "nurbs", "degree", "knots",
 * "control_points", "weights"} or segments JSON {"type": "segments", "segments": [line | arc]}.
 * Profile file: CSV t,s,sd,sdd,sddd, one row per period T (planners/profile.py).
 *
 * NURBS arc length: per non-degenerate knot span SUBDIV sub-intervals, each integrated by
 * 8-point Gauss–Legendre (|C'(u)| is smooth inside a span), giving a cumulative table; s → u
 * by Newton on the same integral from the table node below s, so the travelled arc length
 * matches the profile to ~1e-12 mm (DESIGN.md asks ≤ 1 nm: joint jerk is a third difference). */
#include "interp_path.h"
#include "spiral.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SUBDIV 64
#define MAX_DEGREE 15

/* ---- a small strict JSON reader ------------------------------------------------------- */
typedef enum { J_NULL, J_BOOL, J_NUM, J_STR, J_ARR, J_OBJ } JType;
typedef struct Json {
    JType type;
    double num;
    char *str;             /* J_STR value; for members of an object: the key */
    char *key;
    struct Json *kids;     /* array elements / object members */
    int nkids;
    long offset;           /* byte offset in the file, for messages */
} Json;

typedef struct {
    const char *buf;
    long pos, len;
    char *err;
    size_t nerr;
    const char *file;
    int depth;
} Parser;

static int perr(Parser *P, const char *what) {
    snprintf(P->err, P->nerr, "%s: malformed JSON at byte %ld: %s", P->file, P->pos, what);
    return -1;
}

static void skip_ws(Parser *P) {
    while (P->pos < P->len && isspace((unsigned char)P->buf[P->pos])) P->pos++;
}

static void json_free(Json *j) {
    if (!j) return;
    for (int i = 0; i < j->nkids; i++) json_free(&j->kids[i]);
    free(j->kids);
    free(j->str);
    free(j->key);
    j->kids = NULL, j->str = NULL, j->key = NULL, j->nkids = 0;
}

static int parse_value(Parser *P, Json *out);

static int parse_string(Parser *P, char **out) {
    if (P->buf[P->pos] != '"') return perr(P, "expected a string");
    long start = ++P->pos;
    while (P->pos < P->len && P->buf[P->pos] != '"') {
        if (P->buf[P->pos] == '\\') P->pos++;   /* escapes kept verbatim: keys/types are ASCII */
        else if ((unsigned char)P->buf[P->pos] < 0x20) return perr(P, "control character in a string");
        P->pos++;
    }
    if (P->pos >= P->len) return perr(P, "unterminated string");
    long n = P->pos - start;
    *out = (char *)malloc((size_t)n + 1);
    if (!*out) return perr(P, "out of memory");
    memcpy(*out, P->buf + start, (size_t)n);
    (*out)[n] = 0;
    P->pos++;
    return 0;
}

static int push_kid(Parser *P, Json *parent, Json **kid) {
    if (parent->nkids % 16 == 0) {
        Json *k = (Json *)realloc(parent->kids, sizeof(Json) * (size_t)(parent->nkids + 16));
        if (!k) return perr(P, "out of memory");
        parent->kids = k;
    }
    *kid = &parent->kids[parent->nkids++];
    memset(*kid, 0, sizeof(Json));
    return 0;
}

static int parse_value(Parser *P, Json *out) {
    skip_ws(P);
    out->offset = P->pos;
    if (P->pos >= P->len) return perr(P, "unexpected end of file");
    if (++P->depth > 64) return perr(P, "nesting deeper than 64");
    char c = P->buf[P->pos];
    int rc = 0;
    if (c == '{' || c == '[') {
        char close = c == '{' ? '}' : ']';
        out->type = c == '{' ? J_OBJ : J_ARR;
        P->pos++;
        skip_ws(P);
        if (P->pos < P->len && P->buf[P->pos] == close) {
            P->pos++;
        } else {
            for (;;) {
                Json *kid;
                char *key = NULL;
                skip_ws(P);
                if (out->type == J_OBJ) {
                    if (P->pos >= P->len || parse_string(P, &key)) return P->pos >= P->len ? perr(P, "unexpected end") : -1;
                    skip_ws(P);
                    if (P->pos >= P->len || P->buf[P->pos] != ':') { free(key); return perr(P, "expected ':'"); }
                    P->pos++;
                }
                if (push_kid(P, out, &kid)) { free(key); return -1; }
                kid->key = key;
                if (parse_value(P, kid)) return -1;
                skip_ws(P);
                if (P->pos >= P->len) return perr(P, "unexpected end of file");
                if (P->buf[P->pos] == ',') { P->pos++; continue; }
                if (P->buf[P->pos] == close) { P->pos++; break; }
                return perr(P, out->type == J_OBJ ? "expected ',' or '}'" : "expected ',' or ']'");
            }
        }
    } else if (c == '"') {
        out->type = J_STR;
        rc = parse_string(P, &out->str);
    } else if (!strncmp(P->buf + P->pos, "true", 4) || !strncmp(P->buf + P->pos, "false", 5)) {
        out->type = J_BOOL;
        out->num = c == 't';
        P->pos += c == 't' ? 4 : 5;
    } else if (!strncmp(P->buf + P->pos, "null", 4)) {
        out->type = J_NULL;
        P->pos += 4;
    } else if (c == '-' || isdigit((unsigned char)c)) {
        char *end;
        errno = 0;
        out->type = J_NUM;
        out->num = strtod(P->buf + P->pos, &end);
        if (end == P->buf + P->pos || errno == ERANGE || !isfinite(out->num)) return perr(P, "bad number");
        P->pos = end - P->buf;
    } else {
        return perr(P, "unexpected character");
    }
    P->depth--;
    return rc;
}

static const Json *member(const Json *obj, const char *key) {
    for (int i = 0; i < obj->nkids; i++)
        if (obj->kids[i].key && !strcmp(obj->kids[i].key, key)) return &obj->kids[i];
    return NULL;
}

static char *read_file(const char *file, long *len, char *err, size_t nerr) {
    FILE *f = fopen(file, "rb");
    if (!f) {
        snprintf(err, nerr, "%s: cannot open: %s", file, strerror(errno));
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = (n >= 0) ? (char *)malloc((size_t)n + 1) : NULL;
    if (!buf || fread(buf, 1, (size_t)n, f) != (size_t)n) {
        snprintf(err, nerr, "%s: cannot read", file);
        free(buf);
        fclose(f);
        return NULL;
    }
    fclose(f);
    buf[n] = 0;
    *len = n;
    return buf;
}

static int fail(char *err, size_t nerr, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, nerr, fmt, ap);
    va_end(ap);
    return -1;
}

/* a JSON array of exactly n numbers (n < 0: any length ≥ 1, returned in *count) */
static int numbers(const Json *a, double *out, int n, const char *file, const char *what, char *err, size_t nerr) {
    if (!a || a->type != J_ARR) return fail(err, nerr, "%s: '%s' must be an array", file, what);
    if (n >= 0 && a->nkids != n) return fail(err, nerr, "%s: '%s' has %d numbers, expected %d", file, what, a->nkids, n);
    for (int i = 0; i < a->nkids; i++) {
        if (a->kids[i].type != J_NUM) return fail(err, nerr, "%s: %s[%d] is not a number", file, what, i);
        out[i] = a->kids[i].num;
    }
    return 0;
}

/* ---- NURBS ------------------------------------------------------------------------------ */
static int find_span(const Track *tr, double u) {
    int n = tr->ncp, p = tr->degree;
    if (u >= tr->knots[n]) return n - 1;
    if (u <= tr->knots[p]) return p;
    int lo = p, hi = n;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (u < tr->knots[mid]) hi = mid; else lo = mid;
    }
    return lo;
}

/* C(u) and C'(u) of the rational curve: basis functions and first derivatives (the
 * triangular table of Piegl & Tiller, The NURBS Book, A2.2/A2.3, for one derivative). */
static void nurbs_eval(const Track *tr, double u, double C[3], double dC[3]) {
    int p = tr->degree, span = find_span(tr, u);
    const double *U = tr->knots;
    double ndu[MAX_DEGREE + 1][MAX_DEGREE + 1], left[MAX_DEGREE + 1], right[MAX_DEGREE + 1];
    ndu[0][0] = 1.0;
    for (int j = 1; j <= p; j++) {
        left[j] = u - U[span + 1 - j];
        right[j] = U[span + j] - u;
        double saved = 0.0;
        for (int r = 0; r < j; r++) {
            ndu[j][r] = right[r + 1] + left[j - r];
            double tmp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * tmp;
            saved = left[j - r] * tmp;
        }
        ndu[j][j] = saved;
    }
    double A[4] = {0, 0, 0, 0}, dA[4] = {0, 0, 0, 0};
    for (int r = 0; r <= p; r++) {
        double N = ndu[r][p], dN = 0.0;
        if (p > 0) {
            if (r >= 1) dN += ndu[r - 1][p - 1] / ndu[p][r - 1];
            if (r <= p - 1) dN -= ndu[r][p - 1] / ndu[p][r];
            dN *= p;
        }
        const double *P = tr->cw + 4 * (span - p + r);
        for (int k = 0; k < 4; k++) A[k] += N * P[k], dA[k] += dN * P[k];
    }
    for (int k = 0; k < 3; k++) {
        C[k] = A[k] / A[3];
        dC[k] = (dA[k] - dA[3] * C[k]) / A[3];
    }
}

static double speed(const Track *tr, double u) {
    double C[3], dC[3];
    nurbs_eval(tr, u, C, dC);
    return sqrt(dC[0] * dC[0] + dC[1] * dC[1] + dC[2] * dC[2]);
}

/* ∫ₐᵇ |C'(u)| du by 8-point Gauss–Legendre (a, b inside one knot span) */
static double arc(const Track *tr, double a, double b) {
    static const double x[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363};
    static const double w[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
    double m = 0.5 * (a + b), h = 0.5 * (b - a), s = 0.0;
    for (int i = 0; i < 4; i++) s += w[i] * (speed(tr, m - h * x[i]) + speed(tr, m + h * x[i]));
    return s * h;
}

/* the same with 4 points: for the partial interval [table node, u] inside Newton, which is
 * at most 1/SUBDIV of a span (its error stays below 1e-13 mm; the 1 nm tests check it) */
static double arc4(const Track *tr, double a, double b) {
    static const double x[2] = {0.3399810435848563, 0.8611363115940526};
    static const double w[2] = {0.6521451548625461, 0.3478548451374538};
    double m = 0.5 * (a + b), h = 0.5 * (b - a), s = 0.0;
    for (int i = 0; i < 2; i++) s += w[i] * (speed(tr, m - h * x[i]) + speed(tr, m + h * x[i]));
    return s * h;
}

static int nurbs_build(Track *tr, const Json *root, const char *file, char *err, size_t nerr) {
    const Json *deg = member(root, "degree"), *kn = member(root, "knots"), *cp = member(root, "control_points"),
               *wt = member(root, "weights");
    if (!deg || deg->type != J_NUM || deg->num != floor(deg->num) || deg->num < 1 || deg->num > MAX_DEGREE)
        return fail(err, nerr, "%s: 'degree' must be an integer 1…%d", file, MAX_DEGREE);
    if (!cp || cp->type != J_ARR || cp->nkids < 2) return fail(err, nerr, "%s: 'control_points' must be an array of ≥ 2 points", file);
    tr->degree = (int)deg->num;
    tr->ncp = cp->nkids;
    int nk = tr->ncp + tr->degree + 1;
    if (tr->ncp <= tr->degree)
        return fail(err, nerr, "%s: %d control points for degree %d (need ≥ degree + 1)", file, tr->ncp, tr->degree);
    tr->knots = (double *)malloc(sizeof(double) * (size_t)nk);
    tr->cw = (double *)malloc(sizeof(double) * 4 * (size_t)tr->ncp);
    double *w = (double *)malloc(sizeof(double) * (size_t)tr->ncp);
    if (!tr->knots || !tr->cw || !w) { free(w); return fail(err, nerr, "%s: out of memory", file); }
    if (!kn || kn->type != J_ARR || kn->nkids != nk) {
        free(w);
        return fail(err, nerr, "%s: 'knots' has %d values; %d control points of degree %d need %d",
                    file, kn && kn->type == J_ARR ? kn->nkids : -1, tr->ncp, tr->degree, nk);
    }
    if (numbers(kn, tr->knots, nk, file, "knots", err, nerr)) { free(w); return -1; }
    for (int i = 1; i < nk; i++)
        if (tr->knots[i] < tr->knots[i - 1]) {
            free(w);
            return fail(err, nerr, "%s: knots are not non-decreasing: knots[%d] = %.17g < knots[%d] = %.17g",
                        file, i, tr->knots[i], i - 1, tr->knots[i - 1]);
        }
    if (!(tr->knots[tr->ncp] > tr->knots[tr->degree])) { free(w); return fail(err, nerr, "%s: the knot vector has no non-empty span", file); }
    if (wt) {
        if (numbers(wt, w, tr->ncp, file, "weights", err, nerr)) { free(w); return -1; }
    } else {
        for (int i = 0; i < tr->ncp; i++) w[i] = 1.0;
    }
    for (int i = 0; i < tr->ncp; i++) {
        double P[3];
        char what[48];
        snprintf(what, sizeof what, "control_points[%d]", i);
        if (numbers(&cp->kids[i], P, 3, file, what, err, nerr)) { free(w); return -1; }
        if (!(w[i] > 0)) { double wi = w[i]; free(w); return fail(err, nerr, "%s: weights[%d] = %g must be > 0", file, i, wi); }
        for (int k = 0; k < 3; k++) tr->cw[4 * i + k] = w[i] * P[k];
        tr->cw[4 * i + 3] = w[i];
    }
    free(w);
    /* arc-length table over the non-empty spans */
    int nspan = 0;
    for (int i = tr->degree; i < tr->ncp; i++) nspan += tr->knots[i + 1] > tr->knots[i];
    tr->ntab = (long)nspan * SUBDIV;
    tr->tab_u = (double *)malloc(sizeof(double) * (size_t)(tr->ntab + 1));
    tr->tab_s = (double *)malloc(sizeof(double) * (size_t)(tr->ntab + 1));
    if (!tr->tab_u || !tr->tab_s) return fail(err, nerr, "%s: out of memory", file);
    long k = 0;
    tr->tab_u[0] = tr->knots[tr->degree];
    tr->tab_s[0] = 0.0;
    for (int i = tr->degree; i < tr->ncp; i++) {
        double a = tr->knots[i], b = tr->knots[i + 1];
        if (!(b > a)) continue;
        for (int j = 1; j <= SUBDIV; j++) {
            double u0 = a + (b - a) * (j - 1) / SUBDIV, u1 = j == SUBDIV ? b : a + (b - a) * j / SUBDIV;
            tr->tab_u[k + 1] = u1;
            tr->tab_s[k + 1] = tr->tab_s[k] + arc(tr, u0, u1);
            k++;
        }
    }
    tr->length = tr->tab_s[tr->ntab];
    if (!(tr->length > 0) || !isfinite(tr->length)) return fail(err, nerr, "%s: the curve has zero or undefined length", file);
    return 0;
}

/* ---- segments ----------------------------------------------------------------------------- */
static void cross(const double a[3], const double b[3], double o[3]) {
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}

static void seg_point(const Segment *g, double f, double p[3]) {   /* f ∈ [0, 1] of the length */
    if (g->spiral != 0.0) {
        spiral_point(g, f >= 1.0 ? g->angle : spiral_phi(g, f * g->length), p);
        return;
    }
    if (!g->is_arc) {
        for (int k = 0; k < 3; k++) p[k] = g->start[k] + f * (g->end[k] - g->start[k]);
        return;
    }
    double v[3], nv[3], phi = f * g->angle, c = cos(phi), s = sin(phi);
    for (int k = 0; k < 3; k++) v[k] = g->start[k] - g->center[k];
    cross(g->normal, v, nv);   /* v ⟂ n: Rodrigues without its n(n·v) term */
    for (int k = 0; k < 3; k++) p[k] = g->center[k] + v[k] * c + nv[k] * s + f * g->rise * g->normal[k];
}

static int segments_build(Track *tr, const Json *root, const char *file, char *err, size_t nerr) {
    const Json *segs = member(root, "segments");
    if (!segs || segs->type != J_ARR || segs->nkids < 1) return fail(err, nerr, "%s: 'segments' must be a non-empty array", file);
    tr->nseg = segs->nkids;
    tr->seg = (Segment *)calloc((size_t)tr->nseg, sizeof(Segment));
    tr->seg_s0 = (double *)malloc(sizeof(double) * (size_t)(tr->nseg + 1));
    if (!tr->seg || !tr->seg_s0) return fail(err, nerr, "%s: out of memory", file);
    tr->seg_s0[0] = 0.0;
    for (int i = 0; i < tr->nseg; i++) {
        const Json *o = &segs->kids[i];
        Segment *g = &tr->seg[i];
        char what[64];
        if (o->type != J_OBJ) return fail(err, nerr, "%s: segments[%d] is not an object", file, i);
        const Json *t = member(o, "type");
        if (!t || t->type != J_STR || (strcmp(t->str, "line") && strcmp(t->str, "arc")))
            return fail(err, nerr, "%s: segments[%d].type must be \"line\" or \"arc\"", file, i);
        g->is_arc = !strcmp(t->str, "arc");
        snprintf(what, sizeof what, "segments[%d].start", i);
        if (numbers(member(o, "start"), g->start, 3, file, what, err, nerr)) return -1;
        snprintf(what, sizeof what, "segments[%d].end", i);
        if (numbers(member(o, "end"), g->end, 3, file, what, err, nerr)) return -1;
        if (!g->is_arc) {
            double d[3] = {g->end[0] - g->start[0], g->end[1] - g->start[1], g->end[2] - g->start[2]};
            g->length = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        } else {
            const Json *an = member(o, "angle"), *ri = member(o, "rise"), *sp = member(o, "spiral");
            snprintf(what, sizeof what, "segments[%d].center", i);
            if (numbers(member(o, "center"), g->center, 3, file, what, err, nerr)) return -1;
            snprintf(what, sizeof what, "segments[%d].normal", i);
            if (numbers(member(o, "normal"), g->normal, 3, file, what, err, nerr)) return -1;
            if (!an || an->type != J_NUM || !(an->num > 0)) return fail(err, nerr, "%s: segments[%d].angle must be a number > 0", file, i);
            g->angle = an->num;
            g->rise = (ri && ri->type == J_NUM) ? ri->num : 0.0;
            if (sp && sp->type != J_NUM) return fail(err, nerr, "%s: segments[%d].spiral must be a number (mm)", file, i);
            g->spiral = sp ? sp->num : 0.0;
            double nn = sqrt(g->normal[0] * g->normal[0] + g->normal[1] * g->normal[1] + g->normal[2] * g->normal[2]);
            if (fabs(nn - 1.0) > 1e-9) return fail(err, nerr, "%s: segments[%d].normal is not a unit vector (|n| = %.12g)", file, i, nn);
            double v[3], r2 = 0, vn = 0;
            for (int k = 0; k < 3; k++) v[k] = g->start[k] - g->center[k], r2 += v[k] * v[k], vn += v[k] * g->normal[k];
            if (!(r2 > 0) || fabs(vn) > 1e-6 * (1 + sqrt(r2)))
                return fail(err, nerr, "%s: segments[%d]: center is not in the plane of start perpendicular to normal", file, i);
            if (g->spiral != 0.0) {
                if (g->angle > 1e6)   /* its arc-length table has a panel per 0.5 rad */
                    return fail(err, nerr, "%s: segments[%d]: a spiral arc's angle %.6g rad exceeds 1e6", file, i, g->angle);
                if (!(sqrt(r2) + g->spiral > 0))
                    return fail(err, nerr, "%s: segments[%d]: end radius %.9g + spiral %.9g mm must be > 0", file, i, sqrt(r2), g->spiral);
                if (spiral_init(g)) return fail(err, nerr, "%s: out of memory", file);
            }
            double e[3];
            seg_point(g, 1.0, e);
            double de = sqrt((e[0] - g->end[0]) * (e[0] - g->end[0]) + (e[1] - g->end[1]) * (e[1] - g->end[1]) + (e[2] - g->end[2]) * (e[2] - g->end[2]));
            if (de > 1e-6) return fail(err, nerr, "%s: segments[%d]: end disagrees with start/center/angle/rise/spiral by %.3g mm", file, i, de);
            if (g->spiral == 0.0) g->length = sqrt(r2 * g->angle * g->angle + g->rise * g->rise);
        }
        if (!(g->length > 0)) return fail(err, nerr, "%s: segments[%d] has zero length", file, i);
        if (i > 0) {
            const double *pe = tr->seg[i - 1].end;
            double gap = sqrt((pe[0] - g->start[0]) * (pe[0] - g->start[0]) + (pe[1] - g->start[1]) * (pe[1] - g->start[1]) + (pe[2] - g->start[2]) * (pe[2] - g->start[2]));
            /* the contract of planners/path.py: 1e-9 mm per unit of the largest coordinate
               (rounding grows with it; a near-straight G64 blend of R = 2400 mm ends 3e-9 mm
               from the next segment's start) */
            double scale = fmax(1.0, fmax(fabs(g->start[0]), fmax(fabs(g->start[1]), fabs(g->start[2]))));
            if (gap > 1e-9 * scale) return fail(err, nerr, "%s: segments[%d] starts %.3g mm away from the end of segments[%d]", file, i, gap, i - 1);
        }
        tr->seg_s0[i + 1] = tr->seg_s0[i] + g->length;
    }
    tr->length = tr->seg_s0[tr->nseg];
    return 0;
}

/* ---- profile ------------------------------------------------------------------------------ */
static int profile_load(Track *tr, const char *file, double T, char *err, size_t nerr) {
    long len;
    char *buf = read_file(file, &len, err, nerr);
    if (!buf) return -1;
    char *line = buf, *next;
    long cap = 0, lineno = 1;
    next = strchr(line, '\n');
    if (next) *next = 0;
    char *cr = strchr(line, '\r');
    if (cr) *cr = 0;
    if (strcmp(line, "t,s,sd,sdd,sddd")) {
        free(buf);
        return fail(err, nerr, "%s:1: header must be 't,s,sd,sdd,sddd'", file);
    }
    tr->nrows = 0;
    while (next) {
        line = next + 1;
        lineno++;
        next = strchr(line, '\n');
        if (next) *next = 0;
        if (!*line || (line[0] == '\r' && !line[1])) continue;
        double v[5];
        char *p = line, *end;
        for (int k = 0; k < 5; k++) {
            errno = 0;
            v[k] = strtod(p, &end);
            if (end == p || errno == ERANGE || !isfinite(v[k])) {
                free(buf);
                return fail(err, nerr, "%s:%ld: column %d is not a finite number", file, lineno, k + 1);
            }
            p = end;
            if (k < 4) {
                if (*p != ',') { free(buf); return fail(err, nerr, "%s:%ld: expected 5 comma-separated numbers", file, lineno); }
                p++;
            }
        }
        while (*p == ' ' || *p == '\r') p++;
        if (*p) { free(buf); return fail(err, nerr, "%s:%ld: trailing characters after 5 numbers", file, lineno); }
        if (tr->nrows == cap) {
            cap = cap ? 2 * cap : 1024;
            double *a = (double *)realloc(tr->ps, sizeof(double) * (size_t)cap), *b;
            if (a) tr->ps = a;
            b = (double *)realloc(tr->psd, sizeof(double) * (size_t)cap);
            if (b) tr->psd = b;
            if (!a || !b) { free(buf); return fail(err, nerr, "%s: out of memory", file); }
        }
        long k = tr->nrows;
        if (fabs(v[0] - k * T) > 1e-9 * (1.0 + k * T)) {
            free(buf);
            return fail(err, nerr, "%s:%ld: t = %.17g but row %ld of a profile at T = %.17g s must be at %.17g",
                        file, lineno, v[0], k, T, k * T);
        }
        if (k > 0 && v[1] < tr->ps[k - 1] - 1e-12) {
            free(buf);
            return fail(err, nerr, "%s:%ld: the profile runs backwards (s %.17g → %.17g mm)", file, lineno, tr->ps[k - 1], v[1]);
        }
        tr->ps[k] = v[1];
        tr->psd[k] = v[2];
        tr->nrows++;
    }
    free(buf);
    if (tr->nrows < 1) return fail(err, nerr, "%s: no profile rows", file);
    if (fabs(tr->ps[0]) > 1e-9) return fail(err, nerr, "%s:2: the profile starts at s = %.17g mm, not 0", file, tr->ps[0]);
    if (tr->ps[tr->nrows - 1] > tr->length + 1e-9)
        return fail(err, nerr, "%s: the profile goes to s = %.17g mm, beyond the path length %.17g mm", file,
                    tr->ps[tr->nrows - 1], tr->length);
    tr->period = T;
    return 0;
}

/* ---- public --------------------------------------------------------------------------------- */
void track_free(Track *tr) {
    if (!tr) return;
    for (int i = 0; tr->seg && i < tr->nseg; i++) free(tr->seg[i].sp_S);
    free(tr->knots), free(tr->cw), free(tr->tab_u), free(tr->tab_s), free(tr->seg), free(tr->seg_s0);
    free(tr->ps), free(tr->psd);
    free(tr);
}

Track *track_load(const char *path_file, const char *profile_file, double T, char *err, size_t nerr) {
    Track *tr = (Track *)calloc(1, sizeof(Track));
    long len;
    char *buf = tr ? read_file(path_file, &len, err, nerr) : NULL;
    if (!buf) { track_free(tr); return NULL; }
    Json root;
    memset(&root, 0, sizeof root);
    Parser P = {buf, 0, len, err, nerr, path_file, 0};
    int rc = parse_value(&P, &root);
    if (!rc) {
        skip_ws(&P);
        if (P.pos != P.len) rc = perr(&P, "trailing characters after the JSON value");
    }
    if (!rc) {
        const Json *type = root.type == J_OBJ ? member(&root, "type") : NULL;
        if (!type || type->type != J_STR) rc = fail(err, nerr, "%s: not a path: missing \"type\"", path_file);
        else if (!strcmp(type->str, "nurbs")) tr->is_nurbs = 1, rc = nurbs_build(tr, &root, path_file, err, nerr);
        else if (!strcmp(type->str, "segments")) rc = segments_build(tr, &root, path_file, err, nerr);
        else rc = fail(err, nerr, "%s: unknown path type \"%s\" (valid: nurbs, segments)", path_file, type->str);
    }
    json_free(&root);
    free(buf);
    if (!rc) rc = profile_load(tr, profile_file, T, err, nerr);
    if (rc) { track_free(tr); return NULL; }
    return tr;
}

void track_point(const Track *tr, double s, double p[3], double *u, long *hint, double *residual) {
    if (s < 0) s = 0;
    if (s > tr->length) s = tr->length;
    if (!tr->is_nurbs) {
        long i = *hint;
        if (i < 0 || i >= tr->nseg) i = 0;
        while (i > 0 && s < tr->seg_s0[i]) i--;
        while (i < tr->nseg - 1 && s > tr->seg_s0[i + 1]) i++;
        *hint = i;
        const Segment *g = &tr->seg[i];
        double f = (s - tr->seg_s0[i]) / g->length;
        if (g->spiral != 0.0) spiral_point(g, spiral_phi(g, s - tr->seg_s0[i]), p);
        else seg_point(g, f, p);
        *u = i + f;
        *residual = 0.0;
        return;
    }
    long j = *hint;   /* the profile is monotone: walk the table from the last interval */
    if (j < 0 || j >= tr->ntab) j = 0;
    while (j > 0 && s < tr->tab_s[j]) j--;
    while (j < tr->ntab - 1 && s > tr->tab_s[j + 1]) j++;
    *hint = j;
    double a = tr->tab_u[j], b = tr->tab_u[j + 1], sa = tr->tab_s[j], sb = tr->tab_s[j + 1];
    /* Predictor: Newton's first step from the previous u is the first-order Taylor step
     * Δs/|C'(u)| (TII 2022's interpolator is the second-order form of it); a linear guess in
     * the table interval when the previous u is elsewhere. Corrector: Newton on S(u) − s with
     * the Gauss–Legendre integral, safeguarded by bisection. */
    double lo = a, hi = b, f = 0.0;
    double x = (*u > a && *u < b) ? *u : (sb > sa ? a + (b - a) * (s - sa) / (sb - sa) : a);
    for (int it = 0; it < 50; it++) {
        f = sa + arc4(tr, a, x) - s;
        if (fabs(f) < 1e-11) break;   /* 0.01 nm */
        if (f > 0) hi = x; else lo = x;
        double d = speed(tr, x), xn = d > 0 ? x - f / d : 0.5 * (lo + hi);
        x = (xn > lo && xn < hi) ? xn : 0.5 * (lo + hi);
    }
    double dC[3];
    nurbs_eval(tr, x, p, dC);
    *u = x;
    *residual = fabs(f);
}
