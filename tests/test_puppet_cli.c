/* End-to-end puppetry through the CLI: a real mesh driven by a real Kinect v1 recording, the
 * cache life cycle (build, reuse, corruption detected and rebuilt), and the demo. */
#include "km_test.h"

#include <cjson/cJSON.h>
#include <unistd.h>

static bool all_finite(const double *x, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!isfinite(x[i])) return false;
  return true;
}

/* Handles follow their joints: each mapped handle's centroid moves like its joint's (scaled)
 * displacement since the first frame. The filter lags a little and handles are soft
 * constraints, so the paths are compared as a whole: the mean distance between the two must
 * be small against the mean length of the joint path. `take` is in the rig's joint order. */
static void check_follows(const km_mesh *m, const km_rig *rig, const km_take *take,
                          const double *frames, const km_anim_info *info, const char *label) {
  km_retarget *rt = NULL;
  CHECK_OK(km_retarget_create(rig, m, take->n_joints, NULL, &rt, KM_E));
  km_retarget_push(rt, take->positions, NULL);
  double s = km_retarget_scale(rt);
  CHECK(isfinite(s) && s > 0);
  for (size_t e = 0; e < rig->n_maps; ++e) {
    const km_rig_handle *h = &rig->handles[rig->maps[e].handle];
    int j = rig->maps[e].joint;
    double c0[3] = {0, 0, 0}, err_sum = 0, path_sum = 0;
    const double *j0 = NULL;
    /* A bone handle (issue 12) follows its bone, posed on the character's skeleton: its path
     * is the retargeter's target for it (the unfiltered take through a fresh retargeter). */
    km_retarget *bt = NULL;
    double *bt_targets = NULL, bt0[3] = {0, 0, 0};
    if (rig->maps[e].bone_from > 0) {
      CHECK_OK(km_retarget_create(rig, m, take->n_joints, NULL, &bt, KM_E));
      bt_targets = malloc(3 * rig->n_handles * sizeof(double));
    }
    for (size_t f = 0; f < take->n_frames; ++f) {
      const double *jf = take->positions + (f * take->n_joints + (size_t)j) * 3;
      double bone_want[3] = {0, 0, 0};
      if (bt && bt_targets) {
        km_retarget_push(bt, take->positions + f * take->n_joints * 3, bt_targets);
        double tg[3]; /* in the output frame (rigid root motion) */
        memcpy(tg, bt_targets + 3 * (size_t)rig->maps[e].handle, sizeof tg);
        km_retarget_apply_root(bt, tg, 1);
        if (!j0 && isfinite(jf[0])) memcpy(bt0, tg, sizeof bt0);
        for (int a = 0; a < 3; ++a)
          bone_want[a] = tg[a] - bt0[a];
      }
      double c[3] = {0, 0, 0};
      for (size_t i = 0; i < h->n_vertices; ++i)
        for (int a = 0; a < 3; ++a)
          c[a] +=
              frames[(f * info->vertices + (size_t)h->vertices[i]) * 3 + a] / (double)h->n_vertices;
      if (!j0) {
        if (!isfinite(jf[0])) continue;
        j0 = jf;
        memcpy(c0, c, sizeof c0);
      }
      if (!isfinite(jf[0])) continue;
      double d_err = 0, d_path = 0;
      for (int a = 0; a < 3; ++a) {
        double want = bt ? bone_want[a] : s * (jf[a] - j0[a]);
        d_err += pow(c[a] - c0[a] - want, 2);
        d_path += want * want;
      }
      err_sum += sqrt(d_err);
      path_sum += sqrt(d_path);
    }
    CHECK_MSG(path_sum > 0 && err_sum < 0.25 * path_sum,
              "%s: handle %s vs joint %s: mean deviation %.1f%% of the mean joint displacement",
              label, h->name, km_kinect1_joint_name(j),
              100 * err_sum / (path_sum > 0 ? path_sum : 1));
    km_retarget_free(&bt);
    free(bt_targets);
  }
  km_retarget_free(&rt);
}

/* The floor (issue 12): a sidecar from `rig` keeps the feet out of the ground ("floor": true);
 * `animate --no-floor` turns it off, and the armadillo_1k's toes, tipped down with the
 * performer's feet in cmu_131_01's kicks, go lower again (measured 26 mm lower at worst);
 * --floor with --no-floor is refused and writes nothing. */
static double lowest_y(const char *pc2) {
  double *fr = NULL, y = INFINITY;
  km_anim_info info;
  CHECK_OK(km_pc2_read(pc2, &fr, &info, KM_E));
  for (size_t i = 0; fr && i < info.frames * info.vertices; ++i)
    y = fmin(y, fr[3 * i + 1]);
  free(fr);
  return y;
}

static void test_floor_switch(const char *mesh, const char *bvh) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s' -o puppet_fl.rig.json 2>&1", mesh);
  CHECK(km_test_run(cmd, NULL) == 0);
  CHECK_MSG(km_test_run("grep -Eq '\"floor\":[[:space:]]*true' puppet_fl.rig.json", NULL) == 0,
            "rig wrote no \"floor\": true");
  char *out = NULL;
  snprintf(cmd, sizeof cmd,
           KM_CLI " animate --mesh '%s' --rig puppet_fl.rig.json --motion '%s' -o "
                  "puppet_fl_on.pc2 2>&1",
           mesh, bvh);
  CHECK(km_test_run(cmd, NULL) == 0);
  snprintf(cmd, sizeof cmd,
           KM_CLI " animate --no-floor --mesh '%s' --rig puppet_fl.rig.json --motion '%s' -o "
                  "puppet_fl_off.pc2 2>&1",
           mesh, bvh);
  CHECK(km_test_run(cmd, NULL) == 0);
  double on = lowest_y("puppet_fl_on.pc2"), off = lowest_y("puppet_fl_off.pc2");
  /* the rest floor: the lowest y of the mesh in kinemesh's frame, as animate turns it */
  double floor_y = INFINITY;
  {
    km_mesh cm = {0};
    km_frame_guess g;
    CHECK_OK(km_mesh_read(mesh, &cm, KM_E));
    CHECK_OK(km_mesh_frame_guess(&cm, &g, KM_E));
    CHECK_OK(km_mesh_frame_apply(&g.frame, &cm, KM_E));
    for (size_t v = 0; v < cm.n_vertices; ++v)
      floor_y = fmin(floor_y, cm.V[3 * v + 1]);
    km_mesh_free(&cm);
  }
  printf("armadillo_1k on cmu_131_01: lowest vertex %.4f with the floor (rest floor %.4f), %.4f "
         "without\n",
         on, floor_y, off);
  /* every vertex, not only the handles' (a toe outside the small foot handle went 3 cm under
   * before the solved mesh was held on it); pc2 stores floats */
  CHECK_MSG(on >= floor_y - 1e-5, "with the floor, a vertex at %.4f under the rest floor %.4f", on,
            floor_y);
  CHECK_MSG(off < on - 0.005, "--no-floor: lowest vertex %.4f, with the floor %.4f", off, on);
  snprintf(cmd, sizeof cmd,
           KM_CLI " animate --floor --no-floor --mesh '%s' --rig puppet_fl.rig.json --motion '%s' "
                  "-o puppet_fl_both.pc2 2>&1",
           mesh, bvh);
  CHECK(km_test_run(cmd, &out) == 1);
  CHECK_MSG(out && strstr(out, "--floor and --no-floor"), "message: %s", out ? out : "");
  free(out);
  CHECK(access("puppet_fl_both.pc2", F_OK) != 0);
  km_test_run("rm -f puppet_fl*", NULL);
}

