/* Laplacians, mass matrices, normals and frames on primitive and hand-made meshes. */
#include "km_test.h"
#include "synth/synth.h" /* test fixtures: primitive meshes, one capture frame */

static void free_mesh(km_mesh *m) {
  free(m->V), free(m->F);
  memset(m, 0, sizeof *m);
}

static double tri_area(const km_mesh *m, size_t f) {
  const double *a = m->V + 3 * m->F[3 * f], *b = m->V + 3 * m->F[3 * f + 1],
               *c = m->V + 3 * m->F[3 * f + 2];
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

/* Symmetric, finite, rows sum to zero (relative to the row's diagonal), diagonal <= 0. */
static void check_laplacian(const km_sparse *L, const char *what) {
  size_t n = km_sparse_rows(L);
  CHECK(km_sparse_cols(L) == n);
  const int32_t *p, *ri;
  const double *x;
  km_sparse_csc(L, &p, &ri, &x);
  double *sum = calloc(n, sizeof *sum), *mag = calloc(n, sizeof *mag);
  int asym = 0, nonfinite = 0;
  for (size_t j = 0; j < n; ++j)
    for (int32_t q = p[j]; q < p[j + 1]; ++q) {
      if (!isfinite(x[q])) ++nonfinite;
      if (km_sparse_coeff(L, j, ri[q]) != x[q]) ++asym;
      sum[j] += x[q];
      mag[j] += fabs(x[q]);
    }
  double worst = 0;
  for (size_t j = 0; j < n; ++j)
    if (mag[j] > 0) worst = fmax(worst, fabs(sum[j]) / mag[j]);
  CHECK_MSG(asym == 0, "%s: %d asymmetric entries", what, asym);
  CHECK_MSG(nonfinite == 0, "%s: %d non-finite entries", what, nonfinite);
  CHECK_MSG(worst < 1e-13, "%s: relative row sum %g", what, worst);
  free(sum), free(mag);
}

/* Mass matrices: diagonal, positive, summing to the surface area. */
static void check_mass(const km_mesh *m, const char *what) {
  double area = 0;
  for (size_t f = 0; f < m->n_faces; ++f)
    area += tri_area(m, f);
  for (int type = 0; type < 2; ++type) {
    km_sparse *M = NULL;
    CHECK_OK(km_massmatrix(m, (km_mass_type)type, &M, KM_E));
    if (!M) continue;
    CHECK(km_sparse_nnz(M) == m->n_vertices);
    double s = 0;
    int nonpos = 0;
    for (size_t v = 0; v < m->n_vertices; ++v) {
      double d = km_sparse_coeff(M, v, v);
      s += d;
      if (!(d > 0)) ++nonpos;
    }
    CHECK_MSG(nonpos == 0, "%s type %d: %d non-positive masses", what, type, nonpos);
    CHECK_MSG(fabs(s - area) <= 1e-12 * area, "%s type %d: mass %.17g vs area %.17g", what, type, s,
              area);
    km_sparse_free(&M);
  }
}

static void check_uniform(const km_mesh *m) {
  size_t n = m->n_vertices;
  km_sparse *U = NULL;
  CHECK_OK(km_uniform_laplacian(m, &U, KM_E));
  if (!U) return;
  check_laplacian(U, "uniform");
  unsigned char *adj = calloc(n * n, 1); /* dense reference: tests use small meshes */
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3; ++c) {
      int32_t a = m->F[3 * f + c], b = m->F[3 * f + (c + 1) % 3];
      if (a != b) adj[a * n + b] = adj[b * n + a] = 1;
    }
  int bad = 0;
  for (size_t i = 0; i < n; ++i) {
    int deg = 0;
    for (size_t j = 0; j < n; ++j) {
      deg += adj[i * n + j];
      if (adj[i * n + j] && km_sparse_coeff(U, i, j) != 1) ++bad;
    }
    if (km_sparse_coeff(U, i, i) != -deg) ++bad;
  }
  CHECK_MSG(bad == 0, "uniform Laplacian: %d entries differ from the adjacency", bad);
  free(adj);
  km_sparse_free(&U);
}

static void scale_mesh(km_mesh *m, double s) {
  for (size_t i = 0; i < 3 * m->n_vertices; ++i)
    m->V[i] *= s;
}

