/* The procedural humanoid: kinemesh's built-in default input.
 *
 * Convention: metres, y up, the character faces +z, T-pose with the arms straight along x,
 * feet soles at y = 0, centred on x = z = 0. "Left" joints are the character's own left,
 * which is the +x side (facing +z with y up, the right hand points to -x).
 *
 * The surface is the zero set of a smooth union (quadratic smooth-min, which keeps the
 * 1-Lipschitz bound of the exact round-cone distances) of tapered capsules around the
 * Kinect v1 skeleton, polygonised by marching tetrahedra (polygonize.c). Each primitive
 * belongs to one joint (the joint whose bone to its child it surrounds; leaf joints own the
 * end blobs), which gives the skin weights directly. */
#include "math/math.h"
#include "motion/motion.h"
#include "synth/polygonize.h"

#include <cjson/cJSON.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_PRIMS 40
#define CULL_ALL UINT64_MAX

typedef struct prim {
  double a[3], b[3], r1, r2;
  /* Precomputed round-cone terms (Quilez' exact distance to a round cone). */
  double ba[3], l2, rr, a2, il2;
  int joint;
} prim;

typedef struct body {
  prim p[MAX_PRIMS];
  int np;
  double k; /* smooth-min blend radius */
  double joints[KM_KINECT1_JOINTS * 3];
  double hand_tip[2][3], toe_tip[2][3], head_top[3];
  double lo[3], hi[3]; /* bounding box of the primitives */
  double height;
  int belly_index; /* index of the belly primitive, -1 when there is none */
  /* Cull grid: per cell, the primitives that can change the field there. */
  double co[3], cs;
  int cn[3];
  uint64_t *mask;
} body;

static void prim_finish(prim *q) {
  for (int k = 0; k < 3; ++k)
    q->ba[k] = q->b[k] - q->a[k];
  q->l2 = q->ba[0] * q->ba[0] + q->ba[1] * q->ba[1] + q->ba[2] * q->ba[2];
  q->rr = q->r1 - q->r2;
  /* A cone whose cap swallows the other end is a sphere. */
  if (q->l2 <= q->rr * q->rr * 1.0001 || q->l2 < 1e-18) {
    if (q->r2 > q->r1) memcpy(q->a, q->b, sizeof q->a), q->r1 = q->r2;
    q->l2 = 0;
    return;
  }
  q->a2 = q->l2 - q->rr * q->rr;
  q->il2 = 1.0 / q->l2;
}

static double prim_sdf(const prim *q, const double p[3]) {
  double pa[3] = {p[0] - q->a[0], p[1] - q->a[1], p[2] - q->a[2]};
  if (q->l2 == 0) return sqrt(pa[0] * pa[0] + pa[1] * pa[1] + pa[2] * pa[2]) - q->r1;
  double y = pa[0] * q->ba[0] + pa[1] * q->ba[1] + pa[2] * q->ba[2];
  double z = y - q->l2;
  double w[3];
  for (int k = 0; k < 3; ++k)
    w[k] = pa[k] * q->l2 - q->ba[k] * y;
  double x2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  double y2 = y * y * q->l2, z2 = z * z * q->l2;
  double kk = (q->rr > 0 ? 1 : q->rr < 0 ? -1 : 0) * q->rr * q->rr * x2;
  double sz = z > 0 ? 1 : z < 0 ? -1 : 0, sy = y > 0 ? 1 : y < 0 ? -1 : 0;
  if (sz * q->a2 * z2 > kk) return sqrt(x2 + z2) * q->il2 - q->r2;
  if (sy * q->a2 * y2 < kk) return sqrt(x2 + y2) * q->il2 - q->r1;
  return (sqrt(x2 * q->a2 * q->il2) + y * q->rr) * q->il2 - q->r1;
}

static double smin(double a, double b, double k) {
  double h = k - fabs(a - b);
  double m = a < b ? a : b;
  return h > 0 ? m - 0.25 * h * h / k : m;
}

static uint64_t cull_mask(const body *b, const double p[3]) {
  if (!b->mask) return CULL_ALL;
  int c[3];
  for (int k = 0; k < 3; ++k) {
    double t = (p[k] - b->co[k]) / b->cs;
    if (!(t >= 0) || t >= b->cn[k]) return CULL_ALL;
    c[k] = (int)t;
  }
  return b->mask[c[0] + b->cn[0] * (c[1] + b->cn[1] * c[2])];
}

static double body_field(void *user, const double p[3]) {
  const body *b = user;
  uint64_t m = cull_mask(b, p);
  double r = prim_sdf(&b->p[0], p);
  for (int i = 1; i < b->np; ++i)
    if (m >> i & 1) r = smin(r, prim_sdf(&b->p[i], p), b->k);
  return r;
}

