/* Animation output: glb (parsed back here with an independent little GLB reader), pc2, OBJ
 * and PLY frame directories, info, and failure cases that must leave nothing behind. */
#include "core/core.h"
#include "km_test.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <sys/stat.h>
#include <stdint.h>
#include <unistd.h>

#define NX 12
#define NY 10
#define FRAMES 10
#define FPS 24.0

/* A small open grid, bent differently in each frame. */
static void make_rest(km_mesh *m) {
  m->n_vertices = (NX + 1) * (NY + 1);
  m->n_faces = 2 * NX * NY;
  m->V = malloc(m->n_vertices * 3 * sizeof(double));
  m->F = malloc(m->n_faces * 3 * sizeof(int32_t));
  for (int j = 0; j <= NY; ++j)
    for (int i = 0; i <= NX; ++i) {
      double *v = m->V + 3 * (j * (NX + 1) + i);
      v[0] = 0.1 * i - 0.3;
      v[1] = 0.07 * j + 1.0;
      v[2] = 0.01 * i * j;
    }
  int32_t *f = m->F;
  for (int j = 0; j < NY; ++j)
    for (int i = 0; i < NX; ++i) {
      int a = j * (NX + 1) + i, b = a + 1, c = a + NX + 1, d = c + 1;
      *f++ = a, *f++ = b, *f++ = d;
      *f++ = a, *f++ = d, *f++ = c;
    }
}

static void make_frame(const km_mesh *rest, int k, double *V) {
  for (size_t i = 0; i < rest->n_vertices; ++i) {
    const double *r = rest->V + 3 * i;
    V[3 * i] = r[0] + 0.05 * sin(0.7 * k + 3 * r[1]);
    V[3 * i + 1] = r[1] + 0.02 * k;
    V[3 * i + 2] = r[2] - 0.3 * sin(0.4 * k) * r[0] * r[0];
  }
}

static double *all_frames(const km_mesh *rest) {
  double *all = malloc(FRAMES * rest->n_vertices * 3 * sizeof(double));
  for (int k = 0; k < FRAMES; ++k)
    make_frame(rest, k, all + (size_t)k * rest->n_vertices * 3);
  return all;
}

static km_status write_anim(const char *path, const km_mesh *rest, const km_anim_options *o,
                            const double *frames) {
  km_anim_writer *w = NULL;
  km_status s = km_anim_writer_open(path, rest, o, &w, KM_E);
  if (s != KM_OK) return s;
  for (int k = 0; k < FRAMES && s == KM_OK; ++k)
    s = km_anim_writer_push(w, frames + (size_t)k * rest->n_vertices * 3, KM_E);
  if (s != KM_OK) {
    km_anim_writer_free(&w);
    return s;
  }
  return km_anim_writer_close(&w, KM_E);
}

/* ---------------------------------------------------------------- minimal GLB reader */

typedef struct glb {
  char *data;
  size_t size;
  cJSON *json;
  const unsigned char *bin;
  size_t bin_len;
} glb;

static uint32_t u32(const void *p) {
  const unsigned char *b = p;
  return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static bool glb_load(const char *path, glb *g) {
  memset(g, 0, sizeof *g);
  if (km__read_file(path, &g->data, &g->size, KM_E) != KM_OK) return false;
  const char *d = g->data;
  CHECK(g->size >= 28);
  if (g->size < 28) return false;
  CHECK(memcmp(d, "glTF", 4) == 0);
  CHECK(u32(d + 4) == 2);
  CHECK(u32(d + 8) == g->size);
  uint32_t jl = u32(d + 12);
  CHECK(u32(d + 16) == 0x4E4F534A);
  CHECK(jl % 4 == 0);
  if (20 + (size_t)jl + 8 > g->size) return false;
  const char *bh = d + 20 + jl;
  g->bin_len = u32(bh);
  CHECK(u32(bh + 4) == 0x004E4942);
  CHECK(g->bin_len % 4 == 0);
  CHECK(20 + jl + 8 + g->bin_len == g->size);
  g->bin = (const unsigned char *)bh + 8;
  g->json = cJSON_ParseWithLength(d + 20, jl);
  CHECK(g->json != NULL);
  return g->json != NULL && 20 + jl + 8 + g->bin_len == g->size;
}

static void glb_free(glb *g) {
  cJSON_Delete(g->json);
  free(g->data);
}

static int jint(const cJSON *o, const char *k) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  return cJSON_IsNumber(v) ? v->valueint : -1;
}

