/* Avatar pose transfer through the CLI: transfer, posedb build/query and avatar on procedural
 * subjects that share connectivity, with LBS-posed ground truth. */
#include "km_test.h"

#include <cjson/cJSON.h>

#define DIR "pose_cli"

static double mean_dist(const km_mesh *a, const km_mesh *b) {
  double s = 0;
  for (size_t v = 0; v < a->n_vertices; ++v) {
    double d = 0;
    for (int k = 0; k < 3; ++k)
      d += pow(a->V[3 * v + k] - b->V[3 * v + k], 2);
    s += sqrt(d);
  }
  return s / (double)a->n_vertices;
}

/* A track file: the landmark vertices of posed frames of subject a. */
static void write_track(const char *path, const km_landmark *lm, const char *frames_dir,
                        const int *frames, int n_frames) {
  cJSON *root = cJSON_CreateObject();
  cJSON_AddNumberToObject(root, "fps", 30);
  cJSON *names = cJSON_AddArrayToObject(root, "landmarks");
  for (int l = 0; l < KM_CHARACTER_LANDMARKS; ++l)
    cJSON_AddItemToArray(names, cJSON_CreateString(lm[l].name));
  cJSON *fr = cJSON_AddArrayToObject(root, "frames");
  for (int i = 0; i < n_frames; ++i) {
    char p[256];
    snprintf(p, sizeof p, "%s/frame_%06d.obj", frames_dir, frames[i]);
    km_mesh m = {0};
    CHECK_OK(km_mesh_read(p, &m, KM_E));
    cJSON *row = cJSON_CreateArray();
    for (int l = 0; l < KM_CHARACTER_LANDMARKS && m.V; ++l)
      for (int k = 0; k < 3; ++k)
        cJSON_AddItemToArray(row, cJSON_CreateNumber(m.V[3 * (size_t)lm[l].vertex + k]));
    cJSON_AddItemToArray(fr, row);
    km_mesh_free(&m);
  }
  char *s = cJSON_Print(root);
  FILE *f = fopen(path, "w");
  fputs(s, f);
  fclose(f);
  free(s);
  cJSON_Delete(root);
}

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR "/db", NULL) == 0);
  /* two subjects of one connectivity, three motions each, posed by LBS */
  CHECK(km_test_run(KM_CLI " gen character --vertices 2500 -o " DIR "/a.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2500 --shape stocky -o " DIR "/b.obj",
                    NULL) == 0);
  const char *kinds[3] = {"walk", "wave", "kungfu"};
  char cmd[1024];
  for (int k = 0; k < 3; ++k) {
    snprintf(cmd, sizeof cmd,
             KM_CLI " gen motion --kind %s --frames 90 --character " DIR "/a.obj -o " DIR
                    "/%s.json",
             kinds[k], kinds[k]);
    CHECK(km_test_run(cmd, NULL) == 0);
    for (int s = 0; s < 2; ++s) {
      snprintf(cmd, sizeof cmd,
               KM_CLI " pose --mesh " DIR "/%c.obj --motion " DIR "/%s.json -o " DIR "/%c_%s",
               "ab"[s], kinds[k], "ab"[s], kinds[k]);
      CHECK(km_test_run(cmd, NULL) == 0);
    }
  }
  km_mesh a = {0}, b = {0}, bt = {0}, res = {0};
  CHECK_OK(km_mesh_read(DIR "/a.obj", &a, KM_E));
  CHECK_OK(km_mesh_read(DIR "/b.obj", &b, KM_E));
  CHECK(a.n_vertices == b.n_vertices && a.n_faces == b.n_faces);

  /* transfer: b takes a's kung-fu pose of frame 60; b posed by LBS is the truth */
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a_kungfu/frame_000060.obj -o " DIR "/b60.obj",
                    &out) == 0);
  free(out);
  CHECK_OK(km_mesh_read(DIR "/b_kungfu/frame_000060.obj", &bt, KM_E));
  CHECK_OK(km_mesh_read(DIR "/b60.obj", &res, KM_E));
  if (res.V && bt.V && res.n_vertices == bt.n_vertices) {
    double e_transfer = mean_dist(&res, &bt), e_rest = mean_dist(&b, &bt);
    CHECK_MSG(e_transfer < 0.25 * e_rest && e_transfer < 0.04,
              "transfer error %.4f m, source at rest %.4f m", e_transfer, e_rest);
  }
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a.obj --landmarks " DIR "/none.json -o " DIR "/x.obj",
                    NULL) == 1);
  /* --landmarks auto: farthest-point landmarks, for meshes without a rig */
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --landmarks auto:20 -o " DIR "/b60auto.obj",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "20 landmarks"), "%s", out ? out : "");
  free(out);
  km_mesh ra = {0};
  CHECK_OK(km_mesh_read(DIR "/b60auto.obj", &ra, KM_E));
  if (ra.V && bt.V && ra.n_vertices == bt.n_vertices) {
    double e_auto = mean_dist(&ra, &bt), e_rest = mean_dist(&b, &bt);
    CHECK_MSG(e_auto < 0.35 * e_rest, "auto landmarks: error %.4f m, source at rest %.4f m", e_auto,
              e_rest);
  }
  km_mesh_free(&ra);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a.obj --landmarks auto:2 -o " DIR "/x.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "K >= 3"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run("cp " DIR "/b.obj " DIR "/norig.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/norig.obj --template " DIR "/a.obj -o " DIR
                           "/x.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "norig.rig.json") && strstr(out, "--landmarks auto"), "%s",
            out ? out : "");
  free(out);

  /* database: frames of both subjects labelled by motion, subjects as CV groups */
  FILE *f = fopen(DIR "/labels.csv", "w");
  fputs("mesh,class,subject\n", f);
  for (int k = 0; k < 3; ++k)
    for (int s = 0; s < 2; ++s)
      for (int fr = 40; fr <= 80; fr += 10) {
        snprintf(cmd, sizeof cmd, "cp " DIR "/%c_%s/frame_%06d.obj " DIR "/db/%c_%s_%d.obj",
                 "ab"[s], kinds[k], fr, "ab"[s], kinds[k], fr);
        CHECK(km_test_run(cmd, NULL) == 0);
        fprintf(f, "%c_%s_%d.obj,%s,%c\n", "ab"[s], kinds[k], fr, kinds[k], "ab"[s]);
      }
  /* issue 14: a duplicate line is warned about and ignored */
  fprintf(f, "a_%s_40.obj,%s,a\n", kinds[0], kinds[0]);
  fclose(f);
  /* a mesh the labels do not name is left out, with a warning; a glob without meshes is an
   * error that says so */
  CHECK(km_test_run("cp " DIR "/a.obj " DIR "/db/unlabelled.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " posedb build --meshes " DIR "/db --labels " DIR
                           "/labels.csv --landmarks " DIR "/a.rig.json -o " DIR "/poses.kmposedb",
                    &out) == 0);
  CHECK_MSG(out && strstr(out, "3 classes") && strstr(out, "over 2 folds") &&
                strstr(out, "eq. 8") && strstr(out, "1 of the 31 meshes") &&
                strstr(out, "unlabelled.obj") && strstr(out, "labelled again") &&
                strstr(out, "1 line(s) of"),
            "%s", out);
  free(out);
  CHECK(km_test_run(KM_CLI " posedb build --meshes '" DIR "/db/*.stl' --labels " DIR
                           "/labels.csv --landmarks " DIR "/a.rig.json -o " DIR "/x.kmposedb",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "matched no mesh files"), "%s", out ? out : "");
  free(out);

  /* bench transfer on the same pair: the JSON keys, an error that matches the
   * transfer's above, recognition against the database (values, not speed) */
  CHECK(km_test_run(KM_CLI " bench transfer --source " DIR "/b.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --truth " DIR
                           "/b_kungfu/frame_000060.obj --db " DIR "/poses.kmposedb --json",
                    &out) == 0);
  cJSON *bj = out ? cJSON_Parse(strchr(out, '{') ? strchr(out, '{') : out) : NULL;
  CHECK_MSG(bj != NULL, "bench transfer --json printed: %s", out ? out : "(nothing)");
  if (bj) {
    const char *keys[] = {"n_ver",       "laplacian_ms", "cholesky_ms", "recognition_ms",
                          "frames_ms",   "solve_ms",     "iterations",  "online_ms",
                          "err_mean_mm", "err_max_mm"};
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k)
      CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItem(bj, keys[k])), "bench key %s", keys[k]);
    CHECK(cJSON_GetObjectItem(bj, "n_ver")->valuedouble == (double)b.n_vertices);
    double it = cJSON_GetObjectItem(bj, "iterations")->valuedouble;
    CHECK(it >= 1 && it <= 10);
    if (res.V && bt.V && res.n_vertices == bt.n_vertices) {
      double e = cJSON_GetObjectItem(bj, "err_mean_mm")->valuedouble;
      CHECK_MSG(fabs(e - 1e3 * mean_dist(&res, &bt)) < 0.05, "bench error %g mm vs transfer %g mm",
                e, 1e3 * mean_dist(&res, &bt));
    }
    CHECK(cJSON_GetObjectItem(bj, "err_max_mm")->valuedouble >=
          cJSON_GetObjectItem(bj, "err_mean_mm")->valuedouble);
    /* the baseline is printed next to it, and loses */
    cJSON *lo = cJSON_GetObjectItem(bj, "landmark_only_err_mean_mm");
    CHECK(cJSON_IsNumber(lo) &&
          lo->valuedouble > cJSON_GetObjectItem(bj, "err_mean_mm")->valuedouble);
    cJSON_Delete(bj);
  }
  free(out);
  /* without --db: recognition timed in a generated 10-class database (16 named landmarks) */
  CHECK(km_test_run(KM_CLI " bench transfer --source " DIR "/b.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --json",
                    &out) == 0);
  bj = out ? cJSON_Parse(strchr(out, '{') ? strchr(out, '{') : out) : NULL;
  CHECK_MSG(bj && cJSON_IsNumber(cJSON_GetObjectItem(bj, "recognition_ms")) &&
                cJSON_GetObjectItem(bj, "recognition_ms")->valuedouble > 0 &&
                cJSON_IsNull(cJSON_GetObjectItem(bj, "err_mean_mm")),
            "%s", out ? out : "");
  cJSON_Delete(bj);
  free(out);

  /* query and avatar from a track of subject a's landmarks */
  km_landmark lm[KM_CHARACTER_LANDMARKS];
  size_t nl = 0;
  CHECK_OK(
      km_landmarks_read(DIR "/a.rig.json", a.n_vertices, lm, KM_CHARACTER_LANDMARKS, &nl, KM_E));
  CHECK(nl == KM_CHARACTER_LANDMARKS);
  int frames[12];
  for (int i = 0; i < 12; ++i)
    frames[i] = 35 + 4 * i;
  write_track(DIR "/wave_track.json", lm, DIR "/a_wave", frames, 12);
  /* transfer with tracked landmark positions as the targets (no scaling): the landmark
   * vertices of the result sit exactly on them */
  int f60[1] = {60};
  write_track(DIR "/kf60.json", lm, DIR "/a_kungfu", f60, 1);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --landmarks-xyz " DIR "/kf60.json -o " DIR
                           "/b60xyz.obj",
                    NULL) == 0);
  {
    km_mesh rx = {0}, a60 = {0};
    CHECK_OK(km_mesh_read(DIR "/b60xyz.obj", &rx, KM_E));
    CHECK_OK(km_mesh_read(DIR "/a_kungfu/frame_000060.obj", &a60, KM_E));
    double worst = 0;
    for (size_t l = 0; rx.V && a60.V && l < nl; ++l)
      for (int k = 0; k < 3; ++k)
        worst = fmax(
            worst, fabs(rx.V[3 * (size_t)lm[l].vertex + k] - a60.V[3 * (size_t)lm[l].vertex + k]));
    CHECK_MSG(rx.V && a60.V && worst < 1e-9, "landmarks %g m off the tracked positions", worst);
    km_mesh_free(&rx);
    km_mesh_free(&a60);
  }
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a.obj --landmarks-xyz " DIR "/kf60.json --frame 3 -o " DIR "/x.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "kf60.json") && strstr(out, "out of range"), "%s", out ? out : "");
  free(out);
  /* fewer than 3 landmarks in an LM.json: the error names the file */
  f = fopen(DIR "/lm2.json", "w");
  fprintf(f,
          "{\"landmarks\": [{\"name\": \"%s\", \"vertex\": %d, \"mirror\": \"%s\"}, "
          "{\"name\": \"%s\", \"vertex\": %d, \"mirror\": \"%s\"}]}\n",
          lm[0].name, (int)lm[0].vertex, lm[0].name, lm[1].name, (int)lm[1].vertex, lm[1].name);
  fclose(f);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/b.obj --template " DIR
                           "/a.obj --landmarks " DIR "/lm2.json -o " DIR "/x.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "lm2.json") && strstr(out, "at least 3"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " posedb query " DIR "/poses.kmposedb --landmarks-xyz " DIR
                           "/wave_track.json",
                    &out) == 0);
  size_t wave_rows = 0;
  for (char *p = out; p && (p = strstr(p, ",wave,")); ++p)
    ++wave_rows;
  CHECK_MSG(wave_rows >= 10, "%zu of 12 frames recognised as wave:\n%s", wave_rows, out);
  /* the picked template is named: a wave mesh of the database */
  CHECK_MSG(out && strstr(out, "template_name") && strstr(out, "_wave_") && strstr(out, ".obj"),
            "%s", out ? out : "");
  free(out);
  /* issue 14: `pose --track` writes the rig's landmarks along a take as a track: the same
   * positions as the posed frames' landmark vertices, recognised by posedb query */
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/a.obj --motion " DIR "/wave.json --track " DIR
                           "/wave_pose_track.json",
                    &out) == 0);
  free(out);
  {
    km_track tk = {0};
    km_mesh f35 = {0};
    CHECK_OK(km_track_read(DIR "/wave_pose_track.json", &tk, KM_E));
    CHECK_OK(km_mesh_read(DIR "/a_wave/frame_000035.obj", &f35, KM_E));
    CHECK(tk.n_frames == 90 && tk.n_landmarks == KM_CHARACTER_LANDMARKS);
    double worst = tk.n_frames == 90 && f35.V ? 0 : INFINITY;
    for (size_t l = 0; l < tk.n_landmarks && isfinite(worst); ++l) {
      CHECK(!strcmp(tk.names[l], lm[l].name));
      for (int k = 0; k < 3; ++k)
        worst = fmax(worst, fabs(tk.positions[(35 * tk.n_landmarks + l) * 3 + k] -
                                 f35.V[3 * (size_t)lm[l].vertex + k]));
    }
    CHECK_MSG(worst < 1e-6, "track frame 35 is %g m off the posed frame's landmarks", worst);
    km_track_free(&tk);
    km_mesh_free(&f35);
  }
  CHECK(km_test_run(KM_CLI " posedb query " DIR "/poses.kmposedb --landmarks-xyz " DIR
                           "/wave_pose_track.json",
                    &out) == 0);
  wave_rows = 0;
  for (char *p = out; p && (p = strstr(p, ",wave,")); ++p)
    ++wave_rows;
  CHECK_MSG(wave_rows >= 60, "%zu of 90 frames of the pose track recognised as wave", wave_rows);
  free(out);
  CHECK(km_test_run(KM_CLI " avatar --source " DIR "/b.obj --db " DIR "/poses.kmposedb --track " DIR
                           "/wave_track.json --interval 3 -o " DIR "/avatar.pc2",
                    &out) == 0);
  free(out);
  CHECK(km_test_run(KM_CLI " avatar --source " DIR "/b.obj --db " DIR "/poses.kmposedb --track " DIR
                           "/wave_track.json --interval 3 -o " DIR "/avatar.glb",
                    NULL) == 0);
  km_anim_info ginfo;
  CHECK_OK(km_anim_info_read(DIR "/avatar.glb", &ginfo, KM_E));
  CHECK(ginfo.frames == 12 && ginfo.vertices == b.n_vertices);
  double *anim = NULL;
  km_anim_info info;
  CHECK_OK(km_pc2_read(DIR "/avatar.pc2", &anim, &info, KM_E));
  CHECK(info.frames == 12 && info.vertices == b.n_vertices);
  /* a key frame (every 3rd) follows the tracked pose: frame 6 is wave frame 59 */
  km_mesh bw = {0};
  CHECK_OK(km_mesh_read(DIR "/b_wave/frame_000059.obj", &bw, KM_E));
  if (anim && info.frames == 12 && bw.V && bw.n_vertices == b.n_vertices) {
    km_mesh key = b;
    key.V = anim + 6 * 3 * b.n_vertices;
    double e_key = mean_dist(&key, &bw), e_rest = mean_dist(&b, &bw);
    CHECK_MSG(e_key < 0.3 * e_rest, "avatar key frame %.4f m from the truth, rest %.4f m", e_key,
              e_rest);
  }
  km_mesh_free(&bw);
  free(anim);

  km_mesh_free(&a);
  km_mesh_free(&b);
  km_mesh_free(&bt);
  km_mesh_free(&res);
  /* issue 14: a body of another connectivity (the same generated body at 2,000 vertices)
   * takes kung-fu frame 60 of a (2,500) through --template-rest; truth: LBS of the same take */
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o " DIR "/c.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/c.obj --motion " DIR "/kungfu.json -o " DIR
                           "/c_kungfu",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/c.obj --template " DIR
                           "/a_kungfu/frame_000060.obj -o " DIR "/c60.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "--template-rest"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/c.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --template-rest " DIR "/c.obj -o " DIR
                           "/c60.obj",
                    &out) == 1);
  CHECK_MSG(out && strstr(out, "is not TEMPLATE"), "%s", out ? out : "");
  free(out);
  CHECK(km_test_run(KM_CLI " transfer --source " DIR "/c.obj --template " DIR
                           "/a_kungfu/frame_000060.obj --template-rest " DIR "/a.obj -o " DIR
                           "/c60.obj",
                    &out) == 0);
  free(out);
  {
    km_mesh c60 = {0}, truth = {0};
    CHECK_OK(km_mesh_read(DIR "/c60.obj", &c60, KM_E));
    CHECK_OK(km_mesh_read(DIR "/c_kungfu/frame_000060.obj", &truth, KM_E));
    CHECK(c60.n_vertices == truth.n_vertices && c60.n_faces == truth.n_faces);
    if (c60.n_vertices == truth.n_vertices && c60.V) {
      double mean, max, lo = INFINITY, hi = -INFINITY;
      km_vertex_distance_stats(c60.V, truth.V, c60.n_vertices, &mean, &max);
      for (size_t v = 0; v < truth.n_vertices; ++v)
        lo = fmin(lo, truth.V[3 * v + 1]), hi = fmax(hi, truth.V[3 * v + 1]);
      printf("  2000 vertices take the pose of 2500: mean %.1f mm, max %.1f mm\n", mean * 1e3,
             max * 1e3);
      CHECK_MSG(mean <= 0.01 * (hi - lo), "other connectivity: mean %g m", mean);
    }
    km_mesh_free(&c60);
    km_mesh_free(&truth);
  }
  /* The same source turned 90 degrees about x, scaled x1.2 and moved, registered onto a's rest
   * from --correspondences (the landmarks of one name in both rigs, as vertex pairs); the
   * output stays in the moved source's frame: truth = the moved c posed. */
  {
    km_mesh c = {0}, truth = {0}, cm60 = {0};
    double height = 0;
    km_landmark lc[KM_POSE_MAX_LANDMARKS], la[KM_POSE_MAX_LANDMARKS];
    size_t nc = 0, na = 0;
    CHECK_OK(km_mesh_read(DIR "/c.obj", &c, KM_E));
    CHECK_OK(km_mesh_read(DIR "/c_kungfu/frame_000060.obj", &truth, KM_E));
    CHECK_OK(
        km_landmarks_read(DIR "/c.rig.json", c.n_vertices, lc, KM_POSE_MAX_LANDMARKS, &nc, KM_E));
    CHECK_OK(km_landmarks_read(DIR "/a.rig.json", 0, la, KM_POSE_MAX_LANDMARKS, &na, KM_E));
    km_mesh *ms[2] = {&c, &truth};
    for (int m = 0; m < 2; ++m)
      for (size_t v = 0; v < ms[m]->n_vertices; ++v) {
        double *p = ms[m]->V + 3 * v, y = p[1], z = p[2];
        p[0] = 1.2 * p[0] + 0.4, p[1] = 1.2 * -z - 0.3, p[2] = 1.2 * y + 2.0;
      }
    CHECK_OK(km_mesh_write(DIR "/cm.obj", &c, NULL, KM_E));
    FILE *f = fopen(DIR "/cm_pairs.csv", "w");
    CHECK(f != NULL);
    if (f) {
      fprintf(f, "# source_vertex,template_vertex\n");
      for (size_t i = 0; i < nc; ++i)
        for (size_t k = 0; k < na; ++k)
          if (!strcmp(lc[i].name, la[k].name)) fprintf(f, "%d,%d\n", lc[i].vertex, la[k].vertex);
      fclose(f);
    }
    CHECK(km_test_run(KM_CLI " transfer --source " DIR "/cm.obj --landmarks " DIR
                             "/c.rig.json --template " DIR
                             "/a_kungfu/frame_000060.obj --template-rest " DIR
                             "/a.obj --correspondences " DIR "/cm_pairs.csv -o " DIR "/cm60.obj",
                      &out) == 0);
    CHECK_MSG(out && strstr(out, "registered onto"), "%s", out ? out : "");
    free(out);
    CHECK_OK(km_mesh_read(DIR "/cm60.obj", &cm60, KM_E));
    CHECK(cm60.n_vertices == truth.n_vertices && cm60.n_faces == truth.n_faces);
    if (cm60.n_vertices == truth.n_vertices && cm60.V) {
      double mean, max, lo = INFINITY, hi = -INFINITY;
      km_vertex_distance_stats(cm60.V, truth.V, cm60.n_vertices, &mean, &max);
      for (size_t v = 0; v < truth.n_vertices; ++v)
        lo = fmin(lo, truth.V[3 * v + 2]), hi = fmax(hi, truth.V[3 * v + 2]);
      height = hi - lo;
      printf("  the same turned 90 deg, x1.2, moved (--correspondences): mean %.1f mm, max %.1f "
             "mm, height %.3f m\n",
             mean * 1e3, max * 1e3, hi - lo);
      CHECK_MSG(mean <= 0.01 * (hi - lo), "moved source: mean %g m", mean);
    }
    /* the same with the non-rigid step after the similarity */
    CHECK(km_test_run(KM_CLI " transfer --source " DIR "/cm.obj --landmarks " DIR
                             "/c.rig.json --template " DIR
                             "/a_kungfu/frame_000060.obj --template-rest " DIR
                             "/a.obj --correspondences " DIR
                             "/cm_pairs.csv --register nonrigid -o " DIR "/cm60n.obj",
                      &out) == 0);
    CHECK_MSG(out && strstr(out, "non-rigid registration"), "%s", out ? out : "");
    free(out);
    {
      km_mesh cn = {0};
      CHECK_OK(km_mesh_read(DIR "/cm60n.obj", &cn, KM_E));
      CHECK(cn.n_vertices == truth.n_vertices);
      if (cn.n_vertices == truth.n_vertices && cn.V) {
        double mean, max;
        km_vertex_distance_stats(cn.V, truth.V, cn.n_vertices, &mean, &max);
        printf("  ... with --register nonrigid: mean %.1f mm, max %.1f mm\n", mean * 1e3,
               max * 1e3);
        CHECK_MSG(mean <= 0.01 * height, "moved source, non-rigid: mean %g m", mean);
      }
      km_mesh_free(&cn);
    }
    CHECK(km_test_run(KM_CLI " transfer --source " DIR "/cm.obj --template " DIR
                             "/a_kungfu/frame_000060.obj --template-rest " DIR
                             "/a.obj --register rigid -o " DIR "/cm60n.obj",
                      &out) == 1);
    CHECK_MSG(out && strstr(out, "--register must be"), "%s", out ? out : "");
    free(out);
    /* a malformed pair names the file and the line */
    f = fopen(DIR "/bad_pairs.csv", "w");
    if (f) {
      fputs("1,2\n3,4\n5;6\n", f);
      fclose(f);
    }
    CHECK(km_test_run(KM_CLI " transfer --source " DIR "/cm.obj --landmarks " DIR
                             "/c.rig.json --template " DIR
                             "/a_kungfu/frame_000060.obj --template-rest " DIR
                             "/a.obj --correspondences " DIR "/bad_pairs.csv -o " DIR "/cm60.obj",
                      &out) == 1);
    CHECK_MSG(out && strstr(out, "bad_pairs.csv:3:"), "%s", out ? out : "");
    free(out);
    km_mesh_free(&c);
    km_mesh_free(&truth);
    km_mesh_free(&cm60);
  }
  km_test_run("rm -rf " DIR, NULL);
  return km_test_finish("test_pose_cli");
}
