/* Primitive meshes for tests and examples. */
#include "synth/synth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KM_ICOSPHERE_MAX_SUBDIV 10

/* Plain allocation instead of km_mesh_alloc so this file depends on nothing but libc; the
 * result is freed the same way (free V and F). */
static km_status alloc_mesh(size_t nv, size_t nf, km_mesh *out, const char *who, km_error *err) {
  memset(out, 0, sizeof *out); /* UV and N (issue 11) stay NULL */
  out->V = km__malloc(nv, 3 * sizeof(double));
  out->F = km__malloc(nf, 3 * sizeof(int32_t));
  if (!out->V || !out->F) {
    free(out->V), free(out->F);
    memset(out, 0, sizeof *out);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory (%zu vertices)", who, nv);
  }
  out->n_vertices = nv;
  out->n_faces = nf;
  return KM_OK;
}

static void free_mesh(km_mesh *m) {
  free(m->V), free(m->F);
  memset(m, 0, sizeof *m);
}

/* Midpoint of edge (a,b), created once per edge: an open-addressing table keyed by the
 * ordered pair. Sized to a power of two at least twice the number of edges. */
typedef struct edge_table {
  uint64_t *keys; /* (min << 32 | max) + 1, 0 = empty */
  int32_t *vals;
  size_t mask;
} edge_table;

static int32_t midpoint(edge_table *et, int32_t a, int32_t b, double *V, int32_t *nv,
                        double radius) {
  uint64_t lo = (uint64_t)(a < b ? a : b), hi = (uint64_t)(a < b ? b : a);
  uint64_t key = ((lo << 32) | hi) + 1;
  size_t h = (size_t)((key * 0x9E3779B97F4A7C15ULL) >> 17) & et->mask;
  while (et->keys[h] && et->keys[h] != key)
    h = (h + 1) & et->mask;
  if (et->keys[h]) return et->vals[h];
  int32_t v = (*nv)++;
  double *p = V + 3 * (size_t)v, *pa = V + 3 * (size_t)a, *pb = V + 3 * (size_t)b;
  for (int c = 0; c < 3; ++c)
    p[c] = 0.5 * (pa[c] + pb[c]);
  double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
  for (int c = 0; c < 3; ++c)
    p[c] *= radius / l;
  et->keys[h] = key;
  et->vals[h] = v;
  return v;
}

km_status km_icosphere(int subdivisions, double radius, km_mesh *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_icosphere: out is NULL");
  memset(out, 0, sizeof *out);
  if (subdivisions < 0 || subdivisions > KM_ICOSPHERE_MAX_SUBDIV)
    return km__fail(err, KM_ERR_INVALID, "km_icosphere: subdivisions %d, expected 0..%d",
                    subdivisions, KM_ICOSPHERE_MAX_SUBDIV);
  if (!(radius > 0) || !isfinite(radius))
    return km__fail(err, KM_ERR_INVALID, "km_icosphere: radius %g, expected > 0", radius);
  size_t nv = 10 * ((size_t)1 << (2 * subdivisions)) + 2;
  size_t nf = 20 * ((size_t)1 << (2 * subdivisions));
  km_status s = alloc_mesh(nv, nf, out, "km_icosphere", err);
  if (s) return s;
  int32_t *F2 = km__malloc(nf * 3, sizeof *F2);
  size_t cap = 1;
  while (cap < 3 * nf)
    cap <<= 1; /* > 2x the edges of the last level (nf*3/2) */
  edge_table et = {km__calloc(cap, sizeof(uint64_t)), km__malloc(cap, sizeof(int32_t)), cap - 1};
  if (!F2 || !et.keys || !et.vals) {
    free(F2), free(et.keys), free(et.vals);
    free_mesh(out);
    return km__fail(err, KM_ERR_NOMEM, "km_icosphere: out of memory (%zu vertices)", nv);
  }
  const double g = (1 + sqrt(5.0)) / 2;
  const double ico_v[12][3] = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
                               {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
                               {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  /* counter-clockwise seen from outside */
  const int32_t ico_f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  double l0 = sqrt(1 + g * g);
  for (int i = 0; i < 12; ++i)
    for (int c = 0; c < 3; ++c)
      out->V[3 * i + c] = ico_v[i][c] * radius / l0;
  memcpy(out->F, ico_f, sizeof ico_f);
  int32_t n_v = 12;
  size_t n_f = 20;
  int32_t *F = out->F, *G = F2;
  for (int level = 0; level < subdivisions; ++level) {
    memset(et.keys, 0, cap * sizeof *et.keys);
    for (size_t f = 0; f < n_f; ++f) {
      int32_t a = F[3 * f], b = F[3 * f + 1], c = F[3 * f + 2];
      int32_t ab = midpoint(&et, a, b, out->V, &n_v, radius);
      int32_t bc = midpoint(&et, b, c, out->V, &n_v, radius);
      int32_t ca = midpoint(&et, c, a, out->V, &n_v, radius);
      int32_t *o = G + 12 * f;
      int32_t tri[12] = {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca};
      memcpy(o, tri, sizeof tri);
    }
    n_f *= 4;
    int32_t *tmp = F;
    F = G;
    G = tmp;
  }
  if (F != out->F) memcpy(out->F, F, nf * 3 * sizeof *F);
  free(F2);
  free(et.keys);
  free(et.vals);
  return KM_OK;
}

km_status km_grid(int nx, int ny, double sx, double sy, km_mesh *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_grid: out is NULL");
  memset(out, 0, sizeof *out);
  if (nx < 1 || ny < 1 || (double)(nx + 1) * (ny + 1) > INT32_MAX / 4)
    return km__fail(err, KM_ERR_INVALID,
                    "km_grid: %d x %d cells, expected >= 1 and fewer "
                    "than 2^29 vertices",
                    nx, ny);
  if (!(sx > 0) || !(sy > 0) || !isfinite(sx) || !isfinite(sy))
    return km__fail(err, KM_ERR_INVALID, "km_grid: size %g x %g, expected > 0", sx, sy);
  size_t w = (size_t)nx + 1;
  km_status s = alloc_mesh(w * ((size_t)ny + 1), 2 * (size_t)nx * ny, out, "km_grid", err);
  if (s) return s;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      double *p = out->V + 3 * (j * w + i);
      p[0] = sx * i / nx, p[1] = sy * j / ny, p[2] = 0;
    }
  int32_t *f = out->F;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      int32_t a = (int32_t)(j * w + i), b = a + 1, c = a + (int32_t)w + 1, d = a + (int32_t)w;
      /* counter-clockwise seen from +z */
      f[0] = a, f[1] = b, f[2] = c, f[3] = a, f[4] = c, f[5] = d;
      f += 6;
    }
  return KM_OK;
}

