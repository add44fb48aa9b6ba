/* VMC protocol input for live mode (issue 15): OSC over UDP as VirtualMotionCapture, XR
 * Animator, VSeeFace, SlimeVR, Warudo... send it (sh-akira/VirtualMotionCaptureProtocol).
 * Messages are decoded by liblo; the pose is kept in kinemesh's frame (the library's
 * km_humanoid_unity_convert), turned into joint positions by the library's humanoid FK and
 * into the 20 Kinect v1 joints the pipeline runs on by body point (km_skeleton_convert). */
#include "live.h"

#include <lo/lo.h>
#include <math.h>
#include <string.h>
#include <stdlib.h>

void km_live_vmc_init(km_live_vmc *v) {
  memset(v, 0, sizeof *v);
  v->pose.root[6] = 1; /* identity until a /VMC/Ext/Root/Pos arrives */
}

static bool is_num(char t) { return t == 'f' || t == 'd' || t == 'i'; }

/* liblo's argument pointers are 4-byte aligned while lo_arg wants 8: read through memcpy. */
static double num(char t, const void *a) {
  if (t == 'f') {
    float f;
    memcpy(&f, a, sizeof f);
    return f;
  }
  if (t == 'd') {
    double d;
    memcpy(&d, a, sizeof d);
    return d;
  }
  int32_t i;
  memcpy(&i, a, sizeof i);
  return i;
}

/* s + 7 numbers (position, quaternion x y z w) into p[7], converted to kinemesh's frame.
 * Extra arguments (Root/Pos's scale and offset, v2.1) are counted, not used. */
static km_live_vmc_kind read_pos(km_live_vmc *v, const char *types, const void *const *argv,
                                 int argc, double p[7]) {
  if (argc < 8 || types[0] != 's') return KM_LIVE_VMC_BAD;
  for (int k = 1; k < 8; ++k) {
    if (!is_num(types[k])) return KM_LIVE_VMC_BAD;
    p[k - 1] = num(types[k], argv[k]);
    if (!isfinite(p[k - 1])) return KM_LIVE_VMC_BAD;
  }
  double qn = p[3] * p[3] + p[4] * p[4] + p[5] * p[5] + p[6] * p[6];
  if (!(qn > 1e-12)) return KM_LIVE_VMC_BAD;
  if (argc > 8) ++v->extra_args;
  km_humanoid_unity_convert(p, p + 3);
  return KM_LIVE_VMC_POSE;
}

km_live_vmc_kind km_live_vmc_message(km_live_vmc *v, const char *path, const char *types,
                                     void *const *argv_, int argc) {
  const void *const *argv = (const void *const *)argv_;
  if (!path || !types || argc < 0 || (int)strlen(types) != argc) return KM_LIVE_VMC_BAD;
  ++v->messages;
  if (!strcmp(path, "/VMC/Ext/Bone/Pos")) {
    double p[7];
    km_live_vmc_kind k = read_pos(v, types, argv, argc, p);
    if (k != KM_LIVE_VMC_POSE) return k;
    int b = km_skeleton_joint_index(KM_SKELETON_HUMANOID, (const char *)argv[0]);
    if (b < 0) {
      ++v->unknown;
      return KM_LIVE_VMC_IGNORED;
    }
    memcpy(v->pose.bone + 7 * b, p, sizeof p);
    v->pose.present[b] = true;
    v->pending = true;
    return KM_LIVE_VMC_POSE;
  }
  if (!strcmp(path, "/VMC/Ext/Root/Pos")) {
    double p[7];
    km_live_vmc_kind k = read_pos(v, types, argv, argc, p);
    if (k != KM_LIVE_VMC_POSE) return k;
    memcpy(v->pose.root, p, sizeof p);
    v->pending = true;
    return KM_LIVE_VMC_POSE;
  }
  if (!strcmp(path, "/VMC/Ext/OK") || !strcmp(path, "/VMC/Ext/T")) {
    /* OK: i loaded [i calibration state, i calibration mode [i tracking]]; T: f time. */
    if (argc < 1 || !is_num(types[0])) return KM_LIVE_VMC_BAD;
    if (path[9] == 'T') v->sender_time = num(types[0], argv[0]);
    return KM_LIVE_VMC_SYNC;
  }
  ++v->unknown; /* blend shapes, camera, trackers (/VMC/Ext/Tra/Pos), ... */
  return KM_LIVE_VMC_IGNORED;
}

