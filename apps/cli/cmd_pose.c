/* Verbs of capability 2 (avatar pose transfer, Lifkooee et al. 2019):
 *   kinemesh transfer --source S --template T -o OUT     pose transfer, same connectivity
 *   kinemesh posedb build --meshes GLOB --labels CSV -o DB   pose database (CART + SVM)
 *   kinemesh posedb query DB --landmarks-xyz TRACK       recognise every frame of a track
 *   kinemesh avatar --source S --db DB --track TRACK -o ANIM  key poses + morphing
 * Landmarks come from --landmarks LM.json or the mesh's rig sidecar (<stem>.rig.json).
 * The positional forms (SOURCE TEMPLATE, CLASS=MESH[@GROUP]..., DB TRACK, AVATAR DB TRACK)
 * are accepted too. */
#include "cli.h"

#include <glob.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

/* Landmarks for a mesh: --landmarks file, else the rig sidecar next to the mesh. */
static km_status load_landmarks_cap(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                    km_landmark *lm, size_t capacity, size_t *n, km_error *err) {
  if (lm_path) return km_landmarks_read(lm_path, n_vertices, lm, capacity, n, err);
  char *rig = km_cli_rig_path(mesh_path);
  if (!rig) {
    err->status = KM_ERR_NOMEM;
    snprintf(err->message, sizeof err->message, "out of memory");
    return KM_ERR_NOMEM;
  }
  km_status s = km_landmarks_read(rig, n_vertices, lm, capacity, n, err);
  free(rig);
  return s;
}

/* The descriptor's landmarks: at most KM_POSE_MAX_LANDMARKS. */
static km_status load_landmarks(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                km_landmark *lm, size_t *n, km_error *err) {
  return load_landmarks_cap(lm_path, mesh_path, n_vertices, lm, KM_POSE_MAX_LANDMARKS, n, err);
}

