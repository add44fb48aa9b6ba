/* Puppetry rig: JSON parsing (cJSON) and handle resolution on a mesh (see km_rig_parse). */
#include "motion/motion.h"
#include "math/math.h"
#include "mesh/mesh.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_i32(const void *a, const void *b) {
  int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
  return (x > y) - (x < y);
}

/* Sorts and removes duplicates; returns the new length. */
static size_t sort_unique(int32_t *v, size_t n) {
  if (n == 0) return 0;
  qsort(v, n, sizeof *v, cmp_i32);
  size_t m = 1;
  for (size_t i = 1; i < n; ++i)
    if (v[i] != v[m - 1]) v[m++] = v[i];
  return m;
}

void km_rig_free(km_rig *rig) {
  if (!rig) return;
  for (size_t h = 0; h < rig->n_handles; ++h)
    free(rig->handles[h].vertices);
  free(rig->handles);
  free(rig->maps);
  free(rig->joint_rest);
  memset(rig, 0, sizeof *rig);
}

int32_t km_rig_nearest_handle(const km_rig *rig, const km_mesh *mesh, const double x[3]) {
  double best = INFINITY;
  int32_t h = -1;
  if (!rig || !mesh || !x) return -1;
  for (size_t i = 0; i < rig->n_handles; ++i)
    for (size_t k = 0; k < rig->handles[i].n_vertices; ++k) {
      int32_t v = rig->handles[i].vertices[k];
      if (v < 0 || (size_t)v >= mesh->n_vertices) continue;
      double d[3];
      km__sub3(mesh->V + 3 * (size_t)v, x, d);
      double dd = km__dot3(d, d);
      if (dd < best) best = dd, h = (int32_t)i;
    }
  return h;
}

/* ---- geodesic balls: km__geodesic (mesh) with the radius as its bound, so a run only touches
 * the ball. */

/* Vertices within edge-path distance `radius` of `seed`, into a malloc'ed list. */
static bool geodesic_ball(km__geodesic *g, const double *V, int32_t seed, double radius,
                          int32_t **out, size_t *n_out) {
  const int32_t *reached;
  size_t n;
  km__geodesic_run(g, V, seed, radius, NULL, 0, &reached, &n);
  int32_t *list = km__malloc(n, sizeof(int32_t));
  if (list) memcpy(list, reached, n * sizeof(int32_t));
  *out = list;
  *n_out = list ? n : 0;
  return list != NULL;
}

/* ---- JSON helpers */

static bool json_int(const cJSON *j, double lo, double hi, int64_t *out) {
  return cJSON_IsNumber(j) && km__whole_number(j->valuedouble, lo, hi, out);
}

static bool json_finite(const cJSON *j, double *out) {
  if (!cJSON_IsNumber(j) || !isfinite(j->valuedouble)) return false;
  *out = j->valuedouble;
  return true;
}

/* Line number of a byte offset, for cJSON syntax errors. */
static size_t line_of(const char *text, size_t offset) {
  size_t line = 1;
  for (size_t i = 0; i < offset; ++i)
    line += text[i] == '\n';
  return line;
}

static int find_handle(const km_rig *rig, const char *name) {
  for (size_t h = 0; h < rig->n_handles; ++h)
    if (strcmp(rig->handles[h].name, name) == 0) return (int)h;
  return -1;
}

static km_status parse_axes(const char *s, uint32_t *mask) {
  uint32_t m = 0;
  if (!*s) return KM_ERR_PARSE;
  for (const char *p = s; *p; ++p) {
    uint32_t bit = *p == 'x' ? KM_AXIS_X : *p == 'y' ? KM_AXIS_Y : *p == 'z' ? KM_AXIS_Z : 0;
    if (!bit || (m & bit)) return KM_ERR_PARSE;
    m |= bit;
  }
  *mask = m;
  return KM_OK;
}

