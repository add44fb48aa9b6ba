/* Wavefront OBJ: `v` positions, `f` polygons (fan-triangulated), and `vt`/`vn` attached to
 * the vertices through the faces' v/vt/vn references (first reference wins at a seam: the
 * vertex order and count stay the `v` lines'); everything else that is a keyword is skipped. Parsed
 * in place from the memory buffer, one pass to count vertices (so that positive indices can be
 * range-checked and V allocated once), one pass to parse. */
#include "mesh/mesh.h"
#include "mesh/mesh_io.h"

#include <math.h>
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

/* One `i`, `i/t`, `i//n` or `i/t/n` reference; tn[0], tn[1]: the texture and normal
 * indices as written (0 when absent). */
static bool parse_face_ref(const char *tok, size_t len, int64_t *idx, int64_t tn[2]) {
  const char *slash = memchr(tok, '/', len);
  size_t ilen = slash ? (size_t)(slash - tok) : len;
  tn[0] = tn[1] = 0;
  if (!km__parse_int64(tok, ilen, idx)) return false;
  if (!slash) return true;
  /* Texture and normal parts: empty or integers, at most two of them. */
  const char *p = slash + 1, *end = tok + len;
  for (int part = 0; part < 2; ++part) {
    const char *q = memchr(p, '/', (size_t)(end - p));
    size_t plen = q ? (size_t)(q - p) : (size_t)(end - p);
    if (plen && !km__parse_int64(p, plen, &tn[part])) return false;
    if (part == 0 && plen == 0 && !q) return false; /* "i/" */
    if (!q) return true;
    if (part == 1) return false; /* a third slash */
    p = q + 1;
    if (p == end) return false; /* "i/t/" */
  }
  return true;
}

/* OBJ's line continuation (the spec's "\" at the end of a line: the statement goes on on the
 * next line, as exporters write long `f` lines). NULL when data has none (or out of memory:
 * *nomem); else a copy that keeps every byte offset, the backslash and any '\r' or blanks
 * after it spaces and the newline a vertical tab, which the tokenizer reads as a space and the
 * parser counts as a line, so that errors still name the file's own lines. A backslash
 * elsewhere (a Windows path in a `mtllib`) is left as it is. */
static char *join_continued(const char *data, size_t size, bool *nomem) {
  char *copy = NULL;
  *nomem = false;
  for (const char *p = data, *end = data + size; (p = memchr(p, '\\', (size_t)(end - p)));) {
    const char *q = p + 1;
    while (q < end && (*q == ' ' || *q == '\t' || *q == '\r'))
      ++q;
    if (q == end || *q != '\n') {
      p = q;
      continue;
    }
    if (!copy) {
      if (!(copy = malloc(size))) {
        *nomem = true;
        return NULL;
      }
      memcpy(copy, data, size);
    }
    memset(copy + (p - data), ' ', (size_t)(q - p));
    copy[q - data] = '\v';
    p = q + 1;
  }
  return copy;
}

static km_status obj_parse_joined(const char *data, size_t size, bool joined, const char *name,
                                  km_mesh *out, km_error *err);

km_status km__obj_parse(const char *data, size_t size, const char *name, km_mesh *out,
                        km_error *err) {
  bool nomem;
  char *joined = join_continued(data, size, &nomem);
  if (nomem) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", name);
  km_status s = obj_parse_joined(joined ? joined : data, size, joined != NULL, name, out, err);
  free(joined);
  return s;
}

