/* glTF 2.0 meshes in (.glb, and .gltf with embedded data: URIs or buffer files beside it):
 * triangles (and strips and fans, as the triangles they stand for), POSITION, NORMAL, TEXCOORD_0.
 *
 * Written by hand on cJSON: cgltf (the reference C reader) is not packaged in Debian, and
 * the part a mesh needs (accessors over buffer views over buffers) is small; every offset,
 * stride and count is checked against the bytes that are really there before it is read.
 *
 * What is read is the scene (`scene`, else the first of `scenes`, else every root node): its
 * nodes depth-first in the order they are listed, children in order; each node with a mesh
 * contributes that mesh's primitives in order, with the node's world transform (matrix or
 * TRS, composed down the hierarchy) applied to positions and normals (a mirroring transform
 * also flips the triangles' winding). A file without nodes: the `meshes` in order, as stored.
 * The vertices of primitive k follow those of primitive k-1 and its indices are shifted by
 * their count, so the vertex order is the file's accessor order, primitive after primitive,
 * instance after instance. A glTF is y up, facing +z, in metres by the specification. Texture
 * coordinates are turned to kinemesh's (OBJ's) bottom-left origin: v = 1 - v_gltf; a
 * primitive without NORMAL or TEXCOORD_0 among others that have them gets zeros.
 *
 * Compressed files (gltfpack's, kinemesh's --compress): an EXT_meshopt_compression buffer view
 * is decoded from its extension object's bytes (decode_view) and read like any other, its
 * fallback buffer having no data; KHR_mesh_quantization's byte / short attributes are read
 * through comp() (normalized or not) and dequantised by the node transforms / inverse bind
 * matrices that carry the grid, texture coordinates also by the base colour texture's
 * KHR_texture_transform (gltfpack's 12-bit UV range). A KHR_draco_mesh_compression primitive
 * (prim_accessor) is decoded by libdraco (draco.cc), once per bufferView, and each attribute the
 * extension lists is laid out as its accessor declares (componentType, normalized) and read
 * through comp() like a plain one; its indices are the decoded triangles. The vertex order is
 * the decoded one, which is what the file's accessors describe.
 *
 * Skins: a node with a `skin` whose primitive has JOINTS_0 / WEIGHTS_0 is placed as a viewer
 * shows it, by linear blend skinning with the scene's joint transforms (world matrix of each
 * joint node times its inverse bind matrix; the mesh node's own transform is ignored, as the
 * specification says); at the bind pose that is the positions as stored. When the caller asks
 * for the skin (km_mesh_read_skinned), the joints of every skin used are gathered into one
 * list (each joint node once, in order of first use), each with its name, its nearest
 * ancestor node that is also a joint, and its world position; every vertex gets its 4
 * JOINTS_0 / WEIGHTS_0 influences (weights normalised; with JOINTS_1 / WEIGHTS_1 too, the
 * position is placed by all 8 and the skin keeps the 4 largest, renormalised) and an unskinned
 * primitive is bound whole to the nearest joint above its node (none: no influence). */
#include "mesh/draco_decode.h"
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <meshoptimizer.h>
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
  unsigned char **views; /* n_views: EXT_meshopt_compression views decoded (owned), or NULL */
  size_t *view_len;
  int n_views;
  km__draco **draco; /* n_draco (bufferViews): KHR_draco_mesh_compression meshes (owned) */
  int n_draco;
  unsigned char **dacc; /* n_dacc (accessors): their values decoded from Draco (owned) */
  int n_dacc;
  int n_nodes;
  int *node_parent;   /* n_nodes: parent node, -1 for a root */
  double *node_world; /* n_nodes*16: world matrices (column-major) */
  km_mesh_skin *skin; /* requested skin output, or NULL */
  int *joint_of_node; /* n_nodes: index in skin's joint list, -1 */
  double *S;          /* the current instance's skin matrices (S_n*16), or NULL */
  int32_t *S_ids;     /* their joints' indices in the gathered list */
  size_t S_n;
  /* each placed primitive's run of faces and material index (-1: none), in face order */
  size_t *run_first, *run_n;
  int *run_mat;
  size_t n_runs, cap_runs;
  size_t *prim_base; /* the current mesh's primitives' first vertices (read_instances) */
  size_t cap_base;
} gltf_doc;

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

/* v as an index (a whole number in 0 .. INT_MAX), else -2 (km__whole_number). */
static int jindex(const cJSON *v) {
  int64_t i;
  if (!cJSON_IsNumber(v) || !km__whole_number(v->valuedouble, 0, 2147483647.0, &i))
    return -2; /* invalid */
  return (int)i;
}

static int jint(const cJSON *o, const char *k, int def) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  return v ? jindex(v) : def;
}

static int hex_digit(char c) {
  return c >= '0' && c <= '9'   ? c - '0'
         : c >= 'a' && c <= 'f' ? c - 'a' + 10
         : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                : -1;
}

/* The bytes a glTF uri names (buffers' and images'): a base64 data: URI, or a file beside a
 * .gltf read from disk (a relative path, percent-decoded as the specification's URIs are: a
 * file "my skin.png" is "my%20skin.png"; none that leaves the folder, is absolute or has a
 * scheme).
 * On failure *why says what is wrong and the status is KM_ERR_PARSE (a bad data: URI),
 * KM_ERR_UNSUPPORTED (a file that cannot be read here), KM_ERR_IO (it cannot be read) or
 * KM_ERR_NOMEM. *bytes: allocated, free(). */
static km_status read_uri(const gltf_doc *d, const char *uri, unsigned char **bytes, size_t *n,
                          const char **why) {
  *bytes = NULL, *n = 0;
  if (!strncmp(uri, "data:", 5)) {
    const char *comma = strstr(uri, ";base64,");
    if (comma && b64_decode(comma + 8, bytes, n)) return KM_OK;
    *why = "its data: URI is not base64";
    return KM_ERR_PARSE;
  }
  size_t len = strlen(uri);
  char *name = malloc(len + 1);
  if (!name) return *why = "out of memory", KM_ERR_NOMEM;
  size_t k = 0;
  for (size_t i = 0; i < len; ++i) {
    int hi = i + 2 < len ? hex_digit(uri[i + 1]) : -1, lo = hi >= 0 ? hex_digit(uri[i + 2]) : -1;
    if (uri[i] == '%' && lo >= 0 && (hi | lo)) {
      name[k++] = (char)(hi << 4 | lo);
      i += 2;
    } else {
      name[k++] = uri[i];
    }
  }
  name[k] = 0;
  if (!d->base_path || !name[0] || strstr(name, "..") || name[0] == '/' || strchr(name, ':') ||
      strchr(name, '\\')) {
    free(name);
    *why = "it is an external file that cannot be read here (only a file beside a .gltf read "
           "from disk)";
    return KM_ERR_UNSUPPORTED;
  }
  char *p = km__path_beside(d->base_path, name), *data = NULL;
  free(name);
  if (!p) return *why = "out of memory", KM_ERR_NOMEM;
  km_status s = km__read_file(p, &data, n, NULL);
  free(p);
  if (s) return *why = "its file cannot be read", KM_ERR_IO;
  *bytes = (unsigned char *)data;
  return KM_OK;
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
    if (!uri && cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(b, "extensions"),
                                                 "EXT_meshopt_compression")) {
      /* EXT_meshopt_compression's fallback buffer: no bytes; its views are decoded from their
       * compressed source (decode_view), never read from here (length 0 keeps them out). */
      d->buf_len[i] = 0;
      continue;
    }
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
    const char *why = NULL;
    km_status s = read_uri(d, uri, &d->bufs[i], &d->buf_len[i], &why);
    if (s) return km__fail(err, s, "%s: buffers[%d] ('%.80s'): %s", d->name, i, uri, why);
    if (d->buf_len[i] < (size_t)blen)
      return km__fail(err, KM_ERR_PARSE, "%s: buffers[%d]: %zu bytes, byteLength says %d", d->name,
                      i, d->buf_len[i], blen);
    d->buf_len[i] = (size_t)blen;
  }
  return KM_OK;
}

/* EXT_meshopt_compression: bufferView bvi's bytes decoded from its extension object (buffer,
 * byteOffset, byteLength: the compressed source; count elements of byteStride bytes; mode
 * ATTRIBUTES / TRIANGLES / INDICES; filter NONE / OCTAHEDRAL / QUATERNION / EXPONENTIAL), once
 * per view, into *out (count * byteStride bytes, *n). Everything is checked before the decoder
 * sees it; a decoder failure or a size out of range is a KM_ERR_PARSE naming the view. The
 * decoders write host byte order, which comp() reads as little-endian: kinemesh's platforms
 * are little-endian (the writer, src/anim/glb.c, assumes the same). */
