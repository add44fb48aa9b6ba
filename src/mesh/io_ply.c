/* Stanford PLY (ascii, binary little/big endian). Any elements in any order; only the
 * vertex positions and the face index lists are kept, everything else is skipped by its
 * declared type. All counts are checked against the bytes left in the buffer before
 * anything is allocated from them.
 *
 * rply and miniply were considered; neither is packaged here, rply reads through FILE*
 * callbacks (we parse from memory for fuzzing and speed) and both leave error positions to
 * the caller, so the reader is written out. */
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef enum ply_type { T_NONE = 0, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ply_type;

static const struct {
  const char *name;
  ply_type type;
} k_type_names[] = {
    {"char", T_I8},   {"uchar", T_U8},   {"short", T_I16},   {"ushort", T_U16},
    {"int", T_I32},   {"uint", T_U32},   {"float", T_F32},   {"double", T_F64},
    {"int8", T_I8},   {"uint8", T_U8},   {"int16", T_I16},   {"uint16", T_U16},
    {"int32", T_I32}, {"uint32", T_U32}, {"float32", T_F32}, {"float64", T_F64},
};

static const size_t k_type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

static bool type_is_int(ply_type t) { return t >= T_I8 && t <= T_U32; }

enum {
  ROLE_NONE = 0,
  ROLE_X,
  ROLE_Y,
  ROLE_Z,
  ROLE_INDICES,
  ROLE_U,
  ROLE_V,
  ROLE_NX,
  ROLE_NY,
  ROLE_NZ,
  ROLE_R, /* vertex colour red, green, blue, alpha */
  ROLE_G,
  ROLE_B,
  ROLE_A
};

/* Vertex attribute names: texture coordinates as Blender/MeshLab (s t), Paraview/Open3D
 * (u v) and PCL/others (texture_u texture_v) write them; normals nx ny nz; colours red green
 * blue alpha as MeshLab, Blender, Open3D and scanners write them (diffuse_red ... in older
 * Stanford files). */
static int attribute_role(const char *t, size_t l) {
  static const struct {
    const char *name;
    int role;
  } k[] = {{"u", ROLE_U},
           {"s", ROLE_U},
           {"texture_u", ROLE_U},
           {"texture_s", ROLE_U},
           {"v", ROLE_V},
           {"t", ROLE_V},
           {"texture_v", ROLE_V},
           {"texture_t", ROLE_V},
           {"nx", ROLE_NX},
           {"ny", ROLE_NY},
           {"nz", ROLE_NZ},
           {"red", ROLE_R},
           {"green", ROLE_G},
           {"blue", ROLE_B},
           {"alpha", ROLE_A},
           {"diffuse_red", ROLE_R},
           {"diffuse_green", ROLE_G},
           {"diffuse_blue", ROLE_B},
           {"diffuse_alpha", ROLE_A}};
  for (size_t i = 0; i < sizeof k / sizeof k[0]; ++i)
    if (strlen(k[i].name) == l && !memcmp(k[i].name, t, l)) return k[i].role;
  return ROLE_NONE;
}

typedef struct ply_prop {
  ply_type type;       /* scalar type, or the list's item type */
  ply_type count_type; /* T_NONE for a scalar */
  int role;
} ply_prop;

#define MAX_ELEMENTS 32
#define MAX_PROPS 256

typedef struct ply_element {
  uint64_t count;
  size_t first_prop, n_props;
  size_t header_line;
  bool is_vertex, is_face;
} ply_element;

typedef struct ply_header {
  ply_element el[MAX_ELEMENTS];
  size_t n_el;
  ply_prop props[MAX_PROPS];
  size_t n_props;
  int encoding; /* -1 unknown, else km_ply_encoding */
} ply_header;

typedef struct tok_cursor {
  const char *p, *end;
} tok_cursor;

static bool line_token(tok_cursor *c, const char **tok, size_t *len) {
  return km__token(&c->p, c->end, tok, len);
}

static bool tok_is(const char *tok, size_t len, const char *s) {
  size_t n = strlen(s);
  return len == n && memcmp(tok, s, n) == 0;
}

static ply_type parse_type(const char *tok, size_t len) {
  for (size_t i = 0; i < sizeof k_type_names / sizeof k_type_names[0]; ++i)
    if (tok_is(tok, len, k_type_names[i].name)) return k_type_names[i].type;
  return T_NONE;
}

/* Parses the header; *body is set past the end_header line, *line to the body's first line. */
static km_status parse_header(const char *data, size_t size, const char *name, ply_header *h,
                              const char **body, size_t *line_out, km_error *err) {
  const char *end = data + size, *p = data;
  size_t line = 0;
  char q[64];
  h->encoding = -1;
  for (;;) {
    if (p >= end)
      return km__fail(err, KM_ERR_PARSE,
                      "%s:%zu: unexpected end of file in the PLY header, expected "
                      "'end_header'",
                      name, line + 1);
    const char *nl = memchr(p, '\n', (size_t)(end - p));
    tok_cursor c = {p, nl ? nl : end};
    p = nl ? nl + 1 : end;
    ++line;
    const char *tok, *t2, *t3;
    size_t len, l2, l3;
    bool has = line_token(&c, &tok, &len);
    if (line == 1) {
      if (!has || !tok_is(tok, len, "ply") || line_token(&c, &t2, &l2))
        return km__fail(err, KM_ERR_PARSE, "%s:1: expected 'ply' as the first line", name);
      continue;
    }
    if (!has) continue;
    if (tok_is(tok, len, "comment") || tok_is(tok, len, "obj_info")) continue;
    if (tok_is(tok, len, "end_header")) {
      if (!nl) /* the body starts after the newline; without one there is no body */
        p = end;
      break;
    }
    if (tok_is(tok, len, "format")) {
      if (!line_token(&c, &t2, &l2) || !line_token(&c, &t3, &l3))
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'format <encoding> 1.0'", name, line);
      if (tok_is(t2, l2, "ascii"))
        h->encoding = KM_PLY_ASCII;
      else if (tok_is(t2, l2, "binary_little_endian"))
        h->encoding = KM_PLY_BINARY_LE;
      else if (tok_is(t2, l2, "binary_big_endian"))
        h->encoding = KM_PLY_BINARY_BE;
      else {
        km__quote_token(t2, l2, q, sizeof q);
        return km__fail(err, KM_ERR_PARSE,
                        "%s:%zu: expected ascii, binary_little_endian or "
                        "binary_big_endian, found %s",
                        name, line, q);
      }
      continue;
    }
    if (tok_is(tok, len, "element")) {
      int64_t count;
      if (!line_token(&c, &t2, &l2) || !line_token(&c, &t3, &l3) ||
          !km__parse_int64(t3, l3, &count) || count < 0)
        return km__fail(err, KM_ERR_PARSE,
                        "%s:%zu: expected 'element <name> <count>' with a "
                        "non-negative count",
                        name, line);
      if (h->n_el == MAX_ELEMENTS)
        return km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: more than %d elements", name, line,
                        MAX_ELEMENTS);
      ply_element *e = &h->el[h->n_el++];
      memset(e, 0, sizeof *e);
      e->count = (uint64_t)count;
      e->first_prop = h->n_props;
      e->header_line = line;
      e->is_vertex = tok_is(t2, l2, "vertex");
      e->is_face = tok_is(t2, l2, "face");
      for (size_t i = 0; i + 1 < h->n_el; ++i)
        if ((e->is_vertex && h->el[i].is_vertex) || (e->is_face && h->el[i].is_face))
          return km__fail(err, KM_ERR_PARSE, "%s:%zu: element declared twice", name, line);
      continue;
    }
    if (tok_is(tok, len, "property")) {
      if (!h->n_el)
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected an 'element' line before 'property'",
                        name, line);
      if (h->n_props == MAX_PROPS)
        return km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: more than %d properties", name, line,
                        MAX_PROPS);
      ply_element *e = &h->el[h->n_el - 1];
      ply_prop pr = {0};
      if (!line_token(&c, &t2, &l2))
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a property type", name, line);
      if (tok_is(t2, l2, "list")) {
        const char *tc, *ti;
        size_t lc, li;
        if (!line_token(&c, &tc, &lc) || !line_token(&c, &ti, &li))
          return km__fail(err, KM_ERR_PARSE,
                          "%s:%zu: expected 'property list <count type> <item "
                          "type> <name>'",
                          name, line);
        pr.count_type = parse_type(tc, lc);
        pr.type = parse_type(ti, li);
        if (!type_is_int(pr.count_type) || !pr.type)
          return km__fail(err, KM_ERR_PARSE,
                          "%s:%zu: expected an integer list count type and a "
                          "scalar item type",
                          name, line);
      } else {
        pr.type = parse_type(t2, l2);
        if (!pr.type) {
          km__quote_token(t2, l2, q, sizeof q);
          return km__fail(err, KM_ERR_PARSE,
                          "%s:%zu: expected a scalar type (char, uchar, short, "
                          "ushort, int, uint, float, double or int8..float64), found %s",
                          name, line, q);
        }
      }
      if (!line_token(&c, &t3, &l3))
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a property name", name, line);
      bool list = pr.count_type != T_NONE;
      if (e->is_vertex && (tok_is(t3, l3, "x") || tok_is(t3, l3, "y") || tok_is(t3, l3, "z"))) {
        if (list)
          return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected vertex %.*s to be a scalar", name,
                          line, (int)l3, t3);
        pr.role = ROLE_X + (t3[0] - 'x');
      } else if (e->is_vertex && !list) {
        pr.role = attribute_role(t3, l3);
      }
      if (e->is_face && list &&
          (tok_is(t3, l3, "vertex_indices") || tok_is(t3, l3, "vertex_index"))) {
        if (!type_is_int(pr.type))
          return km__fail(err, KM_ERR_PARSE,
                          "%s:%zu: expected an integer type for face vertex "
                          "indices",
                          name, line);
        pr.role = ROLE_INDICES;
      }
      for (size_t i = e->first_prop; i < h->n_props; ++i)
        if (pr.role >= ROLE_U && h->props[i].role == pr.role)
          pr.role = ROLE_NONE; /* "u" and "s" both: the first is read, the second skipped */
        else if (pr.role && h->props[i].role == pr.role)
          return km__fail(err, KM_ERR_PARSE, "%s:%zu: property declared twice", name, line);
      h->props[h->n_props++] = pr;
      e->n_props++;
      continue;
    }
    km__quote_token(tok, len, q, sizeof q);
    return km__fail(err, KM_ERR_PARSE,
                    "%s:%zu: expected format, element, property, comment or "
                    "end_header, found %s",
                    name, line, q);
  }
  if (h->encoding < 0)
    return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a 'format' line before end_header", name,
                    line);
  *body = p;
  *line_out = line + 1;
  return KM_OK;
}

