/* Shared pieces of the kinemesh command-line tool. The CLI is a thin layer: it parses
 * options, calls the library, and turns km_error / progress into terminal output. */
#ifndef KM_CLI_H
#define KM_CLI_H

#include "kinemesh.h"

#include <cjson/cJSON.h>
#include <stdio.h>

typedef struct km_cli_verb {
  const char *name;
  const char *summary;
  int (*run)(int argc, char **argv); /* argv[0] is the verb */
} km_cli_verb;

typedef enum km_cli_kind {
  KM_OPT_STRING,
  KM_OPT_INT,
  KM_OPT_SIZE,
  KM_OPT_DOUBLE,
  KM_OPT_FLAG
} km_cli_kind;

typedef struct km_cli_opt {
  const char *name; /* long name without dashes, e.g. "vertices" */
  char short_name;  /* 0 when none */
  km_cli_kind kind;
  void *dst; /* const char **, int *, size_t *, double *, bool * */
  const char *help;
} km_cli_opt;

/* Parses argv[1..] into opts; positional arguments go into pos (at most max_pos, count in
 * *n_pos). Prints usage and returns 0 for --help, returns -1 after printing an error,
 * 1 when parsing succeeded. `usage` is the one-line synopsis. */
int km_cli_parse(int argc, char **argv, const km_cli_opt *opts, size_t n_opts, const char **pos,
                 int max_pos, int *n_pos, const char *usage, const char *description);

/* Prints "kinemesh <verb>: <message>" for a library error and returns the exit status 1. */
int km_cli_fail(const char *verb, const km_error *err);
/* Same for a message of the CLI itself. Returns 1 (2 for usage errors). */
int km_cli_error(const char *verb, const char *fmt, ...);

void km_cli_install_logger(void);

/* OpenBLAS on the calling thread only (km_blas_threads(1)) unless OPENBLAS_NUM_THREADS is set:
 * for verbs that factorise many times and run OpenMP loops of their own (reconstruct), where
 * OpenBLAS's spinning idle threads took about half the CPU time. */
void km_cli_serial_blas(void);

/* Monotonic seconds, for the timing lines verbs print. */
double km_cli_now(void);

/* "char.obj" -> "char.rig.json": the rig sidecar next to a mesh. Caller frees. */
char *km_cli_rig_path(const char *mesh_path);

/* A progress reporter for long operations: a bar on a terminal, plain lines otherwise. */
km_progress km_cli_progress(const char *label);
void km_cli_progress_done(void);

/* ---- orientation: one option set for every verb that reads a mesh or a motion (issue 11) */
typedef struct km_cli_frame_opts {
  const char *up, *forward;               /* "+x" ... "-z"; NULL: guessed from the mesh */
  const char *units;                      /* m, cm, mm, in, ft, or metres per unit; NULL: metres */
  const char *motion_up, *motion_forward; /* the take's axes; NULL: y up, facing +z */
  const char *rig; /* the sidecar whose "frame" is used; NULL: <mesh stem>.rig.json */
  bool no_guess;   /* an axis neither given nor recorded is kinemesh's, not guessed */
} km_cli_frame_opts;
/* Entries for a verb's option array (a mesh's frame). */
/* clang-format off */
#define KM_CLI_FRAME_OPTIONS(fo)                                                                   \
  {"up", 0, KM_OPT_STRING, &(fo).up,                                                               \
   "the mesh's up axis: +x -x +y -y +z -z (default: guessed and printed)"},                        \
  {"forward", 0, KM_OPT_STRING, &(fo).forward,                                                     \
   "the axis the mesh faces (default: guessed and printed)"},                                      \
  {"units", 0, KM_OPT_STRING, &(fo).units,                                                         \
   "the mesh's units: m (default), cm, mm, in, ft, or metres per unit"}
