/* glTF in with Draco (issue 11): a KHR_draco_mesh_compression primitive is decoded by libdraco
 * (src/mesh/draco.cc) and read like any other. Draco's encoder reorders vertices, so a Draco
 * file is compared with the file it was made from by matching each decoded vertex to the
 * nearest original one: the matching must be one to one, every attribute within the encoder's
 * quantisation, and the triangles (mapped through it) the same set with the same windings.
 * (1) tests/data/quad_draco.glb and skinned_quad_draco.glb, draco_transcoder's output of
 * quad.gltf and skinned_quad.gltf, kept so this part runs without the tool: positions, UVs,
 * normals, triangles and the skin as the plain files have them.
 * (2) draco_transcoder's output (default quantisation: 11-bit positions, 10-bit texture
 * coordinates, 8-bit normals and weights) of kinemesh's own skinned glb of a textured tube:
 * the same, within those grids; skipped, saying so, without draco_transcoder (Debian package
 * draco, which `make test` installs).
 * (3) broken files: a bitstream that is not Draco, a truncated one, an accessor whose count is
 * not the decoded one, an attribute id the Draco mesh lacks, an integer accessor over a
 * floating-point attribute, Draco under mode 5: each a clear error naming the file, the
 * primitive and what is wrong, and no mesh. */
#include "km_test.h"
#include "mesh/mesh.h"
#include "tube_fixture.h"

#include <cjson/cJSON.h>
#include <unistd.h>

typedef struct tol {
  double pos, uv, n, w;
} tol;

static int tri_cmp(const void *a, const void *b) {
  const int32_t *x = a, *y = b;
  for (int k = 0; k < 3; ++k)
    if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
  return 0;
}

/* f's triangles through map (NULL: as they are), each rotated to lead with its smallest index,
 * sorted: equal sets with equal windings compare equal. */
static int32_t *canonical_tris(const km_mesh *m, const int32_t *map) {
  int32_t *t = malloc((m->n_faces ? m->n_faces : 1) * 3 * sizeof *t);
  for (size_t f = 0; f < m->n_faces; ++f) {
    int32_t s[3];
    for (int k = 0; k < 3; ++k)
      s[k] = map ? map[m->F[3 * f + k]] : m->F[3 * f + k];
    int r = s[0] <= s[1] && s[0] <= s[2] ? 0 : s[1] <= s[2] ? 1 : 2;
    for (int k = 0; k < 3; ++k)
      t[3 * f + k] = s[(r + k) % 3];
  }
  qsort(t, m->n_faces, 3 * sizeof *t, tri_cmp);
  return t;
}

/* The Draco file's mesh d (skin sd) against the plain one p (sp), as the header says. */
static void same_mesh(const char *what, const km_mesh *p, const km_mesh_skin *sp, const km_mesh *d,
                      const km_mesh_skin *sd, tol t) {
  CHECK_MSG(d->n_vertices == p->n_vertices && d->n_faces == p->n_faces,
            "%s: %zu vertices, %zu faces; the plain file %zu, %zu", what, d->n_vertices, d->n_faces,
            p->n_vertices, p->n_faces);
  if (d->n_vertices != p->n_vertices || d->n_faces != p->n_faces) return;
  int32_t *map = malloc(d->n_vertices * sizeof *map);
  char *used = calloc(p->n_vertices, 1);
  double worst = 0, wuv = 0, wn = 0, ww = 0;
  bool one_to_one = true, skin_same = true;
  for (size_t i = 0; i < d->n_vertices; ++i) {
    double best = INFINITY;
    size_t bj = 0;
    for (size_t j = 0; j < p->n_vertices; ++j) {
      double e = 0;
      for (int c = 0; c < 3; ++c)
        e += (d->V[3 * i + c] - p->V[3 * j + c]) * (d->V[3 * i + c] - p->V[3 * j + c]);
      if (e < best) best = e, bj = j;
    }
    map[i] = (int32_t)bj;
    one_to_one &= !used[bj];
    used[bj] = 1;
    worst = fmax(worst, sqrt(best));
    for (int c = 0; p->UV && d->UV && c < 2; ++c)
      wuv = fmax(wuv, fabs(d->UV[2 * i + c] - p->UV[2 * bj + c]));
    for (int c = 0; p->N && d->N && c < 3; ++c)
      wn = fmax(wn, fabs(d->N[3 * i + c] - p->N[3 * bj + c]));
    for (int k = 0; sp && sd && k < 4; ++k) { /* the same joints (by name), weights near */
      double w = 0;
      for (int q = 0; q < 4; ++q)
        if (sd->joints[4 * i + q] >= 0 && sp->joints[4 * bj + k] >= 0 &&
            !strcmp(sd->names[sd->joints[4 * i + q]], sp->names[sp->joints[4 * bj + k]]))
          w += sd->weights[4 * i + q];
      if (sp->joints[4 * bj + k] < 0) continue;
      ww = fmax(ww, fabs(w - sp->weights[4 * bj + k]));
      if (sp->weights[4 * bj + k] > 2 * t.w) skin_same &= w > 0;
    }
  }
  CHECK_MSG(one_to_one && worst <= t.pos, "%s: vertices %s, farthest %g m from the plain one", what,
            one_to_one ? "one to one" : "NOT one to one", worst);
  CHECK_MSG(!p->UV == !d->UV && wuv <= t.uv, "%s: UVs %s, off by %g", what,
            d->UV ? "read" : "missing", wuv);
  CHECK_MSG(!p->N == !d->N && wn <= t.n, "%s: normals %s, off by %g", what,
            d->N ? "read" : "missing", wn);
  if (sp) {
    CHECK_MSG(sd && sd->n_joints == sp->n_joints && skin_same && ww <= t.w,
              "%s: skin: %zu joints (%zu), joints %s, weights off by %g", what,
              sd ? sd->n_joints : 0, sp->n_joints, skin_same ? "same" : "differ", ww);
  }
  int32_t *a = canonical_tris(p, NULL), *b = canonical_tris(d, map);
  CHECK_MSG(!memcmp(a, b, p->n_faces * 3 * sizeof *a),
            "%s: the triangles (through the vertex matching) differ", what);
  printf("# %s: %zu vertices, %zu faces; position within %.2g m, UV %.2g, normal %.2g, weight "
         "%.2g\n",
         what, d->n_vertices, d->n_faces, worst, wuv, wn, ww);
  free(a);
  free(b);
  free(map);
  free(used);
}

