/* Eigenfield timing: cotangent Laplacian + mass matrix, CHOLMOD factor of -L - sigma M, and
 * 9 ARPACK shift-invert eigenpairs, each the median of 5 runs.
 * Usage: bench_eigen [mesh.obj] [k]  (default ../shared/data/meshes/armadillo.obj, k 9).
 * A throw-away OBJ reader ("v x y z" and "f a b c", 1-based, optional /vt/vn) keeps this
 * independent of the mesh IO module. */
#include "kinemesh.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef KM_BENCH_DEFAULT
#define KM_BENCH_DEFAULT "../shared/data/meshes/armadillo.obj"
#endif

static int read_obj(const char *path, km_mesh *m) {
  FILE *f = fopen(path, "r");
  if (!f) return -1;
  size_t cv = 1024, cf = 1024;
  m->V = malloc(cv * 3 * sizeof *m->V);
  m->F = malloc(cf * 3 * sizeof *m->F);
  m->n_vertices = m->n_faces = 0;
  char line[1024];
  while (fgets(line, sizeof line, f)) {
    if (line[0] == 'v' && line[1] == ' ') {
      if (m->n_vertices == cv) m->V = realloc(m->V, (cv *= 2) * 3 * sizeof *m->V);
      double *p = m->V + 3 * m->n_vertices++;
      if (sscanf(line + 2, "%lf %lf %lf", p, p + 1, p + 2) != 3) return -1;
    } else if (line[0] == 'f' && line[1] == ' ') {
      if (m->n_faces == cf) m->F = realloc(m->F, (cf *= 2) * 3 * sizeof *m->F);
      int32_t *t = m->F + 3 * m->n_faces++;
      char *s = line + 2;
      for (int c = 0; c < 3; ++c) {
        long v = strtol(s, &s, 10);
        while (*s && *s != ' ' && *s != '\t')
          ++s; /* skip /vt/vn */
        t[c] = (int32_t)(v - 1);
      }
    }
  }
  fclose(f);
  return 0;
}

static int cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}
static double median(double *t, int n) {
  qsort(t, (size_t)n, sizeof *t, cmp);
  return t[n / 2];
}

static void logger(km_log_level level, const char *msg, void *user) {
  if (getenv("KM_BENCH_LOG")) fprintf(stderr, "%s\n", msg);
}

int main(int argc, char **argv) {
  km_set_logger(logger, NULL);
  const char *path = argc > 1 ? argv[1] : KM_BENCH_DEFAULT;
  int k = argc > 2 ? atoi(argv[2]) : 9;
  km_mesh m = {0};
  if (read_obj(path, &m)) {
    fprintf(stderr, "cannot read %s\n", path);
    return 1;
  }
  km_error e;
  enum { R = 5 };
  double tl[R], tc[R], tf[R], te[R], evals[64];
  double *evecs = malloc(m.n_vertices * (size_t)k * sizeof *evecs);
  for (int r = 0; r < R; ++r) {
    km_sparse *L = NULL, *M = NULL, *K = NULL;
    double t0 = km_seconds();
    if (km_cotmatrix(&m, &L, &e)) goto fail;
    double t0m = km_seconds();
    if (km_massmatrix(&m, KM_MASS_VORONOI, &M, &e)) goto fail;
    double t1 = km_seconds();
    tc[r] = t0m - t0;
    /* the factor step of km_eigs, timed alone (km_eigs repeats it) */
    km_cholesky *c = NULL;
    if (km_sparse_add(-1, L, 1e-6, M, &K, &e) || km_cholesky_analyze(K, &c, &e) ||
        km_cholesky_factorize(c, K, &e))
      goto fail;
    double t2 = km_seconds();
    km_cholesky_free(&c);
    km_sparse_free(&K);
    double t3 = km_seconds();
    if (km_eigs(L, M, k, NULL, evals, evecs, &e)) goto fail;
    double t4 = km_seconds();
    tl[r] = t1 - t0, tf[r] = t2 - t1, te[r] = t4 - t3;
    km_sparse_free(&L);
    km_sparse_free(&M);
  }
  printf("%s: %zu vertices, %zu faces, k = %d\n", path, m.n_vertices, m.n_faces, k);
  printf("eigenvalues:");
  for (int i = 0; i < k; ++i)
    printf(" %.6g", evals[i]);
  double ml = median(tl, R), mf = median(tf, R), me = median(te, R);
  printf("\ncotmatrix %.1f ms | ", 1e3 * median(tc, R));
  printf("laplacian+mass %.1f ms | factor %.1f ms | km_eigs (factor+arpack) %.1f ms -> "
         "arpack ~%.1f ms | total %.1f ms (median of %d)\n",
         1e3 * ml, 1e3 * mf, 1e3 * me, 1e3 * (me - mf), 1e3 * (ml + me), R);
  free(evecs);
  free(m.V);
  free(m.F);
  return 0;
fail:
  fprintf(stderr, "error: %s\n", e.message);
  return 1;
}