static km_status decode_view(gltf_doc *d, int bvi, const cJSON *ext, const unsigned char **out,
                             size_t *n, km_error *err) {
  if (!d->views) {
    d->n_views = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(d->json, "bufferViews"));
    d->views = km__calloc((size_t)d->n_views, sizeof *d->views);
    d->view_len = km__calloc((size_t)d->n_views, sizeof *d->view_len);
    if (!d->views || !d->view_len) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  }
  if (bvi < 0 || bvi >= d->n_views)
    return km__fail(err, KM_ERR_PARSE, "%s: bufferView %d does not exist", d->name, bvi);
  if (d->views[bvi]) {
    *out = d->views[bvi], *n = d->view_len[bvi];
    return KM_OK;
  }
  int bi = jint(ext, "buffer", -1), off = jint(ext, "byteOffset", 0);
  int len = jint(ext, "byteLength", -1), stride = jint(ext, "byteStride", -1);
  int count = jint(ext, "count", -1);
  const char *mode = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(ext, "mode"));
  const cJSON *jf = cJSON_GetObjectItemCaseSensitive(ext, "filter");
  const char *filter = jf ? cJSON_GetStringValue(jf) : "NONE";
  const char *why = NULL;
  int m = !mode                         ? -1
          : !strcmp(mode, "ATTRIBUTES") ? 0
          : !strcmp(mode, "TRIANGLES")  ? 1
          : !strcmp(mode, "INDICES")    ? 2
                                        : -1;
  int f = !filter                          ? -1
          : !strcmp(filter, "NONE")        ? 0
          : !strcmp(filter, "OCTAHEDRAL")  ? 1
          : !strcmp(filter, "QUATERNION")  ? 2
          : !strcmp(filter, "EXPONENTIAL") ? 3
                                           : -1;
  if (bi < 0 || off < 0 || len < 0 || stride < 0 || count < 0)
    why = "expected buffer, byteOffset, byteLength, byteStride and count (non-negative integers)";
  else if (m < 0)
    why = "mode must be ATTRIBUTES, TRIANGLES or INDICES";
  else if (f < 0)
    why = "filter must be NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL";
  else if (bi >= d->n_bufs || !d->buf_len[bi] || (uint64_t)off + (uint64_t)len > d->buf_len[bi])
    why = "the compressed bytes (buffer, byteOffset, byteLength) are not inside a buffer with data";
  else if (m == 0 && (stride == 0 || stride > 256 || stride % 4))
    why = "ATTRIBUTES byteStride must be a multiple of 4 from 4 to 256";
  else if (m != 0 && stride != 2 && stride != 4)
    why = "TRIANGLES / INDICES byteStride must be 2 or 4";
  else if (m == 1 && count % 3)
    why = "TRIANGLES count must be a multiple of 3";
  else if ((f == 1 && stride != 4 && stride != 8) || (f == 2 && stride != 8) || (f && m != 0))
    why = "the filter does not fit the byteStride / mode (OCTAHEDRAL: 4 or 8, QUATERNION: 8, "
          "ATTRIBUTES only)";
  /* count * byteStride: the codecs spend at least 2 bits per 16 attribute bytes and a byte per
   * triangle / index, so more than that many bytes cannot come from byteLength (no huge
   * allocation for a tiny view). */
  else if ((uint64_t)count * (uint64_t)stride > (uint64_t)1 << 31 ||
           (m == 0 && (uint64_t)count * (uint64_t)stride > 64 * (uint64_t)len + 65536) ||
           (m == 1 && (uint64_t)count / 3 > (uint64_t)len) ||
           (m == 2 && (uint64_t)count > (uint64_t)len))
    why = "count * byteStride is more than the compressed bytes can hold";
  if (why)
    return km__fail(err, KM_ERR_PARSE, "%s: bufferView %d: EXT_meshopt_compression: %s", d->name,
                    bvi, why);
  const unsigned char *src = (d->bufs[bi] ? d->bufs[bi] : d->bin) + off;
  size_t raw = (size_t)count * (size_t)stride;
  unsigned char *dst = km__malloc(raw ? raw : 1, 1);
  if (!dst) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  int rc = m == 0 ? meshopt_decodeVertexBuffer(dst, (size_t)count, (size_t)stride, src, (size_t)len)
           : m == 1
               ? meshopt_decodeIndexBuffer(dst, (size_t)count, (size_t)stride, src, (size_t)len)
               : meshopt_decodeIndexSequence(dst, (size_t)count, (size_t)stride, src, (size_t)len);
  if (rc) {
    free(dst);
    return km__fail(err, KM_ERR_PARSE,
                    "%s: bufferView %d: EXT_meshopt_compression: the %s data does not decode "
                    "(meshoptimizer error %d)",
                    d->name, bvi, mode, rc);
  }
  if (f == 1) meshopt_decodeFilterOct(dst, (size_t)count, (size_t)stride);
  if (f == 2) meshopt_decodeFilterQuat(dst, (size_t)count, (size_t)stride);
  if (f == 3) meshopt_decodeFilterExp(dst, (size_t)count, (size_t)stride);
  d->views[bvi] = dst, d->view_len[bvi] = raw;
  *out = dst, *n = raw;
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

/* Accessor a's element layout (type, componentType, count, normalized; not its bytes). */
typedef struct acc_head {
  int ncomp, ct, count, bvi, aoff;
  bool normalized;
} acc_head;

static km_status accessor_head(gltf_doc *d, int a, const char *what, acc_head *h, km_error *err) {
  cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "accessors"), a);
  if (a < 0 || !acc)
    return km__fail(err, KM_ERR_PARSE, "%s: %s: accessor %d does not exist", d->name, what, a);
  if (cJSON_GetObjectItemCaseSensitive(acc, "sparse"))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %s: sparse accessors are not supported", d->name,
                    what);
  const char *type = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(acc, "type"));
  h->ct = jint(acc, "componentType", -1), h->count = jint(acc, "count", -1);
  h->bvi = jint(acc, "bufferView", -1), h->aoff = jint(acc, "byteOffset", 0);
  h->ncomp = !type                     ? 0
             : !strcmp(type, "SCALAR") ? 1
             : !strcmp(type, "VEC2")   ? 2
             : !strcmp(type, "VEC3")   ? 3
             : !strcmp(type, "VEC4")   ? 4
             : !strcmp(type, "MAT4")   ? 16
                                       : 0;
  h->normalized = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(acc, "normalized"));
  if (!h->ncomp || !comp_size(h->ct) || h->count < 0 || h->aoff < 0)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: accessor %d: expected type, componentType, count and bufferView",
                    d->name, what, a);
  return KM_OK;
}

/* bufferView bvi's bytes (*p, *len) and byteStride (0: tightly packed), checked to lie inside
 * their buffer (an EXT_meshopt_compression view: its decoded bytes). */
static km_status view_bytes(gltf_doc *d, int bvi, const char *what, const unsigned char **p,
                            size_t *len, int *stride, km_error *err) {
  cJSON *bv = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "bufferViews"), bvi);
  int bi = jint(bv, "buffer", -1), boff = jint(bv, "byteOffset", 0),
      blen = jint(bv, "byteLength", -1);
  *stride = jint(bv, "byteStride", 0);
  if (bvi < 0 || !bv || bi < 0 || bi >= d->n_bufs || boff < 0 || blen < 0 || *stride < 0)
    return km__fail(err, KM_ERR_PARSE, "%s: %s: bufferView %d is missing or invalid", d->name, what,
                    bvi);
  const unsigned char *buf = d->bufs[bi] ? d->bufs[bi] : d->bin;
  size_t buf_len = d->buf_len[bi];
  const cJSON *mo = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(bv, "extensions"), "EXT_meshopt_compression");
  if (mo) { /* the view's bytes are the decoded ones; byteLength must lie within them */
    km_status s = decode_view(d, bvi, mo, &buf, &buf_len, err);
    if (s) return s;
    boff = 0;
  }
  if ((uint64_t)boff + (uint64_t)blen > buf_len)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: bufferView %d (%d bytes at %d) does not fit its buffer (%zu bytes)",
                    d->name, what, bvi, blen, boff, buf_len);
  *p = buf + boff;
  *len = (size_t)blen;
  return KM_OK;
}

static km_status accessor(gltf_doc *d, int a, const char *what, acc_view *v, km_error *err) {
  acc_head h;
  km_status s = accessor_head(d, a, what, &h, err);
  if (s) return s;
  if (h.bvi < 0)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: accessor %d: expected type, componentType, count and bufferView",
                    d->name, what, a);
  const unsigned char *p;
  size_t blen;
  int stride;
  if ((s = view_bytes(d, h.bvi, what, &p, &blen, &stride, err))) return s;
  size_t cs = comp_size(h.ct), elem = cs * (size_t)h.ncomp, st = stride ? (size_t)stride : elem;
  if (st < elem || (h.count && (uint64_t)h.aoff + (uint64_t)st * (uint64_t)(h.count - 1) + elem >
                                   (uint64_t)blen))
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: accessor %d (%d elements) does not fit its bufferView / buffer",
                    d->name, what, a, h.count);
  v->p = p + h.aoff;
  v->count = (size_t)h.count;
  v->stride = st;
  v->csize = cs;
  v->ncomp = h.ncomp;
  v->ct = h.ct;
  v->normalized = h.normalized;
  return KM_OK;
}

/* KHR_draco_mesh_compression: bufferView bvi's bytes decoded as a Draco triangle mesh
 * (draco.cc), once per view. */
