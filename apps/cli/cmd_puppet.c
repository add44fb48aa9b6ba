/* Puppetry verbs: precompute (the cached reduced model), animate (skeleton take -> mesh
 * animation) and bench deform (the paper's Table 1). */
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ------------------------------------------------------------------ shared pieces */

int km_cli_parse_energy(const char *verb, const char *s, km_puppet_energy *e) {
  if (!s || !strcmp(s, "arap"))
    *e = KM_PUPPET_ENERGY_ARAP;
  else if (!strcmp(s, "laplacian"))
    *e = KM_PUPPET_ENERGY_LAPLACIAN;
  else
    return km_cli_error(verb, "--energy must be laplacian or arap, not '%s'", s);
  return 0;
}

int km_cli_parse_frame_format(const char *verb, const char *s, km_anim_format *f) {
  if (!s)
    *f = KM_ANIM_AUTO;
  else if (!strcmp(s, "obj"))
    *f = KM_ANIM_OBJ_DIR;
  else if (!strcmp(s, "ply"))
    *f = KM_ANIM_PLY_DIR;
  else
    return km_cli_error(verb, "--frame-format must be obj or ply, not '%s'", s);
  return 0;
}

static int parse_solver(const char *verb, const char *s, bool *full) {
  if (!s || !strcmp(s, "reduced"))
    *full = false;
  else if (!strcmp(s, "full"))
    *full = true;
  else
    return km_cli_error(verb, "--solver must be reduced or full, not '%s'", s);
  return 0;
}

char *km_cli_cache_path(const char *mesh_path) {
  size_t n = strlen(mesh_path);
  char *out = malloc(n + 10);
  if (out) snprintf(out, n + 10, "%s.kmcache", mesh_path);
  return out;
}

/* Loads the reduced model from `cache` when it matches the mesh and options, otherwise
 * precomputes it and writes the cache. *loaded tells which happened. */
km_status km_cli_puppet_open(const km_mesh *mesh, const km_puppet_options *po, const char *cache,
                             bool verbose, km_puppet **out, bool *loaded, double *seconds,
                             km_error *err) {
  double t0 = km_cli_now();
  *loaded = false;
  km_error lerr = {0};
  km_status s = km_puppet_load(cache, mesh, po, out, &lerr);
  if (s == KM_OK) {
    *loaded = true;
    *seconds = km_cli_now() - t0;
    return KM_OK;
  }
  if (s == KM_ERR_STALE)
    fprintf(stderr, "kinemesh: cache %s not usable (%s); rebuilding it\n", cache, lerr.message);
  else if (s != KM_ERR_IO) {
    *err = lerr;
    return s;
  }
  km_puppet_options o = *po;
  if (verbose) o.progress = km_cli_progress("precompute");
  t0 = km_cli_now();
  s = km_puppet_precompute(mesh, &o, out, err);
  *seconds = km_cli_now() - t0;
  km_cli_progress_done();
  if (s != KM_OK) return s;
  km_error serr = {0};
  if (km_puppet_save(*out, cache, &serr) != KM_OK)
    fprintf(stderr, "kinemesh: warning: could not write the cache: %s\n", serr.message);
  return KM_OK;
}

/* Reads a motion file by extension: .json (kinemesh take), .csv (Kinect v1 skeleton
 * recording), .bvh. */
km_status km_cli_read_motion(const char *path, km_take *t, km_error *err) {
  size_t n = strlen(path);
  if (n > 4 && !strcasecmp(path + n - 4, ".csv")) return km_kinect_csv_read(path, t, NULL, err);
  if (n > 4 && !strcasecmp(path + n - 4, ".bvh")) return km_bvh_read(path, NULL, t, NULL, err);
  return km_take_read(path, t, err);
}

/* Column of each Kinect v1 joint in take t (by name), -1 when absent; returns how many. */
static int kinect1_columns(const km_take *t, int src[KM_KINECT1_JOINTS]) {
  int found = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    src[j] = -1;
    for (size_t k = 0; k < t->n_joints; ++k)
      if (!strcmp(t->joint_names[k], km_kinect1_joint_name(j))) src[j] = (int)k;
    found += src[j] >= 0;
  }
  return found;
}

/* out: t's columns src[] as a take of the 20 Kinect v1 joints (names, parents; absent joints
 * NaN). */
