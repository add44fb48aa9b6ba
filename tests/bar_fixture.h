/* The two-bone bar of issue 12's rotation tests, shared by test_motion_rotate and
 * test_motion_bones: a thin tube along +x (2 m long, radius 2 cm) of SEGS + 1 rings of RING
 * vertices (ring i at x = 2 i / SEGS, vertex k of ring i is i * RING + k); the largest edge
 * stretch of a deformed copy is km_test.h's km_test_edge_stretch. */
#ifndef KM_BAR_FIXTURE_H
#define KM_BAR_FIXTURE_H

#include "km_test.h"

enum { RING = 8, SEGS = 40 };

/* The bar; free V and F with free(). */
static km_mesh bar(void) {
  km_mesh m = {0};
  m.n_vertices = (size_t)RING * (SEGS + 1);
  m.n_faces = (size_t)2 * RING * SEGS;
  m.V = malloc(m.n_vertices * 3 * sizeof(double));
  m.F = malloc(m.n_faces * 3 * sizeof(int32_t));
  for (int i = 0; i <= SEGS; ++i)
    for (int k = 0; k < RING; ++k) {
      double a = 2 * M_PI * k / RING, *v = m.V + 3 * (size_t)(i * RING + k);
      v[0] = 2.0 * i / SEGS;
      v[1] = 0.02 * cos(a);
      v[2] = 0.02 * sin(a);
    }
  size_t f = 0;
  for (int i = 0; i < SEGS; ++i)
    for (int k = 0; k < RING; ++k) {
      int32_t a = i * RING + k, b = i * RING + (k + 1) % RING, c = a + RING, d = b + RING;
      int32_t t[6] = {a, b, d, a, d, c};
      memcpy(m.F + 3 * f, t, sizeof t);
      f += 2;
    }
  return m;
}

/* Puppetry options that pass the joints through untouched (no filter, no glitch rejection,
 * scale 1) for a rig over joints with the given parents; raw must outlive the options. */
static km_puppetry_options bar_raw_options(const int32_t *parents, km_filter_options *raw) {
  *raw = (km_filter_options){.smoothing = KM_FILTER_ZERO, .trend = KM_FILTER_ZERO};
  km_puppetry_options o = {0};
  o.filter = raw;
  o.no_glitch = true;
  o.joint_parents = parents;
  o.retarget.scale = 1;
  return o;
}

#endif
