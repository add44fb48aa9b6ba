/* kinemesh batch MANIFEST --mpi (issue 17): rank 0 plans the batch (jobs that do not verify,
 * longest first) and hands them out one at a time to the ranks as they free up, running jobs
 * itself between messages; every job is a child process of its rank (batch.c), and the job
 * reports go to a folder all ranks share. Built only when OpenMPI is found; the library never
 * links MPI.
 *
 * A rank that dies: plain MPI has no portable failure notice (ULFM is not in OpenMPI 4), so a
 * rank running a job sends a heartbeat every second and rank 0 takes a rank it has not heard
 * from for --mpi-timeout seconds as dead, reports its job failed and gives it nothing more.
 * For mpirun not to abort every rank when one is killed it needs --enable-recovery; after a
 * death the collective MPI_Finalize would wait forever for the dead rank, so rank 0 writes the
 * batch report and ends the run with MPI_Abort (docs/cluster.md). */
#include "batch.h"

#include <mpi.h>

#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

enum { TAG_DONE = 1, TAG_BEAT = 2, TAG_JOB = 3 };
enum { R_BUSY_NONE = -1, R_STOPPED = -2, R_DEAD = -3 };

typedef struct sched {
  km_batch *b;
  int size;
  const size_t *todo;
  size_t n_todo, next;
  long *running; /* per rank: the job it runs, R_BUSY_NONE when waiting, R_STOPPED, R_DEAD */
  double *last_seen;
  double timeout;
  size_t failed, dead;
} sched;

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void nap(void) { nanosleep(&(struct timespec){0, 20000000}, NULL); }

/* Gives rank r its next job, or tells it to stop. */
static void hand_out(sched *s, int r) {
  int msg = -1;
  if (s->next < s->n_todo) msg = (int)s->todo[s->next++];
  MPI_Send(&msg, 1, MPI_INT, r, TAG_JOB, MPI_COMM_WORLD);
  s->running[r] = msg >= 0 ? msg : R_STOPPED;
  s->last_seen[r] = now();
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
    if (s->running[r] == R_DEAD) continue; /* taken for dead already: its job is reported */
    s->last_seen[r] = now();
    if (st.MPI_TAG == TAG_DONE) {
      if (msg[0] >= 0 && msg[1]) ++s->failed;
      hand_out(s, r);
    }
  }
  double t = now();
  for (int r = 1; r < s->size; ++r) {
    if (s->running[r] == R_STOPPED || s->running[r] == R_DEAD) continue;
    if (t - s->last_seen[r] <= s->timeout) continue;
    char why[256];
    if (s->running[r] >= 0) {
      snprintf(why, sizeof why,
               "MPI rank %d stopped answering for %.0f s while running it (killed or its node "
               "lost)",
               r, s->timeout);
      km_batch_mark_failed(s->b, (size_t)s->running[r], why);
      fprintf(stderr, "kinemesh batch: %s: FAILED: %s\n",
              km_batch_job_id(s->b, (size_t)s->running[r]), why);
      ++s->failed;
    } else {
      fprintf(stderr, "kinemesh batch: MPI rank %d never asked for a job; taken as lost\n", r);
    }
    s->running[r] = R_DEAD;
    ++s->dead;
  }
}

static bool all_finished(const sched *s) {
  for (int r = 1; r < s->size; ++r)
    if (s->running[r] != R_STOPPED && s->running[r] != R_DEAD) return false;
  return s->next >= s->n_todo;
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
    int flag = 0, job;
    /* polling with naps: a blocking receive spins a core, which the jobs need */
    while (MPI_Iprobe(0, TAG_JOB, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE) == MPI_SUCCESS && !flag)
      nap();
    MPI_Recv(&job, 1, MPI_INT, 0, TAG_JOB, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (job < 0) break;
    beat h = {job, now()};
    msg[0] = job;
    msg[1] = km_batch_run_job(b, (size_t)job, heartbeat, &h);
    MPI_Send(msg, 2, MPI_INT, 0, TAG_DONE, MPI_COMM_WORLD);
  }
  MPI_Finalize();
  return 0;
}

int km_batch_mpi(km_batch *b, double timeout_s) {
  int provided = 0, rank = 0, size = 1;
  MPI_Init_thread(NULL, NULL, MPI_THREAD_SINGLE, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (rank != 0) return worker(b);

  sched s = {.b = b, .size = size, .timeout = timeout_s};
  size_t *todo = NULL;
  s.n_todo = km_batch_plan(b, &todo);
  s.running = malloc(sizeof *s.running * (size_t)size);
  s.last_seen = malloc(sizeof *s.last_seen * (size_t)size);
  if (s.n_todo == (size_t)-1 || !s.running || !s.last_seen) {
    fprintf(stderr, "kinemesh batch: out of memory\n");
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  s.todo = todo;
  for (int r = 0; r < size; ++r)
    s.running[r] = R_BUSY_NONE, s.last_seen[r] = now();
  fprintf(stderr, "kinemesh batch: %zu jobs to run on %d MPI ranks, longest first\n", s.n_todo,
          size);
  /* rank 0 runs jobs too (on a small allocation it is a whole worker), serving the others
   * between them and, through the tick, while its own job runs */
  for (;;) {
    service(&s);
    if (s.next < s.n_todo) {
      size_t j = s.todo[s.next++];
      s.failed += km_batch_run_job(b, j, service, &s) != 0;
      continue;
    }
    if (all_finished(&s)) break;
    nap();
  }
  int rc = km_batch_write_report(b) || s.failed ? 1 : 0;
  free(todo);
  free(s.running);
  free(s.last_seen);
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
