/* glTF 2.0 binary output: the rest mesh plus one morph target per key frame holding float32
 * POSITION displacements, and an animation whose LINEAR weights sampler is one-hot per key,
 * so players crossfade between consecutive keys. Many morph targets (hundreds) are valid
 * glTF; Blender imports them as shape keys (named through mesh.extras.targetNames).
 * The frame rate, frame count and key spacing are kept in asset.extras.kinemesh so
 * km_anim_info_read can report them exactly.
 * A rest mesh with texture coordinates or normals (issue 11) also gets TEXCOORD_0 (the UVs
 * as read, v flipped to glTF's top-left origin: v' = 1 - v) and NORMAL on the base mesh, and
 * every morph target carries a NORMAL displacement: the key's own recomputed area-weighted
 * normals minus the rest's, so viewers shade each frame correctly without recomputing
 * anything. A mesh without attributes is written as before (positions only; viewers then
 * shade flat from the morphed positions). */
#include "anim/anim.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#define GLB_MAGIC 0x46546C67u /* "glTF" */
#define GLB_JSON 0x4E4F534Au  /* "JSON" */
#define GLB_BIN 0x004E4942u   /* "BIN\0" */
#define GL_FLOAT 5126
#define GL_UNSIGNED_INT 5125
#define GL_ARRAY_BUFFER 34962
#define GL_ELEMENT_ARRAY_BUFFER 34963

static cJSON *num_array(const float *v, int n) {
  cJSON *a = cJSON_CreateArray();
  for (int i = 0; a && i < n; ++i)
    cJSON_AddItemToArray(a, cJSON_CreateNumber((double)v[i]));
  return a;
}

/* Appends a bufferView + accessor pair and returns the accessor index. */
static int add_view_accessor(cJSON *views, cJSON *accessors, uint64_t offset, uint64_t length,
                             int target, int component, size_t count, const char *type,
                             const float *min, const float *max, int n_minmax) {
  cJSON *v = cJSON_CreateObject();
  cJSON_AddNumberToObject(v, "buffer", 0);
  cJSON_AddNumberToObject(v, "byteOffset", (double)offset);
  cJSON_AddNumberToObject(v, "byteLength", (double)length);
  if (target) cJSON_AddNumberToObject(v, "target", target);
  cJSON_AddItemToArray(views, v);
  cJSON *a = cJSON_CreateObject();
  cJSON_AddNumberToObject(a, "bufferView", cJSON_GetArraySize(views) - 1);
  cJSON_AddNumberToObject(a, "componentType", component);
  cJSON_AddNumberToObject(a, "count", (double)count);
  cJSON_AddStringToObject(a, "type", type);
  if (min) {
    cJSON_AddItemToObject(a, "min", num_array(min, n_minmax));
    cJSON_AddItemToObject(a, "max", num_array(max, n_minmax));
  }
  cJSON_AddItemToArray(accessors, a);
  return cJSON_GetArraySize(accessors) - 1;
}

static km_status write_all(km_anim_writer *w, FILE *f, const void *p, size_t n, km_error *err) {
  if (n && fwrite(p, 1, n, f) != n)
    return km__fail(err, KM_ERR_IO, "%s: write failed: %s", w->path, strerror(errno));
  return KM_OK;
}

