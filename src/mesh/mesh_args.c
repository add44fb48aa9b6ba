/* Argument checks shared by the mesh operators. */
#include "core/core.h"
#include "mesh/mesh_args.h"

km_status km__mesh_check_faces(const km_mesh *m, const char *who, km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "%s: mesh is NULL", who);
  if ((m->n_vertices && !m->V) || (m->n_faces && !m->F))
    return km__fail(err, KM_ERR_INVALID, "%s: mesh has NULL arrays", who);
  if (m->n_vertices > INT32_MAX || m->n_faces > INT32_MAX / 3)
    return km__fail(err, KM_ERR_INVALID, "%s: mesh too large for int32 indices", who);
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3; ++c) {
      int32_t v = m->F[3 * f + c];
      if (v < 0 || (size_t)v >= m->n_vertices)
        return km__fail(err, KM_ERR_INVALID, "%s: face %zu references vertex %d, expected 0..%zu",
                        who, f, (int)v, m->n_vertices ? m->n_vertices - 1 : 0);
    }
  return KM_OK;
}
