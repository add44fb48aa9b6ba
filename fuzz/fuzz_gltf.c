/* Modules: mesh.
 * libFuzzer target for the glTF mesh reader (src/mesh/io_gltf.c): each input is parsed as
 * .glb / .gltf through km_mesh_parse_skinned (no external buffers from memory); a mesh that
 * parses must have in-range indices, finite positions and consistent attribute arrays, and
 * its skin (if any) joint indices in range, parents in range and weights in [0, 1].
 *   bash fuzz/run.sh . /tmp/fuzz 60 fuzz_gltf */
#include "kinemesh.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  km_mesh m;
  km_error err;
  km_mesh_skin sk;
  if (km_mesh_parse_skinned(data, size, "fuzz.glb", &m, &sk, &err) == KM_OK) {
    if (sk.n_joints && sk.n_vertices != m.n_vertices) abort();
    for (size_t j = 0; j < sk.n_joints; ++j)
      if (!sk.names[j] || sk.parents[j] < -1 || sk.parents[j] >= (int32_t)sk.n_joints) abort();
    for (size_t k = 0; sk.n_joints && k < 4 * sk.n_vertices; ++k)
      if (sk.joints[k] < -1 || sk.joints[k] >= (int32_t)sk.n_joints ||
          !(sk.weights[k] >= 0 && sk.weights[k] <= 1.0000001))
        abort();
    km_mesh_skin_free(&sk);
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
