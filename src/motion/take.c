/* kinemesh take JSON (see kinemesh.h): reading with cJSON, except the "frames" array, which is
 * read straight from the text into the positions (issue 18: a cJSON tree costs about 64 bytes
 * a number, so a 20 MB take of short numbers took 920 MB; now the peak is the text, the
 * header's tree and the positions, a few times the file). Writing by hand so each frame is one
 * line and coordinates round-trip exactly (%.17g). A missing joint is written as three nulls
 * and read back as NaN. */
#include "core/core.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Line and column of byte `at` in text, for parse errors. */
static void line_col(const char *text, size_t at, size_t *line, size_t *col) {
  *line = 1;
  *col = 1;
  for (size_t i = 0; i < at && text[i]; ++i) {
    if (text[i] == '\n') {
      ++*line;
      *col = 1;
    } else {
      ++*col;
    }
  }
}

/* ---- the top-level "frames" value, found and read without a cJSON tree */

typedef struct scan {
  const char *s;
  size_t n, i;
} scan;
/* What cJSON skips as whitespace: every byte up to the space. */
static void skip_ws(scan *c) {
  while (c->i < c->n && (unsigned char)c->s[c->i] <= 32)
    ++c->i;
}
/* A string from its opening quote; false when unterminated. */
static bool skip_string(scan *c) {
  ++c->i;
  while (c->i < c->n) {
    char ch = c->s[c->i++];
    if (ch == '\\') {
      if (c->i >= c->n) return false;
      ++c->i;
    } else if (ch == '"') {
      return true;
    }
  }
  return false;
}
/* One value, loosely (brackets balanced outside strings; scalars end at ',' or '}'): only to
 * find where it ends. What it skips is checked by cJSON afterwards. */
static bool skip_value(scan *c) {
  int depth = 0;
  while (c->i < c->n) {
    char ch = c->s[c->i];
    if (ch == '"') {
      if (!skip_string(c)) return false;
      if (depth == 0) return true;
      continue;
    }
    if (ch == '[' || ch == '{') {
      ++depth;
    } else if (ch == ']' || ch == '}') {
      if (depth == 0) return true;
      if (--depth == 0) {
        ++c->i;
        return true;
      }
    } else if (ch == ',' && depth == 0) {
      return true;
    }
    ++c->i;
  }
  return depth == 0;
}
/* Whether the quoted key s[0..n) is "frames" (escapes decoded as cJSON does). */
static bool key_is_frames(const char *s, size_t n) {
  if (n == 8 && !memcmp(s, "\"frames\"", 8)) return true;
  if (!memchr(s, '\\', n)) return false;
  cJSON *k = cJSON_ParseWithLength(s, n);
  bool is = cJSON_IsString(k) && !strcmp(k->valuestring, "frames");
  cJSON_Delete(k);
  return is;
}
/* The first top-level "frames" member's value: text[*a, *b). False when the text is not an
 * object of members (cJSON then parses the whole text and says what is wrong). */
static bool find_frames(const char *text, size_t n, size_t *a, size_t *b) {
  scan c = {text, n, 0};
  if (n >= 3 && !memcmp(text, "\xEF\xBB\xBF", 3)) c.i = 3; /* cJSON skips a UTF-8 BOM */
  skip_ws(&c);
  if (c.i >= n || text[c.i] != '{') return false;
  ++c.i;
  for (;;) {
    skip_ws(&c);
    if (c.i >= n || text[c.i] != '"') return false;
    size_t k0 = c.i;
    if (!skip_string(&c)) return false;
    bool frames = key_is_frames(text + k0, c.i - k0);
    skip_ws(&c);
    if (c.i >= n || text[c.i] != ':') return false;
    ++c.i;
    skip_ws(&c);
    size_t v0 = c.i;
    if (!skip_value(&c)) return false;
    if (frames) {
      *a = v0;
      *b = c.i;
      return true;
    }
    skip_ws(&c);
    if (c.i >= n || text[c.i] != ',') return false;
    ++c.i;
  }
}

/* Reads the frames array text[a, b) strictly: '[' frames of `want` numbers or nulls ']'.
 * pos NULL: checks and counts (*nf); else fills pos (*nf frames, as counted before). Numbers
 * as cJSON reads them (starting with '-' or a digit, a run of [0-9+-.eE] that strtod takes
 * whole); non-finite refused. */