static void test_real_mesh_real_skeleton(const char *mesh_src, const char *csv) {
  /* The cache goes to $XDG_CACHE_HOME (main sets it to puppet_cache/ in the build tree),
   * keyed by the mesh's hash, never beside the mesh. */
  char cmd[8192], *out = NULL, cache[512];
  snprintf(cmd, sizeof cmd, "cp '%s' puppet_a1k.off", mesh_src);
  CHECK(km_test_run(cmd, NULL) == 0);
  {
    km_mesh cm = {0};
    CHECK_OK(km_mesh_read("puppet_a1k.off", &cm, KM_E));
    /* animate turns the mesh into kinemesh's frame by its guess (this file faces -z) before
     * keying the cache */
    km_frame_guess g;
    CHECK_OK(km_mesh_frame_guess(&cm, &g, KM_E));
    CHECK_OK(km_mesh_frame_apply(&g.frame, &cm, KM_E));
    snprintf(cache, sizeof cache, "puppet_cache/kinemesh/%016llx.kmcache",
             (unsigned long long)km_mesh_hash(&cm));
    km_mesh_free(&cm);
    remove(cache);
  }
  const char *rig_path = KM_TEST_DATA "/armadillo_1k.rig.json";
  snprintf(cmd, sizeof cmd,
           KM_CLI " animate --mesh puppet_a1k.off --rig %s --motion '%s' -o puppet_a1k.pc2",
           rig_path, csv);
  CHECK(km_test_run(cmd, &out) == 0);
  CHECK_MSG(strstr(out, "t1 (s)") != NULL, "first run precomputes: %s", out);
  free(out);
  CHECK_MSG(access(cache, F_OK) == 0, "the cache is %s", cache);
  CHECK(access("puppet_a1k.off.kmcache", F_OK) != 0);

  km_take take = {0};
  km_mesh m = {0};
  km_rig rig = {0};
  double *frames = NULL;
  km_anim_info info;
  CHECK_OK(km_kinect_csv_read(csv, &take, NULL, KM_E));
  CHECK_OK(km_mesh_read("puppet_a1k.off", &m, KM_E));
  CHECK_OK(km_rig_read(rig_path, &m, NULL, 0, &rig, KM_E));
  CHECK_OK(km_pc2_read("puppet_a1k.pc2", &frames, &info, KM_E));
  /* One output frame per input frame, no NaN. */
  CHECK(info.frames == take.n_frames && info.vertices == m.n_vertices);
  if (frames && info.frames == take.n_frames && info.vertices == m.n_vertices) {
    CHECK(all_finite(frames, info.frames * info.vertices * 3));
    check_follows(&m, &rig, &take, frames, &info, "armadillo_1k + PRECOG");
  }

  /* Second run loads the cache (t~1) and gives the same animation bit for bit. */
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_a1k.off --rig " KM_TEST_DATA
                           "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_2.pc2",
                    &out) == 0);
  CHECK_MSG(strstr(out, "cache loaded") != NULL, "second run loads the cache: %s", out);
  free(out);
  double *frames2 = NULL;
  km_anim_info info2;
  CHECK_OK(km_pc2_read("puppet_a1k_2.pc2", &frames2, &info2, KM_E));
  CHECK(frames && frames2 && info2.frames == info.frames &&
        memcmp(frames, frames2, sizeof(double) * info.frames * info.vertices * 3) == 0);
  free(frames2);

  /* Corrupt one byte in the middle of the cache: detected, reported, rebuilt, same result. */
  FILE *f = fopen(cache, "r+b");
  CHECK(f != NULL);
  if (f) {
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, n / 2, SEEK_SET);
    int c = fgetc(f);
    fseek(f, n / 2, SEEK_SET);
    fputc(c ^ 0x5a, f);
    fclose(f);
  }
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_a1k.off --rig " KM_TEST_DATA
                           "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_3.pc2",
                    &out) == 0);
  CHECK_MSG(strstr(out, "rebuilding") != NULL, "corrupt cache reported: %s", out);
  free(out);
  frames2 = NULL;
  CHECK_OK(km_pc2_read("puppet_a1k_3.pc2", &frames2, &info2, KM_E));
  CHECK(frames && frames2 && info2.frames == info.frames &&
        memcmp(frames, frames2, sizeof(double) * info.frames * info.vertices * 3) == 0);
  free(frames2);
  /* ... and the rebuilt cache is good again. */
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_a1k.off --rig " KM_TEST_DATA
                           "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_4.pc2",
                    &out) == 0);
  CHECK(strstr(out, "cache loaded") != NULL);
  free(out);

  /* The full reference solver runs on the same input. */
  CHECK(km_test_run(KM_CLI " animate --solver full --mesh puppet_a1k.off --rig " KM_TEST_DATA
                           "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_full.pc2",
                    NULL) == 0);
  CHECK_OK(km_pc2_read("puppet_a1k_full.pc2", &frames2, &info2, KM_E));
  CHECK(info2.frames == take.n_frames && frames2 &&
        all_finite(frames2, info2.frames * info2.vertices * 3));
  /* its handles are soft by default; --handle-weight 0 makes them hard, another result */
  CHECK(km_test_run(
            KM_CLI
            " animate --solver full --handle-weight 0 --mesh puppet_a1k.off --rig " KM_TEST_DATA
            "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
            "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_hard.pc2",
            NULL) == 0);
  double *frames3 = NULL;
  km_anim_info info3;
  CHECK_OK(km_pc2_read("puppet_a1k_hard.pc2", &frames3, &info3, KM_E));
  if (frames2 && frames3 && info3.frames == info2.frames && info3.vertices == info2.vertices) {
    double d = 0;
    for (size_t i = 0; i < info2.frames * info2.vertices * 3; ++i)
      d = fmax(d, fabs(frames2[i] - frames3[i]));
    CHECK_MSG(d > 1e-6, "hard and soft handles gave the same frames (max difference %g)", d);
  }
  free(frames3);
  free(frames2);
  CHECK(km_test_run(KM_CLI " animate --solver full --handle-weight -1 --mesh puppet_a1k.off "
                           "--rig " KM_TEST_DATA "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_bad.pc2 2>&1",
                    &out) == 1);
  CHECK(out && strstr(out, "--handle-weight -1: expected a number >= 0"));
  free(out);
  out = NULL;
  CHECK(km_test_run(KM_CLI " animate --handle-weight 0.1 --mesh puppet_a1k.off --rig " KM_TEST_DATA
                           "/armadillo_1k.rig.json --motion '" KM_SHARED_DATA
                           "/skeleton/precog_Seq1_1.csv' -o puppet_a1k_bad.pc2 2>&1",
                    &out) == 1);
  CHECK(out && strstr(out, "--handle-weight is for --solver full"));
  free(out);
  CHECK(access("puppet_a1k_bad.pc2", F_OK) != 0);

  free(frames);
  km_rig_free(&rig);
  km_mesh_free(&m);
  km_take_free(&take);
  km_test_run("rm -f puppet_a1k*", NULL);
}

