/* kinemesh bench rig: time of automatic rigging (km_autorig) at several vertex counts, on the
 * procedural character ("character:N") and on mesh files. Target: <= 2 s at 50k vertices. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int bench_rig_one(const char *spec, size_t repeat, bool json, bool header,
                         km_autorig_skin skin) {
  km_error err = {0};
  km_mesh m = {0};
  km_character c = {0};
  km_autorig_report rep;
  double *t = calloc(repeat, sizeof *t), *tw = calloc(repeat, sizeof *tw);
  char tmp[] = "/tmp/km_bench_rig_XXXXXX";
  int fd = -1, rc = KM_EXIT_FAIL;
  if (!t || !tw) {
    rc = km_cli_error("bench rig", "out of memory");
    goto done;
  }
  if (km_bench_mesh(spec, &m, NULL, &err) != KM_OK) {
    rc = km_cli_fail("bench rig", &err);
    goto done;
  }
  /* a file in its own axes is rigged as `rig` rigs it: brought into kinemesh's frame by the
   * guess `rig` makes (the horse, z up, was rigged lying down, as a humanoid) */
  km_cli_frame_opts fo = {0};
  if (strncmp(spec, "character:", 10) && km_cli_orient_mesh("bench rig", spec, &fo, &m))
    goto done; /* printed; rc stays KM_EXIT_FAIL */
  fd = mkstemp(tmp);
  if (fd < 0) {
    rc = km_cli_error("bench rig", "cannot create a temporary file");
    goto done;
  }
  km_autorig_options o = {0};
  o.skin = skin;
  for (size_t i = 0; i < repeat; ++i) {
    km_character_free(&c);
    double t0 = km_cli_now();
    if (km_autorig(&m, &o, &c, &rep, &err) != KM_OK) {
      rc = km_cli_fail("bench rig", &err);
      goto done;
    }
    t[i] = km_cli_now() - t0;
    t0 = km_cli_now();
    if (km_character_write_rig(tmp, &c, &err) != KM_OK) {
      rc = km_cli_fail("bench rig", &err);
      goto done;
    }
    tw[i] = km_cli_now() - t0;
  }
  double mt = km_cli_median(t, repeat), mw = km_cli_median(tw, repeat);
  const char *kind = km_autorig_kind_name(rep.kind);
  char machine[320];
  km_bench_machine(machine, sizeof machine);
  if (json) {
    cJSON *o = km_bench_row(spec, machine, m.n_vertices);
    cJSON_AddStringToObject(o, "kind", kind);
    cJSON_AddStringToObject(o, "weights",
                            rep.skin == KM_AUTORIG_SKIN_REACH      ? "reach"
                            : rep.skin == KM_AUTORIG_SKIN_DISTANCE ? "distance"
                                                                   : "heat");
    cJSON_AddNumberToObject(o, "extremities", (double)rep.n_extremities);
    cJSON_AddNumberToObject(o, "repeat", (double)repeat);
    cJSON_AddNumberToObject(o, "rig_s", mt);
    cJSON_AddNumberToObject(o, "write_s", mw);
    km_bench_row_print(o);
  } else {
    if (header) {
      printf("kinemesh bench rig — %s; medians of %zu runs; rig = km_autorig (extremities, "
             "skeleton, skin weights by %s, landmarks), write = the sidecar "
             "(km_character_write_rig)\n",
             machine, repeat,
             skin == KM_AUTORIG_SKIN_REACH      ? "reach"
             : skin == KM_AUTORIG_SKIN_DISTANCE ? "distance"
                                                : "bone heat");
      printf("%-28s %8s %10s %5s %9s %9s\n", "model", "n_ver", "kind", "n_ext", "rig(s)",
             "write(s)");
    }
    const char *base = strrchr(spec, '/');
    printf("%-28.28s %8zu %10s %5zu %9.3f %9.3f\n", base ? base + 1 : spec, m.n_vertices, kind,
           rep.n_extremities, mt, mw);
  }
  rc = KM_EXIT_OK;
done:
  if (fd >= 0) {
    close(fd);
    remove(tmp);
  }
  km_character_free(&c);
  km_mesh_free(&m);
  free(t);
  free(tw);
  return rc;
}

int km_bench_rig(int argc, char **argv) {
  size_t repeat = 3;
  bool json = false;
  const char *weights = NULL;
  const km_cli_opt opts[] = {
      {"repeat", 0, KM_OPT_SIZE, &repeat, "runs per mesh (default 3; the median is printed)"},
      {"json", 0, KM_OPT_FLAG, &json, "print one JSON object per mesh, one per line"},
      {"weights", 0, KM_OPT_STRING, &weights,
       "skin weights: heat (default), distance or reach (rig --weights)"},
  };
  enum { MAX_MESHES = 32 };
  const char *pos[MAX_MESHES];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, MAX_MESHES, &n_pos,
      "kinemesh bench rig [MESH ...] [--repeat 3] [--weights heat|distance|reach] [--json]",
      "Times automatic rigging (kinemesh rig) per mesh: a file, or character:N\n"
      "for the procedural character with N vertices. Default: character:10000\n"
      "character:50000 character:100000. Target: <= 2 s at 50k vertices.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (repeat < 1) return km_cli_error("bench rig", "--repeat must be at least 1");
  km_autorig_skin skin;
  if (km_cli_parse_weights("bench rig", weights, &skin)) return KM_EXIT_USAGE;
  static const char *const defaults[] = {"character:10000", "character:50000", "character:100000"};
  if (!n_pos) {
    for (int i = 0; i < 3; ++i)
      pos[i] = defaults[i];
    n_pos = 3;
  }
  int rc = KM_EXIT_OK;
  for (int i = 0; i < n_pos; ++i) {
    int ri = bench_rig_one(pos[i], repeat, json, i == 0, skin);
    if (ri != KM_EXIT_OK) rc = ri;
    fflush(stdout);
  }
  return rc;
}
