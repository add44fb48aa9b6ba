/* Iso-surface extraction by marching tetrahedra on sparse blocks.
 *
 * Written by hand: no Debian-packaged C library extracts iso-surfaces (CGAL's mesher and
 * VTK's contour filters are C++ and very heavy dependencies for this one use).
 *
 * Every cube of the grid is split into the 6 Kuhn tetrahedra around its main diagonal. The
 * split is translation invariant, so neighbouring cubes agree on shared faces, and each edge
 * of the tetrahedral grid carries at most one vertex, welded through an edge -> vertex hash.
 * With no grid value exactly on the iso value (zeros are nudged to the outside) the result
 * is a closed 2-manifold. Only blocks of BxBxB cells whose centre value does not prove them
 * to be entirely inside or outside (the field is 1-Lipschitz) are evaluated, so memory and
 * time scale with the surface area, not the volume. */
#include "core/core.h"
#include "synth/polygonize.h"
#include "math/math.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define B 8 /* cells per block side */
#define BP (B + 1)

typedef struct grid {
  double o[3], h;
  int64_t nb[3]; /* blocks per axis */
  int64_t np[3]; /* grid points per axis = nb*B + 1 */
} grid;

/* One triangle of a tetrahedron case: three edges, each given by two cube corners (bit
 * masks x | y<<1 | z<<2) such that the first is a subset of the second. */
typedef struct tet_case {
  int ntri;
  unsigned char e[2][3][2];
} tet_case;

