/* km_mesh_info_compute, km_bbox_diagonal, km_adjacency_list and km_boundary_loops on hand-made
 * meshes whose counts are known by construction, and against brute-force recounts on random meshes.
 */
#include "core/core.h"
#include "km_test.h"
#include "mesh/mesh.h"   /* km__seated_base */
#include "synth/synth.h" /* test fixtures: primitive meshes, one capture frame */

static km_mesh make(size_t nv, const double *V, size_t nf, const int32_t *F) {
  km_mesh m = {0};
  CHECK_OK(km_mesh_alloc(nv, nf, &m, KM_E));
  if (nv) memcpy(m.V, V, nv * 3 * sizeof(double));
  if (nf) memcpy(m.F, F, nf * 3 * sizeof(int32_t));
  return m;
}

static km_mesh_info info_of(const km_mesh *m) {
  km_mesh_info info;
  memset(&info, 0xff, sizeof info);
  CHECK_OK(km_mesh_info_compute(m, &info, KM_E));
  return info;
}

static void test_tetrahedron(void) {
  const double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  km_mesh m = make(4, V, 4, F);
  km_mesh_info i = info_of(&m);
  CHECK(i.vertices == 4 && i.faces == 4);
  CHECK(i.edges == 6);
  CHECK(i.boundary_edges == 0 && i.nonmanifold_edges == 0 && i.nonmanifold_vertices == 0);
  CHECK(i.nonmanifold_edge[0] == -1 && i.nonmanifold_edge[1] == -1 && i.nonmanifold_vertex == -1);
  CHECK(i.components == 1 && i.isolated_vertices == 0 && i.degenerate_faces == 0);
  CHECK(i.euler_characteristic == 2);
  CHECK(i.bbox_min[0] == 0 && i.bbox_min[1] == 0 && i.bbox_min[2] == 0);
  CHECK(i.bbox_max[0] == 1 && i.bbox_max[1] == 1 && i.bbox_max[2] == 1);
  CHECK_NEAR(km_bbox_diagonal(m.V, m.n_vertices), sqrt(3.0), 1e-15);

  int32_t *off = NULL, *adj = NULL;
  CHECK_OK(km_adjacency_list(&m, &off, &adj, KM_E));
  if (off && adj) {
    CHECK(off[0] == 0 && off[4] == 12);
    for (int v = 0; v < 4; ++v) {
      CHECK(off[v + 1] - off[v] == 3);
      int k = off[v];
      for (int w = 0; w < 4; ++w)
        if (w != v) CHECK(adj[k++] == w); /* every other vertex, ascending */
    }
  }
  free(off);
  free(adj);
  km_mesh_free(&m);
}

/* A tetrahedron whose last face has its own copies of vertices 1, 2, 3 (as a glTF exporter
 * splits a textured mesh at a seam), and a lone vertex on vertex 0's position (no face: not
 * counted). */
static void test_seams(void) {
  const double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  const int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 4, 5, 6};
  km_mesh m = make(8, V, 4, F);
  km_mesh_info i = info_of(&m);
  CHECK_MSG(i.seam_vertices == 6 && i.components == 2 && i.isolated_vertices == 1,
            "seam vertices %zu, components %zu, isolated %zu", i.seam_vertices, i.components,
            i.isolated_vertices);
  km_mesh_free(&m);
  const int32_t G[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  m = make(4, V, 4, G);
  CHECK(info_of(&m).seam_vertices == 0);
  km_mesh_free(&m);
}

