/* Streaming animation output: a fixed-connectivity mesh, one frame at a time, to
 *  - PC2 (Blender / 3ds Max point cache),
 *  - a directory of per-frame OBJ or binary PLY files,
 *  - glTF 2.0 binary with one morph target per (key) frame (glb.c).
 * Nothing appears at the destination until close succeeds: PC2 and glb go through
 * km__atomic_open/commit, a directory is filled under "<dir>.tmp.<pid>" and renamed. */
#include "anim/anim.h"
#include "linalg/linalg.h"
#include "math/math.h" /* km_lbs */
#include "mesh/mesh.h" /* km__obj_write */

#include <dirent.h>
#include <float.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define PC2_HEADER 32
#define PC2_NSAMPLES_OFFSET 28

static char *dup_str(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

/* "frame_" + at least 6 digits + ".obj"/".ply": the files this module writes into a
 * directory. Returns 1 for obj, 2 for ply, 0 otherwise. */
static int frame_file_kind(const char *name) {
  if (strncmp(name, "frame_", 6) != 0) return 0;
  const char *p = name + 6;
  size_t digits = 0;
  while (*p >= '0' && *p <= '9')
    ++p, ++digits;
  if (digits < 6) return 0;
  if (strcmp(p, ".obj") == 0) return 1;
  if (strcmp(p, ".ply") == 0) return 2;
  return 0;
}

/* "materials.mtl" or "texture_<k>.png|.jpg": an OBJ folder's material library and images
 * (km__obj_write_materials, written once beside the frames). */
static bool material_file(const char *name) {
  if (!strcmp(name, "materials.mtl")) return true;
  if (strncmp(name, "texture_", 8) != 0) return false;
  const char *p = name + 8;
  size_t digits = 0;
  while (*p >= '0' && *p <= '9')
    ++p, ++digits;
  return digits && (!strcmp(p, ".png") || !strcmp(p, ".jpg"));
}

/* Checks that an existing directory holds only frame files (ours, from an earlier run), so
 * replacing it cannot destroy anything else. */
static km_status check_replaceable_dir(const char *path, km_error *err) {
  DIR *d = opendir(path);
  if (!d) return km__fail(err, KM_ERR_IO, "%s: cannot open directory: %s", path, strerror(errno));
  km_status s = KM_OK;
  struct dirent *e;
  while ((e = readdir(d)) != NULL) {
    if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
    if (!frame_file_kind(e->d_name) && !material_file(e->d_name)) {
      s = km__fail(err, KM_ERR_IO,
                   "%s: directory exists and holds '%s', which is not a frame file; refusing to "
                   "replace it",
                   path, e->d_name);
      break;
    }
  }
  closedir(d);
  return s;
}

/* Removes the frame and material files of a directory, then the directory (if it is then
 * empty). */
static void remove_frame_dir(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return;
  size_t n = strlen(dir);
  struct dirent *e;
  while ((e = readdir(d)) != NULL) {
    if (!frame_file_kind(e->d_name) && !material_file(e->d_name)) continue;
    size_t m = n + strlen(e->d_name) + 2;
    char *p = malloc(m);
    if (!p) break;
    snprintf(p, m, "%s/%s", dir, e->d_name);
    remove(p);
    free(p);
  }
  closedir(d);
  if (rmdir(dir) != 0) km__log(KM_LOG_WARN, "%s: could not remove directory", dir);
}

static void writer_discard(km_anim_writer *w) {
  if (w->af.f || w->af.path) km__atomic_abort(&w->af);
  if (w->keys) fclose(w->keys);
  if (w->tmp_dir) remove_frame_dir(w->tmp_dir);
  if (w->tmp_dir) km__tmp_dir_unregister(w->tmp_dir_slot);
  free(w->tmp_dir);
  free(w->path);
  free(w->rest);
  free(w->F);
  free(w->fbuf);
  free(w->bytes);
  free(w->key_frame);
  free(w->key_minmax);
  free(w->last);
  free(w->uv);
  free(w->colors);
  km_mesh_free(&w->material_mesh);
  free(w->nbuf);
  free(w->vbuf);
  free(w->ubuf);
  free(w->pca_weights);
  free(w->bskin.joints);
  free(w->bskin.weights);
  free(w->bcenter);
  for (size_t j = 0; w->bone_names && j < w->n_bones; ++j)
    free(w->bone_names[j]);
  free(w->bone_names);
  free(w->bone_parent);
  free(w->bxf);
  free(w);
}

void km_anim_writer_free(km_anim_writer **w) {
  if (!w || !*w) return;
  writer_discard(*w);
  *w = NULL;
}

/* The format a path names: .glb, .pc2, or a folder of frames (a path with no extension, or a
 * folder that exists); KM_ANIM_AUTO for any other extension. `-o take.fbx` or `-o anim.gltf`
 * made a folder of that name holding hundreds of OBJ frames, where the user asked for a file. */
static km_anim_format format_from_path(const char *path, char ext[16]) {
  km__extension(path, ext, 16);
  if (strcmp(ext, "glb") == 0) return KM_ANIM_GLB;
  if (strcmp(ext, "pc2") == 0) return KM_ANIM_PC2;
  struct stat st;
  if (!ext[0] || (stat(path, &st) == 0 && S_ISDIR(st.st_mode))) return KM_ANIM_OBJ_DIR;
  return KM_ANIM_AUTO;
}

static void minmax_init(float mm[6]) {
  for (int c = 0; c < 3; ++c) {
    mm[c] = INFINITY;
    mm[3 + c] = -INFINITY;
  }
}

/* KM_ANIM_EXPORT_SKELETON: the skeleton and weights copied (checked against the rest mesh's
 * vertex count and the skeleton's joints). */
static km_status skeleton_setup(km_anim_writer *w, const km_anim_options *o, const char *path,
                                km_error *err) {
  const km_skeleton *sk = o->skeleton;
  const km_skin *sw = o->weights;
  if (!sk || !sw || !sk->rest || sk->n_joints == 0 || !sw->joints || !sw->weights)
    return km__fail(err, KM_ERR_INVALID,
                    "%s: a skeleton export needs the skeleton (with its rest joints) and the "
                    "weights",
                    path);
  if (sw->n_vertices != w->n_vertices)
    return km__fail(err, KM_ERR_INVALID, "%s: the weights are for %zu vertices, the mesh has %zu",
                    path, sw->n_vertices, w->n_vertices);
  if (sk->n_joints > 65535)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: %zu joints, at most 65535", path, sk->n_joints);
  const size_t nv = w->n_vertices, nb = sk->n_joints;
  for (size_t i = 0; i < KM_SKIN_INFLUENCES * nv; ++i)
    if (sw->joints[i] >= (int32_t)nb)
      return km__fail(err, KM_ERR_INVALID, "%s: vertex %zu is weighted to joint %d of %zu", path,
                      i / KM_SKIN_INFLUENCES, (int)sw->joints[i], nb);
  w->export_kind = KM_ANIM_EXPORT_SKELETON;
  w->key_every = 1;
  w->n_bones = nb;
  w->bskin.n_vertices = nv;
  w->bskin.joints = km__malloc(KM_SKIN_INFLUENCES * nv, sizeof *w->bskin.joints);
  w->bskin.weights = km__malloc(KM_SKIN_INFLUENCES * nv, sizeof *w->bskin.weights);
  w->bcenter = km__malloc(3 * nb, sizeof *w->bcenter);
  w->bone_names = km__calloc(nb, sizeof *w->bone_names);
  if (sk->parents) w->bone_parent = km__malloc(nb, sizeof *w->bone_parent);
  if (!w->bskin.joints || !w->bskin.weights || !w->bcenter || !w->bone_names ||
      (sk->parents && !w->bone_parent))
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  for (size_t j = 0; sk->parents && j < nb; ++j) {
    if (sk->parents[j] < -1 || sk->parents[j] >= (int32_t)j)
      return km__fail(err, KM_ERR_INVALID, "%s: joint %zu's parent %d is not an earlier joint",
                      path, j, (int)sk->parents[j]);
    w->bone_parent[j] = sk->parents[j];
  }
  memcpy(w->bskin.joints, sw->joints, KM_SKIN_INFLUENCES * nv * sizeof *w->bskin.joints);
  memcpy(w->bskin.weights, sw->weights, KM_SKIN_INFLUENCES * nv * sizeof *w->bskin.weights);
  memcpy(w->bcenter, sk->rest, 3 * nb * sizeof *w->bcenter);
  for (size_t j = 0; j < nb; ++j) {
    char nm[32];
    snprintf(nm, sizeof nm, "joint_%03zu", j);
    if (!(w->bone_names[j] = dup_str(sk->names && sk->names[j] ? sk->names[j] : nm)))
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  return KM_OK;
}

km_status km_anim_writer_open(const char *path, const km_mesh *rest, const km_anim_options *opt,
                              km_anim_writer **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_anim_writer_open: out is NULL");
  *out = NULL;
  if (!path || !*path) return km__fail(err, KM_ERR_INVALID, "km_anim_writer_open: empty path");
  if (!rest || !rest->V || rest->n_vertices == 0)
    return km__fail(err, KM_ERR_INVALID, "%s: the rest mesh has no vertices", path);
  if (rest->n_faces && !rest->F)
    return km__fail(err, KM_ERR_INVALID, "%s: the rest mesh has faces but F is NULL", path);
  /* PC2 stores the point count as int32 and glb indexes with uint32. */
  if (rest->n_vertices > (size_t)INT32_MAX || rest->n_faces > (size_t)INT32_MAX / 3)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: mesh too large for animation output", path);
  const size_t nv = rest->n_vertices, nf = rest->n_faces;
  for (size_t i = 0; i < nf * 3; ++i)
    if (rest->F[i] < 0 || (size_t)rest->F[i] >= nv)
      return km__fail(err, KM_ERR_INVALID, "%s: face %zu references vertex %ld of %zu", path, i / 3,
                      (long)rest->F[i], nv);
  for (size_t i = 0; i < nv * 3; ++i)
    if (!(fabs(rest->V[i]) <= FLT_MAX))
      return km__fail(err, KM_ERR_INVALID, "%s: rest vertex %zu has a non-finite coordinate", path,
                      i / 3);

  km_anim_options o = opt ? *opt : (km_anim_options){0};
  if (o.fps == 0) o.fps = 30;
  if (!(o.fps > 0) || !isfinite(o.fps))
    return km__fail(err, KM_ERR_INVALID, "%s: fps must be positive, got %g", path, o.fps);
  if (o.key_every == 0) o.key_every = 1;
  if (o.format == KM_ANIM_AUTO) {
    char ext[16];
    o.format = format_from_path(path, ext);
    if (o.format == KM_ANIM_AUTO) {
      char hint[96] = "";
      if (!strcmp(ext, "gltf"))
        snprintf(hint, sizeof hint, " (.glb is the same glTF 2.0 in one binary file)");
      else if (!strcmp(ext, "obj") || !strcmp(ext, "ply"))
        snprintf(hint, sizeof hint,
                 " (one file per frame: name the folder, e.g. -o frames/, and --frame-format %s)",
                 ext);
      return km__fail(err, KM_ERR_INVALID,
                      "%s: an animation is written as .glb, .pc2 or a folder of frames (a path "
                      "with no extension), not .%s%s",
                      path, ext, hint);
    }
  }
  if (o.format < KM_ANIM_GLB || o.format > KM_ANIM_PLY_DIR)
    return km__fail(err, KM_ERR_INVALID, "%s: unknown animation format %d", path, (int)o.format);

  km_anim_writer *w = calloc(1, sizeof *w);
  if (!w) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  w->tmp_dir_slot = -1;
  w->format = o.format;
  w->n_vertices = nv;
  w->n_faces = nf;
  w->fps = o.fps;
  w->key_every = o.key_every;
  if (o.export_kind != KM_ANIM_EXPORT_MORPHS && o.export_kind != KM_ANIM_EXPORT_SKIN &&
      o.export_kind != KM_ANIM_EXPORT_MORPHS_PCA && o.export_kind != KM_ANIM_EXPORT_SKELETON) {
    free(w);
    return km__fail(err, KM_ERR_INVALID, "%s: unknown export kind %d", path, (int)o.export_kind);
  }
  if (o.format == KM_ANIM_GLB && o.export_kind == KM_ANIM_EXPORT_SKIN) {
    w->export_kind = KM_ANIM_EXPORT_SKIN;
    w->key_every = 1; /* the fit sees every frame */
    if (o.skin) w->skin = *o.skin;
  }
  if (o.format == KM_ANIM_GLB && o.export_kind == KM_ANIM_EXPORT_MORPHS_PCA) {
    w->export_kind = KM_ANIM_EXPORT_MORPHS_PCA;
    w->key_every = 1; /* the basis sees every frame */
    w->pca_k = o.morphs ? o.morphs : 16;
  }
  if (o.format == KM_ANIM_GLB && o.export_kind == KM_ANIM_EXPORT_SKELETON) {
    km_status ks = skeleton_setup(w, &o, path, err);
    if (ks != KM_OK) {
      km_anim_writer_free(&w);
      return ks;
    }
  }
  w->compress = o.format == KM_ANIM_GLB && o.compress;
  w->path = dup_str(path);
  /* "out/frames/" must not put the temporary directory inside the destination. */
  for (size_t n = w->path ? strlen(w->path) : 0; n > 1 && w->path[n - 1] == '/'; --n)
    w->path[n - 1] = '\0';
  w->rest = km__malloc(nv * 3, sizeof *w->rest);
  w->F = km__malloc(nf * 3, sizeof *w->F);
  if (!w->path || !w->rest || !w->F) goto nomem;
  memcpy(w->rest, rest->V, nv * 3 * sizeof *w->rest);
  if (nf) memcpy(w->F, rest->F, nf * 3 * sizeof *w->F);
  /* Written in a file's frame (issue 11: a point cache on the object a z-up tool imported from
   * the file): the rest copy now, every frame as it is pushed. */
  if (!km_frame_is_identity(o.frame)) {
    if (w->format == KM_ANIM_GLB) {
      km_anim_writer_free(&w);
      return km__fail(err, KM_ERR_INVALID,
                      "%s: a glTF file is in glTF's frame (y up, facing +z, metres) by its "
                      "specification: no other frame is written into one",
                      path);
    }
    w->undo = true;
    w->frame = *o.frame;
    if (!(w->ubuf = km__malloc(nv * 3, sizeof *w->ubuf))) goto nomem;
    km_status fs = km_frame_unapply(&w->frame, w->rest, nv, NULL, 0, err);
    if (fs) {
      km_anim_writer_free(&w);
      return fs;
    }
  }
  if (rest->UV) {
    if (!(w->uv = km__malloc(nv * 2, sizeof *w->uv))) goto nomem;
    memcpy(w->uv, rest->UV, nv * 2 * sizeof *w->uv);
  }
  if (rest->colors && w->format != KM_ANIM_PC2) { /* a point cache has no colour */
    if (!(w->colors = km__malloc(nv * 4, sizeof *w->colors))) goto nomem;
    memcpy(w->colors, rest->colors, nv * 4 * sizeof *w->colors);
  }
  /* A coloured mesh without a material (a scan) gets a plain one in a .glb: glTF's default
   * material is fully metallic (metallicFactor 1), which three.js and engines draw near black
   * without an environment map; a scan is a matte surface its colours paint. */
  if (rest->colors && !rest->n_materials && nf && w->format == KM_ANIM_GLB) {
    if (!(w->material_mesh.materials = km__calloc(1, sizeof *w->material_mesh.materials)))
      goto nomem;
    km_mesh_material *q = w->material_mesh.materials;
    w->material_mesh.n_materials = 1;
    q->base_color[0] = q->base_color[1] = q->base_color[2] = q->base_color[3] = 1;
    q->metallic = 0, q->roughness = 1, q->n_faces = nf;
  }
  /* a glb and an OBJ folder carry the file's materials (PLY has no material) */
  if (rest->n_materials && (w->format == KM_ANIM_GLB || w->format == KM_ANIM_OBJ_DIR)) {
    km_mesh only = {.materials = rest->materials, .n_materials = rest->n_materials};
    if (km_mesh_copy(&only, &w->material_mesh, NULL) != KM_OK) goto nomem;
    /* the runs must tile the faces in order (the writers split the primitive by them): a mesh
     * whose faces changed after reading keeps its first material over every face */
    only.n_faces = nf;
    only.materials = w->material_mesh.materials;
    if (!km__obj_materials_cover(&only)) {
      km__log(KM_LOG_WARN,
              "%s: the mesh's materials do not cover its %zu faces in order: its "
              "first material is written over all of them",
              path, nf);
      for (size_t k = 1; k < w->material_mesh.n_materials; ++k)
        km__material_free_images(w->material_mesh.materials + k);
      w->material_mesh.n_materials = 1;
      w->material_mesh.materials[0].first_face = 0;
      w->material_mesh.materials[0].n_faces = nf;
    }
  }
  w->normals = (rest->UV || rest->N) && nf && w->format != KM_ANIM_PC2;
  if (w->normals && (!(w->nbuf = km__malloc(nv * 3, sizeof(double))) ||
                     !(w->vbuf = km__malloc(nv * 3, sizeof(double)))))
    goto nomem;

  km_status s = KM_OK;
  switch (w->format) {
  case KM_ANIM_PC2: {
    w->bytes = km__malloc(nv, 12);
    if (!w->bytes) goto nomem;
    if ((s = km__atomic_open(&w->af, w->path, err)) != KM_OK) goto fail;
    unsigned char h[PC2_HEADER] = "POINTCACHE2";
    km__put_u32le(h + 12, 1);
    km__put_u32le(h + 16, (uint32_t)nv);
    /* PC2 has no frame rate: startFrame 0 and one sample per frame; the reader takes the
     * scene's frame rate. */
    km__put_f32le(h + 20, 0.0f);
    km__put_f32le(h + 24, 1.0f);
    km__put_u32le(h + 28, 0); /* numSamples, patched by close */
    if (fwrite(h, 1, sizeof h, w->af.f) != sizeof h) {
      s = km__fail(err, KM_ERR_IO, "%s: write failed: %s", path, strerror(errno));
      goto fail;
    }
    break;
  }
  case KM_ANIM_GLB: {
    w->fbuf = km__malloc(nv * 3, sizeof *w->fbuf);
    w->last = km__malloc(nv * 3, sizeof *w->last);
    w->bytes = km__malloc(nv, 12);
    if (!w->fbuf || !w->last || !w->bytes) goto nomem;
    /* Key frames can outgrow memory (1M vertices x hundreds of frames), so they wait in an
     * anonymous temporary file that disappears with the process. */
    /* The output's temporary is created now so a bad path fails here, not after the run. */
    if ((s = km__atomic_open(&w->af, w->path, err)) != KM_OK) goto fail;
    w->keys = tmpfile();
    if (!w->keys) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot create a temporary file: %s", path, strerror(errno));
      goto fail;
    }
    minmax_init(w->rest_minmax);
    for (size_t i = 0; i < nv; ++i)
      for (int c = 0; c < 3; ++c) {
        float f = (float)w->rest[3 * i + c];
        if (f < w->rest_minmax[c]) w->rest_minmax[c] = f;
        if (f > w->rest_minmax[3 + c]) w->rest_minmax[3 + c] = f;
      }
    break;
  }
  case KM_ANIM_OBJ_DIR:
  case KM_ANIM_PLY_DIR: {
    struct stat st;
    if (stat(w->path, &st) == 0) {
      if (!S_ISDIR(st.st_mode)) {
        s = km__fail(err, KM_ERR_IO, "%s: exists and is not a directory", path);
        goto fail;
      }
      if ((s = check_replaceable_dir(w->path, err)) != KM_OK) goto fail;
    }
    size_t n = strlen(w->path) + 32;
    w->tmp_dir = malloc(n);
    if (!w->tmp_dir) goto nomem;
    snprintf(w->tmp_dir, n, "%s.tmp.%ld", w->path, (long)getpid());
    if ((s = km__make_parents(w->tmp_dir, err)) != KM_OK) {
      free(w->tmp_dir);
      w->tmp_dir = NULL;
      goto fail;
    }
    if (mkdir(w->tmp_dir, 0777) != 0) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot create directory: %s", w->tmp_dir, strerror(errno));
      free(w->tmp_dir);
      w->tmp_dir = NULL; /* not ours: never remove it */
      goto fail;
    }
    w->tmp_dir_slot =
        km__tmp_dir_register(w->tmp_dir, w->format == KM_ANIM_PLY_DIR ? "ply" : "obj");
    if (w->material_mesh.n_materials) { /* once for every frame's mtllib */
      km__tmp_dir_materials(w->tmp_dir_slot, w->material_mesh.n_materials * KM__SLOTS);
      if ((s = km__obj_write_materials(w->tmp_dir, "materials.mtl", "texture_",
                                       w->material_mesh.materials, w->material_mesh.n_materials,
                                       err)) != KM_OK)
        goto fail;
    }
    break;
  }
  default: break;
  }
  *out = w;
  return KM_OK;
nomem:
  s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for a %zu-vertex animation", path, nv);
fail:
  writer_discard(w);
  return s;
}

