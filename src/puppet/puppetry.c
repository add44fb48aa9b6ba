/* The puppetry pipeline (see km_puppetry_create): filter -> retarget -> reduced or full solve,
 * one frame at a time, with the reduced model's cache policy and run-time rig swaps. One
 * object for the file animation, the benchmark and the live server, so the three cannot
 * drift apart. */
#include "puppet/puppet.h"
#include "mesh/mesh.h"

#include "motion/motion.h"
#include "math/math.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct km_puppetry {
  const km_mesh *rest;
  km_puppetry_options opt;
  km_filter_options filter_opt; /* opt.filter's value when given */
  char *take_name;
  char **names;        /* create-time columns (NULL: already in the rig's order) */
  int32_t *parents_in; /* n_in create-time parents (NULL: unknown) */
  size_t n_in;         /* joints per pushed frame */

  km_puppet *puppet; /* reduced solver */
  bool own_puppet;
  km_arap *arap; /* full solver (per handle set) */
  double arap_seconds;

  /* the current rig; filter == NULL: none */
  size_t nj;    /* joints in the rig's order */
  int32_t *col; /* nj source columns (-1: absent) or NULL for the identity */
  km_filter *filter;
  km_glitch *glitch; /* NULL: off */
  int32_t *par;      /* nj parents in the rig's joint order (-1: root); NULL: unknown */
  km_retarget *rt;
  size_t n_handles;
  int32_t *off, *hv;
  double *handle_targets, *targets;
  double *filt, *p0, *last; /* nj*3 each */
  /* issue 15: joint rotations in the rig's order, max(n_in, 20)*9 each: the pushed frame's
   * (scratch), the first valid one per joint (the retarget's reference, carried over a rig
   * swap like p0) and the newest frame's (NaN: none) */
  double *rot, *rot0, *rotl;
  /* the vertices of loose pieces lying on the floor (km__ground_vertices: a ground plane or a
   * plinth exported with the character), kept at rest: carried rigidly with the foot nearest
   * to it, a ground quad under armadillo_1k tilted with every step and, pushed under the floor
   * by the tilt, folded into a tent */
  int32_t *ground;
  size_t n_ground;
  bool have_last;
  km_puppetry_times times;
};

static const char *take_name(const km_puppetry *p) {
  return p->take_name ? p->take_name : "the take";
}

/* The rig's joint order from the pushed columns: *col (NULL for the identity) and *nj. A
 * kinect1 rig's map indexes Kinect v1 joints; a joint it maps must be in the take: a BVH with
 * a "Spine" and a "Head" but no "HandLeft" would otherwise animate nothing, silently. */
static km_status rig_columns(const km_puppetry *p, const km_rig *rig, int32_t **col, size_t *nj,
                             km_error *err) {
  *col = NULL;
  *nj = p->n_in;
  if (rig->skeleton != KM_RIG_KINECT1 || !p->names) return KM_OK;
  *nj = KM_KINECT1_JOINTS;
  int src[KM_KINECT1_JOINTS];
  km__kinect1_columns((const char *const *)p->names, p->n_in, src);
  char missing[512] = "";
  size_t n_missing = 0;
  for (size_t m = 0; m < rig->n_maps; ++m) {
    int j = rig->maps[m].joint;
    if (j < 0 || j >= KM_KINECT1_JOINTS || src[j] >= 0 || strstr(missing, km_kinect1_joint_name(j)))
      continue;
    size_t len = strlen(missing);
    snprintf(missing + len, sizeof missing - len, "%s%s", n_missing ? ", " : "",
             km_kinect1_joint_name(j));
    ++n_missing;
  }
  if (n_missing) {
    char have[512] = "";
    for (size_t k = 0; k < p->n_in && k < 12; ++k) {
      size_t len = strlen(have);
      snprintf(have + len, sizeof have - len, "%s%s", k ? ", " : "", p->names[k]);
    }
    return km__fail(err, KM_ERR_INVALID,
                    "%s has no joint named %s, which the kinect1 rig maps (its joints: "
                    "%s%s); use a \"bvh\" rig that names this motion's joints",
                    take_name(p), missing, have, p->n_in > 12 ? ", ..." : "");
  }
  bool same = p->n_in == KM_KINECT1_JOINTS;
  for (int j = 0; same && j < KM_KINECT1_JOINTS; ++j)
    same = src[j] == j;
  if (same) return KM_OK;
  *col = km__malloc(KM_KINECT1_JOINTS, sizeof(int32_t));
  if (!*col) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    (*col)[j] = src[j];
  return KM_OK;
}

