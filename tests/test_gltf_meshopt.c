/* glTF in, compressed (issue 11): the mesh reader decodes EXT_meshopt_compression and
 * KHR_mesh_quantization. (1) kinemesh's own --compress files (per-frame morphs, PCA morphs,
 * skin) read back with km_mesh_read: the vertex count and order of the mesh written, the same
 * triangles (the writer reorders triangles, never vertices), positions within the 14-bit grid's
 * rounding, UVs within 16-bit rounding, normals within the 8-bit octahedral encoding, and
 * equal to the plain file read the same way; the skin (km_mesh_read_skinned) has the plain
 * file's joints and its weights within their 8-bit rounding. (1b) km__gltf_accessor_read (for
 * the animation reader) gives a compressed morph target within half a grid step. (2) gltfpack's
 * output (-c, -cc, and quantisation alone) of a textured OBJ: every vertex on the original within
 * gltfpack's quantisation, its UV too (dequantised by KHR_texture_transform), the same triangle
 * count; and of kinemesh's plain skinned glb, read with its skin; skipped with a message without
 * gltfpack. (3) a corrupted compressed view
 * (its bytes, its byteLength, byteStride, count, mode) is a KM_ERR_PARSE naming the file and
 * the bufferView. */
#include "km_test.h"
#include "mesh/mesh.h"
#include "tube_fixture.h"

#include <cjson/cJSON.h>
#include <unistd.h>

enum { RINGS = 24, SEGS = 16, T = 12 };

static void frame(const km_mesh *m, int k, double *V) {
  double a = 0.6 * sin(2 * M_PI * k / (T - 1));
  for (size_t i = 0; i < m->n_vertices; ++i) {
    const double *p = m->V + 3 * i;
    double c = cos(a * p[0]), s = sin(a * p[0]);
    V[3 * i] = c * p[0] - s * (p[1] - 1.0);
    V[3 * i + 1] = 1.0 + s * p[0] + c * (p[1] - 1.0);
    V[3 * i + 2] = p[2] + 0.5 * k / (T - 1);
  }
}

static km_status write_anim(const char *path, const km_mesh *m, km_anim_export kind, bool z) {
  km_ssdr_options so = {.bones = 5, .iterations = 4};
  km_anim_options ao = {.fps = 30, .export_kind = kind, .morphs = 3, .skin = &so, .compress = z};
  km_anim_writer *w = NULL;
  km_error err = {0};
  km_anim_report rep;
  double *V = malloc(m->n_vertices * 3 * sizeof *V);
  km_status s = km_anim_writer_open(path, m, &ao, &w, &err);
  for (int k = 0; s == KM_OK && k < T; ++k) {
    frame(m, k, V);
    s = km_anim_writer_push(w, V, &err);
  }
  if (s == KM_OK) s = km_anim_writer_finish(&w, &rep, &err);
  km_anim_writer_free(&w);
  if (s != KM_OK) fprintf(stderr, "%s: %s\n", path, err.message);
  free(V);
  return s;
}

/* Triangles as a sorted list of (rotated so the smallest index leads) triples: the same set
 * with the same windings compares equal. */
static int tri_cmp(const void *a, const void *b) {
  const int32_t *x = a, *y = b;
  for (int k = 0; k < 3; ++k)
    if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
  return 0;
}
static int32_t *canonical_tris(const km_mesh *m) {
  int32_t *t = malloc(m->n_faces * 3 * sizeof *t);
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *s = m->F + 3 * f;
    int r = s[0] <= s[1] && s[0] <= s[2] ? 0 : s[1] <= s[2] ? 1 : 2;
    for (int k = 0; k < 3; ++k)
      t[3 * f + k] = s[(r + k) % 3];
  }
  qsort(t, m->n_faces, 3 * sizeof *t, tri_cmp);
  return t;
}

