/* Automatic rigging (km_autorig): geodesic extremities, a Kinect v1 skeleton embedded from
 * height-normalised slices and geodesic rings, bone heat skin (or distance-to-bone, optionally
 * limited by each bone's reach along the surface), landmarks. The method is described at km_autorig
 * in include/kinemesh.h. */
#include "autorig/autorig.h"

#include "math/math.h"
#include "mesh/mesh.h"
#include "motion/motion.h"
#include "recon/recon.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Height fractions of the joints above the soles, measured on the procedural character
 * (src/synth/character.c: stature 1.75 m). */
#define F_HIP_C 0.540
#define F_SPINE 0.671
#define F_SHOULDER_C 0.820
#define F_HEAD 0.929
#define F_SHOULDER 0.809
#define F_HIP 0.523
#define F_KNEE 0.283
#define F_ANKLE 0.049
#define F_ANKLE_SLICE 0.085 /* above the foot: the leg's section alone */
#define F_FOOT 0.023
#define F_SHOULDER_X 0.109 /* shoulder joint's distance from the mid-line */
/* Arm joints as fractions of the shoulder-to-finger-tip length from the shoulder. */
#define F_ELBOW_ARM 0.394
#define F_WRIST_ARM 0.746
#define F_HAND_ARM 0.859
#define TAIL_T 0.3 /* a tail joins the body below this t (rig_humanoid's hands) */

typedef struct rigger {
  const km_mesh *m;
  size_t n;
  double ymin, ymax, H, ext;
  double zlo, zhi; /* the body's extent along +z (forward) */
  km__geodesic *geo;
  double *dist; /* per extremity: n distances */
  size_t n_ext;
  int32_t ext_v[KM_AUTORIG_MAX_EXTREMITIES];
  double ext_d[KM_AUTORIG_MAX_EXTREMITIES];
  double J[KM_KINECT1_JOINTS * 3];
  int32_t tip[KM_KINECT1_JOINTS]; /* extremity vertex a leaf joint reaches to (-1: none) */
  int32_t *uf;                    /* n: slice union-find */
  unsigned char *on_face;         /* n: 1 for vertices some face uses (others are isolated) */
  double *acc;                    /* n*4: slice contour sums */
  bool quadruped;                 /* the heat probe bends it as a quadruped (probe_stretch) */
} rigger;

static const double *P(const rigger *r, int32_t v) { return r->m->V + 3 * (size_t)v; }
static void set3(double *a, double x, double y, double z) { a[0] = x, a[1] = y, a[2] = z; }
static double dist3(const double *a, const double *b) {
  double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return sqrt(dx * dx + dy * dy + dz * dz);
}

static int32_t nearest_vertex(const rigger *r, const double p[3]) {
  double best = DBL_MAX;
  int32_t bi = 0;
  for (size_t v = 0; v < r->n; ++v) {
    if (r->on_face && !r->on_face[v]) continue;
    double d = dist3(r->m->V + 3 * v, p);
    if (d < best) best = d, bi = (int32_t)v;
  }
  return bi;
}

/* ---------------------------------------------------------------- checks */

static km_status check_mesh(const km_mesh *m, km_error *err) {
  if (!m || !m->V || m->n_vertices == 0) return km__fail(err, KM_ERR_INVALID, "rig: empty mesh");
  if (m->n_faces == 0 || !m->F)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the mesh has no faces (a point cloud cannot be rigged)");
  km_mesh_info info;
  km_status st = km_mesh_info_compute(m, &info, err);
  if (st != KM_OK) return st;
  if (info.components != 1) /* autorig_pieces took or refused several pieces */
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: the mesh has %zu components",
                    info.components);
  /* the file's vertex ids (its order is kept), so that the user can find the edge */
  if (info.nonmanifold_edges)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the mesh has %zu non-manifold edge%s (shared by three or more faces), "
                    "the first between vertices %d and %d; repair it first (Blender: Select > "
                    "Select All by Trait > Non Manifold)",
                    info.nonmanifold_edges, info.nonmanifold_edges > 1 ? "s" : "",
                    (int)info.nonmanifold_edge[0], (int)info.nonmanifold_edge[1]);
  if (!(info.bbox_max[1] - info.bbox_min[1] > 0))
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: the mesh has zero height (y extent)");
  for (size_t i = 0; i < 3 * m->n_vertices; ++i)
    if (!isfinite(m->V[i]))
      return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: vertex %zu has a non-finite coordinate",
                      i / 3);
  return KM_OK;
}

/* ---------------------------------------------------------------- extremities */

/* The mean of the vertices faces use (c, 3); the origin when there are none. */
static void face_centroid(const rigger *r, double c[3]) {
  double cnt = 0;
  c[0] = c[1] = c[2] = 0;
  for (size_t v = 0; v < r->n; ++v)
    if (r->on_face[v]) {
      for (int k = 0; k < 3; ++k)
        c[k] += r->m->V[3 * v + k];
      cnt += 1;
    }
  for (int k = 0; k < 3; ++k)
    c[k] /= cnt > 0 ? cnt : 1;
}

static km_status find_extremities(rigger *r, const km_autorig_options *o, km_error *err) {
  size_t n = r->n, maxe = o->max_extremities ? o->max_extremities : KM_AUTORIG_MAX_EXTREMITIES;
  if (maxe > KM_AUTORIG_MAX_EXTREMITIES) maxe = KM_AUTORIG_MAX_EXTREMITIES;
  double thr = (o->min_extremity > 0 ? o->min_extremity : 0.2) * r->ext;
  double c[3];
  face_centroid(r, c);
  int32_t root = nearest_vertex(r, c);
  double *dmin = km__malloc(n, sizeof *dmin);
  r->dist = km__malloc(n * maxe, sizeof *r->dist);
  r->uf = km__malloc(n, sizeof *r->uf);
  r->acc = km__malloc(4 * n, sizeof *r->acc);
  if (!dmin || !r->dist || !r->uf || !r->acc) {
    free(dmin);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (%zu vertices)", n);
  }
  double *d0 = km__malloc(n, sizeof *d0);
  unsigned char *cand = km__malloc(n, 1);
  if (!d0 || !cand) {
    free(dmin);
    free(d0);
    free(cand);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (%zu vertices)", n);
  }
  const double *d = km__geodesic_run(r->geo, r->m->V, root, INFINITY, NULL, 0, NULL, NULL);
  memcpy(dmin, d, n * sizeof *dmin);
  memcpy(d0, d, n * sizeof *d0);
  for (size_t v = 0; v < n; ++v)
    cand[v] = isfinite(d0[v]);
  /* An extremity is the tip of something: the farthest vertex from the root within rho
   * along the surface (a blob's far side is not one). A vertex that is not is dropped with
   * its ball, all but the ball's farthest vertex. */
  double rho = 0.05 * r->ext;
  size_t checks = 0;
  r->n_ext = 0;
  while (r->n_ext < maxe && checks < 4000) {
    int32_t best = -1;
    double bd = -1;
    for (size_t v = 0; v < n; ++v)
      if (cand[v] && dmin[v] > bd) bd = dmin[v], best = (int32_t)v;
    if (best < 0 || bd < thr) break;
    ++checks;
    const int32_t *ball = NULL;
    size_t nb = 0;
    km__geodesic_run(r->geo, r->m->V, best, rho, NULL, 0, &ball, &nb);
    int32_t far = best;
    for (size_t i = 0; i < nb; ++i)
      if (d0[ball[i]] > d0[far]) far = ball[i];
    if (far != best) {
      for (size_t i = 0; i < nb; ++i)
        if (ball[i] != far) cand[ball[i]] = 0;
      continue;
    }
    if (!km__progress(&o->progress, 0.1 + 0.4 * (double)r->n_ext / (double)maxe, "extremities")) {
      free(dmin);
      free(d0);
      free(cand);
      return km__fail(err, KM_ERR_CANCELLED, "rig: cancelled");
    }
    d = km__geodesic_run(r->geo, r->m->V, best, INFINITY, NULL, 0, NULL, NULL);
    double *dst = r->dist + r->n_ext * n;
    memcpy(dst, d, n * sizeof *dst);
    for (size_t v = 0; v < n; ++v)
      if (dst[v] < dmin[v]) dmin[v] = dst[v];
    r->ext_v[r->n_ext] = best;
    r->ext_d[r->n_ext] = bd;
    ++r->n_ext;
  }
  free(d0);
  free(cand);
  free(dmin);
  return KM_OK;
}

/* ---------------------------------------------------------------- centroids */

/* The mesh cut by the plane y = y0: the cut segments of the faces it crosses, grouped into
 * contours (faces joined through shared vertices). Among the contours whose centroid c has
 * |c.x - xc| < hw and, when side != 0, (c.x - xm) * side > 0, the longest one's centroid
 * (segment midpoints weighted by length) goes to out: the middle of that cross-section of
 * the body (torso, a leg), clear of other parts the plane also cuts (hands, a trunk). With D
 * (n geodesic distances from a foot's tip), the contour of that leg: of the qualifying
 * contours at least 0.3 as long as the longest, the one nearest the tip along the surface. A
 * tail lying on the ground beside a foot is cut at ankle and knee height too, and as the
 * longer contour it took the leg's joints: a standing cat's (cat-05) left ankle went 21 cm
 * behind its foot, the dinosaur's right knee and ankle 21 and 31 cm back along its tail. False
 * when no contour qualifies. */
static bool slice_centroid(rigger *r, double y0, double xc, double hw, double xm, int side,
                           const double *D, double out[3]) {
  const km_mesh *m = r->m;
  int32_t *par = r->uf;
  for (size_t v = 0; v < r->n; ++v)
    par[v] = (int32_t)v, r->acc[4 * v] = r->acc[4 * v + 2] = r->acc[4 * v + 3] = 0,
    r->acc[4 * v + 1] = INFINITY; /* acc[1]: the contour's least D */
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    double ya = P(r, t[0])[1], yb = P(r, t[1])[1], yc = P(r, t[2])[1];
    if (fmin(ya, fmin(yb, yc)) > y0 || fmax(ya, fmax(yb, yc)) < y0) continue;
    km__uf_union(par, t[0], t[1]);
    km__uf_union(par, t[0], t[2]);
  }
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    double q[2][3];
    int k = 0;
    for (int e = 0; e < 3 && k < 2; ++e) {
      const double *p0 = P(r, t[e]), *p1 = P(r, t[(e + 1) % 3]);
      if ((p0[1] < y0) == (p1[1] < y0)) continue;
      double u = (y0 - p0[1]) / (p1[1] - p0[1]);
      for (int i = 0; i < 3; ++i)
        q[k][i] = p0[i] + u * (p1[i] - p0[i]);
      ++k;
    }
    if (k < 2) continue;
    double len = dist3(q[0], q[1]);
    double *a = r->acc + 4 * (size_t)km__uf_find(par, t[0]);
    a[0] += len * 0.5 * (q[0][0] + q[1][0]);
    a[2] += len * 0.5 * (q[0][2] + q[1][2]);
    a[3] += len;
    for (int e = 0; D && e < 3; ++e)
      if (D[t[e]] < a[1]) a[1] = D[t[e]];
  }
  double longest = 0, best = 0;
  bool found = false;
  for (int pass = D ? 0 : 1; pass < 2; ++pass)
    for (size_t v = 0; v < r->n; ++v) {
      const double *a = r->acc + 4 * v;
      if (!(a[3] > 0)) continue;
      double cx = a[0] / a[3], cz = a[2] / a[3];
      if (fabs(cx - xc) >= hw || (side && (cx - xm) * side <= 0)) continue;
      if (pass == 0) { /* with D: the longest qualifying contour first */
        longest = fmax(longest, a[3]);
        continue;
      }
      if (D) {
        if (a[3] >= 0.3 * longest && (!found || a[1] < best))
          best = a[1], found = true, set3(out, cx, y0, cz);
      } else if (a[3] > best) {
        best = a[3], found = true, set3(out, cx, y0, cz);
      }
    }
  return found;
}

/* The geodesic ring at distance d0 from tip (D: every vertex's distance from it; ring_at: of
 * extremity e): the vertices with distance in
 * [d0 - band, d0 + band], band widening until it holds some. Its centroid in out (the tip when
 * none); returns its vertices' mean distance from the centroid when radius is asked for (the
 * thickness of the body part that far from the tip: a head's radius, a forearm's; 0 when
 * none), else 0. */
static double ring_at_field(const rigger *r, const double *D, int32_t tip, double d0, bool radius,
                            double out[3]) {
  for (double band = 0.01 * r->H; band < 0.2 * r->H; band *= 1.6) {
    double s[3] = {0, 0, 0};
    size_t cnt = 0;
    for (size_t v = 0; v < r->n; ++v) {
      if (!(fabs(D[v] - d0) <= band)) continue;
      const double *p = r->m->V + 3 * v;
      s[0] += p[0], s[1] += p[1], s[2] += p[2];
      ++cnt;
    }
    if (cnt < 3) continue;
    set3(out, s[0] / (double)cnt, s[1] / (double)cnt, s[2] / (double)cnt);
    double rad = 0;
    for (size_t v = 0; radius && v < r->n; ++v)
      if (fabs(D[v] - d0) <= band) rad += dist3(r->m->V + 3 * v, out);
    return rad / (double)cnt;
  }
  memcpy(out, P(r, tip), 3 * sizeof *out);
  return 0;
}

static double ring_at(const rigger *r, size_t e, double d0, bool radius, double out[3]) {
  return ring_at_field(r, r->dist + e * r->n, r->ext_v[e], d0, radius, out);
}

static void ring_centroid(const rigger *r, size_t e, double d0, double out[3]) {
  ring_at(r, e, d0, false, out);
}

static double ring_radius(const rigger *r, size_t e, double d0) {
  double c[3];
  return ring_at(r, e, d0, true, c);
}

/* How far along extremity a's geodesics the paths from a to b and from a to h part (the
 * geodesic branch point): 0.5 (d(a,b) + d(a,h) - d(b,h)). From one foot with the other foot
 * and the head: the crotch; from a paw with its pair and the head: the legs' root. */
static double branch_distance(const rigger *r, int a, int b, int h) {
  const double *Da = r->dist + (size_t)a * r->n, *Db = r->dist + (size_t)b * r->n;
  return 0.5 * (Da[r->ext_v[b]] + Da[r->ext_v[h]] - Db[r->ext_v[h]]);
}

/* A limb chain from extremity e (tip) to the root point `root` (a joint already placed):
 * joints[k] at fraction f[k] of the way from the root to the tip, as ring centroids of e at
 * the matching geodesic distance (the root vertex's distance scaled). */
static void limb_chain(const rigger *r, size_t e, const double root[3], const double *f, int k,
                       const int *joints, double *J) {
  int32_t rv = nearest_vertex(r, root);
  double L = r->dist[e * r->n + (size_t)rv];
  if (!isfinite(L) || L <= 0) L = dist3(root, P(r, r->ext_v[e]));
  for (int i = 0; i < k; ++i)
    ring_centroid(r, e, (1 - f[i]) * L, J + 3 * joints[i]);
}

/* ---------------------------------------------------------------- roles */

/* Extremities e and c are two tips of one limb (a heel beside its toes, two claws) unless apart
 * by half the height along the surface, or the surface path between them is 1.6 times their
 * straight distance or more (legs parted by a crotch). */
static bool same_limb(const rigger *r, int e, int c) {
  int32_t a = r->ext_v[e], b = r->ext_v[c];
  double g = r->dist[(size_t)e * r->n + (size_t)b];
  return g < 0.5 * r->H && g < 1.6 * dist3(P(r, a), P(r, b));
}

/* The lowest unused extremity that is not a second tip of a limb already chosen. */
static int lowest_distinct(const rigger *r, const bool *used, const int *chosen, int n_chosen) {
  int best = -1;
  for (size_t e = 0; e < r->n_ext; ++e) {
    if (used[e]) continue;
    bool near = false;
    for (int c = 0; c < n_chosen; ++c)
      if (same_limb(r, (int)e, chosen[c])) near = true;
    if (near) continue;
    if (best < 0 || P(r, r->ext_v[e])[1] < P(r, r->ext_v[best])[1]) best = (int)e;
  }
  return best;
}

