/* Pose database: templates of one connectivity with pose classes; recognition by selected
 * angles + SVM, template retrieval by nearest neighbour inside the predicted class (section
 * 3.3). File format (version 2, little endian):
 *   "KMPOSEDB" | u32 version | u64 header bytes | header JSON | int32 F[n_faces*3] |
 *   f64 V[n_meshes*n_vertices*3] | f64 desc[n_meshes*d] | f64 lo[d] | f64 hi[d] |
 *   f64 rho[k(k-1)/2] | f64 coef[(k-1)*l] | int32 sv_row[l] | u64 FNV-1a of everything before
 * The JSON holds counts, landmarks, class names, labels, groups, the selected features, the
 * options, the build report and the SVM's shape ("svm": classes k, vectors l, label and n_sv
 * per class); the binary part after V is the trained model: the templates' scaled descriptors
 * (the nearest-neighbour data), the feature ranges and libsvm's arrays (its own model files
 * only work on their own paths, not inside ours). Loading is linear in the file: nothing is
 * trained (issue 18: version 1 stored no model and was retrained on load, so a forged file of
 * 1.7 MB with 14,880 features cost 92 s and 736 MB). Version 1 files are still read, retrained,
 * when that work is small (KM__POSEDB_V1_WORK). */
#include "transfer/pose.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct km_posedb {
  size_t n_meshes, n_vertices, n_faces, n_classes, nl;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  char (*class_names)[64];
  char (*template_names)[128]; /* NULL: unnamed */
  int32_t *labels, *groups;
  double *V;
  int32_t *F;
  double *P;    /* n_meshes * nl * 3 landmark positions */
  double *desc; /* n_meshes * d scaled descriptors */
  km__pose_model model;
  km_posedb_options opt;
  km_posedb_report report;
};

void km_posedb_free(km_posedb **dbp) {
  if (!dbp || !*dbp) return;
  km_posedb *db = *dbp;
  free(db->class_names);
  free(db->template_names);
  free(db->labels);
  free(db->groups);
  free(db->V);
  free(db->F);
  free(db->P);
  free(db->desc);
  km__pose_model_free(&db->model);
  free(db);
  *dbp = NULL;
}

size_t km_posedb_size(const km_posedb *db) { return db ? db->n_meshes : 0; }
size_t km_posedb_classes(const km_posedb *db) { return db ? db->n_classes : 0; }
const char *km_posedb_class_name(const km_posedb *db, size_t c) {
  return db && c < db->n_classes ? db->class_names[c] : "";
}
km_status km_posedb_set_template_names(km_posedb *db, const char *const *names, km_error *err) {
  if (!db || !names) return km__fail(err, KM_ERR_INVALID, "km_posedb_set_template_names: NULL");
  if (!db->template_names) {
    db->template_names = km__calloc(db->n_meshes ? db->n_meshes : 1, sizeof *db->template_names);
    if (!db->template_names)
      return km__fail(err, KM_ERR_NOMEM, "km_posedb_set_template_names: out of memory");
  }
  for (size_t i = 0; i < db->n_meshes; ++i)
    snprintf(db->template_names[i], sizeof db->template_names[i], "%s", names[i] ? names[i] : "");
  return KM_OK;
}
const char *km_posedb_template_name(const km_posedb *db, size_t i) {
  return db && db->template_names && i < db->n_meshes ? db->template_names[i] : "";
}
int32_t km_posedb_label(const km_posedb *db, size_t i) {
  return db && i < db->n_meshes ? db->labels[i] : -1;
}
size_t km_posedb_landmark_count(const km_posedb *db) { return db ? db->nl : 0; }
const km_landmark *km_posedb_landmarks(const km_posedb *db) { return db ? db->lm : NULL; }
void km_posedb_template(const km_posedb *db, size_t i, km_mesh *view) {
  if (!view) return;
  memset(view, 0, sizeof *view);
  if (!db || i >= db->n_meshes) return;
  view->V = db->V + i * db->n_vertices * 3;
  view->F = db->F;
  view->n_vertices = db->n_vertices;
  view->n_faces = db->n_faces;
}
const int32_t *km_posedb_features(const km_posedb *db, size_t *d) {
  if (d) *d = db ? db->model.d : 0;
  return db ? db->model.triples : NULL;
}

/* Landmark positions of every template into db->P. */
static km_status landmark_positions(km_posedb *db, km_error *err) {
  size_t nl = db->nl;
  for (size_t i = 0; i < db->n_meshes; ++i)
    for (size_t a = 0; a < nl; ++a)
      memcpy(db->P + (i * nl + a) * 3, db->V + (i * db->n_vertices + (size_t)db->lm[a].vertex) * 3,
             3 * sizeof(double));
  for (size_t i = 0; i < db->n_meshes * nl * 3; ++i)
    if (!isfinite(db->P[i]))
      return km__fail(err, KM_ERR_INVALID, "pose database: mesh %zu has a non-finite landmark",
                      i / (nl * 3));
  return KM_OK;
}

