/* Pose recogniser: CART-based selection of the d most salient angles (section 3.2.1), then a
 * libsvm classifier over the selected, range-scaled angles (section 3.3).
 *
 * Mirroring (the paper: "when an incident angle (v_i,v_j,v_k) is observed in the data, we also
 * add an instance of (v_m(i),v_m(j),v_m(k))"): we read it as data augmentation. A mirrored
 * instance of a pose is the same pose with every landmark swapped with its counterpart, so its
 * angle (i,j,k) is the original angle (m(i),m(j),m(k)); it keeps the class of the original.
 * By default the augmentation feeds only the selection trees (the paper gives it as the cure
 * for imbalance in selection), so the chosen angles cover both sides; see km_pose_mirror. */
#include "transfer/pose.h"

#include <libsvm/svm.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

km_posedb_options km__posedb_defaults(const km_posedb_options *opt, size_t n_landmarks) {
  km_posedb_options o = opt ? *opt : (km_posedb_options){0};
  size_t cand = km_pose_candidate_count(n_landmarks);
  if (o.features == 0) o.features = 60;
  if (o.features > cand) o.features = cand;
  if (o.tree_max_depth <= 0) o.tree_max_depth = 16;
  if (!(o.svm_c > 0)) o.svm_c = 10;
  if (!(o.svm_gamma > 0)) o.svm_gamma = o.features ? 1.0 / (double)o.features : 1;
  if (o.cv_folds == 0) o.cv_folds = 5;
  return o;
}

static void quiet(const char *s) { (void)s; }

void km__pose_model_free(km__pose_model *m) {
  if (!m) return;
  if (m->svm) {
    struct svm_model *sm = m->svm;
    svm_free_and_destroy_model(&sm);
  }
  free(m->triples);
  free(m->lo);
  free(m->hi);
  free(m->nodes);
  free(m->y);
  free(m->xptr);
  memset(m, 0, sizeof *m);
}

typedef struct ranked {
  double v;
  int32_t f;
} ranked;
static int cmp_ranked_desc(const void *a, const void *b) {
  const ranked *p = a, *q = b;
  if (p->v > q->v) return -1;
  if (p->v < q->v) return 1;
  return (p->f > q->f) - (p->f < q->f);
}

/* Picks d candidate features: grow a tree on the candidates left, take the features it used
 * (by Gini importance), remove them, repeat; a tree that uses none ends the loop and the rest
 * is filled by variance (the paper observes the selected angles are the high-variance ones). */
static km_status select_features(const double *P, const int32_t *y, size_t n, size_t nc, size_t nl,
                                 const int32_t *mirror, bool augment, const km_posedb_options *o,
                                 int32_t *sel, km_error *err) {
  size_t F = km_pose_candidate_count(nl), rows = augment ? 2 * n : n, d = o->features;
  int32_t *all = km__malloc(F * 3, sizeof *all);
  double *A = km__malloc(rows * F, sizeof *A);          /* all candidate angles */
  int32_t *order = km__malloc(rows * F, sizeof *order); /* presorted columns */
  int32_t *yy = km__malloc(rows, sizeof *yy), *cols = km__malloc(F, sizeof *cols);
  double *imp = km__malloc(F, sizeof *imp);
  ranked *rk = km__malloc(F, sizeof *rk);
  double *Pm = km__malloc(nl * 3, sizeof *Pm);
  bool *used = km__calloc(F, sizeof *used);
  km_status s = KM_OK;
  if (!all || !A || !order || !yy || !cols || !imp || !rk || !Pm || !used) {
    s = km__fail(err, KM_ERR_NOMEM, "pose feature selection: out of memory (%zu x %zu)", rows, F);
    goto done;
  }
  for (size_t f = 0; f < F; ++f)
    km_pose_candidate(nl, f, all + 3 * f);
  for (size_t i = 0; i < n; ++i) {
    km_pose_angles(P + i * nl * 3, all, F, A + i * F);
    yy[i] = y[i];
    if (augment) {
      for (size_t a = 0; a < nl; ++a)
        memcpy(Pm + 3 * a, P + i * nl * 3 + 3 * (size_t)mirror[a], 3 * sizeof(double));
      km_pose_angles(Pm, all, F, A + (n + i) * F);
      yy[n + i] = y[i];
    }
  }
  s = km__cart_presort(A, rows, F, order, err);
  if (s) goto done;
  size_t got = 0;
  while (got < d) {
    size_t m = 0;
    for (size_t f = 0; f < F; ++f)
      if (!used[f]) cols[m++] = (int32_t)f;
    if (m == 0) break;
    km_cart *tree = NULL;
    s = km__cart_fit_presorted(A, F, order, cols, m, yy, rows, nc, o->tree_max_depth, &tree, imp,
                               err);
    km_cart_free(&tree);
    if (s) goto done;
    size_t k = 0;
    for (size_t c = 0; c < m; ++c)
      if (imp[c] > 0) rk[k++] = (ranked){imp[c], cols[c]};
    if (k == 0) break;
    qsort(rk, k, sizeof *rk, cmp_ranked_desc);
    for (size_t a = 0; a < k && got < d; ++a) {
      sel[got++] = rk[a].f;
      used[rk[a].f] = true;
    }
  }
  if (got < d) {
    size_t k = 0;
    for (size_t f = 0; f < F; ++f) {
      if (used[f]) continue;
      double mu = 0, v = 0;
      for (size_t r = 0; r < rows; ++r)
        mu += A[r * F + f];
      mu /= (double)rows;
      for (size_t r = 0; r < rows; ++r)
        v += (A[r * F + f] - mu) * (A[r * F + f] - mu);
      rk[k++] = (ranked){v, (int32_t)f};
    }
    qsort(rk, k, sizeof *rk, cmp_ranked_desc);
    for (size_t a = 0; a < k && got < d; ++a)
      sel[got++] = rk[a].f;
  }
done:
  free(all);
  free(A);
  free(order);
  free(yy);
  free(cols);
  free(imp);
  free(rk);
  free(Pm);
  free(used);
  return s;
}

