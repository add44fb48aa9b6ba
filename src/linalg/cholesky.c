/* km_cholesky: CHOLMOD analyse / factorise / solve. The symmetric matrix (stored with both
 * triangles) is handed to CHOLMOD as stype = -1, so only its lower triangle is read.
 *
 * Supernodal vs simplicial is left to CHOLMOD's default (CHOLMOD_AUTO: supernodal when
 * flops/nnz(L) >= 40, which mesh Laplacians beyond a few thousand vertices exceed). Measured
 * with bench/bench_eigen.c on 2 cores: on armadillo (43k vertices) forcing simplicial was
 * ~20% faster for one factorisation plus ~55 single-vector solves, but on a 41k icosphere
 * its factorisation was 2.6x slower (242 vs 93 ms) and 6x slower at 164k vertices, with
 * solves within 10%; auto is the safer default. Supernodal runs on BLAS: OpenBLAS's thread
 * count is process-wide and left to the application (on a loaded 2-core machine
 * OPENBLAS_NUM_THREADS=1 avoided large slowdowns from spinning threads). */
#include "core/core.h"
#include "linalg/cholmod_door.h"

#include <math.h>

#include <stdlib.h>
#include <string.h>

struct km_cholesky {
  cholmod_common cc;
  cholmod_factor *L;
  cholmod_dense *X, *Y, *E; /* solve2 workspace, kept between solves */
  size_t n;
  size_t nnz;
  int32_t *Ap, *Ai; /* pattern given to analyze, to reject a different one */
  double min_pivot; /* LDL' pivot check, relative to the largest pivot (0: none) */
  int stype;        /* how CHOLMOD reads A: -1 lower triangle, 1 upper */
  double *ws;       /* simplicial LDL': n*4 interleaved right-hand sides for ldl_solve */
  bool factorized;
};

static km_status cholmod_status(km_error *err, const cholmod_common *cc, const char *what) {
  if (cc->status == CHOLMOD_OUT_OF_MEMORY || cc->status == CHOLMOD_TOO_LARGE)
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory (CHOLMOD status %d)", what, cc->status);
  return km__fail(err, KM_ERR_INVALID, "%s: CHOLMOD failed with status %d", what, cc->status);
}

/* A symmetric view of A without copying: same arrays, stype -1 (lower triangle read, upper
 * entries ignored by CHOLMOD) or 1 (upper). */
static cholmod_sparse sym_view(const km_cholesky *c, const km_sparse *A) {
  cholmod_sparse v = *km__sparse_cholmod(A);
  v.stype = c->stype;
  return v;
}

km_status km_cholesky_analyze(const km_sparse *A, km_cholesky **out, km_error *err) {
  return km__cholesky_analyze_with(A, NULL, out, err);
}

km_status km__cholesky_analyze_with(const km_sparse *A, const km__cholesky_options *opt,
                                    km_cholesky **out, km_error *err) {
  km__cholesky_options o = opt ? *opt : (km__cholesky_options){0};
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_cholesky_analyze: out is NULL");
  *out = NULL;
  if (!A) return km__fail(err, KM_ERR_INVALID, "km_cholesky_analyze: matrix is NULL");
  size_t n = km_sparse_rows(A);
  if (n != km_sparse_cols(A))
    return km__fail(err, KM_ERR_INVALID, "km_cholesky_analyze: matrix is %zu x %zu, not square", n,
                    km_sparse_cols(A));
  km_cholesky *c = calloc(1, sizeof *c);
  if (!c) return km__fail(err, KM_ERR_NOMEM, "km_cholesky_analyze: out of memory");
  km__cholmod_start(&c->cc);
  /* Simplicial LDL' (CHOLMOD's default form) succeeds on indefinite matrices with non-zero
   * pivots; LL' fails at the first non-positive pivot, which is the SPD check we promise. */
  c->cc.final_ll = o.kind == KM__CHOLESKY_LL;
  if (o.kind == KM__CHOLESKY_SIMPLICIAL_LDL) c->cc.supernodal = CHOLMOD_SIMPLICIAL;
  c->min_pivot = o.min_pivot;
  c->stype = o.stored > 0 ? 1 : -1;
  c->n = n;
  c->nnz = km_sparse_nnz(A);
  const int32_t *p, *i;
  km_sparse_csc(A, &p, &i, NULL);
  c->Ap = km__malloc(n + 1, sizeof *c->Ap);
  c->Ai = km__malloc(c->nnz, sizeof *c->Ai);
  if (!c->Ap || !c->Ai) {
    km_cholesky_free(&c);
    return km__fail(err, KM_ERR_NOMEM, "km_cholesky_analyze: out of memory");
  }
  memcpy(c->Ap, p, (n + 1) * sizeof *p);
  memcpy(c->Ai, i, c->nnz * sizeof *i);
  cholmod_sparse v = sym_view(c, A);
  c->L = cholmod_analyze(&v, &c->cc);
  if (!c->L || c->cc.status != CHOLMOD_OK) {
    km_status s = cholmod_status(err, &c->cc, "km_cholesky_analyze");
    km_cholesky_free(&c);
    return s;
  }
  *out = c;
  return KM_OK;
}

