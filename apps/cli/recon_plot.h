/* gnuplot figure of a reconstruction report (used by `reconstruct --plot` and
 * `bench reconstruct --plot`). */
#ifndef KM_CLI_RECON_PLOT_H
#define KM_CLI_RECON_PLOT_H

#include "kinemesh.h"

/* Fig. 6 of Park & Lim, both ways: per frame, points -> surface (mean/p95/max) above and
 * surface -> points (mean/p95/max, the unsupported threshold, the flagged frames) below, as
 * a PNG through gnuplot (popen). */
km_status km_recon_report_plot(const char *png_path, const km_recon_report *r, km_error *err);

#endif