/* Primitive i can be skipped in a cell when, everywhere in it, it is at least k above an
 * earlier primitive: the smooth-min fold then returns the running value unchanged, so the
 * culled field is bit-identical to the full one. */
static km_status build_cull(body *b, km_error *err) {
  b->cs = 0.04 * b->height;
  double margin = 0.15 * b->height;
  size_t n = 1;
  for (int k = 0; k < 3; ++k) {
    b->co[k] = b->lo[k] - margin;
    b->cn[k] = (int)ceil((b->hi[k] - b->lo[k] + 2 * margin) / b->cs);
    n *= (size_t)b->cn[k];
  }
  b->mask = km__malloc(n, sizeof *b->mask);
  if (!b->mask) return km__fail(err, KM_ERR_NOMEM, "character: out of memory");
  double R = 0.5 * sqrt(3.0) * b->cs;
  for (int z = 0; z < b->cn[2]; ++z)
    for (int y = 0; y < b->cn[1]; ++y)
      for (int x = 0; x < b->cn[0]; ++x) {
        double c[3] = {b->co[0] + (x + 0.5) * b->cs, b->co[1] + (y + 0.5) * b->cs,
                       b->co[2] + (z + 0.5) * b->cs};
        uint64_t m = 1;
        double best_upper = prim_sdf(&b->p[0], c) + R;
        for (int i = 1; i < b->np; ++i) {
          double d = prim_sdf(&b->p[i], c);
          if (d - R < best_upper + b->k) m |= (uint64_t)1 << i;
          if (d + R < best_upper) best_upper = d + R;
        }
        b->mask[x + b->cn[0] * (y + b->cn[1] * z)] = m;
      }
  return KM_OK;
}

/* splitmix64: per-seed proportions. */
static double rnd_factor(uint64_t *s, double spread) {
  uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  double u = (double)(z >> 11) / 9007199254740992.0; /* [0,1) */
  return 1.0 + spread * (2 * u - 1);
}

static void set3(double *d, double x, double y, double z) {
  d[0] = x;
  d[1] = y;
  d[2] = z;
}

static void add_prim(body *b, const double a[3], double r1, const double c[3], double r2,
                     int joint) {
  prim *q = &b->p[b->np++];
  memcpy(q->a, a, sizeof q->a);
  memcpy(q->b, c, sizeof q->b);
  q->r1 = r1;
  q->r2 = r2;
  q->joint = joint;
}

/* Builds the primitives. Proportions are designed for a 1.75 m subject, then scaled so that
 * head top to sole is opt height. min_r: radius floor (coarse grids must not cut wrists). */
/* seed_blend in [0,1] scales the seed's proportion changes (shape transfer walks from the
 * canonical body to the requested one through intermediate bodies). */