static void pair(const char *what, const char *plain, const char *draco, tol t) {
  km_mesh p = {0}, d = {0};
  km_mesh_skin sp = {0}, sd = {0};
  CHECK_OK(km_mesh_read_skinned(plain, &p, &sp, KM_E));
  CHECK_OK(km_mesh_read_skinned(draco, &d, &sd, KM_E));
  if (p.V && d.V) same_mesh(what, &p, sp.n_joints ? &sp : NULL, &d, &sd, t);
  km_mesh_skin_free(&sp);
  km_mesh_skin_free(&sd);
  km_mesh_free(&p);
  km_mesh_free(&d);
}

/* (1) the kept files (11-bit positions: the quad's corners are on the grid; the skinned
 * quad's 2 m extent puts its points within half a step, 0.5 * 2 / 2047 per axis) */
static void kept_files(void) {
  pair("quad_draco.glb", KM_TEST_DATA "/quad.gltf", KM_TEST_DATA "/quad_draco.glb",
       (tol){1e-6, 1e-3, 1e-2, 1e-3});
  pair("skinned_quad_draco.glb", KM_TEST_DATA "/skinned_quad.gltf",
       KM_TEST_DATA "/skinned_quad_draco.glb",
       (tol){0.5 * 2 / 2047.0 * sqrt(3) + 1e-6, 1e-3, 1e-2, 2.0 / 255});
}

/* (2) draco_transcoder on kinemesh's skinned glb of a textured, bent tube */
static void transcoded(void) {
  if (km_test_run("command -v draco_transcoder", NULL) != 0) {
    printf("# SKIP draco_transcoder cases: draco_transcoder not found (Debian package draco)\n");
    return;
  }
  km_mesh m = {0};
  tube_mesh(&m, 24, 16, true);
  char plain[96], drc[96], cmd[512];
  snprintf(plain, sizeof plain, "test_gltf_draco_%ld.glb", (long)getpid());
  snprintf(drc, sizeof drc, "test_gltf_draco_%ld_drc.glb", (long)getpid());
  km_ssdr_options so = {.bones = 4, .iterations = 4};
  km_anim_options ao = {.fps = 30, .export_kind = KM_ANIM_EXPORT_SKIN, .skin = &so};
  km_anim_writer *w = NULL;
  double *V = malloc(m.n_vertices * 3 * sizeof *V);
  CHECK_OK(km_anim_writer_open(plain, &m, &ao, &w, KM_E));
  for (int k = 0; w && k < 8; ++k) { /* a bend about z, growing */
    double a = 0.1 * k;
    for (size_t i = 0; i < m.n_vertices; ++i) {
      const double *p = m.V + 3 * i;
      double c = cos(a * p[0]), s = sin(a * p[0]);
      V[3 * i] = c * p[0] - s * (p[1] - 1), V[3 * i + 1] = 1 + s * p[0] + c * (p[1] - 1);
      V[3 * i + 2] = p[2];
    }
    CHECK_OK(km_anim_writer_push(w, V, KM_E));
  }
  km_anim_report rep;
  if (w) CHECK_OK(km_anim_writer_finish(&w, &rep, KM_E));
  km_anim_writer_free(&w);
  free(V);
  snprintf(cmd, sizeof cmd, "draco_transcoder -i %s -o %s", plain, drc);
  char *log = NULL;
  int rc = km_test_run(cmd, &log);
  CHECK_MSG(rc == 0, "%s: %s", cmd, log ? log : "");
  free(log);
  /* the grids: 11 bits over the largest extent (1.2 m), 10 bits over [0, 1], 8-bit octahedral
   * normals (~0.01), 8-bit weights (each within 1/255, their renormalisation adds as much) */
  if (rc == 0)
    pair("draco_transcoder tube", plain, drc,
         (tol){0.5 * 1.2 / 2047 * sqrt(3) + 1e-6, 0.5 / 1023 + 1e-6, 0.02, 2.0 / 255});
  remove(plain);
  remove(drc);
  km_mesh_free(&m);
}

