/* Reduced isoline deformation (Wu, Lu & Song, "A Real-Time Mesh Animation Framework Using
 * Kinect", sections 3.1 and 3.4, eq. 1-3, 8-9), on the isoline model of Au et al. 2007 and
 * the dual-Laplacian rotation updates of Au et al. 2006.
 *
 * Model. Field f (f < n_e) is the (f+1)-th eigenvector e_f of -L phi = lambda M phi. Field f
 * has n_iso iso-values; isoline (f,k) carries an affine transform T_fk (3x4). A vertex v with
 * field value e_f(v) between iso-values k and k+1 (parameter t) gets
 *     x_v = sum_f w_f ((1-t) T_fk + t T_f,k+1) [p_v; 1]                        (X = W R)
 * with the per-field weights w_f of eq. 2-3, normalised to sum 1, so the identity in every
 * isoline reproduces the rest mesh exactly. R is (4 n_iso n_e) x 3: row (f*n_iso+k)*4+j,
 * column c holds T_fk[c][j]; x, y and z share W.
 *
 * Everything is solved for dR = R - R_identity in coordinates normalised by the bounding
 * box (centre, diagonal), so the rest pose is the exact zero of every right-hand side
 * (rest targets give X = P bit for bit) and the 320x320 system is well scaled.
 *
 * Energy per frame (eq. 8-9, soft handles as in Au et al.):
 *     |L W R - W_d R_d|^2 + w_c^2 |W_Phi R - C|^2 + mu |R - I|^2
 * W_d R_d interpolates the isolines' rotations R_d (estimated on crossed triangles) to every
 * vertex exactly like W interpolates transforms, and applies them to the rest Laplacian
 * coordinates. Because that is linear in R_d, W^T L^T W_d is precomputed (the paper's
 * W^T L^T W_delta) and a rotation update costs a 320x240 product, independent of #V.
 * The price: a vertex's rotation is a linear blend of rotation matrices, which shortens its
 * Laplacian coordinate slightly where neighbouring isolines disagree (exact length would need
 * an O(#V) pass per iteration). Measured with such an exact pass (blend, renormalise to the
 * rest length, W^T L^T delta per iteration): armadillo, 5 moving handles, deviation from
 * full ARAP 2.370% vs 2.365% of the diagonal, i.e. no loss; so the solve stays independent
 * of #V. The isoline rotations themselves are exact (quaternion mean of the frames of their
 * sampled crossed triangles; a Kabsch fit over the same triangles gave the same deviation).
 *
 * energy = KM_PUPPET_ENERGY_ARAP swaps the Laplacian term for the reduced ARAP energy on the
 * same unknowns and rotations (assemble_reduced_arap): not in the paper, it follows the
 * full ARAP reference more closely (armadillo 1.6% vs 2.4%, horse 2.2% vs 2.8%).
 *
 * Cache: the solve needs W (stored structured: bracket + parameter per vertex and field, and
 * w_f), the crossed triangles, W^T L^T L W and W^T L^T W_delta; LW itself (~100 nonzeros per
 * vertex) is only an intermediate of those two products, so it is not stored. */
#include "core/core.h"

#include "math/math.h"
#include "mesh/mesh.h"

#include <errno.h>
#include "linalg/linalg.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define KM_PUPPET_MAGIC "KMPUPPET"
/* Cache format. 2: energy enum renumbered (ARAP = 0); 3: a mesh split at its seams gets the
 * welded mesh's fields (a format-2 cache of one holds its pieces' own, which let the seams
 * open); 4: a body's small loose pieces take its fields (fields_welded); 5: a loose piece that
 * does not wrap the body takes one body vertex's fields (km__mesh_body); 6: a piece reaching
 * further than 0.2 of the body's diagonal from it no longer counts as wrapping the body. */
#define KM_PUPPET_FORMAT 6u
#define KM_PUPPET_ENDIAN 0x01020304u
#define KM_PUPPET_HEADER 64u

/* mu = KM_PUPPET_RIDGE * trace(U^T U)/#unknowns. W has an exact null space (adding a
 * transform to every isoline of one field and subtracting w_f/w_g of it from another leaves X
 * unchanged: 4(n_e-1) directions per coordinate) that neither L nor the handles see, so
 * U^T U is singular without it. Null-space directions do not move X, so the ridge only has to
 * keep dpotrf away from round-off (>> 1e-16 relative); anything larger biases the smooth,
 * weakly determined modes toward the identity. Measured on the rigid-motion test (icosphere,
 * three small handles, 0.6 rad): ridge 1e-7 -> 1.7e-3 of the diagonal off rigid, 1e-9 ->
 * 1.9e-5, 1e-11 -> 2e-7; the bending deviation from ARAP did not change. */
#define KM_PUPPET_RIDGE 1e-11

struct km_puppet {
  /* ---- model (depends on the mesh and fields/isolines/crossed_per_isoline) */
  size_t n, nf;
  int ne, niso, ncross;
  km_puppet_energy energy;
  size_t nr, nd, n_isolines; /* 4 n_iso n_e, 3 n_iso n_e, n_iso n_e */
  double center[3], scale;
  uint64_t mesh_hash;
  double *P;      /* n*3 rest, world units */
  double *Pn;     /* n*3 rest, normalised: (p - center)/scale */
  double *wfield; /* ne, sum 1 */
  double *iso;    /* ne*niso iso-values, ascending per field */
  /* Vertex-major on purpose: the X = W R kernel reads one vertex's n_e brackets and
   * parameters from one or two cache lines and vectorises over the 12 entries of the blended
   * transform (one 16-lane vector per field), which needs no gathers; a field-major
   * (structure-of-arrays) layout would vectorise over vertices and need 24 gathers per field. */
  uint8_t *bracket; /* n*ne (vertex-major): lower isoline k, 0 <= k <= niso-2 */
  double *tpar;     /* n*ne interpolation parameter in [0,1] */
  float *tparf;     /* n*ne float copy */
  size_t ntri;
  int32_t *tri_v;   /* ntri*3 vertex ids of the crossed triangles */
  int32_t *tri_iso; /* ntri isoline id f*niso+k, ascending */
  int32_t *iso_off; /* n_isolines+1: triangles of isoline i are [iso_off[i], iso_off[i+1]) */
  int32_t *tri_lv;  /* ntri*3 local ids into cv */
  double *tri_F0;   /* ntri*9 rest frames */
  double *tri_a;    /* ntri area weights */
  size_t ncv;
  int32_t *cv;  /* vertices of the crossed triangles */
  double *cv_x; /* ncv*3 their current positions (workspace) */
  /* compact copies for the crossed vertices (the per-iteration loop would otherwise miss
   * the cache on every scattered vertex) */
  uint8_t *cv_br; /* ncv*ne */
  float *cv_t;    /* ncv*ne */
  float *cv_pf;   /* ncv*3 */
  double *cv_pn;  /* ncv*3 */
  int32_t *lone;  /* n_lone vertices no face uses: they keep their rest position */
  size_t n_lone;
  /* Loose pieces that follow one body vertex as a whole (km__mesh_body's rigid: a sword, a
   * ground plane): held_v[i] turns rigidly about anchor held_a[i] (an index into anc_v), by the
   * rotation fitted to that anchor's neighbours anc_nb[anc_off[k] .. anc_off[k+1]) (find_held) */
  int32_t *held_v, *held_a, *anc_v, *anc_off, *anc_nb;
  size_t n_held, n_anc;
  double *anc_R; /* n_anc*9 workspace */
  double *K0;    /* nr*nr  W^T L^T L W */
  double *G;     /* nr*nd  W^T L^T W_d */
  double trK0;
  /* ---- solve settings */
  int iterations;
  double tolerance, handle_weight;
  /* ---- handles */
  bool have_handles;
  size_t n_handles, n_hv;
  int32_t *h_off, *h_v;
  /* W_Phi^T grouped by row block: the (handle vertex, weight) pairs of isoline li are
   * [hw_off[li], hw_off[li+1]), so the right-hand side is gathered one isoline at a time in
   * registers instead of scattered per vertex (a read-modify-write per field and vertex). */
  int32_t *hw_off, *hw_i;
  double *hw_w;
  double *hM; /* n_hv*12 workspace: p4 (x) r of each handle vertex */
  /* Rigid handles. Every rig handle km_puppetry drives moves as an affine map of its rest
   * vertices (R x + t, or x + t), so its residual is r_i = G_h p4_i and its share of isoline
   * li's right-hand side, sum_i w_i p4_i r_i^T, is M_{li,h} G_h^T with the moments
   * M_{li,h} = sum_i w_i p4_i p4_i^T fixed once per handle set: 48 products per (isoline,
   * handle) instead of 12 per (handle vertex, field, isoline). G_h is fitted per frame and
   * checked against every vertex's target (handle_rhs), so a handle whose targets are not
   * affine (a floor clamp, a caller's own targets) still sums its vertices one by one. The
   * pairs of isoline li are in handle vertex order, hence grouped by handle: segment s is
   * pairs [seg_q[s], seg_q[s+1]) of handle seg_h[s], isoline li's segments are
   * [seg_off[li], seg_off[li+1]). */
  int32_t *seg_off, *seg_h, *seg_q;
  double *seg_m;  /* n_seg*16 moments (row-major 4x4) */
  double *h_pinv; /* n_handles*16 pseudo-inverse of sum p4 p4^T over the handle's vertices */
  double *h_G;    /* n_handles*12 workspace: fitted G_h^T (4x3, row-major) */
  unsigned char *h_affine; /* n_handles workspace: G_h reproduces every target */
  double wc2, mu;
  double *K;     /* nr*nr Cholesky factor (upper) of U^T U + mu I */
  double *Kt;    /* its transpose (lower), so both substitutions run as contiguous axpys */
  double *KinvG; /* nr*nd */
  float *KinvGf; /* float copy for the per-iteration product (half the cache traffic) */
  /* ---- state / workspace (solve does not allocate) */
  double *dR, *dR0, *dRnew; /* nr*3 */
  double *dRd;              /* nd*3 isoline rotations minus identity */
  double *quat;             /* n_isolines*4 */
  float *A, *D;             /* n_isolines*12 per-frame tables for X = W R */
  int last_iters;
  double last_change;
};

/* ------------------------------------------------------------------ small helpers */

static uint64_t hash_words(uint64_t h, const void *data, size_t size) {
  /* Word-wise multiply-xorshift: 8x faster than byte FNV on the multi-megabyte payload and
   * every step is a bijection of h, so any change confined to one word is always detected. */
  const unsigned char *b = data;
  size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    memcpy(&w, b + i, 8);
    h = (h ^ w) * 0x9E3779B97F4A7C15ULL;
    h ^= h >> 29;
  }
  uint64_t w = 0;
  memcpy(&w, b + i, size - i);
  h = (h ^ w ^ ((uint64_t)size << 56)) * 0x9E3779B97F4A7C15ULL;
  h ^= h >> 29;
  return h;
}

static uint64_t mesh_hash(const km_mesh *m) {
  uint64_t h = KM__FNV_SEED;
  uint64_t sz[2] = {m->n_vertices, m->n_faces};
  h = hash_words(h, sz, sizeof sz);
  h = hash_words(h, m->V, m->n_vertices * 3 * sizeof(double));
  h = hash_words(h, m->F, m->n_faces * 3 * sizeof(int32_t));
  return h;
}

static void resolve_options(const km_puppet_options *opt, km_puppet_options *o) {
  memset(o, 0, sizeof *o);
  if (opt) *o = *opt;
  if (o->fields == 0) o->fields = 8;
  if (o->isolines == 0) o->isolines = 10;
  if (o->iterations == 0) o->iterations = 4;
  if (o->tolerance == 0) o->tolerance = 1e-4;
  if (o->handle_weight == 0) o->handle_weight = o->energy == KM_PUPPET_ENERGY_ARAP ? 3 : 1;
  if (o->crossed_per_isoline == 0) o->crossed_per_isoline = 10;
}

static km_status check_options(const km_puppet_options *o, km_error *err) {
  if (o->fields < 1 || o->fields > 32)
    return km__fail(err, KM_ERR_INVALID, "puppet: fields must be 1..32 (got %d)", o->fields);
  if (o->isolines < 2 || o->isolines > 64)
    return km__fail(err, KM_ERR_INVALID, "puppet: isolines must be 2..64 (got %d)", o->isolines);
  if (o->iterations < 0 || o->iterations > 1000)
    return km__fail(err, KM_ERR_INVALID, "puppet: iterations must be 0..1000 (got %d)",
                    o->iterations);
  if (!(o->tolerance >= 0) || !(o->handle_weight > 0) || !isfinite(o->handle_weight))
    return km__fail(err, KM_ERR_INVALID,
                    "puppet: tolerance must be >= 0 and handle_weight > 0 and finite");
  if (o->energy != KM_PUPPET_ENERGY_LAPLACIAN && o->energy != KM_PUPPET_ENERGY_ARAP)
    return km__fail(err, KM_ERR_INVALID, "puppet: unknown energy %d", (int)o->energy);
  if (o->crossed_per_isoline < 1 || o->crossed_per_isoline > 1000000)
    return km__fail(err, KM_ERR_INVALID, "puppet: crossed_per_isoline must be >= 1 (got %d)",
                    o->crossed_per_isoline);
  return KM_OK;
}

