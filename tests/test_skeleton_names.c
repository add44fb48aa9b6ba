/* Skeletons by name and humanoid (VMC) poses (issue 15): the tables are trees of the documented
 * sizes, the map between them goes by body point, rigs accept every skeleton's names, a CMU
 * BVH reads as Kinect v1, the Unity conversion is a mirror in x (a Unity avatar's left hand
 * lands on kinemesh's left, +x), and FK of km_humanoid_pose_from_positions gives the
 * positions back. */
#include "km_test.h"
#include "math/math.h"
#include "motion/motion.h"
#include "synth/synth.h"

#include <math.h>
#include <string.h>

static void test_tables(void) {
  const int sizes[KM_SKELETON_KINDS] = {20, 25, 32, 55, 33, 31};
  const char *names[KM_SKELETON_KINDS] = {"kinect1",  "kinect2",   "k4abt",
                                          "humanoid", "mediapipe", "bvh"};
  for (int k = 0; k < KM_SKELETON_KINDS; ++k) {
    CHECK_MSG(km_skeleton_joint_count((km_skeleton_kind)k) == sizes[k], "%s: %d joints", names[k],
              km_skeleton_joint_count((km_skeleton_kind)k));
    CHECK(km_skeleton_kind_from_name(names[k]) == k);
    CHECK(!strcmp(km_skeleton_kind_name((km_skeleton_kind)k), names[k]));
    for (int j = 0; j < sizes[k]; ++j) {
      const char *n = km_skeleton_joint_name((km_skeleton_kind)k, j);
      CHECK(n && km_skeleton_joint_index((km_skeleton_kind)k, n) == j); /* names unique */
      int steps = 0;                                                    /* no cycles */
      for (int p = km_skeleton_joint_parent((km_skeleton_kind)k, j); p >= 0 && steps < 100;
           p = km_skeleton_joint_parent((km_skeleton_kind)k, p))
        ++steps;
      CHECK_MSG(steps < 100, "%s: %s is in a cycle", names[k], n);
      /* a map there and back lands on the same joint */
      for (int t = 0; t < KM_SKELETON_KINDS; ++t) {
        int m = km_skeleton_joint_map((km_skeleton_kind)k, j, (km_skeleton_kind)t);
        if (m >= 0)
          CHECK_MSG(km_skeleton_joint_map((km_skeleton_kind)t, m, (km_skeleton_kind)k) == j,
                    "%s %s -> %s and back", names[k], n, names[t]);
      }
    }
  }
  CHECK(km_skeleton_kind_from_name("kinect3") == -1 && km_skeleton_joint_count(99) == 0);
  /* Kinect v1 and v2 share 20 names, and they map onto each other by name. */
  for (int j = 0; j < 20; ++j) {
    int m = km_skeleton_joint_map(KM_SKELETON_KINECT1, j, KM_SKELETON_KINECT2);
    CHECK(m >= 0 &&
          !strcmp(km_skeleton_joint_name(KM_SKELETON_KINECT2, m), km_kinect1_joint_name(j)) ==
              (strcmp(km_kinect1_joint_name(j), "ShoulderCenter") != 0 &&
               strcmp(km_kinect1_joint_name(j), "HipCenter") != 0 &&
               strcmp(km_kinect1_joint_name(j), "Spine") != 0));
  }
  /* Unity's LeftHand is the wrist; the hand centre is the middle finger's proximal bone. */
  int lh = km_skeleton_joint_index(KM_SKELETON_HUMANOID, "LeftHand");
  CHECK(km_skeleton_joint_map(KM_SKELETON_HUMANOID, lh, KM_SKELETON_KINECT1) == 6);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_HUMANOID, "LeftMiddleProximal") == 7);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_HUMANOID, "Jaw") == -2);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_KINECT1, "NoSuchJoint") == -1);
  /* humanoid LeftShoulder is the clavicle, CMU's LeftShoulder the shoulder joint */
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_HUMANOID, "LeftShoulder") == -2);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_BVH, "LeftShoulder") == 4);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_K4ABT, "HAND_RIGHT") == 11);
  CHECK(km_skeleton_kinect1_joint(KM_SKELETON_MEDIAPIPE, "left_wrist") == 6);
  /* A hand centre driven by the wrist where the source has none (MediaPipe: the index knuckle
   * stands for it; a humanoid stream without fingers: the wrist). */
  bool approx = false;
  int s = km_skeleton_joint_source(KM_SKELETON_KINECT1, 7, KM_SKELETON_MEDIAPIPE, &approx);
  CHECK(s == km_skeleton_joint_index(KM_SKELETON_MEDIAPIPE, "left_index") && !approx);
  s = km_skeleton_joint_source(KM_SKELETON_KINECT1, 14, KM_SKELETON_MEDIAPIPE, &approx);
  CHECK(s == km_skeleton_joint_index(KM_SKELETON_MEDIAPIPE, "left_ankle") && !approx);
  double hum[3 * KM_HUMANOID_BONES], k1[60];
  for (int k = 0; k < 3 * KM_HUMANOID_BONES; ++k)
    hum[k] = NAN;
  hum[3 * lh] = 1, hum[3 * lh + 1] = 2, hum[3 * lh + 2] = 3;
  km_skeleton_convert(KM_SKELETON_HUMANOID, hum, KM_SKELETON_KINECT1, k1);
  CHECK(k1[3 * 7] == 1 && k1[3 * 7 + 1] == 2 && k1[3 * 7 + 2] == 3); /* HandLeft <- wrist */
  CHECK(k1[3 * 6] == 1 && isnan(k1[0]) && isnan(k1[3 * 11]));
  /* MediaPipe has no trunk: the pelvis between the hips, the neck base between the
   * shoulders, the spine between them, the head at the nose */
  double mp[3 * 33], k1m[60];
  for (int k = 0; k < 3 * 33; ++k)
    mp[k] = NAN;
  const double lh_[3] = {0.1, 1.0, 0}, rh_[3] = {-0.1, 1.0, 0.2}, ls_[3] = {0.2, 1.5, 0},
               rs_[3] = {-0.2, 1.5, 0}, nose_[3] = {0, 1.7, 0.1};
  memcpy(mp + 3 * 23, lh_, sizeof lh_);
  memcpy(mp + 3 * 24, rh_, sizeof rh_);
  memcpy(mp + 3 * 11, ls_, sizeof ls_);
  memcpy(mp + 3 * 12, rs_, sizeof rs_);
  memcpy(mp + 3 * 0, nose_, sizeof nose_);
  km_skeleton_convert(KM_SKELETON_MEDIAPIPE, mp, KM_SKELETON_KINECT1, k1m);
  CHECK(k1m[0] == 0 && k1m[1] == 1.0 && k1m[2] == 0.1);   /* HipCenter */
  CHECK(k1m[6] == 0 && k1m[7] == 1.5 && k1m[8] == 0);     /* ShoulderCenter */
  CHECK(k1m[3] == 0 && k1m[4] == 1.25 && k1m[5] == 0.05); /* Spine */
  CHECK(k1m[9] == 0 && k1m[10] == 1.7 && k1m[11] == 0.1); /* Head */
  CHECK(k1m[12] == 0.2 && isnan(k1m[3 * 5]));             /* ShoulderLeft; no elbow sent */
  const char *detect[] = {"Hips", "LeftUpperArm", "LeftHand", "Head"};
  CHECK(km_skeleton_detect(detect, 4, NULL) == KM_SKELETON_HUMANOID);
}

