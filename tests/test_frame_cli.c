/* Orientation (issue 11) on the verbs that read a rigged template, a source or a target mesh:
 * a z-up copy (facing -y, as Blender and most scanners write) of the procedural character,
 * its clouds and its targets gives through `pose`, `reconstruct`, `transfer` and `avatar` the
 * result the y-up original gives. Every output is in kinemesh's frame (y up, facing +z), as
 * `animate`'s is, so the two runs are compared as they are. The copy's frame comes from its
 * rig sidecar's "frame" record (what `rig` writes), from --up/--forward, or, for the clouds,
 * from the template (the default rule) or --clouds-up/--clouds-forward. A copy in other units
 * (x100) poses to the original's result up to that scale, with no flags. */
#include "km_test.h"

#include <unistd.h>

#define DIR "frame_cli"

static const km_frame ZUP = {KM_AXIS_POS_Z, KM_AXIS_NEG_Y, 0};

/* The mesh at src written at dst in frame ZUP. */
static void zup_mesh(const char *src, const char *dst) {
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(src, &m, KM_E));
  km_test_to_frame(&ZUP, m.V, m.V, m.n_vertices);
  CHECK_OK(km_mesh_write(dst, &m, NULL, KM_E));
  km_mesh_free(&m);
}

/* The rig sidecar src with the frame record `rig` writes for a ZUP mesh. */
static void zup_sidecar(const char *src, const char *dst) {
  char cmd[512];
  snprintf(cmd, sizeof cmd,
           "sed '0,/{/s//{\"frame\": {\"up\": \"+z\", \"forward\": \"-y\"},/' %s > %s", src, dst);
  CHECK(km_test_run(cmd, NULL) == 0);
}

/* Runs cmd, which must succeed; prints its output when it does not. */
static void run_ok(const char *cmd) {
  char *out = NULL;
  CHECK_MSG(km_test_run(cmd, &out) == 0, "%s:\n%s", cmd, out ? out : "");
  free(out);
}

/* Largest difference between .pc2 a scaled by k and b. */
static double pc2_diff_scaled(const char *a, double k, const char *b) {
  double *pa = NULL, *pb = NULL, worst = INFINITY;
  km_anim_info ia, ib;
  CHECK_OK(km_pc2_read(a, &pa, &ia, KM_E));
  CHECK_OK(km_pc2_read(b, &pb, &ib, KM_E));
  if (pa && pb && ia.frames == ib.frames && ia.vertices == ib.vertices && ia.frames > 0) {
    worst = 0;
    for (size_t i = 0; i < ia.frames * ia.vertices * 3; ++i)
      worst = fmax(worst, fabs(k * pa[i] - pb[i]));
  }
  free(pa);
  free(pb);
  return worst;
}

/* Largest coordinate difference between two .pc2 files (INFINITY when they do not match). */
static double pc2_diff(const char *a, const char *b) { return pc2_diff_scaled(a, 1.0, b); }

static double mesh_diff(const char *a, const char *b) {
  km_mesh ma = {0}, mb = {0};
  double worst = INFINITY;
  CHECK_OK(km_mesh_read(a, &ma, KM_E));
  CHECK_OK(km_mesh_read(b, &mb, KM_E));
  if (ma.V && mb.V && ma.n_vertices == mb.n_vertices) {
    worst = 0;
    for (size_t i = 0; i < 3 * ma.n_vertices; ++i)
      worst = fmax(worst, fabs(ma.V[i] - mb.V[i]));
  }
  km_mesh_free(&ma);
  km_mesh_free(&mb);
  return worst;
}

