/* Requires: core, linalg, math, mesh, motion, anim, recon. External: Embree. */
/* Test and demo material: the procedural character, generated motion, the depth-capture
 * simulator, primitive meshes. Its public API is in include/kinemesh.h; polygonize.h and
 * poses.h are private to it (tests may include them). */
#ifndef KM_SYNTH_SYNTH_H
#define KM_SYNTH_SYNTH_H

#include "core/core.h"

/* ==== synth: test fixtures / internal (not in include/kinemesh.h) ==== */

/* Primitive meshes for tests (closed, manifold, consistently oriented outward unless said
 * otherwise). Implemented in src/synth/primitives.c.
 * km_icosphere: 10*4^subdivisions+2 vertices on a sphere of `radius` about the origin.
 *   subdivisions  in: 0 .. 10
 *   radius        in: > 0
 *   out           out: allocated mesh; free with km_mesh_free */
km_status km_icosphere(int subdivisions, double radius, km_mesh *out, km_error *err);
/* Open rectangular grid in the z=0 plane, (nx+1)*(ny+1) vertices over [0,sx]x[0,sy],
 * 2*nx*ny triangles.
 *   nx, ny  in: cells >= 1;  sx, sy  in: size > 0
 *   out     out: allocated mesh; free with km_mesh_free */
km_status km_grid(int nx, int ny, double sx, double sy, km_mesh *out, km_error *err);
/* Closed capped cylinder along +z from z=0 to z=length: `rings`+1 rings of `segments`
 * vertices each plus two cap centres.
 *   segments  in: >= 3;  rings  in: >= 1;  radius, length  in: > 0
 *   out       out: allocated mesh; free with km_mesh_free */
km_status km_cylinder(int segments, int rings, double radius, double length, km_mesh *out,
                      km_error *err);

/* One frame of the capture simulator (km_capture_simulate runs it per frame): ray-casts a
 * posed mesh (Embree) from opt->cameras depth cameras on a ring; every camera shoots a
 * regular grid of rays over the mesh's bounding box as seen from it, so the total hit count
 * is about points_per_frame; surfaces hidden from all cameras get no points. Implemented in
 * src/synth/capture.c.
 *   posed  in: triangle mesh, #F > 0
 *   opt    in: may be NULL (defaults)
 *   frame  in: mixed into the noise seed
 *   out    out: allocated points; free with km_points_free
 * Errors: KM_ERR_DEGENERATE_MESH (no faces), KM_ERR_UNSUPPORTED (Embree cannot start). */
km_status km_capture_frame(const km_mesh *posed, const km_capture_options *opt, size_t frame,
                           km_points *out, km_error *err);

#endif