static km_status draco_view(gltf_doc *d, int bvi, const char *what, km__draco **out,
                            km_error *err) {
  if (!d->draco) {
    d->n_draco = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(d->json, "bufferViews"));
    d->draco = km__calloc(d->n_draco ? (size_t)d->n_draco : 1, sizeof *d->draco);
    if (!d->draco) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  }
  if (bvi < 0 || bvi >= d->n_draco)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: KHR_draco_mesh_compression: bufferView %d does not exist", d->name,
                    what, bvi);
  if (!d->draco[bvi]) {
    const unsigned char *p;
    size_t len;
    int stride;
    km_status s = view_bytes(d, bvi, what, &p, &len, &stride, err);
    if (s) return s;
    char why[160];
    if (!(d->draco[bvi] = km__draco_decode(p, len, why, sizeof why)))
      return km__fail(err, strcmp(why, "out of memory") ? KM_ERR_PARSE : KM_ERR_NOMEM,
                      "%s: %s: KHR_draco_mesh_compression: bufferView %d: %s", d->name, what, bvi,
                      why);
  }
  *out = d->draco[bvi];
  return KM_OK;
}

/* The accessor of primitive pr's attribute `sem` (NULL: its indices) as a view comp() reads:
 * from the primitive's KHR_draco_mesh_compression mesh when the extension lists the attribute
 * (indices: whenever the primitive has the extension), else as stored. Decoded values are laid
 * out as the accessor declares them (componentType, normalized: applied by comp(), as in a file
 * without Draco), indices as uint32, once per accessor; the accessor's count must be the
 * decoded one (indices: 3 per triangle) and its type the attribute's component count. */
static km_status prim_accessor(gltf_doc *d, const cJSON *pr, const char *sem, const char *what,
                               acc_view *v, km_error *err) {
  const cJSON *at = cJSON_GetObjectItemCaseSensitive(pr, "attributes");
  int a = sem ? jint(at, sem, -1) : jint(pr, "indices", -1);
  const cJSON *dr = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(pr, "extensions"), "KHR_draco_mesh_compression");
  const cJSON *uid = sem ? cJSON_GetObjectItemCaseSensitive(
                               cJSON_GetObjectItemCaseSensitive(dr, "attributes"), sem)
                         : NULL;
  if (!dr || (sem && !uid)) return accessor(d, a, what, v, err);
  const char *name = sem ? sem : "indices";
  if (!sem && a < 0)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: KHR_draco_mesh_compression: expected the primitive's indices accessor",
                    d->name, what);
  acc_head h;
  km__draco *m = NULL;
  km_status s = accessor_head(d, a, what, &h, err);
  if (s || (s = draco_view(d, jint(dr, "bufferView", -1), what, &m, err))) return s;
  if (!d->dacc) {
    d->n_dacc = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(d->json, "accessors"));
    d->dacc = km__calloc(d->n_dacc ? (size_t)d->n_dacc : 1, sizeof *d->dacc);
    if (!d->dacc) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  }
  size_t np = km__draco_points(m), nf = km__draco_faces(m);
  int ct = sem ? h.ct : 5125, nc = sem ? h.ncomp : 1;
  size_t n = sem ? np : 3 * nf, cs = comp_size(ct);
  if ((size_t)h.count != n)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: %s: KHR_draco_mesh_compression: %s: accessor %d counts %d, the Draco mesh "
                    "has %zu",
                    d->name, what, name, a, h.count, n);
  if (!d->dacc[a]) {
    unsigned char *b = km__malloc(n ? n : 1, (size_t)nc * cs);
    void *tmp = km__malloc(n ? n : 1, (size_t)nc * 4);
    const char *why = NULL;
    if (!b || !tmp) {
      free(b);
      free(tmp);
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
    }
    if (!sem) {
      km__draco_face_indices(m, tmp);
      for (size_t i = 0; i < n; ++i)
        km__put_u32le(b + 4 * i, ((uint32_t *)tmp)[i]);
    } else {
      int64_t id;
      bool isf = false;
      int dnc = cJSON_IsNumber(uid) && km__whole_number(uid->valuedouble, 0, 4294967295.0, &id)
                    ? km__draco_components(m, (uint32_t)id, &isf)
                    : 0;
      if (!dnc)
        why = "the Draco mesh has no attribute with that id";
      else if (dnc != nc)
        why = "the Draco attribute's component count differs from the accessor's type";
      else if (isf && ct != 5126)
        why = "the Draco attribute is floating point, the accessor's componentType an integer";
      else if (!km__draco_values(m, (uint32_t)id, ct == 5126, tmp))
        why = "a decoded value does not fit a 32-bit integer";
      /* integers must fit the accessor's componentType */
      const int64_t lo = ct == 5120 ? -128 : ct == 5122 ? -32768 : 0;
      const int64_t hi = ct == 5120   ? 127
                         : ct == 5121 ? 255
                         : ct == 5122 ? 32767
                         : ct == 5123 ? 65535
                                      : INT32_MAX;
      for (size_t i = 0; !why && i < n * (size_t)nc; ++i) {
        unsigned char *q = b + i * cs;
        if (ct == 5126) {
          km__put_f32le(q, ((float *)tmp)[i]);
          continue;
        }
        int64_t x = ((int32_t *)tmp)[i];
        if (x < lo || x > hi) {
          why = "a decoded value is outside the accessor's componentType";
          break;
        }
        if (cs == 1) q[0] = (unsigned char)(x & 0xff);
        if (cs == 2) q[0] = (unsigned char)(x & 0xff), q[1] = (unsigned char)(x >> 8 & 0xff);
        if (cs == 4) km__put_u32le(q, (uint32_t)x);
      }
    }
    free(tmp);
    if (why) {
      free(b);
      return km__fail(err, KM_ERR_PARSE, "%s: %s: KHR_draco_mesh_compression: %s (accessor %d): %s",
                      d->name, what, name, a, why);
    }
    d->dacc[a] = b;
  }
  v->p = d->dacc[a];
  v->count = n;
  v->csize = cs;
  v->ncomp = nc;
  v->stride = cs * (size_t)nc;
  v->ct = ct;
  v->normalized = sem ? h.normalized : false;
  return KM_OK;
}

static double comp(const acc_view *v, size_t i, int c) {
  const unsigned char *p = v->p + i * v->stride + (size_t)c * v->csize;
  switch (v->ct) {
  case 5126: {
    uint32_t u = km__get_u32le(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
  }
  case 5125: return (double)km__get_u32le(p);
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

/* A mesh placed by a node: its index and world transform (column-major 4x4, as glTF). */
typedef struct instance {
  int mesh, node, skin; /* node -1 and skin -1 for a file without nodes */
  double M[16];
} instance;

#define MAX_INSTANCES 65536 /* node visits: keeps a DAG of shared children from exploding */

typedef struct instances {
  instance *v;
  size_t n, cap;
  size_t visits;
} instances;

static void mat_mul(const double A[16], const double B[16], double C[16]) {
  double T[16];
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) {
      double x = 0;
      for (int k = 0; k < 4; ++k)
        x += A[k * 4 + r] * B[c * 4 + k];
      T[c * 4 + r] = x;
    }
  memcpy(C, T, sizeof T);
}

static bool num_array(const cJSON *a, int n, double *out) {
  if (cJSON_GetArraySize(a) != n) return false;
  for (int i = 0; i < n; ++i) {
    const cJSON *x = cJSON_GetArrayItem(a, i);
    if (!cJSON_IsNumber(x) || !isfinite(x->valuedouble)) return false;
    out[i] = x->valuedouble;
  }
  return true;
}

static km_status node_local(gltf_doc *d, const cJSON *node, int ni, double M[16], km_error *err) {
  static const double I[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  memcpy(M, I, sizeof I);
  const cJSON *m = cJSON_GetObjectItemCaseSensitive(node, "matrix");
  if (m) {
    if (!num_array(m, 16, M))
      return km__fail(err, KM_ERR_PARSE, "%s: nodes[%d]: matrix must be 16 finite numbers", d->name,
                      ni);
    return KM_OK;
  }
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, sc[3] = {1, 1, 1};
  const cJSON *jt = cJSON_GetObjectItemCaseSensitive(node, "translation");
  const cJSON *jr = cJSON_GetObjectItemCaseSensitive(node, "rotation");
  const cJSON *js = cJSON_GetObjectItemCaseSensitive(node, "scale");
  if ((jt && !num_array(jt, 3, t)) || (jr && !num_array(jr, 4, q)) || (js && !num_array(js, 3, sc)))
    return km__fail(err, KM_ERR_PARSE,
                    "%s: nodes[%d]: translation (3), rotation (4) and scale (3) must be finite "
                    "numbers",
                    d->name, ni);
  double qn = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(qn > 0)) qn = 1, q[3] = 1;
  double x = q[0] / qn, y = q[1] / qn, z = q[2] / qn, w = q[3] / qn;
  double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
                 2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                 2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      M[c * 4 + r] = R[r * 3 + c] * sc[c];
  M[12] = t[0], M[13] = t[1], M[14] = t[2];
  return KM_OK;
}

/* The primitive's material's base colour texture's KHR_texture_transform, when that texture
 * reads TEXCOORD_0: uv' = A[0..1] + [A2 A3; A4 A5] uv (offset, rotation, scale as the extension
 * composes them). gltfpack puts the dequantisation of its 12-bit texture coordinates there.
 * Returns false (identity) without one. */
static bool uv_transform(gltf_doc *d, const cJSON *pr, double A[6]) {
  int mi = jint(pr, "material", -1);
  if (mi < 0) return false;
  const cJSON *mat = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "materials"), mi);
  const cJSON *tex = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(mat, "pbrMetallicRoughness"), "baseColorTexture");
  const cJSON *tt = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(tex, "extensions"), "KHR_texture_transform");
  if (!tt || jint(tex, "texCoord", 0) != 0 || jint(tt, "texCoord", 0) != 0) return false;
  double o[2] = {0, 0}, sc[2] = {1, 1}, r = 0;
  const cJSON *jo = cJSON_GetObjectItemCaseSensitive(tt, "offset");
  const cJSON *js = cJSON_GetObjectItemCaseSensitive(tt, "scale");
  const cJSON *jr = cJSON_GetObjectItemCaseSensitive(tt, "rotation");
  if ((jo && !num_array(jo, 2, o)) || (js && !num_array(js, 2, sc)) ||
      (jr && (!cJSON_IsNumber(jr) || !isfinite(jr->valuedouble))))
    return false;
  if (jr) r = jr->valuedouble;
  A[0] = o[0], A[1] = o[1];
  A[2] = cos(r) * sc[0], A[3] = sin(r) * sc[1];
  A[4] = -sin(r) * sc[0], A[5] = cos(r) * sc[1];
  return true;
}

