/* Per-vertex normals: a scatter of weighted face normals over the faces. */
#include "core/core.h"
#include "mesh/mesh_args.h"

#include <math.h>
#include <string.h>

km_status km_vertex_normals(const km_mesh *m, km_normal_weighting w, double *N, km_error *err) {
  km_status s = km__mesh_check_faces(m, "km_vertex_normals", err);
  if (s) return s;
  if (w != KM_NORMALS_AREA && w != KM_NORMALS_ANGLE)
    return km__fail(err, KM_ERR_INVALID, "km_vertex_normals: unknown weighting %d", (int)w);
  if (m->n_vertices && !N) return km__fail(err, KM_ERR_INVALID, "km_vertex_normals: N is NULL");
  if (m->n_vertices) memset(N, 0, m->n_vertices * 3 * sizeof *N);
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    const double *p[3] = {m->V + 3 * (size_t)t[0], m->V + 3 * (size_t)t[1],
                          m->V + 3 * (size_t)t[2]};
    double u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    double v[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    /* |u x v| = 2 * area: unnormalised, it is already the area weight */
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0) || !isfinite(len)) continue; /* degenerate: no direction to contribute */
    for (int c = 0; c < 3; ++c) {
      double wt = 1;
      if (w == KM_NORMALS_ANGLE) {
        const double *a = p[c], *b = p[(c + 1) % 3], *d = p[(c + 2) % 3];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]};
        /* atan2 of |cross| and dot is accurate for tiny and near-straight angles */
        double ang = atan2(sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]),
                           e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]);
        wt = ang / len;
      }
      double *o = N + 3 * (size_t)t[c];
      o[0] += wt * n[0];
      o[1] += wt * n[1];
      o[2] += wt * n[2];
    }
  }
  for (size_t v = 0; v < m->n_vertices; ++v) {
    double *o = N + 3 * v;
    double len = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    if (len > 0 && isfinite(len)) {
      o[0] /= len, o[1] /= len, o[2] /= len;
    } else {
      o[0] = o[1] = o[2] = 0;
    }
  }
  return KM_OK;
}
