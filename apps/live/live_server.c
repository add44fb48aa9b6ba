/* Live mode server. Three threads:
 *  - input: polls the OSC and JSON UDP sockets (its own sockets so they bind to the requested
 *    address; liblo only decodes), assembles per-joint OSC messages into frames and plays the
 *    replay take on time. It stores only the newest joint frame (latest wins).
 *  - deform: takes the newest frame, pushes it through the km_puppetry pipeline (filter ->
 *    retarget -> reduced solve), packs a frame message into a double buffer and wakes the
 *    service loop with lws_cancel_service.
 *  - service (the caller of km_live_run): libwebsockets HTTP + WebSocket. Each page has one
 *    pending slot: on WRITEABLE it sends the newest frame if it has not sent it yet, so a slow
 *    page skips frames instead of queueing them.
 * The rig can be replaced at run time (POST /rig): the deform thread hands it to
 * km_puppetry_set_rig (no eigen precompute; the new retarget is seeded with the reference
 * pose already seen, so the character does not jump). */
#include "live.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <libwebsockets.h>
#include <lo/lo.h>
#include <math.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#define NJ KM_KINECT1_JOINTS
#define RING 2048
#define MAX_POST KM_LIVE_MAX_POST

typedef struct ring {
  double v[RING];
  size_t n, head;
} ring;

static void ring_push(ring *r, double x) {
  r->v[r->head] = x;
  r->head = (r->head + 1) % RING;
  if (r->n < RING) ++r->n;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Quantile of the ring's content (copies; called on /status only). */
static double ring_q(const ring *r, double q) {
  if (!r->n) return NAN;
  double *tmp = malloc(sizeof(double) * r->n);
  if (!tmp) return NAN;
  memcpy(tmp, r->v, sizeof(double) * r->n);
  qsort(tmp, r->n, sizeof(double), cmp_d);
  size_t k = (size_t)ceil(q * (double)r->n) - (q > 0);
  if (k >= r->n) k = r->n - 1;
  double out = tmp[k];
  free(tmp);
  return out;
}

/* OSC messages arrive one joint at a time: this gathers them into frames. */
typedef struct assembler {
  double state[NJ * 3];
  uint32_t pending, learned;
  int user;
  double user_t, first_t, last_t, ts;
} assembler;

typedef struct live_rig {
  km_rig rig;
  char *text;
  size_t len;
  uint64_t gen; /* the POST /rig it came from (1, 2, ...); 0 for the rig the server started with */
} live_rig;

/* A POST /rig handed to the rig thread (parse, merge, write, apply) so the service thread
 * keeps serving pages and frames; the answer goes back to the waiting connection. */
typedef struct rig_job {
  pthread_mutex_t mu;
  pthread_cond_t cv;
  bool busy;       /* from the hand-over until the answer is taken (or its asker is gone) */
  bool queued;     /* body waiting for the rig thread */
  bool done;       /* status + reply ready */
  struct lws *wsi; /* the connection waiting for the answer; NULL once it closed */
  char *body;
  size_t len;
  unsigned status;
  char *reply;
} rig_job;

struct km_live {
  km_live_options opt;
  char bind[64];
  char *web_dir, *rig_path;
  const km_mesh *mesh;
  km_puppetry *pipe;
  const km_take *take;

  /* deform-thread state */
  km_rig rig;
  double *V;
  double rest_joints[NJ * 3];

  /* input slot */
  pthread_mutex_t in_mu;
  pthread_cond_t in_cv;
  double in_joints[NJ * 3];
  double in_rot[NJ * 9]; /* the VMC bones' rotations of the newest frame (issue 15) */
  bool in_has_rot;
  double in_t;
  uint64_t in_seq, taken_seq;
  bool reset_req;
  live_rig pending; /* rig.handles != NULL or text != NULL: a rig to apply */
  bool has_pending;
  double *rec;
  size_t rec_n, rec_cap;
  double rec_t0, rec_t1;

  /* output double buffer (each LWS_PRE + frame_size bytes) */
  pthread_mutex_t out_mu;
  unsigned char *out_latest, *out_work;
  size_t frame_size;
  uint64_t out_seq;
  double out_t_recv;
  uint64_t woke_seq; /* service thread only */
  uint64_t lat_seq;  /* service thread only: newest frame whose latency was recorded */

  /* stats */
  pthread_mutex_t st_mu;
  ring lat, t_rt, t_def, t_pack, out_times;
  double *handle_pos;  /* n_handles*3 current handle centroid targets */
  char **handle_names; /* n_handles */
  size_t n_handles;
  char *rig_text; /* GET /rig */
  size_t rig_len;
  char *handles_json; /* GET /handles */
  uint64_t rig_gen;   /* POST /rig requests saved so far (st_mu) */
  atomic_uint_fast64_t frames_in, frames_out, frames_sent, frames_dropped, osc_messages,
      udp_datagrams, bad_packets, solve_errors;
  atomic_uint_fast64_t ws_messages; /* joint frames from pages (the camera), good or bad */
  atomic_uint_fast64_t vmc_packets, vmc_messages, vmc_frames, vmc_bad, vmc_unknown;
  atomic_uint_fast64_t vmc_out_frames, vmc_out_errors;
  km_live_vmc_out *vmc_out; /* deformation thread only */
  km_live_vmc vmc;          /* input thread only */
  atomic_int clients;

  /* threads, sockets */
  pthread_t in_thr, def_thr;
  bool in_started, def_started;
  atomic_int stop;
  atomic_int replay_req;
  atomic_bool replaying; /* the replay thread is playing the take (for /status) */
  int osc_fd, udp_fd, vmc_fd;
  struct lws_context *ctx;
  struct lws_protocols protocols[3];
  unsigned char *mesh_blob;
  size_t mesh_len;

  /* access control, POST /rig off the service thread */
  char token[72]; /* "" when none */
  bool loopback;  /* bound to 127.x */
  rig_job job;
  pthread_t rig_thr;
  bool rig_started;
};

/* ================================================================ rig handling */

/* Rest joints of the character (rig sidecar "joints": [{"name", "rest"}]) for the skeleton
 * overlay; without them the overlay is centred on the mesh's bounding box. */
static void read_rest_joints(km_live *l, const char *text, size_t len) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < l->mesh->n_vertices; ++v)
    for (int a = 0; a < 3; ++a) {
      double x = l->mesh->V[3 * v + a];
      lo[a] = x < lo[a] ? x : lo[a];
      hi[a] = x > hi[a] ? x : hi[a];
    }
  for (int j = 0; j < NJ; ++j)
    for (int a = 0; a < 3; ++a)
      l->rest_joints[3 * j + a] = 0.5 * (lo[a] + hi[a]);
  cJSON *doc = cJSON_ParseWithLength(text, len);
  const cJSON *js = cJSON_GetObjectItemCaseSensitive(doc, "joints");
  for (const cJSON *e = cJSON_IsArray(js) ? js->child : NULL; e; e = e->next) {
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(e, "name");
    const cJSON *r = cJSON_GetObjectItemCaseSensitive(e, "rest");
    int j = cJSON_IsString(n) ? km_live_joint_index(n->valuestring) : -1;
    if (j < 0 || !cJSON_IsArray(r) || cJSON_GetArraySize(r) != 3) continue;
    for (int a = 0; a < 3; ++a) {
      const cJSON *x = cJSON_GetArrayItem(r, a);
      if (cJSON_IsNumber(x)) l->rest_joints[3 * j + a] = x->valuedouble;
    }
  }
  cJSON_Delete(doc);
}

static char *handles_json(const km_rig *rig) {
  cJSON *doc = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(doc, "handles");
  for (size_t h = 0; h < rig->n_handles; ++h) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", rig->handles[h].name);
    cJSON *vs = cJSON_AddArrayToObject(o, "vertices");
    for (size_t i = 0; i < rig->handles[h].n_vertices; ++i)
      cJSON_AddItemToArray(vs, cJSON_CreateNumber(rig->handles[h].vertices[i]));
    cJSON_AddItemToArray(arr, o);
  }
  char *s = cJSON_PrintUnformatted(doc);
  cJSON_Delete(doc);
  return s;
}

/* A rig whose "handles" array is empty (`live --no-handles`, or a file written that way): the
 * server starts idle, showing the rest mesh, until the page's first handle is saved (POST
 * /rig). km_rig_parse refuses such a rig, so this is checked on the JSON. Returns 1 for an
 * empty or absent "handles", 0 when it has handles, -1 when the text is not a JSON object. */
static int rig_text_without_handles(const char *text, size_t len) {
  cJSON *doc = cJSON_ParseWithLength(text, len);
  if (!cJSON_IsObject(doc)) {
    cJSON_Delete(doc);
    return -1;
  }
  const cJSON *h = cJSON_GetObjectItemCaseSensitive(doc, "handles");
  int r = !h || (cJSON_IsArray(h) && cJSON_GetArraySize(h) == 0);
  cJSON_Delete(doc);
  return r;
}

/* Publishes the handle list of the active rig (all taken over) for /status, /rig and
 * /handles, freeing the previous one. `gen` is the POST /rig the rig came from: /rig and
 * /handles already answer with a newer saved rig when the deformation thread applies an older
 * one (two saves in quick succession), and keep that answer, so a page that saved rig 3 never
 * reads rig 2 back. */
static void publish_handles(km_live *l, uint64_t gen, char **names, double *hpos, size_t n,
                            char *text, size_t len, char *hj) {
  pthread_mutex_lock(&l->st_mu);
  for (size_t h = 0; h < l->n_handles; ++h)
    free(l->handle_names[h]);
  free(l->handle_names);
  free(l->handle_pos);
  l->handle_names = names;
  l->handle_pos = hpos;
  l->n_handles = n;
  if (gen >= l->rig_gen) {
    free(l->rig_text);
    free(l->handles_json);
    l->rig_text = text;
    l->rig_len = len;
    l->handles_json = hj;
  } else {
    free(text);
    free(hj);
  }
  pthread_mutex_unlock(&l->st_mu);
}

