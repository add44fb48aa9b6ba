/* kinemesh — animate any triangle mesh from captured human motion.
 *
 * The one public header. C11, no third-party types: solver objects are opaque.
 * Sections follow the library's layers, bottom up; each names the module (src/<m>/) that
 * implements it and may use only the sections above it (docs/architecture.md):
 *
 *   core      version, errors, logging & progress, clock, atomic files      src/core/
 *   linalg    sparse matrices, sparse Cholesky, eigenpairs                    src/linalg/
 *   math      linear blend skinning, skeleton poses                          src/math/
 *   mesh      meshes, I/O, topology, operators, point clouds                 src/mesh/
 *   motion    skeletons, takes, motion formats, filter, rig, retargeting,
 *             character rig sidecar                                          src/motion/
 *   anim      animation writers and readers (glTF, PC2, frame directories)   src/anim/
 *   puppet    puppetry deformers (Wu, Lu & Song 2012)                        src/puppet/
 *   transfer  pose transfer, pose recognition, morphing (Lifkooee et al. 2019) src/transfer/
 *   recon     point clouds to mesh animation (Park & Lim 2014)               src/recon/
 *   synth     procedural character, generated motion, pose presets,
 *             capture simulator                                              src/synth/
 *
 * The three papers the solvers follow, named wherever an equation or section is cited:
 *   Wu, Lu & Song 2012  — real-time mesh puppetry from Kinect joints with a reduced isoline
 *                         model (puppet, and the motion filter and retargeting it uses).
 *   Lifkooee et al. 2019 — avatar pose transfer by locally encoded Laplacian offsets, pose
 *                         recognition from landmark angles, key-pose morphing (transfer).
 *   Park & Lim 2014     — template-based reconstruction of a mesh animation from point
 *                         clouds, after Allen, Curless & Popovic 2003 (recon).
 *
 * Conventions (read once, they hold everywhere):
 *  - Every fallible call returns km_status (KM_OK == 0) and, when `err` is not NULL,
 *    fills it with a message for the user naming the file, line/byte and what was expected.
 *    Any of them may return KM_ERR_INVALID (NULL or out-of-range argument) and KM_ERR_NOMEM;
 *    a function's "Errors:" line lists the other statuses it returns.
 *  - Arrays are plain, row-major, owned by whoever allocated them. Positions are
 *    `double V[#V*3]` (x0 y0 z0 x1 ...), triangles `int32_t F[#F*3]`. Dense matrices with
 *    several columns (eigenvectors, right-hand sides) are column-major: column c of an
 *    n-row matrix starts at X + c*n.
 *  - Argument lists (libigl's habit): `V  #V*3 rest positions` names an argument, its size
 *    (#V vertices, #F faces, #J joints, #H handles, #L landmarks, #P points) and meaning.
 *    "in" arguments are read only; "out" arguments are caller-allocated arrays of the stated
 *    size unless the text says "allocated", in which case the named free function (or
 *    free()) releases them. A NULL out argument marked "may be NULL" is skipped.
 *  - Units: metres inside the library.
 *  - Laplacian sign: L is negative semidefinite, rows sum to zero (L_ii = -sum_j L_ij).
 *    System matrices are built from -L plus constraints so they are SPD.
 *  - Objects follow precompute (or create / analyze / open) -> solve (or push) -> free.
 *    Solve depends only on values, not on topology or the set of handles, does not allocate
 *    and does not log. No object is thread-safe; distinct objects may be used in parallel.
 *  - Frees take the address of what they free and set it to NULL; freeing NULL is a no-op.
 *    Plain structs (km_mesh, km_take, ...) are freed by value-pointer and zeroed.
 *  - The library never prints. Install a logger with km_set_logger() to see its messages.
 *
 * Test fixtures (primitive meshes, the CART tree, single capture frames) are not part of
 * this API: they are declared in src/synth/synth.h and src/transfer/transfer.h.
 */
#ifndef KINEMESH_H
#define KINEMESH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ==== core: version, errors, logging & progress, clock, atomic files (src/core/) ==== */

#define KM_VERSION_MAJOR 0
#define KM_VERSION_MINOR 1
#define KM_VERSION_PATCH 0
/* Returns the library version, "MAJOR.MINOR.PATCH" (static string, never NULL). */
const char *km_version(void);

/* ---- errors */

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

/* Fills err with status and a printf-formatted message, so that a caller's failure path
 * reads `return km_error_set(err, KM_ERR_IO, "%s: ...", path)`.
 *   err     out: may be NULL (then nothing is written)
 *   status  in: the status to record
 *   fmt     in: printf format and its arguments; the message is truncated to 1023 bytes
 * Returns status. */
