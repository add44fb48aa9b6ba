/* glTF 2.0 meshes in (.glb, and .gltf with embedded data: URIs or buffer files beside it):
 * triangles, POSITION, NORMAL, TEXCOORD_0.
 *
 * Written by hand on cJSON: cgltf (the reference C reader) is not packaged in Debian, and
 * the part a mesh needs (accessors over buffer views over buffers) is small; every offset,
 * stride and count is checked against the bytes that are really there before it is read.
 *
 * Several primitives (of one mesh or of several) are merged in the order of the file's
 * `meshes` array and of each mesh's `primitives`: the vertices of primitive k follow those of
 * primitive k-1 and its indices are shifted by their count, so the vertex order is the file's
 * accessor order, primitive after primitive. Node transforms are not applied (the mesh data is
 * taken as it is stored; a glTF is y up and in metres by the specification). Texture
 * coordinates are turned to kinemesh's (OBJ's) bottom-left origin: v = 1 - v_gltf; a
 * primitive without NORMAL or TEXCOORD_0 among others that have them gets zeros. */
#include "mesh/mesh_io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct gltf_doc {
  const char *name; /* for messages */
  cJSON *json;
  const unsigned char *bin; /* glb BIN chunk, may be NULL */
  size_t bin_len;
  unsigned char **bufs; /* decoded buffers (owned; NULL when the buffer is the BIN chunk) */
  size_t *buf_len;
  int n_bufs;
  const char *base_path; /* for relative buffer URIs; NULL: none allowed */
} gltf_doc;

static uint32_t rd32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int b64v(unsigned char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

static bool b64_decode(const char *s, unsigned char **out, size_t *n) {
  size_t len = strlen(s);
  unsigned char *o = km__malloc(len / 4 * 3 + 3, 1);
  if (!o) return false;
  size_t k = 0;
  uint32_t acc = 0;
  int bits = 0;
  for (size_t i = 0; i < len; ++i) {
    if (s[i] == '=') break;
    int v = b64v((unsigned char)s[i]);
    if (v < 0) {
      free(o);
      return false;
    }
    acc = acc << 6 | (uint32_t)v;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      o[k++] = (unsigned char)(acc >> bits);
    }
  }
  *out = o;
  *n = k;
  return true;
}

static int jint(const cJSON *o, const char *k, int def) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  if (!v) return def;
  if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble) || v->valuedouble < 0 ||
      v->valuedouble > 2147483647.0)
    return -2; /* invalid */
  return (int)v->valuedouble;
}

static km_status load_buffers(gltf_doc *d, km_error *err) {
  cJSON *bufs = cJSON_GetObjectItemCaseSensitive(d->json, "buffers");
  d->n_bufs = cJSON_GetArraySize(bufs);
  if (!d->n_bufs) return KM_OK;
  d->bufs = km__calloc((size_t)d->n_bufs, sizeof *d->bufs);
  d->buf_len = km__calloc((size_t)d->n_bufs, sizeof *d->buf_len);
  if (!d->bufs || !d->buf_len) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  for (int i = 0; i < d->n_bufs; ++i) {
    cJSON *b = cJSON_GetArrayItem(bufs, i);
    const char *uri = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(b, "uri"));
    int blen = jint(b, "byteLength", -1);
    if (blen < 0)
      return km__fail(err, KM_ERR_PARSE, "%s: buffers[%d]: expected a byteLength", d->name, i);
    if (!uri) {
      if (i != 0 || !d->bin)
        return km__fail(err, KM_ERR_PARSE,
                        "%s: buffers[%d] has no uri (only the first buffer of a .glb may use the "
                        "BIN chunk)",
                        d->name, i);
      if ((size_t)blen > d->bin_len)
        return km__fail(err, KM_ERR_PARSE,
                        "%s: buffers[0]: byteLength %d exceeds the %zu-byte BIN chunk", d->name,
                        blen, d->bin_len);
      d->buf_len[i] = (size_t)blen;
      continue;
    }
    if (!strncmp(uri, "data:", 5)) {
      const char *comma = strstr(uri, ";base64,");
      if (!comma || !b64_decode(comma + 8, &d->bufs[i], &d->buf_len[i]))
        return km__fail(err, KM_ERR_PARSE, "%s: buffers[%d]: expected a base64 data: URI",
                        d->name, i);
    } else {
      if (!d->base_path || strstr(uri, "..") || uri[0] == '/' || strchr(uri, ':'))
        return km__fail(err, KM_ERR_UNSUPPORTED,
                        "%s: buffers[%d]: external buffer '%.80s' cannot be read here (only a "
                        "file beside a .gltf read from disk)",
                        d->name, i, uri);
      const char *slash = strrchr(d->base_path, '/');
      size_t dir = slash ? (size_t)(slash - d->base_path) + 1 : 0;
      char *p = malloc(dir + strlen(uri) + 1);
      if (!p) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
      memcpy(p, d->base_path, dir);
      strcpy(p + dir, uri);
      char *data = NULL;
      km_status s = km__read_file(p, &data, &d->buf_len[i], err);
      free(p);
      if (s) return s;
      d->bufs[i] = (unsigned char *)data;
    }
    if (d->buf_len[i] < (size_t)blen)
      return km__fail(err, KM_ERR_PARSE, "%s: buffers[%d]: %zu bytes, byteLength says %d",
                      d->name, i, d->buf_len[i], blen);
    d->buf_len[i] = (size_t)blen;
  }
  return KM_OK;
}

