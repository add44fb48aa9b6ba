/* Fig. 6 of Park & Lim: a reconstruction report's per-frame point error as a PNG, drawn by
 * gnuplot through popen. An application concern (it runs a process), so it lives here and not
 * in the library. */
#include "recon_plot.h"

#include <stdbool.h>
#include <stdio.h>
#include <string.h>

km_status km_recon_report_plot(const char *png_path, const km_recon_report *r, km_error *err) {
  if (!png_path || !r) return km_error_set(err, KM_ERR_INVALID, "km_recon_report_plot: NULL argument");
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
  fprintf(g, "set terminal %s size 900,500\nset output '%s'\n", cairo ? "pngcairo" : "png",
          png_path);
  fprintf(
      g, "set title 'Reconstruction error (distance points to surface)'\nset xlabel 'frame'\n"
         "set ylabel 'mm'\nset grid\nset key top left\n"
         "plot '-' using 1:2 with lines lw 2 title 'mean', '-' using 1:2 with lines title 'max'\n");
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t f = 0; f < r->n_frames; ++f)
      fprintf(g, "%zu %.6g\n", r->frames[f].index,
              pass ? r->frames[f].max_mm : r->frames[f].mean_mm);
    fprintf(g, "e\n");
  }
  int rc = pclose(g);
  if (rc != 0) return km_error_set(err, KM_ERR_IO, "%s: gnuplot failed (exit status %d)", png_path, rc);
  FILE *chk = fopen(png_path, "rb");
  if (!chk) return km_error_set(err, KM_ERR_IO, "%s: gnuplot wrote no file", png_path);
  fclose(chk);
  return KM_OK;
}

