/* Draco mesh decoding for the glTF reader's KHR_draco_mesh_compression (io_gltf.c), behind
 * the C functions of draco_decode.h. Draco (Google's codec, Debian's libdraco-dev) has only a
 * C++ API in Debian (its C-linkage Unity / Emscripten plugins are not built there), so this
 * one file is C++: it calls the library's decoder and copies what it decodes into plain
 * arrays, and nothing else (every check of what the glTF says about them is in io_gltf.c).
 * No C++ exception leaves it: an allocation failure inside the library is reported as out of
 * memory. */
#include "mesh/draco_decode.h"

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include <cstdio>
#include <memory>
#include <new>

struct km__draco {
  std::unique_ptr<draco::Mesh> mesh;
};

km__draco *km__draco_decode(const unsigned char *data, size_t size, char *msg, size_t msg_cap) {
  try {
    draco::DecoderBuffer buf;
    buf.Init(reinterpret_cast<const char *>(data), size);
    auto type = draco::Decoder::GetEncodedGeometryType(&buf);
    if (!type.ok()) {
      std::snprintf(msg, msg_cap, "not a Draco bitstream (%s)", type.status().error_msg());
      return nullptr;
    }
    if (type.value() != draco::TRIANGULAR_MESH) {
      std::snprintf(msg, msg_cap, "a Draco point cloud, not a triangle mesh");
      return nullptr;
    }
    draco::Decoder dec;
    auto r = dec.DecodeMeshFromBuffer(&buf);
    if (!r.ok()) {
      std::snprintf(msg, msg_cap, "the Draco data does not decode (%s)", r.status().error_msg());
      return nullptr;
    }
    km__draco *m = new km__draco;
    m->mesh = std::move(r).value();
    return m;
  } catch (const std::bad_alloc &) {
    std::snprintf(msg, msg_cap, "out of memory");
  } catch (...) {
    std::snprintf(msg, msg_cap, "the Draco decoder failed");
  }
  return nullptr;
}

void km__draco_free(km__draco *m) { delete m; }

size_t km__draco_points(const km__draco *m) { return m->mesh->num_points(); }

size_t km__draco_faces(const km__draco *m) { return m->mesh->num_faces(); }

void km__draco_face_indices(const km__draco *m, uint32_t *out) {
  const draco::Mesh &mesh = *m->mesh;
  for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f)
    for (int c = 0; c < 3; ++c)
      out[3 * f.value() + c] = mesh.face(f)[c].value();
}

int km__draco_components(const km__draco *m, uint32_t unique_id, bool *is_float) {
  const draco::PointAttribute *a = m->mesh->GetAttributeByUniqueId(unique_id);
  if (!a) return 0;
  *is_float = a->data_type() == draco::DT_FLOAT32 || a->data_type() == draco::DT_FLOAT64;
  return a->num_components();
}

/* Point i's values, through the attribute's point-to-value map. Floats as decoded (Draco
 * dequantises quantised positions, normals and texture coordinates itself); integers as
 * stored (as int32; false when one does not fit), not normalised: the glTF accessor's `normalized`
 * applies them, as in a file without Draco. */
bool km__draco_values(const km__draco *m, uint32_t unique_id, bool as_float, void *out) {
  const draco::PointAttribute *a = m->mesh->GetAttributeByUniqueId(unique_id);
  if (!a) return false;
  const int8_t nc = a->num_components();
  for (draco::PointIndex p(0); p < m->mesh->num_points(); ++p) {
    const draco::AttributeValueIndex v = a->mapped_index(p);
    bool ok = as_float
                  ? a->ConvertValue<float>(v, nc, static_cast<float *>(out) + p.value() * nc)
                  : a->ConvertValue<int32_t>(v, nc, static_cast<int32_t *>(out) + p.value() * nc);
    if (!ok) return false;
  }
  return true;
}
