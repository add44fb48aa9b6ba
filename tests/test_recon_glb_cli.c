/* kinemesh's own skinned export as a reconstruction template (issue 13): `pose --export skin`
 * writes a .glb whose bones are the SSDR fit's (bone_000, ...: rigid parts, no skeleton), so
 * `reconstruct --template char.glb` without a sidecar refuses it, naming the bones and the
 * way out; after `rig char.glb --skeleton kinect1` the same .glb is a template that follows a
 * capture of another body (every frame: points -> surface <= 3 mm, surface -> points p99
 * <= 30 mm, nothing flagged). A skinned glTF with a named skeleton (Mixamo, VRM, rigify) needs
 * no sidecar: test_skin_gltf. */
#include "km_test.h"

#include "capture_fixture.h"

#define DIR "recon_glb_cli"

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  /* the template: the procedural character exported as a skinned .glb */
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 -o " DIR "/tmpl.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 3 --character " DIR "/tmpl.obj -o " DIR
                           "/tmpl_take.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/tmpl.obj --motion " DIR
                           "/tmpl_take.json --export skin -o " DIR "/char.glb",
                    NULL) == 0);
  /* the capture: another body */
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 --shape stocky -o " DIR "/subj.obj",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 4 --character " DIR "/subj.obj -o " DIR
                           "/take.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen capture --character " DIR "/subj.obj --motion " DIR
                           "/take.json --cameras 8 --points 12000 --noise-mm 2 -o " DIR "/frames",
                    NULL) == 0);
  /* no sidecar, SSDR bones: refused with the bones named and the rig command suggested */
  int rc = km_test_run(KM_CLI " reconstruct --template " DIR "/char.glb --clouds '" DIR
                              "/frames/*.ply' -o " DIR "/no.pc2",
                       &out);
  CHECK_MSG(rc != 0 && out && strstr(out, "bone_000") && strstr(out, "kinemesh rig"), "exit %d: %s",
            rc, out ? out : "");
  free(out);
  CHECK(km_test_run("test ! -e " DIR "/no.pc2", NULL) == 0);
  /* rigged: the .glb is the template */
  CHECK(km_test_run(KM_CLI " rig " DIR "/char.glb --skeleton kinect1", NULL) == 0);
  CHECK(km_test_run("test -s " DIR "/char.rig.json", NULL) == 0);
  rc = km_test_run(KM_CLI " reconstruct --template " DIR "/char.glb --clouds '" DIR
                          "/frames/*.ply' -o " DIR "/recon.pc2 --report " DIR
                          "/report.json --strict",
                   &out);
  CHECK_MSG(rc == 0, "exit %d: %s", rc, out ? out : "");
  free(out);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(DIR "/recon.pc2", &info, KM_E));
  CHECK(info.frames == 4);
  km_mesh tm = {0};
  CHECK_OK(km_mesh_read(DIR "/tmpl.obj", &tm, KM_E));
  CHECK(info.vertices == tm.n_vertices);
  km_mesh_free(&tm);
  cJSON *rep = km_test_read_json(DIR "/report.json");
  const cJSON *frames = cJSON_GetObjectItemCaseSensitive(rep, "frames");
  CHECK(rep && cJSON_GetArraySize(frames) == 4);
  for (int i = 0; i < cJSON_GetArraySize(frames); ++i) {
    const cJSON *fr = cJSON_GetArrayItem(frames, i);
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(fr, "status");
    double mean = km_test_json_number(fr, "mean_mm"),
           p99 = km_test_json_number(fr, "surface_p99_mm");
    printf("frame %d: %s, points->surface %.2f mm, surface->points p99 %.1f mm\n", i,
           cJSON_IsString(st) ? st->valuestring : "?", mean, p99);
    CHECK_MSG(cJSON_IsString(st) && strcmp(st->valuestring, "KM_OK") == 0, "frame %d", i);
    CHECK_MSG(mean <= 3, "frame %d: points -> surface %.2f mm", i, mean);
    CHECK_MSG(p99 <= 30, "frame %d: surface -> points p99 %.1f mm", i, p99);
  }
  cJSON_Delete(rep);
  if (!km_test_failed && !getenv("KM_TEST_KEEP")) km_test_run("rm -rf " DIR, NULL);
  return km_test_finish("test_recon_glb_cli");
}
