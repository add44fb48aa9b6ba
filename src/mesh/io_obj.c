/* Wavefront OBJ: `v` positions and `f` polygons (fan-triangulated); everything else that is
 * a keyword is skipped. Parsed in place from the memory buffer, one pass to count vertices
 * (so that positive indices can be range-checked and V allocated once), one pass to parse. */
#include "mesh/mesh_io.h"

#include <stdlib.h>
#include <string.h>

typedef struct line_cursor {
  const char *p, *end; /* current position within the line */
} line_cursor;

/* Next whitespace-separated token of the line; false at the end of the line. */
static bool next_token(line_cursor *c, const char **tok, size_t *len) {
  return km__token(&c->p, c->end, tok, len);
}

static bool is_keyword_char(char ch) {
  return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
         ch == '_';
}

static bool keyword_is(const char *tok, size_t len, const char *kw) {
  size_t n = strlen(kw);
  return len == n && memcmp(tok, kw, n) == 0;
}

/* One `i`, `i/t`, `i//n` or `i/t/n` reference; only the position index is kept. */
static bool parse_face_ref(const char *tok, size_t len, int64_t *idx) {
  const char *slash = memchr(tok, '/', len);
  size_t ilen = slash ? (size_t)(slash - tok) : len;
  if (!km__parse_int64(tok, ilen, idx)) return false;
  if (!slash) return true;
  /* Texture and normal parts: empty or integers, at most two of them. */
  const char *p = slash + 1, *end = tok + len;
  for (int part = 0; part < 2; ++part) {
    const char *q = memchr(p, '/', (size_t)(end - p));
    size_t plen = q ? (size_t)(q - p) : (size_t)(end - p);
    int64_t dummy;
    if (plen && !km__parse_int64(p, plen, &dummy)) return false;
    if (part == 0 && plen == 0 && !q) return false; /* "i/" */
    if (!q) return true;
    if (part == 1) return false; /* a third slash */
    p = q + 1;
    if (p == end) return false; /* "i/t/" */
  }
  return true;
}

