/* Point clouds to mesh animation: readers, Horn, capture simulator, registration steps,
 * temporal filter, pipeline. Small meshes only (the file runs in well under a minute with
 * sanitizers). */
#include "km_test.h"
#include "synth/synth.h" /* test fixtures: primitive meshes, one capture frame */
#include "recon/recon.h"
#include "recon_plot.h"

#include <unistd.h>

static void rot_axis(const double *axis, double ang, double *R) {
  double x = axis[0], y = axis[1], z = axis[2], l = sqrt(x * x + y * y + z * z);
  x /= l, y /= l, z /= l;
  double c = cos(ang), s = sin(ang), C = 1 - c;
  double M[9] = {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
                 y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
                 z * x * C - y * s, z * y * C + x * s, c + z * z * C};
  memcpy(R, M, sizeof M);
}

static void test_horn(void) {
  double A[30], B[30], R[9], Rt[9], t[3], s;
  rot_axis((double[]){0.3, -1, 0.5}, 1.1, Rt);
  double tt[3] = {0.4, -2, 7}, st = 1.7;
  for (int i = 0; i < 10; ++i) {
    A[3 * i] = sin(i * 1.3), A[3 * i + 1] = cos(i * 0.7) * 2, A[3 * i + 2] = i * 0.1 - 0.3;
    for (int r = 0; r < 3; ++r)
      B[3 * i + r] = st * (Rt[3 * r] * A[3 * i] + Rt[3 * r + 1] * A[3 * i + 1] +
                           Rt[3 * r + 2] * A[3 * i + 2]) +
                     tt[r];
  }
  CHECK_OK(km_similarity_fit(A, B, NULL, 10, true, &s, R, t, KM_E));
  CHECK_NEAR(s, st, 1e-9);
  for (int k = 0; k < 9; ++k)
    CHECK_NEAR(R[k], Rt[k], 1e-9);
  for (int k = 0; k < 3; ++k)
    CHECK_NEAR(t[k], tt[k], 1e-9);
  /* without scale: rotation still exact when the true scale is 1 */
  for (int i = 0; i < 10; ++i)
    for (int r = 0; r < 3; ++r)
      B[3 * i + r] = Rt[3 * r] * A[3 * i] + Rt[3 * r + 1] * A[3 * i + 1] +
                     Rt[3 * r + 2] * A[3 * i + 2] + tt[r];
  CHECK_OK(km_similarity_fit(A, B, NULL, 10, false, NULL, R, t, KM_E));
  for (int k = 0; k < 9; ++k)
    CHECK_NEAR(R[k], Rt[k], 1e-9);
  /* collinear points cannot fix a rotation */
  for (int i = 0; i < 5; ++i)
    A[3 * i] = i, A[3 * i + 1] = 2 * i, A[3 * i + 2] = 0;
  CHECK_STATUS(km_similarity_fit(A, A, NULL, 5, true, &s, R, t, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_STATUS(km_similarity_fit(A, B, NULL, 2, true, &s, R, t, KM_E), KM_ERR_INVALID);
}

/* ---------------------------------------------------------------- readers */

static void test_readers(void) {
  km_points p = {0};
  const double want[3][3] = {{0.5, 1.25, -2}, {1, 2, 3}, {-1.5, 0, 0.125}};
  CHECK_OK(km_points_read(KM_TEST_DATA "/recon_ascii.pcd", &p, KM_E));
  CHECK(p.n == 3 && p.dropped_nan == 1);
  for (int i = 0; i < 3 && p.n == 3; ++i)
    for (int a = 0; a < 3; ++a)
      CHECK_NEAR(p.P[3 * i + a], want[i][a], 1e-7);
  km_points_free(&p);
  CHECK_OK(km_points_read(KM_TEST_DATA "/recon_binary.pcd", &p, KM_E));
  CHECK(p.n == 3 && p.dropped_nan == 0);
  for (int i = 0; i < 3 && p.n == 3; ++i)
    for (int a = 0; a < 3; ++a)
      CHECK_NEAR(p.P[3 * i + a], want[i][a], 1e-7);
  km_points_free(&p);
  CHECK_OK(km_points_read(KM_TEST_DATA "/recon_points.xyz", &p, KM_E));
  CHECK(p.n == 3 && p.dropped_nan == 1);
  for (int i = 0; i < 3 && p.n == 3; ++i)
    for (int a = 0; a < 3; ++a)
      CHECK_NEAR(p.P[3 * i + a], want[i][a], 1e-12);
  km_points_free(&p);
  CHECK(p.P == NULL);

  /* every truncated prefix of the binary PCD fails cleanly or reads fewer points */
  char *data;
  size_t size;
  CHECK_OK(km__read_file(KM_TEST_DATA "/recon_binary.pcd", &data, &size, KM_E));
  for (size_t n = 0; n < size; ++n) {
    km_status s = km_points_parse(data, n, "cut.pcd", &p, KM_E);
    CHECK(s != KM_OK);
    km_points_free(&p);
  }
  CHECK_STATUS(km_points_parse(data, size - 5, "trunc.pcd", &p, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "trunc.pcd") && strstr(km_test_err.message, "byte"));
  free(data);

  const char *bad_num = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                        "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n1 zz 3\n";
  CHECK_STATUS(km_points_parse(bad_num, strlen(bad_num), "bad.pcd", &p, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "bad.pcd:11") != NULL);
  const char *short_ascii = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 3\nDATA ascii\n1 2 3\n";
  CHECK_STATUS(km_points_parse(short_ascii, strlen(short_ascii), "s.pcd", &p, KM_E), KM_ERR_PARSE);
  const char *no_z = "FIELDS x y\nSIZE 4 4\nTYPE F F\nPOINTS 1\nDATA ascii\n1 2\n";
  CHECK_STATUS(km_points_parse(no_z, strlen(no_z), "noz.pcd", &p, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "x y z") != NULL);
  const char *huge = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 999999999999\nDATA binary\n";
  CHECK_STATUS(km_points_parse(huge, strlen(huge), "huge.pcd", &p, KM_E), KM_ERR_PARSE);
  const char *lzf = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n";
  CHECK_STATUS(km_points_parse(lzf, strlen(lzf), "c.pcd", &p, KM_E), KM_ERR_UNSUPPORTED);
  const char *bad_xyz = "1 2 3\n4 5\n";
  CHECK_STATUS(km_points_parse(bad_xyz, strlen(bad_xyz), "bad.xyz", &p, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "bad.xyz:2") != NULL);
  CHECK_STATUS(km_points_parse("x", 1, "a.foo", &p, KM_E), KM_ERR_UNSUPPORTED);

  /* PLY clouds drop and count NaN/inf rows like PCD and XYZ, keeping the finite points in
   * file order; the mesh reader still refuses the same bytes, naming file and line/byte */
  const char *ply_nan = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\n"
                        "property float y\nproperty float z\nend_header\n"
                        "0.5 1.25 -2\nnan 0 0\n1 2 3\n0 -inf 1\n4 NaN 5\n-1.5 0 0.125\n";
  CHECK_OK(km_points_parse(ply_nan, strlen(ply_nan), "nan.ply", &p, KM_E));
  CHECK_MSG(p.n == 3 && p.dropped_nan == 3, "ascii PLY: %zu points, %zu dropped", p.n,
            p.dropped_nan);
  for (int i = 0; i < 3 && p.n == 3; ++i)
    for (int a = 0; a < 3; ++a)
      CHECK_NEAR(p.P[3 * i + a], want[i][a], 1e-12);
  km_points_free(&p);
  km_mesh mm = {0};
  CHECK_STATUS(km_mesh_parse(ply_nan, strlen(ply_nan), KM_FORMAT_PLY, "nan.ply", &mm, KM_E),
               KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "nan.ply:9:") != NULL, "%s", km_test_err.message);
  km_mesh_free(&mm);
  /* a word that is no number is still an error for a cloud */
  const char *ply_bad = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                        "property float y\nproperty float z\nend_header\n1 2 3\n1 nanx 3\n";
  CHECK_STATUS(km_points_parse(ply_bad, strlen(ply_bad), "bad.ply", &p, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "bad.ply:9:") != NULL, "%s", km_test_err.message);
  {
    /* binary little endian: x y z float plus an ignored uchar, rows 1 and 3 with a NaN */
    const char *hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "property uchar intensity\nend_header\n";
    size_t hl = strlen(hdr), rec = 13;
    unsigned char buf[512];
    memcpy(buf, hdr, hl);
    const float rows[5][3] = {
        {0.5f, 1.25f, -2}, {1, NAN, 0}, {1, 2, 3}, {NAN, NAN, NAN}, {-1.5f, 0, 0.125f}};
    for (int i = 0; i < 5; ++i) {
      memcpy(buf + hl + rec * (size_t)i, rows[i], 12); /* little-endian hosts, as PCD */
      buf[hl + rec * (size_t)i + 12] = (unsigned char)(7 * i);
    }
    CHECK_OK(km_points_parse(buf, hl + 5 * rec, "nan_le.ply", &p, KM_E));
    CHECK_MSG(p.n == 3 && p.dropped_nan == 2, "binary PLY: %zu points, %zu dropped", p.n,
              p.dropped_nan);
    for (int i = 0; i < 3 && p.n == 3; ++i)
      for (int a = 0; a < 3; ++a)
        CHECK_NEAR(p.P[3 * i + a], want[i][a], 1e-7);
    km_points_free(&p);
    CHECK_STATUS(km_mesh_parse(buf, hl + 5 * rec, KM_FORMAT_PLY, "nan_le.ply", &mm, KM_E),
                 KM_ERR_PARSE);
    char where[64];
    snprintf(where, sizeof where, "nan_le.ply: byte %zu:", hl + rec + 4);
    CHECK_MSG(strstr(km_test_err.message, where) != NULL, "%s (wanted %s)", km_test_err.message,
              where);
    km_mesh_free(&mm);
  }

  /* real capture data (D-FAUST points, binary PLY in metres), when the checkout has it */
  char shared[512];
  if (km_test_shared("pointclouds/dfaust_50002_light_hopping_loose/00000080.ply", shared,
                     sizeof shared)) {
    CHECK_OK(km_points_read(shared, &p, KM_E));
    CHECK(p.n == 100000 && p.dropped_nan == 0);
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < p.n; ++i)
      lo = fmin(lo, p.P[3 * i + 1]), hi = fmax(hi, p.P[3 * i + 1]);
    CHECK_MSG(hi - lo > 1.5 && hi - lo < 2.0, "a standing person, metres: height %.3f", hi - lo);
    km_points_free(&p);
  }

  /* PLY round trip through the point writer, and frame listing in name order */
  char dir[] = "/tmp/km_test_recon_XXXXXX";
  CHECK(mkdtemp(dir) != NULL);
  char path[256];
  double P[6] = {1, 2, 3, -0.5, 0.25, 8};
  snprintf(path, sizeof path, "%s/b.ply", dir);
  CHECK_OK(km_points_write_ply(path, P, 2, KM_E));
  snprintf(path, sizeof path, "%s/a.ply", dir);
  CHECK_OK(km_points_write_ply(path, P, 1, KM_E));
  CHECK_OK(km_points_read(path, &p, KM_E));
  CHECK(p.n == 1);
  km_points_free(&p);
  char **paths = NULL;
  size_t n = 0;
  CHECK_OK(km_point_frames_list(dir, &paths, &n, KM_E));
  CHECK(n == 2 && strstr(paths[0], "a.ply") && strstr(paths[1], "b.ply"));
  km_paths_free(&paths, n);
  snprintf(path, sizeof path, "%s/b*.ply", dir);
  CHECK_OK(km_point_frames_list(path, &paths, &n, KM_E));
  CHECK(n == 1);
  km_paths_free(&paths, n);
  snprintf(path, sizeof path, "%s/none*.pcd", dir);
  CHECK_STATUS(km_point_frames_list(path, &paths, &n, KM_E), KM_ERR_IO);
  snprintf(path, sizeof path, "rm -rf '%s'", dir);
  CHECK(system(path) == 0);
}

