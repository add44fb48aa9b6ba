/* bench_live: the full live-mode path with a local WebSocket client.
 *   bench_live [--mesh MESH] [--vertices 60000] [--frames 1200] [--rate 240] [--quantize]
 * Starts the live server in-process on loopback (random ports), connects a libwebsockets
 * client (second thread), and sends a generated take as JSON datagrams over UDP at --rate
 * frames/s. Reports the server's latency from packet received to frame written to the
 * socket (median, p99), the client-side latency from datagram sent to frame received, the
 * stage medians, and the frames per second the client sustained. Without --mesh a procedural
 * character of --vertices is generated (its rig and reduced model cached under /tmp). */
#include "cli.h"
#include "live/live.h"

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
    fprintf(stderr, "bench_live: client: %s\n", in ? (const char *)in : "connection error");
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

/* A minimal WebSocket client on a plain socket, reading whole frames with large recv()s.
 * libwebsockets 4.1's client parses received payload byte by byte (about 150 MB/s here), which
 * would make the measuring client, not the server, the bottleneck for 700 KB frames; it is
 * kept as --lws-client. */
static bool read_full(int fd, unsigned char *b, size_t n) {
  while (n) {
    ssize_t r = recv(fd, b, n, 0);
    if (r <= 0) return false;
    b += r;
    n -= (size_t)r;
  }
  return true;
}

typedef struct raw_client {
  client *c;
  int fd;
} raw_client;

static void *raw_main(void *arg) {
  raw_client *rc = arg;
  client *c = rc->c;
  size_t cap = 1 << 20;
  unsigned char *scratch = malloc(cap);
  while (scratch && !atomic_load(&c->done)) {
    unsigned char h[14];
    if (!read_full(rc->fd, h, 2)) break;
    uint64_t len = h[1] & 127;
    if (len == 126) {
      if (!read_full(rc->fd, h + 2, 2)) break;
      len = ((uint64_t)h[2] << 8) | h[3];
    } else if (len == 127) {
      if (!read_full(rc->fd, h + 2, 8)) break;
      len = 0;
      for (int k = 0; k < 8; ++k)
        len = (len << 8) | h[2 + k];
    }
    int opcode = h[0] & 15;
    bool fin = h[0] & 128;
    if (opcode == 8) break;
    if (opcode != 0) c->head_n = 0;
    while (len) {
      size_t k = len < cap ? (size_t)len : cap;
      if (!read_full(rc->fd, scratch, k)) goto out;
      if (c->head_n < sizeof c->head) {
        size_t m = k < sizeof c->head - c->head_n ? k : sizeof c->head - c->head_n;
        memcpy(c->head + c->head_n, scratch, m);
        c->head_n += m;
      }
      len -= k;
    }
    if (fin && (opcode == 2 || opcode == 0)) {
      record_frame(c);
    }
  }
out:
  free(scratch);
  return NULL;
}

static int raw_connect(int port) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a)) return -1;
  const char *req = "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
                    "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                    "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: kinemesh\r\n\r\n";
  if (send(fd, req, strlen(req), 0) != (ssize_t)strlen(req)) return -1;
  char resp[2048];
  size_t n = 0;
  /* byte by byte so no frame data is consumed with the response */
  while (n + 1 < sizeof resp && recv(fd, resp + n, 1, 0) == 1) {
    ++n;
    if (n >= 4 && !memcmp(resp + n - 4, "\r\n\r\n", 4)) break;
  }
  resp[n] = 0;
  if (!strstr(resp, " 101 ")) {
    close(fd);
    return -1;
  }
  return fd;
}

typedef struct server_run {
  km__live *l;
} server_run;
static void *server_main(void *arg) {
  server_run *r = arg;
  km_error e = {0};
  km__live_run(r->l, &e);
  return NULL;
}

