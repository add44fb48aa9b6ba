/* kinemesh batch (issue 17): the pieces the MPI driver (apps/mpi/batch_mpi.c, built only when
 * OpenMPI is found) shares with the serial driver (batch.c). Every job runs as a child process
 * of the same binary, in the manifest's folder, so a crash or a killed job is that job's alone. */
#ifndef KM_CLI_BATCH_H
#define KM_CLI_BATCH_H

#include <stdbool.h>
#include <stddef.h>

typedef struct km_batch km_batch; /* the manifest, its jobs and where reports go (batch.c) */

/* Called about every 20 ms while a job's process runs (rank 0's service of the other ranks, a
 * worker's heartbeat); the job's end is noticed at once. */
typedef void (*km_batch_tick)(void *user);

/* Runs job j (an index into the manifest) as a child process and writes its report. Returns 0
 * when the job succeeded and its outputs were checksummed, 1 otherwise. */
int km_batch_run_job(km_batch *b, size_t j, km_batch_tick tick, void *user);
/* Writes a failed report for job j that never finished (why: e.g. "rank 2 died"). */
void km_batch_mark_failed(km_batch *b, size_t j, const char *why);
/* Gathers every job's report into the batch report (atomically). Returns 0 when written. */
int km_batch_write_report(km_batch *b);
/* The jobs this invocation must run (its shard, less those whose report and outputs verify),
 * longest first (by frame count), into *todo (caller frees). Returns their count, or
 * (size_t)-1 when out of memory. */
size_t km_batch_plan(km_batch *b, size_t **todo);
/* The job's id (for messages). */
const char *km_batch_job_id(const km_batch *b, size_t j);
/* A segment job (one segment of a long take, `reconstruct --segment-frames`): the index of the
 * segmented job whose stitch waits for it; -1 for any other job. A segmented job is run (its
 * stitch) only after all its segments are done. */
long km_batch_job_parent(const km_batch *b, size_t j);
/* The attempt the next km_batch_run_job of job j is (its report says "attempts"): 1, or 2 when
 * the job of a lost MPI rank is run again. */
void km_batch_set_attempt(km_batch *b, size_t j, int attempt);
/* The MPI rank this process is (its job reports then say "rank"); -1 (the default) outside
 * MPI. */
void km_batch_set_rank(km_batch *b, int rank);

/* The MPI driver: rank 0 plans (km_batch_plan) and hands the jobs out, longest first, to the
 * ranks as they free up and writes the batch report; the other ranks run what they are given.
 * timeout_s: a rank that has not been heard from for that long while running a job is taken as
 * dead and its job handed to another rank once (attempt 2), reported failed if that is lost
 * too. A segmented job's stitch is handed out once its segments are done. Returns the exit status
 * of this rank. Defined only when built with MPI (KM_HAVE_MPI). */
int km_batch_mpi(km_batch *b, double timeout_s);

#endif
