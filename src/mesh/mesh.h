/* Requires: core, linalg, math. External: cJSON, meshoptimizer, Draco. */
/* Meshes: reading and writing (OBJ, PLY, OFF, glTF in, point clouds), orientation, topology,
 * geometric operators (Laplacians, mass, normals, local frames), sampling. Nothing about characters
 * or motion. Its public API is in include/kinemesh.h; mesh_io.h and mesh_args.h are private to it.
 */
#ifndef KM_MESH_MESH_H
#define KM_MESH_MESH_H

#include "core/core.h"
#include <math.h>

/* Coincident vertices: for each vertex v with keep[v] (keep NULL: every vertex), lo[v] = the
 * lowest kept vertex whose position has the same bit pattern (v itself when none is lower);
 * lo[v] = v for the others. Equal bits, not equal values: -0 and 0 stay apart and a NaN is
 * equal to its own bits, a consistent relation whatever the values. The one table of exact
 * positions: km__mesh_weld, the seam count of km_mesh_info and the STL reader's corners.
 *   V    #n x 3 positions
 *   keep #n, or NULL
 *   lo   out: #n */
km_status km__coincident_lowest(const double *V, size_t n, const bool *keep, int32_t *lo,
                                km_error *err);

/* The mesh with its coincident vertices (the same position, bit for bit) merged into one: the
 * surface a glTF exporter split at its texture seams, joined again. Only where that joins
 * something: two used vertices coincide and the mesh is in pieces or open (coincident vertices
 * inside one closed piece, the dinosaur's 8, cut nothing and are left apart). Faces keep their
 * order and count (a face may come out degenerate where a seam ran across it).
 *   out->w      #W < #V vertices, in the order of each class's lowest vertex id (no attributes)
 *   out->to_w   #V: the welded vertex of each vertex
 *   out->first  #W: the lowest vertex id of each welded vertex's copies
 * All empty (to_w NULL) when nothing joins: the caller works on m itself. Free with
 * km__weld_free. */
typedef struct km__weld {
  km_mesh w;
  int32_t *to_w, *first;
} km__weld;
km_status km__mesh_weld(const km_mesh *m, km__weld *out, km_error *err);
void km__weld_free(km__weld *w);

/* A face with a repeated vertex index (a triangle collapsed onto an edge or a point, as
 * decimation and welding leave them): no surface. Topology (edges, boundaries, non-manifold
 * edges, pieces) and geodesics leave it out: counted, one collapsed triangle on an edge made
 * that edge non-manifold and rig refused the mesh; one joining two far vertices opened a
 * boundary between them and armadillo_1k rigged as a bust. */
static inline bool km__face_collapsed(const int32_t *t) {
  return t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
}

/* A local frame's tangent before normalisation (km_local_frames, and the pose transfer's
 * per-frame frames, transfer/offsets.c): the edge e to the reference neighbour projected on
 * the plane of the unit normal n; when e is zero, not finite or (almost) along n (|t| <= 1e-12
 * |e|), the coordinate axis least aligned with n, projected. t (3) out; returns |t|^2. */
static inline double km__frame_tangent(const double n[3], const double e[3], double t[3]) {
  double le2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
  double d = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
  t[0] = e[0] - d * n[0], t[1] = e[1] - d * n[1], t[2] = e[2] - d * n[2];
  double lt2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
  if (!(le2 > 0) || !isfinite(lt2) || !(lt2 > 1e-24 * le2)) {
    int ax = 0;
    for (int c = 1; c < 3; ++c)
      if (fabs(n[c]) < fabs(n[ax])) ax = c;
    t[0] = -n[ax] * n[0], t[1] = -n[ax] * n[1], t[2] = -n[ax] * n[2];
    t[ax] += 1;
    lt2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
  }
  return lt2;
}

/* The nearest of many queries to one point set: the points sorted along x once, each query
 * scanning outward from its x until the slab is wider than its best distance (for points on a
 * surface, a few hundred of a body's 50k instead of all). Ties go to the lower id, NaN points
 * never match, as km_nearest_vertices.
 *   V  #V*3 points, kept (not copied) until km__nearest_x_free
 *   km__nearest_x_query returns the nearest point's id, -1 when there is none */
typedef struct km__nearest_x {
  const double *V;
  double *xs;   /* #n x coordinates, ascending */
  int32_t *ord; /* #n point ids in that order */
  size_t n;
} km__nearest_x;
km_status km__nearest_x_build(const double *V, size_t n, km__nearest_x *out, km_error *err);
int32_t km__nearest_x_query(const km__nearest_x *ix, const double p[3]);
void km__nearest_x_free(km__nearest_x *ix);