km_status km__glb_finish(km_anim_writer *w, km_error *err) {
  /* The last frame always closes the animation, key or not. */
  if ((w->frames - 1) % w->key_every != 0) {
    if (fseek(w->keys, 0, SEEK_END) != 0)
      return km__fail(err, KM_ERR_IO, "%s: cannot seek the key-frame temporary", w->path);
    if (fwrite(w->last, sizeof *w->last, w->n_vertices * 3, w->keys) != w->n_vertices * 3)
      return km__fail(err, KM_ERR_IO, "%s: cannot write the last key frame: %s", w->path,
                      strerror(errno));
    if (w->n_keys == w->key_cap) {
      size_t *kf = realloc(w->key_frame, (w->key_cap + 1) * sizeof *kf);
      if (kf) w->key_frame = kf;
      float *km = kf ? realloc(w->key_minmax, (w->key_cap + 1) * 6 * sizeof *km) : NULL;
      if (km) w->key_minmax = km;
      if (!kf || !km) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
      ++w->key_cap;
    }
    w->key_frame[w->n_keys] = w->frames - 1;
    memcpy(w->key_minmax + 6 * w->n_keys, w->last_minmax, sizeof w->last_minmax);
    ++w->n_keys;
  }
  const size_t nv = w->n_vertices, nf = w->n_faces, nk = w->n_keys;

  /* Binary layout: indices, rest positions, targets, key times, weights. Every piece is a
   * multiple of 4 bytes, so every bufferView offset is 4-aligned. */
  uint64_t off = 0;
  const uint64_t idx_len = (uint64_t)nf * 12, pos_len = (uint64_t)nv * 12;
  /* PCA morphs (issue 16): nk basis targets, one weights row per frame; else one-hot keys. */
  const bool pca = w->pca_weights != NULL;
  const size_t nt = pca ? w->pca_frames : nk;
  const uint64_t times_len = (uint64_t)nt * 4, weights_len = (uint64_t)nt * nk * 4;
  const bool with_n = w->normals;
  const uint64_t uv_len = w->uv ? (uint64_t)nv * 8 : 0;
  uint64_t bin_len =
      idx_len + pos_len * (1 + nk) * (with_n ? 2 : 1) + uv_len + times_len + weights_len;
  if (bin_len + (64u << 20) > UINT32_MAX)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: %zu key frames of %zu vertices exceed the 4 GiB glb limit; use "
                    "key_every > 1 or pc2",
                    w->path, nk, nv);

  float *times = km__malloc(nt, sizeof *times);
  if (!times) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  for (size_t k = 0; k < nt; ++k)
    times[k] = (float)((double)(pca ? k : w->key_frame[k]) / w->fps);

  cJSON *root = cJSON_CreateObject();
  cJSON *asset = cJSON_AddObjectToObject(root, "asset");
  cJSON_AddStringToObject(asset, "version", "2.0");
  cJSON_AddStringToObject(asset, "generator", "kinemesh");
  cJSON *ex = cJSON_AddObjectToObject(cJSON_AddObjectToObject(asset, "extras"), "kinemesh");
  cJSON_AddNumberToObject(ex, "fps", w->fps);
  cJSON_AddNumberToObject(ex, "frames", (double)w->frames);
  cJSON_AddNumberToObject(ex, "key_every", (double)w->key_every);
  if (pca) {
    char ek[32];
    snprintf(ek, sizeof ek, "morphs:%zu", nk);
    cJSON_AddStringToObject(ex, "export", ek);
    cJSON_AddNumberToObject(ex, "rms_error_m", w->pca_rms);
    cJSON_AddNumberToObject(ex, "max_error_m", w->pca_max);
  }
  cJSON_AddNumberToObject(root, "scene", 0);
  cJSON *scene = cJSON_CreateObject();
  cJSON_AddItemToObject(scene, "nodes", cJSON_CreateIntArray((const int[]){0}, 1));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);
  cJSON *node = cJSON_CreateObject();
  cJSON_AddNumberToObject(node, "mesh", 0);
  cJSON_AddStringToObject(node, "name", "kinemesh");
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "nodes"), node);

  cJSON *views = cJSON_CreateArray(), *accessors = cJSON_CreateArray();
  cJSON *prim = cJSON_CreateObject();
  if (nf) {
    int a = add_view_accessor(views, accessors, off, idx_len, GL_ELEMENT_ARRAY_BUFFER,
                              GL_UNSIGNED_INT, nf * 3, "SCALAR", NULL, NULL, 0);
    cJSON_AddNumberToObject(prim, "indices", a);
    off += idx_len;
  }
  int a_pos = add_view_accessor(views, accessors, off, pos_len, GL_ARRAY_BUFFER, GL_FLOAT, nv,
                                "VEC3", w->rest_minmax, w->rest_minmax + 3, 3);
  off += pos_len;
  cJSON *attrs = cJSON_AddObjectToObject(prim, "attributes");
  cJSON_AddNumberToObject(attrs, "POSITION", a_pos);
  if (with_n) {
    int a_n = add_view_accessor(views, accessors, off, pos_len, GL_ARRAY_BUFFER, GL_FLOAT, nv,
                                "VEC3", NULL, NULL, 0);
    off += pos_len;
    cJSON_AddNumberToObject(attrs, "NORMAL", a_n);
  }
  if (w->uv) {
    int a_t = add_view_accessor(views, accessors, off, uv_len, GL_ARRAY_BUFFER, GL_FLOAT, nv,
                                "VEC2", NULL, NULL, 0);
    off += uv_len;
    cJSON_AddNumberToObject(attrs, "TEXCOORD_0", a_t);
  }
  cJSON_AddNumberToObject(prim, "mode", nf ? 4 : 0); /* triangles, or points for a cloud */
  cJSON *targets = cJSON_AddArrayToObject(prim, "targets");
  cJSON *names = cJSON_CreateArray();
  for (size_t k = 0; k < nk; ++k) {
    const float *mm = w->key_minmax + 6 * k;
    int a = add_view_accessor(views, accessors, off, pos_len, GL_ARRAY_BUFFER, GL_FLOAT, nv, "VEC3",
                              mm, mm + 3, 3);
    off += pos_len;
    cJSON *t = cJSON_CreateObject();
    cJSON_AddNumberToObject(t, "POSITION", a);
    if (with_n) {
      int a_n = add_view_accessor(views, accessors, off, pos_len, GL_ARRAY_BUFFER, GL_FLOAT, nv,
                                  "VEC3", NULL, NULL, 0);
      off += pos_len;
      cJSON_AddNumberToObject(t, "NORMAL", a_n);
    }
    cJSON_AddItemToArray(targets, t);
    char nm[32];
    if (pca)
      snprintf(nm, sizeof nm, "basis_%03zu", k);
    else
      snprintf(nm, sizeof nm, "frame_%06zu", w->key_frame[k]);
    cJSON_AddItemToArray(names, cJSON_CreateString(nm));
  }
  cJSON *mesh = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(mesh, "primitives"), prim);
  cJSON *weights0 = cJSON_AddArrayToObject(mesh, "weights");
  for (size_t k = 0; k < nk; ++k)
    cJSON_AddItemToArray(weights0, cJSON_CreateNumber(0));
  cJSON_AddItemToObject(cJSON_AddObjectToObject(mesh, "extras"), "targetNames", names);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);

  int a_in = add_view_accessor(views, accessors, off, times_len, 0, GL_FLOAT, nt, "SCALAR",
                               &times[0], &times[nt - 1], 1);
  off += times_len;
  int a_out = add_view_accessor(views, accessors, off, weights_len, 0, GL_FLOAT, nt * nk, "SCALAR",
                                NULL, NULL, 0);
  off += weights_len;
  cJSON *sampler = cJSON_CreateObject();
  cJSON_AddNumberToObject(sampler, "input", a_in);
  cJSON_AddStringToObject(sampler, "interpolation", "LINEAR");
  cJSON_AddNumberToObject(sampler, "output", a_out);
  cJSON *channel = cJSON_CreateObject();
  cJSON_AddNumberToObject(channel, "sampler", 0);
  cJSON *target = cJSON_AddObjectToObject(channel, "target");
  cJSON_AddNumberToObject(target, "node", 0);
  cJSON_AddStringToObject(target, "path", "weights");
  cJSON *anim = cJSON_CreateObject();
  cJSON_AddStringToObject(anim, "name", "kinemesh");
  cJSON_AddItemToArray(cJSON_AddArrayToObject(anim, "channels"), channel);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(anim, "samplers"), sampler);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "animations"), anim);
  cJSON *buffer = cJSON_CreateObject();
  cJSON_AddNumberToObject(buffer, "byteLength", (double)bin_len);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "buffers"), buffer);
  cJSON_AddItemToObject(root, "bufferViews", views);
  cJSON_AddItemToObject(root, "accessors", accessors);

  char *json = cJSON_PrintUnformatted(root);
  cJSON_Delete(root);
  if (!json || off != bin_len) {
    free(json);
    free(times);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory building the glTF JSON", w->path);
  }
  size_t json_len = strlen(json), json_pad = (4 - json_len % 4) % 4;
  uint64_t total = 12 + 8 + json_len + json_pad + 8 + bin_len;
  if (total > UINT32_MAX) {
    free(json);
    free(times);
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: glb would exceed 4 GiB", w->path);
  }

  km__atomic_file af = w->af; /* opened by km_anim_writer_open */
  memset(&w->af, 0, sizeof w->af);
  km_status s = KM_OK;
  unsigned char h[20];
  km__put_u32le(h, GLB_MAGIC);
  km__put_u32le(h + 4, 2);
  km__put_u32le(h + 8, (uint32_t)total);
  km__put_u32le(h + 12, (uint32_t)(json_len + json_pad));
  km__put_u32le(h + 16, GLB_JSON);
  s = write_all(w, af.f, h, 20, err);
  if (s == KM_OK) s = write_all(w, af.f, json, json_len, err);
  if (s == KM_OK) s = write_all(w, af.f, "   ", json_pad, err);
  free(json);
  km__put_u32le(h, (uint32_t)bin_len);
  km__put_u32le(h + 4, GLB_BIN);
  if (s == KM_OK) s = write_all(w, af.f, h, 8, err);

  unsigned char *b = w->bytes;
  if (s == KM_OK && nf) {
    /* Indices in chunks that reuse the per-vertex scratch buffer (nv*12 bytes). */
    size_t chunk = nv, done = 0;
    while (s == KM_OK && done < nf * 3) {
      size_t n = nf * 3 - done < chunk ? nf * 3 - done : chunk;
      for (size_t i = 0; i < n; ++i)
        km__put_u32le(b + 4 * i, (uint32_t)w->F[done + i]);
      s = write_all(w, af.f, b, 4 * n, err);
      done += n;
    }
  }
  if (s == KM_OK) {
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, (float)w->rest[i]);
    s = write_all(w, af.f, b, nv * 12, err);
  }
  /* Rest normals are kept in vbuf's place until the keys need it: nbuf is reused per key. */
  double *rest_n = NULL;
  if (s == KM_OK && with_n) {
    rest_n = km__malloc(nv * 3, sizeof *rest_n);
    if (!rest_n) s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  }
  if (s == KM_OK && with_n) {
    km__anim_normals(w, w->rest);
    memcpy(rest_n, w->nbuf, nv * 3 * sizeof *rest_n);
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, (float)rest_n[i]);
    s = write_all(w, af.f, b, nv * 12, err);
  }
  if (s == KM_OK && w->uv) {
    for (size_t i = 0; i < nv; ++i) {
      km__put_f32le(b + 8 * i, (float)w->uv[2 * i]);
      km__put_f32le(b + 8 * i + 4, (float)(1.0 - w->uv[2 * i + 1]));
    }
    s = write_all(w, af.f, b, nv * 8, err);
  }
  if (s == KM_OK && fseek(w->keys, 0, SEEK_SET) != 0)
    s = km__fail(err, KM_ERR_IO, "%s: cannot rewind the key-frame temporary", w->path);
  for (size_t k = 0; s == KM_OK && k < nk; ++k) {
    if (fread(w->fbuf, sizeof *w->fbuf, nv * 3, w->keys) != nv * 3) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot read key frame %zu back from its temporary", w->path,
                   k);
      break;
    }
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, w->fbuf[i]);
    s = write_all(w, af.f, b, nv * 12, err);
    if (s == KM_OK && with_n) {
      for (size_t i = 0; i < nv * 3; ++i)
        w->vbuf[i] = w->rest[i] + (double)w->fbuf[i];
      km__anim_normals(w, w->vbuf);
      for (size_t i = 0; i < nv * 3; ++i)
        km__put_f32le(b + 4 * i, (float)(w->nbuf[i] - rest_n[i]));
      s = write_all(w, af.f, b, nv * 12, err);
    }
  }
  free(rest_n);
  /* Key times, then one-hot weights (one row of nk per key), through a row buffer: there
   * can be more keys than vertices. */
  size_t rl = nt > nk ? nt : nk;
  unsigned char *row = s == KM_OK ? calloc(rl, 4) : NULL;
  if (s == KM_OK && !row) s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  if (s == KM_OK) {
    for (size_t k = 0; k < nt; ++k)
      km__put_f32le(row + 4 * k, times[k]);
    s = write_all(w, af.f, row, 4 * nt, err);
    memset(row, 0, 4 * rl);
  }
  free(times);
  for (size_t t = 0; pca && s == KM_OK && t < nt; ++t) {
    for (size_t k = 0; k < nk; ++k)
      km__put_f32le(row + 4 * k, w->pca_weights[t * nk + k]);
    s = write_all(w, af.f, row, 4 * nk, err);
  }
  for (size_t k = 0; !pca && s == KM_OK && k < nk; ++k) {
    km__put_f32le(row + 4 * k, 1.0f);
    s = write_all(w, af.f, row, 4 * nk, err);
    km__put_f32le(row + 4 * k, 0.0f);
  }
  free(row);
  if (s != KM_OK) {
    km__atomic_abort(&af);
    return s;
  }
  return km__atomic_commit(&af, err);
}

