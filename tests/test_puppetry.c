/* The puppetry pipeline (km_puppetry) and the one motion reader (km_motion_read): rest joints
 * reproduce the rest mesh, the pipeline matches the hand-written filter -> retarget -> solve
 * loop bit for bit (reduced and full), Kinect columns are matched by name, the cache policy
 * (built, loaded, stale, forced), run-time rig swaps, and every motion format. */
#include "km_test.h"

#include <stdint.h>
#include <unistd.h>

static char g_dir[] = "/tmp/km_test_puppetry_XXXXXX";

static double max_abs_diff(const double *a, const double *b, size_t n) {
  double m = 0;
  for (size_t i = 0; i < n; ++i) {
    double d = fabs(a[i] - b[i]);
    if (!(d <= m)) m = d; /* NaN counts as a difference */
  }
  return m;
}

typedef struct fixture {
  km_character c;
  km_rig rig;
  km_take take; /* KM_KINECT1 order */
  char rig_path[256];
} fixture;

static bool fixture_make(fixture *fx) {
  memset(fx, 0, sizeof *fx);
  km_character_options co = {0};
  co.target_vertices = 2000;
  bool ok = true;
  CHECK_OK(km_character_generate(&co, &fx->c, KM_E));
  snprintf(fx->rig_path, sizeof fx->rig_path, "%s/c.rig.json", g_dir);
  CHECK_OK(km_character_write_rig(fx->rig_path, &fx->c, KM_E));
  CHECK_OK(km_rig_read(fx->rig_path, &fx->c.mesh, NULL, 0, &fx->rig, KM_E));
  CHECK_OK(km_motion_generate(&fx->c.skeleton, KM_MOTION_WAVE, 24, &fx->take, KM_E));
  ok = fx->rig.n_handles > 0 && fx->take.n_joints == KM_KINECT1_JOINTS && fx->take.n_frames == 24;
  CHECK(ok);
  return ok;
}

static void fixture_free(fixture *fx) {
  km_take_free(&fx->take);
  km_rig_free(&fx->rig);
  km_character_free(&fx->c);
}

/* Pushing the rest joints keeps every handle at its rest centroid: the rest mesh comes back. */
static void test_rest_reproduces_rest(const fixture *fx) {
  km_puppetry *p = NULL;
  km_puppetry_info info;
  CHECK_OK(
      km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, KM_KINECT1_JOINTS, NULL, &p, &info, KM_E));
  if (!p) return;
  CHECK(info.model == KM_PUPPETRY_MODEL_BUILT);
  size_t nv = fx->c.mesh.n_vertices, nh = 0;
  km_puppetry_handles(p, &nh, NULL, NULL);
  CHECK(nh == fx->rig.n_handles);
  /* before any push the handle targets are the rest centroids */
  CHECK(max_abs_diff(km_puppetry_handle_targets(p), km_puppetry_rest_centroids(p), 3 * nh) == 0);
  CHECK(km_puppetry_last_joints(p) == NULL);
  double *V = malloc(sizeof(double) * 3 * nv);
  double diag = km_bbox_diagonal(fx->c.mesh.V, nv);
  for (int f = 0; f < 5; ++f)
    CHECK_OK(km_puppetry_push(p, fx->c.skeleton.rest, V, KM_E));
  CHECK_MSG(max_abs_diff(V, fx->c.mesh.V, 3 * nv) < 1e-6 * diag, "dev %g",
            max_abs_diff(V, fx->c.mesh.V, 3 * nv));
  CHECK(max_abs_diff(km_puppetry_handle_targets(p), km_puppetry_rest_centroids(p), 3 * nh) <
        1e-12 * diag);
  CHECK(km_puppetry_last_joints(p) != NULL);
  CHECK(max_abs_diff(km_puppetry_reference_joints(p), fx->c.skeleton.rest, 3 * 20) < 1e-12);
  /* the character's own joints, posed: at rest where they are; in a waving frame the limbs
   * turn with their bone lengths kept, and the raised wrist leaves its rest place */
  double J[60];
  CHECK(km_puppetry_posed_joints(p, J));
  CHECK_MSG(max_abs_diff(J, fx->c.skeleton.rest, 60) < 1e-9 * diag, "posed rest joints off %g",
            max_abs_diff(J, fx->c.skeleton.rest, 60));
  size_t wf = fx->take.n_frames - 1;
  for (int f = 0; f < 30; ++f) /* let the filter settle on the frame */
    CHECK_OK(km_puppetry_push(p, fx->take.positions + wf * 60, V, KM_E));
  CHECK(km_puppetry_posed_joints(p, J));
  const double *R0 = fx->c.skeleton.rest;
  double worst = 0, moved = 0;
  for (size_t j = 1; j < 20; ++j) {
    size_t q = (size_t)fx->c.skeleton.parents[j];
    double l = 0, l0 = 0;
    for (int a = 0; a < 3; ++a) {
      l += (J[3 * j + a] - J[3 * q + a]) * (J[3 * j + a] - J[3 * q + a]);
      l0 += (R0[3 * j + a] - R0[3 * q + a]) * (R0[3 * j + a] - R0[3 * q + a]);
    }
    worst = fmax(worst, fabs(sqrt(l) - sqrt(l0)));
  }
  for (size_t j = 0; j < 20; ++j)
    moved = fmax(moved, sqrt((J[3 * j] - R0[3 * j]) * (J[3 * j] - R0[3 * j]) +
                             (J[3 * j + 1] - R0[3 * j + 1]) * (J[3 * j + 1] - R0[3 * j + 1]) +
                             (J[3 * j + 2] - R0[3 * j + 2]) * (J[3 * j + 2] - R0[3 * j + 2])));
  CHECK_MSG(worst < 1e-9 * diag && moved > 0.05 * diag,
            "posed joints: bone lengths off by %g, largest move %g (diagonal %g)", worst, moved,
            diag);
  km_puppetry_times t;
  km_puppetry_times_get(p, &t);
  CHECK(t.filter_ms >= 0 && t.retarget_ms >= 0 && t.solve_ms > 0);
  km_puppet_info pi;
  km_puppetry_puppet_info(p, &pi);
  CHECK(pi.vertices == nv && pi.handles == nh);
  km_puppetry_reset(p);
  CHECK(km_puppetry_last_joints(p) == NULL);
  CHECK(isnan(km_puppetry_reference_joints(p)[0]));
  free(V);
  km_puppetry_free(&p);
  CHECK(p == NULL);
  km_puppetry_free(&p); /* NULL-safe */
}

/* A rig without the character's skeleton (no "joints": one translation-only handle, as a
 * user writes by hand) has no posed joints to give. */
static void test_no_posed_joints(const fixture *fx) {
  char path[300];
  snprintf(path, sizeof path, "%s/plain.rig.json", g_dir);
  FILE *f = fopen(path, "w");
  CHECK(f != NULL);
  if (!f) return;
  fprintf(f, "{\"format\":\"kinemesh-rig\",\"version\":1,\"handles\":[{\"name\":\"hand\","
             "\"vertex\":0,\"radius\":0.1}],\"map\":[{\"handle\":\"hand\",\"joint\":"
             "\"HandLeft\"}]}\n");
  fclose(f);
  km_rig rig = {0};
  CHECK_OK(km_rig_read(path, &fx->c.mesh, NULL, 0, &rig, KM_E));
  km_puppetry *p = NULL;
  if (rig.n_handles)
    CHECK_OK(km_puppetry_create(&fx->c.mesh, &rig, NULL, KM_KINECT1_JOINTS, NULL, &p, NULL, KM_E));
  if (p) {
    double J[60] = {0}, *V = malloc(sizeof(double) * 3 * fx->c.mesh.n_vertices);
    CHECK_OK(km_puppetry_push(p, fx->c.skeleton.rest, V, KM_E));
    CHECK(!km_puppetry_posed_joints(p, J) && J[0] == 0);
    free(V);
  }
  km_puppetry_free(&p);
  km_rig_free(&rig);
}

