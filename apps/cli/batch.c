/* kinemesh batch MANIFEST (issue 17): a capture archive's jobs, one JSON line each, run as
 * child processes of this binary in the manifest's folder; a report per job (status, times,
 * exact command line, output checksums) and one for the batch; resumable; sharded for Slurm
 * job arrays; under MPI (apps/mpi/batch_mpi.c) rank 0 hands jobs out longest first.
 *
 * A job is a child process rather than a call of the verb's function in this process: a job
 * that crashes, runs out of memory or is killed takes nothing else with it, and the verbs keep
 * their own process-wide state (logger, progress bar, exit paths) untouched. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include "batch.h"
#include "cli.h"
#include "recon_segments.h"

#include <cjson/cJSON.h>

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#ifdef __linux__
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#endif

/* The verbs a job may name: those that take files in and write files out. */
static const char *const JOB_VERBS[] = {"reconstruct", "animate",    "pose", "avatar",
                                        "transfer",    "precompute", "bake", "check"};
/* The options whose value is an output file of the job (checksummed, verified on resume). */
static const char *const OUTPUT_OPTS[] = {"-o", "--output", "--report", "--plot"};

typedef struct job {
  char *id, *verb;
  char **args;
  int n_args;
  int line;      /* manifest line, 1-based */
  double frames; /* cost for longest-first: frame count, or 1 when unknown */
  /* One long take across ranks: a manifest job `reconstruct ... --segment-frames S` of more
   * than S frames becomes n_seg segment jobs (`... --segment K --segment-dir DIR`, id
   * "ID@segK", parent = its index, output: the part file) run anywhere, and the job itself
   * becomes the stitch (`... --segment-dir DIR`), run once its segments are done. */
  long parent;    /* a segment job: the segmented job's index; else -1 */
  size_t n_seg;   /* a segmented job: its segments (the jobs parts[0..n_seg)) */
  size_t *parts;  /* a segmented job: its segment jobs' indices */
  char *part_dir; /* a segmented job and its segments: folder of the parts */
  char *part;     /* a segment job: its part file, its one output */
  size_t seq;     /* position when segments take their job's place: shards, serial order */
  int attempts;   /* this run's attempt (MPI: 2 when a lost rank's job is reassigned) */
} job;

struct km_batch {
  char *manifest; /* absolute */
  char *dir;      /* the manifest's folder, absolute: the jobs' working directory */
  char *reports;  /* absolute */
  char self[PATH_MAX];
  job *jobs;
  size_t n_jobs;     /* manifest jobs, then the segment jobs */
  size_t n_manifest; /* manifest jobs */
  int shard_i, shard_n;
  int rank; /* MPI rank, -1 outside MPI (km_batch_set_rank) */
  bool force;
};

const char *km_batch_job_id(const km_batch *b, size_t j) { return b->jobs[j].id; }
long km_batch_job_parent(const km_batch *b, size_t j) { return b->jobs[j].parent; }
void km_batch_set_attempt(km_batch *b, size_t j, int attempt) { b->jobs[j].attempts = attempt; }
void km_batch_set_rank(km_batch *b, int rank) { b->rank = rank; }

/* ---- small helpers */

static char *dup_printf(const char *fmt, ...) {
  va_list ap, aq;
  va_start(ap, fmt);
  va_copy(aq, ap);
  int n = vsnprintf(NULL, 0, fmt, ap);
  va_end(ap);
  char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
  if (s) vsnprintf(s, (size_t)n + 1, fmt, aq);
  va_end(aq);
  return s;
}

static int mkdir_p(const char *path) {
  char tmp[PATH_MAX];
  if (snprintf(tmp, sizeof tmp, "%s", path) >= (int)sizeof tmp) return -1;
  for (char *p = tmp + 1; *p; ++p)
    if (*p == '/') {
      *p = '\0';
      if (mkdir(tmp, 0777) && errno != EEXIST) return -1;
      *p = '/';
    }
  return mkdir(tmp, 0777) && errno != EEXIST ? -1 : 0;
}

/* Absolute path of p (relative to the current directory); the file need not exist. */
static char *absolute(const char *p) {
  if (p[0] == '/') return strdup(p);
  char cwd[PATH_MAX];
  if (!getcwd(cwd, sizeof cwd)) return NULL;
  return dup_printf("%s/%s", cwd, p);
}

/* Single-quoted for a POSIX shell when it needs quoting. */
static void shell_quote(char *dst, size_t cap, const char *s) {
  bool plain = *s != '\0';
  for (const char *c = s; *c; ++c)
    if (!strchr("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-./=:,+@%", *c))
      plain = false;
  size_t n = 0;
  if (plain) {
    snprintf(dst, cap, "%s", s);
    return;
  }
  if (n + 1 < cap) dst[n++] = '\'';
  for (const char *c = s; *c && n + 5 < cap; ++c) {
    if (*c == '\'') {
      memcpy(dst + n, "'\\''", 4);
      n += 4;
    } else
      dst[n++] = *c;
  }
  if (n + 1 < cap) dst[n++] = '\'';
  dst[n < cap ? n : cap - 1] = '\0';
}

/* The exact command line a job equals, runnable from anywhere. */
static char *job_command(const km_batch *b, const job *jb) {
  size_t cap = 64 + 2 * strlen(b->dir) + strlen(jb->verb);
  for (int a = 0; a < jb->n_args; ++a)
    cap += 4 * strlen(jb->args[a]) + 3;
  char *s = malloc(cap), q[PATH_MAX * 4];
  if (!s) return NULL;
  shell_quote(q, sizeof q, b->dir);
  size_t n = (size_t)snprintf(s, cap, "cd %s && kinemesh %s", q, jb->verb);
  for (int a = 0; a < jb->n_args && n < cap; ++a) {
    shell_quote(q, sizeof q, jb->args[a]);
    n += (size_t)snprintf(s + n, cap - n, " %s", q);
  }
  return s;
}

/* ---- checksums: 64-bit FNV-1a, the project's file checksum (reduced-model cache, pose
 * database); a directory output (frames) is hashed over its regular files in name order,
 * each name and its bytes. */

#define FNV_OFFSET 1469598103934665603ull
#define FNV_PRIME 1099511628211ull

