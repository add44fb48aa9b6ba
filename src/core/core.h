/* Requires: nothing (libc). */
/* Private helpers shared across kinemesh modules (prefix km__). Not installed. */
#ifndef KM_INTERNAL_H
#define KM_INTERNAL_H

#include "kinemesh.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#if defined(__GNUC__)
#define KM__PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define KM__PRINTF(a, b)
#endif

/* Fills err (if any) and returns status, so call sites read `return km__fail(err, ...)`. */
#define km__fail km_error_set
/* Prefixes an existing message: "context: previous message". Returns err->status or s. */
km_status km__wrap(km_error *err, km_status s, const char *fmt, ...) KM__PRINTF(3, 4);

void km__log(km_log_level level, const char *fmt, ...) KM__PRINTF(2, 3);

/* Progress report; returns false when the caller asked to cancel. */
bool km__progress(const km_progress *p, double fraction, const char *stage);

/* Overflow-checked allocations: NULL on overflow or failure. */
void *km__malloc(size_t count, size_t size);
void *km__calloc(size_t count, size_t size);

/* Atomic output files: write to "<path>.tmp.<pid>.<random>" (created exclusively, never
 * through a symlink, with the replaced file's permissions) then rename on commit. Open
 * temporaries are listed for km_remove_temporaries. */
typedef struct km__atomic_file {
  FILE *f;
  char *path;
  char *tmp_path;
} km__atomic_file;
/* Creates path's missing parent folders first (km__make_parents): every `-o out/x.obj` works
 * without a prior mkdir. */
km_status km__atomic_open(km__atomic_file *af, const char *path, km_error *err);
/* Frame directories being filled (anim's "<dir>.tmp.<pid>"): km_remove_temporaries removes
 * their frame files frame_NNNNNN.<ext> (the first `frames` + 1 of them), the material files of
 * an OBJ folder with materials (materials.mtl, texture_<k>.png|.jpg for k < materials) and the
 * directory. register returns a slot (-1 when full: no cleanup, no error); frames and
 * materials update the counts; unregister forgets it (published or removed). */
int km__tmp_dir_register(const char *dir, const char *ext);
void km__tmp_dir_frames(int slot, size_t frames);
void km__tmp_dir_materials(int slot, size_t n);
void km__tmp_dir_unregister(int slot);
/* Creates the missing folders above path ("a/b/c.obj": a and a/b), like mkdir -p of its
 * dirname. The one place outputs get their folders: km__atomic_open and the frame-directory
 * writer call it. KM_ERR_IO naming the folder that could not be made. */
km_status km__make_parents(const char *path, km_error *err);
/* The path of `name` in the folder of the file `path` ("a/b.gltf", "t.png": "a/t.png"; no
 * folder: name itself; an absolute name as it is), '\\' in name read as '/' (Windows-made
 * OBJ libraries). The one path join of the readers that follow a file to its neighbours (an
 * OBJ's mtllib and map_Kd, a .gltf's buffers and images). NULL when out of memory; free(). */
char *km__path_beside(const char *path, const char *name);
/* Flushes, checks for write errors, fsyncs and renames. Closes in every case. */
km_status km__atomic_commit(km__atomic_file *af, km_error *err);
/* Closes and removes the temporary. Safe on a zeroed or already closed handle. */
void km__atomic_abort(km__atomic_file *af);

/* Reads a whole file into memory (NUL-terminated for convenience, size excludes it). */
km_status km__read_file(const char *path, char **data, size_t *size, km_error *err);

/* Files of a directory (entries whose extension is one of exts, dot-files and folders skipped)
 * or of a glob(3) pattern (folders skipped; filtered by exts too when filter_glob), sorted by
 * name. exts: lowercase extensions without the dot, NULL-terminated; NULL takes every file.
 * *paths: allocated, *n entries (may be 0), free with km_paths_free. KM_ERR_IO naming the
 * pattern when the directory cannot be read or the glob fails. */
km_status km__list_files(const char *pattern, const char *const *exts, bool filter_glob,
                         char ***paths, size_t *n, km_error *err);

/* A number read from a file as an integer: true and *out = v when v is a whole number in
 * lo .. hi, else false with *out untouched (NaN, infinities and fractions too). The one door from a
 * file's double to an integer type: casting a value outside the type's range is undefined behaviour
 * (a glTF scene root of 8.9e83 found by fuzz_gltf). lo and hi must lie within int64's range. */
bool km__whole_number(double v, double lo, double hi, int64_t *out);

/* File extension (lowercase, without the dot) into out; "" when none. */
void km__extension(const char *path, char *out, size_t out_size);

/* Union-find over int32 ids (parent[x] == x: a root), with path halving; union keeps the
 * smaller id as the root, so a set's root is its smallest member. The one union-find of the
 * library (topology's components, pieces and boundary loops, ARAP's anchored check, the
 * polygoniser's largest part, the sidecar's bands, the autorig's slices and skin patches). */
static inline void km__uf_init(int32_t *parent, size_t n) {
  for (size_t i = 0; i < n; ++i)
    parent[i] = (int32_t)i;
}
static inline int32_t km__uf_find(int32_t *parent, int32_t x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]];
    x = parent[x];
  }
  return x;
}
static inline void km__uf_union(int32_t *parent, int32_t a, int32_t b) {
  a = km__uf_find(parent, a);
  b = km__uf_find(parent, b);
  if (a != b) parent[a < b ? b : a] = a < b ? a : b;
}

/* Little-endian encoding independent of the host byte order: the binary formats' fields
 * (PLY aside, which has its own for both orders), read and written: STL, glTF, .pc2. */
static inline void km__put_u32le(unsigned char *p, uint32_t v) {
  p[0] = (unsigned char)v;
  p[1] = (unsigned char)(v >> 8);
  p[2] = (unsigned char)(v >> 16);
  p[3] = (unsigned char)(v >> 24);
}
static inline uint32_t km__get_u32le(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline void km__put_f32le(unsigned char *p, float f) {
  uint32_t u;
  memcpy(&u, &f, 4);
  km__put_u32le(p, u);
}
static inline float km__get_f32le(const unsigned char *p) {
  uint32_t u = km__get_u32le(p);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

/* FNV-1a 64-bit over bytes, chained from `h` (start with KM__FNV_SEED). */
#define KM__FNV_SEED 0xcbf29ce484222325ULL
uint64_t km__fnv1a(uint64_t h, const void *data, size_t size);

#endif
