/* BVH reader: hierarchy + motion to joint world positions (see km_bvh_read). */
#include "motion/motion.h"
#include "math/math.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BVH_MAX_DEPTH 256 /* nesting guard so a hostile file cannot overflow the stack */

enum { CH_XPOS, CH_YPOS, CH_ZPOS, CH_XROT, CH_YROT, CH_ZROT };

typedef struct bvh_joint {
  char *name;
  int32_t parent;
  bool end_site;
  double offset[3];
  int n_ch;
  int ch[6];
  size_t ch_start; /* first channel of this joint in a frame row */
} bvh_joint;

typedef struct bvh_parser {
  const char *path;
  const char *p, *end;
  size_t line;
  bvh_joint *joints;
  size_t n_joints, cap_joints;
  size_t n_channels;
  km_error *err;
} bvh_parser;

typedef struct token {
  const char *s;
  size_t n;
  size_t line;
} token;

static bool tok_is(const token *t, const char *word) {
  size_t n = strlen(word);
  return t->n == n && memcmp(t->s, word, n) == 0;
}

/* Next whitespace-separated token; '{' and '}' are tokens of their own. n == 0 at the end. */
static token next_token(bvh_parser *ps) {
  while (ps->p < ps->end && (*ps->p == ' ' || *ps->p == '\t' || *ps->p == '\r' || *ps->p == '\n' ||
                             *ps->p == '\f' || *ps->p == '\v')) {
    if (*ps->p == '\n') ++ps->line;
    ++ps->p;
  }
  token t = {ps->p, 0, ps->line};
  if (ps->p >= ps->end) return t;
  if (*ps->p == '{' || *ps->p == '}') {
    ++ps->p;
    t.n = 1;
    return t;
  }
  while (ps->p < ps->end && !strchr(" \t\r\n\f\v{}", *ps->p))
    ++ps->p;
  t.n = (size_t)(ps->p - t.s);
  return t;
}

static km_status fail_tok(bvh_parser *ps, const token *t, const char *expected) {
  if (t->n == 0)
    return km__fail(ps->err, KM_ERR_PARSE, "%s:%zu: expected %s, got the end of the file", ps->path,
                    t->line, expected);
  int n = t->n > 40 ? 40 : (int)t->n;
  return km__fail(ps->err, KM_ERR_PARSE, "%s:%zu: expected %s, got '%.*s'", ps->path, t->line,
                  expected, n, t->s);
}

static bool tok_number(const token *t, double *out) {
  char buf[64];
  if (t->n == 0 || t->n >= sizeof buf) return false;
  memcpy(buf, t->s, t->n);
  buf[t->n] = '\0';
  char *e = NULL;
  double v = strtod(buf, &e);
  if (*e != '\0' || !isfinite(v)) return false;
  *out = v;
  return true;
}

static km_status expect(bvh_parser *ps, const char *word) {
  token t = next_token(ps);
  if (!tok_is(&t, word)) {
    char what[64];
    snprintf(what, sizeof what, "'%s'", word);
    return fail_tok(ps, &t, what);
  }
  return KM_OK;
}

static int channel_id(const token *t) {
  static const char *const names[6] = {"Xposition", "Yposition", "Zposition",
                                       "Xrotation", "Yrotation", "Zrotation"};
  for (int c = 0; c < 6; ++c)
    if (tok_is(t, names[c])) return c;
  return -1;
}

