#include "core/core.h"

#include <ctype.h>
#include <dirent.h>
#include <glob.h>
#include <sys/stat.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

const char *km_version(void) { return "0.1.0"; }

const char *km_status_name(km_status s) {
  switch (s) {
  case KM_OK: return "KM_OK";
  case KM_ERR_IO: return "KM_ERR_IO";
  case KM_ERR_PARSE: return "KM_ERR_PARSE";
  case KM_ERR_INVALID: return "KM_ERR_INVALID";
  case KM_ERR_DEGENERATE_MESH: return "KM_ERR_DEGENERATE_MESH";
  case KM_ERR_NOT_POSDEF: return "KM_ERR_NOT_POSDEF";
  case KM_ERR_NO_CONVERGENCE: return "KM_ERR_NO_CONVERGENCE";
  case KM_ERR_NOMEM: return "KM_ERR_NOMEM";
  case KM_ERR_CANCELLED: return "KM_ERR_CANCELLED";
  case KM_ERR_UNSUPPORTED: return "KM_ERR_UNSUPPORTED";
  case KM_ERR_STALE: return "KM_ERR_STALE";
  }
  return "KM_ERR_UNKNOWN";
}

km_status km_error_set(km_error *err, km_status status, const char *fmt, ...) {
  if (err) {
    err->status = status;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->message, sizeof err->message, fmt, ap);
    va_end(ap);
  }
  return status;
}

km_status km__wrap(km_error *err, km_status s, const char *fmt, ...) {
  if (!err) return s;
  char prefix[512];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(prefix, sizeof prefix, fmt, ap);
  va_end(ap);
  /* Built in a larger buffer, then cut to fit: the end of a long message is what gets lost. */
  char joined[sizeof prefix + sizeof err->message + 2];
  snprintf(joined, sizeof joined, "%s: %.*s", prefix, (int)sizeof err->message - 1, err->message);
  memcpy(err->message, joined, sizeof err->message - 1);
  err->message[sizeof err->message - 1] = '\0';
  err->status = s;
  return s;
}

static km_log_fn g_log_fn;
static void *g_log_user;

void km_set_logger(km_log_fn fn, void *user) {
  g_log_fn = fn;
  g_log_user = user;
}

void km__log(km_log_level level, const char *fmt, ...) {
  if (!g_log_fn) return;
  char buf[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  g_log_fn(level, buf, g_log_user);
}

bool km__progress(const km_progress *p, double fraction, const char *stage) {
  if (!p || !p->fn) return true;
  return p->fn(fraction < 0 ? 0 : fraction > 1 ? 1 : fraction, stage, p->user);
}

void *km__malloc(size_t count, size_t size) {
  if (size && count > SIZE_MAX / size) return NULL;
  size_t n = count * size;
  return malloc(n ? n : 1);
}

void *km__calloc(size_t count, size_t size) {
  if (size && count > SIZE_MAX / size) return NULL;
  return calloc(count ? count : 1, size ? size : 1);
}

bool km__whole_number(double v, double lo, double hi, int64_t *out) {
  if (!(v >= lo && v <= hi) || v != floor(v)) return false;
  *out = (int64_t)v;
  return true;
}

char *km__path_beside(const char *path, const char *name) {
  const char *slash = strrchr(path, '/');
  size_t dir = name[0] == '/' || !slash ? 0 : (size_t)(slash - path) + 1;
  char *p = malloc(dir + strlen(name) + 1);
  if (!p) return NULL;
  memcpy(p, path, dir);
  strcpy(p + dir, name);
  for (char *c = p + dir; *c; ++c)
    if (*c == '\\') *c = '/';
  return p;
}

km_status km__make_parents(const char *path, km_error *err) {
  size_t n = path ? strlen(path) : 0;
  char *d = malloc(n + 1);
  if (!d) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path ? path : "");
  memcpy(d, path ? path : "", n + 1);
  km_status s = KM_OK;
  /* Each prefix ending before a '/' (past the first character: "/abs" needs no "/"). */
  for (size_t i = 1; i < n && !s; ++i) {
    if (d[i] != '/' || d[i - 1] == '/') continue;
    d[i] = '\0';
    struct stat st;
    if (stat(d, &st) != 0) {
      if (mkdir(d, 0777) != 0 && errno != EEXIST)
        s = km__fail(err, KM_ERR_IO, "%s: cannot create folder %s: %s", path, d, strerror(errno));
    } else if (!S_ISDIR(st.st_mode)) {
      s = km__fail(err, KM_ERR_IO, "%s: %s exists and is not a folder", path, d);
    }
    d[i] = '/';
  }
  free(d);
  return s;
}