int km_cli_bench_live(int argc, char **argv) {
  const char *mesh_path = NULL;
  size_t vertices = 60000, frames = 1200;
  double rate = 240;
  bool quantize = false, lws_client = false;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--mesh") && i + 1 < argc)
      mesh_path = argv[++i];
    else if (!strcmp(argv[i], "--vertices") && i + 1 < argc)
      vertices = (size_t)atol(argv[++i]);
    else if (!strcmp(argv[i], "--frames") && i + 1 < argc)
      frames = (size_t)atol(argv[++i]);
    else if (!strcmp(argv[i], "--rate") && i + 1 < argc)
      rate = atof(argv[++i]);
    else if (!strcmp(argv[i], "--quantize"))
      quantize = true;
    else if (!strcmp(argv[i], "--lws-client"))
      lws_client = true;
    else {
      FILE *uf = (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) ? stdout : stderr;
      fprintf(uf,
              "usage: kinemesh bench live [--mesh MESH] [--vertices N] [--frames N] [--rate HZ] "
              "[--quantize]\n");
      return uf == stdout ? 0 : 2;
    }
  }
  if (frames < 10 || frames > MAX_FRAMES - 10 || rate <= 0) {
    fprintf(stderr, "bench_live: --frames 10..%d, --rate > 0\n", MAX_FRAMES - 10);
    return 2;
  }
  km_error err = {0};
  km_mesh mesh = {0};
  char path[512], rig_path[600], cache[600];
  km_character ch = {0};
  if (!mesh_path) {
    mkdir("/tmp/kinemesh_bench_live", 0777);
    snprintf(path, sizeof path, "/tmp/kinemesh_bench_live/char_%zu.obj", vertices);
    mesh_path = path;
    struct stat st;
    if (stat(path, &st)) {
      km_character_options co = {0};
      co.target_vertices = vertices;
      if (km_character_generate(&co, &ch, &err) != KM_OK ||
          km_mesh_write(path, &ch.mesh, NULL, &err) != KM_OK)
        goto fail;
      km_character_free(&ch);
    }
  }
  snprintf(rig_path, sizeof rig_path, "%.*s.rig.json",
           (int)(strrchr(mesh_path, '.') ? strrchr(mesh_path, '.') - mesh_path
                                         : (long)strlen(mesh_path)),
           mesh_path);
  snprintf(cache, sizeof cache, "%s.kmcache", mesh_path);
  if (km_mesh_read(mesh_path, &mesh, &err) != KM_OK) goto fail;
  {
    struct stat st;
    if (stat(rig_path, &st)) {
      /* a rig for a mesh without one: generate the character's rig (same generator) */
      km_character_options co = {0};
      co.target_vertices = vertices;
      if (km_character_generate(&co, &ch, &err) != KM_OK || ch.mesh.n_vertices != mesh.n_vertices ||
          km_character_write_rig(rig_path, &ch, &err) != KM_OK) {
        fprintf(stderr, "bench_live: %s has no rig sidecar %s\n", mesh_path, rig_path);
        return 1;
      }
      km_character_free(&ch);
    }
  }
  if (km_character_read_rig(rig_path, mesh.n_vertices, &ch, &err) != KM_OK) goto fail;
  km_puppet *pup = NULL;
  km_puppet_options po = {0};
  double t0 = now_s();
  if (km_puppet_load(cache, &mesh, &po, &pup, &err) != KM_OK) {
    if (km_puppet_precompute(&mesh, &po, &pup, &err) != KM_OK) goto fail;
    km_error e2 = {0};
    km_puppet_save(pup, cache, &e2);
    printf("precompute: %.2f s (cached in %s)\n", now_s() - t0, cache);
  }
  km_take take = {0};
  if (km_motion_generate(&ch.skeleton, KM_MOTION_KUNGFU, 300, &take, &err) != KM_OK) goto fail;
  FILE *f = fopen(rig_path, "rb");
  if (!f) {
    fprintf(stderr, "bench_live: cannot read %s\n", rig_path);
    return 1;
  }
  fseek(f, 0, SEEK_END);
  long rig_n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *rig = malloc((size_t)rig_n + 1);
  if (!rig || fread(rig, 1, (size_t)rig_n, f) != (size_t)rig_n) return 1;
  fclose(f);

  km__live *l = NULL;
  km__live_options o = {0};
  o.quantize = quantize;
  int udp_port = 0, http_port = 0;
  km_status s = KM_ERR_IO;
  srand((unsigned)getpid());
  for (int a = 0; a < 10 && s != KM_OK; ++a) {
    http_port = 20000 + rand() % 40000;
    udp_port = http_port + 1;
    o.http_port = http_port;
    o.udp_port = udp_port;
    s = km__live_create(&o, &mesh, pup, rig, (size_t)rig_n, NULL, &l, &err);
  }
  if (s != KM_OK) goto fail;
  server_run sr = {l};
  pthread_t sth, cth;
  pthread_create(&sth, NULL, server_main, &sr);

  client c;
  memset(&c, 0, sizeof c);
  c.max_seq = frames + 8;
  c.recv_t = calloc(c.max_seq, sizeof(double));
  c.recv_seq = calloc(MAX_FRAMES, sizeof(uint32_t));
  double *send_t = calloc(c.max_seq, sizeof(double));
  struct lws_protocols protos[] = {{"kinemesh", cb_client, 0, 1 << 20, 0, NULL, 0},
                                   {NULL, NULL, 0, 0, 0, NULL, 0}};
  struct lws_context_creation_info info;
  memset(&info, 0, sizeof info);
  info.port = CONTEXT_PORT_NO_LISTEN;
  /* lws reads at most this much per poll wake-up: 4 KiB by default, far too little for
   * 700 KB frames */
  info.pt_serv_buf_size = 1 << 20;
  info.protocols = protos;
  info.user = &c;
  raw_client rc = {&c, -1};
  if (!lws_client) {
    rc.fd = raw_connect(http_port);
    if (rc.fd < 0) {
      fprintf(stderr, "bench_live: the WebSocket handshake failed\n");
      return 1;
    }
    atomic_store(&c.connected, 1);
    pthread_create(&cth, NULL, raw_main, &rc);
  } else {
    c.ctx = lws_create_context(&info);
    struct lws_client_connect_info ci;
    memset(&ci, 0, sizeof ci);
    ci.context = c.ctx;
    ci.address = "127.0.0.1";
    ci.port = http_port;
    ci.path = "/ws";
    ci.host = "127.0.0.1";
    ci.origin = "127.0.0.1";
    ci.protocol = "kinemesh";
    if (!c.ctx || !lws_client_connect_via_info(&ci)) {
      fprintf(stderr, "bench_live: cannot start the WebSocket client\n");
      return 1;
    }
    pthread_create(&cth, NULL, client_main, &c);
  }
  for (int i = 0; i < 500 && !atomic_load(&c.connected) && !atomic_load(&c.failed); ++i)
    usleep(10000);
  if (!atomic_load(&c.connected)) {
    fprintf(stderr, "bench_live: the client did not connect\n");
    return 1;
  }

  int fd = socket(AF_INET, SOCK_DGRAM, 0);
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)udp_port);
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  char buf[4096];
  double start = now_s();
  for (size_t k = 0; k < frames; ++k) {
    double due = start + (double)k / rate;
    double w = due - now_s();
    if (w > 0) {
      struct timespec ts = {(time_t)w, (long)((w - floor(w)) * 1e9)};
      nanosleep(&ts, NULL);
    }
    const double *p = take.positions + 60 * (k % take.n_frames);
    size_t n = (size_t)snprintf(buf, sizeof buf, "[");
    for (int j = 0; j < 60; ++j)
      n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%.5f", j ? "," : "", p[j]);
    n += (size_t)snprintf(buf + n, sizeof buf - n, "]");
    send_t[k + 1] = now_s(); /* the server numbers input frames from 1 */
    sendto(fd, buf, n, 0, (struct sockaddr *)&a, sizeof a);
  }
  double send_end = now_s();
  usleep(300000);
  km__live_stats st;
  km__live_get_stats(l, &st);
  atomic_store(&c.done, 1);
  if (lws_client) {
    lws_cancel_service(c.ctx);
  } else {
    shutdown(rc.fd, SHUT_RDWR);
  }
  pthread_join(cth, NULL);
  km__live_stop(l);
  pthread_join(sth, NULL);

  size_t nr = c.received;
  double *e2e = malloc(sizeof(double) * (nr ? nr : 1));
  size_t ne = 0;
  for (size_t i = 0; i < nr; ++i) {
    uint32_t q = c.recv_seq[i];
    if (q >= 1 && q <= frames) e2e[ne++] = 1e3 * (c.recv_t[q] - send_t[q]);
  }
  double fps = nr > 1 ? (double)(nr - 1) / (c.last_t - c.first_t) : 0;
  {
    char machine[320];
    km_cli_machine(machine, sizeof machine);
    printf("kinemesh bench live — %s\n", machine);
  }
  printf("bench_live: %zu vertices, %s frames, %zu input frames at %.0f/s over %.2f s, %s "
         "client\n",
         mesh.n_vertices, quantize ? "uint16" : "float32", frames, rate, send_end - start,
         lws_client ? "libwebsockets" : "plain-socket");
  printf("  server  packet received -> frame sent:  median %.3f ms   p99 %.3f ms  (%zu frames)\n",
         st.lat_median_ms, st.lat_p99_ms, st.lat_count);
  printf("  stages (median): retarget %.4f ms, deform %.3f ms, pack %.3f ms\n", st.t_retarget_ms,
         st.t_deform_ms, st.t_pack_ms);
  printf("  client  datagram sent -> frame received: median %.3f ms   p99 %.3f ms\n",
         quantile(e2e, ne, 0.5), quantile(e2e, ne, 0.99));
  printf("  client received %zu frames: sustained %.1f frames/s (input %.0f/s; %llu dropped "
         "by latest-wins)\n",
         nr, fps, rate, (unsigned long long)st.frames_dropped);
  free(e2e);
  free(send_t);
  free(c.recv_t);
  free(c.recv_seq);
  close(fd);
  if (rc.fd >= 0) close(rc.fd);
  km__live_free(&l);
  if (c.ctx) lws_context_destroy(c.ctx);
  free(rig);
  km_take_free(&take);
  km_character_free(&ch);
  km_puppet_free(&pup);
  km_mesh_free(&mesh);
  return 0;
fail:
  fprintf(stderr, "bench_live: %s\n", err.message);
  return 1;
}
