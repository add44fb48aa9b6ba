#include "motion/motion.h"

#include <stdlib.h>
#include <string.h>

char *km__strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}
