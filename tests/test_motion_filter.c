/* Double exponential joint filter (paper eq. 4 + Kinect SDK knobs). */
#include "km_test.h"

static uint64_t rng = 0x9e3779b97f4a7c15ULL;
static double uniform(void) { /* xorshift64*, deterministic */
  rng ^= rng >> 12;
  rng ^= rng << 25;
  rng ^= rng >> 27;
  return (double)((rng * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
}

static void test_constant(void) {
  /* Constant input is reproduced bit for bit, whatever the options. */
  km_filter_options opts[] = {
      {0},
      {.smoothing = 0.3, .trend = 0.7},
      {.smoothing = 0.9,
       .trend = 0.1,
       .prediction = 2,
       .jitter_radius = 0.05,
       .max_deviation = 0.04},
  };
  for (size_t o = 0; o < 3; ++o) {
    km_filter *f = NULL;
    CHECK_OK(km_filter_create(2, &opts[o], &f, KM_E));
    const double raw[6] = {0.1234567, -1.7, 2.9, 1e-3, 0.3, -0.7};
    double out[6];
    size_t diff = 0;
    for (int t = 0; t < 100; ++t) {
      km_filter_push(f, raw, out);
      for (int k = 0; k < 6; ++k)
        diff += out[k] != raw[k];
    }
    CHECK_MSG(diff == 0, "options %zu: %zu values changed", o, diff);
    km_filter_free(&f);
    CHECK(f == NULL);
  }
  km_filter_free(NULL); /* no-op */
}

static void test_ramp(void) {
  /* Holt's method has a linear trend as a fixed point: after warm-up the error vanishes. */
  const double v[3] = {0.01, -0.02, 0.005}; /* metres per frame */
  km_filter *f = NULL, *single = NULL;
  CHECK_OK(km_filter_create(1, NULL, &f, KM_E));
  km_filter_options no_trend = {.trend = KM_FILTER_ZERO};
  CHECK_OK(km_filter_create(1, &no_trend, &single, KM_E));
  double err_early = 0, err_late = 0, lag_single = 0;
  for (int t = 0; t < 300; ++t) {
    double raw[3], out[3], out1[3];
    for (int k = 0; k < 3; ++k)
      raw[k] = 1.0 + v[k] * t;
    km_filter_push(f, raw, out);
    km_filter_push(single, raw, out1);
    double e = 0, e1 = 0;
    for (int k = 0; k < 3; ++k) {
      e = fmax(e, fabs(out[k] - raw[k]));
      e1 = fmax(e1, fabs(out1[k] - raw[k]));
    }
    if (t == 5) err_early = e;
    if (t >= 250) err_late = fmax(err_late, e);
    if (t == 299) lag_single = e1;
  }
  CHECK_MSG(err_early > 1e-3, "early error %g (warm-up should show)", err_early);
  CHECK_MSG(err_late < 1e-9, "late error %g", err_late);
  /* Without the trend term (single exponential smoothing) the lag stays at s/(1-s) * step. */
  CHECK_NEAR(lag_single, 0.02, 1e-9);
  km_filter_free(&f);
  km_filter_free(&single);

  /* prediction = 1 frame: the output leads the raw input by one step once locked on. */
  km_filter_options pred = {.prediction = 1};
  CHECK_OK(km_filter_create(1, &pred, &f, KM_E));
  double lead = 0;
  for (int t = 0; t < 300; ++t) {
    double raw[3] = {v[0] * t, v[1] * t, v[2] * t}, out[3];
    km_filter_push(f, raw, out);
    lead = out[0] - raw[0];
  }
  CHECK_NEAR(lead, v[0], 1e-9);
  km_filter_free(&f);

  /* No smoothing: raw passes through exactly. */
  km_filter_options raw_opt = {.smoothing = KM_FILTER_ZERO};
  CHECK_OK(km_filter_create(1, &raw_opt, &f, KM_E));
  size_t diff = 0;
  for (int t = 0; t < 50; ++t) {
    double raw[3] = {uniform(), uniform(), uniform()}, out[3];
    km_filter_push(f, raw, out);
    for (int k = 0; k < 3; ++k)
      diff += out[k] != raw[k];
  }
  CHECK(diff == 0);
  km_filter_free(&f);
}

static void test_missing(void) {
  km_filter *f = NULL, *g = NULL;
  CHECK_OK(km_filter_create(2, NULL, &f, KM_E));
  CHECK_OK(km_filter_create(2, NULL, &g, KM_E));
  double out[6], outg[6];
  /* Joint 1 never seen yet: NaN; joint 0 fine. */
  double raw0[6] = {0, 0, 0, NAN, NAN, NAN};
  km_filter_push(f, raw0, out);
  CHECK(out[0] == 0 && isnan(out[3]) && isnan(out[4]) && isnan(out[5]));
  km_filter_reset(f);

  /* f sees a ramp with a 7-frame gap on joint 0; g sees the same ramp with the gap frames
   * simply left out. A missing joint must leave the state untouched, so both agree after. */
  int tf = 0;
  size_t held_wrong = 0, mismatch = 0;
  for (int t = 0; t < 60; ++t) {
    double raw[6] = {0.02 * t, 1, 0.5 * sin(0.1 * t), 1, 1, 1};
    bool gap = t >= 20 && t < 27;
    double in[6];
    memcpy(in, raw, sizeof in);
    if (gap) in[0] = in[1] = in[2] = NAN;
    double before[3] = {out[0], out[1], out[2]};
    km_filter_push(f, in, out);
    if (gap) {
      held_wrong += out[0] != before[0] || out[1] != before[1] || out[2] != before[2];
      continue;
    }
    km_filter_push(g, raw, outg);
    ++tf;
    for (int k = 0; k < 6; ++k)
      mismatch += out[k] != outg[k];
  }
  CHECK_MSG(held_wrong == 0, "output not held during the gap (%zu)", held_wrong);
  CHECK_MSG(mismatch == 0, "gap corrupted the state (%zu values differ)", mismatch);
  CHECK(tf == 53);
  /* Infinite values count as missing too. */
  double inf_in[6] = {INFINITY, 0, 0, 1, 1, 1}, prev0 = out[0];
  km_filter_push(f, inf_in, out);
  CHECK(out[0] == prev0);
  km_filter_free(&f);
  km_filter_free(&g);
}

/* Catch-up (issue 12): a joint held for 3 frames comes back 0.6 m away (a lost and re-found
 * foot). With catch-up on (3 m/s; off by default) no output step exceeds catchup_speed / fps plus
 * the joint's own motion (and the filter's lag behind that ramp), and the output reaches the new
 * place within a second; off, it snaps. Both filters kinds. */
static void test_catch_up(void) {
  for (int kind = 0; kind < 2; ++kind) {
    double worst[2] = {0, 0}, end_err[2] = {0, 0};
    for (int on = 0; on < 2; ++on) {
      km_filter_options o = {.kind = kind ? KM_FILTER_ONE_EURO : KM_FILTER_HOLT,
                             .catchup_speed = on ? 3 : 0};
      km_filter *f = NULL;
      CHECK_OK(km_filter_create(1, &o, &f, KM_E));
      double prev[3] = {0, 0, 0};
      for (int t = 0; t < 60; ++t) {
        double x[3] = {0.001 * t, t >= 20 ? 0.6 : 0, 0}, y[3];
        if (t >= 17 && t < 20) x[0] = x[1] = x[2] = NAN;
        km_filter_push(f, x, y);
        if (t)
          worst[on] = fmax(worst[on], hypot(hypot(y[0] - prev[0], y[1] - prev[1]), y[2] - prev[2]));
        memcpy(prev, y, sizeof prev);
        if (t == 59) end_err[on] = fabs(y[1] - 0.6);
      }
      km_filter_free(&f);
    }
    /* default 3 m/s at 30 fps: 0.1 m per frame; the Holt filter's lag behind that ramp adds
     * a little when it ends */
    CHECK_MSG(worst[1] <= 0.13, "kind %d: catch-up step %.3f m > 0.13", kind, worst[1]);
    CHECK_MSG(worst[0] >= 0.2, "kind %d: without catch-up the step is %.3f m (a snap expected)",
              kind, worst[0]);
    CHECK_MSG(end_err[1] < 1e-3, "kind %d: catch-up did not arrive (%.4f m off)", kind, end_err[1]);
  }
}

/* Glitch catch-up (issue 12): an arm (shoulder -> elbow -> wrist, forearm 0.25 m) whose
 * wrist is lost for 3 frames and re-found with the forearm turned 90 degrees (0.35 m away):
 * the wrist's output eases back in (no step above 0.15 m; a snap is 0.35 m) and arrives, and
 * meanwhile the forearm keeps its length (the direction turns, not a chord). */
static void test_glitch_catch_up(void) {
  int32_t par[3] = {-1, 0, 1};
  km_glitch *g = NULL, *ga = NULL; /* ga: the same, in place (clean aliasing raw) */
  CHECK_OK(km_glitch_create(3, par, NULL, &g, KM_E));
  CHECK_OK(km_glitch_create(3, par, NULL, &ga, KM_E));
  double prev[3] = {NAN, NAN, NAN}, worst = 0, stretch = 0, y[9];
  size_t alias_diff = 0;
  for (int t = 0; t < 40; ++t) {
    double x[9] = {0, 1.4, 0, 0.3, 1.4, 0, 0.55, 1.4, 0};
    if (t >= 10 && t < 13) x[6] = x[7] = x[8] = NAN; /* wrist lost */
    if (t >= 13) x[6] = 0.3, x[7] = 1.15;            /* re-found, the forearm pointing down */
    km_glitch_push(g, x, y);
    km_glitch_push(ga, x, x);
    for (int k = 0; k < 9; ++k)
      alias_diff += !(x[k] == y[k] || (isnan(x[k]) && isnan(y[k])));
    if (isnan(y[6])) continue;
    if (!isnan(prev[0]))
      worst = fmax(worst, hypot(hypot(y[6] - prev[0], y[7] - prev[1]), y[8] - prev[2]));
    stretch = fmax(stretch, fabs(hypot(hypot(y[6] - y[3], y[7] - y[4]), y[8] - y[5]) - 0.25));
    memcpy(prev, y + 6, sizeof prev);
  }
  CHECK_MSG(worst <= 0.15, "glitch catch-up: a wrist step of %.3f m", worst);
  CHECK_MSG(fabs(y[6] - 0.3) < 1e-3 && fabs(y[7] - 1.15) < 1e-3,
            "glitch catch-up did not arrive: wrist at %.3f %.3f", y[6], y[7]);
  CHECK_MSG(stretch < 1e-9, "the forearm's length changed by %.3f m while easing in", stretch);
  CHECK_MSG(alias_diff == 0, "in place: %zu values differ", alias_diff);
  km_glitch_free(&g);
  km_glitch_free(&ga);
}

static double noise_rms(const km_filter_options *o, double amp) {
  km_filter *f = NULL;
  if (km_filter_create(1, o, &f, NULL) != KM_OK) return NAN;
  rng = 12345;
  double s2 = 0;
  int n = 0;
  for (int t = 0; t < 2000; ++t) {
    double raw[3] = {0.3 + amp * (2 * uniform() - 1), 1.2 + amp * (2 * uniform() - 1),
                     -2 + amp * (2 * uniform() - 1)},
           out[3];
    km_filter_push(f, raw, out);
    if (t >= 100) {
      s2 += pow(out[0] - 0.3, 2) + pow(out[1] - 1.2, 2) + pow(out[2] + 2, 2);
      ++n;
    }
  }
  km_filter_free(&f);
  return sqrt(s2 / n);
}

static void test_jitter(void) {
  /* 5 mm noise on a still joint: the jitter radius (5 cm) damps it far more than the
   * double exponential alone. */
  km_filter_options plain = {0}, jit = {.jitter_radius = 0.05};
  double r_plain = noise_rms(&plain, 0.005), r_jit = noise_rms(&jit, 0.005);
  double r_raw = 0.005; /* uniform in [-a,a]: a^2/3 per axis, 3 axes */
  CHECK_MSG(r_plain < r_raw && r_jit < 0.5 * r_plain && r_jit < 0.25 * r_raw,
            "raw %g plain %g jitter %g", r_raw, r_plain, r_jit);

  /* Large moves pass the jitter stage: a 1 m jump is followed (the last millimetre converges
   * slowly, as in the SDK, because it falls inside the jitter radius). */
  km_filter *f = NULL;
  CHECK_OK(km_filter_create(1, &jit, &f, KM_E));
  double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, out[3];
  km_filter_push(f, a, out);
  for (int t = 0; t < 100; ++t)
    km_filter_push(f, b, out);
  CHECK_NEAR(out[0], 1.0, 1e-3);
  km_filter_free(&f);

  /* max_deviation bounds the distance to the raw sample even with aggressive prediction. */
  km_filter_options dev = {.smoothing = 0.9, .prediction = 5, .max_deviation = 0.04};
  CHECK_OK(km_filter_create(1, &dev, &f, KM_E));
  double worst = 0;
  for (int t = 0; t < 200; ++t) {
    double raw[3] = {0.5 * sin(0.2 * t), 0.05 * t, 0}, o[3];
    km_filter_push(f, raw, o);
    worst = fmax(worst, sqrt(pow(o[0] - raw[0], 2) + pow(o[1] - raw[1], 2) + pow(o[2], 2)));
  }
  CHECK_MSG(worst <= 0.04 + 1e-12, "deviation %g", worst);
  km_filter_free(&f);
}

static void test_options(void) {
  km_filter *f = NULL;
  km_filter_options bad[] = {{.smoothing = 1.0},
                             {.trend = 1.5},
                             {.prediction = -1},
                             {.jitter_radius = NAN},
                             {.max_deviation = -0.1}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
    CHECK_STATUS(km_filter_create(3, &bad[i], &f, KM_E), KM_ERR_INVALID);
    CHECK(f == NULL);
  }
}

/* Issue 12: One Euro keeps a constant exactly, tracks a ramp with a lag that shrinks as the
 * speed term opens the cutoff, and is smoother than the input on noise. */
static void test_one_euro(void) {
  km_filter_options o = {.kind = KM_FILTER_ONE_EURO, .fps = 30};
  km_filter *f = NULL;
  CHECK_OK(km_filter_create(2, &o, &f, KM_E));
  const double raw[6] = {0.25, -1.5, 3.0, 1e-3, 0.3, -0.7};
  double out[6];
  size_t diff = 0;
  for (int t = 0; t < 100; ++t) {
    km_filter_push(f, raw, out);
    for (int k = 0; k < 6; ++k)
      diff += out[k] != raw[k];
  }
  CHECK_MSG(diff == 0, "one euro: constant changed %zu values", diff);
  km_filter_free(&f);
  /* ramp at 1 m/s: the output follows, lag bounded and settled */
  km_filter_options slow = o;
  slow.beta = 1e-12; /* no speed adaptation: plain low-pass at min_cutoff */
  km_filter *g = NULL;
  CHECK_OK(km_filter_create(1, &o, &f, KM_E));
  CHECK_OK(km_filter_create(1, &slow, &g, KM_E));
  double lag = 0, lag_slow = 0, lag_prev = 0;
  for (int t = 0; t < 120; ++t) {
    double x[3] = {t / 30.0, 0, 0}, y[3], z[3];
    km_filter_push(f, x, y);
    km_filter_push(g, x, z);
    CHECK(y[0] <= x[0] + 1e-12 && y[0] >= 0);
    lag_prev = lag;
    lag = x[0] - y[0];
    lag_slow = x[0] - z[0];
  }
  CHECK_MSG(fabs(lag - lag_prev) < 1e-6, "one euro ramp lag not settled: %g vs %g", lag, lag_prev);
  CHECK_MSG(lag < 0.1 && lag < lag_slow, "one euro ramp lag %g (without speed term %g)", lag,
            lag_slow);
  /* noise: smaller frame-to-frame steps than the input */
  km_filter_reset(f);
  double prev_in = 0, prev_out = 0, tv_in = 0, tv_out = 0;
  for (int t = 0; t < 300; ++t) {
    double x[3] = {0.01 * (uniform() - 0.5), 0, 0}, y[3];
    km_filter_push(f, x, y);
    if (t) {
      tv_in += fabs(x[0] - prev_in);
      tv_out += fabs(y[0] - prev_out);
    }
    prev_in = x[0];
    prev_out = y[0];
  }
  CHECK_MSG(tv_out < 0.5 * tv_in, "one euro does not smooth noise: %g vs %g", tv_out, tv_in);
  km_filter_free(&f);
  km_filter_free(&g);
  km_filter_options bad = {.kind = KM_FILTER_ONE_EURO, .min_cutoff = -1};
  CHECK_STATUS(km_filter_create(1, &bad, &f, KM_E), KM_ERR_INVALID);
}

/* Issue 12: Holt no longer carries a joint past its input when a fast move stops. */
static void test_holt_no_overshoot(void) {
  for (int pred = 0; pred < 2; ++pred) {
    km_filter_options o = {.smoothing = 0.5, .trend = 0.9, .prediction = pred};
    km_filter *f = NULL;
    CHECK_OK(km_filter_create(1, &o, &f, KM_E));
    double worst = 0;
    for (int t = 0; t < 60; ++t) {
      double x[3] = {0, t < 10 ? -0.1 * t : -0.9, 0}, y[3]; /* a foot coming down, then stop */
      km_filter_push(f, x, y);
      /* prediction extrapolates while moving; once the input stops, nothing goes past it */
      if (!pred || t > 10) worst = fmin(worst, y[1]);
    }
    CHECK_MSG(worst >= -0.9 - 1e-12, "Holt (prediction %d) overshoots the stop: %g below -0.9",
              pred, -0.9 - worst);
    km_filter_free(&f);
  }
}

/* Issue 12: the glitch rejector rejects a one-frame spike, a too-long bone and a re-found
 * joint (carried by its parent meanwhile, or missing without one), counts them, and lets a
 * real move through after a few frames. */
static void test_glitch(void) {
  const int32_t parents[2] = {-1, 0};
  km_glitch *g = NULL;
  km_glitch_options o = {.fps = 30}; /* 12 m/s: 0.4 m per frame */
  CHECK_OK(km_glitch_create(2, parents, &o, &g, KM_E));
  double x[6], y[6];
  for (int t = 0; t < 20; ++t) { /* a 0.3 m bone, slowly moving */
    double a = 0.01 * t;
    double v[6] = {a, 1, 0, a, 1.3, 0};
    memcpy(x, v, sizeof v);
    km_glitch_push(g, x, y);
    CHECK(memcmp(x, y, sizeof x) == 0);
  }
  km_glitch_stats st;
  km_glitch_stats_get(g, &st);
  CHECK(st.rejected == 0 && st.samples == 40 && st.frames == 20);
  /* a rejected child comes out carried by its parent at the last accepted offset (0.3 m up),
   * not at the glitch (catch-up on, the default; off, it would be NaN) */
#define CARRIED (!isnan(y[0]) && y[3] == y[0] && fabs(y[4] - (y[1] + 0.3)) < 1e-12 && y[5] == y[2])
  x[4] += 0.6; /* spike on the child */
  km_glitch_push(g, x, y);
  CHECK(CARRIED);
  x[4] -= 0.6;
  km_glitch_push(g, x, y);
  CHECK(!isnan(y[3]));
  x[4] += 0.2; /* slow enough, but the bone grows by 67% */
  km_glitch_push(g, x, y);
  CHECK(CARRIED);
  x[4] -= 0.2;
  double lost[6] = {x[0], x[1], x[2], NAN, NAN, NAN};
  km_glitch_push(g, lost, y);
  km_glitch_push(g, x, y); /* re-found: held one frame */
  CHECK(CARRIED);
#undef CARRIED
  km_glitch_push(g, x, y);
  CHECK(!isnan(y[3]));
  km_glitch_stats_get(g, &st);
  CHECK_MSG(st.rejected == 3 && st.speed == 1 && st.bone == 1 && st.refound == 1 && st.missing == 1,
            "stats: rejected %zu speed %zu bone %zu refound %zu missing %zu", st.rejected, st.speed,
            st.bone, st.refound, st.missing);
  /* a real 0.6 m relocation of the whole chain is accepted once the allowance has grown
   * past it (2 frames x 0.4 m) */
  for (int k = 0; k < 6; k += 3)
    x[k] += 0.6;
  km_glitch_push(g, x, y);
  CHECK(isnan(y[0]));
  km_glitch_push(g, x, y);
  CHECK(!isnan(y[0]) && !isnan(y[3]));
  km_glitch_free(&g);
  CHECK(g == NULL);

  /* Timed frames (live input): a 0.6 m move refused one frame (1/30 s) after the last
   * accepted sample is accepted when the frame comes 0.5 s later (a silent tracker, or
   * frames the server dropped), and an untimed frame still counts as one frame (catch-up
   * off: the accepted sample itself comes out). */
  km_glitch_options o2 = o;
  o2.catchup_speed = -1;
  CHECK_OK(km_glitch_create(1, NULL, &o2, &g, KM_E));
  double p[3] = {0, 1, 0}, q[3];
  km_glitch_push_at(g, p, 10.0, q);
  CHECK(!isnan(q[0]));
  p[0] += 0.6;
  km_glitch_push_at(g, p, 10.0 + 1.0 / 30, q);
  CHECK(isnan(q[0]));
  km_glitch_push_at(g, p, 10.5, q);
  CHECK(!isnan(q[0]) && q[0] == p[0]);
  p[0] += 0.6;
  km_glitch_push(g, p, q);
  CHECK(isnan(q[0]));
  km_glitch_free(&g);
}

/* A joint whose first samples were the glitch (a hand 0.6 m off in frame 0, or in frames 0-4):
 * the true samples are rejected (too fast; after 5 frames, a bone unlike the start's, which
 * would reject it for good), and once they have come steadily for as many frames as the start
 * had, the joint is restarted (listed by km_glitch_restarted, output as it comes, counted).
 * Without a start window it is not; nor after a good start longer than the glitch that
 * follows it. A root glitched with its child in frame 0 restarts (absolutely); the child,
 * steady relative to it, does not. km_filter_restart_joint forgets one joint's history. */
static void test_glitch_restart(void) {
  const int32_t parents[2] = {-1, 0};
  /* 0: child glitched in frame 0, 1: no start window, 2: a good start of 15 frames then a
   * 10-frame glitch, 3: the root glitched with its child, 4: child glitched in frames 0-4 */
  const int from[5] = {0, 0, 15, 0, 0}, to[5] = {1, 1, 25, 1, 5}, expect[5] = {2, -1, -1, 2, 9};
  for (int c = 0; c < 5; ++c) {
    km_glitch *g = NULL;
    km_glitch_options o = {.fps = 30, .start_seconds = c == 1 ? -1 : 0};
    CHECK_OK(km_glitch_create(2, parents, &o, &g, KM_E));
    int restarted_at = -1;
    double y[6];
    bool raw_out = false;
    for (int t = 0; t < 25; ++t) {
      double a = 0.005 * t, x[6] = {a, 1, 0, a, 1.3, 0};
      if (t >= from[c] && t < to[c]) {
        x[4] += 0.6;
        if (c == 3) x[1] += 0.6;
      }
      km_glitch_push(g, x, y);
      const bool *re = km_glitch_restarted(g);
      if (re) {
        CHECK(restarted_at < 0);
        restarted_at = t;
        CHECK(re[c == 3 ? 0 : 1] && !re[c == 3 ? 1 : 0]);
        raw_out = memcmp(x, y, sizeof x) == 0;
      }
    }
    km_glitch_stats st;
    km_glitch_stats_get(g, &st);
    CHECK_MSG(restarted_at == expect[c] && st.restarted == (expect[c] >= 0 ? 1u : 0u) &&
                  (expect[c] < 0 || raw_out),
              "case %d: restarted at frame %d (expected %d; raw out %d), %zu restarts", c,
              restarted_at, expect[c], raw_out, st.restarted);
    km_glitch_free(&g);
  }
  km_filter *f = NULL;
  CHECK_OK(km_filter_create(2, NULL, &f, KM_E));
  double x[6] = {0, 0, 0, 0, 0, 0}, y[6];
  for (int t = 0; t < 10; ++t)
    km_filter_push(f, x, y);
  km_filter_restart_joint(f, 1);
  km_filter_restart_joint(f, 2); /* out of range: nothing */
  x[0] = x[3] = 1;
  km_filter_push(f, x, y);
  CHECK_MSG(y[3] == 1 && y[0] < 1, "restarted joint %g (1), the other %g (< 1)", y[3], y[0]);
  km_filter_free(&f);
}

int main(void) {
  test_one_euro();
  test_holt_no_overshoot();
  test_glitch();
  test_glitch_restart();
  test_constant();
  test_ramp();
  test_missing();
  test_catch_up();
  test_glitch_catch_up();
  test_jitter();
  test_options();
  return km_test_finish("test_motion_filter");
}
