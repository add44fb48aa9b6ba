/* reconstruct --segment-frames (issue 17): see recon_segments.h. A segment is tracked into a
 * part (in memory, or written to a file for another process to stitch); the stitch adds the
 * parts in order. */
#include "recon_segments.h"
#include "cli.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One tracked segment: frames [a, b) are its own, [b, e) its overlap into the next. */
typedef struct part {
  size_t k, a, b, e;
  double seconds;
  km_recon_init init;       /* segment 0's first frame (the report's "first_frame") */
  km_recon_frame_stats *st; /* b - a */
  double *joints;           /* (b - a) * nj * 3 */
  double *ref, *glob;       /* (e - a) * nv * 3: refined and LBS-only surfaces */
} part;

static void part_free(part *p) {
  free(p->st);
  free(p->joints);
  free(p->ref);
  free(p->glob);
  memset(p, 0, sizeof *p);
}

size_t km_cli_segment_count(size_t n, size_t seg) { return seg ? (n + seg - 1) / seg : 1; }

static void segment_range(size_t n, size_t seg, size_t overlap, size_t k, part *p) {
  p->k = k;
  p->a = k * seg;
  p->b = p->a + seg < n ? p->a + seg : n;
  p->e = p->b + overlap < n ? p->b + overlap : n;
}

static km_status track(char **paths, size_t n, const km_character *c, const km_recon_feature *feat,
                       size_t nfeat, const km_recon_options *ro, const km_cli_segments *sg,
                       size_t k, part *p, km_error *err) {
  const size_t nv = c->mesh.n_vertices, nj = c->skeleton.n_joints, stride = nv * 3;
  segment_range(n, sg->frames, sg->overlap, k, p);
  const size_t own = p->b - p->a, all = p->e - p->a;
  p->st = calloc(own, sizeof *p->st);
  p->joints = malloc(sizeof *p->joints * (own * nj * 3 + 1));
  p->ref = malloc(sizeof *p->ref * all * stride);
  p->glob = malloc(sizeof *p->glob * all * stride);
  if (!p->st || !p->joints || !p->ref || !p->glob)
    return km_error_set(err, KM_ERR_NOMEM, "reconstruct: out of memory (segment of %zu frames)",
                        all);
  km_recon *r = NULL;
  km_points pts = {0};
  double t0 = km_cli_now();
  km_status s = km_recon_create(c, ro, &r, err);
  for (size_t f = p->a; f < p->e && !s; ++f) {
    km_recon_frame_stats st = {0};
    km_points_free(&pts);
    if ((s = km_points_read(paths[f], &pts, err)) ||
        (ro->points_frame && (s = km_frame_apply(ro->points_frame, pts.P, pts.n, NULL, 0, err))))
      break;
    s = f == p->a ? km_recon_first_frame(r, pts.P, pts.n, k == 0 ? feat : NULL, k == 0 ? nfeat : 0,
                                         &st, err)
                  : km_recon_next_frame(r, pts.P, pts.n, &st, err);
    if (s) break;
    if (f == p->a) km_recon_init_get(r, &p->init);
    memcpy(p->ref + (f - p->a) * stride, km_recon_surface(r), sizeof(double) * stride);
    memcpy(p->glob + (f - p->a) * stride, km_recon_global(r), sizeof(double) * stride);
    if (f < p->b) {
      st.index = f;
      st.dropped = pts.dropped_nan + pts.dropped_zero;
      p->st[f - p->a] = st;
      memcpy(p->joints + (f - p->a) * nj * 3, km_recon_joints(r), sizeof(double) * nj * 3);
    }
    if (ro->progress.fn &&
        !ro->progress.fn((double)(f + 1) / (double)n, "segments", ro->progress.user))
      s = km_error_set(err, KM_ERR_CANCELLED, "reconstruct: cancelled");
  }
  km_points_free(&pts);
  km_recon_free(&r);
  p->seconds = km_cli_now() - t0;
  if (!s) {
    double mm = 0;
    for (size_t i = 0; i < own; ++i)
      mm += p->st[i].mean_mm / (double)own;
    km_cli_progress_done();
    fprintf(stderr,
            "kinemesh reconstruct: segment %zu/%zu: frames %zu-%zu (+%zu overlap), %.2f s, mean "
            "point error %.2f mm\n",
            k + 1, km_cli_segment_count(n, sg->frames), p->a, p->b - 1, p->e - p->b, p->seconds,
            mm);
  }
  return s;
}

