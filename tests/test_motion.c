/* Kinect v1 tables, take JSON, pose fitting, LBS and procedural motion. */
#include "core/core.h"
#include "km_test.h"

#include <sys/resource.h>

#include <unistd.h>

/* A T-pose Kinect skeleton: metres, y up, facing +z, the character's left at +x. */
static void tpose(km_skeleton *s) {
  static const double P[20 * 3] = {
      0,     1.00, 0,    0,     1.20, 0, 0,     1.45, 0,    0,     1.65, 0.01, 0.18,  1.42, 0,
      0.45,  1.42, 0,    0.70,  1.42, 0, 0.78,  1.42, 0,    -0.18, 1.42, 0,    -0.45, 1.42, 0,
      -0.70, 1.42, 0,    -0.78, 1.42, 0, 0.10,  0.95, 0,    0.10,  0.52, 0.01, 0.10,  0.08, 0,
      0.10,  0.02, 0.10, -0.10, 0.95, 0, -0.10, 0.52, 0.01, -0.10, 0.08, 0,    -0.10, 0.02, 0.10};
  s->n_joints = 20;
  s->names = calloc(20, sizeof(char *));
  s->parents = malloc(20 * sizeof(int32_t));
  s->rest = malloc(sizeof P);
  memcpy(s->rest, P, sizeof P);
  for (int j = 0; j < 20; ++j) {
    s->names[j] = strdup(km_kinect1_joint_name(j));
    s->parents[j] = km_kinect1_joint_parent(j);
  }
}

static void test_kinect_tables(void) {
  CHECK(strcmp(km_kinect1_joint_name(0), "HipCenter") == 0);
  CHECK(strcmp(km_kinect1_joint_name(19), "FootRight") == 0);
  CHECK(km_kinect1_joint_name(20) == NULL && km_kinect1_joint_name(-1) == NULL);
  CHECK(km_kinect1_joint_parent(0) == -1);
  CHECK(km_kinect1_joint_parent(4) == 2 && km_kinect1_joint_parent(8) == 2);
  CHECK(km_kinect1_joint_parent(12) == 0 && km_kinect1_joint_parent(16) == 0);
  CHECK(km_kinect1_joint_parent(11) == 10 && km_kinect1_joint_parent(19) == 18);
  CHECK(km_kinect1_joint_index("nope") == -1 && km_kinect1_joint_index("hipcenter") == -1);
  for (int j = 0; j < 20; ++j) {
    CHECK(km_kinect1_joint_index(km_kinect1_joint_name(j)) == j);
    CHECK(km_kinect1_joint_parent(j) < j);
  }
}

static void axis_angle(const double axis[3], double a, double R[9]) {
  double n = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n, c = cos(a), s = sin(a), C = 1 - c;
  double M[9] = {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
                 y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
                 z * x * C - y * s, z * y * C + x * s, c + z * z * C};
  memcpy(R, M, sizeof M);
}

static double transform_error(const double *T, const double R[9], const double t[3]) {
  double e = 0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      e = fmax(e, fabs(T[4 * i + j] - R[3 * i + j]));
    e = fmax(e, fabs(T[4 * i + 3] - t[i]));
  }
  return e;
}

