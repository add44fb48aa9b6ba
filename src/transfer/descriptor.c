/* Pose descriptor (eq. 4): angles between segments joining tracked landmarks; landmark files;
 * TRACK files. */
#include "transfer/pose.h"
#include "motion/motion.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

size_t km_pose_candidate_count(size_t n) { return n < 3 ? 0 : n * (n - 1) * (n - 2) / 2; }

void km_pose_candidate(size_t n, size_t f, int32_t triple[3]) {
  size_t per = (n - 1) * (n - 2) / 2;
  size_t j = f / per, r = f % per;
  /* r-th pair (i < k) of the indices other than j, in lexicographic order. */
  for (size_t a = 0; a < n - 1; ++a) {
    size_t cnt = n - 2 - a;
    if (r < cnt) {
      size_t i = a, k = a + 1 + r;
      if (i >= j) ++i;
      if (k >= j) ++k;
      triple[0] = (int32_t)i, triple[1] = (int32_t)j, triple[2] = (int32_t)k;
      return;
    }
    r -= cnt;
  }
  triple[0] = triple[1] = triple[2] = 0;
}

void km_pose_angles(const double *P, const int32_t *triples, size_t n_features, double *out) {
  for (size_t f = 0; f < n_features; ++f) {
    const double *a = P + 3 * (size_t)triples[3 * f], *o = P + 3 * (size_t)triples[3 * f + 1],
                 *b = P + 3 * (size_t)triples[3 * f + 2];
    double u[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]};
    double v[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
    double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    double lv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(lu > 0) || !(lv > 0) || !isfinite(lu * lv)) {
      out[f] = M_PI / 2;
      continue;
    }
    double c = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (lu * lv);
    out[f] = acos(c > 1 ? 1 : c < -1 ? -1 : c);
  }
}

km_status km__landmark_mirrors(const km_landmark *lm, size_t n, int32_t *m, km_error *err) {
  for (size_t i = 0; i < n; ++i) {
    m[i] = -1;
    for (size_t j = 0; j < n; ++j)
      if (strcmp(lm[i].mirror, lm[j].name) == 0) m[i] = (int32_t)j;
    if (m[i] < 0)
      return km__fail(err, KM_ERR_INVALID,
                      "landmark %zu (\"%s\") names mirror \"%s\", which is not a landmark", i,
                      lm[i].name, lm[i].mirror);
  }
  for (size_t i = 0; i < n; ++i)
    if (m[m[i]] != (int32_t)i)
      return km__fail(err, KM_ERR_INVALID,
                      "landmark \"%s\" mirrors \"%s\" but \"%s\" mirrors \"%s\"", lm[i].name,
                      lm[i].mirror, lm[m[i]].name, lm[m[i]].mirror);
  return KM_OK;
}

/* ---------------------------------------------------------------- landmark files */

/* The array itself is read and written by motion's landmark reader and writer (the rig
 * sidecar carries the same array); matching mirrors is this module's rule. */
km_status km_landmarks_read(const char *path, size_t n_vertices, km_landmark *out, size_t capacity,
                            size_t *n, km_error *err) {
  if (!path || !out || !n) return km__fail(err, KM_ERR_INVALID, "km_landmarks_read: NULL argument");
  *n = 0;
  char *data = NULL;
  size_t size = 0;
  km_status s = km__read_file(path, &data, &size, err);
  if (s) return s;
  size_t i = 0;
  s = km__landmarks_parse(path, data, size, n_vertices, out, capacity, &i, err);
  free(data);
  if (s) return s;
  int32_t m[KM_POSE_MAX_LANDMARKS];
  if (i <= KM_POSE_MAX_LANDMARKS) {
    s = km__landmark_mirrors(out, i, m, err);
    if (s) return km__wrap(err, KM_ERR_PARSE, "%s", path);
  }
  *n = i;
  return KM_OK;
}

km_status km_landmarks_write(const char *path, const km_landmark *lm, size_t n, km_error *err) {
  if (!path || (!lm && n))
    return km__fail(err, KM_ERR_INVALID, "km_landmarks_write: NULL argument");
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s) return s;
  fputs("{\"landmarks\":", af.f);
  km__landmarks_write_json(af.f, lm, n);
  fputs("}\n", af.f);
  return km__atomic_commit(&af, err);
}

/* ---------------------------------------------------------------- TRACK files */

void km_track_free(km_track *t) {
  if (!t) return;
  free(t->names);
  free(t->positions);
  memset(t, 0, sizeof *t);
}

