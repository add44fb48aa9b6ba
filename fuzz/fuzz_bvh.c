/* Modules: motion.
 * libFuzzer target for the BVH reader (km_bvh_read, through a scratch file, fuzz_file.h): a
 * take that reads has parents[j] < j. Both End Site settings. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char path[512];
  if (km_fuzz_write_temp(data, size, "bvh", path, sizeof path)) return 0;
  for (int end_sites = 0; end_sites < 2; ++end_sites) {
    km_bvh_options o = {0};
    o.end_sites = end_sites;
    km_take t = {0};
    km_bvh_info info;
    km_error err;
    if (km_bvh_read(path, &o, &t, &info, &err) == KM_OK) {
      for (size_t j = 0; j < t.n_joints; ++j)
        if (t.parents && (t.parents[j] < -1 || t.parents[j] >= (int32_t)j)) abort();
      volatile double sum = 0;
      for (size_t k = 0; k < t.n_frames * t.n_joints * 3; ++k)
        sum += t.positions[k];
      km_take_free(&t);
    }
  }
  remove(path);
  return 0;
}
