/* Requires: core, linalg, math, mesh, motion, anim. External: Embree, liblbfgs, cJSON. */
/* Private geometry for point cloud reconstruction: closest points on a triangle mesh and
 * k nearest neighbours (both through Embree point queries), point normals, multiresolution
 * clustering. */
#ifndef KM_RECON_RECON_H
#define KM_RECON_RECON_H

#include "core/core.h"

/* Below this many queries a parallel region costs more than it saves (fork/join and the
 * threads' spin-wait, measured on the 2-core CI machine). */
#define KM__OMP_MIN 16384

/* Process-wide Embree device (created once; NULL when Embree cannot start). */
void *km__embree_device(km_error *err);

/* Closest-point structure over a triangle mesh whose positions change between queries. */
typedef struct km__surface km__surface;
km_status km__surface_create(const double *V, size_t nv, const int32_t *F, size_t nf,
                             km__surface **out, km_error *err);
/* New positions (same count), BVH refit. V must stay alive until the next update. */
void km__surface_update(km__surface *s, const double *V);
/* Faces km__surface_closest never returns (skip #F, kept by s, not copied; NULL: none): a
 * template's ground plane, which no point of the subject measures. Occlusion still sees
 * them. */
void km__surface_skip(km__surface *s, const bool *skip);
/* For each query point: closest triangle, barycentrics (3 per point) and distance. Points
 * farther than max_dist (<= 0: unlimited) get tri = -1. Parallel (OpenMP). */
void km__surface_closest(const km__surface *s, const double *Q, size_t n, double max_dist,
                         int32_t *tri, double *bary, double *dist);
/* Segments org -> tgt (n*3 each) crossed by a face beyond tnear (a length) from either end:
 * occluded n (1/0). Parallel (OpenMP). */
void km__surface_occluded(const km__surface *s, const double *org, const double *tgt, size_t n,
                          double tnear, uint8_t *occluded);
void km__surface_free(km__surface **s);

/* Closest point on triangle (a,b,c) to p: barycentrics w (3), returns squared distance. */
double km__closest_on_triangle(const double *p, const double *a, const double *b, const double *c,
                               double *w);

/* k nearest neighbours (the point itself included) of every point: idx n*k. */
km_status km__knn(const double *P, size_t n, int k, int32_t *idx, km_error *err);
/* Nearest point of a fixed cloud (Embree user-geometry BVH, as km__knn). */
typedef struct km__point_index km__point_index;
km_status km__point_index_create(const double *P, size_t n, km__point_index **out, km_error *err);
/* idx[i] = nearest point to Q[i] within max_dist (-1 if none), dist[i] its distance. */
void km__point_index_nearest(const km__point_index *ix, const double *Q, size_t nq, double max_dist,
                             int32_t *idx, double *dist);
void km__point_index_free(km__point_index **ix);
/* k nearest neighbours (the point itself included) of each of the index's own n points (the
 * P it was built over): idx n*k. km__knn without building the index again. */
km_status km__point_index_knn(const km__point_index *ix, size_t n, int k, int32_t *idx,
                              km_error *err);

/* Unit normals by PCA over the k neighbours (unoriented: sign arbitrary). N n*3. */
km_status km__point_normals(const double *P, size_t n, int k, double *N, km_error *err);
/* The same over an index already built over P (NULL: build one); a frame builds its index
 * once for the normals and the surface -> points error (about 0.2 s per 100k points). */
km_status km__point_normals_indexed(const double *P, size_t n, const km__point_index *ix, int k,
                                    double *N, km_error *err);
/* Pauly et al. 2002 hierarchical clustering: splits while a cluster is larger than max_size
 * or curved (surface variation > max_var). Returns representative indices (the point
 * nearest each cluster centroid), about `target` of them. *reps allocated. */
km_status km__cluster_points(const double *P, size_t n, size_t target, int32_t **reps,
                             size_t *n_reps, km_error *err);

/* The template's vertices with no skin influence (km__skin_row_empty: a ground plane), which
 * every frame keeps where the template has them and surface -> points leaves out. */
size_t km__recon_still_vertices(const km_recon *r);

/* The affine registration step alone, as the first frame runs it after the global alignment
 * and the pose: `iterations` rounds of closest points (robust weights) on the current
 * surface, each followed by one Gauss-Newton solve (CHOLMOD) for the per-vertex affine maps
 * of Vb under w_d E_d + w_f E_f + w_s E_s; coarse points first, all points in the last two
 * rounds. Vb has the template's vertex count; the result is km_recon_surface(r). Exposed for
 * the tests (a mesh registered to points of its own surface must reach zero error). */
km_status km__recon_affine_register(km_recon *r, const double *Vb, const double *P, size_t n,
                                    const km_recon_feature *feat, size_t nfeat, int iterations,
                                    km_error *err);

#endif