static const int kuhn_perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                    {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

static void tet_corners(int t, int c[4]) {
  c[0] = 0;
  c[1] = 1 << kuhn_perm[t][0];
  c[2] = c[1] | (1 << kuhn_perm[t][1]);
  c[3] = 7;
}

static void corner_pos(int c, double p[3]) {
  p[0] = c & 1;
  p[1] = (c >> 1) & 1;
  p[2] = (c >> 2) & 1;
}

static void edge_mid(int a, int b, double m[3]) {
  double pa[3], pb[3];
  corner_pos(a, pa);
  corner_pos(b, pb);
  for (int k = 0; k < 3; ++k)
    m[k] = 0.5 * (pa[k] + pb[k]);
}

static void set_edge(unsigned char e[2], int a, int b) {
  /* Corners of a Kuhn tetrahedron form a chain under bit inclusion. */
  if ((a & b) == a) {
    e[0] = (unsigned char)a;
    e[1] = (unsigned char)b;
  } else {
    e[0] = (unsigned char)b;
    e[1] = (unsigned char)a;
  }
}

/* Orients triangle (e0,e1,e2) so that its normal (computed on edge midpoints, which never
 * degenerate) points from the inside corners to the outside ones. */
static void orient(tet_case *tc, int t, const int *in, int nin, const int *out, int nout) {
  unsigned char(*tri)[2] = tc->e[t];
  double m[3][3], ci[3] = {0, 0, 0}, co[3] = {0, 0, 0}, p[3];
  for (int v = 0; v < 3; ++v)
    edge_mid(tri[v][0], tri[v][1], m[v]);
  for (int i = 0; i < nin; ++i) {
    corner_pos(in[i], p);
    for (int k = 0; k < 3; ++k)
      ci[k] += p[k] / nin;
  }
  for (int i = 0; i < nout; ++i) {
    corner_pos(out[i], p);
    for (int k = 0; k < 3; ++k)
      co[k] += p[k] / nout;
  }
  double a[3], b[3], n[3];
  for (int k = 0; k < 3; ++k) {
    a[k] = m[1][k] - m[0][k];
    b[k] = m[2][k] - m[0][k];
  }
  n[0] = a[1] * b[2] - a[2] * b[1];
  n[1] = a[2] * b[0] - a[0] * b[2];
  n[2] = a[0] * b[1] - a[1] * b[0];
  double d = n[0] * (co[0] - ci[0]) + n[1] * (co[1] - ci[1]) + n[2] * (co[2] - ci[2]);
  if (d < 0) {
    unsigned char t0 = tri[1][0], t1 = tri[1][1];
    tri[1][0] = tri[2][0];
    tri[1][1] = tri[2][1];
    tri[2][0] = t0;
    tri[2][1] = t1;
  }
}

static void build_cases(tet_case cases[6][16]) {
  for (int t = 0; t < 6; ++t) {
    int c[4];
    tet_corners(t, c);
    for (int cfg = 0; cfg < 16; ++cfg) {
      tet_case *tc = &cases[t][cfg];
      memset(tc, 0, sizeof *tc);
      int in[4], out[4], nin = 0, nout = 0;
      for (int v = 0; v < 4; ++v) {
        if (cfg & (1 << v))
          in[nin++] = c[v];
        else
          out[nout++] = c[v];
      }
      if (nin == 0 || nin == 4) continue;
      if (nin == 1 || nin == 3) {
        const int *lone = nin == 1 ? in : out, *rest = nin == 1 ? out : in;
        tc->ntri = 1;
        for (int v = 0; v < 3; ++v)
          set_edge(tc->e[0][v], lone[0], rest[v]);
        orient(tc, 0, in, nin, out, nout);
      } else {
        /* Quad ac, ad, bd, bc (cyclic) split into two triangles. */
        int a = in[0], b = in[1], cc = out[0], d = out[1];
        unsigned char q[4][2];
        set_edge(q[0], a, cc);
        set_edge(q[1], a, d);
        set_edge(q[2], b, d);
        set_edge(q[3], b, cc);
        tc->ntri = 2;
        memcpy(tc->e[0][0], q[0], 2);
        memcpy(tc->e[0][1], q[1], 2);
        memcpy(tc->e[0][2], q[2], 2);
        orient(tc, 0, in, nin, out, nout);
        bool flipped = tc->e[0][1][0] != q[1][0] || tc->e[0][1][1] != q[1][1];
        memcpy(tc->e[1][0], q[0], 2);
        memcpy(tc->e[1][1], flipped ? q[3] : q[2], 2);
        memcpy(tc->e[1][2], flipped ? q[2] : q[3], 2);
      }
    }
  }
}

static void grid_setup(grid *g, const double lo[3], const double hi[3], double h) {
  g->h = h;
  for (int k = 0; k < 3; ++k) {
    double ext = hi[k] - lo[k] + 4 * h;
    int64_t cells = (int64_t)ceil(ext / h);
    g->nb[k] = (cells + B - 1) / B;
    if (g->nb[k] < 1) g->nb[k] = 1;
    g->np[k] = g->nb[k] * B + 1;
    /* Centre the grid on the box so that a mirror-symmetric field samples symmetrically. */
    double mid = 0.5 * (lo[k] + hi[k]);
    g->o[k] = mid - 0.5 * (double)(g->np[k] - 1) * h;
  }
}

/* Values of one block, or NULL when the block is provably on one side of the surface or has
 * no sign change (or, with *nomem set, when memory ran out). */
static double *block_values(const grid *g, int64_t bx, int64_t by, int64_t bz, km__field_fn f,
                            void *user, int *nomem) {
  double h = g->h;
  double c[3] = {g->o[0] + ((double)bx * B + 0.5 * B) * h, g->o[1] + ((double)by * B + 0.5 * B) * h,
                 g->o[2] + ((double)bz * B + 0.5 * B) * h};
  double fc = f(user, c);
  double half_diag = 0.5 * B * h * sqrt(3.0);
  if (fabs(fc) > half_diag + h) return NULL;
  double *v = malloc(sizeof(double) * BP * BP * BP);
  if (!v) {
    *nomem = 1;
    return NULL;
  }
  double tiny = 1e-9 * h;
  int npos = 0, nneg = 0;
  for (int k = 0; k < BP; ++k)
    for (int j = 0; j < BP; ++j)
      for (int i = 0; i < BP; ++i) {
        double p[3] = {g->o[0] + (double)(bx * B + i) * h, g->o[1] + (double)(by * B + j) * h,
                       g->o[2] + (double)(bz * B + k) * h};
        double x = f(user, p);
        /* Symbolic perturbation: nothing sits exactly on the iso value. */
        if (fabs(x) < tiny) x = x < 0 ? -tiny : tiny;
        v[i + BP * (j + BP * k)] = x;
        if (x < 0)
          ++nneg;
        else
          ++npos;
      }
  if (!npos || !nneg) {
    free(v);
    return NULL;
  }
  return v;
}

static void free_blocks(double **blocks, int64_t n);

/* Evaluates all blocks in parallel. blocks[b] is NULL for skipped blocks. Returns false on a
 * failed allocation: a missing block would leave a hole, so it is never silently skipped. */
static bool evaluate_blocks(const grid *g, km__field_fn f, void *user, double ***out) {
  int64_t nblocks = g->nb[0] * g->nb[1] * g->nb[2];
  double **blocks = km__calloc((size_t)nblocks, sizeof *blocks);
  if (!blocks) return false;
  int nomem = 0;
#pragma omp parallel for schedule(dynamic, 16) reduction(| : nomem)
  for (int64_t b = 0; b < nblocks; ++b) {
    int64_t bx = b % g->nb[0], by = (b / g->nb[0]) % g->nb[1], bz = b / (g->nb[0] * g->nb[1]);
    blocks[b] = block_values(g, bx, by, bz, f, user, &nomem);
  }
  if (nomem) {
    free_blocks(blocks, nblocks);
    return false;
  }
  *out = blocks;
  return true;
}

static void free_blocks(double **blocks, int64_t n) {
  if (!blocks) return;
  for (int64_t b = 0; b < n; ++b)
    free(blocks[b]);
  free(blocks);
}

km_status km__polygonize_count(km__field_fn f, void *user, const double lo[3], const double hi[3],
                               double h, size_t *n_vertices, km_error *err) {
  grid g;
  grid_setup(&g, lo, hi, h);
  int64_t nblocks = g.nb[0] * g.nb[1] * g.nb[2];
  size_t total = 0;
  int nomem = 0;
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : total) reduction(| : nomem)
  for (int64_t b = 0; b < nblocks; ++b) {
    int64_t bx = b % g.nb[0], by = (b / g.nb[0]) % g.nb[1], bz = b / (g.nb[0] * g.nb[1]);
    double *v = block_values(&g, bx, by, bz, f, user, &nomem);
    if (!v) continue;
    size_t cnt = 0;
    /* Edges owned by points of this block: p -> p + d, d in {0,1}^3 \ 0. */
    for (int k = 0; k < B; ++k)
      for (int j = 0; j < B; ++j)
        for (int i = 0; i < B; ++i) {
          bool s0 = v[i + BP * (j + BP * k)] < 0;
          for (int d = 1; d < 8; ++d) {
            int ii = i + (d & 1), jj = j + ((d >> 1) & 1), kk = k + ((d >> 2) & 1);
            if ((v[ii + BP * (jj + BP * kk)] < 0) != s0) ++cnt;
          }
        }
    total += cnt;
    free(v);
  }
  *n_vertices = total;
  if (nomem) return km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory (h = %g)", h);
  return KM_OK;
}

