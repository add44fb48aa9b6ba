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
