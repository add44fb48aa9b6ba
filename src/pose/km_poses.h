/* Joint-angle pose sets for the procedural character (tests and bench): forward kinematics
 * on the Kinect v1 skeleton, then km_lbs. Subjects posed with the same angles are the
 * ground truth for pose transfer. Character frame: y up, facing +z, left = +x, T-pose. */
#ifndef KM_POSES_H
#define KM_POSES_H

#include "kinemesh.h"

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

#define KP_MAX_ROTS 8
typedef struct kp_pose {
  const char *name;
  kp_rot r[KP_MAX_ROTS];
  int n;
} kp_pose;

/* Ten classes. Arm rest direction: left +x, right -x. About z, +deg lifts the left arm and
 * lowers the right one; about x, -deg swings a leg forward (+z), +deg bends a knee back. */
static const kp_pose kp_poses[] = {
    {"t_pose", {{0}}, 0},
    {"a_pose", {{KP_SHL, 2, -45}, {KP_SHR, 2, 45}}, 2},
    {"arms_up", {{KP_SHL, 2, 80}, {KP_SHR, 2, -80}}, 2},
    {"squat",
     {{KP_HIPL, 0, -80},
      {KP_HIPR, 0, -80},
      {KP_KNL, 0, 100},
      {KP_KNR, 0, 100},
      {KP_SHL, 1, -80},
      {KP_SHR, 1, 80}},
     6},
    {"kick", {{KP_HIPR, 0, -80}, {KP_SHL, 2, -30}, {KP_SHR, 2, 30}}, 3},
    {"punch", {{KP_SHR, 1, 90}, {KP_SHL, 2, -60}, {KP_ELL, 1, -90}}, 3},
    {"wave", {{KP_SHR, 2, -70}, {KP_ELR, 2, -60}, {KP_SHL, 2, -60}}, 3},
    {"sit",
     {{KP_HIPL, 0, -90},
      {KP_HIPR, 0, -90},
      {KP_KNL, 0, 90},
      {KP_KNR, 0, 90},
      {KP_SHL, 2, -60},
      {KP_SHR, 2, 60}},
     6},
    {"lunge",
     {{KP_HIPL, 0, -60}, {KP_KNL, 0, 70}, {KP_HIPR, 0, 25}, {KP_SHL, 2, -50}, {KP_SHR, 2, 50}},
     5},
    {"bow", {{KP_SPINE, 0, 50}, {KP_SHL, 2, -70}, {KP_SHR, 2, 70}}, 3},
};
#define KP_N_POSES ((int)(sizeof kp_poses / sizeof kp_poses[0]))

static void kp_axis_angle(int axis, double deg, double R[9]) {
  double a = deg * M_PI / 180, c = cos(a), s = sin(a);
  memset(R, 0, 9 * sizeof *R);
  if (axis == 0) R[0] = 1, R[4] = c, R[5] = -s, R[7] = s, R[8] = c;
  if (axis == 1) R[4] = 1, R[0] = c, R[2] = s, R[6] = -s, R[8] = c;
  if (axis == 2) R[8] = 1, R[0] = c, R[1] = -s, R[3] = s, R[4] = c;
}

static void kp_mul(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* Per-joint transforms (3x4 row-major) of pose p with every angle scaled by (1 + jitter[k])
 * for rotation k (jitter may be NULL). posed_joints (20*3) may be NULL. */
static void kp_transforms(const km_skeleton *s, const kp_pose *p, const double *jitter, double *T,
                          double *posed_joints) {
  size_t n = s->n_joints;
  double G[KM_KINECT1_JOINTS][9], P[KM_KINECT1_JOINTS][3];
  for (size_t j = 0; j < n && j < KM_KINECT1_JOINTS; ++j) {
    double L[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int k = 0; k < p->n; ++k)
      if (p->r[k].joint == (int)j) {
        double R[9], tmp[9];
        kp_axis_angle(p->r[k].axis, p->r[k].deg * (1 + (jitter ? jitter[k] : 0)), R);
        kp_mul(L, R, tmp);
        memcpy(L, tmp, sizeof L);
      }
    int pa = s->parents[j];
    const double *rj = s->rest + 3 * j;
    if (pa < 0) {
      memcpy(G[j], L, sizeof L);
      memcpy(P[j], rj, 3 * sizeof(double));
    } else {
      kp_mul(G[pa], L, G[j]);
      const double *rp = s->rest + 3 * pa;
      double d[3] = {rj[0] - rp[0], rj[1] - rp[1], rj[2] - rp[2]};
      for (int i = 0; i < 3; ++i)
        P[j][i] =
            P[pa][i] + G[pa][3 * i] * d[0] + G[pa][3 * i + 1] * d[1] + G[pa][3 * i + 2] * d[2];
    }
    double *t = T + 12 * j;
    for (int i = 0; i < 3; ++i) {
      t[4 * i] = G[j][3 * i], t[4 * i + 1] = G[j][3 * i + 1], t[4 * i + 2] = G[j][3 * i + 2];
      t[4 * i + 3] =
          P[j][i] - (G[j][3 * i] * rj[0] + G[j][3 * i + 1] * rj[1] + G[j][3 * i + 2] * rj[2]);
    }
    if (posed_joints) memcpy(posed_joints + 3 * j, P[j], 3 * sizeof(double));
  }
}

/* Character c in pose p (jitter as above) into V (#V*3). */
static km_status kp_pose_character(const km_character *c, const kp_pose *p, const double *jitter,
                                   double *V, km_error *err) {
  double T[KM_KINECT1_JOINTS * 12];
  kp_transforms(&c->skeleton, p, jitter, T, NULL);
  return km_lbs(c->mesh.V, c->mesh.n_vertices, &c->skin, T, c->skeleton.n_joints, V, err);
}

/* Mean and max vertex distance. */
static void kp_error(const double *A, const double *B, size_t n, double *mean, double *max) {
  double s = 0, m = 0;
  for (size_t v = 0; v < n; ++v) {
    double d = sqrt((A[3 * v] - B[3 * v]) * (A[3 * v] - B[3 * v]) +
                    (A[3 * v + 1] - B[3 * v + 1]) * (A[3 * v + 1] - B[3 * v + 1]) +
                    (A[3 * v + 2] - B[3 * v + 2]) * (A[3 * v + 2] - B[3 * v + 2]));
    s += d;
    if (d > m) m = d;
  }
  *mean = n ? s / (double)n : 0;
  *max = m;
}

#endif