static km_status visit(gltf_doc *d, int ni, const double P[16], int depth, instances *out,
                       km_error *err) {
  cJSON *nodes = cJSON_GetObjectItemCaseSensitive(d->json, "nodes");
  cJSON *node = cJSON_GetArrayItem(nodes, ni);
  if (ni < 0)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: a node index (in a scene's \"nodes\" or a node's \"children\") is not "
                    "a whole number from 0 to %d",
                    d->name, INT32_MAX);
  if (!node) return km__fail(err, KM_ERR_PARSE, "%s: node %d does not exist", d->name, ni);
  if (depth > 64 || ++out->visits > MAX_INSTANCES)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: the node hierarchy is deeper than 64 or has more than %d node visits "
                    "(a cycle?)",
                    d->name, MAX_INSTANCES);
  double L[16], M[16];
  km_status s = node_local(d, node, ni, L, err);
  if (s) return s;
  mat_mul(P, L, M);
  int mesh = jint(node, "mesh", -1);
  if (mesh >= 0) {
    if (out->n == out->cap) {
      size_t nc = out->cap ? 2 * out->cap : 16;
      instance *nv = realloc(out->v, nc * sizeof *nv);
      if (!nv) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
      out->v = nv;
      out->cap = nc;
    }
    out->v[out->n].mesh = mesh;
    out->v[out->n].node = ni;
    out->v[out->n].skin = jint(node, "skin", -1);
    memcpy(out->v[out->n++].M, M, sizeof M);
  }
  cJSON *ch = cJSON_GetObjectItemCaseSensitive(node, "children");
  for (int i = 0; i < cJSON_GetArraySize(ch) && !s; ++i) {
    s = visit(d, jindex(cJSON_GetArrayItem(ch, i)), M, depth + 1, out, err);
  }
  return s;
}

/* Whether the document is a VRM 0.x avatar (extensions.VRM without VRM 1.0's VRMC_vrm). */
static bool vrm0(const gltf_doc *d) {
  const cJSON *ext = cJSON_GetObjectItemCaseSensitive(d->json, "extensions");
  return cJSON_GetObjectItemCaseSensitive(ext, "VRM") &&
         !cJSON_GetObjectItemCaseSensitive(ext, "VRMC_vrm");
}

/* The transform above the scene's root nodes (column-major): the identity, or for a VRM 0.x
 * avatar, which faces -z (UniVRM flipped Unity's z on export) where glTF's front, VRM 1.0's and
 * kinemesh's is +z, half a turn about y. Every world matrix starts from it (the mesh instances,
 * the joints), so positions, normals, skinning and joint positions all come out turned alike,
 * the vertex order kept. */
static void root_matrix(const gltf_doc *d, double R[16]) {
  static const double I[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  memcpy(R, I, sizeof I);
  if (vrm0(d)) R[0] = R[10] = -1;
}

/* The meshes to read with their transforms, in the order described at the top. */
static km_status collect_instances(gltf_doc *d, instances *out, km_error *err) {
  double I[16];
  root_matrix(d, I);
  cJSON *nodes = cJSON_GetObjectItemCaseSensitive(d->json, "nodes");
  cJSON *meshes = cJSON_GetObjectItemCaseSensitive(d->json, "meshes");
  int nn = cJSON_GetArraySize(nodes);
  km_status s = KM_OK;
  if (nn == 0) { /* no nodes: every mesh as stored */
    for (int m = 0; m < cJSON_GetArraySize(meshes) && !s; ++m) {
      instance *nv = realloc(out->v, (out->n + 1) * sizeof *nv);
      if (!nv) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
      out->v = nv;
      out->v[out->n].mesh = m;
      out->v[out->n].node = out->v[out->n].skin = -1;
      memcpy(out->v[out->n++].M, I, sizeof I);
    }
    return KM_OK;
  }
  cJSON *scenes = cJSON_GetObjectItemCaseSensitive(d->json, "scenes");
  int si = jint(d->json, "scene", 0);
  cJSON *scene = cJSON_GetArrayItem(scenes, si < 0 ? 0 : si);
  cJSON *roots = cJSON_GetObjectItemCaseSensitive(scene, "nodes");
  if (scene) {
    for (int i = 0; i < cJSON_GetArraySize(roots) && !s; ++i) {
      s = visit(d, jindex(cJSON_GetArrayItem(roots, i)), I, 0, out, err);
    }
    return s;
  }
  /* no scene: every node that is nobody's child */
  unsigned char *child = km__calloc((size_t)nn, 1);
  if (!child) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  for (int i = 0; i < nn; ++i) {
    cJSON *ch = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(nodes, i), "children");
    for (int k = 0; k < cJSON_GetArraySize(ch); ++k) {
      int c = jindex(cJSON_GetArrayItem(ch, k));
      if (c >= 0 && c < nn) child[c] = 1;
    }
  }
  for (int i = 0; i < nn && !s; ++i)
    if (!child[i]) s = visit(d, i, I, 0, out, err);
  free(child);
  return s;
}

static km_status read_instances(gltf_doc *d, const instances *inst, km_mesh *out, km_error *err);

/* Parent and world matrix of every node (the scene's pose; joints need not be in the scene). */
static km_status node_worlds(gltf_doc *d, km_error *err) {
  double I[16];
  root_matrix(d, I);
  cJSON *nodes = cJSON_GetObjectItemCaseSensitive(d->json, "nodes");
  int nn = cJSON_GetArraySize(nodes);
  d->n_nodes = nn;
  if (!nn) return KM_OK;
  d->node_parent = km__malloc((size_t)nn, sizeof *d->node_parent);
  d->node_world = km__malloc((size_t)nn * 16, sizeof *d->node_world);
  unsigned char *done = km__calloc((size_t)nn, 1);
  km_status s = KM_OK;
  if (!d->node_parent || !d->node_world || !done) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
    goto out;
  }
  for (int i = 0; i < nn; ++i)
    d->node_parent[i] = -1;
  for (int i = 0; i < nn; ++i) {
    cJSON *ch = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(nodes, i), "children");
    for (int k = 0; k < cJSON_GetArraySize(ch); ++k) {
      int c = jindex(cJSON_GetArrayItem(ch, k));
      if (c >= 0 && c < nn && d->node_parent[c] < 0 && c != i) d->node_parent[c] = i;
    }
  }
  for (int i = 0; i < nn && !s; ++i) {
    /* the chain up to a done node or a root (at most 64 deep: cycles refused) */
    int chain[65], n = 0, a = i;
    while (a >= 0 && !done[a]) {
      if (n == 65) {
        s = km__fail(err, KM_ERR_UNSUPPORTED,
                     "%s: nodes[%d]: the node hierarchy is deeper than 64 (a cycle?)", d->name, i);
        break;
      }
      chain[n++] = a;
      a = d->node_parent[a];
    }
    while (!s && n > 0) {
      int c = chain[--n];
      double L[16];
      if ((s = node_local(d, cJSON_GetArrayItem(nodes, c), c, L, err))) break;
      int p = d->node_parent[c];
      mat_mul(p >= 0 ? d->node_world + 16 * p : I, L, d->node_world + 16 * c);
      done[c] = 1;
    }
  }
out:
  free(done);
  return s;
}

/* The skin matrices (joint world x inverse bind) of skin si, with the joints' indices in the
 * gathered joint list; *nj their count. */