static void set_role(km_autorig_report *rep, int e, const char *name) {
  if (rep && e >= 0) snprintf(rep->role[e], sizeof rep->role[e], "%s", name);
}

/* Humanoid: feet, head, hands; then the joints. */
static km_status rig_humanoid(rigger *r, km_autorig_report *rep, km_error *err) {
  if (r->n_ext < 5)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: found %zu extremities (geodesic extremes), a humanoid needs 5 (head, "
                    "two hands, two feet)",
                    r->n_ext);
  bool used[KM_AUTORIG_MAX_EXTREMITIES] = {false};
  int feet[2] = {-1, -1};
  feet[0] = lowest_distinct(r, used, feet, 0);
  used[feet[0]] = true;
  feet[1] = lowest_distinct(r, used, feet, 1);
  if (feet[1] < 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: found one foot only (no second low extremity apart from the first)");
  used[feet[1]] = true;
  int f1 = feet[0], f2 = feet[1];
  const double *p1 = P(r, r->ext_v[f1]), *p2 = P(r, r->ext_v[f2]);
  int foot_l = p1[0] >= p2[0] ? f1 : f2, foot_r = foot_l == f1 ? f2 : f1;
  double xm = 0.5 * (p1[0] + p2[0]);
  /* Head: the most prominent extremity near the feet's mid-line in the top 30 % of the height,
   * else above mid-height (ears and horns are less prominent than the head they sit on; a hand
   * resting on a knee of a body bent forward is more, and was taken for the head of FAUST's
   * tr_reg_001, whose Head joint then sat below its shoulders), among those whose body part a
   * tenth of the height from the tip is at least half as thick as the thickest's (ring_radius):
   * a head is thick there, a raised hand or paw is at its forearm. The cat standing up with its
   * forepaws raised together over its head (cat-05) had the higher paw, on the mid-line, for
   * its head, and an ear for a hand; no other mesh of ../shared/data changed roles. The
   * thickest is taken among the candidates that stick out (the ring's centre at least 0.4 of
   * its geodesic distance from the tip: a head, a paw, a hand) where there are any: a bump on a
   * belly or chest is no body part, and its ring, a tenth of the height round it, is the torso
   * (npt_13_643, an SMPL body leaning back on one leg: its belly, 0.3 there, ring 0.083 of the
   * height, made the head's neck, 0.73 and 0.039, too thin, and the belly was its head; a dome
   * of a head such as the armadillo's, 0.25, or the elephant's still counts where nothing sticks
   * out, and no other mesh of ../shared/data changed roles). */
  int head = -1;
  for (int pass = 0; pass < 2 && head < 0; ++pass) {
    double rad[KM_AUTORIG_MAX_EXTREMITIES] = {0}, rmax = 0, rmax_out = 0;
    bool cand[KM_AUTORIG_MAX_EXTREMITIES] = {false};
    for (size_t e = 0; e < r->n_ext; ++e) {
      if (used[e]) continue;
      const double *p = P(r, r->ext_v[e]);
      if (fabs(p[0] - xm) > 0.15 * r->H || p[1] < r->ymin + (pass ? 0.5 : 0.7) * r->H) continue;
      double c[3];
      cand[e] = true;
      rad[e] = ring_at(r, e, 0.1 * r->H, true, c);
      rmax = fmax(rmax, rad[e]);
      if (dist3(c, p) >= 0.4 * 0.1 * r->H) rmax_out = fmax(rmax_out, rad[e]);
    }
    if (rmax_out > 0) rmax = rmax_out;
    for (size_t e = 0; e < r->n_ext; ++e) {
      if (!cand[e] || rad[e] < 0.5 * rmax) continue;
      if (head < 0 || r->ext_d[e] > r->ext_d[head]) head = (int)e;
    }
  }
  if (head < 0)
    for (size_t e = 0; e < r->n_ext; ++e)
      if (!used[e] && (head < 0 || P(r, r->ext_v[e])[1] > P(r, r->ext_v[head])[1])) head = (int)e;
  if (head < 0) return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: no extremity left for the head");
  used[head] = true;
  /* Hands. An extremity's geodesics to the head top and to the nearer foot part at a point
   * `a` of the head-to-foot path: t = (d_foot - d_head) / d(head, feet) is where along the
   * body (1 at the head top, -1 at the feet) and len = (d_head + d_foot - d(head, feet)) / 2
   * how long the limb is from there. An arm is long and joins at the shoulders; an ear or a
   * horn joins near the top; a bump (knee, shoulder) is short. On each side the hand maximises
   * len * (1 - t) among the extremities that pass the strictest filter some extremity on that
   * side passes:
   *   pass 0: joins below t = 0.9 (not an ear or a horn) and off the mid-line (a trunk, a
   *           tail seen from the front), and as pass 1;
   *   pass 1: not a second tip of a foot nor joining the body down a leg (t >= -0.5: a toe
   *           or claw beside the one taken as the foot; armadillo_1k's left foot has both, and
   *           its other toe outscored the hand up by its ear), not reaching back behind the
   *           feet by 0.2 of the height while joining below TAIL_T (a tail: the dinosaur's,
   *           and the cat standing up with its paws raised overhead, whose left paw's tip is on
   *           the mid-line: t below 0.15; an arm joins at the shoulders, t 0.5-0.8, and may
   *           reach back behind feet kicked forward: SMPL's npt_14_664, leaning back with its
   *           arms raised behind it, lost its right hand to a bump at its hips);
   *   pass 2: any. */
  int hand_l = -1, hand_r = -1;
  double best_l = -1, best_r = -1, len_l = 0, len_r = 0;
  const int32_t hv = r->ext_v[head], flv = r->ext_v[foot_l], frv = r->ext_v[foot_r];
  const double *Dh = r->dist + (size_t)head * r->n;
  double A = 0.5 * (Dh[flv] + Dh[frv]);
  double heel_z = fmin(P(r, flv)[2], P(r, frv)[2]) - 0.2 * r->H;
  for (int pass = 0; pass < 3; ++pass) {
    bool need_l = hand_l < 0, need_r = hand_r < 0;
    for (size_t e = 0; e < r->n_ext; ++e) {
      if (used[e]) continue;
      const double *De = r->dist + e * r->n;
      double t = (fmin(De[flv], De[frv]) - De[hv]) / A;
      double x = P(r, r->ext_v[e])[0] - xm;
      double len = 0.5 * (De[hv] + fmin(De[flv], De[frv]) - A);
      if (pass == 0 && (t > 0.9 || fabs(x) < 0.08 * r->H)) continue;
      if (pass <= 1 && (t < -0.5 || (P(r, r->ext_v[e])[2] < heel_z && t < TAIL_T) ||
                        same_limb(r, (int)e, foot_l) || same_limb(r, (int)e, foot_r)))
        continue;
      double sc = fmax(len, 1e-9 * A) * (1 - fmin(t, 0.99));
      if (need_l && x > 0 && sc > best_l) best_l = sc, hand_l = (int)e, len_l = len;
      if (need_r && x < 0 && sc > best_r) best_r = sc, hand_r = (int)e, len_r = len;
    }
  }
  if (hand_l < 0 || hand_r < 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: no %s hand: no extremity besides the head and feet on the %s side (+x is "
                    "the left of a mesh facing +z)",
                    hand_l < 0 ? "left" : "right", hand_l < 0 ? "+x" : "-x");
  set_role(rep, foot_l, "FootLeft");
  set_role(rep, foot_r, "FootRight");
  set_role(rep, head, "Head");
  set_role(rep, hand_l, "HandLeft");
  set_role(rep, hand_r, "HandRight");

  /* The body's proportions are fractions of its stature, feet to head top: a hand raised
   * above the head is not the body's height (npt_14_664's, 0.22 of the mesh's height over its
   * head, put its shoulders at its chin and its hips at its waist). */
  double top_y = P(r, r->ext_v[head])[1], H = r->H;
  if (fmax(P(r, r->ext_v[hand_l])[1], P(r, r->ext_v[hand_r])[1]) > top_y && top_y > r->ymin)
    H = top_y - r->ymin;
  double *J = r->J, y0 = r->ymin, hw = 0.2 * H, xc = xm;
  /* Heights: a person's proportions (fractions of H), unless the body says otherwise. The
   * legs part at the crotch, found as the ring of one foot at the distance where its
   * geodesics to the other foot and to the head part; the arms join where their ring near
   * the limb's root is. Short legs or low arms (a big head on a small body) lower the hips
   * or the shoulders, and the joints between follow. */
  double hip_y = y0 + F_HIP * H, ankle_y = y0 + F_ANKLE * H, sh_y[2];
  {
    double cd = branch_distance(r, foot_l, foot_r, head);
    double crotch[3];
    if (cd > 0) {
      ring_centroid(r, (size_t)foot_l, cd, crotch);
      /* The hip joints at most 0.04 of the stature above the crotch ring, where a person's
       * hip joint centres are (6-8 cm above the perineum). At a person's proportions (0.523)
       * the procedural character's sat 0.069 above it and the armadillo's 0.088: a thigh
       * swinging forward about a pivot that high drags the skin between the legs, which lies
       * below it (a kick or a lunge: the character's crotch 2.1-2.2x). bench motion B, longest
       * edge l/l0, the table's take order, before -> after: character
       * 2.119/2.240/2.043/2.128/2.236 -> 1.817/1.988/1.755/1.857/1.972, armadillo
       * 1.798/2.195/1.789/1.930/2.001 -> 1.763/2.144/1.784/1.972/1.846, elephant within
       * 0.01. Lower still eases the crotch further (at the ring: character 1.56-1.68) but
       * leaves a person's anatomy, and the generator's own skeleton (0.075 above it). */
      hip_y = fmin(hip_y, crotch[1] + 0.04 * H);
    }
  }
  for (int side = 0; side < 2; ++side) {
    double root[3], len = side ? len_r : len_l;
    sh_y[side] = y0 + F_SHOULDER * H;
    if (len > 0) {
      ring_centroid(r, (size_t)(side ? hand_r : hand_l), 0.9 * len, root);
      if (root[1] < sh_y[side] - 0.12 * H) sh_y[side] = root[1];
    }
  }
  /* Shoulders are level: the higher of the two (the decimated knight's rings from its two hands,
   * 2.5 cm apart along its arms, put its right shoulder 5 % of its height below its left, inside
   * the armpit); the shoulder centre already sat above the higher. */
  sh_y[0] = sh_y[1] = fmax(sh_y[0], sh_y[1]);
  double hipc_y = hip_y + (F_HIP_C - F_HIP) * H;
  double sc_y = fmax(sh_y[0], sh_y[1]) + (F_SHOULDER_C - F_SHOULDER) * H;
  double knee_y = ankle_y + (F_KNEE - F_ANKLE) / (F_HIP - F_ANKLE) * (hip_y - ankle_y);
  double ty[4] = {hipc_y, hipc_y + (F_SPINE - F_HIP_C) / (F_SHOULDER_C - F_HIP_C) * (sc_y - hipc_y),
                  sc_y, sc_y + (F_HEAD - F_SHOULDER_C) / (1 - F_SHOULDER_C) * (top_y - sc_y)};
  static const int tj[4] = {J_HIP_C, J_SPINE, J_SHOULDER_C, J_HEAD};
  for (int i = 0; i < 4; ++i)
    if (!slice_centroid(r, ty[i], xc, hw, 0, 0, NULL, J + 3 * tj[i]))
      set3(J + 3 * tj[i], xc, ty[i], P(r, r->ext_v[head])[2]);
  /* A raised foot (a kick, a step: its tip above the ankle's cut) is not met by the cuts at
   * ankle and knee height: its ankle went to the floor under its toes, npt_14_664's left one
   * 0.12 of the height outside the body, the shin running down to it. Its ankle and knee are
   * the rings of its tip's geodesics as far from the tip as the grounded foot's ankle and knee
   * are from that one's tip (the legs placed grounded first). */
  double raise_y = y0 + F_ANKLE_SLICE * H, d_ankle = -1, d_knee = -1;
  int first = P(r, r->ext_v[foot_l])[1] > raise_y && !(P(r, r->ext_v[foot_r])[1] > raise_y);
  for (int k = 0; k < 2; ++k) {
    int side = k ^ first;
    int o4 = 4 * side, foot = side ? foot_r : foot_l, hand = side ? hand_r : hand_l;
    double sx = side ? -1 : 1;
    const double *toe = P(r, r->ext_v[foot]);
    double *kn = J + 3 * (J_KNEE_L + o4), *an = J + 3 * (J_ANKLE_L + o4),
           *ft = J + 3 * (J_FOOT_L + o4), *hp = J + 3 * (J_HIP_L + o4);
    const double *Df = r->dist + (size_t)foot * r->n;
    if (toe[1] > raise_y && d_ankle > 0) {
      ring_centroid(r, (size_t)foot, d_knee, kn);
      ring_centroid(r, (size_t)foot, d_ankle, an);
      for (int c = 0; c < 3; ++c)
        ft[c] = an[c] + 0.5 * (toe[c] - an[c]);
    } else {
      if (!slice_centroid(r, knee_y, toe[0], 0.15 * H, xm, side ? -1 : 1, Df, kn))
        set3(kn, toe[0], knee_y, toe[2]);
      if (!slice_centroid(r, y0 + F_ANKLE_SLICE * H, toe[0], 0.15 * H, xm, side ? -1 : 1, Df, an))
        set3(an, toe[0], ankle_y, toe[2]);
      an[1] = ankle_y;
      set3(ft, an[0], y0 + F_FOOT * H, an[2] + 0.5 * (toe[2] - an[2]));
      if (!(toe[1] > raise_y)) {
        d_ankle = Df[nearest_vertex(r, an)];
        d_knee = Df[nearest_vertex(r, kn)];
      }
    }
    const double *hc = J + 3 * J_HIP_C;
    set3(hp, hc[0] + 0.82 * (kn[0] - hc[0]), hip_y, hc[2]);
    /* Arm: the shoulder beside the shoulder centre, then rings from the hand tip. */
    const double *sc = J + 3 * J_SHOULDER_C;
    double *sh = J + 3 * (J_SHOULDER_L + o4);
    set3(sh, sc[0] + sx * F_SHOULDER_X * H, sh_y[side], sc[2]);
    static const double af[3] = {F_ELBOW_ARM, F_WRIST_ARM, F_HAND_ARM};
    int aj[3] = {J_ELBOW_L + o4, J_WRIST_L + o4, J_HAND_L + o4};
    limb_chain(r, (size_t)hand, sh, af, 3, aj, J);
    r->tip[J_HAND_L + o4] = r->ext_v[hand];
    r->tip[J_FOOT_L + o4] = r->ext_v[foot];
  }
  r->tip[J_HEAD] = r->ext_v[head];
  return KM_OK;
}

/* Where the paths from two paws a and b part from the path to the head h (branch_distance
 * along a's field and along b's), as the middle of the two rings there: between the legs, at
 * their root, whatever the pose. */
static void branch_point(const rigger *r, int a, int b, int h, double out[3]) {
  double p[3], q[3];
  ring_centroid(r, (size_t)a, branch_distance(r, a, b, h), p);
  ring_centroid(r, (size_t)b, branch_distance(r, b, a, h), q);
  for (int k = 0; k < 3; ++k)
    out[k] = 0.5 * (p[k] + q[k]);
}

/* Quadruped: four lowest extremities are limbs, the highest other one the head. */
static km_status rig_quadruped(rigger *r, km_autorig_report *rep, km_error *err) {
  if (r->n_ext < 5)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: found %zu extremities (geodesic extremes), a quadruped needs 5 (four "
                    "limbs and a head)",
                    r->n_ext);
  bool used[KM_AUTORIG_MAX_EXTREMITIES] = {false};
  int limb[4] = {-1, -1, -1, -1};
  double fc[3] = {0, 0, 0};
  /* Limbs: the most prominent of the low extremities (the bottom quarter of the height) that
   * are as thin a tenth of the height from their tip as limbs (ring_radius within 1.25 times
   * the median of the four thinnest low ones), leaving out a tail (an extremity 1.3 times as
   * prominent as any other: a cat's tail tip, 1.45-1.65 times its most prominent paw's); when
   * fewer than four, the most prominent others below half the height and within 1.4 times (a
   * paw raised to the mouth); when still too few, the lowest distinct ones. A sitting animal
   * has more on the ground than its paws: its rump, its hocks and its tail (the sitting cat
   * cat-08 had a point of its tail for a hind paw, cat-09, licking a raised forepaw, its rump
   * and its tail tip), which the lowest four took. Paws measure 1.02-1.14 times that median on
   * the cats, dog0 and the horse; cat-09's point of its tail 1.32, rumps and hocks 1.6-2.5. */
  int tier[KM_AUTORIG_MAX_EXTREMITIES] = {0}; /* 1: a limb, 2: one if too few, 0: none */
  {
    double rad[KM_AUTORIG_MAX_EXTREMITIES], sorted[KM_AUTORIG_MAX_EXTREMITIES];
    bool low[KM_AUTORIG_MAX_EXTREMITIES];
    size_t n_low = 0;
    for (size_t e = 0; e < r->n_ext; ++e) {
      double y = P(r, r->ext_v[e])[1] - r->ymin;
      rad[e] = y < 0.5 * r->H ? ring_radius(r, e, 0.1 * r->H) : INFINITY;
      if ((low[e] = y < 0.25 * r->H)) sorted[n_low++] = rad[e];
    }
    qsort(sorted, n_low, sizeof *sorted, km__cmp_double);
    size_t k = n_low < 4 ? n_low : 4;
    double ref = k ? (k % 2 ? sorted[k / 2] : 0.5 * (sorted[k / 2 - 1] + sorted[k / 2])) : 0;
    int top = -1;
    for (size_t e = 0; e < r->n_ext; ++e) {
      tier[e] = low[e] && rad[e] <= 1.25 * ref ? 1 : rad[e] <= 1.4 * ref ? 2 : 0;
      if (top < 0 || r->ext_d[e] > r->ext_d[top]) top = (int)e;
    }
    bool tail = top >= 0;
    for (size_t e = 0; tail && e < r->n_ext; ++e)
      if ((int)e != top && !(r->ext_d[top] >= 1.3 * r->ext_d[e])) tail = false;
    if (tail) tier[top] = 0;
  }
  for (int i = 0; i < 4; ++i) {
    for (int t = 1; t <= 2 && limb[i] < 0; ++t)
      for (size_t e = 0; e < r->n_ext; ++e) {
        if (used[e] || tier[e] != t) continue;
        bool near = false;
        for (int c = 0; c < i; ++c)
          near |= same_limb(r, (int)e, limb[c]);
        if (!near && (limb[i] < 0 || r->ext_d[e] > r->ext_d[limb[i]])) limb[i] = (int)e;
      }
    if (limb[i] < 0) limb[i] = lowest_distinct(r, used, limb, i);
    if (limb[i] < 0)
      return km__fail(err, KM_ERR_DEGENERATE_MESH,
                      "rig: found %d distinct limbs (low extremities), a quadruped needs 4", i);
    used[limb[i]] = true;
    for (int k = 0; k < 3; ++k)
      fc[k] += 0.25 * P(r, r->ext_v[limb[i]])[k];
  }
  /* Head: the highest other extremity ahead of the feet (kinemesh's frame faces +z), so a
   * tail held up is not taken for it (cat-03 walking, cat-06 stretching); the highest of all
   * when none is ahead. */
  int head = -1;
  for (int pass = 0; pass < 2 && head < 0; ++pass)
    for (size_t e = 0; e < r->n_ext; ++e)
      if (!used[e] && (pass || P(r, r->ext_v[e])[2] > fc[2]) &&
          (head < 0 || P(r, r->ext_v[e])[1] > P(r, r->ext_v[head])[1]))
        head = (int)e;
  /* Forward: kinemesh's (+z; the mesh is oriented before it is rigged), pointing to the head.
   * The feet's principal horizontal axis, used before, lies across the body when the paws
   * spread wider than long: a sitting animal's hind paws stand beside its front ones (the
   * sitting cat cat-02 had a hind paw and a front paw for its hands, cat-08 two); dog0's, the
   * horse's and the other cats' roles are the same either way. */
  double fw[3] = {0, 0, 1};
  const double *hp = P(r, r->ext_v[head]);
  if ((hp[0] - fc[0]) * fw[0] + (hp[2] - fc[2]) * fw[2] < 0) fw[0] = -fw[0], fw[2] = -fw[2];
  double left[3] = {fw[2], 0, -fw[0]}; /* up x forward */
  /* front pair = the two with the largest forward projection */
  double proj[4], lat[4];
  for (int i = 0; i < 4; ++i) {
    const double *p = P(r, r->ext_v[limb[i]]);
    proj[i] = (p[0] - fc[0]) * fw[0] + (p[2] - fc[2]) * fw[2];
    lat[i] = (p[0] - fc[0]) * left[0] + (p[2] - fc[2]) * left[2];
  }
  int ord[4] = {0, 1, 2, 3};
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b)
      if (proj[ord[b]] > proj[ord[a]]) {
        int t = ord[a];
        ord[a] = ord[b], ord[b] = t;
      }
  /* ord[0..1] front, ord[2..3] hind; left = larger lateral */
  int fl = lat[ord[0]] >= lat[ord[1]] ? ord[0] : ord[1], fr = fl == ord[0] ? ord[1] : ord[0];
  int hl = lat[ord[2]] >= lat[ord[3]] ? ord[2] : ord[3], hr = hl == ord[2] ? ord[3] : ord[2];
  int e_fl = limb[fl], e_fr = limb[fr], e_hl = limb[hl], e_hr = limb[hr];
  set_role(rep, e_fl, "HandLeft");
  set_role(rep, e_fr, "HandRight");
  set_role(rep, e_hl, "FootLeft");
  set_role(rep, e_hr, "FootRight");
  set_role(rep, head, "Head");

  double *J = r->J, c[3] = {0, 0, 0};
  for (size_t v = 0; v < r->n; ++v)
    for (int k = 0; k < 3; ++k)
      c[k] += r->m->V[3 * v + k] / (double)r->n;
  double front[3] = {0, 0, 0}, hind[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    front[k] = 0.5 * (P(r, r->ext_v[e_fl])[k] + P(r, r->ext_v[e_fr])[k]);
    hind[k] = 0.5 * (P(r, r->ext_v[e_hl])[k] + P(r, r->ext_v[e_hr])[k]);
  }
  /* The spine at the middle of the trunk's height, measured across the middle of the body
   * between the front and hind feet (no leg there; a slice touching the ground is a leg or a
   * tail: then the centroid's height). At the mesh's centroid, pulled down by the legs, it ran
   * along dog0's and the horse's belly. bench motion B, longest edge, the table's take order,
   * before -> after: dog0 1.294/1.247/1.282/1.346/1.334 -> 1.257/1.200/1.238/1.301/1.292x,
   * horse 1.301/1.264/1.300/1.287/1.272 -> 1.313/1.248/1.336/1.275/1.262x, the walking cat
   * (cat-03) 1.309/1.283/1.308/1.447/1.442 -> 1.272/1.297/1.317/1.428/1.424x; no fold before
   * or after, shortest edges longer on all but two rows (horse CMU 0.748/0.749 ->
   * 0.726/0.738). */
  double ys = c[1], ylo = DBL_MAX, yhi = -DBL_MAX, zm = 0.5 * (front[2] + hind[2]);
  double slab = 0.05 * fabs(front[2] - hind[2]);
  for (size_t v = 0; v < r->n; ++v) {
    const double *p = P(r, (int32_t)v);
    if (r->on_face[v] && fabs(p[2] - zm) <= slab) ylo = fmin(ylo, p[1]), yhi = fmax(yhi, p[1]);
  }
  if (yhi > ylo && ylo > r->ymin) ys = 0.5 * (ylo + yhi);
  /* Where each leg meets the trunk along the body: the ring of its paw's geodesics whose
   * centroid reaches the belly's height (ylo, measured as above; none when that slab touches
   * the ground: then above the paws, as before). dog0's hind legs slant back to paws under its
   * rump: a hip above the paws sat on the rump's back edge, the thigh's bone outside its
   * thigh. bench motion --skin, L (the rig's skeleton and weights skinning the mesh, what an
   * engine does with the export), longest edge, cmu_131_01 / cmu_131_03 / precog_Seq1_1,
   * before -> after: dog0 2.31/2.23/2.04 -> 1.93/1.87/2.03x (folds 29 -> 10 on the last),
   * horse 2.14/2.06/2.51 -> 2.02/1.93/2.36x, cat-reference 1.74/1.92/2.42 -> 1.90/1.84/2.41x
   * (11 and 8 folds on the CMU takes, none before); B within 0.04x on every row of the three. */
  const int leg_e[4] = {e_fl, e_fr, e_hl, e_hr};
  double leg_z[4] = {NAN, NAN, NAN, NAN}; /* NaN: no belly measured (a slab on the ground) */
  for (int i = 0; i < 4; ++i) {
    const double *tp = P(r, r->ext_v[leg_e[i]]);
    if (!(yhi > ylo && ylo > tp[1])) continue;
    for (double d = 0.5 * (ylo - tp[1]); d < 2 * r->H; d += 0.02 * r->H) {
      double q[3];
      ring_centroid(r, (size_t)leg_e[i], d, q);
      if (q[1] >= ylo) {
        leg_z[i] = q[2];
        break;
      }
    }
  }
  bool meet_f = isfinite(leg_z[0] + leg_z[1]), meet_h = isfinite(leg_z[2] + leg_z[3]);
  set3(J + 3 * J_HIP_C, hind[0], ys, meet_h ? 0.5 * (leg_z[2] + leg_z[3]) : hind[2]);
  set3(J + 3 * J_SHOULDER_C, front[0], ys, meet_f ? 0.5 * (leg_z[0] + leg_z[1]) : front[2]);
  /* A sitting body (its four paws on the ground, its trunk rising from the hind legs to the
   * front ones: where the front paws' paths part from the head's, 0.12 of the height or more
   * above where the hind paws' do): the trunk's middle slice above runs through the haunches
   * or the chest, not along the spine. Sitting cats had their hips at the chest (cat-02) or
   * the whole spine along the ground between the paws, outside the body (cat-08). Their spine
   * runs from where the hind legs part (branch_point) to a quarter of the way from where the
   * front legs part to the head: the bottom of the chest is no neck, and a head turning about
   * it swung the snout round (pose, the skinned export, on cat-02: longest edge 2.67 -> 4.66x
   * there; 2.47x with the quarter). Measured, animate / pose on precog_Seq1_1 and cmu_131_01,
   * longest edge, shortest, folded triangles, before -> after: cat-02 1.25/0.07/36 and
   * 1.17/0.06/37 -> 1.33/0.70/0 and 1.23/0.77/0, pose 2.67/0.24/8 and 2.35/0.11/30 ->
   * 2.47/0.32/4 and 2.11/0.21/4; cat-08 1.32/0.07/0 and 1.33/0.05/0 -> 1.77/0.50/0 and
   * 1.63/0.53/0, pose 2.37/0.08/15 and 2.16/0.29/9 -> 1.75/0.17/10 and 1.77/0.18/11. A paw raised
   * off the ground (cat-09 licking one) leaves the rule as it was: its path parts from the other
   * paw's at the chin, and the skinned export stretched 2.80 / 2.87x instead of 1.73 / 1.99x.
   * Standing bodies: their front branch point lies 0.19 below to 0.01 above the hind one (the
   * cats, dog0, the horse), unchanged. */
  bool grounded = true;
  for (int i = 0; i < 4; ++i)
    grounded &= P(r, r->ext_v[leg_e[i]])[1] < r->ymin + 0.1 * r->H;
  if (grounded) {
    double bh[3], bf[3], top[3];
    branch_point(r, e_hl, e_hr, head, bh);
    branch_point(r, e_fl, e_fr, head, bf);
    if (bf[1] - bh[1] > 0.12 * r->H) {
      ring_centroid(r, (size_t)head, 0.12 * r->H, top); /* the Head joint, below */
      for (int k = 0; k < 3; ++k)
        bf[k] += 0.25 * (top[k] - bf[k]);
      memcpy(J + 3 * J_HIP_C, bh, sizeof bh);
      memcpy(J + 3 * J_SHOULDER_C, bf, sizeof bf);
    }
  }
  for (int k = 0; k < 3; ++k)
    J[3 * J_SPINE + k] = 0.5 * (J[3 * J_HIP_C + k] + J[3 * J_SHOULDER_C + k]);
  double hd = 0.12 * r->H;
  ring_centroid(r, (size_t)head, hd, J + 3 * J_HEAD);
  struct {
    int e, root, j0, anchor;
  } limbs[4] = {{e_fl, J_SHOULDER_L, J_ELBOW_L, J_SHOULDER_C},
                {e_fr, J_SHOULDER_R, J_ELBOW_R, J_SHOULDER_C},
                {e_hl, J_HIP_L, J_KNEE_L, J_HIP_C},
                {e_hr, J_HIP_R, J_KNEE_R, J_HIP_C}};
  for (int i = 0; i < 4; ++i) {
    const double *tp = P(r, r->ext_v[limbs[i].e]), *an = J + 3 * limbs[i].anchor;
    double *rt = J + 3 * limbs[i].root;
    /* limb root: beside the spine joint, halfway out towards the foot, where the leg meets
     * the trunk along the body */
    bool meet = i < 2 ? meet_f : meet_h;
    set3(rt, an[0] + 0.5 * (tp[0] - an[0]), an[1], meet ? leg_z[i] : an[2] + 0.5 * (tp[2] - an[2]));
    static const double lf[3] = {0.5, 0.85, 0.95};
    int lj[3] = {limbs[i].j0, limbs[i].j0 + 1, limbs[i].j0 + 2};
    limb_chain(r, (size_t)limbs[i].e, rt, lf, 3, lj, J);
    r->tip[limbs[i].j0 + 2] = r->ext_v[limbs[i].e];
  }
  r->tip[J_HEAD] = r->ext_v[head];
  return KM_OK;
}

/* Prop (a bust, an object: too few extremities for limbs): five handle points by position,
 * the highest vertex for the head, the outermost upper vertex on each side for the hands, the
 * lowest outer vertex on each side for the feet, each at least 0.2 H along the surface from
 * the others; the joints on straight lines from the centroid to them. */
static km_status rig_prop(rigger *r, km_autorig_report *rep, km_error *err) {
  size_t n = r->n;
  double c[3], H = r->H;
  face_centroid(r, c);
  double *dmin = km__malloc(n, sizeof *dmin);
  if (!dmin) return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  for (size_t v = 0; v < n; ++v)
    dmin[v] = INFINITY;
  /* order: head, hand_left, hand_right, foot_left, foot_right */
  int32_t pick[5];
  for (int h = 0; h < 5; ++h) {
    double best = -DBL_MAX;
    int32_t bv = -1;
    for (size_t v = 0; v < n; ++v) {
      if (!r->on_face[v] || !(dmin[v] > 0.2 * H)) continue;
      const double *p = r->m->V + 3 * v;
      double x = (p[0] - c[0]) / r->ext, y = (p[1] - r->ymin) / H, sc;
      switch (h) {
      case 0: sc = y; break;
      case 1: sc = x + 0.5 * y; break;
      case 2: sc = -x + 0.5 * y; break;
      case 3: sc = x - y; break;
      default: sc = -x - y; break;
      }
      if (sc > best) best = sc, bv = (int32_t)v;
    }
    if (bv < 0) {
      free(dmin);
      return km__fail(err, KM_ERR_DEGENERATE_MESH,
                      "rig: the mesh is too small along its surface for five handles 0.2 of its "
                      "height apart (found %d)",
                      h);
    }
    pick[h] = bv;
    const double *d = km__geodesic_run(r->geo, r->m->V, bv, INFINITY, NULL, 0, NULL, NULL);
    for (size_t v = 0; v < n; ++v)
      if (d[v] < dmin[v]) dmin[v] = d[v];
  }
  free(dmin);
  static const char *const roles[5] = {"Head", "HandLeft", "HandRight", "FootLeft", "FootRight"};
  if (rep)
    for (int h = 0; h < 5 && rep->n_extremities < KM_AUTORIG_MAX_EXTREMITIES; ++h) {
      size_t e = rep->n_extremities++;
      rep->extremity[e] = pick[h];
      rep->extremity_distance[e] = 0;
      snprintf(rep->role[e], sizeof rep->role[e], "%s", roles[h]);
    }
  double *J = r->J;
  const double *top = P(r, pick[0]);
  memcpy(J + 3 * J_HIP_C, c, sizeof c);
  for (int k = 0; k < 3; ++k) {
    J[3 * J_SPINE + k] = c[k] + 0.25 * (top[k] - c[k]);
    J[3 * J_SHOULDER_C + k] = c[k] + 0.5 * (top[k] - c[k]);
    J[3 * J_HEAD + k] = c[k] + 0.75 * (top[k] - c[k]);
  }
  static const double f[4] = {0.25, 0.5, 0.75, 0.9};
  const int chain0[4] = {J_SHOULDER_L, J_SHOULDER_R, J_HIP_L, J_HIP_R};
  for (int l = 0; l < 4; ++l) {
    const double *tip = P(r, pick[1 + l]), *from = l < 2 ? J + 3 * J_SHOULDER_C : c;
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 3; ++k)
        J[3 * (chain0[l] + i) + k] = from[k] + f[i] * (tip[k] - from[k]);
    r->tip[chain0[l] + 3] = pick[1 + l];
  }
  r->tip[J_HEAD] = pick[0];
  return KM_OK;
}

