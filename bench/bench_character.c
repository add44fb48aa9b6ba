/* Times km_character_generate and reports triangle quality:
 *   bench_character [target ...]   (default 2000 20000 100000 1000000) */
#include "kinemesh.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double g_max_angle, g_frac120;
static void quality(const km_mesh *m, double *min_angle, double *frac5, double *min_area) {
  double mn = 180, amin = 1e300, mx = 0;
  size_t small = 0, big = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const double *p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = m->V + 3 * (size_t)m->F[3 * f + k];
    double fmin = 180, fmax = 0;
    for (int k = 0; k < 3; ++k) {
      const double *a = p[k], *b = p[(k + 1) % 3], *c = p[(k + 2) % 3];
      double u[3], v[3];
      for (int i = 0; i < 3; ++i) {
        u[i] = b[i] - a[i];
        v[i] = c[i] - a[i];
      }
      double cr[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                      u[0] * v[1] - u[1] * v[0]};
      double s = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
      double d = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
      double ang = atan2(s, d) * 180 / M_PI;
      if (ang < fmin) fmin = ang;
      if (ang > fmax) fmax = ang;
      if (k == 0 && 0.5 * s < amin) amin = 0.5 * s;
    }
    if (fmin < mn) mn = fmin;
    if (fmin < 5) ++small;
    if (fmax > 120) ++big;
    if (fmax > mx) mx = fmax;
  }
  *min_angle = mn;
  g_max_angle = mx;
  g_frac120 = (double)big / (double)m->n_faces;
  *frac5 = (double)small / (double)m->n_faces;
  *min_area = amin;
}

static double t_stage;
static bool on_progress(double fraction, const char *stage, void *user) {
  double t = now();
  if (user) fprintf(stderr, "  %5.2f s  %.2f %s\n", t - t_stage, fraction, stage);
  t_stage = t;
  return true;
}

static void on_log(km_log_level level, const char *message, void *user) {
  fprintf(stderr, "  log: %s\n", message);
}

int main(int argc, char **argv) {
  if (getenv("BENCH_VERBOSE")) km_set_logger(on_log, NULL);
  size_t targets[16] = {2000, 20000, 100000, 1000000};
  int nt = 4;
  if (argc > 1) {
    nt = 0;
    for (int i = 1; i < argc && nt < 16; ++i)
      targets[nt++] = (size_t)atol(argv[i]);
  }
  for (int i = 0; i < nt; ++i) {
    km_character_options o = {0};
    o.target_vertices = targets[i];
    o.progress.fn = on_progress;
    o.progress.user = getenv("BENCH_VERBOSE");
    t_stage = now();
    km_character c;
    km_error e;
    double t0 = now();
    if (km_character_generate(&o, &c, &e) != KM_OK) {
      fprintf(stderr, "generate %zu: %s\n", targets[i], e.message);
      return 1;
    }
    double t1 = now();
    double mn, fr, amin;
    quality(&c.mesh, &mn, &fr, &amin);
    double t2 = now();
    if (km_character_write_rig("bench_character.rig.json", &c, &e) != KM_OK) {
      fprintf(stderr, "write rig: %s\n", e.message);
      return 1;
    }
    double t3 = now();
    km_character r = {0};
    km_status st = km_character_read_rig("bench_character.rig.json", c.mesh.n_vertices, &r, &e);
    double t4 = now();
    printf("target %8zu: %8zu V %8zu F  generate %.3f s  min angle %.2f deg  <5deg %.4f%%  "
           "min area %.3g  max angle %.1f deg  >120deg %.3f%%  rig write %.3f s read %.3f s (%s)\n",
           targets[i], c.mesh.n_vertices, c.mesh.n_faces, t1 - t0, mn, 100 * fr, amin, g_max_angle,
           100 * g_frac120, t3 - t2, t4 - t3, st == KM_OK ? "ok" : e.message);
    (void)t2;
    km_character_free(&r);
    km_character_free(&c);
  }
  remove("bench_character.rig.json");
  return 0;
}
