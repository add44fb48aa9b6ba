/* Smallest eigenpairs of the generalised problem -L phi = lambda M phi.
 *
 * ARPACK dsaupd/dseupd in mode 3 (shift-invert, bmat = 'G', which = "LM"): OP = K^-1 M with
 * K = -L - sigma M factorised once by CHOLMOD, so every Lanczos step is one triangular solve
 * pair. The eigenvalues of OP are 1/(lambda - sigma); with sigma below the spectrum the
 * largest of them belong to the smallest lambda, and the Lanczos basis is M-orthonormal, so
 * the returned eigenvectors are too.
 *
 * ARPACK keeps its state in Fortran SAVE variables (process-global), so the reverse
 * communication loop is serialised by a mutex: concurrent km_eigs calls are safe, they just
 * take turns in that loop. */
#include "core/core.h"
#include "linalg/linalg.h"

#include <arpack.h>
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

static pthread_mutex_t arpack_lock = PTHREAD_MUTEX_INITIALIZER;

/* splitmix64: a fixed-seed start vector makes results reproducible run to run. */
static uint64_t splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/* Sorts pairs ascending by value (k is small: insertion sort) and fixes each vector's sign so
 * that its largest-magnitude entry is positive (a deterministic choice among +-phi). */
static void finish_pairs(size_t n, int k, double *vals, double *vecs, double *tmp) {
  for (int a = 1; a < k; ++a) {
    double v = vals[a];
    if (vecs) memcpy(tmp, vecs + (size_t)a * n, n * sizeof *tmp);
    int b = a - 1;
    while (b >= 0 && vals[b] > v) {
      vals[b + 1] = vals[b];
      if (vecs) memcpy(vecs + (size_t)(b + 1) * n, vecs + (size_t)b * n, n * sizeof *tmp);
      --b;
    }
    vals[b + 1] = v;
    if (vecs) memcpy(vecs + (size_t)(b + 1) * n, tmp, n * sizeof *tmp);
  }
  if (!vecs) return;
  for (int a = 0; a < k; ++a) {
    double *x = vecs + (size_t)a * n, big = 0;
    for (size_t i = 0; i < n; ++i)
      if (fabs(x[i]) > fabs(big)) big = x[i];
    if (big < 0)
      for (size_t i = 0; i < n; ++i)
        x[i] = -x[i];
  }
}

/* Tiny problems (the Krylov space would be the whole space): dense LAPACK dsygvd. */
static km_status eigs_dense(const km_sparse *L, const km_sparse *M, int k, double *evals,
                            double *evecs, km_error *err) {
  size_t n = km_sparse_rows(L);
  double *A = km__calloc(n * n, sizeof *A), *B = km__calloc(n * n, sizeof *B);
  double *w = km__malloc(n, sizeof *w);
  km_status s = KM_OK;
  if (!A || !B || !w) {
    s = km__fail(err, KM_ERR_NOMEM, "km_eigs: out of memory");
    goto done;
  }
  const int32_t *p, *ri;
  const double *x;
  km_sparse_csc(L, &p, &ri, &x);
  for (size_t j = 0; j < n; ++j)
    for (int32_t q = p[j]; q < p[j + 1]; ++q)
      A[j * n + (size_t)ri[q]] = -x[q];
  km_sparse_csc(M, &p, &ri, &x);
  for (size_t j = 0; j < n; ++j)
    for (int32_t q = p[j]; q < p[j + 1]; ++q)
      B[j * n + (size_t)ri[q]] = x[q];
  lapack_int info = LAPACKE_dsygvd(LAPACK_COL_MAJOR, 1, 'V', 'L', (lapack_int)n, A, (lapack_int)n,
                                   B, (lapack_int)n, w);
  if (info > (lapack_int)n) {
    s = km__fail(err, KM_ERR_NOT_POSDEF,
                 "km_eigs: M is not positive definite (LAPACK dsygvd "
                 "info %d)",
                 (int)info);
    goto done;
  }
  if (info != 0) {
    s = km__fail(err, KM_ERR_NO_CONVERGENCE, "km_eigs: LAPACK dsygvd failed (info %d)", (int)info);
    goto done;
  }
  if (evals) memcpy(evals, w, (size_t)k * sizeof *w);
  if (evecs) memcpy(evecs, A, (size_t)k * n * sizeof *A);
done:
  free(A);
  free(B);
  free(w);
  return s;
}

