/* km_deform_check (the measures `bench motion` and `animate` report): edge length ratios,
 * folded triangles, one-frame steps, NaN frames, the JSON report, and km_rig_nearest_handle;
 * checked against frames whose answers are known by construction and against the tests' own
 * edge measure (km_test_edge_stretch) on a deformed character. */
#include "km_test.h"
#include "synth/synth.h" /* test fixtures: km_icosphere */

#include <cjson/cJSON.h>
#include <math.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* A flat unit square in the x-z plane, split along its diagonal 0-2 into two triangles,
 * normals +y. */
static const double k_square[] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
static const int32_t k_square_f[] = {0, 2, 1, 0, 3, 2};

static void test_known_frames(void) {
  km_mesh m = {.V = (double *)k_square, .F = (int32_t *)k_square_f, .n_vertices = 4, .n_faces = 2};
  km_deform_check *c = NULL;
  km_error err = {0};
  CHECK(km_deform_check_create(&m, &c, &err) == KM_OK);
  km_deform_frame fr;
  /* frame 0: the rest itself */
  CHECK(km_deform_check_add(c, k_square, &fr, &err) == KM_OK);
  CHECK(fr.stretch == 0 && fr.ratio_min == 1 && fr.ratio_max == 1);
  CHECK(fr.folded_pairs == 0 && fr.step == 0 && fr.step_vertex == -1);
  /* frame 1: x doubled: the x edges and the diagonal stretch; vertex 1 and 2 move 1 */
  double V[12];
  memcpy(V, k_square, sizeof V);
  for (int v = 0; v < 4; ++v)
    V[3 * v] *= 2;
  CHECK(km_deform_check_add(c, V, &fr, &err) == KM_OK);
  CHECK_MSG(fabs(fr.ratio_max - 2) < 1e-12, "longest %g", fr.ratio_max);
  CHECK(fabs(fr.stretch - 1) < 1e-12 && fr.ratio_min == 1);
  CHECK((fr.long_edge[0] == 0 && fr.long_edge[1] == 1) ||
        (fr.long_edge[0] == 2 && fr.long_edge[1] == 3));
  CHECK(fabs(fr.step - 1) < 1e-12 && (fr.step_vertex == 1 || fr.step_vertex == 2));
  CHECK(fr.folded_pairs == 0);
  /* frame 2: vertex 3 folded over the diagonal onto the other triangle (mirrored through the
   * diagonal: (0,0,1) -> (1,0,0) would be degenerate, so lift it a little) */
  memcpy(V, k_square, sizeof V);
  V[9] = 0.9, V[10] = 0.05, V[11] = 0.1;
  CHECK(km_deform_check_add(c, V, &fr, &err) == KM_OK);
  CHECK_MSG(fr.folded_pairs == 1, "folded pairs %zu", fr.folded_pairs);
  /* frame 3: a NaN vertex: the ratios are NaN, and the summary keeps the NaN */
  memcpy(V, k_square, sizeof V);
  V[0] = NAN;
  CHECK(km_deform_check_add(c, V, &fr, &err) == KM_OK);
  CHECK(isnan(fr.stretch));
  CHECK_MSG(isnan(fr.step) && fr.step_vertex == 0, "step %g at %d", fr.step, (int)fr.step_vertex);
  memcpy(V, k_square, sizeof V);
  CHECK(km_deform_check_add(c, V, NULL, &err) == KM_OK); /* a clean frame after it */
  km_deform_summary s;
  km_deform_check_summary(c, &s);
  CHECK(s.frames == 5);
  CHECK_MSG(isnan(s.stretch) && s.stretch_frame == 3, "stretch %g frame %zu", s.stretch,
            s.stretch_frame);
  CHECK(s.folded == 2 && s.most_folded_pairs == 1 && s.most_folded_frame == 2);
  CHECK(isnan(s.step) && s.step_frame == 3); /* the NaN step stays too */
  const int32_t *first = km_deform_check_first_fold(c);
  CHECK(first[0] == 2 && first[1] == 2);
  CHECK(s.long_frames == 1); /* frame 1 only: 2x; the NaN frame is no "over 1.5x" */
  CHECK(fabs(s.diagonal - sqrt(2)) < 1e-12);
  const km_deform_frame *all = NULL;
  CHECK(km_deform_check_frames(c, &all) == 5 && all && all[2].folded_pairs == 1);
  /* the JSON report: the summary's numbers, one entry per frame, null for the NaN */
  km_test_run("rm -rf dcheck_out", NULL);
  CHECK(km_deform_check_write_json(c, "dcheck_out/sub/r.json", &err) == KM_OK);
  size_t n = 0;
  char *text = km_test_read_file("dcheck_out/sub/r.json", &n);
  cJSON *j = text ? cJSON_Parse(text) : NULL;
  CHECK_MSG(j != NULL, "report not JSON: %s", text ? text : "(none)");
  if (j) {
    CHECK(
        !strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(j, "format")), "kinemesh-deform-report"));
    CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "frames")) == 5);
    CHECK(cJSON_IsNull(cJSON_GetObjectItem(j, "stretch_max")));
    CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "folded_triangles")) == 2);
    CHECK(cJSON_IsNull(cJSON_GetObjectItem(j, "edge_ratio_max"))); /* the NaN frame's */
    cJSON *pf = cJSON_GetObjectItem(j, "per_frame");
    CHECK(fabs(cJSON_GetNumberValue(
                   cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 1), "edge_ratio_max")) -
               2) < 1e-6);
    CHECK(cJSON_GetArraySize(pf) == 5);
    CHECK(cJSON_IsNull(cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 3), "stretch")));
    /* no handle targets were given: no forced fields */
    CHECK(!cJSON_GetObjectItem(j, "forced_edge_ratio_max") &&
          !cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 1), "forced_edge_ratio"));
    /* step 1 in a diagonal of sqrt 2 */
    CHECK(fabs(cJSON_GetNumberValue(cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 1), "step_pct")) -
               100 / sqrt(2)) < 1e-4);
    cJSON_Delete(j);
  }
  free(text);
  /* no temporary left beside it */
  CHECK(km_test_run("ls dcheck_out/sub | grep -c tmp", NULL) != 0);
  /* an unwritable path: an error naming it, nothing written */
  CHECK(km_deform_check_write_json(c, "/proc/no/such/r.json", &err) != KM_OK);
  CHECK_MSG(strstr(err.message, "/proc/no/such") != NULL, "%s", err.message);
  km_deform_check_free(&c);
  CHECK(c == NULL);
  km_deform_check_free(&c); /* twice is fine */
  /* bad input: NULLs are errors, not crashes; no faces is an error naming the function */
  CHECK(km_deform_check_create(&m, NULL, &err) == KM_ERR_INVALID);
  km_mesh bad = m;
  int32_t F_bad[] = {0, 1, 7};
  bad.F = F_bad, bad.n_faces = 1;
  CHECK(km_deform_check_create(&bad, &c, &err) != KM_OK && c == NULL);
  CHECK_MSG(strstr(err.message, "km_deform_check_create") != NULL, "%s", err.message);
  km_test_run("rm -rf dcheck_out", NULL);
}

