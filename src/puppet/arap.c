/* Full-space as-rigid-as-possible surface deformation (Sorkine & Alexa 2007), the quality
 * yardstick for the reduced puppet solver.
 *
 * Energy sum_i sum_j w_ij |(x_i - x_j) - R_i (p_i - p_j)|^2 with cotangent weights w_ij, a
 * negative one raised to a small floor (km_arap_precompute says why).
 * Global step: -L x = b (L of those weights) with b_i = sum_j w_ij/2 (R_i + R_j)(p_i - p_j); handle
 * vertices are eliminated (hard constraints), so the CHOLMOD factor of -L_ff is computed once per
 * handle set and each iteration is one 3-column solve. Local step: R_i = nearest rotation to sum_j
 * w_ij (x_i - x_j)(p_i - p_j)^T, closed form (rot3.h). */
#include "core/core.h"

#include "math/math.h"
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct km_arap {
  size_t n, n_free, n_hv;
  int iterations;
  double tolerance, diag;
  double *P;        /* n*3 rest */
  int32_t *adj_off; /* n+1 */
  int32_t *adj;     /* neighbours */
  double *w;        /* cot weights (L_ij) */
  int32_t *map;     /* vertex -> free index, or -(handle vertex index)-1 (hard handles only: a
                       soft handle's vertex is free, hix names its handle vertex) */
  int32_t *h_v;     /* n_hv */
  km_cholesky *chol;
  double *X;    /* n*3 current (warm start) */
  double *R;    /* n*9 */
  double *B;    /* n_free*3 column-major rhs / solution */
  double soft;  /* > 0: soft handles, the weight of a handle vertex's pull to its target */
  int32_t *hix; /* soft handles: n, the handle vertex index of a vertex, -1 none */
  /* A mesh split at its texture seams (km_arap_precompute) is solved welded: the caller's
   * n_out vertices and n_hv_out handle vertices map onto the welded ones. NULL: not split. */
  km_arap *welded;
  size_t n_out, n_hv_out;
  int32_t *to_w;   /* n_out: the welded vertex of each vertex */
  int32_t *hsrc;   /* welded->n_hv: the caller's handle vertex each welded one takes its target
                      from (the first copy listed) */
  double *Tw, *Vw; /* welded targets and result (the solve does not allocate) */
  /* A small loose piece holding no handle vertex (km__mesh_body: an eye, a buckle): n, the
   * body vertex each of its vertices follows (km__mesh_body's to_body: its nearest at rest, or
   * the one its whole piece follows, which then turns rigidly), -1 for every other vertex;
   * NULL: no such piece. Left out of the solve, then placed by that vertex's rotation. */
  int32_t *att;
};

/* -L_ff is only semidefinite when a connected component holds no handle vertex, and CHOLMOD
 * may still "factor" it with a round-off pivot, so check the topology instead (union-find
 * over the faces). Returns the first unanchored vertex or -1. */
static int32_t unanchored_vertex(const km_mesh *m, const int32_t *map, const int32_t *att,
                                 int32_t *parent) {
  size_t n = m->n_vertices;
  km__uf_init(parent, n);
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int k = 1; k < 3 && !km__face_collapsed(m->F + 3 * f); ++k)
      km__uf_union(parent, m->F[3 * f], m->F[3 * f + k]);
  unsigned char *anchored = calloc(n, 1);
  if (!anchored) return -1;
  for (size_t v = 0; v < n; ++v)
    if ((map[v] < 0 && map[v] != INT32_MIN) || (att && att[v] >= 0))
      anchored[km__uf_find(parent, (int32_t)v)] = 1;
  int32_t bad = -1;
  for (size_t f = 0; f < m->n_faces * 3 && bad < 0; ++f)
    if (!km__face_collapsed(m->F + f / 3 * 3) && !anchored[km__uf_find(parent, m->F[f])])
      bad = m->F[f];
  free(anchored);
  return bad;
}

void km_arap_free(km_arap **pa) {
  if (!pa || !*pa) return;
  km_arap *a = *pa;
  km_cholesky_free(&a->chol);
  free(a->P);
  free(a->adj_off);
  free(a->adj);
  free(a->w);
  free(a->map);
  free(a->hix);
  free(a->h_v);
  free(a->X);
  free(a->R);
  free(a->B);
  km_arap_free(&a->welded);
  free(a->to_w);
  free(a->hsrc);
  free(a->Tw);
  free(a->Vw);
  free(a->att);
  free(a);
  *pa = NULL;
}

