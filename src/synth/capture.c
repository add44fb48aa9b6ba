/* Capture simulator: multi-view depth cameras ray-cast with Embree, giving the point cloud
 * animation a ground truth (the posed meshes). */
#include "recon/recon.h"
#include "synth/synth.h"
#include "math/math.h"

#include <embree3/rtcore.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static uint64_t splitmix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
static double unit(uint64_t h) { return ((double)(h >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
/* Box-Muller from a per-ray hash so the noise is independent of thread scheduling. */
static void gauss3(uint64_t key, double g[3]) {
  double u1 = unit(splitmix(key)), u2 = unit(splitmix(key ^ 0x1234567ULL));
  double u3 = unit(splitmix(key ^ 0xabcdefULL)), u4 = unit(splitmix(key ^ 0x7777777ULL));
  double r1 = sqrt(-2 * log(u1)), r2 = sqrt(-2 * log(u3));
  g[0] = r1 * cos(2 * M_PI * u2);
  g[1] = r1 * sin(2 * M_PI * u2);
  g[2] = r2 * cos(2 * M_PI * u4);
}

typedef struct cam {
  double o[3], fwd[3], right[3], up[3];
  double u0, u1, v0, v1; /* image-plane extent (tangents) of the mesh bbox */
} cam;

/* Casts a res x res grid (scaled to the bbox extent) from every camera; hits (after noise)
 * go to out when out != NULL. Returns the hit count. */
static size_t cast(RTCScene scene, const cam *cams, int nc, double spacing, double sigma,
                   uint64_t seed, double *out, size_t cap) {
  size_t total = 0;
  for (int c = 0; c < nc; ++c) {
    const cam *k = &cams[c];
    size_t nu = (size_t)ceil((k->u1 - k->u0) / spacing) + 1;
    size_t nv = (size_t)ceil((k->v1 - k->v0) / spacing) + 1;
    if (nu > 4096) nu = 4096;
    if (nv > 4096) nv = 4096;
    size_t npix = nu * nv;
    double *hit = out ? malloc(npix * 3 * sizeof *hit) : NULL;
    unsigned char *ok = malloc(npix);
    if (!ok || (out && !hit)) {
      free(hit);
      free(ok);
      return total;
    }
#pragma omp parallel for schedule(dynamic, 64)
    for (size_t pix = 0; pix < npix; ++pix) {
      double u = k->u0 + spacing * (double)(pix % nu), v = k->v0 + spacing * (double)(pix / nu);
      double d[3];
      for (int a = 0; a < 3; ++a)
        d[a] = k->fwd[a] + u * k->right[a] + v * k->up[a];
      km__normalize3(d);
      struct RTCRayHit rh;
      memset(&rh, 0, sizeof rh);
      rh.ray.org_x = (float)k->o[0], rh.ray.org_y = (float)k->o[1], rh.ray.org_z = (float)k->o[2];
      rh.ray.dir_x = (float)d[0], rh.ray.dir_y = (float)d[1], rh.ray.dir_z = (float)d[2];
      rh.ray.tnear = 0, rh.ray.tfar = INFINITY, rh.ray.mask = 0xffffffffu;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      struct RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      rtcIntersect1(scene, &ctx, &rh);
      ok[pix] = 0;
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      double n[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
      km__normalize3(n);
      /* depth sensors return nothing at grazing incidence */
      if (fabs(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) < 0.15) continue;
      ok[pix] = 1;
      if (hit) {
        double g[3] = {0, 0, 0};
        if (sigma > 0) gauss3(seed ^ ((uint64_t)c << 40) ^ (uint64_t)pix * 0x9e3779b1ULL, g);
        for (int a = 0; a < 3; ++a)
          hit[3 * pix + a] = k->o[a] + rh.ray.tfar * d[a] + sigma * g[a];
      }
    }
    for (size_t pix = 0; pix < npix; ++pix) {
      if (!ok[pix]) continue;
      if (out && total < cap) memcpy(out + 3 * total, hit + 3 * pix, 3 * sizeof *out);
      ++total;
    }
    free(hit);
    free(ok);
  }
  return total;
}

km_status km_capture_frame(const km_mesh *posed, const km_capture_options *opt, size_t frame,
                           km_points *out, km_error *err) {
  if (!posed || !out) return km__fail(err, KM_ERR_INVALID, "km_capture_frame: NULL argument");
  memset(out, 0, sizeof *out);
  km_capture_options o = opt ? *opt : (km_capture_options){0};
  int nc = o.cameras > 0 ? o.cameras : 4;
  if (nc > 64) return km__fail(err, KM_ERR_INVALID, "km_capture_frame: %d cameras (max 64)", nc);
  size_t target = o.points_per_frame ? o.points_per_frame : 30000;
  double sigma = o.noise_mm < 0 ? 0 : (o.noise_mm == 0 ? 2.0 : o.noise_mm) * 1e-3;
  double dist = o.distance > 0 ? o.distance : 3.0;
  double height = o.height != 0 ? o.height : 0.3;
  if (!posed->n_faces)
    return km__fail(err, KM_ERR_DEGENERATE_MESH, "km_capture_frame: mesh has no faces");
  RTCDevice dev = km__embree_device(err);
  if (!dev) return KM_ERR_UNSUPPORTED;
  for (size_t i = 0; i < 3 * posed->n_faces; ++i)
    if (posed->F[i] < 0 || (size_t)posed->F[i] >= posed->n_vertices)
      return km__fail(err, KM_ERR_INVALID, "km_capture_frame: face index %d out of range",
                      posed->F[i]);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < posed->n_vertices; ++i)
    for (int a = 0; a < 3; ++a) {
      double v = posed->V[3 * i + a];
      if (v < lo[a]) lo[a] = v;
      if (v > hi[a]) hi[a] = v;
    }
  RTCScene scene = rtcNewScene(dev);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                      3 * sizeof(float), posed->n_vertices);
  unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                         3 * sizeof(unsigned), posed->n_faces);
  if (!vb || !ib) {
    rtcReleaseGeometry(g);
    rtcReleaseScene(scene);
    return km__fail(err, KM_ERR_NOMEM, "Embree: cannot allocate buffers");
  }
  for (size_t i = 0; i < 3 * posed->n_vertices; ++i)
    vb[i] = (float)posed->V[i];
  for (size_t i = 0; i < 3 * posed->n_faces; ++i)
    ib[i] = (unsigned)posed->F[i];
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(scene);

  /* Cameras on a horizontal ring (y up) around the bbox centre, looking at it. */
  double ctr[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
  cam cams[64];
  for (int c = 0; c < nc; ++c) {
    double ang = 2 * M_PI * (c + 0.5) / nc;
    cam *k = &cams[c];
    k->o[0] = ctr[0] + dist * sin(ang);
    k->o[1] = ctr[1] + height;
    k->o[2] = ctr[2] + dist * cos(ang);
    for (int a = 0; a < 3; ++a)
      k->fwd[a] = ctr[a] - k->o[a];
    km__normalize3(k->fwd);
    double upw[3] = {0, 1, 0};
    k->right[0] = k->fwd[1] * upw[2] - k->fwd[2] * upw[1];
    k->right[1] = k->fwd[2] * upw[0] - k->fwd[0] * upw[2];
    k->right[2] = k->fwd[0] * upw[1] - k->fwd[1] * upw[0];
    km__normalize3(k->right);
    k->up[0] = k->right[1] * k->fwd[2] - k->right[2] * k->fwd[1];
    k->up[1] = k->right[2] * k->fwd[0] - k->right[0] * k->fwd[2];
    k->up[2] = k->right[0] * k->fwd[1] - k->right[1] * k->fwd[0];
    k->u0 = k->v0 = INFINITY, k->u1 = k->v1 = -INFINITY;
    for (int corner = 0; corner < 8; ++corner) {
      double p[3] = {corner & 1 ? hi[0] : lo[0], corner & 2 ? hi[1] : lo[1],
                     corner & 4 ? hi[2] : lo[2]};
      double d[3] = {p[0] - k->o[0], p[1] - k->o[1], p[2] - k->o[2]};
      double z = d[0] * k->fwd[0] + d[1] * k->fwd[1] + d[2] * k->fwd[2];
      if (z < 1e-6) z = 1e-6; /* bbox reaching behind the camera: clamp */
      double u = (d[0] * k->right[0] + d[1] * k->right[1] + d[2] * k->right[2]) / z;
      double v = (d[0] * k->up[0] + d[1] * k->up[1] + d[2] * k->up[2]) / z;
      if (u < k->u0) k->u0 = u;
      if (u > k->u1) k->u1 = u;
      if (v < k->v0) k->v0 = v;
      if (v > k->v1) k->v1 = v;
    }
  }
  /* A probe at coarse spacing measures how much of the view the subject fills; the final
   * spacing then gives about `target` hits in total. */
  double area = 0;
  for (int c = 0; c < nc; ++c)
    area += (cams[c].u1 - cams[c].u0) * (cams[c].v1 - cams[c].v0);
  double spacing = sqrt(area / (double)target);
  size_t probe = cast(scene, cams, nc, spacing * 2, 0, 0, NULL, 0);
  if (probe) spacing = spacing * 2 * sqrt((double)probe / (double)target);
  size_t n = cast(scene, cams, nc, spacing, 0, 0, NULL, 0);
  out->P = km__malloc(n ? n : 1, 3 * sizeof(double));
  if (!out->P) {
    rtcReleaseScene(scene);
    return km__fail(err, KM_ERR_NOMEM, "km_capture_frame: out of memory");
  }
  uint64_t seed = splitmix(o.seed ^ splitmix(frame + 1));
  out->n = cast(scene, cams, nc, spacing, sigma, seed, out->P, n);
  if (out->n > n) out->n = n;
  rtcReleaseScene(scene);
  return KM_OK;
}

km_status km_capture_simulate(const km_character *c, const km_take *take,
                              const km_capture_options *opt, const char *out_dir, km_error *err) {
  if (!c || !take || !out_dir)
    return km__fail(err, KM_ERR_INVALID, "km_capture_simulate: NULL argument");
  if (take->n_joints != c->skeleton.n_joints)
    return km__fail(err, KM_ERR_INVALID, "km_capture_simulate: take has %zu joints, skeleton %zu",
                    take->n_joints, c->skeleton.n_joints);
  km_status ps = km__make_parents(out_dir, err); /* missing folders above out_dir */
  if (ps) return ps;
  if (mkdir(out_dir, 0777) != 0 && errno != EEXIST)
    return km__fail(err, KM_ERR_IO, "%s: cannot create directory: %s", out_dir, strerror(errno));
  km_capture_options o = opt ? *opt : (km_capture_options){0};
  size_t nv = c->mesh.n_vertices, nj = c->skeleton.n_joints;
  char path[4096];
  /* OBJ, not PLY: the frames are listed by extension (the directory, or a glob of its .ply
   * files), and the rest mesh must not be read back as one more frame. */
  snprintf(path, sizeof path, "%s/truth_rest.obj", out_dir);
  km_status s = km_mesh_write(path, &c->mesh, NULL, err);
  if (s) return s;
  snprintf(path, sizeof path, "%s/truth.pc2", out_dir);
  km_anim_options ao = {.format = KM_ANIM_PC2, .fps = take->fps > 0 ? take->fps : 30};
  km_anim_writer *w = NULL;
  s = km_anim_writer_open(path, &c->mesh, &ao, &w, err);
  if (s) return s;
  double *T = km__malloc(nj, 12 * sizeof(double));
  km_mesh posed = {.F = c->mesh.F, .n_faces = c->mesh.n_faces, .n_vertices = nv};
  posed.V = km__malloc(nv, 3 * sizeof(double));
  if (!T || !posed.V) {
    s = km__fail(err, KM_ERR_NOMEM, "km_capture_simulate: out of memory");
    goto done;
  }
  for (size_t f = 0; f < take->n_frames; ++f) {
    s = km_skeleton_pose_from_positions(&c->skeleton, take->positions + f * nj * 3, T, err);
    if (!s) s = km_lbs(c->mesh.V, nv, &c->skin, T, nj, posed.V, err);
    km_points pts = {0};
    if (!s) s = km_capture_frame(&posed, &o, f, &pts, err);
    if (!s) {
      snprintf(path, sizeof path, "%s/frame_%05zu.ply", out_dir, f);
      s = km_points_write_ply(path, pts.P, pts.n, err);
    }
    km_points_free(&pts);
    if (!s) s = km_anim_writer_push(w, posed.V, err);
    if (s) goto done;
    if (!km__progress(&o.progress, (double)(f + 1) / (double)take->n_frames, "capture")) {
      s = km__fail(err, KM_ERR_CANCELLED, "km_capture_simulate: cancelled at frame %zu", f);
      goto done;
    }
  }
  s = km_anim_writer_close(&w, err);
done:
  km_anim_writer_free(&w);
  free(T);
  free(posed.V);
  return s;
}
