/* The 1,000,000-vertex character: count, topology and time (skipped under the sanitizers,
 * where it would take minutes). */
#include "character_checks.h"

#include <time.h>

int main(void) {
#if defined(__SANITIZE_ADDRESS__)
  printf("SKIP: 1M-vertex character under the sanitizers\n");
  return KM_TEST_SKIP;
#else
  km_character_options o = {0};
  o.target_vertices = 1000000;
  km_character c;
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  CHECK_OK(km_character_generate(&o, &c, KM_E));
  clock_gettime(CLOCK_MONOTONIC, &t1);
  double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
  printf("1M character: %zu vertices in %.2f s\n", c.mesh.n_vertices, secs);
  CHECK_MSG(secs < 60, "%.1f s", secs);
  cc_check_character(&c, 1000000, 1.75);
  CHECK_OK(km_character_write_rig("test_character_large.rig.json", &c, KM_E));
  km_character r = {0};
  CHECK_OK(km_character_read_rig("test_character_large.rig.json", c.mesh.n_vertices, &r, KM_E));
  CHECK(r.skin.n_vertices == c.mesh.n_vertices);
  remove("test_character_large.rig.json");
  km_character_free(&r);
  km_character_free(&c);
  return km_test_finish("test_character_large");
#endif
}