static int hash_file(const char *path, uint64_t *h, uint64_t *bytes) {
  FILE *f = fopen(path, "rb");
  if (!f) return -1;
  unsigned char buf[65536];
  size_t got;
  while ((got = fread(buf, 1, sizeof buf, f)) > 0) {
    for (size_t i = 0; i < got; ++i)
      *h = (*h ^ buf[i]) * FNV_PRIME;
    *bytes += got;
  }
  int bad = ferror(f);
  fclose(f);
  return bad ? -1 : 0;
}

static int cmp_str(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Checksum of a file or a directory of frames. Returns 0, -1 when it does not exist. */
static int hash_output(const char *path, uint64_t *h, uint64_t *bytes) {
  struct stat st;
  *h = FNV_OFFSET, *bytes = 0;
  if (stat(path, &st)) return -1;
  if (!S_ISDIR(st.st_mode)) return hash_file(path, h, bytes);
  DIR *d = opendir(path);
  if (!d) return -1;
  char **names = NULL;
  size_t n = 0, cap = 0;
  int rc = 0;
  for (struct dirent *e; (e = readdir(d));) {
    if (e->d_name[0] == '.') continue; /* ., .., and temporaries of atomic writes */
    if (n == cap) {
      char **g = realloc(names, (cap = cap ? 2 * cap : 64) * sizeof *g);
      if (!g) {
        rc = -1;
        break;
      }
      names = g;
    }
    names[n++] = strdup(e->d_name);
  }
  closedir(d);
  if (names) qsort(names, n, sizeof *names, cmp_str);
  for (size_t i = 0; i < n && !rc; ++i) {
    char *p = dup_printf("%s/%s", path, names[i]);
    if (!p || stat(p, &st)) rc = -1;
    if (!rc && S_ISREG(st.st_mode)) {
      for (const char *c = names[i]; *c; ++c)
        *h = (*h ^ (unsigned char)*c) * FNV_PRIME;
      *h = (*h ^ 0) * FNV_PRIME;
      rc = hash_file(p, h, bytes);
    }
    free(p);
  }
  for (size_t i = 0; i < n; ++i)
    free(names[i]);
  free(names);
  return rc;
}

/* ---- the manifest */

static bool is_output_opt(const char *a, const char **inline_val) {
  *inline_val = NULL;
  for (size_t k = 0; k < sizeof OUTPUT_OPTS / sizeof OUTPUT_OPTS[0]; ++k) {
    size_t len = strlen(OUTPUT_OPTS[k]);
    if (!strcmp(a, OUTPUT_OPTS[k])) return true;
    if (OUTPUT_OPTS[k][1] == '-' && !strncmp(a, OUTPUT_OPTS[k], len) && a[len] == '=') {
      *inline_val = a + len + 1;
      return true;
    }
  }
  return false;
}

/* The job's output paths (pointers into its args), at most cap. */
static int job_outputs(const job *jb, const char **out, int cap) {
  int n = 0;
  if (jb->part) {
    out[0] = jb->part;
    return 1;
  }
  for (int a = 0; a < jb->n_args && n < cap; ++a) {
    const char *v;
    if (!is_output_opt(jb->args[a], &v)) continue;
    if (v)
      out[n++] = v;
    else if (a + 1 < jb->n_args)
      out[n++] = jb->args[++a];
  }
  return n;
}

static const char *job_value(const job *jb, const char *opt) {
  size_t len = strlen(opt);
  for (int a = 0; a < jb->n_args; ++a) {
    if (!strcmp(jb->args[a], opt) && a + 1 < jb->n_args) return jb->args[a + 1];
    if (!strncmp(jb->args[a], opt, len) && jb->args[a][len] == '=') return jb->args[a] + len + 1;
  }
  return NULL;
}

/* Frame count of a job, for longest-first: the point cloud frames of a reconstruction, the
 * frames of a take; "frames" in the manifest line overrides; 1 when unknown. Runs in the
 * manifest's folder. */
static double job_frames(const job *jb) {
  const char *clouds = job_value(jb, "--clouds"), *motion = job_value(jb, "--motion");
  if (clouds) {
    char **paths = NULL;
    size_t n = 0;
    if (!km_point_frames_list(clouds, &paths, &n, NULL)) {
      km_paths_free(&paths, n);
      return (double)n;
    }
  }
  if (motion) {
    km_take t = {0};
    if (!km_take_read(motion, &t, NULL)) {
      double n = (double)t.n_frames;
      km_take_free(&t);
      return n;
    }
  }
  return 1;
}

static void batch_free(km_batch *b) {
  for (size_t j = 0; j < b->n_jobs; ++j) {
    free(b->jobs[j].id);
    free(b->jobs[j].verb);
    for (int a = 0; a < b->jobs[j].n_args; ++a)
      free(b->jobs[j].args[a]);
    free(b->jobs[j].args);
    free(b->jobs[j].parts);
    free(b->jobs[j].part_dir);
    free(b->jobs[j].part);
  }
  free(b->jobs);
  free(b->manifest);
  free(b->dir);
  free(b->reports);
}

static bool valid_id(const char *s) {
  if (!*s || *s == '.' || strlen(s) > 200) return false;
  for (; *s; ++s)
    if (!strchr("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.", *s))
      return false;
  return true;
}

/* Reads the manifest: JSON lines {"id", "verb", "args": [...], optional "frames"}; blank lines
 * and lines starting with '#' are skipped. Prints "FILE:LINE: byte B: ..." and returns
 * non-zero on the first bad line. */
static int read_manifest(km_batch *b, const char *path) {
  size_t size;
  char *text = km_cli_read_text(path, &size);
  if (!text) return km_cli_error("batch", "%s: cannot read: %s", path, strerror(errno));
  int rc = 0, lineno = 0;
  size_t cap = 0;
  for (char *line = text, *next; line && !rc; line = next) {
    next = strchr(line, '\n');
    if (next) *next++ = '\0';
    ++lineno;
    size_t len = strlen(line);
    if (len && line[len - 1] == '\r') line[--len] = '\0';
    const char *p = line;
    while (*p == ' ' || *p == '\t')
      ++p;
    if (!*p || *p == '#') continue;
    const char *end = NULL;
    cJSON *o = cJSON_ParseWithOpts(line, &end, true);
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(o, "id");
    const cJSON *verb = cJSON_GetObjectItemCaseSensitive(o, "verb");
    const cJSON *args = cJSON_GetObjectItemCaseSensitive(o, "args");
    const cJSON *frames = cJSON_GetObjectItemCaseSensitive(o, "frames");
    if (!o) {
      rc = km_cli_error("batch",
                        "%s:%d: byte %ld: not a JSON object (expected {\"id\": ..., "
                        "\"verb\": ..., \"args\": [...]})",
                        path, lineno, end ? (long)(end - line) + 1 : 1L);
    } else if (!cJSON_IsString(id) || !valid_id(id->valuestring)) {
      rc = km_cli_error("batch",
                        "%s:%d: \"id\" must be a string of letters, digits, '_', '-' "
                        "and '.' (a file name for its report)",
                        path, lineno);
    } else if (!cJSON_IsString(verb)) {
      rc = km_cli_error("batch", "%s:%d: \"verb\" must be a string", path, lineno);
    } else if (!cJSON_IsArray(args)) {
      rc = km_cli_error("batch", "%s:%d: \"args\" must be an array of strings", path, lineno);
    } else if (frames && !(cJSON_IsNumber(frames) && frames->valuedouble >= 0)) {
      rc = km_cli_error("batch", "%s:%d: \"frames\" must be a number >= 0", path, lineno);
    } else {
      bool known = false;
      for (size_t k = 0; k < sizeof JOB_VERBS / sizeof JOB_VERBS[0]; ++k)
        known |= !strcmp(verb->valuestring, JOB_VERBS[k]);
      for (size_t j = 0; j < b->n_jobs && !rc; ++j)
        if (!strcmp(b->jobs[j].id, id->valuestring))
          rc = km_cli_error("batch", "%s:%d: id \"%s\" already used on line %d", path, lineno,
                            id->valuestring, b->jobs[j].line);
      if (!rc && !known)
        rc = km_cli_error("batch",
                          "%s:%d: verb \"%s\" cannot be a batch job (reconstruct, animate, pose, "
                          "avatar, transfer, precompute, bake)",
                          path, lineno, verb->valuestring);
      int n_args = cJSON_GetArraySize(args);
      for (int a = 0; a < n_args && !rc; ++a)
        if (!cJSON_IsString(cJSON_GetArrayItem(args, a)))
          rc = km_cli_error("batch", "%s:%d: args[%d] is not a string", path, lineno, a);
      if (!rc && b->n_jobs == cap) {
        job *g = realloc(b->jobs, (cap = cap ? 2 * cap : 64) * sizeof *g);
        if (!g) rc = km_cli_error("batch", "out of memory");
        if (g) b->jobs = g;
      }
      if (!rc) {
        job *jb = &b->jobs[b->n_jobs++];
        memset(jb, 0, sizeof *jb);
        jb->id = strdup(id->valuestring);
        jb->verb = strdup(verb->valuestring);
        jb->line = lineno;
        jb->frames = frames ? frames->valuedouble : -1;
        jb->parent = -1;
        jb->seq = b->n_jobs - 1;
        jb->args = calloc((size_t)n_args + 1, sizeof *jb->args);
        for (int a = 0; jb->args && a < n_args; ++a)
          jb->args[jb->n_args++] = strdup(cJSON_GetArrayItem(args, a)->valuestring);
        if (!jb->id || !jb->verb || !jb->args) rc = km_cli_error("batch", "out of memory");
      }
    }
    cJSON_Delete(o);
  }
  free(text);
  if (!rc && b->n_jobs == 0) rc = km_cli_error("batch", "%s: no jobs", path);
  b->n_manifest = b->n_jobs;
  return rc;
}

/* Expands every `reconstruct ... --segment-frames S` job of more than S frames into its
 * segment jobs (see job). Runs in the manifest's folder (counts the --clouds frames). Returns
 * non-zero when out of memory. */
static int expand_segments(km_batch *b) {
  size_t seq = 0;
  for (size_t j = 0; j < b->n_manifest; ++j) {
    job *jb = &b->jobs[j];
    const char *sv = job_value(jb, "--segment-frames"), *ov = job_value(jb, "--overlap");
    char **paths = NULL;
    size_t n = 0;
    long S = sv ? strtol(sv, NULL, 10) : 0, O = ov ? strtol(ov, NULL, 10) : 5;
    jb->seq = seq++;
    if (strcmp(jb->verb, "reconstruct") || S <= 0 || O < 0 || job_value(jb, "--segment") ||
        job_value(jb, "--segment-dir") || !job_value(jb, "--clouds"))
      continue;
    if (km_point_frames_list(job_value(jb, "--clouds"), &paths, &n, NULL)) continue;
    km_paths_free(&paths, n);
    if ((size_t)S >= n) continue;
    const size_t nseg = km_cli_segment_count(n, (size_t)S);
    job *g = realloc(b->jobs, (b->n_jobs + nseg) * sizeof *g);
    if (!g) return -1;
    b->jobs = g;
    jb = &b->jobs[j];
    jb->n_seg = nseg;
    jb->parts = malloc(nseg * sizeof *jb->parts);
    jb->part_dir = dup_printf("%s/segments/%s", b->reports, jb->id);
    jb->frames = (double)n;
    if (!jb->parts || !jb->part_dir) return -1;
    for (size_t k = 0; k < nseg; ++k) {
      job *sj = &b->jobs[b->n_jobs];
      memset(sj, 0, sizeof *sj);
      jb->parts[k] = b->n_jobs++;
      sj->id = dup_printf("%s@seg%zu", jb->id, k);
      sj->verb = strdup(jb->verb);
      sj->line = jb->line;
      sj->parent = (long)j;
      sj->seq = k ? seq++ : jb->seq; /* the segments take the job's place */
      const size_t a = k * (size_t)S, e = a + (size_t)(S + O) < n ? a + (size_t)(S + O) : n;
      sj->frames = (double)(e - a);
      sj->part_dir = strdup(jb->part_dir);
      sj->part = km_cli_segment_part_path(jb->part_dir, k);
      sj->args = calloc((size_t)jb->n_args + 5, sizeof *sj->args);
      if (!sj->id || !sj->verb || !sj->part_dir || !sj->part || !sj->args) return -1;
      for (int a2 = 0; a2 < jb->n_args; ++a2)
        if (!(sj->args[sj->n_args++] = strdup(jb->args[a2]))) return -1;
      sj->args[sj->n_args++] = strdup("--segment");
      sj->args[sj->n_args++] = dup_printf("%zu", k);
      sj->args[sj->n_args++] = strdup("--segment-dir");
      sj->args[sj->n_args++] = strdup(jb->part_dir);
      for (int a2 = jb->n_args; a2 < sj->n_args; ++a2)
        if (!sj->args[a2]) return -1;
    }
    jb->seq = b->jobs[jb->parts[nseg - 1]].seq; /* the stitch: in its last segment's shard */
  }
  return 0;
}

/* ---- reports */

static char *report_path(const km_batch *b, const job *jb) {
  return dup_printf("%s/jobs/%s.json", b->reports, jb->id);
}
static char *log_path(const km_batch *b, const job *jb) {
  return dup_printf("%s/logs/%s.log", b->reports, jb->id);
}

static int write_json(const char *path, cJSON *o) {
  char *s = cJSON_Print(o);
  if (!s) return -1;
  size_t n = strlen(s);
  s[n] = '\n'; /* cJSON_Print's terminator becomes the final newline */
  km_error err = {0};
  km_status st = km_write_file_atomic(path, s, n + 1, &err);
  free(s);
  if (st) km_cli_fail("batch", &err);
  return st ? -1 : 0;
}

static void hex64(char out[17], uint64_t h) { snprintf(out, 17, "%016llx", (unsigned long long)h); }

/* Whether the job's report says it succeeded with these very arguments and its outputs still
 * have the checksums it recorded. *why: what does not verify (static text). */
static bool job_verifies(const km_batch *b, const job *jb, const char **why) {
  char *rp = report_path(b, jb);
  cJSON *r = rp ? km_cli_read_json(rp) : NULL;
  free(rp);
  *why = "no report";
  if (!r) return false;
  bool ok = false;
  const cJSON *st = cJSON_GetObjectItemCaseSensitive(r, "status");
  const cJSON *verb = cJSON_GetObjectItemCaseSensitive(r, "verb");
  const cJSON *args = cJSON_GetObjectItemCaseSensitive(r, "args");
  const cJSON *outs = cJSON_GetObjectItemCaseSensitive(r, "outputs");
  if (!cJSON_IsString(st) || strcmp(st->valuestring, "ok")) {
    *why = "failed before";
    goto done;
  }
  *why = "arguments changed";
  if (!cJSON_IsString(verb) || strcmp(verb->valuestring, jb->verb) ||
      cJSON_GetArraySize(args) != jb->n_args)
    goto done;
  for (int a = 0; a < jb->n_args; ++a) {
    const cJSON *v = cJSON_GetArrayItem(args, a);
    if (!cJSON_IsString(v) || strcmp(v->valuestring, jb->args[a])) goto done;
  }
  *why = "an output is missing or changed";
  const cJSON *o;
  cJSON_ArrayForEach(o, outs) {
    const cJSON *p = cJSON_GetObjectItemCaseSensitive(o, "path");
    const cJSON *h = cJSON_GetObjectItemCaseSensitive(o, "fnv1a64");
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(o, "bytes");
    uint64_t hh, bytes;
    char hx[17];
    if (!cJSON_IsString(p) || !cJSON_IsString(h) || !cJSON_IsNumber(n) ||
        hash_output(p->valuestring, &hh, &bytes))
      goto done;
    hex64(hx, hh);
    if (strcmp(hx, h->valuestring) || (double)bytes != n->valuedouble) goto done;
  }
  *why = NULL;
  ok = true;
done:
  cJSON_Delete(r);
  return ok;
}

static void add_string_array(cJSON *o, const char *key, char **v, int n) {
  cJSON *a = cJSON_AddArrayToObject(o, key);
  for (int i = 0; i < n; ++i)
    cJSON_AddItemToArray(a, cJSON_CreateString(v[i]));
}

static cJSON *job_report_base(const km_batch *b, const job *jb) {
  cJSON *r = cJSON_CreateObject();
  cJSON_AddStringToObject(r, "id", jb->id);
  cJSON_AddStringToObject(r, "verb", jb->verb);
  add_string_array(r, "args", jb->args, jb->n_args);
  char *cmd = job_command(b, jb);
  cJSON_AddStringToObject(r, "command", cmd ? cmd : "");
  free(cmd);
  cJSON_AddNumberToObject(r, "frames", jb->frames);
  cJSON_AddNumberToObject(r, "attempts", jb->attempts > 0 ? jb->attempts : 1);
  if (jb->parent >= 0) cJSON_AddStringToObject(r, "part_of", b->jobs[jb->parent].id);
  if (jb->n_seg) {
    /* the command above gives these bytes alone; the batch stitched the parts here */
    cJSON_AddNumberToObject(r, "segments", (double)jb->n_seg);
    cJSON_AddStringToObject(r, "segment_dir", jb->part_dir);
  }
  char host[256] = "";
  gethostname(host, sizeof host - 1);
  cJSON_AddStringToObject(r, "host", host);
  if (b->rank >= 0) cJSON_AddNumberToObject(r, "rank", b->rank);
  return r;
}

void km_batch_mark_failed(km_batch *b, size_t j, const char *why) {
  const job *jb = &b->jobs[j];
  cJSON *r = job_report_base(b, jb);
  cJSON_AddStringToObject(r, "status", "failed");
  cJSON_AddStringToObject(r, "error", why);
  cJSON_AddArrayToObject(r, "outputs");
  char *rp = report_path(b, jb);
  if (rp) write_json(rp, r);
  free(rp);
  cJSON_Delete(r);
}

/* The last non-empty line of the job's log (its summary line: errors, timing). */
static char *log_tail(const char *path) {
  char *t = km_cli_read_text(path, NULL);
  if (!t) return NULL;
  char *end = t + strlen(t);
  while (end > t && (end[-1] == '\n' || end[-1] == '\r' || end[-1] == ' '))
    *--end = '\0';
  char *start = end;
  while (start > t && start[-1] != '\n' && start[-1] != '\r')
    --start;
  char *s = strndup(start, 1000);
  free(t);
  return s;
}

/* Waits for the job's process; with a tick, calls it about every 20 ms meanwhile (rank 0
 * answers the other ranks in it: a worker that finished waits that long at most for its next
 * job) and notices the process's end at once (a pidfd; where there is none, a 20 ms nap).
 * Returns whether the process was waited for. */
static bool wait_job(pid_t pid, int *status, struct rusage *ru, km_batch_tick tick, void *user) {
  int pfd = -1;
#if defined(__linux__) && defined(SYS_pidfd_open)
  if (tick) pfd = (int)syscall(SYS_pidfd_open, pid, 0);
#endif
  bool waited = false;
  for (;;) {
    pid_t w = wait4(pid, status, tick ? WNOHANG : 0, ru);
    if (w == pid) {
      waited = true;
      break;
    }
    if (w < 0 && errno != EINTR) break;
    if (!tick) continue;
    tick(user);
#ifdef __linux__
    if (pfd >= 0) {
      struct pollfd p = {.fd = pfd, .events = POLLIN};
      poll(&p, 1, 20);
      continue;
    }
#endif
    nanosleep(&(struct timespec){0, 20000000}, NULL);
  }
  if (pfd >= 0) close(pfd);
  return waited;
}

int km_batch_run_job(km_batch *b, size_t j, km_batch_tick tick, void *user) {
  const job *jb = &b->jobs[j];
  char *rp = report_path(b, jb), *lp = log_path(b, jb);
  char **argv = calloc((size_t)jb->n_args + 5, sizeof *argv);
  if (!rp || !lp || !argv) {
    free(rp), free(lp), free(argv);
    return 1;
  }
  unlink(rp);      /* a job half rerun must not pass for the old, finished one */
  if (jb->n_seg) { /* the stitch: its segments' parts must be there and verify */
    for (size_t k = 0; k < jb->n_seg; ++k) {
      const job *sj = &b->jobs[jb->parts[k]];
      const char *why = NULL;
      if (job_verifies(b, sj, &why)) continue;
      char msg[512];
      snprintf(msg, sizeof msg, "segment %s is not done (%s): the stitch did not run", sj->id,
               why ? why : "?");
      km_batch_mark_failed(b, j, msg);
      fprintf(stderr, "kinemesh batch: %s: FAILED: %s\n", jb->id, msg);
      free(rp), free(lp), free(argv);
      return 1;
    }
  }
  if (jb->part_dir && mkdir_p(jb->part_dir)) {
    char msg[512];
    snprintf(msg, sizeof msg, "%.400s: cannot create: %s", jb->part_dir, strerror(errno));
    km_batch_mark_failed(b, j, msg);
    free(rp), free(lp), free(argv);
    return 1;
  }
  int na = 0;
  argv[na++] = "kinemesh";
  argv[na++] = jb->verb;
  for (int a = 0; a < jb->n_args; ++a)
    argv[na++] = jb->args[a];
  if (jb->n_seg) argv[na++] = "--segment-dir", argv[na++] = jb->part_dir;
  double t0 = km_seconds();
  struct timespec started;
  clock_gettime(CLOCK_REALTIME, &started);
  pid_t parent = getpid();
  fflush(NULL);
  pid_t pid = fork();
  if (pid == 0) {
#ifdef __linux__
    /* a killed batch process (an MPI rank) takes its job with it */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
#endif
    FILE *log = fopen(lp, "wb");
    if (log) {
      dup2(fileno(log), 1);
      dup2(fileno(log), 2);
    }
    execv(b->self, argv);
    fprintf(stderr, "kinemesh batch: cannot run %s: %s\n", b->self, strerror(errno));
    _exit(127);
  }
  free(argv);
  int status = 0;
  struct rusage ru = {0};
  bool waited = pid > 0 && wait_job(pid, &status, &ru, tick, user);
  double seconds = km_seconds() - t0;
  cJSON *r = job_report_base(b, jb);
  const char *error = NULL;
  char msg[256];
  if (pid < 0 || !waited) {
    error = "could not start the job's process";
  } else if (WIFSIGNALED(status)) {
    snprintf(msg, sizeof msg, "killed by signal %d (%s)", WTERMSIG(status),
             strsignal(WTERMSIG(status)));
    error = msg;
  } else if (WEXITSTATUS(status)) {
    snprintf(msg, sizeof msg, "exit status %d", WEXITSTATUS(status));
    error = msg;
  }
  if (waited && WIFEXITED(status))
    cJSON_AddNumberToObject(r, "exit_code", WEXITSTATUS(status));
  else
    cJSON_AddNullToObject(r, "exit_code");
  cJSON_AddNumberToObject(r, "seconds", seconds);
  /* when, on the clock all ranks share (Unix seconds): how busy each rank was (bench batch) */
  cJSON_AddNumberToObject(r, "started_unix", (double)started.tv_sec + 1e-9 * started.tv_nsec);
  cJSON_AddNumberToObject(r, "cpu_seconds",
                          (double)ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec +
                              (double)ru.ru_stime.tv_sec + 1e-6 * ru.ru_stime.tv_usec);
  cJSON_AddNumberToObject(r, "max_rss_mb", (double)ru.ru_maxrss / 1024.0);
  cJSON *outs = cJSON_AddArrayToObject(r, "outputs");
  const char *op[32];
  int n_out = job_outputs(jb, op, 32);
  for (int k = 0; k < n_out && !error; ++k) {
    uint64_t h, bytes;
    char hx[17];
    if (hash_output(op[k], &h, &bytes)) {
      snprintf(msg, sizeof msg, "output %.200s was not written", op[k]);
      error = msg;
      break;
    }
    hex64(hx, h);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "path", op[k]);
    cJSON_AddNumberToObject(o, "bytes", (double)bytes);
    cJSON_AddStringToObject(o, "fnv1a64", hx);
    cJSON_AddItemToArray(outs, o);
  }
  cJSON_AddStringToObject(r, "status", error ? "failed" : "ok");
  if (error) cJSON_AddStringToObject(r, "error", error);
  cJSON_AddStringToObject(r, "log", lp);
  char *tail = log_tail(lp);
  if (tail) cJSON_AddStringToObject(r, "summary", tail);
  free(tail);
  int rc = write_json(rp, r) ? 1 : error ? 1 : 0;
  cJSON_Delete(r);
  fprintf(stderr, "kinemesh batch: %s: %s (%.2f s)%s%s\n", jb->id, error ? "FAILED" : "ok", seconds,
          error ? ": " : "", error ? error : "");
  free(rp);
  free(lp);
  return rc;
}

