/* Requires: core, math, mesh. External: cJSON. */
/* Private helpers of the motion module. */
#ifndef KM_MOTION_H
#define KM_MOTION_H

#include "core/core.h"

#include <stdio.h>

/* The 20 Kinect v1 joints in km_kinect1 order (KM_KINECT1_JOINTS), for skeleton arrays
 * (20*3) in the modules above: one enum for autorig and synth. */
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
  J_FOOT_R,
};

/* The Kinect v1 joint a bone name of a game or DCC rig stands for, by naming convention rather
 * than by a table (skeleton_names.c holds the tables): Mixamo ("mixamorig:LeftForeArm"), VRM /
 * Unity humanoid ("LeftLowerArm"), VRoid ("J_Bip_L_LowerArm"), rigify ("DEF-forearm.L"), 3ds
 * Max Biped ("Bip01 L Forearm"), Blender ("forearm.L"): the side from a prefix or suffix, the
 * rest against the limb words (upper arm -> Shoulder, forearm -> Elbow, hand -> Wrist, middle
 * finger base -> Hand, thigh -> Hip, shin -> Knee, foot -> Ankle, toe -> Foot; hips / pelvis ->
 * HipCenter, neck -> ShoulderCenter, head, spine -> Spine). -1: no match. */
int km__bone_name_kinect1(const char *name);

/* Heap-copies a string (NULL on failure). */
char *km__strdup(const char *s);

/* Allocates a skin of n vertices (KM_SKIN_INFLUENCES joints and weights each, uninitialised). */
km_status km__skin_alloc(km_skin *s, size_t n, km_error *err);

/* Column of each Kinect v1 joint among names (by exact name; when most names are of another
 * skeleton, km_skeleton_detect, by body point through km_skeleton_joint_source), -1 when
 * absent; returns how many were found. Shared by km_motion_read (kinect1 takes) and km_puppetry
 * (kinect1 rigs). */
int km__kinect1_columns(const char *const *names, size_t n_names, int src[KM_KINECT1_JOINTS]);
/* The one landmark reader (sidecar.c), for rig sidecars and landmark files alike: the
 * "landmarks" array of the JSON text data (size bytes; path names the file in errors), each
 * {"name": string, "vertex": integer, "mirror": string (optional: itself)}. At most capacity
 * entries (more: KM_ERR_PARSE); n_vertices > 0 bounds the vertex ids; names must be unique.
 * Mirrors are not matched here (km__landmark_mirrors in transfer does that). */
km_status km__landmarks_parse(const char *path, const char *data, size_t size, size_t n_vertices,
                              km_landmark *out, size_t capacity, size_t *n, km_error *err);
/* The one landmark writer: the JSON array [{"name":..,"vertex":..,"mirror":..},...] to f. */
void km__landmarks_write_json(FILE *f, const km_landmark *lm, size_t n);
/* The next km_retarget_push is followed at once, not eased by max_step nor held by the bone
 * speed limit (a rig swap replaying the newest frame must land on the current pose, not ease
 * toward it from the reference). */
void km__retarget_settle(km_retarget *r);

/* Smoothing factor of a first-order low-pass with cutoff fc (Hz) over te seconds: the One Euro
 * filter's alpha, 1 / (1 + 1 / (2 pi fc te)). */
double km__one_euro_alpha(double fc, double te);

/* Whether a body's spine (hip centre hc -> shoulder centre sc, y up) is closer to vertical than
 * horizontal; false when either is not finite. */
bool km__spine_upright(const double hc[3], const double sc[3]);
/* Whether a body stands upright as a person does: its spine upright (km__spine_upright) and,
 * where it has hands and knees (hl, hr, kl, kr; NULL: not asked), both hands higher than both
 * knees (y up). A cat sitting up has an upright spine, but its front paws stand on the ground
 * below its haunches: it is a four-legged body sitting, not a person. The rig writer gives a body
 * that is not upright a quadruped's rig, and km_retarget flattens only an upright body's feet. */
bool km__body_upright(const double hc[3], const double sc[3], const double *hl, const double *hr,
                      const double *kl, const double *kr);

#endif
