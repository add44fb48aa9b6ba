/* Issue 12, handles that carry rotation: a thin two-bone bar (2 m, radius 2 cm) anchored at one
 * end, whose end handle turns 90 degrees with its bone, bends instead of shearing the end
 * (through km_puppetry, full ARAP run to convergence, and the reduced model); translation-only
 * handles (the paper's) keep the end ring's orientation and stretch it. A rotating handle also
 * turns about its bone with the joint's child (test_child_twist). */
#include "bar_fixture.h"

/* A rig over the bar's joints root, elbow, end: an anchor "base" (ring 0) and a handle `name`
 * (ring `ring`) mapped to joint `joint` with "rotate": rotate. */
static void bar_rig(char *json, size_t size, const char *name, int ring, const char *joint,
                    bool rotate) {
  int n =
      snprintf(json, size, "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"base\",\"vertices\":[");
  for (int k = 0; k < RING; ++k)
    n += snprintf(json + n, size - (size_t)n, "%s%d", k ? "," : "", k);
  n += snprintf(json + n, size - (size_t)n, "]},{\"name\":\"%s\",\"vertices\":[", name);
  for (int k = 0; k < RING; ++k)
    n += snprintf(json + n, size - (size_t)n, "%s%d", k ? "," : "", ring * RING + k);
  snprintf(json + n, size - (size_t)n,
           "]}],\"map\":[{\"handle\":\"%s\",\"joint\":\"%s\",\"rotate\":%s}]}", name, joint,
           rotate ? "true" : "false");
}

static double run(const km_mesh *m, bool rotate, km_puppetry_solver solver, double *end_ring_y) {
  char json[2048];
  bar_rig(json, sizeof json, "end", SEGS, "end", rotate);
  const char *names[3] = {"root", "elbow", "end"};
  const int32_t parents[3] = {-1, 0, 1};
  km_rig rig;
  double stretch = NAN;
  CHECK_OK(km_rig_parse(json, strlen(json), "bar.rig.json", m, names, 3, &rig, KM_E));
  CHECK(rig.n_maps == 1 && rig.maps[0].rotate == rotate);
  km_filter_options raw;
  km_puppetry_options o = bar_raw_options(parents, &raw);
  o.solver = solver;
  o.puppet.fields = 4;
  o.puppet.isolines = 10;
  o.arap.iterations = 100;
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(m, &rig, names, 3, &o, &p, NULL, KM_E));
  if (p) {
    double *V = malloc(m->n_vertices * 3 * sizeof(double));
    const double straight[9] = {0, 0, 0, 1, 0, 0, 2, 0, 0}, bent[9] = {0, 0, 0, 1, 0, 0, 1, 1, 0};
    CHECK_OK(km_puppetry_push(p, straight, V, KM_E));
    for (int f = 0; f < 20; ++f)
      CHECK_OK(km_puppetry_push(p, bent, V, KM_E));
    stretch = km_test_edge_stretch(m, V);
    /* the end ring now lies across the y axis: its vertices share y = 1 */
    double ylo = INFINITY, yhi = -INFINITY;
    for (int k = 0; k < RING; ++k) {
      ylo = fmin(ylo, V[3 * (size_t)(SEGS * RING + k) + 1]);
      yhi = fmax(yhi, V[3 * (size_t)(SEGS * RING + k) + 1]);
    }
    *end_ring_y = yhi - ylo;
    free(V);
    km_puppetry_free(&p);
  }
  km_rig_free(&rig);
  return stretch;
}

/* The twist from the child: a handle round the bar's middle, mapped to the elbow with "rotate",
 * whose bone (root -> elbow) keeps its direction while the child (elbow -> end) swings from +y
 * to +z about it: the handle turns 90 degrees about x (its swing alone is none). With the child
 * along the bone there is no turn to tell, and the handle keeps its rest orientation. */
