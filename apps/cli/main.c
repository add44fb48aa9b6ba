/* kinemesh <verb>: a thin command-line layer over libkinemesh. */
#include "bench.h"
#include "cli.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

static const km_cli_verb VERBS[] = {
    {"info", "print topology counts and extent of a mesh, or describe a .glb/.pc2", km_cli_info},
    {"convert", "convert a mesh between OBJ, PLY, OFF and STL, or from glTF (by extension)",
     km_cli_convert},
    {"eigen", "smallest eigenvalues of the cotangent Laplacian (ARPACK shift-invert)",
     km_cli_eigen},
    {"gen", "generate a procedural character (gen character) or a motion take (gen motion)",
     km_cli_gen},
    {"pose", "pose a character by linear blend skinning along a take and write an animation",
     km_cli_pose},
    {"bake", "any mesh animation (.glb/.pc2/frames) -> skinned .glb (skinning decomposition)",
     km_cli_bake},
    {"precompute", "build and cache the reduced deformation model of a mesh", km_cli_precompute},
    {"animate", "puppetry: drive a mesh from a skeleton take through a rig -> .glb/.pc2/frames",
     km_cli_animate},
    {"live", "live puppetry server: tracker in (OSC/UDP/replay), mesh out to a browser page",
     km_cli_live},
    {"vmc", "VMC protocol: send a motion (take/BVH/CSV) as VMC bundles (vmc send)", km_cli_vmc},
    {"transfer", "avatar pose transfer: the source takes the template's pose (same connectivity)",
     km_cli_transfer},
    {"posedb", "pose database: build (descriptor, CART selection, SVM) and query", km_cli_posedb},
    {"avatar", "motion generation: recognise, retrieve, transfer every k frames, morph between",
     km_cli_avatar},
    {"reconstruct", "point clouds -> mesh animation: register a rigged template to every frame",
     km_cli_reconstruct},
    {"rig", "automatic rigging: skeleton, skin, landmarks and puppetry handles for any mesh",
     km_cli_rig},
    {"batch", "run a manifest of jobs (JSON lines): resumable, sharded for Slurm, MPI",
     km_cli_batch},
    {"pick", "vertex ids and positions nearest to a point (for rigs and scripts)", km_cli_pick},
    {"check", "where an animation stretches, folds or jumps: every frame against the rest mesh",
     km_cli_check},
    {"bench", "benchmarks printing the papers' tables (bench deform)", km_bench},
};

static void usage(FILE *f) {
  fprintf(f, "kinemesh %s — animate any triangle mesh from captured human motion\n\n",
          km_version());
  fprintf(
      f, "usage: kinemesh <verb> [options]   (kinemesh <verb> --help for its options)\n\nverbs:\n");
  for (size_t i = 0; i < sizeof VERBS / sizeof VERBS[0]; ++i)
    fprintf(f, "  %-10s %s\n", VERBS[i].name, VERBS[i].summary);
}

/* SIGINT/SIGTERM: remove the temporaries of the outputs being written (the old outputs stay
 * as they were), then die of the signal. `live` installs its own handler (clean stop). */
static void on_fatal_signal(int sig) {
  km_remove_temporaries();
  signal(sig, SIG_DFL);
  raise(sig);
}

/* A verb's report on standard output that could not be written (a full disk, a closed pipe)
 * is a failure, not exit 0 with nothing written. */
static int finish_stdout(int rc) {
  errno = 0;
  if (fflush(stdout) != 0 || ferror(stdout)) {
    fprintf(stderr, "kinemesh: cannot write standard output: %s\n",
            errno ? strerror(errno) : "write error");
    return rc ? rc : 1;
  }
  return rc;
}

int main(int argc, char **argv) {
  km_cli_install_logger();
  signal(SIGINT, on_fatal_signal);
  signal(SIGTERM, on_fatal_signal);
  if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") ||
      !strcmp(argv[1], "help")) {
    usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  if (!strcmp(argv[1], "--version")) {
    printf("kinemesh %s\n", km_version());
    return 0;
  }
  for (size_t i = 0; i < sizeof VERBS / sizeof VERBS[0]; ++i)
    if (!strcmp(argv[1], VERBS[i].name)) return finish_stdout(VERBS[i].run(argc - 1, argv + 1));
  fprintf(stderr, "kinemesh: unknown verb '%s'\n\n", argv[1]);
  usage(stderr);
  return 2;
}