/* Entries for verbs that read a take as well. */
#define KM_CLI_MOTION_FRAME_OPTIONS(fo)                                                            \
  {"motion-up", 0, KM_OPT_STRING, &(fo).motion_up, "the take's up axis (default +y)"},             \
  {"motion-forward", 0, KM_OPT_STRING, &(fo).motion_forward,                                       \
   "the axis the performer faces in the take (default +z)"}
/* clang-format on */
/* The frame the options say; with neither --up nor --forward, the "frame" object of the
 * mesh's rig sidecar (fo->rig, else <stem>.rig.json: {"up": "+z", "forward": "-y", "scale":
 * 0.01}, scale optional, metres per file unit) when it has one; the missing axes guessed from m
 * (printed on stderr in one line naming path, so the user can see and override it, unless quiet).
 * *guessed: whether any axis was guessed (may be NULL). Prints the error and returns non-zero
 * on a bad option. */
int km_cli_mesh_frame(const char *verb, const char *path, const km_cli_frame_opts *fo,
                      const km_mesh *m, bool quiet, km_frame *out, bool *guessed);
/* Metres per file unit that the mesh's rig sidecar (rig_path, else <mesh stem>.rig.json)
 * records in its "frame" ("scale"): the unit its joints were written in; 1 when it records
 * none (the joints are in the mesh file's own units). */
double km_cli_sidecar_scale(const char *mesh_path, const char *rig_path);
/* km_rig_read of a sidecar whose lengths are in another unit than m's: resolved on m scaled by
 * 1/k (k: m's metres per unit over the sidecar's, see km_cli_sidecar_scale), its joints then
 * scaled by k back to m's unit (animate, pose). */
km_status km_cli_rig_read_scaled(const char *path, const km_mesh *m, double k,
                                 const char *const *joint_names, size_t n_joint_names, km_rig *out,
                                 km_error *err);
/* km_cli_mesh_frame, then the mesh is brought into kinemesh's frame (y up, facing +z,
 * metres). Returns 0, or prints the error and returns an exit status. */
int km_cli_orient_mesh(const char *verb, const char *path, const km_cli_frame_opts *fo, km_mesh *m);
/* --keep-frame (animate, pose, reconstruct) is for a .pc2 or a frame directory: with keep and
 * a glTF output (.glb / .gltf) prints why not and returns an exit status; 0 otherwise. */
int km_cli_keep_frame_output(const char *verb, const char *out, bool keep);
/* The take's positions into kinemesh's frame by --motion-up/--motion-forward. */
int km_cli_orient_take(const char *verb, const km_cli_frame_opts *fo, km_take *t);
/* Reads the motion that drives the skeleton sk by joint name (pose, gen capture): for a
 * skeleton of the Kinect v1 joints (kinemesh rig, gen character, a mapped skinned glTF) the
 * take's columns by body point as km_motion_read's kinect1 option maps them (a CMU BVH's
 * LeftForeArm is ElbowLeft, ...), else as the file names them. Returns 0, or prints the error
 * and returns an exit status. */
int km_cli_read_motion_for(const char *verb, const char *path, const km_skeleton *sk, km_take *t);
/* map (sk->n_joints): each joint's column in t by exact name, -1 where the take has none.
 * None matched: prints an error naming the rig's joints and returns an exit status; some
 * missing: prints a warning naming them (they hold their rest pose) and returns 0. */
int km_cli_map_joints(const char *verb, const km_skeleton *sk, const km_take *t, int *map);
/* The frame named by options of data that is not a mesh (nothing to guess from): up (NULL:
 * +y), forward (NULL: +z, or -y for a z-up frame), units (NULL: metres); opt names the
 * options in messages ("motion": --motion-up ...). Returns 0, or prints the error and returns
 * an exit status. */
int km_cli_given_frame(const char *verb, const char *opt, const char *up, const char *forward,
                       const char *units, km_frame *out);

/* --OPT's units s (m, cm, mm, in, ft or metres per unit) into *scale (untouched when s is
 * NULL). Returns 0, or prints the error and returns an exit status. */
