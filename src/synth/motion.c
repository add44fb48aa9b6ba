/* Procedural motion for the 20-joint Kinect v1 skeleton: walk, wave and a kung-fu routine.
 *
 * The rest skeleton is in metres, y up, facing +z, feet near y = 0, arms along +-x (T-pose).
 * Each frame sets a local rotation Q_j per joint from a few angles (smooth functions of time)
 * and runs forward kinematics: W_j = W_parent Q_j and p_c = p_j + W_j (rest_c - rest_j) for
 * each child c, so every bone keeps its rest length exactly. Q_j turns the bone(s) below j,
 * matching the skinning convention of lbs.c. Finally the body is shifted vertically so the
 * lowest foot joint sits where it sits at rest (the stance foot stays on the ground).
 *
 * Angle conventions (degrees in the tables, local frames = rest world axes):
 *  arm:  Q_shoulder = Ry(-s*cross) Rx(-pitch) Rz(-s*down): down 0 = T-pose, 90 = hanging;
 *        pitch then swings the arm forward (pitch 90 with down 90 = pointing forward);
 *        cross brings it across the chest. Q_elbow = Rz(s*up) Ry(-s*flex): flex bends the
 *        forearm forward (a hinge), up bends it towards +y in the T-pose frame (waving).
 *  leg:  Q_hip = Rz(s*abd) Rx(-flex): flex forward, abd outwards; Q_knee = Rx(knee) bends
 *        the shin back; Q_ankle = Rx(ankle) points the toes down.
 *  s is +1 on the side whose limb points to +x at rest, -1 on the other (read from rest). */
#include "core/core.h"
#include "math/math.h"
#include "motion/motion.h"

#include <stdlib.h>
#include <string.h>

enum { NJ = KM_KINECT1_JOINTS };

#define DEG (M_PI / 180.0)
/* Seconds the take holds the rest pose, then blends into the motion (smoothstep). */
#define KM__LEAD_HOLD 0.2
#define KM__LEAD_BLEND 0.5

typedef struct arm_pose {
  double down, pitch, cross, flex, up;
} arm_pose;
typedef struct leg_pose {
  double flex, abd, knee, ankle;
} leg_pose;
/* One full-body pose. Angles in degrees, root offsets in metres. */
typedef struct body_pose {
  double dx, dz; /* root offset on the ground plane */
  double yaw;    /* whole-body turn about +y */
  double spine_pitch, spine_yaw, spine_roll;
  double neck_pitch;
  arm_pose arm[2]; /* 0 left, 1 right */
  leg_pose leg[2];
} body_pose;

/* lerp_pose walks the pose as an array of doubles. */
_Static_assert(sizeof(body_pose) == 25 * sizeof(double), "body_pose holds only doubles");

static void lerp_pose(const body_pose *a, const body_pose *b, double u, body_pose *o) {
  const double *pa = (const double *)a, *pb = (const double *)b;
  double *po = (double *)o;
  for (size_t i = 0; i < sizeof *o / sizeof(double); ++i)
    po[i] = pa[i] + u * (pb[i] - pa[i]);
}

/* ---------------------------------------------------------------- the three motions */

static void walk_pose(double t, double leg_length, body_pose *p) {
  const double T = 1.1, A = 25; /* cycle (s), hip swing amplitude (deg) */
  double ph = 2 * M_PI * t / T;
  memset(p, 0, sizeof *p);
  for (int side = 0; side < 2; ++side) {
    double ps = ph + side * M_PI;
    double swing = fmax(0, cos(ps + M_PI / 6));
    p->leg[side] = (leg_pose){.flex = A * sin(ps),
                              .abd = 2,
                              .knee = 5 + 55 * swing * swing * swing,
                              .ankle = 8 * sin(ps - 0.5)};
    /* Arms swing against the leg of the same side. */
    p->arm[side] = (arm_pose){.down = 78, .pitch = -22 * sin(ps), .flex = 18 + 10 * sin(ps + M_PI)};
  }
  p->yaw = -4 * sin(ph);
  p->spine_yaw = 6 * sin(ph);
  p->spine_pitch = 4;
  p->spine_roll = 1.5 * sin(2 * ph);
  p->neck_pitch = -2;
  /* Speed from the step length 2 L sin A per half cycle, so the feet barely slide. */
  p->dz = 4 * leg_length * sin(A * DEG) / T * t;
}