static void test_pose(void) {
  run_ok(KM_CLI " pose --mesh " DIR "/c.obj --motion " DIR "/w.json -o " DIR
                "/pose_y.pc2 --track " DIR "/track_y.json");
  /* the sidecar's "frame": no flags, no guess */
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/cz.obj --motion " DIR "/w.json -o " DIR
                           "/pose_z.pc2 --track " DIR "/track_z.json",
                    &out) == 0);
  CHECK_MSG(out && !strstr(out, "guessed"), "the sidecar's frame is used: %s", out ? out : "");
  free(out);
  double d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_z.pc2");
  CHECK_MSG(d < 1e-5, "pose: z-up copy (sidecar frame) is %g m off the original", d);
  km_track ty = {0}, tz = {0};
  CHECK_OK(km_track_read(DIR "/track_y.json", &ty, KM_E));
  CHECK_OK(km_track_read(DIR "/track_z.json", &tz, KM_E));
  CHECK(ty.n_frames == tz.n_frames && ty.n_landmarks == tz.n_landmarks && ty.n_frames > 0);
  if (ty.n_frames == tz.n_frames && ty.n_landmarks == tz.n_landmarks) {
    double w = 0;
    for (size_t i = 0; i < 3 * ty.n_frames * ty.n_landmarks; ++i)
      w = fmax(w, fabs(ty.positions[i] - tz.positions[i]));
    CHECK_MSG(w < 1e-6, "pose --track: z-up copy is %g m off", w);
  }
  km_track_free(&ty);
  km_track_free(&tz);
  /* --rig names the sidecar whose frame is used; --up/--forward say it outright */
  run_ok(KM_CLI " pose --mesh " DIR "/cz.obj --rig " DIR "/cz.rig.json --motion " DIR
                "/w.json -o " DIR "/pose_zr.pc2");
  d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_zr.pc2");
  CHECK_MSG(d < 1e-5, "pose --rig: %g m off", d);
  run_ok(KM_CLI " pose --mesh " DIR "/cz.obj --rig " DIR "/c.rig.json --up +z --forward -y "
                "--motion " DIR "/w.json -o " DIR "/pose_zf.pc2");
  d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_zf.pc2");
  CHECK_MSG(d < 1e-5, "pose --up +z --forward -y: %g m off", d);
  /* the wrong frame on purpose: the result differs, so the comparisons above can fail */
  run_ok(KM_CLI " pose --mesh " DIR "/cz.obj --rig " DIR "/c.rig.json --up +y --forward +z "
                "--motion " DIR "/w.json -o " DIR "/pose_zw.pc2");
  d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_zw.pc2");
  CHECK_MSG(d > 0.1, "pose in the wrong frame is only %g m off", d);
}

/* A copy of the character in centimetres (x100), rigged with no --units as `rig` rigs such a
 * scan: its sidecar's joints are in the file's units and record no scale. */
static void cm_copy(const char *mesh, const char *dst_mesh, const char *dst_rig) {
  km_character c = {0};
  CHECK_OK(km_mesh_read(mesh, &c.mesh, KM_E));
  char rig[256];
  snprintf(rig, sizeof rig, "%.*s.rig.json", (int)(strlen(mesh) - 4), mesh);
  CHECK_OK(km_character_read_rig(rig, c.mesh.n_vertices, &c, KM_E));
  for (size_t i = 0; i < 3 * c.mesh.n_vertices; ++i)
    c.mesh.V[i] *= 100;
  for (size_t i = 0; i < 3 * c.skeleton.n_joints; ++i)
    c.skeleton.rest[i] *= 100;
  CHECK_OK(km_mesh_write(dst_mesh, &c.mesh, NULL, KM_E));
  CHECK_OK(km_character_write_rig(dst_rig, &c, KM_E));
  km_character_free(&c);
}

/* Other units than the take's: a x100 copy posed with no flags is the original x100 (the
 * performer-to-character scale follows the rig's bone lengths), and with --units cm the
 * original itself (the sidecar's joints rescaled with the mesh); animated with --units cm,
 * the original too. */
