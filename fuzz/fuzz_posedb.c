/* Modules: transfer.
 * libFuzzer target for the pose database reader (km_posedb_load) and one query on what it
 * loads. The file's last 8 bytes are an FNV-1a checksum of the rest: an input that does not
 * end with its own checksum gets one appended, so the fuzzer reaches the header, the sizes
 * and the stored model (issue 18: a forged database with a valid checksum must not make the
 * loader train or allocate beyond the file). Through a scratch file, fuzz_file.h. */
#include "fuzz_file.h"
#include "kinemesh.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t fnv1a(const uint8_t *p, size_t n) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < n; ++i)
    h = (h ^ p[i]) * 0x100000001b3ULL;
  return h;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  uint8_t *buf = malloc(size + 8);
  if (!buf) return 0;
  memcpy(buf, data, size);
  size_t n = size;
  uint64_t h;
  if (size >= 8) memcpy(&h, data + size - 8, 8);
  if (size < 8 || fnv1a(data, size - 8) != h) {
    h = fnv1a(data, size);
    memcpy(buf + size, &h, 8);
    n = size + 8;
  }
  char path[512];
  int w = km_fuzz_write_temp(buf, n, "kmposedb", path, sizeof path);
  free(buf);
  if (w) return 0;
  km_error err;
  km_posedb *db = NULL;
  if (km_posedb_load(path, &db, &err) == KM_OK) {
    size_t nl = km_posedb_landmark_count(db);
    if (nl < 4 || nl > KM_POSE_MAX_LANDMARKS || km_posedb_size(db) < 2) abort();
    double P[KM_POSE_MAX_LANDMARKS * 3];
    for (size_t i = 0; i < nl * 3; ++i)
      P[i] = 0.1 * (double)(i % 7) - 0.2 * (double)(i % 3);
    km_pose_match m;
    if (km_posedb_query(db, P, &m, &err) == KM_OK && m.template_index >= km_posedb_size(db))
      abort();
  }
  km_posedb_free(&db);
  remove(path);
  return 0;
}