static void build_body_blend(body *b, const km_character_options *o, double min_r,
                             double seed_blend) {
  memset(b, 0, sizeof *b);
  uint64_t s = o->seed;
  double fl = 1, fa = 1, fs = 1, fh = 1, ft = 1, fr = 1;
  if (o->seed) {
    fl = 1 + seed_blend * (rnd_factor(&s, 0.05) - 1);
    fa = 1 + seed_blend * (rnd_factor(&s, 0.05) - 1);
    fs = 1 + seed_blend * (rnd_factor(&s, 0.06) - 1);
    fh = 1 + seed_blend * (rnd_factor(&s, 0.04) - 1);
    ft = 1 + seed_blend * (rnd_factor(&s, 0.05) - 1);
    fr = 1 + seed_blend * (rnd_factor(&s, 0.08) - 1);
  }
  double g = o->girth * fr, bel = o->belly;
  double *J = b->joints;
  /* Left side (+x); the right side is mirrored below. */
  double ankle_y = 0.085, knee_y = ankle_y + 0.41 * fl, hip_y = knee_y + 0.42 * fl;
  set3(J + 3 * J_HIP_C, 0, hip_y + 0.03, 0);
  set3(J + 3 * J_SPINE, 0, J[3 * J_HIP_C + 1] + 0.23 * ft, 0);
  set3(J + 3 * J_SHOULDER_C, 0, J[3 * J_SPINE + 1] + 0.26 * ft, 0);
  double sc_y = J[3 * J_SHOULDER_C + 1];
  set3(J + 3 * J_HEAD, 0, sc_y + 0.19 * fh, 0);
  double sh_x = 0.19 * fs, arm_y = sc_y - 0.02;
  set3(J + 3 * J_SHOULDER_L, sh_x, arm_y, 0);
  set3(J + 3 * J_ELBOW_L, sh_x + 0.28 * fa, arm_y, 0);
  set3(J + 3 * J_WRIST_L, sh_x + 0.53 * fa, arm_y, 0);
  set3(J + 3 * J_HAND_L, sh_x + 0.61 * fa, arm_y, 0);
  set3(J + 3 * J_HIP_L, 0.09, hip_y, 0);
  /* Thick legs stand wider so that they stay apart below the crotch. */
  double spread = g > 1 ? g - 1 : 0;
  set3(J + 3 * J_KNEE_L, 0.11 + 0.07 * spread, knee_y, 0);
  set3(J + 3 * J_ANKLE_L, 0.13 + 0.09 * spread, ankle_y, -0.01);
  set3(J + 3 * J_FOOT_L, 0.13 + 0.09 * spread, 0.04, 0.10);
  for (int j = J_SHOULDER_L; j <= J_HAND_L; ++j) {
    memcpy(J + 3 * (j + 4), J + 3 * j, 3 * sizeof *J);
    J[3 * (j + 4)] = -J[3 * j];
  }
  for (int j = J_HIP_L; j <= J_FOOT_L; ++j) {
    memcpy(J + 3 * (j + 4), J + 3 * j, 3 * sizeof *J);
    J[3 * (j + 4)] = -J[3 * j];
  }
  double hc_y = J[3 * J_HIP_C + 1], sp_y = J[3 * J_SPINE + 1], head_y = J[3 * J_HEAD + 1];
  double a[3], c[3];
  /* Torso: three side-by-side tapered capsules per segment give a wider-than-deep section. */
  for (int side = -1; side <= 1; ++side) {
    double rc = side ? 1.0 : 1.08;
    set3(a, side * 0.065, hc_y + 0.02, 0.0);
    set3(c, side * 0.07, sp_y, 0.005);
    add_prim(b, a, 0.105 * rc * g, c, 0.1 * rc * g, J_HIP_C);
  }
  for (int side = -1; side <= 1; ++side) {
    double rc = side ? 1.0 : 1.08;
    set3(a, side * 0.07, sp_y, 0.005);
    set3(c, side * 0.085 * fs, sc_y - 0.07, 0.0);
    add_prim(b, a, 0.1 * rc * g, c, 0.1 * rc * g, J_SPINE);
  }
  set3(a, -0.085, hc_y - 0.03, 0);
  set3(c, 0.085, hc_y - 0.03, 0);
  add_prim(b, a, 0.105 * g, c, 0.105 * g, J_HIP_C);
  /* Fills the top of the V between the thighs, whose crease is too sharp to mesh well. */
  set3(a, 0, hc_y - 0.09, -0.01);
  add_prim(b, a, 0.075 * g, a, 0.075 * g, J_HIP_C);
  b->belly_index = -1;
  if (bel > 0) {
    b->belly_index = b->np;
    /* Grows forward more than down, and stays above the crotch: a belly that reached the
     * thighs would close a handle between them. */
    double r = 0.09 + 0.055 * bel;
    set3(a, 0, hc_y + 0.06 + 0.8 * r, 0.015 + 0.065 * bel);
    add_prim(b, a, r, a, r, J_HIP_C);
  }
  set3(a, 0, sc_y - 0.04, 0);
  set3(c, 0, head_y - 0.06 * fh, 0.005);
  add_prim(b, a, 0.06 * g, c, 0.05 * g, J_SHOULDER_C);
  set3(a, 0, head_y - 0.035 * fh, 0.02 * fh);
  set3(c, 0, head_y + 0.01 * fh, 0);
  add_prim(b, a, 0.08 * fh, c, 0.10 * fh, J_HEAD);
  set3(b->head_top, 0, head_y + 0.11 * fh, 0);
  for (int side = 0; side < 2; ++side) {
    int o4 = side * 4;
    double sx = side ? -1 : 1;
    const double *sh = J + 3 * (J_SHOULDER_L + o4), *el = J + 3 * (J_ELBOW_L + o4),
                 *wr = J + 3 * (J_WRIST_L + o4), *ha = J + 3 * (J_HAND_L + o4);
    set3(a, sx * 0.05, sc_y - 0.02, 0);
    add_prim(b, a, 0.065 * g, sh, 0.055 * g, J_SHOULDER_C);
    add_prim(b, sh, 0.052 * g, el, 0.04 * g, J_SHOULDER_L + o4);
    add_prim(b, el, 0.04 * g, wr, 0.03 * g, J_ELBOW_L + o4);
    add_prim(b, wr, 0.032 * g, ha, 0.038 * g, J_WRIST_L + o4);
    set3(b->hand_tip[side], ha[0] + sx * 0.075 * fa, ha[1], ha[2]);
    add_prim(b, ha, 0.038 * g, b->hand_tip[side], 0.025 * g, J_HAND_L + o4);
    const double *hi = J + 3 * (J_HIP_L + o4), *kn = J + 3 * (J_KNEE_L + o4),
                 *an = J + 3 * (J_ANKLE_L + o4), *fo = J + 3 * (J_FOOT_L + o4);
    add_prim(b, hi, 0.085 * g, kn, 0.055 * g, J_HIP_L + o4);
    add_prim(b, kn, 0.05 * g, an, 0.035 * g, J_KNEE_L + o4);
    set3(a, an[0], 0.045, -0.045);
    add_prim(b, a, 0.045, fo, 0.04, J_ANKLE_L + o4);
    set3(b->toe_tip[side], fo[0], 0.035, fo[2] + 0.075);
    add_prim(b, fo, 0.04, b->toe_tip[side], 0.033, J_FOOT_L + o4);
  }
  /* Scale to the requested height (head top to sole), then sit the soles on y = 0. The radius
   * floor is applied in design units first so that it cannot push the soles below 0. */
  double top = -DBL_MAX, bot = DBL_MAX, sc = 1;
  for (int pass = 0; pass < 2; ++pass) {
    top = -DBL_MAX;
    bot = DBL_MAX;
    for (int i = 0; i < b->np; ++i) {
      prim *q = &b->p[i];
      if (pass) {
        q->r1 = fmax(q->r1, min_r / sc);
        q->r2 = fmax(q->r2, min_r / sc);
      }
      top = fmax(top, fmax(q->a[1] + q->r1, q->b[1] + q->r2));
      bot = fmin(bot, fmin(q->a[1] - q->r1, q->b[1] - q->r2));
    }
    sc = o->height / (top - bot);
  }
  b->height = o->height;
  b->k = fmax(0.03 * sc, 0.8 * min_r);
  for (int i = 0; i < b->np; ++i) {
    prim *q = &b->p[i];
    q->a[1] -= bot;
    q->b[1] -= bot;
    for (int k = 0; k < 3; ++k) {
      q->a[k] *= sc;
      q->b[k] *= sc;
    }
    q->r1 *= sc;
    q->r2 *= sc;
    prim_finish(q);
  }
  double *pts[KM_KINECT1_JOINTS + 5];
  int npts = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    pts[npts++] = J + 3 * j;
  pts[npts++] = b->hand_tip[0];
  pts[npts++] = b->hand_tip[1];
  pts[npts++] = b->toe_tip[0];
  pts[npts++] = b->toe_tip[1];
  pts[npts++] = b->head_top;
  for (int i = 0; i < npts; ++i) {
    pts[i][1] -= bot;
    for (int k = 0; k < 3; ++k)
      pts[i][k] *= sc;
  }
  for (int k = 0; k < 3; ++k) {
    b->lo[k] = DBL_MAX;
    b->hi[k] = -DBL_MAX;
  }
  for (int i = 0; i < b->np; ++i) {
    const prim *q = &b->p[i];
    double r = fmax(q->r1, q->r2);
    for (int k = 0; k < 3; ++k) {
      b->lo[k] = fmin(b->lo[k], fmin(q->a[k], q->b[k]) - r);
      b->hi[k] = fmax(b->hi[k], fmax(q->a[k], q->b[k]) + r);
    }
  }
}