/* Temporaries being written, for km_remove_temporaries (a signal handler): fixed slots, no
 * allocation, so the handler only reads them and calls unlink. */
#define KM__TMP_SLOTS 32
#define KM__TMP_MAX 4096
static char g_tmp_paths[KM__TMP_SLOTS][KM__TMP_MAX];
static sig_atomic_t g_tmp_used[KM__TMP_SLOTS];

static int tmp_register(const char *path) {
  if (strlen(path) >= KM__TMP_MAX) return -1;
  for (int i = 0; i < KM__TMP_SLOTS; ++i) {
    sig_atomic_t free_slot = 0;
    if (__atomic_compare_exchange_n(&g_tmp_used[i], &free_slot, 2, false, __ATOMIC_ACQ_REL,
                                    __ATOMIC_RELAXED)) {
      strcpy(g_tmp_paths[i], path);
      __atomic_store_n(&g_tmp_used[i], 1, __ATOMIC_RELEASE);
      return i;
    }
  }
  return -1;
}

static void tmp_unregister(const char *path) {
  for (int i = 0; i < KM__TMP_SLOTS; ++i)
    if (__atomic_load_n(&g_tmp_used[i], __ATOMIC_ACQUIRE) == 1 && !strcmp(g_tmp_paths[i], path)) {
      __atomic_store_n(&g_tmp_used[i], 0, __ATOMIC_RELEASE);
      return;
    }
}

#define KM__DIR_SLOTS 8
static char g_dir_paths[KM__DIR_SLOTS][KM__TMP_MAX];
static char g_dir_ext[KM__DIR_SLOTS][8];
static size_t g_dir_frames[KM__DIR_SLOTS];
static size_t g_dir_materials[KM__DIR_SLOTS];
static sig_atomic_t g_dir_used[KM__DIR_SLOTS];

int km__tmp_dir_register(const char *dir, const char *ext) {
  if (strlen(dir) + 32 >= KM__TMP_MAX || strlen(ext) >= sizeof g_dir_ext[0]) return -1;
  for (int i = 0; i < KM__DIR_SLOTS; ++i) {
    sig_atomic_t free_slot = 0;
    if (__atomic_compare_exchange_n(&g_dir_used[i], &free_slot, 2, false, __ATOMIC_ACQ_REL,
                                    __ATOMIC_RELAXED)) {
      strcpy(g_dir_paths[i], dir);
      strcpy(g_dir_ext[i], ext);
      __atomic_store_n(&g_dir_frames[i], 0, __ATOMIC_RELAXED);
      __atomic_store_n(&g_dir_materials[i], 0, __ATOMIC_RELAXED);
      __atomic_store_n(&g_dir_used[i], 1, __ATOMIC_RELEASE);
      return i;
    }
  }
  return -1;
}

void km__tmp_dir_frames(int slot, size_t frames) {
  if (slot >= 0 && slot < KM__DIR_SLOTS)
    __atomic_store_n(&g_dir_frames[slot], frames, __ATOMIC_RELEASE);
}

void km__tmp_dir_materials(int slot, size_t n) {
  if (slot >= 0 && slot < KM__DIR_SLOTS)
    __atomic_store_n(&g_dir_materials[slot], n, __ATOMIC_RELEASE);
}

void km__tmp_dir_unregister(int slot) {
  if (slot >= 0 && slot < KM__DIR_SLOTS) __atomic_store_n(&g_dir_used[slot], 0, __ATOMIC_RELEASE);
}

/* "<dir>/<prefix><k, at least `width` digits>.<ext>" without stdio (async-signal-safe);
 * width < 0: no number. */
static void numbered_name(char *out, const char *dir, const char *prefix, size_t k, int width,
                          const char *ext) {
  size_t n = strlen(dir), p = strlen(prefix);
  memcpy(out, dir, n);
  out[n++] = '/';
  memcpy(out + n, prefix, p);
  n += p;
  char d[24];
  int nd = 0;
  while (width >= 0 && (nd == 0 || k)) { /* at least one digit when numbered */
    d[nd++] = (char)('0' + k % 10);
    k /= 10;
  }
  while (nd < width)
    d[nd++] = '0';
  while (nd)
    out[n++] = d[--nd];
  out[n++] = '.';
  size_t e = strlen(ext);
  memcpy(out + n, ext, e + 1);
}

