/* Fig. 6 of Park & Lim: a reconstruction report's per-frame errors, both ways, as a PNG, drawn by
 * gnuplot through popen. An application concern (it runs a process), so it lives here and not
 * in the library. */
#include "recon_plot.h"

#include <stdbool.h>
#include <stdio.h>
#include <string.h>

km_status km_recon_report_plot(const char *png_path, const km_recon_report *r, km_error *err) {
  if (!png_path || !r)
    return km_error_set(err, KM_ERR_INVALID, "km_recon_report_plot: NULL argument");
  if (strpbrk(png_path, "'\"\n"))
    return km_error_set(err, KM_ERR_INVALID, "%s: plot path must not contain quotes", png_path);
  /* pngcairo when this gnuplot has it (gnuplot-nox usually does), else the libgd png */
  FILE *t = popen("gnuplot -e 'set terminal' 2>&1", "r");
  bool cairo = false;
  if (t) {
    char line[256];
    while (fgets(line, sizeof line, t))
      if (strstr(line, "pngcairo")) cairo = true;
    pclose(t);
  }
  FILE *g = popen("gnuplot 2>/dev/null", "w");
  if (!g) return km_error_set(err, KM_ERR_IO, "cannot run gnuplot (is it installed?)");
  /* two panels: the errors differ by two orders of magnitude when a limb is left behind */
  fprintf(g, "set terminal %s size 900,800\nset output '%s'\n", cairo ? "pngcairo" : "png",
          png_path);
  fprintf(g, "set multiplot layout 2,1\nset xlabel 'frame'\nset ylabel 'mm'\nset grid\n"
             "set key outside right top\n");
  fprintf(g, "set title 'Points to surface (each captured point to the reconstruction)'\n"
             "plot '-' using 1:2 with lines lw 2 title 'mean', '-' using 1:2 with lines "
             "title 'p95', '-' using 1:2 with lines title 'max'\n");
  for (int pass = 0; pass < 3; ++pass) {
    for (size_t f = 0; f < r->n_frames; ++f) {
      const km_recon_frame_stats *s = &r->frames[f];
      fprintf(g, "%zu %.6g\n", s->index, pass == 2 ? s->max_mm : pass ? s->p95_mm : s->mean_mm);
    }
    fprintf(g, "e\n");
  }
  double thr = r->unsupported_distance_mm > 0 ? r->unsupported_distance_mm : 30;
  fprintf(g,
          "set title 'Surface to points (each %s to the nearest point; "
          "crosses: frames flagged unsupported)'\n"
          "plot '-' using 1:2 with lines lw 2 title 'mean', '-' using 1:2 with lines title "
          "'p95', '-' using 1:2 with lines title 'max', %.6g with lines dt 2 title "
          "'unsupported beyond %.0f mm', '-' using 1:2 with points pt 2 ps 2 title 'flagged'\n",
          r->visibility_known ? "vertex facing a camera" : "template vertex", thr, thr);
  for (int pass = 0; pass < 4; ++pass) {
    size_t emitted = 0;
    for (size_t f = 0; f < r->n_frames; ++f) {
      const km_recon_frame_stats *s = &r->frames[f];
      if (pass == 3 && !s->unsupported) continue;
      fprintf(g, "%zu %.6g\n", s->index,
              pass == 3   ? s->surface_max_mm
              : pass == 2 ? s->surface_max_mm
              : pass      ? s->surface_p95_mm
                          : s->surface_mean_mm);
      ++emitted;
    }
    if (pass == 3 && !emitted) fprintf(g, "0 NaN\n"); /* gnuplot needs one row */
    fprintf(g, "e\n");
  }
  fprintf(g, "unset multiplot\n");
  int rc = pclose(g);
  if (rc != 0)
    return km_error_set(err, KM_ERR_IO, "%s: gnuplot failed (exit status %d)", png_path, rc);
  FILE *chk = fopen(png_path, "rb");
  if (!chk) return km_error_set(err, KM_ERR_IO, "%s: gnuplot wrote no file", png_path);
  fclose(chk);
  return KM_OK;
}
