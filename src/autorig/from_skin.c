/* A skinned glTF's own skeleton and weights as kinemesh's Kinect v1 rig
 * (km_character_from_skin): joint names mapped by the common conventions, the spine and
 * shoulders found from the hierarchy, every other joint's weights merged into its nearest
 * mapped ancestor. The method is described at km_character_from_skin in include/kinemesh.h. */
#include "autorig/autorig.h"

#include "math/math.h"
#include "motion/motion.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Roles a name can give: a Kinect joint index, or these for the centre line. */
enum { R_NONE = -1, R_HIPS = 100, R_NECK = 101 };

/* A joint name's role: the Kinect v1 joint of the one name matcher (km__bone_name_kinect1),
 * with the centre line kept apart (the spine and shoulders are found from the hierarchy). */
static int classify(const char *name) {
  /* kinemesh's own names first (pose --export skeleton writes them: ShoulderLeft is where the
   * upper arm starts, HandLeft the hand's end), then the conventions' */
  int j = km_skeleton_joint_index(KM_SKELETON_KINECT1, name);
  if (j < 0) j = km__bone_name_kinect1(name);
  if (j == J_HIP_C) return R_HIPS;
  if (j == J_SHOULDER_C) return R_NECK;
  if (j == J_SPINE) return R_NONE;
  return j;
}

typedef struct tree {
  const km_mesh_skin *s;
  int *depth;
} tree;

static bool is_ancestor(const tree *t, int a, int b) { /* a ancestor-or-self of b */
  for (int x = b; x >= 0; x = t->s->parents[x])
    if (x == a) return true;
  return false;
}

static int lca(const tree *t, int a, int b) {
  while (a >= 0 && b >= 0 && a != b) {
    if (t->depth[a] >= t->depth[b])
      a = t->s->parents[a];
    else
      b = t->s->parents[b];
  }
  return a == b ? a : -1;
}

static void lerp3(const double *a, const double *b, double f, double *o) {
  for (int k = 0; k < 3; ++k)
    o[k] = a[k] + f * (b[k] - a[k]);
}