/* A humanoid rig: joint names of the declared skeleton resolve to Kinect v1 joints. */
static void test_rig_names(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(1, 1.0, &m, KM_E));
  const char *rig = "{\"skeleton\":\"humanoid\",\"handles\":[{\"name\":\"a\",\"vertex\":0},"
                    "{\"name\":\"b\",\"vertex\":5}],\"map\":[{\"handle\":\"a\",\"joint\":"
                    "\"LeftMiddleProximal\"},{\"handle\":\"b\",\"joint\":\"RightFoot\","
                    "\"relative_to\":\"Hips\"}]}";
  km_rig r = {0};
  CHECK_OK(km_rig_parse(rig, strlen(rig), "h.rig.json", &m, NULL, 0, &r, KM_E));
  CHECK(r.skeleton == KM_RIG_KINECT1 && r.n_maps == 2);
  if (r.n_maps == 2)
    CHECK(r.maps[0].joint == 7 && r.maps[1].joint == 18 && r.maps[1].relative_to == 1);
  km_rig_free(&r);
  const char *bad = "{\"skeleton\":\"humanoid\",\"handles\":[{\"name\":\"a\",\"vertex\":0}],"
                    "\"map\":[{\"handle\":\"a\",\"joint\":\"Jaw\"}]}";
  CHECK_STATUS(km_rig_parse(bad, strlen(bad), "h.rig.json", &m, NULL, 0, &r, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "'Jaw' has no Kinect v1 counterpart"), "%s",
            km_test_err.message);
  /* a kinect1 rig takes a k4abt name too */
  const char *k4 = "{\"handles\":[{\"name\":\"a\",\"vertex\":0}],"
                   "\"map\":[{\"handle\":\"a\",\"joint\":\"HAND_LEFT\"}]}";
  CHECK_OK(km_rig_parse(k4, strlen(k4), "k.rig.json", &m, NULL, 0, &r, KM_E));
  CHECK(r.n_maps == 1 && r.maps[0].joint == 7);
  km_rig_free(&r);
  km_mesh_free(&m);
}