static void wave_pose(double t, body_pose *p) {
  memset(p, 0, sizeof *p);
  double w = 2 * M_PI * 1.6 * t; /* waving at 1.6 Hz */
  double sway = 2 * M_PI * 0.35 * t;
  double ease = t < 0.6 ? 0.5 - 0.5 * cos(M_PI * t / 0.6) : 1; /* raise the arm first */
  p->arm[1] = (arm_pose){.down = 80 + ease * (-25 + 6 * sin(sway) - 80),
                         .pitch = 12 * ease,
                         .flex = 8,
                         .up = ease * (95 + 28 * sin(w))};
  p->arm[0] = (arm_pose){.down = 80 + 3 * sin(sway), .pitch = 4 * sin(sway), .flex = 15};
  p->spine_roll = 3 * sin(sway);
  p->spine_yaw = 5 * sin(0.5 * sway);
  p->yaw = 6 * sin(0.5 * sway);
  p->neck_pitch = 4 * sin(w * 0.25);
  p->leg[0] = (leg_pose){.flex = 3, .abd = 4 + 3 * sin(sway), .knee = 6 + 4 * sin(sway)};
  p->leg[1] = (leg_pose){.flex = 3, .abd = 4 - 3 * sin(sway), .knee = 6 - 4 * sin(sway)};
}

/* Kung-fu: key poses held together by smoothstep blends, 0.42 s per move, looping. */
#define GUARD_L                                                                                    \
  { .down = 80, .pitch = 55, .cross = 10, .flex = 115 }
#define GUARD_R                                                                                    \
  { .down = 80, .pitch = 55, .cross = 10, .flex = 115 }
#define STANCE_L                                                                                   \
  { .flex = 20, .abd = 14, .knee = 38, .ankle = -8 }
#define STANCE_R                                                                                   \
  { .flex = 20, .abd = 14, .knee = 38, .ankle = -8 }
