/* Puppetry rig parsing, handle selection and retargeting (paper eq. 5-7). */
#include "km_test.h"
#include "motion/motion.h"

/* A 10 x 20 grid of 0.1 m cells in the xy plane (1 m wide, 2 m tall) with a slit: the cells of
 * column 5 are missing below row 18, so the mesh has two "legs" joined at the top. Vertex
 * (i,j) has index j*11+i. */
enum { NX = 10, NY = 20, SLIT = 5 };
static int vid(int i, int j) { return j * (NX + 1) + i; }

static km_mesh legs_mesh(void) {
  km_mesh m = {0};
  m.n_vertices = (NX + 1) * (NY + 1);
  m.V = malloc(m.n_vertices * 3 * sizeof(double));
  m.F = malloc(NX * NY * 6 * sizeof(int32_t));
  for (int j = 0; j <= NY; ++j)
    for (int i = 0; i <= NX; ++i) {
      double *p = m.V + 3 * vid(i, j);
      p[0] = 0.1 * i;
      p[1] = 0.1 * j;
      p[2] = 0;
    }
  for (int j = 0; j < NY; ++j)
    for (int i = 0; i < NX; ++i) {
      if (i == SLIT && j < NY - 2) continue;
      int32_t *f = m.F + 3 * m.n_faces;
      f[0] = vid(i, j), f[1] = vid(i + 1, j), f[2] = vid(i + 1, j + 1);
      f[3] = vid(i, j), f[4] = vid(i + 1, j + 1), f[5] = vid(i, j + 1);
      m.n_faces += 2;
    }
  return m;
}

static void free_mesh(km_mesh *m) {
  free(m->V);
  free(m->F);
  memset(m, 0, sizeof *m);
}

static km_status parse(const char *json, const km_mesh *m, km_rig *rig) {
  return km_rig_parse(json, strlen(json), "puppet.rig.json", m, NULL, 0, rig, KM_E);
}

static bool has(const km_rig_handle *h, int32_t v) {
  for (size_t k = 0; k < h->n_vertices; ++k)
    if (h->vertices[k] == v) return true;
  return false;
}