/* Installs a rig with no handles (text taken over): no puppetry rig, no frames deformed; the
 * page shows the rest mesh and places the first handle. */
static km_status apply_idle_rig(km_live *l, char *text, size_t len, km_error *err) {
  char *hj = strdup("{\"handles\":[]}");
  if (!hj) return km_error_set(err, KM_ERR_NOMEM, "out of memory for the rig");
  read_rest_joints(l, text, len);
  km_rig_free(&l->rig);
  memset(&l->rig, 0, sizeof l->rig);
  publish_handles(l, 0, NULL, NULL, 0, text, len, hj);
  return KM_OK;
}

/* Installs `nr` (taken over on success) as the active rig: km_puppetry_set_rig (handles,
 * filter, retarget seeded with the pose already seen), then the handle list and overlay. */
static km_status apply_rig(km_live *l, live_rig *nr, km_error *err) {
  km_rig *rig = &nr->rig;
  if (rig->skeleton != KM_RIG_KINECT1)
    return km_error_set(err, KM_ERR_INVALID, "live mode needs a \"kinect1\" rig");
  if (rig->n_handles == 0) return km_error_set(err, KM_ERR_INVALID, "the rig has no handles");
  double *hpos = live_alloc(3 * rig->n_handles, sizeof(double));
  char **names = live_zalloc(rig->n_handles, sizeof(char *));
  km_status s = KM_OK;
  if (!hpos || !names) {
    s = km_error_set(err, KM_ERR_NOMEM, "out of memory for the rig");
    goto fail;
  }
  for (size_t h = 0; h < rig->n_handles; ++h)
    if (!(names[h] = strdup(rig->handles[h].name))) {
      s = km_error_set(err, KM_ERR_NOMEM, "out of memory for the rig");
      goto fail;
    }
  if ((s = km_puppetry_set_rig(l->pipe, rig, err)) != KM_OK) goto fail;
  memcpy(hpos, km_puppetry_handle_targets(l->pipe), sizeof(double) * 3 * rig->n_handles);
  char *hj = handles_json(rig);
  read_rest_joints(l, nr->text, nr->len);

  km_rig_free(&l->rig);
  l->rig = *rig;
  memset(rig, 0, sizeof *rig);

  publish_handles(l, nr->gen, names, hpos, l->rig.n_handles, nr->text, nr->len, hj);
  nr->text = NULL;
  return KM_OK;
fail:
  if (names)
    for (size_t h = 0; h < rig->n_handles; ++h)
      free(names[h]);
  free(names);
  free(hpos);
  return s;
}

/* ================================================================ input */

/* A frame of joints (and rot: NJ*9 joint rotations, or NULL) for the deform thread. */
static void push_frame_rot(km_live *l, const double *joints, const double *rot, double t_recv,
                           bool reset) {
  pthread_mutex_lock(&l->in_mu);
  if (l->in_seq != l->taken_seq) atomic_fetch_add(&l->frames_dropped, 1);
  memcpy(l->in_joints, joints, sizeof l->in_joints);
  l->in_has_rot = rot != NULL;
  if (rot) memcpy(l->in_rot, rot, sizeof l->in_rot);
  l->in_t = t_recv;
  ++l->in_seq;
  if (reset) l->reset_req = true;
  if (l->opt.record && l->rec_n < l->opt.record_max) {
    if (l->rec_n == l->rec_cap) {
      size_t cap = l->rec_cap ? 2 * l->rec_cap : 1024;
      double *r = realloc(l->rec, sizeof(double) * 3 * NJ * cap);
      if (r) {
        l->rec = r;
        l->rec_cap = cap;
      }
    }
    if (l->rec_n < l->rec_cap) {
      memcpy(l->rec + 3 * NJ * l->rec_n++, joints, sizeof(double) * 3 * NJ);
      if (l->rec_n == 1) l->rec_t0 = t_recv;
      l->rec_t1 = t_recv;
    }
  }
  pthread_cond_signal(&l->in_cv);
  pthread_mutex_unlock(&l->in_mu);
  atomic_fetch_add(&l->frames_in, 1);
}

static void push_frame(km_live *l, const double *joints, double t_recv, bool reset) {
  push_frame_rot(l, joints, NULL, t_recv, reset);
}