static km_status read_frames(const char *path, const char *text, size_t a, size_t b, size_t want,
                             char *const *names, double *pos, size_t *nf, km_error *err) {
  scan c = {text, b, a};
  size_t f = 0, at;
  char num[512];
#define FRAME_FAIL(...)                                                                            \
  do {                                                                                             \
    size_t line_, col_;                                                                            \
    line_col(text, at, &line_, &col_);                                                             \
    char what_[160];                                                                               \
    snprintf(what_, sizeof what_, __VA_ARGS__);                                                    \
    return km__fail(err, KM_ERR_PARSE, "%s:%zu:%zu (byte %zu): %s", path, line_, col_, at, what_); \
  } while (0)
  at = c.i;
  if (c.i >= b || text[c.i] != '[') FRAME_FAIL("\"frames\" must be a non-empty array");
  ++c.i;
  skip_ws(&c);
  at = c.i;
  if (c.i < b && text[c.i] == ']') FRAME_FAIL("\"frames\" must be a non-empty array");
  for (;;) {
    skip_ws(&c);
    at = c.i;
    if (c.i >= b || text[c.i] != '[') FRAME_FAIL("frame %zu is not an array", f);
    ++c.i;
    size_t k = 0;
    double *p = pos ? pos + f * want : NULL;
    skip_ws(&c);
    if (c.i < b && text[c.i] == ']') {
      ++c.i;
    } else {
      for (;;) {
        skip_ws(&c);
        at = c.i;
        double v;
        if (b - c.i >= 4 && !memcmp(text + c.i, "null", 4)) {
          v = NAN;
          c.i += 4;
        } else {
          size_t n = 0;
          while (c.i + n < b && n < sizeof num - 1 && strchr("0123456789+-.eE", text[c.i + n]) &&
                 text[c.i + n])
            ++n;
          memcpy(num, text + c.i, n);
          num[n] = 0;
          char *end = NULL;
          v = n ? strtod(num, &end) : 0;
          if (!n || end != num + n || !(num[0] == '-' || (num[0] >= '0' && num[0] <= '9')))
            FRAME_FAIL("frame %zu, value %zu%s%s%s is not a number or null", f, k,
                       k / 3 < want / 3 ? " (joint " : "", k / 3 < want / 3 ? names[k / 3] : "",
                       k / 3 < want / 3 ? ")" : "");
          if (!isfinite(v))
            FRAME_FAIL("frame %zu, value %zu%s%s%s is not finite (use null for a missing joint)", f,
                       k, k / 3 < want / 3 ? " (joint " : "", k / 3 < want / 3 ? names[k / 3] : "",
                       k / 3 < want / 3 ? ")" : "");
          c.i += n;
        }
        if (p && k < want) p[k] = v;
        ++k;
        skip_ws(&c);
        at = c.i;
        if (c.i < b && text[c.i] == ',') {
          ++c.i;
          continue;
        }
        if (c.i < b && text[c.i] == ']') {
          ++c.i;
          break;
        }
        FRAME_FAIL("frame %zu: expected ',' or ']' after value %zu", f, k - 1);
      }
    }
    if (k != want) FRAME_FAIL("frame %zu has %zu numbers, expected %zu", f, k, want);
    if (p) /* A joint is present or missing as a whole. */
      for (size_t q = 0; q < want / 3; ++q)
        if (isnan(p[3 * q]) || isnan(p[3 * q + 1]) || isnan(p[3 * q + 2]))
          p[3 * q] = p[3 * q + 1] = p[3 * q + 2] = NAN;
    ++f;
    if (pos && f == *nf) break;
    skip_ws(&c);
    at = c.i;
    if (c.i < b && text[c.i] == ',') {
      ++c.i;
      continue;
    }
    if (c.i < b && text[c.i] == ']') break;
    FRAME_FAIL("\"frames\": expected ',' or ']' after frame %zu", f - 1);
  }
#undef FRAME_FAIL
  if (!pos) *nf = f;
  return KM_OK;
}

/* frames_text: the file's text with the frames at [fa, fb) (the tree's "frames" is then a
 * placeholder), or NULL: the frames are in the tree. */