/* Landmark positions; model training; descriptors for NN. */
static km_status finish(km_posedb *db, const int32_t *fixed, size_t fixed_d, km_error *err) {
  size_t nl = db->nl;
  km_status s = landmark_positions(db, err);
  if (s) return s;
  s = km__pose_model_train(db->P, db->labels, db->n_meshes, db->n_classes, db->lm, nl, &db->opt,
                           fixed, fixed_d, &db->model, err);
  if (s) return s;
  db->desc = km__malloc(db->n_meshes * db->model.d, sizeof(double));
  if (!db->desc) return km__fail(err, KM_ERR_NOMEM, "pose database: out of memory");
  for (size_t i = 0; i < db->n_meshes; ++i)
    km__pose_model_features(&db->model, db->P + i * nl * 3, db->desc + i * db->model.d);
  return KM_OK;
}

static km_posedb *alloc_db(size_t n_meshes, size_t n_vertices, size_t n_faces, size_t n_classes,
                           size_t nl, bool groups) {
  km_posedb *db = calloc(1, sizeof *db);
  if (!db) return NULL;
  db->n_meshes = n_meshes, db->n_vertices = n_vertices, db->n_faces = n_faces;
  db->n_classes = n_classes, db->nl = nl;
  db->class_names = km__calloc(n_classes, sizeof *db->class_names);
  db->labels = km__malloc(n_meshes, sizeof(int32_t));
  db->groups = groups ? km__malloc(n_meshes, sizeof(int32_t)) : NULL;
  size_t nv3 = n_vertices * 3;
  db->V = nv3 && n_meshes <= SIZE_MAX / nv3 ? km__malloc(n_meshes * nv3, sizeof(double)) : NULL;
  db->F = km__malloc(n_faces ? n_faces * 3 : 1, sizeof(int32_t));
  db->P = km__malloc(n_meshes * nl * 3, sizeof(double));
  if (!db->class_names || !db->labels || (groups && !db->groups) || !db->V || !db->F || !db->P) {
    km_posedb_free(&db);
    return NULL;
  }
  return db;
}

