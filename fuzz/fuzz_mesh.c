// libFuzzer target for the mesh readers (not built by CMake). Build and run from the repo root:
//   clang -g -O1 -fsanitize=fuzzer,address,undefined -D_GNU_SOURCE -Iinclude -Isrc -Isrc/core \
//     fuzz/fuzz_mesh.c src/mesh/*.c src/core/*.c -lm -o fuzz_mesh
//   mkdir -p corpus && cp tests/data/* corpus/ && ./fuzz_mesh -max_len=4096 corpus
// Each input is parsed as OBJ, PLY and OFF; a mesh that parses must have in-range indices.
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const km_mesh_format fmts[] = {KM_FORMAT_OBJ, KM_FORMAT_PLY, KM_FORMAT_OFF};
  for (int i = 0; i < 3; ++i) {
    km_mesh m;
    km_error err;
    if (km_mesh_parse(data, size, fmts[i], "fuzz", &m, &err) == KM_OK) {
      for (size_t k = 0; k < m.n_faces * 3; ++k)
        if (m.F[k] < 0 || (size_t)m.F[k] >= m.n_vertices) abort();
      km_mesh_info info;
      if (km_mesh_info_compute(&m, &info, &err) != KM_OK) abort();
      km_mesh_free(&m);
    }
  }
  return 0;
}
