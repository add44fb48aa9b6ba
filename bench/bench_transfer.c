/* Table 2 of Lifkooee et al. for SMPL-size meshes: offline Laplacian / Cholesky, online
 * recognition, frames and solve per iteration, iterations, total online time, and the error
 * against ground truth.
 *
 * Rows: a generated character of ~7,000 vertices (subject A takes the poses of subject B;
 * ground truth: A posed by LBS with the same joint angles; landmark targets are A's tracked
 * landmarks; the template comes from recognition in a database of other subjects), with the
 * default iterations and with one solve; FAUST (tr_reg_000 takes the pose of tr_reg_001 and
 * back, same subject, so the other is the truth; SMPL landmark file and `auto` landmarks) and
 * the cat poses when ../shared/data is present: these run exactly as `kinemesh transfer
 * --source A --template B [--iterations 1]` does (targets from the template through the
 * default alignment). The energy after each solve of the default
 * (km_transfer_energies; generated rows: summed over the poses) ends each default row.
 *
 * kinemesh bench transfer [--vertices N] [--root DIR] [--json]: those rows (DIR: the
 * repository root, for ../shared/data and tests/data/smpl_landmarks.json; default ".").
 * kinemesh bench transfer --source S --template T [--landmarks LM] [--truth X] [--db DB]:
 * one row for the given meshes. Times are medians of 15 runs. */
#include "bench.h"
#include "cli.h"

#include <math.h>

#include <cjson/cJSON.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct row {
  char name[64];
  size_t n_ver;
  double laplacian_ms, cholesky_ms, recognition_ms, frames_ms, solve_ms, iterations, online_ms;
  double online_cpu_ms; /* the same call in this thread's CPU time (a loaded machine) */
  double err_mean_mm, err_max_mm;
  double energy[16]; /* the energy after each solve of the default (edge encoding) */
  int n_energy;
} row;

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* This thread's CPU time: on a shared machine the wall clock also counts the time other
 * processes held the core. */
static double cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static int die(const char *what, const km_error *e) {
  fprintf(stderr, "kinemesh bench transfer: %s: %s\n", what, e->message);
  return 1;
}

/* A row as JSON; what was not measured (NaN) is null. */
static cJSON *row_json(const row *r) {
  cJSON *j = cJSON_CreateObject();
  cJSON_AddStringToObject(j, "name", r->name);
  cJSON_AddNumberToObject(j, "n_ver", (double)r->n_ver);
  const char *k[] = {"laplacian_ms", "cholesky_ms", "recognition_ms", "frames_ms",   "solve_ms",
                     "iterations",   "online_ms",   "online_cpu_ms",  "err_mean_mm", "err_max_mm"};
  const double v[] = {r->laplacian_ms, r->cholesky_ms, r->recognition_ms, r->frames_ms,
                      r->solve_ms,     r->iterations,  r->online_ms,      r->online_cpu_ms,
                      r->err_mean_mm,  r->err_max_mm};
  for (size_t i = 0; i < sizeof v / sizeof v[0]; ++i)
    km_cli_json_number(j, k[i], v[i]);
  if (r->n_energy) {
    cJSON *e = cJSON_AddArrayToObject(j, "energy");
    for (int i = 0; i < r->n_energy; ++i)
      cJSON_AddItemToArray(e, cJSON_CreateNumber(r->energy[i]));
  }
  return j;
}

static void print_row(const row *r) {
  char rec[16] = "       -";
  if (isfinite(r->recognition_ms)) snprintf(rec, sizeof rec, "%8.4f", r->recognition_ms);
  printf("%-40s %6zu %8.2f %8.2f %s %8.3f %8.3f %5.1f %8.2f %8.2f %8.2f %8.2f", r->name, r->n_ver,
         r->laplacian_ms, r->cholesky_ms, rec, r->frames_ms, r->solve_ms, r->iterations,
         r->online_ms, r->online_cpu_ms, r->err_mean_mm, r->err_max_mm);
  for (int i = 0; i < r->n_energy; ++i)
    printf("%s%.4g", i ? " " : "  E: ", r->energy[i]);
  printf("\n");
}