/* Everything a rig owns, built aside and swapped in by install_rig. */
typedef struct rig_state {
  size_t nj, n_handles;
  int32_t *col, *off, *hv;
  km_filter *filter;
  km_retarget *rt;
  km_arap *arap;
  double *handle_targets, *targets, *filt, *p0, *last;
  km_glitch *glitch;
  int32_t *par;
} rig_state;

static void rig_state_free(rig_state *r) {
  free(r->col);
  free(r->off);
  free(r->hv);
  km_filter_free(&r->filter);
  km_glitch_free(&r->glitch);
  free(r->par);
  km_retarget_free(&r->rt);
  km_arap_free(&r->arap);
  free(r->handle_targets);
  free(r->targets);
  free(r->filt);
  free(r->p0);
  free(r->last);
  memset(r, 0, sizeof *r);
}

static km_status install_rig(km_puppetry *p, const km_rig *rig, km_error *err) {
  rig_state r = {0};
  km_status s = rig_columns(p, rig, &r.col, &r.nj, err);
  if (s != KM_OK) return s;
  if (rig->n_handles == 0) {
    free(r.col);
    return km__fail(err, KM_ERR_INVALID, "the rig has no handles");
  }
  r.n_handles = rig->n_handles;
  size_t n_hv = 0;
  for (size_t h = 0; h < rig->n_handles; ++h)
    n_hv += rig->handles[h].n_vertices;
  r.off = km__malloc(rig->n_handles + 1, sizeof(int32_t));
  r.hv = km__malloc(n_hv ? n_hv : 1, sizeof(int32_t));
  r.handle_targets = km__malloc(3 * rig->n_handles, sizeof(double));
  r.targets = km__malloc(3 * (n_hv ? n_hv : 1), sizeof(double));
  r.filt = km__malloc(3 * (r.nj ? r.nj : 1), sizeof(double));
  r.p0 = km__malloc(3 * (r.nj ? r.nj : 1), sizeof(double));
  r.last = km__malloc(3 * (r.nj ? r.nj : 1), sizeof(double));
  if (!r.off || !r.hv || !r.handle_targets || !r.targets || !r.filt || !r.p0 || !r.last) {
    rig_state_free(&r);
    return km__fail(err, KM_ERR_NOMEM, "out of memory for the rig");
  }
  r.off[0] = 0;
  for (size_t h = 0, k = 0; h < rig->n_handles; ++h) {
    for (size_t i = 0; i < rig->handles[h].n_vertices; ++i)
      r.hv[k++] = rig->handles[h].vertices[i];
    r.off[h + 1] = (int32_t)k;
  }
  km_filter_options fo = p->opt.filter ? p->filter_opt : rig->filter;
  double fps = p->opt.fps > 0 ? p->opt.fps : 30.0;
  if (fo.fps == 0) fo.fps = fps;
  /* Bones in the rig's joint order: the Kinect v1 tree, or the take's own. */
  bool kinect_tree = rig->skeleton == KM_RIG_KINECT1 && r.nj == KM_KINECT1_JOINTS;
  if (kinect_tree || (!r.col && p->parents_in)) {
    if (!(r.par = km__malloc(r.nj ? r.nj : 1, sizeof(int32_t)))) {
      rig_state_free(&r);
      return km__fail(err, KM_ERR_NOMEM, "out of memory for the rig");
    }
    for (size_t j = 0; j < r.nj; ++j)
      r.par[j] = kinect_tree ? km_kinect1_joint_parent((int)j) : p->parents_in[j];
  }
  if (!p->opt.no_glitch) {
    km_glitch_options go = p->opt.glitch;
    if (go.fps == 0) go.fps = fps;
    if ((s = km_glitch_create(r.nj, r.par, &go, &r.glitch, err)) != KM_OK) {
      rig_state_free(&r);
      return s;
    }
  }
  km_retarget_options ro = p->opt.retarget; /* rotating handles: bones in the rig's order */
  if (ro.fps == 0) ro.fps = fps;
  if (!ro.parents && rig->skeleton != KM_RIG_KINECT1 && !r.col) ro.parents = p->parents_in;
  if ((s = km_filter_create(r.nj, &fo, &r.filter, err)) != KM_OK ||
      (s = km_retarget_create(rig, p->rest, r.nj, &ro, &r.rt, err)) != KM_OK) {
    rig_state_free(&r);
    return s;
  }
  if (p->opt.solver == KM_PUPPETRY_FULL) {
    double t0 = km_seconds();
    s = km_arap_precompute(p->rest, rig->n_handles, r.off, r.hv, &p->opt.arap, &r.arap, err);
    p->arap_seconds = km_seconds() - t0;
  } else if (p->opt.solver != KM_PUPPETRY_RETARGET) {
    s = km_puppet_set_handles(p->puppet, rig->n_handles, r.off, r.hv, err);
    if (s != KM_OK && p->filter) { /* the puppet may hold a half-set handle set */
      km_error e2 = {0};
      km_puppet_set_handles(p->puppet, p->n_handles, p->off, p->hv, &e2);
    }
  }
  if (s != KM_OK) {
    rig_state_free(&r);
    return s;
  }
  /* The reference pose and newest frame carry over when the joint layout does. */
  bool keep = p->filter && p->nj == r.nj;
  bool seeded = false;
  for (size_t k = 0; k < 3 * r.nj; ++k) {
    r.p0[k] = keep ? p->p0[k] : NAN;
    seeded |= !isnan(r.p0[k]);
  }
  bool have_last = keep && p->have_last;
  if (have_last) memcpy(r.last, p->last, sizeof(double) * 3 * r.nj);
  if (!keep)
    for (size_t k = 0; k < 9 * r.nj; ++k)
      p->rot0[k] = p->rotl[k] = NAN;
  /* the rotations' reference and newest frame carry over with the positions' */
  if (seeded) km_retarget_push_rotations(r.rt, r.p0, p->rot0, NULL);
  if (have_last) {
    km_filter_push(r.filter, r.last, r.filt);
    km__retarget_settle(r.rt);
    km_retarget_push_rotations(r.rt, r.filt, p->rotl, r.handle_targets);
  } else {
    for (size_t k = 0; k < 3 * r.nj; ++k)
      r.filt[k] = NAN;
    memcpy(r.handle_targets, km_retarget_rest_centroids(r.rt), sizeof(double) * 3 * rig->n_handles);
  }
  km_retarget_vertex_targets(r.rt, r.targets);

  rig_state old = {p->nj, p->n_handles,      p->col,     p->off,  p->hv, p->filter, p->rt,
                   NULL,  p->handle_targets, p->targets, p->filt, p->p0, p->last,   p->glitch,
                   p->par};
  if (r.arap) {
    old.arap = p->arap;
    p->arap = r.arap;
    r.arap = NULL;
  }
  p->nj = r.nj;
  p->n_handles = r.n_handles;
  p->col = r.col;
  p->off = r.off;
  p->hv = r.hv;
  p->filter = r.filter;
  p->glitch = r.glitch;
  p->par = r.par;
  p->rt = r.rt;
  p->handle_targets = r.handle_targets;
  p->targets = r.targets;
  p->filt = r.filt;
  p->p0 = r.p0;
  p->last = r.last;
  p->have_last = have_last;
  rig_state_free(&old);
  return KM_OK;
}

