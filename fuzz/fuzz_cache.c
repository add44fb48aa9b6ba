/* Modules: puppet.
 * libFuzzer target for the reduced-model cache reader: km_puppet_cache_options (the header
 * alone) and km_puppet_load against a fixed tetrahedron, with the default parameters and with
 * the ones the header names (what `animate` adopts; issue 18: a forged header must not make
 * either allocate by its word). Through a scratch file, fuzz_file.h. See fuzz_mesh.c. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  static int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  km_mesh m = {V, F, 4, 4, NULL, NULL};
  char path[512];
  if (km_fuzz_write_temp(data, size, "kmcache", path, sizeof path)) return 0;
  km_error err;
  km_puppet *p = NULL;
  if (km_puppet_load(path, &m, NULL, &p, &err) == KM_OK) {
    km_puppet_info pi;
    km_puppet_info_get(p, &pi);
    if (pi.vertices != 4) abort();
  }
  km_puppet_free(&p);
  km_puppet_options o = {0};
  if (km_puppet_cache_options(path, &o, &err) == KM_OK) {
    if (km_puppet_load(path, &m, &o, &p, &err) == KM_OK) km_puppet_free(&p);
  }
  remove(path);
  return 0;
}
