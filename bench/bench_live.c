/* kinemesh bench live: the full live-mode path with a local WebSocket client.
 *   kinemesh bench live [--mesh MESH [--rig RIG] | --vertices 60000] [--take TAKE]
 *                       [--frames 1200] [--rate 240] [--quantize] [--source json|vmc] [--json]
 * Starts the live server in-process on loopback (random ports), connects a WebSocket client
 * (second thread), and sends a take (the generated kungfu take unless --take) as JSON
 * datagrams over UDP at --rate frames/s. Reports the server's latency from packet received to
 * frame written to the socket (median, p99), the client-side latency from datagram sent to
 * frame received, the stage medians, and the frames per second the client sustained.
 * --source vmc sends VMC protocol bundles instead (the take as Unity humanoid bones, built
 * before the clock starts, as live --vmc receives them). Without
 * --mesh a procedural character of --vertices is generated (mesh, rig and reduced model
 * cached under /tmp). */
#include "bench.h"
#include "cli.h"
#include "live.h"
#include "ws_client.h"

#include <cjson/cJSON.h>

#include <arpa/inet.h>
#include <libwebsockets.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double clock_s(clockid_t id) {
  struct timespec t;
  if (clock_gettime(id, &t)) return NAN;
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* CPU seconds of the process less the calling thread's and the client thread's */
static double server_cpu_s(clockid_t client) {
  return clock_s(CLOCK_PROCESS_CPUTIME_ID) - clock_s(CLOCK_THREAD_CPUTIME_ID) - clock_s(client);
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}
static double quantile(double *v, size_t n, double q) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, cmp_d);
  size_t k = (size_t)ceil(q * (double)n) - (q > 0);
  return v[k < n ? k : n - 1];
}

/* ---- the WebSocket client */

#define MAX_FRAMES 100000
typedef struct client {
  struct lws_context *ctx;
  atomic_int connected, done, failed;
  unsigned char head[24];
  size_t head_n;
  size_t received;
  double *recv_t;     /* by input seq */
  uint32_t *recv_seq; /* input seq of each received frame, in order */
  double first_t, last_t;
  size_t max_seq;
} client;

/* A whole frame arrived: its sequence number (header byte 16) gets the arrival time. */
static void record_frame(client *c) {
  double t = now_s();
  uint32_t magic, in_seq;
  memcpy(&magic, c->head, 4);
  memcpy(&in_seq, c->head + 16, 4);
  if (magic == KM_LIVE_MAGIC && c->received < MAX_FRAMES && in_seq < c->max_seq) {
    c->recv_t[in_seq] = t;
    c->recv_seq[c->received++] = in_seq;
    if (c->received == 1) c->first_t = t;
    c->last_t = t;
  }
}

static int cb_client(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
                     size_t len) {
  client *c = lws_context_user(lws_get_context(wsi));
  switch (reason) {
  case LWS_CALLBACK_CLIENT_ESTABLISHED: atomic_store(&c->connected, 1); break;
  case LWS_CALLBACK_CLIENT_CONNECTION_ERROR:
    fprintf(stderr, "kinemesh bench live: client: %s\n",
            in ? (const char *)in : "connection error");
    atomic_store(&c->failed, 1);
    break;
  case LWS_CALLBACK_CLIENT_CLOSED: atomic_store(&c->failed, 1); break;
  case LWS_CALLBACK_CLIENT_RECEIVE:
    if (lws_is_first_fragment(wsi)) c->head_n = 0;
    if (c->head_n < sizeof c->head) {
      size_t k = len < sizeof c->head - c->head_n ? len : sizeof c->head - c->head_n;
      memcpy(c->head + c->head_n, in, k);
      c->head_n += k;
    }
    if (lws_is_final_fragment(wsi) && !lws_remaining_packet_payload(wsi)) {
      record_frame(c);
    }
    break;
  default: break;
  }
  (void)user;
  return 0;
}

static void *client_main(void *arg) {
  client *c = arg;
  while (!atomic_load(&c->done))
    if (lws_service(c->ctx, 0) < 0) break;
  return NULL;
}