static km_status parse_joint(bvh_parser *ps, int32_t parent, bool end_site, const token *name,
                             int depth) {
  if (depth > BVH_MAX_DEPTH)
    return km__fail(ps->err, KM_ERR_PARSE, "%s:%zu: hierarchy nested deeper than %d joints",
                    ps->path, name->line, BVH_MAX_DEPTH);
  if (ps->n_joints == ps->cap_joints) {
    size_t cap = ps->cap_joints ? ps->cap_joints * 2 : 64;
    bvh_joint *nj = realloc(ps->joints, cap * sizeof *nj);
    if (!nj) return km__fail(ps->err, KM_ERR_NOMEM, "%s: out of memory", ps->path);
    ps->joints = nj;
    ps->cap_joints = cap;
  }
  int32_t self = (int32_t)ps->n_joints;
  bvh_joint *j = &ps->joints[ps->n_joints++];
  memset(j, 0, sizeof *j);
  j->parent = parent;
  j->end_site = end_site;
  if (end_site) {
    const char *pn = ps->joints[parent].name;
    size_t n = strlen(pn) + 5;
    j->name = malloc(n);
    if (j->name) snprintf(j->name, n, "%s_End", pn);
  } else {
    j->name = malloc(name->n + 1);
    if (j->name) {
      memcpy(j->name, name->s, name->n);
      j->name[name->n] = '\0';
    }
  }
  if (!j->name) return km__fail(ps->err, KM_ERR_NOMEM, "%s: out of memory", ps->path);
  token t = next_token(ps);
  if (!tok_is(&t, "{")) return fail_tok(ps, &t, "'{' after the joint name");
  bool have_offset = false, have_channels = false;
  for (;;) {
    t = next_token(ps);
    j = &ps->joints[self]; /* children may have reallocated the array */
    if (tok_is(&t, "}")) break;
    if (tok_is(&t, "OFFSET")) {
      for (int k = 0; k < 3; ++k) {
        token v = next_token(ps);
        if (!tok_number(&v, &j->offset[k])) return fail_tok(ps, &v, "3 numbers after OFFSET");
      }
      have_offset = true;
    } else if (tok_is(&t, "CHANNELS") && !end_site) {
      if (have_channels) return fail_tok(ps, &t, "one CHANNELS line per joint");
      token v = next_token(ps);
      double n;
      if (!tok_number(&v, &n) || n != floor(n) || n < 0 || n > 6)
        return fail_tok(ps, &v, "a channel count 0..6 after CHANNELS");
      j->n_ch = (int)n;
      unsigned used = 0;
      for (int c = 0; c < j->n_ch; ++c) {
        token cn = next_token(ps);
        int id = channel_id(&cn);
        if (id < 0)
          return fail_tok(ps, &cn,
                          "a channel name (Xposition Yposition Zposition Xrotation "
                          "Yrotation Zrotation)");
        if (used & (1u << id)) return fail_tok(ps, &cn, "each channel at most once per joint");
        used |= 1u << id;
        j->ch[c] = id;
      }
      j->ch_start = ps->n_channels;
      ps->n_channels += (size_t)j->n_ch;
      have_channels = true;
    } else if (tok_is(&t, "JOINT") && !end_site) {
      token cn = next_token(ps);
      if (cn.n == 0 || tok_is(&cn, "{") || tok_is(&cn, "}"))
        return fail_tok(ps, &cn, "a joint name after JOINT");
      km_status st = parse_joint(ps, self, false, &cn, depth + 1);
      if (st != KM_OK) return st;
    } else if (tok_is(&t, "End") && !end_site) {
      token site = next_token(ps);
      if (!tok_is(&site, "Site")) return fail_tok(ps, &site, "'Site' after 'End'");
      km_status st = parse_joint(ps, self, true, &site, depth + 1);
      if (st != KM_OK) return st;
    } else {
      return fail_tok(ps, &t,
                      end_site ? "OFFSET or '}' in an End Site"
                               : "OFFSET, CHANNELS, JOINT, End Site or '}' in a joint");
    }
  }
  if (!have_offset)
    return km__fail(ps->err, KM_ERR_PARSE, "%s:%zu: joint '%s' has no OFFSET", ps->path, t.line,
                    ps->joints[self].name);
  return KM_OK;
}

/* Forward kinematics of one frame. row: this frame's channel values (NULL = rest pose, i.e.
 * offsets only). Rw/Pw: per joint world rotation and position (n_joints); scratch: local
 * rotations and offsets (n_joints*12), parents (n_joints). */
