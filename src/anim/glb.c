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
#include "math/math.h"
#include "mesh/mesh.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <meshoptimizer.h>
#include <stdlib.h>

#define GLB_MAGIC 0x46546C67u /* "glTF" */
#define GLB_JSON 0x4E4F534Au  /* "JSON" */
#define GLB_BIN 0x004E4942u   /* "BIN\0" */
#define GL_FLOAT 5126
#define GL_BYTE 5120
#define GL_UNSIGNED_BYTE 5121
#define GL_SHORT 5122
#define GL_UNSIGNED_SHORT 5123
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

/* COLOR_0 from km_mesh.colors (sRGB-encoded RGBA): linear RGBA as normalised unsigned shorts,
 * 8 bytes a vertex (16 bits keep an 8-bit sRGB value apart from its neighbours once linear,
 * which 8-bit linear would not in the darks). */
static void color_u16(const double *c, size_t nv, unsigned char *b) {
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 4; ++k) {
      double x = k < 3 ? km__srgb_decode(c[4 * i + k]) : fmin(1, fmax(0, c[4 * i + k]));
      unsigned v = (unsigned)lround(x * 65535);
      b[8 * i + 2 * k] = (unsigned char)(v & 0xff);
      b[8 * i + 2 * k + 1] = (unsigned char)(v >> 8);
    }
}

/* The number under key in o, -1 when absent. */
static int jint_item(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) ? v->valueint : -1;
}

static bool same_sampler(km_mesh_sampler a, km_mesh_sampler b) {
  return a.mag_filter == b.mag_filter && a.min_filter == b.min_filter && a.wrap_s == b.wrap_s &&
         a.wrap_t == b.wrap_t;
}

/* The index in `samplers` (whose 0 is the default, {}) of a sampler with these settings,
 * appended when none has them. */
static int sampler_index(cJSON *samplers, km_mesh_sampler s) {
  if (!s.mag_filter && !s.min_filter && !s.wrap_s && !s.wrap_t) return 0;
  int n = cJSON_GetArraySize(samplers);
  for (int k = 1; k < n; ++k) {
    const cJSON *o = cJSON_GetArrayItem(samplers, k);
    int v[4] = {jint_item(o, "magFilter"), jint_item(o, "minFilter"), jint_item(o, "wrapS"),
                jint_item(o, "wrapT")}; /* -1: absent, i.e. 0 */
    km_mesh_sampler t = {v[0] > 0 ? v[0] : 0, v[1] > 0 ? v[1] : 0, v[2] > 0 ? v[2] : 0,
                         v[3] > 0 ? v[3] : 0};
    if (same_sampler(s, t)) return k;
  }
  cJSON *o = cJSON_CreateObject();
  if (s.mag_filter) cJSON_AddNumberToObject(o, "magFilter", s.mag_filter);
  if (s.min_filter) cJSON_AddNumberToObject(o, "minFilter", s.min_filter);
  if (s.wrap_s) cJSON_AddNumberToObject(o, "wrapS", s.wrap_s);
  if (s.wrap_t) cJSON_AddNumberToObject(o, "wrapT", s.wrap_t);
  cJSON_AddItemToArray(samplers, o);
  return n;
}

/* The rest mesh's materials (km_mesh.materials; issue 11: a textured model must not come out
 * grey): materials[k] with its base colour, metallic, roughness and emissive factors and, where
 * the file had them, its textures (base colour, metallic-roughness, normal with its scale,
 * occlusion with its strength, emissive), slot s's image (PNG or JPEG, as read) in bufferView
 * view[k * KM__SLOTS + s] (-1: none; slots with identical images share one view, texture and
 * image). The
 * mesh's one primitive `prim` (built over every face) becomes one per material, each over its
 * run of faces (an accessor on the same index view at the run's offset; the attributes and
 * morph targets shared), so each part keeps its own colour. */
static void add_materials(cJSON *root, cJSON *accessors, cJSON *mesh, cJSON *prim,
                          const km_mesh_material *m, size_t n, const int *view) {
  if (!n) return;
  cJSON *mats = cJSON_AddArrayToObject(root, "materials"), *texs = NULL, *imgs = NULL, *smps = NULL;
  size_t ni = n * KM__SLOTS;
  int *tex_of = calloc(ni, sizeof *tex_of), /* each slot's texture and image */
      *img_of = calloc(ni, sizeof *img_of);
  int n_tex = 0, n_img = 0;
  if (!img_of) free(tex_of), tex_of = NULL;
  for (size_t k = 0; k < n; ++k) {
    const km_mesh_material *q = m + k;
    cJSON *mat = cJSON_CreateObject();
    char nm[32];
    snprintf(nm, sizeof nm, "kinemesh_%zu", k);
    cJSON_AddStringToObject(mat, "name", nm);
    cJSON *pbr = cJSON_AddObjectToObject(mat, "pbrMetallicRoughness");
    cJSON_AddItemToObject(pbr, "baseColorFactor", cJSON_CreateDoubleArray(q->base_color, 4));
    cJSON_AddNumberToObject(pbr, "metallicFactor", q->metallic);
    cJSON_AddNumberToObject(pbr, "roughnessFactor", q->roughness);
    for (int sl = 0; sl < KM__SLOTS && tex_of; ++sl) {
      size_t i = k * KM__SLOTS + (size_t)sl;
      if (view[i] < 0) continue;
      /* one image per view, one texture per image and sampler, one sampler per setting */
      km_mesh_sampler smp = km__material_slot(m, i).sampler;
      size_t j = 0, jv = 0;
      while (j < i && !(view[j] == view[i] && same_sampler(km__material_slot(m, j).sampler, smp)))
        ++j;
      while (jv < i && view[jv] != view[i])
        ++jv;
      if (j == i) {
        if (!texs) {
          texs = cJSON_AddArrayToObject(root, "textures");
          imgs = cJSON_AddArrayToObject(root, "images");
          smps = cJSON_AddArrayToObject(root, "samplers");
          cJSON_AddItemToArray(smps, cJSON_CreateObject()); /* 0: the default */
        }
        if (jv == i) { /* the view's first use: its image */
          cJSON *img = cJSON_CreateObject();
          cJSON_AddNumberToObject(img, "bufferView", view[i]);
          cJSON_AddStringToObject(img, "mimeType", km__material_slot(m, i).mime);
          cJSON_AddItemToArray(imgs, img);
          img_of[i] = n_img++;
        } else {
          img_of[i] = img_of[jv];
        }
        cJSON *tex = cJSON_CreateObject();
        cJSON_AddNumberToObject(tex, "source", img_of[i]);
        cJSON_AddNumberToObject(tex, "sampler", sampler_index(smps, smp));
        cJSON_AddItemToArray(texs, tex);
        tex_of[i] = n_tex++;
      } else {
        tex_of[i] = tex_of[j];
        img_of[i] = img_of[j];
      }
      static const char *const name[KM__SLOTS] = {"baseColorTexture", "metallicRoughnessTexture",
                                                  "normalTexture", "occlusionTexture",
                                                  "emissiveTexture"};
      cJSON *info = cJSON_AddObjectToObject(sl < 2 ? pbr : mat, name[sl]);
      cJSON_AddNumberToObject(info, "index", tex_of[i]);
      if (sl == 1 + KM_MAP_NORMAL && q->normal_scale && q->normal_scale != 1)
        cJSON_AddNumberToObject(info, "scale", q->normal_scale);
      if (sl == 1 + KM_MAP_OCCLUSION && q->occlusion_strength && q->occlusion_strength != 1)
        cJSON_AddNumberToObject(info, "strength", q->occlusion_strength);
    }
    if (q->emissive[0] || q->emissive[1] || q->emissive[2])
      cJSON_AddItemToObject(mat, "emissiveFactor", cJSON_CreateDoubleArray(q->emissive, 3));
    if (q->alpha_mode == KM_ALPHA_MASK || q->alpha_mode == KM_ALPHA_BLEND)
      cJSON_AddStringToObject(mat, "alphaMode", q->alpha_mode == KM_ALPHA_MASK ? "MASK" : "BLEND");
    if (q->alpha_mode == KM_ALPHA_MASK && q->alpha_cutoff && q->alpha_cutoff != 0.5)
      cJSON_AddNumberToObject(mat, "alphaCutoff", q->alpha_cutoff);
    if (q->double_sided) cJSON_AddBoolToObject(mat, "doubleSided", 1);
    cJSON_AddItemToArray(mats, mat);
  }
  free(tex_of), free(img_of);
  cJSON *prims = cJSON_GetObjectItemCaseSensitive(mesh, "primitives");
  int a_idx = jint_item(prim, "indices");
  /* Every copy is taken from the pristine primitive (and index accessor) before any is changed,
   * and appended in material order: cJSON 1.7.15's (Debian 12's) cJSON_InsertItemInArray loses
   * an item inserted before the last one, which dropped the third material's faces. */
  cJSON **ps = calloc(n, sizeof *ps), **as = calloc(n, sizeof *as);
  if (!ps || !as) {
    free(ps), free(as);
    cJSON_AddNumberToObject(prim, "material", 0); /* out of memory: the first over all */
    return;
  }
  cJSON *acc0 = a_idx >= 0 ? cJSON_GetArrayItem(accessors, a_idx) : NULL;
  for (size_t k = 0; k < n; ++k) {
    ps[k] = k ? cJSON_Duplicate(prim, 1) : prim;
    as[k] = k && acc0 && n > 1 ? cJSON_Duplicate(acc0, 1) : acc0;
  }
  for (size_t k = 0; k < n; ++k) {
    cJSON *p = ps[k];
    if (k) cJSON_AddItemToArray(prims, p);
    cJSON_AddNumberToObject(p, "material", (double)k);
    if (!as[k] || n == 1) continue;
    /* the run's indices: the whole index accessor's view from the run's first face */
    cJSON *acc = as[k];
    cJSON_DeleteItemFromObject(acc, "byteOffset");
    cJSON_AddNumberToObject(acc, "byteOffset", (double)(12 * m[k].first_face));
    cJSON_ReplaceItemInObject(acc, "count", cJSON_CreateNumber((double)(3 * m[k].n_faces)));
    if (k) {
      cJSON_AddItemToArray(accessors, acc);
      cJSON_ReplaceItemInObject(p, "indices",
                                cJSON_CreateNumber((double)(cJSON_GetArraySize(accessors) - 1)));
    }
  }
  free(ps), free(as);
}