/* Float data of accessor a (checked to lie inside the BIN chunk), count*components floats. */
static const unsigned char *glb_accessor(const glb *g, int a, size_t *count, int *comps) {
  const cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItem(g->json, "accessors"), a);
  const cJSON *bv =
      cJSON_GetArrayItem(cJSON_GetObjectItem(g->json, "bufferViews"), jint(acc, "bufferView"));
  if (!acc || !bv) return NULL;
  *count = (size_t)jint(acc, "count");
  const char *type = cJSON_GetStringValue(cJSON_GetObjectItem(acc, "type"));
  *comps = type && strcmp(type, "VEC3") == 0 ? 3 : 1;
  size_t off = (size_t)jint(bv, "byteOffset") +
               (size_t)(jint(acc, "byteOffset") > 0 ? jint(acc, "byteOffset") : 0);
  size_t len = (size_t)jint(bv, "byteLength");
  CHECK(len >= *count * *comps * 4);
  CHECK(off + len <= g->bin_len);
  if (off + len > g->bin_len) return NULL;
  return g->bin + off;
}

static float f32(const unsigned char *p) {
  uint32_t u = u32(p);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

/* min/max of the accessor must equal the true min/max of its data (exactly, as floats). */
static void check_minmax(const glb *g, int a) {
  size_t n;
  int c;
  const unsigned char *p = glb_accessor(g, a, &n, &c);
  if (!p) return;
  const cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItem(g->json, "accessors"), a);
  const cJSON *mn = cJSON_GetObjectItem(acc, "min"), *mx = cJSON_GetObjectItem(acc, "max");
  CHECK(cJSON_GetArraySize(mn) == c && cJSON_GetArraySize(mx) == c);
  for (int k = 0; k < c; ++k) {
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; ++i) {
      float v = f32(p + 4 * (i * c + k));
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    CHECK((float)cJSON_GetArrayItem(mn, k)->valuedouble == lo);
    CHECK((float)cJSON_GetArrayItem(mx, k)->valuedouble == hi);
  }
}

/* Full structural check, then every key frame reconstructed as rest + displacement. */
static void check_glb(const char *path, const km_mesh *rest, const double *frames,
                      size_t key_every) {
  glb g;
  if (!glb_load(path, &g)) {
    CHECK(!"glb loads");
    return;
  }
  cJSON *j = g.json;
  const cJSON *asset = cJSON_GetObjectItem(j, "asset");
  CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(asset, "version")), "2.0") == 0);
  CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(asset, "generator")), "kinemesh") == 0);
  const cJSON *bv;
  cJSON_ArrayForEach(bv, cJSON_GetObjectItem(j, "bufferViews"))
      CHECK(jint(bv, "byteOffset") % 4 == 0);
  CHECK(jint(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "buffers"), 0), "byteLength") <=
        (int)g.bin_len);

  const cJSON *mesh = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "meshes"), 0);
  const cJSON *prim = cJSON_GetArrayItem(cJSON_GetObjectItem(mesh, "primitives"), 0);
  int a_pos = jint(cJSON_GetObjectItem(prim, "attributes"), "POSITION");
  int a_idx = jint(prim, "indices");
  size_t n, nk_expected = 0;
  int c;
  /* indices */
  const unsigned char *ip = glb_accessor(&g, a_idx, &n, &c);
  CHECK(ip && n == rest->n_faces * 3);
  if (ip)
    for (size_t i = 0; i < n && i < rest->n_faces * 3; ++i)
      CHECK(u32(ip + 4 * i) == (uint32_t)rest->F[i]);
  const unsigned char *pp = glb_accessor(&g, a_pos, &n, &c);
  CHECK(pp && n == rest->n_vertices && c == 3);
  check_minmax(&g, a_pos);

  size_t keys[FRAMES + 1];
  for (size_t k = 0; k < FRAMES; k += key_every)
    keys[nk_expected++] = k;
  if (keys[nk_expected - 1] != FRAMES - 1) keys[nk_expected++] = FRAMES - 1;
  const cJSON *targets = cJSON_GetObjectItem(prim, "targets");
  CHECK((size_t)cJSON_GetArraySize(targets) == nk_expected);
  CHECK((size_t)cJSON_GetArraySize(cJSON_GetObjectItem(mesh, "weights")) == nk_expected);

  /* Animation: times k/fps, one-hot LINEAR weights on node 0 */
  const cJSON *anim = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "animations"), 0);
  const cJSON *ch = cJSON_GetArrayItem(cJSON_GetObjectItem(anim, "channels"), 0);
  const cJSON *tg = cJSON_GetObjectItem(ch, "target");
  CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(tg, "path")), "weights") == 0);
  CHECK(jint(tg, "node") == 0);
  CHECK(jint(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "nodes"), 0), "mesh") == 0);
  const cJSON *smp = cJSON_GetArrayItem(cJSON_GetObjectItem(anim, "samplers"), jint(ch, "sampler"));
  CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(smp, "interpolation")), "LINEAR") == 0);
  const unsigned char *tp = glb_accessor(&g, jint(smp, "input"), &n, &c);
  CHECK(tp && n == nk_expected);
  if (tp)
    for (size_t k = 0; k < n && k < nk_expected; ++k)
      CHECK_NEAR(f32(tp + 4 * k), keys[k] / FPS, 1e-6);
  check_minmax(&g, jint(smp, "input"));
  const unsigned char *wp = glb_accessor(&g, jint(smp, "output"), &n, &c);
  CHECK(wp && n == nk_expected * nk_expected);
  if (wp && n == nk_expected * nk_expected)
    for (size_t k = 0; k < nk_expected; ++k)
      for (size_t t = 0; t < nk_expected; ++t)
        CHECK(f32(wp + 4 * (k * nk_expected + t)) == (k == t ? 1.0f : 0.0f));

  /* Each key = rest + displacement, against what was pushed. */
  double worst = 0;
  for (size_t k = 0; k < nk_expected && k < (size_t)cJSON_GetArraySize(targets); ++k) {
    int a = jint(cJSON_GetArrayItem(targets, (int)k), "POSITION");
    const unsigned char *dp = glb_accessor(&g, a, &n, &c);
    CHECK(dp && n == rest->n_vertices);
    if (!dp || !pp) continue;
    check_minmax(&g, a);
    const double *want = frames + keys[k] * rest->n_vertices * 3;
    for (size_t i = 0; i < rest->n_vertices * 3; ++i) {
      double got = (double)f32(pp + 4 * i) + (double)f32(dp + 4 * i);
      double e = fabs(got - want[i]);
      worst = e > worst ? e : worst;
    }
  }
  CHECK_MSG(worst < 1e-6, "worst reconstruction error %g", worst);
  glb_free(&g);
}