static void test_pose_units(void) {
  cm_copy(DIR "/c.obj", DIR "/c100.obj", DIR "/c100.rig.json");
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/c100.obj --motion " DIR "/w.json -o " DIR
                           "/pose_100.pc2",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "scale 100"), "pose prints the scale it found: %s", out ? out : "");
  free(out);
  double d = pc2_diff_scaled(DIR "/pose_y.pc2", 100, DIR "/pose_100.pc2");
  CHECK_MSG(d < 1e-3, "pose: the x100 copy is %g cm off 100 x the original", d);
  run_ok(KM_CLI " pose --mesh " DIR "/c100.obj --units cm --motion " DIR "/w.json -o " DIR
                "/pose_100m.pc2");
  d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_100m.pc2");
  CHECK_MSG(d < 1e-5, "pose --units cm: the x100 copy is %g m off the original", d);
  /* the take for the character itself: scale 1, its joint positions met as they are */
  run_ok(KM_CLI " pose --mesh " DIR "/c.obj --scale 1 --motion " DIR "/w.json -o " DIR
                "/pose_s1.pc2");
  d = pc2_diff(DIR "/pose_y.pc2", DIR "/pose_s1.pc2");
  CHECK_MSG(d < 1e-5, "pose: the character's own take is %g m off --scale 1", d);
  /* the take's metres on the centimetre skeleton (the old collapse): far off, so the checks
   * above can fail */
  run_ok(KM_CLI " pose --mesh " DIR "/c100.obj --scale 1 --motion " DIR "/w.json -o " DIR
                "/pose_100s1.pc2");
  d = pc2_diff_scaled(DIR "/pose_y.pc2", 100, DIR "/pose_100s1.pc2");
  CHECK_MSG(d > 10, "pose --scale 1 on the x100 copy is only %g cm off", d);
  /* animate --units cm on that sidecar: its handle radii and joints are in the file's units,
   * resolved as such (not 100 x too wide balls, refused as overlapping) */
  run_ok(KM_CLI " animate --mesh " DIR "/c.obj --motion " DIR "/w.json -o " DIR "/anim_y.pc2");
  run_ok(KM_CLI " animate --mesh " DIR "/c100.obj --units cm --motion " DIR "/w.json -o " DIR
                "/anim_100m.pc2");
  d = pc2_diff(DIR "/anim_y.pc2", DIR "/anim_100m.pc2");
  CHECK_MSG(d < 1e-4, "animate --units cm: the x100 copy is %g m off the original", d);
}

/* A mesh in millimetres (a 3D-print STL) read with no --units is a body ~1750 m tall: the
 * guess line is followed by a note saying so and naming --units mm; with --units mm, none. */
static void test_units_note(void) {
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(DIR "/c.obj", &m, KM_E));
  for (size_t i = 0; i < 3 * m.n_vertices; ++i)
    m.V[i] *= 1000;
  CHECK_OK(km_mesh_write(DIR "/cmm.stl", &m, NULL, KM_E));
  km_mesh_free(&m);
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " rig " DIR "/cmm.stl -o " DIR "/cmm.rig.json", &out) == 0);
  CHECK_MSG(out && strstr(out, "note: " DIR "/cmm.stl is 17") && strstr(out, "--units mm"),
            "rig on a millimetre mesh: %s", out ? out : "");
  free(out);
  out = NULL;
  CHECK(km_test_run(KM_CLI " rig " DIR "/cmm.stl --units mm -o " DIR "/cmm2.rig.json", &out) == 0);
  CHECK_MSG(out && strstr(out, "height 1.7") && !strstr(out, "note:"), "rig --units mm: %s",
            out ? out : "");
  free(out);
}