int km_cli_parse_units(const char *verb, const char *opt, const char *s, double *scale);
/* The deformation check in one line ("  shape: longest edge ...\n"; empty with no frame):
 * the longest and shortest edge against its rest length, the frames over 1.5x, the folds and
 * the largest one-frame step, with frames (from 0) and places: the nearest handle of rig, or a
 * vertex id when rig is NULL or has no handle. */
void km_cli_shape_line(const km_deform_check *dc, const km_mesh *m, const km_rig *rig, char *line,
                       size_t n);
/* The line saying what the handle targets force (forced > 1.5: km_stretch_bound's largest
 * over the take, in frame; pair: its two mesh vertices) and between which handles. */
void km_cli_forced_line(const km_mesh *m, const km_rig *rig, double forced, size_t frame,
                        const int32_t pair[2], char *line, size_t n);
/* A skinned frame grounded as an engine grounds a character: V (#V*3, y up) raised whole by
 * as far as its lowest vertex is under floor_y; returns that lift (0: none). Holding the low
 * vertices on the floor one by one, as animate does with its solved mesh's few, pressed a
 * skinned paw flat. pose and bench motion --skin (L) use it on the rig's floor. */
double km_cli_floor_lift(double *V, size_t nv, double floor_y);
/* The glitch rejector's counts in one line, as animate and pose print them; restarted: what
 * the caller did with the joints whose start was the glitch (their count follows), NULL to leave
 * them out. */
/* How loose pieces follow the body, after "... follow(s) the body": ", each turning rigidly
 * with the body point nearest to it", ", wrapping the body, bending with it" or a count of each;
 * and a newline. loose > 0, rigid <= loose. */
void km_cli_pieces_how(FILE *f, size_t loose, size_t rigid);
void km_cli_glitch_line(const km_glitch_stats *gs, const char *restarted, char *line, size_t n);

/* Exit codes */
#define KM_EXIT_OK 0
#define KM_EXIT_FAIL 1
#define KM_EXIT_USAGE 2
#define KM_EXIT_LIMITS 3 /* check: the animation exceeds a limit it was given */

int km_cli_info(int argc, char **argv);
int km_cli_convert(int argc, char **argv);
int km_cli_eigen(int argc, char **argv);
int km_cli_gen(int argc, char **argv);
int km_cli_pose(int argc, char **argv);
int km_cli_bake(int argc, char **argv);
int km_cli_precompute(int argc, char **argv);
int km_cli_animate(int argc, char **argv);
int km_cli_gen_capture(int argc, char **argv);
int km_cli_reconstruct(int argc, char **argv);
int km_cli_transfer(int argc, char **argv);
int km_cli_posedb(int argc, char **argv);
int km_cli_avatar(int argc, char **argv);
int km_cli_batch(int argc, char **argv);
/* A character: mesh + rig sidecar (default <stem>.rig.json), or the canonical procedural
 * one with `vertices` vertices when mesh is NULL. */
km_status km_cli_load_character(const char *mesh, const char *rig, size_t vertices, km_character *c,
                                km_error *err);
/* km_cli_load_character, then brought into kinemesh's frame as animate brings a mesh
 * (km_cli_mesh_frame: --up/--forward/--units, else the rig sidecar's "frame", else glTF's,
 * else guessed and printed). The mesh is rotated and scaled; a rig sidecar's joints are in
 * kinemesh's frame already (`rig` writes them so; `gen character`'s frame is kinemesh's), a
 * skinned glTF's own skeleton is turned with its mesh. The procedural character (mesh NULL)
 * is not turned. f: the frame applied (identity when none; may be NULL). Returns 0, or
 * prints the error and returns an exit status. */
int km_cli_load_character_oriented(const char *verb, const char *mesh, const char *rig,
                                   size_t vertices, const km_cli_frame_opts *fo, km_character *c,
                                   km_frame *f);
/* A skinned glTF's own skin as its rig (km_character_from_skin), when no rig is given and
 * <stem>.rig.json does not exist: *c (freed first) gets the mesh, skeleton, skin and landmarks,
 * the mapping is printed on stderr and *used is set. Otherwise *used is false, c untouched. */