/* The hand-written loop every front end used to carry. */
static void manual_loop(const fixture *fx, bool full, double *Vs) {
  size_t nv = fx->c.mesh.n_vertices, nh = fx->rig.n_handles, n_hv = 0;
  for (size_t h = 0; h < nh; ++h)
    n_hv += fx->rig.handles[h].n_vertices;
  int32_t *off = malloc(sizeof(int32_t) * (nh + 1)), *hv = malloc(sizeof(int32_t) * n_hv);
  off[0] = 0;
  for (size_t h = 0, k = 0; h < nh; ++h) {
    for (size_t i = 0; i < fx->rig.handles[h].n_vertices; ++i)
      hv[k++] = fx->rig.handles[h].vertices[i];
    off[h + 1] = (int32_t)k;
  }
  km_filter *f = NULL;
  km_retarget *rt = NULL;
  km_puppet *pup = NULL;
  km_arap *arap = NULL;
  CHECK_OK(km_filter_create(20, &fx->rig.filter, &f, KM_E));
  CHECK_OK(km_retarget_create(&fx->rig, &fx->c.mesh, 20, NULL, &rt, KM_E));
  if (full) {
    CHECK_OK(km_arap_precompute(&fx->c.mesh, nh, off, hv, NULL, &arap, KM_E));
  } else {
    CHECK_OK(km_puppet_precompute(&fx->c.mesh, NULL, &pup, KM_E));
    CHECK_OK(km_puppet_set_handles(pup, nh, off, hv, KM_E));
  }
  double filt[60], *targets = malloc(sizeof(double) * 3 * n_hv);
  for (size_t fr = 0; fr < fx->take.n_frames; ++fr) {
    km_filter_push(f, fx->take.positions + fr * 60, filt);
    km_retarget_push(rt, filt, NULL);
    km_retarget_vertex_targets(rt, targets);
    if (full)
      CHECK_OK(km_arap_solve(arap, targets, Vs + fr * 3 * nv, KM_E));
    else
      CHECK_OK(km_puppet_solve(pup, targets, Vs + fr * 3 * nv, KM_E));
    km_retarget_apply_root(rt, Vs + fr * 3 * nv, nv); /* rigid root motion */
    double fy;                                        /* the floor: no vertex under it */
    if (km_retarget_floor(rt, &fy))
      for (size_t v = 0; v < nv; ++v)
        Vs[fr * 3 * nv + 3 * v + 1] = fmax(Vs[fr * 3 * nv + 3 * v + 1], fy);
  }
  free(targets);
  free(off);
  free(hv);
  km_filter_free(&f);
  km_retarget_free(&rt);
  km_puppet_free(&pup);
  km_arap_free(&arap);
}

static void run_pipeline(const fixture *fx, km_puppetry *p, const km_take *t, double *Vs) {
  size_t nv = fx->c.mesh.n_vertices;
  for (size_t fr = 0; fr < t->n_frames; ++fr)
    CHECK_OK(km_puppetry_push(p, t->positions + fr * t->n_joints * 3, Vs + fr * 3 * nv, KM_E));
}

static void test_same_as_manual_loop(const fixture *fx) {
  size_t nv = fx->c.mesh.n_vertices, nf = fx->take.n_frames;
  double *A = malloc(sizeof(double) * 3 * nv * nf), *B = malloc(sizeof(double) * 3 * nv * nf);
  for (int full = 0; full < 2; ++full) {
    manual_loop(fx, full, A);
    km_puppetry_options o = {0};
    o.solver = full ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED;
    km_puppetry *p = NULL;
    km_puppetry_info info;
    CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &p, &info, KM_E));
    if (!p) continue;
    CHECK(info.model == (full ? KM_PUPPETRY_MODEL_FULL : KM_PUPPETRY_MODEL_BUILT));
    run_pipeline(fx, p, &fx->take, B);
    CHECK_MSG(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0, "%s: max diff %g",
              full ? "full" : "reduced", max_abs_diff(A, B, 3 * nv * nf));
    km_puppetry_free(&p);
  }

  /* Columns in another order, with extra and missing-but-unmapped ones, matched by name. */
  km_take sh = {0};
  sh.n_frames = nf;
  sh.n_joints = 22;
  sh.fps = fx->take.fps;
  char *names[22];
  char extra1[] = "Tail", extra2[] = "HandTipLeft";
  sh.positions = malloc(sizeof(double) * 3 * 22 * nf);
  for (int k = 0; k < 22; ++k) {
    int j = 21 - k; /* reversed; k = 0 and 1 are the extras */
    names[k] = k == 0 ? extra1 : k == 1 ? extra2 : (char *)km_kinect1_joint_name(j);
    for (size_t fr = 0; fr < nf; ++fr)
      for (int a = 0; a < 3; ++a)
        sh.positions[(fr * 22 + (size_t)k) * 3 + a] =
            k < 2 ? 1e9 : fx->take.positions[(fr * 20 + (size_t)j) * 3 + a];
  }
  km_puppetry *p = NULL;
  km_puppetry_options o = {0};
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, (const char *const *)names, 22, &o, &p, NULL,
                              KM_E));
  if (p) {
    manual_loop(fx, false, A);
    run_pipeline(fx, p, &sh, B);
    CHECK(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0);
    km_puppetry_free(&p);
  }
  /* A mapped joint the take lacks is an error naming the take and the joint. */
  names[14] = extra1; /* was HandLeft (j = 7), which the character's rig maps */
  bool maps_hand = false;
  for (size_t m = 0; m < fx->rig.n_maps; ++m)
    maps_hand |= fx->rig.maps[m].joint == 7;
  CHECK(maps_hand);
  o.take_name = "wave.bvh";
  km_status s =
      km_puppetry_create(&fx->c.mesh, &fx->rig, (const char *const *)names, 22, &o, &p, NULL, KM_E);
  CHECK(s == KM_ERR_INVALID && p == NULL);
  CHECK_MSG(strstr(km_test_err.message,
                   "wave.bvh has no joint named HandLeft, which the kinect1 "
                   "rig maps (its joints: Tail, HandTipLeft, FootRight") != NULL,
            "%s", km_test_err.message);
  km_puppetry_free(&p);
  free(sh.positions);
  free(A);
  free(B);
}

/* KM_PUPPETRY_RETARGET (pose --retarget): the pipeline without its mesh solve poses the
 * character's skeleton exactly as the reduced pipeline does from the same frames (the joints
 * are the retargeter's, before any solve), with the same handle targets; it builds no model,
 * takes V_out NULL, and refuses to be created without a rig. */
static void test_retarget_only(const fixture *fx) {
  size_t nf = fx->take.n_frames;
  km_puppetry_options o = {0};
  km_puppetry *a = NULL, *b = NULL;
  km_puppetry_info ia, ib;
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &a, &ia, KM_E));
  o.solver = KM_PUPPETRY_RETARGET;
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &b, &ib, KM_E));
  if (a && b) {
    CHECK(km_puppetry_model(b) == NULL && ib.model_seconds == 0 && ia.model_seconds > 0);
    double *V = malloc(sizeof(double) * 3 * fx->c.mesh.n_vertices), Ja[60], Jb[60];
    double worst = 0, moved = 0;
    for (size_t fr = 0; fr < nf; ++fr) {
      const double *J = fx->take.positions + fr * fx->take.n_joints * 3;
      CHECK_OK(km_puppetry_push(a, J, V, KM_E));
      CHECK_OK(km_puppetry_push(b, J, NULL, KM_E));
      CHECK(km_puppetry_posed_joints(a, Ja) && km_puppetry_posed_joints(b, Jb));
      worst = fmax(worst, max_abs_diff(Ja, Jb, 60));
      worst = fmax(worst, max_abs_diff(km_puppetry_handle_targets(a), km_puppetry_handle_targets(b),
                                       3 * fx->rig.n_handles));
      moved = fmax(moved, max_abs_diff(Jb, fx->c.skeleton.rest, 60));
    }
    CHECK_MSG(worst == 0, "retarget-only differs from the reduced pipeline by %g", worst);
    CHECK_MSG(moved > 0.05, "the posed joints moved only %g m over the take", moved);
    double fa, fb;
    CHECK(km_puppetry_floor(a, &fa) == km_puppetry_floor(b, &fb));
    free(V);
  }
  km_puppetry_free(&a);
  km_puppetry_free(&b);
  km_puppetry *c = NULL;
  CHECK_STATUS(km_puppetry_create(&fx->c.mesh, NULL, NULL, 20, &o, &c, NULL, KM_E), KM_ERR_INVALID);
  CHECK(c == NULL);
}

