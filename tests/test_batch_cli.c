/* kinemesh batch (issue 17): a manifest of six small simulated captures. Shards cover every job
 * once (also through the Slurm and Kubernetes variables); bad manifests are refused naming the
 * line; a failing job is reported and the others still run; the batch (under mpirun -n 3 when
 * built with MPI) gives the same bytes as each job's command run alone, and a rerun then has
 * nothing to do; a worker rank killed mid-job loses only that job, which another rank runs
 * again (attempt 2), and a job whose second rank is killed too is reported failed, the rest
 * completes and a rerun runs that job alone; a segmented reconstruction spread over the ranks
 * (segment jobs, then the stitch) gives the bytes of `reconstruct --segment-frames` alone. */
#include "capture_fixture.h"

#include <unistd.h>

#define DIR "batch_cli"
#define NJ 6
#if defined(__SANITIZE_ADDRESS__)
#define LONG "3" /* a Debug build under the sanitizers: ~10 s a frame */
#define SEGN "6"
#define SEGS "2"
#else
#define LONG "5"
#define SEGN "9"
#define SEGS "3"
#endif

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  if (f) {
    fputs(text, f);
    fclose(f);
  }
}

/* Counts the job ids in a dry run's JSON lines into seen[0..NJ) (ids s1..s6). Returns the
 * number of lines, -1 on a line that is not a job. */
static int count_ids(const char *out, int *seen) {
  int n = 0;
  for (const char *l = out; l && *l;) {
    const char *e = strchr(l, '\n');
    if (*l == '{') {
      char buf[4096];
      size_t len = e ? (size_t)(e - l) : strlen(l);
      if (len >= sizeof buf) return -1;
      memcpy(buf, l, len);
      buf[len] = '\0';
      cJSON *o = cJSON_Parse(buf);
      const cJSON *id = cJSON_GetObjectItemCaseSensitive(o, "id");
      int k = cJSON_IsString(id) && id->valuestring[0] == 's' ? atoi(id->valuestring + 1) : 0;
      cJSON_Delete(o);
      if (k < 1 || k > NJ) return -1;
      ++seen[k - 1];
      ++n;
    }
    l = e ? e + 1 : NULL;
  }
  return n;
}

/* Statuses in the batch report: counts of ok and failed. */
static void report_counts(const char *path, int *ok, int *failed) {
  cJSON *r = km_test_read_json(path);
  const cJSON *c = cJSON_GetObjectItemCaseSensitive(r, "counts");
  const cJSON *o = cJSON_GetObjectItemCaseSensitive(c, "ok");
  const cJSON *f = cJSON_GetObjectItemCaseSensitive(c, "failed");
  *ok = cJSON_IsNumber(o) ? o->valueint : -1;
  *failed = cJSON_IsNumber(f) ? f->valueint : -1;
  cJSON_Delete(r);
}

static bool same_bytes(const char *a, const char *b) {
  char cmd[1024];
  snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", a, b);
  return km_test_run(cmd, NULL) == 0;
}