static size_t comp_size(int ct) {
  switch (ct) {
  case 5120:
  case 5121: return 1;
  case 5122:
  case 5123: return 2;
  case 5125:
  case 5126: return 4;
  default: return 0;
  }
}

/* An accessor resolved to bytes: element i, component c is at p + i*stride + c*csize. */
typedef struct acc_view {
  const unsigned char *p;
  size_t count, stride, csize;
  int ncomp, ct;
  bool normalized;
} acc_view;

static km_status accessor(gltf_doc *d, int a, const char *what, acc_view *v, km_error *err) {
  cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "accessors"), a);
  if (a < 0 || !acc)
    return km__fail(err, KM_ERR_PARSE, "%s: %s: accessor %d does not exist", d->name, what, a);
  if (cJSON_GetObjectItemCaseSensitive(acc, "sparse"))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %s: sparse accessors are not supported", d->name,
                    what);
  const char *type = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(acc, "type"));
  int ct = jint(acc, "componentType", -1), count = jint(acc, "count", -1);
  int bvi = jint(acc, "bufferView", -1), aoff = jint(acc, "byteOffset", 0);
  int ncomp = !type                     ? 0
              : !strcmp(type, "SCALAR") ? 1
              : !strcmp(type, "VEC2")   ? 2
              : !strcmp(type, "VEC3")   ? 3
              : !strcmp(type, "VEC4")   ? 4
                                        : 0;
  size_t cs = comp_size(ct);
  if (!ncomp || !cs || count < 0 || bvi < 0 || aoff < 0)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: accessor %d: expected type, componentType, count and bufferView",
                    d->name, what, a);
  cJSON *bv = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "bufferViews"), bvi);
  int bi = jint(bv, "buffer", -1), boff = jint(bv, "byteOffset", 0), blen = jint(bv, "byteLength", -1);
  int stride = jint(bv, "byteStride", 0);
  if (!bv || bi < 0 || bi >= d->n_bufs || boff < 0 || blen < 0 || stride < 0)
    return km__fail(err, KM_ERR_PARSE, "%s: %s: bufferView %d is missing or invalid", d->name, what,
                    bvi);
  const unsigned char *buf = d->bufs[bi] ? d->bufs[bi] : d->bin;
  size_t elem = cs * (size_t)ncomp, st = stride ? (size_t)stride : elem;
  if ((uint64_t)boff + (uint64_t)blen > d->buf_len[bi] || st < elem ||
      (count && (uint64_t)aoff + (uint64_t)st * (uint64_t)(count - 1) + elem > (uint64_t)blen))
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: accessor %d (%d elements) does not fit its bufferView / buffer",
                    d->name, what, a, count);
  v->p = buf + boff + aoff;
  v->count = (size_t)count;
  v->stride = st;
  v->csize = cs;
  v->ncomp = ncomp;
  v->ct = ct;
  cJSON *nz = cJSON_GetObjectItemCaseSensitive(acc, "normalized");
  v->normalized = cJSON_IsTrue(nz);
  return KM_OK;
}