void km_remove_temporaries(void) {
  for (int i = 0; i < KM__TMP_SLOTS; ++i)
    if (__atomic_load_n(&g_tmp_used[i], __ATOMIC_ACQUIRE) == 1) unlink(g_tmp_paths[i]);
  char p[KM__TMP_MAX + 40];
  for (int i = 0; i < KM__DIR_SLOTS; ++i) {
    if (__atomic_load_n(&g_dir_used[i], __ATOMIC_ACQUIRE) != 1) continue;
    size_t nf = __atomic_load_n(&g_dir_frames[i], __ATOMIC_ACQUIRE);
    for (size_t k = 0; k <= nf; ++k) {
      numbered_name(p, g_dir_paths[i], "frame_", k, 6, g_dir_ext[i]);
      unlink(p);
    }
    /* an OBJ folder's material library and images (km__obj_write_materials' names) */
    size_t nm = __atomic_load_n(&g_dir_materials[i], __ATOMIC_ACQUIRE);
    for (size_t k = 0; k < nm; ++k) {
      numbered_name(p, g_dir_paths[i], "texture_", k, 1, "png");
      unlink(p);
      numbered_name(p, g_dir_paths[i], "texture_", k, 1, "jpg");
      unlink(p);
    }
    if (nm) {
      numbered_name(p, g_dir_paths[i], "materials", 0, -1, "mtl");
      unlink(p);
    }
    rmdir(g_dir_paths[i]);
  }
}