/* ---------------------------------------------------------------- capture simulator */

static km_mesh box_mesh(double sx, double sy, double sz) {
  static const int32_t F[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                2, 3, 7, 2, 7, 6, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3};
  km_mesh m = {0};
  km_mesh_alloc(8, 12, &m, NULL);
  for (int i = 0; i < 8; ++i) {
    m.V[3 * i] = (i == 1 || i == 2 || i == 5 || i == 6) ? sx / 2 : -sx / 2;
    m.V[3 * i + 1] = (i >= 4) ? sy / 2 : -sy / 2;
    m.V[3 * i + 2] = (i == 2 || i == 3 || i == 6 || i == 7) ? sz / 2 : -sz / 2;
  }
  memcpy(m.F, F, sizeof F);
  return m;
}

static void test_capture(void) {
  km_mesh box = box_mesh(0.4, 1.0, 0.3);
  km__surface *surf = NULL;
  CHECK_OK(km__surface_create(box.V, 8, box.F, 12, &surf, KM_E));
  km_capture_options o = {.cameras = 4, .points_per_frame = 6000, .noise_mm = -1, .height = 1.5};
  km_points p = {0};
  CHECK_OK(km_capture_frame(&box, &o, 0, &p, KM_E));
  CHECK(p.n > 4000 && p.n < 8000);
  int32_t *tri = malloc(p.n * sizeof *tri);
  double *d = malloc(p.n * sizeof *d);
  km__surface_closest(surf, p.P, p.n, 0, tri, NULL, d);
  double dmax = 0;
  size_t bottom = 0, top = 0;
  for (size_t i = 0; i < p.n; ++i) {
    dmax = d[i] > dmax ? d[i] : dmax;
    if (p.P[3 * i + 1] < -0.5 + 1e-4) ++bottom;
    if (p.P[3 * i + 1] > 0.5 - 1e-4) ++top;
  }
  CHECK_MSG(dmax < 1e-5, "noise-free points lie on the surface: %g", dmax);
  /* cameras above the centre see the top, never the bottom: an occlusion hole */
  CHECK(bottom == 0);
  CHECK(top > 50);
  free(tri), free(d);
  km_points_free(&p);

  /* noise: the normal component of the offset has the requested sigma */
  o.noise_mm = 3;
  CHECK_OK(km_capture_frame(&box, &o, 1, &p, KM_E));
  tri = malloc(p.n * sizeof *tri);
  double *bary = malloc(p.n * 3 * sizeof *bary);
  double ss = 0;
  size_t cnt = 0;
  km__surface_closest(surf, p.P, p.n, 0, tri, bary, NULL);
  for (size_t i = 0; i < p.n; ++i) {
    /* offset along the normal of the face the point belongs to, away from edges */
    const double *q = p.P + 3 * i, half[3] = {0.2, 0.5, 0.15};
    int face = 0;
    for (int a = 1; a < 3; ++a)
      if (fabs(q[a]) / half[a] > fabs(q[face]) / half[face]) face = a;
    bool edge = false;
    for (int a = 0; a < 3; ++a)
      if (a != face && fabs(q[a]) > half[a] - 0.02) edge = true;
    if (edge) continue;
    double off = fabs(q[face]) - half[face];
    ss += off * off, ++cnt;
  }
  double sigma = sqrt(ss / (double)cnt) * 1e3;
  CHECK_MSG(fabs(sigma - 3) < 0.3, "measured sigma %.3f mm", sigma);
  km_points_free(&p);
  /* deterministic for a seed and frame */
  km_points p2 = {0};
  CHECK_OK(km_capture_frame(&box, &o, 1, &p, KM_E));
  CHECK_OK(km_capture_frame(&box, &o, 1, &p2, KM_E));
  CHECK(p.n == p2.n && !memcmp(p.P, p2.P, p.n * 3 * sizeof(double)));
  km_points_free(&p);
  km_points_free(&p2);
  free(tri), free(bary);
  km__surface_free(&surf);
  km_mesh_free(&box);
}