static double comp(const acc_view *v, size_t i, int c) {
  const unsigned char *p = v->p + i * v->stride + (size_t)c * v->csize;
  switch (v->ct) {
  case 5126: {
    uint32_t u = rd32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
  }
  case 5125: return (double)rd32(p);
  case 5123: {
    double x = (double)(uint16_t)(p[0] | p[1] << 8);
    return v->normalized ? x / 65535.0 : x;
  }
  case 5122: {
    double x = (double)(int16_t)(uint16_t)(p[0] | p[1] << 8);
    return v->normalized ? fmax(x / 32767.0, -1.0) : x;
  }
  case 5121: return v->normalized ? p[0] / 255.0 : p[0];
  case 5120: return v->normalized ? fmax((int8_t)p[0] / 127.0, -1.0) : (int8_t)p[0];
  default: return 0;
  }
}

/* cJSON on a NUL-terminated copy (the input buffer is not terminated); the byte of a syntax
 * error is reported relative to the JSON's start plus `at`. */
static km_status parse_json(const char *p, size_t n, const char *name, size_t at, cJSON **out,
                            km_error *err) {
  char *t = km__malloc(n + 1, 1);
  if (!t) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  memcpy(t, p, n);
  t[n] = '\0';
  const char *end = NULL;
  *out = cJSON_ParseWithLengthOpts(t, n, &end, false);
  km_status s = KM_OK;
  if (!*out)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte %zu: invalid glTF JSON", name,
                 at + (end && end >= t ? (size_t)(end - t) : 0));
  free(t);
  return s;
}

static km_status parse_doc(gltf_doc *d, km_mesh *out, km_error *err) {
  cJSON *meshes = cJSON_GetObjectItemCaseSensitive(d->json, "meshes");
  if (!cJSON_GetArraySize(meshes))
    return km__fail(err, KM_ERR_PARSE, "%s: expected a non-empty 'meshes' array", d->name);
  km_status s = load_buffers(d, err);
  if (s) return s;
  /* Pass 1: count; pass 2: fill. */
  size_t nv = 0, nf = 0;
  bool any_n = false, any_t = false;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      if (nv > INT32_MAX)
        return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %zu vertices exceed the int32 range",
                        d->name, nv);
      if ((s = km_mesh_alloc(nv, nf, out, err))) return s;
      if (any_n && !(out->N = km__calloc(nv ? nv : 1, 3 * sizeof(double)))) goto nomem;
      if (any_t && !(out->UV = km__calloc(nv ? nv : 1, 2 * sizeof(double)))) goto nomem;
    }
    size_t v0 = 0, f0 = 0;
    for (int mi = 0; mi < cJSON_GetArraySize(meshes); ++mi) {
      cJSON *prims = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(meshes, mi), "primitives");
      for (int pi = 0; pi < cJSON_GetArraySize(prims); ++pi) {
        cJSON *pr = cJSON_GetArrayItem(prims, pi);
        char what[64];
        snprintf(what, sizeof what, "meshes[%d].primitives[%d]", mi, pi);
        int mode = jint(pr, "mode", 4);
        if (mode != 4)
          return km__fail(err, KM_ERR_UNSUPPORTED,
                          "%s: %s: mode %d (only triangles, mode 4, are read)", d->name, what,
                          mode);
        cJSON *at = cJSON_GetObjectItemCaseSensitive(pr, "attributes");
        acc_view pos, nrm, tex, idx;
        if ((s = accessor(d, jint(at, "POSITION", -1), what, &pos, err))) return s;
        if (pos.ncomp != 3 || pos.ct != 5126)
          return km__fail(err, KM_ERR_PARSE, "%s: %s: POSITION must be VEC3 float", d->name, what);
        bool hn = cJSON_GetObjectItemCaseSensitive(at, "NORMAL") != NULL;
        bool ht = cJSON_GetObjectItemCaseSensitive(at, "TEXCOORD_0") != NULL;
        if (hn && (s = accessor(d, jint(at, "NORMAL", -1), what, &nrm, err))) return s;
        if (ht && (s = accessor(d, jint(at, "TEXCOORD_0", -1), what, &tex, err))) return s;
        if ((hn && (nrm.ncomp != 3 || nrm.count != pos.count)) ||
            (ht && (tex.ncomp != 2 || tex.count != pos.count)))
          return km__fail(err, KM_ERR_PARSE,
                          "%s: %s: NORMAL (VEC3) / TEXCOORD_0 (VEC2) must have POSITION's count",
                          d->name, what);
        bool hi = cJSON_GetObjectItemCaseSensitive(pr, "indices") != NULL;
        if (hi && (s = accessor(d, jint(pr, "indices", -1), what, &idx, err))) return s;
        if (hi && (idx.ncomp != 1 || (idx.ct != 5121 && idx.ct != 5123 && idx.ct != 5125)))
          return km__fail(err, KM_ERR_PARSE, "%s: %s: indices must be unsigned SCALAR", d->name,
                          what);
        size_t ni = hi ? idx.count : pos.count;
        if (ni % 3)
          return km__fail(err, KM_ERR_PARSE, "%s: %s: %zu indices is not a multiple of 3",
                          d->name, what, ni);
        if (pass == 0) {
          nv += pos.count;
          nf += ni / 3;
          any_n |= hn;
          any_t |= ht;
          if (nv > INT32_MAX) break;
          continue;
        }
        for (size_t i = 0; i < pos.count; ++i)
          for (int c = 0; c < 3; ++c) {
            double x = comp(&pos, i, c);
            if (!isfinite(x))
              return km__fail(err, KM_ERR_PARSE, "%s: %s: POSITION %zu is not finite", d->name,
                              what, i);
            out->V[3 * (v0 + i) + c] = x;
            if (hn) out->N[3 * (v0 + i) + c] = comp(&nrm, i, c);
            if (ht && c < 2) {
              double t = comp(&tex, i, c);
              out->UV[2 * (v0 + i) + c] = c ? 1 - t : t;
            }
          }
        for (size_t k = 0; k < ni; ++k) {
          double ix = hi ? comp(&idx, k, 0) : (double)k;
          if (!(ix < (double)pos.count))
            return km__fail(err, KM_ERR_PARSE,
                            "%s: %s: index %zu is %.0f, outside the primitive's %zu vertices",
                            d->name, what, k, ix, pos.count);
          out->F[3 * f0 + k] = (int32_t)(v0 + (size_t)ix);
        }
        v0 += pos.count;
        f0 += ni / 3;
      }
    }
  }
  if (nv == 0) return km__fail(err, KM_ERR_PARSE, "%s: the meshes have no vertices", d->name);
  return KM_OK;
