/* The k vertices nearest to a point (kinemesh pick): one pass with a sorted k-list; and the
 * nearest of many queries to one point set (km__nearest_x: sorted along x, a slab search). */
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

size_t km_nearest_vertices(const double *V, size_t n, const double p[3], size_t k, int32_t *ids,
                           double *dist) {
  if (!V || !p || !ids || k == 0) return 0;
  if (k > n) k = n;
  size_t cnt = 0;
  double *d2 = dist; /* squared distances while scanning when dist is given */
  double local[64];
  double *dd = d2 ? d2 : (k <= 64 ? local : NULL);
  if (!dd) {
    dd = km__malloc(k, sizeof *dd);
    if (!dd) return 0;
  }
  for (size_t v = 0; v < n; ++v) {
    const double *q = V + 3 * v;
    double d = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
               (q[2] - p[2]) * (q[2] - p[2]);
    if (!(d == d)) continue; /* NaN coordinates never match */
    if (cnt == k && d >= dd[k - 1]) continue;
    size_t pos = cnt < k ? cnt : k - 1;
    while (pos > 0 && dd[pos - 1] > d) {
      dd[pos] = dd[pos - 1];
      ids[pos] = ids[pos - 1];
      --pos;
    }
    dd[pos] = d;
    ids[pos] = (int32_t)v;
    if (cnt < k) ++cnt;
  }
  if (d2)
    for (size_t i = 0; i < cnt; ++i)
      d2[i] = sqrt(d2[i]);
  else if (dd != local)
    free(dd);
  return cnt;
}

typedef struct x_key {
  double x;
  int32_t v;
} x_key;

static int cmp_x(const void *a, const void *b) {
  const x_key *p = a, *q = b;
  return p->x < q->x ? -1 : p->x > q->x ? 1 : (p->v > q->v) - (p->v < q->v);
}

km_status km__nearest_x_build(const double *V, size_t n, km__nearest_x *out, km_error *err) {
  memset(out, 0, sizeof *out);
  x_key *k = km__malloc(n ? n : 1, sizeof *k);
  out->xs = km__malloc(n ? n : 1, sizeof *out->xs);
  out->ord = km__malloc(n ? n : 1, sizeof *out->ord);
  if (!k || !out->xs || !out->ord) {
    free(k);
    km__nearest_x_free(out);
    return km__fail(err, KM_ERR_NOMEM, "nearest: out of memory for %zu points", n);
  }
  size_t m = 0;
  for (size_t v = 0; v < n; ++v)
    if (V[3 * v] == V[3 * v] && V[3 * v + 1] == V[3 * v + 1] && V[3 * v + 2] == V[3 * v + 2])
      k[m].x = V[3 * v], k[m++].v = (int32_t)v; /* NaN points never match */
  qsort(k, m, sizeof *k, cmp_x);
  for (size_t i = 0; i < m; ++i)
    out->xs[i] = k[i].x, out->ord[i] = k[i].v;
  free(k);
  out->V = V;
  out->n = m;
  return KM_OK;
}

/* One point of the slab search: false once it lies farther along x than the best distance. */
static bool slab_visit(const km__nearest_x *ix, size_t i, const double p[3], double *best,
                       int32_t *id) {
  double dx = ix->xs[i] - p[0];
  if (dx * dx > *best) return false;
  const double *q = ix->V + 3 * (size_t)ix->ord[i];
  double d = dx * dx + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]);
  if (d < *best || (d == *best && ix->ord[i] < *id)) *best = d, *id = ix->ord[i];
  return true;
}

/* Outward from p's place along x, each side until the slab is wider than the best distance
 * found (ties: the lower id, as km_nearest_vertices). */
int32_t km__nearest_x_query(const km__nearest_x *ix, const double p[3]) {
  size_t lo = 0, hi = ix->n;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if (ix->xs[mid] < p[0])
      lo = mid + 1;
    else
      hi = mid;
  }
  double best = INFINITY;
  int32_t id = -1;
  for (size_t i = lo; i < ix->n && slab_visit(ix, i, p, &best, &id); ++i) {
  }
  for (size_t i = lo; i-- > 0 && slab_visit(ix, i, p, &best, &id);) {
  }
  return id;
}

void km__nearest_x_free(km__nearest_x *ix) {
  if (!ix) return;
  free(ix->xs);
  free(ix->ord);
  memset(ix, 0, sizeof *ix);
}
