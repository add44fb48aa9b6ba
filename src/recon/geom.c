#include "recon/recon.h"
#include "math/math.h"

#include <embree3/rtcore.h>
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

static RTCDevice g_device;
static pthread_once_t g_device_once = PTHREAD_ONCE_INIT;
static void device_init(void) { g_device = rtcNewDevice(NULL); }

void *km__embree_device(km_error *err) {
  pthread_once(&g_device_once, device_init);
  if (!g_device) km__fail(err, KM_ERR_UNSUPPORTED, "Embree: rtcNewDevice failed");
  return g_device;
}

/* ---------------------------------------------------------------- closest point on triangle */

/* Ericson, Real-Time Collision Detection 5.1.5: Voronoi regions of the triangle. */
double km__closest_on_triangle(const double *p, const double *a, const double *b, const double *c,
                               double *w) {
  double ab[3], ac[3], ap[3];
  for (int k = 0; k < 3; ++k)
    ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
  double d1 = km__dot3(ab, ap), d2 = km__dot3(ac, ap);
  double u, v, t;
  if (d1 <= 0 && d2 <= 0) {
    u = 1, v = 0, t = 0;
    goto done;
  }
  double bp[3];
  for (int k = 0; k < 3; ++k)
    bp[k] = p[k] - b[k];
  double d3 = km__dot3(ab, bp), d4 = km__dot3(ac, bp);
  if (d3 >= 0 && d4 <= d3) {
    u = 0, v = 1, t = 0;
    goto done;
  }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    double s = d1 / (d1 - d3);
    u = 1 - s, v = s, t = 0;
    goto done;
  }
  double cp[3];
  for (int k = 0; k < 3; ++k)
    cp[k] = p[k] - c[k];
  double d5 = km__dot3(ab, cp), d6 = km__dot3(ac, cp);
  if (d6 >= 0 && d5 <= d6) {
    u = 0, v = 0, t = 1;
    goto done;
  }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    double s = d2 / (d2 - d6);
    u = 1 - s, v = 0, t = s;
    goto done;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    double s = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    u = 0, v = 1 - s, t = s;
    goto done;
  }
  {
    double den = va + vb + vc;
    if (!(fabs(den) > 0)) { /* degenerate triangle: fall back to vertex a */
      u = 1, v = 0, t = 0;
      goto done;
    }
    v = vb / den, t = vc / den, u = 1 - v - t;
  }
done:
  w[0] = u, w[1] = v, w[2] = t;
  double q[3], d2s = 0;
  for (int k = 0; k < 3; ++k)
    q[k] = u * a[k] + v * b[k] + t * c[k] - p[k], d2s += q[k] * q[k];
  return d2s;
}

/* ---------------------------------------------------------------- mesh closest points */

struct km__surface {
  RTCScene scene;
  RTCGeometry geom;
  float *vb;
  const double *V;
  const int32_t *F;
  size_t nv, nf;
  const bool *skip; /* nf or NULL: faces no closest point lands on (km__surface_skip) */
};

typedef struct closest_query {
  const km__surface *s;
  double p[3];
  double best_d2;
  int32_t tri;
  double w[3];
} closest_query;

static bool closest_cb(struct RTCPointQueryFunctionArguments *args) {
  closest_query *q = args->userPtr;
  const km__surface *s = q->s;
  unsigned f = args->primID;
  if (s->skip && s->skip[f]) return false;
  const int32_t *t = s->F + 3 * (size_t)f;
  double w[3];
  double d2 = km__closest_on_triangle(q->p, s->V + 3 * (size_t)t[0], s->V + 3 * (size_t)t[1],
                                      s->V + 3 * (size_t)t[2], w);
  if (d2 < q->best_d2) {
    q->best_d2 = d2;
    q->tri = (int32_t)f;
    memcpy(q->w, w, sizeof w);
    /* Embree tests float bounds: keep a small margin so rounding never hides the winner */
    args->query->radius = (float)(sqrt(d2) * (1 + 1e-5) + 1e-7);
    return true;
  }
  return false;
}

