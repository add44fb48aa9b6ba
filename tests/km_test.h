/* Minimal test harness: CHECK records a failure and continues; the test's main returns
 * km_test_finish(), which prints "N passed, M failed" and is non-zero on any failure. */
#ifndef KM_TEST_H
#define KM_TEST_H

#include "kinemesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static int km_test_passed, km_test_failed;

#define CHECK(cond)                                                                                \
  do {                                                                                             \
    if (cond) {                                                                                    \
      ++km_test_passed;                                                                            \
    } else {                                                                                       \
      ++km_test_failed;                                                                            \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);                     \
    }                                                                                              \
  } while (0)

#define CHECK_MSG(cond, ...)                                                                       \
  do {                                                                                             \
    if (cond) {                                                                                    \
      ++km_test_passed;                                                                            \
    } else {                                                                                       \
      ++km_test_failed;                                                                            \
      fprintf(stderr, "%s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond);                     \
      fprintf(stderr, __VA_ARGS__);                                                                \
      fputc('\n', stderr);                                                                         \
    }                                                                                              \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                                                      \
  CHECK_MSG(fabs((double)(a) - (double)(b)) <= (tol), "%.17g vs %.17g (tol %g)", (double)(a),      \
            (double)(b), (double)(tol))

/* Tests pass KM_E as the error argument; CHECK_OK prints its message on failure. */
static km_error km_test_err;
#define KM_E (&km_test_err)
#define CHECK_OK(expr)                                                                             \
  do {                                                                                             \
    km_test_err.message[0] = '\0';                                                                 \
    km_status s_ = (expr);                                                                         \
    CHECK_MSG(s_ == KM_OK, "%s -> %s: %s", #expr, km_status_name(s_), km_test_err.message);        \
  } while (0)
/* Status must be exactly `st`. */
#define CHECK_STATUS(expr, st)                                                                     \
  do {                                                                                             \
    km_test_err.message[0] = '\0';                                                                 \
    km_status s_ = (expr);                                                                         \
    CHECK_MSG(s_ == (st), "%s -> %s (wanted %s): %s", #expr, km_status_name(s_),                   \
              km_status_name(st), km_test_err.message);                                            \
  } while (0)

static inline int km_test_finish(const char *name) {
  printf("%s: %d passed, %d failed\n", name, km_test_passed, km_test_failed);
  return km_test_failed ? 1 : 0;
}

/* Path of a file in ../shared/data, or NULL (with a SKIP line) when it is absent. */
/* n points brought from kinemesh's frame into frame f, the inverse of km_frame_apply:
 * out = R^T p / scale (R: km_frame_rotation(f)); out may alias in. */
static inline void km_test_to_frame(const km_frame *f, const double *in, double *out, size_t n) {
  double R[9];
  CHECK_OK(km_frame_rotation(f, R, KM_E));
  double s = f->scale ? f->scale : 1;
  for (size_t i = 0; i < n; ++i) {
    double q[3];
    for (int a = 0; a < 3; ++a)
      q[a] = (R[a] * in[3 * i] + R[3 + a] * in[3 * i + 1] + R[6 + a] * in[3 * i + 2]) / s;
    memcpy(out + 3 * i, q, sizeof q);
  }
}

static inline const char *km_test_shared(const char *rel, char *buf, size_t n) {
  snprintf(buf, n, "%s/%s", KM_SHARED_DATA, rel);
  struct stat st;
  if (stat(buf, &st) != 0) {
    printf("SKIP: %s not found (../shared/data is absent in this checkout)\n", buf);
    return NULL;
  }
  return buf;
}

/* max over the edges of the faces in face_mask (#F; NULL: every face) of |l / l0 - 1|, V: the
 * deformed positions of m (#V*3). */
static inline double km_test_edge_stretch_in(const km_mesh *m, const double *V,
                                             const unsigned char *face_mask) {
  double worst = 0;
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int e = 0; e < 3 && (!face_mask || face_mask[f]); ++e) {
      int32_t a = m->F[3 * f + e], b = m->F[3 * f + (e + 1) % 3];
      double l = 0, l0 = 0;
      for (int c = 0; c < 3; ++c) {
        l += (V[3 * a + c] - V[3 * b + c]) * (V[3 * a + c] - V[3 * b + c]);
        l0 += (m->V[3 * a + c] - m->V[3 * b + c]) * (m->V[3 * a + c] - m->V[3 * b + c]);
      }
      worst = fmax(worst, fabs(sqrt(l / l0) - 1));
    }
  return worst;
}
/* max over every edge of m of |l / l0 - 1| (km_test_edge_stretch_in). */
static inline double km_test_edge_stretch(const km_mesh *m, const double *V) {
  return km_test_edge_stretch_in(m, V, NULL);
}

#define KM_TEST_SKIP 77

/* The whole file, NUL-terminated (the caller frees); *n its size. NULL when it cannot be read. */
static inline char *km_test_read_file(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long sz = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *b = sz >= 0 ? malloc((size_t)sz + 1) : NULL;
  if (b && fread(b, 1, (size_t)sz, f) != (size_t)sz) {
    free(b);
    b = NULL;
  }
  fclose(f);
  if (b) b[sz] = 0, *n = (size_t)sz;
  return b;
}

#include <sys/wait.h>

/* Runs a shell command with stderr folded into stdout; *out (if given) receives the output
 * (caller frees). Returns the exit status, -1 when the command could not run. */
static inline int km_test_run(const char *cmd, char **out) {
  char full[8192];
  snprintf(full, sizeof full, "%s 2>&1", cmd);
  FILE *p = popen(full, "r");
  if (!p) return -1;
  size_t cap = 1 << 16, n = 0, got;
  char *buf = malloc(cap);
  while (buf && (got = fread(buf + n, 1, cap - n - 1, p)) > 0) {
    n += got;
    if (cap - n < 2) {
      char *nb = realloc(buf, cap *= 2);
      if (!nb) free(buf);
      buf = nb;
    }
  }
  if (buf) buf[n] = '\0';
  int st = pclose(p);
  if (out)
    *out = buf;
  else
    free(buf);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Writes a .glb of json (the JSON chunk, padded with spaces) and bin[0 .. bin_len) (the BIN
 * chunk, padded with zeros), for tests that make or edit glTF files. false when it cannot. */
static inline bool km_test_write_glb(const char *path, const char *json, const void *bin,
                                     size_t bin_len) {
  size_t jn = strlen(json), jp = (jn + 3) & ~(size_t)3, bp = (bin_len + 3) & ~(size_t)3;
  FILE *f = fopen(path, "wb");
  if (!f) return false;
  uint32_t h[5] = {0x46546C67u, 2, (uint32_t)(12 + 8 + jp + 8 + bp), (uint32_t)jp, 0x4E4F534Au};
  uint32_t c[2] = {(uint32_t)bp, 0x004E4942u};
  bool ok = fwrite(h, 4, 5, f) == 5 && fwrite(json, 1, jn, f) == jn;
  for (size_t i = jn; i < jp; ++i)
    ok &= fputc(' ', f) != EOF;
  ok &= fwrite(c, 4, 2, f) == 2 && fwrite(bin, 1, bin_len, f) == bin_len;
  for (size_t i = bin_len; i < bp; ++i)
    ok &= fputc(0, f) != EOF;
  return fclose(f) == 0 && ok;
}

#endif