km_status km_cli_skin_character(const char *verb, const char *mesh_path, const char *rig,
                                km_character *c, bool *used, km_error *err);
/* An end handle (head, hand, foot) of rig holding fewer than 5 vertices pulls a spike out of
 * the surface instead of carrying a part: the automatic rig took a body lying or curled up for
 * one standing. Writes one warning line per such handle to say ("kinemesh VERB: warning: ...",
 * naming mesh_path, the kind rigged and the up axis it stood the body along: up NULL when
 * that axis was printed just before, as the verbs that rig on the spot do). Returns how many
 * it warned of. */
size_t km_cli_warn_point_handles(const char *verb, const char *mesh_path, const km_rig *rig,
                                 const char *kind, const char *up, FILE *say);
/* A rig made on the spot for a mesh that has none (issue 11: a user's own mesh animates, poses
 * or serves as a template with no rig file): km_autorig on m (in kinemesh's frame), what it
 * chose printed in one line on `say` (stdout or stderr) with `then` after it (how to keep it;
 * NULL: "kinemesh rig MESH writes it, to edit"). Nothing is written. *c (freed first) gets the
 * character, json (NULL: not wanted) its rig sidecar's text (km_character_rig_json, made to warn
 * of point handles: km_cli_warn_point_handles; the caller frees it; NULL when it could not be
 * made, and the caller that needs it makes it, to say why). On failure err says that the mesh
 * has no rig at rig_file and why km_autorig refused it. */
km_status km_cli_auto_rig(const char *verb, const char *mesh_path, const char *rig_file,
                          const km_mesh *m, FILE *say, const char *then, km_character *c,
                          char **json, size_t *json_size, km_error *err);
int km_cli_live(int argc, char **argv);
int km_cli_vmc(int argc, char **argv);
int km_cli_rig(int argc, char **argv);
int km_cli_pick(int argc, char **argv);
int km_cli_check(int argc, char **argv);

/* Puppetry helpers shared by animate, bench and live. */
/* The default reduced-model cache of a mesh as read (and oriented): in the user's cache
 * folder, $XDG_CACHE_HOME/kinemesh/<km_mesh_hash>.kmcache, else ~/.cache/kinemesh/..., never
 * beside the input (which may be read-only or shared); the model parameters are recorded in
 * the file and checked on load. NULL when out of memory. Caller frees. */
char *km_cli_cache_path(const km_mesh *mesh);
/* Prints what the cache policy reported that the user must know: a stale cache rebuilt, a
 * cache not written. */
void km_cli_report_cache(const char *cache, const km_puppetry_info *info);
/* The reduced model (default parameters) by the cache policy with a progress bar for the
 * precompute, reported as above: what live mode's server takes. */
km_status km_cli_puppet_open(const km_mesh *mesh, const char *cache, km_puppet **out,
                             km_puppetry_info *info, km_error *err);
/* The whole file at path, '\0'-terminated (also a pipe); *size (may be NULL) its bytes. NULL
 * when unreadable (errno says why), out of memory (ENOMEM) or over 1 GiB (EFBIG). Caller
 * frees. */
char *km_cli_read_text(const char *path, size_t *size);
/* The file at path parsed as JSON; NULL when unreadable or not JSON. Caller cJSON_Deletes. */
cJSON *km_cli_read_json(const char *path);
double km_cli_median(double *v, size_t n); /* sorts v */
/* --energy laplacian|arap; prints the error and returns non-zero when unknown. */
int km_cli_parse_energy(const char *verb, const char *s, km_puppet_energy *e);
/* Adds v under key, or null when v is not finite (not measured): the benches' JSON. */
void km_cli_json_number(cJSON *o, const char *key, double v);
/* --frame-format obj|ply for directory outputs (NULL: from the path, obj for a directory);
 * prints the error and returns non-zero when unknown. */
int km_cli_parse_frame_format(const char *verb, const char *s, km_anim_format *f);
/* --filter holt|one_euro (animate, pose): sets o->kind, other fields kept; prints the error and
 * returns non-zero when unknown. */
