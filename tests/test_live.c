/* Live mode: tracker message parsing (joint names, JSON datagrams, OSC messages), the int16
 * quantisation, and the server in-process (JSON frames over UDP in, frames produced, rig
 * kept, record written; the same frames read over WebSocket as float32 and as int16). */
#include "km_test.h"

#include "live.h"
#include "ws_client.h"

#include <arpa/inet.h>
#include <lo/lo.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sys/socket.h>
#include <unistd.h>

static void test_names(void) {
  CHECK(km_live_joint_index("HandLeft") == 7);
  CHECK(km_live_joint_index("FootRight") == 19);
  CHECK(km_live_joint_index("SpineBase") == 0);
  CHECK(km_live_joint_index("SpineMid") == 1);
  CHECK(km_live_joint_index("SpineShoulder") == 2);
  CHECK(km_live_joint_index("l_hand") == 7);
  CHECK(km_live_joint_index("r_hand") == 11);
  CHECK(km_live_joint_index("l_knee") == 13);
  CHECK(km_live_joint_index("r_foot") == 19);
  CHECK(km_live_joint_index("torso") == 1);
  CHECK(km_live_joint_index("neck") == 2);
  CHECK(km_live_joint_index("head") == 3);
  CHECK(km_live_joint_index("HandTipLeft") == -2);
  CHECK(km_live_joint_index("Neck") == -2);
  /* other skeletons through the library's table (docs/skeletons.md) */
  CHECK(km_live_joint_index("HAND_LEFT") == 7);
  CHECK(km_live_joint_index("LeftMiddleProximal") == 7);
  CHECK(km_live_joint_index("right_wrist") == 10);
  CHECK(km_live_joint_index("Jaw") == -2);
  CHECK(km_live_joint_index("Wing") == -1);
  CHECK(km_live_joint_index("") == -1);
  CHECK(km_live_joint_index(NULL) == -1);
}

static int parse(const char *s, double *j) { return km_live_parse_json(s, strlen(s), j); }