static km_status check_mesh(const km_mesh *m, km_error *err) {
  if (!m || !m->V || !m->F || m->n_vertices < 4 || m->n_faces < 1)
    return km__fail(err, KM_ERR_INVALID,
                    "puppet: the rest mesh needs at least 4 vertices and 1 face");
  if (m->n_vertices > INT32_MAX || m->n_faces > INT32_MAX / 3)
    return km__fail(err, KM_ERR_INVALID, "puppet: mesh too large for int32 indices");
  for (size_t i = 0; i < m->n_vertices * 3; ++i)
    if (!isfinite(m->V[i]))
      return km__fail(err, KM_ERR_INVALID, "puppet: vertex %zu has a non-finite coordinate", i / 3);
  for (size_t i = 0; i < m->n_faces * 3; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= m->n_vertices)
      return km__fail(err, KM_ERR_INVALID,
                      "puppet: face %zu references vertex %d (mesh has %zu vertices)", i / 3,
                      (int)m->F[i], m->n_vertices);
  return KM_OK;
}

/* The vertices no face uses (issue 18): the fields give them arbitrary values, so the solve
 * puts them back at rest instead of moving them with whatever isolines they fall between. */
static km_status find_lone(km_puppet *p, const km_mesh *rest, km_error *err) {
  uint8_t *used = km__calloc(rest->n_vertices ? rest->n_vertices : 1, 1);
  if (!used) return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  for (size_t k = 0; k < 3 * rest->n_faces; ++k)
    used[rest->F[k]] = 1;
  size_t n = 0;
  for (size_t i = 0; i < rest->n_vertices; ++i)
    n += !used[i];
  free(p->lone);
  p->lone = NULL;
  p->n_lone = 0;
  if (n && !(p->lone = km__malloc(n, sizeof(int32_t)))) {
    free(used);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  }
  for (size_t i = 0; i < rest->n_vertices; ++i)
    if (!used[i]) p->lone[p->n_lone++] = (int32_t)i;
  free(used);
  return KM_OK;
}

/* The vertices of loose pieces that follow one body vertex as a whole, and that vertex's
 * neighbours: X = W R gives each of them the anchor's affine transform (its fields), scale and
 * shear included, which a piece far from its anchor magnifies: a 0.5 m blade in armadillo_1k's
 * hand, waving, was 0.70-0.85 of its length (full ARAP, which turns it with the rotation it fits
 * at the anchor, 1.00). The solve places each such vertex at the anchor's solved position plus
 * its rest offset turned by the rotation fitted to the anchor's neighbours (km__rotation_fit3). */
static km_status find_held(km_puppet *p, const km_mesh *rest, km_error *err) {
  size_t n = rest->n_vertices;
  void *old[] = {p->held_v, p->held_a, p->anc_v, p->anc_off, p->anc_nb, p->anc_R};
  for (size_t i = 0; i < sizeof old / sizeof old[0]; ++i)
    free(old[i]);
  p->held_v = p->held_a = p->anc_v = p->anc_off = p->anc_nb = NULL;
  p->anc_R = NULL;
  p->n_held = p->n_anc = 0;
  km__weld wd;
  km__body bd = {0};
  bool found = false;
  int32_t *slot = NULL;
  km_status s = km__file_body(rest, &wd, &bd, &found, err);
  if (s != KM_OK) return s;
  if (!found || !bd.rigid) goto done;
  /* anchors keyed by their vertex of the joined mesh, whose faces give their neighbours (a
   * seam's copies of a vertex move alike, and the lowest copy, wd.first, may be in no face) */
  const km_mesh *wm = wd.to_w ? &wd.w : rest;
  size_t nw = wm->n_vertices;
  if (!(slot = km__malloc(nw ? nw : 1, sizeof *slot))) goto nomem;
  for (size_t u = 0; u < nw; ++u)
    slot[u] = -1;
  size_t nh = 0, na = 0;
  for (size_t v = 0; v < n; ++v) {
    size_t u = wd.to_w ? (size_t)wd.to_w[v] : v;
    if (!bd.rigid[u]) continue;
    size_t ua = (size_t)bd.from_body[bd.to_body[u]];
    if (slot[ua] < 0) slot[ua] = (int32_t)na++;
    ++nh;
  }
  p->held_v = km__malloc(nh, sizeof(int32_t));
  p->held_a = km__malloc(nh, sizeof(int32_t));
  p->anc_v = km__malloc(na, sizeof(int32_t));
  p->anc_off = km__calloc(na + 1, sizeof(int32_t));
  p->anc_R = km__malloc(na, 9 * sizeof(double));
  if (!p->held_v || !p->held_a || !p->anc_v || !p->anc_off || !p->anc_R) goto nomem;
  for (size_t v = 0; v < n; ++v) {
    size_t u = wd.to_w ? (size_t)wd.to_w[v] : v;
    if (!bd.rigid[u]) continue;
    size_t ua = (size_t)bd.from_body[bd.to_body[u]];
    p->anc_v[slot[ua]] = wd.to_w ? wd.first[ua] : (int32_t)ua; /* a vertex of the file */
    p->held_v[p->n_held] = (int32_t)v;
    p->held_a[p->n_held++] = slot[ua];
  }
  p->n_anc = na;
  /* each anchor's neighbours: the other corners of its faces (two passes: count, fill) */
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (size_t k = 0; k < na; ++k)
        p->anc_off[k + 1] += p->anc_off[k];
      if (!(p->anc_nb = km__malloc(p->anc_off[na] ? (size_t)p->anc_off[na] : 1, sizeof(int32_t))))
        goto nomem;
    }
    int32_t *fill = pass ? km__malloc(na ? na : 1, sizeof *fill) : NULL;
    if (pass && !fill) goto nomem;
    for (size_t k = 0; pass && k < na; ++k)
      fill[k] = p->anc_off[k];
    for (size_t f = 0; f < wm->n_faces; ++f) {
      const int32_t *t = wm->F + 3 * f;
      if (km__face_collapsed(t)) continue;
      for (int c = 0; c < 3; ++c) {
        int32_t k = slot[t[c]];
        if (k < 0) continue;
        for (int e = 1; e < 3; ++e) {
          int32_t nb = t[(c + e) % 3];
          if (pass)
            p->anc_nb[fill[k]++] = wd.to_w ? wd.first[nb] : nb;
          else
            ++p->anc_off[k + 1];
        }
      }
    }
    free(fill);
  }
  goto done;
nomem:
  s = km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
done:
  free(slot);
  km__body_free(&bd);
  km__weld_free(&wd);
  return s;
}

/* Places the held vertices (find_held) from the solved positions of their anchors. */
static void place_held(const km_puppet *p, double *V) {
  for (size_t k = 0; k < p->n_anc; ++k) {
    const double *pa = p->P + 3 * (size_t)p->anc_v[k], *xa = V + 3 * (size_t)p->anc_v[k];
    double H[9] = {0}, S[3], *R = p->anc_R + 9 * k;
    for (int32_t i = p->anc_off[k]; i < p->anc_off[k + 1]; ++i) {
      const double *pj = p->P + 3 * (size_t)p->anc_nb[i], *xj = V + 3 * (size_t)p->anc_nb[i];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          H[3 * r + c] += (pj[r] - pa[r]) * (xj[c] - xa[c]);
    }
    km__rotation_fit3(H, R, S); /* identity when it fails */
  }
  for (size_t i = 0; i < p->n_held; ++i) {
    size_t v = (size_t)p->held_v[i], a = (size_t)p->anc_v[p->held_a[i]];
    double d[3] = {p->P[3 * v] - p->P[3 * a], p->P[3 * v + 1] - p->P[3 * a + 1],
                   p->P[3 * v + 2] - p->P[3 * a + 2]},
           y[3];
    km__m3_apply(p->anc_R + 9 * (size_t)p->held_a[i], d, y);
    for (int c = 0; c < 3; ++c)
      V[3 * v + (size_t)c] = V[3 * a + (size_t)c] + y[c];
  }
}

void km_puppet_free(km_puppet **pp) {
  if (!pp || !*pp) return;
  km_puppet *p = *pp;
  void *ptrs[] = {p->P,       p->Pn,      p->wfield,  p->iso,      p->bracket, p->tpar,   p->tparf,
                  p->tri_v,   p->tri_iso, p->iso_off, p->tri_lv,   p->tri_F0,  p->tri_a,  p->cv,
                  p->cv_x,    p->K0,      p->G,       p->h_off,    p->h_v,     p->K,      p->KinvG,
                  p->KinvGf,  p->dR,      p->dR0,     p->dRnew,    p->dRd,     p->quat,   p->A,
                  p->D,       p->cv_br,   p->cv_t,    p->cv_pf,    p->cv_pn,   p->Kt,     p->lone,
                  p->hw_off,  p->hw_i,    p->hw_w,    p->hM,       p->seg_off, p->seg_h,  p->seg_q,
                  p->seg_m,   p->h_pinv,  p->h_G,     p->h_affine, p->held_v,  p->held_a, p->anc_v,
                  p->anc_off, p->anc_nb,  p->anc_R};
  for (size_t i = 0; i < sizeof ptrs / sizeof ptrs[0]; ++i)
    free(ptrs[i]);
  free(p);
  *pp = NULL;
}

/* Allocates the model arrays whose sizes depend only on n, ne, niso (not ntri). */
static km_status alloc_model(km_puppet *p, const km_mesh *m, const km_puppet_options *o,
                             km_error *err) {
  p->n = m->n_vertices;
  p->nf = m->n_faces;
  p->ne = o->fields;
  p->niso = o->isolines;
  p->ncross = o->crossed_per_isoline;
  p->energy = o->energy;
  p->n_isolines = (size_t)p->ne * p->niso;
  p->nr = 4 * p->n_isolines;
  p->nd = 3 * p->n_isolines;
  p->iterations = o->iterations;
  p->tolerance = o->tolerance;
  p->handle_weight = o->handle_weight;
  size_t n = p->n, ne = p->ne;
  p->P = km__malloc(n * 3, sizeof(double));
  p->Pn = km__malloc(n * 3, sizeof(double));
  p->wfield = km__malloc(ne, sizeof(double));
  p->iso = km__malloc(p->n_isolines, sizeof(double));
  p->bracket = km__malloc(n * ne, 1);
  p->tpar = km__malloc(n * ne, sizeof(double));
  p->tparf = km__malloc(n * ne, sizeof(float));
  p->iso_off = km__calloc(p->n_isolines + 1, sizeof(int32_t));
  p->K0 = km__calloc(p->nr * p->nr, sizeof(double));
  p->G = km__calloc(p->nr * p->nd, sizeof(double));
  p->K = km__calloc(p->nr * p->nr, sizeof(double));
  p->Kt = km__calloc(p->nr * p->nr, sizeof(double));
  p->KinvG = km__calloc(p->nr * p->nd, sizeof(double));
  p->KinvGf = km__calloc(p->nr * p->nd, sizeof(float));
  p->dR = km__calloc(p->nr * 3, sizeof(double));
  p->dR0 = km__calloc(p->nr * 3, sizeof(double));
  p->dRnew = km__calloc(p->nr * 3, sizeof(double));
  p->dRd = km__calloc(p->nd * 3, sizeof(double));
  p->quat = km__calloc(p->n_isolines * 4, sizeof(double));
  /* 64-byte aligned, 16 lanes per isoline: one AVX-512 register (or 2 AVX / 4 SSE) */
  p->A = aligned_alloc(64, p->n_isolines * 16 * sizeof(float));
  p->D = aligned_alloc(64, p->n_isolines * 16 * sizeof(float));
  if (p->A) memset(p->A, 0, p->n_isolines * 16 * sizeof(float));
  if (p->D) memset(p->D, 0, p->n_isolines * 16 * sizeof(float));
  if (!p->P || !p->Pn || !p->wfield || !p->iso || !p->bracket || !p->tpar || !p->tparf ||
      !p->iso_off || !p->K0 || !p->G || !p->K || !p->Kt || !p->KinvG || !p->KinvGf || !p->dR ||
      !p->dR0 || !p->dRnew || !p->dRd || !p->quat || !p->A || !p->D)
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory for a %zu-vertex model", n);
  for (size_t i = 0; i < p->n_isolines; ++i)
    p->quat[i * 4] = 1;
  memcpy(p->P, m->V, n * 3 * sizeof(double));
  double lo[3], hi[3];
  for (int c = 0; c < 3; ++c)
    lo[c] = hi[c] = m->V[c];
  for (size_t v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c) {
      double x = m->V[v * 3 + c];
      lo[c] = x < lo[c] ? x : lo[c];
      hi[c] = x > hi[c] ? x : hi[c];
    }
  double d2 = 0;
  for (int c = 0; c < 3; ++c) {
    p->center[c] = 0.5 * (lo[c] + hi[c]);
    d2 += (hi[c] - lo[c]) * (hi[c] - lo[c]);
  }
  p->scale = sqrt(d2);
  if (!(p->scale > 0) || !isfinite(p->scale))
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "puppet: the rest mesh has no extent");
  for (size_t v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c) {
      p->Pn[v * 3 + c] = (m->V[v * 3 + c] - p->center[c]) / p->scale;
    }
  p->mesh_hash = mesh_hash(m);
  return KM_OK;
}

