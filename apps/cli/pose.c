/* kinemesh pose: a character posed by linear blend skinning along a take, written as an
 * animation. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The performer-to-character scale of a take on skeleton s (map: s's joint -> the take's, -1
 * none): the summed rest bone lengths of s over the take's, each take bone its median length
 * over the frames where both its joints are tracked (a posture-independent size, unlike a
 * height, and robust to a tracker's noisy wrist and ankle bones). A take made for s itself
 * (`gen motion --character`) keeps its bone lengths, so it gives 1 (to rounding); a character
 * in centimetres gives about 100. 1 when no bone is tracked. The retargeter's automatic scale
 * (mesh height over performer stature) is not used: it would change a take made for the
 * character by a few percent, where joint positions are to be met as they are. */
static double performer_scale(const km_skeleton *s, const km_take *t, const int *map) {
  double sum_c = 0, sum_t = 0;
  double *len = malloc(sizeof(double) * (t->n_frames ? t->n_frames : 1));
  if (!len) return 1;
  for (size_t j = 0; j < s->n_joints; ++j) {
    int p = s->parents[j];
    if (p < 0 || map[j] < 0 || map[p] < 0) continue;
    size_t n = 0;
    for (size_t f = 0; f < t->n_frames; ++f) {
      const double *a = t->positions + (f * t->n_joints + (size_t)map[j]) * 3;
      const double *b = t->positions + (f * t->n_joints + (size_t)map[p]) * 3;
      double d = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                      (a[2] - b[2]) * (a[2] - b[2]));
      if (isfinite(d)) len[n++] = d;
    }
    if (n == 0) continue;
    const double *ra = s->rest + 3 * j, *rb = s->rest + 3 * p;
    sum_c += sqrt((ra[0] - rb[0]) * (ra[0] - rb[0]) + (ra[1] - rb[1]) * (ra[1] - rb[1]) +
                  (ra[2] - rb[2]) * (ra[2] - rb[2]));
    sum_t += km_cli_median(len, n);
  }
  free(len);
  return sum_t > 0 && sum_c > 0 ? sum_c / sum_t : 1;
}

/* The puppetry rig of the posed character, resolved on c->mesh (kinemesh's frame, its unit
 * mf->scale) with the take's joint names: the sidecar's (rig_path, else the mesh's own
 * <stem>.rig.json when it exists: its handles, map, limits, root motion and floor as animate
 * reads them), else the one km_character_rig_json makes from c (a skinned glTF's own skin, or
 * a rig made on the spot), as animate makes it. Returns KM_OK or the error in err. */
static km_status pose_rig(const char *mesh, const char *rig_path, const km_character *c,
                          const km_frame *mf, const km_take *t, km_rig *out, km_error *err) {
  char *own = rig_path ? NULL : km_cli_rig_path(mesh);
  const char *path = rig_path ? rig_path : (own && access(own, F_OK) == 0 ? own : NULL);
  km_status s;
  if (path) {
    /* the sidecar's lengths are in the unit its "frame" records: resolved on the mesh in that
     * unit, its joints then rescaled to c's (as animate does) */
    double k = (mf->scale > 0 ? mf->scale : 1) / km_cli_sidecar_scale(mesh, rig_path);
    s = km_cli_rig_read_scaled(path, &c->mesh, k, (const char *const *)t->joint_names, t->n_joints,
                               out, err);
  } else {
    char *json = NULL;
    size_t n = 0;
    s = km_character_rig_json(c, &json, &n, err);
    if (s == KM_OK)
      s = km_rig_parse(json, n, mesh, &c->mesh, (const char *const *)t->joint_names, t->n_joints,
                       out, err);
    free(json);
  }
  free(own);
  return s;
}

/* Whether c lies along the ground: its spine (HipCenter -> ShoulderCenter) more than 45 deg from
 * up, as a quadruped's rig has it. A human take's bone directions would stand such a body on its
 * hind legs, so `pose` drives it through the rig's retargeter instead. */
static bool lies_along_ground(const km_skeleton *s) {
  int hip = -1, sc = -1;
  for (size_t j = 0; j < s->n_joints; ++j) {
    if (s->names[j] && !strcmp(s->names[j], "HipCenter")) hip = (int)j;
    if (s->names[j] && !strcmp(s->names[j], "ShoulderCenter")) sc = (int)j;
  }
  if (hip < 0 || sc < 0) return false;
  const double *a = s->rest + 3 * hip, *b = s->rest + 3 * sc;
  double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  return len > 0 && d[1] < len * 0.70710678118654752; /* cos 45 deg */
}