static const body_pose k_kungfu[] = {
    /* ready stance */
    {.arm = {GUARD_L, GUARD_R}, .leg = {STANCE_L, STANCE_R}, .spine_pitch = 6},
    /* left jab */
    {.arm = {{.down = 90, .pitch = 88, .cross = 6, .flex = 0}, GUARD_R},
     .leg = {{.flex = 35, .abd = 10, .knee = 45}, {.flex = -12, .abd = 12, .knee = 20}},
     .spine_yaw = -18,
     .spine_pitch = 8,
     .dz = 0.12},
    /* right cross */
    {.arm = {GUARD_L, {.down = 90, .pitch = 90, .cross = 10, .flex = 0}},
     .leg = {{.flex = 30, .abd = 10, .knee = 40},
             {.flex = -15, .abd = 12, .knee = 15, .ankle = 20}},
     .spine_yaw = 28,
     .spine_pitch = 10,
     .dz = 0.15},
    /* chamber the right knee */
    {.arm = {GUARD_L, GUARD_R},
     .leg = {{.flex = 5, .abd = 5, .knee = 20}, {.flex = 95, .knee = 115, .ankle = 30}},
     .spine_pitch = -4,
     .dz = 0.1},
    /* right front kick */
    {.arm = {{.down = 70, .pitch = 30, .flex = 100}, {.down = 60, .pitch = -20, .flex = 60}},
     .leg = {{.flex = 0, .abd = 5, .knee = 15}, {.flex = 100, .knee = 5, .ankle = 35}},
     .spine_pitch = -12,
     .dz = 0.1},
    /* land in a wide horse stance, double punch to the sides */
    {.arm = {{.down = 5, .flex = 0}, {.down = 5, .flex = 0}},
     .leg = {{.flex = 45, .abd = 32, .knee = 75, .ankle = -15},
             {.flex = 45, .abd = 32, .knee = 75, .ankle = -15}},
     .spine_pitch = 6},
    /* spin, arms open */
    {.arm = {{.down = 15, .pitch = 10, .flex = 20}, {.down = 15, .pitch = 10, .flex = 20}},
     .leg = {{.flex = 10, .abd = 8, .knee = 20}, {.flex = 10, .abd = 8, .knee = 20}},
     .yaw = 180,
     .spine_pitch = 2},
    /* finish the turn into a left side kick */
    {.arm = {{.down = 25, .pitch = 5, .flex = 10}, GUARD_R},
     .leg = {{.flex = 15, .abd = 80, .knee = 10, .ankle = 20}, {.flex = 10, .abd = 5, .knee = 25}},
     .yaw = 360,
     .spine_roll = 25},
    /* crane: left knee high, arms raised like wings */
    {.arm = {{.down = -60, .pitch = 20, .flex = 35}, {.down = -60, .pitch = 20, .flex = 35}},
     .leg = {{.flex = 100, .abd = 10, .knee = 125, .ankle = 40}, {.flex = 5, .abd = 5, .knee = 10}},
     .yaw = 360,
     .neck_pitch = -10},
    /* lunge forward with a double palm strike */
    {.arm = {{.down = 90, .pitch = 85, .cross = 12, .flex = 5, .up = 20},
             {.down = 90, .pitch = 85, .cross = 12, .flex = 5, .up = 20}},
     .leg = {{.flex = 60, .abd = 8, .knee = 65}, {.flex = -30, .abd = 10, .knee = 10, .ankle = 15}},
     .yaw = 360,
     .spine_pitch = 12,
     .dz = 0.3},
    /* right uppercut from low knees */
    {.arm = {GUARD_L, {.down = 90, .pitch = 150, .cross = 5, .flex = 70}},
     .leg = {{.flex = 30, .abd = 15, .knee = 50}, {.flex = 25, .abd = 15, .knee = 45, .ankle = 10}},
     .yaw = 360,
     .spine_yaw = 22,
     .spine_pitch = 4,
     .dz = 0.15},
    /* deep squat, arms sweeping low */
    {.arm = {{.down = 40, .pitch = 40, .flex = 20}, {.down = 40, .pitch = 40, .flex = 20}},
     .leg = {{.flex = 85, .abd = 22, .knee = 110, .ankle = -25},
             {.flex = 85, .abd = 22, .knee = 110, .ankle = -25}},
     .yaw = 360,
     .spine_pitch = 30,
     .dx = -0.1},
};
#define KUNGFU_KEYS (sizeof k_kungfu / sizeof k_kungfu[0])
#define KUNGFU_MOVE 0.42 /* seconds per move */

static void kungfu_pose(double t, body_pose *p) {
  double x = t / KUNGFU_MOVE;
  size_t i = (size_t)floor(x);
  double u = x - floor(x);
  u = u * u * (3 - 2 * u); /* smoothstep: velocity is continuous at every key */
  size_t cycle = i / KUNGFU_KEYS, k = i % KUNGFU_KEYS, k1 = (k + 1) % KUNGFU_KEYS;
  body_pose a = k_kungfu[k], b = k_kungfu[k1];
  /* The turn accumulates: the last key's 360 continues into the next cycle's 0. */
  a.yaw += 360.0 * (double)cycle;
  b.yaw += 360.0 * (double)(cycle + (k1 == 0));
  lerp_pose(&a, &b, u, p);
}

/* ---------------------------------------------------------------- forward kinematics */

static void rot3(int ax0, double a0, int ax1, double a1, int ax2, double a2, double R[9]) {
  double A[9], B[9], C[9];
  km__m3_axis(ax0, a0 * DEG, A);
  km__m3_axis(ax1, a1 * DEG, B);
  km__m3_axis(ax2, a2 * DEG, C);
  km__m3_mul(A, B, R);
  km__m3_mul(R, C, R);
}

