/* Orientation and units of a mesh file against kinemesh's frame (y up, facing +z, metres):
 * parsing axis names, the rotation of a frame change, applying it, and guessing it.
 *
 * The guess only considers the 24 axis-aligned frames: files are made axis-aligned by every
 * modelling tool and scanner pipeline we know of, and a principal-axes fit of a T-pose or a
 * quadruped picks diagonal axes as often as the right ones. See km_mesh_frame_guess in
 * kinemesh.h for the rules; they are heuristics for humanoids and quadruped animals, which is
 * why the CLI always prints the guess with how to override it. */
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const k_axis_names[] = {"none", "+x", "-x", "+y", "-y", "+z", "-z"};

const char *km_axis_name(km_axis a) {
  return (a >= KM_AXIS_NONE && a <= KM_AXIS_NEG_Z) ? k_axis_names[a] : "invalid";
}

km_status km_axis_parse(const char *s, km_axis *out, km_error *err) {
  if (!s || !out) return km__fail(err, KM_ERR_INVALID, "km_axis_parse: NULL argument");
  const char *p = s;
  int sign = 1;
  if (*p == '+' || *p == '-') sign = *p++ == '-' ? -1 : 1;
  char c = (char)tolower((unsigned char)*p);
  if ((c != 'x' && c != 'y' && c != 'z') || p[1] != '\0')
    return km__fail(err, KM_ERR_INVALID, "axis '%s': expected +x, -x, +y, -y, +z or -z", s);
  *out = (km_axis)(KM_AXIS_POS_X + 2 * (c - 'x') + (sign < 0));
  return KM_OK;
}

double km_units_scale(const char *u) {
  if (!u) return 0;
  if (!strcmp(u, "m")) return 1;
  if (!strcmp(u, "cm")) return 0.01;
  if (!strcmp(u, "mm")) return 0.001;
  if (!strcmp(u, "in")) return 0.0254;
  if (!strcmp(u, "ft")) return 0.3048;
  return 0;
}

/* Unit vector of an axis (NONE gives def). */
static void axis_vec(km_axis a, km_axis def, double v[3]) {
  if (a == KM_AXIS_NONE) a = def;
  int i = (a - KM_AXIS_POS_X) / 2;
  v[0] = v[1] = v[2] = 0;
  v[i] = ((a - KM_AXIS_POS_X) % 2) ? -1 : 1;
}

km_status km_frame_rotation(const km_frame *f, double R[9], km_error *err) {
  km_frame z = {0};
  if (!f) f = &z;
  if (f->up < KM_AXIS_NONE || f->up > KM_AXIS_NEG_Z || f->forward < KM_AXIS_NONE ||
      f->forward > KM_AXIS_NEG_Z)
    return km__fail(err, KM_ERR_INVALID, "frame: unknown axis value");
  double u[3], fw[3];
  axis_vec(f->up, KM_AXIS_POS_Y, u);
  axis_vec(f->forward, KM_AXIS_POS_Z, fw);
  if (fabs(u[0] * fw[0] + u[1] * fw[1] + u[2] * fw[2]) > 0.5)
    return km__fail(err, KM_ERR_INVALID,
                    "frame: up %s and forward %s lie on the same axis (they must be "
                    "perpendicular)",
                    km_axis_name(f->up ? f->up : KM_AXIS_POS_Y),
                    km_axis_name(f->forward ? f->forward : KM_AXIS_POS_Z));
  /* Rows: the file's directions that become +x (= up x forward, right-handed), +y, +z. */
  R[0] = u[1] * fw[2] - u[2] * fw[1];
  R[1] = u[2] * fw[0] - u[0] * fw[2];
  R[2] = u[0] * fw[1] - u[1] * fw[0];
  memcpy(R + 3, u, sizeof u);
  memcpy(R + 6, fw, sizeof fw);
  return KM_OK;
}

bool km_frame_is_identity(const km_frame *f) {
  return !f || ((f->up == KM_AXIS_NONE || f->up == KM_AXIS_POS_Y) &&
                (f->forward == KM_AXIS_NONE || f->forward == KM_AXIS_POS_Z) &&
                (f->scale == 0 || f->scale == 1));
}

/* km_frame_apply (inverse false) and km_frame_unapply (true): R is a signed permutation, so
 * each output is one input times +-k (or over k): NaN stays in its own coordinate and nothing
 * is rounded but the scale. */
