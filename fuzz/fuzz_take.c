/* Modules: motion.
 * libFuzzer target for the take JSON reader (km_take_read; it reads files only, so the input
 * goes through a scratch file, fuzz_file.h). A take that reads has parents before their
 * children or -1. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char path[512];
  if (km_fuzz_write_temp(data, size, "json", path, sizeof path)) return 0;
  km_take t = {0};
  km_error err;
  if (km_take_read(path, &t, &err) == KM_OK) {
    for (size_t j = 0; t.parents && j < t.n_joints; ++j)
      if (t.parents[j] < -1 || t.parents[j] >= (int32_t)t.n_joints) abort();
    volatile double sum = 0;
    for (size_t k = 0; k < t.n_frames * t.n_joints * 3; ++k)
      sum += t.positions[k];
    km_take_free(&t);
  }
  remove(path);
  return 0;
}