static km_status take_from_json(const char *path, const cJSON *root, const char *frames_text,
                                size_t fa, size_t fb, km_take *t, km_error *err) {
  if (!cJSON_IsObject(root))
    return km__fail(err, KM_ERR_PARSE, "%s: the top level is not a JSON object", path);
  const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(root, "format");
  if (!cJSON_IsString(fmt) || strcmp(fmt->valuestring, "kinemesh-take") != 0)
    return km__fail(err, KM_ERR_PARSE, "%s: \"format\" must be \"kinemesh-take\"", path);
  const cJSON *ver = cJSON_GetObjectItemCaseSensitive(root, "version");
  if (!cJSON_IsNumber(ver))
    return km__fail(err, KM_ERR_PARSE, "%s: \"version\" is missing or not a number", path);
  if (ver->valuedouble != 1)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: take version %g, this build reads version 1",
                    path, ver->valuedouble);
  const cJSON *fps = cJSON_GetObjectItemCaseSensitive(root, "fps");
  if (!cJSON_IsNumber(fps) || !(fps->valuedouble > 0) || !isfinite(fps->valuedouble))
    return km__fail(err, KM_ERR_PARSE, "%s: \"fps\" must be a positive number", path);
  const cJSON *units = cJSON_GetObjectItemCaseSensitive(root, "units");
  if (units && !(cJSON_IsString(units) && strcmp(units->valuestring, "m") == 0))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: \"units\" must be \"m\" (metres)", path);
  const cJSON *joints = cJSON_GetObjectItemCaseSensitive(root, "joints");
  int nj = cJSON_GetArraySize(joints);
  if (!cJSON_IsArray(joints) || nj == 0)
    return km__fail(err, KM_ERR_PARSE, "%s: \"joints\" must be a non-empty array of names", path);
  const cJSON *frames = cJSON_GetObjectItemCaseSensitive(root, "frames");
  int nf = cJSON_GetArraySize(frames);
  if (!frames_text && (!cJSON_IsArray(frames) || nf == 0))
    return km__fail(err, KM_ERR_PARSE, "%s: \"frames\" must be a non-empty array", path);
  const cJSON *parents = cJSON_GetObjectItemCaseSensitive(root, "parents");
  if (parents && !cJSON_IsNull(parents) &&
      !(cJSON_IsArray(parents) && cJSON_GetArraySize(parents) == nj))
    return km__fail(err, KM_ERR_PARSE, "%s: \"parents\" must be an array of %d joint indices", path,
                    nj);

  t->n_joints = (size_t)nj;
  t->fps = fps->valuedouble;
  t->joint_names = km__calloc((size_t)nj, sizeof *t->joint_names);
  if (cJSON_IsArray(parents)) t->parents = km__malloc((size_t)nj, sizeof *t->parents);
  if (!t->joint_names || (cJSON_IsArray(parents) && !t->parents))
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %d joints", path, nj);

  int j = 0;
  const cJSON *it;
  cJSON_ArrayForEach(it, joints) {
    if (!cJSON_IsString(it) || !it->valuestring[0])
      return km__fail(err, KM_ERR_PARSE, "%s: joints[%d] is not a non-empty string", path, j);
    size_t n = strlen(it->valuestring) + 1;
    if (!(t->joint_names[j] = malloc(n))) return km__fail(err, KM_ERR_NOMEM, "out of memory");
    memcpy(t->joint_names[j], it->valuestring, n);
    ++j;
  }
  if (t->parents) {
    j = 0;
    cJSON_ArrayForEach(it, parents) {
      /* Parents before children keeps every hierarchy walk a single forward pass. */
      int64_t pj;
      if (!cJSON_IsNumber(it) || !km__whole_number(it->valuedouble, -1, j - 1, &pj))
        return km__fail(err, KM_ERR_PARSE,
                        "%s: parents[%d] must be -1 or the index of an earlier joint (0..%d)", path,
                        j, j - 1);
      t->parents[j] = (int32_t)pj;
      ++j;
    }
  }
  size_t f = 0, want = 3 * (size_t)nj;
  if (frames_text) {
    /* Checked and counted first, so the positions are allocated once, at their size. */
    size_t n = 0;
    km_status s = read_frames(path, frames_text, fa, fb, want, t->joint_names, NULL, &n, err);
    if (s) return s;
    t->n_frames = n;
    t->positions = km__malloc(n, want * sizeof *t->positions);
    if (!t->positions)
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", path, n);
    return read_frames(path, frames_text, fa, fb, want, t->joint_names, t->positions, &n, err);
  }
  t->n_frames = (size_t)nf;
  t->positions = km__malloc((size_t)nf * (size_t)nj, 3 * sizeof *t->positions);
  if (!t->positions)
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %d frames", path, nf);
  cJSON_ArrayForEach(it, frames) {
    int n = cJSON_GetArraySize(it);
    if (!cJSON_IsArray(it))
      return km__fail(err, KM_ERR_PARSE, "%s: frame %zu is not an array", path, f);
    if ((size_t)n != want)
      return km__fail(err, KM_ERR_PARSE, "%s: frame %zu has %d numbers, expected %zu", path, f, n,
                      want);
    double *p = t->positions + f * want;
    size_t k = 0;
    const cJSON *v;
    cJSON_ArrayForEach(v, it) {
      if (cJSON_IsNumber(v) && !isfinite(v->valuedouble))
        return km__fail(err, KM_ERR_PARSE,
                        "%s: frame %zu, value %zu (joint %s) is not finite (use null for a "
                        "missing joint)",
                        path, f, k, t->joint_names[k / 3]);
      else if (cJSON_IsNumber(v))
        p[k] = v->valuedouble;
      else if (cJSON_IsNull(v))
        p[k] = NAN;
      else
        return km__fail(err, KM_ERR_PARSE,
                        "%s: frame %zu, value %zu (joint %s) is not a number or null", path, f, k,
                        t->joint_names[k / 3]);
      ++k;
    }
    /* A joint is present or missing as a whole. */
    for (size_t q = 0; q < (size_t)nj; ++q)
      if (isnan(p[3 * q]) || isnan(p[3 * q + 1]) || isnan(p[3 * q + 2]))
        p[3 * q] = p[3 * q + 1] = p[3 * q + 2] = NAN;
    ++f;
  }
  return KM_OK;
}

