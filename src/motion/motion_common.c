#include "motion/motion.h"

#include <stdlib.h>
#include <string.h>

const char *const km__kinect1_names[KM_KINECT1_JOINTS] = {
    "HipCenter",  "Spine",     "ShoulderCenter", "Head",          "ShoulderLeft",
    "ElbowLeft",  "WristLeft", "HandLeft",       "ShoulderRight", "ElbowRight",
    "WristRight", "HandRight", "HipLeft",        "KneeLeft",      "AnkleLeft",
    "FootLeft",   "HipRight",  "KneeRight",      "AnkleRight",    "FootRight"};

const int32_t km__kinect1_parents[KM_KINECT1_JOINTS] = {-1, 0,  1, 2,  2,  4,  5, 6,  2,  8,
                                                        9,  10, 0, 12, 13, 14, 0, 16, 17, 18};

int km__kinect1_index(const char *name) {
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    if (strcmp(name, km__kinect1_names[j]) == 0) return j;
  return -1;
}

void km__take_clear(km_take *t) {
  if (!t) return;
  if (t->joint_names)
    for (size_t j = 0; j < t->n_joints; ++j)
      free(t->joint_names[j]);
  free(t->joint_names);
  free(t->parents);
  free(t->positions);
  memset(t, 0, sizeof *t);
}

char *km__strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}
