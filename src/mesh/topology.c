/* Mesh statistics (km_mesh_info_compute), bounding box and vertex adjacency.
 *
 * Edges are found by sorting packed (min,max) vertex pairs. A radix sort is used instead of
 * qsort: the keys are plain 64-bit integers and 8 byte-passes beat a comparison sort's
 * indirect calls by ~5x at a million faces. No dependency in the project offers one. */
#include "core/core.h"
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* LSD radix sort of n 64-bit keys using tmp (n entries) as scratch. Passes whose byte is the
 * same for every key are skipped, so small meshes only pay for the bytes they use. */
static void radix_sort_u64(uint64_t *a, uint64_t *tmp, size_t n) {
  uint64_t *src = a, *dst = tmp;
  for (int shift = 0; shift < 64; shift += 8) {
    size_t count[256] = {0};
    for (size_t i = 0; i < n; ++i)
      ++count[(src[i] >> shift) & 0xff];
    if (n && count[(src[0] >> shift) & 0xff] == n) continue;
    size_t sum = 0;
    for (int b = 0; b < 256; ++b) {
      size_t c = count[b];
      count[b] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; ++i)
      dst[count[(src[i] >> shift) & 0xff]++] = src[i];
    uint64_t *t = src;
    src = dst;
    dst = t;
  }
  if (src != a) memcpy(a, src, n * sizeof *a);
}

static km_status check_faces(const km_mesh *m, const char *fn, km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "%s: mesh is NULL", fn);
  if ((m->n_vertices && !m->V) || (m->n_faces && !m->F))
    return km__fail(err, KM_ERR_INVALID, "%s: mesh has counts but NULL arrays", fn);
  if (m->n_vertices > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "%s: %zu vertices exceed the int32 index range", fn,
                    m->n_vertices);
  for (size_t i = 0; i < m->n_faces * 3; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= m->n_vertices)
      return km__fail(err, KM_ERR_INVALID, "%s: face %zu has vertex index %d outside [0, %zu)", fn,
                      i / 3, (int)m->F[i], m->n_vertices);
  return KM_OK;
}

/* Appends the undirected edges of face f as packed (min<<32 | max) keys; none for a face with
 * a repeated index (km__face_collapsed). */
static size_t face_edges(const int32_t *t, uint64_t *keys) {
  size_t n = 0;
  if (km__face_collapsed(t)) return 0;
  for (int k = 0; k < 3; ++k) {
    uint32_t a = (uint32_t)t[k], b = (uint32_t)t[(k + 1) % 3];
    if (a == b) continue;
    if (a > b) {
      uint32_t x = a;
      a = b;
      b = x;
    }
    uint64_t key = (uint64_t)a << 32 | b;
    bool dup = false;
    for (size_t j = 0; j < n; ++j)
      dup |= keys[j] == key;
    if (!dup) keys[n++] = key;
  }
  return n;
}

double km_bbox_diagonal(const double *V, size_t n_vertices) {
  if (!V || !n_vertices) return 0.0;
  double lo[3] = {V[0], V[1], V[2]}, hi[3] = {V[0], V[1], V[2]};
  for (size_t i = 1; i < n_vertices; ++i)
    for (int k = 0; k < 3; ++k) {
      double x = V[3 * i + (size_t)k];
      if (x < lo[k]) lo[k] = x;
      if (x > hi[k]) hi[k] = x;
    }
  double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
  return sqrt(dx * dx + dy * dy + dz * dz);
}