/* ---------------------------------------------------------------- per-format frame output */

static km_status push_pc2(km_anim_writer *w, const double *V, km_error *err) {
  for (size_t i = 0; i < w->n_vertices * 3; ++i)
    km__put_f32le(w->bytes + 4 * i, (float)V[i]);
  if (fwrite(w->bytes, 12, w->n_vertices, w->af.f) != w->n_vertices) {
    w->failed = true;
    return km__fail(err, KM_ERR_IO, "%s: write failed at frame %zu: %s", w->path, w->frames,
                    strerror(errno));
  }
  return KM_OK;
}

static km_status store_key(km_anim_writer *w, const float *disp, const float mm[6], size_t frame,
                           km_error *err) {
  if (w->n_keys == w->key_cap) {
    size_t cap = w->key_cap ? 2 * w->key_cap : 64;
    size_t *kf = realloc(w->key_frame, cap * sizeof *kf);
    if (kf) w->key_frame = kf;
    float *km = kf ? realloc(w->key_minmax, cap * 6 * sizeof *km) : NULL;
    if (km) w->key_minmax = km;
    if (!kf || !km) {
      w->failed = true;
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
    }
    w->key_cap = cap;
  }
  if (fwrite(disp, sizeof *disp, w->n_vertices * 3, w->keys) != w->n_vertices * 3) {
    w->failed = true;
    return km__fail(err, KM_ERR_IO, "%s: cannot write key frame %zu to a temporary file: %s",
                    w->path, frame, strerror(errno));
  }
  w->key_frame[w->n_keys] = frame;
  memcpy(w->key_minmax + 6 * w->n_keys, mm, 6 * sizeof *mm);
  ++w->n_keys;
  return KM_OK;
}