int main(void) {
  char *out = NULL, cmd[4096];
  /* every run here with one thread per job: the runs compared must not oversubscribe */
  (void)km_test_err;
  setenv("OMP_NUM_THREADS", "1", 1);
  unsetenv("SLURM_ARRAY_TASK_ID");
  unsetenv("JOB_COMPLETION_INDEX");
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR "/out", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o " DIR "/t.obj", NULL) == 0);
  const char *kinds[3] = {"walk", "wave", "kungfu"};
  FILE *m = fopen(DIR "/m.jsonl", "wb");
  CHECK(m != NULL);
  if (!m) return km_test_finish("test_batch_cli");
  fprintf(m, "# six small simulated captures\n\n");
  for (int i = 1; i <= NJ; ++i) {
    int frames = i == NJ ? atoi(LONG) : 2; /* one longer job, the first handed out */
    char take[64], seed[32], clouds[64];
    snprintf(take, sizeof take, DIR "/take%d.json", i);
    snprintf(seed, sizeof seed, "--seed %d", i);
    snprintf(clouds, sizeof clouds, DIR "/c%d", i);
    CHECK(km_test_capture(DIR "/t.obj", kinds[i % 3], frames, take, 4, 3000, seed, clouds, NULL) ==
          0);
    /* paths relative to the manifest's folder */
    fprintf(m,
            "{\"id\": \"s%d\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
            "\"--clouds\", \"c%d/frame_*.ply\", \"-o\", \"out/s%d.pc2\", \"--report\", "
            "\"out/s%d.json\"]}\n",
            i, i, i, i);
  }
  fclose(m);

  /* ---- dry run: every job, longest first, with its command line */
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run 2>/dev/null", &out) == 0);
  int seen[NJ] = {0};
  CHECK_MSG(count_ids(out, seen) == NJ, "%s", out ? out : "");
  CHECK_MSG(out && strchr(out, '{') && !strncmp(strchr(out, '{'), "{\"id\":\"s6\"", 10),
            "longest first: %s", out ? out : "");
  CHECK(out && strstr(out, "\"frames\":" LONG) &&
        strstr(out, "kinemesh reconstruct --template t.obj"));
  free(out);
  CHECK(km_test_run("test ! -e " DIR "/m.batch/report.json", NULL) == 0);

  /* ---- shards: for every N, the shards together hold every job once */
  for (int n = 1; n <= 4; ++n) {
    int s[NJ] = {0}, total = 0;
    for (int i = 0; i < n; ++i) {
      snprintf(cmd, sizeof cmd, KM_CLI " batch " DIR "/m.jsonl --dry-run --shard %d/%d 2>/dev/null",
               i, n);
      CHECK(km_test_run(cmd, &out) == 0);
      total += count_ids(out, s);
      free(out);
    }
    CHECK_MSG(total == NJ, "N=%d: %d jobs", n, total);
    for (int k = 0; k < NJ; ++k)
      CHECK_MSG(s[k] == 1, "N=%d: job s%d in %d shards", n, k + 1, s[k]);
  }
  /* the scheduler's variables are the same shards (Slurm arrays may start at 1) */
  char *a = NULL, *b = NULL;
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run --shard 1/3 2>/dev/null", &a) == 0);
  CHECK(km_test_run("SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_COUNT=3 " KM_CLI " batch " DIR
                    "/m.jsonl --dry-run 2>/dev/null",
                    &b) == 0);
  CHECK(a && b && !strcmp(a, b) && strstr(a, "\"s2\"") && strstr(a, "\"s5\""));
  free(b);
  CHECK(km_test_run("SLURM_ARRAY_TASK_ID=2 SLURM_ARRAY_TASK_MIN=1 SLURM_ARRAY_TASK_COUNT=3 " KM_CLI
                    " batch " DIR "/m.jsonl --dry-run 2>/dev/null",
                    &b) == 0);
  CHECK(a && b && !strcmp(a, b));
  free(b);
  CHECK(km_test_run("JOB_COMPLETION_INDEX=1 KM_SHARD_COUNT=3 " KM_CLI " batch " DIR
                    "/m.jsonl --dry-run 2>/dev/null",
                    &b) == 0);
  CHECK(a && b && !strcmp(a, b));
  free(a), free(b);
  CHECK(km_test_run("SLURM_ARRAY_TASK_ID=1 " KM_CLI " batch " DIR "/m.jsonl --dry-run", NULL) != 0);
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run --shard 3/3", &out) != 0);
  CHECK(out && strstr(out, "--shard"));
  free(out);

  /* ---- bad manifests: refused, naming file and line */
  const char *bad[][2] = {
      {"{\"id\": \"a\", \"verb\": \"pose\", \"args\": []}\n{\"id\": \"b\", \"verb\": \"pose\", "
       "\"args\": [\"x\"\n",
       "bad.jsonl:2: byte"},
      {"{\"id\": \"a\", \"verb\": \"live\", \"args\": []}\n", "bad.jsonl:1: verb \"live\""},
      {"{\"id\": \"a\", \"verb\": \"pose\", \"args\": []}\n{\"id\": \"a\", \"verb\": \"pose\", "
       "\"args\": []}\n",
       "bad.jsonl:2: id \"a\" already used on line 1"},
      {"{\"id\": \"../x\", \"verb\": \"pose\", \"args\": []}\n", "bad.jsonl:1: \"id\""},
      {"{\"id\": \"a\", \"verb\": \"pose\", \"args\": [1]}\n", "bad.jsonl:1: args[0]"},
      {"# nothing\n", "no jobs"},
  };
  for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
    write_text(DIR "/bad.jsonl", bad[k][0]);
    CHECK(km_test_run(KM_CLI " batch " DIR "/bad.jsonl", &out) == 1);
    CHECK_MSG(out && strstr(out, bad[k][1]), "case %zu: %s", k, out ? out : "");
    free(out);
  }
  CHECK(km_test_run(KM_CLI " batch " DIR "/missing.jsonl", NULL) == 1);

  /* ---- a failing job is reported and the others still run */
  write_text(DIR "/mixed.jsonl",
             "{\"id\": \"broken\", \"verb\": \"pose\", \"args\": [\"--mesh\", \"t.obj\", "
             "\"--motion\", \"no-such-take.json\", \"-o\", \"out/broken.pc2\"]}\n"
             "{\"id\": \"posed\", \"verb\": \"pose\", \"args\": [\"--mesh\", \"t.obj\", "
             "\"--motion\", \"take1.json\", \"-o\", \"out/posed.pc2\"]}\n");
  /* from another folder: the jobs' paths are the manifest's folder's */
  CHECK(km_test_run("d=$(pwd) && cd /tmp && " KM_CLI " batch $d/" DIR "/mixed.jsonl", &out) == 1);
  CHECK_MSG(out && strstr(out, "broken: FAILED") && strstr(out, "exit status 1") &&
                strstr(out, "posed: ok"),
            "%s", out ? out : "");
  free(out);
  cJSON *jr = km_test_read_json(DIR "/mixed.batch/jobs/broken.json");
  const cJSON *st = cJSON_GetObjectItemCaseSensitive(jr, "status");
  const cJSON *summary = cJSON_GetObjectItemCaseSensitive(jr, "summary");
  CHECK(cJSON_IsString(st) && !strcmp(st->valuestring, "failed"));
  CHECK_MSG(cJSON_IsString(summary) && strstr(summary->valuestring, "no-such-take.json"), "%s",
            cJSON_IsString(summary) ? summary->valuestring : "(none)");
  cJSON_Delete(jr);
  int ok = 0, failed = 0;
  report_counts(DIR "/mixed.batch/report.json", &ok, &failed);
  CHECK(ok == 1 && failed == 1);
  /* the rerun retries only the failed job */
  CHECK(km_test_run(KM_CLI " batch " DIR "/mixed.jsonl --dry-run 2>/dev/null", &out) == 0);
  CHECK(out && strstr(out, "\"broken\"") && !strstr(out, "\"posed\"") &&
        strstr(out, "failed before"));
  free(out);

  /* ---- --emit-sbatch: an array over the manifest */
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --emit-sbatch " DIR "/run.sbatch --tasks 3",
                    NULL) == 0);
  CHECK(km_test_run("grep -q '^#SBATCH --array=0-2$' " DIR
                    "/run.sbatch && grep -q 'batch .*m.jsonl' " DIR "/run.sbatch && bash -n " DIR
                    "/run.sbatch",
                    NULL) == 0);

  /* ---- the batch, under MPI when built with it */