static void test_open_square_and_extras(void) {
  /* Two triangles forming a unit square, plus an isolated vertex and a degenerate
   * (collinear) face on a separate strip. */
  const double V[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 5, 5, 2, 0, 0, 3, 0, 0, 4, 0, 0};
  const int32_t F[] = {0, 1, 2, 0, 2, 3};
  km_mesh m = make(4, V, 2, F);
  km_mesh_info i = info_of(&m);
  CHECK(i.edges == 5 && i.boundary_edges == 4 && i.nonmanifold_edges == 0);
  CHECK(i.components == 1 && i.euler_characteristic == 1 && i.degenerate_faces == 0);
  km_mesh_free(&m);

  m = make(5, V, 2, F); /* vertex 4 unused */
  i = info_of(&m);
  CHECK(i.isolated_vertices == 1 && i.components == 1);
  CHECK(i.euler_characteristic == 1); /* isolated vertex not counted */
  CHECK(i.bbox_max[2] == 5);          /* but it is part of the extent */
  km_mesh_free(&m);

  const int32_t F2[] = {0, 1, 2, 0, 2, 3, 5, 6, 7, 1, 1, 2};
  m = make(8, V, 4, F2);
  i = info_of(&m);
  CHECK(i.degenerate_faces == 2); /* collinear (zero area) and repeated index */
  CHECK(i.components == 2);       /* the square (with face 1,1,2) and the collinear strip */
  CHECK(i.isolated_vertices == 1);
  km_mesh_free(&m);

  /* Collapsed faces are no surface: one on an edge of the square (0, 0, 2 over the diagonal)
   * leaves that edge shared by two faces, not three (non-manifold), and one joining the square
   * to the far vertex 4 opens no boundary edge and joins no piece. */
  const int32_t F3[] = {0, 1, 2, 0, 2, 3, 0, 0, 2, 1, 4, 1};
  m = make(5, V, 4, F3);
  i = info_of(&m);
  CHECK_MSG(i.nonmanifold_edges == 0 && i.boundary_edges == 4 && i.edges == 5 &&
                i.components == 1 && i.degenerate_faces == 2,
            "collapsed faces: %zu non-manifold, %zu boundary edges, %zu edges, %zu components",
            i.nonmanifold_edges, i.boundary_edges, i.edges, i.components);
  int32_t loop[5];
  size_t n_loops = 0;
  CHECK_OK(km_boundary_loops(&m, loop, &n_loops, KM_E));
  CHECK(n_loops == 1 && loop[4] == -1);
  km_mesh_free(&m);
}

static void test_nonmanifold(void) {
  /* Bowtie: two triangles sharing only vertex 0. */
  const double V[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0, 0, 0, 1};
  const int32_t bow[] = {0, 1, 2, 0, 3, 4};
  km_mesh m = make(5, V, 2, bow);
  km_mesh_info i = info_of(&m);
  CHECK(i.nonmanifold_vertices == 1 && i.nonmanifold_vertex == 0);
  CHECK(i.nonmanifold_edges == 0 && i.boundary_edges == 6 && i.components == 1);
  km_mesh_free(&m);

  /* Three triangles on edge (0,1): one non-manifold edge; the fans around 0 and 1 stay
   * edge-connected, so no non-manifold vertex. */
  const int32_t fin[] = {0, 1, 2, 1, 0, 3, 0, 1, 5};
  m = make(6, V, 3, fin);
  i = info_of(&m);
  CHECK(i.nonmanifold_edges == 1 && i.nonmanifold_edge[0] == 0 && i.nonmanifold_edge[1] == 1);
  CHECK(i.edges == 7 && i.boundary_edges == 6);
  CHECK(i.nonmanifold_vertices == 0);
  CHECK(i.isolated_vertices == 1 && i.components == 1);
  km_mesh_free(&m);

  /* A vertex on a boundary with two separate fans also counts. */
  const int32_t two[] = {0, 1, 2, 0, 2, 5, 0, 3, 4};
  m = make(6, V, 3, two);
  i = info_of(&m);
  CHECK(i.nonmanifold_vertices == 1);
  km_mesh_free(&m);
}

