/* Requires: core. External: CHOLMOD, ARPACK, LAPACKE/LAPACK/OpenBLAS. */
/* Private linalg entry points for the modules above (prefix km__); no CHOLMOD or LAPACK type
 * appears here: those stay in src/linalg/ (cholmod_door.h). */
#ifndef KM_LINALG_SPARSE_H
#define KM_LINALG_SPARSE_H

#include "kinemesh.h"

/* ---- plain-array CSC assembly: how other modules build a km_sparse by hand */

/* An n_rows x n_cols matrix with room for nnz entries whose CSC arrays the caller fills
 * (km__sparse_arrays): col_ptr[0..n_cols] with col_ptr[n_cols] = entries used, row indices
 * and values in column order. It must be finished with km__sparse_compress before any other
 * km_sparse call reads it. */
km_status km__sparse_alloc(size_t n_rows, size_t n_cols, size_t nnz, km_sparse **out,
                           km_error *err);

/* Mutable CSC arrays of A (col_ptr has cols+1 entries). Valid until km__sparse_compress. */
void km__sparse_arrays(km_sparse *A, int32_t **col_ptr, int32_t **row_idx, double **values);

/* Finishes a matrix whose columns were filled bucket-wise: rows within a column unsorted and
 * possibly repeated. Sorts each column (stable), sums repeated rows in fill order and shrinks
 * the storage; a column already sorted without repeats is left as it is (positions kept).
 * Linear in the entries for short columns. On failure A is freed (set to NULL). */
km_status km__sparse_compress(km_sparse **A, km_error *err);

/* Mutable values array (nnz entries, CSC order) for in-place updates of the same pattern. */
double *km__sparse_values(km_sparse *A);

/* ---- factorisation choices behind km_cholesky (the public calls use the zero options) */

typedef enum km__cholesky_kind {
  /* CHOLMOD picks supernodal or simplicial (CHOLMOD_AUTO) and the factor is LL': the first
   * non-positive pivot fails, the SPD check km_cholesky promises. */
  KM__CHOLESKY_LL = 0,
  /* CHOLMOD's own default: supernodal LL' or simplicial LDL' (CHOLMOD_AUTO picks). */
  KM__CHOLESKY_AUTO_LDL,
  /* Simplicial LDL': no square roots and a unit diagonal in the triangular sweeps, so its
   * few-column solves are the fastest; it only stops at an exactly zero pivot, see
   * min_pivot. */
  KM__CHOLESKY_SIMPLICIAL_LDL,
} km__cholesky_kind;

typedef struct km__cholesky_options {
  km__cholesky_kind kind;
  /* Which triangle of A holds the symmetric matrix: 0 both stored (the lower is read), 1 only
   * the upper triangle is stored, -1 only the lower. */
  int stored;
  /* With an LDL' factor: a pivot d_j <= min_pivot * max_k d_k fails with KM_ERR_NOT_POSDEF
   * (a singular block leaves a round-off pivot of either sign). 0: no check. */
  double min_pivot;
} km__cholesky_options;

/* km_cholesky_analyze with options (NULL: the zero options, which is km_cholesky_analyze). */
km_status km__cholesky_analyze_with(const km_sparse *A, const km__cholesky_options *opt,
                                    km_cholesky **out, km_error *err);

/* ---- dense LAPACK, the only door to it (row/column order as named; return LAPACK's info) */

/* A = U diag(S) Vt for a row-major 3x3 A (destroyed); U, Vt row-major, S descending. */
int km__svd3(double A[9], double S[3], double U[9], double Vt[9]);
/* Cholesky factor K = U^T U in place of the column-major n x n K (upper triangle; dpotrf). */
int km__potrf(size_t n, double *K);
/* B = K^-1 B with the factor of km__potrf; B column-major n x nrhs (dpotrs). */
int km__potrs(size_t n, size_t nrhs, const double *K, double *B);
/* Eigen-decomposition of the symmetric row-major n x n A (upper triangle read): eigenvalues
 * ascending in w, A replaced by the eigenvectors as its columns (dsyev). */
int km__syev(size_t n, double *A, double *w);
/* C = alpha op(A) op(B) + beta C, row-major (dgemm, OpenBLAS): op(A) m x k, op(B) k x n, C m x n;
 * op(X) = X^T when trans_X; lda / ldb / ldc the row strides of the arrays as stored. Call it
 * outside OpenMP parallel regions (OpenBLAS threads itself). */
void km__gemm(bool trans_a, bool trans_b, size_t m, size_t n, size_t k, double alpha,
              const double *A, size_t lda, const double *B, size_t ldb, double beta, double *C,
              size_t ldc);

#endif
