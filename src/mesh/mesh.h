/* Requires: core, linalg, math. */
/* Meshes: reading and writing (OBJ, PLY, OFF, point clouds), topology, geometric operators
 * (Laplacians, mass, normals, local frames), sampling. Nothing about characters or motion.
 * Its public API is in include/kinemesh.h; mesh_io.h and mesh_args.h are private to it. */
#ifndef KM_MESH_MESH_H
#define KM_MESH_MESH_H

#include "core/core.h"

#endif
