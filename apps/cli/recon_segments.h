/* kinemesh reconstruct --segment-frames S [--overlap O] (issue 17): one long take in segments,
 * each initialised on its own first frame and tracked on its own, stitched by cross-fading the
 * overlap, then the temporal filter across the seams. Public API only (km_recon_*). */
#ifndef KM_CLI_RECON_SEGMENTS_H
#define KM_CLI_RECON_SEGMENTS_H

#include "kinemesh.h"

/* Segment k covers frames [k*S, min(n, (k+1)*S)) and is tracked on for `overlap` frames more;
 * in those frames the next segment's surfaces are blended in with weights 1/(O+1) ... O/(O+1).
 * Features (first-frame correspondences) go to the first segment only; the others start with
 * no correspondence (km_recon_first_frame's global search). The stitched refined and LBS-only
 * surfaces go through km_local_motion_filter over the whole take and then to out (.glb, .pc2 or
 * a directory). Prints one line per segment (frames, seconds) and a summary.
 *   paths     in: n point cloud frames
 *   mean_mm   out: mean point -> surface error over the frames (unfiltered); may be NULL
 * Returns an exit status (messages printed). */
int km_cli_reconstruct_segmented(char **paths, size_t n, const km_character *c,
                                 const km_recon_feature *feat, size_t nfeat,
                                 const km_recon_options *ro, size_t segment, size_t overlap,
                                 const char *out);

#endif