static void test_child_twist(const km_mesh *m) {
  char json[2048];
  bar_rig(json, sizeof json, "mid", SEGS / 2, "elbow", true);
  const char *names[3] = {"root", "elbow", "end"};
  const int32_t parents[3] = {-1, 0, 1};
  km_rig rig;
  CHECK_OK(km_rig_parse(json, strlen(json), "twist.rig.json", m, names, 3, &rig, KM_E));
  km_filter_options raw;
  km_puppetry_options o = bar_raw_options(parents, &raw);
  o.solver = KM_PUPPETRY_RETARGET; /* the targets are what is tested */
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(m, &rig, names, 3, &o, &p, NULL, KM_E));
  if (p) {
    double *V = malloc(m->n_vertices * 3 * sizeof(double));
    const double up[9] = {0, 0, 0, 1, 0, 0, 1, 1, 0}, fwd[9] = {0, 0, 0, 1, 0, 0, 1, 0, 1},
                 straight[9] = {0, 0, 0, 1, 0, 0, 2, 0, 0};
    size_t nh = 0;
    const int32_t *off = NULL, *hv = NULL;
    CHECK_OK(km_puppetry_push(p, up, V, KM_E)); /* the reference: bent up */
    CHECK_OK(km_puppetry_push(p, fwd, V, KM_E));
    km_puppetry_handles(p, &nh, &off, &hv);
    const double *T = km_puppetry_vertex_targets(p);
    double err_turned = 0, err_kept = 0;
    for (int32_t i = nh == 2 ? off[1] : 0; nh == 2 && i < off[2]; ++i) {
      const double *x = m->V + 3 * (size_t)hv[i], *t = T + 3 * (size_t)i;
      double want[3] = {x[0], -x[2], x[1]}; /* turned 90 degrees about x: y -> z */
      for (int c = 0; c < 3; ++c)
        err_turned = fmax(err_turned, fabs(t[c] - want[c]));
    }
    CHECK_OK(km_puppetry_push(p, straight, V, KM_E));
    T = km_puppetry_vertex_targets(p);
    for (int32_t i = nh == 2 ? off[1] : 0; nh == 2 && i < off[2]; ++i) {
      const double *x = m->V + 3 * (size_t)hv[i], *t = T + 3 * (size_t)i;
      for (int c = 0; c < 3; ++c)
        err_kept = fmax(err_kept, fabs(t[c] - x[c]));
    }
    printf("  child twist: handle off the 90-degree turn by %.2e m; child along the bone: off "
           "its rest by %.2e m\n",
           err_turned, err_kept);
    CHECK_MSG(nh == 2 && err_turned < 1e-9, "the handle did not turn with its child (%g m off)",
              err_turned);
    CHECK_MSG(nh == 2 && err_kept < 1e-9, "a child along the bone turned the handle (%g m)",
              err_kept);
    free(V);
    km_puppetry_free(&p);
  }
  km_rig_free(&rig);
}

int main(void) {
  km_mesh m = bar();
  test_child_twist(&m);
  for (int solver = 0; solver < 2; ++solver) {
    double spread_rot, spread_tr;
    double s_rot = run(&m, true, solver ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED, &spread_rot);
    double s_tr = run(&m, false, solver ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED, &spread_tr);
    printf("  %s: edge stretch max %.4f with rotating handles, %.4f translation-only; end ring "
           "y spread %.4f vs %.4f\n",
           solver ? "full" : "reduced", s_rot, s_tr, spread_rot, spread_tr);
    /* the end ring (diameter 0.04) lies across y when it turned, along y when it did not;
     * the reduced model meets its handle targets in the least-squares sense only */
    CHECK_MSG(spread_rot < (solver ? 1e-9 : 0.5 * spread_tr),
              "the end handle did not turn (y spread %g vs %g)", spread_rot, spread_tr);
    CHECK_MSG(spread_tr > (solver ? 0.039 : 0.02), "translation-only handle turned (y spread %g)",
              spread_tr);
    CHECK_MSG(s_rot < s_tr, "rotation %g vs translation %g", s_rot, s_tr);
    /* converged full ARAP: 5.0% with rotating handles, 22% translation-only */
    if (solver)
      CHECK_MSG(s_rot <= 0.055 && s_rot < 0.3 * s_tr, "full solver: rotating handles stretch %g",
                s_rot);
  }
  free(m.V);
  free(m.F);
  return km_test_finish("test_motion_rotate");
}
