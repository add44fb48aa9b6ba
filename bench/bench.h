/* The benchmark verbs of the kinemesh CLI (`kinemesh bench live|reconstruct|transfer`; `bench
 * deform` is still apps/cli/cmd_bench.c), built as the static library kinemesh_bench that the
 * CLI links. Each takes argv[0] = its sub-verb and returns an exit status, like every verb.
 * They print the papers' tables and a JSON line; they parse options with the CLI's helpers
 * (apps/cli/cli.h, target kinemesh_cli_common). The names keep the km_cli_ prefix because the
 * `bench` dispatcher (cmd_bench.c) calls them by it.
 *
 * bench_character, bench_eigen and bench_mesh_io in this folder are standalone executables
 * over the library alone. */
#ifndef KM_BENCH_H
#define KM_BENCH_H

/* bench/bench_live.c: the live server in-process, a take sent over UDP, frames read by a
 * WebSocket client on loopback; server and client latency, stage medians, frames/s. */
int km_cli_bench_live(int argc, char **argv);
/* bench/bench_reconstruct.c: simulated multi-view capture reconstructed with a template of
 * another body (Park & Lim 2014), or the D-FAUST sequences with --dfaust. */
int km_cli_bench_reconstruct(int argc, char **argv);
/* bench/bench_transfer.c: Table 2 of Lifkooee et al. (avatar pose transfer). */
int km_cli_bench_transfer(int argc, char **argv);

#endif