int km_batch_write_report(km_batch *b) {
  cJSON *r = cJSON_CreateObject();
  cJSON_AddStringToObject(r, "manifest", b->manifest);
  cJSON_AddStringToObject(r, "folder", b->dir);
  cJSON_AddNumberToObject(r, "jobs_total", (double)b->n_jobs);
  cJSON *counts = cJSON_AddObjectToObject(r, "counts");
  cJSON *jobs = cJSON_AddArrayToObject(r, "jobs");
  size_t ok = 0, failed = 0, pending = 0;
  double seconds = 0;
  for (size_t j = 0; j < b->n_jobs; ++j) {
    const job *jb = &b->jobs[j];
    char *rp = report_path(b, jb);
    cJSON *jr = rp ? km_cli_read_json(rp) : NULL;
    free(rp);
    cJSON *e = cJSON_CreateObject();
    cJSON_AddStringToObject(e, "id", jb->id);
    cJSON_AddStringToObject(e, "verb", jb->verb);
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(jr, "status");
    const char *status = cJSON_IsString(st) ? st->valuestring : "pending";
    ok += !strcmp(status, "ok");
    failed += !strcmp(status, "failed");
    pending += !cJSON_IsString(st);
    cJSON_AddStringToObject(e, "status", status);
    const char *keys[] = {"seconds", "cpu_seconds", "started_unix", "exit_code",
                          "error",   "summary",     "host",         "rank",
                          "outputs", "command",     "attempts",     "part_of"};
    for (size_t k = 0; jr && k < sizeof keys / sizeof keys[0]; ++k) {
      const cJSON *v = cJSON_GetObjectItemCaseSensitive(jr, keys[k]);
      if (v) cJSON_AddItemToObject(e, keys[k], cJSON_Duplicate(v, true));
      if (!strcmp(keys[k], "seconds") && cJSON_IsNumber(v)) seconds += v->valuedouble;
    }
    cJSON_AddItemToArray(jobs, e);
    cJSON_Delete(jr);
  }
  cJSON_AddNumberToObject(counts, "ok", (double)ok);
  cJSON_AddNumberToObject(counts, "failed", (double)failed);
  cJSON_AddNumberToObject(counts, "pending", (double)pending);
  cJSON_AddNumberToObject(r, "job_seconds", seconds);
  char *path = dup_printf("%s/report.json", b->reports);
  int rc = path ? write_json(path, r) : -1;
  if (!rc)
    fprintf(stderr, "kinemesh batch: %zu jobs: %zu ok, %zu failed, %zu pending -> %s\n", b->n_jobs,
            ok, failed, pending, path);
  free(path);
  cJSON_Delete(r);
  return rc;
}

