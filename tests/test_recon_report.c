/* The reconstruction report's two-sided error (issue 13): points -> surface and surface ->
 * points against a brute-force computation written here (no Embree, no library geometry), and
 * a capture with one arm cut out of the clouds flagged "unsupported_surface" on exactly those
 * frames, naming the arm's joints. */
#include "km_test.h"
#include "synth/poses.h"

#include <unistd.h>

/* Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5): the
 * squared distance. Written out here so the check shares nothing with the library. */
static double tri_dist2(const double *p, const double *a, const double *b, const double *c) {
  double ab[3], ac[3], ap[3], q[3];
  for (int k = 0; k < 3; ++k)
    ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
  double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
  double v, w;
  if (d1 <= 0 && d2 <= 0) {
    memcpy(q, a, sizeof q);
    goto out;
  }
  double bp[3], cp[3];
  for (int k = 0; k < 3; ++k)
    bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
  double d3 = DOT(ab, bp), d4 = DOT(ac, bp);
  if (d3 >= 0 && d4 <= d3) {
    memcpy(q, b, sizeof q);
    goto out;
  }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    v = d1 / (d1 - d3);
    for (int k = 0; k < 3; ++k)
      q[k] = a[k] + v * ab[k];
    goto out;
  }
  double d5 = DOT(ab, cp), d6 = DOT(ac, cp);
  if (d6 >= 0 && d5 <= d6) {
    memcpy(q, c, sizeof q);
    goto out;
  }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    w = d2 / (d2 - d6);
    for (int k = 0; k < 3; ++k)
      q[k] = a[k] + w * ac[k];
    goto out;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    for (int k = 0; k < 3; ++k)
      q[k] = b[k] + w * (c[k] - b[k]);
    goto out;
  }
  {
    double den = 1 / (va + vb + vc);
    v = vb * den, w = vc * den;
    for (int k = 0; k < 3; ++k)
      q[k] = a[k] + ab[k] * v + ac[k] * w;
  }
out:;
  double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
  return DOT(d, d);
#undef DOT
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* nearest-rank quantile, by a full sort */
static double quantile_sorted(double *x, size_t n, double q) {
  qsort(x, n, sizeof *x, cmp_d);
  size_t k = (size_t)ceil(q * (double)n);
  return x[k ? k - 1 : 0];
}

/* The largest-weight skin joint of vertex i. */
static int32_t dominant(const km_skin *s, size_t i) {
  int best = 0;
  for (int k = 1; k < 4; ++k)
    if (s->joints[4 * i + k] >= 0 && s->weights[4 * i + k] > s->weights[4 * i + best]) best = k;
  return s->joints[4 * i + best];
}

static int32_t joint_index(const km_skeleton *s, const char *name) {
  for (size_t j = 0; j < s->n_joints; ++j)
    if (!strcmp(s->names[j], name)) return (int32_t)j;
  return -1;
}

/* A capture of subj performing `kind` (frames), into a fresh temporary directory. */
static void capture(const km_character *subj, km_motion_kind kind, size_t frames, size_t points,
                    char *dir, char ***paths, size_t *n, double **truth) {
  km_take take = {0};
  CHECK_OK(km_motion_generate(&subj->skeleton, kind, frames, &take, KM_E));
  strcpy(dir, "/tmp/km_test_recon_report_XXXXXX");
  CHECK(mkdtemp(dir) != NULL);
  km_capture_options co = {.cameras = 8, .points_per_frame = points, .noise_mm = 1, .seed = 5};
  CHECK_OK(km_capture_simulate(subj, &take, &co, dir, KM_E));
  CHECK_OK(km_point_frames_list(dir, paths, n, KM_E));
  CHECK(*n == frames);
  char tp[300];
  snprintf(tp, sizeof tp, "%s/truth.pc2", dir);
  km_anim_info ti;
  *truth = NULL;
  CHECK_OK(km_pc2_read(tp, truth, &ti, KM_E));
  km_take_free(&take);
}

/* The simulator's camera ring (km_capture_options defaults but 8 cameras: 3 m from the
 * centre of the subject's bounding box, 0.3 m above it), placed around frame 0's points. */