static void test_bad_rig_and_motion(void) {
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o puppet_c.obj", NULL) == 0);
  FILE *f = fopen("puppet_bad.rig.json", "w");
  fputs("{\"skeleton\":\"kinect1\",\"handles\":[{\"name\":\"h\",\"vertex\":3,\"radius\":0.05}],"
        "\"map\":[{\"handle\":\"h\",\"joint\":\"Tail\",\"axes\":\"xyz\"}]}",
        f);
  fclose(f);
  CHECK(km_test_run(KM_CLI " gen motion --frames 5 -o puppet_t.json", NULL) == 0);
  CHECK(km_test_run(KM_CLI
                    " animate --mesh puppet_c.obj --rig puppet_bad.rig.json --motion puppet_t.json "
                    "-o puppet_x.glb",
                    &out) == 1);
  CHECK_MSG(strstr(out, "puppet_bad.rig.json") && strstr(out, "Tail"), "%s", out);
  free(out);
  CHECK(access("puppet_x.glb", F_OK) != 0);
  CHECK(km_test_run(KM_CLI
                    " animate --mesh puppet_c.obj --motion no_such_take.json -o puppet_x.glb",
                    &out) == 1);
  CHECK(strstr(out, "no_such_take.json") != NULL);
  free(out);
  km_test_run("rm -f puppet_c.* puppet_bad.rig.json puppet_t.json", NULL);
}

/* The body as a person sees it: each frame's mean distance between the puppetry output and
 * the character skinned (km_lbs) by the take it was driven by, whose torso and neck turn
 * with the skeleton. Returns the worst frame's mean in metres (and its index). The kung-fu
 * spin once turned the limbs but not the handle-less torso: legs and neck twisted into ropes
 * at frame 80 (0.13 m off here while the handle checks passed; torso handles and rigid root
 * motion: 0.039 m at worst). */
static double worst_mean_from_skinned(const char *rig_path, const km_rig *rig, const km_mesh *m,
                                      const km_take *take, const double *frames,
                                      size_t *worst_frame) {
  km_character c = {0};
  km_filter *flt = NULL;
  double worst = INFINITY;
  if (km_character_read_rig(rig_path, m->n_vertices, &c, KM_E) != KM_OK ||
      km_filter_create(take->n_joints, &rig->filter, &flt, KM_E) != KM_OK) {
    km_character_free(&c);
    return worst;
  }
  size_t nv = m->n_vertices, nj = c.skeleton.n_joints;
  double *T = malloc(sizeof(double) * 12 * nj), *ref = malloc(sizeof(double) * 3 * nv);
  double *J = malloc(sizeof(double) * 3 * take->n_joints);
  worst = 0;
  for (size_t f = 0; f < take->n_frames && T && ref && J; ++f) {
    /* skinned by the joints the pipeline saw: the rig's filter lags fast moves */
    km_filter_push(flt, take->positions + f * take->n_joints * 3, J);
    if (km_skeleton_pose_from_positions(&c.skeleton, J, T, KM_E) != KM_OK ||
        km_lbs(m->V, nv, &c.skin, T, nj, ref, KM_E) != KM_OK) {
      worst = INFINITY;
      break;
    }
    double sum = 0;
    for (size_t v = 0; v < nv; ++v) {
      const double *a = frames + (f * nv + v) * 3, *b = ref + 3 * v;
      sum += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                  (a[2] - b[2]) * (a[2] - b[2]));
    }
    if (sum / (double)nv > worst) {
      worst = sum / (double)nv;
      *worst_frame = f;
    }
  }
  free(T);
  free(ref);
  free(J);
  km_filter_free(&flt);
  km_character_free(&c);
  return worst;
}

/* The demo's animation, also written as .pc2: one frame per take frame, no NaN, handles
 * following their joints, the body close to the skinned character on every frame. */
