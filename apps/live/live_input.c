/* Tracker message parsing for live mode: joint names of the three skeleton vocabularies,
 * JSON datagrams (cJSON) and OSC messages (decoded by liblo, interpreted here). */
#include "live.h"

#include <cjson/cJSON.h>
#include <lo/lo.h>
#include <math.h>
#include <string.h>

typedef struct joint_alias {
  const char *name;
  int joint; /* KM_KINECT1 index, -2: known joint without a v1 counterpart */
} joint_alias;

/* OSCeleton (OpenNI) names; every other skeleton's (Kinect v2, Azure Kinect, Unity humanoid,
 * MediaPipe, CMU) come from the library's table (km_skeleton_kinect1_joint, Kinect v2 first).
 * OpenNI's torso is the mid-spine (v1 Spine) and its waist the pelvis (HipCenter). */
static const joint_alias ALIASES[] = {
    {"waist", 0},     {"torso", 1},     {"neck", 2},         {"head", 3},         {"l_shoulder", 4},
    {"l_elbow", 5},   {"l_wrist", 6},   {"l_hand", 7},       {"r_shoulder", 8},   {"r_elbow", 9},
    {"r_wrist", 10},  {"r_hand", 11},   {"l_hip", 12},       {"l_knee", 13},      {"l_ankle", 14},
    {"l_foot", 15},   {"r_hip", 16},    {"r_knee", 17},      {"r_ankle", 18},     {"r_foot", 19},
    {"l_collar", -2}, {"r_collar", -2}, {"l_fingertip", -2}, {"r_fingertip", -2},
};

int km_live_joint_index(const char *name) {
  if (!name) return -1;
  int j = km_kinect1_joint_index(name);
  if (j >= 0) return j;
  for (size_t i = 0; i < sizeof ALIASES / sizeof ALIASES[0]; ++i)
    if (!strcmp(name, ALIASES[i].name)) return ALIASES[i].joint;
  return km_skeleton_kinect1_joint(KM_SKELETON_KINECT2, name);
}

/* ---------------------------------------------------------------- JSON datagrams */

static int read_xyz(const cJSON *a, double *p) {
  if (!a || cJSON_IsNull(a)) return 0;
  if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != 3) return -1;
  for (int k = 0; k < 3; ++k) {
    const cJSON *v = cJSON_GetArrayItem(a, k);
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble)) return -1;
    p[k] = v->valuedouble;
  }
  return 1;
}

static int read_flat(const cJSON *a, double *joints) {
  if (cJSON_GetArraySize(a) != 3 * KM_KINECT1_JOINTS) return -1;
  int n = 0, k = 0;
  for (const cJSON *v = a->child; v; v = v->next, ++k) {
    if (cJSON_IsNull(v)) continue;
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble)) return -1;
    joints[k] = v->valuedouble;
  }
  /* A joint counts only when all three of its numbers are present. */
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    if (isnan(joints[3 * j]) || isnan(joints[3 * j + 1]) || isnan(joints[3 * j + 2]))
      joints[3 * j] = joints[3 * j + 1] = joints[3 * j + 2] = NAN;
    else
      ++n;
  return n;
}

/* {"skeleton": KIND, "joints": {name: [x,y,z] | null} | [count*3 numbers or nulls]}: the
 * frame in KIND's joint order, then km_skeleton_convert to Kinect v1 (which makes up the trunk
 * points MediaPipe lacks). Returns the number of source joints set, -1 when malformed. */
static int read_kind(km_skeleton_kind kind, const cJSON *js, double *joints) {
  int nk = km_skeleton_joint_count(kind), n = 0;
  double in[3 * 64];
  if (nk <= 0 || nk > 64) return -1;
  for (int k = 0; k < 3 * nk; ++k)
    in[k] = NAN;
  if (cJSON_IsArray(js)) {
    if (cJSON_GetArraySize(js) != 3 * nk) return -1;
    int k = 0;
    for (const cJSON *v = js->child; v; v = v->next, ++k) {
      if (cJSON_IsNull(v)) continue;
      if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble)) return -1;
      in[k] = v->valuedouble;
    }
    for (int j = 0; j < nk; ++j)
      if (isnan(in[3 * j]) || isnan(in[3 * j + 1]) || isnan(in[3 * j + 2]))
        in[3 * j] = in[3 * j + 1] = in[3 * j + 2] = NAN;
      else
        ++n;
  } else if (cJSON_IsObject(js)) {
    for (const cJSON *e = js->child; e; e = e->next) {
      int j = km_skeleton_joint_index(kind, e->string);
      if (j < 0) continue; /* another skeleton's joint: not this frame's */
      double p[3];
      int r = read_xyz(e, p);
      if (r < 0) return -1;
      if (r > 0) {
        memcpy(in + 3 * j, p, sizeof p);
        ++n;
      }
    }
  } else {
    return -1;
  }
  if (n) km_skeleton_convert(kind, in, KM_SKELETON_KINECT1, joints);
  return n;
}