/* a usable joint: every coordinate finite (an OSC float may carry inf as well as NaN) */
static bool valid3(const double *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

static void asm_commit(km_live *l, assembler *a) {
  if (!a->pending) return;
  double snap[3 * NJ];
  memcpy(snap, a->state, sizeof snap);
  /* OpenNI has no pelvis joint unless the bridge sends "waist": the mid-hip stands in. */
  if (!valid3(snap) && valid3(snap + 3 * 12) && valid3(snap + 3 * 16))
    for (int k = 0; k < 3; ++k)
      snap[k] = 0.5 * (snap[3 * 12 + k] + snap[3 * 16 + k]);
  a->learned |= a->pending;
  a->pending = 0;
  push_frame(l, snap, a->first_t, false);
}

static void asm_joint(km_live *l, assembler *a, const km_live_osc_joint *j, double now) {
  /* One performer at a time: another body takes over after 0.5 s of silence. */
  if (a->user != j->user) {
    if (a->user != INT32_MIN && now - a->user_t < 0.5) return;
    asm_commit(l, a);
    a->user = j->user;
    a->learned = 0;
    for (int k = 0; k < 3 * NJ; ++k)
      a->state[k] = NAN;
  }
  a->user_t = now;
  uint32_t bit = 1u << j->joint;
  /* A frame ends when a joint repeats or the bridge's timestamp changes. */
  if (a->pending &&
      ((a->pending & bit) || (!isnan(j->timestamp) && !isnan(a->ts) && j->timestamp != a->ts)))
    asm_commit(l, a);
  if (!a->pending) a->first_t = now;
  a->ts = j->timestamp;
  memcpy(a->state + 3 * j->joint, j->p, sizeof j->p);
  a->pending |= bit;
  a->last_t = now;
  /* ... or as soon as every joint this bridge sends has arrived. */
  if (a->learned && (a->pending & a->learned) == a->learned) asm_commit(l, a);
}

typedef struct osc_ctx {
  km_live *l;
  assembler *a;
  double now;
} osc_ctx;
static void on_osc_joint(void *ctx, const km_live_osc_joint *j) {
  osc_ctx *o = ctx;
  asm_joint(o->l, o->a, j, o->now);
}

/* One OSC datagram: its joints into the assembler, its counts into /status. */
static void handle_osc(km_live *l, assembler *a, const char *data, size_t size, double now) {
  osc_ctx o = {l, a, now};
  uint64_t messages = 0;
  int bad = km_live_osc_packet(data, size, on_osc_joint, &o, &messages);
  atomic_fetch_add(&l->osc_messages, messages);
  if (bad) atomic_fetch_add(&l->bad_packets, (uint64_t)bad);
}

/* VMC packets: a frame per bundle; the counters published for /status. */
static void drain_vmc(km_live *l, unsigned char *buf, size_t cap) {
  km_live_vmc *v = &l->vmc;
  uint64_t bad0 = v->bad;
  for (int i = 0; i < 4096; ++i) {
    ssize_t n = recv(l->vmc_fd, buf, cap, MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0) break;
    double now = km_seconds(), joints[3 * NJ];
    if ((size_t)n > cap) {
      ++v->packets;
      ++v->bad;
      continue;
    }
    if (km_live_vmc_packet(v, buf, (size_t)n, joints))
      push_frame_rot(l, joints, v->rotations, now, false);
  }
  atomic_store(&l->vmc_packets, v->packets);
  atomic_store(&l->vmc_messages, v->messages);
  atomic_store(&l->vmc_frames, v->frames);
  atomic_store(&l->vmc_bad, v->bad);
  atomic_store(&l->vmc_unknown, v->unknown);
  if (v->bad > bad0) atomic_fetch_add(&l->bad_packets, v->bad - bad0);
}

static void drain(km_live *l, int fd, bool osc, assembler *a, unsigned char *buf, size_t cap) {
  for (int i = 0; i < 4096; ++i) {
    ssize_t n = recv(fd, buf, cap, MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0) return;
    double now = km_seconds();
    if ((size_t)n > cap) {
      atomic_fetch_add(&l->bad_packets, 1);
      continue;
    }
    if (osc) {
      handle_osc(l, a, (const char *)buf, (size_t)n, now);
    } else {
      atomic_fetch_add(&l->udp_datagrams, 1);
      double joints[3 * NJ];
      if (km_live_parse_json((const char *)buf, (size_t)n, joints) < 0)
        atomic_fetch_add(&l->bad_packets, 1);
      else
        push_frame(l, joints, now, false);
    }
  }
}

static void *input_main(void *arg) {
  km_live *l = arg;
  size_t cap = 65536;
  unsigned char *buf = malloc(cap);
  assembler a;
  memset(&a, 0, sizeof a);
  a.user = INT32_MIN;
  a.ts = NAN;
  for (int k = 0; k < 3 * NJ; ++k)
    a.state[k] = NAN;
  bool playing = false;
  size_t next = 0;
  double t0 = 0, fps = l->take && l->take->fps > 0 ? l->take->fps : 30;
  while (buf && !atomic_load(&l->stop)) {
    if (atomic_load(&l->replay_req) && l->take && l->take->n_frames) {
      /* replaying before the request is cleared: /status never sees neither */
      atomic_store(&l->replaying, true);
      atomic_store(&l->replay_req, 0);
      playing = true;
      next = 0;
      t0 = km_seconds();
    }
    double now = km_seconds(), wait = 0.05;
    if (playing) {
      /* Latest wins here too: when late, jump to the frame that is due now. */
      size_t due = (size_t)floor((now - t0) * fps);
      if (due >= next) {
        if (due >= l->take->n_frames) {
          if (l->opt.loop) {
            t0 += (double)l->take->n_frames / fps;
            due %= l->take->n_frames;
          } else {
            due = l->take->n_frames - 1;
          }
        }
        push_frame(l, l->take->positions + 3 * NJ * due, now, next == 0);
        next = due + 1;
        if (next >= l->take->n_frames && !l->opt.loop) {
          playing = false;
          atomic_store(&l->replaying, false);
        }
      }
      if (playing) {
        double tn = t0 + (double)next / fps - now;
        wait = tn < wait ? tn : wait;
      }
    }
    if (a.pending) {
      double td = a.last_t + 0.010 - now;
      if (td <= 0) {
        asm_commit(l, &a);
      } else if (td < wait) {
        wait = td;
      }
    }
    struct pollfd p[3];
    int np = 0, io = -1, iu = -1, iv = -1;
    if (l->osc_fd >= 0) {
      p[np] = (struct pollfd){.fd = l->osc_fd, .events = POLLIN};
      io = np++;
    }
    if (l->udp_fd >= 0) {
      p[np] = (struct pollfd){.fd = l->udp_fd, .events = POLLIN};
      iu = np++;
    }
    if (l->vmc_fd >= 0) {
      p[np] = (struct pollfd){.fd = l->vmc_fd, .events = POLLIN};
      iv = np++;
    }
    if (wait < 0) wait = 0;
    struct timespec ts = {(time_t)wait, (long)((wait - floor(wait)) * 1e9)};
    int r = ppoll(p, (nfds_t)np, &ts, NULL);
    if (r <= 0) continue;
    if (io >= 0 && (p[io].revents & POLLIN)) drain(l, l->osc_fd, true, &a, buf, cap);
    if (iu >= 0 && (p[iu].revents & POLLIN)) drain(l, l->udp_fd, false, &a, buf, cap);
    if (iv >= 0 && (p[iv].revents & POLLIN)) drain_vmc(l, buf, cap);
  }
  free(buf);
  return NULL;
}

/* ================================================================ deformation */

void km_live_quantize(const double *V, size_t n, const float lo[3], const float hi[3], int16_t *q) {
  /* Centred so the page decodes x = c + q h / 32767 with the lo/hi it already has. */
  float c[3], sc[3];
  for (int a = 0; a < 3; ++a) {
    float h = 0.5f * (hi[a] - lo[a]);
    c[a] = 0.5f * (lo[a] + hi[a]);
    sc[a] = h > 0 ? 32767.0f / h : 0.0f;
  }
  for (size_t v = 0; v < n; ++v)
    for (int a = 0; a < 3; ++a) {
      /* q + 32768.5: positive, so truncation rounds (lrintf is 5x slower here) */
      float t = ((float)V[3 * v + a] - c[a]) * sc[a] + 32768.5f;
      /* Selects the compiler turns into vector blends. Below the range clamps to -32767, NaN
       * (no comparison holds) goes to 0; the clamps also catch the rounding of c and h pushing
       * the box's own extremes just past +-32767. */
      t = t >= 1.0f ? t : (t < 1.0f ? 1.0f : 32768.5f);
      t = t < 65535.5f ? t : 65535.0f;
      q[3 * v + a] = (int16_t)((int32_t)t - 32768);
    }
}

static void pack_frame(km_live *l, unsigned char *dst, const double *filt, uint64_t seq,
                       uint64_t in_seq, float t_rt, float t_def) {
  double t0 = km_seconds();
  size_t n = l->mesh->n_vertices;
  const double *V = l->V;
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  unsigned char *out = dst + KM_LIVE_HEADER;
  /* float32 frames: converted and boxed in one pass over V (the box goes in the header) */
  float *pf = l->opt.quantize ? NULL : (float *)(void *)out;
  for (size_t v = 0; v < n; ++v)
    for (int a = 0; a < 3; ++a) {
      float x = (float)V[3 * v + a];
      if (pf) pf[3 * v + a] = x;
      lo[a] = x < lo[a] ? x : lo[a];
      hi[a] = x > hi[a] ? x : hi[a];
    }
  uint32_t hdr[5] = {KM_LIVE_MAGIC, l->opt.quantize ? 1u : 0u, (uint32_t)n, (uint32_t)seq,
                     (uint32_t)in_seq};
  memcpy(dst, hdr, sizeof hdr);
  double s = km_puppetry_scale(l->pipe);
  const double *p0 = km_puppetry_reference_joints(l->pipe);
  float f[4 + 6 + 3 * NJ];
  f[0] = t_rt;
  f[1] = t_def;
  f[2] = 0;
  f[3] = (float)s;
  memcpy(f + 4, lo, sizeof lo);
  memcpy(f + 7, hi, sizeof hi);
  /* Overlay joints in the character's space: rest joint + the handle's displacement rule
   * s (p - p0), so they move exactly as the handles they drive. */
  for (int j = 0; j < NJ; ++j)
    for (int a = 0; a < 3; ++a) {
      double d = filt[3 * j + a] - p0[3 * j + a];
      f[10 + 3 * j + a] = isnan(d) || isnan(s) ? NAN : (float)(l->rest_joints[3 * j + a] + s * d);
    }
  memcpy(dst + 20, f, sizeof f);
  memset(dst + 300, 0, 4);
  if (l->opt.quantize) km_live_quantize(V, n, lo, hi, (int16_t *)(void *)out);
  float tp = (float)(1e3 * (km_seconds() - t0));
  memcpy(dst + 28, &tp, sizeof tp);
}

static void *deform_main(void *arg) {
  km_live *l = arg;
  double raw[3 * NJ], rot[9 * NJ];
  uint64_t produced = 0;
  for (;;) {
    pthread_mutex_lock(&l->in_mu);
    while (!atomic_load(&l->stop) && l->in_seq == l->taken_seq && !l->has_pending)
      pthread_cond_wait(&l->in_cv, &l->in_mu);
    if (atomic_load(&l->stop)) {
      pthread_mutex_unlock(&l->in_mu);
      break;
    }
    live_rig nr = {0};
    bool has_rig = l->has_pending;
    if (has_rig) {
      nr = l->pending;
      memset(&l->pending, 0, sizeof l->pending);
      l->has_pending = false;
    }
    bool have = l->in_seq != l->taken_seq;
    uint64_t in_seq = l->in_seq;
    double t_recv = l->in_t;
    bool reset = l->reset_req;
    l->reset_req = false;
    bool have_rot = have && l->in_has_rot;
    if (have) memcpy(raw, l->in_joints, sizeof raw);
    if (have_rot) memcpy(rot, l->in_rot, sizeof rot);
    l->taken_seq = l->in_seq;
    pthread_mutex_unlock(&l->in_mu);

    if (has_rig) {
      km_error err = {0};
      if (apply_rig(l, &nr, &err) != KM_OK)
        fprintf(stderr, "kinemesh live: rig not applied: %s\n", err.message);
      km_rig_free(&nr.rig);
      free(nr.text);
      const double *last = km_puppetry_last_joints(l->pipe);
      if (!have && last) {
        /* Show the new handles on the current pose right away. */
        memcpy(raw, last, sizeof raw);
        have = true;
        t_recv = km_seconds();
      }
    }
    if (reset) km_puppetry_reset(l->pipe);
    if (!have) continue;
    if (l->rig.n_handles == 0) continue; /* no handles yet: input is counted, nothing moves */
    km_error err = {0};
    if (km_puppetry_push_rotations(l->pipe, raw, have_rot ? rot : NULL, t_recv, l->V, &err) !=
        KM_OK) {
      atomic_fetch_add(&l->solve_errors, 1);
      continue;
    }
    double t2 = km_seconds();
    km_puppetry_times tm;
    km_puppetry_times_get(l->pipe, &tm);
    double t_rt = tm.filter_ms + tm.retarget_ms, t_def = tm.solve_ms;
    pack_frame(l, l->out_work + LWS_PRE, km_puppetry_filtered_joints(l->pipe), produced + 1, in_seq,
               (float)t_rt, (float)t_def);
    double t3 = km_seconds();
    pthread_mutex_lock(&l->out_mu);
    unsigned char *tmp = l->out_latest;
    l->out_latest = l->out_work;
    l->out_work = tmp;
    l->out_seq = ++produced;
    l->out_t_recv = t_recv;
    pthread_mutex_unlock(&l->out_mu);
    atomic_fetch_add(&l->frames_out, 1);
    pthread_mutex_lock(&l->st_mu);
    ring_push(&l->t_rt, t_rt);
    ring_push(&l->t_def, t_def);
    ring_push(&l->t_pack, 1e3 * (t3 - t2));
    ring_push(&l->out_times, t3);
    if (l->handle_pos && l->n_handles == l->rig.n_handles)
      memcpy(l->handle_pos, km_puppetry_handle_targets(l->pipe), sizeof(double) * 3 * l->n_handles);
    pthread_mutex_unlock(&l->st_mu);
    if (l->ctx) lws_cancel_service(l->ctx);
    if (l->vmc_out) {
      /* Forward the filtered skeleton (after the frame is out, so it adds no latency). */
      const double *fj = km_puppetry_filtered_joints(l->pipe);
      km_humanoid_pose pose;
      if (fj && km_live_vmc_pose_from_kinect1(fj, &pose, NULL) == KM_OK &&
          km_live_vmc_out_send(l->vmc_out, &pose, t_recv, NULL) == KM_OK)
        atomic_fetch_add(&l->vmc_out_frames, 1);
      else
        atomic_fetch_add(&l->vmc_out_errors, 1);
    }
  }
  return NULL;
}

/* ================================================================ status */

void km_live_get_stats(km_live *l, km_live_stats *o) {
  memset(o, 0, sizeof *o);
  o->frames_in = atomic_load(&l->frames_in);
  o->frames_out = atomic_load(&l->frames_out);
  o->frames_sent = atomic_load(&l->frames_sent);
  o->frames_dropped = atomic_load(&l->frames_dropped);
  o->osc_messages = atomic_load(&l->osc_messages);
  o->udp_datagrams = atomic_load(&l->udp_datagrams);
  o->ws_messages = atomic_load(&l->ws_messages);
  o->bad_packets = atomic_load(&l->bad_packets);
  o->solve_errors = atomic_load(&l->solve_errors);
  o->vmc_packets = atomic_load(&l->vmc_packets);
  o->vmc_messages = atomic_load(&l->vmc_messages);
  o->vmc_frames = atomic_load(&l->vmc_frames);
  o->vmc_bad = atomic_load(&l->vmc_bad);
  o->vmc_unknown = atomic_load(&l->vmc_unknown);
  o->vmc_out_frames = atomic_load(&l->vmc_out_frames);
  o->vmc_out_errors = atomic_load(&l->vmc_out_errors);
  o->clients = atomic_load(&l->clients);
  pthread_mutex_lock(&l->st_mu);
  o->lat_median_ms = ring_q(&l->lat, 0.5);
  o->lat_p99_ms = ring_q(&l->lat, 0.99);
  o->lat_count = l->lat.n;
  o->t_retarget_ms = ring_q(&l->t_rt, 0.5);
  o->t_deform_ms = ring_q(&l->t_def, 0.5);
  o->t_pack_ms = ring_q(&l->t_pack, 0.5);
  pthread_mutex_unlock(&l->st_mu);
}

static void add_num(cJSON *o, const char *k, double v) {
  if (isfinite(v))
    cJSON_AddNumberToObject(o, k, v);
  else
    cJSON_AddNullToObject(o, k);
}

char *km_live_status_json(km_live *l) {
  km_live_stats s;
  km_live_get_stats(l, &s);
  cJSON *o = cJSON_CreateObject();
  cJSON_AddNumberToObject(o, "frames_in", (double)s.frames_in);
  cJSON_AddNumberToObject(o, "frames_out", (double)s.frames_out);
  cJSON_AddNumberToObject(o, "frames_sent", (double)s.frames_sent);
  cJSON_AddNumberToObject(o, "frames_dropped", (double)s.frames_dropped);
  cJSON_AddNumberToObject(o, "osc_messages", (double)s.osc_messages);
  cJSON_AddNumberToObject(o, "udp_datagrams", (double)s.udp_datagrams);
  cJSON_AddNumberToObject(o, "ws_messages", (double)s.ws_messages);
  cJSON_AddNumberToObject(o, "bad_packets", (double)s.bad_packets);
  cJSON_AddNumberToObject(o, "solve_errors", (double)s.solve_errors);
  cJSON_AddNumberToObject(o, "clients", s.clients);
  if (l->vmc_fd >= 0) {
    cJSON *vm = cJSON_AddObjectToObject(o, "vmc");
    cJSON_AddNumberToObject(vm, "packets", (double)s.vmc_packets);
    cJSON_AddNumberToObject(vm, "messages", (double)s.vmc_messages);
    cJSON_AddNumberToObject(vm, "frames", (double)s.vmc_frames);
    cJSON_AddNumberToObject(vm, "bad", (double)s.vmc_bad);
    cJSON_AddNumberToObject(vm, "unknown", (double)s.vmc_unknown);
  }
  if (l->vmc_out) {
    cJSON *vo = cJSON_AddObjectToObject(o, "vmc_out");
    cJSON_AddNumberToObject(vo, "frames", (double)s.vmc_out_frames);
    cJSON_AddNumberToObject(vo, "errors", (double)s.vmc_out_errors);
  }
  cJSON_AddNumberToObject(o, "vertices", (double)l->mesh->n_vertices);
  cJSON_AddBoolToObject(o, "quantize", l->opt.quantize);
  cJSON_AddBoolToObject(o, "replay_available", l->take != NULL);
  /* true from a /replay request until its last frame is pushed, so a script can wait for the
     take's end instead of guessing from counters that stand still while the machine is busy */
  cJSON_AddBoolToObject(o, "replaying",
                        atomic_load(&l->replaying) || atomic_load(&l->replay_req) != 0);
  cJSON *t = cJSON_AddObjectToObject(o, "times_ms");
  add_num(t, "retarget", s.t_retarget_ms);
  add_num(t, "deform", s.t_deform_ms);
  add_num(t, "pack", s.t_pack_ms);
  add_num(t, "latency_median", s.lat_median_ms);
  add_num(t, "latency_p99", s.lat_p99_ms);
  pthread_mutex_lock(&l->st_mu);
  double fps = NAN, now = km_seconds();
  {
    /* frames produced in the last second */
    size_t c = 0;
    for (size_t i = 0; i < l->out_times.n; ++i)
      c += now - l->out_times.v[i] <= 1.0;
    fps = (double)c;
  }
  cJSON *h = cJSON_AddObjectToObject(o, "handles");
  for (size_t i = 0; i < l->n_handles; ++i) {
    double *p = l->handle_pos + 3 * i;
    cJSON *a = cJSON_CreateArray();
    for (int k = 0; k < 3; ++k)
      cJSON_AddItemToArray(a, isfinite(p[k]) ? cJSON_CreateNumber(p[k]) : cJSON_CreateNull());
    cJSON_AddItemToObject(h, l->handle_names[i], a);
  }
  pthread_mutex_unlock(&l->st_mu);
  add_num(o, "fps_out", fps);
  char *str = cJSON_PrintUnformatted(o);
  cJSON_Delete(o);
  return str;
}

/* ================================================================ HTTP + WebSocket */

typedef struct http_pss {
  unsigned char *body; /* LWS_PRE + len */
  size_t len, pos;
  char *post;
  size_t post_len, post_cap;
  int post_kind; /* 1: /rig, 2: /replay */
  bool post_too_big;
  bool answered;   /* a response was started for this request: never a second one */
  bool waiting;    /* handed to the rig thread; the answer comes on WRITEABLE */
  unsigned reject; /* POST refused before its body: answered at body completion */
  const char *reject_msg;
} http_pss;

typedef struct ws_pss {
  char *rx; /* a text message from the page, assembled from its fragments */
  size_t rx_len;
  bool rx_skip; /* the message being received is too long: dropped */
  uint64_t sent_seq;
  bool counted; /* ESTABLISHED was reached (a refused upgrade is CLOSED too) */
} ws_pss;

static void pss_clear(http_pss *p) {
  free(p->body);
  free(p->post);
  memset(p, 0, sizeof *p);
}

/* Sends headers now and the body from HTTP_WRITEABLE. Takes `data` (malloc'ed, LWS_PRE
 * bytes reserved in front) over. */
static int respond(struct lws *wsi, http_pss *p, unsigned status, const char *ctype,
                   unsigned char *data, size_t len) {
  free(p->body);
  p->body = data;
  p->len = len;
  p->pos = 0;
  p->answered = true;
  unsigned char hb[LWS_PRE + 1024], *start = hb + LWS_PRE, *q = start, *end = hb + sizeof hb - 1;
  if (lws_add_http_common_headers(wsi, status, ctype, (lws_filepos_t)len, &q, end) ||
      lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL,
                                   (const unsigned char *)"no-store", 8, &q, end) ||
      lws_finalize_write_http_header(wsi, start, &q, end))
    return 1;
  lws_callback_on_writable(wsi);
  return 0;
}