/* Derived data of the crossed triangles (rest frames, local vertex list) and float copies;
 * shared by precompute and load. tri_v/tri_iso must be set and validated. */
static km_status finish_model(km_puppet *p, km_error *err) {
  size_t n = p->n;
  for (size_t i = 0; i < n * (size_t)p->ne; ++i)
    p->tparf[i] = (float)p->tpar[i];
  memset(p->iso_off, 0, (p->n_isolines + 1) * sizeof(int32_t));
  for (size_t t = 0; t < p->ntri; ++t)
    p->iso_off[p->tri_iso[t] + 1]++;
  for (size_t i = 0; i < p->n_isolines; ++i)
    p->iso_off[i + 1] += p->iso_off[i];
  size_t nt = p->ntri ? p->ntri : 1;
  p->tri_lv = km__malloc(nt * 3, sizeof(int32_t));
  p->tri_F0 = km__malloc(nt * 9, sizeof(double));
  p->tri_a = km__malloc(nt, sizeof(double));
  int32_t *local = km__malloc(n, sizeof(int32_t));
  if (!p->tri_lv || !p->tri_F0 || !p->tri_a || !local) {
    free(local);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory for %zu crossed triangles", p->ntri);
  }
  for (size_t v = 0; v < n; ++v)
    local[v] = -1;
  size_t ncv = 0;
  for (size_t t = 0; t < p->ntri * 3; ++t)
    if (local[p->tri_v[t]] < 0) local[p->tri_v[t]] = (int32_t)ncv++;
  p->ncv = ncv;
  p->cv = km__malloc(ncv ? ncv : 1, sizeof(int32_t));
  p->cv_x = km__malloc((ncv ? ncv : 1) * 3, sizeof(double));
  if (!p->cv || !p->cv_x) {
    free(local);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  }
  p->cv_br = km__malloc((ncv ? ncv : 1) * (size_t)p->ne, 1);
  p->cv_t = km__malloc((ncv ? ncv : 1) * (size_t)p->ne, sizeof(float));
  p->cv_pf = km__malloc((ncv ? ncv : 1) * 3, sizeof(float));
  p->cv_pn = km__malloc((ncv ? ncv : 1) * 3, sizeof(double));
  if (!p->cv_br || !p->cv_t || !p->cv_pf || !p->cv_pn) {
    free(local);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  }
  for (size_t v = 0; v < n; ++v)
    if (local[v] >= 0) {
      size_t i = (size_t)local[v], ne = (size_t)p->ne;
      p->cv[i] = (int32_t)v;
      memcpy(p->cv_br + i * ne, p->bracket + v * ne, ne);
      memcpy(p->cv_t + i * ne, p->tparf + v * ne, ne * sizeof(float));
      for (int c = 0; c < 3; ++c)
        p->cv_pf[i * 3 + c] = (float)p->Pn[v * 3 + c];
      memcpy(p->cv_pn + i * 3, p->Pn + v * 3, 3 * sizeof(double));
    }
  for (size_t t = 0; t < p->ntri; ++t) {
    for (int k = 0; k < 3; ++k)
      p->tri_lv[t * 3 + k] = local[p->tri_v[t * 3 + k]];
    const double *a = p->Pn + 3 * p->tri_v[t * 3], *b = p->Pn + 3 * p->tri_v[t * 3 + 1],
                 *c = p->Pn + 3 * p->tri_v[t * 3 + 2];
    p->tri_a[t] = 0.5 * km__tri_frame(a, b, c, p->tri_F0 + t * 9);
    if (p->tri_a[t] <= 0) memset(p->tri_F0 + t * 9, 0, 9 * sizeof(double));
  }
  free(local);
  return KM_OK;
}

/* The 2 isoline ids and weights of vertex v in field f, times w_f. */
static inline void w_entry(const km_puppet *p, size_t v, int f, size_t *i0, double *a0,
                           double *a1) {
  int b = p->bracket[v * p->ne + f];
  double t = p->tpar[v * p->ne + f];
  *i0 = (size_t)f * p->niso + b;
  *a0 = p->wfield[f] * (1 - t);
  *a1 = p->wfield[f] * t;
}

/* ------------------------------------------------------------------ precompute */

/* Diagonal of a (diagonal) sparse matrix. */
static void sparse_diag(const km_sparse *A, double *d) {
  const int32_t *cp, *ri;
  const double *x;
  km_sparse_csc(A, &cp, &ri, &x);
  size_t n = km_sparse_cols(A);
  for (size_t j = 0; j < n; ++j) {
    d[j] = 0;
    for (int32_t k = cp[j]; k < cp[j + 1]; ++k)
      if ((size_t)ri[k] == j) d[j] = x[k];
  }
}

/* Iso-values evenly spaced over the field's range with half-step margins,
 * min + (k + 1/2) (max - min) / n_iso, so the end isolines still cross triangles (an isoline
 * exactly at the extreme is a single vertex and would carry no rotation). We also tried mass
 * quantiles (every isoline controls the same area): on armadillo (43k) and horse (48k) with 5
 * moving handles, even spacing deviated less from full ARAP (mean 2.27% vs 2.45% and 2.72% vs
 * 2.89% of the diagonal; max 10% vs 18% on the horse): the extremities, where eigenfunctions
 * peak, are exactly where handles sit and need the isolines. */
static km_status place_isolines(km_puppet *p, const double *evecs, km_error *err) {
  size_t n = p->n;
  (void)err;
  for (int f = 0; f < p->ne; ++f) {
    const double *e = evecs + (size_t)(f + 1) * n;
    double lo = e[0], hi = e[0];
    for (size_t v = 1; v < n; ++v) {
      lo = e[v] < lo ? e[v] : lo;
      hi = e[v] > hi ? e[v] : hi;
    }
    double *iso = p->iso + (size_t)f * p->niso;
    for (int k = 0; k < p->niso; ++k)
      iso[k] = lo + (hi - lo) * (k + 0.5) / p->niso;
    double range = hi - lo;
    for (int k = 1; k < p->niso; ++k)
      if (iso[k] <= iso[k - 1]) iso[k] = iso[k - 1] + 1e-9 * (range > 0 ? range : 1);
    for (size_t v = 0; v < n; ++v) {
      double x = e[v];
      int b;
      double t;
      if (x <= iso[0]) {
        b = 0;
        t = 0;
      } else if (x >= iso[p->niso - 1]) {
        b = p->niso - 2;
        t = 1;
      } else {
        int lo = 0, hi = p->niso - 1; /* iso[lo] <= x < iso[hi] */
        while (hi - lo > 1) {
          int mid = (lo + hi) / 2;
          if (iso[mid] <= x)
            lo = mid;
          else
            hi = mid;
        }
        b = lo;
        t = (x - iso[lo]) / (iso[lo + 1] - iso[lo]);
        t = t < 0 ? 0 : t > 1 ? 1 : t;
      }
      p->bracket[v * p->ne + f] = (uint8_t)b;
      p->tpar[v * p->ne + f] = t;
    }
  }
  return KM_OK;
}

/* Triangles crossed by each isoline (min < iso <= max over its corners), thinned to at most
 * ncross per isoline by farthest-point sampling of centroids so the samples cover the whole
 * isoline (the paper's n_tri ~ 800 for 80 isolines is ~10 per isoline). */
static km_status select_crossed(km_puppet *p, const km_mesh *m, const double *evecs,
                                km_error *err) {
  size_t n = p->n, nf = m->n_faces, nI = p->n_isolines;
  size_t *cnt = km__calloc(nI + 1, sizeof(size_t));
  if (!cnt) return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  for (int pass = 0; pass < 2; ++pass) {
    /* pass 0 counts, pass 1 fills */
    int32_t *list = NULL;
    size_t *fill = NULL;
    if (pass == 1) {
      for (size_t i = 0; i < nI; ++i)
        cnt[i + 1] += cnt[i];
      list = km__malloc(cnt[nI] ? cnt[nI] : 1, sizeof(int32_t));
      fill = km__calloc(nI, sizeof(size_t));
      if (!list || !fill) {
        free(list);
        free(fill);
        free(cnt);
        return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
      }
    }
    for (size_t t = 0; t < nf; ++t) {
      const int32_t *F = m->F + 3 * t;
      if (F[0] == F[1] || F[1] == F[2] || F[0] == F[2]) continue;
      for (int f = 0; f < p->ne; ++f) {
        const double *e = evecs + (size_t)(f + 1) * n;
        double a = e[F[0]], b = e[F[1]], c = e[F[2]];
        double lo = fmin(a, fmin(b, c)), hi = fmax(a, fmax(b, c));
        const double *iso = p->iso + (size_t)f * p->niso;
        for (int k = 0; k < p->niso; ++k) {
          if (iso[k] > lo && iso[k] <= hi) {
            size_t li = (size_t)f * p->niso + k;
            if (pass == 0)
              cnt[li + 1]++;
            else
              list[cnt[li] + fill[li]++] = (int32_t)t;
          }
        }
      }
    }
    if (pass == 1) {
      free(fill);
      /* farthest-point sampling per isoline */
      size_t cap = (size_t)p->ncross, total = 0;
      for (size_t li = 0; li < nI; ++li)
        total += cnt[li + 1] - cnt[li] < cap ? cnt[li + 1] - cnt[li] : cap;
      p->ntri = total;
      p->tri_v = km__malloc(total ? total * 3 : 3, sizeof(int32_t));
      p->tri_iso = km__malloc(total ? total : 1, sizeof(int32_t));
      size_t maxc = 0;
      for (size_t li = 0; li < nI; ++li)
        if (cnt[li + 1] - cnt[li] > maxc) maxc = cnt[li + 1] - cnt[li];
      double *dist = km__malloc(maxc ? maxc : 1, sizeof(double));
      double *cen = km__malloc(maxc ? maxc * 3 : 3, sizeof(double));
      if (!p->tri_v || !p->tri_iso || !dist || !cen) {
        free(dist);
        free(cen);
        free(list);
        free(cnt);
        return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
      }
      size_t out = 0;
      for (size_t li = 0; li < nI; ++li) {
        const int32_t *L = list + cnt[li];
        size_t c = cnt[li + 1] - cnt[li];
        for (size_t i = 0; i < c; ++i) {
          const int32_t *F = m->F + 3 * L[i];
          for (int d = 0; d < 3; ++d)
            cen[i * 3 + d] = (p->Pn[F[0] * 3 + d] + p->Pn[F[1] * 3 + d] + p->Pn[F[2] * 3 + d]) / 3;
          dist[i] = INFINITY;
        }
        size_t take = c < cap ? c : cap, cur = 0;
        for (size_t s = 0; s < take; ++s) {
          const int32_t *F = m->F + 3 * L[cur];
          memcpy(p->tri_v + out * 3, F, 3 * sizeof(int32_t));
          p->tri_iso[out++] = (int32_t)li;
          dist[cur] = -1;
          size_t best = cur;
          double bd = -1;
          for (size_t i = 0; i < c; ++i) {
            if (dist[i] < 0) continue;
            double dx = cen[i * 3] - cen[cur * 3], dy = cen[i * 3 + 1] - cen[cur * 3 + 1],
                   dz = cen[i * 3 + 2] - cen[cur * 3 + 2];
            double d = dx * dx + dy * dy + dz * dz;
            if (d < dist[i]) dist[i] = d;
            if (dist[i] > bd) {
              bd = dist[i];
              best = i;
            }
          }
          cur = best;
        }
      }
      free(dist);
      free(cen);
      free(list);
    }
  }
  free(cnt);
  return KM_OK;
}

/* K0 = (LW)^T (LW) and G = (LW)^T W_d, one row of L at a time: row i of LW touches only the
 * isolines bracketing i's neighbours (~3 per field), so each row costs ~(12 n_e)^2 instead
 * of a dense 320^2. Per-thread accumulators, summed at the end. */

/* Sparse accumulator over isoline rows: row li of buf (width w) joins the list of rows touched
 * for `owner` (zeroed on first touch), then buf[li] += a * v. */
static inline void spa_add(int32_t *stamp, int32_t *list, int *n, double *buf, int w, size_t li,
                           int32_t owner, double a, const double *v) {
  if (stamp[li] != owner) {
    stamp[li] = owner;
    list[(*n)++] = (int32_t)li;
    for (int k = 0; k < w; ++k)
      buf[li * (size_t)w + k] = 0;
  }
  for (int k = 0; k < w; ++k)
    buf[li * (size_t)w + k] += a * v[k];
}

