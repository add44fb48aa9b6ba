/* kinemesh bench start: how long `kinemesh animate` takes from the command to its last frame on
 * a short take, cold (an empty cache folder: the reduced model precomputed, the stretch
 * bound's Dijkstra runs made) and warm (both read back), the wall time a user waits. Each run
 * is this program's own `animate` in a child process (as a user runs it), its cache folder
 * (XDG_CACHE_HOME) a temporary one, never the user's. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Runs cmd (a shell line) and returns its wall time in seconds, or -1 when it fails. */
static double timed(const char *cmd) {
  double t0 = km_cli_now();
  if (system(cmd) != 0) return -1;
  return km_cli_now() - t0;
}

static int bench_start_one(const char *self, const char *spec, size_t frames, size_t repeat,
                           bool json, bool header) {
  char dir[] = "/tmp/km_bench_start_XXXXXX", mesh[4200], cmd[16384];
  if (!mkdtemp(dir)) return km_cli_error("bench start", "cannot create a temporary folder");
  int rc = KM_EXIT_FAIL;
  double *cold = calloc(repeat, sizeof *cold), *warm = calloc(repeat, sizeof *warm);
  km_mesh m = {0};
  km_error err = {0};
  if (!cold || !warm) {
    rc = km_cli_error("bench start", "out of memory");
    goto done;
  }
  if (strchr(spec, '\'')) {
    rc = km_cli_error("bench start", "%s: a quote in the path", spec);
    goto done;
  }
  if (!strncmp(spec, "character:", 10)) { /* written as a file: animate reads one */
    snprintf(mesh, sizeof mesh, "%s/character.obj", dir);
    snprintf(cmd, sizeof cmd, "'%s' gen character --vertices %s -o '%s' >/dev/null 2>&1", self,
             spec + 10, mesh);
    if (system(cmd) != 0) {
      rc = km_cli_error("bench start", "kinemesh gen character --vertices %s failed", spec + 10);
      goto done;
    }
  } else {
    snprintf(mesh, sizeof mesh, "%s", spec);
  }
  if (km_mesh_read(mesh, &m, &err) != KM_OK) {
    rc = km_cli_fail("bench start", &err);
    goto done;
  }
  /* the rig (timed by bench rig) and the take, made once */
  snprintf(cmd, sizeof cmd,
           "'%s' rig '%s' -o '%s/rig.json' >/dev/null 2>&1 && '%s' gen motion --kind walk "
           "--frames %zu -o '%s/take.json' >/dev/null 2>&1",
           self, mesh, dir, self, frames, dir);
  if (system(cmd) != 0) {
    rc = km_cli_error("bench start", "kinemesh rig %s or gen motion failed (run it to see why)",
                      mesh);
    goto done;
  }
  for (size_t i = 0; i < 2 * repeat; ++i) {
    bool is_cold = i < repeat; /* cold: a fresh cache folder each run; warm: the last one's */
    char fresh[4200] = "";
    if (is_cold) snprintf(fresh, sizeof fresh, "rm -rf '%s/cache' && ", dir);
    snprintf(cmd, sizeof cmd,
             "%sXDG_CACHE_HOME='%s/cache' '%s' animate --mesh '%s' --rig '%s/rig.json' --motion "
             "'%s/take.json' -o '%s/out.pc2' >/dev/null 2>&1",
             fresh, dir, self, mesh, dir, dir, dir);
    double t = timed(cmd);
    if (t < 0) {
      rc = km_cli_error("bench start", "kinemesh animate --mesh %s failed (run it to see why)",
                        mesh);
      goto done;
    }
    (is_cold ? cold : warm)[is_cold ? i : i - repeat] = t;
  }
  double mc = km_cli_median(cold, repeat), mw = km_cli_median(warm, repeat);
  char machine[320];
  km_bench_machine(machine, sizeof machine);
  if (json) {
    cJSON *o = km_bench_row(spec, machine, m.n_vertices);
    cJSON_AddNumberToObject(o, "frames", (double)frames);
    cJSON_AddNumberToObject(o, "repeat", (double)repeat);
    cJSON_AddNumberToObject(o, "cold_s", mc);
    cJSON_AddNumberToObject(o, "warm_s", mw);
    km_bench_row_print(o);
  } else {
    if (header) {
      printf("kinemesh bench start — %s; medians of %zu runs of `kinemesh animate` on a "
             "%zu-frame walk, wall time from the command to its last frame written: cold = an "
             "empty cache folder (reduced model precomputed, stretch bound computed), warm = "
             "both read from it\n",
             machine, repeat, frames);
      printf("%-28s %8s %9s %9s\n", "model", "n_ver", "cold(s)", "warm(s)");
    }
    const char *base = strrchr(spec, '/');
    printf("%-28.28s %8zu %9.3f %9.3f\n", base ? base + 1 : spec, m.n_vertices, mc, mw);
  }
  rc = KM_EXIT_OK;
done:
  km_mesh_free(&m);
  free(cold);
  free(warm);
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  if (system(cmd) != 0) fprintf(stderr, "kinemesh bench start: could not remove %s\n", dir);
  return rc;
}

int km_bench_start(int argc, char **argv) {
  size_t repeat = 3, frames = 30;
  bool json = false;
  const km_cli_opt opts[] = {
      {"repeat", 0, KM_OPT_SIZE, &repeat, "cold and warm runs per mesh (default 3; medians)"},
      {"frames", 0, KM_OPT_SIZE, &frames, "frames of the walk (default 30)"},
      {"json", 0, KM_OPT_FLAG, &json, "print one JSON object per mesh, one per line"},
  };
  enum { MAX_MESHES = 32 };
  const char *pos[MAX_MESHES];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, MAX_MESHES, &n_pos,
                       "kinemesh bench start [MESH ...] [--repeat 3] [--frames 30] [--json]",
                       "Times `kinemesh animate` from the command to its last frame, cold (an\n"
                       "empty cache folder) and warm (the cache read back), per mesh: a file,\n"
                       "or character:N for the procedural character with N vertices. Default:\n"
                       "character:10000 character:100000.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (repeat < 1 || frames < 2)
    return km_cli_error("bench start", "--repeat must be at least 1 and --frames at least 2");
  char self[4096];
  if (!km_bench_self("bench start", self, sizeof self)) return KM_EXIT_FAIL;
  static const char *const defaults[] = {"character:10000", "character:100000"};
  if (!n_pos) {
    for (int i = 0; i < 2; ++i)
      pos[i] = defaults[i];
    n_pos = 2;
  }
  int rc = KM_EXIT_OK;
  for (int i = 0; i < n_pos; ++i) {
    int ri = bench_start_one(self, pos[i], frames, repeat, json, i == 0);
    if (ri != KM_EXIT_OK) rc = ri;
    fflush(stdout);
  }
  return rc;
}
