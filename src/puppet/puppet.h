/* Requires: core, linalg, math, mesh, motion. */
/* Puppetry (Wu, Lu & Song): the reduced isoline model, the full ARAP reference solver.
 * Its public API is in include/kinemesh.h. */
#ifndef KM_PUPPET_PUPPET_H
#define KM_PUPPET_PUPPET_H

#include "core/core.h"

#endif
