/* Humanoid poses as the VMC protocol carries them (issue 15): Unity's left-handed frame to
 * kinemesh's, forward kinematics over the HumanBodyBones hierarchy (the one FK,
 * km__forward_kinematics) and its inverse from joint positions (for `kinemesh vmc send`). */
#include "motion/motion.h"
#include "math/math.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void km_humanoid_unity_convert(double p[3], double q[4]) {
  /* UniVRM's handedness flip (reverse z: p -> (x, y, -z), q -> (-qx, -qy, qz, qw)) followed by
   * a half turn about y (Unity avatars face +z; after the flip they face -z, kinemesh wants
   * +z): together a mirror in x, p -> (-x, y, z), q -> (qx, -qy, -qz, qw). An involution. */
  if (p) p[0] = -p[0];
  if (q) {
    q[1] = -q[1];
    q[2] = -q[2];
  }
}

int km_humanoid_parent(const bool *present, int b) {
  if (b < 0 || b >= KM_HUMANOID_BONES) return -1;
  for (int p = km_skeleton_joint_parent(KM_SKELETON_HUMANOID, b); p >= 0;
       p = km_skeleton_joint_parent(KM_SKELETON_HUMANOID, p))
    if (!present || present[p]) return p;
  return -1;
}

/* Bones in parent-first order (depth in the full hierarchy, then index). */
static void parent_first(int order[KM_HUMANOID_BONES]) {
  int depth[KM_HUMANOID_BONES], n = 0, maxd = 0;
  for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
    int d = 0;
    for (int p = km_skeleton_joint_parent(KM_SKELETON_HUMANOID, b); p >= 0 && d < 64;
         p = km_skeleton_joint_parent(KM_SKELETON_HUMANOID, p))
      ++d;
    depth[b] = d;
    maxd = d > maxd ? d : maxd;
  }
  for (int d = 0; d <= maxd; ++d)
    for (int b = 0; b < KM_HUMANOID_BONES; ++b)
      if (depth[b] == d) order[n++] = b;
}

static void quat_xyzw_to_rot(const double *q, double *R) {
  double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  double wq[4] = {1, 0, 0, 0};
  if (n > 1e-12 && isfinite(n))
    wq[0] = q[3] / n, wq[1] = q[0] / n, wq[2] = q[1] / n, wq[3] = q[2] / n;
  km__rot3_from_quat(wq, R);
}

static void rot_to_quat_xyzw(const double *R, double *q) {
  double wq[4];
  km__quat_from_rot3(R, wq);
  q[0] = wq[1], q[1] = wq[2], q[2] = wq[3], q[3] = wq[0];
}

void km_humanoid_fk(const km_humanoid_pose *pose, double *positions, double *rotations) {
  int order[KM_HUMANOID_BONES], slot[KM_HUMANOID_BONES];
  parent_first(order);
  /* Node 0 is the root; then the present bones, each under its nearest present ancestor. */
  int32_t par[KM_HUMANOID_BONES + 1];
  double L[9 * (KM_HUMANOID_BONES + 1)], o[3 * (KM_HUMANOID_BONES + 1)];
  double W[9 * (KM_HUMANOID_BONES + 1)], P[3 * (KM_HUMANOID_BONES + 1)];
  size_t n = 1;
  par[0] = -1;
  quat_xyzw_to_rot(pose->root + 3, L);
  memcpy(o, pose->root, 3 * sizeof *o);
  for (int i = 0; i < KM_HUMANOID_BONES; ++i) {
    int b = order[i];
    slot[b] = -1;
    if (!pose->present[b]) continue;
    int p = km_humanoid_parent(pose->present, b);
    par[n] = p >= 0 ? slot[p] : 0;
    quat_xyzw_to_rot(pose->bone + 7 * b + 3, L + 9 * n);
    memcpy(o + 3 * n, pose->bone + 7 * b, 3 * sizeof *o);
    slot[b] = (int)n++;
  }
  km__forward_kinematics(n, par, L, o, W, P);
  for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
    int s = slot[b];
    for (int a = 0; a < 3; ++a)
      positions[3 * b + a] = s >= 0 ? P[3 * s + a] : NAN;
    if (rotations)
      for (int a = 0; a < 9; ++a)
        rotations[9 * b + a] = s >= 0 ? W[9 * s + a] : NAN;
  }
}

/* A T-pose in kinemesh's frame (metres, y up, facing +z, the performer's left at +x): only
 * its bone directions matter (the rest of km_skeleton_pose_from_positions). Right side =
 * left mirrored. */