/* ---------------------------------------------------------------- binary values */

static uint64_t load_bits(const unsigned char *p, size_t n, bool be) {
  uint64_t v = 0;
  if (be)
    for (size_t i = 0; i < n; ++i)
      v = v << 8 | p[i];
  else
    for (size_t i = n; i-- > 0;)
      v = v << 8 | p[i];
  return v;
}

static double load_double(const unsigned char *p, ply_type t, bool be) {
  uint64_t b = load_bits(p, k_type_size[t], be);
  switch (t) {
  case T_I8: return (double)(int8_t)b;
  case T_U8: return (double)(uint8_t)b;
  case T_I16: return (double)(int16_t)b;
  case T_U16: return (double)(uint16_t)b;
  case T_I32: return (double)(int32_t)b;
  case T_U32: return (double)(uint32_t)b;
  case T_F32: {
    uint32_t u = (uint32_t)b;
    float f;
    memcpy(&f, &u, 4);
    return (double)f;
  }
  case T_F64: {
    double d;
    memcpy(&d, &b, 8);
    return d;
  }
  default: return 0;
  }
}

static int64_t load_int(const unsigned char *p, ply_type t, bool be) {
  uint64_t b = load_bits(p, k_type_size[t], be);
  switch (t) {
  case T_I8: return (int8_t)b;
  case T_U8: return (uint8_t)b;
  case T_I16: return (int16_t)b;
  case T_U16: return (uint16_t)b;
  case T_I32: return (int32_t)b;
  case T_U32: return (uint32_t)b;
  default: return 0;
  }
}