static void ring_cameras(const char *frame0, int nc, double *cams) {
  km_points p = {0};
  CHECK_OK(km_points_read(frame0, &p, KM_E));
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < p.n; ++i)
    for (int a = 0; a < 3; ++a)
      lo[a] = fmin(lo[a], p.P[3 * i + a]), hi[a] = fmax(hi[a], p.P[3 * i + a]);
  for (int c = 0; c < nc; ++c) {
    double ang = 2 * M_PI * (c + 0.5) / nc;
    cams[3 * c] = (lo[0] + hi[0]) / 2 + 3 * sin(ang);
    cams[3 * c + 1] = (lo[1] + hi[1]) / 2 + 0.3;
    cams[3 * c + 2] = (lo[2] + hi[2]) / 2 + 3 * cos(ang);
  }
  km_points_free(&p);
}

static void remove_dir(const char *dir) {
  char cmd[400];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  CHECK(system(cmd) == 0);
}

/* The frame statistics against brute force: every point to every triangle, every vertex to
 * every point. A small unsupported threshold (4 mm) so that the vertex set is not empty. */
static void test_two_sided_brute_force(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 2000, .seed = 7, .girth = 1.05};
  km_character_options to = {.target_vertices = 2000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  char dir[64], **paths = NULL;
  size_t n = 0;
  double *truth = NULL;
  capture(&subj, KM_MOTION_WAVE, 3, 5000, dir, &paths, &n, &truth);
  km_recon_options o = {.coarse_points = 800, .unsupported_distance = 0.004};
  km_recon *r = NULL;
  CHECK_OK(km_recon_create(&tmpl, &o, &r, KM_E));
  size_t nv = tmpl.mesh.n_vertices, nf = tmpl.mesh.n_faces;
  for (size_t f = 0; r && f < n; ++f) {
    km_points pts = {0};
    CHECK_OK(km_points_read(paths[f], &pts, KM_E));
    km_recon_frame_stats st = {0};
    if (f == 0)
      CHECK_OK(km_recon_first_frame(r, pts.P, pts.n, NULL, 0, &st, KM_E));
    else
      CHECK_OK(km_recon_next_frame(r, pts.P, pts.n, &st, KM_E));
    const double *X = km_recon_surface(r);
    /* points -> surface */
    double *dp = malloc(pts.n * sizeof *dp), mean = 0, mx = 0;
    for (size_t i = 0; i < pts.n; ++i) {
      double best = INFINITY;
      for (size_t t = 0; t < nf; ++t) {
        const int32_t *F = tmpl.mesh.F + 3 * t;
        double d2 = tri_dist2(pts.P + 3 * i, X + 3 * (size_t)F[0], X + 3 * (size_t)F[1],
                              X + 3 * (size_t)F[2]);
        best = d2 < best ? d2 : best;
      }
      dp[i] = 1e3 * sqrt(best);
      mean += dp[i] / (double)pts.n, mx = fmax(mx, dp[i]);
    }
    double p95 = quantile_sorted(dp, pts.n, 0.95);
    /* surface -> points, all vertices (no cameras given) */
    double *dv = malloc(nv * sizeof *dv), smean = 0, smax = 0;
    size_t unsup = 0;
    for (size_t v = 0; v < nv; ++v) {
      double best = INFINITY;
      for (size_t i = 0; i < pts.n; ++i) {
        double d2 = 0;
        for (int a = 0; a < 3; ++a)
          d2 += (X[3 * v + a] - pts.P[3 * i + a]) * (X[3 * v + a] - pts.P[3 * i + a]);
        best = d2 < best ? d2 : best;
      }
      dv[v] = 1e3 * sqrt(best);
      smean += dv[v] / (double)nv, smax = fmax(smax, dv[v]);
      if (dv[v] > 4) ++unsup;
    }
    double *dq = malloc(nv * sizeof *dq); /* the quantile sorts its input: a copy */
    memcpy(dq, dv, nv * sizeof *dq);
    double sp95 = quantile_sorted(dq, nv, 0.95), sp99 = quantile_sorted(dq, nv, 0.99);
    free(dq);
    printf("frame %zu: points->surface %.3f/%.3f/%.3f mm (brute %.3f/%.3f/%.3f), "
           "surface->points %.3f/%.3f/%.3f mm (brute %.3f/%.3f/%.3f), beyond 4 mm %zu (brute "
           "%zu)\n",
           f, st.mean_mm, st.p95_mm, st.max_mm, mean, p95, mx, st.surface_mean_mm,
           st.surface_p95_mm, st.surface_max_mm, smean, sp95, smax, st.unsupported_vertices, unsup);
    /* Embree's queries run in single precision: agreement to a micrometre */
    CHECK_NEAR(st.mean_mm, mean, 1e-3);
    CHECK_NEAR(st.p95_mm, p95, 1e-3);
    CHECK_NEAR(st.max_mm, mx, 1e-3);
    CHECK(st.surface_vertices == nv);
    CHECK_NEAR(st.surface_mean_mm, smean, 1e-3);
    CHECK_NEAR(st.surface_p95_mm, sp95, 1e-3);
    CHECK_NEAR(st.surface_p99_mm, sp99, 1e-3);
    CHECK(sp99 >= sp95 && sp99 <= smax);
    CHECK_NEAR(st.surface_max_mm, smax, 1e-3);
    CHECK_MSG(unsup > 0, "frame %zu: the 4 mm threshold leaves some vertices unsupported", f);
    CHECK_MSG(st.unsupported_vertices + 2 >= unsup && unsup + 2 >= st.unsupported_vertices,
              "frame %zu: %zu unsupported, brute force %zu", f, st.unsupported_vertices, unsup);
    size_t cnt = 0, wrong = 0;
    const int32_t *ids = km_recon_unsupported(r, &cnt);
    CHECK(cnt == st.unsupported_vertices && (ids || !cnt));
    for (size_t k = 0; ids && k < cnt; ++k)
      if (ids[k] < 0 || (size_t)ids[k] >= nv || !(dv[ids[k]] > 4 - 1e-3)) ++wrong;
    CHECK_MSG(wrong == 0, "frame %zu: %zu listed vertices are within 4 mm of a point", f, wrong);
    CHECK(st.unsupported == ((double)st.unsupported_vertices > 0.02 * (double)nv));
    free(dp), free(dv);
    km_points_free(&pts);
  }
  km_recon_free(&r);
  free(truth);
  km_paths_free(&paths, n);
  remove_dir(dir);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

/* The left arm cut out of frames 4..23 (20 frames, as issue 13 asks: every point within 5 cm
 * of the subject's true left arm removed, as an occluder would): exactly those frames are
 * flagged and name the arm, and the frames after are recovered (not flagged). */
static void test_occluded_arm(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 3000, .seed = 7, .girth = 1.05};
  km_character_options to = {.target_vertices = 2000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  enum { NF = 28, CUT0 = 4, CUT1 = 23 };
  char dir[64], **paths = NULL;
  size_t n = 0;
  double *truth = NULL;
  capture(&subj, KM_MOTION_WAVE, NF, 12000, dir, &paths, &n, &truth);
  const char *arm[] = {"ElbowLeft", "WristLeft", "HandLeft"};
  int32_t arm_j[3];
  for (int k = 0; k < 3; ++k) {
    arm_j[k] = joint_index(&subj.skeleton, arm[k]);
    CHECK_MSG(arm_j[k] >= 0, "subject has no joint %s", arm[k]);
  }
  size_t sv = subj.mesh.n_vertices;
  for (size_t f = CUT0; truth && f <= CUT1 && f < n; ++f) {
    km_points pts = {0};
    CHECK_OK(km_points_read(paths[f], &pts, KM_E));
    const double *T = truth + f * sv * 3;
    size_t kept = 0;
    for (size_t i = 0; i < pts.n; ++i) {
      bool cut = false;
      for (size_t v = 0; v < sv && !cut; ++v) {
        int32_t j = dominant(&subj.skin, v);
        if (j != arm_j[0] && j != arm_j[1] && j != arm_j[2]) continue;
        double d2 = 0;
        for (int a = 0; a < 3; ++a)
          d2 += (pts.P[3 * i + a] - T[3 * v + a]) * (pts.P[3 * i + a] - T[3 * v + a]);
        cut = d2 < 0.05 * 0.05;
      }
      if (!cut) memmove(pts.P + 3 * kept++, pts.P + 3 * i, 3 * sizeof(double));
    }
    printf("frame %zu: %zu of %zu points cut with the left arm\n", f, pts.n - kept, pts.n);
    CHECK(kept < pts.n && kept > pts.n / 2);
    CHECK_OK(km_points_write_ply(paths[f], pts.P, kept, KM_E));
    km_points_free(&pts);
  }
  char out[300], json[300];
  snprintf(out, sizeof out, "%s/out.pc2", dir);
  snprintf(json, sizeof json, "%s/report.json", dir);
  km_recon_report rep = {0};
  /* Visibility known: the ring cameras see no sole (its normal faces down, the cameras are
   * above it); with every vertex measured the soles of this template alone are ~2% of it. */
  double cams[8 * 3];
  ring_cameras(paths[0], 8, cams);
  km_recon_options o = {.coarse_points = 1000, .cameras = cams, .n_cameras = 8};
  CHECK_OK(km_reconstruct((const char *const *)paths, n, &tmpl, NULL, 0, &o, out, &rep, KM_E));
  CHECK(rep.n_frames == NF && rep.visibility_known);
  CHECK_NEAR(rep.unsupported_distance_mm, 30, 1e-9);
  CHECK(rep.unsupported_frames == CUT1 - CUT0 + 1);
  for (size_t f = 0; f < rep.n_frames; ++f) {
    const km_recon_frame_stats *s = &rep.frames[f];
    bool cut = f >= CUT0 && f <= CUT1;
    char parts[300] = "";
    bool names_arm = false, names_other = false;
    for (int k = 0; k < s->n_unsupported_joints; ++k) {
      const char *nm = rep.joint_names[s->unsupported_joints[k]];
      size_t len = strlen(parts);
      snprintf(parts + len, sizeof parts - len, " %s", nm);
      bool is_arm = strstr(nm, "Left") && (strstr(nm, "Elbow") || strstr(nm, "Wrist") ||
                                           strstr(nm, "Hand") || strstr(nm, "Shoulder"));
      names_arm |= is_arm;
      names_other |= !is_arm;
    }
    printf("frame %zu: %s, points->surface %.2f mm, surface->points mean %.2f p95 %.1f max %.1f "
           "mm, %zu of %zu unsupported:%s\n",
           f, km_recon_frame_status(s), s->mean_mm, s->surface_mean_mm, s->surface_p95_mm,
           s->surface_max_mm, s->unsupported_vertices, s->surface_vertices, parts);
    CHECK_MSG(s->unsupported == cut, "frame %zu: flagged %d, arm cut %d", f, s->unsupported, cut);
    CHECK(!strcmp(km_recon_frame_status(s), cut ? "unsupported_surface" : "KM_OK"));
    if (cut) {
      CHECK_MSG(names_arm && !names_other, "frame %zu names%s", f, parts);
      CHECK(rep.unsupported && rep.unsupported[f]);
      /* the hidden hand stays where it was carried: 95-350 mm from every point over the 20
       * frames (the waving arm comes near the head late in the take) */
      CHECK_MSG(s->surface_max_mm > 60, "frame %zu: the hand %.0f mm from every point", f,
                s->surface_max_mm);
    }
  }
  /* the JSON says so */
  CHECK_OK(km_recon_report_write_json(json, &rep, KM_E));
  FILE *fp = fopen(json, "rb");
  CHECK(fp != NULL);
  if (fp) {
    static char text[1 << 22];
    size_t got = fread(text, 1, sizeof text - 1, fp);
    text[got] = '\0';
    fclose(fp);
    size_t flagged = 0;
    for (const char *q = text; (q = strstr(q, "\"unsupported_surface\"")); ++q)
      ++flagged;
    CHECK_MSG(flagged == CUT1 - CUT0 + 1, "%zu frames flagged in the JSON", flagged);
    CHECK(strstr(text, "\"surface_to_points\":\t\"vertices facing a camera\"") ||
          strstr(text, "\"surface_to_points\": \"vertices facing a camera\""));
    CHECK(strstr(text, "\"ElbowLeft\"") || strstr(text, "\"WristLeft\"") ||
          strstr(text, "\"HandLeft\""));
  }
  km_recon_report_free(&rep);
  free(truth);
  km_paths_free(&paths, n);
  remove_dir(dir);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

/* Limbs found, not assumed: the first frame is mid-kick (guard up, one knee raised) while the
 * template stands with arms out. Without the limb search both arms and the raised leg stayed
 * where the local fit left them (measured on the 4000-vertex template: 25-29% of the surface
 * unsupported on every frame, up to 689 mm); with it no frame after the first is flagged
 * (the first: the raised foot, 3.6%). With a 2000-vertex template the limbs are found too
 * but the head and neck stay bent (15% unsupported, flagged): not asserted here. */
static void test_limbs_found(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 4000, .seed = 7, .girth = 1.05};
  km_character_options to = {.target_vertices = 4000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  enum { SKIP = 40, NF = 5 };
  char dir[64], **paths = NULL;
  size_t n = 0;
  double *truth = NULL;
  capture(&subj, KM_MOTION_KUNGFU, SKIP + NF, 24000, dir, &paths, &n, &truth);
  if (getenv("KM_TEST_KEEP")) printf("capture in %s\n", dir);
  km_anim_info ti = {0};
  {
    char tp[300];
    snprintf(tp, sizeof tp, "%s/truth.pc2", dir);
    CHECK_OK(km_anim_info_read(tp, &ti, KM_E));
  }
  char out[300];
  snprintf(out, sizeof out, "%s/out.pc2", dir);
  for (int pass = 0; pass < 2 && n == SKIP + NF; ++pass) {
    km_recon_report rep = {0};
    km_recon_options o = {.no_limb_search = pass == 0};
    CHECK_OK(
        km_reconstruct((const char *const *)paths + SKIP, NF, &tmpl, NULL, 0, &o, out, &rep, KM_E));
    size_t flagged_after_first = 0;
    for (size_t f = 0; f < rep.n_frames; ++f) {
      const km_recon_frame_stats *s = &rep.frames[f];
      printf("%s, frame %zu: %s, points->surface %.2f mm, surface->points mean %.2f max %.0f "
             "mm, %zu unsupported (%s %s)\n",
             pass ? "limb search" : "no limb search", f, km_recon_frame_status(s), s->mean_mm,
             s->surface_mean_mm, s->surface_max_mm, s->unsupported_vertices,
             s->n_unsupported_joints > 0 ? rep.joint_names[s->unsupported_joints[0]] : "",
             s->n_unsupported_joints > 1 ? rep.joint_names[s->unsupported_joints[1]] : "");
      flagged_after_first += f > 0 && s->unsupported;
    }
    if (pass == 0) {
      CHECK_MSG(rep.unsupported_frames >= NF - 1, "without the search %zu frames flagged",
                rep.unsupported_frames);
    } else {
      CHECK_MSG(rep.init.limbs_turned >= 2, "%zu joints turned", rep.init.limbs_turned);
      CHECK_MSG(flagged_after_first == 0, "%zu frames after the first flagged",
                flagged_after_first);
      for (size_t f = 1; f < rep.n_frames; ++f)
        CHECK_MSG(rep.frames[f].mean_mm < 5, "frame %zu: %.2f mm", f, rep.frames[f].mean_mm);
    }
    km_recon_report_free(&rep);
  }
  free(truth);
  km_paths_free(&paths, n);
  if (!getenv("KM_TEST_KEEP")) remove_dir(dir);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

/* Mean distance (m) of the vertices V (nv) to the true surface T (the subject's faces F, nf),
 * brute force: every vertex to every triangle. */
static double mean_to_truth(const double *V, size_t nv, const double *T, const int32_t *F,
                            size_t nf, double *max_out) {
  double sum = 0, mx = 0;
  for (size_t i = 0; i < nv; ++i) {
    double best = INFINITY;
    for (size_t f = 0; f < nf; ++f) {
      const int32_t *t = F + 3 * f;
      double d2 =
          tri_dist2(V + 3 * i, T + 3 * (size_t)t[0], T + 3 * (size_t)t[1], T + 3 * (size_t)t[2]);
      if (d2 < best) best = d2;
    }
    sum += sqrt(best);
    mx = fmax(mx, sqrt(best));
  }
  if (max_out) *max_out = mx;
  return sum / (double)(nv ? nv : 1);
}

/* Reconstructs the nf frames paths[0..nf) (no correspondences, default options) into dir/out.pc2
 * with the template tmpl and checks every frame against the true surface (truth: the subject's
 * vertices per frame from paths[0] on, its faces subj->mesh.F): <= 5 mm mean (brute force) and
 * not flagged. label names the case in the printed lines. */
static void check_recovered(const char *label, const char *dir, char *const *paths, size_t nf,
                            const km_character *tmpl, const km_character *subj,
                            const double *truth) {
  char out[300];
  snprintf(out, sizeof out, "%s/out.pc2", dir);
  km_recon_report rep = {0};
  km_recon_options o = {0};
  CHECK_OK(km_reconstruct((const char *const *)paths, nf, tmpl, NULL, 0, &o, out, &rep, KM_E));
  double *R = NULL;
  km_anim_info ri = {0};
  CHECK_OK(km_pc2_read(out, &R, &ri, KM_E));
  CHECK(R && ri.frames == nf && ri.vertices == tmpl->mesh.n_vertices);
  for (size_t f = 0; R && f < rep.n_frames && f < ri.frames; ++f) {
    const km_recon_frame_stats *s = &rep.frames[f];
    double mx = 0;
    double m =
        mean_to_truth(R + f * ri.vertices * 3, ri.vertices, truth + f * subj->mesh.n_vertices * 3,
                      subj->mesh.F, subj->mesh.n_faces, &mx);
    printf("%s, frame %zu: %s, to the truth mean %.2f max %.1f mm; points->surface %.2f mm, "
           "surface->points max %.1f mm, %zu unsupported (limbs turned %zu, scaled %zu)\n",
           label, f, km_recon_frame_status(s), m * 1e3, mx * 1e3, s->mean_mm, s->surface_max_mm,
           s->unsupported_vertices, rep.init.limbs_turned, rep.init.limbs_scaled);
    CHECK_MSG(m <= 0.005, "%s, frame %zu: %.2f mm mean to the truth", label, f, m * 1e3);
    CHECK_MSG(!s->unsupported, "%s, frame %zu flagged", label, f);
  }
  free(R);
  km_recon_report_free(&rep);
}

/* Arms down against a template with arms out (issue 13): the subject walks (arms hanging,
 * 78 degrees down, swinging), the template stands in its T-pose and is longer in the arm
 * (another seed, another girth). Without correspondences, every frame is recovered to <= 5 mm
 * mean to the true surface (brute force here) and none is flagged. */
static void test_arms_down(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 3000, .seed = 7, .girth = 1.05, .height = 1.72};
  km_character_options to = {.target_vertices = 4000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  enum { SKIP = 30, NF = 4 };
  char dir[64], **paths = NULL;
  size_t n = 0;
  double *truth = NULL;
  capture(&subj, KM_MOTION_WALK, SKIP + NF, 24000, dir, &paths, &n, &truth);
  if (n == SKIP + NF && truth)
    check_recovered("arms down", dir, paths + SKIP, NF, &tmpl, &subj,
                    truth + SKIP * subj.mesh.n_vertices * 3);
  free(truth);
  km_paths_free(&paths, n);
  remove_dir(dir);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

/* The reverse (issue 13): the template stands with its arms DOWN (the procedural template
 * posed 75 degrees down at both shoulders, its rest skeleton posed with it) and the subject
 * holds them OUT (the walk take's first frames are its T-pose). Without correspondences every
 * frame is recovered to <= 5 mm mean to the true surface and none is flagged. */
static void test_template_arms_down(void) {
  km_character subj = {0}, tmpl = {0};
  km_character_options so = {.target_vertices = 3000, .seed = 7, .girth = 1.05, .height = 1.72};
  km_character_options to = {.target_vertices = 4000, .seed = 1};
  CHECK_OK(km_character_generate(&so, &subj, KM_E));
  CHECK_OK(km_character_generate(&to, &tmpl, KM_E));
  const kp_pose down = {"arms_down", {{KP_SHL, 2, -75}, {KP_SHR, 2, 75}}, 2};
  double T[KM_KINECT1_JOINTS * 12], PJ[KM_KINECT1_JOINTS * 3];
  size_t tv = tmpl.mesh.n_vertices;
  double *V = malloc(tv * 3 * sizeof *V);
  kp_transforms(&tmpl.skeleton, &down, NULL, T, PJ);
  CHECK_OK(km_lbs(tmpl.mesh.V, tv, &tmpl.skin, T, tmpl.skeleton.n_joints, V, KM_E));
  /* the left hand now hangs below the shoulder, not beside it */
  int32_t hl = joint_index(&tmpl.skeleton, "HandLeft"),
          sl = joint_index(&tmpl.skeleton, "ShoulderLeft");
  CHECK(hl >= 0 && sl >= 0 && PJ[3 * hl + 1] < PJ[3 * sl + 1] - 0.3);
  memcpy(tmpl.mesh.V, V, tv * 3 * sizeof *V);
  memcpy(tmpl.skeleton.rest, PJ, tmpl.skeleton.n_joints * 3 * sizeof(double));
  free(V);
  enum { NF = 4 };
  char dir[64], **paths = NULL;
  size_t n = 0;
  double *truth = NULL;
  capture(&subj, KM_MOTION_WALK, NF, 24000, dir, &paths, &n, &truth);
  if (n == NF && truth)
    check_recovered("template arms down, capture arms out", dir, paths, NF, &tmpl, &subj, truth);
  free(truth);
  km_paths_free(&paths, n);
  remove_dir(dir);
  km_character_free(&subj);
  km_character_free(&tmpl);
}

int main(void) {
  test_two_sided_brute_force();
  test_occluded_arm();
  test_limbs_found();
  test_arms_down();
  test_template_arms_down();
  return km_test_finish("test_recon_report");
}
