#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>

static void print_usage(FILE *f, const km_cli_opt *opts, size_t n_opts, const char *usage,
                        const char *description) {
  fprintf(f, "usage: %s\n", usage);
  if (description) fprintf(f, "\n%s\n", description);
  if (n_opts) fprintf(f, "\noptions:\n");
  for (size_t i = 0; i < n_opts; ++i) {
    char left[64];
    const char *arg = opts[i].kind == KM_OPT_FLAG     ? ""
                      : opts[i].kind == KM_OPT_STRING ? " VALUE"
                      : opts[i].kind == KM_OPT_DOUBLE ? " X"
                                                      : " N";
    if (opts[i].short_name)
      snprintf(left, sizeof left, "-%c, --%s%s", opts[i].short_name, opts[i].name, arg);
    else
      snprintf(left, sizeof left, "    --%s%s", opts[i].name, arg);
    fprintf(f, "  %-26s %s\n", left, opts[i].help);
  }
  fprintf(f, "  %-26s %s\n", "-h, --help", "show this help");
}

static int set_value(const km_cli_opt *o, const char *v, const char *usage) {
  char *end = NULL;
  errno = 0;
  switch (o->kind) {
  case KM_OPT_STRING: *(const char **)o->dst = v; return 1;
  case KM_OPT_INT: {
    long x = strtol(v, &end, 10);
    if (errno || !*v || *end || x < -2147483647L || x > 2147483647L) break;
    *(int *)o->dst = (int)x;
    return 1;
  }
  case KM_OPT_SIZE: {
    if (*v == '-') break;
    unsigned long long x = strtoull(v, &end, 10);
    if (errno || !*v || *end) break;
    *(size_t *)o->dst = (size_t)x;
    return 1;
  }
  case KM_OPT_DOUBLE: {
    double x = strtod(v, &end);
    if (errno || !*v || *end || x != x) break;
    *(double *)o->dst = x;
    return 1;
  }
  case KM_OPT_FLAG: *(bool *)o->dst = true; return 1;
  }
  fprintf(stderr, "kinemesh: option --%s: '%s' is not a valid %s\n(usage: %s)\n", o->name, v,
          o->kind == KM_OPT_DOUBLE ? "number" : "non-negative integer", usage);
  return -1;
}

int km_cli_parse(int argc, char **argv, const km_cli_opt *opts, size_t n_opts, const char **pos,
                 int max_pos, int *n_pos, const char *usage, const char *description) {
  *n_pos = 0;
  bool only_pos = false;
  for (int i = 1; i < argc; ++i) {
    const char *a = argv[i];
    if (!only_pos && (!strcmp(a, "-h") || !strcmp(a, "--help"))) {
      print_usage(stdout, opts, n_opts, usage, description);
      return 0;
    }
    if (!only_pos && !strcmp(a, "--")) {
      only_pos = true;
      continue;
    }
    if (!only_pos && a[0] == '-' && a[1] != '\0' && !(a[1] >= '0' && a[1] <= '9')) {
      const km_cli_opt *o = NULL;
      const char *inline_val = NULL;
      if (a[1] == '-') {
        const char *name = a + 2;
        const char *eq = strchr(name, '=');
        size_t len = eq ? (size_t)(eq - name) : strlen(name);
        for (size_t k = 0; k < n_opts; ++k)
          if (strlen(opts[k].name) == len && !strncmp(opts[k].name, name, len)) o = &opts[k];
        if (eq) inline_val = eq + 1;
      } else if (a[2] == '\0') {
        for (size_t k = 0; k < n_opts; ++k)
          if (opts[k].short_name == a[1]) o = &opts[k];
      }
      if (!o) {
        fprintf(stderr, "kinemesh: unknown option '%s'\n\n", a);
        print_usage(stderr, opts, n_opts, usage, description);
        return -1;
      }
      if (o->kind == KM_OPT_FLAG) {
        if (inline_val) {
          fprintf(stderr, "kinemesh: option --%s takes no value\n", o->name);
          return -1;
        }
        *(bool *)o->dst = true;
        continue;
      }
      const char *v = inline_val;
      if (!v) {
        if (i + 1 >= argc) {
          fprintf(stderr, "kinemesh: option --%s needs a value\n(usage: %s)\n", o->name, usage);
          return -1;
        }
        v = argv[++i];
      }
      if (set_value(o, v, usage) < 0) return -1;
      continue;
    }
    if (*n_pos >= max_pos) {
      fprintf(stderr, "kinemesh: unexpected argument '%s'\n(usage: %s)\n", a, usage);
      return -1;
    }
    pos[(*n_pos)++] = a;
  }
  return 1;
}

int km_cli_fail(const char *verb, const km_error *err) {
  km_cli_progress_done();
  fprintf(stderr, "kinemesh %s: error: %s\n", verb,
          err && err->message[0] ? err->message : "unknown error");
  return KM_EXIT_FAIL;
}

int km_cli_error(const char *verb, const char *fmt, ...) {
  km_cli_progress_done();
  fprintf(stderr, "kinemesh %s: error: ", verb);
  va_list ap;
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fputc('\n', stderr);
  return KM_EXIT_FAIL;
}

static void stderr_logger(km_log_level level, const char *msg, void *user) {
  (void)user;
  static const char *names[] = {"debug", "info", "warning", "error"};
  if (level == KM_LOG_DEBUG && !getenv("KINEMESH_DEBUG")) return;
  km_cli_progress_done();
  fprintf(stderr, "kinemesh: %s: %s\n", names[level], msg);
}