/* ---------------------------------------------------------------- body */

typedef struct body_reader {
  const char *name;
  const unsigned char *base, *p, *end; /* base: start of the whole file (for byte offsets) */
  bool ascii, be;
  size_t line; /* ascii: current line */
  km_error *err;
  bool nonfinite_ok; /* KM__PLY_NONFINITE */
} body_reader;

static bool ascii_ieq(const char *s, size_t len, const char *lit) {
  size_t n = strlen(lit);
  if (len != n) return false;
  for (size_t i = 0; i < n; ++i)
    if ((s[i] | 0x20) != lit[i]) return false;
  return true;
}

/* NaN and infinity as C's printf, Python and PCL spell them: [+-]nan[(...)], [+-]inf,
 * [+-]infinity, any case. Overflowing literals (1e999) stay errors: they are corruption,
 * not a sensor's "no return". */
static bool parse_nonfinite(const char *tok, size_t len, double *d) {
  bool neg = false;
  if (len && (tok[0] == '+' || tok[0] == '-')) neg = tok[0] == '-', ++tok, --len;
  if (len >= 3 && ascii_ieq(tok, 3, "nan") &&
      (len == 3 || (tok[3] == '(' && tok[len - 1] == ')'))) {
    *d = NAN;
    return true;
  }
  if (ascii_ieq(tok, len, "inf") || ascii_ieq(tok, len, "infinity")) {
    *d = neg ? -INFINITY : INFINITY;
    return true;
  }
  return false;
}

