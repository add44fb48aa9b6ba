/* Reconstruction pipeline: frames in, temporal local-motion filter, streamed output,
 * per-frame report (JSON, gnuplot figure). */
#include "recon/recon.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

km_status km_local_motion_filter(size_t n_frames, size_t n_vertices, const double *refined,
                                 const double *global, int radius, double sigma, double *out,
                                 km_error *err) {
  if ((!refined || !global || !out) && n_frames)
    return km__fail(err, KM_ERR_INVALID, "km_local_motion_filter: NULL argument");
  if (radius < 0) radius = 0;
  if (radius > 64)
    return km__fail(err, KM_ERR_INVALID, "km_local_motion_filter: radius %d > 64", radius);
  if (!(sigma > 0)) sigma = 1;
  size_t m = n_vertices * 3;
  double g[129];
  for (int k = -radius; k <= radius; ++k)
    g[k + radius] = exp(-0.5 * k * k / (sigma * sigma));
  /* out may alias refined: compute into a temporary copy of the local motion */
  double *local = km__malloc(n_frames ? n_frames : 1, m * sizeof(double));
  if (!local) return km__fail(err, KM_ERR_NOMEM, "km_local_motion_filter: out of memory");
  for (size_t i = 0; i < n_frames * m; ++i)
    local[i] = refined[i] - global[i];
  for (size_t t = 0; t < n_frames; ++t) {
    double wsum = 0;
    for (int k = -radius; k <= radius; ++k) {
      long tt = (long)t + k;
      if (tt >= 0 && (size_t)tt < n_frames) wsum += g[k + radius];
    }
    double *o = out + t * m;
    const double *gl = global + t * m;
    for (size_t i = 0; i < m; ++i)
      o[i] = gl[i];
    for (int k = -radius; k <= radius; ++k) {
      long tt = (long)t + k;
      if (tt < 0 || (size_t)tt >= n_frames) continue;
      double w = g[k + radius] / wsum;
      const double *l = local + (size_t)tt * m;
      for (size_t i = 0; i < m; ++i)
        o[i] += w * l[i];
    }
  }
  free(local);
  return KM_OK;
}

void km_recon_report_free(km_recon_report *r) {
  if (!r) return;
  free(r->frames);
  free(r->joints);
  if (r->joint_names)
    for (size_t j = 0; j < r->n_joints; ++j)
      free(r->joint_names[j]);
  free(r->joint_names);
  if (r->unsupported)
    for (size_t f = 0; f < r->n_frames; ++f)
      free(r->unsupported[f]);
  free(r->unsupported);
  memset(r, 0, sizeof *r);
}

const char *km_recon_frame_status(const km_recon_frame_stats *s) {
  if (!s) return "";
  return s->status == KM_OK && s->unsupported ? "unsupported_surface" : km_status_name(s->status);
}