static unsigned char *with_pre(const void *src, size_t len) {
  unsigned char *b = malloc(LWS_PRE + len + 1);
  if (b && len) memcpy(b + LWS_PRE, src, len);
  return b;
}

static int respond_str(struct lws *wsi, http_pss *p, unsigned status, const char *ctype,
                       const char *s) {
  size_t n = s ? strlen(s) : 0;
  unsigned char *b = with_pre(s, n);
  if (!b) return 1;
  return respond(wsi, p, status, ctype, b, n);
}

static int respond_error(struct lws *wsi, http_pss *p, unsigned status, const char *msg) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "error", msg);
  char *s = cJSON_PrintUnformatted(o);
  cJSON_Delete(o);
  int r = respond_str(wsi, p, status, "application/json", s);
  free(s);
  return r;
}

static const char *mime(const char *path) {
  const char *dot = strrchr(path, '.');
  if (!dot) return "application/octet-stream";
  if (!strcmp(dot, ".html")) return "text/html; charset=utf-8";
  if (!strcmp(dot, ".js") || !strcmp(dot, ".mjs")) return "text/javascript";
  if (!strcmp(dot, ".css")) return "text/css";
  if (!strcmp(dot, ".json")) return "application/json";
  if (!strcmp(dot, ".png")) return "image/png";
  if (!strcmp(dot, ".svg")) return "image/svg+xml";
  /* MediaPipe Pose (the Camera button): streaming compilation wants application/wasm; the
   * .data, .tflite and .binarypb it fetches are octet-streams */
  if (!strcmp(dot, ".wasm")) return "application/wasm";
  return "application/octet-stream";
}

/* ---------------------------------------------------------------- access control */