km_status km_character_from_skin(const km_mesh *m, const km_mesh_skin *s, km_character *out,
                                 km_skin_mapping *map, km_error *err) {
  if (!m || !s || !out) return km__fail(err, KM_ERR_INVALID, "skin: NULL argument");
  memset(out, 0, sizeof *out);
  if (map) memset(map, 0, sizeof *map);
  if (!s->n_joints || !s->joints || !s->weights || !s->names || !s->parents || !s->rest)
    return km__fail(err, KM_ERR_INVALID, "skin: the mesh has no skin");
  if (s->n_vertices != m->n_vertices)
    return km__fail(err, KM_ERR_INVALID, "skin: %zu vertices, the mesh has %zu", s->n_vertices,
                    m->n_vertices);
  const size_t nj = s->n_joints, nv = m->n_vertices;
  int *role = km__malloc(nj, sizeof *role), *depth = km__malloc(nj, sizeof *depth);
  int *owner = km__malloc(nj, sizeof *owner), *target = km__malloc(nj, sizeof *target);
  int32_t *dom = km__malloc(nv ? nv : 1, sizeof *dom);
  km_status st = KM_OK;
  if (!role || !depth || !owner || !target || !dom) {
    st = km__fail(err, KM_ERR_NOMEM, "skin: out of memory");
    goto done;
  }
  tree t = {s, depth};
  for (size_t j = 0; j < nj; ++j) {
    int d = 0;
    for (int x = s->parents[j]; x >= 0 && d <= (int)nj; x = s->parents[x])
      ++d;
    if (d > (int)nj) {
      st = km__fail(err, KM_ERR_PARSE, "skin: the joint hierarchy has a cycle at %s", s->names[j]);
      goto done;
    }
    depth[j] = d;
    role[j] = classify(s->names[j]);
  }
  /* The shallowest joint of each role. */
  int pick[KM_KINECT1_JOINTS], hips = -1, necks = -1;
  for (int k = 0; k < KM_KINECT1_JOINTS; ++k)
    pick[k] = -1;
  for (size_t j = 0; j < nj; ++j) {
    int r = role[j];
    int *slot = r == R_HIPS ? &hips : r == R_NECK ? &necks : r >= 0 ? &pick[r] : NULL;
    if (slot && (*slot < 0 || depth[j] < depth[*slot])) *slot = (int)j;
  }
  static const int required[] = {J_HEAD,    J_SHOULDER_L, J_ELBOW_L, J_WRIST_L, J_SHOULDER_R,
                                 J_ELBOW_R, J_WRIST_R,    J_HIP_L,   J_KNEE_L,  J_ANKLE_L,
                                 J_HIP_R,   J_KNEE_R,     J_ANKLE_R};
  static const char *const need[] = {
      "Head",          "LeftUpperArm",  "LeftLowerArm", "LeftHand",     "RightUpperArm",
      "RightLowerArm", "RightHand",     "LeftUpperLeg", "LeftLowerLeg", "LeftFoot",
      "RightUpperLeg", "RightLowerLeg", "RightFoot"};
  char missing[256] = "";
  for (size_t i = 0; i < sizeof required / sizeof *required; ++i)
    if (pick[required[i]] < 0)
      snprintf(missing + strlen(missing), sizeof missing - strlen(missing), "%s%s",
               missing[0] ? ", " : "", need[i]);
  if (missing[0]) {
    char names[256] = "";
    for (size_t j = 0; j < nj && strlen(names) < 200; ++j)
      snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", j ? ", " : "",
               s->names[j]);
    st = km__fail(err, KM_ERR_UNSUPPORTED,
                  "skin: no joint found for %s (the joint names follow none of Mixamo, VRM / "
                  "Unity HumanBodyBones, Blender rigify; the file has %zu joints: %s%s); "
                  "rig the mesh with `kinemesh rig --skeleton kinect1` instead",
                  missing, nj, names, nj > 0 && strlen(names) >= 200 ? ", ..." : "");
    goto done;
  }
  double J[KM_KINECT1_JOINTS * 3];