/* ---------------------------------------------------------------- registration */

/* A two-bone "limb": cylinder along +z, joints at the base, middle and tip. */
static void limb(km_character *c) {
  memset(c, 0, sizeof *c);
  km_cylinder(24, 16, 0.08, 1.0, &c->mesh, NULL);
  size_t nv = c->mesh.n_vertices;
  c->skeleton.n_joints = 3;
  c->skeleton.names = calloc(3, sizeof(char *));
  c->skeleton.names[0] = strdup("base");
  c->skeleton.names[1] = strdup("mid");
  c->skeleton.names[2] = strdup("tip");
  c->skeleton.parents = malloc(3 * sizeof(int32_t));
  c->skeleton.parents[0] = -1, c->skeleton.parents[1] = 0, c->skeleton.parents[2] = 1;
  c->skeleton.rest = calloc(9, sizeof(double));
  c->skeleton.rest[5] = 0.5, c->skeleton.rest[8] = 1.0;
  c->skin.n_vertices = nv;
  c->skin.joints = malloc(nv * 4 * sizeof(int32_t));
  c->skin.weights = calloc(nv * 4, sizeof(double));
  for (size_t i = 0; i < nv; ++i) {
    double z = c->mesh.V[3 * i + 2];
    double w = z < 0.45 ? 0 : z > 0.55 ? 1 : (z - 0.45) / 0.1;
    int32_t *j = c->skin.joints + 4 * i;
    j[0] = 0, j[1] = 1, j[2] = -1, j[3] = -1;
    c->skin.weights[4 * i] = 1 - w, c->skin.weights[4 * i + 1] = w;
  }
}

/* vertices and face centroids of a mesh as a point cloud */
static double *sample(const km_mesh *m, const double *V, size_t *n) {
  *n = m->n_vertices + m->n_faces;
  double *P = malloc(*n * 3 * sizeof *P);
  memcpy(P, V, m->n_vertices * 3 * sizeof *P);
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int a = 0; a < 3; ++a)
      P[3 * (m->n_vertices + f) + a] =
          (V[3 * m->F[3 * f] + a] + V[3 * m->F[3 * f + 1] + a] + V[3 * m->F[3 * f + 2] + a]) / 3;
  return P;
}

/* Four correspondences on the limb (positions V of its nv vertices): both ends, two between;
 * returns their vertex ids. */
static const int32_t *limb_features(const double *V, size_t nv, km_recon_feature feat[4]) {
  static int32_t fv[4];
  const int32_t ids[4] = {0, 30, 200, (int32_t)nv - 1};
  for (int k = 0; k < 4; ++k) {
    fv[k] = feat[k].vertex = ids[k];
    memcpy(feat[k].point, V + 3 * (size_t)ids[k], 3 * sizeof(double));
  }
  return fv;
}