static km_status assemble_reduced(km_puppet *p, const km_sparse *L, const double *delta0,
                                  km_error *err) {
  const int32_t *cp, *ri;
  const double *lx;
  km_sparse_csc(L, &cp, &ri, &lx); /* symmetric: column i == row i */
  size_t nr = p->nr, nd = p->nd, nI = p->n_isolines, n = p->n;
  int nthreads = 1;
#ifdef _OPENMP
  nthreads = omp_get_max_threads();
  if (nthreads > 8) nthreads = 8;
  if (n < 20000) nthreads = 1;
#endif
  double *bufK = km__calloc((size_t)nthreads * nr * nr, sizeof(double));
  double *bufG = km__calloc((size_t)nthreads * nr * nd, sizeof(double));
  double *scratch = km__calloc((size_t)nthreads * nr, sizeof(double));
  int32_t *stamp = km__malloc((size_t)nthreads * nI, sizeof(int32_t));
  int32_t *touched = km__malloc((size_t)nthreads * nI, sizeof(int32_t));
  if (!bufK || !bufG || !scratch || !stamp || !touched) {
    free(bufK);
    free(bufG);
    free(scratch);
    free(stamp);
    free(touched);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory assembling the reduced system");
  }
  for (size_t i = 0; i < (size_t)nthreads * nI; ++i)
    stamp[i] = -1;
#ifdef _OPENMP
#pragma omp parallel num_threads(nthreads)
#endif
  {
    int tid = 0;
#ifdef _OPENMP
    tid = omp_get_thread_num();
#endif
    double *Kt = bufK + (size_t)tid * nr * nr, *Gt = bufG + (size_t)tid * nr * nd;
    double *acc = scratch + (size_t)tid * nr;
    int32_t *st = stamp + (size_t)tid * nI, *tl = touched + (size_t)tid * nI;
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
    for (ptrdiff_t ii = 0; ii < (ptrdiff_t)n; ++ii) {
      size_t i = (size_t)ii;
      int nt = 0;
      for (int32_t q = cp[i]; q < cp[i + 1]; ++q) {
        size_t j = (size_t)ri[q];
        double l = lx[q];
        const double *pj = p->Pn + 3 * j;
        double p4[4] = {pj[0], pj[1], pj[2], 1};
        for (int f = 0; f < p->ne; ++f) {
          size_t I0;
          double a0, a1;
          w_entry(p, j, f, &I0, &a0, &a1);
          for (int s = 0; s < 2; ++s) {
            size_t li = I0 + s;
            spa_add(st, tl, &nt, acc, 4, li, (int32_t)i, l * (s ? a1 : a0), p4);
          }
        }
      }
      /* sort the ~24 touched isolines so K0 is filled in its upper block triangle only */
      for (int a = 1; a < nt; ++a) {
        int32_t x = tl[a];
        int b = a - 1;
        while (b >= 0 && tl[b] > x) {
          tl[b + 1] = tl[b];
          --b;
        }
        tl[b + 1] = x;
      }
      for (int a = 0; a < nt; ++a) {
        const double *va = acc + (size_t)tl[a] * 4;
        for (int b = a; b < nt; ++b) {
          const double *vb = acc + (size_t)tl[b] * 4;
          double *Kb = Kt + (size_t)tl[a] * 4 + (size_t)tl[b] * 4 * nr;
          for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r)
              Kb[r + c * nr] += va[r] * vb[c];
        }
      }
      /* W_d row i: isolines of i, coefficient w_f alpha delta0_i[j] */
      const double *d0 = delta0 + 3 * i;
      for (int f = 0; f < p->ne; ++f) {
        size_t I0;
        double a0, a1;
        w_entry(p, i, f, &I0, &a0, &a1);
        for (int s = 0; s < 2; ++s) {
          double a = s ? a1 : a0;
          if (a == 0) continue;
          size_t J = I0 + s;
          for (int j = 0; j < 3; ++j) {
            double cj = a * d0[j];
            double *Gc = Gt + (J * 3 + j) * nr;
            for (int x = 0; x < nt; ++x) {
              const double *va = acc + (size_t)tl[x] * 4;
              double *g = Gc + (size_t)tl[x] * 4;
              for (int r = 0; r < 4; ++r)
                g[r] += va[r] * cj;
            }
          }
        }
      }
    }
  }
  for (int t = 0; t < nthreads; ++t) {
    const double *Kt = bufK + (size_t)t * nr * nr, *Gt = bufG + (size_t)t * nr * nd;
    for (size_t i = 0; i < nr * nr; ++i)
      p->K0[i] += Kt[i];
    for (size_t i = 0; i < nr * nd; ++i)
      p->G[i] += Gt[i];
  }
  /* mirror: blocks (I <= J) were filled, both triangles of the diagonal blocks included */
  for (size_t c = 0; c < nr; ++c)
    for (size_t r = 0; r < nr; ++r)
      if (r / 4 > c / 4) p->K0[r + c * nr] = p->K0[c + r * nr];
  free(bufK);
  free(bufG);
  free(scratch);
  free(stamp);
  free(touched);
  return KM_OK;
}

/* The reduced as-rigid-as-possible energy (energy = KM_PUPPET_ENERGY_ARAP):
 *     sum_ij w_ij |(x_i - x_j) - R_ij (p_i - p_j)|^2,  x = W R,  R_ij = (R_i + R_j)/2
 * with the vertex rotations R_v interpolated from the isolines' rotations exactly like the
 * Laplacian coordinates' in the paper's energy (W_delta). Its normal equations are
 *     W^T (-L) W R = W^T B R_delta,   b_i = sum_j w_ij/2 (R_i + R_j)(p_i - p_j),
 * both sides precomputed: K0 = W^T (-L) W and G = W^T B, so the solve is unchanged. This is
 * the first-order (membrane) energy of the full ARAP reference, where the paper's
 * |L X - delta|^2 is second order (thin-plate-like): it bends handles' surroundings
 * differently, which is most of the paper model's deviation from ARAP. */
static km_status assemble_reduced_arap(km_puppet *p, const km_sparse *L, km_error *err) {
  const int32_t *cp, *ri;
  const double *lx;
  km_sparse_csc(L, &cp, &ri, &lx);
  size_t nr = p->nr, nd = p->nd, nI = p->n_isolines, n = p->n;
  int nthreads = 1;
#ifdef _OPENMP
  nthreads = omp_get_max_threads();
  if (nthreads > 8) nthreads = 8;
  if (n < 20000) nthreads = 1;
#endif
  size_t T = (size_t)nthreads;
  double *bufK = km__calloc(T * nr * nr, sizeof(double));
  double *bufG = km__calloc(T * nr * nd, sizeof(double));
  double *scratch = km__calloc(T * nr, sizeof(double));
  double *gscr = km__calloc(T * nI * 3, sizeof(double));
  int32_t *stamp = km__malloc(T * nI * 2, sizeof(int32_t));
  int32_t *touched = km__malloc(T * nI * 2, sizeof(int32_t));
  if (!bufK || !bufG || !scratch || !gscr || !stamp || !touched) {
    free(bufK);
    free(bufG);
    free(scratch);
    free(gscr);
    free(stamp);
    free(touched);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory assembling the reduced system");
  }
  for (size_t i = 0; i < T * nI * 2; ++i)
    stamp[i] = -1;
#ifdef _OPENMP
#pragma omp parallel num_threads(nthreads)
#endif
  {
    int tid = 0;
#ifdef _OPENMP
    tid = omp_get_thread_num();
#endif
    double *Kt = bufK + (size_t)tid * nr * nr, *Gt = bufG + (size_t)tid * nr * nd;
    double *acc = scratch + (size_t)tid * nr, *g = gscr + (size_t)tid * nI * 3;
    int32_t *st = stamp + (size_t)tid * nI * 2, *tl = touched + (size_t)tid * nI * 2;
    int32_t *sg = st + nI, *tg = tl + nI;
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
    for (ptrdiff_t ii = 0; ii < (ptrdiff_t)n; ++ii) {
      size_t i = (size_t)ii;
      int nt = 0, ng = 0;
      const double *pi = p->Pn + 3 * i;
      for (int32_t q = cp[i]; q < cp[i + 1]; ++q) {
        size_t j = (size_t)ri[q];
        double l = lx[q];
        const double *pj = p->Pn + 3 * j;
        double p4[4] = {pj[0], pj[1], pj[2], 1};
        double e[3] = {pi[0] - pj[0], pi[1] - pj[1], pi[2] - pj[2]};
        for (int f = 0; f < p->ne; ++f) {
          size_t I0, Ii;
          double a0, a1, b0, b1;
          w_entry(p, j, f, &I0, &a0, &a1);
          w_entry(p, i, f, &Ii, &b0, &b1);
          for (int s2 = 0; s2 < 2; ++s2) {
            /* (L W)_i */
            size_t li = I0 + s2;
            spa_add(st, tl, &nt, acc, 4, li, (int32_t)i, l * (s2 ? a1 : a0), p4);
            if (j == i) continue;
            /* B_i: w_ij/2 (c_i + c_j) (p_i - p_j), the c_j part on j's isolines ... */
            spa_add(sg, tg, &ng, g, 3, li, (int32_t)i, 0.5 * l * (s2 ? a1 : a0), e);
            /* ... and the c_i part on i's */
            spa_add(sg, tg, &ng, g, 3, Ii + s2, (int32_t)i, 0.5 * l * (s2 ? b1 : b0), e);
          }
        }
      }
      /* K0 += W_i^T (-(LW)_i), G += W_i^T B_i */
      double p4[4] = {pi[0], pi[1], pi[2], 1};
      for (int f = 0; f < p->ne; ++f) {
        size_t Ii;
        double b0, b1;
        w_entry(p, i, f, &Ii, &b0, &b1);
        for (int s2 = 0; s2 < 2; ++s2) {
          double c = s2 ? b1 : b0;
          if (c == 0) continue;
          for (int k = 0; k < 4; ++k) {
            double wv = c * p4[k];
            size_t r = (Ii + s2) * 4 + k;
            for (int x = 0; x < nt; ++x) {
              const double *va = acc + (size_t)tl[x] * 4;
              double *kc = Kt + r + (size_t)tl[x] * 4 * nr;
              for (int m = 0; m < 4; ++m)
                kc[(size_t)m * nr] -= wv * va[m];
            }
            for (int x = 0; x < ng; ++x) {
              const double *gv = g + (size_t)tg[x] * 3;
              double *gc = Gt + r + (size_t)tg[x] * 3 * nr;
              for (int m = 0; m < 3; ++m)
                gc[(size_t)m * nr] += wv * gv[m];
            }
          }
        }
      }
    }
  }
  for (int t = 0; t < nthreads; ++t) {
    const double *Kt = bufK + (size_t)t * nr * nr, *Gt = bufG + (size_t)t * nr * nd;
    for (size_t i = 0; i < nr * nr; ++i)
      p->K0[i] += Kt[i];
    for (size_t i = 0; i < nr * nd; ++i)
      p->G[i] += Gt[i];
  }
  /* symmetric in exact arithmetic; make it so in floating point for dpotrf */
  for (size_t c = 0; c < nr; ++c)
    for (size_t r = c + 1; r < nr; ++r) {
      double v = 0.5 * (p->K0[r + c * nr] + p->K0[c + r * nr]);
      p->K0[r + c * nr] = p->K0[c + r * nr] = v;
    }
  free(bufK);
  free(bufG);
  free(scratch);
  free(gscr);
  free(stamp);
  free(touched);
  return KM_OK;
}

static void finish_trace(km_puppet *p) {
  p->trK0 = 0;
  for (size_t i = 0; i < p->nr; ++i)
    p->trK0 += p->K0[i + i * p->nr];
}

static bool eigs_progress(double fraction, const char *stage, void *user) {
  const km_progress *outer = user;
  return km__progress(outer, 0.05 + 0.65 * fraction, stage);
}

/* The propagation fields where the mesh's own Laplacian would give pieces' indicators instead:
 *
 * - A mesh split at its texture seams (coincident vertices that no face joins: a glTF
 *   exporter's output) gets the fields of the mesh welded there, each copy of a vertex taking
 *   its vertex's values: split into pieces, the Laplacian has one zero mode per piece and the
 *   fields are the pieces' indicators, so each piece moved on its own and the seams opened; with
 *   equal brackets and parameters, X = W R moves every copy exactly alike. The rest of the model
 *   keeps the file's vertices: the Laplacian and ARAP terms over the split faces sum to the
 *   welded mesh's (a seam edge's two one-sided cotangents are the welded edge's), the crossed
 *   triangles are faces.
 * - A body with small separate pieces (issue 11: a game character's eyes, teeth or buckles, a
 *   scan's loose bits, each at most a quarter of the largest piece's vertices) gets the fields
 *   of its largest piece alone, and a vertex of another piece takes the values of the body
 *   vertex it follows (km__mesh_body: the one nearest to it at rest, or for a piece that does
 *   not wrap the body the one nearest to the piece, find_held), so it moves as the body there
 *   moves: an eye with the head. Computed over the whole mesh, each loose piece took one of
 *   the fields for its own indicator and did not follow the body: armadillo_1k with a 12-vertex
 *   ball beside its head (0.09 m from the nearest head vertices), driven by precog_Seq1_1, left
 *   the ball hanging in the air 0.17-0.19 m from them, and the body lost a field (0.5-1.6 % of
 *   the diagonal off its animation alone, longest edge 2.03x against 1.96x); now the ball keeps
 *   0.089-0.092 m, the body within 0.1 % (test_puppetry's loose-piece test). Pieces of
 *   comparable size (two bodies) keep their own fields, as before: each needs its own handles
 *   (km__mesh_body says which is which).
 *
 * *done false: neither applies, the caller solves on the mesh itself. */