/* ---- planning */

static km_batch *sort_ctx;
static int cmp_longest(const void *a, const void *b) {
  size_t i = *(const size_t *)a, j = *(const size_t *)b;
  double fi = sort_ctx->jobs[i].frames, fj = sort_ctx->jobs[j].frames;
  if (fi != fj) return fi > fj ? -1 : 1;
  return i < j ? -1 : i > j;
}

/* One process: manifest order, a segmented job's segments in its place, then its stitch. */
static int cmp_serial(const void *a, const void *b) {
  const job *x = &sort_ctx->jobs[*(const size_t *)a], *y = &sort_ctx->jobs[*(const size_t *)b];
  size_t kx = 2 * x->seq + (x->n_seg > 0), ky = 2 * y->seq + (y->n_seg > 0);
  return kx < ky ? -1 : kx > ky;
}

/* Whether every segment of segmented job jb has a report and a part that verify. */
static bool segments_done(const km_batch *b, const job *jb) {
  for (size_t k = 0; k < jb->n_seg; ++k) {
    const char *why;
    if (!job_verifies(b, &b->jobs[jb->parts[k]], &why)) return false;
  }
  return true;
}

/* Shards end at different times: whichever ends last (or --collect) stitches every segmented
 * job whose segments are all done and whose own output does not verify yet. Returns the
 * stitches that failed. */
