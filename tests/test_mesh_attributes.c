/* Texture coordinates and normals (issue 11): read from OBJ (vt/vn through the faces' v/vt/vn
 * references, vertex order and count kept) and PLY (u v / s t / texture_u texture_v, nx ny
 * nz), kept by copy, written back by km_mesh_write, `convert`, OBJ/PLY frame directories and
 * .glb (TEXCOORD_0, NORMAL, NORMAL morph targets), and read back intact. Also: `-o` creates
 * missing parent folders, and the puppetry cache goes to $XDG_CACHE_HOME, not beside the
 * input. */
#include "km_test.h"

#include "core/core.h"

#include <cjson/cJSON.h>
#include <sys/stat.h>
#include <unistd.h>

/* A quad split in two, with a texture seam at vertex 0 (two vt), normals, a comment, vt
 * before v and a negative reference. */
static const char k_obj[] = "# textured quad\n"
                            "vt 0.25 0.5\n"
                            "v 0 0 0\n"
                            "v 1 0 0\n"
                            "v 1 1 0\n"
                            "v 0 1 0\n"
                            "vt 1 0\n"
                            "vt 1 1\n"
                            "vt 0 1\n"
                            "vt 0.75 0.125\n"
                            "vn 0 0 1\n"
                            "f 1/1/1 2/2/1 3/3/1\n"
                            "f 1/-1/1 3/3/1 4/4/1\n";

static void test_obj_read(void) {
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(k_obj, sizeof k_obj - 1, KM_FORMAT_OBJ, "quad.obj", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_faces == 2);
  CHECK(m.UV != NULL && m.N != NULL);
  if (m.UV && m.N && m.n_vertices == 4) {
    /* vertex 0: the first reference (vt 1) wins over the seam's second (vt 5) */
    const double want[8] = {0.25, 0.5, 1, 0, 1, 1, 0, 1};
    for (int i = 0; i < 8; ++i)
      CHECK_NEAR(m.UV[i], want[i], 0);
    for (int i = 0; i < 4; ++i)
      CHECK(m.N[3 * i] == 0 && m.N[3 * i + 1] == 0 && m.N[3 * i + 2] == 1);
  }
  km_mesh c = {0};
  CHECK_OK(km_mesh_copy(&m, &c, KM_E));
  CHECK(c.UV && c.N && c.UV != m.UV && memcmp(c.UV, m.UV, 8 * sizeof(double)) == 0);
  km_mesh_free(&c);
  CHECK(c.UV == NULL && c.N == NULL);

  /* Writers: OBJ, PLY ascii / binary LE / BE read back bit for bit; OFF drops them. */
  const char *paths[] = {"attr_t/a.obj", "attr_t/a_ascii.ply", "attr_t/a_le.ply",
                         "attr_t/a_be.ply"};
  km_ply_encoding enc[] = {0, KM_PLY_ASCII, KM_PLY_BINARY_LE, KM_PLY_BINARY_BE};
  km_test_run("rm -rf attr_t", NULL);
  for (int k = 0; k < 4; ++k) {
    km_mesh_write_options wo = {0};
    wo.ply = enc[k];
    /* attr_t/ does not exist: the writer creates it */
    CHECK_OK(km_mesh_write(paths[k], &m, &wo, KM_E));
    km_mesh r = {0};
    CHECK_OK(km_mesh_read(paths[k], &r, KM_E));
    CHECK_MSG(r.n_vertices == 4 && r.UV && r.N, "%s", paths[k]);
    if (r.UV && r.N && r.n_vertices == 4) {
      CHECK_MSG(memcmp(r.UV, m.UV, 8 * sizeof(double)) == 0, "%s: UV", paths[k]);
      CHECK_MSG(memcmp(r.N, m.N, 12 * sizeof(double)) == 0, "%s: N", paths[k]);
      CHECK(memcmp(r.V, m.V, 12 * sizeof(double)) == 0);
    }
    km_mesh_free(&r);
  }
  km_mesh_free(&m);

  /* Without vt lines, i/t references are ignored as before; with them, out of range fails. */
  static const char plain[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/2 3/3\n";
  CHECK_OK(km_mesh_parse(plain, sizeof plain - 1, KM_FORMAT_OBJ, "p.obj", &m, KM_E));
  CHECK(m.UV == NULL && m.N == NULL && m.n_faces == 1);
  km_mesh_free(&m);
  static const char bad[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/7 3/1\n";
  CHECK_STATUS(km_mesh_parse(bad, sizeof bad - 1, KM_FORMAT_OBJ, "b.obj", &m, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "b.obj:5") && strstr(km_test_err.message, "texture"), "%s",
            km_test_err.message);
}

static void test_ply_names(void) {
  /* s t and nx ny nz among other properties (a colour), ascii */
  static const char ply[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                            "property float y\nproperty float z\nproperty uchar red\n"
                            "property float s\nproperty float t\nproperty float nx\n"
                            "property float ny\nproperty float nz\n"
                            "element face 1\nproperty list uchar int vertex_indices\n"
                            "end_header\n"
                            "0 0 0 9 0.5 0.25 0 0 1\n1 0 0 9 1 0 0 0 1\n0 1 0 9 0 1 0 0 1\n"
                            "3 0 1 2\n";
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(ply, sizeof ply - 1, KM_FORMAT_PLY, "st.ply", &m, KM_E));
  CHECK(m.UV && m.N && m.n_vertices == 3);
  if (m.UV && m.N) {
    CHECK(m.UV[0] == 0.5 && m.UV[1] == 0.25 && m.UV[2] == 1 && m.UV[5] == 1);
    CHECK(m.N[2] == 1 && m.N[8] == 1);
  }
  km_mesh_free(&m);
}

/* ---- glb read back */

static uint32_t u32(const unsigned char *b) {
  return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

/* Float data of the accessor named by attribute `attr` of the first primitive (target < 0)
 * or of its morph target `target`; NULL when absent. */
static const unsigned char *glb_attr(const char *data, size_t size, const char *attr, int target,
                                     size_t *count, cJSON **json_out) {
  if (size < 28) return NULL;
  const unsigned char *d = (const unsigned char *)data;
  uint32_t jl = u32(d + 12);
  if (20 + (size_t)jl + 8 > size) return NULL;
  cJSON *j = cJSON_ParseWithLength(data + 20, jl);
  *json_out = j;
  const unsigned char *bin = d + 20 + jl + 8;
  size_t bin_len = u32(d + 20 + jl);
  cJSON *prim = cJSON_GetArrayItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "meshes"), 0), "primitives"),
      0);
  cJSON *attrs = target < 0 ? cJSON_GetObjectItem(prim, "attributes")
                            : cJSON_GetArrayItem(cJSON_GetObjectItem(prim, "targets"), target);
  cJSON *a = cJSON_GetObjectItem(attrs, attr);
  if (!cJSON_IsNumber(a)) return NULL;
  cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "accessors"), a->valueint);
  cJSON *bv = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "bufferViews"),
                                 cJSON_GetObjectItem(acc, "bufferView")->valueint);
  size_t off = (size_t)cJSON_GetObjectItem(bv, "byteOffset")->valuedouble;
  size_t len = (size_t)cJSON_GetObjectItem(bv, "byteLength")->valuedouble;
  *count = (size_t)cJSON_GetObjectItem(acc, "count")->valuedouble;
  if (off + len > bin_len) return NULL;
  return bin + off;
}

