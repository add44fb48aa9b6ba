/* One motion reader for every front end: dispatches on the format (take JSON, Kinect v1 CSV,
 * BVH) and optionally reorders the take into the 20 Kinect v1 joints by name. */
#include "motion/motion.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int km__kinect1_columns(const char *const *names, size_t n_names, int src[KM_KINECT1_JOINTS]) {
  int found = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    src[j] = -1;
    for (size_t k = 0; k < n_names; ++k)
      if (names[k] && !strcmp(names[k], km_kinect1_joint_name(j))) src[j] = (int)k;
    found += src[j] >= 0;
  }
  /* Another skeleton's names (a CMU BVH, a humanoid or Kinect v2 take): by body point, with
   * the fallbacks of km_skeleton_joint_source (a hand centre from the wrist, ...). */
  int matched = 0;
  int kind = km_skeleton_detect(names, n_names, &matched);
  if (kind > KM_SKELETON_KINECT1 && matched > found) {
    found = 0;
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
      int s = km_skeleton_joint_source(KM_SKELETON_KINECT1, j, (km_skeleton_kind)kind, NULL);
      const char *want = km_skeleton_joint_name((km_skeleton_kind)kind, s);
      src[j] = -1;
      for (size_t k = 0; want && k < n_names; ++k)
        if (names[k] && !strcmp(names[k], want)) src[j] = (int)k;
      found += src[j] >= 0;
    }
  }
  /* A game or DCC rig's bone names (a Mixamo or Blender BVH: "mixamorig:LeftForeArm",
   * "forearm.L"): by naming convention, the first bone of each joint in file order (the one
   * nearest the root); a missing hand or foot takes the wrist or ankle. */
  int fz[KM_KINECT1_JOINTS], nfz = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    fz[j] = -1;
  for (size_t k = 0; k < n_names; ++k) {
    int j = km__bone_name_kinect1(names[k]);
    if (j >= 0 && fz[j] < 0) fz[j] = (int)k, ++nfz;
  }
  if (nfz > found) {
    static const int stand_in[][2] = {
        {J_HAND_L, J_WRIST_L}, {J_HAND_R, J_WRIST_R}, {J_FOOT_L, J_ANKLE_L}, {J_FOOT_R, J_ANKLE_R}};
    for (size_t i = 0; i < sizeof stand_in / sizeof stand_in[0]; ++i)
      if (fz[stand_in[i][0]] < 0) fz[stand_in[i][0]] = fz[stand_in[i][1]];
    found = 0;
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      found += (src[j] = fz[j]) >= 0;
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
  out->positions =
      km__malloc(3 * KM_KINECT1_JOINTS * (t->n_frames ? t->n_frames : 1), sizeof(double));
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
