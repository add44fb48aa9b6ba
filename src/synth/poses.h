/* Joint-angle pose sets for the procedural character (tests and bench): forward kinematics
 * on the Kinect v1 skeleton, then km_lbs. Subjects posed with the same angles are the
 * ground truth for pose transfer. Character frame: y up, facing +z, left = +x, T-pose. */
#ifndef KM_POSES_H
#define KM_POSES_H

#include "core/core.h"
#include "math/math.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
  KP_HIPC = 0,
  KP_SPINE,
  KP_SHC,
  KP_HEAD,
  KP_SHL,
  KP_ELL,
  KP_WRL,
  KP_HAL,
  KP_SHR,
  KP_ELR,
  KP_WRR,
  KP_HAR,
  KP_HIPL,
  KP_KNL,
  KP_ANL,
  KP_FOL,
  KP_HIPR,
  KP_KNR,
  KP_ANR,
  KP_FOR
};

/* A rotation of one joint: axis (world axes at rest, 0=x 1=y 2=z) and degrees. */
typedef struct kp_rot {
  int joint, axis;
  double deg;
} kp_rot;

#define KP_MAX_ROTS KM_POSE_PRESET_MAX_ROTATIONS
typedef struct kp_pose {
  const char *name;
  kp_rot r[KP_MAX_ROTS];
  int n;
} kp_pose;

/* The pose set (KP_N_POSES entries; kp_poses[p].name is km_pose_preset_name(p)). */
#define KP_N_POSES KM_POSE_PRESETS
extern const kp_pose kp_poses[KP_N_POSES];

/* Per-joint transforms (3x4 row-major) of pose p with every angle scaled by (1 + jitter[k])
 * for rotation k (jitter may be NULL). posed_joints (20*3) may be NULL. */
void kp_transforms(const km_skeleton *s, const kp_pose *p, const double *jitter, double *T,
                   double *posed_joints);
/* Character c in pose p (jitter as above) into V (#V*3). */
km_status kp_pose_character(const km_character *c, const kp_pose *p, const double *jitter,
                            double *V, km_error *err);
/* Rotation of deg degrees about a coordinate axis (0 x, 1 y, 2 z). */
#define kp_axis_angle(axis, deg, R) km__m3_axis((axis), (deg)*M_PI / 180, (R))
/* Mean and max vertex distance. */
#define kp_error km_vertex_distance_stats

#endif
