/* For fuzz targets whose reader takes a path and has no parse-from-memory form: the input is
 * written to a scratch file named by extension (the readers pick the format from it) and
 * removed after the call. The directory is $KM_FUZZ_TMP (fuzz/run.sh points it at its work
 * folder), else /tmp. */
#ifndef KM_FUZZ_FILE_H
#define KM_FUZZ_FILE_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* Writes data to <dir>/km_fuzz_<pid>.<ext> into path (of n bytes); returns 0 on success. */
static int km_fuzz_write_temp(const uint8_t *data, size_t size, const char *ext, char *path,
                              size_t n) {
  const char *dir = getenv("KM_FUZZ_TMP");
  snprintf(path, n, "%s/km_fuzz_%ld.%s", dir && *dir ? dir : "/tmp", (long)getpid(), ext);
  FILE *f = fopen(path, "wb");
  if (!f) return -1;
  size_t w = size ? fwrite(data, 1, size, f) : 0;
  return fclose(f) == 0 && w == size ? 0 : -1;
}

#endif