#define RJ(j) (s->rest + 3 * (size_t)(j))
  int hip_c = lca(&t, pick[J_HIP_L], pick[J_HIP_R]);
  if (hip_c < 0) hip_c = hips;
  if (hip_c < 0) hip_c = pick[J_HIP_L]; /* legs in separate trees: take one */
  int sh_lca = lca(&t, pick[J_SHOULDER_L], pick[J_SHOULDER_R]);
  if (sh_lca < 0)
    sh_lca = s->parents[pick[J_SHOULDER_L]] >= 0 ? s->parents[pick[J_SHOULDER_L]] : hip_c;
  int neck = sh_lca;
  if (necks >= 0 && is_ancestor(&t, sh_lca, necks) && is_ancestor(&t, necks, pick[J_HEAD]))
    neck = necks;
  if (neck == hip_c) neck = -1; /* arms on the hips: no chest joint of its own */
  memcpy(J + 3 * J_HIP_C, RJ(hip_c), 3 * sizeof(double));
  if (neck >= 0)
    memcpy(J + 3 * J_SHOULDER_C, RJ(neck), 3 * sizeof(double));
  else
    lerp3(RJ(pick[J_SHOULDER_L]), RJ(pick[J_SHOULDER_R]), 0.5, J + 3 * J_SHOULDER_C);
  for (size_t j = 0; j < nj; ++j)
    owner[j] = -1;
  /* Spine: the chain from the neck down to the hips; the joint nearest 48% of the way up
   * (the procedural character's proportion) gives the position, all of them the weights. */
  double want[3];
  lerp3(J + 3 * J_HIP_C, J + 3 * J_SHOULDER_C, 0.48, want);
  memcpy(J + 3 * J_SPINE, want, sizeof want);
  double best = DBL_MAX;
  if (neck >= 0 && is_ancestor(&t, hip_c, neck))
    for (int x = s->parents[neck]; x >= 0 && x != hip_c; x = s->parents[x]) {
      owner[x] = J_SPINE;
      double dd = 0;
      for (int k = 0; k < 3; ++k)
        dd += (RJ(x)[k] - want[k]) * (RJ(x)[k] - want[k]);
      if (dd < best) {
        best = dd;
        memcpy(J + 3 * J_SPINE, RJ(x), 3 * sizeof(double));
        if (map) snprintf(map->source[J_SPINE], sizeof map->source[J_SPINE], "%s", s->names[x]);
      }
    }
  owner[hip_c] = J_HIP_C;
  if (neck >= 0) owner[neck] = J_SHOULDER_C;
  if (map) {
    snprintf(map->source[J_HIP_C], sizeof map->source[J_HIP_C], "%s", s->names[hip_c]);
    if (neck >= 0)
      snprintf(map->source[J_SHOULDER_C], sizeof map->source[J_SHOULDER_C], "%s", s->names[neck]);
  }
  for (int k = 0; k < KM_KINECT1_JOINTS; ++k) {
    if (k == J_HIP_C || k == J_SPINE || k == J_SHOULDER_C) continue;
    int j = pick[k];
    /* a hand or toe joint counts only below its wrist or ankle */
    if ((k == J_HAND_L || k == J_HAND_R || k == J_FOOT_L || k == J_FOOT_R) && j >= 0 &&
        !is_ancestor(&t, pick[k - 1], j))
      j = -1;
    pick[k] = j;
    if (j < 0) continue;
    owner[j] = k;
    memcpy(J + 3 * k, RJ(j), 3 * sizeof(double));
    if (map) snprintf(map->source[k], sizeof map->source[k], "%s", s->names[j]);
  }
  /* Ends without a joint: the hand at the mean of the wrist's children (the fingers' roots),
   * else 0.3 forearm past the wrist; the foot at the ankle's first child, else ahead of and
   * below the ankle. */
  double ymin = DBL_MAX;
  for (size_t v = 0; v < nv; ++v)
    ymin = fmin(ymin, m->V[3 * v + 1]);
  for (int side = 0; side < 2; ++side) {
    int h = side ? J_HAND_R : J_HAND_L, w = h - 1, e = h - 2;
    if (pick[h] < 0) {
      double c[3] = {0, 0, 0};
      int cnt = 0;
      for (size_t j = 0; j < nj; ++j)
        if (s->parents[j] == pick[w]) {
          for (int k = 0; k < 3; ++k)
            c[k] += RJ(j)[k];
          ++cnt;
        }
      if (cnt)
        for (int k = 0; k < 3; ++k)
          J[3 * h + k] = c[k] / cnt;
      else
        lerp3(J + 3 * e, J + 3 * w, 1.3, J + 3 * h);
    }
    int f = side ? J_FOOT_R : J_FOOT_L, a = f - 1;
    if (pick[f] < 0) {
      int child = -1;
      for (size_t j = 0; j < nj && child < 0; ++j)
        if (s->parents[j] == pick[a]) child = (int)j;
      if (child >= 0) {
        memcpy(J + 3 * f, RJ(child), 3 * sizeof(double));
      } else {
        double hgt = J[3 * a + 1] - ymin;
        J[3 * f] = J[3 * a], J[3 * f + 1] = ymin + 0.4 * hgt, J[3 * f + 2] = J[3 * a + 2] + hgt;
      }
    }
  }
  /* Every other joint weights the Kinect joint of its nearest mapped ancestor (none: the
   * hips), except a joint above the hips (the armature's root, which kinemesh's own skinned
   * export binds a ground plane to): its vertices stay (target -1, a skin row with no
   * influence), as they do in the file, where nothing moves that root. */
  size_t merged = 0;
  for (size_t j = 0; j < nj; ++j) {
    int x = (int)j;
    while (x >= 0 && owner[x] < 0)
      x = s->parents[x];
    target[j] = x >= 0                                              ? owner[x]
                : (int)j != hip_c && is_ancestor(&t, (int)j, hip_c) ? -1
                                                                    : J_HIP_C;
    merged += owner[j] < 0 && target[j] >= 0;
  }
  if (map) map->n_merged = merged;
  if ((st = km_mesh_copy(m, &out->mesh, err)) || (st = km__skin_alloc(&out->skin, nv, err)))
    goto done;
  km_skeleton *sk = &out->skeleton;
  sk->n_joints = KM_KINECT1_JOINTS;
  sk->names = km__calloc(KM_KINECT1_JOINTS, sizeof *sk->names);
  sk->parents = km__malloc(KM_KINECT1_JOINTS, sizeof *sk->parents);
  sk->rest = km__malloc(3 * KM_KINECT1_JOINTS, sizeof *sk->rest);
  if (!sk->names || !sk->parents || !sk->rest) {
    st = km__fail(err, KM_ERR_NOMEM, "skin: out of memory");
    goto done;
  }
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    if (!(sk->names[j] = km__strdup(km_kinect1_joint_name(j)))) {
      st = km__fail(err, KM_ERR_NOMEM, "skin: out of memory");
      goto done;
    }
    sk->parents[j] = km_kinect1_joint_parent(j);
  }
  memcpy(sk->rest, J, sizeof J);
  size_t still = 0;
  for (size_t v = 0; v < nv; ++v) {
    double w[KM_KINECT1_JOINTS] = {0}, sum = 0;
    for (int q = 0; q < 4; ++q) {
      int32_t j = s->joints[4 * v + q];
      double x = s->weights[4 * v + q];
      if (!(j >= 0 && (size_t)j < nj && x > 0 && isfinite(x))) continue;
      if (target[j] >= 0) w[target[j]] += x, sum += x; /* target -1: above the hips */
    }
    /* wholly on the root above the hips, or on no joint at all (an unskinned primitive with no
     * joint above its node: a ground plane beside the armature): no influence, so it stays, as
     * Blender's armature leaves an unweighted vertex (km__skin_keep_largest of all zeros) */
    still += !(sum > 0);
    km__skin_keep_largest(w, KM_KINECT1_JOINTS, out->skin.joints + 4 * v,
                          out->skin.weights + 4 * v);
    dom[v] = out->skin.joints[4 * v];
  }
  if (map) map->n_still = still;
  /* Tips for the landmarks: the hand's vertex farthest along wrist -> hand, the foot's
   * farthest along ankle -> foot (horizontally), among the vertices they dominate. */
  int32_t tips[4];
  for (int i = 0; i < 4; ++i) {
    int e = i == 0 ? J_HAND_L : i == 1 ? J_HAND_R : i == 2 ? J_FOOT_L : J_FOOT_R, b = e - 1;
    double d[3];
    for (int k = 0; k < 3; ++k)
      d[k] = J[3 * e + k] - J[3 * b + k];
    if (i >= 2) d[1] = 0;
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0)) d[0] = 0, d[1] = i >= 2 ? 0 : -1, d[2] = i >= 2 ? 1 : 0, len = 1;
    double bt = -DBL_MAX, bd = DBL_MAX;
    int32_t bv = -1, near = 0;
    for (size_t v = 0; v < nv; ++v) {
      const double *p = m->V + 3 * v;
      double q[3] = {p[0] - J[3 * b], p[1] - J[3 * b + 1], p[2] - J[3 * b + 2]};
      double dn = (p[0] - J[3 * e]) * (p[0] - J[3 * e]) +
                  (p[1] - J[3 * e + 1]) * (p[1] - J[3 * e + 1]) +
                  (p[2] - J[3 * e + 2]) * (p[2] - J[3 * e + 2]);
      if (dn < bd) bd = dn, near = (int32_t)v;
      if (dom[v] != e && dom[v] != b) continue;
      double tt = (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / len;
      if (tt > bt) bt = tt, bv = (int32_t)v;
    }
    tips[i] = bv >= 0 ? bv : near;
  }
  st = km__autorig_landmarks(m, J, tips, out->landmarks, err);
#undef RJ
done:
  free(role);
  free(depth);
  free(owner);
  free(target);
  free(dom);
  if (st != KM_OK) km_character_free(out);
  return st;
}