static float f32(const unsigned char *p) {
  uint32_t u = u32(p);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

/* A generated character given UVs (a cylindrical projection) goes through convert, animate
 * to .glb and to OBJ and PLY frames; the UVs come back intact everywhere, normals are unit
 * and follow the frame. */
static void test_cli_textured(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf attr_c attr_cache && mkdir attr_c", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2500 -o attr_c/c.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 8 --character attr_c/c.obj -o "
                           "attr_c/w.json",
                    NULL) == 0);
  km_mesh m = {0};
  CHECK_OK(km_mesh_read("attr_c/c.obj", &m, KM_E));
  if (!m.n_vertices) return;
  m.UV = malloc(m.n_vertices * 2 * sizeof(double));
  for (size_t i = 0; i < m.n_vertices; ++i) {
    m.UV[2 * i] = 0.5 + atan2(m.V[3 * i + 2], m.V[3 * i]) / (2 * M_PI);
    m.UV[2 * i + 1] = m.V[3 * i + 1] / 2;
  }
  CHECK_OK(km_mesh_write("attr_c/t.obj", &m, NULL, KM_E));
  CHECK(km_test_run("cp attr_c/c.rig.json attr_c/t.rig.json", NULL) == 0);

  /* convert into a folder that does not exist yet */
  CHECK(km_test_run(KM_CLI " convert attr_c/t.obj attr_c/new/deeper/t.ply", &out) == 0);
  free(out);
  km_mesh r = {0};
  CHECK_OK(km_mesh_read("attr_c/new/deeper/t.ply", &r, KM_E));
  CHECK(r.UV && r.n_vertices == m.n_vertices &&
        memcmp(r.UV, m.UV, m.n_vertices * 2 * sizeof(double)) == 0);
  km_mesh_free(&r);

  /* animate with the cache in a private XDG cache folder: nothing lands beside the mesh */
  const char *env = "XDG_CACHE_HOME=\"$PWD/attr_cache\" ";
  char cmd[2048];
  const char *outs[] = {"attr_c/out/t.glb", "attr_c/out/frames_obj", "attr_c/out/frames_ply"};
  const char *fmt[] = {"", "", " --frame-format ply"};
  for (int k = 0; k < 3; ++k) {
    snprintf(cmd, sizeof cmd,
             "%s" KM_CLI " animate --mesh attr_c/t.obj --motion attr_c/w.json%s -o %s", env, fmt[k],
             outs[k]);
    CHECK_MSG(km_test_run(cmd, &out) == 0, "%s: %s", cmd, out ? out : "");
    free(out);
  }
  CHECK(access("attr_c/t.obj.kmcache", F_OK) != 0);
  CHECK(km_test_run("ls attr_cache/kinemesh/*.kmcache", NULL) == 0);

  /* frames: UVs exact, normals unit */
  const char *frames[] = {"attr_c/out/frames_obj/frame_000007.obj",
                          "attr_c/out/frames_ply/frame_000007.ply"};
  for (int k = 0; k < 2; ++k) {
    CHECK_OK(km_mesh_read(frames[k], &r, KM_E));
    CHECK_MSG(r.UV && r.N && r.n_vertices == m.n_vertices, "%s", frames[k]);
    if (r.UV && r.N && r.n_vertices == m.n_vertices) {
      CHECK_MSG(memcmp(r.UV, m.UV, m.n_vertices * 2 * sizeof(double)) == 0, "%s UV", frames[k]);
      double worst = 0;
      for (size_t i = 0; i < r.n_vertices; ++i) {
        double *n = r.N + 3 * i;
        worst = fmax(worst, fabs(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) - 1));
      }
      CHECK_MSG(worst < 1e-6, "%s: normal length off by %g", frames[k], worst);
      /* recomputed for the frame: the same as the frame's own normals */
      double *N = malloc(r.n_vertices * 3 * sizeof(double));
      CHECK_OK(km_vertex_normals(&r, KM_NORMALS_AREA, N, KM_E));
      double dev = 0;
      for (size_t i = 0; i < r.n_vertices * 3; ++i)
        dev = fmax(dev, fabs(N[i] - r.N[i]));
      CHECK_MSG(dev < 1e-6, "%s: normals differ from the frame's by %g", frames[k], dev);
      free(N);
    }
    km_mesh_free(&r);
  }

  /* glb: TEXCOORD_0 = (u, 1 - v) as float, NORMAL unit, morph targets carry NORMAL */
  char *data = NULL;
  size_t size = 0, count = 0;
  CHECK_OK(km__read_file("attr_c/out/t.glb", &data, &size, KM_E));
  cJSON *j = NULL;
  const unsigned char *uv = data ? glb_attr(data, size, "TEXCOORD_0", -1, &count, &j) : NULL;
  CHECK(uv && count == m.n_vertices);
  if (uv && count == m.n_vertices) {
    double dev = 0;
    for (size_t i = 0; i < count; ++i) {
      dev = fmax(dev, fabs(f32(uv + 8 * i) - (float)m.UV[2 * i]));
      dev = fmax(dev, fabs(f32(uv + 8 * i + 4) - (float)(1 - m.UV[2 * i + 1])));
    }
    CHECK_MSG(dev == 0, "glb TEXCOORD_0 differs by %g", dev);
  }
  cJSON_Delete(j);
  j = NULL;
  CHECK(data && glb_attr(data, size, "NORMAL", -1, &count, &j) && count == m.n_vertices);
  cJSON_Delete(j);
  j = NULL;
  CHECK(data && glb_attr(data, size, "NORMAL", 3, &count, &j) && count == m.n_vertices);
  cJSON_Delete(j);
  free(data);

  /* the .glb read back as a mesh (glTF in): positions, UVs (v flipped back) and normals */
  CHECK_OK(km_mesh_read("attr_c/out/t.glb", &r, KM_E));
  CHECK(r.n_vertices == m.n_vertices && r.n_faces == m.n_faces && r.UV && r.N);
  if (r.UV && r.n_vertices == m.n_vertices && r.n_faces == m.n_faces) {
    double dv = 0, dt = 0;
    for (size_t i = 0; i < m.n_vertices * 3; ++i)
      dv = fmax(dv, fabs(r.V[i] - (double)(float)m.V[i]));
    for (size_t i = 0; i < m.n_vertices * 2; ++i)
      dt = fmax(dt, fabs(r.UV[i] - m.UV[i]));
    CHECK_MSG(dv == 0 && dt < 1e-6, "glb as a mesh: positions %g, uv %g", dv, dt);
    CHECK(memcmp(r.F, m.F, m.n_faces * 3 * sizeof(int32_t)) == 0);
  }
  km_mesh_free(&r);

  /* a second run loads the cache from the XDG folder */
  snprintf(cmd, sizeof cmd,
           "%s" KM_CLI " animate --mesh attr_c/t.obj --motion attr_c/w.json -o attr_c/out/u.pc2",
           env);
  CHECK(km_test_run(cmd, &out) == 0);
  CHECK_MSG(out && strstr(out, "cache loaded"), "%s", out ? out : "");
  free(out);
  km_mesh_free(&m);
  km_test_run("rm -rf attr_c attr_cache attr_t", NULL);
}

