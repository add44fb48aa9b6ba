/* kinemesh batch MANIFEST --mpi (issue 17): rank 0 plans the batch (jobs that do not verify,
 * longest first) and hands them out one at a time to the ranks as they free up, running jobs
 * itself between messages; every job is a child process of its rank (batch.c), and the job
 * reports go to a folder all ranks share. Built only when OpenMPI is found; the library never
 * links MPI.
 *
 * A rank that dies: plain MPI has no portable failure notice (ULFM is not in OpenMPI 4), so a
 * rank running a job sends a heartbeat every second and rank 0 takes a rank it has not heard
 * from for --mpi-timeout seconds as dead and gives it nothing more; its job goes to another
 * rank once (attempt 2) and is reported failed only when that one is lost too. The second
 * attempt goes to a worker rank, not to rank 0 (whose loss would end the batch) while a worker
 * lives; so that one is there to take it, a worker with nothing left to do waits (instead of
 * stopping) while another worker still runs a job that could be lost.
 *
 * Threads: without OMP_NUM_THREADS, every job gets the cores of its rank (a rank bound to a
 * core: 1; ranks not bound: the node's cores over its ranks), never a thread per core of the
 * node in every rank.
 *
 * One long take: its segment jobs are handed out like any other, its stitch once they have
 * all finished (a rank with nothing else to do waits for it).
 * For mpirun not to abort every rank when one is killed it needs --enable-recovery; after a
 * death the collective MPI_Finalize would wait forever for the dead rank, so rank 0 writes the
 * batch report and ends the run with MPI_Abort (docs/cluster.md). */
#include "batch.h"

#include <mpi.h>

#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* sched_getaffinity */
#endif
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

enum { TAG_DONE = 1, TAG_BEAT = 2, TAG_JOB = 3 };
/* a rank's state besides the todo position of the job it runs */
enum { R_BUSY_NONE = -1, R_STOPPED = -2, R_DEAD = -3, R_WAITING = -4 };

typedef struct sched {
  km_batch *b;
  int size;
  const size_t *todo; /* job indices, longest first */
  size_t n_todo;
  char *taken;      /* per todo position: handed out (or run by rank 0) */
  int *attempt;     /* per todo position: 1, or 2 once reassigned */
  size_t *waits;    /* per todo position: segments of that (segmented) job not finished */
  long *parent_pos; /* per todo position: todo position of the job its segment feeds, or -1 */
  long *running;    /* per rank: the todo position it runs, or an R_ state */
  double *last_seen;
  double timeout;
  size_t failed, dead, reassigned;
} sched;

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void nap(void) { nanosleep(&(struct timespec){0, 20000000}, NULL); }

static bool worker_alive(const sched *s) {
  for (int r = 1; r < s->size; ++r)
    if (s->running[r] != R_DEAD) return true;
  return false;
}

/* The first job not handed out whose segments (if any) are all finished, for rank r; -1 when
 * none now. A job whose rank was lost (attempt 2) is not rank 0's while a worker lives. */
static long take_next(sched *s, int r) {
  const bool second_ok = r != 0 || !worker_alive(s);
  for (size_t t = 0; t < s->n_todo; ++t)
    if (!s->taken[t] && !s->waits[t] && (s->attempt[t] < 2 || second_ok)) {
      s->taken[t] = 1;
      return (long)t;
    }
  return -1;
}

/* Whether a worker rank runs a job (which may yet be lost and handed out again). */
static bool worker_busy(const sched *s) {
  for (int r = 1; r < s->size; ++r)
    if (s->running[r] >= 0) return true;
  return false;
}

static bool all_taken(const sched *s) {
  for (size_t t = 0; t < s->n_todo; ++t)
    if (!s->taken[t]) return false;
  return true;
}

/* The job at todo position t has finished (ok or failed for good): its stitch may be due. */
static void finished(sched *s, long t, int failed) {
  s->failed += failed != 0;
  if (s->parent_pos[t] >= 0) --s->waits[s->parent_pos[t]];
}

/* Gives rank r its next job, tells it to stop when every job is handed out and no other
 * worker runs one, or (a stitch waiting for segments still running, a job that may yet come
 * back from a lost rank) leaves it waiting for the next service. */