/* Laplacian checks at scale 1, 1e8 and 1e-8; cot weights must not change with scale. */
static void check_mesh(km_mesh *m, const char *what) {
  km_sparse *L0 = NULL;
  CHECK_OK(km_cotmatrix(m, &L0, KM_E));
  if (!L0) return;
  check_laplacian(L0, what);
  check_mass(m, what);
  check_uniform(m);
  const double scales[2] = {1e8, 1e-8};
  for (int s = 0; s < 2; ++s) {
    scale_mesh(m, scales[s]);
    km_sparse *L = NULL;
    CHECK_OK(km_cotmatrix(m, &L, KM_E));
    check_laplacian(L, what);
    check_mass(m, what);
    CHECK(km_sparse_nnz(L) == km_sparse_nnz(L0));
    const double *x0, *x;
    km_sparse_csc(L0, NULL, NULL, &x0);
    km_sparse_csc(L, NULL, NULL, &x);
    double worst = 0;
    for (size_t k = 0; k < km_sparse_nnz(L); ++k)
      worst = fmax(worst, fabs(x[k] - x0[k]) / fmax(1, fabs(x0[k])));
    CHECK_MSG(worst < 1e-12, "%s at scale %g: cot weights change by %g", what, scales[s], worst);
    scale_mesh(m, 1 / scales[s]);
    km_sparse_free(&L);
  }
  km_sparse_free(&L0);
}

static void test_primitives_laplacians(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(2, 1.5, &m, KM_E));
  CHECK(m.n_vertices == 162 && m.n_faces == 320);
  check_mesh(&m, "icosphere");
  free_mesh(&m);
  CHECK_OK(km_grid(6, 4, 3.0, 1.0, &m, KM_E));
  CHECK(m.n_vertices == 35 && m.n_faces == 48);
  check_mesh(&m, "grid");
  free_mesh(&m);
  CHECK_OK(km_cylinder(12, 5, 0.3, 2.0, &m, KM_E));
  CHECK(m.n_vertices == 6 * 12 + 2 && m.n_faces == 2 * 5 * 12 + 24);
  check_mesh(&m, "cylinder");
  free_mesh(&m);
  CHECK_STATUS(km_icosphere(-1, 1, &m, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_grid(0, 3, 1, 1, &m, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_cylinder(2, 3, 1, 1, &m, KM_E), KM_ERR_INVALID);
}

/* Closed and outward: every edge in exactly two faces with opposite directions, and the
 * signed volume is positive. */
static void check_closed_outward(const km_mesh *m, double expected_volume, double tol) {
  size_t n = m->n_vertices;
  int *dir = calloc(n * n, sizeof *dir); /* directed edge counts */
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3; ++c)
      dir[m->F[3 * f + c] * n + m->F[3 * f + (c + 1) % 3]]++;
  int bad = 0;
  for (size_t i = 0; i < n; ++i)
    for (size_t j = 0; j < n; ++j)
      if (dir[i * n + j] > 1 || dir[i * n + j] != dir[j * n + i]) ++bad;
  CHECK_MSG(bad == 0, "%d edges not manifold / consistently oriented", bad);
  double vol = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const double *a = m->V + 3 * m->F[3 * f], *b = m->V + 3 * m->F[3 * f + 1],
                 *c = m->V + 3 * m->F[3 * f + 2];
    vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
            a[2] * (b[0] * c[1] - b[1] * c[0])) /
           6;
  }
  CHECK_MSG(fabs(vol - expected_volume) < tol * expected_volume, "volume %g vs %g", vol,
            expected_volume);
  free(dir);
}

static void test_primitive_shapes(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(3, 2.0, &m, KM_E));
  CHECK(m.n_vertices == 642);
  double worst = 0;
  for (size_t v = 0; v < m.n_vertices; ++v)
    worst = fmax(worst, fabs(sqrt(m.V[3 * v] * m.V[3 * v] + m.V[3 * v + 1] * m.V[3 * v + 1] +
                                  m.V[3 * v + 2] * m.V[3 * v + 2]) -
                             2.0));
  CHECK(worst < 1e-14);
  check_closed_outward(&m, 4.0 / 3 * M_PI * 8, 0.03);
  free_mesh(&m);
  CHECK_OK(km_cylinder(32, 4, 0.5, 3.0, &m, KM_E));
  check_closed_outward(&m, M_PI * 0.25 * 3 * 32 / (2 * M_PI) * sin(2 * M_PI / 32), 1e-12);
  free_mesh(&m);
  CHECK_OK(km_grid(3, 2, 1.0, 1.0, &m, KM_E));
  for (size_t f = 0; f < m.n_faces; ++f) { /* faces point to +z */
    const double *a = m.V + 3 * m.F[3 * f], *b = m.V + 3 * m.F[3 * f + 1],
                 *c = m.V + 3 * m.F[3 * f + 2];
    CHECK((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0);
  }
  free_mesh(&m);
}

