/* Spiral arcs (planners/paths/spiral.py has the derivation; this is the same rule on the same
 * panels, so the FMU and the Python path give the same s → point to rounding):
 *
 *   P(φ) = c + (1 + kφ/r0)·(v·cos φ + (n × v)·sin φ) + (φ/θ)·rise·n,  v = start − c, r0 = |v|,
 *   k = spiral/θ, ds/dφ = √((r0 + kφ)² + k² + (rise/θ)²);
 *
 * s(φ) by 8-point Gauss–Legendre on panels of ≤ 0.5 rad (a cumulative table at the panel
 * edges), φ(s) by Newton on the same integral from the panel holding s, stopped at 1e-12 mm
 * per mm of length above 1 mm. */
#include "spiral.h"

#include <math.h>
#include <stdlib.h>

#define PANEL_RAD 0.5
#define NEWTON_MAX 30

static const double GL_X[8] = {-0.9602898564975362, -0.7966664774136267, -0.525532409916329, -0.18343464249564978,
                               0.18343464249564978, 0.525532409916329, 0.7966664774136267, 0.9602898564975362};
static const double GL_W[8] = {0.10122853629037706, 0.22238103445337443, 0.3137066458778869, 0.36268378337836166,
                               0.36268378337836166, 0.3137066458778869, 0.22238103445337443, 0.10122853629037706};

static double speed(const Segment *g, double phi) {
    double rho = g->sp_r0 + g->sp_k * phi;
    return sqrt(rho * rho + g->sp_c2);
}

static double quad(const Segment *g, double a, double b) {   /* ∫ₐᵇ ds/dφ dφ inside one panel */
    double mid = 0.5 * (a + b), half = 0.5 * (b - a), s = 0.0;
    for (int i = 0; i < 8; i++) s += GL_W[i] * speed(g, mid + half * GL_X[i]);
    return half * s;
}

static double edge(const Segment *g, int j) {
    return j == g->sp_npanel ? g->angle : j * (g->angle / g->sp_npanel);
}

int spiral_init(Segment *g) {
    double v2 = 0.0, m = g->rise / g->angle;
    for (int k = 0; k < 3; k++) v2 += (g->start[k] - g->center[k]) * (g->start[k] - g->center[k]);
    g->sp_r0 = sqrt(v2);
    g->sp_k = g->spiral / g->angle;
    g->sp_c2 = g->sp_k * g->sp_k + m * m;
    double np = ceil(g->angle / PANEL_RAD);
    g->sp_npanel = np < 1 ? 1 : (int)np;
    g->sp_S = (double *)malloc(sizeof(double) * (size_t)(g->sp_npanel + 1));
    if (!g->sp_S) return -1;
    g->sp_S[0] = 0.0;
    for (int j = 0; j < g->sp_npanel; j++) g->sp_S[j + 1] = g->sp_S[j] + quad(g, edge(g, j), edge(g, j + 1));
    g->length = g->sp_S[g->sp_npanel];
    return 0;
}

double spiral_phi(const Segment *g, double t) {
    const double *S = g->sp_S;
    int lo = 0, hi = g->sp_npanel;            /* the last panel edge j with S[j] ≤ t */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (S[mid] <= t) lo = mid; else hi = mid;
    }
    double a = edge(g, lo), b = edge(g, lo + 1), S0 = S[lo];
    double phi = a + (b - a) * (t - S0) / (S[lo + 1] - S0);   /* s(φ) is nearly linear */
    double tol = 1e-12 * fmax(1.0, g->length);
    for (int it = 0; it < NEWTON_MAX; it++) {
        double f = S0 + quad(g, a, phi) - t;
        if (fabs(f) <= tol) break;
        phi -= f / speed(g, phi);
        phi = phi < a ? a : (phi > b ? b : phi);
    }
    return phi;
}

void spiral_point(const Segment *g, double phi, double p[3]) {
    double v[3], nv[3], c = cos(phi), s = sin(phi), grow = 1.0 + g->sp_k * phi / g->sp_r0, f = phi / g->angle;
    for (int k = 0; k < 3; k++) v[k] = g->start[k] - g->center[k];
    nv[0] = g->normal[1] * v[2] - g->normal[2] * v[1];
    nv[1] = g->normal[2] * v[0] - g->normal[0] * v[2];
    nv[2] = g->normal[0] * v[1] - g->normal[1] * v[0];
    for (int k = 0; k < 3; k++) p[k] = g->center[k] + grow * (v[k] * c + nv[k] * s) + f * g->rise * g->normal[k];
}