/* Appends a plain bufferView (no accessor, no target: an image) and returns its index. */
static int add_view(cJSON *views, uint64_t offset, uint64_t length) {
  cJSON *v = cJSON_CreateObject();
  cJSON_AddNumberToObject(v, "buffer", 0);
  cJSON_AddNumberToObject(v, "byteOffset", (double)offset);
  cJSON_AddNumberToObject(v, "byteLength", (double)length);
  cJSON_AddItemToArray(views, v);
  return cJSON_GetArraySize(views) - 1;
}

static km_status write_all(km_anim_writer *w, FILE *f, const void *p, size_t n, km_error *err) {
  if (n && fwrite(p, 1, n, f) != n)
    return km__fail(err, KM_ERR_IO, "%s: write failed: %s", w->path, strerror(errno));
  return KM_OK;
}

/* The last frame always closes the animation, key or not: it becomes the closing key. */
static km_status close_last_key(km_anim_writer *w, km_error *err) {
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
  return KM_OK;
}

/* The one GLB container writer (issue 16): the 12-byte header, the JSON chunk (root, printed
 * and deleted here; space-padded to 4 bytes) and the BIN chunk of bin_len bytes (a multiple of
 * 4) into the writer's temporary, published atomically. The BIN chunk is `bin` when given,
 * else what `stream` writes (exactly bin_len bytes: a large morph file is streamed). */
typedef km_status (*glb_bin_stream)(km_anim_writer *w, FILE *f, void *ctx, km_error *err);
static km_status write_glb_container(km_anim_writer *w, cJSON *root, const unsigned char *bin,
                                     uint64_t bin_len, glb_bin_stream stream, void *ctx,
                                     km_error *err) {
  char *json = root ? cJSON_PrintUnformatted(root) : NULL;
  cJSON_Delete(root);
  if (!json)
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory building the glTF JSON", w->path);
  size_t json_len = strlen(json), json_pad = (4 - json_len % 4) % 4;
  uint64_t total = 12 + 8 + json_len + json_pad + 8 + bin_len;
  if (total > UINT32_MAX || bin_len % 4) {
    free(json);
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: glb would exceed 4 GiB", w->path);
  }
  km__atomic_file af = w->af; /* opened by km_anim_writer_open */
  memset(&w->af, 0, sizeof w->af);
  unsigned char h[20];
  km__put_u32le(h, GLB_MAGIC);
  km__put_u32le(h + 4, 2);
  km__put_u32le(h + 8, (uint32_t)total);
  km__put_u32le(h + 12, (uint32_t)(json_len + json_pad));
  km__put_u32le(h + 16, GLB_JSON);
  km_status s = write_all(w, af.f, h, 20, err);
  if (s == KM_OK) s = write_all(w, af.f, json, json_len, err);
  if (s == KM_OK) s = write_all(w, af.f, "   ", json_pad, err);
  free(json);
  km__put_u32le(h, (uint32_t)bin_len);
  km__put_u32le(h + 4, GLB_BIN);
  if (s == KM_OK) s = write_all(w, af.f, h, 8, err);
  if (s == KM_OK) s = bin ? write_all(w, af.f, bin, bin_len, err) : stream(w, af.f, ctx, err);
  if (s != KM_OK) {
    km__atomic_abort(&af);
    return s;
  }
  return km__atomic_commit(&af, err);
}

/* The "asset" object every writer puts in root (version, generator) and its
 * extras.kinemesh object, returned for the writer's own figures: fps, frames, key_every and,
 * when export_kind is not NULL, "export". */
static cJSON *add_asset(cJSON *root, double fps, size_t frames, size_t key_every,
                        const char *export_kind) {
  cJSON *asset = cJSON_AddObjectToObject(root, "asset");
  cJSON_AddStringToObject(asset, "version", "2.0");
  cJSON_AddStringToObject(asset, "generator", "kinemesh");
  cJSON *ex = cJSON_AddObjectToObject(cJSON_AddObjectToObject(asset, "extras"), "kinemesh");
  cJSON_AddNumberToObject(ex, "fps", fps);
  cJSON_AddNumberToObject(ex, "frames", (double)frames);
  cJSON_AddNumberToObject(ex, "key_every", (double)key_every);
  if (export_kind) cJSON_AddStringToObject(ex, "export", export_kind);
  return ex;
}

/* The one animation of a morph file: node 0's morph weights, LINEAR, keyed by accessor a_in
 * (times) with accessor a_out (#keys x #targets weights). */
static void add_weights_animation(cJSON *root, int a_in, int a_out) {
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
}

/* What the plain morph writer streams after the JSON. */
typedef struct morph_stream {
  const float *times;
  size_t nt, nk;
  bool pca, with_n;
  const int *uniq; /* km__material_images_unique of the materials, as finish laid them out */
} morph_stream;
static km_status stream_morph_bin(km_anim_writer *w, FILE *f, void *ctx, km_error *err);
static km_status glb_finish_packed(km_anim_writer *w, km_error *err);

km_status km__glb_finish(km_anim_writer *w, km_error *err) {
  km_status s0 = close_last_key(w, err);
  if (s0 != KM_OK) return s0;
  if (w->compress) return glb_finish_packed(w, err);
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
  const uint64_t col_len = w->colors ? (uint64_t)nv * 8 : 0;
  const km_mesh_material *mat = w->material_mesh.materials;
  const size_t n_mat = w->material_mesh.n_materials;
  const size_t n_img = n_mat * KM__SLOTS; /* every material's texture slots */
  int *uniq = km__malloc(n_img ? n_img : 1, sizeof *uniq),
      *view = km__malloc(n_img ? n_img : 1, sizeof *view);
  if (!uniq || !view) {
    free(uniq), free(view);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  }
  km__material_images_unique(mat, n_mat, uniq);
  uint64_t img_pad = 0;
  for (size_t i = 0; i < n_img; ++i)
    if (uniq[i] == (int)i) img_pad += (km__material_slot(mat, i).size + 3) & ~(uint64_t)3;
  uint64_t bin_len = idx_len + pos_len * (1 + nk) * (with_n ? 2 : 1) + uv_len + col_len +
                     times_len + weights_len + img_pad;
  if (bin_len + (64u << 20) > UINT32_MAX) {
    free(uniq), free(view);
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: %zu key frames of %zu vertices exceed the 4 GiB glb limit; use "
                    "key_every > 1 or pc2",
                    w->path, nk, nv);
  }

  float *times = km__malloc(nt, sizeof *times);
  if (!times) {
    free(uniq), free(view);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  }
  for (size_t k = 0; k < nt; ++k)
    times[k] = (float)((double)(pca ? k : w->key_frame[k]) / w->fps);

  cJSON *root = cJSON_CreateObject();
  char ek[32];
  snprintf(ek, sizeof ek, "morphs:%zu", nk);
  cJSON *ex = add_asset(root, w->fps, w->frames, w->key_every, pca ? ek : NULL);
  if (pca) {
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
  if (w->colors) {
    int a_c = add_view_accessor(views, accessors, off, col_len, GL_ARRAY_BUFFER, GL_UNSIGNED_SHORT,
                                nv, "VEC4", NULL, NULL, 0);
    cJSON_AddBoolToObject(cJSON_GetArrayItem(accessors, a_c), "normalized", 1);
    off += col_len;
    cJSON_AddNumberToObject(attrs, "COLOR_0", a_c);
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
      snprintf(nm, sizeof nm, w->pca_offset && k + 1 == nk ? "basis_offset" : "basis_%03zu", k);
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
  add_weights_animation(root, a_in, a_out);
  for (size_t i = 0; i < n_img; ++i) { /* the images last, in material and slot order */
    view[i] = uniq[i] == (int)i ? add_view(views, off, km__material_slot(mat, i).size)
              : uniq[i] >= 0    ? view[uniq[i]]
                                : -1;
    if (uniq[i] == (int)i) off += (km__material_slot(mat, i).size + 3) & ~(uint64_t)3;
  }
  add_materials(root, accessors, mesh, prim, mat, n_mat, view);
  free(view);
  cJSON *buffer = cJSON_CreateObject();
  cJSON_AddNumberToObject(buffer, "byteLength", (double)bin_len);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "buffers"), buffer);
  cJSON_AddItemToObject(root, "bufferViews", views);
  cJSON_AddItemToObject(root, "accessors", accessors);

  if (off != bin_len) {
    cJSON_Delete(root);
    free(times), free(uniq);
    return km__fail(err, KM_ERR_NOMEM, "%s: glb layout mismatch", w->path);
  }
  morph_stream ms = {times, nt, nk, pca, with_n, uniq};
  km_status s = write_glb_container(w, root, NULL, bin_len, stream_morph_bin, &ms, err);
  free(times), free(uniq);
  return s;
}

