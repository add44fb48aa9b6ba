/* kinemesh — animate any triangle mesh from captured human motion.
 *
 * The one public header. C11, no third-party types: solver objects are opaque.
 *
 * Conventions (read once, they hold everywhere):
 *  - Every fallible call returns km_status (KM_OK == 0) and, when `err` is not NULL,
 *    fills it with a message for the user naming the file, line/byte and what was expected.
 *  - Arrays are plain, row-major, owned by whoever allocated them. Positions are
 *    `double V[#V*3]` (x0 y0 z0 x1 ...), triangles `int32_t F[#F*3]`. Dense matrices with
 *    several columns (eigenvectors, right-hand sides) are column-major: column c of an
 *    n-row matrix starts at X + c*n.
 *  - Units: metres inside the library.
 *  - Laplacian sign: L is negative semidefinite, rows sum to zero (L_ii = -sum_j L_ij).
 *    System matrices are built from -L plus constraints so they are SPD.
 *  - Frees take the address of what they free and set it to NULL; freeing NULL is a no-op.
 *  - The library never prints. Install a logger with km_set_logger() to see its messages.
 */
#ifndef KINEMESH_H
#define KINEMESH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define KM_VERSION_MAJOR 0
#define KM_VERSION_MINOR 1
#define KM_VERSION_PATCH 0
const char *km_version(void);
/* Monotonic clock in seconds (for timing; arbitrary origin). */
double km_seconds(void);

/* ---------------------------------------------------------------- errors */

typedef enum km_status {
  KM_OK = 0,
  KM_ERR_IO,              /* cannot open / read / write a file */
  KM_ERR_PARSE,           /* file content is not what its format says */
  KM_ERR_INVALID,         /* bad argument or option */
  KM_ERR_DEGENERATE_MESH, /* mesh cannot support the operation (zero area, no faces...) */
  KM_ERR_NOT_POSDEF,      /* Cholesky met a non-positive-definite matrix */
  KM_ERR_NO_CONVERGENCE,  /* an iterative method did not converge */
  KM_ERR_NOMEM,
  KM_ERR_CANCELLED,   /* a progress callback asked to stop */
  KM_ERR_UNSUPPORTED, /* valid input using a feature kinemesh does not handle */
  KM_ERR_STALE,       /* a cache does not match its inputs (version, checksum, mesh) */
} km_status;

typedef struct km_error {
  km_status status;
  char message[1024];
} km_error;

/* Fills err (when not NULL) with status and a printf-formatted message; returns status, so
 * that a caller's failure path reads `return km_error_set(err, KM_ERR_IO, "%s: ...", path)`. */