/* A body and its small loose pieces (issue 11: a game character's eyes, teeth or buckles, a
 * scan's loose bits): pieces are the connected components of m's faces; the body is the
 * largest (most vertices), and it counts as one only when every other piece has at most a
 * quarter of its vertices (two bodies side by side do not).
 *   out->body       the largest piece as a mesh of its own: #B vertices (V, F; no attributes),
 *                   in m's order
 *   out->to_body    #V: each vertex's body vertex; for a loose piece's vertex (or one only
 *                   collapsed faces use) the body vertex nearest to it (Euclidean, at rest),
 *                   when its piece wraps the body (a belt, a coat: half its vertices or more
 *                   within 0.05 of the body's diagonal from it, and spanning more than 0.1 of
 *                   it), otherwise (eyes, a buckle, a sword, a ground plane) the one body
 *                   vertex nearest to the piece, which the piece then follows rigidly;
 *                   for a vertex in no face -1
 *   out->from_body  #B: the vertex of m of each body vertex
 *   out->n_pieces   pieces in all; out->largest_other: vertices of the largest other piece
 * *found false with out->body empty (to_body NULL) when m is one piece, or another piece is more
 * than a quarter of the body (n_pieces and largest_other still say so). The nearest body vertex
 * comes from km__nearest_x. Free with km__body_free. */
typedef struct km__body {
  km_mesh body;
  int32_t *to_body, *from_body;
  bool *rigid;    /* #V: the vertex's piece follows its to_body vertex as a whole (NULL: none) */
  int32_t *piece; /* #V: the loose piece of each vertex, 0 .. n_pieces - 2; -1: the body's, or
                     in no face */
  size_t n_pieces, body_vertices, largest_other;
  size_t rigid_pieces; /* the loose pieces that do so */
} km__body;
km_status km__mesh_body(const km_mesh *m, km__body *out, bool *found, km_error *err);
void km__body_free(km__body *b);
/* How many of a file's n vertices lie in a loose piece of bd (found by km__mesh_body on the
 * file's mesh, to_w NULL, or on its seam-welded mesh, to_w #n: each file vertex's welded one):
 * the count info and rig print, in the file's vertices. */
size_t km__body_loose_vertices(const km__body *bd, const int32_t *to_w, size_t n);
/* The body of a file as rig and the solvers see it: km__mesh_weld (wd->to_w NULL when no seam
 * joins anything), then km__mesh_body on the joined mesh, or on m itself. On success free both
 * (km__weld_free, km__body_free); on failure both are freed. */
km_status km__file_body(const km_mesh *m, km__weld *wd, km__body *bd, bool *found, km_error *err);
/* The vertices of m's loose pieces that lie on its floor, ground #V: pieces of a body with
 * small loose pieces (km__mesh_body, after joining the seams) whose highest point is within
 * 0.01 of the body's height (y extent) above the body's lowest point, along y (m in kinemesh's
 * frame, y up): a ground plane or a plinth exported with the character, which an animation
 * keeps still instead of carrying it with a foot. *n_pieces: how many such pieces. */
km_status km__ground_vertices(const km_mesh *m, bool *ground, size_t *n_pieces, km_error *err);
/* km__ground_vertices for a body bd that km__mesh_body found on m itself (no seam joined):
 * ground #V, every entry written. */
km_status km__body_ground(const km_mesh *m, const km__body *bd, bool *ground, size_t *n_pieces,
                          km_error *err);
/* The vertices that make m's shape, keep #V: the body's when m (joined at its seams, as
 * km__mesh_weld joins them) is a body with small loose pieces (km__mesh_body), otherwise every
 * vertex of a face that is not collapsed; every vertex when m has no faces, or when every face
 * is collapsed (the retargeter's height was NaN on such a mesh, its stray-vertex fallback
 * having gone into this function). What the
 * orientation guess, the character's height (the performer-to-character scale) and its rest
 * floor measure: a ground plane exported with a character, a prop beside it or a vertex no face
 * uses is not the character. With a face index out of range: the vertices the faces name. */
km_status km__shape_vertices(const km_mesh *m, bool *keep, km_error *err);

/* Edge-graph geodesic distances: Dijkstra over the mesh's edges with an indexed binary heap,
 * the one Dijkstra of the library (geodesic.c). Created once per connectivity (faces of m;
 * m's positions are not kept); each run reuses its scratch and does not allocate. */
typedef struct km__geodesic km__geodesic;
km_status km__geodesic_create(const km_mesh *m, km__geodesic **out, km_error *err);
/* Distances along edges from seed over positions V (#V*3, same vertex count as the create
 * mesh). Edges that would reach past radius are not followed (INFINITY: no bound); with
 * n_stop > 0 the run ends as soon as every vertex of stop[] is settled (their distances are
 * then final; others may be larger than the truth). Returns the #V distances (INFINITY: not
 * reached), valid until the next run; reached/n_reached (may be NULL): the vertices given a
 * finite distance, seed first, in the order they were reached. */