/* The pose so far as Kinect v1 joints, and their bones' rotations: the bone ending at
 * Kinect joint j is the humanoid bone whose child stands at j's body point (LeftLowerArm for
 * WristLeft, LeftHand for HandLeft). */
static void frame_out(km_live_vmc *v, double *joints) {
  double P[3 * KM_HUMANOID_BONES], R[9 * KM_HUMANOID_BONES];
  km_humanoid_fk(&v->pose, P, R);
  memcpy(v->positions, P, sizeof P);
  km_skeleton_convert(KM_SKELETON_HUMANOID, P, KM_SKELETON_KINECT1, joints);
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    int b = km_skeleton_joint_map(KM_SKELETON_KINECT1, j, KM_SKELETON_HUMANOID);
    int q = b >= 0 ? km_skeleton_joint_parent(KM_SKELETON_HUMANOID, b) : -1;
    for (int k = 0; k < 9; ++k)
      v->rotations[9 * j + k] = b < 0 ? NAN : R[9 * (q >= 0 ? q : b) + k];
  }
  v->pending = false;
  ++v->frames;
}

static uint32_t be32(const unsigned char *p) {
  return ((uint32_t)p[0] << 24) | ((uint32_t)p[1] << 16) | ((uint32_t)p[2] << 8) | p[3];
}

/* One element: a message (a sync message outside a bundle ends a frame) or a nested bundle.
 * Returns false when the element is malformed. */
static bool element(km_live_vmc *v, const unsigned char *d, size_t n, int depth, bool in_bundle,
                    double *joints, int *frames) {
  if (n >= 8 && !memcmp(d, "#bundle", 8)) {
    if (depth > 4 || n < 16) return false;
    bool ok = true;
    for (size_t p = 16; p < n && ok;) {
      uint32_t len = n - p >= 4 ? be32(d + p) : 0;
      p += 4;
      if (p > n || len > n - p || len % 4) {
        ok = false;
        break;
      }
      ok &= element(v, d + p, len, depth + 1, true, joints, frames);
      p += len;
    }
    /* A frame is complete when its bundle ends; a malformed (e.g. truncated) bundle makes none
     * (what it held is kept and goes out with the next frame). */
    if (depth == 0 && v->pending) {
      if (ok) {
        frame_out(v, joints);
        ++*frames;
      } else {
        v->pending = false;
      }
    }
    return ok;
  }
  if (!n || d[0] != '/' || !memchr(d, 0, n)) return false;
  if (km_live_osc_has_blob((const char *)d, n)) /* (why: live.h) judged by its path alone */
    return km_live_vmc_message(v, (const char *)d, "", NULL, 0) != KM_LIVE_VMC_BAD;
  int res = 0;
  /* lo_message_deserialise checks sizes, padding and type tags against the payload. */
  lo_message m = lo_message_deserialise((void *)d, n, &res);
  if (!m) return false;
  km_live_vmc_kind k =
      km_live_vmc_message(v, (const char *)d, lo_message_get_types(m),
                          (void *const *)lo_message_get_argv(m), lo_message_get_argc(m));
  lo_message_free(m);
  if (k == KM_LIVE_VMC_BAD) return false;
  if (k == KM_LIVE_VMC_SYNC && !in_bundle && v->pending) {
    frame_out(v, joints);
    ++*frames;
  }
  return true;
}

int km_live_vmc_packet(km_live_vmc *v, const void *data, size_t size, double *joints) {
  ++v->packets;
  int frames = 0;
  if (!element(v, data, size, 0, false, joints, &frames)) ++v->bad;
  return frames > 0;
}

/* ---------------------------------------------------------------- sending */

static lo_message pos_message(const char *name, const double *p7) {
  lo_message m = lo_message_new();
  if (!m) return NULL;
  double p[7];
  memcpy(p, p7, sizeof p);
  km_humanoid_unity_convert(p, p + 3); /* its own inverse: kinemesh -> Unity */
  lo_message_add_string(m, name);
  for (int k = 0; k < 7; ++k)
    lo_message_add_float(m, (float)p[k]);
  return m;
}