static void test_reconstruct(void) {
  run_ok(KM_CLI " gen capture --character " DIR "/c.obj --motion " DIR "/w3.json --cameras 6 "
                "--points 6000 --noise-mm 1 -o " DIR "/frames");
  /* the clouds in the z-up frame */
  CHECK(km_test_run("mkdir -p " DIR "/frames_z", NULL) == 0);
  char **paths = NULL;
  size_t n = 0;
  CHECK_OK(km_point_frames_list(DIR "/frames/frame_*.ply", &paths, &n, KM_E));
  CHECK(n == 3);
  for (size_t f = 0; f < n; ++f) {
    km_points p = {0};
    CHECK_OK(km_points_read(paths[f], &p, KM_E));
    km_test_to_frame(&ZUP, p.P, p.P, p.n);
    char dst[256];
    snprintf(dst, sizeof dst, DIR "/frames_z/frame_%06zu.ply", f);
    CHECK_OK(km_points_write_ply(dst, p.P, p.n, KM_E));
    km_points_free(&p);
  }
  km_paths_free(&paths, n);
  /* the z-up copy as the subject (its sidecar's frame): the same truth, in kinemesh's frame */
  run_ok(KM_CLI " gen capture --character " DIR "/cz.obj --motion " DIR "/w3.json --cameras 6 "
                "--points 2000 --noise-mm 1 -o " DIR "/frames_cz");
  double dz = pc2_diff(DIR "/frames/truth.pc2", DIR "/frames_cz/truth.pc2");
  CHECK_MSG(dz < 1e-5, "gen capture: the z-up subject's truth is %g m off the original's", dz);
  /* and gen motion, whose take is the character's skeleton in kinemesh's frame */
  run_ok(KM_CLI " gen motion --kind walk --frames 4 --character " DIR "/cz.obj -o " DIR
                "/walk_z.json");
  run_ok(KM_CLI " gen motion --kind walk --frames 4 --character " DIR "/c.obj -o " DIR
                "/walk_y.json");
  km_take ty = {0}, tz = {0};
  CHECK_OK(km_motion_read(DIR "/walk_y.json", NULL, &ty, NULL, KM_E));
  CHECK_OK(km_motion_read(DIR "/walk_z.json", NULL, &tz, NULL, KM_E));
  CHECK(ty.n_frames == 4 && tz.n_frames == 4 && ty.n_joints == tz.n_joints);
  double wz = ty.n_frames == tz.n_frames && ty.n_joints == tz.n_joints ? 0 : INFINITY;
  for (size_t i = 0; isfinite(wz) && i < 3 * ty.n_frames * ty.n_joints; ++i)
    wz = fmax(wz, fabs(ty.positions[i] - tz.positions[i]));
  CHECK_MSG(wz < 1e-6, "gen motion: the z-up character's take is %g m off", wz);
  km_take_free(&ty);
  km_take_free(&tz);
  run_ok(KM_CLI " reconstruct --template " DIR "/c.obj --clouds '" DIR
                "/frames/frame_*.ply' --coarse 800 -o " DIR "/rec_y.pc2");
  /* the template's sidecar frame, and the clouds taken in the template file's frame */
  run_ok(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                "/frames_z/frame_*.ply' --coarse 800 -o " DIR "/rec_z.pc2");
  double d = pc2_diff(DIR "/rec_y.pc2", DIR "/rec_z.pc2");
  CHECK_MSG(d < 1e-4, "reconstruct: z-up template and clouds are %g m off the original", d);
  /* --keep-frame: the same reconstruction written back in the z-up template file's frame (the
   * original's taken into it), with the segmented path's writer too */
  run_ok(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                "/frames_z/frame_*.ply' --coarse 800 --keep-frame -o " DIR "/rec_zk.pc2");
  run_ok(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                "/frames_z/frame_*.ply' --coarse 800 --segment-frames 2 --overlap 1 --keep-frame "
                "-o " DIR "/rec_zks.pc2");
  run_ok(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                "/frames_z/frame_*.ply' --coarse 800 --segment-frames 2 --overlap 1 -o " DIR
                "/rec_zs.pc2");
  for (int seg = 0; seg < 2; ++seg) {
    double *py = NULL, *pk = NULL;
    km_anim_info iy, ik;
    CHECK_OK(km_pc2_read(seg ? DIR "/rec_zs.pc2" : DIR "/rec_z.pc2", &py, &iy, KM_E));
    CHECK_OK(km_pc2_read(seg ? DIR "/rec_zks.pc2" : DIR "/rec_zk.pc2", &pk, &ik, KM_E));
    double worst = INFINITY;
    if (py && pk && iy.frames == ik.frames && iy.vertices == ik.vertices && iy.frames > 0) {
      km_test_to_frame(&ZUP, py, py, iy.frames * iy.vertices);
      worst = 0;
      for (size_t i = 0; i < iy.frames * iy.vertices * 3; ++i)
        worst = fmax(worst, fabs(py[i] - pk[i]));
    }
    CHECK_MSG(worst < 1e-6, "reconstruct --keep-frame%s: %g m off the z-up frame",
              seg ? " (segments)" : "", worst);
    free(py);
    free(pk);
  }
  /* a z-up template with y-up clouds, said by --clouds-up/--clouds-forward */
  run_ok(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                "/frames/frame_*.ply' --clouds-up +y --clouds-forward +z --coarse 800 -o " DIR
                "/rec_zc.pc2");
  d = pc2_diff(DIR "/rec_y.pc2", DIR "/rec_zc.pc2");
  CHECK_MSG(d < 1e-4, "reconstruct --clouds-up +y: %g m off the original", d);
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/cz.obj --clouds '" DIR
                           "/frames/frame_*.ply' --clouds-up +y --clouds-forward -y -o " DIR
                           "/x.pc2",
                    &out) != 0);
  CHECK_MSG(out && strstr(out, "--clouds-up") && strstr(out, "same axis"), "%s", out ? out : "");
  free(out);
}

