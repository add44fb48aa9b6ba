/* Puppet deformation benchmark (Wu, Lu & Song, Table 1 columns).
 *
 *   bench_deform MESH [--handles N] [--frames F] [--full-frames G] [--cache PATH]
 *                     [--iterations K] [--threads T] [--crossed C] [--handle-weight W]
 *                     [--arap-iterations A]
 *
 * MESH is an OBJ/OFF/PLY path, or "icosphere:S" (10*4^S+2 vertices) / "cylinder:SEG:RINGS".
 * N handles (default 5) are seeded by farthest-point sampling; each takes the vertices
 * nearest to its seed (clamp(#V/400, 30, 200) of them). Handle 0 stays anchored, the others
 * follow smooth synthetic motions (translation + rotation about their centroid). Prints one
 * row: n_ver n_han n_tri t1 (precompute, s) t1~ (cache load, s) set (set_handles, ms)
 * t4 (puppet solve per frame incl. X = W R, median ms) full (ARAP per frame, median ms) and
 * the reduced-vs-full deviation (mean, max over vertices and frames, fraction of the bbox
 * diagonal). The full solver runs on the first G frames only (default: all; 0 disables). */
#include "kinemesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Process CPU time: under a loaded machine wall-clock per frame includes waiting for a core;
 * CPU time does not (for the single-threaded 43k path it is the quiet-machine wall time). */
static double cpu_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