km_status km_posedb_build(const km_mesh *meshes, size_t n_meshes, const int32_t *labels,
                          size_t n_classes, const char *const *class_names, const int32_t *groups,
                          const km_landmark *landmarks, size_t n_landmarks,
                          const km_posedb_options *opt, km_posedb **out, km_posedb_report *report,
                          km_error *err) {
  double t0 = km_seconds();
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_posedb_build: out is NULL");
  *out = NULL;
  if (report) memset(report, 0, sizeof *report);
  if (!meshes || !labels || !landmarks)
    return km__fail(err, KM_ERR_INVALID, "km_posedb_build: NULL argument");
  if (n_meshes < 2 || n_classes < 1)
    return km__fail(err, KM_ERR_INVALID,
                    "km_posedb_build: %zu meshes in %zu classes, need at least 2 meshes", n_meshes,
                    n_classes);
  if (n_landmarks < 4 || n_landmarks > KM_POSE_MAX_LANDMARKS)
    return km__fail(err, KM_ERR_INVALID, "km_posedb_build: %zu landmarks, expected 4..%d",
                    n_landmarks, KM_POSE_MAX_LANDMARKS);
  size_t nv = meshes[0].n_vertices, nfc = meshes[0].n_faces;
  for (size_t i = 0; i < n_meshes; ++i) {
    if (!meshes[i].V || (meshes[i].n_faces && !meshes[i].F))
      return km__fail(err, KM_ERR_INVALID, "km_posedb_build: mesh %zu has no data", i);
    if (meshes[i].n_vertices != nv || meshes[i].n_faces != nfc ||
        (nfc && memcmp(meshes[i].F, meshes[0].F, nfc * 3 * sizeof(int32_t)) != 0))
      return km__fail(err, KM_ERR_INVALID,
                      "km_posedb_build: mesh %zu does not share mesh 0's connectivity (%zu "
                      "vertices, %zu faces)",
                      i, nv, nfc);
    if (labels[i] < 0 || (size_t)labels[i] >= n_classes)
      return km__fail(err, KM_ERR_INVALID,
                      "km_posedb_build: label of mesh %zu is %d, expected 0..%zu", i,
                      (int)labels[i], n_classes - 1);
  }
  for (size_t f = 0; f < nfc * 3; ++f)
    if (meshes[0].F[f] < 0 || (size_t)meshes[0].F[f] >= nv)
      return km__fail(err, KM_ERR_INVALID, "km_posedb_build: face %zu has vertex %d of %zu", f / 3,
                      (int)meshes[0].F[f], nv);
  for (size_t a = 0; a < n_landmarks; ++a)
    if (landmarks[a].vertex < 0 || (size_t)landmarks[a].vertex >= nv)
      return km__fail(err, KM_ERR_INVALID,
                      "km_posedb_build: landmark \"%s\" is vertex %d, expected 0..%zu",
                      landmarks[a].name, (int)landmarks[a].vertex, nv - 1);
  int32_t mirror[KM_POSE_MAX_LANDMARKS];
  km_status s = km__landmark_mirrors(landmarks, n_landmarks, mirror, err);
  if (s) return km__wrap(err, s, "km_posedb_build");

  km_posedb *db = alloc_db(n_meshes, nv, nfc, n_classes, n_landmarks, groups != NULL);
  if (!db)
    return km__fail(err, KM_ERR_NOMEM, "km_posedb_build: out of memory (%zu meshes)", n_meshes);
  db->opt = km__posedb_defaults(opt, n_landmarks);
  memcpy(db->lm, landmarks, n_landmarks * sizeof *landmarks);
  memcpy(db->labels, labels, n_meshes * sizeof *labels);
  if (groups) memcpy(db->groups, groups, n_meshes * sizeof *groups);
  if (nfc) memcpy(db->F, meshes[0].F, nfc * 3 * sizeof(int32_t));
  for (size_t i = 0; i < n_meshes; ++i)
    memcpy(db->V + i * nv * 3, meshes[i].V, nv * 3 * sizeof(double));
  for (size_t c = 0; c < n_classes; ++c)
    if (class_names && class_names[c]) snprintf(db->class_names[c], 64, "%s", class_names[c]);

  /* Cross-validation: leave one group out, or stratified k-fold (sample j of a class goes
   * to fold j mod k). Feature selection is redone inside every fold. */
  size_t nl = n_landmarks, folds = 0;
  int32_t *fold = km__malloc(n_meshes, sizeof *fold), *cnt = km__calloc(n_classes, sizeof *cnt);
  double *Ptr = NULL;
  int32_t *ytr = NULL;
  double *x = NULL;
  if (!fold || !cnt) {
    s = km__fail(err, KM_ERR_NOMEM, "km_posedb_build: out of memory");
    goto fail;
  }
  for (size_t i = 0; i < n_meshes; ++i)
    for (size_t a = 0; a < nl; ++a)
      memcpy(db->P + (i * nl + a) * 3, db->V + (i * nv + (size_t)landmarks[a].vertex) * 3,
             3 * sizeof(double));
  if (groups) {
    /* Fold id = rank of the group value among the distinct values. */
    for (size_t i = 0; i < n_meshes; ++i) {
      fold[i] = -1;
      for (size_t j = 0; j < i; ++j)
        if (groups[j] == groups[i]) {
          fold[i] = fold[j];
          break;
        }
      if (fold[i] < 0) fold[i] = (int32_t)folds++;
    }
    if (folds < 2) folds = 0;
  } else if (db->opt.cv_folds >= 2) {
    folds = (size_t)db->opt.cv_folds;
    for (size_t i = 0; i < n_meshes; ++i)
      fold[i] = (int32_t)((size_t)cnt[labels[i]]++ % folds);
  }
  double correct = 0, tested = 0;
  if (folds) {
    Ptr = km__malloc(n_meshes * nl * 3, sizeof *Ptr);
    ytr = km__malloc(n_meshes, sizeof *ytr);
    x = km__malloc(km_pose_candidate_count(nl), sizeof *x);
    if (!Ptr || !ytr || !x) {
      s = km__fail(err, KM_ERR_NOMEM, "km_posedb_build: out of memory");
      goto fail;
    }
    for (size_t f = 0; f < folds; ++f) {
      if (!km__progress(&db->opt.progress, (double)f / (double)(folds + 1), "cross-validation")) {
        s = km__fail(err, KM_ERR_CANCELLED, "km_posedb_build: cancelled");
        goto fail;
      }
      size_t m = 0;
      for (size_t i = 0; i < n_meshes; ++i)
        if (fold[i] != (int32_t)f) {
          memcpy(Ptr + m * nl * 3, db->P + i * nl * 3, nl * 3 * sizeof(double));
          ytr[m++] = labels[i];
        }
      if (m == 0 || m == n_meshes) continue;
      km__pose_model pm;
      s = km__pose_model_train(Ptr, ytr, m, n_classes, landmarks, nl, &db->opt, NULL, 0, &pm, err);
      if (s) {
        km__wrap(err, s, "km_posedb_build: cross-validation fold %zu", f);
        goto fail;
      }
      for (size_t i = 0; i < n_meshes; ++i)
        if (fold[i] == (int32_t)f) {
          km__pose_model_features(&pm, db->P + i * nl * 3, x);
          correct += km__pose_model_predict_scaled(&pm, x) == labels[i];
          tested += 1;
        }
      km__pose_model_free(&pm);
    }
  }
  if (!km__progress(&db->opt.progress, (double)folds / (double)(folds + 1), "training")) {
    s = km__fail(err, KM_ERR_CANCELLED, "km_posedb_build: cancelled");
    goto fail;
  }
  s = finish(db, NULL, 0, err);
  if (s) goto fail;
  db->report.samples = n_meshes;
  db->report.classes = n_classes;
  db->report.features = db->model.d;
  db->report.cv_accuracy = tested > 0 ? correct / tested : -1;
  db->report.cv_accuracy_eq8 =
      tested > 0 && n_classes > 0 ? 1 - 2 * (tested - correct) / (tested * (double)n_classes) : -1;
  db->report.cv_folds = tested > 0 ? folds : 0;
  db->report.build_ms = (km_seconds() - t0) * 1e3;
  if (report) *report = db->report;
  free(fold);
  free(cnt);
  free(Ptr);
  free(ytr);
  free(x);
  km__progress(&db->opt.progress, 1, "done");
  *out = db;
  return KM_OK;
fail:
  free(fold);
  free(cnt);
  free(Ptr);
  free(ytr);
  free(x);
  km_posedb_free(&db);
  return s;
}