static km_status frame_map(const km_frame *f, double *P, size_t n_points, double *N,
                           size_t n_normals, bool inverse, km_error *err) {
  double R[9];
  km_status s = km_frame_rotation(f, R, err);
  if (s) return s;
  double sc = f && f->scale != 0 ? f->scale : 1;
  if (!(sc > 0) || !isfinite(sc))
    return km__fail(err, KM_ERR_INVALID, "frame: scale must be positive and finite, got %g", sc);
  if ((n_points && !P) || (n_normals && !N))
    return km__fail(err, KM_ERR_INVALID, "%s: NULL array with a non-zero count",
                    inverse ? "km_frame_unapply" : "km_frame_apply");
  for (int pass = 0; pass < 2; ++pass) {
    double *X = pass ? N : P;
    size_t n = pass ? n_normals : n_points;
    double k = pass ? 1 : sc;
    for (size_t i = 0; i < n; ++i) {
      double *x = X + 3 * i, y[3] = {0, 0, 0};
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          double e = inverse ? R[3 * c + r] : R[3 * r + c]; /* R^T for the inverse */
          if (e != 0) y[r] = inverse ? e * x[c] / k : k * e * x[c];
        }
      memcpy(x, y, sizeof y);
    }
  }
  return KM_OK;
}

km_status km_frame_apply(const km_frame *f, double *P, size_t n_points, double *N, size_t n_normals,
                         km_error *err) {
  return frame_map(f, P, n_points, N, n_normals, false, err);
}

km_status km_frame_unapply(const km_frame *f, double *P, size_t n_points, double *N,
                           size_t n_normals, km_error *err) {
  return frame_map(f, P, n_points, N, n_normals, true, err);
}

km_status km_mesh_frame_apply(const km_frame *f, km_mesh *m, km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_apply: mesh is NULL");
  return km_frame_apply(f, m->V, m->n_vertices, m->N, m->N ? m->n_vertices : 0, err);
}

/* Area-weighted statistics along one axis: centroid of the area whose coordinate along `a`
 * falls in [lo, hi) (fractions of the extent from the minimum), projected on axis b. */
typedef struct sample {
  double p[3], w;
} sample;

static double slab_mean(const sample *S, size_t n, int a, double mn, double ext, double lo,
                        double hi, int b, double *weight) {
  double sw = 0, sb = 0;
  for (size_t i = 0; i < n; ++i) {
    double t = (S[i].p[a] - mn) / ext;
    if (t < lo || t >= hi) continue;
    sw += S[i].w;
    sb += S[i].w * S[i].p[b];
  }
  if (weight) *weight = sw;
  return sw > 0 ? sb / sw : NAN;
}

/* Bin of coordinate x on a grid of n cells of size `cell` from lo, clamped (NaN: bin 0). */
static int bin_of(double x, double lo, double cell, int n) {
  double t = (x - lo) / cell;
  return t >= 0 ? (t < n - 1 ? (int)t : n - 1) : 0;
}

/* Separate patches of the support along direction d (0..5: +x, -x, +y, ...): the vertices
 * within 4% of the extent of the lowest one, binned on a grid of 1/32 of the larger other
 * extent and flood-filled (8-neighbours); patches holding at least 5% of those vertices count.
 * Two feet or four paws make several; a flank, a back, a head or a base make one. */
#define PATCH_GRID 32
static int contact_patches(const km_mesh *m, int d, const double mn[3], const double mx[3],
                           const double ext[3]) {
  int a = d / 2, b1 = (a + 1) % 3, b2 = (a + 2) % 3;
  double cell = fmax(ext[b1], ext[b2]) / PATCH_GRID;
  int n1 = (int)(ext[b1] / cell) + 1, n2 = (int)(ext[b2] / cell) + 1;
  if (n1 > PATCH_GRID) n1 = PATCH_GRID;
  if (n2 > PATCH_GRID) n2 = PATCH_GRID;
  int count[PATCH_GRID * PATCH_GRID] = {0}, stack[PATCH_GRID * PATCH_GRID];
  size_t total = 0;
  for (size_t i = 0; i < m->n_vertices; ++i) {
    const double *p = m->V + 3 * i;
    double t = d % 2 ? (mx[a] - p[a]) : (p[a] - mn[a]);
    if (!(t <= 0.04 * ext[a])) continue;
    ++count[bin_of(p[b1], mn[b1], cell, n1) * n2 + bin_of(p[b2], mn[b2], cell, n2)];
    ++total;
  }
  int patches = 0;
  for (int c0 = 0; c0 < n1 * n2; ++c0) {
    if (count[c0] <= 0) continue;
    size_t in = 0;
    int top = 0;
    stack[top++] = c0;
    in += (size_t)count[c0];
    count[c0] = -1;
    while (top) {
      int c = stack[--top], i1 = c / n2, i2 = c % n2;
      for (int j1 = i1 - 1; j1 <= i1 + 1; ++j1)
        for (int j2 = i2 - 1; j2 <= i2 + 1; ++j2) {
          if (j1 < 0 || j2 < 0 || j1 >= n1 || j2 >= n2 || count[j1 * n2 + j2] <= 0) continue;
          in += (size_t)count[j1 * n2 + j2];
          count[j1 * n2 + j2] = -1;
          stack[top++] = j1 * n2 + j2;
        }
    }
    if (20 * in >= total) ++patches;
  }
  return patches;
}

