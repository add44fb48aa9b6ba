/* Requires: core, linalg, math, mesh, motion. */
/* Automatic rigging of a mesh kinemesh did not make (km_autorig): extremities by geodesic
 * extremes, a Kinect v1 skeleton embedded from height-normalised slices and geodesic rings,
 * distance-to-bone skin weights, the 16 named landmarks. Its public API is in
 * include/kinemesh.h (section autorig); nothing here is private yet. */
#ifndef KM_AUTORIG_AUTORIG_H
#define KM_AUTORIG_AUTORIG_H

#include "core/core.h"

#endif