/* On a character bent by the puppetry pipeline, the check's stretch per frame is the tests' own
 * edge measure, and the summary is the largest of the frames. */
static void test_against_edge_measure(void) {
  km_character c = {0};
  km_error err = {0};
  km_character_options co = {0};
  co.target_vertices = 3000;
  if (km_character_generate(&co, &c, &err) != KM_OK) {
    CHECK_MSG(0, "character: %s", err.message);
    return;
  }
  const km_mesh *m = &c.mesh;
  km_deform_check *dc = NULL;
  CHECK(km_deform_check_create(m, &dc, &err) == KM_OK);
  double *V = malloc(3 * m->n_vertices * sizeof *V);
  double worst = 0;
  for (int f = 0; f < 6 && V; ++f) {
    /* a shear growing with the frame, and a bulge: every edge changes a different amount */
    for (size_t v = 0; v < m->n_vertices; ++v) {
      const double *p = m->V + 3 * v;
      V[3 * v] = p[0] * (1 + 0.1 * f * p[1]);
      V[3 * v + 1] = p[1] + 0.05 * f * p[0] * p[0];
      V[3 * v + 2] = p[2] * (1 + 0.2 * f);
    }
    km_deform_frame fr;
    CHECK(km_deform_check_add(dc, V, &fr, &err) == KM_OK);
    double ref = km_test_edge_stretch(m, V);
    CHECK_MSG(fabs(fr.stretch - ref) < 1e-9, "frame %d: %g vs %g", f, fr.stretch, ref);
    worst = fmax(worst, ref);
  }
  km_deform_summary s;
  km_deform_check_summary(dc, &s);
  CHECK(fabs(s.stretch - worst) < 1e-9 && s.stretch_frame == 5 && worst > 0.1);
  km_deform_check_free(&dc);
  free(V);
  km_character_free(&c);
}

