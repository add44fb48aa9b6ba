/* kinemesh rig: automatic rigging of a mesh (km_autorig) -> rig sidecar
 * (km_character_write_rig). */
#include "cli.h"

#include <cjson/cJSON.h>

#include <stdlib.h>
#include <string.h>

/* The sidecar of c, with a "frame" record ({"up", "forward", "scale"}) when the mesh was
 * oriented (km_cli_mesh_frame reads it back). */
static int write_sidecar(const char *path, const km_character *c, const km_frame *f) {
  km_error err = {0};
  if (!f) return km_character_write_rig(path, c, &err) != KM_OK ? km_cli_fail("rig", &err) : 0;
  char *json = NULL;
  size_t size = 0;
  if (km_character_rig_json(c, &json, &size, &err) != KM_OK) return km_cli_fail("rig", &err);
  cJSON *doc = cJSON_ParseWithLength(json, size), *fr = cJSON_CreateObject();
  free(json);
  json = NULL;
  if (doc && fr && cJSON_AddStringToObject(fr, "up", km_axis_name(f->up)) &&
      cJSON_AddStringToObject(fr, "forward", km_axis_name(f->forward)) &&
      (f->scale == 0 || cJSON_AddNumberToObject(fr, "scale", f->scale))) {
    cJSON_AddItemToObject(doc, "frame", fr);
    fr = NULL;
    json = cJSON_Print(doc);
  }
  cJSON_Delete(fr);
  cJSON_Delete(doc);
  if (!json) return km_cli_error("rig", "out of memory");
  km_status s = km_write_file_atomic(path, json, strlen(json), &err);
  free(json);
  return s != KM_OK ? km_cli_fail("rig", &err) : 0;
}

