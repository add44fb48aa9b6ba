/* Dense LAPACK for the modules above linalg: thin wrappers, so that LAPACKE's types and
 * headers stay in src/linalg/. */
#include "linalg/linalg.h"

#include <cblas.h>
#include <lapacke.h>

int km_blas_threads(int n) {
  int before = openblas_get_num_threads();
  if (n >= 1) openblas_set_num_threads(n);
  return before;
}

int km__svd3(double A[9], double S[3], double U[9], double Vt[9]) {
  double superb[2];
  return (int)LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'A', 'A', 3, 3, A, 3, S, U, 3, Vt, 3, superb);
}

int km__potrf(size_t n, double *K) {
  return (int)LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'U', (lapack_int)n, K, (lapack_int)n);
}

int km__potrs(size_t n, size_t nrhs, const double *K, double *B) {
  return (int)LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'U', (lapack_int)n, (lapack_int)nrhs, K,
                             (lapack_int)n, B, (lapack_int)n);
}

int km__syev(size_t n, double *A, double *w) {
  return (int)LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', (lapack_int)n, A, (lapack_int)n, w);
}

void km__gemm(bool trans_a, bool trans_b, size_t m, size_t n, size_t k, double alpha,
              const double *A, size_t lda, const double *B, size_t ldb, double beta, double *C,
              size_t ldc) {
  cblas_dgemm(CblasRowMajor, trans_a ? CblasTrans : CblasNoTrans,
              trans_b ? CblasTrans : CblasNoTrans, (blasint)m, (blasint)n, (blasint)k, alpha, A,
              (blasint)lda, B, (blasint)ldb, beta, C, (blasint)ldc);
}
