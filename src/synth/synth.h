/* Requires: core, linalg, math, mesh, motion, anim, recon. External: Embree. */
/* Test and demo material: the procedural character, generated motion, the depth-capture
 * simulator, primitive meshes. Its public API is in include/kinemesh.h; polygonize.h and
 * poses.h are private to it (tests may include them). */
#ifndef KM_SYNTH_SYNTH_H
#define KM_SYNTH_SYNTH_H

#include "core/core.h"

#endif