km_status km_error_set(km_error *err, km_status status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Stable name of a status ("KM_ERR_PARSE").
 *   s  in: any value
 * Returns a static string, never NULL ("KM_ERR_UNKNOWN" for a value out of range). */
const char *km_status_name(km_status s);

/* ---- logging & progress */

typedef enum km_log_level { KM_LOG_DEBUG = 0, KM_LOG_INFO, KM_LOG_WARN, KM_LOG_ERROR } km_log_level;
typedef void (*km_log_fn)(km_log_level level, const char *message, void *user);
/* Installs the process-wide logger (the library is silent by default).
 *   fn    in: called with each message (no trailing newline); NULL silences the library
 *   user  in: passed back to fn untouched */
void km_set_logger(km_log_fn fn, void *user);

/* Called by long operations with fraction in [0,1] and a short stage name.
 * Return false to cancel: the operation then returns KM_ERR_CANCELLED. */
typedef bool (*km_progress_fn)(double fraction, const char *stage, void *user);
typedef struct km_progress {
  km_progress_fn fn; /* NULL: no reports */
  void *user;
} km_progress;

/* ---- clock */

/* Returns a monotonic clock reading in seconds (for timing; arbitrary origin). */
double km_seconds(void);

/* ---- atomic files */

/* Writes a file atomically: a temporary file beside it, flushed, then renamed, so a reader
 * never sees a half-written file and a failure leaves nothing behind. The temporary is
 * created exclusively (never opened through a planted file or symlink) and gets the
 * replaced file's permissions (a new file: 0666 less the umask).
 *   path  in: destination file
 *   data  in: size bytes to write
 * Errors: KM_ERR_IO naming path. */
km_status km_write_file_atomic(const char *path, const void *data, size_t size, km_error *err);

/* Removes the temporaries of every output being written at this moment (every writer of the
 * library goes through one). Async-signal-safe: for a SIGINT/SIGTERM handler that then
 * exits, so an interrupted run leaves no "*.tmp.*" file behind. */
void km_remove_temporaries(void);

/* ==== linalg: sparse matrices, sparse Cholesky, eigenpairs (src/linalg/) ==== */

/* ---- sparse matrices */

/* Sparse matrix (compressed columns, int32 indices, double values, sorted, no duplicates).
 * Symmetric matrices are stored with both triangles. Backed by CHOLMOD. */
typedef struct km_sparse km_sparse;

/* Builds a matrix from triplets; duplicate (i,j) entries are summed.
 *   n_rows, n_cols  in: shape
 *   rows, cols      in: nnz row / column indices, 0-based, within the shape
 *   values          in: nnz values
 *   out             out: allocated matrix; free with km_sparse_free */
km_status km_sparse_from_triplets(size_t n_rows, size_t n_cols, size_t nnz, const int32_t *rows,
                                  const int32_t *cols, const double *values, km_sparse **out,
                                  km_error *err);
/* Diagonal matrix.
 *   diag  in: n diagonal values
 *   out   out: allocated n x n matrix; free with km_sparse_free */
km_status km_sparse_diagonal(size_t n, const double *diag, km_sparse **out, km_error *err);
/* Linear combination C = alpha*A + beta*B.
 *   A, B  in: matrices of the same shape
 *   out   out: allocated C; free with km_sparse_free */
km_status km_sparse_add(double alpha, const km_sparse *A, double beta, const km_sparse *B,
                        km_sparse **out, km_error *err);
/* Shape and stored entries of A (A in; returns the count). */
size_t km_sparse_rows(const km_sparse *A);
size_t km_sparse_cols(const km_sparse *A);
size_t km_sparse_nnz(const km_sparse *A);
/* Read-only view of the CSC arrays, owned by A (valid until it is freed).
 *   A        in: matrix
 *   col_ptr  out: cols+1 column starts
 *   row_idx  out: nnz row indices, sorted within each column
 *   values   out: nnz values */
void km_sparse_csc(const km_sparse *A, const int32_t **col_ptr, const int32_t **row_idx,
                   const double **values);
/* Returns A(i,j), 0 when not stored (or out of range). */
double km_sparse_coeff(const km_sparse *A, size_t i, size_t j);
/* Product Y = A X.
 *   A  in: rows x cols matrix
 *   X  in: cols x k, column-major
 *   Y  out: rows x k, column-major; must not alias X */
void km_sparse_mul(const km_sparse *A, size_t k, const double *X, double *Y);
/* Frees *A and sets it to NULL. */
void km_sparse_free(km_sparse **A);

/* ---- sparse Cholesky */

/* Sparse Cholesky of a symmetric positive-definite matrix (CHOLMOD).
 * analyze once per pattern, factorize whenever the values change, solve many times.
 * solve does not allocate (workspace is kept in the object) and is not thread-safe on one
 * object. */
typedef struct km_cholesky km_cholesky;
/* Symbolic analysis (fill-reducing ordering) of a pattern.
 *   A    in: n x n symmetric matrix (both triangles stored); only its pattern is used
 *   out  out: allocated factor object, not yet factorized; free with km_cholesky_free */
km_status km_cholesky_analyze(const km_sparse *A, km_cholesky **out, km_error *err);
/* Numeric factorisation.
 *   c  in/out: analyzed object
 *   A  in: matrix with the pattern given to analyze
 * Errors: KM_ERR_NOT_POSDEF when A is not SPD. */
km_status km_cholesky_factorize(km_cholesky *c, const km_sparse *A, km_error *err);
/* Solves A X = B with the last factorisation.
 *   B  in: n x nrhs, column-major
 *   X  out: n x nrhs, column-major; may alias B */
km_status km_cholesky_solve(km_cholesky *c, size_t nrhs, const double *B, double *X, km_error *err);
/* Returns n, the order of the analyzed matrix. */
size_t km_cholesky_size(const km_cholesky *c);
/* Frees *c and sets it to NULL. */
void km_cholesky_free(km_cholesky **c);
/* Threads OpenBLAS runs on (process-wide: CHOLMOD's supernodal factorisations and the dense
 * products use it). OpenBLAS starts with one per core, and between calls its idle threads spin
 * (sched_yield) for a while: a program that factorises often and runs OpenMP loops of its own
 * (reconstruct: 4 factorisations of a 16k system per frame) spends about half its CPU time
 * there; 1 keeps the factorisations in the calling thread.
 *   n  in: >= 1 sets the count; <= 0 only queries
 * Returns the count before the call. */
int km_blas_threads(int n);

/* ---- eigenpairs */

typedef struct km_eigs_options {
  double sigma; /* shift; 0: a small negative shift relative to the spectrum scale */
  double tol;   /* ARPACK tolerance; 0: 1e-10 */
  int max_iter; /* 0: 1000 */
  int ncv;      /* Lanczos vectors; 0: min(n, max(2k+1, 20)) */
  km_progress progress;
} km_eigs_options;
/* The k smallest eigenpairs of -L phi = lambda M phi by ARPACK in shift-invert mode on a
 * CHOLMOD factor of (-L - sigma M).
 *   L      in: #V x #V symmetric negative semidefinite (e.g. km_cotmatrix)
 *   M      in: #V x #V diagonal SPD (e.g. km_massmatrix)
 *   k      in: 1 <= k < #V
 *   opt    in: may be NULL (defaults)
 *   evals  out: k eigenvalues, ascending; may be NULL
 *   evecs  out: #V x k column-major, M-orthonormal; may be NULL
 * Errors: KM_ERR_NOT_POSDEF, KM_ERR_NO_CONVERGENCE, KM_ERR_CANCELLED. */
km_status km_eigs(const km_sparse *L, const km_sparse *M, int k, const km_eigs_options *opt,
                  double *evals, double *evecs, km_error *err);

/* ==== math: linear blend skinning, skeleton poses (src/math/) ==== */

/* km_mesh (mesh section), km_skeleton and km_skin (motion section) are defined with the
 * modules that own them; the skinning maths below only takes pointers to them. */
typedef struct km_mesh km_mesh;
typedef struct km_skeleton km_skeleton;
typedef struct km_skin km_skin;

/* Per-joint rigid transforms that take the rest skeleton to the given joint positions: each
 * joint's rotation is the minimal rotation of its rest bone direction(s) onto the posed
 * ones (no twist), composed down the hierarchy.
 *   s           in: skeleton, #J joints with rest positions
 *   positions   in: #J*3 posed joint positions; a NaN joint keeps the rest-relative
 *               transform of its parent
 *   transforms  out: #J*12, per joint row-major 3x4 [R | t] */
km_status km_skeleton_pose_from_positions(const km_skeleton *s, const double *positions,
                                          double *transforms, km_error *err);
/* The same rotations, with the skeleton's own bone lengths: the root goes to its posed
 * position, and every other joint where its parent's transform carries its rest position, so
 * each skinned part moves rigidly and a take of other proportions (a performer's, another
 * skeleton's) turns the limbs without pulling them apart. What `pose` plays.
 *   s, positions, transforms  as km_skeleton_pose_from_positions (the positions give only
 *                             directions below the root) */
km_status km_skeleton_pose_from_directions(const km_skeleton *s, const double *positions,
                                           double *transforms, km_error *err);
/* Joint rest positions at the boundaries of the skinned parts (Park & Lim 2014: the skeleton
 * of a template that has only weights). Joint j sits at the weighted centroid of the
 * vertices its part shares with its parent's part (weight min(w_j, w_parent)); a root, or a
 * joint whose part shares no vertex with its parent's, sits at the weighted centroid of its
 * own part; a joint no vertex is weighted to keeps the position in `rest`.
 *   m        in: mesh, #V vertices
 *   skin     in: #V vertices' weights over n_joints joints
 *   parents  in: n_joints parents, -1 for roots
 *   rest     in/out: n_joints*3; in: a guess (may be the rig's), out: the estimate */
km_status km_skeleton_from_weights(const km_mesh *m, const km_skin *skin, const int32_t *parents,
                                   size_t n_joints, double *rest, km_error *err);
/* Least-squares similarity dst ~ s R src + t (Umeyama 1991 / Kabsch: one SVD); the one fit
 * used for rig alignment, pose transfer and reconstruction alike.
 *   src, dst    in: n*3 paired points, n >= 3
 *   weights     in: n weights >= 0; may be NULL (equal weights)
 *   with_scale  in: false fits a rigid motion (s = 1)
 *   s           out: scale; may be NULL when with_scale is false
 *   R           out: row-major 3x3 proper rotation
 *   t           out: translation
 * Errors: KM_ERR_DEGENERATE_MESH when the source points coincide or the pairs are collinear. */
km_status km_similarity_fit(const double *src, const double *dst, const double *weights, size_t n,
                            bool with_scale, double *s, double R[9], double t[3], km_error *err);
/* Linear blend skinning: out_v = sum_k w_k T_{j_k} rest_v.
 *   rest        in: #V*3 rest positions
 *   skin        in: #V vertices' joints and weights
 *   transforms  in: n_joints*12 row-major 3x4 (km_skeleton_pose_from_positions)
 *   out         out: #V*3 posed positions; may not alias rest */
km_status km_lbs(const double *rest, size_t n_vertices, const km_skin *skin,
                 const double *transforms, size_t n_joints, double *out, km_error *err);

/* ==== mesh: meshes, I/O, topology, operators, point clouds (src/mesh/) ==== */

/* ---- the mesh */

typedef struct km_mesh {
  double *V;  /* #V*3 positions */
  int32_t *F; /* #F*3 triangles, 0-based */
  size_t n_vertices;
  size_t n_faces; /* 0 for a point cloud */
  /* ---- optional per-vertex attributes as read (issue 11); NULL when the file has none.
   * Owned by the mesh like V and F (km_mesh_free frees them, km_mesh_copy copies them). A
   * mesh built by hand may leave them NULL: every function that does not say otherwise
   * ignores them. */
  double *UV; /* #V*2 texture coordinates (u, v), OBJ vt / PLY u v, s t, texture_u texture_v */
  double *N;  /* #V*3 normals as read (OBJ vn / PLY nx ny nz; not renormalised) */
  /* The file's surface colours (a glTF's primitives' materials, an OBJ's usemtl groups: base
   * colour factor and texture image), carried to the .glb outputs so a textured model does not
   * come out grey: n_materials of them, each over a run of faces, the runs in face order
   * covering every face; NULL / 0: none. Owned like UV. */
  struct km_mesh_material *materials;
  size_t n_materials;
  /* #V*4 vertex colours, RGBA in [0, 1], sRGB-encoded as PLY (red green blue [alpha], uchar or
   * float; diffuse_red ...), OBJ (v x y z r g b) and scanners store them: a scan or a
   * photogrammetry model carries its colour so, not as a texture. A glTF's COLOR_0 (linear) is
   * converted on the way in and out. Carried by every writer (.glb COLOR_0, PLY uchar, OBJ v
   * lines). Owned like UV. */
  double *colors;
} km_mesh;

/* How a texture is sampled, as glTF's sampler says (pixel art keeps its pixels with NEAREST,
 * a decal CLAMP_TO_EDGE), in its OpenGL enums (9728 NEAREST, 9729 LINEAR, 9984..9987 the
 * mipmap filters; 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT, 10497 REPEAT); 0: not given
 * (the viewer's default: linear, repeat). */
typedef struct km_mesh_sampler {
  int mag_filter, min_filter, wrap_s, wrap_t;
} km_mesh_sampler;

/* One texture image as encoded in the file it came from (PNG or JPEG bytes). */
typedef struct km_mesh_image {
  unsigned char *bytes;    /* NULL: none */
  size_t size;             /* bytes */
  char mime[16];           /* "image/png" or "image/jpeg" */
  km_mesh_sampler sampler; /* how the texture using it is sampled */
} km_mesh_image;

/* A material's textures besides the base colour (glTF's), indexing km_mesh_material.maps. */
typedef enum km_mesh_map {
  KM_MAP_METALLIC_ROUGHNESS = 0, /* glTF metallicRoughnessTexture: B metallic, G roughness */
  KM_MAP_NORMAL,                 /* glTF normalTexture: tangent-space normals (OBJ norm) */
  KM_MAP_OCCLUSION,              /* glTF occlusionTexture: R ambient occlusion */
  KM_MAP_EMISSIVE,               /* glTF emissiveTexture: RGB emitted colour (OBJ map_Ke) */
  KM_MAP_COUNT
} km_mesh_map;

/* glTF's alphaMode. */
typedef enum km_mesh_alpha_mode {
  KM_ALPHA_OPAQUE = 0, /* alpha ignored */
  KM_ALPHA_MASK,       /* drawn where alpha >= alpha_cutoff, else not at all */
  KM_ALPHA_BLEND       /* blended over what is behind */
} km_mesh_alpha_mode;

/* A mesh's surface: what a .glb output writes as its material (pbrMetallicRoughness, normal,
 * occlusion and emissive textures), an OBJ output as its .mtl entry. */
typedef struct km_mesh_material {
  double base_color[4]; /* RGBA factor, linear (glTF baseColorFactor; 1,1,1,1 by default) */
  double metallic;      /* glTF metallicFactor (1 by default) */
  double roughness;     /* glTF roughnessFactor (1 by default) */
  unsigned char *image; /* the base colour texture as encoded in the file (PNG or JPEG bytes);
                           NULL: none */
  size_t image_size;    /* bytes */
  char image_mime[16];  /* "image/png" or "image/jpeg" */
  km_mesh_sampler image_sampler; /* how the base colour texture is sampled */
  size_t first_face;             /* the faces it colours: first_face .. first_face + n_faces - 1 */
  size_t n_faces;
  /* The other textures, each over TEXCOORD_0 (a glTF texture on another set is left out with
   * a warning: only the first set is carried) and their factors, as glTF defines them. */
  km_mesh_image maps[KM_MAP_COUNT];
  double normal_scale;       /* normalTexture.scale; 0: 1 */
  double occlusion_strength; /* occlusionTexture.strength; 0: 1 */
  double emissive[3];        /* emissiveFactor, linear RGB (0, 0, 0 by default) */
  /* How the alpha (base_color[3] times the texture's) is drawn, as glTF's alphaMode: hair cards
   * and leaves are cut out (MASK), glass and cloth edges blended (BLEND); and whether the back
   * of each face is drawn too (doubleSided: thin cloth, hair). */
  km_mesh_alpha_mode alpha_mode; /* 0: KM_ALPHA_OPAQUE */
  double alpha_cutoff;           /* KM_ALPHA_MASK's threshold; 0: 0.5 */
  bool double_sided;
} km_mesh_material;

/* Allocates a mesh with uninitialised V and F.
 *   n_vertices, n_faces  in: #V (<= INT32_MAX) and #F
 *   out                  out: V #V*3 and F #F*3 allocated; free with km_mesh_free */
km_status km_mesh_alloc(size_t n_vertices, size_t n_faces, km_mesh *out, km_error *err);
/* The vertex colours as 8-bit RGBA, as PLY's uchar colours and the live page's mesh carry
 * them: each channel of km_mesh.colors (sRGB, [0, 1]) times 255, rounded, clamped to 0..255.
 *   m    in: mesh with colors (#V*4)
 *   out  out: #V*4 bytes; left as it is when m has no colours
 * Returns whether m has colours. */
bool km_mesh_colors_rgba8(const km_mesh *m, unsigned char *out);
/* Deep copy.
 *   src  in: mesh
 *   out  out: allocated copy; free with km_mesh_free */
km_status km_mesh_copy(const km_mesh *src, km_mesh *out, km_error *err);
/* Frees m->V, m->F, m->UV, m->N, m->materials and zeroes the struct (the struct itself is the
 * caller's). */
void km_mesh_free(km_mesh *m);
/* 64-bit FNV-1a hash of the counts, positions and faces (attributes are not included): the
 * key of the default reduced-model cache. Same mesh bytes, same hash. 0 for NULL. */
uint64_t km_mesh_hash(const km_mesh *m);

/* ---- I/O */

typedef enum km_mesh_format {
  KM_FORMAT_AUTO = 0, /* from the file extension */
  KM_FORMAT_OBJ,
  KM_FORMAT_PLY,
  KM_FORMAT_OFF,
  KM_FORMAT_GLTF, /* .glb / .gltf: read only (issue 11) */
  KM_FORMAT_STL,  /* .stl: read binary or ASCII, written binary */
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

/* Reads OBJ / PLY (ascii, binary LE/BE) / OFF / STL (binary, ASCII) / glTF 2.0 (.glb, .gltf),
 * format by extension.
 * glTF: the triangles, POSITION, NORMAL and TEXCOORD_0 of the scene's meshes, merged in
 * order (nodes depth-first as listed, each node's mesh's primitives in order; vertex order =
 * accessor order, primitive after primitive) with the nodes' world transforms applied (a
 * file without nodes: its meshes in order, as stored); v = 1 - v_gltf (OBJ's origin).
 * Compressed glTF (gltfpack's, `--compress`) is decoded: EXT_meshopt_compression buffer views
 * (ATTRIBUTES / TRIANGLES / INDICES, filters OCTAHEDRAL / QUATERNION / EXPONENTIAL) and
 * KHR_mesh_quantization (byte / short POSITION, NORMAL, TEXCOORD_0, normalized or not,
 * dequantised by the node transforms or inverse bind matrices; TEXCOORD_0 through the base
 * colour texture's KHR_texture_transform when there is one); a malformed compressed view is
 * KM_ERR_PARSE naming the bufferView. KHR_draco_mesh_compression primitives are decoded
 * (libdraco) and read the same way; their vertex order is the decoded one (Draco's encoder
 * reorders vertices); a bitstream that does not decode or an accessor that disagrees with it
 * is KM_ERR_PARSE naming the primitive and the attribute.
 * Vertex order and count are exactly those of the file; polygons are fan-triangulated
 * (0,i,i+1). A PLY without faces reads as a point cloud (n_faces == 0).
 * STL has no vertex list: corners with bit-equal coordinates are welded into one vertex,
 * vertex i being the i-th distinct position in facet order, and face i is facet i (one
 * whose corners weld together is kept, degenerate); facet normals are ignored. Binary when
 * the count at byte 80 accounts for the file's size (padding of less than a triangle
 * ignored), whatever its header says.
 * Attributes: OBJ `vt`/`vn` are attached to vertices through the faces' v/vt/vn references
 * (the vertex count stays that of the `v` lines: where a vertex is referenced with several
 * UVs or normals, at a texture seam, the first reference in file order wins and the others
 * are dropped; vertices no face references with a vt get (0,0)); PLY vertex properties
 * u v (or s t, texture_u texture_v) and nx ny nz are read as they are.
 *   path  in: file
 *   out   out: allocated mesh; free with km_mesh_free
 * Errors: KM_ERR_IO, KM_ERR_PARSE naming path and the line (text) or byte offset (binary),
 * KM_ERR_UNSUPPORTED. */
km_status km_mesh_read(const char *path, km_mesh *out, km_error *err);
/* km_mesh_read from memory.
 *   data, size  in: file contents (need not be NUL-terminated)
 *   format      in: must not be AUTO unless `name` has an extension
 *   name        in: used for the format and in error messages
 *   out         out: allocated mesh; free with km_mesh_free
 * Errors: as km_mesh_read. */
km_status km_mesh_parse(const void *data, size_t size, km_mesh_format format, const char *name,
                        km_mesh *out, km_error *err);

/* The skin of a skinned glTF as the file has it (km_mesh_read_skinned); kinemesh's skeleton
 * and skin are made from it by km_character_from_skin (autorig section). */
typedef struct km_mesh_skin {
  size_t n_joints;   /* 0: the file has no skin (the arrays are then NULL) */
  char **names;      /* n_joints: the joint nodes' names ("node<i>" for an unnamed node) */
  int32_t *parents;  /* n_joints: the nearest ancestor node that is a joint too, -1 (any order) */
  double *rest;      /* n_joints*3: each joint node's world position in the file's scene */
  size_t n_vertices; /* the mesh's #V */
  int32_t *joints;   /* n_vertices*4: indices into names, -1 for an unused slot */
  double *weights;   /* n_vertices*4: summing to 1, or all 0 for a vertex bound to no joint */
} km_mesh_skin;
/* Frees the arrays of s and zeroes it. */
void km_mesh_skin_free(km_mesh_skin *s);
/* km_mesh_read, with the file's skin. A glTF node with a `skin` whose primitives have
 * JOINTS_0 / WEIGHTS_0 is placed by linear blend skinning with the scene's joint transforms
 * (joint node's world matrix times its inverse bind matrix; the mesh node's own transform is
 * ignored, as glTF says), i.e. as a viewer shows it: at the bind pose, as stored. The joints
 * of every skin used are gathered into one list (each joint node once, in order of first
 * use); with JOINTS_1 / WEIGHTS_1 (8 influences) the position is placed by all 8 and the skin
 * keeps the 4 largest, renormalised; a primitive without JOINTS_0 is bound whole to the
 * nearest joint above its node (else to none). Other formats: the mesh, skin->n_joints 0.
 *   path  in: file
 *   mesh  out: as km_mesh_read; free with km_mesh_free
 *   skin  out: the skin (zeroed when the file has none); free with km_mesh_skin_free
 * Errors: as km_mesh_read, and KM_ERR_PARSE for a skin whose accessors do not fit. */
km_status km_mesh_read_skinned(const char *path, km_mesh *mesh, km_mesh_skin *skin, km_error *err);
/* km_mesh_read_skinned from memory (format from name's extension; buffers embedded only). */
km_status km_mesh_parse_skinned(const void *data, size_t size, const char *name, km_mesh *mesh,
                                km_mesh_skin *skin, km_error *err);
/* Writes a mesh atomically (temporary file, then rename), creating missing parent folders.
 * Coordinates are written exactly (%.17g in text formats, raw doubles in binary PLY), so
 * reading back is bit for bit. UV and N, when present, are written too (OBJ vt/vn with
 * v/t/n face references, one per vertex; PLY u v, nx ny nz); OFF has no place for them.
 * STL (binary): the faces' corners as float32 with unit facet normals, and nothing else (no
 * vertex list, so reading back welds the corners in facet order; a warning when UVs, normals
 * or materials are dropped); a mesh without faces is KM_ERR_UNSUPPORTED.
 *   path  in: file; its extension gives the format unless opt says otherwise
 *   m     in: mesh
 *   opt   in: may be NULL (format from extension, binary little-endian PLY)
 * Errors: KM_ERR_IO; KM_ERR_UNSUPPORTED for glTF (read only) and an STL of a mesh without
 * faces. */
km_status km_mesh_write(const char *path, const km_mesh *m, const km_mesh_write_options *opt,
                        km_error *err);

/* ---- orientation and units (issue 11) ----------------------------------------------------
 * Inside kinemesh a character stands along +y, faces +z and is measured in metres. A file
 * made another way (a z-up scan, a model facing -z, centimetres) is brought into that frame
 * by a rotation that takes its up axis to +y and its forward axis to +z, and a scale. */

typedef enum km_axis {
  KM_AXIS_NONE = 0, /* not given */
  KM_AXIS_POS_X,
  KM_AXIS_NEG_X,
  KM_AXIS_POS_Y,
  KM_AXIS_NEG_Y,
  KM_AXIS_POS_Z,
  KM_AXIS_NEG_Z,
} km_axis;

/* How a file's coordinates relate to kinemesh's frame. Zero: y up, facing +z, metres. */
typedef struct km_frame {
  km_axis up;      /* the file's axis that points up (NONE: +y) */
  km_axis forward; /* the file's axis the model faces (NONE: +z) */
  double scale;    /* file units to metres (0: 1) */
} km_frame;

/* "+x", "-x", "x", "X", "+Y", ... into an axis. Errors: KM_ERR_INVALID quoting s. */
km_status km_axis_parse(const char *s, km_axis *out, km_error *err);
/* "+x" ... "-z"; "none" for KM_AXIS_NONE. Static storage. */
const char *km_axis_name(km_axis a);
/* Metres per unit of "m", "cm", "mm", "in", "ft" (0 for anything else). */
double km_units_scale(const char *units);
/* The rotation of a frame change, row-major: p_kinemesh = scale * R * p_file.
 *   f  in: frame (up and forward must be perpendicular)
 *   R  out: 9 doubles, a proper rotation (a signed permutation)
 * Errors: KM_ERR_INVALID when up and forward lie on the same axis. */
km_status km_frame_rotation(const km_frame *f, double R[9], km_error *err);
/* Applies a frame change in place: positions P (n_points*3) become scale*R*P (NaN stays NaN),
 * normals N (n_normals*3, may be NULL) become R*N (rotation only).
 * Errors: as km_frame_rotation; KM_ERR_INVALID for a non-positive or non-finite scale. */
km_status km_frame_apply(const km_frame *f, double *P, size_t n_points, double *N, size_t n_normals,
                         km_error *err);
/* Whether f is kinemesh's own frame (up +y, forward +z, scale 0 or 1; an axis left
 * KM_AXIS_NONE is its default, as km_frame_rotation reads it): applying or undoing it changes
 * nothing, so callers keep positions bit for bit. NULL: true. */
bool km_frame_is_identity(const km_frame *f);
/* The inverse of km_frame_apply: points and normals from kinemesh's frame back into the file's
 * (its axes; points divided by the scale), in place: what `animate --keep-frame` writes.
 *   P  in/out: #n_points*3; N in/out: #n_normals*3 (may be NULL when n_normals is 0)
 * Errors: as km_frame_apply. */
km_status km_frame_unapply(const km_frame *f, double *P, size_t n_points, double *N,
                           size_t n_normals, km_error *err);
/* km_frame_apply to a mesh's V and N (UV and faces are unchanged; a rotation keeps the
 * winding). */
km_status km_mesh_frame_apply(const km_frame *f, km_mesh *m, km_error *err);

typedef struct km_frame_guess {
  km_frame frame; /* the guessed up and forward (scale 0: units are not guessed) */
  double height;  /* extent along the guessed up axis, in file units */
  bool standing;  /* taller than long along forward (a standing figure) */
  bool sure_up;   /* up stood out: an open cut, the ground plane, or a support 1.5x the next best;
                   * never   for a body lower than long and as wide as long (lying or sprawled) */
  bool sure_forward;
  char why[112]; /* the evidence in one short line, for printing: which rule chose up and
                  * forward, e.g. "up: ground contact 1.35 vs 0.26; forward: mirror plane,
                  * head higher / tail thinner" */
} km_frame_guess;
/* Guesses how a mesh is oriented, among the 24 axis-aligned frames. Heuristic (documented in
 * src/mesh/orient.c), following the file through those 24 rotations: up is (0) away from an
 * open cut at one end (a boundary loop within the lowest 6% that spans the width both ways: a
 * bust, a head cut at the neck, an upper body; in one direction only, and the broadest
 * support of (2): not a crown a scanner missed), else (1) the axis of
 * a model standing on the ground plane (its minimum, or its maximum, within 6% of its extent
 * from 0, no other axis so, and the mesh not plainly standing elsewhere: on several separate
 * feet along its longest axis with twice the support), else (2) the direction whose lowest 4% of
 * surface (its support: feet, hooves, a flat base) spans the widest part of the cross-section
 * with the centre of mass inside it, against a head, nose or tail tip touching in one small
 * patch, never along the lateral axis (across the mirror plane, where the centroids of slabs
 * stay on the centre of mass) when that one is clear. Forward's axis is the one across the
 * body's mirror plane (the centroids of height slabs wander along it and not sideways), or,
 * when that is unclear and the figure is longer than tall, its length (a quadruped whose head
 * is turned). Its sign: for a standing figure (taller than long) the side each foot's toes
 * reach ahead of the shin right above it, else the side the head sits ahead of the chest,
 * else the side the upper half reaches farther from its centroid (a trunk, a snout); for an
 * animal the side of its highest part plus the end of its length that carries more surface (a
 * head and forelegs, not a thin tail). Good for humanoids and animals made axis-aligned
 * (tests/test_orientation_sweep.c: 552 of 576 frames right on ../shared/data); the CLI prints
 * it so a wrong guess is seen and overridden.
 *   m    in: triangle mesh (a point cloud uses vertex weights)
 *   out  out: the guess
 * Errors: KM_ERR_INVALID for an empty or flat (zero extent) mesh. */
km_status km_mesh_frame_guess(const km_mesh *m, km_frame_guess *out, km_error *err);
/* km_mesh_frame_guess's forward for a given up axis (the user said only --up): the lateral
 * axis and forward's sign are found with that up, not with the guessed one.
 *   m    in: triangle mesh
 *   up   in: the up axis; KM_AXIS_NONE: guessed (= km_mesh_frame_guess)
 *   out  out: the guess, out->frame.up = up
 * Errors: as km_mesh_frame_guess; KM_ERR_INVALID for an unknown axis value. */
km_status km_mesh_frame_guess_forward(const km_mesh *m, km_axis up, km_frame_guess *out,
                                      km_error *err);

/* ---- topology and extent */

/* Edges are undirected vertex pairs used by at least one face. A component is a set of
 * faces connected through shared vertices; vertices used by no face are counted as
 * isolated, not as components. A face is degenerate when two of its indices are equal or
 * its area is below 1e-14 * bbox_diagonal^2. */
/* Edges, boundaries, non-manifold edges and components leave out collapsed faces (a repeated
 * vertex index: no surface), which degenerate_faces counts. */
typedef struct km_mesh_info {
  size_t vertices, faces;
  size_t edges;
  size_t boundary_edges;       /* used by exactly one face */
  size_t nonmanifold_edges;    /* used by three or more faces */
  size_t nonmanifold_vertices; /* faces around the vertex form more than one fan */
  size_t components;           /* pieces of faces joined by shared vertices */
  size_t isolated_vertices;
  size_t degenerate_faces;      /* a repeated vertex index, or (nearly) zero area */
  int64_t euler_characteristic; /* V - E + F over non-isolated vertices and faces not collapsed */
  double bbox_min[3], bbox_max[3];
  size_t seam_vertices; /* vertices used by faces whose position is exactly another such
                           vertex's: a surface split where its texture coordinates or normals
                           jump (glTF exporters write every textured mesh so). Its pieces meet
                           there in space but share no vertex, so a rig or a deformation sees
                           separate parts: kinemesh does not weld them (vertex order and count
                           are the file's) */
  /* The pieces rig and the solvers see: components of the mesh joined at its seams (1: one
   * piece). loose_vertices: when every piece but the largest has at most a quarter of its
   * vertices, the file's vertices of those small pieces, which follow the largest, the body
   * (eyes, teeth); 0 otherwise (one piece, or bodies of comparable size, which rig refuses).
   * rigid_pieces: those small pieces that turn rigidly with the one body vertex nearest to them
   * (all but the ones that wrap the body, a belt or a coat, which bend with the body under
   * them: half their vertices within 0.05 of the body's diagonal from it and spanning more
   * than 0.1 of it). ground_pieces: those small pieces lying on the floor, taking y as up
   * (kinemesh's frame: call it on the mesh km_mesh_frame_apply turned): their top within 0.01
   * of the body's height above the body's lowest point, a ground plane or a plinth exported
   * with the character, which animate and live leave where they lie. */
  size_t pieces, loose_vertices, rigid_pieces, ground_pieces;
  /* Where the mesh is not a manifold, to find it in a modeller: the non-manifold edge with
   * the lowest (smaller id, larger id) pair, as its two vertex ids, and the non-manifold vertex
   * with the lowest id; -1 where there is none. */
  int32_t nonmanifold_edge[2];
  int32_t nonmanifold_vertex;
} km_mesh_info;
/* Topology and extent of a mesh.
 *   m    in: mesh (a point cloud is fine)
 *   out  out: counts and bounding box */
km_status km_mesh_info_compute(const km_mesh *m, km_mesh_info *out, km_error *err);

/* Boundary loops: the connected groups of boundary edges (edges used by exactly one face).
 *   m        in: mesh, #V vertices, #F faces
 *   loop     out: #V (the caller's): the loop through vertex v, 0 .. n_loops-1 in the order of
 *            each loop's lowest vertex id, -1 for a vertex on no boundary edge (a closed mesh:
 *            all -1). Two holes that touch at a vertex are one loop.
 *   n_loops  out: the number of loops */
km_status km_boundary_loops(const km_mesh *m, int32_t *loop, size_t *n_loops, km_error *err);

/* Mean and maximum point-to-point distance |A_i - B_i|.
 *   A, B       in: n*3 positions each
 *   mean, max  out: the statistics (0 for n == 0) */
void km_vertex_distance_stats(const double *A, const double *B, size_t n, double *mean,
                              double *max);

/* Returns the length of the bounding-box diagonal of V (#V*3), 0 for an empty set. */
double km_bbox_diagonal(const double *V, size_t n_vertices);

/* Deformation check: how far the frames of an animation of a mesh depart from its rest shape,
 * by the measures of `bench motion` (issue 12): edge length ratios l / l0, folded triangles,
 * one-frame vertex steps. A person sees a stretched limb, a fold or a spike; these are the
 * numbers that find the frame and the place. Create once per rest mesh, add every frame in
 * order, read the summary, free.
 *   A folded pair: two triangles across an edge whose normals are less than 60 degrees apart at
 *   rest and more than 120 degrees apart in the frame (a crease turned inside out). */
typedef struct km_deform_check km_deform_check;

/* One frame's measures (km_deform_check_add). A NaN position propagates into the ratios. */
typedef struct km_deform_frame {
  double stretch;              /* max over edges of |l / l0 - 1| (a squash counts as a stretch) */
  int32_t stretch_edge[2];     /* that edge's vertices */
  double ratio_min, ratio_max; /* shortest and longest l / l0 */
  int32_t long_edge[2];        /* the vertices of the longest one */
  size_t folded_pairs;         /* folded pairs in this frame */
  double step; /* largest vertex move from the previous frame (mesh units); 0 on the first */
  int32_t step_vertex; /* its vertex (-1 on the first frame) */
  double y_min;        /* lowest y of the frame */
  double forced; /* the longest l / l0 the frame's handle targets force (km_deform_check_set_forced;
                    km_stretch_bound), NaN when not given */
} km_deform_frame;

/* The measures over every frame added so far. */
typedef struct km_deform_summary {
  size_t frames;
  double diagonal;      /* of the rest mesh's bounding box (steps are read against it) */
  double stretch;       /* the largest frame stretch */
  size_t stretch_frame; /* its frame */
  int32_t stretch_edge[2];
  double ratio_min, ratio_max; /* over all frames (INFINITY and 0 before the first) */
  size_t ratio_max_frame;      /* the frame of the longest edge */
  int32_t long_edge[2];        /* its vertices */
  size_t long_frames;          /* frames with an edge longer than 1.5 times its rest length */
  size_t short_frames;         /* frames with an edge shorter than 0.5 times */
  size_t folded;               /* triangles folded in some frame (each counted once) */
  size_t most_folded_pairs;    /* the most folded pairs in one frame */
  size_t most_folded_frame;    /* that frame */
  double step;                 /* the largest one-frame vertex step (mesh units) */
  size_t step_frame;           /* the frame it ends in */
  int32_t step_vertex;         /* its vertex (-1 with fewer than two frames) */
  double forced;               /* the largest frame forced (0 when none was given) */
  size_t forced_frame;         /* its frame */
  int32_t forced_pair[2];      /* its two handle vertices (-1 when none) */
} km_deform_summary;

/* Precompute: the rest mesh's edges and lengths and the pairs of triangles that can fold.
 *   rest  in: triangle mesh, #V vertices, #F faces (read here only: the check keeps what it needs)
 *   out   out: the check (free with km_deform_check_free) */
km_status km_deform_check_create(const km_mesh *rest, km_deform_check **out, km_error *err);
/* Adds the next frame.
 *   V      in: #V*3 positions of the frame, in the rest mesh's units and vertex order
 *   frame  out (may be NULL): this frame's measures */
km_status km_deform_check_add(km_deform_check *c, const double *V, km_deform_frame *frame,
                              km_error *err);
/* What the last frame's handle targets force: km_stretch_bound_eval of the targets the frame was
 * solved for, so the summary and the report tell a stretch the rig asks for from one the
 * solver adds. Call after km_deform_check_add (no frame yet: nothing happens).
 *   forced  in: the bound, a ratio (NaN: not known)
 *   pair    in: its two vertex ids in the mesh (may be NULL) */
void km_deform_check_set_forced(km_deform_check *c, double forced, const int32_t pair[2]);
/* The summary of the frames added so far. */
void km_deform_check_summary(const km_deform_check *c, km_deform_summary *out);
/* Per triangle (#F), the first frame in which it was folded, -1 for never (owned by c). */
const int32_t *km_deform_check_first_fold(const km_deform_check *c);
/* The frames added so far, in order (owned by c; valid until the next add).
 *   frames  out: the measures of each frame; may be NULL
 * Returns their count. */
size_t km_deform_check_frames(const km_deform_check *c, const km_deform_frame **frames);
/* Writes the summary and every frame's measures as JSON, atomically (parent folders made):
 * {"format":"kinemesh-deform-report","version":1,"frames":N,"diagonal":..,"stretch_max":..,
 * "stretch_frame":..,"stretch_edge":[a,b],"edge_ratio_min":..,"edge_ratio_max":..,
 * "edge_ratio_max_frame":..,"long_edge":[a,b],"frames_edge_over_1_5x":..,
 * "frames_edge_under_0_5x":..,"folded_triangles":..,"most_folded_pairs":..,
 * "most_folded_frame":..,"step_max_pct":..,"step_frame":..,"step_vertex":..,
 * "per_frame":[{"stretch":..,"edge_ratio_min":..,"edge_ratio_max":..,"long_edge":[a,b],
 * "folded_pairs":..,"step_pct":..,"y_min":..}, ...]}; frames count from 0, steps are % of the
 * rest diagonal, a NaN is null. With km_deform_check_set_forced called on some frame, also
 * "forced_edge_ratio_max":..,"forced_frame":..,"forced_pair":[a,b] and each frame's
 * "forced_edge_ratio" (null where not given). Errors: KM_ERR_IO naming path. */
km_status km_deform_check_write_json(const km_deform_check *c, const char *path, km_error *err);
void km_deform_check_free(km_deform_check **c);

/* Stretch bound: the edge stretch that vertex sets held at given targets (a rig's handles)
 * force on the mesh, whatever the deformation does between them. For two held vertices a, b of
 * different sets, every path along edges between them is at least |x_a - x_b| long in the
 * frame and at most r times its rest length when no edge stretches more than r, so the longest
 * edge ratio l / l0 of any frame that puts them there is at least |x_a - x_b| / D(a, b), with
 * D the shortest rest path along edges (Dijkstra). Over sampled pairs this is a lower bound
 * on the deform check's longest edge when the handles are met exactly (hard handles); a soft
 * solver under it has moved its handles off their targets. issue 12: whether a rig's targets
 * let the mesh stay under 1.5x at all. */
typedef struct km_stretch_bound km_stretch_bound;
typedef struct km_stretch_bound_options {
  /* pairs joined by a rest path at most this long, a fraction of the rest bounding-box
   * diagonal (the bound holds for any pair; far ones are loose and cost time); 0: 0.1 */
  double radius;
  /* a set's boundary vertices (a face neighbour outside it) sampled, spread over its list;
   * 0: 48 */
  int samples;
  /* NULL: none. Else the pairs are read from this file when it holds them for this mesh, these
   * sets and these options (a 64-bit key over all three), else computed and written there
   * (atomically; a file that cannot be read or written is not an error: computed, and a
   * KM_LOG_WARN when it cannot be written). The Dijkstra runs are most of a warm `animate`'s
   * start-up (0.8 of 1.7 s at 100k vertices). */
  const char *cache_path;
} km_stretch_bound_options;
/* Precompute the pairs (one bounded Dijkstra per sampled vertex).
 *   rest      in: triangle mesh, #V vertices
 *   n_sets    in: number of vertex sets (handles)
 *   offsets   in: n_sets+1; set h holds vertices[offsets[h] .. offsets[h+1]-1]
 *   vertices  in: offsets[n_sets] vertex ids, each in at most one set (km_puppetry_handles'
 *             layout)
 *   opt       in: may be NULL (defaults)
 *   out       out: free with km_stretch_bound_free
 * Errors: KM_ERR_INVALID (a vertex out of range), KM_ERR_NOMEM. */
km_status km_stretch_bound_create(const km_mesh *rest, size_t n_sets, const int32_t *offsets,
                                  const int32_t *vertices, const km_stretch_bound_options *opt,
                                  km_stretch_bound **out, km_error *err);
/* The bound for one frame's targets.
 *   targets  in: offsets[n_sets]*3 positions of the sets' vertices, in the vertices' order
 *            (km_puppetry_vertex_targets); a NaN pair is skipped
 *   pair     out (may be NULL): the mesh ids of the two vertices that give it (-1 when no
 *            pair)
 * Returns the bound, a ratio (0 without pairs). */
double km_stretch_bound_eval(const km_stretch_bound *b, const double *targets, int32_t pair[2]);
/* The number of pairs. */
size_t km_stretch_bound_pairs(const km_stretch_bound *b);
void km_stretch_bound_free(km_stretch_bound **b);

/* k vertices spread over the mesh by farthest-point sampling (Euclidean, deterministic: the
 * first is the vertex farthest from the centroid, each next one the farthest from those
 * taken). For landmarks on a mesh without a rig: meshes of one connectivity share the ids.
 * Isolated vertices are never taken.
 *   m    in: mesh with at least k non-isolated vertices
 *   ids  out: k vertex ids */
km_status km_farthest_points(const km_mesh *m, size_t k, int32_t *ids, km_error *err);

/* Vertex-vertex adjacency in CSR form: neighbours of v are adj[offsets[v] .. offsets[v+1]),
 * sorted ascending.
 *   m        in: mesh, #V vertices
 *   offsets  out: allocated, #V+1 entries; free()
 *   adj      out: allocated, offsets[#V] entries; free() */
km_status km_adjacency_list(const km_mesh *m, int32_t **offsets, int32_t **adj, km_error *err);

/* ---- geometric operators */

/* Cotangent Laplacian: L_ij = (cot a_ij + cot b_ij)/2 for each edge, L_ii = -sum.
 * Cotangents are clamped to [-1e5, 1e5] (zero-angle / near-degenerate triangles) and a
 * face with zero area contributes nothing, so the matrix stays finite. Obtuse triangles
 * give negative weights, as the continuous operator does.
 *   m  in: triangle mesh
 *   L  out: allocated #V x #V; free with km_sparse_free */
km_status km_cotmatrix(const km_mesh *m, km_sparse **L, km_error *err);
/* Uniform (graph) Laplacian: L_ij = 1 for each edge, L_ii = -degree.
 *   m  in: triangle mesh
 *   L  out: allocated #V x #V; free with km_sparse_free */
km_status km_uniform_laplacian(const km_mesh *m, km_sparse **L, km_error *err);

typedef enum km_mass_type {
  KM_MASS_VORONOI =
      0, /* mixed Voronoi areas (Meyer et al. 2003): obtuse triangles split 1/2,1/4,1/4 */
  KM_MASS_BARYCENTRIC, /* a third of each incident triangle's area */
} km_mass_type;
/* Lumped (diagonal) mass matrix. Isolated vertices get a tiny positive mass so M stays
 * invertible.
 *   m  in: triangle mesh
 *   M  out: allocated #V x #V diagonal; free with km_sparse_free */
km_status km_massmatrix(const km_mesh *m, km_mass_type type, km_sparse **M, km_error *err);

typedef enum km_normal_weighting {
  KM_NORMALS_AREA = 0, /* face normals weighted by area */
  KM_NORMALS_ANGLE,    /* weighted by the incident angle (Thürmer & Wüthrich) */
} km_normal_weighting;
/* Unit per-vertex normals.
 *   m  in: triangle mesh
 *   N  out: #V*3; a vertex with no non-degenerate face gets (0,0,0) */
km_status km_vertex_normals(const km_mesh *m, km_normal_weighting w, double *N, km_error *err);

/* For every vertex, the neighbour whose edge defines its local frame's tangent. Chosen once
 * on a reference mesh (the lowest-index neighbour) and reused for every pose of the same
 * connectivity, so frames correspond across poses.
 *   m    in: reference triangle mesh
 *   ref  out: #V neighbour ids; isolated vertices get -1 */
km_status km_frame_neighbors(const km_mesh *m, int32_t *ref, km_error *err);
/* Local orthonormal frames, right-handed.
 *   m       in: triangle mesh (any pose of the reference connectivity)
 *   N       in: #V*3 unit normals (km_vertex_normals)
 *   ref     in: #V frame neighbours (km_frame_neighbors)
 *   frames  out: #V*9, per vertex the rows n (normal), t (edge to ref projected on the
 *           tangent plane, normalised), b = n x t */
km_status km_local_frames(const km_mesh *m, const double *N, const int32_t *ref, double *frames,
                          km_error *err);

/* ---- point clouds */

/* One point cloud frame. Points with a NaN/inf coordinate are dropped and counted, and so
 * are points at exactly (0, 0, 0): a depth sensor's "no return" pixels. */
typedef struct km_points {
  double *P; /* n*3 positions, metres */
  size_t n;
  size_t dropped_nan;  /* points skipped because a coordinate was not finite */
  size_t dropped_zero; /* points skipped because they were exactly (0, 0, 0) */
} km_points;
/* Frees p->P and zeroes the struct. */
void km_points_free(km_points *p);

/* Reads a point cloud: .ply (the mesh PLY reader, except that NaN/inf coordinates are
 * accepted, then dropped and counted; faces, if any, are ignored), .pcd
 * (PCD v0.7, DATA ascii or binary; fields x y z as F4/F8, other fields skipped),
 * .xyz/.txt/.pts (whitespace or comma separated, the first three numbers of each line;
 * '#' comments and blank lines skipped).
 *   path  in: file
 *   out   out: allocated points (#P*3); free with km_points_free
 * Errors: KM_ERR_IO, KM_ERR_PARSE naming the file and the line (text) or byte offset
 * (binary), KM_ERR_UNSUPPORTED (PCD binary_compressed). */
km_status km_points_read(const char *path, km_points *out, km_error *err);
/* km_points_read from memory.
 *   data, size  in: file contents
 *   name        in: its extension gives the format; used in error messages
 *   out         out: allocated points; free with km_points_free */
km_status km_points_parse(const void *data, size_t size, const char *name, km_points *out,
                          km_error *err);
/* Writes a binary little-endian PLY with float x y z and no faces, atomically.
 *   P  in: n*3 positions
 * Errors: KM_ERR_IO. */
km_status km_points_write_ply(const char *path, const double *P, size_t n, km_error *err);
/* Frame files in name order.
 *   pattern  in: a directory (its .ply/.pcd/.xyz/.txt/.pts files) or a glob(3) pattern
 *   paths    out: allocated array of *n strings; free with km_paths_free
 *   n        out: number of files
 * Errors: KM_ERR_IO naming the pattern when nothing matches. */
km_status km_point_frames_list(const char *pattern, char ***paths, size_t *n, km_error *err);
/* Frees the n strings of *paths and the array, and sets *paths to NULL. */
void km_paths_free(char ***paths, size_t n);

/* ---- nearest vertices (kinemesh pick; src/mesh/nearest.c) */

/* The k vertices nearest to a point (Euclidean), nearest first; ties by lower id.
 *   V         in: #V*3 positions
 *   n         in: #V
 *   p         in: 3 coordinates
 *   k         in: how many (more than #V: #V)
 *   ids       out: min(k, #V) vertex ids
 *   dist      out: their distances; may be NULL
 * Returns how many were written. */
size_t km_nearest_vertices(const double *V, size_t n, const double p[3], size_t k, int32_t *ids,
                           double *dist);

/* ==== motion: skeletons, takes, formats, filter, rig, retargeting, sidecar (src/motion/) ==== */

/* ---- skeletons */

#define KM_KINECT1_JOINTS 20
/* Kinect v1 joint order: HipCenter, Spine, ShoulderCenter, Head, ShoulderLeft, ElbowLeft,
 * WristLeft, HandLeft, ShoulderRight, ElbowRight, WristRight, HandRight, HipLeft, KneeLeft,
 * AnkleLeft, FootLeft, HipRight, KneeRight, AnkleRight, FootRight. */
/* Returns the name of Kinect v1 joint j (0 .. KM_KINECT1_JOINTS-1), a static string. */
const char *km_kinect1_joint_name(int j);
/* Returns the parent of Kinect v1 joint j (-1 for HipCenter). */
int km_kinect1_joint_parent(int j);
/* Returns the index of a Kinect v1 joint by name (case-sensitive), -1 when unknown. */
int km_kinect1_joint_index(const char *name);

/* ---- skeletons by name (issue 15; docs/skeletons.md has the table) */

/* The joint vocabularies kinemesh knows, by the names rigs use ("skeleton": "humanoid"):
 *   kinect1    Kinect v1 (20, KM_KINECT1 order)
 *   kinect2    Kinect v2 SDK JointType (25: SpineBase, SpineMid, Neck, Head, ..., ThumbRight)
 *   k4abt      Azure Kinect / Orbbec body tracking (32: PELVIS, SPINE_NAVEL, ..., EAR_RIGHT)
 *   humanoid   Unity HumanBodyBones, as VMC sends them (55, enum order: Hips, LeftUpperLeg,
 *              ..., RightLittleDistal, UpperChest); a bone's joint is its origin (LeftHand is
 *              the wrist)
 *   mediapipe  MediaPipe BlazePose landmarks (33: nose, left_eye_inner, ..., right_foot_index)
 *   bvh        the CMU database's BVH conversions (31: Hips, LHipJoint, LeftHip, ..., RThumb)
 * Every joint stands for a body point (pelvis, mid spine, neck base, left wrist, left hand
 * centre, ...) or for none (finger phalanges, CMU's LHipJoint, Unity's UpperChest); two joints
 * of different skeletons map to each other when they stand for the same point. */
typedef enum km_skeleton_kind {
  KM_SKELETON_KINECT1 = 0,
  KM_SKELETON_KINECT2,
  KM_SKELETON_K4ABT,
  KM_SKELETON_HUMANOID,
  KM_SKELETON_MEDIAPIPE,
  KM_SKELETON_BVH,
  KM_SKELETON_KINDS
} km_skeleton_kind;
#define KM_HUMANOID_BONES 55
/* The kind named name ("kinect1", "kinect2", "k4abt", "humanoid", "mediapipe", "bvh"), -1 when
 * unknown. */
int km_skeleton_kind_from_name(const char *name);
/* The name of kind k (static), NULL for an unknown kind. */
const char *km_skeleton_kind_name(km_skeleton_kind k);
/* Joints of kind k (0 for an unknown kind). */
int km_skeleton_joint_count(km_skeleton_kind k);
/* Name (static) and parent (-1 for a root; not always an earlier index: Unity's UpperChest is
 * bone 54) of joint j of kind k; NULL / -1 when out of range. */
const char *km_skeleton_joint_name(km_skeleton_kind k, int j);
int km_skeleton_joint_parent(km_skeleton_kind k, int j);
/* Index of a joint of kind k by exact (case-sensitive) name, -1 when unknown. */
int km_skeleton_joint_index(km_skeleton_kind k, const char *name);
/* The joint of kind `to` that stands for the same body point as joint j of kind `from`, -1
 * when `to` has none. */
int km_skeleton_joint_map(km_skeleton_kind from, int j, km_skeleton_kind to);
/* The joint of kind `from` that drives joint j of kind `to`: the same point, else the nearest
 * one a tracker of `from` gives (a hand centre takes the wrist, a foot the ankle, a neck base
 * the neck; *approx, may be NULL, says so). -1 when there is none. */
int km_skeleton_joint_source(km_skeleton_kind to, int j, km_skeleton_kind from, bool *approx);
/* The kind most of names[0..n) belong to (ties: the first kind in the enum order), -1 when
 * none matches; *matched (may be NULL): how many did. */
int km_skeleton_detect(const char *const *names, size_t n, int *matched);
/* The Kinect v1 joint (KM_KINECT1 index) a joint name stands for: looked up in kind `named`
 * first, then in every kind in enum order, then by the naming conventions of game and DCC rigs
 * (Mixamo "mixamorig:LeftForeArm", VRoid "J_Bip_L_LowerArm", rigify "DEF-forearm.L", Blender
 * "forearm.L", Biped "Bip01 L Forearm"; docs/skeletons.md). -2: a known joint with no Kinect v1
 * counterpart, -1: an unknown name. */
int km_skeleton_kinect1_joint(km_skeleton_kind named, const char *name);
/* One frame of kind `from` as kind `to`, by body point with km_skeleton_joint_source's
 * fallbacks, a fallback also taken where the exact joint is NaN in this frame; trunk points
 * the source lacks are made up: the pelvis between the hips, the neck base between the
 * shoulders, the mid spine between those two, the head at the nose (MediaPipe).
 *   in   in: km_skeleton_joint_count(from)*3 positions, NaN where missing
 *   out  out: km_skeleton_joint_count(to)*3, NaN where nothing drives a joint */
void km_skeleton_convert(km_skeleton_kind from, const double *in, km_skeleton_kind to, double *out);

/* ---- humanoid poses (VMC; issue 15) */

/* A Unity humanoid pose as the VMC protocol carries it (/VMC/Ext/Root/Pos, /VMC/Ext/Bone/Pos),
 * in kinemesh's frame (km_humanoid_unity_convert applied). Quaternions are (x, y, z, w). */
typedef struct km_humanoid_pose {
  double root[7];                     /* the avatar root: position (m) and rotation */
  double bone[7 * KM_HUMANOID_BONES]; /* per HumanBodyBones bone: local position relative to
                                         its parent bone (or the root) and local rotation */
  bool present[KM_HUMANOID_BONES];    /* bones set; an absent bone is skipped: its children
                                         hang from their nearest present ancestor */
} km_humanoid_pose;
/* Unity's left-handed frame (x right, y up, z forward, avatars facing +z) <-> kinemesh's
 * (right-handed, y up, performer facing +z, their left at +x), in place: UniVRM's flip
 * p -> (x, y, -z), q -> (-qx, -qy, qz, qw), then a half turn about y; together
 * p -> (-x, y, z), q -> (qx, -qy, -qz, qw). Its own inverse. p or q may be NULL. */
void km_humanoid_unity_convert(double p[3], double q[4]);
/* The nearest ancestor of bone b whose present[] is set (present NULL: the parent), -1 when
 * none (b hangs from the root). */
int km_humanoid_parent(const bool *present, int b);
/* Forward kinematics over the humanoid hierarchy (the one FK): world joint positions.
 *   pose       in: the pose
 *   positions  out: KM_HUMANOID_BONES*3, NaN for absent bones
 *   rotations  out: KM_HUMANOID_BONES*9 row-major world rotations (NaN absent); may be NULL
 * Does not allocate. */
void km_humanoid_fk(const km_humanoid_pose *pose, double *positions, double *rotations);
/* The inverse for senders: a pose whose FK gives these positions (exactly, up to rounding),
 * root at the origin, rotations those of km_skeleton_pose_from_positions from a T-pose rest
 * (swing only: no twist about the bones), so a receiver that applies the rotations to its own
 * avatar sees the motion.
 *   positions  in: KM_HUMANOID_BONES*3 world positions, NaN for bones not given
 *   out        out: the pose
 * Errors: KM_ERR_INVALID when no bone has a position. */
km_status km_humanoid_pose_from_positions(const double *positions, km_humanoid_pose *out,
                                          km_error *err);

typedef struct km_skeleton {
  size_t n_joints;
  char **names;     /* n_joints strings */
  int32_t *parents; /* -1 for a root; parents[j] < j */
  double *rest;     /* n_joints*3 rest positions */
} km_skeleton;
/* Frees the names, parents and rest arrays of s and zeroes the struct. */
void km_skeleton_free(km_skeleton *s);

/* Linear blend skinning weights (km_lbs). Each vertex has up to 4 influences. */
#define KM_SKIN_INFLUENCES 4
typedef struct km_skin {
  size_t n_vertices;
  int32_t *joints; /* n_vertices*4, -1 for an unused slot */
  double *weights; /* n_vertices*4, summing to 1; or a row with no influence (every slot -1,
                      weights 0): the vertex stays where it is at rest (km_lbs), as a ground
                      plane exported with a character does (km_autorig) */
} km_skin;
/* Frees the joints and weights arrays of s and zeroes the struct. */
void km_skin_free(km_skin *s);

/* ---- takes */

/* A motion take: joint positions per frame (the form trackers deliver). A joint missing in a
 * frame is NaN. */
typedef struct km_take {
  size_t n_frames, n_joints;
  double fps;
  char **joint_names; /* n_joints */
  int32_t *parents;   /* n_joints, -1 for roots; may be NULL when unknown */
  double *positions;  /* n_frames * n_joints * 3 */
} km_take;
/* Frees every array of t and zeroes the struct. */
void km_take_free(km_take *t);
/* kinemesh take JSON:
 * {"format":"kinemesh-take","version":1,"fps":30,"units":"m","joints":["HipCenter",...],
 *  "parents":[-1,0,...],"frames":[[x,y,z, x,y,z, ...], ...]}   (null = missing joint)
 * km_take_read:
 *   path  in: file
 *   out   out: allocated take; free with km_take_free
 *   Errors: KM_ERR_IO, KM_ERR_PARSE naming the file.
 * km_take_write (atomically):
 *   t     in: take (NaN joints are written as null)
 *   Errors: KM_ERR_IO. */
km_status km_take_read(const char *path, km_take *out, km_error *err);
km_status km_take_write(const char *path, const km_take *t, km_error *err);
/* ---- issue 12: resampling */
/* The take resampled to fps: round(#frames * fps / in->fps) frames (at least 1), frame k at
 * time k / fps, positions interpolated linearly between the neighbouring input frames (a
 * missing neighbour: the nearer one's value, NaN when that is missing); the duration
 * #frames / fps is kept. Names and parents are copied.
 *   in   in: take with fps > 0
 *   out  out: allocated take; free with km_take_free
 * Errors: KM_ERR_INVALID (no frames, rates not positive). */
km_status km_take_resample(const km_take *in, double fps, km_take *out, km_error *err);

/* ---- motion formats */

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
 *   path    in: file
 *   out     out: allocated take (#frames x 20 joints); free with km_take_free
 *   labels  out: may be NULL; else an allocated array of #frames action labels (0 when the
 *           file has no label field); free()
 * Errors: KM_ERR_IO, KM_ERR_PARSE naming the file and line. */
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
 * the nearest integer when within 0.01.
 *   path  in: file
 *   opt   in: may be NULL (automatic units, no end sites)
 *   out   out: allocated take (#frames x #J, names and parents); free with km_take_free
 *   info  out: may be NULL; the units and channels used
 * Errors: KM_ERR_IO, KM_ERR_PARSE naming the file and line. */
km_status km_bvh_read(const char *path, const km_bvh_options *opt, km_take *out, km_bvh_info *info,
                      km_error *err);

/* ---- motion reader (any format) */

typedef enum km_motion_format {
  KM_MOTION_AUTO = 0,   /* by extension: .json, .csv, .bvh; otherwise by content */
  KM_MOTION_TAKE_JSON,  /* kinemesh take (km_take_read) */
  KM_MOTION_KINECT_CSV, /* Kinect v1 skeleton recording (km_kinect_csv_read) */
  KM_MOTION_BVH         /* BVH (km_bvh_read) */
} km_motion_format;
typedef struct km_motion_read_options {
  km_motion_format format; /* 0: auto. Content sniffing: "HIERARCHY" is BVH, '{' a take, a
                              first line with ';' a Kinect CSV, anything else a take */
  bool kinect1;            /* the take's columns in KM_KINECT1 order by name: 20 joints with
                              Kinect names and parents, absent joints NaN, fps 30 when the file
                              has none. KM_ERR_INVALID when the file has no frames or none of
                              the 20 Kinect v1 joints */
  km_bvh_options bvh;      /* for BVH files */
} km_motion_read_options;
typedef struct km_motion_read_info {
  km_motion_format format; /* the format read */
  size_t kinect1_found;    /* kinect1: how many of the 20 Kinect v1 joints the file has */
} km_motion_read_info;
/* Reads a motion file of any supported format into out (free with km_take_free).
 * path: the file; opt, info: may be NULL. On failure *out is empty and the error message
 * names the file. */
km_status km_motion_read(const char *path, const km_motion_read_options *opt, km_take *out,
                         km_motion_read_info *info, km_error *err);

/* ---- filter */

/* ---- issue 12: filter kinds */
typedef enum km_filter_kind {
  KM_FILTER_HOLT = 0, /* Holt double exponential smoothing with the Kinect SDK knobs */
  KM_FILTER_ONE_EURO  /* One Euro filter (Casiez, Roussel & Vogel, CHI 2012) */
} km_filter_kind;

/* Holt double exponential smoothing of joint positions (Wu, Lu & Song 2012, eq. 4) with the
 * extra knobs of the Kinect SDK (NUI_TRANSFORM_SMOOTH_PARAMETERS). Per joint, with raw
 * sample x:
 *   x' = x, or lerp(prev_level, x, d/jitter_radius) when d = |x - prev_level| <= jitter_radius
 *   level = (1 - smoothing) x' + smoothing (prev_level + prev_trend), then clamped per
 *           coordinate between prev_level and x' (the trend may not carry the level past the
 *           input after a fast move stops: the overshoot fix of issue 12)
 *   trend = trend_gain (level - prev_level) + (1 - trend_gain) prev_trend
 *   out   = level + prediction * trend', pulled back to within max_deviation of x, where
 *           trend' is the trend clamped per coordinate to the raw step x - prev_x (sign and
 *           size), so a stopped joint is not predicted onward.
 * One Euro (kind KM_FILTER_ONE_EURO), per joint with Te = 1/fps (times the frames since the
 * last good sample): speed = lowpass(|x - prev_x| / Te, d_cutoff); cutoff = min_cutoff + beta
 * speed; out = lowpass(x, cutoff), lowpass(x, fc) = prev + a (x - prev), a = 1/(1 + 1/(2 pi fc
 * Te)). The Holt fields are ignored for it and vice versa.
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
  /* ---- issue 12: One Euro filter, overshoot clamp */
  km_filter_kind kind;  /* 0: Holt (above); KM_FILTER_ONE_EURO: Casiez et al. 2012 */
  double fps;           /* frames per second of the pushed frames (One Euro). 0: 30 */
  double min_cutoff;    /* One Euro minimum cutoff, Hz. 0: 1.5 */
  double beta;          /* One Euro speed coefficient, Hz per m/s. 0: 1.0 */
  double d_cutoff;      /* One Euro cutoff of the speed estimate, Hz. 0: 1.0 */
  double catchup_speed; /* m/s. A joint back after missing frames does not snap from where
                           it was held to where it is now: the output eases over (the gap
                           halves per frame, at most catchup_speed / fps of it per frame). Per
                           joint, so a bone may stretch meanwhile: km_glitch's catch-up (on by
                           default) does it bone by bone. 0: off (snap) */
} km_filter_options;
#define KM_FILTER_ZERO (-1.0)

typedef struct km_filter km_filter;
/* Creates a filter for #J = n_joints joints.
 *   opt  in: may be NULL (defaults)
 *   out  out: allocated filter; free with km_filter_free */
km_status km_filter_create(size_t n_joints, const km_filter_options *opt, km_filter **out,
                           km_error *err);
/* Filters one frame. A NaN raw joint (missing) does not touch the joint's state and outputs
 * its last output (held); before the joint's first good sample it outputs NaN. When it comes
 * back, the output eases from the held position (catchup_speed).
 *   raw       in: #J*3 joint positions
 *   filtered  out: #J*3; may alias raw */
void km_filter_push(km_filter *f, const double *raw, double *filtered);
/* Forgets all history (as if just created). */
void km_filter_reset(km_filter *f);
/* Forgets joint j's history only: its next sample is taken as it comes (a joint whose earlier
 * samples were found wrong, km_glitch_restarted). j >= #J: nothing. */
void km_filter_restart_joint(km_filter *f, size_t j);
/* Frees *f and sets it to NULL. */
void km_filter_free(km_filter **f);

/* ---- issue 12: glitch rejection (before the filter) */

/* Tracker glitches are rejected, so the filter after it does not chase them: a rejected joint
 * is output carried by its parent (parent's output + the offset at the joint's last accepted
 * sample) when catch-up is on (the default) and it has one, else missing (NaN; the filter
 * holds it). Per joint and frame, in this order:
 *   refound: a joint that comes back after missing frames stays missing for refound_frames
 *            more frames (trackers re-acquire a lost joint at a wrong place first);
 *   speed:   the sample is farther than max_speed / fps * k from the joint's last accepted
 *            sample, k = frames since it (so a joint that really moved is re-acquired after a
 *            few frames: the allowance grows while it is rejected);
 *   bone:    the bone from its parent (accepted this frame) departs from the running median
 *            of the bone's accepted lengths (last 31) by more than bone_tolerance * median +
 *            bone_slack (once 5 lengths were seen).
 * An accepted sample after a gap eases in (catchup_speed): the output is then the sample plus
 * a shrinking offset, not the raw sample.
 * A joint's first sample has nothing to be judged by and is accepted. When it was the glitch
 * (a hand 0.6 m off in frame 0), the true samples after it are rejected. Within start_seconds
 * of a joint's first sample, a joint back after a rejection more than 10 cm + half its bone
 * (relative to its parent; else 10 cm + a frame's max_speed move) from where it is held is
 * restarted when it is accepted after a start of at most 0.1 s of samples (3 at 30 fps), or
 * when its rejected samples have come there steadily (each within a frame's move of the one
 * before) for at least 2 frames and as many as its start had (a longer glitched start fills
 * the bone test's lengths): taken as it comes (no catch-up), its start and bone lengths
 * forgotten, and listed by km_glitch_restarted for the user to redo what it built on the start
 * (km_puppetry re-anchors the joint's reference). A longer start accepted again far away
 * eases in as any re-found joint. */
typedef struct km_glitch_options {
  double fps;            /* frames per second of the pushed frames. 0: 30 */
  double max_speed;      /* m/s. 0: 12 (a fast punch or kick peaks near 10 m/s; a 0.6 m
                            one-frame jump at 30 fps is 18 m/s); < 0: off */
  double bone_tolerance; /* relative. 0: 0.4; < 0: no bone test */
  double bone_slack;     /* metres added to the bone tolerance (short, noisy bones). 0: 0.04 */
  int refound_frames;    /* 0: 1; < 0: none */
  double catchup_speed;  /* m/s. A joint accepted again after rejected or missing frames is
                            output with an offset that starts where it was held (relative to
                            its parent when both are accepted: a bone keeps its length) and
                            shrinks, halving per frame while small, at most catchup_speed / fps
                            per frame; children are carried by their parent's offset. The mesh
                            eases back in instead of snapping. 0: 3; < 0: off */
  double start_seconds;  /* the start window for restarts (above), seconds. 0: 1; < 0: none */
} km_glitch_options;
typedef struct km_glitch_stats {
  size_t frames;               /* frames pushed */
  size_t samples;              /* joint samples that were present (not NaN) */
  size_t missing;              /* joint samples that were NaN already */
  size_t rejected;             /* present samples turned missing (the sum of the three reasons) */
  size_t refound, speed, bone; /* rejections by reason */
  size_t restarted;            /* joints restarted (their start was a glitch, see above) */
} km_glitch_stats;
typedef struct km_glitch km_glitch;
/* Creates a glitch rejector for #J = n_joints joints.
 *   parents  in: #J parent indices (-1 roots, parents[j] < j) for the bone test; may be NULL
 *            (no bone test)
 *   opt      in: may be NULL (defaults)
 *   out      out: allocated; free with km_glitch_free
 * Errors: KM_ERR_INVALID for bad options or parents. */
km_status km_glitch_create(size_t n_joints, const int32_t *parents, const km_glitch_options *opt,
                           km_glitch **out, km_error *err);
/* One frame: raw #J*3 in, clean #J*3 out (rejected joints carried or NaN, see above); clean
 * may alias raw. Frames are taken as 1/fps apart. */
void km_glitch_push(km_glitch *g, const double *raw, double *clean);
/* Same for a frame received at time t (seconds, any origin; NaN: untimed): the speed test
 * allows for the time since a joint's last accepted sample when that is longer than its
 * frame count says (frames dropped or a silent tracker). */
void km_glitch_push_at(km_glitch *g, const double *raw, double t, double *clean);
/* Counts since create / reset. */
void km_glitch_stats_get(const km_glitch *g, km_glitch_stats *out);
/* The joints the last push restarted (#J flags; see above), or NULL when it restarted none.
 * Valid until the next push, reset or free. */
const bool *km_glitch_restarted(const km_glitch *g);
/* Forgets history and counts. */
void km_glitch_reset(km_glitch *g);
/* Frees *g and sets it to NULL. */
void km_glitch_free(km_glitch **g);

/* ---- rig */

/* Puppetry rig (JSON):
 * { "skeleton": "kinect1" | "bvh",                       (default kinect1)
 *   "handles": [ {"name": "head", "vertex": 1234, "radius": 0.05},  geodesic ball
 *                {"name": "tail", "vertices": [10, 11, 12]},        explicit list
 *                {"name": "base", "center": [0, 0, 0], "radius": 0.1} ],  Euclidean ball
 *   "relative_to": "HipCenter",                          (optional, every map entry)
 *   "map": [ {"handle": "head", "joint": "Head", "axes": "xyz", "scale": 1.0,
 *             "relative_to": "HipCenter"} ],              (optional, overrides the rig's;
 *                                                          "" = absolute)
 *   "filter": {"smoothing": 0.5, "trend": 0.5, "prediction": 0, "jitter_radius": 0,
 *              "max_deviation": 0,
 *              "kind": "holt" | "one_euro", "min_cutoff": 1.5, "beta": 1.0, "d_cutoff": 1.0} }
 * "floor": true keeps every vertex above the rest floor (km_retarget_options.floor).
 * "max_step": 0.02 eases a faster handle step (a tracker's pose snap) over the next frames: no
 * handle vertex moves more than that fraction of the mesh diagonal per frame, the rigid root's
 * translation and heading included under "root_motion": "rigid"
 * (km_retarget_options.max_step; a speed limit, off by default).
 * "rotate": true (rig level: every entry; or per map entry) makes the handle turn with the bone
 * that ends at the entry's joint: the handle's vertices get rest + displacement rotated about
 * the handle's centroid (the first rotating entry of a handle gives its rotation).
 * "root_motion": "rigid" (needs the rig-level "relative_to": the root) moves the whole mesh
 * rigidly with the root: its translation and its heading (rotation about y of the line from
 * the "heading" joints' left to right one, kinect1 default ["HipLeft", "HipRight"]), while the
 * handles take the motion relative to the root, expressed in the root's heading frame. With
 * "joints" on a kinect1 skeleton the translation's scale is the character's leg length (hip ->
 * knee -> ankle) over the performer's in the first frame (within 0.3 .. 1.5 of the stature
 * scale), else the stature scale.
 * "root_motion": "none" (default) leaves the mesh where the handles put it.
 * A map entry {"handle": "forearm_left", "bone": ["ElbowLeft", "WristLeft"]} (instead of
 * "joint") is a bone handle: the handle moves rigidly with that bone segment (see
 * km_retarget_create), so handles on the upper and lower arm make the elbow bend. "joints":
 * [{"name": "ElbowLeft", "rest": [x, y, z]}, ...] (a rig sidecar's skeleton, in kinemesh's
 * frame: the mesh as animated) gives the character's joints: bone handles then turn about the
 * character's own joints, chained from the root (forward kinematics), so the limbs keep their
 * lengths. "relative_to" names a joint whose displacement is subtracted from the mapped joint's
 * (root-relative motion: the same as a second entry with scale -1 on that joint).
 * Other keys are ignored. "vertex"+"radius" takes every vertex whose shortest path along mesh
 * edges from the seed is <= radius (Dijkstra, so it stays on the seed's connected region and
 * does not jump to a nearby other limb; radius 0 or absent: the seed alone; a mesh without
 * faces falls back to Euclidean distance). "axes" is a non-empty subset of "xyz"; "scale"
 * defaults to 1. In "filter", an explicit 0 for smoothing or trend means zero. Several map
 * entries may drive one handle (their displacements add up: a row of Wu, Lu & Song's eq. 7
 * M with several ones) and one joint may drive several handles. Errors name the rig file and
 * the handle or joint: unknown joint (kinect1: the 20 Kinect v1 names; bvh: the joint_names
 * given), unknown or duplicate handle, empty handle, a vertex in two handles, vertex id out
 * of range, bad axes. */
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
  /* ---- issue 12: root-relative motion */
  int32_t relative_to; /* 0: the joint's own motion; else 1 + the index of a joint whose
                          motion is subtracted ("relative_to": "HipCenter"), so a walk's root
                          translation does not stretch the mesh */
  /* ---- issue 12: handles that carry rotation */
  bool rotate; /* "rotate": true: the handle also turns with the bone that ends at this joint
                  (parent -> joint direction, relative to the reference frame; the shortest
                  rotation), and about it with the joint's child (the twist carrying the
                  reference joint -> child direction onto the current one; several children:
                  the pair most across the bone; none from a leaf nor a child under 0.15 m; a take's
                  own joint rotations instead where it gives them). false (default): translation
                  only, as in the paper */
  /* ---- issue 12: bone handles */
  int32_t bone_from; /* 0: the entry maps a joint. Else a bone entry ("bone": ["ElbowLeft",
                        "WristLeft"]): 1 + the bone's start joint, `joint` its end. The handle
                        moves rigidly with the bone (see km_retarget_create); axes and scale
                        do not apply */
} km_rig_map;

typedef struct km_rig {
  km_rig_skeleton skeleton;
  km_rig_handle *handles;
  size_t n_handles;
  km_rig_map *maps;
  size_t n_maps;
  km_filter_options filter;
  bool floor;      /* ---- issue 12: "floor": true, see km_retarget_options.floor */
  double max_step; /* "max_step": 0.03, see km_retarget_options.max_step; 0: off */
  /* ---- issue 12: rigid root motion ("root_motion": "rigid") */
  bool root_rigid;    /* the whole mesh follows the root rigidly, handles take the motion
                         relative to it (see km_retarget_root_transform) */
  int32_t root;       /* 1 + the root joint (the rig-level "relative_to"); 0: none */
  int32_t heading[2]; /* 1 + the left and right joints whose line gives the heading ("heading":
                         [left, right]; kinect1 default HipLeft, HipRight); 0: no heading */
  /* ---- issue 12: the character's own skeleton, for bone handles */
  double *joint_rest; /* n_joint_rest*3 rest positions of the character's joints in the take's
                         joint order (kinect1: KM_KINECT1 order) from the rig's "joints" array
                         (a rig sidecar's), NaN for a joint it lacks; NULL: no "joints" */
  size_t n_joint_rest;
  bool local_turn; /* "local_turn": true (needs joint_rest): a bone entry's handle turns as
                      the performer's bone turns about itself, re-expressed about the
                      character's bone (the rotation conjugated by the shortest turn from the
                      performer's first direction of the bone onto the character's rest one),
                      about the bone's start at rest; a body lying down nods and tilts its head
                      as it lies instead of turning it as an upright head turns (kinemesh rig
                      writes it for --skeleton resting) */
  bool aim; /* "aim": true (needs joint_rest, kinect1): the limb bones (upper and lower arms and
               legs, hands, feet) are aimed along the performer's bones instead of turned by
               their rotation since the first frame, so a character whose rest pose is not the
               performer's first pose (a T-pose against arms down) takes the performer's pose */
  double swing_limit;      /* "swing_limit": degrees, with aim: a limb bone swings at most this far
                              from where its parent bone carries its rest direction, and a torso,
                              neck or head bone (turned by its rotation since the first frame) at
                              most this far from where its parent carries its first direction (0: no
                              limit). kinemesh rig writes 30 for a body that is not upright (a
                              quadruped's legs do not reach where a person's arms do) and 12
                              for an upright one with stubby limbs (the median limb bone's
                              radius half its length or more: the elephant's) */
  double upper_limb_limit; /* "upper_limb_limit": degrees, with aim on a kinect1 skeleton: an
                              upper arm or thigh (the bone ending at an elbow or knee) swings at
                              most this far from where its parent carries its rest direction
                              (0: swing_limit). kinemesh rig writes 5 for a body that is not
                              upright (a quadruped's humerus and femur lie inside its trunk)
                              and 15 for an upright one with stubby limbs */
  double girdle_limit;     /* "girdle_limit": degrees, on a kinect1 skeleton: a shoulder or hip bone
                              (ShoulderCenter -> Shoulder*, HipCenter -> Hip*), which carries the
                              arm or leg, turns at most this far from where its parent carries its
                              first direction (0: swing_limit). kinemesh rig writes 5 for every
                              body: a performer's shrug or torso lean otherwise swung a whole
                              foreleg about the trunk's middle, stretching the skin between chest
                              and leg, and a Kinect's shoulder joints riding up with a raised arm
                              pulled a person's shoulder skin into a tent */
  double bend_limit; /* "bend_limit": degrees, with aim on a kinect1 skeleton: an elbow or knee
                        (the forearm or shin against the upper arm or thigh) bends at most this
                        far (0: no limit). kinemesh rig writes 150 for an upright body, about
                        the human limit (a tracker's elbow folded further is its arm lost in
                        front of the body), and 20 for one that is not (a quadruped's foreleg
                        below its trunk; with upper_limb_limit 5 a paw reaches 25 degrees plus
                        its own bone's swing) */
  double max_turn;   /* "max_turn": degrees per second, under rigid root motion: the fastest the
                        whole mesh turns about the vertical (its heading) while following the
                        performer's (0: 600, a dancer's fast spin). kinemesh rig writes 360 for a
                        body that is not upright: an animal turns its long body about one turn a
                        second at most (a reining horse's spin), and one turned at a performer's
                        spin swept its head round at the far end of its length */
} km_rig;

/* Parses a rig file and resolves its handles on a mesh.
 *   path         in: rig JSON (a character rig sidecar is accepted as is)
 *   mesh         in: the mesh the handles refer to, #V vertices
 *   joint_names  in: n_joint_names names of the take's joints, needed for "bvh" rigs
 *                (ignored, may be NULL, for kinect1, whose names are fixed)
 *   out          out: allocated rig; free with km_rig_free
 * Errors: KM_ERR_IO, KM_ERR_PARSE and KM_ERR_INVALID naming the file and handle or joint. */
km_status km_rig_read(const char *path, const km_mesh *mesh, const char *const *joint_names,
                      size_t n_joint_names, km_rig *out, km_error *err);
/* km_rig_read from memory.
 *   json, size  in: the rig text
 *   name        in: used in error messages */
km_status km_rig_parse(const char *json, size_t size, const char *name, const km_mesh *mesh,
                       const char *const *joint_names, size_t n_joint_names, km_rig *out,
                       km_error *err);
/* Frees the handles and maps of rig and zeroes the struct. */
void km_rig_free(km_rig *rig);
/* The handle with a vertex nearest to x at rest: where on a character a place is, in the rig's
 * words ("near hand_left").
 *   rig   in: rig resolved on mesh
 *   mesh  in: its rest mesh (#V*3 positions)
 *   x     in: 3 coordinates in the mesh's units
 * Returns the handle's index, -1 when the rig has no handle vertex. */
int32_t km_rig_nearest_handle(const km_rig *rig, const km_mesh *mesh, const double x[3]);

/* ---- retargeting */

/* Retargeting (Wu, Lu & Song 2012, eq. 5-7). Per frame, handle h's target is
 *   target_h = rest_centroid_h + s * sum_{maps e on h} scale_e * mask_e (p_j(e) - p_j(e)^0)
 * (with relative_to r: (p_j - p_r) - (p_j^0 - p_r^0))
 * where p^0 is the joint's first valid (non-NaN) position. That is eq. 7 accumulated over
 * frames: H^t = M S^t with S^t the eq. 6 increments, and sum_t d^t telescopes to p^t - p^0; M
 * is stored sparsely as the map list (M_ij = scale_e, with the axis mask per entry). s maps
 * performer size to character size: by default the mesh's bounding-box height (y; its largest
 * extent if the mesh is flat in y) over the first valid frame's performer stature (kinect1:
 * the Head-to-lower-foot joint span / KM_KINECT1_SPAN_OF_STATURE, since the Head joint sits
 * at the head's centre and the foot joints above the soles; otherwise the y extent of the
 * valid joints), replacing eq. 5's screen-size ratio. Handles no map drives are anchors
 * (target = rest centroid). If a joint a handle needs is NaN, the handle keeps its last
 * target.
 * Bone handles (issue 12, map entries with bone_from): per frame every bone q -> j of the
 * take's tree gets R_j, the shortest rotation taking its first-valid-frame direction to the
 * current one (a bone shorter than 0.15 m of performer, Kinect's wrist -> hand and ankle ->
 * foot, turns with its parent bone instead: their direction is noise). With the rig's
 * joint_rest C^0 the character's joints are posed by forward kinematics,
 *   C_root = C^0_root + s (p_root - p^0_root)  (0 under rigid root motion),
 *   C_j = C_q + R_j (C^0_j - C^0_q),
 * and a bone entry a -> b moves its handle's vertices x to C_a - s d_rel + R_b (x - C^0_a)
 * (d_rel: the displacement of the entry's relative_to joint, 0 if none), so neighbouring bone
 * handles agree at the joint between them whatever the performer's bone lengths; an entry over
 * several bones (a -> ... -> m -> b) turns about m instead, with slerp(R_m, R_b, 1/2). With the
 * rig's "aim" a kinect1 limb bone gets R_j = (R_q (C^0_j - C^0_q) -> current direction) R_q
 * instead (R_q: its parent bone's rotation; the shortest swing, no twist against the parent):
 * the character's limb points where the performer's does. Without
 * joint_rest the handle turns about its centroid and moves with the bone's midpoint. */
/* Kinect v1 Head-to-foot joint span as a fraction of stature (anthropometric head-centre and
 * foot-joint heights: 0.937 and 0.023 of stature on kinemesh's procedural character). */
#define KM_KINECT1_SPAN_OF_STATURE 0.91
typedef struct km_retarget_options {
  double scale; /* performer-to-character factor s; 0: automatic (above) */
  /* ---- issue 12: floor constraint */
  bool floor; /* no vertex goes below the rest mesh's lowest y (the rest floor): a handle's y
                 displacement is clamped from below, and km_puppetry then raises any other
                 vertex still under it onto it. Also on when rig->floor */
  /* ---- issue 12: rotating handles */
  const int32_t *parents; /* #J joint parents (read at create only) for map entries with
                             rotate; NULL: the Kinect v1 tree for kinect1 rigs, else such
                             entries translate only */
  /* ---- issue 12: snap easing */
  double max_step; /* fraction of the rest mesh's bounding-box diagonal a handle vertex may
                      move per push; a faster step (a pose snap of the tracker) is eased over
                      the next pushes, every handle and the rigid root by the same fraction
                      (displacements linearly, rotations by slerp, the root's heading by its
                      angle). 0: rig->max_step (0: off) */
  double fps;      /* pushes per second, for the rigid root's heading filter (at most 600 deg/s
                      shown, 300 deg/s onto a re-fit; a measured change faster than 900 deg/s,
                      or a 180 deg left/right swap, is held) and the bone speed limit. 0: 30 */
  /* ---- issue 12: bone speed limit (bone handles) */
  double bone_catchup; /* m/s of performer. Per push a bone's direction turns at most as far
                          as a bone of the performer's usual length (running mean, 0.8 of it
                          turning freely) must turn for its end to move what the performer's
                          bone end moved relative to its start, and at most 1200 deg/s (less
                          for a bone measuring under 0.8 of its usual length): a Kinect
                          forearm collapsing to a few centimetres swung 50-130 degrees in a
                          frame and the character's hand 3x farther than the wrist moved. A
                          turn held back follows, its end at most bone_catchup faster than
                          the performer's. 0: 1 m/s; < 0: off (bones turn as measured) */
} km_retarget_options;

typedef struct km_retarget km_retarget;
/* Creates a retargeter.
 *   rig       in: rig resolved on `rest` (#H = rig->n_handles handles)
 *   rest      in: the mesh the rig was resolved on
 *   n_joints  in: #J joints per pushed frame (20 for kinect1)
 *   opt       in: may be NULL (automatic scale)
 *   out       out: allocated; free with km_retarget_free
 * Errors: KM_ERR_INVALID when a rig vertex or joint is out of range. */
km_status km_retarget_create(const km_rig *rig, const km_mesh *rest, size_t n_joints,
                             const km_retarget_options *opt, km_retarget **out, km_error *err);
/* One frame.
 *   joints          in: #J*3 (filtered) joint positions, NaN = not valid yet
 *   handle_targets  out: #H*3 handle centroid targets; may be NULL */
void km_retarget_push(km_retarget *r, const double *joints, double *handle_targets);
/* ---- issue 15: joint rotations from the tracker (VMC bones) */
/* km_retarget_push with each joint's rotation as the tracker sent it, so that rotating and
 * bone handles also turn about their bone (a forearm's twist), which positions cannot show.
 *   rotations  in: #J*9 row-major world rotations (kinemesh's frame) of the bone ending at
 *              each joint, NaN (any entry) = not given; NULL: as km_retarget_push
 * A handle turning with the bone ending at joint j (segment q -> j, walked up past bones
 * shorter than 0.15 m as for the swing) gets the twist of G = Q_j Q_j,ref^T about the
 * segment's reference direction (Q_j,ref: the first valid rotation of j since create / reset;
 * swing-twist decomposition), applied about its current direction after the swing the
 * positions give: R = Twist(d, phi) R_swing. Joints without a valid rotation turn as before. */
void km_retarget_push_rotations(km_retarget *r, const double *joints, const double *rotations,
                                double *handle_targets);
/* Per-vertex targets of the last push: for every handle in order, every vertex of it in
 * order, rest position + the handle's displacement (for a rotating handle: centroid +
 * displacement + R (rest position - centroid)).
 *   out  out: km_retarget_vertex_count(r)*3 */
void km_retarget_vertex_targets(const km_retarget *r, double *out);
/* Returns the number of handle vertices (all handles together). */
size_t km_retarget_vertex_count(const km_retarget *r);
/* Returns the rest centroids of the handles, #H*3, owned by r. */
const double *km_retarget_rest_centroids(const km_retarget *r);
/* Returns the performer-to-character factor in use; NaN while auto and no valid frame seen. */
double km_retarget_scale(const km_retarget *r);
/* Returns the number of pushes since create / reset whose motion max_step eased. */
size_t km_retarget_eased_frames(const km_retarget *r);
/* ---- issue 12: rigid root motion */
/* The rigid motion of the last push for a rig with root_rigid: the deformed mesh V is to be
 * placed at R (V - pivot) + pivot + t. R: 3x3 row-major rotation about y by the heading change
 * since the reference frame; t: the root scale (the legs' ratio, see "root_motion" in km_rig)
 * times (root - root reference), raised so that no ankle of the posed character skeleton (nor
 * a quadruped's wrist) is below its rest height; pivot: the character's root joint at rest (the
 * rig's "joints"; on a kinect1 skeleton its x and z half-way to ShoulderCenter's: a quadruped
 * turns about the middle of its trunk), else the rest mesh's bounding box centre. Identity (R = I,
 * t = 0) for other rigs or while the root is not valid. Returns whether the rig has rigid root
 * motion. */
bool km_retarget_root_transform(const km_retarget *r, double R[9], double t[3], double pivot[3]);
/* The floor constraint (km_retarget_options.floor or the rig's "floor"): returns whether it is
 * on, and then sets *floor_y to the rest floor, the rest mesh's lowest y. km_puppetry holds every
 * vertex of the solved mesh there (handles are raised by their own displacement first). */
bool km_retarget_floor(const km_retarget *r, double *floor_y);
/* Places points[n]*3 (in place) by the last push's rigid root motion, x -> R (x - pivot) + pivot
 * + t (see km_retarget_root_transform); leaves them as they are for a rig without rigid root
 * motion. Returns whether it moved them. */
bool km_retarget_apply_root(const km_retarget *r, double *points, size_t n);
/* The character's own joints as the last push posed them (the skeleton its bone handles hang
 * from, with the rigid root motion applied): what a skinned export of the same motion would
 * pose its skeleton to. A bone the rig's map does not move (no entry's joint nor above one; on
 * a map that holds the root still and has an anchor, as a bust's, every bone off the entries'
 * own segments) stays as its parent carries it, and on a map whose every entry is relative to
 * the root (no rigid root motion) the root's travel is taken off, as the handles take it off.
 *   out  out: n_joints*3 (the take's joint order), NaN for a joint the rig's "joints" lacks
 * Returns false, leaving out as it is, for a rig without a character skeleton ("joints"). */
bool km_retarget_joints(const km_retarget *r, double *out);
/* The reference positions (#J*3: each joint's first valid position, NaN until seen), which
 * the motion is measured from. Valid until the next call on r. */
const double *km_retarget_reference(const km_retarget *r);
/* Replaces joint j's reference with p[3] (a start found wrong: km_glitch_restarted), and redoes
 * what was built on it: the auto scale, the root's scale, the bone speed limit's memory. An
 * invalid j or a non-finite p: nothing. */
void km_retarget_set_reference(km_retarget *r, size_t j, const double p[3]);
/* Forgets reference positions (and the auto scale): the next valid frame is the new rest. */
void km_retarget_reset(km_retarget *r);
/* Frees *r and sets it to NULL. */
void km_retarget_free(km_retarget **r);

/* ---- character rig sidecar and landmarks */

/* A named mesh vertex with its left/right counterpart (pose recognition, pose transfer). */
typedef struct km_landmark {
  char name[32];
  char mirror[32]; /* name of the left/right counterpart (itself on the mid-line) */
  int32_t vertex;
} km_landmark;

/* A rigged character: what km_character_generate makes, a rig sidecar stores and the
 * reconstructor takes as its template. */
#define KM_CHARACTER_LANDMARKS 16
/* The 16 landmarks of a character, in their order (km_character.landmarks, the sidecar's
 * "landmarks"): head, neck, shoulder, elbow and hand left and right, chest, pelvis, hip, knee
 * and foot left and right. Returns the name of landmark i (0 .. KM_CHARACTER_LANDMARKS-1) and
 * sets *mirror (when not NULL) to its left/right counterpart's (its own on the mid-line);
 * static strings; NULL for an i out of range. */
const char *km_character_landmark_name(int i, const char **mirror);
typedef struct km_character {
  km_mesh mesh;         /* closed, manifold, one component */
  km_skeleton skeleton; /* the 20 Kinect v1 joints at rest */
  km_skin skin;         /* LBS weights over the skeleton's joints */
  km_landmark landmarks[KM_CHARACTER_LANDMARKS];
} km_character;
/* Frees mesh, skeleton and skin of c and zeroes the struct. */
void km_character_free(km_character *c);

/* Writes a rig sidecar (<mesh>.rig.json, atomically): skeleton, skin, landmarks, and a
 * default puppetry rig: handles at head, hands and feet, and (issue 12) bands of at most 64
 * vertices on each upper arm and thigh (0.5 .. 0.8 of the bone from the shoulder / hip: the
 * joint keeps a free zone to bend in) and around the middle of each forearm and shin (the
 * vertices whose nearest skeleton bone it is, one connected piece, clear of the end handles);
 * and a pelvis and a chest band on the spine bones (HipCenter -> Spine 0.2 .. 0.7, Spine ->
 * ShoulderCenter 0.2 .. 0.6) so the torso turns and bends with the skeleton;
 * every handle is mapped to a bone ("bone": head ShoulderCenter -> Head, hands elbow -> hand,
 * feet knee -> foot, bands their own bone), rings at the elbows and knees of an upright body
 * (the vertices within 0.08 of either bone's length and twice the limb radius of the joint, on
 * limbs whose bones are at least 3 radii long; mapped to shoulder -> wrist and hip -> ankle,
 * they turn with half the bend), with "aim": true, and the whole mesh follows the
 * root rigidly ("root_motion": "rigid", "relative_to": "HipCenter"; see km_rig_parse).
 *   c  in: character (its mesh is not written, only its vertex count)
 * Errors: KM_ERR_IO. */
km_status km_character_write_rig(const char *path, const km_character *c, km_error *err);
/* The sidecar km_character_write_rig writes, in memory (e.g. for km_rig_parse).
 *   json, size  out: malloc'd text (NUL-terminated) and its length; free with free()
 * Errors: KM_ERR_INVALID (as km_character_write_rig), KM_ERR_NOMEM. */
km_status km_character_rig_json(const km_character *c, char **json, size_t *size, km_error *err);
/* Reads the skeleton, skin and landmarks of a rig sidecar.
 *   n_vertices  in: #V of the mesh the sidecar belongs to (checked against the file)
 *   out         in/out: skeleton, skin and landmarks allocated/filled (mesh not touched);
 *               free with km_character_free
 * Errors: KM_ERR_IO, KM_ERR_PARSE naming the file; KM_ERR_STALE when the sidecar is for
 * another vertex count. */
km_status km_character_read_rig(const char *path, size_t n_vertices, km_character *out,
                                km_error *err);

/* ==== anim: animation writers and readers (src/anim/) ==== */

typedef enum km_anim_format {
  KM_ANIM_AUTO = 0, /* from the path: .glb, .pc2, else a directory */
  KM_ANIM_GLB,
  KM_ANIM_PC2,
  KM_ANIM_OBJ_DIR,
  KM_ANIM_PLY_DIR,
} km_anim_format;

/* What a .glb animation stores (issue 16). */
typedef enum km_anim_export {
  KM_ANIM_EXPORT_MORPHS = 0, /* one morph target per key frame: exact, large */
  KM_ANIM_EXPORT_SKIN,       /* a skinned mesh + one TRS channel per bone (km_ssdr_fit at
                                close): what engines play on the GPU, 20-60x smaller */
  KM_ANIM_EXPORT_MORPHS_PCA, /* `morphs` basis targets (PCA of the frame displacements) and
                                per-frame weights: compact, exact as morphs -> frames */
  KM_ANIM_EXPORT_SKELETON,   /* a skinned mesh over a given skeleton and weights
                                (km_anim_options.skeleton, .weights) whose bone transforms the
                                caller pushes with each frame (km_anim_writer_push_pose): no
                                fit, exact for frames skinned by those transforms (pose), one
                                joint node per skeleton joint, named after it and parented as
                                the skeleton's parents say, TRS channels local to the parent */
} km_anim_export;

typedef struct km_anim_options {
  km_anim_format format; /* 0: from the path (a directory gets per-frame .obj) */
  double fps;            /* 0: 30 */
  size_t key_every;      /* glb: one morph target every k frames (0/1: every frame) */
  /* ---- issue 16: what a .glb holds (other formats ignore these) */
  km_anim_export export_kind;         /* 0: KM_ANIM_EXPORT_MORPHS (one target per key frame) */
  const struct km_ssdr_options *skin; /* KM_ANIM_EXPORT_SKIN: the fit's options; NULL: defaults */
  size_t morphs; /* KM_ANIM_EXPORT_MORPHS_PCA: basis targets (0: 16; capped at the frames) */
  /* glb, any export kind: KHR_mesh_quantization (positions on a 14-bit grid dequantised by the
   * mesh node's transform or the inverse bind matrices, morph deltas as 16-bit integers on the
   * same grid, 8-bit octahedral normals, 16-bit UVs, 8-bit weights) + EXT_meshopt_compression
   * (every buffer view meshopt-encoded; rotations, translations and weights filtered). Both
   * extensions are required to read the file. The report's error is then of what a player
   * decodes. false: plain float32. */
  bool compress;
  /* ---- issue 11: the file frame to write positions in (a mesh file's axes and units, as
   * km_frame_apply brought it into kinemesh's frame): km_frame_unapply on the rest mesh and on
   * every pushed frame, so a .pc2 or a frame directory lines up with that file. NULL (or the
   * identity): kinemesh's frame. A .glb refuses one (KM_ERR_INVALID): glTF's frame is
   * kinemesh's by the specification. Copied at open. */
  const km_frame *frame;
  /* ---- KM_ANIM_EXPORT_SKELETON: the skeleton (its joints' names and rest positions: each
   * bone is bound at its joint, no rotation) and the weights (#V vertices, joints indexing
   * skeleton's) of the skinned mesh; copied at open */
  const km_skeleton *skeleton;
  const km_skin *weights;
} km_anim_options;

/* Streams an animation of a fixed-connectivity mesh to disk. Nothing appears at `path`
 * until close succeeds (a temporary is renamed); free without close discards it. */
typedef struct km_anim_writer km_anim_writer;
/* Opens a writer.
 *   path  in: .glb, .pc2 or a directory
 *   rest  in: the mesh (#V vertices, #F faces) whose frames follow; copied as needed
 *   opt   in: may be NULL (format from the path, 30 fps)
 *   out   out: allocated writer; close with km_anim_writer_close or discard with
 *         km_anim_writer_free
 * Errors: KM_ERR_IO. */
km_status km_anim_writer_open(const char *path, const km_mesh *rest, const km_anim_options *opt,
                              km_anim_writer **out, km_error *err);
/* Appends one frame.
 *   V  in: #V*3 positions in metres
 * Errors: KM_ERR_IO. */
km_status km_anim_writer_push(km_anim_writer *w, const double *V, km_error *err);
/* Appends one frame with the bone transforms that skinned it (KM_ANIM_EXPORT_SKELETON; other
 * writers ignore the transforms, as km_anim_writer_push).
 *   V           in: #V*3 positions in metres (the file's error is measured against them)
 *   transforms  in: skeleton->n_joints * 12, row-major 3x4 [R | t] rest -> frame per joint
 *               (km_skeleton_pose_from_*'s), R a rotation
 * Errors: KM_ERR_INVALID (a transform not finite, or NULL), KM_ERR_IO. A skeleton writer
 * refuses km_anim_writer_push (KM_ERR_INVALID): it has no transforms to store. */
km_status km_anim_writer_push_pose(km_anim_writer *w, const double *V, const double *transforms,
                                   km_error *err);
/* Finishes the file, renames it into place, frees *w and sets it to NULL (on failure too).
 * Errors: KM_ERR_IO; KM_ERR_INVALID when no frame was pushed (nothing is written then). */
km_status km_anim_writer_close(km_anim_writer **w, km_error *err);
/* Discards an unfinished animation, frees *w and sets it to NULL. */
void km_anim_writer_free(km_anim_writer **w);

/* What close did (issue 16). Errors are against the exact frames pushed, in metres. */
typedef struct km_anim_report {
  km_anim_export export_kind;
  size_t frames, bones;        /* bones: 0 unless skinned */
  size_t targets;              /* morph targets written (0 for a skin) */
  double rms_error, max_error; /* 0 for an exact export */
  double fit_seconds;          /* time spent fitting (skin), wall clock */
} km_anim_report;
/* km_anim_writer_close that also says what it wrote.
 *   report  out: may be NULL
 * Errors: as km_anim_writer_close; KM_ERR_DEGENERATE_MESH when no rig fits (skin). */
km_status km_anim_writer_finish(km_anim_writer **w, km_anim_report *report, km_error *err);

/* ---- skinning decomposition: Le & Deng 2012, "Smooth Skinning Decomposition with Rigid
 * Bones" (SSDR). Fits a linear-blend-skinning rig to any mesh animation: per-vertex sparse
 * non-negative weights (<= 4 influences, summing to 1) and per-frame rigid bone transforms,
 * initialised by clustering the vertices' trajectories. */
typedef struct km_ssdr_options {
  size_t bones;        /* 0: 32; the starting count when max_error_mm is set */
  size_t max_bones;    /* with max_error_mm: bones are split where the error is until the
                          budget is met or this count (0: 4*bones) */
  double max_error_mm; /* 0: none; else bones are added until the max error is below it */
  int iterations;      /* weight/transform alternations (0: 12) */
  size_t influences;   /* per vertex, 1..4 (0: 4) */
  const double *seed;  /* optional n_seed*3 bone seeds (e.g. the rest centroids of a rig's
                          skinned parts): the starting bones (bones is then n_seed), clusters
                          grow from the vertices nearest them; NULL: k-means++ */
  size_t n_seed;
  km_progress progress; /* optional; may cancel */
} km_ssdr_options;
typedef struct km_ssdr {
  size_t n_vertices, n_frames, n_bones;
  km_skin skin;       /* #V: joints index bones, weights >= 0 sum to 1 */
  double *transforms; /* n_frames * n_bones * 12: row-major 3x4 [R | t], rest -> frame */
  double *centers;    /* n_bones * 3: rest centroid of each bone's vertices (a joint spot) */
  double rms_error, max_error; /* metres, over all frames and vertices */
} km_ssdr;
/* Fits an LBS rig to an animation.
 *   rest      in: #V*3 rest positions
 *   frames    in: n_frames * #V * 3 positions (the exact animation)
 *   opt       in: may be NULL
 *   out       out: filled; free with km_ssdr_free
 * Errors: KM_ERR_INVALID, KM_ERR_DEGENERATE_MESH (fewer than 4 vertices), KM_ERR_NOMEM,
 * KM_ERR_CANCELLED. */
km_status km_ssdr_fit(const double *rest, size_t n_vertices, const double *frames, size_t n_frames,
                      const km_ssdr_options *opt, km_ssdr *out, km_error *err);
/* Frees what km_ssdr_fit allocated and zeroes *r. */
void km_ssdr_free(km_ssdr *r);

typedef struct km_anim_info {
  km_anim_format format;
  size_t frames; /* frames in the file (morph targets for glb) */
  size_t vertices;
  size_t faces; /* 0 for pc2 */
  double fps;
  double duration; /* seconds */
  /* ---- issue 12: one timeline for every writer option */
  size_t timeline_frames; /* frames of the animation's timeline: duration = (timeline_frames
                             - 1) / fps wherever fps is known; = frames except for a glb
                             written with key_every > 1 (frames counts its key frames) */
} km_anim_info;
/* Describes an animation file.
 *   path  in: .glb, .pc2 or a frame directory
 *   out   out: format, counts, frame rate
 * Errors: KM_ERR_IO, KM_ERR_PARSE. */
km_status km_anim_info_read(const char *path, km_anim_info *out, km_error *err);
/* Reads all frames of a .pc2.
 *   frames  out: allocated, info->frames * info->vertices * 3 doubles; free()
 *   info    out: counts and frame rate
 * Errors: KM_ERR_IO, KM_ERR_PARSE. */
km_status km_pc2_read(const char *path, double **frames, km_anim_info *info, km_error *err);

/* Reads a whole animation into memory (issue 16: `kinemesh bake`).
 *   path    in: .pc2, a frame directory (frame_NNNNNN.obj/.ply) or a .glb of morph targets
 *           (kinemesh's own, or any glTF whose first mesh a weights channel animates; skinned
 *           files are not evaluated)
 *   rest    out: the mesh the frames belong to, with its UVs/normals where the file has them:
 *           the glb's base mesh, the directory's first frame, a pc2's first frame (no faces);
 *           free with km_mesh_free
 *   frames  out: allocated info->frames * #V * 3 positions; free()
 *   info    out: format, counts, fps (0 when the file does not say)
 * Errors: KM_ERR_IO, KM_ERR_PARSE (naming file and byte/line), KM_ERR_UNSUPPORTED. */
km_status km_anim_read(const char *path, km_mesh *rest, double **frames, km_anim_info *info,
                       km_error *err);

/* ==== puppet: puppetry deformers, Wu, Lu & Song 2012 (src/puppet/) ==== */

/* Handles (both solvers): handle h owns handle_vertices[handle_offsets[h] ..
 * handle_offsets[h+1]) (offsets: #H+1 entries, offsets[0] == 0, non-decreasing).
 * A vertex may appear in at most one handle. Targets are absolute positions, one xyz per
 * handle vertex in handle_vertices order (handle_offsets[#H]*3 doubles). */

/* ---- reduced isoline model */

/* Reduced isoline model of Wu, Lu & Song 2012 (after Au et al. 2006/2007): n_e propagation
 * fields (the first non-constant eigenvectors of -L phi = lambda M phi), n_iso isolines per
 * field, one affine 3x4 transform per isoline as the unknowns (4*n_iso*n_e per coordinate).
 * Precompute depends on the mesh only (not on handles) and can be cached on disk. Meant for
 * one connected component: with several (or unreferenced vertices) the first eigenvectors
 * are component indicators and the fields degrade. A km_puppet is not thread-safe. */
typedef struct km_puppet km_puppet;
/* Both energies use the same reduced unknowns, the same prefactored U^T U structure and the
 * same rotations estimated on isoline-crossed triangles and interpolated (W_delta R_delta).
 * ARAP is the default because it tracks the full-space reference closer: mean deviation
 * 1.2% / 1.6% of the diagonal on armadillo / horse against 1.9% / 2.3% for Wu, Lu & Song's
 * Laplacian energy (kinemesh bench deform, with the reference's negative cotangent weights
 * floored; 1.2% / 1.7% before), at the same per-frame cost. */
typedef enum km_puppet_energy {
  KM_PUPPET_ENERGY_ARAP = 0,  /* reduced ARAP (membrane) energy (default) */
  KM_PUPPET_ENERGY_LAPLACIAN, /* Wu, Lu & Song eq. 8-9: |L X - rotated rest Laplacian|^2 */
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
  km_puppet_energy energy; /* 0: reduced ARAP; KM_PUPPET_ENERGY_LAPLACIAN: Wu, Lu & Song's */
  km_progress progress;
} km_puppet_options;

/* Builds the reduced model (eigenfields, isolines, prefactored system). Only fields,
 * isolines, crossed_per_isoline and energy shape the model (and the cache key); the other
 * options are solve settings.
 *   rest  in: closed or open triangle mesh, #V >= 4; copied
 *   opt   in: may be NULL (defaults)
 *   out   out: allocated model; free with km_puppet_free
 * Errors: KM_ERR_DEGENERATE_MESH, KM_ERR_NOT_POSDEF, KM_ERR_NO_CONVERGENCE,
 * KM_ERR_CANCELLED. */
km_status km_puppet_precompute(const km_mesh *rest, const km_puppet_options *opt, km_puppet **out,
                               km_error *err);
/* Writes the model atomically: magic, format version, parameters, hash of the rest mesh,
 * payload, checksum (native little-endian doubles).
 * Errors: KM_ERR_IO. */
km_status km_puppet_save(const km_puppet *p, const char *path, km_error *err);
/* Reads a model saved for exactly this rest mesh and these options.
 *   path  in: cache file (km_puppet_save)
 *   rest  in: the mesh the cache must have been built on
 *   opt   in: the options it must have been built with; may be NULL (defaults)
 *   out   out: allocated model; free with km_puppet_free
 * Errors: KM_ERR_STALE (with the reason) when the file is from another version, mesh or
 * parameter set, truncated or corrupted: the caller then precomputes again. KM_ERR_IO when
 * it cannot be read. */
km_status km_puppet_load(const char *path, const km_mesh *rest, const km_puppet_options *opt,
                         km_puppet **out, km_error *err);
/* The model parameters a cache was built with, read from its header only: a caller can
 * adopt them before km_puppet_load, which still checks everything.
 *   path  in: cache file
 *   opt   in/out: fields, isolines, crossed_per_isoline and energy are set; the other
 *         members are left as they are
 * Errors: KM_ERR_IO when the file cannot be read, KM_ERR_STALE when it is not a cache of
 * this format. */
km_status km_puppet_cache_options(const char *path, km_puppet_options *opt, km_error *err);
/* Sets the handle set (milliseconds: a 4*n_iso*n_e dense Cholesky; no eigen-decomposition).
 * The warm start of the previous solve is kept.
 *   handle_offsets   in: #H+1 offsets (see "Handles" above)
 *   handle_vertices  in: handle_offsets[#H] vertex ids */
km_status km_puppet_set_handles(km_puppet *p, size_t n_handles, const int32_t *handle_offsets,
                                const int32_t *handle_vertices, km_error *err);
/* One frame, warm-started from the previous solve. Does not allocate.
 *   targets  in: handle_offsets[#H]*3 absolute handle vertex positions
 *   V_out    out: #V*3 deformed positions
 * Errors: KM_ERR_INVALID before km_puppet_set_handles. */
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
/* Sizes of the model and figures of the last solve.
 *   out  out: filled */
void km_puppet_info_get(const km_puppet *p, km_puppet_info *out);
/* Frees *p and sets it to NULL. */
void km_puppet_free(km_puppet **p);

/* ---- full-space ARAP reference */

/* Full-space as-rigid-as-possible deformation (Sorkine & Alexa 2007), the quality
 * reference: cotangent weights (a negative one, two obtuse angles opposite an edge, raised to
 * a small positive floor in both steps, so that handles at rest give back the rest mesh on a
 * scan too), handle vertices eliminated (hard constraints), a CHOLMOD factor of the free part
 * of -L, per-vertex rotations by a closed-form 3x3 polar decomposition. Every connected
 * component needs at least one handle vertex. */
typedef struct km_arap km_arap;
typedef struct km_arap_options {
  int iterations;       /* local/global iterations per solve; 0: 4 */
  double tolerance;     /* stop earlier when the largest vertex move < tolerance * bbox diagonal;
                           0: 1e-6 */
  double handle_weight; /* 0: hard handles (eliminated), the exact reference. > 0: soft, each
                           handle vertex pulled to its target with this weight times the mean
                           diagonal of -L (KM_ARAP_SOFT_HANDLES: what animate uses) */
} km_arap_options;
/* The soft handle weight `animate --solver full` and `bench motion --solver full` use. Rigid
 * bone handles that meet at a joint with little skin between them (a knee band and ring) tore
 * it with hard handles; soft ones let the band give a little. bench motion --solver full,
 * first 150 frames, B's |l/l0 - 1| with hard -> 0.03 handles: elephant 0.47-0.85 -> 0.23-0.47,
 * horse 0.27-0.95 -> 0.15-0.43, dog0 0.41-0.91 -> 0.13-0.44, all three with no fold; the
 * character on cmu_131_03 1.41 -> 0.39 (0.1: 0.63, 1: 1.14). The handles' centroids stay
 * closer to their targets than the reduced model keeps them (mean over frames 0.01-0.18 % of
 * the diagonal, reduced 0.02-0.42 %), but for the elephant's, whose stubby limbs ask most of
 * the skin (0.37-0.50 %, at worst 3.0 %; reduced 0.25-0.27 %, 1.4 %). */
#define KM_ARAP_SOFT_HANDLES 0.03
/* Factorises the system for a fixed handle set.
 *   rest             in: triangle mesh, #V vertices; copied
 *   handle_offsets   in: #H+1 offsets (see "Handles" above)
 *   handle_vertices  in: handle_offsets[#H] vertex ids
 *   opt              in: may be NULL (defaults)
 *   out              out: allocated solver; free with km_arap_free
 * Errors: KM_ERR_DEGENERATE_MESH, KM_ERR_NOT_POSDEF (a component without handles). */
km_status km_arap_precompute(const km_mesh *rest, size_t n_handles, const int32_t *handle_offsets,
                             const int32_t *handle_vertices, const km_arap_options *opt,
                             km_arap **out, km_error *err);
/* One frame, warm-started from the previous solve (the rest pose at first).
 *   targets  in: handle_offsets[#H]*3 absolute handle vertex positions
 *   V_out    out: #V*3 deformed positions */
km_status km_arap_solve(km_arap *a, const double *targets, double *V_out, km_error *err);
/* Frees *a and sets it to NULL. */
void km_arap_free(km_arap **a);

/* ---- puppetry pipeline */

/* One frame of captured joints in, one deformed mesh out: Holt filter -> retarget (eq. 5-7)
 * -> reduced isoline model (or the full ARAP reference), plus the reduced model's disk cache
 * policy. It is what `animate`, `bench deform` and the live server run. The rig (handles, map,
 * filter) can be replaced at run time without a new eigen precompute. Not thread-safe. */
typedef struct km_puppetry km_puppetry;

typedef enum km_puppetry_solver {
  KM_PUPPETRY_REDUCED = 0, /* reduced isoline model (km_puppet), cached on disk */
  KM_PUPPETRY_FULL,        /* full-space ARAP (km_arap), rebuilt per handle set, no cache */
  /* No mesh solve: glitch rejection, filter and retarget only, for a caller that poses the
   * character's own skeleton (km_puppetry_posed_joints) and skins it itself (`pose
   * --retarget`). No model is built or cached (info: KM_PUPPETRY_MODEL_BUILT, 0 s); a push
   * leaves V_out untouched (it may be NULL); the handle targets and the posed joints are its
   * output. */
  KM_PUPPETRY_RETARGET
} km_puppetry_solver;

typedef struct km_puppetry_options {
  const km_filter_options *filter; /* NULL: the rig's "filter" */
  km_retarget_options retarget;    /* scale 0: automatic */
  km_puppet_options puppet;        /* reduced model and solve settings; its progress callback
                                      reports the precompute */
  km_arap_options arap;            /* full solver settings */
  km_puppetry_solver solver;       /* 0: reduced */
  /* An already built reduced model of the rest mesh to use (borrowed: it stays the caller's
   * and must outlive the pipeline, which sets its handles and resets its solve state, so the
   * pipeline starts from the rest pose whatever used the model before). NULL:
   * km_puppetry_model_open. */
  km_puppet *model;
  /* Reduced model cache: loaded when up to date for this mesh and model parameters, else
   * the model is precomputed and written there. NULL: always precompute, write nothing. */
  const char *cache_path;
  bool force; /* precompute and rewrite the cache even when it is up to date */
  /* Adopt the model parameters an existing cache was built with (fields, isolines,
   * crossed_per_isoline, energy: km_puppet_cache_options) instead of puppet's, so a cache
   * made with other parameters is used as built rather than rebuilt. */
  bool cache_parameters;
  const char *take_name; /* names the take in error messages; NULL: "the take" */
  /* ---- issue 12: glitch rejection and frame rate */
  double fps;                   /* frame rate of the pushed frames, for the glitch speed test
                                   and the One Euro filter when their own fps is 0. 0: 30 */
  km_glitch_options glitch;     /* rejection before the filter (km_glitch_create) */
  bool no_glitch;               /* true: no glitch rejection (raw frames go to the filter) */
  const int32_t *joint_parents; /* n_joints parents of the pushed columns, for the bone test
                                   (copied); NULL: kinect1 rigs use the Kinect v1 bones, other
                                   rigs get no bone test */
} km_puppetry_options;

typedef enum km_puppetry_model_source {
  KM_PUPPETRY_MODEL_BUILT = 0,      /* precomputed: no cache path, or no cache file yet */
  KM_PUPPETRY_MODEL_LOADED,         /* loaded from an up-to-date cache */
  KM_PUPPETRY_MODEL_REBUILT_STALE,  /* the cache did not match: see stale */
  KM_PUPPETRY_MODEL_REBUILT_FORCED, /* options.force */
  KM_PUPPETRY_MODEL_FULL,           /* full solver: ARAP precomputed for the rig's handles */
  KM_PUPPETRY_MODEL_GIVEN           /* options.model was used */
} km_puppetry_model_source;

/* What km_puppetry_create did about the model (the library never prints: the caller
 * reports it). */
typedef struct km_puppetry_info {
  km_puppetry_model_source model;
  double model_seconds;     /* load or precompute time of the solver (not the cache write) */
  bool cache_parameters;    /* options.cache_parameters took the cache's model parameters */
  km_puppet_options puppet; /* the reduced model parameters used (progress cleared) */
  km_error stale;           /* REBUILT_STALE: status KM_ERR_STALE and why the cache was unusable */
  km_error save;            /* status KM_OK, or why the cache could not be written (the pipeline
                               is usable all the same) */
} km_puppetry_info;

/* The cache policy alone: the reduced model of rest by opt->puppet, opt->cache_path,
 * opt->force and opt->cache_parameters (the other members are ignored), loaded when the cache is up
 * to date, else precomputed (opt->puppet.progress reports it) and saved. *out: the caller's, free
 * with km_puppet_free. info: what happened (may be NULL). A cache that is absent or stale is
 * rebuilt; any other load error fails; a failed save is only reported in info->save. */
km_status km_puppetry_model_open(const km_mesh *rest, const km_puppetry_options *opt,
                                 km_puppet **out, km_puppetry_info *info, km_error *err);

/* rest: the mesh to deform (kept by pointer: must outlive the pipeline).
 * rig: resolved on rest (copied; may be NULL: the model only, set a rig with
 * km_puppetry_set_rig before pushing). joint_names, n_joints: the columns of the frames that
 * will be pushed (n_joints*3 doubles each). For a "kinect1" rig with joint_names, columns are
 * matched to the 20 Kinect v1 joints by name (extra columns ignored, absent ones missing),
 * and every joint the rig maps must be present (KM_ERR_INVALID naming take_name and the
 * missing joints); joint_names NULL: frames are already in the rig's joint order. info: may
 * be NULL. The reduced model is options.model, else km_puppetry_model_open's: its errors fail
 * the call; a cache that cannot be written is only reported in info->save. */
km_status km_puppetry_create(const km_mesh *rest, const km_rig *rig, const char *const *joint_names,
                             size_t n_joints, const km_puppetry_options *opt, km_puppetry **out,
                             km_puppetry_info *info, km_error *err);
/* Replaces the rig (handles, map, filter) at run time: new filter and retarget, the solver's
 * handle set changed (reduced: milliseconds, no eigen precompute; full: a new factor). The
 * new retarget's reference pose is seeded with the first valid filtered joints already seen
 * and the newest frame is replayed through it, so the character does not jump; the handle
 * targets reflect that (rest centroids when nothing was pushed yet). On failure the previous
 * rig stays in force. The rig is copied. */
km_status km_puppetry_set_rig(km_puppetry *p, const km_rig *rig, km_error *err);
/* One frame: joints n_joints*3 raw positions in the create-time column order (NaN = missing:
 * the joint holds its last filtered value; a sample the glitch rejector refuses counts as
 * missing); V_out #V*3 deformed positions. Does not allocate.
 * KM_ERR_INVALID when no rig is set; solver errors as km_puppet_solve / km_arap_solve. */
km_status km_puppetry_push(km_puppetry *p, const double *joints, double *V_out, km_error *err);
/* Same for a frame received at time t (seconds, any origin, NaN: untimed), which the glitch
 * rejector's speed test uses (km_glitch_push_at): for live input, where frames are dropped. */
km_status km_puppetry_push_at(km_puppetry *p, const double *joints, double t, double *V_out,
                              km_error *err);
/* ---- issue 15: joint rotations from the tracker */
/* km_puppetry_push_at with the joints' rotations (a VMC sender's bones): rotations
 * n_joints*9 in the create-time column order, row-major world rotations of the bone ending at
 * each joint, NaN = not given, or NULL (= km_puppetry_push_at). They add the twist about the
 * bone to the rig's rotating and bone handles (km_retarget_push_rotations); they are not
 * filtered (the positions are). Does not allocate. */
km_status km_puppetry_push_rotations(km_puppetry *p, const double *joints, const double *rotations,
                                     double t, double *V_out, km_error *err);
/* Forgets the filter history, the retarget's reference pose and auto scale, the first valid
 * joints and the newest frame, and the reduced solver's warm start (the full solver keeps
 * its warm start). */
void km_puppetry_reset(km_puppetry *p);

/* Milliseconds spent by the last push in each stage (Wu, Lu & Song's t2,3 = filter + retarget,
 * t4 = solve). */
typedef struct km_puppetry_times {
  double filter_ms, retarget_ms, solve_ms;
} km_puppetry_times;
void km_puppetry_times_get(const km_puppetry *p, km_puppetry_times *out);
/* The performer-to-character factor in use; NaN while automatic and no valid frame seen. */
double km_puppetry_scale(const km_puppetry *p);
/* Handle set of the current rig: *n_handles, offsets (n_handles+1) and vertices
 * (offsets[n_handles]), as km_puppet_set_handles takes them; owned by the pipeline, valid
 * until the next km_puppetry_set_rig. Zero / NULL when no rig is set. */
void km_puppetry_handles(const km_puppetry *p, size_t *n_handles, const int32_t **offsets,
                         const int32_t **vertices);
/* Targets of the last push (or of km_puppetry_set_rig), owned by the pipeline:
 * handle_targets n_handles*3 (handle centroids where the output puts them: with rigid root
 * motion after km_retarget_root_transform), vertex_targets offsets[n_handles]*3 (one per
 * handle vertex, what the solver got: root-relative under rigid root motion), rest_centroids
 * n_handles*3. NULL without a rig. */
const double *km_puppetry_handle_targets(const km_puppetry *p);
const double *km_puppetry_vertex_targets(const km_puppetry *p);
const double *km_puppetry_rest_centroids(const km_puppetry *p);
/* Joints in the rig's order (20 for kinect1, else n_joints), *3 doubles, owned by the
 * pipeline: filtered = the last push's filter output; reference = per coordinate the first
 * valid filtered value since create / reset (NaN until seen); last = the last raw frame
 * pushed (NULL when none since create / reset). NULL without a rig. */
const double *km_puppetry_filtered_joints(const km_puppetry *p);
const double *km_puppetry_reference_joints(const km_puppetry *p);
const double *km_puppetry_last_joints(const km_puppetry *p);
/* The character's own joints as the last push posed them (km_retarget_joints: the skeleton
 * the bone handles hang from, root motion applied), in the rig's joint order.
 *   out  out: n*3 with n as for km_puppetry_filtered_joints
 * Returns false (out untouched) without a rig or when the rig has no "joints" skeleton. */
bool km_puppetry_posed_joints(const km_puppetry *p, double *out);
/* The floor constraint of the current rig (km_retarget_floor): returns whether it is on, and then
 * sets *floor_y to the rest floor, where km_puppetry_push holds the solved mesh's vertices (a
 * caller skinning the posed joints itself holds its vertices there the same way). */
bool km_puppetry_floor(const km_puppetry *p, double *floor_y);
/* Glitch rejection counts since the current rig was set (or reset); zeroed when off. */
void km_puppetry_glitch_stats(const km_puppetry *p, km_glitch_stats *out);
/* Frames whose handle motion the rig's max_step eased (km_retarget_eased_frames) since the
 * current rig was set (or reset); 0 without a rig. */
size_t km_puppetry_eased_frames(const km_puppetry *p);
/* The reduced model in use (NULL for the full solver); owned by the pipeline unless it was
 * given as options.model. */
km_puppet *km_puppetry_model(const km_puppetry *p);
/* The reduced model's info (zeroed for the full solver). */
void km_puppetry_puppet_info(const km_puppetry *p, km_puppet_info *out);
void km_puppetry_free(km_puppetry **p);

/* ==== transfer: pose transfer & recognition, Lifkooee et al. 2019 (src/transfer/) ==== */

/* ---- pose transfer */

/* Pose transfer by locally encoded Laplacian offsets (Lifkooee et al. 2019): a source mesh S
 * (the avatar) takes the pose of a template mesh T of the same connectivity. Offline:
 * offsets Delta = L X_S, per-vertex frames F(v) (normal, tangent from a fixed neighbour edge,
 * their cross product) and pose-invariant coordinates W_i = F_S(v_i)^T Delta_i. Online: the
 * landmark vertices are fixed at their targets, the rest solves
 *   (-L)_ff x_f = -(F W)_f + L_fc x_c          (eq. 7, symmetric elimination form)
 * (F W stands for the rotated offsets of the chosen km_offset_encoding)
 * The factor of (-L)_ff is computed once per landmark set. Vertex encoding (the paper's):
 * F = frames of T at first, then frames of the previous solution (this drifts towards
 * landmark-only editing). Edge encoding (default): each iteration lowers the energy
 *   E(x, S) = sum_i [ sum_j w_ij |x_j - x_i - R_i S_i e_ij|^2 + lambda_i |S_i - I|^2 ]
 * (e_ij rest edges of S, w_ij = L_ij, R_i the rotation of T's one-ring i fitted onto S's and
 * kept fixed, S_i a symmetric stretch, lambda_i = damping * sum_j w_ij |e_ij|^2) by
 * alternating the Laplacian solve for x with the closed-form S_i per vertex: the one-rings
 * keep T's rotations and take up the stretch that rotated rest edges cannot express. */
typedef enum km_laplacian_kind {
  KM_LAPLACIAN_UNIFORM = 0, /* graph Laplacian, Lifkooee et al.'s eq. 2 */
  KM_LAPLACIAN_COTAN,       /* cotangent weights of the source mesh */
} km_laplacian_kind;

typedef enum km_transfer_align {
  /* T's landmark positions scaled about the origin by size(S)/size(T), T's placement kept.
   * size(S)/size(T) = the median over vertices of the one-ring's RMS edge-length ratio S / T:
   * pose-invariant (edges keep their lengths), so for one body in two poses it is 1 to within
   * 0.0002 (FAUST, the cat poses, generated subjects) and the targets are T's own. */
  KM_TRANSFER_ALIGN_SCALE = 0,
  /* Umeyama similarity (rotation, translation, scale) of T's landmarks onto the source's rest
   * landmarks (scale replaced by the edge-length size ratio): places the result where S
   * stands. Only sensible when T's pose is close to S's rest pose (the fit mixes pose and
   * placement otherwise). */
  KM_TRANSFER_ALIGN_SIMILARITY,
  /* T's landmark positions as they are (a template known to be of S's size). */
  KM_TRANSFER_ALIGN_NONE,
} km_transfer_align;

typedef enum km_offset_encoding {
  /* Default. Each one-ring edge in the frames of both its ends (E_ij = F_S(i) e_ij); the
   * right-hand side is sum_j w_ij (F(i)^T E_ij - F(j)^T E_ji) / 2. Identical to Lifkooee et
   * al.'s encoding at rest (it sums to F(v_i) W_i when both frames agree), but where
   * neighbouring frames differ (a bent joint in the template) the result bends too: the
   * Poisson / ARAP-global-step form of the same locally encoded offsets. Measured on
   * generated subjects (3k vertices, 10 poses, tracked landmarks): 9 mm mean error vs 37 mm. */
  KM_OFFSETS_EDGE = 0,
  /* Lifkooee et al.'s eq. 3 verbatim: one offset per vertex in the vertex's own frame,
   * right-hand side F(v_i) W_i. Rotating a rest offset cannot create the bend of a limb at a
   * joint (a straight tube has no bend in its offsets), so limbs bend only at the landmarks. */
  KM_OFFSETS_VERTEX,
} km_offset_encoding;

typedef struct km_transfer_options {
  km_laplacian_kind laplacian; /* 0: uniform */
  km_offset_encoding encoding; /* 0: per edge (see above); KM_OFFSETS_VERTEX: Lifkooee eq. 3 */
  km_transfer_align align;     /* how landmark targets come from a template; 0: scale */
  int max_iterations;          /* solves per transfer; 0: 4 (edge encoding), 10 (vertex, the
                                  paper's) */
  double tolerance;            /* stop when the largest vertex move between two solves is below
                                  tolerance * bbox diagonal of S and the largest frame (vertex
                                  encoding) or stretch (edge) entry change is below tolerance;
                                  0: 1e-4 */
  double damping;              /* edge encoding: lambda of the energy above, the pull of each
                                  stretch S_i towards I; 0: 0.3; < 0: none */
} km_transfer_options;

typedef struct km_transfer km_transfer;

/* Offline stage: Laplacian, offsets, frames and the Cholesky factor of (-L)_ff.
 *   source       in: the avatar at rest (closed or open triangle mesh, #V vertices); copied
 *   landmarks    in: #L = n_landmarks >= 3 distinct vertex ids (fewer leaves the Laplacian
 *                rank deficient up to a rotation: KM_ERR_INVALID); copied
 *   opt          in: may be NULL (defaults)
 *   out          out: allocated; free with km_transfer_free
 * Errors: KM_ERR_DEGENERATE_MESH, KM_ERR_NOT_POSDEF. */
km_status km_transfer_precompute(const km_mesh *source, const int32_t *landmarks,
                                 size_t n_landmarks, const km_transfer_options *opt,
                                 km_transfer **out, km_error *err);

typedef struct km_transfer_stats {
  int iterations;         /* linear solves done */
  bool converged;         /* tolerance met before max_iterations */
  double position_change; /* last iteration's largest vertex move / bbox diagonal */
  double frame_change;    /* vertex encoding: largest frame entry change at the last frame
                             update; NAN while the positions still move (only measured once they
                             settle; frames are not recomputed after the last allowed solve).
                             Edge encoding: largest stretch entry change at the last local step
                             (NAN after the last allowed solve) */
  double frames_ms;       /* time in normals + frames (edge encoding: + rotation fit and local
                             steps), all iterations */
  double solve_ms;        /* time in right-hand sides + triangular solves, all iterations */
  double total_ms;        /* whole call */
} km_transfer_stats;

/* Online stage. Does not allocate. Not thread-safe on one object.
 *   template_V  in: #V*3 positions of T (same connectivity as S); its frames start the
 *               iteration. May be NULL when warm_start is given.
 *   targets     in: #L*3 landmark positions in precompute order; NULL: from template_V's
 *               landmark vertices through the options' align mode (template_V then required)
 *   warm_start  in: #V*3 a previous result (e.g. the last key pose); its frames start the
 *               iteration when template_V is NULL. Ignored otherwise. May be NULL.
 *   V_out       out: #V*3 result; may alias warm_start but not template_V
 *   stats       out: may be NULL */
km_status km_transfer_solve(km_transfer *t, const double *template_V, const double *targets,
                            const double *warm_start, double *V_out, km_transfer_stats *stats,
                            km_error *err);
/* Energies of the last km_transfer_solve, one per solve (edge encoding; the vertex encoding
 * has none and gives 0): E_k = E(x_k, S_(k-1)) of the energy above, which never rises from
 * one solve to the next. The last one is evaluated here (one pass over the one-rings, about
 * as long as one solve's local step), not in km_transfer_solve.
 *   energies  out: up to cap values, may be NULL
 * Returns the number of solves done (stats.iterations). */
size_t km_transfer_energies(const km_transfer *t, double *energies, size_t cap);
/* ---- bodies of another connectivity (issue 14): S takes the pose of a template T whose
 * mesh differs, given T at rest (TR) and posed (TP). The pose is carried as rotations: each
 * one-ring of TR -> TP gives a rotation (km_transfer_template_rotations), each source vertex
 * takes that of its corresponding template vertex (km_transfer_correspondence), and
 * km_transfer_solve_rotations runs the iteration above from them. S's connectivity and
 * vertex order are kept. */
/* Rotation of every one-ring of a mesh from rest to posed (Procrustes, uniform weights).
 *   rest   in: the template at rest (#VT vertices, faces)
 *   posed  in: #VT*3 the template posed
 *   R      out: #VT*9 row-major rotations
 * Errors: as km_uniform_laplacian. */
km_status km_transfer_template_rotations(const km_mesh *rest, const double *posed, double *R,
                                         km_error *err);
/* Dense correspondence: for every source vertex the nearest template vertex, both at rest and
 * in one frame (same placement and size: see km_transfer_register_rest below).
 *   corr  out: #V (source) template vertex ids */
km_status km_transfer_correspondence(const km_mesh *source_rest, const km_mesh *template_rest,
                                     int32_t *corr, km_error *err);
/* The pose of T carried to S: rotations per source vertex (its corresponding template
 * vertex's, km_transfer_template_rotations) and landmark targets (the corresponding template
 * vertex posed, plus the landmark's rest offset from it turned by that vertex's rotation).
 *   corr       in: #V from km_transfer_correspondence
 *   landmarks  in: n_landmarks source vertex ids (precompute order)
 *   R          out: #V*9;  targets  out: n_landmarks*3 (may be NULL when n_landmarks is 0)
 * Errors: KM_ERR_INVALID (ids out of range), KM_ERR_NOMEM. */
km_status km_transfer_map_pose(const km_mesh *source_rest, const km_mesh *template_rest,
                               const double *template_posed, const int32_t *corr,
                               const int32_t *landmarks, size_t n_landmarks, double *R,
                               double *targets, km_error *err);
/* A source that stands in another frame or at another size than TR (a scan against a game
 * character): register S's rest onto TR's first, then carry the pose over on the registered
 * copy and turn it back into S's frame:
 *   km_transfer_register_rest(S, TR, pairs, n, Sr, &s, Q, t);   Sr = s Q S + t
 *   km_transfer_correspondence(Sr-mesh, TR, corr); km_transfer_map_pose(Sr-mesh, TR, TP, ...);
 *   km_transfer_pose_to_source(s, Q, t, NULL, #V, R, #L, targets); km_transfer_solve_rotations
 * on a km_transfer precomputed on S itself: the output keeps S's frame, size, connectivity and
 * vertex order. The registration is a similarity (Umeyama, km_similarity_fit) of vertex pairs
 * (landmarks of one name in both rigs, or given by the user): exact for one body in two
 * frames. A non-rigid step may follow (km_recon_register_mesh from Sr onto TR, giving Sn):
 * the correspondence is then taken from Sn, the pose still mapped on Sr
 * (km_transfer_map_pose(Sr-mesh, ..., corr from Sn)), and `local` = the one-ring rotations
 * Sr -> Sn (km_transfer_template_rotations(Sr-mesh, Sn)) so that each R_i is seen from S's own
 * one-ring.
 * km_transfer_register_rest:
 *   pairs       in: n_pairs*2 vertex ids (source, template), n_pairs >= 3
 *   registered  out: #V*3 the source's rest moved onto TR: s Q x + t
 *   scale, Q, t out: the similarity (Q row-major 3x3 rotation)
 *   Errors: KM_ERR_INVALID (ids out of range, fewer than 3 pairs), KM_ERR_DEGENERATE_MESH
 *   (collinear or coincident pairs).
 * km_transfer_pose_to_source: R (#V*9, in: TR's frame, out: S's: Q^T L_i^T R_i L_i Q) and
 *   targets (#L*3, Q^T (p - t) / s) in place; either may be NULL. local: #V*9 the rotations
 *   L_i of a non-rigid step after the similarity, or NULL (L_i = I). */
km_status km_transfer_register_rest(const km_mesh *source_rest, const km_mesh *template_rest,
                                    const int32_t *pairs, size_t n_pairs, double *registered,
                                    double *scale, double Q[9], double t[3], km_error *err);
void km_transfer_pose_to_source(double scale, const double Q[9], const double t[3],
                                const double *local, size_t n_vertices, double *R,
                                size_t n_landmarks, double *targets);
/* km_transfer_solve from per-vertex rotations instead of a template of S's connectivity.
 *   R        in: #V*9 row-major rotation of each source vertex's one-ring (the pose)
 *   targets  in: #L*3 landmark positions in precompute order
 *   V_out    out: #V*3
 * Errors: KM_ERR_INVALID (vertex encoding, non-finite input). */
km_status km_transfer_solve_rotations(km_transfer *t, const double *R, const double *targets,
                                      double *V_out, km_transfer_stats *stats, km_error *err);
/* Returns #V of the source. */
size_t km_transfer_vertices(const km_transfer *t);
/* Returns #L, the landmark count. */
size_t km_transfer_landmarks(const km_transfer *t);
/* Landmark targets the solver would use for a template. Uses the object's scratch (one
 * Dijkstra): not thread-safe on one object, does not allocate.
 *   template_V  in: #V*3
 *   targets     out: #L*3 */
km_status km_transfer_targets(const km_transfer *t, const double *template_V, double *targets,
                              km_error *err);
/* Offline timings of precompute in milliseconds.
 *   laplacian_ms  out: Laplacian + offsets + frames; may be NULL
 *   cholesky_ms   out: symbolic + numeric Cholesky; may be NULL */
void km_transfer_precompute_ms(const km_transfer *t, double *laplacian_ms, double *cholesky_ms);
/* Frees *t and sets it to NULL. */
void km_transfer_free(km_transfer **t);

/* Returns the total triangle area of m (for pose-invariant size ratios). */
double km_surface_area(const km_mesh *m);

/* ---- landmark files */

/* LM.json: {"landmarks":[{"name":"head","vertex":411,"mirror":"head"},...]}; a character rig
 * sidecar (*.rig.json) carries the same array and is accepted as is. Every mirror must name
 * a landmark of the file (itself on the mid-line).
 * km_landmarks_read:
 *   n_vertices  in: > 0 checks the vertex ids against #V; 0 skips the check
 *   out         out: up to `capacity` landmarks (more: KM_ERR_PARSE)
 *   n           out: landmarks read
 *   Errors: KM_ERR_IO, KM_ERR_PARSE naming the file.
 * km_landmarks_write (atomically):
 *   lm  in: n landmarks
 *   Errors: KM_ERR_IO. */
#define KM_POSE_MAX_LANDMARKS 32
km_status km_landmarks_read(const char *path, size_t n_vertices, km_landmark *out, size_t capacity,
                            size_t *n, km_error *err);
km_status km_landmarks_write(const char *path, const km_landmark *lm, size_t n, km_error *err);

/* ---- pose recognition */

/* Pose descriptor (Lifkooee et al. 2019, eq. 4). For n landmarks the candidate features are
 * all angles angle(i, j, k) at landmark j between segments j->i and j->k, i < k, i, k != j:
 * n (n-1) (n-2) / 2 of them (1,680 for 16 landmarks), in the order j major, then i, then k.
 * A feature is stored as its triple {i, j, k}. */
/* Returns the number of candidate features for n_landmarks landmarks. */
size_t km_pose_candidate_count(size_t n_landmarks);
/* The triple of candidate feature f.
 *   f       in: 0 .. km_pose_candidate_count(n_landmarks)-1
 *   triple  out: {i, j, k} */
void km_pose_candidate(size_t n_landmarks, size_t f, int32_t triple[3]);
/* Angles of the given triples; a zero-length segment gives pi/2.
 *   P        in: #L*3 landmark positions
 *   triples  in: n_features*3 landmark indices
 *   out      out: n_features angles in radians, [0, pi] */
void km_pose_angles(const double *P, const int32_t *triples, size_t n_features, double *out);

typedef enum km_svm_kernel { KM_SVM_RBF = 0, KM_SVM_LINEAR } km_svm_kernel;

/* How Lifkooee et al.'s left/right mirroring is used (their section 3.2.1): "when an angle
 * (i,j,k) is observed, also add an instance of (m(i),m(j),m(k))". */
typedef enum km_pose_mirror {
  /* default: the feature-selection trees see every sample twice, as measured and mirrored
   * (same class), so the selected angles are not biased to the side the data moves most;
   * the SVM is trained on the samples as measured, so left and right variants of a pose
   * may be distinct classes. */
  KM_POSE_MIRROR_SELECTION = 0,
  KM_POSE_MIRROR_ALL,  /* also add mirrored samples to the SVM training set (same class) */
  KM_POSE_MIRROR_NONE, /* no mirroring */
} km_pose_mirror;

/* ---- labelled pose meshes (the input of a pose database) */

/* The meshes a pose database is built from, with their classes and subjects. All arrays are
 * owned by the set; free with km_pose_set_free. */
typedef struct km_pose_set {
  size_t n;            /* meshes */
  char **paths;        /* n mesh files */
  char **names;        /* n template names: the files' base names */
  int32_t *labels;     /* n class indices into class_names */
  int32_t *groups;     /* n subject ids (equal ids: one subject); NULL when no entry names one */
  size_t n_classes;    /* distinct classes */
  char **class_names;  /* n_classes names, in order of first appearance */
  size_t n_listed;     /* km_pose_set_from_labels: mesh files the folder or glob holds */
  size_t n_unlabelled; /* km_pose_set_from_labels: meshes that no line of the CSV names */
  char **unlabelled;   /* their paths (left out of the set) */
  size_t n_duplicates; /* km_pose_set_from_labels: CSV lines naming a mesh already labelled
                          (warned through the logger and ignored: the first line wins) */
} km_pose_set;
/* From n entries "CLASS=MESH[@GROUP]" (GROUP: the subject, for leave-one-subject-out
 * cross-validation; entries without one are group 0).
 * Errors: KM_ERR_INVALID naming the entry that has no CLASS=. */
km_status km_pose_set_from_entries(const char *const *entries, size_t n, km_pose_set *out,
                                   km_error *err);
/* From the mesh files (.obj .ply .off) of a folder or glob `meshes` and a CSV of lines
 * "mesh,class[,subject]" (',', ';' or tab; an optional header line; '#' comments; `mesh` is a
 * listed file's path or base name), in the CSV's order, after n_before entries
 * "CLASS=MESH[@GROUP]" given otherwise (entries_before may be NULL when n_before is 0).
 * Errors: KM_ERR_IO (nothing matched, unreadable CSV), KM_ERR_PARSE naming the CSV line. */
km_status km_pose_set_from_labels(const char *meshes, const char *labels_csv,
                                  const char *const *entries_before, size_t n_before,
                                  km_pose_set *out, km_error *err);
/* Frees the arrays of s and zeroes it. */
void km_pose_set_free(km_pose_set *s);

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
  double cv_accuracy_eq8; /* Lifkooee et al.'s eq. 8, (TP+TN)/(TP+TN+FP+FN) averaged over the
                             K one-vs-rest problems: 1 - 2 e / (N K) for e errors in N tests,
                             always >= cv_accuracy; -1 when no cross-validation ran */
} km_posedb_report;