/* A hand-written .gltf: two meshes (two primitives and one), an embedded base64 buffer,
 * uint16 indices, a primitive without indices; merged in file order. Every truncated prefix
 * of a .glb is an error, never a crash. */
static void test_gltf_in(void) {
  /* buffer: 4 positions (float VEC3, 48 bytes), uint16 indices 0 1 2 0 2 3 (12 bytes) */
  unsigned char buf[60];
  const float P[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  memcpy(buf, P, 48);
  const uint16_t I[6] = {0, 1, 2, 0, 2, 3};
  memcpy(buf + 48, I, 12);
  static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  char enc[128];
  size_t o = 0;
  for (size_t i = 0; i < 60; i += 3) {
    uint32_t v = (uint32_t)buf[i] << 16 | (uint32_t)buf[i + 1] << 8 | buf[i + 2];
    for (int k = 3; k >= 0; --k)
      enc[o++] = b64[(v >> (6 * k)) & 63];
  }
  enc[o] = 0;
  char json[2048];
  snprintf(json, sizeof json,
           "{\"asset\":{\"version\":\"2.0\"},"
           "\"buffers\":[{\"byteLength\":60,\"uri\":\"data:application/octet-stream;base64,%s\"}],"
           "\"bufferViews\":[{\"buffer\":0,\"byteLength\":48},"
           "{\"buffer\":0,\"byteOffset\":48,\"byteLength\":12}],"
           "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
           "{\"bufferView\":1,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"},"
           "{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}],"
           "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1},"
           "{\"attributes\":{\"POSITION\":2}}]},"
           "{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,\"mode\":4}]}]}",
           enc);
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(json, strlen(json), KM_FORMAT_GLTF, "hand.gltf", &m, KM_E));
  CHECK(m.n_vertices == 11 && m.n_faces == 5 && !m.UV && !m.N);
  if (m.n_vertices == 11 && m.n_faces == 5) {
    CHECK(m.F[6] == 4 && m.F[7] == 5 && m.F[8] == 6);                    /* unindexed, after 4 */
    CHECK(m.F[9] == 7 && m.F[10] == 8 && m.F[11] == 9 && m.F[14] == 10); /* second mesh */
    CHECK(m.V[3 * 8] == 1 && m.V[3 * 8 + 1] == 0 && m.V[3 * 9 + 1] == 1);
  }
  km_mesh_free(&m);
  /* nodes: only mesh 1, placed by a child (translation) of a rotated, scaled parent (TRS,
   * composed down the hierarchy); then mirrored, which flips the winding */
  char *tail = strrchr(json, '}');
  if (tail) {
    char nodes[4096];
    snprintf(nodes, sizeof nodes,
             "%.*s,\"nodes\":[{\"children\":[1],\"rotation\":[0.70710678118654757,0,0,"
             "0.70710678118654757],\"scale\":[2,2,2]},{\"mesh\":1,\"translation\":[0,0,1]}],"
             "\"scenes\":[{\"nodes\":[0]}],\"scene\":0}",
             (int)(tail - json), json);
    CHECK_OK(km_mesh_parse(nodes, strlen(nodes), KM_FORMAT_GLTF, "nodes.gltf", &m, KM_E));
    CHECK(m.n_vertices == 4 && m.n_faces == 2);
    if (m.n_vertices == 4) {
      const double want[12] = {0, -2, 0, 2, -2, 0, 2, -2, 2, 0, -2, 2};
      double dev = 0;
      for (int i = 0; i < 12; ++i)
        dev = fmax(dev, fabs(m.V[i] - want[i]));
      CHECK_MSG(dev < 1e-12, "node transforms: deviation %g", dev);
      CHECK(m.F[0] == 0 && m.F[1] == 1 && m.F[2] == 2);
    }
    km_mesh_free(&m);
    snprintf(nodes, sizeof nodes,
             "%.*s,\"nodes\":[{\"children\":[1],\"scale\":[-1,1,1]},{\"mesh\":1}],"
             "\"scenes\":[{\"nodes\":[0]}]}",
             (int)(tail - json), json);
    CHECK_OK(km_mesh_parse(nodes, strlen(nodes), KM_FORMAT_GLTF, "mirror.gltf", &m, KM_E));
    CHECK(m.n_faces == 2 && m.F[0] == 0 && m.F[1] == 2 && m.F[2] == 1 && m.V[3] == -1);
    km_mesh_free(&m);
  }
  /* tests/data/quad.gltf: NORMAL and TEXCOORD_0 (glTF's top-left v turned to OBJ's) */
  CHECK_OK(km_mesh_read(KM_TEST_DATA "/quad.gltf", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_faces == 2 && m.UV && m.N);
  if (m.UV && m.N && m.n_vertices == 4) {
    const double uv[8] = {0, 0, 1, 0, 1, 1, 0, 1};
    for (int i = 0; i < 8; ++i)
      CHECK(m.UV[i] == uv[i]);
    CHECK(m.N[2] == 1 && m.N[11] == 1 && m.F[3] == 0 && m.F[5] == 3);
  }
  km_mesh_free(&m);
  /* bad files: clear errors */
  char bad[2048];
  snprintf(bad, sizeof bad, "%s", json);
  char *mode = strstr(bad, "\"mode\":4");
  if (mode) mode[7] = '1';
  CHECK_STATUS(km_mesh_parse(bad, strlen(bad), KM_FORMAT_GLTF, "lines.gltf", &m, KM_E),
               KM_ERR_UNSUPPORTED);
  CHECK_MSG(strstr(km_test_err.message, "meshes[1].primitives[0]") &&
                strstr(km_test_err.message, "triangles"),
            "%s", km_test_err.message);
  /* the same indices as a strip (mode 5) and as a fan (6): the triangles they stand for, in
   * the spec's order and winding (strip t: t, t + 1 + t % 2, t + 2 - t % 2; fan t: t + 1,
   * t + 2, 0), a repeated index giving a collapsed face; mesh 1's vertices start at 7 */
  for (int fan = 0; fan < 2; ++fan) {
    snprintf(bad, sizeof bad, "%s", json);
    char *md = strstr(bad, "\"mode\":4");
    if (md) md[7] = fan ? '6' : '5';
    CHECK_OK(km_mesh_parse(bad, strlen(bad), KM_FORMAT_GLTF, "strip.gltf", &m, KM_E));
    CHECK(m.n_vertices == 11 && m.n_faces == 7);
    if (m.n_faces == 7) {
      const int32_t strip[12] = {0, 1, 2, 1, 0, 2, 2, 0, 2, 0, 3, 2};
      const int32_t fanf[12] = {1, 2, 0, 2, 0, 0, 0, 2, 0, 2, 3, 0};
      bool same = true;
      for (int k = 0; k < 12; ++k)
        same = same && m.F[9 + k] == 7 + (fan ? fanf : strip)[k];
      CHECK_MSG(same, "%s: faces %d %d %d, %d %d %d, ...", fan ? "fan" : "strip", m.F[9], m.F[10],
                m.F[11], m.F[12], m.F[13], m.F[14]);
    }
    km_mesh_free(&m);
  }
  snprintf(bad, sizeof bad, "%s", json);
  char *cnt = strstr(bad, "\"count\":6");
  if (cnt) cnt[8] = '9';
  CHECK_STATUS(km_mesh_parse(bad, strlen(bad), KM_FORMAT_GLTF, "short.gltf", &m, KM_E),
               KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "does not fit"), "%s", km_test_err.message);

  /* every prefix of a kinemesh .glb: an error or (the whole file) a mesh */
  CHECK(km_test_run("rm -rf attr_g && mkdir attr_g", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o attr_g/c.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 3 --character attr_g/c.obj -o "
                           "attr_g/w.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " pose --mesh attr_g/c.obj --motion attr_g/w.json -o attr_g/p.glb",
                    NULL) == 0);
  char *data = NULL;
  size_t size = 0;
  CHECK_OK(km__read_file("attr_g/p.glb", &data, &size, KM_E));
  size_t bad_prefixes = 0;
  for (size_t n = 0; data && n < size; n += 1 + n / 64)
    if (km_mesh_parse(data, n, KM_FORMAT_GLTF, "p.glb", &m, KM_E) == KM_OK) {
      ++bad_prefixes;
      km_mesh_free(&m);
    }
  CHECK_MSG(bad_prefixes == 0, "%zu truncated prefixes parsed", bad_prefixes);
  CHECK(data && km_mesh_parse(data, size, KM_FORMAT_GLTF, "p.glb", &m, KM_E) == KM_OK);
  km_mesh_free(&m);
  free(data);
  /* ... and every verb that reads a mesh reads it: convert to OBJ, same vertex count */
  CHECK(km_test_run(KM_CLI " convert attr_g/p.glb attr_g/p.obj", NULL) == 0);
  km_mesh a = {0}, b = {0};
  CHECK_OK(km_mesh_read("attr_g/c.obj", &a, KM_E));
  CHECK_OK(km_mesh_read("attr_g/p.obj", &b, KM_E));
  CHECK(a.n_vertices == b.n_vertices && a.n_faces == b.n_faces && a.n_faces &&
        memcmp(a.F, b.F, a.n_faces * 3 * sizeof(int32_t)) == 0);
  km_mesh_free(&a);
  km_mesh_free(&b);
  km_test_run("rm -rf attr_g", NULL);
}