/* The Unity conversion: a left hand at Unity's -x (the avatar faces +z there) comes out at
 * kinemesh's +x, the performer's left; a rotation keeps its meaning under the mirror. */
static void test_unity_convert(void) {
  double p[3] = {-0.7, 1.4, 0.1}, q[4] = {0.1, 0.2, 0.3, sqrt(1 - 0.14)};
  double q0[4];
  memcpy(q0, q, sizeof q);
  km_humanoid_unity_convert(p, q);
  CHECK(p[0] == 0.7 && p[1] == 1.4 && p[2] == 0.1);
  CHECK(q[0] == 0.1 && q[1] == -0.2 && q[2] == -0.3 && q[3] == q0[3]);
  /* M R_unity M == R_kinemesh for the mirror M = diag(-1, 1, 1): rotate a vector both ways. */
  double Ru[9], Rk[9], v[3] = {0.3, -0.5, 0.8}, vm[3] = {-0.3, -0.5, 0.8}, a[3], b[3];
  double wq0[4] = {q0[3], q0[0], q0[1], q0[2]}, wq[4] = {q[3], q[0], q[1], q[2]};
  km__rot3_from_quat(wq0, Ru);
  km__rot3_from_quat(wq, Rk);
  km__m3_apply(Ru, v, a);
  km__m3_apply(Rk, vm, b);
  CHECK_NEAR(-a[0], b[0], 1e-12);
  CHECK_NEAR(a[1], b[1], 1e-12);
  CHECK_NEAR(a[2], b[2], 1e-12);
  km_humanoid_unity_convert(p, q); /* involution */
  CHECK(p[0] == -0.7 && q[1] == 0.2 && q[2] == 0.3);
}

/* CMU BVH: read as Kinect v1 by body point; its humanoid pose FK's back within 1e-9 m. */
static void test_bvh_humanoid(void) {
  char buf[1024];
  const char *path = km_test_shared("bvh/cmu_131_01.bvh", buf, sizeof buf);
  if (!path) return;
  km_motion_read_options mo = {.kinect1 = true};
  km_motion_read_info info;
  km_take k1 = {0}, t = {0};
  CHECK_OK(km_motion_read(path, &mo, &k1, &info, KM_E));
  CHECK_MSG(info.kinect1_found == 20, "found %zu of the 20 Kinect joints", info.kinect1_found);
  CHECK_OK(km_motion_read(path, NULL, &t, NULL, KM_E));
  int matched = 0;
  CHECK(km_skeleton_detect((const char *const *)t.joint_names, t.n_joints, &matched) ==
        KM_SKELETON_BVH);
  CHECK(matched == 31);
  double hum[3 * KM_HUMANOID_BONES], fk[3 * KM_HUMANOID_BONES], worst = 0;
  int used = 0;
  for (size_t f = 0; f < t.n_frames; f += 7) {
    for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
      int s = km_skeleton_joint_map(KM_SKELETON_HUMANOID, b, KM_SKELETON_BVH);
      for (int a = 0; a < 3; ++a)
        hum[3 * b + a] = s >= 0 ? t.positions[(f * t.n_joints + (size_t)s) * 3 + a] : NAN;
    }
    km_humanoid_pose pose;
    CHECK_OK(km_humanoid_pose_from_positions(hum, &pose, KM_E));
    km_humanoid_fk(&pose, fk, NULL);
    used = 0;
    for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
      if (!pose.present[b]) continue;
      ++used;
      for (int a = 0; a < 3; ++a)
        worst = fmax(worst, fabs(fk[3 * b + a] - hum[3 * b + a]));
    }
  }
  CHECK_MSG(worst < 1e-9, "FK of the pose is %g m off the BVH's joints", worst);
  CHECK_MSG(used >= 18, "%d humanoid bones from the CMU skeleton", used);
  km_take_free(&t);
  km_take_free(&k1);
}