/* Whether the ground-plane candidate g (a direction 0..5) is contradicted: the mesh stands
 * on several feet along its longest axis, with a support at least twice as wide as g's (a FAUST
 * registration's front lies at z = 0; a cat lying on its side on y = 0 has its longest axis
 * along its body, not across the floor). */
static bool stands_elsewhere(const km_mesh *m, const double support[6], int g, const double mn[3],
                             const double mx[3], const double ext[3]) {
  int best = 0;
  for (int d = 1; d < 6; ++d)
    if (support[d] > support[best]) best = d;
  if (best / 2 == g / 2 || support[best] < 2 * support[g]) return false;
  int a = best / 2;
  for (int c = 0; c < 3; ++c)
    if (c != a && ext[c] > ext[a] / 1.2) return false;
  return contact_patches(m, best, mn, mx, ext) >= 2;
}

/* Toes ahead of the shins: for each foot (a patch of the lowest 6% of the height, binned on a
 * grid of 1/32 of the larger horizontal extent, cells 8-connected), the centroid along `fwd`
 * of the foot against that of the 8-22% of the height right above it (the foot's cells
 * dilated by one), averaged over the feet by the shins' area: a leg kicked forward, or a tail
 * whose tip touches the ground behind, is not a shin. Samples' coordinates along up count
 * from `base` upwards. In fractions of ext[fwd]; NAN when no foot has a shin above it. */
static double toes_ahead(const sample *S, size_t n, int up, double base, double h, int fwd,
                         const double mn[3], const double ext[3]) {
  enum { G = PATCH_GRID * PATCH_GRID };
  int lat = 3 - up - fwd;
  double cell = fmax(ext[fwd], ext[lat]) / PATCH_GRID;
  int nf = (int)(ext[fwd] / cell) + 1, nl = (int)(ext[lat] / cell) + 1;
  if (nf > PATCH_GRID) nf = PATCH_GRID;
  if (nl > PATCH_GRID) nl = PATCH_GRID;
  static const double lo[2] = {0, 0.08}, hi[2] = {0.06, 0.22};
  double w[2][G] = {{0}}, sf[2][G] = {{0}};
  int label[G], grown[G], stack[G];
  for (size_t i = 0; i < n; ++i) {
    double t = (S[i].p[up] - base) / h;
    for (int k = 0; k < 2; ++k) {
      if (!(t >= lo[k] && t < hi[k])) continue;
      int c = bin_of(S[i].p[fwd], mn[fwd], cell, nf) * nl + bin_of(S[i].p[lat], mn[lat], cell, nl);
      w[k][c] += S[i].w;
      sf[k][c] += S[i].w * S[i].p[fwd];
    }
  }
  int n_labels = 0;
  for (int c = 0; c < G; ++c)
    label[c] = -1;
  for (int c0 = 0; c0 < nf * nl; ++c0) {
    if (!(w[0][c0] > 0) || label[c0] >= 0) continue;
    int top = 0;
    stack[top++] = c0;
    label[c0] = n_labels;
    while (top) {
      int c = stack[--top], a0 = c / nl, b0 = c % nl;
      for (int a = a0 - 1; a <= a0 + 1; ++a)
        for (int b = b0 - 1; b <= b0 + 1; ++b)
          if (a >= 0 && b >= 0 && a < nf && b < nl && w[0][a * nl + b] > 0 && label[a * nl + b] < 0)
            label[a * nl + b] = n_labels, stack[top++] = a * nl + b;
    }
    ++n_labels;
  }
  for (int c = 0; c < nf * nl; ++c) { /* the cells next to a foot are above it too */
    grown[c] = label[c];
    for (int a = c / nl - 1; grown[c] < 0 && a <= c / nl + 1; ++a)
      for (int b = c % nl - 1; b <= c % nl + 1; ++b)
        if (a >= 0 && b >= 0 && a < nf && b < nl && label[a * nl + b] >= 0) {
          grown[c] = label[a * nl + b];
          break;
        }
  }
  double d = 0, dw = 0;
  for (int l = 0; l < n_labels; ++l) {
    double fw = 0, fs = 0, sw = 0, ss = 0;
    for (int c = 0; c < nf * nl; ++c) {
      if (label[c] == l) fw += w[0][c], fs += sf[0][c];
      if (grown[c] == l) sw += w[1][c], ss += sf[1][c];
    }
    if (!(fw > 0 && sw > 0)) continue;
    d += sw * (fs / fw - ss / sw);
    dw += sw;
  }
  return dw > 0 ? d / dw / ext[fwd] : NAN;
}