static void test_registration(void) {
  km_character c;
  limb(&c);
  size_t nv = c.mesh.n_vertices;
  /* frame 0: the limb under a similarity; its own surface is reachable exactly */
  double R[9], s = 1.1, t[3] = {0.2, -0.1, 0.3};
  rot_axis((double[]){1, 0.2, 0}, 0.35, R);
  double *V0 = malloc(nv * 3 * sizeof *V0);
  for (size_t i = 0; i < nv; ++i)
    for (int r = 0; r < 3; ++r)
      V0[3 * i + r] = s * (R[3 * r] * c.mesh.V[3 * i] + R[3 * r + 1] * c.mesh.V[3 * i + 1] +
                           R[3 * r + 2] * c.mesh.V[3 * i + 2]) +
                      t[r];
  size_t n;
  double *P = sample(&c.mesh, V0, &n);
  km_recon_feature feat[4];
  const int32_t *fv = limb_features(V0, nv, feat);
  km_recon_options o = {.coarse_points = 300};
  km_recon *r = NULL;
  CHECK_OK(km_recon_create(&c, &o, &r, KM_E));
  km_recon_frame_stats st;
  CHECK_OK(km_recon_first_frame(r, P, n, feat, 4, &st, KM_E));
  CHECK_MSG(st.mean_mm < 0.3, "first frame mean %.4f mm", st.mean_mm);
  CHECK_MSG(st.max_mm < 2, "first frame max %.4f mm", st.max_mm);
  const double *S = km_recon_surface(r);
  /* the features pin the vertices they name (the cylinder lets the others slide) */
  double dv = 0;
  for (int k = 0; k < 4; ++k)
    for (int a = 0; a < 3; ++a)
      dv = fmax(dv, fabs(S[3 * (size_t)fv[k] + a] - V0[3 * (size_t)fv[k] + a]));
  CHECK_MSG(dv < 0.003, "feature vertices within 3 mm of their points: %g", dv);
  free(P);

  /* frame 1: the upper bone bends 14 degrees about the middle joint (rigid limb motion) */
  double T[36] = {0}, Rb[9], mid[3], tip[3];
  const double *J = km_recon_joints(r);
  memcpy(mid, J + 3, sizeof mid);
  memcpy(tip, J + 6, sizeof tip);
  double axis[3];
  double bone[3] = {tip[0] - mid[0], tip[1] - mid[1], tip[2] - mid[2]};
  double side[3] = {1, 0, 0};
  axis[0] = bone[1] * side[2] - bone[2] * side[1];
  axis[1] = bone[2] * side[0] - bone[0] * side[2];
  axis[2] = bone[0] * side[1] - bone[1] * side[0];
  rot_axis(axis, 0.25, Rb);
  for (int j = 0; j < 3; ++j) {
    double *Tj = T + 12 * j;
    if (j == 0) {
      Tj[0] = Tj[5] = Tj[10] = 1;
      continue;
    }
    double Rm[3];
    for (int a = 0; a < 3; ++a)
      Rm[a] = Rb[3 * a] * mid[0] + Rb[3 * a + 1] * mid[1] + Rb[3 * a + 2] * mid[2];
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b)
        Tj[4 * a + b] = Rb[3 * a + b];
      Tj[4 * a + 3] = mid[a] - Rm[a];
    }
  }
  double tip_true[3];
  for (int a = 0; a < 3; ++a)
    tip_true[a] = T[24 + 4 * a] * tip[0] + T[24 + 4 * a + 1] * tip[1] + T[24 + 4 * a + 2] * tip[2] +
                  T[24 + 4 * a + 3];
  double *base = malloc(nv * 3 * sizeof *base), *V1 = malloc(nv * 3 * sizeof *V1);
  memcpy(base, S, nv * 3 * sizeof *base);
  CHECK_OK(km_lbs(base, nv, &c.skin, T, 3, V1, KM_E));
  P = sample(&c.mesh, V1, &n);
  CHECK_OK(km_recon_next_frame(r, P, n, &st, KM_E));
  CHECK(st.status == KM_OK);
  J = km_recon_joints(r);
  double e_tip =
      sqrt(pow(J[6] - tip_true[0], 2) + pow(J[7] - tip_true[1], 2) + pow(J[8] - tip_true[2], 2));
  CHECK_MSG(e_tip < 0.01, "tip joint recovered within 1 cm: %.4f m", e_tip);
  CHECK_MSG(st.mean_mm < 0.5, "frame 1 mean %.4f mm", st.mean_mm);
  const double *G = km_recon_global(r);
  double dg = 0;
  for (size_t i = 0; i < nv; ++i)
    for (int a = 0; a < 3; ++a)
      dg = fmax(dg, fabs(G[3 * i + a] - V1[3 * i + a]));
  CHECK_MSG(dg < 0.01, "LBS surface from the estimated skeleton within 1 cm: %g", dg);

  /* the same pose with 5% gross outliers (0.3-0.6 m off) and the upper bone's points gone:
   * the outliers are down-weighted and the unseen bone keeps its pose */
  double tip_before[3];
  memcpy(tip_before, J + 6, sizeof tip_before);
  {
    size_t m = 0;
    double *Q = malloc(n * 3 * sizeof *Q);
    for (size_t i = 0; i < n; ++i) {
      const double *q = P + 3 * i;
      double along =
          (q[0] - mid[0]) * bone[0] + (q[1] - mid[1]) * bone[1] + (q[2] - mid[2]) * bone[2];
      if (along > 0) continue; /* above the middle joint: hidden */
      memcpy(Q + 3 * m, q, 3 * sizeof(double));
      if (i % 20 == 0) Q[3 * m] += 0.3 + 0.3 * (double)(i % 7) / 7.0;
      ++m;
    }
    CHECK_OK(km_recon_next_frame(r, Q, m, &st, KM_E));
    CHECK(st.status == KM_OK);
    J = km_recon_joints(r);
    /* the prediction continues the last frame's angular velocity about the middle joint */
    double pred[3], dt[3] = {tip_before[0] - J[3], tip_before[1] - J[4], tip_before[2] - J[5]};
    for (int a = 0; a < 3; ++a)
      pred[a] = J[3 + a] + Rb[3 * a] * dt[0] + Rb[3 * a + 1] * dt[1] + Rb[3 * a + 2] * dt[2];
    double e = sqrt(pow(J[6] - pred[0], 2) + pow(J[7] - pred[1], 2) + pow(J[8] - pred[2], 2));
    /* (within a few degrees: the blend zone below the middle joint still sees points) */
    CHECK_MSG(e < 0.06, "unseen bone follows the prediction: tip %.4f m away", e);
    CHECK_MSG(sqrt(pow(J[6] - tip_before[0], 2) + pow(J[7] - tip_before[1], 2) +
                   pow(J[8] - tip_before[2], 2)) > 0.08,
              "and does not stay where it was");
    /* lower half still on its points despite the outliers */
    const double *S2 = km_recon_surface(r);
    double dlow = 0;
    size_t nlow = 0;
    for (size_t i = 0; i < nv; ++i)
      if (c.mesh.V[3 * i + 2] < 0.4) {
        dlow += sqrt(pow(S2[3 * i] - V1[3 * i], 2) + pow(S2[3 * i + 1] - V1[3 * i + 1], 2) +
                     pow(S2[3 * i + 2] - V1[3 * i + 2], 2));
        ++nlow;
      }
    dlow /= (double)nlow;
    CHECK_MSG(dlow < 0.002, "outliers ignored: lower half within %.4f m on average", dlow);
    free(Q);
  }
  free(P);

  /* a frame without points is carried by the skeleton prediction, not an error */
  CHECK_OK(km_recon_next_frame(r, NULL, 0, &st, KM_E));
  CHECK(st.status != KM_OK);
  CHECK(isfinite(km_recon_surface(r)[0]));
  km_recon_free(&r);
  CHECK(r == NULL);
  km_recon_free(&r);

  /* invalid input */
  km_recon_feature badf = {.vertex = (int32_t)nv};
  CHECK_OK(km_recon_create(&c, NULL, &r, KM_E));
  P = sample(&c.mesh, c.mesh.V, &n);
  CHECK_STATUS(km_recon_first_frame(r, P, n, &badf, 1, &st, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_recon_next_frame(NULL, P, n, &st, KM_E), KM_ERR_INVALID);
  free(P);
  km_recon_free(&r);
  /* a skin that moves no vertex (every row without influence) is refused, not divided by */
  km_skin keep = c.skin, none = {.n_vertices = nv};
  none.joints = malloc(4 * nv * sizeof *none.joints);
  none.weights = calloc(4 * nv, sizeof *none.weights);
  if (none.joints && none.weights) {
    for (size_t i = 0; i < 4 * nv; ++i)
      none.joints[i] = -1;
    c.skin = none;
    CHECK_STATUS(km_recon_create(&c, NULL, &r, KM_E), KM_ERR_INVALID);
    CHECK(r == NULL && strstr(km_test_err.message, "no vertex an influence"));
    c.skin = keep;
  }
  free(none.joints), free(none.weights);
  free(base), free(V1), free(V0);
  km_character_free(&c);
}

