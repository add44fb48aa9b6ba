/* Template registration to point clouds (Park & Lim 2014, after Allen, Curless & Popovic
 * 2003): similarity from features (km_similarity_fit), per-vertex affine registration,
 * skeletal motion by L-BFGS, surface refinement. */
#include "recon/recon.h"
#include "math/math.h"
#include "linalg/linalg.h"
#include "mesh/mesh.h" /* km__mesh_weld: a template split at its texture seams */

#include <float.h>
#include <lbfgs.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- small 3x3 helpers */

/* Nearest rotation by Gram-Schmidt on the rows: products of rotations drift off SO(3) in
 * floating point, and the constant-velocity prediction would amplify the drift. */
static void orthonormalize(double *R) {
  double *a = R, *b = R + 3, *c = R + 6;
  double l = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  if (!(l > 0)) {
    memset(R, 0, 9 * sizeof *R);
    R[0] = R[4] = R[8] = 1;
    return;
  }
  for (int k = 0; k < 3; ++k)
    a[k] /= l;
  double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  for (int k = 0; k < 3; ++k)
    b[k] -= d * a[k];
  l = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  if (!(l > 0)) {
    memset(R, 0, 9 * sizeof *R);
    R[0] = R[4] = R[8] = 1;
    return;
  }
  for (int k = 0; k < 3; ++k)
    b[k] /= l;
  km__cross3(a, b, c);
}

/* Right Jacobian of SO(3): exp(r + d) ~ exp(r) exp(Jr(r) d). */
static void right_jacobian(const double *r, double *J) {
  double th = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  double K[9] = {0, -r[2], r[1], r[2], 0, -r[0], -r[1], r[0], 0}, K2[9];
  km__m3_mul(K, K, K2);
  double a, b;
  if (th < 1e-5)
    a = 0.5 - th * th / 24, b = 1.0 / 6 - th * th / 120;
  else
    a = (1 - cos(th)) / (th * th), b = (th - sin(th)) / (th * th * th);
  for (int i = 0; i < 9; ++i)
    J[i] = (i % 4 == 0) - a * K[i] + b * K2[i];
}

/* ---------------------------------------------------------------- the reconstructor */

struct km_recon {
  km_recon_options o;
  size_t nv, nf, nj, ne;
  km_mesh tmpl;        /* template (copied) */
  int32_t *parents;    /* nj */
  double *tmpl_joints; /* nj*3 template rest joints */
  km_skin skin;        /* copied */
  char **names;
  int32_t *edges;      /* ne*2, i < j */
  int32_t *face_edges; /* nf*3: edge index of (v0,v1), (v1,v2), (v2,v0) */
  /* A template split at its texture seams (km__mesh_weld): the affine system has one unknown
   * per welded vertex, so every copy of a vertex takes the same transform and the seam stays
   * shut. ns: the system's vertices (nv when nothing is split); sv: nv, each vertex's system
   * vertex (NULL: itself); sv_first: ns, the lowest id of each system vertex's copies. */
  size_t ns;
  int32_t *sv, *sv_first;
  /* affine solver: 4 unknowns per vertex and coordinate, 3 right-hand sides sharing one
   * CHOLMOD factor of the 4#V x 4#V SPD matrix */
  km_sparse *M; /* upper triangle only (km__cholesky_options.stored = 1) */
  km_cholesky *L;
  double *blocks;     /* (nv + ne) * 16 accumulators: diagonal blocks then edge blocks */
  int64_t *block_pos; /* (nv + ne) * 16 positions in M->x (-1: lower triangle) */
  double *rhs;        /* 4nv*3 */
  double *sol;        /* 4nv*3 */
  /* registration state */
  bool have_base;
  double *base;                  /* nv*3 registered first frame (template for later frames) */
  double *base_joints;           /* nj*3 */
  double *Lrot, *Lprev, *Lprev2; /* nj*9 local rotations relative to base */
  double troot[3], tprev[3], tprev2[3];
  size_t frame;
  double *global;  /* nv*3 LBS-only surface */
  double *surface; /* nv*3 refined */
  double *joints;  /* nj*3 current joints */
  double *G;       /* nj*12 current joint transforms (world, from base) */
  double *work;    /* nv*3 scratch */
  km__surface *query;
  double err_hist[8];
  size_t n_hist;
  /* per-frame data (capacity grows) */
  size_t pcap;
  int32_t *ptri;
  double *pbary, *pdist, *pw, *pnormal, *ptsel;
  int32_t *sel;
  /* surface -> points term of the skeletal step: per vertex nearest point and weight */
  int32_t *vnear;
  double *vw, *vdist, *vn;
  double *vq;      /* nv*3: the affine stage's surface -> points targets */
  bool *part_lost; /* nj: the skin joints the last frame flagged unsupported */
  /* template landmarks with a name (pseudo-correspondences without given ones) */
  int32_t lm[KM_CHARACTER_LANDMARKS];
  size_t n_lm;
  km_recon_init init;
  size_t limbs_researched; /* joints turned by the search on later frames */
  /* two-sided error of the last frame: per vertex nearest point distance, the unsupported
   * vertices, vertex normals when cameras are given */
  double *sup_dist;
  int32_t *sup_idx, *sup_list;
  size_t n_sup;
  /* Vertices with no skin influence (km_autorig's ground plane): no body part, so no point
   * of the body explains them; each frame keeps them where the template has them and the
   * surface -> points error leaves them out. NULL when there are none. */
  bool *still;
  size_t n_still;
  bool *still_face; /* nf: faces of still vertices only, which no point lands on */
  double *sup_N;
};

/* The affine system's vertex of template vertex v (its welded vertex where the template is
 * split at its seams). */
#define SV(r, v) ((r)->sv ? (r)->sv[(v)] : (int32_t)(v))

static void opt_defaults(km_recon_options *o) {
  if (!o->coarse_points) o->coarse_points = 2000;
  if (o->knn <= 0) o->knn = 10;
  if (o->first_iterations <= 0) o->first_iterations = 12;
  if (o->refine_iterations <= 0) o->refine_iterations = 4;
  if (o->skeleton_iterations <= 0) o->skeleton_iterations = 6;
  if (o->w_data <= 0) o->w_data = 1;
  if (o->w_feature <= 0) o->w_feature = 10;
  if (o->w_smooth <= 0) o->w_smooth = 0.05;
  if (o->w_pose <= 0) o->w_pose = 3e-4;
  if (o->outlier_scale <= 0) o->outlier_scale = 3;
  if (o->filter_radius == 0) o->filter_radius = 2;
  if (o->filter_sigma <= 0) o->filter_sigma = 1;
  if (!(o->unsupported_distance > 0)) o->unsupported_distance = 0.03;
  if (!(o->unsupported_fraction > 0)) o->unsupported_fraction = 0.02;
  if (!o->cameras) o->n_cameras = 0;
}

static int cmp_edge(const void *a, const void *b) {
  const int32_t *x = a, *y = b;
  if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
  return (x[1] > y[1]) - (x[1] < y[1]);
}

static int64_t find_edge(const km_recon *r, int32_t i, int32_t j) {
  if (i > j) {
    int32_t t = i;
    i = j;
    j = t;
  }
  size_t lo = 0, hi = r->ne;
  while (lo < hi) {
    size_t m = (lo + hi) / 2;
    const int32_t *e = r->edges + 2 * m;
    if (e[0] < i || (e[0] == i && e[1] < j))
      lo = m + 1;
    else
      hi = m;
  }
  if (lo < r->ne && r->edges[2 * lo] == i && r->edges[2 * lo + 1] == j) return (int64_t)lo;
  return -1;
}

/* Builds the edge list and the CSC pattern (upper triangle, stype 1) of the block system. */
static km_status build_system(km_recon *r, km_error *err) {
  size_t nf = r->nf, nv = r->ns; /* the system's vertices: welded where the template is split */
  int32_t *e = km__malloc(nf * 3, 2 * sizeof *e);
  if (!e) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t a = SV(r, r->tmpl.F[3 * f + k]), b = SV(r, r->tmpl.F[3 * f + (k + 1) % 3]);
      e[6 * f + 2 * k] = a < b ? a : b;
      e[6 * f + 2 * k + 1] = a < b ? b : a;
    }
  qsort(e, nf * 3, 2 * sizeof *e, cmp_edge);
  size_t ne = 0;
  for (size_t i = 0; i < nf * 3; ++i) {
    if (e[2 * i] == e[2 * i + 1]) continue;
    if (ne && e[2 * ne - 2] == e[2 * i] && e[2 * ne - 1] == e[2 * i + 1]) continue;
    e[2 * ne] = e[2 * i], e[2 * ne + 1] = e[2 * i + 1];
    ++ne;
  }
  r->edges = e;
  r->ne = ne;
  r->face_edges = km__malloc(nf, 3 * sizeof *r->face_edges);
  if (!r->face_edges) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      r->face_edges[3 * f + k] =
          (int32_t)find_edge(r, SV(r, r->tmpl.F[3 * f + k]), SV(r, r->tmpl.F[3 * f + (k + 1) % 3]));
  /* column block j holds row blocks i <= j: edges (i, j) with i < j, then the diagonal */
  size_t *cnt = calloc(nv, sizeof *cnt);
  if (!cnt) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (size_t k = 0; k < ne; ++k)
    ++cnt[e[2 * k + 1]];
  size_t n = 4 * nv;
  size_t nnz = 16 * ne + 10 * nv;
  km_status s = km__sparse_alloc(n, n, nnz, &r->M, err);
  if (s) return s;
  r->blocks = km__malloc(nv + ne, 16 * sizeof(double));
  r->block_pos = km__malloc(nv + ne, 16 * sizeof(int64_t));
  size_t *colstart = km__malloc(nv + 1, sizeof *colstart);
  size_t *fill = calloc(nv, sizeof *fill);
  if (!r->M || !r->blocks || !r->block_pos || !colstart || !fill) {
    free(cnt);
    free(colstart);
    free(fill);
    return km__fail(err, KM_ERR_NOMEM, "affine system: out of memory (%zu unknowns)", n);
  }
  int32_t *Mp, *Mi;
  double *Mx;
  km__sparse_arrays(r->M, &Mp, &Mi, &Mx);
  /* Per column block j: (cnt[j] edge blocks) * 4 rows + diagonal block rows 0..cc */
  size_t pos = 0;
  for (size_t j = 0; j < nv; ++j) {
    colstart[j] = pos;
    for (int c = 0; c < 4; ++c)
      pos += 4 * cnt[j] + (size_t)c + 1;
  }
  colstart[nv] = pos;
  /* edges sorted by (i, j): for a fixed j, its i's come in ascending order as k increases */
  for (size_t k = 0; k < ne; ++k) {
    size_t i = (size_t)e[2 * k], j = (size_t)e[2 * k + 1];
    size_t slot = fill[j]++;
    for (int c = 0; c < 4; ++c) {
      size_t colbase = colstart[j];
      for (int cc2 = 0; cc2 < c; ++cc2)
        colbase += 4 * cnt[j] + (size_t)cc2 + 1;
      for (int rr = 0; rr < 4; ++rr) {
        size_t p = colbase + 4 * slot + (size_t)rr;
        Mi[p] = (int)(4 * i + (size_t)rr);
        r->block_pos[16 * (nv + k) + 4 * rr + c] = (int64_t)p;
      }
    }
  }
  for (size_t j = 0; j < nv; ++j) {
    size_t colbase = colstart[j];
    for (int c = 0; c < 4; ++c) {
      Mp[4 * j + (size_t)c] = (int)colbase;
      for (int rr = 0; rr < 4; ++rr) {
        if (rr <= c) {
          size_t p = colbase + 4 * cnt[j] + (size_t)rr;
          Mi[p] = (int)(4 * j + (size_t)rr);
          r->block_pos[16 * j + 4 * rr + c] = (int64_t)p;
        } else {
          r->block_pos[16 * j + 4 * rr + c] = -1;
        }
      }
      colbase += 4 * cnt[j] + (size_t)c + 1;
    }
  }
  Mp[n] = (int)pos;
  free(cnt);
  free(colstart);
  free(fill);
  memset(Mx, 0, pos * sizeof(double));
  for (size_t j = 0; j < nv; ++j)
    for (int c = 0; c < 4; ++c)
      Mx[r->block_pos[16 * j + 5 * c]] = 1;
  /* the columns are sorted without repeats, so block_pos stays valid */
  if ((s = km__sparse_compress(&r->M, err))) return s;
  /* CHOLMOD's own choice: supernodal LL' for large templates, simplicial LDL' for small */
  km__cholesky_options co = {.kind = KM__CHOLESKY_AUTO_LDL, .stored = 1};
  if ((s = km__cholesky_analyze_with(r->M, &co, &r->L, err))) return s;
  r->rhs = km__malloc(n, 3 * sizeof(double));
  r->sol = km__malloc(n, 3 * sizeof(double));
  if (!r->rhs || !r->sol) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  return KM_OK;
}

void km_recon_free(km_recon **rp) {
  if (!rp || !*rp) return;
  km_recon *r = *rp;
  km_mesh_free(&r->tmpl);
  free(r->parents);
  free(r->tmpl_joints);
  free(r->skin.joints);
  free(r->skin.weights);
  if (r->names)
    for (size_t j = 0; j < r->nj; ++j)
      free(r->names[j]);
  free(r->names);
  free(r->edges);
  free(r->face_edges);
  free(r->sv);
  free(r->sv_first);
  km_cholesky_free(&r->L);
  km_sparse_free(&r->M);
  free(r->blocks);
  free(r->block_pos);
  free(r->rhs);
  free(r->sol);
  free(r->base);
  free(r->base_joints);
  free(r->Lrot);
  free(r->Lprev);
  free(r->Lprev2);
  free(r->global);
  free(r->surface);
  free(r->joints);
  free(r->G);
  free(r->work);
  km__surface_free(&r->query);
  free(r->ptri);
  free(r->pbary);
  free(r->pdist);
  free(r->pw);
  free(r->pnormal);
  free(r->ptsel);
  free(r->sel);
  free(r->vnear);
  free(r->vw);
  free(r->vdist);
  free(r->vn);
  free(r->vq);
  free(r->part_lost);
  free(r->sup_dist);
  free(r->sup_idx);
  free(r->sup_list);
  free(r->still);
  free(r->still_face);
  free(r->sup_N);
  free(r);
  *rp = NULL;
}

/* A template split at its texture seams (a game character's glTF): the affine system is the
 * welded mesh's (one transform per welded vertex, smoothness over its edges, each welded
 * vertex's own surface term once), and every copy takes its first copy's skin (an exporter's
 * copies normally carry the same weights), so registration and skinning move the copies as
 * one and the seam stays shut. Split, each side followed its own points: a character split at
 * its waist opened there by 2.1 cm over 40 frames of gen capture. */
static km_status seams_find(km_recon *r, km_error *err) {
  r->ns = r->nv;
  km__weld wd;
  km_status s = km__mesh_weld(&r->tmpl, &wd, err);
  if (s != KM_OK || !wd.to_w) {
    if (s == KM_OK && !r->o.rig_joints)
      s = km_skeleton_from_weights(&r->tmpl, &r->skin, r->parents, r->nj, r->tmpl_joints, err);
    return s;
  }
  size_t nw = wd.w.n_vertices;
  r->ns = nw;
  r->sv = wd.to_w, wd.to_w = NULL;
  r->sv_first = wd.first, wd.first = NULL;
  for (size_t v = 0; v < r->nv; ++v) {
    size_t h = (size_t)r->sv_first[r->sv[v]];
    memcpy(r->skin.joints + 4 * v, r->skin.joints + 4 * h, 4 * sizeof(int32_t));
    memcpy(r->skin.weights + 4 * v, r->skin.weights + 4 * h, 4 * sizeof(double));
  }
  /* the joints from the welded mesh's weights: a seam's copies would count twice */
  if (!r->o.rig_joints) {
    km_skin ws = {.n_vertices = nw};
    ws.joints = km__malloc(nw, 4 * sizeof(int32_t));
    ws.weights = km__malloc(nw, 4 * sizeof(double));
    if (!ws.joints || !ws.weights)
      s = km__fail(err, KM_ERR_NOMEM, "km_recon_create: out of memory");
    for (size_t q = 0; s == KM_OK && q < nw; ++q) {
      memcpy(ws.joints + 4 * q, r->skin.joints + 4 * (size_t)r->sv_first[q], 4 * sizeof(int32_t));
      memcpy(ws.weights + 4 * q, r->skin.weights + 4 * (size_t)r->sv_first[q], 4 * sizeof(double));
    }
    if (s == KM_OK)
      s = km_skeleton_from_weights(&wd.w, &ws, r->parents, r->nj, r->tmpl_joints, err);
    free(ws.joints);
    free(ws.weights);
  }
  km__weld_free(&wd);
  return s;
}