static uint64_t mix64(uint64_t x) { /* splitmix64's finaliser */
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/* km__coincident_lowest (mesh.h): one pass over an open-addressing table of the positions
 * (a sort before: with the weld run 8 times at start-up it was 8 % of a warm 100k-vertex
 * `animate`). */
km_status km__coincident_lowest(const double *V, size_t n, const bool *keep, int32_t *lo,
                                km_error *err) {
  size_t cap = 16;
  while (cap < 2 * n)
    cap *= 2;
  int32_t *slot = km__malloc(cap, sizeof *slot);
  if (!slot) return km__fail(err, KM_ERR_NOMEM, "coincident vertices: out of memory (%zu)", n);
  for (size_t i = 0; i < cap; ++i)
    slot[i] = -1;
  for (size_t v = 0; v < n; ++v) {
    lo[v] = (int32_t)v;
    if (keep && !keep[v]) continue;
    uint64_t b[3];
    memcpy(b, V + 3 * v, sizeof b);
    size_t h = (size_t)mix64(b[0] ^ mix64(b[1] ^ mix64(b[2]))) & (cap - 1);
    for (;; h = (h + 1) & (cap - 1)) {
      int32_t u = slot[h];
      if (u < 0) {
        slot[h] = (int32_t)v;
        break;
      }
      if (!memcmp(V + 3 * (size_t)u, b, sizeof b)) { /* u < v: taken in id order */
        lo[v] = u;
        break;
      }
    }
  }
  free(slot);
  return KM_OK;
}

/* Used vertices (vf_off[v + 1] > vf_off[v] after the degree count) that share their exact
 * position with another used vertex: the seams a glTF exporter cuts a textured mesh at. */
static km_status count_seam_vertices(const km_mesh *m, const int32_t *degree_off, size_t *out,
                                     km_error *err) {
  size_t nv = m->n_vertices;
  bool *used = km__malloc(nv ? nv : 1, sizeof *used);
  int32_t *lo = km__malloc(nv ? nv : 1, sizeof *lo), *size = km__calloc(nv ? nv : 1, sizeof *size);
  km_status s = KM_OK;
  if (!used || !lo || !size)
    s = km__fail(err, KM_ERR_NOMEM, "km_mesh_info_compute: cannot allocate for %zu vertices", nv);
  for (size_t v = 0; s == KM_OK && v < nv; ++v)
    used[v] = degree_off[v + 1] > 0;
  if (s == KM_OK) s = km__coincident_lowest(m->V, nv, used, lo, err);
  *out = 0;
  for (size_t v = 0; s == KM_OK && v < nv; ++v)
    size[lo[v]] += used[v];
  for (size_t v = 0; s == KM_OK && v < nv; ++v)
    *out += used[v] && size[lo[v]] > 1;
  free(used), free(lo), free(size);
  return s;
}

static km_status mesh_info(const km_mesh *m, bool seams, km_mesh_info *out, km_error *err);

void km__weld_free(km__weld *w) {
  if (!w) return;
  km_mesh_free(&w->w);
  free(w->to_w);
  free(w->first);
  memset(w, 0, sizeof *w);
}

void km__body_free(km__body *b) {
  if (!b) return;
  km_mesh_free(&b->body);
  free(b->to_body);
  free(b->from_body);
  free(b->rigid);
  free(b->piece);
  memset(b, 0, sizeof *b);
}

/* How a loose piece follows the body. One that wraps the body (it lies against it, half of its
 * vertices or more within KM_LOOSE_AGAINST of the body's bounding-box diagonal from it, none
 * further than KM_LOOSE_REACH, and it spans more than KM_LOOSE_WRAPS of that diagonal: a belt,
 * a shirt, a coat) keeps each vertex's own nearest body vertex and bends with the body under
 * it: a coat moved whole with one body point would leave the legs walking through it, the
 * worse mistake, so a piece half against the body counts as wrapping it. A prop reaching away
 * from the body does not, however much of it is held: a 0.5 m box with half its 8 vertices
 * inside armadillo_1k's hand (diagonal 1.5) counted as wrapping, and on a wave (gen motion
 * --kind wave) its edges bent to 0.56-1.02 of their length. Any other (eyes, teeth, a buckle, a
 * hair card, a sword held in a hand, its blade away from the body, a ground plane under the feet, a
 * scan's stray bit) follows one body vertex as a whole, the one nearest to the piece (where it sits
 * or is held: the hilt's nearest hand vertex), and moves rigidly instead of being torn between the
 * body vertices nearest to each of its vertices: armadillo_1k on a walk (its longest edge 1.72x
 * alone) with a ground quad 4 m wide at its feet stretched the quad to 2.05x, with a strip 2 m long
 * above its head 1.90x, with 300 small pieces scattered in its box 18x. to_body
 * (#V) is rewritten for the vertices of such pieces; piece holds each face vertex's piece root
 * (INT32_MAX: a vertex of collapsed faces only, left as it is). */
#define KM_LOOSE_AGAINST 0.05
#define KM_LOOSE_WRAPS 0.1
#define KM_LOOSE_REACH 0.2
typedef struct loose_piece {
  double lo[3], hi[3], best, reach; /* reach: its vertices' largest distance to the body */
  size_t n, far;
  int32_t held;
} loose_piece;

static double diag3(const double lo[3], const double hi[3]) {
  return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
              (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

static km_status attach_rigid(const km_mesh *m, km__body *bd, const int32_t *piece, int32_t root,
                              km_error *err) {
  size_t n = m->n_vertices, np = 0;
  const km_mesh *b = &bd->body;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < b->n_vertices; ++v)
    for (int d = 0; d < 3; ++d) {
      lo[d] = fmin(lo[d], b->V[3 * v + d]);
      hi[d] = fmax(hi[d], b->V[3 * v + d]);
    }
  double diag = diag3(lo, hi);
  int32_t *id = km__malloc(n, sizeof *id); /* a piece root's index into lp */
  loose_piece *lp = km__calloc(bd->n_pieces, sizeof *lp);
  if (!id || !lp) {
    free(id), free(lp);
    return km__fail(err, KM_ERR_NOMEM, "pieces: out of memory for %zu vertices", n);
  }
  for (size_t v = 0; v < n; ++v)
    id[v] = -1;
  for (size_t v = 0; v < n; ++v) {
    int32_t q = piece[v], t = bd->to_body[v];
    if (q < 0 || q == root || q == INT32_MAX || t < 0) continue;
    if (id[q] < 0) {
      if (np == bd->n_pieces) continue; /* cannot happen: n_pieces counts every root */
      id[q] = (int32_t)np++;
      loose_piece *z = lp + id[q];
      for (int d = 0; d < 3; ++d)
        z->lo[d] = INFINITY, z->hi[d] = -INFINITY;
      z->best = INFINITY, z->held = -1;
    }
    loose_piece *z = lp + id[q];
    const double *x = m->V + 3 * v, *y = b->V + 3 * (size_t)t;
    for (int d = 0; d < 3; ++d) {
      z->lo[d] = fmin(z->lo[d], x[d]);
      z->hi[d] = fmax(z->hi[d], x[d]);
    }
    double dist = sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                       (x[2] - y[2]) * (x[2] - y[2]));
    ++z->n;
    z->far += !(dist <= KM_LOOSE_AGAINST * diag);
    z->reach = fmax(z->reach, dist);
    if (dist < z->best) z->best = dist, z->held = t;
  }
  for (size_t k = 0; k < np; ++k) { /* rigid: held >= 0 stays; wrapping: held = -1 */
    loose_piece *z = lp + k;
    if (2 * z->far <= z->n && diag3(z->lo, z->hi) > KM_LOOSE_WRAPS * diag &&
        z->reach <= KM_LOOSE_REACH * diag)
      z->held = -1;
    bd->rigid_pieces += z->held >= 0;
  }
  if (!(bd->piece = km__malloc(n, sizeof *bd->piece))) {
    free(id), free(lp);
    return km__fail(err, KM_ERR_NOMEM, "pieces: out of memory for %zu vertices", n);
  }
  for (size_t v = 0; v < n; ++v) {
    int32_t q = piece[v];
    bd->piece[v] = q < 0 || q == root || q == INT32_MAX ? -1 : id[q];
  }
  for (size_t v = 0; v < n; ++v) {
    int32_t q = piece[v];
    if (q < 0 || q == root || q == INT32_MAX || id[q] < 0) continue;
    const loose_piece *z = lp + id[q];
    if (z->held < 0) continue;
    if (!bd->rigid && !(bd->rigid = km__calloc(n, sizeof *bd->rigid))) {
      free(id), free(lp);
      return km__fail(err, KM_ERR_NOMEM, "pieces: out of memory for %zu vertices", n);
    }
    bd->to_body[v] = z->held;
    bd->rigid[v] = true;
  }
  free(id), free(lp);
  return KM_OK;
}

km_status km__mesh_body(const km_mesh *m, km__body *out, bool *found, km_error *err) {
  memset(out, 0, sizeof *out);
  *found = false;
  if (!m || !m->V || !m->F || !m->n_faces) return KM_OK;
  size_t n = m->n_vertices;
  int32_t *piece = km__malloc(n ? n : 1, sizeof *piece);
  size_t *cnt = km__calloc(n ? n : 1, sizeof *cnt);
  km_status s = KM_OK;
  if (!piece || !cnt) {
    s = km__fail(err, KM_ERR_NOMEM, "pieces: out of memory for %zu vertices", n);
    goto done;
  }
  for (size_t v = 0; v < n; ++v)
    piece[v] = -1;
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3 && !km__face_collapsed(m->F + 3 * f); ++c)
      piece[m->F[3 * f + (size_t)c]] = m->F[3 * f + (size_t)c];
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 1; c < 3 && !km__face_collapsed(m->F + 3 * f); ++c)
      km__uf_union(piece, m->F[3 * f], m->F[3 * f + (size_t)c]);
  int32_t root = -1;
  for (size_t v = 0; v < n; ++v) {
    if (piece[v] < 0) continue;
    piece[v] = km__uf_find(piece, (int32_t)v);
    out->n_pieces += cnt[piece[v]]++ == 0;
  }
  for (size_t v = 0; v < n; ++v)
    if (cnt[v] > out->body_vertices)
      out->largest_other = out->body_vertices, out->body_vertices = cnt[v], root = (int32_t)v;
    else if (cnt[v] > out->largest_other)
      out->largest_other = cnt[v];
  if (out->n_pieces < 2 || 4 * out->largest_other > out->body_vertices) goto done;
  km_mesh *b = &out->body;
  size_t nb = out->body_vertices, nf = 0;
  for (size_t f = 0; f < m->n_faces; ++f)
    nf += piece[m->F[3 * f]] == root && !km__face_collapsed(m->F + 3 * f);
  out->to_body = km__malloc(n, sizeof(int32_t));
  out->from_body = km__malloc(nb, sizeof(int32_t));
  b->V = km__malloc(3 * nb, sizeof(double));
  b->F = km__malloc(3 * nf, sizeof(int32_t));
  if (!out->to_body || !out->from_body || !b->V || !b->F) {
    s = km__fail(err, KM_ERR_NOMEM, "pieces: out of memory for %zu vertices", n);
    goto done;
  }
  for (size_t v = 0; v < n; ++v) {
    out->to_body[v] = piece[v] == root ? (int32_t)b->n_vertices : -1;
    if (piece[v] != root) continue;
    out->from_body[b->n_vertices] = (int32_t)v;
    memcpy(b->V + 3 * b->n_vertices++, m->V + 3 * v, 3 * sizeof(double));
  }
  for (size_t f = 0; f < m->n_faces; ++f)
    if (piece[m->F[3 * f]] == root && !km__face_collapsed(m->F + 3 * f)) {
      for (int c = 0; c < 3; ++c)
        b->F[3 * b->n_faces + (size_t)c] = out->to_body[m->F[3 * f + (size_t)c]];
      ++b->n_faces;
    }
  km__nearest_x ix;
  if ((s = km__nearest_x_build(b->V, nb, &ix, err)) != KM_OK) goto done;
  for (size_t f = 0; f < m->n_faces; ++f) /* a vertex of collapsed faces only: as a loose one */
    for (int c = 0; c < 3 && km__face_collapsed(m->F + 3 * f); ++c)
      if (piece[m->F[3 * f + (size_t)c]] < 0) piece[m->F[3 * f + (size_t)c]] = INT32_MAX;
  for (size_t v = 0; v < n; ++v)
    if (piece[v] >= 0 && piece[v] != root) out->to_body[v] = km__nearest_x_query(&ix, m->V + 3 * v);
  km__nearest_x_free(&ix);
  if ((s = attach_rigid(m, out, piece, root, err)) != KM_OK) goto done;
  *found = true;
