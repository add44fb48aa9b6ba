/* Pose descriptor, CART feature selection, SVM pose database, TRACK files, morphing. */
#include "synth/poses.h"
#include "km_test.h"
#include "transfer/transfer.h" /* km_cart_*: test fixture */

#include <unistd.h>

static uint64_t rng = 0x9e3779b97f4a7c15ULL;
static double urand(void) { /* [0,1) */
  rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
  return (double)(rng >> 11) / 9007199254740992.0;
}

static void test_candidates(void) {
  CHECK(km_pose_candidate_count(16) == 1680);
  CHECK(km_pose_candidate_count(2) == 0);
  size_t n = 16, F = km_pose_candidate_count(n);
  int seen_ok = 1;
  static unsigned char seen[16][16][16];
  memset(seen, 0, sizeof seen);
  for (size_t f = 0; f < F; ++f) {
    int32_t t[3];
    km_pose_candidate(n, f, t);
    if (t[0] < 0 || t[2] >= 16 || t[0] >= t[2] || t[0] == t[1] || t[2] == t[1] ||
        seen[t[0]][t[1]][t[2]]++)
      seen_ok = 0;
  }
  CHECK(seen_ok);
  /* Right angle, straight angle, zero-length segment. */
  double P[9] = {1, 0, 0, 0, 0, 0, 0, 2, 0}, a[3];
  int32_t tr[9] = {0, 1, 2, 0, 1, 0, 1, 0, 2};
  km_pose_angles(P, tr, 2, a);
  CHECK_NEAR(a[0], M_PI / 2, 1e-15);
  CHECK_NEAR(a[1], 0, 1e-7);
  double Q[9] = {1, 0, 0, 0, 0, 0, -3, 0, 0};
  km_pose_angles(Q, tr, 1, a);
  CHECK_NEAR(a[0], M_PI, 1e-7);
}

static void test_cart(void) {
  /* Feature 3 separates the classes (x3 < 0.5: class 0, else class 1, and x3 > 0.8: 2);
   * the others are noise. */
  enum { N = 90, F = 6 };
  double X[N * F];
  int32_t y[N];
  for (int i = 0; i < N; ++i) {
    for (int f = 0; f < F; ++f)
      X[i * F + f] = urand();
    double v = X[i * F + 3];
    y[i] = v < 0.5 ? 0 : v > 0.8 ? 2 : 1;
  }
  km_cart *t = NULL;
  double imp[F];
  CHECK_OK(km_cart_fit(X, y, N, F, 3, 0, &t, imp, KM_E));
  int correct = 0;
  for (int i = 0; i < N; ++i)
    correct += km_cart_predict(t, X + i * F) == y[i];
  CHECK(correct == N);
  CHECK_NEAR(imp[3], 1.0, 1e-12);
  CHECK(km_cart_nodes(t) == 5);
  double q[F] = {0.1, 0.9, 0.9, 0.9, 0.1, 0.1};
  CHECK(km_cart_predict(t, q) == 2);
  km_cart_free(&t);
  CHECK(t == NULL);
  int32_t bad[1] = {5};
  CHECK_STATUS(km_cart_fit(X, bad, 1, F, 3, 0, &t, NULL, KM_E), KM_ERR_INVALID);
}

/* Toy landmark set: 16 points; class c moves landmark pairs in class-specific ways. */
static void toy_landmarks(km_landmark *lm) {
  for (int i = 0; i < 16; ++i) {
    memset(&lm[i], 0, sizeof lm[i]);
    snprintf(lm[i].name, sizeof lm[i].name, "p%d", i);
    /* pairs (2k, 2k+1) mirror each other */
    snprintf(lm[i].mirror, sizeof lm[i].mirror, "p%d", i ^ 1);
    lm[i].vertex = i;
  }
}
static void toy_pose(int c, double *V) {
  for (int i = 0; i < 16; ++i) {
    double side = (i & 1) ? -1 : 1;
    V[3 * i] = side * (0.2 + 0.05 * (i / 2)) + 0.01 * (urand() - 0.5);
    V[3 * i + 1] = 0.1 * (i / 2) + 0.01 * (urand() - 0.5);
    V[3 * i + 2] = 0.01 * (urand() - 0.5);
  }
  /* class c lifts landmark c */
  V[3 * c + 1] += 0.5;
  V[3 * c + 2] += 0.3;
}

