/* --compress (issue 16): KHR_mesh_quantization + EXT_meshopt_compression on every glb export
 * kind. The test writes the same animation plain and compressed, decodes the compressed file's
 * views itself (meshopt_decodeVertexBuffer / IndexBuffer and the filters, as a player does) and
 * checks that rest positions and every morph target's deltas equal the plain file's within
 * half the quantisation step, the weights and indices come back exactly or within their
 * filter's precision, the skin's inverse bind matrices carry the dequantisation, and the
 * reported error is that of the decoded file. */
#include "km_test.h"
#include "tube_fixture.h"

#include <cjson/cJSON.h>
#include <meshoptimizer.h>
#include <unistd.h>

enum { RINGS = 24, SEGS = 16, T = 20 };

/* Frame k: the tube bends about z (angle growing along x) and walks 3 m along z, more than
 * the rest's extent, so the morph deltas need the grid to grow. */
static void frame(const km_mesh *m, int k, double *V) {
  double ph = sin(2 * M_PI * k / (T - 1)), walk = 3.0 * k / (T - 1);
  for (size_t i = 0; i < m->n_vertices; ++i) {
    const double *p = m->V + 3 * i;
    double a = 0.9 * ph * p[0], c = cos(a), s = sin(a);
    V[3 * i] = c * p[0] - s * (p[1] - 1.0);
    V[3 * i + 1] = 1.0 + s * p[0] + c * (p[1] - 1.0);
    V[3 * i + 2] = p[2] + walk;
  }
}

static km_status write_anim(const char *path, const km_mesh *m, km_anim_export kind, size_t morphs,
                            size_t bones, bool compress, km_anim_report *rep) {
  km_ssdr_options so = {.bones = bones, .iterations = 6};
  km_anim_options ao = {
      .fps = 30, .export_kind = kind, .morphs = morphs, .skin = &so, .compress = compress};
  km_anim_writer *w = NULL;
  km_error err = {0};
  double *V = malloc(m->n_vertices * 3 * sizeof *V);
  km_status s = km_anim_writer_open(path, m, &ao, &w, &err);
  for (int k = 0; s == KM_OK && k < T; ++k) {
    frame(m, k, V);
    s = km_anim_writer_push(w, V, &err);
  }
  if (s == KM_OK) s = km_anim_writer_finish(&w, rep, &err);
  km_anim_writer_free(&w);
  if (s != KM_OK) fprintf(stderr, "%s: %s\n", path, err.message);
  free(V);
  return s;
}

/* ---- a small glb reader: JSON + BIN, and each accessor's bytes decoded */
typedef struct glb {
  unsigned char *data;
  size_t size;
  cJSON *root;
  const unsigned char *bin;
  size_t bin_len;
} glb;

static bool glb_open(const char *path, glb *g) {
  memset(g, 0, sizeof *g);
  g->data = read_all(path, &g->size);
  if (!g->data || g->size < 28) return false;
  uint32_t jl = getu32(g->data + 12);
  g->root = cJSON_ParseWithLength((const char *)g->data + 20, jl);
  g->bin_len = getu32(g->data + 20 + jl);
  g->bin = g->data + 28 + jl;
  return g->root != NULL;
}

static void glb_close(glb *g) {
  cJSON_Delete(g->root);
  free(g->data);
}

static double num(const cJSON *o, const char *k) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  return cJSON_IsNumber(v) ? v->valuedouble : 0;
}

static const cJSON *item(const cJSON *root, const char *arr, int i) {
  return cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, arr), i);
}

/* The bytes of accessor a (malloc'd, count elements of *stride bytes), decoded when its view is
 * meshopt-compressed; *filtered says whether a filter was applied. NULL on a malformed file. */