static km_status obj_parse_joined(const char *data, size_t size, bool joined, const char *name,
                                  km_mesh *out, km_error *err) {
  const char *end = data + size;
  char q[64];

  /* Pass 1: count `v` lines and `f` lines. */
  size_t nv_total = 0, nf_lines = 0, nt_total = 0, nn_total = 0;
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
    } else if (le - p >= 2 && p[0] == 'v' && (p[1] == 't' || p[1] == 'n') &&
               (le - p == 2 || km__is_space(p[2]))) {
      ++*(p[1] == 't' ? &nt_total : &nn_total);
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

  /* Attributes: the file's vt/vn lists, then one per vertex (set = assigned by a face). */
  double *T = nt_total ? km__malloc(nt_total, 2 * sizeof(double)) : NULL;
  double *Nn = nn_total ? km__malloc(nn_total, 3 * sizeof(double)) : NULL;
  double *UV = nt_total ? km__calloc(nv_total, 2 * sizeof(double)) : NULL;
  double *NV = nn_total ? km__calloc(nv_total, 3 * sizeof(double)) : NULL;
  unsigned char *set = (nt_total || nn_total) ? km__calloc(nv_total, 1) : NULL;
  if ((nt_total && (!T || !UV)) || (nn_total && (!Nn || !NV)) || ((nt_total || nn_total) && !set)) {
    free(V), free(tris.F), free(T), free(Nn), free(UV), free(NV), free(set);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu vertices", name, nv_total);
  }
  bool any_t = false, any_n = false;
  size_t nt = 0, nn = 0, seams = 0;
  double *C = NULL, c_max = 0; /* vertex colours, the largest component */
  km_status s = KM_OK;
  size_t nv = 0, line = 0, continued = 0; /* the lines the last statement went on over */
  int32_t poly_buf[64];
  int32_t *poly = poly_buf;
  size_t poly_cap = 64;
  for (const char *p = data; p < end && !s;) {
    const char *nl = memchr(p, '\n', (size_t)(end - p));
    line_cursor c = {p, nl ? nl : end};
    p = nl ? nl + 1 : end;
    line += 1 + continued;
    continued = 0;
    for (const char *q = c.p; joined && (q = memchr(q, '\v', (size_t)(c.end - q))); ++q)
      ++continued;
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
      /* "v x y z r g b": a vertex colour (MeshLab's, ZBrush's and scanners' extension);
       * other extra numbers (w) are ignored */
      double rgb[3];
      int extra = 0;
      while (!s && extra < 4 && next_token(&c, &tok, &len) && tok[0] != '#') {
        if (extra < 3 && !km__parse_double(tok, len, &rgb[extra])) extra = 4;
        ++extra;
      }
      if (!s && extra == 3) {
        if (!C && (C = km__malloc(nv_total, 4 * sizeof(double))))
          for (size_t i = 0; i < 4 * nv_total; ++i)
            C[i] = i % 4 == 3 ? 1 : NAN; /* no colour yet (white, below) */
        if (!C) {
          s = km__fail(err, KM_ERR_NOMEM, "%s:%zu: out of memory", name, line);
          break;
        }
        memcpy(C + 4 * nv, rgb, sizeof rgb);
        for (int k = 0; k < 3; ++k)
          c_max = fmax(c_max, rgb[k]);
      }
      ++nv;
    } else if ((keyword_is(tok, len, "vt") && nt < nt_total) ||
               (keyword_is(tok, len, "vn") && nn < nn_total)) {
      bool is_t = tok[1] == 't';
      double *dst = is_t ? T + 2 * nt++ : Nn + 3 * nn++;
      int need = is_t ? 1 : 3, have = is_t ? 2 : 3;
      dst[0] = dst[1] = 0;
      if (!is_t) dst[2] = 0;
      for (int k = 0; k < have; ++k) {
        if (!next_token(&c, &tok, &len) || tok[0] == '#') {
          if (k >= need) break; /* vt u: v defaults to 0 */
          s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected %d numbers after '%s', found %d", name,
                       line, need, is_t ? "vt" : "vn", k);
          break;
        }
        if (!km__parse_double(tok, len, &dst[k])) {
          km__quote_token(tok, len, q, sizeof q);
          s = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected a finite number in '%s', found %s",
                       name, line, is_t ? "vt" : "vn", q);
          break;
        }
      }
    } else if (keyword_is(tok, len, "f")) {
      size_t n = 0;
      while (next_token(&c, &tok, &len) && tok[0] != '#') { /* a trailing comment ends it */
        int64_t idx, tn[2];
        if (!parse_face_ref(tok, len, &idx, tn)) {
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
        /* vt/vn references: 1-based, or negative relative to those read so far. */
        size_t ref[2] = {0, 0}; /* 1-based resolved, 0: none */
        for (int a = 0; a < 2 && !s; ++a) {
          size_t total = a ? nn_total : nt_total, sofar = a ? nn : nt;
          /* A file without any vt (vn) line: its references name nothing, and were always
           * read as plain positions; kept so. */
          if (!tn[a] || !total) continue;
          if (tn[a] > 0 && (uint64_t)tn[a] <= total)
            ref[a] = (size_t)tn[a];
          else if (tn[a] < 0 && (uint64_t)(-tn[a]) <= sofar)
            ref[a] = sofar + 1 - (size_t)(-tn[a]);
          else
            s = km__fail(err, KM_ERR_PARSE,
                         "%s:%zu: face %s index %lld out of range (expected 1..%zu, or -1..-%zu)",
                         name, line, a ? "normal" : "texture", (long long)tn[a], total, sofar);
        }
        if (s) break;
        size_t vi = (size_t)zero_based;
        if (ref[0]) {
          const double *t = T + 2 * (ref[0] - 1);
          if (!(set[vi] & 1)) {
            UV[2 * vi] = t[0], UV[2 * vi + 1] = t[1];
            set[vi] |= 1;
          } else if (UV[2 * vi] != t[0] || UV[2 * vi + 1] != t[1]) {
            ++seams;
          }
          any_t = true;
        }
        if (ref[1] && !(set[vi] & 2)) {
          memcpy(NV + 3 * vi, Nn + 3 * (ref[1] - 1), 3 * sizeof(double));
          set[vi] |= 2;
        }
        any_n |= ref[1] != 0;
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
  free(T), free(Nn), free(set);
  if (s) {
    free(V), free(tris.F), free(UV), free(NV), free(C);
    return s;
  }
  /* colours written 0..255 (some exporters) rather than 0..1 */
  for (size_t i = 0; C && c_max > 1 && i < nv; ++i)
    for (int k = 0; k < 3; ++k)
      C[4 * i + k] /= 255;
  for (size_t i = 0; C && i < 4 * nv; ++i) /* vertices without a colour: white */
    C[i] = isnan(C[i]) ? 1 : fmin(1, fmax(0, C[i]));
  out->colors = C;
  if (!any_t) free(UV), UV = NULL;
  if (!any_n) free(NV), NV = NULL;
  if (seams)
    km__log(KM_LOG_DEBUG,
            "%s: %zu face corners name another texture coordinate for a vertex that already has "
            "one (texture seams); the first is kept, vertex order stays the file's",
            name, seams);
  out->UV = UV;
  out->N = NV;
  out->V = V;
  out->F = tris.F;
  out->n_vertices = nv;
  out->n_faces = tris.n;
  return KM_OK;
}

/* One line of text starting at p (up to end): its first token (keyword) and the rest, both
 * trimmed; returns the start of the next line. */
static const char *next_line(const char *p, const char *end, char *kw, size_t kn, char *rest,
                             size_t rn) {
  const char *e = memchr(p, '\n', (size_t)(end - p));
  const char *le = e ? e : end, *q = p;
  while (q < le && (*q == ' ' || *q == '\t'))
    ++q;
  size_t k = 0;
  while (q < le && *q != ' ' && *q != '\t' && *q != '\r' && k + 1 < kn)
    kw[k++] = *q++;
  kw[k] = 0;
  while (q < le && (*q == ' ' || *q == '\t'))
    ++q;
  size_t r = 0;
  while (q < le && r + 1 < rn)
    rest[r++] = *q++;
  while (r && (rest[r - 1] == '\r' || rest[r - 1] == ' ' || rest[r - 1] == '\t'))
    --r;
  rest[r] = 0;
  return e ? e + 1 : end;
}

/* The file a map statement names (*bm, if not NULL: its -bm value, when given): its options
 * skipped (-o, -s and -t take one to three numbers,
 * -mm two, every other option one argument), then the rest of the line, spaces kept (Blender
 * writes "map_Kd my skin.png"). */
static const char *map_file(const char *rest, double *bm) {
  const char *p = rest;
  for (;;) {
    while (*p == ' ' || *p == '\t')
      ++p;
    if (*p != '-') return p;
    size_t ol = strcspn(p, " \t");
    if (bm && ol == 3 && !strncmp(p, "-bm", 3)) { /* the bump multiplier: a normal map's scale */
      const char *q = p + 3;
      while (*q == ' ' || *q == '\t')
        ++q;
      double x;
      if (km__parse_double(q, strcspn(q, " \t"), &x)) *bm = x;
    }
    int min = ol == 3 && !strncmp(p, "-mm", 3) ? 2 : 1;
    int max = ol == 2 && strchr("ost", p[1]) ? 3 : min;
    p += ol;
    for (int k = 0; k < max; ++k) {
      const char *q = p;
      while (*q == ' ' || *q == '\t')
        ++q;
      size_t tl = strcspn(q, " \t");
      double x;
      if (!tl || (k >= min && !km__parse_double(q, tl, &x))) break;
      p = q + tl;
    }
  }
}

/* One material of a .mtl: what km_mesh_material needs. */
typedef struct mtl_def {
  char name[1024];
  double kd[3], ns, d, pr, pm; /* pr, pm < 0: not given */
  bool d_given;                /* d wins over Tr */
  double ke[3], bm;            /* emissive factor; the normal map's -bm (0: none given) */
  char bump[1024], map_ke[1024];
  char map[1024];
} mtl_def;

/* The material name's definition in the library (NULL: not there). */
static const mtl_def *mtl_find(const mtl_def *t, size_t n, const char *name) {
  for (size_t i = 0; i < n; ++i)
    if (!strcmp(t[i].name, name)) return t + i;
  return NULL;
}

/* The image a map statement names (map: its file), read beside the library; a path from the
 * machine that wrote it (C:\\Users\\...\\skin.png, /home/...) is looked for by its name beside
 * the library, where the textures travel with it. PNG or JPEG, else left out with a warning. */
static void mtl_image(const char *map, const char *mpath, const char *path, km_mesh_image *out) {
  memset(out, 0, sizeof *out);
  char *ipath = km__path_beside(mpath, map), *img = NULL;
  size_t bytes = 0;
  bool read = ipath && km__read_file(ipath, &img, &bytes, NULL) == KM_OK;
  const char *base = map + strlen(map);
  while (base > map && base[-1] != '/' && base[-1] != '\\')
    --base;
  if (!read && ipath && base != map) {
    char *alt = km__path_beside(mpath, base);
    if (alt && km__read_file(alt, &img, &bytes, NULL) == KM_OK) {
      free(ipath);
      ipath = alt, alt = NULL, read = true;
    }
    free(alt);
  }
  if (read) {
    const char *mime = km__image_mime((const unsigned char *)img, bytes);
    if (mime) {
      out->bytes = (unsigned char *)img, img = NULL;
      out->size = bytes;
      snprintf(out->mime, sizeof out->mime, "%s", mime);
    } else {
      km__log(KM_LOG_WARN, "%s: texture %s is neither PNG nor JPEG: left out", path, ipath);
    }
  } else {
    km__log(KM_LOG_WARN, "%s: texture %s cannot be read: left out", path, ipath ? ipath : map);
  }
  free(img);
  free(ipath);
}

/* def (NULL: none, white) as a km_mesh_material over faces first .. first + n - 1; its maps'
 * images read relative to the library. */
static void mtl_material(const mtl_def *def, const char *mpath, const char *path, size_t first,
                         size_t n, km_mesh_material *m) {
  memset(m, 0, sizeof *m);
  m->first_face = first, m->n_faces = n;
  /* a texture is the colour (Blender's OBJ exporter writes Kd 0.8 beside it, which a factor
   * would darken it by); roughness from the Phong exponent as Blender's importer maps it */
  for (int c = 0; c < 3; ++c)
    m->base_color[c] = !def || def->map[0] ? 1 : fmin(1, fmax(0, def->kd[c]));
  m->base_color[3] = def ? fmin(1, fmax(0, def->d)) : 1;
  if (m->base_color[3] < 1) m->alpha_mode = KM_ALPHA_BLEND; /* a dissolved material shows through */
  m->metallic = def && def->pm >= 0 ? fmin(1, def->pm) : 0;
  m->roughness = def && def->pr >= 0   ? fmin(1, def->pr)
                 : def && def->ns >= 0 ? fmin(1, fmax(0, 1 - sqrt(fmin(def->ns, 1000) / 1000)))
                                       : 1;
  if (!def) return;
  for (int c = 0; c < 3; ++c)
    m->emissive[c] = fmax(0, def->ke[c]);
  m->normal_scale = def->bm;
  if (def->map[0]) {
    km_mesh_image im;
    mtl_image(def->map, mpath, path, &im);
    m->image = im.bytes, m->image_size = im.size;
    memcpy(m->image_mime, im.mime, sizeof m->image_mime);
  }
  if (def->bump[0]) mtl_image(def->bump, mpath, path, &m->maps[KM_MAP_NORMAL]);
  if (def->map_ke[0]) mtl_image(def->map_ke, mpath, path, &m->maps[KM_MAP_EMISSIVE]);
}

/* The libraries of an "mtllib a.mtl b.mtl" line (the specification's list; a name with a space
 * was tried whole first), each beside path, those that read, one after the other. NULL: none
 * read. */
static char *read_libraries(const char *path, const char *list, size_t *n) {
  char *all = NULL, name[1024];
  *n = 0;
  for (const char *p = list; *p;) {
    while (*p == ' ' || *p == '\t')
      ++p;
    size_t tl = strcspn(p, " \t");
    if (!tl) break;
    snprintf(name, sizeof name, "%.*s", (int)tl, p);
    p += tl;
    char *lp = km__path_beside(path, name), *data = NULL;
    size_t dn = 0;
    if (lp && km__read_file(lp, &data, &dn, NULL) == KM_OK) {
      char *t = realloc(all, *n + dn + 2);
      if (t) {
        all = t;
        memcpy(all + *n, data, dn);
        all[*n + dn] = '\n';
        *n += dn + 1;
        all[*n] = 0;
      }
    }
    free(data);
    free(lp);
  }
  return all;
}

void km__obj_read_material(const char *data, size_t size, const char *path, km_mesh *out) {
  char kw[32], rest[1024], lib[1024] = "";
  /* runs of triangles by the usemtl in force (a face of k corners is k - 2 triangles, as the
   * parser fans it) */
  typedef struct run {
    char name[1024];
    size_t first, n;
  } run;
  run *runs = NULL;
  size_t n_runs = 0, cap = 0, tri = 0;
  bool any_use = false;
  for (const char *p = data, *end = data + size; p < end;) {
    p = next_line(p, end, kw, sizeof kw, rest, sizeof rest);
    if (!strcmp(kw, "mtllib") && !lib[0]) snprintf(lib, sizeof lib, "%s", rest);
    bool use = !strcmp(kw, "usemtl"), face = !strcmp(kw, "f");
    if (!use && !face) continue;
    size_t k = 0;
    if (face)
      for (const char *q = rest; *q;) {
        while (*q == ' ' || *q == '\t')
          ++q;
        if (*q) ++k;
        while (*q && *q != ' ' && *q != '\t')
          ++q;
      }
    if (face && k < 3) continue;
    const char *name = use ? rest : n_runs ? runs[n_runs - 1].name : "";
    any_use |= use;
    if (!n_runs || strcmp(runs[n_runs - 1].name, name) != 0) {
      if (n_runs && !runs[n_runs - 1].n) --n_runs; /* a usemtl with no face after it */
      if (n_runs == cap) {
        run *r = realloc(runs, (cap = cap ? 2 * cap : 8) * sizeof *r);
        if (!r) {
          free(runs);
          return;
        }
        runs = r;
      }
      snprintf(runs[n_runs].name, sizeof runs[n_runs].name, "%s", name);
      runs[n_runs].first = tri, runs[n_runs++].n = 0;
    }
    if (face) runs[n_runs - 1].n += k - 2, tri += k - 2;
  }
  if (n_runs && !runs[n_runs - 1].n) --n_runs;
  if (!lib[0] || !any_use || !n_runs) {
    free(runs);
    return;
  }
  char *mpath = km__path_beside(path, lib), *mdata = NULL;
  size_t mn = 0;
  if (mpath && km__read_file(mpath, &mdata, &mn, NULL) != KM_OK && strchr(lib, ' '))
    mdata = read_libraries(path, lib, &mn); /* "mtllib a.mtl b.mtl": several */
  if (!mpath || !mdata) {
    km__log(KM_LOG_WARN, "%s: its material library %s cannot be read: no material carried", path,
            mpath ? mpath : lib);
    free(mpath);
    free(runs);
    return;
  }
  mtl_def *defs = NULL;
  size_t n_defs = 0, dcap = 0;
  for (const char *p = mdata, *end = mdata + mn; p < end;) {
    p = next_line(p, end, kw, sizeof kw, rest, sizeof rest);
    if (!strcmp(kw, "newmtl")) {
      if (n_defs == dcap) {
        mtl_def *t = realloc(defs, (dcap = dcap ? 2 * dcap : 8) * sizeof *t);
        if (!t) break;
        defs = t;
      }
      mtl_def *d = defs + n_defs++;
      memset(d, 0, sizeof *d);
      snprintf(d->name, sizeof d->name, "%s", rest);
      d->kd[0] = d->kd[1] = d->kd[2] = 1;
      d->d = 1;
      d->ns = d->pr = d->pm = -1;
    } else if (n_defs && !strcmp(kw, "Kd")) {
      double *kd = defs[n_defs - 1].kd;
      if (sscanf(rest, "%lf %lf %lf", &kd[0], &kd[1], &kd[2]) != 3) kd[0] = kd[1] = kd[2] = 1;
    } else if (n_defs && !strcmp(kw, "Ns")) {
      sscanf(rest, "%lf", &defs[n_defs - 1].ns);
    } else if (n_defs && !strcmp(kw, "d")) { /* dissolve: the alpha */
      if (sscanf(rest, "%lf", &defs[n_defs - 1].d) != 1) defs[n_defs - 1].d = 1;
      defs[n_defs - 1].d_given = true;
    } else if (n_defs && (!strcmp(kw, "Pr") || !strcmp(kw, "Pm"))) { /* the PBR extension */
      double x;
      if (sscanf(rest, "%lf", &x) == 1 && x >= 0)
        *(kw[1] == 'r' ? &defs[n_defs - 1].pr : &defs[n_defs - 1].pm) = x;
    } else if (n_defs && !strcmp(kw, "Tr") && !defs[n_defs - 1].d_given) { /* 1 - d */
      double x;
      if (sscanf(rest, "%lf", &x) == 1) defs[n_defs - 1].d = 1 - x;
    } else if (n_defs && !strcmp(kw, "map_Kd")) {
      snprintf(defs[n_defs - 1].map, sizeof defs[n_defs - 1].map, "%s", map_file(rest, NULL));
    } else if (n_defs && (!strcmp(kw, "map_Bump") || !strcmp(kw, "map_bump") ||
                          !strcmp(kw, "bump") || !strcmp(kw, "norm"))) {
      /* a normal map (Blender writes map_Bump; the PBR extension norm) */
      snprintf(defs[n_defs - 1].bump, sizeof defs[n_defs - 1].bump, "%s",
               map_file(rest, &defs[n_defs - 1].bm));
    } else if (n_defs && !strcmp(kw, "map_Ke")) {
      snprintf(defs[n_defs - 1].map_ke, sizeof defs[n_defs - 1].map_ke, "%s", map_file(rest, NULL));
    } else if (n_defs && !strcmp(kw, "Ke")) {
      double *ke = defs[n_defs - 1].ke;
      if (sscanf(rest, "%lf %lf %lf", &ke[0], &ke[1], &ke[2]) != 3) ke[0] = ke[1] = ke[2] = 0;
    }
  }
  free(mdata);
  if (tri != out->n_faces) { /* the parser saw other faces: one material over all */
    runs[0].first = 0, runs[0].n = out->n_faces, n_runs = 1;
    km__log(KM_LOG_WARN, "%s: its faces do not match its usemtl groups: one material carried",
            path);
  }
  bool any = false;
  for (size_t r = 0; r < n_runs; ++r) {
    if (runs[r].name[0] && !mtl_find(defs, n_defs, runs[r].name))
      km__log(KM_LOG_WARN, "%s: material '%s' is not in %s: white", path, runs[r].name, mpath);
    any |= mtl_find(defs, n_defs, runs[r].name) != NULL;
  }
  if (any && (out->materials = km__calloc(n_runs, sizeof *out->materials))) {
    out->n_materials = n_runs;
    for (size_t r = 0; r < n_runs; ++r)
      mtl_material(mtl_find(defs, n_defs, runs[r].name), mpath, path, runs[r].first, runs[r].n,
                   out->materials + r);
  }
  free(defs);
  free(runs);
  free(mpath);
}

static void write_double_digits(FILE *f, double x, char sep, int digits) {
  char buf[40];
  int n = km__format_double_digits(buf, sizeof buf - 1, x, digits);
  buf[n] = sep;
  fwrite(buf, 1, (size_t)n + 1, f);
}

static void write_double(FILE *f, double x, char sep) { write_double_digits(f, x, sep, 17); }

km_status km__obj_write(FILE *f, const km_mesh *m, const char *header, const char *mtllib,
                        bool float_normals) {
  fprintf(f, "# %s\n", header ? header : "kinemesh");
  bool mats = mtllib && m->n_materials;
  if (mats) fprintf(f, "mtllib %s\n", mtllib);
  for (size_t i = 0; i < m->n_vertices; ++i) {
    fputs("v ", f);
    write_double(f, m->V[3 * i], ' ');
    write_double(f, m->V[3 * i + 1], ' ');
    write_double(f, m->V[3 * i + 2], m->colors ? ' ' : '\n');
    if (m->colors) /* the vertex colour extension: r g b in 0..1 (alpha has no place) */
      for (int k = 0; k < 3; ++k)
        write_double(f, m->colors[4 * i + k], k < 2 ? ' ' : '\n');
  }
  /* One vt and one vn per vertex, in vertex order, so every face reference is i/i/i. */
  for (size_t i = 0; m->UV && i < m->n_vertices; ++i) {
    fputs("vt ", f);
    write_double(f, m->UV[2 * i], ' ');
    write_double(f, m->UV[2 * i + 1], '\n');
  }
  /* a frame's recomputed normals to a float's 9 digits: a smaller file than 17 would make */
  int nd = float_normals ? 9 : 17;
  for (size_t i = 0; m->N && i < m->n_vertices; ++i) {
    fputs("vn ", f);
    write_double_digits(f, m->N[3 * i], ' ', nd);
    write_double_digits(f, m->N[3 * i + 1], ' ', nd);
    write_double_digits(f, m->N[3 * i + 2], '\n', nd);
  }
  size_t run = 0; /* the material whose run the next face starts, or continues */
  for (size_t i = 0; i < m->n_faces; ++i) {
    for (; mats && run < m->n_materials && m->materials[run].first_face == i; ++run)
      if (m->materials[run].n_faces) fprintf(f, "usemtl kinemesh_%zu\n", run);
    fputc('f', f);
    for (int k = 0; k < 3; ++k) {
      int v = m->F[3 * i + k] + 1;
      if (m->UV && m->N)
        fprintf(f, " %d/%d/%d", v, v, v);
      else if (m->UV)
        fprintf(f, " %d/%d", v, v);
      else if (m->N)
        fprintf(f, " %d//%d", v, v);
      else
        fprintf(f, " %d", v);
    }
    fputc('\n', f);
  }
  return ferror(f) ? KM_ERR_IO : KM_OK;
}

km_mesh_image km__material_slot(const km_mesh_material *materials, size_t i) {
  const km_mesh_material *m = materials + i / KM__SLOTS;
  size_t s = i % KM__SLOTS;
  if (s > 0) return m->maps[s - 1];
  km_mesh_image im = {.bytes = m->image, .size = m->image_size, .sampler = m->image_sampler};
  memcpy(im.mime, m->image_mime, sizeof im.mime);
  return im;
}

void km__material_images_unique(const km_mesh_material *m, size_t n, int *uniq) {
  size_t ni = n * KM__SLOTS;
  for (size_t i = 0; i < ni; ++i) {
    uniq[i] = -1;
    km_mesh_image a = km__material_slot(m, i);
    if (!a.bytes || !a.size) continue;
    size_t j = 0;
    for (; j < i; ++j) {
      if (uniq[j] != (int)j) continue;
      km_mesh_image b = km__material_slot(m, j);
      if (b.size == a.size && !memcmp(b.bytes, a.bytes, a.size)) break;
    }
    uniq[i] = (int)j;
  }
}

bool km__obj_materials_cover(const km_mesh *m) {
  size_t next = 0;
  for (size_t k = 0; k < m->n_materials; ++k) {
    if (m->materials[k].first_face != next) return false;
    next += m->materials[k].n_faces;
  }
  return m->n_materials && next == m->n_faces;
}

void km__obj_texture_name(char *buf, size_t n, const char *prefix, int i, const char *mime) {
  snprintf(buf, n, "%s%d.%s", prefix, i, strcmp(mime, "image/jpeg") ? "png" : "jpg");
}

/* The .mtl statement of each texture slot (km__material_slot's s): the base colour, the normal
 * map (as Blender's importer takes map_Bump) and the emissive map; glTF's packed
 * metallic-roughness and occlusion maps have none. */
static const char *const k_mtl_map[KM__SLOTS] = {"map_Kd", NULL, "map_Bump", NULL, "map_Ke"};

/* Slot i (km__material_slot's numbering) has an .mtl statement. */
static bool obj_slot(size_t i) { return k_mtl_map[i % KM__SLOTS] != NULL; }

/* The image file an .mtl statement of slot i names: the first slot with a statement holding the
 * same bytes (km__material_images_unique's uniq), so an image shared only with a slot the .mtl
 * cannot name is still written once. */
static size_t obj_file_index(const int *uniq, size_t i) {
  size_t j = (size_t)uniq[i];
  while (!(obj_slot(j) && uniq[j] == uniq[i]))
    ++j;
  return j;
}

km_status km__obj_write_materials(const char *dir, const char *mtl_name, const char *tex_prefix,
                                  const km_mesh_material *m, size_t n, km_error *err) {
  size_t ni = n * KM__SLOTS;
  int *uniq = km__calloc(ni ? ni : 1, sizeof *uniq);
  size_t dn = strlen(dir), pn = dn + strlen(mtl_name) + strlen(tex_prefix) + 64;
  char *path = malloc(pn);
  if (!uniq || !path) {
    free(uniq), free(path);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for its materials", dir);
  }
  km__material_images_unique(m, n, uniq);
  km_status s = KM_OK;
  char tex[64 + 256];
  /* the images first: a library is only there once what it names is */
  for (size_t i = 0; i < ni && s == KM_OK; ++i) {
    /* what an OBJ library can say (k_mtl_map) */
    if (uniq[i] < 0 || !obj_slot(i) || obj_file_index(uniq, i) != i) continue;
    km_mesh_image im = km__material_slot(m, i);
    km__obj_texture_name(tex, sizeof tex, tex_prefix, (int)i, im.mime);
    snprintf(path, pn, "%s/%s", dir, tex);
    km__atomic_file af;
    if ((s = km__atomic_open(&af, path, err)) != KM_OK) break;
    fwrite(im.bytes, 1, im.size, af.f);
    s = km__atomic_commit(&af, err);
  }
  snprintf(path, pn, "%s/%s", dir, mtl_name);
  km__atomic_file af;
  if (s == KM_OK && (s = km__atomic_open(&af, path, err)) == KM_OK) {
    /* Kd the base colour (linear, as glTF's factor and as Blender's importer takes Kd), d its
     * alpha, Pr / Pm the PBR extension's roughness and metallic (what Blender's and most
     * engines' importers read), Ns the Phong exponent older readers take roughness from, Ke
     * the emissive factor; map_Kd, map_Bump (a tangent-space normal map, as Blender's importer
     * takes it, -bm its scale) and map_Ke the textures. */
    fputs("# kinemesh materials\n", af.f);
    for (size_t k = 0; k < n; ++k) {
      const km_mesh_material *q = m + k;
      fprintf(af.f, "\nnewmtl kinemesh_%zu\nKd ", k);
      for (int c = 0; c < 3; ++c)
        write_double(af.f, q->base_color[c], c < 2 ? ' ' : '\n');
      fputs("d ", af.f);
      write_double(af.f, q->base_color[3], '\n');
      fputs("Pr ", af.f);
      write_double(af.f, q->roughness, '\n');
      fputs("Pm ", af.f);
      write_double(af.f, q->metallic, '\n');
      fputs("Ns ", af.f);
      write_double(af.f, 1000 * (1 - q->roughness) * (1 - q->roughness), '\n');
      if (q->emissive[0] || q->emissive[1] || q->emissive[2]) {
        fputs("Ke ", af.f);
        for (int c = 0; c < 3; ++c)
          write_double(af.f, q->emissive[c], c < 2 ? ' ' : '\n');
      }
      for (int sl = 0; sl < KM__SLOTS; ++sl) {
        size_t i = k * KM__SLOTS + (size_t)sl;
        if (uniq[i] < 0 || !obj_slot(i)) continue;
        int u = (int)obj_file_index(uniq, i);
        km__obj_texture_name(tex, sizeof tex, tex_prefix, u, km__material_slot(m, (size_t)u).mime);
        fprintf(af.f, "%s ", k_mtl_map[sl]);
        if (sl == 1 + KM_MAP_NORMAL) {
          fputs("-bm ", af.f);
          write_double(af.f, q->normal_scale ? q->normal_scale : 1, ' ');
        }
        fprintf(af.f, "%s\n", tex);
      }
    }
    s = km__atomic_commit(&af, err);
  }
  free(uniq);
  free(path);
  return s;
}
