/* kinemesh gen: the built-in inputs.
 *   kinemesh gen character   a procedural character (mesh + rig sidecar)
 *   kinemesh gen motion      a motion take (walk, wave, kungfu) for a character's skeleton
 *   kinemesh gen capture     simulated multi-view depth capture of an animated character */
#include "cli.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* --shape takes a preset name or key=value pairs: "stocky", "height=1.6,girth=1.3,belly=0.6". */
static int parse_shape(const char *shape, km_character_options *co) {
  static const struct {
    const char *name;
    double height, girth, belly;
  } presets[] = {
      {"default", 1.75, 1.0, 0.0}, {"tall", 1.92, 0.9, 0.0}, {"short", 1.58, 1.05, 0.1},
      {"stocky", 1.70, 1.3, 0.5},  {"slim", 1.80, 0.8, 0.0}, {"belly", 1.74, 1.1, 1.0},
  };
  for (size_t i = 0; i < sizeof presets / sizeof presets[0]; ++i)
    if (!strcmp(shape, presets[i].name)) {
      co->height = presets[i].height;
      co->girth = presets[i].girth;
      co->belly = presets[i].belly;
      return 0;
    }
  char buf[256];
  snprintf(buf, sizeof buf, "%s", shape);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    char *eq = strchr(tok, '=');
    if (!eq) return -1;
    *eq = '\0';
    char *end;
    double v = strtod(eq + 1, &end);
    if (*end || !(v == v)) return -1;
    if (!strcmp(tok, "height"))
      co->height = v;
    else if (!strcmp(tok, "girth"))
      co->girth = v;
    else if (!strcmp(tok, "belly"))
      co->belly = v;
    else
      return -1;
  }
  return 0;
}