static km_status fields_welded(const km_mesh *rest, int k, const km_eigs_options *eo, double *evals,
                               double *evecs, bool *done, km_error *err) {
  size_t n = rest->n_vertices;
  *done = false;
  km__weld wd;
  km__body bd = {0};
  bool glue = false;
  km_status s = km__mesh_weld(rest, &wd, err);
  const km_mesh *w = wd.to_w ? &wd.w : rest; /* the welded mesh, or the file's */
  if (s == KM_OK) s = km__mesh_body(w, &bd, &glue, err);
  km_sparse *L = NULL, *M = NULL;
  double *ev = NULL;
  if (s != KM_OK || (!glue && !wd.to_w)) goto done;
  const km_mesh *solve = glue ? &bd.body : w;
  size_t ns = solve->n_vertices;
  if (!(ev = km__malloc(ns * (size_t)k, sizeof *ev))) {
    s = km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
    goto done;
  }
  if (!(s = km_cotmatrix(solve, &L, err)) &&
      !(s = km_massmatrix(solve, KM_MASS_VORONOI, &M, err)) &&
      !(s = km_eigs(L, M, k, eo, evals, ev, err))) {
    for (size_t v = 0; v < n; ++v) {
      size_t u = wd.to_w ? (size_t)wd.to_w[v] : v;
      /* a vertex in no face: any values (find_lone puts it back at rest) */
      int32_t su = glue ? bd.to_body[u] : (int32_t)u;
      for (int f = 0; f < k; ++f)
        evecs[(size_t)f * n + v] = su >= 0 ? ev[(size_t)f * ns + (size_t)su] : 0;
    }
    *done = true;
  }
done:
  km_sparse_free(&L);
  km_sparse_free(&M);
  km__body_free(&bd);
  km__weld_free(&wd);
  free(ev);
  return s;
}

km_status km_puppet_precompute(const km_mesh *rest, const km_puppet_options *opt, km_puppet **out,
                               km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "puppet: out is NULL");
  *out = NULL;
  km_puppet_options o;
  resolve_options(opt, &o);
  km_status s = check_options(&o, err);
  if (s) return s;
  if ((s = check_mesh(rest, err))) return s;
  if (rest->n_vertices < (size_t)o.fields + 2)
    return km__fail(err, KM_ERR_INVALID, "puppet: %zu vertices cannot carry %d fields",
                    rest->n_vertices, o.fields);
  km_puppet *p = calloc(1, sizeof *p);
  if (!p) return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  km_sparse *L = NULL, *M = NULL;
  double *evecs = NULL, *evals = NULL, *mass = NULL, *delta0 = NULL, *cm = NULL;
  if ((s = alloc_model(p, rest, &o, err))) goto fail;
  if (!km__progress(&o.progress, 0.0, "laplacian")) goto cancel;
  if ((s = km_cotmatrix(rest, &L, err)) || (s = km_massmatrix(rest, KM_MASS_VORONOI, &M, err)))
    goto fail;
  size_t n = p->n;
  int k = o.fields + 1;
  evecs = km__malloc(n * (size_t)k, sizeof(double));
  evals = km__malloc((size_t)k, sizeof(double));
  mass = km__malloc(n, sizeof(double));
  delta0 = km__malloc(n * 3, sizeof(double));
  cm = km__malloc(n * 3, sizeof(double));
  if (!evecs || !evals || !mass || !delta0 || !cm) {
    s = km__fail(err, KM_ERR_NOMEM, "puppet: out of memory for %d eigenvectors of %zu", k, n);
    goto fail;
  }
  if (!km__progress(&o.progress, 0.05, "eigenvectors")) goto cancel;
  km_eigs_options eo = {0};
  if (o.progress.fn) { /* eigs reports 0..1 of its own: mapped into this call's 0.05..0.7 */
    eo.progress.fn = eigs_progress;
    eo.progress.user = &o.progress;
  }
  bool welded = false;
  if (!(s = fields_welded(rest, k, &eo, evals, evecs, &welded, err)) && !welded)
    s = km_eigs(L, M, k, &eo, evals, evecs, err);
  if (s) {
    km__wrap(err, s, "puppet: propagation fields");
    goto fail;
  }
  if (!km__progress(&o.progress, 0.7, "isolines")) goto cancel;
  sparse_diag(M, mass);
  /* eq. 2-3 with the M-inner product: the fields are M-orthonormal, so xi = <X, e_i>_M are
   * the coordinates' spectral coefficients (the plain dot product would weight vertices by
   * sampling density instead of area). Over the shape's vertices (km__shape_vertices): a
   * loose piece's (a ground quad 4 m wide at armadillo_1k's feet, its area and its distance)
   * changed the weights and the body's deformation (longest edge on a walk 1.72x -> 1.77x). */
  bool *shape = km__malloc(n, sizeof *shape);
  if (!shape) {
    s = km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
    goto fail;
  }
  if ((s = km__shape_vertices(rest, shape, err)) != KM_OK) {
    free(shape);
    goto fail;
  }
  double wsum = 0;
  for (int f = 0; f < o.fields; ++f) {
    const double *e = evecs + (size_t)(f + 1) * n;
    double xi[3] = {0, 0, 0};
    for (size_t v = 0; v < n; ++v)
      for (int c = 0; c < 3 && shape[v]; ++c)
        xi[c] += mass[v] * p->Pn[v * 3 + c] * e[v];
    p->wfield[f] = sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
    if (!isfinite(p->wfield[f])) p->wfield[f] = 0;
    wsum += p->wfield[f];
  }
  free(shape);
  for (int f = 0; f < o.fields; ++f)
    p->wfield[f] = wsum > 0 ? p->wfield[f] / wsum : 1.0 / o.fields;
  for (size_t i = 0; i < n * (size_t)k; ++i)
    if (!isfinite(evecs[i])) {
      s = km__fail(err, KM_ERR_DEGENERATE_MESH, "puppet: eigenvectors are not finite");
      goto fail;
    }
  if ((s = place_isolines(p, evecs, err))) goto fail;
  if ((s = select_crossed(p, rest, evecs, err))) goto fail;
  if ((s = finish_model(p, err))) goto fail;
  if (!km__progress(&o.progress, 0.8, "reduced system")) goto cancel;
  /* delta0 = L Pn (rest Laplacian coordinates, normalised units) */
  for (size_t v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c)
      cm[v + c * n] = p->Pn[v * 3 + c];
  km_sparse_mul(L, 3, cm, delta0 /* column-major, transposed below */);
  for (size_t v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c)
      cm[v * 3 + c] = delta0[v + c * n];
  if (o.energy == KM_PUPPET_ENERGY_ARAP)
    s = assemble_reduced_arap(p, L, err);
  else
    s = assemble_reduced(p, L, cm, err);
  if (s) goto fail;
  finish_trace(p);
  if (!km__progress(&o.progress, 1.0, "done")) goto cancel;
  km_sparse_free(&L);
  km_sparse_free(&M);
  free(evecs);
  free(evals);
  free(mass);
  free(delta0);
  free(cm);
  if ((s = find_lone(p, rest, err)) || (s = find_held(p, rest, err))) {
    km_puppet_free(&p);
    return s;
  }
  *out = p;
  return KM_OK;
cancel:
  s = km__fail(err, KM_ERR_CANCELLED, "puppet: precompute cancelled");
fail:
  km_sparse_free(&L);
  km_sparse_free(&M);
  free(evecs);
  free(evals);
  free(mass);
  free(delta0);
  free(cm);
  km_puppet_free(&p);
  return s;
}

/* ------------------------------------------------------------------ cache */

typedef struct {
  unsigned char *buf;
  size_t size, cap;
} wbuf;

static bool wb_put(wbuf *w, const void *data, size_t size) {
  /* 8-byte alignment for every array keeps the layout simple to validate */
  size_t pad = (8 - size % 8) % 8;
  if (w->size + size + pad > w->cap) return false;
  if (size) memcpy(w->buf + w->size, data, size);
  memset(w->buf + w->size + size, 0, pad);
  w->size += size + pad;
  return true;
}

static size_t pad8(size_t x) { return (x + 7) / 8 * 8; }

static size_t payload_size(const km_puppet *p) {
  size_t n = p->n, ne = p->ne;
  return 4 * 8 + pad8(ne * 8) + pad8(p->n_isolines * 8) + pad8(n * ne) + pad8(n * ne * 8) + 8 +
         pad8(p->ntri * 12) + pad8(p->ntri * 4) + pad8(p->nr * p->nr * 8) + pad8(p->nr * p->nd * 8);
}

km_status km_puppet_save(const km_puppet *p, const char *path, km_error *err) {
  if (!p || !path) return km__fail(err, KM_ERR_INVALID, "puppet save: NULL argument");
  size_t psize = payload_size(p), total = KM_PUPPET_HEADER + psize + 8;
  wbuf w = {km__malloc(total, 1), 0, total};
  if (!w.buf) return km__fail(err, KM_ERR_NOMEM, "puppet save: out of memory (%zu bytes)", total);
  unsigned char hdr[KM_PUPPET_HEADER];
  memset(hdr, 0, sizeof hdr);
  memcpy(hdr, KM_PUPPET_MAGIC, 8);
  uint32_t u32[2] = {KM_PUPPET_FORMAT, KM_PUPPET_ENDIAN};
  memcpy(hdr + 8, u32, 8);
  uint64_t sizes[2] = {p->n, p->nf};
  memcpy(hdr + 16, sizes, 16);
  int32_t params[4] = {p->ne, p->niso, p->ncross, (int32_t)p->energy};
  memcpy(hdr + 32, params, 16);
  memcpy(hdr + 48, &p->mesh_hash, 8);
  uint64_t ps = psize;
  memcpy(hdr + 56, &ps, 8);
  size_t n = p->n, ne = p->ne;
  uint64_t ntri = p->ntri;
  double geo[4] = {p->center[0], p->center[1], p->center[2], p->scale};
  bool ok = wb_put(&w, hdr, sizeof hdr) && wb_put(&w, geo, sizeof geo) &&
            wb_put(&w, p->wfield, ne * 8) && wb_put(&w, p->iso, p->n_isolines * 8) &&
            wb_put(&w, p->bracket, n * ne) && wb_put(&w, p->tpar, n * ne * 8) &&
            wb_put(&w, &ntri, 8) && wb_put(&w, p->tri_v, p->ntri * 12) &&
            wb_put(&w, p->tri_iso, p->ntri * 4) && wb_put(&w, p->K0, p->nr * p->nr * 8) &&
            wb_put(&w, p->G, p->nr * p->nd * 8);
  uint64_t sum = hash_words(KM__FNV_SEED, w.buf, w.size);
  ok = ok && wb_put(&w, &sum, 8) && w.size == total;
  if (!ok) {
    free(w.buf);
    return km__fail(err, KM_ERR_INVALID, "puppet save: internal size mismatch");
  }
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s) {
    free(w.buf);
    return s;
  }
  if (fwrite(w.buf, 1, w.size, af.f) != w.size) {
    km__atomic_abort(&af);
    free(w.buf);
    return km__fail(err, KM_ERR_IO, "%s: write failed", path);
  }
  free(w.buf);
  return km__atomic_commit(&af, err);
}

typedef struct {
  const unsigned char *buf;
  size_t size, pos;
} rbuf;

static bool rb_get(rbuf *r, void *dst, size_t size) {
  size_t pad = (8 - size % 8) % 8;
  if (size + pad > r->size - r->pos) return false;
  if (size) memcpy(dst, r->buf + r->pos, size);
  r->pos += size + pad;
  return true;
}

