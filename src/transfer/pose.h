/* Private pieces of pose recognition shared by the src/pose sources. */
#ifndef KM_POSE_POSE_H
#define KM_POSE_POSE_H

#include "transfer/transfer.h"

/* Mirror map m[i] = index of landmark i's counterpart, from the names. */
km_status km__landmark_mirrors(const km_landmark *lm, size_t n, int32_t *m, km_error *err);

/* A trained recogniser: selected angle triples, feature scaling, SVM. */
typedef struct km__pose_model {
  size_t n_landmarks, d, n_classes;
  int32_t *triples; /* d*3 */
  double *lo, *hi;  /* d, training range per feature (scaled to [-1,1]) */
  void *svm;        /* struct svm_model* */
  void *nodes;      /* struct svm_node storage the model points into */
  double *y;        /* libsvm labels storage */
  void *xptr;       /* struct svm_node** rows */
} km__pose_model;

/* P: n_samples poses, each n_landmarks*3 positions. y: labels. */
km_status km__pose_model_train(const double *P, const int32_t *y, size_t n_samples,
                               size_t n_classes, const km_landmark *lm, size_t n_landmarks,
                               const km_posedb_options *opt, const int32_t *fixed_triples,
                               size_t fixed_d, km__pose_model *out, km_error *err);
/* Scaled descriptor of one pose (d values) into x. */
void km__pose_model_features(const km__pose_model *m, const double *P, double *x);
int32_t km__pose_model_predict_scaled(const km__pose_model *m, const double *x);
void km__pose_model_free(km__pose_model *m);

/* The trained SVM as plain arrays, so a pose database stores it (issue 18: a database is not
 * retrained on load, loading is linear in the file). nr_class classes, l support vectors;
 * label, n_sv: nr_class; rho: nr_class (nr_class-1) / 2; coef: (nr_class-1) rows of l;
 * sv_row: l training rows (0-based; rows >= n_samples are the mirrored copies of
 * KM_POSE_MIRROR_ALL). km__pose_model_svm points into the model (nothing to free). */
typedef struct km__pose_svm {
  int nr_class, l;
  const int *label, *n_sv, *sv_row1; /* sv_row1: 1-based (libsvm's sv_indices) */
  const double *rho;
  const double *const *coef;
} km__pose_svm;
void km__pose_model_svm(const km__pose_model *m, km__pose_svm *out);
/* Rebuilds m from stored parts without training: triples (d*3), lo, hi (d), the SVM arrays
 * (coef as (nr_class-1)*l values row after row, sv_row 0-based below `rows`), the scaled
 * descriptors desc (n*d) of the n training samples and their landmark positions P (n*nl*3,
 * for mirrored support vectors). The work is O((n + l) d). Errors: KM_ERR_PARSE on arrays
 * that do not fit together, KM_ERR_NOMEM. */
km_status km__pose_model_restore(km__pose_model *m, size_t nl, const int32_t *mirror,
                                 const int32_t *triples, size_t d, const double *lo,
                                 const double *hi, const km_posedb_options *o, int nr_class, int l,
                                 const int *label, const int *n_sv, const double *rho,
                                 const double *coef, const int32_t *sv_row, size_t rows,
                                 const double *desc, const double *P, size_t n, size_t nc,
                                 km_error *err);

/* CART pieces for repeated trees over shrinking column sets (cart.c): presort every column of
 * X (n x stride) once into order (stride x n), then fit on the columns listed in cols;
 * importance has n_cols entries (in cols order). */
km_status km__cart_presort(const double *X, size_t n, size_t stride, int32_t *order, km_error *err);
km_status km__cart_fit_presorted(const double *X, size_t stride, const int32_t *order,
                                 const int32_t *cols, size_t n_cols, const int32_t *y,
                                 size_t n_samples, size_t n_classes, int max_depth, km_cart **out,
                                 double *importance, km_error *err);

/* Normalised options with defaults filled in. */
km_posedb_options km__posedb_defaults(const km_posedb_options *opt, size_t n_landmarks);

#endif
