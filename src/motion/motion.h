/* Private helpers of the motion module (Kinect names, take cleanup). */
#ifndef KM_MOTION_H
#define KM_MOTION_H

#include "internal.h"

/* The 20 Kinect v1 joint names and parents in SDK order. Local to this module because the
 * public km_kinect1_joint_* functions live in another module; the tables must agree. */
extern const char *const km__kinect1_names[KM_KINECT1_JOINTS];
extern const int32_t km__kinect1_parents[KM_KINECT1_JOINTS];
int km__kinect1_index(const char *name);

/* Frees what a take owns and zeroes it (same effect as km_take_free). */
void km__take_clear(km_take *t);

/* Heap-copies a string (NULL on failure). */
char *km__strdup(const char *s);

#endif