/* The energies of t's last solve into r (summed with what r holds). */
static void add_energy(row *r, const km_transfer *t) {
  double e[16];
  size_t k = km_transfer_energies(t, e, 16);
  if (k > 16) k = 16;
  for (size_t i = 0; i < k; ++i)
    r->energy[i] += e[i];
  if ((int)k > r->n_energy) r->n_energy = (int)k;
}

/* Online stage for one key pose: recognition (if db, queried with P or Pq) + transfer; medians
 * of 15 runs. With fixed_template the targets come from it (the CLI's default), otherwise P. */
typedef struct online {
  double rec_ms, frames_ms, solve_ms, total_ms, total_cpu_ms;
  int iterations;
} online;

enum { ONLINE_REPS = 15 };

static km_status run_online_q(km_transfer *t, const km_posedb *db, const double *P,
                              const double *Pq, const double *fixed_template, const double *warm,
                              double *X, online *o, km_error *e) {
  double rec[ONLINE_REPS], fr[ONLINE_REPS], so[ONLINE_REPS], tot[ONLINE_REPS], cpu[ONLINE_REPS];
  for (int rep = 0; rep < ONLINE_REPS; ++rep) {
    double t0 = now_ms(), c0 = cpu_ms();
    rec[rep] = 0;
    const double *T = fixed_template;
    if (db) {
      km_pose_match m;
      km_status s = km_posedb_query(db, Pq ? Pq : P, &m, e);
      if (s) return s;
      /* With a fixed template the database only times the recognition. */
      if (!fixed_template) {
        km_mesh tm;
        km_posedb_template(db, m.template_index, &tm);
        T = tm.V;
      }
      rec[rep] = now_ms() - t0;
    }
    km_transfer_stats st;
    /* A given template gives the landmark targets itself, through the default alignment, as
     * `kinemesh transfer --source S --template T` does; a recognised template goes with the
     * tracked targets P, as `avatar` and `transfer --landmarks-xyz` do. */
    km_status s = km_transfer_solve(t, T, fixed_template ? NULL : P, T ? NULL : warm, X, &st, e);
    if (s) return s;
    tot[rep] = now_ms() - t0;
    cpu[rep] = cpu_ms() - c0;
    fr[rep] = st.frames_ms / st.iterations;
    so[rep] = st.solve_ms / st.iterations;
    o->iterations = st.iterations;
  }
  o->rec_ms = km_cli_median(rec, ONLINE_REPS);
  o->frames_ms = km_cli_median(fr, ONLINE_REPS);
  o->solve_ms = km_cli_median(so, ONLINE_REPS);
  o->total_ms = km_cli_median(tot, ONLINE_REPS);
  o->total_cpu_ms = km_cli_median(cpu, ONLINE_REPS);
  return KM_OK;
}

static km_status run_online(km_transfer *t, const km_posedb *db, const double *P,
                            const double *fixed_template, const double *warm, double *X, online *o,
                            km_error *e) {
  return run_online_q(t, db, P, NULL, fixed_template, warm, X, o, e);
}

/* A row of a real pair: "NAME (<=10 it)" or "NAME (1 it)", errors of X against truth. */
static void fill_row(row *r, const char *name, int one_it, const km_transfer *t, const online *o,
                     bool recognition, const double *X, const double *truth, size_t n) {
  memset(r, 0, sizeof *r);
  snprintf(r->name, sizeof r->name, "%s (%s)", name, one_it ? "1 it" : "default");
  r->n_ver = n;
  km_transfer_precompute_ms(t, &r->laplacian_ms, &r->cholesky_ms);
  r->recognition_ms = recognition ? o->rec_ms : NAN;
  r->frames_ms = o->frames_ms;
  r->solve_ms = o->solve_ms;
  r->iterations = o->iterations;
  r->online_ms = o->total_ms;
  r->online_cpu_ms = o->total_cpu_ms;
  double mean, max;
  km_vertex_distance_stats(X, truth, n, &mean, &max);
  r->err_mean_mm = mean * 1e3;
  r->err_max_mm = max * 1e3;
  if (!one_it) add_energy(r, t);
}