/* The report of a bust-like rig (a bust's, a resting body's): one extremity, the head's tip
 * (rep NULL: none). */
static void report_head(km_autorig_report *rep, int32_t tip) {
  if (!rep) return;
  memset(rep->role, 0, sizeof rep->role);
  rep->n_extremities = 1;
  rep->extremity[0] = tip;
  rep->extremity_distance[0] = 0;
  snprintf(rep->role[0], sizeof rep->role[0], "Head");
}

/* Bust (an open cut at its bottom, km__bust_base): the torso joints on the mid-line of the
 * height slices (HipCenter at the cut, ShoulderCenter at the neck: below the head's widest
 * slice, the narrowest above the shoulders, Head half way from there to the top), the shoulders at
 * 0.35 of the width on either side of the highest slice below the neck that is 0.8 as wide as the
 * widest there, the arms folded into the shoulders and the
 * legs into the base (short bones that no handle drives and no vertex is skinned to: the
 * skin is the spine's and the neck's, below). */
#define BUST_SLICES 24
static km_status rig_bust(rigger *r, const int *hands, km_autorig_report *rep, km_error *err) {
  double lo[BUST_SLICES], hi[BUST_SLICES], sx[BUST_SLICES] = {0}, sz[BUST_SLICES] = {0},
                                           cnt[BUST_SLICES] = {0};
  for (int i = 0; i < BUST_SLICES; ++i)
    lo[i] = DBL_MAX, hi[i] = -DBL_MAX;
  /* An upper body (hands: its two free tips): the slices see only the torso and head, within
   * a quarter of the cut's width beyond it on either side (the arms reach further) */
  double xwin[2] = {-DBL_MAX, DBL_MAX};
  if (hands) {
    double clo = DBL_MAX, chi = -DBL_MAX;
    for (size_t v = 0; v < r->n; ++v)
      if (r->on_face[v] && P(r, (int32_t)v)[1] < r->ymin + r->H / BUST_SLICES)
        clo = fmin(clo, P(r, (int32_t)v)[0]), chi = fmax(chi, P(r, (int32_t)v)[0]);
    xwin[0] = clo - 0.25 * (chi - clo), xwin[1] = chi + 0.25 * (chi - clo);
  }
  int32_t top = -1;
  for (size_t v = 0; v < r->n; ++v) {
    if (!r->on_face[v]) continue;
    const double *p = P(r, (int32_t)v);
    if (p[0] < xwin[0] || p[0] > xwin[1]) continue;
    int i = (int)((p[1] - r->ymin) / r->H * BUST_SLICES);
    i = i < 0 ? 0 : i >= BUST_SLICES ? BUST_SLICES - 1 : i;
    lo[i] = fmin(lo[i], p[0]), hi[i] = fmax(hi[i], p[0]);
    sx[i] += p[0], sz[i] += p[2], cnt[i] += 1;
    if (top < 0 || p[1] > P(r, top)[1]) top = (int32_t)v;
  }
  /* The neck: from the top down, past the head's widest slice, the narrowest before the
   * width grows a quarter again (the shoulders) or the cut is reached (a head cut at its
   * neck) */
  int neck = -1, shoulder = -1;
  double wpeak = 0, wmin = DBL_MAX;
  for (int i = BUST_SLICES - 1; i >= 0; --i) {
    if (!(cnt[i] > 0)) continue;
    double w = hi[i] - lo[i];
    if (neck < 0 && w >= wpeak) { /* still widening: the head */
      wpeak = w;
      continue;
    }
    if (w < wmin) wmin = w, neck = i;
    if (w > 1.25 * wmin) break;
  }
  if (neck < 0) /* a shape that only widens downwards: the middle */
    for (int i = BUST_SLICES / 2; i >= 0 && neck < 0; --i)
      if (cnt[i] > 0) neck = i;
  if (neck < 0 || top < 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: the bust has no vertices at its neck");
  double wmax = 0; /* the shoulders: the highest slice below the neck at 0.8 of its widest */
  for (int i = 0; i < neck; ++i)
    if (cnt[i] > 0) wmax = fmax(wmax, hi[i] - lo[i]);
  for (int i = neck - 1; i >= 0 && shoulder < 0; --i)
    if (cnt[i] > 0 && hi[i] - lo[i] >= 0.8 * wmax) shoulder = i;
  if (shoulder < 0) shoulder = neck;
  int base = 0;
  while (base < neck && cnt[base] <= 0)
    ++base;
  double slice = r->H / BUST_SLICES, *J = r->J;
#define MID(i, a) (a == 0 ? sx[i] / cnt[i] : sz[i] / cnt[i])
  double yneck = r->ymin + (neck + 0.5) * slice, ysh = r->ymin + (shoulder + 0.5) * slice;
  set3(J + 3 * J_HIP_C, MID(base, 0), r->ymin, MID(base, 2));
  set3(J + 3 * J_SHOULDER_C, MID(neck, 0), yneck, MID(neck, 2));
  for (int k = 0; k < 3; ++k)
    J[3 * J_SPINE + k] = 0.5 * (J[3 * J_HIP_C + k] + J[3 * J_SHOULDER_C + k]);
  double hx = 0, hz = 0, hn = 0;
  for (int i = neck + 1; i < BUST_SLICES; ++i)
    hx += sx[i], hz += sz[i], hn += cnt[i];
  set3(J + 3 * J_HEAD, hn > 0 ? hx / hn : MID(neck, 0), 0.5 * (yneck + P(r, top)[1]),
       hn > 0 ? hz / hn : MID(neck, 2));
  double cx = MID(shoulder, 0), cz = MID(shoulder, 2), w = hi[shoulder] - lo[shoulder];
  double hb = 0.15 * (hi[base] - lo[base]);
#undef MID
  for (int side = 0; side < 2; ++side) {
    double sgn = side ? -1 : 1; /* kinemesh's frame faces +z: the left is +x */
    int j0 = side ? J_SHOULDER_R : J_SHOULDER_L, h0 = side ? J_HIP_R : J_HIP_L;
    static const double arm[4] = {0.35, 0.40, 0.43, 0.45};
    for (int k = 0; k < 4; ++k)
      set3(J + 3 * (j0 + k), cx + sgn * arm[k] * w, ysh - 0.02 * k * r->H, cz);
    for (int k = 0; k < 4; ++k)
      set3(J + 3 * (h0 + k), J[3 * J_HIP_C] + sgn * hb, r->ymin + 0.03 * (3 - k) * r->H,
           J[3 * J_HIP_C + 2] + (k == 3 ? 0.02 * r->H : 0));
    if (hands) { /* the arm: rings from the hand tip, as a humanoid's (rig_humanoid) */
      static const double af[3] = {F_ELBOW_ARM, F_WRIST_ARM, F_HAND_ARM};
      int aj[3] = {j0 + 1, j0 + 2, j0 + 3};
      limb_chain(r, (size_t)hands[side], J + 3 * j0, af, 3, aj, J);
      r->tip[j0 + 3] = r->ext_v[hands[side]];
    }
  }
  r->tip[J_HEAD] = top;
  report_head(rep, top);
  for (int side = 0; rep && hands && side < 2; ++side) {
    size_t e = rep->n_extremities++;
    rep->extremity[e] = r->ext_v[hands[side]];
    rep->extremity_distance[e] = r->ext_d[hands[side]];
    snprintf(rep->role[e], sizeof rep->role[e], "%s", side ? "HandRight" : "HandLeft");
  }
  return KM_OK;
}

/* A body lying or curled up (KM_AUTORIG_RESTING, asked for: a cat asleep on its side, cat-04,
 * or curled up, cat-07, a person lying down). Rigged automatically as a standing humanoid, its
 * head, hand and foot handles were points of one or two vertices that dragged spikes out of its
 * flank; and no rule tried here told its head from its rump or a paw reliably (the geodesic
 * rings' widths along each extremity split where a ring crosses a tucked paw or a tail). So
 * the head's tip is the user's (head: an ear tip, the top of a skull, a snout; NULL: the most
 * prominent extremity), and the rest is a bust's rig along the head's own geodesic rings
 * instead of horizontal slices, at fractions of L, the farthest any vertex lies from the tip
 * along the surface. Their width w(d), every 0.01 L, averaged over three: the neck is the
 * narrowest ring past the widest between 0.05 and 0.16 L when it is under 0.7 of that (FAUST's
 * tr_reg_000 from its crown: 0.042 L at 0.08 L, then 0.021 L at 0.13 L), else 0.12 L from the
 * tip (a cat's neck is as thick as its skull: from an ear tip the rings only widen, or narrow
 * where they cross a tucked paw). ShoulderCenter is the neck ring's centroid, Head the ring
 * half-way to the tip's, Spine and HipCenter the rings 0.2 and 0.4 L beyond the neck; arms and legs
 * folded beside the shoulders and the hips (no vertex skinned to them, as a bust's), so the sidecar
 * (arms and legs folded, no base it sits on: resting_handles) gives it a bust's two handles: the
 * head, turning with the performer's neck, and the body behind the shoulders, held still. */
static km_status rig_resting(rigger *r, const int32_t *head_tip, km_autorig_report *rep,
                             km_error *err) {
  if (!head_tip && r->n_ext == 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "rig: a resting body needs a head (no extremity)");
  int32_t tip = head_tip ? *head_tip : r->ext_v[0];
  if (tip < 0 || (size_t)tip >= r->n || !r->on_face[tip])
    return km__fail(err, KM_ERR_INVALID,
                    "rig: the head vertex %ld is not a vertex of a face (0..%zu)", (long)tip,
                    r->n ? r->n - 1 : 0);
  double *D = km__malloc(r->n, sizeof *D);
  if (!D) return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  memcpy(D, km__geodesic_run(r->geo, r->m->V, tip, INFINITY, NULL, 0, NULL, NULL),
         r->n * sizeof *D);
  /* lengths are fractions of L, the farthest any vertex lies from the tip along the surface
   * (crown to toe, ear to tail tip) */
  double L = 0, c[3];
  for (size_t v = 0; v < r->n; ++v)
    if (isfinite(D[v]) && D[v] > L) L = D[v];
  if (!(L > 0)) {
    free(D);
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the head vertex %ld has no surface around it", (long)tip);
  }
  enum { STEPS = 18 }; /* widths every 0.01 L from 0.01 to 0.18, averaged over three */
  double w[STEPS], ws[STEPS];
  for (int i = 0; i < STEPS; ++i)
    w[i] = ring_at_field(r, D, tip, 0.01 * (i + 1) * L, true, c);
  for (int i = 0; i < STEPS; ++i)
    ws[i] = (w[i > 0 ? i - 1 : 0] + w[i] + w[i < STEPS - 1 ? i + 1 : i]) / 3;
  int skull = 4, neck = -1; /* the widest from 0.05 to 0.16, the narrowest after it */
  for (int i = 4; i < 16; ++i)
    if (ws[i] > ws[skull]) skull = i;
  for (int i = skull + 1; i < 16; ++i)
    if (neck < 0 || ws[i] < ws[neck]) neck = i;
  double dn = neck >= 0 && ws[neck] < 0.7 * ws[skull] ? 0.01 * (neck + 1) * L : 0.12 * L;
  double *J = r->J;
  double rn = ring_at_field(r, D, tip, dn, true, J + 3 * J_SHOULDER_C); /* the neck's width */
  ring_at_field(r, D, tip, 0.5 * dn, false, J + 3 * J_HEAD);
  ring_at_field(r, D, tip, dn + 0.2 * L, false, J + 3 * J_SPINE);
  ring_at_field(r, D, tip, dn + 0.4 * L, false, J + 3 * J_HIP_C);
  free(D);
  /* the limbs folded beside the shoulders and hips, across the neck's direction on the ground */
  const double *sc = J + 3 * J_SHOULDER_C, *hd = J + 3 * J_HEAD, *hc = J + 3 * J_HIP_C;
  double ax = hd[0] - sc[0], az = hd[2] - sc[2], al = hypot(ax, az);
  double lat[3] = {1, 0, 0};
  if (al > 0) set3(lat, -az / al, 0, ax / al);
  if (!(rn > 0)) rn = 0.03 * L;
  double spine = dist3(hc, sc);
  if (!(spine > 0)) spine = 0.4 * L;
  for (int side = 0; side < 2; ++side) {
    double sgn = side ? -1 : 1;
    int j0 = side ? J_SHOULDER_R : J_SHOULDER_L, h0 = side ? J_HIP_R : J_HIP_L;
    for (int k = 0; k < 4; ++k) {
      /* the sidecar's arms_folded: a hand within 0.4 of the shoulders' span (rn) of its
       * shoulder; legs_folded: a foot within a quarter of the spine of HipCenter */
      set3(J + 3 * (j0 + k), sc[0] + sgn * 0.5 * rn * lat[0], sc[1] - 0.1 * k * rn,
           sc[2] + sgn * 0.5 * rn * lat[2]);
      set3(J + 3 * (h0 + k), hc[0] + sgn * 0.05 * spine * lat[0], hc[1] - 0.03 * k * spine,
           hc[2] + sgn * 0.05 * spine * lat[2]);
    }
  }
  r->tip[J_HEAD] = tip;
  report_head(rep, tip);
  return KM_OK;
}

/* A body whose limbs no handle drives: the legs' weights go to HipCenter (bones folded into
 * its base) and, unless arms_to < 0 (an upper body's arms are driven), the arms' and
 * shoulders' to arms_to. */
static void fold_skin(km_skin *skin, size_t n, int arms_to) {
  for (size_t v = 0; v < n; ++v) {
    int32_t *jv = skin->joints + KM_SKIN_INFLUENCES * v;
    double *wv = skin->weights + KM_SKIN_INFLUENCES * v;
    for (int k = 0; k < KM_SKIN_INFLUENCES; ++k) {
      if (jv[k] >= J_HIP_L && jv[k] <= J_FOOT_R) jv[k] = J_HIP_C;
      if (arms_to >= 0 && jv[k] >= J_SHOULDER_L && jv[k] <= J_HAND_R) jv[k] = arms_to;
    }
    for (int a = 0; a < KM_SKIN_INFLUENCES; ++a) /* one entry per joint */
      for (int b = a + 1; b < KM_SKIN_INFLUENCES; ++b)
        if (wv[b] > 0 && jv[b] == jv[a]) wv[a] += wv[b], wv[b] = 0;
    for (int a = 0; a < KM_SKIN_INFLUENCES; ++a) /* a sum of 0.7 and 0.3 may pass 1 */
      if (wv[a] > 1) wv[a] = 1;
  }
}

/* ---------------------------------------------------------------- skin */

/* Distance from p to the segment a-b; q (3): the closest point on it. */
static double seg_closest(const double *p, const double *a, const double *b, double *q) {
  double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  double t = l2 > 0 ? (ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / l2 : 0;
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  set3(q, a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]);
  return dist3(p, q);
}

/* Each joint's reach (compute_skin): G n*NJ, 1 within band along the edges of the joint's
 * own patch of nearest vertices (near n), smoothstep to 0 at 4 band. */
static km_status skin_reach(const rigger *r, const int32_t *near, double band, double *G,
                            km_error *err) {
  enum { NJ = KM_KINECT1_JOINTS };
  size_t n = r->n;
  double r0 = band, r1 = 4 * band;
  /* a bone's own patch: the largest group of its nearest vertices joined along faces (a hand
   * raised beside the head is also nearest to some cheek or shoulder vertices: a patch of its
   * own, not a seed of the hand's reach) */
  int32_t *par = km__malloc(n, sizeof *par), *size = km__calloc(n, sizeof *size),
          *seeds = km__malloc(n, sizeof *seeds);
  if (!par || !size || !seeds) {
    free(par), free(size), free(seeds);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (skin of %zu vertices)", n);
  }
  km__uf_init(par, n);
  for (size_t f = 0; f < r->m->n_faces; ++f)
    for (int c = 0; c < 3; ++c) {
      int32_t a = r->m->F[3 * f + c], b = r->m->F[3 * f + (c + 1) % 3];
      if (near[a] != near[b]) continue;
      km__uf_union(par, a, b);
    }
  int32_t best[NJ];
  for (int j = 0; j < NJ; ++j)
    best[j] = -1;
  for (size_t v = 0; v < n; ++v) /* every vertex straight to its root */
    ++size[par[v] = km__uf_find(par, (int32_t)v)];
  for (size_t v = 0; v < n; ++v) {
    int32_t root = par[v], j = near[v];
    if (r->on_face[v] && (best[j] < 0 || size[root] > size[best[j]])) best[j] = root;
  }
  for (int j = 0; j < NJ; ++j) {
    size_t k = 0;
    for (size_t v = 0; v < n; ++v)
      if (near[v] == j && r->on_face[v] && par[v] == best[j]) seeds[k++] = (int32_t)v;
    if (!k) continue;
    const int32_t *hit;
    size_t nh;
    const double *g = km__geodesic_run_set(r->geo, r->m->V, seeds, k, r1, NULL, 0, &hit, &nh);
    for (size_t i = 0; i < nh; ++i) {
      double x = (g[hit[i]] - r0) / (r1 - r0);
      /* smoothstep from 1 (within r0) to 0 (at r1) */
      G[NJ * (size_t)hit[i] + j] = x <= 0 ? 1 : x >= 1 ? 0 : 1 - x * x * (3 - 2 * x);
    }
  }
  free(par), free(size), free(seeds);
  return KM_OK;
}

/* Bone heat (Baran & Popovic 2007, section 4): each joint's weight w_j solves
 *     (-L + M H) w_j = M H p_j
 * over the surface (L the cotangent Laplacian, M the Voronoi areas: the area-weighted form of
 * their -Laplacian(w) + H w = H p), where a vertex whose nearest bone is visible from it (the
 * segment to its closest point on the bone crosses no face, Embree) has H = 1/d^2 (d that
 * distance) and p_j = 1 for that bone's joint (shared on a tie, at a joint), and a vertex that
 * sees no bone 1e-4 of that toward its nearest bone: its weights diffuse from its neighbours'.
 * Every p sums to 1 and L 1 = 0, so the weights sum to 1 without normalising. A vertex tests its
 * four nearest joints' bones, nearest first. One factorisation (CHOLMOD) and one solve of NJ
 * right-hand sides. Out: W n*NJ. */
static km_status skin_heat(const rigger *r, const double *D, const double *Q, size_t n_c,
                           const double *cs, double *W, km_error *err) {
  enum { NJ = KM_KINECT1_JOINTS, TRY = 4 };
  const km_mesh *m = r->m;
  size_t n = r->n;
  km_status st = KM_OK;
  km_sparse *L = NULL, *M = NULL, *MH = NULL, *A = NULL;
  km_cholesky *chol = NULL;
  km__surface *surf = NULL;
  double *h = km__calloc(n, sizeof *h), *B = km__calloc(n * NJ, sizeof *B);
  int32_t *order = km__malloc(n * TRY, sizeof *order), *todo = km__malloc(n, sizeof *todo);
  double *org = km__malloc(3 * n, sizeof *org), *tgt = km__malloc(3 * n, sizeof *tgt);
  uint8_t *occ = km__malloc(n, 1), *done = km__calloc(n, 1);
  if (!h || !B || !order || !todo || !org || !tgt || !occ || !done) {
    st = km__fail(err, KM_ERR_NOMEM, "rig: out of memory (heat weights of %zu vertices)", n);
    goto out;
  }
  for (size_t v = 0; v < n; ++v) {
    int32_t *o = order + TRY * v;
    for (int k = 0; k < TRY; ++k)
      o[k] = -1;
    for (int j = 0; j < NJ; ++j) {
      double d = D[NJ * v + j];
      if (d == DBL_MAX) continue;
      for (int k = 0; k < TRY; ++k)
        if (o[k] < 0 || d < D[NJ * v + o[k]]) {
          for (int l = TRY - 1; l > k; --l)
            o[l] = o[l - 1];
          o[k] = j;
          break;
        }
    }
  }
  if ((st = km__surface_create(m->V, m->n_vertices, m->F, m->n_faces, &surf, err)) != KM_OK)
    goto out;
  double tnear = 1e-4 * r->H, tie = 1e-6 * r->H;
  for (int k = 0; k < TRY; ++k) {
    size_t nt = 0;
    for (size_t v = 0; v < n; ++v)
      if (!done[v] && r->on_face[v] && order[TRY * v + k] >= 0) {
        int j = order[TRY * v + k];
        memcpy(org + 3 * nt, m->V + 3 * v, 3 * sizeof(double));
        memcpy(tgt + 3 * nt, Q + 3 * (NJ * v + j), 3 * sizeof(double));
        todo[nt++] = (int32_t)v;
      }
    km__surface_occluded(surf, org, tgt, nt, tnear, occ);
    for (size_t i = 0; i < nt; ++i) {
      if (occ[i]) continue;
      size_t v = (size_t)todo[i];
      done[v] = 1;
      double d = D[NJ * v + order[TRY * v + k]];
      h[v] = 1 / (d * d + tie * tie); /* their c = 1; scaled by cs below */
      int nb = 0;
      for (int j = 0; j < NJ; ++j)
        if (D[NJ * v + j] <= d + tie) ++nb;
      for (int j = 0; j < NJ; ++j)
        if (D[NJ * v + j] <= d + tie) B[n * j + v] = 1.0 / nb;
    }
  }
  for (size_t v = 0; v < n; ++v)
    if (!done[v]) {
      /* a vertex no face uses has no surface to diffuse along: its nearest bone. One that sees
       * no bone is held to its nearest by 1e-4 of the heat, which changes no weight
       * measurably but keeps every part of the surface anchored (a part that saw no bone at
       * all, every bone outside it, would leave the system singular) */
      double d = D[NJ * v + order[TRY * v]];
      h[v] = (r->on_face[v] ? 1e-4 : 1) / (d * d + tie * tie);
      B[n * order[TRY * v] + v] = 1;
    }
  if ((st = km_cotmatrix(m, &L, err)) != KM_OK ||
      (st = km_massmatrix(m, KM_MASS_VORONOI, &M, err)) != KM_OK)
    goto out;
  for (size_t v = 0; v < n; ++v) {
    h[v] *= km_sparse_coeff(M, v, v);
    for (int j = 0; j < NJ; ++j)
      B[n * j + v] *= h[v];
  }
  if ((st = km_sparse_diagonal(n, h, &MH, err)) != KM_OK) goto out;
  /* (-L + c M H) w = c M H p for each c: one visibility pass and one symbolic analysis, a
   * factorisation and a solve per c */
  for (size_t ci = 0; ci < n_c && st == KM_OK; ++ci) {
    km_sparse_free(&A);
    if ((st = km_sparse_add(-1, L, cs[ci], MH, &A, err)) != KM_OK ||
        (!chol && (st = km_cholesky_analyze(A, &chol, err)) != KM_OK) ||
        (st = km_cholesky_factorize(chol, A, err)) != KM_OK)
      goto out;
    double *X = km__malloc(n * NJ, sizeof *X);
    if (!X) {
      st = km__fail(err, KM_ERR_NOMEM, "rig: out of memory (heat weights)");
      goto out;
    }
    st = km_cholesky_solve(chol, NJ, B, X, err);
    /* the right-hand side is c M H p: scaling the solution by c is the same */
    double *Wc = W + n * NJ * ci;
    for (size_t v = 0; st == KM_OK && v < n; ++v)
      for (int j = 0; j < NJ; ++j)
        Wc[NJ * v + j] = cs[ci] * X[n * j + v];
    free(X);
  }
out:
  km_cholesky_free(&chol);
  km_sparse_free(&L), km_sparse_free(&M), km_sparse_free(&MH), km_sparse_free(&A);
  km__surface_free(&surf);
  free(h), free(B), free(order), free(todo), free(org), free(tgt), free(occ), free(done);
  return st;
}

/* the KM_SKIN_INFLUENCES largest of w (n) less the next one (continuous when two swap) */
static void skin_sparsify(double *w, int n) {
  double top[KM_SKIN_INFLUENCES + 1] = {0};
  for (int j = 0; j < n; ++j) {
    double x = w[j];
    for (int q = 0; q <= KM_SKIN_INFLUENCES; ++q)
      if (x > top[q]) {
        double t = top[q];
        top[q] = x, x = t;
      }
  }
  for (int j = 0; j < n; ++j)
    w[j] = w[j] > top[KM_SKIN_INFLUENCES] ? w[j] - top[KM_SKIN_INFLUENCES] : 0;
}

/* One probe pose: the subtree of joint j0 (j0 and its descendants) turned by R about point c,
 * the rest of the skeleton at rest; the mesh skinned by skin (km_lbs into X, n*3) and its worst
 * edge l/l0 from the deformation check dc in *ratio. */
static km_status probe_pose(const rigger *r, const km_skin *skin, km_deform_check *dc, double *X,
                            int j0, const double c[3], const double R[9], double *ratio,
                            km_error *err) {
  enum { NJ = KM_KINECT1_JOINTS };
  static const double identity[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  double T[12 * NJ], Tq[12], Rc[3];
  km__m3_apply(R, c, Rc);
  for (int i = 0; i < 3; ++i) {
    memcpy(Tq + 4 * i, R + 3 * i, 3 * sizeof(double));
    Tq[4 * i + 3] = c[i] - Rc[i];
  }
  for (int j = 0; j < NJ; ++j) { /* j turns when j0 is j or one of its ancestors */
    int k = j;
    while (k >= 0 && k != j0)
      k = km_kinect1_joint_parent(k);
    memcpy(T + 12 * j, k == j0 ? Tq : identity, sizeof Tq);
  }
  km_deform_frame fr;
  km_status st = km_lbs(r->m->V, r->n, skin, T, NJ, X, err);
  if (st == KM_OK) st = km_deform_check_add(dc, X, &fr, err);
  if (st == KM_OK) *ratio = fr.ratio_max;
  return st;
}

/* The quadruped's probe: the bends its rig lets a take make ("bend_limit" 20 at the elbows and
 * knees, "swing_limit" 30 below them and along the spine and neck; the upper legs, inside the
 * trunk, hardly move): each forearm and shin swung 20 degrees forwards and backwards, each paw
 * 30, the spine and the neck (the head about ShoulderCenter) 30 up, down, left and right; about
 * the body's own lateral and vertical axes (its forward is hips -> shoulders). The humanoid's
 * probe, which swings upper legs 90 degrees, did not follow bench motion --skin on a quadruped
 * (it chose 0.5 for the walking cat, whose worst edge rose 1.57-1.65x -> 1.68-1.78x, and 1 for
 * dog0, which 0.5 improves); this one chooses 1 and 0.5 there (KM_HEAT_MARGIN). */
static km_status probe_stretch_quadruped(const rigger *r, const km_skin *skin, km_deform_check *dc,
                                         double *X, double *score, int *n_poses, km_error *err) {
  static const struct {
    int joint, pivot, axis; /* axis 0: lateral, 1: vertical */
    double deg;
  } poses[] = {{5, 5, 0, 20},   {5, 5, 0, -20},   {9, 9, 0, 20},   {9, 9, 0, -20},
               {13, 13, 0, 20}, {13, 13, 0, -20}, {17, 17, 0, 20}, {17, 17, 0, -20},
               {6, 6, 0, 30},   {6, 6, 0, -30},   {10, 10, 0, 30}, {10, 10, 0, -30},
               {14, 14, 0, 30}, {14, 14, 0, -30}, {18, 18, 0, 30}, {18, 18, 0, -30},
               {1, 1, 0, 30},   {1, 1, 0, -30},   {1, 1, 1, 30},   {1, 1, 1, -30},
               {3, 2, 0, 30},   {3, 2, 0, -30},   {3, 2, 1, 30},   {3, 2, 1, -30}};
  double fwd[3] = {r->J[3 * 2] - r->J[0], 0, r->J[3 * 2 + 2] - r->J[2]}, up[3] = {0, 1, 0}, lat[3];
  if (!(km__normalize3(fwd) > 0)) set3(fwd, 0, 0, 1);
  km__cross3(up, fwd, lat);
  double sum = 0;
  for (size_t q = 0; q < sizeof poses / sizeof poses[0]; ++q) {
    double a = poses[q].deg * M_PI / 180, rv[3], R[9], ratio = 0;
    const double *ax = poses[q].axis ? up : lat;
    for (int i = 0; i < 3; ++i)
      rv[i] = a * ax[i];
    km__m3_from_rotvec(rv, R);
    km_status st =
        probe_pose(r, skin, dc, X, poses[q].joint, r->J + 3 * poses[q].pivot, R, &ratio, err);
    if (st != KM_OK) return st;
    sum += ratio;
  }
  *score = sum / (double)(sizeof poses / sizeof poses[0]);
  *n_poses = (int)(sizeof poses / sizeof poses[0]);
  return KM_OK;
}

/* The mean over 13 probe poses (24 for a quadruped: probe_stretch_quadruped) of the worst edge
 * stretch l/l0 of the mesh skinned by skin (the 4-influence skin being weighed), in *score, and
 * the number of poses in *n_poses. The poses, of the rig's own skeleton: each upper
 * arm and thigh swung 90 degrees about the body's x axis and about its z axis (outwards), each
 * forearm and shin bent 90 degrees about x, and the spine bent 30 degrees forward (each
 * rotation about the joint that starts the bone, carrying the whole subtree below it). Posed by
 * km_lbs and measured by the deformation check dc (on the rest mesh; its frame-to-frame steps
 * are not read); X: n*3 scratch. */
static km_status probe_stretch(const rigger *r, const km_skin *skin, km_deform_check *dc, double *X,
                               double *score, int *n_poses, km_error *err) {
  if (r->quadruped) return probe_stretch_quadruped(r, skin, dc, X, score, n_poses, err);
  static const struct {
    int joint, axis;
    double deg;
  } poses[] = {{4, 0, -90}, {4, 2, 90},   {8, 0, -90}, {8, 2, 90},  {12, 0, -90},
               {12, 2, 90}, {16, 0, -90}, {16, 2, 90}, {5, 0, -90}, {9, 0, -90},
               {13, 0, 90}, {17, 0, 90},  {1, 0, 30}};
  double sum = 0;
  for (size_t q = 0; q < sizeof poses / sizeof poses[0]; ++q) {
    int j0 = poses[q].joint;
    /* outwards: towards the joint's own side of the body (left +x, right -x) */
    double a = poses[q].deg * M_PI / 180, R[9], ratio = 0;
    if (poses[q].axis == 2 && r->J[3 * j0] < r->J[0]) a = -a;
    km__m3_axis(poses[q].axis, a, R);
    km_status st = probe_pose(r, skin, dc, X, j0, r->J + 3 * j0, R, &ratio, err);
    if (st != KM_OK) return st;
    sum += ratio;
  }
  *score = sum / (double)(sizeof poses / sizeof poses[0]);
  *n_poses = (int)(sizeof poses / sizeof poses[0]);
  return KM_OK;
}

/* The probe is a proxy for real takes: a smoother heat constant must beat c = 1 by more than
 * this share of its score to be kept. bench motion --skin (L, the worst edge over the five
 * takes) against the probe's margin, on the bodies where c = 0.5 scored better: dog0 8 %
 * (1.49-2.20x -> 1.45-1.82x), the horse 6.5 % (1.54-2.07x -> 1.47-1.88x), the sitting cats
 * cat-02 21 % (2.70-5.86x -> 2.10-4.18x), cat-08 17 % (2.65-4.54x -> 2.09-3.26x) and cat-09 5 %
 * (1.85-2.49x -> 1.73-2.15x) gained; cat-01 at 3 % lost (3.45-3.80x -> 4.20-4.63x) and cat-06
 * at 1.6 % was even (1.40-1.48x either way). Every humanoid body that takes 0.5 wins by 6 % or
 * more (the dinosaur 6 %, the armadillo 16 %, the knight 22 %, the bunny 56 %). */
#define KM_HEAT_MARGIN 0.04

/* Skin weights (mode): bone heat (skin_heat, the default), or by distance: a vertex takes the
 * bones within `band` (6 % of the height) of its nearest bone, weighted by
 * (1 - (d - dmin) / band)^2; with `reach`, each bone's weight also multiplied by its reach at
 * the vertex: 1 within `band` along the edges of the bone's own patch (the largest connected
 * group of vertices nearest to it), falling to 0 at 4 band by a smoothstep (one multi-source
 * Dijkstra per joint), and dmin is the nearest bone that reaches. Distance in space alone leaks
 * through the air: the armadillo's ears, beside its raised hands at rest, are the hands' and
 * fly off with them (posed by the rig's skeleton, 54-91x stretch), the elephant's ears and
 * trunk its arms'. The reach follows the surface but still blends by distance, so a shell far
 * from every bone takes a steep mix (the armadillo's back, 5-10x); heat diffuses (README). */
static km_status compute_skin(const rigger *r, km_autorig_skin mode, km_skin *skin,
                              km_autorig_report *report, km_error *err) {
  bool reach = mode == KM_AUTORIG_SKIN_REACH, heat = mode == KM_AUTORIG_SKIN_HEAT;
  enum { NJ = KM_KINECT1_JOINTS };
  double seg[2 * NJ][6];
  int segj[2 * NJ], ns = 0;
  for (int j = 1; j < NJ; ++j) {
    int p = km_kinect1_joint_parent(j);
    memcpy(seg[ns], r->J + 3 * p, 3 * sizeof(double));
    memcpy(seg[ns] + 3, r->J + 3 * j, 3 * sizeof(double));
    segj[ns++] = p;
  }
  for (int j = 0; j < NJ; ++j)
    if (r->tip[j] >= 0) {
      memcpy(seg[ns], r->J + 3 * j, 3 * sizeof(double));
      memcpy(seg[ns] + 3, P(r, r->tip[j]), 3 * sizeof(double));
      segj[ns++] = j;
    }
  size_t n = r->n;
  double *D = km__malloc(n * NJ, sizeof *D), *G = reach ? km__calloc(n * NJ, sizeof *G) : NULL;
  double *Q = heat ? km__malloc(3 * n * NJ, sizeof *Q) : NULL;
  int32_t *near = km__malloc(n, sizeof *near);
  if (!D || (reach && !G) || (heat && !Q) || !near) {
    free(D), free(G), free(Q), free(near);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (skin of %zu vertices)", n);
  }
  /* D: each vertex's distance to each joint's bones (Q: the closest point on them); near: its
   * nearest bone's joint */
#pragma omp parallel for schedule(static)
  for (size_t v = 0; v < n; ++v) {
    const double *p = r->m->V + 3 * v;
    double *d = D + NJ * v, dmin = DBL_MAX;
    for (int j = 0; j < NJ; ++j)
      d[j] = DBL_MAX;
    near[v] = 0;
    for (int s = 0; s < ns; ++s) {
      double q[3], x = seg_closest(p, seg[s], seg[s] + 3, q);
      if (x < d[segj[s]]) {
        d[segj[s]] = x;
        if (Q) memcpy(Q + 3 * (NJ * v + segj[s]), q, sizeof q);
      }
      if (x < dmin) dmin = x, near[v] = segj[s];
    }
  }
  double band = 0.06 * r->H;
  km_status st = reach ? skin_reach(r, near, band, G, err) : KM_OK;
  if (heat) {
    /* Baran & Popovic's heat constant c (H = c / d^2) sets how far a bone's weight diffuses
     * (about d / sqrt(c)). Their c = 1 suits a slim body; a bulky one (the armadillo's chest
     * and back, far from the spine) gets steep blends from it that stretch 3-5x under skinning,
     * and a smoother c = 0.5 halves that, while a slim one (the procedural character) lets a
     * thigh's weight climb into the waist with it. Each c is tried and the one whose skin
     * stretches least in the probe poses kept (probe_stretch; a quadruped's own poses), the
     * smoother one only when it wins by more than KM_HEAT_MARGIN. */
    static const double heat_c[] = {1, 0.5};
    const size_t NC = sizeof heat_c / sizeof heat_c[0];
    double *W = km__malloc(NC * n * NJ, sizeof *W), *X = km__malloc(3 * n, sizeof *X);
    double best = INFINITY;
    int32_t *tj = km__malloc(KM_SKIN_INFLUENCES * n, sizeof *tj);
    double *tw = km__malloc(KM_SKIN_INFLUENCES * n, sizeof *tw);
    km_skin trial = {n, tj, tw};
    km_deform_check *dc = NULL;
    if (!W || !X || !tj || !tw)
      st = km__fail(err, KM_ERR_NOMEM, "rig: out of memory (skin of %zu vertices)", n);
    if (st == KM_OK) st = km_deform_check_create(r->m, &dc, err);
    if (st == KM_OK) st = skin_heat(r, D, Q, NC, heat_c, W, err);
    for (size_t ci = 0; st == KM_OK && ci < NC; ++ci) {
      for (size_t v = 0; v < n; ++v) {
        double *w = W + n * NJ * ci + NJ * v;
        /* small negative weights from obtuse triangles' negative cotangents: dropped */
        for (int j = 0; j < NJ; ++j)
          w[j] = w[j] > 1e-4 ? w[j] : 0;
        skin_sparsify(w, NJ);
        if (!km__skin_keep_largest(w, NJ, tj + 4 * v, tw + 4 * v)) {
          for (int i = 0; i < 4; ++i)
            tj[4 * v + i] = -1, tw[4 * v + i] = 0;
          tj[4 * v] = near[v], tw[4 * v] = 1;
        }
      }
      double score = 0;
      int n_poses = 0;
      if ((st = probe_stretch(r, &trial, dc, X, &score, &n_poses, err)) != KM_OK) break;
      if (report) report->heat_probe[ci] = score, report->heat_probe_poses = n_poses;
      if (ci == 0 || score < best * (1 - KM_HEAT_MARGIN)) {
        best = score;
        if (report) report->heat_c = heat_c[ci];
        memcpy(skin->joints, tj, KM_SKIN_INFLUENCES * n * sizeof *tj);
        memcpy(skin->weights, tw, KM_SKIN_INFLUENCES * n * sizeof *tw);
      }
    }
    km_deform_check_free(&dc);
    free(W), free(X), free(tj), free(tw);
  } else if (st == KM_OK)
#pragma omp parallel for schedule(static)
    for (size_t v = 0; v < n; ++v) {
      const double *d = D + NJ * v, *gv = G ? G + NJ * v : NULL;
      /* the nearest bone that reaches the vertex (its own patch's bone unless cut off); a
       * vertex no face uses has no surface to reach along: distance alone */
      bool all = !gv || !r->on_face[v];
      double dmin = DBL_MAX;
      for (int j = 0; j < NJ; ++j)
        if ((all || gv[j] > 0) && d[j] < dmin) dmin = d[j];
      if (dmin == DBL_MAX) dmin = d[near[v]];
      double w[NJ];
      for (int j = 0; j < NJ; ++j) {
        double t = (d[j] - dmin) / band;
        w[j] = t >= 1 ? 0 : (1 - t) * (1 - t) * (all ? 1 : gv[j]);
      }
      if (!km__skin_keep_largest(w, NJ, skin->joints + 4 * v, skin->weights + 4 * v))
        skin->joints[4 * v] = near[v], skin->weights[4 * v] = 1; /* no bone within band */
    }
  free(D), free(G), free(Q), free(near);
  return st;
}

/* ---------------------------------------------------------------- landmarks */

/* Where the ray o + t dir (dir a unit vector) crosses face f (Moller-Trumbore): t, or -1 when it
 * misses (or the face has an index out of range). */
static double ray_triangle(const rigger *r, size_t f, const double o[3], const double dir[3]) {
  const int32_t *t = r->m->F + 3 * f;
  if (t[0] < 0 || t[1] < 0 || t[2] < 0 || (size_t)t[0] >= r->n || (size_t)t[1] >= r->n ||
      (size_t)t[2] >= r->n)
    return -1;
  const double *a = P(r, t[0]), *b = P(r, t[1]), *c = P(r, t[2]);
  double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double pv[3] = {dir[1] * e2[2] - dir[2] * e2[1], dir[2] * e2[0] - dir[0] * e2[2],
                  dir[0] * e2[1] - dir[1] * e2[0]};
  double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
  if (fabs(det) < 1e-300) return -1;
  double inv = 1 / det, tv[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
  double u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) * inv;
  if (u < 0 || u > 1) return -1;
  double qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2],
                  tv[0] * e1[1] - tv[1] * e1[0]};
  double w = (dir[0] * qv[0] + dir[1] * qv[1] + dir[2] * qv[2]) * inv;
  if (w < 0 || u + w > 1) return -1;
  double d = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) * inv;
  return d > 0 ? d : -1;
}