void km_cli_install_logger(void) { km_set_logger(stderr_logger, NULL); }

void km_cli_serial_blas(void) {
  const char *env = getenv("OPENBLAS_NUM_THREADS");
  if (!env || !*env) km_blas_threads(1);
}

/* Progress: on a terminal a redrawn bar; otherwise a line per stage and per 25%. */
static struct {
  const char *label;
  char stage[64];
  int last_quarter;
  bool active, tty;
} g_prog;

static bool progress_cb(double f, const char *stage, void *user) {
  (void)user;
  if (!stage) stage = "";
  bool new_stage = strncmp(g_prog.stage, stage, sizeof g_prog.stage - 1) != 0;
  if (new_stage) {
    snprintf(g_prog.stage, sizeof g_prog.stage, "%s", stage);
    g_prog.last_quarter = -1;
  }
  if (g_prog.tty) {
    int width = 30, filled = (int)(f * width + 0.5);
    char bar[64];
    for (int i = 0; i < width; ++i)
      bar[i] = i < filled ? '#' : '.';
    bar[width] = '\0';
    fprintf(stderr, "\r%s [%s] %3d%% %-24.24s", g_prog.label, bar, (int)(f * 100 + 0.5), stage);
    g_prog.active = true;
  } else {
    int q = (int)(f * 4);
    if (new_stage || q > g_prog.last_quarter) {
      fprintf(stderr, "%s: %s %d%%\n", g_prog.label, stage, (int)(f * 100 + 0.5));
      g_prog.last_quarter = q;
    }
  }
  fflush(stderr);
  return true;
}

km_progress km_cli_progress(const char *label) {
  g_prog.label = label;
  g_prog.stage[0] = '\0';
  g_prog.last_quarter = -1;
  g_prog.tty = isatty(2) != 0;
  km_progress p = {progress_cb, NULL};
  return p;
}

void km_cli_progress_done(void) {
  if (g_prog.active) {
    fputc('\n', stderr);
    g_prog.active = false;
  }
}

double km_cli_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

char *km_cli_rig_path(const char *mesh_path) {
  size_t n = strlen(mesh_path);
  const char *slash = strrchr(mesh_path, '/');
  const char *dot = strrchr(mesh_path, '.');
  size_t stem = (dot && (!slash || dot > slash)) ? (size_t)(dot - mesh_path) : n;
  char *out = malloc(stem + 10);
  if (!out) return NULL;
  memcpy(out, mesh_path, stem);
  memcpy(out + stem, ".rig.json", 10);
  return out;
}

/* Whether path names a glTF file (.glb, .gltf or a VRM avatar's .vrm, any case). */
static bool gltf_path(const char *path) {
  size_t n = path ? strlen(path) : 0;
  return (n > 4 && !strcasecmp(path + n - 4, ".glb")) ||
         (n > 5 && !strcasecmp(path + n - 5, ".gltf")) ||
         (n > 4 && !strcasecmp(path + n - 4, ".vrm"));
}

km_status km_cli_skin_character(const char *verb, const char *mesh_path, const char *rig,
                                km_character *c, bool *used, km_error *err) {
  *used = false;
  if (rig || !gltf_path(mesh_path)) return KM_OK;
  char *def = km_cli_rig_path(mesh_path);
  bool have = def && access(def, F_OK) == 0;
  free(def);
  if (have) return KM_OK;
  km_mesh m = {0};
  km_mesh_skin sk = {0};
  km_skin_mapping map;
  km_status s = km_mesh_read_skinned(mesh_path, &m, &sk, err);
  if (s == KM_OK && sk.n_joints) {
    km_character tmp;
    s = km_character_from_skin(&m, &sk, &tmp, &map, err);
    if (s == KM_OK) {
      km_character_free(c);
      *c = tmp;
      *used = true;
      fprintf(stderr,
              "kinemesh %s: %s: rigged from its own skin (%zu joints; %zu merged into an "
              "ancestor):",
              verb, mesh_path, sk.n_joints, map.n_merged);
      for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
        fprintf(stderr, "%s %s <- %s", j ? "," : "", km_kinect1_joint_name(j),
                map.source[j][0] ? map.source[j] : "(derived)");
      fputc('\n', stderr);
    }
  }
  km_mesh_free(&m);
  km_mesh_skin_free(&sk);
  return s;
}

int km_cli_keep_frame_output(const char *verb, const char *out, bool keep) {
  if (keep && out && gltf_path(out))
    return km_cli_error(verb, "--keep-frame is for .pc2 and frame directories: a glTF file is in "
                              "glTF's frame (y up, facing +z, metres) by its specification, "
                              "which kinemesh writes as it is");
  return 0;
}

/* Cat-04 lying on its side and cat-07 curled asleep (../shared/data/poses) get heads of 1 and 2
 * vertices; of the shared meshes that stand, the smallest end handle is 6 (the 502-vertex
 * knight's head), most hold 30 to 500. Said, not refused: the user decides. */