km_status km_puppet_cache_options(const char *path, km_puppet_options *opt, km_error *err) {
  if (!path || !opt) return km__fail(err, KM_ERR_INVALID, "puppet cache options: NULL argument");
  FILE *f = fopen(path, "rb");
  if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  unsigned char b[KM_PUPPET_HEADER];
  size_t got = fread(b, 1, sizeof b, f);
  fclose(f);
  if (got < sizeof b)
    return km__fail(err, KM_ERR_STALE, "%s: truncated puppet cache (%zu bytes, a header is %u)",
                    path, got, KM_PUPPET_HEADER);
  uint32_t u32[2];
  memcpy(u32, b + 8, 8);
  if (memcmp(b, KM_PUPPET_MAGIC, 8) != 0 || u32[0] != KM_PUPPET_FORMAT ||
      u32[1] != KM_PUPPET_ENDIAN)
    return km__fail(err, KM_ERR_STALE, "%s: not a puppet cache of format %u", path,
                    KM_PUPPET_FORMAT);
  int32_t params[4];
  memcpy(params, b + 32, 16);
  if (params[3] != KM_PUPPET_ENERGY_ARAP && params[3] != KM_PUPPET_ENERGY_LAPLACIAN)
    return km__fail(err, KM_ERR_STALE, "%s: unknown energy %d in the cache header", path,
                    params[3]);
  opt->fields = params[0];
  opt->isolines = params[1];
  opt->crossed_per_isoline = params[2];
  opt->energy = (km_puppet_energy)params[3];
  return KM_OK;
}

km_status km_puppet_load(const char *path, const km_mesh *rest, const km_puppet_options *opt,
                         km_puppet **out, km_error *err) {
  if (!out || !path) return km__fail(err, KM_ERR_INVALID, "puppet load: NULL argument");
  *out = NULL;
  km_puppet_options o;
  resolve_options(opt, &o);
  km_status s = check_options(&o, err);
  if (s) return s;
  if ((s = check_mesh(rest, err))) return s;
  char *data = NULL;
  size_t size = 0;
  if ((s = km__read_file(path, &data, &size, err))) return s;
  const unsigned char *b = (const unsigned char *)data;
  km_puppet *p = NULL;
#define STALE(...)                                                                                 \
  do {                                                                                             \
    s = km__fail(err, KM_ERR_STALE, __VA_ARGS__);                                                  \
    goto done;                                                                                     \
  } while (0)
  if (size < KM_PUPPET_HEADER + 8)
    STALE("%s: truncated puppet cache (%zu bytes, a header alone is %u)", path, size,
          KM_PUPPET_HEADER + 8);
  if (memcmp(b, KM_PUPPET_MAGIC, 8) != 0)
    STALE("%s: not a kinemesh puppet cache (bad magic at byte 0)", path);
  uint32_t u32[2];
  memcpy(u32, b + 8, 8);
  if (u32[0] != KM_PUPPET_FORMAT)
    STALE("%s: puppet cache format %u, this build reads format %u", path, u32[0], KM_PUPPET_FORMAT);
  if (u32[1] != KM_PUPPET_ENDIAN) STALE("%s: puppet cache written on another byte order", path);
  uint64_t psize;
  memcpy(&psize, b + 56, 8);
  if (psize > size || size != KM_PUPPET_HEADER + psize + 8)
    STALE("%s: truncated or padded puppet cache (%zu bytes, header announces %llu)", path, size,
          (unsigned long long)(KM_PUPPET_HEADER + (psize > size ? 0 : psize) + 8));
  uint64_t sum;
  memcpy(&sum, b + size - 8, 8);
  if (hash_words(KM__FNV_SEED, b, size - 8) != sum)
    STALE("%s: puppet cache checksum mismatch (corrupted)", path);
  uint64_t sizes[2];
  int32_t params[4];
  uint64_t mh;
  memcpy(sizes, b + 16, 16);
  memcpy(params, b + 32, 16);
  memcpy(&mh, b + 48, 8);
  if (params[0] != o.fields || params[1] != o.isolines || params[2] != o.crossed_per_isoline ||
      params[3] != (int32_t)o.energy)
    STALE("%s: puppet cache built with fields=%d isolines=%d crossed_per_isoline=%d energy=%d, "
          "wanted %d/%d/%d/%d",
          path, params[0], params[1], params[2], params[3], o.fields, o.isolines,
          o.crossed_per_isoline, (int)o.energy);
  if (sizes[0] != rest->n_vertices || sizes[1] != rest->n_faces || mh != mesh_hash(rest))
    STALE("%s: puppet cache is for another mesh (%llu vertices, %llu faces, or different "
          "positions)",
          path, (unsigned long long)sizes[0], (unsigned long long)sizes[1]);
  p = calloc(1, sizeof *p);
  if (!p) {
    s = km__fail(err, KM_ERR_NOMEM, "puppet load: out of memory");
    goto done;
  }
  if ((s = alloc_model(p, rest, &o, err))) goto done;
  rbuf r = {b, size - 8, KM_PUPPET_HEADER};
  size_t n = p->n, ne = p->ne;
  double geo[4];
  uint64_t ntri = 0;
  if (!rb_get(&r, geo, sizeof geo) || !rb_get(&r, p->wfield, ne * 8) ||
      !rb_get(&r, p->iso, p->n_isolines * 8) || !rb_get(&r, p->bracket, n * ne) ||
      !rb_get(&r, p->tpar, n * ne * 8) || !rb_get(&r, &ntri, 8))
    STALE("%s: truncated puppet cache payload", path);
  for (int c = 0; c < 3; ++c)
    if (geo[c] != p->center[c]) STALE("%s: puppet cache normalisation differs", path);
  if (geo[3] != p->scale) STALE("%s: puppet cache normalisation differs", path);
  if (ntri > (r.size - r.pos) / 16)
    STALE("%s: puppet cache announces %llu crossed triangles, more than its size allows", path,
          (unsigned long long)ntri);
  p->ntri = (size_t)ntri;
  p->tri_v = km__malloc(p->ntri ? p->ntri * 3 : 3, sizeof(int32_t));
  p->tri_iso = km__malloc(p->ntri ? p->ntri : 1, sizeof(int32_t));
  if (!p->tri_v || !p->tri_iso) {
    s = km__fail(err, KM_ERR_NOMEM, "puppet load: out of memory");
    goto done;
  }
  if (!rb_get(&r, p->tri_v, p->ntri * 12) || !rb_get(&r, p->tri_iso, p->ntri * 4) ||
      !rb_get(&r, p->K0, p->nr * p->nr * 8) || !rb_get(&r, p->G, p->nr * p->nd * 8) ||
      r.pos != r.size)
    STALE("%s: puppet cache payload size does not match its header", path);
  /* never trusted: the checksum guards against accidents, these against a forged file */
  for (size_t i = 0; i < n * ne; ++i)
    if (p->bracket[i] > p->niso - 2 || !(p->tpar[i] >= 0 && p->tpar[i] <= 1))
      STALE("%s: puppet cache has an invalid interpolation entry %zu", path, i);
  for (int f = 0; f < p->ne; ++f)
    if (!(p->wfield[f] >= 0 && p->wfield[f] <= 1))
      STALE("%s: puppet cache has an invalid field weight", path);
  for (size_t t = 0; t < p->ntri; ++t) {
    if (p->tri_iso[t] < 0 || (size_t)p->tri_iso[t] >= p->n_isolines ||
        (t && p->tri_iso[t] < p->tri_iso[t - 1]))
      STALE("%s: puppet cache crossed triangle %zu has a bad isoline", path, t);
    for (int k = 0; k < 3; ++k)
      if (p->tri_v[t * 3 + k] < 0 || (size_t)p->tri_v[t * 3 + k] >= n)
        STALE("%s: puppet cache crossed triangle %zu has a bad vertex", path, t);
  }
  for (size_t i = 0; i < p->nr * p->nr; ++i)
    if (!isfinite(p->K0[i])) STALE("%s: puppet cache has non-finite values", path);
  for (size_t i = 0; i < p->nr * p->nd; ++i)
    if (!isfinite(p->G[i])) STALE("%s: puppet cache has non-finite values", path);
  if ((s = finish_model(p, err))) goto done;
  finish_trace(p);
  if ((s = find_lone(p, rest, err)) || (s = find_held(p, rest, err))) goto done;
  *out = p;
  p = NULL;
  s = KM_OK;
#undef STALE
done:
  km_puppet_free(&p);
  free(data);
  return s;
}

/* ------------------------------------------------------------------ handles */

/* K += w_c^2 W_Phi^T W_Phi */
static void add_handle_terms(const km_puppet *p, double *K) {
  size_t nr = p->nr, nhv = p->n_hv;
  const int32_t *hv = p->h_v;
  double wc2 = p->wc2;
  for (size_t i = 0; i < nhv; ++i) {
    size_t v = (size_t)hv[i];
    const double *pv = p->Pn + 3 * v;
    double p4[4] = {pv[0], pv[1], pv[2], 1};
    size_t idx[256]; /* 2 isolines x 4 coefficients x at most 32 fields */
    double val[256];
    int m = 0;
    for (int f = 0; f < p->ne; ++f) {
      size_t I0;
      double a0, a1;
      w_entry(p, v, f, &I0, &a0, &a1);
      for (int s = 0; s < 2; ++s)
        for (int k = 0; k < 4; ++k) {
          idx[m] = (I0 + s) * 4 + k;
          val[m++] = (s ? a1 : a0) * p4[k];
        }
    }
    for (int a = 0; a < m; ++a)
      for (int b2 = 0; b2 < m; ++b2)
        K[idx[a] + idx[b2] * nr] += wc2 * val[a] * val[b2];
  }
}

/* The rigid-handle tables (see seg_off in km_puppet) for the handle set in h_off, h_v,
 * hw_*: segments and their moments, and each handle's pseudo-inverse of sum p4 p4^T (LAPACK
 * dsyev; eigenvalues below 1e-12 of the largest are dropped, so a ring, a line or a single
 * vertex, whose G_h is not unique, gets one that reproduces its targets). false: out of
 * memory. */
static bool rigid_moments(km_puppet *p) {
  size_t nI = p->n_isolines, nh = p->n_handles, nhv = p->n_hv;
  int32_t *hid = km__malloc(nhv ? nhv : 1, sizeof(int32_t));
  int32_t *seg_off = km__calloc(nI + 1, sizeof(int32_t));
  if (!hid || !seg_off) goto nomem;
  for (size_t h = 0; h < nh; ++h)
    for (int32_t i = p->h_off[h]; i < p->h_off[h + 1]; ++i)
      hid[i] = (int32_t)h;
  size_t nseg = 0;
  for (size_t li = 0; li < nI; ++li) {
    for (int32_t q = p->hw_off[li]; q < p->hw_off[li + 1]; ++q)
      nseg += q == p->hw_off[li] || hid[p->hw_i[q]] != hid[p->hw_i[q - 1]];
    seg_off[li + 1] = (int32_t)nseg;
  }
  int32_t *seg_h = km__malloc(nseg ? nseg : 1, sizeof(int32_t));
  int32_t *seg_q = km__malloc(nseg + 1, sizeof(int32_t));
  double *seg_m = km__calloc(nseg ? nseg * 16 : 1, sizeof(double));
  double *pinv = km__calloc(nh ? nh * 16 : 1, sizeof(double));
  double *G = km__malloc(nh ? nh * 12 : 1, sizeof(double));
  unsigned char *aff = km__malloc(nh ? nh : 1, 1);
  if (!seg_h || !seg_q || !seg_m || !pinv || !G || !aff) {
    free(seg_h);
    free(seg_q);
    free(seg_m);
    free(pinv);
    free(G);
    free(aff);
    goto nomem;
  }
  size_t sg = 0;
  for (size_t li = 0; li < nI; ++li)
    for (int32_t q = p->hw_off[li]; q < p->hw_off[li + 1]; ++q) {
      int32_t i = p->hw_i[q];
      if (q == p->hw_off[li] || hid[i] != hid[p->hw_i[q - 1]]) {
        seg_h[sg] = hid[i];
        seg_q[sg++] = q;
      }
      const double *pv = p->Pn + 3 * (size_t)p->h_v[i];
      double p4[4] = {pv[0], pv[1], pv[2], 1}, *m = seg_m + 16 * (sg - 1);
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
          m[4 * a + b] += p->hw_w[q] * p4[a] * p4[b];
    }
  seg_q[nseg] = nI ? p->hw_off[nI] : 0;
  for (size_t h = 0; h < nh; ++h) {
    double A[16] = {0}, w[4];
    for (int32_t i = p->h_off[h]; i < p->h_off[h + 1]; ++i) {
      const double *pv = p->Pn + 3 * (size_t)p->h_v[i];
      double p4[4] = {pv[0], pv[1], pv[2], 1};
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
          A[4 * a + b] += p4[a] * p4[b];
    }
    /* an empty handle, or dsyev failing, leaves pinv 0: G_h = 0, which the per-frame check
     * accepts only for zero residuals (the sum is then 0 either way) */
    if (p->h_off[h + 1] == p->h_off[h] || km__syev(4, A, w) != 0) continue;
    for (int k = 0; k < 4; ++k) {
      if (!(w[k] > 1e-12 * w[3])) continue;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
          pinv[16 * h + 4 * a + b] += A[4 * a + k] * A[4 * b + k] / w[k];
    }
  }
  free(hid);
  free(p->seg_off);
  free(p->seg_h);
  free(p->seg_q);
  free(p->seg_m);
  free(p->h_pinv);
  free(p->h_G);
  free(p->h_affine);
  p->seg_off = seg_off;
  p->seg_h = seg_h;
  p->seg_q = seg_q;
  p->seg_m = seg_m;
  p->h_pinv = pinv;
  p->h_G = G;
  p->h_affine = aff;
  return true;
nomem:
  free(hid);
  free(seg_off);
  return false;
}