static void hand_out(sched *s, int r) {
  long t = take_next(s, r);
  s->last_seen[r] = now();
  s->running[r] = R_WAITING; /* not busy, for worker_busy */
  if (t < 0 && (!all_taken(s) || worker_busy(s))) return;
  int msg[2] = {t >= 0 ? (int)s->todo[t] : -1, t >= 0 ? s->attempt[t] : 0};
  MPI_Send(msg, 2, MPI_INT, r, TAG_JOB, MPI_COMM_WORLD);
  s->running[r] = t >= 0 ? t : R_STOPPED;
}

/* Rank 0's bookkeeping: answers every message waiting, then looks for silent ranks. */
static void service(void *user) {
  sched *s = user;
  for (;;) {
    int flag = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st);
    if (!flag) break;
    int r = st.MPI_SOURCE, msg[2] = {0, 0};
    MPI_Recv(msg, st.MPI_TAG == TAG_DONE ? 2 : 1, MPI_INT, r, st.MPI_TAG, MPI_COMM_WORLD,
             MPI_STATUS_IGNORE);
    if (s->running[r] == R_DEAD) continue; /* taken for dead already: its job is dealt with */
    s->last_seen[r] = now();
    if (st.MPI_TAG == TAG_DONE) {
      if (s->running[r] >= 0) finished(s, s->running[r], msg[1]);
      hand_out(s, r);
    }
  }
  for (int r = 1; r < s->size; ++r)
    if (s->running[r] == R_WAITING) hand_out(s, r);
  double t = now();
  for (int r = 1; r < s->size; ++r) {
    const long run = s->running[r];
    if (run == R_STOPPED || run == R_DEAD || run == R_WAITING) continue;
    if (t - s->last_seen[r] <= s->timeout) continue;
    s->running[r] = R_DEAD;
    ++s->dead;
    if (run < 0) {
      fprintf(stderr, "kinemesh batch: MPI rank %d never asked for a job; taken as lost\n", r);
      continue;
    }
    const size_t j = s->todo[run];
    if (s->attempt[run] < 2) {
      /* once: a node lost is not the job's fault; a job that kills its rank twice is */
      s->attempt[run] = 2;
      s->taken[run] = 0;
      ++s->reassigned;
      fprintf(stderr,
              "kinemesh batch: %s: MPI rank %d stopped answering for %.0f s while running it "
              "(killed or its node lost): handing it to another rank (attempt 2)\n",
              km_batch_job_id(s->b, j), r, s->timeout);
      continue;
    }
    char why[256];
    snprintf(why, sizeof why,
             "MPI rank %d stopped answering for %.0f s while running it (killed or its node "
             "lost), the second rank it was given",
             r, s->timeout);
    km_batch_set_attempt(s->b, j, 2);
    km_batch_mark_failed(s->b, j, why);
    fprintf(stderr, "kinemesh batch: %s: FAILED: %s\n", km_batch_job_id(s->b, j), why);
    finished(s, run, 1);
  }
}

static bool all_finished(const sched *s) {
  for (int r = 1; r < s->size; ++r)
    if (s->running[r] != R_STOPPED && s->running[r] != R_DEAD) return false;
  return all_taken(s);
}

typedef struct beat {
  int job;
  double last;
} beat;

static void heartbeat(void *user) {
  beat *h = user;
  double t = now();
  if (t - h->last < 1.0) return;
  h->last = t;
  MPI_Send(&h->job, 1, MPI_INT, 0, TAG_BEAT, MPI_COMM_WORLD);
}

static int worker(km_batch *b) {
  int msg[2] = {-1, 0};
  MPI_Send(msg, 2, MPI_INT, 0, TAG_DONE, MPI_COMM_WORLD); /* ready */
  for (;;) {
    int flag = 0, got[2];
    /* polling with naps: a blocking receive spins a core, which the jobs need */
    while (MPI_Iprobe(0, TAG_JOB, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE) == MPI_SUCCESS && !flag)
      nap();
    MPI_Recv(got, 2, MPI_INT, 0, TAG_JOB, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    const int job = got[0];
    if (job < 0) break;
    km_batch_set_attempt(b, (size_t)job, got[1]);
    beat h = {job, now()};
    msg[0] = job;
    msg[1] = km_batch_run_job(b, (size_t)job, heartbeat, &h);
    MPI_Send(msg, 2, MPI_INT, 0, TAG_DONE, MPI_COMM_WORLD);
  }
  MPI_Finalize();
  return 0;
}

/* Threads per job when OMP_NUM_THREADS is not set: the cores this rank may run on when it is
 * bound to fewer than the node's, else the node's cores over the ranks on the node (at least
 * 1). Set in the environment the jobs inherit; returns it (0: left as the user set it). */
static int threads_per_job(void) {
  /* the ranks on this node: a collective, so every rank calls it (the environment may differ
   * from node to node) */
  MPI_Comm node;
  int local = 1;
  if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) ==
      MPI_SUCCESS) {
    MPI_Comm_size(node, &local);
    MPI_Comm_free(&node);
  }
  const char *env = getenv("OMP_NUM_THREADS");
  if (env && *env) return 0;
  long cores = sysconf(_SC_NPROCESSORS_ONLN);
  if (cores < 1) cores = 1;
  long mine = cores;