static bool is_loopback_v4(const char *addr) {
  struct in_addr a;
  return inet_pton(AF_INET, addr, &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

/* Host header allow-list: loopback names, the bound address, any IPv4 literal when bound to
 * every interface (a DNS-rebinding page always comes with a name, never a literal). */
static bool host_allowed(const km_live *l, const char *host) {
  char h[256];
  size_t n = strlen(host);
  if (!n || n >= sizeof h) return false;
  if (host[0] == '[') {
    const char *e = strchr(host, ']');
    if (!e || (e[1] && e[1] != ':')) return false;
    return (size_t)(e - host) == 4 && !strncmp(host, "[::1", 4);
  }
  const char *c = strchr(host, ':');
  n = c ? (size_t)(c - host) : n;
  memcpy(h, host, n);
  h[n] = 0;
  if (c) {
    for (const char *d = c + 1; *d; ++d)
      if (*d < '0' || *d > '9') return false;
  }
  if (!strcasecmp(h, "localhost") || is_loopback_v4(h)) return true;
  if (!strcmp(h, l->bind)) return true;
  struct in_addr a;
  return !strcmp(l->bind, "0.0.0.0") && inet_pton(AF_INET, h, &a) == 1;
}

static bool token_ok(const km_live *l, struct lws *wsi) {
  if (!l->token[0]) return true;
  char buf[128];
  /* returns a pointer into buf past "token=" */
  const char *v = lws_get_urlarg_by_name(wsi, "token=", buf, sizeof buf);
  if (!v) return false;
  size_t n = strlen(v), m = strlen(l->token);
  unsigned diff = (unsigned)(n ^ m);
  for (size_t i = 0; i < m; ++i)
    diff |= (unsigned char)(l->token[i] ^ (i < n ? v[i] : 0));
  return diff == 0;
}

/* Checks a request's Host (always), and for state-changing requests and the WebSocket its
 * Origin and token. NULL when allowed, else the reason (status in *status). */
static const char *access_denied(const km_live *l, struct lws *wsi, bool changes_state,
                                 unsigned *status) {
  char host[256] = "", origin[300] = "";
  *status = 403;
  if (lws_hdr_copy(wsi, host, sizeof host, WSI_TOKEN_HOST) <= 0 || !host_allowed(l, host))
    return "Host not allowed (open the URL the server printed)";
  if (!changes_state) return NULL;
  int on = lws_hdr_total_length(wsi, WSI_TOKEN_ORIGIN);
  if (on > 0) {
    char want[300];
    snprintf(want, sizeof want, "http://%s", host);
    if (on >= (int)sizeof origin ||
        lws_hdr_copy(wsi, origin, sizeof origin, WSI_TOKEN_ORIGIN) <= 0 || strcasecmp(origin, want))
      return "cross-origin request refused";
  }
  if (!token_ok(l, wsi)) {
    *status = 401;
    return "missing or wrong token (open the URL the server printed, with its ?token=)";
  }
  return NULL;
}

static bool json_content_type(struct lws *wsi) {
  char ct[128] = "";
  if (lws_hdr_copy(wsi, ct, sizeof ct, WSI_TOKEN_HTTP_CONTENT_TYPE) <= 0) return false;
  size_t n = strlen("application/json");
  return !strncasecmp(ct, "application/json", n) && (ct[n] == 0 || ct[n] == ';' || ct[n] == ' ');
}

/* ---------------------------------------------------------------- POST /rig */

/* The rig file as it is on disk now (NULL when unreadable). */
static char *read_text_file(const char *path, size_t max, size_t *len) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  size_t cap = 65536, n = 0;
  char *b = malloc(cap + 1);
  while (b) {
    size_t got = fread(b + n, 1, cap - n, f);
    n += got;
    if (n < cap) break;
    char *nb = cap * 2 <= max ? realloc(b, cap * 2 + 1) : NULL;
    if (!nb) {
      free(b);
      b = NULL;
      break;
    }
    b = nb;
    cap *= 2;
  }
  if (b && ferror(f)) {
    free(b);
    b = NULL;
  }
  fclose(f);
  if (b) {
    b[n] = 0;
    *len = n;
  }
  return b;
}

/* The sidecar's layout: one top-level key per line, one array element per line. */
static char *rig_print(const cJSON *doc) {
  size_t cap = 4096, n = 0;
  char *out = malloc(cap);
  bool ok = out != NULL;
#define PUT(str)                                                                                   \
  do {                                                                                             \
    const char *s_ = (str);                                                                        \
    size_t k_ = strlen(s_);                                                                        \
    if (ok && n + k_ + 1 > cap) {                                                                  \
      while (n + k_ + 1 > cap)                                                                     \
        cap *= 2;                                                                                  \
      char *o_ = realloc(out, cap);                                                                \
      if (o_)                                                                                      \
        out = o_;                                                                                  \
      else                                                                                         \
        ok = false;                                                                                \
    }                                                                                              \
    if (ok) {                                                                                      \
      memcpy(out + n, s_, k_ + 1);                                                                 \
      n += k_;                                                                                     \
    }                                                                                              \
  } while (0)
  PUT("{");
  for (const cJSON *it = doc->child; it && ok; it = it->next) {
    cJSON *key = cJSON_CreateString(it->string ? it->string : "");
    char *k = cJSON_PrintUnformatted(key);
    cJSON_Delete(key);
    if (!k) ok = false;
    PUT(it == doc->child ? "" : ",\n");
    if (k) PUT(k);
    free(k);
    PUT(":");
    if (cJSON_IsArray(it)) {
      PUT("[");
      for (const cJSON *e = it->child; e && ok; e = e->next) {
        char *v = cJSON_PrintUnformatted(e);
        if (!v) ok = false;
        PUT(e == it->child ? "\n" : ",\n");
        if (v) PUT(v);
        free(v);
      }
      PUT("]");
    } else {
      char *v = cJSON_PrintUnformatted(it);
      if (!v) ok = false;
      if (v) PUT(v);
      free(v);
    }
  }
  PUT("}\n");
#undef PUT
  if (!ok) {
    free(out);
    return NULL;
  }
  return out;
}

/* Merges the puppetry part of a posted rig (handles, map, filter) into the sidecar (or, with
 * "autorig", into a rig made anew: below), checks
 * the result against the mesh, writes it (atomically, mode kept) and queues it for the
 * deform thread. Runs on the rig thread. Returns the HTTP status; *reply: JSON. */
static unsigned rig_post(km_live *l, const char *body, size_t len, char **reply) {
  char msg[sizeof(((km_error *)0)->message) + 64];
  *reply = NULL;
  cJSON *posted = cJSON_ParseWithLength(body ? body : "", len);
  if (!cJSON_IsObject(posted)) {
    cJSON_Delete(posted);
    snprintf(msg, sizeof msg, "POST /rig: the body is not a JSON object");
    goto bad;
  }
  size_t flen = 0;
  char *ftext = read_text_file(l->rig_path, 64u << 20, &flen);
  cJSON *base = ftext ? cJSON_ParseWithLength(ftext, flen) : NULL;
  free(ftext);
  if (!cJSON_IsObject(base)) {
    /* Unreadable or broken on disk: merge into the rig the server is running with. */
    cJSON_Delete(base);
    pthread_mutex_lock(&l->st_mu);
    base = l->rig_text ? cJSON_ParseWithLength(l->rig_text, l->rig_len) : NULL;
    pthread_mutex_unlock(&l->st_mu);
    if (!cJSON_IsObject(base)) {
      cJSON_Delete(base);
      base = cJSON_CreateObject();
    }
  }
  /* {"autorig": {"skeleton": "resting", "head": V}}: the page's "rig lying" button. The mesh
   * is rigged anew (km_autorig, as `kinemesh rig MESH --skeleton resting --head V`) and the
   * whole rig replaced: skeleton, skin, handles, map and limits; the sidecar's "frame" record
   * (how the file's mesh was turned, which is the mesh rigged here) is kept. */
  cJSON *ar = cJSON_DetachItemFromObjectCaseSensitive(posted, "autorig");
  if (ar) {
    const cJSON *sk = cJSON_GetObjectItemCaseSensitive(ar, "skeleton"),
                *hd = cJSON_GetObjectItemCaseSensitive(ar, "head");
    double hv = cJSON_IsNumber(hd) ? hd->valuedouble : -1;
    char got[40] = "none";
    if (cJSON_IsNumber(hd)) snprintf(got, sizeof got, "%.10g", hv);
    bool ok = cJSON_IsObject(ar) && cJSON_IsString(sk) && !strcmp(sk->valuestring, "resting");
    cJSON_Delete(ar); /* sk and hd with it */
    if (!ok) {
      cJSON_Delete(base);
      cJSON_Delete(posted);
      snprintf(msg, sizeof msg,
               "POST /rig: \"autorig\" takes {\"skeleton\": \"resting\", \"head\": V}");
      goto bad;
    }
    if (!(hv >= 0 && hv < (double)l->mesh->n_vertices && hv == floor(hv))) {
      cJSON_Delete(base);
      cJSON_Delete(posted);
      snprintf(msg, sizeof msg,
               "POST /rig: \"autorig\": the head must be a vertex id (0..%zu), got %s",
               l->mesh->n_vertices - 1, got);
      goto bad;
    }
    int32_t head = (int32_t)hv;
    km_autorig_options ao = {0};
    ao.skeleton = KM_AUTORIG_RESTING;
    ao.head = &head;
    km_character c = {0};
    km_error e = {0};
    char *json = NULL;
    size_t jlen = 0;
    cJSON *fresh = NULL;
    if (km_autorig(l->mesh, &ao, &c, NULL, &e) == KM_OK &&
        km_character_rig_json(&c, &json, &jlen, &e) == KM_OK)
      fresh = cJSON_ParseWithLength(json, jlen);
    km_character_free(&c);
    free(json);
    if (!cJSON_IsObject(fresh)) {
      cJSON_Delete(fresh);
      cJSON_Delete(base);
      cJSON_Delete(posted);
      snprintf(msg, sizeof msg, "POST /rig: the mesh could not be rigged lying: %s",
               e.message[0] ? e.message : "out of memory");
      goto bad;
    }
    cJSON *fr = cJSON_DetachItemFromObjectCaseSensitive(base, "frame");
    if (fr) cJSON_AddItemToObject(fresh, "frame", fr);
    cJSON_Delete(base);
    base = fresh;
  }
  static const char *const keys[] = {"handles", "map", "filter"};
  for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k) {
    cJSON *v = cJSON_DetachItemFromObjectCaseSensitive(posted, keys[k]);
    if (!v) continue;
    if (cJSON_GetObjectItemCaseSensitive(base, keys[k]))
      cJSON_ReplaceItemInObjectCaseSensitive(base, keys[k], v);
    else
      cJSON_AddItemToObject(base, keys[k], v);
  }
  cJSON_Delete(posted);
  char *text = rig_print(base);
  cJSON_Delete(base);
  if (!text) {
    *reply = strdup("{\"error\":\"out of memory\"}");
    return 500;
  }
  live_rig nr = {0};
  km_error err = {0};
  size_t tlen = strlen(text);
  if (km_rig_parse(text, tlen, "POST /rig", l->mesh, NULL, 0, &nr.rig, &err) != KM_OK) {
    free(text);
    snprintf(msg, sizeof msg, "%s", err.message);
    goto bad;
  }
  if (nr.rig.skeleton != KM_RIG_KINECT1 || nr.rig.n_handles == 0) {
    km_rig_free(&nr.rig);
    free(text);
    snprintf(msg, sizeof msg, "the rig needs skeleton kinect1 and at least one handle");
    goto bad;
  }
  if (km_write_file_atomic(l->rig_path, text, tlen, &err) != KM_OK) {
    km_rig_free(&nr.rig);
    free(text);
    snprintf(msg, sizeof msg, "%s", err.message[0] ? err.message : "cannot write the rig");
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "error", msg);
    *reply = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return 500;
  }
  nr.text = text;
  nr.len = tlen;
  size_t n_handles = nr.rig.n_handles;
  /* GET /rig and /handles answer with the saved rig from now on, even before the deform
   * thread has switched to it. */
  char *hj = handles_json(&nr.rig), *copy = malloc(nr.len + 1);
  if (!hj || !copy) { /* out of memory: /rig and /handles switch when the rig is applied */
    free(hj);
    free(copy);
    hj = copy = NULL;
  } else {
    memcpy(copy, nr.text, nr.len + 1);
  }
  pthread_mutex_lock(&l->st_mu);
  nr.gen = ++l->rig_gen;
  if (copy) {
    free(l->rig_text);
    free(l->handles_json);
    l->rig_text = copy;
    l->rig_len = nr.len;
    l->handles_json = hj;
  }
  pthread_mutex_unlock(&l->st_mu);
  pthread_mutex_lock(&l->in_mu);
  if (l->has_pending) {
    km_rig_free(&l->pending.rig);
    free(l->pending.text);
  }
  l->pending = nr;
  l->has_pending = true;
  pthread_cond_signal(&l->in_cv);
  pthread_mutex_unlock(&l->in_mu);
  snprintf(msg, sizeof msg, "{\"ok\":true,\"handles\":%zu}", n_handles);
  *reply = strdup(msg);
  return 200;
