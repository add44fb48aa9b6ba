/* Modules: motion.
 * libFuzzer target for the Kinect v1 CSV reader (km_kinect_csv_read, through a scratch file,
 * fuzz_file.h): a take that reads has the 20 Kinect joints and one label per frame. See
 * fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char path[512];
  if (km_fuzz_write_temp(data, size, "csv", path, sizeof path)) return 0;
  km_take t = {0};
  int32_t *labels = NULL;
  km_error err;
  if (km_kinect_csv_read(path, &t, &labels, &err) == KM_OK) {
    if (t.n_joints != KM_KINECT1_JOINTS) abort();
    volatile int64_t sum = 0;
    for (size_t f = 0; f < t.n_frames; ++f)
      sum += labels[f];
    free(labels);
    km_take_free(&t);
  }
  remove(path);
  return 0;
}
