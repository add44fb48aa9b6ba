/* Requires: core, linalg, math, mesh. External: cJSON, meshoptimizer. */
/* Private interface between the animation writer (anim.c) and its format back-ends. */
#ifndef KM_IO_ANIM_H
#define KM_IO_ANIM_H

#include "core/core.h"

/* Writer state shared by the back-ends. */
struct km_anim_writer {
  km_anim_format format;
  char *path;
  size_t n_vertices, n_faces;
  double *rest; /* copy of the rest positions */
  int32_t *F;   /* copy of the rest faces */
  double fps;
  size_t key_every;
  size_t frames;        /* frames accepted so far */
  bool failed;          /* an I/O error happened: close refuses to publish */
  float *fbuf;          /* one frame as float32 (glb) */
  unsigned char *bytes; /* one frame encoded (pc2, ply) */
  /* pc2: the output itself, streamed to its temporary. */
  km__atomic_file af;
  /* glb: key-frame displacements, float32, in an anonymous temporary file. */
  FILE *keys;
  size_t n_keys;
  size_t *key_frame; /* frame index of each stored key */
  float *key_minmax; /* 6 per key: min xyz, max xyz of the displacement */
  size_t key_cap;
  float *last; /* the latest frame's displacement (glb), for the closing key */
  float last_minmax[6];
  float rest_minmax[6];
  /* directories: frames are written into tmp_dir, renamed into place on close. */
  char *tmp_dir;
  int tmp_dir_slot; /* km__tmp_dir_register's slot (SIGINT cleanup), -1: none */
  /* Attributes of a rest mesh that has them (issue 11): its texture coordinates, copied, and
   * whether normals are written (recomputed from each frame's positions: a deformed mesh's
   * normals are not the rest's). NULL / false: positions only, as before. */
  double *uv;            /* #V*2 */
  double *colors;        /* #V*4 (km_mesh.colors), NULL: none */
  km_mesh material_mesh; /* holds only a copy of the rest mesh's material (glb), or none */
  bool normals;          /* rest had UV or N */
  double *nbuf;          /* #V*3 scratch: one frame's normals */
  double *vbuf;          /* #V*3 scratch: one key's positions (glb) */
  /* A file frame to write in (km_anim_options.frame): the rest copy is in it already, each
   * pushed frame is taken into it through ubuf (km_frame_unapply). */
  bool undo;
  km_frame frame;
  double *ubuf; /* #V*3 scratch: one pushed frame in the file's frame */
  /* issue 16: a skinned glb fits km_ssdr at close over every frame (stored as keys). */
  km_anim_export export_kind;
  km_ssdr_options skin;
  /* PCA morphs: the keys are replaced by pca_k basis targets at close; weights T x K. */
  size_t pca_k;
  float *pca_weights; /* pca_frames * n_keys, row per frame */
  size_t pca_frames;
  bool pca_offset;         /* the last target is the offset (weight 1 at every frame), named so */
  double pca_rms, pca_max; /* its error against the frames (m), kept in the extras */
  const double *pca_D;     /* the exact displacements (pca_frames * #V*3) while writing */
  /* --compress: KHR_mesh_quantization + EXT_meshopt_compression; the error a player sees of
   * what was written (m; the quantisation's on top of the fit's) */
  bool compress;
  double q_rms, q_max;
  /* KM_ANIM_EXPORT_SKELETON: the given skeleton and weights (copies), the pushed transforms
   * (n_frames * n_bones * 12, grown as frames come) */
  size_t n_bones;
  km_skin bskin;
  double *bcenter;      /* n_bones*3: joint rest positions, where each bone is bound */
  char **bone_names;    /* n_bones */
  int32_t *bone_parent; /* n_bones, -1 a root: the joints' hierarchy (NULL: flat bones) */
  double *bxf;
  size_t bxf_cap; /* frames bxf holds room for */
};

/* Unit area-weighted normals of positions V over the writer's faces into w->nbuf; a vertex
 * with no non-degenerate face gets +y (glTF requires unit normals). */
void km__anim_normals(km_anim_writer *w, const double *V);

/* Writes the final .glb from the stored keys (called by close). */
km_status km__glb_finish(km_anim_writer *w, km_error *err);

/* Writes the skinned .glb of a fit over the writer's rest mesh into w->af and commits it;
 * frames (fit->n_frames * #V*3, may be NULL) give the compressed file's error (w->q_rms). */
km_status km__glb_write_skin(km_anim_writer *w, const km_ssdr *fit, const double *frames,
                             km_error *err);

/* Every frame of a morph-target .glb (base + sum of weighted targets at each key of the first
 * weights channel; one frame per target without one): *frames n_frames * nv * 3, allocated.
 * fps: from kinemesh's extras or the key spacing; untouched when unknown. */
km_status km__glb_frames(const char *path, size_t nv, double **frames, size_t *n_frames,
                         double *fps, km_error *err);

/* Reads the .glb header and JSON chunk only (the binary chunk may be large). */
km_status km__glb_info(const char *path, km_anim_info *out, km_error *err);

#endif
