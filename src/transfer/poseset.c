/* The labelled meshes a pose database is built from: "CLASS=MESH[@GROUP]" entries, or a folder
 * (or glob) of meshes with a labels CSV. Parsed here, not in the CLI, so that every front end
 * gets the same rules and the same file:line errors. */
#include "transfer/pose.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void km_pose_set_free(km_pose_set *s) {
  if (!s) return;
  km_paths_free(&s->paths, s->n);
  km_paths_free(&s->names, s->n);
  km_paths_free(&s->class_names, s->n_classes);
  km_paths_free(&s->unlabelled, s->n_unlabelled);
  free(s->labels);
  free(s->groups);
  memset(s, 0, sizeof *s);
}

static const char *base_name(const char *path) {
  const char *b = strrchr(path, '/');
  return b ? b + 1 : path;
}

km_status km_pose_set_from_entries(const char *const *entries, size_t n, km_pose_set *out,
                                   km_error *err) {
  if (!out || (!entries && n)) return km__fail(err, KM_ERR_INVALID, "km_pose_set: NULL argument");
  memset(out, 0, sizeof *out);
  size_t cap = n ? n : 1;
  out->paths = km__calloc(cap, sizeof *out->paths);
  out->names = km__calloc(cap, sizeof *out->names);
  out->class_names = km__calloc(cap, sizeof *out->class_names);
  out->labels = km__calloc(cap, sizeof *out->labels);
  out->groups = km__calloc(cap, sizeof *out->groups);
  char **group_names = km__calloc(cap, sizeof *group_names);
  km_status s = KM_OK;
  bool have_groups = false;
  if (!out->paths || !out->names || !out->class_names || !out->labels || !out->groups ||
      !group_names)
    s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
  for (size_t i = 0; s == KM_OK && i < n; ++i) {
    const char *e = entries[i], *eq = strchr(e, '=');
    if (!eq || eq == e) {
      s = km__fail(err, KM_ERR_INVALID, "argument %zu '%s': expected CLASS=MESH[@GROUP]", i + 1, e);
      break;
    }
    const char *path = eq + 1, *at = strrchr(path, '@');
    size_t plen = at ? (size_t)(at - path) : strlen(path);
    out->paths[i] = strndup(path, plen);
    if (at) {
      /* subjects are names ("alice") or numbers: each distinct one is its own group */
      size_t g = 0;
      while (g < i && !(group_names[g] && !strcmp(group_names[g], at + 1)))
        ++g;
      group_names[i] = strdup(at + 1);
      out->groups[i] = g < i ? out->groups[g] : (int32_t)i;
      have_groups = true;
    }
    size_t c = 0, clen = (size_t)(eq - e);
    while (c < out->n_classes &&
           !(strlen(out->class_names[c]) == clen && !strncmp(out->class_names[c], e, clen)))
      ++c;
    if (c == out->n_classes) out->class_names[out->n_classes++] = strndup(e, clen);
    out->labels[i] = (int32_t)c;
    out->n = i + 1;
    if (!out->paths[i] || !out->class_names[c] || (at && !group_names[i])) {
      s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
      break;
    }
    /* templates are named by their file names, so that a query says which mesh it picked */
    if (!(out->names[i] = strdup(base_name(out->paths[i]))))
      s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
  }
  km_paths_free(&group_names, n);
  if (s == KM_OK && !have_groups) {
    free(out->groups);
    out->groups = NULL;
  }
  if (s != KM_OK) km_pose_set_free(out);
  return s;
}

