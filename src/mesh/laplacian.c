/* Cotangent and uniform Laplacians and lumped mass matrices, assembled from triplets
 * (CHOLMOD sums the duplicates). Off-diagonal triplets are emitted per face and the
 * diagonal is accumulated densely, so the triplet list is 6 per face + #V. */
#include "internal.h"
#include "linalg/sparse.h"
#include "mesh/mesh_check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KM_COT_CLAMP 1e5

km_status km__check_mesh(const km_mesh *m, const char *who, km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "%s: mesh is NULL", who);
  if ((m->n_vertices && !m->V) || (m->n_faces && !m->F))
    return km__fail(err, KM_ERR_INVALID, "%s: mesh has NULL arrays", who);
  if (m->n_vertices > INT32_MAX || m->n_faces > INT32_MAX / 3)
    return km__fail(err, KM_ERR_INVALID, "%s: mesh too large for int32 indices", who);
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int c = 0; c < 3; ++c) {
      int32_t v = m->F[3 * f + c];
      if (v < 0 || (size_t)v >= m->n_vertices)
        return km__fail(err, KM_ERR_INVALID, "%s: face %zu references vertex %d, expected 0..%zu",
                        who, f, (int)v, m->n_vertices ? m->n_vertices - 1 : 0);
    }
  return KM_OK;
}

static inline void sub3(const double *a, const double *b, double *o) {
  o[0] = a[0] - b[0];
  o[1] = a[1] - b[1];
  o[2] = a[2] - b[2];
}
static inline double dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void cross3(const double *a, const double *b, double *o) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

/* Cotangents of the three corners of face f and twice its area; false when the area is zero
 * (or not finite), in which case the face contributes nothing. */
static bool face_cots(const km_mesh *m, size_t f, double cot[3], double *area2) {
  const int32_t *t = m->F + 3 * f;
  const double *p[3] = {m->V + 3 * (size_t)t[0], m->V + 3 * (size_t)t[1], m->V + 3 * (size_t)t[2]};
  double u[3], v[3], n[3];
  sub3(p[1], p[0], u);
  sub3(p[2], p[0], v);
  cross3(u, v, n);
  double a2 = sqrt(dot3(n, n));
  if (!(a2 > 0) || !isfinite(a2)) return false;
  for (int c = 0; c < 3; ++c) {
    /* cot of the corner at c = (e1 . e2) / |e1 x e2|, and |e1 x e2| is 2*area at any corner */
    sub3(p[(c + 1) % 3], p[c], u);
    sub3(p[(c + 2) % 3], p[c], v);
    double ct = dot3(u, v) / a2;
    cot[c] = ct > KM_COT_CLAMP ? KM_COT_CLAMP : ct < -KM_COT_CLAMP ? -KM_COT_CLAMP : ct;
  }
  *area2 = a2;
  return true;
}

/* Builds the matrix from off-diagonal triplets (rows/cols/vals, n_off entries, with room for
 * n more) plus the dense diagonal. Frees nothing. */
static km_status assemble(size_t n, size_t n_off, int32_t *rows, int32_t *cols, double *vals,
                          const double *diag, km_sparse **out, km_error *err) {
  for (size_t v = 0; v < n; ++v) {
    rows[n_off + v] = cols[n_off + v] = (int32_t)v;
    vals[n_off + v] = diag[v];
  }
  return km_sparse_from_triplets(n, n, n_off + n, rows, cols, vals, out, err);
}

km_status km_cotmatrix(const km_mesh *m, km_sparse **L, km_error *err) {
  if (!L) return km__fail(err, KM_ERR_INVALID, "km_cotmatrix: L is NULL");
  *L = NULL;
  km_status s = km__check_mesh(m, "km_cotmatrix", err);
  if (s) return s;
  size_t n = m->n_vertices, nt = 6 * m->n_faces + n;
  int32_t *rows = km__malloc(nt, sizeof *rows), *cols = km__malloc(nt, sizeof *cols);
  double *vals = km__malloc(nt, sizeof *vals), *diag = km__calloc(n, sizeof *diag);
  if (!rows || !cols || !vals || !diag) {
    s = km__fail(err, KM_ERR_NOMEM, "km_cotmatrix: out of memory (%zu vertices)", n);
    goto done;
  }
  size_t k = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    double cot[3], a2;
    if (!face_cots(m, f, cot, &a2)) continue;
    const int32_t *t = m->F + 3 * f;
    for (int c = 0; c < 3; ++c) {
      /* the corner c is opposite the edge (c+1, c+2) */
      int32_t i = t[(c + 1) % 3], j = t[(c + 2) % 3];
      double w = 0.5 * cot[c];
      rows[k] = i, cols[k] = j, vals[k++] = w;
      rows[k] = j, cols[k] = i, vals[k++] = w;
      diag[i] -= w;
      diag[j] -= w;
    }
  }
  s = assemble(n, k, rows, cols, vals, diag, L, err);
done:
  free(rows);
  free(cols);
  free(vals);
  free(diag);
  return s;
}

km_status km_uniform_laplacian(const km_mesh *m, km_sparse **L, km_error *err) {
  if (!L) return km__fail(err, KM_ERR_INVALID, "km_uniform_laplacian: L is NULL");
  *L = NULL;
  km_status s = km__check_mesh(m, "km_uniform_laplacian", err);
  if (s) return s;
  size_t n = m->n_vertices, nt = 6 * m->n_faces + n;
  int32_t *rows = km__malloc(nt, sizeof *rows), *cols = km__malloc(nt, sizeof *cols);
  double *vals = km__malloc(nt, sizeof *vals), *diag = km__calloc(n, sizeof *diag);
  if (!rows || !cols || !vals || !diag) {
    s = km__fail(err, KM_ERR_NOMEM, "km_uniform_laplacian: out of memory (%zu vertices)", n);
    goto done;
  }
  size_t k = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    for (int c = 0; c < 3; ++c) {
      int32_t i = t[c], j = t[(c + 1) % 3];
      if (i == j) continue;
      rows[k] = i, cols[k] = j, vals[k++] = 1;
      rows[k] = j, cols[k] = i, vals[k++] = 1;
    }
  }
  s = assemble(n, k, rows, cols, vals, diag, L, err);
  if (s) goto done;
  {
    /* An interior edge appears in two faces and was summed to 2: reset every edge to 1 and
     * the diagonal to minus the number of distinct neighbours. */
    cholmod_sparse *A = km__sparse_cholmod(*L);
    const int32_t *p = A->p, *ri = A->i;
    double *x = A->x;
    for (size_t j = 0; j < n; ++j) {
      int32_t dpos = -1, deg = 0;
      for (int32_t q = p[j]; q < p[j + 1]; ++q) {
        if ((size_t)ri[q] == j)
          dpos = q;
        else
          x[q] = 1, ++deg;
      }
      if (dpos >= 0) x[dpos] = -deg;
    }
  }
done:
  free(rows);
  free(cols);
  free(vals);
  free(diag);
  return s;
}

km_status km_massmatrix(const km_mesh *m, km_mass_type type, km_sparse **M, km_error *err) {
  if (!M) return km__fail(err, KM_ERR_INVALID, "km_massmatrix: M is NULL");
  *M = NULL;
  km_status s = km__check_mesh(m, "km_massmatrix", err);
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
      sub3(m->V + 3 * (size_t)t[(c + 1) % 3], m->V + 3 * (size_t)t[(c + 2) % 3], e);
      l2[c] = dot3(e, e);
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