km_status km_puppetry_model_open(const km_mesh *rest, const km_puppetry_options *opt,
                                 km_puppet **out, km_puppetry_info *info, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_puppetry_model_open: NULL argument");
  *out = NULL;
  if (!rest || !opt) return km__fail(err, KM_ERR_INVALID, "km_puppetry_model_open: NULL argument");
  km_puppetry_info local;
  if (!info) info = &local;
  memset(info, 0, sizeof *info);
  const char *cache = opt->cache_path;
  km_puppet_options po = opt->puppet;
  km_error cerr = {0};
  km_status s;
  if (cache && opt->cache_parameters && km_puppet_cache_options(cache, &po, &cerr) == KM_OK) {
    /* The header's parameters are adopted only from a cache that loads: checksum, mesh hash
     * and sizes verified. A forged or foreign header (a 128-byte file asking for the largest
     * model) falls back to the caller's parameters and the cache is rebuilt with them. */
    km_error lerr = {0};
    double t0 = km_seconds();
    s = opt->force ? KM_ERR_STALE : km_puppet_load(cache, rest, &po, out, &lerr);
    if (s == KM_OK) {
      info->cache_parameters = true;
      info->puppet = po;
      info->puppet.progress = (km_progress){0};
      info->model = KM_PUPPETRY_MODEL_LOADED;
      info->model_seconds = km_seconds() - t0;
      return KM_OK;
    }
    po = opt->puppet;
  }
  info->puppet = po;
  info->puppet.progress = (km_progress){0};
  if (cache && !opt->force) {
    km_error lerr = {0};
    double t0 = km_seconds();
    s = km_puppet_load(cache, rest, &po, out, &lerr);
    if (s == KM_OK) {
      info->model = KM_PUPPETRY_MODEL_LOADED;
      info->model_seconds = km_seconds() - t0;
      return KM_OK;
    }
    if (s == KM_ERR_STALE) {
      info->model = KM_PUPPETRY_MODEL_REBUILT_STALE;
      info->stale = lerr;
    } else if (s != KM_ERR_IO) {
      if (err) *err = lerr;
      return s;
    }
  } else if (cache) {
    info->model = KM_PUPPETRY_MODEL_REBUILT_FORCED;
  }
  double t0 = km_seconds();
  s = km_puppet_precompute(rest, &po, out, err);
  info->model_seconds = km_seconds() - t0;
  if (s != KM_OK) return s;
  if (cache) km_puppet_save(*out, cache, &info->save);
  return KM_OK;
}

