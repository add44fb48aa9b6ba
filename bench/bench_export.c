/* kinemesh bench export (issue 16): what each glTF export kind costs and loses on a mesh
 * animation: file size, RMS / max error against the exact frames (mm and % of the rest
 * diagonal), and the time to write it (the skinning fit for skin). Targets on the demo
 * (20k vertices, 150 frames): skin <= 2 MB at RMS <= 2 mm, max <= 15 mm, in <= 20 s; compressed
 * (KIND+c: KHR_mesh_quantization + EXT_meshopt_compression) skin <= 0.6 MB, morphs:K <= 3 MB at
 * RMS <= 1 mm. With --take, the animation is first made the way a user makes it: the mesh rigged by
 * `kinemesh rig` and animated by `kinemesh animate` (puppetry) from the take, both run as child
 * processes of this program (like bench batch), the frames written as .pc2 in a temporary
 * folder; e.g. the armadillo row of the README: --mesh ../shared/data/meshes/armadillo.obj
 * --take ../shared/data/skeleton/precog_Seq2_1.csv. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* label: the name printed for the animation (NULL: the file name of path). */
static int bench_one(const char *path, const char *label, const char *mesh_path,
                     const char *const *kinds, size_t n_kinds, size_t repeat, bool json,
                     bool header) {
  km_error err = {0};
  km_mesh rest = {0}, given = {0};
  double *frames = NULL, *t = calloc(repeat, sizeof *t);
  km_anim_info info;
  int rc = KM_EXIT_FAIL;
  char tmp[64];
  snprintf(tmp, sizeof tmp, "/tmp/km_bench_export_%ld.glb", (long)getpid());
  if (!t) return km_cli_error("bench export", "out of memory");
  if (km_anim_read(path, &rest, &frames, &info, &err) != KM_OK ||
      (mesh_path && km_mesh_read(mesh_path, &given, &err) != KM_OK)) {
    rc = km_cli_fail("bench export", &err);
    goto done;
  }
  if (mesh_path && given.n_vertices != rest.n_vertices) {
    rc = km_cli_error("bench export", "%s has %zu vertices, %s %zu", mesh_path, given.n_vertices,
                      path, rest.n_vertices);
    goto done;
  }
  const km_mesh *m = mesh_path ? &given : &rest;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < m->n_vertices; ++i)
    for (int a = 0; a < 3; ++a)
      lo[a] = fmin(lo[a], m->V[3 * i + a]), hi[a] = fmax(hi[a], m->V[3 * i + a]);
  double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                     (hi[2] - lo[2]) * (hi[2] - lo[2]));
  char machine[320];
  km_bench_machine(machine, sizeof machine);
  if (header && !json) {
    printf("kinemesh bench export — %s; medians of %zu runs; error against the exact frames; "
           "time = writing the file (the SSDR fit for skin)\n",
           machine, repeat);
    printf("%-26s %7s %6s %-12s %6s %10s %9s %9s %8s %8s %8s\n", "animation", "n_ver", "frames",
           "export", "bones", "size(MB)", "rms(mm)", "max(mm)", "rms(%d)", "max(%d)", "time(s)");
  }
  for (size_t k = 0; k < n_kinds; ++k) {
    km_anim_report rep = {0};
    /* KIND+c: the same kind with --compress */
    char kind[64];
    snprintf(kind, sizeof kind, "%s", kinds[k]);
    size_t kl = strlen(kind);
    bool z = kl > 2 && !strcmp(kind + kl - 2, "+c");
    if (z) kind[kl - 2] = '\0';
    for (size_t r = 0; r < repeat; ++r) {
      km_anim_options ao = {.fps = info.fps > 0 ? info.fps : 30};
      km_ssdr_options so;
      if (km_cli_parse_export("bench export", kind, 0, z, tmp, &ao, &so)) goto done;
      so.progress = (km_progress){0};
      km_anim_writer *w = NULL;
      double t0 = km_cli_now();
      km_status s = km_anim_writer_open(tmp, m, &ao, &w, &err);
      for (size_t f = 0; s == KM_OK && f < info.frames; ++f)
        s = km_anim_writer_push(w, frames + f * m->n_vertices * 3, &err);
      if (s == KM_OK) s = km_anim_writer_finish(&w, &rep, &err);
      km_anim_writer_free(&w);
      if (s != KM_OK) {
        rc = km_cli_fail("bench export", &err);
        goto done;
      }
      t[r] = km_cli_now() - t0;
    }
    double mt = km_cli_median(t, repeat);
    struct stat st;
    double mb = stat(tmp, &st) == 0 ? (double)st.st_size / 1e6 : NAN;
    remove(tmp);
    const char *base = strrchr(path, '/');
    base = label ? label : base ? base + 1 : path;
    if (json) {
      cJSON *o = cJSON_CreateObject();
      cJSON_AddStringToObject(o, "animation", label ? label : path);
      cJSON_AddStringToObject(o, "machine", machine);
      cJSON_AddNumberToObject(o, "n_ver", (double)m->n_vertices);
      cJSON_AddNumberToObject(o, "frames", (double)info.frames);
      cJSON_AddStringToObject(o, "export", kinds[k]);
      cJSON_AddNumberToObject(o, "bones", (double)rep.bones);
      km_cli_json_number(o, "size_mb", mb);
      cJSON_AddNumberToObject(o, "rms_mm", rep.rms_error * 1e3);
      cJSON_AddNumberToObject(o, "max_mm", rep.max_error * 1e3);
      km_cli_json_number(o, "rms_pct_diag", 100 * rep.rms_error / diag);
      km_cli_json_number(o, "max_pct_diag", 100 * rep.max_error / diag);
      cJSON_AddNumberToObject(o, "repeat", (double)repeat);
      cJSON_AddNumberToObject(o, "time_s", mt);
      char *s = cJSON_PrintUnformatted(o);
      cJSON_Delete(o);
      if (s) puts(s);
      free(s);
    } else {
      printf("%-26.26s %7zu %6zu %-12s %6zu %10.2f %9.3f %9.3f %8.4f %8.4f %8.2f\n", base,
             m->n_vertices, info.frames, kinds[k], rep.bones, mb, rep.rms_error * 1e3,
             rep.max_error * 1e3, 100 * rep.rms_error / diag, 100 * rep.max_error / diag, mt);
    }
    fflush(stdout);
  }
  rc = KM_EXIT_OK;
