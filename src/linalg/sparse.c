/* km_sparse: a thin owner of a CHOLMOD cholmod_sparse (int32 indices, real double, sorted,
 * packed, stype 0). Each matrix carries its own cholmod_common so that no mutable state is
 * shared between threads; cholmod_start does not allocate, so this costs only its size. */
#include "linalg/sparse.h"

#include "internal.h"

#include <limits.h>
#include <stdlib.h>
#include <string.h>

struct km_sparse {
  cholmod_common cc;
  cholmod_sparse *A;
};

void km__cholmod_start(cholmod_common *cc) {
  cholmod_start(cc);
  cc->itype = CHOLMOD_INT;
  cc->dtype = CHOLMOD_DOUBLE;
  /* The library never prints: CHOLMOD reports through Common->status instead. */
  cc->print = 0;
  cc->error_handler = NULL;
}

cholmod_sparse *km__sparse_cholmod(const km_sparse *A) { return A ? A->A : NULL; }

double *km__sparse_values(km_sparse *A) { return A ? (double *)A->A->x : NULL; }

static km_status cholmod_fail(km_error *err, const cholmod_common *cc, const char *what) {
  if (cc->status == CHOLMOD_OUT_OF_MEMORY || cc->status == CHOLMOD_TOO_LARGE)
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory (CHOLMOD status %d)", what, cc->status);
  return km__fail(err, KM_ERR_INVALID, "%s: CHOLMOD failed with status %d", what, cc->status);
}

km_status km__sparse_from_cholmod(cholmod_sparse **C, km_sparse **out, km_error *err) {
  *out = NULL;
  km_sparse *S = malloc(sizeof *S);
  if (!S) {
    cholmod_common cc;
    km__cholmod_start(&cc);
    cholmod_free_sparse(C, &cc);
    cholmod_finish(&cc);
    return km__fail(err, KM_ERR_NOMEM, "sparse matrix: out of memory");
  }
  km__cholmod_start(&S->cc);
  S->A = *C;
  *C = NULL;
  cholmod_sparse *A = S->A;
  if (!A || A->itype != CHOLMOD_INT || A->xtype != CHOLMOD_REAL || A->dtype != CHOLMOD_DOUBLE ||
      A->stype != 0) {
    km_sparse_free(&S);
    return km__fail(err, KM_ERR_INVALID,
                    "sparse matrix: expected an int32, real double, unsymmetric CHOLMOD matrix");
  }
  /* cholmod_sort also packs the matrix */
  if ((!A->sorted || !A->packed) && !cholmod_sort(A, &S->cc)) {
    km_status s = cholmod_fail(err, &S->cc, "sparse matrix: sort");
    km_sparse_free(&S);
    return s;
  }
  *out = S;
  return KM_OK;
}

km_status km_sparse_from_triplets(size_t n_rows, size_t n_cols, size_t nnz, const int32_t *rows,
                                  const int32_t *cols, const double *values, km_sparse **out,
                                  km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_sparse_from_triplets: out is NULL");
  *out = NULL;
  if (n_rows > INT32_MAX || n_cols > INT32_MAX || nnz > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID,
                    "km_sparse_from_triplets: %zu x %zu with %zu entries exceeds int32 indices",
                    n_rows, n_cols, nnz);
  if (nnz && (!rows || !cols || !values))
    return km__fail(err, KM_ERR_INVALID, "km_sparse_from_triplets: NULL triplet arrays");
  for (size_t k = 0; k < nnz; ++k) {
    if (rows[k] < 0 || (size_t)rows[k] >= n_rows || cols[k] < 0 || (size_t)cols[k] >= n_cols)
      return km__fail(err, KM_ERR_INVALID,
                      "km_sparse_from_triplets: entry %zu at (%d,%d) is outside the %zu x %zu "
                      "matrix",
                      k, (int)rows[k], (int)cols[k], n_rows, n_cols);
  }
  cholmod_common cc;
  km__cholmod_start(&cc);
  /* A shallow triplet header over the caller's arrays: cholmod_triplet_to_sparse only reads
   * them, and does the two-pass bucket sort that sums duplicates and sorts rows. */
  cholmod_triplet T;
  memset(&T, 0, sizeof T);
  T.nrow = n_rows;
  T.ncol = n_cols;
  T.nzmax = nnz;
  T.nnz = nnz;
  T.i = (void *)rows;
  T.j = (void *)cols;
  T.x = (void *)values;
  T.stype = 0;
  T.itype = CHOLMOD_INT;
  T.xtype = CHOLMOD_REAL;
  T.dtype = CHOLMOD_DOUBLE;
  cholmod_sparse *C = cholmod_triplet_to_sparse(&T, nnz, &cc);
  if (!C) {
    km_status s = cholmod_fail(err, &cc, "km_sparse_from_triplets");
    cholmod_finish(&cc);
    return s;
  }
  cholmod_finish(&cc);
  return km__sparse_from_cholmod(&C, out, err);
}