static km_status push_glb(km_anim_writer *w, const double *V, km_error *err) {
  /* glb is limited to 4 GiB (uint32 lengths); refuse early rather than at close. */
  uint64_t per_key = (uint64_t)w->n_vertices * 12;
  uint64_t estimate = per_key * (w->n_keys + 2) + (uint64_t)w->n_faces * 12 +
                      (uint64_t)(w->n_keys + 1) * (w->n_keys + 2) * 4 + (1u << 20);
  if (estimate > UINT32_MAX && w->export_kind == KM_ANIM_EXPORT_MORPHS)
    return km__fail(err, KM_ERR_UNSUPPORTED,
                    "%s: frame %zu would make the glb exceed 4 GiB; use key_every > 1 or pc2",
                    w->path, w->frames);
  float mm[6];
  minmax_init(mm);
  for (size_t i = 0; i < w->n_vertices * 3; ++i) {
    float d = (float)(V[i] - w->rest[i]);
    w->last[i] = d;
    if (d < mm[i % 3]) mm[i % 3] = d;
    if (d > mm[3 + i % 3]) mm[3 + i % 3] = d;
  }
  memcpy(w->last_minmax, mm, sizeof mm);
  if (w->frames % w->key_every == 0) return store_key(w, w->last, mm, w->frames, err);
  return KM_OK;
}