/* Builds a pose database. Feature selection is CART (Gini) over all candidate angles,
 * classification libsvm, template choice nearest neighbour inside the class.
 *   meshes       in: n_meshes meshes of one connectivity (point clouds are fine when only
 *                recognition is wanted); copied as the templates
 *   labels       in: n_meshes pose classes in [0, n_classes)
 *   class_names  in: n_classes names; may be NULL
 *   groups       in: n_meshes subject ids, so that cross-validation leaves one subject out
 *                at a time; may be NULL (k-fold)
 *   landmarks    in: #L = n_landmarks >= 4 vertex ids on the meshes, with mirrors
 *   opt          in: may be NULL (defaults)
 *   out          out: allocated database; free with km_posedb_free
 *   report       out: may be NULL
 * Errors: KM_ERR_CANCELLED. */
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

/* Recognises a pose.
 *   P    in: #L*3 landmark positions in database order, all finite
 *   out  out: class, nearest template, distance, time */
km_status km_posedb_query(const km_posedb *db, const double *P, km_pose_match *out, km_error *err);
/* Single-file database (binary, versioned: "KMPOSEDB" magic, version, JSON header, raw
 * little-endian arrays, FNV-1a checksum), written atomically. The SVM is retrained on load
 * from the stored templates (deterministic, milliseconds for thousands of samples).
 * km_posedb_save: Errors: KM_ERR_IO.
 * km_posedb_load:
 *   out  out: allocated database; free with km_posedb_free
 *   Errors: KM_ERR_IO, KM_ERR_PARSE (not a database, truncated, checksum). */