static km_status truncated(body_reader *r, const char *what) {
  if (r->ascii)
    return km__fail(r->err, KM_ERR_PARSE, "%s:%zu: unexpected end of file, expected %s", r->name,
                    r->line, what);
  return km__fail(r->err, KM_ERR_PARSE, "%s: byte %zu: unexpected end of file, expected %s",
                  r->name, (size_t)(r->p - r->base), what);
}

/* Next ascii token, counting lines. */
static bool ascii_token(body_reader *r, const char **tok, size_t *len) {
  const unsigned char *p = r->p;
  for (;;) {
    while (p < r->end && km__is_space((char)*p))
      ++p;
    if (p < r->end && *p == '\n') {
      ++r->line;
      ++p;
      continue;
    }
    break;
  }
  if (p >= r->end) {
    r->p = p;
    return false;
  }
  *tok = (const char *)p;
  while (p < r->end && !km__is_space((char)*p) && *p != '\n')
    ++p;
  *len = (size_t)((const char *)p - *tok);
  r->p = p;
  return true;
}

/* Reads one scalar as a double (for coordinates) or as an integer (counts and indices). */
static km_status read_value(body_reader *r, ply_type t, bool as_int, double *d, int64_t *i,
                            const char *what) {
  if (r->ascii) {
    const char *tok;
    size_t len;
    if (!ascii_token(r, &tok, &len)) return truncated(r, what);
    bool ok =
        as_int ? km__parse_int64(tok, len, i)
               : km__parse_double(tok, len, d) || (r->nonfinite_ok && parse_nonfinite(tok, len, d));
    if (!ok) {
      char q[64];
      km__quote_token(tok, len, q, sizeof q);
      return km__fail(r->err, KM_ERR_PARSE, "%s:%zu: expected %s (%s), found %s", r->name, r->line,
                      what, as_int ? "an integer" : "a finite number", q);
    }
    return KM_OK;
  }
  size_t n = k_type_size[t];
  if ((size_t)(r->end - r->p) < n) return truncated(r, what);
  if (as_int)
    *i = load_int(r->p, t, r->be);
  else {
    *d = load_double(r->p, t, r->be);
    if (!isfinite(*d) && !r->nonfinite_ok)
      return km__fail(r->err, KM_ERR_PARSE, "%s: byte %zu: expected %s (a finite number), found %g",
                      r->name, (size_t)(r->p - r->base), what, *d);
  }
  r->p += n;
  return KM_OK;
}