size_t km_cli_warn_point_handles(const char *verb, const char *mesh_path, const km_rig *rig,
                                 const char *kind, const char *up, FILE *say) {
  size_t n = 0;
  for (size_t h = 0; h < rig->n_handles; ++h) {
    const char *name = rig->handles[h].name;
    bool end = !strcmp(name, "head") || !strncmp(name, "hand_", 5) || !strncmp(name, "foot_", 5);
    if (!end || rig->handles[h].n_vertices >= 5) continue;
    fprintf(say,
            "kinemesh %s: warning: handle %s holds %zu vertices: a point drags a spike out of "
            "the surface, not a part; the rig takes %s for a %s standing along %s, and a body "
            "lying or curled up is none: its animation may not read (kinemesh rig %s "
            "--skeleton resting --head V rigs it lying: its head, V the vertex at its tip, "
            "turns with the performer's neck and its body stays; kinemesh pick --near x,y,z or "
            "the live page's hover shows vertex ids; or in kinemesh live click the head's tip "
            "and press \"rig lying\")\n",
            verb, name, rig->handles[h].n_vertices, mesh_path, kind, up ? up : "the up axis above",
            mesh_path);
    ++n;
  }
  return n;
}

km_status km_cli_auto_rig(const char *verb, const char *mesh_path, const char *rig_file,
                          const km_mesh *m, FILE *say, const char *then, km_character *c,
                          char **json, size_t *json_size, km_error *err) {
  km_character tmp = {0};
  km_autorig_report rep;
  km_status s = km_autorig(m, NULL, &tmp, &rep, err);
  if (s != KM_OK) {
    char why[sizeof err->message]; /* the message is rewritten in place: a copy to read from */
    snprintf(why, sizeof why, "%s", err->message);
    km_error_set(err, s,
                 "%s has no rig (%s) and cannot be rigged automatically: %s; place handles "
                 "by hand (kinemesh pick) in a rig file and pass --rig",
                 mesh_path, rig_file, why);
    return s;
  }
  km_character_free(c);
  *c = tmp;
  fprintf(say, "kinemesh %s: no rig at %s: rigged %s as a %s in %.2f s:", verb, rig_file, mesh_path,
          km_autorig_kind_name(rep.kind), rep.seconds);
  const char *sep = " ";
  for (size_t e = 0; e < rep.n_extremities; ++e)
    if (rep.role[e][0]) {
      fprintf(say, "%s%s at vertex %d", sep, rep.role[e], (int)rep.extremity[e]);
      sep = ", ";
    }
  if (rep.fallback[0]) fprintf(say, " (not a humanoid or quadruped: %s)", rep.fallback);
  if (rep.loose_pieces)
    fprintf(say, "; %zu loose piece%s (%zu vertices) follow%s the body", rep.loose_pieces,
            rep.loose_pieces > 1 ? "s" : "", rep.loose_vertices, rep.loose_pieces > 1 ? "" : "s");
  if (then)
    fprintf(say, "; %s\n", then);
  else
    fprintf(say, "; kinemesh rig %s writes it, to edit\n", mesh_path);
  /* what `kinemesh rig` warns of, said here too: the rig on the spot is the same rig; its
   * sidecar text, made for that, goes to the caller that puppets with it */
  char *text = NULL;
  size_t size = 0;
  km_rig rig = {0};
  km_error ee = {0};
  if (km_character_rig_json(c, &text, &size, &ee) == KM_OK &&
      km_rig_parse(text, size, mesh_path, m, NULL, 0, &rig, &ee) == KM_OK)
    km_cli_warn_point_handles(verb, mesh_path, &rig, km_autorig_kind_name(rep.kind), NULL, say);
  km_rig_free(&rig);
  if (json) {
    *json = text;
    *json_size = size;
  } else {
    free(text);
  }
  return KM_OK;
}

void km_cli_json_number(cJSON *o, const char *key, double v) {
  if (isfinite(v))
    cJSON_AddNumberToObject(o, key, v);
  else
    cJSON_AddNullToObject(o, key);
}

/* ---- puppetry pieces shared by precompute, animate, live and the benches */

int km_cli_parse_energy(const char *verb, const char *s, km_puppet_energy *e) {
  if (!s || !strcmp(s, "arap"))
    *e = KM_PUPPET_ENERGY_ARAP;
  else if (!strcmp(s, "laplacian"))
    *e = KM_PUPPET_ENERGY_LAPLACIAN;
  else
    return km_cli_error(verb, "--energy must be laplacian or arap, not '%s'", s);
  return 0;
}

int km_cli_parse_frame_format(const char *verb, const char *s, km_anim_format *f) {
  if (!s)
    *f = KM_ANIM_AUTO;
  else if (!strcmp(s, "obj"))
    *f = KM_ANIM_OBJ_DIR;
  else if (!strcmp(s, "ply"))
    *f = KM_ANIM_PLY_DIR;
  else
    return km_cli_error(verb, "--frame-format must be obj or ply, not '%s'", s);
  return 0;
}

int km_cli_parse_filter(const char *verb, const char *s, km_filter_options *o) {
  if (!strcmp(s, "holt"))
    o->kind = KM_FILTER_HOLT;
  else if (!strcmp(s, "one_euro"))
    o->kind = KM_FILTER_ONE_EURO;
  else
    return km_cli_error(verb, "--filter must be holt or one_euro, not '%s'", s);
  return 0;
}

km_status km_cli_rig_read_scaled(const char *path, const km_mesh *m, double k,
                                 const char *const *joint_names, size_t n_joint_names, km_rig *out,
                                 km_error *err) {
  km_mesh rm = *m; /* m in the sidecar's unit when it differs (V replaced, not freed) */
  double *V = NULL;
  if (k != 1) {
    if (!(V = malloc(sizeof(double) * 3 * m->n_vertices)))
      return km_error_set(err, KM_ERR_NOMEM, "out of memory");
    for (size_t i = 0; i < 3 * m->n_vertices; ++i)
      V[i] = m->V[i] / k;
    rm.V = V;
  }
  km_status s = km_rig_read(path, &rm, joint_names, n_joint_names, out, err);
  free(V);
  for (size_t i = 0; s == KM_OK && k != 1 && out->joint_rest && i < 3 * out->n_joint_rest; ++i)
    out->joint_rest[i] *= k;
  return s;
}