/* ---------------------------------------------------------------- tests */

static void test_glb(const km_mesh *rest, const double *frames) {
  const char *path = "test_anim.glb";
  remove(path);
  km_anim_options o = {.fps = FPS};
  CHECK_OK(write_anim(path, rest, &o, frames));
  check_glb(path, rest, frames, 1);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(path, &info, KM_E));
  CHECK(info.format == KM_ANIM_GLB);
  CHECK(info.frames == FRAMES);
  CHECK(info.vertices == rest->n_vertices);
  CHECK(info.faces == rest->n_faces);
  CHECK_NEAR(info.fps, FPS, 1e-9);
  CHECK_NEAR(info.duration, (FRAMES - 1) / FPS, 1e-6);

  /* key_every = 3: frames 0,3,6,9 (9 is also the last); = 4: 0,4,8 and the last, 9. */
  o.key_every = 3;
  CHECK_OK(write_anim(path, rest, &o, frames));
  check_glb(path, rest, frames, 3);
  CHECK_OK(km_anim_info_read(path, &info, KM_E));
  CHECK(info.frames == 4);
  CHECK_NEAR(info.fps, FPS, 1e-9);
  o.key_every = 4;
  CHECK_OK(write_anim(path, rest, &o, frames));
  check_glb(path, rest, frames, 4);
  CHECK_OK(km_anim_info_read(path, &info, KM_E));
  CHECK(info.frames == 4);
  CHECK_NEAR(info.duration, (FRAMES - 1) / FPS, 1e-6);
  if (getenv("KM_KEEP_GLB")) return; /* for running the Khronos validator on it by hand */
  remove(path);
}

static void test_pc2(const km_mesh *rest, const double *frames) {
  const char *path = "test_anim.pc2";
  remove(path);
  CHECK_OK(write_anim(path, rest, NULL, frames));
  double *back = NULL;
  km_anim_info info;
  CHECK_OK(km_pc2_read(path, &back, &info, KM_E));
  CHECK(info.format == KM_ANIM_PC2 && info.frames == FRAMES && info.vertices == rest->n_vertices);
  CHECK(info.fps == 0); /* PC2 does not store a frame rate */
  if (back) {
    double worst = 0;
    for (size_t i = 0; i < FRAMES * rest->n_vertices * 3; ++i)
      worst = fmax(worst, fabs(back[i] - frames[i]));
    CHECK_MSG(worst < 1e-6, "worst %g", worst);
    CHECK(back[0] == (double)(float)frames[0]);
  }
  free(back);
  km_anim_info i2;
  CHECK_OK(km_anim_info_read(path, &i2, KM_E));
  CHECK(i2.frames == FRAMES && i2.vertices == rest->n_vertices && i2.faces == 0);

  /* Header layout, byte for byte. */
  char *data;
  size_t size;
  CHECK_OK(km__read_file(path, &data, &size, KM_E));
  CHECK(size == 32 + FRAMES * rest->n_vertices * 12);
  CHECK(memcmp(data, "POINTCACHE2\0", 12) == 0);
  CHECK(u32(data + 12) == 1 && u32(data + 16) == rest->n_vertices && u32(data + 28) == FRAMES);
  CHECK(f32((unsigned char *)data + 20) == 0.0f && f32((unsigned char *)data + 24) == 1.0f);

  /* Truncated and corrupted files are parse errors naming the file. */
  FILE *f = fopen("test_anim_bad.pc2", "wb");
  fwrite(data, 1, size - 5, f);
  fclose(f);
  CHECK_STATUS(km_pc2_read("test_anim_bad.pc2", &back, NULL, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "test_anim_bad.pc2") != NULL);
  CHECK(back == NULL);
  data[3] = 'X';
  f = fopen("test_anim_bad.pc2", "wb");
  fwrite(data, 1, size, f);
  fclose(f);
  CHECK_STATUS(km_anim_info_read("test_anim_bad.pc2", &i2, KM_E), KM_ERR_PARSE);
  f = fopen("test_anim_bad.pc2", "wb");
  fwrite(data, 1, 10, f);
  fclose(f);
  CHECK_STATUS(km_pc2_read("test_anim_bad.pc2", &back, NULL, KM_E), KM_ERR_PARSE);
  remove("test_anim_bad.pc2");
  free(data);
  remove(path);
}