done:
  if (s != KM_OK) km__body_free(out);
  free(piece);
  free(cnt);
  return s;
}

size_t km__body_loose_vertices(const km__body *bd, const int32_t *to_w, size_t n) {
  size_t loose = 0;
  for (size_t v = 0; bd->to_body && v < n; ++v) {
    size_t u = to_w ? (size_t)to_w[v] : v;
    int32_t b = bd->to_body[u];
    loose += b >= 0 && bd->from_body[b] != (int32_t)u;
  }
  return loose;
}

km_status km__file_body(const km_mesh *m, km__weld *wd, km__body *bd, bool *found, km_error *err) {
  memset(bd, 0, sizeof *bd);
  *found = false;
  km_status s = km__mesh_weld(m, wd, err);
  if (s == KM_OK) s = km__mesh_body(wd->to_w ? &wd->w : m, bd, found, err);
  if (s != KM_OK) km__weld_free(wd);
  return s;
}

/* The loose pieces of bd lying on the floor (km__ground_vertices), counted; with ground, the
 * file's vertices in them flagged (ground[v], n entries, all written). wd NULL: bd was found on
 * m itself. false: out of memory. */
static bool ground_of_body(const km_mesh *m, const km__weld *wd, const km__body *bd,
                           size_t *n_pieces, bool *ground) {
  size_t n = m->n_vertices, np = bd->n_pieces - 1;
  const int32_t *to_w = wd ? wd->to_w : NULL;
  *n_pieces = 0;
  for (size_t v = 0; ground && v < n; ++v)
    ground[v] = false;
  double lo = INFINITY, hi = -INFINITY, *top = km__malloc(np ? np : 1, sizeof *top);
  if (!top) return false;
  for (size_t k = 0; k < np; ++k)
    top[k] = -INFINITY;
  for (size_t b = 0; b < bd->body.n_vertices; ++b)
    lo = fmin(lo, bd->body.V[3 * b + 1]), hi = fmax(hi, bd->body.V[3 * b + 1]);
  size_t nw = to_w ? wd->w.n_vertices : n;
  const double *W = to_w ? wd->w.V : m->V;
  for (size_t u = 0; u < nw; ++u)
    if (bd->piece[u] >= 0) top[bd->piece[u]] = fmax(top[bd->piece[u]], W[3 * u + 1]);
  for (size_t k = 0; k < np; ++k)
    *n_pieces += top[k] <= lo + 0.01 * (hi - lo);
  for (size_t v = 0; ground && *n_pieces && v < n; ++v) {
    int32_t q = bd->piece[to_w ? (size_t)to_w[v] : v];
    ground[v] = q >= 0 && top[q] <= lo + 0.01 * (hi - lo);
  }
  free(top);
  return true;
}