static void test_transfer_avatar(void) {
  /* b takes c's kung-fu frame 5 (same connectivity: one generator, other shape) */
  run_ok(KM_CLI " pose --mesh " DIR "/c.obj --motion " DIR "/w.json -o " DIR "/c_w");
  run_ok(KM_CLI " pose --mesh " DIR "/c.obj --motion " DIR "/k.json -o " DIR "/c_k");
  zup_mesh(DIR "/c_k/frame_000005.obj", DIR "/t3z.obj");
  run_ok(KM_CLI " transfer --source " DIR "/b.obj --template " DIR "/c_k/frame_000005.obj -o " DIR
                "/tr_y.obj");
  run_ok(KM_CLI " transfer --source " DIR "/bz.obj --template " DIR "/t3z.obj -o " DIR "/tr_z.obj");
  double d = mesh_diff(DIR "/tr_y.obj", DIR "/tr_z.obj");
  CHECK_MSG(d < 1e-5, "transfer: z-up source and template are %g m off the original", d);
  d = mesh_diff(DIR "/tr_y.obj", DIR "/b.obj");
  CHECK_MSG(d > 0.02, "transfer moved the source by %g m only", d);
  /* tracked targets are in kinemesh's frame: a z-up source meets them there */
  run_ok(KM_CLI " transfer --source " DIR "/b.obj --template " DIR "/b.obj --landmarks-xyz " DIR
                "/track_y.json --frame 3 -o " DIR "/trx_y.obj");
  run_ok(KM_CLI " transfer --source " DIR "/bz.obj --template " DIR "/bz.obj --landmarks-xyz " DIR
                "/track_y.json --frame 3 -o " DIR "/trx_z.obj");
  d = mesh_diff(DIR "/trx_y.obj", DIR "/trx_z.obj");
  CHECK_MSG(d < 1e-5, "transfer --landmarks-xyz: z-up source is %g m off the original", d);

  /* avatar: a small database of both subjects' wave and walk frames */
  run_ok(KM_CLI " pose --mesh " DIR "/b.obj --motion " DIR "/w.json -o " DIR "/b_w");
  run_ok(KM_CLI " pose --mesh " DIR "/b.obj --motion " DIR "/k.json -o " DIR "/b_k");
  CHECK(km_test_run("mkdir -p " DIR "/db", NULL) == 0);
  FILE *f = fopen(DIR "/labels.csv", "w");
  CHECK(f != NULL);
  if (!f) return;
  fputs("mesh,class,subject\n", f);
  for (int s = 0; s < 2; ++s)
    for (int k = 0; k < 2; ++k)
      for (int fr = 2; fr < 6; ++fr) {
        char cmd[512];
        snprintf(cmd, sizeof cmd, "cp " DIR "/%c_%c/frame_%06d.obj " DIR "/db/%c%c%d.obj", "cb"[s],
                 "wk"[k], fr, "cb"[s], "wk"[k], fr);
        CHECK(km_test_run(cmd, NULL) == 0);
        fprintf(f, "%c%c%d.obj,%s,%c\n", "cb"[s], "wk"[k], fr, k ? "kungfu" : "wave", "cb"[s]);
      }
  fclose(f);
  run_ok(KM_CLI " posedb build --meshes " DIR "/db --labels " DIR "/labels.csv --landmarks " DIR
                "/c.rig.json -o " DIR "/poses.kmposedb");
  run_ok(KM_CLI " avatar --source " DIR "/b.obj --db " DIR "/poses.kmposedb --track " DIR
                "/track_y.json --interval 2 -o " DIR "/av_y.pc2");
  run_ok(KM_CLI " avatar --source " DIR "/bz.obj --db " DIR "/poses.kmposedb --track " DIR
                "/track_y.json --interval 2 -o " DIR "/av_z.pc2");
  d = pc2_diff(DIR "/av_y.pc2", DIR "/av_z.pc2");
  CHECK_MSG(d < 1e-5, "avatar: z-up source is %g m off the original", d);
  run_ok(KM_CLI " avatar --source " DIR "/bz.obj --db " DIR "/poses.kmposedb --track " DIR
                "/track_y.json --interval 2 --landmarks " DIR
                "/b.rig.json --up +z --forward -y -o " DIR "/av_zf.pc2");
  d = pc2_diff(DIR "/av_y.pc2", DIR "/av_zf.pc2");
  CHECK_MSG(d < 1e-5, "avatar --up +z --forward -y: %g m off", d);
}

