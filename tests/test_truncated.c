/* Issue 18: every reader, given a truncated prefix of a valid file, returns a clean error (or,
 * for line-based text where the prefix ends on a record, a shorter valid result) and never
 * crashes or reads past the end (the sanitize run checks that). The mesh readers have had
 * this loop since issue 3; this covers take, track, rig sidecar, character sidecar, puppet
 * cache, pc2, glb, BVH, Kinect CSV and the pose database. Large files are cut at every byte of
 * their first and last 256 bytes and at ~300 evenly spaced lengths in between. */
#include "km_test.h"

#include <unistd.h>

static char g_dir[] = "/tmp/km_trunc_XXXXXX";

static bool spit(const char *path, const char *data, size_t n) {
  FILE *f = fopen(path, "wb");
  if (!f) return false;
  bool ok = fwrite(data, 1, n, f) == n;
  return fclose(f) == 0 && ok;
}

/* A reader run on one file: KM_OK (and frees what it read) or an error. */
typedef km_status (*reader_fn)(const char *path, void *ctx, km_error *err);

/* Cuts `src` at the lengths described above into `ext` files and runs `read` on each.
 * strict: every strict prefix must fail (binary formats with sizes or checksums, JSON). A
 * failure must come with a message. Returns the number of prefixes read OK. */
static size_t prefix_loop(const char *what, const char *src, const char *ext, reader_fn read,
                          void *ctx, size_t strict_below) {
  size_t n = 0;
  char *data = km_test_read_file(src, &n);
  CHECK_MSG(data && n > 0, "%s: cannot read %s", what, src);
  if (!data) return 0;
  char path[512];
  snprintf(path, sizeof path, "%s/prefix.%s", g_dir, ext);
  CHECK_MSG(spit(path, data, n) && read(path, ctx, KM_E) == KM_OK, "%s: the whole file: %s", what,
            km_test_err.message);
  size_t ok = 0, bad_msg = 0, bad_strict = 0, tried = 0;
  size_t step = n > 600 ? (n - 512) / 300 + 1 : 1;
  for (size_t len = 0; len < n; ++len) {
    if (len >= 256 && len + 256 < n && (len - 256) % step) continue;
    ++tried;
    if (!spit(path, data, len)) continue;
    km_error e = {0};
    km_status s = read(path, ctx, &e);
    if (s == KM_OK) {
      ++ok;
      if (len < strict_below) ++bad_strict;
    } else if (!e.message[0]) {
      ++bad_msg;
    }
  }
  CHECK_MSG(bad_msg == 0, "%s: %zu failures without a message", what, bad_msg);
  CHECK_MSG(bad_strict == 0, "%s: %zu truncated prefixes read as valid", what, bad_strict);
  printf("%s: %zu prefixes of %zu bytes, %zu read as shorter valid files\n", what, tried, n, ok);
  remove(path);
  free(data);
  return ok;
}

static km_status read_take(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_take t;
  km_status s = km_take_read(p, &t, e);
  if (!s) km_take_free(&t);
  return s;
}
static km_status read_track(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_track t;
  km_status s = km_track_read(p, &t, e);
  if (!s) km_track_free(&t);
  return s;
}
static km_status read_rig(const char *p, void *ctx, km_error *e) {
  km_rig r;
  km_status s = km_rig_read(p, ctx, NULL, 0, &r, e);
  if (!s) km_rig_free(&r);
  return s;
}
static km_status read_char_rig(const char *p, void *ctx, km_error *e) {
  const km_mesh *m = ctx;
  km_character c = {0};
  km_status s = km_character_read_rig(p, m->n_vertices, &c, e);
  km_character_free(&c);
  return s;
}
static km_status read_cache(const char *p, void *ctx, km_error *e) {
  km_puppet *pp = NULL;
  km_status s = km_puppet_load(p, ctx, NULL, &pp, e);
  km_puppet_free(&pp);
  return s;
}
static km_status read_pc2(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  double *fr = NULL;
  km_anim_info info;
  km_status s = km_pc2_read(p, &fr, &info, e);
  free(fr);
  return s;
}
static km_status read_anim_info(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_anim_info info;
  return km_anim_info_read(p, &info, e);
}
static km_status read_glb_mesh(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_mesh m = {0};
  km_status s = km_mesh_read(p, &m, e);
  km_mesh_free(&m);
  return s;
}
static km_status read_bvh(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_take t;
  km_status s = km_bvh_read(p, NULL, &t, NULL, e);
  if (!s) km_take_free(&t);
  return s;
}
static km_status read_csv(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_take t;
  int32_t *labels = NULL;
  km_status s = km_kinect_csv_read(p, &t, &labels, e);
  if (!s) km_take_free(&t);
  free(labels);
  return s;
}

static km_status read_posedb(const char *p, void *ctx, km_error *e) {
  (void)ctx;
  km_posedb *db = NULL;
  km_status s = km_posedb_load(p, &db, e);
  km_posedb_free(&db);
  return s;
}

