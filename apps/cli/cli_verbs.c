/* Helpers shared by verb files (cli_verbs.h). */
#include "cli_verbs.h"

#include <stdlib.h>

int km_cli_print_json(const char *verb, cJSON *root) {
  char *s = cJSON_Print(root);
  cJSON_Delete(root);
  if (!s) return km_cli_error(verb, "out of memory");
  puts(s);
  free(s);
  return KM_EXIT_OK;
}

km_status km_cli_load_landmarks(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                km_landmark *lm, size_t capacity, size_t *n, km_error *err) {
  if (lm_path) return km_landmarks_read(lm_path, n_vertices, lm, capacity, n, err);
  char *rig = km_cli_rig_path(mesh_path);
  if (!rig) {
    err->status = KM_ERR_NOMEM;
    snprintf(err->message, sizeof err->message, "out of memory");
    return KM_ERR_NOMEM;
  }
  km_status s = km_landmarks_read(rig, n_vertices, lm, capacity, n, err);
  free(rig);
  return s;
}