static km_status parse_filter(const char *name, const cJSON *jf, km_filter_options *fo,
                              km_error *err) {
  memset(fo, 0, sizeof *fo);
  if (!jf) return KM_OK;
  if (!cJSON_IsObject(jf))
    return km__fail(err, KM_ERR_PARSE, "%s: \"filter\" must be an object", name);
  static const char *const keys[5] = {"smoothing", "trend", "prediction", "jitter_radius",
                                      "max_deviation"};
  double *dst[5] = {&fo->smoothing, &fo->trend, &fo->prediction, &fo->jitter_radius,
                    &fo->max_deviation};
  const cJSON *jk = cJSON_GetObjectItemCaseSensitive(jf, "kind");
  if (jk) {
    if (cJSON_IsString(jk) && !strcmp(jk->valuestring, "holt"))
      fo->kind = KM_FILTER_HOLT;
    else if (cJSON_IsString(jk) && !strcmp(jk->valuestring, "one_euro"))
      fo->kind = KM_FILTER_ONE_EURO;
    else
      return km__fail(err, KM_ERR_PARSE, "%s: filter.kind: expected \"holt\" or \"one_euro\"",
                      name);
  }
  static const char *const euro_keys[3] = {"min_cutoff", "beta", "d_cutoff"};
  double *euro_dst[3] = {&fo->min_cutoff, &fo->beta, &fo->d_cutoff};
  for (int k = 0; k < 3; ++k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(jf, euro_keys[k]);
    if (!v) continue;
    double x;
    if (!json_finite(v, &x) || !(k == 1 ? x >= 0 : x > 0))
      return km__fail(err, KM_ERR_PARSE, "%s: filter.%s: expected a number %s", name, euro_keys[k],
                      k == 1 ? ">= 0" : "> 0");
    /* beta 0 in the file means no speed adaptation: a tiny positive stands for it */
    *euro_dst[k] = (k == 1 && x == 0) ? 1e-12 : x;
  }
  for (int k = 0; k < 5; ++k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(jf, keys[k]);
    if (!v) continue;
    double x;
    bool ok = json_finite(v, &x) && x >= 0 && (k != 0 || x < 1) && (k != 1 || x <= 1);
    if (!ok)
      return km__fail(err, KM_ERR_PARSE, "%s: filter.%s: expected a number in %s", name, keys[k],
                      k == 0   ? "[0,1)"
                      : k == 1 ? "[0,1]"
                               : "[0,inf)");
    /* In the options struct 0 means "default"; an explicit 0 in the file means zero. */
    *dst[k] = (x == 0 && k < 2) ? KM_FILTER_ZERO : x;
  }
  return KM_OK;
}

/* The character's joints ("joints": [{"name": .., "rest": [x, y, z]}, ...], a rig sidecar's
 * skeleton) in the take's joint order; names the take lacks and entries of another shape are
 * skipped (joint_rest stays NaN there). */
static km_status parse_joints(const char *name, const cJSON *jj, const char *const *joint_names,
                              size_t n_joint_names, km_rig *out, km_error *err) {
  if (!jj) return KM_OK;
  if (!cJSON_IsArray(jj)) return KM_OK; /* not a skeleton: ignored like other keys */
  size_t n = out->skeleton == KM_RIG_KINECT1 ? KM_KINECT1_JOINTS : n_joint_names;
  if (n == 0) return KM_OK;
  if (!(out->joint_rest = km__malloc(n, 3 * sizeof(double))))
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  out->n_joint_rest = n;
  for (size_t i = 0; i < 3 * n; ++i)
    out->joint_rest[i] = NAN;
  const cJSON *it;
  size_t i = 0;
  cJSON_ArrayForEach(it, jj) {
    const cJSON *nm = cJSON_GetObjectItemCaseSensitive(it, "name");
    const cJSON *rs = cJSON_GetObjectItemCaseSensitive(it, "rest");
    double x[3];
    bool ok = cJSON_IsString(nm) && cJSON_IsArray(rs) && cJSON_GetArraySize(rs) == 3;
    for (int k = 0; ok && k < 3; ++k)
      ok = json_finite(cJSON_GetArrayItem(rs, k), &x[k]);
    if (!ok) { /* not a skeleton joint (other files use "joints" otherwise): ignored */
      ++i;
      continue;
    }
    int j = -1;
    if (out->skeleton == KM_RIG_KINECT1)
      j = km_kinect1_joint_index(nm->valuestring);
    else
      for (size_t k = 0; k < n_joint_names && j < 0; ++k)
        if (joint_names[k] && !strcmp(joint_names[k], nm->valuestring)) j = (int)k;
    if (j >= 0) memcpy(out->joint_rest + 3 * (size_t)j, x, sizeof x);
    ++i;
  }
  return KM_OK;
}

