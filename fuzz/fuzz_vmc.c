/* Modules: motion.
 * libFuzzer target for the live server's VMC receiver (km_live_vmc_packet on one receiver
 * state across inputs, as UDP packets arrive: bundles, /VMC/Ext/Root/Pos, Bone/Pos, OK, T;
 * apps/live/live_vmc.c compiled in here, liblo linked as installed). A completed frame holds
 * 60 values, each finite or NaN (not driven). */
#include "../apps/live/live_vmc.c"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static km_live_vmc v;
  static int init;
  if (!init || v.packets > 100000) {
    km_live_vmc_init(&v);
    init = 1;
  }
  double joints[60];
  uint64_t bad0 = v.bad;
  if (km_live_vmc_packet(&v, data, size, joints)) {
    for (int k = 0; k < 60; ++k)
      if (isinf(joints[k])) abort();
  }
  if (v.bad > bad0 + 1) abort();
  return 0;
}
