/* Live mode, the application target kinemesh_live: tracker input (OSC, JSON over UDP, a
 * replayed take) -> the puppetry pipeline (km_puppetry) -> WebSocket frames to browser pages,
 * plus the HTTP side (static page, /status, /mesh, /rig, /handles, POST /rig, POST /replay).
 * Built on include/kinemesh.h only; the only target that links libwebsockets and liblo. Its
 * users: the CLI's `live` verb, `bench live`, tests/test_live.c. */
#ifndef KM_LIVE_H
#define KM_LIVE_H

#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Overflow-checked allocations for the server (NULL on overflow or failure). */
static inline void *live_alloc(size_t count, size_t size) {
  return size && count > SIZE_MAX / size ? NULL : malloc(count && size ? count * size : 1);
}
static inline void *live_zalloc(size_t count, size_t size) {
  return calloc(count ? count : 1, size ? size : 1);
}

/* ---------------------------------------------------------------- input parsing */

/* Whether an OSC message (msg[0..size), its path NUL-terminated inside) has a blob ('b') among
 * its type tags. Such a message must not reach lo_message_deserialise: liblo 0.31's
 * lo_validate_blob reads a blob's 4-byte size word before checking that 4 bytes are left, a
 * read past the end of its copy of the message (fuzz_osc found it: a ",b" tag with the data
 * used up). No message kinemesh reads has a blob, so a caller judges one by its path alone. */
static inline int km_live_osc_has_blob(const char *msg, size_t size) {
  size_t tags = (strlen(msg) / 4 + 1) * 4; /* the path, NUL-padded to 4 bytes */
  if (tags >= size || msg[tags] != ',') return 0;
  const char *end = memchr(msg + tags, 0, size - tags);
  return end && memchr(msg + tags, 'b', (size_t)(end - (msg + tags))) != NULL;
}

/* Index of a tracker joint name in KM_KINECT1 order: Kinect v1 names (HandLeft), OSCeleton/
 * OpenNI names (l_hand, torso, waist, ...), then any skeleton of km_skeleton_kinect1_joint,
 * Kinect v2 first (SpineBase, SpineShoulder, ...; then HAND_LEFT, LeftMiddleProximal,
 * left_wrist, lhand, ...). -1: unknown name. -2: a known joint that has no Kinect v1
 * counterpart (HandTipLeft, ThumbRight, l_finger, r_collar, Neck of v2 when SpineShoulder is
 * sent, Jaw, ...). */
int km_live_joint_index(const char *name);

/* A JSON-lines UDP datagram (one frame): either {"joints": {"HandLeft": [x,y,z], ...}}
 * (names as above, null or absent = missing), {"joints": [60 numbers or nulls]} or a bare
 * array of 60 numbers, Kinect v1 order, metres in kinemesh space (y up, performer facing +z,
 * as in takes). joints: 60 doubles, NaN where missing. Returns the number of joints set, or
 * -1 for a malformed datagram (bad JSON, wrong count, non-numbers, non-finite values, no
 * known joint). With "skeleton": KIND (a km_skeleton_kind_from_name name, e.g. "mediapipe"),
 * "joints" is {name of KIND: [x,y,z] | null} or count(KIND)*3 numbers or nulls in KIND's
 * order, converted with km_skeleton_convert (trunk points made up, e.g. the pelvis between
 * MediaPipe's hips); the count returned is then of KIND's joints. The live page's camera
 * sends this over the WebSocket, the same parser as the UDP input. */
int km_live_parse_json(const char *data, size_t size, double *joints);