km_status km_recon_report_write_json(const char *path, const km_recon_report *r, km_error *err) {
  if (!path || !r)
    return km__fail(err, KM_ERR_INVALID, "km_recon_report_write_json: NULL argument");
  cJSON *root = cJSON_CreateObject();
  if (!root) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  cJSON_AddStringToObject(root, "format", "kinemesh-recon-report");
  cJSON_AddNumberToObject(root, "version", 1);
  cJSON_AddStringToObject(root, "units", "mm (errors), m (joints, jerk)");
  cJSON *names = cJSON_AddArrayToObject(root, "joint_names");
  for (size_t j = 0; j < r->n_joints; ++j)
    cJSON_AddItemToArray(names, cJSON_CreateString(r->joint_names ? r->joint_names[j] : ""));
  cJSON *frames = cJSON_AddArrayToObject(root, "frames");
  for (size_t f = 0; f < r->n_frames; ++f) {
    const km_recon_frame_stats *s = &r->frames[f];
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "index", (double)s->index);
    cJSON_AddNumberToObject(o, "points", (double)s->points);
    cJSON_AddNumberToObject(o, "dropped", (double)s->dropped);
    cJSON_AddNumberToObject(o, "mean_mm", s->mean_mm);
    cJSON_AddNumberToObject(o, "max_mm", s->max_mm);
    cJSON_AddNumberToObject(o, "iterations", s->iterations);
    cJSON_AddNumberToObject(o, "seconds", s->seconds);
    cJSON_AddStringToObject(o, "status", km_recon_frame_status(s));
    if (s->status && s->message[0]) cJSON_AddStringToObject(o, "message", s->message);
    cJSON_AddNumberToObject(o, "p95_mm", s->p95_mm);
    cJSON_AddNumberToObject(o, "surface_mean_mm", s->surface_mean_mm);
    cJSON_AddNumberToObject(o, "surface_p95_mm", s->surface_p95_mm);
    cJSON_AddNumberToObject(o, "surface_p99_mm", s->surface_p99_mm);
    cJSON_AddNumberToObject(o, "surface_max_mm", s->surface_max_mm);
    cJSON_AddNumberToObject(o, "surface_vertices", (double)s->surface_vertices);
    cJSON_AddNumberToObject(o, "unsupported_vertices", (double)s->unsupported_vertices);
    cJSON *uj = cJSON_AddArrayToObject(o, "unsupported_joints");
    for (int k = 0; k < s->n_unsupported_joints && k < KM_RECON_MAX_PARTS; ++k) {
      int32_t j = s->unsupported_joints[k];
      cJSON_AddItemToArray(
          uj, cJSON_CreateString(
                  r->joint_names && j >= 0 && (size_t)j < r->n_joints ? r->joint_names[j] : ""));
    }
    if (r->unsupported && r->unsupported[f]) {
      cJSON *ids = cJSON_AddArrayToObject(o, "unsupported_ids");
      for (size_t k = 0; k < s->unsupported_vertices; ++k)
        cJSON_AddItemToArray(ids, cJSON_CreateNumber(r->unsupported[f][k]));
    }
    if (r->joints) {
      cJSON *j = cJSON_AddArrayToObject(o, "joints");
      for (size_t k = 0; k < r->n_joints * 3; ++k)
        cJSON_AddItemToArray(j, cJSON_CreateNumber(r->joints[f * r->n_joints * 3 + k]));
    }
    cJSON_AddItemToArray(frames, o);
  }
  cJSON_AddNumberToObject(root, "failed_frames", (double)r->failed_frames);
  cJSON_AddStringToObject(root, "surface_to_points",
                          r->visibility_known ? "vertices facing a camera"
                                              : "all vertices (visibility unknown)");
  cJSON_AddNumberToObject(root, "still_vertices", (double)r->still_vertices);
  cJSON_AddNumberToObject(root, "unsupported_distance_mm", r->unsupported_distance_mm);
  cJSON_AddNumberToObject(root, "unsupported_fraction", r->unsupported_fraction);
  cJSON_AddNumberToObject(root, "unsupported_frames", (double)r->unsupported_frames);
  cJSON *ff = cJSON_AddObjectToObject(root, "first_frame");
  const km_recon_init *in = &r->init;
  cJSON_AddNumberToObject(ff, "correspondences", (double)r->correspondences);
  char text_init[640];
  if (r->correspondences >= 3) {
    snprintf(text_init, sizeof text_init,
             "Horn alignment on the %zu given correspondences, the skeletal pose from them, "
             "then scale and rotation again on the posed correspondences",
             r->correspondences);
  } else if (in->yaw_candidates) {
    snprintf(text_init, sizeof text_init,
             "%s: global alignment (centroids, height scale %.3f; the subject assumed upright, "
             "y up; %d headings about the vertical axis, rigid ICP and the skeletal pose from "
             "each; kept heading %.0f deg, rotation %.1f deg, capped residual %.1f mm rigid, "
             "%.1f mm posed, %.1f mm at the feet), then %zu of the template's landmarks matched "
             "to their closest "
             "points as pseudo-correspondences of the feature-only affine stage",
             r->correspondences ? "fewer than 3 correspondences given" : "no correspondences given",
             in->scale, in->yaw_candidates, in->yaw_deg, in->rotation_deg, in->rigid_residual_mm,
             in->residual_mm, in->feet_residual_mm, in->landmarks);
  } else {
    snprintf(text_init, sizeof text_init, "first frame not registered");
  }
  cJSON_AddStringToObject(ff, "initialisation", text_init);
  if (r->correspondences < 3 && in->yaw_candidates) {
    cJSON_AddNumberToObject(ff, "yaw_candidates", in->yaw_candidates);
    cJSON_AddNumberToObject(ff, "yaw_deg", in->yaw_deg);
    cJSON_AddNumberToObject(ff, "rotation_deg", in->rotation_deg);
    cJSON_AddNumberToObject(ff, "rigid_residual_mm", in->rigid_residual_mm);
    cJSON_AddNumberToObject(ff, "residual_mm", in->residual_mm);
    cJSON_AddNumberToObject(ff, "feet_residual_mm", in->feet_residual_mm);
    cJSON_AddNumberToObject(ff, "scale", in->scale);
    cJSON_AddNumberToObject(ff, "landmarks", (double)in->landmarks);
  }
  cJSON_AddNumberToObject(ff, "limbs_turned", (double)in->limbs_turned);
  cJSON_AddNumberToObject(ff, "limbs_scaled", (double)in->limbs_scaled);
  cJSON_AddStringToObject(root, "joints_from", r->rig_joints ? "rig" : "skin weights");
  cJSON_AddNumberToObject(root, "jerk_before", r->jerk_before);
  cJSON_AddNumberToObject(root, "jerk_after", r->jerk_after);
  char *text = cJSON_Print(root);
  cJSON_Delete(root);
  if (!text) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  km__atomic_file af;
  km_status s = km__atomic_open(&af, path, err);
  if (!s) {
    fputs(text, af.f);
    fputc('\n', af.f);
    s = km__atomic_commit(&af, err);
  }
  free(text);
  return s;
}