static km_status track_json(const char *path, const char *data, size_t size, km_track *out,
                            km_error *err) {
  cJSON *root = cJSON_ParseWithLength(data, size);
  if (!root) {
    const char *e = cJSON_GetErrorPtr();
    size_t off = e && e >= data && e <= data + size ? (size_t)(e - data) : 0;
    return km__fail(err, KM_ERR_PARSE, "%s: byte %zu: not valid JSON", path, off);
  }
  km_status s = KM_OK;
  cJSON *fps = cJSON_GetObjectItemCaseSensitive(root, "fps");
  cJSON *names = cJSON_GetObjectItemCaseSensitive(root, "landmarks");
  cJSON *frames = cJSON_GetObjectItemCaseSensitive(root, "frames");
  if (!cJSON_IsArray(names) || !cJSON_IsArray(frames)) {
    s = km__fail(
        err, KM_ERR_PARSE,
        "%s: expected {\"fps\": number, \"landmarks\": [names], \"frames\": [[x,y,z,...]]}", path);
    goto done;
  }
  size_t nl = (size_t)cJSON_GetArraySize(names), nfr = (size_t)cJSON_GetArraySize(frames);
  if (nl < 1 || nl > 4096) {
    s = km__fail(err, KM_ERR_PARSE, "%s: %zu landmark names, expected 1..4096", path, nl);
    goto done;
  }
  out->fps = cJSON_IsNumber(fps) && fps->valuedouble > 0 ? fps->valuedouble : 30;
  out->n_landmarks = nl;
  out->n_frames = nfr;
  out->names = km__calloc(nl, sizeof *out->names);
  out->positions = km__malloc(nfr ? nfr * nl * 3 : 1, sizeof(double));
  if (!out->names || !out->positions) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto done;
  }
  size_t i = 0;
  cJSON *it;
  cJSON_ArrayForEach(it, names) {
    if (!cJSON_IsString(it) || strlen(it->valuestring) >= sizeof out->names[0]) {
      s = km__fail(err, KM_ERR_PARSE, "%s: landmarks[%zu]: expected a name of < 32 characters",
                   path, i);
      goto done;
    }
    strcpy(out->names[i++], it->valuestring);
  }
  size_t f = 0;
  cJSON_ArrayForEach(it, frames) {
    if (!cJSON_IsArray(it) || (size_t)cJSON_GetArraySize(it) != nl * 3) {
      s = km__fail(err, KM_ERR_PARSE, "%s: frames[%zu]: expected an array of %zu numbers", path, f,
                   nl * 3);
      goto done;
    }
    size_t c = 0;
    cJSON *x;
    cJSON_ArrayForEach(x, it) {
      if (cJSON_IsNumber(x))
        out->positions[f * nl * 3 + c] = x->valuedouble;
      else if (cJSON_IsNull(x))
        out->positions[f * nl * 3 + c] = NAN;
      else {
        s = km__fail(err, KM_ERR_PARSE, "%s: frames[%zu][%zu]: expected a number or null", path, f,
                     c);
        goto done;
      }
      ++c;
    }
    ++f;
  }
done:
  cJSON_Delete(root);
  return s;
}