/* The centroid along fwd of the slab just above the narrowest (along lat) of 20 slabs between
 * 0.2 and 0.9 of the height, minus the narrowest's: a jaw over a neck. NAN when a slab is
 * empty. Samples' coordinates along up count from base upwards. */
static double jaw_ahead(const sample *S, size_t n, int up, double base, double h, int fwd,
                        int lat) {
  enum { N = 20 };
  double lo[N], hi[N], w[N] = {0}, sf[N] = {0};
  for (int i = 0; i < N; ++i)
    lo[i] = INFINITY, hi[i] = -INFINITY;
  for (size_t i = 0; i < n; ++i) {
    int k = bin_of(S[i].p[up], base, h / N, N);
    lo[k] = fmin(lo[k], S[i].p[lat]), hi[k] = fmax(hi[k], S[i].p[lat]);
    w[k] += S[i].w, sf[k] += S[i].w * S[i].p[fwd];
  }
  int neck = -1;
  for (int k = (int)(0.2 * N); k <= (int)(0.9 * N) && k + 1 < N; ++k)
    if (w[k] > 0 && (neck < 0 || hi[k] - lo[k] < hi[neck] - lo[neck])) neck = k;
  if (neck < 0 || !(w[neck + 1] > 0)) return NAN;
  return sf[neck + 1] / w[neck + 1] - sf[neck] / w[neck];
}

/* The mesh's shape alone (km__shape_vertices): its body's vertices, in order, and the faces
 * among them that are not collapsed (out->V NULL when that is every vertex and face: use m).
 * A vertex no face uses (an exporter's leftover, a scan's stray point) moved the extent the
 * guess measures: one at (0.5, 0.5, 0.5) beside armadillo_1k turned its guess from facing -z to
 * +z (unsure) and its height from 0.997 to 1.077; so did loose pieces that are no part of the
 * body: armadillo_1k with a ground quad 4 m wide at its feet was guessed unsure of both axes
 * ("stands on its open cut"), with a small piece 100 m away up +x with a height of 100.4, with
 * 300 small pieces scattered in its box (1200 vertices to its 864) up -y. */
static km_status surface_only(const km_mesh *m, km_mesh *out, km_error *err) {
  size_t n = m->n_vertices, nf = 0, nv = 0;
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= n) return KM_OK; /* not one to compact: as it is */
  int32_t *map = km__malloc(n ? n : 1, sizeof *map);
  bool *keep = km__malloc(n ? n : 1, sizeof *keep);
  km_status s = KM_OK;
  if (!map || !keep) {
    s = km__fail(err, KM_ERR_NOMEM, "km_mesh_frame_guess: out of memory");
    goto done;
  }
  if ((s = km__shape_vertices(m, keep, err)) != KM_OK) goto done;
  for (size_t v = 0; v < n; ++v)
    map[v] = keep[v] ? (int32_t)nv++ : -1;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    nf += !km__face_collapsed(t) && keep[t[0]] && keep[t[1]] && keep[t[2]];
  }
  if ((nv < n || nf < m->n_faces) && nv > 0 && nf > 0 &&
      (s = km_mesh_alloc(nv, nf, out, err)) == KM_OK) {
    for (size_t v = 0; v < n; ++v)
      if (map[v] >= 0) memcpy(out->V + 3 * (size_t)map[v], m->V + 3 * v, 3 * sizeof(double));
    for (size_t f = 0, k = 0; f < m->n_faces; ++f) {
      const int32_t *t = m->F + 3 * f;
      if (km__face_collapsed(t) || !keep[t[0]] || !keep[t[1]] || !keep[t[2]]) continue;
      for (int c = 0; c < 3; ++c)
        out->F[3 * k + (size_t)c] = map[t[c]];
      ++k;
    }
  }