km_status km_posedb_query(const km_posedb *db, const double *P, km_pose_match *out, km_error *err) {
  double t0 = km_seconds();
  if (!db || !P || !out) return km__fail(err, KM_ERR_INVALID, "km_posedb_query: NULL argument");
  memset(out, 0, sizeof *out);
  for (size_t i = 0; i < db->nl * 3; ++i)
    if (!isfinite(P[i]))
      return km__fail(err, KM_ERR_INVALID, "km_posedb_query: landmark %zu (\"%s\") is not finite",
                      i / 3, db->lm[i / 3].name);
  size_t d = db->model.d;
  double buf[256], *x = buf, *heap = NULL;
  if (d > 256) {
    heap = km__malloc(d, sizeof *heap);
    if (!heap) return km__fail(err, KM_ERR_NOMEM, "km_posedb_query: out of memory");
    x = heap;
  }
  km__pose_model_features(&db->model, P, x);
  int32_t label = km__pose_model_predict_scaled(&db->model, x);
  double best = INFINITY;
  size_t bi = 0;
  for (size_t i = 0; i < db->n_meshes; ++i) {
    if (db->labels[i] != label) continue;
    const double *q = db->desc + i * d;
    double s2 = 0;
    for (size_t f = 0; f < d; ++f)
      s2 += (x[f] - q[f]) * (x[f] - q[f]);
    if (s2 < best) best = s2, bi = i;
  }
  free(heap);
  if (!isfinite(best))
    return km__fail(err, KM_ERR_INVALID, "km_posedb_query: class %d has no template", label);
  out->label = label;
  out->template_index = bi;
  out->distance = sqrt(best);
  out->ms = (km_seconds() - t0) * 1e3;
  return KM_OK;
}

/* ---------------------------------------------------------------- file */

static bool little_endian(void) {
  uint16_t x = 1;
  unsigned char c;
  memcpy(&c, &x, 1);
  return c == 1;
}

typedef struct hashed_writer {
  FILE *f;
  uint64_t h;
} hashed_writer;
static void hw(hashed_writer *w, const void *p, size_t n) {
  if (!n) return;
  fwrite(p, 1, n, w->f);
  w->h = km__fnv1a(w->h, p, n);
}