/* ---------------------------------------------------------------- info */

static const cJSON *get_path(const cJSON *o, const char *key, int index) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (index >= 0) v = cJSON_IsArray(v) ? cJSON_GetArrayItem(v, index) : NULL;
  return v;
}

static bool get_count(const cJSON *accessors, const cJSON *index, double *count) {
  if (!cJSON_IsNumber(index)) return false;
  const cJSON *a = cJSON_GetArrayItem(accessors, index->valueint);
  const cJSON *c = cJSON_GetObjectItemCaseSensitive(a, "count");
  if (!cJSON_IsNumber(c) || !(c->valuedouble >= 0 && c->valuedouble < 4294967296.0)) return false;
  *count = c->valuedouble;
  return true;
}

km_status km__glb_info(const char *path, km_anim_info *out, km_error *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  unsigned char h[20];
  size_t got = fread(h, 1, sizeof h, f);
  long size = -1;
  if (fseek(f, 0, SEEK_END) == 0) size = ftell(f);
  km_status s = KM_OK;
  char *json = NULL;
  if (got < sizeof h)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte %zu: truncated glb header (20 bytes expected)", path,
                 got);
  else if (km__get_u32le(h) != GLB_MAGIC)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 0: not a glTF binary (magic is not 'glTF')", path);
  else if (km__get_u32le(h + 4) != 2)
    s = km__fail(err, KM_ERR_UNSUPPORTED, "%s: byte 4: glb version %u, expected 2", path,
                 km__get_u32le(h + 4));
  else if (size < 0 || km__get_u32le(h + 8) != (uint64_t)size)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 8: header length %u but the file has %ld bytes", path,
                 km__get_u32le(h + 8), size);
  else if (km__get_u32le(h + 16) != GLB_JSON)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 16: first chunk is not JSON", path);
  else if ((uint64_t)km__get_u32le(h + 12) > (uint64_t)size - 20)
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 12: JSON chunk length %u runs past the end", path,
                 km__get_u32le(h + 12));
  size_t jl = s == KM_OK ? km__get_u32le(h + 12) : 0;
  if (s == KM_OK && !(json = malloc(jl + 1)))
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  if (s == KM_OK && (fseek(f, 20, SEEK_SET) != 0 || fread(json, 1, jl, f) != jl))
    s = km__fail(err, KM_ERR_IO, "%s: cannot read the JSON chunk", path);
  fclose(f);
  if (s != KM_OK) {
    free(json);
    return s;
  }
  json[jl] = '\0';
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(json, jl, &end, false);
  if (!root) {
    size_t at = end && end >= json ? (size_t)(end - json) : 0;
    free(json);
    return km__fail(err, KM_ERR_PARSE, "%s: byte %zu: invalid JSON in the glb JSON chunk", path,
                    20 + at);
  }
  free(json);
  const cJSON *accessors = cJSON_GetObjectItemCaseSensitive(root, "accessors");
  const cJSON *prim = get_path(get_path(root, "meshes", 0), "primitives", 0);
  const cJSON *pos = get_path(get_path(prim, "attributes", -1), "POSITION", -1);
  double count = 0;
  if (!prim || !get_count(accessors, pos, &count)) {
    cJSON_Delete(root);
    return km__fail(err, KM_ERR_PARSE,
                    "%s: JSON: meshes[0].primitives[0].attributes.POSITION does not name an "
                    "accessor with a count",
                    path);
  }
  out->format = KM_ANIM_GLB;
  out->vertices = (size_t)count;
  const cJSON *mode = get_path(prim, "mode", -1);
  int m = cJSON_IsNumber(mode) ? mode->valueint : 4;
  const cJSON *ind = get_path(prim, "indices", -1);
  if (m == 4) {
    if (ind && get_count(accessors, ind, &count))
      out->faces = (size_t)count / 3;
    else if (!ind)
      out->faces = out->vertices / 3;
  }
  out->frames = (size_t)cJSON_GetArraySize(get_path(prim, "targets", -1));
  /* Timing: exact values from our own extras; otherwise from the sampler's key times,
   * assuming evenly spaced keys. */
  const cJSON *ex = get_path(get_path(get_path(root, "asset", -1), "extras", -1), "kinemesh", -1);
  const cJSON *fps = get_path(ex, "fps", -1);
  const cJSON *total = get_path(ex, "frames", -1);
  if (cJSON_IsNumber(total) && total->valuedouble >= 1 && total->valuedouble < 1e12)
    out->timeline_frames = (size_t)total->valuedouble;
  /* A skinned export (issue 16) has no targets: its frames are the timeline's. */
  if (cJSON_IsString(get_path(ex, "export", -1)) && out->timeline_frames)
    out->frames = out->timeline_frames;
  const cJSON *input =
      get_path(get_path(get_path(root, "animations", 0), "samplers", 0), "input", -1);
  const cJSON *in_acc =
      cJSON_IsNumber(input) ? cJSON_GetArrayItem(accessors, input->valueint) : NULL;
  const cJSON *tmax = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(in_acc, "max"), 0);
  double n_in = 0;
  if (cJSON_IsNumber(tmax)) out->duration = tmax->valuedouble;
  if (cJSON_IsNumber(fps) && fps->valuedouble > 0) {
    out->fps = fps->valuedouble;
  } else if (cJSON_IsNumber(tmax) && tmax->valuedouble > 0 && get_count(accessors, input, &n_in) &&
             n_in > 1) {
    out->fps = (n_in - 1) / tmax->valuedouble;
  }
  cJSON_Delete(root);
  return KM_OK;
}

