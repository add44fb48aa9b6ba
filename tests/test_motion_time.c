/* Issue 12, time: resampling a take keeps its duration (--fps resamples instead of
 * relabelling), and every animation writer's info agrees with itself (frames, rate, duration). */
#include "km_test.h"

#include <unistd.h>

static char g_dir[] = "/tmp/km_test_motion_time_XXXXXX";

/* A 120 fps BVH written here: 120 frames, the root sliding 1 m along x per second. */
static void test_bvh_120_to_30(void) {
  char path[300];
  snprintf(path, sizeof path, "%s/fast.bvh", g_dir);
  FILE *f = fopen(path, "w");
  CHECK(f != NULL);
  if (!f) return;
  fprintf(f, "HIERARCHY\nROOT A\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition "
             "Zrotation Xrotation Yrotation\n\tJOINT B\n\t{\n\t\tOFFSET 0 1 0\n\t\tCHANNELS 3 "
             "Zrotation Xrotation Yrotation\n\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 0 0.5 0\n\t\t}\n\t}"
             "\n}\nMOTION\nFrames: 120\nFrame Time: 0.00833333\n");
  for (int k = 0; k < 120; ++k)
    fprintf(f, "%.6f 1 0 0 0 0 %d 0 0\n", k / 120.0, k % 90);
  fclose(f);
  km_take t = {0}, r = {0};
  km_motion_read_options mo = {0};
  mo.bvh.units_to_m = 1;
  CHECK_OK(km_motion_read(path, &mo, &t, NULL, KM_E));
  CHECK(t.n_frames == 120 && fabs(t.fps - 120) < 1e-9);
  CHECK_OK(km_take_resample(&t, 30, &r, KM_E));
  CHECK_MSG(r.n_frames == 30 && r.fps == 30, "%zu frames at %g fps", r.n_frames, r.fps);
  CHECK(fabs(r.n_frames / r.fps - t.n_frames / t.fps) < 1e-12); /* same duration */
  CHECK(r.n_joints == t.n_joints && r.parents && r.parents[1] == 0 &&
        !strcmp(r.joint_names[1], "B"));
  double worst = 0;
  for (size_t k = 0; k < r.n_frames; ++k) /* frame k is input frame 4k */
    for (size_t i = 0; i < 3 * t.n_joints; ++i)
      worst = fmax(worst, fabs(r.positions[k * 3 * t.n_joints + i] -
                               t.positions[4 * k * 3 * t.n_joints + i]));
  CHECK_MSG(worst < 1e-12, "resampled positions differ by %g", worst);
  km_take_free(&r);
  /* upsampling interpolates: 120 -> 240 puts frame 1 half-way between input frames 0 and 1 */
  CHECK_OK(km_take_resample(&t, 240, &r, KM_E));
  CHECK(r.n_frames == 240);
  CHECK(fabs(r.positions[3 * t.n_joints] - 0.5 * t.positions[3 * t.n_joints]) < 1e-12);
  km_take_free(&r);
  CHECK_STATUS(km_take_resample(&t, 0, &r, KM_E), KM_ERR_INVALID);
  km_take_free(&t);
}

/* Every writer option: frames, fps and duration of km_anim_info agree. */
static void test_writer_info(void) {
  km_mesh m = {0};
  double V[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  int32_t F[3] = {0, 1, 2};
  m.V = V;
  m.F = F;
  m.n_vertices = 3;
  m.n_faces = 1;
  const char *names[5] = {"a.glb", "k.glb", "a.pc2", "objs", "plys"};
  km_anim_format fmt[5] = {0, 0, 0, KM_ANIM_OBJ_DIR, KM_ANIM_PLY_DIR};
  size_t key_every[5] = {0, 3, 0, 0, 0};
  const size_t NF = 10;
  for (int w = 0; w < 5; ++w) {
    char path[300];
    snprintf(path, sizeof path, "%s/%s", g_dir, names[w]);
    km_anim_options o = {0};
    o.fps = 24;
    o.format = fmt[w];
    o.key_every = key_every[w];
    km_anim_writer *aw = NULL;
    CHECK_OK(km_anim_writer_open(path, &m, &o, &aw, KM_E));
    if (!aw) continue;
    for (size_t f = 0; f < NF; ++f) {
      double X[9];
      for (int i = 0; i < 9; ++i)
        X[i] = V[i] + 0.01 * (double)f;
      CHECK_OK(km_anim_writer_push(aw, X, KM_E));
    }
    CHECK_OK(km_anim_writer_close(&aw, KM_E));
    km_anim_info ai;
    CHECK_OK(km_anim_info_read(path, &ai, KM_E));
    CHECK_MSG(ai.timeline_frames == NF, "%s: %zu timeline frames", names[w], ai.timeline_frames);
    if (ai.fps > 0)
      CHECK_MSG(fabs(ai.fps - 24) < 1e-9 &&
                    fabs(ai.duration - (double)(ai.timeline_frames - 1) / ai.fps) < 1e-9,
                "%s: %zu frames, %g fps, %g s", names[w], ai.timeline_frames, ai.fps, ai.duration);
    else
      CHECK(ai.duration == 0);
    if (key_every[w] > 1) CHECK(ai.frames == 4); /* keys 0, 3, 6, 9 (the last) */
  }
}

int main(void) {
  if (!mkdtemp(g_dir)) {
    perror("mkdtemp");
    return 1;
  }
  test_bvh_120_to_30();
  test_writer_info();
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
  return km_test_finish("test_motion_time");
}