/* Four generated subjects of nv vertices (c[0] the avatar) and a database of 10 pose classes
 * from subjects 1..3 (each pose plain and jittered); the subjects are the CV groups. */
static km_status generated_db(size_t nv, km_character c[4], km_posedb **db, km_posedb_report *rep,
                              km_error *e) {
  km_character_options so[4] = {{nv, 5, 1.70, 1.1, 0, {0}},
                                {nv, 11, 1.85, 0.9, 0.6, {0}},
                                {nv, 3, 1.60, 1.0, 0.3, {0}},
                                {nv, 0, 0, 0, 0, {0}}};
  memset(c, 0, 4 * sizeof *c);
  km_status st = KM_OK;
  for (int i = 0; i < 4 && !st; ++i)
    st = km_character_generate(&so[i], &c[i], e);
  if (st) {
    for (int i = 0; i < 4; ++i)
      km_character_free(&c[i]);
    return st;
  }
  size_t n = c[0].mesh.n_vertices;
  enum { JIT = 2 };
  size_t ndb = 3 * KM_POSE_PRESETS * JIT;
  km_mesh *meshes = calloc(ndb, sizeof *meshes);
  int32_t *labels = malloc(ndb * sizeof *labels), *groups = malloc(ndb * sizeof *groups);
  double *buf = malloc(ndb * n * 3 * sizeof *buf);
  if (!meshes || !labels || !groups || !buf) {
    st = km_error_set(e, KM_ERR_NOMEM, "out of memory for the pose database");
    goto done;
  }
  uint64_t rs = 88172645463325252ULL;
  size_t k = 0;
  for (int si = 1; si < 4 && !st; ++si)
    for (int p = 0; p < KM_POSE_PRESETS && !st; ++p)
      for (int j = 0; j < JIT && !st; ++j, ++k) {
        double jit[KM_POSE_PRESET_MAX_ROTATIONS];
        for (int q = 0; q < KM_POSE_PRESET_MAX_ROTATIONS; ++q) {
          rs ^= rs << 13, rs ^= rs >> 7, rs ^= rs << 17;
          jit[q] = 0.2 * ((double)(rs >> 11) / 9007199254740992.0 - 0.5);
        }
        meshes[k] = c[si].mesh;
        meshes[k].V = buf + k * n * 3;
        st = km_character_pose_preset(&c[si], p, j ? jit : NULL, meshes[k].V, e);
        labels[k] = p;
        groups[k] = si;
      }
  if (!st)
    st = km_posedb_build(meshes, ndb, labels, KM_POSE_PRESETS, NULL, groups, c[0].landmarks, 16,
                         NULL, db, rep, e);
done:
  free(meshes);
  free(labels);
  free(groups);
  free(buf);
  if (st)
    for (int i = 0; i < 4; ++i)
      km_character_free(&c[i]);
  return st;
}

/* One row for given meshes: S takes T's pose; landmarks from --landmarks or S's rig sidecar;
 * recognition against --db when given; errors against --truth when given. */