static void corrupt(const char *path) {
  FILE *f = fopen(path, "r+b");
  CHECK(f != NULL);
  if (!f) return;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, n / 2, SEEK_SET);
  unsigned char junk[64];
  memset(junk, 0xA5, sizeof junk);
  fwrite(junk, 1, sizeof junk, f);
  fclose(f);
}

static void test_cache_policy(const fixture *fx) {
  char cache[300];
  snprintf(cache, sizeof cache, "%s/c.kmcache", g_dir);
  size_t nv = fx->c.mesh.n_vertices, nf = fx->take.n_frames;
  double *A = malloc(sizeof(double) * 3 * nv * nf), *B = malloc(sizeof(double) * 3 * nv * nf);
  km_puppetry_options o = {0};
  o.cache_path = cache;
  km_puppetry_info info;
  km_puppetry *p = NULL;

  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &p, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_BUILT && info.save.status == KM_OK);
  CHECK(access(cache, R_OK) == 0);
  if (p) run_pipeline(fx, p, &fx->take, A);
  km_puppetry_free(&p);

  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &p, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_LOADED && info.model_seconds >= 0);
  if (p) run_pipeline(fx, p, &fx->take, B);
  CHECK(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0);
  km_puppetry_free(&p);

  corrupt(cache);
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &p, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_REBUILT_STALE);
  CHECK(info.stale.status == KM_ERR_STALE && info.stale.message[0] != '\0');
  CHECK(info.save.status == KM_OK);
  km_puppetry_free(&p);
  /* rewritten: loads again */
  km_puppet *model = NULL;
  CHECK_OK(km_puppetry_model_open(&fx->c.mesh, &o, &model, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_LOADED);

  o.force = true;
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &o, &p, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_REBUILT_FORCED);
  km_puppetry_free(&p);

  /* A borrowed model: used as is, left to the caller. Each puppetry made on it starts from
   * the rest pose, whatever the one before left in it (its last solve): both runs give the
   * same frames as a pipeline with its own model. bench motion runs T and then B on one
   * model; B used to start from T's last frame. */
  km_puppetry_options ob = {0};
  ob.model = model;
  for (int run = 0; run < 2; ++run) {
    CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &ob, &p, &info, KM_E));
    CHECK(info.model == KM_PUPPETRY_MODEL_GIVEN && km_puppetry_model(p) == model);
    if (p) run_pipeline(fx, p, &fx->take, B);
    CHECK_MSG(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0,
              "borrowed model, run %d: frames differ from a fresh pipeline's", run);
    km_puppetry_free(&p);
  }
  km_puppet_info pi;
  km_puppet_info_get(model, &pi); /* still alive */
  CHECK(pi.vertices == nv);
  km_puppet_free(&model);

  /* A cache that cannot be written is reported, the pipeline works all the same. */
  km_puppetry_options bad = {0};
  /* (under a file, not a folder: writers create missing folders, and a root run could) */
  bad.cache_path = "/dev/null/c.kmcache";
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, &bad, &p, &info, KM_E));
  CHECK(info.model == KM_PUPPETRY_MODEL_BUILT && info.save.status != KM_OK);
  km_puppetry_free(&p);
  remove(cache);
  free(A);
  free(B);
}

/* Issue 18: a forged cache header (128 bytes asking for the largest model) is not adopted by
 * cache_parameters: the caller's parameters are used and the cache rebuilt with them. */
static void test_forged_cache(const fixture *fx) {
  char cache[300];
  snprintf(cache, sizeof cache, "%s/forged.kmcache", g_dir);
  km_puppetry_options o = {0};
  o.cache_path = cache;
  km_puppetry_info info;
  km_puppet *model = NULL;
  CHECK_OK(km_puppetry_model_open(&fx->c.mesh, &o, &model, &info, KM_E));
  km_puppet_free(&model);
  FILE *f = fopen(cache, "rb");
  unsigned char head[128] = {0};
  CHECK(f && fread(head, 1, sizeof head, f) == sizeof head);
  if (f) fclose(f);
  int32_t params[2] = {32, 64};
  memcpy(head + 32, params, sizeof params);
  f = fopen(cache, "wb");
  CHECK(f && fwrite(head, 1, sizeof head, f) == sizeof head);
  if (f) fclose(f);
  o.cache_parameters = true;
  CHECK_OK(km_puppetry_model_open(&fx->c.mesh, &o, &model, &info, KM_E));
  CHECK_MSG(!info.cache_parameters && info.puppet.fields != 32 && info.puppet.isolines != 64,
            "forged header adopted: %d fields x %d isolines", info.puppet.fields,
            info.puppet.isolines);
  CHECK(info.model == KM_PUPPETRY_MODEL_REBUILT_STALE);
  km_puppet_free(&model);
  /* the rebuilt cache is genuine: its parameters are adopted from now on */
  CHECK_OK(km_puppetry_model_open(&fx->c.mesh, &o, &model, &info, KM_E));
  CHECK_MSG(info.cache_parameters && info.model == KM_PUPPETRY_MODEL_LOADED &&
                info.puppet.fields != 32 && info.puppet.isolines != 64,
            "genuine cache: adopted %d, model %d, %d fields (%s)", info.cache_parameters,
            (int)info.model, info.puppet.fields, info.stale.message);
  km_puppet_free(&model);
  remove(cache);
}

static void test_set_rig(const fixture *fx) {
  size_t nv = fx->c.mesh.n_vertices, nf = fx->take.n_frames;
  double *A = malloc(sizeof(double) * 3 * nv * nf), *B = malloc(sizeof(double) * 3 * nv * nf);
  km_puppetry *p = NULL, *q = NULL;
  /* model only, then a rig */
  CHECK_OK(km_puppetry_create(&fx->c.mesh, NULL, NULL, 20, NULL, &p, NULL, KM_E));
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, 20, NULL, &q, NULL, KM_E));
  if (!p || !q) return;
  CHECK_STATUS(km_puppetry_push(p, fx->take.positions, A, KM_E), KM_ERR_INVALID);
  CHECK_OK(km_puppetry_set_rig(p, &fx->rig, KM_E));
  run_pipeline(fx, p, &fx->take, A);
  run_pipeline(fx, q, &fx->take, B);
  CHECK(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0);

  /* A rig that fails leaves the old one in force. */
  km_rig empty = fx->rig;
  empty.n_handles = 0;
  CHECK_STATUS(km_puppetry_set_rig(p, &empty, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "no handles") != NULL);
  km_puppetry_reset(p);
  km_puppetry_reset(q);
  run_pipeline(fx, p, &fx->take, A);
  run_pipeline(fx, q, &fx->take, B);
  CHECK(memcmp(A, B, sizeof(double) * 3 * nv * nf) == 0);

  /* A swap mid-take keeps the pose: the newest frame is replayed through the new rig. */
  const double *last = fx->take.positions + (nf - 1) * 60;
  double before[3 * 64];
  size_t nh = fx->rig.n_handles < 64 ? fx->rig.n_handles : 64;
  memcpy(before, km_puppetry_handle_targets(p), sizeof(double) * 3 * nh);
  CHECK_OK(km_puppetry_set_rig(p, &fx->rig, KM_E));
  CHECK(km_puppetry_last_joints(p) != NULL &&
        max_abs_diff(km_puppetry_last_joints(p), last, 60) == 0);
  double diag = km_bbox_diagonal(fx->c.mesh.V, nv);
  CHECK_MSG(max_abs_diff(before, km_puppetry_handle_targets(p), 3 * nh) < 0.05 * diag, "%g",
            max_abs_diff(before, km_puppetry_handle_targets(p), 3 * nh));
  CHECK(isfinite(km_puppetry_scale(p)));
  km_puppetry_free(&p);
  km_puppetry_free(&q);
  free(A);
  free(B);
}

static bool mentions(const char *path) { return strstr(km_test_err.message, path) != NULL; }

