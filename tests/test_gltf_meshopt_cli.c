/* Compressed glTF in through the CLI (issue 11): `animate --compress` writes a .glb with
 * KHR_mesh_quantization + EXT_meshopt_compression; `info` and `convert` read its mesh (the
 * template's 3012 vertices in their order, each within the 14-bit grid's half step of the
 * template), and `bake` takes it as the rest mesh (--mesh) of the plain animation and bakes
 * the compressed animation itself. A Draco file (tests/data/quad_draco.glb) converts to OBJ;
 * one whose Draco buffer view is missing is refused naming the extension. */
#include "km_test.h"

#define DIR "gltf_meshopt_cli"

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 -o " DIR "/tmpl.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 6 --character " DIR "/tmpl.obj -o " DIR
                           "/take.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " animate --mesh " DIR "/tmpl.obj --motion " DIR
                           "/take.json --compress -o " DIR "/z.glb",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " animate --mesh " DIR "/tmpl.obj --motion " DIR "/take.json -o " DIR
                           "/p.glb",
                    NULL) == 0);

  int rc = km_test_run(KM_CLI " info " DIR "/z.glb", &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "3012"), "info: %s", out ? out : "");
  free(out);
  out = NULL;

  rc = km_test_run(KM_CLI " convert " DIR "/z.glb " DIR "/z.obj", &out);
  CHECK_MSG(rc == 0, "convert: %s", out ? out : "");
  free(out);
  out = NULL;
  km_mesh t = {0}, z = {0};
  CHECK_OK(km_mesh_read(DIR "/tmpl.obj", &t, KM_E));
  if (rc == 0) CHECK_OK(km_mesh_read(DIR "/z.obj", &z, KM_E));
  CHECK(z.n_vertices == t.n_vertices && z.n_faces == t.n_faces);
  if (z.V && z.n_vertices == t.n_vertices) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < t.n_vertices; ++i)
      for (int c = 0; c < 3; ++c)
        lo[c] = fmin(lo[c], t.V[3 * i + c]), hi[c] = fmax(hi[c], t.V[3 * i + c]);
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2])), worst = 0;
    for (size_t i = 0; i < t.n_vertices; ++i)
      for (int c = 0; c < 3; ++c)
        worst = fmax(worst, fabs(z.V[3 * i + c] - t.V[3 * i + c]));
    /* the grid step grows with the morph deltas (max delta / 32000): a few mm of waving at most
     * (the bound below is 1 mm; the writer's own report is the precise figure) */
    CHECK_MSG(worst <= fmax(0.5 * ext / 16383, 1e-3) + 1e-6,
              "convert: vertices off the template by up to %g m (extent %g m)", worst, ext);
    printf("# convert z.glb: %zu vertices in the template's order, max %.2g m off\n", z.n_vertices,
           worst);
  }
  km_mesh_free(&t);
  km_mesh_free(&z);

  rc = km_test_run(
      KM_CLI " bake " DIR "/p.glb --mesh " DIR "/z.glb --export skin:6 -o " DIR "/b.glb", &out);
  CHECK_MSG(rc == 0, "bake --mesh z.glb: %s", out ? out : "");
  free(out);
  out = NULL;
  /* and bakes the compressed animation itself (its morph frames decoded) */
  rc = km_test_run(KM_CLI " bake " DIR "/z.glb --export skin:6 -o " DIR "/bz.glb", &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "frames of 3012 vertices"), "bake z.glb: %s",
            out ? out : "");
  free(out);
  out = NULL;

  /* Draco: read (draco_transcoder's quad), and a primitive whose Draco view is missing is
   * refused naming the extension and the file */
  rc = km_test_run(KM_CLI " convert " KM_TEST_DATA "/quad_draco.glb " DIR "/quad.obj", &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "4 vertices, 2 triangles"), "draco convert: %s",
            out ? out : "");
  free(out);
  out = NULL;
  FILE *f = fopen(DIR "/draco.gltf", "w");
  CHECK(f != NULL);
  if (f) {
    fputs(
        "{\"asset\":{\"version\":\"2.0\"},\"extensionsUsed\":[\"KHR_draco_mesh_compression\"],"
        "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],"
        "\"accessors\":[{\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"extensions\":"
        "{\"KHR_draco_mesh_compression\":{\"bufferView\":0,\"attributes\":{\"POSITION\":0}}}}]}]}",
        f);
    fclose(f);
  }
  rc = km_test_run(KM_CLI " info " DIR "/draco.gltf", &out);
  CHECK_MSG(rc != 0 && out && strstr(out, "KHR_draco_mesh_compression: bufferView 0") &&
                strstr(out, "draco.gltf"),
            "draco: rc %d: %s", rc, out ? out : "");
  free(out);
  CHECK(km_test_run("rm -rf " DIR, NULL) == 0);
  return km_test_finish("test_gltf_meshopt_cli");
}