km_status km_posedb_save(const km_posedb *db, const char *path, km_error *err) {
  if (!db || !path) return km__fail(err, KM_ERR_INVALID, "km_posedb_save: NULL argument");
  if (!little_endian())
    return km__fail(err, KM_ERR_UNSUPPORTED, "km_posedb_save: big-endian hosts are not supported");
  cJSON *root = cJSON_CreateObject();
  if (!root) return km__fail(err, KM_ERR_NOMEM, "km_posedb_save: out of memory");
  cJSON_AddStringToObject(root, "format", "kinemesh-posedb");
  cJSON_AddNumberToObject(root, "version", 1);
  cJSON_AddNumberToObject(root, "n_meshes", (double)db->n_meshes);
  cJSON_AddNumberToObject(root, "n_vertices", (double)db->n_vertices);
  cJSON_AddNumberToObject(root, "n_faces", (double)db->n_faces);
  cJSON *lm = cJSON_AddArrayToObject(root, "landmarks");
  for (size_t a = 0; a < db->nl; ++a) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", db->lm[a].name);
    cJSON_AddNumberToObject(o, "vertex", db->lm[a].vertex);
    cJSON_AddStringToObject(o, "mirror", db->lm[a].mirror);
    cJSON_AddItemToArray(lm, o);
  }
  cJSON *cl = cJSON_AddArrayToObject(root, "classes");
  for (size_t c = 0; c < db->n_classes; ++c)
    cJSON_AddItemToArray(cl, cJSON_CreateString(db->class_names[c]));
  if (db->template_names) {
    cJSON *tn = cJSON_AddArrayToObject(root, "templates");
    for (size_t i = 0; i < db->n_meshes; ++i)
      cJSON_AddItemToArray(tn, cJSON_CreateString(db->template_names[i]));
  }
  cJSON *lb = cJSON_AddArrayToObject(root, "labels");
  cJSON *gr = db->groups ? cJSON_AddArrayToObject(root, "groups") : NULL;
  for (size_t i = 0; i < db->n_meshes; ++i) {
    cJSON_AddItemToArray(lb, cJSON_CreateNumber(db->labels[i]));
    if (gr) cJSON_AddItemToArray(gr, cJSON_CreateNumber(db->groups[i]));
  }
  cJSON *fe = cJSON_AddArrayToObject(root, "features");
  for (size_t f = 0; f < db->model.d; ++f) {
    int tr[3] = {db->model.triples[3 * f], db->model.triples[3 * f + 1],
                 db->model.triples[3 * f + 2]};
    cJSON_AddItemToArray(fe, cJSON_CreateIntArray(tr, 3));
  }
  cJSON *op = cJSON_AddObjectToObject(root, "options");
  cJSON_AddNumberToObject(op, "tree_max_depth", db->opt.tree_max_depth);
  cJSON_AddNumberToObject(op, "mirror", db->opt.mirror);
  cJSON_AddNumberToObject(op, "kernel", db->opt.kernel);
  cJSON_AddNumberToObject(op, "svm_c", db->opt.svm_c);
  cJSON_AddNumberToObject(op, "svm_gamma", db->opt.svm_gamma);
  cJSON_AddNumberToObject(op, "cv_folds", db->opt.cv_folds);
  cJSON *rp = cJSON_AddObjectToObject(root, "report");
  cJSON_AddNumberToObject(rp, "cv_accuracy", db->report.cv_accuracy);
  cJSON_AddNumberToObject(rp, "cv_accuracy_eq8", db->report.cv_accuracy_eq8);
  cJSON_AddNumberToObject(rp, "cv_folds", (double)db->report.cv_folds);
  cJSON_AddNumberToObject(rp, "build_ms", db->report.build_ms);
  km__pose_svm sv;
  km__pose_model_svm(&db->model, &sv);
  cJSON *so = cJSON_AddObjectToObject(root, "svm");
  cJSON_AddNumberToObject(so, "classes", sv.nr_class);
  cJSON_AddNumberToObject(so, "vectors", sv.l);
  if (sv.nr_class > 0) {
    cJSON_AddItemToObject(so, "label", cJSON_CreateIntArray(sv.label, sv.nr_class));
    cJSON_AddItemToObject(so, "n_sv", cJSON_CreateIntArray(sv.n_sv, sv.nr_class));
  }
  char *json = cJSON_PrintUnformatted(root);
  cJSON_Delete(root);
  if (!json) return km__fail(err, KM_ERR_NOMEM, "km_posedb_save: out of memory");
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s) {
    free(json);
    return s;
  }
  hashed_writer w = {af.f, KM__FNV_SEED};
  uint32_t version = 2;
  uint64_t hl = strlen(json);
  hw(&w, "KMPOSEDB", 8);
  hw(&w, &version, 4);
  hw(&w, &hl, 8);
  hw(&w, json, hl);
  free(json);
  hw(&w, db->F, db->n_faces * 3 * sizeof(int32_t));
  hw(&w, db->V, db->n_meshes * db->n_vertices * 3 * sizeof(double));
  size_t d = db->model.d, k = sv.nr_class > 0 ? (size_t)sv.nr_class : 1;
  hw(&w, db->desc, db->n_meshes * d * sizeof(double));
  hw(&w, db->model.lo, d * sizeof(double));
  hw(&w, db->model.hi, d * sizeof(double));
  hw(&w, sv.rho, k * (k - 1) / 2 * sizeof(double));
  for (size_t r = 0; r + 1 < k; ++r)
    hw(&w, sv.coef[r], (size_t)sv.l * sizeof(double));
  for (int i = 0; i < sv.l; ++i) {
    int32_t row = sv.sv_row1[i] - 1;
    hw(&w, &row, 4);
  }
  uint64_t h = w.h;
  fwrite(&h, 1, 8, af.f);
  return km__atomic_commit(&af, err);
}

/* Samples^2 x features that a version 1 database may cost to retrain on load (a few seconds). */
#define KM__POSEDB_V1_WORK 4.0e9

/* An index read from the file: a whole number in 0 .. n - 1 (a fraction, which the cast used to
 * truncate, is no index). */
static bool json_index(const cJSON *v, size_t n, int32_t *out) {
  int64_t x;
  if (!n || !cJSON_IsNumber(v) || !km__whole_number(v->valuedouble, 0, (double)n - 1, &x))
    return false;
  *out = (int32_t)x;
  return true;
}

/* Version 2: the stored descriptors and SVM (q: the bytes after V) into db; k, l checked
 * against the file by the caller. */