static void test_motion_read(const fixture *fx) {
  km_take t;
  km_motion_read_info info;
  /* BVH, by extension */
  CHECK_OK(km_motion_read(KM_TEST_DATA "/bvh_two_joint.bvh", NULL, &t, &info, KM_E));
  CHECK(info.format == KM_MOTION_BVH && t.n_frames == 3 && t.n_joints == 2);
  km_take_free(&t);
  km_motion_read_options mo = {0};
  mo.bvh.end_sites = true;
  CHECK_OK(km_motion_read(KM_TEST_DATA "/bvh_two_joint.bvh", &mo, &t, NULL, KM_E));
  CHECK(t.n_joints == 3);
  km_take_free(&t);
  /* Kinect CSV */
  CHECK_OK(km_motion_read(KM_TEST_DATA "/kinect_reordered.csv", NULL, &t, &info, KM_E));
  CHECK(info.format == KM_MOTION_KINECT_CSV && t.n_frames == 3 && t.n_joints == 20);
  km_take_free(&t);
  /* take JSON, and the same file without an extension (by content) */
  char take_path[300], noext[300];
  snprintf(take_path, sizeof take_path, "%s/wave.json", g_dir);
  snprintf(noext, sizeof noext, "%s/wave_take", g_dir);
  CHECK_OK(km_take_write(take_path, &fx->take, KM_E));
  CHECK_OK(km_take_write(noext, &fx->take, KM_E));
  CHECK_OK(km_motion_read(take_path, NULL, &t, &info, KM_E));
  CHECK(info.format == KM_MOTION_TAKE_JSON && t.n_frames == fx->take.n_frames);
  km_take_free(&t);
  CHECK_OK(km_motion_read(noext, NULL, &t, &info, KM_E));
  CHECK(info.format == KM_MOTION_TAKE_JSON && t.n_frames == fx->take.n_frames);
  km_take_free(&t);
  char bvh_noext[300];
  snprintf(bvh_noext, sizeof bvh_noext, "%s/two_joint_motion", g_dir);
  char cmd[700];
  snprintf(cmd, sizeof cmd, "cp %s %s", KM_TEST_DATA "/bvh_two_joint.bvh", bvh_noext);
  CHECK(system(cmd) == 0);
  CHECK_OK(km_motion_read(bvh_noext, NULL, &t, &info, KM_E));
  CHECK(info.format == KM_MOTION_BVH && t.n_frames == 3);
  km_take_free(&t);

  /* kinect1: a BVH's columns by name; the two-joint BVH has none of them */
  mo = (km_motion_read_options){.kinect1 = true};
  CHECK_STATUS(km_motion_read(KM_TEST_DATA "/bvh_two_joint.bvh", &mo, &t, NULL, KM_E),
               KM_ERR_INVALID);
  CHECK(mentions(KM_TEST_DATA "/bvh_two_joint.bvh") &&
        strstr(km_test_err.message, "Kinect v1 joints") != NULL);
  CHECK(t.n_frames == 0 && t.positions == NULL);
  /* a take with the Kinect joints in another order and one missing */
  km_take sh = {0};
  sh.n_frames = 2;
  sh.n_joints = 3;
  sh.fps = 0;
  char *names[3] = {"HandLeft", "Foo", "HipCenter"};
  double pos[18];
  for (int k = 0; k < 18; ++k)
    pos[k] = k;
  sh.joint_names = names;
  sh.positions = pos;
  sh.fps = 25;
  char sh_path[300];
  snprintf(sh_path, sizeof sh_path, "%s/partial.json", g_dir);
  CHECK_OK(km_take_write(sh_path, &sh, KM_E));
  CHECK_OK(km_motion_read(sh_path, &mo, &t, &info, KM_E));
  CHECK(t.n_joints == 20 && t.n_frames == 2 && info.kinect1_found == 2 && t.fps == 25);
  if (t.n_joints == 20) {
    CHECK(!strcmp(t.joint_names[0], "HipCenter") && !strcmp(t.joint_names[7], "HandLeft"));
    CHECK(t.parents && t.parents[0] == -1 && t.parents[7] == km_kinect1_joint_parent(7));
    CHECK(t.positions[0] == 6 && t.positions[2] == 8);           /* HipCenter, frame 0 */
    CHECK(t.positions[7 * 3] == 0 && t.positions[60 + 21] == 9); /* HandLeft */
    CHECK(isnan(t.positions[3]));                                /* Spine absent */
  }
  km_take_free(&t);

  /* Garbage: an error that names the file, whatever the format. */
  const char *exts[] = {".json", ".bvh", ".csv", ""};
  for (int e = 0; e < 4; ++e) {
    char g[300];
    snprintf(g, sizeof g, "%s/garbage%s", g_dir, exts[e]);
    FILE *f = fopen(g, "wb");
    if (f) {
      fputs("\x01\x02 this is not motion\n{[;;\n", f);
      fclose(f);
    }
    km_status s = km_motion_read(g, NULL, &t, NULL, KM_E);
    CHECK_MSG(s != KM_OK && mentions(g), "%s: %s", g, km_test_err.message);
    CHECK(t.positions == NULL && t.n_frames == 0);
  }
  char missing[300];
  snprintf(missing, sizeof missing, "%s/absent.bvh", g_dir);
  CHECK(km_motion_read(missing, NULL, &t, NULL, KM_E) != KM_OK && mentions(missing));
}

/* Issue 12: a 0.6 m one-frame spike on a hand is rejected before the filter: the mesh stays
 * within 1% of the diagonal of the clean take's result (and without rejection it does not).
 * In the first frame (at = 0) the spike is the reference the motion is measured from; the
 * joint is restarted when the true samples come back (km_glitch_restarted) and from then on
 * (frame 3) the mesh is again within 1% of the clean take's: not the spike's offset for the
 * whole take. */
static void test_spike_rejected(const fixture *fx, size_t at) {
  km_take t = {0};
  CHECK_OK(km_motion_generate(&fx->c.skeleton, KM_MOTION_WAVE, 60, &t, KM_E));
  if (t.n_frames != 60) {
    km_take_free(&t);
    return;
  }
  size_t nv = fx->c.mesh.n_vertices, nf = t.n_frames, nj = t.n_joints;
  double *clean = malloc(sizeof(double) * 3 * nv * nf),
         *spiked = malloc(sizeof(double) * 3 * nv * nf);
  double *pos = malloc(sizeof(double) * 3 * nj * nf);
  memcpy(pos, t.positions, sizeof(double) * 3 * nj * nf);
  /* The wrist: it steers the default rig's forearm band (bone handles), so its spike shows
   * on the arm when it is not rejected. */
  int hand = km_kinect1_joint_index("WristLeft");
  pos[(at * nj + (size_t)hand) * 3 + 1] += 0.6;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < nv; ++v)
    for (int d = 0; d < 3; ++d) {
      lo[d] = fmin(lo[d], fx->c.mesh.V[3 * v + d]);
      hi[d] = fmax(hi[d], fx->c.mesh.V[3 * v + d]);
    }
  double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                     (hi[2] - lo[2]) * (hi[2] - lo[2]));
  for (int off = 0; off < 2; ++off) {
    km_puppetry_options o = {0};
    o.fps = t.fps;
    o.no_glitch = off;
    km_puppetry *p = NULL;
    CHECK_OK(km_puppetry_create(&fx->c.mesh, &fx->rig, NULL, nj, &o, &p, NULL, KM_E));
    if (!p) break;
    for (size_t f = 0; f < nf; ++f)
      CHECK_OK(km_puppetry_push(p, t.positions + f * nj * 3, clean + f * 3 * nv, KM_E));
    km_glitch_stats st0;
    km_puppetry_glitch_stats(p, &st0);
    km_puppetry_reset(p);
    for (size_t f = 0; f < nf; ++f)
      CHECK_OK(km_puppetry_push(p, pos + f * nj * 3, spiked + f * 3 * nv, KM_E));
    km_glitch_stats st;
    km_puppetry_glitch_stats(p, &st);
    double worst = 0;
    for (size_t f = at ? 0 : 3; f < nf; ++f)
      for (size_t v = 0; v < nv; ++v) {
        const double *a = clean + (f * nv + v) * 3, *b = spiked + (f * nv + v) * 3;
        worst = fmax(worst, sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                 (a[2] - b[2]) * (a[2] - b[2])));
      }
    if (!off) {
      CHECK_MSG(st0.rejected == 0, "clean take: %zu samples rejected", st0.rejected);
      CHECK_MSG(st.rejected >= 1 && st.speed >= 1, "spike not counted (%zu rejected)", st.rejected);
      CHECK_MSG(st.restarted == (at ? 0u : 1u), "spike in frame %zu: %zu joints restarted", at,
                st.restarted);
      CHECK_MSG(worst <= 0.01 * diag, "spike in frame %zu moves the mesh %.4f (diag %.4f)", at,
                worst, diag);
    } else {
      CHECK_MSG(st.rejected == 0 && worst > 0.01 * diag,
                "without rejection the spike should show (%.4f of diag %.4f)", worst, diag);
    }
    km_puppetry_free(&p);
  }
  free(clean);
  free(spiked);
  free(pos);
  km_take_free(&t);
}

