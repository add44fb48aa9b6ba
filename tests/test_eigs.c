/* km_eigs on icospheres: the Laplace-Beltrami spectrum of a sphere of radius r is
 * l(l+1)/r^2 with multiplicity 2l+1, so the 9 smallest are 0, 2/r^2 (x3), 6/r^2 (x5). */
#include "km_test.h"
#include "synth/synth.h" /* test fixtures: primitive meshes, one capture frame */

static void free_mesh(km_mesh *m) {
  free(m->V), free(m->F);
  memset(m, 0, sizeof *m);
}

static const double exact_l[9] = {0, 2, 2, 2, 6, 6, 6, 6, 6};

/* Runs km_eigs on an icosphere and checks multiplicities, M-orthonormality and residuals.
 * Returns the largest relative error of the non-zero eigenvalues. */
static double sphere_case(int subdiv, double r, double *evals_out) {
  const int k = 9;
  km_mesh m = {0};
  CHECK_OK(km_icosphere(subdiv, r, &m, KM_E));
  size_t n = m.n_vertices;
  km_sparse *L = NULL, *M = NULL;
  CHECK_OK(km_cotmatrix(&m, &L, KM_E));
  CHECK_OK(km_massmatrix(&m, KM_MASS_VORONOI, &M, KM_E));
  double ev[9], *phi = malloc(n * k * sizeof *phi);
  CHECK_OK(km_eigs(L, M, k, NULL, ev, phi, KM_E));
  for (int i = 1; i < k; ++i)
    CHECK(ev[i] >= ev[i - 1]); /* ascending */
  double scale = 1 / (r * r), err = 0;
  CHECK_MSG(fabs(ev[0]) < 1e-8 * scale, "subdiv %d: lambda0 = %g", subdiv, ev[0]);
  for (int i = 1; i < k; ++i)
    err = fmax(err, fabs(ev[i] / scale - exact_l[i]) / exact_l[i]);
  /* multiplicities: within a cluster the values agree far better than between clusters */
  double spread3 = (ev[3] - ev[1]) / ev[1], spread5 = (ev[8] - ev[4]) / ev[4];
  CHECK_MSG(spread3 < 0.02 && spread5 < 0.05, "subdiv %d: cluster spreads %g %g", subdiv, spread3,
            spread5);
  CHECK(ev[4] / ev[3] > 2.5 && ev[1] / scale > 1.5);

  /* M-orthonormal and -L phi = lambda M phi */
  double *Mphi = malloc(n * k * sizeof *Mphi), *Lphi = malloc(n * k * sizeof *Lphi);
  km_sparse_mul(M, k, phi, Mphi);
  km_sparse_mul(L, k, phi, Lphi);
  double orth = 0, res = 0;
  for (int a = 0; a < k; ++a) {
    for (int b = 0; b < k; ++b) {
      double d = 0;
      for (size_t i = 0; i < n; ++i)
        d += phi[a * n + i] * Mphi[b * n + i];
      orth = fmax(orth, fabs(d - (a == b)));
    }
    double rn = 0, mn = 0;
    for (size_t i = 0; i < n; ++i) {
      double t = -Lphi[a * n + i] - ev[a] * Mphi[a * n + i];
      rn += t * t, mn += Mphi[a * n + i] * Mphi[a * n + i];
    }
    /* relative to the scale of the operator times the M-norm */
    res = fmax(res, sqrt(rn) / (fmax(ev[a], scale) * sqrt(mn)));
  }
  CHECK_MSG(orth < 1e-8, "subdiv %d: M-orthonormality error %g", subdiv, orth);
  CHECK_MSG(res < 1e-7, "subdiv %d: relative residual %g", subdiv, res);
  if (evals_out) memcpy(evals_out, ev, sizeof ev);
  free(phi), free(Mphi), free(Lphi);
  km_sparse_free(&L);
  km_sparse_free(&M);
  free_mesh(&m);
  return err;
}

static void test_sphere_spectrum(void) {
  double e3 = sphere_case(3, 1.0, NULL);
  double ev4[9];
  double e4 = sphere_case(4, 1.0, ev4);
  double e5 = sphere_case(5, 1.0, NULL);
  printf("relative eigenvalue error: subdiv 3 %.3g, 4 %.3g, 5 %.3g\n", e3, e4, e5);
  CHECK(e4 < e3 && e5 < e4); /* converges under refinement */
  CHECK(e5 < 2e-3);
  /* radius 2: eigenvalues scale as 1/r^2 */
  double ev4r[9];
  sphere_case(4, 2.0, ev4r);
  for (int i = 1; i < 9; ++i)
    CHECK_NEAR(ev4r[i] * 4, ev4[i], 1e-8 * ev4[i]);
}

static bool cancel_at_half(double fraction, const char *stage, void *user) {
  int *calls = user;
  ++*calls;
  return fraction < 0.3;
}

