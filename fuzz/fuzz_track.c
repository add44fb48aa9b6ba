/* Modules: transfer.
 * libFuzzer target for the landmark track reader (km_track_read, .json and .csv; it reads
 * files only, so through a scratch file, fuzz_file.h). A track that reads has the positions
 * its counts promise. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const char *const ext[2] = {"json", "csv"};
  for (int k = 0; k < 2; ++k) {
    char path[512];
    if (km_fuzz_write_temp(data, size, ext[k], path, sizeof path)) return 0;
    km_track t = {0};
    km_error err;
    if (km_track_read(path, &t, &err) == KM_OK) {
      volatile double sum = 0;
      for (size_t i = 0; i < t.n_frames * t.n_landmarks * 3; ++i)
        sum += t.positions[i];
      for (size_t l = 0; l < t.n_landmarks; ++l)
        if (!memchr(t.names[l], 0, sizeof t.names[l])) abort();
      km_track_free(&t);
    }
    remove(path);
  }
  return 0;
}
