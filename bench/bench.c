/* kinemesh bench <what>: paper-style timing tables (medians of repeated runs, machine named).
 * Speed is measured here, never in tests. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* "model name" of the first CPU and the core count, for the table header. */
void km_bench_machine(char *out, size_t n) {
  char model[256] = "unknown CPU";
  FILE *f = fopen("/proc/cpuinfo", "r");
  if (f) {
    char line[512];
    while (fgets(line, sizeof line, f))
      if (!strncmp(line, "model name", 10)) {
        char *c = strchr(line, ':');
        if (c) {
          c += 1 + (c[1] == ' ');
          c[strcspn(c, "\n")] = '\0';
          snprintf(model, sizeof model, "%s", c);
        }
        break;
      }
    fclose(f);
  }
  snprintf(out, n, "%s, %ld cores", model, sysconf(_SC_NPROCESSORS_ONLN));
}

bool km_bench_self(const char *verb, char *out, size_t n) {
  ssize_t len = readlink("/proc/self/exe", out, n - 1);
  if (len <= 0) {
    km_cli_error(verb, "cannot find this program (/proc/self/exe)");
    return false;
  }
  out[len] = '\0';
  if (strchr(out, '\'')) {
    km_cli_error(verb, "%s: a quote in the path", out);
    return false;
  }
  return true;
}

cJSON *km_bench_row(const char *spec, const char *machine, size_t n_ver) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "mesh", spec);
  cJSON_AddStringToObject(o, "machine", machine);
  cJSON_AddNumberToObject(o, "n_ver", (double)n_ver);
  return o;
}

void km_bench_row_print(cJSON *row) {
  char *s = row ? cJSON_PrintUnformatted(row) : NULL;
  cJSON_Delete(row);
  if (s) puts(s);
  free(s);
}

km_status km_bench_mesh(const char *spec, km_mesh *m, bool *procedural, km_error *err) {
  if (procedural) *procedural = false;
  if (strncmp(spec, "character:", 10)) return km_mesh_read(spec, m, err);
  km_character_options co = {0};
  co.target_vertices = (size_t)strtoull(spec + 10, NULL, 10);
  km_character c = {0};
  km_status s = km_character_generate(&co, &c, err);
  if (s != KM_OK) return s;
  *m = c.mesh; /* the character's mesh, taken out of it */
  memset(&c.mesh, 0, sizeof c.mesh);
  km_character_free(&c);
  if (procedural) *procedural = true;
  return KM_OK;
}

int km_bench(int argc, char **argv) {
  if (argc >= 2 && !strcmp(argv[1], "deform")) return km_bench_deform(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "live")) return km_bench_live(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "transfer")) return km_bench_transfer(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "rig")) return km_bench_rig(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "motion")) return km_bench_motion(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "batch")) return km_bench_batch(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "export")) return km_bench_export(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "start")) return km_bench_start(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "reconstruct")) return km_bench_reconstruct(argc - 1, argv + 1);
  FILE *f = (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) ? stdout : stderr;
  fprintf(f, "usage: kinemesh bench deform --mesh MESH [--handles N] [--frames F] [--json]\n"
             "       kinemesh bench live [--mesh MESH [--rig RIG]] [--take TAKE] [--json]\n"
             "       kinemesh bench transfer [--source S --template T [--truth X] [--db DB]]\n"
             "       kinemesh bench reconstruct [--frames 300] [--report R.json] [--plot P.png]\n"
             "       kinemesh bench rig [MESH ...] [--repeat 3] [--json]\n"
             "       kinemesh bench motion [--takes T,..] [--meshes M,..] [--json]\n"
             "       kinemesh bench batch [--jobs 4] [--frames 4] [--json]\n"
             "       kinemesh bench export [ANIM ...] [--mesh REST] [--kinds K,..] [--json]\n"
             "       kinemesh bench start [MESH ...] [--repeat 3] [--frames 30] [--json]\n"
             "(kinemesh bench <what> --help for options)\n");
  return f == stdout ? KM_EXIT_OK : KM_EXIT_USAGE;
}
