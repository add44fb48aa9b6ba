/* kinemesh bake: any mesh animation (.glb morph targets, .pc2, a frame directory) to a
 * skinned .glb fitted by skinning decomposition (km_ssdr_fit), or to another export kind. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

int km_cli_bake(int argc, char **argv) {
  const char *out = NULL, *mesh_path = NULL, *export_kind = "skin";
  bool compress = false;
  double max_error_mm = 0, fps = 0;
  const km_cli_opt opts[] = {
      KM_CLI_EXPORT_OPTIONS(export_kind, max_error_mm, compress),
      {"mesh", 0, KM_OPT_STRING, &mesh_path,
       "rest mesh (faces, UVs, normals) for a .pc2 or to replace the input's; same vertex count "
       "and order"},
      {"fps", 0, KM_OPT_DOUBLE, &fps, "frame rate when the input does not say (default 30)"},
      {"output", 'o', KM_OPT_STRING, &out, "output .glb"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                   "kinemesh bake IN(.glb|.pc2|frames dir) [--mesh REST] [--export skin[:BONES]] "
                   "[--max-error-mm MM] [--compress] -o OUT.glb",
                   "Fits a linear-blend-skinning rig to a mesh animation (Le & Deng 2012,\n"
                   "SSDR): <= 4 bone weights per vertex and one rotation + translation per\n"
                   "bone and frame, written as a skinned glTF that engines and Blender play\n"
                   "as is. Prints the RMS and max error against the input's frames.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1 || !out) return km_cli_error("bake", "expected IN and -o OUT.glb (see --help)");
  km_anim_options ao = {0};
  km_ssdr_options so;
  if (km_cli_parse_export("bake", export_kind, max_error_mm, compress, out, &ao, &so))
    return KM_EXIT_FAIL;
  km_error err = {0};
  km_mesh rest = {0}, given = {0};
  double *frames = NULL;
  km_anim_info info;
  km_anim_writer *w = NULL;
  int rc = KM_EXIT_FAIL;
  double t0 = km_cli_now();
  if (km_anim_read(pos[0], &rest, &frames, &info, &err) != KM_OK) goto fail;
  if (mesh_path) {
    if (km_mesh_read(mesh_path, &given, &err) != KM_OK) goto fail;
    if (given.n_vertices != rest.n_vertices) {
      rc = km_cli_error("bake", "%s has %zu vertices, %s %zu", mesh_path, given.n_vertices, pos[0],
                        rest.n_vertices);
      goto done;
    }
  }
  ao.fps = info.fps > 0 ? info.fps : (fps > 0 ? fps : 30);
  if (fps > 0) ao.fps = fps;
  double t_read = km_cli_now() - t0;
  const km_mesh *m = mesh_path ? &given : &rest;
  if (km_anim_writer_open(out, m, &ao, &w, &err) != KM_OK) goto fail;
  for (size_t k = 0; k < info.frames; ++k)
    if (km_anim_writer_push(w, frames + k * rest.n_vertices * 3, &err) != KM_OK) goto fail;
  km_anim_report rep;
  if (km_anim_writer_finish(&w, &rep, &err) != KM_OK) goto fail;
  km_cli_progress_done();
  km_cli_report_export("bake", &rep);
  fprintf(stderr, "kinemesh bake: %zu frames of %zu vertices (read in %.2f s) in %.1f s -> %s\n",
          info.frames, rest.n_vertices, t_read, km_cli_now() - t0, out);
  rc = KM_EXIT_OK;
  goto done;
fail:
  km_cli_progress_done();
  rc = km_cli_fail("bake", &err);
done:
  km_anim_writer_free(&w);
  free(frames);
  km_mesh_free(&rest);
  km_mesh_free(&given);
  return rc;
}