int main(void) {
  CHECK(km_test_run("rm -rf " DIR " && mkdir " DIR, NULL) == 0);
  char cwd[900], xdg[1024]; /* any cache here, not in the user's ~/.cache */
  if (getcwd(cwd, sizeof cwd)) {
    snprintf(xdg, sizeof xdg, "%s/" DIR "/cache", cwd);
    setenv("XDG_CACHE_HOME", xdg, 1);
  }
  run_ok(KM_CLI " gen character --vertices 2500 -o " DIR "/c.obj");
  run_ok(KM_CLI " gen character --vertices 2500 --shape stocky -o " DIR "/b.obj");
  run_ok(KM_CLI " gen motion --kind wave --frames 6 --character " DIR "/c.obj -o " DIR "/w.json");
  run_ok(KM_CLI " gen motion --kind kungfu --frames 6 --character " DIR "/c.obj -o " DIR "/k.json");
  run_ok(KM_CLI " gen motion --kind wave --frames 3 --character " DIR "/c.obj -o " DIR "/w3.json");
  zup_mesh(DIR "/c.obj", DIR "/cz.obj");
  zup_sidecar(DIR "/c.rig.json", DIR "/cz.rig.json");
  zup_mesh(DIR "/b.obj", DIR "/bz.obj");
  zup_sidecar(DIR "/b.rig.json", DIR "/bz.rig.json");
  test_pose();
  test_pose_units();
  test_units_note();
  test_reconstruct();
  test_transfer_avatar();
  if (!km_test_failed) km_test_run("rm -rf " DIR, NULL);
  return km_test_finish("test_frame_cli");
}