nomem:
  return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
}

km_status km__gltf_parse(const char *data, size_t size, const char *name, const char *base_path,
                         km_mesh *out, km_error *err) {
  gltf_doc d = {0};
  d.name = name;
  d.base_path = base_path;
  const unsigned char *u = (const unsigned char *)data;
  if (size >= 4 && !memcmp(data, "glTF", 4)) {
    if (size < 20 || rd32(u + 4) != 2)
      return km__fail(err, KM_ERR_PARSE, "%s: expected a glTF 2.0 binary header", name);
    size_t total = rd32(u + 8), jl = rd32(u + 12);
    if (total > size || total < 20 || rd32(u + 16) != 0x4E4F534Au || jl > total - 20)
      return km__fail(err, KM_ERR_PARSE,
                      "%s: byte 12: the JSON chunk (%zu bytes) does not fit the %zu-byte file",
                      name, jl, size);
    km_status s = parse_json(data + 20, jl, name, 20, &d.json, err);
    if (s) return s;
    size_t bo = 20 + jl;
    if (bo + 8 <= total && rd32(u + bo + 4) == 0x004E4942u) {
      size_t bl = rd32(u + bo);
      if (bl > total - bo - 8) {
        cJSON_Delete(d.json);
        return km__fail(err, KM_ERR_PARSE, "%s: byte %zu: the BIN chunk is truncated", name, bo);
      }
      d.bin = u + bo + 8;
      d.bin_len = bl;
    }
  } else {
    km_status s = parse_json(data, size, name, 0, &d.json, err);
    if (s) return s;
  }
  km_status s = parse_doc(&d, out, err);
  if (s) km_mesh_free(out);
  for (int i = 0; i < d.n_bufs && d.bufs; ++i)
    free(d.bufs[i]);
  free(d.bufs);
  free(d.buf_len);
  cJSON_Delete(d.json);
  return s;
}
