/* Holt double exponential joint filter (paper eq. 4) with the Kinect SDK's jitter, prediction
 * and max-deviation stages (NUI_TRANSFORM_SMOOTH_PARAMETERS), and the One Euro filter
 * (Casiez, Roussel & Vogel 2012). See km_filter_options. */
#include "motion/motion.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct joint_state {
  double level[3], trend[3], out[3];
  double prev_x[3]; /* last good raw sample */
  double speed;     /* One Euro: filtered speed, m/s */
  int gap;          /* frames since the last good sample */
  double off[3];    /* catch-up: added to the raw samples after a gap, shrinking */
  bool valid;       /* has seen a good sample */
} joint_state;

struct km_filter {
  size_t n;
  km_filter_kind kind;
  double smoothing, trend, prediction, jitter, max_dev;
  double te, min_cutoff, beta, d_cutoff; /* One Euro */
  double catchup; /* metres per frame the catch-up offset shrinks by at most; 0: snap */
  double decay;   /* the catch-up offset's factor per frame when small */
  joint_state *s;
};

static double option(double v, double def) { return v == 0 ? def : (v < 0 ? 0.0 : v); }

km_status km_filter_create(size_t n_joints, const km_filter_options *opt, km_filter **out,
                           km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_filter_create: out is NULL");
  *out = NULL;
  km_filter_options o = opt ? *opt : (km_filter_options){0};
  double sm = option(o.smoothing, 0.5), tr = option(o.trend, 0.5);
  if (!(sm < 1.0))
    return km__fail(err, KM_ERR_INVALID,
                    "filter smoothing must be in [0,1) (1 would freeze the joints), got %g", sm);
  if (!(tr <= 1.0))
    return km__fail(err, KM_ERR_INVALID, "filter trend must be in [0,1], got %g", tr);
  if (!(o.prediction >= 0) || !isfinite(o.prediction) || !(o.jitter_radius >= 0) ||
      !isfinite(o.jitter_radius) || !(o.max_deviation >= 0) || !isfinite(o.max_deviation))
    return km__fail(err, KM_ERR_INVALID,
                    "filter prediction, jitter_radius and max_deviation must be finite and >= 0 "
                    "(got %g, %g, %g)",
                    o.prediction, o.jitter_radius, o.max_deviation);
  if (o.kind != KM_FILTER_HOLT && o.kind != KM_FILTER_ONE_EURO)
    return km__fail(err, KM_ERR_INVALID, "filter kind %d is unknown", (int)o.kind);
  double fps = o.fps == 0 ? 30.0 : o.fps, mc = o.min_cutoff == 0 ? 1.5 : o.min_cutoff;
  double beta = o.beta == 0 ? 1.0 : o.beta, dc = o.d_cutoff == 0 ? 1.0 : o.d_cutoff;
  if (!(fps > 0) || !isfinite(fps) || !(mc > 0) || !isfinite(mc) || !(beta >= 0) ||
      !isfinite(beta) || !(dc > 0) || !isfinite(dc))
    return km__fail(err, KM_ERR_INVALID,
                    "filter fps, min_cutoff and d_cutoff must be finite and > 0, beta >= 0 (got "
                    "%g, %g, %g, %g)",
                    o.fps, o.min_cutoff, o.d_cutoff, o.beta);
  km_filter *f = calloc(1, sizeof *f);
  if (!f) return km__fail(err, KM_ERR_NOMEM, "km_filter_create: out of memory");
  f->s = km__calloc(n_joints ? n_joints : 1, sizeof *f->s);
  if (!f->s) {
    free(f);
    return km__fail(err, KM_ERR_NOMEM, "km_filter_create: out of memory (%zu joints)", n_joints);
  }
  f->n = n_joints;
  f->smoothing = sm;
  f->trend = tr;
  f->prediction = o.prediction;
  f->jitter = o.jitter_radius;
  f->max_dev = o.max_deviation;
  f->kind = o.kind;
  f->te = 1.0 / fps;
  f->min_cutoff = mc;
  f->beta = beta;
  f->d_cutoff = dc;
  f->catchup = o.catchup_speed > 0 ? o.catchup_speed / fps : 0;
  f->decay = pow(0.5, 30.0 / fps);
  *out = f;
  return KM_OK;
}

static double dist3(const double a[3], const double b[3]) {
  double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return sqrt(dx * dx + dy * dy + dz * dz);
}

static double clamp2(double v, double a, double b) {
  double lo = a < b ? a : b, hi = a < b ? b : a;
  return v < lo ? lo : (v > hi ? hi : v);
}

/* Smoothing factor of a first-order low-pass with cutoff fc (Hz) over te seconds (One Euro
 * filter's alpha; retarget.c's heading filter uses it too). */
double km__one_euro_alpha(double fc, double te) {
  double tau = 1.0 / (2.0 * M_PI * fc);
  return 1.0 / (1.0 + tau / te);
}