int km_cli_transfer(int argc, char **argv) {
  const char *out = NULL, *lm_path = NULL, *encoding = "edge", *laplacian = "uniform",
             *align = "scale", *source = NULL, *templ = NULL, *xyz = NULL;
  int iterations = 0;
  size_t xyz_frame = 0;
  const km_cli_opt opts[] = {
      {"source", 's', KM_OPT_STRING, &source, "the avatar mesh S"},
      {"template", 't', KM_OPT_STRING, &templ, "the posed template T (same connectivity as S)"},
      {"output", 'o', KM_OPT_STRING, &out, "output mesh (.obj/.ply/.off)"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path,
       "LM.json with the landmark vertices (default: SOURCE's rig sidecar), or auto[:K]: K "
       "(default 16) vertices spread by farthest-point sampling, for any mesh"},
      {"landmarks-xyz", 0, KM_OPT_STRING, &xyz,
       "tracked landmark positions (a track .json/.csv, names as in the landmarks) as the "
       "targets, instead of TEMPLATE's landmarks"},
      {"frame", 0, KM_OPT_SIZE, &xyz_frame, "frame of --landmarks-xyz (default 0)"},
      {"iterations", 'i', KM_OPT_INT, &iterations, "maximum solves (default 10)"},
      {"encoding", 0, KM_OPT_STRING, &encoding,
       "edge (default) or vertex (the paper's eq. 3 verbatim)"},
      {"laplacian", 0, KM_OPT_STRING, &laplacian, "uniform (default, eq. 2) or cotan"},
      {"align", 0, KM_OPT_STRING, &align,
       "scale (default: TEMPLATE's landmarks scaled to SOURCE's size) or similarity"},
  };
  const char *pos[2];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 2, &n_pos,
                       "kinemesh transfer --source S --template T -o OUT [--landmarks LM.json]",
                       "SOURCE (the avatar) takes the pose of TEMPLATE (same connectivity) by\n"
                       "locally encoded Laplacian offsets; landmark vertices follow TEMPLATE's,\n"
                       "scaled to SOURCE's size.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (source && n_pos < 2) pos[n_pos++] = source;
  if (templ && n_pos < 2) pos[n_pos++] = templ;
  if (n_pos != 2) return km_cli_error("transfer", "expected --source S and --template T");
  if (!out) return km_cli_error("transfer", "-o OUTPUT is required");
  km_transfer_options to = {0};
  to.max_iterations = iterations;
  if (!strcmp(encoding, "vertex"))
    to.encoding = KM_OFFSETS_VERTEX;
  else if (strcmp(encoding, "edge"))
    return km_cli_error("transfer", "--encoding must be edge or vertex, not '%s'", encoding);
  if (!strcmp(laplacian, "cotan"))
    to.laplacian = KM_LAPLACIAN_COTAN;
  else if (strcmp(laplacian, "uniform"))
    return km_cli_error("transfer", "--laplacian must be uniform or cotan, not '%s'", laplacian);
  if (!strcmp(align, "similarity"))
    to.align = KM_TRANSFER_ALIGN_SIMILARITY;
  else if (strcmp(align, "scale"))
    return km_cli_error("transfer", "--align must be scale or similarity, not '%s'", align);
  km_error err = {0};
  km_mesh s = {0}, t = {0}, o = {0};
  km_transfer *tr = NULL;
  km_track trk = {0};
  km_landmark *lm = NULL;
  int32_t *ids = NULL;
  double *targets = NULL;
  size_t nl = 0, auto_k = 0;
  int rc = KM_EXIT_OK;
  bool auto_lm = lm_path && !strncmp(lm_path, "auto", 4);
  if (auto_lm) {
    const char *k = lm_path + 4;
    char *end = NULL;
    long v = *k == ':' ? strtol(k + 1, &end, 10) : 16;
    if ((*k && *k != ':') || (*k == ':' && (end == k + 1 || *end)) || v < 3)
      return km_cli_error("transfer", "--landmarks auto:K needs K >= 3, not '%s'", lm_path);
    auto_k = (size_t)v;
  }
  if (xyz && auto_lm)
    return km_cli_error("transfer", "--landmarks-xyz needs named landmarks (LM.json or the rig), "
                                    "not --landmarks auto");
  if (km_mesh_read(pos[0], &s, &err) || km_mesh_read(pos[1], &t, &err)) {
    rc = km_cli_fail("transfer", &err);
    goto done;
  }
  /* Transfer takes any number of landmarks (at least 3, at least one vertex free). */
  lm = calloc(s.n_vertices ? s.n_vertices : 1, sizeof *lm);
  ids = calloc(s.n_vertices ? s.n_vertices : 1, sizeof *ids);
  if (!lm || !ids) {
    rc = km_cli_error("transfer", "out of memory");
    goto done;
  }
  if (auto_lm) {
    nl = auto_k;
    if (km_farthest_points(&s, nl, ids, &err)) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
  } else if (load_landmarks_cap(lm_path, pos[0], s.n_vertices, lm, s.n_vertices, &nl, &err)) {
    rc = km_cli_fail("transfer", &err);
    if (!lm_path)
      fprintf(stderr, "kinemesh transfer: no landmarks: give --landmarks LM.json, or --landmarks "
                      "auto for a mesh without a rig\n");
    goto done;
  }
  if (!auto_lm && nl < 3) {
    char *rig = lm_path ? NULL : km_cli_rig_path(pos[0]);
    rc = km_cli_error("transfer",
                      "%s: %zu landmark(s); transfer needs at least 3 to fix the avatar's "
                      "rotation",
                      lm_path ? lm_path
                      : rig   ? rig
                              : pos[0],
                      nl);
    free(rig);
    goto done;
  }
  if (t.n_vertices != s.n_vertices || t.n_faces != s.n_faces ||
      memcmp(t.F, s.F, s.n_faces * 3 * sizeof(int32_t)) != 0) {
    rc = km_cli_error("transfer",
                      "%s (%zu vertices, %zu faces) does not share the connectivity of %s (%zu "
                      "vertices, %zu faces)",
                      pos[1], t.n_vertices, t.n_faces, pos[0], s.n_vertices, s.n_faces);
    goto done;
  }
  for (size_t i = 0; i < nl && !auto_lm; ++i)
    ids[i] = lm[i].vertex;
  if (xyz) {
    /* tracked targets: matched to the landmarks by name */
    if (km_track_read(xyz, &trk, &err)) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
    if (xyz_frame >= trk.n_frames) {
      rc = km_cli_error("transfer", "%s has %zu frame(s); --frame %zu is out of range", xyz,
                        trk.n_frames, xyz_frame);
      goto done;
    }
    targets = malloc(sizeof(double) * 3 * nl);
    if (!targets) {
      rc = km_cli_error("transfer", "out of memory");
      goto done;
    }
    for (size_t i = 0; i < nl; ++i) {
      size_t k = 0;
      while (k < trk.n_landmarks && strcmp(trk.names[k], lm[i].name))
        ++k;
      if (k == trk.n_landmarks) {
        rc = km_cli_error("transfer", "%s has no landmark named '%s'", xyz, lm[i].name);
        goto done;
      }
      const double *p = trk.positions + (xyz_frame * trk.n_landmarks + k) * 3;
      if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
        rc = km_cli_error("transfer", "%s: landmark '%s' is not tracked in frame %zu", xyz,
                          lm[i].name, xyz_frame);
        goto done;
      }
      memcpy(targets + 3 * i, p, 3 * sizeof(double));
    }
  }
  double t0 = km_cli_now();
  km_transfer_stats st;
  if (km_transfer_precompute(&s, ids, nl, &to, &tr, &err) || km_mesh_copy(&s, &o, &err) ||
      km_transfer_solve(tr, t.V, targets, NULL, o.V, &st, &err) ||
      km_mesh_write(out, &o, NULL, &err)) {
    rc = km_cli_fail("transfer", &err);
    goto done;
  }
  double lap, chol;
  km_transfer_precompute_ms(tr, &lap, &chol);
  fprintf(stderr,
          "kinemesh transfer: %zu vertices, %zu landmarks; offline %.1f ms (Laplacian %.1f, "
          "Cholesky %.1f); online %.2f ms, %d iterations (frames %.3f, solve %.3f ms each) in "
          "%.2f s -> %s\n",
          s.n_vertices, nl, lap + chol, lap, chol, st.total_ms, st.iterations,
          st.frames_ms / st.iterations, st.solve_ms / st.iterations, km_cli_now() - t0, out);