static void test_rig_parse(void) {
  km_mesh m = legs_mesh();
  km_rig rig;
  char json[2048];
  snprintf(json, sizeof json,
           "{\"skeleton\":\"kinect1\", \"joints\": [1,2,3], \"skin\": {\"x\": 1},"
           " \"handles\": ["
           "  {\"name\":\"leftfoot\", \"vertex\": %d, \"radius\": 0.25},"
           "  {\"name\":\"top\", \"vertices\": [%d, %d, %d, %d]},"
           "  {\"name\":\"rightfoot\", \"center\": [0.9, 0, 0], \"radius\": 0.15}],"
           " \"map\": [{\"handle\":\"leftfoot\", \"joint\":\"FootLeft\", \"axes\":\"xz\"},"
           "          {\"handle\":\"rightfoot\", \"joint\":\"FootRight\", \"scale\": 2.5},"
           "          {\"handle\":\"rightfoot\", \"joint\":\"KneeRight\", \"axes\":\"y\"}],"
           " \"filter\": {\"smoothing\": 0, \"trend\": 0.25, \"jitter_radius\": 0.03}}",
           vid(SLIT, 0), vid(0, NY), vid(1, NY), vid(0, NY), vid(2, NY));
  CHECK_OK(parse(json, &m, &rig));
  CHECK(rig.skeleton == KM_RIG_KINECT1 && rig.n_handles == 3 && rig.n_maps == 3);
  /* Geodesic ball: the seed's own leg only, although the other leg is 0.1 m away. */
  const km_rig_handle *lf = &rig.handles[0];
  CHECK(has(lf, vid(SLIT, 0)) && has(lf, vid(SLIT - 1, 0)) && has(lf, vid(SLIT, 2)) &&
        has(lf, vid(SLIT - 2, 0)));
  CHECK(!has(lf, vid(SLIT, 3)) && !has(lf, vid(SLIT - 3, 0)));
  size_t other_leg = 0;
  for (size_t k = 0; k < lf->n_vertices; ++k)
    other_leg += m.V[3 * lf->vertices[k]] > 0.55;
  CHECK_MSG(other_leg == 0, "%zu vertices of the other leg selected", other_leg);
  bool sorted = true;
  for (size_t k = 1; k < lf->n_vertices; ++k)
    sorted &= lf->vertices[k - 1] < lf->vertices[k];
  CHECK(sorted);
  /* Explicit list, duplicates removed. */
  CHECK(rig.handles[1].n_vertices == 3 && rig.handles[1].vertices[0] == vid(0, NY));
  /* Euclidean ball: |p - (0.9,0,0)| <= 0.15 on the grid: (8..10, 0) and (8..10, 1) minus
   * corners farther than 0.15: (8,1) and (10,1) are at sqrt(0.02) = 0.141: 6 vertices. */
  CHECK_MSG(rig.handles[2].n_vertices == 6, "%zu", rig.handles[2].n_vertices);
  CHECK(rig.maps[0].handle == 0 && rig.maps[0].joint == 15 &&
        rig.maps[0].axes == (KM_AXIS_X | KM_AXIS_Z) && rig.maps[0].scale == 1.0);
  CHECK(rig.maps[1].handle == 2 && rig.maps[1].joint == 19 && rig.maps[1].scale == 2.5 &&
        rig.maps[1].axes == 7u);
  CHECK(rig.maps[2].axes == KM_AXIS_Y && rig.maps[2].joint == 17);
  CHECK(rig.filter.smoothing == KM_FILTER_ZERO && rig.filter.trend == 0.25 &&
        rig.filter.jitter_radius == 0.03 && rig.filter.prediction == 0);
  km_rig_free(&rig);
  CHECK(rig.handles == NULL && rig.n_handles == 0);

  /* The same seed as a Euclidean ball would reach across the slit. */
  snprintf(json, sizeof json,
           "{\"handles\":[{\"name\":\"h\",\"center\":[0.5,0,0],\"radius\":0.25}],\"map\":[]}");
  CHECK_OK(parse(json, &m, &rig));
  CHECK(has(&rig.handles[0], vid(SLIT + 1, 0)));
  km_rig_free(&rig);

  /* A bvh rig resolves joint names against the take's. */
  const char *names[] = {"Hips", "Head", "LeftHand"};
  const char *bvh = "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertex\":0}],"
                    "\"map\":[{\"handle\":\"h\",\"joint\":\"LeftHand\"}]}";
  CHECK_OK(km_rig_parse(bvh, strlen(bvh), "b.json", &m, names, 3, &rig, KM_E));
  CHECK(rig.skeleton == KM_RIG_BVH && rig.maps[0].joint == 2 && rig.handles[0].n_vertices == 1);
  km_rig_free(&rig);
  CHECK_STATUS(km_rig_parse(bvh, strlen(bvh), "b.json", &m, names, 2, &rig, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "LeftHand") && strstr(km_test_err.message, "b.json"));
  free_mesh(&m);
}