/* Open-addressing map from edge keys to vertex indices. */
typedef struct edge_map {
  uint64_t *keys; /* key + 1; 0 = empty */
  int32_t *vals;
  size_t cap, n;
} edge_map;

static uint64_t mix64(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

static bool map_init(edge_map *m, size_t cap) {
  size_t c = 1024;
  while (c < cap)
    c <<= 1;
  m->keys = km__calloc(c, sizeof *m->keys);
  m->vals = km__malloc(c, sizeof *m->vals);
  m->cap = c;
  m->n = 0;
  return m->keys && m->vals;
}

static bool map_grow(edge_map *m) {
  edge_map nm;
  if (!map_init(&nm, m->cap * 2)) {
    free(nm.keys);
    free(nm.vals);
    return false;
  }
  for (size_t i = 0; i < m->cap; ++i) {
    if (!m->keys[i]) continue;
    size_t s = mix64(m->keys[i]) & (nm.cap - 1);
    while (nm.keys[s])
      s = (s + 1) & (nm.cap - 1);
    nm.keys[s] = m->keys[i];
    nm.vals[s] = m->vals[i];
  }
  nm.n = m->n;
  free(m->keys);
  free(m->vals);
  *m = nm;
  return true;
}

/* Growable output arrays. */
typedef struct out_buf {
  double *V;
  int32_t *F;
  size_t nv, nf, cv, cf;
} out_buf;

static bool reserve(void **p, size_t *cap, size_t need, size_t elem) {
  if (need <= *cap) return true;
  size_t c = *cap ? *cap : 1024;
  while (c < need)
    c *= 2;
  void *q = realloc(*p, c * elem);
  if (!q) return false;
  *p = q;
  *cap = c;
  return true;
}

/* Keeps the largest connected component (ties: the one with the smallest vertex index). */
static km_status keep_largest(out_buf *o, km_mesh *out, km_error *err) {
  size_t nv = o->nv, nf = o->nf;
  int32_t *par = km__malloc(nv, sizeof *par);
  int32_t *cnt = km__calloc(nv, sizeof *cnt);
  if (!par || !cnt) {
    free(par);
    free(cnt);
    return km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory (%zu vertices)", nv);
  }
  km__uf_init(par, nv);
  for (size_t f = 0; f < nf; ++f) {
    km__uf_union(par, o->F[3 * f], o->F[3 * f + 1]);
    km__uf_union(par, o->F[3 * f], o->F[3 * f + 2]);
  }
  int32_t best = -1;
  for (size_t i = 0; i < nv; ++i) {
    int32_t r = km__uf_find(par, (int32_t)i);
    ++cnt[r];
    if (best < 0 || cnt[r] > cnt[best] || (cnt[r] == cnt[best] && r < best)) best = r;
  }
  /* Remap: cnt reused as the new index. */
  size_t nnv = 0;
  for (size_t i = 0; i < nv; ++i)
    cnt[i] = km__uf_find(par, (int32_t)i) == best ? (int32_t)nnv++ : -1;
  double *V = km__malloc(nnv * 3, sizeof *V);
  int32_t *F = km__malloc(nf * 3, sizeof *F);
  if (!V || !F) {
    free(V);
    free(F);
    free(par);
    free(cnt);
    return km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory (%zu vertices)", nv);
  }
  for (size_t i = 0; i < nv; ++i)
    if (cnt[i] >= 0) memcpy(V + 3 * (size_t)cnt[i], o->V + 3 * i, 3 * sizeof *V);
  size_t nnf = 0;
  for (size_t f = 0; f < nf; ++f) {
    int32_t a = o->F[3 * f];
    if (cnt[a] < 0) continue;
    for (int k = 0; k < 3; ++k)
      F[3 * nnf + k] = cnt[o->F[3 * f + k]];
    ++nnf;
  }
  free(par);
  free(cnt);
  out->V = V;
  out->F = F;
  out->n_vertices = nnv;
  out->n_faces = nnf;
  return KM_OK;
}

km_status km__polygonize(km__field_fn f, void *user, const double lo[3], const double hi[3],
                         double h, km_mesh *out, km_error *err) {
  memset(out, 0, sizeof *out);
  grid g;
  grid_setup(&g, lo, hi, h);
  int64_t nblocks = g.nb[0] * g.nb[1] * g.nb[2];
  if ((uint64_t)g.np[0] * (uint64_t)g.np[1] * (uint64_t)g.np[2] > (UINT64_MAX >> 4))
    return km__fail(err, KM_ERR_INVALID, "polygonise: grid too fine (h = %g)", h);
  double **blocks = NULL;
  if (!evaluate_blocks(&g, f, user, &blocks))
    return km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory (%lld blocks)",
                    (long long)nblocks);
  tet_case cases[6][16];
  build_cases(cases);
  int tc[6][4];
  for (int t = 0; t < 6; ++t)
    tet_corners(t, tc[t]);

  edge_map map = {0};
  out_buf o = {0};
  km_status st = KM_OK;
  if (!map_init(&map, 1 << 16)) st = km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory");
  for (int64_t b = 0; b < nblocks && st == KM_OK; ++b) {
    const double *v = blocks[b];
    if (!v) continue;
    int64_t bx = b % g.nb[0], by = (b / g.nb[0]) % g.nb[1], bz = b / (g.nb[0] * g.nb[1]);
    for (int k = 0; k < B && st == KM_OK; ++k)
      for (int j = 0; j < B && st == KM_OK; ++j)
        for (int i = 0; i < B && st == KM_OK; ++i) {
          double cv[8];
          int neg = 0;
          for (int c = 0; c < 8; ++c) {
            cv[c] = v[(i + (c & 1)) + BP * ((j + ((c >> 1) & 1)) + BP * (k + ((c >> 2) & 1)))];
            neg += cv[c] < 0;
          }
          if (neg == 0 || neg == 8) continue;
          int64_t gi = bx * B + i, gj = by * B + j, gk = bz * B + k;
          for (int t = 0; t < 6; ++t) {
            int cfg = 0;
            for (int q = 0; q < 4; ++q)
              cfg |= (cv[tc[t][q]] < 0) << q;
            const tet_case *cs = &cases[t][cfg];
            for (int tri = 0; tri < cs->ntri; ++tri) {
              int32_t idx[3];
              for (int q = 0; q < 3; ++q) {
                int ca = cs->e[tri][q][0], cb = cs->e[tri][q][1];
                int64_t oi = gi + (ca & 1), oj = gj + ((ca >> 1) & 1), ok = gk + ((ca >> 2) & 1);
                uint64_t key =
                    ((uint64_t)(oi + g.np[0] * (oj + g.np[1] * ok)) << 3 | (uint64_t)(ca ^ cb)) + 1;
                if (2 * (map.n + 1) > map.cap && !map_grow(&map)) {
                  st = km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory");
                  break;
                }
                size_t s = mix64(key) & (map.cap - 1);
                while (map.keys[s] && map.keys[s] != key)
                  s = (s + 1) & (map.cap - 1);
                if (map.keys[s]) {
                  idx[q] = map.vals[s];
                  continue;
                }
                if (o.nv >= INT32_MAX ||
                    !reserve((void **)&o.V, &o.cv, 3 * (o.nv + 1), sizeof *o.V)) {
                  st = km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory");
                  break;
                }
                double fa = cv[ca], fb = cv[cb];
                double tt = fa / (fa - fb);
                double pa[3], pb[3];
                corner_pos(ca, pa);
                corner_pos(cb, pb);
                double *P = o.V + 3 * o.nv;
                P[0] = g.o[0] + ((double)gi + pa[0] + tt * (pb[0] - pa[0])) * h;
                P[1] = g.o[1] + ((double)gj + pa[1] + tt * (pb[1] - pa[1])) * h;
                P[2] = g.o[2] + ((double)gk + pa[2] + tt * (pb[2] - pa[2])) * h;
                map.keys[s] = key;
                map.vals[s] = (int32_t)o.nv;
                ++map.n;
                idx[q] = (int32_t)o.nv++;
              }
              if (st != KM_OK) break;
              if (!reserve((void **)&o.F, &o.cf, 3 * (o.nf + 1), sizeof *o.F)) {
                st = km__fail(err, KM_ERR_NOMEM, "polygonise: out of memory");
                break;
              }
              memcpy(o.F + 3 * o.nf, idx, sizeof idx);
              ++o.nf;
            }
            if (st != KM_OK) break;
          }
        }
  }
  free_blocks(blocks, nblocks);
  free(map.keys);
  free(map.vals);
  if (st == KM_OK && o.nf == 0)
    st = km__fail(err, KM_ERR_DEGENERATE_MESH, "polygonise: the surface is empty at h = %g", h);
  if (st == KM_OK) st = keep_largest(&o, out, err);
  free(o.V);
  free(o.F);
  return st;
}