km_status km__body_ground(const km_mesh *m, const km__body *bd, bool *ground, size_t *n_pieces,
                          km_error *err) {
  if (!ground_of_body(m, NULL, bd, n_pieces, ground))
    return km__fail(err, KM_ERR_NOMEM, "pieces: out of memory");
  return KM_OK;
}

km_status km__ground_vertices(const km_mesh *m, bool *ground, size_t *n_pieces, km_error *err) {
  size_t n = m->n_vertices;
  *n_pieces = 0;
  for (size_t v = 0; v < n; ++v)
    ground[v] = false;
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= n) return KM_OK;
  km__weld wd;
  km__body bd;
  bool found = false;
  km_status s = km__file_body(m, &wd, &bd, &found, err);
  if (s != KM_OK) return s;
  if (found && !ground_of_body(m, &wd, &bd, n_pieces, ground))
    s = km__fail(err, KM_ERR_NOMEM, "pieces: out of memory");
  km__body_free(&bd);
  km__weld_free(&wd);
  return s;
}

km_status km__shape_vertices(const km_mesh *m, bool *keep, km_error *err) {
  size_t n = m->n_vertices;
  for (size_t v = 0; v < n; ++v)
    keep[v] = m->n_faces == 0;
  if (!m->n_faces) return KM_OK;
  bool in_range = true;
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3 && !km__face_collapsed(m->F + 3 * f); ++c) {
      int32_t v = m->F[3 * f + (size_t)c];
      if (v >= 0 && (size_t)v < n)
        keep[v] = true;
      else
        in_range = false;
    }
  if (!in_range) return KM_OK; /* not a mesh to take apart: the vertices its faces name */
  bool any = false;
  for (size_t v = 0; v < n && !any; ++v)
    any = keep[v];
  if (!any) { /* every face collapsed: no surface to tell, so every vertex, as with no faces */
    for (size_t v = 0; v < n; ++v)
      keep[v] = true;
    return KM_OK;
  }
  km__weld wd;
  km__body bd;
  bool found = false;
  km_status s = km__file_body(m, &wd, &bd, &found, err);
  if (s != KM_OK) return s;
  const int32_t *to_w = wd.to_w;
  if (found)
    for (size_t v = 0; v < n; ++v) {
      size_t u = to_w ? (size_t)to_w[v] : v;
      int32_t b = bd.to_body[u];
      keep[v] = b >= 0 && bd.from_body[b] == (int32_t)u;
    }
  km__body_free(&bd);
  km__weld_free(&wd);
  return s;
}