static void test_rig_errors(void) {
  km_mesh m = legs_mesh();
  struct {
    const char *what, *json, *expect1, *expect2;
  } cases[] = {
      {"unknown joint",
       "{\"handles\":[{\"name\":\"hand\",\"vertex\":3}],"
       "\"map\":[{\"handle\":\"hand\",\"joint\":\"HandLeftt\"}]}",
       "HandLeftt", "hand"},
      {"unknown handle",
       "{\"handles\":[{\"name\":\"hand\",\"vertex\":3}],"
       "\"map\":[{\"handle\":\"foot\",\"joint\":\"HandLeft\"}]}",
       "unknown handle 'foot'", NULL},
      {"empty handle", "{\"handles\":[{\"name\":\"far\",\"center\":[9,9,9],\"radius\":0.1}]}",
       "'far' selects no "
       "vertex",
       NULL},
      {"overlap",
       "{\"handles\":[{\"name\":\"a\",\"vertices\":[1,2,3]},{\"name\":\"b\",\"vertex\":2}]}",
       "'a' and 'b' overlap", "vertex 2"},
      {"out of range", "{\"handles\":[{\"name\":\"h\",\"vertex\":231}]}", "vertex 231 out of range",
       "'h'"},
      {"out of range in list", "{\"handles\":[{\"name\":\"h\",\"vertices\":[0,-1]}]}",
       "vertex -1 out of range", NULL},
      {"bad axes",
       "{\"handles\":[{\"name\":\"h\",\"vertex\":0}],"
       "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\",\"axes\":\"xq\"}]}",
       "axes", "'Head'"},
      {"repeated axis",
       "{\"handles\":[{\"name\":\"h\",\"vertex\":0}],"
       "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\",\"axes\":\"xx\"}]}",
       "axes", NULL},
      {"empty axes",
       "{\"handles\":[{\"name\":\"h\",\"vertex\":0}],"
       "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\",\"axes\":\"\"}]}",
       "axes", NULL},
      {"duplicate handle",
       "{\"handles\":[{\"name\":\"h\",\"vertex\":0},{\"name\":\"h\",\"vertex\":5}]}",
       "'h' is defined twice", NULL},
      {"two selectors", "{\"handles\":[{\"name\":\"h\",\"vertex\":0,\"vertices\":[1]}]}",
       "exactly one", NULL},
      {"no handles", "{\"map\":[]}", "handles", NULL},
      {"bad skeleton", "{\"skeleton\":\"kinect3\",\"handles\":[]}", "skeleton", NULL},
      {"bad filter", "{\"handles\":[{\"name\":\"h\",\"vertex\":0}],\"filter\":{\"smoothing\":1.5}}",
       "filter.smoothing", NULL},
      {"bad json", "{\"handles\": [\n{\"name\": \"h\",,}]}", "puppet.rig.json:2:", "JSON"},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
    km_rig rig;
    km_status s = parse(cases[i].json, &m, &rig);
    CHECK_MSG(s == KM_ERR_PARSE || s == KM_ERR_INVALID, "%s: %s", cases[i].what, km_status_name(s));
    CHECK_MSG(strstr(km_test_err.message, "puppet.rig.json") != NULL, "%s: %s", cases[i].what,
              km_test_err.message);
    CHECK_MSG(strstr(km_test_err.message, cases[i].expect1) != NULL, "%s: %s", cases[i].what,
              km_test_err.message);
    if (cases[i].expect2)
      CHECK_MSG(strstr(km_test_err.message, cases[i].expect2) != NULL, "%s: %s", cases[i].what,
                km_test_err.message);
    CHECK(rig.handles == NULL && rig.maps == NULL);
  }
  /* A bvh rig without joint names to resolve against. */
  km_rig rig;
  const char *bvh = "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertex\":0}]}";
  CHECK_STATUS(parse(bvh, &m, &rig), KM_ERR_INVALID);
  /* Reading from a file names the file. */
  const char *path = "test_motion_retarget_bad.json";
  FILE *f = fopen(path, "wb");
  fputs(cases[0].json, f);
  fclose(f);
  CHECK_STATUS(km_rig_read(path, &m, NULL, 0, &rig, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, path) != NULL);
  remove(path);
  free_mesh(&m);
}

/* A standing Kinect skeleton: Head at 1.6 m, feet on the floor, everything at x = z = 0. */
static void standing(double *J) {
  static const double y[KM_KINECT1_JOINTS] = {1.0, 1.1, 1.4, 1.6, 1.4, 1.2, 1.0, 0.9, 1.4, 1.2,
                                              1.0, 0.9, 1.0, 0.5, 0.1, 0.0, 1.0, 0.5, 0.1, 0.0};
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    J[3 * j] = j < 12 ? 0.1 * (j % 4) : 0.0;
    J[3 * j + 1] = y[j];
    J[3 * j + 2] = -2.0;
  }
}

