/* Skeletons by name (issue 15): the joint vocabularies of the trackers people use (Kinect v1,
 * Kinect v2, Azure Kinect body tracking, Unity's HumanBodyBones as sent over VMC, MediaPipe
 * BlazePose, the CMU BVH conversions) and one table that maps each to the others through the
 * body point every joint stands for. docs/skeletons.md prints the same table. */
#include "motion/motion.h"

#include <ctype.h>
#include <math.h>
#include <string.h>

/* Body points: the landmarks the skeletons share. A joint that stands for none of them (CMU's
 * LHipJoint, Unity's UpperChest, finger phalanges, MediaPipe's mouth) has P_NONE and maps to
 * nothing. */
enum {
  P_NONE = -1,
  P_PELVIS,
  P_SPINE_MID,
  P_CHEST,
  P_NECK_BASE, /* between the shoulders: Kinect ShoulderCenter / SpineShoulder */
  P_NECK,      /* mid neck: Kinect v2 Neck, CMU upper neck */
  P_HEAD,
  P_NOSE,
  P_L_EYE,
  P_R_EYE,
  P_L_EAR,
  P_R_EAR,
  P_L_CLAVICLE,
  P_L_SHOULDER,
  P_L_ELBOW,
  P_L_WRIST,
  P_L_HAND, /* the palm / knuckles */
  P_L_HANDTIP,
  P_L_THUMB,
  P_R_CLAVICLE,
  P_R_SHOULDER,
  P_R_ELBOW,
  P_R_WRIST,
  P_R_HAND,
  P_R_HANDTIP,
  P_R_THUMB,
  P_L_HIP,
  P_L_KNEE,
  P_L_ANKLE,
  P_L_FOOT, /* the toes / ball of the foot */
  P_L_HEEL,
  P_R_HIP,
  P_R_KNEE,
  P_R_ANKLE,
  P_R_FOOT,
  P_R_HEEL,
  P_COUNT
};

/* Where a point is missing in a skeleton, the nearest point that a tracker of it gives, for
 * driving (km_skeleton_convert): a hand handle follows the wrist, a foot the ankle. */
static const int FALLBACK[P_COUNT] = {
    [P_PELVIS] = P_NONE,     [P_SPINE_MID] = P_CHEST,  [P_CHEST] = P_SPINE_MID,
    [P_NECK_BASE] = P_NECK,  [P_NECK] = P_NECK_BASE,   [P_HEAD] = P_NECK,
    [P_NOSE] = P_HEAD,       [P_L_EYE] = P_NONE,       [P_R_EYE] = P_NONE,
    [P_L_EAR] = P_NONE,      [P_R_EAR] = P_NONE,       [P_L_CLAVICLE] = P_NONE,
    [P_L_SHOULDER] = P_NONE, [P_L_ELBOW] = P_NONE,     [P_L_WRIST] = P_L_HAND,
    [P_L_HAND] = P_L_WRIST,  [P_L_HANDTIP] = P_L_HAND, [P_L_THUMB] = P_L_HAND,
    [P_R_CLAVICLE] = P_NONE, [P_R_SHOULDER] = P_NONE,  [P_R_ELBOW] = P_NONE,
    [P_R_WRIST] = P_R_HAND,  [P_R_HAND] = P_R_WRIST,   [P_R_HANDTIP] = P_R_HAND,
    [P_R_THUMB] = P_R_HAND,  [P_L_HIP] = P_NONE,       [P_L_KNEE] = P_NONE,
    [P_L_ANKLE] = P_L_HEEL,  [P_L_FOOT] = P_L_ANKLE,   [P_L_HEEL] = P_L_ANKLE,
    [P_R_HIP] = P_NONE,      [P_R_KNEE] = P_NONE,      [P_R_ANKLE] = P_R_HEEL,
    [P_R_FOOT] = P_R_ANKLE,  [P_R_HEEL] = P_R_ANKLE,
};

typedef struct joint_def {
  const char *name;
  int parent; /* index in the same skeleton, -1 for a root */
  int point;
} joint_def;

