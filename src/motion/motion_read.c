/* One motion reader for every front end: dispatches on the format (take JSON, Kinect v1 CSV,
 * BVH) and optionally reorders the take into the 20 Kinect v1 joints by name. */
#include "motion/motion.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* BVH names standing in for each Kinect v1 joint (in KM_KINECT1 order), tried in order when
 * the Kinect name itself is absent: the CMU ASF-derived skeleton (cgspeed conversions:
 * LeftShoulder/LeftElbow/LeftWrist/lhand, LeftHip/LeftKnee/LeftAnkle/LeftToe, lowerback,
 * lowerneck) and the Mixamo / MotionBuilder style (LeftArm/LeftForeArm/LeftHand,
 * LeftUpLeg/LeftLeg/LeftFoot/LeftToeBase, Spine, Neck). The Kinect shoulder joint is the top
 * of the upper arm, so CMU's LeftShoulder and Mixamo's LeftArm (not the clavicles LeftCollar /
 * LeftShoulder of Mixamo) stand in for it; the Kinect hand joint is mid-hand, after the wrist. */
static const char *const bvh_alias[KM_KINECT1_JOINTS][4] = {
    {"Hips", "hip", "Hip", NULL},                           /* HipCenter */
    {"lowerback", "Spine", "Spine1", "Chest"},              /* Spine */
    {"lowerneck", "Neck", "Neck1", NULL},                   /* ShoulderCenter */
    {"Head", "head", NULL, NULL},                           /* Head */
    {"LeftArm", "lShldr", NULL, NULL},                      /* ShoulderLeft, then CMU below */
    {"LeftElbow", "LeftForeArm", "lForeArm", NULL},         /* ElbowLeft */
    {"LeftWrist", "LeftHand", "lHand", NULL},               /* WristLeft */
    {"lhand", "LeftHandMiddle1", "LeftFingerBase", NULL},   /* HandLeft */
    {"RightArm", "rShldr", NULL, NULL},                     /* ShoulderRight */
    {"RightElbow", "RightForeArm", "rForeArm", NULL},       /* ElbowRight */
    {"RightWrist", "RightHand", "rHand", NULL},             /* WristRight */
    {"rhand", "RightHandMiddle1", "RightFingerBase", NULL}, /* HandRight */
    {"LeftHip", "LeftUpLeg", "lThigh", NULL},               /* HipLeft */
    {"LeftKnee", "LeftLeg", "lShin", NULL},                 /* KneeLeft */
    {"LeftAnkle", "LeftFoot", "lFoot", NULL},               /* AnkleLeft */
    {"LeftToe", "LeftToeBase", "LeftToe_End", NULL},        /* FootLeft */
    {"RightHip", "RightUpLeg", "rThigh", NULL},             /* HipRight */
    {"RightKnee", "RightLeg", "rShin", NULL},               /* KneeRight */
    {"RightAnkle", "RightFoot", "rFoot", NULL},             /* AnkleRight */
    {"RightToe", "RightToeBase", "RightToe_End", NULL},     /* FootRight */
};

static int column_of(const char *const *names, size_t n_names, const char *want) {
  for (size_t k = 0; k < n_names; ++k)
    if (names[k] && !strcmp(names[k], want)) return (int)k;
  return -1;
}

int km__kinect1_columns(const char *const *names, size_t n_names, int src[KM_KINECT1_JOINTS]) {
  int found = 0;
  /* CMU names its upper-arm joint LeftShoulder, where Mixamo's LeftShoulder is the clavicle
   * (Mixamo has LeftArm): CMU's is used only when the take has no LeftArm. */
  bool cmu = column_of(names, n_names, "lowerback") >= 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    src[j] = column_of(names, n_names, km_kinect1_joint_name(j));
    for (int a = 0; a < 4 && src[j] < 0 && bvh_alias[j][a]; ++a)
      src[j] = column_of(names, n_names, bvh_alias[j][a]);
    if (src[j] < 0 && cmu && (j == 4 || j == 8))
      src[j] = column_of(names, n_names, j == 4 ? "LeftShoulder" : "RightShoulder");
    found += src[j] >= 0;
  }
  return found;
}

/* out: t's columns src[] as a take of the 20 Kinect v1 joints (names, parents; absent joints
 * NaN). */
