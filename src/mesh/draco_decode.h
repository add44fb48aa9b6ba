/* Draco mesh bitstreams decoded (draco.cc, over Debian's libdraco), for the glTF reader's
 * KHR_draco_mesh_compression. Private to src/mesh/. A C interface, so that the reader stays C
 * and only draco.cc is C++. */
#ifndef KM_MESH_DRACO_DECODE_H
#define KM_MESH_DRACO_DECODE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct km__draco km__draco;

/* The triangle mesh encoded in data[0 .. size), or NULL with a reason written into msg
 * (msg_cap bytes: not a Draco bitstream, a point cloud, a decoder error, out of memory).
 * Free with km__draco_free. */
km__draco *km__draco_decode(const unsigned char *data, size_t size, char *msg, size_t msg_cap);
void km__draco_free(km__draco *m);
/* Decoded points (the glTF accessors' count) and triangles. */
size_t km__draco_points(const km__draco *m);
size_t km__draco_faces(const km__draco *m);
/* out[3 * n_faces]: each triangle's three point indices, in decoded order. */
void km__draco_face_indices(const km__draco *m, uint32_t *out);
/* Components per point of the attribute with this unique id (the glTF extension's
 * `attributes` values), 0 when the mesh has none; *is_float: stored as floating point. */
int km__draco_components(const km__draco *m, uint32_t unique_id, bool *is_float);
/* out[n_points * components]: the attribute's values per point, as float (as_float) or as
 * int32 (integers as stored, not normalised). false when a value does not convert. */
bool km__draco_values(const km__draco *m, uint32_t unique_id, bool as_float, void *out);

#ifdef __cplusplus
}
#endif

#endif