static void test_toy_classification(void) {
  enum { C = 5, PER = 8 };
  km_landmark lm[16];
  toy_landmarks(lm);
  km_mesh meshes[C * PER];
  int32_t labels[C * PER];
  double *buf = malloc(C * PER * 48 * sizeof *buf);
  for (int i = 0; i < C * PER; ++i) {
    labels[i] = i % C;
    meshes[i] = (km_mesh){.V = buf + 48 * i, .n_vertices = 16};
    toy_pose(labels[i], buf + 48 * i);
  }
  km_posedb_options o = {0};
  o.features = 20;
  km_posedb *db = NULL;
  km_posedb_report rep;
  CHECK_OK(km_posedb_build(meshes, C * PER, labels, C, NULL, NULL, lm, 16, &o, &db, &rep, KM_E));
  CHECK_NEAR(rep.cv_accuracy, 1.0, 0);
  CHECK(rep.cv_folds == 5 && rep.features == 20 && rep.classes == C);
  int correct = 0;
  for (int i = 0; i < 50; ++i) {
    double P[48];
    toy_pose(i % C, P);
    km_pose_match m;
    CHECK_OK(km_posedb_query(db, P, &m, KM_E));
    correct += m.label == i % C && km_posedb_label(db, m.template_index) == m.label;
  }
  CHECK_MSG(correct == 50, "%d of 50 toy poses recognised", correct);
  /* Linear kernel, mirrored SVM training, no mirroring. */
  for (int variant = 0; variant < 3; ++variant) {
    km_posedb_options ov = o;
    ov.kernel = variant == 0 ? KM_SVM_LINEAR : KM_SVM_RBF;
    ov.mirror = variant == 1   ? KM_POSE_MIRROR_ALL
                : variant == 2 ? KM_POSE_MIRROR_NONE
                               : KM_POSE_MIRROR_SELECTION;
    ov.cv_folds = 1;
    km_posedb *dv = NULL;
    km_posedb_report rv;
    CHECK_OK(km_posedb_build(meshes, C * PER, labels, C, NULL, NULL, lm, 16, &ov, &dv, &rv, KM_E));
    CHECK(rv.cv_accuracy == -1 && rv.cv_accuracy_eq8 == -1 && rv.cv_folds == 0);
    int ok = 0;
    for (int i = 0; i < 20 && dv; ++i) {
      double P[48];
      toy_pose(i % C, P);
      km_pose_match m;
      CHECK_OK(km_posedb_query(dv, P, &m, KM_E));
      /* Mirrored training merges a class with its mirror image (here class 2k+1 lifts the
       * mirror of what class 2k lifts), so only the pair must be right. */
      int c = i % C;
      ok += m.label == c || (variant == 1 && m.label == (c ^ 1));
    }
    CHECK_MSG(ok == 20, "variant %d: %d of 20", variant, ok);
    km_posedb_free(&dv);
  }
  /* Errors: bad label, mirror naming a missing landmark, NaN query. */
  labels[3] = C;
  km_posedb *bad = NULL;
  CHECK_STATUS(
      km_posedb_build(meshes, C * PER, labels, C, NULL, NULL, lm, 16, &o, &bad, NULL, KM_E),
      KM_ERR_INVALID);
  labels[3] = 3 % C;
  strcpy(lm[4].mirror, "nobody");
  CHECK_STATUS(
      km_posedb_build(meshes, C * PER, labels, C, NULL, NULL, lm, 16, &o, &bad, NULL, KM_E),
      KM_ERR_INVALID);
  double P[48];
  toy_pose(0, P);
  P[7] = NAN;
  km_pose_match m;
  CHECK_STATUS(km_posedb_query(db, P, &m, KM_E), KM_ERR_INVALID);
  km_posedb_free(&db);
  CHECK(db == NULL);
  free(buf);
}

/* Generated subjects; all share connectivity. */
typedef struct subject {
  km_character c;
} subject;

static const km_character_options subject_opts[] = {
    {2000, 0, 0, 0, 0, {0}},        {2000, 3, 1.60, 0.9, 0, {0}},
    {2000, 7, 1.90, 1.2, 0.8, {0}}, {2000, 11, 1.75, 1.0, 0.4, {0}},
    {2000, 21, 1.68, 1.1, 0, {0}},  {2000, 42, 1.82, 0.85, 1.2, {0}},
};
#define N_SUBJECTS 6
#define N_TRAIN 4
#define JITTERS 2

static void pose_sample(const km_character *c, int cls, double *V) {
  double jit[KP_MAX_ROTS];
  for (int k = 0; k < KP_MAX_ROTS; ++k)
    jit[k] = 0.3 * (urand() - 0.5);
  CHECK_OK(kp_pose_character(c, &kp_poses[cls], jit, V, KM_E));
}

typedef struct capture {
  double *frames;
  size_t n, count;
  int out_of_order;
} capture;
static km_status capture_frame(size_t frame, const double *V, void *user, km_error *err) {
  (void)err;
  capture *c = user;
  if (frame != c->count) c->out_of_order = 1;
  if (frame < 11) memcpy(c->frames + frame * c->n * 3, V, c->n * 3 * sizeof(double));
  ++c->count;
  return KM_OK;
}

