/* Shared argument checks for mesh operators (prefix km__). */
#ifndef KM_MESH_ARGS_H
#define KM_MESH_ARGS_H

#include "kinemesh.h"

/* KM_ERR_INVALID unless m is non-NULL, has V/F when counts are non-zero, fits int32 indices
 * and every face index is in [0, n_vertices). `who` names the caller in the message. */
km_status km__mesh_check_faces(const km_mesh *m, const char *who, km_error *err);

#endif