int km_cli_parse_export(const char *verb, const char *s, double max_error_mm, bool compress,
                        const char *out, km_anim_options *ao, km_ssdr_options *ssdr) {
  memset(ssdr, 0, sizeof *ssdr);
  ao->export_kind = KM_ANIM_EXPORT_MORPHS;
  ao->skin = NULL;
  ao->compress = compress;
  if (compress) {
    const char *dot = out ? strrchr(out, '.') : NULL;
    if (!dot || strcasecmp(dot, ".glb") != 0)
      return km_cli_error(verb, "--compress writes a .glb; the output is '%s'", out ? out : "");
  }
  if (!(max_error_mm >= 0) || !isfinite(max_error_mm))
    return km_cli_error(verb, "--max-error-mm must be >= 0, not %g", max_error_mm);
  if (!s || !strcmp(s, "morphs") || !strcmp(s, "morphs:all")) {
    if (max_error_mm > 0) return km_cli_error(verb, "--max-error-mm applies to --export skin only");
    return 0;
  }
  if (!strncmp(s, "morphs:", 7)) {
    char *end = NULL;
    long k = strtol(s + 7, &end, 10);
    if (!end || *end || end == s + 7 || k < 1 || k > 100000)
      return km_cli_error(verb, "--export morphs:K needs a target count 1..100000 or all, not '%s'",
                          s + 7);
    if (max_error_mm > 0) return km_cli_error(verb, "--max-error-mm applies to --export skin only");
    const char *dot = out ? strrchr(out, '.') : NULL;
    if (!dot || strcasecmp(dot, ".glb") != 0)
      return km_cli_error(verb, "--export morphs:K writes a .glb; the output is '%s'",
                          out ? out : "");
    ao->export_kind = KM_ANIM_EXPORT_MORPHS_PCA;
    ao->morphs = (size_t)k;
    return 0;
  }
  if (!strcmp(s, "skeleton")) {
    /* the frames' own bones: only pose skins its frames by a skeleton it can hand over */
    if (strcmp(verb, "pose"))
      return km_cli_error(verb, "--export skeleton is pose's (its frames are skinned by the rig's "
                                "skeleton); use --export skin to fit bones to these frames");
    if (max_error_mm > 0)
      return km_cli_error(verb, "--max-error-mm applies to --export skin only (skeleton is exact)");
    const char *dot = out ? strrchr(out, '.') : NULL;
    if (!dot || strcasecmp(dot, ".glb") != 0)
      return km_cli_error(verb, "--export skeleton writes a .glb; the output is '%s'",
                          out ? out : "");
    ao->export_kind = KM_ANIM_EXPORT_SKELETON;
    return 0;
  }
  if (strncmp(s, "skin", 4) != 0 || (s[4] != '\0' && s[4] != ':'))
    return km_cli_error(verb, "--export must be morphs[:all], morphs:K, skin[:BONES]%s, not '%s'",
                        strcmp(verb, "pose") ? "" : " or skeleton", s);
  if (s[4] == ':') {
    char *end = NULL;
    long b = strtol(s + 5, &end, 10);
    if (!end || *end || end == s + 5 || b < 1 || b > 65535)
      return km_cli_error(verb, "--export skin:BONES needs a bone count 1..65535, not '%s'", s + 5);
    ssdr->bones = (size_t)b;
  }
  char ext[8];
  const char *dot = out ? strrchr(out, '.') : NULL;
  snprintf(ext, sizeof ext, "%s", dot ? dot + 1 : "");
  for (char *c = ext; *c; ++c)
    *c = (char)tolower((unsigned char)*c);
  if (strcmp(ext, "glb") != 0)
    return km_cli_error(verb, "--export skin writes a .glb; the output is '%s'", out ? out : "");
  /* Plain "skin": a budget that keeps the targets (max 15 mm on a 1.75 m figure). */
  ssdr->max_error_mm = max_error_mm > 0 ? max_error_mm : (s[4] == ':' ? 0 : 15);
  ssdr->progress = km_cli_progress("skin fit");
  ao->export_kind = KM_ANIM_EXPORT_SKIN;
  ao->skin = ssdr;
  return 0;
}

int km_cli_skin_seeds(const char *verb, const km_anim_options *ao, const km_mesh *m,
                      const km_skin *skin, size_t n_joints, km_ssdr_options *ssdr, double **seeds) {
  *seeds = NULL;
  if (ao->export_kind != KM_ANIM_EXPORT_SKIN || ssdr->bones != 0 || !skin || !skin->joints ||
      n_joints == 0)
    return 0;
  double *s = calloc(n_joints * 4, sizeof *s);
  if (!s) return km_cli_error(verb, "out of memory");
  for (size_t i = 0; i < m->n_vertices && i < skin->n_vertices; ++i)
    for (int k = 0; k < KM_SKIN_INFLUENCES; ++k) {
      int32_t j = skin->joints[KM_SKIN_INFLUENCES * i + k];
      double wk = skin->weights[KM_SKIN_INFLUENCES * i + k];
      if (j < 0 || (size_t)j >= n_joints || !(wk > 0)) continue;
      for (int a = 0; a < 3; ++a)
        s[4 * j + a] += wk * m->V[3 * i + a];
      s[4 * j + 3] += wk;
    }
  size_t ns = 0;
  for (size_t j = 0; j < n_joints; ++j)
    if (s[4 * j + 3] > 0) {
      for (int a = 0; a < 3; ++a)
        s[3 * ns + a] = s[4 * j + a] / s[4 * j + 3];
      ++ns;
    }
  ssdr->seed = s;
  ssdr->n_seed = ns;
  *seeds = s;
  return 0;
}

