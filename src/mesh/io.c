/* Mesh allocation, format dispatch for reading/writing, and the number helpers shared by
 * the text parsers. */
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <ctype.h>
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

km_status km_mesh_alloc(size_t n_vertices, size_t n_faces, km_mesh *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_mesh_alloc: out is NULL");
  memset(out, 0, sizeof *out);
  if (n_vertices > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "km_mesh_alloc: %zu vertices exceed the int32 index range",
                    n_vertices);
  /* Allocate at least one element so that an empty mesh still has valid pointers. */
  out->V = km__malloc(n_vertices ? n_vertices * 3 : 1, sizeof(double));
  out->F = km__malloc(n_faces ? n_faces : 1, 3 * sizeof(int32_t));
  if (!out->V || !out->F) {
    km_mesh_free(out);
    return km__fail(err, KM_ERR_NOMEM, "km_mesh_alloc: out of memory for %zu vertices, %zu faces",
                    n_vertices, n_faces);
  }
  out->n_vertices = n_vertices;
  out->n_faces = n_faces;
  return KM_OK;
}

km_status km_mesh_copy(const km_mesh *src, km_mesh *out, km_error *err) {
  if (!src || !out) return km__fail(err, KM_ERR_INVALID, "km_mesh_copy: NULL argument");
  km_mesh tmp;
  km_status s = km_mesh_alloc(src->n_vertices, src->n_faces, &tmp, err);
  if (s) return s;
  if (src->n_vertices) memcpy(tmp.V, src->V, src->n_vertices * 3 * sizeof(double));
  if (src->n_faces) memcpy(tmp.F, src->F, src->n_faces * 3 * sizeof(int32_t));
  size_t nv = src->n_vertices ? src->n_vertices : 1;
  if (src->UV && !(tmp.UV = km__malloc(nv * 2, sizeof(double)))) goto nomem;
  if (src->N && !(tmp.N = km__malloc(nv * 3, sizeof(double)))) goto nomem;
  if (src->UV && src->n_vertices) memcpy(tmp.UV, src->UV, src->n_vertices * 2 * sizeof(double));
  if (src->N && src->n_vertices) memcpy(tmp.N, src->N, src->n_vertices * 3 * sizeof(double));
  if (src->colors && !(tmp.colors = km__malloc(nv * 4, sizeof(double)))) goto nomem;
  if (src->colors && src->n_vertices)
    memcpy(tmp.colors, src->colors, src->n_vertices * 4 * sizeof(double));
  if (src->materials && src->n_materials) {
    if (!(tmp.materials = km__calloc(src->n_materials, sizeof *tmp.materials))) goto nomem;
    tmp.n_materials = src->n_materials;
    for (size_t k = 0; k < src->n_materials; ++k) {
      if (!km__material_copy(tmp.materials + k, src->materials + k)) goto nomem;
    }
  }
  *out = tmp;
  return KM_OK;
nomem:
  km_mesh_free(&tmp);
  return km__fail(err, KM_ERR_NOMEM, "km_mesh_copy: out of memory");
}

uint64_t km_mesh_hash(const km_mesh *m) {
  if (!m) return 0;
  uint64_t sz[2] = {m->n_vertices, m->n_faces};
  uint64_t h = km__fnv1a(KM__FNV_SEED, sz, sizeof sz);
  if (m->V) h = km__fnv1a(h, m->V, m->n_vertices * 3 * sizeof(double));
  if (m->F) h = km__fnv1a(h, m->F, m->n_faces * 3 * sizeof(int32_t));
  return h;
}

bool km__material_copy(km_mesh_material *dst, const km_mesh_material *src) {
  *dst = *src;
  dst->image = NULL;
  for (int q = 0; q < KM_MAP_COUNT; ++q)
    dst->maps[q].bytes = NULL;
  size_t n = src->image ? src->image_size : 0;
  if (n && !(dst->image = km__malloc(n, 1))) return false;
  if (n) memcpy(dst->image, src->image, n);
  for (int q = 0; q < KM_MAP_COUNT; ++q) {
    n = src->maps[q].bytes ? src->maps[q].size : 0;
    if (n && !(dst->maps[q].bytes = km__malloc(n, 1))) return false;
    if (n) memcpy(dst->maps[q].bytes, src->maps[q].bytes, n);
  }
  return true;
}

void km__material_free_images(km_mesh_material *m) {
  free(m->image);
  m->image = NULL;
  for (int q = 0; q < KM_MAP_COUNT; ++q) {
    free(m->maps[q].bytes);
    m->maps[q].bytes = NULL;
  }
}