/* A glTF's material (issue 11: a textured model must not come out grey): the first
 * primitive's base colour factor, metallic and roughness factors and base colour texture (a
 * 1x1 PNG in a data: URI) are read, and a .glb written from the mesh carries them: the image
 * bytes identical, the factors the same, read back as glTF in. An image that is neither PNG nor
 * JPEG is left out with a warning, the mesh still read. */
static void test_material(void) {
  static const char png_b64[] = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDw"
                                "AEhQGAhKmMIQAAAABJRU5ErkJggg==";
  char json[4096], *quad = NULL;
  size_t qn = 0;
  CHECK_OK(km__read_file(KM_TEST_DATA "/quad.gltf", &quad, &qn, KM_E));
  if (!quad) return;
  /* quad.gltf with a material on its primitive */
  cJSON *j = cJSON_Parse(quad);
  free(quad);
  CHECK(j != NULL);
  if (!j) return;
  cJSON *pr = cJSON_GetArrayItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "meshes"), 0), "primitives"),
      0);
  cJSON_AddNumberToObject(pr, "material", 0);
  snprintf(json, sizeof json,
           "{\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.25,1,1],"
           "\"metallicFactor\":0,\"roughnessFactor\":0.75,\"baseColorTexture\":{\"index\":0}}}],"
           "\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"data:image/png;base64,%s\"}]}",
           png_b64);
  cJSON *add = cJSON_Parse(json), *it;
  cJSON_ArrayForEach(it, add) cJSON_AddItemToObject(j, it->string, cJSON_Duplicate(it, 1));
  char *text = cJSON_PrintUnformatted(j);
  km_mesh m = {0}, r = {0};
  CHECK_OK(km_mesh_parse(text, strlen(text), KM_FORMAT_GLTF, "mat.gltf", &m, KM_E));
  const km_mesh_material *mm = m.n_materials == 1 ? m.materials : NULL;
  CHECK(mm && mm->first_face == 0 && mm->n_faces == m.n_faces);
  CHECK_MSG(mm && mm->image && mm->image_size == 70 && !memcmp(mm->image, "\x89PNG", 4) &&
                !strcmp(mm->image_mime, "image/png"),
            "material read: image %zu bytes", mm ? mm->image_size : 0);
  CHECK(mm && mm->base_color[0] == 0.5 && mm->base_color[1] == 0.25 && mm->metallic == 0 &&
        mm->roughness == 0.75);
  /* written to a .glb (the rest frame twice) and read back */
  CHECK(km_test_run("rm -rf attr_m && mkdir attr_m", NULL) == 0);
  km_anim_writer *w = NULL;
  CHECK_OK(km_anim_writer_open("attr_m/out.glb", &m, NULL, &w, KM_E));
  for (int k = 0; w && k < 2; ++k)
    CHECK_OK(km_anim_writer_push(w, m.V, KM_E));
  if (w) CHECK_OK(km_anim_writer_close(&w, KM_E));
  CHECK_OK(km_mesh_read("attr_m/out.glb", &r, KM_E));
  const km_mesh_material *rm = r.n_materials == 1 ? r.materials : NULL;
  CHECK_MSG(rm && mm && rm->image_size == mm->image_size &&
                !memcmp(rm->image, mm->image, mm->image_size) &&
                !memcmp(rm->base_color, mm->base_color, sizeof rm->base_color) &&
                rm->metallic == 0 && rm->roughness == 0.75,
            "material written: %s", rm ? "differs" : "missing");
  km_mesh_free(&r);
  km_mesh_free(&m);
  /* a second primitive (the quad again, the same attributes: its vertices are shared, read
   * once) with a plain material: two runs of faces, each its material, written as two
   * primitives over one set of vertices and read back so */
  cJSON *pr2 = cJSON_Duplicate(pr, 1);
  cJSON_ReplaceItemInObject(pr2, "material", cJSON_CreateNumber(1));
  cJSON_AddItemToArray(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "meshes"), 0), "primitives"),
      pr2);
  cJSON *plain = cJSON_Parse("{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.2,0.4,0.6,1]}}");
  cJSON_AddItemToArray(cJSON_GetObjectItem(j, "materials"), plain);
  free(text);
  text = cJSON_PrintUnformatted(j);
  CHECK_OK(km_mesh_parse(text, strlen(text), KM_FORMAT_GLTF, "two.gltf", &m, KM_E));
  CHECK_MSG(m.n_materials == 2 && m.n_faces == 4 && m.n_vertices == 4 &&
                m.materials[0].first_face == 0 && m.materials[0].n_faces == 2 &&
                m.materials[1].first_face == 2 && m.materials[1].n_faces == 2 &&
                m.materials[0].image && !m.materials[1].image &&
                m.materials[1].base_color[1] == 0.4 && m.materials[1].metallic == 1,
            "two materials: %zu", m.n_materials);
  CHECK_OK(km_anim_writer_open("attr_m/two.glb", &m, NULL, &w, KM_E));
  for (int k = 0; w && k < 2; ++k)
    CHECK_OK(km_anim_writer_push(w, m.V, KM_E));
  if (w) CHECK_OK(km_anim_writer_close(&w, KM_E));
  CHECK_OK(km_mesh_read("attr_m/two.glb", &r, KM_E));
  CHECK_MSG(r.n_materials == 2 && r.n_faces == 4 && r.n_vertices == 4 &&
                r.materials[1].first_face == 2 && r.materials[1].n_faces == 2 &&
                r.materials[0].image_size == 70 && r.materials[1].base_color[2] == 0.6 &&
                !memcmp(r.F, m.F, sizeof(int32_t) * 12),
            "two materials written: %zu", r.n_materials);
  km_mesh_free(&r);
  km_mesh_free(&m);
  /* the image as a file beside a .gltf read from disk, its uri percent-encoded as Blender
   * writes a name with a space; a uri that leaves the folder once decoded is refused */
  {
    unsigned char *png = NULL; /* the data: URI's image, as read */
    size_t pn = 0;
    char *t0 = cJSON_PrintUnformatted(j);
    CHECK_OK(km_mesh_parse(t0, strlen(t0), KM_FORMAT_GLTF, "uri.gltf", &m, KM_E));
    free(t0);
    if (m.n_materials && m.materials[0].image) {
      png = m.materials[0].image, pn = m.materials[0].image_size;
      m.materials[0].image = NULL;
    }
    km_mesh_free(&m);
    CHECK(png && pn == 70);
    FILE *pf = fopen("attr_m/my skin.png", "wb");
    if (pf && png) fwrite(png, 1, pn, pf);
    if (pf) fclose(pf);
    const char *uris[2] = {"my%20skin.png", "%2E%2E/attr_m/my%20skin.png"};
    for (int k = 0; k < 2; ++k) {
      cJSON *im = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "images"), 0);
      cJSON_ReplaceItemInObject(im, "uri", cJSON_CreateString(uris[k]));
      char *t = cJSON_PrintUnformatted(j);
      pf = fopen("attr_m/pct.gltf", "w");
      if (pf && t) fputs(t, pf);
      if (pf) fclose(pf);
      free(t);
      CHECK_OK(km_mesh_read("attr_m/pct.gltf", &m, KM_E));
      bool got = m.n_materials == 2 && m.materials[0].image_size == pn && png &&
                 !memcmp(m.materials[0].image, png, pn);
      CHECK_MSG(k == 0 ? got : m.n_materials == 2 && !m.materials[0].image, "%s: the image %s",
                uris[k], got ? "was read" : "was not read");
      km_mesh_free(&m);
    }
    free(png);
  }
  /* an image that is not PNG or JPEG: left out, the factors and the mesh kept */
  cJSON *img = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "images"), 0);
  cJSON_ReplaceItemInObject(img, "uri", cJSON_CreateString("data:image/png;base64,AAAAAAAAAAAA"));
  free(text);
  text = cJSON_PrintUnformatted(j);
  CHECK_OK(km_mesh_parse(text, strlen(text), KM_FORMAT_GLTF, "bad.gltf", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_materials == 2 && !m.materials[0].image &&
        m.materials[0].base_color[0] == 0.5);
  km_mesh_free(&m);
  free(text);
  cJSON_Delete(add);
  cJSON_Delete(j);
}