km_status km__mesh_weld(const km_mesh *m, km__weld *out, km_error *err) {
  memset(out, 0, sizeof *out);
  if (!m || !m->V || !m->F || !m->n_faces) return KM_OK;
  size_t n = m->n_vertices, nf = m->n_faces, nw = 0;
  int32_t *first = km__malloc(n ? n : 1, sizeof *first), *n_used = NULL;
  bool *used = km__calloc(n ? n : 1, sizeof *used);
  km_status s = KM_OK;
  if (!first || !used || !(n_used = km__calloc(n ? n : 1, sizeof *n_used))) {
    s = km__fail(err, KM_ERR_NOMEM, "weld: out of memory for %zu vertices", n);
    goto fail;
  }
  for (size_t i = 0; i < 3 * nf; ++i)
    if (m->F[i] >= 0 && (size_t)m->F[i] < n) used[m->F[i]] = true;
  /* each class's representative: its lowest vertex id; joins: a class with two used members */
  if ((s = km__coincident_lowest(m->V, n, NULL, first, err)) != KM_OK) goto fail;
  bool joins = false;
  for (size_t v = 0; v < n; ++v)
    joins |= (n_used[first[v]] += used[v]) > 1;
  free(n_used), n_used = NULL;
  free(used), used = NULL;
  /* coincident vertices inside one closed piece (the dinosaur's 8) cut nothing: left alone */
  km_mesh_info info;
  if (!joins || mesh_info(m, false, &info, NULL) != KM_OK ||
      (info.components < 2 && info.boundary_edges == 0)) {
    free(first);
    return KM_OK;
  }
  if (!(out->to_w = km__malloc(n, sizeof *out->to_w))) {
    s = km__fail(err, KM_ERR_NOMEM, "weld: out of memory for %zu vertices", n);
    goto fail;
  }
  /* welded ids in the order of the representatives' ids */
  for (size_t v = 0; v < n; ++v)
    out->to_w[v] = first[v] == (int32_t)v ? (int32_t)nw++ : -1;
  for (size_t v = 0; v < n; ++v)
    if (out->to_w[v] < 0) out->to_w[v] = out->to_w[first[v]];
  /* first[] now per welded vertex: the lowest file id of its class */
  for (size_t v = n; v-- > 0;)
    first[out->to_w[v]] = (int32_t)v;
  out->first = first, first = NULL;
  if ((s = km_mesh_alloc(nw, nf, &out->w, err)) != KM_OK) goto fail;
  for (size_t v = 0; v < n; ++v)
    memcpy(out->w.V + 3 * (size_t)out->to_w[v], m->V + 3 * v, 3 * sizeof(double));
  for (size_t i = 0; i < 3 * nf; ++i)
    out->w.F[i] = out->to_w[m->F[i]];
  return KM_OK;
fail:
  free(n_used);
  free(used);
  free(first);
  km__weld_free(out);
  return s;
}

km_status km_mesh_info_compute(const km_mesh *m, km_mesh_info *out, km_error *err) {
  km_status s = mesh_info(m, true, out, err);
  if (s != KM_OK || !m->n_faces) return s;
  out->pieces = out->components;
  if (out->components < 2) return KM_OK;
  /* the pieces rig sees: joined at the seams first, then a body and its loose pieces */
  km__weld wd;
  km__body bd;
  bool found = false;
  if ((s = km__file_body(m, &wd, &bd, &found, err)) != KM_OK) return s;
  out->pieces = bd.n_pieces;
  if (found) out->loose_vertices = km__body_loose_vertices(&bd, wd.to_w, m->n_vertices);
  if (found) out->rigid_pieces = bd.rigid_pieces;
  if (found && !ground_of_body(m, &wd, &bd, &out->ground_pieces, NULL))
    s = km__fail(err, KM_ERR_NOMEM, "km_mesh_info_compute: out of memory");
  km__body_free(&bd);
  km__weld_free(&wd);
  return s;
}

