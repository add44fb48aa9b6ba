/* kinemesh posedb: the pose database of avatar pose transfer (Lifkooee et al. 2019).
 *   kinemesh posedb build --meshes GLOB --labels CSV -o DB   descriptor, CART selection, SVM
 *                                    (or CLASS=MESH[@GROUP]... positionally)
 *   kinemesh posedb query DB --landmarks-xyz TRACK           recognise every frame of a track
 * Landmarks come from --landmarks LM.json or the mesh's rig sidecar (<stem>.rig.json). */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

/* posedb build CLASS=MESH[@GROUP]... */
static int posedb_build(int argc, char **argv) {
  const char *out = NULL, *lm_path = NULL, *kernel = "rbf", *mesh_glob = NULL, *labels_csv = NULL;
  size_t features = 60;
  int folds = 0;
  const km_cli_opt opts[] = {
      {"meshes", 0, KM_OPT_STRING, &mesh_glob, "the database meshes: a quoted glob or a directory"},
      {"labels", 0, KM_OPT_STRING, &labels_csv, "CSV lines 'mesh,class[,subject]' for --meshes"},
      {"output", 'o', KM_OPT_STRING, &out, "output database (.kmposedb)"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path,
       "LM.json with 16 landmark vertices and mirrors (default: the first mesh's rig sidecar)"},
      {"features", 'd', KM_OPT_SIZE, &features, "selected angles d (default 60)"},
      {"kernel", 0, KM_OPT_STRING, &kernel, "rbf (default) or linear"},
      {"folds", 0, KM_OPT_INT, &folds,
       "k-fold cross-validation when no @GROUP is given (default 5, 1: none)"},
  };
  enum { MAX_POS = 100000 };
  const char **pos = malloc(MAX_POS * sizeof *pos);
  if (!pos) return km_cli_error("posedb build", "out of memory");
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, MAX_POS, &n_pos,
      "kinemesh posedb build --meshes 'DIR/*.ply' --labels labels.csv --landmarks LM.json -o DB",
      "A pose database from meshes of one connectivity labelled with pose classes (GROUP: the\n"
      "subject, for leave-one-subject-out cross-validation). Prints the cross-validated\n"
      "accuracy for the chosen number of features.");
  if (r <= 0) {
    free(pos);
    return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  }
  int rc = KM_EXIT_OK;
  km_error err = {0};
  km_pose_set set = {0};
  km_posedb *db = NULL;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t nl = 0;
  km_mesh *meshes = NULL;
  km_status ss;
  if (mesh_glob || labels_csv) {
    if (!mesh_glob || !labels_csv) {
      free(pos);
      return km_cli_error("posedb build", "--meshes and --labels go together");
    }
    ss = km_pose_set_from_labels(mesh_glob, labels_csv, pos, (size_t)n_pos, &set, &err);
  } else {
    ss = km_pose_set_from_entries(pos, (size_t)n_pos, &set, &err);
  }
  free(pos);
  if (ss != KM_OK) return km_cli_fail("posedb build", &err);
  if (set.n_unlabelled) {
    /* A mesh the labels do not name is left out: said, not silent. */
    char names[512] = "";
    for (size_t k = 0; k < set.n_unlabelled && k < 5; ++k) {
      const char *base = strrchr(set.unlabelled[k], '/');
      size_t len = strlen(names);
      snprintf(names + len, sizeof names - len, "%s%s", k ? ", " : "",
               base ? base + 1 : set.unlabelled[k]);
    }
    fprintf(stderr,
            "kinemesh posedb build: warning: %zu of the %zu meshes of %s have no line in %s "
            "and are left out (%s%s)\n",
            set.n_unlabelled, set.n_listed, mesh_glob, labels_csv, names,
            set.n_unlabelled > 5 ? ", ..." : "");
  }
  if (set.n_duplicates)
    fprintf(stderr,
            "kinemesh posedb build: warning: %zu line(s) of %s label a mesh already labelled "
            "and are ignored (the first line wins)\n",
            set.n_duplicates, labels_csv);
  size_t n = set.n;
  if (!out || n < 2) {
    rc = km_cli_error("posedb build", "need -o OUTPUT and at least two CLASS=MESH arguments");
    goto done;
  }
  if (!(meshes = calloc(n, sizeof *meshes))) {
    rc = km_cli_error("posedb build", "out of memory");
    goto done;
  }
  for (size_t i = 0; i < n; ++i) {
    if (km_mesh_read(set.paths[i], &meshes[i], &err)) {
      rc = km_cli_fail("posedb build", &err);
      goto done;
    }
    if (i == 0 && km_cli_load_landmarks(lm_path, set.paths[0], meshes[0].n_vertices, lm,
                                        KM_POSE_MAX_LANDMARKS, &nl, &err)) {
      rc = km_cli_fail("posedb build", &err);
      goto done;
    }
  }
  km_posedb_options po = {0};
  po.features = features;
  po.cv_folds = folds;
  po.kernel = !strcmp(kernel, "linear") ? KM_SVM_LINEAR : KM_SVM_RBF;
  po.progress = km_cli_progress("posedb");
  km_posedb_report rep;
  km_status bs =
      km_posedb_build(meshes, n, set.labels, set.n_classes, (const char *const *)set.class_names,
                      set.groups, lm, nl, &po, &db, &rep, &err);
  /* templates named by their file names, so that a query says which mesh it picked */
  if (!bs) bs = km_posedb_set_template_names(db, (const char *const *)set.names, &err);
  if (bs || km_posedb_save(db, out, &err)) {
    km_cli_progress_done();
    rc = km_cli_fail("posedb build", &err);
    goto done;
  }
  km_cli_progress_done();
  fprintf(stderr,
          "kinemesh posedb build: %zu meshes, %zu classes, d = %zu; cross-validated accuracy "
          "%.3f over %zu folds (eq. 8, one-vs-rest: %.3f); %.0f ms -> %s\n",
          rep.samples, rep.classes, rep.features, rep.cv_accuracy, rep.cv_folds,
          rep.cv_accuracy_eq8, rep.build_ms, out);