/* An OBJ's material (mtllib + usemtl): the library beside it, the used material's Kd, Ns and
 * map_Kd image (options before the file name skipped) read into km_mesh.material; a texture
 * is the colour (factor 1, not Kd's 0.8); without a texture, Kd; a missing library or image is
 * a warning and the mesh still reads. */
/* A 1x1 RGBA PNG, 70 bytes. */
static const unsigned char k_png[70] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48,
    0x44, 0x52, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x06, 0x00, 0x00,
    0x00, 0x1f, 0x15, 0xc4, 0x89, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x44, 0x41, 0x54, 0x78,
    0xda, 0x63, 0xfc, 0xcf, 0xc0, 0x50, 0x0f, 0x00, 0x04, 0x85, 0x01, 0x80, 0x84, 0xa9,
    0x8c, 0x21, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

/* Writes n bytes (put_file) or a string (put_text) to path. */
static void put_file(const char *path, const void *data, size_t n) {
  FILE *f = fopen(path, "wb");
  CHECK_MSG(f != NULL, "cannot write %s", path);
  if (f) fwrite(data, 1, n, f), fclose(f);
}
static void put_text(const char *path, const char *text) { put_file(path, text, strlen(text)); }

/* attr_o/q.obj: quad with "mtllib <lib>" and "usemtl <use>", read into *m; its one material,
 * or NULL. */
static const km_mesh_material *read_quad_material(const char *quad, const char *lib,
                                                  const char *use, km_mesh *m) {
  char obj[512];
  snprintf(obj, sizeof obj, "mtllib %s\nusemtl %s\n%s", lib, use, quad);
  put_text("attr_o/q.obj", obj);
  CHECK_OK(km_mesh_read("attr_o/q.obj", m, KM_E));
  return m->n_materials == 1 ? m->materials : NULL;
}