/* (1) kinemesh's own compressed files */
static void own_files(const km_mesh *m, const double *N) {
  static const km_anim_export kinds[3] = {KM_ANIM_EXPORT_MORPHS, KM_ANIM_EXPORT_MORPHS_PCA,
                                          KM_ANIM_EXPORT_SKIN};
  static const char *names[3] = {"morphs", "pca", "skin"};
  int32_t *t0 = canonical_tris(m);
  for (int k = 0; k < 3; ++k) {
    char a[96], b[96];
    snprintf(a, sizeof a, "test_gltf_meshopt_%ld_%s_p.glb", (long)getpid(), names[k]);
    snprintf(b, sizeof b, "test_gltf_meshopt_%ld_%s_z.glb", (long)getpid(), names[k]);
    CHECK(write_anim(a, m, kinds[k], false) == KM_OK);
    CHECK(write_anim(b, m, kinds[k], true) == KM_OK);
    km_mesh p = {0}, z = {0};
    CHECK_OK(km_mesh_read(a, &p, KM_E));
    CHECK_OK(km_mesh_read(b, &z, KM_E));
    CHECK_MSG(z.n_vertices == m->n_vertices && z.n_faces == m->n_faces,
              "%s: %zu vertices, %zu faces read; %zu, %zu written", names[k], z.n_vertices,
              z.n_faces, m->n_vertices, m->n_faces);
    if (z.n_vertices != m->n_vertices || z.n_faces != m->n_faces || !z.V) goto next;
    int32_t *tz = canonical_tris(&z);
    CHECK_MSG(!memcmp(t0, tz, m->n_faces * 3 * sizeof *t0), "%s: the triangles differ", names[k]);
    free(tz);
    /* The writer's grid: 14 bits over the largest extent (1.2 m here), a step that grows to
     * max morph delta / 32000 (the walk, 0.5 m, and the bend: < 1.5 m): half a step per axis. */
    double step = fmax(1.2 / 16383, 1.5 / 32000), worst = 0, worst_p = 0, worst_uv = 0;
    double worst_n = 1;
    for (size_t i = 0; i < m->n_vertices; ++i) {
      for (int c = 0; c < 3; ++c) {
        worst = fmax(worst, fabs(z.V[3 * i + c] - m->V[3 * i + c]));
        worst_p = fmax(worst_p, fabs(z.V[3 * i + c] - p.V[3 * i + c]));
      }
      for (int c = 0; z.UV && c < 2; ++c)
        worst_uv = fmax(worst_uv, fabs(z.UV[2 * i + c] - m->UV[2 * i + c]));
      if (z.N) {
        double dot = 0;
        for (int c = 0; c < 3; ++c)
          dot += z.N[3 * i + c] * N[3 * i + c];
        worst_n = fmin(worst_n, dot);
      }
    }
    CHECK_MSG(worst <= 0.5 * step + 1e-6 && worst_p <= 0.5 * step + 1e-6,
              "%s: positions off by %g m (plain file: %g m), half step %g m", names[k], worst,
              worst_p, 0.5 * step);
    CHECK_MSG(z.UV != NULL && worst_uv <= 1.0 / 65535 + 1e-9, "%s: UVs %s, off by %g", names[k],
              z.UV ? "read" : "missing", worst_uv);
    /* NORMAL where the file has it (the skin and morph files write the rest's normals) */
    if (p.N) CHECK_MSG(z.N && worst_n > 0.999, "%s: normals: min dot %g", names[k], worst_n);
    printf("# %s: %zu vertices in order, max position error %.2g m (half step %.2g m), UV %.2g, "
           "normal min dot %.5f\n",
           names[k], z.n_vertices, worst, 0.5 * step, worst_uv, worst_n);
    if (kinds[k] == KM_ANIM_EXPORT_SKIN) { /* the skin: same joints, 8-bit weights */
      km_mesh mp = {0}, mz = {0};
      km_mesh_skin sp = {0}, sz = {0};
      CHECK_OK(km_mesh_read_skinned(a, &mp, &sp, KM_E));
      CHECK_OK(km_mesh_read_skinned(b, &mz, &sz, KM_E));
      CHECK(sz.n_joints == sp.n_joints && sz.n_joints == 5 && sz.n_vertices == m->n_vertices);
      double werr = 0;
      bool same = sz.n_vertices == sp.n_vertices && sz.joints && sp.joints;
      for (size_t i = 0; same && i < 4 * sz.n_vertices; ++i) {
        if (sp.weights[i] > 1.0 / 255) same = sz.joints[i] == sp.joints[i];
        werr = fmax(werr, fabs(sz.weights[i] - sp.weights[i]));
      }
      /* each rounded to 1/255, the largest absorbing the sum's rounding (<= 1.5/255 more) */
      CHECK_MSG(same && werr <= 2.0 / 255, "skin: joints %s, weights off by %g",
                same ? "same" : "differ", werr);
      km_mesh_skin_free(&sp);
      km_mesh_skin_free(&sz);
      km_mesh_free(&mp);
      km_mesh_free(&mz);
    }
  next:
    km_mesh_free(&p);
    km_mesh_free(&z);
    remove(a);
    remove(b);
  }
  free(t0);
}

