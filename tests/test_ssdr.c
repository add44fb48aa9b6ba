/* Skinning decomposition (km_ssdr_fit, Le & Deng 2012) and the skinned glb export: an
 * animation made by linear blend skinning from a known rig is recovered (RMS <= 0.1 mm), the
 * weights are sparse and convex, an error budget adds bones, and the .glb, evaluated the way
 * a viewer does (joint TRS x inverse bind matrix, blended by JOINTS_0/WEIGHTS_0), gives back
 * the frames within the reported error. */
#include "km_test.h"
#include "tube_fixture.h"

#include <cjson/cJSON.h>
#include <stdint.h>
#include <unistd.h>

#define RINGS 48
#define SEGS 20
#define NB 4
#define FRAMES 30

/* The tube (tube_fixture.h) rigged with four bones in a chain (0, 0.3, 0.6, 0.9 m), each vertex
 * blended between the two bones nearest its x over a 0.1 m band. */
static void make_tube(km_mesh *m, km_skin *skin) {
  tube_mesh(m, RINGS, SEGS, false);
  skin->n_vertices = m->n_vertices;
  skin->joints = malloc(m->n_vertices * 4 * sizeof(int32_t));
  skin->weights = malloc(m->n_vertices * 4 * sizeof(double));
  for (size_t i = 0; i < m->n_vertices; ++i) {
    double x = m->V[3 * i];
    int b = (int)(x / 0.3);
    if (b > NB - 1) b = NB - 1;
    double w1 = 0; /* share of the next bone near its joint at 0.3 (b + 1) */
    double d = x - 0.3 * (b + 1);
    if (b < NB - 1 && d > -0.1) w1 = (d + 0.1) / 0.2;
    if (b > 0 && x - 0.3 * b < 0.1) { /* near the joint to the previous bone */
      double wprev = 0.5 - (x - 0.3 * b) / 0.2;
      skin->joints[4 * i] = b - 1, skin->weights[4 * i] = wprev;
      skin->joints[4 * i + 1] = b, skin->weights[4 * i + 1] = 1 - wprev;
    } else {
      skin->joints[4 * i] = b, skin->weights[4 * i] = 1 - w1;
      skin->joints[4 * i + 1] = b + 1 < NB ? b + 1 : b, skin->weights[4 * i + 1] = w1;
    }
    skin->joints[4 * i + 2] = skin->joints[4 * i + 3] = -1;
    skin->weights[4 * i + 2] = skin->weights[4 * i + 3] = 0;
  }
}

/* Forward kinematics of the chain: each joint turns about z and y by smooth functions of the
 * frame; the root also moves. G: NB*12 row-major [R | t] rest -> posed. */
static void chain_pose(int k, double *G) {
  double W[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, P[3] = {0.05 * sin(0.2 * k), 0.02 * k * 0.1, 0};
  for (int j = 0; j < NB; ++j) {
    double az = 0.5 * sin(0.3 * k + j), ay = 0.3 * cos(0.25 * k + 2 * j);
    double Rz[9] = {cos(az), -sin(az), 0, sin(az), cos(az), 0, 0, 0, 1};
    double Ry[9] = {cos(ay), 0, sin(ay), 0, 1, 0, -sin(ay), 0, cos(ay)};
    double L[9], Wn[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        L[3 * r + c] = 0;
        for (int q = 0; q < 3; ++q)
          L[3 * r + c] += Rz[3 * r + q] * Ry[3 * q + c];
      }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        Wn[3 * r + c] = 0;
        for (int q = 0; q < 3; ++q)
          Wn[3 * r + c] += W[3 * r + q] * L[3 * q + c];
      }
    if (j > 0) /* joint j sits at the end of bone j-1: P += W_parent (0.3, 0, 0) */
      for (int r = 0; r < 3; ++r)
        P[r] += W[3 * r] * 0.3;
    memcpy(W, Wn, sizeof W);
    /* G x = W (x - J) + P with J = (0.3 j, 1, 0) */
    double J[3] = {0.3 * j, 1.0, 0};
    for (int r = 0; r < 3; ++r) {
      G[12 * j + 4 * r] = W[3 * r], G[12 * j + 4 * r + 1] = W[3 * r + 1],
                     G[12 * j + 4 * r + 2] = W[3 * r + 2];
      G[12 * j + 4 * r + 3] =
          P[r] + (r == 1 ? 1.0 : 0) - (W[3 * r] * J[0] + W[3 * r + 1] * J[1] + W[3 * r + 2] * J[2]);
    }
  }
}