static void test_obj_material(void) {
  const unsigned char *png = k_png;
  CHECK(km_test_run("rm -rf attr_o && mkdir -p attr_o/tex", NULL) == 0);
  put_file("attr_o/tex/skin.png", png, sizeof k_png);
  put_text("attr_o/q.mtl", "newmtl red\nKd 1 0 0\n\nnewmtl skin\nNs 250\nKd 0.8 0.8 0.8\n"
                           "map_Kd -s 1 1 1 tex\\skin.png\n\nnewmtl plain\nKd 0.2 0.4 0.6\n");
  const char *quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                     "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
  const char *use[3] = {"skin", "plain", "none"};
  for (int k = 0; k < 3; ++k) {
    km_mesh m = {0};
    const km_mesh_material *mm = read_quad_material(quad, "q.mtl", use[k], &m);
    if (k == 0)
      CHECK_MSG(mm && mm->image_size == sizeof k_png && !memcmp(mm->image, png, sizeof k_png) &&
                    mm->base_color[0] == 1 && fabs(mm->roughness - 0.5) < 1e-12 &&
                    mm->metallic == 0,
                "skin: %s", mm ? "differs" : "no material");
    if (k == 1)
      CHECK_MSG(mm && !mm->image && mm->base_color[0] == 0.2 && mm->base_color[2] == 0.6,
                "plain: %s", mm ? "differs" : "no material");
    if (k == 2) CHECK_MSG(!m.materials, "a material that is not in the library was made up");
    CHECK(m.n_vertices == 4 && m.UV);
    km_mesh_free(&m);
  }
  /* what other exporters write: a texture name with a space after options (-s takes three
   * numbers, -bm one, -o two here), a Windows path from the machine that wrote it (its file
   * beside the library), several libraries on one mtllib line, and Tr for the alpha */
  put_file("attr_o/my skin.png", png, sizeof k_png);
  put_text("attr_o/q2.mtl", "newmtl spaced\nmap_Kd -s 1 1 1 -bm 0.5 -o 0.5 0.5 my skin.png\n\n"
                            "newmtl windows\nTr 0.25\nmap_Kd C:\\Users\\me\\Textures\\my "
                            "skin.png\n");
  const char *use2[2] = {"spaced", "windows"};
  for (int k = 0; k < 2; ++k) {
    km_mesh m = {0};
    const km_mesh_material *mm = read_quad_material(quad, "none.mtl q2.mtl", use2[k], &m);
    CHECK_MSG(mm && mm->image_size == sizeof k_png && !memcmp(mm->image, png, sizeof k_png) &&
                  mm->base_color[3] == (k ? 0.75 : 1),
              "%s: %s", use2[k], mm ? "differs" : "no material");
    km_mesh_free(&m);
  }
  km_mesh m0 = {0}; /* q.obj back on q.mtl */
  read_quad_material(quad, "q.mtl", "skin", &m0);
  km_mesh_free(&m0);
  /* the library gone: the mesh reads, no material */
  CHECK(km_test_run("rm attr_o/q.mtl", NULL) == 0);
  km_mesh m = {0};
  CHECK_OK(km_mesh_read("attr_o/q.obj", &m, KM_E));
  CHECK(m.n_vertices == 4 && !m.materials && !m.n_materials);
  km_mesh_free(&m);
}

/* Materials written with an OBJ (issue 11: a textured model must not come out grey in
 * Blender): km_mesh_write's "<stem>.mtl" + images and a frame folder's materials.mtl, read back
 * by kinemesh's own OBJ reader with every material's colour, alpha, metallic, roughness, image
 * and run of faces as written. */
static bool same_material(const km_mesh_material *a, const km_mesh_material *b) {
  for (int c = 0; c < 4; ++c)
    if (fabs(a->base_color[c] - b->base_color[c]) > 1e-15) return false;
  return fabs(a->metallic - b->metallic) < 1e-15 && fabs(a->roughness - b->roughness) < 1e-15 &&
         a->first_face == b->first_face && a->n_faces == b->n_faces &&
         a->image_size == b->image_size && a->alpha_mode == b->alpha_mode &&
         !memcmp(&a->image_sampler, &b->image_sampler, sizeof a->image_sampler) &&
         a->double_sided == b->double_sided &&
         (!a->image_size || !memcmp(a->image, b->image, a->image_size)) &&
         !strcmp(a->image_mime, b->image_mime);
}