static void rm_dir(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return;
  struct dirent *e;
  char p[1024];
  while ((e = readdir(d)) != NULL) {
    if (e->d_name[0] == '.') continue;
    snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
    remove(p);
  }
  closedir(d);
  rmdir(dir);
}

static bool dir_has_prefix(const char *prefix) {
  DIR *d = opendir(".");
  struct dirent *e;
  bool found = false;
  while ((e = readdir(d)) != NULL)
    if (strncmp(e->d_name, prefix, strlen(prefix)) == 0) found = true;
  closedir(d);
  return found;
}

static void test_dirs(const km_mesh *rest, const double *frames) {
  const char *dir = "test_anim_obj";
  rm_dir(dir);
  km_anim_options o = {.fps = FPS};
  CHECK_OK(write_anim(dir, rest, &o, frames));
  km_anim_info info;
  CHECK_OK(km_anim_info_read(dir, &info, KM_E));
  CHECK(info.format == KM_ANIM_OBJ_DIR && info.frames == FRAMES);
  CHECK(info.vertices == rest->n_vertices && info.faces == rest->n_faces);
  CHECK_NEAR(info.fps, FPS, 0);
  /* Exact text coordinates: frame 7, vertex 5. */
  char *data;
  size_t size;
  CHECK_OK(km__read_file("test_anim_obj/frame_000007.obj", &data, &size, KM_E));
  if (data) {
    const char *v = data;
    for (int i = 0; i <= 5 && v; ++i)
      v = strstr(v + 1, "\nv ");
    double x, y, z;
    CHECK(v && sscanf(v, "\nv %lf %lf %lf", &x, &y, &z) == 3);
    const double *want = frames + (7 * rest->n_vertices + 5) * 3;
    CHECK(x == want[0] && y == want[1] && z == want[2]);
    CHECK(strstr(data, "\nf 1 2 15\n") != NULL);
    free(data);
  }
  /* Overwriting an earlier animation works and leaves no temporaries. */
  CHECK_OK(write_anim(dir, rest, &o, frames));
  CHECK_OK(km_anim_info_read(dir, &info, KM_E));
  CHECK(info.frames == FRAMES);

  const char *pdir = "test_anim_ply";
  rm_dir(pdir);
  o.format = KM_ANIM_PLY_DIR;
  CHECK_OK(write_anim(pdir, rest, &o, frames));
  CHECK_OK(km_anim_info_read(pdir, &info, KM_E));
  CHECK(info.format == KM_ANIM_PLY_DIR && info.frames == FRAMES);
  CHECK(info.vertices == rest->n_vertices && info.faces == rest->n_faces);
  CHECK_OK(km__read_file("test_anim_ply/frame_000003.ply", &data, &size, KM_E));
  if (data) {
    char *body = strstr(data, "end_header\n");
    CHECK(body != NULL);
    if (body) {
      body += 11;
      CHECK(size == (size_t)(body - data) + rest->n_vertices * 24 + rest->n_faces * 13);
      double x;
      memcpy(&x, body + 24 * 4 + 8, 8); /* vertex 4, y (little-endian host) */
      CHECK(x == frames[(3 * rest->n_vertices + 4) * 3 + 1]);
    }
    free(data);
  }
  /* A directory holding foreign files is never replaced. */
  FILE *f = fopen("test_anim_ply/notes.txt", "w");
  fputs("mine", f);
  fclose(f);
  km_anim_writer *w = NULL;
  CHECK_STATUS(km_anim_writer_open(pdir, rest, &o, &w, KM_E), KM_ERR_IO);
  CHECK(w == NULL);
  CHECK(access("test_anim_ply/notes.txt", F_OK) == 0);
  rm_dir(dir);
  rm_dir(pdir);
  /* A trailing slash names the same directory (the temporary must not go inside it). */
  o.format = KM_ANIM_AUTO;
  CHECK_OK(write_anim("test_anim_slash/", rest, &o, frames));
  CHECK_OK(km_anim_info_read("test_anim_slash", &info, KM_E));
  CHECK(info.frames == FRAMES && info.format == KM_ANIM_OBJ_DIR);
  rm_dir("test_anim_slash");
  CHECK(!dir_has_prefix("test_anim_slash"));
  CHECK(!dir_has_prefix("test_anim_obj"));
  /* Another extension is refused, creating nothing: -o take.fbx made a folder "take.fbx" of OBJ
   * frames. A folder that exists keeps its name, dot or not; --frame-format (an explicit
   * format) names a folder whatever the path. */
  const char *other[] = {"test_anim_x.fbx", "test_anim_x.gltf", "test_anim_x.obj"};
  const char *hint[] = {"not .fbx", "glTF 2.0 in one binary file", "--frame-format obj"};
  for (int k = 0; k < 3; ++k) {
    CHECK_STATUS(km_anim_writer_open(other[k], rest, &o, &w, KM_E), KM_ERR_INVALID);
    CHECK_MSG(strstr(km_test_err.message, hint[k]) != NULL, "%s", km_test_err.message);
    CHECK(w == NULL && access(other[k], F_OK) != 0 && !dir_has_prefix("test_anim_x"));
  }
  CHECK(mkdir("test_anim_v1.2", 0777) == 0);
  CHECK_OK(write_anim("test_anim_v1.2", rest, &o, frames));
  CHECK_OK(km_anim_info_read("test_anim_v1.2", &info, KM_E));
  CHECK(info.format == KM_ANIM_OBJ_DIR && info.frames == FRAMES);
  rm_dir("test_anim_v1.2");
  o.format = KM_ANIM_PLY_DIR;
  CHECK_OK(write_anim("test_anim_x.obj", rest, &o, frames));
  CHECK_OK(km_anim_info_read("test_anim_x.obj", &info, KM_E));
  CHECK(info.format == KM_ANIM_PLY_DIR && info.frames == FRAMES);
  rm_dir("test_anim_x.obj");
}

