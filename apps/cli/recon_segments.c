/* reconstruct --segment-frames (issue 17): see recon_segments.h. Segments are independent
 * until the stitch, which is what lets them run on different nodes; here they run one after
 * the other in this process. */
#include "recon_segments.h"
#include "cli.h"

#include <stdlib.h>
#include <string.h>

static km_status read_frame(const char *path, km_points *p, km_error *err) {
  km_points_free(p);
  return km_points_read(path, p, err);
}

int km_cli_reconstruct_segmented(char **paths, size_t n, const km_character *c,
                                 const km_recon_feature *feat, size_t nfeat,
                                 const km_recon_options *ro, size_t seg, size_t overlap,
                                 const char *out) {
  const size_t nv = c->mesh.n_vertices, stride = nv * 3;
  const size_t nseg = (n + seg - 1) / seg;
  double *ref = malloc(sizeof *ref * stride * n), *glob = malloc(sizeof *glob * stride * n);
  double *tref = malloc(sizeof *tref * stride * (overlap + 1));
  double *tglob = malloc(sizeof *tglob * stride * (overlap + 1));
  km_recon *first = NULL, *r = NULL;
  km_points pts = {0};
  km_error err = {0};
  km_status s = KM_OK;
  int rc = KM_EXIT_OK;
  double sum_mm = 0, t_all = km_cli_now();
  size_t carried = 0, tail = 0; /* frames of the previous segment's overlap held in tref */
  if (!ref || !glob || !tref || !tglob) {
    rc = km_cli_error("reconstruct", "out of memory (%zu frames of %zu vertices)", n, nv);
    goto done;
  }
  for (size_t k = 0; k < nseg && !s; ++k) {
    const size_t a = k * seg, b = a + seg < n ? a + seg : n, e = b + overlap < n ? b + overlap : n;
    double t0 = km_cli_now(), seg_mm = 0;
    if ((s = km_recon_create(c, ro, &r, &err))) break;
    for (size_t f = a; f < e && !s; ++f) {
      km_recon_frame_stats st = {0};
      if ((s = read_frame(paths[f], &pts, &err))) break;
      s = f == a ? km_recon_first_frame(r, pts.P, pts.n, k == 0 ? feat : NULL, k == 0 ? nfeat : 0,
                                        &st, &err)
                 : km_recon_next_frame(r, pts.P, pts.n, &st, &err);
      if (s) break;
      const double *sv = km_recon_surface(r), *gv = km_recon_global(r);
      if (f >= b) { /* this segment's overlap: blended into the next one's first frames */
        memcpy(tref + (f - b) * stride, sv, sizeof *sv * stride);
        memcpy(tglob + (f - b) * stride, gv, sizeof *gv * stride);
        continue;
      }
      sum_mm += st.mean_mm;
      seg_mm += st.mean_mm;
      carried += st.status != 0;
      double *dr = ref + f * stride, *dg = glob + f * stride;
      if (f - a < tail) {
        /* the previous segment has tracked into this frame: fade it out */
        const double w = (double)(f - a + 1) / (double)(tail + 1);
        const double *pr = tref + (f - a) * stride, *pg = tglob + (f - a) * stride;
        for (size_t i = 0; i < stride; ++i) {
          dr[i] = (1 - w) * pr[i] + w * sv[i];
          dg[i] = (1 - w) * pg[i] + w * gv[i];
        }
      } else {
        memcpy(dr, sv, sizeof *sv * stride);
        memcpy(dg, gv, sizeof *gv * stride);
      }
      if (ro->progress.fn &&
          !ro->progress.fn((double)(f + 1) / (double)n, "segments", ro->progress.user)) {
        s = km_error_set(&err, KM_ERR_CANCELLED, "reconstruct: cancelled");
      }
    }
    if (s) break;
    tail = e - b;
    km_cli_progress_done();
    fprintf(stderr,
            "kinemesh reconstruct: segment %zu/%zu: frames %zu-%zu (+%zu overlap), %.2f s, mean "
            "point error %.2f mm\n",
            k + 1, nseg, a, b - 1, e - b, km_cli_now() - t0, seg_mm / (double)(b - a));
    if (!first)
      first = r, r = NULL; /* its template gives the output's faces */
    else
      km_recon_free(&r);
  }
  if (!s) {
    const int radius = ro->filter_radius ? ro->filter_radius : 2;
    const double sigma = ro->filter_sigma > 0 ? ro->filter_sigma : 1;
    if (radius > 0) s = km_local_motion_filter(n, nv, ref, glob, radius, sigma, ref, &err);
  }
  if (!s) {
    km_anim_writer *w = NULL;
    km_anim_options ao = {.fps = 30};
    s = km_anim_writer_open(out, km_recon_template(first), &ao, &w, &err);
    for (size_t f = 0; f < n && !s; ++f)
      s = km_anim_writer_push(w, ref + f * stride, &err);
    if (!s)
      s = km_anim_writer_close(&w, &err);
    else
      km_anim_writer_free(&w);
  }
  if (s) {
    rc = km_cli_fail("reconstruct", &err);
  } else {
    fprintf(stderr,
            "kinemesh reconstruct: %zu frames in %zu segments of %zu (+%zu overlap), %zu carried "
            "by the skeleton, mean point error %.2f mm (before the filter), %.2f s/frame -> %s\n",
            n, nseg, seg, overlap, carried, sum_mm / (double)n, (km_cli_now() - t_all) / (double)n,
            out);
  }
done:
  km_points_free(&pts);
  km_recon_free(&r);
  km_recon_free(&first);
  free(ref);
  free(glob);
  free(tref);
  free(tglob);
  return rc;
}