static size_t run_ready_stitches(km_batch *b) {
  size_t failed = 0;
  for (size_t j = 0; j < b->n_manifest; ++j) {
    const char *why;
    if (!b->jobs[j].n_seg || job_verifies(b, &b->jobs[j], &why) || !segments_done(b, &b->jobs[j]))
      continue;
    failed += km_batch_run_job(b, j, NULL, NULL) != 0;
  }
  return failed;
}

size_t km_batch_plan(km_batch *b, size_t **todo) {
  *todo = malloc((b->n_jobs + 1) * sizeof **todo);
  if (!*todo) return (size_t)-1;
  size_t n = 0;
  for (size_t j = 0; j < b->n_jobs; ++j) {
    if ((int)(b->jobs[j].seq % (size_t)b->shard_n) != b->shard_i) continue;
    const char *why;
    if (!b->force && job_verifies(b, &b->jobs[j], &why)) continue;
    if (b->jobs[j].frames < 0) b->jobs[j].frames = job_frames(&b->jobs[j]);
    (*todo)[n++] = j;
  }
  sort_ctx = b;
  qsort(*todo, n, sizeof **todo, cmp_longest);
  return n;
}

/* ---- shards */

static int parse_shard(const char *s, int *i, int *n) {
  char *e1, *e2;
  long a = strtol(s, &e1, 10);
  if (e1 == s || *e1 != '/') return -1;
  long c = strtol(e1 + 1, &e2, 10);
  if (e2 == e1 + 1 || *e2 || c < 1 || c > 1000000 || a < 0 || a >= c) return -1;
  *i = (int)a, *n = (int)c;
  return 0;
}