void km__pose_model_features(const km__pose_model *m, const double *P, double *x) {
  km_pose_angles(P, m->triples, m->d, x);
  for (size_t f = 0; f < m->d; ++f) {
    double w = m->hi[f] - m->lo[f];
    x[f] = w > 0 ? 2 * (x[f] - m->lo[f]) / w - 1 : 0;
  }
}

int32_t km__pose_model_predict_scaled(const km__pose_model *m, const double *x) {
  /* Stack nodes: d is at most the candidate count (a few thousand), bounded by the caller. */
  struct svm_node buf[257], *nodes = buf, *heap = NULL;
  if (m->d + 1 > sizeof buf / sizeof buf[0]) {
    heap = km__malloc(m->d + 1, sizeof *heap);
    if (!heap) return -1;
    nodes = heap;
  }
  for (size_t f = 0; f < m->d; ++f)
    nodes[f] = (struct svm_node){(int)f + 1, x[f]};
  nodes[m->d].index = -1;
  double r = svm_predict(m->svm, nodes);
  free(heap);
  return (int32_t)lround(r);
}

km_status km__pose_model_train(const double *P, const int32_t *y, size_t n, size_t nc,
                               const km_landmark *lm, size_t nl, const km_posedb_options *opt,
                               const int32_t *fixed_triples, size_t fixed_d, km__pose_model *m,
                               km_error *err) {
  memset(m, 0, sizeof *m);
  km_posedb_options o = km__posedb_defaults(opt, nl);
  int32_t mirror[KM_POSE_MAX_LANDMARKS];
  if (nl < 4 || nl > KM_POSE_MAX_LANDMARKS)
    return km__fail(err, KM_ERR_INVALID, "pose model: %zu landmarks, expected 4..%d", nl,
                    KM_POSE_MAX_LANDMARKS);
  km_status s = km__landmark_mirrors(lm, nl, mirror, err);
  if (s) return s;
  size_t d = fixed_triples ? fixed_d : o.features;
  m->n_landmarks = nl;
  m->d = d;
  m->n_classes = nc;
  m->triples = km__malloc(d * 3, sizeof(int32_t));
  m->lo = km__malloc(d, sizeof(double));
  m->hi = km__malloc(d, sizeof(double));
  bool aug_svm = o.mirror == KM_POSE_MIRROR_ALL;
  size_t rows = aug_svm ? 2 * n : n;
  double *X = km__malloc(rows * d, sizeof *X);
  double *Pm = km__malloc(nl * 3, sizeof *Pm);
  int32_t *sel = km__malloc(d, sizeof *sel);
  m->nodes = km__malloc(rows * (d + 1), sizeof(struct svm_node));
  m->y = km__malloc(rows, sizeof(double));
  m->xptr = km__malloc(rows, sizeof(struct svm_node *));
  if (!m->triples || !m->lo || !m->hi || !X || !Pm || !sel || !m->nodes || !m->y || !m->xptr) {
    s = km__fail(err, KM_ERR_NOMEM, "pose model: out of memory");
    goto done;
  }
  if (fixed_triples) {
    memcpy(m->triples, fixed_triples, d * 3 * sizeof(int32_t));
    for (size_t f = 0; f < d * 3; ++f)
      if (m->triples[f] < 0 || (size_t)m->triples[f] >= nl) {
        s = km__fail(err, KM_ERR_INVALID, "pose model: feature %zu names landmark %d of %zu", f / 3,
                     (int)m->triples[f], nl);
        goto done;
      }
  } else {
    s = select_features(P, y, n, nc, nl, mirror, o.mirror != KM_POSE_MIRROR_NONE, &o, sel, err);
    if (s) goto done;
    for (size_t f = 0; f < d; ++f)
      km_pose_candidate(nl, (size_t)sel[f], m->triples + 3 * f);
  }
  for (size_t i = 0; i < n; ++i) {
    km_pose_angles(P + i * nl * 3, m->triples, d, X + i * d);
    if (aug_svm) {
      for (size_t a = 0; a < nl; ++a)
        memcpy(Pm + 3 * a, P + i * nl * 3 + 3 * (size_t)mirror[a], 3 * sizeof(double));
      km_pose_angles(Pm, m->triples, d, X + (n + i) * d);
    }
  }
  for (size_t f = 0; f < d; ++f) {
    m->lo[f] = INFINITY, m->hi[f] = -INFINITY;
    for (size_t r = 0; r < rows; ++r) {
      double v = X[r * d + f];
      if (v < m->lo[f]) m->lo[f] = v;
      if (v > m->hi[f]) m->hi[f] = v;
    }
  }
  struct svm_node *nodes = m->nodes;
  struct svm_node **xp = m->xptr;
  for (size_t r = 0; r < rows; ++r) {
    struct svm_node *row = nodes + r * (d + 1);
    for (size_t f = 0; f < d; ++f) {
      double w = m->hi[f] - m->lo[f];
      row[f].index = (int)f + 1;
      row[f].value = w > 0 ? 2 * (X[r * d + f] - m->lo[f]) / w - 1 : 0;
    }
    row[d].index = -1;
    row[d].value = 0;
    xp[r] = row;
    m->y[r] = (double)y[r < n ? r : r - n];
  }
  struct svm_problem prob = {(int)rows, m->y, xp};
  struct svm_parameter par;
  memset(&par, 0, sizeof par);
  par.svm_type = C_SVC;
  par.kernel_type = o.kernel == KM_SVM_LINEAR ? LINEAR : RBF;
  par.gamma = o.svm_gamma;
  par.C = o.svm_c;
  par.cache_size = 20;
  par.eps = 1e-3;
  par.shrinking = 1;
  const char *bad = svm_check_parameter(&prob, &par);
  if (bad) {
    s = km__fail(err, KM_ERR_INVALID, "pose model: libsvm rejects the parameters: %s", bad);
    goto done;
  }
  /* libsvm prints training progress to stdout unless told otherwise; the library is silent. */
  svm_set_print_string_function(quiet);
  m->svm = svm_train(&prob, &par);
  if (!m->svm) s = km__fail(err, KM_ERR_NOMEM, "pose model: libsvm training failed");
done:
  free(X);
  free(Pm);
  free(sel);
  if (s) km__pose_model_free(m);
  return s;
}