/* Issue 12: "root_motion": "rigid" with "relative_to": "HipCenter": a performer who only
 * walks and turns (the skeleton moved rigidly: 90 degrees about y and 0.3 m) moves the mesh
 * rigidly (rest mesh rotated about the root joint and translated by the root scale times
 * 0.3 m: the character's leg length over the performer's, 1 here where the performer is the
 * character's own skeleton, while the stature scale s is not exactly 1), unstretched. */
static void test_root_rigid(const fixture *fx) {
  km_rig rig = fx->rig;
  rig.maps = malloc(rig.n_maps * sizeof *rig.maps);
  memcpy(rig.maps, fx->rig.maps, rig.n_maps * sizeof *rig.maps);
  for (size_t e = 0; e < rig.n_maps; ++e)
    rig.maps[e].relative_to = 1; /* HipCenter */
  rig.root_rigid = true;
  rig.root = 1;
  rig.heading[0] = 1 + km_kinect1_joint_index("HipLeft");
  rig.heading[1] = 1 + km_kinect1_joint_index("HipRight");
  km_filter_options raw = {.smoothing = KM_FILTER_ZERO, .trend = KM_FILTER_ZERO};
  km_puppetry_options o = {0};
  o.filter = &raw;
  o.no_glitch = true;
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &rig, NULL, KM_KINECT1_JOINTS, &o, &p, NULL, KM_E));
  free(rig.maps);
  if (!p) return;
  size_t nv = fx->c.mesh.n_vertices;
  double *V = malloc(sizeof(double) * 3 * nv), J[3 * KM_KINECT1_JOINTS];
  const double *J0 = fx->c.skeleton.rest;
  CHECK_OK(km_puppetry_push(p, J0, V, KM_E));
  const double move[3] = {0.3, 0, 0.2};
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) { /* R_y(90): (x, z) -> (z, -x) about the hips */
    double w[3] = {J0[3 * j] - J0[0], J0[3 * j + 1] - J0[1], J0[3 * j + 2] - J0[2]};
    J[3 * j] = J0[0] + w[2] + move[0];
    J[3 * j + 1] = J0[1] + w[1] + move[1];
    J[3 * j + 2] = J0[2] - w[0] + move[2];
  }
  /* a 90 degree turn in one frame is held as a glitch for a few frames, then the heading
   * follows at most 180 degrees a second through its filter: 150 frames to settle exactly */
  for (int f = 0; f < 150; ++f)
    CHECK_OK(km_puppetry_push(p, J, V, KM_E));
  double s = 1 /* legs over legs, see above */, diag = km_bbox_diagonal(fx->c.mesh.V, nv);
  CHECK_MSG(fabs(km_puppetry_scale(p) - 1) > 1e-4,
            "the stature scale is %.6f: the test cannot tell it from the legs' ratio",
            km_puppetry_scale(p));
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < nv; ++v)
    for (int d = 0; d < 3; ++d) {
      lo[d] = fmin(lo[d], fx->c.mesh.V[3 * v + d]);
      hi[d] = fmax(hi[d], fx->c.mesh.V[3 * v + d]);
    }
  /* about the vertical through the middle of the spine (HipCenter -> ShoulderCenter) when the
   * rig has kinect1 joints, else the box centre */
  double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
  if (fx->rig.joint_rest && fx->rig.n_joint_rest == KM_KINECT1_JOINTS)
    cx = 0.5 * (fx->rig.joint_rest[0] + fx->rig.joint_rest[6]),
    cz = 0.5 * (fx->rig.joint_rest[2] + fx->rig.joint_rest[8]);
  double worst = 0;
  for (size_t v = 0; v < nv; ++v) {
    const double *x = fx->c.mesh.V + 3 * v;
    double w[3] = {x[0] - cx, x[1], x[2] - cz};
    double e[3] = {cx + w[2] + s * move[0], w[1] + s * move[1], cz - w[0] + s * move[2]};
    for (int d = 0; d < 3; ++d)
      worst = fmax(worst, fabs(V[3 * v + d] - e[d]));
  }
  CHECK_MSG(worst < 1e-6 * diag, "rigid root motion: off by %g (diag %g)", worst, diag);
  free(V);
  km_puppetry_free(&p);
}

/* Issue 12: the rigid root's heading ignores tracker glitches: a one-frame 60 degree re-fit
 * of the hips and shoulders and a 180 degree left/right swap of them (3 frames) leave the mesh
 * where it was (within 1% of the diagonal; following them at 20 degrees a frame moved it by
 * a tenth), while a real turn of 90 degrees over a second is followed. */
/* A puppetry of fx's character whose mesh is turned by the heading alone: translation-only
 * handles at head, hands and feet, relative to the hips (the paper's), the other handles
 * anchors, rigid root motion with the hips as heading, the joints unfiltered (the heading sees
 * every push); max_turn: the rig's "max_turn" (0: default). NULL on failure (checked). */
static km_puppetry *heading_puppetry(const fixture *fx, double max_turn) {
  km_rig rig = fx->rig;
  rig.maps = malloc(rig.n_maps * sizeof *rig.maps);
  rig.n_maps = 0;
  for (size_t e = 0; e < fx->rig.n_maps; ++e) {
    km_rig_map m = fx->rig.maps[e];
    if (m.handle >= 5) continue;
    m.bone_from = 0;
    m.rotate = false;
    m.axes = KM_AXIS_X | KM_AXIS_Y | KM_AXIS_Z;
    m.scale = 1;
    m.relative_to = 1; /* HipCenter */
    rig.maps[rig.n_maps++] = m;
  }
  rig.root_rigid = true;
  rig.root = 1;
  rig.heading[0] = 1 + km_kinect1_joint_index("HipLeft");
  rig.heading[1] = 1 + km_kinect1_joint_index("HipRight");
  rig.max_turn = max_turn;
  km_filter_options raw = {.smoothing = KM_FILTER_ZERO, .trend = KM_FILTER_ZERO};
  km_puppetry_options o = {0};
  o.filter = &raw;
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(&fx->c.mesh, &rig, NULL, KM_KINECT1_JOINTS, &o, &p, NULL, KM_E));
  free(rig.maps);
  return p;
}

/* The turn about y (degrees) taking the mesh V0 to V, #V = nv vertices, of the vertices with
 * mask[v] (NULL: all): the library's rigid fit (km_similarity_fit), read as the angle of its
 * rotation about y (the meshes only turn about y here). */
static double mesh_turn(const double *V0, const double *V, size_t nv, const bool *mask) {
  double *w = NULL, R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, t[3];
  if (mask && (w = malloc(nv * sizeof *w)))
    for (size_t v = 0; v < nv; ++v)
      w[v] = mask[v] ? 1 : 0;
  CHECK_OK(km_similarity_fit(V0, V, w, nv, false, NULL, R, t, KM_E));
  free(w);
  return atan2(R[2], R[0]) * 180 / M_PI;
}

/* J: the rest joints J0 turned by a radians about the vertical through the root. */
static void turn_joints(const double *J0, double a, double *J) {
  double c = cos(a), sn = sin(a);
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    double w[3] = {J0[3 * j] - J0[0], J0[3 * j + 1] - J0[1], J0[3 * j + 2] - J0[2]};
    J[3 * j] = J0[0] + c * w[0] + sn * w[2];
    J[3 * j + 1] = J0[3 * j + 1];
    J[3 * j + 2] = J0[2] - sn * w[0] + c * w[2];
  }
}