bad:;
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "error", msg);
  *reply = cJSON_PrintUnformatted(o);
  cJSON_Delete(o);
  return 400;
}

static void *rig_main(void *arg) {
  km_live *l = arg;
  rig_job *j = &l->job;
  pthread_mutex_lock(&j->mu);
  for (;;) {
    while (!atomic_load(&l->stop) && !j->queued)
      pthread_cond_wait(&j->cv, &j->mu);
    if (atomic_load(&l->stop)) break;
    char *body = j->body;
    size_t len = j->len;
    j->body = NULL;
    j->queued = false;
    pthread_mutex_unlock(&j->mu);
    char *reply = NULL;
    unsigned status = rig_post(l, body, len, &reply);
    free(body);
    pthread_mutex_lock(&j->mu);
    if (j->wsi) {
      j->status = status;
      j->reply = reply;
      j->done = true;
    } else { /* the asker hung up: nobody takes the answer */
      free(reply);
      j->busy = false;
    }
    if (l->ctx) lws_cancel_service(l->ctx);
  }
  pthread_mutex_unlock(&j->mu);
  return NULL;
}

static int handle_post(km_live *l, struct lws *wsi, http_pss *p) {
  if (p->answered) return 0; /* Content-Length: 0 was answered at the headers already */
  if (p->reject) return respond_error(wsi, p, p->reject, p->reject_msg);
  if (p->post_too_big) return respond_error(wsi, p, 413, "request body too large");
  if (p->post_kind == 2) {
    if (!km_live_replay(l)) return respond_error(wsi, p, 409, "no --replay take loaded");
    return respond_str(wsi, p, 200, "application/json", "{\"ok\":true}");
  }
  if (!l->rig_path) return respond_error(wsi, p, 403, "rig saving is disabled");
  rig_job *j = &l->job;
  pthread_mutex_lock(&j->mu);
  if (j->busy) {
    pthread_mutex_unlock(&j->mu);
    return respond_error(wsi, p, 503, "another rig is being saved; try again");
  }
  j->busy = j->queued = true;
  j->done = false;
  j->wsi = wsi;
  j->body = p->post;
  j->len = p->post_len;
  p->post = NULL;
  p->post_len = p->post_cap = 0;
  p->waiting = true;
  p->answered = true;
  pthread_cond_signal(&j->cv);
  pthread_mutex_unlock(&j->mu);
  return 0;
}

/* The rig thread's answer for this connection, when it is ready. */
static int rig_answer(struct lws *wsi, http_pss *p, km_live *l) {
  rig_job *j = &l->job;
  pthread_mutex_lock(&j->mu);
  if (!j->done || j->wsi != wsi) {
    pthread_mutex_unlock(&j->mu);
    return 0;
  }
  unsigned status = j->status;
  char *reply = j->reply;
  j->reply = NULL;
  j->wsi = NULL;
  j->done = j->busy = false;
  pthread_mutex_unlock(&j->mu);
  p->waiting = false;
  int r = respond_str(wsi, p, status, "application/json", reply ? reply : "{}");
  free(reply);
  return r;
}

static void rig_forget(km_live *l, struct lws *wsi) {
  rig_job *j = &l->job;
  pthread_mutex_lock(&j->mu);
  if (j->wsi == wsi) {
    j->wsi = NULL;
    if (j->done) {
      free(j->reply);
      j->reply = NULL;
      j->done = j->busy = false;
    }
  }
  pthread_mutex_unlock(&j->mu);
}

static int cb_http(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
                   size_t len) {
  km_live *l = lws_context_user(lws_get_context(wsi));
  http_pss *p = user;
  switch (reason) {
  case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
    /* The rig thread may have an answer ready. */
    pthread_mutex_lock(&l->job.mu);
    if (l->job.done && l->job.wsi) lws_callback_on_writable(l->job.wsi);
    pthread_mutex_unlock(&l->job.mu);
    return 0;
  case LWS_CALLBACK_HTTP: {
    const char *uri = in;
    if (p->waiting) rig_forget(l, wsi);
    pss_clear(p);
    unsigned st = 403;
    bool post = lws_hdr_total_length(wsi, WSI_TOKEN_POST_URI) > 0;
    const char *why = access_denied(l, wsi, post, &st);
    if (post) {
      char cl[32] = "";
      bool body = lws_hdr_copy(wsi, cl, sizeof cl, WSI_TOKEN_HTTP_CONTENT_LENGTH) > 0 &&
                  strtoull(cl, NULL, 10) > 0;
      if (!strcmp(uri, "/rig"))
        p->post_kind = 1;
      else if (!strcmp(uri, "/replay"))
        p->post_kind = 2;
      else if (!why)
        why = "unknown POST endpoint", st = 404;
      if (!why && !json_content_type(wsi)) why = "Content-Type must be application/json", st = 415;
      if (!why && body && strtoull(cl, NULL, 10) > MAX_POST)
        why = "request body too large", st = 413;
      if (why) {
        p->reject = st;
        p->reject_msg = why;
      }
      if (!body) return handle_post(l, wsi, p); /* no body is coming */
      return 0;
    }
    if (why) return respond_error(wsi, p, st, why);
    bool data = !strcmp(uri, "/status") || !strcmp(uri, "/mesh") || !strcmp(uri, "/rig") ||
                !strcmp(uri, "/handles");
    if (data && !l->loopback && !token_ok(l, wsi))
      return respond_error(wsi, p, 401, "missing or wrong token");
    if (!strcmp(uri, "/status")) {
      char *s = km_live_status_json(l);
      int r = s ? respond_str(wsi, p, 200, "application/json", s) : 1;
      free(s);
      return r;
    }
    if (!strcmp(uri, "/mesh")) {
      unsigned char *b = with_pre(l->mesh_blob, l->mesh_len);
      return b ? respond(wsi, p, 200, "application/octet-stream", b, l->mesh_len) : 1;
    }
    if (!strcmp(uri, "/rig") || !strcmp(uri, "/handles")) {
      pthread_mutex_lock(&l->st_mu);
      bool rig = !strcmp(uri, "/rig");
      size_t n = rig ? l->rig_len : (l->handles_json ? strlen(l->handles_json) : 0);
      unsigned char *b = with_pre(rig ? l->rig_text : l->handles_json, n);
      pthread_mutex_unlock(&l->st_mu);
      return b ? respond(wsi, p, 200, "application/json", b, n) : 1;
    }
    if (!l->web_dir || strstr(uri, "..") || strlen(uri) > 200 || uri[0] != '/')
      return respond_error(wsi, p, 404, "not found");
    char path[1024];
    snprintf(path, sizeof path, "%s%s", l->web_dir, !strcmp(uri, "/") ? "/index.html" : uri);
    if (access(path, R_OK)) return respond_error(wsi, p, 404, "not found");
    int n = lws_serve_http_file(wsi, path, mime(path), NULL, 0);
    if (n < 0 || (n > 0 && lws_http_transaction_completed(wsi))) return -1;
    return 0;
  }
  case LWS_CALLBACK_HTTP_BODY:
    if (!len || !in || p->reject || p->answered) return 0;
    if (p->post_len + len > MAX_POST) {
      p->post_too_big = true;
      return 0;
    }
    if (p->post_len + len + 1 > p->post_cap) {
      size_t cap = p->post_cap ? p->post_cap : 4096;
      while (cap < p->post_len + len + 1)
        cap *= 2;
      char *q = realloc(p->post, cap);
      if (!q) {
        p->post_too_big = true;
        return 0;
      }
      p->post = q;
      p->post_cap = cap;
    }
    memcpy(p->post + p->post_len, in, len);
    p->post_len += len;
    p->post[p->post_len] = 0;
    return 0;
  case LWS_CALLBACK_HTTP_BODY_COMPLETION: return handle_post(l, wsi, p);
  case LWS_CALLBACK_HTTP_WRITEABLE: {
    if (p->waiting) return rig_answer(wsi, p, l);
    if (!p->body) return 0;
    size_t chunk = p->len - p->pos;
    if (chunk > 65536) chunk = 65536;
    bool final = p->pos + chunk == p->len;
    if (lws_write(wsi, p->body + LWS_PRE + p->pos, chunk,
                  final ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) != (int)chunk)
      return 1;
    p->pos += chunk;
    if (!final) {
      lws_callback_on_writable(wsi);
      return 0;
    }
    free(p->body);
    p->body = NULL;
    if (lws_http_transaction_completed(wsi)) return -1;
    return 0;
  }
  case LWS_CALLBACK_CLOSED_HTTP:
  case LWS_CALLBACK_HTTP_DROP_PROTOCOL:
    if (p && p->waiting) rig_forget(l, wsi);
    if (p) pss_clear(p);
    return 0;
  default: break;
  }
  return lws_callback_http_dummy(wsi, reason, user, in, len);
}