km_status km_posedb_save(const km_posedb *db, const char *path, km_error *err);
km_status km_posedb_load(const char *path, km_posedb **out, km_error *err);
/* Accessors (db in; strings and arrays owned by the database):
 *   size            number of templates (meshes)
 *   classes         number of classes
 *   class_name      name of class c, "" when unnamed
 *   label           class of template i
 *   landmark_count  #L
 *   landmarks       #L landmarks */
size_t km_posedb_size(const km_posedb *db);
size_t km_posedb_classes(const km_posedb *db);
const char *km_posedb_class_name(const km_posedb *db, size_t c); /* "" when unnamed */
int32_t km_posedb_label(const km_posedb *db, size_t i);
size_t km_posedb_landmark_count(const km_posedb *db);
const km_landmark *km_posedb_landmarks(const km_posedb *db);
/* Template i as a mesh view.
 *   view  out: V, F owned by the database; do not free */
void km_posedb_template(const km_posedb *db, size_t i, km_mesh *view);
/* Names for the templates (e.g. their file names), saved with the database so a query can
 * say which mesh it picked.
 *   names  in: km_posedb_size(db) strings, at most 127 characters of each kept; copied */
km_status km_posedb_set_template_names(km_posedb *db, const char *const *names, km_error *err);
/* Returns the name of template i, "" when unnamed (owned by the database). */
const char *km_posedb_template_name(const km_posedb *db, size_t i); /* "" when unnamed */
/* Selected features, best first.
 *   d  out: number of features
 * Returns d*3 landmark indices (triples), owned by the database. */