/* The ray o + t dir's crossings with the surface for t > 0: how many, and the nearest one's t
 * (INFINITY when none). */
static size_t ray_crossings(const rigger *r, const double o[3], const double dir[3],
                            double *nearest) {
  size_t n = 0;
  double best = INFINITY;
  for (size_t f = 0; f < r->m->n_faces; ++f) {
    double d = ray_triangle(r, f, o, dir);
    if (d > 0) ++n, best = fmin(best, d);
  }
  if (nearest) *nearest = best;
  return n;
}

/* Whether p lies inside the closed surface: the parity of three rays' crossings in fixed
 * directions off every axis, by majority, so that a ray grazing an edge (counted twice or not
 * at all) or a small hole does not decide alone. */
static bool inside_body(const rigger *r, const double p[3]) {
  static const double dirs[3][3] = {{0.8017837, 0.2672612, 0.5345225},
                                    {-0.4850713, 0.7276069, -0.4850713},
                                    {0.2357023, -0.9428090, -0.2357023}};
  size_t a = ray_crossings(r, p, dirs[0], NULL) & 1, b = ray_crossings(r, p, dirs[1], NULL) & 1;
  return a == b ? a : ray_crossings(r, p, dirs[2], NULL) & 1; /* the third only to break a tie */
}

/* Where a ray from a joint leaves the body: the first face the ray from o along dir (unit)
 * crosses within 0.4 H (Moeller-Trumbore over all faces), and of that face the vertex nearest
 * the crossing. The first crossing, not the farthest vertex near the ray: the farthest one
 * is whatever sticks out along the ray (the nose for the neck's ray too, the shoulder for an
 * elbow's ray up a hanging arm, the hand hanging beside the hip's ray). A vertex already
 * taken (used, n_used) gives way to the nearest free one, so landmarks stay distinct. The
 * vertex nearest o when the ray crosses nothing (a joint outside a thin part). A ray cast
 * per landmark over the F faces: 16 * F tests, a few milliseconds at 100k faces, so no
 * acceleration structure (Embree is in recon, above this module). */
