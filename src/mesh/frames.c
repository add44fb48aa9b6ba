/* Per-vertex local frames (normal, tangent, bitangent) that follow the surface across poses
 * of one connectivity: the tangent is always the projected edge to the same neighbour. */
#include "core/core.h"
#include "math/math.h"
#include "mesh/mesh.h"
#include "mesh/mesh_args.h"

#include <math.h>

km_status km_frame_neighbors(const km_mesh *m, int32_t *ref, km_error *err) {
  km_status s = km__mesh_check_faces(m, "km_frame_neighbors", err);
  if (s) return s;
  if (m->n_vertices && !ref)
    return km__fail(err, KM_ERR_INVALID, "km_frame_neighbors: ref is NULL");
  for (size_t v = 0; v < m->n_vertices; ++v)
    ref[v] = -1;
  /* The lowest-index neighbour over the face corners: one pass, no adjacency needed. */
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    for (int c = 0; c < 3; ++c) {
      int32_t v = t[c];
      for (int d = 1; d < 3; ++d) {
        int32_t u = t[(c + d) % 3];
        if (u != v && (ref[v] < 0 || u < ref[v])) ref[v] = u;
      }
    }
  }
  return KM_OK;
}

/* Frames: rows n, t, b with b = n x t.
 * Fallbacks, so that every frame is orthonormal and right-handed:
 *  - a zero or non-finite normal (isolated vertex) is replaced by +z;
 *  - when the vertex has no reference neighbour, or the edge to it projects to (almost) zero
 *    on the tangent plane (|t| <= 1e-12 |edge|, the edge is along the normal or has zero
 *    length), t is the coordinate axis least aligned with n, projected. That fallback does
 *    not rotate with the mesh, but it only occurs at such degenerate vertices. */
km_status km_local_frames(const km_mesh *m, const double *N, const int32_t *ref, double *frames,
                          km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "km_local_frames: mesh is NULL");
  size_t n = m->n_vertices;
  if (n && (!m->V || !N || !ref || !frames))
    return km__fail(err, KM_ERR_INVALID, "km_local_frames: NULL argument");
  for (size_t v = 0; v < n; ++v)
    if (ref[v] < -1 || (ref[v] >= 0 && (size_t)ref[v] >= n))
      return km__fail(err, KM_ERR_INVALID, "km_local_frames: ref[%zu] = %d, expected -1 or 0..%zu",
                      v, (int)ref[v], n - 1);
  for (size_t v = 0; v < n; ++v) {
    double *fr = frames + 9 * v, *nn = fr, *t = fr + 3, *b = fr + 6;
    nn[0] = N[3 * v], nn[1] = N[3 * v + 1], nn[2] = N[3 * v + 2];
    double ln = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
    if (ln > 0 && isfinite(ln)) {
      nn[0] /= ln, nn[1] /= ln, nn[2] /= ln;
    } else {
      nn[0] = 0, nn[1] = 0, nn[2] = 1;
    }
    double e[3] = {0, 0, 0};
    if (ref[v] >= 0) {
      const double *p = m->V + 3 * v, *q = m->V + 3 * (size_t)ref[v];
      e[0] = q[0] - p[0], e[1] = q[1] - p[1], e[2] = q[2] - p[2];
    }
    km__frame_tangent(nn, e, t);
    km__normalize3(t);
    b[0] = nn[1] * t[2] - nn[2] * t[1];
    b[1] = nn[2] * t[0] - nn[0] * t[2];
    b[2] = nn[0] * t[1] - nn[1] * t[0];
    km__normalize3(b);
  }
  return KM_OK;
}