const double *km__geodesic_run(km__geodesic *g, const double *V, int32_t seed, double radius,
                               const int32_t *stop, size_t n_stop, const int32_t **reached,
                               size_t *n_reached);
/* The same from a set of seeds (n_seeds >= 1, repeats allowed): each vertex's distance to the
 * nearest seed along edges; reached lists the seeds first. */
const double *km__geodesic_run_set(km__geodesic *g, const double *V, const int32_t *seeds,
                                   size_t n_seeds, double radius, const int32_t *stop,
                                   size_t n_stop, const int32_t **reached, size_t *n_reached);
void km__geodesic_free(km__geodesic **g);

/* A bust's base (the autorig's and the rig writer's one test): an open cut at the bottom of a
 * mesh in kinemesh's frame (y up), i.e. a boundary loop (km_boundary_loops) whose vertices all
 * lie within 0.06 of the height (y extent), or 2.5 mean edge lengths when that is more (a
 * coarse mesh's cut is ragged), of the lowest vertex and which spans at least 0.3 of
 * the mesh's width (x extent) or 0.8 of its bottom's (the vertices that low; a T-posed upper
 * body's waist is 0.2 of its arm span): a bust's chest or neck cut, not the small holes of a
 * scan's soles. *found: whether there is one; *cut_top: the highest y of the widest such loop. */
km_status km__bust_base(const km_mesh *m, bool *found, double *cut_top, km_error *err);
/* The same in a mesh's own axes: up (0..2: x, y, z) pointing up_sign (+1, -1), widths along
 * lat (the lateral axis); *cut_top along up as stored. */
km_status km__bust_base_axes(const km_mesh *m, int up, int up_sign, int lat, bool *found,
                             double *cut_top, km_error *err);
/* The same with the mesh's boundary loops given (km_boundary_loops: loop #V, nl loops), for a
 * caller that asks along several axes (km_mesh_frame_guess: six directions, two widths). */
km_status km__bust_base_axes_loops(const km_mesh *m, const int32_t *loop, size_t nl, int up,
                                   int up_sign, int lat, bool *found, double *cut_top,
                                   km_error *err);
/* A seated body's base (a mesh in kinemesh's frame, y up, that sits on its bottom: a sitting
 * rabbit, a figure on a plinth): the faces wholly within 0.05 of the height (y extent) of the
 * lowest vertex form one part (joined along faces; parts of under 0.2 of its vertices left
 * out) that spans at least 0.5 of the mesh's width (x extent) and of its depth (z extent) and
 * holds under half the vertices. A
 * standing body's bottom 0.05 is its separate feet (two or four parts, each 0.12 to 0.25 of the
 * width on the meshes in ../shared/data; the Stanford bunny's one part spans 0.71 x 0.74), a
 * round body's a small cap (an ellipsoid's spans 0.44), a cat lying on its side a strip of its
 * flank (0.16 x 0.15). *found: whether it sits; *base_top: the y of the top of that 0.05. */
km_status km__seated_base(const km_mesh *m, bool *found, double *base_top, km_error *err);
/* The base a bust or an upper body stands on (the autorig's and the rig writer's one test):
 * an open cut (km__bust_base), else a broad base it sits on (km__seated_base). *top: the cut's
 * or the seated base's top y. */
km_status km__rest_base(const km_mesh *m, bool *found, double *top, km_error *err);

/* One accessor of a glTF (.glb, or .gltf with data: URIs) in memory, as doubles: any component
 * type (KHR_mesh_quantization's byte / short, normalized or not, as the specification reads
 * them), its buffer view decoded when EXT_meshopt_compression compresses it (io_gltf.c, the
 * mesh reader's code). No node transform is applied: a quantised accessor's dequantisation
 * (the node's scale / translation, inverse bind matrices) is the caller's. For the animation
 * reader's morph targets and samplers of a compressed .glb.
 *   data, size      in: the file's bytes;  name: for messages
 *   accessor_index  in: index into `accessors`
 *   out             out: count*ncomp values (element i, component c at i*ncomp + c); free()
 *   count, ncomp    out: elements and components per element (1 SCALAR ... 16 MAT4)
 * Errors: KM_ERR_PARSE naming name and the accessor / bufferView, KM_ERR_UNSUPPORTED (sparse),
 * KM_ERR_NOMEM. */
km_status km__gltf_accessor_read(const void *data, size_t size, const char *name,
                                 int accessor_index, double **out, size_t *count, int *ncomp,
                                 km_error *err);
