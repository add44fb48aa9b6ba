/* CART decision tree (Breiman et al. 1984) with Gini impurity, for feature selection.
 *
 * Written by hand: no Debian-packaged C library does CART (libsvm, liblbfgs, LAPACK and the
 * SuiteSparse family have none; the usual implementations are scikit-learn (Python/Cython),
 * OpenCV's ml module (C++) and R's rpart, none of which we may link from C here). The tree is
 * small (hundreds to a few thousand samples, ~1,700 angle features), so the plain
 * sort-per-node split search is fast enough: O(F n log n) per tree level. */
#include "transfer/pose.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct cart_node {
  int32_t feature; /* -1: leaf */
  double threshold;
  int32_t left, right;
  int32_t label;
} cart_node;

struct km_cart {
  size_t n_features, n_classes;
  cart_node *nodes;
  size_t n_nodes, cap;
};

typedef struct fit_ctx {
  const double *X;      /* row-major n x stride */
  size_t stride;        /* columns of X */
  const int32_t *order; /* per column of X, the n samples sorted by value */
  const int32_t *cols;  /* the nf columns the tree may use */
  const int32_t *y;
  size_t n, nf, nc;
  int max_depth;
  double *imp; /* nf */
  km_cart *tree;
  int32_t *mark; /* n: node id a sample belongs to */
  size_t *cnt_left, *cnt_node;
} fit_ctx;

static double gini(const size_t *cnt, size_t nc, size_t tot) {
  if (!tot) return 0;
  double s = 0;
  for (size_t c = 0; c < nc; ++c) {
    double p = (double)cnt[c] / (double)tot;
    s += p * p;
  }
  return 1 - s;
}

static int32_t new_node(km_cart *t) {
  if (t->n_nodes == t->cap) {
    size_t nc = t->cap ? 2 * t->cap : 64;
    cart_node *nn = realloc(t->nodes, nc * sizeof *nn);
    if (!nn) return -1;
    t->nodes = nn;
    t->cap = nc;
  }
  memset(&t->nodes[t->n_nodes], 0, sizeof(cart_node));
  t->nodes[t->n_nodes].feature = -1;
  return (int32_t)t->n_nodes++;
}

/* Grows the node whose samples are idx[0..m) (all with mark == id). Split search walks each
 * column's presorted order and skips samples of other nodes: O(n) per column and node, no
 * sorting after the one presort. Returns the node id, or -1 when out of memory. */
static int32_t grow(fit_ctx *c, int32_t *idx, size_t m, int depth) {
  int32_t id = new_node(c->tree);
  if (id < 0) return -1;
  for (size_t a = 0; a < m; ++a)
    c->mark[idx[a]] = id;
  size_t *cnt = c->cnt_node, *cl = c->cnt_left;
  memset(cnt, 0, c->nc * sizeof *cnt);
  for (size_t a = 0; a < m; ++a)
    ++cnt[c->y[idx[a]]];
  size_t best_c = 0;
  for (size_t k = 1; k < c->nc; ++k)
    if (cnt[k] > cnt[best_c]) best_c = k;
  c->tree->nodes[id].label = (int32_t)best_c;
  double g = gini(cnt, c->nc, m);
  if (g <= 0 || m < 2 || (c->max_depth > 0 && depth >= c->max_depth)) return id;

  double best_gain = 1e-12, best_thr = 0, best_gap = 0, sr0 = 0;
  int32_t best_f = -1;
  for (size_t k = 0; k < c->nc; ++k)
    sr0 += (double)cnt[k] * (double)cnt[k];
  for (size_t f = 0; f < c->nf; ++f) {
    size_t col = (size_t)c->cols[f];
    const int32_t *ord = c->order + col * c->n;
    memset(cl, 0, c->nc * sizeof *cl);
    double sl = 0, sr = sr0, prev_v = 0;
    double range =
        c->X[(size_t)ord[c->n - 1] * c->stride + col] - c->X[(size_t)ord[0] * c->stride + col];
    if (!(range > 0)) continue;
    size_t seen = 0;
    for (size_t q = 0; q < c->n && seen < m; ++q) {
      int32_t i = ord[q];
      if (c->mark[i] != id) continue;
      double v = c->X[(size_t)i * c->stride + col];
      if (seen > 0 && prev_v < v) {
        /* split between the previous sample and this one */
        double nl = (double)seen, nr = (double)(m - seen);
        double gain = g - (nl * (1 - sl / (nl * nl)) + nr * (1 - sr / (nr * nr))) / (double)m;
        /* Equal gains (common: many angles separate the same classes) go to the widest gap
         * (radians: all columns are angles), the split most likely to hold on new data. */
        double gap = v - prev_v;
        if (gain > best_gain + 1e-12 ||
            (gain > best_gain - 1e-12 && best_f >= 0 && gap > best_gap)) {
          best_gain = gain;
          best_gap = gap;
          best_f = (int32_t)f;
          best_thr = 0.5 * (prev_v + v);
        }
      }
      size_t k = (size_t)c->y[i];
      sl += 2.0 * (double)cl[k] + 1;
      sr -= 2.0 * (double)(cnt[k] - cl[k]) - 1;
      ++cl[k];
      ++seen;
      prev_v = v;
    }
  }
  if (best_f < 0) return id;
  if (c->imp) c->imp[best_f] += best_gain * (double)m;
  size_t col = (size_t)c->cols[best_f];
  size_t lo = 0, hi = m;
  while (lo < hi) {
    if (c->X[(size_t)idx[lo] * c->stride + col] <= best_thr)
      ++lo;
    else {
      --hi;
      int32_t tmp = idx[lo];
      idx[lo] = idx[hi];
      idx[hi] = tmp;
    }
  }
  int32_t l = grow(c, idx, lo, depth + 1);
  if (l < 0) return -1;
  int32_t r = grow(c, idx + lo, m - lo, depth + 1);
  if (r < 0) return -1;
  cart_node *nd = &c->tree->nodes[id];
  nd->feature = (int32_t)col;
  nd->threshold = best_thr;
  nd->left = l;
  nd->right = r;
  return id;
}

