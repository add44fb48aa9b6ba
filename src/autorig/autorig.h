/* Requires: core, linalg, math, mesh, motion. */
/* Automatic rigging of a mesh kinemesh did not make (km_autorig): extremities by geodesic
 * extremes, a Kinect v1 skeleton embedded from height-normalised slices and geodesic rings,
 * distance-to-bone skin weights, the 16 named landmarks. Its public API is in
 * include/kinemesh.h (section autorig). */
#ifndef KM_AUTORIG_AUTORIG_H
#define KM_AUTORIG_AUTORIG_H

#include "core/core.h"

/* The 20 Kinect v1 joints in km_kinect1 order, for the module's skeleton arrays (20*3). */
enum {
  J_HIP_C = 0,
  J_SPINE,
  J_SHOULDER_C,
  J_HEAD,
  J_SHOULDER_L,
  J_ELBOW_L,
  J_WRIST_L,
  J_HAND_L,
  J_SHOULDER_R,
  J_ELBOW_R,
  J_WRIST_R,
  J_HAND_R,
  J_HIP_L,
  J_KNEE_L,
  J_ANKLE_L,
  J_FOOT_L,
  J_HIP_R,
  J_KNEE_R,
  J_ANKLE_R,
  J_FOOT_R
};

/* The 16 landmarks of km_autorig for a given Kinect v1 skeleton (J: 20*3 positions) and the
 * tip vertices of the left hand, right hand, left foot and right foot (from_skin.c). */
km_status km__autorig_landmarks(const km_mesh *m, const double *J, const int32_t tips[4],
                                km_landmark *lm, km_error *err);

#endif