done:
  remove(tmp);
  free(t);
  free(frames);
  km_mesh_free(&rest);
  km_mesh_free(&given);
  return rc;
}

/* Stem of a path: "a/b/armadillo.obj" -> "armadillo". */
static void stem(const char *path, char *out, size_t cap) {
  const char *b = strrchr(path, '/');
  snprintf(out, cap, "%s", b ? b + 1 : path);
  char *dot = strrchr(out, '.');
  if (dot && dot != out) *dot = '\0';
}

/* The puppetry run of mesh_path driven by take (rigged by `kinemesh rig` unless rig is given)
 * written to dir/anim.pc2 by this program's own verbs. Returns 0, or prints why and returns an
 * exit status. */
static int make_take_animation(const char *mesh_path, const char *rig, const char *take,
                               const char *dir) {
  char self[4096], cmd[16384], rig_path[4200];
  if (!km_bench_self("bench export", self, sizeof self)) return KM_EXIT_FAIL;
  for (const char *p = mesh_path; *p; ++p)
    if (*p == '\'') return km_cli_error("bench export", "%s: a quote in the path", mesh_path);
  for (const char *p = take; *p; ++p)
    if (*p == '\'') return km_cli_error("bench export", "%s: a quote in the path", take);
  snprintf(rig_path, sizeof rig_path, "%s/rig.json", dir);
  if (!rig) {
    snprintf(cmd, sizeof cmd, "'%s' rig '%s' -o '%s' >/dev/null 2>&1", self, mesh_path, rig_path);
    if (system(cmd) != 0)
      return km_cli_error("bench export", "kinemesh rig %s failed (run it to see why)", mesh_path);
  } else if (strchr(rig, '\'')) {
    return km_cli_error("bench export", "%s: a quote in the path", rig);
  }
  /* the reduced model's cache stays in the temporary folder, not the user's cache */
  snprintf(cmd, sizeof cmd,
           "'%s' animate --mesh '%s' --rig '%s' --motion '%s' --cache '%s/model.kmcache' "
           "-o '%s/anim.pc2' >/dev/null 2>&1",
           self, mesh_path, rig ? rig : rig_path, take, dir, dir);
  if (system(cmd) != 0)
    return km_cli_error("bench export",
                        "kinemesh animate --mesh %s --motion %s failed (run it "
                        "to see why)",
                        mesh_path, take);
  return KM_EXIT_OK;
}