static const joint_def KINECT1[] = {
    {"HipCenter", -1, P_PELVIS},
    {"Spine", 0, P_SPINE_MID},
    {"ShoulderCenter", 1, P_NECK_BASE},
    {"Head", 2, P_HEAD},
    {"ShoulderLeft", 2, P_L_SHOULDER},
    {"ElbowLeft", 4, P_L_ELBOW},
    {"WristLeft", 5, P_L_WRIST},
    {"HandLeft", 6, P_L_HAND},
    {"ShoulderRight", 2, P_R_SHOULDER},
    {"ElbowRight", 8, P_R_ELBOW},
    {"WristRight", 9, P_R_WRIST},
    {"HandRight", 10, P_R_HAND},
    {"HipLeft", 0, P_L_HIP},
    {"KneeLeft", 12, P_L_KNEE},
    {"AnkleLeft", 13, P_L_ANKLE},
    {"FootLeft", 14, P_L_FOOT},
    {"HipRight", 0, P_R_HIP},
    {"KneeRight", 16, P_R_KNEE},
    {"AnkleRight", 17, P_R_ANKLE},
    {"FootRight", 18, P_R_FOOT},
};

/* The Kinect for Windows SDK 2.0 JointType order. */
static const joint_def KINECT2[] = {
    {"SpineBase", -1, P_PELVIS},
    {"SpineMid", 0, P_SPINE_MID},
    {"Neck", 20, P_NECK},
    {"Head", 2, P_HEAD},
    {"ShoulderLeft", 20, P_L_SHOULDER},
    {"ElbowLeft", 4, P_L_ELBOW},
    {"WristLeft", 5, P_L_WRIST},
    {"HandLeft", 6, P_L_HAND},
    {"ShoulderRight", 20, P_R_SHOULDER},
    {"ElbowRight", 8, P_R_ELBOW},
    {"WristRight", 9, P_R_WRIST},
    {"HandRight", 10, P_R_HAND},
    {"HipLeft", 0, P_L_HIP},
    {"KneeLeft", 12, P_L_KNEE},
    {"AnkleLeft", 13, P_L_ANKLE},
    {"FootLeft", 14, P_L_FOOT},
    {"HipRight", 0, P_R_HIP},
    {"KneeRight", 16, P_R_KNEE},
    {"AnkleRight", 17, P_R_ANKLE},
    {"FootRight", 18, P_R_FOOT},
    {"SpineShoulder", 1, P_NECK_BASE},
    {"HandTipLeft", 7, P_L_HANDTIP},
    {"ThumbLeft", 7, P_L_THUMB},
    {"HandTipRight", 11, P_R_HANDTIP},
    {"ThumbRight", 11, P_R_THUMB},
};

/* Azure Kinect / Orbbec body tracking (k4abt_joint_id_t, K4ABT_JOINT_ prefix dropped). */
static const joint_def K4ABT[] = {
    {"PELVIS", -1, P_PELVIS},
    {"SPINE_NAVEL", 0, P_SPINE_MID},
    {"SPINE_CHEST", 1, P_CHEST},
    {"NECK", 2, P_NECK_BASE},
    {"CLAVICLE_LEFT", 2, P_L_CLAVICLE},
    {"SHOULDER_LEFT", 4, P_L_SHOULDER},
    {"ELBOW_LEFT", 5, P_L_ELBOW},
    {"WRIST_LEFT", 6, P_L_WRIST},
    {"HAND_LEFT", 7, P_L_HAND},
    {"HANDTIP_LEFT", 8, P_L_HANDTIP},
    {"THUMB_LEFT", 7, P_L_THUMB},
    {"CLAVICLE_RIGHT", 2, P_R_CLAVICLE},
    {"SHOULDER_RIGHT", 11, P_R_SHOULDER},
    {"ELBOW_RIGHT", 12, P_R_ELBOW},
    {"WRIST_RIGHT", 13, P_R_WRIST},
    {"HAND_RIGHT", 14, P_R_HAND},
    {"HANDTIP_RIGHT", 15, P_R_HANDTIP},
    {"THUMB_RIGHT", 14, P_R_THUMB},
    {"HIP_LEFT", 0, P_L_HIP},
    {"KNEE_LEFT", 18, P_L_KNEE},
    {"ANKLE_LEFT", 19, P_L_ANKLE},
    {"FOOT_LEFT", 20, P_L_FOOT},
    {"HIP_RIGHT", 0, P_R_HIP},
    {"KNEE_RIGHT", 22, P_R_KNEE},
    {"ANKLE_RIGHT", 23, P_R_ANKLE},
    {"FOOT_RIGHT", 24, P_R_FOOT},
    {"HEAD", 3, P_HEAD},
    {"NOSE", 26, P_NOSE},
    {"EYE_LEFT", 26, P_L_EYE},
    {"EAR_LEFT", 26, P_L_EAR},
    {"EYE_RIGHT", 26, P_R_EYE},
    {"EAR_RIGHT", 26, P_R_EAR},
};

