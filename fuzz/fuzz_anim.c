/* Modules: anim.
 * libFuzzer target for the animation readers behind `kinemesh info` (km_anim_info_read on a
 * .glb and a .pc2, and km_pc2_read; they read files only, so through a scratch file,
 * fuzz_file.h). A .pc2 that reads has the frames its header promised. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char path[512];
  km_anim_info info;
  km_error err;
  if (km_fuzz_write_temp(data, size, "glb", path, sizeof path)) return 0;
  (void)km_anim_info_read(path, &info, &err);
  remove(path);
  if (km_fuzz_write_temp(data, size, "pc2", path, sizeof path)) return 0;
  (void)km_anim_info_read(path, &info, &err);
  double *frames = NULL;
  if (km_pc2_read(path, &frames, &info, &err) == KM_OK) {
    volatile double sum = 0;
    for (size_t k = 0; k < info.frames * info.vertices * 3; ++k)
      sum += frames[k];
    free(frames);
  }
  remove(path);
  return 0;
}