km_status km_puppet_set_handles(km_puppet *p, size_t n_handles, const int32_t *handle_offsets,
                                const int32_t *handle_vertices, km_error *err) {
  if (!p) return km__fail(err, KM_ERR_INVALID, "puppet: NULL model");
  if (n_handles && !handle_offsets)
    return km__fail(err, KM_ERR_INVALID, "puppet: handle_offsets is NULL");
  if (n_handles > INT32_MAX) return km__fail(err, KM_ERR_INVALID, "puppet: too many handles");
  size_t nhv = 0;
  if (n_handles) {
    if (handle_offsets[0] != 0)
      return km__fail(err, KM_ERR_INVALID, "puppet: handle_offsets[0] must be 0");
    for (size_t h = 0; h < n_handles; ++h)
      if (handle_offsets[h + 1] < handle_offsets[h])
        return km__fail(err, KM_ERR_INVALID, "puppet: handle_offsets decreases at handle %zu", h);
    nhv = (size_t)handle_offsets[n_handles];
    if (nhv > p->n)
      return km__fail(err, KM_ERR_INVALID, "puppet: %zu handle vertices for %zu vertices", nhv,
                      p->n);
    if (nhv && !handle_vertices)
      return km__fail(err, KM_ERR_INVALID, "puppet: handle_vertices is NULL");
  }
  unsigned char *seen = km__calloc(p->n, 1);
  int32_t *off = km__malloc(n_handles + 1, sizeof(int32_t));
  int32_t *hv = km__malloc(nhv ? nhv : 1, sizeof(int32_t));
  if (!seen || !off || !hv) {
    free(seen);
    free(off);
    free(hv);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  }
  for (size_t i = 0; i < nhv; ++i) {
    int32_t v = handle_vertices[i];
    if (v < 0 || (size_t)v >= p->n || seen[v]) {
      free(seen);
      free(off);
      free(hv);
      return km__fail(err, KM_ERR_INVALID,
                      "puppet: handle vertex %zu is %d (out of range or repeated)", i, (int)v);
    }
    seen[v] = 1;
    hv[i] = v;
  }
  free(seen);
  off[0] = 0;
  for (size_t h = 0; h < n_handles; ++h)
    off[h + 1] = handle_offsets[h + 1];
  /* the pairs (handle vertex, weight) of W_Phi grouped by isoline: each vertex and field
   * adds one pair to its lower and one to its upper isoline */
  size_t nI = p->n_isolines, npair = 2 * nhv * (size_t)p->ne;
  int32_t *hw_off = km__calloc(nI + 1, sizeof(int32_t));
  int32_t *hw_i = km__malloc(npair ? npair : 1, sizeof(int32_t));
  double *hw_w = km__malloc(npair ? npair : 1, sizeof(double));
  double *hM = km__malloc(nhv ? nhv * 12 : 1, sizeof(double));
  if (!hw_off || !hw_i || !hw_w || !hM || npair > INT32_MAX) {
    free(hw_off);
    free(hw_i);
    free(hw_w);
    free(hM);
    free(off);
    free(hv);
    return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");
  }
  for (size_t i = 0; i < nhv; ++i)
    for (int f = 0; f < p->ne; ++f) {
      size_t I0;
      double a0, a1;
      w_entry(p, (size_t)hv[i], f, &I0, &a0, &a1);
      ++hw_off[I0 + 1];
      ++hw_off[I0 + 2];
    }
  for (size_t li = 0; li < nI; ++li)
    hw_off[li + 1] += hw_off[li];
  for (size_t i = 0; i < nhv; ++i)
    for (int f = 0; f < p->ne; ++f) {
      size_t I0;
      double a0, a1;
      w_entry(p, (size_t)hv[i], f, &I0, &a0, &a1);
      /* hw_off[li] is isoline li's fill cursor here, shifted back to its start below */
      int32_t k0 = hw_off[I0]++, k1 = hw_off[I0 + 1]++;
      hw_i[k0] = (int32_t)i;
      hw_w[k0] = a0;
      hw_i[k1] = (int32_t)i;
      hw_w[k1] = a1;
    }
  for (size_t li = nI; li > 0; --li)
    hw_off[li] = hw_off[li - 1];
  hw_off[0] = 0;
  free(p->hw_off);
  free(p->hw_i);
  free(p->hw_w);
  free(p->hM);
  p->hw_off = hw_off;
  p->hw_i = hw_i;
  p->hw_w = hw_w;
  p->hM = hM;
  free(p->h_off);
  free(p->h_v);
  p->h_off = off;
  p->h_v = hv;
  p->n_handles = n_handles;
  p->n_hv = nhv;
  p->have_handles = false;
  if (!rigid_moments(p)) return km__fail(err, KM_ERR_NOMEM, "puppet: out of memory");

  size_t nr = p->nr;
  double *K = p->K;
  memcpy(K, p->K0, nr * nr * sizeof(double));
  /* W_Phi^T W_Phi, and its trace for the relative handle weight */
  double trH = 0;
  for (size_t i = 0; i < nhv; ++i) {
    size_t v = (size_t)hv[i];
    const double *pv = p->Pn + 3 * v;
    double p4[4] = {pv[0], pv[1], pv[2], 1};
    for (int f = 0; f < p->ne; ++f) {
      size_t I0;
      double a0, a1;
      w_entry(p, v, f, &I0, &a0, &a1);
      trH += (a0 * a0 + a1 * a1) * (p4[0] * p4[0] + p4[1] * p4[1] + p4[2] * p4[2] + 1);
    }
  }
  p->wc2 = nhv ? p->handle_weight * p->handle_weight * (p->trK0 > 0 ? p->trK0 : 1) / trH : 0;
  add_handle_terms(p, K);
  double tr = 0;
  for (size_t i = 0; i < nr; ++i)
    tr += K[i + i * nr];
  /* the ridge is retried 100x larger if the factorisation meets round-off trouble */
  int info = 1;
  for (double ridge = KM_PUPPET_RIDGE; info != 0 && ridge < 1e-4; ridge *= 100) {
    if (ridge > KM_PUPPET_RIDGE) {
      memcpy(K, p->K0, nr * nr * sizeof(double));
      add_handle_terms(p, K);
    }
    p->mu = ridge * (tr > 0 ? tr / (double)nr : 1);
    for (size_t i = 0; i < nr; ++i)
      K[i + i * nr] += p->mu;
    info = km__potrf(nr, K);
  }
  if (info != 0)
    return km__fail(err, KM_ERR_NOT_POSDEF,
                    "puppet: reduced system not positive definite (dpotrf info %d)", (int)info);
  for (size_t c = 0; c < nr; ++c)
    for (size_t r = 0; r < nr; ++r)
      p->Kt[r + c * nr] = r >= c ? K[c + r * nr] : 0;
  memcpy(p->KinvG, p->G, nr * p->nd * sizeof(double));
  info = km__potrs(nr, p->nd, K, p->KinvG);
  if (info != 0)
    return km__fail(err, KM_ERR_NOT_POSDEF, "puppet: dpotrs failed (info %d)", (int)info);
  for (size_t i = 0; i < nr * p->nd; ++i)
    p->KinvGf[i] = (float)p->KinvG[i];
  p->have_handles = true;
  return KM_OK;
}

void km_puppet_reset(km_puppet *p) {
  if (!p) return;
  memset(p->dR, 0, p->nr * 3 * sizeof(double));
  for (size_t i = 0; i < p->n_isolines; ++i) {
    p->quat[i * 4] = 1;
    p->quat[i * 4 + 1] = p->quat[i * 4 + 2] = p->quat[i * 4 + 3] = 0;
  }
  p->last_iters = 0;
  p->last_change = 0;
}

/* ------------------------------------------------------------------ solve */

/* The per-frame kernels are compiled for AVX-512, AVX2+FMA and baseline x86-64 and picked
 * at load time (GCC/clang function multi-versioning), because the project builds for
 * baseline x86-64 (SSE2, no FMA) where the X = W R loop runs ~3x slower. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 12
#define KM__SIMD_CLONES                                                                            \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"),                     \
                 optimize("fp-contract=fast")))
#else
#define KM__SIMD_CLONES
#endif

/* X = W R runs on one thread below this many vertices. Measured on the shared 2-core
 * machine (load ~3-4 from other jobs), 1M vertices: one thread 10.4 ms per frame; two
 * threads 26 ms wall for 12.3 ms of CPU, because the parallel region's join waits until the
 * other thread gets a core back. One thread already meets the 16 ms budget up to ~1.5M
 * vertices, so the threads are kept for meshes beyond that (set OMP_NUM_THREADS to taste). */
#define KM_PUPPET_PARALLEL 1500000

typedef float km__v16sf __attribute__((vector_size(64)));

/* Per-isoline tables of the current dR, 16 float lanes per isoline (rows c at lanes
 * 4c..4c+3, column j): A = w_f scale dT_fk and D = A_f,k+1 - A_fk, so a vertex's transform is
 * sum_f A[b_f] + t_f D[b_f]: one vector multiply-add per field. */
static void build_tables(km_puppet *p) {
  size_t nr = p->nr, nI = p->n_isolines;
  int niso = p->niso;
  for (size_t li = 0; li < nI; ++li) {
    double ws = p->wfield[li / (size_t)niso] * p->scale;
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < 4; ++j)
        p->A[li * 16 + c * 4 + j] = (float)(ws * p->dR[li * 4 + j + c * nr]);
  }
  for (size_t li = 0; li < nI; ++li)
    for (int q = 0; q < 12; ++q)
      p->D[li * 16 + q] =
          ((int)(li % (size_t)niso) == niso - 1) ? 0 : p->A[(li + 1) * 16 + q] - p->A[li * 16 + q];
}

/* Blended (world-scaled) displacement transform of a vertex with brackets b and parameters
 * t, rows at lanes 0-3, 4-7, 8-11. */
static inline void blend16(const km_puppet *p, const uint8_t *b, const float *t, km__v16sf *out) {
  const int ne = p->ne, niso = p->niso;
  const km__v16sf *A = (const km__v16sf *)p->A, *D = (const km__v16sf *)p->D;
  km__v16sf m = {0};
  for (int f = 0; f < ne; ++f) {
    size_t li = (size_t)f * niso + b[f];
    m += A[li] + t[f] * D[li];
  }
  *out = m;
}

/* Normalised positions of the crossed triangles' vertices under R = I + dR. Float carries
 * only the displacement, as in eval_range (rotations come out to ~1e-7). */
KM__SIMD_CLONES
static void eval_crossed(const km_puppet *p) {
  double inv = 1.0 / p->scale;
  size_t ne = (size_t)p->ne;
  for (size_t i = 0; i < p->ncv; ++i) {
    km__v16sf m;
    blend16(p, p->cv_br + i * ne, p->cv_t + i * ne, &m);
    const float *pf = p->cv_pf + 3 * i;
    const double *pv = p->cv_pn + 3 * i;
    double *x = p->cv_x + 3 * i;
    x[0] = pv[0] + inv * (double)(m[0] * pf[0] + m[1] * pf[1] + m[2] * pf[2] + m[3]);
    x[1] = pv[1] + inv * (double)(m[4] * pf[0] + m[5] * pf[1] + m[6] * pf[2] + m[7]);
    x[2] = pv[2] + inv * (double)(m[8] * pf[0] + m[9] * pf[1] + m[10] * pf[2] + m[11]);
  }
}

/* Isoline rotations from the current dR: every sampled crossed triangle gives the rotation
 * of its orthonormal frame (edge, normal; exact for rigid motions, no SVD needed), and the
 * isoline takes their area-weighted quaternion mean (signs aligned to its previous
 * rotation). dRd receives rotation - identity in R_d's layout. */
static void update_rotations(km_puppet *p) {
  eval_crossed(p);
  size_t nd = p->nd;
  for (size_t li = 0; li < p->n_isolines; ++li) {
    double *qp = p->quat + 4 * li;
    double qs[4] = {0, 0, 0, 0};
    for (int32_t t = p->iso_off[li]; t < p->iso_off[li + 1]; ++t) {
      if (p->tri_a[t] <= 0) continue;
      const int32_t *lv = p->tri_lv + 3 * t;
      double F1[9];
      if (km__tri_frame(p->cv_x + 3 * lv[0], p->cv_x + 3 * lv[1], p->cv_x + 3 * lv[2], F1) <= 0)
        continue;
      const double *F0 = p->tri_F0 + 9 * t;
      double R[9], q[4];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          R[r * 3 + c] = F1[r] * F0[c] + F1[3 + r] * F0[3 + c] + F1[6 + r] * F0[6 + c];
      km__quat_from_rot3(R, q);
      double dot = q[0] * qp[0] + q[1] * qp[1] + q[2] * qp[2] + q[3] * qp[3];
      double w = dot < 0 ? -p->tri_a[t] : p->tri_a[t];
      for (int k = 0; k < 4; ++k)
        qs[k] += w * q[k];
    }
    double len = sqrt(qs[0] * qs[0] + qs[1] * qs[1] + qs[2] * qs[2] + qs[3] * qs[3]);
    if (len > 1e-300)
      for (int k = 0; k < 4; ++k)
        qp[k] = qs[k] / len;
    double R[9];
    km__rot3_from_quat(qp, R);
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < 3; ++j)
        p->dRd[li * 3 + j + c * nd] = R[c * 3 + j] - (c == j);
  }
}