/* Point-to-surface distances of P to mesh (V, F of m): mean and max. */
static void surface_error(const km_mesh *m, const double *V, const double *P, size_t n,
                          double *mean, double *mx) {
  km__surface *s = NULL;
  *mean = *mx = INFINITY;
  CHECK_OK(km__surface_create(V, m->n_vertices, m->F, m->n_faces, &s, KM_E));
  if (!s) return;
  int32_t *tri = malloc(n * sizeof *tri);
  double *d = malloc(n * sizeof *d);
  km__surface_closest(s, P, n, 0, tri, NULL, d);
  *mean = *mx = 0;
  for (size_t i = 0; i < n; ++i)
    *mean += d[i] / (double)n, *mx = fmax(*mx, d[i]);
  free(tri), free(d);
  km__surface_free(&s);
}

/* The affine registration step alone (w_d E_d + w_f E_f + w_s E_s, Gauss-Newton on a CHOLMOD
 * factor; km__recon_affine_register runs it as the first frame does). A mesh registered to
 * points of its own surface (vertices and face centroids) from the identity stays exactly on
 * them: any inconsistency between the assembled normal matrix and right-hand side, the
 * barycentric Jacobians, the centring or the block placement would move it off. */
static void test_affine_self(void) {
  km_character c;
  limb(&c);
  size_t nv = c.mesh.n_vertices, n;
  double *P = sample(&c.mesh, c.mesh.V, &n);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < nv; ++i)
    for (int a = 0; a < 3; ++a)
      lo[a] = fmin(lo[a], c.mesh.V[3 * i + a]), hi[a] = fmax(hi[a], c.mesh.V[3 * i + a]);
  double diag = sqrt(pow(hi[0] - lo[0], 2) + pow(hi[1] - lo[1], 2) + pow(hi[2] - lo[2], 2));
  km_recon_options o = {.coarse_points = 300};
  km_recon *r = NULL;
  CHECK_OK(km_recon_create(&c, &o, &r, KM_E));
  double mean, mx, dv = 0;
  /* data + smoothness (measured: max 1.5e-15 x the bbox diagonal) */
  CHECK_OK(km__recon_affine_register(r, c.mesh.V, P, n, NULL, 0, 12, KM_E));
  surface_error(&c.mesh, km_recon_surface(r), P, n, &mean, &mx);
  printf("affine registration to its own points: max %.3g x bbox diagonal\n", mx / diag);
  CHECK_MSG(mx < 1e-9 * diag, "max %.3g m", mx);
  for (size_t i = 0; i < 3 * nv; ++i)
    dv = fmax(dv, fabs(km_recon_surface(r)[i] - c.mesh.V[i]));
  CHECK_MSG(dv < 1e-9 * diag, "vertices stay: %.3g m", dv);
  /* with the feature term too: features at their own vertices */
  km_recon_feature feat[4];
  const int32_t fv[4] = {0, 30, 200, (int32_t)nv - 1};
  for (int k = 0; k < 4; ++k) {
    feat[k].vertex = fv[k];
    memcpy(feat[k].point, c.mesh.V + 3 * (size_t)fv[k], 3 * sizeof(double));
  }
  CHECK_OK(km__recon_affine_register(r, c.mesh.V, P, n, feat, 4, 12, KM_E));
  surface_error(&c.mesh, km_recon_surface(r), P, n, &mean, &mx);
  CHECK_MSG(mx < 1e-9 * diag, "with features: max %.3g m", mx);

  /* From a perturbed template (3 degrees about a tilted axis, 2-3% anisotropic scale, 5 mm
   * shift) the step does NOT reach zero: the first solves fit the closest-point
   * correspondences almost exactly by bending the per-vertex maps, those correspondences
   * then stop changing, and the tangential error they carry stays (measured: mean 18.8 ->
   * 0.84 mm, 4.5%, max 56 -> 19 mm at a cap rim; 40 rounds do no better). The bound below records
   * that behaviour so a change to it shows. */
  double R[9], *Vb = malloc(nv * 3 * sizeof *Vb);
  rot_axis((double[]){0.3, 1, 0.2}, 3 * M_PI / 180, R);
  const double sc[3] = {1.03, 0.98, 1.02}, t[3] = {0.005, -0.003, 0.004};
  for (size_t i = 0; i < nv; ++i)
    for (int a = 0; a < 3; ++a) {
      double x = t[a];
      for (int b = 0; b < 3; ++b)
        x += R[3 * a + b] * sc[b] * c.mesh.V[3 * i + b];
      Vb[3 * i + a] = x;
    }
  double mean0, mx0;
  surface_error(&c.mesh, Vb, P, n, &mean0, &mx0);
  CHECK_OK(km__recon_affine_register(r, Vb, P, n, NULL, 0, 12, KM_E));
  surface_error(&c.mesh, km_recon_surface(r), P, n, &mean, &mx);
  printf("affine registration from a perturbed template: mean %.3g -> %.3g mm, max %.3g -> %.3g "
         "mm\n",
         mean0 * 1e3, mean * 1e3, mx0 * 1e3, mx * 1e3);
  CHECK_MSG(mean0 > 0.01, "the perturbation moves the surface: mean %.4f m", mean0);
  CHECK_MSG(mean < 0.1 * mean0, "mean %.3g m from %.3g m", mean, mean0);
  free(Vb);
  km_recon_free(&r);
  free(P);
  km_character_free(&c);
}

/* ---------------------------------------------------------------- global alignment */

static void rot_y(double *p, size_t n, double ang) {
  double c = cos(ang), s = sin(ang);
  for (size_t i = 0; i < n; ++i) {
    double x = p[3 * i], z = p[3 * i + 2];
    p[3 * i] = c * x + s * z, p[3 * i + 2] = -s * x + c * z;
  }
}

/* No correspondences, and the subject turned 125 degrees about the vertical (between two of
 * the tried headings): the simulated capture is reconstructed onto the truth. Before the
 * heading search the template was only centred and scaled, facing +z, and the nonrigid
 * stages wrapped it around the points the wrong way round: measured on this capture, 7.4
 * and 6.5 mm from the true surface on average, and its landmarks 0.56 m from the subject's.
 * Now: 2.0 mm, and 28 mm (the two bodies differ, so their landmarks do too). */