static double median(double *x, size_t n) {
  if (!n) return NAN;
  qsort(x, n, sizeof *x, cmp_d);
  return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

static int die(const char *what, const km_error *e) {
  fprintf(stderr, "bench_deform: %s: %s\n", what, e->message);
  return 1;
}

typedef struct {
  double d;
  int32_t v;
} dv;
static int cmp_dv(const void *a, const void *b) {
  return cmp_d(&((const dv *)a)->d, &((const dv *)b)->d);
}

/* Farthest-point seeds, then the `per` nearest untaken vertices of each seed. */
static void pick_handles(const km_mesh *m, int nh, size_t per, int32_t *off, int32_t *hv) {
  size_t n = m->n_vertices;
  double *dist = malloc(n * sizeof(double));
  unsigned char *taken = calloc(n, 1);
  dv *order = malloc(n * sizeof(dv));
  int32_t *seeds = malloc((size_t)nh * sizeof(int32_t));
  /* first seed: the vertex farthest from the centroid */
  double c[3] = {0, 0, 0};
  for (size_t v = 0; v < n; ++v)
    for (int k = 0; k < 3; ++k)
      c[k] += m->V[3 * v + k] / (double)n;
  for (size_t v = 0; v < n; ++v)
    dist[v] = INFINITY;
  size_t cur = 0;
  double best = -1;
  for (size_t v = 0; v < n; ++v) {
    const double *x = m->V + 3 * v;
    double d = (x[0] - c[0]) * (x[0] - c[0]) + (x[1] - c[1]) * (x[1] - c[1]) +
               (x[2] - c[2]) * (x[2] - c[2]);
    if (d > best) best = d, cur = v;
  }
  for (int h = 0; h < nh; ++h) {
    seeds[h] = (int32_t)cur;
    const double *s = m->V + 3 * cur;
    best = -1;
    for (size_t v = 0; v < n; ++v) {
      const double *x = m->V + 3 * v;
      double d = (x[0] - s[0]) * (x[0] - s[0]) + (x[1] - s[1]) * (x[1] - s[1]) +
                 (x[2] - s[2]) * (x[2] - s[2]);
      if (d < dist[v]) dist[v] = d;
      if (dist[v] > best) best = dist[v], cur = v;
    }
  }
  size_t k = 0;
  off[0] = 0;
  for (int h = 0; h < nh; ++h) {
    const double *s = m->V + 3 * (size_t)seeds[h];
    for (size_t v = 0; v < n; ++v) {
      const double *x = m->V + 3 * v;
      order[v].d = (x[0] - s[0]) * (x[0] - s[0]) + (x[1] - s[1]) * (x[1] - s[1]) +
                   (x[2] - s[2]) * (x[2] - s[2]);
      order[v].v = (int32_t)v;
    }
    qsort(order, n, sizeof(dv), cmp_dv);
    size_t got = 0;
    for (size_t i = 0; i < n && got < per; ++i)
      if (!taken[order[i].v]) {
        taken[order[i].v] = 1;
        hv[k++] = order[i].v;
        ++got;
      }
    off[h + 1] = (int32_t)k;
  }
  free(dist);
  free(taken);
  free(order);
  free(seeds);
}

static void rot_axis(const double *u, double a, double *R) {
  double c = cos(a), s = sin(a), t = 1 - c;
  R[0] = t * u[0] * u[0] + c, R[1] = t * u[0] * u[1] - s * u[2], R[2] = t * u[0] * u[2] + s * u[1];
  R[3] = t * u[0] * u[1] + s * u[2], R[4] = t * u[1] * u[1] + c, R[5] = t * u[1] * u[2] - s * u[0];
  R[6] = t * u[0] * u[2] - s * u[1], R[7] = t * u[1] * u[2] + s * u[0], R[8] = t * u[2] * u[2] + c;
}

/* Frame f of the synthetic take: handle 0 anchored, handle h > 0 translated along a fixed
 * direction by up to 12% of the diagonal and rotated up to 0.5 rad about its centroid. */
static void targets_at(const km_mesh *m, int nh, const int32_t *off, const int32_t *hv, int f,
                       double diag, double *T) {
  for (int h = 0; h < nh; ++h) {
    double c[3] = {0, 0, 0};
    int cnt = off[h + 1] - off[h];
    for (int32_t i = off[h]; i < off[h + 1]; ++i)
      for (int k = 0; k < 3; ++k)
        c[k] += m->V[3 * (size_t)hv[i] + k] / cnt;
    double ph = 0.9 * h, w = 2 * 3.14159265358979 / 60.0;
    double amp = h == 0 ? 0 : sin(w * f + ph) * (0.5 + 0.5 * sin(0.37 * f * w));
    double dir[3] = {cos(1.7 * h), sin(1.7 * h), cos(2.9 * h)};
    double ax[3] = {sin(2.3 * h), cos(0.7 * h), sin(1.1 * h + 0.4)};
    double l = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
    for (int k = 0; k < 3; ++k)
      ax[k] /= l;
    l = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    double R[9];
    rot_axis(ax, 0.5 * amp, R);
    for (int32_t i = off[h]; i < off[h + 1]; ++i) {
      const double *x = m->V + 3 * (size_t)hv[i];
      double d[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
      for (int r = 0; r < 3; ++r)
        T[3 * i + r] = c[r] + R[r * 3] * d[0] + R[r * 3 + 1] * d[1] + R[r * 3 + 2] * d[2] +
                       0.12 * diag * amp * dir[r] / l;
    }
  }
}

int main(int argc, char **argv) {
  if (argc < 2) {
    fprintf(stderr,
            "usage: %s MESH|icosphere:S|cylinder:SEG:RINGS [--handles N] [--frames F] "
            "[--full-frames G] [--cache PATH] [--iterations K] [--threads T] [--crossed C] "
            "[--handle-weight W] [--arap-iterations A]\n",
            argv[0]);
    return 2;
  }
  const char *mesh_path = argv[1], *cache = NULL;
  int nh = 5, frames = 60, full_frames = -1, iterations = 0, crossed = 0, arap_iterations = 0;
  double handle_weight = 0;
  int fields = 0, isolines = 0;
  km_puppet_energy energy = KM_PUPPET_ENERGY_LAPLACIAN;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!strcmp(argv[i], "--handles"))
      nh = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--frames"))
      frames = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--full-frames"))
      full_frames = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--cache"))
      cache = argv[i + 1];
    else if (!strcmp(argv[i], "--iterations"))
      iterations = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--arap-iterations"))
      arap_iterations = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--energy"))
      energy = !strcmp(argv[i + 1], "arap") ? KM_PUPPET_ENERGY_ARAP : KM_PUPPET_ENERGY_LAPLACIAN;
    else if (!strcmp(argv[i], "--fields"))
      fields = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--isolines"))
      isolines = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--crossed"))
      crossed = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--handle-weight"))
      handle_weight = atof(argv[i + 1]);
#ifdef _OPENMP
    else if (!strcmp(argv[i], "--threads"))
      omp_set_num_threads(atoi(argv[i + 1]));
#endif
    else {
      fprintf(stderr, "bench_deform: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  if (nh < 1 || frames < 1) return 2;
  if (full_frames < 0 || full_frames > frames) full_frames = frames;
  km_error e = {0};
  km_mesh m = {0};
  int a1, a2;
  if (sscanf(mesh_path, "icosphere:%d", &a1) == 1) {
    if (km_icosphere(a1, 1.0, &m, &e)) return die(mesh_path, &e);
  } else if (sscanf(mesh_path, "cylinder:%d:%d", &a1, &a2) == 2) {
    if (km_cylinder(a1, a2, 0.1, 1.0, &m, &e)) return die(mesh_path, &e);
  } else if (km_mesh_read(mesh_path, &m, &e)) {
    return die(mesh_path, &e);
  }
  size_t n = m.n_vertices;
  double diag = km_bbox_diagonal(m.V, n);
  size_t per = n / 400;
  per = per < 30 ? 30 : per > 200 ? 200 : per;
  if (per * (size_t)nh > n / 2) per = n / (2 * (size_t)nh);
  int32_t *off = malloc(((size_t)nh + 1) * sizeof(int32_t)), *hv = malloc(n * sizeof(int32_t));
  pick_handles(&m, nh, per, off, hv);
  size_t nhv = (size_t)off[nh];

  km_puppet_options po = {0};
  po.iterations = iterations;
  po.crossed_per_isoline = crossed;
  po.fields = fields;
  po.energy = energy;
  po.isolines = isolines;
  po.handle_weight = handle_weight;
  km_puppet *p = NULL;
  double t = now();
  if (km_puppet_precompute(&m, &po, &p, &e)) return die("precompute", &e);
  double t1 = now() - t;
  char tmp[512];
  if (!cache) {
    snprintf(tmp, sizeof tmp, "/tmp/bench_deform_%d.kmp", (int)getpid());
    cache = tmp;
  }
  if (km_puppet_save(p, cache, &e)) return die("save", &e);
  km_puppet_free(&p);
  double t1c = INFINITY;
  for (int rep = 0; rep < 3; ++rep) {
    km_puppet_free(&p);
    t = now();
    if (km_puppet_load(cache, &m, &po, &p, &e)) return die("load", &e);
    double dt = now() - t;
    t1c = dt < t1c ? dt : t1c;
  }
  if (cache == tmp) remove(tmp);
  t = now();
  if (km_puppet_set_handles(p, (size_t)nh, off, hv, &e)) return die("set_handles", &e);
  double tset = now() - t;

  km_arap *a = NULL;
  double tfull_pre = 0;
  if (full_frames > 0) {
    t = now();
    km_arap_options ao = {.iterations = arap_iterations};
    if (km_arap_precompute(&m, (size_t)nh, off, hv, &ao, &a, &e)) return die("arap", &e);
    tfull_pre = now() - t;
  }
  double *T = malloc(nhv * 3 * sizeof(double)), *X = malloc(n * 3 * sizeof(double)),
         *Y = malloc(n * 3 * sizeof(double));
  double *t4cpu = malloc((size_t)frames * sizeof(double));
  double *t4 = malloc((size_t)frames * sizeof(double)),
         *tf = malloc((size_t)frames * sizeof(double));
  double dev_sum = 0, dev_max = 0;
  int iters_sum = 0;
  double handle_err = 0;
  for (int f = 0; f < frames; ++f) {
    targets_at(&m, nh, off, hv, f, diag, T);
    t = now();
    double c0 = cpu_now();
    if (km_puppet_solve(p, T, X, &e)) return die("solve", &e);
    t4[f] = now() - t;
    t4cpu[f] = cpu_now() - c0;
    km_puppet_info info;
    km_puppet_info_get(p, &info);
    iters_sum += info.last_iterations;
    for (size_t i = 0; i < nhv; ++i) {
      const double *x = X + 3 * (size_t)hv[i], *y = T + 3 * i;
      handle_err += sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                         (x[2] - y[2]) * (x[2] - y[2])) /
                    (double)nhv / frames / diag;
    }
    if (f < full_frames) {
      t = now();
      if (km_arap_solve(a, T, Y, &e)) return die("arap solve", &e);
      tf[f] = now() - t;
      double s = 0, mx = 0;
      for (size_t v = 0; v < n; ++v) {
        double d = sqrt((X[3 * v] - Y[3 * v]) * (X[3 * v] - Y[3 * v]) +
                        (X[3 * v + 1] - Y[3 * v + 1]) * (X[3 * v + 1] - Y[3 * v + 1]) +
                        (X[3 * v + 2] - Y[3 * v + 2]) * (X[3 * v + 2] - Y[3 * v + 2]));
        s += d;
        mx = d > mx ? d : mx;
      }
      dev_sum += s / (double)n;
      dev_max = mx > dev_max ? mx : dev_max;
    }
  }
  km_puppet_info info;
  km_puppet_info_get(p, &info);
  const char *name = strrchr(mesh_path, '/') ? strrchr(mesh_path, '/') + 1 : mesh_path;
  printf("%-16s %8s %5s %5s %8s %8s %7s %8s %9s %9s %9s %6s\n", "model", "n_ver", "n_han", "n_tri",
         "t1(s)", "t1~(s)", "set(ms)", "t4(ms)", "full(ms)", "dev_mean", "dev_max", "iters");
  double fm = full_frames > 0 ? median(tf, (size_t)full_frames) * 1e3 : NAN;
  printf("%-16s %8zu %5d %5zu %8.3f %8.4f %7.2f %8.3f %9.2f %9.5f %9.5f %6.2f\n", name, n, nh,
         info.crossed_triangles, t1, t1c, tset * 1e3, median(t4, (size_t)frames) * 1e3, fm,
         full_frames > 0 ? dev_sum / full_frames / diag : NAN,
         full_frames > 0 ? dev_max / diag : NAN, (double)iters_sum / frames);
  printf("# puppet handle vertices' mean distance to their targets: %.5f of the diagonal\n",
         handle_err);
  printf("# t4 as process CPU time (all threads): median %.3f ms\n",
         median(t4cpu, (size_t)frames) * 1e3);
  printf("# %zu handle vertices (%zu per handle), %d frames (%d with the full solver, ARAP "
         "precompute %.2f s)\n",
         nhv, per, frames, full_frames, tfull_pre);
  (void)dev_sum;
  free(T);
  free(X);
  free(Y);
  free(t4);
  free(t4cpu);
  free(tf);
  free(off);
  free(hv);
  km_arap_free(&a);
  km_puppet_free(&p);
  km_mesh_free(&m);
  return 0;
}
