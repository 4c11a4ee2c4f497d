/* Spiral arcs of Interpolator.fmu: an arc whose radius changes linearly with the swept angle
 * (LinuxCNC's G2/G3 whose end radius differs; planners/paths/spiral.py, the same rule). */
#ifndef INTERP_SPIRAL_H
#define INTERP_SPIRAL_H

#include "interp_path.h"

/* The panel table and the length of the spiral arc g (g->spiral != 0); -1 when out of memory. */
int spiral_init(Segment *g);

/* Sweep angle φ at arc length t ∈ [0, g->length] from the arc's start. */
double spiral_phi(const Segment *g, double t);

/* The point at sweep angle φ. */
void spiral_point(const Segment *g, double phi, double p[3]);

#endif