static int gen_character(int argc, char **argv) {
  size_t vertices = 20000;
  size_t seed = 0;
  const char *shape = NULL, *out = NULL, *weights = NULL;
  const km_cli_opt opts[] = {
      {"vertices", 'n', KM_OPT_SIZE, &vertices,
       "target vertex count, 2000..1000000 (+-10%, default 20000)"},
      {"weights", 0, KM_OPT_STRING, &weights,
       "skin weights of the sidecar: heat (default: bone heat around the character's own "
       "skeleton, as kinemesh rig weights a mesh) or primitive (the generator's: distance to "
       "its body parts, blended over a narrow band)"},
      {"seed", 0, KM_OPT_SIZE, &seed, "per-subject variation of proportions (default 0)"},
      {"shape", 0, KM_OPT_STRING, &shape,
       "preset (default, tall, short, stocky, slim, belly) or height=M,girth=F,belly=B"},
      {"output", 'o', KM_OPT_STRING, &out,
       "output mesh (.obj/.ply/.off); rig goes to <stem>.rig.json"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                       "kinemesh gen character [--vertices N] [--seed S] [--shape ...] -o char.obj",
                       "A closed, manifold humanoid around a Kinect v1 skeleton (T-pose, y up,\n"
                       "facing +z, metres), with a rig sidecar: skeleton, LBS weights, 16\n"
                       "landmarks and a default puppetry rig (head, hands, feet).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!out) return km_cli_error("gen character", "-o OUTPUT is required");
  bool heat = !weights || !strcmp(weights, "heat");
  if (!heat && strcmp(weights, "primitive"))
    return km_cli_error("gen character", "--weights '%s': expected heat or primitive", weights);
  km_character_options co = {0};
  co.target_vertices = vertices;
  co.seed = seed;
  if (shape && parse_shape(shape, &co) != 0)
    return km_cli_error("gen character",
                        "--shape '%s': expected a preset (default, tall, short, "
                        "stocky, slim, belly) or height=M,girth=F,belly=B",
                        shape);
  co.progress = km_cli_progress("character");
  km_error err = {0};
  km_character c = {0};
  double t0 = km_cli_now();
  if (km_character_generate(&co, &c, &err) != KM_OK) return km_cli_fail("gen character", &err);
  km_cli_progress_done();
  if (heat) {
    /* The generator's weights fall off over a narrow band from each body part, so linear
     * blend skinning creases the skin where two parts meet and stretches the hip and shoulder
     * (pose on cmu_131_01, 20k vertices: longest edge 3.84x near the thigh, an edge over 1.5x
     * in every frame). Bone heat around the same skeleton (km_autorig given the joints: what
     * `rig` computes for a mesh, its heat constant probed) follows the surface: 1.88x. */
    km_autorig_options ao = {0};
    ao.skeleton = KM_AUTORIG_KINECT1;
    ao.joints = c.skeleton.rest;
    ao.progress = km_cli_progress("skin");
    km_character hc = {0};
    km_status hs = km_autorig(&c.mesh, &ao, &hc, NULL, &err);
    km_cli_progress_done();
    if (hs != KM_OK) {
      km_character_free(&c);
      return km_cli_fail("gen character", &err);
    }
    km_skin t = c.skin;
    c.skin = hc.skin;
    hc.skin = t;
    km_character_free(&hc);
  }
  double t1 = km_cli_now();
  int rc = KM_EXIT_OK;
  char *rig = km_cli_rig_path(out);
  if (!rig)
    rc = km_cli_error("gen character", "out of memory");
  else if (km_mesh_write(out, &c.mesh, NULL, &err) != KM_OK ||
           km_character_write_rig(rig, &c, &err) != KM_OK)
    rc = km_cli_fail("gen character", &err);
  else
    fprintf(stderr, "kinemesh gen character: %zu vertices, %zu triangles in %.2f s -> %s, %s\n",
            c.mesh.n_vertices, c.mesh.n_faces, t1 - t0, out, rig);
  free(rig);
  km_character_free(&c);
  return rc;
}

/* km_cli_load_character; *own: the character is a skinned glTF's own skin; unrigged (may be
 * NULL: then a missing rig file is an error): set when no rig is given and MESH has no
 * <stem>.rig.json, with only c->mesh read (the caller rigs it once it is in kinemesh's frame). */
static km_status load_character(const char *mesh, const char *rig, size_t vertices, km_character *c,
                                bool *own, bool *unrigged, km_error *err) {
  *own = false;
  if (unrigged) *unrigged = false;
  if (!mesh) {
    km_character_options co = {0};
    co.target_vertices = vertices;
    return km_character_generate(&co, c, err);
  }
  km_status s = km_cli_skin_character("template", mesh, rig, c, own, err);
  if (s != KM_OK || *own) return s;
  char *rig_path = rig ? NULL : km_cli_rig_path(mesh);
  if (!rig && !rig_path) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  s = km_mesh_read(mesh, &c->mesh, err);
  if (s == KM_OK && !rig && access(rig_path, F_OK) != 0) {
    if (unrigged)
      *unrigged = true;
    else
      s = km_error_set(err, KM_ERR_IO, "%s has no rig (%s): make one with kinemesh rig %s", mesh,
                       rig_path, mesh);
  } else if (s == KM_OK)
    s = km_character_read_rig(rig ? rig : rig_path, c->mesh.n_vertices, c, err);
  free(rig_path);
  return s;
}

km_status km_cli_load_character(const char *mesh, const char *rig, size_t vertices, km_character *c,
                                km_error *err) {
  bool own;
  return load_character(mesh, rig, vertices, c, &own, NULL, err);
}

int km_cli_load_character_oriented(const char *verb, const char *mesh, const char *rig,
                                   size_t vertices, const km_cli_frame_opts *fo, km_character *c,
                                   km_frame *f) {
  km_frame id = {KM_AXIS_POS_Y, KM_AXIS_POS_Z, 0}, fr = id;
  if (f) *f = id;
  km_error err = {0};
  bool own = false, unrigged = false;
  if (load_character(mesh, rig, vertices, c, &own, &unrigged, &err) != KM_OK)
    return km_cli_fail(verb, &err);
  if (!mesh) return 0;
  km_cli_frame_opts o = fo ? *fo : (km_cli_frame_opts){0};
  if (!o.rig) o.rig = rig;
  int rc = km_cli_mesh_frame(verb, mesh, &o, &c->mesh, false, &fr, NULL);
  if (rc) return rc;
  if (!own && !unrigged) {
    /* The sidecar's joints are in kinemesh's axes and in the unit its "frame" records (the
     * file's own when none): --units other than that one rescales them with the mesh. */
    double k = (fr.scale > 0 ? fr.scale : 1) / km_cli_sidecar_scale(mesh, o.rig);
    for (size_t i = 0; k != 1 && i < 3 * c->skeleton.n_joints; ++i)
      c->skeleton.rest[i] *= k;
  }
  if (!km_frame_is_identity(&fr)) { /* else already kinemesh's frame: kept bit for bit */
    if (km_mesh_frame_apply(&fr, &c->mesh, &err) != KM_OK ||
        (own &&
         km_frame_apply(&fr, c->skeleton.rest, c->skeleton.n_joints, NULL, 0, &err) != KM_OK))
      return km_cli_fail(verb, &err);
    if (f) *f = fr;
  }
  if (unrigged) { /* no rig file: one made on the spot, in kinemesh's frame */
    char *def = km_cli_rig_path(mesh);
    km_mesh m = c->mesh;
    c->mesh = (km_mesh){0}; /* km_cli_auto_rig frees *c, and the character copies m */
    km_status s = km_cli_auto_rig(verb, mesh, def ? def : "<stem>.rig.json", &m, stderr, NULL, c,
                                  NULL, NULL, &err);
    km_mesh_free(&m);
    free(def);
    if (s != KM_OK) return km_cli_fail(verb, &err);
  }
  return 0;
}

static int gen_motion(int argc, char **argv) {
  const char *kind = "kungfu", *out = NULL, *rig = NULL, *character = NULL;
  size_t frames = 150;
  /* The character is brought into kinemesh's frame as animate brings it (a mesh with no rig
   * file is rigged on the spot, and needs its up axis for that); the take is in that frame. */
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      {"kind", 0, KM_OPT_STRING, &kind, "walk, wave or kungfu (default kungfu)"},
      {"frames", 'f', KM_OPT_SIZE, &frames, "number of frames at 30 Hz (default 150)"},
      {"character", 'c', KM_OPT_STRING, &character,
       "character mesh whose skeleton to use (default: the canonical one)"},
      {"rig", 0, KM_OPT_STRING, &rig, "its rig sidecar (default <character stem>.rig.json)"},
      {"output", 'o', KM_OPT_STRING, &out, "output take (.json)"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
      "kinemesh gen motion --kind walk|wave|kungfu --frames F [--character CHAR] -o take.json",
      "A skeleton take of the 20 Kinect v1 joints (metres, 30 Hz) for a character.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!out) return km_cli_error("gen motion", "-o OUTPUT is required");
  km_motion_kind mk;
  if (!strcmp(kind, "walk"))
    mk = KM_MOTION_WALK;
  else if (!strcmp(kind, "wave"))
    mk = KM_MOTION_WAVE;
  else if (!strcmp(kind, "kungfu"))
    mk = KM_MOTION_KUNGFU;
  else
    return km_cli_error("gen motion", "--kind must be walk, wave or kungfu, not '%s'", kind);
  if (frames < 1) return km_cli_error("gen motion", "--frames must be at least 1");
  km_error err = {0};
  km_character c = {0};
  km_take t = {0};
  int rc = km_cli_load_character_oriented("gen motion", character, rig, 2000, &fo, &c, NULL);
  if (rc) {
    km_character_free(&c);
    return rc;
  }
  if (km_motion_generate(&c.skeleton, mk, frames, &t, &err) != KM_OK ||
      km_take_write(out, &t, &err) != KM_OK)
    rc = km_cli_fail("gen motion", &err);
  else
    fprintf(stderr, "kinemesh gen motion: %s, %zu frames at %g Hz -> %s\n", kind, t.n_frames, t.fps,
            out);
  km_take_free(&t);
  km_character_free(&c);
  return rc;
}

int km_cli_gen_capture(int argc, char **argv) {
  const char *character = NULL, *rig = NULL, *kind = "kungfu", *out = NULL, *motion = NULL;
  size_t frames = 60, cameras = 8, points = 30000, seed = 1, vertices = 8000;
  double noise = 2;
  /* The subject is brought into kinemesh's frame as animate brings it, the take by
   * --motion-up/--motion-forward; the clouds and the truth are written in kinemesh's frame
   * (y up, facing +z, metres), as reconstruct's output is. */
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      KM_CLI_MOTION_FRAME_OPTIONS(fo),
      {"character", 'c', KM_OPT_STRING, &character,
       "subject mesh (default: procedural, --vertices); its rig sidecar, a glTF's own skin, or "
       "one made on the spot as kinemesh rig makes it"},
      {"rig", 0, KM_OPT_STRING, &rig, "its rig sidecar (default <stem>.rig.json)"},
      {"vertices", 'n', KM_OPT_SIZE, &vertices, "procedural subject size (default 8000)"},
      {"motion", 'm', KM_OPT_STRING, &motion,
       "take to perform (.json/.csv/.bvh; default: generated --kind)"},
      {"kind", 0, KM_OPT_STRING, &kind, "generated motion: walk, wave or kungfu (default kungfu)"},
      {"frames", 'f', KM_OPT_SIZE, &frames, "frames (default 60; with --motion: all of the take)"},
      {"cameras", 0, KM_OPT_SIZE, &cameras, "depth cameras on a ring (default 8)"},
      {"points", 0, KM_OPT_SIZE, &points, "points per frame over all cameras (default 30000)"},
      {"noise-mm", 0, KM_OPT_DOUBLE, &noise, "Gaussian noise sigma in mm (default 2, 0: none)"},
      {"seed", 0, KM_OPT_SIZE, &seed, "noise seed (default 1)"},
      {"output", 'o', KM_OPT_STRING, &out, "output directory"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
      "kinemesh gen capture --character CHAR --motion TAKE [--cameras 8] [--noise-mm 2] -o DIR",
      "Ray-casts the animated character from depth cameras (Embree): one binary\n"
      "PLY point cloud per frame with occlusion holes and noise, plus the\n"
      "ground truth as DIR/truth.pc2 (faces: DIR/truth_rest.obj, which a\n"
      "directory or 'DIR/*.ply' given to reconstruct does not read as a frame),\n"
      "all in kinemesh's frame (y up, facing +z, metres).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!out) return km_cli_error("gen capture", "-o DIR is required");
  km_motion_kind mk = !strcmp(kind, "walk")     ? KM_MOTION_WALK
                      : !strcmp(kind, "wave")   ? KM_MOTION_WAVE
                      : !strcmp(kind, "kungfu") ? KM_MOTION_KUNGFU
                                                : (km_motion_kind)-1;
  if ((int)mk < 0) return km_cli_error("gen capture", "--kind '%s': walk, wave or kungfu", kind);
  km_error err = {0};
  km_character c = {0};
  km_take take = {0};
  int rc = KM_EXIT_OK;
  km_capture_options co = {.cameras = (int)cameras,
                           .points_per_frame = points,
                           .noise_mm = noise > 0 ? noise : -1,
                           .seed = seed};
  double t0 = km_cli_now();
  if ((rc = km_cli_load_character_oriented("gen capture", character, rig, vertices, &fo, &c, NULL)))
    goto done;
  if (motion) {
    if ((rc = km_cli_read_motion_for("gen capture", motion, &c.skeleton, &take))) goto done;
  } else if (km_motion_generate(&c.skeleton, mk, frames, &take, &err)) {
    rc = km_cli_fail("gen capture", &err);
    goto done;
  }
  if (motion && (rc = km_cli_orient_take("gen capture", &fo, &take))) goto done;
  co.progress = km_cli_progress("capture");
  if (km_capture_simulate(&c, &take, &co, out, &err))
    rc = km_cli_fail("gen capture", &err);
  else
    fprintf(stderr,
            "kinemesh gen capture: %zu frames in %.1f s -> %s/frame_*.ply, truth.pc2, "
            "truth_rest.obj\n",
            take.n_frames, km_cli_now() - t0, out);
  km_cli_progress_done();
done:
  km_take_free(&take);
  km_character_free(&c);
  return rc;
}

int km_cli_gen(int argc, char **argv) {
  if (argc >= 2 && !strcmp(argv[1], "character")) return gen_character(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "motion")) return gen_motion(argc - 1, argv + 1);
  if (argc >= 2 && !strcmp(argv[1], "capture")) return km_cli_gen_capture(argc - 1, argv + 1);
  FILE *f = (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) ? stdout : stderr;
  fprintf(f, "usage: kinemesh gen character [options] -o char.obj\n"
             "       kinemesh gen motion --kind walk|wave|kungfu --frames F -o take.json\n"
             "       kinemesh gen capture --character CHAR --motion TAKE -o FRAMES/\n"
             "(kinemesh gen character --help, kinemesh gen motion --help for options)\n");
  return f == stdout ? KM_EXIT_OK : KM_EXIT_USAGE;
}