static void test_grid(void) {
  /* n x n quads split in two: known counts for any n. */
  const int n = 7;
  km_mesh m = {0};
  CHECK_OK(km_mesh_alloc((size_t)((n + 1) * (n + 1)), (size_t)(2 * n * n), &m, KM_E));
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      double *p = m.V + 3 * (y * (n + 1) + x);
      p[0] = x, p[1] = y, p[2] = 0;
    }
  int32_t *f = m.F;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      int32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 2, d = a + n + 1;
      f[0] = a, f[1] = b, f[2] = c, f[3] = a, f[4] = c, f[5] = d;
      f += 6;
    }
  km_mesh_info i = info_of(&m);
  CHECK(i.edges == (size_t)(2 * n * (n + 1) + n * n));
  CHECK(i.boundary_edges == (size_t)(4 * n));
  CHECK(i.euler_characteristic == 1 && i.components == 1 && i.nonmanifold_vertices == 0);

  int32_t *off = NULL, *adj = NULL;
  CHECK_OK(km_adjacency_list(&m, &off, &adj, KM_E));
  if (off && adj) {
    CHECK((size_t)off[m.n_vertices] == 2 * i.edges);
    CHECK(off[0 + 1] - off[0] == 3); /* corner (0,0): right, up, diagonal */
    int inner = 2 * (n + 1) + 3;
    CHECK(off[inner + 1] - off[inner] == 6);
  }
  free(off);
  free(adj);
  km_mesh_free(&m);
}

/* Brute-force recount (O(F^2)) of edges and non-manifold vertices on random small meshes. */
static void test_random_against_brute_force(void) {
  uint64_t rng = 12345;
#define RNG() (rng = rng * 6364136223846793005ULL + 1442695040888963407ULL, (uint32_t)(rng >> 33))
  for (int trial = 0; trial < 200; ++trial) {
    size_t nv = 4 + RNG() % 10, nf = 1 + RNG() % 14;
    km_mesh m = {0};
    CHECK_OK(km_mesh_alloc(nv, nf, &m, KM_E));
    for (size_t k = 0; k < nv * 3; ++k)
      m.V[k] = (double)(RNG() % 1000) / 100.0;
    for (size_t k = 0; k < nf * 3; ++k)
      m.F[k] = (int32_t)(RNG() % nv);
    km_mesh_info i = info_of(&m);

    /* Edges: distinct unordered pairs (a != b) over the sides of the faces that are not
     * collapsed (a repeated index: no surface, left out). */
    size_t edges = 0, boundary = 0, nonman = 0;
    int32_t first_a = -1, first_b = -1, first_v = -1;
    for (size_t a = 0; a < nv; ++a)
      for (size_t b = a + 1; b < nv; ++b) {
        size_t uses = 0;
        for (size_t f = 0; f < nf; ++f) {
          const int32_t *t = m.F + 3 * f;
          if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
          bool ha = t[0] == (int32_t)a || t[1] == (int32_t)a || t[2] == (int32_t)a;
          bool hb = t[0] == (int32_t)b || t[1] == (int32_t)b || t[2] == (int32_t)b;
          uses += ha && hb;
        }
        if (uses) ++edges;
        if (uses == 1) ++boundary;
        if (uses >= 3 && nonman++ == 0) first_a = (int32_t)a, first_b = (int32_t)b;
      }
    CHECK(i.edges == edges && i.boundary_edges == boundary && i.nonmanifold_edges == nonman);
    CHECK_MSG(i.nonmanifold_edge[0] == first_a && i.nonmanifold_edge[1] == first_b,
              "trial %d: first non-manifold edge %d-%d vs brute force %d-%d", trial,
              (int)i.nonmanifold_edge[0], (int)i.nonmanifold_edge[1], (int)first_a, (int)first_b);

    /* Non-manifold vertices: flood fill over proper faces around v, joined by shared (v,w). */
    size_t nmv = 0;
    for (size_t v = 0; v < nv; ++v) {
      int comp[64];
      size_t fans = 0;
      for (size_t f = 0; f < nf; ++f)
        comp[f] = -1;
      for (size_t f = 0; f < nf; ++f) {
        const int32_t *t = m.F + 3 * f;
        bool proper = t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
        bool has = t[0] == (int32_t)v || t[1] == (int32_t)v || t[2] == (int32_t)v;
        if (!proper || !has || comp[f] >= 0) continue;
        comp[f] = (int)fans;
        for (bool grew = true; grew;) {
          grew = false;
          for (size_t g = 0; g < nf; ++g) {
            const int32_t *u = m.F + 3 * g;
            bool pg = u[0] != u[1] && u[1] != u[2] && u[0] != u[2];
            bool hg = u[0] == (int32_t)v || u[1] == (int32_t)v || u[2] == (int32_t)v;
            if (!pg || !hg || comp[g] >= 0) continue;
            for (size_t h = 0; h < nf && comp[g] < 0; ++h) {
              if (comp[h] != (int)fans) continue;
              const int32_t *w = m.F + 3 * h;
              for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                  if (w[a] == u[b] && w[a] != (int32_t)v) comp[g] = (int)fans, grew = true;
            }
          }
        }
        ++fans;
      }
      if (fans > 1 && nmv++ == 0) first_v = (int32_t)v;
    }
    CHECK_MSG(i.nonmanifold_vertices == nmv, "trial %d: %zu vs brute force %zu", trial,
              i.nonmanifold_vertices, nmv);
    CHECK(i.nonmanifold_vertex == first_v);

    int32_t *off = NULL, *adj = NULL;
    CHECK_OK(km_adjacency_list(&m, &off, &adj, KM_E));
    if (off && adj) {
      CHECK((size_t)off[nv] == 2 * edges);
      bool sorted = true;
      for (size_t v = 0; v < nv; ++v)
        for (int32_t k = off[v] + 1; k < off[v + 1]; ++k)
          sorted &= adj[k - 1] < adj[k];
      CHECK(sorted);
    }
    free(off);
    free(adj);
    km_mesh_free(&m);
  }
}