static void gradient(km__field_fn f, void *user, const double p[3], double f0, double eps,
                     double g[3]) {
  for (int k = 0; k < 3; ++k) {
    double q[3] = {p[0], p[1], p[2]};
    q[k] += eps;
    g[k] = (f(user, q) - f0) / eps;
  }
}

/* One Newton step of q towards the zero set; g receives the gradient at the start point. */
static void newton_step(km__field_fn f, void *user, double q[3], double eps, double g[3]) {
  double fq = f(user, q);
  gradient(f, user, q, fq, eps, g);
  double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
  if (g2 < 1e-12) return;
  for (int k = 0; k < 3; ++k)
    q[k] -= fq * g[k] / g2;
}

void km__surface_relax(km_mesh *m, km__field_fn f, void *user, int iterations, double eps) {
  size_t nv = m->n_vertices, nf = m->n_faces;
  double *sum = km__malloc(nv * 3, sizeof *sum);
  int32_t *cnt = km__malloc(nv, sizeof *cnt);
  double *nV = km__malloc(nv * 3, sizeof *nV);
  double *G = km__malloc(nv * 3, sizeof *G);
  if (!sum || !cnt || !nV || !G) {
    /* Relaxation only improves quality; without memory the mesh stays as it is. */
    free(sum);
    free(cnt);
    free(nV);
    free(G);
    return;
  }
  /* The normal of the tangent plane is the gradient met by the previous Newton step: the
   * vertex moved by a fraction of an edge since, and this halves the field evaluations. */
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < nv; ++i) {
    const double *p = m->V + 3 * i;
    gradient(f, user, p, f(user, p), eps, G + 3 * i);
  }
  for (int it = 0; it < iterations; ++it) {
    memset(sum, 0, nv * 3 * sizeof *sum);
    memset(cnt, 0, nv * sizeof *cnt);
    /* In a closed mesh every edge is in two faces, so each neighbour counts twice: uniform. */
    for (size_t t = 0; t < nf; ++t) {
      const int32_t *F = m->F + 3 * t;
      for (int e = 0; e < 3; ++e) {
        int32_t a = F[e], b = F[(e + 1) % 3];
        for (int k = 0; k < 3; ++k) {
          sum[3 * (size_t)a + k] += m->V[3 * (size_t)b + k];
          sum[3 * (size_t)b + k] += m->V[3 * (size_t)a + k];
        }
        ++cnt[a];
        ++cnt[b];
      }
    }
    bool last = it == iterations - 1;
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < nv; ++i) {
      const double *p = m->V + 3 * i;
      double *g = G + 3 * i, q[3], d[3];
      if (!cnt[i]) {
        memcpy(nV + 3 * i, p, sizeof q);
        continue;
      }
      double gn2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
      for (int k = 0; k < 3; ++k)
        d[k] = sum[3 * i + k] / cnt[i] - p[k];
      if (gn2 > 1e-12) {
        double dn = (d[0] * g[0] + d[1] * g[1] + d[2] * g[2]) / gn2;
        for (int k = 0; k < 3; ++k)
          d[k] -= dn * g[k];
      }
      for (int k = 0; k < 3; ++k)
        q[k] = p[k] + 0.5 * d[k];
      newton_step(f, user, q, eps, g);
      if (last) newton_step(f, user, q, eps, g);
      memcpy(nV + 3 * i, q, sizeof q);
    }
    memcpy(m->V, nV, nv * 3 * sizeof *nV);
  }
  free(sum);
  free(cnt);
  free(nV);
  free(G);
}