static km_status kinect1_take(const km_take *t, const int src[KM_KINECT1_JOINTS], km_take *out,
                              km_error *err) {
  memset(out, 0, sizeof *out);
  out->n_frames = t->n_frames;
  out->n_joints = KM_KINECT1_JOINTS;
  out->fps = t->fps;
  out->positions = malloc(sizeof(double) * 3 * KM_KINECT1_JOINTS * (t->n_frames ? t->n_frames : 1));
  out->joint_names = calloc(KM_KINECT1_JOINTS, sizeof *out->joint_names);
  out->parents = malloc(sizeof(int32_t) * KM_KINECT1_JOINTS);
  bool ok = out->positions && out->joint_names && out->parents;
  for (int j = 0; ok && j < KM_KINECT1_JOINTS; ++j) {
    ok = (out->joint_names[j] = strdup(km_kinect1_joint_name(j))) != NULL;
    out->parents[j] = km_kinect1_joint_parent(j);
  }
  if (!ok) {
    km_take_free(out);
    return km_cli_set_error(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t f = 0; f < t->n_frames; ++f)
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      for (int a = 0; a < 3; ++a)
        out->positions[(f * KM_KINECT1_JOINTS + (size_t)j) * 3 + a] =
            src[j] < 0 ? NAN : t->positions[(f * t->n_joints + (size_t)src[j]) * 3 + a];
  return KM_OK;
}

km_status km_cli_take_kinect1(const char *path, const km_take *t, km_take *out, km_error *err) {
  int src[KM_KINECT1_JOINTS];
  memset(out, 0, sizeof *out);
  if (!kinect1_columns(t, src) || !t->n_frames)
    return km_cli_set_error(err, KM_ERR_INVALID,
                            "%s: the take has no frames or none of the 20 Kinect v1 joints "
                            "(HipCenter, HandLeft, ...)",
                            path);
  km_status s = kinect1_take(t, src, out, err);
  if (s == KM_OK && !(out->fps > 0)) out->fps = 30;
  return s;
}

/* For a kinect1 rig the map's joint indices are Kinect v1 indices: reorders a take's columns
 * into that order by name (joints the rig does not map may be absent: they become NaN). A
 * joint the rig maps must be in the take: a BVH with a "Spine" and a "Head" but no "HandLeft"
 * would otherwise animate nothing, silently. */
static km_status take_to_kinect_order(km_take *t, const km_rig *rig, const char *motion,
                                      km_error *err) {
  int src[KM_KINECT1_JOINTS];
  kinect1_columns(t, src);
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
    for (size_t k = 0; k < t->n_joints && k < 12; ++k) {
      size_t len = strlen(have);
      snprintf(have + len, sizeof have - len, "%s%s", k ? ", " : "", t->joint_names[k]);
    }
    return km_cli_set_error(err, KM_ERR_INVALID,
                            "%s has no joint named %s, which the kinect1 rig maps (its joints: "
                            "%s%s); use a \"bvh\" rig that names this motion's joints",
                            motion, missing, have, t->n_joints > 12 ? ", ..." : "");
  }
  bool same = t->n_joints == KM_KINECT1_JOINTS;
  for (int j = 0; same && j < KM_KINECT1_JOINTS; ++j)
    same = src[j] == j;
  if (same) return KM_OK;
  km_take k;
  km_status s = kinect1_take(t, src, &k, err);
  if (s) return s;
  km_take_free(t);
  *t = k;
  return KM_OK;
}

/* ------------------------------------------------------------------ precompute */

