/* Helpers that two or more verb files share and cli_common.c does not have (yet). */
#ifndef KM_CLI_VERBS_H
#define KM_CLI_VERBS_H

#include "cli.h"

/* Prints root (then deletes it) as indented JSON on stdout; "kinemesh <verb>: out of memory"
 * and exit status 1 when it cannot. */
int km_cli_print_json(const char *verb, cJSON *root);

/* Landmarks for a mesh of n_vertices: the --landmarks file lm_path, else the rig sidecar next
 * to mesh_path (<stem>.rig.json). At most capacity into lm, count in *n. */
km_status km_cli_load_landmarks(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                km_landmark *lm, size_t capacity, size_t *n, km_error *err);

#endif
