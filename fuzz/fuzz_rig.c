/* Modules: motion.
 * libFuzzer target for the rig readers: km_rig_parse (the puppetry rig, from memory) on a
 * tetrahedron with the Kinect v1 joints and a three-joint BVH-like skeleton, and
 * km_character_read_rig (the sidecar's skeleton, skin and landmarks; through a scratch file,
 * fuzz_file.h). A rig that parses has its handles on the mesh. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  static int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  const km_mesh mesh = {V, F, 4, 4};
  static const char *const joints[] = {"Hips", "Spine", "Head"};
  km_error err;
  for (int named = 0; named < 2; ++named) {
    km_rig rig = {0};
    if (km_rig_parse((const char *)data, size, "fuzz.rig.json", &mesh, named ? joints : NULL,
                     named ? 3 : 0, &rig, &err) == KM_OK) {
      for (size_t h = 0; h < rig.n_handles; ++h)
        for (size_t k = 0; k < rig.handles[h].n_vertices; ++k)
          if (rig.handles[h].vertices[k] < 0 ||
              (size_t)rig.handles[h].vertices[k] >= mesh.n_vertices)
            abort();
      km_rig_free(&rig);
    }
  }
  char path[512];
  if (km_fuzz_write_temp(data, size, "rig.json", path, sizeof path)) return 0;
  km_character c = {0};
  if (km_character_read_rig(path, mesh.n_vertices, &c, &err) == KM_OK) km_character_free(&c);
  remove(path);
  return 0;
}