static void test_obj_material_out(void) {
  unsigned char *png = (unsigned char *)k_png; /* km_mesh_material.image is not const: only read */
  CHECK(km_test_run("rm -rf attr_m && mkdir attr_m", NULL) == 0);
  /* a strip of 4 quads (8 triangles): textured, plain, textured with the same image */
  double V[10 * 3], UV[10 * 2];
  int32_t F[8 * 3];
  for (int i = 0; i < 5; ++i)
    for (int r = 0; r < 2; ++r) {
      int v = 2 * i + r;
      V[3 * v] = i, V[3 * v + 1] = r, V[3 * v + 2] = 0.1 * i * i;
      UV[2 * v] = i / 4.0, UV[2 * v + 1] = r;
    }
  for (int i = 0; i < 4; ++i) {
    int32_t a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
    int32_t *t = F + 6 * i;
    t[0] = a, t[1] = c, t[2] = d, t[3] = a, t[4] = d, t[5] = b;
  }
  km_mesh_material mat[3] = {{.base_color = {1, 1, 1, 1},
                              .metallic = 0,
                              .roughness = 0.5,
                              .image = png,
                              .image_size = sizeof k_png,
                              .image_mime = "image/png",
                              .first_face = 0,
                              .n_faces = 2},
                             {.base_color = {0.25, 0.5, 0.125, 0.75},
                              .metallic = 0.5,
                              .roughness = 0.25,
                              .first_face = 2,
                              .n_faces = 4,
                              .alpha_mode = KM_ALPHA_BLEND},
                             {.base_color = {1, 1, 1, 1},
                              .metallic = 0,
                              .roughness = 1,
                              .image = png,
                              .image_size = sizeof k_png,
                              .image_mime = "image/png",
                              .first_face = 6,
                              .n_faces = 2}};
  km_mesh m = {
      .V = V, .F = F, .n_vertices = 10, .n_faces = 8, .UV = UV, .materials = mat, .n_materials = 3};
  CHECK_OK(km_mesh_write("attr_m/out/strip.obj", &m, NULL, KM_E));
  /* one image for the two materials that share it, the library beside the OBJ */
  CHECK(access("attr_m/out/strip.mtl", F_OK) == 0);
  CHECK(access("attr_m/out/strip_texture_0.png", F_OK) == 0);
  CHECK(access("attr_m/out/strip_texture_2.png", F_OK) != 0);
  km_mesh r = {0};
  CHECK_OK(km_mesh_read("attr_m/out/strip.obj", &r, KM_E));
  CHECK_MSG(r.n_materials == 3, "%zu materials read back", r.n_materials);
  for (size_t k = 0; k < 3 && k < r.n_materials; ++k)
    CHECK_MSG(same_material(&mat[k], &r.materials[k]), "material %zu differs after the OBJ", k);
  CHECK(r.n_vertices == 10 && r.UV && !memcmp(r.UV, UV, sizeof UV));
  km_mesh_free(&r);

  /* the other textures: through a .glb all four with their factors (the images stored once:
   * occlusion is the base colour's bytes, emissive the normal map's); through an OBJ the normal
   * (map_Bump -bm) and emissive (map_Ke, Ke) maps, which an .mtl can name */
  static unsigned char png2[70], png3[70];
  memcpy(png2, png, 70), memcpy(png3, png, 70);
  png2[69] ^= 1, png3[69] ^= 2; /* other bytes after the signature: other images */
  km_mesh_image im0 = {.bytes = png, .size = 70, .mime = "image/png"},
                im2 = {.bytes = png2, .size = 70, .mime = "image/png"},
                im3 = {.bytes = png3, .size = 70, .mime = "image/png"};
  mat[0].maps[KM_MAP_NORMAL] = im2, mat[0].maps[KM_MAP_EMISSIVE] = im2;
  mat[0].maps[KM_MAP_METALLIC_ROUGHNESS] = im3, mat[0].maps[KM_MAP_OCCLUSION] = im0;
  mat[0].normal_scale = 0.5, mat[0].occlusion_strength = 0.8;
  /* and how alpha is drawn: hair cut out (MASK at 0.3), both sides drawn; an OBJ says neither,
   * only d (its material 1, alpha 0.75, reads back as BLEND) */
  mat[0].alpha_mode = KM_ALPHA_MASK, mat[0].alpha_cutoff = 0.3, mat[0].double_sided = true;
  /* pixel art: its base colour sampled NEAREST and clamped, its normal map mirrored; the same
   * image (png) as material 2's default-sampled base colour: one image, two textures */
  mat[0].image_sampler = (km_mesh_sampler){9728, 9728, 33071, 33071};
  mat[0].maps[KM_MAP_NORMAL].sampler.wrap_s = 33648;
  mat[0].emissive[0] = 0.1, mat[0].emissive[1] = 0.2, mat[0].emissive[2] = 0.3;
  for (int out = 0; out < 3; ++out) { /* glb, compressed glb (the packed writer), OBJ */
    const char *path = out < 2 ? "attr_m/maps.glb" : "attr_m/maps/maps.obj";
    if (out < 2) {
      km_anim_options ao = {.compress = out == 1};
      km_anim_writer *w = NULL;
      CHECK_OK(km_anim_writer_open(path, &m, &ao, &w, KM_E));
      for (int k = 0; w && k < 2; ++k)
        CHECK_OK(km_anim_writer_push(w, V, KM_E));
      if (w) CHECK_OK(km_anim_writer_close(&w, KM_E));
    } else {
      CHECK_OK(km_mesh_write(path, &m, NULL, KM_E));
    }
    CHECK_OK(km_mesh_read(path, &r, KM_E));
    const km_mesh_material *q = r.n_materials == 3 ? r.materials : NULL;
    CHECK_MSG(q != NULL, "%s: %zu materials", path, r.n_materials);
    /* every run of faces in its place (a third material's faces were once dropped from a glb;
     * the glb writer may reorder faces within a run for the vertex cache) */
    CHECK_MSG(q && r.n_faces == 8 && same_material(&mat[1], q + 1) && same_material(&mat[2], q + 2),
              "%s: the faces or their materials differ", path);
    for (int k = 0; q && k < KM_MAP_COUNT; ++k) {
      bool carried = out < 2 || k == KM_MAP_NORMAL || k == KM_MAP_EMISSIVE;
      const km_mesh_image *a = &mat[0].maps[k], *b = &q->maps[k];
      CHECK_MSG(carried ? b->size == a->size && b->bytes && !memcmp(b->bytes, a->bytes, a->size) &&
                              !strcmp(b->mime, a->mime) &&
                              b->sampler.wrap_s == (out < 2 ? a->sampler.wrap_s : 0)
                        : !b->bytes,
                "%s: map %d %s", path, k, b->bytes ? "differs" : "missing");
      CHECK(!q[1].maps[k].bytes && !q[2].maps[k].bytes);
    }
    km_mesh_material want = mat[0];
    if (out == 2) /* what an .mtl cannot say */
      want.alpha_mode = KM_ALPHA_OPAQUE, want.double_sided = false,
      want.image_sampler = (km_mesh_sampler){0};
    CHECK_MSG(q && q->normal_scale == 0.5 && q->emissive[1] == 0.2 &&
                  (out == 2 || (q->occlusion_strength == 0.8 && q->alpha_cutoff == 0.3)) &&
                  same_material(&want, q),
              "%s: the factors differ", path);
    km_mesh_free(&r);
  }
  /* one image per distinct bytes: the base colour, the normal / emissive, the OBJ's two */
  CHECK(km_test_run("test $(ls attr_m/maps | grep -c texture) = 2", NULL) == 0);
  for (int k = 0; k < KM_MAP_COUNT; ++k)
    mat[0].maps[k] = (km_mesh_image){0};
  mat[0].alpha_mode = KM_ALPHA_OPAQUE, mat[0].double_sided = false;
  mat[0].image_sampler = (km_mesh_sampler){0};

  /* runs that do not tile the faces: the first material over all, as the glb writer does */
  mat[1].first_face = 3;
  CHECK_OK(km_mesh_write("attr_m/odd.obj", &m, NULL, KM_E));
  CHECK_OK(km_mesh_read("attr_m/odd.obj", &r, KM_E));
  CHECK(r.n_materials == 1 && r.materials[0].n_faces == 8 && r.materials[0].image_size == 70);
  km_mesh_free(&r);
  mat[1].first_face = 2;

  /* a frame folder: materials.mtl and the image once, every frame naming them; a second run
   * replaces the folder (its material files are the writer's own) */
  for (int run = 0; run < 2; ++run) {
    km_anim_writer *w = NULL;
    CHECK_OK(km_anim_writer_open("attr_m/frames", &m, NULL, &w, KM_E));
    double X[30];
    for (int f = 0; f < 3 && w; ++f) {
      memcpy(X, V, sizeof X);
      for (int v = 0; v < 10; ++v)
        X[3 * v + 1] += 0.1 * f * v;
      CHECK_OK(km_anim_writer_push(w, X, KM_E));
    }
    CHECK_OK(km_anim_writer_close(&w, KM_E));
  }
  CHECK(access("attr_m/frames/materials.mtl", F_OK) == 0);
  CHECK(access("attr_m/frames/texture_0.png", F_OK) == 0);
  CHECK_OK(km_mesh_read("attr_m/frames/frame_000002.obj", &r, KM_E));
  CHECK_MSG(r.n_materials == 3, "%zu materials in a frame", r.n_materials);
  for (size_t k = 0; k < 3 && k < r.n_materials; ++k)
    CHECK_MSG(same_material(&mat[k], &r.materials[k]), "material %zu differs in a frame", k);
  CHECK(r.n_vertices == 10 && fabs(r.V[3 * 9 + 1] - (1 + 0.2 * 9)) < 1e-12);
  km_mesh_free(&r);
  km_anim_info info;
  CHECK_OK(km_anim_info_read("attr_m/frames", &info, KM_E));
  CHECK(info.frames == 3 && info.vertices == 10);
  /* a PLY folder has no material file (PLY has no materials) */
  km_anim_options po = {.format = KM_ANIM_PLY_DIR};
  km_anim_writer *w = NULL;
  CHECK_OK(km_anim_writer_open("attr_m/plys", &m, &po, &w, KM_E));
  if (w) CHECK_OK(km_anim_writer_push(w, V, KM_E));
  CHECK_OK(km_anim_writer_close(&w, KM_E));
  CHECK(access("attr_m/plys/frame_000000.ply", F_OK) == 0 &&
        access("attr_m/plys/materials.mtl", F_OK) != 0);
  /* what a SIGINT handler calls removes a half-written folder with its material files */
  CHECK_OK(km_anim_writer_open("attr_m/sig", &m, NULL, &w, KM_E));
  if (w) CHECK_OK(km_anim_writer_push(w, V, KM_E));
  CHECK(km_test_run("ls attr_m | grep -q '^sig.tmp'", NULL) == 0);
  km_remove_temporaries();
  CHECK_MSG(km_test_run("ls attr_m | grep -q '^sig'", NULL) != 0,
            "a temporary frame folder is left after the cleanup");
  km_anim_writer_free(&w);
  /* a folder holding something else is still not replaced */
  CHECK(km_test_run("touch attr_m/frames/notes.txt", NULL) == 0);
  CHECK(km_anim_writer_open("attr_m/frames", &m, NULL, &w, NULL) == KM_ERR_IO && !w);
}

