/* Iso-surface extraction of an implicit function (private to kinemesh). */
#ifndef KM_POLYGONIZE_H
#define KM_POLYGONIZE_H

#include "core/core.h"

/* Field value at p: negative inside, positive outside. Must be 1-Lipschitz (a signed
 * distance or a smooth union of them) so that blocks far from the surface can be skipped. */
typedef double (*km__field_fn)(void *user, const double p[3]);

/* Number of vertices the polygonisation at cell size h would have (before dropping small
 * components). Evaluates the field only in a narrow band. */
km_status km__polygonize_count(km__field_fn f, void *user, const double lo[3], const double hi[3],
                               double h, size_t *n_vertices, km_error *err);

/* Marching tetrahedra over sparse blocks of the grid of spacing h covering [lo,hi] (the
 * surface must lie strictly inside). The result is the largest connected component: closed,
 * manifold, oriented with normals pointing to positive field values. out->V/F are malloc'd. */
km_status km__polygonize(km__field_fn f, void *user, const double lo[3], const double hi[3],
                         double h, km_mesh *out, km_error *err);

/* Tangential uniform-Laplacian relaxation with projection back onto the zero set
 * (Newton steps along the gradient, finite differences with step eps). Connectivity kept. */
void km__surface_relax(km_mesh *m, km__field_fn f, void *user, int iterations, double eps);

/* Delaunay-style edge flips (opposite angles summing over 180 degrees) between nearly
 * coplanar faces, keeping the mesh closed, manifold and oriented: a flip is skipped when the
 * new edge exists, a vertex would drop to valence 3 or a new face would fold. Returns the
 * number of flips (0 also when the mesh is not closed and manifold or memory runs out). */
size_t km__delaunay_flips(km_mesh *m, int max_passes);

#endif
