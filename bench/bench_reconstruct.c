/* Benchmark: simulated multi-view capture of the procedural character performing the kungfu
 * take, reconstructed with a template of a different body (Park & Lim 2014).
 *   bench_reconstruct [frames=300] [--dfaust DIR] [--keep DIR] [--json FILE]
 * Prints a table and a JSON line. Errors: err_points_mm = mean distance captured points ->
 * reconstructed surface; err_truth_* = distance from reconstructed vertices to the true
 * (noise-free) surface of the subject, per frame mean / max over frames. */
#include "recon/recon.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void die(const char *what, km_error *e) {
  fprintf(stderr, "bench_reconstruct: %s: %s\n", what, e->message);
  exit(1);
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void logger(km_log_level l, const char *m, void *u) {
  (void)u;
  if (l >= KM_LOG_WARN || getenv("KM_BENCH_DEBUG")) fprintf(stderr, "%s\n", m);
}

static int run_dfaust(const char *dir, const char *json) {
  km_error e = {0};
  char **paths = NULL;
  size_t n = 0;
  if (km_point_frames_list(dir, &paths, &n, &e)) die("frames", &e);
  km_character tmpl = {0};
  km_character_options co = {.target_vertices = 4000};
  if (km_character_generate(&co, &tmpl, &e)) die("template", &e);
  km_recon_report rep = {0};
  km_recon_options ro = {0};
  char out[512];
  snprintf(out, sizeof out, "/tmp/bench_recon_dfaust_%d.pc2", (int)getpid());
  double t0 = km__now();
  /* D-FAUST has no feature correspondences: global alignment (centroid + height) only */
  if (km_reconstruct((const char *const *)paths, n, &tmpl, NULL, 0, &ro, out, &rep, &e))
    die("reconstruct", &e);
  double secs = km__now() - t0;
  printf("D-FAUST %s: %zu frames, %.2f s/frame (no correspondences: global alignment only)\n", dir,
         rep.n_frames, secs / (double)(rep.n_frames ? rep.n_frames : 1));
  printf("%6s %8s %9s %9s %6s %8s %s\n", "frame", "points", "mean_mm", "max_mm", "iters", "seconds",
         "status");
  for (size_t f = 0; f < rep.n_frames; ++f) {
    km_recon_frame_stats *s = &rep.frames[f];
    printf("%6zu %8zu %9.2f %9.2f %6d %8.3f %s\n", s->index, s->points, s->mean_mm, s->max_mm,
           s->iterations, s->seconds, km_status_name(s->status));
  }
  if (json && km_recon_report_write_json(json, &rep, &e)) die("json", &e);
  unlink(out);
  km_recon_report_free(&rep);
  km_character_free(&tmpl);
  km_paths_free(&paths, n);
  return 0;
}

