/* Modules: mesh.
 * libFuzzer target for the point cloud readers (km_points_parse): each input is read as PLY,
 * PCD and XYZ text; a cloud that parses has finite coordinates. See fuzz_mesh.c. */
#include "kinemesh.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const char *names[] = {"fuzz.ply", "fuzz.pcd", "fuzz.xyz"};
  for (int i = 0; i < 3; ++i) {
    km_points p = {0};
    km_error err;
    if (km_points_parse(data, size, names[i], &p, &err) == KM_OK) {
      for (size_t k = 0; k < p.n * 3; ++k)
        if (!isfinite(p.P[k])) abort();
      km_points_free(&p);
    }
  }
  return 0;
}