km_status km_recon_create(const km_character *c, const km_recon_options *opt, km_recon **out,
                          km_error *err) {
  if (!c || !out) return km__fail(err, KM_ERR_INVALID, "km_recon_create: NULL argument");
  *out = NULL;
  const km_mesh *m = &c->mesh;
  if (!m->n_faces || m->n_vertices < 4)
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "km_recon_create: template needs faces");
  if (c->skin.n_vertices != m->n_vertices || !c->skin.joints || !c->skin.weights)
    return km__fail(err, KM_ERR_INVALID, "km_recon_create: skin has %zu vertices, mesh %zu",
                    c->skin.n_vertices, m->n_vertices);
  size_t nj = c->skeleton.n_joints;
  if (!nj || !c->skeleton.parents || !c->skeleton.rest)
    return km__fail(err, KM_ERR_INVALID, "km_recon_create: template has no skeleton");
  for (size_t j = 0; j < nj; ++j)
    if (c->skeleton.parents[j] >= (int32_t)j || (j == 0) != (c->skeleton.parents[j] < 0))
      return km__fail(err, KM_ERR_INVALID,
                      "km_recon_create: joint %zu: parent %d must precede it (one root, first)", j,
                      c->skeleton.parents[j]);
  for (size_t i = 0; i < 4 * m->n_vertices; ++i)
    if (c->skin.joints[i] >= (int32_t)nj)
      return km__fail(err, KM_ERR_INVALID, "km_recon_create: skin joint %d out of range",
                      c->skin.joints[i]);
  km_recon *r = calloc(1, sizeof *r);
  if (!r) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  r->o = opt ? *opt : (km_recon_options){0};
  opt_defaults(&r->o);
  km_status s = km_mesh_copy(m, &r->tmpl, err);
  if (s) {
    km_recon_free(&r);
    return s;
  }
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= m->n_vertices) {
      km_recon_free(&r);
      return km__fail(err, KM_ERR_INVALID, "km_recon_create: face index %d out of range", m->F[i]);
    }
  r->nv = m->n_vertices, r->nf = m->n_faces, r->nj = nj;
  size_t nv = r->nv;
  r->parents = km__malloc(nj, sizeof *r->parents);
  r->tmpl_joints = km__malloc(nj, 3 * sizeof(double));
  r->names = calloc(nj, sizeof *r->names);
  r->skin.n_vertices = nv;
  r->skin.joints = km__malloc(nv, 4 * sizeof(int32_t));
  r->skin.weights = km__malloc(nv, 4 * sizeof(double));
  r->base = km__malloc(nv, 3 * sizeof(double));
  r->base_joints = km__malloc(nj, 3 * sizeof(double));
  r->Lrot = km__malloc(nj, 9 * sizeof(double));
  r->Lprev = km__malloc(nj, 9 * sizeof(double));
  r->Lprev2 = km__malloc(nj, 9 * sizeof(double));
  r->global = km__malloc(nv, 3 * sizeof(double));
  r->surface = km__malloc(nv, 3 * sizeof(double));
  r->work = km__malloc(nv * 3 > nj * 12 ? nv * 3 : nj * 12, sizeof(double));
  r->joints = km__malloc(nj, 3 * sizeof(double));
  r->G = km__malloc(nj, 12 * sizeof(double));
  r->vnear = km__malloc(nv, sizeof *r->vnear);
  r->vw = km__malloc(nv, sizeof(double));
  r->vdist = km__malloc(nv, sizeof(double));
  r->vn = km__malloc(nv, 3 * sizeof(double));
  r->vq = km__malloc(nv, 3 * sizeof(double));
  r->part_lost = calloc(nj ? nj : 1, sizeof *r->part_lost);
  r->sup_dist = km__malloc(nv, sizeof(double));
  r->sup_idx = km__malloc(nv, sizeof(int32_t));
  r->sup_list = km__malloc(nv, sizeof(int32_t));
  if (r->o.n_cameras) r->sup_N = km__malloc(nv, 3 * sizeof(double));
  if (!r->sup_dist || !r->sup_idx || !r->sup_list || (r->o.n_cameras && !r->sup_N) || !r->vnear ||
      !r->vw || !r->vq || !r->part_lost || !r->vdist || !r->vn || !r->parents || !r->tmpl_joints ||
      !r->names || !r->skin.joints || !r->skin.weights || !r->base || !r->base_joints || !r->Lrot ||
      !r->Lprev || !r->Lprev2 || !r->global || !r->surface || !r->work || !r->joints || !r->G) {
    km_recon_free(&r);
    return km__fail(err, KM_ERR_NOMEM, "km_recon_create: out of memory");
  }
  memcpy(r->parents, c->skeleton.parents, nj * sizeof *r->parents);
  memcpy(r->tmpl_joints, c->skeleton.rest, nj * 3 * sizeof(double));
  memcpy(r->skin.joints, c->skin.joints, nv * 4 * sizeof(int32_t));
  memcpy(r->skin.weights, c->skin.weights, nv * 4 * sizeof(double));
  for (size_t i = 0; i < nv; ++i) {
    if (!km__skin_row_empty(r->skin.joints + 4 * i, r->skin.weights + 4 * i)) continue;
    if (!r->still && !(r->still = km__calloc(nv, sizeof *r->still))) {
      km_recon_free(&r);
      return km__fail(err, KM_ERR_NOMEM, "km_recon_create: out of memory");
    }
    r->still[i] = true;
    ++r->n_still;
  }
  if (nv && r->n_still == nv) {
    km_recon_free(&r);
    return km__fail(err, KM_ERR_INVALID,
                    "km_recon_create: the template's skin gives no vertex an influence (every "
                    "joint -1): nothing of it can follow the points");
  }
  if ((s = seams_find(r, err)) != KM_OK) {
    km_recon_free(&r);
    return s;
  }
  for (size_t j = 0; j < nj; ++j)
    r->names[j] =
        strdup(c->skeleton.names && c->skeleton.names[j] ? c->skeleton.names[j] : "joint");
  for (int l = 0; l < KM_CHARACTER_LANDMARKS; ++l)
    if (c->landmarks[l].name[0] && c->landmarks[l].vertex >= 0 &&
        (size_t)c->landmarks[l].vertex < nv)
      r->lm[r->n_lm++] = c->landmarks[l].vertex;
  memcpy(r->surface, m->V, nv * 3 * sizeof(double));
  memcpy(r->global, m->V, nv * 3 * sizeof(double));
  memcpy(r->joints, r->tmpl_joints, nj * 3 * sizeof(double));
  s = build_system(r, err);
  if (!s) s = km__surface_create(r->surface, nv, r->tmpl.F, r->nf, &r->query, err);
  if (!s && r->still) {
    if (!(r->still_face = km__malloc(r->nf ? r->nf : 1, sizeof *r->still_face)))
      s = km__fail(err, KM_ERR_NOMEM, "km_recon_create: out of memory");
    for (size_t f = 0; !s && f < r->nf; ++f)
      r->still_face[f] =
          r->still[m->F[3 * f]] && r->still[m->F[3 * f + 1]] && r->still[m->F[3 * f + 2]];
    if (!s) km__surface_skip(r->query, r->still_face);
  }
  if (s) {
    km_recon_free(&r);
    return s;
  }
  *out = r;
  return KM_OK;
}

const double *km_recon_surface(const km_recon *r) { return r ? r->surface : NULL; }

size_t km__recon_still_vertices(const km_recon *r) { return r ? r->n_still : 0; }
const double *km_recon_global(const km_recon *r) { return r ? r->global : NULL; }
const double *km_recon_joints(const km_recon *r) { return r ? r->joints : NULL; }
const km_mesh *km_recon_template(const km_recon *r) { return r ? &r->tmpl : NULL; }
const int32_t *km_recon_unsupported(const km_recon *r, size_t *count) {
  if (count) *count = r && r->have_base ? r->n_sup : 0;
  return r && r->have_base ? r->sup_list : NULL;
}

void km_recon_init_get(const km_recon *r, km_recon_init *out) {
  if (!out) return;
  if (r)
    *out = r->init;
  else
    memset(out, 0, sizeof *out);
}

/* ---------------------------------------------------------------- correspondences */

static km_status reserve_points(km_recon *r, size_t n, km_error *err) {
  if (n <= r->pcap) return KM_OK;
  free(r->ptri), free(r->pbary), free(r->pdist), free(r->pw), free(r->pnormal), free(r->ptsel),
      free(r->sel);
  r->ptri = km__malloc(n, sizeof *r->ptri);
  r->pbary = km__malloc(n, 3 * sizeof(double));
  r->pdist = km__malloc(n, sizeof(double));
  r->pw = km__malloc(n, sizeof(double));
  r->pnormal = km__malloc(n, 3 * sizeof(double));
  r->ptsel = km__malloc(n, 3 * sizeof(double));
  r->sel = km__malloc(n, sizeof *r->sel);
  r->pcap = n;
  if (!r->ptri || !r->pbary || !r->pdist || !r->pw || !r->pnormal || !r->ptsel || !r->sel) {
    r->pcap = 0;
    return km__fail(err, KM_ERR_NOMEM, "out of memory for %zu points", n);
  }
  return KM_OK;
}

/* Closest points of Q (n) on surface X, then robust weights: Geman-McClure with scale
 * c = outlier_scale * 1.4826 * median residual, floored (at 3 mm in the end, so sensor noise
 * is never treated as outliers; larger in early rounds, so a limb that moved far while the
 * rest stood still is not mistaken for outliers), zero beyond 4c, and zero where the point normal
 * (if given) and the face normal are more than 60 degrees apart (a point on the inner thigh must
 * not pull the other leg). Returns the sum of weights. */
static double correspond(km_recon *r, const double *X, const double *Q, const double *NQ, size_t n,
                         double max_dist, double floor) {
  km__surface_update(r->query, X);
  km__surface_closest(r->query, Q, n, max_dist, r->ptri, r->pbary, r->pdist);
  size_t m = 0;
  for (size_t i = 0; i < n; ++i)
    if (r->ptri[i] >= 0) r->pw[m++] = r->pdist[i];
  double med = 0;
  if (m) {
    qsort(r->pw, m, sizeof(double), km__cmp_double);
    med = r->pw[m / 2];
  }
  double c = r->o.outlier_scale * 1.4826 * med;
  if (c < floor) c = floor;
  double wsum = 0;
  for (size_t i = 0; i < n; ++i) {
    double w = 0;
    if (r->ptri[i] >= 0 && r->pdist[i] < 4 * c) {
      double q = r->pdist[i] / c;
      w = 1.0 / ((1 + q * q) * (1 + q * q));
      {
        const int32_t *t = r->tmpl.F + 3 * (size_t)r->ptri[i];
        const double *a = X + 3 * (size_t)t[0], *b = X + 3 * (size_t)t[1],
                     *cc = X + 3 * (size_t)t[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
               v[3] = {cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]}, fn[3];
        km__cross3(u, v, fn);
        double l = sqrt(fn[0] * fn[0] + fn[1] * fn[1] + fn[2] * fn[2]);
        for (int a = 0; a < 3; ++a)
          r->pnormal[3 * i + a] = l > 0 ? fn[a] / l : 0;
        if (NQ) {
          const double *pn = NQ + 3 * i;
          if (l > 0 && fabs(fn[0] * pn[0] + fn[1] * pn[1] + fn[2] * pn[2]) < 0.5 * l) w = 0;
        }
      }
    }
    r->pw[i] = w;
    wsum += w;
  }
  return wsum;
}

/* ---------------------------------------------------------------- affine registration */

/* Solves for per-vertex affine A_i (x_i = c + A_i [v_i - c; 1]) minimising
 *   w_d/sum(w) sum_p w_p |p - sum_b beta_b x_b|^2 + w_f/nf sum |q_k - x_{v_k}|^2
 *   + w_s/ne sum_edges |A_i - A_j|_F^2 + w_id/nv sum |A_i - [I 0]|_F^2
 * for fixed correspondences: one linear least-squares (Gauss-Newton) step. The tiny w_id
 * keeps the system SPD where neither data nor features reach. X receives the result. */
static km_status affine_solve(km_recon *r, const double *Vb, const double *Q, size_t nq, double wd,
                              const km_recon_feature *feat, size_t nfeat, double wf,
                              const double *VQ, const double *vwt, double *X, km_error *err) {
  size_t nv = r->ns, ne = r->ne; /* the system's vertices; r->nv template vertices */
  double c[3] = {0, 0, 0};
  for (size_t i = 0; i < r->nv; ++i)
    for (int a = 0; a < 3; ++a)
      c[a] += Vb[3 * i + a];
  for (int a = 0; a < 3; ++a)
    c[a] /= (double)r->nv;
  memset(r->blocks, 0, (nv + ne) * 16 * sizeof(double));
  memset(r->rhs, 0, 4 * nv * 3 * sizeof(double));
  size_t n4 = 4 * nv;
#define H(i, k) ((k) < 3 ? Vb[3 * (size_t)(i) + (k)] - c[k] : 1.0)
  double wsum = 0;
  for (size_t p = 0; p < nq; ++p)
    wsum += r->pw[p];
  if (wd > 0 && wsum > 0) {
    double scale = wd / wsum;
    for (size_t p = 0; p < nq; ++p) {
      double w = r->pw[p] * scale;
      if (w <= 0 || r->ptri[p] < 0) continue;
      size_t f = (size_t)r->ptri[p];
      const int32_t *tv = r->tmpl.F + 3 * f;
      int32_t t[3] = {SV(r, tv[0]), SV(r, tv[1]), SV(r, tv[2])}; /* J from the face's own */
      const double *be = r->pbary + 3 * p;
      double J[3][4];
      for (int b = 0; b < 3; ++b)
        for (int k = 0; k < 4; ++k)
          J[b][k] = be[b] * H(tv[b], k);
      for (int b = 0; b < 3; ++b) {
        for (int k = 0; k < 4; ++k)
          for (int a = 0; a < 3; ++a)
            r->rhs[a * n4 + 4 * (size_t)t[b] + k] += w * J[b][k] * (Q[3 * p + a] - c[a]);
        for (int b2 = 0; b2 < 3; ++b2) {
          if (t[b] == t[b2]) { /* b2 != b: two copies of one welded vertex (a seam crossed it) */
            double *B = r->blocks + 16 * (size_t)t[b];
            for (int k = 0; k < 4; ++k)
              for (int l = 0; l < 4; ++l)
                B[4 * k + l] += w * J[b][k] * J[b2][l];
          } else if (t[b] < t[b2]) {
            /* edge block stores rows of the smaller vertex, columns of the larger */
            int ek = (b2 == (b + 1) % 3) ? b : b2;
            int32_t e = r->face_edges[3 * f + ek];
            if (e < 0) continue;
            double *B = r->blocks + 16 * (nv + (size_t)e);
            for (int k = 0; k < 4; ++k)
              for (int l = 0; l < 4; ++l)
                B[4 * k + l] += w * J[b][k] * J[b2][l];
          }
        }
      }
    }
  }
  if (nfeat && wf > 0) {
    double w = wf / (double)nfeat;
    for (size_t k = 0; k < nfeat; ++k) {
      int32_t v = feat[k].vertex;
      if (v < 0 || (size_t)v >= r->nv) continue;
      double *B = r->blocks + 16 * (size_t)SV(r, v);
      for (int a = 0; a < 4; ++a) {
        for (int b = 0; b < 4; ++b)
          B[4 * a + b] += w * H(v, a) * H(v, b);
        for (int d = 0; d < 3; ++d)
          r->rhs[d * n4 + 4 * (size_t)SV(r, v) + a] += w * H(v, a) * (feat[k].point[d] - c[d]);
      }
    }
  }
  /* surface -> points: vertex i towards the point VQ[i] with weight vwt[i] (point-to-point, so
   * the three coordinates keep one matrix) */
  for (size_t v = 0; VQ && vwt && v < r->nv; ++v) {
    double w = vwt[v];
    size_t sv = (size_t)SV(r, v);
    if (w <= 0 || (r->sv && r->sv_first[sv] != (int32_t)v)) continue; /* one copy: one vertex */
    double *B = r->blocks + 16 * sv;
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b)
        B[4 * a + b] += w * H(v, a) * H(v, b);
      for (int d = 0; d < 3; ++d)
        r->rhs[d * n4 + 4 * sv + (size_t)a] += w * H(v, a) * (VQ[3 * v + d] - c[d]);
    }
  }
  double ws = r->o.w_smooth / (double)(ne ? ne : 1);
  for (size_t e = 0; e < ne; ++e) {
    size_t i = (size_t)r->edges[2 * e], j = (size_t)r->edges[2 * e + 1];
    for (int k = 0; k < 4; ++k) {
      r->blocks[16 * i + 5 * k] += ws;
      r->blocks[16 * j + 5 * k] += ws;
      r->blocks[16 * (nv + e) + 5 * k] -= ws;
    }
  }
  double wid = 0.01 * ws; /* ~1% of one edge: keeps the system SPD, barely biases it */
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 4; ++k) {
      r->blocks[16 * i + 5 * k] += wid;
      if (k < 3) r->rhs[(size_t)k * n4 + 4 * i + (size_t)k] += wid;
    }
