/* Requires: core, math, mesh. External: cJSON. */
/* Private helpers of the motion module. */
#ifndef KM_MOTION_H
#define KM_MOTION_H

#include "core/core.h"

/* Heap-copies a string (NULL on failure). */
char *km__strdup(const char *s);

/* Allocates a skin of n vertices (KM_SKIN_INFLUENCES joints and weights each, uninitialised). */
km_status km__skin_alloc(km_skin *s, size_t n, km_error *err);

/* Column of each Kinect v1 joint among names (by exact name), -1 when absent; returns how
 * many were found. Shared by km_motion_read (kinect1 takes) and km_puppetry (kinect1 rigs). */
int km__kinect1_columns(const char *const *names, size_t n_names, int src[KM_KINECT1_JOINTS]);

#endif