static void test_database(subject *s, const char *tmpdir) {
  size_t n = s[0].c.mesh.n_vertices;
  size_t ntr = (size_t)N_TRAIN * KP_N_POSES * JITTERS;
  km_mesh *meshes = calloc(ntr, sizeof *meshes);
  int32_t *labels = malloc(ntr * sizeof *labels), *groups = malloc(ntr * sizeof *groups);
  double *buf = malloc(ntr * n * 3 * sizeof *buf);
  const char *names[KP_N_POSES];
  for (int c = 0; c < KP_N_POSES; ++c)
    names[c] = kp_poses[c].name;
  size_t k = 0;
  for (int si = 0; si < N_TRAIN; ++si)
    for (int c = 0; c < KP_N_POSES; ++c)
      for (int j = 0; j < JITTERS; ++j, ++k) {
        meshes[k] = s[si].c.mesh;
        meshes[k].V = buf + k * n * 3;
        pose_sample(&s[si].c, c, meshes[k].V);
        labels[k] = c;
        groups[k] = si;
      }
  km_posedb_options o = {0}; /* d = 60 */
  km_posedb *db = NULL;
  km_posedb_report rep;
  CHECK_OK(km_posedb_build(meshes, ntr, labels, KP_N_POSES, names, groups, s[0].c.landmarks, 16, &o,
                           &db, &rep, KM_E));
  if (!db) return;
  printf("  database: %zu samples, %zu classes, d = %zu, leave-one-subject-out accuracy %.3f over "
         "%zu folds, built in %.0f ms\n",
         rep.samples, rep.classes, rep.features, rep.cv_accuracy, rep.cv_folds, rep.build_ms);
  CHECK(rep.features == 60 && rep.cv_folds == N_TRAIN);
  CHECK(rep.cv_accuracy >= 0.95);
  /* eq. 8 over the one-vs-rest problems: 1 - 2 e / (N K), never below correct / total */
  CHECK_NEAR(rep.cv_accuracy_eq8, 1 - 2 * (1 - rep.cv_accuracy) / (double)rep.classes, 1e-12);
  CHECK(rep.cv_accuracy_eq8 >= rep.cv_accuracy);
  size_t d = 0;
  const int32_t *fe = km_posedb_features(db, &d);
  CHECK(d == 60 && fe != NULL);
  printf("  top features (angle at landmark j between j-i and j-k):");
  for (size_t f = 0; f < 6 && fe; ++f)
    printf(" %s-%s-%s", s[0].c.landmarks[fe[3 * f]].name, s[0].c.landmarks[fe[3 * f + 1]].name,
           s[0].c.landmarks[fe[3 * f + 2]].name);
  printf("\n");
  /* Held-out subjects. */
  int correct = 0, total = 0;
  double qms = 0, P[48], *V = malloc(n * 3 * sizeof *V);
  for (int si = N_TRAIN; si < N_SUBJECTS; ++si)
    for (int c = 0; c < KP_N_POSES; ++c)
      for (int j = 0; j < JITTERS; ++j) {
        pose_sample(&s[si].c, c, V);
        for (int l = 0; l < 16; ++l)
          memcpy(P + 3 * l, V + 3 * (size_t)s[si].c.landmarks[l].vertex, 3 * sizeof(double));
        km_pose_match m;
        CHECK_OK(km_posedb_query(db, P, &m, KM_E));
        correct += m.label == c;
        ++total;
        qms += m.ms;
      }
  double acc = (double)correct / total;
  printf("  held-out subjects: accuracy %.3f (%d/%d), query %.4f ms mean\n", acc, correct, total,
         qms / total);
  CHECK_MSG(acc >= 0.95, "held-out accuracy %g", acc);
  /* Save / load gives the same database and the same answers (and the template names). */
  CHECK(!strcmp(km_posedb_template_name(db, 0), ""));
  {
    size_t nt = km_posedb_size(db);
    char(*tn)[32] = calloc(nt, sizeof *tn);
    const char **tp = calloc(nt, sizeof *tp);
    for (size_t i = 0; tn && tp && i < nt; ++i) {
      snprintf(tn[i], sizeof tn[i], "template %zu", i);
      tp[i] = tn[i];
    }
    if (tn && tp) CHECK_OK(km_posedb_set_template_names(db, tp, KM_E));
    free(tn);
    free(tp);
  }
  char path[1024];
  snprintf(path, sizeof path, "%s/db.kmposedb", tmpdir);
  CHECK_OK(km_posedb_save(db, path, KM_E));
  km_posedb *db2 = NULL;
  CHECK_OK(km_posedb_load(path, &db2, KM_E));
  if (db2) {
    CHECK(km_posedb_size(db2) == ntr && km_posedb_classes(db2) == KP_N_POSES);
    CHECK(strcmp(km_posedb_class_name(db2, 3), "squat") == 0);
    size_t d2;
    const int32_t *fe2 = km_posedb_features(db2, &d2);
    CHECK(d2 == d && memcmp(fe, fe2, d * 3 * sizeof *fe) == 0);
    km_posedb_report r2;
    km_posedb_info(db2, &r2);
    CHECK_NEAR(r2.cv_accuracy, rep.cv_accuracy, 1e-12);
    CHECK_NEAR(r2.cv_accuracy_eq8, rep.cv_accuracy_eq8, 1e-12);
    CHECK(!strcmp(km_posedb_template_name(db2, 17), "template 17"));
    CHECK(!strcmp(km_posedb_template_name(db2, 0), "template 0"));
    km_mesh t1, t2;
    km_posedb_template(db, 17, &t1);
    km_posedb_template(db2, 17, &t2);
    CHECK(memcmp(t1.V, t2.V, n * 3 * sizeof(double)) == 0 && t2.n_faces == t1.n_faces);
    /* same predictions on the held-out set */
    rng = 12345;
    int same = 1, t = 0;
    for (int si = N_TRAIN; si < N_SUBJECTS; ++si)
      for (int c = 0; c < KP_N_POSES; ++c) {
        pose_sample(&s[si].c, c, V);
        for (int l = 0; l < 16; ++l)
          memcpy(P + 3 * l, V + 3 * (size_t)s[si].c.landmarks[l].vertex, 3 * sizeof(double));
        km_pose_match m1, m2;
        CHECK_OK(km_posedb_query(db, P, &m1, KM_E));
        CHECK_OK(km_posedb_query(db2, P, &m2, KM_E));
        same &= m1.label == m2.label && m1.template_index == m2.template_index;
        ++t;
      }
    CHECK(same);
    km_posedb_free(&db2);
  }
  /* Corruptions are reported, not crashed on. */
  char *data = NULL;
  size_t size = 0;
  FILE *f = fopen(path, "rb");
  if (f) {
    fseek(f, 0, SEEK_END);
    size = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    data = malloc(size);
    CHECK(fread(data, 1, size, f) == size);
    fclose(f);
  }
  if (data) {
    char bad[1024];
    snprintf(bad, sizeof bad, "%s/bad.kmposedb", tmpdir);
    size_t cuts[] = {0, 7, 20, 100, size / 2, size - 1};
    for (size_t ci = 0; ci < sizeof cuts / sizeof cuts[0]; ++ci) {
      f = fopen(bad, "wb");
      fwrite(data, 1, cuts[ci], f);
      fclose(f);
      km_posedb *x = NULL;
      km_status st = km_posedb_load(bad, &x, KM_E);
      CHECK_MSG(st == KM_ERR_PARSE && x == NULL, "cut at %zu: %s", cuts[ci], km_status_name(st));
    }
    data[size / 3] ^= 0x40;
    f = fopen(bad, "wb");
    fwrite(data, 1, size, f);
    fclose(f);
    km_posedb *x = NULL;
    CHECK_STATUS(km_posedb_load(bad, &x, KM_E), KM_ERR_PARSE);
    remove(bad);
    free(data);
  }
  remove(path);

  /* Motion generation: a held-out subject's track drives subject 1 as the avatar. */
  const km_character *av = &s[1].c, *user = &s[N_SUBJECTS - 1].c;
  int32_t ids[16];
  for (int l = 0; l < 16; ++l)
    ids[l] = av->landmarks[l].vertex;
  km_transfer *tr = NULL;
  CHECK_OK(km_transfer_precompute(&av->mesh, ids, 16, NULL, &tr, KM_E));
  enum { NF = 11 };
  km_track trk = {NF, 16, 30, NULL, NULL};
  trk.names = calloc(16, sizeof *trk.names);
  trk.positions = malloc(NF * 48 * sizeof(double));
  for (int l = 0; l < 16; ++l)
    strcpy(trk.names[15 - l], s[0].c.landmarks[l].name); /* reversed order: matched by name */
  for (int fr = 0; fr < NF; ++fr) {
    pose_sample(user, (fr / 3) % KP_N_POSES, V);
    for (int l = 0; l < 16; ++l)
      memcpy(trk.positions + fr * 48 + 3 * (15 - l), V + 3 * (size_t)user->landmarks[l].vertex,
             3 * sizeof(double));
  }
  capture cap = {malloc(NF * n * 3 * sizeof(double)), n, 0, 0};
  km_avatar_options ao = {0};
  ao.key_every = 4;
  ao.track_scale = 1.0;
  km_avatar_stats ast;
  CHECK_OK(km_avatar_animate(tr, db, &trk, &ao, capture_frame, &cap, &ast, KM_E));
  CHECK(cap.count == NF && !cap.out_of_order);
  CHECK(ast.frames == NF && ast.key_frames == 4); /* frames 0, 4, 8, 10 */
  printf("  avatar: %zu frames, %zu key frames, recognition %.3f ms, transfer %.2f ms, %.1f "
         "iterations per key pose\n",
         ast.frames, ast.key_frames, ast.recognition_ms / ast.key_frames,
         ast.transfer_ms / ast.key_frames, ast.iterations_mean);
  /* Key frames equal a direct recognition + transfer; frames between are the linear
   * interpolation of their two key poses, endpoints included. */
  double *key[4];
  const int keys[4] = {0, 4, 8, 10};
  for (int q = 0; q < 4; ++q) {
    key[q] = malloc(n * 3 * sizeof(double));
    double Pk[48], tg[48];
    for (int l = 0; l < 16; ++l)
      memcpy(Pk + 3 * l, trk.positions + keys[q] * 48 + 3 * (15 - l), 3 * sizeof(double));
    km_pose_match m;
    CHECK_OK(km_posedb_query(db, Pk, &m, KM_E));
    km_mesh T;
    km_posedb_template(db, m.template_index, &T);
    for (int i = 0; i < 48; ++i)
      tg[i] = ao.track_scale * Pk[i];
    CHECK_OK(km_transfer_solve(tr, T.V, tg, NULL, key[q], NULL, KM_E));
    double e, mx;
    kp_error(key[q], cap.frames + (size_t)keys[q] * n * 3, n, &e, &mx);
    CHECK_MSG(mx < 1e-12, "key frame %d differs by %g", keys[q], mx);
  }
  double *lerp = malloc(n * 3 * sizeof(double)), worst = 0;
  for (int fr = 0; fr < NF; ++fr) {
    int q = fr >= 8 ? 2 : fr >= 4 ? 1 : 0;
    if (fr == 10) q = 2;
    double a = (double)(fr - keys[q]) / (keys[q + 1 < 4 ? q + 1 : 3] - keys[q]);
    km_pose_lerp(key[q], key[q + 1 < 4 ? q + 1 : 3], n, a, lerp);
    double e, mx;
    kp_error(lerp, cap.frames + (size_t)fr * n * 3, n, &e, &mx);
    worst = fmax(worst, mx);
  }
  CHECK_MSG(worst < 1e-12, "in-between frames differ from the interpolation by %g", worst);
  km_pose_lerp(key[0], key[1], n, 0.0, lerp);
  CHECK(memcmp(lerp, key[0], n * 3 * sizeof(double)) == 0);
  km_pose_lerp(key[0], key[1], n, 1.0, lerp);
  CHECK(memcmp(lerp, key[1], n * 3 * sizeof(double)) == 0);
  /* Automatic track scale: the avatar's size over the user's. */
  ao.track_scale = 0;
  cap.count = 0;
  CHECK_OK(km_avatar_animate(tr, db, &trk, &ao, capture_frame, &cap, &ast, KM_E));
  CHECK(cap.count == NF);
  /* A track without one of the database's landmarks is refused. */
  strcpy(trk.names[3], "tail");
  CHECK_STATUS(km_avatar_animate(tr, db, &trk, &ao, capture_frame, &cap, &ast, KM_E),
               KM_ERR_INVALID);
  /* TRACK files round-trip (JSON and CSV), NaN included. */
  strcpy(trk.names[3], s[0].c.landmarks[12].name);
  trk.positions[5] = NAN;
  const char *exts[2] = {"json", "csv"};
  for (int x = 0; x < 2; ++x) {
    char tp[1024];
    snprintf(tp, sizeof tp, "%s/track.%s", tmpdir, exts[x]);
    CHECK_OK(km_track_write(tp, &trk, KM_E));
    km_track rd;
    CHECK_OK(km_track_read(tp, &rd, KM_E));
    CHECK(rd.n_frames == NF && rd.n_landmarks == 16 && rd.fps == 30);
    CHECK(rd.names && strcmp(rd.names[3], trk.names[3]) == 0);
    int eq = rd.positions != NULL;
    for (int i = 0; eq && i < NF * 48; ++i)
      eq = (isnan(trk.positions[i]) && isnan(rd.positions[i])) ||
           trk.positions[i] == rd.positions[i];
    CHECK_MSG(eq, "%s track does not round-trip", exts[x]);
    km_track_free(&rd);
    remove(tp);
  }
  char tp[1024];
  snprintf(tp, sizeof tp, "%s/bad.csv", tmpdir);
  f = fopen(tp, "w");
  fputs("a,b\n1,2,3,4,5,6\n1,2,x,4,5,6\n", f);
  fclose(f);
  km_track rd;
  CHECK_STATUS(km_track_read(tp, &rd, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "line 3") != NULL);
  snprintf(tp, sizeof tp, "%s/bad.json", tmpdir);
  f = fopen(tp, "w");
  fputs("{\"fps\":30,\"landmarks\":[\"a\"],\"frames\":[[1,2]]}", f);
  fclose(f);
  CHECK_STATUS(km_track_read(tp, &rd, KM_E), KM_ERR_PARSE);
  remove(tp);
  snprintf(tp, sizeof tp, "%s/bad.csv", tmpdir);
  remove(tp);
  for (int q = 0; q < 4; ++q)
    free(key[q]);
  free(lerp);
  free(cap.frames);
  free(V);
  km_track_free(&trk);
  km_transfer_free(&tr);
  free(meshes);
  free(labels);
  free(groups);
  free(buf);
  km_posedb_free(&db);
}