/* X = (K)^-1 B for the 3 columns of B (nr x 3, column-major, in place) with the upper factor
 * U (K = U^T U). Hand-written rather than LAPACKE_dpotrs: the pthread OpenBLAS wakes its
 * worker threads for every call, and on a 2-core machine they then fight the OpenMP X = W R
 * loop (7 ms per frame instead of 1); these 320x320 substitutions take ~50 us in place. */
KM__SIMD_CLONES
static void chol_solve3(const double *U, const double *Ut, size_t nr, double *B) {
  for (int c = 0; c < 3; ++c) {
    double *y = B + (size_t)c * nr;
    for (size_t j = 0; j < nr; ++j) { /* U^T y = b, column j of U^T below the diagonal */
      const double *l = Ut + j * nr;
      double x = y[j] / l[j];
      y[j] = x;
      for (size_t i = j + 1; i < nr; ++i)
        y[i] -= x * l[i];
    }
    for (size_t j = nr; j-- > 0;) { /* U x = y, column j of U above the diagonal */
      const double *u = U + j * nr;
      double x = y[j] / u[j];
      y[j] = x;
      for (size_t i = 0; i < j; ++i)
        y[i] -= x * u[i];
    }
  }
}

/* out = base + KinvG * dRd (nr x nd times nd x 3). Register-blocked over 8 rows with the 3
 * right-hand sides as accumulators, so KinvG streams through once and `out` is written once
 * (an axpy loop re-reads and re-writes it 720 times: 3x slower). KinvG is read in float
 * (300 kB instead of 600 kB of L2 traffic per iteration; accumulation stays double): it only
 * multiplies the rotation update dRd, which is exactly 0 at rest, and its 6e-8 relative
 * rounding moves the rigid-motion test's result by < 1e-6 of the diagonal. */
typedef double km__v8df_u __attribute__((vector_size(64), aligned(8)));
typedef float km__v8sf_u __attribute__((vector_size(32), aligned(4)));
KM__SIMD_CLONES
static void apply_rotations(const float *KinvG, size_t nr, size_t nd, const double *dRd,
                            const double *base, double *out) {
  const double *s0 = dRd, *s1 = dRd + nd, *s2 = dRd + 2 * nd;
  size_t i0 = 0;
  for (; i0 + 8 <= nr; i0 += 8) {
    km__v8df_u a0 = {0}, a1 = {0}, a2 = {0};
    for (size_t d = 0; d < nd; ++d) {
      km__v8sf_u gf = *(const km__v8sf_u *)(KinvG + d * nr + i0);
      km__v8df_u g = __builtin_convertvector(gf, km__v8df_u);
      a0 += g * s0[d];
      a1 += g * s1[d];
      a2 += g * s2[d];
    }
    for (int k = 0; k < 8; ++k) {
      out[i0 + k] = base[i0 + k] + a0[k];
      out[nr + i0 + k] = base[nr + i0 + k] + a1[k];
      out[2 * nr + i0 + k] = base[2 * nr + i0 + k] + a2[k];
    }
  }
  for (; i0 < nr; ++i0) {
    double a[3] = {0, 0, 0};
    for (size_t d = 0; d < nd; ++d) {
      double g = KinvG[d * nr + i0];
      a[0] += g * s0[d];
      a[1] += g * s1[d];
      a[2] += g * s2[d];
    }
    for (int c = 0; c < 3; ++c)
      out[(size_t)c * nr + i0] = base[(size_t)c * nr + i0] + a[c];
  }
}

/* X = P + scale * W dR for vertices [v0, v1), in float on the pre-multiplied per-isoline
 * tables: the rest part stays exact in double and float only carries the displacement
 * (relative error ~1e-7 of the displacement; the rigid-motion test bounds it). One 16-lane
 * vector holds a blended 3x4 transform, so a field costs one load-multiply-add pair. */
KM__SIMD_CLONES
static void eval_range(const km_puppet *p, double *V, size_t v0, size_t v1) {
  const double *P = p->P;
  const double c0 = p->center[0], c1 = p->center[1], c2 = p->center[2], inv = 1 / p->scale;
  for (size_t v = v0; v < v1; ++v) {
    km__v16sf m;
    blend16(p, p->bracket + v * (size_t)p->ne, p->tparf + v * (size_t)p->ne, &m);
    /* normalised rest position from P itself: one memory stream less than a float copy */
    const float pf[3] = {(float)((P[3 * v] - c0) * inv), (float)((P[3 * v + 1] - c1) * inv),
                         (float)((P[3 * v + 2] - c2) * inv)};
    V[3 * v + 0] = P[3 * v + 0] + (double)(m[0] * pf[0] + m[1] * pf[1] + m[2] * pf[2] + m[3]);
    V[3 * v + 1] = P[3 * v + 1] + (double)(m[4] * pf[0] + m[5] * pf[1] + m[6] * pf[2] + m[7]);
    V[3 * v + 2] = P[3 * v + 2] + (double)(m[8] * pf[0] + m[9] * pf[1] + m[10] * pf[2] + m[11]);
  }
}

static void eval_full(km_puppet *p, double *V) {
  build_tables(p);
  size_t n = p->n;
#ifdef _OPENMP
#pragma omp parallel if (n > KM_PUPPET_PARALLEL)
  {
    size_t nt = (size_t)omp_get_num_threads(), id = (size_t)omp_get_thread_num();
    eval_range(p, V, n * id / nt, n * (id + 1) / nt);
  }
#else
  eval_range(p, V, 0, n);
#endif
}

/* b = w_c^2 W_Phi^T (C - P_Phi) into b (nr x 3, column-major), C the handle vertices'
 * targets (world units). Every vertex's residual r enters row block I through p4 r^T
 * (4 x 3) times its weight in isoline I, so the 12 products are made once per vertex and
 * each isoline sums its pairs in registers and writes its rows once, instead of scattering
 * 24 read-modify-writes per field and vertex (60k-vertex character, 4250 handle vertices,
 * perf samples on the shared 2-core machine under load: 0.50 -> 0.19 ms per frame). A rigid
 * handle (its targets an affine map of its rest vertices) adds its precomputed moments
 * instead (seg_off in km_puppet): the armadillo's rig, 6220 handle vertices, spent 0.21-0.24
 * ms of its 0.90-0.98 ms solve here before. */
KM__SIMD_CLONES
static void handle_rhs(km_puppet *p, const double *targets, double *b) {
  size_t nr = p->nr;
  double *M = p->hM;
  for (size_t h = 0; h < p->n_handles; ++h) {
    /* r_i, then G_h^T = pinv_h sum_i p4_i r_i^T (4 x 3), then every r_i checked against
     * G_h p4_i: a relative 1e-9 leaves the sum exact to that digit, and rigid targets,
     * made in double, meet it by six orders */
    double S[12] = {0}, rmax = 0, *G = p->h_G + 12 * h;
    for (int32_t i = p->h_off[h]; i < p->h_off[h + 1]; ++i) {
      const double *pv = p->Pn + 3 * (size_t)p->h_v[i];
      double p4[4] = {pv[0], pv[1], pv[2], 1}, *r = M + 12 * (size_t)i;
      for (int c = 0; c < 3; ++c) {
        r[c] = p->wc2 * ((targets[3 * (size_t)i + c] - p->center[c]) / p->scale - pv[c]);
        rmax = fmax(rmax, fabs(r[c]));
        for (int a = 0; a < 4; ++a)
          S[3 * a + c] += p4[a] * r[c];
      }
    }
    const double *P = p->h_pinv + 16 * h;
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c)
        G[3 * a + c] = P[4 * a] * S[c] + P[4 * a + 1] * S[3 + c] + P[4 * a + 2] * S[6 + c] +
                       P[4 * a + 3] * S[9 + c];
    bool affine = true;
    double tol = 1e-9 * rmax + 1e-12 * p->wc2; /* and 1e-12 of the model's unit size */
    for (int32_t i = p->h_off[h]; i < p->h_off[h + 1] && affine; ++i) {
      const double *pv = p->Pn + 3 * (size_t)p->h_v[i], *r = M + 12 * (size_t)i;
      for (int c = 0; c < 3; ++c)
        affine &= fabs(pv[0] * G[c] + pv[1] * G[3 + c] + pv[2] * G[6 + c] + G[9 + c] - r[c]) <= tol;
    }
    p->h_affine[h] = affine;
    if (affine) continue;
    for (int32_t i = p->h_off[h]; i < p->h_off[h + 1]; ++i) {
      const double *pv = p->Pn + 3 * (size_t)p->h_v[i];
      double p4[4] = {pv[0], pv[1], pv[2], 1}, *m = M + 12 * (size_t)i, r[3] = {m[0], m[1], m[2]};
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 4; ++k)
          m[4 * c + k] = p4[k] * r[c];
    }
  }
  for (size_t li = 0; li < p->n_isolines; ++li) {
    double acc[12] = {0};
    for (int32_t sg = p->seg_off[li]; sg < p->seg_off[li + 1]; ++sg) {
      int32_t h = p->seg_h[sg];
      if (p->h_affine[h]) {
        /* acc(c, k) += sum_j M_{li,h}(k, j) G_h^T(j, c) */
        const double *m = p->seg_m + 16 * (size_t)sg, *G = p->h_G + 12 * (size_t)h;
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 4; ++k)
            acc[4 * c + k] += m[4 * k] * G[c] + m[4 * k + 1] * G[3 + c] + m[4 * k + 2] * G[6 + c] +
                              m[4 * k + 3] * G[9 + c];
        continue;
      }
      for (int32_t q = p->seg_q[sg]; q < p->seg_q[sg + 1]; ++q) {
        const double *m = M + 12 * (size_t)p->hw_i[q];
        double w = p->hw_w[q];
        for (int k = 0; k < 12; ++k)
          acc[k] += w * m[k];
      }
    }
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 4; ++k)
        b[li * 4 + k + (size_t)c * nr] = acc[4 * c + k];
  }
}

km_status km_puppet_solve(km_puppet *p, const double *targets, double *V_out, km_error *err) {
  if (!p || !V_out) return km__fail(err, KM_ERR_INVALID, "puppet solve: NULL argument");
  if (!p->have_handles)
    return km__fail(err, KM_ERR_INVALID, "puppet solve: call km_puppet_set_handles first");
  if (p->n_hv && !targets) return km__fail(err, KM_ERR_INVALID, "puppet solve: targets is NULL");
  for (size_t i = 0; i < p->n_hv * 3; ++i)
    if (!isfinite(targets[i]))
      return km__fail(err, KM_ERR_INVALID,
                      "puppet solve: target of handle vertex %zu is not finite", i / 3);
  size_t nr = p->nr;
  /* b = w_c^2 W_Phi^T (C - P_Phi), then dR0 = K^-1 b: the rotation-free part of the solve */
  handle_rhs(p, targets, p->dR0);
  chol_solve3(p->K, p->Kt, nr, p->dR0);
  int it = 0;
  double change = 0;
  if (p->iterations == 0) memcpy(p->dR, p->dR0, nr * 3 * sizeof(double));
  for (; it < p->iterations; ++it) {
    build_tables(p);
    update_rotations(p);
    apply_rotations(p->KinvGf, nr, p->nd, p->dRd, p->dR0, p->dRnew);
    double num = 0, den = 0;
    for (size_t i = 0; i < nr * 3; ++i) {
      double d = p->dRnew[i] - p->dR[i];
      num += d * d;
      den += p->dRnew[i] * p->dRnew[i];
    }
    double *tmp = p->dR;
    p->dR = p->dRnew;
    p->dRnew = tmp;
    change = den > 0 ? sqrt(num / den) : 0;
    if (change < p->tolerance) {
      ++it;
      break;
    }
  }
  p->last_iters = it;
  p->last_change = change;
  eval_full(p, V_out);
  place_held(p, V_out);
  for (size_t k = 0; k < p->n_lone; ++k)
    memcpy(V_out + 3 * (size_t)p->lone[k], p->P + 3 * (size_t)p->lone[k], 3 * sizeof(double));
  return KM_OK;
}

void km_puppet_info_get(const km_puppet *p, km_puppet_info *out) {
  if (!out) return;
  memset(out, 0, sizeof *out);
  if (!p) return;
  out->vertices = p->n;
  out->fields = p->ne;
  out->isolines = p->niso;
  out->unknowns = p->nr;
  out->crossed_triangles = p->ntri;
  out->handles = p->n_handles;
  out->handle_vertices = p->n_hv;
  out->last_iterations = p->last_iters;
  out->last_change = p->last_change;
}