static km_status arap_precompute(const km_mesh *rest, size_t n_handles,
                                 const int32_t *handle_offsets, const int32_t *handle_vertices,
                                 const km_arap_options *opt, km_arap **out, km_error *err);

/* The small loose pieces holding no handle vertex (a->att): with its handles only on the body,
 * a mesh with eyes or teeth of their own had pieces of no solution and was refused, while the
 * reduced model carries them with the body (km_puppet_precompute); here each of their vertices
 * follows its nearest body vertex, turned as that vertex's neighbourhood turns. A piece that
 * holds a handle vertex is solved as any. */
static km_status attach_loose(km_arap *a, const km_mesh *rest, km_error *err) {
  km__body bd;
  bool found = false;
  km_status s = km__mesh_body(rest, &bd, &found, err);
  if (s != KM_OK || !found) return s;
  size_t n = a->n, n_att = 0;
  int32_t *parent = km__malloc(n, sizeof *parent);
  unsigned char *held = km__calloc(n, 1);
  if (!parent || !held || !(a->att = km__malloc(n, sizeof *a->att))) {
    s = km__fail(err, KM_ERR_NOMEM, "arap: out of memory");
    goto done;
  }
  for (size_t v = 0; v < n; ++v)
    parent[v] = (int32_t)v, a->att[v] = -1;
  for (size_t f = 0; f < rest->n_faces; ++f)
    for (int k = 1; k < 3 && !km__face_collapsed(rest->F + 3 * f); ++k)
      km__uf_union(parent, rest->F[3 * f], rest->F[3 * f + k]);
  for (size_t i = 0; i < a->n_hv; ++i)
    held[km__uf_find(parent, a->h_v[i])] = 1;
  for (size_t v = 0; v < n; ++v) {
    int32_t b = bd.to_body[v];
    if (b < 0 || bd.from_body[b] == (int32_t)v || held[km__uf_find(parent, (int32_t)v)]) continue;
    a->att[v] = bd.from_body[b]; /* a loose piece's vertex, its piece holding no handle */
    a->map[v] = INT32_MIN;       /* out of the solve */
    ++n_att;
  }
  if (!n_att) free(a->att), a->att = NULL;
done:
  free(parent);
  free(held);
  km__body_free(&bd);
  return s;
}

/* A mesh split at its texture seams (coincident vertices that cut it into pieces or open it:
 * km_mesh_info.seam_vertices) is solved on the mesh welded there, so the seams stay shut:
 * split, each piece turned on its own and a piece without a handle had no solution. Each
 * handle keeps one copy of each welded vertex (the first listed). */