#undef H
  double *Mx = km__sparse_values(r->M);
  for (size_t b = 0; b < nv + ne; ++b)
    for (int k = 0; k < 16; ++k) {
      int64_t p = r->block_pos[16 * b + k];
      if (p >= 0) Mx[p] = r->blocks[16 * b + k];
    }
  km_error ferr;
  km_status fs = km_cholesky_factorize(r->L, r->M, &ferr);
  if (fs)
    return km__fail(err, fs == KM_ERR_NOT_POSDEF ? KM_ERR_NOT_POSDEF : KM_ERR_NOMEM,
                    "affine registration: factorization failed: %s", ferr.message);
  if ((fs = km_cholesky_solve(r->L, 3, r->rhs, r->sol, err))) return fs;
  for (size_t i = 0; i < r->nv; ++i) {
    double h[4] = {Vb[3 * i] - c[0], Vb[3 * i + 1] - c[1], Vb[3 * i + 2] - c[2], 1};
    for (int a = 0; a < 3; ++a) {
      const double *A = r->sol + (size_t)a * n4 + 4 * (size_t)SV(r, i);
      double x = c[a] + A[0] * h[0] + A[1] * h[1] + A[2] * h[2] + A[3] * h[3];
      X[3 * i + a] = isfinite(x) ? x : Vb[3 * i + a];
    }
  }
  return KM_OK;
}

/* Affine map of a point by the solved A of vertex i (for carrying joints along). */
static void affine_apply(const km_recon *r, const double *Vb, size_t i, const double *p,
                         double *out) {
  size_t nv = r->nv, n4 = 4 * r->ns;
  double c[3] = {0, 0, 0};
  for (size_t k = 0; k < nv; ++k)
    for (int a = 0; a < 3; ++a)
      c[a] += Vb[3 * k + a];
  for (int a = 0; a < 3; ++a)
    c[a] /= (double)nv;
  double h[4] = {p[0] - c[0], p[1] - c[1], p[2] - c[2], 1};
  for (int a = 0; a < 3; ++a) {
    const double *A = r->sol + (size_t)a * n4 + 4 * (size_t)SV(r, i);
    out[a] = c[a] + A[0] * h[0] + A[1] * h[1] + A[2] * h[2] + A[3] * h[3];
  }
}

/* ---------------------------------------------------------------- skeleton: FK and LBS */

/* World transforms G_j (3x4) taking base positions to posed ones, from local rotations
 * L_j and root translation t: W_j = W_parent L_j, c_j = c_parent + W_parent (J_j - J_parent). */
static void forward_kinematics(const km_recon *r, const double *Lrot, const double *t, double *W,
                               double *cj, double *G) {
  const double *J = r->base_joints;
  for (size_t j = 0; j < r->nj; ++j) { /* offsets, turned into positions in place */
    int32_t p = r->parents[j];
    for (int a = 0; a < 3; ++a)
      cj[3 * j + a] = p < 0 ? J[3 * j + a] + t[a] : J[3 * j + a] - J[3 * (size_t)p + a];
  }
  km__forward_kinematics(r->nj, r->parents, Lrot, cj, W, cj);
  km__joint_transforms(r->nj, W, cj, J, G);
}

/* The vertices with no skin influence (a ground plane) matched to no point: near[i] = -1 for
 * them, after a nearest-point query over the template's vertices. */
static void unhook_still(const km_recon *r, int32_t *near) {
  for (size_t i = 0; r->still && i < r->nv; ++i)
    if (r->still[i]) near[i] = -1;
}

/* km_lbs runs serially below 20000 vertices: called once per L-BFGS evaluation on a few
 * thousand vertices, an OpenMP fork/join would cost more than the work. The skin was checked
 * by km_recon_create. */
static void lbs_apply(const km_recon *r, const double *G, const double *Vb, double *X) {
  km_lbs(Vb, r->nv, &r->skin, G, r->nj, X, NULL);
}

/* ---------------------------------------------------------------- skeleton: L-BFGS */

#define PLANE_MU 0.1
/* First frame: the pose comes from the features and is only refined by the data, so it is
 * held closer than later frames (whose reference is a prediction). */
#define KM__FIRST_FRAME_POSE_WEIGHT 1e-3
#define S2S_WEIGHT 0.5

typedef struct pose_ctx {
  km_recon *r;
  const double *Q; /* points */
  size_t nq;
  double wsum;
  const double *Lref; /* nj*9 rotations the parameters are relative to */
  const double *tref;
  double *Lrot, *W, *cj, *G, *X, *gv, *acc; /* scratch */
  double lambda;
  const double *NQ;   /* point normals */
  double vwsum;       /* surface -> points weight sum (0: term off) */
  const double *xoff; /* n: parameters accumulated in earlier rounds (prediction offset) */
  const km_recon_feature *feat;
  size_t nfeat;
  double wf;
  bool use_data;
  int evals;
} pose_ctx;

static void pose_from_params(pose_ctx *pc, const double *x) {
  km_recon *r = pc->r;
  for (size_t j = 0; j < r->nj; ++j) {
    double E[9];
    km__m3_from_rotvec(x + 3 + 3 * j, E);
    km__m3_mul(pc->Lref + 9 * j, E, pc->Lrot + 9 * j);
  }
  double t[3] = {pc->tref[0] + x[0], pc->tref[1] + x[1], pc->tref[2] + x[2]};
  forward_kinematics(r, pc->Lrot, t, pc->W, pc->cj, pc->G);
}

static lbfgsfloatval_t pose_evaluate(void *inst, const lbfgsfloatval_t *x, lbfgsfloatval_t *g,
                                     const int n, const lbfgsfloatval_t step) {
  (void)step;
  pose_ctx *pc = inst;
  km_recon *r = pc->r;
  size_t nv = r->nv, nj = r->nj;
  ++pc->evals;
  pose_from_params(pc, x);
  lbs_apply(r, pc->G, r->base, pc->X);
  memset(pc->gv, 0, nv * 3 * sizeof(double));
  double E = 0, s = 1.0 / (pc->wsum > 0 ? pc->wsum : 1);
  for (size_t k = 0; k < pc->nfeat; ++k) {
    size_t v = (size_t)pc->feat[k].vertex;
    double w = pc->wf / (double)pc->nfeat;
    for (int a = 0; a < 3; ++a) {
      double e = pc->X[3 * v + a] - pc->feat[k].point[a];
      E += w * e * e;
      pc->gv[3 * v + a] += 2 * w * e;
    }
  }
  /* surface -> points: pulls template parts towards points they do not yet cover (a limb
   * that moved away leaves its points closer to another part of the surface) */
  if (pc->use_data && pc->vwsum > 0) {
    double sv = S2S_WEIGHT / pc->vwsum;
    for (size_t v = 0; v < nv; ++v) {
      double w = r->vw[v] * sv;
      if (w <= 0) continue;
      size_t q = (size_t)r->vnear[v];
      const double *nn = pc->NQ + 3 * q;
      double e[3] = {pc->X[3 * v] - pc->Q[3 * q], pc->X[3 * v + 1] - pc->Q[3 * q + 1],
                     pc->X[3 * v + 2] - pc->Q[3 * q + 2]};
      double en = nn[0] * e[0] + nn[1] * e[1] + nn[2] * e[2];
      E += w * (en * en + PLANE_MU * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]));
      for (int a = 0; a < 3; ++a)
        pc->gv[3 * v + a] += 2 * w * (en * nn[a] + PLANE_MU * e[a]);
    }
  }
  for (size_t p = 0; pc->use_data && p < pc->nq; ++p) {
    double w = r->pw[p] * s;
    if (w <= 0) continue;
    const int32_t *t = r->tmpl.F + 3 * (size_t)r->ptri[p];
    const double *be = r->pbary + 3 * p;
    double e[3];
    for (int a = 0; a < 3; ++a)
      e[a] = be[0] * pc->X[3 * (size_t)t[0] + a] + be[1] * pc->X[3 * (size_t)t[1] + a] +
             be[2] * pc->X[3 * (size_t)t[2] + a] - pc->Q[3 * p + a];
    /* point-to-plane plus a little point-to-point (the face normal is frozen with the
     * correspondence): converges in far fewer rounds than point-to-point alone */
    const double *nn = r->pnormal + 3 * p;
    double en = nn[0] * e[0] + nn[1] * e[1] + nn[2] * e[2];
    E += w * (en * en + PLANE_MU * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]));
    double ge[3];
    for (int a = 0; a < 3; ++a)
      ge[a] = 2 * w * (en * nn[a] + PLANE_MU * e[a]);
    for (int b = 0; b < 3; ++b)
      for (int a = 0; a < 3; ++a)
        pc->gv[3 * (size_t)t[b] + a] += be[b] * ge[a];
  }
  /* per joint: a_k = sum w (G_k v) x g_v, b_k = sum w g_v */
  double *acc = pc->acc; /* nj*6 */
  memset(acc, 0, nj * 6 * sizeof(double));
  for (size_t i = 0; i < nv; ++i) {
    const double *gvi = pc->gv + 3 * i;
    if (gvi[0] == 0 && gvi[1] == 0 && gvi[2] == 0) continue;
    const double *v = r->base + 3 * i;
    for (int k = 0; k < 4; ++k) {
      int32_t j = r->skin.joints[4 * i + k];
      double w = r->skin.weights[4 * i + k];
      if (j < 0 || w == 0) continue;
      const double *G = pc->G + 12 * (size_t)j;
      double y[3], yx[3];
      for (int a = 0; a < 3; ++a)
        y[a] = G[4 * a] * v[0] + G[4 * a + 1] * v[1] + G[4 * a + 2] * v[2] + G[4 * a + 3];
      km__cross3(y, gvi, yx);
      for (int a = 0; a < 3; ++a)
        acc[6 * (size_t)j + a] += w * yx[a], acc[6 * (size_t)j + 3 + a] += w * gvi[a];
    }
  }
  /* subtree sums, children after parents */
  for (size_t j = nj; j-- > 1;) {
    int32_t p = r->parents[j];
    for (int a = 0; a < 6; ++a)
      acc[6 * (size_t)p + a] += acc[6 * j + a];
  }
  for (int a = 0; a < 3; ++a)
    g[a] = acc[3 + a];
  for (size_t j = 0; j < nj; ++j) {
    double cb[3], gphi[3], Jr[9], tmp[3];
    km__cross3(pc->cj + 3 * j, acc + 6 * j + 3, cb);
    for (int a = 0; a < 3; ++a)
      gphi[a] = acc[6 * j + a] - cb[a];
    km__m3_apply_t(pc->W + 9 * j, gphi, tmp);
    right_jacobian(x + 3 + 3 * j, Jr);
    km__m3_apply_t(Jr, tmp, g + 3 + 3 * j);
  }
  /* small change from the reference pose (the skeleton prediction) */
  double lam = pc->lambda;
  for (int k = 0; k < n; ++k) {
    double wk = k < 3 ? lam * 4 : lam; /* translation in metres: 0.5 m ~ 1 rad */
    double d = x[k] + pc->xoff[k];
    E += wk * d * d;
    g[k] += 2 * wk * d;
  }
  return E;
}

/* Estimates the pose for points Q (with normals NQ) starting from (Lref, tref). Returns the
 * L-BFGS iterations used; the pose ends in r->Lrot / r->troot, LBS surface in r->global. */
static int skeleton_fit(km_recon *r, const double *Q, const double *NQ, size_t nq,
                        const double *Lref, const double *tref, int outer,
                        const km_recon_feature *feat, size_t nfeat, bool use_data, double lambda,
                        km_status *status) {
  size_t nj = r->nj, nv = r->nv;
  int n = (int)(3 + 3 * nj);
  lbfgsfloatval_t *x = lbfgs_malloc(n);
  double *scratch = km__malloc(nj * 9 * 2 + nj * 3 + nj * 12 + nv * 6 + nj * 6, sizeof(double));
  double *Lcur = km__malloc(nj, 9 * sizeof(double));
  double *xoff = calloc((size_t)n, sizeof(double));
  if (!x || !scratch || !Lcur || !xoff) {
    free(xoff);
    lbfgs_free(x);
    free(scratch);
    free(Lcur);
    *status = KM_ERR_NOMEM;
    return 0;
  }
  km__point_index *ix = NULL;
  if (use_data && nq) km__point_index_create(Q, nq, &ix, NULL);
  pose_ctx pc = {.r = r,
                 .Q = Q,
                 .NQ = NQ,
                 .nq = nq,
                 .lambda = lambda,
                 .xoff = xoff,
                 .feat = feat,
                 .nfeat = nfeat,
                 .wf = r->o.w_feature,
                 .use_data = use_data};
  pc.Lrot = scratch;
  pc.W = pc.Lrot + nj * 9;
  pc.cj = pc.W + nj * 9;
  pc.G = pc.cj + nj * 3;
  pc.X = pc.G + nj * 12;
  pc.gv = pc.X + nv * 3;
  pc.acc = pc.gv + nv * 3;
  memcpy(Lcur, Lref, nj * 9 * sizeof(double));
  double tcur[3] = {tref[0], tref[1], tref[2]};
  int iters = 0;
  *status = KM_OK;
  lbfgs_parameter_t par;
  lbfgs_parameter_init(&par);
  par.max_iterations = use_data ? 60 : 300;
  par.epsilon = 1e-6;
  par.past = 3;
  par.delta = 1e-7;
  /* Each outer round fixes the correspondences (closest points on the current LBS surface)
   * and optimises the pose around the current estimate; the regulariser keeps it near the
   * prediction through the accumulated translation (rotations: per round). */
  for (int it = 0; it < outer; ++it) {
    pc.Lref = Lcur;
    pc.tref = tcur;
    memset(x, 0, (size_t)n * sizeof *x);
    pose_from_params(&pc, x);
    lbs_apply(r, pc.G, r->base, pc.X);
    memcpy(r->work, pc.X, nv * 3 * sizeof(double));
    double floor_m = fmax(0.003, ldexp(0.1, -it));
    pc.wsum = use_data ? correspond(r, r->work, Q, NQ, nq, 0.3, floor_m) : 1;
    pc.vwsum = 0;
    if (use_data && ix && NQ) {
      km_mesh cur = {.V = r->work, .F = r->tmpl.F, .n_vertices = nv, .n_faces = r->nf};
      if (km_vertex_normals(&cur, KM_NORMALS_AREA, r->vn, NULL) == KM_OK) {
        km__point_index_nearest(ix, r->work, nv, 0.3, r->vnear, r->vdist);
        unhook_still(r, r->vnear);
        size_t m = 0;
        for (size_t v = 0; v < nv; ++v)
          if (r->vnear[v] >= 0) r->vw[m++] = r->vdist[v];
        double med = 0;
        if (m) {
          qsort(r->vw, m, sizeof(double), km__cmp_double);
          med = r->vw[m / 2];
        }
        double c = fmax(r->o.outlier_scale * 1.4826 * med, floor_m);
        for (size_t v = 0; v < nv; ++v) {
          double w = 0;
          /* only towards points the surface does not explain yet (residual > 1 cm): a
           * vertex of a hidden limb must not be dragged onto points another part covers */
          if (r->vnear[v] >= 0 && r->vdist[v] < 4 * c && r->pdist[r->vnear[v]] > 0.01) {
            const double *pn = NQ + 3 * (size_t)r->vnear[v], *vn = r->vn + 3 * v;
            double q = r->vdist[v] / c;
            if (fabs(pn[0] * vn[0] + pn[1] * vn[1] + pn[2] * vn[2]) > 0.5)
              w = 1.0 / ((1 + q * q) * (1 + q * q));
          }
          r->vw[v] = w;
          pc.vwsum += w;
        }
      }
    }
    if (pc.wsum <= 0) {
      *status = KM_ERR_NO_CONVERGENCE;
      break;
    }
    lbfgsfloatval_t fx;
    int ret = lbfgs(n, x, &fx, pose_evaluate, NULL, &pc, &par);
    if (ret < 0 && ret != LBFGSERR_MAXIMUMITERATION && ret != LBFGSERR_ROUNDING_ERROR &&
        ret != LBFGSERR_MAXIMUMLINESEARCH && ret != LBFGSERR_MINIMUMSTEP &&
        ret != LBFGSERR_MAXIMUMSTEP && ret != LBFGSERR_WIDTHTOOSMALL) {
      *status = KM_ERR_NO_CONVERGENCE;
      break;
    }
    iters += pc.evals;
    pc.evals = 0;
    for (size_t j = 0; j < nj; ++j) {
      double E[9];
      km__m3_from_rotvec(x + 3 + 3 * j, E);
      km__m3_mul(Lcur + 9 * j, E, Lcur + 9 * j);
      orthonormalize(Lcur + 9 * j);
    }
    for (int a = 0; a < 3; ++a)
      tcur[a] += x[a];
    /* first-order accumulation of the deviation from the prediction */
    for (int k = 0; k < n; ++k)
      xoff[k] += x[k];
  }
  memcpy(r->Lrot, Lcur, nj * 9 * sizeof(double));
  memcpy(r->troot, tcur, sizeof tcur);
  double *W = pc.W, *cj = pc.cj;
  forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
  memcpy(r->joints, cj, nj * 3 * sizeof(double));
  lbs_apply(r, r->G, r->base, r->global);
  lbfgs_free(x);
  free(scratch);
  free(Lcur);
  free(xoff);
  km__point_index_free(&ix);
  return iters;
}