/* A tracker OSC message, already decoded by liblo. */
typedef enum km_live_osc_kind {
  KM_LIVE_OSC_BAD = -1,    /* malformed (wrong arity or types, NaN, unknown joint) */
  KM_LIVE_OSC_IGNORED = 0, /* valid but carries no v1 joint (hand states, /new_user, ...) */
  KM_LIVE_OSC_JOINT = 1
} km_live_osc_kind;
typedef struct km_live_osc_joint {
  int joint;        /* KM_KINECT1 index */
  int user;         /* OSCeleton user id or Kinect v2 body id (0 when it does not parse) */
  double p[3];      /* kinemesh space, metres; NaN when the tracker says "NotTracked" */
  double timestamp; /* OSCeleton trailing timestamp (ms); NaN when absent */
} km_live_osc_joint;
/* OSCeleton "/joint" siiffff[d] (name, sensor, user, x, y, z in cm with y down, confidence,
 * [timestamp ms]) and KinectV2-OSC "/bodies/{id}/joints/{Name}" fffs (metres, tracking state).
 * Both are Kinect camera space; they are turned into kinemesh space like the Kinect CSV
 * reader does (180 degrees about y). argv: liblo's argument array (lo_arg **). */
km_live_osc_kind km_live_parse_osc(const char *path, const char *types, void *const *argv, int argc,
                                   km_live_osc_joint *out);
/* One OSC UDP datagram: a message, or a bundle ("#bundle\0", 8-byte time tag, then (int32
 * size, element)*, nested at most 8 deep) whose messages are taken in order. Each message is
 * decoded by liblo and km_live_parse_osc; on_joint (may be NULL) gets every joint message.
 * *messages (may be NULL) grows by the messages liblo decoded. Returns the number of malformed
 * elements: a bundle with bad framing (the rest of that bundle is skipped), a message liblo
 * refuses, a KM_LIVE_OSC_BAD message. A message with a blob argument is not decoded (liblo 0.31
 * reads past the data on a truncated one): bad on a tracker's path, ignored on any other. */
typedef void (*km_live_osc_fn)(void *ctx, const km_live_osc_joint *j);
int km_live_osc_packet(const char *data, size_t size, km_live_osc_fn on_joint, void *ctx,
                       uint64_t *messages);

/* ---------------------------------------------------------------- VMC (live_vmc.c) */

/* VMC protocol receiver state (OSC over UDP; sh-akira/VirtualMotionCaptureProtocol):
 * /VMC/Ext/Root/Pos (s)"root" px py pz qx qy qz qw [sx sy sz ox oy oz] and /VMC/Ext/Bone/Pos
 * (s)HumanBodyBones-name px py pz qx qy qz qw (local, parent-relative) in Unity's left-handed
 * frame, converted on receipt to kinemesh's (km_humanoid_unity_convert: p -> (-x, y, z),
 * q -> (qx, -qy, -qz, qw), i.e. UniVRM's z flip then a half turn so the performer faces +z).
 * A frame is complete when its bundle ends, or, for senders that do not bundle, at the next
 * /VMC/Ext/OK or /VMC/Ext/T. Bones not resent keep their last value. */
typedef struct km_live_vmc {
  km_humanoid_pose pose;                   /* the newest pose, kinemesh's frame */
  double positions[3 * KM_HUMANOID_BONES]; /* its FK at the last frame (NaN: never sent) */
  /* issue 15: the last frame's world rotation of the bone ending at each Kinect v1 joint
   * (row-major, kinemesh's frame; NaN: its bone not sent), for km_puppetry_push_rotations */
  double rotations[9 * KM_KINECT1_JOINTS];
  bool pending;       /* pose data since the last frame */
  double sender_time; /* the last /VMC/Ext/T */
  uint64_t packets, messages, frames;
  uint64_t bad;        /* packets with a malformed element: truncated bundle, bad type tags,
                          wrong argument types or counts, non-finite numbers */
  uint64_t unknown;    /* messages with an address or bone name kinemesh does not use */
  uint64_t extra_args; /* Root/Bone messages with arguments beyond the 8 used */
} km_live_vmc;
typedef enum km_live_vmc_kind {
  KM_LIVE_VMC_BAD = -1,
  KM_LIVE_VMC_IGNORED = 0, /* unknown address or bone */
  KM_LIVE_VMC_POSE = 1,    /* Root/Pos or Bone/Pos taken */
  KM_LIVE_VMC_SYNC = 2     /* /VMC/Ext/OK or /VMC/Ext/T */
} km_live_vmc_kind;
void km_live_vmc_init(km_live_vmc *v);
/* One decoded message (argv: liblo's lo_arg **). */
km_live_vmc_kind km_live_vmc_message(km_live_vmc *v, const char *path, const char *types,
                                     void *const *argv, int argc);