/* The optional number root[key] in [lo, hi] ([lo, hi) with hi_open) into *out (absent: 0);
 * else KM_ERR_PARSE saying it must be `expected`. */
static km_status parse_number(const char *name, const cJSON *root, const char *key, double lo,
                              double hi, bool hi_open, const char *expected, double *out,
                              km_error *err) {
  const cJSON *j = cJSON_GetObjectItemCaseSensitive(root, key);
  if (j && !(cJSON_IsNumber(j) && j->valuedouble >= lo &&
             (hi_open ? j->valuedouble < hi : j->valuedouble <= hi)))
    return km__fail(err, KM_ERR_PARSE, "%s: \"%s\" must be %s", name, key, expected);
  *out = j ? j->valuedouble : 0;
  return KM_OK;
}

/* An optional number of degrees in [0, 180] (0 when absent). */
static km_status parse_degrees(const char *name, const cJSON *root, const char *key, double *out,
                               km_error *err) {
  return parse_number(name, root, key, 0, 180, false, "a number of degrees in [0, 180]", out, err);
}

km_status km_rig_parse(const char *json, size_t size, const char *name, const km_mesh *mesh,
                       const char *const *joint_names, size_t n_joint_names, km_rig *out,
                       km_error *err) {
  if (!name) name = "rig";
  if (!json || !mesh || !out) return km__fail(err, KM_ERR_INVALID, "%s: NULL argument", name);
  memset(out, 0, sizeof *out);
  if (mesh->n_vertices > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "%s: mesh has too many vertices", name);
  const size_t nv = mesh->n_vertices;
  for (size_t i = 0; i < 3 * mesh->n_faces; ++i)
    if (mesh->F[i] < 0 || (size_t)mesh->F[i] >= nv)
      return km__fail(err, KM_ERR_INVALID, "%s: mesh face %zu has vertex index %d out of range",
                      name, i / 3, (int)mesh->F[i]);

  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(json, size, &end, false);
  if (!root) {
    size_t off = end && end >= json && end <= json + size ? (size_t)(end - json) : 0;
    return km__fail(err, KM_ERR_PARSE, "%s:%zu: invalid JSON (byte %zu)", name, line_of(json, off),
                    off);
  }
  km_status st = KM_OK;
  int32_t *owner = NULL;
  km__geodesic *geo = NULL;
  if (!cJSON_IsObject(root)) {
    st = km__fail(err, KM_ERR_PARSE, "%s: expected a JSON object at the top level", name);
    goto done;
  }
  const cJSON *js = cJSON_GetObjectItemCaseSensitive(root, "skeleton");
  out->skeleton = KM_RIG_KINECT1;
  /* Joint names of a kinect1 rig: the named skeleton's first, then any other's, each resolved
   * to the Kinect v1 joint it stands for (km_skeleton_kinect1_joint). */
  km_skeleton_kind named = KM_SKELETON_KINECT1;
  if (js) {
    int kind = cJSON_IsString(js) ? km_skeleton_kind_from_name(js->valuestring) : -1;
    if (cJSON_IsString(js) && strcmp(js->valuestring, "bvh") == 0) {
      out->skeleton = KM_RIG_BVH;
    } else if (kind >= 0) {
      named = (km_skeleton_kind)kind;
    } else {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: \"skeleton\": expected \"kinect1\", \"kinect2\", \"k4abt\", "
                    "\"humanoid\", \"mediapipe\" or \"bvh\"",
                    name);
      goto done;
    }
  }
  if (out->skeleton == KM_RIG_BVH && (!joint_names || n_joint_names == 0)) {
    st = km__fail(err, KM_ERR_INVALID,
                  "%s: a \"bvh\" rig needs the take's joint names to resolve its map", name);
    goto done;
  }

  const cJSON *jh = cJSON_GetObjectItemCaseSensitive(root, "handles");
  if (!cJSON_IsArray(jh) || cJSON_GetArraySize(jh) == 0) {
    st = km__fail(err, KM_ERR_PARSE, "%s: expected a non-empty \"handles\" array", name);
    goto done;
  }
  size_t nh = (size_t)cJSON_GetArraySize(jh);
  out->handles = km__calloc(nh, sizeof *out->handles);
  owner = km__malloc(nv ? nv : 1, sizeof(int32_t));
  if (!out->handles || !owner) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
    goto done;
  }
  for (size_t v = 0; v < nv; ++v)
    owner[v] = -1;

  const cJSON *h;
  size_t hi = 0;
  cJSON_ArrayForEach(h, jh) {
    km_rig_handle *rh = &out->handles[hi];
    const cJSON *jn = cJSON_GetObjectItemCaseSensitive(h, "name");
    if (!cJSON_IsObject(h) || !cJSON_IsString(jn) || !jn->valuestring[0] ||
        strlen(jn->valuestring) >= sizeof rh->name) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: handles[%zu]: expected an object with a \"name\" (1..63 characters)", name,
                    hi);
      goto done;
    }
    const char *hn = jn->valuestring;
    if (find_handle(out, hn) >= 0) {
      st = km__fail(err, KM_ERR_PARSE, "%s: handle '%s' is defined twice", name, hn);
      goto done;
    }
    snprintf(rh->name, sizeof rh->name, "%s", hn);
    ++out->n_handles; /* counted now so km_rig_free releases its vertices on failure */
    const cJSON *jv = cJSON_GetObjectItemCaseSensitive(h, "vertex");
    const cJSON *jl = cJSON_GetObjectItemCaseSensitive(h, "vertices");
    const cJSON *jc = cJSON_GetObjectItemCaseSensitive(h, "center");
    const cJSON *jr = cJSON_GetObjectItemCaseSensitive(h, "radius");
    if ((jv != NULL) + (jl != NULL) + (jc != NULL) != 1) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: handle '%s': expected exactly one of \"vertex\" (+\"radius\"), "
                    "\"vertices\" or \"center\"+\"radius\"",
                    name, hn);
      goto done;
    }
    double radius = 0;
    if (jr && (!json_finite(jr, &radius) || radius < 0)) {
      st = km__fail(err, KM_ERR_PARSE, "%s: handle '%s': \"radius\" must be a number >= 0", name,
                    hn);
      goto done;
    }
    if (jv) {
      int64_t seed;
      if (!json_int(jv, -1e18, 1e18, &seed)) {
        st =
            km__fail(err, KM_ERR_PARSE, "%s: handle '%s': \"vertex\" must be an integer", name, hn);
        goto done;
      }
      if (seed < 0 || (uint64_t)seed >= nv) {
        st = km__fail(err, KM_ERR_INVALID,
                      "%s: handle '%s': vertex %lld out of range (mesh has %zu vertices)", name, hn,
                      (long long)seed, nv);
        goto done;
      }
      if (radius > 0 && mesh->n_faces > 0) {
        if (!geo && km__geodesic_create(mesh, &geo, NULL) != KM_OK) {
          st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
          goto done;
        }
        if (!geodesic_ball(geo, mesh->V, (int32_t)seed, radius, &rh->vertices, &rh->n_vertices)) {
          st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
          goto done;
        }
      } else {
        /* Point cloud (no edges) or radius 0: Euclidean ball around the seed. */
        const double *c = mesh->V + 3 * (size_t)seed;
        rh->vertices = km__malloc(nv, sizeof(int32_t));
        if (!rh->vertices) {
          st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
          goto done;
        }
        for (size_t v = 0; v < nv; ++v) {
          const double *p = mesh->V + 3 * v;
          double d2 = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                      (p[2] - c[2]) * (p[2] - c[2]);
          if ((int64_t)v == seed || (radius > 0 && d2 <= radius * radius))
            rh->vertices[rh->n_vertices++] = (int32_t)v;
        }
      }
    } else if (jl) {
      size_t n = cJSON_IsArray(jl) ? (size_t)cJSON_GetArraySize(jl) : 0;
      if (!cJSON_IsArray(jl)) {
        st =
            km__fail(err, KM_ERR_PARSE, "%s: handle '%s': \"vertices\" must be an array", name, hn);
        goto done;
      }
      rh->vertices = km__malloc(n ? n : 1, sizeof(int32_t));
      if (!rh->vertices) {
        st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
        goto done;
      }
      const cJSON *e;
      size_t k = 0;
      cJSON_ArrayForEach(e, jl) {
        int64_t v;
        if (!json_int(e, -1e18, 1e18, &v)) {
          st = km__fail(err, KM_ERR_PARSE,
                        "%s: handle '%s': vertices[%zu] must be an integer vertex id", name, hn, k);
          goto done;
        }
        if (v < 0 || (uint64_t)v >= nv) {
          st = km__fail(err, KM_ERR_INVALID,
                        "%s: handle '%s': vertex %lld out of range (mesh has %zu vertices)", name,
                        hn, (long long)v, nv);
          goto done;
        }
        rh->vertices[k++] = (int32_t)v;
      }
      rh->n_vertices = k;
    } else {
      double c[3];
      bool ok = cJSON_IsArray(jc) && cJSON_GetArraySize(jc) == 3;
      for (int k = 0; ok && k < 3; ++k)
        ok = json_finite(cJSON_GetArrayItem(jc, k), &c[k]);
      if (!ok || !jr) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s: handle '%s': expected \"center\": [x, y, z] and a \"radius\"", name, hn);
        goto done;
      }
      rh->vertices = km__malloc(nv ? nv : 1, sizeof(int32_t));
      if (!rh->vertices) {
        st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
        goto done;
      }
      for (size_t v = 0; v < nv; ++v) {
        const double *p = mesh->V + 3 * v;
        double d2 = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                    (p[2] - c[2]) * (p[2] - c[2]);
        if (d2 <= radius * radius) rh->vertices[rh->n_vertices++] = (int32_t)v;
      }
    }
    rh->n_vertices = sort_unique(rh->vertices, rh->n_vertices);
    if (rh->n_vertices == 0) {
      st = km__fail(err, KM_ERR_INVALID, "%s: handle '%s' selects no vertex", name, hn);
      goto done;
    }
    if (rh->n_vertices < nv / 4 + 1) { /* give back the over-allocation of ball scans */
      int32_t *s = realloc(rh->vertices, rh->n_vertices * sizeof(int32_t));
      if (s) rh->vertices = s;
    }
    for (size_t k = 0; k < rh->n_vertices; ++k) {
      int32_t v = rh->vertices[k];
      if (owner[v] >= 0) {
        st = km__fail(err, KM_ERR_INVALID,
                      "%s: handles '%s' and '%s' overlap (vertex %d is in both); a vertex may "
                      "belong to one handle only",
                      name, out->handles[owner[v]].name, hn, (int)v);
        goto done;
      }
      owner[v] = (int32_t)hi;
    }
    ++hi;
  }

  const cJSON *jm = cJSON_GetObjectItemCaseSensitive(root, "map");
  if (jm && !cJSON_IsArray(jm)) {
    st = km__fail(err, KM_ERR_PARSE, "%s: \"map\" must be an array", name);
    goto done;
  }
  size_t nm = jm ? (size_t)cJSON_GetArraySize(jm) : 0;
  out->maps = km__calloc(nm ? nm : 1, sizeof *out->maps);
  if (!out->maps) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
    goto done;
  }
  const cJSON *m;
  size_t mi = 0;
  cJSON_ArrayForEach(m, jm) {
    const cJSON *mh = cJSON_GetObjectItemCaseSensitive(m, "handle");
    const cJSON *mj = cJSON_GetObjectItemCaseSensitive(m, "joint");
    const cJSON *mb = cJSON_GetObjectItemCaseSensitive(m, "bone");
    const cJSON *mb0 = NULL;
    if (mb && !mj) { /* a bone entry: its end joint resolves below as "joint" */
      if (!cJSON_IsArray(mb) || cJSON_GetArraySize(mb) != 2 ||
          !cJSON_IsString(cJSON_GetArrayItem(mb, 0)) ||
          !cJSON_IsString(cJSON_GetArrayItem(mb, 1))) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s: map[%zu]: \"bone\" must be two joint names [start, end], e.g. "
                      "[\"ElbowLeft\", \"WristLeft\"]",
                      name, mi);
        goto done;
      }
      mb0 = cJSON_GetArrayItem(mb, 0);
      mj = cJSON_GetArrayItem(mb, 1);
    }
    if (!cJSON_IsObject(m) || !cJSON_IsString(mh) || !cJSON_IsString(mj) || (mb && mb0 == NULL)) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: map[%zu]: expected an object with a \"handle\" string and a \"joint\" "
                    "string or a \"bone\" [start, end] (not both)",
                    name, mi);
      goto done;
    }
    km_rig_map *rm = &out->maps[mi];
    if (mb0) {
      int b0 = -1;
      if (out->skeleton == KM_RIG_KINECT1) {
        b0 = km_skeleton_kinect1_joint(named, mb0->valuestring); /* any skeleton's name */
        if (b0 < 0) b0 = -1;
      } else
        for (size_t k = 0; k < n_joint_names && b0 < 0; ++k)
          if (joint_names[k] && strcmp(joint_names[k], mb0->valuestring) == 0) b0 = (int)k;
      if (b0 < 0) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s: map[%zu] (handle '%s'): \"bone\": unknown %s joint '%s'", name, mi,
                      mh->valuestring, out->skeleton == KM_RIG_KINECT1 ? "Kinect v1" : "take",
                      mb0->valuestring);
        goto done;
      }
      rm->bone_from = b0 + 1;
    }
    int hidx = find_handle(out, mh->valuestring);
    if (hidx < 0) {
      st = km__fail(err, KM_ERR_PARSE, "%s: map[%zu]: unknown handle '%s'", name, mi,
                    mh->valuestring);
      goto done;
    }
    int jidx = -1;
    if (out->skeleton == KM_RIG_KINECT1) {
      jidx = km_skeleton_kinect1_joint(named, mj->valuestring);
      if (jidx == -2) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s: map[%zu] (handle '%s'): joint '%s' has no Kinect v1 counterpart "
                      "(live input and kinect1 rigs drive the 20 Kinect v1 joints; see "
                      "docs/skeletons.md)",
                      name, mi, mh->valuestring, mj->valuestring);
        goto done;
      }
    } else {
      for (size_t k = 0; k < n_joint_names && jidx < 0; ++k)
        if (joint_names[k] && strcmp(joint_names[k], mj->valuestring) == 0) jidx = (int)k;
    }
    if (jidx < 0) {
      st = km__fail(err, KM_ERR_PARSE, "%s: map[%zu] (handle '%s'): unknown %s joint '%s'%s", name,
                    mi, mh->valuestring, out->skeleton == KM_RIG_KINECT1 ? "Kinect v1" : "take",
                    mj->valuestring,
                    out->skeleton == KM_RIG_KINECT1
                        ? " (expected e.g. Head, HandLeft, FootRight, or another skeleton's "
                          "name such as LeftHand; names are case-sensitive)"
                        : "");
      goto done;
    }
    rm->handle = hidx;
    rm->joint = jidx;
    rm->axes = KM_AXIS_X | KM_AXIS_Y | KM_AXIS_Z;
    const cJSON *ma = cJSON_GetObjectItemCaseSensitive(m, "axes");
    if (ma && (!cJSON_IsString(ma) || parse_axes(ma->valuestring, &rm->axes) != KM_OK)) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: map[%zu] (handle '%s', joint '%s'): bad \"axes\" (expected a non-empty "
                    "combination of x, y, z such as \"xyz\" or \"xz\")",
                    name, mi, mh->valuestring, mj->valuestring);
      goto done;
    }
    const cJSON *mr = cJSON_GetObjectItemCaseSensitive(m, "relative_to");
    if (!mr) mr = cJSON_GetObjectItemCaseSensitive(root, "relative_to");
    if (mr) {
      int ridx = -2;
      if (cJSON_IsString(mr) && !mr->valuestring[0]) {
        ridx = -1;
      } else if (cJSON_IsString(mr) && out->skeleton == KM_RIG_KINECT1) {
        ridx = km_skeleton_kinect1_joint(named, mr->valuestring);
        if (ridx < 0) ridx = -2;
      } else if (cJSON_IsString(mr)) {
        for (size_t k = 0; k < n_joint_names && ridx < 0; ++k)
          if (joint_names[k] && strcmp(joint_names[k], mr->valuestring) == 0) ridx = (int)k;
      }
      if (ridx == -2) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s: map[%zu] (handle '%s', joint '%s'): \"relative_to\" must name a "
                      "%s joint (or be \"\" for absolute motion)",
                      name, mi, mh->valuestring, mj->valuestring,
                      out->skeleton == KM_RIG_KINECT1 ? "Kinect v1" : "take");
        goto done;
      }
      rm->relative_to = ridx + 1;
    }
    const cJSON *mrot = cJSON_GetObjectItemCaseSensitive(m, "rotate");
    if (!mrot) mrot = cJSON_GetObjectItemCaseSensitive(root, "rotate");
    if (mrot && !cJSON_IsBool(mrot)) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: map[%zu] (handle '%s', joint '%s'): \"rotate\" must be true or false",
                    name, mi, mh->valuestring, mj->valuestring);
      goto done;
    }
    rm->rotate = cJSON_IsTrue(mrot);
    rm->scale = 1.0;
    const cJSON *ms = cJSON_GetObjectItemCaseSensitive(m, "scale");
    if (ms && !json_finite(ms, &rm->scale)) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: map[%zu] (handle '%s', joint '%s'): \"scale\" must be a number", name, mi,
                    mh->valuestring, mj->valuestring);
      goto done;
    }
    ++mi;
  }
  out->n_maps = mi;
  {
    const cJSON *jrm = cJSON_GetObjectItemCaseSensitive(root, "root_motion");
    if (jrm && !(cJSON_IsString(jrm) &&
                 (!strcmp(jrm->valuestring, "rigid") || !strcmp(jrm->valuestring, "none")))) {
      st = km__fail(err, KM_ERR_PARSE, "%s: \"root_motion\": expected \"rigid\" or \"none\"", name);
      goto done;
    }
    out->root_rigid = jrm && !strcmp(jrm->valuestring, "rigid");
    const cJSON *jrt = cJSON_GetObjectItemCaseSensitive(root, "relative_to");
    int32_t ids[3] = {0, 0, 0};
    const cJSON *jhd = cJSON_GetObjectItemCaseSensitive(root, "heading");
    const char *want[3] = {cJSON_IsString(jrt) ? jrt->valuestring : NULL, NULL, NULL};
    if (jhd) {
      if (!cJSON_IsArray(jhd) || cJSON_GetArraySize(jhd) != 2 ||
          !cJSON_IsString(cJSON_GetArrayItem(jhd, 0)) ||
          !cJSON_IsString(cJSON_GetArrayItem(jhd, 1))) {
        st = km__fail(err, KM_ERR_PARSE, "%s: \"heading\": expected two joint names [left, right]",
                      name);
        goto done;
      }
      want[1] = cJSON_GetArrayItem(jhd, 0)->valuestring;
      want[2] = cJSON_GetArrayItem(jhd, 1)->valuestring;
    } else if (out->skeleton == KM_RIG_KINECT1) {
      want[1] = "HipLeft";
      want[2] = "HipRight";
    }
    for (int k = 0; k < 3; ++k) {
      if (!want[k] || !want[k][0]) continue;
      int idx = -1;
      if (out->skeleton == KM_RIG_KINECT1)
        idx = km_skeleton_kinect1_joint(named, want[k]);
      else
        for (size_t q = 0; q < n_joint_names && idx < 0; ++q)
          if (joint_names[q] && !strcmp(joint_names[q], want[k])) idx = (int)q;
      if (idx < 0) {
        st = km__fail(err, KM_ERR_PARSE, "%s: %s: unknown %s joint '%s'", name,
                      k ? "\"heading\"" : "\"relative_to\"",
                      out->skeleton == KM_RIG_KINECT1 ? "Kinect v1" : "take", want[k]);
        goto done;
      }
      ids[k] = idx + 1;
    }
    if (out->root_rigid && !ids[0]) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s: \"root_motion\": \"rigid\" needs a rig-level \"relative_to\" naming "
                    "the root joint (e.g. \"HipCenter\")",
                    name);
      goto done;
    }
    out->root = ids[0];
    out->heading[0] = ids[1] && ids[2] ? ids[1] : 0;
    out->heading[1] = ids[1] && ids[2] ? ids[2] : 0;
  }
  const cJSON *jfl = cJSON_GetObjectItemCaseSensitive(root, "floor");
  if (jfl && !cJSON_IsBool(jfl)) {
    st = km__fail(err, KM_ERR_PARSE, "%s: \"floor\" must be true or false", name);
    goto done;
  }
  if ((st = parse_number(name, root, "max_step", 0, 1, true,
                         "a number in [0, 1) (a fraction of the mesh diagonal per frame)",
                         &out->max_step, err)) != KM_OK)
    goto done;
  const cJSON *jaim = cJSON_GetObjectItemCaseSensitive(root, "aim");
  if (jaim && !cJSON_IsBool(jaim)) {
    st = km__fail(err, KM_ERR_PARSE, "%s: \"aim\" must be true or false", name);
    goto done;
  }
  out->aim = cJSON_IsTrue(jaim);
  const cJSON *jlocal = cJSON_GetObjectItemCaseSensitive(root, "local_turn");
  if (jlocal && !cJSON_IsBool(jlocal)) {
    st = km__fail(err, KM_ERR_PARSE, "%s: \"local_turn\" must be true or false", name);
    goto done;
  }
  out->local_turn = cJSON_IsTrue(jlocal);
  if ((st = parse_degrees(name, root, "swing_limit", &out->swing_limit, err)) != KM_OK ||
      (st = parse_degrees(name, root, "upper_limb_limit", &out->upper_limb_limit, err)) != KM_OK ||
      (st = parse_degrees(name, root, "girdle_limit", &out->girdle_limit, err)) != KM_OK ||
      (st = parse_degrees(name, root, "bend_limit", &out->bend_limit, err)) != KM_OK)
    goto done;
  if ((st = parse_number(name, root, "max_turn", 0, 1e5, false,
                         "a number of degrees per second in [0, 100000] (0: the default, 600)",
                         &out->max_turn, err)) != KM_OK)
    goto done;
  if ((st = parse_joints(name, cJSON_GetObjectItemCaseSensitive(root, "joints"), joint_names,
                         n_joint_names, out, err)) != KM_OK)
    goto done;
  out->floor = cJSON_IsTrue(jfl);
  st = parse_filter(name, cJSON_GetObjectItemCaseSensitive(root, "filter"), &out->filter, err);

done:
  cJSON_Delete(root);
  free(owner);
  km__geodesic_free(&geo);
  if (st != KM_OK) km_rig_free(out);
  return st;
}

km_status km_rig_read(const char *path, const km_mesh *mesh, const char *const *joint_names,
                      size_t n_joint_names, km_rig *out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_rig_read: NULL argument");
  memset(out, 0, sizeof *out);
  char *data = NULL;
  size_t size = 0;
  km_status st = km__read_file(path, &data, &size, err);
  if (st != KM_OK) return st;
  st = km_rig_parse(data, size, path, mesh, joint_names, n_joint_names, out, err);
  free(data);
  return st;
}
