/* The tube of the skinning and compression tests, shared by test_ssdr and test_glb_compress:
 * rings x segs vertices around the line y = 1 m, z = 0 from x = 0 to 1.2 m, radius 8 cm (ring r
 * at x = 1.2 r / (rings - 1), vertex s of ring r is r * segs + s), open at both ends, with UVs
 * (s / segs, r / (rings - 1)) when asked; and the little-endian readers the tests check .glb
 * files with. */
#ifndef KM_TUBE_FIXTURE_H
#define KM_TUBE_FIXTURE_H

#include "km_test.h"

#include <stdint.h>

/* The tube; free with km_mesh_free. */
static inline void tube_mesh(km_mesh *m, int rings, int segs, bool uv) {
  m->n_vertices = (size_t)rings * (size_t)segs;
  m->n_faces = (size_t)2 * (size_t)(rings - 1) * (size_t)segs;
  m->V = malloc(m->n_vertices * 3 * sizeof(double));
  m->F = malloc(m->n_faces * 3 * sizeof(int32_t));
  m->UV = uv ? malloc(m->n_vertices * 2 * sizeof(double)) : NULL;
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segs; ++s) {
      size_t i = (size_t)(r * segs + s);
      double x = 1.2 * r / (rings - 1), a = 2 * M_PI * s / segs;
      m->V[3 * i] = x;
      m->V[3 * i + 1] = 1.0 + 0.08 * cos(a);
      m->V[3 * i + 2] = 0.08 * sin(a);
      if (uv) m->UV[2 * i] = (double)s / segs, m->UV[2 * i + 1] = (double)r / (rings - 1);
    }
  int32_t *f = m->F;
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segs; ++s) {
      int a = r * segs + s, b = r * segs + (s + 1) % segs, c = a + segs, d = b + segs;
      *f++ = a, *f++ = c, *f++ = d;
      *f++ = a, *f++ = d, *f++ = b;
    }
}

/* The whole file (malloc'd; *n its size), NULL when it cannot be read. */
static inline unsigned char *read_all(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  *n = (size_t)ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *b = malloc(*n ? *n : 1);
  if (b && fread(b, 1, *n, f) != *n) {
    free(b);
    b = NULL;
  }
  fclose(f);
  return b;
}

static inline uint32_t getu32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint16_t getu16(const unsigned char *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline int16_t gets16(const unsigned char *p) { return (int16_t)getu16(p); }
static inline float getf(const unsigned char *p) {
  uint32_t u = getu32(p);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

#endif