static void fill_vb(km__surface *s) {
  for (size_t i = 0; i < s->nv; ++i) {
    s->vb[4 * i + 0] = (float)s->V[3 * i + 0];
    s->vb[4 * i + 1] = (float)s->V[3 * i + 1];
    s->vb[4 * i + 2] = (float)s->V[3 * i + 2];
    s->vb[4 * i + 3] = 0;
  }
}

km_status km__surface_create(const double *V, size_t nv, const int32_t *F, size_t nf,
                             km__surface **out, km_error *err) {
  *out = NULL;
  RTCDevice dev = km__embree_device(err);
  if (!dev) return KM_ERR_UNSUPPORTED;
  if (!nf || !nv) return km__fail(err, KM_ERR_DEGENERATE_MESH, "closest point: mesh has no faces");
  for (size_t i = 0; i < 3 * nf; ++i)
    if (F[i] < 0 || (size_t)F[i] >= nv)
      return km__fail(err, KM_ERR_INVALID, "closest point: face index %d out of range", F[i]);
  km__surface *s = calloc(1, sizeof *s);
  if (!s) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  s->V = V, s->F = F, s->nv = nv, s->nf = nf;
  s->scene = rtcNewScene(dev);
  rtcSetSceneFlags(s->scene, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s->scene, RTC_BUILD_QUALITY_LOW);
  s->geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(s->geom, RTC_BUILD_QUALITY_REFIT);
  s->vb = rtcSetNewGeometryBuffer(s->geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                  4 * sizeof(float), nv);
  unsigned *ib = rtcSetNewGeometryBuffer(s->geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                         3 * sizeof(unsigned), nf);
  if (!s->vb || !ib) {
    rtcReleaseGeometry(s->geom);
    rtcReleaseScene(s->scene);
    free(s);
    return km__fail(err, KM_ERR_NOMEM, "Embree: cannot allocate buffers");
  }
  for (size_t i = 0; i < 3 * nf; ++i)
    ib[i] = (unsigned)F[i];
  fill_vb(s);
  rtcSetGeometryPointQueryFunction(s->geom, closest_cb);
  rtcCommitGeometry(s->geom);
  rtcAttachGeometry(s->scene, s->geom);
  rtcCommitScene(s->scene);
  *out = s;
  return KM_OK;
}

void km__surface_skip(km__surface *s, const bool *skip) { s->skip = skip; }