km_status km_cholesky_factorize(km_cholesky *c, const km_sparse *A, km_error *err) {
  if (!c || !A) return km__fail(err, KM_ERR_INVALID, "km_cholesky_factorize: NULL argument");
  const int32_t *p, *i;
  km_sparse_csc(A, &p, &i, NULL);
  if (km_sparse_rows(A) != c->n || km_sparse_cols(A) != c->n || km_sparse_nnz(A) != c->nnz ||
      memcmp(p, c->Ap, (c->n + 1) * sizeof *p) != 0 || memcmp(i, c->Ai, c->nnz * sizeof *i) != 0)
    return km__fail(err, KM_ERR_INVALID,
                    "km_cholesky_factorize: the matrix does not have the sparsity pattern given "
                    "to km_cholesky_analyze (%zu x %zu, %zu entries)",
                    c->n, c->n, c->nnz);
  c->factorized = false;
  cholmod_sparse v = sym_view(c, A);
  int ok = cholmod_factorize(&v, c->L, &c->cc);
  if (ok && c->cc.status == CHOLMOD_OK && c->min_pivot > 0 && !c->L->is_ll && !c->L->is_super) {
    /* LDL' only stops at an exactly zero pivot; a singular block (say, a mesh component
     * without a constraint) leaves a pivot of round-off, of either sign, many orders below the
     * others. */
    const int *Lp = c->L->p;
    const double *Lx = c->L->x;
    double dmax = 0;
    for (size_t j = 0; j < c->n; ++j)
      dmax = fmax(dmax, Lx[Lp[j]]);
    for (size_t j = 0; j < c->n; ++j)
      if (!(Lx[Lp[j]] > c->min_pivot * dmax)) {
        c->cc.status = CHOLMOD_NOT_POSDEF;
        c->L->minor = j;
        break;
      }
  }
  if (c->cc.status == CHOLMOD_NOT_POSDEF)
    return km__fail(err, KM_ERR_NOT_POSDEF,
                    "km_cholesky_factorize: the %zu x %zu matrix is not positive definite: "
                    "factorisation broke down at column %zu",
                    c->n, c->n, (size_t)c->L->minor);
  if (!ok || c->cc.status != CHOLMOD_OK)
    return cholmod_status(err, &c->cc, "km_cholesky_factorize");
  if (!c->L->is_ll && !c->L->is_super && !c->ws) {
    c->ws = km__malloc(c->n ? c->n * 4 : 1, sizeof *c->ws);
    if (!c->ws) return km__fail(err, KM_ERR_NOMEM, "km_cholesky_factorize: out of memory");
  }
  c->factorized = true;
  return KM_OK;
}

/* x = A^-1 b for k <= 4 interleaved columns (y[k * row + col]) with a simplicial LDL' factor
 * P A P' = L D L' (CHOLMOD's layout: column j holds D_jj first, then L's entries below the
 * unit diagonal). Written by hand because no maintained library offers it allocation-free:
 * Debian 12's cholmod_solve2 does the same sweeps but frees and reallocates its 220 kB
 * workspace on every call even with kept Y/E handles (two mallocs, mmap-sized, per transfer
 * solve: found with gdb); here it is kept in c->ws. The factor is CHOLMOD's; quietly measured
 * (bench transfer, 7k vertices) a default transfer costs ~0.2 ms more per solve through
 * cholmod_solve2. */