static void forward_kinematics(const bvh_joint *J, size_t n, const double *row, double scale,
                               double *scratch, int32_t *parents, double *Rw, double *Pw) {
  double *L = scratch, *o = scratch + 9 * n;
  for (size_t i = 0; i < n; ++i) {
    const bvh_joint *j = &J[i];
    double *t = o + 3 * i, *R = L + 9 * i;
    memcpy(t, j->offset, 3 * sizeof *t);
    km__m3_identity(R);
    if (row) {
      for (int c = 0; c < j->n_ch; ++c) {
        double v = row[j->ch_start + (size_t)c];
        int id = j->ch[c];
        if (id <= CH_ZPOS) {
          t[id] = v; /* position channels replace the offset component */
        } else {
          double A[9];
          km__m3_axis(id - CH_XROT, v * (M_PI / 180.0), A);
          km__m3_mul(R, A, R); /* intrinsic: later channels rotate in the already-rotated frame */
        }
      }
    }
    for (int k = 0; k < 3; ++k)
      t[k] *= scale;
    parents[i] = j->parent;
  }
  km__forward_kinematics(n, parents, L, o, Rw, Pw);
}

static void free_joints(bvh_parser *ps) {
  for (size_t i = 0; i < ps->n_joints; ++i)
    free(ps->joints[i].name);
  free(ps->joints);
  ps->joints = NULL;
  ps->n_joints = 0;
}

/* The CMU mocap skeleton (ASF-derived names, as in the cgspeed BVH conversions), whose units
 * are known exactly. */
static bool looks_like_cmu(const bvh_parser *ps) {
  int found = 0;
  for (size_t i = 0; i < ps->n_joints; ++i)
    if (ps->joints[i].name && (strcmp(ps->joints[i].name, "LHipJoint") == 0 ||
                               strcmp(ps->joints[i].name, "RHipJoint") == 0 ||
                               strcmp(ps->joints[i].name, "lowerback") == 0))
      ++found;
  return found == 3;
}

/* The rest of the current line must be blank; moves to the next line. */
static const char *next_line(const char *p, const char *end) {
  const char *e = memchr(p, '\n', (size_t)(end - p));
  return e ? e + 1 : end;
}