static void test_landmark_files(const km_character *c, const char *tmpdir) {
  char path[1024];
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t n = 0;
  /* A rig sidecar carries the same "landmarks" array. */
  snprintf(path, sizeof path, "%s/c.rig.json", tmpdir);
  CHECK_OK(km_character_write_rig(path, c, KM_E));
  CHECK_OK(km_landmarks_read(path, c->mesh.n_vertices, lm, KM_POSE_MAX_LANDMARKS, &n, KM_E));
  CHECK(n == 16);
  for (size_t i = 0; i < n && i < 16; ++i)
    CHECK(lm[i].vertex == c->landmarks[i].vertex && !strcmp(lm[i].name, c->landmarks[i].name) &&
          !strcmp(lm[i].mirror, c->landmarks[i].mirror));
  remove(path);
  /* LM.json round trip. */
  snprintf(path, sizeof path, "%s/LM.json", tmpdir);
  CHECK_OK(km_landmarks_write(path, c->landmarks, 16, KM_E));
  km_landmark lm2[KM_POSE_MAX_LANDMARKS];
  CHECK_OK(km_landmarks_read(path, 0, lm2, KM_POSE_MAX_LANDMARKS, &n, KM_E));
  CHECK(n == 16 && memcmp(lm, lm2, 16 * sizeof *lm) == 0);
  /* Vertex out of range for the mesh, too many for the capacity, a mirror that is missing. */
  CHECK_STATUS(km_landmarks_read(path, 10, lm2, KM_POSE_MAX_LANDMARKS, &n, KM_E), KM_ERR_PARSE);
  CHECK_STATUS(km_landmarks_read(path, 0, lm2, 8, &n, KM_E), KM_ERR_PARSE);
  FILE *f = fopen(path, "w");
  fputs("{\"landmarks\":[{\"name\":\"a\",\"vertex\":1,\"mirror\":\"b\"}]}", f);
  fclose(f);
  CHECK_STATUS(km_landmarks_read(path, 0, lm2, KM_POSE_MAX_LANDMARKS, &n, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "\"b\"") != NULL);
  f = fopen(path, "w");
  fputs("{\"landmarks\":[{\"name\":\"a\",\"vertex\":-1}]", f);
  fclose(f);
  CHECK_STATUS(km_landmarks_read(path, 0, lm2, KM_POSE_MAX_LANDMARKS, &n, KM_E), KM_ERR_PARSE);
  remove(path);
}