void km__anim_normals(km_anim_writer *w, const double *V) {
  km_mesh view = {.V = (double *)V, .F = w->F, .n_vertices = w->n_vertices, .n_faces = w->n_faces};
  if (km_vertex_normals(&view, KM_NORMALS_AREA, w->nbuf, NULL) != KM_OK)
    memset(w->nbuf, 0, w->n_vertices * 3 * sizeof *w->nbuf);
  for (size_t i = 0; i < w->n_vertices; ++i) {
    double *n = w->nbuf + 3 * i;
    if (!(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.5)) n[0] = 0, n[1] = 1, n[2] = 0;
  }
}

static km_status push_dir(km_anim_writer *w, const double *V, km_error *err) {
  bool ply = w->format == KM_ANIM_PLY_DIR;
  if (w->normals) km__anim_normals(w, V);
  size_t n = strlen(w->tmp_dir) + 40;
  char *fp = malloc(n);
  if (!fp) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  snprintf(fp, n, "%s/frame_%06zu.%s", w->tmp_dir, w->frames, ply ? "ply" : "obj");
  FILE *f = fopen(fp, "wb");
  if (!f) {
    km_status s = km__fail(err, KM_ERR_IO, "%s: cannot open for writing: %s", fp, strerror(errno));
    free(fp);
    w->failed = true;
    return s;
  }
  const size_t nv = w->n_vertices, nf = w->n_faces;
  /* the frame as a mesh: one vt / vn per vertex in vertex order (vt as read, vn recomputed
   * for this frame), so every OBJ face reference is i/i/i and the vertex order stays the rest
   * mesh's; coordinates exact (%.17g / raw doubles), as km_mesh_write writes them; the fps in
   * the header comment, for km_anim_info_read */
  char header[96];
  snprintf(header, sizeof header, "kinemesh animation frame %zu fps %.17g", w->frames, w->fps);
  km_mesh view = {.V = (double *)V,
                  .F = w->F,
                  .n_vertices = nv,
                  .n_faces = nf,
                  .UV = w->uv,
                  .N = w->normals ? w->nbuf : NULL,
                  .materials = w->material_mesh.materials,
                  .n_materials = w->material_mesh.n_materials,
                  .colors = w->colors};
  if (ply) {
    km__ply_write(f, &view, KM_PLY_BINARY_LE, header);
  } else {
    km__obj_write(f, &view, header, "materials.mtl", true);
  }
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  km_status s = KM_OK;
  if (bad) {
    s = km__fail(err, KM_ERR_IO, "%s: write failed: %s", fp, strerror(errno));
    w->failed = true;
  }
  free(fp);
  return s;
}

static km_status writer_push(km_anim_writer *w, const double *V, km_error *err);

km_status km_anim_writer_push(km_anim_writer *w, const double *V, km_error *err) {
  if (w && w->export_kind == KM_ANIM_EXPORT_SKELETON)
    return km__fail(err, KM_ERR_INVALID,
                    "%s: a skeleton export takes each frame's bone transforms "
                    "(km_anim_writer_push_pose)",
                    w->path);
  return writer_push(w, V, err);
}

km_status km_anim_writer_push_pose(km_anim_writer *w, const double *V, const double *transforms,
                                   km_error *err) {
  if (!w || w->export_kind != KM_ANIM_EXPORT_SKELETON) return writer_push(w, V, err);
  if (!transforms)
    return km__fail(err, KM_ERR_INVALID, "%s: frame %zu: no bone transforms", w->path, w->frames);
  for (size_t i = 0; i < 12 * w->n_bones; ++i)
    if (!isfinite(transforms[i]))
      return km__fail(err, KM_ERR_INVALID, "%s: frame %zu: joint %s's transform is not finite",
                      w->path, w->frames, w->bone_names[i / 12]);
  if (w->frames >= w->bxf_cap) {
    size_t cap = w->bxf_cap ? 2 * w->bxf_cap : 64;
    double *x = realloc(w->bxf, cap * 12 * w->n_bones * sizeof *x);
    if (!x)
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for the bone transforms", w->path);
    w->bxf = x;
    w->bxf_cap = cap;
  }
  size_t f = w->frames;
  km_status s = writer_push(w, V, err);
  if (s == KM_OK)
    memcpy(w->bxf + f * 12 * w->n_bones, transforms, 12 * w->n_bones * sizeof(double));
  return s;
}