/* ---------------------------------------------------------------- skinned export (issue 16) */

/* Appends n bytes to a growing binary chunk, 4-aligned. */
typedef struct bin_buf {
  unsigned char *p;
  size_t len, cap;
} bin_buf;

static unsigned char *bin_grow(bin_buf *b, size_t n) {
  size_t need = b->len + ((n + 3) & ~(size_t)3);
  if (need > b->cap) {
    size_t cap = b->cap ? b->cap : 1 << 16;
    while (cap < need)
      cap *= 2;
    unsigned char *p = realloc(b->p, cap);
    if (!p) return NULL;
    b->p = p;
    b->cap = cap;
  }
  unsigned char *at = b->p + b->len;
  memset(at, 0, need - b->len);
  b->len = need;
  return at;
}

/* Row-major rotation to a unit quaternion (x, y, z, w). */
static void quat_from_m3(const double R[9], double q[4]) {
  double tr = R[0] + R[4] + R[8];
  if (tr > 0) {
    double s = sqrt(tr + 1.0) * 2;
    q[3] = 0.25 * s;
    q[0] = (R[7] - R[5]) / s;
    q[1] = (R[2] - R[6]) / s;
    q[2] = (R[3] - R[1]) / s;
  } else if (R[0] > R[4] && R[0] > R[8]) {
    double s = sqrt(1.0 + R[0] - R[4] - R[8]) * 2;
    q[3] = (R[7] - R[5]) / s;
    q[0] = 0.25 * s;
    q[1] = (R[1] + R[3]) / s;
    q[2] = (R[2] + R[6]) / s;
  } else if (R[4] > R[8]) {
    double s = sqrt(1.0 + R[4] - R[0] - R[8]) * 2;
    q[3] = (R[2] - R[6]) / s;
    q[0] = (R[1] + R[3]) / s;
    q[1] = 0.25 * s;
    q[2] = (R[5] + R[7]) / s;
  } else {
    double s = sqrt(1.0 + R[8] - R[0] - R[4]) * 2;
    q[3] = (R[3] - R[1]) / s;
    q[0] = (R[2] + R[6]) / s;
    q[1] = (R[5] + R[7]) / s;
    q[2] = 0.25 * s;
  }
  double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (int k = 0; k < 4; ++k)
    q[k] /= l;
}

