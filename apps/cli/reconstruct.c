/* kinemesh reconstruct: point clouds -> mesh animation, a rigged template registered to
 * every frame (Park & Lim 2014). The simulated capture it reads is `kinemesh gen capture`
 * (gen.c). */
#include "cli.h"
#include "recon_plot.h"
#include "recon_segments.h"

#include <cjson/cJSON.h>

#include <stdlib.h>
#include <string.h>

/* Features file: one "vertex x y z" per line ('#' comments). */
/* First-frame correspondences: JSON {"correspondences": [{"vertex": 12, "point": [x, y, z]},
 * ...]} or text/CSV lines "vertex x y z" / "vertex,x,y,z" (a header line and # comments are
 * skipped). Returns 0, -1 when unreadable, or the 1-based line (JSON: entry) that is wrong. */
static int read_features(const char *path, km_recon_feature **out, size_t *n) {
  char *text = km_cli_read_text(path, NULL);
  if (!text) return -1;
  *n = 0;
  *out = NULL;
  const char *q = text;
  while (*q == ' ' || *q == '\t' || *q == '\n' || *q == '\r')
    ++q;
  if (*q == '{') {
    cJSON *root = cJSON_Parse(text);
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, "correspondences");
    int count = cJSON_GetArraySize(arr), bad = root && cJSON_IsArray(arr) ? 0 : 1;
    *out = malloc(sizeof **out * (size_t)(count > 0 ? count : 1));
    for (int i = 0; !bad && *out && i < count; ++i) {
      const cJSON *e = cJSON_GetArrayItem(arr, i);
      const cJSON *v = cJSON_GetObjectItemCaseSensitive(e, "vertex");
      const cJSON *pt = cJSON_GetObjectItemCaseSensitive(e, "point");
      if (!cJSON_IsNumber(v) || v->valuedouble < 0 || v->valuedouble > INT32_MAX ||
          cJSON_GetArraySize(pt) != 3) {
        bad = i + 1;
        break;
      }
      (*out)[*n].vertex = (int32_t)v->valuedouble;
      for (int k = 0; k < 3; ++k) {
        const cJSON *c = cJSON_GetArrayItem(pt, k);
        if (!cJSON_IsNumber(c)) bad = i + 1;
        (*out)[*n].point[k] = cJSON_IsNumber(c) ? c->valuedouble : 0;
      }
      ++*n;
    }
    cJSON_Delete(root);
    free(text);
    return bad;
  }
  size_t cap = 16;
  *out = malloc(cap * sizeof **out);
  int lineno = 0, bad = 0;
  for (char *line = strtok(text, "\n"); line && *out && !bad; line = strtok(NULL, "\n")) {
    ++lineno;
    for (char *c = line; *c; ++c)
      if (*c == ',' || *c == ';' || *c == '\r') *c = ' ';
    char *p = line;
    while (*p == ' ' || *p == '\t')
      ++p;
    if (*p == '#' || !*p) continue;
    if (*n == 0 && lineno == 1 && !(*p >= '0' && *p <= '9')) continue; /* CSV header */
    long v;
    double x, y, z;
    if (sscanf(p, "%ld %lf %lf %lf", &v, &x, &y, &z) != 4 || v < 0 || v > INT32_MAX) {
      bad = lineno;
      break;
    }
    if (*n == cap) {
      km_recon_feature *g = realloc(*out, 2 * cap * sizeof *g);
      if (!g) break;
      *out = g, cap *= 2;
    }
    (*out)[*n].vertex = (int32_t)v;
    (*out)[*n].point[0] = x, (*out)[*n].point[1] = y, (*out)[*n].point[2] = z;
    ++*n;
  }
  free(text);
  return bad;
}

