/* Pose database: templates of one connectivity with pose classes; recognition by selected
 * angles + SVM, template retrieval by nearest neighbour inside the predicted class (section
 * 3.3). File format (version 1, little endian):
 *   "KMPOSEDB" | u32 version | u64 header bytes | header JSON | int32 F[n_faces*3] |
 *   f64 V[n_meshes*n_vertices*3] | u64 FNV-1a of everything before it
 * The JSON holds counts, landmarks, class names, labels, groups, the selected features, the
 * options and the build report. The SVM is not stored: it is retrained on load from the
 * templates with the stored features, which is deterministic and avoids libsvm's model files
 * (svm_save_model/svm_load_model only work on their own paths, not inside our file). */
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

/* Landmark positions of every template into db->P; model training; descriptors for NN. */
static km_status finish(km_posedb *db, const int32_t *fixed, size_t fixed_d, km_error *err) {
  size_t nl = db->nl;
  for (size_t i = 0; i < db->n_meshes; ++i)
    for (size_t a = 0; a < nl; ++a)
      memcpy(db->P + (i * nl + a) * 3, db->V + (i * db->n_vertices + (size_t)db->lm[a].vertex) * 3,
             3 * sizeof(double));
  for (size_t i = 0; i < db->n_meshes * nl * 3; ++i)
    if (!isfinite(db->P[i]))
      return km__fail(err, KM_ERR_INVALID, "pose database: mesh %zu has a non-finite landmark",
                      i / (nl * 3));
  km_status s = km__pose_model_train(db->P, db->labels, db->n_meshes, db->n_classes, db->lm, nl,
                                     &db->opt, fixed, fixed_d, &db->model, err);
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
  uint32_t version = 1;
  uint64_t hl = strlen(json);
  hw(&w, "KMPOSEDB", 8);
  hw(&w, &version, 4);
  hw(&w, &hl, 8);
  hw(&w, json, hl);
  free(json);
  hw(&w, db->F, db->n_faces * 3 * sizeof(int32_t));
  hw(&w, db->V, db->n_meshes * db->n_vertices * 3 * sizeof(double));
  uint64_t h = w.h;
  fwrite(&h, 1, 8, af.f);
  return km__atomic_commit(&af, err);
}

static bool get_size(cJSON *o, const char *k, size_t max, size_t *out) {
  cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  if (!cJSON_IsNumber(v) || !(v->valuedouble >= 0) || v->valuedouble > (double)max ||
      v->valuedouble != floor(v->valuedouble))
    return false;
  *out = (size_t)v->valuedouble;
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
  if (version != 1) {
    s = km__fail(err, KM_ERR_UNSUPPORTED, "%s: byte 8: version %u, this build reads version 1",
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
  /* Sizes are checked against the file before anything is allocated. */
  if (nv == 0 || nm < 2 || nf > body / 12 || nm > body / 24 / nv ||
      nf * 12 + nm * nv * 24 != body) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s: %zu meshes x %zu vertices and %zu faces do not match the %zu data bytes",
                 path, nm, nv, nf, body);
    goto done;
  }
  if (nl < 4 || nl > KM_POSE_MAX_LANDMARKS || nc < 1 || (size_t)cJSON_GetArraySize(lb) != nm ||
      (gr && (!cJSON_IsArray(gr) || (size_t)cJSON_GetArraySize(gr) != nm)) || d < 1 ||
      d > km_pose_candidate_count(nl)) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s: inconsistent header (landmarks, classes, labels, features)", path);
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
    if (!cJSON_IsString(a) || !cJSON_IsString(c) || !cJSON_IsNumber(b) ||
        strlen(a->valuestring) > 31 || strlen(c->valuestring) > 31 || !(b->valuedouble >= 0) ||
        b->valuedouble >= (double)nv) {
      s = km__fail(err, KM_ERR_PARSE, "%s: landmark %zu is malformed", path, i);
      break;
    }
    strcpy(db->lm[i].name, a->valuestring);
    strcpy(db->lm[i].mirror, c->valuestring);
    db->lm[i].vertex = (int32_t)b->valuedouble;
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
      if (!cJSON_IsNumber(it) || !(it->valuedouble >= 0) || it->valuedouble >= (double)nc) {
        s = km__fail(err, KM_ERR_PARSE, "%s: label %zu is not a class index", path, i);
        break;
      }
      db->labels[i++] = (int32_t)it->valuedouble;
    }
  i = 0;
  if (!s && gr) cJSON_ArrayForEach(it, gr) {
      db->groups[i++] = cJSON_IsNumber(it) ? (int32_t)it->valuedouble : 0;
    }
  i = 0;
  if (!s) cJSON_ArrayForEach(it, fe) {
      bool ok = cJSON_IsArray(it) && cJSON_GetArraySize(it) == 3;
      for (int k = 0; ok && k < 3; ++k) {
        cJSON *v = cJSON_GetArrayItem(it, k);
        ok = cJSON_IsNumber(v) && v->valuedouble >= 0 && v->valuedouble < (double)nl;
        if (ok) tri[3 * i + k] = (int32_t)v->valuedouble;
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
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "tree_max_depth")))
        o.tree_max_depth = (int)v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "mirror")))
        o.mirror = (km_pose_mirror)(int)v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "kernel")))
        o.kernel = (km_svm_kernel)(int)v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "svm_c")))
        o.svm_c = v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "svm_gamma")))
        o.svm_gamma = v->valuedouble;
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(op, "cv_folds")))
        o.cv_folds = (int)v->valuedouble;
    }
    if (o.mirror > KM_POSE_MIRROR_NONE) o.mirror = KM_POSE_MIRROR_SELECTION;
    if (o.kernel > KM_SVM_LINEAR) o.kernel = KM_SVM_RBF;
    db->opt = km__posedb_defaults(&o, nl);
    int32_t mirror[KM_POSE_MAX_LANDMARKS];
    s = km__landmark_mirrors(db->lm, nl, mirror, err);
    if (!s) s = finish(db, tri, d, err);
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
      if (cJSON_IsNumber(v = cJSON_GetObjectItemCaseSensitive(rp, "cv_folds")) &&
          v->valuedouble >= 0)
        db->report.cv_folds = (size_t)v->valuedouble;
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