static km_status restore_model(km_posedb *db, const int32_t *mirror, const int32_t *tri, size_t d,
                               size_t k, size_t l, cJSON *sla, cJSON *sna, const char *q,
                               km_error *err) {
  size_t nm = db->n_meshes, nrho = k * (k - 1) / 2;
  km_status s = landmark_positions(db, err);
  if (s) return s;
  size_t tail_n = 2 * d + nrho + (k - 1) * l; /* doubles, then l int32 */
  double *tail = km__malloc(tail_n * 8 + l * 4 + 8, 1);
  int *label = km__malloc(k, sizeof *label), *nsv = km__malloc(k, sizeof *nsv);
  db->desc = km__malloc(nm * d, sizeof(double));
  if (!tail || !label || !nsv || !db->desc) {
    s = km__fail(err, KM_ERR_NOMEM, "pose database: out of memory");
    goto done;
  }
  memcpy(db->desc, q, nm * d * 8);
  memcpy(tail, q + nm * d * 8, tail_n * 8 + l * 4);
  size_t c = 0;
  cJSON *a = sla->child, *b = sna->child;
  for (; a && b && c < k; a = a->next, b = b->next, ++c) {
    int32_t la, nb;
    if (!json_index(a, db->n_classes, &la) || !json_index(b, (size_t)l + 1, &nb)) {
      s = km__fail(err, KM_ERR_PARSE, "pose database: svm class %zu: label or n_sv out of range",
                   c);
      goto done;
    }
    label[c] = la;
    nsv[c] = nb;
  }
  const double *lo = tail, *hi = lo + d, *rho = hi + d, *coef = rho + nrho;
  int32_t *sv_row = km__malloc(l ? l : 1, sizeof *sv_row);
  if (!sv_row) {
    s = km__fail(err, KM_ERR_NOMEM, "pose database: out of memory");
    goto done;
  }
  memcpy(sv_row, coef + (k - 1) * l, l * 4);
  size_t rows = db->opt.mirror == KM_POSE_MIRROR_ALL ? 2 * nm : nm;
  s = km__pose_model_restore(&db->model, db->nl, mirror, tri, d, lo, hi, &db->opt, (int)k, (int)l,
                             label, nsv, rho, coef, sv_row, rows, db->desc, db->P, nm,
                             db->n_classes, err);
  free(sv_row);
done:
  free(tail);
  free(label);
  free(nsv);
  return s;
}

static bool get_size(cJSON *o, const char *k, size_t max, size_t *out) {
  cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  int64_t x;
  if (!cJSON_IsNumber(v) || !km__whole_number(v->valuedouble, 0, (double)max, &x)) return false;
  *out = (size_t)x;
  return true;
}

