/* Requires: core, linalg. */
/* Small 3x3 rotation helpers shared by the deformation solvers. Row-major 3x3 matrices.
 *
 * These run per vertex / per triangle inside real-time loops, where a LAPACK call
 * (dgesvd on a 3x3, ~2-5 us of call and workspace overhead) would dominate the frame, so the
 * 3x3 polar decomposition is done in closed form here: cyclic Jacobi on the symmetric
 * 3x3 A^T A (converges to machine precision in 4-6 sweeps). */
#ifndef KM_MATH_MATH_H
#define KM_MATH_MATH_H

#include "kinemesh.h"

#include <math.h>
#include <string.h>

/* The best rotation R (det +1, row-major) with R a_i ~ b_i from the cross-covariance
 * H = sum_i w_i a_i b_i^T (row-major; Kabsch by a 3x3 SVD, reflection-corrected).
 * S: H's singular values, descending (S[1] ~ 0: the a_i are collinear and R's turn about
 * their line is arbitrary). Returns the trace of R H (the Umeyama scale's numerator), or -1
 * when the SVD failed (R identity). Used by km_similarity_fit (similarity.c). */
double km__rotation_fit3(const double H[9], double R[9], double S[3]);

/* The one forward kinematics (skinning.c), over joints in parent-first order (parents[j] < j,
 * -1 for a root): W_j = W_parent L_j and P_j = P_parent + W_parent o_j; a root has W_j = L_j,
 * P_j = o_j. L n*9 local rotations (row-major), o n*3 offsets from the parent (a root: its
 * position); out W n*9 world rotations, P n*3 world positions (P may be o: in place). */
void km__forward_kinematics(size_t n, const int32_t *parents, const double *L, const double *o,
                            double *W, double *P);
/* Rigid 3x4 transforms (row-major [R | t], as km_lbs takes them) that move rest joint J_j to
 * P_j turned by W_j: G_j x = W_j (x - J_j) + P_j. W n*9, P n*3, rest n*3, G n*12. */
void km__joint_transforms(size_t n, const double *W, const double *P, const double *rest,
                          double *G);

/* The one "keep the largest influences" step of every skin writer (skinning.c): one vertex's
 * weight per joint w (n of them; a weight <= 0 or NaN is no influence) becomes its
 * KM_SKIN_INFLUENCES slots, the largest first (a tie keeps the lower joint), normalised to sum
 * 1; unused slots are joint -1, weight 0. Returns how many it kept (0: no joint had weight). */
int km__skin_keep_largest(const double *w, int n, int32_t *joints, double *weights);

/* Whether one vertex's KM_SKIN_INFLUENCES slots give it no influence (no slot with a joint >= 0
 * and a weight > 0): a km_skin row that stays where it is (km_lbs keeps it at rest; a ground
 * plane km_autorig left out of the skin). */
bool km__skin_row_empty(const int32_t *joints, const double *weights);

/* The joint of one vertex's largest skin weight (its body part): joints, weights its
 * KM_SKIN_INFLUENCES slots; slot 0's joint when no used slot (joint >= 0) weighs more. */
int32_t km__skin_dominant(const int32_t *joints, const double *weights);