static unsigned char *accessor_bytes(const glb *g, int a, size_t *count, size_t *stride,
                                     bool *compressed) {
  const cJSON *acc = item(g->root, "accessors", a);
  const cJSON *view = item(g->root, "bufferViews", (int)num(acc, "bufferView"));
  if (!acc || !view) return NULL;
  *count = (size_t)num(acc, "count");
  const cJSON *ext = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(view, "extensions"), "EXT_meshopt_compression");
  *compressed = ext != NULL;
  size_t len = (size_t)num(view, "byteLength");
  unsigned char *out = malloc(len + 16);
  if (!ext) {
    memcpy(out, g->bin + (size_t)num(view, "byteOffset"), len);
    *stride = num(view, "byteStride") > 0 ? (size_t)num(view, "byteStride") : len / *count;
    return out;
  }
  size_t n = (size_t)num(ext, "count"), st = (size_t)num(ext, "byteStride");
  size_t off = (size_t)num(ext, "byteOffset"), bl = (size_t)num(ext, "byteLength");
  const char *mode = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(ext, "mode"));
  const char *filter = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(ext, "filter"));
  if ((int)num(ext, "buffer") != 0 || off + bl > g->bin_len || n * st != len) {
    free(out);
    return NULL;
  }
  int rc = !strcmp(mode, "TRIANGLES") ? meshopt_decodeIndexBuffer(out, n, st, g->bin + off, bl)
                                      : meshopt_decodeVertexBuffer(out, n, st, g->bin + off, bl);
  if (rc != 0) {
    free(out);
    return NULL;
  }
  if (filter && !strcmp(filter, "OCTAHEDRAL")) meshopt_decodeFilterOct(out, n, st);
  if (filter && !strcmp(filter, "QUATERNION")) meshopt_decodeFilterQuat(out, n, st);
  if (filter && !strcmp(filter, "EXPONENTIAL")) meshopt_decodeFilterExp(out, n, st);
  *stride = st;
  size_t ao = (size_t)num(acc, "byteOffset"); /* bones share a view, each at its offset */
  if (ao + *count * st > len) {
    free(out);
    return NULL;
  }
  memmove(out, out + ao, *count * st);
  return out;
}

/* Triangles compared as rotated so their smallest index leads, then sorted. */
static void canon(uint32_t t[3]) {
  while (t[0] > t[1] || t[0] > t[2]) {
    uint32_t x = t[0];
    t[0] = t[1], t[1] = t[2], t[2] = x;
  }
}
static int cmp_tri(const void *a, const void *b) {
  uint32_t x[3], y[3];
  memcpy(x, a, 12);
  memcpy(y, b, 12);
  canon(x);
  canon(y);
  for (int k = 0; k < 3; ++k)
    if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
  return 0;
}

static bool has_string(const cJSON *arr, const char *s) {
  const cJSON *e;
  cJSON_ArrayForEach(e, arr) if (cJSON_IsString(e) && !strcmp(e->valuestring, s)) return true;
  return false;
}