int main(int argc, char **argv) {
  size_t frames = 300;
  const char *keep = NULL, *json = NULL, *dfaust = NULL, *plot = NULL;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--keep") && i + 1 < argc)
      keep = argv[++i];
    else if (!strcmp(argv[i], "--json") && i + 1 < argc)
      json = argv[++i];
    else if (!strcmp(argv[i], "--dfaust") && i + 1 < argc)
      dfaust = argv[++i];
    else if (!strcmp(argv[i], "--plot") && i + 1 < argc)
      plot = argv[++i];
    else
      frames = (size_t)strtoul(argv[i], NULL, 10);
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
  if (getenv("KM_BENCH_SAME")) to = so;
  if (km_character_generate(&to, &tmpl, &e)) die("template", &e);
  km_take take = {0};
  if (km_motion_generate(&subj.skeleton, KM_MOTION_KUNGFU, frames, &take, &e)) die("motion", &e);
  char dir[512];
  if (keep)
    snprintf(dir, sizeof dir, "%s", keep);
  else
    snprintf(dir, sizeof dir, "/tmp/bench_recon_%d", (int)getpid());
  km_capture_options cap = {.points_per_frame = 32000, .noise_mm = 2, .seed = 42};
  double tc = km__now();
  if (km_capture_simulate(&subj, &take, &cap, dir, &e)) die("capture", &e);
  tc = km__now() - tc;
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
    memcpy(feat[nfeat].point, getenv("KM_BENCH_EXACT") ? q : p0.P + 3 * bi, 3 * sizeof(double));
    ++nfeat;
  }
  size_t npts0 = p0.n;
  km_points_free(&p0);
  km_recon_options ro = {0};
  km_recon_report rep = {0};
  snprintf(path, sizeof path, "%s/recon.pc2", dir);
  double t0 = km__now();
  if (km_reconstruct((const char *const *)paths, n, &tmpl, feat, nfeat, &ro, path, &rep, &e))
    die("reconstruct", &e);
  double total = km__now() - t0;
  double *rec = NULL;
  km_anim_info ri;
  if (km_pc2_read(path, &rec, &ri, &e)) die("recon", &e);
  /* distances reconstructed vertices -> true surface */
  km_mesh tm = subj.mesh;
  double *tv = malloc(tm.n_vertices * 3 * sizeof(double));
  memcpy(tv, truth, tm.n_vertices * 3 * sizeof(double));
  km__surface *ts = NULL;
  if (km__surface_create(tv, tm.n_vertices, tm.F, tm.n_faces, &ts, &e)) die("truth surface", &e);
  size_t nv = tmpl.mesh.n_vertices;
  int32_t *tri = malloc(nv * sizeof *tri);
  double *dist = malloc(nv * sizeof *dist);
  double *secs = malloc(n * sizeof *secs);
  double tmean = 0, tmax = 0, pmean = 0;
  printf("%6s %8s %9s %9s %9s %6s %8s %s\n", "frame", "points", "mean_mm", "max_mm", "truth_mm",
         "iters", "seconds", "status");
  for (size_t f = 0; f < rep.n_frames && f < ri.frames; ++f) {
    memcpy(tv, truth + f * tm.n_vertices * 3, tm.n_vertices * 3 * sizeof(double));
    km__surface_update(ts, tv);
    km__surface_closest(ts, rec + f * nv * 3, nv, 0, tri, NULL, dist);
    double m = 0, mx = 0;
    for (size_t i = 0; i < nv; ++i)
      m += dist[i], mx = dist[i] > mx ? dist[i] : mx;
    m /= (double)nv;
    tmean += m;
    tmax = mx * 1e3 > tmax ? mx * 1e3 : tmax;
    pmean += rep.frames[f].mean_mm;
    secs[f] = rep.frames[f].seconds;
    if (getenv("KM_BENCH_JOINTS")) {
      int worst = 0;
      double we = 0;
      for (size_t j = 0; j < take.n_joints; ++j) {
        double d = 0;
        for (int a = 0; a < 3; ++a) {
          double x = rep.joints[(f * take.n_joints + j) * 3 + a] -
                     take.positions[(f * take.n_joints + j) * 3 + a];
          d += x * x;
        }
        if (sqrt(d) > we) we = sqrt(d), worst = (int)j;
      }
      printf("   worst joint %s %.1f mm\n", take.joint_names[worst], we * 1e3);
    }
    km_recon_frame_stats *s = &rep.frames[f];
    if (f < 10 || f % 25 == 0 || s->status)
      printf("%6zu %8zu %9.2f %9.2f %9.2f %6d %8.3f %s\n", s->index, s->points, s->mean_mm,
             s->max_mm, m * 1e3, s->iterations, s->seconds, km_status_name(s->status));
  }
  size_t nf = rep.n_frames < ri.frames ? rep.n_frames : ri.frames;
  tmean = 1e3 * tmean / (double)nf;
  pmean /= (double)nf;
  qsort(secs + 1, nf - 1, sizeof *secs, cmp_d); /* frame 0 (first-frame registration) apart */
  double med = secs[1 + (nf - 1) / 2];
  printf("\n%-22s %zu\n%-22s %zu (template %zu vertices, subject %zu)\n%-22s %.3f\n"
         "%-22s %.3f\n%-22s %.3f\n%-22s %.3f\n%-22s %.3f\n%-22s %.5f\n%-22s %.5f\n%-22s %zu\n"
         "%-22s %zu\n%-22s %.1f s (capture %.1f s)\n",
         "frames", nf, "points_frame0", npts0, nv, subj.mesh.n_vertices, "s_per_frame", med,
         "first_frame_s", rep.frames[0].seconds, "err_points_mm", pmean, "err_truth_mean_mm", tmean,
         "err_truth_max_mm", tmax, "jerk_before_mm", rep.jerk_before * 1e3, "jerk_after_mm",
         rep.jerk_after * 1e3, "features", nfeat, "failed_frames", rep.failed_frames, "total",
         total, tc);
  printf("{\"bench\":\"reconstruct\",\"frames\":%zu,\"s_per_frame\":%.4f,\"err_points_mm\":%.3f,"
         "\"err_truth_mean_mm\":%.3f,\"err_truth_max_mm\":%.3f,\"jerk_before\":%.6g,"
         "\"jerk_after\":%.6g,\"failed_frames\":%zu}\n",
         nf, med, pmean, tmean, tmax, rep.jerk_before, rep.jerk_after, rep.failed_frames);
  if (json && km_recon_report_write_json(json, &rep, &e)) die("json", &e);
  if (plot && km_recon_report_plot(plot, &rep, &e)) die("plot", &e);
  km__surface_free(&ts);
  free(tv), free(tri), free(dist), free(secs), free(rec), free(truth);
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