static void test_root_heading_glitch(const fixture *fx) {
  km_puppetry *p = heading_puppetry(fx, 0);
  if (!p) return;
  size_t nv = fx->c.mesh.n_vertices;
  double diag = km_bbox_diagonal(fx->c.mesh.V, nv);
  double *V = malloc(sizeof(double) * 3 * nv), *V0 = malloc(sizeof(double) * 3 * nv);
  double J[3 * KM_KINECT1_JOINTS];
  const double *J0 = fx->c.skeleton.rest;
  for (int f = 0; f < 10; ++f)
    CHECK_OK(km_puppetry_push(p, J0, V0, KM_E));
  int lr[2][2] = {{12, 16}, {4, 8}}; /* hips, shoulders: the heading's joints */
  double worst = 0;
  for (int f = 0; f < 40; ++f) {
    memcpy(J, J0, sizeof J);
    if (f == 5) { /* a re-fit: hips and shoulders turned 60 degrees for one frame */
      double c = cos(M_PI / 3), sn = sin(M_PI / 3);
      for (int k = 0; k < 4; ++k) {
        int j = lr[k / 2][k % 2];
        double w[3] = {J0[3 * j] - J0[0], J0[3 * j + 1] - J0[1], J0[3 * j + 2] - J0[2]};
        J[3 * j] = J0[0] + c * w[0] + sn * w[2];
        J[3 * j + 2] = J0[2] - sn * w[0] + c * w[2];
      }
    }
    if (f >= 20 && f < 23) /* left and right swapped */
      for (int k = 0; k < 2; ++k)
        for (int d = 0; d < 3; ++d) {
          J[3 * lr[k][0] + d] = J0[3 * lr[k][1] + d];
          J[3 * lr[k][1] + d] = J0[3 * lr[k][0] + d];
        }
    CHECK_OK(km_puppetry_push(p, J, V, KM_E));
    for (size_t i = 0; i < 3 * nv; ++i)
      worst = fmax(worst, fabs(V[i] - V0[i]));
  }
  CHECK_MSG(worst < 0.01 * diag, "heading glitches moved the mesh by %.1f%% of the diagonal",
            100 * worst / diag);
  /* a real turn: 90 degrees over 30 frames, then held: the heading arrives */
  for (int f = 1; f <= 90; ++f) {
    turn_joints(J0, 0.5 * M_PI * fmin(1.0, f / 30.0), J);
    CHECK_OK(km_puppetry_push(p, J, V, KM_E));
  }
  double turned = mesh_turn(V0, V, nv, NULL);
  CHECK_MSG(fabs(turned - 90) < 3, "a real 90 degree turn shown as %.1f degrees", turned);
  free(V);
  free(V0);
  km_puppetry_free(&p);
}

/* The heading's lines count by their length on the floor: a hip line read 3 cm wide and turned
 * 80 degrees (MediaPipe now and then lifts the hips so; held for 30 frames, so the glitch test
 * lets it through) while the shoulders stay square turns the mesh 1.7 degrees, where counting
 * each line's direction alike turned it 15.3. */
static void test_root_heading_short_line(const fixture *fx) {
  km_puppetry *p = heading_puppetry(fx, 0);
  if (!p) return;
  size_t nv = fx->c.mesh.n_vertices;
  double *V = malloc(sizeof(double) * 3 * nv), *V0 = malloc(sizeof(double) * 3 * nv);
  double J[3 * KM_KINECT1_JOINTS];
  const double *J0 = fx->c.skeleton.rest;
  for (int f = 0; f < 10; ++f)
    CHECK_OK(km_puppetry_push(p, J0, V0, KM_E));
  int hl = km_kinect1_joint_index("HipLeft"), hr = km_kinect1_joint_index("HipRight");
  double mid[3], a = 80 * M_PI / 180;
  for (int d = 0; d < 3; ++d)
    mid[d] = 0.5 * (J0[3 * hl + d] + J0[3 * hr + d]);
  for (int f = 0; f < 30; ++f) {
    memcpy(J, J0, sizeof J);
    for (int s = -1; s <= 1; s += 2) { /* left at +x: 1.5 cm either side of the middle, turned */
      int j = s > 0 ? hl : hr;
      J[3 * j] = mid[0] + s * 0.015 * cos(a);
      J[3 * j + 2] = mid[2] - s * 0.015 * sin(a);
    }
    CHECK_OK(km_puppetry_push(p, J, V, KM_E));
  }
  double turned = mesh_turn(V0, V, nv, NULL);
  CHECK_MSG(fabs(turned) < 10, "a 3 cm hip line turned 80 degrees turned the mesh %.1f degrees",
            turned);
  free(V);
  free(V0);
  km_puppetry_free(&p);
}

/* The rig's "max_turn" (deg/s): a performer's spin of 540 deg/s (18 degrees a frame at 30 fps,
 * below the heading's glitch rate) turns the torso (the vertices skinned mostly to the spine;
 * the handles at hands, head and feet lead it while the heading lags) at most max_turn / fps
 * a frame, and the turn arrives in full once the performer stops; without it (600 deg/s) the
 * spin is followed at its own pace. */
static void test_root_max_turn(const fixture *fx) {
  static const double limits[2] = {0, 180};
  size_t nv = fx->c.mesh.n_vertices;
  bool *torso = calloc(nv, sizeof(bool));
  for (size_t v = 0; v < nv; ++v) {
    const double *w = fx->c.skin.weights + KM_SKIN_INFLUENCES * v;
    int best = 0;
    for (int i = 1; i < KM_SKIN_INFLUENCES; ++i)
      if (w[i] > w[best]) best = i;
    int32_t j = fx->c.skin.joints[KM_SKIN_INFLUENCES * v + best];
    torso[v] = j == km_kinect1_joint_index("Spine") || j == km_kinect1_joint_index("HipCenter");
  }
  for (int k = 0; k < 2; ++k) {
    km_puppetry *p = heading_puppetry(fx, limits[k]);
    if (!p) break;
    double *V = malloc(sizeof(double) * 3 * nv), *V0 = malloc(sizeof(double) * 3 * nv);
    double J[3 * KM_KINECT1_JOINTS], prev = 0, step_max = 0, at_stop = 0;
    const double *J0 = fx->c.skeleton.rest;
    for (int f = 0; f < 10; ++f)
      CHECK_OK(km_puppetry_push(p, J0, V0, KM_E));
    for (int f = 1; f <= 60; ++f) { /* 90 degrees in 5 frames, then held */
      turn_joints(J0, 0.5 * M_PI * fmin(1.0, f / 5.0), J);
      CHECK_OK(km_puppetry_push(p, J, V, KM_E));
      double t = mesh_turn(V0, V, nv, torso);
      step_max = fmax(step_max, fabs(t - prev));
      prev = t;
      if (f == 5) at_stop = t;
    }
    if (limits[k] > 0) {
      CHECK_MSG(step_max <= limits[k] / 30 + 0.5, "max_turn %g: %.1f degrees in a frame", limits[k],
                step_max);
      CHECK_MSG(at_stop <= 5 * limits[k] / 30 + 0.5, "max_turn %g: %.1f degrees after 5 frames",
                limits[k], at_stop);
    } else {
      CHECK_MSG(step_max > 12, "default: the spin followed at %.1f degrees a frame at most",
                step_max);
    }
    CHECK_MSG(fabs(prev - 90) < 3, "max_turn %g: a 90 degree turn shown as %.1f degrees", limits[k],
              prev);
    free(V);
    free(V0);
    km_puppetry_free(&p);
  }
  free(torso);
}

/* A body with a small loose piece (issue 11: a character's eye, a buckle; here an octahedron
 * of 6 vertices in front of the top of the head, appended after the body's vertices): the
 * reduced model gives the piece the fields of the body's nearest vertices, so it follows the
 * head, and the body moves as it does alone. Before, the piece took a field of its own (its
 * indicator) and was left behind: on this walk its gap to the head (0.022 at rest) was off by
 * up to 0.088, and the body 0.25 % of the diagonal off its animation alone; now 0.0005 and
 * 0.02 %, the piece's size within 3.5 %. */