km_status km_take_read(const char *path, km_take *out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_take_read: NULL argument");
  memset(out, 0, sizeof *out);
  char *text = NULL;
  size_t size = 0;
  km_status s = km__read_file(path, &text, &size, err);
  if (s != KM_OK) return s;
  /* The header parsed by cJSON with "frames": [] in place of the frames, which read_frames
   * reads from the text. */
  size_t fa = 0, fb = 0;
  bool split = find_frames(text, size, &fa, &fb);
  char *head = text;
  size_t hsize = size;
  if (split) {
    hsize = size - (fb - fa) + 2;
    head = malloc(hsize + 1);
    if (!head) {
      free(text);
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    }
    memcpy(head, text, fa);
    memcpy(head + fa, "[]", 2);
    memcpy(head + fa + 2, text + fb, size - fb);
    head[hsize] = 0;
  }
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(head, hsize, &end, false);
  if (!root) {
    size_t at = end && end >= head && end <= head + hsize ? (size_t)(end - head) : 0;
    if (split && at >= fa + 2) at += (fb - fa) - 2; /* back to the file's bytes */
    size_t line, col;
    line_col(text, at, &line, &col);
    if (head != text) free(head);
    free(text);
    return km__fail(err, KM_ERR_PARSE, "%s:%zu:%zu (byte %zu): invalid JSON", path, line, col, at);
  }
  if (head != text) free(head);
  s = take_from_json(path, root, split ? text : NULL, fa, fb, out, err);
  free(text);
  cJSON_Delete(root);
  if (s != KM_OK) km_take_free(out);
  return s;
}

km_status km_take_write(const char *path, const km_take *t, km_error *err) {
  if (!path || !t) return km__fail(err, KM_ERR_INVALID, "km_take_write: NULL argument");
  if (t->n_joints == 0 || !t->joint_names || (t->n_frames && !t->positions))
    return km__fail(err, KM_ERR_INVALID, "%s: take has no joints or no positions", path);
  if (t->n_frames == 0) return km__fail(err, KM_ERR_INVALID, "%s: take has no frames", path);
  if (!(t->fps > 0) || !isfinite(t->fps))
    return km__fail(err, KM_ERR_INVALID, "%s: fps must be positive, got %g", path, t->fps);
  cJSON *names = cJSON_CreateArray();
  for (size_t j = 0; names && j < t->n_joints; ++j) {
    if (!t->joint_names[j] || !t->joint_names[j][0]) {
      cJSON_Delete(names);
      return km__fail(err, KM_ERR_INVALID, "%s: joint %zu has no name", path, j);
    }
    cJSON_AddItemToArray(names, cJSON_CreateString(t->joint_names[j]));
  }
  if (t->parents)
    for (size_t j = 0; j < t->n_joints; ++j)
      if (t->parents[j] < -1 || t->parents[j] >= (int32_t)j) {
        cJSON_Delete(names);
        return km__fail(err, KM_ERR_INVALID, "%s: parent of joint %zu is %ld, not an earlier joint",
                        path, j, (long)t->parents[j]);
      }
  char *names_json = names ? cJSON_PrintUnformatted(names) : NULL;
  cJSON_Delete(names);
  if (!names_json) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s != KM_OK) {
    free(names_json);
    return s;
  }
  FILE *f = af.f;
  fprintf(f, "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":%.17g,\"units\":\"m\",\n",
          t->fps);
  fprintf(f, "\"joints\":%s,\n", names_json);
  free(names_json);
  if (t->parents) {
    fputs("\"parents\":[", f);
    for (size_t j = 0; j < t->n_joints; ++j)
      fprintf(f, "%s%ld", j ? "," : "", (long)t->parents[j]);
    fputs("],\n", f);
  }
  fputs("\"frames\":[\n", f);
  for (size_t k = 0; k < t->n_frames; ++k) {
    const double *p = t->positions + k * t->n_joints * 3;
    fputc('[', f);
    for (size_t j = 0; j < t->n_joints; ++j) {
      const double *q = p + 3 * j;
      if (isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2]))
        fprintf(f, "%s%.17g,%.17g,%.17g", j ? "," : "", q[0], q[1], q[2]);
      else
        fprintf(f, "%snull,null,null", j ? "," : "");
    }
    fputs(k + 1 < t->n_frames ? "],\n" : "]\n", f);
  }
  fputs("]}\n", f);
  return km__atomic_commit(&af, err);
}