/* --shard I/N, else Slurm's array variables, else a Kubernetes indexed job's. */
static int resolve_shard(const char *opt, int *i, int *n) {
  *i = 0, *n = 1;
  if (opt) {
    if (parse_shard(opt, i, n))
      return km_cli_error("batch", "--shard %s: expected I/N with 0 <= I < N", opt);
    return 0;
  }
  const char *id = getenv("SLURM_ARRAY_TASK_ID"), *count = getenv("SLURM_ARRAY_TASK_COUNT");
  const char *min = getenv("SLURM_ARRAY_TASK_MIN");
  char buf[64];
  if (id && *id) {
    if (!count || !*count)
      return km_cli_error("batch", "SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is "
                                   "not: give --shard I/N");
    snprintf(buf, sizeof buf, "%ld/%s", strtol(id, NULL, 10) - (min ? strtol(min, NULL, 10) : 0),
             count);
    if (parse_shard(buf, i, n))
      return km_cli_error("batch",
                          "SLURM_ARRAY_TASK_ID=%s SLURM_ARRAY_TASK_MIN=%s "
                          "SLURM_ARRAY_TASK_COUNT=%s: not a shard I/N with 0 <= I < N",
                          id, min ? min : "(unset)", count);
    return 0;
  }
  const char *k8s = getenv("JOB_COMPLETION_INDEX");
  if (k8s && *k8s) {
    const char *kc = getenv("KM_SHARD_COUNT");
    if (!kc || !*kc)
      return km_cli_error("batch", "JOB_COMPLETION_INDEX is set: set KM_SHARD_COUNT to the "
                                   "job's completions (or give --shard I/N)");
    snprintf(buf, sizeof buf, "%s/%s", k8s, kc);
    if (parse_shard(buf, i, n))
      return km_cli_error("batch", "JOB_COMPLETION_INDEX=%s KM_SHARD_COUNT=%s: not a shard I/N",
                          k8s, kc);
  }
  return 0;
}