static int32_t ray_pick(const rigger *r, const double o[3], const double dir[3],
                        const int32_t *used, int n_used) {
  const km_mesh *m = r->m;
  double best_t = 0.4 * r->H;
  size_t best_f = SIZE_MAX;
  for (size_t f = 0; f < m->n_faces; ++f) {
    double d = ray_triangle(r, f, o, dir);
    if (d > 0 && d < best_t) best_t = d, best_f = f;
  }
  double hit[3] = {o[0], o[1], o[2]};
  if (best_f != SIZE_MAX)
    for (int k = 0; k < 3; ++k)
      hit[k] += best_t * dir[k];
  int32_t best = -1;
  double bd = DBL_MAX;
  for (int k = 0; best_f != SIZE_MAX && k < 3; ++k) {
    int32_t v = m->F[3 * best_f + k];
    double d = dist3(P(r, v), hit);
    if (d < bd) bd = d, best = v;
  }
  if (best < 0) best = nearest_vertex(r, hit);
  bool taken = false;
  for (int i = 0; i < n_used; ++i)
    taken = taken || used[i] == best;
  if (!taken) return best;
  best = -1, bd = DBL_MAX;
  for (size_t v = 0; v < r->n; ++v) {
    if (r->on_face && !r->on_face[v]) continue;
    bool u = false;
    for (int i = 0; i < n_used && !u; ++i)
      u = used[i] == (int32_t)v;
    double d = dist3(r->m->V + 3 * v, hit);
    if (!u && d < bd) bd = d, best = (int32_t)v;
  }
  return best >= 0 ? best : nearest_vertex(r, hit);
}