const int32_t *km_posedb_features(const km_posedb *db, size_t *d);
/* The build report (cv figures as stored; samples/classes/features of this database).
 *   report  out: filled */
void km_posedb_info(const km_posedb *db, km_posedb_report *report);
/* Frees *db and sets it to NULL. */
void km_posedb_free(km_posedb **db);

/* ---- landmark tracks */

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
/* km_track_read:
 *   out  out: allocated track; free with km_track_free
 *   Errors: KM_ERR_IO, KM_ERR_PARSE naming the file and line.
 * km_track_write (atomically, format by extension):
 *   t  in: track (NaN written as null / an empty field)
 *   Errors: KM_ERR_IO. */
km_status km_track_read(const char *path, km_track *out, km_error *err);
km_status km_track_write(const char *path, const km_track *t, km_error *err);
/* Frees names and positions of t and zeroes the struct. */
void km_track_free(km_track *t);

/* ---- key-pose morphing */

/* Linear interpolation out = (1-a) A + a B of two key poses.
 *   A, B  in: #V*3 each
 *   out   out: #V*3; may alias A or B */
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

/* Motion generation (Lifkooee et al. 2019, section 3.5): every k-th track frame (and the
 * last) is recognised in db, its template transferred onto the avatar with the tracked
 * landmarks (scaled to the avatar) as targets, and frames in between are linear
 * interpolations of consecutive key poses, so there is one output frame per track frame. A
 * key frame with an untracked (NaN) landmark repeats the previous key pose.
 *   t      in/out: precomputed on the avatar with the landmark vertices in the database's
 *          landmark order (its scratch is used)
 *   db     in: pose database
 *   track  in: landmark track; its landmarks are matched to the database's by name (or
 *          taken in order when the track has no names)
 *   opt    in: may be NULL (defaults)
 *   fn     in: receives each output frame, V #V*3 (valid during the call only), and user
 *   stats  out: may be NULL
 * Errors: whatever fn returns, KM_ERR_CANCELLED. */
