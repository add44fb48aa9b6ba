/* Tracker glitch rejection before the joint filter (issue 12), see km_glitch_create. Three
 * tests per joint and frame, each rejecting the sample: with catch-up on (the default) the
 * joint is then carried by its parent at its last accepted offset (a lost hand stays at the
 * end of the forearm), else, or without a parent, it is "missing" (NaN) so that the filter
 * after it holds its state instead of chasing the glitch:
 *   refound: a joint that was missing stays missing for refound_frames more frames (trackers
 *            re-acquire a lost joint at a wrong place first);
 *   speed:   the sample lies farther from the joint's last accepted sample than max_speed
 *            allows over the time since then (the allowance grows with every rejected frame,
 *            so a joint that really moved is re-acquired after a few frames);
 *   bone:    the bone from the (accepted) parent departs from the running median of its
 *            accepted lengths by more than bone_tolerance * median + bone_slack.
 * A joint's first samples have nothing to be judged against: the first is accepted as it
 * comes. When that start was the glitch (a hand placed 0.6 m off in frame 0), the true samples
 * after it are rejected (too fast, or, after a longer start, a bone unlike the start's); once
 * they have come steadily for as many frames as the start had, within the start window, the
 * joint is restarted (km_glitch_restarted): taken as it comes, its start and bone lengths
 * forgotten, and its user told to redo what it built on that start.
 * A plain ring buffer and a selection over it give the running median; the window is small
 * (KM_GLITCH_WINDOW samples), so nothing cleverer (two heaps) pays for itself. */
#include "motion/motion.h"
#include "math/math.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KM_GLITCH_WINDOW 31
#define KM_GLITCH_MIN_SAMPLES 5 /* bone lengths seen before the bone test starts */

typedef struct glitch_joint {
  double last[3]; /* last accepted sample */
  bool has_last;
  double rel[3]; /* last accepted sample minus its parent's raw sample then (both accepted) */
  bool has_rel;
  double off[3]; /* catch-up: added to the accepted samples after a gap, shrinking */
  int since;     /* frames since the last accepted sample (1 = the previous frame) */
  double t_last; /* time of the last accepted sample (seconds; NaN: frames are not timed) */
  int hold;      /* refound: frames still to treat as missing */
  bool was_missing;
  double len[KM_GLITCH_WINDOW]; /* accepted bone lengths to the parent */
  int n_len, next_len;
  size_t first;   /* the frame (count before it) of the first accepted sample, or of a restart */
  int run;        /* samples accepted since then */
  double prev[3]; /* the previous frame's sample (has_prev: it was present) */
  bool has_prev;
  int streak; /* rejected samples since the last accepted one, each steady (within a frame's
                 allowed move) with the one before */
} glitch_joint;

struct km_glitch {
  size_t n;
  int32_t *parents; /* n, -1: root or no bone test */
  int32_t *par_all; /* n, -1: root (parents as given, for the catch-up) */
  double step;      /* max_speed / fps: metres per frame; <= 0: off */
  double fps;       /* frames per second the step is for */
  double tol, slack;
  int refound;
  double catchup, decay; /* catch-up: metres per frame at most, factor per frame when small */
  size_t start;          /* the start window, frames; 0: no restarts */
  int short_start;       /* a start this short (0.1 s of samples) may be wholly wrong */
  glitch_joint *j;
  bool *restarted; /* n: restarted in the last push */
  bool any_restarted;
  bool *ok;   /* n, scratch: accepted this frame */
  double *in; /* n*3, scratch: the raw frame (clean may alias raw) */
  km_glitch_stats stats;
};

