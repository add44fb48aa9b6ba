/* The benchmark verbs of the kinemesh CLI (`kinemesh bench deform|live|reconstruct|transfer`),
 * built as the static library kinemesh_bench that the CLI links. Each takes argv[0] = its
 * sub-verb and returns an exit status, like every verb. They print the papers' tables (medians
 * of repeats, machine named) and, with --json, one JSON object per row; they parse options
 * with the CLI's helpers (apps/cli/cli.h, target kinemesh_cli_common).
 *
 * bench_character, bench_eigen and bench_mesh_io in this folder are standalone executables
 * over the library alone. */
#ifndef KM_BENCH_H
#define KM_BENCH_H

#include "kinemesh.h"

#include <stddef.h>

/* `kinemesh bench <what> ...`: dispatches to the verbs below (bench/bench.c). */
int km_bench(int argc, char **argv);
/* "<CPU model>, <n> cores" for the table headers (bench/bench.c). */
void km_bench_machine(char *out, size_t n);
/* This program's own path (/proc/self/exe), for a bench that runs its verbs in child
 * processes, as a user runs them: false, having printed why (prefixed by verb), when it cannot
 * be found or holds a quote (the shell lines quote it with '). */
bool km_bench_self(const char *verb, char *out, size_t n);
/* A --json row of a bench over meshes (bench/bench.c): {"mesh": spec, "machine": machine,
 * "n_ver": n_ver}, for the bench to add its columns to; km_bench_row_print prints it on one
 * line and deletes it. NULL when out of memory (km_bench_row_print(NULL) prints nothing). */
struct cJSON *km_bench_row(const char *spec, const char *machine, size_t n_ver);
void km_bench_row_print(struct cJSON *row);
/* A bench's mesh (bench/bench.c): SPEC is a mesh file (read as it is), or "character:N" for
 * the procedural character of about N vertices (*procedural true: in kinemesh's frame). */
km_status km_bench_mesh(const char *spec, km_mesh *m, bool *procedural, km_error *err);
/* bench/bench_deform.c: Table 1 of Wu, Lu & Song (2012). */
int km_bench_deform(int argc, char **argv);

/* bench/bench_live.c: the live server in-process, a take sent over UDP, frames read by a
 * WebSocket client on loopback; server and client latency, stage medians, frames/s. */
int km_bench_live(int argc, char **argv);
/* bench/bench_reconstruct.c: simulated multi-view capture reconstructed with a template of
 * another body (Park & Lim 2014), or the D-FAUST sequences with --dfaust. */
int km_bench_reconstruct(int argc, char **argv);
/* bench/bench_transfer.c: Table 2 of Lifkooee et al. (avatar pose transfer). */
int km_bench_transfer(int argc, char **argv);
/* bench/bench_rig.c: time of automatic rigging (km_autorig) at 10k, 50k, 100k vertices. */
int km_bench_rig(int argc, char **argv);
/* bench/bench_motion.c (issue 12): real takes on auto-rigged meshes through puppetry,
 * translation-only vs rotating handles: stretch, folds, jumps, floor, per-frame time. */
int km_bench_motion(int argc, char **argv);
/* bench/bench_batch.c (issue 17): kinemesh batch throughput with 1 and 2 ranks, serial parts,
 * and the projected wall time of a Dynamic FAUST-sized archive on 8, 64, 512 ranks. */
int km_bench_batch(int argc, char **argv);
/* bench/bench_export.c (issue 16): size, error and time of each glTF export kind (per-frame
 * morphs, skinned by SSDR) of a mesh animation. */
int km_bench_export(int argc, char **argv);
/* bench/bench_start.c: `kinemesh animate`'s wall time on a short take, cold (empty cache
 * folder) and warm (its reduced model and stretch bound read back). */
int km_bench_start(int argc, char **argv);

#endif
