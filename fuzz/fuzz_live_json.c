/* Modules: motion.
 * libFuzzer target for the live server's JSON-over-UDP datagram parser (km_live_parse_json,
 * apps/live/live_input.c, compiled in here: the fuzz build takes library modules from src/
 * only). A datagram that parses sets 60 values, each finite or NaN (missing). */
#include "../apps/live/live_input.c"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  double joints[60];
  int n = km_live_parse_json((const char *)data, size, joints);
  if (n > 20) abort();
  if (n >= 0)
    for (int k = 0; k < 60; ++k)
      if (isinf(joints[k])) abort();
  return 0;
}