/* Unity HumanBodyBones in enum order (0..54). Parents follow Unity's humanoid hierarchy with
 * every optional bone present (Chest, UpperChest, Neck, the shoulders); a bone's joint is the
 * bone's origin, so LeftHand is the wrist and LeftFoot the ankle. */
static const joint_def HUMANOID[KM_HUMANOID_BONES] = {
    {"Hips", -1, P_PELVIS},
    {"LeftUpperLeg", 0, P_L_HIP},
    {"RightUpperLeg", 0, P_R_HIP},
    {"LeftLowerLeg", 1, P_L_KNEE},
    {"RightLowerLeg", 2, P_R_KNEE},
    {"LeftFoot", 3, P_L_ANKLE},
    {"RightFoot", 4, P_R_ANKLE},
    {"Spine", 0, P_SPINE_MID},
    {"Chest", 7, P_CHEST},
    {"Neck", 54, P_NECK_BASE},
    {"Head", 9, P_HEAD},
    {"LeftShoulder", 54, P_L_CLAVICLE},
    {"RightShoulder", 54, P_R_CLAVICLE},
    {"LeftUpperArm", 11, P_L_SHOULDER},
    {"RightUpperArm", 12, P_R_SHOULDER},
    {"LeftLowerArm", 13, P_L_ELBOW},
    {"RightLowerArm", 14, P_R_ELBOW},
    {"LeftHand", 15, P_L_WRIST},
    {"RightHand", 16, P_R_WRIST},
    {"LeftToes", 5, P_L_FOOT},
    {"RightToes", 6, P_R_FOOT},
    {"LeftEye", 10, P_L_EYE},
    {"RightEye", 10, P_R_EYE},
    {"Jaw", 10, P_NONE},
    {"LeftThumbProximal", 17, P_NONE},
    {"LeftThumbIntermediate", 24, P_NONE},
    {"LeftThumbDistal", 25, P_L_THUMB},
    {"LeftIndexProximal", 17, P_NONE},
    {"LeftIndexIntermediate", 27, P_NONE},
    {"LeftIndexDistal", 28, P_NONE},
    {"LeftMiddleProximal", 17, P_L_HAND},
    {"LeftMiddleIntermediate", 30, P_NONE},
    {"LeftMiddleDistal", 31, P_L_HANDTIP},
    {"LeftRingProximal", 17, P_NONE},
    {"LeftRingIntermediate", 33, P_NONE},
    {"LeftRingDistal", 34, P_NONE},
    {"LeftLittleProximal", 17, P_NONE},
    {"LeftLittleIntermediate", 36, P_NONE},
    {"LeftLittleDistal", 37, P_NONE},
    {"RightThumbProximal", 18, P_NONE},
    {"RightThumbIntermediate", 39, P_NONE},
    {"RightThumbDistal", 40, P_R_THUMB},
    {"RightIndexProximal", 18, P_NONE},
    {"RightIndexIntermediate", 42, P_NONE},
    {"RightIndexDistal", 43, P_NONE},
    {"RightMiddleProximal", 18, P_R_HAND},
    {"RightMiddleIntermediate", 45, P_NONE},
    {"RightMiddleDistal", 46, P_R_HANDTIP},
    {"RightRingProximal", 18, P_NONE},
    {"RightRingIntermediate", 48, P_NONE},
    {"RightRingDistal", 49, P_NONE},
    {"RightLittleProximal", 18, P_NONE},
    {"RightLittleIntermediate", 51, P_NONE},
    {"RightLittleDistal", 52, P_NONE},
    {"UpperChest", 8, P_NONE},
};

