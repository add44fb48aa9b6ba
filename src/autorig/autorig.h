/* Requires: core, linalg, math, mesh, motion, recon. */
/* Automatic rigging of a mesh kinemesh did not make (km_autorig): extremities by geodesic
 * extremes, a Kinect v1 skeleton embedded from height-normalised slices and geodesic rings,
 * distance-to-bone skin weights, the 16 named landmarks. Its public API is in
 * include/kinemesh.h (section autorig). */
#ifndef KM_AUTORIG_AUTORIG_H
#define KM_AUTORIG_AUTORIG_H

#include "core/core.h"

/* The 16 landmarks of km_autorig for a given Kinect v1 skeleton (J: 20*3 positions) and the
 * tip vertices of the left hand, right hand, left foot and right foot (from_skin.c). */
km_status km__autorig_landmarks(const km_mesh *m, const double *J, const int32_t tips[4],
                                km_landmark *lm, km_error *err);

#endif
