/* Per-joint rigid transforms from joint positions, and linear blend skinning.
 *
 * Skinning convention: a vertex weighted to joint j follows the rigid transform of the bone
 * that starts at j and goes to j's child (or children). So forearm vertices are weighted to
 * the elbow, upper-arm vertices to the shoulder, and T_j(p) = R_j (p - rest_j) + pos_j, i.e.
 * the joint's rest position maps to its posed position and the bone(s) below it turn by R_j.
 *
 * R_j is found from the directions of j's children:
 *  - one child: the parent's rotation, followed by the minimal rotation taking the
 *    parent-rotated rest direction onto the posed direction (no twist about the bone beyond
 *    what the parent carries), so a rigidly moved skeleton gives every joint that motion;
 *  - several children (HipCenter, ShoulderCenter): the best-fit rotation of the unit child
 *    directions (km__rotation_fit3: Kabsch, reflection-corrected);
 *  - no child (Head, hands, feet) or no valid child position: the parent's rotation.
 * A joint whose position is NaN holds its parent's transform (applied to its rest offset). */
#include "core/core.h"
#include "math/math.h"

#include <stdlib.h>

static double norm3(const double v[3]) { return sqrt(km__dot3(v, v)); }

/* km_skeleton_pose_from_positions (lengths false) and km_skeleton_pose_from_directions (true:
 * a joint below the root is placed where its parent's transform carries its rest position). */
static km_status pose_from(const km_skeleton *s, const double *positions, bool lengths,
                           double *transforms, km_error *err) {
  if (!s || !positions || !transforms || !s->parents || !s->rest)
    return km__fail(err, KM_ERR_INVALID, "km_skeleton_pose_from_%s: NULL argument",
                    lengths ? "directions" : "positions");
  const size_t n = s->n_joints;
  for (size_t j = 0; j < n; ++j) {
    if (s->parents[j] < -1 || s->parents[j] >= (int32_t)j)
      return km__fail(err, KM_ERR_INVALID,
                      "skeleton: parent of joint %zu is %ld, not an earlier joint", j,
                      (long)s->parents[j]);
    if (!km__finite3(s->rest + 3 * j))
      return km__fail(err, KM_ERR_INVALID, "skeleton: rest position of joint %zu is not finite", j);
  }
  /* Children in CSR form; the skeleton is tiny, but one allocation serves any size. */
  int32_t *first = km__calloc(n + 1, sizeof *first);
  int32_t *kids = km__malloc(n, sizeof *kids);
  double *P = km__malloc(n, 3 * sizeof *P);
  double *dir = km__malloc(n, 6 * sizeof *dir); /* rest and posed unit child directions */
  if (!first || !kids || !P || !dir) {
    free(first), free(kids), free(P), free(dir);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t j = 0; j < n; ++j)
    if (s->parents[j] >= 0) ++first[s->parents[j] + 1];
  for (size_t j = 0; j < n; ++j)
    first[j + 1] += first[j];
  {
    int32_t *fill = km__malloc(n + 1, sizeof *fill);
    if (!fill) {
      free(first), free(kids), free(P), free(dir);
      return km__fail(err, KM_ERR_NOMEM, "out of memory");
    }
    memcpy(fill, first, (n + 1) * sizeof *fill);
    for (size_t j = 0; j < n; ++j)
      if (s->parents[j] >= 0) kids[fill[s->parents[j]]++] = (int32_t)j;
    free(fill);
  }

  for (size_t j = 0; j < n; ++j) {
    double *T = transforms + 12 * j;
    const double *rj = s->rest + 3 * j;
    double Rp[9], tp[3] = {0, 0, 0};
    int p = s->parents[j];
    if (p >= 0) {
      const double *Tp = transforms + 12 * p;
      for (int i = 0; i < 3; ++i) {
        Rp[3 * i] = Tp[4 * i], Rp[3 * i + 1] = Tp[4 * i + 1], Rp[3 * i + 2] = Tp[4 * i + 2];
        tp[i] = Tp[4 * i + 3];
      }
    } else {
      km__m3_identity(Rp);
    }
    double R[9];
    memcpy(R, Rp, sizeof R);
    const double *pj = positions + 3 * j;
    bool tracked = km__finite3(pj);
    if (tracked && !(lengths && p >= 0)) {
      memcpy(P + 3 * j, pj, 3 * sizeof *P);
    } else {
      /* carried rigidly by its parent: a missing joint, or (lengths) the rig's own bone */
      double q[3];
      km__m3_apply(Rp, rj, q);
      for (int i = 0; i < 3; ++i)
        P[3 * j + i] = q[i] + tp[i];
    }
    if (tracked) {
      int m = 0;
      for (int32_t k = first[j]; k < first[j + 1]; ++k) {
        const double *pc = positions + 3 * kids[k], *rc = s->rest + 3 * kids[k];
        if (!km__finite3(pc)) continue;
        double d[3] = {rc[0] - rj[0], rc[1] - rj[1], rc[2] - rj[2]};
        double e[3] = {pc[0] - pj[0], pc[1] - pj[1], pc[2] - pj[2]};
        double nd = norm3(d), ne = norm3(e);
        if (!(nd > 1e-12 && ne > 1e-12)) continue;
        for (int i = 0; i < 3; ++i)
          dir[6 * m + i] = d[i] / nd, dir[6 * m + 3 + i] = e[i] / ne;
        ++m;
      }
      bool done = false;
      if (m >= 2) {
        /* H = sum d_i e_i^T; collinear directions leave the turn about them open */
        double H[9] = {0}, S[3], Rk[9];
        for (int k = 0; k < m; ++k)
          for (int i = 0; i < 3; ++i)
            for (int jj = 0; jj < 3; ++jj)
              H[3 * i + jj] += dir[6 * k + i] * dir[6 * k + 3 + jj];
        if (km__rotation_fit3(H, Rk, S) >= 0 && S[1] > 1e-9 * S[0]) {
          memcpy(R, Rk, sizeof Rk);
          done = true;
        }
      }
      if (!done && m >= 1) {
        double a[3], Rm[9];
        km__m3_apply(Rp, dir, a);
        km__rot3_between(a, dir + 3, Rm);
        km__m3_mul(Rm, Rp, R);
      }
    }
    double Rr[3];
    km__m3_apply(R, rj, Rr);
    for (int i = 0; i < 3; ++i) {
      T[4 * i] = R[3 * i], T[4 * i + 1] = R[3 * i + 1], T[4 * i + 2] = R[3 * i + 2];
      T[4 * i + 3] = P[3 * j + i] - Rr[i];
    }
  }
  free(first), free(kids), free(P), free(dir);
  return KM_OK;
}

