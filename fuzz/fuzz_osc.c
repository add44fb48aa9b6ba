/* Modules: motion.
 * libFuzzer target for the live server's OSC datagram handling (km_live_osc_packet,
 * apps/live/live_input.c, compiled in here: the fuzz build takes library modules from src/
 * only): bundles walked, messages decoded by liblo (linked as installed) and parsed as
 * OSCeleton /joint or KinectV2-OSC /bodies/... A joint comes out with a Kinect v1 index and
 * finite (or NaN, "NotTracked") coordinates; the malformed count never exceeds the elements. */
#include "../apps/live/live_input.c"

#include <stdint.h>
#include <stdlib.h>

static void check_joint(void *ctx, const km_live_osc_joint *j) {
  (void)ctx;
  if (j->joint < 0 || j->joint >= 20) abort();
  for (int k = 0; k < 3; ++k)
    if (isinf(j->p[k])) abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  uint64_t messages = 0;
  int bad = km_live_osc_packet((const char *)data, size, check_joint, NULL, &messages);
  if (bad < 0 || (size_t)bad > size + 1 || messages > size / 4) abort();
  return 0;
}