static km_status skin_matrices(gltf_doc *d, int si, double **S, int32_t **ids, size_t *nj,
                               km_error *err) {
  *S = NULL;
  *ids = NULL;
  cJSON *sk = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "skins"), si);
  cJSON *js = cJSON_GetObjectItemCaseSensitive(sk, "joints");
  int n = cJSON_GetArraySize(js);
  if (si < 0 || !sk || n < 1)
    return km__fail(err, KM_ERR_PARSE, "%s: skins[%d] is missing or has no joints", d->name, si);
  *S = km__malloc((size_t)n * 16, sizeof **S);
  *ids = km__malloc((size_t)n, sizeof **ids);
  if (!*S || !*ids) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  acc_view ibm;
  bool has_ibm = cJSON_GetObjectItemCaseSensitive(sk, "inverseBindMatrices") != NULL;
  char what[48];
  snprintf(what, sizeof what, "skins[%d]", si);
  km_status s = KM_OK;
  if (has_ibm && (s = accessor(d, jint(sk, "inverseBindMatrices", -1), what, &ibm, err))) return s;
  if (has_ibm && (ibm.ncomp != 16 || ibm.ct != 5126 || ibm.count < (size_t)n))
    return km__fail(err, KM_ERR_PARSE, "%s: %s: inverseBindMatrices must be %d float MAT4", d->name,
                    what, n);
  for (int k = 0; k < n; ++k) {
    int node = jindex(cJSON_GetArrayItem(js, k));
    if (node < 0 || node >= d->n_nodes)
      return km__fail(err, KM_ERR_PARSE, "%s: %s: joints[%d] is not a node", d->name, what, k);
    double B[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (int c = 0; has_ibm && c < 16; ++c) {
      B[c] = comp(&ibm, (size_t)k, c);
      if (!isfinite(B[c]))
        return km__fail(err, KM_ERR_PARSE, "%s: %s: inverse bind matrix %d is not finite", d->name,
                        what, k);
    }
    mat_mul(d->node_world + 16 * node, B, *S + 16 * k);
    (*ids)[k] = d->joint_of_node ? d->joint_of_node[node] : -1;
  }
  *nj = (size_t)n;
  return KM_OK;
}

/* A VRM avatar's (.vrm: a .glb with VRoid / UniVRM's extension) humanoid bone on node `node`
 * ("hips", "leftUpperArm", ... as VRM and Unity's HumanBodyBones name them), NULL when the file
 * maps none there: VRM 0.x lists {"bone", "node"} pairs in extensions.VRM.humanoid.humanBones,
 * VRM 1.0 keys {"node"} by bone in extensions.VRMC_vrm.humanoid.humanBones. The avatar's own
 * node names are free (VRoid's J_Bip_L_UpperArm, a modeller's Bone.017), so this mapping is what
 * makes any VRM a rigged template. */
static const char *vrm_bone(const gltf_doc *d, int node) {
  const cJSON *ext = cJSON_GetObjectItemCaseSensitive(d->json, "extensions"), *b;
  const cJSON *h1 = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(ext, "VRMC_vrm"),
                                       "humanoid"),
      "humanBones");
  cJSON_ArrayForEach(b, h1) if (b->string && jint(b, "node", -1) == node) return b->string;
  const cJSON *h0 = cJSON_GetObjectItemCaseSensitive(
      cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(ext, "VRM"), "humanoid"),
      "humanBones");
  cJSON_ArrayForEach(b, h0) {
    const char *bone = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(b, "bone"));
    if (bone && bone[0] && jint(b, "node", -1) == node) return bone;
  }
  return NULL;
}

/* The joint list of the skins the instances use (each joint node once, first use first). */
static km_status gather_joints(gltf_doc *d, const instances *inst, km_error *err) {
  km_mesh_skin *sk = d->skin;
  cJSON *skins = cJSON_GetObjectItemCaseSensitive(d->json, "skins");
  cJSON *nodes = cJSON_GetObjectItemCaseSensitive(d->json, "nodes");
  if (!d->n_nodes) return KM_OK;
  d->joint_of_node = km__malloc((size_t)d->n_nodes, sizeof *d->joint_of_node);
  int *order = km__malloc((size_t)d->n_nodes, sizeof *order);
  if (!d->joint_of_node || !order) {
    free(order);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  }
  for (int i = 0; i < d->n_nodes; ++i)
    d->joint_of_node[i] = -1;
  size_t n = 0;
  for (size_t ii = 0; ii < inst->n; ++ii) {
    int si = inst->v[ii].skin;
    if (si < 0) continue;
    cJSON *js = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(skins, si), "joints");
    for (int k = 0; k < cJSON_GetArraySize(js); ++k) {
      int node = jindex(cJSON_GetArrayItem(js, k));
      if (node < 0 || node >= d->n_nodes) continue;
      if (d->joint_of_node[node] >= 0) continue;
      d->joint_of_node[node] = (int)n;
      order[n++] = node;
    }
  }
  km_status s = KM_OK;
  sk->n_joints = n;
  if (n) {
    sk->names = km__calloc(n, sizeof *sk->names);
    sk->parents = km__malloc(n, sizeof *sk->parents);
    sk->rest = km__malloc(3 * n, sizeof *sk->rest);
    if (!sk->names || !sk->parents || !sk->rest) s = km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  for (size_t j = 0; j < n && !s; ++j) {
    int node = order[j];
    const char *nm = cJSON_GetStringValue(
        cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(nodes, node), "name"));
    char buf[32], named[300];
    snprintf(buf, sizeof buf, "node%d", node);
    const char *bone = vrm_bone(d, node);
    if (bone) /* "J_Bip_C_Hips|hips": the joint mapper reads the part after '|' */
      snprintf(named, sizeof named, "%.200s|%.64s", nm && nm[0] ? nm : buf, bone);
    sk->names[j] = strdup(bone ? named : nm && nm[0] ? nm : buf);
    if (!sk->names[j]) s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
    int a = d->node_parent[node];
    for (int depth = 0; a >= 0 && d->joint_of_node[a] < 0 && depth < 65; ++depth)
      a = d->node_parent[a];
    sk->parents[j] = a >= 0 ? d->joint_of_node[a] : -1;
    memcpy(sk->rest + 3 * j, d->node_world + 16 * node + 12, 3 * sizeof(double));
  }
  free(order);
  return s;
}

/* The image of a material's textureInfo `info` (NULL: none), the encoded PNG or JPEG bytes as
 * stored (a bufferView, a data: URI, or a file beside a .gltf read from disk), into *out. An
 * image that cannot be read, or a texture on another set than TEXCOORD_0 (the only one carried),
 * is left out with a warning (the geometry is what was asked for), never an error. */
static void texture_image(gltf_doc *d, const cJSON *info, int mi, const char *what,
                          km_mesh_image *out) {
  memset(out, 0, sizeof *out);
  int ti = jint(info, "index", -1);
  const cJSON *tex =
      ti < 0 ? NULL : cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "textures"), ti);
  int ii = jint(tex, "source", -1);
  const cJSON *img =
      ii < 0 ? NULL : cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "images"), ii);
  if (!img) return;
  const char *uri = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(img, "uri"));
  int bvi = jint(img, "bufferView", -1);
  unsigned char *bytes = NULL;
  size_t n = 0;
  const char *why = NULL;
  if (jint(info, "texCoord", 0) != 0) {
    why = "it is on another texture coordinate set than TEXCOORD_0, the one carried";
  } else if (bvi >= 0) {
    const cJSON *bv =
        cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "bufferViews"), bvi);
    int bi = jint(bv, "buffer", -1), boff = jint(bv, "byteOffset", 0),
        blen = jint(bv, "byteLength", -1);
    if (!bv || bi < 0 || bi >= d->n_bufs || boff < 0 || blen <= 0 ||
        (size_t)boff + (size_t)blen > d->buf_len[bi])
      why = "its bufferView is missing or out of its buffer";
    else if ((bytes = km__malloc((size_t)blen, 1)))
      memcpy(bytes, (d->bufs[bi] ? d->bufs[bi] : d->bin) + boff, n = (size_t)blen);
  } else if (uri) {
    read_uri(d, uri, &bytes, &n, &why);
  }
  /* the outputs embed what a glTF viewer decodes: PNG or JPEG */
  const char *mime = bytes ? km__image_mime(bytes, n) : NULL;
  if (bytes && !mime) why = "it is neither PNG nor JPEG";
  if (why || !bytes) {
    km__log(KM_LOG_WARN, "%s: images[%d] (materials[%d]'s %s) is left out: %s", d->name, ii, mi,
            what, why ? why : "out of memory");
    free(bytes);
    return;
  }
  out->bytes = bytes;
  out->size = n;
  snprintf(out->mime, sizeof out->mime, "%s", mime);
  /* its sampler, each value one of glTF's enums (anything else: not given) */
  int si = jint(tex, "sampler", -1);
  const cJSON *smp =
      si < 0 ? NULL : cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "samplers"), si);
  int mag = jint(smp, "magFilter", 0), min = jint(smp, "minFilter", 0);
  int ws = jint(smp, "wrapS", 0), wt = jint(smp, "wrapT", 0);
  out->sampler.mag_filter = mag == 9728 || mag == 9729 ? mag : 0;
  out->sampler.min_filter = min == 9728 || min == 9729 || (min >= 9984 && min <= 9987) ? min : 0;
  out->sampler.wrap_s = ws == 33071 || ws == 33648 || ws == 10497 ? ws : 0;
  out->sampler.wrap_t = wt == 33071 || wt == 33648 || wt == 10497 ? wt : 0;
}

/* A finite number member of o, else def. */
static double jnum(const cJSON *o, const char *k, double def) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
  return cJSON_IsNumber(v) && isfinite(v->valuedouble) ? v->valuedouble : def;
}

/* materials[mi]: its base colour, metallic, roughness and emissive factors and its textures
 * (texture_image). mi -1: glTF's default material. */