static void build_body(body *b, const km_character_options *o, double min_r) {
  build_body_blend(b, o, min_r, 1.0);
}

/* ---------------------------------------------------------------- skin and landmarks */

/* Weight of joint j from how far the vertex is from j's primitives compared with the nearest
 * primitive: within `band` of the nearest surface, falling off quadratically. */
static void compute_skin(const body *b, const km_mesh *m, km_skin *skin) {
  double band = 0.035 * b->height;
  size_t n = m->n_vertices;
#pragma omp parallel for schedule(static)
  for (size_t v = 0; v < n; ++v) {
    double d[KM_KINECT1_JOINTS];
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      d[j] = DBL_MAX;
    double dmin = DBL_MAX;
    for (int i = 0; i < b->np; ++i) {
      double x = prim_sdf(&b->p[i], m->V + 3 * v);
      int j = b->p[i].joint;
      if (x < d[j]) d[j] = x;
      if (x < dmin) dmin = x;
    }
    double w[KM_KINECT1_JOINTS];
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
      double t = (d[j] - dmin) / band;
      w[j] = t >= 1 ? 0 : (1 - t) * (1 - t);
    }
    km__skin_keep_largest(w, KM_KINECT1_JOINTS, skin->joints + 4 * v, skin->weights + 4 * v);
  }
}