/* km_rig_nearest_handle: the handle with the nearest vertex; -1 without handles. */
static void test_nearest_handle(void) {
  km_mesh m = {.V = (double *)k_square, .F = (int32_t *)k_square_f, .n_vertices = 4, .n_faces = 2};
  int32_t a[] = {0}, b[] = {2, 3};
  km_rig_handle h[2] = {{.name = "a", .vertices = a, .n_vertices = 1},
                        {.name = "b", .vertices = b, .n_vertices = 2}};
  km_rig rig = {.handles = h, .n_handles = 2};
  double near_a[3] = {0.1, 0, 0.2}, near_b[3] = {0.4, 0, 0.9}, far[3] = {5, 5, 5};
  CHECK(km_rig_nearest_handle(&rig, &m, near_a) == 0);
  CHECK(km_rig_nearest_handle(&rig, &m, near_b) == 1);
  CHECK(km_rig_nearest_handle(&rig, &m, far) == 1); /* (1,0,1) is b's */
  km_rig none = {0};
  CHECK(km_rig_nearest_handle(&none, &m, near_a) == -1);
}

/* km_stretch_bound: the longest edge l / l0 that vertex sets held at targets force. On a strip
 * along x (a grid of 41 x 3 vertices, 2 by 0.2) with a set at each end: at rest a pair along a
 * row is as far apart as its path, so the bound is 1; with x doubled it is 2; and for any
 * deformation, its targets' bound is at most that deformation's longest edge (the bound's
 * promise: with the sets met, no mesh does better). */
