/* Interpolator.fmu: replays a feed profile s(t) along a toolpath (NURBS or lines/arcs). */
#ifndef INTERPOLATOR_CONFIG_H
#define INTERPOLATOR_CONFIG_H

#include <stdbool.h>

#define MODEL_IDENTIFIER "Interpolator"
#define INSTANTIATION_TOKEN "{2f7a9c41-5d0e-4b3a-9e6f-8c1d2b4a7e02}"

typedef enum {
    vr_T = 1,                                                  /* Real parameter, s */
    vr_x = 10, vr_y, vr_z, vr_s, vr_u, vr_feed, vr_feed_error, /* Real outputs */
    vr_path_file = 100, vr_profile_file,                       /* String parameters */
    vr_done = 200                                              /* Boolean output */
} ValueReference;

struct Track;   /* the parsed path and profile (interp_path.c); read-only after initialisation */

typedef struct {
    double T;
    char path_file[1024], profile_file[1024];
    double x, y, z, s, u, feed, feed_error;
    bool done;
    long row;              /* profile row of the current outputs */
    long hint;             /* arc-length table interval of the last point (search start) */
    double residual;       /* arc-length residual of the last point, mm */
    struct Track *track;
} ModelData;

#endif