/* The plain-socket client (apps/live/ws_client.c) on its own thread. */
typedef struct raw_client {
  client *c;
  int fd;
} raw_client;

static void *raw_main(void *arg) {
  raw_client *rc = arg;
  client *c = rc->c;
  unsigned char *msg = NULL;
  size_t cap = 0, len = 0;
  while (!atomic_load(&c->done) && km_live_ws_read(rc->fd, &msg, &cap, &len)) {
    c->head_n = len < sizeof c->head ? len : sizeof c->head;
    memcpy(c->head, msg, c->head_n);
    record_frame(c);
  }
  free(msg);
  return NULL;
}

typedef struct server_run {
  km_live *l;
} server_run;
static void *server_main(void *arg) {
  server_run *r = arg;
  km_error e = {0};
  km_live_run(r->l, &e);
  return NULL;
}

/* Reads a whole text file (the rig, handed to the server as text). */
static char *read_text(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *b = NULL;
  long sz = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  if (sz >= 0 && fseek(f, 0, SEEK_SET) == 0 && (b = malloc((size_t)sz + 1)) &&
      fread(b, 1, (size_t)sz, f) == (size_t)sz) {
    b[sz] = 0;
    *n = (size_t)sz;
  } else {
    free(b);
    b = NULL;
  }
  fclose(f);
  return b;
}

#define VERB "bench live"