static double *lbs_frames(const km_mesh *m, const km_skin *skin) {
  double *fr = malloc((size_t)FRAMES * m->n_vertices * 3 * sizeof(double)), G[NB * 12];
  for (int k = 0; k < FRAMES; ++k) {
    chain_pose(k, G);
    CHECK_OK(km_lbs(m->V, m->n_vertices, skin, G, NB, fr + (size_t)k * m->n_vertices * 3, KM_E));
  }
  return fr;
}

static void check_skin(const km_ssdr *r) {
  size_t bad = 0;
  for (size_t i = 0; i < r->n_vertices; ++i) {
    double sum = 0;
    for (int k = 0; k < 4; ++k) {
      int32_t j = r->skin.joints[4 * i + k];
      double w = r->skin.weights[4 * i + k];
      if (j < 0) {
        bad += w != 0;
        continue;
      }
      bad += (size_t)j >= r->n_bones || !(w >= 0);
      sum += w;
    }
    bad += fabs(sum - 1) > 1e-12;
  }
  CHECK_MSG(bad == 0, "%zu bad weights", bad);
}

/* ---- an independent evaluation of the skinned glb, as a viewer does it */

static const unsigned char *acc_data(const cJSON *root, const unsigned char *bin, int a,
                                     int *count) {
  const cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "accessors"), a);
  const cJSON *view = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "bufferViews"),
                                         cJSON_GetObjectItem(acc, "bufferView")->valueint);
  *count = cJSON_GetObjectItem(acc, "count")->valueint;
  const cJSON *o = cJSON_GetObjectItem(view, "byteOffset");
  return bin + (o ? (size_t)o->valuedouble : 0);
}