static void test_turned_subject(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 4000, .seed = 7, .girth = 1.08, .height = 1.72};
  km_character_options to = {.target_vertices = 2000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  km_take take = {0};
  CHECK_OK(km_motion_generate(&subj.skeleton, KM_MOTION_WAVE, 2, &take, KM_E));
  double turn = 125 * M_PI / 180;
  rot_y(subj.mesh.V, subj.mesh.n_vertices, turn);
  rot_y(subj.skeleton.rest, subj.skeleton.n_joints, turn);
  rot_y(take.positions, take.n_frames * take.n_joints, turn);
  char dir[] = "/tmp/km_test_recon_XXXXXX";
  CHECK(mkdtemp(dir) != NULL);
  km_capture_options co = {.cameras = 8, .points_per_frame = 12000, .noise_mm = 2, .seed = 3};
  CHECK_OK(km_capture_simulate(&subj, &take, &co, dir, KM_E));
  char **paths = NULL, out[300], truth_path[300];
  size_t n = 0;
  CHECK_OK(km_point_frames_list(dir, &paths, &n, KM_E)); /* directory mode: frames only */
  CHECK(n == take.n_frames);
  snprintf(out, sizeof out, "%s/out.pc2", dir);
  snprintf(truth_path, sizeof truth_path, "%s/truth.pc2", dir);
  km_recon_report rep = {0};
  CHECK_OK(km_reconstruct((const char *const *)paths, n, &tmpl, NULL, 0, NULL, out, &rep, KM_E));
  const km_recon_init *in = &rep.init;
  printf("turned subject: heading %.0f deg kept, rotation %.1f deg (turned 125), residual %.1f "
         "mm rigid, %.1f mm posed, %zu landmarks\n",
         in->yaw_deg, in->rotation_deg, in->rigid_residual_mm, in->residual_mm, in->landmarks);
  CHECK(in->correspondences == 0 && in->yaw_candidates >= 8);
  /* ICP's rotation; the skeletal step turns the root further (measured 116 deg) */
  CHECK_MSG(fabs(in->rotation_deg - 125) < 20, "rotation %.1f deg", in->rotation_deg);
  double *truth = NULL, *rec = NULL;
  km_anim_info ti = {0}, ri = {0};
  CHECK_OK(km_pc2_read(truth_path, &truth, &ti, KM_E));
  CHECK_OK(km_pc2_read(out, &rec, &ri, KM_E));
  size_t nv = tmpl.mesh.n_vertices, sv = subj.mesh.n_vertices;
  for (size_t f = 0; truth && rec && f < ri.frames && f < ti.frames; ++f) {
    /* reconstructed vertices to the true surface, and landmark to same-named landmark */
    double mean, mx, lm = 0;
    km__surface *ts = NULL;
    CHECK_OK(km__surface_create(truth + f * sv * 3, sv, subj.mesh.F, subj.mesh.n_faces, &ts, KM_E));
    int32_t *tri = malloc(nv * sizeof *tri);
    double *d = malloc(nv * sizeof *d);
    km__surface_closest(ts, rec + f * nv * 3, nv, 0, tri, NULL, d);
    mean = mx = 0;
    for (size_t i = 0; i < nv; ++i)
      mean += d[i] / (double)nv, mx = fmax(mx, d[i]);
    for (int l = 0; l < KM_CHARACTER_LANDMARKS; ++l) {
      const double *q = truth + f * sv * 3 + 3 * (size_t)subj.landmarks[l].vertex;
      const double *x = rec + f * nv * 3 + 3 * (size_t)tmpl.landmarks[l].vertex;
      lm += sqrt(pow(q[0] - x[0], 2) + pow(q[1] - x[1], 2) + pow(q[2] - x[2], 2)) /
            KM_CHARACTER_LANDMARKS;
    }
    printf("turned subject, frame %zu: to the true surface mean %.2f max %.1f mm, landmarks "
           "%.1f mm off\n",
           f, mean * 1e3, mx * 1e3, lm * 1e3);
    CHECK_MSG(mean < 0.003, "frame %zu: mean %.2f mm to the true surface", f, mean * 1e3);
    CHECK_MSG(lm < 0.05, "frame %zu: landmarks %.1f mm off", f, lm * 1e3);
    free(tri), free(d);
    km__surface_free(&ts);
  }
  CHECK(ri.frames == take.n_frames);
  free(truth), free(rec);
  km_recon_report_free(&rep);
  km_paths_free(&paths, n);
  char cmd[400];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  CHECK(system(cmd) == 0);
  km_take_free(&take);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

/* ---------------------------------------------------------------- filter and pipeline */

static void test_filter(void) {
  enum { NF = 9, NV = 5 };
  double ref[NF * NV * 3], glob[NF * NV * 3], out[NF * NV * 3];
  for (int f = 0; f < NF; ++f)
    for (int i = 0; i < NV * 3; ++i) {
      glob[f * NV * 3 + i] = 0.1 * f + 0.01 * i;                 /* global motion moves */
      ref[f * NV * 3 + i] = glob[f * NV * 3 + i] + 0.3 * sin(i); /* constant local motion */
    }
  CHECK_OK(km_local_motion_filter(NF, NV, ref, glob, 2, 1, out, KM_E));
  double d = 0;
  for (int k = 0; k < NF * NV * 3; ++k)
    d = fmax(d, fabs(out[k] - ref[k]));
  CHECK_MSG(d < 1e-12, "constant local motion unchanged: %g", d);
  /* a constant sequence stays constant, in place too */
  for (int k = 0; k < NF * NV * 3; ++k)
    ref[k] = glob[k] = 0.5 + 0.1 * (k % 7);
  CHECK_OK(km_local_motion_filter(NF, NV, ref, glob, 2, 1, ref, KM_E));
  d = 0;
  for (int k = 0; k < NF * NV * 3; ++k)
    d = fmax(d, fabs(ref[k] - glob[k]));
  CHECK(d < 1e-12);
  /* alternating jitter in the local motion is reduced, the global motion is not touched */
  for (int f = 0; f < NF; ++f)
    for (int i = 0; i < NV * 3; ++i) {
      glob[f * NV * 3 + i] = 0.2 * f;
      ref[f * NV * 3 + i] = glob[f * NV * 3 + i] + ((f & 1) ? 0.01 : -0.01);
    }
  CHECK_OK(km_local_motion_filter(NF, NV, ref, glob, 2, 1, out, KM_E));
  double jb = 0, ja = 0;
  for (int f = 1; f + 1 < NF; ++f) {
    int k = f * NV * 3;
    jb += fabs(ref[k + NV * 3] - 2 * ref[k] + ref[k - NV * 3]);
    ja += fabs(out[k + NV * 3] - 2 * out[k] + out[k - NV * 3]);
  }
  CHECK(ja < 0.3 * jb);
  CHECK_STATUS(km_local_motion_filter(NF, NV, ref, glob, 100, 1, out, KM_E), KM_ERR_INVALID);
}

static bool cancel_after_two(double f, const char *stage, void *u) {
  (void)f, (void)stage;
  return ++*(int *)u < 3;
}

static void test_pipeline(void) {
  km_character c;
  limb(&c);
  size_t nv = c.mesh.n_vertices;
  char dir[] = "/tmp/km_test_recon_XXXXXX";
  CHECK(mkdtemp(dir) != NULL);
  enum { NF = 5 };
  char *paths[NF];
  double *V = malloc(nv * 3 * sizeof *V);
  for (int f = 0; f < NF; ++f) {
    for (size_t i = 0; i < nv; ++i) {
      memcpy(V + 3 * i, c.mesh.V + 3 * i, 3 * sizeof(double));
      V[3 * i] += 0.01 * f; /* slides along x */
    }
    size_t n;
    double *P = sample(&c.mesh, V, &n);
    paths[f] = malloc(300);
    snprintf(paths[f], 300, "%s/f%02d.ply", dir, f);
    CHECK_OK(km_points_write_ply(paths[f], P, n, KM_E));
    free(P);
  }
  km_recon_feature feat[3] = {{0, {0}}, {100, {0}}, {(int32_t)nv - 1, {0}}};
  for (int k = 0; k < 3; ++k)
    memcpy(feat[k].point, c.mesh.V + 3 * (size_t)feat[k].vertex, 3 * sizeof(double));
  char out[300], json[300], png[300];
  snprintf(out, sizeof out, "%s/out.pc2", dir);
  snprintf(json, sizeof json, "%s/report.json", dir);
  snprintf(png, sizeof png, "%s/errors.png", dir);
  km_recon_report rep = {0};
  km_recon_options o = {.coarse_points = 300};
  CHECK_OK(km_reconstruct((const char *const *)paths, NF, &c, feat, 3, &o, out, &rep, KM_E));
  CHECK(rep.n_frames == NF && rep.n_joints == 3 && rep.failed_frames == 0);
  for (int f = 0; f < NF; ++f) {
    CHECK(rep.frames[f].index == (size_t)f);
    CHECK_MSG(rep.frames[f].mean_mm < 1.0, "frame %d mean %.3f mm", f, rep.frames[f].mean_mm);
    /* root joint follows the slide */
    CHECK_NEAR(rep.joints[f * 9 + 0], 0.01 * f, 0.003);
  }
  km_anim_info info;
  CHECK_OK(km_anim_info_read(out, &info, KM_E));
  CHECK(info.frames == NF && info.vertices == nv);
  CHECK_OK(km_recon_report_write_json(json, &rep, KM_E));
  char *text;
  size_t size;
  CHECK_OK(km__read_file(json, &text, &size, KM_E));
  CHECK(strstr(text, "\"kinemesh-recon-report\"") && strstr(text, "\"mean_mm\""));
  free(text);
  if (system("command -v gnuplot >/dev/null 2>&1") == 0) {
    CHECK_OK(km_recon_report_plot(png, &rep, KM_E));
    struct stat stt;
    CHECK(stat(png, &stt) == 0 && stt.st_size > 1000);
  }
  km_recon_report_free(&rep);
  /* cancelling keeps the frames already finished */
  int calls = 0;
  o.progress = (km_progress){cancel_after_two, &calls};
  CHECK_STATUS(km_reconstruct((const char *const *)paths, NF, &c, feat, 3, &o, out, &rep, KM_E),
               KM_ERR_CANCELLED);
  CHECK_OK(km_anim_info_read(out, &info, KM_E));
  CHECK(info.frames == 3);
  km_recon_report_free(&rep);
  /* a missing frame file in the middle is reported and carried, the run completes */
  o.progress = (km_progress){0};
  snprintf(paths[2], 300, "%s/missing.ply", dir);
  CHECK_OK(km_reconstruct((const char *const *)paths, NF, &c, feat, 3, &o, out, &rep, KM_E));
  CHECK(rep.n_frames == NF && rep.failed_frames == 1 && rep.frames[2].status == KM_ERR_IO);
  /* the read error survives the skeleton carry, file name and all */
  CHECK_MSG(strstr(rep.frames[2].message, "missing.ply") != NULL, "frame 2: '%s'",
            rep.frames[2].message);
  CHECK(rep.frames[1].message[0] == '\0' && rep.frames[3].message[0] == '\0');
  km_recon_report_free(&rep);
  for (int f = 0; f < NF; ++f)
    free(paths[f]);
  free(V);
  char cmd[400];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  CHECK(system(cmd) == 0);
  km_character_free(&c);
}

/* Issue 18: duplicate points. 200k copies of one point (a sensor's no-return pixels) made
 * the kNN quadratic (minutes); copies are now grouped, so this runs in well under a second
 * and a copy's neighbours are its copies. Exact zeros are dropped by the readers and counted. */
static void test_duplicates(void) {
  const size_t dup = 200000, other = 1000, n = dup + other;
  double *P = malloc(n * 3 * sizeof *P);
  for (size_t i = 0; i < dup; ++i)
    P[3 * i] = 0.25, P[3 * i + 1] = 1, P[3 * i + 2] = -0.5;
  for (size_t i = 0; i < other; ++i) {
    double t = (double)i / (double)other * 6.283185307179586;
    P[3 * (dup + i)] = cos(t), P[3 * (dup + i) + 1] = sin(t), P[3 * (dup + i) + 2] = 0.1 * t;
  }
  const int k = 8;
  int32_t *idx = malloc(n * (size_t)k * sizeof *idx);
  CHECK_OK(km__knn(P, n, k, idx, KM_E));
  bool copies = true, valid = true, near = true;
  for (size_t i = 0; i < dup; i += 997)
    for (int j = 0; j < k; ++j)
      copies &= idx[(size_t)k * i + j] >= 0 && (size_t)idx[(size_t)k * i + j] < dup;
  /* the distinct points get their true neighbours: brute force on a few */
  for (size_t i = dup; i < n; i += 97) {
    double worst = 0;
    for (int j = 0; j < k; ++j) {
      int32_t q = idx[(size_t)k * i + j];
      valid &= q >= 0 && (size_t)q < n;
      if (q < 0 || (size_t)q >= n) continue;
      double d[3] = {P[3 * q] - P[3 * i], P[3 * q + 1] - P[3 * i + 1], P[3 * q + 2] - P[3 * i + 2]};
      worst = fmax(worst, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    int closer = 0;
    for (size_t q = dup; q < n; ++q) {
      double d[3] = {P[3 * q] - P[3 * i], P[3 * q + 1] - P[3 * i + 1], P[3 * q + 2] - P[3 * i + 2]};
      closer += d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < worst * (1 - 1e-9);
    }
    near &= closer < k; /* no more than k-1 points strictly closer than the k-th found */
  }
  CHECK_MSG(copies, "a copy's neighbours are copies");
  CHECK(valid);
  CHECK_MSG(near, "distinct points get their k nearest");
  /* the nearest-point index answers with a copy too */
  km__point_index *ix = NULL;
  CHECK_OK(km__point_index_create(P, n, &ix, KM_E));
  double q[6] = {0.25, 1.01, -0.5, 1, 0, 0};
  int32_t id[2];
  double dist[2];
  if (ix) km__point_index_nearest(ix, q, 2, 0, id, dist);
  CHECK(ix && id[0] >= 0 && (size_t)id[0] < dup && fabs(dist[0] - 0.01) < 1e-9);
  CHECK(ix && id[1] == (int32_t)dup && dist[1] < 1e-12);
  km__point_index_free(&ix);
  free(idx);
  free(P);

  const char xyz[] = "0 0 0\n1 2 3\n0 0 0\nnan 0 0\n0.0 -0 0e5\n0 0 1\n";
  km_points p = {0};
  CHECK_OK(km_points_parse(xyz, sizeof xyz - 1, "zeros.xyz", &p, KM_E));
  CHECK_MSG(p.n == 2 && p.dropped_zero == 3 && p.dropped_nan == 1, "%zu points, %zu zeros, %zu nan",
            p.n, p.dropped_zero, p.dropped_nan);
  km_points_free(&p);
}

/* A template split at a texture seam (the limb's middle ring: the faces above use copies of
 * its vertices, appended after the file's, with the same skin), as a game character's glTF
 * is. Registered and tracked, every copy stays exactly on its vertex (the seam stays shut)
 * and the limb comes out as the unsplit one does. Before the copies were tied and joined, each
 * side followed its own points and the seam opened (2.1 cm on a gen character split at its
 * waist, 40 frames of gen capture). */
static double dist3(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

static void test_seam_split(void) {
  km_character c, sc;
  limb(&c);
  size_t n = c.mesh.n_vertices, segs = 24, ring = 8;
  double zr = c.mesh.V[3 * ring * segs + 2];
  CHECK_MSG(fabs(zr - 0.5) < 1e-9 && fabs(c.mesh.V[3 * (ring * segs + segs - 1) + 2] - 0.5) < 1e-9,
            "ring %zu at z = %g", ring, zr);
  limb(&sc);
  km_mesh_free(&sc.mesh);
  CHECK_OK(km_mesh_alloc(n + segs, c.mesh.n_faces, &sc.mesh, KM_E));
  memcpy(sc.mesh.V, c.mesh.V, 3 * n * sizeof(double));
  memcpy(sc.mesh.V + 3 * n, c.mesh.V + 3 * ring * segs, 3 * segs * sizeof(double));
  memcpy(sc.mesh.F, c.mesh.F, 3 * c.mesh.n_faces * sizeof(int32_t));
  for (size_t f = 0; f < c.mesh.n_faces; ++f) {
    const int32_t *t = c.mesh.F + 3 * f;
    double zc = (c.mesh.V[3 * t[0] + 2] + c.mesh.V[3 * t[1] + 2] + c.mesh.V[3 * t[2] + 2]) / 3;
    for (int k = 0; k < 3 && zc > zr; ++k)
      if ((size_t)t[k] / segs == ring) sc.mesh.F[3 * f + k] = (int32_t)(n + (size_t)t[k] % segs);
  }
  sc.skin.n_vertices = n + segs;
  sc.skin.joints = realloc(sc.skin.joints, (n + segs) * 4 * sizeof(int32_t));
  sc.skin.weights = realloc(sc.skin.weights, (n + segs) * 4 * sizeof(double));
  memcpy(sc.skin.joints + 4 * n, c.skin.joints + 4 * ring * segs, 4 * segs * sizeof(int32_t));
  memcpy(sc.skin.weights + 4 * n, c.skin.weights + 4 * ring * segs, 4 * segs * sizeof(double));
  km_mesh_info info;
  CHECK_OK(km_mesh_info_compute(&sc.mesh, &info, KM_E));
  CHECK_MSG(info.components == 2 && info.seam_vertices == 2 * segs, "split: %zu pieces, %zu seam",
            info.components, info.seam_vertices);

  /* frame 0: the limb turned and moved; frame 1: its upper bone bent 20 degrees about the
   * middle joint; points sampled from the whole limb's surface */
  double R[9], t0[3] = {0.2, -0.1, 0.3};
  rot_axis((double[]){1, 0.2, 0}, 0.35, R);
  double *V0 = malloc(n * 3 * sizeof *V0), *V1 = malloc(n * 3 * sizeof *V1);
  for (size_t i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      V0[3 * i + r] = R[3 * r] * c.mesh.V[3 * i] + R[3 * r + 1] * c.mesh.V[3 * i + 1] +
                      R[3 * r + 2] * c.mesh.V[3 * i + 2] + t0[r];
  double Rb[9], mid[3];
  rot_axis((double[]){1, 0, 0}, 20 * 3.14159265358979 / 180, Rb);
  for (int r = 0; r < 3; ++r)
    mid[r] = R[3 * r + 2] * 0.5 + t0[r];
  for (size_t i = 0; i < n; ++i) {
    double w = c.skin.weights[4 * i + 1], d[3], q[3];
    for (int r = 0; r < 3; ++r)
      d[r] = V0[3 * i + r] - mid[r];
    for (int r = 0; r < 3; ++r) {
      q[r] = mid[r] + Rb[3 * r] * d[0] + Rb[3 * r + 1] * d[1] + Rb[3 * r + 2] * d[2];
      V1[3 * i + r] = (1 - w) * V0[3 * i + r] + w * q[r];
    }
  }
  size_t n0, n1;
  double *P0 = sample(&c.mesh, V0, &n0), *P1 = sample(&c.mesh, V1, &n1);
  km_recon_feature feat[4];
  limb_features(V0, n, feat);
  km_recon_options o = {.coarse_points = 300};
  km_recon *rw = NULL, *rs = NULL;
  CHECK_OK(km_recon_create(&c, &o, &rw, KM_E));
  CHECK_OK(km_recon_create(&sc, &o, &rs, KM_E));
  double gap = 0, dj = 0, dmean = 0;
  for (int f = 0; f < 3 && rw && rs; ++f) {
    const double *P = f ? P1 : P0;
    size_t np = f ? n1 : n0;
    km_recon_frame_stats sw, ss;
    if (f == 0) {
      CHECK_OK(km_recon_first_frame(rw, P, np, feat, 4, &sw, KM_E));
      CHECK_OK(km_recon_first_frame(rs, P, np, feat, 4, &ss, KM_E));
    } else {
      CHECK_OK(km_recon_next_frame(rw, P, np, &sw, KM_E));
      CHECK_OK(km_recon_next_frame(rs, P, np, &ss, KM_E));
    }
    const double *Ss = km_recon_surface(rs), *Jw = km_recon_joints(rw), *Js = km_recon_joints(rs);
    for (size_t k = 0; k < segs; ++k)
      gap = fmax(gap, dist3(Ss + 3 * (n + k), Ss + 3 * (ring * segs + k)));
    for (size_t j = 0; j < 3; ++j)
      dj = fmax(dj, dist3(Jw + 3 * j, Js + 3 * j));
    dmean = fmax(dmean, fabs(ss.mean_mm - sw.mean_mm));
  }
  /* (the vertices themselves may differ by a centimetre at the free end: a cylinder slides
   * along itself, and the skeletal step counts a copy as a vertex of its own) */
  printf("seam split: copies %.3g m apart; against the whole limb joints within %.2g m, mean "
         "point error within %.3f mm\n",
         gap, dj, dmean);
  CHECK_MSG(gap == 0, "the seam opened by %g m", gap);
  CHECK_MSG(dj < 0.002, "the split limb's joints are %g m from the whole one's", dj);
  CHECK_MSG(dmean < 0.05, "the split limb's mean point error is %g mm from the whole one's", dmean);
  km_recon_free(&rw);
  km_recon_free(&rs);
  free(P0), free(P1), free(V0), free(V1);
  km_character_free(&c);
  km_character_free(&sc);
}

int main(void) {
  test_duplicates();
  test_horn();
  test_readers();
  test_capture();
  test_registration();
  test_seam_split();
  test_affine_self();
  test_turned_subject();
  test_filter();
  test_pipeline();
  return km_test_finish("test_recon");
}