static void test_options_and_errors(void) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(3, 1.0, &m, KM_E));
  km_sparse *L = NULL, *M = NULL;
  CHECK_OK(km_cotmatrix(&m, &L, KM_E));
  CHECK_OK(km_massmatrix(&m, KM_MASS_BARYCENTRIC, &M, KM_E));
  double ev[9], ev2[9];
  double *phi = malloc(m.n_vertices * 9 * sizeof *phi);
  double *phi2 = malloc(m.n_vertices * 9 * sizeof *phi2);
  /* reproducible, bit for bit */
  CHECK_OK(km_eigs(L, M, 9, NULL, ev, phi, KM_E));
  CHECK_OK(km_eigs(L, M, 9, NULL, ev2, phi2, KM_E));
  CHECK(memcmp(ev, ev2, sizeof ev) == 0 && memcmp(phi, phi2, m.n_vertices * 9 * 8) == 0);
  /* evals only, explicit options */
  km_eigs_options o = {.sigma = -0.01, .tol = 1e-12, .ncv = 30, .max_iter = 500};
  CHECK_OK(km_eigs(L, M, 4, &o, ev2, NULL, KM_E));
  for (int i = 0; i < 4; ++i)
    CHECK_NEAR(ev2[i], ev[i], 1e-8 * fmax(1, ev[i]));
  /* cancellation */
  int calls = 0;
  o = (km_eigs_options){.progress = {cancel_at_half, &calls}};
  CHECK_STATUS(km_eigs(L, M, 9, &o, ev, NULL, KM_E), KM_ERR_CANCELLED);
  CHECK(calls > 1);
  /* too few iterations */
  o = (km_eigs_options){.max_iter = 1, .tol = 1e-14};
  CHECK_STATUS(km_eigs(L, M, 9, &o, ev, NULL, KM_E), KM_ERR_NO_CONVERGENCE);
  CHECK(strstr(km_test_err.message, "converged") != NULL);
  /* a shift above the spectrum makes -L - sigma M indefinite */
  o = (km_eigs_options){.sigma = 3.0};
  CHECK_STATUS(km_eigs(L, M, 3, &o, ev, NULL, KM_E), KM_ERR_NOT_POSDEF);
  /* bad arguments */
  CHECK_STATUS(km_eigs(L, M, 0, NULL, ev, NULL, KM_E), KM_ERR_INVALID);
  o = (km_eigs_options){.ncv = 5};
  CHECK_STATUS(km_eigs(L, M, 9, &o, ev, NULL, KM_E), KM_ERR_INVALID);
  km_sparse *S = NULL;
  CHECK_OK(km_sparse_diagonal(3, (double[]){1, 1, 1}, &S, KM_E));
  CHECK_STATUS(km_eigs(L, S, 2, NULL, ev, NULL, KM_E), KM_ERR_INVALID);
  km_sparse_free(&S);
  free(phi), free(phi2);
  km_sparse_free(&L);
  km_sparse_free(&M);
  free_mesh(&m);

  /* a tiny mesh (dense path): icosphere subdiv 0 has 12 vertices; first value is 0 and the
   * next three are equal by symmetry */
  CHECK_OK(km_icosphere(0, 1.0, &m, KM_E));
  CHECK_OK(km_cotmatrix(&m, &L, KM_E));
  CHECK_OK(km_massmatrix(&m, KM_MASS_VORONOI, &M, KM_E));
  CHECK_OK(km_eigs(L, M, 4, NULL, ev, NULL, KM_E));
  CHECK(fabs(ev[0]) < 1e-10 && ev[1] > 1 && fabs(ev[3] - ev[1]) < 1e-10 * ev[1]);
  km_sparse_free(&L);
  km_sparse_free(&M);
  free_mesh(&m);
}

/* Issue 18: meshes without a spectrum are refused (KM_ERR_DEGENERATE_MESH), not answered
 * with -0 or NaN: all vertices coincident, no faces, coordinates whose areas overflow. */
static km_status eigs_of(double *V, size_t nv, int32_t *F, size_t nf, double *ev) {
  km_mesh m = {.V = V, .F = F, .n_vertices = nv, .n_faces = nf};
  km_sparse *L = NULL, *M = NULL;
  km_status s = km_cotmatrix(&m, &L, NULL);
  if (s == KM_OK) s = km_massmatrix(&m, KM_MASS_VORONOI, &M, NULL);
  if (s == KM_OK) s = km_eigs(L, M, 3, NULL, ev, NULL, KM_E);
  km_sparse_free(&L);
  km_sparse_free(&M);
  return s;
}

static void test_degenerate(void) {
  int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  double ev[3];
  double same[12] = {1, 2, 3, 1, 2, 3, 1, 2, 3, 1, 2, 3};
  km_status s = eigs_of(same, 4, F, 4, ev);
  CHECK_MSG(s != KM_OK, "coincident vertices: %s (%g %g %g)", km_status_name(s), ev[0], ev[1],
            ev[2]);
  double tet[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  s = eigs_of(tet, 4, F, 0, ev);
  CHECK_MSG(s != KM_OK, "no faces: %s", km_status_name(s));
  double huge[12] = {-1e308, -1e308, 0, 1e308, -1e308, 0, 0, 1e308, 0, 0, 0, 1e308};
  s = eigs_of(huge, 4, F, 4, ev);
  CHECK_MSG(s != KM_OK, "+-1e308 coordinates: %s", km_status_name(s));
  /* the same tetrahedron at a sane size still works */
  CHECK_OK(eigs_of(tet, 4, F, 4, ev));
}

int main(void) {
  test_degenerate();
  test_sphere_spectrum();
  test_options_and_errors();
  return km_test_finish("test_eigs");
}