/* The unit direction of a limb landmark's ray from joint j: pref made perpendicular to the
 * limb through j (from joint a to joint b), so the ray leaves through the side of the limb
 * and not along it; when pref lies along the limb (an arm hanging down for an elbow's "up"),
 * alt made perpendicular instead. */
static void limb_ray(const double *J, int a, int b, const double pref[3], const double alt[3],
                     double out[3]) {
  double l[3] = {J[3 * b] - J[3 * a], J[3 * b + 1] - J[3 * a + 1], J[3 * b + 2] - J[3 * a + 2]};
  double ll = sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  const double *cand[2] = {pref, alt};
  for (int c = 0; c < 2; ++c) {
    const double *p = cand[c];
    double d = ll > 0 ? (p[0] * l[0] + p[1] * l[1] + p[2] * l[2]) / (ll * ll) : 0;
    double q[3] = {p[0] - d * l[0], p[1] - d * l[1], p[2] - d * l[2]};
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    if (n > 0.5 || c == 1) { /* within 60 degrees of perpendicular to the limb */
      for (int k = 0; k < 3; ++k)
        out[k] = n > 0 ? q[k] / n : p[k];
      return;
    }
  }
}

static void compute_landmarks(const rigger *r, const double fwd[3], km_landmark *lm) {
  const double *J = r->J, up[3] = {0, 1, 0};
  double left[3] = {fwd[2], 0, -fwd[0]}, right[3] = {-fwd[2], 0, fwd[0]};
  double o[3], d_l[3], d_r[3];
  int32_t v[KM_CHARACTER_LANDMARKS];
  int n = 0; /* landmarks placed so far (v[0..n-1]): a later one takes another vertex */
  /* the tips first: they are vertices of their own (extremities) */
  int order[KM_CHARACTER_LANDMARKS] = {6, 7, 14, 15, 0, 1, 2, 3, 4, 5, 8, 9, 10, 11, 12, 13};
  int32_t placed[KM_CHARACTER_LANDMARKS];
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    int k = order[i];
    const double *dir = fwd;
    const double *from = J;
    switch (k) {
    case 0: from = J + 3 * J_HEAD; break;
    case 1:
      for (int a = 0; a < 3; ++a)
        o[a] = 0.5 * (J[3 * J_SHOULDER_C + a] + J[3 * J_HEAD + a]);
      from = o;
      break;
    case 2: from = J + 3 * J_SHOULDER_L, dir = up; break;
    case 3: from = J + 3 * J_SHOULDER_R, dir = up; break;
    case 4: /* the top of the elbow in a T pose, its outer side when the arm hangs */
      limb_ray(J, J_SHOULDER_L, J_WRIST_L, up, left, d_l);
      from = J + 3 * J_ELBOW_L, dir = d_l;
      break;
    case 5:
      limb_ray(J, J_SHOULDER_R, J_WRIST_R, up, right, d_r);
      from = J + 3 * J_ELBOW_R, dir = d_r;
      break;
    case 8:
      for (int a = 0; a < 3; ++a)
        o[a] = J[3 * J_SPINE + a] + 0.6 * (J[3 * J_SHOULDER_C + a] - J[3 * J_SPINE + a]);
      from = o;
      break;
    case 9: from = J + 3 * J_HIP_C; break;
    case 10: from = J + 3 * J_HIP_L, dir = left; break;
    case 11: from = J + 3 * J_HIP_R, dir = right; break;
    case 12: from = J + 3 * J_KNEE_L; break;
    case 13: from = J + 3 * J_KNEE_R; break;
    default: break;
    }
    int32_t tip = k == 6    ? r->tip[J_HAND_L]
                  : k == 7  ? r->tip[J_HAND_R]
                  : k == 14 ? r->tip[J_FOOT_L]
                  : k == 15 ? r->tip[J_FOOT_R]
                            : -2;
    if (tip == -2)
      v[k] = ray_pick(r, from, dir, placed, n);
    else
      v[k] = tip >= 0 ? tip
                      : nearest_vertex(r, J + 3 * (k == 6    ? J_HAND_L
                                                   : k == 7  ? J_HAND_R
                                                   : k == 14 ? J_FOOT_L
                                                             : J_FOOT_R));
    placed[n++] = v[k];
  }
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    memset(&lm[i], 0, sizeof lm[i]);
    const char *mirror, *name = km_character_landmark_name(i, &mirror);
    snprintf(lm[i].name, sizeof lm[i].name, "%s", name);
    snprintf(lm[i].mirror, sizeof lm[i].mirror, "%s", mirror);
    lm[i].vertex = v[i];
  }
}