km_status km_error_set(km_error *err, km_status status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* Writes size bytes to path atomically: a temporary file beside it, flushed, then renamed,
 * so a reader never sees a half-written file and a failure leaves nothing behind. */
km_status km_write_file_atomic(const char *path, const void *data, size_t size, km_error *err);

/* Stable name of a status ("KM_ERR_PARSE"). Never NULL. */
const char *km_status_name(km_status s);

/* ---------------------------------------------------------------- logging & progress */

typedef enum km_log_level { KM_LOG_DEBUG = 0, KM_LOG_INFO, KM_LOG_WARN, KM_LOG_ERROR } km_log_level;
typedef void (*km_log_fn)(km_log_level level, const char *message, void *user);
/* Installs the process-wide logger (NULL silences the library, the default). */
void km_set_logger(km_log_fn fn, void *user);

/* Called by long operations with fraction in [0,1] and a short stage name.
 * Return false to cancel: the operation then returns KM_ERR_CANCELLED. */
typedef bool (*km_progress_fn)(double fraction, const char *stage, void *user);
typedef struct km_progress {
  km_progress_fn fn; /* NULL: no reports */
  void *user;
} km_progress;

/* ---------------------------------------------------------------- meshes */

typedef struct km_mesh {
  double *V;  /* #V*3 positions */
  int32_t *F; /* #F*3 triangles, 0-based */
  size_t n_vertices;
  size_t n_faces; /* 0 for a point cloud */
} km_mesh;

typedef enum km_mesh_format {
  KM_FORMAT_AUTO = 0, /* from the file extension */
  KM_FORMAT_OBJ,
  KM_FORMAT_PLY,
  KM_FORMAT_OFF,
} km_mesh_format;

typedef enum km_ply_encoding {
  KM_PLY_BINARY_LE = 0, /* default */
  KM_PLY_BINARY_BE,
  KM_PLY_ASCII,
} km_ply_encoding;

typedef struct km_mesh_write_options {
  km_mesh_format format; /* 0: from extension */
  km_ply_encoding ply;   /* 0: binary little endian */
} km_mesh_write_options;

/* Allocates a mesh with uninitialised V and F of the given sizes. */
km_status km_mesh_alloc(size_t n_vertices, size_t n_faces, km_mesh *out, km_error *err);
/* Deep copy. */
km_status km_mesh_copy(const km_mesh *src, km_mesh *out, km_error *err);
/* Frees V and F and zeroes the struct. */
void km_mesh_free(km_mesh *m);

/* Reads OBJ / PLY (ascii, binary LE/BE) / OFF. Vertex order and count are exactly those of
 * the file; polygons are fan-triangulated (0,i,i+1). A PLY without faces reads as a point
 * cloud (n_faces == 0). Errors name `path` and the line (text) or byte offset (binary). */
km_status km_mesh_read(const char *path, km_mesh *out, km_error *err);
/* Same from memory; `name` is used in error messages. format must not be AUTO unless
 * `name` has an extension. */
km_status km_mesh_parse(const void *data, size_t size, km_mesh_format format, const char *name,
                        km_mesh *out, km_error *err);
/* Writes atomically (temporary file, then rename). Coordinates are written exactly
 * (%.17g in text formats, raw doubles in binary PLY), so reading back is bit for bit. */
km_status km_mesh_write(const char *path, const km_mesh *m, const km_mesh_write_options *opt,
                        km_error *err);

/* Topology and extent. Edges are undirected vertex pairs used by at least one face.
 * A component is a set of faces connected through shared vertices; vertices used by no
 * face are counted as isolated, not as components. A face is degenerate when two of its
 * indices are equal or its area is below 1e-14 * bbox_diagonal^2. */
typedef struct km_mesh_info {
  size_t vertices, faces;
  size_t edges;
  size_t boundary_edges;       /* used by exactly one face */
  size_t nonmanifold_edges;    /* used by three or more faces */
  size_t nonmanifold_vertices; /* faces around the vertex form more than one fan */
  size_t components;
  size_t isolated_vertices;
  size_t degenerate_faces;
  int64_t euler_characteristic; /* V - E + F over non-isolated vertices */
  double bbox_min[3], bbox_max[3];
} km_mesh_info;
km_status km_mesh_info_compute(const km_mesh *m, km_mesh_info *out, km_error *err);

/* Mean and maximum of |A_v - B_v| over n points (A, B n*3). */
void km_vertex_distance_stats(const double *A, const double *B, size_t n, double *mean,
                              double *max);

/* Length of the bounding-box diagonal (0 for an empty mesh). */
double km_bbox_diagonal(const double *V, size_t n_vertices);

/* k vertices spread over the mesh by farthest-point sampling (Euclidean, deterministic: the
 * first is the vertex farthest from the centroid, each next one the farthest from those
 * taken). Written to ids (k entries). For landmarks on a mesh without a rig: meshes of one
 * connectivity share the ids. Isolated vertices are never taken. */
km_status km_farthest_points(const km_mesh *m, size_t k, int32_t *ids, km_error *err);

/* Vertex-vertex adjacency in CSR form: neighbours of v are
 * adj[offsets[v] .. offsets[v+1]), sorted ascending. offsets has #V+1 entries.
 * Both arrays are allocated by the call; free them with free(). */
km_status km_adjacency_list(const km_mesh *m, int32_t **offsets, int32_t **adj, km_error *err);

/* Primitive meshes for tests and examples (closed, manifold, consistently oriented
 * outward). icosphere: 10*4^subdiv+2 vertices on a sphere of `radius`. */
km_status km_icosphere(int subdivisions, double radius, km_mesh *out, km_error *err);
/* Open rectangular grid in the z=0 plane, (nx+1)*(ny+1) vertices over [0,sx]x[0,sy]. */
km_status km_grid(int nx, int ny, double sx, double sy, km_mesh *out, km_error *err);
/* Closed capped cylinder along +z from z=0 to z=length: `rings`+1 rings of `segments`
 * vertices each plus two cap centres. */
km_status km_cylinder(int segments, int rings, double radius, double length, km_mesh *out,
                      km_error *err);

/* ---------------------------------------------------------------- sparse matrices */

/* Sparse matrix (compressed columns, int32 indices, double values, sorted, no duplicates).
 * Symmetric matrices are stored with both triangles. Backed by CHOLMOD. */
typedef struct km_sparse km_sparse;

/* Builds an n_rows x n_cols matrix from triplets; duplicate (i,j) entries are summed. */
km_status km_sparse_from_triplets(size_t n_rows, size_t n_cols, size_t nnz, const int32_t *rows,
                                  const int32_t *cols, const double *values, km_sparse **out,
                                  km_error *err);
/* Diagonal matrix. */
km_status km_sparse_diagonal(size_t n, const double *diag, km_sparse **out, km_error *err);
/* C = alpha*A + beta*B (same shape). */
km_status km_sparse_add(double alpha, const km_sparse *A, double beta, const km_sparse *B,
                        km_sparse **out, km_error *err);
size_t km_sparse_rows(const km_sparse *A);
size_t km_sparse_cols(const km_sparse *A);
size_t km_sparse_nnz(const km_sparse *A);
/* Read-only view of the CSC arrays: col_ptr has cols+1 entries. */
void km_sparse_csc(const km_sparse *A, const int32_t **col_ptr, const int32_t **row_idx,
                   const double **values);
/* A(i,j), 0 when not stored. */
double km_sparse_coeff(const km_sparse *A, size_t i, size_t j);
/* Y = A X for X column-major cols x k, Y rows x k. Y must not alias X. */
void km_sparse_mul(const km_sparse *A, size_t k, const double *X, double *Y);
void km_sparse_free(km_sparse **A);

/* Sparse Cholesky of a symmetric positive-definite matrix (CHOLMOD).
 * analyze once per pattern, factorize whenever the values change, solve many times.
 * solve does not allocate (workspace is kept in the object) and is not thread-safe on one
 * object. */
typedef struct km_cholesky km_cholesky;
km_status km_cholesky_analyze(const km_sparse *A, km_cholesky **out, km_error *err);
/* A must have the pattern given to analyze. KM_ERR_NOT_POSDEF when it is not SPD. */
km_status km_cholesky_factorize(km_cholesky *c, const km_sparse *A, km_error *err);
/* X = A^-1 B, B and X column-major n x nrhs (may alias). */
km_status km_cholesky_solve(km_cholesky *c, size_t nrhs, const double *B, double *X, km_error *err);
size_t km_cholesky_size(const km_cholesky *c);
void km_cholesky_free(km_cholesky **c);

/* ---------------------------------------------------------------- geometric operators */

/* Cotangent Laplacian, #V x #V: L_ij = (cot a_ij + cot b_ij)/2 for each edge, L_ii = -sum.
 * Cotangents are clamped to [-1e5, 1e5] (zero-angle / near-degenerate triangles) and a
 * face with zero area contributes nothing, so the matrix stays finite. Obtuse triangles
 * give negative weights, as the continuous operator does. */
km_status km_cotmatrix(const km_mesh *m, km_sparse **L, km_error *err);
/* Uniform (graph) Laplacian: L_ij = 1 for each edge, L_ii = -degree. */
km_status km_uniform_laplacian(const km_mesh *m, km_sparse **L, km_error *err);

typedef enum km_mass_type {
  KM_MASS_VORONOI =
      0, /* mixed Voronoi areas (Meyer et al. 2003): obtuse triangles split 1/2,1/4,1/4 */
  KM_MASS_BARYCENTRIC, /* a third of each incident triangle's area */
} km_mass_type;
/* Lumped (diagonal) mass matrix. Isolated vertices get a tiny positive mass so M stays
 * invertible. */
km_status km_massmatrix(const km_mesh *m, km_mass_type type, km_sparse **M, km_error *err);

typedef enum km_normal_weighting {
  KM_NORMALS_AREA = 0, /* face normals weighted by area */
  KM_NORMALS_ANGLE,    /* weighted by the incident angle (Thürmer & Wüthrich) */
} km_normal_weighting;
/* Unit per-vertex normals, N #V*3. A vertex with no non-degenerate face gets (0,0,0). */
km_status km_vertex_normals(const km_mesh *m, km_normal_weighting w, double *N, km_error *err);

/* For every vertex, the neighbour whose edge defines its local frame's tangent. Chosen once
 * on a reference mesh (the lowest-index neighbour) and reused for every pose of the same
 * connectivity, so frames correspond across poses. ref #V; isolated vertices get -1. */
km_status km_frame_neighbors(const km_mesh *m, int32_t *ref, km_error *err);
/* Local orthonormal frames: frames #V*9, per vertex the rows n (normal), t (edge to ref
 * projected on the tangent plane, normalised), b = n x t. Right-handed. */
km_status km_local_frames(const km_mesh *m, const double *N, const int32_t *ref, double *frames,
                          km_error *err);

/* ---------------------------------------------------------------- eigenfields */

typedef struct km_eigs_options {
  double sigma; /* shift; 0: a small negative shift relative to the spectrum scale */
  double tol;   /* ARPACK tolerance; 0: 1e-10 */
  int max_iter; /* 0: 1000 */
  int ncv;      /* Lanczos vectors; 0: min(n, max(2k+1, 20)) */
  km_progress progress;
} km_eigs_options;
/* The k smallest eigenpairs of -L phi = lambda M phi (L symmetric NSD, M diagonal SPD) by
 * ARPACK in shift-invert mode on a CHOLMOD factor of (-L - sigma M). evals ascending (k),
 * evecs column-major #V x k, M-orthonormal. Either output may be NULL. */
km_status km_eigs(const km_sparse *L, const km_sparse *M, int k, const km_eigs_options *opt,
                  double *evals, double *evecs, km_error *err);

/* ---------------------------------------------------------------- skeletons & takes */

#define KM_KINECT1_JOINTS 20
/* Kinect v1 joint order: HipCenter, Spine, ShoulderCenter, Head, ShoulderLeft, ElbowLeft,
 * WristLeft, HandLeft, ShoulderRight, ElbowRight, WristRight, HandRight, HipLeft, KneeLeft,
 * AnkleLeft, FootLeft, HipRight, KneeRight, AnkleRight, FootRight. */
const char *km_kinect1_joint_name(int j);
/* Parent of joint j in the Kinect v1 hierarchy (-1 for HipCenter). */
int km_kinect1_joint_parent(int j);
/* Index of a Kinect v1 joint by name (case-sensitive), -1 when unknown. */
int km_kinect1_joint_index(const char *name);

typedef struct km_skeleton {
  size_t n_joints;
  char **names;     /* n_joints strings */
  int32_t *parents; /* -1 for a root; parents[j] < j */
  double *rest;     /* n_joints*3 rest positions */
} km_skeleton;
void km_skeleton_free(km_skeleton *s);

/* A motion take: joint positions per frame (the form trackers deliver). A joint missing in a
 * frame is NaN. */
typedef struct km_take {
  size_t n_frames, n_joints;
  double fps;
  char **joint_names; /* n_joints */
  int32_t *parents;   /* n_joints, -1 for roots; may be NULL when unknown */
  double *positions;  /* n_frames * n_joints * 3 */
} km_take;
void km_take_free(km_take *t);
/* kinemesh take JSON:
 * {"format":"kinemesh-take","version":1,"fps":30,"units":"m","joints":["HipCenter",...],
 *  "parents":[-1,0,...],"frames":[[x,y,z, x,y,z, ...], ...]}   (null = missing joint) */
km_status km_take_read(const char *path, km_take *out, km_error *err);
km_status km_take_write(const char *path, const km_take *t, km_error *err);

/* Linear blend skinning. Each vertex has up to 4 influences. */
#define KM_SKIN_INFLUENCES 4
typedef struct km_skin {
  size_t n_vertices;
  int32_t *joints; /* n_vertices*4, -1 for an unused slot */
  double *weights; /* n_vertices*4, summing to 1 */
} km_skin;
void km_skin_free(km_skin *s);

/* Per-joint rigid transforms (row-major 3x4: [R | t]) that take the rest skeleton to the
 * given joint positions: each joint's rotation is the minimal rotation of its rest bone
 * direction(s) onto the posed ones (no twist), composed down the hierarchy. NaN positions
 * keep the rest-relative transform of the parent. transforms: n_joints*12. */
km_status km_skeleton_pose_from_positions(const km_skeleton *s, const double *positions,
                                          double *transforms, km_error *err);
/* Joint rest positions at the boundaries of the skinned parts (Park & Lim: the skeleton of a
 * template that has only weights). Joint j sits at the weighted centroid of the vertices its
 * part shares with its parent's part (weight min(w_j, w_parent)); a root, or a joint whose
 * part shares no vertex with its parent's, sits at the weighted centroid of its own part; a
 * joint no vertex is weighted to keeps the position in `rest` (in: a guess, may be the
 * rig's; out: the estimate). parents: n_joints entries, -1 for roots. */
km_status km_skeleton_from_weights(const km_mesh *m, const km_skin *skin, const int32_t *parents,
                                   size_t n_joints, double *rest, km_error *err);
/* Least-squares similarity dst ~ s R src + t (Umeyama 1991 / Kabsch: one SVD), n >= 3 point
 * pairs (src, dst n*3). weights (n, >= 0) may be NULL for equal weights. with_scale false
 * fits a rigid motion (s = 1; s may then be NULL). R row-major 3x3, a proper rotation.
 * KM_ERR_DEGENERATE_MESH when the source points coincide or the pairs are collinear. */
km_status km_similarity_fit(const double *src, const double *dst, const double *weights, size_t n,
                            bool with_scale, double *s, double R[9], double t[3], km_error *err);
/* out = sum_k w_k T_{j_k} v for each rest vertex. out #V*3 may not alias rest. */
km_status km_lbs(const double *rest, size_t n_vertices, const km_skin *skin,
                 const double *transforms, size_t n_joints, double *out, km_error *err);

/* ---------------------------------------------------------------- procedural character */

typedef struct km_character_options {
  size_t target_vertices; /* 0: 20000. Output within +-10%. 2,000 .. 1,000,000 */
  uint64_t seed;          /* small per-subject variation of proportions; 0 is valid */
  double height;          /* metres; 0: 1.75 */
  double girth;           /* limb thickness factor; 0: 1.0 */
  double belly;           /* belly size factor; 0: 0 (none), 1: pronounced */
  km_progress progress;
} km_character_options;

#define KM_CHARACTER_LANDMARKS 16
typedef struct km_landmark {
  char name[32];
  char mirror[32]; /* name of the left/right counterpart (itself on the mid-line) */
  int32_t vertex;
} km_landmark;

typedef struct km_character {
  km_mesh mesh;         /* closed, manifold, one component */
  km_skeleton skeleton; /* the 20 Kinect v1 joints at rest */
  km_skin skin;         /* LBS weights over the skeleton's joints */
  km_landmark landmarks[KM_CHARACTER_LANDMARKS];
} km_character;
void km_character_free(km_character *c);

/* Generates a humanoid as an implicit surface around a skeleton, polygonised so that its
 * vertex count is target_vertices +-10%. Equal options (shape, seed) give equal meshes.
 * All subjects of one target_vertices SHARE CONNECTIVITY (same F, same vertex count and
 * order, same landmark vertex ids): the canonical subject (seed 0, height 1.75, girth 1,
 * belly 0) is polygonised at that resolution and every other shape is obtained by carrying
 * its vertices to the new skeleton's primitives (bone lengths, offsets, radii), projecting
 * them onto the new implicit surface (Newton steps along the field gradient) and relaxing
 * them tangentially, in a few steps through intermediate bodies. Skeleton and skin are the
 * new subject's. Costs about twice a direct polygonisation. */
km_status km_character_generate(const km_character_options *opt, km_character *out, km_error *err);
/* Rig sidecar (<mesh>.rig.json): skeleton, skin, landmarks, and a default puppetry rig
 * (handles at head, hands, feet mapped to the matching Kinect joints). */
km_status km_character_write_rig(const char *path, const km_character *c, km_error *err);
/* Reads the skeleton, skin and landmarks of a rig sidecar (mesh not touched). */
km_status km_character_read_rig(const char *path, size_t n_vertices, km_character *out,
                                km_error *err);

/* The built-in pose set: KM_POSE_PRESETS named joint-angle poses (t_pose, a_pose, arms_up,
 * squat, ...) of the Kinect v1 skeleton, each up to KM_POSE_PRESET_MAX_ROTATIONS joint
 * rotations. Ground truth for pose-transfer tests and benchmarks. */
#define KM_POSE_PRESETS 10
#define KM_POSE_PRESET_MAX_ROTATIONS 8
/* Name of preset p (NULL when out of range). */
const char *km_pose_preset_name(int p);
/* Character c in preset p by forward kinematics and km_lbs: V #V*3 posed positions. jitter:
 * NULL, or KM_POSE_PRESET_MAX_ROTATIONS factors; rotation k's angle is scaled by 1+jitter[k]. */
km_status km_character_pose_preset(const km_character *c, int p, const double *jitter, double *V,
                                   km_error *err);

typedef enum km_motion_kind { KM_MOTION_WALK = 0, KM_MOTION_WAVE, KM_MOTION_KUNGFU } km_motion_kind;
/* A take of the 20 Kinect v1 joints at 30 Hz for skeleton s (the character's rest skeleton),
 * frames >= 1. Deterministic. Like a tracked performer it starts in the rest (T) pose — the
 * calibration pose puppetry measures displacements from — holds it 0.2 s and blends into
 * the motion over the next 0.5 s. */
km_status km_motion_generate(const km_skeleton *s, km_motion_kind kind, size_t frames, km_take *out,
                             km_error *err);

/* ---------------------------------------------------------------- animation output */

typedef enum km_anim_format {
  KM_ANIM_AUTO = 0, /* from the path: .glb, .pc2, else a directory */
  KM_ANIM_GLB,
  KM_ANIM_PC2,
  KM_ANIM_OBJ_DIR,
  KM_ANIM_PLY_DIR,
} km_anim_format;

typedef struct km_anim_options {
  km_anim_format format; /* 0: from the path (a directory gets per-frame .obj) */
  double fps;            /* 0: 30 */
  size_t key_every;      /* glb: one morph target every k frames (0/1: every frame) */
} km_anim_options;

/* Streams an animation of a fixed-connectivity mesh to disk. Nothing appears at `path`
 * until close succeeds (a temporary is renamed); free without close discards it. */
typedef struct km_anim_writer km_anim_writer;
km_status km_anim_writer_open(const char *path, const km_mesh *rest, const km_anim_options *opt,
                              km_anim_writer **out, km_error *err);
/* Appends one frame: V is #V*3 positions in metres. */
km_status km_anim_writer_push(km_anim_writer *w, const double *V, km_error *err);
km_status km_anim_writer_close(km_anim_writer **w, km_error *err);
void km_anim_writer_free(km_anim_writer **w);

typedef struct km_anim_info {
  km_anim_format format;
  size_t frames; /* frames in the file (morph targets for glb) */
  size_t vertices;
  size_t faces; /* 0 for pc2 */
  double fps;
  double duration; /* seconds */
} km_anim_info;
km_status km_anim_info_read(const char *path, km_anim_info *out, km_error *err);
/* Reads all frames of a .pc2 (frames*vertices*3 doubles, allocated; free()). */
km_status km_pc2_read(const char *path, double **frames, km_anim_info *info, km_error *err);

/* ---- motion input, filtering, retargeting (puppetry) */

/* Kinect v1 skeleton recording as CSV (the PRECOG dataset layout): a header line of the 20
 * joint names separated by ';', then one line per frame of 20 "x y z" triples separated by
 * ';' and an optional 21st field holding an integer action label. Columns are matched to
 * joints by their header names, so any column order works; the take always has the 20 Kinect
 * v1 joints in KM_KINECT1 order with their parents, fps 30, metres.
 * Axes: Kinect skeleton space is right-handed, camera at the origin, y up, z the depth
 * towards the performer, who therefore faces -z. kinemesh characters face +z, so every point
 * is rotated 180 degrees about y: (x, y, z) -> (-x, y, -z). That is a rotation, not a mirror:
 * the performer's left hand stays the character's left (+x). The origin stays at the sensor.
 * A joint at exactly (0,0,0) (the SDK's "not tracked") becomes NaN (missing).
 * labels: optional (NULL to skip); receives a malloc'ed array of n_frames action labels
 * (0 when the file has no label field); free() it. */
km_status km_kinect_csv_read(const char *path, km_take *out, int32_t **labels, km_error *err);

/* Metres per unit of the CMU mocap BVH files (cgspeed conversion): 1 unit = 1/0.45 inch. */
#define KM_BVH_CMU_UNITS (0.0254 / 0.45)

typedef struct km_bvh_options {
  /* Metres per BVH unit (BVH has no units). 0: auto from the rest skeleton's height h (y
   * extent of the offsets, end sites included): 1 when 1 <= h <= 2.5 (metres), 0.01 when
   * 100 <= h <= 250 (centimetres), KM_BVH_CMU_UNITS for the CMU skeleton (joints LHipJoint,
   * RHipJoint and lowerback), otherwise 1.7/h (unknown units: a 1.7 m rest height). */
  double units_to_m;
  /* false (default): End Site blocks are dropped. true: each becomes an extra joint named
   * "<parent>_End" (fingertips, head top, toe tips). */
  bool end_sites;
} km_bvh_options;

typedef struct km_bvh_info {
  double units_to_m;  /* the factor applied */
  double rest_height; /* rest skeleton height in metres (after scaling) */
  size_t n_channels;  /* numbers per frame */
} km_bvh_info;

/* Reads a BVH motion file into joint world positions per frame (forward kinematics).
 * Joints are in file order (depth first, parents[j] < j, -1 for a ROOT).
 * Each joint's local transform is translate(t) * R, where t is its OFFSET with any
 * X/Y/Zposition channels replacing the matching components (so a root's position channels
 * are absolute, as exporters write them), and R is the product of the rotation channels in
 * the order listed (intrinsic): "Zrotation Xrotation Yrotation" gives R = Rz*Rx*Ry, angles in
 * degrees, right-handed. Channels may come in any order; 0..6 per joint, each at most once.
 * Axes are kept as in the file (BVH is y up by convention). fps = 1/Frame Time, snapped to
 * the nearest integer when within 0.01. opt and info may be NULL. */
km_status km_bvh_read(const char *path, const km_bvh_options *opt, km_take *out, km_bvh_info *info,
                      km_error *err);

/* Holt double exponential smoothing of joint positions (paper eq. 4) with the extra knobs of
 * the Kinect SDK (NUI_TRANSFORM_SMOOTH_PARAMETERS). Per joint, with raw sample x:
 *   x' = x, or lerp(prev_level, x, d/jitter_radius) when d = |x - prev_level| <= jitter_radius
 *   level = (1 - smoothing) x' + smoothing (prev_level + prev_trend)
 *   trend = trend_gain (level - prev_level) + (1 - trend_gain) prev_trend
 *   out   = level + prediction * trend, pulled back to within max_deviation of x.
 * So eq. 4's beta = 1 - smoothing and gamma = trend. The first good sample initialises
 * level = x, trend = 0 (eq. 4 with p^0 = p^1). */
typedef struct km_filter_options {
  double smoothing;     /* Kinect fSmoothing in [0,1): more = smoother, laggier.
                           0: 0.5. KM_FILTER_ZERO (any negative): no smoothing (raw) */
  double trend;         /* gamma, Kinect fCorrection, in [0,1]. 0: 0.5.
                           KM_FILTER_ZERO (any negative): no trend (single exponential) */
  double prediction;    /* frames of trend added to the output (Kinect fPrediction). 0: none */
  double jitter_radius; /* metres (Kinect fJitterRadius). 0: off */
  double max_deviation; /* metres (Kinect fMaxDeviationRadius). 0: off */
} km_filter_options;
#define KM_FILTER_ZERO (-1.0)

typedef struct km_filter km_filter;
km_status km_filter_create(size_t n_joints, const km_filter_options *opt, km_filter **out,
                           km_error *err);
/* One frame: raw and filtered are n_joints*3 (may alias). A NaN raw joint (missing) does not
 * touch the joint's state and outputs its last filtered value; before the joint's first good
 * sample it outputs NaN. */
void km_filter_push(km_filter *f, const double *raw, double *filtered);
/* Forgets all history (as if just created). */
void km_filter_reset(km_filter *f);
void km_filter_free(km_filter **f);

/* Puppetry rig (JSON):
 * { "skeleton": "kinect1" | "bvh",                       (default kinect1)
 *   "handles": [ {"name": "head", "vertex": 1234, "radius": 0.05},  geodesic ball
 *                {"name": "tail", "vertices": [10, 11, 12]},        explicit list
 *                {"name": "base", "center": [0, 0, 0], "radius": 0.1} ],  Euclidean ball
 *   "map": [ {"handle": "head", "joint": "Head", "axes": "xyz", "scale": 1.0} ],
 *   "filter": {"smoothing": 0.5, "trend": 0.5, "prediction": 0, "jitter_radius": 0,
 *              "max_deviation": 0} }
 * Other keys are ignored. "vertex"+"radius" takes every vertex whose shortest path along mesh
 * edges from the seed is <= radius (Dijkstra, so it stays on the seed's connected region and
 * does not jump to a nearby other limb; radius 0 or absent: the seed alone; a mesh without
 * faces falls back to Euclidean distance). "axes" is a non-empty subset of "xyz"; "scale"
 * defaults to 1. In "filter", an explicit 0 for smoothing or trend means zero. Several map
 * entries may drive one handle (their displacements add up: a row of eq. 7's M with several
 * ones) and one joint may drive several handles. Errors name the rig file and the handle or
 * joint: unknown joint (kinect1: the 20 Kinect v1 names; bvh: the joint_names given),
 * unknown or duplicate handle, empty handle, a vertex in two handles, vertex id out of range,
 * bad axes. */
typedef enum km_rig_skeleton { KM_RIG_KINECT1 = 0, KM_RIG_BVH } km_rig_skeleton;

typedef struct km_rig_handle {
  char name[64];
  int32_t *vertices; /* sorted ascending, no duplicates */
  size_t n_vertices;
} km_rig_handle;

#define KM_AXIS_X 1u
#define KM_AXIS_Y 2u
#define KM_AXIS_Z 4u
typedef struct km_rig_map {
  int32_t handle; /* index into handles */
  int32_t joint;  /* index into the take's joints (KM_KINECT1 order for kinect1) */
  uint32_t axes;  /* KM_AXIS_* mask of the displacement components kept */
  double scale;   /* per-map factor on top of the performer-to-character scale */
} km_rig_map;

typedef struct km_rig {
  km_rig_skeleton skeleton;
  km_rig_handle *handles;
  size_t n_handles;
  km_rig_map *maps;
  size_t n_maps;
  km_filter_options filter;
} km_rig;

/* Parses a rig and resolves its handles on `mesh`. joint_names/n_joint_names: the take's
 * joints, needed for "bvh" rigs (ignored for kinect1, whose names are fixed). */
km_status km_rig_read(const char *path, const km_mesh *mesh, const char *const *joint_names,
                      size_t n_joint_names, km_rig *out, km_error *err);
/* Same from memory; `name` is used in error messages. */
km_status km_rig_parse(const char *json, size_t size, const char *name, const km_mesh *mesh,
                       const char *const *joint_names, size_t n_joint_names, km_rig *out,
                       km_error *err);
void km_rig_free(km_rig *rig);

/* Retargeting (paper eq. 5-7). Per frame, handle h's target is
 *   target_h = rest_centroid_h + s * sum_{maps e on h} scale_e * mask_e (p_j(e) - p_j(e)^0)
 * where p^0 is the joint's first valid (non-NaN) position. That is eq. 7 accumulated over
 * frames: H^t = M S^t with S^t the eq. 6 increments, and sum_t d^t telescopes to p^t - p^0; M
 * is stored sparsely as the map list (M_ij = scale_e, with the axis mask per entry). s maps
 * performer size to character size: by default the mesh's bounding-box height (y; its largest
 * extent if the mesh is flat in y) over the first valid frame's performer stature (kinect1:
 * the Head-to-lower-foot joint span / KM_KINECT1_SPAN_OF_STATURE, since the Head joint sits
 * at the head's centre and the foot joints above the soles; otherwise the y extent of the
 * valid joints), replacing eq. 5's
 * screen-size ratio. Handles no map drives are
 * anchors (target = rest centroid). If a joint a handle needs is NaN, the handle keeps its
 * last target. */
/* Kinect v1 Head-to-foot joint span as a fraction of stature (anthropometric head-centre and
 * foot-joint heights: 0.937 and 0.023 of stature on kinemesh's procedural character). */
#define KM_KINECT1_SPAN_OF_STATURE 0.91
typedef struct km_retarget_options {
  double scale; /* performer-to-character factor s; 0: automatic (above) */
} km_retarget_options;

typedef struct km_retarget km_retarget;
/* n_joints: joints per frame in what will be pushed (20 for kinect1). The rig's vertex ids
 * must be valid for `rest`, which must be the mesh the rig was resolved on. */
km_status km_retarget_create(const km_rig *rig, const km_mesh *rest, size_t n_joints,
                             const km_retarget_options *opt, km_retarget **out, km_error *err);
/* One frame of (filtered) joints, n_joints*3, NaN = not valid yet. Writes n_handles*3 targets
 * into handle_targets (may be NULL). */
void km_retarget_push(km_retarget *r, const double *joints, double *handle_targets);
/* Per-vertex targets of the last push: for every handle in order, every vertex of it in
 * order, rest position + the handle's displacement. out: km_retarget_vertex_count()*3. */
void km_retarget_vertex_targets(const km_retarget *r, double *out);
size_t km_retarget_vertex_count(const km_retarget *r);
/* Rest centroids of the handles, n_handles*3. */
const double *km_retarget_rest_centroids(const km_retarget *r);
/* The performer-to-character factor in use; NaN while auto and no valid frame seen yet. */
double km_retarget_scale(const km_retarget *r);
/* Forgets reference positions (and the auto scale): the next valid frame is the new rest. */
void km_retarget_reset(km_retarget *r);
void km_retarget_free(km_retarget **r);
/* ---- deformation: reduced isoline model (puppetry) and full reference solver */

/* Handles (both solvers): handle h owns handle_vertices[handle_offsets[h] ..
 * handle_offsets[h+1]) (offsets: n_handles+1 entries, offsets[0] == 0, non-decreasing).
 * A vertex may appear in at most one handle. Targets are absolute positions, one xyz per
 * handle vertex in handle_vertices order (handle_offsets[n_handles]*3 doubles). */

/* Reduced isoline model of Wu, Lu & Song (after Au et al. 2006/2007): n_e propagation fields
 * (the first non-constant eigenvectors of -L phi = lambda M phi), n_iso isolines per field,
 * one affine 3x4 transform per isoline as the unknowns (4*n_iso*n_e per coordinate).
 * Precompute depends on the mesh only (not on handles) and can be cached on disk. Meant for
 * one connected component: with several (or unreferenced vertices) the first eigenvectors
 * are component indicators and the fields degrade. A km_puppet is not thread-safe. */
typedef struct km_puppet km_puppet;
/* Both energies use the same reduced unknowns, the same prefactored U^T U structure and the
 * same rotations estimated on isoline-crossed triangles and interpolated (W_delta R_delta).
 * ARAP is the default because it tracks the full-space reference closer: mean deviation
 * 1.2% / 1.7% of the diagonal on armadillo / horse against 1.9% / 2.3% for the paper's
 * Laplacian energy (kinemesh bench deform, README), at the same per-frame cost. */
typedef enum km_puppet_energy {
  KM_PUPPET_ENERGY_ARAP = 0,  /* reduced ARAP (membrane) energy (default) */
  KM_PUPPET_ENERGY_LAPLACIAN, /* the paper's eq. 8-9: |L X - rotated rest Laplacian|^2 */
} km_puppet_energy;
typedef struct km_puppet_options {
  int fields;              /* n_e propagation fields; 0: 8 (1 .. 32) */
  int isolines;            /* n_iso isolines per field; 0: 10 (2 .. 64) */
  int iterations;          /* dual-Laplacian rotation updates per solve; 0: 4 */
  double tolerance;        /* stop earlier when |dR| / |R - I| < tolerance; 0: 1e-4 */
  double handle_weight;    /* relative handle weight w_c (1: the handle and Laplacian terms of
                              U^T U have equal trace); 0: 1 (Laplacian energy) or 3 (ARAP
                              energy). Handles are soft: larger follows them closer and
                              bends the rest more */
  int crossed_per_isoline; /* crossed triangles sampled per isoline for rotations; 0: 10 */
  km_puppet_energy energy; /* 0: reduced ARAP; KM_PUPPET_ENERGY_LAPLACIAN: the paper's */
  km_progress progress;
} km_puppet_options;

/* Builds the reduced model of `rest` (closed or open triangle mesh, >= 4 vertices).
 * Only fields, isolines, crossed_per_isoline and energy shape the model (and the cache key);
 * the other options are solve settings. */
km_status km_puppet_precompute(const km_mesh *rest, const km_puppet_options *opt, km_puppet **out,
                               km_error *err);
/* Writes the model atomically: magic, format version, parameters, hash of the rest mesh,
 * payload, checksum (native little-endian doubles). */
km_status km_puppet_save(const km_puppet *p, const char *path, km_error *err);
/* Reads a model saved for exactly this rest mesh and these options. KM_ERR_STALE (with the
 * reason) when the file is from another version, mesh or parameter set, truncated or
 * corrupted: the caller then precomputes again. KM_ERR_IO when it cannot be read. */
km_status km_puppet_load(const char *path, const km_mesh *rest, const km_puppet_options *opt,
                         km_puppet **out, km_error *err);
/* The model parameters a cache was built with (fields, isolines, crossed_per_isoline, energy;
 * the other members of *opt are left as they are), read from its header only: a caller can
 * adopt them before km_puppet_load, which still checks everything. KM_ERR_IO when the file
 * cannot be read, KM_ERR_STALE when it is not a cache of this format. */
km_status km_puppet_cache_options(const char *path, km_puppet_options *opt, km_error *err);
/* Sets the handle set (milliseconds: a 4*n_iso*n_e dense Cholesky; no eigen-decomposition).
 * The warm start of the previous solve is kept. */
km_status km_puppet_set_handles(km_puppet *p, size_t n_handles, const int32_t *handle_offsets,
                                const int32_t *handle_vertices, km_error *err);
/* One frame: targets as described above; V_out #V*3 deformed positions. Does not allocate.
 * Warm-started from the previous solve. */
km_status km_puppet_solve(km_puppet *p, const double *targets, double *V_out, km_error *err);
/* Forgets the warm start (the next solve starts from the rest pose). */
void km_puppet_reset(km_puppet *p);

typedef struct km_puppet_info {
  size_t vertices;
  int fields, isolines;
  size_t unknowns;          /* 4*n_iso*n_e per coordinate */
  size_t crossed_triangles; /* n_tri: triangles whose rotations drive the update */
  size_t handles, handle_vertices;
  int last_iterations; /* rotation updates done by the last solve */
  double last_change;  /* its last relative update |dR| / |R - I| */
} km_puppet_info;
void km_puppet_info_get(const km_puppet *p, km_puppet_info *out);
void km_puppet_free(km_puppet **p);

/* Full-space as-rigid-as-possible deformation (Sorkine & Alexa 2007), the quality
 * reference: cotangent weights, handle vertices eliminated (hard constraints), a CHOLMOD
 * factor of the free part of -L, per-vertex rotations by a closed-form 3x3 polar
 * decomposition. Every connected component needs at least one handle vertex. */
typedef struct km_arap km_arap;
typedef struct km_arap_options {
  int iterations;   /* local/global iterations per solve; 0: 4 */
  double tolerance; /* stop earlier when the largest vertex move < tolerance * bbox diagonal;
                       0: 1e-6 */
} km_arap_options;
km_status km_arap_precompute(const km_mesh *rest, size_t n_handles, const int32_t *handle_offsets,
                             const int32_t *handle_vertices, const km_arap_options *opt,
                             km_arap **out, km_error *err);
/* Warm-started from the previous solve (the rest pose at first). V_out #V*3. */
km_status km_arap_solve(km_arap *a, const double *targets, double *V_out, km_error *err);
void km_arap_free(km_arap **a);
/* ---- point clouds to mesh animation */

/* One point cloud frame. Points with a NaN/inf coordinate are dropped and counted. */
typedef struct km_points {
  double *P; /* n*3 positions, metres */
  size_t n;
  size_t dropped_nan; /* points skipped because a coordinate was not finite */
} km_points;
void km_points_free(km_points *p);

/* Reads a point cloud: .ply (the mesh PLY reader, except that NaN/inf coordinates are
 * accepted, then dropped and counted; faces, if any, are ignored), .pcd
 * (PCD v0.7, DATA ascii or binary; fields x y z as F4/F8, other fields skipped;
 * binary_compressed is KM_ERR_UNSUPPORTED), .xyz/.txt/.pts (whitespace or comma separated,
 * the first three numbers of each line; '#' comments and blank lines skipped). Errors name
 * the file and the line (text) or byte offset (binary). */
km_status km_points_read(const char *path, km_points *out, km_error *err);
/* Same from memory; the format comes from the extension of `name`. */
km_status km_points_parse(const void *data, size_t size, const char *name, km_points *out,
                          km_error *err);
/* Writes a binary little-endian PLY with float x y z and no faces, atomically. */
km_status km_points_write_ply(const char *path, const double *P, size_t n, km_error *err);
/* Frame files in name order: `pattern` is a directory (its .ply/.pcd/.xyz/.txt/.pts files)
 * or a glob(3) pattern. *paths is an array of *n strings; free with km_paths_free. An empty
 * result is KM_ERR_IO naming the pattern. */
km_status km_point_frames_list(const char *pattern, char ***paths, size_t *n, km_error *err);
void km_paths_free(char ***paths, size_t n);

/* Closest points on a triangle mesh (Embree point queries, OpenMP over queries).
 * V #V*3 and F #F*3 the mesh; Q #Q*3 query points. Outputs (each may be NULL):
 * tri #Q closest triangle, bary #Q*3 its barycentrics, dist #Q distance (mesh units). */
km_status km_point_mesh_distance(const double *V, size_t n_vertices, const int32_t *F,
                                 size_t n_faces, const double *Q, size_t n_queries, int32_t *tri,
                                 double *bary, double *dist, km_error *err);

/* ---- capture simulator (ground truth for reconstruction tests and benchmarks) */
typedef struct km_capture_options {
  int cameras;             /* depth cameras on a ring around the subject; 0: 4 */
  size_t points_per_frame; /* target total over all cameras; 0: 30000 */
  double noise_mm;         /* Gaussian noise sigma along each axis, mm; 0: 2, < 0: none */
  double distance;         /* camera distance from the subject's centre, m; 0: 3 */
  double height;           /* camera height above the subject's centre, m; 0: 0.3 */
  uint64_t seed;           /* noise seed (frame index is mixed in) */
  km_progress progress;
} km_capture_options;
/* Ray-casts one posed mesh (Embree) from the cameras: every camera shoots a regular grid of
 * rays over the mesh's bounding box as seen from it, so the total hit count is about
 * points_per_frame; surfaces hidden from all cameras get no points. out is allocated.
 * frame mixes into the noise seed. */
km_status km_capture_frame(const km_mesh *posed, const km_capture_options *opt, size_t frame,
                           km_points *out, km_error *err);
/* Poses character c by the take (km_skeleton_pose_from_positions + km_lbs), captures every
 * frame and writes out_dir/frame_00000.ply ... plus out_dir/truth.pc2 (the posed meshes)
 * and out_dir/truth_rest.obj (c->mesh, whose faces give truth.pc2 its connectivity; OBJ so
 * that listing the frames, by directory or by a glob of its .ply files, never picks it up).
 * out_dir is created if missing. */
km_status km_capture_simulate(const km_character *c, const km_take *take,
                              const km_capture_options *opt, const char *out_dir, km_error *err);

/* ---- reconstruction (Park & Lim 2014 after Allen, Curless & Popovic 2003) */
typedef struct km_recon_options {
  size_t coarse_points;    /* multiresolution level size (Pauly clustering); 0: 2000 */
  int knn;                 /* neighbours for point normals; 0: 10 */
  int first_iterations;    /* first frame: nonrigid iterations per phase; 0: 12 */
  int refine_iterations;   /* later frames: surface refinement iterations; 0: 4 */
  int skeleton_iterations; /* later frames: correspondence updates of the skeletal step; 0: 6 */
  double w_data;           /* 0: 1 */
  double w_feature;        /* 0: 10 */
  double w_smooth;         /* 0: 0.05 (per edge; data is per point, normalised by count) */
  double w_pose;           /* skeletal step: penalty (per rad^2) on the change from the
                            * constant-velocity prediction; 0: 3e-4 (the data term is a mean
                            * squared distance in m^2, so this is small) */
  double outlier_scale;    /* Geman-McClure scale as a multiple of 1.4826*median residual; 0: 3 */
  int filter_radius;       /* temporal Gaussian half width in frames; 0: 2 (5 frames), <0: off */
  double filter_sigma;     /* frames; 0: 1 */
  bool rig_joints;         /* false (default): joints estimated at the part boundaries of the
                            * LBS weights (km_skeleton_from_weights), as the paper does; true:
                            * the template rig's joint positions as they are */
  km_progress progress;
} km_recon_options;

/* A user-given feature correspondence: template vertex <-> point position (first frame). */
typedef struct km_recon_feature {
  int32_t vertex;
  double point[3];
} km_recon_feature;

typedef struct km_recon_frame_stats {
  size_t index;
  size_t points;  /* finite points used */
  size_t dropped; /* NaN points dropped */
  double mean_mm; /* mean distance points -> reconstructed surface */
  double max_mm;
  int iterations; /* solver iterations (skeleton L-BFGS + surface) */
  double seconds;
  km_status status;  /* KM_OK, or why the frame was carried by the skeleton */
  char message[512]; /* status != KM_OK: what went wrong (a read error names the file) */
} km_recon_frame_stats;

/* How the first frame was placed before the nonrigid registration. */
typedef struct km_recon_init {
  size_t correspondences; /* given correspondences (>= 3: Horn's alignment on them) */
  /* Fewer than 3 given: a global alignment that assumes the subject upright (y up) but not
   * its heading. Centroids and heights are matched (scale = height ratio), then the template
   * is turned about the vertical axis to each of yaw_candidates headings; from each, rigid
   * ICP (point-to-plane on the trimmed closest points), then the skeletal step; the heading
   * whose posed surface leaves the smallest residual plus feet residual is kept. Residuals
   * are the mean point-to-surface distance over the coarse points, each capped at 5 cm. */
  int yaw_candidates;
  double yaw_deg;           /* heading kept: the template's rotation about +y before ICP */
  double rotation_deg;      /* angle of its rigid rotation after ICP, degrees */
  double rigid_residual_mm; /* its residual after rigid ICP */
  double residual_mm;       /* its residual after the skeletal step */
  double feet_residual_mm;  /* the same over the points of the lowest 8% of the height */
  double scale;             /* height ratio points / template */
  /* template landmarks (rig sidecar) matched to their closest points after the skeletal
   * fit, used as pseudo-correspondences in the feature-only affine stage (w_d = 0) */
  size_t landmarks;
} km_recon_init;

typedef struct km_recon_report {
  size_t n_frames, n_joints;
  km_recon_frame_stats *frames;   /* n_frames */
  double *joints;                 /* n_frames*n_joints*3 estimated joint positions */
  char **joint_names;             /* n_joints */
  double jerk_before, jerk_after; /* mean |second difference| of vertices, m, around the filter */
  size_t failed_frames;
  size_t correspondences; /* first-frame correspondences given */
  km_recon_init init;     /* how the first frame was initialised */
  bool rig_joints;        /* joints from the rig as given (else from the skin weights) */
} km_recon_report;
void km_recon_report_free(km_recon_report *r);
/* JSON: {"format":"kinemesh-recon-report","version":1,"frames":[{"index":..,"points":..,
 * "mean_mm":..,"max_mm":..,"iterations":..,"seconds":..,"status":"KM_OK",
 * "message":".." (failed frames only), "joints":[x,y,z,...]}...], "jerk_before":..,
 * "jerk_after":.., "first_frame": {"correspondences": N, "initialisation": "...", and
 * without correspondences "yaw_candidates", "yaw_deg", "rotation_deg", "rigid_residual_mm",
 * "residual_mm", "feet_residual_mm", "scale", "landmarks"}, "joints_from": "skin weights"|"rig"}.
 * Written atomically.
 */
km_status km_recon_report_write_json(const char *path, const km_recon_report *r, km_error *err);

/* Incremental reconstructor: create with the template (mesh, skeleton, skin), register the
 * first frame with features, then feed the following frames one at a time. */
typedef struct km_recon km_recon;
km_status km_recon_create(const km_character *template_character, const km_recon_options *opt,
                          km_recon **out, km_error *err);
/* Global alignment (Horn, rigid) from the features; the skeletal step posed by the features,
 * then the least-squares scale and rotation again against the posed landmarks; then affine
 * registration with w_d = 0 and then with all three terms. With fewer than 3 features the
 * subject is assumed upright (y up) but may face any way: see km_recon_init; the pose comes
 * from the data, and the template's landmarks (those of the character given to
 * km_recon_create that have a name) matched to their closest points stand in for the
 * features of the w_d = 0 stage. */
km_status km_recon_first_frame(km_recon *r, const double *P, size_t n,
                               const km_recon_feature *features, size_t n_features,
                               km_recon_frame_stats *stats, km_error *err);
/* Skeletal motion (L-BFGS) then surface refinement. A frame that fails is carried by the
 * skeleton prediction: the call still returns KM_OK with stats->status and stats->message
 * set (err is only filled when the call itself fails). */
km_status km_recon_next_frame(km_recon *r, const double *P, size_t n, km_recon_frame_stats *stats,
                              km_error *err);
/* Results of the last frame: refined surface and LBS-only (global motion) surface, #V*3,
 * and joint positions n_joints*3. Valid until the next call. */
const double *km_recon_surface(const km_recon *r);
const double *km_recon_global(const km_recon *r);
const double *km_recon_joints(const km_recon *r);
const km_mesh *km_recon_template(const km_recon *r); /* faces of the output */
/* How the first frame was initialised (zeros before it). */
void km_recon_init_get(const km_recon *r, km_recon_init *out);
void km_recon_free(km_recon **r);

/* Local-motion filter (paper IV-3C): out_t = global_t + sum_k g_k (refined - global)_{t+k},
 * Gaussian weights over |k| <= radius renormalised at the sequence ends. Arrays are
 * n_frames * n_vertices*3; out may alias refined. */
km_status km_local_motion_filter(size_t n_frames, size_t n_vertices, const double *refined,
                                 const double *global, int radius, double sigma, double *out,
                                 km_error *err);

/* Whole pipeline: reads frames, reconstructs, filters and streams frames to out_anim
 * (km_anim_writer: .glb, .pc2 or a directory) with a delay of filter_radius frames, so a
 * failure late in the run never loses finished frames. report may be NULL. */
km_status km_reconstruct(const char *const *frame_paths, size_t n_frames,
                         const km_character *template_character, const km_recon_feature *features,
                         size_t n_features, const km_recon_options *opt, const char *out_anim,
                         km_recon_report *report, km_error *err);

/* ---- avatar pose transfer, pose recognition, key-pose morphing */

/* Pose transfer by locally encoded Laplacian offsets (Lifkooee et al. 2019): a source mesh S
 * (the avatar) takes the pose of a template mesh T of the same connectivity. Offline:
 * offsets Delta = L X_S, per-vertex frames F(v) (normal, tangent from a fixed neighbour edge,
 * their cross product) and pose-invariant coordinates W_i = F_S(v_i)^T Delta_i. Online: the
 * landmark vertices are fixed at their targets, the rest solves
 *   (-L)_ff x_f = -(F W)_f + L_fc x_c          (eq. 7, symmetric elimination form)
 * (F W stands for the rotated offsets of the chosen km_offset_encoding)
 * with F = frames of T at first, then frames of the previous solution, until positions and
 * frames settle. The factor of (-L)_ff is computed once per landmark set. */
typedef enum km_laplacian_kind {
  KM_LAPLACIAN_UNIFORM = 0, /* graph Laplacian, the paper's eq. 2 */
  KM_LAPLACIAN_COTAN,       /* cotangent weights of the source mesh */
} km_laplacian_kind;

typedef enum km_transfer_align {
  /* T's landmark positions scaled about the origin by size(S)/size(T), T's placement kept.
   * size = sum of edge-graph geodesic distances from landmark 0 to the other landmarks:
   * pose-invariant and, unlike the surface area, insensitive to girth and belly. */
  KM_TRANSFER_ALIGN_SCALE = 0,
  /* Umeyama similarity (rotation, translation, scale) of T's landmarks onto the source's rest
   * landmarks (scale replaced by the geodesic size ratio): places the result where S
   * stands. Only sensible when T's pose is close to S's rest pose (the fit mixes pose and
   * placement otherwise). */
  KM_TRANSFER_ALIGN_SIMILARITY,
} km_transfer_align;

typedef enum km_offset_encoding {
  /* Default. Each one-ring edge in the frames of both its ends (E_ij = F_S(i) e_ij); the
   * right-hand side is sum_j w_ij (F(i)^T E_ij - F(j)^T E_ji) / 2. Identical to the paper's
   * encoding at rest (it sums to F(v_i) W_i when both frames agree), but where neighbouring
   * frames differ (a bent joint in the template) the result bends too: the Poisson /
   * ARAP-global-step form of the same locally encoded offsets. Measured on generated
   * subjects (3k vertices, 10 poses, tracked landmarks): 9 mm mean error vs 37 mm. */
  KM_OFFSETS_EDGE = 0,
  /* The paper's eq. 3 verbatim: one offset per vertex in the vertex's own frame, right-hand
   * side F(v_i) W_i. Rotating a rest offset cannot create the bend of a limb at a joint (a
   * straight tube has no bend in its offsets), so limbs bend only at the landmarks. */
  KM_OFFSETS_VERTEX,
} km_offset_encoding;

typedef struct km_transfer_options {
  km_laplacian_kind laplacian; /* 0: uniform */
  km_offset_encoding encoding; /* 0: per edge (see above); KM_OFFSETS_VERTEX: paper's eq. 3 */
  km_transfer_align align;     /* how landmark targets come from a template; 0: scale */
  int max_iterations;          /* solves per transfer; 0: 10 */
  double tolerance;            /* stop when the largest vertex move between two solves is below
                                  tolerance * bbox diagonal of S and the largest frame entry change is
                                  below tolerance; 0: 1e-4 */
} km_transfer_options;

typedef struct km_transfer km_transfer;

/* Offline stage. source: the avatar at rest (closed or open triangle mesh, #V vertices).
 * landmarks: n_landmarks distinct vertex ids, >= 3 (fewer leaves the Laplacian rank
 * deficient up to a rotation: KM_ERR_INVALID). The object keeps copies of what it needs. */
km_status km_transfer_precompute(const km_mesh *source, const int32_t *landmarks,
                                 size_t n_landmarks, const km_transfer_options *opt,
                                 km_transfer **out, km_error *err);

typedef struct km_transfer_stats {
  int iterations;         /* linear solves done */
  bool converged;         /* tolerance met before max_iterations */
  double position_change; /* last iteration's largest vertex move / bbox diagonal */
  double frame_change;    /* largest frame entry change at the last frame update; NAN while the
                             positions still move (only measured once they settle; frames are not
                             recomputed after the last allowed solve) */
  double frames_ms;       /* time in normals + frames, all iterations */
  double solve_ms;        /* time in right-hand sides + triangular solves, all iterations */
  double total_ms;        /* whole call */
} km_transfer_stats;

/* Online stage. All arrays are #V*3 (or n_landmarks*3 for targets), row-major.
 *  template_V  positions of T (same connectivity as S); its frames start the iteration.
 *              May be NULL when warm_start is given.
 *  targets     landmark positions in precompute order; NULL: from template_V's landmark
 *              vertices through the options' align mode (template_V then required).
 *  warm_start  a previous result (e.g. the last key pose); its frames start the iteration
 *              when template_V is NULL. Ignored otherwise. May be NULL.
 *  V_out       result, may alias warm_start but not template_V.
 *  stats       may be NULL.
 * Does not allocate. Not thread-safe on one object. */
km_status km_transfer_solve(km_transfer *t, const double *template_V, const double *targets,
                            const double *warm_start, double *V_out, km_transfer_stats *stats,
                            km_error *err);
size_t km_transfer_vertices(const km_transfer *t);
size_t km_transfer_landmarks(const km_transfer *t);
/* Landmark targets the solver would use for template_V (n_landmarks*3). Uses the object's
 * scratch (one Dijkstra): not thread-safe on one object, does not allocate. */
km_status km_transfer_targets(const km_transfer *t, const double *template_V, double *targets,
                              km_error *err);
/* Offline timings of precompute: Laplacian + offsets + frames, and symbolic + numeric
 * Cholesky, in milliseconds. Either may be NULL. */
void km_transfer_precompute_ms(const km_transfer *t, double *laplacian_ms, double *cholesky_ms);
void km_transfer_free(km_transfer **t);

/* Total triangle area (for pose-invariant size ratios). */
double km_surface_area(const km_mesh *m);

/* Landmark files. LM.json: {"landmarks":[{"name":"head","vertex":411,"mirror":"head"},...]};
 * a character rig sidecar (*.rig.json) carries the same array and is accepted as is.
 * Every mirror must name a landmark of the file (itself on the mid-line). Reads at most
 * `capacity` landmarks (more: KM_ERR_PARSE); n_vertices > 0 checks vertex ids. */
#define KM_POSE_MAX_LANDMARKS 32
km_status km_landmarks_read(const char *path, size_t n_vertices, km_landmark *out, size_t capacity,
                            size_t *n, km_error *err);
km_status km_landmarks_write(const char *path, const km_landmark *lm, size_t n, km_error *err);

/* Pose descriptor (eq. 4). For n landmarks the candidate features are all angles
 * angle(i, j, k) at landmark j between segments j->i and j->k, i < k, i, k != j:
 * n (n-1) (n-2) / 2 of them (1,680 for 16 landmarks), in the order j major, then i, then k.
 * A feature is stored as its triple {i, j, k}. */
size_t km_pose_candidate_count(size_t n_landmarks);
/* The triple of candidate feature f. */
void km_pose_candidate(size_t n_landmarks, size_t f, int32_t triple[3]);
/* Angles in radians [0, pi] of the given triples for landmark positions P (n*3);
 * a zero-length segment gives pi/2. */
void km_pose_angles(const double *P, const int32_t *triples, size_t n_features, double *out);

typedef enum km_svm_kernel { KM_SVM_RBF = 0, KM_SVM_LINEAR } km_svm_kernel;

/* How the paper's left/right mirroring is used (section 3.2.1): "when an angle (i,j,k) is
 * observed, also add an instance of (m(i),m(j),m(k))". */
typedef enum km_pose_mirror {
  /* default: the feature-selection trees see every sample twice, as measured and mirrored
   * (same class), so the selected angles are not biased to the side the data moves most;
   * the SVM is trained on the samples as measured, so left and right variants of a pose
   * may be distinct classes. */
  KM_POSE_MIRROR_SELECTION = 0,
  KM_POSE_MIRROR_ALL,  /* also add mirrored samples to the SVM training set (same class) */
  KM_POSE_MIRROR_NONE, /* no mirroring */
} km_pose_mirror;

typedef struct km_posedb_options {
  size_t features;       /* d, selected angles; 0: 60 (capped by the candidate count) */
  int tree_max_depth;    /* CART depth limit; 0: 16 */
  km_pose_mirror mirror; /* 0: mirrored samples in feature selection only */
  km_svm_kernel kernel;  /* 0: RBF */
  double svm_c;          /* 0: 10 */
  double svm_gamma;      /* RBF gamma on features scaled to [-1,1]; 0: 1/d */
  int cv_folds;          /* k-fold cross-validation when no groups are given; 0: 5, 1: none */
  km_progress progress;
} km_posedb_options;

typedef struct km_posedb km_posedb;

typedef struct km_posedb_report {
  size_t samples, classes, features;
  double cv_accuracy; /* correct / total over held-out folds; -1 when no cross-validation ran */
  size_t cv_folds;    /* folds used (groups: one per group) */
  double build_ms;
  double cv_accuracy_eq8; /* the paper's eq. 8, (TP+TN)/(TP+TN+FP+FN) averaged over the K
                             one-vs-rest problems: 1 - 2 e / (N K) for e errors in N tests,
                             always >= cv_accuracy; -1 when no cross-validation ran */
} km_posedb_report;

/* Builds a pose database from n_meshes meshes of one connectivity (point clouds are fine when
 * only recognition is wanted). labels[i] in [0, n_classes) is the pose class of mesh i;
 * class_names (n_classes, may be NULL) label them; groups (may be NULL) give the subject of
 * each mesh so that cross-validation leaves one subject out at a time. landmarks (n >= 4,
 * with mirrors) are vertex ids on the meshes. Feature selection is CART (Gini) over all
 * candidate angles, classification libsvm, template choice nearest neighbour inside the class.
 * The database keeps a copy of the meshes as templates. report may be NULL. */
km_status km_posedb_build(const km_mesh *meshes, size_t n_meshes, const int32_t *labels,
                          size_t n_classes, const char *const *class_names, const int32_t *groups,
                          const km_landmark *landmarks, size_t n_landmarks,
                          const km_posedb_options *opt, km_posedb **out, km_posedb_report *report,
                          km_error *err);

typedef struct km_pose_match {
  int32_t label;         /* predicted class */
  size_t template_index; /* nearest database mesh of that class */
  double distance;       /* descriptor distance to it (scaled features) */
  double ms;             /* descriptor + SVM + nearest neighbour time */
} km_pose_match;

/* Recognises the pose given by landmark positions P (n_landmarks*3, database order). */
km_status km_posedb_query(const km_posedb *db, const double *P, km_pose_match *out, km_error *err);
/* Single-file database (binary, versioned: "KMPOSEDB" magic, version, JSON header, raw
 * little-endian arrays, FNV-1a checksum). The SVM is retrained on load from the stored
 * templates (deterministic, milliseconds for thousands of samples). */
km_status km_posedb_save(const km_posedb *db, const char *path, km_error *err);
km_status km_posedb_load(const char *path, km_posedb **out, km_error *err);
size_t km_posedb_size(const km_posedb *db);
size_t km_posedb_classes(const km_posedb *db);
const char *km_posedb_class_name(const km_posedb *db, size_t c); /* "" when unnamed */
int32_t km_posedb_label(const km_posedb *db, size_t i);
size_t km_posedb_landmark_count(const km_posedb *db);
const km_landmark *km_posedb_landmarks(const km_posedb *db);
/* Template i as a mesh view (V, F owned by the database; do not free). */
void km_posedb_template(const km_posedb *db, size_t i, km_mesh *view);
/* Names for the templates (e.g. their file names, n = km_posedb_size entries, at most 127
 * characters kept), saved with the database so a query can say which mesh it picked. */
km_status km_posedb_set_template_names(km_posedb *db, const char *const *names, km_error *err);
const char *km_posedb_template_name(const km_posedb *db, size_t i); /* "" when unnamed */
/* Selected features: d triples (d*3 ints, owned by the database), best first. */
const int32_t *km_posedb_features(const km_posedb *db, size_t *d);
/* The build report (cv figures as stored; samples/classes/features of this database). */
void km_posedb_info(const km_posedb *db, km_posedb_report *report);
void km_posedb_free(km_posedb **db);

/* Decision tree (CART, Gini impurity) over dense features, exposed for tests and tools.
 * X row-major n_samples x n_features, y in [0, n_classes). importance (n_features, may be
 * NULL): total weighted impurity decrease per feature, normalised to sum 1. */
typedef struct km_cart km_cart;
km_status km_cart_fit(const double *X, const int32_t *y, size_t n_samples, size_t n_features,
                      size_t n_classes, int max_depth, km_cart **out, double *importance,
                      km_error *err);
int32_t km_cart_predict(const km_cart *tree, const double *x);
size_t km_cart_nodes(const km_cart *tree);
void km_cart_free(km_cart **tree);

/* Tracked landmark sequences (TRACK).
 * JSON: {"fps":30,"landmarks":["head",...],"frames":[[x,y,z, ...], ...]} with 3 numbers per
 *       landmark per frame (null: not tracked in that frame -> NaN).
 * CSV:  first line the landmark names separated by commas; then one frame per line with
 *       3 numbers per landmark (x,y,z in landmark order), comma-separated; empty field: NaN.
 *       fps 30. Format by extension (.json / .csv). Units: metres. */
typedef struct km_track {
  size_t n_frames, n_landmarks;
  double fps;
  char (*names)[32]; /* n_landmarks */
  double *positions; /* n_frames * n_landmarks * 3 */
} km_track;
km_status km_track_read(const char *path, km_track *out, km_error *err);
km_status km_track_write(const char *path, const km_track *t, km_error *err);
void km_track_free(km_track *t);

/* Linear interpolation out = (1-a) A + a B of two key poses (n*3 values); out may alias. */
void km_pose_lerp(const double *A, const double *B, size_t n_vertices, double a, double *out);

typedef struct km_avatar_options {
  size_t key_every;   /* k: recognise + transfer every k frames, interpolate between; 0: 1 */
  double track_scale; /* avatar size / tracked body size; 0: from the first key frame
                         (size(avatar)/size(template) as in KM_TRANSFER_ALIGN_SCALE, over the
                         Umeyama scale template->track) */
  km_progress progress;
} km_avatar_options;

typedef struct km_avatar_stats {
  size_t frames, key_frames;
  double recognition_ms, transfer_ms; /* totals over key frames */
  double iterations_mean;
  double max_frame_ms; /* slowest key frame, recognition + transfer */
} km_avatar_stats;

/* Called once per output frame, in order; returning non-OK stops the run with that status. */
typedef km_status (*km_avatar_frame_fn)(size_t frame, const double *V, void *user, km_error *err);

/* Motion generation (section 3.5): every k-th track frame (and the last) is recognised in db,
 * its template transferred onto the avatar with the tracked landmarks (scaled to the avatar)
 * as targets, and frames in between are linear interpolations of consecutive key poses, so
 * there is one output frame per track frame. t must be precomputed on the avatar with the
 * landmark vertices in the database's landmark order; the track's landmarks are matched to
 * the database's by name (or taken in order when the track has no names). A key frame with
 * an untracked (NaN) landmark repeats the previous key pose. */
km_status km_avatar_animate(km_transfer *t, const km_posedb *db, const km_track *track,
                            const km_avatar_options *opt, km_avatar_frame_fn fn, void *user,
                            km_avatar_stats *stats, km_error *err);

#ifdef __cplusplus
}
#endif
#endif /* KINEMESH_H */
