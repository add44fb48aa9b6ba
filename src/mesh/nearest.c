/* The k vertices nearest to a point (kinemesh pick): one pass with a sorted k-list. */
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>

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