static int32_t nearest_vertex(const km_mesh *m, const double p[3]) {
  double best = DBL_MAX;
  int32_t bi = 0;
  for (size_t v = 0; v < m->n_vertices; ++v) {
    const double *q = m->V + 3 * v;
    double d = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
               (q[2] - p[2]) * (q[2] - p[2]);
    if (d < best) {
      best = d;
      bi = (int32_t)v;
    }
  }
  return bi;
}

/* Landmarks are the surface vertices nearest to points on the primitives' surfaces, so they
 * are defined for any shape and resolution. */
static void compute_landmarks(const body *b, const km_mesh *m, km_landmark *lm) {
  const double *J = b->joints;
  double s = b->height / 1.75, t[KM_CHARACTER_LANDMARKS][3];
  const double *hd = J + 3 * J_HEAD, *sc = J + 3 * J_SHOULDER_C, *sp = J + 3 * J_SPINE,
               *hc = J + 3 * J_HIP_C;
  set3(t[0], 0, hd[1], hd[2] + 0.1 * s);
  set3(t[1], 0, 0.5 * (sc[1] + hd[1]) - 0.03 * s, 0.055 * s);
  set3(t[8], 0, sp[1] + 0.6 * (sc[1] - sp[1]), 0.115 * s);
  set3(t[9], 0, hc[1] - 0.03 * s, 0.105 * s);
  for (int side = 0; side < 2; ++side) {
    int o4 = 4 * side;
    double sx = side ? -1 : 1;
    const double *sh = J + 3 * (J_SHOULDER_L + o4), *el = J + 3 * (J_ELBOW_L + o4),
                 *hi = J + 3 * (J_HIP_L + o4), *kn = J + 3 * (J_KNEE_L + o4);
    set3(t[2 + side], sh[0], sh[1] + 0.055 * s, sh[2]);
    set3(t[4 + side], el[0], el[1] + 0.04 * s, el[2]);
    const double *ht = b->hand_tip[side], *tt = b->toe_tip[side];
    set3(t[6 + side], ht[0] + sx * 0.025 * s, ht[1], ht[2]);
    set3(t[10 + side], hi[0] + sx * 0.1 * s, hi[1], hi[2]);
    set3(t[12 + side], kn[0], kn[1], kn[2] + 0.055 * s);
    set3(t[14 + side], tt[0], tt[1], tt[2] + 0.033 * s);
  }
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    memset(&lm[i], 0, sizeof lm[i]);
    const char *mirror, *name = km_character_landmark_name(i, &mirror);
    snprintf(lm[i].name, sizeof lm[i].name, "%s", name);
    snprintf(lm[i].mirror, sizeof lm[i].mirror, "%s", mirror);
    lm[i].vertex = nearest_vertex(m, t[i]);
  }
}

/* ---------------------------------------------------------------- public API */

static km_status alloc_skeleton(km_skeleton *s, km_error *err) {
  memset(s, 0, sizeof *s);
  s->n_joints = KM_KINECT1_JOINTS;
  s->names = km__calloc(KM_KINECT1_JOINTS, sizeof *s->names);
  s->parents = km__malloc(KM_KINECT1_JOINTS, sizeof *s->parents);
  s->rest = km__malloc(KM_KINECT1_JOINTS * 3, sizeof *s->rest);
  bool ok = s->names && s->parents && s->rest;
  for (int j = 0; ok && j < KM_KINECT1_JOINTS; ++j) {
    s->names[j] = strdup(km_kinect1_joint_name(j));
    ok = s->names[j] != NULL;
    s->parents[j] = km_kinect1_joint_parent(j);
  }
  if (!ok) {
    km_skeleton_free(s);
    return km__fail(err, KM_ERR_NOMEM, "character: out of memory");
  }
  return KM_OK;
}

/* Vertex count of the polygonisation at cell size h (radius floor tied to h). */
static km_status count_at(const km_character_options *o, double h, size_t *n, km_error *err) {
  body *b = malloc(sizeof *b);
  if (!b) return km__fail(err, KM_ERR_NOMEM, "character: out of memory");
  build_body(b, o, 1.0 * h);
  km_status st = build_cull(b, err);
  if (st == KM_OK) st = km__polygonize_count(body_field, b, b->lo, b->hi, h, n, err);
  free(b->mask);
  free(b);
  return st;
}