void km__surface_update(km__surface *s, const double *V) {
  s->V = V;
  fill_vb(s);
  rtcUpdateGeometryBuffer(s->geom, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(s->geom);
  rtcCommitScene(s->scene);
}

void km__surface_closest(const km__surface *s, const double *Q, size_t n, double max_dist,
                         int32_t *tri, double *bary, double *dist) {
#pragma omp parallel for schedule(dynamic, 256) if (n > KM__OMP_MIN)
  for (size_t i = 0; i < n; ++i) {
    closest_query q = {.s = s, .best_d2 = INFINITY, .tri = -1};
    memcpy(q.p, Q + 3 * i, sizeof q.p);
    struct RTCPointQuery pq = {(float)q.p[0], (float)q.p[1], (float)q.p[2], 0,
                               max_dist > 0 ? (float)max_dist : INFINITY};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(s->scene, &pq, &ctx, NULL, &q);
    if (max_dist > 0 && q.best_d2 > max_dist * max_dist) q.tri = -1;
    tri[i] = q.tri;
    if (bary) memcpy(bary + 3 * i, q.w, sizeof q.w);
    if (dist) dist[i] = q.tri >= 0 ? sqrt(q.best_d2) : INFINITY;
  }
}

/* For each segment org[i] -> tgt[i]: whether a face of the surface crosses it strictly inside
 * (beyond tnear, a length, from both ends, so the faces at a vertex the segment starts on do
 * not count). Embree's occlusion query (rtcOccluded1) on the closest-point structure's BVH. */
void km__surface_occluded(const km__surface *s, const double *org, const double *tgt, size_t n,
                          double tnear, uint8_t *occluded) {
#pragma omp parallel for schedule(dynamic, 256) if (n > KM__OMP_MIN)
  for (size_t i = 0; i < n; ++i) {
    const double *o = org + 3 * i, *t = tgt + 3 * i;
    double d[3] = {t[0] - o[0], t[1] - o[1], t[2] - o[2]};
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (len <= 2 * tnear) {
      occluded[i] = 0;
      continue;
    }
    struct RTCRay ray = {.org_x = (float)o[0],
                         .org_y = (float)o[1],
                         .org_z = (float)o[2],
                         .tnear = (float)tnear,
                         .dir_x = (float)(d[0] / len),
                         .dir_y = (float)(d[1] / len),
                         .dir_z = (float)(d[2] / len),
                         .tfar = (float)(len - tnear),
                         .mask = (unsigned)-1,
                         .flags = 0};
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(s->scene, &ctx, &ray);
    occluded[i] = ray.tfar < 0; /* Embree sets tfar to -inf on a hit */
  }
}

void km__surface_free(km__surface **s) {
  if (!s || !*s) return;
  rtcReleaseGeometry((*s)->geom);
  rtcReleaseScene((*s)->scene);
  free(*s);
  *s = NULL;
}

/* ---------------------------------------------------------------- k nearest neighbours */
/* Embree user geometry of points: the same BVH and point-query machinery as the closest
 * surface point, which copes with the very uneven density of captured clouds (a uniform
 * grid hash would need a cell size per region). */

typedef struct knn_geom {
  const double *P;
} knn_geom;

typedef struct knn_query {
  const double *P;
  double p[3];
  int k, count;
  int32_t *idx;
  double *d2; /* max-heap by distance of size count */
} knn_query;

static void knn_bounds(const struct RTCBoundsFunctionArguments *args) {
  const knn_geom *g = args->geometryUserPtr;
  const double *p = g->P + 3 * (size_t)args->primID;
  struct RTCBounds *b = args->bounds_o;
  b->lower_x = nextafterf((float)p[0], -INFINITY);
  b->lower_y = nextafterf((float)p[1], -INFINITY);
  b->lower_z = nextafterf((float)p[2], -INFINITY);
  b->upper_x = nextafterf((float)p[0], INFINITY);
  b->upper_y = nextafterf((float)p[1], INFINITY);
  b->upper_z = nextafterf((float)p[2], INFINITY);
}

static void heap_sift_down(knn_query *q, int i) {
  for (;;) {
    int l = 2 * i + 1, r = l + 1, m = i;
    if (l < q->count && q->d2[l] > q->d2[m]) m = l;
    if (r < q->count && q->d2[r] > q->d2[m]) m = r;
    if (m == i) return;
    double td = q->d2[i];
    int32_t ti = q->idx[i];
    q->d2[i] = q->d2[m], q->idx[i] = q->idx[m];
    q->d2[m] = td, q->idx[m] = ti;
    i = m;
  }
}

static bool knn_cb(struct RTCPointQueryFunctionArguments *args) {
  knn_query *q = args->userPtr;
  const double *p = q->P + 3 * (size_t)args->primID;
  double d[3] = {p[0] - q->p[0], p[1] - q->p[1], p[2] - q->p[2]};
  double d2 = km__dot3(d, d);
  if (q->count < q->k) {
    int i = q->count++;
    q->d2[i] = d2, q->idx[i] = (int32_t)args->primID;
    while (i > 0 && q->d2[(i - 1) / 2] < q->d2[i]) {
      int par = (i - 1) / 2;
      double td = q->d2[i];
      int32_t ti = q->idx[i];
      q->d2[i] = q->d2[par], q->idx[i] = q->idx[par];
      q->d2[par] = td, q->idx[par] = ti;
      i = par;
    }
  } else if (d2 < q->d2[0]) {
    q->d2[0] = d2, q->idx[0] = (int32_t)args->primID;
    heap_sift_down(q, 0);
  } else {
    return false;
  }
  if (q->count == q->k) {
    args->query->radius = (float)(sqrt(q->d2[0]) * (1 + 1e-5) + 1e-9);
    return true;
  }
  return false;
}

/* k nearest neighbours of every point of P (the points the scene was built over). */
static void knn_scene(RTCScene scene, const double *P, size_t n, int k, int32_t *idx) {
#pragma omp parallel if (n > KM__OMP_MIN)
  {
    double d2[64];
    int kk = k > 64 ? 64 : k;
#pragma omp for schedule(dynamic, 512)
    for (size_t i = 0; i < n; ++i) {
      knn_query q = {.P = P, .k = kk, .idx = idx + (size_t)k * i, .d2 = d2};
      memcpy(q.p, P + 3 * i, sizeof q.p);
      struct RTCPointQuery pq = {(float)q.p[0], (float)q.p[1], (float)q.p[2], 0, INFINITY};
      struct RTCPointQueryContext ctx;
      rtcInitPointQueryContext(&ctx);
      rtcPointQuery(scene, &pq, &ctx, NULL, &q);
      for (int j = q.count; j < k; ++j)
        idx[(size_t)k * i + j] = (int32_t)i;
    }
  }
}

struct km__point_index {
  RTCScene scene;
  knn_geom g; /* over the distinct points (P itself when there are no duplicates) */
  size_t n, nu;
  double *U;      /* nu*3 distinct positions; NULL when nu == n */
  int32_t *start; /* nu+1: members of distinct point u are mem[start[u] .. start[u+1]) */
  int32_t *mem;   /* n original ids, grouped, ascending within a group */
};

/* k nearest neighbours over the distinct points, expanded to their copies: a cloud with many
 * copies of one point (a depth sensor's zeros, a stuck pixel) costs O(n k), where querying
 * the copies themselves would visit every copy from every copy (quadratic). */
static void knn_dedup(const km__point_index *ix, int k, int32_t *idx) {
  const size_t nu = ix->nu;
#pragma omp parallel if (nu > KM__OMP_MIN)
  {
    double d2[64];
    int32_t near[64];
    int kk = k > 64 ? 64 : k;
    if ((size_t)kk > nu) kk = (int)nu;
#pragma omp for schedule(dynamic, 512)
    for (size_t u = 0; u < nu; ++u) {
      knn_query q = {.P = ix->U, .k = kk, .idx = near, .d2 = d2};
      memcpy(q.p, ix->U + 3 * u, sizeof q.p);
      struct RTCPointQuery pq = {(float)q.p[0], (float)q.p[1], (float)q.p[2], 0, INFINITY};
      struct RTCPointQueryContext ctx;
      rtcInitPointQueryContext(&ctx);
      rtcPointQuery(ix->scene, &pq, &ctx, NULL, &q);
      /* nearest first, so the point's own copies come before farther points */
      for (int a = 1; a < q.count; ++a)
        for (int b = a; b > 0 && d2[b - 1] > d2[b]; --b) {
          double td = d2[b];
          int32_t ti = near[b];
          d2[b] = d2[b - 1], near[b] = near[b - 1];
          d2[b - 1] = td, near[b - 1] = ti;
        }
      for (int32_t m = ix->start[u]; m < ix->start[u + 1]; ++m) {
        int32_t i = ix->mem[m], *out = idx + (size_t)k * (size_t)i;
        int c = 0;
        for (int r = 0; r < q.count && c < kk; ++r)
          for (int32_t t = ix->start[near[r]]; t < ix->start[near[r] + 1] && c < kk; ++t)
            out[c++] = ix->mem[t];
        while (c < k)
          out[c++] = i;
      }
    }
  }
}

km_status km__knn(const double *P, size_t n, int k, int32_t *idx, km_error *err) {
  if (k < 1 || (size_t)k > n)
    return km__fail(err, KM_ERR_INVALID, "knn: k=%d with %zu points", k, n);
  km__point_index *ix = NULL;
  km_status s = km__point_index_create(P, n, &ix, err);
  if (s) return s;
  s = km__point_index_knn(ix, n, k, idx, err);
  km__point_index_free(&ix);
  return s;
}

typedef struct pt_key {
  double x[3];
  int32_t i;
} pt_key;

/* By the bytes of the coordinates: a total order even with NaN; copies are bit-equal. */
static int cmp_pt_key(const void *a, const void *b) {
  const pt_key *p = a, *q = b;
  int c = memcmp(p->x, q->x, sizeof p->x);
  return c ? c : (p->i > q->i) - (p->i < q->i);
}

/* Groups exact copies (ix->U, start, mem); leaves them NULL when every point is distinct. */
static km_status group_copies(km__point_index *ix, const double *P, size_t n, km_error *err) {
  ix->n = ix->nu = n;
  if (n < 2) return KM_OK;
  pt_key *key = km__malloc(n, sizeof *key);
  if (!key) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  for (size_t i = 0; i < n; ++i) {
    memcpy(key[i].x, P + 3 * i, sizeof key[i].x);
    key[i].i = (int32_t)i;
  }
  qsort(key, n, sizeof *key, cmp_pt_key);
  size_t nu = 1;
  for (size_t i = 1; i < n; ++i)
    nu += memcmp(key[i].x, key[i - 1].x, sizeof key[i].x) != 0;
  if (nu == n) {
    free(key);
    return KM_OK;
  }
  ix->U = km__malloc(nu, 3 * sizeof(double));
  ix->start = km__malloc(nu + 1, sizeof(int32_t));
  ix->mem = km__malloc(n, sizeof(int32_t));
  if (!ix->U || !ix->start || !ix->mem) {
    free(key);
    return km__fail(err, KM_ERR_NOMEM, "out of memory");
  }
  size_t u = 0;
  for (size_t i = 0; i < n; ++i) {
    if (i == 0 || memcmp(key[i].x, key[i - 1].x, sizeof key[i].x)) {
      memcpy(ix->U + 3 * u, key[i].x, sizeof key[i].x);
      ix->start[u++] = (int32_t)i;
    }
    ix->mem[i] = key[i].i;
  }
  ix->start[nu] = (int32_t)n;
  ix->nu = nu;
  free(key);
  return KM_OK;
}

km_status km__point_index_create(const double *P, size_t n, km__point_index **out, km_error *err) {
  *out = NULL;
  RTCDevice dev = km__embree_device(err);
  if (!dev) return KM_ERR_UNSUPPORTED;
  km__point_index *ix = calloc(1, sizeof *ix);
  if (!ix) return km__fail(err, KM_ERR_NOMEM, "out of memory");
  km_status gs = group_copies(ix, P, n, err);
  if (gs) {
    free(ix->U), free(ix->start), free(ix->mem), free(ix);
    return gs;
  }
  ix->g.P = ix->U ? ix->U : P;
  ix->scene = rtcNewScene(dev);
  RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geom, (unsigned)ix->nu);
  rtcSetGeometryUserData(geom, &ix->g);
  rtcSetGeometryBoundsFunction(geom, knn_bounds, &ix->g);
  rtcSetGeometryPointQueryFunction(geom, knn_cb);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(ix->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(ix->scene);
  *out = ix;
  return KM_OK;
}

km_status km__point_index_knn(const km__point_index *ix, size_t n, int k, int32_t *idx,
                              km_error *err) {
  if (k < 1 || (size_t)k > n)
    return km__fail(err, KM_ERR_INVALID, "knn: k=%d with %zu points", k, n);
  if (n != ix->n)
    return km__fail(err, KM_ERR_INVALID, "knn: %zu points, the index has %zu", n, ix->n);
  if (ix->U)
    knn_dedup(ix, k, idx);
  else
    knn_scene(ix->scene, ix->g.P, n, k, idx);
  return KM_OK;
}

void km__point_index_nearest(const km__point_index *ix, const double *Q, size_t nq, double max_dist,
                             int32_t *idx, double *dist) {
#pragma omp parallel for schedule(dynamic, 256) if (nq > KM__OMP_MIN)
  for (size_t i = 0; i < nq; ++i) {
    double d2 = INFINITY;
    int32_t id = -1;
    knn_query q = {.P = ix->g.P, .k = 1, .idx = &id, .d2 = &d2};
    memcpy(q.p, Q + 3 * i, sizeof q.p);
    struct RTCPointQuery pq = {(float)q.p[0], (float)q.p[1], (float)q.p[2], 0,
                               max_dist > 0 ? (float)max_dist : INFINITY};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(ix->scene, &pq, &ctx, NULL, &q);
    if (q.count == 0 || (max_dist > 0 && d2 > max_dist * max_dist)) id = -1;
    if (id >= 0 && ix->U) id = ix->mem[ix->start[id]]; /* the first copy of that point */
    idx[i] = id;
    if (dist) dist[i] = id >= 0 ? sqrt(d2) : INFINITY;
  }
}

void km__point_index_free(km__point_index **ix) {
  if (!ix || !*ix) return;
  rtcReleaseScene((*ix)->scene);
  free((*ix)->U);
  free((*ix)->start);
  free((*ix)->mem);
  free(*ix);
  *ix = NULL;
}

static void covariance(const double *P, const int32_t *ids, size_t m, double c[3], double C[9]) {
  c[0] = c[1] = c[2] = 0;
  for (size_t j = 0; j < m; ++j)
    for (int a = 0; a < 3; ++a)
      c[a] += P[3 * (size_t)ids[j] + a];
  for (int a = 0; a < 3; ++a)
    c[a] /= (double)(m ? m : 1);
  memset(C, 0, 9 * sizeof *C);
  for (size_t j = 0; j < m; ++j) {
    const double *p = P + 3 * (size_t)ids[j];
    double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        C[3 * a + b] += d[a] * d[b];
  }
}

km_status km__point_normals(const double *P, size_t n, int k, double *N, km_error *err) {
  return km__point_normals_indexed(P, n, NULL, k, N, err);
}

km_status km__point_normals_indexed(const double *P, size_t n, const km__point_index *ix, int k,
                                    double *N, km_error *err) {
  if ((size_t)k > n) k = (int)n;
  if (k > 64) k = 64;
  int32_t *idx = km__malloc(n, (size_t)k * sizeof *idx);
  if (!idx) return km__fail(err, KM_ERR_NOMEM, "normals: out of memory");
  km_status s = ix ? km__point_index_knn(ix, n, k, idx, err) : km__knn(P, n, k, idx, err);
  if (!s) {
#pragma omp parallel for schedule(static) if (n > KM__OMP_MIN)
    for (size_t i = 0; i < n; ++i) {
      double c[3], C[9], ev[3], V[9];
      covariance(P, idx + (size_t)k * i, (size_t)k, c, C);
      km__sym_eig3(C, ev, V); /* descending: the normal is the last column */
      N[3 * i + 0] = V[2], N[3 * i + 1] = V[5], N[3 * i + 2] = V[8];
    }
  }
  free(idx);
  return s;
}

/* ---------------------------------------------------------------- multiresolution clustering */
/* Pauly, Gross & Kobbelt 2002, hierarchical clustering: a cluster is split through its
 * centroid along the direction of greatest variance while it is bigger than max_size or its
 * surface variation lambda0/(lambda0+lambda1+lambda2) exceeds max_var. Flat regions end as
 * big clusters, curved ones as small ones. */

typedef struct cluster_ctx {
  const double *P;
  int32_t *ids;
  int32_t *reps;
  size_t n_reps, cap;
  size_t max_size;
  double max_var;
} cluster_ctx;

static void cluster_rec(cluster_ctx *cx, size_t lo, size_t hi, int depth) {
  size_t m = hi - lo;
  if (!m) return;
  double c[3], C[9], ev[3], V[9];
  covariance(cx->P, cx->ids + lo, m, c, C);
  km__sym_eig3(C, ev, V); /* descending */
  double tr = ev[0] + ev[1] + ev[2];
  double var = tr > 0 ? ev[2] / tr : 0;
  bool split = m > cx->max_size || (var > cx->max_var && m > 4);
  if (split && depth < 60 && m > 1) {
    double ax[3] = {V[0], V[3], V[6]};
    size_t i = lo, j = hi;
    while (i < j) {
      const double *p = cx->P + 3 * (size_t)cx->ids[i];
      double d = (p[0] - c[0]) * ax[0] + (p[1] - c[1]) * ax[1] + (p[2] - c[2]) * ax[2];
      if (d < 0)
        ++i;
      else {
        --j;
        int32_t t = cx->ids[i];
        cx->ids[i] = cx->ids[j];
        cx->ids[j] = t;
      }
    }
    if (i > lo && i < hi) {
      cluster_rec(cx, lo, i, depth + 1);
      cluster_rec(cx, i, hi, depth + 1);
      return;
    }
  }
  if (cx->n_reps == cx->cap) return;
  double best = INFINITY;
  int32_t bi = cx->ids[lo];
  for (size_t j = lo; j < hi; ++j) {
    const double *p = cx->P + 3 * (size_t)cx->ids[j];
    double d = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
               (p[2] - c[2]) * (p[2] - c[2]);
    if (d < best) best = d, bi = cx->ids[j];
  }
  cx->reps[cx->n_reps++] = bi;
}

km_status km__cluster_points(const double *P, size_t n, size_t target, int32_t **reps,
                             size_t *n_reps, km_error *err) {
  *reps = NULL;
  *n_reps = 0;
  if (!n) return KM_OK;
  if (target < 1) target = 1;
  cluster_ctx cx = {.P = P};
  cx.ids = km__malloc(n, sizeof *cx.ids);
  cx.reps = km__malloc(n, sizeof *cx.reps);
  if (!cx.ids || !cx.reps) {
    free(cx.ids);
    free(cx.reps);
    return km__fail(err, KM_ERR_NOMEM, "clustering: out of memory");
  }
  cx.cap = n;
  /* Size bound and curvature bound chosen together: about half the clusters come from the
   * size bound, the rest from curvature; the variation threshold is searched so that the
   * count lands near target. */
  double lo = 0.0005, hi = 0.2;
  for (int it = 0; it < 12; ++it) {
    cx.max_size = (size_t)(2.0 * (double)n / (double)target) + 1;
    cx.max_var = sqrt(lo * hi);
    cx.n_reps = 0;
    for (size_t i = 0; i < n; ++i)
      cx.ids[i] = (int32_t)i;
    cluster_rec(&cx, 0, n, 0);
    if (cx.n_reps > target * 11 / 10)
      lo = cx.max_var;
    else if (cx.n_reps < target * 9 / 10)
      hi = cx.max_var;
    else
      break;
  }
  free(cx.ids);
  *reps = cx.reps;
  *n_reps = cx.n_reps;
  return KM_OK;
}

km_status km_point_mesh_distance(const double *V, size_t n_vertices, const int32_t *F,
                                 size_t n_faces, const double *Q, size_t n_queries, int32_t *tri,
                                 double *bary, double *dist, km_error *err) {
  if (!V || !F || (!Q && n_queries))
    return km__fail(err, KM_ERR_INVALID, "km_point_mesh_distance: NULL argument");
  int32_t *t = tri ? tri : km__malloc(n_queries ? n_queries : 1, sizeof *t);
  if (!t) return km__fail(err, KM_ERR_NOMEM, "km_point_mesh_distance: out of memory");
  km__surface *s = NULL;
  km_status st = km__surface_create(V, n_vertices, F, n_faces, &s, err);
  if (st == KM_OK) km__surface_closest(s, Q, n_queries, 0, t, bary, dist);
  km__surface_free(&s);
  if (t != tri) free(t);
  return st;
}