static void ldl_sweeps(const cholmod_factor *L, double *y, size_t n, int k) {
  const int *Lp = L->p, *Li = L->i, *Lnz = L->nz;
  const double *Lx = L->x;
  if (k == 3) {
    for (size_t j = 0; j < n; ++j) {
      const double *yj = y + 3 * j;
      double a = yj[0], b = yj[1], c = yj[2];
      for (int p = Lp[j] + 1, e = Lp[j] + Lnz[j]; p < e; ++p) {
        double *yi = y + 3 * (size_t)Li[p], l = Lx[p];
        yi[0] -= l * a, yi[1] -= l * b, yi[2] -= l * c;
      }
    }
    for (size_t j = n; j-- > 0;) {
      double *yj = y + 3 * j, d = 1.0 / Lx[Lp[j]];
      double a = yj[0] * d, b = yj[1] * d, c = yj[2] * d;
      for (int p = Lp[j] + 1, e = Lp[j] + Lnz[j]; p < e; ++p) {
        const double *yi = y + 3 * (size_t)Li[p];
        double l = Lx[p];
        a -= l * yi[0], b -= l * yi[1], c -= l * yi[2];
      }
      yj[0] = a, yj[1] = b, yj[2] = c;
    }
    return;
  }
  for (size_t j = 0; j < n; ++j) {
    const double *yj = y + (size_t)k * j;
    for (int p = Lp[j] + 1, e = Lp[j] + Lnz[j]; p < e; ++p) {
      double *yi = y + (size_t)k * (size_t)Li[p], l = Lx[p];
      for (int q = 0; q < k; ++q)
        yi[q] -= l * yj[q];
    }
  }
  for (size_t j = n; j-- > 0;) {
    double *yj = y + (size_t)k * j, d = 1.0 / Lx[Lp[j]], acc[4];
    for (int q = 0; q < k; ++q)
      acc[q] = yj[q] * d;
    for (int p = Lp[j] + 1, e = Lp[j] + Lnz[j]; p < e; ++p) {
      const double *yi = y + (size_t)k * (size_t)Li[p];
      double l = Lx[p];
      for (int q = 0; q < k; ++q)
        acc[q] -= l * yi[q];
    }
    for (int q = 0; q < k; ++q)
      yj[q] = acc[q];
  }
}

/* km_cholesky_solve with a simplicial LDL' factor: column-major B -> X in chunks of up to 4
 * columns, permuted into c->ws and back (B == X allowed: a chunk is read before written). */
static void ldl_solve(km_cholesky *c, size_t nrhs, const double *B, double *X) {
  size_t n = c->n;
  const int *perm = c->L->Perm;
  double *y = c->ws;
  for (size_t c0 = 0; c0 < nrhs; c0 += 4) {
    int k = (int)(nrhs - c0 < 4 ? nrhs - c0 : 4);
    for (int q = 0; q < k; ++q) {
      const double *b = B + (c0 + (size_t)q) * n;
      for (size_t r = 0; r < n; ++r)
        y[(size_t)k * r + (size_t)q] = b[perm ? (size_t)perm[r] : r];
    }
    ldl_sweeps(c->L, y, n, k);
    for (int q = 0; q < k; ++q) {
      double *x = X + (c0 + (size_t)q) * n;
      for (size_t r = 0; r < n; ++r)
        x[perm ? (size_t)perm[r] : r] = y[(size_t)k * r + (size_t)q];
    }
  }
}

km_status km_cholesky_solve(km_cholesky *c, size_t nrhs, const double *B, double *X,
                            km_error *err) {
  if (!c) return km__fail(err, KM_ERR_INVALID, "km_cholesky_solve: NULL factor");
  if (!c->factorized)
    return km__fail(err, KM_ERR_INVALID, "km_cholesky_solve: no successful factorisation");
  if (nrhs == 0 || c->n == 0) return KM_OK;
  if (!B || !X) return km__fail(err, KM_ERR_INVALID, "km_cholesky_solve: NULL B or X");
  if (nrhs > SIZE_MAX / c->n)
    return km__fail(err, KM_ERR_INVALID, "km_cholesky_solve: %zu right-hand sides overflow", nrhs);
  if (c->ws && !c->L->is_ll && !c->L->is_super && c->L->xtype == CHOLMOD_REAL) {
    ldl_solve(c, nrhs, B, X);
    return KM_OK;
  }
  /* Shallow dense header over the caller's B; solve2 writes into c->X, reused across calls
   * with the same nrhs, and Y/E are its kept workspace, so steady-state solves allocate
   * nothing. Copying out afterwards makes B == X aliasing safe. */
  cholmod_dense b;
  memset(&b, 0, sizeof b);
  b.nrow = c->n;
  b.ncol = nrhs;
  b.nzmax = c->n * nrhs;
  b.d = c->n;
  b.x = (void *)B;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  if (!cholmod_solve2(CHOLMOD_A, c->L, &b, NULL, &c->X, NULL, &c->Y, &c->E, &c->cc) ||
      c->cc.status != CHOLMOD_OK)
    return cholmod_status(err, &c->cc, "km_cholesky_solve");
  memcpy(X, c->X->x, c->n * nrhs * sizeof *X);
  return KM_OK;
}

size_t km_cholesky_size(const km_cholesky *c) { return c ? c->n : 0; }

void km_cholesky_free(km_cholesky **c) {
  if (!c || !*c) return;
  km_cholesky *f = *c;
  cholmod_free_factor(&f->L, &f->cc);
  cholmod_free_dense(&f->X, &f->cc);
  cholmod_free_dense(&f->Y, &f->cc);
  cholmod_free_dense(&f->E, &f->cc);
  cholmod_finish(&f->cc);
  free(f->Ap);
  free(f->Ai);
  free(f->ws);
  free(f);
  *c = NULL;
}