km_status km__obj_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err) {
  const char *end = data + size;
  char q[64];

  /* Pass 1: count `v` lines and `f` lines. */
  size_t nv_total = 0, nf_lines = 0;
  for (const char *p = data; p < end;) {
    const char *nl = memchr(p, '\n', (size_t)(end - p));
    const char *le = nl ? nl : end;
    while (p < le && km__is_space(*p))
      ++p;
    if (le - p >= 1 && (le - p == 1 || km__is_space(p[1]))) {
      if (p[0] == 'v')
        ++nv_total;
      else if (p[0] == 'f')
        ++nf_lines;
    }
    p = nl ? nl + 1 : end;
  }
  if (nv_total > INT32_MAX)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %zu vertices exceed the int32 index range", name,
                    nv_total);

  double *V = km__malloc(nv_total ? nv_total * 3 : 1, sizeof(double));
  km__tris tris = {0};
  if (!V || !km__tris_reserve(&tris, nf_lines ? nf_lines : 1)) {
    free(V);
    free(tris.F);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu vertices", name, nv_total);
  }

  km_status s = KM_OK;
  size_t nv = 0, line = 0;
  int32_t poly_buf[64];
  int32_t *poly = poly_buf;
  size_t poly_cap = 64;
  for (const char *p = data; p < end && !s;) {
    const char *nl = memchr(p, '\n', (size_t)(end - p));
    line_cursor c = {p, nl ? nl : end};
    p = nl ? nl + 1 : end;
    ++line;
    const char *tok;
    size_t len;
    if (!next_token(&c, &tok, &len) || tok[0] == '#') continue;
    if (keyword_is(tok, len, "v")) {
      if (nv >= nv_total) { /* pass 1 and pass 2 disagree only on malformed separators */
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: unexpected vertex line", name, line);
        break;
      }
      for (int k = 0; k < 3; ++k) {
        if (!next_token(&c, &tok, &len)) {
          s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 3 coordinates after 'v', found %d",
                       name, line, k);
          break;
        }
        if (!km__parse_double(tok, len, &V[nv * 3 + k])) {
          km__quote_token(tok, len, q, sizeof q);
          s = km__fail(err, KM_ERR_PARSE,
                       "%s:%zu: expected a finite number for coordinate %c, found %s", name, line,
                       "xyz"[k], q);
          break;
        }
      }
      ++nv; /* extra numbers (w, colours) are ignored */
    } else if (keyword_is(tok, len, "f")) {
      size_t n = 0;
      while (next_token(&c, &tok, &len) && tok[0] != '#') { /* a trailing comment ends it */
        int64_t idx;
        if (!parse_face_ref(tok, len, &idx)) {
          km__quote_token(tok, len, q, sizeof q);
          s = km__fail(err, KM_ERR_PARSE,
                       "%s:%zu: expected a face vertex 'i', 'i/t', 'i//n' or 'i/t/n', found %s",
                       name, line, q);
          break;
        }
        int64_t zero_based;
        if (idx > 0 && (uint64_t)idx <= nv_total)
          zero_based = idx - 1;
        else if (idx < 0 && (uint64_t)(-idx) <= nv)
          zero_based = (int64_t)nv + idx;
        else {
          s = km__fail(err, KM_ERR_PARSE,
                       "%s:%zu: face vertex index %lld out of range (expected 1..%zu, or -1..-%zu "
                       "relative to the %zu vertices read so far)",
                       name, line, (long long)idx, nv_total, nv, nv);
          break;
        }
        if (n == poly_cap) {
          size_t nc = poly_cap * 2;
          int32_t *np = km__malloc(nc, sizeof *np);
          if (!np) {
            s = km__fail(err, KM_ERR_NOMEM, "%s:%zu: out of memory", name, line);
            break;
          }
          memcpy(np, poly, n * sizeof *np);
          if (poly != poly_buf) free(poly);
          poly = np;
          poly_cap = nc;
        }
        poly[n++] = (int32_t)zero_based;
      }
      if (s) break;
      if (n < 3) {
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected at least 3 vertices in a face, found %zu",
                     name, line, n);
        break;
      }
      if (!km__tris_reserve(&tris, tris.n + n - 2)) {
        s = km__fail(err, KM_ERR_NOMEM, "%s:%zu: out of memory", name, line);
        break;
      }
      for (size_t i = 1; i + 1 < n; ++i) {
        int32_t *t = tris.F + 3 * tris.n++;
        t[0] = poly[0], t[1] = poly[i], t[2] = poly[i + 1];
      }
    } else {
      /* vt, vn, vp, o, g, s, usemtl, mtllib, l, p and other statements carry nothing we use;
       * a token that is not even a keyword means this is not an OBJ file. */
      for (size_t i = 0; i < len; ++i)
        if (!is_keyword_char(tok[i])) {
          km__quote_token(tok, len, q, sizeof q);
          s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected an OBJ statement keyword, found %s",
                       name, line, q);
          break;
        }
    }
  }
  if (poly != poly_buf) free(poly);
  if (!s && nv == 0)
    s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected at least one 'v' line, found none", name,
                 line);
  if (s) {
    free(V);
    free(tris.F);
    return s;
  }
  out->V = V;
  out->F = tris.F;
  out->n_vertices = nv;
  out->n_faces = tris.n;
  return KM_OK;
}

static void write_double(FILE *f, double x, char sep) {
  char buf[40];
  int n = km__format_double(buf, sizeof buf - 1, x);
  buf[n] = sep;
  fwrite(buf, 1, (size_t)n + 1, f);
}

km_status km__obj_write(FILE *f, const km_mesh *m) {
  fputs("# kinemesh\n", f);
  for (size_t i = 0; i < m->n_vertices; ++i) {
    fputs("v ", f);
    write_double(f, m->V[3 * i], ' ');
    write_double(f, m->V[3 * i + 1], ' ');
    write_double(f, m->V[3 * i + 2], '\n');
  }
  for (size_t i = 0; i < m->n_faces; ++i)
    fprintf(f, "f %d %d %d\n", m->F[3 * i] + 1, m->F[3 * i + 1] + 1, m->F[3 * i + 2] + 1);
  return ferror(f) ? KM_ERR_IO : KM_OK;
}