static void test_json(void) {
  double j[60];
  CHECK(parse("{\"joints\":{\"HandLeft\":[1,2,3],\"SpineBase\":[4,5,6],\"HandTipLeft\":[0,0,0]}}",
              j) == 2);
  CHECK(j[21] == 1 && j[22] == 2 && j[23] == 3 && j[0] == 4 && j[2] == 6);
  CHECK(isnan(j[3]) && isnan(j[59]));
  CHECK(parse("{\"joints\":{\"HandLeft\":null,\"Head\":[0,1.6,0]}}", j) == 1);
  CHECK(isnan(j[21]) && j[10] == 1.6);
  char buf[1024];
  size_t n = (size_t)snprintf(buf, sizeof buf, "[");
  for (int k = 0; k < 60; ++k)
    n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%d", k ? "," : "", k);
  snprintf(buf + n, sizeof buf - n, "]");
  CHECK(parse(buf, j) == 20);
  CHECK(j[0] == 0 && j[59] == 59 && j[31] == 31);
  /* a null component drops its joint */
  n = (size_t)snprintf(buf, sizeof buf, "[null");
  for (int k = 1; k < 60; ++k)
    n += (size_t)snprintf(buf + n, sizeof buf - n, ",%d", k);
  snprintf(buf + n, sizeof buf - n, "]");
  CHECK(parse(buf, j) == 19 && isnan(j[0]) && isnan(j[1]) && j[3] == 3);
  const char *bad[] = {"",
                       "{",
                       "[1,2,3]",
                       "{\"joints\":{}}",
                       "{\"joints\":{\"HandLeft\":[1,2]}}",
                       "{\"joints\":{\"HandLeft\":[1,2,\"x\"]}}",
                       "{\"joints\":{\"HandLeft\":[1e999,0,0]}}",
                       "{\"joints\":{\"Tail\":[1,2,3]}}",
                       "{\"hello\":1}",
                       "NaN",
                       "{\"joints\":{\"HandLeft\":[NaN,0,0]}}"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
    CHECK_MSG(parse(bad[i], j) == -1, "%s", bad[i]);
    CHECK(isnan(j[0]) && isnan(j[21]));
  }
  CHECK(km_live_parse_json(NULL, 0, j) == -1);

  /* "skeleton": the live page's camera sends MediaPipe landmarks (33) in kinemesh space */
  CHECK(parse("{\"skeleton\":\"mediapipe\",\"joints\":{\"left_wrist\":[0.5,1.2,0.1],"
              "\"left_hip\":[0.1,1,0],\"right_hip\":[-0.1,0.9,0],\"HandLeft\":[9,9,9]}}",
              j) == 3);
  CHECK(j[18] == 0.5 && j[19] == 1.2 && j[20] == 0.1); /* WristLeft */
  CHECK(j[21] == 0.5 && j[22] == 1.2);                 /* HandLeft from the wrist (no index) */
  CHECK_NEAR(j[0], 0, 1e-12);                          /* HipCenter between the hips */
  CHECK_NEAR(j[1], 0.95, 1e-12);
  CHECK(isnan(j[3 * 9])); /* ElbowRight not sent */
  n = (size_t)snprintf(buf, sizeof buf, "{\"skeleton\":\"mediapipe\",\"joints\":[");
  for (int k = 0; k < 99; ++k) {
    /* the right hand (wrist 16, pinky 18, index 20, thumb 22) out of sight: sent as nulls */
    int lm = k / 3;
    if (lm == 16 || lm == 18 || lm == 20 || lm == 22)
      n += (size_t)snprintf(buf + n, sizeof buf - n, "%snull", k ? "," : "");
    else
      n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%g", k ? "," : "", 0.01 * k);
  }
  snprintf(buf + n, sizeof buf - n, "]}");
  CHECK(parse(buf, j) == 29);
  CHECK_NEAR(j[3 * 6], 0.01 * 45, 1e-12);      /* WristLeft = left_wrist (15) */
  CHECK_NEAR(j[3 * 7], 0.01 * 57, 1e-12);      /* HandLeft = left_index (19) */
  CHECK_NEAR(j[3 * 13 + 1], 0.01 * 76, 1e-12); /* KneeLeft = left_knee (25) y */
  CHECK(isnan(j[3 * 10]) && isnan(j[3 * 11])); /* WristRight, HandRight lost (held) */
  CHECK_NEAR(j[3 * 9], 0.01 * 42, 1e-12);      /* ElbowRight = right_elbow (14) */
  const char *badk[] = {"{\"skeleton\":\"martian\",\"joints\":{\"left_wrist\":[0,0,0]}}",
                        "{\"skeleton\":3,\"joints\":{\"left_wrist\":[0,0,0]}}",
                        "{\"skeleton\":\"mediapipe\",\"joints\":[1,2,3]}",
                        "{\"skeleton\":\"mediapipe\",\"joints\":{\"HandLeft\":[0,0,0]}}",
                        "{\"skeleton\":\"mediapipe\",\"joints\":{\"left_wrist\":[0,0]}}",
                        "{\"skeleton\":\"mediapipe\"}"};
  for (size_t i = 0; i < sizeof badk / sizeof badk[0]; ++i) {
    CHECK_MSG(parse(badk[i], j) == -1, "%s", badk[i]);
    CHECK(isnan(j[0]) && isnan(j[21]));
  }
}

static km_live_osc_kind osc(lo_message m, const char *path, km_live_osc_joint *o) {
  return km_live_parse_osc(path, lo_message_get_types(m), (void *const *)lo_message_get_argv(m),
                           lo_message_get_argc(m), o);
}