km_status km_skeleton_pose_from_positions(const km_skeleton *s, const double *positions,
                                          double *transforms, km_error *err) {
  return pose_from(s, positions, false, transforms, err);
}

km_status km_skeleton_pose_from_directions(const km_skeleton *s, const double *positions,
                                           double *transforms, km_error *err) {
  return pose_from(s, positions, true, transforms, err);
}

void km__forward_kinematics(size_t n, const int32_t *parents, const double *L, const double *o,
                            double *W, double *P) {
  for (size_t j = 0; j < n; ++j) {
    int32_t p = parents[j];
    if (p < 0) {
      memcpy(W + 9 * j, L + 9 * j, 9 * sizeof *W);
      if (P != o) memcpy(P + 3 * j, o + 3 * j, 3 * sizeof *P);
    } else {
      const double *Wp = W + 9 * (size_t)p, *Pp = P + 3 * (size_t)p;
      double d[3];
      km__m3_apply(Wp, o + 3 * j, d);
      for (int a = 0; a < 3; ++a)
        P[3 * j + a] = Pp[a] + d[a];
      km__m3_mul(Wp, L + 9 * j, W + 9 * j);
    }
  }
}

void km__joint_transforms(size_t n, const double *W, const double *P, const double *rest,
                          double *G) {
  for (size_t j = 0; j < n; ++j) {
    const double *Wj = W + 9 * j;
    double WJ[3];
    km__m3_apply(Wj, rest + 3 * j, WJ);
    double *Gj = G + 12 * j;
    for (int r = 0; r < 3; ++r) {
      Gj[4 * r] = Wj[3 * r], Gj[4 * r + 1] = Wj[3 * r + 1], Gj[4 * r + 2] = Wj[3 * r + 2];
      Gj[4 * r + 3] = P[3 * j + r] - WJ[r];
    }
  }
}

int km__skin_keep_largest(const double *w, int n, int32_t *joints, double *weights) {
  int32_t jj[KM_SKIN_INFLUENCES];
  double ww[KM_SKIN_INFLUENCES];
  int cnt = 0;
  for (int j = 0; j < n; ++j) { /* insertion into the sorted few */
    if (!(w[j] > 0)) continue;
    int pos = cnt;
    while (pos > 0 && ww[pos - 1] < w[j])
      --pos;
    if (pos >= KM_SKIN_INFLUENCES) continue;
    int last = cnt < KM_SKIN_INFLUENCES ? cnt : KM_SKIN_INFLUENCES - 1;
    for (int q = last; q > pos; --q)
      ww[q] = ww[q - 1], jj[q] = jj[q - 1];
    ww[pos] = w[j], jj[pos] = j;
    if (cnt < KM_SKIN_INFLUENCES) ++cnt;
  }
  double sum = 0;
  for (int q = 0; q < cnt; ++q)
    sum += ww[q];
  for (int q = 0; q < KM_SKIN_INFLUENCES; ++q) {
    joints[q] = q < cnt ? jj[q] : -1;
    weights[q] = q < cnt ? ww[q] / sum : 0.0;
  }
  return cnt;
}

bool km__skin_row_empty(const int32_t *joints, const double *weights) {
  for (int k = 0; k < KM_SKIN_INFLUENCES; ++k)
    if (joints[k] >= 0 && weights[k] > 0) return false;
  return true;
}

