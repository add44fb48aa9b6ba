/* STL: 3D-printing files and many scanners' output. Read binary and ASCII; written binary
 * (km__stl_write: a posed frame to print).
 *
 * An STL stores each triangle with its own three corner positions and no vertex list, so the
 * reader welds corners with exactly equal coordinates (bit for bit after -0 -> +0; ASCII
 * values compared after parsing, so "1" and "1.0" are one vertex) into one vertex. The
 * order is fixed by the file alone: vertex i is the i-th distinct position in facet order,
 * corners in the order written; face i is facet i (a facet whose corners weld together is
 * kept as a degenerate face, so facet and face numbers stay one to one). Facet normals and
 * the binary attribute bytes are ignored (normals are recomputed from the faces).
 *
 * Binary or ASCII: binary when the triangle count at byte 80 accounts for the file's size
 * (84 + 50 bytes per triangle, or up to 49 bytes more: padding, ignored with a warning),
 * whatever the 80-byte header says (several CAD exporters start a binary header with
 * "solid"); otherwise ASCII when its first 512 bytes hold no NUL (then it must start with
 * "solid", after an optional UTF-8 byte-order mark). Keywords are read case-insensitively; several
 * solids in one file are merged in order.
 *
 * admesh (Debian libadmesh-dev) was considered: it opens files by path only (we parse from
 * memory for fuzzing and the readers' shared error handling), reports errors with perror and
 * no position, takes a binary file for ASCII when bytes 84-211 are all below 128, and counts
 * ASCII facets as lines / 7; so the reader is written out, as the PLY reader is. */
#include "math/math.h"
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* -------------------------------------------------------------------- welding */

/* Welds nc corners (3 per facet, in facet order; P #nc x 3, taken over) into out: each
 * distinct position (km__coincident_lowest, after -0 -> +0 when stored) becomes a vertex, in
 * order of first appearance, and the corners' vertex ids are the faces. */
static km_status weld_corners(double *P, size_t nc, const char *name, km_mesh *out, km_error *err) {
  int32_t *F = km__malloc(nc ? nc : 1, sizeof *F);
  km_status s = F ? km__coincident_lowest(P, nc, NULL, F, err)
                  : km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu corners", name, nc);
  if (s) {
    free(F);
    free(P);
    return s;
  }
  /* F[c] is the first corner at c's position, so c >= F[c]; in one pass, a first corner's
   * position moves down to its vertex's slot (nv <= c) and every corner takes that id */
  size_t nv = 0;
  for (size_t c = 0; c < nc; ++c)
    if (F[c] == (int32_t)c) {
      memmove(P + 3 * nv, P + 3 * c, 3 * sizeof *P);
      F[c] = (int32_t)nv++;
    } else
      F[c] = F[F[c]];
  double *V = realloc(P, (nv ? nv : 1) * 3 * sizeof *P);
  out->V = V ? V : P;
  out->F = F;
  out->n_vertices = nv;
  out->n_faces = nc / 3;
  return KM_OK;
}

/* -------------------------------------------------------------------- binary */

/* d: a file of 84 + 50 n bytes at least, n the count at byte 80. */
static km_status parse_binary(const unsigned char *d, const char *name, km_mesh *out,
                              km_error *err) {
  size_t n = km__get_u32le(d + 80);
  if (n > INT32_MAX / 3)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: binary STL with %zu triangles exceeds the int32 index range", name, n);
  double *P = km__malloc(n ? 9 * n : 1, sizeof *P);
  if (!P) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu triangles", name, n);
  for (size_t t = 0; t < n; ++t) {
    const unsigned char *f = d + 84 + 50 * t + 12; /* past the facet normal */
    for (int k = 0; k < 9; ++k) {
      double x = km__get_f32le(f + 4 * k);
      if (!isfinite(x)) {
        int c = k / 3;
        km_status s =
            km__fail(err, KM_ERR_PARSE,
                     "%s: byte %zu: corner %d of triangle %zu is not a finite position (%g %g %g)",
                     name, (size_t)(f + 12 * c - d), c + 1, t + 1, km__get_f32le(f + 12 * c),
                     km__get_f32le(f + 12 * c + 4), km__get_f32le(f + 12 * c + 8));
        free(P);
        return s;
      }
      P[9 * t + (size_t)k] = x + 0.0; /* -0 + 0 = +0: one vertex for both zeros */
    }
  }
  return weld_corners(P, 3 * n, name, out, err);
}

/* -------------------------------------------------------------------- ASCII */

typedef struct stl_text {
  const char *p, *end;
  size_t line; /* 1-based line of p */
  const char *name;
  km_error *err;
} stl_text;

/* Next whitespace-separated token (newlines counted); false at the end. */
static bool next_token(stl_text *r, const char **tok, size_t *len) {
  while (r->p < r->end && (km__is_space(*r->p) || *r->p == '\n')) {
    if (*r->p == '\n') ++r->line;
    ++r->p;
  }
  if (r->p >= r->end) return false;
  *tok = r->p;
  while (r->p < r->end && !km__is_space(*r->p) && *r->p != '\n')
    ++r->p;
  *len = (size_t)(r->p - *tok);
  return true;
}