/* (3) broken files, made from quad_draco.glb by editing its JSON or its BIN chunk */
static void broken(void) {
  size_t n = 0;
  unsigned char *glb = read_all(KM_TEST_DATA "/quad_draco.glb", &n);
  CHECK(glb && n > 28);
  if (!glb || n <= 28) return;
  uint32_t jn = getu32(glb + 12);
  const unsigned char *bin = glb + 20 + jn + 8;
  size_t bn = getu32(glb + 20 + jn);
  char path[96];
  snprintf(path, sizeof path, "test_gltf_draco_%ld_bad.glb", (long)getpid());
  enum { NOT_DRACO, TRUNCATED, COUNT, ID, INT_OVER_FLOAT, STRIP, NCASES };
  static const char *expect[NCASES][2] = {
      {"not a Draco bitstream", "bufferView 0"},
      {"does not decode", "bufferView 0"},
      {"POSITION: accessor 1 counts 5, the Draco mesh has 4", "primitives[0]"},
      {"no attribute with that id", "POSITION"},
      {"floating point", "TEXCOORD_0"},
      {"mode 5", "primitives[0]"}};
  for (int k = 0; k < NCASES; ++k) {
    cJSON *j = cJSON_ParseWithLength((const char *)glb + 20, jn);
    cJSON *pr = cJSON_GetArrayItem(
        cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "meshes"), 0), "primitives"),
        0);
    cJSON *ext =
        cJSON_GetObjectItem(cJSON_GetObjectItem(pr, "extensions"), "KHR_draco_mesh_compression");
    cJSON *acc = cJSON_GetObjectItem(j, "accessors");
    unsigned char *b = malloc(bn);
    memcpy(b, bin, bn);
    size_t len = bn;
    if (k == NOT_DRACO) memcpy(b, "DRACX", 5);
    if (k == TRUNCATED) /* the view's first 40 bytes: the header and little more */
      cJSON_SetNumberValue(
          cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "bufferViews"), 0),
                              "byteLength"),
          40);
    if (k == COUNT)
      cJSON_SetNumberValue(cJSON_GetObjectItem(cJSON_GetArrayItem(acc, 1), "count"), 5);
    if (k == ID)
      cJSON_SetNumberValue(cJSON_GetObjectItem(cJSON_GetObjectItem(ext, "attributes"), "POSITION"),
                           7);
    if (k == INT_OVER_FLOAT)
      cJSON_SetNumberValue(cJSON_GetObjectItem(cJSON_GetArrayItem(acc, 3), "componentType"), 5123);
    if (k == STRIP) cJSON_SetNumberValue(cJSON_GetObjectItem(pr, "mode"), 5);
    char *js = cJSON_PrintUnformatted(j);
    CHECK(km_test_write_glb(path, js, b, len));
    km_mesh m = {0};
    km_status s = km_mesh_read(path, &m, KM_E);
    CHECK_MSG(s != KM_OK && m.V == NULL && strstr(km_test_err.message, path) &&
                  strstr(km_test_err.message, "KHR_draco_mesh_compression") &&
                  strstr(km_test_err.message, expect[k][0]) &&
                  strstr(km_test_err.message, expect[k][1]),
              "case %d: status %d, message: %s", k, (int)s, s ? km_test_err.message : "(none)");
    if (s) printf("# case %d: %s\n", k, km_test_err.message);
    km_mesh_free(&m);
    free(js);
    free(b);
    cJSON_Delete(j);
  }
  remove(path);
  free(glb);
}

int main(void) {
  kept_files();
  transcoded();
  broken();
  return km_test_finish("test_gltf_draco");
}
