/* kinemesh reconstruct --segment-frames S [--overlap O] (issue 17): one long take in segments,
 * each initialised on its own first frame and tracked on its own, stitched by cross-fading the
 * overlap, then the temporal filter across the seams. Public API only (km_recon_*).
 *
 * The segments are independent until the stitch, so they can run in other processes (batch
 * jobs on other MPI ranks or Slurm tasks): `--segment K --segment-dir DIR` tracks segment K
 * alone and writes its part (DIR/segment-KKKK.kmseg: the tracked surfaces as doubles, per-frame
 * statistics and joints), and `--segment-dir DIR` without --segment stitches the parts there.
 * The stitch does the same arithmetic on the same doubles whether the parts were tracked in
 * this process or read back, so the output has the same bytes either way. */
#ifndef KM_CLI_RECON_SEGMENTS_H
#define KM_CLI_RECON_SEGMENTS_H

#include "kinemesh.h"

typedef struct km_cli_segments {
  size_t frames;   /* S: frames of a segment (> 0) */
  size_t overlap;  /* O: frames a segment tracks into the next, cross-faded */
  long only;       /* >= 0: track only this segment and write its part into dir; < 0: all */
  const char *dir; /* parts folder: where segment `only` goes, or (only < 0) the parts to
                    * stitch; NULL with only < 0: track every segment here, one after the
                    * other */
} km_cli_segments;

/* Number of segments of n frames. */
size_t km_cli_segment_count(size_t n, size_t segment_frames);
/* The part file of segment k in dir (DIR/segment-KKKK.kmseg), allocated (caller frees); NULL
 * when out of memory. */
char *km_cli_segment_part_path(const char *dir, size_t k);

/* Segment k covers frames [k*S, min(n, (k+1)*S)) and is tracked on for O frames more; in those
 * frames the next segment's surfaces are blended in with weights 1/(O+1) ... O/(O+1).
 * Features (first-frame correspondences) go to the first segment only; the others start with
 * no correspondence (km_recon_first_frame's global search). The stitched refined and LBS-only
 * surfaces go through km_local_motion_filter over the whole take and then to out (.glb, .pc2 or
 * a directory) through ro->anim (so --export works as unsegmented).
 *   paths     in: n point cloud frames
 *   rep       out (not with sg->only >= 0): the report of the stitched take, as km_reconstruct
 *             fills it (per-frame statistics and joints from each frame's own segment; the
 *             jerk before/after the filter over the stitched take; no unsupported vertex
 *             ids); free with km_recon_report_free
 * Prints one line per segment (frames, seconds). Returns KM_OK or the error (err filled). */
km_status km_cli_reconstruct_segmented(char **paths, size_t n, const km_character *c,
                                       const km_recon_feature *feat, size_t nfeat,
                                       const km_recon_options *ro, const km_cli_segments *sg,
                                       const char *out, km_recon_report *rep, km_error *err);

#endif
