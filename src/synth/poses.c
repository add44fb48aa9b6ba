/* The procedural pose set: ten joint-angle poses of the Kinect v1 skeleton, applied by forward
 * kinematics and km_lbs. Subjects posed with the same angles are the ground truth for pose
 * transfer tests and benchmarks. */
#include "synth/poses.h"

#include <math.h>
#include <string.h>

/* Ten classes. Arm rest direction: left +x, right -x. About z, +deg lifts the left arm and
 * lowers the right one; about x, -deg swings a leg forward (+z), +deg bends a knee back. */
const kp_pose kp_poses[KP_N_POSES] = {
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
void kp_transforms(const km_skeleton *s, const kp_pose *p, const double *jitter, double *T,
                   double *posed_joints) {
  size_t n = s->n_joints < KM_KINECT1_JOINTS ? s->n_joints : KM_KINECT1_JOINTS;
  double L[KM_KINECT1_JOINTS][9], o[KM_KINECT1_JOINTS][3], G[KM_KINECT1_JOINTS][9],
      P[KM_KINECT1_JOINTS][3];
  for (size_t j = 0; j < n; ++j) {
    km__m3_identity(L[j]);
    for (int k = 0; k < p->n; ++k)
      if (p->r[k].joint == (int)j) {
        double R[9];
        kp_axis_angle(p->r[k].axis, p->r[k].deg * (1 + (jitter ? jitter[k] : 0)), R);
        km__m3_mul(L[j], R, L[j]);
      }
    int pa = s->parents[j];
    const double *rj = s->rest + 3 * j;
    for (int i = 0; i < 3; ++i)
      o[j][i] = pa < 0 ? rj[i] : rj[i] - s->rest[3 * pa + i];
  }
  km__forward_kinematics(n, s->parents, L[0], o[0], G[0], P[0]);
  km__joint_transforms(n, G[0], P[0], s->rest, T);
  if (posed_joints) memcpy(posed_joints, P, n * 3 * sizeof(double));
}

km_status kp_pose_character(const km_character *c, const kp_pose *p, const double *jitter,
                            double *V, km_error *err) {
  double T[KM_KINECT1_JOINTS * 12];
  kp_transforms(&c->skeleton, p, jitter, T, NULL);
  return km_lbs(c->mesh.V, c->mesh.n_vertices, &c->skin, T, c->skeleton.n_joints, V, err);
}

const char *km_pose_preset_name(int p) {
  return p >= 0 && p < KP_N_POSES ? kp_poses[p].name : NULL;
}

km_status km_character_pose_preset(const km_character *c, int p, const double *jitter, double *V,
                                   km_error *err) {
  if (!c || !V) return km__fail(err, KM_ERR_INVALID, "km_character_pose_preset: NULL argument");
  if (p < 0 || p >= KP_N_POSES)
    return km__fail(err, KM_ERR_INVALID, "km_character_pose_preset: pose %d, expected 0..%d", p,
                    KP_N_POSES - 1);
  return kp_pose_character(c, &kp_poses[p], jitter, V, err);
}