km_status km_cylinder(int segments, int rings, double radius, double length, km_mesh *out,
                      km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_cylinder: out is NULL");
  memset(out, 0, sizeof *out);
  if (segments < 3 || rings < 1 || (double)segments * (rings + 1) > INT32_MAX / 4)
    return km__fail(err, KM_ERR_INVALID,
                    "km_cylinder: %d segments, %d rings, expected segments >= 3, rings >= 1 "
                    "and fewer than 2^29 vertices",
                    segments, rings);
  if (!(radius > 0) || !(length > 0) || !isfinite(radius) || !isfinite(length))
    return km__fail(err, KM_ERR_INVALID, "km_cylinder: radius %g, length %g, expected > 0", radius,
                    length);
  size_t S = (size_t)segments, R = (size_t)rings;
  size_t nv = (R + 1) * S + 2, nf = 2 * R * S + 2 * S;
  km_status s = alloc_mesh(nv, nf, out, "km_cylinder", err);
  if (s) return s;
  const double two_pi = 6.283185307179586476925286766559;
  for (size_t r = 0; r <= R; ++r)
    for (size_t k = 0; k < S; ++k) {
      double th = two_pi * (double)k / (double)S, *p = out->V + 3 * (r * S + k);
      p[0] = radius * cos(th), p[1] = radius * sin(th), p[2] = length * (double)r / (double)R;
    }
  int32_t cb = (int32_t)((R + 1) * S), ct = cb + 1;
  double *p = out->V + 3 * (size_t)cb;
  p[0] = p[1] = p[2] = 0;
  p[3] = p[4] = 0, p[5] = length;
  int32_t *f = out->F;
  for (size_t r = 0; r < R; ++r)
    for (size_t k = 0; k < S; ++k) {
      int32_t a = (int32_t)(r * S + k), b = (int32_t)(r * S + (k + 1) % S);
      int32_t c = b + (int32_t)S, d = a + (int32_t)S;
      /* (theta, z) is counter-clockwise seen from outside since r x theta = z */
      f[0] = a, f[1] = b, f[2] = c, f[3] = a, f[4] = c, f[5] = d;
      f += 6;
    }
  for (size_t k = 0; k < S; ++k) {
    int32_t a = (int32_t)k, b = (int32_t)((k + 1) % S);
    f[0] = cb, f[1] = b, f[2] = a; /* bottom cap faces -z */
    f[3] = ct, f[4] = a + (int32_t)(R * S), f[5] = b + (int32_t)(R * S);
    f += 6;
  }
  return KM_OK;
}
