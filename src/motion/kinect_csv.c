/* Kinect v1 skeleton CSV reader (PRECOG dataset layout, see km_kinect_csv_read). */
#include "motion/motion.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *skip_blank(const char *p, const char *end) {
  while (p < end && (*p == ' ' || *p == '\t' || *p == '\r'))
    ++p;
  return p;
}

/* Parses one number that must start before `end` (the line end); strtod alone would skip
 * the newline and read the next line. */
static bool parse_number(const char **pp, const char *end, double *out) {
  const char *p = skip_blank(*pp, end);
  if (p >= end || *p == ';') return false;
  char *e = NULL;
  double v = strtod(p, &e);
  if (e == p || e > end || !isfinite(v)) return false;
  *out = v;
  *pp = e;
  return true;
}

static km_status parse_header(const char *path, const char *line, const char *end,
                              int *column_joint, km_error *err) {
  bool seen[KM_KINECT1_JOINTS] = {false};
  int col = 0;
  const char *p = line;
  for (;;) {
    const char *q = p;
    while (q < end && *q != ';')
      ++q;
    const char *a = skip_blank(p, q);
    const char *b = q;
    while (b > a && (b[-1] == ' ' || b[-1] == '\t' || b[-1] == '\r'))
      --b;
    char name[64];
    size_t len = (size_t)(b - a);
    if (len >= sizeof name) len = sizeof name - 1;
    memcpy(name, a, len);
    name[len] = '\0';
    if (col >= KM_KINECT1_JOINTS)
      return km__fail(err, KM_ERR_PARSE,
                      "%s:1: header has more than %d joint names (expected the 20 Kinect v1 "
                      "joints separated by ';')",
                      path, KM_KINECT1_JOINTS);
    int j = km_kinect1_joint_index(name);
    if (j < 0)
      return km__fail(err, KM_ERR_PARSE,
                      "%s:1: header column %d: '%s' is not a Kinect v1 joint name (expected "
                      "e.g. HipCenter; Spine; ShoulderCenter; Head; ...)",
                      path, col + 1, name);
    if (seen[j])
      return km__fail(err, KM_ERR_PARSE, "%s:1: header column %d: joint '%s' appears twice", path,
                      col + 1, name);
    seen[j] = true;
    column_joint[col++] = j;
    if (q >= end) break;
    p = q + 1;
  }
  if (col != KM_KINECT1_JOINTS)
    return km__fail(err, KM_ERR_PARSE,
                    "%s:1: header has %d joint names, expected the %d Kinect v1 joints", path, col,
                    KM_KINECT1_JOINTS);
  return KM_OK;
}