static void test_stretch_bound(void) {
  enum { NX = 41, NZ = 3 };
  double V0[NX * NZ * 3], V[NX * NZ * 3];
  int32_t F[(NX - 1) * (NZ - 1) * 6], sets[NX * NZ], off[3];
  for (int i = 0; i < NX; ++i)
    for (int k = 0; k < NZ; ++k) {
      double *p = V0 + 3 * (i * NZ + k);
      p[0] = 2.0 * i / (NX - 1), p[1] = 0, p[2] = 0.1 * k;
    }
  size_t nf = 0;
  for (int i = 0; i + 1 < NX; ++i)
    for (int k = 0; k + 1 < NZ; ++k) {
      int32_t a = i * NZ + k, b = (i + 1) * NZ + k, c = (i + 1) * NZ + k + 1, d = i * NZ + k + 1;
      int32_t t[6] = {a, c, b, a, d, c};
      memcpy(F + 6 * nf / 2, t, sizeof t);
      nf += 2;
    }
  km_mesh m = {.V = V0, .F = F, .n_vertices = NX * NZ, .n_faces = nf};
  size_t n = 0; /* set 0: x <= 0.3, set 1: x >= 1.7 */
  off[0] = 0;
  for (int v = 0; v < NX * NZ; ++v)
    if (V0[3 * v] <= 0.3 + 1e-9) sets[n++] = v;
  off[1] = (int32_t)n;
  for (int v = 0; v < NX * NZ; ++v)
    if (V0[3 * v] >= 1.7 - 1e-9) sets[n++] = v;
  off[2] = (int32_t)n;
  km_stretch_bound_options o = {.radius = 1.0};
  km_stretch_bound *b = NULL;
  km_error err = {0};
  CHECK_OK(km_stretch_bound_create(&m, 2, off, sets, &o, &b, KM_E));
  CHECK_MSG(km_stretch_bound_pairs(b) > 0, "no pairs");
  double T[NX * NZ * 3];
  int32_t pr[2];
  for (size_t i = 0; i < n; ++i)
    memcpy(T + 3 * i, V0 + 3 * (size_t)sets[i], 3 * sizeof(double));
  double at_rest = km_stretch_bound_eval(b, T, pr);
  CHECK_MSG(fabs(at_rest - 1) < 1e-9, "at rest: %.12f", at_rest);
  /* the pair's mesh ids: one vertex of each set */
  CHECK_MSG(pr[0] >= 0 && pr[1] >= 0 && V0[3 * (size_t)pr[0]] <= 0.3 + 1e-9 &&
                V0[3 * (size_t)pr[1]] >= 1.7 - 1e-9,
            "pair %d %d", (int)pr[0], (int)pr[1]);
  for (size_t i = 0; i < n; ++i)
    T[3 * i] *= 2;
  double doubled = km_stretch_bound_eval(b, T, NULL);
  CHECK_MSG(fabs(doubled - 2) < 1e-9, "x doubled: %.12f", doubled);
  /* deformations: a bend of the right half up about x = 1, and a wave; each one's longest edge
   * is at least its targets' bound */
  for (int d = 0; d < 2; ++d) {
    for (int v = 0; v < NX * NZ; ++v) {
      const double *p = V0 + 3 * v;
      double *q = V + 3 * v;
      if (d == 0) {
        double a = p[0] > 1 ? 1.2 * (p[0] - 1) : 0; /* up to 72 degrees at the far end */
        q[0] = p[0] > 1 ? 1 + sin(a) / 1.2 : p[0], q[1] = p[0] > 1 ? (1 - cos(a)) / 1.2 : 0;
        q[0] += 0.1 * p[0] * p[0], q[2] = p[2];
      } else {
        q[0] = p[0] + 0.2 * sin(3 * p[0]), q[1] = 0.3 * sin(5 * p[0]) * p[2], q[2] = p[2];
      }
    }
    for (size_t i = 0; i < n; ++i)
      memcpy(T + 3 * i, V + 3 * (size_t)sets[i], 3 * sizeof(double));
    km_deform_check *dc = NULL;
    CHECK_OK(km_deform_check_create(&m, &dc, KM_E));
    km_deform_frame fr = {0};
    CHECK_OK(km_deform_check_add(dc, V, &fr, KM_E));
    double bound = km_stretch_bound_eval(b, T, NULL);
    printf("stretch bound, deformation %d: %.4f <= longest edge %.4f\n", d, bound, fr.ratio_max);
    CHECK_MSG((d || bound > 1.1) && bound <= fr.ratio_max + 1e-12,
              "deformation %d: bound %.6f, longest %.6f", d, bound, fr.ratio_max);
    km_deform_check_free(&dc);
  }
  /* the deform check keeps each frame's bound (km_deform_check_set_forced): summary and report */
  km_deform_check *dc = NULL;
  CHECK_OK(km_deform_check_create(&m, &dc, KM_E));
  km_deform_check_set_forced(dc, 5, NULL); /* before any frame: nothing */
  for (int k = 0; k < 3; ++k) {
    for (int v = 0; v < NX * NZ; ++v)
      for (int c = 0; c < 3; ++c)
        V[3 * v + c] = V0[3 * v + c] * (c == 0 && k == 1 ? 2 : 1);
    for (size_t i = 0; i < n; ++i)
      memcpy(T + 3 * i, V + 3 * (size_t)sets[i], 3 * sizeof(double));
    CHECK_OK(km_deform_check_add(dc, V, NULL, KM_E));
    double fb = km_stretch_bound_eval(b, T, pr);
    if (k < 2) km_deform_check_set_forced(dc, fb, pr); /* frame 2: not given */
  }
  km_deform_summary sum;
  km_deform_check_summary(dc, &sum);
  CHECK_MSG(fabs(sum.forced - 2) < 1e-9 && sum.forced_frame == 1 && sum.forced_pair[0] >= 0 &&
                V0[3 * (size_t)sum.forced_pair[1]] >= 1.7 - 1e-9,
            "summary forced %g frame %zu pair %d %d", sum.forced, sum.forced_frame,
            (int)sum.forced_pair[0], (int)sum.forced_pair[1]);
  km_test_run("rm -rf dcheck_forced", NULL);
  CHECK_OK(km_deform_check_write_json(dc, "dcheck_forced/r.json", KM_E));
  size_t tn = 0;
  char *text = km_test_read_file("dcheck_forced/r.json", &tn);
  cJSON *j = text ? cJSON_Parse(text) : NULL, *pf = j ? cJSON_GetObjectItem(j, "per_frame") : NULL;
  CHECK_MSG(
      j && fabs(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "forced_edge_ratio_max")) - 2) < 1e-6 &&
          cJSON_GetNumberValue(cJSON_GetObjectItem(j, "forced_frame")) == 1 &&
          fabs(cJSON_GetNumberValue(
                   cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 0), "forced_edge_ratio")) -
               1) < 1e-6 &&
          cJSON_IsNull(cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 2), "forced_edge_ratio")),
      "report: %s", text ? text : "(none)");
  cJSON_Delete(j);
  free(text);
  km_test_run("rm -rf dcheck_forced", NULL);
  km_deform_check_free(&dc);
  /* the pairs cached in a file (options.cache_path): written on the first create, read on the
   * next (a doctored rest length there shows it was read, not recomputed), recomputed when the
   * sets change or the file is damaged */
  km_test_run("rm -rf dcheck_bound", NULL);
  km_stretch_bound_options oc = o;
  oc.cache_path = "dcheck_bound/x.bound";
  km_stretch_bound *c1 = NULL, *c2 = NULL, *c3 = NULL, *c4 = NULL;
  CHECK_OK(km_stretch_bound_create(&m, 2, off, sets, &oc, &c1, KM_E));
  for (size_t i = 0; i < n; ++i) /* targets: x doubled */
    memcpy(T + 3 * i, V0 + 3 * (size_t)sets[i], 3 * sizeof(double)), T[3 * i] *= 2;
  double x2 = km_stretch_bound_eval(b, T, NULL);
  CHECK_MSG(c1 && km_stretch_bound_pairs(c1) == km_stretch_bound_pairs(b) &&
                km_stretch_bound_eval(c1, T, NULL) == x2,
            "written: %zu pairs", km_stretch_bound_pairs(c1));
  size_t fn = 0;
  char *bytes = km_test_read_file("dcheck_bound/x.bound", &fn);
  size_t np = km_stretch_bound_pairs(b);
  CHECK(bytes && fn == 28 + 24 * np);
  if (bytes && fn == 28 + 24 * np) { /* every rest length halved: the bound read doubles */
    for (size_t p = 0; p < np; ++p) {
      double d;
      memcpy(&d, bytes + 28 + 16 * np + 8 * p, sizeof d);
      d /= 2;
      memcpy(bytes + 28 + 16 * np + 8 * p, &d, sizeof d);
    }
    FILE *bf = fopen("dcheck_bound/x.bound", "wb");
    CHECK(bf && fwrite(bytes, 1, fn, bf) == fn);
    if (bf) fclose(bf);
    CHECK_OK(km_stretch_bound_create(&m, 2, off, sets, &oc, &c2, KM_E));
    CHECK_MSG(c2 && fabs(km_stretch_bound_eval(c2, T, NULL) - 2 * x2) < 1e-9,
              "read back: %g, computed %g", km_stretch_bound_eval(c2, T, NULL), x2);
    FILE *tf = fopen("dcheck_bound/x.bound", "wb"); /* damaged: cut short */
    CHECK(tf && fwrite(bytes, 1, fn / 2, tf) == fn / 2);
    if (tf) fclose(tf);
    CHECK_OK(km_stretch_bound_create(&m, 2, off, sets, &oc, &c3, KM_E));
    CHECK_MSG(c3 && km_stretch_bound_eval(c3, T, NULL) == x2, "after damage: %g",
              km_stretch_bound_eval(c3, T, NULL));
    int32_t off1[3] = {off[0], off[1] - 1, off[2]}; /* other sets: another key */
    int32_t *sets1 = malloc(sizeof(int32_t) * (size_t)off[2]);
    if (sets1) {
      memcpy(sets1, sets, sizeof(int32_t) * (size_t)off[1] - sizeof(int32_t));
      memcpy(sets1 + off1[1], sets + off[1], sizeof(int32_t) * (size_t)(off[2] - off[1]));
      off1[2] = off1[1] + (off[2] - off[1]);
      CHECK_OK(km_stretch_bound_create(&m, 2, off1, sets1, &oc, &c4, KM_E));
      km_stretch_bound *c5 = NULL;
      CHECK_OK(km_stretch_bound_create(&m, 2, off1, sets1, &o, &c5, KM_E));
      CHECK(c4 && c5 && km_stretch_bound_pairs(c4) == km_stretch_bound_pairs(c5));
      km_stretch_bound_free(&c5);
      free(sets1);
    }
  }
  free(bytes);
  km_stretch_bound_free(&c1), km_stretch_bound_free(&c2), km_stretch_bound_free(&c3);
  km_stretch_bound_free(&c4);
  km_test_run("rm -rf dcheck_bound", NULL);
  km_stretch_bound_free(&b);
  CHECK(b == NULL);
  sets[0] = NX * NZ; /* out of range */
  CHECK(km_stretch_bound_create(&m, 2, off, sets, NULL, &b, &err) == KM_ERR_INVALID && !b);
  CHECK_MSG(strstr(err.message, "out of range") != NULL, "%s", err.message);
}