static bool is_word(const char *tok, size_t len, const char *word);

/* Skips a solid's name: the tokens after "solid" or "endsolid" on its line, up to a keyword
 * that starts the next statement (a file written on one line: "solid a facet normal ..."). */
static void skip_name(stl_text *r) {
  size_t line = r->line;
  for (;;) {
    const char *p = r->p, *tok;
    size_t len;
    if (!next_token(r, &tok, &len)) return;
    if (r->line != line || is_word(tok, len, "facet") || is_word(tok, len, "endsolid") ||
        is_word(tok, len, "solid")) {
      r->p = p; /* not part of the name: read it again */
      r->line = line;
      return;
    }
  }
}

static bool is_word(const char *tok, size_t len, const char *word) {
  size_t n = strlen(word);
  if (len != n) return false;
  for (size_t i = 0; i < n; ++i)
    if (tolower((unsigned char)tok[i]) != word[i]) return false;
  return true;
}

/* Reads the next token, which must be `word`; fails naming the line and what was found. */
static km_status expect(stl_text *r, const char *word, const char *context) {
  const char *tok;
  size_t len;
  if (!next_token(r, &tok, &len))
    return km__fail(r->err, KM_ERR_PARSE, "%s:%zu: expected '%s' %s, found end of file", r->name,
                    r->line, word, context);
  if (!is_word(tok, len, word)) {
    char q[64];
    km__quote_token(tok, len, q, sizeof q);
    return km__fail(r->err, KM_ERR_PARSE, "%s:%zu: expected '%s' %s, found %s", r->name, r->line,
                    word, context, q);
  }
  return KM_OK;
}

static km_status number(stl_text *r, double *x, char axis, const char *what) {
  const char *tok;
  size_t len;
  if (!next_token(r, &tok, &len))
    return km__fail(r->err, KM_ERR_PARSE, "%s:%zu: expected coordinate %c of %s, found end of file",
                    r->name, r->line, axis, what);
  if (!km__parse_double(tok, len, x)) {
    char q[64];
    km__quote_token(tok, len, q, sizeof q);
    return km__fail(r->err, KM_ERR_PARSE,
                    "%s:%zu: expected a finite number for coordinate %c of %s, found %s", r->name,
                    r->line, axis, what, q);
  }
  return KM_OK;
}

static km_status parse_ascii(const char *data, size_t size, const char *name, km_mesh *out,
                             km_error *err) {
  stl_text r = {data, data + size, 1, name, err};
  /* Every facet takes at least "facet normal 0 0 0 outer loop vertex 0 0 0 vertex 0 0 0 vertex
   * 0 0 0 endloop endfacet" (> 64 bytes): bound the corners by the size before allocating. */
  size_t max_facets = size / 64 + 1, nc = 0; /* corners read, 3 per facet */
  double *P = km__malloc(9 * max_facets, sizeof *P);
  if (!P) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu bytes of STL", name, size);
  km_status s = KM_OK;
  const char *tok;
  size_t len;
  size_t solids = 0;
  bool in_solid = false;
  while (!s) {
    if (!next_token(&r, &tok, &len)) {
      if (!solids)
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'solid', found end of file", name,
                     r.line);
      else if (in_solid) /* as Blender and most readers: the facets read are kept */
        km__log(KM_LOG_WARN, "%s:%zu: the file ends without 'endsolid' (truncated?)", name, r.line);
      break;
    }
    if (!in_solid) {
      if (!is_word(tok, len, "solid")) {
        char q[64];
        km__quote_token(tok, len, q, sizeof q);
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'solid'%s, found %s", name, r.line,
                     solids ? " or the end of the file" : " (an ASCII STL starts with it)", q);
        break;
      }
      skip_name(&r);
      in_solid = true;
      ++solids;
      continue;
    }
    if (is_word(tok, len, "endsolid")) {
      skip_name(&r);
      in_solid = false;
      continue;
    }
    if (!is_word(tok, len, "facet")) {
      char q[64];
      km__quote_token(tok, len, q, sizeof q);
      s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected 'facet' or 'endsolid', found %s", name,
                   r.line, q);
      break;
    }
    size_t facet = nc / 3 + 1;
    if (facet > max_facets) { /* cannot happen: the bound above */
      s = km__fail(err, KM_ERR_PARSE, "%s:%zu: more facets than the file's size allows", name,
                   r.line);
      break;
    }
    char what[64];
    if ((s = expect(&r, "normal", "after 'facet'"))) break;
    /* The normal is ignored, and may be anything an exporter writes for a degenerate facet
     * ("nan"): three tokens on the facet's line. */
    size_t line = r.line;
    for (int k = 0; k < 3 && !s; ++k)
      if (!next_token(&r, &tok, &len) || r.line != line)
        s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected the 3 numbers of facet %zu's normal",
                     name, line, facet);
    if (s) break;
    if ((s = expect(&r, "outer", "(a facet's 'outer loop')")) ||
        (s = expect(&r, "loop", "after 'outer'")))
      break;
    for (int k = 0; k < 3 && !s; ++k) {
      snprintf(what, sizeof what, "corner %d of facet %zu", k + 1, facet);
      double *x = P + 3 * (nc + (size_t)k);
      if ((s = expect(&r, "vertex", k ? "(a facet has 3 corners)" : "after 'outer loop'")) ||
          (s = number(&r, x, 'x', what)) || (s = number(&r, x + 1, 'y', what)) ||
          (s = number(&r, x + 2, 'z', what)))
        break;
      for (int a = 0; a < 3; ++a)
        x[a] += 0.0; /* -0 + 0 = +0: one vertex for both zeros */
    }
    if (s) break;
    if ((s = expect(&r, "endloop", "(an STL facet has exactly 3 corners)")) ||
        (s = expect(&r, "endfacet", "after 'endloop'")))
      break;
    nc += 3;
  }
  if (s) {
    free(P);
    return s;
  }
  return weld_corners(P, nc, name, out, err);
}