/* seams false: seam_vertices left 0 (the weld, which has sorted the positions itself). */
static km_status mesh_info(const km_mesh *m, bool seams, km_mesh_info *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_mesh_info_compute: out is NULL");
  km_status s = check_faces(m, "km_mesh_info_compute", err);
  if (s) return s;
  memset(out, 0, sizeof *out);
  out->nonmanifold_edge[0] = out->nonmanifold_edge[1] = out->nonmanifold_vertex = -1;
  size_t nv = m->n_vertices, nf = m->n_faces;
  out->vertices = nv;
  out->faces = nf;
  if (nv) {
    for (int k = 0; k < 3; ++k)
      out->bbox_min[k] = out->bbox_max[k] = m->V[k];
    for (size_t i = 1; i < nv; ++i)
      for (int k = 0; k < 3; ++k) {
        double x = m->V[3 * i + (size_t)k];
        if (x < out->bbox_min[k]) out->bbox_min[k] = x;
        if (x > out->bbox_max[k]) out->bbox_max[k] = x;
      }
  }

  uint64_t *keys = km__malloc(nf ? nf * 3 : 1, sizeof *keys);
  uint64_t *tmp = km__malloc(nf ? nf * 3 : 1, sizeof *tmp);
  int32_t *parent = km__malloc(nv ? nv : 1, sizeof *parent);
  int32_t *vf_off = km__calloc(nv + 1, sizeof *vf_off);
  int32_t *vf = km__malloc(nf ? nf * 3 : 1, sizeof *vf);
  int32_t *local = km__malloc(nv ? nv : 1, sizeof *local);
  int32_t *lparent = km__malloc(nf ? nf * 3 : 1, sizeof *lparent);
  int32_t *touched = km__malloc(nf ? nf * 3 : 1, sizeof *touched);
  if (!keys || !tmp || !parent || !vf_off || !vf || !local || !lparent || !touched ||
      nf * 3 > INT32_MAX) {
    s = km__fail(err, nf * 3 > INT32_MAX ? KM_ERR_UNSUPPORTED : KM_ERR_NOMEM,
                 "km_mesh_info_compute: cannot allocate for %zu vertices, %zu faces", nv, nf);
    goto done;
  }

  /* Edges: sorted keys, each run is one edge used by (run length) faces. */
  size_t nk = 0;
  for (size_t f = 0; f < nf; ++f)
    nk += face_edges(m->F + 3 * f, keys + nk);
  radix_sort_u64(keys, tmp, nk);
  for (size_t i = 0; i < nk;) {
    size_t j = i + 1;
    while (j < nk && keys[j] == keys[i])
      ++j;
    out->edges++;
    if (j - i == 1)
      out->boundary_edges++;
    else if (j - i >= 3 && out->nonmanifold_edges++ == 0) {
      /* the keys are sorted: the first is the lowest pair */
      out->nonmanifold_edge[0] = (int32_t)(keys[i] >> 32);
      out->nonmanifold_edge[1] = (int32_t)(keys[i] & 0xffffffffu);
    }
    i = j;
  }

  /* Components (union-find through shared vertices), isolated vertices. */
  km__uf_init(parent, nv);
  for (size_t v = 0; v < nv; ++v)
    local[v] = 0; /* 1: in a face that is not collapsed */
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *t = m->F + 3 * f;
    if (!km__face_collapsed(t)) {
      km__uf_union(parent, t[0], t[1]);
      km__uf_union(parent, t[0], t[2]);
      local[t[0]] = local[t[1]] = local[t[2]] = 1;
    }
    vf_off[t[0] + 1]++, vf_off[t[1] + 1]++, vf_off[t[2] + 1]++;
  }
  size_t used = 0, proper = 0;
  for (size_t v = 0; v < nv; ++v) {
    if (vf_off[v + 1] == 0)
      out->isolated_vertices++;
    else {
      ++used;
      if (local[v] && km__uf_find(parent, (int32_t)v) == (int32_t)v) out->components++;
    }
  }
  for (size_t f = 0; f < nf; ++f)
    proper += !km__face_collapsed(m->F + 3 * f);
  out->euler_characteristic = (int64_t)used - (int64_t)out->edges + (int64_t)proper;
  if (seams && (s = count_seam_vertices(m, vf_off, &out->seam_vertices, err)) != KM_OK) goto done;

  /* Degenerate faces. */
  double diag = km_bbox_diagonal(m->V, nv);
  double min_area = 1e-14 * diag * diag;
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *t = m->F + 3 * f;
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      out->degenerate_faces++;
      continue;
    }
    const double *a = m->V + 3 * (size_t)t[0], *b = m->V + 3 * (size_t)t[1],
                 *c = m->V + 3 * (size_t)t[2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2],
           cz = u[0] * w[1] - u[1] * w[0];
    double area = 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
    if (!(area >= min_area) || area == 0.0) out->degenerate_faces++;
  }

  /* Non-manifold vertices: the faces around v are fans joined where they share an edge
   * (v,w); equivalently, components of v's link graph whose edges are the opposite sides
   * (u,w) of the incident faces. Faces with a repeated index form no wedge and are left out. */
  for (size_t v = 0; v < nv; ++v)
    vf_off[v + 1] += vf_off[v];
  for (size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t v = m->F[3 * f + (size_t)k];
      vf[vf_off[v]++] = (int32_t)f;
    }
  for (size_t v = nv; v > 0; --v)
    vf_off[v] = vf_off[v - 1];
  vf_off[0] = 0;
  for (size_t v = 0; v < nv; ++v)
    local[v] = -1;
  for (size_t v = 0; v < nv; ++v) {
    int32_t n_local = 0;
    for (int32_t i = vf_off[v]; i < vf_off[v + 1]; ++i) {
      const int32_t *t = m->F + 3 * (size_t)vf[i];
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      int32_t opp[2], no = 0;
      for (int k = 0; k < 3; ++k)
        if (t[k] != (int32_t)v) opp[no++] = t[k];
      for (int k = 0; k < 2; ++k)
        if (local[opp[k]] < 0) {
          local[opp[k]] = n_local;
          lparent[n_local] = n_local;
          touched[n_local++] = opp[k];
        }
      km__uf_union(lparent, local[opp[0]], local[opp[1]]);
    }
    int32_t fans = 0;
    for (int32_t i = 0; i < n_local; ++i) {
      if (km__uf_find(lparent, i) == i) ++fans;
      local[touched[i]] = -1;
    }
    if (fans > 1 && out->nonmanifold_vertices++ == 0) out->nonmanifold_vertex = (int32_t)v;
  }

done:
  free(keys);
  free(tmp);
  free(parent);
  free(vf_off);
  free(vf);
  free(local);
  free(lparent);
  free(touched);
  return s;
}

km_status km_adjacency_list(const km_mesh *m, int32_t **offsets, int32_t **adj, km_error *err) {
  if (!offsets || !adj) return km__fail(err, KM_ERR_INVALID, "km_adjacency_list: NULL output");
  *offsets = NULL;
  *adj = NULL;
  km_status s = check_faces(m, "km_adjacency_list", err);
  if (s) return s;
  size_t nv = m->n_vertices, nf = m->n_faces;
  if (nf > INT32_MAX / 6)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "km_adjacency_list: %zu faces exceed the int32 "
                    "offset range",
                    nf);
  /* Both directions of every edge as (from<<32 | to): sorting groups rows and orders each
   * row's neighbours at once; duplicates (shared edges) become adjacent and are dropped. */
  uint64_t *keys = km__malloc(nf ? nf * 6 : 1, sizeof *keys);
  uint64_t *tmp = km__malloc(nf ? nf * 6 : 1, sizeof *tmp);
  int32_t *off = km__calloc(nv + 1, sizeof *off);
  if (!keys || !tmp || !off) {
    free(keys);
    free(tmp);
    free(off);
    return km__fail(err, KM_ERR_NOMEM, "km_adjacency_list: out of memory for %zu faces", nf);
  }
  size_t nk = 0;
  uint64_t e[3];
  for (size_t f = 0; f < nf; ++f) {
    size_t ne = face_edges(m->F + 3 * f, e);
    for (size_t j = 0; j < ne; ++j) {
      keys[nk++] = e[j];
      keys[nk++] = (e[j] << 32) | (e[j] >> 32);
    }
  }
  radix_sort_u64(keys, tmp, nk);
  size_t nu = 0;
  for (size_t i = 0; i < nk; ++i)
    if (i == 0 || keys[i] != keys[i - 1]) keys[nu++] = keys[i];
  free(tmp);
  int32_t *a = km__malloc(nu ? nu : 1, sizeof *a);
  if (!a) {
    free(keys);
    free(off);
    return km__fail(err, KM_ERR_NOMEM, "km_adjacency_list: out of memory");
  }
  for (size_t i = 0; i < nu; ++i) {
    off[(keys[i] >> 32) + 1]++;
    a[i] = (int32_t)(keys[i] & 0xffffffffu);
  }
  for (size_t v = 0; v < nv; ++v)
    off[v + 1] += off[v];
  free(keys);
  *offsets = off;
  *adj = a;
  return KM_OK;
}

