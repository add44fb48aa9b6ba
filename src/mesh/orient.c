/* Orientation and units of a mesh file against kinemesh's frame (y up, facing +z, metres):
 * parsing axis names, the rotation of a frame change, applying it, and guessing it.
 *
 * The guess only considers the 24 axis-aligned frames: files are made axis-aligned by every
 * modelling tool and scanner pipeline we know of, and a principal-axes fit of a T-pose or a
 * quadruped picks diagonal axes as often as the right ones. See km_mesh_frame_guess in
 * kinemesh.h for the rules; they are heuristics for humanoids and quadruped animals, which is
 * why the CLI always prints the guess with how to override it. */
#include "mesh/mesh_io.h"

#include <ctype.h>
#include <math.h>
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

km_status km_frame_apply(const km_frame *f, double *P, size_t n_points, double *N, size_t n_normals,
                         km_error *err) {
  double R[9];
  km_status s = km_frame_rotation(f, R, err);
  if (s) return s;
  double sc = f && f->scale != 0 ? f->scale : 1;
  if (!(sc > 0) || !isfinite(sc))
    return km__fail(err, KM_ERR_INVALID, "frame: scale must be positive and finite, got %g", sc);
  if ((n_points && !P) || (n_normals && !N))
    return km__fail(err, KM_ERR_INVALID, "km_frame_apply: NULL array with a non-zero count");
  for (int pass = 0; pass < 2; ++pass) {
    double *X = pass ? N : P;
    size_t n = pass ? n_normals : n_points;
    double k = pass ? 1 : sc;
    for (size_t i = 0; i < n; ++i) {
      double *x = X + 3 * i, y[3] = {0, 0, 0};
      /* R is a signed permutation: each output is one input times +-k, so NaN stays in its
       * own coordinate and nothing is rounded but the scale. */
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          if (R[3 * r + c] != 0) y[r] = k * R[3 * r + c] * x[c];
      memcpy(x, y, sizeof y);
    }
  }
  return KM_OK;
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

/* km_mesh_frame_guess with the up axis given (KM_AXIS_NONE: guessed). */
static km_status frame_guess(const km_mesh *m, km_axis given_up, km_frame_guess *out,
                             km_error *err) {
  if (!m || !out) return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: NULL argument");
  if (given_up < KM_AXIS_NONE || given_up > KM_AXIS_NEG_Z)
    return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: unknown up axis value");
  memset(out, 0, sizeof *out);
  if (!m->n_vertices || !m->V)
    return km__fail(err, KM_ERR_INVALID, "km_mesh_frame_guess: the mesh has no vertices");
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
  /* Up: (1) a model placed on the ground plane at the origin: the one axis whose minimum is
   * within 3% of its extent from 0 (while the others are not); (2) a standing figure: the
   * longest extent when it is 1.5x the next; (3) y when its extent is at least half the
   * longest (the common convention), else z. Sign: (1) +; else the side of the centroid. */
  int up = -1, n_ground = 0, ground = -1;
  for (int c = 0; c < 3; ++c)
    if (fabs(mn[c]) <= 0.03 * ext[c] && mx[c] > 0) ++n_ground, ground = c;
  double all = 0;
  int up_sign = 1;
  if (given_up != KM_AXIS_NONE) {
    up = (given_up - KM_AXIS_POS_X) / 2;
    up_sign = (given_up - KM_AXIS_POS_X) % 2 ? -1 : 1;
    out->sure_up = true;
  } else if (n_ground == 1) {
    up = ground;
    out->sure_up = true;
  } else {
    if (ext[order[0]] >= 1.5 * ext[order[1]])
      up = order[0];
    else
      up = ext[1] >= 0.5 * ext[order[0]] ? 1 : 2;
    double cu = slab_mean(S, n, up, mn[up], ext[up], -1, 2, up, &all);
    double off = (cu - (mn[up] + 0.5 * ext[up])) / ext[up];
    out->sure_up = fabs(off) > 0.01;
    up_sign = out->sure_up && off < 0 ? -1 : 1;
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
  /* Upright (a human): taller than deep; else an animal on four legs. */
  out->standing = ext[up] >= ext[fwd];
  /* Forward's sign, measured with up pointing up: coordinates along up are negated when up
   * is negative, so fractions count from the bottom. */
  double h = ext[up], base = up_sign > 0 ? mn[up] : -mx[up];
  if (up_sign < 0)
    for (size_t i = 0; i < n; ++i)
      S[i].p[up] = -S[i].p[up];
  double d = 0;
  if (out->standing) {
    double feet = slab_mean(S, n, up, base, h, 0, 0.06, fwd, NULL);
    double shins = slab_mean(S, n, up, base, h, 0.08, 0.22, fwd, NULL);
    d = feet - shins;
  } else {
    double top = slab_mean(S, n, up, base, h, 0.7, 1.01, fwd, NULL);
    double mid = slab_mean(S, n, up, base, h, -1, 2, fwd, NULL);
    d = top - mid;
  }
  int fwd_sign = d < 0 ? -1 : 1;
  out->sure_forward = isfinite(d) && fabs(d) > 0.05 * ext[fwd];
  if (!out->sure_forward) fwd_sign = 1;
  free(S);
  out->frame.up = (km_axis)(KM_AXIS_POS_X + 2 * up + (up_sign < 0));
  out->frame.forward = (km_axis)(KM_AXIS_POS_X + 2 * fwd + (fwd_sign < 0));
  out->height = h;
  return KM_OK;
}

km_status km_mesh_frame_guess(const km_mesh *m, km_frame_guess *out, km_error *err) {
  return frame_guess(m, KM_AXIS_NONE, out, err);
}

km_status km_mesh_frame_guess_forward(const km_mesh *m, km_axis up, km_frame_guess *out,
                                      km_error *err) {
  return frame_guess(m, up, out, err);
}