/* Vertex colours (a scan's, a photogrammetry model's): read from PLY (uchar and float, with and
 * without alpha) and OBJ (v x y z r g b, 0..1 or 0..255), carried by every writer (PLY, OBJ,
 * .glb plain and compressed, frame folders) and read back. */
static double color_dev(const km_mesh *r, const double *c, size_t n, bool alpha) {
  if (!r->colors || r->n_vertices != n) return INFINITY;
  double d = 0;
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < (alpha ? 4 : 3); ++k)
      d = fmax(d, fabs(r->colors[4 * i + k] - c[4 * i + k]));
  return d;
}

static void test_colors(void) {
  CHECK(km_test_run("rm -rf attr_col && mkdir attr_col", NULL) == 0);
  put_text("attr_col/a.ply",
           "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0 255 0 0\n1 0 0 0 128 0\n0 1 0 0 0 51\n3 0 1 2\n");
  km_mesh m = {0}, r = {0};
  CHECK_OK(km_mesh_read("attr_col/a.ply", &m, KM_E));
  const double want[12] = {1, 0, 0, 1, 0, 128 / 255.0, 0, 1, 0, 0, 0.2, 1};
  CHECK_MSG(color_dev(&m, want, 3, true) < 1e-12, "PLY uchar colours: off by %g",
            color_dev(&m, want, 3, true));
  km_mesh_free(&m);
  put_text("attr_col/b.obj", "v 0 0 0 255 0 0\nv 1 0 0 0 128 0\nv 0 1 0 0 0 51\nf 1 2 3\n");
  /* a vertex without a colour among coloured ones (0..255) is white, not 1/255 */
  put_text("attr_col/c.obj", "v 0 0 0 255 0 0\nv 1 0 0\nv 0 1 0 0 0 51\nf 1 2 3\n");
  CHECK_OK(km_mesh_read("attr_col/c.obj", &m, KM_E));
  CHECK_MSG(m.colors && m.colors[4] == 1 && m.colors[5] == 1 && m.colors[6] == 1 &&
                m.colors[0] == 1 && fabs(m.colors[10] - 0.2) < 1e-12,
            "OBJ: a vertex without a colour is not white");
  km_mesh_free(&m);
  CHECK_OK(km_mesh_read("attr_col/b.obj", &m, KM_E));
  CHECK_MSG(color_dev(&m, want, 3, true) < 1e-12, "OBJ 0..255 colours: off by %g",
            color_dev(&m, want, 3, true));
  km_mesh_free(&m);
  /* a strip with colours and alpha, through every writer */
  double V[8 * 3], C[8 * 4];
  int32_t F[6 * 3];
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 2; ++k) {
      int v = 2 * i + k;
      V[3 * v] = i, V[3 * v + 1] = k, V[3 * v + 2] = 0.2 * i;
      C[4 * v] = v / 7.0, C[4 * v + 1] = 1 - v / 7.0, C[4 * v + 2] = (v % 3) / 2.0;
      C[4 * v + 3] = v == 5 ? 0.6 : 1;
    }
  for (int i = 0; i < 3; ++i) {
    int32_t *t = F + 6 * i, a = 2 * i;
    t[0] = a, t[1] = a + 2, t[2] = a + 3, t[3] = a, t[4] = a + 3, t[5] = a + 1;
  }
  m = (km_mesh){.V = V, .F = F, .n_vertices = 8, .n_faces = 6, .colors = C};
  /* 8-bit RGBA (the live page's /mesh, PLY uchar): rounded, and clamped where out of [0, 1] */
  unsigned char c8[8 * 4];
  CHECK(km_mesh_colors_rgba8(&m, c8));
  CHECK_MSG(c8[4 * 3] == 109 && c8[4 * 3 + 1] == 146 && c8[4 * 5 + 3] == 153 && c8[4 * 7] == 255,
            "8-bit colours %d %d %d %d", c8[12], c8[13], c8[23], c8[28]);
  C[0] = -0.2, C[1] = 1.3;
  CHECK(km_mesh_colors_rgba8(&m, c8) && c8[0] == 0 && c8[1] == 255);
  C[0] = 0, C[1] = 1;
  CHECK(!km_mesh_colors_rgba8(&(km_mesh){.V = V, .n_vertices = 8}, c8));
  const char *paths[4] = {"attr_col/o/s.ply", "attr_col/o/s.obj", "attr_col/o/s.glb",
                          "attr_col/o/z.glb"};
  for (int k = 0; k < 4; ++k) {
    if (k < 2) {
      km_mesh_write_options wo = {.ply = KM_PLY_ASCII};
      CHECK_OK(km_mesh_write(paths[k], &m, &wo, KM_E));
    } else {
      km_anim_options ao = {.compress = k == 3};
      km_anim_writer *w = NULL;
      CHECK_OK(km_anim_writer_open(paths[k], &m, &ao, &w, KM_E));
      for (int q = 0; w && q < 2; ++q)
        CHECK_OK(km_anim_writer_push(w, V, KM_E));
      if (w) CHECK_OK(km_anim_writer_close(&w, KM_E));
    }
    CHECK_OK(km_mesh_read(paths[k], &r, KM_E));
    /* PLY: 8 bits; OBJ: exact, no alpha; glb: 16-bit linear */
    double tol = k == 0 ? 0.5 / 255 + 1e-12 : k == 1 ? 1e-15 : 1e-4;
    double dev = color_dev(&r, C, 8, k != 1);
    CHECK_MSG(dev <= tol, "%s: colours off by %g", paths[k], dev);
    km_mesh_free(&r);
  }
  /* frame folders, PLY and OBJ */
  for (int k = 0; k < 2; ++k) {
    km_anim_options ao = {.format = k ? KM_ANIM_OBJ_DIR : KM_ANIM_PLY_DIR};
    km_anim_writer *w = NULL;
    const char *dir = k ? "attr_col/fo" : "attr_col/fp";
    CHECK_OK(km_anim_writer_open(dir, &m, &ao, &w, KM_E));
    if (w) CHECK_OK(km_anim_writer_push(w, V, KM_E));
    CHECK_OK(km_anim_writer_close(&w, KM_E));
    char fp[64];
    snprintf(fp, sizeof fp, "%s/frame_000000.%s", dir, k ? "obj" : "ply");
    CHECK_OK(km_mesh_read(fp, &r, KM_E));
    double dev = color_dev(&r, C, 8, !k);
    CHECK_MSG(dev <= (k ? 1e-15 : 0.5 / 255 + 1e-12), "%s: colours off by %g", fp, dev);
    km_mesh_free(&r);
  }
}

int main(void) {
  test_gltf_in();
  test_material();
  test_obj_material();
  test_obj_material_out();
  test_colors();
  test_obj_read();
  test_ply_names();
  test_cli_textured();
  return km_test_finish("test_mesh_attributes");
}
