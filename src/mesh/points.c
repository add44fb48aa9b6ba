/* Point cloud frame readers: PLY (the mesh PLY parser, told to keep NaN), PCD v0.7 and XYZ
 * text.
 *
 * The PCD parser is written by hand: the reference reader is PCL's (C++, with Boost and
 * Eigen, far too heavy to link into a C library for a header plus a packed array). Only
 * what kinemesh needs is read: x y z of each point, other fields are skipped by their
 * declared SIZE*COUNT. */
#include "core/core.h"
#include "mesh/mesh_io.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void km_points_free(km_points *p) {
  if (!p) return;
  free(p->P);
  memset(p, 0, sizeof *p);
}

/* Appends finite points, counts the others; exact zeros (a depth sensor's pixels with no
 * return, often many thousands per frame) are dropped and counted too. Capacity is checked by
 * the caller. */
static void push_point(km_points *o, double x, double y, double z) {
  if (!isfinite(x) || !isfinite(y) || !isfinite(z)) {
    ++o->dropped_nan;
    return;
  }
  if (x == 0 && y == 0 && z == 0) {
    ++o->dropped_zero;
    return;
  }
  o->P[o->n * 3 + 0] = x;
  o->P[o->n * 3 + 1] = y;
  o->P[o->n * 3 + 2] = z;
  ++o->n;
}

static km_status parse_ply(const void *data, size_t size, const char *name, km_points *out,
                           km_error *err) {
  km_mesh m = {0};
  /* NaN rows stay in place so push_point drops and counts them as for PCD and XYZ; the
   * finite points keep the file's order. */
  km_status s = km__ply_parse_ex(data, size, name, KM__PLY_NONFINITE, &m, err);
  if (s) return s;
  out->P = km__malloc(m.n_vertices ? m.n_vertices : 1, 3 * sizeof(double));
  if (!out->P) {
    km_mesh_free(&m);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu points", name, m.n_vertices);
  }
  for (size_t i = 0; i < m.n_vertices; ++i)
    push_point(out, m.V[3 * i], m.V[3 * i + 1], m.V[3 * i + 2]);
  km_mesh_free(&m);
  return KM_OK;
}

/* ---------------------------------------------------------------- XYZ text */

static km_status parse_xyz(const char *text, size_t size, const char *name, km_points *out,
                           km_error *err) {
  /* Each point needs at least 6 bytes ("0 0 0\n"), which bounds the allocation. */
  size_t cap = size / 6 + 1;
  out->P = km__malloc(cap, 3 * sizeof(double));
  if (!out->P) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  const char *p = text, *end = text + size;
  size_t line = 0;
  while (p < end) {
    ++line;
    const char *eol = memchr(p, '\n', (size_t)(end - p));
    if (!eol) eol = end;
    char buf[512];
    size_t len = (size_t)(eol - p);
    if (len >= sizeof buf)
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: line longer than %zu bytes", name, line,
                      sizeof buf - 1);
    memcpy(buf, p, len);
    buf[len] = '\0';
    p = eol + 1;
    char *c = buf;
    while (*c && isspace((unsigned char)*c))
      ++c;
    if (!*c || *c == '#') continue;
    double v[3];
    for (int k = 0; k < 3; ++k) {
      while (*c && (isspace((unsigned char)*c) || *c == ','))
        ++c;
      char *e;
      errno = 0;
      v[k] = strtod(c, &e);
      if (e == c)
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 3 numbers (x y z), found %d", name,
                        line, k);
      c = e;
    }
    if (out->n + out->dropped_nan + out->dropped_zero >= cap)
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: too many points", name, line);
    push_point(out, v[0], v[1], v[2]);
  }
  return KM_OK;
}

/* ---------------------------------------------------------------- PCD v0.7 */

#define PCD_MAX_FIELDS 64

typedef struct pcd_field {
  char name[32];
  int size;
  char type;
  size_t count;
  size_t offset; /* bytes from the start of a binary record */
  size_t column; /* first token in an ascii record */
} pcd_field;