static double diag_sum(const km_sparse *A) {
  const int32_t *p, *ri;
  const double *x;
  km_sparse_csc(A, &p, &ri, &x);
  double s = 0;
  for (size_t j = 0; j < km_sparse_cols(A); ++j)
    for (int32_t q = p[j]; q < p[j + 1]; ++q)
      if ((size_t)ri[q] == j) s += x[q];
  return s;
}

typedef struct eig_ctx {
  size_t n;
  const km_sparse *M;
  km_cholesky *chol;
  double sigma, tol;
  int max_iter, ncv;
  const km_progress *progress;
  size_t n_op;
  double *tmp;  /* n */
  double *coef; /* nd */
  /* deflation: nd M-orthonormal vectors Phi (n x nd) and M Phi */
  const double *Phi, *MPhi;
  int nd;
} eig_ctx;

/* y <- (I - Phi Phi^T M) y */
static void deflate(const eig_ctx *c, double *y) {
  if (!c->nd) return;
  cblas_dgemv(CblasColMajor, CblasTrans, (blasint)c->n, c->nd, 1.0, c->MPhi, (blasint)c->n, y, 1,
              0.0, c->coef, 1);
  cblas_dgemv(CblasColMajor, CblasNoTrans, (blasint)c->n, c->nd, -1.0, c->Phi, (blasint)c->n,
              c->coef, 1, 1.0, y, 1);
}

/* One ARPACK shift-invert run for nev pairs of OP = P K^-1 M: values into vals, M-orthonormal
 * vectors into vecs (n x nev). The caller holds arpack_lock. */