done:
  for (size_t i = 0; meshes && i < set.n; ++i)
    km_mesh_free(&meshes[i]);
  free(meshes);
  km_pose_set_free(&set);
  km_posedb_free(&db);
  return rc;
}

/* Track landmark index of each database landmark, by name. */
static int map_track(const km_posedb *db, const km_track *t, int32_t *map, const char *verb) {
  size_t nl = km_posedb_landmark_count(db);
  const km_landmark *lm = km_posedb_landmarks(db);
  for (size_t a = 0; a < nl; ++a) {
    map[a] = -1;
    for (size_t b = 0; b < t->n_landmarks; ++b)
      if (!strcmp(t->names[b], lm[a].name)) map[a] = (int32_t)b;
    if (map[a] < 0) return km_cli_error(verb, "the track has no landmark '%s'", lm[a].name);
  }
  return KM_EXIT_OK;
}

static int posedb_query(int argc, char **argv) {
  const char *xyz = NULL;
  const km_cli_opt opts[] = {{"landmarks-xyz", 0, KM_OPT_STRING, &xyz,
                              "tracked landmark positions: a track file (.json/.csv), one frame "
                              "or many"}};
  const char *pos[2];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, 1, pos, 2, &n_pos, "kinemesh posedb query DB --landmarks-xyz FRAME.json",
      "Recognises the pose of every frame of a track file (.json/.csv; a single\n"
      "frame is a track of one frame) and prints frame, class, template and time.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (xyz && n_pos < 2) pos[n_pos++] = xyz;
  if (n_pos != 2) return km_cli_error("posedb query", "expected DB and --landmarks-xyz FILE");
  km_error err = {0};
  km_posedb *db = NULL;
  km_track t = {0};
  int rc = KM_EXIT_OK;
  int32_t map[KM_POSE_MAX_LANDMARKS];
  if (km_posedb_load(pos[0], &db, &err) || km_track_read(pos[1], &t, &err)) {
    rc = km_cli_fail("posedb query", &err);
    goto done;
  }
  if ((rc = map_track(db, &t, map, "posedb query")) != KM_EXIT_OK) goto done;
  size_t nl = km_posedb_landmark_count(db);
  double P[3 * KM_POSE_MAX_LANDMARKS], ms = 0;
  size_t done_frames = 0;
  printf("frame,class,template,distance,ms,template_name\n");
  for (size_t f = 0; f < t.n_frames; ++f) {
    for (size_t a = 0; a < nl; ++a)
      memcpy(P + 3 * a, t.positions + (f * t.n_landmarks + (size_t)map[a]) * 3, 3 * sizeof(double));
    km_pose_match m;
    if (km_posedb_query(db, P, &m, &err)) {
      printf("%zu,,,,,\n", f); /* untracked landmark: no answer for this frame */
      continue;
    }
    const char *cn = km_posedb_class_name(db, (size_t)m.label);
    printf("%zu,%s,%zu,%.6g,%.4f,%s\n", f, *cn ? cn : "?", m.template_index, m.distance, m.ms,
           km_posedb_template_name(db, m.template_index));
    ms += m.ms;
    ++done_frames;
  }
  fprintf(stderr, "kinemesh posedb query: %zu of %zu frames recognised, %.4f ms per query\n",
          done_frames, t.n_frames, done_frames ? ms / done_frames : 0.0);
done:
  km_posedb_free(&db);
  km_track_free(&t);
  return rc;
}

int km_cli_posedb(int argc, char **argv) {
  if (argc >= 2 && !strcmp(argv[1], "build")) return posedb_build(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "query")) return posedb_query(argc - 1, argv + 1);
  fprintf(argc >= 2 && strcmp(argv[1], "-h") && strcmp(argv[1], "--help") ? stderr : stdout,
          "usage: kinemesh posedb build --meshes 'DIR/*.ply' --labels labels.csv -o DB\n"
          "       kinemesh posedb query DB --landmarks-xyz FRAME.json\n");
  return argc >= 2 && (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) ? KM_EXIT_OK
                                                                             : KM_EXIT_USAGE;
}