void km__pose_model_svm(const km__pose_model *m, km__pose_svm *out) {
  memset(out, 0, sizeof *out);
  const struct svm_model *sm = m ? m->svm : NULL;
  if (!sm) return;
  out->nr_class = sm->nr_class;
  out->l = sm->l;
  out->label = sm->label;
  out->n_sv = sm->nSV;
  out->sv_row1 = sm->sv_indices;
  out->rho = sm->rho;
  out->coef = (const double *const *)sm->sv_coef;
}

km_status km__pose_model_restore(km__pose_model *m, size_t nl, const int32_t *mirror,
                                 const int32_t *triples, size_t d, const double *lo,
                                 const double *hi, const km_posedb_options *o, int nr_class, int l,
                                 const int *label, const int *n_sv, const double *rho,
                                 const double *coef, const int32_t *sv_row, size_t rows,
                                 const double *desc, const double *P, size_t n, size_t nc,
                                 km_error *err) {
  memset(m, 0, sizeof *m);
  if (nr_class < 1 || (size_t)nr_class > nc || l < 0 || (size_t)l > rows || d < 1 ||
      nl > KM_POSE_MAX_LANDMARKS)
    return km__fail(err, KM_ERR_PARSE, "pose model: %d classes, %d support vectors of %zu rows",
                    nr_class, l, rows);
  long sum = 0;
  for (int c = 0; c < nr_class; ++c) {
    if (label[c] < 0 || (size_t)label[c] >= nc || n_sv[c] < 0)
      return km__fail(err, KM_ERR_PARSE, "pose model: class %d is label %d with %d vectors", c,
                      label[c], n_sv[c]);
    sum += n_sv[c];
  }
  if (sum != l)
    return km__fail(err, KM_ERR_PARSE, "pose model: %ld support vectors by class, %d in all", sum,
                    l);
  for (int i = 0; i < l; ++i)
    if (sv_row[i] < 0 || (size_t)sv_row[i] >= rows || (size_t)sv_row[i] >= 2 * n)
      return km__fail(err, KM_ERR_PARSE, "pose model: support vector %d is row %d of %zu", i,
                      (int)sv_row[i], rows);
  for (size_t f = 0; f < d * 3; ++f)
    if (triples[f] < 0 || (size_t)triples[f] >= nl)
      return km__fail(err, KM_ERR_PARSE, "pose model: feature %zu names landmark %d of %zu", f / 3,
                      (int)triples[f], nl);
  size_t nrho = (size_t)nr_class * (size_t)(nr_class - 1) / 2, k1 = (size_t)nr_class - 1;
  m->n_landmarks = nl;
  m->d = d;
  m->n_classes = nc;
  m->triples = km__malloc(d * 3, sizeof(int32_t));
  m->lo = km__malloc(d, sizeof(double));
  m->hi = km__malloc(d, sizeof(double));
  m->nodes = km__malloc((size_t)(l ? l : 1), (d + 1) * sizeof(struct svm_node));
  struct svm_model *sm = calloc(1, sizeof *sm);
  double *Pm = km__malloc(nl * 3, sizeof *Pm), *x = km__malloc(d, sizeof *x);
  km_status s = KM_OK;
  if (sm) {
    m->svm = sm;
    sm->nr_class = nr_class;
    sm->l = l;
    sm->free_sv = 0; /* the rows live in m->nodes */
    sm->SV = km__malloc((size_t)(l ? l : 1), sizeof *sm->SV);
    sm->sv_coef = km__calloc(k1 ? k1 : 1, sizeof *sm->sv_coef);
    sm->rho = km__malloc(nrho ? nrho : 1, sizeof *sm->rho);
    sm->label = km__malloc((size_t)nr_class, sizeof *sm->label);
    sm->nSV = km__malloc((size_t)nr_class, sizeof *sm->nSV);
    sm->sv_indices = km__malloc((size_t)(l ? l : 1), sizeof *sm->sv_indices);
  }
  bool ok = sm && m->triples && m->lo && m->hi && m->nodes && Pm && x && sm->SV && sm->sv_coef &&
            sm->rho && sm->label && sm->nSV && sm->sv_indices;
  for (size_t r = 0; ok && r < k1; ++r)
    ok = (sm->sv_coef[r] = km__malloc((size_t)(l ? l : 1), sizeof(double))) != NULL;
  if (!ok) {
    s = km__fail(err, KM_ERR_NOMEM, "pose model: out of memory (%d support vectors x %zu)", l, d);
    goto done;
  }
  memcpy(m->triples, triples, d * 3 * sizeof(int32_t));
  memcpy(m->lo, lo, d * sizeof(double));
  memcpy(m->hi, hi, d * sizeof(double));
  sm->param.svm_type = C_SVC;
  sm->param.kernel_type = o->kernel == KM_SVM_LINEAR ? LINEAR : RBF;
  sm->param.gamma = o->svm_gamma;
  sm->param.C = o->svm_c;
  memcpy(sm->label, label, (size_t)nr_class * sizeof(int));
  memcpy(sm->nSV, n_sv, (size_t)nr_class * sizeof(int));
  if (nrho) memcpy(sm->rho, rho, nrho * sizeof(double));
  for (size_t r = 0; r < k1; ++r)
    if (l) memcpy(sm->sv_coef[r], coef + r * (size_t)l, (size_t)l * sizeof(double));
  struct svm_node *nodes = m->nodes;
  for (int i = 0; i < l; ++i) {
    size_t row = (size_t)sv_row[i];
    struct svm_node *sv = nodes + (size_t)i * (d + 1);
    const double *v = desc + row * d;
    if (row >= n) { /* a mirrored sample: every landmark swapped with its counterpart */
      for (size_t a = 0; a < nl; ++a)
        memcpy(Pm + 3 * a, P + (row - n) * nl * 3 + 3 * (size_t)mirror[a], 3 * sizeof(double));
      km__pose_model_features(m, Pm, x);
      v = x;
    }
    for (size_t f = 0; f < d; ++f)
      sv[f] = (struct svm_node){(int)f + 1, v[f]};
    sv[d] = (struct svm_node){-1, 0};
    sm->SV[i] = sv;
    sm->sv_indices[i] = (int)row + 1;
  }
done:
  free(Pm);
  free(x);
  if (s) km__pose_model_free(m);
  return s;
}