static void test_osc(void) {
  km_live_osc_joint o;
  lo_message m = lo_message_new();
  lo_message_add_string(m, "r_hand");
  lo_message_add_int32(m, 0);
  lo_message_add_int32(m, 3);
  lo_message_add_float(m, 10);
  lo_message_add_float(m, 20);
  lo_message_add_float(m, 200);
  lo_message_add_float(m, 1);
  CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_JOINT);
  CHECK(o.joint == 11 && o.user == 3 && isnan(o.timestamp));
  /* cm -> m, y down -> up, Kinect camera space -> kinemesh (180 degrees about y) */
  CHECK_NEAR(o.p[0], -0.1, 1e-6);
  CHECK_NEAR(o.p[1], -0.2, 1e-6);
  CHECK_NEAR(o.p[2], -2.0, 1e-6);
  CHECK(osc(m, "/other", &o) == KM_LIVE_OSC_IGNORED);
  lo_message_add_double(m, 1234.5);
  CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_JOINT && o.timestamp == 1234.5);
  lo_message_add_double(m, 1);
  CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_BAD); /* 9 arguments */
  lo_message_free(m);
  /* Issue 18: 64-bit user ids (>= 2^31) are no float->int overflow (UB): distinct, >= 0. */
  int users[2];
  for (int k = 0; k < 2; ++k) {
    m = lo_message_new();
    lo_message_add_string(m, "r_hand");
    lo_message_add_int32(m, 0);
    lo_message_add_int64(m, ((int64_t)1 << 40) + k);
    for (int c = 0; c < 4; ++c)
      lo_message_add_float(m, 1);
    CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_JOINT);
    users[k] = o.user;
    lo_message_free(m);
  }
  CHECK_MSG(users[0] >= 0 && users[1] >= 0 && users[0] != users[1], "user ids %d %d", users[0],
            users[1]);

  m = lo_message_new();
  lo_message_add_string(m, "r_hand");
  lo_message_add_int32(m, 0);
  lo_message_add_int32(m, 3);
  lo_message_add_float(m, NAN);
  lo_message_add_float(m, 20);
  lo_message_add_float(m, 200);
  lo_message_add_float(m, 1);
  CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_BAD);
  lo_message_free(m);

  m = lo_message_new();
  lo_message_add_string(m, "l_collar");
  lo_message_add_int32(m, 0);
  lo_message_add_int32(m, 3);
  for (int k = 0; k < 4; ++k)
    lo_message_add_float(m, 1);
  CHECK(osc(m, "/joint", &o) == KM_LIVE_OSC_IGNORED);
  lo_message_free(m);

  m = lo_message_new();
  lo_message_add_float(m, 1);
  lo_message_add_float(m, 2);
  lo_message_add_float(m, 3);
  lo_message_add_string(m, "Tracked");
  CHECK(osc(m, "/bodies/42/joints/WristLeft", &o) == KM_LIVE_OSC_JOINT);
  CHECK(o.joint == 6 && o.user == 42 && o.p[0] == -1 && o.p[1] == 2 && o.p[2] == -3);
  CHECK(osc(m, "/bodies/42/joints/Tail", &o) == KM_LIVE_OSC_BAD);
  CHECK(osc(m, "/bodies/42/joints/ThumbLeft", &o) == KM_LIVE_OSC_IGNORED);
  CHECK(osc(m, "/bodies/42", &o) == KM_LIVE_OSC_BAD);
  lo_message_free(m);
  m = lo_message_new();
  lo_message_add_float(m, 1);
  lo_message_add_float(m, 2);
  lo_message_add_float(m, 3);
  lo_message_add_string(m, "NotTracked");
  CHECK(osc(m, "/bodies/1/joints/Head", &o) == KM_LIVE_OSC_JOINT && isnan(o.p[0]));
  lo_message_free(m);
  m = lo_message_new();
  lo_message_add_float(m, 1);
  CHECK(osc(m, "/bodies/1/joints/Head", &o) == KM_LIVE_OSC_BAD);
  lo_message_free(m);
}

/* km_live_osc_packet: a bundle of two joints (one in a nested bundle) and an ignored message,
 * then broken framing; what the server counts as OSC messages and bad packets. */