km_status km_sparse_diagonal(size_t n, const double *diag, km_sparse **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_sparse_diagonal: out is NULL");
  *out = NULL;
  if (n > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "km_sparse_diagonal: size %zu exceeds int32", n);
  if (n && !diag) return km__fail(err, KM_ERR_INVALID, "km_sparse_diagonal: diag is NULL");
  cholmod_common cc;
  km__cholmod_start(&cc);
  cholmod_sparse *C = cholmod_allocate_sparse(n, n, n, 1, 1, 0, CHOLMOD_REAL, &cc);
  if (!C) {
    km_status s = cholmod_fail(err, &cc, "km_sparse_diagonal");
    cholmod_finish(&cc);
    return s;
  }
  cholmod_finish(&cc);
  int32_t *p = C->p, *i = C->i;
  double *x = C->x;
  for (size_t k = 0; k < n; ++k) {
    p[k] = (int32_t)k;
    i[k] = (int32_t)k;
    x[k] = diag[k];
  }
  p[n] = (int32_t)n;
  return km__sparse_from_cholmod(&C, out, err);
}

km_status km_sparse_add(double alpha, const km_sparse *A, double beta, const km_sparse *B,
                        km_sparse **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_sparse_add: out is NULL");
  *out = NULL;
  if (!A || !B) return km__fail(err, KM_ERR_INVALID, "km_sparse_add: NULL matrix");
  if (A->A->nrow != B->A->nrow || A->A->ncol != B->A->ncol)
    return km__fail(err, KM_ERR_INVALID, "km_sparse_add: shapes differ (%zu x %zu vs %zu x %zu)",
                    A->A->nrow, A->A->ncol, B->A->nrow, B->A->ncol);
  cholmod_common cc;
  km__cholmod_start(&cc);
  double a[2] = {alpha, 0}, b[2] = {beta, 0};
  cholmod_sparse *C = cholmod_add(A->A, B->A, a, b, 1, 1, &cc);
  if (!C) {
    km_status s = cholmod_fail(err, &cc, "km_sparse_add");
    cholmod_finish(&cc);
    return s;
  }
  cholmod_finish(&cc);
  return km__sparse_from_cholmod(&C, out, err);
}

size_t km_sparse_rows(const km_sparse *A) { return A ? A->A->nrow : 0; }
size_t km_sparse_cols(const km_sparse *A) { return A ? A->A->ncol : 0; }
size_t km_sparse_nnz(const km_sparse *A) {
  return A ? (size_t)((const int32_t *)A->A->p)[A->A->ncol] : 0;
}

void km_sparse_csc(const km_sparse *A, const int32_t **col_ptr, const int32_t **row_idx,
                   const double **values) {
  if (col_ptr) *col_ptr = A ? A->A->p : NULL;
  if (row_idx) *row_idx = A ? A->A->i : NULL;
  if (values) *values = A ? A->A->x : NULL;
}

double km_sparse_coeff(const km_sparse *A, size_t i, size_t j) {
  if (!A || i >= A->A->nrow || j >= A->A->ncol) return 0;
  const int32_t *p = A->A->p, *ri = A->A->i;
  const double *x = A->A->x;
  int32_t lo = p[j], hi = p[j + 1];
  while (lo < hi) { /* rows are sorted within a column */
    int32_t mid = lo + (hi - lo) / 2;
    if ((size_t)ri[mid] < i)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < p[j + 1] && (size_t)ri[lo] == i ? x[lo] : 0;
}

/* cholmod_sdmult needs a mutable cholmod_common, which a const matrix (possibly shared by
 * threads) cannot lend; the CSC product is a short loop, so it is written here. */
void km_sparse_mul(const km_sparse *A, size_t k, const double *X, double *Y) {
  if (!A) return;
  size_t m = A->A->nrow, n = A->A->ncol;
  const int32_t *p = A->A->p, *ri = A->A->i;
  const double *x = A->A->x;
  for (size_t c = 0; c < k; ++c) {
    const double *xc = X + c * n;
    double *yc = Y + c * m;
    for (size_t i = 0; i < m; ++i)
      yc[i] = 0;
    for (size_t j = 0; j < n; ++j) {
      double xj = xc[j];
      for (int32_t q = p[j]; q < p[j + 1]; ++q)
        yc[ri[q]] += x[q] * xj;
    }
  }
}

void km_sparse_free(km_sparse **A) {
  if (!A || !*A) return;
  cholmod_free_sparse(&(*A)->A, &(*A)->cc);
  cholmod_finish(&(*A)->cc);
  free(*A);
  *A = NULL;
}