km_status km_arap_precompute(const km_mesh *rest, size_t n_handles, const int32_t *handle_offsets,
                             const int32_t *handle_vertices, const km_arap_options *opt,
                             km_arap **out, km_error *err) {
  km__weld wd = {0};
  km_status s = KM_OK;
  if (!rest || !rest->V || !rest->F || !handle_offsets || !handle_vertices || !n_handles ||
      (s = km__mesh_weld(rest, &wd, err)) != KM_OK || !wd.to_w)
    return s != KM_OK
               ? s
               : arap_precompute(rest, n_handles, handle_offsets, handle_vertices, opt, out, err);
  size_t n = rest->n_vertices,
         nhv = handle_offsets[n_handles] > 0 ? (size_t)handle_offsets[n_handles] : 0;
  km_arap *a = NULL;
  int32_t *seen = NULL, *off = NULL, *hv = NULL;
  if (!out) {
    s = km__fail(err, KM_ERR_INVALID, "arap: out is NULL");
    goto done;
  }
  *out = NULL;
  for (size_t i = 0; i < nhv; ++i)
    if (handle_vertices[i] < 0 || (size_t)handle_vertices[i] >= n) {
      s = km__fail(err, KM_ERR_INVALID, "arap: handle vertex %zu is %d (out of range)", i,
                   (int)handle_vertices[i]);
      goto done;
    }
  a = calloc(1, sizeof *a);
  off = km__malloc(n_handles + 1, sizeof *off);
  hv = km__malloc(nhv ? nhv : 1, sizeof *hv);
  seen = km__malloc(wd.w.n_vertices, sizeof *seen);
  if (!a || !off || !hv || !seen || !(a->hsrc = km__malloc(nhv ? nhv : 1, sizeof *a->hsrc))) {
    s = km__fail(err, KM_ERR_NOMEM, "arap: out of memory");
    goto done;
  }
  a->to_w = wd.to_w, wd.to_w = NULL; /* kept for the solve */
  for (size_t v = 0; v < wd.w.n_vertices; ++v)
    seen[v] = -1;
  size_t k = 0;
  off[0] = 0;
  for (size_t h = 0; h < n_handles; ++h) {
    for (int32_t i = handle_offsets[h]; i < handle_offsets[h + 1] && (size_t)i < nhv; ++i) {
      int32_t v = a->to_w[handle_vertices[i]];
      if (seen[v] >= 0) continue; /* another copy (or a repeat, refused below as before) */
      seen[v] = (int32_t)k;
      a->hsrc[k] = i;
      hv[k++] = v;
    }
    off[h + 1] = (int32_t)k;
  }
  if ((s = arap_precompute(&wd.w, n_handles, off, hv, opt, &a->welded, err)) != KM_OK) goto done;
  a->n = n;
  a->n_out = n;
  a->n_hv = nhv;
  a->n_hv_out = nhv;
  if (!(a->Tw = km__malloc(3 * (k ? k : 1), sizeof(double))) ||
      !(a->Vw = km__malloc(3 * wd.w.n_vertices, sizeof(double))))
    s = km__fail(err, KM_ERR_NOMEM, "arap: out of memory");
done:
  free(seen);
  free(off);
  free(hv);
  km__weld_free(&wd);
  if (s != KM_OK) {
    km_arap_free(&a);
    return s;
  }
  *out = a;
  return KM_OK;
}