/* Plain vs compressed morph files (per-frame or PCA targets). */
static void check_morphs(const char *plain, const char *packed, const km_anim_report *rp,
                         const km_anim_report *rz) {
  glb p, z;
  CHECK(glb_open(plain, &p));
  CHECK(glb_open(packed, &z));
  if (!p.root || !z.root) return;
  CHECK(has_string(cJSON_GetObjectItem(z.root, "extensionsRequired"), "EXT_meshopt_compression"));
  CHECK(has_string(cJSON_GetObjectItem(z.root, "extensionsRequired"), "KHR_mesh_quantization"));
  const cJSON *node = item(z.root, "nodes", 0);
  double off[3], s = num(node, "scale") /* an array */;
  const cJSON *sc = cJSON_GetObjectItem(node, "scale"),
              *tr = cJSON_GetObjectItem(node, "translation");
  s = cJSON_GetArrayItem(sc, 0)->valuedouble;
  for (int a = 0; a < 3; ++a)
    off[a] = cJSON_GetArrayItem(tr, a)->valuedouble;
  CHECK(s > 0 && s < 1e-3);
  const double tol = 0.5 * s * (1 + 1e-6) + 1e-6; /* half a step (+ float32 of the plain file) */
  const cJSON *pp = item(item(p.root, "meshes", 0), "primitives", 0);
  const cJSON *pz = item(item(z.root, "meshes", 0), "primitives", 0);
  size_t np, nz, sp, sz;
  bool cp, cz;
  /* rest positions */
  int ap = (int)num(cJSON_GetObjectItem(pp, "attributes"), "POSITION");
  int az = (int)num(cJSON_GetObjectItem(pz, "attributes"), "POSITION");
  unsigned char *bp = accessor_bytes(&p, ap, &np, &sp, &cp),
                *bz = accessor_bytes(&z, az, &nz, &sz, &cz);
  CHECK(bp && bz && np == nz && cz && !cp);
  CHECK((int)num(item(z.root, "accessors", az), "componentType") == 5123);
  double worst = 0;
  for (size_t i = 0; bp && bz && i < np; ++i)
    for (int c = 0; c < 3; ++c)
      worst =
          fmax(worst, fabs(off[c] + s * getu16(bz + i * sz + 2 * c) - getf(bp + i * sp + 4 * c)));
  CHECK_MSG(worst <= tol, "rest positions off by %g m, step %g m", worst, s);
  free(bp);
  free(bz);
  /* indices */
  bp = accessor_bytes(&p, (int)num(pp, "indices"), &np, &sp, &cp);
  bz = accessor_bytes(&z, (int)num(pz, "indices"), &nz, &sz, &cz);
  /* the same triangles (the writer reorders them for the index codec; vertices stay) */
  CHECK(bp && bz && np == nz && cz && sp == 4 && sz == 4 && np % 3 == 0);
  if (bp && bz && np == nz) {
    for (size_t t = 0; t < np / 3; ++t) {
      uint32_t x[3];
      memcpy(x, bp + 12 * t, 12);
      canon(x);
      memcpy(bp + 12 * t, x, 12);
      memcpy(x, bz + 12 * t, 12);
      canon(x);
      memcpy(bz + 12 * t, x, 12);
    }
    qsort(bp, np / 3, 12, cmp_tri);
    qsort(bz, np / 3, 12, cmp_tri);
    CHECK(!memcmp(bp, bz, np * 4));
  }
  free(bp);
  free(bz);
  /* every target's position deltas */
  const cJSON *tp = cJSON_GetObjectItem(pp, "targets"), *tz = cJSON_GetObjectItem(pz, "targets");
  CHECK(cJSON_GetArraySize(tp) == cJSON_GetArraySize(tz) && cJSON_GetArraySize(tz) > 0);
  worst = 0;
  double big = 0;
  for (int k = 0; k < cJSON_GetArraySize(tz); ++k) {
    bp = accessor_bytes(&p, (int)num(cJSON_GetArrayItem(tp, k), "POSITION"), &np, &sp, &cp);
    bz = accessor_bytes(&z, (int)num(cJSON_GetArrayItem(tz, k), "POSITION"), &nz, &sz, &cz);
    CHECK(bp && bz && np == nz && cz);
    for (size_t i = 0; bp && bz && i < np; ++i)
      for (int c = 0; c < 3; ++c) {
        double d = getf(bp + i * sp + 4 * c);
        worst = fmax(worst, fabs(s * gets16(bz + i * sz + 2 * c) - d));
        big = fmax(big, fabs(d));
      }
    free(bp);
    free(bz);
  }
  CHECK_MSG(worst <= tol, "morph deltas off by %g m, step %g m", worst, s);
  CHECK_MSG(big > 2.5, "the deltas reach %g m (the walk is 3 m)", big);
  /* weights: the exponential filter keeps 16 bits of mantissa */
  const cJSON *smp = item(item(p.root, "animations", 0), "samplers", 0);
  const cJSON *smz = item(item(z.root, "animations", 0), "samplers", 0);
  bp = accessor_bytes(&p, (int)num(smp, "output"), &np, &sp, &cp);
  bz = accessor_bytes(&z, (int)num(smz, "output"), &nz, &sz, &cz);
  CHECK(bp && bz && np == nz && cz);
  worst = 0;
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; bp && bz && i < np; ++i) {
    double a = getf(bp + 4 * i), b = getf(bz + 4 * i);
    worst = fmax(worst, fabs(a - b) / fmax(fabs(a), 1e-3));
    lo = fmin(lo, fmin(a, b)), hi = fmax(hi, fmax(a, b));
  }
  CHECK_MSG(worst <= 1.0 / 16384, "weights off by %g (relative)", worst);
  /* in [0, 1], where Blender 3.4's shape-key sliders do not clamp them */
  CHECK_MSG(lo >= 0 && hi <= 1, "weights in [%g, %g]", lo, hi);
  free(bp);
  free(bz);
  /* the reported error is the decoded file's: at least the plain file's, within a few steps */
  CHECK_MSG(rz->max_error >= rp->max_error - 1e-6 && rz->max_error <= rp->max_error + 8 * s,
            "max error %g m compressed, %g m plain, step %g m", rz->max_error, rp->max_error, s);
  CHECK(rz->rms_error > 0);
  glb_close(&p);
  glb_close(&z);
}

