/* Private helpers shared by the mesh readers and writers (src/mesh/). */
#ifndef KM_MESH_IO_H
#define KM_MESH_IO_H

#include "core/core.h"

#include <stdint.h>

/* Each parser reads `size` bytes at `data` (not necessarily NUL-terminated) and on success
 * fills `out` (which the caller has zeroed). `name` is used in error messages. */
km_status km__obj_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err);
km_status km__ply_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err);
/* km__ply_parse with flags. KM__PLY_NONFINITE: vertex coordinates may be NaN or +-inf (ascii
 * "nan", "-inf", "infinity", any case; binary: any bit pattern) and are kept as such. Only
 * the point cloud reader (src/io/points.c) sets it: sensors write NaN for pixels without a
 * return, which a point cloud drops and counts, while a mesh with one is broken. */
#define KM__PLY_NONFINITE 1u
km_status km__ply_parse_ex(const char *data, size_t size, const char *name, unsigned flags,
                           km_mesh *out, km_error *err);
/* glTF 2.0 (.glb or .gltf JSON; io_gltf.c). base_path: the file's path, for buffers in files
 * beside it (NULL: only the BIN chunk and data: URIs). skin: NULL, or filled as
 * km_mesh_read_skinned describes (zeroed when the file has none). */
km_status km__gltf_parse(const char *data, size_t size, const char *name, const char *base_path,
                         km_mesh *out, km_mesh_skin *skin, km_error *err);
/* STL, binary or ASCII (io_stl.c); corners welded as km_mesh_read describes. */
km_status km__stl_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err);
km_status km__off_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err);

/* An OBJ read from path: its usemtl groups' materials from the mtllib beside it (Kd, d, Pr or Ns,
 * Pm and map_Kd's image, PNG or JPEG bytes), one per run of faces, into out->materials. Anything
 * missing or unreadable is a warning, never an error (the geometry was asked for). */
void km__obj_read_material(const char *data, size_t size, const char *path, km_mesh *out);

km_status km__off_write(FILE *f, const km_mesh *m);
/* Binary STL: one record per face (float32 corners, unit facet normal, 0 0 0 for a degenerate
 * face); vertices no face uses are not written. */
km_status km__stl_write(FILE *f, const km_mesh *m);

/* The MIME type of an encoded image by its signature: "image/png", "image/jpeg", or NULL for
 * anything else (what a glTF viewer decodes, so what the readers keep as a texture). */
const char *km__image_mime(const unsigned char *bytes, size_t n);

/* Parses a whole token as a finite double, locale-independently (strtod in the "C" locale,
 * correctly rounded). False for anything else (garbage, trailing characters, NaN, inf,
 * overflow). */
bool km__parse_double(const char *s, size_t len, double *out);
/* Parses a whole token as a decimal integer with an optional sign. False on garbage or
 * overflow of int64. */
bool km__parse_int64(const char *s, size_t len, int64_t *out);
/* Writes %.17g of x into buf (always with '.' as decimal point), returns its length. */
int km__format_double(char *buf, size_t n, double x);
/* The same with `digits` significant digits (9: a float's). */
int km__format_double_digits(char *buf, size_t n, double x, int digits);

/* Shows at most ~40 bytes of a token in an error message, escaping non-printables. */
void km__quote_token(const char *s, size_t len, char *out, size_t out_size);

/* Growable triangle array used by the readers (amortised doubling, no per-face malloc). */
typedef struct km__tris {
  int32_t *F;
  size_t n, cap; /* in triangles */
} km__tris;
bool km__tris_reserve(km__tris *t, size_t n_tris);
/* Fan triangulation (0, j-1, j) of a polygon fed one index at a time: corner j of the polygon
 * is idx; first/prev carry the fan's state between calls. False when out of memory. */
bool km__tris_fan(km__tris *t, size_t j, int32_t idx, int32_t *first, int32_t *prev);

static inline bool km__is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/* Next whitespace-separated token in [*p, end), advancing *p past it; false when none is
 * left. The readers call it on a cursor bounded by the current line. */
static inline bool km__token(const char **p, const char *end, const char **tok, size_t *len) {
  const char *q = *p;
  while (q < end && km__is_space(*q))
    ++q;
  if (q >= end) {
    *p = q;
    return false;
  }
  *tok = q;
  while (q < end && !km__is_space(*q))
    ++q;
  *len = (size_t)(q - *tok);
  *p = q;
  return true;
}

#endif
