/* kinemesh bench batch (issue 17): throughput of `kinemesh batch` on a batch of equal
 * reconstruction jobs (simulated captures) with 1 and 2 ranks (mpirun when the CLI has MPI:
 * rank 0 hands the jobs out and runs jobs too, so 2 ranks are 2 job runners; else two shard
 * processes side by side), the serial parts measured (manifest scan and plan, the MPI launch
 * and teardown, the ranks' idle time between jobs; the per-job start, template read and
 * first-frame alignment, is each job's own work and runs in parallel), a segmented take through the
 * batch's segment jobs and stitch (per-segment and stitch times), CPU seconds beside the wall
 * ones (a shared machine's wall times include waiting), and from those the projected wall time
 * of Dynamic FAUST's size (40,000 frames in 129 sequences) on 8, 64 and 512 ranks, one job per
 * sequence and in segments of 200. Targets: 2 ranks >= 1.8x one rank; segmented overhead at
 * S = 200 <= 15%. */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

static double unix_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int sh(const char *cmd) {
  int st = system(cmd);
  return st == 0 ? 0 : 1;
}

/* Wall seconds of a shell command; NAN when it fails. */
static double timed(const char *cmd) {
  double t0 = km_cli_now();
  return sh(cmd) ? NAN : km_cli_now() - t0;
}

/* Wall seconds of a shell command; *cpu: the CPU seconds (user + system) of every process it
 * ran (jobs are waited by their batch process, ranks by mpirun: all reach RUSAGE_CHILDREN). */
static double timed_cpu(const char *cmd, double *cpu) {
  struct rusage a, b;
  getrusage(RUSAGE_CHILDREN, &a);
  double t = timed(cmd);
  getrusage(RUSAGE_CHILDREN, &b);
  *cpu = (double)(b.ru_utime.tv_sec - a.ru_utime.tv_sec) +
         1e-6 * (double)(b.ru_utime.tv_usec - a.ru_utime.tv_usec) +
         (double)(b.ru_stime.tv_sec - a.ru_stime.tv_sec) +
         1e-6 * (double)(b.ru_stime.tv_usec - a.ru_stime.tv_usec);
  return t;
}

/* Median wall and CPU seconds of the batch report's jobs: segments = false, the jobs that are
 * no segment (plain jobs, a segmented take's stitch); true, the segment jobs ("part_of").
 * *n: how many. */
static void job_times(const char *report, bool segments, double *job_s, double *cpu_s, size_t *n) {
  *job_s = *cpu_s = NAN;
  *n = 0;
  cJSON *r = km_cli_read_json(report);
  if (!r) return;
  const cJSON *jobs = cJSON_GetObjectItemCaseSensitive(r, "jobs");
  int count = cJSON_GetArraySize(jobs);
  double *t = calloc(2 * (size_t)count + 2, sizeof *t), *c = t ? t + count + 1 : NULL;
  for (int i = 0; t && i < count; ++i) {
    const cJSON *e = cJSON_GetArrayItem(jobs, i);
    if ((cJSON_GetObjectItemCaseSensitive(e, "part_of") != NULL) != segments) continue;
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(e, "seconds");
    const cJSON *u = cJSON_GetObjectItemCaseSensitive(e, "cpu_seconds");
    if (!cJSON_IsNumber(s)) continue;
    c[*n] = cJSON_IsNumber(u) ? u->valuedouble : NAN;
    t[(*n)++] = s->valuedouble;
  }
  if (t && *n) *job_s = km_cli_median(t, *n), *cpu_s = km_cli_median(c, *n);
  free(t);
  cJSON_Delete(r);
}

/* How a run spent its wall time, from the batch report's jobs ("rank", "started_unix",
 * "seconds"): *sum, the seconds of all jobs; busy[r], those rank r ran; launch, from the
 * command's start (t0, Unix seconds) to the first job's; tail, from the last job's end to the
 * command's end (t1). Returns false when the report has no ranks (one process, the shards). */
