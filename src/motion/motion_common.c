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

bool km__body_upright(const double hc[3], const double sc[3], const double *hl, const double *hr,
                      const double *kl, const double *kr) {
  if (!km__spine_upright(hc, sc)) return false;
  if (!hl || !hr || !kl || !kr) return true;
  for (int d = 0; d < 3; ++d)
    if (!isfinite(hl[d]) || !isfinite(hr[d]) || !isfinite(kl[d]) || !isfinite(kr[d])) return true;
  return fmin(hl[1], hr[1]) > fmax(kl[1], kr[1]);
}