static km_status writer_push(km_anim_writer *w, const double *V, km_error *err) {
  if (!w) return km__fail(err, KM_ERR_INVALID, "km_anim_writer_push: writer is NULL (closed?)");
  if (!V) return km__fail(err, KM_ERR_INVALID, "%s: frame %zu: V is NULL", w->path, w->frames);
  if (w->failed)
    return km__fail(err, KM_ERR_IO, "%s: an earlier write failed; the animation is discarded",
                    w->path);
  if (w->frames >= (size_t)INT32_MAX)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: too many frames", w->path);
  if (w->undo) { /* the file's frame: a signed permutation and a scale, exact but for that */
    memcpy(w->ubuf, V, w->n_vertices * 3 * sizeof *w->ubuf);
    km_status fs = km_frame_unapply(&w->frame, w->ubuf, w->n_vertices, NULL, 0, err);
    if (fs) return fs;
    V = w->ubuf;
  }
  /* A rejected frame is not written, so the writer stays usable. */
  for (size_t i = 0; i < w->n_vertices * 3; ++i)
    if (!(fabs(V[i]) <= FLT_MAX && fabs(V[i] - w->rest[i]) <= FLT_MAX))
      return km__fail(err, KM_ERR_INVALID,
                      "%s: frame %zu: vertex %zu coordinate %zu is not finite in float32 (%g)",
                      w->path, w->frames, i / 3, i % 3, V[i]);
  km_status s = KM_OK;
  switch (w->format) {
  case KM_ANIM_PC2: s = push_pc2(w, V, err); break;
  case KM_ANIM_GLB: s = push_glb(w, V, err); break;
  default: s = push_dir(w, V, err); break;
  }
  if (s == KM_OK) ++w->frames;
  if (s == KM_OK && w->tmp_dir) km__tmp_dir_frames(w->tmp_dir_slot, w->frames);
  return s;
}

/* ---------------------------------------------------------------- close */

static km_status close_pc2(km_anim_writer *w, km_error *err) {
  unsigned char b[4];
  km__put_u32le(b, (uint32_t)w->frames);
  if (fseek(w->af.f, PC2_NSAMPLES_OFFSET, SEEK_SET) != 0 || fwrite(b, 1, 4, w->af.f) != 4)
    return km__fail(err, KM_ERR_IO, "%s: cannot patch the sample count: %s", w->path,
                    strerror(errno));
  return km__atomic_commit(&w->af, err);
}

static km_status close_dir(km_anim_writer *w, km_error *err) {
  struct stat st;
  if (stat(w->path, &st) != 0) {
    if (rename(w->tmp_dir, w->path) != 0)
      return km__fail(err, KM_ERR_IO, "%s: cannot rename %s into place: %s", w->path, w->tmp_dir,
                      strerror(errno));
  } else {
    /* Replace an earlier animation: move it aside, move the new one in, then delete the old
     * frame files. Re-checked here because the directory may have changed since open. */
    km_status s = check_replaceable_dir(w->path, err);
    if (s != KM_OK) return s;
    size_t n = strlen(w->path) + 32;
    char *old = malloc(n);
    if (!old) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
    snprintf(old, n, "%s.old.%ld", w->path, (long)getpid());
    if (rename(w->path, old) != 0) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot move the existing directory aside: %s", w->path,
                   strerror(errno));
      free(old);
      return s;
    }
    if (rename(w->tmp_dir, w->path) != 0) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot rename %s into place: %s", w->path, w->tmp_dir,
                   strerror(errno));
      (void)rename(old, w->path);
      free(old);
      return s;
    }
    remove_frame_dir(old);
    free(old);
  }
  km__tmp_dir_unregister(w->tmp_dir_slot);
  free(w->tmp_dir);
  w->tmp_dir = NULL; /* published: discard must not remove it */
  return KM_OK;
}

/* Every pushed frame read back from the key temporary (a skin's keys are every frame), as
 * positions: *frames w->n_keys * #V*3, allocated (NULL on failure). */
static km_status read_frames(km_anim_writer *w, double **frames, km_error *err) {
  const size_t nv3 = w->n_vertices * 3, T = w->n_keys;
  double *F = km__malloc(T * nv3, sizeof *F);
  *frames = NULL;
  if (!F) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", w->path, T);
  if (fseek(w->keys, 0, SEEK_SET) != 0) {
    free(F);
    return km__fail(err, KM_ERR_IO, "%s: cannot rewind the frame temporary", w->path);
  }
  for (size_t t = 0; t < T; ++t) {
    if (fread(w->fbuf, sizeof *w->fbuf, nv3, w->keys) != nv3) {
      free(F);
      return km__fail(err, KM_ERR_IO, "%s: cannot read frame %zu back from its temporary", w->path,
                      t);
    }
    for (size_t i = 0; i < nv3; ++i)
      F[t * nv3 + i] = w->rest[i] + (double)w->fbuf[i];
  }
  *frames = F;
  return KM_OK;
}

/* Fits the rig over every frame (read back from the key temporary) and writes it. */
static km_status close_skin(km_anim_writer *w, km_anim_report *rep, km_error *err) {
  const size_t nv = w->n_vertices, T = w->n_keys;
  double *frames = NULL;
  km_status s = read_frames(w, &frames, err);
  if (s != KM_OK) return s;
  km_ssdr fit = {0};
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if (s == KM_OK) s = km_ssdr_fit(w->rest, nv, frames, T, &w->skin, &fit, err);
  clock_gettime(CLOCK_MONOTONIC, &t1);
  if (s != KM_OK) {
    free(frames);
    return km__wrap(err, s, "%s", w->path);
  }
  if (rep) {
    rep->bones = fit.n_bones;
    rep->rms_error = fit.rms_error;
    rep->max_error = fit.max_error;
    rep->fit_seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
  }
  s = km__glb_write_skin(w, &fit, frames, err);
  free(frames);
  if (rep && w->compress) {
    rep->rms_error = w->q_rms;
    rep->max_error = w->q_max;
  }
  km_ssdr_free(&fit);
  return s;
}

/* The given skeleton's skin: the pushed transforms are the bones' motion (no fit); the error
 * is that of skinning the rest by them against the pushed frames (0 up to rounding for frames
 * skinned by the same transforms and weights). */
static km_status close_skeleton(km_anim_writer *w, km_anim_report *rep, km_error *err) {
  const size_t nv = w->n_vertices, T = w->n_keys, B = w->n_bones;
  double *frames = NULL, *P = km__malloc(nv * 3, sizeof *P);
  km_status s =
      P ? read_frames(w, &frames, err) : km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
  double se = 0, emax = 0;
  for (size_t t = 0; s == KM_OK && t < T; ++t) {
    const double *V = frames + t * nv * 3;
    s = km_lbs(w->rest, nv, &w->bskin, w->bxf + t * 12 * B, B, P, err);
    for (size_t i = 0; s == KM_OK && i < nv; ++i) {
      double d2 = 0;
      for (int a = 0; a < 3; ++a)
        d2 += (P[3 * i + a] - V[3 * i + a]) * (P[3 * i + a] - V[3 * i + a]);
      se += d2;
      if (d2 > emax) emax = d2;
    }
  }
  free(P);
  km_ssdr fit = {nv, T, B, w->bskin, w->bxf, w->bcenter, 0, 0};
  fit.rms_error = T && nv ? sqrt(se / (double)(T * nv)) : 0;
  fit.max_error = sqrt(emax);
  if (rep) {
    rep->bones = B;
    rep->rms_error = fit.rms_error;
    rep->max_error = fit.max_error;
  }
  if (s == KM_OK) s = km__glb_write_skin(w, &fit, frames, err);
  free(frames);
  if (s == KM_OK && rep && w->compress) {
    rep->rms_error = w->q_rms;
    rep->max_error = w->q_max;
  }
  return s;
}

