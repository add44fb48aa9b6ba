/* 3x3 rotation helpers (row-major) shared by pose fitting and motion generation. Small fixed
 * size: a BLAS call would cost more than the arithmetic. */
#ifndef KM_MOTION_ROT_H
#define KM_MOTION_ROT_H

#include <math.h>
#include <string.h>

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