int km_bench_live(int argc, char **argv) {
  const char *mesh_arg = NULL, *rig_arg = NULL, *take_path = NULL, *source = "json";
  size_t vertices = 60000, frames = 1200;
  double rate = 240;
  bool quantize = false, lws_client = false, json = false;
  const km_cli_opt opts[] = {
      {"mesh", 0, KM_OPT_STRING, &mesh_arg,
       "mesh to animate (default: a generated character of --vertices)"},
      {"rig", 0, KM_OPT_STRING, &rig_arg, "its rig (default <mesh stem>.rig.json)"},
      {"vertices", 0, KM_OPT_SIZE, &vertices, "without --mesh: character size (default 60000)"},
      {"take", 0, KM_OPT_STRING, &take_path,
       "take to send (.json/.csv/.bvh with Kinect joint names; default: generated kungfu)"},
      {"frames", 0, KM_OPT_SIZE, &frames, "input frames to send (default 1200; the take loops)"},
      {"rate", 0, KM_OPT_DOUBLE, &rate, "input frames per second (default 240)"},
      {"quantize", 0, KM_OPT_FLAG, &quantize, "int16 frames (live --quantize)"},
      {"source", 0, KM_OPT_STRING, &source,
       "input: json (JSON datagrams, default) or vmc (VMC protocol bundles, live --vmc)"},
      {"json", 0, KM_OPT_FLAG, &json, "print one JSON object (null: not measured)"},
      {"lws-client", 0, KM_OPT_FLAG, &lws_client,
       "measure with a libwebsockets client (slower to parse than the server sends)"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
      "kinemesh bench live [--mesh MESH [--rig RIG] | --vertices 60000] [--take TAKE] "
      "[--frames 1200] [--rate 240] [--quantize] [--source json|vmc] [--json]",
      "The live server in-process on loopback with a local WebSocket client: the take is sent\n"
      "as JSON datagrams at --rate frames/s. Prints the server latency from packet received\n"
      "to frame sent (median, p99), the stage medians, the client-side latency from datagram\n"
      "sent to frame received, and the frames per second the client sustained.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (frames < 10 || frames > MAX_FRAMES - 10)
    return km_cli_error(VERB, "--frames must be in 10..%d, got %zu", MAX_FRAMES - 10, frames);
  if (!(rate > 0) || !isfinite(rate))
    return km_cli_error(VERB, "--rate must be a positive number of frames per second");
  if (rig_arg && !mesh_arg)
    return km_cli_error(VERB, "--rig goes with --mesh (the generated character has its own)");
  bool vmc = !strcmp(source, "vmc");
  if (!vmc && strcmp(source, "json"))
    return km_cli_error(VERB, "--source must be json or vmc, got %s", source);
  if (!mesh_arg && vertices < 500)
    return km_cli_error(VERB, "--vertices must be at least 500, got %zu", vertices);

  km_error err = {0};
  km_mesh mesh = {0};
  km_character ch = {0};
  km_take take = {0};
  km_puppet *pup = NULL;
  km_live *l = NULL;
  char *rig = NULL, *rig_default = NULL, *cache = NULL;
  size_t rig_n = 0;
  int rc = KM_EXIT_FAIL;
  char gen_mesh[512];
  const char *mesh_path = mesh_arg;
  FILE *info = json ? stderr : stdout; /* --json keeps stdout for the one object */

  if (!mesh_path) {
    /* The generated character and its rig are cached beside each other; both are rewritten
     * when either is missing (writes are atomic, so a concurrent run reads whole files). */
    char gen_rig[540];
    mkdir("/tmp/kinemesh_bench_live", 0777);
    snprintf(gen_mesh, sizeof gen_mesh, "/tmp/kinemesh_bench_live/char_%zu.obj", vertices);
    snprintf(gen_rig, sizeof gen_rig, "/tmp/kinemesh_bench_live/char_%zu.rig.json", vertices);
    mesh_path = gen_mesh;
    struct stat st;
    if (stat(gen_mesh, &st) || stat(gen_rig, &st)) {
      km_character_options co = {0};
      co.target_vertices = vertices;
      if (km_character_generate(&co, &ch, &err) != KM_OK ||
          km_mesh_write(gen_mesh, &ch.mesh, NULL, &err) != KM_OK ||
          km_character_write_rig(gen_rig, &ch, &err) != KM_OK)
        goto fail;
      km_character_free(&ch);
    }
  }
  rig_default = rig_arg ? NULL : km_cli_rig_path(mesh_path);
  const char *rig_path = rig_arg ? rig_arg : rig_default;
  if (!rig_path) {
    rc = km_cli_error(VERB, "out of memory");
    goto done;
  }
  if (km_mesh_read(mesh_path, &mesh, &err) != KM_OK) goto fail;
  if (!(cache = km_cli_cache_path(&mesh))) {
    rc = km_cli_error(VERB, "out of memory");
    goto done;
  }
  {
    struct stat st;
    if (!rig_arg && stat(rig_path, &st)) {
      rc = km_cli_error(VERB, "%s has no rig sidecar %s; pass --rig RIG (a rig JSON for it)",
                        mesh_path, rig_path);
      goto done;
    }
  }
  if (!(rig = read_text(rig_path, &rig_n))) {
    rc = km_cli_error(VERB, "cannot read the rig %s", rig_path);
    goto done;
  }
  if (take_path) {
    km_motion_read_options mo = {0};
    mo.kinect1 = true;
    if (km_motion_read(take_path, &mo, &take, NULL, &err) != KM_OK) goto fail;
  } else {
    /* The generated take follows the rig's own skeleton. */
    if (km_character_read_rig(rig_path, mesh.n_vertices, &ch, &err) != KM_OK) {
      rc = km_cli_error(VERB, "%s; the generated take needs the rig's skeleton (or pass --take)",
                        err.message);
      goto done;
    }
    if (km_motion_generate(&ch.skeleton, KM_MOTION_KUNGFU, 300, &take, &err) != KM_OK) goto fail;
  }
  {
    km_puppetry_info pi;
    if (km_cli_puppet_open(&mesh, cache, &pup, &pi, &err) != KM_OK) goto fail;
    if (pi.model != KM_PUPPETRY_MODEL_LOADED)
      fprintf(info, "precompute: %.2f s (cached in %s)\n", pi.model_seconds, cache);
  }

  km_live_options o = {0};
  o.quantize = quantize;
  int udp_port = 0, http_port = 0;
  km_status s = KM_ERR_IO;
  srand((unsigned)getpid());
  for (int a = 0; a < 10 && s != KM_OK; ++a) {
    http_port = 20000 + rand() % 40000;
    udp_port = http_port + 1;
    o.http_port = http_port;
    o.udp_port = vmc ? 0 : udp_port;
    o.vmc_port = vmc ? udp_port : 0;
    s = km_live_create(&o, &mesh, pup, rig, rig_n, NULL, &l, &err);
  }
  if (s != KM_OK) goto fail;
  server_run sr = {l};
  pthread_t sth, cth;
  pthread_create(&sth, NULL, server_main, &sr);
  bool client_started = false;

  client c;
  memset(&c, 0, sizeof c);
  c.max_seq = frames + 8;
  c.recv_t = calloc(c.max_seq, sizeof(double));
  c.recv_seq = calloc(MAX_FRAMES, sizeof(uint32_t));
  double *send_t = calloc(c.max_seq, sizeof(double));
  /* VMC: every take frame's bundle made before the clock starts (the sender's cost is not
   * the server's); Kinect v1 joints to humanoid bones at the same body point. */
  void **vmc_pk = vmc ? calloc(take.n_frames, sizeof(void *)) : NULL;
  size_t *vmc_len = vmc ? calloc(take.n_frames, sizeof(size_t)) : NULL;
  for (size_t f = 0; vmc && vmc_pk && vmc_len && f < take.n_frames; ++f) {
    km_humanoid_pose pose;
    if (km_live_vmc_pose_from_kinect1(take.positions + 60 * f, &pose, NULL) == KM_OK)
      vmc_pk[f] = km_live_vmc_bundle(&pose, (double)f / rate, &vmc_len[f]);
  }
  int fd = socket(AF_INET, SOCK_DGRAM, 0);
  raw_client rcl = {&c, -1};
  double start = 0, send_end = 0, server_cpu_ms = NAN;
  km_live_stats st;
  memset(&st, 0, sizeof st);
  if (!c.recv_t || !c.recv_seq || !send_t || fd < 0 || (vmc && (!vmc_pk || !vmc_len))) {
    rc = km_cli_error(VERB, "out of memory or no UDP socket");
    goto stop;
  }
  if (!lws_client) {
    rcl.fd = km_live_ws_connect("127.0.0.1", http_port, km_live_token(l), 0);
    if (rcl.fd < 0) {
      rc = km_cli_error(VERB, "the WebSocket handshake with 127.0.0.1:%d failed", http_port);
      goto stop;
    }
    atomic_store(&c.connected, 1);
    pthread_create(&cth, NULL, raw_main, &rcl);
  } else {
    struct lws_protocols protos[] = {{"kinemesh", cb_client, 0, 1 << 20, 0, NULL, 0},
                                     {NULL, NULL, 0, 0, 0, NULL, 0}};
    struct lws_context_creation_info ci0;
    memset(&ci0, 0, sizeof ci0);
    ci0.port = CONTEXT_PORT_NO_LISTEN;
    /* lws reads at most this much per poll wake-up: 4 KiB by default, far too little for
     * 700 KB frames */
    ci0.pt_serv_buf_size = 1 << 20;
    ci0.protocols = protos;
    ci0.user = &c;
    c.ctx = lws_create_context(&ci0);
    struct lws_client_connect_info ci;
    memset(&ci, 0, sizeof ci);
    ci.context = c.ctx;
    ci.address = "127.0.0.1";
    ci.port = http_port;
    char ws_path[128];
    snprintf(ws_path, sizeof ws_path, "/ws?token=%s", km_live_token(l));
    ci.path = ws_path;
    ci.host = "127.0.0.1";
    ci.origin = "127.0.0.1"; /* lws sends Origin: http://127.0.0.1 */
    ci.protocol = "kinemesh";
    if (!c.ctx || !lws_client_connect_via_info(&ci)) {
      rc = km_cli_error(VERB, "cannot start the libwebsockets client");
      goto stop;
    }
    pthread_create(&cth, NULL, client_main, &c);
  }
  client_started = true;
  for (int i = 0; i < 500 && !atomic_load(&c.connected) && !atomic_load(&c.failed); ++i)
    usleep(10000);
  if (!atomic_load(&c.connected)) {
    rc = km_cli_error(VERB, "the WebSocket client did not connect to 127.0.0.1:%d", http_port);
    goto stop;
  }

  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)udp_port);
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  char buf[4096];
  /* CPU time of the server's threads: the process's minus this thread's and the client's
   * (scheduling delays on a loaded machine inflate the latencies, not this) */
  clockid_t client_clock;
  bool have_cpu = pthread_getcpuclockid(cth, &client_clock) == 0;
  double cpu0 = have_cpu ? server_cpu_s(client_clock) : 0;
  uint64_t out0 = 0;
  {
    km_live_stats st0;
    km_live_get_stats(l, &st0);
    out0 = st0.frames_out;
  }
  start = now_s();
  for (size_t k = 0; k < frames; ++k) {
    double due = start + (double)k / rate;
    double w = due - now_s();
    if (w > 0) {
      struct timespec ts = {(time_t)w, (long)((w - floor(w)) * 1e9)};
      nanosleep(&ts, NULL);
    }
    if (vmc) {
      const void *pk = vmc_pk[k % take.n_frames];
      send_t[k + 1] = now_s();
      if (pk) sendto(fd, pk, vmc_len[k % take.n_frames], 0, (struct sockaddr *)&a, sizeof a);
      continue;
    }
    const double *p = take.positions + 60 * (k % take.n_frames);
    size_t n = (size_t)snprintf(buf, sizeof buf, "[");
    for (int j = 0; j < 60; ++j) {
      /* a joint the take lacks goes as null (missing), as trackers send it */
      if (isfinite(p[j]))
        n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%.5f", j ? "," : "", p[j]);
      else
        n += (size_t)snprintf(buf + n, sizeof buf - n, "%snull", j ? "," : "");
    }
    n += (size_t)snprintf(buf + n, sizeof buf - n, "]");
    send_t[k + 1] = now_s(); /* the server numbers input frames from 1 */
    sendto(fd, buf, n, 0, (struct sockaddr *)&a, sizeof a);
  }
  send_end = now_s();
  /* Let the pipeline drain: every input frame deformed or superseded, and everything the
   * server wrote read by the client, unchanged over 100 ms (at most 10 s; a slow machine
   * just waits longer, the figures do not depend on it). */
  {
    uint64_t last_sent = UINT64_MAX;
    size_t last_recv = SIZE_MAX;
    for (double t_end = now_s() + 10; now_s() < t_end;) {
      usleep(100000);
      km_live_get_stats(l, &st);
      size_t got = c.received;
      bool drained = st.frames_in >= frames &&
                     st.frames_out + st.frames_dropped + st.solve_errors >= st.frames_in &&
                     got >= st.frames_sent;
      if (drained && st.frames_sent == last_sent && got == last_recv) break;
      last_sent = st.frames_sent;
      last_recv = got;
    }
  }
  km_live_get_stats(l, &st);
  if (have_cpu && st.frames_out > out0)
    server_cpu_ms = 1e3 * (server_cpu_s(client_clock) - cpu0) / (double)(st.frames_out - out0);
  rc = KM_EXIT_OK;
stop:
  atomic_store(&c.done, 1);
  if (client_started) {
    if (lws_client)
      lws_cancel_service(c.ctx);
    else
      shutdown(rcl.fd, SHUT_RDWR);
    pthread_join(cth, NULL);
  }
  km_live_stop(l);
  pthread_join(sth, NULL);

  if (rc == KM_EXIT_OK) {
    size_t nr = c.received;
    double *e2e = malloc(sizeof(double) * (nr ? nr : 1));
    size_t ne = 0;
    for (size_t i = 0; e2e && i < nr; ++i) {
      uint32_t q = c.recv_seq[i];
      if (q >= 1 && q <= frames) e2e[ne++] = 1e3 * (c.recv_t[q] - send_t[q]);
    }
    double fps = nr > 1 && c.last_t > c.first_t ? (double)(nr - 1) / (c.last_t - c.first_t) : NAN;
    double cmed = quantile(e2e, ne, 0.5), cp99 = quantile(e2e, ne, 0.99);
    double lat_med = st.lat_count ? st.lat_median_ms : NAN,
           lat_p99 = st.lat_count ? st.lat_p99_ms : NAN;
    char machine[320];
    km_bench_machine(machine, sizeof machine);
    const char *client_name = lws_client ? "libwebsockets" : "plain-socket";
    if (json) {
      cJSON *j = cJSON_CreateObject();
      cJSON_AddStringToObject(j, "machine", machine);
      cJSON_AddStringToObject(j, "mesh", mesh_path);
      cJSON_AddStringToObject(j, "take", take_path ? take_path : "kungfu (generated)");
      cJSON_AddNumberToObject(j, "n_ver", (double)mesh.n_vertices);
      cJSON_AddBoolToObject(j, "quantize", quantize);
      cJSON_AddStringToObject(j, "source", source);
      cJSON_AddStringToObject(j, "client", client_name);
      cJSON_AddNumberToObject(j, "frames", (double)frames);
      cJSON_AddNumberToObject(j, "rate", rate);
      km_cli_json_number(j, "send_s", send_end - start);
      km_cli_json_number(j, "latency_median_ms", lat_med);
      km_cli_json_number(j, "latency_p99_ms", lat_p99);
      cJSON_AddNumberToObject(j, "latency_frames", (double)st.lat_count);
      km_cli_json_number(j, "retarget_ms", st.t_retarget_ms);
      km_cli_json_number(j, "deform_ms", st.t_deform_ms);
      km_cli_json_number(j, "pack_ms", st.t_pack_ms);
      km_cli_json_number(j, "server_cpu_ms_per_frame", server_cpu_ms);
      km_cli_json_number(j, "client_latency_median_ms", cmed);
      km_cli_json_number(j, "client_latency_p99_ms", cp99);
      cJSON_AddNumberToObject(j, "frames_in", (double)st.frames_in);
      cJSON_AddNumberToObject(j, "frames_deformed", (double)st.frames_out);
      cJSON_AddNumberToObject(j, "frames_dropped", (double)st.frames_dropped);
      cJSON_AddNumberToObject(j, "frames_received", (double)nr);
      km_cli_json_number(j, "fps", fps);
      cJSON_AddNumberToObject(j, "solve_errors", (double)st.solve_errors);
      char *js = cJSON_PrintUnformatted(j);
      cJSON_Delete(j);
      if (js) puts(js);
      free(js);
    } else {
      printf("kinemesh bench live — %s\n", machine);
      printf("bench_live: %zu vertices, %s frames, %zu input frames at %.0f/s over %.2f s, %s "
             "client, %s input\n",
             mesh.n_vertices, quantize ? "int16" : "float32", frames, rate, send_end - start,
             client_name, vmc ? "VMC bundles" : "JSON datagrams");
      printf("  server  packet received -> frame sent:  median %.3f ms   p99 %.3f ms  (%zu "
             "frames)\n",
             lat_med, lat_p99, st.lat_count);
      printf("  stages (median): retarget %.4f ms, deform %.3f ms, pack %.3f ms\n",
             st.t_retarget_ms, st.t_deform_ms, st.t_pack_ms);
      printf("  server CPU (all its threads): %.3f ms per deformed frame\n", server_cpu_ms);
      printf("  client  datagram sent -> frame received: median %.3f ms   p99 %.3f ms\n", cmed,
             cp99);
      printf("  client received %zu frames: sustained %.1f frames/s (input %.0f/s; %llu dropped "
             "by latest-wins)\n",
             nr, fps, rate, (unsigned long long)st.frames_dropped);
    }
    free(e2e);
  }
  free(send_t);
  for (size_t f = 0; vmc_pk && f < take.n_frames; ++f)
    free(vmc_pk[f]);
  free(vmc_pk);
  free(vmc_len);
  free(c.recv_t);
  free(c.recv_seq);
  if (fd >= 0) close(fd);
  if (rcl.fd >= 0) close(rcl.fd);
  if (c.ctx) lws_context_destroy(c.ctx);
  goto done;
fail:
  rc = km_cli_fail(VERB, &err);
done:
  km_live_free(&l);
  free(rig);
  free(rig_default);
  free(cache);
  km_take_free(&take);
  km_character_free(&ch);
  km_puppet_free(&pup);
  km_mesh_free(&mesh);
  return rc;
}