static void test_demo(void) {
  char *out = NULL;
  CHECK(
      km_test_run("rm -rf puppet_demo && mkdir puppet_demo && cd puppet_demo && bash " KM_TEST_DATA
                  "/../../scripts/demo.sh " KM_CLI,
                  &out) == 0);
  CHECK_MSG(strstr(out, "out/demo.glb") != NULL && strstr(out, "t4 (ms)") != NULL, "%s", out);
  free(out);
  km_anim_info info;
  CHECK_OK(km_anim_info_read("puppet_demo/out/demo.glb", &info, KM_E));
  CHECK(info.frames == 150 && info.vertices > 18000 && info.fps == 30);
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_demo/out/character.obj --motion "
                           "puppet_demo/out/kungfu.json -o puppet_demo/out/demo.pc2",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "cache loaded"), "the demo's cache is reused: %s", out ? out : "");
  free(out);
  km_mesh m = {0};
  km_take take = {0};
  km_rig rig = {0};
  double *frames = NULL;
  CHECK_OK(km_mesh_read("puppet_demo/out/character.obj", &m, KM_E));
  CHECK_OK(km_take_read("puppet_demo/out/kungfu.json", &take, KM_E));
  CHECK_OK(km_rig_read("puppet_demo/out/character.rig.json", &m, NULL, 0, &rig, KM_E));
  CHECK_OK(km_pc2_read("puppet_demo/out/demo.pc2", &frames, &info, KM_E));
  CHECK(rig.skeleton == KM_RIG_KINECT1 && take.n_joints == KM_KINECT1_JOINTS);
  for (size_t j = 0; j < take.n_joints && j < KM_KINECT1_JOINTS; ++j)
    CHECK(!strcmp(take.joint_names[j], km_kinect1_joint_name((int)j)));
  CHECK(frames && info.frames == take.n_frames && info.vertices == m.n_vertices);
  if (frames && info.frames == take.n_frames && info.vertices == m.n_vertices &&
      take.n_joints == KM_KINECT1_JOINTS) {
    CHECK(all_finite(frames, info.frames * info.vertices * 3));
    CHECK(rig.n_maps >= 5);
    check_follows(&m, &rig, &take, frames, &info, "demo");
    size_t wf = 0;
    double wm =
        worst_mean_from_skinned("puppet_demo/out/character.rig.json", &rig, &m, &take, frames, &wf);
    printf("demo: worst frame %zu: mean %.1f mm from the skinned character\n", wf, 1e3 * wm);
    CHECK_MSG(wm < 0.05, "demo frame %zu: mean %.1f mm from the skinned character (limit 50 mm)",
              wf, 1e3 * wm);
  }
  free(frames);
  km_rig_free(&rig);
  km_take_free(&take);
  km_mesh_free(&m);
  km_test_run("rm -rf puppet_demo", NULL);
}

/* A fresh folder DIR with a generated character DIR/c.obj (and its rig) of `vertices` and a
 * generated take DIR/w.json of `frames` frames for it (gen motion --kind: wave, kungfu, ...). */
static void character_and_take(const char *dir, int vertices, int frames, const char *kind) {
  char cmd[512];
  snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir %s", dir, dir);
  CHECK(km_test_run(cmd, NULL) == 0);
  snprintf(cmd, sizeof cmd, KM_CLI " gen character --vertices %d -o %s/c.obj", vertices, dir);
  CHECK(km_test_run(cmd, NULL) == 0);
  snprintf(cmd, sizeof cmd,
           KM_CLI " gen motion --kind %s --frames %d --character %s/c.obj -o %s/w.json", kind,
           frames, dir, dir);
  CHECK(km_test_run(cmd, NULL) == 0);
}

/* animate's deformation check: the summary line, and --report's JSON, whose per-frame stretch
 * is the tests' own edge measure on the frames written; a report that cannot be written is an
 * error naming it, and leaves no animation behind. */
static void test_report(void) {
  char *out = NULL;
  character_and_take("puppet_r", 2500, 16, "wave");
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_r/c.obj --motion puppet_r/w.json "
                           "-o puppet_r/x.pc2 --report puppet_r/new/r.json",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "shape: longest edge") && strstr(out, "frames have an edge over") &&
                strstr(out, "deformation check -> puppet_r/new/r.json"),
            "%s", out ? out : "");
  free(out);
  km_mesh m = {0};
  km_error err = {0};
  double *frames = NULL;
  km_anim_info info = {0};
  size_t n = 0;
  char *text = km_test_read_file("puppet_r/new/r.json", &n);
  cJSON *j = text ? cJSON_Parse(text) : NULL;
  CHECK_MSG(j != NULL, "report: %s", text ? text : "(none)");
  if (j && km_mesh_read("puppet_r/c.obj", &m, &err) == KM_OK &&
      km_pc2_read("puppet_r/x.pc2", &frames, &info, &err) == KM_OK) {
    cJSON *pf = cJSON_GetObjectItem(j, "per_frame");
    CHECK(cJSON_GetArraySize(pf) == (int)info.frames && info.frames == 16);
    CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "frames")) == 16);
    double worst = 0;
    for (size_t f = 0; f < info.frames; ++f) {
      double ref = km_test_edge_stretch(&m, frames + 3 * f * m.n_vertices);
      double got =
          cJSON_GetNumberValue(cJSON_GetObjectItem(cJSON_GetArrayItem(pf, (int)f), "stretch"));
      /* the pc2 holds floats */
      CHECK_MSG(fabs(got - ref) < 1e-4, "frame %zu: report %g, frames %g", f, got, ref);
      worst = fmax(worst, ref);
    }
    CHECK(fabs(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "stretch_max")) - worst) < 1e-4);
    CHECK(worst > 0); /* the wave moves the mesh */
    /* animate gives every frame what its handle targets force (a check of a file has none) */
    CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItem(j, "forced_edge_ratio_max")) &&
                  cJSON_GetObjectItem(cJSON_GetArrayItem(pf, 3), "forced_edge_ratio"),
              "no forced fields in the report");
  } else {
    CHECK_MSG(0, "reading back: %s", err.message);
  }
  cJSON_Delete(j);
  free(text);
  free(frames);
  km_mesh_free(&m);
  /* kinemesh check on the files written: the same measures */
  CHECK(km_test_run(KM_CLI " check puppet_r/x.pc2 --mesh puppet_r/c.obj --report puppet_r/r2.json",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "16 frames") && strstr(out, "shape: longest edge"), "%s",
            out ? out : "");
  free(out);
  char *t1 = km_test_read_file("puppet_r/new/r.json", &n),
       *t2 = km_test_read_file("puppet_r/r2.json", &n);
  cJSON *j1 = t1 ? cJSON_Parse(t1) : NULL, *j2 = t2 ? cJSON_Parse(t2) : NULL;
  CHECK(j1 && j2);
  if (j1 && j2) {
    static const char *const keys[] = {"stretch_max", "edge_ratio_min", "edge_ratio_max",
                                       "step_max_pct", "folded_triangles"};
    for (int k = 0; k < 5; ++k) {
      double a = cJSON_GetNumberValue(cJSON_GetObjectItem(j1, keys[k])),
             b = cJSON_GetNumberValue(cJSON_GetObjectItem(j2, keys[k]));
      CHECK_MSG(fabs(a - b) <= 1e-4 * fmax(1, fabs(a)), "%s: animate %g, check %g", keys[k], a, b);
    }
  }
  cJSON_Delete(j1);
  cJSON_Delete(j2);
  free(t1);
  free(t2);
  /* a .glb is checked against its base mesh: animate's own line, word for word */
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_r/c.obj --motion puppet_r/w.json "
                           "-o puppet_r/x.glb",
                    &out) == 0);
  char *line = out ? strstr(out, "  shape:") : NULL, *eol = line ? strchr(line, '\n') : NULL;
  if (eol) *eol = 0;
  char *out2 = NULL;
  CHECK(km_test_run(KM_CLI " check puppet_r/x.glb", &out2) == 0);
  /* near: the handle in animate, a vertex id without --rig; compare up to "near" */
  char *cut = line ? strstr(line, ", near") : NULL;
  if (cut) *cut = 0;
  CHECK_MSG(line && out2 && strstr(out2, line), "animate: %s\ncheck: %s", line ? line : "",
            out2 ? out2 : "");
  free(out);
  free(out2);
  /* limits: exit 3 when exceeded (a stretch limit below the measured one, and only it named:
   * the step's limit is far above), 0 within (every limit far above) */
  CHECK(km_test_run(KM_CLI " check puppet_r/x.glb --max-stretch 0.000001 --max-step 1000", &out) ==
        3);
  CHECK_MSG(out && strstr(out, "limits exceeded: stretch") && !strstr(out, "> 1000"), "%s",
            out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " check puppet_r/x.glb --max-stretch 100 --max-folded 1000000 "
                           "--max-step 1000",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "within the limits"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " check puppet_r/x.glb --max-folded -2", &out) == 1);
  free(out);
  /* bad input: named, exit 1 */
  CHECK(km_test_run(KM_CLI " check puppet_r/x.pc2", &out) == 1);
  CHECK_MSG(out && strstr(out, "--mesh"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " check puppet_r/x.pc2 --mesh puppet_r/c.obj --units cm", &out) == 1);
  CHECK_MSG(out && strstr(out, "not in its units"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o puppet_r/small.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " check puppet_r/x.pc2 --mesh puppet_r/small.obj", &out) == 1);
  CHECK_MSG(out && strstr(out, "not the same mesh"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_r/c.obj --motion puppet_r/w.json "
                           "-o puppet_r/y.pc2 --report /proc/no_such/r.json",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "/proc/no_such/r.json"), "%s", out ? out : "");
  free(out);
  CHECK(access("puppet_r/y.pc2", F_OK) != 0);
  km_test_run("rm -rf puppet_r", NULL);
}