/* One UDP packet (a message or a bundle). Returns 1 when it completed a frame: joints (60
 * doubles, KM_KINECT1 order, kinemesh space, NaN where the stream drives nothing) then holds
 * it; 0 otherwise. */
int km_live_vmc_packet(km_live_vmc *v, const void *data, size_t size, double *joints);
/* Sending (kinemesh vmc send): one frame's bundle as VMC senders make it (/VMC/Ext/OK 1,
 * /VMC/Ext/T t, /VMC/Ext/Root/Pos, /VMC/Ext/Bone/Pos per present bone, floats, Unity's frame).
 * km_live_vmc_bundle returns its bytes (malloc'ed, *len) or NULL. */
void *km_live_vmc_bundle(const km_humanoid_pose *pose, double t, size_t *len);
typedef struct km_live_vmc_out km_live_vmc_out;
/* host_port: "HOST:PORT". Errors: KM_ERR_INVALID for a malformed address. */
km_status km_live_vmc_out_open(const char *host_port, km_live_vmc_out **out, km_error *err);
/* Sends one frame. Errors: KM_ERR_IO (e.g. nothing listening reported by the system). */
km_status km_live_vmc_out_send(km_live_vmc_out *o, const km_humanoid_pose *pose, double t,
                               km_error *err);
void km_live_vmc_out_free(km_live_vmc_out **o);
/* The humanoid pose of 20 Kinect v1 joints (60 doubles, NaN missing), bones at the same body
 * point (km_humanoid_pose_from_positions). Errors: KM_ERR_INVALID when no joint is given. */
km_status km_live_vmc_pose_from_kinect1(const double *joints, km_humanoid_pose *pose,
                                        km_error *err);

/* ---------------------------------------------------------------- server */

typedef struct km_live_options {
  const char *bind;     /* listen address for HTTP, OSC and UDP; NULL: 127.0.0.1 */
  int http_port;        /* 8080 when 0 */
  int osc_port;         /* 0: no OSC input */
  int udp_port;         /* 0: no JSON/UDP input */
  int vmc_port;         /* 0: no VMC input (the protocol's receiver port is 39539) */
  const char *vmc_out;  /* "HOST:PORT": every deformed frame's filtered skeleton is sent there
                           as VMC bundles (humanoid bones); NULL: none */
  bool quantize;        /* frames as int16 quantised to the frame's bounding box, not float32 */
  bool loop;            /* replay the take in a loop */
  bool no_autoplay;     /* do not start the replay at start-up (page button / POST only) */
  const char *web_dir;  /* static page assets; NULL: no page (404) */
  const char *rig_path; /* written (atomically) on POST /rig; NULL: POST /rig refused */
  bool record;          /* keep every received raw frame for km_live_record_take */
  /* Access control (issue 18). Every request must name an allowed Host (localhost, 127.x,
   * [::1], the bound address; any IPv4 literal when bound to 0.0.0.0); POSTs and the
   * WebSocket must carry ?token=TOKEN, and their Origin, when sent, must be the page's own
   * (http://HOST); POST bodies must be application/json, at most KM_LIVE_MAX_POST bytes. Off
   * loopback the data GETs (/status, /mesh, /rig, /handles) need the token too. */
  const char *token; /* NULL: a random one per run (km_live_token); else >= 16 of [A-Za-z0-9_-] */
  bool no_token;     /* no token at all: refused unless bound to loopback */
  int max_clients;   /* WebSocket pages at once; 0: KM_LIVE_MAX_CLIENTS */
  size_t record_max; /* frames kept by `record`; 0: KM_LIVE_RECORD_MAX (older ones stay) */
} km_live_options;