int km_cli_parse_filter(const char *verb, const char *s, km_filter_options *o);

/* Issue 16: what a .glb holds. --export morphs[:all] (one morph target per frame, exact) or
 * skin[:BONES] (a fitted skinned mesh, km_ssdr_fit), and --max-error-mm (skin: bones are added
 * until the max error is below it), --compress (any kind: quantised + meshopt-encoded). */
#define KM_CLI_EXPORT_HELP                                                                         \
  "glb content: morphs[:all] (one target per frame, exact; default), morphs:K (K PCA basis "       \
  "targets + per-frame weights) or skin[:BONES] (skinned "                                         \
  "mesh + bone animation fitted by SSDR; plain skin: 32 bones grown to meet 15 mm)"
#define KM_CLI_EXPORT_OPTIONS(exp, max_mm, zip)                                                    \
  KM_CLI_EXPORT_OPTIONS_HELP(exp, max_mm, zip, KM_CLI_EXPORT_HELP)
/* the same with the --export help given (pose adds its skeleton export) */
#define KM_CLI_EXPORT_OPTIONS_HELP(exp, max_mm, zip, help)                                         \
  {"export", 0, KM_OPT_STRING, &(exp), help},                                                      \
      {"max-error-mm", 0, KM_OPT_DOUBLE, &(max_mm),                                                \
       "skin: split bones until the max error is below this (up to 4x BONES)"},                    \
  {                                                                                                \
    "compress", 0, KM_OPT_FLAG, &(zip),                                                            \
        "glb: KHR_mesh_quantization + EXT_meshopt_compression (engines and three.js with "         \
        "MeshoptDecoder read it; the printed error includes the quantisation)"                     \
  }
/* `--weights` of rig and the benches: NULL -> KM_AUTORIG_SKIN_AUTO (bone heat), "heat" ->
 * KM_AUTORIG_SKIN_HEAT, "distance" -> KM_AUTORIG_SKIN_DISTANCE, "reach" ->
 * KM_AUTORIG_SKIN_REACH; anything else prints an error naming the choices and returns
 * KM_EXIT_USAGE (0 otherwise). */
int km_cli_parse_weights(const char *verb, const char *s, km_autorig_skin *out);

/* Fills ao->export_kind / ao->skin (pointing at *ssdr, which must outlive ao) from --export
 * and --max-error-mm for output `out`; prints the error and returns non-zero when malformed
 * or when skin is asked for a non-.glb output. */
int km_cli_parse_export(const char *verb, const char *s, double max_error_mm, bool compress,
                        const char *out, km_anim_options *ao, km_ssdr_options *ssdr);
/* An animation that comes from a skinned character starts its skin fit from the character's
 * own parts: when ao asks for a skin with no bone count, ssdr->seed gets the weighted rest
 * centroid of every joint's skinned vertices (*seeds allocated, free() it). Returns non-zero
 * (error printed) when out of memory. */
int km_cli_skin_seeds(const char *verb, const km_anim_options *ao, const km_mesh *m,
                      const km_skin *skin, size_t n_joints, km_ssdr_options *ssdr, double **seeds);
/* "  skin: N bones, rms X mm, max Y mm (fit Z s)" on stderr for a skinned export; nothing
 * for an exact one. */
void km_cli_report_export(const char *verb, const km_anim_report *rep);

/* Prints root (then deletes it) as indented JSON on stdout; "kinemesh <verb>: out of memory"
 * and exit status 1 when it cannot. */
int km_cli_print_json(const char *verb, cJSON *root);
/* Landmarks for a mesh of n_vertices: the --landmarks file lm_path, else the rig sidecar next
 * to mesh_path (<stem>.rig.json). At most capacity into lm, count in *n. */
km_status km_cli_load_landmarks(const char *lm_path, const char *mesh_path, size_t n_vertices,
                                km_landmark *lm, size_t capacity, size_t *n, km_error *err);

#endif