/* (1b) km__gltf_accessor_read, for the animation reader: the last morph target of the
 * compressed file (16-bit deltas on the grid, times the mesh node's scale) is the plain file's
 * within half a grid step. */
static int last_target(const char *path, unsigned char **data, size_t *size, double *scale) {
  *data = read_all(path, size);
  if (!*data || *size < 28) return -1;
  cJSON *root = cJSON_ParseWithLength((const char *)*data + 20, getu32(*data + 12));
  const cJSON *prim = cJSON_GetArrayItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "meshes"), 0), "primitives"),
      0);
  const cJSON *ts = cJSON_GetObjectItem(prim, "targets"); /* the last: frame 0's is zero */
  const cJSON *t =
      cJSON_GetObjectItem(cJSON_GetArrayItem(ts, cJSON_GetArraySize(ts) - 1), "POSITION");
  const cJSON *sc = NULL, *node;
  cJSON_ArrayForEach(node, cJSON_GetObjectItem(root, "nodes")) {
    if (cJSON_GetObjectItem(node, "mesh")) sc = cJSON_GetObjectItem(node, "scale");
  }
  *scale = sc ? cJSON_GetArrayItem(sc, 0)->valuedouble : 1.0;
  int a = cJSON_IsNumber(t) ? t->valueint : -1;
  cJSON_Delete(root);
  return a;
}

static void accessor_helper(const km_mesh *m) {
  char a[96], b[96];
  snprintf(a, sizeof a, "test_gltf_meshopt_%ld_acc_p.glb", (long)getpid());
  snprintf(b, sizeof b, "test_gltf_meshopt_%ld_acc_z.glb", (long)getpid());
  CHECK(write_anim(a, m, KM_ANIM_EXPORT_MORPHS, false) == KM_OK);
  CHECK(write_anim(b, m, KM_ANIM_EXPORT_MORPHS, true) == KM_OK);
  unsigned char *dp = NULL, *dz = NULL;
  size_t np = 0, nz = 0, cp = 0, cz = 0;
  double sp = 1, sz = 1, *xp = NULL, *xz = NULL;
  int ap = last_target(a, &dp, &np, &sp), az = last_target(b, &dz, &nz, &sz), kp = 0, kz = 0;
  CHECK(ap >= 0 && az >= 0 && sp == 1.0 && sz < 1e-3);
  CHECK_OK(km__gltf_accessor_read(dp, np, a, ap, &xp, &cp, &kp, KM_E));
  CHECK_OK(km__gltf_accessor_read(dz, nz, b, az, &xz, &cz, &kz, KM_E));
  CHECK(cp == m->n_vertices && cz == cp && kp == 3 && kz == 3);
  double worst = 0;
  for (size_t i = 0; xp && xz && cz == cp && i < 3 * cp; ++i)
    worst = fmax(worst, fabs(sz * xz[i] - xp[i]));
  CHECK_MSG(worst <= 0.5 * sz + 1e-6, "last target: off by %g m, grid step %g m", worst, sz);
  printf("# km__gltf_accessor_read: compressed last morph target within %.2g m (step %.2g m)\n",
         worst, sz);
  /* a missing accessor: a clear error */
  double *x = NULL;
  size_t c = 0;
  int k = 0;
  CHECK_STATUS(km__gltf_accessor_read(dz, nz, b, 999, &x, &c, &k, KM_E), KM_ERR_PARSE);
  CHECK(x == NULL && strstr(km_test_err.message, "999"));
  free(xp);
  free(xz);
  free(dp);
  free(dz);
  remove(a);
  remove(b);
}