#define KM_LIVE_MAX_POST (4u << 20)
#define KM_LIVE_MAX_CLIENTS 32
#define KM_LIVE_RECORD_MAX ((size_t)1 << 18) /* 2.4 hours at 30 fps, 126 MB */

typedef struct km_live km_live;

/* mesh and puppet (the reduced model) stay owned by the caller and must outlive the server,
 * which runs them in its own km_puppetry pipeline; the rig (rig_json, the rig file's text) is
 * set there with km_puppetry_set_rig, as POST /rig does later. replay: a take already in
 * KM_KINECT1 order (20 joints) or NULL. Binds the sockets (KM_ERR_IO naming the port when it
 * is taken) and starts the input and deformation threads; the HTTP service runs in
 * km_live_run. */
km_status km_live_create(const km_live_options *opt, const km_mesh *mesh, km_puppet *puppet,
                         const char *rig_json, size_t rig_size, const km_take *replay,
                         km_live **out, km_error *err);
/* The token the page and clients must send (?token=...), "" when none (no_token). */
const char *km_live_token(const km_live *l);
/* Serves until km_live_stop (callable from any thread and from a signal handler). */
km_status km_live_run(km_live *l, km_error *err);
void km_live_stop(km_live *l);
/* Starts (or restarts) the replay, as POST /replay does. false when there is no take. */
bool km_live_replay(km_live *l);

typedef struct km_live_stats {
  uint64_t frames_in, frames_out, frames_sent, frames_dropped;
  uint64_t osc_messages, udp_datagrams, bad_packets, solve_errors;
  uint64_t ws_messages; /* joint frames sent by pages over the WebSocket (the camera) */
  uint64_t vmc_packets, vmc_messages, vmc_frames, vmc_bad, vmc_unknown; /* VMC input */
  uint64_t vmc_out_frames, vmc_out_errors;                              /* --vmc-out */
  int clients;
  double lat_median_ms, lat_p99_ms;             /* packet received -> frame written to a socket */
  double t_retarget_ms, t_deform_ms, t_pack_ms; /* medians of the recent frames */
  size_t lat_count;
} km_live_stats;
void km_live_get_stats(km_live *l, km_live_stats *out);
/* Writes /status's JSON (malloc'ed, NUL-terminated). */
char *km_live_status_json(km_live *l);
/* The raw received frames as a take (fps measured from the arrival times). */
km_status km_live_record_take(km_live *l, const char *path, km_error *err);
void km_live_free(km_live **l);

/* Frame message layout (little-endian), shared with web/live.js:
 * u32 magic 'KMF1', u32 flags (1: int16 positions), u32 n_vertices, u32 frame seq,
 * u32 input seq, f32 retarget ms, f32 deform ms, f32 pack ms, f32 scale,
 * f32 bbox min[3], f32 bbox max[3], f32 joints[60] (filtered, in the character's space; NaN
 * missing), 4 bytes pad, then positions: f32[3n], or i16[3n] with p = c + q h / 32767 per
 * axis, c = (min + max) / 2 and h = (max - min) / 2 (q in [-32767, 32767]; 0 for NaN). */
#define KM_LIVE_MAGIC 0x31464d4bu
#define KM_LIVE_HEADER 304

/* The quantised payload: n vertices (V, 3n doubles) as int16 in the box lo..hi as above.
 * NaN becomes 0 (the centre); points outside the box are clamped to it. An axis with
 * hi <= lo (flat, or no finite point) gets 0 throughout. */
void km_live_quantize(const double *V, size_t n, const float lo[3], const float hi[3], int16_t *q);

#endif