void km_cli_report_export(const char *verb, const km_anim_report *rep) {
  if (rep->export_kind == KM_ANIM_EXPORT_MORPHS_PCA) {
    fprintf(stderr,
            "kinemesh %s: morphs: %zu basis targets, %zu frames, rms %.4f mm, max %.4f mm\n", verb,
            rep->targets, rep->frames, rep->rms_error * 1e3, rep->max_error * 1e3);
    return;
  }
  if (rep->export_kind == KM_ANIM_EXPORT_MORPHS && (rep->rms_error > 0 || rep->max_error > 0)) {
    fprintf(stderr, "kinemesh %s: morphs (compressed): %zu frames, rms %.4f mm, max %.4f mm\n",
            verb, rep->frames, rep->rms_error * 1e3, rep->max_error * 1e3);
    return;
  }
  if (rep->export_kind == KM_ANIM_EXPORT_SKELETON) {
    fprintf(
        stderr,
        "kinemesh %s: skeleton: %zu joints, %zu frames, rms %.4f mm, max %.4f mm (the rig's own "
        "bones and weights, no fit)\n",
        verb, rep->bones, rep->frames, rep->rms_error * 1e3, rep->max_error * 1e3);
    return;
  }
  if (rep->export_kind != KM_ANIM_EXPORT_SKIN) return;
  km_cli_progress_done();
  fprintf(stderr,
          "kinemesh %s: skin: %zu bones, %zu frames, rms %.3f mm, max %.3f mm (fit %.1f s)\n", verb,
          rep->bones, rep->frames, rep->rms_error * 1e3, rep->max_error * 1e3, rep->fit_seconds);
}

char *km_cli_cache_path(const km_mesh *mesh) {
  const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
  char dir[4096];
  if (xdg && xdg[0] == '/') /* the XDG spec: a relative value is to be ignored */
    snprintf(dir, sizeof dir, "%s/kinemesh", xdg);
  else if (home && home[0])
    snprintf(dir, sizeof dir, "%s/.cache/kinemesh", home);
  else
    snprintf(dir, sizeof dir, "/tmp/kinemesh-cache-%ld", (long)getuid());
  size_t n = strlen(dir) + 32;
  char *out = malloc(n);
  if (out) snprintf(out, n, "%s/%016llx.kmcache", dir, (unsigned long long)km_mesh_hash(mesh));
  return out;
}

void km_cli_report_cache(const char *cache, const km_puppetry_info *info) {
  if (info->model == KM_PUPPETRY_MODEL_REBUILT_STALE)
    fprintf(stderr, "kinemesh: cache %s not usable (%s); rebuilding it\n", cache,
            info->stale.message);
  if (info->save.status != KM_OK)
    fprintf(stderr, "kinemesh: warning: could not write the cache: %s\n", info->save.message);
}

km_status km_cli_puppet_open(const km_mesh *mesh, const char *cache, km_puppet **out,
                             km_puppetry_info *info, km_error *err) {
  km_puppetry_options o = {0};
  o.cache_path = cache;
  o.puppet.progress = km_cli_progress("precompute");
  km_status s = km_puppetry_model_open(mesh, &o, out, info, err);
  km_cli_progress_done();
  if (s == KM_OK) km_cli_report_cache(cache, info);
  return s;
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

#define KM_CLI_TEXT_MAX ((size_t)1 << 30)

char *km_cli_read_text(const char *path, size_t *size) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = NULL;
  size_t n = 0, cap = 0, got;
  do {
    if (cap - n < 4096) {
      /* A text or JSON input (manifest, features, rig, report) larger than 1 GiB is not one;
       * refuse it rather than try to hold it (a pipe or /dev/zero would never end). */
      char *g = cap >= KM_CLI_TEXT_MAX ? NULL : realloc(buf, cap = cap ? 2 * cap : 65536);
      if (!g) {
        int e = cap >= KM_CLI_TEXT_MAX ? EFBIG : ENOMEM;
        free(buf);
        fclose(f);
        errno = e;
        return NULL;
      }
      buf = g;
    }
    got = fread(buf + n, 1, cap - n - 1, f);
    n += got;
  } while (got > 0);
  fclose(f);
  buf[n] = '\0';
  if (size) *size = n;
  return buf;
}

cJSON *km_cli_read_json(const char *path) {
  char *t = km_cli_read_text(path, NULL);
  cJSON *o = t ? cJSON_Parse(t) : NULL;
  free(t);
  return o;
}

double km_cli_median(double *v, size_t n) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* ---- shared by several verbs */

int km_cli_print_json(const char *verb, cJSON *root) {
  char *s = cJSON_Print(root);
  cJSON_Delete(root);
  if (!s) return km_cli_error(verb, "out of memory");
  puts(s);
  free(s);
  return KM_EXIT_OK;
}

km_status km_cli_load_landmarks(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                km_landmark *lm, size_t capacity, size_t *n, km_error *err) {
  if (lm_path) return km_landmarks_read(lm_path, n_vertices, lm, capacity, n, err);
  char *rig = km_cli_rig_path(mesh_path);
  if (!rig) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  km_status s = km_landmarks_read(rig, n_vertices, lm, capacity, n, err);
  free(rig);
  return s;
}