static km_status stream_morph_bin(km_anim_writer *w, FILE *f, void *ctx, km_error *err) {
  const morph_stream *ms = ctx;
  const size_t nv = w->n_vertices, nf = w->n_faces, nk = ms->nk, nt = ms->nt;
  const bool pca = ms->pca, with_n = ms->with_n;
  const float *times = ms->times;
  km_status s = KM_OK;
  unsigned char *b = w->bytes;
  if (s == KM_OK && nf) {
    /* Indices in chunks that reuse the per-vertex scratch buffer (nv*12 bytes). */
    size_t chunk = nv, done = 0;
    while (s == KM_OK && done < nf * 3) {
      size_t n = nf * 3 - done < chunk ? nf * 3 - done : chunk;
      for (size_t i = 0; i < n; ++i)
        km__put_u32le(b + 4 * i, (uint32_t)w->F[done + i]);
      s = write_all(w, f, b, 4 * n, err);
      done += n;
    }
  }
  if (s == KM_OK) {
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, (float)w->rest[i]);
    s = write_all(w, f, b, nv * 12, err);
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
    s = write_all(w, f, b, nv * 12, err);
  }
  if (s == KM_OK && w->uv) {
    for (size_t i = 0; i < nv; ++i) {
      km__put_f32le(b + 8 * i, (float)w->uv[2 * i]);
      km__put_f32le(b + 8 * i + 4, (float)(1.0 - w->uv[2 * i + 1]));
    }
    s = write_all(w, f, b, nv * 8, err);
  }
  if (s == KM_OK && w->colors) {
    color_u16(w->colors, nv, b);
    s = write_all(w, f, b, nv * 8, err);
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
    s = write_all(w, f, b, nv * 12, err);
    if (s == KM_OK && with_n) {
      for (size_t i = 0; i < nv * 3; ++i)
        w->vbuf[i] = w->rest[i] + (double)w->fbuf[i];
      km__anim_normals(w, w->vbuf);
      for (size_t i = 0; i < nv * 3; ++i)
        km__put_f32le(b + 4 * i, (float)(w->nbuf[i] - rest_n[i]));
      s = write_all(w, f, b, nv * 12, err);
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
    s = write_all(w, f, row, 4 * nt, err);
    memset(row, 0, 4 * rl);
  }
  for (size_t t = 0; pca && s == KM_OK && t < nt; ++t) {
    for (size_t k = 0; k < nk; ++k)
      km__put_f32le(row + 4 * k, w->pca_weights[t * nk + k]);
    s = write_all(w, f, row, 4 * nk, err);
  }
  for (size_t k = 0; !pca && s == KM_OK && k < nk; ++k) {
    km__put_f32le(row + 4 * k, 1.0f);
    s = write_all(w, f, row, 4 * nk, err);
    km__put_f32le(row + 4 * k, 0.0f);
  }
  free(row);
  /* the materials' images last, each once, padded to 4 bytes (finish's layout) */
  const km_mesh_material *mat = w->material_mesh.materials;
  const size_t n_img = w->material_mesh.n_materials * KM__SLOTS;
  for (size_t i = 0; s == KM_OK && i < n_img; ++i) {
    static const unsigned char zero[3] = {0, 0, 0};
    if (ms->uniq[i] != (int)i) continue;
    km_mesh_image im = km__material_slot(mat, i);
    s = write_all(w, f, im.bytes, im.size, err);
    if (s == KM_OK && im.size % 4) s = write_all(w, f, zero, 4 - im.size % 4, err);
  }
  return s;
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

/* ---------------------------------------------------------------- packing (issue 16) */

/* The binary views of a glb being built in memory: plain (buffer 0 is the BIN chunk), or with
 * compress EXT_meshopt_compression: each view's bytes are meshopt-encoded into the BIN chunk
 * (buffer 0) and the view itself addresses buffer 1, the fallback buffer decoders fill (it
 * has no uri, so the extension is required). */
typedef struct glb_pack {
  bin_buf bin;
  uint64_t raw_len; /* the fallback buffer's length (compress) */
  cJSON *views, *accessors;
  bool compress;
  size_t nv; /* vertices: the index codec's bound */
} glb_pack;

enum { PACK_ATTRIBUTES, PACK_TRIANGLES };

/* Appends count elements of `stride` bytes (little-endian; for PACK_TRIANGLES host uint32
 * indices) as one bufferView; filter: the meshopt filter the data was encoded with (NULL:
 * NONE). vertex_stride: the view holds vertex attributes (byteStride is written). Returns the
 * view index, -1 when out of memory. */
static int pack_view(glb_pack *pk, const void *data, size_t count, size_t stride, int mode,
                     const char *filter, int target, bool vertex_stride) {
  size_t raw = count * stride;
  cJSON *v = cJSON_CreateObject();
  if (!v) return -1;
  cJSON_AddItemToArray(pk->views, v);
  if (!pk->compress) {
    size_t off = pk->bin.len;
    unsigned char *p = bin_grow(&pk->bin, raw);
    if (!p) return -1;
    memcpy(p, data, raw);
    cJSON_AddNumberToObject(v, "buffer", 0);
    cJSON_AddNumberToObject(v, "byteOffset", (double)off);
  } else {
    size_t bound = mode == PACK_TRIANGLES ? meshopt_encodeIndexBufferBound(count, pk->nv)
                                          : meshopt_encodeVertexBufferBound(count, stride);
    size_t off = pk->bin.len;
    unsigned char *p = bin_grow(&pk->bin, bound);
    if (!p) return -1;
    size_t n = mode == PACK_TRIANGLES
                   ? meshopt_encodeIndexBuffer(p, bound, (const unsigned int *)data, count)
                   : meshopt_encodeVertexBuffer(p, bound, data, count, stride);
    if (!n) return -1;
    pk->bin.len = off + ((n + 3) & ~(size_t)3);
    cJSON_AddNumberToObject(v, "buffer", 1);
    cJSON_AddNumberToObject(v, "byteOffset", (double)pk->raw_len);
    pk->raw_len += (raw + 3) & ~(uint64_t)3;
    cJSON *e = cJSON_AddObjectToObject(cJSON_AddObjectToObject(v, "extensions"),
                                       "EXT_meshopt_compression");
    cJSON_AddNumberToObject(e, "buffer", 0);
    cJSON_AddNumberToObject(e, "byteOffset", (double)off);
    cJSON_AddNumberToObject(e, "byteLength", (double)n);
    cJSON_AddNumberToObject(e, "byteStride", (double)stride);
    cJSON_AddStringToObject(e, "mode", mode == PACK_TRIANGLES ? "TRIANGLES" : "ATTRIBUTES");
    if (filter) cJSON_AddStringToObject(e, "filter", filter);
    cJSON_AddNumberToObject(e, "count", (double)count);
  }
  cJSON_AddNumberToObject(v, "byteLength", (double)raw);
  if (vertex_stride) cJSON_AddNumberToObject(v, "byteStride", (double)stride);
  if (target) cJSON_AddNumberToObject(v, "target", target);
  return cJSON_GetArraySize(pk->views) - 1;
}

/* The rest mesh's materials with their images as plain views in the real buffer (0: never
 * meshopt-encoded, which is for vertex data), prim split per material (add_materials); -1 on
 * out of memory. */
static int pack_materials(glb_pack *pk, cJSON *root, cJSON *mesh, cJSON *prim,
                          const km_mesh_material *m, size_t n) {
  if (!n) return 0;
  size_t ni = n * KM__SLOTS;
  int *uniq = km__malloc(ni, sizeof *uniq), *view = km__malloc(ni, sizeof *view), rc = 0;
  if (!uniq || !view) rc = -1;
  if (!rc) km__material_images_unique(m, n, uniq);
  for (size_t i = 0; !rc && i < ni; ++i) {
    view[i] = uniq[i] >= 0 && uniq[i] < (int)i ? view[uniq[i]] : -1;
    if (uniq[i] != (int)i) continue;
    km_mesh_image im = km__material_slot(m, i);
    size_t off = pk->bin.len;
    unsigned char *p = bin_grow(&pk->bin, im.size);
    if (!p) {
      rc = -1;
      break;
    }
    memcpy(p, im.bytes, im.size);
    view[i] = add_view(pk->views, off, im.size);
  }
  if (!rc) add_materials(root, pk->accessors, mesh, prim, m, n, view);
  free(uniq), free(view);
  return rc;
}

/* Appends an accessor over a whole view; min/max (n values each) may be NULL. Returns its
 * index, -1 when view is -1. */
static int pack_accessor_at(glb_pack *pk, int view, size_t byte_offset, int component,
                            bool normalized, size_t count, const char *type, const double *mn,
                            const double *mx, int n) {
  if (view < 0) return -1;
  cJSON *a = cJSON_CreateObject();
  cJSON_AddNumberToObject(a, "bufferView", view);
  if (byte_offset) cJSON_AddNumberToObject(a, "byteOffset", (double)byte_offset);
  cJSON_AddNumberToObject(a, "componentType", component);
  if (normalized) cJSON_AddBoolToObject(a, "normalized", 1);
  cJSON_AddNumberToObject(a, "count", (double)count);
  cJSON_AddStringToObject(a, "type", type);
  if (mn) {
    cJSON_AddItemToObject(a, "min", cJSON_CreateDoubleArray(mn, n));
    cJSON_AddItemToObject(a, "max", cJSON_CreateDoubleArray(mx, n));
  }
  cJSON_AddItemToArray(pk->accessors, a);
  return cJSON_GetArraySize(pk->accessors) - 1;
}
static int pack_accessor(glb_pack *pk, int view, int component, bool normalized, size_t count,
                         const char *type, const double *mn, const double *mx, int n) {
  return pack_accessor_at(pk, view, 0, component, normalized, count, type, mn, mx, n);
}

/* KHR_mesh_quantization grid: position p is stored as the integer round((p - off) / s) with
 * POS_BITS bits over the rest's largest extent; morph deltas as signed 16-bit on the same
 * grid (s grows when a delta would not fit). Whoever displays the mesh dequantises through
 * the mesh node's scale s and translation off (morphs) or the inverse bind matrices (skin). */
#define POS_BITS 14
#define ROT_BITS 12 /* quaternion filter bits (gltfpack default): ~3e-4 rad */
typedef struct qgrid {
  double off[3], s;
} qgrid;

static qgrid make_grid(const float rest_minmax[6], double max_delta) {
  qgrid g;
  double ext = 0;
  for (int a = 0; a < 3; ++a) {
    g.off[a] = (double)rest_minmax[a];
    ext = fmax(ext, (double)rest_minmax[3 + a] - (double)rest_minmax[a]);
  }
  g.s = fmax(ext / ((1 << POS_BITS) - 1), max_delta / 32000.0);
  if (!(g.s > 0)) g.s = 1e-6;
  /* a float32 scale, as the JSON holds it, so the file and the error estimate agree */
  g.s = (double)(float)g.s;
  for (int a = 0; a < 3; ++a)
    g.off[a] = (double)(float)g.off[a];
  return g;
}

static void put_u16le(unsigned char *p, unsigned v) {
  p[0] = (unsigned char)v;
  p[1] = (unsigned char)(v >> 8);
}

/* Rest positions quantised into b (8 bytes per vertex: u16 xyz + padding), their integer
 * min/max, and the dequantised positions into dq (#V*3). */
static void quantise_positions(const double *V, size_t nv, const qgrid *g, unsigned char *b,
                               double mn[3], double mx[3], double *dq) {
  for (int a = 0; a < 3; ++a)
    mn[a] = 65535, mx[a] = 0;
  for (size_t i = 0; i < nv; ++i) {
    for (int a = 0; a < 3; ++a) {
      double q = round((V[3 * i + a] - g->off[a]) / g->s);
      q = q < 0 ? 0 : q > 65535 ? 65535 : q;
      put_u16le(b + 8 * i + 2 * a, (unsigned)q);
      mn[a] = fmin(mn[a], q), mx[a] = fmax(mx[a], q);
      if (dq) dq[3 * i + a] = g->off[a] + g->s * q;
    }
    put_u16le(b + 8 * i + 6, 0);
  }
}

/* Unit normals N (#V*3), octahedral-encoded 8-bit into b (4 bytes per vertex). */
static int pack_normals(glb_pack *pk, const double *N, size_t nv, unsigned char *b, float *f4) {
  if (!pk->compress) {
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, (float)N[i]);
    return pack_accessor(pk,
                         pack_view(pk, b, nv, 12, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, false),
                         GL_FLOAT, false, nv, "VEC3", NULL, NULL, 0);
  }
  for (size_t i = 0; i < nv; ++i) {
    for (int a = 0; a < 3; ++a)
      f4[4 * i + a] = (float)N[3 * i + a];
    f4[4 * i + 3] = 0;
  }
  meshopt_encodeFilterOct(b, nv, 4, 8, f4);
  return pack_accessor(
      pk, pack_view(pk, b, nv, 4, PACK_ATTRIBUTES, "OCTAHEDRAL", GL_ARRAY_BUFFER, true), GL_BYTE,
      true, nv, "VEC3", NULL, NULL, 0);
}

