/* Live mode: tracker message parsing (joint names, JSON datagrams, OSC messages) and the
 * server in-process (JSON frames over UDP in, frames produced, rig kept, record written). */
#include "km_test.h"

#include "live/live.h"

#include <arpa/inet.h>
#include <lo/lo.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sys/socket.h>
#include <unistd.h>

static void test_names(void) {
  CHECK(km__live_joint_index("HandLeft") == 7);
  CHECK(km__live_joint_index("FootRight") == 19);
  CHECK(km__live_joint_index("SpineBase") == 0);
  CHECK(km__live_joint_index("SpineMid") == 1);
  CHECK(km__live_joint_index("SpineShoulder") == 2);
  CHECK(km__live_joint_index("l_hand") == 7);
  CHECK(km__live_joint_index("r_hand") == 11);
  CHECK(km__live_joint_index("l_knee") == 13);
  CHECK(km__live_joint_index("r_foot") == 19);
  CHECK(km__live_joint_index("torso") == 1);
  CHECK(km__live_joint_index("neck") == 2);
  CHECK(km__live_joint_index("head") == 3);
  CHECK(km__live_joint_index("HandTipLeft") == -2);
  CHECK(km__live_joint_index("Neck") == -2);
  CHECK(km__live_joint_index("Wing") == -1);
  CHECK(km__live_joint_index("") == -1);
  CHECK(km__live_joint_index(NULL) == -1);
}

static int parse(const char *s, double *j) { return km__live_parse_json(s, strlen(s), j); }

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
  CHECK(km__live_parse_json(NULL, 0, j) == -1);
}

static km__live_osc_kind osc(lo_message m, const char *path, km__live_osc_joint *o) {
  return km__live_parse_osc(path, lo_message_get_types(m), (void *const *)lo_message_get_argv(m),
                            lo_message_get_argc(m), o);
}

static void test_osc(void) {
  km__live_osc_joint o;
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

/* ---- the server in-process */

typedef struct runner {
  km__live *l;
  km_status s;
} runner;

static void *run_main(void *arg) {
  runner *r = arg;
  km_error e = {0};
  r->s = km__live_run(r->l, &e);
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

  km__live *l = NULL;
  km__live_options o = {0};
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
    s = km__live_create(&o, &c.mesh, p, rig, rig_n, &take, &l, KM_E);
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
    km__live_stats st;
    for (int i = 0; i < 200; ++i) {
      km__live_get_stats(l, &st);
      if (st.frames_out >= 1 && st.bad_packets >= 1 && st.frames_in >= 10) break;
      usleep(10000);
    }
    CHECK_MSG(st.frames_in == 10, "frames_in %llu", (unsigned long long)st.frames_in);
    CHECK(st.frames_out >= 1 && st.frames_out <= st.frames_in);
    CHECK(st.udp_datagrams == 11 && st.bad_packets == 1);
    char *js = km__live_status_json(l);
    CHECK(js && strstr(js, "\"frames_in\":10") && strstr(js, "\"hand_left\""));
    free(js);
    /* the replay plays the 20-frame take at 30 fps (a late input thread skips to the frame
     * that is due, so under load a few may be skipped; the last one always comes) */
    CHECK(km__live_replay(l));
    uint64_t last = 0;
    for (int i = 0; i < 300; ++i) {
      usleep(100000);
      km__live_get_stats(l, &st);
      if (st.frames_in == last) break;
      last = st.frames_in;
    }
    CHECK_MSG(st.frames_in >= 11 && st.frames_in <= 30, "frames_in %llu after replay",
              (unsigned long long)st.frames_in);
    km__live_stop(l);
    pthread_join(th, NULL);
    CHECK(r.s == KM_OK);
    CHECK_OK(km__live_record_take(l, rec_path, KM_E));
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
    km__live_free(&l);
  }
  /* a second server on a taken port fails cleanly */
  if (s == KM_OK) {
    km__live *l2 = NULL, *l3 = NULL;
    o.record = false;
    CHECK_OK(km__live_create(&o, &c.mesh, p, rig, rig_n, NULL, &l2, KM_E));
    CHECK_STATUS(km__live_create(&o, &c.mesh, p, rig, rig_n, NULL, &l3, KM_E), KM_ERR_IO);
    CHECK(l3 == NULL);
    km__live_free(&l2);
  }
  /* a rig that does not parse */
  km__live *l4 = NULL;
  CHECK_STATUS(km__live_create(&o, &c.mesh, p, "{", 1, NULL, &l4, KM_E), KM_ERR_PARSE);
  remove(rig_path);
  remove(rec_path);
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
  test_server();
  return km_test_finish("test_live");
}