/* ---- orientation (issue 11) */

static int parse_axis_opt(const char *verb, const char *opt, const char *s, km_axis *a) {
  km_error e = {0};
  if (!s) return 0;
  if (km_axis_parse(s, a, &e) != KM_OK) return km_cli_error(verb, "--%s: %s", opt, e.message);
  return 0;
}

/* An axis perpendicular to up for a forward that was not given or clashes: +z, or -y for
 * a z-up file (Blender's convention: the front view looks along +y at a model facing -y). */
static km_axis default_forward(km_axis up) {
  return (up == KM_AXIS_POS_Z || up == KM_AXIS_NEG_Z) ? KM_AXIS_NEG_Y : KM_AXIS_POS_Z;
}

int km_cli_parse_units(const char *verb, const char *opt, const char *s, double *scale) {
  if (!s) return 0;
  char *end = NULL;
  double x = km_units_scale(s);
  if (x == 0) x = strtod(s, &end);
  if (!(x > 0) || !isfinite(x) || (end && *end))
    return km_cli_error(verb, "--%s must be m, cm, mm, in, ft or a positive number, not '%s'", opt,
                        s);
  *scale = x;
  return 0;
}

static bool same_axis(km_axis a, km_axis b) { return a && b && (a - 1) / 2 == (b - 1) / 2; }

/* The "frame" object of the mesh's rig sidecar (<stem>.rig.json), when it has a valid one:
 *   "frame": {"up": "+z", "forward": "-y", "scale": 0.01}
 * up/forward are the file's axes, scale metres per file unit (optional). */
static bool sidecar_frame(const char *mesh_path, const char *rig_path, km_frame *out) {
  memset(out, 0, sizeof *out);
  char *own = !rig_path && mesh_path ? km_cli_rig_path(mesh_path) : NULL;
  const char *rig = rig_path ? rig_path : own;
  cJSON *j = rig ? km_cli_read_json(rig) : NULL;
  free(own);
  if (!j) return false;
  cJSON *fr = cJSON_GetObjectItemCaseSensitive(j, "frame");
  const char *up = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(fr, "up"));
  const char *fw = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(fr, "forward"));
  cJSON *sc = cJSON_GetObjectItemCaseSensitive(fr, "scale");
  bool ok = up && fw && km_axis_parse(up, &out->up, NULL) == KM_OK &&
            km_axis_parse(fw, &out->forward, NULL) == KM_OK && !same_axis(out->up, out->forward);
  if (ok && cJSON_IsNumber(sc) && sc->valuedouble > 0 && isfinite(sc->valuedouble))
    out->scale = sc->valuedouble;
  cJSON_Delete(j);
  return ok;
}

double km_cli_sidecar_scale(const char *mesh_path, const char *rig_path) {
  km_frame f;
  return sidecar_frame(mesh_path, rig_path, &f) && f.scale > 0 ? f.scale : 1;
}

int km_cli_mesh_frame(const char *verb, const char *path, const km_cli_frame_opts *fo,
                      const km_mesh *m, bool quiet, km_frame *out, bool *guessed) {
  memset(out, 0, sizeof *out);
  if (guessed) *guessed = false;
  km_cli_frame_opts none = {0};
  if (!fo) fo = &none;
  if (parse_axis_opt(verb, "up", fo->up, &out->up) ||
      parse_axis_opt(verb, "forward", fo->forward, &out->forward))
    return KM_EXIT_USAGE;
  if (km_cli_parse_units(verb, "units", fo->units, &out->scale)) return KM_EXIT_USAGE;
  if (same_axis(out->up, out->forward))
    return km_cli_error(verb, "--up %s and --forward %s lie on the same axis", fo->up, fo->forward);
  if (out->up && out->forward) return 0;
  /* No axis given: the rig sidecar's record of them (written by whoever rigged the mesh). */
  km_frame sf;
  if (!out->up && !out->forward && sidecar_frame(path, fo->rig, &sf)) {
    out->up = sf.up;
    out->forward = sf.forward;
    if (!fo->units && sf.scale > 0) out->scale = sf.scale;
    return 0;
  }
  /* glTF says it itself: +y up, the front facing +z, metres (glTF 2.0, 3.4); a VRM 0.x
   * avatar, which faces -z, is turned by the reader. */
  if (!out->up && !out->forward && gltf_path(path)) {
    out->up = KM_AXIS_POS_Y;
    out->forward = KM_AXIS_POS_Z;
    return 0;
  }
  km_frame_guess g;
  km_error e = {0};
  if (fo->no_guess ||
      /* with --up alone, forward is guessed for that up, not for a guessed one */
      km_mesh_frame_guess_forward(m, out->up, &g, &e) != KM_OK) { /* flat or empty */
    if (!out->up) out->up = KM_AXIS_POS_Y;
    if (!out->forward || same_axis(out->up, out->forward)) out->forward = default_forward(out->up);
    return 0;
  }
  if (!out->up) out->up = g.frame.up;
  if (!out->forward)
    out->forward = same_axis(out->up, g.frame.forward) ? default_forward(out->up) : g.frame.forward;
  if (guessed) *guessed = true;
  if (!quiet)
    fprintf(stderr,
            "kinemesh %s: %s: up %s, forward %s (%s%s; height %.4g %s; %s) - override with "
            "--up / --forward\n",
            verb, path, km_axis_name(out->up), km_axis_name(out->forward),
            fo->up || fo->forward ? "partly guessed" : "guessed",
            /* an axis the guess is unsure of is said, so the user checks that one */
            (!fo->up && !g.sure_up) && (!fo->forward && !g.sure_forward) ? ", unsure of both"
            : !fo->up && !g.sure_up                                      ? ", unsure of up"
            : !fo->forward && !g.sure_forward                            ? ", unsure of forward"
                                                                         : "",
            g.height, fo->units ? fo->units : "units", g.why);
  /* Read as metres (the default), a 3D-print STL in millimetres is a body 1000 m tall, and
   * every output (.glb, .pc2, frames) is written that big: an engine or Blender shows a
   * giant. The motion is scaled to the body, so nothing else tells the user. Heights of
   * 20-300 units read as a 0.2-3 m body in centimetres, 300-30000 as one in millimetres. */
  if (!quiet && !fo->units && !(g.height >= 0.05 && g.height <= 20)) {
    const char *hint = g.height > 20 && g.height <= 300    ? "centimetres, give --units cm"
                       : g.height > 300 && g.height <= 3e4 ? "millimetres, give --units mm"
                                                           : "not metres, give --units";
    fprintf(stderr,
            "kinemesh %s: note: %s is %.4g units tall and is read in metres, so its outputs are "
            "%.4g m tall: if its units are %s\n",
            verb, path, g.height, g.height, hint);
  }
  return 0;
}