/* Compact morphs: PCA of the frame displacements D (T x 3#V) through the T x T Gram matrix
 * D D^T (LAPACK dsyev in linalg): the K leading eigenvectors u_k give orthonormal basis
 * targets b_k = D^T u_k / sqrt(l_k) and weights w_tk = sqrt(l_k) u_k[t], each target scaled
 * and offset so its weights stay in [0, 1] (the offset: one more target, weighted 1). The keys are
 * replaced by the targets, then the usual glb writer runs with the weights. */
static km_status close_pca(km_anim_writer *w, km_anim_report *rep, km_error *err) {
  const size_t nv3 = w->n_vertices * 3, T = w->n_keys;
  size_t K = w->pca_k < T ? w->pca_k : T;
  double *D = km__malloc(T * nv3, sizeof *D), *C = km__malloc(T * T, sizeof *C);
  double *ev = km__malloc(T, sizeof *ev), *B = NULL, *Wt = NULL;
  FILE *nk = NULL;
  km_status s = KM_OK;
  if (!D || !C || !ev) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", w->path, T);
    goto done;
  }
  if (fseek(w->keys, 0, SEEK_SET) != 0)
    s = km__fail(err, KM_ERR_IO, "%s: cannot rewind the frame temporary", w->path);
  for (size_t t = 0; s == KM_OK && t < T; ++t) {
    if (fread(w->fbuf, sizeof *w->fbuf, nv3, w->keys) != nv3) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot read frame %zu back", w->path, t);
      break;
    }
    for (size_t i = 0; i < nv3; ++i)
      D[t * nv3 + i] = w->fbuf[i];
  }
  if (s != KM_OK) goto done;
#pragma omp parallel for schedule(dynamic, 1)
  for (size_t a = 0; a < T; ++a)
    for (size_t b = a; b < T; ++b) {
      double d = 0;
      for (size_t i = 0; i < nv3; ++i)
        d += D[a * nv3 + i] * D[b * nv3 + i];
      C[a * T + b] = C[b * T + a] = d;
    }
  if (km__syev(T, C, ev) != 0) {
    s = km__fail(err, KM_ERR_NO_CONVERGENCE, "%s: PCA eigen-decomposition failed", w->path);
    goto done;
  }
  /* drop directions the frames do not span (a still animation has none) */
  double lmax = ev[T - 1] > 0 ? ev[T - 1] : 0;
  while (K > 1 && !(ev[T - K] > 1e-18 * lmax))
    --K;
  /* one more row and column for the offset target (below) */
  B = km__calloc((K + 1) * nv3, sizeof *B);
  Wt = km__calloc(T * (K + 1), sizeof *Wt);
  if (!B || !Wt) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
    goto done;
  }
  for (size_t k = 0; k < K; ++k) {
    size_t col = T - 1 - k;
    double l = ev[col] > 0 ? sqrt(ev[col]) : 0, m = 0;
    for (size_t t = 0; t < T; ++t) {
      Wt[t * K + k] = l * C[t * T + col];
      m = fmax(m, fabs(Wt[t * K + k]));
    }
    double inv = l > 0 ? 1 / l : 0;
    for (size_t t = 0; t < T; ++t) {
      double u = C[t * T + col] * inv * m;
      if (u == 0) continue;
      for (size_t i = 0; i < nv3; ++i)
        B[k * nv3 + i] += u * D[t * nv3 + i];
    }
    for (size_t t = 0; m > 0 && t < T; ++t)
      Wt[t * K + k] /= m;
  }
  /* Every weight in [0, 1]: w' = (w - lo) / (hi - lo) over the frames, the target times
   * (hi - lo), and sum_k lo_k b_k moved into one more target, the offset, weighted 1 at every
   * frame. Blender 3.4's importer clamps a shape key's weight to a slider range of [0, 1]
   * widened by the first frame's weight only (gltf2_blender_animation_weight.py), so weights
   * below 0 or above 1 later in the take would play wrong there. The offset is a target rather
   * than a shifted base mesh so that the base stays the rest mesh the file's readers (bake,
   * km_mesh_read) and viewers take as the rest pose. */
  bool offset = false;
  for (size_t k = 0; k < K; ++k) {
    double lo = INFINITY, hi = -INFINITY;
    for (size_t t = 0; t < T; ++t)
      lo = fmin(lo, Wt[t * K + k]), hi = fmax(hi, Wt[t * K + k]);
    double span = hi - lo, *b = B + k * nv3, *o = B + K * nv3;
    if (!(span > 0)) lo = hi, span = 1; /* a constant weight: all of it in the offset */
    if (lo != 0) offset = true;
    for (size_t i = 0; i < nv3; ++i)
      o[i] += lo * b[i], b[i] *= span;
    for (size_t t = 0; t < T; ++t)
      Wt[t * K + k] = (Wt[t * K + k] - lo) / span;
  }
  if (offset) { /* the weights' rows grow by the offset's 1 */
    for (size_t t = T; t-- > 0;) {
      Wt[t * (K + 1) + K] = 1;
      for (size_t k = K; k-- > 0;)
        Wt[t * (K + 1) + k] = Wt[t * K + k];
    }
    ++K;
  }
  /* Error as a viewer evaluates it: float32 targets and weights. */
  if (!(w->pca_weights = km__malloc(T * K, sizeof *w->pca_weights))) {
    s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
    goto done;
  }
  for (size_t i = 0; i < T * K; ++i)
    w->pca_weights[i] = (float)Wt[i];
  double sum = 0, mx = 0;
#pragma omp parallel for reduction(+ : sum) reduction(max : mx) schedule(static)
  for (size_t t = 0; t < T; ++t)
    for (size_t v = 0; v < nv3 / 3; ++v) {
      double e2 = 0;
      for (int c = 0; c < 3; ++c) {
        double r = 0;
        for (size_t k = 0; k < K; ++k)
          r += (double)w->pca_weights[t * K + k] * (double)(float)B[k * nv3 + 3 * v + c];
        double d = r - D[t * nv3 + 3 * v + c];
        e2 += d * d;
      }
      sum += e2;
      if (e2 > mx) mx = e2;
    }
  w->pca_rms = sqrt(sum / (double)(T * nv3 / 3));
  w->pca_max = sqrt(mx);
  if (rep) {
    rep->targets = K;
    rep->rms_error = w->pca_rms;
    rep->max_error = w->pca_max;
  }
  /* the targets replace the keys (the offset may make one more than the frames) */
  if (K > w->key_cap) {
    size_t *kf = realloc(w->key_frame, K * sizeof *kf);
    if (kf) w->key_frame = kf;
    float *km = kf ? realloc(w->key_minmax, K * 6 * sizeof *km) : NULL;
    if (km) w->key_minmax = km;
    if (!kf || !km) {
      s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", w->path);
      goto done;
    }
    w->key_cap = K;
  }
  if (!(nk = tmpfile())) {
    s = km__fail(err, KM_ERR_IO, "%s: cannot create a temporary file: %s", w->path,
                 strerror(errno));
    goto done;
  }
  for (size_t k = 0; k < K; ++k) {
    float *mm = w->key_minmax + 6 * k;
    minmax_init(mm);
    for (size_t i = 0; i < nv3; ++i) {
      float f = (float)B[k * nv3 + i];
      w->fbuf[i] = f;
      if (f < mm[i % 3]) mm[i % 3] = f;
      if (f > mm[3 + i % 3]) mm[3 + i % 3] = f;
    }
    w->key_frame[k] = k;
    if (fwrite(w->fbuf, sizeof *w->fbuf, nv3, nk) != nv3) {
      s = km__fail(err, KM_ERR_IO, "%s: cannot write a basis target: %s", w->path, strerror(errno));
      goto done;
    }
  }
  fclose(w->keys);
  w->keys = nk;
  nk = NULL;
  w->n_keys = K;
  w->pca_frames = T;
  w->pca_offset = offset;
  w->pca_D = D;
  s = km__glb_finish(w, err);
  w->pca_D = NULL;
  if (rep && w->compress) {
    rep->rms_error = w->q_rms;
    rep->max_error = w->q_max;
  }
