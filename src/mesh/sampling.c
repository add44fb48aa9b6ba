/* Farthest-point sampling of mesh vertices (km_farthest_points). Hand-written: a dozen lines
 * of O(k n) distance updates that none of the project's dependencies offers on their own. */
#include "core/core.h"

#include <math.h>
#include <stdlib.h>

km_status km_farthest_points(const km_mesh *m, size_t k, int32_t *ids, km_error *err) {
  if (!m || (k && !ids)) return km__fail(err, KM_ERR_INVALID, "km_farthest_points: NULL argument");
  if (k == 0) return KM_OK;
  size_t n = m->n_vertices;
  if (!m->V || !m->F || m->n_faces == 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "km_farthest_points: the mesh has no faces");
  /* Only vertices used by a face: an isolated vertex is no place for a landmark. */
  unsigned char *used = km__calloc(n, 1);
  double *d = km__malloc(n, sizeof(double));
  if (!used || !d) {
    free(used);
    free(d);
    return km__fail(err, KM_ERR_NOMEM, "km_farthest_points: out of memory (%zu vertices)", n);
  }
  size_t n_used = 0;
  for (size_t f = 0; f < 3 * m->n_faces; ++f) {
    int32_t v = m->F[f];
    if (v >= 0 && (size_t)v < n && !used[v]) used[v] = 1, ++n_used;
  }
  km_status s = KM_OK;
  if (k > n_used) {
    s = km__fail(err, KM_ERR_INVALID,
                 "km_farthest_points: %zu points asked of a mesh with %zu vertices in faces", k,
                 n_used);
    goto done;
  }
  double c[3] = {0, 0, 0};
  for (size_t v = 0; v < n; ++v)
    if (used[v])
      for (int a = 0; a < 3; ++a)
        c[a] += m->V[3 * v + a] / (double)n_used;
  for (size_t v = 0; v < n; ++v) {
    const double *p = m->V + 3 * v;
    d[v] = used[v] ? (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                         (p[2] - c[2]) * (p[2] - c[2])
                   : -1;
  }
  for (size_t i = 0; i < k; ++i) {
    size_t far = 0;
    for (size_t v = 1; v < n; ++v)
      if (d[v] > d[far]) far = v;
    if (i > 0 && !(d[far] > 0)) {
      s = km__fail(err, KM_ERR_DEGENERATE_MESH,
                   "km_farthest_points: only %zu distinct vertex positions, %zu asked", i, k);
      goto done;
    }
    ids[i] = (int32_t)far;
    /* from here on d is the squared distance to the nearest point taken */
    const double *q = m->V + 3 * far;
    for (size_t v = 0; v < n; ++v) {
      if (!used[v]) continue;
      const double *p = m->V + 3 * v;
      double e = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                 (p[2] - q[2]) * (p[2] - q[2]);
      if (i == 0 || e < d[v]) d[v] = e;
    }
  }
done:
  free(used);
  free(d);
  return s;
}
