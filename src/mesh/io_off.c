/* Geomview OFF (and COFF/NOFF/CNOFF, whose per-vertex extras are ignored). Read line by
 * line: one vertex or face per line, so trailing colours/normals need no declared layout. */
#include "mesh/mesh_io.h"

#include <stdlib.h>
#include <string.h>

typedef struct off_reader {
  const char *p, *end; /* remaining input */
  const char *lp, *le; /* current line */
  size_t line;
} off_reader;

/* Advances to the next line with content (skips blank lines and # comments). */
static bool next_line(off_reader *r) {
  while (r->p < r->end) {
    const char *nl = memchr(r->p, '\n', (size_t)(r->end - r->p));
    r->lp = r->p;
    r->le = nl ? nl : r->end;
    r->p = nl ? nl + 1 : r->end;
    ++r->line;
    const char *hash = memchr(r->lp, '#', (size_t)(r->le - r->lp));
    if (hash) r->le = hash;
    while (r->lp < r->le && km__is_space(*r->lp))
      ++r->lp;
    if (r->lp < r->le) return true;
  }
  return false;
}

static bool line_token(off_reader *r, const char **tok, size_t *len) {
  return km__token(&r->lp, r->le, tok, len);
}

km_status km__off_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err) {
  off_reader r = {data, data + size, NULL, NULL, 0};
  char q[64];
  const char *tok;
  size_t len;
  if (!next_line(&r) || !line_token(&r, &tok, &len))
    return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'OFF' header, found end of file", name,
                    r.line);
  if (!((len == 3 && !memcmp(tok, "OFF", 3)) || (len == 4 && !memcmp(tok, "COFF", 4)) ||
        (len == 4 && !memcmp(tok, "NOFF", 4)) || (len == 5 && !memcmp(tok, "CNOFF", 5)))) {
    /* The counts may directly follow a bare "OFF" on the same line, e.g. "OFF 8 12 0". */
    km__quote_token(tok, len, q, sizeof q);
    return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'OFF' (or COFF/NOFF/CNOFF), found %s",
                    name, r.line, q);
  }
  if (!line_token(&r, &tok, &len)) {
    if (!next_line(&r))
      return km__fail(err, KM_ERR_PARSE,
                      "%s:%zu: expected the counts line 'vertices faces "
                      "edges', found end of file",
                      name, r.line);
    line_token(&r, &tok, &len);
  }
  if (len == 6 && !memcmp(tok, "BINARY", 6))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: binary OFF is not supported", name, r.line);
  int64_t counts[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    if (k > 0 && !line_token(&r, &tok, &len)) {
      if (k == 2) break; /* the edge count is often omitted */
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected the counts 'vertices faces edges'", name,
                      r.line);
    }
    if (!km__parse_int64(tok, len, &counts[k]) || counts[k] < 0) {
      km__quote_token(tok, len, q, sizeof q);
      return km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a non-negative %s count, found %s", name,
                      r.line,
                      k == 0   ? "vertex"
                      : k == 1 ? "face"
                               : "edge",
                      q);
    }
  }
  /* Each vertex line holds at least 3 numbers and each face at least 4, every number taking a
   * character and a separator: bound the counts by the bytes left before allocating. */
  uint64_t left = (uint64_t)(r.end - r.p) + 1;
  uint64_t nv64 = (uint64_t)counts[0], nf64 = (uint64_t)counts[1];
  if (nv64 > left / 6 || nf64 > left / 8 || nv64 * 6 + nf64 * 8 > left)
    return km__fail(err, KM_ERR_PARSE,
                    "%s:%zu: counts %lld vertices, %lld faces cannot fit in the "
                    "%llu bytes left (file truncated or counts wrong)",
                    name, r.line, (long long)counts[0], (long long)counts[1],
                    (unsigned long long)(left - 1));
  if (nv64 > INT32_MAX)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s:%zu: %llu vertices exceed the int32 index range",
                    name, r.line, (unsigned long long)nv64);
  size_t nv = (size_t)nv64, nf = (size_t)nf64;
  double *V = km__malloc(nv ? nv * 3 : 1, sizeof(double));
  km__tris tris = {0};
  km_status s = KM_OK;
  if (!V || !km__tris_reserve(&tris, nf ? nf : 1)) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu vertices", name, nv);
    goto done;
  }
  for (size_t i = 0; i < nv && !s; ++i) {
    if (!next_line(&r)) {
      s = km__fail(err, KM_ERR_PARSE, "%s:%zu: unexpected end of file, expected vertex %zu of %zu",
                   name, r.line, i + 1, nv);
      break;
    }
    for (int k = 0; k < 3; ++k) {
      if (!line_token(&r, &tok, &len)) {
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 3 coordinates for vertex %zu, found %d",
                     name, r.line, i + 1, k);
        break;
      }
      if (!km__parse_double(tok, len, &V[3 * i + (size_t)k])) {
        km__quote_token(tok, len, q, sizeof q);
        s = km__fail(err, KM_ERR_PARSE,
                     "%s:%zu: expected a finite number for coordinate %c, "
                     "found %s",
                     name, r.line, "xyz"[k], q);
        break;
      }
    }
  }
  for (size_t i = 0; i < nf && !s; ++i) {
    if (!next_line(&r)) {
      s = km__fail(err, KM_ERR_PARSE, "%s:%zu: unexpected end of file, expected face %zu of %zu",
                   name, r.line, i + 1, nf);
      break;
    }
    int64_t n;
    line_token(&r, &tok, &len);
    if (!km__parse_int64(tok, len, &n) || n < 3) {
      km__quote_token(tok, len, q, sizeof q);
      s = km__fail(err, KM_ERR_PARSE,
                   "%s:%zu: expected a face vertex count of at least 3, found "
                   "%s",
                   name, r.line, q);
      break;
    }
    int32_t first = 0, prev = 0;
    for (int64_t j = 0; j < n; ++j) {
      int64_t idx;
      if (!line_token(&r, &tok, &len)) {
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected %lld vertex indices, found %lld", name,
                     r.line, (long long)n, (long long)j);
        break;
      }
      if (!km__parse_int64(tok, len, &idx) || idx < 0 || (uint64_t)idx >= nv) {
        km__quote_token(tok, len, q, sizeof q);
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a vertex index in 0..%zu, found %s", name,
                     r.line, nv ? nv - 1 : 0, q);
        break;
      }
      if (!km__tris_fan(&tris, (size_t)j, (int32_t)idx, &first, &prev)) {
        s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
        break;
      }
    }
    /* Anything after the indices (a face colour) is ignored. */
  }
done:
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

km_status km__off_write(FILE *f, const km_mesh *m) {
  fprintf(f, "OFF\n%zu %zu 0\n", m->n_vertices, m->n_faces);
  char buf[40];
  for (size_t i = 0; i < m->n_vertices; ++i)
    for (int k = 0; k < 3; ++k) {
      int n = km__format_double(buf, sizeof buf - 1, m->V[3 * i + (size_t)k]);
      buf[n] = k == 2 ? '\n' : ' ';
      fwrite(buf, 1, (size_t)n + 1, f);
    }
  for (size_t i = 0; i < m->n_faces; ++i)
    fprintf(f, "3 %d %d %d\n", m->F[3 * i], m->F[3 * i + 1], m->F[3 * i + 2]);
  return ferror(f) ? KM_ERR_IO : KM_OK;
}