static void test_pose(void) {
  km_skeleton s;
  tpose(&s);
  double T[20 * 12], P[60];
  const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, zero[3] = {0, 0, 0};
  CHECK_OK(km_skeleton_pose_from_positions(&s, s.rest, T, KM_E));
  for (int j = 0; j < 20; ++j)
    CHECK_MSG(transform_error(T + 12 * j, I, zero) < 1e-12, "joint %d", j);

  /* A rigid motion of the whole skeleton is every joint's transform. */
  double R[9], t[3] = {0.3, -0.2, 1.5};
  axis_angle((double[]){0.3, 1, -0.4}, 2.1, R);
  for (int j = 0; j < 20; ++j)
    for (int i = 0; i < 3; ++i)
      P[3 * j + i] = R[3 * i] * s.rest[3 * j] + R[3 * i + 1] * s.rest[3 * j + 1] +
                     R[3 * i + 2] * s.rest[3 * j + 2] + t[i];
  CHECK_OK(km_skeleton_pose_from_positions(&s, P, T, KM_E));
  for (int j = 0; j < 20; ++j)
    CHECK_MSG(transform_error(T + 12 * j, R, t) < 1e-9, "joint %d: %g", j,
              transform_error(T + 12 * j, R, t));
  /* ... also when some joints are missing: they ride with their parent. */
  P[3 * 5] = NAN;      /* ElbowLeft */
  P[3 * 18 + 1] = NAN; /* AnkleRight */
  CHECK_OK(km_skeleton_pose_from_positions(&s, P, T, KM_E));
  for (int j = 0; j < 20; ++j)
    CHECK_MSG(transform_error(T + 12 * j, R, t) < 1e-9, "joint %d", j);

  /* Bend the left elbow 90 degrees upwards: forearm vertices follow, upper arm ones do not. */
  memcpy(P, s.rest, sizeof P);
  const double *el = s.rest + 3 * 5;
  for (int j = 6; j <= 7; ++j) {
    double dx = s.rest[3 * j] - el[0];
    P[3 * j] = el[0];
    P[3 * j + 1] = el[1] + dx;
  }
  CHECK_OK(km_skeleton_pose_from_positions(&s, P, T, KM_E));
  enum { NV = 20 };
  double V[NV * 3], out[NV * 3];
  km_skin skin = {NV, malloc(NV * 4 * sizeof(int32_t)), malloc(NV * 4 * sizeof(double))};
  for (int v = 0; v < NV; ++v) {
    double u = (v % 10 + 0.5) / 10;
    bool fore = v >= 10;
    const double *a = s.rest + 3 * (fore ? 5 : 4), *b = s.rest + 3 * (fore ? 6 : 5);
    for (int i = 0; i < 3; ++i)
      V[3 * v + i] = a[i] + u * (b[i] - a[i]) + (i == 2 ? 0.03 : 0);
    for (int k = 0; k < 4; ++k)
      skin.joints[4 * v + k] = -1, skin.weights[4 * v + k] = 0;
    skin.joints[4 * v] = fore ? 5 : 4;
    skin.weights[4 * v] = 1;
  }
  CHECK_OK(km_lbs(V, NV, &skin, T, 20, out, KM_E));
  for (int v = 0; v < NV; ++v) {
    double d = fabs(out[3 * v] - V[3 * v]) + fabs(out[3 * v + 1] - V[3 * v + 1]) +
               fabs(out[3 * v + 2] - V[3 * v + 2]);
    if (v < 10) {
      CHECK_MSG(d < 1e-12, "upper arm vertex %d moved %g", v, d);
    } else {
      /* Rotated 90 degrees about z around the elbow. */
      double dx = V[3 * v] - el[0];
      CHECK_MSG(d > 0.02, "forearm vertex %d moved only %g", v, d);
      CHECK_NEAR(out[3 * v], el[0], 1e-12);
      CHECK_NEAR(out[3 * v + 1], el[1] + dx, 1e-12);
      CHECK_NEAR(out[3 * v + 2], V[3 * v + 2], 1e-12);
    }
  }
  /* Identity transforms reproduce the rest mesh, whatever the (normalised) weights. */
  for (int v = 0; v < NV; ++v) {
    skin.joints[4 * v + 1] = (v * 7) % 20;
    skin.weights[4 * v] = 0.6;
    skin.weights[4 * v + 1] = 0.4;
  }
  CHECK_OK(km_skeleton_pose_from_positions(&s, s.rest, T, KM_E));
  CHECK_OK(km_lbs(V, NV, &skin, T, 20, out, KM_E));
  for (int i = 0; i < NV * 3; ++i)
    CHECK_NEAR(out[i], V[i], 1e-12);
  /* Bad influences are reported, not followed. */
  skin.joints[4 * 3 + 2] = 20;
  skin.weights[4 * 3 + 2] = 0.1;
  CHECK_STATUS(km_lbs(V, NV, &skin, T, 20, out, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "vertex 3") != NULL);
  km_skin_free(&skin);
  CHECK(skin.joints == NULL);
  s.parents[3] = 5; /* not an earlier joint */
  CHECK_STATUS(km_skeleton_pose_from_positions(&s, s.rest, T, KM_E), KM_ERR_INVALID);
  km_skeleton_free(&s);
  CHECK(s.rest == NULL && s.n_joints == 0);
  km_skeleton_free(&s);
}

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  fputs(text, f);
  fclose(f);
}