/* qsort comparator for doubles, ascending. */
static inline int km__cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static inline void km__cross3(const double *a, const double *b, double *c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double km__dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* o = a - b */
static inline void km__sub3(const double *a, const double *b, double *o) {
  o[0] = a[0] - b[0];
  o[1] = a[1] - b[1];
  o[2] = a[2] - b[2];
}

static inline bool km__finite3(const double *p) {
  return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* Normalises in place; returns the old length (vector untouched when it is ~0). */
static inline double km__normalize3(double *a) {
  double l = sqrt(km__dot3(a, a));
  if (l > 1e-300) {
    double inv = 1 / l; /* one division: this runs per triangle per iteration */
    a[0] *= inv;
    a[1] *= inv;
    a[2] *= inv;
  }
  return l;
}

/* Any unit vector orthogonal to unit a. */
static inline void km__any_perp3(const double *a, double *p) {
  double e[3] = {0, 0, 0};
  int i = fabs(a[0]) < fabs(a[1]) ? (fabs(a[0]) < fabs(a[2]) ? 0 : 2)
                                  : (fabs(a[1]) < fabs(a[2]) ? 1 : 2);
  e[i] = 1;
  km__cross3(a, e, p);
  km__normalize3(p);
}

/* Eigen-decomposition of symmetric S (row-major, destroyed): eigenvalues in ev, eigenvectors
 * as the columns of V (row-major), sorted by decreasing eigenvalue. */
static inline void km__sym_eig3(double *S, double *ev, double *V) {
  double v[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int sweep = 0; sweep < 12; ++sweep) {
    double off = S[1] * S[1] + S[2] * S[2] + S[5] * S[5];
    double diag = S[0] * S[0] + S[4] * S[4] + S[8] * S[8];
    if (off <= 1e-30 * diag || off == 0) break;
    for (int pq = 0; pq < 3; ++pq) {
      int p = pq == 2 ? 1 : 0, q = pq == 0 ? 1 : 2;
      double apq = S[p * 3 + q];
      if (apq == 0) continue;
      double theta = (S[q * 3 + q] - S[p * 3 + p]) / (2 * apq);
      double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
      double c = 1 / sqrt(t * t + 1), s = t * c;
      /* S <- J^T S J with the rotation in the (p,q) plane */
      for (int k = 0; k < 3; ++k) {
        double skp = S[k * 3 + p], skq = S[k * 3 + q];
        S[k * 3 + p] = c * skp - s * skq;
        S[k * 3 + q] = s * skp + c * skq;
      }
      for (int k = 0; k < 3; ++k) {
        double spk = S[p * 3 + k], sqk = S[q * 3 + k];
        S[p * 3 + k] = c * spk - s * sqk;
        S[q * 3 + k] = s * spk + c * sqk;
      }
      for (int k = 0; k < 3; ++k) {
        double vkp = v[k * 3 + p], vkq = v[k * 3 + q];
        v[k * 3 + p] = c * vkp - s * vkq;
        v[k * 3 + q] = s * vkp + c * vkq;
      }
    }
  }
  double d[3] = {S[0], S[4], S[8]};
  int o[3] = {0, 1, 2};
  for (int i = 0; i < 2; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (d[o[j]] > d[o[i]]) {
        int t = o[i];
        o[i] = o[j];
        o[j] = t;
      }
  for (int c = 0; c < 3; ++c) {
    ev[c] = d[o[c]];
    for (int r = 0; r < 3; ++r)
      V[r * 3 + c] = v[r * 3 + o[c]];
  }
}

/* The rotation R (det +1) closest to A in Frobenius norm (Kabsch / polar with reflection
 * fix): R = U diag(1,1,det) V^T for A = U S V^T. Rank-2 A (a flat neighbourhood) is fine. */
static inline void km__nearest_rotation3(const double *A, double *R) {
  double S[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      S[i * 3 + j] =
          A[0 * 3 + i] * A[0 * 3 + j] + A[1 * 3 + i] * A[1 * 3 + j] + A[2 * 3 + i] * A[2 * 3 + j];
  double ev[3], V[9];
  km__sym_eig3(S, ev, V);
  double v1[3] = {V[0], V[3], V[6]}, v2[3] = {V[1], V[4], V[7]}, v3[3];
  km__cross3(v1, v2, v3);
  double u1[3], u2[3], u3[3];
  for (int r = 0; r < 3; ++r) {
    u1[r] = A[r * 3 + 0] * v1[0] + A[r * 3 + 1] * v1[1] + A[r * 3 + 2] * v1[2];
    u2[r] = A[r * 3 + 0] * v2[0] + A[r * 3 + 1] * v2[1] + A[r * 3 + 2] * v2[2];
  }
  if (km__normalize3(u1) <= 1e-300) {
    memcpy(R, (double[9]){1, 0, 0, 0, 1, 0, 0, 0, 1}, 9 * sizeof(double));
    return;
  }
  double d = km__dot3(u1, u2);
  for (int r = 0; r < 3; ++r)
    u2[r] -= d * u1[r];
  if (km__normalize3(u2) <= 1e-12 * sqrt(fabs(ev[0])) + 1e-300) km__any_perp3(u1, u2);
  km__cross3(u1, u2, u3);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      R[i * 3 + j] = u1[i] * v1[j] + u2[i] * v2[j] + u3[i] * v3[j];
}

/* Unit quaternion (w,x,y,z) of rotation R (Shepperd's method, stable for every angle). */
static inline void km__quat_from_rot3(const double *R, double *q) {
  double tr = R[0] + R[4] + R[8];
  if (tr > 0) {
    double s = sqrt(tr + 1.0) * 2, is = 1 / s;
    q[0] = 0.25 * s;
    q[1] = (R[7] - R[5]) * is;
    q[2] = (R[2] - R[6]) * is;
    q[3] = (R[3] - R[1]) * is;
  } else if (R[0] > R[4] && R[0] > R[8]) {
    double s = sqrt(1.0 + R[0] - R[4] - R[8]) * 2, is = 1 / s;
    q[0] = (R[7] - R[5]) * is;
    q[1] = 0.25 * s;
    q[2] = (R[1] + R[3]) * is;
    q[3] = (R[2] + R[6]) * is;
  } else if (R[4] > R[8]) {
    double s = sqrt(1.0 + R[4] - R[0] - R[8]) * 2, is = 1 / s;
    q[0] = (R[2] - R[6]) * is;
    q[1] = (R[1] + R[3]) * is;
    q[2] = 0.25 * s;
    q[3] = (R[5] + R[7]) * is;
  } else {
    double s = sqrt(1.0 + R[8] - R[0] - R[4]) * 2, is = 1 / s;
    q[0] = (R[3] - R[1]) * is;
    q[1] = (R[2] + R[6]) * is;
    q[2] = (R[5] + R[7]) * is;
    q[3] = 0.25 * s;
  }
}

/* Rotation matrix of a unit quaternion. */
static inline void km__rot3_from_quat(const double *q, double *R) {
  double w = q[0], x = q[1], y = q[2], z = q[3];
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
}

/* out = slerp(A, B, alpha) for rotations A, B (row-major): the rotation alpha of the way from
 * A to B along the shorter arc (alpha 0: A, 1: B). out may alias A or B. */
static inline void km__rot3_slerp(const double *A, const double *B, double alpha, double *out) {
  double q0[4], q1[4], q[4];
  km__quat_from_rot3(A, q0);
  km__quat_from_rot3(B, q1);
  double dot = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3];
  if (dot < 0) {
    dot = -dot;
    for (int i = 0; i < 4; ++i)
      q1[i] = -q1[i];
  }
  double th = acos(fmin(1.0, dot)), w0 = 1 - alpha, w1 = alpha;
  if (th > 1e-6) w0 = sin((1 - alpha) * th) / sin(th), w1 = sin(alpha * th) / sin(th);
  double n = 0;
  for (int i = 0; i < 4; ++i)
    q[i] = w0 * q0[i] + w1 * q1[i], n += q[i] * q[i];
  n = sqrt(n);
  for (int i = 0; i < 4; ++i)
    q[i] /= n;
  km__rot3_from_quat(q, out);
}

/* The angle (radians, 0 .. pi) of the rotation taking B to A (row-major 3x3 rotations):
 * trace(A B^T) = 1 + 2 cos(angle). */
static inline double km__rot3_angle_between(const double *A, const double *B) {
  double tr = 0;
  for (int i = 0; i < 9; ++i)
    tr += A[i] * B[i];
  return acos(fmax(-1.0, fmin(1.0, 0.5 * (tr - 1))));
}

/* Orthonormal frame of triangle (a,b,c) as rows: t (unit edge a->b), n x t, n (unit normal).
 * Returns twice the area (0: degenerate, frame undefined). */
static inline double km__tri_frame(const double *a, const double *b, const double *c, double *F) {
  double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3];
  km__cross3(e1, e2, n);
  double area2 = km__normalize3(n);
  if (area2 <= 1e-300 || km__normalize3(e1) <= 1e-300) return 0;
  double bt[3];
  km__cross3(n, e1, bt);
  memcpy(F, e1, sizeof e1);
  memcpy(F + 3, bt, sizeof bt);
  memcpy(F + 6, n, sizeof n);
  return area2;
}

/* ---- from the motion helpers: 3x3 products and axis rotations */

static inline void km__m3_identity(double R[9]) {
  static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  memcpy(R, I, sizeof I);
}

/* C = A B (C may alias A or B). */
static inline void km__m3_mul(const double A[9], const double B[9], double C[9]) {
  double T[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      T[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
  memcpy(C, T, sizeof T);
}

/* y = R x (y may alias x). */
static inline void km__m3_apply(const double R[9], const double x[3], double y[3]) {
  double t0 = R[0] * x[0] + R[1] * x[1] + R[2] * x[2];
  double t1 = R[3] * x[0] + R[4] * x[1] + R[5] * x[2];
  double t2 = R[6] * x[0] + R[7] * x[1] + R[8] * x[2];
  y[0] = t0, y[1] = t1, y[2] = t2;
}

/* y = R^T x (y may alias x). */
static inline void km__m3_apply_t(const double R[9], const double x[3], double y[3]) {
  double t0 = R[0] * x[0] + R[3] * x[1] + R[6] * x[2];
  double t1 = R[1] * x[0] + R[4] * x[1] + R[7] * x[2];
  double t2 = R[2] * x[0] + R[5] * x[1] + R[8] * x[2];
  y[0] = t0, y[1] = t1, y[2] = t2;
}

/* Rotation of the rotation vector r (axis * angle in radians; Rodrigues), series near 0. */
static inline void km__m3_from_rotvec(const double r[3], double R[9]) {
  double th = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  double K[9] = {0, -r[2], r[1], r[2], 0, -r[0], -r[1], r[0], 0}, K2[9];
  km__m3_mul(K, K, K2);
  double a, b;
  if (th < 1e-6)
    a = 1 - th * th / 6, b = 0.5 - th * th / 24;
  else
    a = sin(th) / th, b = (1 - cos(th)) / (th * th);
  for (int i = 0; i < 9; ++i)
    R[i] = (i % 4 == 0) + a * K[i] + b * K2[i];
}

/* The shortest rotation R (row-major) taking unit a onto unit b (Rodrigues: I + K + K^2 / (1 + c),
 * K the cross-product matrix of a x b, c = a . b); opposite directions give a half turn about
 * km__any_perp3(a). The one used by skinning and the retargeter. */
static inline void km__rot3_between(const double a[3], const double b[3], double R[9]) {
  double c = km__dot3(a, b);
  if (c < -1 + 1e-12) {
    double u[3];
    km__any_perp3(a, u);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        R[3 * i + j] = 2 * u[i] * u[j] - (i == j);
    return;
  }
  double v[3];
  km__cross3(a, b, v);
  double K[9] = {0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0}, K2[9];
  km__m3_mul(K, K, K2);
  double f = 1 / (1 + c);
  for (int i = 0; i < 9; ++i)
    R[i] = (i % 4 == 0) + K[i] + f * K2[i];
}

/* Rotation by angle a (radians) about a coordinate axis (0 x, 1 y, 2 z), right-handed. */
static inline void km__m3_axis(int axis, double a, double R[9]) {
  double c = cos(a), s = sin(a);
  km__m3_identity(R);
  int i = (axis + 1) % 3, j = (axis + 2) % 3;
  R[3 * i + i] = c;
  R[3 * i + j] = -s;
  R[3 * j + i] = s;
  R[3 * j + j] = c;
}

#endif