km_status km_posedb_load(const char *path, km_posedb **out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_posedb_load: NULL argument");
  *out = NULL;
  if (!little_endian())
    return km__fail(err, KM_ERR_UNSUPPORTED, "km_posedb_load: big-endian hosts are not supported");
  char *data = NULL;
  size_t size = 0;
  km_status s = km__read_file(path, &data, &size, err);
  if (s) return s;
  cJSON *root = NULL;
  km_posedb *db = NULL;
  uint32_t version;
  uint64_t hl;
  if (size < 28 || memcmp(data, "KMPOSEDB", 8) != 0) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 0: not a kinemesh pose database (no KMPOSEDB magic)",
                 path);
    goto done;
  }
  memcpy(&version, data + 8, 4);
  if (version != 1 && version != 2) {
    s = km__fail(err, KM_ERR_UNSUPPORTED, "%s: byte 8: version %u, this build reads versions 1, 2",
                 path, version);
    goto done;
  }
  uint64_t stored;
  memcpy(&stored, data + size - 8, 8);
  if (km__fnv1a(KM__FNV_SEED, data, size - 8) != stored) {
    s = km__fail(err, KM_ERR_PARSE, "%s: checksum mismatch (file truncated or corrupted)", path);
    goto done;
  }
  memcpy(&hl, data + 12, 8);
  if (hl > size - 28) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 12: header length %llu exceeds the file", path,
                 (unsigned long long)hl);
    goto done;
  }
  root = cJSON_ParseWithLength(data + 20, (size_t)hl);
  size_t nm, nv, nf;
  cJSON *lm, *cl, *lb, *gr, *fe, *op, *rp;
  if (!root || !get_size(root, "n_meshes", 1e9, &nm) || !get_size(root, "n_vertices", 1e9, &nv) ||
      !get_size(root, "n_faces", 1e9, &nf) ||
      !cJSON_IsArray(lm = cJSON_GetObjectItemCaseSensitive(root, "landmarks")) ||
      !cJSON_IsArray(cl = cJSON_GetObjectItemCaseSensitive(root, "classes")) ||
      !cJSON_IsArray(lb = cJSON_GetObjectItemCaseSensitive(root, "labels")) ||
      !cJSON_IsArray(fe = cJSON_GetObjectItemCaseSensitive(root, "features"))) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s: byte 20: header JSON lacks counts, landmarks, classes, "
                 "labels or features",
                 path);
    goto done;
  }
  gr = cJSON_GetObjectItemCaseSensitive(root, "groups");
  op = cJSON_GetObjectItemCaseSensitive(root, "options");
  rp = cJSON_GetObjectItemCaseSensitive(root, "report");
  size_t body = size - 28 - (size_t)hl;
  size_t nl = (size_t)cJSON_GetArraySize(lm), nc = (size_t)cJSON_GetArraySize(cl);
  size_t d = (size_t)cJSON_GetArraySize(fe);
  if (nl < 4 || nl > KM_POSE_MAX_LANDMARKS || nc < 1 || (size_t)cJSON_GetArraySize(lb) != nm ||
      (gr && (!cJSON_IsArray(gr) || (size_t)cJSON_GetArraySize(gr) != nm)) || d < 1 ||
      d > km_pose_candidate_count(nl)) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s: inconsistent header (landmarks, classes, labels, features)", path);
    goto done;
  }
  /* Version 2: the model's shape (k classes, l support vectors), checked against the file. */
  size_t k = 0, l = 0, extra = 0;
  cJSON *sla = NULL, *sna = NULL;
  if (version == 2) {
    cJSON *so = cJSON_GetObjectItemCaseSensitive(root, "svm");
    if (!cJSON_IsObject(so) || !get_size(so, "classes", nc, &k) || k < 1 ||
        !get_size(so, "vectors", 2000000000, &l) ||
        !cJSON_IsArray(sla = cJSON_GetObjectItemCaseSensitive(so, "label")) ||
        !cJSON_IsArray(sna = cJSON_GetObjectItemCaseSensitive(so, "n_sv")) ||
        (size_t)cJSON_GetArraySize(sla) != k || (size_t)cJSON_GetArraySize(sna) != k) {
      s = km__fail(err, KM_ERR_PARSE,
                   "%s: byte 20: header JSON's \"svm\" lacks classes (1..%zu), vectors, label "
                   "or n_sv",
                   path, nc);
      goto done;
    }
  }
  /* Sizes are checked against the file before anything is allocated; every product is
   * bounded by the data bytes first. */
  bool fits = nv > 0 && nm >= 2 && nf <= body / 12 && nm <= body / 24 / nv;
  if (fits && version == 2) {
    fits = nm <= body / 8 / d && l <= 2 * nm && k - 1 <= body / 8 / k &&
           (l == 0 || k - 1 <= body / 8 / l);
    if (fits) extra = nm * d * 8 + 2 * d * 8 + k * (k - 1) / 2 * 8 + (k - 1) * l * 8 + l * 4;
  }
  if (!fits || nf * 12 + nm * nv * 24 + extra != body) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s: %zu meshes x %zu vertices and %zu faces%s do not match the %zu data bytes",
                 path, nm, nv, nf, version == 2 ? " with their model" : "", body);
    goto done;
  }
  /* Version 1 is retrained on load: libsvm's work grows as samples^2 x features, so only a
   * database small enough to train in seconds is accepted. */
  if (version == 1 && (double)nm * (double)nm * (double)d > KM__POSEDB_V1_WORK) {
    s = km__fail(err, KM_ERR_UNSUPPORTED,
                 "%s: a version 1 database (no stored model) of %zu templates x %zu features would "
                 "be retrained on load (over %.0e samples^2 x features); rebuild it with "
                 "`kinemesh posedb build`, which stores the model",
                 path, nm, d, KM__POSEDB_V1_WORK);
    goto done;
  }
  db = alloc_db(nm, nv, nf, nc, nl, gr != NULL);
  int32_t *tri = km__malloc(d * 3, sizeof *tri);
  if (!db || !tri) {
    free(tri);
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto done;
  }
  size_t i = 0;
  cJSON *it;
  cJSON_ArrayForEach(it, lm) {
    cJSON *a = cJSON_GetObjectItemCaseSensitive(it, "name"),
          *b = cJSON_GetObjectItemCaseSensitive(it, "vertex"),
          *c = cJSON_GetObjectItemCaseSensitive(it, "mirror");
    if (!cJSON_IsString(a) || !cJSON_IsString(c) || strlen(a->valuestring) > 31 ||
        strlen(c->valuestring) > 31 || !json_index(b, nv, &db->lm[i].vertex)) {
      s = km__fail(err, KM_ERR_PARSE, "%s: landmark %zu is malformed", path, i);
      break;
    }
    strcpy(db->lm[i].name, a->valuestring);
    strcpy(db->lm[i].mirror, c->valuestring);
    ++i;
  }
  i = 0;
  if (!s) cJSON_ArrayForEach(it, cl) {
      snprintf(db->class_names[i++], 64, "%s", cJSON_IsString(it) ? it->valuestring : "");
    }
  /* optional (databases from before template names have none) */
  cJSON *tn = cJSON_GetObjectItemCaseSensitive(root, "templates");
  if (!s && cJSON_IsArray(tn) && (size_t)cJSON_GetArraySize(tn) == db->n_meshes) {
    db->template_names = km__calloc(db->n_meshes ? db->n_meshes : 1, sizeof *db->template_names);
    if (!db->template_names) {
      s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    } else {
      i = 0;
      cJSON_ArrayForEach(it, tn) {
        snprintf(db->template_names[i++], sizeof *db->template_names, "%s",
                 cJSON_IsString(it) ? it->valuestring : "");
      }
    }
  }
  i = 0;
  if (!s) cJSON_ArrayForEach(it, lb) {
      if (!json_index(it, nc, &db->labels[i])) {
        s = km__fail(err, KM_ERR_PARSE, "%s: label %zu is not a class index", path, i);
        break;
      }
      ++i;
    }
  i = 0;
  if (!s && gr) cJSON_ArrayForEach(it, gr) {
      /* a group is a whole number in int32's range; anything else is no group (0): a cast of
       * 1e30 to int32_t is undefined behaviour */
      int64_t g = 0; /* km__whole_number leaves it 0 when it refuses */
      if (cJSON_IsNumber(it)) km__whole_number(it->valuedouble, INT32_MIN, INT32_MAX, &g);
      db->groups[i++] = (int32_t)g;
    }
  i = 0;
  if (!s) cJSON_ArrayForEach(it, fe) {
      bool ok = cJSON_IsArray(it) && cJSON_GetArraySize(it) == 3;
      for (int k = 0; ok && k < 3; ++k) {
        cJSON *v = cJSON_GetArrayItem(it, k);
        ok = json_index(v, nl, &tri[3 * i + k]);
      }
      if (!ok) {
        s = km__fail(err, KM_ERR_PARSE, "%s: feature %zu is not a landmark triple", path, i);
        break;
      }
      ++i;
    }
  if (!s) {
    const char *p = data + 20 + hl;
    memcpy(db->F, p, nf * 12);
    memcpy(db->V, p + nf * 12, nm * nv * 24);
    for (size_t f = 0; f < nf * 3 && !s; ++f)
      if (db->F[f] < 0 || (size_t)db->F[f] >= nv)
        s = km__fail(err, KM_ERR_PARSE, "%s: face %zu has vertex %d of %zu", path, f / 3,
                     (int)db->F[f], nv);
  }
  if (!s) {
    km_posedb_options o = {0};
    o.features = d;
    if (op) {
      cJSON *v;
      /* the integer options are used only as whole numbers in range (casting 1e30 to int is
       * undefined behaviour); a value outside is the file's error. cv_folds may be negative
       * (the API's int: anything under 2 is no cross-validation). */
      static const char *const ikeys[] = {"tree_max_depth", "mirror", "kernel", "cv_folds"};
      static const double ilo[] = {-1e6, 0, 0, -1e6};
      static const double ihi[] = {1e6, KM_POSE_MIRROR_NONE, KM_SVM_LINEAR, 1e6};
      int iv[4] = {0};
      for (int k = 0; k < 4 && !s; ++k) {
        v = cJSON_GetObjectItemCaseSensitive(op, ikeys[k]);
        if (!v) continue;
        int64_t x;
        if (!cJSON_IsNumber(v) || !km__whole_number(v->valuedouble, ilo[k], ihi[k], &x))
          s = km__fail(err, KM_ERR_PARSE, "options.%s is not a whole number from %.0f to %.0f",
                       ikeys[k], ilo[k], ihi[k]); /* km__wrap below names the file */
        else
          iv[k] = (int)x;
      }
      o.tree_max_depth = iv[0];
      o.mirror = (km_pose_mirror)iv[1];
      o.kernel = (km_svm_kernel)iv[2];
      o.cv_folds = iv[3];
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "svm_c")))
        o.svm_c = v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "svm_gamma")))
        o.svm_gamma = v->valuedouble;
    }
    db->opt = km__posedb_defaults(&o, nl);
    int32_t mirror[KM_POSE_MAX_LANDMARKS];
    if (!s) s = km__landmark_mirrors(db->lm, nl, mirror, err);
    if (!s && version == 1) s = finish(db, tri, d, err);
    if (!s && version == 2)
      s = restore_model(db, mirror, tri, d, k, l, sla, sna, data + 20 + hl + nf * 12 + nm * nv * 24,
                        err);
    if (s) km__wrap(err, s, "%s", path);
  }
  free(tri);
  if (!s) {
    db->report.samples = nm;
    db->report.classes = nc;
    db->report.features = d;
    db->report.cv_accuracy = -1;
    db->report.cv_accuracy_eq8 = -1;
    if (rp) {
      cJSON *v;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(rp, "cv_accuracy")))
        db->report.cv_accuracy = v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(rp, "cv_accuracy_eq8")))
        db->report.cv_accuracy_eq8 = v->valuedouble;
      size_t folds;
      if (get_size(rp, "cv_folds", 1000000, &folds)) db->report.cv_folds = folds;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(rp, "build_ms")))
        db->report.build_ms = v->valuedouble;
    }
  }
done:
  cJSON_Delete(root);
  free(data);
  if (s) km_posedb_free(&db);
  *out = db;
  return s;
}

void km_posedb_info(const km_posedb *db, km_posedb_report *r) {
  if (!r) return;
  if (db)
    *r = db->report;
  else
    memset(r, 0, sizeof *r);
}