static km_status arpack_run(eig_ctx *c, int nev, int ncv, uint64_t stream, double *vals,
                            double *vecs, km_error *err) {
  size_t n = c->n, lworkl = (size_t)ncv * ((size_t)ncv + 8);
  km_status s = KM_OK;
  a_int ido = 0, info = 1; /* info = 1: use resid as the start vector */
  a_int iparam[11] = {0}, ipntr[14] = {0};
  double *resid = km__malloc(n, sizeof *resid), *V = km__malloc(n * (size_t)ncv, sizeof *V);
  double *workd = km__malloc(3 * n, sizeof *workd), *workl = km__malloc(lworkl, sizeof *workl);
  a_int *select = km__calloc((size_t)ncv, sizeof *select);
  if (!resid || !V || !workd || !workl || !select) {
    s = km__fail(err, KM_ERR_NOMEM, "km_eigs: out of memory (%zu unknowns, ncv %d)", n, ncv);
    goto done;
  }
  uint64_t seed = 0x6b696e656d657368ULL + stream; /* "kinemesh" */
  for (size_t i = 0; i < n; ++i)
    resid[i] = (double)(splitmix64(&seed) >> 11) * 0x1.0p-52 - 1.0;
  deflate(c, resid);

  iparam[0] = 1; /* exact shifts */
  iparam[2] = c->max_iter;
  iparam[3] = 1;
  iparam[6] = 3; /* shift-invert */
  for (;;) {
    dsaupd_c(&ido, "G", (a_int)n, "LM", nev, c->tol, resid, ncv, V, (a_int)n, iparam, ipntr, workd,
             workl, (a_int)lworkl, &info);
    /* ipntr holds 1-based (Fortran) offsets into workd */
    double *x = workd + ipntr[0] - 1, *y = workd + ipntr[1] - 1;
    if (ido == -1) { /* y = P K^-1 M x */
      km_sparse_mul(c->M, 1, x, c->tmp);
      s = km_cholesky_solve(c->chol, 1, c->tmp, y, err);
      deflate(c, y);
    } else if (ido == 1) { /* y = P K^-1 (M x), M x already at ipntr[2] */
      s = km_cholesky_solve(c->chol, 1, workd + ipntr[2] - 1, y, err);
      deflate(c, y);
    } else if (ido == 2) { /* y = M x */
      km_sparse_mul(c->M, 1, x, y);
    } else {
      break;
    }
    if (s) goto done;
    ++c->n_op;
    double frac = 0.05 + 0.9 * (double)c->n_op / ((double)c->n_op + 4.0 * c->ncv);
    if (!km__progress(c->progress, frac, "eigs: arpack")) {
      s = km__fail(err, KM_ERR_CANCELLED, "km_eigs: cancelled after %zu Lanczos steps", c->n_op);
      goto done;
    }
  }
  if (info == 1) {
    s = km__fail(err, KM_ERR_NO_CONVERGENCE,
                 "km_eigs: ARPACK converged %d of %d eigenpairs in %d iterations (max_iter; "
                 "tol %g, ncv %d)",
                 (int)iparam[4], nev, c->max_iter, c->tol, ncv);
    goto done;
  }
  if (info == 3) {
    s = km__fail(err, KM_ERR_NO_CONVERGENCE,
                 "km_eigs: ARPACK could not apply shifts (info 3); try a larger ncv than %d", ncv);
    goto done;
  }
  if (info != 0) {
    s = km__fail(err, KM_ERR_INVALID, "km_eigs: ARPACK dsaupd failed with info %d", (int)info);
    goto done;
  }
  dseupd_c(1, "A", select, vals, vecs, (a_int)n, c->sigma, "G", (a_int)n, "LM", nev, c->tol, resid,
           ncv, V, (a_int)n, iparam, ipntr, workd, workl, (a_int)lworkl, &info);
  if (info != 0) {
    s = km__fail(err, KM_ERR_NO_CONVERGENCE, "km_eigs: ARPACK dseupd failed with info %d",
                 (int)info);
    goto done;
  }
  if (iparam[4] < nev)
    s = km__fail(err, KM_ERR_NO_CONVERGENCE, "km_eigs: ARPACK converged %d of %d eigenpairs",
                 (int)iparam[4], nev);
done:
  km__log(KM_LOG_DEBUG, "km_eigs: ARPACK nev %d ncv %d deflated %d: %d restarts, %d OP, status %d",
          nev, ncv, c->nd, (int)iparam[2], (int)iparam[8], (int)s);
  free(resid), free(V), free(workd), free(workl), free(select);
  return s;
}

