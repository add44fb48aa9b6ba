/* Mesh readers and writers: every format and encoding, exact vertex order, bit-exact round
 * trips, precise error messages, robustness on truncated and corrupted input, real data. */
#include "core/core.h"
#include "km_test.h"

#include <float.h>
#include <stdint.h>

static char *load(const char *rel, size_t *n) {
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", KM_TEST_DATA, rel);
  char *d = NULL;
  CHECK_OK(km__read_file(path, &d, n, KM_E));
  return d;
}

static bool faces_valid(const km_mesh *m) {
  for (size_t i = 0; i < m->n_faces * 3; ++i)
    if (m->F[i] < 0 || (size_t)m->F[i] >= m->n_vertices) return false;
  return m->V != NULL && m->F != NULL;
}

static bool face_is(const km_mesh *m, size_t f, int a, int b, int c) {
  return f < m->n_faces && m->F[3 * f] == a && m->F[3 * f + 1] == b && m->F[3 * f + 2] == c;
}

static bool vertex_is(const km_mesh *m, size_t v, double x, double y, double z) {
  return v < m->n_vertices && m->V[3 * v] == x && m->V[3 * v + 1] == y && m->V[3 * v + 2] == z;
}

static void test_obj_forms(void) {
  char path[1024];
  snprintf(path, sizeof path, "%s/mixed.obj", KM_TEST_DATA);
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  CHECK(m.n_vertices == 7);
  CHECK(m.n_faces == 6);
  /* Colours after v are ignored; CRLF is fine. */
  CHECK(vertex_is(&m, 0, 0, 0, 0));
  CHECK(vertex_is(&m, 1, 1, 0, 0));
  CHECK(vertex_is(&m, 3, 0, 1, 0));
  CHECK(vertex_is(&m, 6, 1, 1, 1.5));
  /* Quad fan (0,i,i+1) with i/t/n and i//n forms. */
  CHECK(face_is(&m, 0, 0, 1, 2));
  CHECK(face_is(&m, 1, 0, 2, 3));
  /* Negative indices relative to the 7 vertices read so far. */
  CHECK(face_is(&m, 2, 4, 5, 6));
  /* Pentagon. */
  CHECK(face_is(&m, 3, 4, 5, 6));
  CHECK(face_is(&m, 4, 4, 6, 2));
  CHECK(face_is(&m, 5, 4, 2, 1));
  km_mesh_free(&m);
  CHECK(m.V == NULL && m.F == NULL && m.n_vertices == 0);
  /* A statement continued on the next line with a backslash (the OBJ spec's "\", as a long
   * face is exported; CRLF or blanks after it too); a backslash inside a line (a Windows
   * path) is a character as any other. */
  const char cont[] = "mtllib C:\\art\\a.mtl\nv 0 0 0\nv 1 0 \\\n  0\nv 0 1 0\nv 0 0 1\n"
                      "f 1 2 \\\r\n 3\nf 1 \\ \n 2 \\\n 4\n";
  CHECK_OK(km_mesh_parse(cont, sizeof cont - 1, KM_FORMAT_OBJ, "cont.obj", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_faces == 2);
  CHECK(vertex_is(&m, 1, 1, 0, 0) && vertex_is(&m, 3, 0, 0, 1));
  CHECK(face_is(&m, 0, 0, 1, 2) && face_is(&m, 1, 0, 1, 3));
  km_mesh_free(&m);
}

static void test_ply_ascii(void) {
  size_t n;
  char *d = load("ascii.ply", &n);
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_AUTO, "ascii.ply", &m, KM_E));
  CHECK(m.n_vertices == 5 && m.n_faces == 4);
  CHECK(vertex_is(&m, 0, 0, 0, 0));
  CHECK(vertex_is(&m, 1, 1.5, 0, 0));
  CHECK(vertex_is(&m, 3, 0, 1, -3));
  CHECK(vertex_is(&m, 4, 0.25, 0.125, 1));
  CHECK(face_is(&m, 0, 0, 1, 2));
  CHECK(face_is(&m, 1, 0, 2, 3));
  CHECK(face_is(&m, 2, 0, 3, 4));
  CHECK(face_is(&m, 3, 4, 3, 1));
  km_mesh_free(&m);
  free(d);
}