/* MediaPipe BlazePose landmarks (33). BlazePose has no tree; the parents below are the lines
 * its drawing utilities connect, rooted at the nose, the shoulders and the hips. */
static const joint_def MEDIAPIPE[] = {
    {"nose", -1, P_NOSE},
    {"left_eye_inner", 0, P_NONE},
    {"left_eye", 0, P_L_EYE},
    {"left_eye_outer", 0, P_NONE},
    {"right_eye_inner", 0, P_NONE},
    {"right_eye", 0, P_R_EYE},
    {"right_eye_outer", 0, P_NONE},
    {"left_ear", 0, P_L_EAR},
    {"right_ear", 0, P_R_EAR},
    {"mouth_left", 0, P_NONE},
    {"mouth_right", 0, P_NONE},
    {"left_shoulder", -1, P_L_SHOULDER},
    {"right_shoulder", -1, P_R_SHOULDER},
    {"left_elbow", 11, P_L_ELBOW},
    {"right_elbow", 12, P_R_ELBOW},
    {"left_wrist", 13, P_L_WRIST},
    {"right_wrist", 14, P_R_WRIST},
    {"left_pinky", 15, P_NONE},
    {"right_pinky", 16, P_NONE},
    {"left_index", 15, P_L_HAND},
    {"right_index", 16, P_R_HAND},
    {"left_thumb", 15, P_L_THUMB},
    {"right_thumb", 16, P_R_THUMB},
    {"left_hip", -1, P_L_HIP},
    {"right_hip", -1, P_R_HIP},
    {"left_knee", 23, P_L_KNEE},
    {"right_knee", 24, P_R_KNEE},
    {"left_ankle", 25, P_L_ANKLE},
    {"right_ankle", 26, P_R_ANKLE},
    {"left_heel", 27, P_L_HEEL},
    {"right_heel", 28, P_R_HEEL},
    {"left_foot_index", 27, P_L_FOOT},
    {"right_foot_index", 28, P_R_FOOT},
};

/* The CMU motion capture database as converted to BVH (the ASF bone names: the files in
 * ../shared/data/bvh). */
static const joint_def CMU[] = {
    {"Hips", -1, P_PELVIS},
    {"LHipJoint", 0, P_NONE},
    {"LeftHip", 1, P_L_HIP},
    {"LeftKnee", 2, P_L_KNEE},
    {"LeftAnkle", 3, P_L_ANKLE},
    {"LeftToe", 4, P_L_FOOT},
    {"RHipJoint", 0, P_NONE},
    {"RightHip", 6, P_R_HIP},
    {"RightKnee", 7, P_R_KNEE},
    {"RightAnkle", 8, P_R_ANKLE},
    {"RightToe", 9, P_R_FOOT},
    {"lowerback", 0, P_NONE},
    {"Chest", 11, P_SPINE_MID},
    {"Chest2", 12, P_CHEST},
    {"lowerneck", 13, P_NECK_BASE},
    {"Neck", 14, P_NECK},
    {"Head", 15, P_HEAD},
    {"LeftCollar", 13, P_L_CLAVICLE},
    {"LeftShoulder", 17, P_L_SHOULDER},
    {"LeftElbow", 18, P_L_ELBOW},
    {"LeftWrist", 19, P_L_WRIST},
    {"lhand", 20, P_L_HAND},
    {"LFingers", 21, P_NONE},
    {"LThumb", 20, P_NONE},
    {"RightCollar", 13, P_R_CLAVICLE},
    {"RightShoulder", 24, P_R_SHOULDER},
    {"RightElbow", 25, P_R_ELBOW},
    {"RightWrist", 26, P_R_WRIST},
    {"rhand", 27, P_R_HAND},
    {"RFingers", 28, P_NONE},
    {"RThumb", 27, P_NONE},
};

typedef struct skeleton_def {
  const char *name;
  const joint_def *joints;
  int n;
} skeleton_def;

#define DEF(name, t)                                                                               \
  { name, t, (int)(sizeof t / sizeof t[0]) }
