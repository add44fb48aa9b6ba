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

/* Overflow-checked allocations for the server (NULL on overflow or failure). */
static inline void *live_alloc(size_t count, size_t size) {
  return size && count > SIZE_MAX / size ? NULL : malloc(count && size ? count * size : 1);
}
static inline void *live_zalloc(size_t count, size_t size) {
  return calloc(count ? count : 1, size ? size : 1);
}

/* ---------------------------------------------------------------- input parsing */

/* Index of a tracker joint name in KM_KINECT1 order: Kinect v1 names (HandLeft), Kinect v2
 * names (SpineBase, SpineShoulder, WristLeft, ...) and OSCeleton/OpenNI names (l_hand, torso,
 * waist, ...). -1: unknown name. -2: a known joint that has no Kinect v1 counterpart
 * (HandTipLeft, ThumbRight, l_finger, r_collar, Neck of v2 when SpineShoulder is sent, ...). */
int km_live_joint_index(const char *name);

/* A JSON-lines UDP datagram (one frame): either {"joints": {"HandLeft": [x,y,z], ...}}
 * (names as above, null or absent = missing), {"joints": [60 numbers or nulls]} or a bare
 * array of 60 numbers, Kinect v1 order, metres in kinemesh space (y up, performer facing +z,
 * as in takes). joints: 60 doubles, NaN where missing. Returns the number of joints set, or
 * -1 for a malformed datagram (bad JSON, wrong count, non-numbers, non-finite values, no
 * known joint). */
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
km_live_osc_kind km_live_parse_osc(const char *path, const char *types, void *const *argv,
                                     int argc, km_live_osc_joint *out);

/* ---------------------------------------------------------------- server */

typedef struct km_live_options {
  const char *bind;     /* listen address for HTTP, OSC and UDP; NULL: 127.0.0.1 */
  int http_port;        /* 8080 when 0 */
  int osc_port;         /* 0: no OSC input */
  int udp_port;         /* 0: no JSON/UDP input */
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