static void test_ply_binary(void) {
  size_t n;
  char *d = load("tet_le.ply", &n);
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_PLY, "tet_le.ply", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_faces == 4);
  CHECK(vertex_is(&m, 0, 0, 0, 0));
  CHECK(vertex_is(&m, 1, 1, 0, 0));
  CHECK(vertex_is(&m, 3, 0, 0, 1));
  CHECK(face_is(&m, 0, 0, 2, 1));
  CHECK(face_is(&m, 3, 1, 2, 3));
  km_mesh_free(&m);
  free(d);

  /* Big endian, face element before vertex element, mixed scalar types. */
  d = load("quad_be.ply", &n);
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_PLY, "quad_be.ply", &m, KM_E));
  CHECK(m.n_vertices == 5 && m.n_faces == 3);
  CHECK(vertex_is(&m, 0, 0.1, 0, 0));
  CHECK(vertex_is(&m, 2, 1, 1, 0));
  CHECK(m.n_vertices == 5 && signbit(m.V[9]) && m.V[9] == 0.0); /* -0.0 kept */
  CHECK(vertex_is(&m, 4, 0.5, -2, 70000));
  CHECK(face_is(&m, 0, 0, 1, 2));
  CHECK(face_is(&m, 1, 0, 2, 3));
  CHECK(face_is(&m, 2, 0, 3, 4));
  km_mesh_free(&m);
  free(d);

  /* Point cloud: no face element. */
  const char pc[] = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n1 2 3\n4 5 6\n";
  CHECK_OK(km_mesh_parse(pc, sizeof pc - 1, KM_FORMAT_PLY, "pc.ply", &m, KM_E));
  CHECK(m.n_vertices == 2 && m.n_faces == 0 && vertex_is(&m, 1, 4, 5, 6));
  km_mesh_free(&m);
}

static void test_off(void) {
  size_t n;
  char *d = load("poly.off", &n);
  km_mesh m = {0};
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_OFF, "poly.off", &m, KM_E));
  CHECK(m.n_vertices == 6 && m.n_faces == 5);
  CHECK(vertex_is(&m, 3, 0.5, 1.5, 0));
  CHECK(vertex_is(&m, 4, -0.5, 1, 0));
  CHECK(face_is(&m, 0, 0, 1, 2));
  CHECK(face_is(&m, 1, 0, 2, 3));
  CHECK(face_is(&m, 2, 0, 3, 4));
  CHECK(face_is(&m, 3, 0, 1, 5));
  CHECK(face_is(&m, 4, 1, 2, 5));
  km_mesh_free(&m);
  free(d);

  d = load("coff_sameline.off", &n);
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_OFF, "c.off", &m, KM_E));
  CHECK(m.n_vertices == 4 && m.n_faces == 2);
  CHECK(vertex_is(&m, 3, 0, 0, 1));
  CHECK(face_is(&m, 1, 0, 2, 3));
  km_mesh_free(&m);
  free(d);
}

/* Doubles whose text form is easy to get wrong. */
static const double k_tricky[] = {0.1,
                                  1e-300,
                                  -0.0,
                                  1.0 / 3.0,
                                  5e-324,
                                  2.2250738585072009e-308,
                                  DBL_MAX,
                                  -DBL_MIN,
                                  123456789.123456789,
                                  3.141592653589793,
                                  1e300,
                                  -2.5e-310,
                                  0.0,
                                  -1.0 / 7.0,
                                  6.02214076e23};

static bool same_bits(const km_mesh *a, const km_mesh *b) {
  return a->n_vertices == b->n_vertices && a->n_faces == b->n_faces &&
         memcmp(a->V, b->V, a->n_vertices * 3 * sizeof(double)) == 0 &&
         (a->n_faces == 0 || memcmp(a->F, b->F, a->n_faces * 3 * sizeof(int32_t)) == 0);
}