km_status km_puppetry_create(const km_mesh *rest, const km_rig *rig, const char *const *joint_names,
                             size_t n_joints, const km_puppetry_options *opt, km_puppetry **out,
                             km_puppetry_info *info, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_puppetry_create: NULL argument");
  *out = NULL;
  if (!rest) return km__fail(err, KM_ERR_INVALID, "km_puppetry_create: NULL argument");
  km_puppetry_info local;
  if (!info) info = &local;
  memset(info, 0, sizeof *info);
  km_puppetry *p = km__calloc(1, sizeof *p);
  if (!p) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  if (opt) p->opt = *opt;
  p->rest = rest;
  p->n_in = n_joints;
  km_status s = KM_OK;
  if (rest->n_faces) {
    size_t n_gp = 0;
    bool *g = km__malloc(rest->n_vertices ? rest->n_vertices : 1, sizeof *g);
    if (!g) goto nomem;
    if ((s = km__ground_vertices(rest, g, &n_gp, err)) != KM_OK) {
      free(g);
      km_puppetry_free(&p);
      return s;
    }
    for (size_t v = 0; v < rest->n_vertices; ++v)
      p->n_ground += g[v];
    if (p->n_ground && !(p->ground = km__malloc(p->n_ground, sizeof *p->ground))) {
      free(g);
      goto nomem;
    }
    for (size_t v = 0, k = 0; v < rest->n_vertices; ++v)
      if (g[v]) p->ground[k++] = (int32_t)v;
    free(g);
  }
  /* a rig's joints are the pushed columns or the 20 Kinect v1 joints (rig_columns) */
  size_t nrot = 9 * (n_joints > KM_KINECT1_JOINTS ? n_joints : KM_KINECT1_JOINTS);
  if (!(p->rot = km__malloc(nrot, sizeof(double))) ||
      !(p->rot0 = km__malloc(nrot, sizeof(double))) ||
      !(p->rotl = km__malloc(nrot, sizeof(double))))
    goto nomem;
  for (size_t k = 0; k < nrot; ++k)
    p->rot0[k] = p->rotl[k] = NAN;
  if (p->opt.filter) {
    p->filter_opt = *p->opt.filter;
    p->opt.filter = &p->filter_opt;
  }
  /* Pointers the caller keeps need not outlive this call. */
  p->opt.cache_path = NULL;
  p->opt.take_name = NULL;
  if (opt && opt->take_name && !(p->take_name = km__strdup(opt->take_name))) goto nomem;
  p->opt.joint_parents = NULL;
  p->opt.retarget.parents = NULL; /* the pipeline's bones come from joint_parents */
  if (opt && opt->joint_parents) {
    if (!(p->parents_in = km__malloc(n_joints ? n_joints : 1, sizeof(int32_t)))) goto nomem;
    memcpy(p->parents_in, opt->joint_parents, n_joints * sizeof(int32_t));
  }
  if (joint_names) {
    p->names = km__calloc(n_joints ? n_joints : 1, sizeof(char *));
    if (!p->names) goto nomem;
    for (size_t k = 0; k < n_joints; ++k)
      if (!(p->names[k] = km__strdup(joint_names[k] ? joint_names[k] : ""))) goto nomem;
  }
  if (rig) { /* fail on the rig before the costly model */
    int32_t *col = NULL;
    size_t nj;
    s = rig_columns(p, rig, &col, &nj, err);
    free(col);
    if (s != KM_OK) goto fail;
    if (rig->n_handles == 0) {
      s = km__fail(err, KM_ERR_INVALID, "the rig has no handles");
      goto fail;
    }
  }
  if (p->opt.solver == KM_PUPPETRY_RETARGET) {
    if (!rig) {
      s = km__fail(err, KM_ERR_INVALID, "a retarget-only pipeline needs a rig at creation");
      goto fail;
    }
  } else if (p->opt.solver == KM_PUPPETRY_FULL) {
    if (!rig) {
      s = km__fail(err, KM_ERR_INVALID, "the full solver needs a rig at creation");
      goto fail;
    }
    info->model = KM_PUPPETRY_MODEL_FULL;
  } else if (p->opt.model) {
    /* A given model may come from an earlier puppetry, holding that one's last solve (its
     * rotations and warm start): a new one starts from the rest pose. Without this, bench
     * motion's B, which reuses T's model, started from T's last frame, and its first steps
     * were that solve relaxing (cat-03 on cmu_131_03: 3.66 % of the diagonal at frame 1 when T
     * had run 150 frames, 0.13 % after 100). */
    p->puppet = p->opt.model;
    km_puppet_reset(p->puppet);
    info->model = KM_PUPPETRY_MODEL_GIVEN;
  } else {
    p->opt.cache_path = opt ? opt->cache_path : NULL; /* for this call only */
    s = km_puppetry_model_open(rest, &p->opt, &p->puppet, info, err);
    p->opt.cache_path = NULL;
    if (s != KM_OK) goto fail;
    p->own_puppet = true;
  }
  p->opt.model = NULL;
  if (rig && (s = install_rig(p, rig, err)) != KM_OK) goto fail;
  if (p->opt.solver == KM_PUPPETRY_FULL) info->model_seconds = p->arap_seconds;
  *out = p;
  return KM_OK;
nomem:
  s = km__fail(err, KM_ERR_NOMEM, "out of memory");
fail:
  km_puppetry_free(&p);
  return s;
}