/* A small pose database: 12 point sets of 16 landmarks in two classes (class 1 lifts a hand). */
static km_status write_posedb(const char *path, km_error *e) {
  km_landmark lm[16];
  double V[12 * 48];
  km_mesh m[12];
  int32_t labels[12];
  for (int i = 0; i < 16; ++i) {
    memset(&lm[i], 0, sizeof lm[i]);
    snprintf(lm[i].name, sizeof lm[i].name, "p%d", i);
    snprintf(lm[i].mirror, sizeof lm[i].mirror, "p%d", i ^ 1);
    lm[i].vertex = i;
  }
  for (int k = 0; k < 12; ++k) {
    for (int i = 0; i < 16; ++i) {
      V[48 * k + 3 * i] = (i & 1 ? -1 : 1) * (0.2 + 0.05 * (i / 2)) + 0.003 * (k % 5);
      V[48 * k + 3 * i + 1] = 0.1 * (i / 2) + 0.002 * ((k * 7 + i) % 3);
      V[48 * k + 3 * i + 2] = 0.001 * ((k + i) % 4);
    }
    if (k & 1) V[48 * k + 1] += 0.5;
    m[k] = (km_mesh){.V = V + 48 * k, .n_vertices = 16};
    labels[k] = k & 1;
  }
  km_posedb_options o = {0};
  o.features = 20;
  o.cv_folds = 1;
  km_posedb *db = NULL;
  km_status s = km_posedb_build(m, 12, labels, 2, NULL, NULL, lm, 16, &o, &db, NULL, e);
  if (!s) s = km_posedb_save(db, path, e);
  km_posedb_free(&db);
  return s;
}

int main(void) {
  if (!mkdtemp(g_dir)) {
    perror("mkdtemp");
    return 1;
  }
  char path[512];
  km_character_options co = {0};
  co.target_vertices = 2000;
  km_character c = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  km_take take = {0};
  CHECK_OK(km_motion_generate(&c.skeleton, KM_MOTION_WAVE, 12, &take, KM_E));

  /* take (JSON): no strict prefix is a whole JSON document, except a trailing newline */
  snprintf(path, sizeof path, "%s/t.json", g_dir);
  CHECK_OK(km_take_write(path, &take, KM_E));
  size_t n = 0;
  free(km_test_read_file(path, &n));
  prefix_loop("take", path, "json", read_take, NULL, n > 2 ? n - 2 : 0);

  /* landmark track, JSON and CSV */
  km_track tr = {0};
  tr.n_frames = 5;
  tr.n_landmarks = 4;
  tr.fps = 30;
  char names[4][32] = {"a", "b", "c", "d"};
  double pos[5 * 4 * 3];
  for (size_t i = 0; i < sizeof pos / sizeof pos[0]; ++i)
    pos[i] = 0.01 * (double)i - 0.2;
  pos[7] = NAN;
  tr.names = names;
  tr.positions = pos;
  snprintf(path, sizeof path, "%s/tr.json", g_dir);
  CHECK_OK(km_track_write(path, &tr, KM_E));
  free(km_test_read_file(path, &n));
  prefix_loop("track (json)", path, "json", read_track, NULL, n > 2 ? n - 2 : 0);
  snprintf(path, sizeof path, "%s/tr.csv", g_dir);
  CHECK_OK(km_track_write(path, &tr, KM_E));
  prefix_loop("track (csv)", path, "csv", read_track, NULL, 0);

  /* rig sidecar: the puppetry rig and the character parts */
  snprintf(path, sizeof path, "%s/c.rig.json", g_dir);
  CHECK_OK(km_character_write_rig(path, &c, KM_E));
  free(km_test_read_file(path, &n));
  prefix_loop("rig", path, "json", read_rig, &c.mesh, n > 2 ? n - 2 : 0);
  prefix_loop("character rig", path, "json", read_char_rig, &c.mesh, n > 2 ? n - 2 : 0);

  /* reduced-model cache: sizes and checksum, every prefix refused */
  km_puppet *pp = NULL;
  CHECK_OK(km_puppet_precompute(&c.mesh, NULL, &pp, KM_E));
  snprintf(path, sizeof path, "%s/c.kmcache", g_dir);
  CHECK_OK(km_puppet_save(pp, path, KM_E));
  km_puppet_free(&pp);
  free(km_test_read_file(path, &n));
  prefix_loop("puppet cache", path, "kmcache", read_cache, &c.mesh, n);

  /* pose database: sizes and checksum, every prefix refused */
  snprintf(path, sizeof path, "%s/p.kmposedb", g_dir);
  CHECK_OK(write_posedb(path, KM_E));
  free(km_test_read_file(path, &n));
  prefix_loop("pose database", path, "kmposedb", read_posedb, NULL, n);

  /* pc2 and glb animations */
  const char *fmts[2] = {"pc2", "glb"};
  for (int k = 0; k < 2; ++k) {
    snprintf(path, sizeof path, "%s/a.%s", g_dir, fmts[k]);
    km_anim_writer *w = NULL;
    CHECK_OK(km_anim_writer_open(path, &c.mesh, NULL, &w, KM_E));
    for (int f = 0; w && f < 3; ++f) {
      for (size_t i = 0; i < 3 * c.mesh.n_vertices; ++i)
        c.mesh.V[i] += 0.001;
      CHECK_OK(km_anim_writer_push(w, c.mesh.V, KM_E));
    }
    CHECK_OK(km_anim_writer_close(&w, KM_E));
    free(km_test_read_file(path, &n));
    if (k == 0) {
      prefix_loop("pc2", path, "pc2", read_pc2, NULL, n);
      prefix_loop("pc2 info", path, "pc2", read_anim_info, NULL, n);
    } else {
      prefix_loop("glb info", path, "glb", read_anim_info, NULL, n);
      prefix_loop("glb mesh", path, "glb", read_glb_mesh, NULL, n);
    }
  }

  /* BVH and Kinect CSV: line-based, a prefix ending on a frame may be a shorter take */
  prefix_loop("bvh", KM_TEST_DATA "/bvh_two_joint.bvh", "bvh", read_bvh, NULL, 0);
  prefix_loop("kinect csv", KM_TEST_DATA "/kinect_reordered.csv", "csv", read_csv, NULL, 0);

  km_take_free(&take);
  km_character_free(&c);
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
  return km_test_finish("test_truncated");
}