static void round_trip(size_t n_faces) {
  size_t nt = sizeof k_tricky / sizeof k_tricky[0];
  km_mesh orig = {0};
  CHECK_OK(km_mesh_alloc(nt, n_faces, &orig, KM_E));
  for (size_t i = 0; i < nt * 3; ++i)
    orig.V[i] = k_tricky[(i * 7) % nt] * (i % 2 ? -1 : 1);
  for (size_t f = 0; f < n_faces; ++f)
    for (int k = 0; k < 3; ++k)
      orig.F[3 * f + (size_t)k] = (int32_t)((f + (size_t)k * 3) % nt);

  /* OBJ -> PLY (LE, BE, ascii) -> OFF -> OBJ, each read back and compared bit for bit. */
  const char *paths[] = {"rt_a.obj", "rt_b.ply", "rt_c.ply", "rt_d.ply", "rt_e.off", "rt_f.obj"};
  const km_ply_encoding enc[] = {0, KM_PLY_BINARY_LE, KM_PLY_BINARY_BE, KM_PLY_ASCII, 0, 0};
  km_mesh cur = {0};
  CHECK_OK(km_mesh_copy(&orig, &cur, KM_E));
  for (int i = 0; i < 6; ++i) {
    km_mesh_write_options opt = {KM_FORMAT_AUTO, enc[i]};
    CHECK_OK(km_mesh_write(paths[i], &cur, &opt, KM_E));
    km_mesh next = {0};
    CHECK_OK(km_mesh_read(paths[i], &next, KM_E));
    CHECK_MSG(same_bits(&orig, &next), "round trip through %s with %zu faces", paths[i], n_faces);
    km_mesh_free(&cur);
    cur = next;
    remove(paths[i]);
  }
  km_mesh_free(&cur);

  /* The PLY writer's declared layout: doubles and `list uchar int`, BE when asked. */
  km_mesh_write_options be = {KM_FORMAT_PLY, KM_PLY_BINARY_BE};
  CHECK_OK(km_mesh_write("rt_be.bin", &orig, &be, KM_E));
  char *d = NULL;
  size_t n = 0;
  CHECK_OK(km__read_file("rt_be.bin", &d, &n, KM_E));
  if (d) {
    CHECK(strstr(d, "format binary_big_endian 1.0\n") != NULL);
    CHECK(strstr(d, "property double x\n") != NULL);
    CHECK((n_faces != 0) == (strstr(d, "property list uchar int vertex_indices\n") != NULL));
    const char *body = strstr(d, "end_header\n") + 11;
    unsigned char first[8];
    uint64_t bits;
    memcpy(&bits, &orig.V[0], 8);
    for (int k = 0; k < 8; ++k)
      first[k] = (unsigned char)(bits >> (56 - 8 * k));
    CHECK(memcmp(body, first, 8) == 0);
    CHECK(n == (size_t)(body - d) + nt * 24 + n_faces * 13);
  }
  free(d);
  remove("rt_be.bin");
  km_mesh_free(&orig);
}