static void test_retarget(void) {
  km_mesh m = legs_mesh();
  km_rig rig;
  char json[1024];
  snprintf(json, sizeof json,
           "{\"handles\":[{\"name\":\"hand\",\"vertices\":[%d]},"
           "{\"name\":\"foot\",\"vertex\":%d,\"radius\":0.15},"
           "{\"name\":\"anchor\",\"vertices\":[%d,%d]},"
           "{\"name\":\"both\",\"vertices\":[%d]}],"
           "\"map\":[{\"handle\":\"hand\",\"joint\":\"HandLeft\",\"scale\":2},"
           "{\"handle\":\"foot\",\"joint\":\"FootRight\",\"axes\":\"y\"},"
           "{\"handle\":\"both\",\"joint\":\"HandLeft\",\"axes\":\"x\"},"
           "{\"handle\":\"both\",\"joint\":\"HandRight\",\"axes\":\"z\"}]}",
           vid(0, NY), vid(8, 0), vid(5, NY), vid(6, NY), vid(10, NY));
  CHECK_OK(parse(json, &m, &rig));
  km_retarget *r = NULL;
  CHECK_STATUS(km_retarget_create(&rig, &m, 19, NULL, &r, KM_E), KM_ERR_INVALID);
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, NULL, &r, KM_E));
  CHECK(isnan(km_retarget_scale(r)));
  const double *c = km_retarget_rest_centroids(r);
  CHECK(c[0] == 0.0 && c[1] == 2.0); /* hand: one vertex */
  CHECK_NEAR(c[6], 0.55, 1e-12);     /* anchor: midpoint of two vertices */

  double Jt[KM_KINECT1_JOINTS * 3], T[4 * 3];
  /* First frame with HandRight not tracked yet. */
  standing(Jt);
  Jt[33] = Jt[34] = Jt[35] = NAN;
  km_retarget_push(r, Jt, T);
  /* Auto scale: mesh height 2 m over the stature of a skeleton whose Head-to-feet joint span
   * is 1.6 m. */
  CHECK_NEAR(km_retarget_scale(r), 2.0 / (1.6 / KM_KINECT1_SPAN_OF_STATURE), 1e-12);
  size_t moved = 0;
  for (int k = 0; k < 12; ++k)
    moved += T[k] != c[k];
  CHECK(moved == 0); /* first frame: every handle at rest */

  /* Move the left hand by (0.1, 0.2, 0.3), the right foot by (0.4, 0.5, 0.6); HandRight
   * becomes valid for the first time at a shifted place: that is its reference. */
  standing(Jt);
  Jt[3 * 7 + 0] += 0.1, Jt[3 * 7 + 1] += 0.2, Jt[3 * 7 + 2] += 0.3;
  Jt[3 * 19 + 0] += 0.4, Jt[3 * 19 + 1] += 0.5, Jt[3 * 19 + 2] += 0.6;
  Jt[3 * 11 + 2] += 0.7;
  km_retarget_push(r, Jt, T);
  const double s = 2.0 / (1.6 / KM_KINECT1_SPAN_OF_STATURE);
  CHECK_NEAR(T[0], c[0] + s * 2 * 0.1, 1e-12); /* per-map scale 2 */
  CHECK_NEAR(T[1], c[1] + s * 2 * 0.2, 1e-12);
  CHECK_NEAR(T[2], c[2] + s * 2 * 0.3, 1e-12);
  CHECK(T[3] == c[3] && T[5] == c[5]); /* foot: axes "y" zeroes x and z exactly */
  CHECK_NEAR(T[4], c[4] + s * 0.5, 1e-12);
  CHECK(T[6] == c[6] && T[7] == c[7] && T[8] == c[8]); /* anchor stays */
  /* both: x from HandLeft, z from HandRight (reference = first valid frame, so 0). */
  CHECK_NEAR(T[9], c[9] + s * 0.1, 1e-12);
  CHECK(T[10] == c[10] && T[11] == c[11]);

  /* Per-vertex targets: rest vertex + its handle's displacement. */
  size_t nv = km_retarget_vertex_count(r);
  CHECK(nv == 1 + rig.handles[1].n_vertices + 2 + 1);
  double *VT = malloc(nv * 3 * sizeof(double));
  km_retarget_vertex_targets(r, VT);
  size_t bad = 0, k = 0;
  for (size_t h = 0; h < rig.n_handles; ++h)
    for (size_t i = 0; i < rig.handles[h].n_vertices; ++i, ++k)
      for (int d = 0; d < 3; ++d)
        bad += fabs(VT[3 * k + d] - (m.V[3 * rig.handles[h].vertices[i] + d] + T[3 * h + d] -
                                     c[3 * h + d])) > 1e-12;
  CHECK(bad == 0);
  free(VT);

  /* HandRight moves in z: "both" follows in z; then HandLeft goes missing: the handles that
   * need it hold their last target, the others still move. */
  Jt[3 * 11 + 2] += 0.2;
  km_retarget_push(r, Jt, T);
  CHECK_NEAR(T[11], c[11] + s * 0.2, 1e-12);
  double held[12];
  memcpy(held, T, sizeof held);
  Jt[3 * 7] = Jt[3 * 7 + 1] = Jt[3 * 7 + 2] = NAN;
  Jt[3 * 19 + 1] += 0.1;
  Jt[3 * 11 + 2] += 0.5;
  km_retarget_push(r, Jt, T);
  CHECK(T[0] == held[0] && T[1] == held[1] && T[2] == held[2]);
  CHECK(T[9] == held[9] && T[11] == held[11]); /* "both" needs HandLeft too */
  CHECK_NEAR(T[4], c[4] + s * 0.6, 1e-12);

  /* reset: the next frame is the new reference. */
  km_retarget_reset(r);
  CHECK(isnan(km_retarget_scale(r)));
  standing(Jt);
  km_retarget_push(r, Jt, T);
  CHECK(T[0] == c[0] && T[4] == c[4]);
  km_retarget_free(&r);
  CHECK(r == NULL);

  /* Explicit scale overrides the automatic one. */
  km_retarget_options o = {.scale = 3.0};
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, &o, &r, KM_E));
  c = km_retarget_rest_centroids(r);
  standing(Jt);
  km_retarget_push(r, Jt, T);
  Jt[3 * 7 + 1] += 0.1;
  km_retarget_push(r, Jt, T);
  CHECK(km_retarget_scale(r) == 3.0);
  CHECK_NEAR(T[1], c[1] + 3.0 * 2 * 0.1, 1e-12);
  km_retarget_free(&r);
  km_retarget_free(NULL);
  km_rig_free(&rig);
  free_mesh(&m);
}