km_status km_puppetry_set_rig(km_puppetry *p, const km_rig *rig, km_error *err) {
  if (!p || !rig) return km__fail(err, KM_ERR_INVALID, "km_puppetry_set_rig: NULL argument");
  return install_rig(p, rig, err);
}

km_status km_puppetry_push(km_puppetry *p, const double *joints, double *V_out, km_error *err) {
  return km_puppetry_push_at(p, joints, NAN, V_out, err);
}

km_status km_puppetry_push_at(km_puppetry *p, const double *joints, double t, double *V_out,
                              km_error *err) {
  return km_puppetry_push_rotations(p, joints, NULL, t, V_out, err);
}

/* Joints whose start the glitch rejector found wrong (km_glitch_restarted): the reference the
 * motion is measured from was that start, so a hand placed 0.6 m off in the first frame held
 * the mesh's hand 0.6 m off for the whole take (precog_Seq1_1 on the character: up to 11 % of
 * the diagonal over 185 of 232 frames). The joint's reference is redone as where it is now less
 * the motion since their references of its neighbours (parent and children) that kept theirs,
 * else of every such joint. */
static void restart_references(km_puppetry *p, const bool *re) {
  const double *ref = km_retarget_reference(p->rt), *x = p->filt;
  for (size_t j = 0; j < p->nj; ++j) {
    if (!re[j] || !km__finite3(x + 3 * j)) continue;
    double d[3] = {0, 0, 0};
    int n = 0;
    for (int pass = 0; pass < 2 && n == 0; ++pass)
      for (size_t q = 0; q < p->nj; ++q) {
        bool near = p->par && (p->par[j] == (int32_t)q || p->par[q] == (int32_t)j);
        /* a joint restarted in this push counts once its own reference is redone (q < j) */
        if (q == j || (re[q] && q > j) || (pass == 0 && !near) || !km__finite3(x + 3 * q) ||
            !km__finite3(ref + 3 * q))
          continue;
        for (int c = 0; c < 3; ++c)
          d[c] += x[3 * q + c] - ref[3 * q + c];
        ++n;
      }
    if (n == 0) continue;
    double r0[3];
    for (int c = 0; c < 3; ++c)
      r0[c] = x[3 * j + c] - d[c] / n;
    km_retarget_set_reference(p->rt, j, r0);
    memcpy(p->p0 + 3 * j, r0, sizeof r0);
  }
}