typedef struct sort_ctx_item {
  double v;
  int32_t i;
} sort_ctx_item;
static int cmp_item(const void *a, const void *b) {
  const sort_ctx_item *p = a, *q = b;
  if (p->v < q->v) return -1;
  if (p->v > q->v) return 1;
  return (p->i > q->i) - (p->i < q->i);
}

km_status km__cart_presort(const double *X, size_t n, size_t stride, int32_t *order,
                           km_error *err) {
  sort_ctx_item *it = km__malloc(n ? n : 1, sizeof *it);
  if (!it) return km__fail(err, KM_ERR_NOMEM, "CART: out of memory");
  for (size_t f = 0; f < stride; ++f) {
    for (size_t i = 0; i < n; ++i)
      it[i] = (sort_ctx_item){X[i * stride + f], (int32_t)i};
    qsort(it, n, sizeof *it, cmp_item);
    for (size_t i = 0; i < n; ++i)
      order[f * n + i] = it[i].i;
  }
  free(it);
  return KM_OK;
}

km_status km__cart_fit_presorted(const double *X, size_t stride, const int32_t *order,
                                 const int32_t *cols, size_t n_cols, const int32_t *y,
                                 size_t n_samples, size_t n_classes, int max_depth, km_cart **out,
                                 double *importance, km_error *err) {
  *out = NULL;
  km_cart *t = calloc(1, sizeof *t);
  fit_ctx c = {X,         stride,    order,      cols, y,    n_samples, n_cols,
               n_classes, max_depth, importance, t,    NULL, NULL,      NULL};
  int32_t *idx = km__malloc(n_samples, sizeof *idx);
  c.mark = km__malloc(n_samples, sizeof *c.mark);
  c.cnt_left = km__malloc(n_classes, sizeof(size_t));
  c.cnt_node = km__malloc(n_classes, sizeof(size_t));
  km_status s = KM_OK;
  if (!t || !idx || !c.mark || !c.cnt_left || !c.cnt_node) {
    s = km__fail(err, KM_ERR_NOMEM, "km_cart_fit: out of memory");
    goto done;
  }
  t->n_features = stride;
  t->n_classes = n_classes;
  if (importance) memset(importance, 0, n_cols * sizeof *importance);
  for (size_t i = 0; i < n_samples; ++i)
    idx[i] = (int32_t)i;
  if (grow(&c, idx, n_samples, 0) < 0) {
    s = km__fail(err, KM_ERR_NOMEM, "km_cart_fit: out of memory");
    goto done;
  }
  if (importance) {
    double sum = 0;
    for (size_t f = 0; f < n_cols; ++f)
      sum += importance[f];
    if (sum > 0)
      for (size_t f = 0; f < n_cols; ++f)
        importance[f] /= sum;
  }
done:
  free(idx);
  free(c.mark);
  free(c.cnt_left);
  free(c.cnt_node);
  if (s) km_cart_free(&t);
  *out = t;
  return s;
}

km_status km_cart_fit(const double *X, const int32_t *y, size_t n_samples, size_t n_features,
                      size_t n_classes, int max_depth, km_cart **out, double *importance,
                      km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_cart_fit: out is NULL");
  *out = NULL;
  if (!X || !y || n_samples == 0 || n_features == 0 || n_classes == 0)
    return km__fail(err, KM_ERR_INVALID, "km_cart_fit: empty or NULL training set");
  if (n_samples > INT32_MAX || n_features > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "km_cart_fit: too many samples or features");
  for (size_t i = 0; i < n_samples; ++i)
    if (y[i] < 0 || (size_t)y[i] >= n_classes)
      return km__fail(err, KM_ERR_INVALID, "km_cart_fit: label %zu is %d, expected 0..%zu", i,
                      (int)y[i], n_classes - 1);
  for (size_t i = 0; i < n_samples * n_features; ++i)
    if (!isfinite(X[i]))
      return km__fail(err, KM_ERR_INVALID, "km_cart_fit: sample %zu feature %zu is not finite",
                      i / n_features, i % n_features);
  int32_t *order = km__malloc(n_samples * n_features, sizeof *order);
  int32_t *cols = km__malloc(n_features, sizeof *cols);
  km_status s = KM_OK;
  if (!order || !cols) s = km__fail(err, KM_ERR_NOMEM, "km_cart_fit: out of memory");
  if (!s) s = km__cart_presort(X, n_samples, n_features, order, err);
  if (!s) {
    for (size_t f = 0; f < n_features; ++f)
      cols[f] = (int32_t)f;
    s = km__cart_fit_presorted(X, n_features, order, cols, n_features, y, n_samples, n_classes,
                               max_depth, out, importance, err);
  }
  free(order);
  free(cols);
  return s;
}

int32_t km_cart_predict(const km_cart *t, const double *x) {
  if (!t || !t->n_nodes || !x) return -1;
  int32_t id = 0;
  while (t->nodes[id].feature >= 0)
    id = x[t->nodes[id].feature] <= t->nodes[id].threshold ? t->nodes[id].left : t->nodes[id].right;
  return t->nodes[id].label;
}

size_t km_cart_nodes(const km_cart *t) { return t ? t->n_nodes : 0; }

void km_cart_free(km_cart **t) {
  if (!t || !*t) return;
  free((*t)->nodes);
  free(*t);
  *t = NULL;
}
