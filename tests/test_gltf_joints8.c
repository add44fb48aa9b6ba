/* Eight influences per vertex (issue 11): a skinned glTF whose primitive has JOINTS_0 /
 * WEIGHTS_0 and JOINTS_1 / WEIGHTS_1, written by hand here. Eight root joints translated along
 * x by 0.1 j (inverse binds the identity), so a vertex placed by linear blend skinning moves by
 * sum_j w_j 0.1 j: the position must use all 8 weights (as a viewer does), the skin must keep
 * the 4 largest renormalised, and a JOINTS_1 index outside the skin is an error naming it. */
#include "km_test.h"

enum { NV = 3, NJ = 8 };
static const double W[NV][8] = {
    {0.30, 0.20, 0.15, 0.05, 0.12, 0.08, 0.06, 0.04}, /* JOINTS_0 = 0..3, JOINTS_1 = 4..7 */
    {0.05, 0.05, 0.05, 0.05, 0.50, 0.10, 0.10, 0.10}, /* the largest is in the second set */
    {1.00, 0.00, 0.00, 0.00, 0.00, 0.00, 0.00, 0.00}, /* one influence, the rest unused */
};
static const float P[NV][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};

static void put(unsigned char *b, size_t *at, const void *x, size_t n) {
  memcpy(b + *at, x, n);
  *at += n;
}

/* The .glb; bad_joint: JOINTS_1 of vertex 0 names joint 9 of 8. Returns its size. */
static size_t make_glb(unsigned char *out, bool bad_joint) {
  unsigned char bin[1024];
  size_t at = 0;
  put(bin, &at, P, sizeof P); /* 0: positions, 36 bytes */
  uint16_t idx[4] = {0, 1, 2, 0};
  put(bin, &at, idx, 8);            /* 36: indices (6 bytes, padded to 8) */
  for (int set = 0; set < 2; ++set) /* 44, 56: JOINTS_0, JOINTS_1 (u8 VEC4) */
    for (int v = 0; v < NV; ++v)
      for (int q = 0; q < 4; ++q) {
        uint8_t j = (uint8_t)(4 * set + q);
        if (bad_joint && set == 1 && v == 0 && q == 0) j = 9;
        put(bin, &at, &j, 1);
      }
  for (int set = 0; set < 2; ++set) /* 68, 116: WEIGHTS_0, WEIGHTS_1 (float VEC4) */
    for (int v = 0; v < NV; ++v)
      for (int q = 0; q < 4; ++q) {
        float w = (float)W[v][4 * set + q];
        put(bin, &at, &w, 4);
      }
  for (int j = 0; j < NJ; ++j) /* 164: inverse bind matrices, the identity */
    for (int e = 0; e < 16; ++e) {
      float x = e % 5 == 0 ? 1.0f : 0.0f;
      put(bin, &at, &x, 4);
    }
  size_t nbin = at; /* 676 */
  char json[4096];
  int n = snprintf(
      json, sizeof json,
      "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0,1,2,3,4,5,6,7,8]}],"
      "\"nodes\":[{\"name\":\"j0\",\"translation\":[0,0,0]},{\"name\":\"j1\",\"translation\":[0.1,"
      "0,0]},{\"name\":\"j2\",\"translation\":[0.2,0,0]},{\"name\":\"j3\",\"translation\":[0.3,0,"
      "0]},{\"name\":\"j4\",\"translation\":[0.4,0,0]},{\"name\":\"j5\",\"translation\":[0.5,0,0]}"
      ",{\"name\":\"j6\",\"translation\":[0.6,0,0]},{\"name\":\"j7\",\"translation\":[0.7,0,0]},"
      "{\"name\":\"body\",\"mesh\":0,\"skin\":0}],"
      "\"skins\":[{\"joints\":[0,1,2,3,4,5,6,7],\"inverseBindMatrices\":6}],"
      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"JOINTS_0\":2,\"JOINTS_1\":3,"
      "\"WEIGHTS_0\":4,\"WEIGHTS_1\":5},\"indices\":1}]}],"
      "\"buffers\":[{\"byteLength\":%zu}],"
      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":36},"
      "{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6},"
      "{\"buffer\":0,\"byteOffset\":44,\"byteLength\":12},{\"buffer\":0,\"byteOffset\":56,"
      "\"byteLength\":12},{\"buffer\":0,\"byteOffset\":68,\"byteLength\":48},{\"buffer\":0,"
      "\"byteOffset\":116,\"byteLength\":48},{\"buffer\":0,\"byteOffset\":164,\"byteLength\":512}],"
      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
      "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"},"
      "{\"bufferView\":2,\"componentType\":5121,\"count\":3,\"type\":\"VEC4\"},"
      "{\"bufferView\":3,\"componentType\":5121,\"count\":3,\"type\":\"VEC4\"},"
      "{\"bufferView\":4,\"componentType\":5126,\"count\":3,\"type\":\"VEC4\"},"
      "{\"bufferView\":5,\"componentType\":5126,\"count\":3,\"type\":\"VEC4\"},"
      "{\"bufferView\":6,\"componentType\":5126,\"count\":8,\"type\":\"MAT4\"}]}",
      nbin);
  while (n % 4)
    json[n++] = ' ';
  uint32_t hdr[3] = {0x46546C67u, 2, (uint32_t)(12 + 8 + n + 8 + nbin)};
  uint32_t cj[2] = {(uint32_t)n, 0x4E4F534Au}, cb[2] = {(uint32_t)nbin, 0x004E4942u};
  size_t o = 0;
  put(out, &o, hdr, 12);
  put(out, &o, cj, 8);
  put(out, &o, json, (size_t)n);
  put(out, &o, cb, 8);
  put(out, &o, bin, nbin);
  return o;
}