/* ---- sbatch */

static int emit_sbatch(const km_batch *b, const char *path, int tasks, int cpus,
                       const char *time_limit) {
  char qexe[PATH_MAX * 4], qman[PATH_MAX * 4], qrep[PATH_MAX * 4];
  shell_quote(qexe, sizeof qexe, b->self);
  shell_quote(qman, sizeof qman, b->manifest);
  shell_quote(qrep, sizeof qrep, b->reports);
  if (tasks <= 0) tasks = b->n_jobs < 64 ? (int)b->n_jobs : 64;
  if (cpus <= 0) cpus = 1;
  char *s = dup_printf(
      "#!/bin/bash\n"
      "# Written by `kinemesh batch %s --emit-sbatch`: one Slurm array task per shard of the\n"
      "# manifest's %zu jobs. Submit with `sbatch THIS_FILE`; a task reads its shard from\n"
      "# SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT. Resumable: submitting again runs only the\n"
      "# jobs that failed or are missing. See docs/cluster.md.\n"
      "#SBATCH --job-name=kinemesh-batch\n"
      "#SBATCH --array=0-%d\n"
      "#SBATCH --ntasks=1\n"
      "#SBATCH --cpus-per-task=%d\n"
      "#SBATCH --time=%s\n"
      "#SBATCH --output=%s/slurm-%%A_%%a.out\n"
      "set -euo pipefail\n"
      "# threads inside a job = the cores Slurm gave the task (no oversubscription)\n"
      "export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}\n"
      "%s batch %s --reports %s\n"
      "# The batch report gathers every shard; after the array, refresh it with:\n"
      "#   sbatch --dependency=afterany:$SLURM_ARRAY_JOB_ID --wrap \"%s batch %s --reports %s "
      "--collect\"\n",
      qman, b->n_jobs, tasks - 1, cpus, time_limit ? time_limit : "04:00:00", qrep, qexe, qman,
      qrep, qexe, qman, qrep);
  if (!s) return km_cli_error("batch", "out of memory");
  int rc = 0;
  if (!strcmp(path, "-")) {
    fputs(s, stdout);
  } else {
    km_error err = {0};
    if (km_write_file_atomic(path, s, strlen(s), &err)) rc = km_cli_fail("batch", &err);
    if (!rc) {
      chmod(path, 0755);
      fprintf(stderr, "kinemesh batch: wrote %s (array of %d tasks): sbatch %s\n", path, tasks,
              path);
    }
  }
  free(s);
  return rc;
}

/* ---- the verb */