/* A joint frame from a page (the camera's MediaPipe landmarks): a text message in the JSON of
 * the UDP input, km_live_parse_json, e.g. {"skeleton": "mediapipe", "joints": [99 numbers or
 * nulls]}. The upgrade already checked Host, Origin and token. Binary and oversized messages
 * are bad packets. */
#define WS_RX_MAX 16384
static void ws_receive(km_live *l, struct lws *wsi, ws_pss *p, const void *in, size_t len) {
  if (lws_is_first_fragment(wsi)) {
    p->rx_len = 0;
    p->rx_skip = lws_frame_is_binary(wsi);
  }
  if (!p->rx_skip && p->rx_len + len > WS_RX_MAX) p->rx_skip = true;
  if (!p->rx_skip && !p->rx) p->rx = malloc(WS_RX_MAX);
  if (!p->rx) p->rx_skip = true;
  if (!p->rx_skip && len) {
    memcpy(p->rx + p->rx_len, in, len);
    p->rx_len += len;
  }
  if (!lws_is_final_fragment(wsi)) return;
  atomic_fetch_add(&l->ws_messages, 1);
  double joints[3 * NJ];
  if (p->rx_skip || km_live_parse_json(p->rx, p->rx_len, joints) < 0)
    atomic_fetch_add(&l->bad_packets, 1);
  else
    push_frame(l, joints, km_seconds(), false);
  p->rx_len = 0;
  p->rx_skip = false;
}

static int cb_ws(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
                 size_t len) {
  struct lws_context *ctx = lws_get_context(wsi);
  km_live *l = lws_context_user(ctx);
  ws_pss *p = user;
  switch (reason) {
  case LWS_CALLBACK_EVENT_WAIT_CANCELLED: {
    /* The deform thread has a new frame (or km_live_stop was called). */
    pthread_mutex_lock(&l->out_mu);
    uint64_t seq = l->out_seq;
    pthread_mutex_unlock(&l->out_mu);
    if (seq != l->woke_seq) {
      l->woke_seq = seq;
      lws_callback_on_writable_all_protocol(ctx, &l->protocols[1]);
    }
    return 0;
  }
  case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION: {
    /* The upgrade: Host, Origin and token as for a POST, and a cap on the pages. */
    unsigned st;
    if (access_denied(l, wsi, true, &st)) return -1;
    return atomic_load(&l->clients) >= l->opt.max_clients ? -1 : 0;
  }
  case LWS_CALLBACK_ESTABLISHED: {
    memset(p, 0, sizeof *p);
    /* Room for about one frame in the kernel: with the default (autotuned to megabytes) a
     * slow page would have several old frames queued in the socket, defeating latest-wins. */
    int fd = lws_get_socket_fd(wsi), sz = (int)(l->frame_size + 65536);
    if (fd >= 0) setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &sz, sizeof sz);
    atomic_fetch_add(&l->clients, 1);
    p->counted = true;
    lws_callback_on_writable(wsi);
    return 0;
  }
  case LWS_CALLBACK_CLOSED:
    if (p->counted) atomic_fetch_sub(&l->clients, 1);
    p->counted = false;
    free(p->rx);
    p->rx = NULL;
    return 0;
  case LWS_CALLBACK_SERVER_WRITEABLE: {
    if (lws_send_pipe_choked(wsi)) {
      lws_callback_on_writable(wsi);
      return 0;
    }
    /* Written straight from the newest frame, under out_mu so the deform thread cannot swap
     * it away meanwhile (it only takes the lock to swap, after packing the next frame):
     * lws_write hands the frame to the kernel or keeps a copy of what it could not send, so
     * the per-page copy that was made here (a frame's size per page and frame) is not
     * needed. lws only writes the WebSocket header into the LWS_PRE bytes before it. */
    pthread_mutex_lock(&l->out_mu);
    uint64_t seq = l->out_seq;
    double t_recv = l->out_t_recv;
    bool fresh = seq && seq != p->sent_seq;
    int wrote =
        fresh ? lws_write(wsi, l->out_latest + LWS_PRE, l->frame_size, LWS_WRITE_BINARY) : 0;
    pthread_mutex_unlock(&l->out_mu);
    if (!fresh) return 0;
    if (wrote < (int)l->frame_size) return -1;
    p->sent_seq = seq;
    atomic_fetch_add(&l->frames_sent, 1);
    if (seq > l->lat_seq) {
      l->lat_seq = seq;
      double lat = 1e3 * (km_seconds() - t_recv);
      pthread_mutex_lock(&l->st_mu);
      ring_push(&l->lat, lat);
      pthread_mutex_unlock(&l->st_mu);
    }
    return 0;
  }
  case LWS_CALLBACK_RECEIVE: ws_receive(l, wsi, p, in, len); return 0;
  default: break;
  }
  return 0;
}

/* ================================================================ life cycle */

static int udp_socket(const char *bind_addr, int port, km_error *err, const char *what) {
  int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return km_error_set(err, KM_ERR_IO, "%s: socket: %s", what, strerror(errno)), -1;
  struct sockaddr_in a = {0};
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  if (inet_pton(AF_INET, bind_addr, &a.sin_addr) != 1) {
    close(fd);
    km_error_set(err, KM_ERR_INVALID, "%s: --bind %s is not an IPv4 address", what, bind_addr);
    return -1;
  }
  int rcv = 1 << 20;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcv, sizeof rcv);
  if (bind(fd, (struct sockaddr *)&a, sizeof a)) {
    km_error_set(err, KM_ERR_IO, "%s: cannot bind %s:%d: %s", what, bind_addr, port,
                 strerror(errno));
    close(fd);
    return -1;
  }
  return fd;
}

/* GET /mesh: 'KMM1', #V, #F, flags (bit 0: vertex colours follow), #V*3 float positions, #F*3
 * uint32 indices, then with bit 0 #V*4 bytes RGBA (sRGB, as km_mesh.colors), so a scan shows
 * its own colours under the handles. */
static bool build_mesh_blob(km_live *l) {
  const km_mesh *m = l->mesh;
  size_t n = 16 + 12 * m->n_vertices + 12 * m->n_faces + (m->colors ? 4 * m->n_vertices : 0);
  l->mesh_blob = malloc(n);
  if (!l->mesh_blob) return false;
  uint32_t h[4] = {0x314d4d4bu /* 'KMM1' */, (uint32_t)m->n_vertices, (uint32_t)m->n_faces,
                   m->colors ? 1u : 0u};
  memcpy(l->mesh_blob, h, 16);
  float *v = (float *)(void *)(l->mesh_blob + 16);
  for (size_t k = 0; k < 3 * m->n_vertices; ++k)
    v[k] = (float)m->V[k];
  uint32_t *f = (uint32_t *)(void *)(l->mesh_blob + 16 + 12 * m->n_vertices);
  for (size_t k = 0; k < 3 * m->n_faces; ++k)
    f[k] = (uint32_t)m->F[k];
  unsigned char *c = l->mesh_blob + 16 + 12 * m->n_vertices + 12 * m->n_faces;
  km_mesh_colors_rgba8(m, c);
  l->mesh_len = n;
  return true;
}