km_status km__glb_write_skin(km_anim_writer *w, const km_ssdr *fit, km_error *err) {
  const size_t nv = w->n_vertices, nf = w->n_faces, B = fit->n_bones, T = fit->n_frames;
  bin_buf b = {0};
  cJSON *root = cJSON_CreateObject();
  cJSON *views = cJSON_CreateArray(), *accessors = cJSON_CreateArray();
  km_status s = KM_OK;
  unsigned char *p;
#define GROW(n)                                                                                    \
  do {                                                                                             \
    if (!(p = bin_grow(&b, (n)))) goto nomem;                                                      \
  } while (0)

  cJSON *asset = cJSON_AddObjectToObject(root, "asset");
  cJSON_AddStringToObject(asset, "version", "2.0");
  cJSON_AddStringToObject(asset, "generator", "kinemesh");
  cJSON *ex = cJSON_AddObjectToObject(cJSON_AddObjectToObject(asset, "extras"), "kinemesh");
  cJSON_AddNumberToObject(ex, "fps", w->fps);
  cJSON_AddNumberToObject(ex, "frames", (double)T);
  cJSON_AddNumberToObject(ex, "key_every", 1);
  cJSON_AddStringToObject(ex, "export", "skin");
  cJSON_AddNumberToObject(ex, "bones", (double)B);
  cJSON_AddNumberToObject(ex, "rms_error_m", fit->rms_error);
  cJSON_AddNumberToObject(ex, "max_error_m", fit->max_error);

  /* ---- the mesh: indices, rest positions, normals, UVs, joints, weights */
  cJSON *prim = cJSON_CreateObject();
  cJSON *attrs = cJSON_AddObjectToObject(prim, "attributes");
  size_t off;
  if (nf) {
    off = b.len;
    GROW(nf * 12);
    for (size_t i = 0; i < nf * 3; ++i)
      km__put_u32le(p + 4 * i, (uint32_t)w->F[i]);
    cJSON_AddNumberToObject(prim, "indices",
                            add_view_accessor(views, accessors, off, nf * 12,
                                              GL_ELEMENT_ARRAY_BUFFER, GL_UNSIGNED_INT, nf * 3,
                                              "SCALAR", NULL, NULL, 0));
  }
  off = b.len;
  GROW(nv * 12);
  for (size_t i = 0; i < nv * 3; ++i)
    km__put_f32le(p + 4 * i, (float)w->rest[i]);
  cJSON_AddNumberToObject(attrs, "POSITION",
                          add_view_accessor(views, accessors, off, nv * 12, GL_ARRAY_BUFFER,
                                            GL_FLOAT, nv, "VEC3", w->rest_minmax,
                                            w->rest_minmax + 3, 3));
  if (nf) {
    /* Engines skin the normals with the bones, so the rest's normals are all they need. */
    if (!w->nbuf && !(w->nbuf = km__malloc(nv * 3, sizeof *w->nbuf))) goto nomem;
    km__anim_normals(w, w->rest);
    off = b.len;
    GROW(nv * 12);
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(p + 4 * i, (float)w->nbuf[i]);
    cJSON_AddNumberToObject(attrs, "NORMAL",
                            add_view_accessor(views, accessors, off, nv * 12, GL_ARRAY_BUFFER,
                                              GL_FLOAT, nv, "VEC3", NULL, NULL, 0));
  }
  if (w->uv) {
    off = b.len;
    GROW(nv * 8);
    for (size_t i = 0; i < nv; ++i) {
      km__put_f32le(p + 8 * i, (float)w->uv[2 * i]);
      km__put_f32le(p + 8 * i + 4, (float)(1.0 - w->uv[2 * i + 1]));
    }
    cJSON_AddNumberToObject(attrs, "TEXCOORD_0",
                            add_view_accessor(views, accessors, off, nv * 8, GL_ARRAY_BUFFER,
                                              GL_FLOAT, nv, "VEC2", NULL, NULL, 0));
  }
  const bool wide = B > 256;
  off = b.len;
  GROW(nv * (wide ? 8 : 4));
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 4; ++k) {
      int32_t j = fit->skin.joints[4 * i + k];
      uint32_t v = j < 0 ? 0 : (uint32_t)j;
      if (wide) {
        p[8 * i + 2 * k] = (unsigned char)v;
        p[8 * i + 2 * k + 1] = (unsigned char)(v >> 8);
      } else {
        p[4 * i + k] = (unsigned char)v;
      }
    }
  cJSON_AddNumberToObject(attrs, "JOINTS_0",
                          add_view_accessor(views, accessors, off, nv * (wide ? 8 : 4),
                                            GL_ARRAY_BUFFER, wide ? 5123 : 5121, nv, "VEC4", NULL,
                                            NULL, 0));
  off = b.len;
  GROW(nv * 16);
  for (size_t i = 0; i < nv; ++i) {
    /* float32 weights renormalised so their float sum is 1 (the validator checks it). */
    float f[4];
    double sum = 0;
    int big = 0;
    for (int k = 0; k < 4; ++k) {
      double x = fit->skin.joints[4 * i + k] < 0 ? 0 : fit->skin.weights[4 * i + k];
      f[k] = (float)x;
      if (f[k] > f[big]) big = k;
    }
    for (int k = 0; k < 4; ++k)
      if (k != big) sum += f[k];
    f[big] = (float)(1.0 - sum);
    for (int k = 0; k < 4; ++k)
      km__put_f32le(p + 16 * i + 4 * k, f[k]);
  }
  cJSON_AddNumberToObject(attrs, "WEIGHTS_0",
                          add_view_accessor(views, accessors, off, nv * 16, GL_ARRAY_BUFFER,
                                            GL_FLOAT, nv, "VEC4", NULL, NULL, 0));
  cJSON_AddNumberToObject(prim, "mode", nf ? 4 : 0);
  cJSON *mesh = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(mesh, "primitives"), prim);
  cJSON_AddStringToObject(mesh, "name", "kinemesh");
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);

  /* ---- skeleton: node 0 the skinned mesh, node 1 an identity root, nodes 2.. the bones,
   * each bound at its rest centre with no rotation, so inverseBindMatrix_j = T(-c_j) and the
   * fitted rest->frame transform [R | t] is the node's TRS: rotation R, translation R c_j + t. */
  cJSON *nodes = cJSON_AddArrayToObject(root, "nodes");
  cJSON *n0 = cJSON_CreateObject();
  cJSON_AddStringToObject(n0, "name", "kinemesh");
  cJSON_AddNumberToObject(n0, "mesh", 0);
  cJSON_AddNumberToObject(n0, "skin", 0);
  cJSON_AddItemToArray(nodes, n0);
  cJSON *n1 = cJSON_CreateObject();
  cJSON_AddStringToObject(n1, "name", "armature");
  cJSON *children = cJSON_AddArrayToObject(n1, "children");
  cJSON_AddItemToArray(nodes, n1);
  cJSON *joints = cJSON_CreateArray();
  for (size_t j = 0; j < B; ++j) {
    cJSON_AddItemToArray(children, cJSON_CreateNumber((double)(j + 2)));
    cJSON_AddItemToArray(joints, cJSON_CreateNumber((double)(j + 2)));
    cJSON *nj = cJSON_CreateObject();
    char nm[32];
    snprintf(nm, sizeof nm, "bone_%03zu", j);
    cJSON_AddStringToObject(nj, "name", nm);
    float c[3] = {(float)fit->centers[3 * j], (float)fit->centers[3 * j + 1],
                  (float)fit->centers[3 * j + 2]};
    cJSON_AddItemToObject(nj, "translation", num_array(c, 3));
    cJSON_AddItemToArray(nodes, nj);
  }
  off = b.len;
  GROW(B * 64);
  for (size_t j = 0; j < B; ++j) {
    float m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (int a = 0; a < 3; ++a)
      m[12 + a] = -(float)fit->centers[3 * j + a]; /* column-major: translation last */
    for (int k = 0; k < 16; ++k)
      km__put_f32le(p + 64 * j + 4 * k, m[k]);
  }
  int a_ibm =
      add_view_accessor(views, accessors, off, B * 64, 0, GL_FLOAT, B, "MAT4", NULL, NULL, 0);
  cJSON *skin = cJSON_CreateObject();
  cJSON_AddNumberToObject(skin, "inverseBindMatrices", a_ibm);
  cJSON_AddNumberToObject(skin, "skeleton", 1);
  cJSON_AddItemToObject(skin, "joints", joints);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "skins"), skin);
  cJSON_AddNumberToObject(root, "scene", 0);
  cJSON *scene = cJSON_CreateObject();
  cJSON_AddItemToObject(scene, "nodes", cJSON_CreateIntArray((const int[]){0, 1}, 2));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);

  /* ---- animation: shared key times, then per bone a translation and a rotation channel */
  off = b.len;
  GROW(T * 4);
  for (size_t t = 0; t < T; ++t)
    km__put_f32le(p + 4 * t, (float)((double)t / w->fps));
  float tmin = 0, tmax = (float)((double)(T - 1) / w->fps);
  int a_time =
      add_view_accessor(views, accessors, off, T * 4, 0, GL_FLOAT, T, "SCALAR", &tmin, &tmax, 1);
  cJSON *anim = cJSON_CreateObject();
  cJSON_AddStringToObject(anim, "name", "kinemesh");
  cJSON *channels = cJSON_AddArrayToObject(anim, "channels");
  cJSON *samplers = cJSON_AddArrayToObject(anim, "samplers");
  for (size_t j = 0; j < B; ++j) {
    size_t off_t = b.len;
    GROW(T * 12);
    unsigned char *pt = p;
    size_t off_r = b.len;
    GROW(T * 16);
    unsigned char *pr = p;
    pt = b.p + off_t; /* the second GROW may have moved the buffer */
    double qprev[4] = {0, 0, 0, 1};
    for (size_t t = 0; t < T; ++t) {
      const double *M = fit->transforms + (t * B + j) * 12;
      const double *c = fit->centers + 3 * j;
      double R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]}, q[4];
      for (int a = 0; a < 3; ++a)
        km__put_f32le(pt + 12 * t + 4 * a, (float)(R[3 * a] * c[0] + R[3 * a + 1] * c[1] +
                                                   R[3 * a + 2] * c[2] + M[4 * a + 3]));
      quat_from_m3(R, q);
      /* the shorter arc between keys: players interpolate (s)linearly */
      if (q[0] * qprev[0] + q[1] * qprev[1] + q[2] * qprev[2] + q[3] * qprev[3] < 0)
        for (int k = 0; k < 4; ++k)
          q[k] = -q[k];
      memcpy(qprev, q, sizeof q);
      for (int k = 0; k < 4; ++k)
        km__put_f32le(pr + 16 * t + 4 * k, (float)q[k]);
    }
    int a_t =
        add_view_accessor(views, accessors, off_t, T * 12, 0, GL_FLOAT, T, "VEC3", NULL, NULL, 0);
    int a_r =
        add_view_accessor(views, accessors, off_r, T * 16, 0, GL_FLOAT, T, "VEC4", NULL, NULL, 0);
    const char *paths[2] = {"translation", "rotation"};
    int outs[2] = {a_t, a_r};
    for (int k = 0; k < 2; ++k) {
      cJSON *sm = cJSON_CreateObject();
      cJSON_AddNumberToObject(sm, "input", a_time);
      cJSON_AddStringToObject(sm, "interpolation", "LINEAR");
      cJSON_AddNumberToObject(sm, "output", outs[k]);
      cJSON_AddItemToArray(samplers, sm);
      cJSON *ch = cJSON_CreateObject();
      cJSON_AddNumberToObject(ch, "sampler", cJSON_GetArraySize(samplers) - 1);
      cJSON *tg = cJSON_AddObjectToObject(ch, "target");
      cJSON_AddNumberToObject(tg, "node", (double)(j + 2));
      cJSON_AddStringToObject(tg, "path", paths[k]);
      cJSON_AddItemToArray(channels, ch);
    }
  }
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "animations"), anim);
  cJSON *buffer = cJSON_CreateObject();
  cJSON_AddNumberToObject(buffer, "byteLength", (double)b.len);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "buffers"), buffer);
  cJSON_AddItemToObject(root, "bufferViews", views);
  cJSON_AddItemToObject(root, "accessors", accessors);
  views = accessors = NULL;