km_status km_eigs(const km_sparse *L, const km_sparse *M, int k, const km_eigs_options *opt,
                  double *evals, double *evecs, km_error *err) {
  static const km_eigs_options defaults = {0};
  if (!opt) opt = &defaults;
  if (!L || !M) return km__fail(err, KM_ERR_INVALID, "km_eigs: L or M is NULL");
  size_t n = km_sparse_rows(L);
  if (km_sparse_cols(L) != n || km_sparse_rows(M) != n || km_sparse_cols(M) != n)
    return km__fail(err, KM_ERR_INVALID,
                    "km_eigs: L is %zu x %zu and M %zu x %zu, expected "
                    "two square matrices of one size",
                    n, km_sparse_cols(L), km_sparse_rows(M), km_sparse_cols(M));
  if (k < 1 || (size_t)k > n)
    return km__fail(err, KM_ERR_INVALID,
                    "km_eigs: k = %d eigenpairs of a %zu x %zu problem, "
                    "expected 1..%zu",
                    k, n, n, n);
  if (n > INT32_MAX / 4)
    return km__fail(err, KM_ERR_INVALID, "km_eigs: %zu unknowns is too large", n);
  if (opt->tol < 0 || opt->max_iter < 0 || opt->ncv < 0 || !isfinite(opt->sigma))
    return km__fail(err, KM_ERR_INVALID,
                    "km_eigs: negative tol, max_iter or ncv, or non-finite "
                    "sigma");
  double tol = opt->tol > 0 ? opt->tol : 1e-10;
  int max_iter = opt->max_iter > 0 ? opt->max_iter : 1000;
  int ncv = opt->ncv > 0 ? opt->ncv : (2 * k + 1 > 20 ? 2 * k + 1 : 20);
  if ((size_t)ncv > n) ncv = (int)n;
  if (opt->ncv > 0 && opt->ncv <= k)
    return km__fail(err, KM_ERR_INVALID, "km_eigs: ncv = %d, expected more than k = %d", opt->ncv,
                    k);
  /* A mesh whose faces have no area (coincident vertices), no faces at all, or coordinates
   * so large that areas overflow gives a zero or non-finite L or M: no spectrum, and ARPACK
   * would return -0 or NaN as if it were one. */
  {
    const km_sparse *A[2] = {L, M};
    for (int a = 0; a < 2; ++a) {
      const int32_t *p, *ri;
      const double *x;
      km_sparse_csc(A[a], &p, &ri, &x);
      for (int32_t q = 0; q < p[n]; ++q)
        if (!isfinite(x[q]))
          return km__fail(err, KM_ERR_DEGENERATE_MESH,
                          "km_eigs: %s has a non-finite entry (faces of zero area or coordinates "
                          "too large)",
                          a ? "the mass matrix" : "the Laplacian");
    }
    double trM = diag_sum(M), trL = -diag_sum(L);
    if (!(trM > 0) || !(trL > 0) || !isfinite(trM) || !isfinite(trL))
      return km__fail(err, KM_ERR_DEGENERATE_MESH,
                      "km_eigs: the mesh has no area (no faces, or all of zero area): no "
                      "spectrum");
  }
  if (!km__progress(&opt->progress, 0, "eigs: factorize"))
    return km__fail(err, KM_ERR_CANCELLED, "km_eigs: cancelled");
  if (n <= (size_t)2 * k + 1 || n <= 20) return eigs_dense(L, M, k, evals, evecs, err);

  /* Default shift: -1e-3 * trace(-L) / (n trace(M)). trace(-L)/trace(M) is roughly the mean
   * eigenvalue of M^-1 (-L) (~3.5 n / area on a well-shaped mesh: cot weights sum to ~3.5 per
   * vertex), so dividing by n gives ~3.5 / area, the order of the first non-zero eigenvalue
   * (2/r^2 = 8 pi / area on a sphere), so sigma sits well below the spectrum (K SPD although -L is
   * singular) yet close enough to 0 that 1/(lambda - sigma) separates the wanted eigenvalues well.
   * The constant mode gets K-eigenvalue |sigma| M_ii, about 1e-3/n of the diagonal of -L: far above
   * rounding (1e-16) even at 1M vertices, so the factorisation stays accurate. */
  double sigma = opt->sigma;
  if (sigma == 0) {
    double trL = -diag_sum(L), trM = diag_sum(M);
    double scale = trL / trM / (double)n;
    if (!(scale > 0) || !isfinite(scale)) scale = 1;
    sigma = -1e-3 * scale;
  }

  km_status s = KM_OK;
  km_sparse *K = NULL;
  eig_ctx c = {.n = n,
               .M = M,
               .sigma = sigma,
               .tol = tol,
               .max_iter = max_iter,
               .progress = &opt->progress,
               .ncv = ncv};
  int cap = 2 * k; /* run 1 gives k pairs, each check run at most one more */
  double *vals = km__malloc((size_t)cap, sizeof *vals);
  double *Phi = km__malloc(n * (size_t)cap, sizeof *Phi);
  double *MPhi = km__malloc(n * (size_t)cap, sizeof *MPhi);
  double *sorted = km__malloc((size_t)cap, sizeof *sorted);
  int *order = km__malloc((size_t)cap, sizeof *order);
  c.tmp = km__malloc(n, sizeof *c.tmp);
  c.coef = km__malloc((size_t)cap, sizeof *c.coef);
  bool locked = false;
  if (!vals || !Phi || !MPhi || !sorted || !order || !c.tmp || !c.coef) {
    s = km__fail(err, KM_ERR_NOMEM, "km_eigs: out of memory (%zu unknowns, k %d)", n, k);
    goto done;
  }

  s = km_sparse_add(-1.0, L, -sigma, M, &K, err);
  if (s) goto done;
  s = km_cholesky_analyze(K, &c.chol, err);
  if (s) goto done;
  s = km_cholesky_factorize(c.chol, K, err);
  if (s == KM_ERR_NOT_POSDEF) {
    km__wrap(err, s,
             "km_eigs: -L - sigma M with sigma = %g (L must be negative semidefinite, "
             "M positive definite and sigma below the smallest eigenvalue)",
             sigma);
    goto done;
  }
  if (s) goto done;
  km_sparse_free(&K);

  pthread_mutex_lock(&arpack_lock);
  locked = true;
  s = arpack_run(&c, k, ncv, 0, vals, Phi, err);
  if (s) goto done;
  int nd = k;
  /* Single-vector Lanczos sees one direction per distinct eigenvalue of the start vector's
   * Krylov space; further copies of a multiple eigenvalue (exact on symmetric meshes, e.g. the
   * 5-fold l=2 space of an icosphere) only appear through rounding and can be missed. Check:
   * run ARPACK for one pair on OP deflated by everything found (P K^-1 M with the M-orthogonal
   * projector P = I - Phi Phi^T M, still M-self-adjoint because Phi are eigenvectors of OP).
   * If that pair lies below the current k-th value it was missed: add it and check again.
   * On a mesh without exact multiplicities this costs one short extra run (a few tens of
   * solves). A block method (LOBPCG) would avoid this but is not in our dependencies. */
  while (nd < cap && n - (size_t)nd >= 3) {
    for (int a = 0; a < nd; ++a)
      sorted[a] = vals[a];
    for (int a = 1; a < nd; ++a) /* insertion sort: nd <= 2k */
      for (int b = a; b > 0 && sorted[b - 1] > sorted[b]; --b) {
        double t = sorted[b];
        sorted[b] = sorted[b - 1], sorted[b - 1] = t;
      }
    double thr = sorted[k - 1];
    km_sparse_mul(M, (size_t)nd - (size_t)c.nd, Phi + n * (size_t)c.nd, MPhi + n * (size_t)c.nd);
    c.Phi = Phi, c.MPhi = MPhi, c.nd = nd;
    int ncv2 = ncv < 20 ? ncv : 20;
    if ((size_t)ncv2 > n - (size_t)nd) ncv2 = (int)(n - (size_t)nd);
    s = arpack_run(&c, 1, ncv2, (uint64_t)nd, vals + nd, Phi + n * (size_t)nd, err);
    if (s) goto done;
    if (!(vals[nd] < thr - 1e-8 * fabs(thr))) break;
    km__log(KM_LOG_DEBUG, "km_eigs: recovered a missed copy of eigenvalue %g", vals[nd]);
    ++nd;
  }
  pthread_mutex_unlock(&arpack_lock);
  locked = false;

  /* the k smallest of the nd pairs, ascending */
  for (int a = 0; a < nd; ++a)
    order[a] = a;
  for (int a = 1; a < nd; ++a)
    for (int b = a; b > 0 && vals[order[b - 1]] > vals[order[b]]; --b) {
      int t = order[b];
      order[b] = order[b - 1], order[b - 1] = t;
    }
  for (int a = 0; a < k; ++a) {
    sorted[a] = vals[order[a]];
    if (evecs) memcpy(evecs + n * (size_t)a, Phi + n * (size_t)order[a], n * sizeof *evecs);
  }
  finish_pairs(n, k, sorted, evecs, c.tmp);
  if (evals) memcpy(evals, sorted, (size_t)k * sizeof *evals);
  km__progress(&opt->progress, 1, "eigs: done");
done:
  if (locked) pthread_mutex_unlock(&arpack_lock);
  km_sparse_free(&K);
  km_cholesky_free(&c.chol);
  free(vals), free(Phi), free(MPhi), free(sorted), free(order), free(c.tmp), free(c.coef);
  return s;
}
