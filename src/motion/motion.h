/* Private helpers of the motion module. */
#ifndef KM_MOTION_H
#define KM_MOTION_H

#include "internal.h"

/* Heap-copies a string (NULL on failure). */
char *km__strdup(const char *s);

#endif