#undef GROW

  char *json = cJSON_PrintUnformatted(root);
  cJSON_Delete(root);
  root = NULL;
  if (!json) goto nomem;
  size_t json_len = strlen(json), json_pad = (4 - json_len % 4) % 4;
  uint64_t total = 12 + 8 + json_len + json_pad + 8 + b.len;
  if (total > UINT32_MAX) {
    free(json);
    free(b.p);
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: glb would exceed 4 GiB", w->path);
  }
  km__atomic_file af = w->af;
  memset(&w->af, 0, sizeof w->af);
  unsigned char h[20];
  km__put_u32le(h, GLB_MAGIC);
  km__put_u32le(h + 4, 2);
  km__put_u32le(h + 8, (uint32_t)total);
  km__put_u32le(h + 12, (uint32_t)(json_len + json_pad));
  km__put_u32le(h + 16, GLB_JSON);
  s = write_all(w, af.f, h, 20, err);
  if (s == KM_OK) s = write_all(w, af.f, json, json_len, err);
  if (s == KM_OK) s = write_all(w, af.f, "   ", json_pad, err);
  free(json);
  km__put_u32le(h, (uint32_t)b.len);
  km__put_u32le(h + 4, GLB_BIN);
  if (s == KM_OK) s = write_all(w, af.f, h, 8, err);
  if (s == KM_OK) s = write_all(w, af.f, b.p, b.len, err);
  free(b.p);
  if (s != KM_OK) {
    km__atomic_abort(&af);
    return s;
  }
  return km__atomic_commit(&af, err);
