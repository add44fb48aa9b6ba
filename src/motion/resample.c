/* Resampling a take to another frame rate (issue 12: --fps resamples instead of relabelling). */
#include "motion/motion.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

km_status km_take_resample(const km_take *in, double fps, km_take *out, km_error *err) {
  if (!in || !out) return km__fail(err, KM_ERR_INVALID, "km_take_resample: NULL argument");
  memset(out, 0, sizeof *out);
  if (!(fps > 0) || !isfinite(fps) || !(in->fps > 0) || !isfinite(in->fps))
    return km__fail(err, KM_ERR_INVALID,
                    "km_take_resample: frame rates must be positive (take %g fps, asked %g fps)",
                    in->fps, fps);
  if (in->n_frames == 0)
    return km__fail(err, KM_ERR_INVALID, "km_take_resample: the take has no frames");
  double nf = round((double)in->n_frames * fps / in->fps);
  if (nf < 1) nf = 1;
  if (nf > 1e8) return km__fail(err, KM_ERR_INVALID, "km_take_resample: %g frames is too many", nf);
  size_t n = (size_t)nf, nj = in->n_joints;
  out->n_frames = n;
  out->n_joints = nj;
  out->fps = fps;
  out->joint_names = km__calloc(nj ? nj : 1, sizeof(char *));
  out->parents = in->parents ? km__malloc(nj ? nj : 1, sizeof(int32_t)) : NULL;
  out->positions = km__malloc(n * (nj ? nj : 1), 3 * sizeof(double));
  if (!out->joint_names || (in->parents && !out->parents) || !out->positions) goto nomem;
  for (size_t j = 0; j < nj; ++j) {
    if (!(out->joint_names[j] =
              km__strdup(in->joint_names && in->joint_names[j] ? in->joint_names[j] : "")))
      goto nomem;
    if (in->parents) out->parents[j] = in->parents[j];
  }
  for (size_t k = 0; k < n; ++k) {
    double s = (double)k * in->fps / fps;
    size_t i0 = (size_t)floor(s);
    if (i0 >= in->n_frames - 1) i0 = in->n_frames - 1;
    size_t i1 = i0 + 1 < in->n_frames ? i0 + 1 : i0;
    double a = i1 == i0 ? 0.0 : s - (double)i0;
    if (a < 0) a = 0;
    if (a > 1) a = 1;
    for (size_t j = 0; j < nj; ++j) {
      const double *p = in->positions + (i0 * nj + j) * 3, *q = in->positions + (i1 * nj + j) * 3;
      double *o = out->positions + (k * nj + j) * 3;
      bool vp = isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
      bool vq = isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2]);
      for (int c = 0; c < 3; ++c) /* a missing end: the nearer sample, missing if it is */
        o[c] = vp && vq ? p[c] + a * (q[c] - p[c]) : (a < 0.5 ? p[c] : q[c]);
    }
  }
  return KM_OK;
nomem:
  km_take_free(out);
  return km__fail(err, KM_ERR_NOMEM, "km_take_resample: out of memory");
}