/* The square split along its diagonal as a glTF exporter splits a mesh at a texture seam: the
 * second triangle uses copies 4 and 5 of vertices 0 and 2. Folding it over the diagonal is a
 * fold across the seam, which the check finds as it does on the whole square (before, the two
 * triangles shared no edge and the fold went unseen); the copies' edges are measured too. */
static void test_seam_fold(void) {
  const double V0[] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 1};
  const int32_t F[] = {0, 2, 1, 4, 3, 5};
  km_mesh m = {.V = (double *)V0, .F = (int32_t *)F, .n_vertices = 6, .n_faces = 2};
  km_deform_check *c = NULL;
  CHECK_OK(km_deform_check_create(&m, &c, KM_E));
  if (!c) return;
  km_deform_frame fr;
  double V[18];
  memcpy(V, V0, sizeof V);
  V[9] = 0.9, V[10] = 0.05, V[11] = 0.1; /* vertex 3 over the diagonal, as test_known_frames */
  CHECK_OK(km_deform_check_add(c, V, &fr, KM_E));
  CHECK_MSG(fr.folded_pairs == 1, "folded pairs across the seam %zu", fr.folded_pairs);
  memcpy(V, V0, sizeof V);
  V[15] = 2; /* copy 5 of vertex 2 pulled out along x: the edges 3-5 and 4-5 stretch */
  CHECK_OK(km_deform_check_add(c, V, &fr, KM_E));
  CHECK_MSG(fr.ratio_max > 1.3 && (fr.long_edge[0] == 5 || fr.long_edge[1] == 5),
            "longest %g at %d-%d", fr.ratio_max, (int)fr.long_edge[0], (int)fr.long_edge[1]);
  km_deform_check_free(&c);
}

