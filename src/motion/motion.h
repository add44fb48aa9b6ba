/* Requires: core, math, mesh. External: cJSON. */
/* Private helpers of the motion module. */
#ifndef KM_MOTION_H
#define KM_MOTION_H

#include "core/core.h"

/* Heap-copies a string (NULL on failure). */
char *km__strdup(const char *s);

/* Allocates a skin of n vertices (KM_SKIN_INFLUENCES joints and weights each, uninitialised). */
km_status km__skin_alloc(km_skin *s, size_t n, km_error *err);

#endif
