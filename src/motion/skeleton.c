/* Kinect v1 joint table and the frees of skeleton-side structures. */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

static const char *const k_names[KM_KINECT1_JOINTS] = {
    "HipCenter",  "Spine",     "ShoulderCenter", "Head",          "ShoulderLeft",
    "ElbowLeft",  "WristLeft", "HandLeft",       "ShoulderRight", "ElbowRight",
    "WristRight", "HandRight", "HipLeft",        "KneeLeft",      "AnkleLeft",
    "FootLeft",   "HipRight",  "KneeRight",      "AnkleRight",    "FootRight"};

static const int k_parents[KM_KINECT1_JOINTS] = {-1, 0,  1, 2,  2,  4,  5, 6,  2,  8,
                                                 9,  10, 0, 12, 13, 14, 0, 16, 17, 18};

const char *km_kinect1_joint_name(int j) {
  return j >= 0 && j < KM_KINECT1_JOINTS ? k_names[j] : NULL;
}

int km_kinect1_joint_parent(int j) { return j >= 0 && j < KM_KINECT1_JOINTS ? k_parents[j] : -1; }

int km_kinect1_joint_index(const char *name) {
  if (!name) return -1;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    if (strcmp(name, k_names[j]) == 0) return j;
  return -1;
}

static void free_names(char **names, size_t n) {
  if (!names) return;
  for (size_t i = 0; i < n; ++i)
    free(names[i]);
  free(names);
}

void km_skeleton_free(km_skeleton *s) {
  if (!s) return;
  free_names(s->names, s->n_joints);
  free(s->parents);
  free(s->rest);
  memset(s, 0, sizeof *s);
}

void km_take_free(km_take *t) {
  if (!t) return;
  free_names(t->joint_names, t->n_joints);
  free(t->parents);
  free(t->positions);
  memset(t, 0, sizeof *t);
}

void km_skin_free(km_skin *s) {
  if (!s) return;
  free(s->joints);
  free(s->weights);
  memset(s, 0, sizeof *s);
}