done:
  free(map);
  free(keep);
  return s;
}

/* km_mesh_frame_guess with the up axis given (KM_AXIS_NONE: guessed). */
static km_status frame_guess(const km_mesh *m, km_axis given_up, km_frame_guess *out,
                             km_error *err) {
  if (!m || !out) return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: NULL argument");
  if (given_up < KM_AXIS_NONE || given_up > KM_AXIS_NEG_Z)
    return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: unknown up axis value");
  memset(out, 0, sizeof *out);
  if (!m->n_vertices || !m->V)
    return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: the mesh has no vertices");
  if (m->n_faces) { /* the shape alone (surface_only): a leftover vertex, a loose prop */
    km_mesh sm = {0};
    km_status ss = surface_only(m, &sm, err);
    if (ss != KM_OK) return ss;
    if (sm.V) {
      ss = frame_guess(&sm, given_up, out, err);
      km_mesh_free(&sm);
      return ss;
    }
  }
  /* Samples: face centroids weighted by area (the surface's mass), or the vertices of a
   * point cloud. */
  size_t n = m->n_faces ? m->n_faces : m->n_vertices;
  sample *S = km__malloc(n, sizeof *S);
  if (!S) return km__fail(err, KM_ERR_NOMEM, "km_mesh_frame_guess: out of memory");
  double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < m->n_vertices; ++i)
    for (int c = 0; c < 3; ++c) {
      double x = m->V[3 * i + c];
      if (x < mn[c]) mn[c] = x;
      if (x > mx[c]) mx[c] = x;
    }
  for (size_t i = 0; i < n; ++i) {
    if (!m->n_faces) {
      memcpy(S[i].p, m->V + 3 * i, sizeof S[i].p);
      S[i].w = 1;
      continue;
    }
    const double *a = m->V + 3 * (size_t)m->F[3 * i], *b = m->V + 3 * (size_t)m->F[3 * i + 1],
                 *c = m->V + 3 * (size_t)m->F[3 * i + 2];
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k) {
      S[i].p[k] = (a[k] + b[k] + c[k]) / 3;
      e1[k] = b[k] - a[k];
      e2[k] = c[k] - a[k];
    }
    double x = e1[1] * e2[2] - e1[2] * e2[1], y = e1[2] * e2[0] - e1[0] * e2[2],
           z = e1[0] * e2[1] - e1[1] * e2[0];
    S[i].w = 0.5 * sqrt(x * x + y * y + z * z);
  }
  double ext[3];
  for (int c = 0; c < 3; ++c)
    ext[c] = mx[c] - mn[c];
  int order[3] = {0, 1, 2}; /* by extent, longest first */
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (ext[order[j]] > ext[order[i]]) {
        int t = order[i];
        order[i] = order[j];
        order[j] = t;
      }
  if (!(ext[order[0]] > 0) || !(ext[order[2]] > 0)) {
    free(S);
    return km__fail(err, KM_ERR_INVALID,
                    "km_mesh_frame_guess: the mesh is flat or a single point (extents %g, %g, %g)",
                    ext[0], ext[1], ext[2]);
  }
  /* Up, among the 6 directions: (1) a model placed on the ground plane at the origin: the
   * one axis with its minimum within 6% of its extent from 0 and its maximum well above, or
   * its maximum so (a model hanging below the origin: both signs alike, so that a rotated
   * copy is guessed as its original), unless the mesh plainly stands elsewhere (FAUST
   * registrations have their front at z = 0 and stand on two feet along their longest axis;
   * a cat lying on its side on y = 0 does not); (2) ground contact: the surface within 4% of
   * the extent of the lowest point along each direction is its support (feet, hooves, a flat
   * base); up is the direction whose support's bounding rectangle spans the widest part of
   * the cross-section with the centre of mass inside it (it stands), against a head, a nose
   * or a tail tip that touches in one small patch, and never the lateral axis (a standing
   * cat's flank spans as wide as its paws). Only (1)'s refusal looks at which axis is
   * longest: a cat's tail, a T-pose's arms and a horse's neck each make the wrong one
   * longest. */
  int up = -1, n_ground = 0, ground = -1, ground_sign = 1;
  for (int c = 0; c < 3; ++c) {
    if (fabs(mn[c]) <= 0.06 * ext[c] && mx[c] > 0.5 * ext[c])
      ++n_ground, ground = c, ground_sign = 1;
    else if (fabs(mx[c]) <= 0.06 * ext[c] && mn[c] < -0.5 * ext[c])
      ++n_ground, ground = c, ground_sign = -1;
  }
  double com[3] = {0, 0, 0}, all = 0;
  for (size_t i = 0; i < n; ++i) {
    all += S[i].w;
    for (int c = 0; c < 3; ++c)
      com[c] += S[i].w * S[i].p[c];
  }
  for (int c = 0; c < 3; ++c)
    com[c] = all > 0 ? com[c] / all : 0.5 * (mn[c] + mx[c]);
  double support[6];
  for (int d = 0; d < 6; ++d) {
    int a = d / 2, b1 = (a + 1) % 3, b2 = (a + 2) % 3;
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t i = 0; i < m->n_vertices; ++i) {
      const double *p = m->V + 3 * i;
      double t = d % 2 ? (mx[a] - p[a]) : (p[a] - mn[a]);
      if (t > 0.04 * ext[a]) continue;
      lo[0] = fmin(lo[0], p[b1]), hi[0] = fmax(hi[0], p[b1]);
      lo[1] = fmin(lo[1], p[b2]), hi[1] = fmax(hi[1], p[b2]);
    }
    double w1 = (hi[0] - lo[0]) / ext[b1], w2 = (hi[1] - lo[1]) / ext[b2];
    /* how far inside the support the centre of mass is (0 on its edge, 0.5 in its middle) */
    double in1 = fmin(com[b1] - lo[0], hi[0] - com[b1]) / fmax(hi[0] - lo[0], 1e-300 * ext[b1]);
    double in2 = fmin(com[b2] - lo[1], hi[1] - com[b2]) / fmax(hi[1] - lo[1], 1e-300 * ext[b2]);
    double inside = fmax(0, fmin(in1, in2));
    support[d] = (w1 + w2) * (0.5 + inside);
  }
  /* The lateral axis, across the mirror plane: the centroids of slabs cut along either other
   * axis stay on the centre of mass along it (a limb or a tail to one side moves them a
   * little); -1 when no axis is clearly so (a cat lying curled). */
  int lateral = -1;
  {
    double sw[3][10] = {{0}}, sp[3][10][3] = {{{0}}}, wander3[3] = {0, 0, 0};
    for (size_t i = 0; i < n; ++i)
      for (int b = 0; b < 3; ++b) {
        int sl = bin_of(S[i].p[b], mn[b], ext[b] / 10, 10);
        sw[b][sl] += S[i].w;
        for (int a = 0; a < 3; ++a)
          sp[b][sl][a] += S[i].w * S[i].p[a];
      }
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        for (int sl = 0; b != a && sl < 10; ++sl)
          if (sw[b][sl] > 0) wander3[a] += fabs(sp[b][sl][a] - sw[b][sl] * com[a]) / ext[a];
    int lo = 0;
    for (int a = 1; a < 3; ++a)
      if (wander3[a] < wander3[lo]) lo = a;
    bool clear = true;
    for (int a = 0; a < 3; ++a)
      if (a != lo && wander3[lo] >= 0.85 * wander3[a]) clear = false;
    if (clear) lateral = lo;
  }
  double support_max = 0;
  for (int d = 0; d < 6; ++d)
    support_max = fmax(support_max, support[d]);
  int up_sign = 1;
  char up_why[64];
  /* (0) An open cut at one end (km__bust_base_axes: a boundary loop at the lowest 6 % that
   * spans the width, measured across both other axes, in one direction only) that is also the
   * broadest support (2, below): a bust, a head cut at the neck or an upper body stands on its
   * cut, whatever the origin says. A FAUST bust keeps FAUST's coordinates, its face at z = 0,
   * which (1) took for the ground plane (its cut's support 1.49, the next 0.33). Closed meshes
   * and scans whose holes are small (soles, ears) have none; a crown the scanner missed is a
   * cut at the head's narrow top, whose support is no match for the feet's; a tube open at both
   * ends has two and is left to the rules below. */
  int cut_dir = -1, n_cut = 0;
  size_t n_loops = 0; /* the loops found once, asked along every axis (none: a closed mesh) */
  int32_t *loop =
      given_up == KM_AXIS_NONE && m->n_faces ? km__malloc(m->n_vertices, sizeof *loop) : NULL;
  if (loop && km_boundary_loops(m, loop, &n_loops, NULL) != KM_OK) n_loops = 0;
  for (int d = 0; d < 6 && n_loops; ++d) {
    bool both = true;
    for (int k = 1; k <= 2 && both; ++k) {
      bool found = false;
      double top;
      both = km__bust_base_axes_loops(m, loop, n_loops, d / 2, d % 2 ? -1 : 1, (d / 2 + k) % 3,
                                      &found, &top, NULL) == KM_OK &&
             found;
    }
    if (both) cut_dir = d, ++n_cut;
  }
  free(loop);
  if (given_up != KM_AXIS_NONE) {
    up = (given_up - KM_AXIS_POS_X) / 2;
    up_sign = (given_up - KM_AXIS_POS_X) % 2 ? -1 : 1;
    out->sure_up = true;
    snprintf(up_why, sizeof up_why, "given");
  } else if (n_cut == 1 && support[cut_dir] >= support_max) {
    up = cut_dir / 2;
    up_sign = cut_dir % 2 ? -1 : 1;
    out->sure_up = true;
    snprintf(up_why, sizeof up_why, "stands on its open cut");
  } else if (n_ground == 1 &&
             !stands_elsewhere(m, support, 2 * ground + (ground_sign < 0), mn, mx, ext)) {
    up = ground;
    up_sign = ground_sign;
    out->sure_up = true;
    snprintf(up_why, sizeof up_why, "on the ground plane");
  } else {
    /* not on its side: up is not the lateral axis */
    int best = -1;
    for (int d = 0; d < 6; ++d) {
      if (d / 2 == lateral) continue;
      if (best < 0 || support[d] > support[best]) best = d;
    }
    up = best / 2;
    up_sign = best % 2 ? -1 : 1;
    double second = 0;
    for (int d = 0; d < 6; ++d)
      if (d != best && d / 2 != lateral) second = fmax(second, support[d]);
    out->sure_up = support[best] > 1.5 * second;
    snprintf(up_why, sizeof up_why, "ground contact %.2f vs %.2f", support[best], second);
  }
  /* Forward: of the two other axes, the one across the body's plane of mirror symmetry.
   * Humans and animals are left-right symmetric, so the centroid of each height slab stays
   * on the mid-plane along the lateral axis and wanders front-to-back (chest, seat, toes,
   * muzzle) along the forward one. */
  int o1 = (up + 1) % 3, o2 = (up + 2) % 3;
  double wander[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    int a = k ? o2 : o1;
    double mid = 0.5 * (mn[a] + mx[a]), sw = 0;
    for (int sl = 0; sl < 10; ++sl) {
      double w;
      double c =
          slab_mean(S, n, up, mn[up], ext[up], sl / 10.0, (sl + 1) / 10.0 + (sl == 9), a, &w);
      if (!(w > 0)) continue;
      wander[k] += w * fabs(c - mid) / ext[a];
      sw += w;
    }
    if (sw > 0) wander[k] /= sw;
  }
  int fwd = wander[0] >= wander[1] ? o1 : o2;
  /* An animal on four legs (lower than long): its length is forward-back whatever its head
   * and tail do (a head turned sideways wanders across the mirror plane). */
  double lng = fmax(ext[o1], ext[o2]), shrt = fmin(ext[o1], ext[o2]);
  bool clear = fmax(wander[0], wander[1]) >= 1.5 * fmin(wander[0], wander[1]);
  const char *axis_why = "mirror plane";
  if (!clear && ext[up] < lng && lng >= 1.2 * shrt) {
    fwd = ext[o1] >= ext[o2] ? o1 : o2;
    axis_why = "body length";
  }
  /* Upright (a human): taller than deep; else an animal on four legs. */
  out->standing = ext[up] >= ext[fwd];
  /* An animal on four legs is longer than wide (the cats, dogs and horses of ../shared/data:
   * width 0.2-0.8 of length). A body lower than long and about as wide as long is more
   * likely a figure lying down or sprawled (npt_13_643, a man leaning far back with a leg
   * kicked up, rests on his back) or curled up: whatever up the support chose, it is a
   * guess a person should check, so it is not called sure. */
  bool sprawled = !out->standing && ext[3 - up - fwd] >= 0.85 * ext[fwd];
  if (given_up == KM_AXIS_NONE && sprawled && out->sure_up) {
    out->sure_up = false;
    size_t l = strlen(up_why);
    snprintf(up_why + l, sizeof up_why - l, ", as wide as long");
  }
  /* Forward's sign, measured with up pointing up: coordinates along up are negated when up
   * is negative, so fractions count from the bottom. */
  double h = ext[up], base = up_sign > 0 ? mn[up] : -mx[up];
  if (up_sign < 0)
    for (size_t i = 0; i < n; ++i)
      S[i].p[up] = -S[i].p[up];
  /* Fractions of the forward extent; out->sure_forward when one clue is clear. */
  double d = 0, ef = ext[fwd];
  const char *sign_why = "unclear (+)";
  if (out->standing) {
    /* toes reach ahead of the shins above them; else the head (and a face, a snout) sits
     * ahead of the chest and belly; else the upper half reaches farther ahead of its centroid
     * than behind it (a trunk, a muzzle, arms reaching forward; the back is flat) */
    double toes = toes_ahead(S, n, up, base, h, fwd, mn, ext);
    double head = (slab_mean(S, n, up, base, h, 0.85, 1.01, fwd, NULL) -
                   slab_mean(S, n, up, base, h, 0.5, 0.7, fwd, NULL)) /
                  ef;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; ++i)
      if (S[i].p[up] - base >= 0.5 * h) lo = fmin(lo, S[i].p[fwd]), hi = fmax(hi, S[i].p[fwd]);
    double reach = (hi + lo - 2 * slab_mean(S, n, up, base, h, 0.5, 2, fwd, NULL)) / ef;
    out->sure_forward = true;
    if (isfinite(toes) && fabs(toes) >= 0.05)
      d = toes, sign_why = "toes ahead";
    else if (isfinite(head) && fabs(head) >= 0.1)
      d = head, sign_why = "head ahead of chest";
    else if (isfinite(reach) && fabs(reach) >= 0.05)
      d = reach, sign_why = "upper body reaches ahead";
    else {
      out->sure_forward = false;
      /* A bust (open at its bottom) has no toes and its skull sits over its neck: the jaw
       * juts ahead of the neck (the head's lowest slab against the narrowest one below it;
       * 0.034 of the depth on FAUST's top 30 %). A weak clue, left unsure. Full bodies are
       * left out: on FAUST's the slab above the neck's narrowest leans either way. */
      bool bust = false;
      double cut;
      if (km__bust_base_axes(m, up, up_sign, 3 - up - fwd, &bust, &cut, NULL) == KM_OK && bust) {
        double jaw = jaw_ahead(S, n, up, base, h, fwd, 3 - up - fwd) / ef;
        if (isfinite(jaw) && fabs(jaw) >= 0.015)
          d = jaw, sign_why = "a bust's jaw ahead of its neck";
      }
    }
  } else {
    /* an animal: the head is held higher than the body's middle (top), and the front end of
     * its length carries more surface (a head, forelegs) than the back end (a thin tail,
     * which may also rise above the head: hence both) */
    double top = (slab_mean(S, n, up, base, h, 0.7, 1.01, fwd, NULL) -
                  slab_mean(S, n, up, base, h, -1, 2, fwd, NULL)) /
                 ef;
    double front = 0, back = 0;
    for (size_t i = 0; i < n; ++i) {
      double t = (S[i].p[fwd] - mn[fwd]) / ef;
      if (t > 0.85)
        front += S[i].w;
      else if (t < 0.15)
        back += S[i].w;
    }
    double ends = front + back > 0 ? (front - back) / (front + back) : 0;
    d = (isfinite(top) ? top : 0) + 1.2 * ends;
    out->sure_forward = fabs(d) > 0.05;
    if (out->sure_forward) sign_why = "head higher, tail thinner";
  }
  int fwd_sign = d < 0 ? -1 : 1;
  free(S);
  out->frame.up = (km_axis)(KM_AXIS_POS_X + 2 * up + (up_sign < 0));
  out->frame.forward = (km_axis)(KM_AXIS_POS_X + 2 * fwd + (fwd_sign < 0));
  out->height = h;
  snprintf(out->why, sizeof out->why, "up: %s; forward: %s, %s", up_why, axis_why, sign_why);
  return KM_OK;
}

km_status km_mesh_frame_guess(const km_mesh *m, km_frame_guess *out, km_error *err) {
  return frame_guess(m, KM_AXIS_NONE, out, err);
}

km_status km_mesh_frame_guess_forward(const km_mesh *m, km_axis up, km_frame_guess *out,
                                      km_error *err) {
  return frame_guess(m, up, out, err);
}