/* Polygonises the body of options o (already validated) directly; h_out gets the cell size. */
static km_status generate_direct(const km_character_options *opt, km_character *out, double *h_out,
                                 km_error *err) {
  km_character_options o = *opt;

  /* Vertex count ~ area / h^2: measure at a cheap resolution, rescale, correct. */
  double T = (double)o.target_vertices;
  double s = o.height / 1.75;
  size_t probe = o.target_vertices < 20000 ? o.target_vertices : 20000;
  double h = s * sqrt(3.6 / (double)probe);
  size_t n = 0;
  km_status st = KM_OK;
  for (int it = 0; it < 6; ++it) {
    double want = it == 0 ? (double)probe : T;
    if ((st = count_at(&o, h, &n, err)) != KM_OK) return st;
    if (n == 0) return km__fail(err, KM_ERR_DEGENERATE_MESH, "character: empty surface");
    double ratio = (double)n / want;
    h *= sqrt(ratio);
    if (!km__progress(&o.progress, 0.05 * (it + 1), "character: resolution"))
      return km__fail(err, KM_ERR_CANCELLED, "character: cancelled");
    if (it > 0 && fabs(ratio - 1) < 0.02) break;
  }

  body *b = malloc(sizeof *b);
  if (!b) return km__fail(err, KM_ERR_NOMEM, "character: out of memory");
  memset(b, 0, sizeof *b);
  for (int attempt = 0; attempt < 3; ++attempt) {
    free(b->mask);
    build_body(b, &o, 1.0 * h);
    if ((st = build_cull(b, err)) != KM_OK) break;
    if (!km__progress(&o.progress, 0.35, "character: polygonise")) {
      st = km__fail(err, KM_ERR_CANCELLED, "character: cancelled");
      break;
    }
    free(out->mesh.V);
    free(out->mesh.F);
    st = km__polygonize(body_field, b, b->lo, b->hi, h, &out->mesh, err);
    if (st != KM_OK) break;
    double ratio = (double)out->mesh.n_vertices / T;
    if (fabs(ratio - 1) < 0.08) break;
    h *= sqrt(ratio);
  }
  if (st == KM_OK && fabs((double)out->mesh.n_vertices / T - 1) > 0.1)
    st = km__fail(err, KM_ERR_NO_CONVERGENCE,
                  "character: %zu vertices after 3 polygonisations, target %zu +-10%%",
                  out->mesh.n_vertices, o.target_vertices);
  if (st == KM_OK && !km__progress(&o.progress, 0.6, "character: relax"))
    st = km__fail(err, KM_ERR_CANCELLED, "character: cancelled");
  if (st == KM_OK) {
    /* Relax, flip to Delaunay (removes most obtuse triangles, which give negative cotangent
     * weights later), relax again for the new connectivity. */
    double t0 = km_seconds();
    km__surface_relax(&out->mesh, body_field, b, 4, 1e-6 * o.height);
    double t1 = km_seconds();
    size_t flips = km__delaunay_flips(&out->mesh, 8);
    double t2 = km_seconds();
    km__surface_relax(&out->mesh, body_field, b, 3, 1e-6 * o.height);
    km__log(KM_LOG_DEBUG, "character: relax %.3f s, %zu edge flips %.3f s, relax %.3f s", t1 - t0,
            flips, t2 - t1, km_seconds() - t2);
  }
  if (st == KM_OK) st = alloc_skeleton(&out->skeleton, err);
  if (st == KM_OK) {
    memcpy(out->skeleton.rest, b->joints, sizeof b->joints);
    st = km__skin_alloc(&out->skin, out->mesh.n_vertices, err);
  }
  if (st == KM_OK && !km__progress(&o.progress, 0.85, "character: skin"))
    st = km__fail(err, KM_ERR_CANCELLED, "character: cancelled");
  if (st == KM_OK) {
    compute_skin(b, &out->mesh, &out->skin);
    compute_landmarks(b, &out->mesh, out->landmarks);
    km__log(KM_LOG_INFO, "character: %zu vertices, %zu faces (target %zu, cell %.4g m)",
            out->mesh.n_vertices, out->mesh.n_faces, o.target_vertices, h);
    km__progress(&o.progress, 1.0, "character: done");
  }
  free(b->mask);
  free(b);
  if (st != KM_OK) km_character_free(out);
  if (h_out) *h_out = h;
  return st;
}