static void count_joint(void *ctx, const km_live_osc_joint *j) {
  int *seen = ctx;
  seen[j->joint] += 1;
}
static void test_osc_packet(void) {
  lo_message a = lo_message_new(), b = lo_message_new(), c = lo_message_new();
  lo_message_add_string(a, "r_hand");
  lo_message_add_string(b, "head");
  lo_message_add_int32(c, 1);
  lo_message ab[2] = {a, b};
  for (int k = 0; k < 2; ++k) {
    lo_message_add_int32(ab[k], 0);
    lo_message_add_int32(ab[k], 1);
    for (int q = 0; q < 4; ++q)
      lo_message_add_float(ab[k], 10);
  }
  lo_bundle inner = lo_bundle_new(LO_TT_IMMEDIATE), outer = lo_bundle_new(LO_TT_IMMEDIATE);
  lo_bundle_add_message(inner, "/joint", b);
  lo_bundle_add_message(outer, "/joint", a);
  lo_bundle_add_bundle(outer, inner);
  lo_bundle_add_message(outer, "/new_user", c);
  size_t n = 0;
  char *data = lo_bundle_serialise(outer, NULL, &n);
  int seen[20] = {0};
  uint64_t msgs = 0;
  CHECK(data && km_live_osc_packet(data, n, count_joint, seen, &msgs) == 0);
  CHECK_MSG(msgs == 3 && seen[11] == 1 && seen[3] == 1, "%llu messages, hand %d, head %d",
            (unsigned long long)msgs, seen[11], seen[3]);
  /* the last element's size word says more than the packet holds: one bad, the rest taken */
  if (data && n > 24) {
    memset(seen, 0, sizeof seen);
    msgs = 0;
    /* its size word: 4 bytes before "/new_user\0\0\0" ",i\0\0" and the int (20 bytes) */
    data[n - 24] = 0x7f;
    CHECK(km_live_osc_packet(data, n, count_joint, seen, &msgs) == 1);
    CHECK(msgs == 2 && seen[11] == 1 && seen[3] == 1);
  }
  /* a blob message, whole or with its size word missing, never reaches liblo: bad on
   * OSCeleton's path, ignored on another */
  char blob[] = "/joint\0\0,sb\0r_hand\0\0\0\0\0\0\0";
  msgs = 0;
  CHECK(km_live_osc_packet(blob, sizeof blob - 1, count_joint, seen, &msgs) == 1 && msgs == 0);
  CHECK(km_live_osc_packet(blob, sizeof blob - 5, count_joint, seen, &msgs) == 1 && msgs == 0);
  blob[1] = 'p'; /* "/point" */
  CHECK(km_live_osc_packet(blob, sizeof blob - 5, count_joint, seen, &msgs) == 0 && msgs == 0);
  CHECK(km_live_osc_packet("#bundle", 8, NULL, NULL, NULL) == 1);
  CHECK(km_live_osc_packet("joint", 6, NULL, NULL, NULL) == 1);
  free(data);
  lo_bundle_free_recursive(outer);
}

/* Decodes what km_live_quantize wrote, the way web/live.js does. */
static double dequant(int16_t q, float lo, float hi) {
  double c = 0.5 * ((double)lo + hi), h = 0.5 * ((double)hi - lo);
  return c + q * h / 32767.0;
}