static void test_invalid(void) {
  const double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const int32_t F[] = {0, 1, 3};
  km_mesh m = make(3, V, 1, F);
  km_mesh_info i;
  CHECK_STATUS(km_mesh_info_compute(&m, &i, KM_E), KM_ERR_INVALID);
  CHECK(strstr(km_test_err.message, "index 3") != NULL);
  int32_t *off = NULL, *adj = NULL;
  CHECK_STATUS(km_adjacency_list(&m, &off, &adj, KM_E), KM_ERR_INVALID);
  CHECK(off == NULL && adj == NULL);
  km_mesh_free(&m);

  km_mesh empty = {0};
  i = info_of(&empty);
  CHECK(i.vertices == 0 && i.edges == 0 && i.components == 0 && i.euler_characteristic == 0);
  CHECK(km_bbox_diagonal(NULL, 0) == 0.0);
}

static void test_shared_armadillo(void) {
  char buf[1024];
  const char *path = km_test_shared("meshes/armadillo.obj", buf, sizeof buf);
  if (!path) return;
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  km_mesh_info i = info_of(&m);
  int32_t *off = NULL, *adj = NULL;
  CHECK_OK(km_adjacency_list(&m, &off, &adj, KM_E));
  if (off) CHECK((size_t)off[m.n_vertices] == 2 * i.edges);
  /* Every face edge 1..3 uses: 3F = sum over edges of uses >= 2E - boundary. */
  CHECK(3 * i.faces >= 2 * i.edges - i.boundary_edges);
  CHECK(i.euler_characteristic ==
        (int64_t)(i.vertices - i.isolated_vertices) - (int64_t)i.edges + (int64_t)i.faces);
  free(off);
  free(adj);
  km_mesh_free(&m);
}

/* Farthest-point sampling: spread (2 points on a sphere are antipodal, 4 form a near-regular
 * tetrahedron), deterministic, never an isolated vertex, clear errors. */