static void material_def(gltf_doc *d, int mi, km_mesh_material *m) {
  const cJSON *mat =
      mi < 0 ? NULL
             : cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d->json, "materials"), mi);
  const cJSON *pbr = cJSON_GetObjectItemCaseSensitive(mat, "pbrMetallicRoughness");
  if (!num_array(cJSON_GetObjectItemCaseSensitive(pbr, "baseColorFactor"), 4, m->base_color))
    m->base_color[0] = m->base_color[1] = m->base_color[2] = m->base_color[3] = 1;
  m->metallic = jnum(pbr, "metallicFactor", 1);
  m->roughness = jnum(pbr, "roughnessFactor", 1);
  if (!num_array(cJSON_GetObjectItemCaseSensitive(mat, "emissiveFactor"), 3, m->emissive))
    m->emissive[0] = m->emissive[1] = m->emissive[2] = 0;
  km_mesh_image im;
  texture_image(d, cJSON_GetObjectItemCaseSensitive(pbr, "baseColorTexture"), mi,
                "base colour texture", &im);
  m->image = im.bytes, m->image_size = im.size, m->image_sampler = im.sampler;
  memcpy(m->image_mime, im.mime, sizeof m->image_mime);
  const cJSON *nt = cJSON_GetObjectItemCaseSensitive(mat, "normalTexture"),
              *ot = cJSON_GetObjectItemCaseSensitive(mat, "occlusionTexture");
  texture_image(d, cJSON_GetObjectItemCaseSensitive(pbr, "metallicRoughnessTexture"), mi,
                "metallic-roughness texture", &m->maps[KM_MAP_METALLIC_ROUGHNESS]);
  texture_image(d, nt, mi, "normal texture", &m->maps[KM_MAP_NORMAL]);
  texture_image(d, ot, mi, "occlusion texture", &m->maps[KM_MAP_OCCLUSION]);
  texture_image(d, cJSON_GetObjectItemCaseSensitive(mat, "emissiveTexture"), mi, "emissive texture",
                &m->maps[KM_MAP_EMISSIVE]);
  m->normal_scale = jnum(nt, "scale", 1);
  m->occlusion_strength = jnum(ot, "strength", 1);
  const char *am = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(mat, "alphaMode"));
  m->alpha_mode = am && !strcmp(am, "MASK")    ? KM_ALPHA_MASK
                  : am && !strcmp(am, "BLEND") ? KM_ALPHA_BLEND
                                               : KM_ALPHA_OPAQUE;
  m->alpha_cutoff = jnum(mat, "alphaCutoff", 0.5);
  m->double_sided = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(mat, "doubleSided"));
}

/* The primitives' materials, one per run of faces (km_mesh.materials), so a textured model does
 * not come out grey; none when no primitive has a material. */
static km_status read_materials(gltf_doc *d, km_mesh *out, km_error *err) {
  bool any = false;
  for (size_t r = 0; r < d->n_runs; ++r)
    any |= d->run_mat[r] >= 0;
  if (!any) return KM_OK;
  if (!(out->materials = km__calloc(d->n_runs, sizeof *out->materials)))
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
  out->n_materials = d->n_runs;
  for (size_t r = 0; r < d->n_runs; ++r) {
    km_mesh_material *m = out->materials + r;
    m->first_face = d->run_first[r];
    m->n_faces = d->run_n[r];
    /* a material met before shares its image (one copy read) */
    size_t q = 0;
    while (q < r && d->run_mat[q] != d->run_mat[r])
      ++q;
    if (q < r) {
      if (!km__material_copy(m, out->materials + q))
        return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
      m->first_face = d->run_first[r], m->n_faces = d->run_n[r];
    } else {
      material_def(d, d->run_mat[r], m);
    }
  }
  return KM_OK;
}

static km_status parse_doc(gltf_doc *d, km_mesh *out, km_error *err) {
  cJSON *meshes = cJSON_GetObjectItemCaseSensitive(d->json, "meshes");
  if (!cJSON_GetArraySize(meshes))
    return km__fail(err, KM_ERR_PARSE, "%s: expected a non-empty 'meshes' array", d->name);
  km_status s = load_buffers(d, err);
  if (s) return s;
  instances inst = {0};
  if ((s = collect_instances(d, &inst, err))) {
    free(inst.v);
    return s;
  }
  bool skinned = false;
  for (size_t i = 0; i < inst.n; ++i)
    skinned |= inst.v[i].skin >= 0;
  if ((skinned && (s = node_worlds(d, err))) ||
      (skinned && d->skin && (s = gather_joints(d, &inst, err)))) {
    free(inst.v);
    return s;
  }
  s = read_instances(d, &inst, out, err);
  if (s == KM_OK) s = read_materials(d, out, err);
  free(inst.v);
  return s;
}