km_status km_pose_set_from_labels(const char *meshes, const char *labels_csv,
                                  const char *const *entries_before, size_t n_before,
                                  km_pose_set *out, km_error *err) {
  if (!meshes || !labels_csv || !out)
    return km__fail(err, KM_ERR_INVALID, "km_pose_set: NULL argument");
  memset(out, 0, sizeof *out);
  static const char *const exts[] = {"obj", "ply", "off", "stl", NULL};
  char **paths = NULL;
  size_t np = 0;
  km_status s = km__list_files(meshes, exts, true, &paths, &np, err);
  if (s != KM_OK) return s;
  if (!np) {
    km_paths_free(&paths, np);
    return km__fail(err, KM_ERR_IO, "--meshes '%s' matched no mesh files (.obj .ply .off .stl)",
                    meshes);
  }
  char *data = NULL;
  size_t size = 0;
  bool *used = km__calloc(np, sizeof *used);
  int *first_line = km__calloc(np, sizeof *first_line); /* CSV line that labelled mesh k */
  size_t n_dup = 0;
  char **entries = km__calloc(np + n_before, sizeof *entries);
  size_t ne = 0;
  for (size_t i = 0; entries && i < n_before; ++i)
    if ((entries[ne] = strdup(entries_before[i]))) ++ne;
  if (!used || !entries || !first_line) {
    s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
  } else if (km__read_file(labels_csv, &data, &size, NULL) != KM_OK) {
    s = km__fail(err, KM_ERR_IO, "%s: cannot open the labels file", labels_csv);
  }
  int line_no = 0;
  for (char *line = data, *next; s == KM_OK && line && *line; line = next) {
    next = strchr(line, '\n');
    if (next) *next++ = '\0';
    ++line_no;
    line[strcspn(line, "\r")] = '\0';
    char *fields[3] = {NULL, NULL, NULL}, *save = NULL;
    int nf = 0;
    for (char *tok = strtok_r(line, ",;\t", &save); tok && nf < 3;
         tok = strtok_r(NULL, ",;\t", &save)) {
      while (*tok == ' ')
        ++tok;
      fields[nf++] = tok;
    }
    if (nf == 0 || fields[0][0] == '#') continue;
    if (nf < 2) {
      s = km__fail(err, KM_ERR_PARSE, "%s:%d: expected 'mesh,class[,subject]'", labels_csv,
                   line_no);
      break;
    }
    size_t k = 0;
    while (k < np && strcmp(paths[k], fields[0]) && strcmp(base_name(paths[k]), fields[0]))
      ++k;
    if (k == np) {
      if (line_no == 1) continue; /* a header line */
      s = km__fail(err, KM_ERR_PARSE, "%s:%d: '%s' is not among the meshes of %s", labels_csv,
                   line_no, fields[0], meshes);
      break;
    }
    if (used[k]) {
      /* The same mesh twice: one sample, not two (a duplicate would leak into both sides of the
       * cross-validation); the first line wins. */
      km__log(KM_LOG_WARN, "%s:%d: '%s' is labelled again (first on line %d): line ignored",
              labels_csv, line_no, fields[0], first_line[k]);
      ++n_dup;
      continue;
    }
    if (ne >= np + n_before) break;
    used[k] = true;
    first_line[k] = line_no;
    size_t len = strlen(fields[1]) + strlen(paths[k]) + (fields[2] ? strlen(fields[2]) : 0) + 4;
    if (!(entries[ne] = malloc(len))) {
      s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
      break;
    }
    snprintf(entries[ne++], len, "%s=%s%s%s", fields[1], paths[k], fields[2] ? "@" : "",
             fields[2] ? fields[2] : "");
  }
  free(data);
  if (s == KM_OK) s = km_pose_set_from_entries((const char *const *)entries, ne, out, err);
  if (s == KM_OK) {
    /* a mesh the labels do not name is left out: the caller says so */
    out->n_listed = np;
    out->n_duplicates = n_dup;
    for (size_t k = 0; k < np; ++k)
      out->n_unlabelled += !used[k];
    out->unlabelled =
        km__calloc(out->n_unlabelled ? out->n_unlabelled : 1, sizeof *out->unlabelled);
    size_t u = 0;
    for (size_t k = 0; out->unlabelled && k < np; ++k)
      if (!used[k]) out->unlabelled[u++] = strdup(paths[k]);
    if (!out->unlabelled) {
      km_pose_set_free(out);
      s = km__fail(err, KM_ERR_NOMEM, "pose set: out of memory");
    }
  }
  km_paths_free(&entries, ne);
  km_paths_free(&paths, np);
  free(used);
  free(first_line);
  return s;
}