static void test_failures(const km_mesh *rest, const double *frames) {
  const char *paths[] = {"test_anim_fail.glb", "test_anim_fail.pc2", "test_anim_fail_dir"};
  for (int p = 0; p < 3; ++p) {
    km_anim_writer *w = NULL;
    CHECK_OK(km_anim_writer_open(paths[p], rest, NULL, &w, KM_E));
    CHECK_OK(km_anim_writer_push(w, frames, KM_E));
    /* A non-finite coordinate is rejected with a message naming frame and vertex. */
    double *bad = malloc(rest->n_vertices * 3 * sizeof(double));
    memcpy(bad, frames, rest->n_vertices * 3 * sizeof(double));
    bad[3 * 17 + 1] = NAN;
    CHECK_STATUS(km_anim_writer_push(w, bad, KM_E), KM_ERR_INVALID);
    CHECK(strstr(km_test_err.message, "vertex 17") != NULL);
    bad[3 * 17 + 1] = 1e300; /* finite double, infinite float */
    CHECK_STATUS(km_anim_writer_push(w, bad, KM_E), KM_ERR_INVALID);
    free(bad);
    /* Nothing at the path before close; free without close leaves nothing at all. */
    CHECK(access(paths[p], F_OK) != 0);
    km_anim_writer_free(&w);
    CHECK(w == NULL);
    CHECK(access(paths[p], F_OK) != 0);
    CHECK(!dir_has_prefix("test_anim_fail"));

    /* Pushing after close is an error, not a crash. */
    CHECK_OK(km_anim_writer_open(paths[p], rest, NULL, &w, KM_E));
    CHECK_OK(km_anim_writer_push(w, frames, KM_E));
    CHECK_OK(km_anim_writer_close(&w, KM_E));
    CHECK(w == NULL);
    CHECK_STATUS(km_anim_writer_push(w, frames, KM_E), KM_ERR_INVALID);
    CHECK_STATUS(km_anim_writer_close(&w, KM_E), KM_ERR_INVALID);
    km_anim_info info;
    CHECK_OK(km_anim_info_read(paths[p], &info, KM_E));
    CHECK(info.frames == 1);
    /* Closing with no frames fails and publishes nothing. */
    if (p < 2)
      remove(paths[p]);
    else
      rm_dir(paths[p]);
    CHECK_OK(km_anim_writer_open(paths[p], rest, NULL, &w, KM_E));
    CHECK_STATUS(km_anim_writer_close(&w, KM_E), KM_ERR_INVALID);
    CHECK(!dir_has_prefix("test_anim_fail"));
  }
  /* Issue 18: what a SIGINT/SIGTERM handler calls (km_remove_temporaries) leaves no
   * temporary file or half-filled frame directory behind; the writer is then freed safely. */
  const char *sig[] = {"test_anim_sig.glb", "test_anim_sig.pc2", "test_anim_sig_dir",
                       "test_anim_sig_ply/"};
  for (int p = 0; p < 4; ++p) {
    km_anim_writer *w = NULL;
    CHECK_OK(km_anim_writer_open(sig[p], rest, NULL, &w, KM_E));
    CHECK_OK(km_anim_writer_push(w, frames, KM_E));
    CHECK_OK(km_anim_writer_push(w, frames, KM_E));
    CHECK(dir_has_prefix("test_anim_sig"));
    km_remove_temporaries();
    CHECK_MSG(!dir_has_prefix("test_anim_sig"), "%s: temporary left after the cleanup", sig[p]);
    km_anim_writer_free(&w);
    CHECK(access(sig[p], F_OK) != 0);
  }
  /* Wrong paths name themselves (missing folders are created, so: under a file). */
  km_anim_writer *w = NULL;
  CHECK_STATUS(km_anim_writer_open("/dev/null/dir/a.glb", rest, NULL, &w, KM_E), KM_ERR_IO);
  CHECK(strstr(km_test_err.message, "/dev/null/dir/a.glb") != NULL);
  CHECK_STATUS(km_anim_writer_open("/dev/null/dir/a.pc2", rest, NULL, &w, KM_E), KM_ERR_IO);
  CHECK_STATUS(km_anim_writer_open("/dev/null/dir/frames", rest, NULL, &w, KM_E), KM_ERR_IO);
  CHECK(w == NULL);
  km_anim_info info;
  CHECK_STATUS(km_anim_info_read("no/such/file.glb", &info, KM_E), KM_ERR_IO);
  /* Bad arguments. */
  km_mesh empty = {0};
  CHECK_STATUS(km_anim_writer_open("x.glb", &empty, NULL, &w, KM_E), KM_ERR_INVALID);
  km_mesh badf = *rest;
  badf.F = malloc(rest->n_faces * 3 * sizeof(int32_t));
  memcpy(badf.F, rest->F, rest->n_faces * 3 * sizeof(int32_t));
  badf.F[7] = (int32_t)rest->n_vertices;
  CHECK_STATUS(km_anim_writer_open("x.glb", &badf, NULL, &w, KM_E), KM_ERR_INVALID);
  free(badf.F);
  km_anim_options o = {.fps = -1};
  CHECK_STATUS(km_anim_writer_open("x.glb", rest, &o, &w, KM_E), KM_ERR_INVALID);
  CHECK(access("x.glb", F_OK) != 0);

  /* Corrupt glb files are parse errors naming the file. */
  FILE *f = fopen("test_anim_bad.glb", "wb");
  fputs("glTF\x02\0\0\0garbage", f);
  fclose(f);
  CHECK_STATUS(km_anim_info_read("test_anim_bad.glb", &info, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "test_anim_bad.glb") != NULL);
  remove("test_anim_bad.glb");
}