static const skeleton_def SKELETONS[KM_SKELETON_KINDS] = {
    DEF("kinect1", KINECT1),   DEF("kinect2", KINECT2),     DEF("k4abt", K4ABT),
    DEF("humanoid", HUMANOID), DEF("mediapipe", MEDIAPIPE), DEF("bvh", CMU),
};

static const skeleton_def *def_of(km_skeleton_kind k) {
  return (int)k >= 0 && k < KM_SKELETON_KINDS ? &SKELETONS[k] : NULL;
}

int km_skeleton_kind_from_name(const char *name) {
  if (!name) return -1;
  for (int k = 0; k < KM_SKELETON_KINDS; ++k)
    if (!strcmp(name, SKELETONS[k].name)) return k;
  return -1;
}

const char *km_skeleton_kind_name(km_skeleton_kind k) {
  const skeleton_def *d = def_of(k);
  return d ? d->name : NULL;
}

int km_skeleton_joint_count(km_skeleton_kind k) {
  const skeleton_def *d = def_of(k);
  return d ? d->n : 0;
}

const char *km_skeleton_joint_name(km_skeleton_kind k, int j) {
  const skeleton_def *d = def_of(k);
  return d && j >= 0 && j < d->n ? d->joints[j].name : NULL;
}

int km_skeleton_joint_parent(km_skeleton_kind k, int j) {
  const skeleton_def *d = def_of(k);
  return d && j >= 0 && j < d->n ? d->joints[j].parent : -1;
}

int km_skeleton_joint_index(km_skeleton_kind k, const char *name) {
  const skeleton_def *d = def_of(k);
  if (!d || !name) return -1;
  for (int j = 0; j < d->n; ++j)
    if (!strcmp(name, d->joints[j].name)) return j;
  return -1;
}

static int joint_at_point(const skeleton_def *d, int point) {
  if (point < 0) return -1;
  for (int j = 0; j < d->n; ++j)
    if (d->joints[j].point == point) return j;
  return -1;
}

int km_skeleton_joint_map(km_skeleton_kind from, int j, km_skeleton_kind to) {
  const skeleton_def *f = def_of(from), *t = def_of(to);
  if (!f || !t || j < 0 || j >= f->n) return -1;
  return joint_at_point(t, f->joints[j].point);
}

int km_skeleton_joint_source(km_skeleton_kind to, int j, km_skeleton_kind from, bool *approx) {
  const skeleton_def *f = def_of(from), *t = def_of(to);
  if (approx) *approx = false;
  if (!f || !t || j < 0 || j >= t->n) return -1;
  int point = t->joints[j].point;
  int s = joint_at_point(f, point);
  if (s >= 0 || point < 0) return s;
  /* Follow the fallbacks (at most two steps: hand -> wrist, handtip -> hand -> wrist). */
  for (int step = 0, p = point; step < 2 && s < 0; ++step) {
    p = FALLBACK[p];
    if (p < 0) break;
    s = joint_at_point(f, p);
  }
  if (s >= 0 && approx) *approx = true;
  return s;
}

int km_skeleton_detect(const char *const *names, size_t n, int *matched) {
  int best = -1, best_n = 0;
  for (int k = 0; k < KM_SKELETON_KINDS; ++k) {
    int c = 0;
    for (size_t i = 0; i < n; ++i)
      if (km_skeleton_joint_index((km_skeleton_kind)k, names[i]) >= 0) ++c;
    if (c > best_n) best = k, best_n = c;
  }
  if (matched) *matched = best_n;
  return best;
}

int km_skeleton_kinect1_joint(km_skeleton_kind named, const char *name) {
  int j = km_skeleton_joint_index(named, name);
  if (j >= 0) {
    int v1 = km_skeleton_joint_map(named, j, KM_SKELETON_KINECT1);
    return v1 >= 0 ? v1 : -2;
  }
  for (int k = 0; k < KM_SKELETON_KINDS; ++k) {
    j = km_skeleton_joint_index((km_skeleton_kind)k, name);
    if (j >= 0) {
      int v1 = km_skeleton_joint_map((km_skeleton_kind)k, j, KM_SKELETON_KINECT1);
      return v1 >= 0 ? v1 : -2;
    }
  }
  return km__bone_name_kinect1(name); /* a game / DCC rig's bone name ("mixamorig:LeftArm") */
}