/* (2) gltfpack's output of the tube as an OBJ */
static void gltfpack_files(const km_mesh *m) {
  if (km_test_run("gltfpack -h > /dev/null 2>&1", NULL) != 0 &&
      km_test_run("command -v gltfpack", NULL) != 0) {
    printf("# SKIP gltfpack cases: gltfpack not found (Debian package gltfpack)\n");
    return;
  }
  char obj[96], mtl[96], out[96], cmd[512];
  snprintf(obj, sizeof obj, "test_gltf_meshopt_%ld.obj", (long)getpid());
  snprintf(mtl, sizeof mtl, "test_gltf_meshopt_%ld.mtl", (long)getpid());
  snprintf(out, sizeof out, "test_gltf_meshopt_%ld_pack.glb", (long)getpid());
  /* a textured OBJ (gltfpack keeps TEXCOORD_0 only for a textured material, and then puts
   * their dequantisation in the texture's KHR_texture_transform) */
  FILE *f = fopen(mtl, "w"), *o = fopen(obj, "w");
  CHECK(f && o);
  if (!f || !o) return;
  fprintf(f, "newmtl skin\nmap_Kd skin.png\n");
  fclose(f);
  fprintf(o, "mtllib %s\nusemtl skin\n", mtl);
  for (size_t i = 0; i < m->n_vertices; ++i)
    fprintf(o, "v %.9g %.9g %.9g\n", m->V[3 * i], m->V[3 * i + 1], m->V[3 * i + 2]);
  for (size_t i = 0; i < m->n_vertices; ++i) /* a corner of the texture: not [0, 1] */
    fprintf(o, "vt %.9g %.9g\n", 0.25 + 0.5 * m->UV[2 * i], 0.1 + 0.3 * m->UV[2 * i + 1]);
  for (size_t t = 0; t < m->n_faces; ++t) {
    const int32_t *v = m->F + 3 * t;
    fprintf(o, "f %d/%d %d/%d %d/%d\n", v[0] + 1, v[0] + 1, v[1] + 1, v[1] + 1, v[2] + 1, v[2] + 1);
  }
  fclose(o);
  static const char *flags[3] = {"-c", "-cc", ""};
  for (int k = 0; k < 3; ++k) {
    snprintf(cmd, sizeof cmd, "gltfpack -i %s -o %s %s", obj, out, flags[k]);
    char *log = NULL;
    int rc = km_test_run(cmd, &log);
    CHECK_MSG(rc == 0, "%s: %s", cmd, log ? log : "");
    free(log);
    if (rc) continue;
    km_mesh g = {0};
    CHECK_OK(km_mesh_read(out, &g, KM_E));
    if (!g.V) continue;
    /* gltfpack may reorder and split vertices; each must lie on an original one within its
     * 14-bit grid over the 1.2 m extent */
    double worst = 0, worst_uv = 0;
    for (size_t i = 0; i < g.n_vertices; ++i) {
      double best = INFINITY;
      size_t bj = 0;
      for (size_t j = 0; j < m->n_vertices; ++j) {
        double d2 = 0;
        for (int c = 0; c < 3; ++c)
          d2 += (g.V[3 * i + c] - m->V[3 * j + c]) * (g.V[3 * i + c] - m->V[3 * j + c]);
        if (d2 < best) best = d2, bj = j;
      }
      worst = fmax(worst, sqrt(best));
      if (g.UV) /* gltfpack may split vertices but not move them in the texture */
        worst_uv = fmax(worst_uv, fmax(fabs(g.UV[2 * i] - (0.25 + 0.5 * m->UV[2 * bj])),
                                       fabs(g.UV[2 * i + 1] - (0.1 + 0.3 * m->UV[2 * bj + 1]))));
    }
    /* 12-bit texture coordinates over their range */
    CHECK_MSG(g.UV && worst_uv < 3e-4, "gltfpack %s: UVs %s, off by %g", flags[k],
              g.UV ? "read" : "missing", worst_uv);
    CHECK_MSG(g.n_faces == m->n_faces && g.n_vertices >= m->n_vertices / 2 && worst < 2e-4,
              "gltfpack %s: %zu faces (%zu), %zu vertices, farthest %g m from the original",
              flags[k], g.n_faces, m->n_faces, g.n_vertices, worst);
    printf("# gltfpack %s: %zu vertices, %zu faces, max distance %.2g m, UV %.2g\n", flags[k],
           g.n_vertices, g.n_faces, worst, worst_uv);
    km_mesh_free(&g);
  }
  /* a skinned file: kinemesh's plain skin export packed by gltfpack (which reorders the
   * vertices) reads at the same place, with its skin */
  char plain[96];
  snprintf(plain, sizeof plain, "test_gltf_meshopt_%ld_skin.glb", (long)getpid());
  CHECK(write_anim(plain, m, KM_ANIM_EXPORT_SKIN, false) == KM_OK);
  snprintf(cmd, sizeof cmd, "gltfpack -i %s -o %s -cc", plain, out);
  CHECK(km_test_run(cmd, NULL) == 0);
  km_mesh g = {0};
  km_mesh_skin sk = {0};
  CHECK_OK(km_mesh_read_skinned(out, &g, &sk, KM_E));
  CHECK_MSG(g.n_vertices == m->n_vertices && sk.n_joints == 5 && sk.n_vertices == g.n_vertices,
            "gltfpack skin: %zu vertices, %zu joints", g.n_vertices, sk.n_joints);
  double worst = 0, wsum_err = 0;
  for (size_t i = 0; g.V && i < g.n_vertices; ++i) {
    double best = INFINITY;
    for (size_t j = 0; j < m->n_vertices; ++j) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c)
        d2 += (g.V[3 * i + c] - m->V[3 * j + c]) * (g.V[3 * i + c] - m->V[3 * j + c]);
      best = fmin(best, d2);
    }
    worst = fmax(worst, sqrt(best));
    double ws = 0;
    for (int k = 0; sk.weights && k < 4; ++k)
      ws += sk.weights[4 * i + k];
    wsum_err = fmax(wsum_err, fabs(ws - 1));
  }
  CHECK_MSG(worst < 2e-4 && wsum_err < 1e-9, "gltfpack skin: %g m off, weight sums off by %g",
            worst, wsum_err);
  printf("# gltfpack -cc of a skinned glb: %zu vertices, %zu joints, max distance %.2g m\n",
         g.n_vertices, sk.n_joints, worst);
  km_mesh_skin_free(&sk);
  km_mesh_free(&g);
  remove(plain);
  remove(obj);
  remove(mtl);
  remove(out);
}