/* Real recording -> filter -> retarget: targets stay finite and move a plausible amount. */
static void test_pipeline(void) {
  char buf[1024];
  const char *path = km_test_shared("skeleton/precog_Seq1_1.csv", buf, sizeof buf);
  if (!path) return;
  km_take t;
  CHECK_OK(km_kinect_csv_read(path, &t, NULL, KM_E));
  km_mesh m = legs_mesh();
  km_rig rig;
  const char *json = "{\"handles\":[{\"name\":\"lh\",\"vertex\":220,\"radius\":0.2},"
                     "{\"name\":\"lf\",\"vertex\":2,\"radius\":0.2},"
                     "{\"name\":\"rf\",\"vertex\":8,\"radius\":0.2}],"
                     "\"map\":[{\"handle\":\"lh\",\"joint\":\"HandLeft\"},"
                     "{\"handle\":\"lf\",\"joint\":\"FootLeft\"},"
                     "{\"handle\":\"rf\",\"joint\":\"FootRight\"}],"
                     "\"filter\":{\"smoothing\":0.5,\"trend\":0.5}}";
  CHECK_OK(parse(json, &m, &rig));
  km_filter *f = NULL;
  km_retarget *r = NULL;
  CHECK_OK(km_filter_create(t.n_joints, &rig.filter, &f, KM_E));
  CHECK_OK(km_retarget_create(&rig, &m, t.n_joints, NULL, &r, KM_E));
  double J[KM_KINECT1_JOINTS * 3], T[9];
  size_t nonfinite = 0;
  double maxmove = 0;
  const double *c = km_retarget_rest_centroids(r);
  for (size_t i = 0; i < t.n_frames; ++i) {
    km_filter_push(f, t.positions + i * t.n_joints * 3, J);
    km_retarget_push(r, J, T);
    for (int k = 0; k < 9; ++k) {
      nonfinite += !isfinite(T[k]);
      maxmove = fmax(maxmove, fabs(T[k] - c[k]));
    }
  }
  CHECK(nonfinite == 0);
  CHECK(km_retarget_scale(r) > 0.8 && km_retarget_scale(r) < 2.0);
  CHECK_MSG(maxmove > 0.05 && maxmove < 4.0, "max handle move %g m", maxmove);
  km_retarget_free(&r);
  km_filter_free(&f);
  km_rig_free(&rig);
  free_mesh(&m);
  km_take_free(&t);
}