km_status km_avatar_animate(km_transfer *t, const km_posedb *db, const km_track *track,
                            const km_avatar_options *opt, km_avatar_frame_fn fn, void *user,
                            km_avatar_stats *stats, km_error *err);

/* ==== recon: point clouds to mesh animation, Park & Lim 2014 (src/recon/) ==== */

/* ---- geometry */

/* Closest points on a triangle mesh (Embree point queries, OpenMP over queries).
 *   V     in: #V*3 mesh positions
 *   F     in: #F*3 triangles
 *   Q     in: #Q*3 query points (#Q = n_queries)
 *   tri   out: #Q closest triangle; may be NULL
 *   bary  out: #Q*3 its barycentrics; may be NULL
 *   dist  out: #Q distance (mesh units); may be NULL
 * Errors: KM_ERR_DEGENERATE_MESH (no faces), KM_ERR_UNSUPPORTED when Embree cannot start. */
km_status km_point_mesh_distance(const double *V, size_t n_vertices, const int32_t *F,
                                 size_t n_faces, const double *Q, size_t n_queries, int32_t *tri,
                                 double *bary, double *dist, km_error *err);

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
                            * LBS weights (km_skeleton_from_weights), as Park & Lim do; true:
                            * the template rig's joint positions as they are */
  km_progress progress;
  /* ---- two-sided error (surface -> points) and unsupported surface */
  double unsupported_distance; /* m: a template vertex farther than this from every point of
                                * its frame is unsupported; 0: 0.03 */
  double unsupported_fraction; /* a frame whose unsupported vertices exceed this fraction of
                                * the vertices measured is flagged; 0: 0.02 */
  const double *cameras;       /* n_cameras*3 camera centres in the points' frame (metres), or
                                * NULL: visibility unknown, every vertex is measured. Given,
                                * only vertices whose normal faces a camera are measured (no
                                * occlusion test: a vertex the body hides from every camera
                                * still counts). Borrowed: must outlive the reconstructor. */
  size_t n_cameras;
  /* ---- limbs found, not assumed */
  bool no_limb_search;       /* true: skip the first frame's limb search (see km_recon_init) */
  bool no_surface_to_points; /* true: the surface refinement uses points -> surface only (no
                              * pull of unclaimed template surface towards its nearest point) */
  /* ---- issue 16: how km_reconstruct writes out_anim (export kind, skin fit); NULL: per-frame
   * morphs at 30 fps. fps 0 in it: 30. Borrowed for the call. */
  const km_anim_options *anim;
  /* ---- issue 11: the frame of km_reconstruct's point cloud files (their up and forward axes
   * and units), brought into kinemesh's (y up, facing +z, metres) as each file is read; NULL:
   * already in it. Borrowed for the call. */
  const km_frame *points_frame;
} km_recon_options;