int km_bench_export(int argc, char **argv) {
  size_t repeat = 1;
  bool json = false;
  const char *mesh_path = NULL, *kinds_s = NULL, *take = NULL, *rig = NULL;
  const km_cli_opt opts[] = {
      {"mesh", 0, KM_OPT_STRING, &mesh_path,
       "rest mesh for every ANIM (a .pc2 has no faces); same vertex count and order"},
      {"take", 0, KM_OPT_STRING, &take,
       "instead of ANIM: animate --mesh from this take (.csv Kinect, .bvh, .json) first, "
       "rigged by `kinemesh rig` (puppetry, as `kinemesh animate` does)"},
      {"rig", 0, KM_OPT_STRING, &rig, "with --take: this rig instead of `kinemesh rig`'s"},
      {"kinds", 0, KM_OPT_STRING, &kinds_s,
       "export kinds, comma-separated; KIND+c: with --compress (default "
       "morphs:all,skin:32,skin,skin+c,morphs:48+c)"},
      {"repeat", 0, KM_OPT_SIZE, &repeat, "runs per kind (default 1; the median is printed)"},
      {"json", 0, KM_OPT_FLAG, &json, "print one JSON object per row, one per line"},
  };
  enum { MAX_ANIMS = 16, MAX_KINDS = 8 };
  const char *pos[MAX_ANIMS];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, MAX_ANIMS, &n_pos,
                       "kinemesh bench export [ANIM ...] [--mesh REST] [--kinds K,..] "
                       "[--repeat 1] [--json]\n"
                       "       kinemesh bench export --mesh MESH --take TAKE [--rig RIG] ...",
                       "Size, error and time of each glTF export kind of a mesh animation\n"
                       "(.glb, .pc2 or a frame directory), or of the puppetry run of MESH from\n"
                       "TAKE. Default ANIM: out/demo.glb from scripts/demo.sh (skipped with a\n"
                       "message when absent).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (repeat < 1) return km_cli_error("bench export", "--repeat must be at least 1");
  char kbuf[256];
  snprintf(kbuf, sizeof kbuf, "%s",
           kinds_s ? kinds_s : "morphs:all,skin:32,skin,skin+c,morphs:48+c");
  const char *kinds[MAX_KINDS];
  size_t nk = 0;
  for (char *tok = strtok(kbuf, ","); tok && nk < MAX_KINDS; tok = strtok(NULL, ","))
    kinds[nk++] = tok;
  if (take) {
    if (!mesh_path)
      return km_cli_error("bench export", "--take needs --mesh (the mesh to animate)");
    if (n_pos) return km_cli_error("bench export", "--take replaces ANIM: name one or the other");
    char dir[] = "/tmp/km_bench_export_XXXXXX", anim[64], label[128], ms[64], ts[64];
    if (!mkdtemp(dir)) return km_cli_error("bench export", "cannot create a temporary folder");
    snprintf(anim, sizeof anim, "%s/anim.pc2", dir);
    stem(mesh_path, ms, sizeof ms);
    stem(take, ts, sizeof ts);
    snprintf(label, sizeof label, "%s:%s", ms, ts);
    int rc = make_take_animation(mesh_path, rig, take, dir);
    if (rc == KM_EXIT_OK) rc = bench_one(anim, label, mesh_path, kinds, nk, repeat, json, true);
    const char *const tmp_files[] = {"anim.pc2", "rig.json", "model.kmcache"};
    for (size_t i = 0; i < sizeof tmp_files / sizeof tmp_files[0]; ++i) {
      char f[128];
      snprintf(f, sizeof f, "%s/%s", dir, tmp_files[i]);
      remove(f);
    }
    rmdir(dir);
    return rc;
  }
  if (!n_pos) {
    struct stat st;
    if (stat("out/demo.glb", &st) != 0) {
      fprintf(stderr, "kinemesh bench export: out/demo.glb not found: run scripts/demo.sh first "
                      "or name an animation\n");
      return KM_EXIT_OK;
    }
    pos[n_pos++] = "out/demo.glb";
  }
  int rc = KM_EXIT_OK;
  for (int i = 0; i < n_pos; ++i) {
    int ri = bench_one(pos[i], NULL, mesh_path, kinds, nk, repeat, json, i == 0);
    if (ri != KM_EXIT_OK) rc = ri;
  }
  return rc;
}