km_status km_puppetry_push_rotations(km_puppetry *p, const double *joints, const double *rotations,
                                     double t, double *V_out, km_error *err) {
  if (!p->filter) return km__fail(err, KM_ERR_INVALID, "km_puppetry_push: no rig set");
  double t0 = km_seconds();
  if (p->col) {
    for (size_t j = 0; j < p->nj; ++j)
      for (int a = 0; a < 3; ++a)
        p->last[3 * j + a] = p->col[j] < 0 ? NAN : joints[3 * (size_t)p->col[j] + a];
  } else {
    memcpy(p->last, joints, sizeof(double) * 3 * p->nj);
  }
  p->have_last = true;
  if (p->glitch) {
    km_glitch_push_at(p->glitch, p->last, t, p->filt); /* filt as scratch: the filter may alias */
    const bool *re = km_glitch_restarted(p->glitch);
    for (size_t j = 0; re && j < p->nj; ++j)
      if (re[j]) km_filter_restart_joint(p->filter, j);
    km_filter_push(p->filter, p->filt, p->filt);
    if (re) restart_references(p, re);
  } else {
    km_filter_push(p->filter, p->last, p->filt);
  }
  for (size_t k = 0; k < 3 * p->nj; ++k)
    if (isnan(p->p0[k]) && !isnan(p->filt[k])) p->p0[k] = p->filt[k];
  double t1 = km_seconds();
  const double *rot = rotations;
  if (rotations && p->col) {
    for (size_t j = 0; j < p->nj; ++j)
      for (int a = 0; a < 9; ++a)
        p->rot[9 * j + a] = p->col[j] < 0 ? NAN : rotations[9 * (size_t)p->col[j] + a];
    rot = p->rot;
  }
  for (size_t k = 0; k < 9 * p->nj; ++k)
    p->rotl[k] = rot ? rot[k] : NAN;
  for (size_t j = 0; rot && j < p->nj; ++j)
    if (isnan(p->rot0[9 * j]) && isfinite(rot[9 * j]))
      memcpy(p->rot0 + 9 * j, rot + 9 * j, 9 * sizeof(double));
  km_retarget_push_rotations(p->rt, p->filt, rot, p->handle_targets);
  km_retarget_vertex_targets(p->rt, p->targets);
  double t2 = km_seconds();
  if (p->opt.solver == KM_PUPPETRY_RETARGET) { /* the caller skins the posed joints */
    km_retarget_apply_root(p->rt, p->handle_targets, p->n_handles);
    p->times.filter_ms = 1e3 * (t1 - t0);
    p->times.retarget_ms = 1e3 * (t2 - t1);
    p->times.solve_ms = 0;
    return KM_OK;
  }
  km_status s = p->opt.solver == KM_PUPPETRY_FULL
                    ? km_arap_solve(p->arap, p->targets, V_out, err)
                    : km_puppet_solve(p->puppet, p->targets, V_out, err);
  if (s == KM_OK) {
    /* rigid root motion: the deformed mesh (root-relative) follows the root as a whole, and the
     * handle targets with it (km_puppetry_handle_targets is where the handles go) */
    km_retarget_apply_root(p->rt, V_out, p->rest->n_vertices);
    km_retarget_apply_root(p->rt, p->handle_targets, p->n_handles);
    /* The floor: the handles were raised above it before the solve, but free skin next to a
     * handle (a toe outside a small foot handle, a knee, a soft handle's give) can still sink:
     * armadillo_1k's toe went 3 cm under it on cmu_131_01. Held on the floor, like skin
     * pressed on the ground; a per-vertex clamp, continuous in the solve's result. */
    double fy;
    if (km_retarget_floor(p->rt, &fy))
      for (size_t v = 0; v < p->rest->n_vertices; ++v)
        if (V_out[3 * v + 1] < fy) V_out[3 * v + 1] = fy;
    for (size_t k = 0; k < p->n_ground; ++k) /* the ground stays */
      memcpy(V_out + 3 * (size_t)p->ground[k], p->rest->V + 3 * (size_t)p->ground[k],
             3 * sizeof(double));
  }
  double t3 = km_seconds();
  p->times.filter_ms = 1e3 * (t1 - t0);
  p->times.retarget_ms = 1e3 * (t2 - t1);
  p->times.solve_ms = 1e3 * (t3 - t2);
  return s;
}