static km_status skip_values(body_reader *r, ply_type t, uint64_t n) {
  if (r->ascii) {
    for (uint64_t k = 0; k < n; ++k) {
      const char *tok;
      size_t len;
      if (!ascii_token(r, &tok, &len)) return truncated(r, "a property value");
    }
    return KM_OK;
  }
  uint64_t avail = (uint64_t)(r->end - r->p) / k_type_size[t];
  if (n > avail) return truncated(r, "list items");
  r->p += n * k_type_size[t];
  return KM_OK;
}

static km_status read_list_count(body_reader *r, const ply_prop *pr, int64_t *n) {
  const unsigned char *at = r->p;
  size_t line = r->line;
  km_status s = read_value(r, pr->count_type, true, NULL, n, "a list count");
  if (s) return s;
  if (*n < 0) {
    if (r->ascii)
      return km__fail(r->err, KM_ERR_PARSE,
                      "%s:%zu: expected a non-negative list count, found "
                      "%lld",
                      r->name, line, (long long)*n);
    return km__fail(r->err, KM_ERR_PARSE,
                    "%s: byte %zu: expected a non-negative list count, "
                    "found %lld",
                    r->name, (size_t)(at - r->base), (long long)*n);
  }
  return KM_OK;
}

km_status km__ply_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err) {
  return km__ply_parse_ex(data, size, name, 0, out, err);
}