static void test_take_io(void) {
  km_skeleton s;
  tpose(&s);
  km_take t;
  CHECK_OK(km_motion_generate(&s, KM_MOTION_WAVE, 12, &t, KM_E));
  t.positions[3 * (20 * 4 + 7) + 1] = NAN; /* HandLeft missing in frame 4 */
  t.fps = 29.97;
  CHECK_OK(km_take_write("test_motion_take.json", &t, KM_E));
  km_take b;
  CHECK_OK(km_take_read("test_motion_take.json", &b, KM_E));
  CHECK(b.n_frames == 12 && b.n_joints == 20 && b.fps == 29.97);
  CHECK(b.parents != NULL);
  for (int j = 0; j < 20 && b.parents; ++j) {
    CHECK(strcmp(b.joint_names[j], t.joint_names[j]) == 0);
    CHECK(b.parents[j] == t.parents[j]);
  }
  size_t n = 12 * 20 * 3, mismatches = 0;
  for (size_t i = 0; i < n && b.positions; ++i) {
    bool missing = i / 3 == 20 * 4 + 7;
    if (missing ? !isnan(b.positions[i]) : b.positions[i] != t.positions[i]) ++mismatches;
  }
  CHECK_MSG(mismatches == 0, "%zu values differ after a round trip", mismatches);
  km_take_free(&b);
  CHECK(b.positions == NULL);

  /* Errors name the file and what is wrong. */
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\",\"B\"],"
             "\"frames\":[[0,0,0,1,1,1],[0,0,0,1,1]]}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "test_motion_bad.json") != NULL);
  CHECK(strstr(km_test_err.message, "frame 1 has 5 numbers, expected 6") != NULL);
  CHECK(b.positions == NULL && b.joint_names == NULL);
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\n\"version\":1,\n\"fps\":30,,}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "test_motion_bad.json:3:") != NULL);
  write_text("test_motion_bad.json", "{\"format\":\"bvh\",\"version\":1}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "format") != NULL);
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\",\"B\"],"
             "\"parents\":[-1,1],\"frames\":[[0,0,0,1,1,1]]}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "parents[1]") != NULL);
  write_text("test_motion_bad.json", /* a parent is a joint's index, not a fraction of one */
             "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\",\"B\"],"
             "\"parents\":[-1,0.5],\"frames\":[[0,0,0,1,1,1]]}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "parents[1]") != NULL);
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\"],"
             "\"frames\":[[0,\"x\",0]]}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_PARSE);
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\"version\":2,\"fps\":30,\"joints\":[\"A\"],"
             "\"frames\":[[0,0,0]]}");
  CHECK_STATUS(km_take_read("test_motion_bad.json", &b, KM_E), KM_ERR_UNSUPPORTED);
  /* A minimal valid file (no parents, nulls) reads. */
  write_text("test_motion_bad.json",
             "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":60,\"joints\":[\"A\"],"
             "\"frames\":[[1,2,3],[null,2,3]]}");
  CHECK_OK(km_take_read("test_motion_bad.json", &b, KM_E));
  CHECK(b.parents == NULL && b.n_frames == 2 && b.positions && b.positions[2] == 3);
  CHECK(b.positions && isnan(b.positions[3]) && isnan(b.positions[5]));
  km_take_free(&b);
  remove("test_motion_bad.json");
  CHECK_STATUS(km_take_read("no/such/take.json", &b, KM_E), KM_ERR_IO);
  /* (missing folders are made; one under a file cannot be) */
  CHECK_STATUS(km_take_write("/dev/null/dir/take.json", &t, KM_E), KM_ERR_IO);
  remove("test_motion_take.json");
  km_take_free(&t);
  km_take_free(&t);
  km_skeleton_free(&s);
}

static double dist(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* Largest distance joint j gets from where it is in frame 0. */
static double travel(const km_take *t, int j) {
  double m = 0;
  for (size_t f = 0; f < t->n_frames; ++f)
    m = fmax(m, dist(t->positions + 3 * (20 * f + j), t->positions + 3 * j));
  return m;
}

static void test_generate(void) {
  km_skeleton s;
  tpose(&s);
  const char *names[] = {"walk", "wave", "kungfu"};
  const size_t frames[] = {90, 120, 160};
  for (int kind = 0; kind < 3; ++kind) {
    km_take t, u;
    CHECK_OK(km_motion_generate(&s, (km_motion_kind)kind, frames[kind], &t, KM_E));
    if (!t.positions) continue;
    CHECK(t.n_frames == frames[kind] && t.n_joints == 20 && t.fps == 30);
    CHECK(t.parents && t.parents[0] == -1 && t.parents[19] == 18);
    CHECK(strcmp(t.joint_names[11], "HandRight") == 0);
    double worst_len = 0, worst_ground = 0, foot_rest = 1e9, max_foot = 0, max_hand = 0;
    for (int j = 14; j < 20; ++j)
      if (j != 16 && j != 17) foot_rest = fmin(foot_rest, s.rest[3 * j + 1]);
    size_t nan = 0;
    for (size_t f = 0; f < t.n_frames; ++f) {
      const double *p = t.positions + 60 * f;
      for (int i = 0; i < 60; ++i)
        nan += !isfinite(p[i]);
      for (int j = 1; j < 20; ++j) {
        int q = s.parents[j];
        worst_len = fmax(worst_len,
                         fabs(dist(p + 3 * j, p + 3 * q) - dist(s.rest + 3 * j, s.rest + 3 * q)));
      }
      double lo = fmin(fmin(p[3 * 14 + 1], p[3 * 15 + 1]), fmin(p[3 * 18 + 1], p[3 * 19 + 1]));
      worst_ground = fmax(worst_ground, fabs(lo - foot_rest));
      max_foot = fmax(max_foot, fmax(p[3 * 15 + 1], p[3 * 19 + 1]) - foot_rest);
      max_hand = fmax(max_hand, fmax(p[3 * 7 + 1], p[3 * 11 + 1]));
      CHECK(p[3 * 3 + 1] > p[1]); /* the head stays above the hips */
    }
    CHECK_MSG(nan == 0, "%s: %zu non-finite values", names[kind], nan);
    CHECK_MSG(worst_len < 1e-9, "%s: bone length error %g", names[kind], worst_len);
    CHECK_MSG(worst_ground < 1e-9, "%s: lowest foot off the ground by %g", names[kind],
              worst_ground);
    double hl = travel(&t, 7), hr = travel(&t, 11), fl = travel(&t, 15), fr = travel(&t, 19);
    printf("%s: hands move %.2f %.2f m, feet %.2f %.2f m, highest foot %.2f m, hand %.2f m\n",
           names[kind], hl, hr, fl, fr, max_foot, max_hand);
    CHECK_MSG(hr > 0.1, "%s: right hand moves %g", names[kind], hr);
    if (kind != KM_MOTION_WAVE) {
      CHECK_MSG(hl > 0.1 && fl > 0.1 && fr > 0.1, "%s: %g %g %g", names[kind], hl, fl, fr);
    } else {
      /* Waving: the right hand goes above the head. */
      CHECK(max_hand > s.rest[3 * 3 + 1]);
    }
    if (kind == KM_MOTION_WALK) {
      /* Forward along +z, about 1.3 m/s. */
      double dz = t.positions[60 * (t.n_frames - 1) + 2] - t.positions[2];
      CHECK_MSG(dz > 0.8 * 3 && dz < 1.8 * 3, "walked %g m in 3 s", dz);
    }
    if (kind == KM_MOTION_KUNGFU) {
      CHECK_MSG(max_foot > 0.5, "kicks reach only %g m", max_foot);
      CHECK(max_hand > s.rest[3 * 3 + 1]);
    }
    /* Deterministic. */
    CHECK_OK(km_motion_generate(&s, (km_motion_kind)kind, frames[kind], &u, KM_E));
    CHECK(u.positions && memcmp(u.positions, t.positions, 60 * t.n_frames * sizeof(double)) == 0);
    km_take_free(&u);
    km_take_free(&t);
  }
  km_take t;
  CHECK_STATUS(km_motion_generate(&s, KM_MOTION_WALK, 0, &t, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_motion_generate(&s, (km_motion_kind)7, 10, &t, KM_E), KM_ERR_INVALID);
  s.n_joints = 19;
  CHECK_STATUS(km_motion_generate(&s, KM_MOTION_WALK, 10, &t, KM_E), KM_ERR_INVALID);
  s.n_joints = 20;
  km_skeleton_free(&s);
}

/* Joints recovered from the skin weights alone land near the rig's joints on the procedural
 * character (whose weights blend over a band around each joint), and a joint no vertex is
 * weighted to keeps its guess. */
static void test_skeleton_from_weights(void) {
  km_character c = {0};
  km_character_options co = {0};
  co.target_vertices = 8000;
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  size_t nj = c.skeleton.n_joints;
  double *est = malloc(sizeof(double) * 3 * nj);
  for (size_t i = 0; i < 3 * nj; ++i)
    est[i] = 1e3; /* far-away guesses */
  CHECK_OK(km_skeleton_from_weights(&c.mesh, &c.skin, c.skeleton.parents, nj, est, KM_E));
  double worst = 0, sum = 0;
  for (size_t j = 0; j < nj; ++j) {
    double d = 0;
    for (int k = 0; k < 3; ++k)
      d += pow(est[3 * j + k] - c.skeleton.rest[3 * j + k], 2);
    d = sqrt(d);
    sum += d;
    if (d > worst) worst = d;
    printf("joint %-14s estimated %.1f cm from the rig's\n", c.skeleton.names[j], 100 * d);
  }
  CHECK_MSG(sum / (double)nj < 0.03 && worst < 0.12, "mean %.3f m, worst %.3f m", sum / (double)nj,
            worst);
  /* no vertex weighted to any joint: every guess stays */
  km_skin empty = c.skin;
  empty.weights = calloc(4 * c.mesh.n_vertices, sizeof(double));
  for (size_t i = 0; i < 3 * nj; ++i)
    est[i] = (double)i;
  CHECK_OK(km_skeleton_from_weights(&c.mesh, &empty, c.skeleton.parents, nj, est, KM_E));
  bool kept = true;
  for (size_t i = 0; i < 3 * nj; ++i)
    kept &= est[i] == (double)i;
  CHECK(kept);
  free(empty.weights);
  int32_t bad_parents[KM_KINECT1_JOINTS];
  memcpy(bad_parents, c.skeleton.parents, sizeof bad_parents);
  bad_parents[3] = 99;
  CHECK_STATUS(km_skeleton_from_weights(&c.mesh, &c.skin, bad_parents, nj, est, KM_E),
               KM_ERR_INVALID);
  free(est);
  km_character_free(&c);
}

/* Issue 18: reading a take costs memory in proportion to its bytes. A 4 MB take of short
 * numbers ("0,") took 42 times its size as a cJSON tree (a 20 MB one: 853 MB); the frames are
 * now read from the text into the positions (8 bytes a number): the peak is the text, its
 * header and the positions, about 5 times the file. Measured as the growth of the process's
 * peak resident size, so it runs first; not under AddressSanitizer (its allocator keeps freed
 * memory in quarantine). */
static void test_take_memory(void) {
  const char *path = "test_motion_zeros.json";
  FILE *f = fopen(path, "wb");
  CHECK(f != NULL);
  if (!f) return;
  fputs("{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[", f);
  for (int j = 0; j < 20; ++j)
    fprintf(f, "%s\"J%d\"", j ? "," : "", j);
  fputs("],\"frames\":[\n", f);
  enum { FRAMES = 33000 };
  for (int k = 0; k < FRAMES; ++k) {
    fputc('[', f);
    for (int v = 0; v < 60; ++v)
      fputs(v ? ",0" : (k % 7 ? "0" : "null"), f);
    fputs(k + 1 < FRAMES ? "],\n" : "]]}\n", f);
  }
  long bytes = ftell(f);
  fclose(f);
  struct rusage ru0, ru1;
  getrusage(RUSAGE_SELF, &ru0);
  km_take t = {0};
  CHECK_OK(km_take_read(path, &t, KM_E));
  getrusage(RUSAGE_SELF, &ru1);
  CHECK(t.n_frames == FRAMES && t.n_joints == 20);
  if (t.positions) CHECK(isnan(t.positions[0]) && t.positions[3 * 20 * 1] == 0);
  double grew = (double)(ru1.ru_maxrss - ru0.ru_maxrss) * 1024.0;
  printf("take of %.1f MB: peak resident size grew by %.1f MB (%.1f x the file)\n", bytes / 1e6,
         grew / 1e6, grew / (double)bytes);
#if !defined(__SANITIZE_ADDRESS__)
  CHECK_MSG(grew < 10.0 * (double)bytes, "reading a %.1f MB take took %.1f MB", bytes / 1e6,
            grew / 1e6);
#endif
  km_take_free(&t);
  /* the frames are read as strictly as cJSON reads JSON */
  const char *bad[] = {"[[+1,0,0]]", "[[.5,0,0]]",  "[[1,0,0],]", "[[1,0,0]",
                       "[[1 0,0]]",  "[[1,0,nul]]", "[]",         "[[1,0,0]]x"};
  for (size_t b = 0; b < sizeof bad / sizeof bad[0]; ++b) {
    f = fopen(path, "wb");
    if (!f) break;
    fprintf(f,
            "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\"],"
            "\"frames\":%s}",
            bad[b]);
    fclose(f);
    km_status st = km_take_read(path, &t, KM_E);
    CHECK_MSG(st == KM_ERR_PARSE && km_test_err.message[0], "frames %s: %s", bad[b],
              km_status_name(st));
    if (st == KM_OK) km_take_free(&t);
  }
  remove(path);
}

int main(void) {
  test_take_memory(); /* first: it measures the peak resident size */
  test_kinect_tables();
  test_skeleton_from_weights();
  test_pose();
  test_take_io();
  test_generate();
  return km_test_finish("test_motion");
}