static void test_round_trip(void) {
  round_trip(9);
  round_trip(0); /* point cloud */

  /* Writing checks its input and reports the path; a failed write leaves nothing behind. */
  const double V[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  int32_t F[3] = {0, 1, 3};
  km_mesh bad = {.V = (double *)V, .F = F, .n_vertices = 3, .n_faces = 1};
  CHECK_STATUS(km_mesh_write("bad_write.obj", &bad, NULL, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "bad_write.obj") != NULL);
  FILE *f = fopen("bad_write.obj", "rb");
  CHECK(f == NULL);
  if (f) fclose(f);
  F[2] = 2;
  /* Missing folders are created (issue 11); one that cannot be (under a file) fails. */
  CHECK_STATUS(km_mesh_write("/dev/null/such/dir/x.ply", &bad, NULL, KM_E), KM_ERR_IO);
  CHECK(strstr(km_test_err.message, "/dev/null/such/dir/x.ply") != NULL);
  CHECK_STATUS(km_mesh_write("x.fbx", &bad, NULL, KM_E), KM_ERR_UNSUPPORTED);
  CHECK(strstr(km_test_err.message, "unknown mesh extension 'fbx'") != NULL);
}

/* The call must fail with `st` and a message naming `name` followed by `where` (":3" or
 * ": byte 123"), plus `what` somewhere. */
static void expect_fail(const char *text, size_t len, km_mesh_format fmt, const char *name,
                        km_status st, const char *where, const char *what) {
  km_mesh m = {0};
  char *copy = malloc(len ? len : 1); /* exact-size buffer: ASan sees any overread */
  memcpy(copy, text, len);
  CHECK_STATUS(km_mesh_parse(copy, len, fmt, name, &m, KM_E), st);
  char loc[256];
  snprintf(loc, sizeof loc, "%s%s", name, where);
  CHECK_MSG(strstr(km_test_err.message, loc) != NULL, "message '%s' should name '%s'",
            km_test_err.message, loc);
  if (what)
    CHECK_MSG(strstr(km_test_err.message, what) != NULL, "message '%s' should say '%s'",
              km_test_err.message, what);
  CHECK(m.V == NULL && m.F == NULL);
  free(copy);
}
#define EXPECT_FAIL(s, fmt, name, st, where, what)                                                 \
  expect_fail(s, sizeof(s) - 1, fmt, name, st, where, what)

static void test_bad_obj(void) {
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nf 1 2 3\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":3:", "out of range");
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":4:", "out of range");
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf -1 -2 -4\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":4:", "out of range");
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 x 3\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":4:", "'x'");
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/2/3/4 2 3\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":4:", "face vertex");
  EXPECT_FAIL("v 0 0 0\r\nv 1 nan 0\r\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":2:", "'nan'");
  EXPECT_FAIL("v 0 0 0\nv 1 0 inf\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":2:", "finite");
  EXPECT_FAIL("v 0 0 0\nv 1 0 1e999\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":2:", "finite");
  EXPECT_FAIL("v 0 0 0\nv 1 0x 0\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":2:", "coordinate y");
  EXPECT_FAIL("v 0 0 0\nv 1 0\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":2:", "3 coordinates");
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":4:", "at least 3");
  /* 2^64 + 2 must not wrap around to a valid index. */
  EXPECT_FAIL("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 18446744073709551618 2 3\n", KM_FORMAT_OBJ, "a.obj",
              KM_ERR_PARSE, ":4:", "face vertex");
  /* a continued statement's lines still count: the bad face is on line 7 */
  EXPECT_FAIL("v 0 0 0\nv 1 0 \\\n 0\nv 1 1 0\nf 1 \\\n 2 3\nf 1 2 x\n", KM_FORMAT_OBJ, "a.obj",
              KM_ERR_PARSE, ":7:", "'x'");
  EXPECT_FAIL("# nothing\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE, ":", "'v'");
  EXPECT_FAIL("v 0 0 0\n\x7f\x45\x4c\x46\x02\x01\n", KM_FORMAT_OBJ, "a.obj", KM_ERR_PARSE,
              ":2:", "keyword");
}

static void test_bad_ply(void) {
  const char *hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                    "property float y\nproperty float z\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n";
  size_t hl = strlen(hdr);
  unsigned char buf[256];
  memcpy(buf, hdr, hl);
  float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  memcpy(buf + hl, xyz, sizeof xyz); /* the test host is little endian (checked below) */
  unsigned char face[13] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 7, 0, 0, 0};
  memcpy(buf + hl + 36, face, 13);
  uint32_t one = 1;
  unsigned char host_le;
  memcpy(&host_le, &one, 1);
  if (host_le) {
    char where[64];
    /* Index 7 of 3 vertices: the byte offset of that index. */
    snprintf(where, sizeof where, ": byte %zu:", hl + 36 + 9);
    expect_fail((char *)buf, hl + 49, KM_FORMAT_PLY, "b.ply", KM_ERR_PARSE, where, "out of range");
    /* Truncated in the middle of the face list. */
    buf[hl + 45] = 2;
    snprintf(where, sizeof where, ": byte %zu:", hl + 45);
    expect_fail((char *)buf, hl + 47, KM_FORMAT_PLY, "b.ply", KM_ERR_PARSE, where, "end of file");
    /* NaN coordinate in a binary body. */
    float nan = NAN;
    memcpy(buf + hl + 4, &nan, 4);
    snprintf(where, sizeof where, ": byte %zu:", hl + 4);
    expect_fail((char *)buf, hl + 49, KM_FORMAT_PLY, "b.ply", KM_ERR_PARSE, where, "finite");
  }
  /* A header claiming 2^31 vertices in a tiny file fails on the header line, without
   * allocating 48 GB (ASan would abort on such an allocation). */
  EXPECT_FAIL("ply\nformat binary_little_endian 1.0\nelement vertex 2147483648\nproperty float x\n"
              "property float y\nproperty float z\nend_header\n0123456789",
              KM_FORMAT_PLY, "h.ply", KM_ERR_PARSE, ":3:", "cannot fit");
  EXPECT_FAIL("ply\nformat binary_little_endian 1.0\nelement vertex 2147483647\nproperty float x\n"
              "property float y\nproperty float z\nend_header\n0123456789",
              KM_FORMAT_PLY, "h.ply", KM_ERR_PARSE, ":3:", "cannot fit");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nelement face 99999999999\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n",
              KM_FORMAT_PLY, "h.ply", KM_ERR_PARSE, ":7:", "cannot fit");
  /* Ascii: wrong counts (fewer lines than declared), bad number, index out of range. */
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0.0 0.0 0.0\n1.0 0.0 0.0\n",
              KM_FORMAT_PLY, "c.ply", KM_ERR_PARSE, ":10:", "end of file");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0 0 0\n1 0 0\n",
              KM_FORMAT_PLY, "c.ply", KM_ERR_PARSE, ":3:", "cannot fit");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0 0 0\n1 zero 0\n",
              KM_FORMAT_PLY, "c.ply", KM_ERR_PARSE, ":9:", "'zero'");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
              KM_FORMAT_PLY, "c.ply", KM_ERR_PARSE, ":13:", "out of range");
  /* Header problems. */
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "end_header\n0 0\n",
              KM_FORMAT_PLY, "d.ply", KM_ERR_PARSE, ":3:", "x, y and z");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\n", KM_FORMAT_PLY, "d.ply",
              KM_ERR_PARSE, ":4:", "'quad'");
  EXPECT_FAIL("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", KM_FORMAT_PLY, "d.ply",
              KM_ERR_PARSE, ":5:", "end_header");
  EXPECT_FAIL("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", KM_FORMAT_PLY, "g.ply", KM_ERR_PARSE,
              ":1:", "'ply'");
}