/* ---------------------------------------------------------------- per-frame driver */

typedef struct frame_data {
  const double *P; /* full points */
  size_t n;
  double *N;  /* normals of P */
  double *C;  /* coarse points */
  double *CN; /* coarse normals */
  size_t nc;
  km__point_index *ix; /* nearest points of P (normals, surface -> points) */
} frame_data;

static void frame_data_free(frame_data *fd) {
  km__point_index_free(&fd->ix);
  free(fd->N);
  free(fd->C);
  free(fd->CN);
}

static km_status frame_prepare(km_recon *r, const double *P, size_t n, frame_data *fd,
                               km_error *err) {
  memset(fd, 0, sizeof *fd);
  fd->P = P;
  fd->n = n;
  if (n < 16) return km__fail(err, KM_ERR_INVALID, "frame has %zu points (need >= 16)", n);
  fd->N = km__malloc(n, 3 * sizeof(double));
  if (!fd->N) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  km_status s = km__point_index_create(P, n, &fd->ix, err);
  if (!s) s = km__point_normals_indexed(P, n, fd->ix, r->o.knn, fd->N, err);
  if (s) return s;
  int32_t *reps = NULL;
  size_t nr = 0;
  if (n > r->o.coarse_points * 3 / 2) {
    s = km__cluster_points(P, n, r->o.coarse_points, &reps, &nr, err);
    if (s) return s;
  }
  if (!nr) {
    fd->C = km__malloc(n, 3 * sizeof(double));
    fd->CN = km__malloc(n, 3 * sizeof(double));
    if (!fd->C || !fd->CN) return km__fail(err, KM_ERR_NOMEM, "out of memory");
    memcpy(fd->C, P, n * 3 * sizeof(double));
    memcpy(fd->CN, fd->N, n * 3 * sizeof(double));
    fd->nc = n;
  } else {
    fd->C = km__malloc(nr, 3 * sizeof(double));
    fd->CN = km__malloc(nr, 3 * sizeof(double));
    if (!fd->C || !fd->CN) {
      free(reps);
      return km__fail(err, KM_ERR_NOMEM, "out of memory");
    }
    for (size_t i = 0; i < nr; ++i) {
      memcpy(fd->C + 3 * i, P + 3 * (size_t)reps[i], 3 * sizeof(double));
      memcpy(fd->CN + 3 * i, fd->N + 3 * (size_t)reps[i], 3 * sizeof(double));
    }
    fd->nc = nr;
    free(reps);
  }
  return reserve_points(r, n, err);
}

/* The q-quantile (0..1) of x[0..n) by the nearest-rank rule; reorders x. Quickselect: a
 * full sort of 100k distances per frame is measurable, and no library here has a select. */
static double quantile(double *x, size_t n, double q) {
  if (!n) return 0;
  size_t kk = (size_t)ceil(q * (double)n);
  long long k = kk ? (long long)kk - 1 : 0, l = 0, m = (long long)n - 1;
  if (k > m) k = m;
  while (l < m) { /* Wirth's select */
    double xk = x[k];
    long long i = l, j = m;
    do {
      while (x[i] < xk)
        ++i;
      while (xk < x[j])
        --j;
      if (i <= j) {
        double t = x[i];
        x[i] = x[j], x[j] = t;
        ++i, --j;
      }
    } while (i <= j);
    if (j < k) l = i;
    if (k < i) m = j;
  }
  return x[k];
}

/* The skin joint of vertex i's largest weight (its body part), -1 when it has none. */
static int32_t dominant_joint(const km_recon *r, size_t i) {
  return km__skin_dominant(r->skin.joints + 4 * i, r->skin.weights + 4 * i);
}

/* Surface -> points: every measured vertex of X to its nearest point, the unsupported
 * vertices and the skin joints they belong to. */
static void surface_support(km_recon *r, const frame_data *fd, const double *X,
                            km_recon_frame_stats *st) {
  size_t nv = r->nv;
  r->n_sup = 0;
  if (!fd->ix) return;
  km__point_index_nearest(fd->ix, X, nv, 0, r->sup_idx, r->sup_dist);
  bool *seen = NULL;
  if (r->o.n_cameras) {
    km_mesh view = {.V = (double *)X, .F = r->tmpl.F, .n_vertices = nv, .n_faces = r->nf};
    seen = km__malloc(nv, sizeof *seen);
    if (seen && km_vertex_normals(&view, KM_NORMALS_AREA, r->sup_N, NULL)) free(seen), seen = NULL;
    for (size_t i = 0; seen && i < nv; ++i) {
      seen[i] = false;
      for (size_t c = 0; c < r->o.n_cameras && !seen[i]; ++c) {
        double d = 0;
        for (int a = 0; a < 3; ++a)
          d += r->sup_N[3 * i + a] * (r->o.cameras[3 * c + a] - X[3 * i + a]);
        seen[i] = d > 0;
      }
    }
  }
  double *d = km__malloc(nv, sizeof *d);
  size_t m = 0;
  double sum = 0, mx = 0;
  size_t *per_joint = calloc(r->nj, sizeof *per_joint);
  for (size_t i = 0; i < nv; ++i) {
    if ((seen && !seen[i]) || (r->still && r->still[i])) continue;
    double di = r->sup_dist[i];
    sum += di;
    mx = di > mx ? di : mx;
    if (d) d[m] = di;
    ++m;
    if (di > r->o.unsupported_distance) {
      r->sup_list[r->n_sup++] = (int32_t)i;
      int32_t j = dominant_joint(r, i);
      if (per_joint && j >= 0) ++per_joint[j];
    }
  }
  st->surface_vertices = m;
  st->surface_mean_mm = m ? 1e3 * sum / (double)m : 0;
  st->surface_max_mm = 1e3 * mx;
  st->surface_p95_mm = d ? 1e3 * quantile(d, m, 0.95) : st->surface_max_mm;
  st->surface_p99_mm = d ? 1e3 * quantile(d, m, 0.99) : st->surface_max_mm;
  st->unsupported_vertices = r->n_sup;
  st->unsupported = (double)r->n_sup > r->o.unsupported_fraction * (double)m;
  st->n_unsupported_joints = 0;
  /* the parts: joints holding at least a tenth of the unsupported vertices, most first */
  while (per_joint && r->n_sup && st->n_unsupported_joints < KM_RECON_MAX_PARTS) {
    size_t jb = 0;
    for (size_t j = 1; j < r->nj; ++j)
      if (per_joint[j] > per_joint[jb]) jb = j;
    if (!per_joint[jb] || 10 * per_joint[jb] < r->n_sup) break;
    st->unsupported_joints[st->n_unsupported_joints++] = (int32_t)jb;
    per_joint[jb] = 0;
  }
  free(per_joint);
  free(d);
  free(seen);
}

/* The vertices with no skin influence of a frame's surface X put back where the template has
 * them. */
static void hold_still(const km_recon *r, double *X) {
  for (size_t i = 0; r->still && i < r->nv; ++i)
    if (r->still[i]) memcpy(X + 3 * i, r->tmpl.V + 3 * i, 3 * sizeof(double));
}

/* Points -> surface (mean, p95, max in mm over all points) and surface -> points, of a frame's
 * result X (its vertices with no skin influence first held: hold_still). */
static void frame_error(km_recon *r, const frame_data *fd, double *X, km_recon_frame_stats *st) {
  hold_still(r, X);
  km__surface_update(r->query, X);
  km__surface_closest(r->query, fd->P, fd->n, 0, r->ptri, NULL, r->pdist);
  double sum = 0, mx = 0;
  for (size_t i = 0; i < fd->n; ++i) {
    sum += r->pdist[i];
    if (r->pdist[i] > mx) mx = r->pdist[i];
  }
  st->mean_mm = 1e3 * sum / (double)fd->n;
  st->max_mm = 1e3 * mx;
  double t0 = km_seconds();
  double *d = km__malloc(fd->n, sizeof *d);
  if (d) memcpy(d, r->pdist, fd->n * sizeof *d);
  st->p95_mm = d ? 1e3 * quantile(d, fd->n, 0.95) : st->max_mm;
  free(d);
  surface_support(r, fd, X, st);
  km__log(KM_LOG_DEBUG, "frame %zu: two-sided error %.4f s (%zu points, %zu vertices)", r->frame,
          km_seconds() - t0, fd->n, r->nv);
}

/* Surface -> points in the affine stage: points -> surface alone cannot see surface that no
 * point claims (a bulge on top of the forearm whose points are closer to the arm's sides
 * stayed 47 mm off the truth). Each template vertex of X is drawn to its nearest captured
 * point when that point is between KM__S2P_NEAR and KM__S2P_FAR away and the normals agree
 * (within 60 degrees, either orientation); nearer vertices are already explained, farther
 * ones may belong to a hidden limb that must stay unsupported (and flagged), and so do the
 * vertices of the parts the last frame flagged (a hidden arm would otherwise creep onto the
 * torso's points over the frames it is hidden, 6 cm at a time). Weight per vertex:
 * KM__S2P_WEIGHT * w_data / #V. Returns false when no vertex qualifies. */
#define KM__S2P_NEAR 0.006
#define KM__S2P_FAR 0.06
#define KM__S2P_WEIGHT 1.0
static bool surface_targets(km_recon *r, const frame_data *fd, const double *X, double *VQ,
                            double *w) {
  size_t nv = r->nv;
  if (!fd->ix || !fd->N || r->o.no_surface_to_points) return false;
  km_mesh cur = {.V = (double *)X, .F = r->tmpl.F, .n_vertices = nv, .n_faces = r->nf};
  if (km_vertex_normals(&cur, KM_NORMALS_AREA, r->vn, NULL) != KM_OK) return false;
  km__point_index_nearest(fd->ix, X, nv, KM__S2P_FAR, r->vnear, r->vdist);
  unhook_still(r, r->vnear);
  double wv = KM__S2P_WEIGHT * r->o.w_data / (double)nv;
  size_t m = 0;
  for (size_t v = 0; v < nv; ++v) {
    w[v] = 0;
    int32_t q = r->vnear[v];
    if (q < 0 || r->vdist[v] < KM__S2P_NEAR || r->vdist[v] > KM__S2P_FAR) continue;
    int32_t j = dominant_joint(r, v);
    if (j >= 0 && r->part_lost[j]) continue;
    const double *pn = fd->N + 3 * (size_t)q, *vn = r->vn + 3 * v;
    if (fabs(pn[0] * vn[0] + pn[1] * vn[1] + pn[2] * vn[2]) < 0.5) continue;
    memcpy(VQ + 3 * v, fd->P + 3 * (size_t)q, 3 * sizeof(double));
    w[v] = wv;
    ++m;
  }
  return m > 0;
}

/* Surface refinement from Vb (coarse level first, full data for the last two rounds). */
/* floor0/decay: the robust scale's floor starts at floor0 and shrinks by decay per round
 * (the first frame starts farther from the data than a tracked frame). */
static km_status refine(km_recon *r, const frame_data *fd, const double *Vb, int iters,
                        const km_recon_feature *feat, size_t nfeat, double wf, double floor0,
                        double decay, int *count, km_error *err) {
  memcpy(r->surface, Vb, r->nv * 3 * sizeof(double));
  double prev = INFINITY;
  for (int it = 0; it < iters; ++it) {
    bool full = it >= iters - 2;
    const double *Q = full ? fd->P : fd->C, *NQ = full ? fd->N : fd->CN;
    size_t nq = full ? fd->n : fd->nc;
    memcpy(r->work, r->surface, r->nv * 3 * sizeof(double));
    double ws = correspond(r, r->work, Q, NQ, nq, 0.15, fmax(0.003, floor0 * pow(decay, it)));
    double mean = 0;
    for (size_t i = 0; i < nq; ++i)
      if (r->pw[i] > 0) mean += r->pw[i] * r->pdist[i];
    mean /= ws > 0 ? ws : 1;
    double *VQ = r->vq;
    bool s2p = surface_targets(r, fd, r->work, VQ, r->vw);
    km_status s = affine_solve(r, Vb, Q, nq, r->o.w_data, feat, nfeat, wf, s2p ? VQ : NULL, r->vw,
                               r->surface, err);
    ++*count;
    if (s) return s;
    if (!full && fabs(prev - mean) < 1e-5) it = iters - 3 > it ? iters - 3 : it;
    prev = mean;
  }
  return KM_OK;
}

/* ---------------------------------------------------------------- global alignment */

#define KM__YAW_CANDIDATES 12
#define KM__ICP_ROUNDS 10
#define KM__RESIDUAL_CAP 0.05   /* m: a point farther than this counts as this far */
#define KM__LANDMARK_REACH 0.04 /* m: a landmark farther from every point is not used */
#define KM__FEET_HEIGHT 0.08    /* of the subject's height: the points scored as the feet */

/* X = sc R V + t over the template. */
static void place(const km_recon *r, const double *R, double sc, const double *t, double *X) {
  for (size_t i = 0; i < r->nv; ++i) {
    km__m3_apply(R, r->tmpl.V + 3 * i, X + 3 * i);
    for (int a = 0; a < 3; ++a)
      X[3 * i + a] = sc * X[3 * i + a] + t[a];
  }
}

/* Closest points of Q on X (r->ptri, r->pbary, r->pdist); returns the capped mean distance,
 * which counts a body part with no counterpart (a foot pointing the wrong way) at most
 * KM__RESIDUAL_CAP per point instead of letting it dominate. */
static double capped_residual(km_recon *r, const double *X, const double *Q, size_t n) {
  km__surface_update(r->query, X);
  km__surface_closest(r->query, Q, n, 0, r->ptri, r->pbary, r->pdist);
  double sum = 0;
  for (size_t i = 0; i < n; ++i)
    sum += fmin(r->ptri[i] >= 0 ? r->pdist[i] : INFINITY, KM__RESIDUAL_CAP);
  return sum / (double)(n ? n : 1);
}

