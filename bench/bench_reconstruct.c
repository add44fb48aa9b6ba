/* kinemesh bench reconstruct: simulated multi-view capture of the procedural character
 * performing the kungfu take, reconstructed with a template of a different body (Park & Lim
 * 2014).  kinemesh bench reconstruct [--frames 300] [--dfaust DIR [--template MESH |
 * --template-shape stocky|slim]] [--keep DIR] [--report F]
 * Prints a table and a JSON line. Errors: err_points_mm = mean distance captured points ->
 * reconstructed surface; err_truth_* = distance from reconstructed vertices to the true
 * (noise-free) surface of the subject, per frame mean / max over frames; err_surface_* =
 * surface -> points (template vertex to its nearest captured point: the surface that no point
 * supports, which err_points_mm cannot see), unsupported_frames = frames the reconstructor
 * flagged (more than 2% of the vertices 3 cm or more from every point). Every length in the
 * JSON line is in mm, jerk and jitter included (the table prints them in mm too). */
#include "bench.h"
#include "cli.h"
#include "recon_plot.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static void die(const char *what, km_error *e) {
  fprintf(stderr, "kinemesh bench reconstruct: %s: %s\n", what, e->message);
  exit(1);
}

/* CPU seconds of this process (all its threads): on a loaded machine the wall time per frame
 * measures the neighbours too */
static double cpu_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void logger(km_log_level l, const char *m, void *u) {
  (void)u;
  if (l >= KM_LOG_WARN || getenv("KM_BENCH_DEBUG")) fprintf(stderr, "%s\n", m);
}

static bool g_rig_joints;      /* --rig-joints, read by both scenarios */
static const char *g_shape;    /* --template-shape (D-FAUST): stocky | slim | NULL */
static const char *g_template; /* --template (D-FAUST): a mesh with its rig sidecar, or NULL */

static int run_dfaust(const char *dir, const char *json) {
  km_error e = {0};
  char **paths = NULL;
  size_t n = 0;
  if (km_point_frames_list(dir, &paths, &n, &e)) die("frames", &e);
  km_character tmpl = {0};
  km_character_options co = {.target_vertices = 4000};
  /* a template of another build (the presets of gen character --shape) */
  if (g_shape && !strcmp(g_shape, "stocky"))
    co.height = 1.70, co.girth = 1.3, co.belly = 0.5;
  else if (g_shape && !strcmp(g_shape, "slim"))
    co.height = 1.80, co.girth = 0.8;
  else if (g_shape) {
    fprintf(stderr, "kinemesh bench reconstruct: --template-shape %s: stocky or slim\n", g_shape);
    return KM_EXIT_USAGE;
  }
  if (g_template && g_shape) {
    fprintf(stderr, "kinemesh bench reconstruct: --template and --template-shape: one of them\n");
    return KM_EXIT_USAGE;
  }
  if (g_template ? km_cli_load_character(g_template, NULL, 0, &tmpl, &e)
                 : km_character_generate(&co, &tmpl, &e))
    die("template", &e);
  if (g_template)
    printf("template %s: %zu vertices, its rig sidecar\n", g_template, tmpl.mesh.n_vertices);
  km_recon_report rep = {0};
  km_recon_options ro = {0};
  ro.rig_joints = g_rig_joints;
  char out[512];
  snprintf(out, sizeof out, "/tmp/bench_recon_dfaust_%d.pc2", (int)getpid());
  double t0 = km_seconds();
  /* D-FAUST has no feature correspondences: the heading search and the template's landmarks
   * as pseudo-correspondences (km_recon_init, in the report) */
  if (km_reconstruct((const char *const *)paths, n, &tmpl, NULL, 0, &ro, out, &rep, &e))
    die("reconstruct", &e);
  double secs = km_seconds() - t0;
  printf("D-FAUST %s: %zu frames, %.2f s/frame (no correspondences: heading %.0f deg kept of %d, "
         "rotation %.1f deg, %zu landmarks as pseudo-correspondences)\n",
         dir, rep.n_frames, secs / (double)(rep.n_frames ? rep.n_frames : 1), rep.init.yaw_deg,
         rep.init.yaw_candidates, rep.init.rotation_deg, rep.init.landmarks);
  printf("%6s %8s %9s %9s %9s | %9s %9s %9s %9s %6s | %6s %8s %s\n", "frame", "points", "mean_mm",
         "p95_mm", "max_mm", "s_mean", "s_p95", "s_p99", "s_max", "unsup", "iters", "seconds",
         "status");
  double smax = 0, sp99max = 0;
  for (size_t f = 0; f < rep.n_frames; ++f) {
    km_recon_frame_stats *s = &rep.frames[f];
    printf("%6zu %8zu %9.2f %9.2f %9.2f | %9.2f %9.2f %9.2f %9.2f %6zu | %6d %8.3f %s\n", s->index,
           s->points, s->mean_mm, s->p95_mm, s->max_mm, s->surface_mean_mm, s->surface_p95_mm,
           s->surface_p99_mm, s->surface_max_mm, s->unsupported_vertices, s->iterations, s->seconds,
           km_recon_frame_status(s));
    smax = s->surface_max_mm > smax ? s->surface_max_mm : smax;
    sp99max = s->surface_p99_mm > sp99max ? s->surface_p99_mm : sp99max;
  }
  printf("surface -> points over %s; p99 at most %.1f mm, max %.1f mm; %zu frame(s) flagged "
         "unsupported_surface\n",
         rep.visibility_known ? "vertices facing a camera" : "all vertices", sp99max, smax,
         rep.unsupported_frames);
  if (json && km_recon_report_write_json(json, &rep, &e)) die("json", &e);
  unlink(out);
  km_recon_report_free(&rep);
  km_character_free(&tmpl);
  km_paths_free(&paths, n);
  return 0;
}