int km_cli_orient_mesh(const char *verb, const char *path, const km_cli_frame_opts *fo,
                       km_mesh *m) {
  km_frame f;
  int rc = km_cli_mesh_frame(verb, path, fo, m, false, &f, NULL);
  if (rc) return rc;
  if (km_frame_is_identity(&f)) return 0; /* already kinemesh's frame: kept bit for bit */
  km_error e = {0};
  if (km_mesh_frame_apply(&f, m, &e) != KM_OK) return km_cli_fail(verb, &e);
  return 0;
}

int km_cli_given_frame(const char *verb, const char *opt, const char *up, const char *forward,
                       const char *units, km_frame *out) {
  char n_up[64], n_fw[64], n_un[64];
  snprintf(n_up, sizeof n_up, "%s-up", opt);
  snprintf(n_fw, sizeof n_fw, "%s-forward", opt);
  snprintf(n_un, sizeof n_un, "%s-units", opt);
  memset(out, 0, sizeof *out);
  if (parse_axis_opt(verb, n_up, up, &out->up) ||
      parse_axis_opt(verb, n_fw, forward, &out->forward) ||
      km_cli_parse_units(verb, n_un, units, &out->scale))
    return KM_EXIT_USAGE;
  if (!out->up) out->up = KM_AXIS_POS_Y;
  if (!out->forward) out->forward = default_forward(out->up);
  if (same_axis(out->up, out->forward))
    return km_cli_error(verb, "--%s %s and --%s %s lie on the same axis", n_up, up ? up : "+y",
                        n_fw, forward ? forward : "+z");
  return 0;
}

int km_cli_read_motion_for(const char *verb, const char *path, const km_skeleton *sk, km_take *t) {
  bool kinect1 = sk->n_joints == KM_KINECT1_JOINTS;
  for (size_t j = 0; kinect1 && j < sk->n_joints; ++j)
    kinect1 = sk->names[j] && km_kinect1_joint_index(sk->names[j]) == (int)j;
  km_motion_read_options mo = {.kinect1 = kinect1};
  km_error e = {0};
  if (km_motion_read(path, &mo, t, NULL, &e) != KM_OK) return km_cli_fail(verb, &e);
  return 0;
}

int km_cli_map_joints(const char *verb, const km_skeleton *sk, const km_take *t, int *map) {
  size_t found = 0;
  for (size_t j = 0; j < sk->n_joints; ++j) {
    map[j] = -1;
    for (size_t k = 0; k < t->n_joints; ++k)
      if (sk->names[j] && t->joint_names[k] && !strcmp(sk->names[j], t->joint_names[k]))
        map[j] = (int)k;
    found += map[j] >= 0;
  }
  if (found == sk->n_joints) return 0;
  char names[512] = "";
  size_t len = 0;
  for (size_t j = 0; j < sk->n_joints && len + 40 < sizeof names; ++j)
    if (map[j] < 0)
      len += (size_t)snprintf(names + len, sizeof names - len, "%s%s", len ? ", " : "",
                              sk->names[j] ? sk->names[j] : "?");
  if (!found)
    return km_cli_error(verb, "the take has none of the rig's %zu joints by name (%s)",
                        sk->n_joints, names);
  fprintf(stderr,
          "kinemesh %s: warning: the take has %zu of the rig's %zu joints; these hold their rest "
          "pose: %s\n",
          verb, found, sk->n_joints, names);
  return 0;
}

int km_cli_orient_take(const char *verb, const km_cli_frame_opts *fo, km_take *t) {
  if (!fo || (!fo->motion_up && !fo->motion_forward)) return 0;
  km_frame f;
  int rc = km_cli_given_frame(verb, "motion", fo->motion_up, fo->motion_forward, NULL, &f);
  if (rc) return rc;
  km_error e = {0};
  if (km_frame_apply(&f, t->positions, t->n_frames * t->n_joints, NULL, 0, &e) != KM_OK)
    return km_cli_fail(verb, &e);
  return 0;
}

