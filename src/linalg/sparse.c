/* km_sparse: a thin owner of a CHOLMOD cholmod_sparse (int32 indices, real double, sorted,
 * packed, stype 0). Each matrix carries its own cholmod_common so that no mutable state is
 * shared between threads; cholmod_start does not allocate, so this costs only its size. */
#include "linalg/cholmod_door.h"

#include "core/core.h"

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

static km_status compress_cholmod(cholmod_sparse **Cp, km_sparse **out, km_error *err);

struct entry {
  int32_t row, order;
  double value;
};
static int entry_cmp(const void *a, const void *b) {
  const struct entry *x = a, *y = b;
  if (x->row != y->row) return x->row < y->row ? -1 : 1;
  return (x->order > y->order) - (x->order < y->order);
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
  /* Bucket by column, then compress. cholmod_triplet_to_sparse does the same in
   * the same time (two transposes); this path is shared with the Laplacian assembly, which
   * scatters straight into columns without a triplet list. */
  cholmod_common cc;
  km__cholmod_start(&cc);
  cholmod_sparse *C = cholmod_allocate_sparse(n_rows, n_cols, nnz, 1, 1, 0, CHOLMOD_REAL, &cc);
  int32_t *next = km__malloc(n_cols + 1, sizeof *next);
  km_status s = KM_OK;
  if (!C || !next) {
    s = C ? km__fail(err, KM_ERR_NOMEM, "km_sparse_from_triplets: out of memory")
          : cholmod_fail(err, &cc, "km_sparse_from_triplets");
    goto done;
  }
  int32_t *p = C->p, *ri = C->i;
  double *x = C->x;
  memset(p, 0, (n_cols + 1) * sizeof *p);
  for (size_t k = 0; k < nnz; ++k)
    ++p[cols[k] + 1];
  for (size_t j = 0; j < n_cols; ++j)
    p[j + 1] += p[j];
  memcpy(next, p, (n_cols + 1) * sizeof *p);
  for (size_t k = 0; k < nnz; ++k) {
    int32_t q = next[cols[k]]++;
    ri[q] = rows[k];
    x[q] = values[k];
  }
  free(next);
  cholmod_finish(&cc);
  return compress_cholmod(&C, out, err);
done:
  free(next);
  cholmod_free_sparse(&C, &cc);
  cholmod_finish(&cc);
  return s;
}

static km_status compress_cholmod(cholmod_sparse **Cp, km_sparse **out, km_error *err) {
  cholmod_sparse *C = *Cp;
  size_t n_cols = C->ncol, nnz = (size_t)((int32_t *)C->p)[n_cols];
  int32_t *p = C->p, *ri = C->i;
  double *x = C->x;
  int32_t longest = 0;
  for (size_t j = 0; j < n_cols; ++j)
    if (p[j + 1] - p[j] > longest) longest = p[j + 1] - p[j];
  struct entry *buf = NULL;
  if (longest > 32 && !(buf = km__malloc((size_t)longest, sizeof *buf))) {
    cholmod_common cc;
    km__cholmod_start(&cc);
    cholmod_free_sparse(Cp, &cc);
    cholmod_finish(&cc);
    return km__fail(err, KM_ERR_NOMEM, "sparse matrix: out of memory");
  }
  int32_t w = 0, start = 0;
  for (size_t j = 0; j < n_cols; ++j) {
    int32_t end = p[j + 1], len = end - start;
    if (len <= 32) { /* insertion sort, stable */
      for (int32_t a = start + 1; a < end; ++a) {
        int32_t r = ri[a];
        double v = x[a];
        int32_t b = a - 1;
        for (; b >= start && ri[b] > r; --b)
          ri[b + 1] = ri[b], x[b + 1] = x[b];
        ri[b + 1] = r, x[b + 1] = v;
      }
    } else {
      for (int32_t a = 0; a < len; ++a)
        buf[a] = (struct entry){ri[start + a], a, x[start + a]};
      qsort(buf, (size_t)len, sizeof *buf, entry_cmp);
      for (int32_t a = 0; a < len; ++a)
        ri[start + a] = buf[a].row, x[start + a] = buf[a].value;
    }
    int32_t col_start = w;
    for (int32_t q = start; q < end; ++q) {
      if (w > col_start && ri[w - 1] == ri[q]) {
        x[w - 1] += x[q];
      } else {
        ri[w] = ri[q], x[w] = x[q];
        ++w;
      }
    }
    p[j] = col_start;
    start = end;
  }
  p[n_cols] = w;
  free(buf);
  C->sorted = 1;
  C->packed = 1;
  if ((size_t)w < nnz && w > 0) {
    cholmod_common cc;
    km__cholmod_start(&cc);
    cholmod_reallocate_sparse((size_t)w, C, &cc); /* shrinking cannot fail in a harmful way */
    cholmod_finish(&cc);
  }
  return km__sparse_from_cholmod(Cp, out, err);
}

km_status km__sparse_alloc(size_t n_rows, size_t n_cols, size_t nnz, km_sparse **out,
                           km_error *err) {
  *out = NULL;
  if (n_rows > INT32_MAX || n_cols > INT32_MAX || nnz > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID,
                    "sparse matrix: %zu x %zu with %zu entries exceeds int32 indices", n_rows,
                    n_cols, nnz);
  km_sparse *S = malloc(sizeof *S);
  if (!S) return km__fail(err, KM_ERR_NOMEM, "sparse matrix: out of memory");
  km__cholmod_start(&S->cc);
  S->A = cholmod_allocate_sparse(n_rows, n_cols, nnz, 0, 1, 0, CHOLMOD_REAL, &S->cc);
  if (!S->A) {
    km_status s = cholmod_fail(err, &S->cc, "sparse matrix");
    km_sparse_free(&S);
    return s;
  }
  ((int32_t *)S->A->p)[0] = 0;
  *out = S;
  return KM_OK;
}

void km__sparse_arrays(km_sparse *A, int32_t **col_ptr, int32_t **row_idx, double **values) {
  if (col_ptr) *col_ptr = A->A->p;
  if (row_idx) *row_idx = A->A->i;
  if (values) *values = A->A->x;
}

km_status km__sparse_compress(km_sparse **A, km_error *err) {
  cholmod_sparse *C = (*A)->A;
  (*A)->A = NULL;
  km_sparse_free(A);
  return compress_cholmod(&C, A, err);
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
  if ((*A)->A) cholmod_free_sparse(&(*A)->A, &(*A)->cc);
  cholmod_finish(&(*A)->cc);
  free(*A);
  *A = NULL;
}