int km_cli_batch(int argc, char **argv) {
  const char *reports = NULL, *shard = NULL, *sbatch = NULL, *time_limit = NULL;
  bool dry = false, force = false, mpi = false, collect = false;
  int tasks = 0, cpus = 0;
  double timeout = 0;
  const km_cli_opt opts[] = {
      {"reports", 0, KM_OPT_STRING, &reports,
       "folder of the job reports, logs and report.json (default: MANIFEST's folder, "
       "<stem>.batch/)"},
      {"dry-run", 'n', KM_OPT_FLAG, &dry,
       "print the jobs this invocation would run (JSON lines) and run nothing"},
      {"shard", 0, KM_OPT_STRING, &shard,
       "run shard I of N (jobs whose index mod N is I; default: SLURM_ARRAY_TASK_ID/COUNT, "
       "else JOB_COMPLETION_INDEX/KM_SHARD_COUNT, else all)"},
      {"force", 0, KM_OPT_FLAG, &force, "rerun jobs that verify too"},
      {"collect", 0, KM_OPT_FLAG, &collect,
       "only gather the job reports into report.json (after the stitches whose segments are all "
       "done)"},
      {"mpi", 0, KM_OPT_FLAG, &mpi,
       "under mpirun: rank 0 hands jobs out longest first to the ranks as they free up"},
      {"mpi-timeout", 0, KM_OPT_DOUBLE, &timeout,
       "seconds without word from a rank running a job before it is taken as dead (default 30)"},
      {"emit-sbatch", 0, KM_OPT_STRING, &sbatch,
       "write a Slurm array script for the manifest to this file ('-': stdout) and stop"},
      {"tasks", 0, KM_OPT_INT, &tasks, "--emit-sbatch: array tasks (default: jobs, at most 64)"},
      {"cpus-per-task", 0, KM_OPT_INT, &cpus, "--emit-sbatch: cores per task (default 1)"},
      {"time", 0, KM_OPT_STRING, &time_limit, "--emit-sbatch: time limit (default 04:00:00)"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
      "kinemesh batch MANIFEST [--dry-run] [--shard I/N] [--mpi] [--reports DIR] [--force] "
      "[--collect] [--emit-sbatch FILE]",
      "Runs a manifest of jobs, one JSON line each:\n"
      "  {\"id\": \"s01\", \"verb\": \"reconstruct\", \"args\": [\"--template\", \"t.obj\", "
      "\"--clouds\",\n"
      "   \"s01/*.ply\", \"-o\", \"out/s01.pc2\", \"--report\", \"out/s01.json\"]}\n"
      "(verbs: reconstruct, animate, pose, avatar, transfer, precompute, bake, check), each as a\n"
      "child process `kinemesh VERB ARGS...` in the manifest's folder (relative paths resolve\n"
      "there). Each job gets a report (status, times, exact command line, checksums of its\n"
      "outputs: -o/--output/--report/--plot) and a log; report.json gathers them. A rerun skips\n"
      "the jobs whose report says ok for the same arguments and whose outputs still match.\n"
      "Exit status 1 when a job failed. See docs/cluster.md for Slurm and MPI.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("batch", "one MANIFEST is required (see --help)");
  if (timeout < 0) return km_cli_error("batch", "--mpi-timeout must be >= 0");
#ifndef KM_HAVE_MPI
  if (mpi)
    return km_cli_error("batch", "--mpi: this kinemesh was built without MPI (install "
                                 "libopenmpi-dev and rebuild); use --shard I/N instead");
#endif
  km_batch b = {.rank = -1};
  char *sbatch_abs = NULL; /* before entering the manifest's folder */
  int rc = KM_EXIT_OK;
  ssize_t len = readlink("/proc/self/exe", b.self, sizeof b.self - 1);
  if (len <= 0) return km_cli_error("batch", "cannot find this program (/proc/self/exe)");
  b.self[len] = '\0';
  char *real = realpath(pos[0], NULL);
  if (!real) return km_cli_error("batch", "%s: cannot open: %s", pos[0], strerror(errno));
  b.manifest = real;
  b.dir = strdup(real);
  if (b.dir) *strrchr(b.dir, '/') = '\0';
  if (b.dir && !b.dir[0]) strcpy(b.dir, "/");
  if (reports) {
    b.reports = absolute(reports);
  } else {
    const char *base = strrchr(real, '/') + 1;
    const char *dot = strrchr(base, '.');
    int stem = dot && dot != base ? (int)(dot - base) : (int)strlen(base);
    b.reports = dup_printf("%s/%.*s.batch", b.dir, stem, base);
  }
  if (!b.dir || !b.reports) {
    batch_free(&b);
    return km_cli_error("batch", "out of memory");
  }
  if ((rc = read_manifest(&b, b.manifest)) != 0) goto out;
  if (sbatch && strcmp(sbatch, "-") && !(sbatch_abs = absolute(sbatch))) {
    rc = km_cli_error("batch", "out of memory");
    goto out;
  }
  if (chdir(b.dir)) {
    rc = km_cli_error("batch", "%s: cannot enter: %s", b.dir, strerror(errno));
    goto out;
  }
  if (sbatch) {
    rc = emit_sbatch(&b, sbatch_abs ? sbatch_abs : sbatch, tasks, cpus, time_limit);
    goto out;
  }
  if (mpi && shard) {
    rc = km_cli_error("batch", "--mpi and --shard: give one");
    goto out;
  }
  if (!mpi && (rc = resolve_shard(shard, &b.shard_i, &b.shard_n)) != 0) goto out;
  if (mpi) b.shard_i = 0, b.shard_n = 1;
  b.force = force;
  if (!dry && !collect) {
    char *jobs = dup_printf("%s/jobs", b.reports), *logs = dup_printf("%s/logs", b.reports);
    if (!jobs || !logs || mkdir_p(jobs) || mkdir_p(logs))
      rc = km_cli_error("batch", "%s: cannot create: %s", b.reports, strerror(errno));
    free(jobs);
    free(logs);
    if (rc) goto out;
  }
  if (expand_segments(&b)) {
    rc = km_cli_error("batch", "out of memory");
    goto out;
  }
  if (collect) {
    rc = run_ready_stitches(&b) ? KM_EXIT_FAIL : KM_EXIT_OK;
    if (km_batch_write_report(&b)) rc = KM_EXIT_FAIL;
    goto out;
  }
#ifdef KM_HAVE_MPI
  if (mpi && !dry) {
    rc = km_batch_mpi(&b, timeout > 0 ? timeout : 30);
    goto out;
  }
#endif
  size_t *todo = NULL;
  size_t n = km_batch_plan(&b, &todo);
  if (n == (size_t)-1) {
    rc = km_cli_error("batch", "out of memory");
    goto out;
  }
  if (dry) {
    for (size_t k = 0; k < n; ++k) {
      const job *jb = &b.jobs[todo[k]];
      const char *why = "forced";
      if (!force) job_verifies(&b, jb, &why);
      cJSON *o = cJSON_CreateObject();
      cJSON_AddStringToObject(o, "id", jb->id);
      cJSON_AddStringToObject(o, "verb", jb->verb);
      add_string_array(o, "args", jb->args, jb->n_args);
      cJSON_AddNumberToObject(o, "frames", jb->frames);
      cJSON_AddStringToObject(o, "reason", why ? why : "forced");
      char *cmd = job_command(&b, jb);
      cJSON_AddStringToObject(o, "command", cmd ? cmd : "");
      free(cmd);
      char *s = cJSON_PrintUnformatted(o);
      if (s) printf("%s\n", s);
      free(s);
      cJSON_Delete(o);
    }
    fflush(stdout);
    fprintf(stderr, "kinemesh batch: dry run: %zu of %zu jobs to run (shard %d/%d)\n", n, b.n_jobs,
            b.shard_i, b.shard_n);
  } else {
    /* one process: in manifest order, which is what a person reading the log expects */
    sort_ctx = &b;
    qsort(todo, n, sizeof *todo, cmp_serial);
    size_t failed = 0;
    fprintf(stderr, "kinemesh batch: %zu of %zu jobs to run (shard %d/%d), %s\n", n, b.n_jobs,
            b.shard_i, b.shard_n, b.reports);
    for (size_t k = 0; k < n; ++k) {
      const job *jb = &b.jobs[todo[k]];
      if (jb->n_seg && b.shard_n > 1 && !segments_done(&b, jb)) {
        fprintf(stderr,
                "kinemesh batch: %s: its segments are not all done (other shards): the shard "
                "that ends last, or --collect, stitches it\n",
                jb->id);
        continue;
      }
      failed += km_batch_run_job(&b, todo[k], NULL, NULL) != 0;
    }
    if (b.shard_n > 1) failed += run_ready_stitches(&b);
    if (km_batch_write_report(&b)) rc = KM_EXIT_FAIL;
    if (failed) rc = KM_EXIT_FAIL;
  }
  free(todo);
out:
  free(sbatch_abs);
  batch_free(&b);
  return rc;
}