/* ---- issue 18: forged pose databases (valid checksums) */

static uint64_t fnv1a(uint64_t h, const void *p, size_t n) {
  const unsigned char *b = p;
  for (size_t i = 0; i < n; ++i)
    h = (h ^ b[i]) * 0x100000001b3ULL;
  return h;
}
/* Writes "KMPOSEDB" | version | header length | json | body | FNV-1a, as km_posedb_save. */
static void write_db(const char *path, uint32_t version, const char *json, const void *body,
                     size_t nb) {
  FILE *f = fopen(path, "wb");
  CHECK(f != NULL);
  if (!f) return;
  uint64_t hl = strlen(json), h = 0xcbf29ce484222325ULL;
  h = fnv1a(h, "KMPOSEDB", 8), h = fnv1a(h, &version, 4), h = fnv1a(h, &hl, 8);
  h = fnv1a(h, json, hl), h = fnv1a(h, body, nb);
  fwrite("KMPOSEDB", 1, 8, f), fwrite(&version, 4, 1, f), fwrite(&hl, 8, 1, f);
  fwrite(json, 1, hl, f), fwrite(body, 1, nb, f), fwrite(&h, 8, 1, f);
  fclose(f);
}
/* Header JSON of n meshes of 16 vertices (the toy landmarks), two classes, the first d
 * candidate features; svm: NULL (version 1) or the "svm" member's text. */