static void check_skin(const char *plain, const char *packed) {
  glb p, z;
  CHECK(glb_open(plain, &p));
  CHECK(glb_open(packed, &z));
  if (!p.root || !z.root) return;
  const cJSON *q = cJSON_GetObjectItem(
      cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(z.root, "asset"), "extras"),
                          "kinemesh"),
      "quantization");
  double s = num(q, "scale"), off[3];
  for (int a = 0; a < 3; ++a)
    off[a] = cJSON_GetArrayItem(cJSON_GetObjectItem(q, "offset"), a)->valuedouble;
  CHECK(s > 0 && s < 1e-3);
  const cJSON *pp = item(item(p.root, "meshes", 0), "primitives", 0);
  const cJSON *pz = item(item(z.root, "meshes", 0), "primitives", 0);
  size_t np, nz, sp, sz, nv;
  bool cp, cz;
  const cJSON *atp = cJSON_GetObjectItem(pp, "attributes"),
              *atz = cJSON_GetObjectItem(pz, "attributes");
  unsigned char *bp = accessor_bytes(&p, (int)num(atp, "POSITION"), &np, &sp, &cp);
  unsigned char *bz = accessor_bytes(&z, (int)num(atz, "POSITION"), &nz, &sz, &cz);
  CHECK(bp && bz && np == nz && cz);
  double worst = 0;
  for (size_t i = 0; bp && bz && i < np; ++i)
    for (int c = 0; c < 3; ++c)
      worst =
          fmax(worst, fabs(off[c] + s * getu16(bz + i * sz + 2 * c) - getf(bp + i * sp + 4 * c)));
  CHECK_MSG(worst <= 0.5 * s + 1e-6, "skin rest positions off by %g m, step %g", worst, s);
  nv = np;
  free(bp);
  free(bz);
  /* joints equal, weights within half of 1/255 and summing to 255 exactly */
  bp = accessor_bytes(&p, (int)num(atp, "JOINTS_0"), &np, &sp, &cp);
  bz = accessor_bytes(&z, (int)num(atz, "JOINTS_0"), &nz, &sz, &cz);
  CHECK(bp && bz && np == nv && nz == nv && sp == sz && !memcmp(bp, bz, nv * sp));
  free(bp);
  free(bz);
  bp = accessor_bytes(&p, (int)num(atp, "WEIGHTS_0"), &np, &sp, &cp);
  bz = accessor_bytes(&z, (int)num(atz, "WEIGHTS_0"), &nz, &sz, &cz);
  CHECK(bp && bz && sz == 4);
  int bad_sum = 0;
  worst = 0;
  for (size_t i = 0; bp && bz && i < nv; ++i) {
    int sum = 0;
    for (int k = 0; k < 4; ++k) {
      sum += bz[4 * i + k];
      worst = fmax(worst, fabs(bz[4 * i + k] / 255.0 - getf(bp + i * sp + 4 * k)));
    }
    bad_sum += sum != 255;
  }
  CHECK_MSG(bad_sum == 0 && worst <= 2.0 / 255, "weights: %d sums != 255, off by %g", bad_sum,
            worst);
  free(bp);
  free(bz);
  /* inverse bind matrices: T(o - c) S(s) against the plain T(-c) */
  const cJSON *skp = item(p.root, "skins", 0), *skz = item(z.root, "skins", 0);
  bp = accessor_bytes(&p, (int)num(skp, "inverseBindMatrices"), &np, &sp, &cp);
  bz = accessor_bytes(&z, (int)num(skz, "inverseBindMatrices"), &nz, &sz, &cz);
  CHECK(bp && bz && np == nz && np > 0);
  worst = 0;
  for (size_t j = 0; bp && bz && j < np; ++j)
    for (int c = 0; c < 3; ++c) {
      worst = fmax(worst, fabs(getf(bz + 64 * j + 4 * (5 * c)) - s));
      worst = fmax(worst, fabs(getf(bz + 64 * j + 4 * (12 + c)) -
                               (off[c] + getf(bp + 64 * j + 4 * (12 + c)))));
    }
  CHECK_MSG(worst < 1e-5, "inverse bind matrices off by %g", worst);
  free(bp);
  free(bz);
  /* rotations: the quaternion filter (16 bits): within 1e-3 rad (1 - cos(a/2) < 1e-7) */
  const cJSON *anp = item(p.root, "animations", 0), *anz = item(z.root, "animations", 0);
  worst = 0;
  for (int k = 1; k < cJSON_GetArraySize(cJSON_GetObjectItem(anz, "samplers")); k += 2) {
    bp = accessor_bytes(&p, (int)num(item(anp, "samplers", k), "output"), &np, &sp, &cp);
    bz = accessor_bytes(&z, (int)num(item(anz, "samplers", k), "output"), &nz, &sz, &cz);
    CHECK(bp && bz && np == nz && sz == 8);
    for (size_t t = 0; bp && bz && t < np; ++t) {
      double dot = 0, n2 = 0;
      for (int c = 0; c < 4; ++c) {
        double qz = gets16(bz + 8 * t + 2 * c) / 32767.0;
        dot += getf(bp + 16 * t + 4 * c) * qz;
        n2 += qz * qz;
      }
      CHECK(fabs(n2 - 1) < 1e-3); /* unit within the 16-bit rounding; players normalise */
      dot /= sqrt(n2);
      worst = fmax(worst, 1 - fabs(dot));
    }
    free(bp);
    free(bz);
  }
  CHECK_MSG(worst < 1e-7, "rotations: 1 - |q.q'| up to %g", worst);
  glb_close(&p);
  glb_close(&z);
}

