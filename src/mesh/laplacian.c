/* Cotangent and uniform Laplacians and lumped mass matrices. Per-face weights are scattered
 * straight into CSC columns and km__sparse_compress sums the duplicates (an edge shared by two
 * faces), so no triplet list is materialised. */
#include "core/core.h"
#include "linalg/linalg.h"
#include "math/math.h"
#include "mesh/mesh_args.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KM_COT_CLAMP 1e5

/* Cotangents of the three corners of face f and twice its area; false when the area is zero
 * (or not finite), in which case the face contributes nothing. */
static bool face_cots(const km_mesh *m, size_t f, double cot[3], double *area2) {
  const int32_t *t = m->F + 3 * f;
  const double *p[3] = {m->V + 3 * (size_t)t[0], m->V + 3 * (size_t)t[1], m->V + 3 * (size_t)t[2]};
  double u[3], v[3], n[3];
  km__sub3(p[1], p[0], u);
  km__sub3(p[2], p[0], v);
  km__cross3(u, v, n);
  double a2 = sqrt(km__dot3(n, n));
  if (!(a2 > 0) || !isfinite(a2)) return false;
  for (int c = 0; c < 3; ++c) {
    /* cot of the corner at c = (e1 . e2) / |e1 x e2|, and |e1 x e2| is 2*area at any corner */
    km__sub3(p[(c + 1) % 3], p[c], u);
    km__sub3(p[(c + 2) % 3], p[c], v);
    double ct = km__dot3(u, v) / a2;
    cot[c] = ct > KM_COT_CLAMP ? KM_COT_CLAMP : ct < -KM_COT_CLAMP ? -KM_COT_CLAMP : ct;
  }
  *area2 = a2;
  return true;
}

/* Scatters symmetric edge weights straight into CSC columns (no triplet list): column v
 * holds its diagonal first, then two entries per incident face, which km__sparse_compress
 * sorts and sums. w has 3 entries per face, the weight of the edge opposite each corner;
 * faces with keep[f] == 0 are skipped. The diagonal is minus the row sum. */
static km_status assemble(const km_mesh *m, const double *w, const unsigned char *keep,
                          km_sparse **out, km_error *err) {
  size_t n = m->n_vertices, nf = m->n_faces;
  size_t nz = n;
  for (size_t f = 0; f < nf; ++f)
    nz += keep[f] ? 6 : 0;
  if (nz > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "Laplacian: %zu entries exceed int32 indices", nz);
  km_sparse *C = NULL;
  km_status s = km__sparse_alloc(n, n, nz, &C, err);
  if (s) return s;
  int32_t *next = km__malloc(n + 1, sizeof *next);
  if (!next) {
    km_sparse_free(&C);
    return km__fail(err, KM_ERR_NOMEM, "Laplacian: out of memory (%zu vertices)", n);
  }
  int32_t *p, *ri;
  double *x;
  km__sparse_arrays(C, &p, &ri, &x);
  for (size_t v = 0; v <= n; ++v)
    p[v] = v ? 1 : 0;
  for (size_t f = 0; f < nf; ++f)
    if (keep[f])
      for (int c = 0; c < 3; ++c)
        p[m->F[3 * f + c] + 1] += 2;
  for (size_t v = 0; v < n; ++v) {
    p[v + 1] += p[v];
    ri[p[v]] = (int32_t)v; /* diagonal slot, summed below */
    x[p[v]] = 0;
    next[v] = p[v] + 1;
  }
  for (size_t f = 0; f < nf; ++f) {
    if (!keep[f]) continue;
    const int32_t *t = m->F + 3 * f;
    for (int c = 0; c < 3; ++c) {
      int32_t i = t[(c + 1) % 3], j = t[(c + 2) % 3];
      double wt = w[3 * f + c];
      int32_t q = next[j]++;
      ri[q] = i, x[q] = wt;
      x[p[j]] -= wt;
      q = next[i]++;
      ri[q] = j, x[q] = wt;
      x[p[i]] -= wt;
    }
  }
  free(next);
  s = km__sparse_compress(&C, err);
  *out = C;
  return s;
}

km_status km_cotmatrix(const km_mesh *m, km_sparse **L, km_error *err) {
  if (!L) return km__fail(err, KM_ERR_INVALID, "km_cotmatrix: L is NULL");
  *L = NULL;
  km_status s = km__mesh_check_faces(m, "km_cotmatrix", err);
  if (s) return s;
  double *w = km__malloc(m->n_faces, 3 * sizeof *w);
  unsigned char *keep = km__malloc(m->n_faces, 1);
  if (!w || !keep) {
    free(w), free(keep);
    return km__fail(err, KM_ERR_NOMEM, "km_cotmatrix: out of memory (%zu faces)", m->n_faces);
  }
  for (size_t f = 0; f < m->n_faces; ++f) {
    double cot[3], a2;
    keep[f] = face_cots(m, f, cot, &a2);
    for (int c = 0; c < 3; ++c)
      w[3 * f + c] = 0.5 * cot[c];
  }
  s = assemble(m, w, keep, L, err);
  free(w), free(keep);
  return s;
}

