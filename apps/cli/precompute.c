/* kinemesh precompute: the reduced puppetry model of a mesh, cached (km_puppetry_model_open). */
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int km_cli_precompute(int argc, char **argv) {
  const char *out = NULL, *energy = NULL;
  int fields = 8, isolines = 10;
  bool force = false;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      {"output", 'o', KM_OPT_STRING, &out,
       "cache file (default: the user's cache folder, $XDG_CACHE_HOME/kinemesh)"},
      {"fields", 0, KM_OPT_INT, &fields, "propagation fields n_e (default 8)"},
      {"isolines", 0, KM_OPT_INT, &isolines, "isolines per field n_iso (default 10)"},
      {"energy", 0, KM_OPT_STRING, &energy,
       "reduced model energy: arap (default) or laplacian (the paper's eq. 8-9)"},
      {"force", 0, KM_OPT_FLAG, &force, "rebuild even when the cache is up to date"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                       "kinemesh precompute MESH [-o CACHE] [--fields 8] [--isolines 10] "
                       "[--energy arap|laplacian] [--force]",
                       "Builds the reduced isoline model of a mesh (eigenfields of the cotangent\n"
                       "Laplacian, isolines, interpolation W, W'L'LW) and writes it to a\n"
                       "versioned, checksummed cache that animate and live reuse. A cache that\n"
                       "is already up to date for this mesh and these parameters is loaded and\n"
                       "kept (--force rebuilds it).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("precompute", "expected one MESH");
  km_puppet_options po = {0};
  po.fields = fields;
  po.isolines = isolines;
  if (km_cli_parse_energy("precompute", energy, &po.energy)) return KM_EXIT_FAIL;
  km_error err = {0};
  km_mesh m = {0};
  km_puppetry *p = NULL;
  char *cache = NULL;
  const char *path = out;
  int rc = KM_EXIT_OK;
  double t0;
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) {
    rc = km_cli_fail("precompute", &err);
    goto done;
  }
  if ((rc = km_cli_orient_mesh("precompute", pos[0], &fo, &m))) goto done;
  if (!out && !(path = cache = km_cli_cache_path(&m))) {
    rc = km_cli_error("precompute", "out of memory");
    goto done;
  }
  km_puppetry_options o = {0};
  o.puppet = po;
  o.puppet.progress = km_cli_progress("precompute");
  o.cache_path = path;
  o.force = force;
  km_puppetry_info pi;
  t0 = km_cli_now();
  if (km_puppetry_create(&m, NULL, NULL, 0, &o, &p, &pi, &err) != KM_OK) {
    rc = km_cli_fail("precompute", &err);
    goto done;
  }
  km_cli_progress_done();
  if (pi.model == KM_PUPPETRY_MODEL_REBUILT_STALE)
    fprintf(stderr, "kinemesh precompute: rebuilding %s: %s\n", path, pi.stale.message);
  if (pi.save.status != KM_OK) {
    rc = km_cli_fail("precompute", &pi.save);
    goto done;
  }
  bool loaded = pi.model == KM_PUPPETRY_MODEL_LOADED;
  km_puppet_info info;
  km_puppetry_puppet_info(p, &info);
  fprintf(stderr,
          "kinemesh precompute: %zu vertices, %d fields x %d isolines (%zu unknowns per "
          "coordinate), %zu crossed triangles; %s in %.3f s -> %s\n",
          info.vertices, info.fields, info.isolines, info.unknowns, info.crossed_triangles,
          loaded ? "up to date, loaded (t~1)" : "built (t1)", km_cli_now() - t0, path);
done:
  free(cache);
  km_puppetry_free(&p);
  km_mesh_free(&m);
  return rc;
}