/* A user-given feature correspondence: template vertex <-> point position (first frame). */
typedef struct km_recon_feature {
  int32_t vertex;
  double point[3];
} km_recon_feature;

#define KM_RECON_MAX_PARTS 8 /* body parts named per unsupported frame */
typedef struct km_recon_frame_stats {
  size_t index;
  size_t points;  /* finite points used */
  size_t dropped; /* points dropped: NaN/inf, or exactly (0, 0, 0) (no sensor return) */
  double mean_mm; /* mean distance points -> reconstructed surface */
  double max_mm;
  int iterations; /* solver iterations (skeleton L-BFGS + surface) */
  double seconds;
  km_status status;  /* KM_OK, or why the frame was carried by the skeleton */
  char message[512]; /* status != KM_OK: what went wrong (a read error names the file) */
  /* ---- two-sided error. mean_mm/max_mm above measure points -> surface only: surface no
   * point supports (a limb left behind) is invisible to them. These measure the registered
   * (unfiltered) surface km_recon_surface. */
  double p95_mm;          /* points -> surface, 95th percentile */
  double surface_mean_mm; /* surface -> points: each measured template vertex to its nearest
                           * point of the frame; mean, 95th percentile, max */
  double surface_p95_mm;
  double surface_max_mm;
  size_t surface_vertices;     /* vertices measured: all (no cameras given) or those facing a
                                * camera (km_recon_options.cameras) */
  size_t unsupported_vertices; /* measured vertices farther than unsupported_distance from
                                * every point */
  bool unsupported;            /* unsupported_vertices > unsupported_fraction * surface_vertices:
                                * the report's status "unsupported_surface" */
  int n_unsupported_joints;    /* entries of unsupported_joints */
  int32_t
      unsupported_joints[KM_RECON_MAX_PARTS]; /* the body parts concerned: skin joints
                                               * (each vertex's largest weight) holding at least a
                                               * tenth of the unsupported vertices, most first */
  double surface_p99_mm;                      /* surface -> points, 99th percentile */
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
  /* ---- limbs found, not assumed: after the skeletal step each limb chain's first two
   * joints (shoulder then elbow, hip then knee: joints below a branching joint whose subtree
   * is a simple chain of >= 3) are turned to the best of 160 bone directions, scored
   * two-sided (limb vertices to points, unexplained points to the limb), then the skeletal
   * step runs again. The joints turned (a direction is kept only below the current score
   * and where it lowers the whole body's two-sided residual, or raises it < 5% when the
   * limb's score drops > 10%; each chain is also tried from its second joint at the
   * template's bend, the better start kept): */
  size_t limbs_turned;
  /* ---- bone lengths: then each limb chain's three segments (upper arm, forearm, hand;
   * thigh, shin, foot) are stretched along their bones in the template by the best scale of
   * 0.8..1.25 (coordinate descent, the same two-sided score), kept only where the limb's
   * score drops below 97%; the skeletal step runs again. The limbs stretched: */
  size_t limbs_scaled;
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
  /* ---- two-sided error */
  bool visibility_known;          /* cameras were given: surface -> points over the vertices
                                   * facing one; else over all vertices */
  size_t still_vertices;          /* template vertices with no skin influence (a ground plane
                                   * km_autorig left out of the skin): kept where the template
                                   * has them in every frame and left out of surface -> points */
  double unsupported_distance_mm; /* the thresholds used */
  double unsupported_fraction;
  size_t unsupported_frames;    /* frames flagged "unsupported_surface" */
  int32_t **unsupported;        /* n_frames (km_reconstruct; may be NULL): per frame the ids
                                 * of its unsupported vertices, frames[f].unsupported_vertices
                                 * of them (NULL when none) */
  km_anim_report export_report; /* what km_reconstruct's writer wrote (issue 16) */
} km_recon_report;
/* Frees frames, joints, joint_names and unsupported of r and zeroes the struct. */
void km_recon_report_free(km_recon_report *r);
/* ---- two-sided error: frame status and unsupported vertices */
/* A frame's status as the report writes it: "unsupported_surface" for a frame that is
 * otherwise KM_OK but flagged (s->unsupported), else km_status_name(s->status). Static. */
const char *km_recon_frame_status(const km_recon_frame_stats *s);

/* Writes a report as JSON, atomically:
 * {"format":"kinemesh-recon-report","version":1,"frames":[{"index":..,"points":..,
 * "mean_mm":..,"max_mm":..,"iterations":..,"seconds":..,"status":"KM_OK",
 * "message":".." (failed frames only), "joints":[x,y,z,...], and the two-sided error:
 * "p95_mm", "surface_mean_mm", "surface_p95_mm", "surface_p99_mm", "surface_max_mm",
 * "surface_vertices", "unsupported_vertices", "unsupported_joints":[names],
 * "unsupported_ids":[vertex ids] (when report->unsupported has them); a flagged frame has
 * "status":"unsupported_surface"}...], "surface_to_points": "all vertices (visibility
 * unknown)"|"vertices facing a camera", "still_vertices" (km_recon_report.still_vertices),
 * "unsupported_distance_mm", "unsupported_fraction",
 * "unsupported_frames", "jerk_before":.., "jerk_after":.., "first_frame": {"correspondences": N,
 * "initialisation": "...", and without correspondences "yaw_candidates", "yaw_deg", "rotation_deg",
 * "rigid_residual_mm", "residual_mm", "feet_residual_mm", "scale", "landmarks"; and "limbs_turned",
 * "limbs_scaled"}, "joints_from": "skin weights"|"rig"}. r  in: report (km_reconstruct) Errors:
 * KM_ERR_IO. */
km_status km_recon_report_write_json(const char *path, const km_recon_report *r, km_error *err);

/* Incremental reconstructor: create with the template (mesh, skeleton, skin), register the
 * first frame with features, then feed the following frames one at a time. */
typedef struct km_recon km_recon;
/* Prepares the template.
 *   template_character  in: mesh (#V vertices), skeleton (#J joints), skin, landmarks;
 *                       copied
 *   opt                 in: may be NULL (defaults)
 *   out                 out: allocated; free with km_recon_free */
km_status km_recon_create(const km_character *template_character, const km_recon_options *opt,
                          km_recon **out, km_error *err);
/* Registers the first frame. Global alignment (Horn, rigid) from the features; the skeletal
 * step posed by the features, then the least-squares scale and rotation again against the
 * posed landmarks; then affine registration with w_d = 0 and then with all three terms.
 * With fewer than 3 features the subject is assumed upright (y up) but may face any way:
 * see km_recon_init; the pose comes from the data, and the template's landmarks (those of
 * the character given to km_recon_create that have a name) matched to their closest points
 * stand in for the features of the w_d = 0 stage.
 *   P         in: n*3 points (non-finite points are dropped)
 *   features  in: n_features correspondences; may be NULL when n_features == 0
 *   stats     out: may be NULL
 * Errors: KM_ERR_DEGENERATE_MESH, KM_ERR_NOT_POSDEF, KM_ERR_NO_CONVERGENCE. */
km_status km_recon_first_frame(km_recon *r, const double *P, size_t n,
                               const km_recon_feature *features, size_t n_features,
                               km_recon_frame_stats *stats, km_error *err);
/* Registers the next frame: skeletal motion (L-BFGS) then surface refinement. A frame that
 * fails is carried by the skeleton prediction: the call still returns KM_OK with
 * stats->status and stats->message set (err is only filled when the call itself fails).
 *   P      in: n*3 points
 *   stats  out: may be NULL */
km_status km_recon_next_frame(km_recon *r, const double *P, size_t n, km_recon_frame_stats *stats,
                              km_error *err);
/* Results of the last frame, owned by r and valid until the next call:
 *   surface   #V*3 refined surface
 *   global    #V*3 LBS-only (global motion) surface
 *   joints    #J*3 joint positions
 *   template  the template mesh (its faces are those of the output) */
const double *km_recon_surface(const km_recon *r);
const double *km_recon_global(const km_recon *r);
const double *km_recon_joints(const km_recon *r);
const km_mesh *km_recon_template(const km_recon *r); /* faces of the output */
/* How the first frame was initialised.
 *   out  out: filled (zeros before the first frame) */
void km_recon_init_get(const km_recon *r, km_recon_init *out);
/* ---- two-sided error: the unsupported vertices of the last registered frame (see
 * km_recon_frame_stats).
 *   count  out: how many (stats.unsupported_vertices); may be NULL
 * Returns their ids, owned by r, valid until the next frame (NULL before the first). */