km_status km_bvh_read(const char *path, const km_bvh_options *opt, km_take *out, km_bvh_info *info,
                      km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_bvh_read: NULL argument");
  memset(out, 0, sizeof *out);
  km_bvh_options o = opt ? *opt : (km_bvh_options){0};
  if (!(o.units_to_m >= 0) || !isfinite(o.units_to_m))
    return km__fail(err, KM_ERR_INVALID, "%s: units_to_m must be >= 0 (0: auto), got %g", path,
                    o.units_to_m);
  char *data = NULL;
  size_t size = 0;
  km_status st = km__read_file(path, &data, &size, err);
  if (st != KM_OK) return st;
  bvh_parser ps = {.path = path, .p = data, .end = data + size, .line = 1, .err = err};
  double *Rw = NULL, *Pw = NULL, *fk = NULL, *row = NULL, *positions = NULL;
  int32_t *fk_parents = NULL;
  char **names = NULL;
  int32_t *parents = NULL, *out_index = NULL;
  size_t n_out = 0;

  if ((st = expect(&ps, "HIERARCHY")) != KM_OK) goto done;
  token t = next_token(&ps);
  if (!tok_is(&t, "ROOT")) {
    st = fail_tok(&ps, &t, "ROOT");
    goto done;
  }
  while (tok_is(&t, "ROOT")) {
    token name = next_token(&ps);
    if (name.n == 0 || tok_is(&name, "{")) {
      st = fail_tok(&ps, &name, "a joint name after ROOT");
      goto done;
    }
    if ((st = parse_joint(&ps, -1, false, &name, 0)) != KM_OK) goto done;
    t = next_token(&ps);
  }
  if (!tok_is(&t, "MOTION")) {
    st = fail_tok(&ps, &t, "MOTION (or another ROOT) after the hierarchy");
    goto done;
  }
  if (ps.n_channels == 0) {
    st = km__fail(err, KM_ERR_PARSE, "%s: the hierarchy declares no CHANNELS", path);
    goto done;
  }
  /* Joint names must be unique: rigs refer to joints by name. */
  for (size_t a = 0; a < ps.n_joints; ++a) {
    if (ps.joints[a].end_site) continue;
    for (size_t b = 0; b < a; ++b)
      if (!ps.joints[b].end_site && strcmp(ps.joints[a].name, ps.joints[b].name) == 0) {
        st = km__fail(err, KM_ERR_PARSE, "%s: joint name '%s' is used twice", path,
                      ps.joints[a].name);
        goto done;
      }
  }

  t = next_token(&ps);
  if (tok_is(&t, "Frames")) {
    if ((st = expect(&ps, ":")) != KM_OK) goto done;
  } else if (!tok_is(&t, "Frames:")) {
    st = fail_tok(&ps, &t, "'Frames:'");
    goto done;
  }
  token fn = next_token(&ps);
  double frames_d;
  if (!tok_number(&fn, &frames_d) || frames_d < 0 || frames_d != floor(frames_d) ||
      frames_d > 1e12) {
    st = fail_tok(&ps, &fn, "a frame count after 'Frames:'");
    goto done;
  }
  size_t n_frames = (size_t)frames_d;
  if ((st = expect(&ps, "Frame")) != KM_OK) goto done;
  t = next_token(&ps);
  if (tok_is(&t, "Time")) {
    if ((st = expect(&ps, ":")) != KM_OK) goto done;
  } else if (!tok_is(&t, "Time:")) {
    st = fail_tok(&ps, &t, "'Time:' after 'Frame'");
    goto done;
  }
  token ft = next_token(&ps);
  double frame_time;
  if (!tok_number(&ft, &frame_time) || !(frame_time > 0)) {
    st = fail_tok(&ps, &ft, "a positive frame time in seconds after 'Frame Time:'");
    goto done;
  }
  /* Each value takes at least two bytes ("0 "), which bounds the allocation by the file. */
  size_t remaining = (size_t)(ps.end - ps.p);
  if (n_frames > remaining / 2 / ps.n_channels + 1) {
    st = km__fail(err, KM_ERR_PARSE,
                  "%s:%zu: 'Frames: %zu' needs %zu values per frame, more than the %zu bytes "
                  "left in the file can hold",
                  path, fn.line, n_frames, ps.n_channels, remaining);
    goto done;
  }

  /* Units from the rest pose (offsets only). */
  Rw = km__malloc(ps.n_joints, 9 * sizeof(double));
  Pw = km__malloc(ps.n_joints, 3 * sizeof(double));
  fk = km__malloc(ps.n_joints, 12 * sizeof(double));
  fk_parents = km__malloc(ps.n_joints, sizeof(int32_t));
  row = km__malloc(ps.n_channels, sizeof(double));
  out_index = km__malloc(ps.n_joints, sizeof(int32_t));
  if (!Rw || !Pw || !fk || !fk_parents || !row || !out_index) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto done;
  }
  forward_kinematics(ps.joints, ps.n_joints, NULL, 1.0, fk, fk_parents, Rw, Pw);
  double ymin = INFINITY, ymax = -INFINITY;
  for (size_t i = 0; i < ps.n_joints; ++i) {
    ymin = fmin(ymin, Pw[3 * i + 1]);
    ymax = fmax(ymax, Pw[3 * i + 1]);
  }
  double h = ymax - ymin, scale = o.units_to_m;
  if (scale == 0) {
    if (h >= 1.0 && h <= 2.5)
      scale = 1.0;
    else if (h >= 100 && h <= 250)
      scale = 0.01;
    else if (looks_like_cmu(&ps))
      scale = KM_BVH_CMU_UNITS;
    else if (h > 0)
      scale = 1.7 / h;
    else
      scale = 1.0; /* flat skeleton: nothing to infer from */
  }

  for (size_t i = 0; i < ps.n_joints; ++i)
    out_index[i] = (!ps.joints[i].end_site || o.end_sites) ? (int32_t)n_out++ : -1;
  names = km__calloc(n_out, sizeof(char *));
  parents = km__malloc(n_out, sizeof(int32_t));
  positions = km__malloc(n_frames * n_out, 3 * sizeof(double));
  if (!names || !parents || (!positions && n_frames > 0)) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory (%zu frames x %zu joints)", path, n_frames,
                  n_out);
    goto done;
  }
  for (size_t i = 0; i < ps.n_joints; ++i) {
    int32_t k = out_index[i];
    if (k < 0) continue;
    names[k] = ps.joints[i].name;
    ps.joints[i].name = NULL; /* ownership moves to the take */
    parents[k] = ps.joints[i].parent < 0 ? -1 : out_index[ps.joints[i].parent];
  }

  /* Frames: one line each, exactly n_channels numbers. */
  const char *p = next_line(ps.p, ps.end);
  {
    const char *rest = ps.p;
    while (rest < p && (*rest == ' ' || *rest == '\t' || *rest == '\r' || *rest == '\n'))
      ++rest;
    if (rest < p) {
      st = km__fail(err, KM_ERR_PARSE, "%s:%zu: expected the end of the line after the frame time",
                    path, ft.line);
      goto done;
    }
  }
  size_t line = ft.line + 1, f = 0;
  for (; p < ps.end; ++line) {
    const char *eol = memchr(p, '\n', (size_t)(ps.end - p));
    if (!eol) eol = ps.end;
    const char *q = p;
    size_t c = 0;
    for (;;) {
      while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r'))
        ++q;
      if (q >= eol) break;
      if (f >= n_frames) {
        st = km__fail(err, KM_ERR_PARSE, "%s:%zu: more frame lines than 'Frames: %zu'", path, line,
                      n_frames);
        goto done;
      }
      char *e = NULL;
      double v = strtod(q, &e);
      if (e == q || e > eol || !isfinite(v) || (e < eol && *e != ' ' && *e != '\t' && *e != '\r')) {
        st = km__fail(err, KM_ERR_PARSE, "%s:%zu: frame %zu, value %zu: expected a number", path,
                      line, f + 1, c + 1);
        goto done;
      }
      if (c >= ps.n_channels) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s:%zu: frame %zu has more than the %zu values the CHANNELS declare", path,
                      line, f + 1, ps.n_channels);
        goto done;
      }
      row[c++] = v;
      q = e;
    }
    if (c > 0) {
      if (c != ps.n_channels) {
        st = km__fail(err, KM_ERR_PARSE,
                      "%s:%zu: frame %zu has %zu values, the CHANNELS declare %zu", path, line,
                      f + 1, c, ps.n_channels);
        goto done;
      }
      forward_kinematics(ps.joints, ps.n_joints, row, scale, fk, fk_parents, Rw, Pw);
      double *dst = positions + f * n_out * 3;
      for (size_t i = 0; i < ps.n_joints; ++i)
        if (out_index[i] >= 0)
          memcpy(dst + 3 * (size_t)out_index[i], Pw + 3 * i, 3 * sizeof(double));
      ++f;
    }
    p = eol + (eol < ps.end);
  }
  if (f != n_frames) {
    st = km__fail(err, KM_ERR_PARSE, "%s:%zu: file ends after %zu of the %zu frames declared", path,
                  line, f, n_frames);
    goto done;
  }

  double fps = 1.0 / frame_time;
  if (fabs(fps - round(fps)) < 0.01) fps = round(fps);
  out->n_frames = n_frames;
  out->n_joints = n_out;
  out->fps = fps;
  out->joint_names = names;
  out->parents = parents;
  out->positions = positions;
  names = NULL;
  parents = NULL;
  positions = NULL;
  if (info) {
    info->units_to_m = scale;
    info->rest_height = h * scale;
    info->n_channels = ps.n_channels;
  }
  st = KM_OK;

done:
  if (names)
    for (size_t k = 0; k < n_out; ++k)
      free(names[k]);
  free(names);
  free(parents);
  free(positions);
  free(Rw);
  free(Pw);
  free(fk);
  free(fk_parents);
  free(row);
  free(out_index);
  free_joints(&ps);
  free(data);
  return st;
}