#ifdef __linux__
  cpu_set_t set;
  if (!sched_getaffinity(0, sizeof set, &set)) mine = CPU_COUNT(&set);
#endif
  long t = mine < cores ? mine : cores / (local > 0 ? local : 1);
  if (t < 1) t = 1;
  char buf[32];
  snprintf(buf, sizeof buf, "%ld", t);
  setenv("OMP_NUM_THREADS", buf, 1);
  return (int)t;
}

int km_batch_mpi(km_batch *b, double timeout_s) {
  int provided = 0, rank = 0, size = 1;
  MPI_Init_thread(NULL, NULL, MPI_THREAD_SINGLE, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  /* a send to a rank that died must not end the batch (rank 0 tells waiting ranks to stop) */
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  km_batch_set_rank(b, rank);
  const int threads = threads_per_job(); /* collective: every rank */
  if (rank != 0) return worker(b);
  if (threads > 0)
    fprintf(stderr,
            "kinemesh batch: OMP_NUM_THREADS not set: %d thread(s) per job (this rank's cores)\n",
            threads);

  sched s = {.b = b, .size = size, .timeout = timeout_s};
  size_t *todo = NULL;
  s.n_todo = km_batch_plan(b, &todo);
  const size_t nt = s.n_todo == (size_t)-1 ? 0 : s.n_todo;
  s.running = malloc(sizeof *s.running * (size_t)size);
  s.last_seen = malloc(sizeof *s.last_seen * (size_t)size);
  s.taken = calloc(nt + 1, 1);
  s.attempt = malloc(sizeof *s.attempt * (nt + 1));
  s.waits = calloc(nt + 1, sizeof *s.waits);
  s.parent_pos = malloc(sizeof *s.parent_pos * (nt + 1));
  if (s.n_todo == (size_t)-1 || !s.running || !s.last_seen || !s.taken || !s.attempt || !s.waits ||
      !s.parent_pos) {
    fprintf(stderr, "kinemesh batch: out of memory\n");
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  s.todo = todo;
  /* a segment that verified before is not in the plan: its stitch waits only for the others */
  for (size_t t = 0; t < nt; ++t) {
    s.attempt[t] = 1;
    s.parent_pos[t] = -1;
    const long p = km_batch_job_parent(b, todo[t]);
    for (size_t q = 0; p >= 0 && q < nt; ++q)
      if (todo[q] == (size_t)p) s.parent_pos[t] = (long)q, ++s.waits[q];
  }
  for (int r = 0; r < size; ++r)
    s.running[r] = R_BUSY_NONE, s.last_seen[r] = now();
  fprintf(stderr, "kinemesh batch: %zu jobs to run on %d MPI ranks, longest first\n", s.n_todo,
          size);
  /* rank 0 runs jobs too (on a small allocation it is a whole worker), serving the others
   * between them and, through the tick, while its own job runs */
  for (;;) {
    service(&s);
    const long t = take_next(&s, 0);
    if (t >= 0) {
      km_batch_set_attempt(b, todo[t], s.attempt[t]);
      finished(&s, t, km_batch_run_job(b, todo[t], service, &s));
      continue;
    }
    if (all_finished(&s)) break;
    nap();
  }
  int rc = km_batch_write_report(b) || s.failed ? 1 : 0;
  free(todo);
  free(s.running);
  free(s.last_seen);
  free(s.taken);
  free(s.attempt);
  free(s.waits);
  free(s.parent_pos);
  if (s.dead) {
    /* every live rank has been told to stop; MPI_Finalize, a collective, would wait for the
     * dead one forever (in every rank), so end them all here */
    fprintf(stderr,
            "kinemesh batch: %zu MPI rank(s) lost; the report is written, ending the run with "
            "MPI_Abort (MPI_Finalize would wait for them). Rerun the batch to complete the failed "
            "jobs.\n",
            s.dead);
    fflush(NULL);
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  MPI_Finalize();
  return rc;
}
