/* Modules: mesh.
 * libFuzzer target for the glTF mesh reader (src/mesh/io_gltf.c): each input is parsed as
 * .glb / .gltf through km_mesh_parse (no external buffers from memory); a mesh that parses
 * must have in-range indices, finite positions and consistent attribute arrays.
 *   bash fuzz/run.sh . /tmp/fuzz 60 fuzz_gltf */
#include "kinemesh.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  km_mesh m;
  km_error err;
  if (km_mesh_parse(data, size, KM_FORMAT_GLTF, "fuzz.glb", &m, &err) == KM_OK) {
    if (!m.n_vertices) abort();
    for (size_t k = 0; k < m.n_faces * 3; ++k)
      if (m.F[k] < 0 || (size_t)m.F[k] >= m.n_vertices) abort();
    for (size_t k = 0; k < m.n_vertices * 3; ++k)
      if (!isfinite(m.V[k])) abort();
    volatile double sink = 0;
    for (size_t k = 0; m.UV && k < m.n_vertices * 2; ++k)
      sink += m.UV[k];
    for (size_t k = 0; m.N && k < m.n_vertices * 3; ++k)
      sink += m.N[k];
    (void)sink;
    km_mesh_free(&m);
  }
  return 0;
}
