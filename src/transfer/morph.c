/* Key-pose morphing and motion generation (section 3.5): every k-th tracked frame is
 * recognised, its template transferred onto the avatar, and the frames in between are linear
 * interpolations of consecutive key poses (the paper's "simple linear interpolation"). */
#include "transfer/transfer.h"
#include "transfer/pose.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void km_pose_lerp(const double *A, const double *B, size_t n_vertices, double a, double *out) {
  if (!A || !B || !out) return;
  double b = 1 - a;
  for (size_t i = 0; i < n_vertices * 3; ++i)
    out[i] = b * A[i] + a * B[i];
}

km_status km_avatar_animate(km_transfer *t, const km_posedb *db, const km_track *track,
                            const km_avatar_options *opt, km_avatar_frame_fn fn, void *user,
                            km_avatar_stats *stats, km_error *err) {
  if (stats) memset(stats, 0, sizeof *stats);
  if (!t || !db || !track || !track->positions || (!track->names && track->n_landmarks))
    return km__fail(err, KM_ERR_INVALID, "km_avatar_animate: NULL argument");
  if (track->n_frames == 0 || track->n_landmarks == 0)
    return km__fail(err, KM_ERR_INVALID, "km_avatar_animate: the track has no frames or landmarks");
  km_avatar_options o = opt ? *opt : (km_avatar_options){0};
  size_t k = o.key_every ? o.key_every : 1;
  size_t nl = km_posedb_landmark_count(db), n = km_transfer_vertices(t);
  const km_landmark *lm = km_posedb_landmarks(db);
  const km_mesh *src = km__transfer_source(t);
  km_mesh tm0;
  km_posedb_template(db, 0, &tm0);
  if (km_transfer_landmarks(t) != nl)
    return km__fail(err, KM_ERR_INVALID,
                    "km_avatar_animate: the transfer has %zu landmarks, the database %zu",
                    km_transfer_landmarks(t), nl);
  if (tm0.n_vertices != n || tm0.n_faces != src->n_faces ||
      memcmp(tm0.F, src->F, src->n_faces * 3 * sizeof(int32_t)) != 0)
    return km__fail(err, KM_ERR_INVALID,
                    "km_avatar_animate: the database templates (%zu vertices) do not share the "
                    "avatar's connectivity (%zu vertices)",
                    tm0.n_vertices, n);
  int32_t map[KM_POSE_MAX_LANDMARKS];
  for (size_t a = 0; a < nl; ++a) {
    map[a] = -1;
    for (size_t b = 0; b < track->n_landmarks; ++b)
      if (strcmp(track->names[b], lm[a].name) == 0) map[a] = (int32_t)b;
    if (map[a] < 0)
      return km__fail(err, KM_ERR_INVALID,
                      "km_avatar_animate: the track has no landmark \"%s\" (the database's "
                      "landmark %zu)",
                      lm[a].name, a);
  }
  double *prev = km__malloc(n * 3, sizeof(double)), *cur = km__malloc(n * 3, sizeof(double));
  double *frame = km__malloc(n * 3, sizeof(double));
  double P[3 * KM_POSE_MAX_LANDMARKS], tg[3 * KM_POSE_MAX_LANDMARKS], TL[3 * KM_POSE_MAX_LANDMARKS];
  km_status s = KM_OK;
  if (!prev || !cur || !frame) {
    s = km__fail(err, KM_ERR_NOMEM, "km_avatar_animate: out of memory (%zu vertices)", n);
    goto done;
  }
  memcpy(prev, src->V, n * 3 * sizeof(double));
  double scale = o.track_scale > 0 ? o.track_scale : 0;
  size_t nfr = track->n_frames, pk = 0, iters = 0;
  bool have_key = false;
  for (size_t kf = 0;; kf = kf + k < nfr - 1 ? kf + k : nfr - 1) {
    if (!km__progress(&o.progress, (double)kf / (double)nfr, "avatar")) {
      s = km__fail(err, KM_ERR_CANCELLED, "km_avatar_animate: cancelled");
      goto done;
    }
    double t0 = km_seconds();
    bool ok = true;
    for (size_t a = 0; a < nl; ++a)
      for (int c = 0; c < 3; ++c) {
        P[3 * a + c] = track->positions[(kf * track->n_landmarks + (size_t)map[a]) * 3 + c];
        ok = ok && isfinite(P[3 * a + c]);
      }
    if (ok) {
      km_pose_match m;
      s = km_posedb_query(db, P, &m, err);
      if (s) goto done;
      double t1 = km_seconds();
      km_mesh T;
      km_posedb_template(db, m.template_index, &T);
      if (!(scale > 0)) {
        for (size_t a = 0; a < nl; ++a)
          memcpy(TL + 3 * a, T.V + 3 * (size_t)lm[a].vertex, 3 * sizeof(double));
        double su, R[9], tr[3];
        s = km_similarity_fit(TL, P, NULL, nl, true, &su, R, tr, err);
        if (s) {
          km__wrap(err, s, "km_avatar_animate: frame %zu: sizing the track", kf);
          goto done;
        }
        double r = km__transfer_size_ratio(t, T.V);
        scale = su > 0 ? r / su : 1;
      }
      for (size_t a = 0; a < nl * 3; ++a)
        tg[a] = scale * P[a];
      km_transfer_stats ts;
      /* The iteration starts from the retrieved template's frames (the paper's step 1), not
       * from the previous key pose's: given frames the solve is direct, so frames are the only
       * state to warm-start from, and the previous pose's frames know nothing of the new
       * template (that is landmark-only editing iterated: 15.7 mm against 10.9 mm on the
       * generated subjects, tests/test_transfer.c). The previous key pose holds the avatar
       * when landmarks are lost and is the start of the morph. */
      s = km_transfer_solve(t, T.V, tg, NULL, cur, &ts, err);
      if (s) {
        km__wrap(err, s, "km_avatar_animate: frame %zu", kf);
        goto done;
      }
      double t2 = km_seconds();
      iters += (size_t)ts.iterations;
      if (stats) {
        stats->recognition_ms += (t1 - t0) * 1e3;
        stats->transfer_ms += (t2 - t1) * 1e3;
        if ((t2 - t0) * 1e3 > stats->max_frame_ms) stats->max_frame_ms = (t2 - t0) * 1e3;
        ++stats->key_frames;
      }
    } else {
      memcpy(cur, prev, n * 3 * sizeof(double));
    }
    if (!have_key) {
      if (fn && (s = fn(0, cur, user, err))) goto done;
      have_key = true;
    } else {
      for (size_t g = pk + 1; g <= kf; ++g) {
        km_pose_lerp(prev, cur, n, (double)(g - pk) / (double)(kf - pk), frame);
        if (fn && (s = fn(g, frame, user, err))) goto done;
      }
    }
    double *sw = prev;
    prev = cur;
    cur = sw;
    pk = kf;
    if (kf + 1 >= nfr) break;
  }
  if (stats) {
    stats->frames = nfr;
    stats->iterations_mean = stats->key_frames ? (double)iters / (double)stats->key_frames : 0;
  }
done:
  free(prev);
  free(cur);
  free(frame);
  return s;
}