static void test_bad_off(void) {
  EXPECT_FAIL("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", KM_FORMAT_OFF, "e.off", KM_ERR_PARSE,
              ":6:", "'3'");
  EXPECT_FAIL("OFF\n3 1 0\n0.0 0.0 0.0\n1.0 0.0 0.0\n0.0 1.0 0.0\n", KM_FORMAT_OFF, "e.off",
              KM_ERR_PARSE, ":5:", "end of file");
  EXPECT_FAIL("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n", KM_FORMAT_OFF, "e.off", KM_ERR_PARSE,
              ":2:", "cannot fit");
  EXPECT_FAIL("OFF\n3000000000 1 0\n0 0 0\n", KM_FORMAT_OFF, "e.off", KM_ERR_PARSE,
              ":2:", "cannot fit");
  EXPECT_FAIL("OFF\n2 0 0\n0 0 0\n0 nan 0\n", KM_FORMAT_OFF, "e.off", KM_ERR_PARSE, ":4:", "'nan'");
  EXPECT_FAIL("OFF\n3 1\n0.0 0.0 0.0\n1.0 0.0 0.0\n0.0 1.0 0.0\n2 0 1\n", KM_FORMAT_OFF, "e.off",
              KM_ERR_PARSE, ":6:", "at least 3");
  EXPECT_FAIL("\x7f\x45LF\x02\x01\x01\0\0\0", KM_FORMAT_OFF, "e.off", KM_ERR_PARSE, ":1:", "'OFF'");
  EXPECT_FAIL("v 1 2 3\n", KM_FORMAT_AUTO, "noext", KM_ERR_UNSUPPORTED, "", "extension");
}

/* ---------------------------------------------------------------- STL */

/* The tetrahedron of tetra.obj as STL: welded back to its 4 vertices in first-appearance
 * order (which is tetra.obj's: facet 1 is 1 3 2, so vertex 2 of the STL is its (0,1,0)). */
static void check_stl_tetra(const km_mesh *m, const char *what) {
  CHECK_MSG(m->n_vertices == 4 && m->n_faces == 4, "%s: %zu vertices, %zu faces", what,
            m->n_vertices, m->n_faces);
  CHECK_MSG(vertex_is(m, 0, 0, 0, 0) && vertex_is(m, 1, 0, 1, 0) && vertex_is(m, 2, 1, 0, 0) &&
                vertex_is(m, 3, 0, 0, 1),
            "%s: vertices not in first-appearance order", what);
  CHECK_MSG(face_is(m, 0, 0, 1, 2) && face_is(m, 1, 0, 2, 3) && face_is(m, 2, 0, 3, 1) &&
                face_is(m, 3, 2, 1, 3),
            "%s: faces not facet for facet", what);
}