static void test_known_values(void) {
  /* Right isosceles triangle: cot 90 = 0, cot 45 = 1. */
  double V[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  int32_t F[3] = {0, 1, 2};
  km_mesh m = {.V = V, .F = F, .n_vertices = 3, .n_faces = 1};
  km_sparse *L = NULL;
  CHECK_OK(km_cotmatrix(&m, &L, KM_E));
  CHECK_NEAR(km_sparse_coeff(L, 0, 1), 0.5, 1e-15);
  CHECK_NEAR(km_sparse_coeff(L, 0, 2), 0.5, 1e-15);
  CHECK_NEAR(km_sparse_coeff(L, 1, 2), 0.0, 1e-15);
  CHECK_NEAR(km_sparse_coeff(L, 0, 0), -1.0, 1e-15);
  CHECK_NEAR(km_sparse_coeff(L, 1, 1), -0.5, 1e-15);
  km_sparse_free(&L);
  check_mesh(&m, "right triangle");
  /* Voronoi areas of a right triangle: 1/4 area to each acute corner, 1/2 to the right one */
  km_sparse *M = NULL;
  CHECK_OK(km_massmatrix(&m, KM_MASS_VORONOI, &M, KM_E));
  CHECK_NEAR(km_sparse_coeff(M, 0, 0), 0.25, 1e-15);
  CHECK_NEAR(km_sparse_coeff(M, 1, 1), 0.125, 1e-15);
  km_sparse_free(&M);

  /* A single obtuse triangle: the weight of the edge opposite the obtuse angle is negative,
   * the mixed area gives the obtuse corner half the area. */
  double Vo[9] = {0, 0, 0, 2, 0, 0, 1, 0.2, 0};
  km_mesh o = {.V = Vo, .F = F, .n_vertices = 3, .n_faces = 1};
  CHECK_OK(km_cotmatrix(&o, &L, KM_E));
  double cot2 = (1 * -1 + -0.2 * -0.2) / (2 * 0.2); /* at vertex 2: (v0-v2).(v1-v2)/|x| */
  CHECK_NEAR(km_sparse_coeff(L, 0, 1), 0.5 * cot2, 1e-14);
  CHECK(km_sparse_coeff(L, 0, 1) < 0);
  km_sparse_free(&L);
  CHECK_OK(km_massmatrix(&o, KM_MASS_VORONOI, &M, KM_E));
  CHECK_NEAR(km_sparse_coeff(M, 2, 2), 0.1, 1e-15);
  CHECK_NEAR(km_sparse_coeff(M, 0, 0), 0.05, 1e-15);
  km_sparse_free(&M);
  check_mesh(&o, "obtuse triangle");
}

static void test_linear_precision(void) {
  /* On a flat grid the cotangent Laplacian of f = a x + b y + c vanishes inside. */
  km_mesh m = {0};
  CHECK_OK(km_grid(7, 5, 2.0, 1.3, &m, KM_E));
  size_t n = m.n_vertices;
  /* jitter interior vertices in-plane so that this is not just the regular stencil */
  for (int j = 1; j < 5; ++j)
    for (int i = 1; i < 7; ++i) {
      double *p = m.V + 3 * (j * 8 + i);
      p[0] += 0.05 * sin(3.0 * i + j), p[1] += 0.04 * cos(2.0 * j + i);
    }
  km_sparse *L = NULL;
  CHECK_OK(km_cotmatrix(&m, &L, KM_E));
  double *f = malloc(n * sizeof *f), *Lf = malloc(n * sizeof *Lf);
  for (size_t v = 0; v < n; ++v)
    f[v] = 0.7 * m.V[3 * v] - 1.9 * m.V[3 * v + 1] + 3.0;
  km_sparse_mul(L, 1, f, Lf);
  double interior = 0, boundary = 0;
  for (int j = 0; j <= 5; ++j)
    for (int i = 0; i <= 7; ++i) {
      double r = fabs(Lf[j * 8 + i]);
      if (i == 0 || j == 0 || i == 7 || j == 5)
        boundary = fmax(boundary, r);
      else
        interior = fmax(interior, r);
    }
  CHECK_MSG(interior < 1e-12, "interior |Lf| = %g", interior);
  CHECK(boundary > 1e-3); /* boundary rows are not zero: the test can fail */
  free(f), free(Lf);
  km_sparse_free(&L);
  free_mesh(&m);
}

static void test_degenerate(void) {
  /* A 2x1 grid plus a zero-area face on collinear vertices and one with a repeated index:
   * they must contribute nothing. */
  km_mesh g = {0};
  CHECK_OK(km_grid(2, 1, 2.0, 1.0, &g, KM_E));
  km_sparse *Lg = NULL, *Ld = NULL;
  CHECK_OK(km_cotmatrix(&g, &Lg, KM_E));
  int32_t F[4 * 3 + 6];
  memcpy(F, g.F, 12 * sizeof *F);
  int32_t extra[6] = {0, 1, 2, 3, 3, 4}; /* 0,1,2 lie on y=0 */
  memcpy(F + 12, extra, sizeof extra);
  km_mesh d = {.V = g.V, .F = F, .n_vertices = g.n_vertices, .n_faces = 6};
  CHECK_OK(km_cotmatrix(&d, &Ld, KM_E));
  double worst = 0;
  for (size_t i = 0; i < d.n_vertices; ++i)
    for (size_t j = 0; j < d.n_vertices; ++j)
      worst = fmax(worst, fabs(km_sparse_coeff(Ld, i, j) - km_sparse_coeff(Lg, i, j)));
  CHECK(worst == 0);
  check_mesh(&d, "zero-area face");
  /* A sliver (nearly zero angle): clamped, finite */
  double Vs[9] = {0, 0, 0, 1, 0, 0, 0.5, 1e-9, 0};
  int32_t Fs[3] = {0, 1, 2};
  km_mesh s = {.V = Vs, .F = Fs, .n_vertices = 3, .n_faces = 1};
  km_sparse *Ls = NULL;
  CHECK_OK(km_cotmatrix(&s, &Ls, KM_E));
  check_laplacian(Ls, "sliver");
  CHECK(fabs(km_sparse_coeff(Ls, 0, 1)) <= 0.5e5);
  km_sparse_free(&Ls);
  /* out-of-range index */
  int32_t Fb[3] = {0, 1, 9};
  km_mesh b = {.V = Vs, .F = Fb, .n_vertices = 3, .n_faces = 1};
  CHECK_STATUS(km_cotmatrix(&b, &Ls, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "face 0") != NULL);
  CHECK_STATUS(km_massmatrix(&b, KM_MASS_VORONOI, &Ls, KM_E), KM_ERR_INVALID);
  /* a point cloud: zero Laplacian (diagonal only), tiny masses */
  km_mesh pc = {.V = Vs, .F = NULL, .n_vertices = 3, .n_faces = 0};
  CHECK_OK(km_cotmatrix(&pc, &Ls, KM_E));
  CHECK(km_sparse_rows(Ls) == 3 && km_sparse_coeff(Ls, 1, 1) == 0);
  km_sparse_free(&Ls);
  CHECK_OK(km_uniform_laplacian(&pc, &Ls, KM_E));
  CHECK(km_sparse_coeff(Ls, 2, 2) == 0);
  km_sparse_free(&Ls);
  /* an isolated vertex gets a tiny positive mass */
  double Vi[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5};
  km_mesh iso = {.V = Vi, .F = Fs, .n_vertices = 4, .n_faces = 1};
  km_sparse *M = NULL;
  CHECK_OK(km_massmatrix(&iso, KM_MASS_VORONOI, &M, KM_E));
  CHECK(km_sparse_coeff(M, 3, 3) > 0 && km_sparse_coeff(M, 3, 3) < 1e-9);
  km_sparse_free(&M);
  km_sparse_free(&Lg);
  km_sparse_free(&Ld);
  free_mesh(&g);
}

static void rotate(const double R[9], const double *x, double *y) {
  for (int r = 0; r < 3; ++r)
    y[r] = R[3 * r] * x[0] + R[3 * r + 1] * x[1] + R[3 * r + 2] * x[2];
}

static void test_normals_frames(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(2, 3.0, &m, KM_E));
  size_t n = m.n_vertices;
  double *N = malloc(n * 3 * sizeof *N), *fr = malloc(n * 9 * sizeof *fr);
  for (int w = 0; w < 2; ++w) {
    CHECK_OK(km_vertex_normals(&m, (km_normal_weighting)w, N, KM_E));
    double worst = 1;
    for (size_t v = 0; v < n; ++v)
      worst = fmin(worst, (N[3 * v] * m.V[3 * v] + N[3 * v + 1] * m.V[3 * v + 1] +
                           N[3 * v + 2] * m.V[3 * v + 2]) /
                              3.0);
    CHECK_MSG(worst > 0.999, "normal vs radial: min cos %g", worst);
  }
  int32_t *ref = malloc(n * sizeof *ref);
  CHECK_OK(km_frame_neighbors(&m, ref, KM_E));
  int bad_ref = 0;
  for (size_t v = 0; v < n; ++v)
    if (ref[v] < 0 || (size_t)ref[v] == v) ++bad_ref;
  CHECK(bad_ref == 0);
  CHECK_OK(km_local_frames(&m, N, ref, fr, KM_E));
  double orth = 0, handed = 1;
  for (size_t v = 0; v < n; ++v) {
    const double *a = fr + 9 * v;
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) {
        double d = a[3 * r] * a[3 * s] + a[3 * r + 1] * a[3 * s + 1] + a[3 * r + 2] * a[3 * s + 2];
        orth = fmax(orth, fabs(d - (r == s)));
      }
    double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                 a[2] * (a[3] * a[7] - a[4] * a[6]);
    handed = fmin(handed, det);
    /* t points towards the reference neighbour */
    const double *p = m.V + 3 * v, *q = m.V + 3 * ref[v];
    CHECK(a[3] * (q[0] - p[0]) + a[4] * (q[1] - p[1]) + a[5] * (q[2] - p[2]) > 0);
  }
  CHECK(orth < 1e-12);
  CHECK(handed > 1 - 1e-12);

  /* rigidly rotated (and translated) mesh: frames rotate with it */
  const double c = cos(0.7), s = sin(0.7), c2 = cos(-1.1), s2 = sin(-1.1);
  double Rz[9] = {c, -s, 0, s, c, 0, 0, 0, 1}, Rx[9] = {1, 0, 0, 0, c2, -s2, 0, s2, c2}, R[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      R[3 * i + j] = Rx[3 * i] * Rz[j] + Rx[3 * i + 1] * Rz[3 + j] + Rx[3 * i + 2] * Rz[6 + j];
  km_mesh r = {
      .V = malloc(n * 3 * sizeof(double)), .F = m.F, .n_vertices = n, .n_faces = m.n_faces};
  for (size_t v = 0; v < n; ++v) {
    rotate(R, m.V + 3 * v, r.V + 3 * v);
    r.V[3 * v] += 10, r.V[3 * v + 1] -= 4;
  }
  double *N2 = malloc(n * 3 * sizeof *N2), *fr2 = malloc(n * 9 * sizeof *fr2);
  CHECK_OK(km_vertex_normals(&r, KM_NORMALS_ANGLE, N2, KM_E));
  CHECK_OK(km_vertex_normals(&m, KM_NORMALS_ANGLE, N, KM_E));
  CHECK_OK(km_local_frames(&m, N, ref, fr, KM_E));
  CHECK_OK(km_local_frames(&r, N2, ref, fr2, KM_E));
  double worst = 0;
  for (size_t v = 0; v < n; ++v)
    for (int row = 0; row < 3; ++row) {
      double y[3];
      rotate(R, fr + 9 * v + 3 * row, y);
      for (int k = 0; k < 3; ++k)
        worst = fmax(worst, fabs(y[k] - fr2[9 * v + 3 * row + k]));
    }
  CHECK_MSG(worst < 1e-9, "rotated frames differ by %g", worst);

  /* degenerate inputs: zero normal and no reference still give an orthonormal frame */
  double Nz[3] = {0, 0, 0}, Vz[3] = {1, 2, 3}, f1[9];
  int32_t rz = -1;
  km_mesh one = {.V = Vz, .F = NULL, .n_vertices = 1, .n_faces = 0};
  CHECK_OK(km_local_frames(&one, Nz, &rz, f1, KM_E));
  CHECK_NEAR(f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2], 1, 1e-15);
  CHECK_NEAR(f1[0] * f1[3] + f1[1] * f1[4] + f1[2] * f1[5], 0, 1e-15);
  rz = 5;
  CHECK_STATUS(km_local_frames(&one, Nz, &rz, f1, KM_E), KM_ERR_INVALID);

  free(r.V), free(N2), free(fr2), free(N), free(fr), free(ref);
  free_mesh(&m);
}

int main(void) {
  test_primitives_laplacians();
  test_primitive_shapes();
  test_known_values();
  test_linear_precision();
  test_degenerate();
  test_normals_frames();
  return km_test_finish("test_laplacian");
}