/* ---------------------------------------------------------------- public */

/* Joints into the body. A joint the embedding left outside the surface (a sitting cat's hips
 * under its haunches, a head joint between the ears, a foot joint past the toe tip: 62 joints of
 * 19 of the 25 shared bodies before this step, 39 of 12 after it) turns its bones about a point
 * in the air: the skin weights, the bone bands and the exported skeleton all hang off it.
 * - A leaf joint (head, hand, foot) walks back along its bone towards its parent, in 1/32
 *   steps, to the second step inside: it stays at the end of its limb.
 * - Any other joint goes to the middle of the body part nearest to it: of the chord along the
 *   line from the joint to its nearest surface vertex, between where that line enters the
 *   surface and where it leaves it again. Walking along a bone instead, a hip joint beside the
 *   groin went into the thigh and then, centred across the bone from the hip centre, to the
 *   middle of the belly (the armadillo's thighs 0.14 and 0.22 of the height long).
 * A joint neither finds inside, or that would move farther than FAR_* of the height (not its
 * own part), stays, and its bit (1 << joint) is set in *outside. Returns how many moved. */
static int joints_inside(rigger *r, uint32_t *outside) {
  enum { NJ = KM_KINECT1_JOINTS, STEPS = 32 };
  const double NEAR_SURFACE = 0.03, FAR_JOINT = 0.05, FAR_LEAF = 0.15;
  int moved = 0;
  for (int j = 0; j < NJ; ++j) {
    double *p = r->J + 3 * j, x[3];
    if (inside_body(r, p)) continue;
    *outside |= 1u << j;
    bool leaf = true, ok = false;
    for (int n = 0; n < NJ; ++n)
      leaf = leaf && km_kinect1_joint_parent(n) != j;
    int par = km_kinect1_joint_parent(j);
    if (leaf && par >= 0) {
      const double *q = r->J + 3 * par;
      for (int k = 1, in = 0; k < STEPS && !ok; ++k) {
        for (int c = 0; c < 3; ++c)
          x[c] = p[c] + (q[c] - p[c]) * k / STEPS;
        if (inside_body(r, x)) ok = ++in == 2;
      }
    } else if (!leaf) {
      const double *s = P(r, nearest_vertex(r, p));
      double w[3] = {s[0] - p[0], s[1] - p[1], s[2] - p[2]}, l = dist3(s, p), t1 = INFINITY,
             t2 = INFINITY, e[3] = {0, 0, 0};
      if (l > 0) {
        for (int c = 0; c < 3; ++c)
          w[c] /= l;
        ray_crossings(r, p, w, &t1);
        if (t1 <= NEAR_SURFACE * r->H) {
          for (int c = 0; c < 3; ++c)
            e[c] = p[c] + w[c] * (t1 + 1e-6 * r->H); /* past the entry, not on it */
          ray_crossings(r, e, w, &t2);
          for (int c = 0; c < 3 && isfinite(t2); ++c)
            x[c] = e[c] + w[c] * 0.5 * t2;
          ok = isfinite(t2) && inside_body(r, x) && dist3(p, x) <= FAR_JOINT * r->H;
        }
      }
      /* The chord's middle too far: the line crosses a whole trunk (a shoulder just outside
       * a chest's side: the dinosaur's left, 0.026 of the height out; the standing cat-05's
       * right). Then along that line only as deep as the limit allows, short of the chord's
       * middle: the joint sits just under the skin of the part it touches. */
      double depth = fmin(0.5 * t2, 0.9 * FAR_JOINT * r->H - t1);
      if (!ok && t1 <= NEAR_SURFACE * r->H && isfinite(t2) && depth > 0) {
        for (int c = 0; c < 3; ++c)
          x[c] = e[c] + w[c] * depth;
        ok = inside_body(r, x);
      }
      /* Neither (the line to the nearest vertex enters too far away, or only a thin part):
       * along its bone towards its parent, in 1/32 steps of at most the limit, to the second
       * step inside, as a leaf joint does (a curled cat's shoulder centre). */
      const double *q = par >= 0 ? r->J + 3 * par : NULL;
      double lq = q ? dist3(p, q) : 0;
      for (int k = 1, in = 0; k < STEPS && !ok && lq > 0 && k * lq / STEPS <= FAR_JOINT * r->H;
           ++k) {
        for (int c = 0; c < 3; ++c)
          x[c] = p[c] + (q[c] - p[c]) * k / STEPS;
        if (inside_body(r, x)) ok = ++in == 2;
      }
    }
    /* a longer way in is not the joint's own part (a cat's shoulder beside its chest went
     * down into the leg, 0.07-0.14 of the height) */
    if (!ok || dist3(p, x) > (leaf ? FAR_LEAF : FAR_JOINT) * r->H) continue;
    memcpy(p, x, sizeof x);
    *outside &= ~(1u << j);
    ++moved;
  }
  return moved;
}

/* How many legs the body stands on: distinct extremities within 0.1 H of the ground (at most
 * 4), resting tails left out when there are three or more. Three or more: a quadruped (a
 * humanoid stands on two). */
static int ground_legs(const rigger *r) {
  bool used[KM_AUTORIG_MAX_EXTREMITIES] = {false};
  int chosen[KM_AUTORIG_MAX_EXTREMITIES] = {0}, n = 0;
  while (n < 4) {
    int e = lowest_distinct(r, used, chosen, n);
    if (e < 0 || P(r, r->ext_v[e])[1] > r->ymin + 0.1 * r->H) break;
    used[e] = true;
    chosen[n++] = e;
  }
  if (n < 3) return n;
  /* A tip at the back end of the body (kinemesh's frame faces +z) that lies on the mid-line,
   * or does not touch the ground (2.5 % of the height above it), is a tail resting there, not
   * a leg: legs stand under the body, with their soles down (the horse's and dog0's within
   * 1.1 %; a cat's front paws stretched forward can be the front end).
   * The dinosaur in ../shared/data (a biped whose tail tip is 6 % of its height above the
   * ground) and the cat standing up to reach (cat-05, its tail tip 3.8 %, curled aside) were
   * taken for quadrupeds with the tail as a hind leg. The mid-line: half way between the two
   * ground tips farthest apart across the body (x). */
  double wide = -1, xm = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      double xi = P(r, r->ext_v[chosen[i]])[0], xj = P(r, r->ext_v[chosen[j]])[0];
      if (fabs(xi - xj) > wide) wide = fabs(xi - xj), xm = 0.5 * (xi + xj);
    }
  int legs = n;
  for (int i = 0; i < n; ++i) {
    const double *p = P(r, r->ext_v[chosen[i]]);
    bool mid = fabs(p[0] - xm) < 0.25 * wide;
    bool end = p[2] < r->zlo + 0.1 * (r->zhi - r->zlo);
    if (end && (mid || p[1] > r->ymin + 0.025 * r->H)) --legs;
  }
  return legs;
}

/* An upper body with free limbs (a T-posed character cut at the waist: two hands far above
 * the cut) is not a bust: its arms would be left to hang. Extremities other than the highest,
 * 0.2 of the height above the cut (cut_top: its highest y) and farther from the cut's middle
 * (across the height) than twice the cut's width (limbs reaching out; a head cut at its neck
 * reaches 1.2 neck widths with its nose and the back of its skull): two or more. hands: the
 * farthest such tip on the left (+x of the cut's middle) and on the right, -1 none. */
static bool limbs_reach_out(const rigger *r, double cut_top, int hands[2]) {
  int free_tips = 0, top = -1;
  double far[2] = {0, 0};
  hands[0] = hands[1] = -1;
  for (size_t e = 0; e < r->n_ext; ++e)
    if (top < 0 || P(r, r->ext_v[e])[1] > P(r, r->ext_v[top])[1]) top = (int)e;
  double cx = 0, cz = 0, cn = 0, xlo = DBL_MAX, xhi = -DBL_MAX; /* the cut */
  for (size_t v = 0; v < r->n; ++v) {
    const double *q = P(r, (int32_t)v);
    if (!r->on_face[v] || q[1] > cut_top) continue;
    cx += q[0], cz += q[2], cn += 1, xlo = fmin(xlo, q[0]), xhi = fmax(xhi, q[0]);
  }
  cx /= cn > 0 ? cn : 1, cz /= cn > 0 ? cn : 1;
  for (size_t e = 0; e < r->n_ext; ++e) {
    const double *q = P(r, r->ext_v[e]);
    double d = hypot(q[0] - cx, q[2] - cz);
    bool free_tip = (int)e != top && q[1] > cut_top + 0.2 * r->H && d >= 2 * (xhi - xlo);
    free_tips += free_tip;
    int side = q[0] < cx; /* kinemesh's frame faces +z: the left is +x */
    if (free_tip && d > far[side]) far[side] = d, hands[side] = (int)e;
  }
  return free_tips >= 2;
}

const char *km_autorig_kind_name(km_autorig_skeleton kind) {
  switch (kind) {
  case KM_AUTORIG_AUTO: return "auto";
  case KM_AUTORIG_KINECT1: return "humanoid";
  case KM_AUTORIG_QUADRUPED: return "quadruped";
  case KM_AUTORIG_PROP: return "prop";
  case KM_AUTORIG_BUST: return "bust";
  case KM_AUTORIG_UPPER: return "upper body";
  case KM_AUTORIG_RESTING: return "resting body";
  }
  return "unknown";
}

/* A mesh split at its texture seams (coincident vertices that cut it into pieces or open it,
 * km_mesh_info.seam_vertices: what a glTF exporter writes) is rigged welded there, and the
 * character comes back on the file's vertices: the mesh as given, every copy with its vertex's
 * skin, landmarks and extremities on the lowest id of their copies. Split, the rig saw pieces
 * (refused) or a cut (extremities and heat stopped at it). *done false: nothing to weld. */
/* A character rigged on a part of m (the mesh welded at its seams, or its body without its
 * loose pieces) brought back onto m's vertices: m's mesh, the part's skeleton (moved out of
 * part), each vertex v the skin of the part's vertex to_part[v] (-1: unskinned, a vertex in no
 * face), and the landmarks' and the report's extremities' vertices from_part[] of theirs. */
static km_status character_from_part(const km_mesh *m, km_character *part, const int32_t *to_part,
                                     const int32_t *from_part, km_character *out,
                                     km_autorig_report *report, km_error *err) {
  size_t n = m->n_vertices;
  km_status s = km_mesh_copy(m, &out->mesh, err);
  if (s != KM_OK) return s;
  out->skeleton = part->skeleton;
  memset(&part->skeleton, 0, sizeof part->skeleton);
  out->skin.n_vertices = n;
  out->skin.joints = km__malloc(4 * n, sizeof(int32_t));
  out->skin.weights = km__malloc(4 * n, sizeof(double));
  if (!out->skin.joints || !out->skin.weights)
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (%zu vertices)", n);
  for (size_t v = 0; v < n; ++v) {
    int32_t b = to_part[v];
    for (int k = 0; k < 4; ++k) {
      out->skin.joints[4 * v + (size_t)k] =
          b >= 0 ? part->skin.joints[4 * (size_t)b + (size_t)k] : -1;
      out->skin.weights[4 * v + (size_t)k] =
          b >= 0 ? part->skin.weights[4 * (size_t)b + (size_t)k] : 0;
    }
  }
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    out->landmarks[i] = part->landmarks[i];
    if (part->landmarks[i].vertex >= 0)
      out->landmarks[i].vertex = from_part[part->landmarks[i].vertex];
  }
  for (size_t e = 0; report && e < report->n_extremities; ++e)
    if (report->extremity[e] >= 0) report->extremity[e] = from_part[report->extremity[e]];
  return KM_OK;
}

static km_status autorig_welded(const km_mesh *m, const km_autorig_options *opt, km_character *out,
                                km_autorig_report *report, bool *done, km_error *err) {
  *done = false;
  km__weld wd;
  km_status s = km__mesh_weld(m, &wd, err);
  if (s != KM_OK || !wd.to_w) return s;
  size_t n = m->n_vertices;
  const int32_t *to_w = wd.to_w, *first = wd.first;
  km_character cw = {0};
  *done = true;
  /* the head's tip, a vertex of the file, on the joined mesh */
  km_autorig_options ow = {0};
  if (opt) ow = *opt;
  int32_t head_w = -1;
  if (ow.head && *ow.head >= 0 && (size_t)*ow.head < n) head_w = to_w[*ow.head], ow.head = &head_w;
  if ((s = km_autorig(&wd.w, &ow, &cw, report, err)) != KM_OK) {
    /* what is wrong is the joined mesh's, which info does not show: say so */
    km__wrap(err, s, "joined at its texture seams (%zu vertices lying on others merged)",
             n - wd.w.n_vertices);
    goto done;
  }
  s = character_from_part(m, &cw, to_w, first, out, report, err);
  if (s == KM_OK && report && report->loose_pieces) {
    /* loose pieces counted in the file's vertices, as info counts them */
    km__body bd;
    bool found = false;
    if (km__mesh_body(&wd.w, &bd, &found, NULL) == KM_OK && found)
      report->loose_vertices = km__body_loose_vertices(&bd, to_w, n);
    km__body_free(&bd);
  }
done:
  if (s != KM_OK) km_character_free(out);
  km_character_free(&cw);
  km__weld_free(&wd);
  return s;
}