static km_status kinect1_take(const km_take *t, const int src[KM_KINECT1_JOINTS], km_take *out,
                              km_error *err) {
  memset(out, 0, sizeof *out);
  out->n_frames = t->n_frames;
  out->n_joints = KM_KINECT1_JOINTS;
  out->fps = t->fps;
  out->positions = km__malloc(3 * KM_KINECT1_JOINTS * (t->n_frames ? t->n_frames : 1),
                              sizeof(double));
  out->joint_names = km__calloc(KM_KINECT1_JOINTS, sizeof *out->joint_names);
  out->parents = km__malloc(KM_KINECT1_JOINTS, sizeof(int32_t));
  bool ok = out->positions && out->joint_names && out->parents;
  for (int j = 0; ok && j < KM_KINECT1_JOINTS; ++j) {
    ok = (out->joint_names[j] = km__strdup(km_kinect1_joint_name(j))) != NULL;
    out->parents[j] = km_kinect1_joint_parent(j);
  }
  if (!ok) {
    km_take_free(out);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t f = 0; f < t->n_frames; ++f)
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      for (int a = 0; a < 3; ++a)
        out->positions[(f * KM_KINECT1_JOINTS + (size_t)j) * 3 + a] =
            src[j] < 0 ? NAN : t->positions[(f * t->n_joints + (size_t)src[j]) * 3 + a];
  return KM_OK;
}

/* The format of a file whose extension does not say: its first bytes. */
static km_motion_format sniff(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return KM_MOTION_TAKE_JSON; /* the take reader reports the I/O error */
  char buf[512];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = '\0';
  const char *p = buf;
  while (*p && isspace((unsigned char)*p))
    ++p;
  if (!strncmp(p, "HIERARCHY", 9)) return KM_MOTION_BVH;
  if (*p == '{') return KM_MOTION_TAKE_JSON;
  const char *eol = strchr(p, '\n');
  const char *semi = strchr(p, ';');
  if (semi && (!eol || semi < eol)) return KM_MOTION_KINECT_CSV;
  return KM_MOTION_TAKE_JSON;
}

km_status km_motion_read(const char *path, const km_motion_read_options *opt, km_take *out,
                         km_motion_read_info *info, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_motion_read: NULL argument");
  memset(out, 0, sizeof *out);
  km_motion_read_options o = opt ? *opt : (km_motion_read_options){0};
  km_motion_format fmt = o.format;
  if (fmt == KM_MOTION_AUTO) {
    char ext[16];
    km__extension(path, ext, sizeof ext);
    fmt = !strcmp(ext, "csv")    ? KM_MOTION_KINECT_CSV
          : !strcmp(ext, "bvh")  ? KM_MOTION_BVH
          : !strcmp(ext, "json") ? KM_MOTION_TAKE_JSON
                                 : sniff(path);
  }
  km_take t = {0};
  km_status s;
  switch (fmt) {
  case KM_MOTION_KINECT_CSV: s = km_kinect_csv_read(path, &t, NULL, err); break;
  case KM_MOTION_BVH: s = km_bvh_read(path, &o.bvh, &t, NULL, err); break;
  case KM_MOTION_TAKE_JSON: s = km_take_read(path, &t, err); break;
  default: return km__fail(err, KM_ERR_INVALID, "%s: unknown motion format %d", path, (int)fmt);
  }
  /* Every error names the file, whichever reader failed. */
  if (s != KM_OK) return err && !strstr(err->message, path) ? km__wrap(err, s, "%s", path) : s;
  if (info) {
    memset(info, 0, sizeof *info);
    info->format = fmt;
  }
  if (!o.kinect1) {
    *out = t;
    return KM_OK;
  }
  int src[KM_KINECT1_JOINTS];
  int found = km__kinect1_columns((const char *const *)t.joint_names, t.n_joints, src);
  if (info) info->kinect1_found = (size_t)found;
  if (!found || !t.n_frames) {
    km_take_free(&t);
    return km__fail(err, KM_ERR_INVALID,
                    "%s: the take has no frames or none of the 20 Kinect v1 joints "
                    "(HipCenter, HandLeft, ...)",
                    path);
  }
  s = kinect1_take(&t, src, out, err);
  km_take_free(&t);
  if (s == KM_OK && !(out->fps > 0)) out->fps = 30;
  return s;
}