/* -------------------------------------------------------------------- dispatch */

km_status km__stl_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err) {
  const unsigned char *d = (const unsigned char *)data;
  if (size >= 84) {
    uint64_t n = km__get_u32le(d + 80);
    if (84 + 50 * n == size) return parse_binary(d, name, out, err);
    /* A few bytes past the last triangle (less than one: a writer's padding or a newline
     * appended in transfer) are ignored, as Blender's reader does, when the header is not
     * text: the count still accounts for the file. */
    if (n && size > 84 + 50 * n && size - (84 + 50 * n) < 50 && memchr(d, 0, 84)) {
      km__log(KM_LOG_WARN, "%s: %llu bytes after the last of its %llu triangles are ignored", name,
              (unsigned long long)(size - (84 + 50 * n)), (unsigned long long)n);
      return parse_binary(d, name, out, err);
    }
  }
  /* Not a consistent binary file: ASCII when its start holds no NUL byte (a binary header is
   * NUL-padded and a small count's high bytes are 0); the ASCII parser then says which line
   * is wrong, from "solid" on. */
  if (!memchr(d, 0, size < 512 ? size : 512)) {
    size_t i = size >= 3 && !memcmp(d, "\xef\xbb\xbf", 3) ? 3 : 0; /* a UTF-8 byte-order mark */
    return parse_ascii(data + i, size - i, name, out, err);
  }
  if (size < 84)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: not an STL file: %zu bytes, neither an ASCII STL (starting with "
                    "'solid') nor a binary one (an 80-byte header, a triangle count, 50 bytes "
                    "per triangle)",
                    name, size);
  uint64_t n = km__get_u32le(d + 80);
  uint64_t want = 84 + 50 * n;
  if (size < want)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: byte %zu: binary STL ends inside triangle %llu of %llu (the count at byte "
                    "80 needs %llu bytes, the file has %zu: truncated?)",
                    name, size, (unsigned long long)((size - 84) / 50 + 1), (unsigned long long)n,
                    (unsigned long long)want, size);
  return km__fail(err, KM_ERR_PARSE,
                  "%s: byte %llu: binary STL has %llu bytes after its %llu triangles (the count "
                  "at byte 80 says %llu, the size %zu bytes fits %zu): the count or the file is "
                  "wrong",
                  name, (unsigned long long)want, (unsigned long long)(size - want),
                  (unsigned long long)n, (unsigned long long)n, size, (size - 84) / 50);
}

/* -------------------------------------------------------------------- writer */

km_status km__stl_write(FILE *f, const km_mesh *m) {
  /* The header must not start with "solid": readers that go by the header alone would take
   * the file for ASCII. */
  unsigned char head[84] = {0};
  static const char title[] = "binary STL written by kinemesh";
  memcpy(head, title, sizeof title - 1);
  km__put_u32le(head + 80, (uint32_t)m->n_faces);
  fwrite(head, 1, sizeof head, f);
  for (size_t t = 0; t < m->n_faces; ++t) {
    const double *c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = m->V + 3 * (size_t)m->F[3 * t + (size_t)k];
    double e1[3], e2[3], n[3];
    km__sub3(c[1], c[0], e1);
    km__sub3(c[2], c[0], e2);
    km__cross3(e1, e2, n);
    double len = sqrt(km__dot3(n, n));
    unsigned char rec[50] = {0}; /* a degenerate facet's normal stays 0 0 0 */
    for (int k = 0; k < 3; ++k) {
      km__put_f32le(rec + 4 * k, (float)(len > 0 ? n[k] / len : 0)); /* STL's own type */
      for (int a = 0; a < 3; ++a)
        km__put_f32le(rec + 12 + 12 * k + 4 * a, (float)c[k][a]);
    }
    fwrite(rec, 1, sizeof rec, f);
  }
  return ferror(f) ? KM_ERR_IO : KM_OK;
}