/* Texture coordinates (v flipped to glTF's top-left origin), 16-bit normalised when compress
 * and all lie in [0, 1], else float. */
static int pack_uv(glb_pack *pk, const double *uv, size_t nv, unsigned char *b) {
  bool unit = pk->compress;
  for (size_t i = 0; unit && i < nv * 2; ++i)
    unit = uv[i] >= 0 && uv[i] <= 1;
  if (unit) {
    for (size_t i = 0; i < nv; ++i) {
      put_u16le(b + 4 * i, (unsigned)lround(uv[2 * i] * 65535));
      put_u16le(b + 4 * i + 2, (unsigned)lround((1.0 - uv[2 * i + 1]) * 65535));
    }
    return pack_accessor(pk, pack_view(pk, b, nv, 4, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, true),
                         GL_UNSIGNED_SHORT, true, nv, "VEC2", NULL, NULL, 0);
  }
  for (size_t i = 0; i < nv; ++i) {
    km__put_f32le(b + 8 * i, (float)uv[2 * i]);
    km__put_f32le(b + 8 * i + 4, (float)(1.0 - uv[2 * i + 1]));
  }
  return pack_accessor(
      pk, pack_view(pk, b, nv, 8, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, pk->compress), GL_FLOAT,
      false, nv, "VEC2", NULL, NULL, 0);
}

/* COLOR_0 (color_u16), meshopt-encoded when compress. */
static int pack_colors(glb_pack *pk, const double *c, size_t nv, unsigned char *b) {
  color_u16(c, nv, b);
  return pack_accessor(
      pk, pack_view(pk, b, nv, 8, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, pk->compress),
      GL_UNSIGNED_SHORT, true, nv, "VEC4", NULL, NULL, 0);
}

/* The surface attributes a mesh carries besides its shape, TEXCOORD_0 (pack_uv) and COLOR_0
 * (pack_colors), where it has them (uv, colors NULL: none), added to attrs. b: scratch of nv*8
 * bytes. Returns false out of memory. */
static bool pack_surface(glb_pack *pk, const double *uv, const double *colors, size_t nv,
                         unsigned char *b, cJSON *attrs) {
  int a;
  if (uv) {
    if ((a = pack_uv(pk, uv, nv, b)) < 0) return false;
    cJSON_AddNumberToObject(attrs, "TEXCOORD_0", a);
  }
  if (colors) {
    if ((a = pack_colors(pk, colors, nv, b)) < 0) return false;
    cJSON_AddNumberToObject(attrs, "COLOR_0", a);
  }
  return true;
}

/* Triangle indices: little-endian bytes when plain; compressed, host uint32 in an order the
 * index codec packs well (meshopt_optimizeVertexCache reorders the triangles, never the
 * vertices: vertex order and count stay the input's). b: nf*12 bytes. */
static int pack_indices(glb_pack *pk, const int32_t *F, size_t nf, unsigned char *b,
                        const km_mesh_material *m, size_t n_mat) {
  if (pk->compress) {
    unsigned int *in = km__malloc(nf * 3, sizeof *in);
    if (!in) return -1;
    for (size_t i = 0; i < nf * 3; ++i)
      in[i] = (unsigned int)F[i];
    /* reordered within each material's run of faces only (the runs stay where they are) */
    for (size_t k = 0; k < (n_mat ? n_mat : 1); ++k) {
      size_t f0 = n_mat ? m[k].first_face : 0, fn = n_mat ? m[k].n_faces : nf;
      meshopt_optimizeVertexCache((unsigned int *)b + 3 * f0, in + 3 * f0, 3 * fn, pk->nv);
    }
    free(in);
  } else {
    for (size_t i = 0; i < nf * 3; ++i)
      km__put_u32le(b + 4 * i, (uint32_t)F[i]);
  }
  return pack_accessor(
      pk, pack_view(pk, b, nf * 3, 4, PACK_TRIANGLES, NULL, GL_ELEMENT_ARRAY_BUFFER, false),
      GL_UNSIGNED_INT, false, nf * 3, "SCALAR", NULL, NULL, 0);
}

/* Float data through the exponential filter (compress; `bits` of mantissa, one exponent per
 * element of `comps` floats), else plain float32. decoded (may be NULL) receives what a
 * decoder reads back. */
static int pack_floats(glb_pack *pk, const float *x, size_t count, int comps, int bits,
                       unsigned char *b, float *decoded, const char *type, const double *mn,
                       const double *mx) {
  size_t stride = 4 * (size_t)comps;
  if (pk->compress) {
    meshopt_encodeFilterExp(b, count, stride, bits, x);
    if (decoded) {
      memcpy(decoded, b, count * stride);
      meshopt_decodeFilterExp(decoded, count, stride);
    }
  } else {
    for (size_t i = 0; i < count * (size_t)comps; ++i)
      km__put_f32le(b + 4 * i, x[i]);
    if (decoded) memcpy(decoded, x, count * stride);
  }
  return pack_accessor(pk,
                       pack_view(pk, b, count, stride, PACK_ATTRIBUTES,
                                 pk->compress ? "EXPONENTIAL" : NULL, 0, false),
                       GL_FLOAT, false, count, type, mn, mx, comps);
}

/* Adds the extensions a packed file uses and its buffers (the BIN chunk; with compress the
 * fallback buffer too). */
static void pack_finish_json(glb_pack *pk, cJSON *root) {
  cJSON *buffers = cJSON_AddArrayToObject(root, "buffers");
  cJSON *b0 = cJSON_CreateObject();
  cJSON_AddNumberToObject(b0, "byteLength", (double)pk->bin.len);
  cJSON_AddItemToArray(buffers, b0);
  if (pk->compress) {
    cJSON *b1 = cJSON_CreateObject();
    cJSON_AddNumberToObject(b1, "byteLength", (double)pk->raw_len);
    cJSON_AddBoolToObject(cJSON_AddObjectToObject(cJSON_AddObjectToObject(b1, "extensions"),
                                                  "EXT_meshopt_compression"),
                          "fallback", 1);
    cJSON_AddItemToArray(buffers, b1);
    const char *ext[2] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
    cJSON_AddItemToObject(root, "extensionsUsed", cJSON_CreateStringArray(ext, 2));
    cJSON_AddItemToObject(root, "extensionsRequired", cJSON_CreateStringArray(ext, 2));
  }
  cJSON_AddItemToObject(root, "bufferViews", pk->views);
  cJSON_AddItemToObject(root, "accessors", pk->accessors);
  pk->views = pk->accessors = NULL;
}