int km_bench_reconstruct(int argc, char **argv) {
  size_t frames = 300;
  const char *keep = NULL, *json = NULL, *dfaust = NULL, *plot = NULL;
  const km_cli_opt opts[] = {
      {"frames", 'f', KM_OPT_SIZE, &frames, "frames of the kungfu take (default 300)"},
      {"report", 0, KM_OPT_STRING, &json, "also write the per-frame JSON report here"},
      {"plot", 0, KM_OPT_STRING, &plot, "also plot the per-frame errors (PNG, gnuplot)"},
      {"keep", 0, KM_OPT_STRING, &keep, "keep the simulated capture in this directory"},
      {"dfaust", 0, KM_OPT_STRING, &dfaust, "reconstruct real D-FAUST clouds from DIR instead"},
      {"template-shape", 0, KM_OPT_STRING, &g_shape,
       "with --dfaust: a template of another build (stocky | slim)"},
      {"template", 0, KM_OPT_STRING, &g_template,
       "with --dfaust: this mesh and its rig sidecar (e.g. made by kinemesh rig) as template"},
      {"rig-joints", 0, KM_OPT_FLAG, &g_rig_joints,
       "use the template rig's joints (default: estimated from the skin weights)"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                   "kinemesh bench reconstruct [--frames 300] [--report R.json] [--plot P.png]",
                   "Simulated 8-camera capture (about 32,000 points, 2 mm noise) of a procedural\n"
                   "subject performing the kungfu take, reconstructed from a 4,000-vertex\n"
                   "template of a different body. Prints a per-frame table, the summary and one\n"
                   "JSON line (frames, s_per_frame, err_points_mm, err_truth_mean_mm,\n"
                   "err_truth_max_mm, jerk_before, jerk_after, jitter_before, jitter_after,\n"
                   "err_surface_mean_mm, err_surface_p95_max_mm, err_surface_max_mm (surface\n"
                   "to points), unsupported_frames; errors, jerk and jitter in mm). Per frame:\n"
                   "both directions of the error and the mean and max to the truth.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (frames < 3) return km_cli_error("bench reconstruct", "--frames must be at least 3");
  km_cli_serial_blas();
  {
    char machine[320];
    km_bench_machine(machine, sizeof machine);
    int blas = km_blas_threads(0);
    printf("kinemesh bench reconstruct — %s, OpenBLAS %d thread%s\n", machine, blas,
           blas == 1 ? "" : "s");
  }
  km_set_logger(logger, NULL);
  if (dfaust) return run_dfaust(dfaust, json);
  if (frames < 3) frames = 3;
  km_error e = {0};
  /* subject and template: same generator, different bodies */
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 8000, .seed = 7, .girth = 1.08, .height = 1.72};
  km_character_options to = {.target_vertices = 4000, .seed = 1};
  if (km_character_generate(&so, &subj, &e)) die("subject", &e);
  if (km_character_generate(&to, &tmpl, &e)) die("template", &e);
  km_take take = {0};
  if (km_motion_generate(&subj.skeleton, KM_MOTION_KUNGFU, frames, &take, &e)) die("motion", &e);
  char dir[512];
  if (keep)
    snprintf(dir, sizeof dir, "%s", keep);
  else
    snprintf(dir, sizeof dir, "/tmp/bench_recon_%d", (int)getpid());
  /* 8 cameras as the help and the simulator example say (the library default is 4) */
  km_capture_options cap = {.cameras = 8, .points_per_frame = 32000, .noise_mm = 2, .seed = 42};
  double tc = km_seconds();
  if (km_capture_simulate(&subj, &take, &cap, dir, &e)) die("capture", &e);
  tc = km_seconds() - tc;
  char path[1024];
  snprintf(path, sizeof path, "%s/truth_take.json", dir);
  if (keep && km_take_write(path, &take, &e)) die("take", &e);
  snprintf(path, sizeof path, "%s/truth.pc2", dir);
  double *truth = NULL;
  km_anim_info ti;
  if (km_pc2_read(path, &truth, &ti, &e)) die("truth", &e);
  snprintf(path, sizeof path, "%s/frame_*.ply", dir);
  char **paths = NULL;
  size_t n = 0;
  if (km_point_frames_list(path, &paths, &n, &e)) die("frames", &e);
  /* features: template landmark <-> the captured point nearest the subject's landmark in
   * frame 0 (what a user clicking on the cloud would give) */
  km_points p0 = {0};
  if (km_points_read(paths[0], &p0, &e)) die("frame 0", &e);
  km_recon_feature feat[KM_CHARACTER_LANDMARKS];
  size_t nfeat = 0;
  for (int l = 0; l < KM_CHARACTER_LANDMARKS; ++l) {
    const double *q = truth + 3 * (size_t)subj.landmarks[l].vertex;
    double best = INFINITY;
    size_t bi = 0;
    for (size_t i = 0; i < p0.n; ++i) {
      double d = 0;
      for (int a = 0; a < 3; ++a)
        d += (p0.P[3 * i + a] - q[a]) * (p0.P[3 * i + a] - q[a]);
      if (d < best) best = d, bi = i;
    }
    if (sqrt(best) > 0.05) { /* landmark hidden from every camera */
      fprintf(stderr, "landmark %s hidden (%.0f mm)\n", subj.landmarks[l].name, sqrt(best) * 1e3);
      continue;
    }
    int tl = -1;
    for (int k = 0; k < KM_CHARACTER_LANDMARKS; ++k)
      if (!strcmp(tmpl.landmarks[k].name, subj.landmarks[l].name)) tl = k;
    if (tl < 0) continue;
    feat[nfeat].vertex = tmpl.landmarks[tl].vertex;
    memcpy(feat[nfeat].point, p0.P + 3 * bi, 3 * sizeof(double));
    ++nfeat;
  }
  size_t npts0 = p0.n;
  /* the simulator's ring (8 cameras 3 m from the subject's bounding-box centre, 0.3 m above
   * it) around frame 0: surface -> points is measured over the vertices facing a camera */
  double cams[8 * 3], lo[3] = {INFINITY, INFINITY, INFINITY},
                      hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < p0.n; ++i)
    for (int a = 0; a < 3; ++a)
      lo[a] = fmin(lo[a], p0.P[3 * i + a]), hi[a] = fmax(hi[a], p0.P[3 * i + a]);
  for (int c = 0; c < 8; ++c) {
    double ang = 2 * M_PI * (c + 0.5) / 8;
    cams[3 * c] = (lo[0] + hi[0]) / 2 + 3 * sin(ang);
    cams[3 * c + 1] = (lo[1] + hi[1]) / 2 + 0.3;
    cams[3 * c + 2] = (lo[2] + hi[2]) / 2 + 3 * cos(ang);
  }
  km_points_free(&p0);
  km_recon_options ro = {.cameras = cams, .n_cameras = 8};
  ro.rig_joints = g_rig_joints;
  /* The incremental API (what km_reconstruct streams through) so both the refined and the
   * filtered sequences are at hand for the jitter measure. */
  km_recon *rc = NULL;
  if (km_recon_create(&tmpl, &ro, &rc, &e)) die("recon", &e);
  size_t nv = tmpl.mesh.n_vertices, nj = tmpl.skeleton.n_joints;
  double *ref = malloc(n * nv * 3 * sizeof *ref), *glob = malloc(n * nv * 3 * sizeof *glob);
  double *filt = malloc(n * nv * 3 * sizeof *filt);
  km_recon_report rep = {0};
  rep.n_frames = n, rep.n_joints = nj;
  rep.unsupported_distance_mm = 30, rep.unsupported_fraction = 0.02; /* the defaults ro has */
  rep.visibility_known = true;
  rep.frames = calloc(n, sizeof *rep.frames);
  rep.joints = malloc(n * nj * 3 * sizeof *rep.joints);
  rep.joint_names = calloc(nj, sizeof *rep.joint_names);
  for (size_t j = 0; j < nj; ++j)
    rep.joint_names[j] = strdup(tmpl.skeleton.names[j]);
  double t0 = km_seconds();
  double *cpu = malloc(n * sizeof *cpu);
  for (size_t f = 0; f < n; ++f) {
    double tf = km_seconds(), cf = cpu_seconds();
    km_points pts = {0};
    if (km_points_read(paths[f], &pts, &e)) die("frame", &e);
    if (f == 0) {
      if (km_recon_first_frame(rc, pts.P, pts.n, feat, nfeat, &rep.frames[f], &e))
        die("first frame", &e);
      rep.correspondences = nfeat;
      km_recon_init_get(rc, &rep.init);
    } else {
      km_recon_next_frame(rc, pts.P, pts.n, &rep.frames[f], &e);
    }
    rep.frames[f].index = f;
    rep.frames[f].seconds = km_seconds() - tf; /* including reading the file */
    cpu[f] = cpu_seconds() - cf;
    if (rep.frames[f].status) ++rep.failed_frames;
    if (rep.frames[f].unsupported) ++rep.unsupported_frames;
    km_points_free(&pts);
    memcpy(ref + f * nv * 3, km_recon_surface(rc), nv * 3 * sizeof(double));
    memcpy(glob + f * nv * 3, km_recon_global(rc), nv * 3 * sizeof(double));
    memcpy(rep.joints + f * nj * 3, km_recon_joints(rc), nj * 3 * sizeof(double));
  }
  if (km_local_motion_filter(n, nv, ref, glob, 2, 1, filt, &e)) die("filter", &e);
  if (getenv("KM_BENCH_DUMP")) /* the first frames' registered surfaces, to look at */
    for (size_t f = 0; f < n && f < 3; ++f) {
      km_mesh dm = tmpl.mesh;
      dm.V = ref + f * nv * 3;
      dm.UV = NULL, dm.N = NULL;
      char dp[1200];
      snprintf(dp, sizeof dp, "%s/recon_%05zu.obj", getenv("KM_BENCH_DUMP"), f);
      if (km_mesh_write(dp, &dm, NULL, &e)) die("dump", &e);
      dm.V = glob + f * nv * 3;
      snprintf(dp, sizeof dp, "%s/global_%05zu.obj", getenv("KM_BENCH_DUMP"), f);
      if (km_mesh_write(dp, &dm, NULL, &e)) die("dump", &e);
    }
  double total = km_seconds() - t0;
  km_recon_free(&rc);
  double *rec = filt;
  km_anim_info ri = {.frames = n};
  /* truth trajectories of the template vertices: each vertex anchored at frame 0 to its
   * closest point on the true surface (triangle + barycentrics), carried through the true
   * animation; jitter = mean |second difference| of (reconstruction - anchored truth) */
  km_mesh tm = subj.mesh;
  double *tv = malloc(tm.n_vertices * 3 * sizeof(double));
  memcpy(tv, truth, tm.n_vertices * 3 * sizeof(double));
  int32_t *tri = malloc(nv * sizeof *tri);
  double *dist = malloc(nv * sizeof *dist), *bary = malloc(nv * 3 * sizeof *bary);
  if (km_point_mesh_distance(tv, tm.n_vertices, tm.F, tm.n_faces, ref, nv, tri, bary, NULL, &e))
    die("truth surface", &e);
  double jit[3] = {0, 0, 0}, jerk[3] = {0, 0, 0};
  for (int pass = 0; pass < 3; ++pass) {
    const double *seq = pass == 2 ? glob : pass ? filt : ref;
    for (size_t f = 1; f + 1 < n; ++f) {
      double acc = 0, accj = 0;
      for (size_t i = 0; i < nv; ++i) {
        double d2 = 0, dj = 0;
        for (int a = 0; a < 3; ++a) {
          double tr[3];
          for (int k = 0; k < 3; ++k) {
            size_t ff = f - 1 + (size_t)k;
            const int32_t *t = tm.F + 3 * (size_t)tri[i];
            const double *T = truth + ff * tm.n_vertices * 3;
            tr[k] = bary[3 * i] * T[3 * (size_t)t[0] + a] +
                    bary[3 * i + 1] * T[3 * (size_t)t[1] + a] +
                    bary[3 * i + 2] * T[3 * (size_t)t[2] + a];
          }
          double s0 = seq[(f - 1) * nv * 3 + 3 * i + a], s1 = seq[f * nv * 3 + 3 * i + a],
                 s2 = seq[(f + 1) * nv * 3 + 3 * i + a];
          double d = (s2 - tr[2]) - 2 * (s1 - tr[1]) + (s0 - tr[0]);
          double dd = s2 - 2 * s1 + s0;
          d2 += d * d, dj += dd * dd;
        }
        acc += sqrt(d2), accj += sqrt(dj);
      }
      jit[pass] += acc / (double)nv / (double)(n - 2);
      jerk[pass] += accj / (double)nv / (double)(n - 2);
    }
  }
  rep.jerk_before = jerk[0], rep.jerk_after = jerk[1];
  printf("jitter of the LBS-only (skeleton) sequence: %.3f mm\n", jit[2] * 1e3);
  if (getenv("KM_BENCH_TRACE")) {
    size_t i = (size_t)tmpl.landmarks[6].vertex; /* hand_left */
    for (size_t f = 0; f < n; ++f) {
      const int32_t *t = tm.F + 3 * (size_t)tri[i];
      const double *T = truth + f * tm.n_vertices * 3;
      double tr[3];
      for (int a = 0; a < 3; ++a)
        tr[a] = bary[3 * i] * T[3 * (size_t)t[0] + a] + bary[3 * i + 1] * T[3 * (size_t)t[1] + a] +
                bary[3 * i + 2] * T[3 * (size_t)t[2] + a];
      const double *x = ref + f * nv * 3 + 3 * i;
      printf("f%zu truth %.4f %.4f %.4f rec %.4f %.4f %.4f\n", f, tr[0], tr[1], tr[2], x[0], x[1],
             x[2]);
    }
  }
  double *secs = malloc(n * sizeof *secs);
  double tmean = 0, tmax = 0, pmean = 0, smean = 0, smax = 0, sp95max = 0;
  /* two-sided: mean/p95/max points -> surface, s_* surface -> points (every template vertex to
   * its nearest captured point), unsup = vertices beyond 30 mm; truth = mean/max of the
   * filtered output's vertices to the true surface */
  printf("%6s %8s %9s %9s %9s | %9s %9s %9s %6s | %9s %9s %6s %8s %s\n", "frame", "points",
         "mean_mm", "p95_mm", "max_mm", "s_mean", "s_p95", "s_max", "unsup", "truth_mm",
         "truth_max", "iters", "seconds", "status");
  for (size_t f = 0; f < rep.n_frames && f < ri.frames; ++f) {
    memcpy(tv, truth + f * tm.n_vertices * 3, tm.n_vertices * 3 * sizeof(double));
    if (km_point_mesh_distance(tv, tm.n_vertices, tm.F, tm.n_faces, rec + f * nv * 3, nv, tri, NULL,
                               dist, &e))
      die("truth surface", &e);
    double m = 0, mx = 0;
    size_t imx = 0;
    for (size_t i = 0; i < nv; ++i) {
      m += dist[i];
      if (dist[i] > mx) mx = dist[i], imx = i;
    }
    if (getenv("KM_BENCH_TRACE") && f < 3) {
      size_t far = 0;
      for (size_t i = 0; i < nv; ++i)
        far += dist[i] > 0.02;
      printf("frame %zu: worst vertex %zu (%s, %.0f mm), %zu vertices > 2 cm\n", f, imx,
             tmpl.skeleton.names[tmpl.skin.joints[4 * imx]], mx * 1e3, far);
    }
    m /= (double)nv;
    tmean += m;
    tmax = mx * 1e3 > tmax ? mx * 1e3 : tmax;
    pmean += rep.frames[f].mean_mm;
    secs[f] = rep.frames[f].seconds;
    km_recon_frame_stats *s = &rep.frames[f];
    smean += s->surface_mean_mm;
    smax = s->surface_max_mm > smax ? s->surface_max_mm : smax;
    sp95max = s->surface_p95_mm > sp95max ? s->surface_p95_mm : sp95max;
    if (f < 10 || f % 25 == 0 || s->status || s->unsupported || mx > 0.03)
      printf("%6zu %8zu %9.2f %9.2f %9.2f | %9.2f %9.2f %9.2f %6zu | %9.2f %9.2f %6d %8.3f %s\n",
             s->index, s->points, s->mean_mm, s->p95_mm, s->max_mm, s->surface_mean_mm,
             s->surface_p95_mm, s->surface_max_mm, s->unsupported_vertices, m * 1e3, mx * 1e3,
             s->iterations, s->seconds, km_recon_frame_status(s));
  }
  size_t nf = rep.n_frames < ri.frames ? rep.n_frames : ri.frames;
  tmean = 1e3 * tmean / (double)nf;
  pmean /= (double)nf;
  smean /= (double)nf;
  qsort(secs + 1, nf - 1, sizeof *secs, cmp_d); /* frame 0 (first-frame registration) apart */
  double med = secs[1 + (nf - 1) / 2];
  qsort(cpu + 1, nf - 1, sizeof *cpu, cmp_d);
  double cmed = cpu[1 + (nf - 1) / 2];
  printf("cpu_s_per_frame        %.3f (median CPU time of frames 1.., all threads; frame 0: "
         "%.3f)\n",
         cmed, cpu[0]);
  printf("surface -> points over the vertices facing one of the 8 cameras\n");
  printf("\n%-22s %zu\n%-22s %zu (template %zu vertices, subject %zu)\n%-22s %.3f\n"
         "%-22s %.3f\n%-22s %.3f\n%-22s %.3f\n%-22s %.3f\n%-22s %.5f\n%-22s %.5f\n%-22s %zu\n"
         "%-22s %zu\n%-22s %.1f s (capture %.1f s)\n%-22s %.4f\n%-22s %.4f\n"
         "%-22s %.3f\n%-22s %.3f\n%-22s %.3f\n%-22s %zu\n",
         "frames", nf, "points_frame0", npts0, nv, subj.mesh.n_vertices, "s_per_frame", med,
         "first_frame_s", rep.frames[0].seconds, "err_points_mm", pmean, "err_truth_mean_mm", tmean,
         "err_truth_max_mm", tmax, "jerk_before_mm", rep.jerk_before * 1e3, "jerk_after_mm",
         rep.jerk_after * 1e3, "features", nfeat, "failed_frames", rep.failed_frames, "total",
         total, tc, "jitter_before_mm", jit[0] * 1e3, "jitter_after_mm", jit[1] * 1e3,
         "err_surface_mean_mm", smean, "err_surface_p95_max_mm", sp95max, "err_surface_max_mm",
         smax, "unsupported_frames", rep.unsupported_frames);
  printf("{\"bench\":\"reconstruct\",\"frames\":%zu,\"s_per_frame\":%.4f,\"cpu_s_per_frame\":%.4f,"
         "\"err_points_mm\":%.3f,"
         "\"err_truth_mean_mm\":%.3f,\"err_truth_max_mm\":%.3f,\"jerk_before\":%.6g,"
         "\"jerk_after\":%.6g,\"jitter_before\":%.6g,\"jitter_after\":%.6g,\"failed_frames\":%zu,"
         "\"err_surface_mean_mm\":%.3f,\"err_surface_p95_max_mm\":%.3f,\"err_surface_max_mm\":%.3f,"
         "\"unsupported_frames\":%zu}\n",
         nf, med, cmed, pmean, tmean, tmax, rep.jerk_before * 1e3, rep.jerk_after * 1e3,
         jit[0] * 1e3, jit[1] * 1e3, rep.failed_frames, smean, sp95max, smax,
         rep.unsupported_frames);
  if (json && km_recon_report_write_json(json, &rep, &e)) die("json", &e);
  if (plot && km_recon_report_plot(plot, &rep, &e)) die("plot", &e);
  free(cpu);
  free(tv), free(tri), free(dist), free(bary), free(secs), free(ref), free(glob), free(filt),
      free(truth);
  km_recon_report_free(&rep);
  km_paths_free(&paths, n);
  km_take_free(&take);
  km_character_free(&subj);
  km_character_free(&tmpl);
  if (!keep) {
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
  }
  return 0;
}