static void pose_to_positions(const double *rest, const double side_arm[2],
                              const double side_leg[2], double foot_rest_min, const body_pose *p,
                              double *out) {
  double Q[NJ][9], W[NJ][9];
  for (int j = 0; j < NJ; ++j)
    km__m3_identity(Q[j]);
  km__m3_axis(1, p->yaw * DEG, Q[J_HIP_C]);
  rot3(1, p->spine_yaw, 0, p->spine_pitch, 2, p->spine_roll, Q[J_SPINE]);
  km__m3_axis(0, p->neck_pitch * DEG, Q[J_SHOULDER_C]);
  static const int shoulder[2] = {J_SHOULDER_L, J_SHOULDER_R}, hip[2] = {J_HIP_L, J_HIP_R};
  for (int side = 0; side < 2; ++side) {
    const arm_pose *a = &p->arm[side];
    double s = side_arm[side];
    rot3(1, -s * a->cross, 0, -a->pitch, 2, -s * a->down, Q[shoulder[side]]);
    double E[9], F[9];
    km__m3_axis(2, s * a->up * DEG, E);
    km__m3_axis(1, -s * a->flex * DEG, F);
    km__m3_mul(E, F, Q[shoulder[side] + 1]);
    const leg_pose *l = &p->leg[side];
    double sl = side_leg[side];
    double Z[9], X[9];
    km__m3_axis(2, sl * l->abd * DEG, Z);
    km__m3_axis(0, -l->flex * DEG, X);
    km__m3_mul(Z, X, Q[hip[side]]);
    km__m3_axis(0, l->knee * DEG, Q[hip[side] + 1]);
    km__m3_axis(0, l->ankle * DEG, Q[hip[side] + 2]);
  }
  int32_t parents[NJ];
  for (int j = 0; j < NJ; ++j) { /* offsets from the parent, positions after the FK */
    int par = parents[j] = km_kinect1_joint_parent(j);
    for (int i = 0; i < 3; ++i)
      out[3 * j + i] = par < 0 ? rest[3 * j + i] : rest[3 * j + i] - rest[3 * par + i];
  }
  out[3 * J_HIP_C] += p->dx;
  out[3 * J_HIP_C + 2] += p->dz;
  km__forward_kinematics(NJ, parents, Q[0], out, W[0], out);
  static const int feet[4] = {J_ANKLE_L, J_FOOT_L, J_ANKLE_R, J_FOOT_R};
  double lo = INFINITY;
  for (int k = 0; k < 4; ++k)
    lo = fmin(lo, out[3 * feet[k] + 1]);
  for (int j = 0; j < NJ; ++j)
    out[3 * j + 1] += foot_rest_min - lo;
}