/* km__gltf_accessor_read for n accessors with one parse of the file: fn(ctx, k, values, count,
 * ncomp, err) is called for accessors[k] in order, values valid only during the call; a
 * non-KM_OK return stops and is returned. For the animation reader's morph targets (one per
 * frame: one parse each would reread the JSON of a long take per frame). */
typedef km_status (*km__gltf_accessor_fn)(void *ctx, size_t k, const double *values, size_t count,
                                          int ncomp, km_error *err);
km_status km__gltf_accessors_each(const void *data, size_t size, const char *name,
                                  const int *accessors, size_t n, km__gltf_accessor_fn fn,
                                  void *ctx, km_error *err);
/* The world transform (column-major 4x4) of the first instance of mesh `mesh` in the scene, as
 * the mesh reader applies it (a quantised file's dequantisation among it); the identity when no
 * node uses the mesh. For the animation reader's morph targets.
 * Errors: KM_ERR_PARSE naming name (a bad node hierarchy), KM_ERR_NOMEM. */
km_status km__gltf_mesh_transform(const void *data, size_t size, const char *name, int mesh,
                                  double M[16], km_error *err);

/* ---- OBJ output with its materials (io_obj.c): what convert, pose and the frame folders
 * write, so a textured model does not come out grey in Blender or an engine's OBJ import. */
/* Writes m as OBJ text: "# header" (NULL: "kinemesh"), then, when mtllib is not NULL and m has
 * materials, "mtllib <mtllib>" and "usemtl kinemesh_<k>" before each material's run of faces
 * (km__obj_write_materials writes the library). Vertex order and count as in m. Coordinates,
 * texture coordinates and colours exactly (%.17g); normals so too, or with float_normals to a
 * float's 9 digits (an animation frame's, recomputed per frame). */
km_status km__obj_write(FILE *f, const km_mesh *m, const char *header, const char *mtllib,
                        bool float_normals);
/* A deep copy of src (its images too) into dst; false when out of memory (dst then holds what
 * was copied: free it with km__material_free_images). */
bool km__material_copy(km_mesh_material *dst, const km_mesh_material *src);
/* The sRGB transfer function (IEC 61966-2-1) one way and the other, on [0, 1] (clamped):
 * km_mesh.colors are sRGB-encoded, glTF's COLOR_0 linear. */
double km__srgb_encode(double linear);
double km__srgb_decode(double srgb);
/* A colour in [0, 1] (km_mesh.colors) as the 8-bit values files store: round(255 c), clamped. */
void km__color8(const double c[4], unsigned char out[4]);
/* Frees a material's images (base colour and maps) and sets them NULL. */
void km__material_free_images(km_mesh_material *m);
/* The materials' texture slots as one numbering: slot i = k * KM__SLOTS + s is material k's
 * base colour (s 0: image, image_size, image_mime, image_sampler) or maps[s - 1]; bytes NULL
 * when it has none. */
#define KM__SLOTS (1 + KM_MAP_COUNT)
km_mesh_image km__material_slot(const km_mesh_material *m, size_t i);
/* Writes m as PLY (x y z as doubles, u v, nx ny nz, colours as uchar red green blue alpha,
 * triangles) with "comment <comment>" (NULL: "kinemesh") in the header. Vertex order and count
 * as in m. */
km_status km__ply_write(FILE *f, const km_mesh *m, km_ply_encoding enc, const char *comment);
/* Identical images among materials' texture slots (a glTF's primitives often share one; a
 * normal map is never a base colour, but bytes decide):
 *   m, n  in: materials
 *   uniq  out: n * KM__SLOTS, entry i = k * KM__SLOTS + s for material k's slot s: the lowest j
 *         whose image is byte-equal to it (j == i: the first of its kind), -1 where it has none */
void km__material_images_unique(const km_mesh_material *m, size_t n, int *uniq);
/* True when m's materials tile its faces in order (the runs km_mesh.materials documents). */
bool km__obj_materials_cover(const km_mesh *m);
/* The name image i (km__material_images_unique's index) is written under: prefix + i +
 * ".png" or ".jpg" by its mime type. */
void km__obj_texture_name(char *buf, size_t n, const char *prefix, int i, const char *mime);
/* Writes the library km__obj_write's "mtllib" names: dir/mtl_name with newmtl kinemesh_<k> per
 * material (Kd, d, Pr, Pm, Ns, map_Kd), and each distinct image once as
 * dir/<tex_prefix><k>.png|.jpg; every file atomically (temporary, then rename), images first.
 * Errors: KM_ERR_IO naming the file, KM_ERR_NOMEM. */
km_status km__obj_write_materials(const char *dir, const char *mtl_name, const char *tex_prefix,
                                  const km_mesh_material *m, size_t n, km_error *err);

#endif