static int bench_pair(const char *src, const char *tmpl, const char *lm_path, const char *truth,
                      const char *db_path, bool json_only) {
  km_error e = {0};
  km_mesh S = {0}, T = {0}, X = {0};
  km_posedb *db = NULL;
  km_transfer *t = NULL;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t nl = 0;
  int32_t ids[KM_POSE_MAX_LANDMARKS];
  double P[3 * KM_POSE_MAX_LANDMARKS], *V = NULL;
  int rc = 1;
  char *rig = lm_path ? NULL : km_cli_rig_path(src);
  if (km_mesh_read(src, &S, &e) || km_mesh_read(tmpl, &T, &e) ||
      km_landmarks_read(lm_path ? lm_path : rig, S.n_vertices, lm, KM_POSE_MAX_LANDMARKS, &nl,
                        &e) ||
      (truth && km_mesh_read(truth, &X, &e)) || (db_path && km_posedb_load(db_path, &db, &e))) {
    rc = die("input", &e);
    goto done;
  }
  if (T.n_vertices != S.n_vertices || (truth && X.n_vertices != S.n_vertices)) {
    fprintf(stderr, "kinemesh bench transfer: source, template and truth need one connectivity\n");
    goto done;
  }
  for (size_t l = 0; l < nl; ++l)
    ids[l] = lm[l].vertex;
  /* untimed first precompute, as in the generated scenario */
  if (km_transfer_precompute(&S, ids, nl, NULL, &t, &e)) {
    rc = die("precompute", &e);
    goto done;
  }
  km_transfer_free(&t);
  if (km_transfer_precompute(&S, ids, nl, NULL, &t, &e)) {
    rc = die("precompute", &e);
    goto done;
  }
  /* The tracked landmarks: T's, scaled to S's size as km_transfer_solve does for a template. */
  if (km_transfer_targets(t, T.V, P, &e)) {
    rc = die("targets", &e);
    goto done;
  }
  /* Without --db, recognition is timed in the generated 10-class database when the landmarks
   * are the generator's 16 (same names): the query takes them in the database's order. */
  double Pq[3 * KM_POSE_MAX_LANDMARKS];
  const char *rec_note = NULL;
  km_character gc[4];
  bool have_gc = false;
  km_posedb_report grep_rep;
  if (!db && nl == KM_CHARACTER_LANDMARKS && generated_db(3000, gc, &db, &grep_rep, &e) == KM_OK) {
    have_gc = true;
    const km_landmark *glm = km_posedb_landmarks(db);
    bool names_ok = true;
    for (size_t a = 0; a < KM_CHARACTER_LANDMARKS && names_ok; ++a) {
      size_t b = 0;
      while (b < nl && strcmp(lm[b].name, glm[a].name))
        ++b;
      names_ok = b < nl;
      if (names_ok) memcpy(Pq + 3 * a, P + 3 * b, 3 * sizeof(double));
    }
    if (names_ok) {
      rec_note = "recognition in a generated 10-class database";
    } else {
      km_posedb_free(&db);
      for (int i = 0; i < 4; ++i)
        km_character_free(&gc[i]);
      have_gc = false;
    }
  }
  if (!db) rec_note = "no recognition: give --db, or the generator's 16 named landmarks";
  V = malloc(sizeof *V * 3 * S.n_vertices);
  online o;
  if (!V || run_online_q(t, db, P, have_gc ? Pq : NULL, T.V, NULL, V, &o, &e)) {
    rc = die("online", &e);
    goto done;
  }
  /* The baseline next to it: landmark-only editing (no template, frames from S). */
  double lo_mean = NAN, lo_max = NAN;
  if (truth) {
    online ob;
    if (run_online(t, NULL, P, NULL, S.V, V, &ob, &e)) {
      rc = die("online", &e);
      goto done;
    }
    km_vertex_distance_stats(V, X.V, S.n_vertices, &lo_mean, &lo_max);
    if (run_online(t, NULL, P, T.V, NULL, V, &ob, &e)) { /* V back to the transfer */
      rc = die("online", &e);
      goto done;
    }
  }
  row r;
  memset(&r, 0, sizeof r);
  const char *base = strrchr(src, '/');
  snprintf(r.name, sizeof r.name, "%s", base ? base + 1 : src);
  r.n_ver = S.n_vertices;
  km_transfer_precompute_ms(t, &r.laplacian_ms, &r.cholesky_ms);
  r.recognition_ms = db ? o.rec_ms : NAN;
  if (have_gc)
    for (int i = 0; i < 4; ++i)
      km_character_free(&gc[i]);
  r.frames_ms = o.frames_ms;
  r.solve_ms = o.solve_ms;
  r.iterations = o.iterations;
  r.online_ms = o.total_ms;
  r.online_cpu_ms = o.total_cpu_ms;
  r.err_mean_mm = r.err_max_mm = NAN;
  if (truth) {
    double mean, max;
    km_vertex_distance_stats(V, X.V, S.n_vertices, &mean, &max);
    r.err_mean_mm = 1e3 * mean;
    r.err_max_mm = 1e3 * max;
  }
  if (!json_only) {
    char machine[320];
    km_bench_machine(machine, sizeof machine);
    printf("kinemesh bench transfer — %s; medians of %d runs\n", machine, ONLINE_REPS);
    printf("%-40s %6s %8s %8s %8s %8s %8s %5s %8s %8s %8s %8s\n", "mesh", "n_ver", "lapl_ms",
           "chol_ms", "recog_ms", "frame_ms", "solve_ms", "iters", "online", "cpu_ms", "err_mean",
           "err_max");
    print_row(&r);
    if (truth)
      printf("landmark-only editing (no template): error mean %.2f mm, max %.2f mm\n",
             1e3 * lo_mean, 1e3 * lo_max);
    if (rec_note) printf("(%s)\n", rec_note);
  }
  cJSON *j = row_json(&r);
  km_cli_json_number(j, "landmark_only_err_mean_mm", 1e3 * lo_mean);
  km_cli_json_number(j, "landmark_only_err_max_mm", 1e3 * lo_max);
  char *js = cJSON_PrintUnformatted(j);
  cJSON_Delete(j);
  if (js) puts(js);
  free(js);
  rc = 0;
done:
  free(rig);
  free(V);
  km_transfer_free(&t);
  km_posedb_free(&db);
  km_mesh_free(&S);
  km_mesh_free(&T);
  km_mesh_free(&X);
  return rc;
}