/* Two-sided capped residual of the surface X: points -> surface over the coarse points plus
 * surface -> points over the vertices (each distance counted at most KM__RESIDUAL_CAP). */
static double two_sided_residual(km_recon *r, const frame_data *fd, const double *X) {
  double a = capped_residual(r, X, fd->C, fd->nc), b = 0;
  if (!fd->ix) return a;
  km__point_index_nearest(fd->ix, X, r->nv, KM__RESIDUAL_CAP, r->vnear, r->vdist);
  size_t m = 0; /* the still vertices (a ground plane) are no surface of the subject */
  for (size_t i = 0; i < r->nv; ++i) {
    if (r->still && r->still[i]) continue;
    b += r->vnear[i] >= 0 ? fmin(r->vdist[i], KM__RESIDUAL_CAP) : KM__RESIDUAL_CAP;
    ++m;
  }
  return a + b / (double)(m ? m : 1);
}

/* Solves the 6x6 SPD system M x = b in place (Gaussian elimination, partial pivoting). */
static bool solve6(double M[36], double b[6]) {
  for (int c = 0; c < 6; ++c) {
    int p = c;
    for (int r = c + 1; r < 6; ++r)
      if (fabs(M[6 * r + c]) > fabs(M[6 * p + c])) p = r;
    if (!(fabs(M[6 * p + c]) > 1e-300)) return false;
    if (p != c) {
      for (int k = 0; k < 6; ++k) {
        double tmp = M[6 * c + k];
        M[6 * c + k] = M[6 * p + k], M[6 * p + k] = tmp;
      }
      double tmp = b[c];
      b[c] = b[p], b[p] = tmp;
    }
    for (int r = c + 1; r < 6; ++r) {
      double f = M[6 * r + c] / M[6 * c + c];
      for (int k = c; k < 6; ++k)
        M[6 * r + k] -= f * M[6 * c + k];
      b[r] -= f * b[c];
    }
  }
  for (int c = 5; c >= 0; --c) {
    for (int k = c + 1; k < 6; ++k)
      b[c] -= M[6 * c + k] * b[k];
    b[c] /= M[6 * c + c];
  }
  return true;
}

/* One rigid ICP step of the placed template X (closest points of Q in r->ptri/pbary/pdist)
 * towards the points within `keep`: point-to-plane plus PLANE_MU point-to-point, linearised
 * about the kept surface points' centroid. Point-to-point alone turns a roughly cylindrical
 * body about its axis only a little per step. Updates R, t (X = sc R V + t). */
static bool icp_step(km_recon *r, const double *X, const double *Q, size_t nq, double keep,
                     double *R, double *t) {
  double cs[3] = {0, 0, 0}, cnt = 0;
  for (size_t i = 0; i < nq; ++i) {
    if (r->ptri[i] < 0 || r->pdist[i] > keep) continue;
    const int32_t *f = r->tmpl.F + 3 * (size_t)r->ptri[i];
    const double *w = r->pbary + 3 * i;
    for (int a = 0; a < 3; ++a)
      cs[a] += w[0] * X[3 * (size_t)f[0] + a] + w[1] * X[3 * (size_t)f[1] + a] +
               w[2] * X[3 * (size_t)f[2] + a];
    ++cnt;
  }
  if (cnt < 6) return false;
  for (int a = 0; a < 3; ++a)
    cs[a] /= cnt;
  double M[36] = {0}, b[6] = {0};
  for (size_t i = 0; i < nq; ++i) {
    if (r->ptri[i] < 0 || r->pdist[i] > keep) continue;
    const int32_t *f = r->tmpl.F + 3 * (size_t)r->ptri[i];
    const double *w = r->pbary + 3 * i, *x0 = X + 3 * (size_t)f[0], *x1 = X + 3 * (size_t)f[1],
                 *x2 = X + 3 * (size_t)f[2];
    double sp[3], e[3], u[3], v[3], nn[3];
    for (int a = 0; a < 3; ++a) {
      double sa = w[0] * x0[a] + w[1] * x1[a] + w[2] * x2[a];
      sp[a] = sa - cs[a];
      e[a] = sa - Q[3 * i + a];
      u[a] = x1[a] - x0[a], v[a] = x2[a] - x0[a];
    }
    km__cross3(u, v, nn);
    double l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
    if (!(l > 0)) continue;
    for (int a = 0; a < 3; ++a)
      nn[a] /= l;
    /* rows: the plane residual, then the three point residuals scaled by sqrt(mu) */
    double J[4][6], res[4], sxn[3];
    km__cross3(sp, nn, sxn);
    for (int k = 0; k < 3; ++k)
      J[0][k] = sxn[k], J[0][3 + k] = nn[k];
    res[0] = e[0] * nn[0] + e[1] * nn[1] + e[2] * nn[2];
    double sm = sqrt(PLANE_MU);
    for (int a = 0; a < 3; ++a) {
      /* d(omega x s)_a / d omega = -[s]x row a */
      double row[3] = {0, 0, 0};
      row[(a + 1) % 3] = sp[(a + 2) % 3];
      row[(a + 2) % 3] = -sp[(a + 1) % 3];
      for (int k = 0; k < 3; ++k)
        J[1 + a][k] = sm * row[k], J[1 + a][3 + k] = sm * (k == a);
      res[1 + a] = sm * e[a];
    }
    for (int q = 0; q < 4; ++q)
      for (int j = 0; j < 6; ++j) {
        b[j] -= J[q][j] * res[q];
        for (int k = 0; k < 6; ++k)
          M[6 * j + k] += J[q][j] * J[q][k];
      }
  }
  if (!solve6(M, b)) return false;
  double Ri[9];
  km__m3_from_rotvec(b, Ri);
  /* X' = Ri (X - cs) + cs + tau: R <- Ri R, t <- Ri (t - cs) + cs + tau */
  km__m3_mul(Ri, R, R);
  orthonormalize(R);
  double d[3] = {t[0] - cs[0], t[1] - cs[1], t[2] - cs[2]};
  km__m3_apply(Ri, d, d);
  for (int a = 0; a < 3; ++a)
    t[a] = d[a] + cs[a] + b[3 + a];
  return true;
}

/* Without correspondences: the subject is upright (y up) like the template, but its heading
 * is unknown. Every heading of a ring is tried: centroids and heights matched, the template
 * turned about the vertical axis, rigid ICP (icp_step on the closest points within 2.5
 * median distances, which leaves out limbs posed differently from the template), then the
 * skeletal step from there; the smallest capped residual of the posed surface wins. The
 * rigid residual alone cannot choose: a person turned 180 degrees has nearly the same
 * silhouette, and when the subject's pose is far from the template's (legs apart and arms
 * down against arms out) every heading leaves about the same rigid residual. Rigid ICP from a
 * single start falls into the nearest local minimum, which for a body turned 120 degrees is not
 * the right one. Even posed, front and back differ by little over the whole body; they
 * differ most at the feet (toes reach forward, heels barely back), so the points of the
 * lowest 8% of the height count as much as all the others together: turned the wrong way,
 * the posed feet leave them 1.3-2 times as far from the surface (simulated captures and a
 * D-FAUST scan). */
static km_status global_alignment(km_recon *r, const frame_data *fd, double *Rbest, double *tbest,
                                  double *scbest, km_error *err) {
  const double *Q = fd->C;
  size_t nq = fd->nc, nv = r->nv, nj = r->nj;
  double cp[3] = {0}, ct[3] = {0}, plo = INFINITY, phi = -INFINITY, tlo = INFINITY, thi = -INFINITY;
  for (size_t i = 0; i < fd->n; ++i) {
    for (int a = 0; a < 3; ++a)
      cp[a] += fd->P[3 * i + a] / (double)fd->n;
    plo = fmin(plo, fd->P[3 * i + 1]), phi = fmax(phi, fd->P[3 * i + 1]);
  }
  size_t nb = nv - r->n_still; /* the body's vertices: a ground plane is no part of it */
  for (size_t i = 0; i < nv; ++i) {
    if (r->still && r->still[i]) continue;
    for (int a = 0; a < 3; ++a)
      ct[a] += r->tmpl.V[3 * i + a] / (double)nb;
    tlo = fmin(tlo, r->tmpl.V[3 * i + 1]), thi = fmax(thi, r->tmpl.V[3 * i + 1]);
  }
  double sc = (thi > tlo && phi > plo) ? (phi - plo) / (thi - tlo) : 1;
  double *X = km__malloc(nv, 3 * sizeof(double)), *Lid = km__malloc(nj, 9 * sizeof(double));
  if (!X || !Lid) {
    free(X), free(Lid);
    return km__fail(err, KM_ERR_NOMEM, "global alignment: out of memory");
  }
  double best = INFINITY;
  for (int k = 0; k < KM__YAW_CANDIDATES; ++k) {
    double yaw = 2 * M_PI * k / KM__YAW_CANDIDATES, R[9], t[3], c = cos(yaw), sn = sin(yaw);
    double Ry[9] = {c, 0, sn, 0, 1, 0, -sn, 0, c};
    memcpy(R, Ry, sizeof R);
    km__m3_apply(R, ct, t);
    for (int a = 0; a < 3; ++a)
      t[a] = cp[a] - sc * t[a];
    for (int it = 0; it < KM__ICP_ROUNDS; ++it) {
      place(r, R, sc, t, X);
      capped_residual(r, X, Q, nq);
      size_t m = 0;
      for (size_t i = 0; i < nq; ++i)
        if (r->ptri[i] >= 0) r->pw[m++] = r->pdist[i];
      if (m < 6) break;
      qsort(r->pw, m, sizeof(double), km__cmp_double);
      if (!icp_step(r, X, Q, nq, fmax(2.5 * r->pw[m / 2], 0.01), R, t)) break;
    }
    place(r, R, sc, t, X);
    double rigid = capped_residual(r, X, Q, nq);
    /* the skeletal step from this placement, as the first frame will run it */
    memcpy(r->base, X, nv * 3 * sizeof(double));
    for (size_t j = 0; j < nj; ++j) {
      km__m3_apply(R, r->tmpl_joints + 3 * j, r->base_joints + 3 * j);
      for (int a = 0; a < 3; ++a)
        r->base_joints[3 * j + a] = sc * r->base_joints[3 * j + a] + t[a];
      double *L = Lid + 9 * j;
      memset(L, 0, 9 * sizeof(double));
      L[0] = L[4] = L[8] = 1;
    }
    double zero[3] = {0, 0, 0}, posed = INFINITY, feet = 0, n_feet = 0;
    km_status ps = KM_OK;
    skeleton_fit(r, Q, fd->CN, nq, Lid, zero, r->o.skeleton_iterations, NULL, 0, true, r->o.w_pose,
                 &ps);
    if (ps == KM_OK) {
      posed = capped_residual(r, r->global, Q, nq);
      for (size_t i = 0; i < nq; ++i)
        if (Q[3 * i + 1] < plo + KM__FEET_HEIGHT * (phi - plo)) {
          feet += fmin(r->ptri[i] >= 0 ? r->pdist[i] : INFINITY, KM__RESIDUAL_CAP);
          ++n_feet;
        }
      feet = n_feet ? feet / n_feet : 0;
    }
    km__log(KM_LOG_DEBUG,
            "first frame: heading %3.0f deg: residual %.2f mm rigid, %.2f mm posed, feet %.2f mm",
            yaw * 180 / M_PI, rigid * 1e3, posed * 1e3, feet * 1e3);
    if (posed + feet < best) {
      best = posed + feet;
      r->init.residual_mm = posed * 1e3;
      r->init.feet_residual_mm = feet * 1e3;
      memcpy(Rbest, R, 9 * sizeof(double));
      memcpy(tbest, t, 3 * sizeof(double));
      r->init.yaw_deg = yaw * 180 / M_PI;
      r->init.rigid_residual_mm = rigid * 1e3;
    }
  }
  free(X), free(Lid);
  if (!isfinite(best))
    return km__fail(err, KM_ERR_NO_CONVERGENCE, "global alignment: no heading fits the points");
  *scbest = sc;
  r->init.yaw_candidates = KM__YAW_CANDIDATES;
  r->init.scale = sc;
  double tr = Rbest[0] + Rbest[4] + Rbest[8];
  r->init.rotation_deg = acos(fmax(-1, fmin(1, (tr - 1) / 2))) * 180 / M_PI;
  return KM_OK;
}

/* ---------------------------------------------------------------- limb search */

#define KM__LIMB_DIRECTIONS 160 /* bone directions tried per joint (about 16 degrees apart) */
#define KM__LIMB_CAP 0.10       /* m: a distance counts at most this much in the score */
#define KM__LIMB_BEND_MARGIN                                                                       \
  3e-4 /* m: the start at the template's bend is kept when its two-sided residual is lower than    \
        * the pose's start by this much (a near tie keeps the pose) */
#define KM__LIMB_STRONG 0.9        /* a direction this far below the score ... */
#define KM__LIMB_STRONG_SLACK 1.05 /* ... is turned unless the whole body's residual grows 5% */
#define KM__LIMB_GAIN 0.999 /* a searched direction is tried below this fraction of the score */

/* The limb chains of the skeleton: a joint whose parent branches (>= 2 children) and whose
 * subtree is a simple chain of at least 3 joints (shoulder -> elbow -> wrist -> hand,
 * hip -> knee -> ankle -> foot on the Kinect rig; any rig of that shape). chain[c*4 + k]:
 * the first two joints of chain c (searched) and the joint after them; returns the count. */
static int limb_chains(const km_recon *r, int32_t *chain, int max) {
  size_t nj = r->nj;
  int count = 0;
  for (size_t j = 1; j < nj && count < max; ++j) {
    int32_t p = r->parents[j];
    int children_p = 0;
    for (size_t k = 1; k < nj; ++k)
      children_p += r->parents[k] == p;
    if (children_p < 2) continue;
    int32_t cur = (int32_t)j, seq[3];
    int len = 0;
    bool simple = true;
    while (simple) {
      if (len < 3) seq[len] = cur;
      ++len;
      int32_t next = -1;
      int nc = 0;
      for (size_t k = (size_t)cur + 1; k < nj; ++k)
        if (r->parents[k] == cur) next = (int32_t)k, ++nc;
      if (nc == 0) break;
      if (nc > 1) simple = false;
      cur = next;
    }
    if (!simple || len < 3) continue;
    chain[4 * count] = seq[0], chain[4 * count + 1] = seq[1], chain[4 * count + 2] = seq[2];
    ++count;
  }
  return count;
}

/* Score of limb vertices Y (m of them) against the frame: surface -> points (each vertex to
 * its nearest point) plus points -> limb over the points U no other part explains (each to
 * its nearest limb vertex), distances capped. */
static double limb_score(const frame_data *fd, const double *Y, size_t m, const double *U,
                         const double *Urest, size_t nu, int32_t *idx, double *dist) {
  km__point_index_nearest(fd->ix, Y, m, KM__LIMB_CAP, idx, dist);
  double a = 0, b = 0;
  for (size_t i = 0; i < m; ++i)
    a += idx[i] >= 0 ? dist[i] : KM__LIMB_CAP;
  for (size_t u = 0; u < nu; ++u) {
    double best = Urest ? Urest[u] * Urest[u] : KM__LIMB_CAP * KM__LIMB_CAP;
    for (size_t i = 0; i < m; ++i) {
      double d[3] = {U[3 * u] - Y[3 * i], U[3 * u + 1] - Y[3 * i + 1], U[3 * u + 2] - Y[3 * i + 2]};
      double d2 = km__dot3(d, d);
      if (d2 < best) best = d2;
    }
    b += sqrt(best);
  }
  return a / (double)(m ? m : 1) + b / (double)(nu ? nu : 1);
}

/* Limbs found, not assumed: after the skeletal step of the first frame, each limb chain's
 * first joint (shoulder, hip) and then its second (elbow, knee) is turned so that its bone
 * points along the best of KM__LIMB_DIRECTIONS directions (a Fibonacci sphere, the current
 * one included), scored two-sided over the vertices of the joint's subtree (by the skin
 * weights' largest joint) and the points the rest of the body leaves unexplained (each at
 * most its distance to the rest of the body). A turn is kept where the whole body's
 * two-sided residual drops (or, for a direction below 90% of the score, grows less than
 * 5%: the skeletal step refines it); each chain is searched from two starts (its pose, and
 * its second joint at the template's bend), then both joints again, and the better start is
 * kept. A limb the local fit left outside its capture radius is thus put where its points
 * are; the skeletal step then refines it. Returns how many joints were turned. */
