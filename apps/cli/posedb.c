/* kinemesh posedb: the pose database of avatar pose transfer (Lifkooee et al. 2019).
 *   kinemesh posedb build --meshes GLOB --labels CSV -o DB   descriptor, CART selection, SVM
 *                                    (or CLASS=MESH[@GROUP]... positionally)
 *   kinemesh posedb query DB --landmarks-xyz TRACK           recognise every frame of a track
 * Landmarks come from --landmarks LM.json or the mesh's rig sidecar (<stem>.rig.json). */
#include "cli.h"

#include <glob.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

/* posedb build CLASS=MESH[@GROUP]... */
/* --meshes GLOB --labels CSV -> "CLASS=PATH[@GROUP]" entries. The CSV has lines
 * "mesh,class[,subject]" (an optional header; `mesh` matches a listed file by path or by
 * base name). Entries are heap strings appended to pos; returns how many, -1 after an error. */
static int cmp_path(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

static bool is_mesh_ext(const char *path) {
  const char *dot = strrchr(path, '.');
  return dot && (!strcasecmp(dot, ".obj") || !strcasecmp(dot, ".ply") || !strcasecmp(dot, ".off"));
}

/* The mesh files of a directory (.obj .ply .off) or of a glob, sorted; NULL after an error. */
static char **list_meshes(const char *pattern, size_t *n) {
  *n = 0;
  struct stat st;
  bool dir = stat(pattern, &st) == 0 && S_ISDIR(st.st_mode);
  char pat[4096];
  snprintf(pat, sizeof pat, dir ? "%s/*" : "%s", pattern);
  glob_t g;
  int r = glob(pat, 0, NULL, &g);
  if (r != 0 && r != GLOB_NOMATCH) {
    km_cli_error("posedb build", "--meshes '%s': cannot list the files", pattern);
    return NULL;
  }
  char **list = calloc(r == 0 && g.gl_pathc ? g.gl_pathc : 1, sizeof *list);
  for (size_t i = 0; list && r == 0 && i < g.gl_pathc; ++i) {
    if (stat(g.gl_pathv[i], &st) != 0 || S_ISDIR(st.st_mode) || !is_mesh_ext(g.gl_pathv[i]))
      continue;
    if (!(list[*n] = strdup(g.gl_pathv[i]))) break;
    ++*n;
  }
  if (r == 0) globfree(&g);
  if (!list || !*n) {
    km_paths_free(&list, *n);
    km_cli_error("posedb build", "--meshes '%s' matched no mesh files (.obj .ply .off)", pattern);
    return NULL;
  }
  qsort(list, *n, sizeof *list, cmp_path);
  return list;
}

static int labelled_meshes(const char *glob_pattern, const char *labels_path, const char **pos,
                           int n_pos, int max_pos, char ***owned, size_t *n_owned) {
  size_t np = 0;
  char **paths = list_meshes(glob_pattern, &np);
  if (!paths) return -1;
  bool *used = calloc(np, sizeof *used);
  if (!used) {
    km_paths_free(&paths, np);
    km_cli_error("posedb build", "out of memory");
    return -1;
  }
  FILE *f = fopen(labels_path, "r");
  if (!f) {
    km_paths_free(&paths, np);
    free(used);
    km_cli_error("posedb build", "%s: cannot open the labels file", labels_path);
    return -1;
  }
  *owned = calloc(np ? np : 1, sizeof **owned);
  char line[4096];
  int line_no = 0, rc = 0;
  while (*owned && fgets(line, sizeof line, f)) {
    ++line_no;
    line[strcspn(line, "\r\n")] = '\0';
    char *fields[3] = {NULL, NULL, NULL};
    int nf = 0;
    for (char *tok = strtok(line, ",;\t"); tok && nf < 3; tok = strtok(NULL, ",;\t")) {
      while (*tok == ' ')
        ++tok;
      fields[nf++] = tok;
    }
    if (nf == 0 || fields[0][0] == '#') continue;
    if (nf < 2) {
      km_cli_error("posedb build", "%s:%d: expected 'mesh,class[,subject]'", labels_path, line_no);
      rc = -1;
      break;
    }
    size_t k = 0;
    for (; k < np; ++k) {
      const char *base = strrchr(paths[k], '/');
      if (!strcmp(paths[k], fields[0]) || !strcmp(base ? base + 1 : paths[k], fields[0])) break;
    }
    if (k == np) {
      if (line_no == 1) continue; /* a header line */
      km_cli_error("posedb build", "%s:%d: '%s' is not among the meshes of %s", labels_path,
                   line_no, fields[0], glob_pattern);
      rc = -1;
      break;
    }
    if (n_pos >= max_pos || *n_owned >= np) break;
    used[k] = true;
    size_t len = strlen(fields[1]) + strlen(paths[k]) + (fields[2] ? strlen(fields[2]) : 0) + 4;
    char *e = malloc(len);
    if (!e) break;
    snprintf(e, len, "%s=%s%s%s", fields[1], paths[k], fields[2] ? "@" : "",
             fields[2] ? fields[2] : "");
    (*owned)[(*n_owned)++] = e;
    pos[n_pos++] = e;
  }
  fclose(f);
  if (rc == 0) {
    /* A mesh the labels do not name is left out: said, not silent. */
    size_t unlabelled = 0;
    char names[512] = "";
    for (size_t k = 0; k < np; ++k) {
      if (used[k]) continue;
      if (unlabelled < 5) {
        const char *base = strrchr(paths[k], '/');
        size_t len = strlen(names);
        snprintf(names + len, sizeof names - len, "%s%s", unlabelled ? ", " : "",
                 base ? base + 1 : paths[k]);
      }
      ++unlabelled;
    }
    if (unlabelled)
      fprintf(stderr,
              "kinemesh posedb build: warning: %zu of the %zu meshes of %s have no line in %s "
              "and are left out (%s%s)\n",
              unlabelled, np, glob_pattern, labels_path, names, unlabelled > 5 ? ", ..." : "");
  }
  free(used);
  km_paths_free(&paths, np);
  return rc < 0 ? -1 : n_pos;
}

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
  char **owned = NULL;
  size_t n_owned = 0;
  if (mesh_glob || labels_csv) {
    if (!mesh_glob || !labels_csv) {
      free(pos);
      return km_cli_error("posedb build", "--meshes and --labels go together");
    }
    n_pos = labelled_meshes(mesh_glob, labels_csv, pos, n_pos, MAX_POS, &owned, &n_owned);
    if (n_pos < 0) {
      for (size_t i = 0; i < n_owned; ++i)
        free(owned[i]);
      free(owned);
      free(pos);
      return KM_EXIT_FAIL;
    }
  }
  int rc = KM_EXIT_OK;
  km_error err = {0};
  size_t n = (size_t)n_pos, nc = 0;
  km_mesh *meshes = calloc(n ? n : 1, sizeof *meshes);
  int32_t *labels = malloc((n ? n : 1) * sizeof *labels), *groups = malloc((n ? n : 1) * 4);
  char **names = calloc(n ? n : 1, sizeof *names);
  char **group_names = calloc(n ? n : 1, sizeof *group_names);
  bool have_groups = false;
  km_posedb *db = NULL;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t nl = 0;
  if (!out || n < 2) {
    rc = km_cli_error("posedb build", "need -o OUTPUT and at least two CLASS=MESH arguments");
    goto done;
  }
  if (!meshes || !labels || !groups || !names || !group_names) {
    rc = km_cli_error("posedb build", "out of memory");
    goto done;
  }
  for (size_t i = 0; i < n; ++i) {
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", pos[i]);
    char *eq = strchr(buf, '=');
    if (!eq || eq == buf) {
      rc = km_cli_error("posedb build", "argument %zu '%s': expected CLASS=MESH[@GROUP]", i + 1,
                        pos[i]);
      goto done;
    }
    *eq = '\0';
    char *path = eq + 1, *at = strrchr(path, '@');
    groups[i] = 0;
    if (at) {
      *at = '\0';
      /* subjects are names ("alice") or numbers: each distinct one is its own group */
      size_t g = 0;
      while (g < i && !(groups[g] >= 0 && group_names[g] && !strcmp(group_names[g], at + 1)))
        ++g;
      group_names[i] = strdup(at + 1);
      groups[i] = g < i ? groups[g] : (int32_t)i;
      have_groups = true;
    }
    size_t c = 0;
    while (c < nc && strcmp(names[c], buf))
      ++c;
    if (c == nc) names[nc++] = strdup(buf);
    labels[i] = (int32_t)c;
    if (km_mesh_read(path, &meshes[i], &err)) {
      rc = km_cli_fail("posedb build", &err);
      goto done;
    }
    if (i == 0) {
      if (km_cli_load_landmarks(lm_path, path, meshes[0].n_vertices, lm, KM_POSE_MAX_LANDMARKS, &nl,
                                &err)) {
        rc = km_cli_fail("posedb build", &err);
        goto done;
      }
    }
  }
  km_posedb_options po = {0};
  po.features = features;
  po.cv_folds = folds;
  po.kernel = !strcmp(kernel, "linear") ? KM_SVM_LINEAR : KM_SVM_RBF;
  po.progress = km_cli_progress("posedb");
  km_posedb_report rep;
  /* templates named by their file names, so that a query says which mesh it picked */
  const char **tnames = calloc(n, sizeof *tnames);
  for (size_t i = 0; tnames && i < n; ++i) {
    const char *eq = strchr(pos[i], '='), *base = eq ? strrchr(eq + 1, '/') : NULL;
    tnames[i] = base ? base + 1 : eq ? eq + 1 : pos[i];
  }
  km_status bs = km_posedb_build(meshes, n, labels, nc, (const char *const *)names,
                                 have_groups ? groups : NULL, lm, nl, &po, &db, &rep, &err);
  if (!bs && tnames) {
    /* drop an "@GROUP" suffix from the names */
    char **clean = calloc(n, sizeof *clean);
    for (size_t i = 0; clean && i < n; ++i) {
      clean[i] = strdup(tnames[i]);
      char *at = clean[i] ? strrchr(clean[i], '@') : NULL;
      if (at) *at = '\0';
    }
    if (clean) bs = km_posedb_set_template_names(db, (const char *const *)clean, &err);
    for (size_t i = 0; clean && i < n; ++i)
      free(clean[i]);
    free(clean);
  }
  free(tnames);
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
  for (size_t i = 0; i < n; ++i) {
    if (meshes) km_mesh_free(&meshes[i]);
    if (names) free(names[i]);
    if (group_names) free(group_names[i]);
  }
  free(group_names);
  free(meshes);
  free(labels);
  free(groups);
  free(names);
  free(pos);
  for (size_t i = 0; i < n_owned; ++i)
    free(owned[i]);
  free(owned);
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