/* (3) corrupted compressed views: the glb rebuilt with an edited JSON or BIN */
static unsigned char *glb_rebuild(const cJSON *root, const unsigned char *bin, size_t bin_len,
                                  size_t *n) {
  char *js = cJSON_PrintUnformatted(root);
  size_t jl = (strlen(js) + 3) & ~(size_t)3, bl = (bin_len + 3) & ~(size_t)3;
  *n = 12 + 8 + jl + 8 + bl;
  unsigned char *g = calloc(*n, 1);
  uint32_t h[5] = {0x46546C67u, 2, (uint32_t)*n, (uint32_t)jl, 0x4E4F534Au};
  memcpy(g, h, sizeof h);
  memset(g + 20, ' ', jl);
  memcpy(g + 20, js, strlen(js));
  uint32_t b[2] = {(uint32_t)bl, 0x004E4942u};
  memcpy(g + 20 + jl, b, 8);
  memcpy(g + 28 + jl, bin, bin_len);
  free(js);
  return g;
}

static void corrupted(const km_mesh *m) {
  char path[96];
  snprintf(path, sizeof path, "test_gltf_meshopt_%ld_bad.glb", (long)getpid());
  CHECK(write_anim(path, m, KM_ANIM_EXPORT_MORPHS, true) == KM_OK);
  size_t size = 0;
  unsigned char *data = read_all(path, &size);
  remove(path);
  CHECK(data && size > 28);
  if (!data || size <= 28) return;
  size_t jl = getu32(data + 12), bl = getu32(data + 20 + jl);
  unsigned char *bin = data + 28 + jl;
  /* the POSITION accessor's view */
  cJSON *root = cJSON_ParseWithLength((const char *)data + 20, jl);
  const cJSON *prim = cJSON_GetArrayItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "meshes"), 0), "primitives"),
      0);
  int pa = cJSON_GetObjectItem(cJSON_GetObjectItem(prim, "attributes"), "POSITION")->valueint;
  int bvi = cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "accessors"), pa),
                                "bufferView")
                ->valueint;
  cJSON *ext = cJSON_GetObjectItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "bufferViews"), bvi),
                          "extensions"),
      "EXT_meshopt_compression");
  CHECK(ext != NULL);
  if (!ext) goto done;
  size_t off = (size_t)cJSON_GetObjectItem(ext, "byteOffset")->valuedouble;
  size_t len = (size_t)cJSON_GetObjectItem(ext, "byteLength")->valuedouble;
  char view[32];
  snprintf(view, sizeof view, "bufferView %d", bvi);
  for (int c = 0; c < 7; ++c) {
    cJSON *r = cJSON_Duplicate(root, 1);
    cJSON *e = cJSON_GetObjectItem(
        cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(r, "bufferViews"), bvi),
                            "extensions"),
        "EXT_meshopt_compression");
    unsigned char *b2 = malloc(bl);
    memcpy(b2, bin, bl);
    const char *what = "";
    switch (c) {
    case 0: /* the codec's header byte */ b2[off] = 0x00, what = "header byte zeroed"; break;
    case 1: /* the data cut short */
      cJSON_ReplaceItemInObject(e, "byteLength", cJSON_CreateNumber((double)(len / 2)));
      what = "byteLength halved";
      break;
    case 2:
      cJSON_ReplaceItemInObject(e, "byteStride", cJSON_CreateNumber(6));
      what = "byteStride 6";
      break;
    case 3:
      cJSON_ReplaceItemInObject(e, "count", cJSON_CreateNumber(2e9));
      what = "count 2e9";
      break;
    case 4:
      cJSON_ReplaceItemInObject(e, "mode", cJSON_CreateString("POINTS"));
      what = "mode POINTS";
      break;
    case 5:
      cJSON_ReplaceItemInObject(e, "byteOffset", cJSON_CreateNumber((double)bl));
      what = "byteOffset past the buffer";
      break;
    case 6: /* every byte of the view's data after the header scrambled: the tail check or the
               sizes must fail; if it happens to decode, the mesh must still be sound */
      for (size_t i = 1; i < len; ++i)
        b2[off + i] = (unsigned char)(b2[off + i] * 31 + 7);
      cJSON_ReplaceItemInObject(e, "byteLength", cJSON_CreateNumber((double)(len - 1)));
      what = "bytes scrambled, one short";
      break;
    }
    size_t n = 0;
    unsigned char *g = glb_rebuild(r, b2, bl, &n);
    km_mesh out = {0};
    km_status s = km_mesh_parse(g, n, KM_FORMAT_GLTF, "bad.glb", &out, KM_E);
    CHECK_MSG(s == KM_ERR_PARSE && strstr(km_test_err.message, "bad.glb") &&
                  strstr(km_test_err.message, view),
              "%s: status %d, '%s'", what, (int)s, km_test_err.message);
    printf("# %s: %s\n", what, km_test_err.message);
    km_mesh_free(&out);
    free(g);
    free(b2);
    cJSON_Delete(r);
  }
done:
  cJSON_Delete(root);
  free(data);
}

int main(void) {
  km_mesh m = {0};
  tube_mesh(&m, RINGS, SEGS, true);
  double *N = malloc(m.n_vertices * 3 * sizeof *N);
  CHECK_OK(km_vertex_normals(&m, KM_NORMALS_AREA, N, KM_E));
  own_files(&m, N);
  accessor_helper(&m);
  gltfpack_files(&m);
  corrupted(&m);
  free(N);
  km_mesh_free(&m);
  return km_test_finish("test_gltf_meshopt");
}