km_status km_kinect_csv_read(const char *path, km_take *out, int32_t **labels, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_kinect_csv_read: NULL argument");
  memset(out, 0, sizeof *out);
  if (labels) *labels = NULL;
  char *data = NULL;
  size_t size = 0;
  km_status st = km__read_file(path, &data, &size, err);
  if (st != KM_OK) return st;

  /* Upper bound on frames: the number of lines (the file size bounds the allocation). */
  size_t n_lines = 1;
  for (size_t i = 0; i < size; ++i)
    n_lines += data[i] == '\n';

  const char *p = data, *file_end = data + size;
  const char *eol = memchr(p, '\n', size);
  if (!eol) eol = file_end;
  int column_joint[KM_KINECT1_JOINTS];
  if (skip_blank(p, eol) == eol) {
    free(data);
    return km__fail(err, KM_ERR_PARSE,
                    "%s:1: expected a header of the 20 Kinect v1 joint names separated by ';'",
                    path);
  }
  st = parse_header(path, p, eol, column_joint, err);
  if (st != KM_OK) {
    free(data);
    return st;
  }

  double *pos = km__malloc(n_lines * KM_KINECT1_JOINTS * 3, sizeof(double));
  int32_t *lab = km__malloc(n_lines, sizeof(int32_t));
  char **names = km__calloc(KM_KINECT1_JOINTS, sizeof(char *));
  int32_t *parents = km__malloc(KM_KINECT1_JOINTS, sizeof(int32_t));
  if (!pos || !lab || !names || !parents) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto fail;
  }
  size_t frames = 0, line_no = 1;
  p = eol < file_end ? eol + 1 : file_end;
  while (p < file_end) {
    ++line_no;
    eol = memchr(p, '\n', (size_t)(file_end - p));
    if (!eol) eol = file_end;
    const char *q = p;
    if (skip_blank(q, eol) == eol) { /* blank line (e.g. a trailing newline) */
      p = eol + (eol < file_end);
      continue;
    }
    double *row = pos + frames * KM_KINECT1_JOINTS * 3;
    for (int c = 0; c < KM_KINECT1_JOINTS; ++c) {
      double v[3];
      for (int k = 0; k < 3; ++k) {
        if (!parse_number(&q, eol, &v[k])) {
          st = km__fail(err, KM_ERR_PARSE,
                        "%s:%zu: field %d (%s): expected 3 finite numbers \"x y z\", got %s", path,
                        line_no, c + 1, km_kinect1_joint_name(column_joint[c]),
                        k == 0 ? "none" : (k == 1 ? "1" : "2"));
          goto fail;
        }
      }
      q = skip_blank(q, eol);
      if (c + 1 < KM_KINECT1_JOINTS) {
        if (q >= eol) {
          st = km__fail(err, KM_ERR_PARSE,
                        "%s:%zu: the line ends after %d joints, expected 20 joints \"x y z\" "
                        "separated by ';' (then the action label)",
                        path, line_no, c + 1);
          goto fail;
        }
        if (*q != ';') {
          st = km__fail(err, KM_ERR_PARSE,
                        "%s:%zu: field %d (%s): expected ';' after 3 numbers (20 joints \"x y z\" "
                        "separated by ';', then the action label)",
                        path, line_no, c + 1, km_kinect1_joint_name(column_joint[c]));
          goto fail;
        }
        ++q;
      }
      double *dst = row + 3 * column_joint[c];
      if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0) {
        dst[0] = dst[1] = dst[2] = NAN; /* the SDK writes 0,0,0 for an untracked joint */
      } else {
        /* 180 degrees about y: the performer faces the camera (-z), characters face +z. */
        dst[0] = -v[0];
        dst[1] = v[1];
        dst[2] = -v[2];
      }
    }
    int32_t label = 0;
    if (q < eol && *q == ';') {
      ++q;
      q = skip_blank(q, eol);
      char *e = NULL;
      errno = 0;
      long l = (q < eol && *q != ';') ? strtol(q, &e, 10) : 0;
      if (!e || e == q || e > eol || errno || l < INT32_MIN || l > INT32_MAX) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s:%zu: field 21: expected an integer action label after the 20 joints",
                      path, line_no);
        goto fail;
      }
      label = (int32_t)l;
      q = e;
    }
    if (skip_blank(q, eol) != eol) {
      st = km__fail(err, KM_ERR_PARSE,
                    "%s:%zu: unexpected text after the %s (expected 20 joints and an optional "
                    "integer label)",
                    path, line_no, q < eol && q[-1] != ';' ? "last field" : "label");
      goto fail;
    }
    lab[frames++] = label;
    p = eol + (eol < file_end);
  }
  free(data);
  data = NULL;

  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    names[j] = km__strdup(km_kinect1_joint_name(j));
    if (!names[j]) {
      st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
      goto fail;
    }
    parents[j] = km_kinect1_joint_parent(j);
  }
  if (frames > 0 && frames < n_lines) {
    double *shrunk = realloc(pos, frames * KM_KINECT1_JOINTS * 3 * sizeof(double));
    if (shrunk) pos = shrunk;
  }
  out->n_frames = frames;
  out->n_joints = KM_KINECT1_JOINTS;
  out->fps = 30.0;
  out->joint_names = names;
  out->parents = parents;
  out->positions = pos;
  if (labels)
    *labels = lab;
  else
    free(lab);
  return KM_OK;

fail:
  free(data);
  free(pos);
  free(lab);
  if (names)
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      free(names[j]);
  free(names);
  free(parents);
  return st;
}