int km_live_parse_json(const char *data, size_t size, double *joints) {
  for (int k = 0; k < 3 * KM_KINECT1_JOINTS; ++k)
    joints[k] = NAN;
  if (!data || !size) return -1;
  cJSON *doc = cJSON_ParseWithLength(data, size);
  if (!doc) return -1;
  int n = -1;
  const cJSON *js = cJSON_IsArray(doc) ? doc : cJSON_GetObjectItemCaseSensitive(doc, "joints");
  const cJSON *sk = cJSON_IsObject(doc) ? cJSON_GetObjectItemCaseSensitive(doc, "skeleton") : NULL;
  if (sk) {
    int kind = cJSON_IsString(sk) ? km_skeleton_kind_from_name(sk->valuestring) : -1;
    n = kind >= 0 ? read_kind((km_skeleton_kind)kind, js, joints) : -1;
  } else if (cJSON_IsArray(js)) {
    n = read_flat(js, joints);
  } else if (cJSON_IsObject(js)) {
    n = 0;
    for (const cJSON *e = js->child; e; e = e->next) {
      int j = km_live_joint_index(e->string);
      if (j == -2) continue;
      double p[3];
      int r = j >= 0 ? read_xyz(e, p) : 0;
      if (r < 0) {
        n = -1;
        break;
      }
      if (r > 0) {
        memcpy(joints + 3 * j, p, sizeof p);
        ++n;
      }
    }
  }
  cJSON_Delete(doc);
  if (n <= 0) {
    for (int k = 0; k < 3 * KM_KINECT1_JOINTS; ++k)
      joints[k] = NAN;
    return -1;
  }
  return n;
}

/* ---------------------------------------------------------------- OSC */

static bool is_num(char t) { return t == 'f' || t == 'd' || t == 'i' || t == 'h'; }
/* liblo's argument pointers point into the message, 4-byte aligned, while lo_arg (a union
 * with int64 and double) wants 8: read through memcpy instead of the union. */
static double num(char t, const void *a) {
  switch (t) {
  case 'f': {
    float f;
    memcpy(&f, a, sizeof f);
    return f;
  }
  case 'd': {
    double d;
    memcpy(&d, a, sizeof d);
    return d;
  }
  case 'i': {
    int32_t i;
    memcpy(&i, a, sizeof i);
    return i;
  }
  default: {
    int64_t h;
    memcpy(&h, a, sizeof h);
    return (double)h;
  }
  }
}

/* A user id as an int: int32 as sent; an int64 outside the int range (Kinect v2 tracking ids
 * are 64-bit) folded into 0..INT32_MAX, never converted out of range (undefined). */
static int user_id(char type, const void *a) {
  if (type == 'i') {
    int32_t i;
    memcpy(&i, a, sizeof i);
    return i;
  }
  int64_t h;
  memcpy(&h, a, sizeof h);
  if (h >= INT32_MIN && h <= INT32_MAX) return (int)h;
  uint64_t u = (uint64_t)h;
  return (int)((u ^ (u >> 31) ^ (u >> 62)) & 0x7fffffffu);
}