static double pcd_value(const unsigned char *b, char type, int size) {
  if (type == 'F' && size == 4) {
    float f;
    memcpy(&f, b, 4);
    return f;
  }
  if (type == 'F' && size == 8) {
    double d;
    memcpy(&d, b, 8);
    return d;
  }
  uint64_t u = 0;
  memcpy(&u, b, (size_t)size); /* little endian hosts only, as PCL itself */
  if (type == 'U') return (double)u;
  int64_t i = size == 1 ? (int8_t)u : size == 2 ? (int16_t)u : size == 4 ? (int32_t)u : (int64_t)u;
  return (double)i;
}

static km_status parse_pcd(const char *data, size_t size, const char *name, km_points *out,
                           km_error *err) {
  pcd_field f[PCD_MAX_FIELDS];
  int nf = 0, n_size = 0, n_type = 0, n_count = 0;
  size_t width = 0, height = 1, points = 0;
  bool have_points = false, have_width = false;
  char mode[32] = "";
  const char *p = data, *end = data + size;
  size_t line = 0;
  memset(f, 0, sizeof f);
  while (p < end && !mode[0]) {
    ++line;
    const char *eol = memchr(p, '\n', (size_t)(end - p));
    if (!eol) eol = end;
    char buf[2048];
    size_t len = (size_t)(eol - p);
    if (len >= sizeof buf)
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: header line too long", name, line);
    memcpy(buf, p, len);
    buf[len] = '\0';
    if (len && buf[len - 1] == '\r') buf[len - 1] = '\0';
    p = eol < end ? eol + 1 : end;
    char *save = NULL, *key = strtok_r(buf, " \t", &save);
    if (!key || key[0] == '#') continue;
    char *tok;
    if (!strcmp(key, "VERSION")) {
      continue;
    } else if (!strcmp(key, "FIELDS")) {
      nf = 0;
      while ((tok = strtok_r(NULL, " \t", &save))) {
        if (nf == PCD_MAX_FIELDS)
          return km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: more than %d fields", name, line,
                          PCD_MAX_FIELDS);
        snprintf(f[nf].name, sizeof f[nf].name, "%s", tok);
        f[nf].count = 1;
        ++nf;
      }
    } else if (!strcmp(key, "SIZE") || !strcmp(key, "TYPE") || !strcmp(key, "COUNT")) {
      int k = 0;
      while ((tok = strtok_r(NULL, " \t", &save))) {
        if (k >= nf)
          return km__fail(err, KM_ERR_PARSE, "%s:%zu: %s has more entries than FIELDS (%d)", name,
                          line, key, nf);
        if (key[0] == 'S') {
          int s = atoi(tok);
          if (s != 1 && s != 2 && s != 4 && s != 8)
            return km__fail(err, KM_ERR_PARSE, "%s:%zu: SIZE %s is not 1, 2, 4 or 8", name, line,
                            tok);
          f[k].size = s;
        } else if (key[0] == 'T') {
          if (strlen(tok) != 1 || !strchr("FIU", tok[0]))
            return km__fail(err, KM_ERR_PARSE, "%s:%zu: TYPE %s is not F, I or U", name, line, tok);
          f[k].type = tok[0];
        } else {
          char *e;
          long c = strtol(tok, &e, 10);
          if (*e || c < 1 || c > 1000000)
            return km__fail(err, KM_ERR_PARSE, "%s:%zu: bad COUNT %s", name, line, tok);
          f[k].count = (size_t)c;
        }
        ++k;
      }
      if (k != nf)
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: %s has %d entries, FIELDS has %d", name, line,
                        key, k, nf);
      if (key[0] == 'S')
        n_size = k;
      else if (key[0] == 'T')
        n_type = k;
      else
        n_count = k;
    } else if (!strcmp(key, "WIDTH") || !strcmp(key, "HEIGHT") || !strcmp(key, "POINTS")) {
      tok = strtok_r(NULL, " \t", &save);
      char *e;
      unsigned long long v = tok ? strtoull(tok, &e, 10) : 0;
      if (!tok || *e || tok[0] == '-')
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: %s needs a non-negative integer", name, line,
                        key);
      if (key[0] == 'W')
        width = (size_t)v, have_width = true;
      else if (key[0] == 'H')
        height = (size_t)v;
      else
        points = (size_t)v, have_points = true;
    } else if (!strcmp(key, "VIEWPOINT")) {
      continue; /* sensor pose: the points are kept in the file's frame */
    } else if (!strcmp(key, "DATA")) {
      tok = strtok_r(NULL, " \t", &save);
      snprintf(mode, sizeof mode, "%s", tok ? tok : "?");
    } else {
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: unknown PCD header keyword '%s'", name, line,
                      key);
    }
  }
  if (!mode[0]) return km__fail(err, KM_ERR_PARSE, "%s:%zu: header has no DATA line", name, line);
  if (!nf) return km__fail(err, KM_ERR_PARSE, "%s: header has no FIELDS", name);
  if (n_type != nf || n_size != nf)
    return km__fail(err, KM_ERR_PARSE, "%s: SIZE/TYPE must list all %d FIELDS", name, nf);
  (void)n_count;
  if (!have_points) {
    if (!have_width)
      return km__fail(err, KM_ERR_PARSE, "%s: header has neither POINTS nor WIDTH", name);
    if (height && width > SIZE_MAX / height)
      return km__fail(err, KM_ERR_PARSE, "%s: WIDTH*HEIGHT overflows", name);
    points = width * height;
  }
  int ix[3] = {-1, -1, -1};
  size_t rec = 0, cols = 0;
  for (int k = 0; k < nf; ++k) {
    if ((f[k].type == 'F' && f[k].size != 4 && f[k].size != 8))
      return km__fail(err, KM_ERR_PARSE, "%s: field %s: F needs SIZE 4 or 8", name, f[k].name);
    f[k].offset = rec;
    f[k].column = cols;
    if (f[k].count > SIZE_MAX / 64) return km__fail(err, KM_ERR_PARSE, "%s: bad COUNT", name);
    rec += (size_t)f[k].size * f[k].count;
    cols += f[k].count;
    for (int a = 0; a < 3; ++a)
      if (!strcmp(f[k].name, (const char *[]){"x", "y", "z"}[a])) ix[a] = k;
  }
  if (ix[0] < 0 || ix[1] < 0 || ix[2] < 0)
    return km__fail(err, KM_ERR_PARSE, "%s: FIELDS lacks one of x y z", name);
  size_t header_bytes = (size_t)(p - data);
  if (!strcmp(mode, "binary")) {
    if (rec && points > (size - header_bytes) / rec)
      return km__fail(err, KM_ERR_PARSE,
                      "%s: byte %zu: binary data holds %zu bytes, POINTS %zu needs %zu", name,
                      header_bytes, size - header_bytes, points, points * rec);
    out->P = km__malloc(points ? points : 1, 3 * sizeof(double));
    if (!out->P) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
    const unsigned char *b = (const unsigned char *)p;
    for (size_t i = 0; i < points; ++i, b += rec)
      push_point(out, pcd_value(b + f[ix[0]].offset, f[ix[0]].type, f[ix[0]].size),
                 pcd_value(b + f[ix[1]].offset, f[ix[1]].type, f[ix[1]].size),
                 pcd_value(b + f[ix[2]].offset, f[ix[2]].type, f[ix[2]].size));
    return KM_OK;
  }
  if (!strcmp(mode, "binary_compressed"))
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s:%zu: DATA binary_compressed (LZF) is not supported", name, line);
  if (strcmp(mode, "ascii"))
    return km__fail(err, KM_ERR_PARSE,
                    "%s:%zu: DATA '%s' is not ascii, binary or binary_compressed", name, line,
                    mode);
  /* ascii: a record needs at least 2 bytes per column, which bounds POINTS. */
  if (points > (size - header_bytes) / (2 * cols) + 1)
    return km__fail(err, KM_ERR_PARSE, "%s:%zu: POINTS %zu cannot fit in %zu bytes of data", name,
                    line + 1, points, size - header_bytes);
  out->P = km__malloc(points ? points : 1, 3 * sizeof(double));
  if (!out->P) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  size_t got = 0;
  while (got < points) {
    ++line;
    if (p >= end)
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: file ends after %zu of %zu points", name, line,
                      got, points);
    const char *eol = memchr(p, '\n', (size_t)(end - p));
    if (!eol) eol = end;
    double v[3] = {0, 0, 0};
    const char *c = p;
    for (size_t col = 0; col < cols; ++col) {
      while (c < eol && (*c == ' ' || *c == '\t' || *c == '\r'))
        ++c;
      if (c >= eol)
        return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected %zu values, found %zu", name, line,
                        cols, col);
      char tmp[64];
      size_t l = 0;
      while (c < eol && !isspace((unsigned char)*c) && l < sizeof tmp - 1)
        tmp[l++] = *c++;
      tmp[l] = '\0';
      for (int a = 0; a < 3; ++a) {
        if (col == f[ix[a]].column) {
          char *e;
          v[a] = strtod(tmp, &e);
          if (e == tmp || *e)
            return km__fail(err, KM_ERR_PARSE, "%s:%zu: '%s' is not a number (field %s)", name,
                            line, tmp, f[ix[a]].name);
        }
      }
    }
    push_point(out, v[0], v[1], v[2]);
    ++got;
    p = eol < end ? eol + 1 : end;
  }
  return KM_OK;
}