static km_status track_csv(const char *path, const char *data, size_t size, km_track *out,
                           km_error *err) {
  const char *p = data, *end = data + size;
  /* Header: count fields. */
  const char *eol = memchr(p, '\n', (size_t)(end - p));
  if (!eol) eol = end;
  size_t nl = 1;
  for (const char *q = p; q < eol; ++q)
    if (*q == ',') ++nl;
  if (eol == p) return km__fail(err, KM_ERR_PARSE, "%s: line 1: expected landmark names", path);
  size_t lines = 0;
  for (const char *q = eol; q < end; ++q)
    if (*q == '\n') ++lines;
  out->fps = 30;
  out->n_landmarks = nl;
  out->names = km__calloc(nl, sizeof *out->names);
  out->positions = km__malloc((lines + 1) * nl * 3, sizeof(double));
  if (!out->names || !out->positions) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  size_t i = 0;
  const char *q = p;
  while (q <= eol && i < nl) {
    const char *c = q;
    while (c < eol && *c != ',')
      ++c;
    const char *a = q, *b = c;
    while (a < b && isspace((unsigned char)*a))
      ++a;
    while (b > a && isspace((unsigned char)b[-1]))
      --b;
    if (b - a == 0 || b - a >= 32)
      return km__fail(err, KM_ERR_PARSE,
                      "%s: line 1, field %zu: expected a name of 1..31 characters", path, i + 1);
    memcpy(out->names[i], a, (size_t)(b - a));
    ++i;
    q = c + 1;
  }
  size_t f = 0, line = 1;
  p = eol < end ? eol + 1 : end;
  while (p < end) {
    ++line;
    eol = memchr(p, '\n', (size_t)(end - p));
    if (!eol) eol = end;
    const char *a = p;
    while (a < eol && isspace((unsigned char)*a))
      ++a;
    if (a == eol) {
      p = eol + (eol < end);
      continue;
    }
    double *row = out->positions + f * nl * 3;
    size_t c = 0;
    const char *x = p;
    for (;;) {
      const char *fe = x;
      while (fe < eol && *fe != ',')
        ++fe;
      if (c >= nl * 3)
        return km__fail(err, KM_ERR_PARSE, "%s: line %zu: more than %zu numbers", path, line,
                        nl * 3);
      const char *s0 = x;
      while (s0 < fe && isspace((unsigned char)*s0))
        ++s0;
      const char *s1 = fe;
      while (s1 > s0 && isspace((unsigned char)s1[-1]))
        --s1;
      if (s1 == s0) {
        row[c] = NAN;
      } else {
        char buf[64];
        size_t len = (size_t)(s1 - s0);
        if (len >= sizeof buf)
          return km__fail(err, KM_ERR_PARSE, "%s: line %zu, field %zu: not a number", path, line,
                          c + 1);
        memcpy(buf, s0, len);
        buf[len] = 0;
        char *ep;
        errno = 0;
        row[c] = strtod(buf, &ep);
        if (*ep || errno == ERANGE)
          return km__fail(err, KM_ERR_PARSE, "%s: line %zu, field %zu: \"%s\" is not a number",
                          path, line, c + 1, buf);
      }
      ++c;
      if (fe >= eol) break;
      x = fe + 1;
    }
    if (c != nl * 3)
      return km__fail(err, KM_ERR_PARSE, "%s: line %zu: %zu numbers, expected %zu (3 per landmark)",
                      path, line, c, nl * 3);
    ++f;
    p = eol + (eol < end);
  }
  out->n_frames = f;
  return KM_OK;
}

km_status km_track_read(const char *path, km_track *out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_track_read: NULL argument");
  memset(out, 0, sizeof *out);
  char ext[16];
  km__extension(path, ext, sizeof ext);
  if (strcmp(ext, "json") && strcmp(ext, "csv"))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: a track must be .json or .csv", path);
  char *data = NULL;
  size_t size = 0;
  km_status s = km__read_file(path, &data, &size, err);
  if (s) return s;
  s = strcmp(ext, "json") == 0 ? track_json(path, data, size, out, err)
                               : track_csv(path, data, size, out, err);
  free(data);
  if (!s && out->n_frames == 0) s = km__fail(err, KM_ERR_PARSE, "%s: no frames", path);
  if (s) km_track_free(out);
  return s;
}

km_status km_track_write(const char *path, const km_track *t, km_error *err) {
  if (!path || !t || !t->names || (t->n_frames && !t->positions))
    return km__fail(err, KM_ERR_INVALID, "km_track_write: NULL argument");
  char ext[16];
  km__extension(path, ext, sizeof ext);
  bool csv = strcmp(ext, "csv") == 0;
  if (!csv && strcmp(ext, "json"))
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: a track must be .json or .csv", path);
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (s) return s;
  size_t nl = t->n_landmarks;
  if (csv) {
    for (size_t i = 0; i < nl; ++i)
      fprintf(af.f, "%s%s", i ? "," : "", t->names[i]);
    fputc('\n', af.f);
  } else {
    fprintf(af.f, "{\"fps\": %.17g, \"landmarks\": [", t->fps > 0 ? t->fps : 30);
    for (size_t i = 0; i < nl; ++i)
      fprintf(af.f, "%s\"%s\"", i ? ", " : "", t->names[i]);
    fprintf(af.f, "],\n\"frames\": [\n");
  }
  for (size_t f = 0; f < t->n_frames; ++f) {
    if (!csv) fputc('[', af.f);
    for (size_t c = 0; c < nl * 3; ++c) {
      double v = t->positions[f * nl * 3 + c];
      if (c) fputc(',', af.f);
      if (isfinite(v))
        fprintf(af.f, "%.17g", v);
      else if (!csv)
        fputs("null", af.f);
    }
    fputs(csv ? "\n" : (f + 1 < t->n_frames ? "],\n" : "]\n"), af.f);
  }
  if (!csv) fputs("]}\n", af.f);
  return km__atomic_commit(&af, err);
}