static double dist3(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

km_status km_motion_generate(const km_skeleton *s, km_motion_kind kind, size_t frames, km_take *out,
                             km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_motion_generate: out is NULL");
  memset(out, 0, sizeof *out);
  if (!s || !s->rest) return km__fail(err, KM_ERR_INVALID, "km_motion_generate: no rest skeleton");
  if (s->n_joints != KM_KINECT1_JOINTS)
    return km__fail(err, KM_ERR_INVALID,
                    "km_motion_generate: skeleton has %zu joints, expected the 20 Kinect v1 joints",
                    s->n_joints);
  for (int j = 0; j < NJ; ++j) {
    if (s->parents && s->parents[j] != km_kinect1_joint_parent(j))
      return km__fail(err, KM_ERR_INVALID,
                      "km_motion_generate: joint %d (%s) has parent %ld, Kinect v1 has %d", j,
                      km_kinect1_joint_name(j), (long)s->parents[j], km_kinect1_joint_parent(j));
    for (int i = 0; i < 3; ++i)
      if (!isfinite(s->rest[3 * j + i]))
        return km__fail(err, KM_ERR_INVALID, "km_motion_generate: rest joint %d is not finite", j);
  }
  if (frames < 1 || frames > 100000000)
    return km__fail(err, KM_ERR_INVALID, "km_motion_generate: frames must be in 1..1e8, got %zu",
                    frames);
  if (kind != KM_MOTION_WALK && kind != KM_MOTION_WAVE && kind != KM_MOTION_KUNGFU)
    return km__fail(err, KM_ERR_INVALID, "km_motion_generate: unknown motion kind %d", (int)kind);

  const double *rest = s->rest;
  double side_arm[2], side_leg[2];
  side_arm[0] = rest[3 * J_ELBOW_L] >= rest[3 * J_SHOULDER_L] ? 1 : -1;
  side_arm[1] = rest[3 * J_ELBOW_R] > rest[3 * J_SHOULDER_R] ? 1 : -1;
  side_leg[0] = rest[3 * J_HIP_L] >= rest[3 * J_HIP_C] ? 1 : -1;
  side_leg[1] = rest[3 * J_HIP_R] > rest[3 * J_HIP_C] ? 1 : -1;
  if (side_arm[0] == side_arm[1]) side_arm[0] = 1, side_arm[1] = -1;
  if (side_leg[0] == side_leg[1]) side_leg[0] = 1, side_leg[1] = -1;
  static const int feet[4] = {J_ANKLE_L, J_FOOT_L, J_ANKLE_R, J_FOOT_R};
  double foot_min = INFINITY;
  for (int k = 0; k < 4; ++k)
    foot_min = fmin(foot_min, rest[3 * feet[k] + 1]);
  double leg_length = 0.5 * (dist3(rest + 3 * J_HIP_L, rest + 3 * J_KNEE_L) +
                             dist3(rest + 3 * J_KNEE_L, rest + 3 * J_ANKLE_L) +
                             dist3(rest + 3 * J_HIP_R, rest + 3 * J_KNEE_R) +
                             dist3(rest + 3 * J_KNEE_R, rest + 3 * J_ANKLE_R));

  out->n_frames = frames;
  out->n_joints = NJ;
  out->fps = 30;
  out->joint_names = km__calloc(NJ, sizeof *out->joint_names);
  out->parents = km__malloc(NJ, sizeof *out->parents);
  out->positions = km__malloc(frames * NJ, 3 * sizeof *out->positions);
  if (!out->joint_names || !out->parents || !out->positions) {
    km_take_free(out);
    return km__fail(err, KM_ERR_NOMEM, "km_motion_generate: out of memory for %zu frames", frames);
  }
  for (int j = 0; j < NJ; ++j) {
    const char *nm = km_kinect1_joint_name(j);
    size_t n = strlen(nm) + 1;
    if (!(out->joint_names[j] = malloc(n))) {
      km_take_free(out);
      return km__fail(err, KM_ERR_NOMEM, "km_motion_generate: out of memory");
    }
    memcpy(out->joint_names[j], nm, n);
    out->parents[j] = km_kinect1_joint_parent(j);
  }
  for (size_t f = 0; f < frames; ++f) {
    double t = (double)f / out->fps;
    body_pose p;
    switch (kind) {
    case KM_MOTION_WALK: walk_pose(t, leg_length, &p); break;
    case KM_MOTION_WAVE: wave_pose(t, &p); break;
    default: kungfu_pose(t, &p); break;
    }
    /* Calibration lead-in: a tracked performer starts in the rest pose (puppetry measures joint
     * displacements from the first frame), holds it briefly and blends into the motion. */
    double u = (t - KM__LEAD_HOLD) / KM__LEAD_BLEND;
    if (u < 1) {
      u = u < 0 ? 0 : u * u * (3 - 2 * u);
      body_pose rest_pose;
      memset(&rest_pose, 0, sizeof rest_pose);
      lerp_pose(&rest_pose, &p, u, &p);
    }
    pose_to_positions(rest, side_arm, side_leg, foot_min, &p, out->positions + f * NJ * 3);
  }
  return KM_OK;
}
