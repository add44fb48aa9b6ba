/* Tests of the capture verbs through the CLI (reconstruct, batch): a simulated capture made by
 * `gen motion` + `gen capture`, and JSON reports read back. Include after km_test.h. */
#ifndef KM_CAPTURE_FIXTURE_H
#define KM_CAPTURE_FIXTURE_H

#include "km_test.h"

#include <cjson/cJSON.h>

/* A JSON file parsed, or NULL when it cannot be read or parsed (caller cJSON_Deletes). */
static inline cJSON *km_test_read_json(const char *path) {
  size_t n = 0;
  char *data = km_test_read_file(path, &n);
  cJSON *j = data ? cJSON_Parse(data) : NULL;
  free(data);
  return j;
}

/* o[key] as a number, NaN when absent or not a number. */
static inline double km_test_json_number(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

/* A simulated capture of the character mesh CHARACTER (its rig sidecar beside it, as `gen
 * character` writes): `gen motion --kind KIND --frames FRAMES` into the take TAKE, then `gen
 * capture` of that take by `cameras` cameras and `points` points a frame, with EXTRA further
 * options ("--noise-mm 2 --seed 3"; "" for none), into the folder OUT (OUT/frame_*.ply,
 * OUT/truth.pc2). *log (if given) receives the commands' output (caller frees). Returns 0, or
 * non-zero when a command failed (it is printed on stderr with its output). */
static inline int km_test_capture(const char *character, const char *kind, int frames,
                                  const char *take, int cameras, int points, const char *extra,
                                  const char *out, char **log) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd,
           KM_CLI " gen motion --kind %s --frames %d --character %s -o %s && " KM_CLI
                  " gen capture --character %s --motion %s --cameras %d --points %d %s -o %s",
           kind, frames, character, take, character, take, cameras, points, extra, out);
  char *o = NULL;
  int rc = km_test_run(cmd, &o);
  if (rc) fprintf(stderr, "km_test_capture: %s: exit %d\n%s\n", cmd, rc, o ? o : "");
  if (log)
    *log = o;
  else
    free(o);
  return rc;
}

#endif
