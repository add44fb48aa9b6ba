/* kinemesh take JSON (see kinemesh.h): reading with cJSON, writing by hand so each frame is
 * one line and coordinates round-trip exactly (%.17g). A missing joint is written as three
 * nulls and read back as NaN. */
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

static km_status take_from_json(const char *path, const cJSON *root, km_take *t, km_error *err) {
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
  if (!cJSON_IsArray(frames) || nf == 0)
    return km__fail(err, KM_ERR_PARSE, "%s: \"frames\" must be a non-empty array", path);
  const cJSON *parents = cJSON_GetObjectItemCaseSensitive(root, "parents");
  if (parents && !cJSON_IsNull(parents) &&
      !(cJSON_IsArray(parents) && cJSON_GetArraySize(parents) == nj))
    return km__fail(err, KM_ERR_PARSE, "%s: \"parents\" must be an array of %d joint indices", path,
                    nj);

  t->n_joints = (size_t)nj;
  t->n_frames = (size_t)nf;
  t->fps = fps->valuedouble;
  t->joint_names = km__calloc((size_t)nj, sizeof *t->joint_names);
  t->positions = km__malloc((size_t)nf * (size_t)nj, 3 * sizeof *t->positions);
  if (cJSON_IsArray(parents)) t->parents = km__malloc((size_t)nj, sizeof *t->parents);
  if (!t->joint_names || !t->positions || (cJSON_IsArray(parents) && !t->parents))
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %d frames", path, nf);

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
      if (!cJSON_IsNumber(it) || it->valuedouble != floor(it->valuedouble) ||
          it->valuedouble < -1 || it->valuedouble >= j)
        return km__fail(err, KM_ERR_PARSE,
                        "%s: parents[%d] must be -1 or the index of an earlier joint (0..%d)", path,
                        j, j - 1);
      t->parents[j] = (int32_t)it->valuedouble;
      ++j;
    }
  }
  size_t f = 0, want = 3 * (size_t)nj;
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
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(text, size, &end, false);
  if (!root) {
    size_t at = end && end >= text && end <= text + size ? (size_t)(end - text) : 0;
    size_t line, col;
    line_col(text, at, &line, &col);
    free(text);
    return km__fail(err, KM_ERR_PARSE, "%s:%zu:%zu (byte %zu): invalid JSON", path, line, col, at);
  }
  free(text);
  s = take_from_json(path, root, out, err);
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