static void test_farthest_points(void) {
  km_mesh s = {0};
  CHECK_OK(km_icosphere(3, 1.0, &s, KM_E));
  if (!s.V) return;
  /* one isolated vertex far away: a landmark there would float */
  size_t n = s.n_vertices;
  double *V = realloc(s.V, sizeof(double) * 3 * (n + 1));
  CHECK(V != NULL);
  if (!V) return;
  s.V = V;
  s.V[3 * n] = 50, s.V[3 * n + 1] = 0, s.V[3 * n + 2] = 0;
  s.n_vertices = n + 1;
  int32_t ids[8], again[8];
  CHECK_OK(km_farthest_points(&s, 2, ids, KM_E));
  double d2 = 0;
  for (int a = 0; a < 3; ++a)
    d2 += pow(s.V[3 * ids[0] + a] - s.V[3 * ids[1] + a], 2);
  CHECK_MSG(fabs(sqrt(d2) - 2) < 1e-6, "two samples %g apart, not antipodal", sqrt(d2));
  CHECK_OK(km_farthest_points(&s, 8, ids, KM_E));
  CHECK_OK(km_farthest_points(&s, 8, again, KM_E));
  CHECK(memcmp(ids, again, sizeof ids) == 0);
  double dmin4 = INFINITY;
  for (int i = 0; i < 8; ++i) {
    CHECK((size_t)ids[i] < n); /* not the isolated vertex */
    for (int j = 0; j < i; ++j) {
      CHECK(ids[i] != ids[j]);
      double e = 0;
      for (int a = 0; a < 3; ++a)
        e += pow(s.V[3 * ids[i] + a] - s.V[3 * ids[j] + a], 2);
      if (i < 4) dmin4 = fmin(dmin4, sqrt(e));
    }
  }
  /* a regular tetrahedron in the unit sphere has edges 1.633; greedy sampling gets close */
  CHECK_MSG(dmin4 > 1.35, "4 samples only %g apart", dmin4);
  CHECK_STATUS(km_farthest_points(&s, n + 1, ids, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_farthest_points(NULL, 2, ids, KM_E), KM_ERR_INVALID);
  km_mesh cloud = s;
  cloud.n_faces = 0;
  CHECK_STATUS(km_farthest_points(&cloud, 2, ids, KM_E), KM_ERR_DEGENERATE_MESH);
  km_mesh_free(&s);
}

/* km_boundary_loops: none on a closed mesh; a grid with a hole in its middle has its outer
 * loop (4 n vertices, numbered first: it holds vertex 0) and the hole's (4); two triangles
 * touching at a vertex make one loop. */
static void test_boundary_loops(void) {
  const double V[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0};
  const int32_t T[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  km_mesh m = make(4, V, 4, T);
  int32_t loop[64];
  size_t nl = 99;
  CHECK_OK(km_boundary_loops(&m, loop, &nl, KM_E));
  CHECK(nl == 0);
  for (int v = 0; v < 4; ++v)
    CHECK(loop[v] == -1);
  km_mesh_free(&m);
  const int n = 5; /* 6 x 6 vertices, the middle quad (2, 2) removed */
  CHECK_OK(km_mesh_alloc((size_t)((n + 1) * (n + 1)), (size_t)(2 * n * n - 2), &m, KM_E));
  for (int y = 0; m.V && y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      double *p = m.V + 3 * (y * (n + 1) + x);
      p[0] = x, p[1] = y, p[2] = 0;
    }
  int32_t *f = m.F;
  for (int y = 0; f && y < n; ++y)
    for (int x = 0; x < n; ++x) {
      if (x == 2 && y == 2) continue;
      int32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 2, d = a + n + 1;
      f[0] = a, f[1] = b, f[2] = c, f[3] = a, f[4] = c, f[5] = d;
      f += 6;
    }
  CHECK_OK(km_boundary_loops(&m, loop, &nl, KM_E));
  CHECK(nl == 2);
  size_t on[2] = {0, 0}, off = 0;
  for (int v = 0; v < (n + 1) * (n + 1); ++v) {
    if (loop[v] < 0) {
      ++off;
      continue;
    }
    if (loop[v] < 2) ++on[loop[v]];
    int x = v % (n + 1), y = v / (n + 1);
    bool outer = x == 0 || y == 0 || x == n || y == n;
    CHECK_MSG(loop[v] == (outer ? 0 : 1), "vertex %d (%d, %d) in loop %d", v, x, y, loop[v]);
  }
  CHECK(on[0] == 4 * (size_t)n && on[1] == 4 && off == 36 - 20 - 4);
  km_mesh_free(&m);
  const int32_t B[] = {0, 1, 4, 0, 2, 3}; /* bowtie: triangles touching at vertex 0 */
  m = make(5, V, 2, B);
  CHECK_OK(km_boundary_loops(&m, loop, &nl, KM_E));
  CHECK(nl == 1);
  for (int v = 0; v < 5; ++v)
    CHECK(loop[v] == 0);
  CHECK_STATUS(km_boundary_loops(&m, NULL, &nl, KM_E), KM_ERR_INVALID);
  km_mesh_free(&m);
}

/* km__seated_base: a standing cylinder sits on its flat cap (a plinth); a sphere touches the
 * ground in a small cap; two cylinders side by side stand on two parts (two feet); a lone
 * tetrahedron's bottom face is most of its vertices. */
static void test_seated_base(void) {
  km_mesh c = {0}, two = {0}, s = {0};
  CHECK_OK(km_cylinder(24, 8, 0.2, 1.0, &c, KM_E));
  for (size_t v = 0; c.V && v < c.n_vertices; ++v) { /* its axis along y */
    double y = c.V[3 * v + 2];
    c.V[3 * v + 2] = c.V[3 * v + 1], c.V[3 * v + 1] = y;
  }
  bool found = false;
  double top = 0;
  CHECK_OK(km__seated_base(&c, &found, &top, KM_E));
  CHECK_MSG(found && fabs(top - 0.05) < 1e-9, "the cylinder: found %d, base top %g", found, top);
  CHECK_OK(km_mesh_alloc(2 * c.n_vertices, 2 * c.n_faces, &two, KM_E));
  for (size_t v = 0; two.V && v < c.n_vertices; ++v)
    for (int k = 0; k < 3; ++k) {
      two.V[3 * v + k] = c.V[3 * v + k] - (k == 0 ? 0.3 : 0);
      two.V[3 * (v + c.n_vertices) + k] = c.V[3 * v + k] + (k == 0 ? 0.3 : 0);
    }
  for (size_t i = 0; two.F && i < 3 * c.n_faces; ++i) {
    two.F[i] = c.F[i];
    two.F[i + 3 * c.n_faces] = c.F[i] + (int32_t)c.n_vertices;
  }
  CHECK_OK(km__seated_base(&two, &found, &top, KM_E));
  CHECK_MSG(!found, "two cylinders (two feet) taken for a seated body");
  CHECK_OK(km_icosphere(3, 0.5, &s, KM_E));
  CHECK_OK(km__seated_base(&s, &found, &top, KM_E));
  CHECK_MSG(!found, "a sphere taken for a seated body");
  const double V[] = {0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 0};
  const int32_t T[] = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
  km_mesh t = make(4, V, 4, T);
  CHECK_OK(km__seated_base(&t, &found, &top, KM_E));
  CHECK_MSG(!found, "a lone tetrahedron taken for a seated body");
  km_mesh_free(&t), km_mesh_free(&s), km_mesh_free(&two), km_mesh_free(&c);
}

/* km__nearest_x against km_nearest_vertices (a brute-force scan) on random points with
 * duplicates (ties: the lower id) and a NaN point; km__mesh_body on two tetrahedra (comparable:
 * no body) and on a tetrahedron beside a mesh of 20 vertices (the body, the tetrahedron's
 * vertices mapped to their nearest body vertex). */
static void test_nearest_and_body(void) {
  enum { N = 2000, Q = 500 };
  double *V = malloc(3 * N * sizeof(double));
  uint32_t seed = 7;
  for (size_t i = 0; V && i < 3 * N; ++i) {
    seed = seed * 1664525u + 1013904223u;
    V[i] = (double)(seed >> 8) / (double)(1u << 24);
  }
  if (!V) return;
  for (int i = 0; i < 20; ++i) /* duplicates: ties */
    memcpy(V + 3 * (100 + i), V + 3 * i, 3 * sizeof(double));
  V[3 * 50] = NAN;
  km__nearest_x ix;
  CHECK_OK(km__nearest_x_build(V, N, &ix, KM_E));
  size_t same = 0;
  for (int q = 0; q < Q; ++q) {
    double p[3];
    for (int c = 0; c < 3; ++c) {
      seed = seed * 1664525u + 1013904223u;
      p[c] = 1.2 * (double)(seed >> 8) / (double)(1u << 24) - 0.1;
    }
    if (q < 20) memcpy(p, V + 3 * q, sizeof p); /* on a duplicated point */
    int32_t a = -1;
    km_nearest_vertices(V, N, p, 1, &a, NULL);
    same += km__nearest_x_query(&ix, p) == a;
  }
  CHECK_MSG(same == Q, "km__nearest_x: %zu of %d queries as the brute force", same, Q);
  km__nearest_x_free(&ix);
  free(V);

  static const double T[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  static const int32_t TF[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  km_mesh two = {0};
  CHECK_OK(km_mesh_alloc(8, 8, &two, KM_E));
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 12; ++i) {
      two.V[12 * k + i] = T[i] + (i % 3 == 0 ? 3.0 * k : 0);
      two.F[12 * k + i] = TF[i] + 4 * k;
    }
  km__body bd;
  bool found = true;
  CHECK_OK(km__mesh_body(&two, &bd, &found, KM_E));
  CHECK(!found && bd.to_body == NULL && bd.n_pieces == 2 && bd.body_vertices == 4 &&
        bd.largest_other == 4);
  km__body_free(&bd);
  km_mesh_free(&two);
  /* a body: a strip of 18 triangles (20 vertices, 4.5 x 1), a small tetrahedron beside it,
   * which follows the one body vertex nearest to it as a whole, and a quad lying 0.01 over the
   * whole strip (it wraps the body), whose vertices follow their own nearest ones */
  km_mesh m = {0};
  CHECK_OK(km_mesh_alloc(28, 24, &m, KM_E));
  for (int i = 0; i < 20; ++i)
    m.V[3 * i] = 0.5 * (i / 2), m.V[3 * i + 1] = i % 2, m.V[3 * i + 2] = 0;
  for (int t = 0; t < 18; ++t)
    for (int c = 0; c < 3; ++c)
      m.F[3 * t + c] = t + (t % 2 ? (c == 1 ? 2 : c == 2 ? 1 : 0) : c);
  for (int i = 0; i < 12; ++i) {
    m.V[60 + i] = 0.1 * T[i] + (i % 3 == 0 ? 2.02 : i % 3 == 2 ? 0.3 : 0);
    m.F[54 + i] = TF[i] + 20;
  }
  static const double QV[12] = {0, 0, 0.01, 4.5, 0, 0.01, 4.5, 1, 0.01, 0, 1, 0.01};
  static const int32_t QF[6] = {24, 25, 26, 24, 26, 27};
  memcpy(m.V + 72, QV, sizeof QV);
  memcpy(m.F + 66, QF, sizeof QF);
  CHECK_OK(km__mesh_body(&m, &bd, &found, KM_E));
  CHECK(found && bd.n_pieces == 3 && bd.body_vertices == 20 && bd.largest_other == 4);
  if (found) {
    CHECK(bd.body.n_vertices == 20 && bd.body.n_faces == 18);
    bool ok = true;
    for (int i = 0; i < 20; ++i)
      ok = ok && bd.to_body[i] == i && bd.from_body[i] == i;
    CHECK_MSG(ok, "km__mesh_body: the body's vertices");
    int32_t held = -1, a = -1;
    double best = INFINITY, d = 0;
    for (int i = 20; i < 24; ++i) { /* the body vertex nearest to the tetrahedron */
      km_nearest_vertices(m.V, 20, m.V + 3 * i, 1, &a, &d);
      if (d < best) best = d, held = a;
    }
    for (int i = 20; i < 24; ++i)
      CHECK_MSG(bd.to_body[i] == held, "tetrahedron vertex %d follows body vertex %d, not %d", i,
                bd.to_body[i], held);
    for (int i = 24; i < 28; ++i) {
      km_nearest_vertices(m.V, 20, m.V + 3 * i, 1, &a, NULL);
      CHECK_MSG(bd.to_body[i] == a, "quad vertex %d follows body vertex %d, not its nearest %d", i,
                bd.to_body[i], a);
    }
  }
  km__body_free(&bd);
  /* a sliver 2 long standing on the strip, half its vertices at the strip's surface (a prop
   * held in a hand, half inside it): it reaches away from the body, so it turns rigidly with
   * one body vertex instead of wrapping the body */
  km_mesh bx = {0};
  CHECK_OK(km_mesh_alloc(24, 22, &bx, KM_E));
  memcpy(bx.V, m.V, 20 * 3 * sizeof(double));
  memcpy(bx.F, m.F, 18 * 3 * sizeof(int32_t));
  static const double SV[12] = {2, 0, 0.02, 2.05, 0.05, 0.02, 2, 0, 2, 2.05, 0.1, 2};
  memcpy(bx.V + 60, SV, sizeof SV);
  for (int i = 0; i < 12; ++i)
    bx.F[54 + i] = TF[i] + 20;
  CHECK_OK(km__mesh_body(&bx, &bd, &found, KM_E));
  CHECK_MSG(found && bd.n_pieces == 2 && bd.rigid_pieces == 1,
            "a sliver reaching away from the body: %zu pieces, %zu rigid", bd.n_pieces,
            bd.rigid_pieces);
  bool one = found;
  for (int k = 1; found && k < 4; ++k)
    one = one && bd.to_body[20 + k] == bd.to_body[20];
  CHECK_MSG(one, "the sliver's vertices follow one body vertex");
  km__body_free(&bd);
  km_mesh_free(&bx);
  km_mesh_info mi;
  CHECK_OK(km_mesh_info_compute(&m, &mi, KM_E));
  CHECK_MSG(mi.pieces == 3 && mi.ground_pieces == 0, "pieces %zu, on the floor %zu", mi.pieces,
            mi.ground_pieces);
  /* a quad 0.2 under the strip (y up: a ground plane) lies on the floor; turned so that y
   * points sideways it does not (ground_pieces asks with y as up) */
  km_mesh g = {0};
  CHECK_OK(km_mesh_alloc(32, 26, &g, KM_E));
  memcpy(g.V, m.V, 28 * 3 * sizeof(double));
  memcpy(g.F, m.F, 24 * 3 * sizeof(int32_t));
  static const double GV[12] = {-1, -0.2, -2, 5.5, -0.2, -2, 5.5, -0.2, 2, -1, -0.2, 2};
  static const int32_t GF[6] = {28, 30, 29, 28, 31, 30};
  memcpy(g.V + 84, GV, sizeof GV);
  memcpy(g.F + 72, GF, sizeof GF);
  CHECK_OK(km_mesh_info_compute(&g, &mi, KM_E));
  CHECK_MSG(mi.pieces == 4 && mi.ground_pieces == 1, "pieces %zu, on the floor %zu", mi.pieces,
            mi.ground_pieces);
  for (size_t v = 0; v < g.n_vertices; ++v) { /* (x, y, z) -> (x, z, -y) */
    double y = g.V[3 * v + 1];
    g.V[3 * v + 1] = g.V[3 * v + 2], g.V[3 * v + 2] = -y;
  }
  CHECK_OK(km_mesh_info_compute(&g, &mi, KM_E));
  CHECK_MSG(mi.pieces == 4 && mi.ground_pieces == 0, "turned: pieces %zu, on the floor %zu",
            mi.pieces, mi.ground_pieces);
  km_mesh_free(&g);
  km_mesh_free(&m);
}

int main(void) {
  test_nearest_and_body();
  test_seated_base();
  test_boundary_loops();
  test_farthest_points();
  test_tetrahedron();
  test_seams();
  test_open_square_and_extras();
  test_nonmanifold();
  test_grid();
  test_random_against_brute_force();
  test_invalid();
  test_shared_armadillo();
  return km_test_finish("test_topology");
}
