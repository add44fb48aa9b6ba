/* Modules: mesh.
 * libFuzzer target for the mesh readers: each input is parsed as OBJ, PLY, OFF and STL through
 * km_mesh_parse; a mesh that parses must have in-range indices and a mesh info.
 * Built and run by fuzz/run.sh (ctest `fuzz`, when clang is present): the "Modules:" line
 * above names the library modules it needs, compiled from src/ with clang
 * -fsanitize=fuzzer,address,undefined together with the modules they require. By hand:
 *   bash fuzz/run.sh . /tmp/fuzz 60 fuzz_mesh */
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const km_mesh_format fmts[] = {KM_FORMAT_OBJ, KM_FORMAT_PLY, KM_FORMAT_OFF, KM_FORMAT_STL};
  for (size_t i = 0; i < sizeof fmts / sizeof fmts[0]; ++i) {
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