/* Catch-up after a gap (issue 12): a joint that was missing or rejected for some frames comes
 * back where the tracker now puts it, often far from where it was held; snapping there moves
 * the mesh by a tenth of its size in one frame. Instead the filter is fed the new samples plus
 * an offset that starts at the held position (the last sample it was fed) and goes: halving per
 * frame (at 30 fps) while small, at most catchup metres per frame while large. The joint's own
 * motion since it came back passes through unchanged.
 *   x  in: the raw sample; out: what the filter is fed */
static void catch_up(const km_filter *f, joint_state *s, int gap, double x[3]) {
  if (!(f->catchup > 0) || !s->valid) return;
  if (gap > 1) /* back after a gap: start from the held input */
    for (int k = 0; k < 3; ++k)
      s->off[k] = s->prev_x[k] - x[k];
  double n = sqrt(s->off[0] * s->off[0] + s->off[1] * s->off[1] + s->off[2] * s->off[2]);
  if (!(n > 0)) return;
  double k = f->decay;
  if (n * (1 - k) > f->catchup) k = 1 - f->catchup / n;
  if (n * k < 1e-5) k = 0;
  for (int c = 0; c < 3; ++c) {
    s->off[c] *= k;
    x[c] += s->off[c];
  }
}

void km_filter_push(km_filter *f, const double *raw, double *filtered) {
  for (size_t j = 0; j < f->n; ++j) {
    joint_state *s = &f->s[j];
    double x[3] = {raw[3 * j], raw[3 * j + 1], raw[3 * j + 2]};
    double *o = filtered + 3 * j;
    ++s->gap;
    if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2])) {
      /* Missing: the state is left alone so the trend is not polluted; hold the output. */
      for (int k = 0; k < 3; ++k)
        o[k] = s->valid ? s->out[k] : NAN;
      continue;
    }
    int gap = s->gap;
    catch_up(f, s, gap, x);
    double prev_x[3] = {s->prev_x[0], s->prev_x[1], s->prev_x[2]};
    memcpy(s->prev_x, x, sizeof x);
    s->gap = 0;
    if (!s->valid) {
      for (int k = 0; k < 3; ++k) {
        s->level[k] = x[k];
        s->trend[k] = 0;
        s->out[k] = x[k];
      }
      s->speed = 0;
      s->valid = true;
      memset(s->off, 0, sizeof s->off);
      if (f->kind == KM_FILTER_ONE_EURO) {
        for (int k = 0; k < 3; ++k)
          o[k] = x[k];
        continue;
      }
    } else if (f->kind == KM_FILTER_ONE_EURO) {
      double te = f->te * (gap > 0 ? gap : 1);
      double v = dist3(x, prev_x) / te;
      s->speed += km__one_euro_alpha(f->d_cutoff, te) * (v - s->speed);
      double a = km__one_euro_alpha(f->min_cutoff + f->beta * s->speed, te);
      for (int k = 0; k < 3; ++k)
        o[k] = s->out[k] = s->out[k] + a * (x[k] - s->out[k]);
      continue;
    } else {
      double in[3] = {x[0], x[1], x[2]};
      if (f->jitter > 0) {
        double d = dist3(x, s->level);
        if (d <= f->jitter) {
          double a = d / f->jitter; /* small moves are damped proportionally */
          for (int k = 0; k < 3; ++k)
            in[k] = s->level[k] + a * (x[k] - s->level[k]);
        }
      }
      for (int k = 0; k < 3; ++k) {
        double prev = s->level[k];
        /* Written as lerps so that a constant input is reproduced bit for bit. */
        double lv = in[k] + f->smoothing * ((prev + s->trend[k]) - in[k]);
        lv = clamp2(lv, prev, in[k]); /* no overshoot past the input */
        s->trend[k] += f->trend * ((lv - prev) - s->trend[k]);
        s->level[k] = lv;
      }
    }
    double y[3];
    for (int k = 0; k < 3; ++k) /* predict no farther than the raw step, in its direction */
      y[k] = s->level[k] + f->prediction * clamp2(s->trend[k], 0.0, x[k] - prev_x[k]);
    if (f->max_dev > 0) {
      double d = dist3(y, x);
      if (d > f->max_dev) {
        double a = f->max_dev / d;
        for (int k = 0; k < 3; ++k)
          y[k] = x[k] + a * (y[k] - x[k]);
      }
    }
    for (int k = 0; k < 3; ++k)
      o[k] = s->out[k] = y[k];
  }
}

void km_filter_reset(km_filter *f) {
  if (f) memset(f->s, 0, f->n * sizeof *f->s);
}

void km_filter_restart_joint(km_filter *f, size_t j) {
  if (f && j < f->n) memset(&f->s[j], 0, sizeof f->s[j]);
}

void km_filter_free(km_filter **f) {
  if (!f || !*f) return;
  free((*f)->s);
  free(*f);
  *f = NULL;
}