/* Bone names by convention (km__bone_name_kinect1, one matcher for glTF skins, BVH takes and
 * rig files): the CMU take with its joints renamed as Mixamo names them reads as the same
 * Kinect v1 take, and rig entries take Mixamo, VRoid, rigify, Blender and Biped names. */
static const char *const CMU_TO_MIXAMO[][2] = {{"Hips", "Hips"},
                                               {"LHipJoint", "LHipJoint"},
                                               {"LeftHip", "LeftUpLeg"},
                                               {"LeftKnee", "LeftLeg"},
                                               {"LeftAnkle", "LeftFoot"},
                                               {"LeftToe", "LeftToeBase"},
                                               {"RHipJoint", "RHipJoint"},
                                               {"RightHip", "RightUpLeg"},
                                               {"RightKnee", "RightLeg"},
                                               {"RightAnkle", "RightFoot"},
                                               {"RightToe", "RightToeBase"},
                                               {"lowerback", "lowerback"},
                                               {"Chest", "Spine"},
                                               {"Chest2", "Spine1"},
                                               {"lowerneck", "Neck"},
                                               {"Neck", "Neck1"},
                                               {"Head", "Head"},
                                               {"LeftCollar", "LeftShoulder"},
                                               {"LeftShoulder", "LeftArm"},
                                               {"LeftElbow", "LeftForeArm"},
                                               {"LeftWrist", "LeftHand"},
                                               {"lhand", "LeftHandMiddle1"},
                                               {"LFingers", "LeftHandMiddle2"},
                                               {"LThumb", "LeftHandThumb1"},
                                               {"RightCollar", "RightShoulder"},
                                               {"RightShoulder", "RightArm"},
                                               {"RightElbow", "RightForeArm"},
                                               {"RightWrist", "RightHand"},
                                               {"rhand", "RightHandMiddle1"},
                                               {"RFingers", "RightHandMiddle2"},
                                               {"RThumb", "RightHandThumb1"}};

