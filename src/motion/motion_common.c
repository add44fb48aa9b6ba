#include "motion/motion.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

char *km__strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

bool km__spine_upright(const double hc[3], const double sc[3]) {
  for (int d = 0; d < 3; ++d)
    if (!isfinite(hc[d]) || !isfinite(sc[d])) return false;
  return sc[1] - hc[1] > hypot(sc[0] - hc[0], sc[2] - hc[2]);
}
