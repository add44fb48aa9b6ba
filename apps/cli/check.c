/* kinemesh check: the deformation check (km_deform_check) of any mesh animation, as animate
 * prints it for its own: a .glb of morph targets, a .pc2 or a frame directory, written by
 * kinemesh or by another tool, measured against its rest mesh. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int km_cli_check(int argc, char **argv) {
  const char *mesh_path = NULL, *rig_path = NULL, *report = NULL, *units = NULL;
  double max_stretch = NAN, max_step = NAN, max_folded = NAN;
  const km_cli_opt opts[] = {
      {"mesh", 0, KM_OPT_STRING, &mesh_path,
       "the rest mesh, vertex for vertex (needed for a .pc2; default: a .glb's base mesh, a "
       "frame directory's first frame)"},
      {"units", 0, KM_OPT_STRING, &units,
       "the rest mesh's units, as given to animate --units: m (default), cm, mm, in, ft, or "
       "metres per unit (animate writes metres)"},
      {"rig", 0, KM_OPT_STRING, &rig_path,
       "name places by this rig's handles (default: vertex ids)"},
      {"report", 0, KM_OPT_STRING, &report, "write every frame's measures as JSON"},
      {"max-stretch", 0, KM_OPT_DOUBLE, &max_stretch,
       "limit on |l/l0 - 1| of every edge in every frame (issue 12's target: 0.5)"},
      {"max-folded", 0, KM_OPT_DOUBLE, &max_folded,
       "limit on the triangles folded in some frame (issue 12's target: 0)"},
      {"max-step", 0, KM_OPT_DOUBLE, &max_step,
       "limit on the largest one-frame vertex step, % of the mesh's size (issue 12's target: 3)"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                   "kinemesh check ANIM [--mesh REST] [--units U] [--rig RIG] [--report R.json] "
                   "[--max-stretch S] [--max-folded N] [--max-step P]",
                   "Measures every frame of a mesh animation against its rest mesh, as\n"
                   "animate does for its own (edge length ratios l/l0, folded triangles,\n"
                   "one-frame steps), prints one line saying where the mesh suffered and,\n"
                   "with --report, every frame's measures as JSON. With limits (--max-*),\n"
                   "the exit status is 3 when the animation exceeds one of them, so a\n"
                   "pipeline can flag the takes to look at (1 is an error, as everywhere).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("check", "expected one animation (.glb, .pc2 or a folder)");
  double scale = 1;
  if (km_cli_parse_units("check", "units", units, &scale)) return KM_EXIT_USAGE;
  const double *lim[3] = {&max_stretch, &max_folded, &max_step};
  static const char *const lim_name[3] = {"--max-stretch", "--max-folded", "--max-step"};
  for (int k = 0; k < 3; ++k)
    if (!isnan(*lim[k]) && !(*lim[k] >= 0 && isfinite(*lim[k])))
      return km_cli_error("check", "%s %g: expected a number >= 0", lim_name[k], *lim[k]);
  km_error err = {0};
  km_mesh rest = {0}, given = {0};
  km_rig rig = {0};
  km_anim_info info = {0};
  double *frames = NULL;
  km_deform_check *dc = NULL;
  int rc = KM_EXIT_FAIL;
  if (km_anim_read(pos[0], &rest, &frames, &info, &err) != KM_OK) goto fail;
  if (mesh_path) {
    if (km_mesh_read(mesh_path, &given, &err) != KM_OK) goto fail;
    if (given.n_vertices != info.vertices) {
      rc = km_cli_error("check", "%s has %zu vertices, %s %zu: not the same mesh", mesh_path,
                        given.n_vertices, pos[0], info.vertices);
      goto done;
    }
    for (size_t i = 0; i < 3 * given.n_vertices; ++i)
      given.V[i] *= scale;
    km_mesh_free(&rest);
    rest = given;
    memset(&given, 0, sizeof given);
  } else if (!rest.n_faces) {
    rc = km_cli_error("check",
                      "%s has no faces (a .pc2 holds positions only): give the rest "
                      "mesh with --mesh",
                      pos[0]);
    goto done;
  }
  if (!info.frames) {
    rc = km_cli_error("check", "%s has no frames", pos[0]);
    goto done;
  }
  /* units: a frame many times the rest's size is in other units, not a stretch (a NaN frame
   * is left to the check, which reports it) */
  double d0 = km_bbox_diagonal(rest.V, rest.n_vertices),
         d1 = km_bbox_diagonal(frames, info.vertices);
  if (!isnan(d1) && !(d1 <= 4 * d0 && d1 >= 0.25 * d0)) {
    rc = km_cli_error("check",
                      "%s: its first frame is %.3g times the size of the rest mesh: not in its "
                      "units (animate writes metres; --units gives the rest mesh's)",
                      pos[0], d0 > 0 ? d1 / d0 : INFINITY);
    goto done;
  }
  if (rig_path && km_rig_read(rig_path, &rest, NULL, 0, &rig, &err) != KM_OK) goto fail;
  if (km_deform_check_create(&rest, &dc, &err) != KM_OK) goto fail;
  for (size_t f = 0; f < info.frames; ++f)
    if (km_deform_check_add(dc, frames + 3 * f * info.vertices, NULL, &err) != KM_OK) goto fail;
  if (report && km_deform_check_write_json(dc, report, &err) != KM_OK) goto fail;
  char line[1024];
  km_cli_shape_line(dc, &rest, rig_path ? &rig : NULL, line, sizeof line);
  printf("%s: %zu frames, %zu vertices, against %s\n%s", pos[0], info.frames, info.vertices,
         mesh_path ? mesh_path : (info.format == KM_ANIM_GLB ? "its base mesh" : "its first frame"),
         line);
  if (report) printf("-> %s\n", report);
  rc = KM_EXIT_OK;
  if (!isnan(max_stretch) || !isnan(max_folded) || !isnan(max_step)) {
    km_deform_summary s;
    km_deform_check_summary(dc, &s);
    double step = s.diagonal > 0 ? 100 * s.step / s.diagonal : 0;
    char over[512] = "";
    int k = 0;
    /* a NaN frame exceeds every limit: no number of it is within one */
    if (!isnan(max_stretch) && !(s.stretch <= max_stretch))
      k += snprintf(over + k, sizeof over - (size_t)k, "%sstretch %.3f > %g (frame %zu)",
                    k ? ", " : "", s.stretch, max_stretch, s.stretch_frame);
    if (!isnan(max_folded) && !((double)s.folded <= max_folded))
      k += snprintf(over + k, sizeof over - (size_t)k,
                    "%s%zu folded triangles > %g (most in frame %zu)", k ? ", " : "", s.folded,
                    max_folded, s.most_folded_frame);
    if (!isnan(max_step) && !(step <= max_step))
      k += snprintf(over + k, sizeof over - (size_t)k, "%sstep %.2f %% > %g %% (frame %zu)",
                    k ? ", " : "", step, max_step, s.step_frame);
    if (k) {
      printf("  limits exceeded: %s\n", over);
      rc = KM_EXIT_LIMITS;
    } else {
      printf("  within the limits\n");
    }
  }
  goto done;
fail:
  rc = km_cli_fail("check", &err);
done:
  km_deform_check_free(&dc);
  km_rig_free(&rig);
  km_mesh_free(&rest);
  km_mesh_free(&given);
  free(frames);
  return rc;
}