nomem:
  cJSON_Delete(root);
  cJSON_Delete(views);
  cJSON_Delete(accessors);
  free(b.p);
  return km__fail(err, KM_ERR_NOMEM, "%s: out of memory writing the skinned glb", w->path);
}

/* ---------------------------------------------------------------- morph frames (issue 16) */

/* Float data of accessor a (FLOAT, `comps` components, tightly packed or strided), checked
 * against the binary chunk; NULL with err filled otherwise. */
static const unsigned char *float_accessor(const char *path, const cJSON *root,
                                           const unsigned char *bin, size_t bin_len, int a,
                                           int comps, size_t *count, size_t *stride,
                                           km_error *err) {
  const cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "accessors"), a);
  const cJSON *bv = cJSON_GetObjectItemCaseSensitive(acc, "bufferView");
  const cJSON *ct = cJSON_GetObjectItemCaseSensitive(acc, "componentType");
  const cJSON *cn = cJSON_GetObjectItemCaseSensitive(acc, "count");
  if (!cJSON_IsNumber(bv) || !cJSON_IsNumber(ct) || ct->valueint != GL_FLOAT ||
      !cJSON_IsNumber(cn) || cn->valuedouble < 0 ||
      cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(acc, "sparse"))) {
    km__fail(err, KM_ERR_UNSUPPORTED,
             "%s: JSON: accessors[%d] is not a dense float accessor in a bufferView", path, a);
    return NULL;
  }
  const cJSON *view =
      cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "bufferViews"), bv->valueint);
  const cJSON *vo = cJSON_GetObjectItemCaseSensitive(view, "byteOffset");
  const cJSON *ao = cJSON_GetObjectItemCaseSensitive(acc, "byteOffset");
  const cJSON *bs = cJSON_GetObjectItemCaseSensitive(view, "byteStride");
  const cJSON *vl = cJSON_GetObjectItemCaseSensitive(view, "byteLength");
  double off =
      (cJSON_IsNumber(vo) ? vo->valuedouble : 0) + (cJSON_IsNumber(ao) ? ao->valuedouble : 0);
  double st = cJSON_IsNumber(bs) && bs->valuedouble > 0 ? bs->valuedouble : 4.0 * comps;
  double n = cn->valuedouble;
  if (!view || !cJSON_IsNumber(vl) || off < 0 || st < 4.0 * comps ||
      (n > 0 && off + st * (n - 1) + 4.0 * comps > (double)bin_len)) {
    km__fail(err, KM_ERR_PARSE, "%s: JSON: accessors[%d] runs past the binary chunk", path, a);
    return NULL;
  }
  *count = (size_t)n;
  *stride = (size_t)st;
  return bin + (size_t)off;
}