/* ---- the part file: a header of sizes (checked against the stitch's), then the arrays as
 * this machine's doubles and structs: the parts of one take are written and read by the same
 * kinemesh build (a batch runs one binary everywhere). */

static const char PART_MAGIC[8] = "KMSEG01\n";
enum { H_N, H_NV, H_NJ, H_SEG, H_OVERLAP, H_K, H_A, H_B, H_E, H_STATS, H_COUNT };

char *km_cli_segment_part_path(const char *dir, size_t k) {
  size_t len = strlen(dir) + 40;
  char *s = malloc(len);
  if (s) snprintf(s, len, "%s/segment-%04zu.kmseg", dir, k);
  return s;
}

static km_status part_write(const char *dir, size_t n, size_t nv, size_t nj,
                            const km_cli_segments *sg, const part *p, km_error *err) {
  const size_t own = p->b - p->a, all = p->e - p->a;
  const size_t sizes[] = {sizeof PART_MAGIC,
                          sizeof(uint64_t) * H_COUNT,
                          sizeof p->seconds,
                          sizeof p->init,
                          sizeof *p->st * own,
                          sizeof *p->joints * own * nj * 3,
                          sizeof *p->ref * all * nv * 3,
                          sizeof *p->glob * all * nv * 3};
  const uint64_t h[H_COUNT] = {n,    nv,   nj,   sg->frames, sg->overlap,
                               p->k, p->a, p->b, p->e,       sizeof *p->st};
  const void *src[] = {PART_MAGIC, h, &p->seconds, &p->init, p->st, p->joints, p->ref, p->glob};
  size_t total = 0;
  for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; ++i)
    total += sizes[i];
  char *buf = malloc(total), *path = km_cli_segment_part_path(dir, p->k);
  km_status s = KM_OK;
  if (!buf || !path) {
    s = km_error_set(err, KM_ERR_NOMEM, "reconstruct: out of memory (%zu bytes)", total);
  } else {
    size_t at = 0;
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; ++i)
      memcpy(buf + at, src[i], sizes[i]), at += sizes[i];
    s = km_write_file_atomic(path, buf, total, err);
  }
  if (!s)
    fprintf(stderr, "kinemesh reconstruct: segment %zu written to %s (%zu bytes)\n", p->k, path,
            total);
  free(buf);
  free(path);
  return s;
}

