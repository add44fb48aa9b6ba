/* Modules: anim.
 * libFuzzer target for the animation readers behind `kinemesh info` and `bake` (km_anim_info_read
 * on a .glb and a .pc2, km_pc2_read, and km_anim_read: a .glb's rest mesh and its morph targets
 * evaluated at the weight keys, a .pc2's frames; they read files only, so through a scratch
 * file, fuzz_file.h). What reads has the frames its header promised. See fuzz_mesh.c. */
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
  km_mesh rest = {0};
  double *baked = NULL;
  if (km_anim_read(path, &rest, &baked, &info, &err) == KM_OK) {
    volatile double sum = 0;
    for (size_t k = 0; k < info.frames * rest.n_vertices * 3; ++k)
      sum += baked[k];
    free(baked);
    km_mesh_free(&rest);
  }
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