/* Issue 12: "relative_to" subtracts a root joint's motion: a whole-body walk moves no handle;
 * per entry it overrides the rig's, "" restores absolute motion; a bad name is an error. */
static void test_relative_to(void) {
  km_mesh m = legs_mesh();
  km_rig rig;
  char json[1024];
  snprintf(json, sizeof json,
           "{\"relative_to\":\"HipCenter\",\"handles\":[{\"name\":\"hand\",\"vertices\":[%d]},"
           "{\"name\":\"foot\",\"vertices\":[%d]}],"
           "\"map\":[{\"handle\":\"hand\",\"joint\":\"HandLeft\"},"
           "{\"handle\":\"foot\",\"joint\":\"FootRight\",\"relative_to\":\"\"}]}",
           vid(0, NY), vid(8, 0));
  CHECK_OK(parse(json, &m, &rig));
  CHECK(rig.n_maps == 2 && rig.maps[0].relative_to == 1 && rig.maps[1].relative_to == 0);
  km_retarget *r = NULL;
  km_retarget_options o = {.scale = 1};
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, &o, &r, KM_E));
  double J[KM_KINECT1_JOINTS * 3], T[6];
  standing(J);
  km_retarget_push(r, J, T);
  const double *c = km_retarget_rest_centroids(r);
  for (int k = 0; k < 3 * KM_KINECT1_JOINTS; k += 3)
    J[k] += 0.5;       /* the performer walks 0.5 m along x */
  J[3 * 7 + 1] += 0.1; /* and lifts the left hand 0.1 m */
  km_retarget_push(r, J, T);
  CHECK_NEAR(T[0], c[0], 1e-12); /* hand: relative to the hips, only the lift */
  CHECK_NEAR(T[1], c[1] + 0.1, 1e-12);
  CHECK_NEAR(T[3], c[3] + 0.5, 1e-12); /* foot: absolute */
  km_retarget_free(&r);
  km_rig_free(&rig);
  /* "root_motion": "rigid" takes the rig-level root and the Kinect hips as heading */
  snprintf(json, sizeof json,
           "{\"relative_to\":\"HipCenter\",\"root_motion\":\"rigid\","
           "\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
           "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\"}]}");
  CHECK_OK(parse(json, &m, &rig));
  CHECK(rig.root_rigid && rig.root == 1 && rig.heading[0] == 13 && rig.heading[1] == 17);
  km_rig_free(&rig);
  snprintf(json, sizeof json,
           "{\"root_motion\":\"rigid\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
           "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\"}]}");
  CHECK_STATUS(parse(json, &m, &rig), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "puppet.rig.json") &&
        strstr(km_test_err.message, "relative_to"));
  /* "floor": a foot pushed 0.3 m down stops at the rest floor; lifted, it moves freely */
  snprintf(json, sizeof json,
           "{\"floor\":true,\"handles\":[{\"name\":\"foot\",\"vertices\":[%d]}],"
           "\"map\":[{\"handle\":\"foot\",\"joint\":\"FootRight\"}]}",
           vid(8, 0));
  CHECK_OK(parse(json, &m, &rig));
  CHECK(rig.floor);
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, &o, &r, KM_E));
  c = km_retarget_rest_centroids(r);
  double lowest = INFINITY;
  for (size_t v = 0; v < m.n_vertices; ++v)
    lowest = fmin(lowest, m.V[3 * v + 1]);
  standing(J);
  km_retarget_push(r, J, T);
  J[3 * 19 + 1] -= 0.3;
  km_retarget_push(r, J, T);
  CHECK_NEAR(T[1], lowest, 1e-12);
  J[3 * 19 + 1] += 0.5;
  km_retarget_push(r, J, T);
  CHECK_NEAR(T[1], c[1] + 0.2, 1e-12);
  km_retarget_free(&r);
  km_rig_free(&rig);
  snprintf(json, sizeof json,
           "{\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
           "\"map\":[{\"handle\":\"h\",\"joint\":\"Head\",\"relative_to\":\"Hipz\"}]}");
  CHECK_STATUS(parse(json, &m, &rig), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "puppet.rig.json") &&
        strstr(km_test_err.message, "relative_to"));
  free_mesh(&m);
}

