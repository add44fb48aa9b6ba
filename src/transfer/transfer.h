/* Requires: core, linalg, math, mesh, motion. External: libsvm, cJSON. */
/* Private access to a km_transfer's source (for motion generation in src/pose/morph.c). */
#ifndef KM_DEFORM_OFFSETS_H
#define KM_DEFORM_OFFSETS_H

#include "core/core.h"

/* The source mesh (rest positions, connectivity) the transfer was precomputed on. */
const km_mesh *km__transfer_source(const km_transfer *t);
/* Landmark vertex ids in precompute order (km_transfer_landmarks of them). */
const int32_t *km__transfer_landmark_ids(const km_transfer *t);
/* Surface area of the source. */
double km__transfer_area(const km_transfer *t);
/* size(source) / size(T) for positions T of the source's connectivity (median one-ring
 * edge-length ratio, see KM_TRANSFER_ALIGN_SCALE). Uses the object's scratch. */
double km__transfer_size_ratio(const km_transfer *t, const double *T);

/* The solver's own per-iteration frames of positions V (#V*9, rows n, t, b), for tests: they
 * must equal km_vertex_normals (area) + km_local_frames on the same positions. */
void km__transfer_frames(km_transfer *t, const double *V, double *frames);

/* Changes the solves per km_transfer_solve of t (1 .. the value t was precomputed with) and
 * the tolerance, for tests that measure the error after each iteration without a precompute
 * per count. */
void km__transfer_set_iterations(km_transfer *t, int max_iterations, double tolerance);

/* ==== transfer: test fixtures / internal (not in include/kinemesh.h) ==== */

/* Decision tree (CART, Gini impurity) over dense features: the feature selection of pose
 * databases (km_posedb_build), exposed for tests. Implemented in src/transfer/cart.c.
 * km_cart_fit:
 *   X           in: n_samples x n_features, row-major
 *   y           in: n_samples labels in [0, n_classes)
 *   max_depth   in: depth limit; <= 0: unlimited
 *   out         out: allocated tree; free with km_cart_free
 *   importance  out: n_features total weighted impurity decrease per feature, normalised to
 *               sum 1; may be NULL
 * km_cart_predict: x in: n_features values; returns the predicted label.
 * km_cart_nodes: returns the number of nodes of the tree.
 * km_cart_free: frees *tree and sets it to NULL. */
typedef struct km_cart km_cart;
km_status km_cart_fit(const double *X, const int32_t *y, size_t n_samples, size_t n_features,
                      size_t n_classes, int max_depth, km_cart **out, double *importance,
                      km_error *err);
int32_t km_cart_predict(const km_cart *tree, const double *x);
size_t km_cart_nodes(const km_cart *tree);
void km_cart_free(km_cart **tree);

#endif