km_live_osc_kind km_live_parse_osc(const char *path, const char *types, void *const *argv_,
                                   int argc, km_live_osc_joint *out) {
  const void *const *argv = (const void *const *)argv_;
  if (!path || !types || argc < 0 || (int)strlen(types) != argc) return KM_LIVE_OSC_BAD;
  out->timestamp = NAN;
  out->user = 0;
  if (!strcmp(path, "/joint")) {
    /* OSCeleton: s i i f f f f [d]; some builds send the numbers as doubles. */
    if (argc != 7 && argc != 8) return KM_LIVE_OSC_BAD;
    if (types[0] != 's' || (types[1] != 'i' && types[1] != 'h') ||
        (types[2] != 'i' && types[2] != 'h'))
      return KM_LIVE_OSC_BAD;
    for (int k = 3; k < argc; ++k)
      if (!is_num(types[k])) return KM_LIVE_OSC_BAD;
    int j = km_live_joint_index((const char *)argv[0]);
    if (j == -1) return KM_LIVE_OSC_BAD;
    double x = num(types[3], argv[3]), y = num(types[4], argv[4]), z = num(types[5], argv[5]);
    if (!isfinite(x) || !isfinite(y) || !isfinite(z) || !isfinite(num(types[6], argv[6])))
      return KM_LIVE_OSC_BAD;
    if (j == -2) return KM_LIVE_OSC_IGNORED;
    out->joint = j;
    out->user = user_id(types[2], argv[2]);
    /* centimetres, y pointing down; then Kinect camera space -> kinemesh (x,y,z)->(-x,y,-z) */
    out->p[0] = -x / 100.0;
    out->p[1] = -y / 100.0;
    out->p[2] = -z / 100.0;
    if (argc == 8) {
      double ts = num(types[7], argv[7]);
      if (!isfinite(ts)) return KM_LIVE_OSC_BAD;
      out->timestamp = ts;
    }
    return KM_LIVE_OSC_JOINT;
  }
  if (!strncmp(path, "/bodies/", 8)) {
    const char *id = path + 8, *slash = strchr(id, '/');
    if (!slash) return KM_LIVE_OSC_BAD;
    int user = 0;
    for (const char *c = id; c < slash && c - id < 9; ++c)
      if (*c >= '0' && *c <= '9') user = user * 10 + (*c - '0');
    if (strncmp(slash, "/joints/", 8)) return KM_LIVE_OSC_IGNORED; /* hands/{Left} states */
    int j = km_live_joint_index(slash + 8);
    if (j == -1) return KM_LIVE_OSC_BAD;
    if (argc < 3 || argc > 4 || !is_num(types[0]) || !is_num(types[1]) || !is_num(types[2]) ||
        (argc == 4 && types[3] != 's'))
      return KM_LIVE_OSC_BAD;
    double x = num(types[0], argv[0]), y = num(types[1], argv[1]), z = num(types[2], argv[2]);
    if (!isfinite(x) || !isfinite(y) || !isfinite(z)) return KM_LIVE_OSC_BAD;
    if (j == -2) return KM_LIVE_OSC_IGNORED;
    out->joint = j;
    out->user = user;
    out->p[0] = -x;
    out->p[1] = y;
    out->p[2] = -z;
    if (argc == 4 && !strcmp((const char *)argv[3], "NotTracked"))
      out->p[0] = out->p[1] = out->p[2] = NAN;
    return KM_LIVE_OSC_JOINT;
  }
  /* OSCeleton's /new_user, /new_skel, /lost_user and anything else a bridge sends. */
  return KM_LIVE_OSC_IGNORED;
}

/* A bundle element's or message's walk (see km_live_osc_packet); depth: bundle nesting. */
static int osc_element(const char *data, size_t size, int depth, km_live_osc_fn on_joint, void *ctx,
                       uint64_t *messages) {
  if (size >= 8 && !memcmp(data, "#bundle", 8)) {
    /* "#bundle\0", 8-byte time tag, then (int32 size, element)* */
    if (depth > 8 || size < 16) return 1;
    int bad = 0;
    size_t p = 16;
    while (p < size) {
      if (size - p < 4) return bad + 1;
      uint32_t n = ((uint32_t)(unsigned char)data[p] << 24) |
                   ((uint32_t)(unsigned char)data[p + 1] << 16) |
                   ((uint32_t)(unsigned char)data[p + 2] << 8) | (unsigned char)data[p + 3];
      p += 4;
      if (n > size - p || n % 4) return bad + 1;
      bad += osc_element(data + p, n, depth + 1, on_joint, ctx, messages);
      p += n;
    }
    return bad;
  }
  if (!size || !memchr(data, 0, size) || data[0] != '/') return 1;
  if (km_live_osc_has_blob(data, size)) { /* (why: live.h) bad on a tracker's path */
    km_live_osc_joint j;
    return km_live_parse_osc(data, "", NULL, 0, &j) == KM_LIVE_OSC_BAD;
  }
  int res = 0;
  /* lo_message_deserialise validates sizes, padding and type tags. */
  lo_message m = lo_message_deserialise((void *)data, size, &res);
  if (!m) return 1;
  ++*messages;
  km_live_osc_joint j;
  km_live_osc_kind k =
      km_live_parse_osc(data, lo_message_get_types(m), (void *const *)lo_message_get_argv(m),
                        lo_message_get_argc(m), &j);
  lo_message_free(m);
  if (k == KM_LIVE_OSC_JOINT && on_joint) on_joint(ctx, &j);
  return k == KM_LIVE_OSC_BAD;
}

int km_live_osc_packet(const char *data, size_t size, km_live_osc_fn on_joint, void *ctx,
                       uint64_t *messages) {
  uint64_t dummy = 0;
  if (!data) return 1;
  return osc_element(data, size, 0, on_joint, ctx, messages ? messages : &dummy);
}