static km_status part_read(const char *dir, size_t n, size_t nv, size_t nj,
                           const km_cli_segments *sg, size_t k, part *p, km_error *err) {
  char *path = km_cli_segment_part_path(dir, k);
  if (!path) return km_error_set(err, KM_ERR_NOMEM, "out of memory");
  segment_range(n, sg->frames, sg->overlap, k, p);
  const size_t own = p->b - p->a, all = p->e - p->a;
  const uint64_t want[H_COUNT] = {n, nv,   nj,   sg->frames, sg->overlap,
                                  k, p->a, p->b, p->e,       sizeof *p->st};
  static const char *const names[H_COUNT] = {
      "frames",  "vertices",    "joints",    "segment frames", "overlap",
      "segment", "first frame", "end frame", "overlap end",    "statistics record size"};
  FILE *f = fopen(path, "rb");
  km_status s = KM_OK;
  char magic[8];
  uint64_t h[H_COUNT];
  if (!f) {
    s = km_error_set(err, KM_ERR_IO,
                     "%s: cannot open (segment %zu not tracked yet? run the same command with "
                     "--segment %zu --segment-dir %s)",
                     path, k, k, dir);
    goto out;
  }
  if (fread(magic, 1, 8, f) != 8 || memcmp(magic, PART_MAGIC, 8)) {
    s = km_error_set(err, KM_ERR_PARSE, "%s: byte 0: not a kinemesh segment part (KMSEG01)", path);
    goto out;
  }
  if (fread(h, sizeof *h, H_COUNT, f) != H_COUNT) {
    s = km_error_set(err, KM_ERR_PARSE, "%s: byte 8: truncated header", path);
    goto out;
  }
  for (int i = 0; i < H_COUNT; ++i)
    if (h[i] != want[i]) {
      s = km_error_set(err, KM_ERR_INVALID,
                       "%s: byte %zu: %s %llu, this stitch expects %llu (a part of another "
                       "take or other options)",
                       path, 8 + sizeof *h * (size_t)i, names[i], (unsigned long long)h[i],
                       (unsigned long long)want[i]);
      goto out;
    }
  p->st = calloc(own, sizeof *p->st);
  p->joints = malloc(sizeof *p->joints * (own * nj * 3 + 1));
  p->ref = malloc(sizeof *p->ref * all * nv * 3);
  p->glob = malloc(sizeof *p->glob * all * nv * 3);
  if (!p->st || !p->joints || !p->ref || !p->glob) {
    s = km_error_set(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto out;
  }
  if (fread(&p->seconds, sizeof p->seconds, 1, f) != 1 ||
      fread(&p->init, sizeof p->init, 1, f) != 1 || fread(p->st, sizeof *p->st, own, f) != own ||
      fread(p->joints, sizeof *p->joints, own * nj * 3, f) != own * nj * 3 ||
      fread(p->ref, sizeof *p->ref, all * nv * 3, f) != all * nv * 3 ||
      fread(p->glob, sizeof *p->glob, all * nv * 3, f) != all * nv * 3) {
    s = km_error_set(err, KM_ERR_PARSE, "%s: byte %ld: truncated", path, ftell(f));
    goto out;
  }
  if (fgetc(f) != EOF)
    s = km_error_set(err, KM_ERR_PARSE, "%s: byte %ld: data after the part's end", path,
                     ftell(f) - 1);
out:
  if (f) fclose(f);
  free(path);
  return s;
}

/* ---- the stitch */

typedef struct stitch {
  size_t nv, nj;
  double *ref, *glob;   /* n frames */
  double *tref, *tglob; /* the previous part's overlap frames */
  size_t tail;          /* how many */
  km_recon_report *rep;
} stitch;

/* Adds part p (parts in order): its own frames, the first `tail` of them cross-faded from the
 * previous part's overlap. */
static void stitch_add(stitch *s, const part *p) {
  const size_t stride = s->nv * 3;
  for (size_t f = p->a; f < p->b; ++f) {
    const double *sv = p->ref + (f - p->a) * stride, *gv = p->glob + (f - p->a) * stride;
    double *dr = s->ref + f * stride, *dg = s->glob + f * stride;
    if (f - p->a < s->tail) {
      const double w = (double)(f - p->a + 1) / (double)(s->tail + 1);
      const double *pr = s->tref + (f - p->a) * stride, *pg = s->tglob + (f - p->a) * stride;
      for (size_t i = 0; i < stride; ++i) {
        dr[i] = (1 - w) * pr[i] + w * sv[i];
        dg[i] = (1 - w) * pg[i] + w * gv[i];
      }
    } else {
      memcpy(dr, sv, sizeof *sv * stride);
      memcpy(dg, gv, sizeof *gv * stride);
    }
    km_recon_frame_stats *st = &s->rep->frames[f];
    *st = p->st[f - p->a];
    if (st->status) ++s->rep->failed_frames;
    if (km_recon_frame_status(st)[0] == 'u') ++s->rep->unsupported_frames;
  }
  memcpy(s->rep->joints + p->a * s->nj * 3, p->joints, sizeof(double) * (p->b - p->a) * s->nj * 3);
  if (p->k == 0) s->rep->init = p->init;
  s->tail = p->e - p->b;
  memcpy(s->tref, p->ref + (p->b - p->a) * stride, sizeof(double) * s->tail * stride);
  memcpy(s->tglob, p->glob + (p->b - p->a) * stride, sizeof(double) * s->tail * stride);
}

static double jerk(const double *X, size_t n, size_t nv) {
  double acc = 0;
  for (size_t f = 2; f < n; ++f) {
    const double *x = X + f * nv * 3, *x1 = x - nv * 3, *x2 = x1 - nv * 3;
    double sum = 0;
    for (size_t i = 0; i < nv; ++i) {
      double d2 = 0;
      for (int a = 0; a < 3; ++a) {
        double d = x[3 * i + a] - 2 * x1[3 * i + a] + x2[3 * i + a];
        d2 += d * d;
      }
      sum += sqrt(d2);
    }
    acc += sum / (double)nv;
  }
  return n > 2 ? acc / (double)(n - 2) : 0;
}

km_status km_cli_reconstruct_segmented(char **paths, size_t n, const km_character *c,
                                       const km_recon_feature *feat, size_t nfeat,
                                       const km_recon_options *ro, const km_cli_segments *sg,
                                       const char *out, km_recon_report *rep, km_error *err) {
  const size_t nv = c->mesh.n_vertices, nj = c->skeleton.n_joints, stride = nv * 3;
  const size_t nseg = km_cli_segment_count(n, sg->frames);
  part p = {0};
  km_status s = KM_OK;
  if (sg->only >= 0) { /* one segment, into its part file */
    if ((size_t)sg->only >= nseg)
      return km_error_set(err, KM_ERR_INVALID,
                          "reconstruct: --segment %ld: the take has %zu segments (0-%zu)", sg->only,
                          nseg, nseg - 1);
    s = track(paths, n, c, feat, nfeat, ro, sg, (size_t)sg->only, &p, err);
    if (!s) s = part_write(sg->dir, n, nv, nj, sg, &p, err);
    part_free(&p);
    return s;
  }
  memset(rep, 0, sizeof *rep);
  stitch st = {.nv = nv, .nj = nj, .rep = rep};
  st.ref = malloc(sizeof(double) * stride * n);
  st.glob = malloc(sizeof(double) * stride * n);
  st.tref = malloc(sizeof(double) * stride * (sg->overlap + 1));
  st.tglob = malloc(sizeof(double) * stride * (sg->overlap + 1));
  rep->frames = calloc(n, sizeof *rep->frames);
  rep->joints = malloc(sizeof *rep->joints * (n * nj * 3 + 1));
  rep->joint_names = calloc(nj + 1, sizeof *rep->joint_names);
  if (!st.ref || !st.glob || !st.tref || !st.tglob || !rep->frames || !rep->joints ||
      !rep->joint_names) {
    s = km_error_set(err, KM_ERR_NOMEM, "reconstruct: out of memory (%zu frames of %zu vertices)",
                     n, nv);
    goto done;
  }
  rep->n_joints = nj;
  for (size_t j = 0; j < nj; ++j)
    rep->joint_names[j] =
        strdup(c->skeleton.names && c->skeleton.names[j] ? c->skeleton.names[j] : "");
  rep->correspondences = nfeat;
  rep->rig_joints = ro->rig_joints;
  rep->visibility_known = ro->cameras && ro->n_cameras;
  rep->unsupported_distance_mm =
      1e3 * (ro->unsupported_distance > 0 ? ro->unsupported_distance : 0.03);
  rep->unsupported_fraction = ro->unsupported_fraction > 0 ? ro->unsupported_fraction : 0.02;
  for (size_t k = 0; k < nseg && !s; ++k) {
    s = sg->dir ? part_read(sg->dir, n, nv, nj, sg, k, &p, err)
                : track(paths, n, c, feat, nfeat, ro, sg, k, &p, err);
    if (!s) stitch_add(&st, &p);
    part_free(&p);
  }
  if (s) goto done;
  rep->n_frames = n;
  rep->jerk_before = jerk(st.ref, n, nv);
  const int radius = ro->filter_radius ? ro->filter_radius : 2;
  const double sigma = ro->filter_sigma > 0 ? ro->filter_sigma : 1;
  if (radius > 0) s = km_local_motion_filter(n, nv, st.ref, st.glob, radius, sigma, st.ref, err);
  if (s) goto done;
  rep->jerk_after = jerk(st.ref, n, nv);
  km_anim_writer *w = NULL;
  km_anim_options ao = ro->anim ? *ro->anim : (km_anim_options){0};
  if (ao.fps == 0) ao.fps = 30;
  s = km_anim_writer_open(out, &c->mesh, &ao, &w, err);
  for (size_t f = 0; f < n && !s; ++f)
    s = km_anim_writer_push(w, st.ref + f * stride, err);
  if (!s)
    s = km_anim_writer_finish(&w, &rep->export_report, err);
  else
    km_anim_writer_free(&w);
done:
  free(st.ref);
  free(st.glob);
  free(st.tref);
  free(st.tglob);
  return s;
}