/* animate says when the rig itself asks for a stretch (km_stretch_bound over the handle
 * targets): a kung-fu take bends the character's knees and elbows, and its bone handles ask for
 * more than 1.5x across them. With hard handles (the full solver, --handle-weight 0) every handle
 * is met, so the longest edge printed is at least what the handles ask for. */
static void test_forced_line(void) {
  char *out = NULL;
  character_and_take("puppet_f", 2500, 60, "kungfu");
  int rc = km_test_run(KM_CLI " animate --mesh puppet_f/c.obj --motion puppet_f/w.json "
                              "-o puppet_f/k.pc2 --solver full --handle-weight 0",
                       &out);
  const char *sh = out ? strstr(out, "shape: longest edge ") : NULL,
             *fl = out ? strstr(out, "  handles: ") : NULL;
  double longest = 0, forced = 0;
  const char *at = fl ? strstr(fl, "at least ") : NULL;
  CHECK_MSG(rc == 0 && sh && at && sscanf(sh, "shape: longest edge %lfx", &longest) == 1 &&
                sscanf(at, "at least %lfx", &forced) == 1,
            "no shape or handles line: %s", out ? out : "");
  printf("kung fu, hard handles: longest edge %.2fx, the handles ask for %.2fx\n", longest, forced);
  CHECK_MSG(forced > 1.5 && longest >= forced - 0.01, "longest edge %.2fx, handles ask %.2fx",
            longest, forced);
  free(out);
  km_test_run("rm -rf puppet_f", NULL);
}

/* precompute keeps an up-to-date cache and builds with its own parameters, which animate then
 * adopts; --frame-format ply; a motion without the joints a kinect1 rig maps is an error. */
static void test_cache_params_and_formats(void) {
  char *out = NULL;
  character_and_take("puppet_p", 2500, 12, "wave");
  CHECK(km_test_run(KM_CLI " precompute puppet_p/c.obj --fields 6 --isolines 12", &out) == 0);
  CHECK_MSG(out && strstr(out, "6 fields x 12 isolines") && strstr(out, "built"), "%s",
            out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " precompute puppet_p/c.obj --fields 6 --isolines 12", &out) == 0);
  CHECK_MSG(out && strstr(out, "up to date"), "second precompute loads: %s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_p/c.obj --motion puppet_p/w.json "
                           "--frame-format ply -o puppet_p/frames",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "6 fields x 12 isolines") && strstr(out, "cache loaded") &&
                !strstr(out, "not usable"),
            "animate adopts the cache's parameters: %s", out ? out : "");
  free(out);
  km_mesh c = {0}, f0 = {0};
  CHECK_OK(km_mesh_read("puppet_p/c.obj", &c, KM_E));
  CHECK_OK(km_mesh_read("puppet_p/frames/frame_000011.ply", &f0, KM_E));
  CHECK(c.n_vertices == f0.n_vertices && c.n_faces == f0.n_faces);
  CHECK(f0.V && all_finite(f0.V, f0.n_vertices * 3));
  km_mesh_free(&f0);
  km_mesh_free(&c);
  /* asking for other parameters rebuilds (and says so) */
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_p/c.obj --motion puppet_p/w.json --fields 8 "
                           "-o puppet_p/a.pc2",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "not usable"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_p/c.obj --motion puppet_p/w.json "
                           "--frame-format stl -o puppet_p/x",
                    &out) != 0);
  CHECK_MSG(out && strstr(out, "obj or ply"), "%s", out ? out : "");
  free(out);
  char bvh[1024];
  if (km_test_shared("bvh/cmu_131_01.bvh", bvh, sizeof bvh)) {
    char cmd[2048];
    /* The CMU joint names (LeftShoulder, LeftElbow, lhand, LeftToe, ...) map onto the Kinect
     * v1 joints the character's kinect1 rig uses (issue 12). */
    snprintf(cmd, sizeof cmd,
             KM_CLI " animate --mesh puppet_p/c.obj --motion '%s' --fps 30 -o puppet_p/b.pc2", bvh);
    /* issue 15: the CMU joints stand for the Kinect v1 ones (lhand is HandLeft, ...), so the
     * kinect1 rig is driven by body point (docs/skeletons.md); before, a named error */
    CHECK_MSG(km_test_run(cmd, &out) == 0, "%s", out ? out : "");
    free(out);
    CHECK(access("puppet_p/b.pc2", F_OK) == 0);
  }
  km_test_run("rm -rf puppet_p", NULL);
}