#ifdef KM_MPIRUN
  /* (OpenMPI keeps allocations to its exit: no leak report from a sanitizer build) */
  const char *run = "ASAN_OPTIONS=detect_leaks=0 OMPI_ALLOW_RUN_AS_ROOT=1 "
                    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 " KM_MPIRUN
                    " -n 3 --oversubscribe --enable-recovery " KM_CLI " batch " DIR
                    "/m.jsonl --mpi --mpi-timeout 3";
#else
  const char *run = KM_CLI " batch " DIR "/m.jsonl";
  printf("built without MPI: the batch runs in one process, the killed-rank case is skipped\n");
#endif
  CHECK_MSG(km_test_run(run, &out) == 0, "%s", out ? out : "");
  free(out);
  report_counts(DIR "/m.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == NJ && failed == 0, "ok %d failed %d", ok, failed);
  /* each job's own command line, run alone, gives the same bytes */
  CHECK(km_test_run("mkdir -p " DIR "/keep && cp " DIR "/out/* " DIR "/keep/", NULL) == 0);
  for (int i = 1; i <= NJ; ++i) {
    char path[256];
    snprintf(path, sizeof path, DIR "/m.batch/jobs/s%d.json", i);
    jr = km_test_read_json(path);
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(jr, "command");
    const cJSON *outs = cJSON_GetObjectItemCaseSensitive(jr, "outputs");
    CHECK(cJSON_GetArraySize(outs) == 2);
    CHECK(cJSON_IsString(c) && !strncmp(c->valuestring, "cd /", 4));
    if (cJSON_IsString(c)) {
      /* the command says "kinemesh": put this build's first on the PATH */
      char *dir = strdup(KM_CLI);
      *strrchr(dir, '/') = '\0';
      snprintf(cmd, sizeof cmd, "PATH=%s:$PATH; %s", dir, c->valuestring);
      free(dir);
      CHECK_MSG(km_test_run(cmd, NULL) == 0, "%s", cmd);
    }
    cJSON_Delete(jr);
    char x[128], y[128];
    snprintf(x, sizeof x, DIR "/out/s%d.pc2", i);
    snprintf(y, sizeof y, DIR "/keep/s%d.pc2", i);
    CHECK_MSG(same_bytes(x, y), "s%d.pc2 differs from the job run alone", i);
  }
  /* the batch's own outputs back (a reconstruction report holds timings, which differ from run
   * to run): the rerun verifies every output and has nothing to do */
  CHECK(km_test_run("cp " DIR "/keep/* " DIR "/out/", NULL) == 0);
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run 2>/dev/null", &out) == 0);
  CHECK_MSG(out && !strchr(out, '{'), "%s", out ? out : "");
  free(out);
  /* a changed output is noticed */
  write_text(DIR "/out/s3.json", "{}");
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run 2>/dev/null", &out) == 0);
  memset(seen, 0, sizeof seen);
  CHECK(count_ids(out, seen) == 1 && seen[2] == 1 && strstr(out, "changed"));
  free(out);

#ifdef KM_MPIRUN
  /* ---- a worker rank killed mid-job: its job goes to another rank once (attempt 2), the
   * batch completes with the same bytes. OpenMPI 4 needs --enable-recovery for the others to
   * live on (in `run`).
   * A worker rank is a batch process that is not rank 0 and runs a job (has a child). */
  snprintf(cmd, sizeof cmd,
           "%s --force > " DIR "/mpi_kill.log 2>&1 & MP=$!; "
           "for t in $(seq 1 600); do "
           "  for p in $(pgrep -f 'kinemesh batch " DIR "/m.jsonl --mpi'); do "
           "    tr '\\0' '\\n' < /proc/$p/environ 2>/dev/null | grep -q '^OMPI_COMM_WORLD_RANK=0$' "
           "&& continue; "
           "    tr '\\0' '\\n' < /proc/$p/environ 2>/dev/null | grep -q '^OMPI_COMM_WORLD_RANK=' "
           "|| continue; "
           "    c=$(pgrep -P $p | head -1); "
           "    if [ -n \"$c\" ] && grep -q reconstruct /proc/$c/cmdline 2>/dev/null; then "
           "      kill -9 $p; echo killed rank pid $p; wait $MP; exit 0; fi; "
           "  done; sleep 0.1; "
           "done; echo no worker found; wait $MP; exit 1",
           run);
  CHECK_MSG(km_test_run(cmd, &out) == 0, "%s", out ? out : "");
  free(out);
  report_counts(DIR "/m.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == NJ && failed == 0, "after a kill: ok %d failed %d", ok, failed);
  CHECK(km_test_run("grep -q 'handing it to another rank (attempt 2)' " DIR "/mpi_kill.log",
                    NULL) == 0);
  CHECK(km_test_run("test $(grep -l '\"attempts\":.2' " DIR "/m.batch/jobs/*.json | wc -l) = 1",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run 2>/dev/null", &out) == 0);
  CHECK_MSG(out && !strchr(out, '{'), "%s", out ? out : "");
  free(out);
  for (int i = 1; i <= NJ; ++i) {
    char x[128], y[128];
    snprintf(x, sizeof x, DIR "/out/s%d.pc2", i);
    snprintf(y, sizeof y, DIR "/keep/s%d.pc2", i);
    CHECK_MSG(same_bytes(x, y), "s%d.pc2 differs after the kill", i);
  }

  /* ---- a job lost twice: the worker rank running it is killed, then the worker rank running
   * its second attempt too. The job is reported failed (attempts 2), the rest completes, and a
   * rerun runs that job alone. (The second attempt goes to a worker, never rank 0, and an idle
   * worker waits while a job may still come back, so there is a worker to kill.) */
  snprintf(
      cmd, sizeof cmd,
      "%s --force > " DIR "/mpi_kill2.log 2>&1 & MP=$!; job=; "
      "for t in $(seq 1 1200); do "
      "  for p in $(pgrep -f 'kinemesh batch " DIR "/m.jsonl --mpi'); do "
      "    tr '\\0' '\\n' < /proc/$p/environ 2>/dev/null | grep -q '^OMPI_COMM_WORLD_RANK=0$' "
      "&& continue; "
      "    tr '\\0' '\\n' < /proc/$p/environ 2>/dev/null | grep -q '^OMPI_COMM_WORLD_RANK=' "
      "|| continue; "
      "    c=$(pgrep -P $p | head -1); [ -n \"$c\" ] || continue; "
      "    o=$(tr '\\0' ' ' < /proc/$c/cmdline 2>/dev/null | grep -o "
      "'reconstruct.*out/s[0-9]*\\.pc2' "
      "| grep -o 's[0-9]*\\.pc2'); [ -n \"$o\" ] || continue; "
      "    if [ -z \"$job\" ]; then job=$o; kill -9 $p; echo \"killed rank pid $p running $o\"; "
      "    elif [ \"$o\" = \"$job\" ]; then kill -9 $p; echo \"killed rank pid $p running $o "
      "again\"; wait $MP; echo \"lost job ${o%%.pc2}, batch exit $?\"; exit 0; fi; "
      "  done; sleep 0.1; "
      "done; echo \"job $job not seen twice\"; kill $MP; wait $MP; exit 1",
      run);
  CHECK_MSG(km_test_run(cmd, &out) == 0, "%s", out ? out : "");
  char lost[16] = "";
  const char *lj = out ? strstr(out, "lost job ") : NULL;
  if (lj) sscanf(lj + 9, "%15[a-z0-9]", lost);
  CHECK_MSG(lost[0] == 's', "%s", out ? out : "");
  free(out);
  /* (mpirun's exit status says nothing here: under --enable-recovery OpenMPI 4.1 exits 0 after
   * rank 0's MPI_Abort; the report and rank 0's last lines say what failed) */
  CHECK(km_test_run("grep -q '6 jobs: 5 ok, 1 failed' " DIR "/mpi_kill2.log", NULL) == 0);
  report_counts(DIR "/m.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == NJ - 1 && failed == 1, "lost twice: ok %d failed %d", ok, failed);
  snprintf(cmd, sizeof cmd, DIR "/m.batch/jobs/%s.json", lost);
  jr = km_test_read_json(cmd);
  st = cJSON_GetObjectItemCaseSensitive(jr, "status");
  const cJSON *att = cJSON_GetObjectItemCaseSensitive(jr, "attempts");
  const cJSON *err = cJSON_GetObjectItemCaseSensitive(jr, "error");
  CHECK(cJSON_IsString(st) && !strcmp(st->valuestring, "failed"));
  CHECK(cJSON_IsNumber(att) && att->valueint == 2);
  CHECK_MSG(cJSON_IsString(err) && strstr(err->valuestring, "the second rank it was given"), "%s",
            cJSON_IsString(err) ? err->valuestring : "(none)");
  cJSON_Delete(jr);
  CHECK(km_test_run("grep -q 'handing it to another rank (attempt 2)' " DIR "/mpi_kill2.log",
                    NULL) == 0);
  /* the rerun: that job alone, then everything verifies with the bytes of the jobs alone */
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl --dry-run 2>/dev/null", &out) == 0);
  memset(seen, 0, sizeof seen);
  CHECK_MSG(count_ids(out, seen) == 1 && seen[atoi(lost + 1) - 1] == 1 &&
                strstr(out, "failed before"),
            "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " batch " DIR "/m.jsonl", &out) == 0);
  char want[64];
  snprintf(want, sizeof want, "%s: ok", lost);
  CHECK_MSG(out && strstr(out, "1 of 6 jobs to run") && strstr(out, want), "%s", out ? out : "");
  free(out);
  report_counts(DIR "/m.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == NJ && failed == 0, "after the rerun: ok %d failed %d", ok, failed);
  for (int i = 1; i <= NJ; ++i) {
    char x[128], y[128];
    snprintf(x, sizeof x, DIR "/out/s%d.pc2", i);
    snprintf(y, sizeof y, DIR "/keep/s%d.pc2", i);
    CHECK_MSG(same_bytes(x, y), "s%d.pc2 differs after the rerun", i);
  }
#endif

  /* ---- one long take across ranks: a segmented job becomes segment jobs (any rank, any
   * shard) and a stitch once they are done; the output has the bytes of the job run alone */
  CHECK(km_test_capture(DIR "/t.obj", "walk", atoi(SEGN), DIR "/long.json", 4, 3000, "", DIR "/cl",
                        NULL) == 0);
  write_text(DIR "/seg.jsonl",
             "{\"id\": \"long\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
             "\"--clouds\", \"cl/frame_*.ply\", \"--segment-frames\", \"" SEGS "\", \"--overlap\", "
             "\"1\", \"-o\", \"out/long.pc2\", \"--report\", \"out/long.json\"]}\n");
  /* the segments spread over shards, each once; the stitch goes with the last one */
  for (int n = 1; n <= 3; ++n) {
    int found[4] = {0};
    for (int i = 0; i < n; ++i) {
      snprintf(cmd, sizeof cmd,
               KM_CLI " batch " DIR "/seg.jsonl --dry-run --shard %d/%d 2>/dev/null", i, n);
      CHECK(km_test_run(cmd, &out) == 0);
      for (int k = 0; k < 3; ++k) {
        char id[32];
        snprintf(id, sizeof id, "\"long@seg%d\"", k);
        found[k] += out && strstr(out, id) != NULL;
      }
      found[3] += out && strstr(out, "{\"id\":\"long\"") != NULL;
      free(out);
    }
    for (int k = 0; k < 4; ++k)
      CHECK_MSG(found[k] == 1, "N=%d: %s in %d shards", n, k < 3 ? "a segment" : "the stitch",
                found[k]);
  }
  char segrun[1024];
#ifdef KM_MPIRUN
  snprintf(segrun, sizeof segrun,
           "ASAN_OPTIONS=detect_leaks=0 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
           "%s -n 3 --oversubscribe --enable-recovery " KM_CLI " batch " DIR
           "/seg.jsonl --mpi --mpi-timeout 3",
           KM_MPIRUN);
#else
  snprintf(segrun, sizeof segrun, KM_CLI " batch " DIR "/seg.jsonl");
#endif
  CHECK_MSG(km_test_run(segrun, &out) == 0, "%s", out ? out : "");
  CHECK(out && strstr(out, "long@seg2: ok") && strstr(out, "long: ok"));
  free(out);
  report_counts(DIR "/seg.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == 4 && failed == 0, "segmented: ok %d failed %d", ok, failed);
  CHECK(km_test_run("cd " DIR " && " KM_CLI
                    " reconstruct --template t.obj --clouds 'cl/frame_*.ply' "
                    "--segment-frames " SEGS " --overlap 1 -o alone.pc2 2>/dev/null",
                    NULL) == 0);
  CHECK_MSG(same_bytes(DIR "/out/long.pc2", DIR "/alone.pc2"),
            "the batch's stitched take differs from reconstruct --segment-frames alone");
  CHECK(km_test_run("grep -q '\"frames\"' " DIR "/out/long.json", NULL) == 0); /* its report */
  /* shards end at different times: --collect (the array's afterany step) stitches a take
   * whose segments are all done, from the parts alone */
  CHECK(km_test_run("rm " DIR "/out/long.pc2 " DIR "/seg.batch/jobs/long.json", NULL) == 0);
  CHECK(km_test_run(KM_CLI " batch " DIR "/seg.jsonl --collect", &out) == 0);
  CHECK_MSG(out && strstr(out, "long: ok") && !strstr(out, "long@seg"), "%s", out ? out : "");
  free(out);
  CHECK(same_bytes(DIR "/out/long.pc2", DIR "/alone.pc2"));
  /* a rerun verifies everything: nothing to do */
  CHECK(km_test_run(KM_CLI " batch " DIR "/seg.jsonl --dry-run 2>/dev/null", &out) == 0);
  CHECK_MSG(out && !strchr(out, '{'), "%s", out ? out : "");
  free(out);

  /* ---- a QA pass over the takes: check jobs, one within its limits, one beyond (exit 3: the
   * job is failed, its report names the code and the limit) */
  write_text(DIR "/qa.jsonl",
             "{\"id\": \"q1\", \"verb\": \"check\", \"args\": [\"out/long.pc2\", \"--mesh\", "
             "\"t.obj\", \"--report\", \"out/q1.json\", \"--max-stretch\", \"100\"]}\n"
             "{\"id\": \"q2\", \"verb\": \"check\", \"args\": [\"out/long.pc2\", \"--mesh\", "
             "\"t.obj\", \"--max-stretch\", \"0\"]}\n");
  CHECK(km_test_run(KM_CLI " batch " DIR "/qa.jsonl", &out) == 1);
  CHECK_MSG(out && strstr(out, "q1: ok") && strstr(out, "q2: FAILED") &&
                strstr(out, "exit status 3"),
            "%s", out ? out : "");
  free(out);
  report_counts(DIR "/qa.batch/report.json", &ok, &failed);
  CHECK_MSG(ok == 1 && failed == 1, "qa: ok %d failed %d", ok, failed);
  cJSON *q2 = km_test_read_json(DIR "/qa.batch/jobs/q2.json");
  const cJSON *code = cJSON_GetObjectItemCaseSensitive(q2, "exit_code");
  const cJSON *sum = cJSON_GetObjectItemCaseSensitive(q2, "summary");
  CHECK(cJSON_IsNumber(code) && code->valueint == 3);
  CHECK_MSG(cJSON_IsString(sum) && strstr(sum->valuestring, "limits exceeded: stretch"), "%s",
            cJSON_IsString(sum) ? sum->valuestring : "(no summary)");
  cJSON_Delete(q2);
  CHECK(km_test_run("grep -q kinemesh-deform-report " DIR "/out/q1.json", NULL) == 0);
  return km_test_finish("test_batch_cli");
}