void km_mesh_free(km_mesh *m) {
  if (!m) return;
  free(m->V);
  free(m->F);
  free(m->UV);
  free(m->N);
  free(m->colors);
  for (size_t k = 0; m->materials && k < m->n_materials; ++k)
    km__material_free_images(m->materials + k);
  free(m->materials);
  memset(m, 0, sizeof *m);
}

static km_status format_from_name(const char *name, km_mesh_format *fmt, km_error *err) {
  char ext[16];
  km__extension(name ? name : "", ext, sizeof ext);
  if (!strcmp(ext, "obj"))
    *fmt = KM_FORMAT_OBJ;
  else if (!strcmp(ext, "ply"))
    *fmt = KM_FORMAT_PLY;
  else if (!strcmp(ext, "off"))
    *fmt = KM_FORMAT_OFF;
  else if (!strcmp(ext, "stl"))
    *fmt = KM_FORMAT_STL;
  else if (!strcmp(ext, "glb") || !strcmp(ext, "gltf") || !strcmp(ext, "vrm")) /* VRM: a .glb */
    *fmt = KM_FORMAT_GLTF;
  else
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: unknown mesh extension '%s' (expected .obj, .ply, .off, .stl, .glb, "
                    ".gltf or .vrm)",
                    name ? name : "(unnamed)", ext);
  return KM_OK;
}

km_status km_mesh_parse(const void *data, size_t size, km_mesh_format format, const char *name,
                        km_mesh *out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_mesh_parse: out is NULL");
  memset(out, 0, sizeof *out);
  if (!data && size) return km__fail(err, KM_ERR_INVALID, "km_mesh_parse: data is NULL");
  if (!name) name = "(memory)";
  if (format == KM_FORMAT_AUTO) {
    km_status s = format_from_name(name, &format, err);
    if (s) return s;
  }
  const char *d = data ? data : "";
  switch (format) {
  case KM_FORMAT_OBJ: return km__obj_parse(d, size, name, out, err);
  case KM_FORMAT_PLY: return km__ply_parse(d, size, name, out, err);
  case KM_FORMAT_OFF: return km__off_parse(d, size, name, out, err);
  case KM_FORMAT_GLTF: return km__gltf_parse(d, size, name, NULL, out, NULL, err);
  case KM_FORMAT_STL: return km__stl_parse(d, size, name, out, err);
  default: return km__fail(err, KM_ERR_INVALID, "%s: unknown mesh format %d", name, (int)format);
  }
}

km_status km_mesh_read(const char *path, km_mesh *out, km_error *err) {
  return km_mesh_read_skinned(path, out, NULL, err);
}

km_status km_mesh_parse_skinned(const void *data, size_t size, const char *name, km_mesh *out,
                                km_mesh_skin *skin, km_error *err) {
  if (!out || !skin) return km__fail(err, KM_ERR_INVALID, "km_mesh_parse_skinned: NULL argument");
  memset(skin, 0, sizeof *skin);
  km_mesh_format fmt;
  km_status s = format_from_name(name ? name : "", &fmt, err);
  if (s) return s;
  if (fmt != KM_FORMAT_GLTF) return km_mesh_parse(data, size, fmt, name, out, err);
  memset(out, 0, sizeof *out);
  if (!data && size) return km__fail(err, KM_ERR_INVALID, "km_mesh_parse_skinned: data is NULL");
  return km__gltf_parse(data ? data : "", size, name, NULL, out, skin, err);
}

km_status km_mesh_read_skinned(const char *path, km_mesh *out, km_mesh_skin *skin, km_error *err) {
  if (skin) memset(skin, 0, sizeof *skin);
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_mesh_read: NULL argument");
  memset(out, 0, sizeof *out);
  km_mesh_format fmt;
  km_status s = format_from_name(path, &fmt, err);
  if (s) return s;
  char *data = NULL;
  size_t size = 0;
  s = km__read_file(path, &data, &size, err);
  if (s) return s;
  double t0 = km_seconds();
  if (fmt == KM_FORMAT_GLTF) /* buffers may be files beside it */
    s = km__gltf_parse(data, size, path, path, out, skin, err);
  else
    s = km_mesh_parse(data, size, fmt, path, out, err);
  if (s == KM_OK && fmt == KM_FORMAT_OBJ) km__obj_read_material(data, size, path, out);
  free(data);
  if (!s)
    km__log(KM_LOG_DEBUG, "%s: %zu vertices, %zu faces in %.3f s", path, out->n_vertices,
            out->n_faces, km_seconds() - t0);
  return s;
}