done:
  km_transfer_free(&tr);
  km_track_free(&trk);
  free(lm);
  free(ids);
  free(targets);
  km_mesh_free(&s);
  km_mesh_free(&t);
  km_mesh_free(&o);
  return rc;
}

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
      if (load_landmarks(lm_path, path, meshes[0].n_vertices, lm, &nl, &err)) {
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

typedef struct avatar_sink {
  km_anim_writer *w;
  km_progress prog;
  size_t frames;
} avatar_sink;

static km_status push_frame(size_t frame, const double *V, void *user, km_error *err) {
  avatar_sink *s = user;
  km_status st = km_anim_writer_push(s->w, V, err);
  if (s->prog.fn) s->prog.fn((double)(frame + 1) / (double)s->frames, "avatar", s->prog.user);
  return st;
}

int km_cli_avatar(int argc, char **argv) {
  const char *out = NULL, *lm_path = NULL, *source = NULL, *dbp = NULL, *track = NULL;
  size_t key_every = 1;
  double scale = 0;
  const km_cli_opt opts[] = {
      {"source", 's', KM_OPT_STRING, &source, "the avatar mesh (same connectivity as the DB)"},
      {"db", 0, KM_OPT_STRING, &dbp, "pose database (kinemesh posedb build)"},
      {"track", 0, KM_OPT_STRING, &track, "tracked landmark positions (.json/.csv)"},
      {"interval", 0, KM_OPT_SIZE, &key_every, "same as --key-every"},
      {"output", 'o', KM_OPT_STRING, &out, "output animation (.glb, .pc2, or a directory)"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path,
       "LM.json with the avatar's landmark vertices (default: AVATAR's rig sidecar)"},
      {"key-every", 'k', KM_OPT_SIZE, &key_every,
       "recognise + transfer every k-th frame, interpolate between (default 1)"},
      {"scale", 0, KM_OPT_DOUBLE, &scale,
       "avatar size / tracked body size (default: estimated at the first key frame)"},
  };
  const char *pos[3];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 3, &n_pos,
                       "kinemesh avatar --source S --db DB --track TRACK -o OUT.glb [--interval K]",
                       "Drives AVATAR (same connectivity as DB's templates) from a TRACK of\n"
                       "landmark positions: key poses are recognised in DB and transferred, the\n"
                       "frames in between interpolated; one output frame per track frame.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (source && n_pos < 3) pos[n_pos++] = source;
  if (dbp && n_pos < 3) pos[n_pos++] = dbp;
  if (track && n_pos < 3) pos[n_pos++] = track;
  if (n_pos != 3) return km_cli_error("avatar", "expected --source S, --db DB and --track TRACK");
  if (!out) return km_cli_error("avatar", "-o OUTPUT is required");
  km_error err = {0};
  km_mesh avatar = {0};
  km_posedb *db = NULL;
  km_track t = {0};
  km_transfer *tr = NULL;
  avatar_sink sink = {0};
  int rc = KM_EXIT_OK;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t nl = 0;
  int32_t ids[KM_POSE_MAX_LANDMARKS];
  if (km_mesh_read(pos[0], &avatar, &err) || km_posedb_load(pos[1], &db, &err) ||
      km_track_read(pos[2], &t, &err) ||
      load_landmarks(lm_path, pos[0], avatar.n_vertices, lm, &nl, &err)) {
    rc = km_cli_fail("avatar", &err);
    goto done;
  }
  /* The avatar's landmark vertices in the database's landmark order, by name. */
  size_t dnl = km_posedb_landmark_count(db);
  const km_landmark *dlm = km_posedb_landmarks(db);
  for (size_t a = 0; a < dnl; ++a) {
    ids[a] = -1;
    for (size_t b = 0; b < nl; ++b)
      if (!strcmp(lm[b].name, dlm[a].name)) ids[a] = lm[b].vertex;
    if (ids[a] < 0) {
      rc = km_cli_error("avatar", "the avatar has no landmark '%s' (the database's)", dlm[a].name);
      goto done;
    }
  }
  double t0 = km_cli_now();
  km_anim_options ao = {0};
  ao.fps = t.fps;
  km_avatar_options vo = {0};
  vo.key_every = key_every;
  vo.track_scale = scale;
  km_avatar_stats st;
  sink.prog = km_cli_progress("avatar");
  sink.frames = t.n_frames;
  if (km_transfer_precompute(&avatar, ids, dnl, NULL, &tr, &err) ||
      km_anim_writer_open(out, &avatar, &ao, &sink.w, &err) ||
      km_avatar_animate(tr, db, &t, &vo, push_frame, &sink, &st, &err) ||
      km_anim_writer_close(&sink.w, &err)) {
    km_cli_progress_done();
    rc = km_cli_fail("avatar", &err);
    goto done;
  }
  km_cli_progress_done();
  fprintf(stderr,
          "kinemesh avatar: %zu frames, %zu key poses (recognition %.3f ms, transfer %.2f ms, "
          "%.1f iterations each; slowest key frame %.2f ms) in %.2f s -> %s\n",
          st.frames, st.key_frames, st.key_frames ? st.recognition_ms / st.key_frames : 0.0,
          st.key_frames ? st.transfer_ms / st.key_frames : 0.0, st.iterations_mean, st.max_frame_ms,
          km_cli_now() - t0, out);
done:
  km_anim_writer_free(&sink.w);
  km_transfer_free(&tr);
  km_posedb_free(&db);
  km_track_free(&t);
  km_mesh_free(&avatar);
  return rc;
}