/* A point cloud (no faces) is written with mode POINTS and no indices. */
static void test_point_cloud(const km_mesh *rest, const double *frames) {
  km_mesh pc = *rest;
  pc.n_faces = 0;
  pc.F = NULL;
  CHECK_OK(write_anim("test_anim_pc.glb", &pc, NULL, frames));
  km_anim_info info;
  CHECK_OK(km_anim_info_read("test_anim_pc.glb", &info, KM_E));
  CHECK(info.faces == 0 && info.vertices == rest->n_vertices && info.frames == FRAMES);
  CHECK_NEAR(info.fps, 30, 1e-12);
  remove("test_anim_pc.glb");
}

/* More keys than vertices (a tetrahedron, 70 frames): buffers sized by keys, not vertices. */
static void test_many_keys(void) {
  double V[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, X[12];
  int32_t F[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  km_mesh m = {.V = V, .F = F, .n_vertices = 4, .n_faces = 4};
  km_anim_writer *w = NULL;
  CHECK_OK(km_anim_writer_open("test_anim_tet.glb", &m, NULL, &w, KM_E));
  for (int k = 0; k < 70; ++k) {
    for (int i = 0; i < 12; ++i)
      X[i] = V[i] + 0.01 * k * (i % 3 == 1);
    CHECK_OK(km_anim_writer_push(w, X, KM_E));
  }
  CHECK_OK(km_anim_writer_close(&w, KM_E));
  km_anim_info info;
  CHECK_OK(km_anim_info_read("test_anim_tet.glb", &info, KM_E));
  CHECK(info.frames == 70 && info.vertices == 4 && info.faces == 4);
  CHECK_NEAR(info.duration, 69 / 30.0, 1e-6);
  remove("test_anim_tet.glb");
}

/* Issue 18: a .pc2 header's counts are checked against the file's length before anything is
 * sized by them. tests/data/pc2_no_frames_huge_count.pc2 (32 bytes, 1.78e9 points, no samples;
 * found by fuzz_anim) once asked for a 21 GB frame buffer; a header claiming more samples than
 * the file holds is refused naming the sizes. */
static void test_pc2_header_bombs(void) {
  const char *seed = KM_TEST_DATA "/pc2_no_frames_huge_count.pc2";
  double *fr = NULL;
  km_anim_info in;
  km_status s = km_pc2_read(seed, &fr, &in, KM_E);
  CHECK_MSG(s == KM_OK && in.frames == 0, "no-frames pc2: %s (%s)", km_status_name(s),
            km_test_err.message);
  free(fr);
  fr = NULL;
  unsigned char h[44] = "POINTCACHE2";
  uint32_t one = 1, np = 1000000, ns = 1000;
  memcpy(h + 12, &one, 4);
  memcpy(h + 16, &np, 4);
  memcpy(h + 28, &ns, 4);
  FILE *f = fopen("test_anim_bomb.pc2", "wb");
  CHECK(f && fwrite(h, 1, sizeof h, f) == sizeof h);
  if (f) fclose(f);
  CHECK_STATUS(km_pc2_read("test_anim_bomb.pc2", &fr, &in, KM_E), KM_ERR_PARSE);
  CHECK(fr == NULL && strstr(km_test_err.message, "file is 44 bytes"));
  CHECK_STATUS(km_anim_info_read("test_anim_bomb.pc2", &in, KM_E), KM_ERR_PARSE);
  remove("test_anim_bomb.pc2");
}

/* A forged morph .glb whose accessors share their bytes (issue 18): 80 kB of zeros hold a
 * 6,666-vertex mesh, its one morph target and 20,000 weight keys, which km_anim_read (bake)
 * would expand to 20,000 x 6,666 positions (3.2 GB). Refused, naming the sizes. */
static void test_glb_expansion_bomb(void) {
  enum { BIN = 80000, NV = 6666, NK = 20000 };
  char json[2048];
  int n = snprintf(
      json, sizeof json,
      "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
      "\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},"
      "\"targets\":[{\"POSITION\":1}]}]}],\"animations\":[{\"channels\":[{\"sampler\":0,"
      "\"target\":{\"node\":0,\"path\":\"weights\"}}],\"samplers\":[{\"input\":2,\"output\":3}]}],"
      "\"buffers\":[{\"byteLength\":%d}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":%d}],"
      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\","
      "\"min\":[0,0,0],\"max\":[0,0,0]},{\"bufferView\":0,\"componentType\":5126,\"count\":%d,"
      "\"type\":\"VEC3\"},{\"bufferView\":0,\"componentType\":5126,\"count\":%d,\"type\":"
      "\"SCALAR\",\"min\":[0],\"max\":[0]},{\"bufferView\":0,\"componentType\":5126,\"count\":%d,"
      "\"type\":\"SCALAR\"}]}",
      BIN, BIN, NV, NV, NK, NK);
  while (n % 4)
    json[n++] = ' ';
  const char *path = "anim_bomb.glb";
  FILE *f = fopen(path, "wb");
  CHECK(f != NULL);
  if (!f) return;
  uint32_t hdr[5] = {0x46546C67u, 2, (uint32_t)(12 + 8 + n + 8 + BIN), (uint32_t)n, 0x4E4F534Au};
  uint32_t bh[2] = {BIN, 0x004E4942u};
  static unsigned char zeros[BIN];
  fwrite(hdr, 1, sizeof hdr, f);
  fwrite(json, 1, (size_t)n, f);
  fwrite(bh, 1, sizeof bh, f);
  fwrite(zeros, 1, sizeof zeros, f);
  fclose(f);
  km_mesh rest = {0};
  double *frames = NULL;
  km_anim_info info;
  CHECK_STATUS(km_anim_read(path, &rest, &frames, &info, KM_E), KM_ERR_UNSUPPORTED);
  CHECK_MSG(strstr(km_test_err.message, "20000 keys x 6666 vertices") &&
                strstr(km_test_err.message, "anim_bomb.glb"),
            "%s", km_test_err.message);
  CHECK(frames == NULL);
  free(frames);
  km_mesh_free(&rest);
  remove(path);
}