/* ---------------------------------------------------------------- edge flips
 * Half-edge h = 3f + k runs from F[3f+k] to F[3f+(k+1)%3]; opp[h] is its twin. */

static int32_t he_target(const int32_t *F, size_t h) { return F[3 * (h / 3) + (h % 3 + 1) % 3]; }
static size_t he_prev(size_t h) { return 3 * (h / 3) + (h % 3 + 2) % 3; }

/* Walks the half-edges leaving the source of h; returns the valence, or -1 when `probe`
 * is a neighbour. */
static int ring(const int32_t *F, const size_t *opp, size_t h, int32_t probe) {
  size_t start = h;
  int n = 0;
  do {
    if (he_target(F, h) == probe) return -1;
    h = opp[he_prev(h)];
    if (++n > 10000) return -1; /* not a disk: refuse */
  } while (h != start);
  return n;
}

static void tri_normal(const double *V, int32_t a, int32_t b, int32_t c, double n[3]) {
  const double *p = V + 3 * (size_t)a, *q = V + 3 * (size_t)b, *r = V + 3 * (size_t)c;
  double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
  double w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
  n[0] = u[1] * w[2] - u[2] * w[1];
  n[1] = u[2] * w[0] - u[0] * w[2];
  n[2] = u[0] * w[1] - u[1] * w[0];
}