/* Position of body point p in a frame of skeleton f (exact joint only), false when missing. */
static bool point_pos(const skeleton_def *f, const double *in, int p, double out[3]) {
  int j = joint_at_point(f, p);
  if (j < 0 || !(isfinite(in[3 * j]) && isfinite(in[3 * j + 1]) && isfinite(in[3 * j + 2])))
    return false;
  memcpy(out, in + 3 * j, 3 * sizeof *out);
  return true;
}

static bool midpoint(const skeleton_def *f, const double *in, int a, int b, double out[3]) {
  double pa[3], pb[3];
  if (!point_pos(f, in, a, pa) || !point_pos(f, in, b, pb)) return false;
  for (int k = 0; k < 3; ++k)
    out[k] = 0.5 * (pa[k] + pb[k]);
  return true;
}

void km_skeleton_convert(km_skeleton_kind from, const double *in, km_skeleton_kind to,
                         double *out) {
  const skeleton_def *f = def_of(from), *t = def_of(to);
  if (!f || !t) return;
  /* Trunk points a source may lack (MediaPipe has no pelvis, spine or neck; OpenNI bridges
   * often no waist): the pelvis between the hips, the neck base between the shoulders, the
   * mid spine between those two, the head at the nose. */
  double pelvis[3], neck[3], spine[3], head[3];
  bool has_pelvis = point_pos(f, in, P_PELVIS, pelvis) || midpoint(f, in, P_L_HIP, P_R_HIP, pelvis);
  bool has_neck = point_pos(f, in, P_NECK_BASE, neck) || point_pos(f, in, P_NECK, neck) ||
                  midpoint(f, in, P_L_SHOULDER, P_R_SHOULDER, neck);
  bool has_spine = point_pos(f, in, P_SPINE_MID, spine) || point_pos(f, in, P_CHEST, spine);
  if (!has_spine && has_pelvis && has_neck) {
    for (int k = 0; k < 3; ++k)
      spine[k] = 0.5 * (pelvis[k] + neck[k]);
    has_spine = true;
  }
  bool has_head = point_pos(f, in, P_HEAD, head) || point_pos(f, in, P_NOSE, head);
  for (int j = 0; j < t->n; ++j) {
    int s = -1, p0 = t->joints[j].point;
    /* The exact point, else its fallbacks, skipping joints missing (NaN) in this frame. */
    for (int step = 0, p = p0; step < 3 && p >= 0 && s < 0; ++step) {
      s = joint_at_point(f, p);
      if (s >= 0 && !(isfinite(in[3 * s]) && isfinite(in[3 * s + 1]) && isfinite(in[3 * s + 2])))
        s = -1;
      p = FALLBACK[p];
    }
    const double *src = s >= 0 ? in + 3 * s : NULL;
    if (!src) {
      src = p0 == P_PELVIS && has_pelvis     ? pelvis
            : p0 == P_NECK_BASE && has_neck  ? neck
            : p0 == P_SPINE_MID && has_spine ? spine
            : p0 == P_HEAD && has_head       ? head
                                             : NULL;
    }
    for (int a = 0; a < 3; ++a)
      out[3 * j + a] = src ? src[a] : NAN;
  }
}

/* ---- bone names by convention (km__bone_name_kinect1): game and DCC rigs name their bones
 * in a few styles; the side and the limb word say which joint a bone starts at. */

static bool starts(const char *s, const char *p) { return !strncmp(s, p, strlen(p)); }
static bool ends(const char *s, const char *p) {
  size_t n = strlen(s), k = strlen(p);
  return n >= k && !strcmp(s + n - k, p);
}
static bool in(const char *core, const char *const *list) {
  for (; *list; ++list)
    if (!strcmp(core, *list)) return true;
  return false;
}

/* Side (-1 none, 0 left, 1 right) and core (lower case, letters and digits only) of a joint
 * name: "mixamorig:LeftForeArm" -> left "forearm", "upper_arm.L" -> left "upperarm",
 * "J_Bip_R_UpperLeg" -> right "upperleg", "leftUpperArm" -> left "upperarm". */