static km_status read_instances(gltf_doc *d, const instances *inst, km_mesh *out, km_error *err) {
  cJSON *meshes = cJSON_GetObjectItemCaseSensitive(d->json, "meshes");
  km_status s = KM_OK;
  /* Pass 1: count; pass 2: fill. */
  size_t nv = 0, nf = 0;
  bool any_n = false, any_t = false, any_c = false;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      if (nv > INT32_MAX)
        return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %zu vertices exceed the int32 range", d->name,
                        nv);
      if ((s = km_mesh_alloc(nv, nf, out, err))) return s;
      if (d->skin) {
        d->skin->n_vertices = nv;
        d->skin->joints = km__malloc(nv ? nv * 4 : 1, sizeof *d->skin->joints);
        d->skin->weights = km__calloc(nv ? nv * 4 : 1, sizeof *d->skin->weights);
        if (!d->skin->joints || !d->skin->weights) goto nomem;
        for (size_t i = 0; i < 4 * nv; ++i)
          d->skin->joints[i] = -1;
      }
      if (any_n && !(out->N = km__calloc(nv ? nv : 1, 3 * sizeof(double)))) goto nomem;
      if (any_t && !(out->UV = km__calloc(nv ? nv : 1, 2 * sizeof(double)))) goto nomem;
      if (any_c && !(out->colors = km__malloc(nv ? nv : 1, 4 * sizeof(double)))) goto nomem;
      for (size_t i = 0; any_c && i < 4 * nv; ++i)
        out->colors[i] = 1; /* a primitive without COLOR_0 among others: white */
    }
    size_t v0 = 0, f0 = 0;
    for (size_t ii = 0; ii < inst->n; ++ii) {
      int mi = inst->v[ii].mesh;
      const double *M = inst->v[ii].M;
      int si = inst->v[ii].skin;
      free(d->S);
      free(d->S_ids);
      d->S = NULL, d->S_ids = NULL, d->S_n = 0;
      if (pass == 1 && si >= 0 && (s = skin_matrices(d, si, &d->S, &d->S_ids, &d->S_n, err)))
        return s;
      int32_t rigid = -1; /* an unskinned mesh: bound to the nearest joint above its node */
      if (pass == 1 && d->skin && d->joint_of_node && inst->v[ii].node >= 0) {
        int a = inst->v[ii].node;
        for (int depth = 0; a >= 0 && d->joint_of_node[a] < 0 && depth < 65; ++depth)
          a = d->node_parent[a];
        if (a >= 0) rigid = d->joint_of_node[a];
      }
      cJSON *mesh = cJSON_GetArrayItem(meshes, mi);
      if (!mesh)
        return km__fail(err, KM_ERR_PARSE, "%s: a node names mesh %d, which does not exist",
                        d->name, mi);
      /* normals by the cofactor matrix of the linear part (inverse transpose up to scale) */
      double C[9], det = M[0] * (M[5] * M[10] - M[9] * M[6]) - M[4] * (M[1] * M[10] - M[9] * M[2]) +
                         M[8] * (M[1] * M[6] - M[5] * M[2]);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
          C[r * 3 + c] = M[c1 * 4 + r1] * M[c2 * 4 + r2] - M[c2 * 4 + r1] * M[c1 * 4 + r2];
        }
      cJSON *prims = cJSON_GetObjectItemCaseSensitive(mesh, "primitives");
      for (int pi = 0; pi < cJSON_GetArraySize(prims); ++pi) {
        cJSON *pr = cJSON_GetArrayItem(prims, pi);
        char what[64];
        snprintf(what, sizeof what, "meshes[%d].primitives[%d]", mi, pi);
        /* Triangles (4), and strips (5) and fans (6) as the triangles they stand for, in the
         * spec's order and winding; their vertices are the file's either way. */
        int mode = jint(pr, "mode", 4);
        if (mode < 4 || mode > 6)
          return km__fail(err, KM_ERR_UNSUPPORTED,
                          "%s: %s: mode %d (points or lines; triangles, strips and fans, modes "
                          "4-6, are read)",
                          d->name, what, mode);
        cJSON *at = cJSON_GetObjectItemCaseSensitive(pr, "attributes");
        const cJSON *drc = cJSON_GetObjectItemCaseSensitive(
            cJSON_GetObjectItemCaseSensitive(pr, "extensions"), "KHR_draco_mesh_compression");
        if (drc && mode != 4)
          return km__fail(err, KM_ERR_UNSUPPORTED,
                          "%s: %s: KHR_draco_mesh_compression with mode %d (Draco primitives are "
                          "read as triangles, mode 4)",
                          d->name, what, mode);
        acc_view pos, nrm, tex, idx, col;
        if ((s = prim_accessor(d, pr, "POSITION", what, &pos, err))) return s;
        /* KHR_mesh_quantization: (normalized) byte / short components too, dequantised by
         * comp() and the node transform / inverse bind matrices, like float ones. */
        if (pos.ncomp != 3 || pos.ct == 5125)
          return km__fail(err, KM_ERR_PARSE, "%s: %s: POSITION must be VEC3 float, byte or short",
                          d->name, what);
        bool hn = cJSON_GetObjectItemCaseSensitive(at, "NORMAL") != NULL;
        bool ht = cJSON_GetObjectItemCaseSensitive(at, "TEXCOORD_0") != NULL;
        if (hn && (s = prim_accessor(d, pr, "NORMAL", what, &nrm, err))) return s;
        if (ht && (s = prim_accessor(d, pr, "TEXCOORD_0", what, &tex, err))) return s;
        if ((hn && (nrm.ncomp != 3 || nrm.count != pos.count || nrm.ct == 5125)) ||
            (ht && (tex.ncomp != 2 || tex.count != pos.count || tex.ct == 5125)))
          return km__fail(err, KM_ERR_PARSE,
                          "%s: %s: NORMAL (VEC3) / TEXCOORD_0 (VEC2) must have POSITION's count",
                          d->name, what);
        bool hc = cJSON_GetObjectItemCaseSensitive(at, "COLOR_0") != NULL;
        if (hc && (s = prim_accessor(d, pr, "COLOR_0", what, &col, err))) return s;
        if (hc && ((col.ncomp != 3 && col.ncomp != 4) || col.count != pos.count ||
                   (col.ct != 5126 && !col.normalized)))
          return km__fail(err, KM_ERR_PARSE,
                          "%s: %s: COLOR_0 must be VEC3 or VEC4 (float, or normalized unsigned "
                          "byte or short) with POSITION's count",
                          d->name, what);
        double uvA[6] = {0, 0, 1, 0, 0, 1};
        bool uvt = ht && uv_transform(d, pr, uvA);
        bool hi = cJSON_GetObjectItemCaseSensitive(pr, "indices") != NULL || drc;
        if (hi && (s = prim_accessor(d, pr, NULL, what, &idx, err))) return s;
        acc_view aj[2], aw[2];
        bool hs = pass == 1 && d->S && cJSON_GetObjectItemCaseSensitive(at, "JOINTS_0") &&
                  cJSON_GetObjectItemCaseSensitive(at, "WEIGHTS_0");
        /* A second set (JOINTS_1 / WEIGHTS_1: influences 5-8) when both are there. */
        int nsets = hs && cJSON_GetObjectItemCaseSensitive(at, "JOINTS_1") &&
                            cJSON_GetObjectItemCaseSensitive(at, "WEIGHTS_1")
                        ? 2
                        : 1;
        for (int k = 0; hs && k < nsets; ++k) {
          char jn[24], wn[24]; /* room for any int: no -Wformat-truncation */
          snprintf(jn, sizeof jn, "JOINTS_%d", k);
          snprintf(wn, sizeof wn, "WEIGHTS_%d", k);
          if ((s = prim_accessor(d, pr, jn, what, &aj[k], err)) ||
              (s = prim_accessor(d, pr, wn, what, &aw[k], err)))
            return s;
          if (aj[k].ncomp != 4 || aw[k].ncomp != 4 || aj[k].count != pos.count ||
              aw[k].count != pos.count || (aj[k].ct != 5121 && aj[k].ct != 5123) ||
              aj[k].normalized || (aw[k].ct != 5126 && aw[k].ct != 5121 && aw[k].ct != 5123))
            return km__fail(err, KM_ERR_PARSE,
                            "%s: %s: %s (VEC4 unsigned byte/short) and %s (VEC4 float or "
                            "normalized) must have POSITION's count",
                            d->name, what, jn, wn);
        }
        if (hi && (idx.ncomp != 1 || (idx.ct != 5121 && idx.ct != 5123 && idx.ct != 5125)))
          return km__fail(err, KM_ERR_PARSE, "%s: %s: indices must be unsigned SCALAR", d->name,
                          what);
        size_t ni = hi ? idx.count : pos.count;
        if (mode == 4 && ni % 3)
          return km__fail(err, KM_ERR_PARSE, "%s: %s: %zu indices is not a multiple of 3", d->name,
                          what, ni);
        size_t nt = mode == 4 ? ni / 3 : ni >= 3 ? ni - 2 : 0; /* triangles */
        /* A primitive whose attributes are an earlier one's of this mesh (kinemesh's own
         * output of several materials: one set of vertices, a primitive per material) shares
         * that one's vertices, read once: the file's vertex count, not one copy per material. */
        size_t vb = v0;
        bool shared = false;
        if ((size_t)pi >= d->cap_base) {
          size_t c = 2 * (size_t)pi + 8, *b = realloc(d->prim_base, c * sizeof *b);
          if (!b) goto nomem;
          d->prim_base = b, d->cap_base = c;
        }
        for (int q = 0; q < pi && !shared; ++q) {
          const cJSON *pq = cJSON_GetArrayItem(prims, q);
          const cJSON *dq = cJSON_GetObjectItemCaseSensitive(
              cJSON_GetObjectItemCaseSensitive(pq, "extensions"), "KHR_draco_mesh_compression");
          if (cJSON_Compare(cJSON_GetObjectItemCaseSensitive(pq, "attributes"), at, true) &&
              (dq ? drc && cJSON_Compare(dq, drc, true) : !drc))
            shared = true, vb = d->prim_base[q];
        }
        d->prim_base[pi] = vb;
        if (pass == 0) {
          if (!shared) nv += pos.count;
          nf += nt;
          any_n |= hn;
          any_t |= ht;
          any_c |= hc;
          if (nv > INT32_MAX) break;
          continue;
        }
        for (size_t i = 0; !shared && i < pos.count; ++i) {
          double p[3], n[3] = {0, 0, 0};
          for (int c = 0; c < 3; ++c) {
            p[c] = comp(&pos, i, c);
            if (hn) n[c] = comp(&nrm, i, c);
            if (ht && c < 2) {
              double t = comp(&tex, i, c);
              if (uvt)
                t = uvA[c] + uvA[2 + 2 * c] * comp(&tex, i, 0) + uvA[3 + 2 * c] * comp(&tex, i, 1);
              out->UV[2 * (v0 + i) + c] = c ? 1 - t : t;
            }
          }
          for (int c = 0; hc && c < col.ncomp; ++c) /* linear in glTF, sRGB in km_mesh */
            out->colors[4 * (v0 + i) + c] =
                c < 3 ? km__srgb_encode(comp(&col, i, c)) : fmin(1, fmax(0, comp(&col, i, c)));
          double nl = 0, Mv[16];
          const double *Mp = M;
          if (hs) { /* linear blend skinning by the scene's joint transforms */
            double wsum = 0, wq[8];
            int32_t jq[8];
            memset(Mv, 0, sizeof Mv);
            for (int q = 0; q < 4 * nsets; ++q) {
              double jx = comp(&aj[q / 4], i, q % 4), w = comp(&aw[q / 4], i, q % 4);
              jq[q] = -1, wq[q] = 0;
              if (!(w > 0)) continue;
              if (!(jx < (double)d->S_n) || !isfinite(w))
                return km__fail(err, KM_ERR_PARSE,
                                "%s: %s: vertex %zu: JOINTS_%d %.0f is outside the skin's %zu "
                                "joints (or its weight is not finite)",
                                d->name, what, i, q / 4, jx, d->S_n);
              jq[q] = d->S_ids[(size_t)jx], wq[q] = w;
              wsum += w;
              for (int e = 0; e < 16; ++e)
                Mv[e] += w * d->S[16 * (size_t)jx + e];
            }
            if (wsum > 0) {
              for (int e = 0; e < 16; ++e)
                Mv[e] /= wsum;
              Mp = Mv;
              /* The position uses every influence (as a viewer does); the skin keeps 4 per
               * vertex (kinemesh's skinning): the 4 largest, renormalised. */
              int keep[4] = {0, 1, 2, 3};
              double ksum = wsum;
              if (nsets == 2) {
                bool used[8] = {false};
                ksum = 0;
                for (int q = 0; q < 4; ++q) {
                  int b = -1;
                  for (int c = 0; c < 8; ++c)
                    if (!used[c] && (b < 0 || wq[c] > wq[b])) b = c;
                  used[b] = true;
                  keep[q] = b;
                  ksum += wq[b];
                }
              }
              for (int q = 0; q < 4 && d->skin; ++q) {
                d->skin->joints[4 * (v0 + i) + q] = wq[keep[q]] > 0 ? jq[keep[q]] : -1;
                d->skin->weights[4 * (v0 + i) + q] = wq[keep[q]] / ksum;
              }
            }
          } else if (rigid >= 0) {
            d->skin->joints[4 * (v0 + i)] = rigid;
            d->skin->weights[4 * (v0 + i)] = 1;
          }
          for (int r = 0; r < 3; ++r) {
            double x = Mp[12 + r];
            for (int c = 0; c < 3; ++c)
              x += Mp[c * 4 + r] * p[c];
            if (!isfinite(x))
              return km__fail(err, KM_ERR_PARSE, "%s: %s: POSITION %zu is not finite", d->name,
                              what, i);
            out->V[3 * (v0 + i) + r] = x;
            if (hn) {
              double y = Mp != M ? Mp[r] * n[0] + Mp[4 + r] * n[1] + Mp[8 + r] * n[2]
                                 : C[r * 3] * n[0] + C[r * 3 + 1] * n[1] + C[r * 3 + 2] * n[2];
              out->N[3 * (v0 + i) + r] = y;
              nl += y * y;
            }
          }
          if (hn && nl > 0 && isfinite(nl) && fabs(nl - 1) > 1e-12) /* renormalise if scaled */
            for (int r = 0; r < 3; ++r)
              out->N[3 * (v0 + i) + r] /= sqrt(nl);
        }
        for (size_t t = 0; t < nt; ++t)
          for (size_t c = 0; c < 3; ++c) {
            /* strip: {t, t + 1 + t % 2, t + 2 - t % 2}; fan: {t + 1, t + 2, 0} (glTF 2.0, 3.7.2.1)
             */
            size_t k = mode == 4   ? 3 * t + c
                       : mode == 5 ? (c == 0   ? t
                                      : c == 1 ? t + 1 + t % 2
                                               : t + 2 - t % 2)
                                   : (c == 2 ? 0 : t + 1 + c);
            double ix = hi ? comp(&idx, k, 0) : (double)k;
            if (!(ix < (double)pos.count))
              return km__fail(err, KM_ERR_PARSE,
                              "%s: %s: index %zu is %.0f, outside the primitive's %zu vertices",
                              d->name, what, k, ix, pos.count);
            out->F[3 * (f0 + t) + c] = (int32_t)(vb + (size_t)ix);
          }
        if (det < 0 && !hs) /* a mirror: keep the outward winding */
          for (size_t t = 0; t < nt; ++t) {
            int32_t *f = out->F + 3 * (f0 + t);
            int32_t tmp = f[1];
            f[1] = f[2];
            f[2] = tmp;
          }
        if (!shared) v0 += pos.count;
        f0 += nt;
        if (pass == 1 && nt > 0) { /* its run of faces (one with the last if same material) */
          int pm = jint(pr, "material", -1);
          if (d->n_runs && d->run_mat[d->n_runs - 1] == pm) {
            d->run_n[d->n_runs - 1] += nt;
          } else {
            if (d->n_runs == d->cap_runs) {
              size_t c = d->cap_runs ? 2 * d->cap_runs : 8;
              size_t *a = realloc(d->run_first, c * sizeof *a), *b = NULL;
              if (a) d->run_first = a;
              if (a && (b = realloc(d->run_n, c * sizeof *b))) d->run_n = b;
              int *m = a && b ? realloc(d->run_mat, c * sizeof *m) : NULL;
              if (!m) goto nomem;
              d->run_mat = m;
              d->cap_runs = c;
            }
            d->run_first[d->n_runs] = f0 - nt;
            d->run_n[d->n_runs] = nt;
            d->run_mat[d->n_runs++] = pm;
          }
        }
      }
    }
  }
  if (nv == 0) return km__fail(err, KM_ERR_PARSE, "%s: the meshes have no vertices", d->name);
  return KM_OK;