km_status km_points_parse(const void *data, size_t size, const char *name, km_points *out,
                          km_error *err) {
  if (!data || !name || !out)
    return km__fail(err, KM_ERR_INVALID, "km_points_parse: NULL argument");
  memset(out, 0, sizeof *out);
  char ext[16];
  km__extension(name, ext, sizeof ext);
  km_status s;
  if (!strcmp(ext, "ply"))
    s = parse_ply(data, size, name, out, err);
  else if (!strcmp(ext, "pcd"))
    s = parse_pcd(data, size, name, out, err);
  else if (!strcmp(ext, "xyz") || !strcmp(ext, "txt") || !strcmp(ext, "pts"))
    s = parse_xyz(data, size, name, out, err);
  else
    s = km__fail(err, KM_ERR_UNSUPPORTED, "%s: unknown point cloud extension '%s' (ply, pcd, xyz)",
                 name, ext);
  if (s) km_points_free(out);
  return s;
}

km_status km_points_read(const char *path, km_points *out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_points_read: NULL argument");
  char *data;
  size_t size;
  km_status s = km__read_file(path, &data, &size, err);
  if (s) return s;
  s = km_points_parse(data, size, path, out, err);
  free(data);
  return s;
}

km_status km_points_write_ply(const char *path, const double *P, size_t n, km_error *err) {
  if (!path || (!P && n))
    return km__fail(err, KM_ERR_INVALID, "km_points_write_ply: NULL argument");
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s) return s;
  fprintf(af.f,
          "ply\nformat binary_little_endian 1.0\ncomment kinemesh point cloud\nelement vertex %zu\n"
          "property float x\nproperty float y\nproperty float z\nend_header\n",
          n);
  float buf[3 * 1024];
  for (size_t i = 0; i < n; i += 1024) {
    size_t m = n - i < 1024 ? n - i : 1024;
    for (size_t k = 0; k < 3 * m; ++k)
      buf[k] = (float)P[3 * i + k];
    fwrite(buf, sizeof(float), 3 * m, af.f);
  }
  return km__atomic_commit(&af, err);
}

km_status km_point_frames_list(const char *pattern, char ***paths, size_t *n, km_error *err) {
  if (!pattern || !paths || !n)
    return km__fail(err, KM_ERR_INVALID, "km_point_frames_list: NULL argument");
  static const char *const exts[] = {"ply", "pcd", "xyz", "txt", "pts", NULL};
  km_status s = km__list_files(pattern, exts, false, paths, n, err);
  if (s != KM_OK) return s;
  if (!*n) {
    km_paths_free(paths, 0);
    return km__fail(err, KM_ERR_IO, "%s: no point cloud frames (.ply .pcd .xyz) found", pattern);
  }
  return KM_OK;
}