int main(void) {
  km_mesh m = {0};
  tube_mesh(&m, RINGS, SEGS, true);
  char a[64], b[64];
  snprintf(a, sizeof a, "test_glb_compress_%ld_p.glb", (long)getpid());
  snprintf(b, sizeof b, "test_glb_compress_%ld_z.glb", (long)getpid());
  km_anim_report rp, rz;

  /* per-frame morphs */
  CHECK(write_anim(a, &m, KM_ANIM_EXPORT_MORPHS, 0, 0, false, &rp) == KM_OK);
  CHECK(write_anim(b, &m, KM_ANIM_EXPORT_MORPHS, 0, 0, true, &rz) == KM_OK);
  check_morphs(a, b, &rp, &rz);
  struct stat sa, sb;
  CHECK(stat(a, &sa) == 0 && stat(b, &sb) == 0 && sb.st_size * 3 < sa.st_size);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(b, &info, KM_E));
  CHECK(info.frames == T && info.vertices == m.n_vertices && fabs(info.fps - 30) < 1e-9);

  /* The animation reader decodes it too (what `kinemesh bake` reads): the same frames as the
   * plain file's, vertex for vertex, within the quantisation error the writer reported. */
  {
    km_mesh bp = {0}, bz = {0};
    double *fp = NULL, *fz = NULL;
    km_anim_info ip, iz;
    CHECK_OK(km_anim_read(a, &bp, &fp, &ip, KM_E));
    CHECK_OK(km_anim_read(b, &bz, &fz, &iz, KM_E));
    CHECK(iz.frames == ip.frames && bz.n_vertices == bp.n_vertices && fabs(iz.fps - ip.fps) < 1e-9);
    double worst = fp && fz ? 0 : INFINITY;
    for (size_t i = 0; fp && fz && iz.frames == ip.frames && i < 3 * ip.frames * bp.n_vertices; ++i)
      worst = fmax(worst, fabs(fz[i] - fp[i]));
    printf("  km_anim_read of the compressed morphs: %zu frames, worst coordinate %.3g m off the "
           "plain file's (writer's max error %.3g m)\n",
           iz.frames, worst, rz.max_error);
    CHECK_MSG(worst <= rz.max_error + 1e-6, "compressed frames %g m off (writer said %g)", worst,
              rz.max_error);
    km_mesh_free(&bp);
    km_mesh_free(&bz);
    free(fp);
    free(fz);
  }

  /* PCA morphs */
  CHECK(write_anim(a, &m, KM_ANIM_EXPORT_MORPHS_PCA, 4, 0, false, &rp) == KM_OK);
  CHECK(write_anim(b, &m, KM_ANIM_EXPORT_MORPHS_PCA, 4, 0, true, &rz) == KM_OK);
  check_morphs(a, b, &rp, &rz);
  CHECK(rz.targets == 5); /* 4 basis targets and the offset that keeps their weights >= 0 */

  /* skin */
  CHECK(write_anim(a, &m, KM_ANIM_EXPORT_SKIN, 0, 6, false, &rp) == KM_OK);
  CHECK(write_anim(b, &m, KM_ANIM_EXPORT_SKIN, 0, 6, true, &rz) == KM_OK);
  check_skin(a, b);
  CHECK_MSG(rz.max_error <= rp.max_error + 1e-3 && rz.max_error >= 0.5 * rp.max_error,
            "skin max error %g m compressed vs %g m plain", rz.max_error, rp.max_error);
  CHECK(stat(a, &sa) == 0 && stat(b, &sb) == 0 && sb.st_size * 2 < sa.st_size);

  remove(a);
  remove(b);
  km_mesh_free(&m);
  return km_test_finish("test_glb_compress");
}