int km_cli_parse_weights(const char *verb, const char *s, km_autorig_skin *out) {
  if (!s) {
    *out = KM_AUTORIG_SKIN_AUTO;
    return 0;
  }
  if (!strcmp(s, "distance")) {
    *out = KM_AUTORIG_SKIN_DISTANCE;
    return 0;
  }
  if (!strcmp(s, "reach")) {
    *out = KM_AUTORIG_SKIN_REACH;
    return 0;
  }
  if (!strcmp(s, "heat")) {
    *out = KM_AUTORIG_SKIN_HEAT;
    return 0;
  }
  km_cli_error(verb, "--weights %s: expected heat, distance or reach", s);
  return KM_EXIT_USAGE;
}

/* ---- the deformation check in one line (animate, check) */

/* Where edge e (two vertices; a vertex twice) is: the rig's handle nearest to its middle at
 * rest, or its first vertex without a rig ("-" with no edge). */
static const char *near_place(const km_rig *rig, const km_mesh *m, const int32_t e[2], char *buf,
                              size_t n) {
  if (e[0] < 0 || e[1] < 0) return "-";
  if (!rig || !rig->n_handles) {
    snprintf(buf, n, "vertex %d", (int)e[0]);
    return buf;
  }
  double x[3];
  for (int k = 0; k < 3; ++k)
    x[k] = 0.5 * (m->V[3 * (size_t)e[0] + k] + m->V[3 * (size_t)e[1] + k]);
  int32_t h = km_rig_nearest_handle(rig, m, x);
  return h >= 0 ? rig->handles[h].name : "-";
}

double km_cli_floor_lift(double *V, size_t nv, double floor_y) {
  double low = INFINITY;
  for (size_t v = 0; v < nv; ++v)
    low = fmin(low, V[3 * v + 1]);
  if (!(low < floor_y)) return 0;
  for (size_t v = 0; v < nv; ++v)
    V[3 * v + 1] += floor_y - low;
  return floor_y - low;
}

/* The deformation check in one line: the longest and shortest edge against its rest length,
 * the frames over 1.5x, the folds and the largest one-frame step (frames count from 0). */
void km_cli_shape_line(const km_deform_check *dc, const km_mesh *m, const km_rig *rig, char *line,
                       size_t n) {
  km_deform_summary s;
  km_deform_check_summary(dc, &s);
  if (!s.frames) {
    line[0] = 0;
    return;
  }
  int32_t sv[2] = {s.step_vertex, s.step_vertex};
  char b1[32], b2[32], step[160];
  if (s.step_vertex >= 0)
    snprintf(step, sizeof step,
             "largest one-frame step %.1f %% of the mesh's size (frame %zu, near %s)",
             s.diagonal > 0 ? 100 * s.step / s.diagonal : 0.0, s.step_frame,
             near_place(rig, m, sv, b2, sizeof b2));
  else
    snprintf(step, sizeof step, "no vertex moves from one frame to the next");
  snprintf(line, n,
           "  shape: longest edge %.2fx its rest length (frame %zu, near %s), shortest %.2fx; "
           "%zu of %zu frames have an edge over 1.5x; %zu triangles folded in some frame "
           "(most: %zu pairs, frame %zu); %s\n",
           s.ratio_max, s.ratio_max_frame, near_place(rig, m, s.long_edge, b1, sizeof b1),
           s.ratio_min, s.long_frames, s.frames, s.folded, s.most_folded_pairs, s.most_folded_frame,
           step);
}

/* What the handle targets force (km_stretch_bound), when it is over 1.5x: the two handles,
 * and that no deformation meeting them does better, so the rig, not the solver, sets it. */
void km_cli_forced_line(const km_mesh *m, const km_rig *rig, double forced, size_t frame,
                        const int32_t pair[2], char *line, size_t n) {
  const char *h[2] = {"-", "-"};
  for (int k = 0; k < 2 && rig; ++k) {
    int32_t i = pair[k] >= 0 ? km_rig_nearest_handle(rig, m, m->V + 3 * (size_t)pair[k]) : -1;
    if (i >= 0) h[k] = rig->handles[i].name;
  }
  snprintf(line, n,
           "  handles: %s and %s ask for an edge of at least %.2fx between them (frame %zu): "
           "no deformation that meets them keeps every edge under 1.5x, and the solver's soft "
           "handles give there (to ask less, move those handles apart or shrink them in the "
           "rig)\n",
           h[0], h[1], forced, frame);
}

void km_cli_glitch_line(const km_glitch_stats *gs, const char *restarted, char *line, size_t n) {
  int k = snprintf(line, n,
                   "  glitches rejected: %zu of %zu joint samples (speed %zu, bone %zu, re-found "
                   "%zu)",
                   gs->rejected, gs->samples, gs->speed, gs->bone, gs->refound);
  if (restarted && k >= 0 && (size_t)k < n)
    k += snprintf(line + k, n - (size_t)k, "; %s: %zu", restarted, gs->restarted);
  if (k >= 0 && (size_t)k < n) snprintf(line + k, n - (size_t)k, "\n");
}

void km_cli_pieces_how(FILE *f, size_t loose, size_t rigid) {
  if (rigid == loose)
    fprintf(f, ", %s rigidly with the body point nearest to it\n",
            loose > 1 ? "each turning" : "turning");
  else if (rigid == 0)
    fprintf(f, ", %s the body, bending with it\n", loose > 1 ? "each wrapping" : "wrapping");
  else
    fprintf(f,
            ": %zu turning rigidly with the body point nearest to %s, %zu wrapping the body and "
            "bending with it\n",
            rigid, rigid > 1 ? "them" : "it", loose - rigid);
}