void km_vertex_distance_stats(const double *A, const double *B, size_t n, double *mean,
                              double *max) {
  double s = 0, m = 0;
  for (size_t v = 0; v < n; ++v) {
    double d = sqrt((A[3 * v] - B[3 * v]) * (A[3 * v] - B[3 * v]) +
                    (A[3 * v + 1] - B[3 * v + 1]) * (A[3 * v + 1] - B[3 * v + 1]) +
                    (A[3 * v + 2] - B[3 * v + 2]) * (A[3 * v + 2] - B[3 * v + 2]));
    s += d;
    if (d > m) m = d;
  }
  *mean = n ? s / (double)n : 0;
  *max = m;
}

km_status km_boundary_loops(const km_mesh *m, int32_t *loop, size_t *n_loops, km_error *err) {
  if (!loop || !n_loops) return km__fail(err, KM_ERR_INVALID, "km_boundary_loops: NULL output");
  *n_loops = 0;
  km_status s = check_faces(m, "km_boundary_loops", err);
  if (s) return s;
  size_t nv = m->n_vertices, nf = m->n_faces;
  uint64_t *keys = km__malloc(nf ? nf * 3 : 1, sizeof *keys);
  uint64_t *tmp = km__malloc(nf ? nf * 3 : 1, sizeof *tmp);
  int32_t *parent = km__malloc(nv ? nv : 1, sizeof *parent);
  if (!keys || !tmp || !parent) {
    free(keys), free(tmp), free(parent);
    return km__fail(err, KM_ERR_NOMEM, "km_boundary_loops: out of memory for %zu faces", nf);
  }
  size_t nk = 0;
  for (size_t f = 0; f < nf; ++f)
    nk += face_edges(m->F + 3 * f, keys + nk);
  radix_sort_u64(keys, tmp, nk);
  for (size_t v = 0; v < nv; ++v)
    parent[v] = (int32_t)v, loop[v] = -1;
  for (size_t i = 0; i < nk;) {
    size_t j = i + 1;
    while (j < nk && keys[j] == keys[i])
      ++j;
    if (j - i == 1) {
      int32_t a = (int32_t)(keys[i] >> 32), b = (int32_t)(keys[i] & 0xffffffffu);
      km__uf_union(parent, a, b);
      loop[a] = loop[b] = 0; /* on a boundary; labelled below */
    }
    i = j;
  }
  /* label each root once, in the order of the loops' lowest vertex ids */
  for (size_t v = 0; v < nv; ++v)
    if (loop[v] == 0) loop[v] = -2; /* on a boundary, not yet labelled */
  for (size_t v = 0; v < nv; ++v) {
    if (loop[v] != -2) continue;
    int32_t r = km__uf_find(parent, (int32_t)v);
    if (loop[r] < 0) loop[r] = (int32_t)(*n_loops)++;
    loop[v] = loop[r];
  }
  free(keys), free(tmp), free(parent);
  return KM_OK;
}

km_status km__bust_base(const km_mesh *m, bool *found, double *cut_top, km_error *err) {
  return km__bust_base_axes(m, 1, 1, 0, found, cut_top, err);
}

km_status km__bust_base_axes(const km_mesh *m, int up, int up_sign, int lat, bool *found,
                             double *cut_top, km_error *err) {
  *found = false;
  *cut_top = NAN;
  if (!m || !m->n_vertices || !m->n_faces) return KM_OK;
  int32_t *loop = km__malloc(m->n_vertices, sizeof *loop);
  if (!loop) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  size_t nl = 0;
  km_status s = km_boundary_loops(m, loop, &nl, err);
  if (s == KM_OK) s = km__bust_base_axes_loops(m, loop, nl, up, up_sign, lat, found, cut_top, err);
  free(loop);
  return s;
}