int main(void) {
  static unsigned char glb[8192];
  size_t n = make_glb(glb, false);
  km_mesh m = {0};
  km_mesh_skin sk = {0};
  CHECK_OK(km_mesh_parse_skinned(glb, n, "joints8.glb", &m, &sk, KM_E));
  CHECK(m.n_vertices == NV && m.n_faces == 1 && sk.n_joints == NJ);
  for (int v = 0; v < NV && m.V && sk.weights; ++v) {
    /* the position: all 8 influences */
    double dx = 0;
    for (int j = 0; j < 8; ++j)
      dx += W[v][j] * 0.1 * j;
    CHECK_NEAR(m.V[3 * v], P[v][0] + dx, 1e-6);
    CHECK_NEAR(m.V[3 * v + 1], P[v][1], 1e-6);
    /* the skin: the 4 largest, renormalised, each with its own joint */
    int order[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    for (int a = 0; a < 8; ++a)
      for (int b = a + 1; b < 8; ++b)
        if (W[v][order[b]] > W[v][order[a]]) {
          int t = order[a];
          order[a] = order[b];
          order[b] = t;
        }
    double top = 0, sum = 0;
    for (int q = 0; q < 4; ++q)
      top += W[v][order[q]];
    for (int q = 0; q < 4; ++q) {
      int32_t j = sk.joints[4 * v + q];
      double w = sk.weights[4 * v + q];
      sum += w;
      if (w > 0) {
        CHECK_MSG(j >= 0 && j < NJ && !strcmp(sk.names[j], (char[]){'j', (char)('0' + j), 0}),
                  "vertex %d slot %d: joint %d", v, q, j);
        CHECK_MSG(j >= 0 && j < NJ && fabs(w - W[v][j] / top) < 1e-6,
                  "vertex %d joint %d: weight %g, want %g", v, j, w, j >= 0 ? W[v][j] / top : 0);
        bool in_top = false;
        for (int k = 0; k < 4; ++k)
          in_top |= order[k] == j;
        CHECK_MSG(in_top, "vertex %d keeps joint %d, not one of its 4 largest", v, j);
      }
    }
    CHECK_NEAR(sum, 1, 1e-9);
  }
  CHECK(sk.joints && sk.joints[4 * 1] >= 0 && sk.weights[4 * 1] > 0); /* vertex 1: joint 4 kept */
  km_mesh_free(&m);
  km_mesh_skin_free(&sk);

  /* A JOINTS_1 index outside the skin: refused, naming the attribute and the vertex. */
  n = make_glb(glb, true);
  CHECK_STATUS(km_mesh_parse_skinned(glb, n, "joints8.glb", &m, &sk, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "JOINTS_1") && strstr(km_test_err.message, "vertex 0"),
            "error names JOINTS_1 and the vertex: %s", km_test_err.message);
  km_mesh_free(&m);
  km_mesh_skin_free(&sk);
  return km_test_finish("test_gltf_joints8");
}