static const double TPOSE_LEFT[KM_HUMANOID_BONES][3] = {
    [0] = {0, 1.0, 0},           [1] = {0.09, 0.95, 0},       [3] = {0.09, 0.52, 0},
    [5] = {0.09, 0.08, 0},       [7] = {0, 1.1, 0},           [8] = {0, 1.25, 0},
    [9] = {0, 1.5, 0},           [10] = {0, 1.6, 0},          [11] = {0.03, 1.45, 0},
    [13] = {0.17, 1.45, 0},      [15] = {0.45, 1.45, 0},      [17] = {0.7, 1.45, 0},
    [19] = {0.09, 0.02, 0.13},   [21] = {0.03, 1.67, 0.08},   [23] = {0, 1.62, 0.05},
    [24] = {0.72, 1.44, 0.03},   [25] = {0.75, 1.44, 0.05},   [26] = {0.77, 1.44, 0.06},
    [27] = {0.79, 1.45, 0.03},   [28] = {0.83, 1.45, 0.03},   [29] = {0.855, 1.45, 0.03},
    [30] = {0.8, 1.45, 0.01},    [31] = {0.845, 1.45, 0.01},  [32] = {0.875, 1.45, 0.01},
    [33] = {0.79, 1.45, -0.01},  [34] = {0.83, 1.45, -0.01},  [35] = {0.855, 1.45, -0.01},
    [36] = {0.775, 1.45, -0.03}, [37] = {0.805, 1.45, -0.03}, [38] = {0.825, 1.45, -0.03},
    [54] = {0, 1.38, 0},
};

static void tpose(int b, double *x) {
  const char *name = km_skeleton_joint_name(KM_SKELETON_HUMANOID, b);
  bool right = !strncmp(name, "Right", 5);
  int src = b;
  if (right) {
    char left[64];
    snprintf(left, sizeof left, "Left%s", name + 5);
    src = km_skeleton_joint_index(KM_SKELETON_HUMANOID, left);
  }
  for (int a = 0; a < 3; ++a)
    x[a] = TPOSE_LEFT[src][a];
  if (right) x[0] = -x[0];
}

km_status km_humanoid_pose_from_positions(const double *positions, km_humanoid_pose *out,
                                          km_error *err) {
  if (!positions || !out)
    return km__fail(err, KM_ERR_INVALID, "km_humanoid_pose_from_positions: NULL argument");
  memset(out, 0, sizeof *out);
  out->root[6] = 1;
  int order[KM_HUMANOID_BONES], slot[KM_HUMANOID_BONES], bone_of[KM_HUMANOID_BONES];
  parent_first(order);
  for (int b = 0; b < KM_HUMANOID_BONES; ++b)
    out->present[b] = km__finite3(positions + 3 * b);
  char *names[KM_HUMANOID_BONES];
  int32_t par[KM_HUMANOID_BONES];
  double rest[3 * KM_HUMANOID_BONES], P[3 * KM_HUMANOID_BONES], T[12 * KM_HUMANOID_BONES];
  size_t n = 0;
  for (int i = 0; i < KM_HUMANOID_BONES; ++i) {
    int b = order[i];
    slot[b] = -1;
    if (!out->present[b]) continue;
    int p = km_humanoid_parent(out->present, b);
    par[n] = p >= 0 ? slot[p] : -1;
    names[n] = (char *)km_skeleton_joint_name(KM_SKELETON_HUMANOID, b);
    tpose(b, rest + 3 * n);
    memcpy(P + 3 * n, positions + 3 * b, 3 * sizeof *P);
    bone_of[n] = b;
    slot[b] = (int)n++;
  }
  if (n == 0) return km__fail(err, KM_ERR_INVALID, "humanoid pose: no bone has a position");
  km_skeleton s = {.n_joints = n, .names = names, .parents = par, .rest = rest};
  km_status st = km_skeleton_pose_from_positions(&s, P, T, err);
  if (st != KM_OK) return st;
  /* World rotation of node k: the 3x3 part of T; local = parent's inverse times it. */
  for (size_t k = 0; k < n; ++k) {
    int b = bone_of[k];
    double R[9], Rp[9], Rl[9], d[3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        R[3 * i + j] = T[12 * k + 4 * i + j];
    const double *pp;
    static const double zero[3] = {0, 0, 0};
    if (par[k] >= 0) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          Rp[3 * i + j] = T[12 * par[k] + 4 * i + j];
      pp = P + 3 * par[k];
    } else {
      km__m3_identity(Rp);
      pp = zero;
    }
    /* Rl = Rp^T R */
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        Rl[3 * i + j] = Rp[i] * R[j] + Rp[3 + i] * R[3 + j] + Rp[6 + i] * R[6 + j];
    km__sub3(P + 3 * k, pp, d);
    km__m3_apply_t(Rp, d, out->bone + 7 * b);
    rot_to_quat_xyzw(Rl, out->bone + 7 * b + 3);
  }
  return KM_OK;
}