static int split_name(const char *name, char *core, size_t cap) {
  const char *b = name;
  for (const char *p = name; *p; ++p)
    if (*p == ':' || *p == '|') b = p + 1;
  char s[128];
  size_t n = 0;
  for (; *b && n + 1 < sizeof s; ++b)
    s[n++] = (char)tolower((unsigned char)*b);
  s[n] = '\0';
  char *t = s;
  static const char *const prefixes[] = {"def-",   "org-",    "mch-",   "def_",    "j_bip_",
                                         "bip01 ", "bip001 ", "bip01_", "bip001_", NULL};
  for (const char *const *p = prefixes; *p; ++p)
    if (starts(t, *p)) t += strlen(*p);
  int side = -1;
  for (int pass = 0; pass < 2 && side < 0; ++pass) {
    if (starts(t, "left"))
      side = 0, t += 4;
    else if (starts(t, "right"))
      side = 1, t += 5;
    else if ((t[0] == 'l' || t[0] == 'r') && t[1] && strchr("_. -", t[1]))
      side = t[0] == 'r', t += 2;
    else if (starts(t, "c_"))
      t += 2;
    else {
      static const char *const suf[2][5] = {{".l", "_l", "-l", " l", ".left"},
                                            {".r", "_r", "-r", " r", ".right"}};
      for (int sd = 0; sd < 2 && side < 0; ++sd)
        for (int k = 0; k < 5; ++k)
          if (ends(t, suf[sd][k])) {
            side = sd;
            t[strlen(t) - strlen(suf[sd][k])] = '\0';
            break;
          }
      /* "upper_arm.L.001" (a twist segment): drop a numbered tail once and look again */
      char *dot = strrchr(t, '.');
      if (side < 0 && pass == 0 && dot && dot[1] &&
          strspn(dot + 1, "0123456789") == strlen(dot + 1))
        *dot = '\0';
      else
        break;
    }
  }
  size_t k = 0;
  for (; *t && k + 1 < cap; ++t)
    if (isalnum((unsigned char)*t)) core[k++] = *t;
  core[k] = '\0';
  return side;
}

int km__bone_name_kinect1(const char *name) {
  if (!name) return -1;
  char core[128];
  int side = split_name(name, core, sizeof core);
  static const char *const arm[] = {"arm", "upperarm", "uparm", NULL};
  static const char *const fore[] = {"forearm", "lowerarm", "elbow", NULL};
  static const char *const hand[] = {"hand", "wrist", NULL};
  static const char *const hand_end[] = {"handmiddle1", "middleproximal", "middle1", "fmiddle01",
                                         "middle01",    "fingermiddle1",  NULL};
  static const char *const thigh[] = {"upleg", "upperleg", "thigh", "hip", "uplegroll", NULL};
  static const char *const shin[] = {"leg", "lowerleg", "shin", "calf", "knee", NULL};
  static const char *const foot[] = {"foot", "ankle", NULL};
  static const char *const toe[] = {"toebase", "toes", "toe", "toe0", "ball", NULL};
  if (side < 0) {
    static const char *const hips[] = {"hips", "hip", "pelvis", NULL};
    static const char *const neck[] = {"neck", "neck1", "neck01", NULL};
    static const char *const spine[] = {"spine", "spine0", "spine01", "abdomen", NULL};
    if (in(core, hips)) return J_HIP_C;
    if (in(core, neck)) return J_SHOULDER_C;
    if (in(core, spine)) return J_SPINE;
    if (!strcmp(core, "head")) return J_HEAD;
    return -1;
  }
  int o = side ? J_SHOULDER_R - J_SHOULDER_L : 0, l = side ? J_HIP_R - J_HIP_L : 0;
  if (in(core, arm)) return J_SHOULDER_L + o;
  if (in(core, fore)) return J_ELBOW_L + o;
  if (in(core, hand)) return J_WRIST_L + o;
  if (in(core, hand_end)) return J_HAND_L + o;
  if (in(core, thigh)) return J_HIP_L + l;
  if (in(core, shin)) return J_KNEE_L + l;
  if (in(core, foot)) return J_ANKLE_L + l;
  if (in(core, toe)) return J_FOOT_L + l;
  return -1;
}