int32_t km__skin_dominant(const int32_t *joints, const double *weights) {
  int best = 0;
  for (int k = 1; k < KM_SKIN_INFLUENCES; ++k)
    if (joints[k] >= 0 && weights[k] > weights[best]) best = k;
  return joints[best];
}

km_status km_lbs(const double *rest, size_t n_vertices, const km_skin *skin,
                 const double *transforms, size_t n_joints, double *out, km_error *err) {
  if (!rest || !skin || !transforms || !out || (n_vertices && (!skin->joints || !skin->weights)))
    return km__fail(err, KM_ERR_INVALID, "km_lbs: NULL argument");
  if (skin->n_vertices != n_vertices)
    return km__fail(err, KM_ERR_INVALID, "km_lbs: skin has %zu vertices, mesh has %zu",
                    skin->n_vertices, n_vertices);
  if (out == rest) return km__fail(err, KM_ERR_INVALID, "km_lbs: out aliases rest");
  long bad = -1;
#pragma omp parallel for schedule(static) if (n_vertices > 20000)
  for (long v = 0; v < (long)n_vertices; ++v) {
    const double *p = rest + 3 * v;
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (int k = 0; k < KM_SKIN_INFLUENCES; ++k) {
      int32_t j = skin->joints[KM_SKIN_INFLUENCES * v + k];
      double w = skin->weights[KM_SKIN_INFLUENCES * v + k];
      if (j < 0) continue;
      if ((size_t)j >= n_joints || !isfinite(w)) {
#pragma omp critical(km_lbs_bad)
        bad = v;
        continue;
      }
      if (w == 0) continue;
      const double *T = transforms + 12 * j;
      for (int i = 0; i < 3; ++i)
        acc[i] += w * (T[4 * i] * p[0] + T[4 * i + 1] * p[1] + T[4 * i + 2] * p[2] + T[4 * i + 3]);
      wsum += w;
    }
    /* A vertex without influences stays at rest instead of collapsing to the origin. */
    double *o = out + 3 * v;
    if (wsum == 0)
      o[0] = p[0], o[1] = p[1], o[2] = p[2];
    else
      o[0] = acc[0], o[1] = acc[1], o[2] = acc[2];
  }
  if (bad >= 0)
    return km__fail(err, KM_ERR_INVALID,
                    "km_lbs: vertex %ld has an influence on joint outside 0..%zu or a non-finite "
                    "weight",
                    bad, n_joints - 1);
  return KM_OK;
}

km_status km_skeleton_from_weights(const km_mesh *m, const km_skin *skin, const int32_t *parents,
                                   size_t n_joints, double *rest, km_error *err) {
  if (!m || !skin || !parents || !rest || !n_joints)
    return km__fail(err, KM_ERR_INVALID, "km_skeleton_from_weights: NULL argument");
  if (skin->n_vertices != m->n_vertices || !skin->joints || !skin->weights)
    return km__fail(err, KM_ERR_INVALID,
                    "km_skeleton_from_weights: skin has %zu vertices, mesh %zu", skin->n_vertices,
                    m->n_vertices);
  for (size_t j = 0; j < n_joints; ++j)
    if (parents[j] >= (int32_t)n_joints)
      return km__fail(err, KM_ERR_INVALID, "km_skeleton_from_weights: joint %zu: bad parent %d", j,
                      parents[j]);
  /* per joint: boundary sums (weight, weighted position) and own-part sums */
  double *acc = km__calloc(n_joints * 8, sizeof *acc);
  if (!acc) return km__fail(err, KM_ERR_NOMEM, "km_skeleton_from_weights: out of memory");
  for (size_t v = 0; v < m->n_vertices; ++v) {
    const int32_t *jv = skin->joints + KM_SKIN_INFLUENCES * v;
    const double *wv = skin->weights + KM_SKIN_INFLUENCES * v, *x = m->V + 3 * v;
    for (int a = 0; a < KM_SKIN_INFLUENCES; ++a) {
      int32_t j = jv[a];
      if (j < 0 || (size_t)j >= n_joints || !(wv[a] > 0)) continue;
      double *own = acc + 8 * (size_t)j + 4;
      own[0] += wv[a];
      for (int k = 0; k < 3; ++k)
        own[1 + k] += wv[a] * x[k];
      for (int b = 0; b < KM_SKIN_INFLUENCES; ++b)
        if (jv[b] == parents[j] && wv[b] > 0) {
          double w = fmin(wv[a], wv[b]);
          double *bd = acc + 8 * (size_t)j;
          bd[0] += w;
          for (int k = 0; k < 3; ++k)
            bd[1 + k] += w * x[k];
        }
    }
  }
  for (size_t j = 0; j < n_joints; ++j) {
    const double *bd = acc + 8 * j, *own = bd + 4;
    const double *use = parents[j] >= 0 && bd[0] > 0 ? bd : own[0] > 0 ? own : NULL;
    if (use)
      for (int k = 0; k < 3; ++k)
        rest[3 * j + k] = use[1 + k] / use[0];
  }
  free(acc);
  return KM_OK;
}