int km_cli_reconstruct(int argc, char **argv) {
  const char *tmpl = NULL, *rig = NULL, *features = NULL, *out = NULL, *report = NULL, *plot = NULL;
  const char *clouds = NULL;
  bool rig_joints = false, strict = false, keep_frame = false;
  double unsupported_mm = 0, unsupported_fraction = 0;
  size_t coarse = 0, vertices = 4000, segment = 0, overlap = 5;
  int radius = 0, segment_only = -1;
  const char *segment_dir = NULL;
  bool compress = false;
  const char *export_kind = NULL;
  double max_error_mm = 0;
  km_cli_frame_opts fo = {0};
  const char *clouds_up = NULL, *clouds_forward = NULL, *clouds_units = NULL;
  const km_cli_opt opts[] = {
      KM_CLI_EXPORT_OPTIONS(export_kind, max_error_mm, compress),
      KM_CLI_FRAME_OPTIONS(fo),
      {"clouds-up", 0, KM_OPT_STRING, &clouds_up,
       "the point clouds' up axis (default: the template's, as given or found)"},
      {"clouds-forward", 0, KM_OPT_STRING, &clouds_forward,
       "the axis the captured subject faces in the clouds (default: the template's)"},
      {"clouds-units", 0, KM_OPT_STRING, &clouds_units,
       "the clouds' units (default: the template's)"},
      {"template", 't', KM_OPT_STRING, &tmpl,
       "template mesh with rig sidecar (default: procedural, --vertices)"},
      {"rig", 0, KM_OPT_STRING, &rig,
       "its rig sidecar (default <stem>.rig.json, else a glTF's own skin, else "
       "one made on the spot as kinemesh rig makes it)"},
      {"vertices", 'n', KM_OPT_SIZE, &vertices, "procedural template size (default 4000)"},
      {"clouds", 0, KM_OPT_STRING, &clouds, "point cloud frames: a directory or a quoted glob"},
      {"correspondences", 0, KM_OPT_STRING, &features,
       "first-frame correspondences: JSON, CSV or 'vertex x y z' lines (default: global "
       "alignment)"},
      {"features", 0, KM_OPT_STRING, &features, "same as --correspondences"},
      {"coarse", 0, KM_OPT_SIZE, &coarse, "points of the coarse level (default 2000)"},
      {"filter-radius", 0, KM_OPT_INT, &radius, "temporal filter half width (default 2, -1 off)"},
      {"rig-joints", 0, KM_OPT_FLAG, &rig_joints,
       "use the template rig's joints (default: estimated from the skin weights)"},
      {"unsupported-mm", 0, KM_OPT_DOUBLE, &unsupported_mm,
       "a template vertex farther than this from every point is unsupported (default 30)"},
      {"unsupported-fraction", 0, KM_OPT_DOUBLE, &unsupported_fraction,
       "flag a frame with more than this fraction of its surface unsupported (default 0.02)"},
      {"strict", 0, KM_OPT_FLAG, &strict,
       "exit non-zero when a frame is flagged (unsupported surface) or carried"},
      {"report", 0, KM_OPT_STRING, &report, "per-frame report (JSON)"},
      {"plot", 0, KM_OPT_STRING, &plot, "error plot (PNG, through gnuplot)"},
      {"output", 'o', KM_OPT_STRING, &out, "output animation (.glb, .pc2 or a directory)"},
      {"keep-frame", 0, KM_OPT_FLAG, &keep_frame,
       ".pc2 and frame directories in the template file's own axes and units, as animate "
       "--keep-frame (default: kinemesh's frame; a .glb is always in glTF's, which is that one)"},
      {"segment-frames", 0, KM_OPT_SIZE, &segment,
       "split the take into segments of this many frames, each started on its own first frame, "
       "stitched (default: one segment)"},
      {"overlap", 0, KM_OPT_SIZE, &overlap,
       "with --segment-frames: frames a segment tracks into the next, cross-faded (default 5)"},
      {"segment", 0, KM_OPT_INT, &segment_only,
       "with --segment-frames and --segment-dir: track only segment K (from 0) and write its "
       "part there; -o, --report, --plot, --strict and --export belong to the stitch"},
      {"segment-dir", 0, KM_OPT_STRING, &segment_dir,
       "with --segment-frames: folder of the segments' parts; without --segment, stitch them "
       "(the output has the bytes of the same command without --segment-dir)"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                   "kinemesh reconstruct --template T [--rig R] --clouds 'FRAMES/*.ply' "
                   "[--correspondences C] -o OUT [--report R.json] [--plot P.png] [--strict]",
                   "Template-based mesh animation from point cloud frames (Park & Lim 2014).\n"
                   "FRAMES (--clouds, or the one positional argument) is a directory or a quoted\n"
                   "glob of .ply/.pcd/.xyz files, read in name order. Every frame is measured\n"
                   "both ways: points to surface, and surface to points (template vertices far\n"
                   "from every point: a limb left behind or hidden); a frame with too much\n"
                   "unsupported surface gets a warning line, and with --strict the exit status\n"
                   "is 1. The template is brought into kinemesh's frame (y up, facing +z,\n"
                   "metres) by --up/--forward/--units, else its rig sidecar's \"frame\", else a\n"
                   "guess (printed); the clouds and correspondences are taken in the template\n"
                   "file's frame unless --clouds-up/--clouds-forward/--clouds-units say\n"
                   "otherwise. The output is in kinemesh's frame, as animate's is (--keep-frame:\n"
                   "in the template file's).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!clouds && n_pos == 1) clouds = pos[0];
  int kf = km_cli_keep_frame_output("reconstruct", out, keep_frame);
  if (kf) return kf;
  const bool one_segment = segment_only >= 0;
  if (segment_only < -1 || ((one_segment || segment_dir) && !segment) ||
      (one_segment && !segment_dir))
    return km_cli_error("reconstruct", "--segment K (K >= 0) needs --segment-frames S and "
                                       "--segment-dir DIR; --segment-dir needs --segment-frames");
  if (!clouds || (!out && !one_segment))
    return km_cli_error("reconstruct", "--clouds FRAMES and -o OUT are required");
  if (one_segment) report = plot = export_kind = NULL, strict = false;
  km_cli_serial_blas();
  km_error err = {0};
  char **paths = NULL;
  size_t n = 0;
  if (km_point_frames_list(clouds, &paths, &n, &err)) return km_cli_fail("reconstruct", &err);
  km_recon_feature *feat = NULL;
  size_t nfeat = 0;
  if (features) {
    int fl = read_features(features, &feat, &nfeat);
    if (fl != 0) {
      free(feat);
      km_paths_free(&paths, n);
      return fl < 0 ? km_cli_error("reconstruct", "%s: cannot open", features)
                    : km_cli_error("reconstruct",
                                   "%s: entry/line %d: expected 'vertex x y z' (text or CSV) or "
                                   "{\"vertex\": V, \"point\": [x, y, z]} (JSON)",
                                   features, fl);
    }
  }
  km_character c = {0};
  int rc = KM_EXIT_OK;
  km_recon_report rep = {0};
  if (unsupported_mm < 0 || unsupported_fraction < 0 || unsupported_fraction >= 1) {
    free(feat);
    km_paths_free(&paths, n);
    return km_cli_error("reconstruct",
                        "--unsupported-mm must be >= 0 and --unsupported-fraction in [0, 1)");
  }
  km_recon_options ro = {.coarse_points = coarse,
                         .filter_radius = radius,
                         .rig_joints = rig_joints,
                         .unsupported_distance = unsupported_mm * 1e-3,
                         .unsupported_fraction = unsupported_fraction};
  ro.progress = km_cli_progress("reconstruct");
  if ((one_segment || segment_dir) && segment >= n) {
    free(feat);
    km_paths_free(&paths, n);
    return km_cli_error("reconstruct",
                        "--segment-dir: the take has %zu frames, one segment of %zu: nothing to "
                        "split (run it without --segment-frames)",
                        n, segment);
  }
  km_anim_options ao = {0};
  km_ssdr_options so;
  double *seeds = NULL;
  if (!one_segment &&
      km_cli_parse_export("reconstruct", export_kind, max_error_mm, compress, out, &ao, &so)) {
    free(feat);
    km_paths_free(&paths, n);
    return KM_EXIT_FAIL;
  }
  ro.anim = &ao;
  double t0 = km_cli_now();
  km_frame tf, cf;
  if ((rc = km_cli_load_character_oriented("reconstruct", tmpl, rig, vertices, &fo, &c, &tf)) ||
      ((clouds_up || clouds_forward || clouds_units) &&
       (rc = km_cli_given_frame("reconstruct", "clouds", clouds_up, clouds_forward, clouds_units,
                                &cf)))) {
    km_character_free(&c);
    free(feat);
    km_paths_free(&paths, n);
    return rc;
  }
  if (!(clouds_up || clouds_forward || clouds_units)) cf = tf; /* the template file's frame */
  if (keep_frame) ao.frame = &tf; /* the writer takes each frame back into the template file's */
  if (!km_frame_is_identity(&cf)) {
    ro.points_frame = &cf;
    for (size_t i = 0; i < nfeat; ++i) /* the frame is valid: parsed or applied already */
      (void)km_frame_apply(&cf, feat[i].point, 1, NULL, 0, NULL);
  }
  km_status s = KM_OK;
  /* The template is skinned: its parts seed a skin fit. */
  if (!s && !one_segment &&
      km_cli_skin_seeds("reconstruct", &ao, &c.mesh, &c.skin, c.skeleton.n_joints, &so, &seeds))
    s = km_error_set(&err, KM_ERR_NOMEM, "out of memory");
  if (!s && segment && segment < n) {
    /* segments: tracked here one after the other, or one of them (--segment), or stitched
     * from parts other processes tracked (--segment-dir); the report as unsegmented */
    km_cli_segments sg = {
        .frames = segment, .overlap = overlap, .only = segment_only, .dir = segment_dir};
    s = km_cli_reconstruct_segmented(paths, n, &c, feat, nfeat, &ro, &sg, out, &rep, &err);
    if (!s && !one_segment)
      fprintf(stderr, "kinemesh reconstruct: %zu segments of %zu frames (+%zu overlap) %s\n",
              km_cli_segment_count(n, segment), segment, overlap,
              segment_dir ? "stitched from their parts" : "tracked and stitched");
  } else if (!s) {
    s = km_reconstruct((const char *const *)paths, n, &c, feat, nfeat, &ro, out, &rep, &err);
  }
  km_cli_progress_done();
  if (rep.n_frames) {
    double mean = 0, smean = 0, smax = 0;
    for (size_t f = 0; f < rep.n_frames; ++f) {
      const km_recon_frame_stats *st = &rep.frames[f];
      mean += st->mean_mm / (double)rep.n_frames;
      smean += st->surface_mean_mm / (double)rep.n_frames;
      smax = st->surface_max_mm > smax ? st->surface_max_mm : smax;
      if (!st->unsupported) continue;
      char parts[512] = "";
      for (int k = 0; k < st->n_unsupported_joints; ++k) {
        size_t len = strlen(parts);
        snprintf(parts + len, sizeof parts - len, "%s%s", k ? ", " : "",
                 rep.joint_names[st->unsupported_joints[k]]);
      }
      fprintf(stderr,
              "kinemesh reconstruct: warning: frame %zu: unsupported surface: %zu of %zu "
              "vertices (%.1f%%) farther than %.0f mm from every point (up to %.0f mm): %s\n",
              st->index, st->unsupported_vertices, st->surface_vertices,
              st->surface_vertices
                  ? 100.0 * (double)st->unsupported_vertices / (double)st->surface_vertices
                  : 0.0,
              rep.unsupported_distance_mm, st->surface_max_mm, parts[0] ? parts : "no one part");
    }
    fprintf(stderr,
            "kinemesh reconstruct: %zu frames (%zu carried by the skeleton, %zu with unsupported "
            "surface), mean point error %.2f mm, surface to points mean %.2f mm max %.0f mm "
            "(%s%s), %.2f s/frame, jerk %.2f -> %.2f mm -> %s\n",
            rep.n_frames, rep.failed_frames, rep.unsupported_frames, mean, smean, smax,
            rep.visibility_known ? "vertices facing a camera" : "all vertices",
            rep.still_vertices ? " but those the skin leaves still, lying on the floor" : "",
            (km_cli_now() - t0) / (double)rep.n_frames, rep.jerk_before * 1e3, rep.jerk_after * 1e3,
            out);
    if (strict && (rep.unsupported_frames || rep.failed_frames) && rc == KM_EXIT_OK && !s) {
      fprintf(stderr, "kinemesh reconstruct: --strict: %zu frame(s) flagged, %zu carried\n",
              rep.unsupported_frames, rep.failed_frames);
      rc = KM_EXIT_FAIL;
    }
    km_error e2 = {0};
    if (report && km_recon_report_write_json(report, &rep, &e2))
      rc = km_cli_fail("reconstruct", &e2);
    if (plot && km_recon_report_plot(plot, &rep, &e2)) rc = km_cli_fail("reconstruct", &e2);
  }
  if (s) rc = km_cli_fail("reconstruct", &err);
  if (!s) km_cli_report_export("reconstruct", &rep.export_report);
  free(seeds);
  km_recon_report_free(&rep);
  km_character_free(&c);
  free(feat);
  km_paths_free(&paths, n);
  return rc;
}
