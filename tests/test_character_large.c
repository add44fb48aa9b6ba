/* The 1,000,000-vertex character: count and topology (skipped under the sanitizers, where it
 * would take minutes). Its speed is measured by bench/bench_character, not here. */
#include "character_checks.h"

int main(void) {
#if defined(__SANITIZE_ADDRESS__)
  (void)cc_check_character;
  (void)km_test_err;
  printf("SKIP: 1M-vertex character under the sanitizers\n");
  return KM_TEST_SKIP;
#else
  km_character_options o = {0};
  o.target_vertices = 1000000;
  km_character c;
  CHECK_OK(km_character_generate(&o, &c, KM_E));
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