/* The bound over a mesh large enough for its Dijkstra runs to share the cores: the same pairs,
 * in the same order, whatever the number of threads (an icosphere of 10242 vertices, four caps
 * held, each turned by its own small rotation). */
static void test_stretch_bound_threads(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(5, 1.0, &m, KM_E));
  if (!m.V) return;
  const double c[4][3] = {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, 0, 1}};
  int32_t off[5] = {0}, *sets = malloc(m.n_vertices * sizeof *sets);
  size_t k = 0;
  for (int h = 0; sets && h < 4; ++h) {
    for (size_t v = 0; v < m.n_vertices; ++v) {
      const double *x = m.V + 3 * v;
      double d2 = (x[0] - c[h][0]) * (x[0] - c[h][0]) + (x[1] - c[h][1]) * (x[1] - c[h][1]) +
                  (x[2] - c[h][2]) * (x[2] - c[h][2]);
      if (d2 < 0.3) sets[k++] = (int32_t)v;
    }
    off[h + 1] = (int32_t)k;
  }
  double *T = malloc(k * 3 * sizeof *T);
  for (size_t i = 0; T && i < k; ++i) { /* each cap turned about z by its own angle */
    int h = 0;
    while (h < 3 && (int32_t)i >= off[h + 1])
      ++h;
    const double *x = m.V + 3 * (size_t)sets[i];
    double a = 0.3 * (h + 1), ca = cos(a), sa = sin(a);
    T[3 * i] = ca * x[0] - sa * x[1], T[3 * i + 1] = sa * x[0] + ca * x[1], T[3 * i + 2] = x[2];
  }
  km_stretch_bound_options o = {.radius = 0.5};
  km_stretch_bound *b1 = NULL, *b2 = NULL;
  double f1 = NAN, f2 = NAN;
  int32_t p1[2] = {-1, -1}, p2[2] = {-2, -2};
