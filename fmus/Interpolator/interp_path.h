/* Toolpaths and feed profiles for Interpolator.fmu: parsing and arc-length evaluation. */
#ifndef INTERP_PATH_H
#define INTERP_PATH_H

#include <stddef.h>

typedef struct {
    int is_arc;
    double start[3], end[3];
    double center[3], normal[3], angle, rise;   /* arcs (DESIGN.md / planners/path.py contract) */
    double spiral;                             /* r_end − r_start (mm); 0: a circle or helix */
    double length;
    /* a spiral arc's arc-length table (spiral.c): start radius, dr/dφ, k² + (rise/θ)², panels */
    double sp_r0, sp_k, sp_c2, *sp_S;
    int sp_npanel;
} Segment;

typedef struct Track {
    /* path */
    int is_nurbs;
    int degree, ncp;
    double *knots, *cw;        /* cw: 4 per control point (w·x, w·y, w·z, w) */
    long ntab;                 /* arc-length table: ntab + 1 nodes */
    double *tab_u, *tab_s;
    int nseg;
    Segment *seg;
    double *seg_s0;
    double length;
    /* profile */
    long nrows;
    double *ps, *psd;
    double period;
} Track;

/* Each returns NULL on error, with a message naming the file and the problem in err. */
Track *track_load(const char *path_file, const char *profile_file, double T, char *err, size_t nerr);
void track_free(Track *tr);

/* Point at arc length s (clamped to [0, length]); *u = curve parameter (segments: index +
 * fraction); *hint = table interval to start searching from (updated); *residual = |S(u) − s|. */
void track_point(const Track *tr, double s, double p[3], double *u, long *hint, double *residual);

#endif