static void test_quantize(void) {
  enum { N = 1000 };
  double *V = malloc(sizeof(double) * 3 * N);
  int16_t *q = malloc(sizeof(int16_t) * 3 * N);
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  unsigned r = 12345;
  for (int k = 0; k < 3 * N; ++k) {
    r = r * 1103515245u + 12345u;
    /* a character-sized box that is not centred on the origin */
    V[k] = (k % 3 == 1 ? 1.8 : 0.9) * ((r >> 8) / 16777216.0) + (k % 3 == 0 ? -0.45 : 0.3);
    float x = (float)V[k];
    lo[k % 3] = x < lo[k % 3] ? x : lo[k % 3];
    hi[k % 3] = x > hi[k % 3] ? x : hi[k % 3];
  }
  km_live_quantize(V, N, lo, hi, q);
  double worst = 0;
  int neg = 0;
  for (int k = 0; k < 3 * N; ++k) {
    int a = k % 3;
    /* rounding is at most half a step h/32767; the float arithmetic adds a little */
    double step = 0.5 * ((double)hi[a] - lo[a]) / 32767.0;
    double e = fabs(dequant(q[k], lo[a], hi[a]) - V[k]) / step;
    worst = e > worst ? e : worst;
    neg += q[k] < 0;
    CHECK(q[k] >= -32767 && q[k] <= 32767);
  }
  CHECK_MSG(worst <= 0.55, "worst decoding error %.3f steps (half-extent / 32767)", worst);
  CHECK(neg > N / 2 && neg < 5 * N / 2); /* centred: about half the values are negative */

  /* the box's corners are the ends of the range, its centre is 0; NaN is 0 and points outside
   * the box clamp to it; a flat axis is 0 */
  double W[15] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], 0.5 * (lo[0] + hi[0]), 7, NAN,
                  -100,  1e30,  NAN,   5,     5,     5};
  float flo[3] = {lo[0], lo[1], 5}, fhi[3] = {hi[0], hi[1], 5};
  int16_t w[15];
  km_live_quantize(W, 5, flo, fhi, w);
  CHECK(w[0] == -32767 && w[1] == -32767 && w[3] == 32767 && w[4] == 32767);
  CHECK(w[6] == 0);
  CHECK(w[7] == 32767 && w[8] == 0);
  CHECK(w[9] == -32767 && w[10] == 32767 && w[11] == 0);
  CHECK(w[2] == 0 && w[5] == 0 && w[14] == 0); /* z is flat at 5 */
  free(V);
  free(q);
}

/* ---- the server in-process */

typedef struct runner {
  km_live *l;
  km_status s;
} runner;

static void *run_main(void *arg) {
  runner *r = arg;
  km_error e = {0};
  r->s = km_live_run(r->l, &e);
  return NULL;
}