const int32_t *km_recon_unsupported(const km_recon *r, size_t *count);
/* Frees *r and sets it to NULL. */
void km_recon_free(km_recon **r);
/* Non-rigid registration of a mesh onto another surface: the first frame's surface stage
 * (per-vertex affine maps under data + feature + smoothness terms, robust closest points,
 * coarse points first) with the target's vertices as the points. For pose transfer across
 * connectivity (kinemesh transfer --template-rest): the source's rest, already placed on the
 * target by a similarity, is pulled onto the target's rest.
 *   source      in: the mesh's faces (#V vertices; its V is not used)
 *   V_start     in: #V*3 start positions, near the target (metres)
 *   target      in: the surface to reach (its vertices are the points; >= 16)
 *   features    in: n_features source vertex <-> target point pairs; may be NULL when 0
 *   iterations  in: closest-point rounds; <= 0: 12
 *   V_out       out: #V*3 registered positions; may alias V_start
 * Errors: KM_ERR_DEGENERATE_MESH, KM_ERR_NOT_POSDEF, KM_ERR_INVALID, KM_ERR_UNSUPPORTED (no
 * Embree). */
km_status km_recon_register_mesh(const km_mesh *source, const double *V_start,
                                 const km_mesh *target, const km_recon_feature *features,
                                 size_t n_features, int iterations, double *V_out, km_error *err);

/* Local-motion filter (Park & Lim 2014, section IV-3C):
 * out_t = global_t + sum_k g_k (refined - global)_{t+k}, Gaussian weights over |k| <= radius
 * renormalised at the sequence ends.
 *   refined  in: n_frames * #V*3 refined surfaces
 *   global   in: n_frames * #V*3 LBS-only surfaces
 *   radius   in: half width in frames; sigma in frames
 *   out      out: n_frames * #V*3; may alias refined */
km_status km_local_motion_filter(size_t n_frames, size_t n_vertices, const double *refined,
                                 const double *global, int radius, double sigma, double *out,
                                 km_error *err);

/* Whole pipeline: reads frames, reconstructs, filters and streams frames to out_anim with a
 * delay of filter_radius frames, so a failure late in the run never loses finished frames.
 *   frame_paths         in: n_frames point cloud files (km_points_read), in order
 *   template_character  in: as km_recon_create
 *   features            in: n_features first-frame correspondences; may be NULL
 *   opt                 in: may be NULL (defaults)
 *   out_anim            in: output for km_anim_writer (.glb, .pc2 or a directory)
 *   report              out: may be NULL; allocated contents, free with
 *                       km_recon_report_free
 * Errors: KM_ERR_IO (output), the first frame's errors, KM_ERR_CANCELLED. */
km_status km_reconstruct(const char *const *frame_paths, size_t n_frames,
                         const km_character *template_character, const km_recon_feature *features,
                         size_t n_features, const km_recon_options *opt, const char *out_anim,
                         km_recon_report *report, km_error *err);

/* ==== autorig: automatic rigging of a mesh kinemesh did not make (src/autorig/) ==== */

/* Embeds a Kinect v1 skeleton in a mesh, computes skin weights and the 16 named landmarks,
 * so that km_character_write_rig can write its sidecar (skeleton, skin, landmarks and the
 * default puppetry rig: handles at the head, the hand_* and foot_* landmarks).
 *
 * Method. The mesh is taken as y up, facing +z (left = +x), height = its y extent H.
 * Extremities are geodesic extremes: starting from the vertex nearest the vertex centroid,
 * repeatedly the vertex farthest along mesh edges (Dijkstra) from the root and from every
 * extremity found so far, while that distance exceeds min_extremity * the largest bbox
 * extent, keeping only tips (the farthest vertex from the root within 0.05 of that extent
 * along the surface; a blob has one). A humanoid's roles: the two lowest extremities of
 * distinct limbs are the feet (a heel beside its toes is one limb), the most prominent above
 * mid-height near the feet's mid-line the head top, the hand tips as below. Its torso and leg
 * joints are centroids of thin horizontal slices at height-normalised levels (fractions of
 * H measured on the procedural character), each the centroid of the longest contour the
 * plane cuts near the torso or on that leg's side (so a hand or a trunk the plane also cuts
 * is left out); short legs or low arms (where the feet's geodesics part, where an arm's
 * ring near its root is) lower the hips or the shoulders and the joints between follow.
 * Hands: the extremity on each side maximising limb length * (1 - t), t being where along
 * the head-to-foot path its geodesics part (an arm beats an ear or a horn), among those off
 * the mid-line joining below the top, else those that are not a second tip of a foot, join
 * the body above the legs' middle and do not reach back 0.2 H behind the feet (a tail), else
 * any. Arm joints are
 * centroids of geodesic rings (vertices at one geodesic distance from the hand tip) at
 * proportional distances between the tip and the shoulder, which follows the arm whatever
 * its pose. Those centroids lie inside tubular parts. A non-humanoid (quadruped):
 * the four lowest extremities are its limbs, split front/hind along the feet's principal
 * horizontal axis (front = towards the head) and left/right across it; the highest other
 * extremity ahead of the feet (+z) is the head (a raised tail is not). Auto takes a mesh for
 * a quadruped when three or more distinct extremities lie within 0.1 H of the ground, not
 * counting one at the back end (0.1 of the z extent) that lies on the mid-line or 0.025 H
 * above the ground (a resting tail). Front limbs take the Kinect arm joints (HandLeft/Right at the
 * tips), hind limbs the leg joints, the head Head; limb joints are geodesic ring centroids,
 * the spine runs between the hind and front limb roots at the centroid's height. A prop (a
 * bust, an object; what auto falls back to when neither fits, the reason in the report):
 * the highest vertex drives Head, the outermost upper vertex on each side HandLeft /
 * HandRight, the lowest outer one on each side FootLeft / FootRight (each at least 0.2 H
 * along the surface from the others), the joints on straight lines from the centroid.
 * Last, a humanoid's or quadruped's joints are checked against the surface (the parity of
 * three rays' crossings, by majority): one outside moves in, a leaf (head, hand, foot) back
 * along its bone to the second of 32 steps inside, another to the middle of the chord through
 * the body along the line to its nearest vertex; one more than 0.03 H outside or whose way in
 * is longer than 0.05 H (0.15 H for a leaf) stays, named in the report (joints_outside).
 * Skin (skin = KM_AUTORIG_SKIN_HEAT, the default): bone heat (Baran & Popovic 2007). Each
 * bone is a segment from a joint to its child, weighting that joint (leaf joints reaching to
 * their extremity). Joint j's weights w_j solve (-L + M H) w_j = M H p_j on the surface (L the
 * cotangent Laplacian, M the Voronoi areas), H = 1/d^2 at a vertex whose nearest bone (among
 * its four nearest joints' bones, nearest first) it sees (the segment to the bone's closest
 * point crosses no face), p_j = 1 there for that joint (shared at a tie), H = 1e-4/d^2 (its
 * nearest bone's) at a vertex that sees none; the weights diffuse along the surface, so a part near
 * a bone in space but far from it along the skin (an ear beside a raised hand, a shell beside a
 * shoulder) follows where it joins the body. Kept: the 4 largest less the 5th (continuous where two
 * swap), summing to
 * 1. One CHOLMOD factorisation, one solve of 20 right-hand sides. KM_AUTORIG_SKIN_DISTANCE:
 * every vertex is weighted on the bones nearest to it, w = (1 - (d - dmin) / band)^2 within
 * band = 0.06 H of the nearest, at most 4 influences, summing to 1. KM_AUTORIG_SKIN_REACH: each
 * bone's distance w also multiplied by its reach along the surface: 1 within band (along the
 * edges, Dijkstra) of the bone's own patch (the largest connected group of vertices nearest to
 * it), falling smoothly to 0 at 4 band. Landmarks: the surface vertex hit by a
 * ray from a joint (forward, up or sideways, like the procedural character's), hands and feet at
 * their tips. Meshes it refuses: no faces, several components (each connected set of faces),
 * non-manifold edges (three or more faces), too few extremities for the requested skeleton (kinect1
 * or quadruped asked for), a surface too small for five separate handles. */
typedef enum km_autorig_skeleton {
  KM_AUTORIG_AUTO = 0,  /* a bust when it has a bust's cut or sits on a broad base (an upper
                           body when hands reach out from it); else humanoid or quadruped from
                           where the extremities are, else prop */
  KM_AUTORIG_KINECT1,   /* humanoid: Kinect v1 joints embedded in the body */
  KM_AUTORIG_QUADRUPED, /* four limbs and a head mapped onto the Kinect v1 joints */
  KM_AUTORIG_PROP,      /* an object: five handle points by position (below) */
  KM_AUTORIG_BUST,      /* a bust: an open cut at its bottom (a boundary loop within 0.06 of
                           the height of the lowest vertex, 0.3 of the width wide) or a closed
                           body sitting on a broad base (its faces within 0.05 of the height of
                           the lowest vertex one part, at least 0.5 of the mesh's width and
                           depth: a sitting rabbit, a figure on a plinth); the Kinect
                           v1 joints placed in its neck, head and shoulders (arms and legs
                           folded into the shoulders and the base); the rig sidecar's handles:
                           the head, turning with the neck, and the base, held still */
  KM_AUTORIG_UPPER,     /* an upper body: a bust's base (either kind) with a hand reaching
                           out on either side (an extremity 0.2 of the height above the base,
                           farther from its middle than twice its width: a VR avatar or a
                           T-posed character cut at the waist); torso, neck and head as a
                           bust's, arms along rings from the hand tips as a humanoid's, legs
                           folded into the base; the sidecar's handles: head, hands and arm
                           bands, chest, and the base, held still */
  KM_AUTORIG_RESTING    /* a body lying or curled up (asked for: never chosen automatically):
                           a cat asleep on its side or curled up, a person lying down; the
                           Kinect v1 joints along the geodesic rings from the head's tip
                           (km_autorig_options.head), the neck at the narrowest ring past the
                           skull's widest, arms and legs folded into the shoulders and hips;
                           the sidecar's handles: the head, turning with the neck, and the
                           body behind the shoulders, held still */
} km_autorig_skeleton;

#define KM_AUTORIG_MAX_EXTREMITIES 16
/* How km_autorig weights the skin (see km_autorig). */
typedef enum km_autorig_skin {
  /* bone heat for every kind of body. bench motion --skin (L: the rig's skeleton posed by the
   * take skinning the mesh), worst edge over the 5 takes, before (distance for a humanoid,
   * reach for a quadruped) -> heat: armadillo 55-92x -> 3.4-5.1x, elephant 16-18x -> 1.5-1.7x,
   * FAUST tr_reg_000 10-14x -> 2.0-5.6x, horse 1.9-2.6x -> 1.5-2.1x, the walking cat (cat-03)
   * 1.7-2.2x -> 1.4-1.6x with no fold; the procedural character 2.3-3.1x -> 1.7-2.1x but a bent
   * knee's back collapses (folds 0-125 -> 105-321), SMPL's npt_14_664 3.2-4.9x -> 3.5-5.6x */
  KM_AUTORIG_SKIN_AUTO = 0,
  KM_AUTORIG_SKIN_DISTANCE, /* distance to the bones in space, within a 0.06 H band */
  KM_AUTORIG_SKIN_REACH,    /* the same, limited by each bone's reach along the surface */
  KM_AUTORIG_SKIN_HEAT      /* bone heat (Baran & Popovic 2007): diffused along the surface from
                               each vertex's nearest visible bone */
} km_autorig_skin;

typedef struct km_autorig_options {
  km_autorig_skeleton skeleton; /* 0: auto */
  km_autorig_skin skin;         /* 0: auto (bone heat) */
  double min_extremity; /* extremity prominence, fraction of the largest bbox extent; 0: 0.2 */
  size_t
      max_extremities; /* most extremities sought; 0: KM_AUTORIG_MAX_EXTREMITIES (also the cap) */
  /* The skeleton when it is known (a generated character's, or one placed by hand): the 20
   * Kinect v1 joints' rest positions (20*3, km_kinect1_joint_name order), which replace the
   * embedded ones; the extremities are still found (the leaf bones reach to them), and the
   * skin and landmarks are computed around these joints. NULL: embedded. */
  const double *joints;
  /* KM_AUTORIG_RESTING: the vertex at the tip of the head (an ear tip, the top of a skull, a
   * snout: kinemesh pick finds ids). NULL: the most prominent extremity. */
  const int32_t *head;
  km_progress progress;
} km_autorig_options;

/* What km_autorig chose (the library never prints: the caller reports it). */
typedef struct km_autorig_report {
  km_autorig_skeleton kind; /* KM_AUTORIG_KINECT1 (humanoid), _QUADRUPED, _PROP, _BUST, _UPPER,
                               _RESTING */
  size_t n_extremities;
  int32_t extremity[KM_AUTORIG_MAX_EXTREMITIES];         /* vertex ids, most prominent first */
  double extremity_distance[KM_AUTORIG_MAX_EXTREMITIES]; /* geodesic prominence, metres */
  /* Role of each extremity: the Kinect joint it drives ("Head", "HandLeft", ...) or "" */
  char role[KM_AUTORIG_MAX_EXTREMITIES][16];
  double height;  /* y extent of the mesh */
  double seconds; /* wall time */
  /* auto: why the humanoid or quadruped rig failed when the mesh was rigged as a prop
   * instead ("" otherwise) */
  char fallback[256];
  km_autorig_skin skin; /* the weights written: KM_AUTORIG_SKIN_DISTANCE or _REACH */
  /* Bone heat: the heat constant c written (H = c / d^2: 1, Baran & Popovic's, or 0.5,
   * smoother, kept when its score is more than 4 % lower) and each one's probe score: the mean
   * over heat_probe_poses probe poses of the rig's own skeleton (13; 24 for a quadruped, bent
   * as far as its rig lets a take bend it) of the skin's worst edge l/l0 (0: not tried). */
  double heat_c;
  double heat_probe[2]; /* c = 1, c = 0.5 */
  int heat_probe_poses;
  /* Joints the embedding left outside the surface and moved in (humanoid and quadruped: a leaf
   * back along its bone, another to the middle of the chord through the nearest part) */
  int joints_moved_inside;
  uint32_t joints_outside; /* bit j set: joint j (KM_KINECT1 order) is still outside, too far
                              from the body part it should be in to move it safely */
  /* Small loose pieces (eyes, teeth, buckles: each at most a quarter of the largest piece's
   * vertices) rigged to follow the body, the largest piece: how many, and their vertices in
   * all (0, 0: one piece); rigid_pieces: those that turn rigidly with one body vertex (see
   * km_mesh_info.rigid_pieces); ground_pieces: those lying on the floor (a ground plane, a
   * plinth: km_mesh_info.ground_pieces), whose vertices the skin leaves without influence, so
   * they stay where they are */
  size_t loose_pieces, loose_vertices, rigid_pieces, ground_pieces;
} km_autorig_report;

/* The kind's name: "humanoid" (KM_AUTORIG_KINECT1), "quadruped", "prop", "bust", "upper body"
 * (KM_AUTORIG_UPPER); "auto" for KM_AUTORIG_AUTO; "unknown" otherwise. */
const char *km_autorig_kind_name(km_autorig_skeleton kind);

/* Rigs a mesh.
 *   m       in: triangle mesh, #V vertices, #F faces (manifold edges; one piece, or a body
 *           with small loose pieces that follow it: report->loose_pieces)
 *   opt     in: may be NULL (defaults)
 *   out     out: a character: mesh (a copy of m, vertex order kept), skeleton (the 20 Kinect
 *           v1 joints), skin (#V vertices; a loose piece lying on the floor with no
 *           influence, so it stays: m in kinemesh's frame, y up) and 16 landmarks; free with
 *           km_character_free
 *   report  out: what was chosen; may be NULL
 * Errors: KM_ERR_DEGENERATE_MESH naming what is wrong (no faces, N components of which two
 * are comparable, N non-manifold edges, zero height, too few extremities, too small for five
 * handles);
 * KM_ERR_NOMEM; KM_ERR_CANCELLED. */
km_status km_autorig(const km_mesh *m, const km_autorig_options *opt, km_character *out,
                     km_autorig_report *report, km_error *err);

/* ---- a skinned glTF's own rig */

/* What km_character_from_skin took from the file. */
typedef struct km_skin_mapping {
  /* For each Kinect v1 joint (km_kinect1_joint_name order): the file's joint placed there,
   * "" where the position was derived (Spine without a joint between hips and neck, a hand
   * or foot end without its own joint). */
  char source[KM_KINECT1_JOINTS][64];
  size_t n_merged; /* the file's joints whose weights went to a mapped ancestor's joint */
  size_t n_still;  /* vertices weighted only to joints above the hips (the armature's root: a
                      ground plane) or to none: left with no influence, they stay */
} km_skin_mapping;

/* A rigged template from a mesh's own skin (a skinned glTF, km_mesh_read_skinned): the 20
 * Kinect v1 joints placed at the file's joints, the file's weights summed onto them, the 16
 * landmarks placed as km_autorig places them. Joint names are matched after dropping any
 * "namespace:" prefix (mixamorig:), a DEF-/ORG-/J_Bip_ prefix, case and punctuation, with the
 * side from a Left/Right/L_/R_ prefix or a .L/_L/.R/_R suffix: upper arm (Mixamo Arm, VRM /
 * Unity UpperArm, rigify upper_arm) -> Shoulder, ForeArm / LowerArm / forearm -> Elbow, Hand ->
 * Wrist, HandMiddle1 / MiddleProximal / f_middle.01 -> Hand (else the mean of the wrist's
 * children, else 0.3 forearm past the wrist), UpLeg / UpperLeg / thigh -> Hip, Leg / LowerLeg
 * / shin -> Knee, Foot -> Ankle, ToeBase / Toes / toe -> Foot (else the ankle's first child),
 * Head -> Head. HipCenter is the joint both legs hang from, ShoulderCenter the Neck (else the
 * joint both arms hang from), Spine the joint between them nearest 48% of the way up (every
 * joint between them weights it). Every other joint (fingers, clavicles, twist bones, toes'
 * ends) gives its weights to its nearest mapped ancestor's joint (none: HipCenter); each vertex
 * keeps its 4 largest sums, normalised. A joint above the hips (the armature's root) gives
 * none: a vertex weighted only to such joints (a ground plane bound to the root, as
 * km_anim_writer's skeleton export binds a vertex with no influence), or to no joint at all,
 * gets no influence and stays (map->n_still counts them); a vertex with some weight below the
 * hips keeps only that.
 *   m    in: the mesh as read with the skin (#V vertices)
 *   s    in: its skin (s->n_vertices == #V)
 *   out  out: mesh (a copy of m), skeleton (20 Kinect v1 joints), skin, landmarks, as
 *        km_autorig makes; free with km_character_free
 *   map  out: which joint went where; may be NULL
 * Errors: KM_ERR_INVALID (no skin, vertex counts differ), KM_ERR_UNSUPPORTED naming the
 * limbs no joint name matched and listing the file's joints; KM_ERR_NOMEM. */
km_status km_character_from_skin(const km_mesh *m, const km_mesh_skin *s, km_character *out,
                                 km_skin_mapping *map, km_error *err);

/* ==== synth: character, generated motion, pose presets, capture (src/synth/) ==== */

/* ---- procedural character */

typedef struct km_character_options {
  size_t target_vertices; /* 0: 20000. Output within +-10%. 2,000 .. 1,000,000 */
  uint64_t seed;          /* small per-subject variation of proportions; 0 is valid */
  double height;          /* metres; 0: 1.75 */
  double girth;           /* limb thickness factor; 0: 1.0 */
  double belly;           /* belly size factor; 0: 0 (none), 1: pronounced */
  km_progress progress;
} km_character_options;

/* Generates a humanoid as an implicit surface around a skeleton, polygonised so that its
 * vertex count is target_vertices +-10%. Equal options (shape, seed) give equal meshes.
 * All subjects of one target_vertices SHARE CONNECTIVITY (same F, same vertex count and
 * order, same landmark vertex ids): the canonical subject (seed 0, height 1.75, girth 1,
 * belly 0) is polygonised at that resolution and every other shape is obtained by carrying
 * its vertices to the new skeleton's primitives (bone lengths, offsets, radii), projecting
 * them onto the new implicit surface (Newton steps along the field gradient) and relaxing
 * them tangentially, in a few steps through intermediate bodies. Skeleton and skin are the
 * new subject's. Costs about twice a direct polygonisation.
 *   opt  in: may be NULL (defaults)
 *   out  out: allocated mesh, skeleton (20 Kinect v1 joints), skin and 16 landmarks; free
 *        with km_character_free
 * Errors: KM_ERR_CANCELLED. */
km_status km_character_generate(const km_character_options *opt, km_character *out, km_error *err);

/* ---- generated motion */

typedef enum km_motion_kind { KM_MOTION_WALK = 0, KM_MOTION_WAVE, KM_MOTION_KUNGFU } km_motion_kind;
/* A take of the 20 Kinect v1 joints at 30 Hz. Deterministic. Like a tracked performer it
 * starts in the rest (T) pose — the calibration pose puppetry measures displacements from —
 * holds it 0.2 s and blends into the motion over the next 0.5 s.
 *   s       in: the character's rest skeleton (20 Kinect v1 joints)
 *   frames  in: >= 1
 *   out     out: allocated take (frames x 20 joints); free with km_take_free */
km_status km_motion_generate(const km_skeleton *s, km_motion_kind kind, size_t frames, km_take *out,
                             km_error *err);

/* ---- pose presets */

/* The built-in pose set: KM_POSE_PRESETS named joint-angle poses (t_pose, a_pose, arms_up,
 * squat, ...) of the Kinect v1 skeleton, each up to KM_POSE_PRESET_MAX_ROTATIONS joint
 * rotations. Ground truth for pose-transfer tests and benchmarks. */
#define KM_POSE_PRESETS 10
#define KM_POSE_PRESET_MAX_ROTATIONS 8
/* Returns the name of preset p (static string; NULL when out of range). */
const char *km_pose_preset_name(int p);
/* Character c in preset p by forward kinematics and km_lbs.
 *   c       in: character (km_character_generate)
 *   p       in: 0 .. KM_POSE_PRESETS-1
 *   jitter  in: NULL, or KM_POSE_PRESET_MAX_ROTATIONS factors; rotation k's angle is scaled
 *           by 1+jitter[k]
 *   V       out: #V*3 posed positions */
km_status km_character_pose_preset(const km_character *c, int p, const double *jitter, double *V,
                                   km_error *err);

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
/* Poses a character by a take (km_skeleton_pose_from_positions + km_lbs), ray-casts every
 * frame from depth cameras on a ring (Embree) and writes out_dir/frame_00000.ply ... plus
 * out_dir/truth.pc2 (the posed meshes) and out_dir/truth_rest.obj (c->mesh, whose faces give
 * truth.pc2 its connectivity; OBJ so that listing the frames, by directory or by a glob of
 * its .ply files, never picks it up).
 *   c        in: character whose skeleton matches the take's joints
 *   take     in: motion
 *   opt      in: may be NULL (defaults)
 *   out_dir  in: created if missing
 * Errors: KM_ERR_IO, KM_ERR_CANCELLED. */
km_status km_capture_simulate(const km_character *c, const km_take *take,
                              const km_capture_options *opt, const char *out_dir, km_error *err);

#ifdef __cplusplus
}
#endif
#endif /* KINEMESH_H */