km_status km__atomic_open(km__atomic_file *af, const char *path, km_error *err) {
  memset(af, 0, sizeof *af);
  km_status ps = km__make_parents(path, err);
  if (ps) return ps;
  size_t n = strlen(path);
  af->path = malloc(n + 1);
  af->tmp_path = malloc(n + 48);
  if (!af->path || !af->tmp_path) {
    km__atomic_abort(af);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  memcpy(af->path, path, n + 1);
  /* Exclusive creation beside the target (O_EXCL | O_NOFOLLOW): a file or symlink planted
   * under the temporary's name is never opened, the name is retried instead. */
  static _Atomic unsigned long counter;
  unsigned long seed = (unsigned long)getpid() * 2654435761ul ^ (unsigned long)time(NULL);
  int fd = -1, e = 0;
  for (int tries = 0; tries < 64 && fd < 0; ++tries) {
    unsigned long r = seed ^ (++counter * 0x9e3779b97f4a7c15ul);
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    r ^= (unsigned long)ts.tv_nsec * 0xbf58476d1ce4e5b9ul;
    snprintf(af->tmp_path, n + 48, "%s.tmp.%ld.%08lx", path, (long)getpid(), r & 0xfffffffful);
    fd = open(af->tmp_path, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    e = errno;
    if (fd < 0 && e != EEXIST) break;
  }
  if (fd >= 0) {
    /* Replacing a file keeps its permissions (a 0600 sidecar stays 0600). */
    struct stat st;
    if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) (void)fchmod(fd, st.st_mode & 07777);
    tmp_register(af->tmp_path);
    if (!(af->f = fdopen(fd, "wb"))) {
      e = errno;
      close(fd);
      unlink(af->tmp_path);
      tmp_unregister(af->tmp_path);
    }
  }
  if (!af->f) {
    km_status s = km__fail(err, KM_ERR_IO, "%s: cannot open for writing: %s", path, strerror(e));
    free(af->path);
    free(af->tmp_path);
    memset(af, 0, sizeof *af);
    return s;
  }
  return KM_OK;
}

km_status km__atomic_commit(km__atomic_file *af, km_error *err) {
  if (!af->f) return km__fail(err, KM_ERR_INVALID, "atomic file already closed");
  int bad = ferror(af->f) || fflush(af->f) != 0;
  if (!bad) (void)fsync(fileno(af->f));
  bad |= fclose(af->f) != 0;
  af->f = NULL;
  km_status s = KM_OK;
  if (bad) {
    s = km__fail(err, KM_ERR_IO, "%s: write failed: %s", af->path, strerror(errno));
    remove(af->tmp_path);
  } else if (rename(af->tmp_path, af->path) != 0) {
    s = km__fail(err, KM_ERR_IO, "%s: cannot rename temporary into place: %s", af->path,
                 strerror(errno));
    remove(af->tmp_path);
  }
  tmp_unregister(af->tmp_path);
  free(af->path);
  free(af->tmp_path);
  af->path = af->tmp_path = NULL;
  return s;
}

void km__atomic_abort(km__atomic_file *af) {
  if (af->f) {
    fclose(af->f);
    af->f = NULL;
    if (af->tmp_path) remove(af->tmp_path);
  }
  if (af->tmp_path) tmp_unregister(af->tmp_path);
  free(af->path);
  free(af->tmp_path);
  af->path = af->tmp_path = NULL;
}

km_status km__read_file(const char *path, char **data, size_t *size, km_error *err) {
  *data = NULL;
  *size = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return km__fail(err, KM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  size_t cap = 1 << 16, n = 0;
  char *buf = malloc(cap + 1);
  if (!buf) {
    fclose(f);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  for (;;) {
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (n < cap) break;
    char *nb = realloc(buf, cap * 2 + 1);
    if (!nb) {
      free(buf);
      fclose(f);
      return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    }
    buf = nb;
    cap *= 2;
  }
  int rerr = ferror(f);
  fclose(f);
  if (rerr) {
    free(buf);
    return km__fail(err, KM_ERR_IO, "%s: read error", path);
  }
  buf[n] = '\0';
  *data = buf;
  *size = n;
  return KM_OK;
}

void km__extension(const char *path, char *out, size_t out_size) {
  if (!out_size) return;
  out[0] = '\0';
  const char *slash = strrchr(path, '/');
  const char *base = slash ? slash + 1 : path;
  const char *dot = strrchr(base, '.');
  if (!dot || dot == base) return;
  size_t i = 0;
  for (const char *p = dot + 1; *p && i + 1 < out_size; ++p)
    out[i++] = (char)tolower((unsigned char)*p);
  out[i] = '\0';
}

double km_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint64_t km__fnv1a(uint64_t h, const void *data, size_t size) {
  const unsigned char *p = data;
  for (size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

km_status km_write_file_atomic(const char *path, const void *data, size_t size, km_error *err) {
  if (!path || (!data && size))
    return km__fail(err, KM_ERR_INVALID, "km_write_file_atomic: NULL argument");
  km__atomic_file af = {0};
  km_status s = km__atomic_open(&af, path, err);
  if (s != KM_OK) return s;
  if (size && fwrite(data, 1, size, af.f) != size) {
    km__atomic_abort(&af);
    return km__fail(err, KM_ERR_IO, "%s: write failed", path);
  }
  return km__atomic_commit(&af, err);
}

void km_paths_free(char ***paths, size_t n) {
  if (!paths || !*paths) return;
  for (size_t i = 0; i < n; ++i)
    free((*paths)[i]);
  free(*paths);
  *paths = NULL;
}

static bool has_ext(const char *name, const char *const *exts) {
  if (!exts) return true;
  char ext[16];
  km__extension(name, ext, sizeof ext);
  for (; *exts; ++exts)
    if (!strcmp(ext, *exts)) return true;
  return false;
}

static int cmp_path(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

km_status km__list_files(const char *pattern, const char *const *exts, bool filter_glob,
                         char ***paths, size_t *n, km_error *err) {
  *paths = NULL;
  *n = 0;
  struct stat st;
  char **list = NULL;
  size_t count = 0, cap = 0;
  bool oom = false;
  if (stat(pattern, &st) == 0 && S_ISDIR(st.st_mode)) {
    DIR *d = opendir(pattern);
    if (!d)
      return km__fail(err, KM_ERR_IO, "%s: cannot open directory: %s", pattern, strerror(errno));
    struct dirent *e;
    while (!oom && (e = readdir(d))) {
      if (e->d_name[0] == '.' || !has_ext(e->d_name, exts)) continue;
      size_t len = strlen(pattern) + strlen(e->d_name) + 2;
      char *path = malloc(len);
      if (!path) break;
      snprintf(path, len, "%s/%s", pattern, e->d_name);
      if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        free(path);
        continue;
      }
      if (count == cap) {
        cap = cap ? 2 * cap : 64;
        char **nl = realloc(list, cap * sizeof *nl);
        if (!nl) {
          free(path);
          oom = true;
          break;
        }
        list = nl;
      }
      list[count++] = path;
    }
    closedir(d);
  } else {
    glob_t g;
    int r = glob(pattern, 0, NULL, &g);
    if (r != 0 && r != GLOB_NOMATCH) {
      if (r != GLOB_NOMATCH) globfree(&g);
      return km__fail(err, KM_ERR_IO, "%s: cannot list the files", pattern);
    }
    if (r == 0) {
      list = calloc(g.gl_pathc ? g.gl_pathc : 1, sizeof *list);
      oom = !list;
      for (size_t i = 0; list && i < g.gl_pathc; ++i) {
        if (stat(g.gl_pathv[i], &st) == 0 && S_ISDIR(st.st_mode)) continue;
        if (filter_glob && !has_ext(g.gl_pathv[i], exts)) continue;
        if (!(list[count] = strdup(g.gl_pathv[i]))) {
          oom = true;
          break;
        }
        ++count;
      }
    }
    globfree(&g);
  }
  if (oom) {
    km_paths_free(&list, count);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory listing the files", pattern);
  }
  if (count) qsort(list, count, sizeof *list, cmp_path);
  *paths = list;
  *n = count;
  return KM_OK;
}