km_status km_live_create(const km_live_options *opt, const km_mesh *mesh, km_puppet *puppet,
                         const char *rig_json, size_t rig_size, const km_take *replay,
                         km_live **out, km_error *err) {
  *out = NULL;
  if (!mesh || !mesh->n_vertices || !puppet || !rig_json)
    return km_error_set(err, KM_ERR_INVALID, "live: mesh, puppet and rig are required");
  if (replay && (replay->n_joints != NJ || !replay->positions))
    return km_error_set(err, KM_ERR_INVALID,
                        "live: the replay take must have the 20 Kinect joints");
  km_live *l = live_zalloc(1, sizeof *l);
  if (!l) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  l->opt = *opt;
  snprintf(l->bind, sizeof l->bind, "%s", opt->bind ? opt->bind : "127.0.0.1");
  l->opt.bind = l->bind;
  if (!l->opt.http_port) l->opt.http_port = 8080;
  l->web_dir = opt->web_dir ? strdup(opt->web_dir) : NULL;
  l->rig_path = opt->rig_path ? strdup(opt->rig_path) : NULL;
  l->opt.web_dir = l->web_dir;
  l->opt.rig_path = l->rig_path;
  l->mesh = mesh;
  l->take = replay;
  l->osc_fd = l->udp_fd = l->vmc_fd = -1;
  km_live_vmc_init(&l->vmc);
  if (!l->opt.max_clients) l->opt.max_clients = KM_LIVE_MAX_CLIENTS;
  if (!l->opt.record_max) l->opt.record_max = KM_LIVE_RECORD_MAX;
  pthread_mutex_init(&l->job.mu, NULL);
  pthread_cond_init(&l->job.cv, NULL);
  pthread_mutex_init(&l->in_mu, NULL);
  pthread_cond_init(&l->in_cv, NULL);
  pthread_mutex_init(&l->out_mu, NULL);
  pthread_mutex_init(&l->st_mu, NULL);
  km_status s = KM_OK;
  l->loopback = is_loopback_v4(l->bind);
  l->opt.token = NULL;
  if (opt->no_token) {
    if (!l->loopback) {
      s = km_error_set(err, KM_ERR_INVALID,
                       "live: --bind %s is off loopback: a token is required there (drop "
                       "--no-token)",
                       l->bind);
      goto fail;
    }
  } else if (opt->token) {
    size_t tn = strlen(opt->token);
    bool okc = tn >= 16 && tn < sizeof l->token;
    for (size_t i = 0; okc && i < tn; ++i) {
      char c = opt->token[i];
      okc = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
            c == '-' || c == '_';
    }
    if (!okc) {
      s = km_error_set(err, KM_ERR_INVALID,
                       "live: the token must be 16 to %zu characters of A-Z a-z 0-9 - _",
                       sizeof l->token - 1);
      goto fail;
    }
    memcpy(l->token, opt->token, tn + 1);
  } else {
    unsigned char r[16];
    if (getrandom(r, sizeof r, 0) != (ssize_t)sizeof r) {
      s = km_error_set(err, KM_ERR_IO, "live: no random bytes for the token");
      goto fail;
    }
    for (size_t i = 0; i < sizeof r; ++i)
      snprintf(l->token + 2 * i, 3, "%02x", r[i]);
  }
  size_t n = mesh->n_vertices;
  l->frame_size = KM_LIVE_HEADER + n * 3 * (opt->quantize ? 2 : 4);
  l->out_latest = live_zalloc(LWS_PRE + l->frame_size, 1);
  l->out_work = live_zalloc(LWS_PRE + l->frame_size, 1);
  l->V = live_alloc(3 * n, sizeof(double));
  if (!l->out_latest || !l->out_work || !l->V || !build_mesh_blob(l) ||
      (opt->web_dir && !l->web_dir) || (opt->rig_path && !l->rig_path)) {
    s = km_error_set(err, KM_ERR_NOMEM, "out of memory");
    goto fail;
  }
  km_puppetry_options po = {0};
  po.model = puppet;
  if ((s = km_puppetry_create(mesh, NULL, NULL, NJ, &po, &l->pipe, NULL, err)) != KM_OK) goto fail;
  live_rig nr = {0};
  if (rig_text_without_handles(rig_json, rig_size) == 1) {
    char *text = malloc(rig_size + 1);
    if (!text) {
      s = km_error_set(err, KM_ERR_NOMEM, "out of memory");
      goto fail;
    }
    memcpy(text, rig_json, rig_size);
    text[rig_size] = 0;
    if ((s = apply_idle_rig(l, text, rig_size, err)) != KM_OK) {
      free(text);
      goto fail;
    }
    goto rig_done;
  }
  if ((s = km_rig_parse(rig_json, rig_size, opt->rig_path ? opt->rig_path : "rig", mesh, NULL, 0,
                        &nr.rig, err)) != KM_OK)
    goto fail;
  nr.text = malloc(rig_size + 1);
  if (!nr.text) {
    km_rig_free(&nr.rig);
    s = km_error_set(err, KM_ERR_NOMEM, "out of memory");
    goto fail;
  }
  memcpy(nr.text, rig_json, rig_size);
  nr.text[rig_size] = 0;
  nr.len = rig_size;
  s = apply_rig(l, &nr, err);
  km_rig_free(&nr.rig);
  free(nr.text);
  if (s != KM_OK) goto fail;
rig_done:

  if (opt->osc_port > 0 && (l->osc_fd = udp_socket(l->bind, opt->osc_port, err, "OSC")) < 0) {
    s = KM_ERR_IO;
    goto fail;
  }
  if (opt->udp_port > 0 && (l->udp_fd = udp_socket(l->bind, opt->udp_port, err, "UDP")) < 0) {
    s = KM_ERR_IO;
    goto fail;
  }
  if (opt->vmc_port > 0 && (l->vmc_fd = udp_socket(l->bind, opt->vmc_port, err, "VMC")) < 0) {
    s = KM_ERR_IO;
    goto fail;
  }
  if (opt->vmc_out && (s = km_live_vmc_out_open(opt->vmc_out, &l->vmc_out, err)) != KM_OK)
    goto fail;

  l->protocols[0] = (struct lws_protocols){"http", cb_http, sizeof(http_pss), 0, 0, NULL, 0};
  /* tx_packet_size: lws sends at most this much per send() (else rx_buffer_size, 4 KiB) and
   * keeps the rest for later POLLOUTs: a 720 kB frame went out in ~180 send/poll rounds of
   * the service thread. One frame per send() (the socket's SO_SNDBUF holds one). */
  l->protocols[1] = (struct lws_protocols){"kinemesh", cb_ws, sizeof(ws_pss),         4096,
                                           0,          NULL,  l->frame_size + LWS_PRE};
  lws_set_log_level(LLL_ERR, NULL);
  struct lws_context_creation_info info;
  memset(&info, 0, sizeof info);
  info.port = l->opt.http_port;
  info.iface = l->bind;
  info.protocols = l->protocols;
  info.user = l;
  info.options = LWS_SERVER_OPTION_DISABLE_IPV6;
  info.count_threads = 1;
  l->ctx = lws_create_context(&info);
  if (!l->ctx) {
    s = km_error_set(err, KM_ERR_IO, "cannot listen for HTTP on %s:%d (port taken?)", l->bind,
                     l->opt.http_port);
    goto fail;
  }
  if (pthread_create(&l->def_thr, NULL, deform_main, l)) {
    s = km_error_set(err, KM_ERR_IO, "cannot start the deformation thread");
    goto fail;
  }
  l->def_started = true;
  if (l->rig_path) {
    if (pthread_create(&l->rig_thr, NULL, rig_main, l)) {
      s = km_error_set(err, KM_ERR_IO, "cannot start the rig thread");
      goto fail;
    }
    l->rig_started = true;
  }
  if (replay && !opt->no_autoplay) atomic_store(&l->replay_req, 1);
  if (pthread_create(&l->in_thr, NULL, input_main, l)) {
    s = km_error_set(err, KM_ERR_IO, "cannot start the input thread");
    goto fail;
  }
  l->in_started = true;
  *out = l;
  return KM_OK;
fail:
  km_live_free(&l);
  return s;
}

km_status km_live_run(km_live *l, km_error *err) {
  while (!atomic_load(&l->stop))
    if (lws_service(l->ctx, 0) < 0) return km_error_set(err, KM_ERR_IO, "HTTP service failed");
  return KM_OK;
}

const char *km_live_token(const km_live *l) { return l->token; }

void km_live_stop(km_live *l) {
  atomic_store(&l->stop, 1);
  if (l->ctx) lws_cancel_service(l->ctx);
}

bool km_live_replay(km_live *l) {
  if (!l->take) return false;
  atomic_store(&l->replay_req, 1);
  return true;
}

km_status km_live_record_take(km_live *l, const char *path, km_error *err) {
  pthread_mutex_lock(&l->in_mu);
  km_take t = {0};
  t.n_frames = l->rec_n;
  t.n_joints = NJ;
  /* Frames arrive at the tracker's rate: the take's fps is the measured mean. */
  t.fps = l->rec_n > 1 && l->rec_t1 > l->rec_t0
              ? round((double)(l->rec_n - 1) / (l->rec_t1 - l->rec_t0))
              : 30;
  if (t.fps < 1) t.fps = 1;
  char *names[NJ];
  int32_t parents[NJ];
  for (int j = 0; j < NJ; ++j) {
    names[j] = (char *)km_kinect1_joint_name(j);
    parents[j] = km_kinect1_joint_parent(j);
  }
  t.joint_names = names;
  t.parents = parents;
  t.positions = l->rec;
  km_status s = km_take_write(path, &t, err);
  pthread_mutex_unlock(&l->in_mu);
  return s;
}

void km_live_free(km_live **lp) {
  km_live *l = lp ? *lp : NULL;
  if (!l) return;
  atomic_store(&l->stop, 1);
  pthread_mutex_lock(&l->in_mu);
  pthread_cond_broadcast(&l->in_cv);
  pthread_mutex_unlock(&l->in_mu);
  pthread_mutex_lock(&l->job.mu);
  pthread_cond_broadcast(&l->job.cv);
  pthread_mutex_unlock(&l->job.mu);
  if (l->in_started) pthread_join(l->in_thr, NULL);
  if (l->def_started) pthread_join(l->def_thr, NULL);
  if (l->rig_started) pthread_join(l->rig_thr, NULL);
  if (l->ctx) lws_context_destroy(l->ctx);
  if (l->osc_fd >= 0) close(l->osc_fd);
  if (l->udp_fd >= 0) close(l->udp_fd);
  if (l->vmc_fd >= 0) close(l->vmc_fd);
  km_live_vmc_out_free(&l->vmc_out);
  km_puppetry_free(&l->pipe);
  km_rig_free(&l->rig);
  if (l->has_pending) {
    km_rig_free(&l->pending.rig);
    free(l->pending.text);
  }
  publish_handles(l, UINT64_MAX, NULL, NULL, 0, NULL, 0, NULL); /* frees the handle list */
  free(l->V);
  free(l->out_latest);
  free(l->out_work);
  free(l->mesh_blob);
  free(l->rec);
  free(l->web_dir);
  free(l->rig_path);
  free(l->job.body);
  free(l->job.reply);
  pthread_mutex_destroy(&l->job.mu);
  pthread_cond_destroy(&l->job.cv);
  pthread_mutex_destroy(&l->in_mu);
  pthread_cond_destroy(&l->in_cv);
  pthread_mutex_destroy(&l->out_mu);
  pthread_mutex_destroy(&l->st_mu);
  free(l);
  *lp = NULL;
}