static void test_stl(void) {
  size_t n;
  km_mesh m = {0};
  char *d = load("tetra_ascii.stl", &n); /* CRLF, a name on solid and endsolid */
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_AUTO, "tetra_ascii.stl", &m, KM_E));
  check_stl_tetra(&m, "ascii");
  km_mesh_free(&m);
  free(d);
  d = load("tetra_bin.stl", &n); /* binary, its header starting with "solid" */
  CHECK_OK(km_mesh_parse(d, n, KM_FORMAT_STL, "tetra_bin.stl", &m, KM_E));
  check_stl_tetra(&m, "binary");
  km_mesh_free(&m);
  /* the same file read from disk by extension */
  char path[1024];
  snprintf(path, sizeof path, "%s/tetra_bin.stl", KM_TEST_DATA);
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  check_stl_tetra(&m, "binary from disk");
  km_mesh_free(&m);
  /* a binary file whose 4th triangle has a NaN corner: named by byte */
  float nan = NAN;
  char *bad = malloc(n);
  memcpy(bad, d, n);
  memcpy(bad + 84 + 3 * 50 + 12 + 12 + 4, &nan, 4);
  CHECK_STATUS(km_mesh_parse(bad, n, KM_FORMAT_STL, "nan.stl", &m, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "nan.stl: byte 258: corner 2 of triangle 4") != NULL);
  CHECK(m.V == NULL && m.F == NULL);
  /* truncated in triangle 3; one byte too many */
  CHECK_STATUS(km_mesh_parse(bad, 84 + 2 * 50 + 20, KM_FORMAT_STL, "cut.stl", &m, KM_E),
               KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "cut.stl: byte 204:") != NULL &&
        strstr(km_test_err.message, "triangle 3 of 4") != NULL);
  free(bad);
  /* a few bytes past the last triangle are ignored (a writer's padding); a triangle's worth
   * or more is a count that does not fit the file */
  bad = calloc(n + 50, 1);
  memcpy(bad, d, n);
  CHECK_OK(km_mesh_parse(bad, n + 2, KM_FORMAT_STL, "pad.stl", &m, KM_E));
  check_stl_tetra(&m, "binary with 2 bytes of padding");
  km_mesh_free(&m);
  CHECK_STATUS(km_mesh_parse(bad, n + 50, KM_FORMAT_STL, "long.stl", &m, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "long.stl: byte 284:") != NULL &&
        strstr(km_test_err.message, "50 bytes after its 4 triangles") != NULL);
  free(bad);
  free(d);

  /* welding: -0 and +0 are one vertex, "1" and "1.0" too; a facet whose corners weld is
   * kept (degenerate); two solids merge in order; keywords in any case; all on one line */
  static const char weld[] =
      "SOLID a FACET NORMAL nan nan nan OUTER LOOP VERTEX 0 0 0 VERTEX 1 0 0 VERTEX 0 1 0 "
      "ENDLOOP ENDFACET ENDSOLID a solid b facet normal 0 0 1 outer loop vertex -0 1.0 0 "
      "vertex 1.0 0 -0.0 vertex 1 1 0 endloop endfacet facet normal 0 0 0 outer loop vertex 1 1 "
      "0 vertex 1 1 0 vertex 1 1 0e0 endloop endfacet endsolid";
  CHECK_OK(km_mesh_parse(weld, sizeof weld - 1, KM_FORMAT_STL, "weld.stl", &m, KM_E));
  CHECK_MSG(m.n_vertices == 4 && m.n_faces == 3, "weld: %zu vertices, %zu faces", m.n_vertices,
            m.n_faces);
  CHECK(face_is(&m, 0, 0, 1, 2) && face_is(&m, 1, 2, 1, 3) && face_is(&m, 2, 3, 3, 3));
  CHECK(vertex_is(&m, 3, 1, 1, 0) && !signbit(m.V[0]) && !signbit(m.V[6]));
  km_mesh_free(&m);
  /* a missing endsolid keeps the facets read (as Blender's reader does), with a warning */
  static const char open_end[] = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 "
                                 "0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  CHECK_OK(km_mesh_parse(open_end, sizeof open_end - 1, KM_FORMAT_STL, "o.stl", &m, KM_E));
  CHECK(m.n_vertices == 3 && m.n_faces == 1);
  km_mesh_free(&m);
  /* written (binary): read back, the faces are the same corners (float32), the vertices in
   * first-appearance order; the header does not start with "solid"; facet normals are unit */
  {
    const double V[15] = {0.1, 0, 0, 0, 0, 0, 0, 1.3, 0, 0, 0, 1, 5, 5, 5}; /* 4: no face */
    const int32_t F[12] = {1, 2, 0, 1, 0, 3, 1, 3, 2, 0, 2, 3};
    km_mesh w = {.V = (double *)V, .F = (int32_t *)F, .n_vertices = 5, .n_faces = 4};
    CHECK_OK(km_mesh_write("stl_write.stl", &w, NULL, KM_E));
    CHECK_OK(km__read_file("stl_write.stl", &d, &n, KM_E));
    CHECK(n == 84 + 4 * 50 && strncmp(d, "solid", 5) != 0);
    float nrm[3];
    memcpy(nrm, d + 84, sizeof nrm); /* facet 1: (0,0,0) (0,1.3,0) (0.1,0,0): normal -z */
    CHECK(nrm[0] == 0 && nrm[1] == 0 && nrm[2] == -1);
    free(d);
    CHECK_OK(km_mesh_read("stl_write.stl", &m, KM_E));
    CHECK(m.n_vertices == 4 && m.n_faces == 4);
    CHECK(face_is(&m, 0, 0, 1, 2) && face_is(&m, 1, 0, 2, 3) && face_is(&m, 2, 0, 3, 1) &&
          face_is(&m, 3, 2, 1, 3));
    CHECK(vertex_is(&m, 0, 0, 0, 0) && vertex_is(&m, 1, 0, (float)1.3, 0) &&
          vertex_is(&m, 2, (float)0.1, 0, 0) && vertex_is(&m, 3, 0, 0, 1));
    km_mesh_free(&m);
    remove("stl_write.stl");
    w.n_faces = 0; /* a point cloud has no STL */
    CHECK_STATUS(km_mesh_write("stl_points.stl", &w, NULL, KM_E), KM_ERR_UNSUPPORTED);
    CHECK(strstr(km_test_err.message, "no faces") != NULL);
    FILE *f = fopen("stl_points.stl", "rb");
    CHECK(f == NULL);
    if (f) fclose(f);
  }
  /* no facets at all: an empty mesh, not an error (the caller checks what it needs) */
  CHECK_OK(km_mesh_parse("solid e\nendsolid e\n", 19, KM_FORMAT_STL, "e.stl", &m, KM_E));
  CHECK(m.n_vertices == 0 && m.n_faces == 0);
  km_mesh_free(&m);
}