int km_cli_precompute(int argc, char **argv) {
  const char *out = NULL, *energy = NULL;
  int fields = 8, isolines = 10;
  bool force = false;
  const km_cli_opt opts[] = {
      {"output", 'o', KM_OPT_STRING, &out, "cache file (default MESH.kmcache)"},
      {"fields", 0, KM_OPT_INT, &fields, "propagation fields n_e (default 8)"},
      {"isolines", 0, KM_OPT_INT, &isolines, "isolines per field n_iso (default 10)"},
      {"energy", 0, KM_OPT_STRING, &energy,
       "reduced model energy: arap (default) or laplacian (the paper's eq. 8-9)"},
      {"force", 0, KM_OPT_FLAG, &force, "rebuild even when the cache is up to date"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                       "kinemesh precompute MESH [-o CACHE] [--fields 8] [--isolines 10] "
                       "[--energy arap|laplacian] [--force]",
                       "Builds the reduced isoline model of a mesh (eigenfields of the cotangent\n"
                       "Laplacian, isolines, interpolation W, W'L'LW) and writes it to a\n"
                       "versioned, checksummed cache that animate and live reuse. A cache that\n"
                       "is already up to date for this mesh and these parameters is loaded and\n"
                       "kept (--force rebuilds it).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("precompute", "expected one MESH");
  km_puppet_options po = {0};
  po.fields = fields;
  po.isolines = isolines;
  if (km_cli_parse_energy("precompute", energy, &po.energy)) return KM_EXIT_FAIL;
  km_error err = {0};
  km_mesh m = {0};
  km_puppet *p = NULL;
  char *cache = out ? NULL : km_cli_cache_path(pos[0]);
  const char *path = out ? out : cache;
  int rc = KM_EXIT_OK;
  double t0 = km_cli_now();
  bool loaded = false;
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) {
    rc = km_cli_fail("precompute", &err);
    goto done;
  }
  if (!force) {
    km_error lerr = {0};
    km_status s = km_puppet_load(path, &m, &po, &p, &lerr);
    if (s == KM_OK)
      loaded = true;
    else if (s == KM_ERR_STALE)
      fprintf(stderr, "kinemesh precompute: rebuilding %s: %s\n", path, lerr.message);
  }
  if (!loaded) {
    po.progress = km_cli_progress("precompute");
    t0 = km_cli_now();
    if (km_puppet_precompute(&m, &po, &p, &err) != KM_OK ||
        km_puppet_save(p, path, &err) != KM_OK) {
      rc = km_cli_fail("precompute", &err);
      goto done;
    }
    km_cli_progress_done();
  }
  km_puppet_info info;
  km_puppet_info_get(p, &info);
  fprintf(stderr,
          "kinemesh precompute: %zu vertices, %d fields x %d isolines (%zu unknowns per "
          "coordinate), %zu crossed triangles; %s in %.3f s -> %s\n",
          info.vertices, info.fields, info.isolines, info.unknowns, info.crossed_triangles,
          loaded ? "up to date, loaded (t~1)" : "built (t1)", km_cli_now() - t0, path);
done:
  free(cache);
  km_puppet_free(&p);
  km_mesh_free(&m);
  return rc;
}

/* ------------------------------------------------------------------ animate */

typedef struct stage_times {
  double *t23, *t4; /* per frame, ms */
  size_t n;
} stage_times;

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

double km_cli_median(double *v, size_t n) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int km_cli_animate(int argc, char **argv) {
  const char *mesh_path = NULL, *rig_path = NULL, *motion = NULL, *cache = NULL, *out = NULL;
  const char *solver = NULL, *energy = NULL;
  const char *frame_format = NULL;
  int iterations = 0, fields = 0, isolines = 0;
  double scale = 0, fps = 0;
  size_t key_every = 0;
  const km_cli_opt opts[] = {
      {"mesh", 0, KM_OPT_STRING, &mesh_path, "mesh to animate (OBJ/PLY/OFF)"},
      {"rig", 0, KM_OPT_STRING, &rig_path,
       "rig: handles, joint map, filter (default <mesh stem>.rig.json)"},
      {"motion", 0, KM_OPT_STRING, &motion,
       "take: .json (kinemesh), .csv (Kinect v1 recording), .bvh"},
      {"cache", 0, KM_OPT_STRING, &cache, "reduced-model cache (default MESH.kmcache)"},
      {"solver", 0, KM_OPT_STRING, &solver,
       "reduced (default, real time) or full (ARAP reference)"},
      {"energy", 0, KM_OPT_STRING, &energy,
       "reduced model energy: arap (default) or laplacian (the paper's eq. 8-9)"},
      {"fields", 0, KM_OPT_INT, &fields,
       "propagation fields n_e (default: the cache's when it has one, else 8)"},
      {"isolines", 0, KM_OPT_INT, &isolines,
       "isolines per field n_iso (default: the cache's when it has one, else 10)"},
      {"iterations", 0, KM_OPT_INT, &iterations, "rotation updates per frame (default 4)"},
      {"scale", 0, KM_OPT_DOUBLE, &scale, "performer-to-character scale (default: automatic)"},
      {"fps", 0, KM_OPT_DOUBLE, &fps, "output frame rate (default: the take's)"},
      {"key-every", 0, KM_OPT_SIZE, &key_every, "glb: one morph target every N frames"},
      {"frame-format", 0, KM_OPT_STRING, &frame_format,
       "directory output: obj (default) or ply (binary) per frame"},
      {"output", 'o', KM_OPT_STRING, &out, "output: .glb, .pc2 or a directory of per-frame meshes"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                   "kinemesh animate --mesh MESH [--rig RIG] --motion TAKE [--cache FILE] -o OUT",
                   "Puppetry: skeleton joints are smoothed (Holt-Winters), mapped to the rig's\n"
                   "handles and the mesh is deformed per frame by the reduced isoline model\n"
                   "(precomputed once and cached) or, with --solver full, by full-space ARAP.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!mesh_path || !motion || !out)
    return km_cli_error("animate", "--mesh, --motion and -o are required (see --help)");
  bool full = false;
  km_puppet_energy pe = KM_PUPPET_ENERGY_ARAP;
  km_anim_format af = 0;
  if (parse_solver("animate", solver, &full) || km_cli_parse_energy("animate", energy, &pe) ||
      km_cli_parse_frame_format("animate", frame_format, &af))
    return KM_EXIT_FAIL;

  km_error err = {0};
  km_mesh m = {0};
  km_take take = {0};
  km_rig rig = {0};
  km_filter *filter = NULL;
  km_retarget *rt = NULL;
  km_puppet *pup = NULL;
  km_arap *arap = NULL;
  km_anim_writer *w = NULL;
  int32_t *offsets = NULL;
  double *raw = NULL, *filt = NULL, *targets = NULL, *V = NULL, *t23 = NULL, *t4 = NULL;
  char *rig_default = rig_path ? NULL : km_cli_rig_path(mesh_path);
  char *cache_default = cache ? NULL : km_cli_cache_path(mesh_path);
  int rc = KM_EXIT_FAIL;
  double t_pre = 0;
  bool loaded = false;

  if (km_mesh_read(mesh_path, &m, &err) != KM_OK ||
      km_cli_read_motion(motion, &take, &err) != KM_OK)
    goto fail;
  if (take.n_frames == 0) {
    rc = km_cli_error("animate", "%s has no frames", motion);
    goto done;
  }
  if (km_rig_read(rig_path ? rig_path : rig_default, &m, (const char *const *)take.joint_names,
                  take.n_joints, &rig, &err) != KM_OK)
    goto fail;
  if (rig.skeleton == KM_RIG_KINECT1 && take_to_kinect_order(&take, &rig, motion, &err) != KM_OK)
    goto fail;
  if (rig.n_handles == 0) {
    rc = km_cli_error("animate", "the rig has no handles");
    goto done;
  }
  offsets = malloc(sizeof(int32_t) * (rig.n_handles + 1));
  if (!offsets) goto nomem;
  offsets[0] = 0;
  size_t n_hv = 0;
  for (size_t h = 0; h < rig.n_handles; ++h)
    offsets[h + 1] = offsets[h] + (int32_t)rig.handles[h].n_vertices;
  n_hv = (size_t)offsets[rig.n_handles];
  int32_t *hverts = malloc(sizeof(int32_t) * (n_hv ? n_hv : 1));
  if (!hverts) goto nomem;
  for (size_t h = 0, k = 0; h < rig.n_handles; ++h)
    for (size_t i = 0; i < rig.handles[h].n_vertices; ++i)
      hverts[k++] = rig.handles[h].vertices[i];

  km_retarget_options ro = {0};
  ro.scale = scale;
  if (km_filter_create(take.n_joints, &rig.filter, &filter, &err) != KM_OK ||
      km_retarget_create(&rig, &m, take.n_joints, &ro, &rt, &err) != KM_OK) {
    free(hverts);
    goto fail;
  }
  if (full) {
    km_arap_options ao = {0};
    ao.iterations = iterations;
    double t0 = km_cli_now();
    km_status s = km_arap_precompute(&m, rig.n_handles, offsets, hverts, &ao, &arap, &err);
    t_pre = km_cli_now() - t0;
    free(hverts);
    if (s != KM_OK) goto fail;
  } else {
    km_puppet_options po = {0};
    const char *cpath = cache ? cache : cache_default;
    /* A cache made by `precompute --fields/--isolines/--energy` is used as built unless this
     * run asks for other parameters. */
    km_error cerr = {0};
    if (!fields && !isolines && !energy && km_puppet_cache_options(cpath, &po, &cerr) == KM_OK)
      fprintf(stderr, "kinemesh animate: %s: %d fields x %d isolines, %s energy\n", cpath,
              po.fields, po.isolines,
              po.energy == KM_PUPPET_ENERGY_LAPLACIAN ? "laplacian" : "arap");
    else {
      po.fields = fields;
      po.isolines = isolines;
      po.energy = pe;
    }
    po.iterations = iterations;
    km_status s = km_cli_puppet_open(&m, &po, cpath, true, &pup, &loaded, &t_pre, &err);
    if (s == KM_OK) s = km_puppet_set_handles(pup, rig.n_handles, offsets, hverts, &err);
    free(hverts);
    if (s != KM_OK) goto fail;
  }
  raw = malloc(sizeof(double) * 3 * take.n_joints);
  filt = malloc(sizeof(double) * 3 * take.n_joints);
  targets = malloc(sizeof(double) * 3 * (n_hv ? n_hv : 1));
  V = malloc(sizeof(double) * 3 * m.n_vertices);
  t23 = malloc(sizeof(double) * take.n_frames);
  t4 = malloc(sizeof(double) * take.n_frames);
  if (!raw || !filt || !targets || !V || !t23 || !t4) goto nomem;

  km_anim_options wo = {0};
  wo.fps = fps > 0 ? fps : take.fps;
  wo.key_every = key_every;
  wo.format = af;
  if (km_anim_writer_open(out, &m, &wo, &w, &err) != KM_OK) goto fail;
  km_progress prog = km_cli_progress("animate");
  for (size_t f = 0; f < take.n_frames; ++f) {
    double a = km_cli_now();
    memcpy(raw, take.positions + f * take.n_joints * 3, sizeof(double) * 3 * take.n_joints);
    km_filter_push(filter, raw, filt);
    km_retarget_push(rt, filt, NULL);
    km_retarget_vertex_targets(rt, targets);
    double b = km_cli_now();
    km_status s =
        full ? km_arap_solve(arap, targets, V, &err) : km_puppet_solve(pup, targets, V, &err);
    double c = km_cli_now();
    if (s != KM_OK) goto fail;
    t23[f] = 1e3 * (b - a);
    t4[f] = 1e3 * (c - b);
    if (km_anim_writer_push(w, V, &err) != KM_OK) goto fail;
    prog.fn((double)(f + 1) / (double)take.n_frames, full ? "full ARAP" : "reduced model", NULL);
  }
  if (km_anim_writer_close(&w, &err) != KM_OK) goto fail;
  km_cli_progress_done();
  double m23 = km_cli_median(t23, take.n_frames), m4 = km_cli_median(t4, take.n_frames);
  fprintf(stderr,
          "kinemesh animate: %zu frames, %zu vertices, %zu handles (%zu vertices), scale %.3f\n"
          "  %-22s %10s %12s %12s %12s\n"
          "  %-22s %10.3f %12.4f %12.3f %12.3f\n"
          "-> %s\n",
          take.n_frames, m.n_vertices, rig.n_handles, n_hv, km_retarget_scale(rt),
          full ? "stage (full ARAP)" : (loaded ? "stage (cache loaded)" : "stage (precomputed)"),
          full ? "t1 (s)" : (loaded ? "t~1 (s)" : "t1 (s)"), "t2,3 (ms)", "t4 (ms)", "tper (ms)",
          "median per frame", t_pre, m23, m4, m23 + m4, out);
  rc = KM_EXIT_OK;
  goto done;
nomem:
  rc = km_cli_error("animate", "out of memory");
  goto done;
fail:
  rc = km_cli_fail("animate", &err);
done:
  km_anim_writer_free(&w);
  free(offsets);
  free(raw);
  free(filt);
  free(targets);
  free(V);
  free(t23);
  free(t4);
  free(rig_default);
  free(cache_default);
  km_puppet_free(&pup);
  km_arap_free(&arap);
  km_retarget_free(&rt);
  km_filter_free(&filter);
  km_rig_free(&rig);
  km_take_free(&take);
  km_mesh_free(&m);
  return rc;
}
