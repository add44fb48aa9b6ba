/* kinemesh convert: a mesh between OBJ, PLY, OFF and STL (and from glTF), chosen by extension;
 * with --up / --forward / --units / --scale, rewritten into kinemesh's frame (y up, facing +z,
 * metres). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int km_cli_convert(int argc, char **argv) {
  const char *ply = NULL, *out = NULL;
  double scale = 0;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      {"output", 'o', KM_OPT_STRING, &out, "output mesh (.obj, .ply, .off, .stl), or OUT"},
      {"ply", 0, KM_OPT_STRING, &ply, "PLY encoding: binary (default), binary-be, ascii"},
      KM_CLI_FRAME_OPTIONS(fo),
      {"scale", 0, KM_OPT_DOUBLE, &scale, "multiply coordinates by X (after --units)"},
  };
  const char *pos[2];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 2, &n_pos,
                       "kinemesh convert IN OUT|-o OUT [--ply ascii] [--up +z --forward -y] "
                       "[--units cm] [--scale X]",
                       "Converts between OBJ, PLY, OFF and STL by file extension (glTF is read\n"
                       "too). Vertex order and coordinates are kept exactly (an STL has no\n"
                       "vertex list: its equal corners are welded into one vertex, in facet\n"
                       "order, and it is written binary, float32, positions only); polygons\n"
                       "are fan-triangulated; texture coordinates and normals are kept (OBJ,\n"
                       "PLY). With --up, --forward, --units or --scale the mesh is rotated and\n"
                       "scaled into kinemesh's frame (y up, facing +z, metres; a missing axis\n"
                       "is guessed and printed).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  /* OUT as every other verb takes it (-o) or as the second argument, as cp does */
  if (n_pos == 2 && out && strcmp(out, pos[1]))
    return km_cli_error("convert", "two outputs given ('%s' and -o '%s'): give one", pos[1], out);
  if (n_pos == 1 && out) pos[n_pos++] = out;
  if (n_pos != 2)
    return km_cli_error("convert", "expected IN and OUT (or -o OUT; see kinemesh convert --help)");
  if (scale < 0 || !isfinite(scale))
    return km_cli_error("convert", "--scale must be positive, not %g", scale);
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
  if (fo.up || fo.forward || fo.units || scale > 0) {
    km_frame f;
    int rc = km_cli_mesh_frame("convert", pos[0], &fo, &m, false, &f, NULL);
    if (!rc) {
      if (scale > 0) f.scale = (f.scale > 0 ? f.scale : 1) * scale;
      if (km_mesh_frame_apply(&f, &m, &err) != KM_OK) rc = km_cli_fail("convert", &err);
    }
    if (rc) {
      km_mesh_free(&m);
      return rc;
    }
  }
  km_status s = km_mesh_write(pos[1], &m, &wo, &err);
  size_t nv = m.n_vertices, nf = m.n_faces;
  km_mesh_free(&m);
  if (s != KM_OK) return km_cli_fail("convert", &err);
  fprintf(stderr, "kinemesh convert: wrote %s (%zu vertices, %zu triangles)\n", pos[1], nv, nf);
  return KM_EXIT_OK;
}