km_status km_glitch_create(size_t n_joints, const int32_t *parents, const km_glitch_options *opt,
                           km_glitch **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_glitch_create: out is NULL");
  *out = NULL;
  km_glitch_options o = opt ? *opt : (km_glitch_options){0};
  double fps = o.fps == 0 ? 30.0 : o.fps;
  double speed = o.max_speed == 0 ? 12.0 : o.max_speed;
  double tol = o.bone_tolerance == 0 ? 0.4 : o.bone_tolerance;
  double slack = o.bone_slack == 0 ? 0.04 : o.bone_slack;
  if (!(fps > 0) || !isfinite(fps) || !isfinite(speed) || !isfinite(tol) || !isfinite(slack) ||
      slack < 0)
    return km__fail(err, KM_ERR_INVALID,
                    "glitch options: fps must be > 0 and max_speed, bone_tolerance, bone_slack "
                    "finite (bone_slack >= 0); got fps %g, max_speed %g, bone_tolerance %g, "
                    "bone_slack %g",
                    o.fps, o.max_speed, o.bone_tolerance, o.bone_slack);
  if (parents)
    for (size_t k = 0; k < n_joints; ++k)
      if (parents[k] >= (int32_t)k || parents[k] < -1)
        return km__fail(err, KM_ERR_INVALID,
                        "km_glitch_create: parent of joint %zu is %d (expected -1 or < %zu)", k,
                        (int)parents[k], k);
  km_glitch *g = km__calloc(1, sizeof *g);
  if (!g) return km__fail(err, KM_ERR_NOMEM, "km_glitch_create: out of memory");
  size_t n = n_joints ? n_joints : 1;
  g->parents = km__malloc(n, sizeof(int32_t));
  g->par_all = km__malloc(n, sizeof(int32_t));
  g->j = km__calloc(n, sizeof *g->j);
  g->ok = km__calloc(n, sizeof(bool));
  g->restarted = km__calloc(n, sizeof(bool));
  g->in = km__malloc(3 * n, sizeof(double));
  if (!g->parents || !g->par_all || !g->j || !g->ok || !g->restarted || !g->in) {
    km_glitch_free(&g);
    return km__fail(err, KM_ERR_NOMEM, "km_glitch_create: out of memory (%zu joints)", n_joints);
  }
  g->n = n_joints;
  for (size_t k = 0; k < n_joints; ++k)
    g->parents[k] = parents && tol > 0 ? parents[k] : -1;
  for (size_t k = 0; k < n_joints; ++k)
    g->par_all[k] = parents ? parents[k] : -1;
  g->step = speed > 0 ? speed / fps : 0;
  g->fps = fps;
  g->tol = tol;
  g->slack = slack;
  g->refound = o.refound_frames == 0 ? 1 : (o.refound_frames < 0 ? 0 : o.refound_frames);
  g->catchup = o.catchup_speed < 0 ? 0 : (o.catchup_speed == 0 ? 3.0 : o.catchup_speed) / fps;
  g->decay = pow(0.5, 30.0 / fps);
  double start = o.start_seconds < 0 ? 0 : (o.start_seconds == 0 ? 1.0 : o.start_seconds);
  g->start = isfinite(start) ? (size_t)ceil(start * fps) : 0;
  g->short_start = (int)fmax(3, ceil(0.1 * fps));
  *out = g;
  return KM_OK;
}

static double median(const double *v, int n) {
  double a[KM_GLITCH_WINDOW];
  memcpy(a, v, (size_t)n * sizeof *a);
  /* insertion sort: n <= 31 */
  for (int i = 1; i < n; ++i) {
    double x = a[i];
    int k = i - 1;
    for (; k >= 0 && a[k] > x; --k)
      a[k + 1] = a[k];
    a[k + 1] = x;
  }
  return n % 2 ? a[n / 2] : 0.5 * (a[n / 2 - 1] + a[n / 2]);
}