static void quat_to_m3(const double q[4], double R[9]) {
  double x = q[0], y = q[1], z = q[2], w = q[3], l = sqrt(x * x + y * y + z * z + w * w);
  if (l > 0) x /= l, y /= l, z /= l, w /= l;
  R[0] = 1 - 2 * (y * y + z * z), R[1] = 2 * (x * y - z * w), R[2] = 2 * (x * z + y * w);
  R[3] = 2 * (x * y + z * w), R[4] = 1 - 2 * (x * x + z * z), R[5] = 2 * (y * z - x * w);
  R[6] = 2 * (x * z - y * w), R[7] = 2 * (y * z + x * w), R[8] = 1 - 2 * (x * x + y * y);
}

/* Little-endian float32 copy of a float array into b, for pack_view without a filter. */
static int pack_raw_floats(glb_pack *pk, const float *x, size_t count, const char *type, int comps,
                           unsigned char *b, const double *mn, const double *mx) {
  for (size_t i = 0; i < count * (size_t)comps; ++i)
    km__put_f32le(b + 4 * i, x[i]);
  return pack_accessor(pk,
                       pack_view(pk, b, count, 4 * (size_t)comps, PACK_ATTRIBUTES, NULL, 0, false),
                       GL_FLOAT, false, count, type, mn, mx, comps);
}

static void add_grid_extras(cJSON *ex, const qgrid *g) {
  cJSON *q = cJSON_AddObjectToObject(ex, "quantization");
  cJSON_AddItemToObject(q, "offset", cJSON_CreateDoubleArray(g->off, 3));
  cJSON_AddNumberToObject(q, "scale", g->s);
  cJSON_AddNumberToObject(q, "position_bits", POS_BITS);
}

/* Whether vertex i of sk has no influence (km__skin_row_empty). */
static bool still_row(const km_skin *sk, size_t i) {
  return km__skin_row_empty(sk->joints + KM_SKIN_INFLUENCES * i,
                            sk->weights + KM_SKIN_INFLUENCES * i);
}