km_status km_uniform_laplacian(const km_mesh *m, km_sparse **L, km_error *err) {
  if (!L) return km__fail(err, KM_ERR_INVALID, "km_uniform_laplacian: L is NULL");
  *L = NULL;
  km_status s = km__mesh_check_faces(m, "km_uniform_laplacian", err);
  if (s) return s;
  double *w = km__malloc(m->n_faces, 3 * sizeof *w);
  unsigned char *keep = km__malloc(m->n_faces, 1);
  if (!w || !keep) {
    free(w), free(keep);
    return km__fail(err, KM_ERR_NOMEM, "km_uniform_laplacian: out of memory");
  }
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    keep[f] = 1;
    for (int c = 0; c < 3; ++c)
      w[3 * f + c] = t[(c + 1) % 3] != t[(c + 2) % 3];
  }
  s = assemble(m, w, keep, L, err);
  free(w), free(keep);
  if (s) return s;
  /* An interior edge appears in two faces and was summed to 2: reset every edge to 1 and
   * the diagonal to minus the number of distinct neighbours. A face with a repeated index
   * adds a zero-weight self entry to the diagonal only (weight 0), which changes nothing. */
  const int32_t *p, *ri;
  km_sparse_csc(*L, &p, &ri, NULL);
  double *x = km__sparse_values(*L);
  for (size_t j = 0; j < m->n_vertices; ++j) {
    int32_t dpos = -1, deg = 0;
    for (int32_t q = p[j]; q < p[j + 1]; ++q) {
      if ((size_t)ri[q] == j)
        dpos = q;
      else if (x[q] != 0)
        x[q] = 1, ++deg;
    }
    if (dpos >= 0) x[dpos] = -deg;
  }
  return KM_OK;
}

km_status km_massmatrix(const km_mesh *m, km_mass_type type, km_sparse **M, km_error *err) {
  if (!M) return km__fail(err, KM_ERR_INVALID, "km_massmatrix: M is NULL");
  *M = NULL;
  km_status s = km__mesh_check_faces(m, "km_massmatrix", err);
  if (s) return s;
  if (type != KM_MASS_VORONOI && type != KM_MASS_BARYCENTRIC)
    return km__fail(err, KM_ERR_INVALID, "km_massmatrix: unknown mass type %d", (int)type);
  size_t n = m->n_vertices;
  double *mass = km__calloc(n, sizeof *mass);
  if (!mass) return km__fail(err, KM_ERR_NOMEM, "km_massmatrix: out of memory");
  double total = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    double cot[3], a2;
    if (!face_cots(m, f, cot, &a2)) continue;
    const int32_t *t = m->F + 3 * f;
    double area = 0.5 * a2;
    total += area;
    if (type == KM_MASS_BARYCENTRIC) {
      for (int c = 0; c < 3; ++c)
        mass[t[c]] += area / 3;
      continue;
    }
    /* Meyer et al. 2003, mixed area: the Voronoi region of each corner when the triangle is
     * not obtuse; otherwise half the area to the obtuse corner and a quarter to the others. */
    int obtuse = -1;
    for (int c = 0; c < 3; ++c)
      if (cot[c] < 0) obtuse = c;
    if (obtuse >= 0) {
      for (int c = 0; c < 3; ++c)
        mass[t[c]] += c == obtuse ? area / 2 : area / 4;
      continue;
    }
    double l2[3]; /* squared length of the edge opposite corner c */
    for (int c = 0; c < 3; ++c) {
      double e[3];
      km__sub3(m->V + 3 * (size_t)t[(c + 1) % 3], m->V + 3 * (size_t)t[(c + 2) % 3], e);
      l2[c] = km__dot3(e, e);
    }
    for (int c = 0; c < 3; ++c) {
      int a = (c + 1) % 3, b = (c + 2) % 3;
      /* edge c-a is opposite corner b, edge c-b opposite corner a */
      mass[t[c]] += (l2[b] * cot[b] + l2[a] * cot[a]) / 8;
    }
  }
  /* Isolated vertices (or ones touching only zero-area faces) get a tiny positive mass,
   * relative to the mean vertex area, so that M stays invertible. */
  double tiny = total > 0 && n ? 1e-12 * total / (double)n : 1e-300;
  for (size_t v = 0; v < n; ++v)
    if (!(mass[v] > 0)) mass[v] = tiny;
  s = km_sparse_diagonal(n, mass, M, err);
  free(mass);
  return s;
}