static void test_bad_stl(void) {
  EXPECT_FAIL("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 oops 0\n",
              KM_FORMAT_STL, "s.stl", KM_ERR_PARSE, ":5:", "coordinate y of corner 2 of facet 1");
  EXPECT_FAIL("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 nan 0\n",
              KM_FORMAT_STL, "s.stl", KM_ERR_PARSE, ":5:", "'nan'");
  EXPECT_FAIL("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 "
              "0\nvertex 1 1 0\nendloop\nendfacet\nendsolid\n",
              KM_FORMAT_STL, "s.stl", KM_ERR_PARSE, ":7:", "exactly 3 corners");
  EXPECT_FAIL("solid x\nfacet normal 0 0\nouter loop\n", KM_FORMAT_STL, "s.stl", KM_ERR_PARSE,
              ":2:", "3 numbers of facet 1's normal");
  EXPECT_FAIL("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 "
              "0\nendloop\nendfacet\nfacets\n",
              KM_FORMAT_STL, "s.stl", KM_ERR_PARSE, ":9:", "expected 'facet' or 'endsolid'");
  EXPECT_FAIL("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 "
              "0\nendloop\n",
              KM_FORMAT_STL, "s.stl", KM_ERR_PARSE, ":8:", "expected 'endfacet'");
  EXPECT_FAIL("v 0 0 0\n", KM_FORMAT_STL, "o.stl", KM_ERR_PARSE, ":1:", "expected 'solid'");
  EXPECT_FAIL("", KM_FORMAT_STL, "z.stl", KM_ERR_PARSE, ":1:", "found end of file");
  EXPECT_FAIL("\0\0\0\0tiny", KM_FORMAT_STL, "t.stl", KM_ERR_PARSE, ": not an STL file", "8 bytes");
}

/* Every prefix of every sample file, and deterministic byte corruptions, must give either an
 * error or a mesh whose indices are all in range: never a crash or an out-of-bounds read. */
static void test_truncation_and_corruption(void) {
  const char *files[] = {"mixed.obj", "ascii.ply",         "tet_le.ply",      "quad_be.ply",
                         "poly.off",  "coff_sameline.off", "tetra_ascii.stl", "tetra_bin.stl"};
  const km_mesh_format fmts[] = {KM_FORMAT_OBJ, KM_FORMAT_PLY, KM_FORMAT_PLY, KM_FORMAT_PLY,
                                 KM_FORMAT_OFF, KM_FORMAT_OFF, KM_FORMAT_STL, KM_FORMAT_STL};
  uint64_t rng = 0x9e3779b97f4a7c15ULL;
  for (size_t fi = 0; fi < sizeof files / sizeof files[0]; ++fi) {
    size_t n;
    char *d = load(files[fi], &n);
    if (!d) continue;
    size_t ok = 0, bad = 0, invalid = 0, unnamed = 0;
    for (size_t len = 0; len <= n; ++len) {
      char *p = malloc(len ? len : 1);
      memcpy(p, d, len);
      km_mesh m = {0};
      km_error e = {0};
      km_status s = km_mesh_parse(p, len, fmts[fi], files[fi], &m, &e);
      if (s == KM_OK) {
        ++ok;
        invalid += !faces_valid(&m);
        km_mesh_free(&m);
      } else {
        ++bad;
        unnamed += strstr(e.message, files[fi]) == NULL;
      }
      free(p);
    }
    CHECK_MSG(invalid == 0 && unnamed == 0, "%s: %zu invalid meshes, %zu unnamed errors", files[fi],
              invalid, unnamed);
    CHECK_MSG(ok >= 1 && bad >= 1, "%s: %zu ok, %zu errors", files[fi], ok, bad);
    invalid = 0;
    for (int trial = 0; trial < 300; ++trial) {
      char *p = malloc(n);
      memcpy(p, d, n);
      for (int k = 0; k < 1 + trial % 4; ++k) {
        rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
        p[(rng >> 33) % n] = (char)(rng >> 17);
      }
      km_mesh m = {0};
      if (km_mesh_parse(p, n, fmts[fi], files[fi], &m, NULL) == KM_OK) {
        invalid += !faces_valid(&m);
        km_mesh_free(&m);
      }
      free(p);
    }
    CHECK_MSG(invalid == 0, "%s: %zu corrupted inputs gave invalid meshes", files[fi], invalid);
    free(d);
  }
}