/* KM_ANIM_EXPORT_SKELETON (pose --export skeleton): a two-bone skeleton bends the rest mesh by
 * linear blend skinning; the writer stores the pushed transforms as the bones' motion, so the
 * file is exact (its reported error only float rounding), keeps the joints' names, and has a
 * frame per push. A plain push, weights for another vertex count or a joint out of range, and a
 * transform that is not finite are refused, naming the problem. */
static void test_skeleton_export(const km_mesh *rest) {
  const size_t nv = rest->n_vertices;
  const char *names[2] = {"Upper", "Lower"};
  int32_t par[2] = {-1, 0};
  double jr[6] = {0, 0, 0, 0.5, 0, 0};
  km_skeleton sk = {2, (char **)names, par, jr};
  km_skin sw = {nv, malloc(sizeof(int32_t) * 4 * nv), malloc(sizeof(double) * 4 * nv)};
  for (size_t i = 0; i < nv; ++i) { /* blended across x = 0.5 */
    double t = fmin(1, fmax(0, (rest->V[3 * i] - 0.3) / 0.4));
    int32_t j[4] = {0, 1, -1, -1};
    double w[4] = {1 - t, t, 0, 0};
    memcpy(sw.joints + 4 * i, j, sizeof j);
    memcpy(sw.weights + 4 * i, w, sizeof w);
  }
  km_anim_options o = {.fps = FPS, .export_kind = KM_ANIM_EXPORT_SKELETON};
  o.skeleton = &sk;
  o.weights = &sw;
  km_anim_writer *w = NULL;
  const char *path = "test_anim_skel.glb";
  remove(path);
  CHECK_OK(km_anim_writer_open(path, rest, &o, &w, KM_E));
  double *V = malloc(sizeof(double) * 3 * nv), X[24];
  CHECK_STATUS(km_anim_writer_push(w, rest->V, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "km_anim_writer_push_pose") != NULL);
  for (int f = 0; f < FRAMES && w; ++f) {
    double a = 0.1 * f, c = cos(a), sn = sin(a);
    double X0[12] = {1, 0, 0, 0, 0, 1, 0, 0.01 * f, 0, 0, 1, 0};
    /* the lower bone turns by a about z around its joint (0.5, 0, 0) */
    double X1[12] = {c, -sn, 0, 0.5 - 0.5 * c, sn, c, 0, -0.5 * sn + 0.01 * f, 0, 0, 1, 0};
    memcpy(X, X0, sizeof X0);
    memcpy(X + 12, X1, sizeof X1);
    CHECK_OK(km_lbs(rest->V, nv, &sw, X, 2, V, KM_E));
    if (f == 3) {
      X[5] = NAN;
      CHECK_STATUS(km_anim_writer_push_pose(w, V, X, KM_E), KM_ERR_INVALID);
      CHECK(strstr(km_test_err.message, "Upper") != NULL);
      X[5] = 1;
    }
    CHECK_OK(km_anim_writer_push_pose(w, V, X, KM_E));
  }
  km_anim_report rep = {0};
  CHECK_OK(km_anim_writer_finish(&w, &rep, KM_E));
  CHECK(rep.export_kind == KM_ANIM_EXPORT_SKELETON && rep.bones == 2 && rep.frames == FRAMES);
  CHECK_MSG(rep.max_error < 1e-6, "max error %g m", rep.max_error);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(path, &info, KM_E));
  CHECK(info.frames == FRAMES && info.vertices == nv);
  size_t n = 0;
  char *json = km_test_read_file(path, &n);
  CHECK(json && memmem(json, n, "\"name\":\"Lower\"", 14) != NULL);
  free(json);
  remove(path);
  sw.n_vertices = nv - 1;
  CHECK_STATUS(km_anim_writer_open(path, rest, &o, &w, KM_E), KM_ERR_INVALID);
  sw.n_vertices = nv;
  sw.joints[0] = 2;
  CHECK_STATUS(km_anim_writer_open(path, rest, &o, &w, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "joint 2") != NULL && access(path, F_OK) != 0);
  free(V);
  free(sw.joints);
  free(sw.weights);
}

int main(void) {
  test_pc2_header_bombs();
  test_many_keys();
  test_glb_expansion_bomb();
  km_mesh rest = {0};
  make_rest(&rest);
  double *frames = all_frames(&rest);
  test_glb(&rest, frames);
  test_pc2(&rest, frames);
  test_dirs(&rest, frames);
  test_failures(&rest, frames);
  test_point_cloud(&rest, frames);
  test_skeleton_export(&rest);
  free(frames);
  free(rest.V);
  free(rest.F);
  return km_test_finish("test_anim");
}