km_status km__ply_parse_ex(const char *data, size_t size, const char *name, unsigned flags,
                           km_mesh *out, km_error *err) {
  ply_header *h = calloc(1, sizeof *h);
  if (!h) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  const char *body = NULL;
  size_t line = 0;
  km_status s = parse_header(data, size, name, h, &body, &line, err);
  double *V = NULL, *UV = NULL, *NV = NULL, *C = NULL;
  km__tris tris = {0};
  if (s) goto done;

  ply_element *ve = NULL, *fe = NULL;
  for (size_t i = 0; i < h->n_el; ++i) {
    if (h->el[i].is_vertex) ve = &h->el[i];
    if (h->el[i].is_face) fe = &h->el[i];
  }
  if (!ve) {
    s = km__fail(err, KM_ERR_PARSE, "%s: expected an 'element vertex' in the header", name);
    goto done;
  }
  int have = 0;
  for (size_t k = 0; k < ve->n_props; ++k) {
    int role = h->props[ve->first_prop + k].role;
    if (role >= ROLE_X && role <= ROLE_Z) have |= 1 << role;
  }
  if (have != ((1 << ROLE_X) | (1 << ROLE_Y) | (1 << ROLE_Z))) {
    s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected properties x, y and z in element vertex",
                 name, ve->header_line);
    goto done;
  }
  int attrs = 0; /* bit per role present */
  for (size_t k = 0; k < ve->n_props; ++k)
    attrs |= 1 << h->props[ve->first_prop + k].role;
  bool want_uv = (attrs & (1 << ROLE_U)) && (attrs & (1 << ROLE_V));
  bool want_n = (attrs & (7 << ROLE_NX)) == (7 << ROLE_NX);
  bool want_c = (attrs & (7 << ROLE_R)) == (7 << ROLE_R);
  bool has_indices = false;
  if (fe)
    for (size_t k = 0; k < fe->n_props; ++k)
      has_indices |= h->props[fe->first_prop + k].role == ROLE_INDICES;
  if (fe && !has_indices) {
    s = km__fail(err, KM_ERR_PARSE,
                 "%s:%zu: expected a list property vertex_indices (or "
                 "vertex_index) in element face",
                 name, fe->header_line);
    goto done;
  }
  /* Every instance needs at least a few bytes (binary: its scalars and list counts; ascii: one
   * character and one separator per value), so the declared counts are bounded by the bytes
   * left. This is what keeps a 100-byte file claiming 2^31 vertices from allocating. */
  bool ascii = h->encoding == KM_PLY_ASCII;
  size_t body_size = (size_t)(data + size - body);
  uint64_t need = 0;
  for (size_t i = 0; i < h->n_el; ++i) {
    ply_element *e = &h->el[i];
    uint64_t per = 0;
    for (size_t k = 0; k < e->n_props; ++k) {
      const ply_prop *pr = &h->props[e->first_prop + k];
      per += ascii ? 2 : k_type_size[pr->count_type ? pr->count_type : pr->type];
    }
    if (per && e->count > (UINT64_MAX / 2) / per)
      need = UINT64_MAX / 2;
    else
      need += e->count * per;
    if (need > (uint64_t)body_size + (ascii ? 1 : 0) ||
        (per == 0 && e->count && (e->is_vertex || e->is_face))) {
      s = km__fail(err, KM_ERR_PARSE,
                   "%s:%zu: element count %llu cannot fit in the %zu bytes "
                   "after the header (file truncated or count wrong)",
                   name, e->header_line, (unsigned long long)e->count, body_size);
      goto done;
    }
  }

  if (ve->count > INT32_MAX) {
    s = km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: %llu vertices exceed the int32 index range",
                 name, ve->header_line, (unsigned long long)ve->count);
    goto done;
  }

  size_t nv = (size_t)ve->count;
  V = km__malloc(nv ? nv * 3 : 1, sizeof(double));
  if (want_uv) UV = km__malloc(nv ? nv * 2 : 1, sizeof(double));
  if (want_n) NV = km__malloc(nv ? nv * 3 : 1, sizeof(double));
  if (want_c) C = km__malloc(nv ? nv * 4 : 1, sizeof(double));
  for (size_t i = 0; C && i < nv; ++i)
    C[4 * i + 3] = 1; /* no alpha property: opaque */
  if (!V || (want_uv && !UV) || (want_n && !NV) || (want_c && !C) ||
      (fe && !km__tris_reserve(&tris, fe->count ? (size_t)fe->count : 1))) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu vertices", name, nv);
    goto done;
  }

  body_reader r = {name,
                   (const unsigned char *)data,
                   (const unsigned char *)body,
                   (const unsigned char *)data + size,
                   ascii,
                   h->encoding == KM_PLY_BINARY_BE,
                   line,
                   err,
                   (flags & KM__PLY_NONFINITE) != 0};
  for (size_t ei = 0; ei < h->n_el && !s; ++ei) {
    ply_element *e = &h->el[ei];
    const ply_prop *props = &h->props[e->first_prop];
    if (e->n_props == 0) continue; /* instances without properties occupy no bytes */
    /* Fast skip of binary elements made only of scalars. */
    if (!ascii && !e->is_vertex && !e->is_face) {
      bool fixed = true;
      uint64_t per = 0;
      for (size_t k = 0; k < e->n_props; ++k) {
        fixed &= props[k].count_type == T_NONE;
        per += k_type_size[props[k].type];
      }
      if (fixed) {
        if (per && e->count > (uint64_t)(r.end - r.p) / per)
          s = truncated(&r, "element data");
        else
          r.p += e->count * per;
        continue;
      }
    }
    for (uint64_t n = 0; n < e->count && !s; ++n) {
      for (size_t k = 0; k < e->n_props && !s; ++k) {
        const ply_prop *pr = &props[k];
        if (e->is_vertex && pr->role >= ROLE_X && pr->role <= ROLE_Z) {
          s = read_value(&r, pr->type, false, &V[n * 3 + (size_t)(pr->role - ROLE_X)], NULL,
                         "a vertex coordinate");
        } else if (e->is_vertex && pr->role >= ROLE_U && pr->role <= ROLE_V && UV) {
          s = read_value(&r, pr->type, false, &UV[n * 2 + (size_t)(pr->role - ROLE_U)], NULL,
                         "a texture coordinate");
        } else if (e->is_vertex && pr->role >= ROLE_NX && pr->role <= ROLE_NZ && NV) {
          s = read_value(&r, pr->type, false, &NV[n * 3 + (size_t)(pr->role - ROLE_NX)], NULL,
                         "a normal component");
        } else if (e->is_vertex && pr->role >= ROLE_R && C && pr->count_type == T_NONE) {
          /* integers over their type's range (uchar 0..255, ushort 0..65535), floats as they
           * are; clamped to [0, 1] */
          double *c = &C[n * 4 + (size_t)(pr->role - ROLE_R)];
          s = read_value(&r, pr->type, false, c, NULL, "a colour component");
          double full = pr->type == T_U16 || pr->type == T_I16 ? 65535
                        : type_is_int(pr->type)                ? 255
                                                               : 1;
          *c = fmin(1, fmax(0, *c / full));
        } else if (pr->count_type == T_NONE) {
          s = skip_values(&r, pr->type, 1);
        } else if (pr->role != ROLE_INDICES) {
          int64_t cnt;
          s = read_list_count(&r, pr, &cnt);
          if (!s) s = skip_values(&r, pr->type, (uint64_t)cnt);
        } else {
          const unsigned char *at = r.p;
          size_t at_line = r.line;
          int64_t cnt;
          s = read_list_count(&r, pr, &cnt);
          if (s) break;
          if (cnt < 3) {
            if (ascii)
              s = km__fail(err, KM_ERR_PARSE,
                           "%s:%zu: face %llu: expected at least 3 vertex "
                           "indices, found %lld",
                           name, at_line, (unsigned long long)n, (long long)cnt);
            else
              s = km__fail(err, KM_ERR_PARSE,
                           "%s: byte %zu: face %llu: expected at least 3 "
                           "vertex indices, found %lld",
                           name, (size_t)(at - r.base), (unsigned long long)n, (long long)cnt);
            break;
          }
          /* Fan triangulation streams: (first, previous, current) for each index after the
           * second, so polygons of any size need no buffer. */
          int32_t first = 0, prev = 0;
          for (int64_t j = 0; j < cnt && !s; ++j) {
            at = r.p;
            int64_t idx;
            s = read_value(&r, pr->type, true, NULL, &idx, "a face vertex index");
            if (s) break;
            if (idx < 0 || (uint64_t)idx >= nv) {
              if (ascii)
                s = km__fail(err, KM_ERR_PARSE,
                             "%s:%zu: face %llu: vertex index %lld out of "
                             "range (expected 0..%zu)",
                             name, r.line, (unsigned long long)n, (long long)idx, nv ? nv - 1 : 0);
              else
                s = km__fail(err, KM_ERR_PARSE,
                             "%s: byte %zu: face %llu: vertex index %lld out "
                             "of range (expected 0..%zu)",
                             name, (size_t)(at - r.base), (unsigned long long)n, (long long)idx,
                             nv ? nv - 1 : 0);
              break;
            }
            if (!km__tris_fan(&tris, (size_t)j, (int32_t)idx, &first, &prev)) {
              s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
              break;
            }
          }
        }
      }
    }
  }
  if (s) goto done;
  out->V = V;
  out->F = tris.F;
  out->n_vertices = nv;
  out->n_faces = tris.n;
  out->UV = UV;
  out->N = NV;
  out->colors = C;
  V = UV = NV = C = NULL;
  tris.F = NULL;
  if (!fe) { /* point cloud: keep a valid (empty) face array */
    out->F = km__malloc(1, 3 * sizeof(int32_t));
    if (!out->F) {
      km_mesh_free(out);
      s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
    }
  }
