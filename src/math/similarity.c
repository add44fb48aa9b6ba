/* The one rigid / similarity fit of the library (Umeyama 1991 on Kabsch's SVD). Horn's
 * quaternion method (recon) and a separate Kabsch (skinning) were folded into it: all three
 * solve the same least-squares problem, and one SVD core with one reflection fix keeps their
 * answers (and their degenerate cases) the same. */
#include "core/core.h"
#include "linalg/linalg.h"
#include "math/math.h"

double km__rotation_fit3(const double H[9], double R[9], double S[3]) {
  double A[9], U[9], Vt[9];
  memcpy(A, H, sizeof A);
  if (km__svd3(A, S, U, Vt) != 0) {
    S[0] = S[1] = S[2] = 0;
    km__m3_identity(R);
    return -1;
  }
  /* R = V diag(1,1,sign det(V U^T)) U^T */
  double V[9], Ut[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      V[3 * i + j] = Vt[3 * j + i];
      Ut[3 * i + j] = U[3 * j + i];
    }
  double M[9];
  km__m3_mul(V, Ut, M);
  double det = M[0] * (M[4] * M[8] - M[5] * M[7]) - M[1] * (M[3] * M[8] - M[5] * M[6]) +
               M[2] * (M[3] * M[7] - M[4] * M[6]);
  if (det < 0)
    for (int i = 0; i < 3; ++i)
      V[3 * i + 2] = -V[3 * i + 2];
  km__m3_mul(V, Ut, R);
  return S[0] + S[1] + (det < 0 ? -S[2] : S[2]);
}

km_status km_similarity_fit(const double *src, const double *dst, const double *weights, size_t n,
                            bool with_scale, double *s, double R[9], double t[3], km_error *err) {
  if (!src || !dst || !R || !t || (with_scale && !s))
    return km__fail(err, KM_ERR_INVALID, "km_similarity_fit: NULL argument");
  if (n < 3) return km__fail(err, KM_ERR_INVALID, "km_similarity_fit: %zu points, need >= 3", n);
  double wsum = 0, ms[3] = {0, 0, 0}, md[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    double w = weights ? weights[i] : 1.0;
    if (!(w >= 0) || !isfinite(w))
      return km__fail(err, KM_ERR_INVALID, "km_similarity_fit: weight %zu is %g, expected >= 0", i,
                      w);
    for (int c = 0; c < 3; ++c) {
      if (!isfinite(src[3 * i + c]) || !isfinite(dst[3 * i + c]))
        return km__fail(err, KM_ERR_INVALID, "km_similarity_fit: point %zu is not finite", i);
      ms[c] += w * src[3 * i + c];
      md[c] += w * dst[3 * i + c];
    }
    wsum += w;
  }
  if (!(wsum > 0)) return km__fail(err, KM_ERR_INVALID, "km_similarity_fit: all weights are 0");
  for (int c = 0; c < 3; ++c)
    ms[c] /= wsum, md[c] /= wsum;
  /* H = sum w (s - ms)(d - md)^T / wsum, var_s = sum w |s - ms|^2 / wsum. */
  double H[9] = {0}, var = 0;
  for (size_t i = 0; i < n; ++i) {
    double w = (weights ? weights[i] : 1.0) / wsum;
    double a[3], b[3];
    for (int c = 0; c < 3; ++c)
      a[c] = src[3 * i + c] - ms[c], b[c] = dst[3 * i + c] - md[c];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        H[3 * r + c] += w * a[r] * b[c];
    var += w * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  }
  if (!(var > 0))
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "km_similarity_fit: the %zu source points coincide", n);
  double S[3];
  double trace = km__rotation_fit3(H, R, S);
  if (trace < 0) return km__fail(err, KM_ERR_NO_CONVERGENCE, "km_similarity_fit: SVD failed");
  /* Collinear points leave the rotation about their line undetermined. */
  if (!(S[1] > 1e-12 * S[0]))
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "km_similarity_fit: the %zu point pairs are collinear", n);
  double sc = with_scale ? trace / var : 1;
  if (s) *s = sc;
  for (int r = 0; r < 3; ++r)
    t[r] = md[r] - sc * (R[3 * r] * ms[0] + R[3 * r + 1] * ms[1] + R[3 * r + 2] * ms[2]);
  return KM_OK;
}
