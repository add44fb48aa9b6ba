/* CART decision tree (Breiman et al. 1984) with Gini impurity, for feature selection.
 *
 * Written by hand: no Debian-packaged C library does CART (libsvm, liblbfgs, LAPACK and the
 * SuiteSparse family have none; the usual implementations are scikit-learn (Python/Cython),
 * OpenCV's ml module (C++) and R's rpart, none of which we may link from C here). The tree is
 * small (hundreds to a few thousand samples, ~1,700 angle features), so the plain
 * sort-per-node split search is fast enough: O(F n log n) per tree level. */
#include "internal.h"

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
  const double *X;
  const int32_t *y;
  size_t n, nf, nc;
  int max_depth;
  double *imp;
  km_cart *tree;
  /* scratch */
  struct pair {
    double v;
    int32_t i;
  } * pairs;
  size_t *cnt_left, *cnt_node;
} fit_ctx;

static int cmp_pair(const void *a, const void *b) {
  const struct pair *p = a, *q = b;
  if (p->v < q->v) return -1;
  if (p->v > q->v) return 1;
  return (p->i > q->i) - (p->i < q->i);
}

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

/* idx: the node's samples (reordered in place into left | right). Returns node id or -1 on
 * out-of-memory. */
static int32_t grow(fit_ctx *c, int32_t *idx, size_t m, int depth) {
  int32_t id = new_node(c->tree);
  if (id < 0) return -1;
  size_t *cnt = c->cnt_node;
  memset(cnt, 0, c->nc * sizeof *cnt);
  for (size_t a = 0; a < m; ++a)
    ++cnt[c->y[idx[a]]];
  size_t best_c = 0;
  for (size_t k = 1; k < c->nc; ++k)
    if (cnt[k] > cnt[best_c]) best_c = k;
  c->tree->nodes[id].label = (int32_t)best_c;
  double g = gini(cnt, c->nc, m);
  if (g <= 0 || m < 2 || (c->max_depth > 0 && depth >= c->max_depth)) return id;

  double best_gain = 1e-12;
  int32_t best_f = -1;
  double best_thr = 0;
  size_t *cl = c->cnt_left;
  /* Right counts are node counts minus left counts, so only the left side is tracked. */
  size_t *tot = malloc(c->nc * sizeof *tot);
  if (!tot) return -1;
  memcpy(tot, cnt, c->nc * sizeof *tot);
  for (size_t f = 0; f < c->nf; ++f) {
    for (size_t a = 0; a < m; ++a) {
      c->pairs[a].v = c->X[(size_t)idx[a] * c->nf + f];
      c->pairs[a].i = idx[a];
    }
    qsort(c->pairs, m, sizeof *c->pairs, cmp_pair);
    if (!(c->pairs[0].v < c->pairs[m - 1].v)) continue;
    memset(cl, 0, c->nc * sizeof *cl);
    double sl = 0; /* sum of squared left counts, kept incrementally */
    double sr = 0;
    for (size_t k = 0; k < c->nc; ++k)
      sr += (double)tot[k] * (double)tot[k];
    for (size_t a = 0; a + 1 < m; ++a) {
      size_t k = (size_t)c->y[c->pairs[a].i];
      sl += 2.0 * (double)cl[k] + 1;
      double r = (double)(tot[k] - cl[k]);
      sr -= 2.0 * r - 1;
      ++cl[k];
      if (!(c->pairs[a].v < c->pairs[a + 1].v)) continue;
      double nl = (double)(a + 1), nr = (double)(m - a - 1);
      double gl = 1 - sl / (nl * nl), gr = 1 - sr / (nr * nr);
      double gain = g - (nl * gl + nr * gr) / (double)m;
      if (gain > best_gain) {
        best_gain = gain;
        best_f = (int32_t)f;
        best_thr = 0.5 * (c->pairs[a].v + c->pairs[a + 1].v);
      }
    }
  }
  free(tot);
  if (best_f < 0) return id;
  if (c->imp) c->imp[best_f] += best_gain * (double)m;
  /* Partition idx by the split. */
  size_t lo = 0, hi = m;
  while (lo < hi) {
    if (c->X[(size_t)idx[lo] * c->nf + (size_t)best_f] <= best_thr)
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
  nd->feature = best_f;
  nd->threshold = best_thr;
  nd->left = l;
  nd->right = r;
  return id;
}

km_status km_cart_fit(const double *X, const int32_t *y, size_t n_samples, size_t n_features,
                      size_t n_classes, int max_depth, km_cart **out, double *importance,
                      km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_cart_fit: out is NULL");
  *out = NULL;
  if (!X || !y || n_samples == 0 || n_features == 0 || n_classes == 0)
    return km__fail(err, KM_ERR_INVALID, "km_cart_fit: empty or NULL training set");
  if (n_samples > INT32_MAX) return km__fail(err, KM_ERR_INVALID, "km_cart_fit: too many samples");
  for (size_t i = 0; i < n_samples; ++i)
    if (y[i] < 0 || (size_t)y[i] >= n_classes)
      return km__fail(err, KM_ERR_INVALID, "km_cart_fit: label %zu is %d, expected 0..%zu", i,
                      (int)y[i], n_classes - 1);
  for (size_t i = 0; i < n_samples * n_features; ++i)
    if (!isfinite(X[i]))
      return km__fail(err, KM_ERR_INVALID, "km_cart_fit: sample %zu feature %zu is not finite",
                      i / n_features, i % n_features);
  km_cart *t = calloc(1, sizeof *t);
  fit_ctx c = {X, y, n_samples, n_features, n_classes, max_depth, importance, t, NULL, NULL, NULL};
  int32_t *idx = km__malloc(n_samples, sizeof *idx);
  c.pairs = km__malloc(n_samples, sizeof *c.pairs);
  c.cnt_left = km__malloc(n_classes, sizeof(size_t));
  c.cnt_node = km__malloc(n_classes, sizeof(size_t));
  km_status s = KM_OK;
  if (!t || !idx || !c.pairs || !c.cnt_left || !c.cnt_node) {
    s = km__fail(err, KM_ERR_NOMEM, "km_cart_fit: out of memory");
    goto done;
  }
  t->n_features = n_features;
  t->n_classes = n_classes;
  if (importance) memset(importance, 0, n_features * sizeof *importance);
  for (size_t i = 0; i < n_samples; ++i)
    idx[i] = (int32_t)i;
  if (grow(&c, idx, n_samples, 0) < 0) {
    s = km__fail(err, KM_ERR_NOMEM, "km_cart_fit: out of memory");
    goto done;
  }
  if (importance) {
    double sum = 0;
    for (size_t f = 0; f < n_features; ++f)
      sum += importance[f];
    if (sum > 0)
      for (size_t f = 0; f < n_features; ++f)
        importance[f] /= sum;
  }
done:
  free(idx);
  free(c.pairs);
  free(c.cnt_left);
  free(c.cnt_node);
  if (s) km_cart_free(&t);
  *out = t;
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