nomem:
  return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", d->name);
}

/* The document of a .glb / .gltf in memory: its JSON and BIN chunk (buffers not loaded yet). */
static km_status doc_open(gltf_doc *d, const char *data, size_t size, const char *name,
                          const char *base_path, km_error *err) {
  memset(d, 0, sizeof *d);
  d->name = name;
  d->base_path = base_path;
  const unsigned char *u = (const unsigned char *)data;
  if (size >= 4 && !memcmp(data, "glTF", 4)) {
    if (size < 20 || km__get_u32le(u + 4) != 2)
      return km__fail(err, KM_ERR_PARSE, "%s: expected a glTF 2.0 binary header", name);
    size_t total = km__get_u32le(u + 8), jl = km__get_u32le(u + 12);
    if (total > size || total < 20 || km__get_u32le(u + 16) != 0x4E4F534Au || jl > total - 20)
      return km__fail(err, KM_ERR_PARSE,
                      "%s: byte 12: the JSON chunk (%zu bytes) does not fit the %zu-byte file",
                      name, jl, size);
    km_status s = parse_json(data + 20, jl, name, 20, &d->json, err);
    if (s) return s;
    size_t bo = 20 + jl;
    if (bo + 8 <= total && km__get_u32le(u + bo + 4) == 0x004E4942u) {
      size_t bl = km__get_u32le(u + bo);
      if (bl > total - bo - 8) {
        cJSON_Delete(d->json);
        d->json = NULL;
        return km__fail(err, KM_ERR_PARSE, "%s: byte %zu: the BIN chunk is truncated", name, bo);
      }
      d->bin = u + bo + 8;
      d->bin_len = bl;
    }
    return KM_OK;
  }
  return parse_json(data, size, name, 0, &d->json, err);
}

static void doc_close(gltf_doc *d) {
  free(d->node_parent);
  free(d->node_world);
  free(d->joint_of_node);
  free(d->S);
  free(d->S_ids);
  free(d->run_first);
  free(d->run_n);
  free(d->run_mat);
  free(d->prim_base);
  for (int i = 0; i < d->n_views && d->views; ++i)
    free(d->views[i]);
  free(d->views);
  free(d->view_len);
  for (int i = 0; i < d->n_draco && d->draco; ++i)
    if (d->draco[i]) km__draco_free(d->draco[i]);
  free(d->draco);
  for (int i = 0; i < d->n_dacc && d->dacc; ++i)
    free(d->dacc[i]);
  free(d->dacc);
  for (int i = 0; i < d->n_bufs && d->bufs; ++i)
    free(d->bufs[i]);
  free(d->bufs);
  free(d->buf_len);
  cJSON_Delete(d->json);
  memset(d, 0, sizeof *d);
}

km_status km__gltf_parse(const char *data, size_t size, const char *name, const char *base_path,
                         km_mesh *out, km_mesh_skin *skin, km_error *err) {
  gltf_doc d;
  if (skin) memset(skin, 0, sizeof *skin);
  km_status s = doc_open(&d, data, size, name, base_path, err);
  if (s) return s;
  d.skin = skin;
  s = parse_doc(&d, out, err);
  if (!s && vrm0(&d)) /* root_matrix turned it */
    km__log(KM_LOG_INFO, "%s: a VRM 0.x avatar (facing -z): turned to face +z", name);
  if (s) km_mesh_free(out);
  if (s || (skin && !skin->n_joints)) km_mesh_skin_free(skin);
  doc_close(&d);
  return s;
}

km_status km__gltf_accessors_each(const void *data, size_t size, const char *name,
                                  const int *accessors, size_t n, km__gltf_accessor_fn fn,
                                  void *ctx, km_error *err) {
  gltf_doc d;
  km_status s = doc_open(&d, data, size, name, NULL, err);
  if (s) return s;
  double *x = NULL;
  size_t cap = 0;
  if (!(s = load_buffers(&d, err)))
    for (size_t k = 0; k < n && !s; ++k) {
      acc_view v;
      char what[32];
      snprintf(what, sizeof what, "accessors[%d]", accessors[k]);
      if ((s = accessor(&d, accessors[k], what, &v, err))) break;
      size_t need = v.count * (size_t)v.ncomp + 1;
      if (need > cap) {
        double *g = realloc(x, need * sizeof *x);
        if (!g) {
          s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
          break;
        }
        x = g, cap = need;
      }
      for (size_t i = 0; i < v.count; ++i)
        for (int c = 0; c < v.ncomp; ++c)
          x[i * (size_t)v.ncomp + (size_t)c] = comp(&v, i, c);
      s = fn(ctx, k, x, v.count, v.ncomp, err);
    }
  free(x);
  doc_close(&d);
  return s;
}

typedef struct {
  double *out;
  size_t count;
  int ncomp;
} one_accessor;

static km_status keep_one(void *ctx, size_t k, const double *v, size_t count, int ncomp,
                          km_error *err) {
  (void)k;
  one_accessor *o = ctx;
  size_t n = count * (size_t)ncomp;
  if (!(o->out = km__malloc(n + 1, sizeof *o->out)))
    return km__fail(err, KM_ERR_NOMEM, "out of memory for an accessor of %zu values", n);
  memcpy(o->out, v, n * sizeof *v);
  o->count = count, o->ncomp = ncomp;
  return KM_OK;
}

km_status km__gltf_accessor_read(const void *data, size_t size, const char *name,
                                 int accessor_index, double **out, size_t *count, int *ncomp,
                                 km_error *err) {
  *out = NULL, *count = 0, *ncomp = 0;
  one_accessor o = {0};
  km_status s = km__gltf_accessors_each(data, size, name, &accessor_index, 1, keep_one, &o, err);
  if (s) {
    free(o.out);
    return s;
  }
  *out = o.out, *count = o.count, *ncomp = o.ncomp;
  return KM_OK;
}

void km_mesh_skin_free(km_mesh_skin *s) {
  if (!s) return;
  for (size_t j = 0; s->names && j < s->n_joints; ++j)
    free(s->names[j]);
  free(s->names);
  free(s->parents);
  free(s->rest);
  free(s->joints);
  free(s->weights);
  memset(s, 0, sizeof *s);
}

km_status km__gltf_mesh_transform(const void *data, size_t size, const char *name, int mesh,
                                  double M[16], km_error *err) {
  static const double I[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  memcpy(M, I, sizeof I);
  gltf_doc d;
  km_status s = doc_open(&d, data, size, name, NULL, err);
  if (s) return s;
  instances inst = {0};
  if (!(s = collect_instances(&d, &inst, err)))
    for (size_t i = 0; i < inst.n; ++i)
      if (inst.v[i].mesh == mesh) {
        memcpy(M, inst.v[i].M, sizeof I);
        break;
      }
  free(inst.v);
  doc_close(&d);
  return s;
}