km_status km__glb_frames(const char *path, size_t nv, double **frames, size_t *n_frames,
                         double *fps, km_error *err) {
  *frames = NULL;
  *n_frames = 0;
  char *data = NULL;
  size_t size = 0;
  km_status s = km__read_file(path, &data, &size, err);
  if (s != KM_OK) return s;
  const unsigned char *b = (const unsigned char *)data;
  cJSON *root = NULL;
  double *out = NULL;
  if (size < 28 || km__get_u32le(b) != GLB_MAGIC || km__get_u32le(b + 16) != GLB_JSON ||
      (uint64_t)km__get_u32le(b + 12) + 28 > size) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 0: not a glTF binary with a JSON chunk", path);
    goto done;
  }
  size_t jl = km__get_u32le(b + 12);
  const unsigned char *bin = b + 20 + jl + 8;
  size_t bin_len = km__get_u32le(b + 20 + jl);
  if (km__get_u32le(b + 24 + jl) != GLB_BIN || bin_len > size - 28 - jl) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte %zu: missing or truncated BIN chunk", path, 20 + jl);
    goto done;
  }
  root = cJSON_ParseWithLength(data + 20, jl);
  if (!root) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 20: invalid JSON chunk", path);
    goto done;
  }
  const cJSON *prim = get_path(get_path(root, "meshes", 0), "primitives", 0);
  const cJSON *targets = cJSON_GetObjectItemCaseSensitive(prim, "targets");
  const cJSON *pos = get_path(get_path(prim, "attributes", -1), "POSITION", -1);
  size_t nt = (size_t)cJSON_GetArraySize(targets), cnt = 0, st = 0;
  if (!cJSON_IsNumber(pos) || nt == 0) {
    s = km__fail(err, KM_ERR_UNSUPPORTED,
                 "%s: meshes[0].primitives[0] has no morph targets: not a morph animation", path);
    goto done;
  }
  const unsigned char *base =
      float_accessor(path, root, bin, bin_len, pos->valueint, 3, &cnt, &st, err);
  if (!base) {
    s = err ? err->status : KM_ERR_PARSE;
    goto done;
  }
  if (cnt != nv) {
    s = km__fail(err, KM_ERR_PARSE, "%s: POSITION has %zu vertices, the mesh %zu", path, cnt, nv);
    goto done;
  }
  /* The weights channel (if any): frames at its key times; else one frame per target. */
  const cJSON *anim = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "animations"), 0);
  const cJSON *ch, *wsampler = NULL;
  cJSON_ArrayForEach(ch, cJSON_GetObjectItemCaseSensitive(anim, "channels")) {
    const cJSON *p = get_path(get_path(ch, "target", -1), "path", -1);
    if (cJSON_IsString(p) && !strcmp(p->valuestring, "weights")) {
      const cJSON *si = get_path(ch, "sampler", -1);
      if (cJSON_IsNumber(si)) wsampler = get_path(anim, "samplers", si->valueint);
      break;
    }
  }
  size_t nk = nt, wst = 0, tst = 0, wcnt = 0;
  const unsigned char *wdata = NULL, *tdata = NULL;
  if (wsampler) {
    const cJSON *in = get_path(wsampler, "input", -1), *o = get_path(wsampler, "output", -1);
    if (!cJSON_IsNumber(in) || !cJSON_IsNumber(o) ||
        !(tdata = float_accessor(path, root, bin, bin_len, in->valueint, 1, &nk, &tst, err)) ||
        !(wdata = float_accessor(path, root, bin, bin_len, o->valueint, 1, &wcnt, &wst, err))) {
      s = err && err->status ? err->status : KM_ERR_PARSE;
      if (!err || !err->status)
        km__fail(err, s, "%s: the weights sampler's input/output are not float accessors", path);
      goto done;
    }
    if (wcnt != nk * nt) {
      s = km__fail(err, KM_ERR_UNSUPPORTED,
                   "%s: weights sampler has %zu values for %zu keys x %zu targets (cubic "
                   "splines are not read)",
                   path, wcnt, nk, nt);
      goto done;
    }
    if (nk >= 2) {
      double t0 = km__get_f32le(tdata), t1 = km__get_f32le(tdata + (nk - 1) * tst);
      if (t1 > t0 && fps) *fps = (double)(nk - 1) / (t1 - t0);
    }
  }
  const cJSON *ex = get_path(get_path(get_path(root, "asset", -1), "extras", -1), "kinemesh", -1);
  const cJSON *efps = get_path(ex, "fps", -1);
  if (fps && cJSON_IsNumber(efps) && efps->valuedouble > 0) *fps = efps->valuedouble;
  if (!(out = km__malloc(nk * nv * 3, sizeof *out))) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", path, nk);
    goto done;
  }
  for (size_t k = 0; k < nk; ++k)
    for (size_t i = 0; i < nv; ++i)
      for (int c = 0; c < 3; ++c)
        out[(k * nv + i) * 3 + c] = km__get_f32le(base + i * st + 4 * c);
  for (size_t t = 0; t < nt; ++t) {
    const cJSON *tp = get_path(cJSON_GetArrayItem(targets, (int)t), "POSITION", -1);
    size_t tc = 0, ts = 0;
    const unsigned char *td = cJSON_IsNumber(tp) ? float_accessor(path, root, bin, bin_len,
                                                                  tp->valueint, 3, &tc, &ts, err)
                                                 : NULL;
    if (!td || tc != nv) {
      if (td || !cJSON_IsNumber(tp))
        km__fail(err, KM_ERR_PARSE, "%s: morph target %zu has no POSITION of %zu vertices", path, t,
                 nv);
      s = err && err->status ? err->status : KM_ERR_PARSE;
      goto done;
    }
    for (size_t k = 0; k < nk; ++k) {
      double wk = wdata ? km__get_f32le(wdata + (k * nt + t) * wst) : (k == t ? 1.0 : 0.0);
      if (wk == 0) continue;
      for (size_t i = 0; i < nv; ++i)
        for (int c = 0; c < 3; ++c)
          out[(k * nv + i) * 3 + c] += wk * km__get_f32le(td + i * ts + 4 * c);
    }
  }
  *frames = out;
  *n_frames = nk;
  out = NULL;
done:
  cJSON_Delete(root);
  free(out);
  free(data);
  return s;
}