done:
  if (nk) fclose(nk);
  free(D);
  free(C);
  free(ev);
  free(B);
  free(Wt);
  return s;
}

km_status km_anim_writer_close(km_anim_writer **wp, km_error *err) {
  return km_anim_writer_finish(wp, NULL, err);
}

km_status km_anim_writer_finish(km_anim_writer **wp, km_anim_report *rep, km_error *err) {
  if (rep) memset(rep, 0, sizeof *rep);
  if (!wp || !*wp) return km__fail(err, KM_ERR_INVALID, "km_anim_writer_close: writer is NULL");
  km_anim_writer *w = *wp;
  *wp = NULL;
  if (rep) {
    rep->export_kind = w->export_kind;
    rep->frames = w->frames;
  }
  km_status s = KM_OK;
  if (w->failed)
    s = km__fail(err, KM_ERR_IO, "%s: an earlier write failed; nothing written", w->path);
  else if (w->frames == 0)
    s = km__fail(err, KM_ERR_INVALID, "%s: no frames were pushed; nothing written", w->path);
  else if (w->format == KM_ANIM_PC2)
    s = close_pc2(w, err);
  else if (w->format == KM_ANIM_GLB && w->export_kind == KM_ANIM_EXPORT_SKIN)
    s = close_skin(w, rep, err);
  else if (w->format == KM_ANIM_GLB && w->export_kind == KM_ANIM_EXPORT_SKELETON)
    s = close_skeleton(w, rep, err);
  else if (w->format == KM_ANIM_GLB && w->export_kind == KM_ANIM_EXPORT_MORPHS_PCA)
    s = close_pca(w, rep, err);
  else if (w->format == KM_ANIM_GLB) {
    s = km__glb_finish(w, err);
    if (rep && w->compress) {
      rep->rms_error = w->q_rms;
      rep->max_error = w->q_max;
    }
  } else
    s = close_dir(w, err);
  writer_discard(w);
  return s;
}

/* ---------------------------------------------------------------- reading */

/* Parses the 32-byte PC2 header and checks it against the file size. */
static km_status pc2_header(FILE *f, const char *path, km_anim_info *info, km_error *err) {
  unsigned char h[PC2_HEADER];
  size_t got = fread(h, 1, sizeof h, f);
  if (got < sizeof h)
    return km__fail(err, KM_ERR_PARSE, "%s: byte %zu: truncated PC2 header (32 bytes expected)",
                    path, got);
  if (memcmp(h, "POINTCACHE2\0", 12) != 0)
    return km__fail(err, KM_ERR_PARSE, "%s: byte 0: not a PC2 file (no POINTCACHE2 signature)",
                    path);
  uint32_t version = km__get_u32le(h + 12);
  int32_t np = (int32_t)km__get_u32le(h + 16), ns = (int32_t)km__get_u32le(h + 28);
  if (version != 1)
    return km__fail(err, KM_ERR_UNSUPPORTED, "%s: byte 12: PC2 version %u, expected 1", path,
                    version);
  if (np < 0) return km__fail(err, KM_ERR_PARSE, "%s: byte 16: negative point count", path);
  if (ns < 0) return km__fail(err, KM_ERR_PARSE, "%s: byte 28: negative sample count", path);
  if (fseek(f, 0, SEEK_END) != 0)
    return km__fail(err, KM_ERR_IO, "%s: cannot seek: %s", path, strerror(errno));
  long size = ftell(f);
  uint64_t want = PC2_HEADER + (uint64_t)np * (uint64_t)ns * 12;
  if (size < 0 || (uint64_t)size != want)
    return km__fail(err, KM_ERR_PARSE,
                    "%s: file is %ld bytes, header (%d points x %d samples) needs %llu", path, size,
                    np, ns, (unsigned long long)want);
  if (fseek(f, PC2_HEADER, SEEK_SET) != 0)
    return km__fail(err, KM_ERR_IO, "%s: cannot seek: %s", path, strerror(errno));
  memset(info, 0, sizeof *info);
  info->format = KM_ANIM_PC2;
  info->frames = (size_t)ns;
  info->vertices = (size_t)np;
  /* PC2 carries a sample step, not a frame rate, so fps and duration are unknown (0). */
  return KM_OK;
}

km_status km_pc2_read(const char *path, double **frames, km_anim_info *info, km_error *err) {
  if (frames) *frames = NULL;
  if (!path || !frames) return km__fail(err, KM_ERR_INVALID, "km_pc2_read: NULL argument");
  FILE *f = fopen(path, "rb");
  if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  km_anim_info tmp;
  km_status s = pc2_header(f, path, &tmp, err);
  if (s != KM_OK) {
    fclose(f);
    return s;
  }
  size_t n = tmp.frames * tmp.vertices * 3;
  double *out = km__malloc(n, sizeof *out);
  /* The header was checked against the file size, which bounds vertices * frames; with no
   * frames it bounds nothing, so the frame buffer is only sized by a header that has frames. */
  unsigned char *buf = km__malloc(tmp.frames && tmp.vertices ? tmp.vertices : 1, 12);
  if (!out || !buf) {
    free(out);
    free(buf);
    fclose(f);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", path, tmp.frames);
  }
  for (size_t k = 0; k < tmp.frames; ++k) {
    if (fread(buf, 12, tmp.vertices, f) != tmp.vertices) {
      free(out);
      free(buf);
      fclose(f);
      return km__fail(err, KM_ERR_IO, "%s: read error in frame %zu", path, k);
    }
    double *o = out + k * tmp.vertices * 3;
    for (size_t i = 0; i < tmp.vertices * 3; ++i)
      o[i] = km__get_f32le(buf + 4 * i);
  }
  free(buf);
  fclose(f);
  *frames = out;
  if (info) *info = tmp;
  return KM_OK;
}

/* Vertex / face counts and fps of one frame file we wrote (or any OBJ / PLY with the usual
 * header); reads the PLY header only, the whole OBJ. */