static void test_server(void) {
  km_character c = {0};
  km_character_options co = {0};
  co.target_vertices = 2000;
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  char dir[] = "/tmp/km_test_live_XXXXXX";
  CHECK(mkdtemp(dir) != NULL);
  char rig_path[128], rec_path[128];
  snprintf(rig_path, sizeof rig_path, "%s/c.rig.json", dir);
  snprintf(rec_path, sizeof rec_path, "%s/rec.json", dir);
  CHECK_OK(km_character_write_rig(rig_path, &c, KM_E));
  FILE *f = fopen(rig_path, "rb");
  char *rig = malloc(1 << 22);
  size_t rig_n = f ? fread(rig, 1, (1 << 22) - 1, f) : 0;
  if (f) fclose(f);
  km_puppet *p = NULL;
  CHECK_OK(km_puppet_precompute(&c.mesh, &(km_puppet_options){0}, &p, KM_E));
  km_take take = {0};
  CHECK_OK(km_motion_generate(&c.skeleton, KM_MOTION_WAVE, 20, &take, KM_E));

  km_live *l = NULL;
  km_live_options o = {0};
  o.record = true;
  o.no_autoplay = true;
  o.rig_path = rig_path;
  km_status s = KM_ERR_IO;
  int udp_port = 0;
  for (int attempt = 0; attempt < 8 && s != KM_OK; ++attempt) {
    int base = 20000 + (int)((getpid() * 131 + attempt * 977) % 40000);
    o.http_port = base;
    o.udp_port = udp_port = base + 1;
    o.osc_port = base + 2;
    s = km_live_create(&o, &c.mesh, p, rig, rig_n, &take, &l, KM_E);
  }
  CHECK_MSG(s == KM_OK, "%s", km_test_err.message);
  if (s == KM_OK) {
    runner r = {l, KM_OK};
    pthread_t th;
    pthread_create(&th, NULL, run_main, &r);
    int fd = socket(AF_INET, SOCK_DGRAM, 0);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)udp_port);
    inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    /* ten JSON frames: the take's first frames as 60-number arrays */
    for (int fr = 0; fr < 10; ++fr) {
      char buf[4096];
      size_t n = (size_t)snprintf(buf, sizeof buf, "{\"joints\":[");
      for (int k = 0; k < 60; ++k)
        n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%.6f", k ? "," : "",
                              take.positions[fr * 60 + k]);
      n += (size_t)snprintf(buf + n, sizeof buf - n, "]}");
      sendto(fd, buf, n, 0, (struct sockaddr *)&a, sizeof a);
      usleep(20000);
    }
    sendto(fd, "garbage", 7, 0, (struct sockaddr *)&a, sizeof a);
    km_live_stats st;
    for (int i = 0; i < 200; ++i) {
      km_live_get_stats(l, &st);
      if (st.frames_out >= 1 && st.bad_packets >= 1 && st.frames_in >= 10) break;
      usleep(10000);
    }
    CHECK_MSG(st.frames_in == 10, "frames_in %llu", (unsigned long long)st.frames_in);
    CHECK(st.frames_out >= 1 && st.frames_out <= st.frames_in);
    CHECK(st.udp_datagrams == 11 && st.bad_packets == 1);
    char *js = km_live_status_json(l);
    CHECK(js && strstr(js, "\"frames_in\":10") && strstr(js, "\"hand_left\""));
    free(js);
    /* the replay plays the 20-frame take at 30 fps (a late input thread skips to the frame
     * that is due, so under load a few may be skipped; the last one always comes) */
    CHECK(km_live_replay(l));
    /* /status says it plays from the request on, and when its last frame is in (counters that
     * stand still for a while said so before, wrongly when the machine starved the thread) */
    js = km_live_status_json(l);
    CHECK_MSG(js && strstr(js, "\"replaying\":true"), "%s", js ? js : "(null)");
    free(js);
    bool ended = false;
    for (int i = 0; i < 300 && !ended; ++i) {
      usleep(100000);
      js = km_live_status_json(l);
      ended = js && strstr(js, "\"replaying\":false");
      free(js);
    }
    CHECK_MSG(ended, "the replay of a 20-frame take did not end in 30 s");
    km_live_get_stats(l, &st);
    CHECK_MSG(st.frames_in >= 11 && st.frames_in <= 30, "frames_in %llu after replay",
              (unsigned long long)st.frames_in);
    km_live_stop(l);
    pthread_join(th, NULL);
    CHECK(r.s == KM_OK);
    CHECK_OK(km_live_record_take(l, rec_path, KM_E));
    km_take rec = {0};
    CHECK_OK(km_take_read(rec_path, &rec, KM_E));
    CHECK(rec.n_frames == st.frames_in && rec.n_joints == 20);
    if (rec.n_frames == st.frames_in && rec.n_frames >= 1) {
      size_t lf = rec.n_frames - 1;
      CHECK_NEAR(rec.positions[3 * 20 * lf + 21], take.positions[3 * 20 * 19 + 21], 1e-9);
      CHECK_NEAR(rec.positions[21], take.positions[21], 1e-5); /* first UDP frame */
    }
    km_take_free(&rec);
    close(fd);
    km_live_free(&l);
  }
  /* a second server on a taken port fails cleanly */
  if (s == KM_OK) {
    km_live *l2 = NULL, *l3 = NULL;
    o.record = false;
    CHECK_OK(km_live_create(&o, &c.mesh, p, rig, rig_n, NULL, &l2, KM_E));
    CHECK_STATUS(km_live_create(&o, &c.mesh, p, rig, rig_n, NULL, &l3, KM_E), KM_ERR_IO);
    CHECK(l3 == NULL);
    km_live_free(&l2);
  }
  /* Issue 18: --record is capped (record_max frames kept, the first ones), not unbounded. */
  if (s == KM_OK) {
    km_live *l5 = NULL;
    o.record = true;
    o.record_max = 5;
    o.no_autoplay = false;
    CHECK_OK(km_live_create(&o, &c.mesh, p, rig, rig_n, &take, &l5, KM_E));
    km_live_stats st5 = {0};
    for (int i = 0; l5 && i < 500 && st5.frames_in < 8; ++i) {
      usleep(20000);
      km_live_get_stats(l5, &st5);
    }
    CHECK_MSG(st5.frames_in >= 8, "frames_in %llu", (unsigned long long)st5.frames_in);
    if (l5) CHECK_OK(km_live_record_take(l5, rec_path, KM_E));
    km_take rec = {0};
    CHECK_OK(km_take_read(rec_path, &rec, KM_E));
    CHECK_MSG(rec.n_frames == 5, "recorded %zu frames (cap 5)", rec.n_frames);
    km_take_free(&rec);
    km_live_free(&l5);
  }
  /* a rig that does not parse */
  km_live *l4 = NULL;
  CHECK_STATUS(km_live_create(&o, &c.mesh, p, "{", 1, NULL, &l4, KM_E), KM_ERR_PARSE);
  remove(rig_path);
  remove(rec_path);
  rmdir(dir);
  free(rig);
  km_take_free(&take);
  km_puppet_free(&p);
  km_character_free(&c);
}

