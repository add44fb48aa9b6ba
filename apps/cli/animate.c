/* kinemesh animate: a take drives a mesh through the puppetry pipeline (km_puppetry), one frame
 * at a time, into .glb / .pc2 / a frame directory. */
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int parse_solver(const char *verb, const char *s, bool *full) {
  if (!s || !strcmp(s, "reduced"))
    *full = false;
  else if (!strcmp(s, "full"))
    *full = true;
  else
    return km_cli_error(verb, "--solver must be reduced or full, not '%s'", s);
  return 0;
}

typedef struct stage_times {
  double *t23, *t4; /* per frame, ms */
  size_t n;
} stage_times;

int km_cli_animate(int argc, char **argv) {
  const char *mesh_path = NULL, *rig_path = NULL, *motion = NULL, *cache = NULL, *out = NULL;
  const char *solver = NULL, *energy = NULL;
  const char *frame_format = NULL, *filter_kind = NULL;
  bool no_glitch = false, floor_on = false, no_floor = false, keep_frame = false;
  int iterations = 0, fields = 0, isolines = 0;
  double scale = 0, fps = 0, handle_weight = NAN;
  size_t key_every = 0;
  bool compress = false;
  const char *export_kind = NULL, *report = NULL;
  double max_error_mm = 0;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      KM_CLI_MOTION_FRAME_OPTIONS(fo),
      {"mesh", 0, KM_OPT_STRING, &mesh_path, "mesh to animate (OBJ/PLY/OFF/STL/glTF)"},
      {"rig", 0, KM_OPT_STRING, &rig_path,
       "rig: handles, joint map, filter (default <mesh stem>.rig.json, else a glTF's own skin, "
       "else one made on the spot as kinemesh rig makes it)"},
      {"motion", 0, KM_OPT_STRING, &motion,
       "take: .json (kinemesh), .csv (Kinect v1 recording), .bvh"},
      {"cache", 0, KM_OPT_STRING, &cache,
       "reduced-model cache (default: $XDG_CACHE_HOME/kinemesh/<mesh hash>.kmcache)"},
      {"solver", 0, KM_OPT_STRING, &solver,
       "reduced (default, real time) or full (full-space ARAP, 15-150 ms a frame)"},
      {"handle-weight", 0, KM_OPT_DOUBLE, &handle_weight,
       "full solver: how hard handle vertices are pulled to their targets, relative to the mean "
       "Laplacian diagonal (default 0.03: soft, a band may give a little; 0: hard handles, the "
       "exact ARAP reference)"},
      {"energy", 0, KM_OPT_STRING, &energy,
       "reduced model energy: arap (default) or laplacian (the paper's eq. 8-9)"},
      {"fields", 0, KM_OPT_INT, &fields,
       "propagation fields n_e (default: the cache's when it has one, else 8)"},
      {"isolines", 0, KM_OPT_INT, &isolines,
       "isolines per field n_iso (default: the cache's when it has one, else 10)"},
      {"iterations", 0, KM_OPT_INT, &iterations, "rotation updates per frame (default 4)"},
      {"scale", 0, KM_OPT_DOUBLE, &scale, "performer-to-character scale (default: automatic)"},
      {"fps", 0, KM_OPT_DOUBLE, &fps,
       "output frame rate; the motion is resampled (default: the take's)"},
      {"key-every", 0, KM_OPT_SIZE, &key_every, "glb: one morph target every N frames"},
      KM_CLI_EXPORT_OPTIONS(export_kind, max_error_mm, compress),
      {"filter", 0, KM_OPT_STRING, &filter_kind,
       "joint filter: holt or one_euro (default: the rig's \"filter\", else holt)"},
      {"no-glitch", 0, KM_OPT_FLAG, &no_glitch,
       "do not reject tracker glitches (jumps, bone-length outliers) before the filter"},
      {"floor", 0, KM_OPT_FLAG, &floor_on,
       "keep every vertex above the rest floor (a rig from kinemesh rig says so already)"},
      {"no-floor", 0, KM_OPT_FLAG, &no_floor,
       "let the mesh go below the rest floor (turns the rig's \"floor\": true off)"},
      {"frame-format", 0, KM_OPT_STRING, &frame_format,
       "directory output: obj (default) or ply (binary) per frame"},
      {"output", 'o', KM_OPT_STRING, &out, "output: .glb, .pc2 or a directory of per-frame meshes"},
      {"report", 0, KM_OPT_STRING, &report,
       "write the deformation check as JSON: per frame the edge length ratios l/l0, folded "
       "triangles and one-frame step (the summary line's measures)"},
      {"keep-frame", 0, KM_OPT_FLAG, &keep_frame,
       ".pc2 and frame directories in the mesh file's own axes and units (its --up/--forward/"
       "--units, given, recorded or guessed, undone), to line up with the file: a point cache "
       "on the object imported from it (default: kinemesh's frame, y up, facing +z, metres; a "
       ".glb is always in glTF's, which is that one)"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                   "kinemesh animate --mesh MESH [--rig RIG] --motion TAKE [--cache FILE] -o OUT",
                   "Puppetry: skeleton joints are smoothed (Holt-Winters), mapped to the rig's\n"
                   "handles and the mesh is deformed per frame by the reduced isoline model\n"
                   "(precomputed once and cached) or, with --solver full, by full-space ARAP\n"
                   "(offline quality: soft handles by default, --handle-weight 0 for hard ones).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!mesh_path || !motion || !out)
    return km_cli_error("animate", "--mesh, --motion and -o are required (see --help)");
  int kf = km_cli_keep_frame_output("animate", out, keep_frame);
  if (kf) return kf;
  bool full = false;
  km_puppet_energy pe = KM_PUPPET_ENERGY_ARAP;
  km_anim_format af = 0;
  if (floor_on && no_floor)
    return km_cli_error("animate", "--floor and --no-floor: give one of them, not both");
  if (parse_solver("animate", solver, &full) || km_cli_parse_energy("animate", energy, &pe) ||
      km_cli_parse_frame_format("animate", frame_format, &af))
    return KM_EXIT_FAIL;
  if (!isnan(handle_weight) && !(handle_weight >= 0 && isfinite(handle_weight)))
    return km_cli_error("animate", "--handle-weight %g: expected a number >= 0 (0: hard handles)",
                        handle_weight);
  if (!isnan(handle_weight) && !full)
    return km_cli_error("animate", "--handle-weight is for --solver full (the reduced model's "
                                   "handles are soft by construction)");

  km_error err = {0};
  km_mesh m = {0};
  km_take take = {0};
  km_rig rig = {0};
  km_puppetry *pl = NULL;
  km_anim_writer *w = NULL;
  double *V = NULL, *t23 = NULL, *t4 = NULL;
  km_deform_check *dc = NULL;
  km_stretch_bound *sb = NULL;
  char *rig_default = rig_path ? NULL : km_cli_rig_path(mesh_path);
  char *cache_default = NULL, *skin_json = NULL, *sb_cache = NULL;
  size_t skin_json_n = 0;
  int rc = KM_EXIT_FAIL;

  if (km_mesh_read(mesh_path, &m, &err) != KM_OK ||
      km_motion_read(motion, NULL, &take, NULL, &err) != KM_OK)
    goto fail;
  fo.rig = rig_path; /* the frame its sidecar records (the default one when not given) */
  km_frame mf;
  if ((rc = km_cli_mesh_frame("animate", mesh_path, &fo, &m, false, &mf, NULL)) ||
      (rc = km_cli_orient_take("animate", &fo, &take)))
    goto done;
  if (!km_frame_is_identity(&mf) && km_mesh_frame_apply(&mf, &m, &err) != KM_OK) goto fail;
  /* The sidecar's lengths (handle radii, joints) are in the unit its "frame" records (the
   * file's own when none); --units other than that one: the rig is resolved on the mesh in
   * that unit and its joints rescaled, so `rig` without --units then `animate --units cm`
   * agree. */
  double rig_k = (mf.scale > 0 ? mf.scale : 1) / km_cli_sidecar_scale(mesh_path, rig_path);
  rc = KM_EXIT_FAIL;
  if (!cache && !(cache_default = km_cli_cache_path(&m))) goto nomem;
  if (take.n_frames == 0) {
    rc = km_cli_error("animate", "%s has no frames", motion);
    goto done;
  }
  if (fps > 0 && fps != take.fps) { /* resample, do not relabel: the duration is kept */
    km_take rs;
    if (km_take_resample(&take, fps, &rs, &err) != KM_OK) goto fail;
    km_take_free(&take);
    take = rs;
  }
  if (!rig_path) { /* a skinned glTF without a sidecar: its own skin makes the rig */
    km_character sc = {0};
    bool own = false;
    km_status ss = km_cli_skin_character("animate", mesh_path, NULL, &sc, &own, &err);
    if (ss == KM_OK && own) ss = km_character_rig_json(&sc, &skin_json, &skin_json_n, &err);
    km_character_free(&sc);
    if (ss != KM_OK) goto fail;
  }
  if (!rig_path && !skin_json && access(rig_default, F_OK) != 0) {
    /* no rig file: one made on the spot, as `kinemesh rig` would write it */
    km_character ac = {0};
    km_status as = km_cli_auto_rig("animate", mesh_path, rig_default, &m, stderr, NULL, &ac,
                                   &skin_json, &skin_json_n, &err);
    if (as == KM_OK && !skin_json) as = km_character_rig_json(&ac, &skin_json, &skin_json_n, &err);
    km_character_free(&ac);
    if (as != KM_OK) goto fail;
  }
  km_status rs =
      skin_json ? km_rig_parse(skin_json, skin_json_n, mesh_path, &m,
                               (const char *const *)take.joint_names, take.n_joints, &rig, &err)
                : km_cli_rig_read_scaled(rig_path ? rig_path : rig_default, &m, rig_k,
                                         (const char *const *)take.joint_names, take.n_joints, &rig,
                                         &err);
  if (rs != KM_OK) goto fail;

  if (rig.n_maps == 0) { /* all anchors: a still animation nobody asked for */
    rc = km_cli_error("animate",
                      "%s: the rig's \"map\" is empty or absent, so every handle is an anchor and "
                      "the mesh would not move; map handles to joints, e.g. {\"handle\": "
                      "\"%s\", \"joint\": \"Head\"}",
                      rig_path ? rig_path : rig_default, rig.n_handles ? rig.handles[0].name : "h");
    goto done;
  }
  km_filter_options filt = rig.filter;
  if (filter_kind && (rc = km_cli_parse_filter("animate", filter_kind, &filt))) goto done;
  km_puppetry_options o = {0};
  if (filter_kind) o.filter = &filt;
  o.no_glitch = no_glitch;
  if (no_floor) rig.floor = false;
  o.retarget.floor = floor_on;
  o.retarget.scale = scale;
  o.take_name = motion;
  o.fps = take.fps;
  o.joint_parents = take.parents;
  o.solver = full ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED;
  o.arap.iterations = iterations;
  o.arap.handle_weight = isnan(handle_weight) ? KM_ARAP_SOFT_HANDLES : handle_weight;
  const char *cpath = cache ? cache : cache_default;
  if (!full) {
    /* A cache made by `precompute --fields/--isolines/--energy` is used as built unless this
     * run asks for other parameters. */
    o.cache_parameters = !fields && !isolines && !energy;
    o.puppet.fields = fields;
    o.puppet.isolines = isolines;
    o.puppet.energy = pe;
    o.puppet.iterations = iterations;
    o.puppet.progress = km_cli_progress("precompute");
    o.cache_path = cpath;
  }
  km_puppetry_info pi;
  km_status cs = km_puppetry_create(&m, &rig, (const char *const *)take.joint_names, take.n_joints,
                                    &o, &pl, &pi, &err);
  km_cli_progress_done();
  if (cs != KM_OK) goto fail;
  if (pi.cache_parameters)
    fprintf(stderr, "kinemesh animate: %s: %d fields x %d isolines, %s energy\n", cpath,
            pi.puppet.fields, pi.puppet.isolines,
            pi.puppet.energy == KM_PUPPET_ENERGY_LAPLACIAN ? "laplacian" : "arap");
  km_cli_report_cache(cpath, &pi);
  bool loaded = pi.model == KM_PUPPETRY_MODEL_LOADED;
  const int32_t *offsets = NULL, *hverts = NULL;
  km_puppetry_handles(pl, NULL, &offsets, &hverts);
  size_t n_hv = (size_t)offsets[rig.n_handles];
  /* what the handle targets force: when the mesh stretches, whether the rig asked for it; its
   * pairs cached in the user's cache folder (their Dijkstra runs were half a warm start), also
   * under --cache, whose file may be a shared, read-only model */
  km_stretch_bound_options sbo = {0};
  char *sb_dir = cache_default ? NULL : km_cli_cache_path(&m); /* the mesh hash once */
  const char *sb_base = cache_default ? cache_default : sb_dir;
  size_t cpl = sb_base ? strlen(sb_base) + 8 : 0;
  if (sb_base && (sb_cache = malloc(cpl))) snprintf(sb_cache, cpl, "%s.bound", sb_base);
  free(sb_dir);
  if (!sb_cache) goto nomem;
  sbo.cache_path = sb_cache;
  if (km_stretch_bound_create(&m, rig.n_handles, offsets, hverts, &sbo, &sb, &err) != KM_OK)
    goto fail;
  V = malloc(sizeof(double) * 3 * m.n_vertices);
  t23 = malloc(sizeof(double) * take.n_frames);
  t4 = malloc(sizeof(double) * take.n_frames);
  if (!V || !t23 || !t4) goto nomem;

  km_anim_options wo = {0};
  wo.fps = fps > 0 ? fps : take.fps;
  wo.key_every = key_every;
  wo.format = af;
  km_ssdr_options so;
  if (km_cli_parse_export("animate", export_kind, max_error_mm, compress, out, &wo, &so)) goto done;
  /* --keep-frame: the writer takes each frame back into the file's axes and units */
  if (keep_frame) wo.frame = &mf;
  if (km_anim_writer_open(out, &m, &wo, &w, &err) != KM_OK) goto fail;
  /* every frame checked against the rest mesh, so the user reads where the mesh stretched */
  if (km_deform_check_create(&m, &dc, &err) != KM_OK) goto fail;
  km_progress prog = km_cli_progress("animate");
  for (size_t f = 0; f < take.n_frames; ++f) {
    if (km_puppetry_push(pl, take.positions + f * take.n_joints * 3, V, &err) != KM_OK) goto fail;
    km_puppetry_times tm;
    km_puppetry_times_get(pl, &tm);
    t23[f] = tm.filter_ms + tm.retarget_ms;
    t4[f] = tm.solve_ms;
    if (km_anim_writer_push(w, V, &err) != KM_OK || km_deform_check_add(dc, V, NULL, &err) != KM_OK)
      goto fail;
    int32_t pr[2];
    double fb = km_stretch_bound_eval(sb, km_puppetry_vertex_targets(pl), pr);
    km_deform_check_set_forced(dc, km_stretch_bound_pairs(sb) ? fb : NAN, pr);
    prog.fn((double)(f + 1) / (double)take.n_frames, full ? "full ARAP" : "reduced model", NULL);
  }
  /* the report before the animation is finished: a report that cannot be written leaves no
   * animation behind either */
  char shape_line[1024], forced_line[512] = "";
  km_cli_shape_line(dc, &m, &rig, shape_line, sizeof shape_line);
  km_deform_summary ds;
  km_deform_check_summary(dc, &ds);
  if (ds.forced > 1.5)
    km_cli_forced_line(&m, &rig, ds.forced, ds.forced_frame, ds.forced_pair, forced_line,
                       sizeof forced_line);
  if (report && km_deform_check_write_json(dc, report, &err) != KM_OK) goto fail;
  km_anim_report rep;
  if (km_anim_writer_finish(&w, &rep, &err) != KM_OK) goto fail;
  km_cli_progress_done();
  km_cli_report_export("animate", &rep);
  double m23 = km_cli_median(t23, take.n_frames), m4 = km_cli_median(t4, take.n_frames);
  km_glitch_stats gs;
  km_puppetry_glitch_stats(pl, &gs);
  char glitch_line[256] = "";
  if (!no_glitch)
    km_cli_glitch_line(&gs, "joints whose start was the glitch, reference redone", glitch_line,
                       sizeof glitch_line);
  fprintf(stderr,
          "kinemesh animate: %zu frames, %zu vertices, %zu handles (%zu vertices), scale %.3f\n"
          "  %-22s %10s %12s %12s %12s\n"
          "  %-22s %10.3f %12.4f %12.3f %12.3f\n"
          "%s%s%s"
          "-> %s%s%s\n",
          take.n_frames, m.n_vertices, rig.n_handles, n_hv, km_puppetry_scale(pl),
          full ? "stage (full ARAP)" : (loaded ? "stage (cache loaded)" : "stage (precomputed)"),
          full ? "t1 (s)" : (loaded ? "t~1 (s)" : "t1 (s)"), "t2,3 (ms)", "t4 (ms)", "tper (ms)",
          "median per frame", pi.model_seconds, m23, m4, m23 + m4, glitch_line, shape_line,
          forced_line, out, report ? ", deformation check -> " : "", report ? report : "");
  rc = KM_EXIT_OK;
  goto done;
nomem:
  rc = km_cli_error("animate", "out of memory");
  goto done;
fail:
  rc = km_cli_fail("animate", &err);
done:
  km_anim_writer_free(&w);
  km_deform_check_free(&dc);
  km_stretch_bound_free(&sb);
  free(V);
  free(t23);
  free(t4);
  free(rig_default);
  free(skin_json);
  free(cache_default);
  free(sb_cache);
  km_puppetry_free(&pl);
  km_rig_free(&rig);
  km_take_free(&take);
  km_mesh_free(&m);
  return rc;
}