/* One frame as VMC senders bundle it: OK, T, Root/Pos, then Bone/Pos per present bone. */
static lo_bundle frame_bundle(const km_humanoid_pose *pose, double t) {
  lo_bundle b = lo_bundle_new(LO_TT_IMMEDIATE);
  if (!b) return NULL;
  lo_message ok = lo_message_new(), tm = lo_message_new();
  bool good = ok && tm;
  if (ok) lo_message_add_int32(ok, 1);
  if (tm) lo_message_add_float(tm, (float)t);
  if (ok) good &= lo_bundle_add_message(b, "/VMC/Ext/OK", ok) == 0;
  if (tm) good &= lo_bundle_add_message(b, "/VMC/Ext/T", tm) == 0;
  lo_message r = pos_message("root", pose->root);
  good &= r && lo_bundle_add_message(b, "/VMC/Ext/Root/Pos", r) == 0;
  for (int k = 0; good && k < KM_HUMANOID_BONES; ++k) {
    if (!pose->present[k]) continue;
    lo_message m = pos_message(km_skeleton_joint_name(KM_SKELETON_HUMANOID, k), pose->bone + 7 * k);
    good &= m && lo_bundle_add_message(b, "/VMC/Ext/Bone/Pos", m) == 0;
  }
  if (!good) {
    lo_bundle_free_recursive(b);
    return NULL;
  }
  return b;
}

void *km_live_vmc_bundle(const km_humanoid_pose *pose, double t, size_t *len) {
  lo_bundle b = frame_bundle(pose, t);
  if (!b) return NULL;
  void *data = lo_bundle_serialise(b, NULL, len);
  lo_bundle_free_recursive(b);
  return data;
}

struct km_live_vmc_out {
  lo_address addr;
};

km_status km_live_vmc_out_open(const char *host_port, km_live_vmc_out **out, km_error *err) {
  *out = NULL;
  char host[256];
  const char *colon = host_port ? strrchr(host_port, ':') : NULL;
  if (!colon || colon == host_port || (size_t)(colon - host_port) >= sizeof host || !colon[1] ||
      strspn(colon + 1, "0123456789") != strlen(colon + 1) || atoi(colon + 1) < 1 ||
      atoi(colon + 1) > 65535)
    return km_error_set(err, KM_ERR_INVALID, "--to %s: expected HOST:PORT (e.g. 127.0.0.1:39539)",
                        host_port ? host_port : "(null)");
  memcpy(host, host_port, (size_t)(colon - host_port));
  host[colon - host_port] = 0;
  km_live_vmc_out *o = live_zalloc(1, sizeof *o);
  if (!o) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  o->addr = lo_address_new(host, colon + 1);
  if (!o->addr) {
    free(o);
    return km_error_set(err, KM_ERR_INVALID, "--to %s: cannot use this address", host_port);
  }
  *out = o;
  return KM_OK;
}

km_status km_live_vmc_out_send(km_live_vmc_out *o, const km_humanoid_pose *pose, double t,
                               km_error *err) {
  lo_bundle b = frame_bundle(pose, t);
  if (!b) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  int r = lo_send_bundle(o->addr, b);
  lo_bundle_free_recursive(b);
  if (r < 0)
    return km_error_set(err, KM_ERR_IO, "VMC send to %s:%s: %s", lo_address_get_hostname(o->addr),
                        lo_address_get_port(o->addr), lo_address_errstr(o->addr));
  return KM_OK;
}

void km_live_vmc_out_free(km_live_vmc_out **o) {
  if (!o || !*o) return;
  lo_address_free((*o)->addr);
  free(*o);
  *o = NULL;
}

km_status km_live_vmc_pose_from_kinect1(const double *joints, km_humanoid_pose *pose,
                                        km_error *err) {
  double hum[3 * KM_HUMANOID_BONES];
  for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
    /* the same body point only: a fallback would put two bones at one place */
    int k1 = km_skeleton_joint_map(KM_SKELETON_HUMANOID, b, KM_SKELETON_KINECT1);
    for (int a = 0; a < 3; ++a)
      hum[3 * b + a] = k1 >= 0 ? joints[3 * k1 + a] : NAN;
  }
  return km_humanoid_pose_from_positions(hum, pose, err);
}