static char *forged_json(size_t n, size_t d, const char *svm) {
  size_t cap = 64 * d + 8 * n + 4096, len = 0;
  char *j = malloc(cap);
  len += (size_t)snprintf(j + len, cap - len,
                          "{\"format\":\"kinemesh-posedb\",\"n_meshes\":%zu,\"n_vertices\":16,"
                          "\"n_faces\":0,\"landmarks\":[",
                          n);
  for (int i = 0; i < 16; ++i)
    len += (size_t)snprintf(j + len, cap - len,
                            "%s{\"name\":\"p%d\",\"vertex\":%d,\"mirror\":\"p%d\"}", i ? "," : "",
                            i, i, i ^ 1);
  len += (size_t)snprintf(j + len, cap - len, "],\"classes\":[\"a\",\"b\"],\"labels\":[");
  for (size_t i = 0; i < n; ++i)
    len += (size_t)snprintf(j + len, cap - len, "%s%zu", i ? "," : "", i & 1);
  len += (size_t)snprintf(j + len, cap - len, "],\"features\":[");
  for (size_t f = 0; f < d; ++f) {
    int32_t t[3];
    km_pose_candidate(16, f, t);
    len += (size_t)snprintf(j + len, cap - len, "%s[%d,%d,%d]", f ? "," : "", t[0], t[1], t[2]);
  }
  len += (size_t)snprintf(j + len, cap - len, "]%s%s}", svm ? ",\"svm\":" : "", svm ? svm : "");
  return j;
}

