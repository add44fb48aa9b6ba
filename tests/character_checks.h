/* Mesh and rig checks shared by test_character and test_character_large. Computed here from
 * scratch (sorting directed edges) so the character tests do not depend on the topology
 * module. */
#ifndef KM_CHARACTER_CHECKS_H
#define KM_CHARACTER_CHECKS_H

#include "km_test.h"

#include <stdint.h>

static int cc_cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

static uint64_t cc_key(int32_t a, int32_t b) { return (uint64_t)(uint32_t)a << 32 | (uint32_t)b; }

/* Index of directed edge a->b in the sorted array, -1 when absent. */
static ptrdiff_t cc_find(const uint64_t *keys, size_t n, uint64_t k) {
  size_t lo = 0, hi = n;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if ((keys[mid] >> 0) < k)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < n && keys[lo] == k ? (ptrdiff_t)lo : -1;
}

static int32_t cc_root(int32_t *p, int32_t x) {
  while (p[x] != x)
    x = p[x] = p[p[x]];
  return x;
}

typedef struct cc_topology {
  bool closed_oriented; /* every directed edge once, its reverse once */
  bool manifold;        /* one fan per vertex */
  size_t components;
  int64_t euler;
  double volume, min_area;
  double min_normal_dot;       /* over pairs of faces sharing an edge: -1 is a fold */
  double min_angle, max_angle; /* degrees, over all triangle corners */
  bool distinct_corners;
} cc_topology;