static km_status check_mesh(const char *path, const km_mesh *m, km_error *err) {
  if (!m) return km__fail(err, KM_ERR_INVALID, "%s: mesh is NULL", path);
  if ((m->n_vertices && !m->V) || (m->n_faces && !m->F))
    return km__fail(err, KM_ERR_INVALID, "%s: mesh has counts but NULL arrays", path);
  if (m->n_vertices > INT32_MAX)
    return km__fail(err, KM_ERR_INVALID, "%s: %zu vertices exceed the int32 index range", path,
                    m->n_vertices);
  for (size_t i = 0; i < m->n_faces * 3; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= m->n_vertices)
      return km__fail(err, KM_ERR_INVALID, "%s: face %zu has vertex index %d outside [0, %zu)",
                      path, i / 3, (int)m->F[i], m->n_vertices);
  return KM_OK;
}

/* An OBJ's materials (issue 11: a textured model must not come out grey): "<stem>.mtl" and its
 * images "<stem>_texture_<k>.png|.jpg" beside path (the output the user named, never an input's
 * folder); *mtl: the library's name for the OBJ's mtllib line. A mesh whose materials do not
 * tile its faces writes its first over all of them, as the glb writer does. */
static km_status write_obj_materials(const char *path, const km_mesh *m, char **mtl,
                                     km_error *err) {
  const char *slash = strrchr(path, '/');
  const char *base = slash ? slash + 1 : path, *dot = strrchr(base, '.');
  size_t stem = dot && dot > base ? (size_t)(dot - base) : strlen(base);
  /* the output's folder: "a/." for a/x.obj, "." for x.obj, "/." for /x.obj */
  char *dir = km__path_beside(path, "."), *name = malloc(stem + 5), *prefix = malloc(stem + 10);
  if (!dir || !name || !prefix) {
    free(dir), free(name), free(prefix);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  snprintf(name, stem + 5, "%.*s.mtl", (int)stem, base);
  snprintf(prefix, stem + 10, "%.*s_texture_", (int)stem, base);
  km_mesh_material one;
  const km_mesh_material *mats = m->materials;
  size_t n = m->n_materials;
  if (!km__obj_materials_cover(m)) {
    km__log(KM_LOG_WARN,
            "%s: the mesh's materials do not cover its %zu faces in order: its first material is "
            "written over all of them",
            path, m->n_faces);
    one = m->materials[0];
    mats = &one, n = 1;
  }
  km_status s = km__obj_write_materials(dir, name, prefix, mats, n, err);
  free(dir), free(prefix);
  if (s)
    free(name);
  else
    *mtl = name;
  return s;
}

km_status km_mesh_write(const char *path, const km_mesh *m, const km_mesh_write_options *opt,
                        km_error *err) {
  if (!path) return km__fail(err, KM_ERR_INVALID, "km_mesh_write: path is NULL");
  km_status s = check_mesh(path, m, err);
  if (s) return s;
  km_mesh_format fmt = opt ? opt->format : KM_FORMAT_AUTO;
  km_ply_encoding enc = opt ? opt->ply : KM_PLY_BINARY_LE;
  if (fmt == KM_FORMAT_AUTO) {
    s = format_from_name(path, &fmt, err);
    if (s) return s;
  }
  if (fmt == KM_FORMAT_GLTF)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: glTF is read, not written, as a mesh (write .obj or .ply; animations "
                    "are written as .glb by the animation writer)",
                    path);
  if (fmt == KM_FORMAT_STL && !m->n_faces)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: the mesh has no faces and an STL holds triangles only (write a point "
                    "cloud as .ply)",
                    path);
  if (fmt == KM_FORMAT_STL && (m->UV || m->N || m->n_materials))
    km__log(KM_LOG_WARN,
            "%s: STL keeps the triangles' positions only: the texture coordinates, normals and "
            "materials are not written (.obj, .ply or .glb keep them)",
            path);
  if (fmt != KM_FORMAT_OBJ && fmt != KM_FORMAT_PLY && fmt != KM_FORMAT_OFF && fmt != KM_FORMAT_STL)
    return km__fail(err, KM_ERR_INVALID, "%s: unknown mesh format %d", path, (int)fmt);
  if (enc != KM_PLY_BINARY_LE && enc != KM_PLY_BINARY_BE && enc != KM_PLY_ASCII)
    return km__fail(err, KM_ERR_INVALID, "%s: unknown PLY encoding %d", path, (int)enc);
  char *mtl = NULL;
  if (fmt == KM_FORMAT_OBJ && m->n_materials && (s = write_obj_materials(path, m, &mtl, err)))
    return s;
  km__atomic_file af;
  s = km__atomic_open(&af, path, err);
  if (s) {
    free(mtl);
    return s;
  }
  /* Writers only fail through the FILE error state, which commit reports. */
  if (fmt == KM_FORMAT_OBJ) {
    km_mesh view = *m;
    km_mesh_material one;
    if (mtl && !km__obj_materials_cover(m)) { /* as the glb writer: the first over all */
      one = m->materials[0];
      one.first_face = 0, one.n_faces = m->n_faces;
      view.materials = &one, view.n_materials = 1;
    }
    km__obj_write(af.f, &view, NULL, mtl, false);
    free(mtl);
  } else if (fmt == KM_FORMAT_PLY)
    km__ply_write(af.f, m, enc, NULL);
  else if (fmt == KM_FORMAT_STL)
    km__stl_write(af.f, m);
  else
    km__off_write(af.f, m);
  return km__atomic_commit(&af, err);
}

/* ---------------------------------------------------------------- number helpers */

/* Text formats are locale-independent: a process that called setlocale(LC_ALL, "de_DE")
 * must still read "0.5" as one half. */
static locale_t g_c_locale;
static pthread_once_t g_c_locale_once = PTHREAD_ONCE_INIT;
static void make_c_locale(void) { g_c_locale = newlocale(LC_ALL_MASK, "C", (locale_t)0); }

bool km__parse_double(const char *s, size_t len, double *out) {
  /* strtod needs a terminated string and the input buffer is not; tokens are short. */
  char buf[512];
  if (len == 0 || len >= sizeof buf) return false;
  memcpy(buf, s, len);
  buf[len] = '\0';
  pthread_once(&g_c_locale_once, make_c_locale);
  char *end;
  double x = g_c_locale ? strtod_l(buf, &end, g_c_locale) : strtod(buf, &end);
  if (end != buf + len || !isfinite(x)) return false;
  *out = x;
  return true;
}

bool km__parse_int64(const char *s, size_t len, int64_t *out) {
  size_t i = 0;
  bool neg = false;
  if (i < len && (s[i] == '+' || s[i] == '-')) neg = s[i++] == '-';
  if (i == len) return false;
  uint64_t v = 0;
  for (; i < len; ++i) {
    unsigned d = (unsigned)(unsigned char)s[i] - '0';
    if (d > 9) return false;
    if (v > ((uint64_t)INT64_MAX - d) / 10) return false;
    v = v * 10 + d;
  }
  *out = neg ? -(int64_t)v : (int64_t)v;
  return true;
}

const char *km__image_mime(const unsigned char *b, size_t n) {
  if (n >= 8 && !memcmp(b, "\x89PNG\r\n\x1a\n", 8)) return "image/png";
  if (n >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return "image/jpeg";
  return NULL;
}

int km__format_double_digits(char *buf, size_t n, double x, int digits) {
  pthread_once(&g_c_locale_once, make_c_locale);
  locale_t old = g_c_locale ? uselocale(g_c_locale) : (locale_t)0;
  int len = snprintf(buf, n, "%.*g", digits, x);
  if (g_c_locale) uselocale(old);
  return len;
}

int km__format_double(char *buf, size_t n, double x) {
  return km__format_double_digits(buf, n, x, 17);
}

void km__quote_token(const char *s, size_t len, char *out, size_t out_size) {
  size_t o = 0;
  if (out_size < 8) {
    if (out_size) out[0] = '\0';
    return;
  }
  out[o++] = '\'';
  for (size_t i = 0; i < len && o + 6 < out_size; ++i) {
    if (i == 40) {
      out[o++] = '.', out[o++] = '.', out[o++] = '.';
      break;
    }
    unsigned char c = (unsigned char)s[i];
    if (isprint(c))
      out[o++] = (char)c;
    else
      o += (size_t)snprintf(out + o, out_size - o, "\\x%02x", c);
  }
  out[o++] = '\'';
  out[o] = '\0';
}

bool km__tris_fan(km__tris *t, size_t j, int32_t idx, int32_t *first, int32_t *prev) {
  if (j >= 2) {
    if (!km__tris_reserve(t, t->n + 1)) return false;
    int32_t *f = t->F + 3 * t->n++;
    f[0] = *first, f[1] = *prev, f[2] = idx;
  } else if (j == 0) {
    *first = idx;
  }
  *prev = idx;
  return true;
}

bool km__tris_reserve(km__tris *t, size_t n_tris) {
  if (n_tris <= t->cap) return true;
  size_t cap = t->cap ? t->cap : 64;
  while (cap < n_tris) {
    if (cap > SIZE_MAX / 2) return false;
    cap *= 2;
  }
  if (cap > SIZE_MAX / (3 * sizeof(int32_t))) return false;
  int32_t *nf = realloc(t->F, cap * 3 * sizeof(int32_t));
  if (!nf) return false;
  t->F = nf;
  t->cap = cap;
  return true;
}
