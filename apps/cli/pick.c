/* kinemesh pick: the vertex ids nearest to a point (km_nearest_vertices), for scripts and
 * hand-written rigs. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

int km_cli_pick(int argc, char **argv) {
  const char *near = NULL;
  size_t k = 1;
  bool json = false;
  const km_cli_opt opts[] = {
      {"near", 0, KM_OPT_STRING, &near, "the point x,y,z (mesh units)"},
      {"k", 'k', KM_OPT_SIZE, &k, "how many vertices (default 1)"},
      {"json", 0, KM_OPT_FLAG, &json, "print a JSON array of {vertex, position, distance}"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                       "kinemesh pick MESH --near x,y,z [--k N] [--json]",
                       "Prints the ids and positions of the k vertices nearest to a point,\n"
                       "nearest first (ids are 0-based, in the file's vertex order: what rig\n"
                       "handles and landmarks refer to).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("pick", "expected one MESH");
  if (!near) return km_cli_error("pick", "--near x,y,z is required");
  double p[3];
  char *end = NULL;
  const char *s = near;
  for (int i = 0; i < 3; ++i) {
    p[i] = strtod(s, &end);
    if (end == s || (i < 2 && *end != ',') || (i == 2 && *end != '\0'))
      return km_cli_error("pick", "--near %s: expected three numbers x,y,z", near);
    s = end + 1;
  }
  if (k < 1) return km_cli_error("pick", "--k must be at least 1");
  km_error err = {0};
  km_mesh m = {0};
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) return km_cli_fail("pick", &err);
  if (k > m.n_vertices) k = m.n_vertices;
  int32_t *ids = malloc(sizeof *ids * (k ? k : 1));
  double *d = malloc(sizeof *d * (k ? k : 1));
  if (!ids || !d) {
    free(ids);
    free(d);
    km_mesh_free(&m);
    return km_cli_error("pick", "out of memory");
  }
  size_t n = km_nearest_vertices(m.V, m.n_vertices, p, k, ids, d);
  if (json) putchar('[');
  for (size_t i = 0; i < n; ++i) {
    const double *q = m.V + 3 * (size_t)ids[i];
    if (json)
      printf("%s{\"vertex\":%d,\"position\":[%.9g,%.9g,%.9g],\"distance\":%.9g}", i ? "," : "",
             (int)ids[i], q[0], q[1], q[2], d[i]);
    else
      printf("%d %.9g %.9g %.9g  (distance %.6g)\n", (int)ids[i], q[0], q[1], q[2], d[i]);
  }
  if (json) puts("]");
  free(ids);
  free(d);
  km_mesh_free(&m);
  return KM_EXIT_OK;
}