/* ---------------------------------------------------------------- shape transfer
 *
 * Every subject is the canonical one (seed 0, 1.75 m, girth 1, no belly) polygonised at the
 * requested resolution and mapped onto its own implicit surface, so all subjects of one
 * target_vertices share connectivity (pose transfer and pose databases need that):
 *  1. each vertex is carried by the primitives near it (soft weights on their distance):
 *     for a primitive, the vertex's axial parameter along the canonical segment and its
 *     radial offset (rotated by the minimal rotation between the two segment directions and
 *     scaled by the ratio of the radii there) give its place around the new segment, so
 *     bone-length, offset and thickness changes move it consistently (a per-primitive
 *     form of LBS from the canonical skeleton to the new one);
 *  2. a few Newton steps along the field gradient put it on the new surface;
 *  3. three iterations of tangential relaxation with re-projection (km__surface_relax).
 *  The walk goes through intermediate bodies (height, girth, belly and the seed's proportions
 *  blended from the canonical ones), 1 + ceil(max(|girth-1|/0.25, belly/0.5, |height/1.75-1|
 *  /0.25)) steps, at least 2 with a seed: one big step folds triangles where parts merge
 *  differently (crotch, armpits, a big belly). Vertex count and order never change. */

static double seg_param(const prim *q, const double x[3], double c[3]) {
  double t = 0;
  if (q->l2 > 0) {
    t = ((x[0] - q->a[0]) * q->ba[0] + (x[1] - q->a[1]) * q->ba[1] + (x[2] - q->a[2]) * q->ba[2]) *
        q->il2;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
  }
  for (int k = 0; k < 3; ++k)
    c[k] = q->a[k] + t * (q->l2 > 0 ? q->ba[k] : 0);
  return t;
}

/* Minimal rotation taking unit u onto unit v, applied to r. */
static void rotate_min(const double u[3], const double v[3], const double r[3], double out[3]) {
  double c = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  double w[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  if (c < -0.999999) {
    for (int k = 0; k < 3; ++k)
      out[k] = r[k];
    return;
  }
  /* Rodrigues with k = w/|w|, sin = |w|, cos = c: R r = r c + (w x r) + w (w.r)/(1+c). */
  double wxr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]};
  double wr = w[0] * r[0] + w[1] * r[1] + w[2] * r[2];
  for (int k = 0; k < 3; ++k)
    out[k] = r[k] * c + wxr[k] + w[k] * wr / (1 + c);
}

static void map_vertex(const body *bc, const body *bn, const double x[3], double out[3]) {
  double d[MAX_PRIMS], dmin = DBL_MAX;
  for (int i = 0; i < bc->np; ++i) {
    d[i] = prim_sdf(&bc->p[i], x);
    if (d[i] < dmin) dmin = d[i];
  }
  double sig = bc->k > 0 ? bc->k : 0.03, acc[3] = {0, 0, 0}, wsum = 0;
  for (int i = 0; i < bc->np; ++i) {
    double e = (d[i] - dmin) / sig;
    if (e > 8) continue;
    double w = exp(-e);
    /* The canonical body has no belly primitive; later steps have it at the same index. */
    int j = i + (bc->belly_index < 0 && bn->belly_index >= 0 && i >= bn->belly_index ? 1 : 0);
    const prim *p = &bc->p[i], *q = &bn->p[j];
    double c[3], cn[3], r[3], rr[3];
    double t = seg_param(p, x, c);
    for (int k = 0; k < 3; ++k) {
      r[k] = x[k] - c[k];
      cn[k] = q->a[k] + t * (q->l2 > 0 ? q->ba[k] : 0);
    }
    double ru = p->r1 + t * (p->r2 - p->r1), rv = q->r1 + t * (q->r2 - q->r1);
    double rho = ru > 0 ? rv / ru : 1;
    if (p->l2 > 0 && q->l2 > 0) {
      double lu = sqrt(p->l2), lv = sqrt(q->l2);
      double u[3] = {p->ba[0] / lu, p->ba[1] / lu, p->ba[2] / lu};
      double v[3] = {q->ba[0] / lv, q->ba[1] / lv, q->ba[2] / lv};
      rotate_min(u, v, r, rr);
    } else {
      memcpy(rr, r, sizeof rr);
    }
    for (int k = 0; k < 3; ++k)
      acc[k] += w * (cn[k] + rho * rr[k]);
    wsum += w;
  }
  for (int k = 0; k < 3; ++k)
    out[k] = acc[k] / wsum;
}

static void project_newton(const body *b, double x[3], double eps) {
  for (int it = 0; it < 8; ++it) {
    double f0 = body_field((void *)b, x), g[3];
    if (fabs(f0) < 1e-9 * b->height) return;
    for (int k = 0; k < 3; ++k) {
      double p[3] = {x[0], x[1], x[2]}, m[3] = {x[0], x[1], x[2]};
      p[k] += eps;
      m[k] -= eps;
      g[k] = (body_field((void *)b, p) - body_field((void *)b, m)) / (2 * eps);
    }
    double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    if (g2 < 1e-12) return;
    for (int k = 0; k < 3; ++k)
      x[k] -= f0 * g[k] / g2;
  }
}