static double pc2_max_diff(const char *a, const char *b) {
  double *fa = NULL, *fb = NULL, d = INFINITY;
  km_anim_info ia = {0}, ib = {0};
  CHECK_OK(km_pc2_read(a, &fa, &ia, KM_E));
  CHECK_OK(km_pc2_read(b, &fb, &ib, KM_E));
  if (fa && fb && ia.frames == ib.frames && ia.vertices == ib.vertices && ia.frames) {
    d = 0;
    for (size_t i = 0; i < 3 * ia.frames * ia.vertices; ++i)
      d = fmax(d, isfinite(fa[i]) && isfinite(fb[i]) ? fabs(fa[i] - fb[i]) : INFINITY);
  }
  free(fa);
  free(fb);
  return d;
}

/* Issue 11: a mesh with no rig file animates and poses with a rig made on the spot (said in
 * one line, nothing written beside the mesh), the same as after `kinemesh rig`; a mesh that
 * cannot be rigged says so and why. */
static void test_no_rig(void) {
  char *out = NULL;
  character_and_take("puppet_n", 2000, 8, "wave");
  CHECK(km_test_run("cp puppet_n/c.obj puppet_n/u.obj", NULL) == 0); /* the mesh alone */
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_n/u.obj --motion puppet_n/w.json -o "
                           "puppet_n/auto.pc2",
                    &out) == 0);
  CHECK_MSG(out &&
                strstr(out, "no rig at puppet_n/u.rig.json: rigged puppet_n/u.obj as a humanoid") &&
                !strstr(out, "warning: handle"),
            "%s", out ? out : "");
  free(out);
  CHECK(access("puppet_n/u.rig.json", F_OK) != 0); /* nothing written beside the input */
  CHECK(km_test_run(KM_CLI " rig puppet_n/u.obj -o puppet_n/r/u.rig.json", &out) == 0);
  CHECK_MSG(out && !strstr(out, "warning"), "%s", out ? out : ""); /* a standing body */
  free(out);
  out = NULL;
  /* A cat lying on its side is rigged all the same, with a warning: its head handle is a point
   * (rigged as a body standing along +y) */
  char buf[1024], cmd[1400];
  const char *cat = km_test_shared("poses/cat-poses/cat-04.obj", buf, sizeof buf);
  if (cat) {
    snprintf(cmd, sizeof cmd, KM_CLI " rig %s -o puppet_n/r/cat.rig.json", cat);
    CHECK(km_test_run(cmd, &out) == 0);
    CHECK_MSG(out && strstr(out, "warning: handle head holds 1 vertices") &&
                  strstr(out, "lying or curled up") && strstr(out, "kinemesh live"),
              "%s", out ? out : "");
    free(out);
    out = NULL; /* and so is it when animate rigs it on the spot */
    snprintf(cmd, sizeof cmd,
             KM_CLI " animate --mesh %s --motion puppet_n/w.json -o puppet_n/cat.pc2", cat);
    CHECK(km_test_run(cmd, &out) == 0);
    CHECK_MSG(out && strstr(out, "kinemesh animate: warning: handle head holds 1 vertices") &&
                  strstr(out, "lying or curled up") && strstr(out, "--skeleton resting --head V"),
              "%s", out ? out : "");
    free(out);
    out = NULL;
    /* what the warning says to do: rigged lying with its head's tip (an ear tip), it animates
     * with no warning; --head is refused without --skeleton resting, or when it is no vertex */
    snprintf(cmd, sizeof cmd,
             KM_CLI " rig %s --skeleton resting --head 3799 -o puppet_n/r/cat_rest.rig.json", cat);
    CHECK(km_test_run(cmd, &out) == 0);
    CHECK_MSG(out && strstr(out, "rigged as a resting body") && strstr(out, "handle head:") &&
                  strstr(out, "handle base:") && !strstr(out, "warning"),
              "%s", out ? out : "");
    free(out);
    out = NULL;
    snprintf(cmd, sizeof cmd,
             KM_CLI
             " animate --mesh %s --rig puppet_n/r/cat_rest.rig.json --motion puppet_n/w.json "
             "-o puppet_n/cat_rest.pc2",
             cat);
    CHECK(km_test_run(cmd, &out) == 0);
    CHECK_MSG(out && !strstr(out, "warning"), "%s", out ? out : "");
    free(out);
    out = NULL;
    /* pose (skinning) on the resting rig: the body is held still and the head turns with the
     * neck, as animate shows it. The take used to drive the folded legs and arms inside the
     * body and bend the trunk with the performer's spine over its base (precog_Seq2_1: longest
     * edge 2.07x, 113 of 147 frames over 1.5x; now 1.17x, no fold), and the skinned head then
     * turned a third to a half of animate's: the head handle's vertices' mean step from the
     * first frame, pose against animate, 0.79 (0.53 before the bust skin of spine and neck). */
    char kin[1024];
    if (km_test_shared("skeleton/precog_Seq2_1.csv", kin, sizeof kin)) {
      const char *verb[2] = {"pose", "animate"},
                 *pc2[2] = {"puppet_n/cat_rest_pose.pc2", "puppet_n/cat_rest_anim.pc2"};
      double moved[2] = {0, 0};
      km_mesh cm = {0};
      km_rig rr = {0};
      CHECK_OK(km_mesh_read(cat, &cm, KM_E));
      if (cm.V) CHECK_OK(km_rig_read("puppet_n/r/cat_rest.rig.json", &cm, NULL, 0, &rr, KM_E));
      for (int k = 0; k < 2; ++k) {
        snprintf(cmd, sizeof cmd,
                 KM_CLI " %s --mesh %s --rig puppet_n/r/cat_rest.rig.json --motion %s -o %s",
                 verb[k], cat, kin, pc2[k]);
        CHECK(km_test_run(cmd, &out) == 0);
        if (k == 0) {
          const char *e = out ? strstr(out, "longest edge ") : NULL;
          double longest = e ? strtod(e + strlen("longest edge "), NULL) : NAN;
          printf("resting cat posed on precog_Seq2_1: longest edge %.2fx\n", longest);
          CHECK_MSG(longest < 1.4 && strstr(out, " 0 triangles folded"), "%s", out ? out : "");
        }
        free(out);
        out = NULL;
        double *X = NULL;
        km_anim_info ai;
        CHECK_OK(km_pc2_read(pc2[k], &X, &ai, KM_E));
        for (size_t h = 0; X && h < rr.n_handles; ++h) {
          if (strcmp(rr.handles[h].name, "head")) continue;
          for (size_t f = 1; f < ai.frames; ++f)
            for (size_t i = 0; i < rr.handles[h].n_vertices; ++i) {
              size_t v = (size_t)rr.handles[h].vertices[i];
              const double *a = X + 3 * (f * ai.vertices + v), *b = X + 3 * v;
              moved[k] += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                               (a[2] - b[2]) * (a[2] - b[2]));
            }
        }
        free(X);
      }
      double ratio = moved[0] / moved[1];
      printf("resting cat: its head moves %.2f as far posed as animated\n", ratio);
      CHECK_MSG(ratio > 0.7 && ratio < 1.3, "posed head moves %.3f of the animated one's", ratio);
      km_rig_free(&rr);
      km_mesh_free(&cm);
    }
    static const char *const bad[3][2] = {
        {"--head 3799", "--head is for --skeleton resting"},
        {"--skeleton resting --head ear", "--head ear: expected a vertex id"},
        {"--skeleton resting --head 999999", "the head vertex 999999 is not a vertex"}};
    for (int k = 0; k < 3; ++k) {
      snprintf(cmd, sizeof cmd, KM_CLI " rig %s %s -o puppet_n/r/bad.rig.json", cat, bad[k][0]);
      CHECK(km_test_run(cmd, &out) != 0);
      CHECK_MSG(out && strstr(out, bad[k][1]), "%s: %s", bad[k][0], out ? out : "");
      free(out);
      out = NULL;
    }
    CHECK(access("puppet_n/r/bad.rig.json", F_OK) != 0);
  }
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_n/u.obj --rig puppet_n/r/u.rig.json --motion "
                           "puppet_n/w.json -o puppet_n/file.pc2",
                    NULL) == 0);
  /* the written rig rounds weights to 7 digits: equal to a few micrometres */
  double d = pc2_max_diff("puppet_n/auto.pc2", "puppet_n/file.pc2");
  CHECK_MSG(d < 1e-5, "animate with no rig differs from animate after kinemesh rig by %g m", d);
  CHECK(km_test_run(KM_CLI " pose --mesh puppet_n/u.obj --motion puppet_n/w.json -o "
                           "puppet_n/pose.pc2",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "no rig at"), "%s", out ? out : "");
  free(out);
  km_anim_info info = {0};
  double *frames = NULL;
  CHECK_OK(km_pc2_read("puppet_n/pose.pc2", &frames, &info, KM_E));
  CHECK(info.frames == 8 && frames && all_finite(frames, 3 * info.frames * info.vertices));
  free(frames);
  /* and a template for reconstruct */
  CHECK(km_test_run(KM_CLI " gen capture --character puppet_n/c.obj --motion puppet_n/w.json "
                           "--frames 2 --cameras 4 --points 3000 -o puppet_n/clouds",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template puppet_n/u.obj --clouds "
                           "'puppet_n/clouds/frame_*.ply' -o puppet_n/recon.pc2",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "no rig at") && access("puppet_n/recon.pc2", F_OK) == 0, "%s",
            out ? out : "");
  free(out);
  CHECK(access("puppet_n/u.rig.json", F_OK) != 0);
  /* the character with an eye of its own (an octahedron of 6 vertices in front of its face,
   * appended): animate rigs the body on the spot and the eye follows it; the body moves as it
   * does alone (the reduced model's fields are the body's, the eye takes its nearest body
   * vertex's). Refused before as "2 components". */
  {
    km_mesh u = {0};
    CHECK_OK(km_mesh_read("puppet_n/u.obj", &u, KM_E));
    FILE *e = u.V ? fopen("puppet_n/eye.obj", "w") : NULL;
    size_t n = u.n_vertices, top = 0;
    for (size_t v = 0; v < n; ++v)
      if (u.V[3 * v + 1] > u.V[3 * top + 1]) top = v;
    double c0[3] = {u.V ? u.V[3 * top] : 0, u.V ? u.V[3 * top + 1] - 0.1 : 0, 0.2}, r = 0.015;
    for (size_t v = 0; e && v < n; ++v)
      if (fabs(u.V[3 * v + 1] - c0[1]) < 0.03 && fabs(u.V[3 * v]) < 0.05)
        c0[2] = fmax(c0[2], u.V[3 * v + 2] + 0.02);
    static const double oct[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                     {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
    static const int of[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                 {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    if (e) {
      for (size_t v = 0; v < n; ++v)
        fprintf(e, "v %.9g %.9g %.9g\n", u.V[3 * v], u.V[3 * v + 1], u.V[3 * v + 2]);
      for (int k = 0; k < 6; ++k)
        fprintf(e, "v %.9g %.9g %.9g\n", c0[0] + r * oct[k][0], c0[1] + r * oct[k][1],
                c0[2] + r * oct[k][2]);
      for (size_t f = 0; f < u.n_faces; ++f)
        fprintf(e, "f %d %d %d\n", u.F[3 * f] + 1, u.F[3 * f + 1] + 1, u.F[3 * f + 2] + 1);
      for (int f = 0; f < 8; ++f)
        fprintf(e, "f %zu %zu %zu\n", n + 1 + (size_t)of[f][0], n + 1 + (size_t)of[f][1],
                n + 1 + (size_t)of[f][2]);
      fclose(e);
      CHECK(km_test_run(KM_CLI " animate --mesh puppet_n/eye.obj --motion puppet_n/w.json -o "
                               "puppet_n/eye.pc2",
                        &out) == 0);
      CHECK_MSG(out && strstr(out, "no rig at") && strstr(out, "as a humanoid") &&
                    strstr(out, "; 1 loose piece (6 vertices) follows the body"),
                "%s", out ? out : "");
      free(out);
      out = NULL;
      double *X = NULL, *Y = NULL;
      km_anim_info ix = {0}, iy = {0};
      CHECK_OK(km_pc2_read("puppet_n/auto.pc2", &X, &ix, KM_E));
      CHECK_OK(km_pc2_read("puppet_n/eye.pc2", &Y, &iy, KM_E));
      if (X && Y && ix.frames == iy.frames && iy.vertices == n + 6 && ix.vertices == n) {
        double body = 0, gap_dev = 0, gap0 = -1;
        for (size_t f = 0; f < ix.frames; ++f) {
          const double *x = X + 3 * f * n, *y = Y + 3 * f * (n + 6);
          for (size_t i = 0; i < 3 * n; ++i)
            body = fmax(body, fabs(x[i] - y[i]));
          double c[3] = {0, 0, 0}; /* the eye's centre against the top of the head */
          for (int k = 0; k < 6; ++k)
            for (int d = 0; d < 3; ++d)
              c[d] += y[3 * (n + (size_t)k) + (size_t)d] / 6;
          double g = sqrt(pow(c[0] - y[3 * top], 2) + pow(c[1] - y[3 * top + 1], 2) +
                          pow(c[2] - y[3 * top + 2], 2));
          if (gap0 < 0) gap0 = g;
          gap_dev = fmax(gap_dev, fabs(g - gap0));
        }
        printf("character with an eye (animate, no rig): body within %.2g m of it alone, the "
               "eye's distance to the top of the head %.3f, off by %.4f at most\n",
               body, gap0, gap_dev);
        CHECK_MSG(body < 0.005, "the body %g m off its animation alone", body);
        CHECK_MSG(gap_dev < 0.25 * gap0, "the eye's gap to the head off by %g (%g)", gap_dev, gap0);
      } else {
        CHECK_MSG(false, "eye.pc2: %zu frames of %zu vertices", iy.frames, iy.vertices);
      }
      free(X);
      free(Y);
    }
    km_mesh_free(&u);
  }
  /* two separate tetrahedra: no rig can be made, and the message says why */
  FILE *f = fopen("puppet_n/two.obj", "w");
  CHECK(f != NULL);
  if (f) {
    for (int k = 0; k < 2; ++k)
      fprintf(f, "v %d 0 0\nv %d 0 0\nv %d 1 0\nv %d 0 1\n", 3 * k, 3 * k + 1, 3 * k, 3 * k);
    for (int k = 0; k < 2; ++k)
      fprintf(f, "f %d %d %d\nf %d %d %d\nf %d %d %d\nf %d %d %d\n", 4 * k + 1, 4 * k + 3,
              4 * k + 2, 4 * k + 1, 4 * k + 2, 4 * k + 4, 4 * k + 1, 4 * k + 4, 4 * k + 3,
              4 * k + 2, 4 * k + 3, 4 * k + 4);
    fclose(f);
  }
  CHECK(km_test_run(KM_CLI " animate --mesh puppet_n/two.obj --motion puppet_n/w.json -o "
                           "puppet_n/two.pc2",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "has no rig") && strstr(out, "2 components"), "%s", out ? out : "");
  free(out);
  CHECK(access("puppet_n/two.pc2", F_OK) != 0);
  km_test_run("rm -rf puppet_n", NULL);
}

/* bench deform: one JSON object per mesh with the keys (values, not speed). */
static void test_bench_deform_json(void) {
  char *out = NULL;
  CHECK(km_test_run(KM_CLI " bench deform --mesh character:2000 character:2600 --frames 6 "
                           "--full-frames 2 --repeat 1 --json 2>/dev/null",
                    &out) == 0);
  const char *keys[] = {"n_ver", "n_han",   "n_tri",        "t1_s",         "t1_cached_s", "t23_ms",
                        "t4_ms", "tper_ms", "full_tper_ms", "dev_mean_rel", "dev_max_rel"};
  int rows = 0;
  double nv[2] = {0, 0};
  for (char *line = out ? strtok(out, "\n") : NULL; line; line = strtok(NULL, "\n")) {
    cJSON *o = cJSON_Parse(line);
    if (!o) continue;
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k)
      CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItem(o, keys[k])), "row %d key %s", rows, keys[k]);
    if (rows < 2 && cJSON_IsNumber(cJSON_GetObjectItem(o, "n_ver")))
      nv[rows] = cJSON_GetObjectItem(o, "n_ver")->valuedouble;
    cJSON *d = cJSON_GetObjectItem(o, "dev_mean_rel");
    CHECK(cJSON_IsNumber(d) && d->valuedouble >= 0 && d->valuedouble < 0.05);
    cJSON_Delete(o);
    ++rows;
  }
  CHECK_MSG(rows == 2, "%d JSON rows", rows);
  CHECK(nv[0] > 1500 && nv[0] < 2500 && nv[1] > nv[0]);
  free(out);
}