/* Runs a fresh server (float32 or int16 frames), sends the take's frames 0, 4, 8, ... as JSON
 * datagrams, each once the previous one is deformed (so both runs deform the same sequence),
 * and returns the WebSocket message of the last one (NULL on failure). */
static unsigned char *serve_frames(const km_mesh *m, km_puppet *p, const char *rig, size_t rig_n,
                                   const km_take *take, bool quantize, size_t *len) {
  enum { SENT = 10 };
  km_puppet_reset(p);
  km_live *l = NULL;
  km_live_options o = {0};
  o.quantize = quantize;
  km_status s = KM_ERR_IO;
  int http_port = 0, udp_port = 0;
  for (int attempt = 0; attempt < 8 && s != KM_OK; ++attempt) {
    http_port = 20000 + (int)((getpid() * 257 + attempt * 1559 + quantize * 31) % 40000);
    o.http_port = http_port;
    o.udp_port = udp_port = http_port + 1;
    s = km_live_create(&o, m, p, rig, rig_n, NULL, &l, KM_E);
  }
  CHECK_MSG(s == KM_OK, "%s", km_test_err.message);
  if (s != KM_OK) return NULL;
  runner r = {l, KM_OK};
  pthread_t th;
  pthread_create(&th, NULL, run_main, &r);
  unsigned char *out = NULL;
  *len = 0;
  /* a client on a plain socket: the frames are what the page receives; a server that stops
   * sending fails the test, never hangs it */
  int ws = km_live_ws_connect("127.0.0.1", http_port, km_live_token(l), 10);
  CHECK_MSG(ws >= 0, "WebSocket handshake with the server on port %d", http_port);
  km_live_stats st = {0};
  for (int i = 0; ws >= 0 && i < 500 && st.clients < 1; ++i) {
    usleep(10000);
    km_live_get_stats(l, &st);
  }
  int fd = socket(AF_INET, SOCK_DGRAM, 0);
  struct sockaddr_in a = {0};
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)udp_port);
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  for (int k = 0; ws >= 0 && k < SENT; ++k) {
    const double *j = take->positions + 60 * (size_t)(4 * k);
    char buf[4096];
    size_t n = (size_t)snprintf(buf, sizeof buf, "[");
    for (int c = 0; c < 60; ++c)
      n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%.17g", c ? "," : "", j[c]);
    n += (size_t)snprintf(buf + n, sizeof buf - n, "]");
    sendto(fd, buf, n, 0, (struct sockaddr *)&a, sizeof a);
    for (int i = 0; i < 1000; ++i) {
      km_live_get_stats(l, &st);
      if (st.frames_out >= (uint64_t)k + 1) break;
      usleep(5000);
    }
  }
  CHECK_MSG(st.frames_out == SENT && st.frames_dropped == 0, "%s: %llu frames deformed of %d",
            quantize ? "int16" : "float32", (unsigned long long)st.frames_out, SENT);
  /* the page gets the newest frame; older ones may come first */
  unsigned char *msg = NULL;
  size_t n = 0, cap = 0;
  while (ws >= 0 && km_live_ws_read(ws, &msg, &cap, &n)) {
    uint32_t in_seq = 0;
    if (n >= KM_LIVE_HEADER) memcpy(&in_seq, msg + 16, 4);
    if (in_seq == SENT) {
      out = msg;
      *len = n;
      break;
    }
  }
  if (!out) free(msg);
  CHECK_MSG(out != NULL, "%s: no WebSocket message for input frame %d",
            quantize ? "int16" : "float32", SENT);
  if (ws >= 0) close(ws);
  close(fd);
  km_live_stop(l);
  pthread_join(th, NULL);
  km_live_free(&l);
  return out;
}

