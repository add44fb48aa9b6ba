/* Point clouds to mesh animation through the CLI: a simulated capture, then reconstruct with
 * a report and a plot; bad inputs exit non-zero with a message naming them. */
#include "capture_fixture.h"

#define DIR "recon_cli"

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 6000 --shape stocky -o " DIR "/subject.obj",
                    NULL) == 0);
  CHECK(km_test_capture(DIR "/subject.obj", "wave", 5, DIR "/take.json", 8, 12000, "--noise-mm 2",
                        DIR "/frames", NULL) == 0);
  km_anim_info truth;
  CHECK_OK(km_anim_info_read(DIR "/frames/truth.pc2", &truth, KM_E));
  CHECK(truth.frames == 5);
  /* the rest mesh (faces of truth.pc2) is no .ply, so the frame lister never takes it */
  km_mesh rest = {0};
  CHECK_OK(km_mesh_read(DIR "/frames/truth_rest.obj", &rest, KM_E));
  CHECK(rest.n_vertices == truth.vertices && rest.n_faces > 0);
  km_mesh_free(&rest);
  CHECK(km_test_run("test ! -e " DIR "/frames/truth_rest.ply", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 -o " DIR "/template.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/recon.pc2 --report " DIR
                           "/report.json --plot " DIR "/errors.png",
                    &out) == 0);
  free(out);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(DIR "/recon.pc2", &info, KM_E));
  CHECK(info.frames == 5);
  cJSON *rep = km_test_read_json(DIR "/report.json");
  CHECK(rep != NULL);
  const cJSON *frames = cJSON_GetObjectItemCaseSensitive(rep, "frames");
  CHECK(cJSON_GetArraySize(frames) == 5);
  for (int i = 0; i < cJSON_GetArraySize(frames); ++i) {
    const cJSON *fr = cJSON_GetArrayItem(frames, i);
    const char *keys[] = {"index", "points", "mean_mm", "max_mm", "iterations", "seconds"};
    for (int k = 0; k < (int)(sizeof keys / sizeof keys[0]); ++k)
      CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(fr, keys[k])), "frame %d: %s", i,
                keys[k]);
    const cJSON *mean = cJSON_GetObjectItemCaseSensitive(fr, "mean_mm");
    /* 2 mm noise: the surface sits a few mm from the points on average */
    CHECK_MSG(cJSON_IsNumber(mean) && mean->valuedouble > 0 && mean->valuedouble < 6,
              "frame %d: mean %.2f mm", i, cJSON_IsNumber(mean) ? mean->valuedouble : -1);
    CHECK(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(fr, "joints")) ==
          3 * KM_KINECT1_JOINTS);
  }
  const cJSON *ff = cJSON_GetObjectItemCaseSensitive(rep, "first_frame");
  CHECK(cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(ff, "correspondences")) &&
        cJSON_GetObjectItemCaseSensitive(ff, "correspondences")->valuedouble == 0);
  /* without correspondences the report says how frame 0 was placed */
  const cJSON *init = cJSON_GetObjectItemCaseSensitive(ff, "initialisation");
  CHECK_MSG(cJSON_IsString(init) && strstr(init->valuestring, "headings") &&
                strstr(init->valuestring, "landmarks"),
            "%s", cJSON_IsString(init) ? init->valuestring : "(none)");
  const cJSON *yc = cJSON_GetObjectItemCaseSensitive(ff, "yaw_candidates");
  CHECK(cJSON_IsNumber(yc) && yc->valuedouble >= 8);
  const cJSON *nl = cJSON_GetObjectItemCaseSensitive(ff, "landmarks");
  CHECK(cJSON_IsNumber(nl) && nl->valuedouble >= 3 && nl->valuedouble <= KM_CHARACTER_LANDMARKS);
  cJSON_Delete(rep);
  FILE *f = fopen(DIR "/errors.png", "rb");
  unsigned char sig[8] = {0};
  CHECK(f && fread(sig, 1, 8, f) == 8 && sig[0] == 0x89 && sig[1] == 'P' && sig[2] == 'N');
  if (f) fclose(f);

  /* the README's glob of every .ply in FRAMES: exactly the captured frames, nothing else */
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/frames/*.ply' -o " DIR "/glob.pc2 --report " DIR "/glob.json",
                    &out) == 0);
  free(out);
  rep = km_test_read_json(DIR "/glob.json");
  CHECK_MSG(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(rep, "frames")) ==
                (int)truth.frames,
            "'frames/*.ply': %d frames in the report, %zu captured",
            cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(rep, "frames")), truth.frames);
  cJSON_Delete(rep);
  CHECK_OK(km_anim_info_read(DIR "/glob.pc2", &info, KM_E));
  CHECK(info.frames == truth.frames);

  /* a corrupt frame in the middle (directory mode, which also holds truth.pc2 and
   * truth_rest.obj): the run completes, and the report and the warning keep the read
   * error naming the file */
  CHECK(km_test_run("cp -r " DIR "/frames " DIR "/corrupt && truncate -s 300 " DIR
                    "/corrupt/frame_00002.ply",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds " DIR
                           "/corrupt -o " DIR "/corrupt.pc2 --report " DIR "/corrupt.json",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "frame_00002.ply"), "warning names the file: %s", out);
  free(out);
  rep = km_test_read_json(DIR "/corrupt.json");
  frames = cJSON_GetObjectItemCaseSensitive(rep, "frames");
  CHECK(cJSON_GetArraySize(frames) == (int)truth.frames);
  for (int i = 0; i < cJSON_GetArraySize(frames); ++i) {
    const cJSON *fr = cJSON_GetArrayItem(frames, i);
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(fr, "status");
    const cJSON *msg = cJSON_GetObjectItemCaseSensitive(fr, "message");
    if (i == 2) {
      CHECK(cJSON_IsString(st) && !strcmp(st->valuestring, "KM_ERR_PARSE"));
      CHECK_MSG(cJSON_IsString(msg) && strstr(msg->valuestring, "frame_00002.ply"),
                "frame 2 message: %s", cJSON_IsString(msg) ? msg->valuestring : "(none)");
    } else {
      CHECK_MSG(cJSON_IsString(st) && !strcmp(st->valuestring, "KM_OK") && !msg, "frame %d", i);
    }
  }
  const cJSON *failed = cJSON_GetObjectItemCaseSensitive(rep, "failed_frames");
  CHECK(cJSON_IsNumber(failed) && failed->valuedouble == 1);
  cJSON_Delete(rep);
  CHECK_OK(km_anim_info_read(DIR "/corrupt.pc2", &info, KM_E));
  CHECK(info.frames == truth.frames);

  /* two-sided error: a 5 mm threshold leaves surface unsupported on every frame (2 mm noise,
   * a template of another build, soles no camera sees): a warning line per frame, exit 0;
   * with --strict, exit 1 */
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/tight.pc2 --unsupported-mm 5 "
                           "--report " DIR "/tight.json",
                    &out) == 0);
  int warnings = 0;
  for (const char *q = out; q && (q = strstr(q, "warning: frame ")); ++q)
    ++warnings;
  CHECK_MSG(warnings == (int)truth.frames && strstr(out, "unsupported surface"), "%s", out);
  free(out);
  rep = km_test_read_json(DIR "/tight.json");
  frames = cJSON_GetObjectItemCaseSensitive(rep, "frames");
  for (int i = 0; i < cJSON_GetArraySize(frames); ++i) {
    const cJSON *fr = cJSON_GetArrayItem(frames, i);
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(fr, "status");
    CHECK(cJSON_IsString(st) && !strcmp(st->valuestring, "unsupported_surface"));
    const char *keys[] = {
        "p95_mm",         "surface_mean_mm",  "surface_p95_mm",      "surface_p99_mm",
        "surface_max_mm", "surface_vertices", "unsupported_vertices"};
    for (int k = 0; k < (int)(sizeof keys / sizeof keys[0]); ++k)
      CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(fr, keys[k])), "frame %d: %s", i,
                keys[k]);
    CHECK(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(fr, "unsupported_joints")) > 0);
    CHECK(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(fr, "unsupported_ids")) ==
          (int)cJSON_GetObjectItemCaseSensitive(fr, "unsupported_vertices")->valuedouble);
  }
  const cJSON *uf = cJSON_GetObjectItemCaseSensitive(rep, "unsupported_frames");
  CHECK(cJSON_IsNumber(uf) && uf->valuedouble == (double)truth.frames);
  const cJSON *stp = cJSON_GetObjectItemCaseSensitive(rep, "surface_to_points");
  CHECK(cJSON_IsString(stp) && strstr(stp->valuestring, "all vertices"));
  cJSON_Delete(rep);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/tight.pc2 --unsupported-mm 5 --strict",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "--strict"), "%s", out);
  free(out);

  /* a template with a ground quad under its feet (as a character comes out of a scene): rig
   * leaves the quad out of the skin, reconstruct keeps it where it lies in every frame and
   * leaves it out of surface -> points (its corners, a metre from any point, measured 1335 mm
   * before and held the report's surface error there) */
  CHECK(km_test_run("awk -f " KM_TEST_DATA "/ground_quad.awk " DIR "/template.obj > " DIR
                    "/ground.obj",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " rig " DIR "/ground.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/ground.obj --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/ground.pc2 --report " DIR
                           "/ground.json",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "but those the skin leaves still"), "%s", out ? out : "");
  free(out);
  km_mesh gm = {0};
  double *gf = NULL;
  km_anim_info gi;
  CHECK_OK(km_mesh_read(DIR "/ground.obj", &gm, KM_E));
  CHECK_OK(km_pc2_read(DIR "/ground.pc2", &gf, &gi, KM_E));
  if (gf && gm.n_vertices == gi.vertices && gi.frames == 5) {
    double moved = 0;
    for (size_t t = 0; t < gi.frames; ++t)
      for (size_t v = gm.n_vertices - 4; v < gm.n_vertices; ++v)
        for (int a = 0; a < 3; ++a)
          moved = fmax(moved,
                       fabs(gf[(t * gm.n_vertices + v) * 3 + (size_t)a] - gm.V[3 * v + (size_t)a]));
    CHECK_MSG(moved < 1e-6, "the ground quad moved %g m", moved);
  } else
    CHECK_MSG(false, "ground.pc2: %zu frames of %zu vertices", gi.frames, gi.vertices);
  free(gf);
  km_mesh_free(&gm);
  rep = km_test_read_json(DIR "/ground.json");
  const cJSON *sv = rep ? cJSON_GetObjectItemCaseSensitive(rep, "still_vertices") : NULL;
  CHECK(cJSON_IsNumber(sv) && sv->valuedouble == 4);
  frames = rep ? cJSON_GetObjectItemCaseSensitive(rep, "frames") : NULL;
  for (int i = 0; i < cJSON_GetArraySize(frames); ++i) {
    const cJSON *fr = cJSON_GetArrayItem(frames, i);
    const cJSON *smax = cJSON_GetObjectItemCaseSensitive(fr, "surface_max_mm");
    const cJSON *mean = cJSON_GetObjectItemCaseSensitive(fr, "mean_mm");
    CHECK_MSG(cJSON_IsNumber(smax) && smax->valuedouble < 300 && cJSON_IsNumber(mean) &&
                  mean->valuedouble < 6,
              "frame %d: surface -> points max %.0f mm, points -> surface mean %.2f mm", i,
              cJSON_IsNumber(smax) ? smax->valuedouble : -1,
              cJSON_IsNumber(mean) ? mean->valuedouble : -1);
  }
  cJSON_Delete(rep);

  /* bad inputs */
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/nothing_*.ply' -o " DIR "/x.pc2",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "nothing_"), "%s", out);
  free(out);
  f = fopen(DIR "/bad.json", "w");
  fputs("{\"correspondences\": [{\"vertex\": \"x\"}]}", f);
  fclose(f);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/template.obj --clouds '" DIR
                           "/frames/frame_*.ply' --correspondences " DIR "/bad.json -o " DIR
                           "/x.pc2",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "bad.json"), "%s", out);
  free(out);
  CHECK(km_test_run("test ! -e " DIR "/x.pc2", NULL) == 0);
  km_test_run("rm -rf " DIR, NULL);
  return km_test_finish("test_recon_cli");
}