/* bench start: a row per mesh with its cold and warm times (values, not speed), its runs'
 * caches in a temporary folder: the cache folder this test points XDG_CACHE_HOME at gets no
 * model of the bench's mesh. */
static void test_bench_start_json(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf puppet_cache_bench", NULL) == 0);
  CHECK(km_test_run("XDG_CACHE_HOME=\"$PWD/puppet_cache_bench\" " KM_CLI
                    " bench start character:2000 --repeat 1 --frames 4 --json 2>/dev/null",
                    &out) == 0);
  cJSON *o = out ? cJSON_Parse(out) : NULL;
  const cJSON *nv = cJSON_GetObjectItem(o, "n_ver"), *cs = cJSON_GetObjectItem(o, "cold_s"),
              *ws = cJSON_GetObjectItem(o, "warm_s");
  CHECK_MSG(cJSON_IsNumber(nv) && nv->valuedouble > 1500 && nv->valuedouble < 2500 &&
                cJSON_IsNumber(cs) && cs->valuedouble > 0 && cJSON_IsNumber(ws) &&
                ws->valuedouble > 0,
            "%s", out ? out : "(no output)");
  CHECK(km_test_run("test ! -e puppet_cache_bench", NULL) == 0);
  cJSON_Delete(o);
  free(out);
}

int main(void) {
  char a[1024], c[1024], cwd[900], xdg[1024];
  /* The CLI's default cache folder: here, not the user's ~/.cache. */
  if (getcwd(cwd, sizeof cwd)) {
    snprintf(xdg, sizeof xdg, "%s/puppet_cache", cwd);
    setenv("XDG_CACHE_HOME", xdg, 1);
  }
  test_bad_rig_and_motion();
  test_cache_params_and_formats();
  test_report();
  test_forced_line();
  test_no_rig();
  test_bench_deform_json();
  test_bench_start_json();
  test_demo();
  if (km_test_shared("meshes/armadillo_1k.off", a, sizeof a) &&
      km_test_shared("skeleton/precog_Seq1_1.csv", c, sizeof c))
    test_real_mesh_real_skeleton(a, c);
  else /* the CLI checks above still count: a failure there is a failure */
    return km_test_finish("test_puppet_cli") ? 1 : KM_TEST_SKIP;
  if (km_test_shared("bvh/cmu_131_01.bvh", c, sizeof c))
    test_floor_switch(a, c);
  else
    return km_test_finish("test_puppet_cli") ? 1 : KM_TEST_SKIP;
  return km_test_finish("test_puppet_cli");
}