/* Max distance between the glb's skinned positions at key k and `exact`. */
static double glb_frame_error(const char *path, int k, const double *exact, size_t nv) {
  size_t n = 0;
  unsigned char *b = read_all(path, &n);
  if (!b || n < 28) return INFINITY;
  uint32_t jl = getu32(b + 12);
  cJSON *root = cJSON_ParseWithLength((const char *)b + 20, jl);
  const unsigned char *bin = b + 20 + jl + 8;
  double worst = INFINITY;
  if (!root) goto out;
  const cJSON *prim = cJSON_GetArrayItem(
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "meshes"), 0), "primitives"),
      0);
  const cJSON *at = cJSON_GetObjectItem(prim, "attributes");
  int cnt;
  const unsigned char *pos =
      acc_data(root, bin, cJSON_GetObjectItem(at, "POSITION")->valueint, &cnt);
  const unsigned char *jo =
      acc_data(root, bin, cJSON_GetObjectItem(at, "JOINTS_0")->valueint, &cnt);
  const unsigned char *we =
      acc_data(root, bin, cJSON_GetObjectItem(at, "WEIGHTS_0")->valueint, &cnt);
  const cJSON *skin = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "skins"), 0);
  const cJSON *joints = cJSON_GetObjectItem(skin, "joints");
  int nb = cJSON_GetArraySize(joints);
  const unsigned char *ibm =
      acc_data(root, bin, cJSON_GetObjectItem(skin, "inverseBindMatrices")->valueint, &cnt);
  /* joint matrices: node TRS at key k (from the channels) x inverse bind */
  double *Mj = calloc((size_t)nb * 12, sizeof(double));
  const cJSON *anim = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "animations"), 0);
  const cJSON *samplers = cJSON_GetObjectItem(anim, "samplers");
  double *Tr = calloc((size_t)nb * 3, sizeof(double)), *Q = calloc((size_t)nb * 4, sizeof(double));
  const cJSON *ch;
  cJSON_ArrayForEach(ch, cJSON_GetObjectItem(anim, "channels")) {
    const cJSON *tg = cJSON_GetObjectItem(ch, "target");
    int node = cJSON_GetObjectItem(tg, "node")->valueint, j = -1;
    for (int q = 0; q < nb; ++q)
      if (cJSON_GetArrayItem(joints, q)->valueint == node) j = q;
    const cJSON *sm = cJSON_GetArrayItem(samplers, cJSON_GetObjectItem(ch, "sampler")->valueint);
    const unsigned char *o = acc_data(root, bin, cJSON_GetObjectItem(sm, "output")->valueint, &cnt);
    const char *path_s = cJSON_GetObjectItem(tg, "path")->valuestring;
    if (j < 0 || k >= cnt) goto out;
    if (!strcmp(path_s, "translation"))
      for (int a = 0; a < 3; ++a)
        Tr[3 * j + a] = getf(o + 12 * k + 4 * a);
    else
      for (int a = 0; a < 4; ++a)
        Q[4 * j + a] = getf(o + 16 * k + 4 * a);
  }
  for (int j = 0; j < nb; ++j) {
    double x = Q[4 * j], y = Q[4 * j + 1], z = Q[4 * j + 2], w = Q[4 * j + 3];
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
                   2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                   2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
    double I[16]; /* column-major */
    for (int q = 0; q < 16; ++q)
      I[q] = getf(ibm + 64 * j + 4 * q);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        double s = c == 3 ? Tr[3 * j + r] : 0;
        for (int q = 0; q < 3; ++q)
          s += R[3 * r + q] * I[4 * c + q];
        Mj[12 * j + 4 * r + c] = s;
      }
    }
  }
  worst = 0;
  for (size_t i = 0; i < nv; ++i) {
    double p[3] = {getf(pos + 12 * i), getf(pos + 12 * i + 4), getf(pos + 12 * i + 8)}, v[3] = {0};
    for (int s = 0; s < 4; ++s) {
      int j = jo[4 * i + s];
      double w = getf(we + 16 * i + 4 * s);
      for (int r = 0; r < 3; ++r)
        v[r] += w * (Mj[12 * j + 4 * r] * p[0] + Mj[12 * j + 4 * r + 1] * p[1] +
                     Mj[12 * j + 4 * r + 2] * p[2] + Mj[12 * j + 4 * r + 3]);
    }
    double d = sqrt(pow(v[0] - exact[3 * i], 2) + pow(v[1] - exact[3 * i + 1], 2) +
                    pow(v[2] - exact[3 * i + 2], 2));
    if (d > worst) worst = d;
  }
  free(Mj);
  free(Tr);
  free(Q);
out:
  cJSON_Delete(root);
  free(b);
  return worst;
}