static km_status frame_file_info(const char *fp, int kind, km_anim_info *info, km_error *err) {
  FILE *f = fopen(fp, "rb");
  if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", fp, strerror(errno));
  char line[512];
  size_t lineno = 0, nv = 0, nf = 0;
  double fps = 0;
  km_status s = KM_OK;
  while (fgets(line, sizeof line, f)) {
    ++lineno;
    size_t len = strlen(line);
    bool whole = len && line[len - 1] == '\n';
    const char *c = strstr(line, "kinemesh animation frame");
    if (c) {
      const char *q = strstr(c, "fps ");
      if (q) fps = strtod(q + 4, NULL);
    }
    if (kind == 2) {
      if (lineno == 1 && strncmp(line, "ply", 3) != 0) {
        s = km__fail(err, KM_ERR_PARSE, "%s:1: not a PLY file", fp);
        break;
      }
      unsigned long long n;
      if (sscanf(line, "element vertex %llu", &n) == 1) nv = (size_t)n;
      if (sscanf(line, "element face %llu", &n) == 1) nf = (size_t)n;
      if (strncmp(line, "end_header", 10) == 0) break;
    } else if (line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
      ++nv;
    } else if (line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
      size_t corners = 0;
      for (char *p = line + 1; *p;) {
        while (*p == ' ' || *p == '\t')
          ++p;
        if (!*p || *p == '\n' || *p == '\r') break;
        ++corners;
        while (*p && *p != ' ' && *p != '\t' && *p != '\n')
          ++p;
      }
      if (corners >= 3) nf += corners - 2; /* fan triangulation, as km_mesh_read does */
    }
    /* Skip the rest of an over-long line (only comments can be that long). */
    while (!whole) {
      if (!fgets(line, sizeof line, f)) break;
      len = strlen(line);
      whole = len && line[len - 1] == '\n';
    }
  }
  fclose(f);
  info->vertices = nv;
  info->faces = nf;
  info->fps = isfinite(fps) && fps > 0 ? fps : 0;
  return s;
}

static km_status dir_info(const char *path, km_anim_info *out, km_error *err) {
  DIR *d = opendir(path);
  if (!d) return km__fail(err, KM_ERR_IO, "%s: cannot open directory: %s", path, strerror(errno));
  size_t n_obj = 0, n_ply = 0;
  struct dirent *e;
  while ((e = readdir(d)) != NULL) {
    int k = frame_file_kind(e->d_name);
    n_obj += k == 1;
    n_ply += k == 2;
  }
  closedir(d);
  if (n_obj + n_ply == 0)
    return km__fail(err, KM_ERR_PARSE, "%s: no frame_NNNNNN.obj / .ply files in the directory",
                    path);
  memset(out, 0, sizeof *out);
  int kind = n_obj >= n_ply ? 1 : 2;
  out->format = kind == 1 ? KM_ANIM_OBJ_DIR : KM_ANIM_PLY_DIR;
  out->frames = kind == 1 ? n_obj : n_ply;
  size_t m = strlen(path) + 32;
  char *fp = malloc(m);
  if (!fp) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  snprintf(fp, m, "%s/frame_000000.%s", path, kind == 1 ? "obj" : "ply");
  km_status s = frame_file_info(fp, kind, out, err);
  free(fp);
  if (s == KM_OK && out->fps > 0) out->duration = (double)(out->frames - 1) / out->fps;
  return s;
}

static km_status anim_info_read(const char *path, km_anim_info *out, km_error *err);

/* Every format reports one timeline (issue 12): frames, fps and duration agree. */
km_status km_anim_info_read(const char *path, km_anim_info *out, km_error *err) {
  km_status s = anim_info_read(path, out, err);
  if (s == KM_OK && out->timeline_frames == 0) out->timeline_frames = out->frames;
  if (s == KM_OK && out->fps > 0 && out->timeline_frames > 0)
    out->duration = (double)(out->timeline_frames - 1) / out->fps;
  return s;
}

static km_status anim_info_read(const char *path, km_anim_info *out, km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "km_anim_info_read: NULL argument");
  memset(out, 0, sizeof *out);
  struct stat st;
  if (stat(path, &st) != 0) return km__fail(err, KM_ERR_IO, "%s: %s", path, strerror(errno));
  if (S_ISDIR(st.st_mode)) return dir_info(path, out, err);
  char ext[8];
  km__extension(path, ext, sizeof ext);
  if (strcmp(ext, "glb") == 0) return km__glb_info(path, out, err);
  if (strcmp(ext, "pc2") == 0) {
    FILE *f = fopen(path, "rb");
    if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    km_status s = pc2_header(f, path, out, err);
    fclose(f);
    return s;
  }
  return km__fail(err, KM_ERR_UNSUPPORTED,
                  "%s: unknown animation format (expected .glb, .pc2 or a frame directory)", path);
}

/* ---------------------------------------------------------------- whole animations (issue 16) */

km_status km_anim_read(const char *path, km_mesh *rest, double **frames, km_anim_info *info,
                       km_error *err) {
  if (!path || !rest || !frames || !info)
    return km__fail(err, KM_ERR_INVALID, "km_anim_read: NULL argument");
  memset(rest, 0, sizeof *rest);
  *frames = NULL;
  km_status s = km_anim_info_read(path, info, err);
  if (s != KM_OK) return s;
  if (info->format == KM_ANIM_PC2) {
    km_anim_info in2;
    if ((s = km_pc2_read(path, frames, &in2, err)) != KM_OK) return s;
    if (in2.frames == 0) {
      free(*frames);
      *frames = NULL;
      return km__fail(err, KM_ERR_PARSE, "%s: the point cache has no frames", path);
    }
    *info = in2;
    if (!(rest->V = km__malloc(in2.vertices * 3, sizeof *rest->V))) {
      free(*frames);
      *frames = NULL;
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    }
    memcpy(rest->V, *frames, in2.vertices * 3 * sizeof *rest->V);
    rest->n_vertices = in2.vertices;
    return KM_OK;
  }
  if (info->format == KM_ANIM_GLB) {
    if ((s = km_mesh_read(path, rest, err)) != KM_OK) return s;
    size_t n = 0;
    double fps = info->fps;
    s = km__glb_frames(path, rest->n_vertices, frames, &n, &fps, err);
    if (s != KM_OK) {
      km_mesh_free(rest);
      return s;
    }
    info->frames = info->timeline_frames = n;
    info->fps = fps;
    info->duration = fps > 0 && n > 0 ? (double)(n - 1) / fps : 0;
    return KM_OK;
  }
  /* a frame directory: frame_000000 .. in order, every one with the first's vertex count */
  const char *ext = info->format == KM_ANIM_PLY_DIR ? "ply" : "obj";
  size_t m = strlen(path) + 40, nv = 0;
  char *fp = malloc(m);
  if (!fp) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  for (size_t k = 0; s == KM_OK && k < info->frames; ++k) {
    snprintf(fp, m, "%s/frame_%06zu.%s", path, k, ext);
    km_mesh f = {0};
    if ((s = km_mesh_read(fp, k == 0 ? rest : &f, err)) != KM_OK) break;
    if (k == 0) {
      nv = rest->n_vertices;
      if (!(*frames = km__malloc(info->frames * nv * 3, sizeof **frames))) {
        s = km__fail(err, KM_ERR_NOMEM, "%s: out of memory for %zu frames", path, info->frames);
        break;
      }
      memcpy(*frames, rest->V, nv * 3 * sizeof **frames);
      continue;
    }
    if (f.n_vertices != nv)
      s = km__fail(err, KM_ERR_PARSE, "%s: %zu vertices, frame 0 has %zu", fp, f.n_vertices, nv);
    else
      memcpy(*frames + k * nv * 3, f.V, nv * 3 * sizeof **frames);
    km_mesh_free(&f);
  }
  free(fp);
  if (s != KM_OK) {
    free(*frames);
    *frames = NULL;
    km_mesh_free(rest);
    return s;
  }
  info->vertices = nv;
  return KM_OK;
}