static void test_loose_piece(const fixture *fx) {
  const km_mesh *a = &fx->c.mesh;
  size_t na = a->n_vertices, nf = 24;
  km_mesh b = {0};
  b.n_vertices = na + 6;
  b.n_faces = a->n_faces + 8;
  b.V = malloc(sizeof(double) * 3 * b.n_vertices);
  b.F = malloc(sizeof(int32_t) * 3 * b.n_faces);
  km_take walk = {0};
  CHECK_OK(km_motion_generate(&fx->c.skeleton, KM_MOTION_WALK, nf, &walk, KM_E));
  double *A = malloc(sizeof(double) * 3 * na * nf),
         *B = malloc(sizeof(double) * 3 * b.n_vertices * nf);
  if (!b.V || !b.F || !A || !B || !walk.positions) goto done;
  memcpy(b.V, a->V, sizeof(double) * 3 * na);
  memcpy(b.F, a->F, sizeof(int32_t) * 3 * a->n_faces);
  size_t top = 0;
  for (size_t v = 1; v < na; ++v)
    if (a->V[3 * v + 1] > a->V[3 * top + 1]) top = v;
  double diag = km_bbox_diagonal(a->V, na), r = 0.01 * diag;
  double c0[3] = {a->V[3 * top], a->V[3 * top + 1], a->V[3 * top + 2] + 0.02 * diag};
  static const double oct[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                   {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
  static const int of[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                               {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int k = 0; k < 6; ++k)
    for (int c = 0; c < 3; ++c)
      b.V[3 * (na + (size_t)k) + (size_t)c] = c0[c] + r * oct[k][c];
  for (int f = 0; f < 8; ++f)
    for (int c = 0; c < 3; ++c)
      b.F[3 * (a->n_faces + (size_t)f) + (size_t)c] = (int32_t)na + of[f][c];
  int32_t near[8];
  km_nearest_vertices(a->V, na, c0, 8, near, NULL);
  for (int full = 0; full < 2; ++full) {
    km_puppetry *pa = NULL, *pb = NULL;
    km_puppetry_options o = {0};
    o.solver = full ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED;
    CHECK_OK(km_puppetry_create(a, &fx->rig, NULL, 20, &o, &pa, NULL, KM_E));
    CHECK_OK(km_puppetry_create(&b, &fx->rig, NULL, 20, &o, &pb, NULL, KM_E));
    double body = 0, gap_dev = 0, size_dev = 0, gap0 = 0;
    for (size_t fr = 0; pa && pb && fr < nf; ++fr) {
      const double *j = walk.positions + fr * 20 * 3;
      double *X = A + fr * 3 * na, *Y = B + fr * 3 * b.n_vertices;
      CHECK_OK(km_puppetry_push(pa, j, X, KM_E));
      CHECK_OK(km_puppetry_push(pb, j, Y, KM_E));
      body = fmax(body, max_abs_diff(X, Y, 3 * na));
      /* the piece's centre against the centroid of the 8 body vertices nearest to it at rest */
      double c[3] = {0, 0, 0}, h[3] = {0, 0, 0}, h0[3] = {0, 0, 0}, sz = 0;
      for (int k = 0; k < 6; ++k)
        for (int d = 0; d < 3; ++d)
          c[d] += Y[3 * (na + (size_t)k) + (size_t)d] / 6;
      for (int k = 0; k < 8; ++k)
        for (int d = 0; d < 3; ++d)
          h[d] += Y[3 * (size_t)near[k] + (size_t)d] / 8,
              h0[d] += a->V[3 * (size_t)near[k] + (size_t)d] / 8;
      for (int k = 0; k < 6; ++k)
        sz += sqrt(pow(Y[3 * (na + (size_t)k)] - c[0], 2) +
                   pow(Y[3 * (na + (size_t)k) + 1] - c[1], 2) +
                   pow(Y[3 * (na + (size_t)k) + 2] - c[2], 2)) /
              6;
      gap0 = sqrt(pow(c0[0] - h0[0], 2) + pow(c0[1] - h0[1], 2) + pow(c0[2] - h0[2], 2));
      double gap = sqrt(pow(c[0] - h[0], 2) + pow(c[1] - h[1], 2) + pow(c[2] - h[2], 2));
      gap_dev = fmax(gap_dev, fabs(gap - gap0));
      size_dev = fmax(size_dev, fabs(sz / r - 1));
    }
    const char *tag = full ? "full ARAP" : "reduced";
    printf("loose piece (%s): body within %.4f %% of the diagonal of its animation alone; the "
           "piece's gap to the head %.3f at rest, off by %.4f at most; its size off by %.2f %%\n",
           tag, 100 * body / diag, gap0, gap_dev, 100 * size_dev);
    CHECK_MSG(pa && pb, "%s: created", tag);
    CHECK_MSG(body < 0.005 * diag, "%s: the body moves %.4f %% of the diagonal off", tag,
              100 * body / diag);
    CHECK_MSG(gap_dev < 0.25 * gap0,
              "%s: the loose piece's gap to the head is off by %.4f (rest %.4f)", tag, gap_dev,
              gap0);
    CHECK_MSG(size_dev < 0.08, "%s: the loose piece's size is off by %.2f %%", tag, 100 * size_dev);
    km_puppetry_free(&pa);
    km_puppetry_free(&pb);
  }
done:
  km_take_free(&walk);
  free(A);
  free(B);
  km_mesh_free(&b);
}

/* A vertex no face uses (an exporter's leftover) does not set the performer-to-character scale
 * (the surface's height: one above the head made it 1.514 instead of 1.020 on a walk): the
 * pipeline on the character with one at 1.5x its height scales as without it. (The reduced
 * model still differs a little, up to 1.5 cm on this wave: the lone vertex is a row of the
 * Laplacian the fields are computed on; left for later.) */
static void test_stray_vertex(const fixture *fx) {
  const km_mesh *a = &fx->c.mesh;
  size_t n = a->n_vertices;
  km_mesh b = *a; /* the same faces, one vertex more */
  b.V = malloc(sizeof(double) * 3 * (n + 1));
  b.n_vertices = n + 1;
  b.UV = b.N = b.colors = NULL;
  b.materials = NULL, b.n_materials = 0;
  double *X = malloc(sizeof(double) * 3 * (n + 1)), *Y = malloc(sizeof(double) * 3 * (n + 1));
  km_puppetry *pa = NULL, *pb = NULL;
  if (!b.V || !X || !Y) goto done;
  memcpy(b.V, a->V, sizeof(double) * 3 * n);
  double hi = -INFINITY;
  for (size_t v = 0; v < n; ++v)
    hi = fmax(hi, a->V[3 * v + 1]);
  b.V[3 * n] = 0.1, b.V[3 * n + 1] = 1.5 * hi, b.V[3 * n + 2] = -0.2;
  km_puppetry_options o = {0};
  CHECK_OK(km_puppetry_create(a, &fx->rig, NULL, 20, &o, &pa, NULL, KM_E));
  CHECK_OK(km_puppetry_create(&b, &fx->rig, NULL, 20, &o, &pb, NULL, KM_E));
  if (!pa || !pb) goto done;
  double d = 0;
  for (size_t fr = 0; fr < fx->take.n_frames; ++fr) {
    const double *j = fx->take.positions + fr * 20 * 3;
    CHECK_OK(km_puppetry_push(pa, j, X, KM_E));
    CHECK_OK(km_puppetry_push(pb, j, Y, KM_E));
    d = fmax(d, max_abs_diff(X, Y, 3 * n));
  }
  printf("stray vertex: scale %.4f (without it %.4f), the mesh within %.2g m\n",
         km_puppetry_scale(pb), km_puppetry_scale(pa), d);
  CHECK(fabs(km_puppetry_scale(pb) - km_puppetry_scale(pa)) < 1e-12);
  CHECK_MSG(d < 0.05, "the mesh %g m off without the stray vertex", d);
done:
  km_puppetry_free(&pa);
  km_puppetry_free(&pb);
  free(b.V);
  free(X);
  free(Y);
}
/* A ground quad exported with the character (4 m wide at its feet; a loose piece lying on the
 * floor, km__ground_vertices): the performer-to-character scale and the rest floor are the
 * character's (its height measured without the quad), the body moves as without it, and the
 * quad stays where it is, neither torn between the feet and whatever body vertex is nearest to
 * each corner (armadillo_1k on a walk: 2.05x) nor tilted with the foot nearest to it. */
static void test_ground_quad(const fixture *fx) {
  const km_mesh *a = &fx->c.mesh;
  size_t n = a->n_vertices, nf = a->n_faces;
  km_mesh b = {0};
  double *X = malloc(sizeof(double) * 3 * (n + 4)), *Y = malloc(sizeof(double) * 3 * (n + 4));
  km_puppetry *pa = NULL, *pb = NULL;
  CHECK_OK(km_mesh_alloc(n + 4, nf + 2, &b, KM_E));
  if (!b.V || !X || !Y) goto done;
  memcpy(b.V, a->V, sizeof(double) * 3 * n);
  memcpy(b.F, a->F, sizeof(int32_t) * 3 * nf);
  double lo = INFINITY;
  for (size_t v = 0; v < n; ++v)
    lo = fmin(lo, a->V[3 * v + 1]);
  const double quad[12] = {-2, lo, -2, 2, lo, -2, 2, lo, 2, -2, lo, 2};
  const int32_t qf[6] = {0, 2, 1, 0, 3, 2};
  memcpy(b.V + 3 * n, quad, sizeof quad);
  for (int k = 0; k < 6; ++k)
    b.F[3 * nf + (size_t)k] = (int32_t)n + qf[k];
  km_puppetry_options o = {0};
  CHECK_OK(km_puppetry_create(a, &fx->rig, NULL, 20, &o, &pa, NULL, KM_E));
  CHECK_OK(km_puppetry_create(&b, &fx->rig, NULL, 20, &o, &pb, NULL, KM_E));
  if (!pa || !pb) goto done;
  double d = 0, moved = 0;
  for (size_t fr = 0; fr < fx->take.n_frames; ++fr) {
    const double *j = fx->take.positions + fr * 20 * 3;
    CHECK_OK(km_puppetry_push(pa, j, X, KM_E));
    CHECK_OK(km_puppetry_push(pb, j, Y, KM_E));
    d = fmax(d, max_abs_diff(X, Y, 3 * n));
    moved = fmax(moved, max_abs_diff(Y + 3 * n, quad, 12));
  }
  printf("ground quad: scale %.4f (without it %.4f), the body within %.2g m, the quad %.2g m "
         "from where it lies\n",
         km_puppetry_scale(pb), km_puppetry_scale(pa), d, moved);
  CHECK(fabs(km_puppetry_scale(pb) - km_puppetry_scale(pa)) < 1e-12);
  CHECK_MSG(d < 0.05, "the body %g m off without the quad", d);
  CHECK_MSG(moved == 0, "the ground quad moved %g m", moved);
done:
  km_puppetry_free(&pa);
  km_puppetry_free(&pb);
  km_mesh_free(&b);
  free(X);
  free(Y);
}

/* A piece held away from the body (a blade, 0.5 m of 11 rings beside the character's right
 * hand): it turns rigidly with the body vertex nearest to it (find_held), its edges kept. */
static void test_held_blade(const fixture *fx) {
  const km_mesh *a = &fx->c.mesh;
  size_t n = a->n_vertices, nf = a->n_faces;
  enum { RINGS = 11, NB = 4 * RINGS, NBF = 8 * (RINGS - 1) };
  km_mesh b = {0};
  double *Y = malloc(sizeof(double) * 3 * (n + NB));
  km_puppetry *pb = NULL;
  CHECK_OK(km_mesh_alloc(n + NB, nf + NBF, &b, KM_E));
  if (!b.V || !Y) goto done;
  memcpy(b.V, a->V, sizeof(double) * 3 * n);
  memcpy(b.F, a->F, sizeof(int32_t) * 3 * nf);
  size_t hand = 0; /* the vertex farthest along -x: the right hand's tip in the rest pose */
  for (size_t v = 1; v < n; ++v)
    if (a->V[3 * v] < a->V[3 * hand]) hand = v;
  for (int i = 0; i < RINGS; ++i)
    for (int k = 0; k < 4; ++k) {
      double *q = b.V + 3 * (n + 4 * (size_t)i + (size_t)k);
      q[0] = a->V[3 * hand] + ((k == 1 || k == 2) ? 0.01 : -0.01);
      q[1] = a->V[3 * hand + 1] + (k >= 2 ? 0.01 : -0.01);
      q[2] = a->V[3 * hand + 2] + 0.05 + 0.5 * i / (RINGS - 1);
    }
  for (int i = 0, f = 0; i < RINGS - 1; ++i)
    for (int k = 0; k < 4; ++k, f += 2) {
      int32_t p0 = (int32_t)n + 4 * i + k, p1 = (int32_t)n + 4 * i + (k + 1) % 4;
      int32_t t[6] = {p0, p1, p1 + 4, p0, p1 + 4, p0 + 4};
      memcpy(b.F + 3 * (nf + (size_t)f), t, sizeof t);
    }
  km_puppetry_options o = {0};
  CHECK_OK(km_puppetry_create(&b, &fx->rig, NULL, 20, &o, &pb, NULL, KM_E));
  if (!pb) goto done;
  double worst = 0, turned = 0;
  for (size_t fr = 0; fr < fx->take.n_frames; ++fr) {
    CHECK_OK(km_puppetry_push(pb, fx->take.positions + fr * 20 * 3, Y, KM_E));
    for (size_t f = nf; f < nf + NBF; ++f) /* every edge of the blade keeps its length */
      for (int c = 0; c < 3; ++c) {
        int32_t u = b.F[3 * f + (size_t)c], w = b.F[3 * f + (size_t)(c + 1) % 3];
        double l = 0, l0 = 0;
        for (int e = 0; e < 3; ++e) {
          l += (Y[3 * (size_t)u + e] - Y[3 * (size_t)w + e]) *
               (Y[3 * (size_t)u + e] - Y[3 * (size_t)w + e]);
          l0 += (b.V[3 * (size_t)u + e] - b.V[3 * (size_t)w + e]) *
                (b.V[3 * (size_t)u + e] - b.V[3 * (size_t)w + e]);
        }
        worst = fmax(worst, fabs(sqrt(l / l0) - 1));
      }
    /* and it turns with the hand: its axis leaves +z (a walk turns the hand a little) */
    const double *q0 = Y + 3 * n, *q1 = Y + 3 * (n + NB - 4);
    double ax[3] = {q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]};
    turned =
        fmax(turned, acos(fmin(1, ax[2] / sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]))));
  }
  printf("held blade: its edges within %.2g of their length, turned up to %.0f degrees\n", worst,
         turned * 180 / M_PI);
  CHECK_MSG(worst < 1e-9, "the blade's edges off their length by %g", worst);
  CHECK_MSG(turned > 2 * M_PI / 180, "the blade turned only %g degrees", turned * 180 / M_PI);
done:
  km_puppetry_free(&pb);
  km_mesh_free(&b);
  free(Y);
}

int main(void) {
  if (!mkdtemp(g_dir)) {
    perror("mkdtemp");
    return 1;
  }
  fixture fx;
  if (fixture_make(&fx)) {
    test_rest_reproduces_rest(&fx);
    test_no_posed_joints(&fx);
    test_same_as_manual_loop(&fx);
    test_retarget_only(&fx);
    test_cache_policy(&fx);
    test_forged_cache(&fx);
    test_set_rig(&fx);
    test_motion_read(&fx);
    test_spike_rejected(&fx, 30);
    test_spike_rejected(&fx, 0);
    test_root_rigid(&fx);
    test_root_heading_glitch(&fx);
    test_root_heading_short_line(&fx);
    test_root_max_turn(&fx);
    test_loose_piece(&fx);
    test_ground_quad(&fx);
    test_held_blade(&fx);
    test_stray_vertex(&fx);
  }
  fixture_free(&fx);
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
  return km_test_finish("test_puppetry");
}