static km_status arap_precompute(const km_mesh *rest, size_t n_handles,
                                 const int32_t *handle_offsets, const int32_t *handle_vertices,
                                 const km_arap_options *opt, km_arap **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "arap: out is NULL");
  *out = NULL;
  if (!rest || !rest->V || !rest->F || rest->n_vertices < 3 || rest->n_faces < 1)
    return km__fail(err, KM_ERR_INVALID, "arap: the rest mesh needs vertices and faces");
  if (rest->n_vertices > INT32_MAX / 2)
    return km__fail(err, KM_ERR_INVALID, "arap: mesh too large");
  for (size_t i = 0; i < rest->n_faces * 3; ++i)
    if (rest->F[i] < 0 || (size_t)rest->F[i] >= rest->n_vertices)
      return km__fail(err, KM_ERR_INVALID, "arap: face %zu references vertex %d", i / 3,
                      (int)rest->F[i]);
  if (!n_handles || !handle_offsets || !handle_vertices || handle_offsets[0] != 0)
    return km__fail(err, KM_ERR_INVALID,
                    "arap: needs at least one handle (offsets starting at 0 and vertices)");
  for (size_t h = 0; h < n_handles; ++h)
    if (handle_offsets[h + 1] < handle_offsets[h])
      return km__fail(err, KM_ERR_INVALID, "arap: handle_offsets decreases at handle %zu", h);
  size_t n = rest->n_vertices, nhv = (size_t)handle_offsets[n_handles];
  if (nhv == 0 || nhv > n)
    return km__fail(err, KM_ERR_INVALID, "arap: %zu handle vertices for %zu vertices", nhv, n);
  km_arap_options o = {0};
  if (opt) o = *opt;
  if (o.iterations == 0) o.iterations = 4;
  if (o.tolerance == 0) o.tolerance = 1e-6;
  if (o.iterations < 0 || !(o.tolerance >= 0) || !(o.handle_weight >= 0))
    return km__fail(err, KM_ERR_INVALID,
                    "arap: iterations, tolerance and handle_weight must be >= 0");

  km_arap *a = calloc(1, sizeof *a);
  if (!a) return km__fail(err, KM_ERR_NOMEM, "arap: out of memory");
  a->n = n;
  a->n_hv = nhv;
  a->iterations = o.iterations;
  a->tolerance = o.tolerance;
  km_status s = KM_OK;
  km_sparse *L = NULL, *A = NULL;
  int32_t *ti = NULL, *tj = NULL;
  double *tv = NULL;
  a->P = km__malloc(n * 3, sizeof(double));
  a->X = km__malloc(n * 3, sizeof(double));
  a->R = km__malloc(n * 9, sizeof(double));
  a->map = km__malloc(n, sizeof(int32_t));
  a->h_v = km__malloc(nhv, sizeof(int32_t));
  a->adj_off = km__calloc(n + 1, sizeof(int32_t));
  if (!a->P || !a->X || !a->R || !a->map || !a->h_v || !a->adj_off) goto nomem;
  memcpy(a->P, rest->V, n * 3 * sizeof(double));
  a->diag = km_bbox_diagonal(rest->V, n);
  memcpy(a->X, rest->V, n * 3 * sizeof(double));
  for (size_t v = 0; v < n; ++v)
    a->map[v] = 0;
  for (size_t i = 0; i < nhv; ++i) {
    int32_t v = handle_vertices[i];
    if (v < 0 || (size_t)v >= n || a->map[v] != 0) {
      s = km__fail(err, KM_ERR_INVALID, "arap: handle vertex %zu is %d (out of range or repeated)",
                   i, (int)v);
      goto fail;
    }
    a->map[v] = -(int32_t)i - 1;
    a->h_v[i] = v;
  }
  if ((s = attach_loose(a, rest, err)) != KM_OK) goto fail;
  /* vertices used by no face, or only by collapsed ones (a repeated index: no area, so no
   * Laplacian row either: a lone one made the system singular and --solver full refused the
   * mesh), stay where they are (INT32_MIN); they draw nothing */
  unsigned char *used = km__calloc(n, 1);
  if (!used) goto nomem;
  for (size_t f = 0; f < rest->n_faces; ++f)
    for (int k = 0; k < 3 && !km__face_collapsed(rest->F + 3 * f); ++k)
      used[rest->F[3 * f + (size_t)k]] = 1;
  size_t nfree = 0;
  for (size_t v = 0; v < n; ++v)
    if (a->map[v] == 0) a->map[v] = used[v] ? (int32_t)nfree++ : INT32_MIN;
  free(used);
  a->n_free = nfree;

  {
    int32_t *parent = km__malloc(n, sizeof(int32_t));
    if (!parent) goto nomem;
    int32_t bad = unanchored_vertex(rest, a->map, a->att, parent);
    free(parent);
    if (bad >= 0) {
      s = km__fail(err, KM_ERR_INVALID,
                   "arap: the connected component of vertex %d has no handle vertex (its "
                   "position would be undetermined; the reduced solver, the default, carries a "
                   "small loose piece with the body nearest to it)",
                   (int)bad);
      goto fail;
    }
  }
  if ((s = km_cotmatrix(rest, &L, err))) goto fail;
  const int32_t *cp, *ri;
  const double *lx;
  km_sparse_csc(L, &cp, &ri, &lx);
  /* neighbour lists (off-diagonal entries of the symmetric L) */
  size_t nnz = 0;
  for (size_t j = 0; j < n; ++j)
    for (int32_t q = cp[j]; q < cp[j + 1]; ++q)
      if ((size_t)ri[q] != j) {
        a->adj_off[j + 1]++;
        ++nnz;
      }
  for (size_t j = 0; j < n; ++j)
    a->adj_off[j + 1] += a->adj_off[j];
  a->adj = km__malloc(nnz ? nnz : 1, sizeof(int32_t));
  a->w = km__malloc(nnz ? nnz : 1, sizeof(double));
  if (!a->adj || !a->w) goto nomem;
  /* Edge weights: the cotangent weights, negative ones raised to a small positive floor.
   * Two obtuse angles opposite an edge make its cotangent weight negative (scanned meshes
   * have many: dog0, the horse). In the rotation fit such weights can outweigh the positive
   * ones at a vertex, whose best rotation at rest is then not the identity, so the rest pose
   * was not a fixed point: dog0's first frame, handles at rest, came out with edges 3.3x their
   * length and 304 folded triangles (bench motion --solver full). Both steps use the same
   * weights, so each still lowers one energy; the floor (1e-6 of the mean positive weight)
   * keeps every edge in the system, which stays as connected as the mesh. */
  double wsum = 0;
  size_t wpos = 0;
  for (size_t j = 0; j < n; ++j)
    for (int32_t q = cp[j]; q < cp[j + 1]; ++q)
      if ((size_t)ri[q] != j && lx[q] > 0) wsum += lx[q], ++wpos;
  double wfloor = wpos ? 1e-6 * wsum / (double)wpos : 1e-12;
  for (size_t j = 0, k = 0; j < n; ++j)
    for (int32_t q = cp[j]; q < cp[j + 1]; ++q)
      if ((size_t)ri[q] != j) {
        a->adj[k] = ri[q];
        a->w[k++] = lx[q] > wfloor ? lx[q] : wfloor;
      }
  if (o.handle_weight > 0) { /* soft handles: their vertices are unknowns too */
    a->hix = km__malloc(n, sizeof(int32_t));
    if (!a->hix) goto nomem;
    double dsum = 0;
    for (size_t k = 0; k < (size_t)a->adj_off[n]; ++k)
      dsum += a->w[k];
    a->soft = o.handle_weight * dsum / (double)n; /* relative to the mean diagonal of -L */
    for (size_t v = 0; v < n; ++v) {
      a->hix[v] = a->map[v] < 0 && a->map[v] != INT32_MIN ? -a->map[v] - 1 : -1;
      if (a->hix[v] >= 0) a->map[v] = (int32_t)nfree++;
    }
    a->n_free = nfree;
  }
  if (nfree > 0) {
    /* -L restricted to the free vertices, of the weights above: off the diagonal minus an
     * edge's weight, on it the sum of the vertex's weights (its handle neighbours' too) */
    size_t cap = (size_t)a->adj_off[n] + n; /* every edge both ways, and the diagonals */
    ti = km__malloc(cap ? cap : 1, sizeof(int32_t));
    tj = km__malloc(cap ? cap : 1, sizeof(int32_t));
    tv = km__malloc(cap ? cap : 1, sizeof(double));
    a->B = km__malloc(nfree * 3, sizeof(double));
    if (!ti || !tj || !tv || !a->B) goto nomem;
    size_t m = 0;
    for (size_t j = 0; j < n; ++j) {
      if (a->map[j] < 0) continue;
      double diag = 0;
      for (int32_t k = a->adj_off[j]; k < a->adj_off[j + 1]; ++k) {
        diag += a->w[k];
        if (a->map[a->adj[k]] < 0) continue;
        ti[m] = a->map[a->adj[k]];
        tj[m] = a->map[j];
        tv[m++] = -a->w[k];
      }
      ti[m] = tj[m] = a->map[j];
      tv[m++] = diag + (a->hix && a->hix[j] >= 0 ? a->soft : 0);
    }
    if ((s = km_sparse_from_triplets(nfree, nfree, m, ti, tj, tv, &A, err))) goto fail;
    if ((s = km_cholesky_analyze(A, &a->chol, err))) goto fail;
    if ((s = km_cholesky_factorize(a->chol, A, err))) {
      km__wrap(err, s,
               "arap: the constrained Laplacian is singular (every connected component needs "
               "a handle vertex)");
      goto fail;
    }
  }
  km_sparse_free(&L);
  km_sparse_free(&A);
  free(ti);
  free(tj);
  free(tv);
  *out = a;
  return KM_OK;