static bool is_canonical(const km_character_options *o) {
  return o->seed == 0 && o->height == 1.75 && o->girth == 1.0 && o->belly == 0;
}

km_status km_character_generate(const km_character_options *opt, km_character *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_character_generate: out is NULL");
  memset(out, 0, sizeof *out);
  km_character_options o = {0};
  if (opt) o = *opt;
  if (!o.target_vertices) o.target_vertices = 20000;
  if (o.height == 0) o.height = 1.75;
  if (o.girth == 0) o.girth = 1.0;
  if (o.target_vertices < 2000 || o.target_vertices > 1000000)
    return km__fail(err, KM_ERR_INVALID, "character: target_vertices %zu is outside 2000..1000000",
                    o.target_vertices);
  if (!(o.height >= 0.1 && o.height <= 10))
    return km__fail(err, KM_ERR_INVALID, "character: height %g m is outside 0.1..10", o.height);
  if (!(o.girth >= 0.5 && o.girth <= 1.6))
    return km__fail(err, KM_ERR_INVALID, "character: girth %g is outside 0.5..1.6", o.girth);
  if (!(o.belly >= 0 && o.belly <= 2.0))
    return km__fail(err, KM_ERR_INVALID, "character: belly %g is outside 0..2", o.belly);
  if (is_canonical(&o)) return generate_direct(&o, out, NULL, err);

  km_character_options c = o;
  c.seed = 0, c.height = 1.75, c.girth = 1.0, c.belly = 0;
  double h = 0;
  km_status st = generate_direct(&c, out, &h, err);
  if (st != KM_OK) return st;
  /* Walk from the canonical body to the requested one in small steps (each step maps the
   * vertices from one body to the next and projects them): one big step folds triangles
   * where parts merge differently (crotch, armpits, a large belly). */
  body *bc = malloc(sizeof *bc), *bn = malloc(sizeof *bn);
  if (!bc || !bn) {
    free(bc);
    free(bn);
    km_character_free(out);
    return km__fail(err, KM_ERR_NOMEM, "character: out of memory");
  }
  build_body(bc, &c, 1.0 * h);
  double change =
      fmax(fabs(o.girth - 1) / 0.25, fmax(o.belly / 0.5, fabs(o.height / 1.75 - 1) / 0.25));
  int steps = 1 + (int)ceil(change);
  if (o.seed) steps = steps < 2 ? 2 : steps;
  km_mesh *m = &out->mesh;
  double eps = 1e-6 * o.height;
  for (int k = 1; k <= steps && st == KM_OK; ++k) {
    double lam = (double)k / steps;
    km_character_options ok = o;
    ok.height = 1.75 + lam * (o.height - 1.75);
    ok.girth = 1 + lam * (o.girth - 1);
    ok.belly = lam * o.belly;
    build_body_blend(bn, &ok, 1.0 * h * ok.height / 1.75, lam);
    st = build_cull(bn, err);
    if (st != KM_OK) break;
#pragma omp parallel for schedule(static)
    for (size_t v = 0; v < m->n_vertices; ++v) {
      double x[3];
      map_vertex(bc, bn, m->V + 3 * v, x);
      project_newton(bn, x, eps);
      memcpy(m->V + 3 * v, x, sizeof x);
    }
    /* A light tangential relaxation per step untangles what merging parts squeeze (thighs
     * of a girth-1.6 subject close the gap the canonical crotch has). */
    km__surface_relax(m, body_field, bn, 3, eps);
    if (!km__progress(&o.progress, 0.9 + 0.1 * lam, "character: shape transfer"))
      st = km__fail(err, KM_ERR_CANCELLED, "character: cancelled");
    if (k < steps) {
      /* bn becomes the next step's source. */
      free(bc->mask);
      body *tmp = bc;
      bc = bn;
      bn = tmp;
    }
  }
  if (st == KM_OK) {
    km_mesh *m = &out->mesh;
    memcpy(out->skeleton.rest, bn->joints, sizeof bn->joints);
    compute_skin(bn, m, &out->skin);
    /* Landmarks keep the canonical vertex ids: same connectivity, same landmark vertices. */
    km__progress(&o.progress, 1.0, "character: done");
  }
  free(bn->mask);
  free(bc->mask);
  free(bc);
  free(bn);
  if (st != KM_OK) km_character_free(out);
  return st;
}