km_status km__glb_write_skin(km_anim_writer *w, const km_ssdr *fit, const double *frames,
                             km_error *err) {
  const size_t nv = w->n_vertices, nf = w->n_faces, B = fit->n_bones, T = fit->n_frames;
  const bool z = w->compress;
  /* A vertex with no influence (a ground plane km_autorig left out of the skin) stays where it
   * is: glTF wants every vertex's weights to sum to 1, so it is bound to one more joint, the
   * armature root (node 1), which no channel moves. BJ: the skin's joints. */
  bool any_still = false;
  for (size_t i = 0; i < nv && !any_still; ++i)
    any_still = still_row(&fit->skin, i);
  const size_t BJ = B + any_still;
  glb_pack pk = {.compress = z, .nv = nv};
  pk.views = cJSON_CreateArray();
  pk.accessors = cJSON_CreateArray();
  cJSON *root = cJSON_CreateObject();
  size_t scratch = nv * 16;
  if (nf * 12 > scratch) scratch = nf * 12;
  if (T * 16 > scratch) scratch = T * 16;
  if (BJ * 64 > scratch) scratch = BJ * 64;
  unsigned char *b = malloc(scratch), *b2 = malloc(T * 16 + 16);
  float *f4 = km__malloc((nv > T ? nv : T) * 4, sizeof *f4);
  double *vq = z ? km__malloc(nv * 3, sizeof *vq) : NULL;       /* dequantised rest */
  double *wq = z ? km__malloc(nv * 4, sizeof *wq) : NULL;       /* dequantised weights */
  double *rig = z ? km__malloc(T * B * 12, sizeof *rig) : NULL; /* decoded [R | t] per frame */
  const qgrid g = make_grid(w->rest_minmax, 0);
  km_status s = KM_OK;
  if (!root || !pk.views || !pk.accessors || !b || !b2 || !f4 || (z && (!vq || !wq || !rig)))
    goto nomem;

  cJSON *ex = add_asset(root, w->fps, T, 1, "skin");
  cJSON_AddNumberToObject(ex, "bones", (double)B);

  /* ---- the mesh: indices, rest positions, normals, UVs, joints, weights */
  cJSON *mesh = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);
  cJSON *prim = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(mesh, "primitives"), prim);
  cJSON_AddStringToObject(mesh, "name", "kinemesh");
  cJSON *attrs = cJSON_AddObjectToObject(prim, "attributes");
  int a;
  if (nf) {
    if ((a = pack_indices(&pk, w->F, nf, b, w->material_mesh.materials,
                          w->material_mesh.n_materials)) < 0)
      goto nomem;
    cJSON_AddNumberToObject(prim, "indices", a);
  }
  double mn[3], mx[3];
  if (z) {
    quantise_positions(w->rest, nv, &g, b, mn, mx, vq);
    a = pack_accessor(&pk, pack_view(&pk, b, nv, 8, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, true),
                      GL_UNSIGNED_SHORT, false, nv, "VEC3", mn, mx, 3);
  } else {
    for (size_t i = 0; i < nv * 3; ++i)
      km__put_f32le(b + 4 * i, (float)w->rest[i]);
    for (int c = 0; c < 3; ++c)
      mn[c] = w->rest_minmax[c], mx[c] = w->rest_minmax[3 + c];
    a = pack_accessor(&pk, pack_view(&pk, b, nv, 12, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, false),
                      GL_FLOAT, false, nv, "VEC3", mn, mx, 3);
  }
  if (a < 0) goto nomem;
  cJSON_AddNumberToObject(attrs, "POSITION", a);
  if (nf) {
    /* Engines skin the normals with the bones, so the rest's normals are all they need. */
    if (!w->nbuf && !(w->nbuf = km__malloc(nv * 3, sizeof *w->nbuf))) goto nomem;
    km__anim_normals(w, w->rest);
    if ((a = pack_normals(&pk, w->nbuf, nv, b, f4)) < 0) goto nomem;
    cJSON_AddNumberToObject(attrs, "NORMAL", a);
  }
  if (!pack_surface(&pk, w->uv, w->colors, nv, b, attrs)) goto nomem;
  const bool wide = BJ > 256;
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 4; ++k) {
      int32_t j = fit->skin.joints[4 * i + k];
      uint32_t v = still_row(&fit->skin, i) && k == 0 ? (uint32_t)B : j < 0 ? 0 : (uint32_t)j;
      if (wide)
        put_u16le(b + 8 * i + 2 * k, v);
      else
        b[4 * i + k] = (unsigned char)v;
    }
  a = pack_accessor(&pk,
                    pack_view(&pk, b, nv, wide ? 8 : 4, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, z),
                    wide ? GL_UNSIGNED_SHORT : GL_UNSIGNED_BYTE, false, nv, "VEC4", NULL, NULL, 0);
  if (a < 0) goto nomem;
  cJSON_AddNumberToObject(attrs, "JOINTS_0", a);
  for (size_t i = 0; i < nv; ++i) {
    /* Weights renormalised so their stored sum is exactly 1 (the validator checks it): float32
     * when plain, 8-bit normalised (sum 255) when compressed. */
    double x[4];
    int big = 0;
    for (int k = 0; k < 4; ++k) {
      x[k] = fit->skin.joints[4 * i + k] < 0 ? 0 : fit->skin.weights[4 * i + k];
      if (x[k] > x[big]) big = k;
    }
    if (still_row(&fit->skin, i)) x[0] = 1, x[1] = x[2] = x[3] = 0, big = 0;
    if (z) {
      int q[4], sum = 0;
      for (int k = 0; k < 4; ++k)
        sum += (q[k] = (int)lround(x[k] * 255));
      q[big] += 255 - sum;
      for (int k = 0; k < 4; ++k) {
        b[4 * i + k] = (unsigned char)q[k];
        wq[4 * i + k] = q[k] / 255.0;
      }
    } else {
      float f[4];
      double sum = 0;
      for (int k = 0; k < 4; ++k)
        f[k] = (float)x[k];
      for (int k = 0; k < 4; ++k)
        if (k != big) sum += f[k];
      f[big] = (float)(1.0 - sum);
      for (int k = 0; k < 4; ++k)
        km__put_f32le(b + 16 * i + 4 * k, f[k]);
    }
  }
  a = pack_accessor(&pk,
                    pack_view(&pk, b, nv, z ? 4 : 16, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, z),
                    z ? GL_UNSIGNED_BYTE : GL_FLOAT, z, nv, "VEC4", NULL, NULL, 0);
  if (a < 0) goto nomem;
  cJSON_AddNumberToObject(attrs, "WEIGHTS_0", a);
  cJSON_AddNumberToObject(prim, "mode", nf ? 4 : 0);

  /* ---- skeleton: node 0 the skinned mesh, node 1 an identity root, nodes 2.. the bones,
   * each bound at its rest centre with no rotation, so inverseBindMatrix_j = T(-c_j) and the
   * fitted rest->frame transform [R | t] is the node's TRS: rotation R, translation R c_j + t.
   * Compressed, the dequantisation (scale s, offset o) joins each inverse bind matrix:
   * T(o - c_j) S(s), as gltfpack does (a skinned mesh's own node transform is ignored). */
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
  /* A skeleton export's joints keep their hierarchy (each node under its parent's, at its rest
   * offset from it, its channels local to it), so an animator gets a bone chain to edit and an
   * engine one to retarget; SSDR's bones are siblings under the root. Either way every bone is
   * bound at its rest centre with no rotation, so the inverse bind matrices are the same. */
  const int32_t *par = w->bone_parent;
  for (size_t j = 0; j < B; ++j) {
    cJSON_AddItemToArray(joints, cJSON_CreateNumber((double)(j + 2)));
    if (!par || par[j] < 0) cJSON_AddItemToArray(children, cJSON_CreateNumber((double)(j + 2)));
    cJSON *nj = cJSON_CreateObject();
    char nm[32];
    snprintf(nm, sizeof nm, "bone_%03zu", j);
    cJSON_AddStringToObject(nj, "name", w->bone_names && w->bone_names[j] ? w->bone_names[j] : nm);
    float c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = (float)(fit->centers[3 * j + k] -
                     (par && par[j] >= 0 ? fit->centers[3 * (size_t)par[j] + k] : 0.0));
    cJSON_AddItemToObject(nj, "translation", num_array(c, 3));
    cJSON_AddItemToArray(nodes, nj);
  }
  if (any_still) cJSON_AddItemToArray(joints, cJSON_CreateNumber(1)); /* joint B */
  for (size_t j = 0; par && j < B; ++j)
    if (par[j] >= 0) {
      cJSON *pn = cJSON_GetArrayItem(nodes, par[j] + 2);
      cJSON *ch = cJSON_GetObjectItemCaseSensitive(pn, "children");
      if (!ch) ch = cJSON_AddArrayToObject(pn, "children");
      cJSON_AddItemToArray(ch, cJSON_CreateNumber((double)(j + 2)));
    }
  for (size_t j = 0; j < BJ; ++j) { /* the armature root (j == B) is bound where it is */
    float m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (int c = 0; c < 3; ++c) {
      m[5 * c] = z ? (float)g.s : 1.0f;
      m[12 + c] = (float)((z ? g.off[c] : 0.0) -
                          (j < B ? fit->centers[3 * j + c] : 0.0)); /* column-major */
    }
    for (int k = 0; k < 16; ++k)
      km__put_f32le(b + 64 * j + 4 * k, m[k]);
  }
  a = pack_accessor(&pk, pack_view(&pk, b, BJ, 64, PACK_ATTRIBUTES, NULL, 0, false), GL_FLOAT,
                    false, BJ, "MAT4", NULL, NULL, 0);
  if (a < 0) goto nomem;
  cJSON *skin = cJSON_CreateObject();
  cJSON_AddNumberToObject(skin, "inverseBindMatrices", a);
  cJSON_AddNumberToObject(skin, "skeleton", 1);
  cJSON_AddItemToObject(skin, "joints", joints);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "skins"), skin);
  cJSON_AddNumberToObject(root, "scene", 0);
  cJSON *scene = cJSON_CreateObject();
  cJSON_AddItemToObject(scene, "nodes", cJSON_CreateIntArray((const int[]){0, 1}, 2));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);

  /* ---- animation: shared key times, then per bone a translation and a rotation channel
   * (compressed: translations through the exponential filter, 16-bit mantissa; rotations
   * through the quaternion filter, 16 bits, stored as normalised shorts) */
  for (size_t t = 0; t < T; ++t)
    f4[t] = (float)((double)t / w->fps);
  double tmin = 0, tmax = f4[T - 1];
  int a_time = pack_raw_floats(&pk, f4, T, "SCALAR", 1, b, &tmin, &tmax);
  if (a_time < 0) goto nomem;
  cJSON *anim = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "animations"), anim);
  cJSON_AddStringToObject(anim, "name", "kinemesh");
  cJSON *channels = cJSON_AddArrayToObject(anim, "channels");
  cJSON *samplers = cJSON_AddArrayToObject(anim, "samplers");
  /* Compressed, all bones share one translation and one rotation view (an accessor per bone
   * at its offset): far less JSON than two views per bone. Plain: a view per channel. */
  float *tr = km__malloc(B * T * 3, sizeof *tr), *rq = km__malloc(B * T * 4, sizeof *rq);
  unsigned char *eb = malloc(B * T * 16), *db = malloc(B * T * 16);
  if (!tr || !rq || !eb || !db) {
    free(tr);
    free(rq);
    free(eb);
    free(db);
    goto nomem;
  }
  for (size_t j = 0; j < B; ++j) {
    const double *c = fit->centers + 3 * j;
    double qprev[4] = {0, 0, 0, 1};
    for (size_t t = 0; t < T; ++t) {
      const double *M = fit->transforms + (t * B + j) * 12;
      /* the node's world pose: rotation R, its bind centre carried to x */
      double x[3], R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]}, q[4];
      for (int k = 0; k < 3; ++k)
        x[k] = M[4 * k] * c[0] + M[4 * k + 1] * c[1] + M[4 * k + 2] * c[2] + M[4 * k + 3];
      if (par && par[j] >= 0) { /* local to the parent's pose: Rp^T R, Rp^T (x - xp) */
        const double *P = fit->transforms + (t * B + (size_t)par[j]) * 12,
                     *cp = fit->centers + 3 * (size_t)par[j];
        double d[3], L[9];
        for (int k = 0; k < 3; ++k)
          d[k] = x[k] -
                 (P[4 * k] * cp[0] + P[4 * k + 1] * cp[1] + P[4 * k + 2] * cp[2] + P[4 * k + 3]);
        for (int r = 0; r < 3; ++r) {
          x[r] = P[r] * d[0] + P[4 + r] * d[1] + P[8 + r] * d[2];
          for (int k = 0; k < 3; ++k)
            L[3 * r + k] = P[r] * R[k] + P[4 + r] * R[3 + k] + P[8 + r] * R[6 + k];
        }
        memcpy(R, L, sizeof L);
      }
      for (int k = 0; k < 3; ++k)
        tr[(j * T + t) * 3 + k] = (float)x[k];
      quat_from_m3(R, q);
      /* the shorter arc between keys: players interpolate (s)linearly */
      if (q[0] * qprev[0] + q[1] * qprev[1] + q[2] * qprev[2] + q[3] * qprev[3] < 0)
        for (int k = 0; k < 4; ++k)
          q[k] = -q[k];
      memcpy(qprev, q, sizeof q);
      for (int k = 0; k < 4; ++k)
        rq[(j * T + t) * 4 + k] = (float)q[k];
    }
  }
  int v_t = -1, v_r = -1;
  if (z) {
    meshopt_encodeFilterExp(eb, B * T, 12, 16, tr);
    memcpy(db, eb, B * T * 12);
    meshopt_decodeFilterExp(db, B * T, 12);
    for (size_t j = 0; j < B; ++j)
      for (size_t t = 0; t < T; ++t)
        for (int k = 0; k < 3; ++k)
          rig[(t * B + j) * 12 + 4 * k + 3] = ((const float *)db)[(j * T + t) * 3 + k];
    v_t = pack_view(&pk, eb, B * T, 12, PACK_ATTRIBUTES, "EXPONENTIAL", 0, false);
    meshopt_encodeFilterQuat(eb, B * T, 8, ROT_BITS, rq);
    memcpy(db, eb, B * T * 8);
    meshopt_decodeFilterQuat(db, B * T, 8);
    for (size_t j = 0; j < B; ++j)
      for (size_t t = 0; t < T; ++t) {
        double q[4], R[9];
        for (int k = 0; k < 4; ++k) {
          int16_t v;
          memcpy(&v, db + 8 * (j * T + t) + 2 * k, 2);
          q[k] = fmax(v / 32767.0, -1.0);
        }
        quat_to_m3(q, R);
        double *D = rig + (t * B + j) * 12;
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k)
            D[4 * r + k] = R[3 * r + k];
      }
    v_r = pack_view(&pk, eb, B * T, 8, PACK_ATTRIBUTES, "QUATERNION", 0, false);
    /* a hierarchy's channels are local: the decoded poses composed down the chain (parents
     * come first), as a player composes them */
    for (size_t t = 0; par && t < T; ++t)
      for (size_t j = 0; j < B; ++j) {
        if (par[j] < 0) continue;
        const double *P = rig + (t * B + (size_t)par[j]) * 12;
        double *D = rig + (t * B + j) * 12, W[12];
        for (int r = 0; r < 3; ++r) {
          for (int k = 0; k < 3; ++k)
            W[4 * r + k] = P[4 * r] * D[k] + P[4 * r + 1] * D[4 + k] + P[4 * r + 2] * D[8 + k];
          W[4 * r + 3] =
              P[4 * r] * D[3] + P[4 * r + 1] * D[7] + P[4 * r + 2] * D[11] + P[4 * r + 3];
        }
        memcpy(D, W, sizeof W);
      }
  }
  free(eb);
  free(db);
  for (size_t j = 0; j < B; ++j) {
    int a_t, a_r;
    if (z) {
      a_t = pack_accessor_at(&pk, v_t, j * T * 12, GL_FLOAT, false, T, "VEC3", NULL, NULL, 0);
      a_r = pack_accessor_at(&pk, v_r, j * T * 8, GL_SHORT, true, T, "VEC4", NULL, NULL, 0);
    } else {
      a_t = pack_raw_floats(&pk, tr + j * T * 3, T, "VEC3", 3, b, NULL, NULL);
      a_r = pack_raw_floats(&pk, rq + j * T * 4, T, "VEC4", 4, b, NULL, NULL);
    }
    if (a_t < 0 || a_r < 0) {
      free(tr);
      free(rq);
      goto nomem;
    }
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

  free(tr);
  free(rq);

  /* ---- the error of what a player evaluates from the compressed file: dequantised rest and
   * weights, decoded rotations and translations, float32 bind centres */
  double rms = fit->rms_error, emax = fit->max_error;
  if (z && frames) {
    double sum = 0, m2 = 0;
#pragma omp parallel for reduction(+ : sum) reduction(max : m2) schedule(static)
    for (size_t t = 0; t < T; ++t)
      for (size_t i = 0; i < nv; ++i) {
        double p[3] = {0, 0, 0};
        if (still_row(&fit->skin, i)) /* bound to the armature root, which stays */
          p[0] = vq[3 * i], p[1] = vq[3 * i + 1], p[2] = vq[3 * i + 2];
        for (int k = 0; k < 4; ++k) {
          int32_t j = fit->skin.joints[4 * i + k];
          if (j < 0 || wq[4 * i + k] == 0) continue;
          const double *D = rig + (t * B + (size_t)j) * 12;
          double l[3];
          for (int c = 0; c < 3; ++c)
            l[c] = vq[3 * i + c] - (double)(float)fit->centers[3 * j + c];
          for (int r = 0; r < 3; ++r)
            p[r] += wq[4 * i + k] *
                    (D[4 * r] * l[0] + D[4 * r + 1] * l[1] + D[4 * r + 2] * l[2] + D[4 * r + 3]);
        }
        const double *X = frames + (t * nv + i) * 3;
        double e2 = (p[0] - X[0]) * (p[0] - X[0]) + (p[1] - X[1]) * (p[1] - X[1]) +
                    (p[2] - X[2]) * (p[2] - X[2]);
        sum += e2;
        if (e2 > m2) m2 = e2;
      }
    rms = sqrt(sum / (double)(T * nv));
    emax = sqrt(m2);
  }
  w->q_rms = rms;
  w->q_max = emax;
  cJSON_AddNumberToObject(ex, "rms_error_m", rms);
  cJSON_AddNumberToObject(ex, "max_error_m", emax);
  if (z) add_grid_extras(ex, &g);
  if (pack_materials(&pk, root, mesh, prim, w->material_mesh.materials,
                     w->material_mesh.n_materials) < 0)
    goto nomem;
  pack_finish_json(&pk, root);
  free(b);
  free(b2);
  free(f4);
  free(vq);
  free(wq);
  free(rig);
  s = write_glb_container(w, root, pk.bin.p, pk.bin.len, NULL, NULL, err);
  free(pk.bin.p);
  return s;
nomem:
  cJSON_Delete(root);
  cJSON_Delete(pk.views);
  cJSON_Delete(pk.accessors);
  free(pk.bin.p);
  free(b);
  free(b2);
  free(f4);
  free(vq);
  free(wq);
  free(rig);
  return km__fail(err, KM_ERR_NOMEM, "%s: out of memory writing the skinned glb", w->path);
}