static void test_forged_database(const char *tmpdir) {
  char path[1024];
  snprintf(path, sizeof path, "%s/forged.kmposedb", tmpdir);
  enum { NBIG = 3000 };
  double *V = malloc((size_t)NBIG * 48 * sizeof *V);
  for (size_t i = 0; i < (size_t)NBIG; ++i)
    toy_pose((int)(i % 2), V + 48 * i);
  size_t dall = km_pose_candidate_count(16); /* 1,680 */
  km_posedb *db = NULL;

  /* Version 1 (no stored model) with many templates and every candidate feature: retraining
   * it would cost samples^2 x features = 1.5e10; refused, naming the way out. */
  char *json = forged_json(NBIG, dall, NULL);
  write_db(path, 1, json, V, (size_t)NBIG * 48 * sizeof *V);
  free(json);
  CHECK_STATUS(km_posedb_load(path, &db, KM_E), KM_ERR_UNSUPPORTED);
  CHECK(db == NULL && strstr(km_test_err.message, "posedb build"));

  /* A small version 1 database is still read (retrained): it recognises its own templates. */
  json = forged_json(40, 60, NULL);
  write_db(path, 1, json, V, 40 * 48 * sizeof *V);
  free(json);
  CHECK_OK(km_posedb_load(path, &db, KM_E));
  if (db) {
    size_t d = 0;
    km_posedb_features(db, &d);
    int right = 0;
    for (int i = 0; i < 40; ++i) {
      km_pose_match m;
      CHECK_OK(km_posedb_query(db, V + 48 * i, &m, KM_E));
      right += m.label == i % 2;
    }
    CHECK_MSG(d == 60 && right >= 38, "version 1: %zu features, %d of 40 right", d, right);
    km_posedb_free(&db);
  }

  /* Numbers the file stores for integers: an option far outside int's range (casting it was
   * undefined behaviour) is refused, naming the key; a group that is no whole int32 is no
   * group, and the database still loads. */
  static const char *const bad_opts[] = {"{\"tree_max_depth\":1e30}", "{\"cv_folds\":-1e300}",
                                         "{\"mirror\":7}", "{\"kernel\":0.5}"};
  for (int b = 0; b < 4; ++b) {
    char extra[256];
    snprintf(extra, sizeof extra, "null,\"options\":%s", bad_opts[b]);
    json = forged_json(40, 60, extra);
    write_db(path, 1, json, V, 40 * 48 * sizeof *V);
    free(json);
    CHECK_STATUS(km_posedb_load(path, &db, KM_E), KM_ERR_PARSE);
    CHECK_MSG(db == NULL && strstr(km_test_err.message, "options.") &&
                  strstr(km_test_err.message, "forged.kmposedb"),
              "options %s: %s", bad_opts[b], km_test_err.message);
  }
  {
    char extra[1024] = "null,\"groups\":[1e30,-1e30,1.5";
    for (int i = 3; i < 40; ++i)
      strcat(extra, i & 1 ? ",1" : ",2");
    strcat(extra, "]");
    json = forged_json(40, 60, extra);
    write_db(path, 1, json, V, 40 * 48 * sizeof *V);
    free(json);
    CHECK_OK(km_posedb_load(path, &db, KM_E));
    km_posedb_free(&db);
  }

  /* Indices the file stores (a landmark's vertex, a label, a feature's landmark) are whole
   * numbers: 3.5 is refused, naming what is wrong, where the cast used to take vertex 3. */
  {
    /* the text before the index, and the message naming it */
    static const char *const what[3][2] = {{"\"vertex\":3", "landmark 3"},
                                           {"\"labels\":[", "label 0"},
                                           {"\"features\":[[", "feature 0"}};
    for (int w = 0; w < 3; ++w) {
      json = forged_json(40, 60, NULL);
      char *at = strstr(json, what[w][0]);
      CHECK_MSG(at != NULL, "forged header lacks %s", what[w][0]);
      if (at) {
        const char *num = at + strlen(what[w][0]), *end = num;
        while (*end >= '0' && *end <= '9')
          ++end;
        size_t cap = strlen(json) + 16;
        char *j2 = malloc(cap);
        snprintf(j2, cap, "%.*s.5%s", (int)(end - json), json, end); /* the index and a half */
        write_db(path, 1, j2, V, 40 * 48 * sizeof *V);
        free(j2);
        CHECK_STATUS(km_posedb_load(path, &db, KM_E), KM_ERR_PARSE);
        CHECK_MSG(db == NULL && strstr(km_test_err.message, what[w][1]), "%s: %s", what[w][0],
                  km_test_err.message);
      }
      free(json);
    }
  }

  /* Version 2 must carry the model in its bytes: the same big header claiming a model it does
   * not hold (no descriptors, no support vectors) is refused by its size, before allocating. */
  json = forged_json(NBIG, dall,
                     "{\"classes\":2,\"vectors\":6000,\"label\":[0,1],"
                     "\"n_sv\":[3000,3000]}");
  write_db(path, 2, json, V, (size_t)NBIG * 48 * sizeof *V);
  free(json);
  CHECK_STATUS(km_posedb_load(path, &db, KM_E), KM_ERR_PARSE);
  CHECK(db == NULL && strstr(km_test_err.message, "with their model"));
  /* ... and a model of more classes than the database has is refused. */
  json = forged_json(40, 60, "{\"classes\":3,\"vectors\":0,\"label\":[0,1,2],\"n_sv\":[0,0,0]}");
  write_db(path, 2, json, V, 40 * 48 * sizeof *V);
  free(json);
  CHECK_STATUS(km_posedb_load(path, &db, KM_E), KM_ERR_PARSE);

  /* Built with mirrored SVM samples (support vectors that are mirrored copies), saved with
   * its model and loaded without training: the same answers. */
  km_landmark lm[16];
  toy_landmarks(lm);
  km_mesh meshes[40];
  int32_t labels[40];
  for (int i = 0; i < 40; ++i) {
    meshes[i] = (km_mesh){.V = V + 48 * i, .n_vertices = 16};
    labels[i] = i % 2;
  }
  km_posedb_options o = {0};
  o.mirror = KM_POSE_MIRROR_ALL;
  o.cv_folds = 1;
  CHECK_OK(km_posedb_build(meshes, 40, labels, 2, NULL, NULL, lm, 16, &o, &db, NULL, KM_E));
  CHECK_OK(km_posedb_save(db, path, KM_E));
  km_posedb *db2 = NULL;
  CHECK_OK(km_posedb_load(path, &db2, KM_E));
  if (db && db2) {
    int same = 1;
    for (int i = 40; i < 140; ++i) {
      km_pose_match m1, m2;
      CHECK_OK(km_posedb_query(db, V + 48 * i, &m1, KM_E));
      CHECK_OK(km_posedb_query(db2, V + 48 * i, &m2, KM_E));
      same &= m1.label == m2.label && m1.template_index == m2.template_index &&
              m1.distance == m2.distance;
    }
    CHECK_MSG(same, "mirrored model: answers differ after save and load");
  }
  km_posedb_free(&db);
  km_posedb_free(&db2);
  remove(path);
  free(V);
}

int main(void) {
  char tmpdir[] = "/tmp/km_test_pose_XXXXXX";
  if (!mkdtemp(tmpdir)) return 1;
  test_candidates();
  test_cart();
  test_toy_classification();
  test_forged_database(tmpdir);
  subject s[N_SUBJECTS];
  for (int i = 0; i < N_SUBJECTS; ++i)
    CHECK_OK(km_character_generate(&subject_opts[i], &s[i].c, KM_E));
  for (int i = 1; i < N_SUBJECTS; ++i)
    CHECK_MSG(s[i].c.mesh.n_vertices == s[0].c.mesh.n_vertices &&
                  s[i].c.mesh.n_faces == s[0].c.mesh.n_faces &&
                  memcmp(s[i].c.mesh.F, s[0].c.mesh.F, s[0].c.mesh.n_faces * 12) == 0 &&
                  s[i].c.landmarks[5].vertex == s[0].c.landmarks[5].vertex,
              "subject %d does not share subject 0's connectivity", i);
  test_landmark_files(&s[2].c, tmpdir);
  test_database(s, tmpdir);
  for (int i = 0; i < N_SUBJECTS; ++i)
    km_character_free(&s[i].c);
  rmdir(tmpdir);
  return km_test_finish("test_pose");
}