km_status km__bust_base_axes_loops(const km_mesh *m, const int32_t *loop, size_t nl, int up,
                                   int up_sign, int lat, bool *found, double *cut_top,
                                   km_error *err) {
  *found = false;
  *cut_top = NAN;
  if (!m || !m->n_vertices || !m->n_faces || nl == 0) return KM_OK;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    for (int k = 0; k < 3; ++k) {
      double x = m->V[3 * (size_t)m->F[i] + (size_t)k];
      lo[k] = fmin(lo[k], x), hi[k] = fmax(hi[k], x);
    }
  /* heights along up counted upwards (negated for a negative up) */
  double H = hi[up] - lo[up], W = hi[lat] - lo[lat], best = 0,
         bottom = up_sign > 0 ? lo[up] : -hi[up];
  double *xlo = km__malloc(nl, sizeof *xlo), *xhi = km__malloc(nl, sizeof *xhi),
         *yhi = km__malloc(nl, sizeof *yhi);
  if (!xlo || !xhi || !yhi) {
    free(xlo), free(xhi), free(yhi);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t l = 0; l < nl; ++l)
    xlo[l] = INFINITY, xhi[l] = yhi[l] = -INFINITY;
  for (size_t v = 0; v < m->n_vertices; ++v) {
    if (loop[v] < 0) continue;
    const double *p = m->V + 3 * v;
    size_t l = (size_t)loop[v];
    double y = up_sign > 0 ? p[up] : -p[up];
    xlo[l] = fmin(xlo[l], p[lat]), xhi[l] = fmax(xhi[l], p[lat]), yhi[l] = fmax(yhi[l], y);
  }
  /* A cut through a coarse mesh is as ragged as its edges are long: the faces wholly above
   * a plane leave a boundary one edge deep (FAUST's head cut at the neck, 1-2 cm edges on a
   * 23 cm mesh) */
  double elen = 0;
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      const double *a = m->V + 3 * (size_t)m->F[3 * f + (size_t)k],
                   *b = m->V + 3 * (size_t)m->F[3 * f + (size_t)(k + 1) % 3];
      elen += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
    }
  elen /= 3.0 * (double)m->n_faces;
  double depth = fmax(0.06 * H, 2.5 * elen);
  /* The bottom's own width: a cut at the waist of a T-posed upper body spans 0.2 of the arms'
   * width, and all of its bottom; a scan's open sole a third of the bottom's (two feet) */
  double blo = INFINITY, bhi = -INFINITY;
  for (size_t v = 0; v < m->n_vertices; ++v) {
    double y = up_sign > 0 ? m->V[3 * v + (size_t)up] : -m->V[3 * v + (size_t)up];
    if (y - bottom <= depth)
      blo = fmin(blo, m->V[3 * v + (size_t)lat]), bhi = fmax(bhi, m->V[3 * v + (size_t)lat]);
  }
  for (size_t l = 0; l < nl && H > 0 && W > 0; ++l) {
    double span = xhi[l] - xlo[l];
    if (yhi[l] - bottom <= depth && depth < 0.5 * H &&
        (span >= 0.3 * W || span >= 0.8 * (bhi - blo)) && span > best) {
      best = span;
      *found = true;
      *cut_top = up_sign > 0 ? yhi[l] : -yhi[l];
    }
  }
  free(xlo), free(xhi), free(yhi);
  return KM_OK;
}

km_status km__seated_base(const km_mesh *m, bool *found, double *base_top, km_error *err) {
  *found = false;
  *base_top = NAN;
  if (!m || !m->n_vertices || !m->n_faces) return KM_OK;
  size_t nv = m->n_vertices;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    for (int k = 0; k < 3; ++k) {
      double x = m->V[3 * (size_t)m->F[i] + (size_t)k];
      lo[k] = fmin(lo[k], x), hi[k] = fmax(hi[k], x);
    }
  double H = hi[1] - lo[1], W = hi[0] - lo[0], D = hi[2] - lo[2], ytop = lo[1] + 0.05 * H;
  if (!(H > 0 && W > 0 && D > 0)) return KM_OK;
  int32_t *parent = km__malloc(nv, sizeof *parent);
  size_t *count = km__calloc(nv, sizeof *count);
  if (!parent || !count) {
    free(parent), free(count);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t v = 0; v < nv; ++v)
    parent[v] = -1; /* -1: not in the bottom slab */
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    if (!(m->V[3 * (size_t)t[0] + 1] <= ytop && m->V[3 * (size_t)t[1] + 1] <= ytop &&
          m->V[3 * (size_t)t[2] + 1] <= ytop))
      continue;
    for (int k = 0; k < 3; ++k)
      if (parent[t[k]] < 0) parent[t[k]] = t[k];
    km__uf_union(parent, t[0], t[1]);
    km__uf_union(parent, t[0], t[2]);
  }
  int32_t big = -1;
  for (size_t v = 0; v < nv; ++v)
    if (parent[v] >= 0) {
      int32_t r = km__uf_find(parent, (int32_t)v);
      if (++count[r] > (big < 0 ? 0 : count[big])) big = r;
    }
  if (big >= 0) {
    double xl = INFINITY, xh = -INFINITY, zl = INFINITY, zh = -INFINITY;
    bool alone = true;
    for (size_t v = 0; v < nv; ++v) {
      if (parent[v] < 0) continue;
      int32_t r = km__uf_find(parent, (int32_t)v);
      if (r != big) {
        alone = alone && !(count[r] >= 0.2 * (double)count[big]);
        continue;
      }
      const double *p = m->V + 3 * v;
      xl = fmin(xl, p[0]), xh = fmax(xh, p[0]), zl = fmin(zl, p[2]), zh = fmax(zh, p[2]);
    }
    /* under half the vertices: a body above its base (a lone tetrahedron's bottom face is 3 of
     * its 4) */
    *found = alone && xh - xl >= 0.5 * W && zh - zl >= 0.5 * D && 2 * count[big] < nv;
    if (*found) *base_top = ytop;
  }
  free(parent), free(count);
  return KM_OK;
}

km_status km__rest_base(const km_mesh *m, bool *found, double *top, km_error *err) {
  km_status s = km__bust_base(m, found, top, err);
  if (s == KM_OK && !*found) s = km__seated_base(m, found, top, err);
  return s;
}