nomem:
  s = km__fail(err, KM_ERR_NOMEM, "arap: out of memory for %zu vertices", n);
fail:
  km_sparse_free(&L);
  km_sparse_free(&A);
  free(ti);
  free(tj);
  free(tv);
  km_arap_free(&a);
  return s;
}

static void local_step(km_arap *a) {
  const double *P = a->P, *X = a->X;
  ptrdiff_t n = (ptrdiff_t)a->n;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (n > 8192)
#endif
  for (ptrdiff_t i = 0; i < n; ++i) {
    double S[9] = {0};
    for (int32_t k = a->adj_off[i]; k < a->adj_off[i + 1]; ++k) {
      int32_t j = a->adj[k];
      double w = a->w[k];
      double e0[3], e1[3];
      for (int c = 0; c < 3; ++c) {
        e0[c] = P[3 * i + c] - P[3 * j + c];
        e1[c] = X[3 * i + c] - X[3 * j + c];
      }
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          S[r * 3 + c] += w * e1[r] * e0[c];
    }
    km__nearest_rotation3(S, a->R + 9 * i);
  }
}

km_status km_arap_solve(km_arap *a, const double *targets, double *V_out, km_error *err) {
  if (!a || !targets || !V_out) return km__fail(err, KM_ERR_INVALID, "arap solve: NULL argument");
  for (size_t i = 0; i < a->n_hv * 3; ++i)
    if (!isfinite(targets[i]))
      return km__fail(err, KM_ERR_INVALID, "arap solve: target of handle vertex %zu is not finite",
                      i / 3);
  if (a->welded) { /* split at its seams: solved welded, every copy takes its vertex's place */
    for (size_t k = 0; k < a->welded->n_hv; ++k)
      memcpy(a->Tw + 3 * k, targets + 3 * (size_t)a->hsrc[k], 3 * sizeof(double));
    km_status s = km_arap_solve(a->welded, a->Tw, a->Vw, err);
    if (s != KM_OK) return s;
    for (size_t v = 0; v < a->n_out; ++v)
      memcpy(V_out + 3 * v, a->Vw + 3 * (size_t)a->to_w[v], 3 * sizeof(double));
    return KM_OK;
  }
  for (size_t i = 0; i < a->n_hv && !a->hix; ++i)
    memcpy(a->X + 3 * (size_t)a->h_v[i], targets + 3 * i, 3 * sizeof(double));
  size_t n = a->n, nf = a->n_free;
  const double *P = a->P;
  for (int it = 0; it < a->iterations && nf > 0; ++it) {
    local_step(a);
    double *B = a->B;
    for (size_t i = 0; i < n; ++i) {
      int32_t fi = a->map[i];
      if (fi < 0) continue;
      double b[3] = {0, 0, 0};
      const double *Ri = a->R + 9 * i;
      for (int32_t k = a->adj_off[i]; k < a->adj_off[i + 1]; ++k) {
        int32_t j = a->adj[k];
        double w = 0.5 * a->w[k];
        const double *Rj = a->R + 9 * (size_t)j;
        double e0[3] = {P[3 * i] - P[3 * j], P[3 * i + 1] - P[3 * j + 1],
                        P[3 * i + 2] - P[3 * j + 2]};
        for (int r = 0; r < 3; ++r)
          b[r] += w * ((Ri[r * 3] + Rj[r * 3]) * e0[0] + (Ri[r * 3 + 1] + Rj[r * 3 + 1]) * e0[1] +
                       (Ri[r * 3 + 2] + Rj[r * 3 + 2]) * e0[2]);
        int32_t fj = a->map[j];
        if (fj < 0) /* eliminated handle: L_ij x_j moves to the right-hand side */
          for (int r = 0; r < 3; ++r)
            b[r] += a->w[k] * a->X[3 * j + r];
      }
      if (a->hix && a->hix[i] >= 0) /* a soft handle's pull to its target */
        for (int r = 0; r < 3; ++r)
          b[r] += a->soft * targets[3 * (size_t)a->hix[i] + r];
      for (int r = 0; r < 3; ++r)
        B[fi + r * nf] = b[r];
    }
    km_status s = km_cholesky_solve(a->chol, 3, B, B, err);
    if (s) return km__wrap(err, s, "arap solve");
    double move = 0;
    for (size_t i = 0; i < n; ++i) {
      int32_t fi = a->map[i];
      if (fi < 0) continue;
      for (int r = 0; r < 3; ++r) {
        double d = fabs(B[fi + r * nf] - a->X[3 * i + r]);
        move = d > move ? d : move;
        a->X[3 * i + r] = B[fi + r * nf];
      }
    }
    if (move < a->tolerance * a->diag) break;
  }
  if (a->att) { /* loose pieces: each vertex as its body vertex turns, the rotation of now */
    local_step(a);
    for (size_t v = 0; v < n; ++v) {
      int32_t b = a->att[v];
      if (b < 0) continue;
      double e[3] = {P[3 * v] - P[3 * b], P[3 * v + 1] - P[3 * b + 1], P[3 * v + 2] - P[3 * b + 2]};
      const double *Rb = a->R + 9 * (size_t)b;
      for (int r = 0; r < 3; ++r)
        a->X[3 * v + r] =
            a->X[3 * b + r] + Rb[3 * r] * e[0] + Rb[3 * r + 1] * e[1] + Rb[3 * r + 2] * e[2];
    }
  }
  memcpy(V_out, a->X, n * 3 * sizeof(double));
  return KM_OK;
}