/* Snap easing (issue 12): a 0.6 m one-frame jump of the hand joint moves the hand handle by at
 * most max_step of the diagonal per push, keeps the direction, arrives after the expected
 * number of pushes and is counted; a step under the limit passes untouched. A bad max_step is
 * a parse error naming the key. */
static void test_max_step(void) {
  km_mesh m = legs_mesh();
  double diag = sqrt(1.0 * 1.0 + 2.0 * 2.0);
  km_rig rig;
  char json[512];
  snprintf(json, sizeof json,
           "{\"max_step\":0.02,\"handles\":[{\"name\":\"hand\",\"vertices\":[%d]},"
           "{\"name\":\"anchor\",\"vertices\":[%d]}],"
           "\"map\":[{\"handle\":\"hand\",\"joint\":\"HandLeft\"}]}",
           vid(0, NY), vid(8, 0));
  CHECK_OK(parse(json, &m, &rig));
  CHECK(rig.max_step == 0.02);
  km_retarget *r = NULL;
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, NULL, &r, KM_E));
  double Jt[KM_KINECT1_JOINTS * 3], T[2 * 3], prev[3];
  standing(Jt);
  km_retarget_push(r, Jt, T);
  const double s = km_retarget_scale(r), lim = 0.02 * diag;
  /* a small step (under the limit) is followed at once */
  Jt[3 * 7 + 1] += 0.5 * lim / s;
  km_retarget_push(r, Jt, T);
  const double *c = km_retarget_rest_centroids(r);
  CHECK_NEAR(T[1], c[1] + 0.5 * lim, 1e-12);
  CHECK(km_retarget_eased_frames(r) == 0);
  /* the snap: 0.6 m along x */
  Jt[3 * 7] += 0.6;
  double goal = c[0] + s * 0.6;
  size_t pushes = 0, worst_bad = 0;
  memcpy(prev, T, sizeof prev);
  for (int i = 0; i < 200 && fabs(T[0] - goal) > 1e-9; ++i) {
    km_retarget_push(r, Jt, T);
    ++pushes;
    double d = sqrt((T[0] - prev[0]) * (T[0] - prev[0]) + (T[1] - prev[1]) * (T[1] - prev[1]) +
                    (T[2] - prev[2]) * (T[2] - prev[2]));
    worst_bad += d > lim * (1 + 1e-9) || fabs(T[1] - prev[1]) > 1e-12;
    memcpy(prev, T, sizeof prev);
  }
  size_t expect = (size_t)ceil(s * 0.6 / lim - 1e-9);
  CHECK_MSG(pushes == expect, "arrived after %zu pushes, expected %zu", pushes, expect);
  CHECK(worst_bad == 0);
  CHECK_MSG(km_retarget_eased_frames(r) == expect - 1, "%zu eased", km_retarget_eased_frames(r));
  CHECK(T[3] == c[3] && T[4] == c[4] && T[5] == c[5]); /* the anchor stays */
  km_retarget_reset(r);
  CHECK(km_retarget_eased_frames(r) == 0);
  km_retarget_free(&r);
  km_rig_free(&rig);
  /* Under rigid root motion the root's translation counts too: the performer steps 0.6 m in
   * one frame, the hand's handle (root-relative) stays put in the root's frame, and the whole
   * mesh, carried by the root, moves at most max_step of the diagonal per push (it moved the
   * full step at once: the limit covered the handles only) and arrives. */
  snprintf(json, sizeof json,
           "{\"max_step\":0.02,\"relative_to\":\"HipCenter\",\"root_motion\":\"rigid\","
           "\"handles\":[{\"name\":\"hand\",\"vertices\":[%d]}],"
           "\"map\":[{\"handle\":\"hand\",\"joint\":\"HandLeft\"}]}",
           vid(0, NY));
  CHECK_OK(parse(json, &m, &rig));
  CHECK_OK(km_retarget_create(&rig, &m, KM_KINECT1_JOINTS, NULL, &r, KM_E));
  standing(Jt);
  km_retarget_push(r, Jt, T);
  double t[3], tprev[3];
  CHECK(km_retarget_root_transform(r, NULL, tprev, NULL));
  CHECK(tprev[0] == 0 && tprev[1] == 0 && tprev[2] == 0);
  for (int k = 0; k < 3 * KM_KINECT1_JOINTS; k += 3)
    Jt[k] += 0.6;
  pushes = worst_bad = 0;
  double far = 0;
  for (int i = 0; i < 400; ++i) {
    km_retarget_push(r, Jt, T);
    km_retarget_root_transform(r, NULL, t, NULL);
    double d = sqrt((t[0] - tprev[0]) * (t[0] - tprev[0]) + (t[1] - tprev[1]) * (t[1] - tprev[1]) +
                    (t[2] - tprev[2]) * (t[2] - tprev[2]));
    worst_bad += d > lim * (1 + 1e-9);
    far = fmax(far, d);
    memcpy(tprev, t, sizeof t);
    if (d == 0) break;
    ++pushes;
  }
  CHECK_MSG(worst_bad == 0 && pushes > 1, "the root stepped %.4f (limit %.4f) in %zu pushes", far,
            lim, pushes);
  CHECK_MSG(t[0] > 0.1 && t[1] == 0 && t[2] == 0, "the root arrived at %g %g %g", t[0], t[1], t[2]);
  CHECK(km_retarget_eased_frames(r) + 1 == pushes);
  km_retarget_free(&r);
  km_rig_free(&rig);
  /* bad values */
  const char *bad[] = {"{\"max_step\":-0.1,\"handles\":[{\"name\":\"h\",\"vertex\":0}]}",
                       "{\"max_step\":\"x\",\"handles\":[{\"name\":\"h\",\"vertex\":0}]}"};
  for (int i = 0; i < 2; ++i) {
    CHECK_STATUS(parse(bad[i], &m, &rig), KM_ERR_PARSE);
    CHECK(strstr(km_test_err.message, "max_step") != NULL);
  }
  /* "swing_limit", "bend_limit", "upper_limb_limit", "girdle_limit": degrees in [0, 180] */
  static const char *const keys[] = {"swing_limit", "bend_limit", "upper_limb_limit",
                                     "girdle_limit"};
  for (int k = 0; k < 4; ++k) {
    const char *bad_v[] = {"-1", "181", "true", "\"150\""};
    char js[160];
    for (int i = 0; i < 4; ++i) {
      snprintf(js, sizeof js, "{\"%s\":%s,\"handles\":[{\"name\":\"h\",\"vertex\":0}]}", keys[k],
               bad_v[i]);
      CHECK_STATUS(parse(js, &m, &rig), KM_ERR_PARSE);
      CHECK(strstr(km_test_err.message, keys[k]) != NULL);
    }
    snprintf(js, sizeof js, "{\"%s\":60,\"handles\":[{\"name\":\"h\",\"vertex\":0}]}", keys[k]);
    CHECK_OK(parse(js, &m, &rig));
    double got[4] = {rig.swing_limit, rig.bend_limit, rig.upper_limb_limit, rig.girdle_limit};
    for (int o = 0; o < 4; ++o)
      CHECK(got[o] == (o == k ? 60 : 0));
    km_rig_free(&rig);
  }
  /* "max_turn": degrees per second in [0, 1e5] */
  const char *bad_t[] = {"-1", "1e6", "true", "\"360\""};
  for (int i = 0; i < 4; ++i) {
    char js[160];
    snprintf(js, sizeof js, "{\"max_turn\":%s,\"handles\":[{\"name\":\"h\",\"vertex\":0}]}",
             bad_t[i]);
    CHECK_STATUS(parse(js, &m, &rig), KM_ERR_PARSE);
    CHECK(strstr(km_test_err.message, "max_turn") != NULL);
  }
  CHECK_OK(parse("{\"max_turn\":360,\"handles\":[{\"name\":\"h\",\"vertex\":0}]}", &m, &rig));
  CHECK(rig.max_turn == 360);
  km_rig_free(&rig);
  free_mesh(&m);
}

int main(void) {
  test_max_step();
  test_relative_to();
  test_rig_parse();
  test_rig_errors();
  test_retarget();
  test_pipeline();
  return km_test_finish("test_motion_retarget");
}