#ifdef _OPENMP
  int was = omp_get_max_threads();
  omp_set_num_threads(1);
#endif
  if (sets && T) CHECK_OK(km_stretch_bound_create(&m, 4, off, sets, &o, &b1, KM_E));
#ifdef _OPENMP
  omp_set_num_threads(2);
#endif
  if (sets && T) CHECK_OK(km_stretch_bound_create(&m, 4, off, sets, &o, &b2, KM_E));
#ifdef _OPENMP
  omp_set_num_threads(was);
#endif
  if (b1 && b2) {
    f1 = km_stretch_bound_eval(b1, T, p1);
    f2 = km_stretch_bound_eval(b2, T, p2);
  }
  printf("stretch bound on %zu vertices, 1 and 2 threads: %zu and %zu pairs, %.6f and %.6f\n",
         m.n_vertices, km_stretch_bound_pairs(b1), km_stretch_bound_pairs(b2), f1, f2);
  CHECK_MSG(km_stretch_bound_pairs(b1) > 0 &&
                km_stretch_bound_pairs(b1) == km_stretch_bound_pairs(b2) && f1 > 1 && f1 == f2 &&
                p1[0] == p2[0] && p1[1] == p2[1],
            "threads changed the bound: %g (%d-%d) vs %g (%d-%d)", f1, (int)p1[0], (int)p1[1], f2,
            (int)p2[0], (int)p2[1]);
  km_stretch_bound_free(&b1);
  km_stretch_bound_free(&b2);
  free(sets);
  free(T);
  km_mesh_free(&m);
}

int main(void) {
  test_stretch_bound_threads();
  test_known_frames();
  test_seam_fold();
  test_against_edge_measure();
  test_nearest_handle();
  test_stretch_bound();
  return km_test_finish("test_deform_check");
}