done:
  free(V);
  free(UV);
  free(NV);
  free(C);
  free(tris.F);
  free(h);
  return s;
}

/* ---------------------------------------------------------------- writer */

static void store_bits(unsigned char *p, uint64_t v, size_t n, bool be) {
  for (size_t i = 0; i < n; ++i) {
    unsigned char byte = (unsigned char)(v >> (8 * i));
    p[be ? n - 1 - i : i] = byte;
  }
}

double km__srgb_encode(double x) {
  x = fmin(1, fmax(0, x));
  return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
}

double km__srgb_decode(double x) {
  x = fmin(1, fmax(0, x));
  return x <= 0.04045 ? x / 12.92 : pow((x + 0.055) / 1.055, 2.4);
}

void km__color8(const double c[4], unsigned char out[4]) {
  for (int k = 0; k < 4; ++k) {
    double x = c[k] * 255 + 0.5;
    out[k] = (unsigned char)(x > 255 ? 255 : x > 0 ? x : 0);
  }
}

bool km_mesh_colors_rgba8(const km_mesh *m, unsigned char *out) {
  if (!m || !m->colors || !out) return false;
  for (size_t i = 0; i < m->n_vertices; ++i)
    km__color8(m->colors + 4 * i, out + 4 * i);
  return true;
}