static double angle_at(const double *V, int32_t at, int32_t x, int32_t y) {
  const double *p = V + 3 * (size_t)at, *q = V + 3 * (size_t)x, *r = V + 3 * (size_t)y;
  double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
  double w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
  double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
               u[0] * w[0] + u[1] * w[1] + u[2] * w[2]);
}

size_t km__delaunay_flips(km_mesh *m, int max_passes) {
  size_t nf = m->n_faces, nh = 3 * nf, flips = 0;
  int32_t *F = m->F;
  const double *V = m->V;
  size_t nv = m->n_vertices;
  /* Twins through half-edges bucketed by source vertex (linear; valences are small). */
  size_t *opp = km__malloc(nh, sizeof *opp);
  size_t *start = km__calloc(nv + 1, sizeof *start);
  size_t *out = km__malloc(nh, sizeof *out);
  if (!opp || !start || !out) {
    free(opp);
    free(start);
    free(out);
    return 0;
  }
  for (size_t h = 0; h < nh; ++h)
    ++start[F[h] + 1];
  for (size_t v = 0; v < nv; ++v)
    start[v + 1] += start[v];
  for (size_t h = 0; h < nh; ++h)
    out[start[F[h]]++] = h;
  for (size_t v = nv; v > 0; --v)
    start[v] = start[v - 1];
  start[0] = 0;
  bool ok = true;
  for (size_t h = 0; h < nh && ok; ++h) {
    int32_t a = F[h], b = he_target(F, h);
    size_t found = SIZE_MAX;
    int count = 0;
    for (size_t i = start[b]; i < start[b + 1]; ++i)
      if (he_target(F, out[i]) == a) {
        found = out[i];
        ++count;
      }
    /* Closed manifold: each directed edge has exactly one reverse (duplicates of a->b would
     * show up as two reverses of b->a). */
    if (count != 1) ok = false;
    opp[h] = found;
  }
  free(start);
  free(out);
  if (!ok) {
    free(opp);
    return 0;
  }
  const double coplanar = cos(30.0 * M_PI / 180.0);
  for (int pass = 0; pass < max_passes; ++pass) {
    size_t pass_flips = 0;
    for (size_t e = 0; e < nh; ++e) {
      size_t t = opp[e];
      if (t < e) continue;
      size_t f = e / 3, g = t / 3;
      int k = (int)(e % 3), mm = (int)(t % 3);
      int32_t a = F[3 * f + k], b = F[3 * f + (k + 1) % 3], c = F[3 * f + (k + 2) % 3];
      int32_t d = F[3 * g + (mm + 2) % 3];
      if (c == d) continue;
      if (angle_at(V, c, a, b) + angle_at(V, d, a, b) <= M_PI + 1e-9) continue;
      double nf1[3], ng1[3];
      tri_normal(V, a, b, c, nf1);
      tri_normal(V, b, a, d, ng1);
      double lf = sqrt(km__dot3(nf1, nf1)), lg = sqrt(km__dot3(ng1, ng1));
      if (lf == 0 || lg == 0 || km__dot3(nf1, ng1) < coplanar * lf * lg) continue;
      double n1[3], n2[3],
          sum[3] = {nf1[0] / lf + ng1[0] / lg, nf1[1] / lf + ng1[1] / lg,
                    nf1[2] / lf + ng1[2] / lg};
      tri_normal(V, d, b, c, n1);
      tri_normal(V, c, a, d, n2);
      double l1 = sqrt(km__dot3(n1, n1)), l2 = sqrt(km__dot3(n2, n2));
      if (l1 <= 1e-12 * (lf + lg) || l2 <= 1e-12 * (lf + lg)) continue;
      if (km__dot3(n1, sum) < 0.5 * l1 || km__dot3(n2, sum) < 0.5 * l2) continue;
      size_t h_bc = 3 * f + (size_t)(k + 1) % 3, h_ca = 3 * f + (size_t)(k + 2) % 3;
      size_t h_ad = 3 * g + (size_t)(mm + 1) % 3, h_db = 3 * g + (size_t)(mm + 2) % 3;
      /* New edge must not exist; a and b keep valence >= 3. */
      if (ring(F, opp, h_ca, d) < 0) continue;
      int va = ring(F, opp, h_ad, -1), vb = ring(F, opp, h_bc, -1);
      if (va <= 3 || vb <= 3) continue;
      size_t o_bc = opp[h_bc], o_ca = opp[h_ca], o_ad = opp[h_ad], o_db = opp[h_db];
      F[3 * f] = d;
      F[3 * f + 1] = b;
      F[3 * f + 2] = c;
      F[3 * g] = c;
      F[3 * g + 1] = a;
      F[3 * g + 2] = d;
      opp[3 * f] = o_db;
      opp[o_db] = 3 * f;
      opp[3 * f + 1] = o_bc;
      opp[o_bc] = 3 * f + 1;
      opp[3 * f + 2] = 3 * g + 2;
      opp[3 * g + 2] = 3 * f + 2;
      opp[3 * g] = o_ca;
      opp[o_ca] = 3 * g;
      opp[3 * g + 1] = o_ad;
      opp[o_ad] = 3 * g + 1;
      ++pass_flips;
    }
    flips += pass_flips;
    if (!pass_flips) break;
  }
  free(opp);
  return flips;
}