/* Poses a skinned character along a take by linear blend skinning: the rig's skeleton is
 * driven by the take's joints (matched by name; a Kinect v1 rig takes any skeleton's by body
 * point): their directions turn the rig's bones, which keep their lengths, and the root goes
 * where the take has it (--exact-positions: every joint where the take has it). */
int km_cli_pose(int argc, char **argv) {
  const char *mesh = NULL, *rig = NULL, *motion = NULL, *out = NULL, *frame_format = NULL,
             *track_out = NULL;
  double fps = 0;
  size_t key_every = 0;
  bool compress = false;
  const char *export_kind = NULL;
  double max_error_mm = 0, scale = 0;
  bool keep_frame = false, exact = false, no_glitch = false, retarget = false, direct = false;
  const char *filter_kind = NULL;
  /* The mesh is brought into kinemesh's frame as animate brings it (the rig sidecar's
   * skeleton is stored in that frame); the output is in it, as animate's is. */
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      KM_CLI_MOTION_FRAME_OPTIONS(fo),
      {"mesh", 0, KM_OPT_STRING, &mesh, "rigged mesh (gen character, rig, or a skinned .glb)"},
      {"key-every", 0, KM_OPT_SIZE, &key_every, "glb: one morph target every N frames (default 1)"},
      KM_CLI_EXPORT_OPTIONS_HELP(
          export_kind, max_error_mm, compress,
          KM_CLI_EXPORT_HELP "; skeleton: the rig's own skeleton (its joints, named) and weights "
                             "with each frame's bone transforms, exact and with no fit"),
      {"rig", 0, KM_OPT_STRING, &rig,
       "its rig sidecar (default <mesh stem>.rig.json, else a glTF's own skin, else one made on "
       "the spot as kinemesh rig makes it)"},
      {"motion", 0, KM_OPT_STRING, &motion,
       "take: .json (kinemesh), .csv (Kinect v1 recording), .bvh; joints matched by name"},
      {"scale", 0, KM_OPT_DOUBLE, &scale,
       "performer-to-character scale: the take's positions are multiplied by it (default: the "
       "rig's bone lengths over the take's; 1 meets the take's positions as they are)"},
      {"fps", 0, KM_OPT_DOUBLE, &fps,
       "frame rate of the output; the motion is resampled (default: the take's)"},
      {"frame-format", 0, KM_OPT_STRING, &frame_format,
       "directory output: obj (default) or ply (binary) per frame"},
      {"exact-positions", 0, KM_OPT_FLAG, &exact,
       "put every joint where the take has it (default: the take turns the bones and the "
       "rig keeps their lengths, so a performer of other proportions does not pull the parts "
       "apart; the root goes where the take has it either way)"},
      {"retarget", 0, KM_OPT_FLAG, &retarget,
       "drive the skeleton through animate's retargeter (the rig's map, bone limits, aim, "
       "root motion, floor, glitch rejection and filter) and skin the skeleton it poses: what "
       "a skinned export of animate's motion shows (default for a body whose rig limits its "
       "limbs' swing, a quadruped's, a stubby-limbed or a seated body's, or that lies along "
       "the ground)"},
      {"direct", 0, KM_OPT_FLAG, &direct,
       "turn the skeleton's bones to the take's own directions, also on a quadruped (default "
       "for an upright body without a swing limit)"},
      {"no-glitch", 0, KM_OPT_FLAG, &no_glitch,
       "do not reject tracker glitches (jumps, bone-length outliers, re-found joints) before "
       "skinning (default: rejected as animate rejects them, so a lost hand does not throw the "
       "arm)"},
      {"filter", 0, KM_OPT_STRING, &filter_kind,
       "smooth the take's joints before skinning: holt or one_euro, as animate's filter with "
       "its defaults (default: none, the take as recorded, so a Kinect take's jitter and fast "
       "re-fits reach the mesh; with --retarget the rig's filter, as animate)"},
      {"output", 'o', KM_OPT_STRING, &out, "output: .glb, .pc2 or a directory"},
      {"keep-frame", 0, KM_OPT_FLAG, &keep_frame,
       ".pc2 and frame directories in the mesh file's own axes and units, as animate "
       "--keep-frame (default: kinemesh's frame; a .glb is always in glTF's, which is that one)"},
      {"track", 0, KM_OPT_STRING, &track_out,
       "also (or only) write the rig's landmarks per frame as a landmark track (.json/.csv) for "
       "posedb query, avatar and transfer --landmarks-xyz"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                       "kinemesh pose --mesh MESH [--rig RIG] --motion TAKE -o OUT [--track T]",
                       "Linear-blend-skinning playback of a take on a rigged character.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!mesh || !motion || (!out && !track_out))
    return km_cli_error("pose", "--mesh, --motion and -o (or --track) are required");
  if (retarget && direct)
    return km_cli_error("pose", "--retarget and --direct: give one of them, not both");
  if (retarget && exact)
    return km_cli_error("pose", "--exact-positions turns the bones to the take's joints; "
                                "--retarget poses them by the rig's retargeter: give one");
  km_anim_format af = 0;
  if (km_cli_parse_frame_format("pose", frame_format, &af)) return KM_EXIT_FAIL;
  int kf = km_cli_keep_frame_output("pose", out, keep_frame);
  if (kf) return kf;
  km_error err = {0};
  km_character c = {0};
  km_take t = {0};
  km_anim_writer *w = NULL;
  km_deform_check *dc = NULL;
  km_track trk = {0};
  double *pos_frame = NULL, *xf = NULL, *V = NULL, *seed = NULL, *clean = NULL;
  km_glitch *g = NULL;
  km_filter *jf = NULL;
  km_puppetry *pl = NULL;
  km_rig prig = {0};
  km_filter_options filt = {0};
  if (filter_kind && km_cli_parse_filter("pose", filter_kind, &filt)) return KM_EXIT_FAIL;
  km_frame mf = {KM_AXIS_POS_Y, KM_AXIS_POS_Z, 0}; /* the mesh file's frame (--keep-frame) */
  int *map = NULL;
  int rc = KM_EXIT_FAIL;
  if ((rc = km_cli_load_character_oriented("pose", mesh, rig, 0, &fo, &c, &mf))) goto done;
  if ((rc = km_cli_read_motion_for("pose", motion, &c.skeleton, &t))) goto done;
  if ((rc = km_cli_orient_take("pose", &fo, &t))) goto done;
  rc = KM_EXIT_FAIL;
  if (fps > 0 && fps != t.fps && t.n_frames > 0) { /* resample, do not relabel */
    km_take rs;
    if (km_take_resample(&t, fps, &rs, &err) != KM_OK) goto fail;
    km_take_free(&t);
    t = rs;
  }
  size_t nj = c.skeleton.n_joints;
  map = malloc(sizeof(int) * nj);
  pos_frame = malloc(sizeof(double) * 3 * nj);
  xf = malloc(sizeof(double) * 12 * nj);
  V = malloc(sizeof(double) * 3 * c.mesh.n_vertices);
  clean = malloc(sizeof(double) * 3 * (t.n_joints ? t.n_joints : 1));
  if (!map || !pos_frame || !xf || !V || !clean) {
    rc = km_cli_error("pose", "out of memory");
    goto done;
  }
  if ((rc = km_cli_map_joints("pose", &c.skeleton, &t, map))) goto done;
  rc = KM_EXIT_FAIL;
  /* The rig once: its handles name the places in the shape line, and --retarget runs its
   * retargeter. Turning the bones directly does not need it: an error there only loses the
   * names. */
  km_error rerr = {0};
  bool have_rig = pose_rig(mesh, rig, &c, &mf, &t, &prig, &rerr) == KM_OK;
  /* A body that cannot follow a person's bone directions is driven through its rig by
   * default: one whose rig limits its limbs' swing (kinemesh rig writes "swing_limit" for a
   * quadruped, a stubby-limbed and a seated body) or that lies along the ground. Turned to the
   * take's directions, a quadruped stands up on its hind legs and the elephant's legs swing as
   * far as a person's (cmu_131_01: longest edge 2.89x, 518 triangles folded; through its rig
   * 1.55x, none; dog0 3.52x -> 1.49x). An upright body of a person's proportions keeps the
   * take's own directions (FAUST 2.29x, through its rig 2.53x). */
  if (!retarget && !direct && !exact && have_rig &&
      (prig.swing_limit > 0 || lies_along_ground(&c.skeleton))) {
    retarget = true;
    if (prig.swing_limit > 0)
      fprintf(stderr,
              "kinemesh pose: %s: its rig limits how far its limbs swing (\"swing_limit\" %g: a "
              "quadruped's, a stubby-limbed or a seated body's), so the take drives it through "
              "the rig's retargeter, as animate does (--direct: the take's own bone "
              "directions)\n",
              mesh, prig.swing_limit);
    else
      fprintf(stderr,
              "kinemesh pose: %s lies along the ground (a quadruped's spine), so the take drives "
              "it through the rig's retargeter, as animate does (--direct: the take's own bone "
              "directions)\n",
              mesh);
  }
  if (retarget) {
    if (!have_rig) {
      err = rerr;
      goto fail;
    }
    if (prig.skeleton != KM_RIG_KINECT1 || nj != KM_KINECT1_JOINTS || !prig.joint_rest) {
      rc = km_cli_error("pose",
                        "--retarget needs a rig on the 20 Kinect v1 joints with their rest "
                        "positions (\"joints\"), as kinemesh rig and gen character write it");
      goto done;
    }
    /* animate's pipeline without its mesh solve: glitch rejection, the rig's filter (or
     * --filter), retarget with the rig's limits and root motion; the character's skeleton it
     * poses is skinned below */
    km_puppetry_options po = {0};
    if (filter_kind) po.filter = &filt;
    po.no_glitch = no_glitch;
    po.retarget.scale = scale;
    po.take_name = motion;
    po.fps = t.fps;
    po.joint_parents = t.parents;
    po.solver = KM_PUPPETRY_RETARGET;
    if (km_puppetry_create(&c.mesh, &prig, (const char *const *)t.joint_names, t.n_joints, &po, &pl,
                           NULL, &err) != KM_OK)
      goto fail;
  }
  /* A character in other units than the take's metres (a scan in centimetres, rigged with
   * no --units) or of another size: the take is scaled to it, as animate scales it. */
  if (!pl && !(scale > 0)) scale = performer_scale(&c.skeleton, &t, map);
  km_anim_options ao = {0};
  ao.fps = fps > 0 ? fps : t.fps;
  ao.key_every = key_every;
  ao.format = af;
  km_ssdr_options so;
  if (out) {
    if (km_cli_parse_export("pose", export_kind, max_error_mm, compress, out, &ao, &so)) goto done;
    /* The animation comes from a skeleton: its skinned parts seed the fit. */
    if (km_cli_skin_seeds("pose", &ao, &c.mesh, &c.skin, nj, &so, &seed)) goto done;
    /* --keep-frame: the writer takes each frame back into the file's axes and units */
    if (keep_frame) ao.frame = &mf;
    /* --export skeleton: the rig's own bones and weights, each frame's bone transforms pushed */
    ao.skeleton = &c.skeleton;
    ao.weights = &c.skin;
    if (km_anim_writer_open(out, &c.mesh, &ao, &w, &err) != KM_OK) goto fail;
    /* every frame checked against the rest mesh, as animate does: where skinning collapses */
    if (km_deform_check_create(&c.mesh, &dc, &err) != KM_OK) goto fail;
  }
  if (track_out) {
    trk.n_frames = t.n_frames;
    trk.n_landmarks = KM_CHARACTER_LANDMARKS;
    trk.fps = ao.fps;
    trk.names = calloc(KM_CHARACTER_LANDMARKS, sizeof *trk.names);
    trk.positions = malloc(sizeof(double) * 3 * KM_CHARACTER_LANDMARKS * (t.n_frames + 1));
    if (!trk.names || !trk.positions) {
      rc = km_cli_error("pose", "out of memory");
      goto done;
    }
    for (size_t l = 0; l < KM_CHARACTER_LANDMARKS; ++l)
      snprintf(trk.names[l], sizeof trk.names[l], "%s", c.landmarks[l].name);
  }
  /* Tracker glitches (a hand lost and re-found 0.6 m away) are rejected on the take's own
   * joints, in metres, before anything is built on them, as animate rejects them: skinning
   * follows a joint wherever it goes, and the armadillo on precog_Seq3_2 stepped 55 % of its
   * size in one frame. A clean capture (a BVH) has none: no move is faster than the limit and
   * no bone changes length. */
  if (!pl && !no_glitch) {
    km_glitch_options go = {0};
    go.fps = t.fps > 0 ? t.fps : 30;
    if (km_glitch_create(t.n_joints, t.parents, &go, &g, &err) != KM_OK) goto fail;
  }
  /* --filter: the joint filter animate runs after the glitch rejection, at the take's rate
   * (after --fps), on the take's own joints in metres. */
  if (!pl && filter_kind) {
    filt.fps = t.fps > 0 ? t.fps : 30;
    if (km_filter_create(t.n_joints, &filt, &jf, &err) != KM_OK) goto fail;
  }
  double floor_y = 0;
  bool floor_on = pl && km_puppetry_floor(pl, &floor_y);
  km_progress prog = km_cli_progress("pose");
  for (size_t f = 0; f < t.n_frames; ++f) {
    const double *raw = t.positions + f * t.n_joints * 3;
    if (pl) { /* the character's skeleton as the rig's retargeter posed it */
      if (km_puppetry_push(pl, raw, NULL, &err) != KM_OK) goto fail;
      km_puppetry_posed_joints(pl, pos_frame); /* a kinect1 rig with joints: checked above */
    } else { /* the take's own joints, glitches rejected and (--filter) smoothed */
      if (g) km_glitch_push(g, raw, clean);
      const double *in = g ? clean : raw;
      if (jf) {
        const bool *restarted = g ? km_glitch_restarted(g) : NULL;
        for (size_t j = 0; restarted && j < t.n_joints; ++j)
          if (restarted[j]) km_filter_restart_joint(jf, j);
        km_filter_push(jf, in, clean);
        in = clean;
      }
      for (size_t j = 0; j < nj; ++j)
        for (int a = 0; a < 3; ++a)
          pos_frame[3 * j + a] = map[j] < 0 ? NAN : scale * in[(size_t)map[j] * 3 + a];
    }
    if ((pl || exact
             ? km_skeleton_pose_from_positions(&c.skeleton, pos_frame, xf, &err)
             : km_skeleton_pose_from_directions(&c.skeleton, pos_frame, xf, &err)) != KM_OK ||
        km_lbs(c.mesh.V, c.mesh.n_vertices, &c.skin, xf, nj, V, &err) != KM_OK)
      goto fail;
    if (floor_on) {
      /* The rig's floor (retargeted only): the retargeter keeps the ankles above their rest
       * height, but a tilted paw's toes can still dip under it (dog0 on precog_Seq1_1: 1.4
       * units, 0.7 % of its size, in 29 frames). The whole mesh is raised by that much, as an
       * engine grounds a character; holding those vertices on the floor one by one, as animate
       * does with its solved mesh's few, pressed the skinned paw flat (edges 0.05x, 88
       * triangles folded). */
      double lift = km_cli_floor_lift(V, c.mesh.n_vertices, floor_y);
      for (size_t j = 0; lift > 0 && j < nj; ++j)
        xf[12 * j + 7] += lift; /* the bones carry the lift (--export skeleton) */
    }
    if (w && (km_anim_writer_push_pose(w, V, xf, &err) != KM_OK ||
              km_deform_check_add(dc, V, NULL, &err) != KM_OK))
      goto fail;
    for (size_t l = 0; track_out && l < KM_CHARACTER_LANDMARKS; ++l)
      memcpy(trk.positions + 3 * (f * KM_CHARACTER_LANDMARKS + l),
             V + 3 * (size_t)c.landmarks[l].vertex, 3 * sizeof(double));
    prog.fn((double)(f + 1) / (double)t.n_frames, "skinning", NULL);
  }
  km_anim_report rep;
  if (w && km_anim_writer_finish(&w, &rep, &err) != KM_OK) goto fail;
  if (track_out && km_track_write(track_out, &trk, &err) != KM_OK) goto fail;
  km_cli_progress_done();
  if (out) km_cli_report_export("pose", &rep);
  char shape_line[1024] = "";
  /* places named by the rig's handles (else vertex ids) */
  if (dc) km_cli_shape_line(dc, &c.mesh, have_rig ? &prig : NULL, shape_line, sizeof shape_line);
  if (g || (pl && !no_glitch)) {
    km_glitch_stats gs;
    char glitch_line[256];
    if (g)
      km_glitch_stats_get(g, &gs);
    else
      km_puppetry_glitch_stats(pl, &gs);
    km_cli_glitch_line(&gs, pl ? "joints whose start was the glitch, reference redone" : NULL,
                       glitch_line, sizeof glitch_line);
    fputs(glitch_line, stderr);
  }
  if (pl) scale = km_puppetry_scale(pl);
  fputs(shape_line, stderr);
  fprintf(stderr, "kinemesh pose: %zu frames of %zu vertices, scale %.4g -> %s%s%s\n", t.n_frames,
          c.mesh.n_vertices, scale, out ? out : "", out && track_out ? ", landmark track " : "",
          track_out ? track_out : "");
  rc = KM_EXIT_OK;
  goto done;
fail:
  rc = km_cli_fail("pose", &err);
done:
  km_anim_writer_free(&w);
  km_deform_check_free(&dc);
  km_glitch_free(&g);
  km_filter_free(&jf);
  km_puppetry_free(&pl);
  km_rig_free(&prig);
  free(clean);
  km_track_free(&trk);
  free(map);
  free(pos_frame);
  free(seed);
  free(xf);
  free(V);
  km_take_free(&t);
  km_character_free(&c);
  return rc;
}