static bool rank_times(const char *report, double t0, double t1, double *sum, double busy[2],
                       double *launch, double *tail) {
  *sum = busy[0] = busy[1] = 0;
  *launch = *tail = NAN;
  cJSON *r = km_cli_read_json(report);
  if (!r) return false;
  const cJSON *e;
  double first = INFINITY, last = -INFINITY;
  bool ranks = false;
  cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(r, "jobs")) {
    const cJSON *rk = cJSON_GetObjectItemCaseSensitive(e, "rank");
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(e, "started_unix");
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(e, "seconds");
    if (!cJSON_IsNumber(st) || !cJSON_IsNumber(s)) continue;
    *sum += s->valuedouble;
    if (st->valuedouble < first) first = st->valuedouble;
    if (st->valuedouble + s->valuedouble > last) last = st->valuedouble + s->valuedouble;
    if (cJSON_IsNumber(rk) && rk->valueint >= 0 && rk->valueint < 2) {
      busy[rk->valueint] += s->valuedouble;
      ranks = true;
    }
  }
  cJSON_Delete(r);
  if (isfinite(first)) *launch = first - t0, *tail = t1 - last;
  return ranks;
}

/* Measured costs, seconds: the manifest scan per job, a job's (or segment's) start (process,
 * template, first-frame alignment) beyond one frame, a frame, the stitch per frame; and the
 * ranks' efficiency (measured with 2). */
typedef struct costs {
  double scan_job, start, frame, stitch_frame, eff;
} costs;

/* Dynamic FAUST's size, 40,000 frames in 129 sequences (~310 frames each), on 8/64/512 ranks:
 * one job per sequence, and every sequence in segments of 200 (+5 overlap) spread over the
 * ranks and stitched; and the overhead of segments of 200 (start + overlap + stitch over the
 * segment's own work). */
typedef struct projection {
  double per_seq[3], segmented[3], seg200, overhead;
  bool bound[3]; /* per sequence: bound by the longest sequence */
} projection;

static const int RANKS[3] = {8, 64, 512};

static void project(const costs *c, projection *p) {
  const double frames = 40000, seqs = 129, S = 200, O = 5, per_seq = frames / seqs;
  const double longest = c->start + c->frame * per_seq;
  const double segs = seqs * ceil(per_seq / S);
  double stitch_frame = isfinite(c->stitch_frame) ? c->stitch_frame : 0;
  p->seg200 = c->start + (S + O) * c->frame;
  p->overhead = (c->start + O * c->frame + S * stitch_frame) / (S * c->frame);
  for (int k = 0; k < 3; ++k) {
    double w = (seqs * c->start + frames * c->frame) / (RANKS[k] * c->eff);
    p->bound[k] = w <= longest;
    p->per_seq[k] = c->scan_job * seqs + (w > longest ? w : longest);
    /* segments: wall = scan (the segment jobs too) + the segments over the ranks (at least
     * one) + the stitches over the ranks (at least one take's) */
    double ws = segs * p->seg200 / (RANKS[k] * c->eff);
    double st = frames * stitch_frame / RANKS[k];
    if (st < per_seq * stitch_frame) st = per_seq * stitch_frame;
    p->segmented[k] = c->scan_job * (seqs + segs) + (ws > p->seg200 ? ws : p->seg200) + st;
  }
}

