/* kinemesh convert: a mesh between OBJ, PLY and OFF, chosen by extension. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

int km_cli_convert(int argc, char **argv) {
  const char *ply = NULL;
  const km_cli_opt opts[] = {
      {"ply", 0, KM_OPT_STRING, &ply, "PLY encoding: binary (default), binary-be, ascii"}};
  const char *pos[2];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, 1, pos, 2, &n_pos, "kinemesh convert IN OUT [--ply ascii]",
                       "Converts between OBJ, PLY and OFF by file extension. Vertex order and\n"
                       "coordinates are kept exactly; polygons are fan-triangulated.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 2)
    return km_cli_error("convert", "expected IN and OUT (see kinemesh convert --help)");
  km_mesh_write_options wo = {0};
  if (ply) {
    if (!strcmp(ply, "binary") || !strcmp(ply, "binary-le"))
      wo.ply = KM_PLY_BINARY_LE;
    else if (!strcmp(ply, "binary-be"))
      wo.ply = KM_PLY_BINARY_BE;
    else if (!strcmp(ply, "ascii"))
      wo.ply = KM_PLY_ASCII;
    else
      return km_cli_error("convert", "--ply must be binary, binary-be or ascii, not '%s'", ply);
  }
  km_error err = {0};
  km_mesh m = {0};
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) return km_cli_fail("convert", &err);
  km_status s = km_mesh_write(pos[1], &m, &wo, &err);
  size_t nv = m.n_vertices, nf = m.n_faces;
  km_mesh_free(&m);
  if (s != KM_OK) return km_cli_fail("convert", &err);
  fprintf(stderr, "kinemesh convert: wrote %s (%zu vertices, %zu triangles)\n", pos[1], nv, nf);
  return KM_EXIT_OK;
}