/* The int16 frames (--quantize) decode, as the page does, to the float32 frames' positions
 * within half a quantisation step of the frame's box. */
static void test_server_quantized(void) {
  km_character c = {0};
  km_character_options co = {0};
  co.target_vertices = 2000;
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  char dir[] = "/tmp/km_test_liveq_XXXXXX";
  CHECK(mkdtemp(dir) != NULL);
  char rig_path[128];
  snprintf(rig_path, sizeof rig_path, "%s/c.rig.json", dir);
  CHECK_OK(km_character_write_rig(rig_path, &c, KM_E));
  FILE *f = fopen(rig_path, "rb");
  char *rig = malloc(1 << 22);
  size_t rig_n = f ? fread(rig, 1, (1 << 22) - 1, f) : 0;
  if (f) fclose(f);
  km_puppet *p = NULL;
  CHECK_OK(km_puppet_precompute(&c.mesh, &(km_puppet_options){0}, &p, KM_E));
  km_take take = {0};
  CHECK_OK(km_motion_generate(&c.skeleton, KM_MOTION_WAVE, 40, &take, KM_E));
  size_t nv = c.mesh.n_vertices, lf = 0, lq = 0;
  unsigned char *ff = p ? serve_frames(&c.mesh, p, rig, rig_n, &take, false, &lf) : NULL;
  unsigned char *fq = p ? serve_frames(&c.mesh, p, rig, rig_n, &take, true, &lq) : NULL;
  CHECK_MSG(!ff || lf == KM_LIVE_HEADER + 12 * nv, "float32 frame of %zu bytes for %zu vertices",
            lf, nv);
  CHECK_MSG(!fq || lq == KM_LIVE_HEADER + 6 * nv, "int16 frame of %zu bytes for %zu vertices", lq,
            nv);
  if (ff && fq && lf == KM_LIVE_HEADER + 12 * nv && lq == KM_LIVE_HEADER + 6 * nv) {
    uint32_t flf, flq;
    memcpy(&flf, ff + 4, 4);
    memcpy(&flq, fq + 4, 4);
    CHECK(flf == 0 && flq == 1);
    float lo[3], hi[3], lo2[3], hi2[3];
    memcpy(lo, fq + 36, 12);
    memcpy(hi, fq + 48, 12);
    memcpy(lo2, ff + 36, 12);
    memcpy(hi2, ff + 48, 12);
    CHECK(!memcmp(lo, lo2, 12) && !memcmp(hi, hi2, 12)); /* the same deformation */
    double worst = 0, moved = 0;
    for (size_t k = 0; k < 3 * nv; ++k) {
      float x;
      int16_t q;
      memcpy(&x, ff + KM_LIVE_HEADER + 4 * k, 4);
      memcpy(&q, fq + KM_LIVE_HEADER + 2 * k, 2);
      int a = (int)(k % 3);
      double step = 0.5 * ((double)hi[a] - lo[a]) / 32767.0;
      double e = fabs(dequant(q, lo[a], hi[a]) - x) / step;
      worst = e > worst ? e : worst;
      double d = fabs(x - c.mesh.V[k]);
      moved = d > moved ? d : moved;
    }
    CHECK_MSG(worst <= 0.55, "int16 frame decodes %.3f steps (half-extent / 32767) from float32",
              worst);
    CHECK_MSG(moved > 0.01, "the compared frame is posed: %.4f m from rest", moved);
  }
  free(ff);
  free(fq);
  remove(rig_path);
  rmdir(dir);
  free(rig);
  km_take_free(&take);
  km_puppet_free(&p);
  km_character_free(&c);
}

int main(void) {
  test_names();
  test_json();
  test_osc();
  test_osc_packet();
  test_quantize();
  test_server();
  test_server_quantized();
  return km_test_finish("test_live");
}