static void test_bone_names(void) {
  static const struct {
    const char *name;
    int joint;
  } cases[] = {
      {"mixamorig:LeftForeArm", 5},
      {"mixamorig:RightUpLeg", 16},
      {"J_Bip_L_UpperArm", 4},
      {"J_Bip_R_Foot", 18},
      {"DEF-forearm.L", 5},
      {"DEF-shin.R", 17},
      {"forearm.L", 5},
      {"hand.R", 10},
      {"Bip01 L Thigh", 12},
      {"Bip01 R Calf", 17},
      {"mixamorig:Hips", 0},
      {"mixamorig:Neck", 2},
      {"mixamorig:Head", 3},
      {"mixamorig:LeftHandMiddle1", 7},
      {"Tail", -1},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
    int j = km_skeleton_kinect1_joint(KM_SKELETON_KINECT1, cases[i].name);
    CHECK_MSG(j == cases[i].joint, "%s -> %d, want %d", cases[i].name, j, cases[i].joint);
  }
  char buf[1024];
  const char *path = km_test_shared("bvh/cmu_131_01.bvh", buf, sizeof buf);
  if (!path) return;
  FILE *f = fopen(path, "rb");
  CHECK(f != NULL);
  if (!f) return;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *text = malloc((size_t)n + 1);
  size_t got = text ? fread(text, 1, (size_t)n, f) : 0;
  fclose(f);
  CHECK(text && got == (size_t)n);
  if (!text || got != (size_t)n) {
    free(text);
    return;
  }
  text[n] = 0;
  const char *out_path = "skeleton_names_mixamo.bvh";
  FILE *o = fopen(out_path, "wb");
  CHECK(o != NULL);
  int renamed = 0;
  for (char *line = text; o && line && *line;) {
    char *eol = strchr(line, '\n');
    if (eol) *eol = 0;
    char kw[16] = "", name[64] = "";
    int ind = (int)strspn(line, " \t");
    if (sscanf(line, "%15s %63s", kw, name) == 2 && (!strcmp(kw, "ROOT") || !strcmp(kw, "JOINT"))) {
      const char *to = NULL;
      for (size_t k = 0; k < sizeof CMU_TO_MIXAMO / sizeof CMU_TO_MIXAMO[0]; ++k)
        if (!strcmp(name, CMU_TO_MIXAMO[k][0])) to = CMU_TO_MIXAMO[k][1];
      CHECK_MSG(to != NULL, "CMU joint %s has no Mixamo name in the test", name);
      /* LHipJoint, RHipJoint, lowerback stay as they are: the BVH reader knows CMU's units
       * by them (and they stand for no Kinect joint). */
      bool keep = to && !strcmp(to, name);
      fprintf(o, "%.*s%s %s%s\n", ind, line, kw, keep ? "" : "mixamorig:", to ? to : name);
      ++renamed;
    } else {
      fprintf(o, "%s\n", line);
    }
    line = eol ? eol + 1 : NULL;
  }
  if (o) fclose(o);
  free(text);
  CHECK(renamed == 31);
  km_motion_read_options mo = {.kinect1 = true};
  km_motion_read_info i0, i1;
  km_take a = {0}, b = {0};
  CHECK_OK(km_motion_read(path, &mo, &a, &i0, KM_E));
  CHECK_OK(km_motion_read(out_path, &mo, &b, &i1, KM_E));
  CHECK_MSG(i1.kinect1_found == 20, "Mixamo names: %zu of the 20 Kinect joints", i1.kinect1_found);
  double worst = a.n_frames == b.n_frames && a.n_joints == b.n_joints ? 0 : INFINITY;
  for (size_t k = 0; isfinite(worst) && k < 3 * a.n_frames * a.n_joints; ++k)
    worst = fmax(worst, fabs(a.positions[k] - b.positions[k]));
  CHECK_MSG(worst == 0, "the Mixamo-named take differs from the CMU one by %g m", worst);
  km_take_free(&a);
  km_take_free(&b);
}

/* docs/skeletons.md prints the table: every body point row the code has must be there. */
static void test_docs_table(void) {
  FILE *f = fopen(KM_TEST_DATA "/../../docs/skeletons.md", "rb");
  CHECK(f != NULL);
  if (!f) return;
  static char doc[1 << 16];
  size_t n = fread(doc, 1, sizeof doc - 1, f);
  fclose(f);
  doc[n] = 0;
  int rows = 0;
  for (int k = 0; k < KM_SKELETON_KINDS; ++k)
    for (int j = 0; j < km_skeleton_joint_count((km_skeleton_kind)k); ++j) {
      if (km_skeleton_joint_map((km_skeleton_kind)k, j, (km_skeleton_kind)k) < 0) continue;
      char row[512] = "|";
      bool earlier = false;
      for (int t = 0; t < KM_SKELETON_KINDS; ++t) {
        int m = km_skeleton_joint_map((km_skeleton_kind)k, j, (km_skeleton_kind)t);
        earlier |= m >= 0 && t < k;
        char c[80];
        snprintf(c, sizeof c, " %s |",
                 m >= 0 ? km_skeleton_joint_name((km_skeleton_kind)t, m) : "-");
        strcat(row, c);
      }
      if (earlier) continue; /* the row was made from an earlier skeleton's joint */
      strcat(row, "\n");
      ++rows;
      CHECK_MSG(strstr(doc, row) != NULL, "docs/skeletons.md lacks the row %s", row);
    }
  CHECK(rows == 35);
}

int main(void) {
  test_tables();
  test_rig_names();
  test_unity_convert();
  test_bvh_humanoid();
  test_bone_names();
  test_docs_table();
  return km_test_finish("test_skeleton_names");
}