static double dist3(const double *a, const double *b) {
  double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Joint k's start was the glitch: it is taken as it comes (o, the catch-up offset, zeroed),
 * listed and counted, and the bone lengths measured from the wrong start forgotten: its own
 * and its children's. */
static void restart_joint(km_glitch *g, size_t k, size_t frame, double o[3]) {
  glitch_joint *s = &g->j[k];
  memset(o, 0, 3 * sizeof(double));
  g->restarted[k] = g->any_restarted = true;
  ++g->stats.restarted;
  s->first = frame;
  s->run = 0;
  s->n_len = s->next_len = 0;
  for (size_t c = k + 1; c < g->n; ++c)
    if (g->parents[c] == (int32_t)k) g->j[c].n_len = g->j[c].next_len = 0;
}

void km_glitch_push(km_glitch *g, const double *raw, double *clean) {
  km_glitch_push_at(g, raw, NAN, clean);
}

void km_glitch_push_at(km_glitch *g, const double *raw_in, double t, double *clean) {
  memcpy(g->in, raw_in, 3 * g->n * sizeof(double));
  const double *raw = g->in;
  if (g->any_restarted) memset(g->restarted, 0, g->n * sizeof(bool));
  g->any_restarted = false;
  size_t frame = g->stats.frames++;
  for (size_t k = 0; k < g->n; ++k) {
    glitch_joint *s = &g->j[k];
    const double *x = raw + 3 * k;
    g->ok[k] = false;
    if (s->has_last) ++s->since;
    bool back = s->has_last && s->since > 1; /* if accepted: back after a gap */
    if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2])) {
      ++g->stats.missing;
      s->was_missing = true;
      s->has_prev = false;
      continue;
    }
    ++g->stats.samples;
    bool steady = s->has_prev && dist3(x, s->prev) <= (g->step > 0 ? g->step : 0.1);
    memcpy(s->prev, x, sizeof s->prev);
    s->has_prev = true;
    int streak = back && steady ? s->streak + 1 : 1; /* with this sample, if it is rejected */
    int32_t pa = g->par_all[k];
    bool rel = pa >= 0 && g->ok[pa] && s->has_rel;
    double o[3] = {0, 0, 0}; /* where it was held minus where it is (back only), relative to
                                its parent if it can */
    for (int c = 0; back && c < 3; ++c)
      o[c] = rel ? s->rel[c] - (x[c] - raw[3 * (size_t)pa + c]) : s->last[c] - x[c];
    /* Restart (see the top): early on (within the start window of its first sample), back
     * after a rejection far from where it is held (farther than 10 cm plus half the bone it
     * hangs from, a hand 8 cm off its wrist: 14 cm; or 10 cm plus a frame's allowed move for a
     * joint held absolutely), and either accepted again after a short start (0.1 s of
     * samples), or rejected steadily there for at least 2 frames and as many as its start had
     * (a start of 5 glitched frames fills the bone test's lengths, which would then reject the
     * true joint for good). A longer start is trusted: a joint lost and re-found far away
     * after it eases in (catch-up). */
    bool far = false;
    if (back && g->start && frame - s->first <= g->start) {
      double bar = 0.1 + (rel ? 0.5 * sqrt(km__dot3(s->rel, s->rel)) : g->step);
      far = sqrt(km__dot3(o, o)) > bar;
    }
    bool restart = far && streak >= 2 && streak >= s->run && !s->hold;
    if (s->was_missing && s->has_last) s->hold = g->refound;
    s->was_missing = false;
    if (s->hold > 0) {
      --s->hold;
      ++g->stats.refound;
      s->streak = streak;
      continue;
    }
    /* The allowance grows with the frames since the last accepted sample, or with the time
     * since then when frames are timed: a live server that keeps only the newest of several
     * frames, or a tracker that went silent, must not make a real move look too fast. */
    double frames = s->since;
    if (isfinite(t) && isfinite(s->t_last) && t - s->t_last > 0)
      frames = fmax(frames, (t - s->t_last) * g->fps);
    if (restart) {
      restart_joint(g, k, frame, o);
    } else if (s->has_last && g->step > 0 && dist3(x, s->last) > g->step * frames) {
      ++g->stats.speed;
      s->streak = streak;
      continue;
    }
    int32_t p = g->parents[k];
    if (p >= 0 && g->ok[p]) {
      double len = dist3(x, raw + 3 * (size_t)p);
      if (s->n_len >= KM_GLITCH_MIN_SAMPLES) {
        double med = median(s->len, s->n_len);
        if (fabs(len - med) > g->tol * med + g->slack) {
          ++g->stats.bone;
          s->streak = streak;
          continue;
        }
      }
      s->len[s->next_len] = len;
      s->next_len = (s->next_len + 1) % KM_GLITCH_WINDOW;
      if (s->n_len < KM_GLITCH_WINDOW) ++s->n_len;
    }
    g->ok[k] = true;
    if (!s->has_last) s->first = frame;
    if (far && !restart && s->run <= g->short_start) restart_joint(g, k, frame, o);
    if (back && g->catchup > 0) memcpy(s->off, o, sizeof o); /* eases in from where it was held */
    ++s->run;
    s->streak = 0;
    s->has_rel = pa >= 0 && g->ok[pa];
    for (int c = 0; s->has_rel && c < 3; ++c)
      s->rel[c] = x[c] - raw[3 * (size_t)pa + c];
    memcpy(s->last, x, sizeof s->last);
    s->has_last = true;
    s->since = 0;
    s->t_last = t;
  }
  for (size_t k = 0; k < g->n; ++k) {
    if (!g->ok[k] && isfinite(raw[3 * k]) && isfinite(raw[3 * k + 1]) && isfinite(raw[3 * k + 2]))
      ++g->stats.rejected;
    if (!g->ok[k]) {
      int32_t pp = g->par_all[k];
      bool carry = g->catchup > 0 && pp >= 0 && g->j[k].has_rel && isfinite(clean[3 * (size_t)pp]);
      for (int c = 0; c < 3; ++c)
        clean[3 * k + c] = carry ? clean[3 * (size_t)pp + c] + g->j[k].rel[c] : NAN;
      continue;
    }
    /* catch-up: the offset shrinks (halving per frame while small, at most catchup metres
     * per frame), and a joint is carried by its parent's offset (parents come first), so a
     * bone keeps its length and direction while its end eases back in */
    glitch_joint *s = &g->j[k];
    double *off = s->off, n = sqrt(off[0] * off[0] + off[1] * off[1] + off[2] * off[2]);
    if (n > 0) {
      double f = g->decay;
      if (n * (1 - f) > g->catchup) f = 1 - g->catchup / n;
      if (n * f < 1e-5) f = 0;
      for (int c = 0; c < 3; ++c)
        off[c] *= f;
    }
    int32_t p = g->par_all[k];
    bool carried = p >= 0 && g->ok[p];
    double *o = clean + 3 * k;
    for (int c = 0; c < 3; ++c)
      o[c] = raw[3 * k + c] + off[c] +
             (carried ? clean[3 * (size_t)p + c] - raw[3 * (size_t)p + c] : 0);
    if (carried && n > 0) { /* the bone turns back in at its current length, not a chord */
      const double *q = clean + 3 * (size_t)p, *xq = raw + 3 * (size_t)p, *x = raw + 3 * k;
      double b[3] = {o[0] - q[0], o[1] - q[1], o[2] - q[2]};
      double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]), l = dist3(x, xq);
      for (int c = 0; lb > 1e-9 && c < 3; ++c)
        o[c] = q[c] + b[c] * (l / lb);
    }
  }
}

void km_glitch_stats_get(const km_glitch *g, km_glitch_stats *out) { *out = g->stats; }

const bool *km_glitch_restarted(const km_glitch *g) {
  return g && g->any_restarted ? g->restarted : NULL;
}

void km_glitch_reset(km_glitch *g) {
  if (!g) return;
  memset(g->j, 0, g->n * sizeof *g->j);
  memset(g->restarted, 0, g->n * sizeof(bool));
  g->any_restarted = false;
  memset(&g->stats, 0, sizeof g->stats);
}

void km_glitch_free(km_glitch **g) {
  if (!g || !*g) return;
  free((*g)->parents);
  free((*g)->par_all);
  free((*g)->j);
  free((*g)->ok);
  free((*g)->restarted);
  free((*g)->in);
  free(*g);
  *g = NULL;
}