/* ---------------------------------------------------------------- compressed morphs (issue 16) */

/* The morph file (per-key or PCA targets) with KHR_mesh_quantization + EXT_meshopt_compression:
 * rest positions on the 14-bit grid (the mesh node's scale and translation dequantise),
 * target POSITION deltas as signed shorts on the same grid, normals octahedral 8-bit, NORMAL
 * deltas as normalised bytes, UVs as normalised shorts, weights through the exponential
 * filter. The error a player sees (against the key frames, or against every frame for PCA) is
 * left in w->q_rms / w->q_max and the extras. */
static km_status glb_finish_packed(km_anim_writer *w, km_error *err) {
  const size_t nv = w->n_vertices, nf = w->n_faces, nk = w->n_keys, nv3 = nv * 3;
  const bool pca = w->pca_weights != NULL, with_n = w->normals;
  const size_t nt = pca ? w->pca_frames : nk;
  double maxd = 0;
  for (size_t i = 0; i < 6 * nk; ++i)
    maxd = fmax(maxd, fabs((double)w->key_minmax[i]));
  const qgrid g = make_grid(w->rest_minmax, maxd);
  glb_pack pk = {.compress = true, .nv = nv};
  pk.views = cJSON_CreateArray();
  pk.accessors = cJSON_CreateArray();
  cJSON *root = cJSON_CreateObject();
  size_t scratch = nv * 16;
  if (nf * 12 > scratch) scratch = nf * 12;
  if (nt * nk * 4 > scratch) scratch = nt * nk * 4;
  unsigned char *b = malloc(scratch);
  float *f4 = km__malloc(nv * 4, sizeof *f4), *wts = km__malloc(nt * nk, sizeof *wts);
  float *wdec = km__malloc(nt * nk, sizeof *wdec);
  double *vq = km__malloc(nv3, sizeof *vq), *rest_n = NULL;
  double *acc = pca ? km__calloc(nt * nv3, sizeof *acc) : NULL;
  km_status s = KM_OK;
  double sum = 0, m2 = 0;
  size_t n_err = 0;
  if (!root || !pk.views || !pk.accessors || !b || !f4 || !wts || !wdec || !vq || (pca && !acc))
    goto nomem;

  char ek[32];
  snprintf(ek, sizeof ek, "morphs:%zu", nk);
  cJSON *ex = add_asset(root, w->fps, w->frames, w->key_every, pca ? ek : NULL);
  add_grid_extras(ex, &g);
  cJSON_AddNumberToObject(root, "scene", 0);
  cJSON *scene = cJSON_CreateObject();
  cJSON_AddItemToObject(scene, "nodes", cJSON_CreateIntArray((const int[]){0}, 1));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);
  cJSON *node = cJSON_CreateObject();
  cJSON_AddNumberToObject(node, "mesh", 0);
  cJSON_AddStringToObject(node, "name", "kinemesh");
  cJSON_AddItemToObject(node, "translation", cJSON_CreateDoubleArray(g.off, 3));
  const double sc[3] = {g.s, g.s, g.s};
  cJSON_AddItemToObject(node, "scale", cJSON_CreateDoubleArray(sc, 3));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "nodes"), node);
  cJSON *mesh = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);
  cJSON *prim = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(mesh, "primitives"), prim);
  cJSON *attrs = cJSON_AddObjectToObject(prim, "attributes");

  /* weights first: the decoded values enter the error */
  for (size_t t = 0; t < nt; ++t)
    for (size_t k = 0; k < nk; ++k)
      wts[t * nk + k] = pca ? w->pca_weights[t * nk + k] : (float)(t == k);
  int a_w = pack_floats(&pk, wts, nt * nk, 1, 16, b, wdec, "SCALAR", NULL, NULL);
  for (size_t k = 0; k < nt; ++k)
    wts[k] = (float)((double)(pca ? k : w->key_frame[k]) / w->fps);
  double tmin = wts[0], tmax = wts[nt - 1];
  int a_in = pack_raw_floats(&pk, wts, nt, "SCALAR", 1, b, &tmin, &tmax);
  if (a_w < 0 || a_in < 0) goto nomem;
  int a;
  if (nf) {
    if ((a = pack_indices(&pk, w->F, nf, b, w->material_mesh.materials,
                          w->material_mesh.n_materials)) < 0)
      goto nomem;
    cJSON_AddNumberToObject(prim, "indices", a);
  }
  double mn[3], mx[3];
  quantise_positions(w->rest, nv, &g, b, mn, mx, vq);
  a = pack_accessor(&pk, pack_view(&pk, b, nv, 8, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, true),
                    GL_UNSIGNED_SHORT, false, nv, "VEC3", mn, mx, 3);
  if (a < 0) goto nomem;
  cJSON_AddNumberToObject(attrs, "POSITION", a);
  if (with_n) {
    if (!(rest_n = km__malloc(nv3, sizeof *rest_n))) goto nomem;
    km__anim_normals(w, w->rest);
    memcpy(rest_n, w->nbuf, nv3 * sizeof *rest_n);
    if ((a = pack_normals(&pk, rest_n, nv, b, f4)) < 0) goto nomem;
    cJSON_AddNumberToObject(attrs, "NORMAL", a);
  }
  if (!pack_surface(&pk, w->uv, w->colors, nv, b, attrs)) goto nomem;
  cJSON_AddNumberToObject(prim, "mode", nf ? 4 : 0);
  cJSON *targets = cJSON_AddArrayToObject(prim, "targets");
  cJSON *names = cJSON_CreateArray();
  cJSON_AddItemToObject(cJSON_AddObjectToObject(mesh, "extras"), "targetNames", names);
  cJSON *weights0 = cJSON_AddArrayToObject(mesh, "weights");
  if (fseek(w->keys, 0, SEEK_SET) != 0) {
    s = km__fail(err, KM_ERR_IO, "%s: cannot rewind the key-frame temporary", w->path);
    goto fail;
  }
  for (size_t k = 0; k < nk; ++k) {
    if (fread(w->fbuf, sizeof *w->fbuf, nv3, w->keys) != nv3) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot read key frame %zu back from its temporary", w->path,
                   k);
      goto fail;
    }
    double dmn[3] = {32767, 32767, 32767}, dmx[3] = {-32767, -32767, -32767};
    for (size_t i = 0; i < nv; ++i) {
      for (int c = 0; c < 3; ++c) {
        double q = round((double)w->fbuf[3 * i + c] / g.s);
        q = q < -32767 ? -32767 : q > 32767 ? 32767 : q;
        dmn[c] = fmin(dmn[c], q), dmx[c] = fmax(dmx[c], q);
        put_u16le(b + 8 * i + 2 * c, (unsigned)(int)q & 0xffffu);
        if (!pca) {
          /* a key frame: what a player shows there against the exact displacement */
          double d = vq[3 * i + c] + wdec[k * nk + k] * g.s * q -
                     (w->rest[3 * i + c] + (double)w->fbuf[3 * i + c]);
          f4[i] = (c ? f4[i] : 0) + (float)(d * d);
        } else {
          for (size_t t = 0; t < nt; ++t)
            acc[t * nv3 + 3 * i + c] += wdec[t * nk + k] * g.s * q;
        }
      }
      put_u16le(b + 8 * i + 6, 0);
      if (!pca) {
        sum += f4[i];
        m2 = fmax(m2, f4[i]);
        ++n_err;
      }
    }
    cJSON *tg = cJSON_CreateObject();
    cJSON_AddItemToArray(targets, tg);
    a = pack_accessor(&pk, pack_view(&pk, b, nv, 8, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, true),
                      GL_SHORT, false, nv, "VEC3", dmn, dmx, 3);
    if (a < 0) goto nomem;
    cJSON_AddNumberToObject(tg, "POSITION", a);
    if (with_n) {
      /* the key's own normals minus the rest's, as normalised bytes (clamped to [-1, 1]) */
      for (size_t i = 0; i < nv3; ++i)
        w->vbuf[i] = w->rest[i] + (double)w->fbuf[i];
      km__anim_normals(w, w->vbuf);
      for (size_t i = 0; i < nv; ++i) {
        for (int c = 0; c < 3; ++c) {
          double d = fmax(-1.0, fmin(1.0, w->nbuf[3 * i + c] - rest_n[3 * i + c]));
          b[4 * i + c] = (unsigned char)(signed char)lround(d * 127);
        }
        b[4 * i + 3] = 0;
      }
      a = pack_accessor(&pk, pack_view(&pk, b, nv, 4, PACK_ATTRIBUTES, NULL, GL_ARRAY_BUFFER, true),
                        GL_BYTE, true, nv, "VEC3", NULL, NULL, 0);
      if (a < 0) goto nomem;
      cJSON_AddNumberToObject(tg, "NORMAL", a);
    }
    char nm[32];
    if (pca)
      snprintf(nm, sizeof nm, w->pca_offset && k + 1 == nk ? "basis_offset" : "basis_%03zu", k);
    else
      snprintf(nm, sizeof nm, "frame_%06zu", w->key_frame[k]);
    cJSON_AddItemToArray(names, cJSON_CreateString(nm));
    cJSON_AddItemToArray(weights0, cJSON_CreateNumber(0));
  }
  if (pca && w->pca_D) {
    /* every frame: base + weighted targets against the exact displacements */
    for (size_t t = 0; t < nt; ++t)
      for (size_t i = 0; i < nv; ++i) {
        double e2 = 0;
        for (int c = 0; c < 3; ++c) {
          double d = vq[3 * i + c] + acc[t * nv3 + 3 * i + c] -
                     (w->rest[3 * i + c] + w->pca_D[t * nv3 + 3 * i + c]);
          e2 += d * d;
        }
        sum += e2;
        m2 = fmax(m2, e2);
        ++n_err;
      }
  }
  w->q_rms = n_err ? sqrt(sum / (double)n_err) : 0;
  w->q_max = sqrt(m2);
  cJSON_AddNumberToObject(ex, "rms_error_m", w->q_rms);
  cJSON_AddNumberToObject(ex, "max_error_m", w->q_max);

  add_weights_animation(root, a_in, a_w);
  if (pack_materials(&pk, root, mesh, prim, w->material_mesh.materials,
                     w->material_mesh.n_materials) < 0)
    goto nomem;
  pack_finish_json(&pk, root);
  s = write_glb_container(w, root, pk.bin.p, pk.bin.len, NULL, NULL, err);
  root = NULL;
  goto done;