int km_cli_rig(int argc, char **argv) {
  const char *out = NULL, *skel = NULL, *weights = NULL;
  double min_ext = 0;
  const char *head_s = NULL;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      {"output", 'o', KM_OPT_STRING, &out, "rig sidecar to write (default MESH.rig.json)"},
      {"skeleton", 0, KM_OPT_STRING, &skel,
       "auto (default: a skinned glTF's own skin, else a bust when it has an open cut at its "
       "bottom or sits on a broad base (an upper body when a hand reaches out from it on either "
       "side), else humanoid or quadruped from the extremities, else prop), kinect1 (humanoid), "
       "quadruped, prop (handles by position), bust, upper or resting (a body lying or curled "
       "up: the head turns with the neck, the body stays; with --head)"},
      {"head", 0, KM_OPT_STRING, &head_s,
       "--skeleton resting: the vertex id at the tip of the head (an ear tip, the top of a "
       "skull, a snout; kinemesh pick --near x,y,z or the live page's hover shows ids; default: "
       "the most prominent extremity)"},
      {"weights", 0, KM_OPT_STRING, &weights,
       "skin weights: heat (the default: bone heat, diffused along the surface from each "
       "vertex's nearest visible bone, Baran & Popovic), distance (by the distance to the "
       "bones in space) or reach (distance, limited along the surface)"},
      {"min-extremity", 0, KM_OPT_DOUBLE, &min_ext,
       "extremity prominence as a fraction of the largest extent (default 0.2)"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                       "kinemesh rig MESH [-o MESH.rig.json] "
                       "[--skeleton auto|kinect1|quadruped|prop|bust|upper|resting [--head V]] "
                       "[--weights heat|distance|reach] [--up +z --forward -y]",
                       "Rigs a mesh kinemesh did not make: finds its extremities (geodesic\n"
                       "extremes), embeds the 20 Kinect v1 joints in its interior, computes\n"
                       "skin weights and the 16 landmarks, and writes the rig sidecar that\n"
                       "animate, live, pose and reconstruct read (skeleton, skin, landmarks and\n"
                       "a puppetry rig: handles at the head, hands and feet). A quadruped's\n"
                       "front limbs take the hands, its hind limbs the feet, its highest other\n"
                       "extremity the head. A bust (an open cut at its bottom) or a body sitting\n"
                       "on a broad base (a sitting rabbit: its bottom 5 % one part, half as\n"
                       "wide and deep as the mesh) gets a head handle that turns with the\n"
                       "performer's neck and a base that stays; with a hand reaching out on\n"
                       "either side (an upper body: a VR avatar) its arms move as a humanoid's\n"
                       "too. A mesh with none of these (an object) gets five handles by\n"
                       "position: highest -> head, upper sides -> hands, lower sides -> feet.\n"
                       "The mesh is rigged in kinemesh's frame (y up, facing +z): its up and\n"
                       "forward axes come from --up/--forward, else are guessed (printed); the\n"
                       "sidecar records them (\"frame\") and holds the joints in that frame, so\n"
                       "animate and live orient the mesh the same way. A skinned glTF is rigged\n"
                       "from its own skeleton and weights (joint names mapped from Mixamo, VRM /\n"
                       "Unity HumanBodyBones or rigify) unless --skeleton names another.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("rig", "expected one MESH");
  km_autorig_options o = {0};
  if (!skel || !strcmp(skel, "auto"))
    o.skeleton = KM_AUTORIG_AUTO;
  else if (!strcmp(skel, "kinect1") || !strcmp(skel, "humanoid"))
    o.skeleton = KM_AUTORIG_KINECT1;
  else if (!strcmp(skel, "quadruped"))
    o.skeleton = KM_AUTORIG_QUADRUPED;
  else if (!strcmp(skel, "prop"))
    o.skeleton = KM_AUTORIG_PROP;
  else if (!strcmp(skel, "bust"))
    o.skeleton = KM_AUTORIG_BUST;
  else if (!strcmp(skel, "upper"))
    o.skeleton = KM_AUTORIG_UPPER;
  else if (!strcmp(skel, "resting"))
    o.skeleton = KM_AUTORIG_RESTING;
  else
    return km_cli_error(
        "rig", "--skeleton %s: expected auto, kinect1, quadruped, prop, bust, upper or resting",
        skel);
  if (km_cli_parse_weights("rig", weights, &o.skin)) return KM_EXIT_USAGE;
  o.min_extremity = min_ext;
  int32_t head = -1;
  if (head_s) {
    char *end = NULL;
    long hv = strtol(head_s, &end, 10);
    if (!*head_s || *end || hv < 0 || hv > INT32_MAX)
      return km_cli_error("rig", "--head %s: expected a vertex id (0, 1, 2, ...)", head_s);
    if (o.skeleton != KM_AUTORIG_RESTING)
      return km_cli_error("rig", "--head is for --skeleton resting (a body lying or curled up)");
    head = (int32_t)hv;
    o.head = &head;
  }
  km_error err = {0};
  km_mesh m = {0};
  km_character c = {0};
  km_autorig_report rep;
  char *def = out ? NULL : km_cli_rig_path(pos[0]);
  const char *path = out ? out : def;
  int rc = KM_EXIT_OK;
  km_mesh_skin sk = {0};
  km_frame frame = {0};
  bool oriented = false, autorigged = false;
  if (km_mesh_read_skinned(pos[0], &m, &sk, &err) != KM_OK) {
    rc = km_cli_fail("rig", &err);
    goto done;
  }
  if (sk.n_joints && o.skeleton == KM_AUTORIG_AUTO) { /* a skinned glTF: its own skeleton */
    km_skin_mapping map;
    km_status ss = km_character_from_skin(&m, &sk, &c, &map, &err);
    if (ss != KM_OK) {
      rc = km_cli_fail("rig", &err);
      goto done;
    }
    printf("%s: %zu vertices, rigged from its own skin (%zu joints, %zu merged into an "
           "ancestor's weights):\n",
           pos[0], m.n_vertices, sk.n_joints, map.n_merged);
    if (map.n_still)
      printf("  %zu vertices weighted only to joints above the hips (the armature's root) or to "
             "none (a ground plane?): no influence, they stay where they are\n",
             map.n_still);
    for (size_t j = 0; j < c.skeleton.n_joints; ++j)
      printf("  %-14s <- %-28s (%8.4f %8.4f %8.4f)\n", c.skeleton.names[j],
             map.source[j][0] ? map.source[j] : "(derived)", c.skeleton.rest[3 * j],
             c.skeleton.rest[3 * j + 1], c.skeleton.rest[3 * j + 2]);
    goto write;
  }
  /* Orientation: the mesh is rigged in kinemesh's frame (a z-up scan rigged as if y were up
   * puts both legs on its tail); the sidecar records the frame for the verbs that orient. */
  if ((rc = km_cli_mesh_frame("rig", pos[0], &fo, &m, false, &frame, NULL))) goto done;
  oriented = !km_frame_is_identity(&frame);
  if (oriented && km_mesh_frame_apply(&frame, &m, &err) != KM_OK) {
    rc = km_cli_fail("rig", &err);
    goto done;
  }
  if (km_autorig(&m, &o, &c, &rep, &err) != KM_OK) {
    rc = km_cli_fail("rig", &err);
    goto done;
  }
  autorigged = true;
  if (rep.fallback[0]) printf("not a humanoid or quadruped (%s): rigged as a prop\n", rep.fallback);
  printf("%s: %zu vertices, height %.4g, rigged as %s in %.3f s\n", pos[0], m.n_vertices,
         rep.height,
         rep.kind == KM_AUTORIG_QUADRUPED ? "a quadruped"
         : rep.kind == KM_AUTORIG_PROP    ? "a prop (handles by position)"
         : rep.kind == KM_AUTORIG_BUST    ? "a bust or seated body (the head turns with the "
                                            "neck, the base stays)"
         : rep.kind == KM_AUTORIG_RESTING ? "a resting body, lying or curled up (the head turns "
                                            "with the neck, the body stays)"
         : rep.kind == KM_AUTORIG_UPPER   ? "an upper body (head and arms move, the base "
                                            "stays)"
                                          : "a humanoid (kinect1)",
         rep.seconds);
  if (rep.loose_pieces) {
    size_t nl = rep.loose_pieces, nr = rep.rigid_pieces;
    size_t ng = rep.ground_pieces; /* found in kinemesh's frame, y up */
    if (ng == nl)                  /* only a ground plane (or several) */
      printf("%zu loose piece%s (%zu vertices) lie%s on the floor (a ground plane?): the skin "
             "leaves %s out, so %s where %s in animate, live, pose and a skinned export (bound "
             "to the armature's root)\n",
             nl, nl > 1 ? "s" : "", rep.loose_vertices, nl > 1 ? "" : "s", nl > 1 ? "them" : "it",
             nl > 1 ? "they stay" : "it stays", nl > 1 ? "they lie" : "it lies");
    else {
      printf("%zu loose piece%s (%zu vertices: eyes, teeth, ...) follow%s the body where %s", nl,
             nl > 1 ? "s" : "", rep.loose_vertices, nl > 1 ? "" : "s",
             nl > 1 ? "they sit" : "it sits");
      km_cli_pieces_how(stdout, nl, nr);
    }
    if (ng && ng < nl)
      printf("  but %zu of them lie%s on the floor (a ground plane?): the skin leaves %s out, so "
             "%s where %s in animate, live, pose and a skinned export (bound to the armature's "
             "root)\n",
             ng, ng > 1 ? "" : "s", ng > 1 ? "them" : "it", ng > 1 ? "they stay" : "it stays",
             ng > 1 ? "they lie" : "it lies");
  }
  printf(rep.kind == KM_AUTORIG_PROP ? "extremities and handle points:\n"
                                     : "extremities (geodesic extremes, most prominent first):\n");
  for (size_t e = 0; e < rep.n_extremities; ++e) {
    const double *p = m.V + 3 * (size_t)rep.extremity[e];
    printf("  vertex %-8d at (%8.4f %8.4f %8.4f)  prominence %.4f  %s\n", (int)rep.extremity[e],
           p[0], p[1], p[2], rep.extremity_distance[e], rep.role[e][0] ? rep.role[e] : "(unused)");
  }
  printf("joints%s:\n", oriented ? " (in kinemesh's frame: y up, facing +z)" : "");
  if (rep.joints_moved_inside)
    printf("  (%d joint%s the embedding put outside the surface moved into the body)\n",
           rep.joints_moved_inside, rep.joints_moved_inside > 1 ? "s" : "");
  if (rep.joints_outside) {
    printf("  (outside the surface, left where the embedding put them:");
    for (int j = 0; j < 32; ++j)
      if (rep.joints_outside >> j & 1u) printf(" %s", km_kinect1_joint_name(j));
    printf("; their \"rest\" in the sidecar's \"joints\" can be edited)\n");
  }
  for (size_t j = 0; j < c.skeleton.n_joints; ++j)
    printf("  %-14s (%8.4f %8.4f %8.4f)\n", c.skeleton.names[j], c.skeleton.rest[3 * j],
           c.skeleton.rest[3 * j + 1], c.skeleton.rest[3 * j + 2]);
  printf("skin weights: %s\n",
         rep.skin == KM_AUTORIG_SKIN_HEAT
             ? "bone heat (diffused along the surface from each vertex's nearest visible bone; "
               "--weights distance or reach for the others)"
         : rep.skin == KM_AUTORIG_SKIN_REACH
             ? "by distance to the bones, each limited by its reach along the surface"
             : "by distance to the bones");
  if (rep.skin == KM_AUTORIG_SKIN_HEAT && rep.heat_probe[0] > 0)
    printf("  heat constant c %g: the skin's worst edge in %d probe poses of the skeleton, mean "
           "%.2fx at c 1, %.2fx at c 0.5 (0.5 is kept when 4 %% lower)\n",
           rep.heat_c, rep.heat_probe_poses, rep.heat_probe[0], rep.heat_probe[1]);
write:
  /* The frame is recorded also when it is kinemesh's own (y up, facing +z): a mesh whose guess
   * was wrong and was rigged with --up +y --forward +z was otherwise guessed again, wrongly, by
   * every verb that read it with this sidecar (npt_13_643, a body leaning back on one leg,
   * guessed z up: animated lying on its back, rigged as a quadruped). */
  if ((rc = write_sidecar(path, &c, frame.up && frame.forward ? &frame : NULL))) goto done;
  /* The puppetry rig in the sidecar must resolve on the mesh (handles apart, in range). */
  km_rig rig = {0};
  if (km_rig_read(path, &m, NULL, 0, &rig, &err) != KM_OK) {
    fprintf(stderr, "kinemesh rig: wrote %s, but its puppetry handles do not resolve: %s\n", path,
            err.message);
    rc = KM_EXIT_FAIL;
    goto done;
  }
  for (size_t h = 0; h < rig.n_handles; ++h)
    printf("%shandle %s: %zu vertices", h ? ", " : "", rig.handles[h].name,
           rig.handles[h].n_vertices);
  printf("\n");
  if (autorigged)
    km_cli_warn_point_handles("rig", pos[0], &rig, km_autorig_kind_name(rep.kind),
                              frame.up != KM_AXIS_NONE ? km_axis_name(frame.up) : "+y", stderr);
  /* the limits the puppetry applies, so the user knows what to edit for a wider range */
  if (rig.bend_limit > 0 || rig.swing_limit > 0 || rig.upper_limb_limit > 0 ||
      rig.girdle_limit > 0 || rig.max_turn > 0) {
    printf("limits:");
    const char *sep = "";
    if (rig.bend_limit > 0) {
      printf(" elbows and knees bend at most %g deg (\"bend_limit\")", rig.bend_limit);
      sep = ";";
    }
    if (rig.swing_limit > 0) {
      printf("%s every bone swings at most %g deg from where its parent carries it "
             "(\"swing_limit\": 30 for a body that is not upright, 12 for stubby limbs, 45 for a "
             "bust's neck)",
             sep, rig.swing_limit);
      sep = ";";
    }
    if (rig.upper_limb_limit > 0) {
      printf("%s upper arms and thighs at most %g deg (\"upper_limb_limit\")", sep,
             rig.upper_limb_limit);
      sep = ";";
    }
    if (rig.girdle_limit > 0) {
      printf("%s shoulders and hips, which carry the limbs, turn at most %g deg "
             "(\"girdle_limit\")",
             sep, rig.girdle_limit);
      sep = ";";
    }
    if (rig.max_turn > 0)
      printf("%s the whole body turns at most %g deg/s (\"max_turn\")", sep, rig.max_turn);
    printf("\n");
  }
  km_rig_free(&rig);
  printf("wrote %s\n", path);
done:
  km_mesh_skin_free(&sk);
  free(def);
  km_character_free(&c);
  km_mesh_free(&m);
  return rc;
}