int km_bench_transfer(int argc, char **argv) {
  size_t nv = 7000;
  bool json_only = false;
  const char *root = ".", *src = NULL, *tmpl = NULL, *lm_path = NULL, *truth = NULL, *dbp = NULL;
  const km_cli_opt opts[] = {
      {"source", 's', KM_OPT_STRING, &src, "avatar mesh S (with --template: one row for them)"},
      {"template", 't', KM_OPT_STRING, &tmpl, "template T whose pose S takes"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path, "LM.json (default: S's rig sidecar)"},
      {"truth", 0, KM_OPT_STRING, &truth, "S in T's pose, for the error in mm"},
      {"db", 0, KM_OPT_STRING, &dbp, "pose database for the recognition time"},
      {"vertices", 'n', KM_OPT_SIZE, &nv, "without --source: character size (default 7000)"},
      {"root", 0, KM_OPT_STRING, &root, "without --source: repository root (default .)"},
      {"json", 0, KM_OPT_FLAG, &json_only, "JSON only"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                   "kinemesh bench transfer [--source S --template T [--landmarks LM.json] "
                   "[--truth X] [--db DB]] [--json]",
                   "Table 2 of Lifkooee et al.: Laplacian and Cholesky (offline); recognition,\n"
                   "local frames and linear solve per iteration, iterations, total (online);\n"
                   "errors against the truth in mm. Without --source: generated subjects (A takes\n"
                   "B's pose, truth by LBS, recognition in a 10-class database of other subjects)\n"
                   "and FAUST when ../shared/data is present.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (src || tmpl) {
    if (!src || !tmpl) return km_cli_error("bench transfer", "--source and --template go together");
    return bench_pair(src, tmpl, lm_path, truth, dbp, json_only);
  }
  km_error e;
  row rows[24];
  int nrows = 0;

  /* Subjects: A is the avatar, B..D populate the pose database. */
  km_character c[4];
  km_posedb *db = NULL;
  km_posedb_report rep;
  if (generated_db(nv, c, &db, &rep, &e)) return die("pose database", &e);
  size_t n = c[0].mesh.n_vertices, ndb = rep.samples;
  int32_t ids[16];
  for (int l = 0; l < 16; ++l)
    ids[l] = c[0].landmarks[l].vertex;
  double *G = malloc(n * 3 * sizeof *G), *X = malloc(n * 3 * sizeof *X), P[48];
  /* 3, 4: the baseline the issue compares with, landmark-only Laplacian editing (no template:
   * frames from the avatar at rest), iterated or a single solve. */
  static const char *const vname[5] = {"default", "1 it", "paper's vertex enc.",
                                       "landmark-only, default", "landmark-only, 1 solve"};
  /* One untimed precompute first: the first one in a process pays for page faults and
   * CHOLMOD's first allocations (measured: Laplacian 11 vs 4 ms, Cholesky 16 vs 8 ms). */
  {
    km_transfer *warm = NULL;
    if (km_transfer_precompute(&c[0].mesh, ids, 16, NULL, &warm, &e)) return die("precompute", &e);
    km_transfer_free(&warm);
  }
  for (int variant = 0; variant < 5; ++variant) {
    km_transfer_options to = {0};
    if (variant == 1 || variant == 4) to.max_iterations = 1;
    if (variant == 2) to.encoding = KM_OFFSETS_VERTEX;
    km_transfer *t = NULL;
    if (km_transfer_precompute(&c[0].mesh, ids, 16, &to, &t, &e)) return die("precompute", &e);
    row *r = &rows[nrows++];
    memset(r, 0, sizeof *r);
    snprintf(r->name, sizeof r->name, "character %zu (%s)", n, vname[variant]);
    r->n_ver = n;
    km_transfer_precompute_ms(t, &r->laplacian_ms, &r->cholesky_ms);
    int correct = 0;
    for (int p = 0; p < KM_POSE_PRESETS; ++p) {
      if (km_character_pose_preset(&c[0], p, NULL, G, &e)) return die("pose", &e);
      for (int l = 0; l < 16; ++l)
        memcpy(P + 3 * l, G + 3 * (size_t)ids[l], 3 * sizeof(double));
      online o;
      if (run_online(t, variant < 3 ? db : NULL, P, NULL, c[0].mesh.V, X, &o, &e))
        return die("online", &e);
      km_pose_match m;
      km_posedb_query(db, P, &m, &e);
      correct += m.label == p;
      double mean, max;
      km_vertex_distance_stats(X, G, n, &mean, &max);
      r->recognition_ms += o.rec_ms / KM_POSE_PRESETS;
      r->frames_ms += o.frames_ms / KM_POSE_PRESETS;
      r->solve_ms += o.solve_ms / KM_POSE_PRESETS;
      r->iterations += (double)o.iterations / KM_POSE_PRESETS;
      r->online_ms += o.total_ms / KM_POSE_PRESETS;
      r->online_cpu_ms += o.total_cpu_ms / KM_POSE_PRESETS;
      r->err_mean_mm += mean * 1e3 / KM_POSE_PRESETS;
      r->err_max_mm = fmax(r->err_max_mm, max * 1e3);
      if (variant == 0) add_energy(r, t); /* summed over the poses */
    }
    if (variant >= 3) r->recognition_ms = NAN;
    if (!json_only && variant == 0)
      fprintf(stderr,
              "pose database: %zu templates, cv accuracy %.3f; avatar's poses recognised "
              "%d/%d\n",
              ndb, rep.cv_accuracy, correct, KM_POSE_PRESETS);
    km_transfer_free(&t);
  }
  km_posedb_free(&db);

  /* FAUST: same subject, pose 0 -> pose 1. */
  char p0[1024], p1[1024], pl[1024];
  snprintf(p0, sizeof p0, "%s/../shared/data/poses/tr_reg_000.off", root);
  snprintf(p1, sizeof p1, "%s/../shared/data/poses/tr_reg_001.off", root);
  snprintf(pl, sizeof pl, "%s/tests/data/smpl_landmarks.json", root);
  km_mesh s = {0}, tt = {0};
  if (km_mesh_read(p0, &s, &e) == KM_OK && km_mesh_read(p1, &tt, &e) == KM_OK) {
    km_landmark lm[KM_POSE_MAX_LANDMARKS];
    size_t nl;
    if (km_landmarks_read(pl, s.n_vertices, lm, KM_POSE_MAX_LANDMARKS, &nl, &e))
      return die("landmarks", &e);
    int32_t fid[KM_POSE_MAX_LANDMARKS];
    double FP[3 * KM_POSE_MAX_LANDMARKS];
    for (size_t l = 0; l < nl; ++l) {
      fid[l] = lm[l].vertex;
      memcpy(FP + 3 * l, tt.V + 3 * (size_t)fid[l], 3 * sizeof(double));
    }
    /* A small FAUST database for the recognition time: registrations by pose index. */
    const char *fdb[5] = {"tr_reg_000.off", "tr_reg_010.off", "tr_reg_001.off", "tr_reg_025.ply",
                          "tr_reg_095.ply"};
    const int32_t flab[5] = {0, 0, 1, 2, 2};
    km_mesh fm[5];
    memset(fm, 0, sizeof fm);
    km_posedb *fdbp = NULL;
    int nfm = 0;
    for (int i = 0; i < 5; ++i) {
      char fp[1100];
      snprintf(fp, sizeof fp, "%s/../shared/data/poses/%s", root, fdb[i]);
      if (km_mesh_read(fp, &fm[nfm], &e) == KM_OK) ++nfm;
    }
    km_posedb_options fo = {0};
    fo.cv_folds = 1;
    if (nfm == 5 &&
        km_posedb_build(fm, 5, flab, 3, NULL, NULL, lm, nl, &fo, &fdbp, NULL, &e) != KM_OK)
      return die("FAUST database", &e);
    for (int i = 0; i < nfm; ++i)
      km_mesh_free(&fm[i]);
    /* Both directions (000 -> 001 and 001 -> 000, each the other's truth), the SMPL landmark
     * file and 16 farthest-point landmarks (`--landmarks auto`); targets as the CLI takes them. */
    for (int pair = 0; pair < 4; ++pair) {
      const km_mesh *A = pair % 2 ? &tt : &s, *B = pair % 2 ? &s : &tt;
      int32_t pid[KM_POSE_MAX_LANDMARKS];
      size_t pl_n = nl;
      if (pair < 2) {
        memcpy(pid, fid, nl * sizeof *pid);
      } else {
        pl_n = 16;
        if (km_farthest_points(A, pl_n, pid, &e)) return die("FAUST landmarks", &e);
      }
      for (size_t l = 0; l < pl_n; ++l)
        memcpy(FP + 3 * l, B->V + 3 * (size_t)pid[l], 3 * sizeof(double));
      char nm[48];
      snprintf(nm, sizeof nm, "FAUST %s %s", pair % 2 ? "001->000" : "000->001",
               pair < 2 ? "SMPL lm" : "auto lm");
      for (int variant = 0; variant < 2; ++variant) {
        km_transfer_options to = {0};
        to.max_iterations = variant ? 1 : 0;
        km_transfer *t = NULL;
        if (km_transfer_precompute(A, pid, pl_n, &to, &t, &e)) return die("FAUST precompute", &e);
        double *FX = malloc(A->n_vertices * 3 * sizeof *FX);
        online o;
        /* The template is B; the small database (SMPL landmarks) times the recognition. */
        const km_posedb *qdb = pair < 2 ? fdbp : NULL;
        if (!FX || run_online(t, qdb, FP, B->V, NULL, FX, &o, &e)) return die("FAUST online", &e);
        fill_row(&rows[nrows++], nm, variant, t, &o, qdb != NULL, FX, B->V, A->n_vertices);
        free(FX);
        km_transfer_free(&t);
      }
    }
    km_posedb_free(&fdbp);
  }
  km_mesh_free(&s);
  km_mesh_free(&tt);

  /* A non-human avatar: the cat reference takes each of the nine poses cat-01..09 (same cat,
   * so the pose is the truth), 16 farthest-point landmarks as `transfer --landmarks auto` picks
   * them. One row per variant: errors and times averaged over the poses (max: the largest). */
  char c0[1024];
  snprintf(c0, sizeof c0, "%s/../shared/data/poses/cat-poses/cat-reference.obj", root);
  km_mesh ca = {0};
  if (km_mesh_read(c0, &ca, &e) == KM_OK) {
    int32_t cid[16];
    double CP[48];
    if (km_farthest_points(&ca, 16, cid, &e)) return die("cat landmarks", &e);
    double *CX = malloc(ca.n_vertices * 3 * sizeof *CX);
    if (!CX) return die("cat", &e);
    for (int variant = 0; variant < 2; ++variant) {
      km_transfer_options to = {0};
      to.max_iterations = variant ? 1 : 0;
      km_transfer *t = NULL;
      if (km_transfer_precompute(&ca, cid, 16, &to, &t, &e)) return die("cat precompute", &e);
      row acc;
      memset(&acc, 0, sizeof acc);
      int np = 0;
      for (int k = 1; k <= 9; ++k) {
        char ck[1100];
        snprintf(ck, sizeof ck, "%s/../shared/data/poses/cat-poses/cat-%02d.obj", root, k);
        km_mesh cb = {0};
        if (km_mesh_read(ck, &cb, &e) != KM_OK || cb.n_vertices != ca.n_vertices) {
          km_mesh_free(&cb);
          continue;
        }
        for (int l = 0; l < 16; ++l)
          memcpy(CP + 3 * l, cb.V + 3 * (size_t)cid[l], 3 * sizeof(double));
        online o;
        if (run_online(t, NULL, CP, cb.V, NULL, CX, &o, &e)) return die("cat online", &e);
        row r1;
        fill_row(&r1, "cat", variant, t, &o, false, CX, cb.V, ca.n_vertices);
        km_mesh_free(&cb);
        if (!np)
          acc = r1;
        else {
          acc.frames_ms += r1.frames_ms, acc.solve_ms += r1.solve_ms;
          acc.iterations += r1.iterations, acc.online_ms += r1.online_ms;
          acc.online_cpu_ms += r1.online_cpu_ms;
          acc.err_mean_mm += r1.err_mean_mm, acc.err_max_mm = fmax(acc.err_max_mm, r1.err_max_mm);
          for (int i = 0; i < r1.n_energy && i < 16; ++i)
            acc.energy[i] += r1.energy[i];
        }
        ++np;
      }
      if (np) {
        acc.frames_ms /= np, acc.solve_ms /= np, acc.iterations /= np, acc.online_ms /= np;
        acc.online_cpu_ms /= np;
        acc.err_mean_mm /= np;
        snprintf(acc.name, sizeof acc.name, "cat ref->%d poses (%s)", np,
                 variant ? "1 it" : "default");
        rows[nrows++] = acc;
      }
      km_transfer_free(&t);
    }
    free(CX);
  }
  km_mesh_free(&ca);

  if (!json_only) {
    char machine[320];
    km_bench_machine(machine, sizeof machine);
    printf("kinemesh bench transfer — %s; medians of %d runs\n", machine, ONLINE_REPS);
    printf("%-40s %6s %8s %8s %8s %8s %8s %5s %8s %8s %8s %8s\n", "mesh", "n_ver", "lapl_ms",
           "chol_ms", "recog_ms", "frame_ms", "solve_ms", "iters", "online", "cpu_ms", "err_mean",
           "err_max");
    for (int i = 0; i < nrows; ++i)
      print_row(&rows[i]);
    printf("(frames/solve: per iteration; online: recognition + all iterations, wall clock; "
           "cpu_ms: the same, this thread's CPU time; errors in mm; paper's Table 2: 2.1 / 3.9 / "
           "12.0 / 0.8 / 1.9 ms)\n");
  }
  printf("[\n");
  for (int i = 0; i < nrows; ++i) {
    cJSON *j = row_json(&rows[i]);
    char *js = cJSON_PrintUnformatted(j);
    cJSON_Delete(j);
    printf("  %s%s\n", js ? js : "null", i + 1 < nrows ? "," : "");
    free(js);
  }
  printf("]\n");
  for (int i = 0; i < 4; ++i)
    km_character_free(&c[i]);
  free(G);
  free(X);
  return 0;
}
