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
/* size(source) / size(T) for positions T of the source's connectivity (geodesic landmark
 * distances, see KM_TRANSFER_ALIGN_SCALE). Uses the object's scratch. */
double km__transfer_size_ratio(const km_transfer *t, const double *T);

/* The solver's own per-iteration frames of positions V (#V*9, rows n, t, b), for tests: they
 * must equal km_vertex_normals (area) + km_local_frames on the same positions. */
void km__transfer_frames(km_transfer *t, const double *V, double *frames);

#endif