static void cc_topology_compute(const km_mesh *m, cc_topology *t) {
  memset(t, 0, sizeof *t);
  size_t nv = m->n_vertices, nf = m->n_faces, ne = 3 * nf;
  uint64_t *keys = malloc(ne * sizeof *keys);
  int32_t *face_of = malloc(ne * sizeof *face_of);
  uint64_t *tmp = malloc(ne * 2 * sizeof *tmp);
  int32_t *deg = calloc(nv, sizeof *deg);
  int32_t *par = malloc(nv * sizeof *par);
  /* Sort (key, face) pairs by key: pack face into a parallel array via an index sort. */
  for (size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      tmp[2 * (3 * f + k)] = cc_key(m->F[3 * f + k], m->F[3 * f + (k + 1) % 3]);
      tmp[2 * (3 * f + k) + 1] = f;
    }
  qsort(tmp, ne, 2 * sizeof *tmp, cc_cmp_u64);
  for (size_t i = 0; i < ne; ++i) {
    keys[i] = tmp[2 * i];
    face_of[i] = (int32_t)tmp[2 * i + 1];
  }
  t->closed_oriented = true;
  for (size_t i = 0; i < ne; ++i) {
    if (i + 1 < ne && keys[i + 1] == keys[i]) t->closed_oriented = false; /* duplicate */
    int32_t a = (int32_t)(keys[i] >> 32), b = (int32_t)(keys[i] & 0xffffffffu);
    if (cc_find(keys, ne, cc_key(b, a)) < 0) t->closed_oriented = false; /* border or flip */
  }
  /* Fans: walk around each vertex across edges, count the faces reached. */
  t->distinct_corners = true;
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *F = m->F + 3 * f;
    if (F[0] == F[1] || F[1] == F[2] || F[0] == F[2]) t->distinct_corners = false;
    for (int k = 0; k < 3; ++k)
      ++deg[F[k]];
  }
  unsigned char *seen = calloc(nv, 1);
  t->manifold = t->closed_oriented && t->distinct_corners;
  for (size_t f = 0; f < nf && t->manifold; ++f)
    for (int k = 0; k < 3 && t->manifold; ++k) {
      int32_t v = m->F[3 * f + k];
      if (seen[v]) continue;
      seen[v] = 1;
      size_t cur = f;
      int steps = 0;
      do {
        const int32_t *F = m->F + 3 * cur;
        int pos = F[0] == v ? 0 : F[1] == v ? 1 : 2;
        int32_t prev = F[(pos + 2) % 3];
        ptrdiff_t e = cc_find(keys, ne, cc_key(v, prev));
        if (e < 0) {
          t->manifold = false;
          break;
        }
        cur = (size_t)face_of[e];
        ++steps;
      } while (cur != f && steps <= deg[v]);
      if (steps != deg[v]) t->manifold = false;
    }
  free(seen);
  for (size_t i = 0; i < nv; ++i)
    par[i] = (int32_t)i;
  for (size_t f = 0; f < nf; ++f)
    for (int k = 1; k < 3; ++k) {
      int32_t a = cc_root(par, m->F[3 * f]), b = cc_root(par, m->F[3 * f + k]);
      if (a != b) par[a < b ? b : a] = a < b ? a : b;
    }
  size_t used = 0;
  for (size_t i = 0; i < nv; ++i) {
    if (deg[i]) ++used;
    if (deg[i] && cc_root(par, (int32_t)i) == (int32_t)i) ++t->components;
  }
  t->euler = (int64_t)used - (int64_t)(ne / 2) + (int64_t)nf;
  t->min_normal_dot = 1;
  if (t->closed_oriented)
    for (size_t i = 0; i < ne; ++i) {
      int32_t a = (int32_t)(keys[i] >> 32), b = (int32_t)(keys[i] & 0xffffffffu);
      if (a > b) continue;
      ptrdiff_t j = cc_find(keys, ne, cc_key(b, a));
      double n[2][3];
      for (int s = 0; s < 2; ++s) {
        const int32_t *F = m->F + 3 * (size_t)face_of[s ? (size_t)j : i];
        const double *p = m->V + 3 * (size_t)F[0], *q = m->V + 3 * (size_t)F[1],
                     *r = m->V + 3 * (size_t)F[2];
        double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
        double w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
        n[s][0] = u[1] * w[2] - u[2] * w[1];
        n[s][1] = u[2] * w[0] - u[0] * w[2];
        n[s][2] = u[0] * w[1] - u[1] * w[0];
        double l = sqrt(n[s][0] * n[s][0] + n[s][1] * n[s][1] + n[s][2] * n[s][2]);
        for (int k = 0; k < 3; ++k)
          n[s][k] /= l > 0 ? l : 1;
      }
      double d = n[0][0] * n[1][0] + n[0][1] * n[1][1] + n[0][2] * n[1][2];
      if (d < t->min_normal_dot) t->min_normal_dot = d;
    }
  t->min_angle = 180;
  t->max_angle = 0;
  for (size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const double *p = m->V + 3 * (size_t)m->F[3 * f + k];
      const double *q = m->V + 3 * (size_t)m->F[3 * f + (k + 1) % 3];
      const double *r = m->V + 3 * (size_t)m->F[3 * f + (k + 2) % 3];
      double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
      double w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
      double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                     u[0] * w[1] - u[1] * w[0]};
      double ang = atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                         u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) *
                   180 / M_PI;
      t->min_angle = fmin(t->min_angle, ang);
      t->max_angle = fmax(t->max_angle, ang);
    }
  t->min_area = INFINITY;
  for (size_t f = 0; f < nf; ++f) {
    const double *a = m->V + 3 * (size_t)m->F[3 * f], *b = m->V + 3 * (size_t)m->F[3 * f + 1],
                 *c = m->V + 3 * (size_t)m->F[3 * f + 2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    double area = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (area < t->min_area) t->min_area = area;
    t->volume += (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6.0;
  }
  free(keys);
  free(face_of);
  free(tmp);
  free(deg);
  free(par);
}

/* The checks every generated character must pass. */
static void cc_check_character(const km_character *c, size_t target, double height) {
  const km_mesh *m = &c->mesh;
  CHECK_MSG(m->n_vertices >= 0.9 * target && m->n_vertices <= 1.1 * target,
            "%zu vertices for target %zu", m->n_vertices, target);
  cc_topology t;
  cc_topology_compute(m, &t);
  CHECK(t.closed_oriented);
  CHECK(t.manifold);
  CHECK(t.distinct_corners);
  CHECK_MSG(t.components == 1, "%zu components", t.components);
  CHECK_MSG(t.euler == 2, "Euler characteristic %lld", (long long)t.euler);
  CHECK_MSG(t.volume > 0, "signed volume %g", t.volume);
  /* No face folded over its neighbour (coarse meshes have creases near 120 degrees). */
  CHECK_MSG(t.min_normal_dot > -0.8, "adjacent face normals at %g", t.min_normal_dot);
  /* Relaxation + Delaunay flips give about 20..123 degrees on the default subject (6..156 at
   * worst on extreme shapes at 2-8k vertices); raw marching tetrahedra has slivers near 0
   * and 180. */
  CHECK_MSG(t.min_angle > 5 && t.max_angle < 165, "angles %.2f..%.2f degrees", t.min_angle,
            t.max_angle);
  /* Average triangle area is ~1.9 m^2 / #F; demand no face below 1e-4 of it. */
  double avg = 1.9 / (double)m->n_faces;
  CHECK_MSG(t.min_area > 1e-4 * avg, "min face area %g (average %g)", t.min_area, avg);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < m->n_vertices; ++v)
    for (int k = 0; k < 3; ++k) {
      lo[k] = fmin(lo[k], m->V[3 * v + k]);
      hi[k] = fmax(hi[k], m->V[3 * v + k]);
    }
  CHECK_NEAR(hi[1] - lo[1], height, 0.02 * height);
  CHECK_NEAR(lo[1], 0.0, 0.01 * height);
  CHECK_NEAR(lo[0] + hi[0], 0.0, 0.01 * height); /* centred, symmetric arms */
  CHECK(hi[0] - lo[0] > 0.8 * height);           /* T-pose arm span */
}

#endif