/* ---------------------------------------------------------------- real data */

static bool read_shared(const char *rel, km_mesh *m, size_t nv, size_t nf) {
  char buf[1024];
  const char *path = km_test_shared(rel, buf, sizeof buf);
  if (!path) return false;
  CHECK_OK(km_mesh_read(path, m, KM_E));
  CHECK_MSG(m->n_vertices == nv && m->n_faces == nf, "%s: %zu/%zu, expected %zu/%zu", rel,
            m->n_vertices, m->n_faces, nv, nf);
  CHECK(faces_valid(m));
  return true;
}

/* Parses the first and last `v` lines of an OBJ independently of the reader. */
static void obj_first_last(const char *data, double first[3], double last[3]) {
  const char *p = data, *line_v = NULL, *first_v = NULL;
  while (*p) {
    if (p[0] == 'v' && p[1] == ' ') {
      if (!first_v) first_v = p;
      line_v = p;
    }
    const char *nl = strchr(p, '\n');
    if (!nl) break;
    p = nl + 1;
  }
  CHECK(first_v && sscanf(first_v, "v %lf %lf %lf", &first[0], &first[1], &first[2]) == 3);
  CHECK(line_v && sscanf(line_v, "v %lf %lf %lf", &last[0], &last[1], &last[2]) == 3);
}

static int test_shared(void) {
  km_mesh m = {0};
  int found = 0;
  if (read_shared("meshes/armadillo.obj", &m, 43243, 86482)) {
    ++found;
    char buf[1024], *d = NULL;
    size_t n;
    km_test_shared("meshes/armadillo.obj", buf, sizeof buf);
    CHECK_OK(km__read_file(buf, &d, &n, KM_E));
    double first[3] = {0}, last[3] = {0};
    if (d) obj_first_last(d, first, last);
    CHECK(vertex_is(&m, 0, first[0], first[1], first[2]));
    CHECK(vertex_is(&m, m.n_vertices - 1, last[0], last[1], last[2]));
    free(d);
    km_mesh_free(&m);
  }
  if (read_shared("meshes/horse.ply", &m, 48485, 96966)) {
    ++found;
    /* First and last vertex straight from the file bytes (float x y z nx ny nz, LE). */
    char buf[1024], *d = NULL;
    size_t n;
    km_test_shared("meshes/horse.ply", buf, sizeof buf);
    CHECK_OK(km__read_file(buf, &d, &n, KM_E));
    const char *body = d ? strstr(d, "end_header\n") : NULL;
    CHECK(body != NULL);
    if (body) {
      body += 11;
      for (int which = 0; which < 2; ++which) {
        size_t v = which ? m.n_vertices - 1 : 0;
        for (int k = 0; k < 3; ++k) {
          const unsigned char *b = (const unsigned char *)body + v * 24 + (size_t)k * 4;
          uint32_t u =
              (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
          float f;
          memcpy(&f, &u, 4);
          CHECK(m.V[3 * v + (size_t)k] == (double)f);
        }
      }
    }
    free(d);
    km_mesh_free(&m);
  }
  if (read_shared("meshes/dino.off", &m, 14070, 28136)) {
    ++found;
    CHECK(vertex_is(&m, 0, -0.102994, -0.0814559, 0.379478));
    km_mesh_free(&m);
  }
  if (read_shared("poses/tr_reg_025.ply", &m, 6890, 13776)) {
    ++found;
    km_mesh_free(&m);
  }
  if (read_shared("pointclouds/dfaust_50002_light_hopping_loose/00000080.ply", &m, 100000, 0)) {
    ++found;
    km_mesh_free(&m);
  }
  return found;
}

int main(void) {
  test_obj_forms();
  test_ply_ascii();
  test_ply_binary();
  test_off();
  test_round_trip();
  test_bad_obj();
  test_bad_ply();
  test_bad_off();
  test_stl();
  test_bad_stl();
  test_truncation_and_corruption();
  int found = test_shared();
  int rc = km_test_finish("test_mesh_io");
  if (rc == 0 && found == 0) return KM_TEST_SKIP;
  return rc;
}