int main(void) {
  km_mesh m = {0};
  km_skin truth = {0};
  make_tube(&m, &truth);
  double *fr = lbs_frames(&m, &truth);
  const size_t nv = m.n_vertices;

  /* 1. recovery of a known LBS rig */
  km_ssdr r = {0};
  km_ssdr_options o = {.bones = NB, .iterations = 30};
  CHECK_OK(km_ssdr_fit(m.V, nv, fr, FRAMES, &o, &r, KM_E));
  CHECK(r.n_bones >= 1 && r.n_bones <= NB);
  CHECK(r.n_frames == FRAMES && r.n_vertices == nv);
  CHECK_MSG(r.rms_error <= 1e-4, "rms %.4f mm", r.rms_error * 1e3);
  CHECK_MSG(r.max_error <= 1e-3, "max %.4f mm", r.max_error * 1e3);
  printf("ssdr on a known %d-bone LBS rig: rms %.4f mm, max %.4f mm\n", NB, r.rms_error * 1e3,
         r.max_error * 1e3);
  check_skin(&r);
  /* the reported error is the real one: recompute frame 17 through km_lbs */
  {
    double *V = malloc(nv * 3 * sizeof(double)), worst = 0;
    CHECK_OK(km_lbs(m.V, nv, &r.skin, r.transforms + 17 * r.n_bones * 12, r.n_bones, V, KM_E));
    for (size_t i = 0; i < nv * 3; ++i)
      worst = fmax(worst, fabs(V[i] - fr[17 * nv * 3 + i]));
    CHECK(worst <= r.max_error + 1e-12);
    free(V);
  }
  km_ssdr_free(&r);
  CHECK(r.transforms == NULL && r.skin.joints == NULL);

  /* 2. too few bones is worse; an error budget adds bones until met */
  km_ssdr_options o1 = {.bones = 1};
  CHECK_OK(km_ssdr_fit(m.V, nv, fr, FRAMES, &o1, &r, KM_E));
  double one = r.max_error;
  CHECK_MSG(one > 5e-3, "one bone max %.3f mm", one * 1e3);
  km_ssdr_free(&r);
  km_ssdr_options ob = {.bones = 1, .max_error_mm = 1.0, .max_bones = 12};
  CHECK_OK(km_ssdr_fit(m.V, nv, fr, FRAMES, &ob, &r, KM_E));
  CHECK_MSG(r.max_error * 1e3 <= 1.0, "budget 1 mm, max %.3f mm with %zu bones", r.max_error * 1e3,
            r.n_bones);
  CHECK(r.n_bones > 1);
  check_skin(&r);
  km_ssdr_free(&r);
  km_ssdr_options o2 = {.bones = 6, .influences = 2};
  CHECK_OK(km_ssdr_fit(m.V, nv, fr, FRAMES, &o2, &r, KM_E));
  for (size_t i = 0; i < nv; ++i)
    CHECK(r.skin.joints[4 * i + 2] < 0 && r.skin.joints[4 * i + 3] < 0);
  km_ssdr_free(&r);

  /* 3. bad input */
  CHECK_STATUS(km_ssdr_fit(NULL, nv, fr, FRAMES, NULL, &r, KM_E), KM_ERR_INVALID);
  CHECK_STATUS(km_ssdr_fit(m.V, 3, fr, FRAMES, NULL, &r, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_STATUS(km_ssdr_fit(m.V, nv, fr, 0, NULL, &r, KM_E), KM_ERR_INVALID);
  km_ssdr_options o5 = {.influences = 5};
  CHECK_STATUS(km_ssdr_fit(m.V, nv, fr, FRAMES, &o5, &r, KM_E), KM_ERR_INVALID);
  double keep = fr[100];
  fr[100] = NAN;
  CHECK_STATUS(km_ssdr_fit(m.V, nv, fr, FRAMES, NULL, &r, KM_E), KM_ERR_INVALID);
  fr[100] = keep;

  /* 4. the skinned glb through the writer, evaluated as a viewer does */
  char path[64];
  snprintf(path, sizeof path, "test_ssdr_%ld.glb", (long)getpid());
  km_ssdr_options so = {.bones = NB, .iterations = 30};
  km_anim_options ao = {.fps = 24, .export_kind = KM_ANIM_EXPORT_SKIN, .skin = &so};
  km_anim_writer *w = NULL;
  CHECK_OK(km_anim_writer_open(path, &m, &ao, &w, KM_E));
  for (int k = 0; k < FRAMES; ++k)
    CHECK_OK(km_anim_writer_push(w, fr + (size_t)k * nv * 3, KM_E));
  km_anim_report rep;
  CHECK_OK(km_anim_writer_finish(&w, &rep, KM_E));
  CHECK(w == NULL);
  CHECK(rep.export_kind == KM_ANIM_EXPORT_SKIN && rep.frames == FRAMES);
  CHECK(rep.bones >= 1 && rep.bones <= NB);
  CHECK_MSG(rep.rms_error <= 1e-4, "writer rms %.4f mm", rep.rms_error * 1e3);
  km_anim_info info;
  CHECK_OK(km_anim_info_read(path, &info, KM_E));
  CHECK(info.format == KM_ANIM_GLB && info.vertices == nv && info.faces == m.n_faces);
  CHECK(info.frames == FRAMES && info.timeline_frames == FRAMES);
  CHECK_NEAR(info.fps, 24, 1e-9);
  for (int k = 0; k < FRAMES; k += 7) {
    /* float32 TRS and positions add ~1e-6 m to the fit's error */
    double e = glb_frame_error(path, k, fr + (size_t)k * nv * 3, nv);
    CHECK_MSG(e <= rep.max_error + 2e-5, "frame %d: glb %.4f mm vs fit max %.4f mm", k, e * 1e3,
              rep.max_error * 1e3);
  }
  struct stat st;
  CHECK(stat(path, &st) == 0 && st.st_size < 200000);
  remove(path);
  /* a morph export keeps reporting no error */
  km_anim_options mo = {.fps = 24};
  CHECK_OK(km_anim_writer_open(path, &m, &mo, &w, KM_E));
  CHECK_OK(km_anim_writer_push(w, fr, KM_E));
  CHECK_OK(km_anim_writer_finish(&w, &rep, KM_E));
  CHECK(rep.export_kind == KM_ANIM_EXPORT_MORPHS && rep.frames == 1 && rep.max_error == 0);
  remove(path);

  /* 5. compact morphs: PCA basis targets + per-frame weights; all of them are exact */
  for (int pass = 0; pass < 2; ++pass) {
    km_anim_options po = {
        .fps = 24, .export_kind = KM_ANIM_EXPORT_MORPHS_PCA, .morphs = pass ? FRAMES : 3};
    CHECK_OK(km_anim_writer_open(path, &m, &po, &w, KM_E));
    for (int k = 0; k < FRAMES; ++k)
      CHECK_OK(km_anim_writer_push(w, fr + (size_t)k * nv * 3, KM_E));
    CHECK_OK(km_anim_writer_finish(&w, &rep, KM_E));
    CHECK(rep.export_kind == KM_ANIM_EXPORT_MORPHS_PCA && rep.frames == FRAMES);
    CHECK(rep.targets >= 1 && rep.targets <= (pass ? FRAMES : 3) + 1); /* + the offset */
    if (pass)
      CHECK_MSG(rep.max_error <= 1e-6, "all targets: max %.6f mm", rep.max_error * 1e3);
    else
      CHECK_MSG(rep.max_error > 1e-6 && rep.rms_error < rep.max_error, "3 targets: max %.3f mm",
                rep.max_error * 1e3);
    CHECK_OK(km_anim_info_read(path, &info, KM_E));
    CHECK(info.frames == FRAMES && info.vertices == nv);
    /* read back through km_anim_read: base + weights x targets at every frame */
    km_mesh back = {0};
    double *bf = NULL;
    km_anim_info bi;
    CHECK_OK(km_anim_read(path, &back, &bf, &bi, KM_E));
    if (bf) {
      CHECK(bi.frames == FRAMES && back.n_vertices == nv && back.n_faces == m.n_faces);
      double worst = 0;
      for (size_t i = 0; i < (size_t)FRAMES * nv * 3; ++i)
        worst = fmax(worst, fabs(bf[i] - fr[i]));
      CHECK_MSG(worst <= rep.max_error + 1e-5, "read back %.4f mm vs reported %.4f mm", worst * 1e3,
                rep.max_error * 1e3);
    }
    free(bf);
    km_mesh_free(&back);
    remove(path);
  }

  free(fr);
  km_skin_free(&truth);
  km_mesh_free(&m);
  return km_test_finish("test_ssdr");
}