/* A body with small loose pieces (km__mesh_body: a game character's eyes, teeth or buckles,
 * each at most a quarter of the largest piece's vertices) is rigged as its largest piece, the
 * body, and each vertex of a loose piece takes the skin weights of the body vertex nearest to
 * it, so it moves as the body there does (an eye with the head); the landmarks and extremities
 * are the body's. Refused before (issue 11: "several components" was the first wall of a game
 * character whose eyes are separate meshes); the reduced model glues such pieces alike
 * (km_puppet_precompute). *done false: m is one piece; two or more pieces none of which is a
 * body (another piece has over a quarter of the largest's vertices) are refused here, naming
 * the two largest sizes. */
static km_status autorig_pieces(const km_mesh *m, const km_autorig_options *opt, km_character *out,
                                km_autorig_report *report, bool *done, km_error *err) {
  *done = false;
  km__body bd;
  km_status s = km__mesh_body(m, &bd, done, err);
  if (s == KM_OK && !*done && bd.n_pieces > 1)
    s = km__fail(err, KM_ERR_DEGENERATE_MESH,
                 "rig: the mesh has %zu components (separate pieces of connected faces), the "
                 "two largest of %zu and %zu vertices: rig rigs one body, whose small pieces "
                 "(at most a quarter of its vertices: eyes, teeth) follow it; keep one body or "
                 "join the pieces",
                 bd.n_pieces, bd.body_vertices, bd.largest_other);
  if (s != KM_OK || !*done) return s;
  size_t n = m->n_vertices;
  km_character cb = {0};
  km_autorig_options ob = {0};
  if (opt) ob = *opt;
  int32_t head_b = -1; /* the head's tip, a vertex of the file, on the body */
  if (ob.head && *ob.head >= 0 && (size_t)*ob.head < n)
    head_b = bd.to_body[*ob.head], ob.head = &head_b;
  if ((s = km_autorig(&bd.body, &ob, &cb, report, err)) != KM_OK) {
    km__wrap(err, s, "its body, the largest of %zu pieces (%zu of %zu vertices)", bd.n_pieces,
             bd.body_vertices, n);
    goto done;
  }
  s = character_from_part(m, &cb, bd.to_body, bd.from_body, out, report, err);
  /* A piece lying on the floor (a ground plane, a plinth exported with the character) is not
   * carried by the foot nearest to it: its rows get no influence, so it stays where it is in
   * pose, a skinned export and reconstruct, as animate and live leave it (km_puppet). */
  bool *ground = s == KM_OK ? km__malloc(n, sizeof *ground) : NULL;
  size_t n_ground = 0;
  if (s == KM_OK && !ground) s = km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  if (s == KM_OK && (s = km__body_ground(m, &bd, ground, &n_ground, err)) == KM_OK)
    for (size_t v = 0; v < n; ++v)
      for (int k = 0; ground[v] && k < KM_SKIN_INFLUENCES; ++k)
        out->skin.joints[4 * v + (size_t)k] = -1, out->skin.weights[4 * v + (size_t)k] = 0;
  free(ground);
  if (report) { /* the loose pieces of this mesh, besides any the body's own rigging found */
    report->loose_pieces = bd.n_pieces - 1;
    report->loose_vertices = km__body_loose_vertices(&bd, NULL, n);
    report->rigid_pieces = bd.rigid_pieces;
    report->ground_pieces = n_ground;
  }
done:
  if (s != KM_OK) km_character_free(out);
  km_character_free(&cb);
  km__body_free(&bd);
  return s;
}

km_status km_autorig(const km_mesh *m, const km_autorig_options *opt, km_character *out,
                     km_autorig_report *report, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "rig: NULL output");
  memset(out, 0, sizeof *out);
  if (report) memset(report, 0, sizeof *report);
  bool welded = false;
  km_status sw = autorig_welded(m, opt, out, report, &welded, err);
  if (sw != KM_OK || welded) return sw;
  sw = autorig_pieces(m, opt, out, report, &welded, err);
  if (sw != KM_OK || welded) return sw;
  km_autorig_options o = {0};
  if (opt) o = *opt;
  double t0 = km_seconds();
  km_status st = check_mesh(m, err);
  if (st != KM_OK) return st;
  rigger r;
  memset(&r, 0, sizeof r);
  r.m = m;
  r.n = m->n_vertices;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    r.tip[j] = -1;
  r.on_face = km__calloc(r.n, 1);
  if (!r.on_face) return km__fail(err, KM_ERR_NOMEM, "rig: out of memory (%zu vertices)", r.n);
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] >= 0 && (size_t)m->F[i] < r.n) r.on_face[m->F[i]] = 1;
  double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
  for (size_t v = 0; v < r.n; ++v)
    for (int k = 0; k < 3 && r.on_face[v]; ++k) {
      double x = m->V[3 * v + k];
      if (x < lo[k]) lo[k] = x;
      if (x > hi[k]) hi[k] = x;
    }
  r.ymin = lo[1], r.ymax = hi[1], r.H = hi[1] - lo[1], r.zlo = lo[2], r.zhi = hi[2];
  r.ext = fmax(hi[0] - lo[0], fmax(r.H, hi[2] - lo[2]));
  if (!km__progress(&o.progress, 0.0, "geodesics")) {
    free(r.on_face);
    return km__fail(err, KM_ERR_CANCELLED, "rig: cancelled");
  }
  st = km__geodesic_create(m, &r.geo, err);
  if (st != KM_OK) {
    free(r.on_face);
    return st;
  }
  km_autorig_skeleton kind = o.skeleton;
  bool bust = false, searched = false;
  bool based = kind == KM_AUTORIG_AUTO || kind == KM_AUTORIG_BUST || kind == KM_AUTORIG_UPPER;
  double cut_top;
  int hands[2] = {-1, -1};
  /* An open cut, or a broad base the body sits on (km__rest_base): a body sitting on one (a
   * sitting rabbit, a figure on a plinth) is rigged as a bust too: the head turns, the base
   * stays. Rigged by its extremities, the Stanford bunny took an ear and its snout for hands
   * and its tail for a foot, and a performer's step tore its haunch (bench motion B, longest
   * edge 2.4-3.3x, 62-88 folded triangles). */
  if (based) st = km__rest_base(m, &bust, &cut_top, err);
  if (st == KM_OK && kind != KM_AUTORIG_AUTO && based && !bust)
    st = km__fail(err, KM_ERR_DEGENERATE_MESH,
                  "rig: not a %s: no open cut at its bottom (a boundary loop within 0.06 of "
                  "the height of the lowest vertex, 0.3 of the width wide) and no broad base it "
                  "sits on (its bottom 0.05 of the height one part, half as wide and deep as the "
                  "mesh)",
                  km_autorig_kind_name(kind));
  if (st == KM_OK && bust && kind != KM_AUTORIG_BUST) {
    /* A bust's extremities are its head and the corners of its cut; one with too few for
     * that is a bust all the same. An upper body's hands reach out from its base, one on
     * either side: its arms are rigged as a humanoid's, its legs folded into the base. */
    km_error ee = {0};
    searched = true;
    bool reach = false;
    if (find_extremities(&r, &o, &ee) == KM_OK)
      reach = limbs_reach_out(&r, cut_top, hands);
    else if (ee.status == KM_ERR_CANCELLED)
      st = km__fail(err, KM_ERR_CANCELLED, "rig: cancelled");
    bool two = reach && hands[0] >= 0 && hands[1] >= 0;
    if (st == KM_OK && kind == KM_AUTORIG_AUTO)
      kind = !reach ? KM_AUTORIG_BUST : two ? KM_AUTORIG_UPPER : kind;
    if (st == KM_OK && kind == KM_AUTORIG_UPPER && !two)
      st = km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: not an upper body: no %s hand reaching out from its base (an extremity "
                    "0.2 of the height above it, farther from its middle than twice its width, "
                    "on the %s side)",
                    hands[0] < 0 ? "left" : "right", hands[0] < 0 ? "+x" : "-x");
  }
  if (st == KM_OK && kind != KM_AUTORIG_BUST && kind != KM_AUTORIG_UPPER && !searched)
    st = find_extremities(&r, &o, err);
  if (st == KM_OK && kind == KM_AUTORIG_AUTO)
    kind = ground_legs(&r) >= 3 ? KM_AUTORIG_QUADRUPED : KM_AUTORIG_KINECT1;
  if (report) {
    report->kind = kind;
    report->height = r.H;
    report->n_extremities = r.n_ext;
    memcpy(report->extremity, r.ext_v, sizeof r.ext_v);
    memcpy(report->extremity_distance, r.ext_d, sizeof r.ext_d);
  }
  if (st == KM_OK) {
    if (kind == KM_AUTORIG_BUST || kind == KM_AUTORIG_UPPER)
      st = rig_bust(&r, kind == KM_AUTORIG_UPPER ? hands : NULL, report, err);
    else if (kind == KM_AUTORIG_PROP)
      st = rig_prop(&r, report, err);
    else if (kind == KM_AUTORIG_RESTING)
      st = rig_resting(&r, o.head, report, err);
    else
      st = kind == KM_AUTORIG_QUADRUPED ? rig_quadruped(&r, report, err)
                                        : rig_humanoid(&r, report, err);
    /* Automatic choice: a body whose limbs cannot be told apart is rigged as a prop. */
    if (st == KM_ERR_DEGENERATE_MESH && o.skeleton == KM_AUTORIG_AUTO) {
      if (report) {
        snprintf(report->fallback, sizeof report->fallback, "%.200s", err ? err->message : "");
        memset(report->role, 0, sizeof report->role);
        report->kind = KM_AUTORIG_PROP;
      }
      kind = KM_AUTORIG_PROP;
      for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
        r.tip[j] = -1;
      st = rig_prop(&r, report, err);
    }
  }
  if (st == KM_OK && (kind == KM_AUTORIG_KINECT1 || kind == KM_AUTORIG_QUADRUPED)) {
    uint32_t outside = 0;
    int moved = joints_inside(&r, &outside);
    if (report) report->joints_moved_inside = moved, report->joints_outside = outside;
  }
  /* a known skeleton replaces the embedded joints; the tips found for the leaf bones stay */
  if (st == KM_OK && o.joints) {
    for (int k = 0; k < 3 * KM_KINECT1_JOINTS; ++k)
      if (!isfinite(o.joints[k]))
        st = km__fail(err, KM_ERR_INVALID, "rig: the given joint %s is not finite",
                      km_kinect1_joint_name(k / 3));
    if (st == KM_OK) memcpy(r.J, o.joints, sizeof r.J);
  }
  if (st == KM_OK && !km__progress(&o.progress, 0.6, "skin"))
    st = km__fail(err, KM_ERR_CANCELLED, "rig: cancelled");
  if (st == KM_OK) st = km_mesh_copy(m, &out->mesh, err);
  if (st == KM_OK) st = km__skin_alloc(&out->skin, r.n, err);
  if (st == KM_OK) {
    km_skeleton *sk = &out->skeleton;
    sk->n_joints = KM_KINECT1_JOINTS;
    sk->names = km__calloc(KM_KINECT1_JOINTS, sizeof *sk->names);
    sk->parents = km__malloc(KM_KINECT1_JOINTS, sizeof *sk->parents);
    sk->rest = km__malloc(3 * KM_KINECT1_JOINTS, sizeof *sk->rest);
    if (!sk->names || !sk->parents || !sk->rest)
      st = km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
    for (int j = 0; st == KM_OK && j < KM_KINECT1_JOINTS; ++j) {
      sk->names[j] = km__strdup(km_kinect1_joint_name(j));
      if (!sk->names[j]) st = km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
      sk->parents[j] = km_kinect1_joint_parent(j);
    }
    if (st == KM_OK) memcpy(sk->rest, r.J, sizeof r.J);
  }
  if (st == KM_OK) {
    km_autorig_skin skin = o.skin != KM_AUTORIG_SKIN_AUTO ? o.skin : KM_AUTORIG_SKIN_HEAT;
    if (report) report->skin = skin;
    r.quadruped = kind == KM_AUTORIG_QUADRUPED;
    if (kind == KM_AUTORIG_BUST || kind == KM_AUTORIG_RESTING) {
      /* A bust's or a resting body's skin: bone heat around its spine and neck alone, the
       * folded arms drawn into ShoulderCenter and the legs into HipCenter (bones of no length
       * there), so the head and neck are skinned to the neck (ShoulderCenter: kinemesh skins
       * a vertex with the bone that starts at its joint) and the body to the spine, the two
       * blended round ShoulderCenter as heat diffuses. Only the head turns in such a rig. With
       * the whole skeleton's heat, the folded arms' and legs' weights given to the shoulders
       * and hips, the head's vertices took ShoulderCenter's turn, which `pose` fits to its
       * three children (the head and two shoulders held still): the skinned head turned a
       * third to a half of animate's (the bunny on precog_Seq1_1, frames 57 / 100 / 196: 14.6
       * / 4.4 / 4.5 deg against 27.3 / 10.0 / 22.6), and turning the shoulders with the neck
       * turned the upper chest too (2.72x, 326 folded triangles). */
      rigger rb = r;
      for (int j = J_SHOULDER_L; j <= J_HAND_R; ++j) {
        memcpy(rb.J + 3 * j, r.J + 3 * J_SHOULDER_C, 3 * sizeof(double));
        rb.tip[j] = -1;
      }
      for (int j = J_HIP_L; j <= J_FOOT_R; ++j) {
        memcpy(rb.J + 3 * j, r.J + 3 * J_HIP_C, 3 * sizeof(double));
        rb.tip[j] = -1;
      }
      st = compute_skin(&rb, skin, &out->skin, report, err);
      if (st == KM_OK) fold_skin(&out->skin, r.n, J_SHOULDER_C);
    } else {
      st = compute_skin(&r, skin, &out->skin, report, err);
      if (st == KM_OK && kind == KM_AUTORIG_UPPER) fold_skin(&out->skin, r.n, -1);
    }
  }
  if (st == KM_OK) {
    double fwd[3] = {0, 0, 1};
    if (kind == KM_AUTORIG_QUADRUPED) {
      double a[3] = {r.J[3 * J_SHOULDER_C] - r.J[3 * J_HIP_C], 0,
                     r.J[3 * J_SHOULDER_C + 2] - r.J[3 * J_HIP_C + 2]};
      double l = hypot(a[0], a[2]);
      if (l > 0) set3(fwd, a[0] / l, 0, a[2] / l);
    }
    compute_landmarks(&r, fwd, out->landmarks);
    km__progress(&o.progress, 1.0, "done");
  }
  km__geodesic_free(&r.geo);
  free(r.dist);
  free(r.uf);
  free(r.on_face);
  free(r.acc);
  if (st != KM_OK) {
    km_character_free(out);
    return st;
  }
  if (report) report->seconds = km_seconds() - t0;
  return KM_OK;
}

/* ---------------------------------------------------------------- landmarks for a given skeleton
 */

km_status km__autorig_landmarks(const km_mesh *m, const double *J, const int32_t tips[4],
                                km_landmark *lm, km_error *err) {
  rigger r;
  memset(&r, 0, sizeof r);
  r.m = m;
  r.n = m->n_vertices;
  r.on_face = km__calloc(r.n ? r.n : 1, 1);
  if (!r.on_face) return km__fail(err, KM_ERR_NOMEM, "landmarks: out of memory");
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] >= 0 && (size_t)m->F[i] < r.n) r.on_face[m->F[i]] = 1;
  double ymin = DBL_MAX, ymax = -DBL_MAX;
  for (size_t v = 0; v < r.n; ++v)
    if (r.on_face[v]) ymin = fmin(ymin, m->V[3 * v + 1]), ymax = fmax(ymax, m->V[3 * v + 1]);
  r.H = ymax > ymin ? ymax - ymin : 1;
  memcpy(r.J, J, sizeof r.J);
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    r.tip[j] = -1;
  r.tip[J_HAND_L] = tips[0], r.tip[J_HAND_R] = tips[1];
  r.tip[J_FOOT_L] = tips[2], r.tip[J_FOOT_R] = tips[3];
  const double fwd[3] = {0, 0, 1};
  compute_landmarks(&r, fwd, lm);
  free(r.on_face);
  return KM_OK;
}
