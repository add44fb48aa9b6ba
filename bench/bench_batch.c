/* kinemesh bench batch (issue 17): throughput of `kinemesh batch` on a batch of equal
 * reconstruction jobs (simulated captures) with 1 and 2 ranks (mpirun when the CLI has MPI,
 * else two shard processes side by side), the serial parts measured (manifest scan and plan,
 * the per-job start: template read and first-frame alignment), and from those the projected
 * wall time of Dynamic FAUST's size (40,000 frames in 129 sequences) on 8, 64 and 512 ranks.
 * Target: 2 ranks >= 1.8x one rank. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int sh(const char *cmd) {
  int st = system(cmd);
  return st == 0 ? 0 : 1;
}

/* Wall seconds of a shell command; NAN when it fails. */
static double timed(const char *cmd) {
  double t0 = km_cli_now();
  return sh(cmd) ? NAN : km_cli_now() - t0;
}

/* Median per-job seconds of the batch report, over the *n jobs it timed. */
static void job_times(const char *report, double *job_s, size_t *n) {
  FILE *f = fopen(report, "rb");
  *job_s = NAN;
  *n = 0;
  if (!f) return;
  char buf[1 << 16];
  size_t got = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[got] = '\0';
  cJSON *r = cJSON_Parse(buf);
  const cJSON *jobs = cJSON_GetObjectItemCaseSensitive(r, "jobs");
  int count = cJSON_GetArraySize(jobs);
  double *t = calloc((size_t)count + 1, sizeof *t);
  for (int i = 0; t && i < count; ++i) {
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(jobs, i), "seconds");
    if (cJSON_IsNumber(s)) t[(*n)++] = s->valuedouble;
  }
  if (t && *n) *job_s = km_cli_median(t, *n);
  free(t);
  cJSON_Delete(r);
}