int km_bench_batch(int argc, char **argv) {
  size_t jobs = 4, frames = 12, vertices = 2000;
  bool json = false;
  const km_cli_opt opts[] = {
      {"jobs", 0, KM_OPT_SIZE, &jobs, "equal reconstruction jobs (default 4)"},
      {"frames", 'f', KM_OPT_SIZE, &frames,
       "frames per job (default 12: a job's own start, its first frame, is not all of it)"},
      {"vertices", 'n', KM_OPT_SIZE, &vertices, "template vertices (default 2000)"},
      {"json", 0, KM_OPT_FLAG, &json, "one JSON object instead of the table"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                       "kinemesh bench batch [--jobs 4] [--frames 12] [--vertices 2000] [--json]",
                       "Throughput of kinemesh batch with 1 and 2 ranks on equal jobs, and the\n"
                       "projected wall time of a Dynamic FAUST-sized archive (40k frames).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (jobs < 2 || frames < 2) return km_cli_error("bench batch", "--jobs and --frames >= 2");
  char self[4096], dir[] = "/tmp/km_bench_batch_XXXXXX", cmd[32768];
  if (!km_bench_self("bench batch", self, sizeof self)) return KM_EXIT_FAIL;
  if (!mkdtemp(dir)) return km_cli_error("bench batch", "cannot create a temporary folder");
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
  /* one take of the same frames in segments of half of it (at least 2 segments), overlap 1:
   * the per-segment cost and the stitch, measured through the batch's segment jobs */
  const size_t seg_s = frames / 2, seg_o = 1;
  snprintf(path, sizeof path, "%s/seg.jsonl", dir);
  m = fopen(path, "wb");
  if (!m) return km_cli_error("bench batch", "%s: cannot write", path);
  fprintf(m,
          "{\"id\": \"take\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
          "\"--clouds\", \"c/frame_*.ply\", \"--segment-frames\", \"%zu\", \"--overlap\", \"%zu\", "
          "\"-o\", \"out/take.pc2\"]}\n",
          seg_s, seg_o);
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
  double cpu_scan, cpu_start, cpu1, cpu2, cpu_seg;
  double scan = timed_cpu(cmd, &cpu_scan);
  snprintf(cmd, sizeof cmd, "cd %s && '%s' batch one.jsonl --force >/dev/null 2>&1", dir, self);
  double start = timed_cpu(cmd, &cpu_start);
  snprintf(cmd, sizeof cmd, "cd %s && '%s' batch m.jsonl --force >/dev/null 2>&1", dir, self);
  double l0[3], sum1, sum2, busy1[2], launch1, tail1;
  getloadavg(l0, 3);
  const double u1 = unix_now();
  double t1 = timed_cpu(cmd, &cpu1);
  snprintf(path, sizeof path, "%s/m.batch/report.json", dir);
  rank_times(path, u1, unix_now(), &sum1, busy1, &launch1, &tail1);
  double job1, jcpu1, job2, jcpu2;
  size_t n1, n2;
  job_times(path, false, &job1, &jcpu1, &n1);
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
  double l1[3];
  getloadavg(l1, 3);
  const double u0 = unix_now();
  double t2 = timed_cpu(cmd, &cpu2);
  job_times(path, false, &job2, &jcpu2, &n2);
  double busy[2], launch, tail;
  const bool ranked = rank_times(path, u0, unix_now(), &sum2, busy, &launch, &tail);
  /* the launch and teardown alone: the same command once every job verifies (no job runs) */
  char *noop = strdup(cmd);
  for (char *f = noop; f && (f = strstr(f, " --force"));)
    memset(f, ' ', strlen(" --force"));
  double cpu_noop, t_noop = noop ? timed_cpu(noop, &cpu_noop) : NAN;
  free(noop);
  /* the segmented take, one process: segment jobs then the stitch */
  snprintf(cmd, sizeof cmd, "cd %s && '%s' batch seg.jsonl --force >/dev/null 2>&1", dir, self);
  double tseg = timed_cpu(cmd, &cpu_seg);
  double seg_job, seg_cpu, stitch, stitch_cpu;
  size_t nseg, nst;
  snprintf(path, sizeof path, "%s/seg.batch/report.json", dir);
  job_times(path, true, &seg_job, &seg_cpu, &nseg);
  job_times(path, false, &stitch, &stitch_cpu, &nst);
  double speedup = t1 / t2;
  /* less each run's cost with nothing to do (one process: the dry run's scan; 2 ranks: the
   * launch and teardown): the jobs' part of the wall time */
  double speedup_jobs = (t1 - scan) / (t2 - t_noop);
  /* job-seconds per wall second: how many jobs ran at once on average. speedup = its ratio x
   * (a job's wall seconds in the 1-rank run / in the 2-rank run); the second factor is the
   * machine (a loaded one stretches the jobs of the run with more processes), the first the
   * batch (2.0 at best) */
  const double par1 = sum1 / t1, par2 = sum2 / t2;
  /* per frame beyond the first: (job - one-frame job) / (frames - 1); wall seconds (this
   * machine as it is) and CPU seconds (what a rank with a core of its own would take) */
  double one_job, one_cpu;
  size_t n_one;
  snprintf(path, sizeof path, "%s/one.batch/report.json", dir);
  job_times(path, false, &one_job, &one_cpu, &n_one);
  costs cw = {.scan_job = scan / (double)jobs,
              .start = start,
              .frame = (job1 - start) / (double)(frames - 1),
              .stitch_frame = stitch / (double)frames,
              .eff = speedup / 2 > 1 ? 1 : speedup / 2};
  if (!(cw.frame > 0)) cw.frame = job1 / (double)frames;
  cw.start = start - cw.frame > 0 ? start - cw.frame : start;
  costs cc = {.scan_job = cpu_scan / (double)jobs,
              .start = one_cpu,
              .frame = (jcpu1 - one_cpu) / (double)(frames - 1),
              .stitch_frame = stitch_cpu / (double)frames,
              .eff = cpu2 > 0 && cpu1 / cpu2 < 1 ? cpu1 / cpu2 : 1};
  if (!(cc.frame > 0)) cc.frame = jcpu1 / (double)frames;
  cc.start = one_cpu - cc.frame > 0 ? one_cpu - cc.frame : one_cpu;
  projection pw, pc;
  project(&cw, &pw);
  project(&cc, &pc);
  char machine[320];
  km_bench_machine(machine, sizeof machine);
  if (json) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "machine", machine);
    cJSON_AddNumberToObject(o, "jobs", (double)jobs);
    cJSON_AddNumberToObject(o, "frames_per_job", (double)frames);
    cJSON_AddNumberToObject(o, "vertices", (double)vertices);
    cJSON_AddStringToObject(o, "two_ranks", how);
    km_cli_json_number(o, "loadavg_1rank", l0[0]);
    km_cli_json_number(o, "loadavg_2ranks", l1[0]);
    km_cli_json_number(o, "scan_s", scan);
    km_cli_json_number(o, "job_start_s", cw.start);
    km_cli_json_number(o, "frame_s", cw.frame);
    km_cli_json_number(o, "job_start_cpu_s", cc.start);
    km_cli_json_number(o, "frame_cpu_s", cc.frame);
    km_cli_json_number(o, "job_median_1rank_s", job1);
    km_cli_json_number(o, "job_median_2ranks_s", job2);
    km_cli_json_number(o, "wall_1rank_s", t1);
    km_cli_json_number(o, "wall_2ranks_s", t2);
    km_cli_json_number(o, "jobs_per_s_1rank", (double)jobs / t1);
    km_cli_json_number(o, "jobs_per_s_2ranks", (double)jobs / t2);
    km_cli_json_number(o, "speedup_2ranks", speedup);
    km_cli_json_number(o, "speedup_2ranks_jobs", speedup_jobs);
    km_cli_json_number(o, "parallelism_1rank", par1);
    km_cli_json_number(o, "parallelism_2ranks", par2);
    km_cli_json_number(o, "noop_2ranks_s", t_noop);
    km_cli_json_number(o, "noop_2ranks_cpu_s", cpu_noop);
    if (ranked) {
      km_cli_json_number(o, "rank0_busy_s", busy[0]);
      km_cli_json_number(o, "rank1_busy_s", busy[1]);
      km_cli_json_number(o, "first_job_after_s", launch);
      km_cli_json_number(o, "after_last_job_s", tail);
    }
    km_cli_json_number(o, "cpu_scan_s", cpu_scan);
    km_cli_json_number(o, "cpu_job_start_s", cpu_start);
    km_cli_json_number(o, "cpu_1rank_s", cpu1);
    km_cli_json_number(o, "cpu_2ranks_s", cpu2);
    km_cli_json_number(o, "job_cpu_median_1rank_s", jcpu1);
    km_cli_json_number(o, "job_cpu_median_2ranks_s", jcpu2);
    km_cli_json_number(o, "segment_frames", (double)seg_s);
    km_cli_json_number(o, "segments", (double)nseg);
    km_cli_json_number(o, "segment_median_s", seg_job);
    km_cli_json_number(o, "segment_cpu_median_s", seg_cpu);
    km_cli_json_number(o, "stitch_s", stitch);
    km_cli_json_number(o, "stitch_cpu_s", stitch_cpu);
    km_cli_json_number(o, "segmented_wall_s", tseg);
    km_cli_json_number(o, "segmented_cpu_s", cpu_seg);
    const projection *pp[2] = {&pw, &pc};
    for (int q = 0; q < 2; ++q) {
      cJSON *pj = cJSON_AddObjectToObject(o, q ? "projection_cpu" : "projection_wall");
      km_cli_json_number(pj, "rank_efficiency", q ? cc.eff : cw.eff);
      km_cli_json_number(pj, "segment200_s", pp[q]->seg200);
      km_cli_json_number(pj, "segment200_overhead", pp[q]->overhead);
      cJSON *a1 = cJSON_AddObjectToObject(pj, "dfaust_per_sequence_s");
      cJSON *a2 = cJSON_AddObjectToObject(pj, "dfaust_segmented200_s");
      for (int k = 0; k < 3; ++k) {
        char key[16];
        snprintf(key, sizeof key, "%d", RANKS[k]);
        km_cli_json_number(a1, key, pp[q]->per_seq[k]);
        km_cli_json_number(a2, key, pp[q]->segmented[k]);
      }
    }
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (s) puts(s);
    free(s);
  } else {
    printf("kinemesh bench batch — %s\n", machine);
    printf("%zu equal jobs: reconstruct %zu frames, %zu-vertex template, OMP_NUM_THREADS=1\n\n",
           jobs, frames, vertices);
    printf("(the machine may be shared: CPU seconds are the work done, wall seconds include "
           "waiting for a core)\n\n");
    printf("%-34s %10s %10s %10s %10s %10s\n", "ranks", "wall s", "CPU s", "jobs/s", "job s",
           "job CPU s");
    printf("%-34s %10.2f %10.2f %10.3f %10.2f %10.2f\n", "1 (one process)", t1, cpu1,
           (double)jobs / t1, job1, jcpu1);
    printf("%-34s %10.2f %10.2f %10.3f %10.2f %10.2f\n", how, t2, cpu2, (double)jobs / t2, job2,
           jcpu2);
    printf("\nspeedup 2 ranks / 1: %.2fx wall (target >= 1.8x); CPU 2 ranks / 1: %.2fx (1.0 = no "
           "extra work)\n",
           speedup, cpu2 / cpu1);
    printf("2 ranks = %s%s\n", how,
           ranked ? " (rank 0 hands the jobs out and runs jobs too: 2 job runners)" : "");
    printf("the same with nothing to run: %.2f s wall (CPU %.2f s); speedup of the rest (each run "
           "less its nothing-to-run cost): %.2fx\n",
           t_noop, cpu_noop, speedup_jobs);
    printf("jobs at once (job-seconds per wall second): 1 rank %.2f, 2 ranks %.2f (at best 2): the "
           "batch's part of the speedup %.2fx; a job's wall time 1 rank / 2 ranks %.2f (the "
           "machine's part: 1.0 on idle cores)\n",
           par1, par2, par2 / par1, job1 / job2);
    if (ranked)
      printf("2 ranks' wall %.2f s: rank 0 ran jobs %.2f s (%.0f%%), rank 1 %.2f s (%.0f%%); first "
             "job %.2f s after the start, the end %.2f s after the last job\n",
             t2, busy[0], 100 * busy[0] / t2, busy[1], 100 * busy[1] / t2, launch, tail);
    printf("load average (1 min) before the 1-rank run %.2f, before the 2-rank run %.2f, on %ld "
           "cores: above 0 the ranks share the cores with others and wall speedups shrink\n",
           l0[0], l1[0], sysconf(_SC_NPROCESSORS_ONLN));
    printf("serial parts: manifest scan + plan %.3f s (CPU %.3f s, %zu jobs); job start "
           "(process, template, first frame) %.2f s (CPU %.2f s); per frame %.2f s (CPU %.2f s)\n",
           scan, cpu_scan, jobs, cw.start, cc.start, cw.frame, cc.frame);
    printf("segmented take (%zu frames, S = %zu, overlap %zu, one process): %zu segments, median "
           "%.2f s (CPU %.2f s) each; stitch %.2f s (CPU %.2f s); all %.2f s (CPU %.2f s)\n",
           frames, seg_s, seg_o, nseg, seg_job, seg_cpu, stitch, stitch_cpu, tseg, cpu_seg);
    printf("segment of S = 200 (+5 overlap, own first frame): %.0f s (CPU %.0f s); overhead "
           "(start + overlap + stitch) %.1f%% of its work (CPU %.1f%%; target <= 15%%)\n",
           pw.seg200, pc.seg200, 100 * pw.overhead, 100 * pc.overhead);
    printf("\nprojected: Dynamic FAUST size (40,000 frames, 129 sequences); wall: this machine's "
           "wall costs and 2-rank efficiency (%.0f%%); CPU: a core per rank, efficiency from the "
           "CPU seconds (%.0f%%)\n",
           100 * cw.eff, 100 * cc.eff);
    printf("%8s %22s %22s %22s %22s\n", "ranks", "per sequence (wall)", "segments 200 (wall)",
           "per sequence (CPU)", "segments 200 (CPU)");
    for (int k = 0; k < 3; ++k)
      printf("%8d %12.0f s %5.2f h%s %12.0f s %5.2f h %12.0f s %5.2f h%s %12.0f s %5.2f h\n",
             RANKS[k], pw.per_seq[k], pw.per_seq[k] / 3600, pw.bound[k] ? "*" : " ",
             pw.segmented[k], pw.segmented[k] / 3600, pc.per_seq[k], pc.per_seq[k] / 3600,
             pc.bound[k] ? "*" : " ", pc.segmented[k], pc.segmented[k] / 3600);
    printf("(* bound by the longest sequence: more ranks than sequences help only in segments)\n");
  }
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  sh(cmd);
  return isfinite(t1) && isfinite(t2) ? KM_EXIT_OK : KM_EXIT_FAIL;
}