nomem:
  s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory writing the compressed glb", w->path);
fail:
  cJSON_Delete(root);
  cJSON_Delete(pk.views);
  cJSON_Delete(pk.accessors);
done:
  free(pk.bin.p);
  free(b);
  free(f4);
  free(wts);
  free(wdec);
  free(vq);
  free(rest_n);
  free(acc);
  return s;
}

/* ---------------------------------------------------------------- morph frames (issue 16) */

/* Accessor a of the file as doubles (any component type, decompressed: the mesh reader's
 * km__gltf_accessor_read), which must have `comps` components; NULL with err filled
 * otherwise. Caller frees. */
static double *read_accessor(const char *path, const char *data, size_t size, int a, int comps,
                             size_t *count, km_error *err) {
  double *v = NULL;
  int nc = 0;
  if (km__gltf_accessor_read(data, size, path, a, &v, count, &nc, err) != KM_OK) return NULL;
  if (nc != comps) {
    free(v);
    km__fail(err, KM_ERR_PARSE, "%s: JSON: accessors[%d] has %d components, expected %d", path, a,
             nc, comps);
    return NULL;
  }
  return v;
}

/* Adds morph target k (its displacements turned by the mesh's world transform's linear part)
 * to every frame with its weight (km__gltf_accessors_each's callback). */
typedef struct {
  const char *path;
  double *out; /* nk*nv*3 */
  size_t nv, nt, nk;
  const double *w; /* nk*nt weights, or NULL: target k is frame k */
  const double *M; /* column-major 4x4 */
} morph_sum;

static km_status add_target(void *ctx, size_t t, const double *td, size_t count, int ncomp,
                            km_error *err) {
  morph_sum *m = ctx;
  if (count != m->nv || ncomp != 3)
    return km__fail(err, KM_ERR_PARSE, "%s: morph target %zu has no POSITION of %zu vertices",
                    m->path, t, m->nv);
  const double *M = m->M;
  for (size_t k = 0; k < m->nk; ++k) {
    double wk = m->w ? m->w[k * m->nt + t] : (k == t ? 1.0 : 0.0);
    if (wk == 0) continue;
    double *o = m->out + k * m->nv * 3;
    for (size_t i = 0; i < m->nv; ++i)
      for (int c = 0; c < 3; ++c)
        o[3 * i + c] +=
            wk * (M[c] * td[3 * i] + M[4 + c] * td[3 * i + 1] + M[8 + c] * td[3 * i + 2]);
  }
  return KM_OK;
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
  double *out = NULL, *base = NULL, *tdata = NULL, *wdata = NULL;
  if (size < 28 || km__get_u32le(b) != GLB_MAGIC || km__get_u32le(b + 16) != GLB_JSON ||
      (uint64_t)km__get_u32le(b + 12) + 28 > size) {
    s = km__fail(err, KM_ERR_PARSE, "%s: byte 0: not a glTF binary with a JSON chunk", path);
    goto done;
  }
  size_t jl = km__get_u32le(b + 12);
  size_t bin_len = km__get_u32le(b + 20 + jl); /* the accessors are read (checked) from it below */
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
  size_t nt = (size_t)cJSON_GetArraySize(targets), cnt = 0;
  if (!cJSON_IsNumber(pos) || nt == 0) {
    s = km__fail(err, KM_ERR_UNSUPPORTED,
                 "%s: meshes[0].primitives[0] has no morph targets: not a morph animation", path);
    goto done;
  }
  /* The mesh's world transform (a quantised file dequantises there): the base positions take
   * all of it, the targets' displacements its linear part. */
  double M[16];
  if ((s = km__gltf_mesh_transform(data, size, path, 0, M, err)) != KM_OK) goto done;
  if (!(base = read_accessor(path, data, size, pos->valueint, 3, &cnt, err))) {
    s = err && err->status ? err->status : KM_ERR_PARSE;
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
  size_t nk = nt, wcnt = 0;
  if (wsampler) {
    const cJSON *in = get_path(wsampler, "input", -1), *o = get_path(wsampler, "output", -1);
    if (!cJSON_IsNumber(in) || !cJSON_IsNumber(o) ||
        !(tdata = read_accessor(path, data, size, in->valueint, 1, &nk, err)) ||
        !(wdata = read_accessor(path, data, size, o->valueint, 1, &wcnt, err))) {
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
      double t0 = tdata[0], t1 = tdata[nk - 1];
      if (t1 > t0 && fps) *fps = (double)(nk - 1) / (t1 - t0);
    }
  }
  const cJSON *ex = get_path(get_path(get_path(root, "asset", -1), "extras", -1), "kinemesh", -1);
  const cJSON *efps = get_path(ex, "fps", -1);
  if (fps && cJSON_IsNumber(efps) && efps->valuedouble > 0) *fps = efps->valuedouble;
  /* Keys and targets may share bytes, so a small forged file can ask for keys x vertices
   * positions growing with the square of its size: refuse an expansion beyond 2000 times the
   * file (a compact morph export of a long take expands ~400x) and beyond 1 GiB. */
  {
    double need = (double)nk * (double)nv * 3 * sizeof *out;
    double cap = fmax((double)(1u << 30), 2000.0 * (double)size);
    if (need > cap) {
      s = km__fail(err, KM_ERR_UNSUPPORTED,
                   "%s: %zu keys x %zu vertices would expand to %.3g GB, more than 2000 times the "
                   "%zu-byte file: refused (a forged or degenerate animation)",
                   path, nk, nv, need / 1e9, size);
      goto done;
    }
  }
  if (!(out = km__malloc(nk * nv * 3, sizeof *out))) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", path, nk);
    goto done;
  }
  for (size_t k = 0; k < nk; ++k)
    for (size_t i = 0; i < nv; ++i)
      for (int c = 0; c < 3; ++c) /* column-major M: x' = M[0..2] x + M[4..6] y + ... + M[12..14] */
        out[(k * nv + i) * 3 + c] = M[c] * base[3 * i] + M[4 + c] * base[3 * i + 1] +
                                    M[8 + c] * base[3 * i + 2] + M[12 + c];
  {
    int *ti = km__malloc(nt, sizeof *ti);
    if (!ti) {
      s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
      goto done;
    }
    for (size_t t = 0; t < nt; ++t) {
      const cJSON *tp = get_path(cJSON_GetArrayItem(targets, (int)t), "POSITION", -1);
      if (!cJSON_IsNumber(tp)) {
        free(ti);
        s = km__fail(err, KM_ERR_PARSE, "%s: morph target %zu has no POSITION", path, t);
        goto done;
      }
      ti[t] = tp->valueint;
    }
    morph_sum ms = {path, out, nv, nt, nk, wdata, M};
    s = km__gltf_accessors_each(data, size, path, ti, nt, add_target, &ms, err);
    free(ti);
    if (s != KM_OK) goto done;
  }
  *frames = out;
  *n_frames = nk;
  out = NULL;
done:
  cJSON_Delete(root);
  free(out);
  free(base);
  free(tdata);
  free(wdata);
  free(data);
  return s;
}