int km_bench_batch(int argc, char **argv) {
  size_t jobs = 4, frames = 4, vertices = 2000;
  bool json = false;
  const km_cli_opt opts[] = {
      {"jobs", 0, KM_OPT_SIZE, &jobs, "equal reconstruction jobs (default 4)"},
      {"frames", 'f', KM_OPT_SIZE, &frames, "frames per job (default 4)"},
      {"vertices", 'n', KM_OPT_SIZE, &vertices, "template vertices (default 2000)"},
      {"json", 0, KM_OPT_FLAG, &json, "one JSON object instead of the table"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                       "kinemesh bench batch [--jobs 4] [--frames 4] [--vertices 2000] [--json]",
                       "Throughput of kinemesh batch with 1 and 2 ranks on equal jobs, and the\n"
                       "projected wall time of a Dynamic FAUST-sized archive (40k frames).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (jobs < 2 || frames < 2) return km_cli_error("bench batch", "--jobs and --frames >= 2");
  char self[4096], dir[] = "/tmp/km_bench_batch_XXXXXX", cmd[32768];
  ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
  if (len <= 0 || !mkdtemp(dir)) return km_cli_error("bench batch", "cannot set up");
  self[len] = '\0';
  setenv("OMP_NUM_THREADS", "1", 1); /* ranks x threads = cores */
  setenv("XDG_CACHE_HOME", dir, 1);
  snprintf(cmd, sizeof cmd,
           "cd %s && '%s' gen character --vertices %zu -o t.obj >/dev/null 2>&1 && "
           "'%s' gen motion --kind walk --frames %zu --character t.obj -o take.json "
           ">/dev/null 2>&1 && '%s' gen capture --character t.obj --motion take.json --cameras 4 "
           "--points 4000 -o c >/dev/null 2>&1 && '%s' gen motion --kind walk --frames 1 "
           "--character t.obj -o take1.json >/dev/null 2>&1 && '%s' gen capture --character "
           "t.obj --motion take1.json --cameras 4 --points 4000 -o c1 >/dev/null 2>&1",
           dir, self, vertices, self, frames, self, self, self);
  if (sh(cmd)) return km_cli_error("bench batch", "gen capture failed (in %s)", dir);
  char path[4200];
  snprintf(path, sizeof path, "%s/m.jsonl", dir);
  FILE *m = fopen(path, "wb");
  if (!m) return km_cli_error("bench batch", "%s: cannot write", path);
  for (size_t j = 0; j < jobs; ++j)
    fprintf(m,
            "{\"id\": \"j%zu\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
            "\"--clouds\", \"c/frame_*.ply\", \"-o\", \"out/j%zu.pc2\"]}\n",
            j, j);
  fclose(m);
  snprintf(path, sizeof path, "%s/one.jsonl", dir);
  m = fopen(path, "wb");
  if (!m) return km_cli_error("bench batch", "%s: cannot write", path);
  fprintf(m, "{\"id\": \"one\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
             "\"--clouds\", \"c1/frame_*.ply\", \"-o\", \"out/one.pc2\"]}\n");
  fclose(m);

  /* serial parts: the manifest scan and plan (a dry run), a one-frame job (process start,
   * template, first-frame alignment: what every job and every segment pays once) */
  snprintf(cmd, sizeof cmd, "cd %s && mkdir -p out && '%s' batch m.jsonl --dry-run >/dev/null 2>&1",
           dir, self);
  double scan = timed(cmd);
  snprintf(cmd, sizeof cmd, "cd %s && '%s' batch one.jsonl --force >/dev/null 2>&1", dir, self);
  double start = timed(cmd);
  snprintf(cmd, sizeof cmd, "cd %s && '%s' batch m.jsonl --force >/dev/null 2>&1", dir, self);
  double t1 = timed(cmd);
  double job1;
  size_t n1;
  snprintf(path, sizeof path, "%s/m.batch/report.json", dir);
  job_times(path, &job1, &n1);
#ifdef KM_HAVE_MPI
  const char *how = "mpirun -n 2 ... --mpi";
  snprintf(cmd, sizeof cmd,
           "cd %s && OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 "
           "--oversubscribe '%s' batch m.jsonl --mpi --force >/dev/null 2>&1",
           dir, self);
#else
  const char *how = "2 processes, --shard 0/2 and 1/2";
  snprintf(cmd, sizeof cmd,
           "cd %s && ('%s' batch m.jsonl --shard 0/2 --force >/dev/null 2>&1 & '%s' batch m.jsonl "
           "--shard 1/2 --force >/dev/null 2>&1; wait)",
           dir, self, self);
#endif
  double t2 = timed(cmd);
  double job2;
  size_t n2;
  job_times(path, &job2, &n2);
  double speedup = t1 / t2;
  /* per frame beyond the first: (job - one-frame job) / (frames - 1) */
  double per_frame = (job1 - start) / (double)(frames - 1);
  if (!(per_frame > 0)) per_frame = job1 / (double)frames;
  double per_start = start - per_frame > 0 ? start - per_frame : start;
  /* Dynamic FAUST's size: 40,000 frames in 129 sequences (~310 frames each), one job each; the
   * ranks' efficiency is the measured 2-rank one, the scan scaled from the manifest here */
  const double dfaust_frames = 40000, dfaust_seqs = 129;
  const int ranks[3] = {8, 64, 512};
  double proj[3];
  double eff = speedup / 2 > 1 ? 1 : speedup / 2;
  double scan_d = scan / (double)jobs * dfaust_seqs;
  double longest = per_start + per_frame * dfaust_frames / dfaust_seqs;
  for (int k = 0; k < 3; ++k) {
    double work = dfaust_seqs * per_start + dfaust_frames * per_frame;
    double w = work / (ranks[k] * eff);
    proj[k] = scan_d + (w > longest ? w : longest);
  }
  /* reconstruct --segment-frames 200 --overlap 5: a segment pays its own start (first-frame
   * alignment) and tracks 5 frames into the next */
  double seg200 = per_start + 205 * per_frame;
  double seg_over = (per_start + 5 * per_frame) / (200 * per_frame);
  char machine[320];
  km_bench_machine(machine, sizeof machine);
  if (json) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "machine", machine);
    cJSON_AddNumberToObject(o, "jobs", (double)jobs);
    cJSON_AddNumberToObject(o, "frames_per_job", (double)frames);
    cJSON_AddNumberToObject(o, "vertices", (double)vertices);
    cJSON_AddStringToObject(o, "two_ranks", how);
    km_cli_json_number(o, "scan_s", scan);
    km_cli_json_number(o, "job_start_s", per_start);
    km_cli_json_number(o, "frame_s", per_frame);
    km_cli_json_number(o, "job_median_1rank_s", job1);
    km_cli_json_number(o, "job_median_2ranks_s", job2);
    km_cli_json_number(o, "wall_1rank_s", t1);
    km_cli_json_number(o, "wall_2ranks_s", t2);
    km_cli_json_number(o, "jobs_per_s_1rank", (double)jobs / t1);
    km_cli_json_number(o, "jobs_per_s_2ranks", (double)jobs / t2);
    km_cli_json_number(o, "speedup_2ranks", speedup);
    km_cli_json_number(o, "segment200_s", seg200);
    km_cli_json_number(o, "segment200_overhead", seg_over);
    cJSON *p = cJSON_AddObjectToObject(o, "dfaust_projection_s");
    for (int k = 0; k < 3; ++k) {
      char key[16];
      snprintf(key, sizeof key, "%d", ranks[k]);
      km_cli_json_number(p, key, proj[k]);
    }
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (s) puts(s);
    free(s);
  } else {
    printf("kinemesh bench batch — %s\n", machine);
    printf("%zu equal jobs: reconstruct %zu frames, %zu-vertex template, OMP_NUM_THREADS=1\n\n",
           jobs, frames, vertices);
    printf("%-34s %10s %10s %10s\n", "ranks", "wall s", "jobs/s", "job s");
    printf("%-34s %10.2f %10.3f %10.2f\n", "1 (one process)", t1, (double)jobs / t1, job1);
    printf("%-34s %10.2f %10.3f %10.2f\n", how, t2, (double)jobs / t2, job2);
    printf("\nspeedup 2 ranks / 1: %.2fx (target >= 1.8x)\n", speedup);
    printf("serial parts: manifest scan + plan %.3f s (%zu jobs), job start (process, template, "
           "first frame) %.2f s, per frame %.2f s\n",
           scan, jobs, per_start, per_frame);
    printf("segment of S = 200 (+5 overlap, own first frame): %.0f s; overhead (start + overlap) "
           "%.1f%% of its work (target <= 15%%; from the measured start and per-frame costs)\n",
           seg200, 100 * seg_over);
    printf("\nprojected: Dynamic FAUST size (40,000 frames, 129 sequences), one job per "
           "sequence, 2-rank efficiency %.0f%%\n",
           100 * eff);
    for (int k = 0; k < 3; ++k)
      printf("  %4d ranks: %10.0f s (%.1f h)%s\n", ranks[k], proj[k], proj[k] / 3600,
             proj[k] <= scan_d + longest + 1e-9 ? "  (bound by the longest sequence)" : "");
  }
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  sh(cmd);
  return isfinite(t1) && isfinite(t2) ? KM_EXIT_OK : KM_EXIT_FAIL;
}
