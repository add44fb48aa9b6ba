/* km_sparse and km_cholesky against dense references. */
#include "km_test.h"
#include "linalg/linalg.h"

#include <stdint.h>

static uint64_t rng_state = 12345;
static double urand(void) { /* uniform [0,1), xorshift64* */
  rng_state ^= rng_state >> 12, rng_state ^= rng_state << 25, rng_state ^= rng_state >> 27;
  return (double)((rng_state * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

static void dense_of(const km_sparse *A, double *D) { /* column-major */
  size_t m = km_sparse_rows(A), n = km_sparse_cols(A);
  memset(D, 0, m * n * sizeof *D);
  const int32_t *p, *i;
  const double *x;
  km_sparse_csc(A, &p, &i, &x);
  for (size_t j = 0; j < n; ++j) {
    for (int32_t q = p[j]; q < p[j + 1]; ++q) {
      D[j * m + (size_t)i[q]] = x[q];
      if (q > p[j]) CHECK(i[q] > i[q - 1]); /* sorted, no duplicates */
    }
  }
}

static void test_sparse(void) {
  enum { M = 7, N = 5, NNZ = 40 };
  int32_t r[NNZ], c[NNZ];
  double v[NNZ], D[M * N] = {0};
  for (int k = 0; k < NNZ; ++k) { /* 40 entries in 35 slots: duplicates guaranteed */
    r[k] = (int32_t)(urand() * M), c[k] = (int32_t)(urand() * N), v[k] = urand() - 0.5;
    D[c[k] * M + r[k]] += v[k];
  }
  km_sparse *A = NULL, *B = NULL, *C = NULL;
  CHECK_OK(km_sparse_from_triplets(M, N, NNZ, r, c, v, &A, KM_E));
  CHECK(km_sparse_rows(A) == M && km_sparse_cols(A) == N);
  CHECK(km_sparse_nnz(A) <= M * N && km_sparse_nnz(A) < NNZ);
  double G[M * N];
  dense_of(A, G);
  double maxd = 0;
  for (int k = 0; k < M * N; ++k)
    maxd = fmax(maxd, fabs(G[k] - D[k]));
  CHECK(maxd < 1e-15);
  for (int i = 0; i < M; ++i)
    for (int j = 0; j < N; ++j)
      CHECK_NEAR(km_sparse_coeff(A, i, j), D[j * M + i], 1e-15);
  CHECK(km_sparse_coeff(A, M, 0) == 0 && km_sparse_coeff(A, 0, N + 3) == 0);

  /* mul with 2 columns against the dense product */
  double X[N * 2], Y[M * 2];
  for (int k = 0; k < N * 2; ++k)
    X[k] = urand() - 0.5;
  km_sparse_mul(A, 2, X, Y);
  for (int col = 0; col < 2; ++col)
    for (int i = 0; i < M; ++i) {
      double s = 0;
      for (int j = 0; j < N; ++j)
        s += D[j * M + i] * X[col * N + j];
      CHECK_NEAR(Y[col * M + i], s, 1e-14);
    }

  /* add: 2A - 3B with B another random matrix */
  for (int k = 0; k < NNZ; ++k)
    r[k] = (int32_t)(urand() * M), c[k] = (int32_t)(urand() * N);
  CHECK_OK(km_sparse_from_triplets(M, N, NNZ, r, c, v, &B, KM_E));
  double DB[M * N];
  dense_of(B, DB);
  CHECK_OK(km_sparse_add(2, A, -3, B, &C, KM_E));
  dense_of(C, G);
  maxd = 0;
  for (int k = 0; k < M * N; ++k)
    maxd = fmax(maxd, fabs(G[k] - (2 * D[k] - 3 * DB[k])));
  CHECK(maxd < 1e-14);
  km_sparse_free(&C);

  /* shape mismatch and out-of-range triplets are errors, not crashes */
  km_sparse *S = NULL;
  CHECK_OK(km_sparse_diagonal(3, (double[]){1, 2, 3}, &S, KM_E));
  CHECK(km_sparse_nnz(S) == 3 && km_sparse_coeff(S, 1, 1) == 2 && km_sparse_coeff(S, 0, 1) == 0);
  CHECK_STATUS(km_sparse_add(1, A, 1, S, &C, KM_E), KM_ERR_INVALID);
  CHECK(C == NULL);
  int32_t bad_r[1] = {7}, bad_c[1] = {0};
  CHECK_STATUS(km_sparse_from_triplets(M, N, 1, bad_r, bad_c, v, &C, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "(7,0)") != NULL);
  km_sparse_free(&S);
  /* empty: no entries at all, and a 0 x 0 matrix */
  CHECK_OK(km_sparse_from_triplets(4, 3, 0, NULL, NULL, NULL, &S, KM_E));
  CHECK(km_sparse_nnz(S) == 0 && km_sparse_rows(S) == 4 && km_sparse_coeff(S, 1, 1) == 0);
  km_sparse_free(&S);
  CHECK_OK(km_sparse_diagonal(0, NULL, &S, KM_E));
  CHECK(km_sparse_nnz(S) == 0 && km_sparse_rows(S) == 0);
  km_sparse_free(&S);
  km_sparse_free(&A);
  km_sparse_free(&B);
  CHECK(A == NULL);
  km_sparse_free(&A); /* NULL is a no-op */
}

/* Random sparse SPD matrix: a random symmetric pattern, diagonal dominance + shift. */
static km_sparse *random_spd(int n, double shift) {
  int cap = 2 * 4 * n + n, k = 0;
  int32_t *r = malloc(cap * sizeof *r), *c = malloc(cap * sizeof *c);
  double *v = malloc(cap * sizeof *v), *diag = calloc(n, sizeof *diag);
  for (int i = 0; i < n; ++i)
    for (int t = 0; t < 4; ++t) {
      int j = (int)(urand() * n);
      if (j == i) continue;
      double w = urand() - 0.5;
      r[k] = i, c[k] = j, v[k++] = w;
      r[k] = j, c[k] = i, v[k++] = w;
      diag[i] += fabs(w), diag[j] += fabs(w);
    }
  for (int i = 0; i < n; ++i)
    r[k] = c[k] = i, v[k++] = diag[i] + shift;
  km_sparse *A = NULL;
  CHECK_OK(km_sparse_from_triplets(n, n, k, r, c, v, &A, KM_E));
  free(r), free(c), free(v), free(diag);
  return A;
}

static double residual(const km_sparse *A, int n, int nrhs, const double *X, const double *B) {
  double *AX = malloc((size_t)n * nrhs * sizeof *AX), worst = 0;
  km_sparse_mul(A, nrhs, X, AX);
  for (int col = 0; col < nrhs; ++col) {
    double rn = 0, bn = 0;
    for (int i = 0; i < n; ++i) {
      double d = AX[col * n + i] - B[col * n + i];
      rn += d * d, bn += B[col * n + i] * B[col * n + i];
    }
    worst = fmax(worst, sqrt(rn / bn));
  }
  free(AX);
  return worst;
}

static void test_cholesky(void) {
  const int n = 2000, nrhs = 3;
  km_sparse *A = random_spd(n, 0.1);
  km_cholesky *ch = NULL;
  CHECK_OK(km_cholesky_analyze(A, &ch, KM_E));
  CHECK(km_cholesky_size(ch) == (size_t)n);
  CHECK_STATUS(km_cholesky_solve(ch, 1, (double[1]){0}, (double[1]){0}, KM_E), KM_ERR_INVALID);
  CHECK_OK(km_cholesky_factorize(ch, A, KM_E));
  double *B = malloc(n * nrhs * sizeof *B), *X = malloc(n * nrhs * sizeof *X);
  for (int i = 0; i < n * nrhs; ++i)
    B[i] = urand() - 0.5;
  CHECK_OK(km_cholesky_solve(ch, 1, B, X, KM_E));
  CHECK(residual(A, n, 1, X, B) < 1e-12);
  CHECK_OK(km_cholesky_solve(ch, nrhs, B, X, KM_E));
  CHECK(residual(A, n, nrhs, X, B) < 1e-12);
  /* B and X may alias */
  double *BX = malloc(n * nrhs * sizeof *BX);
  memcpy(BX, B, n * nrhs * sizeof *BX);
  CHECK_OK(km_cholesky_solve(ch, nrhs, BX, BX, KM_E));
  CHECK(residual(A, n, nrhs, BX, B) < 1e-12);

  /* refactorise with new values of the same pattern */
  km_sparse *I = NULL, *A2 = NULL;
  double *ones = malloc(n * sizeof *ones);
  for (int i = 0; i < n; ++i)
    ones[i] = 1;
  CHECK_OK(km_sparse_diagonal(n, ones, &I, KM_E));
  CHECK_OK(km_sparse_add(3, A, 5, I, &A2, KM_E));
  CHECK(km_sparse_nnz(A2) == km_sparse_nnz(A));
  CHECK_OK(km_cholesky_factorize(ch, A2, KM_E));
  CHECK_OK(km_cholesky_solve(ch, nrhs, B, X, KM_E));
  CHECK(residual(A2, n, nrhs, X, B) < 1e-12);
  CHECK(residual(A, n, 1, X, B) > 1e-3); /* really the new matrix */

  /* a different pattern is refused */
  km_sparse *other = random_spd(n, 0.1);
  CHECK_STATUS(km_cholesky_factorize(ch, other, KM_E), KM_ERR_INVALID);

  /* not positive definite: A - big I; the message names a column */
  km_sparse *NP = NULL;
  CHECK_OK(km_sparse_add(1, A, -100, I, &NP, KM_E));
  CHECK_STATUS(km_cholesky_factorize(ch, NP, KM_E), KM_ERR_NOT_POSDEF);
  CHECK(strstr(km_test_err.message, "column") != NULL);
  /* after a failed factorisation, solve refuses instead of using a partial factor */
  CHECK_STATUS(km_cholesky_solve(ch, 1, B, X, KM_E), KM_ERR_INVALID);
  /* and a good one works again */
  CHECK_OK(km_cholesky_factorize(ch, A, KM_E));
  CHECK_OK(km_cholesky_solve(ch, 1, B, X, KM_E));
  CHECK(residual(A, n, 1, X, B) < 1e-12);

  /* a small indefinite matrix, known column: diag(1, 2, -1) breaks at column 2 */
  km_sparse *S = NULL;
  km_cholesky *cs = NULL;
  CHECK_OK(km_sparse_diagonal(3, (double[]){1, 2, -1}, &S, KM_E));
  CHECK_OK(km_cholesky_analyze(S, &cs, KM_E));
  CHECK_STATUS(km_cholesky_factorize(cs, S, KM_E), KM_ERR_NOT_POSDEF);
  CHECK(strstr(km_test_err.message, "column 2") != NULL);

  km_cholesky_free(&cs);
  km_sparse_free(&S);
  km_sparse_free(&NP);
  km_sparse_free(&other);
  km_sparse_free(&I);
  km_sparse_free(&A2);
  free(ones), free(B), free(X), free(BX);
  km_cholesky_free(&ch);
  CHECK(ch == NULL);
  km_sparse_free(&A);
}

/* km_blas_threads: a query changes nothing, a count is set and read back, and a factorisation
 * on one thread solves as before. */
static void test_blas_threads(void) {
  int before = km_blas_threads(0);
  CHECK_MSG(before >= 1, "OpenBLAS threads %d", before);
  CHECK(km_blas_threads(0) == before);
  CHECK(km_blas_threads(1) == before);
  CHECK(km_blas_threads(0) == 1);
  test_cholesky();
  CHECK(km_blas_threads(before) == 1);
  CHECK(km_blas_threads(0) == before);
}

/* The simplicial LDL' kind (km_transfer's), solved by kinemesh's own sweeps: 1, 3 and 6 columns,
 * aliased or not, against the residual and the LL' solution. */
static void test_cholesky_ldl(void) {
  const int n = 1500, nrhs = 6;
  km_sparse *A = random_spd(n, 0.1);
  km__cholesky_options co = {.kind = KM__CHOLESKY_SIMPLICIAL_LDL, .min_pivot = 1e-10};
  km_cholesky *ldl = NULL, *ll = NULL;
  CHECK_OK(km__cholesky_analyze_with(A, &co, &ldl, KM_E));
  CHECK_OK(km_cholesky_analyze(A, &ll, KM_E));
  if (!ldl || !ll) return;
  CHECK_OK(km_cholesky_factorize(ldl, A, KM_E));
  CHECK_OK(km_cholesky_factorize(ll, A, KM_E));
  double *B = malloc(n * nrhs * sizeof *B), *X = malloc(n * nrhs * sizeof *X);
  double *Y = malloc(n * nrhs * sizeof *Y);
  for (int i = 0; i < n * nrhs; ++i)
    B[i] = urand() - 0.5;
  const int ks[3] = {1, 3, 6};
  for (int t = 0; t < 3; ++t) {
    int k = ks[t];
    CHECK_OK(km_cholesky_solve(ldl, (size_t)k, B, X, KM_E));
    CHECK_MSG(residual(A, n, k, X, B) < 1e-12, "LDL' %d columns: residual %g", k,
              residual(A, n, k, X, B));
    CHECK_OK(km_cholesky_solve(ll, (size_t)k, B, Y, KM_E));
    double d = 0;
    for (int i = 0; i < n * k; ++i)
      d = fmax(d, fabs(X[i] - Y[i]));
    CHECK_MSG(d < 1e-10, "LDL' vs LL' %d columns: %g", k, d);
    memcpy(Y, B, n * k * sizeof *Y);
    CHECK_OK(km_cholesky_solve(ldl, (size_t)k, Y, Y, KM_E));
    CHECK(residual(A, n, k, Y, B) < 1e-12);
  }
  free(B), free(X), free(Y);
  km_cholesky_free(&ldl);
  km_cholesky_free(&ll);
  km_sparse_free(&A);
}

int main(void) {
  test_sparse();
  test_cholesky();
  test_blas_threads();
  test_cholesky_ldl();
  return km_test_finish("test_linalg");
}