void km_puppetry_reset(km_puppetry *p) {
  if (!p) return;
  if (p->filter) {
    km_filter_reset(p->filter);
    km_glitch_reset(p->glitch);
    km_retarget_reset(p->rt);
    for (size_t k = 0; k < 3 * p->nj; ++k)
      p->p0[k] = NAN;
    for (size_t k = 0; k < 9 * p->nj; ++k)
      p->rot0[k] = p->rotl[k] = NAN;
  }
  p->have_last = false;
  if (p->puppet) km_puppet_reset(p->puppet);
}

void km_puppetry_times_get(const km_puppetry *p, km_puppetry_times *out) { *out = p->times; }

double km_puppetry_scale(const km_puppetry *p) { return p->rt ? km_retarget_scale(p->rt) : NAN; }

void km_puppetry_handles(const km_puppetry *p, size_t *n_handles, const int32_t **offsets,
                         const int32_t **vertices) {
  if (n_handles) *n_handles = p->n_handles;
  if (offsets) *offsets = p->off;
  if (vertices) *vertices = p->hv;
}

const double *km_puppetry_handle_targets(const km_puppetry *p) { return p->handle_targets; }
const double *km_puppetry_vertex_targets(const km_puppetry *p) { return p->targets; }
const double *km_puppetry_rest_centroids(const km_puppetry *p) {
  return p->rt ? km_retarget_rest_centroids(p->rt) : NULL;
}
const double *km_puppetry_filtered_joints(const km_puppetry *p) { return p->filt; }
const double *km_puppetry_reference_joints(const km_puppetry *p) { return p->p0; }
const double *km_puppetry_last_joints(const km_puppetry *p) {
  return p->have_last ? p->last : NULL;
}

void km_puppetry_glitch_stats(const km_puppetry *p, km_glitch_stats *out) {
  if (p->glitch)
    km_glitch_stats_get(p->glitch, out);
  else
    memset(out, 0, sizeof *out);
}

bool km_puppetry_floor(const km_puppetry *p, double *floor_y) {
  return p && p->rt && floor_y && km_retarget_floor(p->rt, floor_y);
}

bool km_puppetry_posed_joints(const km_puppetry *p, double *out) {
  return p && p->rt && out && km_retarget_joints(p->rt, out);
}

size_t km_puppetry_eased_frames(const km_puppetry *p) {
  return p->rt ? km_retarget_eased_frames(p->rt) : 0;
}

km_puppet *km_puppetry_model(const km_puppetry *p) { return p->puppet; }

void km_puppetry_puppet_info(const km_puppetry *p, km_puppet_info *out) {
  if (p->puppet)
    km_puppet_info_get(p->puppet, out);
  else
    memset(out, 0, sizeof *out);
}

void km_puppetry_free(km_puppetry **pp) {
  if (!pp || !*pp) return;
  km_puppetry *p = *pp;
  rig_state r = {p->nj,   p->n_handles,      p->col,     p->off,  p->hv, p->filter, p->rt,
                 p->arap, p->handle_targets, p->targets, p->filt, p->p0, p->last,   p->glitch,
                 p->par};
  rig_state_free(&r);
  if (p->own_puppet) km_puppet_free(&p->puppet);
  if (p->names)
    for (size_t k = 0; k < p->n_in; ++k)
      free(p->names[k]);
  free(p->names);
  free(p->parents_in);
  free(p->take_name);
  free(p->rot);
  free(p->rot0);
  free(p->rotl);
  free(p->ground);
  free(p);
  *pp = NULL;
}