static int limb_search(km_recon *r, const frame_data *fd) {
  size_t nv = r->nv, nj = r->nj;
  int32_t chains[4 * 8];
  int nc = limb_chains(r, chains, 8);
  if (!nc || !fd->ix) return 0;
  int32_t *dom = km__malloc(nv, sizeof *dom), *idx = km__malloc(nv, sizeof *idx);
  double *W = km__malloc(nj, 9 * sizeof(double)), *cj = km__malloc(nj, 3 * sizeof(double));
  double *Y = km__malloc(nv, 3 * sizeof(double)), *Y0 = km__malloc(nv, 3 * sizeof(double));
  double *dist = km__malloc(nv, sizeof(double)), *U = km__malloc(fd->nc, 3 * sizeof(double));
  int32_t *sel = km__malloc(nv, sizeof *sel), *ptri = km__malloc(fd->nc, sizeof *ptri);
  double *pd = km__malloc(fd->nc, sizeof(double)), *Urest = km__malloc(fd->nc, sizeof(double));
  bool *in_sub = km__malloc(nj, sizeof *in_sub);
  int turned = 0;
  if (!dom || !idx || !W || !cj || !Y || !Y0 || !dist || !U || !sel || !ptri || !pd || !in_sub ||
      !Urest)
    goto out;
  for (size_t i = 0; i < nv; ++i) {
    dom[i] = dominant_joint(r, i);
  }
  double dirs[KM__LIMB_DIRECTIONS][3];
  for (int k = 0; k < KM__LIMB_DIRECTIONS; ++k) { /* Fibonacci sphere */
    double z = 1 - (2.0 * k + 1) / KM__LIMB_DIRECTIONS, rr = sqrt(fmax(0, 1 - z * z));
    double ph = k * M_PI * (3 - sqrt(5.0));
    dirs[k][0] = rr * cos(ph), dirs[k][1] = z, dirs[k][2] = rr * sin(ph);
  }
  double Lbest[18], Lstart[18], res_best = 0;
  for (int c = 0; c < nc; ++c) {
    for (int step = 0; step < 8; ++step) {
      /* two starts per chain: the current pose, then the second joint (elbow, knee) at the
       * template's own bend (a forearm the local fit folded back would otherwise hold the
       * upper arm where it is); each: the first joint, the second, then both again (the
       * kick of test_recon_report needs the second round). The start that explains the
       * frame better both ways is kept. */
      int32_t j0 = chains[4 * c], j1 = chains[4 * c + 1];
      int stage = step & 1;
      if (step == 0 || step == 4) {
        forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
        lbs_apply(r, r->G, r->base, r->global);
        double res = two_sided_residual(r, fd, r->global);
        if (step == 0) {
          memcpy(Lstart, r->Lrot + 9 * (size_t)j0, 9 * sizeof(double));
          memcpy(Lstart + 9, r->Lrot + 9 * (size_t)j1, 9 * sizeof(double));
          memcpy(Lbest, Lstart, sizeof Lbest);
          res_best = res;
        } else {
          if (res < res_best) {
            res_best = res;
            memcpy(Lbest, r->Lrot + 9 * (size_t)j0, 9 * sizeof(double));
            memcpy(Lbest + 9, r->Lrot + 9 * (size_t)j1, 9 * sizeof(double));
          }
          memcpy(r->Lrot + 9 * (size_t)j0, Lstart, 9 * sizeof(double));
          double *L1 = r->Lrot + 9 * (size_t)j1;
          memset(L1, 0, 9 * sizeof(double));
          L1[0] = L1[4] = L1[8] = 1;
        }
      }
      int32_t j = chains[4 * c + stage], child = chains[4 * c + stage + 1];
      forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
      lbs_apply(r, r->G, r->base, r->global);
      /* the joint's subtree: its vertices move with it */
      for (size_t k = 0; k < nj; ++k)
        in_sub[k] =
            (int32_t)k == j || (k > (size_t)j && r->parents[k] >= 0 && in_sub[r->parents[k]]);
      /* scored: the first joint from the pose by its own segment alone (upper arm, thigh:
       * the joint below is not placed yet), otherwise by the whole subtree */
      size_t m = 0, all = 0;
#define KM__LIMB_SCORED(i) (dom[i] >= 0 && (step != 0 ? in_sub[dom[i]] : dom[i] == j))
      for (size_t i = 0; i < nv; ++i)
        if (KM__LIMB_SCORED(i)) ++all;
      size_t stride = all > 300 ? all / 300 + 1 : 1, cnt = 0;
      for (size_t i = 0; i < nv; ++i)
        if (KM__LIMB_SCORED(i) && cnt++ % stride == 0) sel[m++] = (int32_t)i;
#undef KM__LIMB_SCORED
      if (m < 8) continue;
      /* points unexplained by the rest of the body: farther than 2 cm from the surface, or
       * closest to a triangle of this subtree */
      km__surface_update(r->query, r->global);
      km__surface_closest(r->query, fd->C, fd->nc, 0, ptri, NULL, pd);
      size_t nu = 0;
      for (size_t q = 0; q < fd->nc; ++q) {
        int32_t v0 = ptri[q] >= 0 ? r->tmpl.F[3 * (size_t)ptri[q]] : -1;
        bool mine = v0 >= 0 && dom[v0] >= 0 && in_sub[dom[v0]];
        if (pd[q] > 0.02 || mine) memcpy(U + 3 * nu++, fd->C + 3 * q, 3 * sizeof(double));
      }
      /* each such point counts at most its distance to the rest of the body: a template
       * slimmer than the subject leaves the torso's points unexplained too, and a limb must
       * not win by lying on them (on FAUST tr_reg_000 the left arm stayed folded onto the
       * torso of D-FAUST's subject while the subject held it out) */
      size_t nrest = 0;
      for (size_t i = 0; i < nv; ++i)
        if (!(dom[i] >= 0 && in_sub[dom[i]]))
          memcpy(Y + 3 * nrest++, r->global + 3 * i, 3 * sizeof(double));
      bool have_rest = false;
      if (nrest >= 8 && nu) {
        km__point_index *rix = NULL;
        if (km__point_index_create(Y, nrest, &rix, NULL) == KM_OK) {
          km__point_index_nearest(rix, U, nu, KM__LIMB_CAP, ptri, Urest);
          for (size_t u = 0; u < nu; ++u)
            if (ptri[u] < 0) Urest[u] = KM__LIMB_CAP;
          have_rest = true;
        }
        km__point_index_free(&rix);
      }
      const double *ur = have_rest ? Urest : NULL;
      for (size_t k = 0; k < m; ++k)
        memcpy(Y0 + 3 * k, r->global + 3 * (size_t)sel[k], 3 * sizeof(double));
      double bone[3] = {cj[3 * child] - cj[3 * j], cj[3 * child + 1] - cj[3 * j + 1],
                        cj[3 * child + 2] - cj[3 * j + 2]};
      if (km__normalize3(bone) < 1e-9) continue;
      double score0 = limb_score(fd, Y0, m, U, ur, nu, idx, dist), best = score0;
      double Rbest[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      for (int k = 0; k < KM__LIMB_DIRECTIONS; ++k) {
        double axis[3], R[9];
        km__cross3(bone, dirs[k], axis);
        double sn = km__normalize3(axis), cs = km__dot3(bone, dirs[k]);
        if (sn < 1e-9) continue;
        double ang = atan2(sn, cs), rv[3] = {axis[0] * ang, axis[1] * ang, axis[2] * ang};
        km__m3_from_rotvec(rv, R);
        for (size_t i = 0; i < m; ++i) {
          double d[3] = {Y0[3 * i] - cj[3 * j], Y0[3 * i + 1] - cj[3 * j + 1],
                         Y0[3 * i + 2] - cj[3 * j + 2]};
          km__m3_apply(R, d, Y + 3 * i);
          for (int a = 0; a < 3; ++a)
            Y[3 * i + a] += cj[3 * j + a];
        }
        double sc = limb_score(fd, Y, m, U, ur, nu, idx, dist);
        if (sc < best) best = sc, memcpy(Rbest, R, sizeof Rbest);
      }
      km__log(KM_LOG_DEBUG, "first frame: limb search %s: score %.1f -> %.1f mm", r->names[j],
              score0 * 1e3, best * 1e3);
      if (!(best < KM__LIMB_GAIN * score0)) continue;
      /* world rotation Rbest about the joint: W_j' = Rbest W_j, so L_j' = W_p^T Rbest W_p L_j */
      int32_t p = r->parents[j];
      double Wp[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, Wpt[9], T[9], L2[9], Lkeep[9];
      if (p >= 0) memcpy(Wp, W + 9 * (size_t)p, sizeof Wp);
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          Wpt[3 * a + b] = Wp[3 * b + a];
      km__m3_mul(Wpt, Rbest, T);
      km__m3_mul(T, Wp, L2);
      km__m3_mul(L2, r->Lrot + 9 * (size_t)j, T);
      memcpy(Lkeep, r->Lrot + 9 * (size_t)j, sizeof Lkeep);
      memcpy(r->Lrot + 9 * (size_t)j, T, sizeof T);
      orthonormalize(r->Lrot + 9 * (size_t)j);
      /* a turn is kept only when the whole body explains the frame better both ways: the
       * limb's own score can prefer a leg folded onto the belly of a subject stouter than
       * the template, which the rest of the body's points then contradict */
      double before = two_sided_residual(r, fd, r->global);
      forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
      lbs_apply(r, r->G, r->base, r->global);
      double after = two_sided_residual(r, fd, r->global);
      /* a turn the limb's score clearly wants may cost the whole body a little before the
       * skeletal step refines it (the raised knee of a kick) */
      bool keep = after < before ||
                  (best < KM__LIMB_STRONG * score0 && after < KM__LIMB_STRONG_SLACK * before);
      km__log(KM_LOG_DEBUG, "limb search %s: two-sided %.2f -> %.2f mm%s", r->names[j],
              before * 1e3, after * 1e3, keep ? "" : " (not turned)");
      if (!keep) {
        memcpy(r->Lrot + 9 * (size_t)j, Lkeep, sizeof Lkeep);
        forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
        lbs_apply(r, r->G, r->base, r->global);
        continue;
      }
    }
    int32_t j0 = chains[4 * c], j1 = chains[4 * c + 1];
    forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
    lbs_apply(r, r->G, r->base, r->global);
    double res = two_sided_residual(r, fd, r->global);
    bool bend = res < res_best - KM__LIMB_BEND_MARGIN;
    if (!bend) {
      memcpy(r->Lrot + 9 * (size_t)j0, Lbest, 9 * sizeof(double));
      memcpy(r->Lrot + 9 * (size_t)j1, Lbest + 9, 9 * sizeof(double));
    }
    km__log(KM_LOG_DEBUG, "limb search %s: start %s kept (two-sided %.2f, %.2f mm)", r->names[j0],
            bend ? "at the template's bend" : "from the pose", res_best * 1e3, res * 1e3);
    turned += (memcmp(r->Lrot + 9 * (size_t)j0, Lstart, 9 * sizeof(double)) != 0) +
              (memcmp(r->Lrot + 9 * (size_t)j1, Lstart + 9, 9 * sizeof(double)) != 0);
  }
  forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
  memcpy(r->joints, cj, nj * 3 * sizeof(double));
  lbs_apply(r, r->G, r->base, r->global);
out:
  free(dom), free(idx), free(W), free(cj), free(Y), free(Y0), free(dist), free(U), free(sel);
  free(ptri), free(pd), free(in_sub), free(Urest);
  return turned;
}

/* ---------------------------------------------------------------- bone lengths */

#define KM__BONE_SCALE_MIN 0.80 /* bone length scales searched, relative to the template's */
#define KM__BONE_SCALE_MAX 1.25
#define KM__BONE_SCALE_STEP 0.025
#define KM__BONE_SEGMENT 0.075 /* each segment's scale within this of the chain's */
#define KM__BONE_GAIN 0.97
#define KM__BONE_ROUNDS                                                                            \
  3 /* length search and skeletal step alternate (a pose fitted with
                           * the wrong lengths bends the limb to reach its points) */ /* a limb's scales are kept only below this fraction of its score */

/* The template's bones stretched in the unposed base: joint k's segment (the bone from J_k to
 * its single child, or for a leaf the part beyond J_k along the bone into it) is scaled by
 * s[k] along the bone, everything below it follows. Every vertex moves by its skin weights'
 * blend of the joints' displacement fields D_k(x) = T_k + (s_k - 1) clamp((x - J_k).u_k, 0,
 * L_k) u_k (T_k: how far J_k moved), so the girth stays and blended regions stay smooth.
 * B0/J0: the unstretched base and joints; B/J: the result. */
static void stretch_base(const km_recon *r, const double *s, const double *B0, const double *J0,
                         double *B, double *J, double *U /* nj*3 */, double *Lb /* nj */,
                         double *T /* nj*3 */) {
  size_t nj = r->nj, nv = r->nv;
  for (size_t k = 0; k < nj; ++k) {
    int32_t child = -1;
    int nc = 0;
    for (size_t c = k + 1; c < nj; ++c)
      if (r->parents[c] == (int32_t)k) child = (int32_t)c, ++nc;
    double u[3] = {0, 0, 0}, len = 0;
    if (nc == 1) {
      for (int a = 0; a < 3; ++a)
        u[a] = J0[3 * (size_t)child + a] - J0[3 * k + a];
      len = km__normalize3(u);
    } else if (nc == 0 && r->parents[k] >= 0) {
      size_t p = (size_t)r->parents[k];
      for (int a = 0; a < 3; ++a)
        u[a] = J0[3 * k + a] - J0[3 * p + a];
      km__normalize3(u);
      len = INFINITY;
    }
    memcpy(U + 3 * k, u, sizeof u);
    Lb[k] = len;
    int32_t p = r->parents[k];
    for (int a = 0; a < 3; ++a)
      J[3 * k + a] = p < 0 ? J0[3 * k + a]
                           : J[3 * (size_t)p + a] + s[p] * (J0[3 * k + a] - J0[3 * (size_t)p + a]);
    for (int a = 0; a < 3; ++a)
      T[3 * k + a] = J[3 * k + a] - J0[3 * k + a];
  }
  for (size_t i = 0; i < nv; ++i) {
    const double *x = B0 + 3 * i;
    double d[3] = {0, 0, 0};
    for (int q = 0; q < 4; ++q) {
      int32_t k = r->skin.joints[4 * i + q];
      double w = r->skin.weights[4 * i + q];
      if (k < 0 || w == 0) continue;
      const double *u = U + 3 * (size_t)k, *jk = J0 + 3 * (size_t)k;
      double t = 0;
      if (s[k] != 1 && Lb[k] > 0) {
        t = (x[0] - jk[0]) * u[0] + (x[1] - jk[1]) * u[1] + (x[2] - jk[2]) * u[2];
        t = t < 0 ? 0 : t > Lb[k] ? Lb[k] : t;
        t *= s[k] - 1;
      }
      for (int a = 0; a < 3; ++a)
        d[a] += w * (T[3 * (size_t)k + a] + t * u[a]);
    }
    for (int a = 0; a < 3; ++a)
      B[3 * i + a] = x[a] + d[a];
  }
}

/* Bone lengths found, not assumed: a template whose limbs are longer or shorter than the
 * subject's would keep the excess (a hand reaching 8 cm past the fingertips). After the
 * pose of the first frame, each limb chain's three segments (upper arm, forearm, hand;
 * thigh, shin, foot) are stretched along their bones by the best of the scales
 * KM__BONE_SCALE_MIN..MAX (coordinate descent, two sweeps), scored two-sided like the limb
 * search (limb_score), in the current pose. The stretch goes into r->base / r->base_joints;
 * returns how many limbs changed, scales per chain segment in scales_out (3 per chain). */
static int bone_lengths(km_recon *r, const frame_data *fd, double *scales_out, int max_chains) {
  size_t nv = r->nv, nj = r->nj;
  int32_t chains[4 * 8];
  int nc = limb_chains(r, chains, 8);
  if (nc > max_chains) nc = max_chains;
  if (!nc || !fd->ix) return 0;
  double *B0 = km__malloc(nv, 3 * sizeof(double)), *J0 = km__malloc(nj, 3 * sizeof(double));
  double *s = km__malloc(nj, sizeof(double)), *Ub = km__malloc(nj, 3 * sizeof(double));
  double *Lb = km__malloc(nj, sizeof(double)), *Tb = km__malloc(nj, 3 * sizeof(double));
  double *W = km__malloc(nj, 9 * sizeof(double)), *cj = km__malloc(nj, 3 * sizeof(double));
  double *Y = km__malloc(nv, 3 * sizeof(double)), *dist = km__malloc(nv, sizeof(double));
  double *U = km__malloc(fd->nc, 3 * sizeof(double)), *pd = km__malloc(fd->nc, sizeof(double));
  int32_t *dom = km__malloc(nv, sizeof *dom), *idx = km__malloc(nv, sizeof *idx);
  int32_t *sel = km__malloc(nv, sizeof *sel), *ptri = km__malloc(fd->nc, sizeof *ptri);
  bool *in_sub = km__malloc(nj, sizeof *in_sub);
  int changed = 0;
  if (!B0 || !J0 || !s || !Ub || !Lb || !Tb || !W || !cj || !Y || !dist || !U || !pd || !dom ||
      !idx || !sel || !ptri || !in_sub)
    goto out;
  memcpy(B0, r->base, nv * 3 * sizeof(double));
  memcpy(J0, r->base_joints, nj * 3 * sizeof(double));
  for (size_t k = 0; k < nj; ++k)
    s[k] = 1;
  for (size_t i = 0; i < nv; ++i) {
    dom[i] = dominant_joint(r, i);
  }
  for (int c = 0; c < nc; ++c) {
    int32_t j = chains[4 * c];
    for (size_t k = 0; k < nj; ++k)
      in_sub[k] = (int32_t)k == j || (k > (size_t)j && r->parents[k] >= 0 && in_sub[r->parents[k]]);
    size_t m = 0, all = 0;
    for (size_t i = 0; i < nv; ++i)
      all += dom[i] >= 0 && in_sub[dom[i]];
    size_t stride = all > 1000 ? all / 1000 + 1 : 1, cnt = 0;
    for (size_t i = 0; i < nv; ++i)
      if (dom[i] >= 0 && in_sub[dom[i]] && cnt++ % stride == 0) sel[m++] = (int32_t)i;
    if (m < 8) continue;
    /* the points the rest of the body leaves unexplained, in the current pose */
    forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
    lbs_apply(r, r->G, r->base, r->global);
    km__surface_update(r->query, r->global);
    km__surface_closest(r->query, fd->C, fd->nc, 0, ptri, NULL, pd);
    size_t nu = 0;
    for (size_t q = 0; q < fd->nc; ++q) {
      int32_t v0 = ptri[q] >= 0 ? r->tmpl.F[3 * (size_t)ptri[q]] : -1;
      bool mine = v0 >= 0 && dom[v0] >= 0 && in_sub[dom[v0]];
      if (pd[q] > 0.02 || mine) memcpy(U + 3 * nu++, fd->C + 3 * q, 3 * sizeof(double));
    }
    if (nu < 8) {
      km__log(KM_LOG_DEBUG, "first frame: bone lengths %s: %zu unexplained points", r->names[j],
              nu);
      continue;
    }
    /* segments: chain[0], chain[1], chain[2] with everything below it */
    double seg[3] = {1, 1, 1};
#define KM__SET_SCALES()                                                                           \
  for (size_t k = 0; k < nj; ++k)                                                                  \
    if (in_sub[k])                                                                                 \
      s[k] = (int32_t)k == chains[4 * c]       ? seg[0]                                            \
             : (int32_t)k == chains[4 * c + 1] ? seg[1]                                            \
                                               : seg[2];
    KM__SET_SCALES();
    stretch_base(r, s, B0, J0, r->base, r->base_joints, Ub, Lb, Tb);
    for (size_t k = 0; k < m; ++k)
      memcpy(Y + 3 * k, r->global + 3 * (size_t)sel[k], 3 * sizeof(double));
    double score0 = limb_score(fd, Y, m, U, NULL, nu, idx, dist), best = score0;
    /* one scale for the whole chain first (a straight limb cannot tell where its elbow is
     * from its length alone), then each segment within KM__BONE_SEGMENT of it */
    for (int g = -1; g < 3; ++g) {
      double keep = g < 0 ? 1 : seg[g];
      double lo = g < 0 ? KM__BONE_SCALE_MIN : keep - KM__BONE_SEGMENT,
             hi = g < 0 ? KM__BONE_SCALE_MAX : keep + KM__BONE_SEGMENT;
      for (double v = lo; v <= hi + 1e-9; v += KM__BONE_SCALE_STEP) {
        if (fabs(v - keep) < 1e-9) continue;
        if (g < 0)
          seg[0] = seg[1] = seg[2] = v;
        else
          seg[g] = v;
        KM__SET_SCALES();
        stretch_base(r, s, B0, J0, r->base, r->base_joints, Ub, Lb, Tb);
        forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
        lbs_apply(r, r->G, r->base, r->global);
        for (size_t k = 0; k < m; ++k)
          memcpy(Y + 3 * k, r->global + 3 * (size_t)sel[k], 3 * sizeof(double));
        double sc = limb_score(fd, Y, m, U, NULL, nu, idx, dist);
        if (sc < best) best = sc, keep = v;
      }
      if (g < 0)
        seg[0] = seg[1] = seg[2] = keep;
      else
        seg[g] = keep;
    }
    bool take = best < KM__BONE_GAIN * score0;
    km__log(KM_LOG_DEBUG, "first frame: bone lengths %s: %.3f %.3f %.3f, score %.1f -> %.1f mm%s",
            r->names[j], seg[0], seg[1], seg[2], score0 * 1e3, best * 1e3, take ? "" : " (kept)");
    if (!take) seg[0] = seg[1] = seg[2] = 1;
    KM__SET_SCALES();
#undef KM__SET_SCALES
    if (scales_out) memcpy(scales_out + 3 * c, seg, sizeof seg);
    changed += take;
    stretch_base(r, s, B0, J0, r->base, r->base_joints, Ub, Lb, Tb);
  }
  forward_kinematics(r, r->Lrot, r->troot, W, cj, r->G);
  memcpy(r->joints, cj, nj * 3 * sizeof(double));
  lbs_apply(r, r->G, r->base, r->global);
out:
  free(B0), free(J0), free(s), free(Ub), free(Lb), free(Tb), free(W), free(cj), free(Y);
  free(dist), free(U), free(pd), free(dom), free(idx), free(sel), free(ptri), free(in_sub);
  return changed;
}

km_status km__recon_affine_register(km_recon *r, const double *Vb, const double *P, size_t n,
                                    const km_recon_feature *feat, size_t nfeat, int iterations,
                                    km_error *err) {
  if (!r || !Vb || !P || (!feat && nfeat) || iterations < 1)
    return km__fail(err, KM_ERR_INVALID, "km__recon_affine_register: bad argument");
  frame_data fd;
  km_status s = frame_prepare(r, P, n, &fd, err);
  int count = 0;
  if (!s) s = refine(r, &fd, Vb, iterations, feat, nfeat, r->o.w_feature, 0.1, 0.7, &count, err);
  frame_data_free(&fd);
  return s;
}

km_status km_recon_first_frame(km_recon *r, const double *P, size_t n, const km_recon_feature *feat,
                               size_t nfeat, km_recon_frame_stats *st, km_error *err) {
  if (!r || (!P && n) || (!feat && nfeat))
    return km__fail(err, KM_ERR_INVALID, "km_recon_first_frame: NULL argument");
  double t0 = km_seconds();
  km_recon_frame_stats local = {0};
  if (!st) st = &local;
  memset(st, 0, sizeof *st);
  st->points = n;
  memset(&r->init, 0, sizeof r->init);
  r->init.correspondences = nfeat;
  size_t nv = r->nv, nj = r->nj;
  memset(r->part_lost, 0, nj * sizeof *r->part_lost);
  for (size_t k = 0; k < nfeat; ++k)
    if (feat[k].vertex < 0 || (size_t)feat[k].vertex >= nv)
      return km__fail(err, KM_ERR_INVALID, "feature %zu: vertex %d out of range (%zu vertices)", k,
                      feat[k].vertex, nv);
  frame_data fd;
  km_status s = frame_prepare(r, P, n, &fd, err);
  if (s) {
    frame_data_free(&fd);
    return s;
  }
  /* 1. global similarity: km_similarity_fit (rigid) on the features, else centroid + height */
  double R[9], t[3], sc = 1;
  if (nfeat >= 3) {
    double *A = km__malloc(nfeat, 3 * sizeof(double)), *B = km__malloc(nfeat, 3 * sizeof(double));
    if (!A || !B) {
      free(A), free(B), frame_data_free(&fd);
      return km__fail(err, KM_ERR_NOMEM, "out of memory");
    }
    for (size_t k = 0; k < nfeat; ++k) {
      memcpy(A + 3 * k, r->tmpl.V + 3 * (size_t)feat[k].vertex, 3 * sizeof(double));
      memcpy(B + 3 * k, feat[k].point, 3 * sizeof(double));
    }
    /* rigid only here: with the subject in another pose than the template, a scale from
     * unposed landmarks is biased (arms out vs. arms in); scale comes after posing */
    s = km_similarity_fit(A, B, NULL, nfeat, false, NULL, R, t, err);
    free(A), free(B);
    if (s) {
      frame_data_free(&fd);
      return km__wrap(err, s, "first frame: global alignment from %zu features", nfeat);
    }
  } else {
    s = global_alignment(r, &fd, R, t, &sc, err);
    if (s) {
      frame_data_free(&fd);
      return km__wrap(err, s, "first frame");
    }
  }
  double *V1 = km__malloc(nv, 3 * sizeof(double));
  if (!V1) {
    frame_data_free(&fd);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t i = 0; i < nv; ++i) {
    km__m3_apply(R, r->tmpl.V + 3 * i, V1 + 3 * i);
    for (int a = 0; a < 3; ++a)
      V1[3 * i + a] = sc * V1[3 * i + a] + t[a];
  }
  for (size_t j = 0; j < nj; ++j) {
    km__m3_apply(R, r->tmpl_joints + 3 * j, r->base_joints + 3 * j);
    for (int a = 0; a < 3; ++a)
      r->base_joints[3 * j + a] = sc * r->base_joints[3 * j + a] + t[a];
  }
  memcpy(r->base, V1, nv * 3 * sizeof(double));
  /* 2. pose: the skeletal step on the aligned template (the subject need not stand exactly
   * in the template's pose) */
  for (size_t j = 0; j < nj; ++j) {
    double *L = r->Lrot + 9 * j;
    memset(L, 0, 9 * sizeof(double));
    L[0] = L[4] = L[8] = 1;
  }
  double zero[3] = {0, 0, 0};
  km_status ps = KM_OK;
  double *Lid = km__malloc(nj, 9 * sizeof(double));
  if (!Lid) {
    free(V1), frame_data_free(&fd);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  memcpy(Lid, r->Lrot, nj * 9 * sizeof(double));
  /* Features drive the pose first (the subject may stand far from the template's pose);
   * the similarity is then re-estimated against the posed landmarks, which removes the bias
   * a pose difference puts into the fitted scale and rotation; then features and data. */
  if (nfeat >= 3) {
    double *A = km__malloc(nfeat, 3 * sizeof(double)), *B = km__malloc(nfeat, 3 * sizeof(double));
    for (int pass = 0; pass < 3 && A && B; ++pass) {
      ps = KM_OK;
      st->iterations += skeleton_fit(r, fd.C, fd.CN, fd.nc, Lid, zero, 2, feat, nfeat, false,
                                     KM__FIRST_FRAME_POSE_WEIGHT, &ps);
      if (ps != KM_OK) break;
      memcpy(Lid, r->Lrot, nj * 9 * sizeof(double));
      for (size_t k = 0; k < nfeat; ++k) {
        memcpy(A + 3 * k, r->global + 3 * (size_t)feat[k].vertex, 3 * sizeof(double));
        memcpy(B + 3 * k, feat[k].point, 3 * sizeof(double));
      }
      double R2[9], t2[3], s2 = 1;
      if (km_similarity_fit(A, B, NULL, nfeat, true, &s2, R2, t2, NULL) != KM_OK) break;
      /* the similarity goes into the unposed base; the root offset follows it */
      for (size_t i = 0; i < nv; ++i) {
        km__m3_apply(R2, r->base + 3 * i, r->base + 3 * i);
        for (int a = 0; a < 3; ++a)
          r->base[3 * i + a] = s2 * r->base[3 * i + a] + t2[a];
      }
      for (size_t j = 0; j < nj; ++j) {
        km__m3_apply(R2, r->base_joints + 3 * j, r->base_joints + 3 * j);
        for (int a = 0; a < 3; ++a)
          r->base_joints[3 * j + a] = s2 * r->base_joints[3 * j + a] + t2[a];
      }
      km__m3_apply(R2, r->troot, zero);
      for (int a = 0; a < 3; ++a)
        zero[a] *= s2;
    }
    free(A), free(B);
    ps = KM_OK;
  }
  /* with features the fitted pose is trusted: data refines it under a stronger tie */
  st->iterations +=
      skeleton_fit(r, fd.C, fd.CN, fd.nc, Lid, zero, r->o.skeleton_iterations, feat, nfeat, true,
                   nfeat >= 3 ? KM__FIRST_FRAME_POSE_WEIGHT : r->o.w_pose, &ps);
  /* limbs found, not assumed: a limb the local fit could not reach is searched for, then
   * the skeletal step refines from there */
  if (ps == KM_OK && !r->o.no_limb_search) {
    /* the pose before the search, kept when the search does not explain the points better
     * both ways (on FAUST tr_reg_000 rigged by kinemesh rig the search folded a leg into the
     * pelvis: D-FAUST p99 70 mm, every frame flagged; 27 mm without it) */
    double *keepL = km__malloc(nj, 9 * sizeof(double));
    double keept[3] = {r->troot[0], r->troot[1], r->troot[2]};
    double before = keepL ? two_sided_residual(r, &fd, r->global) : 0;
    if (keepL) memcpy(keepL, r->Lrot, nj * 9 * sizeof(double));
    int turned = limb_search(r, &fd);
    if (turned) {
      memcpy(Lid, r->Lrot, nj * 9 * sizeof(double));
      double t1[3] = {r->troot[0], r->troot[1], r->troot[2]};
      st->iterations +=
          skeleton_fit(r, fd.C, fd.CN, fd.nc, Lid, t1, r->o.skeleton_iterations, feat, nfeat, true,
                       nfeat >= 3 ? KM__FIRST_FRAME_POSE_WEIGHT : r->o.w_pose, &ps);
      double after = keepL && ps == KM_OK ? two_sided_residual(r, &fd, r->global) : INFINITY;
      km__log(KM_LOG_DEBUG, "first frame: limb search: two-sided residual %.2f -> %.2f mm, %s",
              before * 1e3, after * 1e3, after < before ? "kept" : "not kept");
      if (keepL && !(after < before)) {
        memcpy(r->Lrot, keepL, nj * 9 * sizeof(double));
        memcpy(r->troot, keept, sizeof keept);
        forward_kinematics(r, r->Lrot, r->troot, r->work, r->work + 9 * nj, r->G);
        memcpy(r->joints, r->work + 9 * nj, nj * 3 * sizeof(double));
        lbs_apply(r, r->G, r->base, r->global);
        turned = 0;
        ps = KM_OK;
      }
    }
    free(keepL);
    r->init.limbs_turned = (size_t)turned;
    /* bone lengths: the limbs stretched to the subject's in the found pose, then the
     * skeletal step once more */
    int scaled = 0;
    for (int round = 0; round < KM__BONE_ROUNDS; ++round) {
      int sc = bone_lengths(r, &fd, NULL, 8);
      if (!sc) break;
      scaled = sc > scaled ? sc : scaled;
      memcpy(Lid, r->Lrot, nj * 9 * sizeof(double));
      double t1[3] = {r->troot[0], r->troot[1], r->troot[2]};
      st->iterations +=
          skeleton_fit(r, fd.C, fd.CN, fd.nc, Lid, t1, r->o.skeleton_iterations, feat, nfeat, true,
                       nfeat >= 3 ? KM__FIRST_FRAME_POSE_WEIGHT : r->o.w_pose, &ps);
    }
    r->init.limbs_scaled = (size_t)scaled;
  }
  free(Lid);
  if (ps != KM_OK) {
    /* keep the aligned template */
    memcpy(r->global, V1, nv * 3 * sizeof(double));
    memcpy(r->joints, r->base_joints, nj * 3 * sizeof(double));
  }
  /* 3. affine registration: features + smoothness, then all three terms */
  memcpy(V1, r->global, nv * 3 * sizeof(double));
  /* Without correspondences the template's landmarks on the posed surface, matched to their
   * closest points, are the features of the w_d = 0 stage. Only there: a closest point is
   * no true correspondence, and at w_f = 10 it would hold the surface against the data in
   * the later stage. */
  const km_recon_feature *f1 = feat;
  size_t nf1 = nfeat;
  km_recon_feature *pseudo = NULL;
  if (nfeat < 3 && r->n_lm) {
    pseudo = km__malloc(nfeat + r->n_lm, sizeof *pseudo);
    km__point_index *ix = NULL;
    s = pseudo ? km__point_index_create(fd.P, fd.n, &ix, err)
               : km__fail(err, KM_ERR_NOMEM, "out of memory");
    if (s) {
      free(pseudo);
      goto fail;
    }
    if (nfeat) memcpy(pseudo, feat, nfeat * sizeof *pseudo);
    size_t m = nfeat;
    for (size_t l = 0; l < r->n_lm; ++l) {
      int32_t idx;
      double d;
      km__point_index_nearest(ix, r->global + 3 * (size_t)r->lm[l], 1, KM__LANDMARK_REACH, &idx,
                              &d);
      if (idx < 0) continue; /* hidden from every camera, or posed away from the template */
      pseudo[m].vertex = r->lm[l];
      memcpy(pseudo[m].point, fd.P + 3 * (size_t)idx, 3 * sizeof(double));
      ++m;
    }
    km__point_index_free(&ix);
    r->init.landmarks = m - nfeat;
    f1 = pseudo, nf1 = m;
  }
  if (nf1) {
    /* feature term alone is linear: one solve */
    for (size_t i = 0; i < n; ++i)
      r->pw[i] = 0;
    s = affine_solve(r, V1, fd.C, 0, 0, f1, nf1, r->o.w_feature, NULL, NULL, r->surface, err);
    ++st->iterations;
    if (!s) memcpy(V1, r->surface, nv * 3 * sizeof(double));
  }
  free(pseudo);
  if (s) goto fail;
  s = refine(r, &fd, V1, r->o.first_iterations, feat, nfeat, r->o.w_feature, 0.1, 0.7,
             &st->iterations, err);
  if (s) goto fail;
  /* 4. the registered surface is the template for the rest: joints carried by the skinned
   * vertices' affine maps */
  for (size_t j = 0; j < nj; ++j) {
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (size_t i = 0; i < nv; ++i)
      for (int k = 0; k < 4; ++k)
        if (r->skin.joints[4 * i + k] == (int32_t)j && r->skin.weights[4 * i + k] > 0.3) {
          double q[3];
          affine_apply(r, V1, i, r->joints + 3 * j, q);
          double w = r->skin.weights[4 * i + k];
          for (int a = 0; a < 3; ++a)
            acc[a] += w * q[a];
          wsum += w;
        }
    if (wsum > 0)
      for (int a = 0; a < 3; ++a)
        r->joints[3 * j + a] = acc[a] / wsum;
  }
  hold_still(r, r->surface);
  memcpy(r->base, r->surface, nv * 3 * sizeof(double));
  memcpy(r->base_joints, r->joints, nj * 3 * sizeof(double));
  memcpy(r->global, r->surface, nv * 3 * sizeof(double));
  for (size_t j = 0; j < nj; ++j) {
    double *L = r->Lrot + 9 * j;
    memset(L, 0, 9 * sizeof(double));
    L[0] = L[4] = L[8] = 1;
  }
  memcpy(r->Lprev, r->Lrot, nj * 9 * sizeof(double));
  memcpy(r->Lprev2, r->Lrot, nj * 9 * sizeof(double));
  memset(r->troot, 0, sizeof r->troot);
  memset(r->tprev, 0, sizeof r->tprev);
  memset(r->tprev2, 0, sizeof r->tprev2);
  forward_kinematics(r, r->Lrot, r->troot, r->work, r->work + 9 * nj, r->G);
  r->have_base = true;
  r->frame = 1;
  frame_error(r, &fd, r->surface, st);
  st->status = KM_OK;
  st->seconds = km_seconds() - t0;
  r->n_hist = 0;
  free(V1);
  frame_data_free(&fd);
  return KM_OK;
fail:
  free(V1);
  frame_data_free(&fd);
  return s;
}

/* Later frames: a part that became unsupported (tracking lost a limb) is searched again from
 * the current pose, as on the first frame (limb_search), then the skeletal step and the
 * surface refinement run again. The new pose is kept only when it leaves fewer unsupported
 * vertices AND explains the points better (points -> surface mean below 90%): a limb hidden
 * from the cameras has no points to find, and must stay flagged rather than be laid onto
 * the torso's points. */
static void research_limbs(km_recon *r, const frame_data *fd, km_recon_frame_stats *st,
                           km_status *fs) {
  size_t nv = r->nv, nj = r->nj;
  double *save = km__malloc(nj * 9 + 3 + nv * 6 + nj * 3, sizeof(double));
  if (!save) return;
  double *sL = save, *sT = sL + nj * 9, *sG = sT + 3, *sS = sG + nv * 3, *sJ = sS + nv * 3;
  memcpy(sL, r->Lrot, nj * 9 * sizeof(double));
  memcpy(sT, r->troot, 3 * sizeof(double));
  memcpy(sG, r->global, nv * 3 * sizeof(double));
  memcpy(sS, r->surface, nv * 3 * sizeof(double));
  memcpy(sJ, r->joints, nj * 3 * sizeof(double));
  km_recon_frame_stats before = *st;
  int turned = limb_search(r, fd);
  bool keep = false;
  if (turned) {
    double *Lref = km__malloc(nj, 9 * sizeof(double));
    km_status ps = Lref ? KM_OK : KM_ERR_NOMEM;
    if (Lref) {
      memcpy(Lref, r->Lrot, nj * 9 * sizeof(double));
      double t1[3] = {r->troot[0], r->troot[1], r->troot[2]};
      st->iterations += skeleton_fit(r, fd->C, fd->CN, fd->nc, Lref, t1, r->o.skeleton_iterations,
                                     NULL, 0, true, r->o.w_pose, &ps);
      free(Lref);
    }
    km_error e2;
    if (ps == KM_OK)
      ps = refine(r, fd, r->global, r->o.refine_iterations, NULL, 0, 0, 0.03, 0.5, &st->iterations,
                  &e2);
    for (size_t i = 0; ps == KM_OK && i < nv * 3; ++i)
      if (!isfinite(r->surface[i])) ps = KM_ERR_NO_CONVERGENCE;
    if (ps == KM_OK) {
      frame_error(r, fd, r->surface, st);
      keep = st->unsupported_vertices < before.unsupported_vertices &&
             st->mean_mm < 0.9 * before.mean_mm;
    }
  }
  km__log(KM_LOG_DEBUG, "frame %zu: unsupported (%zu vertices): %d joints searched again, %s",
          r->frame, before.unsupported_vertices, turned, keep ? "kept" : "not kept");
  if (!keep) {
    int it = st->iterations;
    memcpy(r->Lrot, sL, nj * 9 * sizeof(double));
    memcpy(r->troot, sT, 3 * sizeof(double));
    memcpy(r->global, sG, nv * 3 * sizeof(double));
    memcpy(r->surface, sS, nv * 3 * sizeof(double));
    memcpy(r->joints, sJ, nj * 3 * sizeof(double));
    double *W = r->work; /* the transforms of the kept pose */
    forward_kinematics(r, r->Lrot, r->troot, W, W + 9 * nj, r->G);
    if (turned) frame_error(r, fd, r->surface, st);
    st->iterations = it;
  } else {
    r->limbs_researched += (size_t)turned;
  }
  (void)fs;
  free(save);
}

km_status km_recon_next_frame(km_recon *r, const double *P, size_t n, km_recon_frame_stats *st,
                              km_error *err) {
  if (!r || (!P && n)) return km__fail(err, KM_ERR_INVALID, "km_recon_next_frame: NULL argument");
  if (!r->have_base)
    return km__fail(err, KM_ERR_INVALID, "km_recon_next_frame: register the first frame first");
  double t0 = km_seconds();
  km_recon_frame_stats local = {0};
  if (!st) st = &local;
  memset(st, 0, sizeof *st);
  st->index = r->frame;
  st->points = n;
  size_t nv = r->nv, nj = r->nj;
  /* prediction: constant angular velocity per joint and constant root velocity */
  double *Lpred = km__malloc(nj, 9 * sizeof(double));
  if (!Lpred) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (size_t j = 0; j < nj; ++j) {
    double D[9], Pt[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        Pt[3 * a + b] = r->Lprev2[9 * j + 3 * b + a];
    km__m3_mul(Pt, r->Lprev + 9 * j, D);
    km__m3_mul(r->Lprev + 9 * j, D, Lpred + 9 * j);
    orthonormalize(Lpred + 9 * j);
  }
  double tpred[3];
  for (int a = 0; a < 3; ++a)
    tpred[a] = 2 * r->tprev[a] - r->tprev2[a];
  frame_data fd;
  double tp0 = km_seconds();
  km_error pe = {0};
  km_status s = frame_prepare(r, P, n, &fd, &pe);
  double tp1 = km_seconds();
  km_status fs = KM_OK;
  if (s) {
    fs = s;
    snprintf(st->message, sizeof st->message, "%.*s", (int)sizeof st->message - 1, pe.message);
  } else {
    st->iterations += skeleton_fit(r, fd.C, fd.CN, fd.nc, Lpred, tpred, r->o.skeleton_iterations,
                                   NULL, 0, true, r->o.w_pose, &fs);
  }
  double tp2 = km_seconds();
  km__log(KM_LOG_DEBUG,
          "frame %zu: skeleton %s, root (%.3f %.3f %.3f), %d evaluations; prepare %.3f s, "
          "skeleton %.3f s",
          r->frame, km_status_name(fs), r->troot[0], r->troot[1], r->troot[2], st->iterations,
          tp1 - tp0, tp2 - tp1);
  bool finite = true;
  for (size_t i = 0; fs == KM_OK && i < nv * 3 && finite; ++i)
    finite = isfinite(r->global[i]);
  if (fs == KM_OK && !finite) fs = KM_ERR_NO_CONVERGENCE;
  if (fs != KM_OK) {
    /* carried by the skeleton: the previous pose (a failed frame must not extrapolate a
     * velocity that may be what made it fail) */
    memcpy(r->Lrot, r->Lprev, nj * 9 * sizeof(double));
    memcpy(r->troot, r->tprev, sizeof tpred);
    forward_kinematics(r, r->Lrot, r->troot, r->work, r->work + 9 * nj, r->G);
    memcpy(r->joints, r->work + 9 * nj, nj * 3 * sizeof(double));
    lbs_apply(r, r->G, r->base, r->global);
    memcpy(r->surface, r->global, nv * 3 * sizeof(double));
  } else {
    km_error e2;
    fs = refine(r, &fd, r->global, r->o.refine_iterations, NULL, 0, 0, 0.03, 0.5, &st->iterations,
                &e2);
    for (size_t i = 0; fs == KM_OK && i < nv * 3; ++i)
      if (!isfinite(r->surface[i])) fs = KM_ERR_NO_CONVERGENCE;
    if (fs) memcpy(r->surface, r->global, nv * 3 * sizeof(double));
  }
  if (fd.P && fd.n >= 16 && fd.N) {
    frame_error(r, &fd, r->surface, st);
    if (fs == KM_OK && st->unsupported && !r->o.no_limb_search) research_limbs(r, &fd, st, &fs);
    /* a frame far worse than the recent ones did not converge: carry it by the skeleton */
    double ref = 0;
    for (size_t k = 0; k < r->n_hist; ++k)
      ref += r->err_hist[k] / (double)r->n_hist;
    if (fs == KM_OK && r->n_hist >= 3 && st->mean_mm > 4 * ref + 5) {
      fs = KM_ERR_NO_CONVERGENCE;
      memcpy(r->surface, r->global, nv * 3 * sizeof(double));
      frame_error(r, &fd, r->surface, st);
    }
    if (fs == KM_OK) {
      if (r->n_hist < 8)
        r->err_hist[r->n_hist++] = st->mean_mm;
      else {
        memmove(r->err_hist, r->err_hist + 1, 7 * sizeof(double));
        r->err_hist[7] = st->mean_mm;
      }
    }
  }
  frame_data_free(&fd);
  free(Lpred);
  memset(r->part_lost, 0, nj * sizeof *r->part_lost);
  for (int k = 0; st->unsupported && k < st->n_unsupported_joints; ++k)
    r->part_lost[st->unsupported_joints[k]] = true;
  st->status = fs;
  if (fs && !st->message[0])
    snprintf(st->message, sizeof st->message, "did not converge (%s)", km_status_name(fs));
  if (fs)
    km__log(KM_LOG_WARN, "reconstruct: frame %zu: %s: carried by the skeleton", r->frame,
            st->message);
  /* after a failure the velocity restarts from zero */
  memcpy(r->Lprev2, fs ? r->Lrot : r->Lprev, nj * 9 * sizeof(double));
  memcpy(r->Lprev, r->Lrot, nj * 9 * sizeof(double));
  memcpy(r->tprev2, fs ? r->troot : r->tprev, sizeof r->tprev);
  memcpy(r->tprev, r->troot, sizeof r->troot);
  ++r->frame;
  st->seconds = km_seconds() - t0;
  return KM_OK;
}

km_status km_recon_register_mesh(const km_mesh *source, const double *V_start,
                                 const km_mesh *target, const km_recon_feature *features,
                                 size_t n_features, int iterations, double *V_out, km_error *err) {
  if (!source || !source->V || !source->F || !V_start || !target || !target->V || !V_out ||
      (!features && n_features))
    return km__fail(err, KM_ERR_INVALID, "km_recon_register_mesh: NULL argument");
  size_t nv = source->n_vertices;
  if (iterations <= 0) iterations = 12;
  /* The reconstructor wants a rigged template; the surface stage uses none of the rig, so one
   * joint carries every vertex (rig_joints: no joint estimation from the weights). */
  km_character c = {0};
  c.mesh = *source;
  c.mesh.V = (double *)V_start;
  int32_t parent = -1;
  double root[3] = {0, 0, 0};
  char name[] = "root", *names[1] = {name};
  c.skeleton.n_joints = 1;
  c.skeleton.parents = &parent;
  c.skeleton.rest = root;
  c.skeleton.names = names;
  c.skin.n_vertices = nv;
  c.skin.joints = km__malloc(nv, 4 * sizeof(int32_t));
  c.skin.weights = km__calloc(nv * 4, sizeof(double));
  if (!c.skin.joints || !c.skin.weights) {
    free(c.skin.joints), free(c.skin.weights);
    return km__fail(err, KM_ERR_NOMEM, "km_recon_register_mesh: out of memory");
  }
  for (size_t i = 0; i < nv; ++i) {
    c.skin.joints[4 * i] = 0;
    c.skin.joints[4 * i + 1] = c.skin.joints[4 * i + 2] = c.skin.joints[4 * i + 3] = -1;
    c.skin.weights[4 * i] = 1;
  }
  km_recon_options o = {0};
  o.rig_joints = true;
  o.no_limb_search = true;
  km_recon *r = NULL;
  km_status s = km_recon_create(&c, &o, &r, err);
  free(c.skin.joints), free(c.skin.weights);
  if (!s)
    s = km__recon_affine_register(r, V_start, target->V, target->n_vertices, features, n_features,
                                  iterations, err);
  if (!s) memcpy(V_out, km_recon_surface(r), nv * 3 * sizeof(double));
  km_recon_free(&r);
  if (s) return km__wrap(err, s, "km_recon_register_mesh");
  return KM_OK;
}