/* Jerk: mean over vertices of |x_t - 2 x_{t-1} + x_{t-2}| (metres). */
static double mean_second_difference(const double *x, const double *x1, const double *x2,
                                     size_t nv) {
  double acc = 0;
  for (size_t i = 0; i < nv; ++i) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
      double d = x[3 * i + a] - 2 * x1[3 * i + a] + x2[3 * i + a];
      d2 += d * d;
    }
    acc += sqrt(d2);
  }
  return acc / (double)nv;
}

/* ---------------------------------------------------------------- pipeline */

km_status km_reconstruct(const char *const *paths, size_t n_frames, const km_character *tmpl,
                         const km_recon_feature *feat, size_t n_feat, const km_recon_options *opt,
                         const char *out_anim, km_recon_report *report, km_error *err) {
  if (!paths || !n_frames || !tmpl || !out_anim)
    return km__fail(err, KM_ERR_INVALID, "km_reconstruct: needs frames, a template and an output");
  km_recon_options o = opt ? *opt : (km_recon_options){0};
  int radius = o.filter_radius == 0 ? 2 : o.filter_radius < 0 ? 0 : o.filter_radius;
  if (radius > 64) radius = 64;
  double sigma = o.filter_sigma > 0 ? o.filter_sigma : 1;
  km_recon_report local_rep = {0};
  km_recon_report *rep = report ? report : &local_rep;
  memset(rep, 0, sizeof *rep);
  rep->correspondences = n_feat;
  rep->rig_joints = o.rig_joints;
  rep->visibility_known = o.cameras && o.n_cameras;
  rep->unsupported_distance_mm = 1e3 * (o.unsupported_distance > 0 ? o.unsupported_distance : 0.03);
  rep->unsupported_fraction = o.unsupported_fraction > 0 ? o.unsupported_fraction : 0.02;
  size_t done_frames = 0;
  km_recon *r = NULL;
  km_anim_writer *w = NULL;
  size_t nv = tmpl->mesh.n_vertices, nj = tmpl->skeleton.n_joints, win = 2 * (size_t)radius + 1;
  double *ring_ref = NULL, *ring_glob = NULL, *outf = NULL, *prev_out = NULL, *prev2_out = NULL;
  double *prev_ref = NULL, *prev2_ref = NULL;
  double jerk_b = 0, jerk_a = 0;
  size_t jerk_nb = 0, jerk_na = 0, written = 0;
  km_status s = km_recon_create(tmpl, &o, &r, err);
  if (s) return s;
  rep->still_vertices = km__recon_still_vertices(r);
  rep->n_joints = nj;
  rep->frames = calloc(n_frames, sizeof *rep->frames);
  rep->joints = km__malloc(n_frames, nj * 3 * sizeof(double));
  rep->joint_names = calloc(nj, sizeof *rep->joint_names);
  rep->unsupported = calloc(n_frames, sizeof *rep->unsupported);
  ring_ref = km__malloc(win, nv * 3 * sizeof(double));
  ring_glob = km__malloc(win, nv * 3 * sizeof(double));
  outf = km__malloc(nv, 3 * sizeof(double));
  prev_out = km__malloc(nv, 6 * sizeof(double));
  prev_ref = km__malloc(nv, 6 * sizeof(double));
  if (!rep->frames || !rep->joints || !rep->joint_names || !rep->unsupported || !ring_ref ||
      !ring_glob || !outf || !prev_out || !prev_ref) {
    s = km__fail(err, KM_ERR_NOMEM, "km_reconstruct: out of memory");
    goto done;
  }
  prev2_out = prev_out + 3 * nv;
  prev2_ref = prev_ref + 3 * nv;
  for (size_t j = 0; j < nj; ++j)
    rep->joint_names[j] =
        strdup(tmpl->skeleton.names && tmpl->skeleton.names[j] ? tmpl->skeleton.names[j] : "");
  km_anim_options ao = o.anim ? *o.anim : (km_anim_options){0};
  if (ao.fps == 0) ao.fps = 30;
  s = km_anim_writer_open(out_anim, km_recon_template(r), &ao, &w, err);
  if (s) goto done;
  /* Frame t is written once frames up to t + radius are in (or at the end): the Gaussian
   * filter needs them, and every finished frame reaches the writer as soon as it can. */
  for (size_t f = 0; f <= n_frames; ++f) {
    if (f < n_frames) {
      km_points pts = {0};
      km_recon_frame_stats *st = &rep->frames[f];
      km_error fe = {0};
      km_status rs = km_points_read(paths[f], &pts, &fe);
      if (!rs && o.points_frame) rs = km_frame_apply(o.points_frame, pts.P, pts.n, NULL, 0, &fe);
      if (f == 0) {
        if (rs) {
          if (err) *err = fe;
          s = rs;
          goto done;
        }
        rs = km_recon_first_frame(r, pts.P, pts.n, feat, n_feat, st, err);
        if (rs) {
          km_points_free(&pts);
          s = km__wrap(err, rs, "%s", paths[0]);
          goto done;
        }
        km_recon_init_get(r, &rep->init);
      } else {
        /* its own error: fe must still hold the read error (with the file name) afterwards */
        km_error ne = {0};
        if (rs)
          km__log(KM_LOG_WARN, "reconstruct: frame %zu: %s: carried by the skeleton", f,
                  fe.message);
        km_recon_next_frame(r, rs ? NULL : pts.P, rs ? 0 : pts.n, st, &ne);
        if (rs) {
          st->status = rs;
          snprintf(st->message, sizeof st->message, "%.*s", (int)sizeof st->message - 1,
                   fe.message);
        }
      }
      st->index = f;
      st->dropped = pts.dropped_nan + pts.dropped_zero;
      if (st->status) ++rep->failed_frames;
      if (km_recon_frame_status(st)[0] == 'u') {
        ++rep->unsupported_frames;
        char parts[400] = "";
        for (int k = 0; k < st->n_unsupported_joints; ++k) {
          const char *nm = rep->joint_names[st->unsupported_joints[k]];
          size_t len = strlen(parts);
          snprintf(parts + len, sizeof parts - len, "%s%s", k ? ", " : "", nm);
        }
        /* debug only: the applications print the flagged frames from the report */
        km__log(KM_LOG_DEBUG,
                "reconstruct: frame %zu: unsupported surface: %zu of %zu vertices farther than "
                "%.0f mm from every point (%s)",
                f, st->unsupported_vertices, st->surface_vertices, rep->unsupported_distance_mm,
                parts);
      }
      if (st->unsupported_vertices) {
        size_t cnt = 0;
        const int32_t *ids = km_recon_unsupported(r, &cnt);
        rep->unsupported[f] = ids && cnt ? km__malloc(cnt, sizeof(int32_t)) : NULL;
        if (rep->unsupported[f]) memcpy(rep->unsupported[f], ids, cnt * sizeof(int32_t));
      }
      km_points_free(&pts);
      memcpy(rep->joints + f * nj * 3, km_recon_joints(r), nj * 3 * sizeof(double));
      memcpy(ring_ref + (f % win) * nv * 3, km_recon_surface(r), nv * 3 * sizeof(double));
      memcpy(ring_glob + (f % win) * nv * 3, km_recon_global(r), nv * 3 * sizeof(double));
      ++done_frames;
      /* jerk before filtering */
      const double *cur = km_recon_surface(r);
      if (f >= 2) {
        jerk_b += mean_second_difference(cur, prev_ref, prev2_ref, nv), ++jerk_nb;
      }
      memcpy(prev2_ref, prev_ref, nv * 3 * sizeof(double));
      memcpy(prev_ref, cur, nv * 3 * sizeof(double));
      if (!km__progress(&o.progress, (double)(f + 1) / (double)n_frames, "reconstruct")) {
        s = km__fail(err, KM_ERR_CANCELLED, "km_reconstruct: cancelled after frame %zu", f);
        goto flush;
      }
    }
    /* emit every frame whose window is complete */
    while (written < done_frames && (written + (size_t)radius < done_frames || f == n_frames)) {
      size_t t = written;
      for (size_t i = 0; i < nv * 3; ++i)
        outf[i] = ring_glob[(t % win) * nv * 3 + i];
      double wsum = 0, wk[129];
      for (int k = -radius; k <= radius; ++k) {
        long tt = (long)t + k;
        wk[k + radius] =
            (tt >= 0 && (size_t)tt < done_frames) ? exp(-0.5 * k * k / (sigma * sigma)) : 0;
        wsum += wk[k + radius];
      }
      for (int k = -radius; k <= radius; ++k) {
        if (wk[k + radius] == 0) continue;
        size_t tt = (size_t)((long)t + k) % win;
        double ww = wk[k + radius] / wsum;
        for (size_t i = 0; i < nv * 3; ++i)
          outf[i] += ww * (ring_ref[tt * nv * 3 + i] - ring_glob[tt * nv * 3 + i]);
      }
      km_error we;
      km_status ws = km_anim_writer_push(w, outf, &we);
      if (ws) {
        s = ws;
        if (err) *err = we;
        goto done;
      }
      if (t >= 2) {
        jerk_a += mean_second_difference(outf, prev_out, prev2_out, nv), ++jerk_na;
      }
      memcpy(prev2_out, prev_out, nv * 3 * sizeof(double));
      memcpy(prev_out, outf, nv * 3 * sizeof(double));
      ++written;
    }
  }
  goto close;
flush:
  /* cancelled: write what is finished, then close so nothing already computed is lost */
  while (written < done_frames) {
    size_t t = written;
    for (size_t i = 0; i < nv * 3; ++i)
      outf[i] = ring_ref[(t % win) * nv * 3 + i];
    km_anim_writer_push(w, outf, NULL);
    ++written;
  }
close : {
  km_error ce;
  km_status cs = km_anim_writer_finish(&w, &rep->export_report, &ce);
  if (cs && !s) {
    s = cs;
    if (err) *err = ce;
  }
}
  rep->n_frames = done_frames;
  rep->jerk_before = jerk_nb ? jerk_b / (double)jerk_nb : 0;
  rep->jerk_after = jerk_na ? jerk_a / (double)jerk_na : 0;
done:
  rep->n_frames = done_frames; /* on an error too: the frames finished (and their lists) */
  km_anim_writer_free(&w);
  km_recon_free(&r);
  free(ring_ref);
  free(ring_glob);
  free(outf);
  free(prev_out);
  free(prev_ref);
  if (rep == &local_rep) km_recon_report_free(&local_rep);
  return s;
}