km_status km__ply_write(FILE *f, const km_mesh *m, km_ply_encoding enc, const char *comment) {
  const char *fmt = enc == KM_PLY_ASCII       ? "ascii"
                    : enc == KM_PLY_BINARY_BE ? "binary_big_endian"
                                              : "binary_little_endian";
  fprintf(f,
          "ply\nformat %s 1.0\ncomment %s\nelement vertex %zu\nproperty double x\n"
          "property double y\nproperty double z\n",
          fmt, comment ? comment : "kinemesh", m->n_vertices);
  if (m->UV) fputs("property double u\nproperty double v\n", f);
  if (m->N) fputs("property double nx\nproperty double ny\nproperty double nz\n", f);
  /* colours as every PLY reader takes them: uchar 0..255 (8 bits: what they were read as) */
  if (m->colors)
    fputs("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n",
          f);
  if (m->n_faces)
    fprintf(f, "element face %zu\nproperty list uchar int vertex_indices\n", m->n_faces);
  fputs("end_header\n", f);
  if (enc == KM_PLY_ASCII) {
    char buf[40];
    for (size_t i = 0; i < m->n_vertices; ++i) {
      double rec[8];
      int n_rec = 0;
      for (int k = 0; k < 3; ++k)
        rec[n_rec++] = m->V[3 * i + (size_t)k];
      for (int k = 0; m->UV && k < 2; ++k)
        rec[n_rec++] = m->UV[2 * i + (size_t)k];
      for (int k = 0; m->N && k < 3; ++k)
        rec[n_rec++] = m->N[3 * i + (size_t)k];
      for (int k = 0; k < n_rec; ++k) {
        int n = km__format_double(buf, sizeof buf - 1, rec[k]);
        buf[n] = k == n_rec - 1 && !m->colors ? '\n' : ' ';
        fwrite(buf, 1, (size_t)n + 1, f);
      }
      if (m->colors) {
        unsigned char c8[4];
        km__color8(m->colors + 4 * i, c8);
        fprintf(f, "%u %u %u %u\n", c8[0], c8[1], c8[2], c8[3]);
      }
    }
    for (size_t i = 0; i < m->n_faces; ++i)
      fprintf(f, "3 %d %d %d\n", m->F[3 * i], m->F[3 * i + 1], m->F[3 * i + 2]);
  } else {
    bool be = enc == KM_PLY_BINARY_BE;
    unsigned char rec[8 * 8 + 4]; /* 8 doubles (x y z u v nx ny nz) and 4 colour bytes */
    for (size_t i = 0; i < m->n_vertices; ++i) {
      double val[8];
      int n_val = 0;
      for (int k = 0; k < 3; ++k)
        val[n_val++] = m->V[3 * i + (size_t)k];
      for (int k = 0; m->UV && k < 2; ++k)
        val[n_val++] = m->UV[2 * i + (size_t)k];
      for (int k = 0; m->N && k < 3; ++k)
        val[n_val++] = m->N[3 * i + (size_t)k];
      for (int k = 0; k < n_val; ++k) {
        uint64_t b;
        memcpy(&b, &val[k], 8);
        store_bits(rec + 8 * k, b, 8, be);
      }
      size_t nb = 8 * (size_t)n_val;
      if (m->colors) km__color8(m->colors + 4 * i, rec + nb), nb += 4;
      fwrite(rec, 1, nb, f);
    }
    for (size_t i = 0; i < m->n_faces; ++i) {
      rec[0] = 3;
      for (int k = 0; k < 3; ++k)
        store_bits(rec + 1 + 4 * k, (uint32_t)m->F[3 * i + (size_t)k], 4, be);
      fwrite(rec, 1, 13, f);
    }
  }
  return ferror(f) ? KM_ERR_IO : KM_OK;
}
