/* Issue 12, one-frame jumps on a real Kinect take: precog_Seq2_1 (../shared) carries tracker
 * glitches (a hand 0.85 m away for one frame, a foot that jumps 0.46 m and stays, joints lost
 * and re-found), so the mapped joints' own largest step is about a third of the character's
 * diagonal. Through `kinemesh bench motion` on the procedural character, the paper's
 * translation-only rig (T) and the bone rig (B) must keep the mesh's largest one-frame vertex
 * step well below that: glitches rejected, a re-found joint eased back in bone by bone
 * (km_glitch catch-up) rather than snapped, the root heading's glitches held. Before: T 14.9 %,
 * B 18.4 % of the diagonal; after: T 11.1 %, B 14.5 %. Skips when ../shared is absent.
 * The bone speed limit (km_retarget_options.bone_catchup) and the heading's re-fit easing: B
 * on precog_Seq1_1 (a collapsing Kinect forearm swung the character's hand 19.5 % of the
 * diagonal in a frame) and on dog0 (precog_Seq2_1's skeleton re-fit turned the quadruped 26 %
 * of its diagonal in a frame) must stay well below; on a synthetic two-bone arm (no ../shared
 * needed) a forearm that collapses to 7 cm and flips 135 degrees for a frame no longer swings
 * the forearm band, while a real full-length swing of 30 degrees a frame arrives unchanged. */
#include "bar_fixture.h"

#include <cjson/cJSON.h>
#include <unistd.h>

/* The bar arm of test_motion_bones (shoulder 0, elbow 1, wrist 2 on x; a band on each bone)
 * driven by frames[nf][9] (shoulder, elbow, wrist of the performer, 0.9 m and 0.8 m bones):
 * the largest one-frame step of the forearm band's ring at x = 1.5, and the ring's centre per
 * frame (ring[nf][3]). bone_catchup < 0: the bone speed limit off. */
static double arm_run(const km_mesh *m, const double (*frames)[9], int nf, double bone_catchup,
                      double (*ring)[3]) {
  char json[8192];
  size_t n = sizeof json;
  int w =
      snprintf(json, n, "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"upper\",\"vertices\":[");
  for (int i = 6; i <= 14; ++i)
    for (int k = 0; k < RING; ++k)
      w += snprintf(json + w, n - (size_t)w, "%s%d", i == 6 && !k ? "" : ",", i * RING + k);
  w += snprintf(json + w, n - (size_t)w, "]},{\"name\":\"fore\",\"vertices\":[");
  for (int i = 26; i <= 34; ++i)
    for (int k = 0; k < RING; ++k)
      w += snprintf(json + w, n - (size_t)w, "%s%d", i == 26 && !k ? "" : ",", i * RING + k);
  snprintf(json + w, n - (size_t)w,
           "]}],\"map\":[{\"handle\":\"upper\",\"bone\":[\"shoulder\",\"elbow\"]},"
           "{\"handle\":\"fore\",\"bone\":[\"elbow\",\"wrist\"]}],"
           "\"joints\":[{\"name\":\"shoulder\",\"rest\":[0,0,0]},"
           "{\"name\":\"elbow\",\"rest\":[1,0,0]},{\"name\":\"wrist\",\"rest\":[2,0,0]}]}");
  const char *names[3] = {"shoulder", "elbow", "wrist"};
  const int32_t parents[3] = {-1, 0, 1};
  km_rig rig;
  double worst = NAN;
  CHECK_OK(km_rig_parse(json, strlen(json), "arm.rig.json", m, names, 3, &rig, KM_E));
  km_filter_options raw;
  km_puppetry_options o = bar_raw_options(parents, &raw);
  o.retarget.bone_catchup = bone_catchup;
  o.solver = KM_PUPPETRY_FULL;
  o.arap.iterations = 100;
  o.fps = 30;
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(m, &rig, names, 3, &o, &p, NULL, KM_E));
  if (p) {
    double *V = malloc(m->n_vertices * 3 * sizeof(double)), prev[3] = {0, 0, 0};
    worst = 0;
    for (int f = 0; f < nf; ++f) {
      CHECK_OK(km_puppetry_push(p, frames[f], V, KM_E));
      double c[3] = {0, 0, 0};
      for (int k = 0; k < RING; ++k)
        for (int d = 0; d < 3; ++d)
          c[d] += V[3 * (size_t)(30 * RING + k) + d] / RING;
      if (f)
        worst = fmax(worst, sqrt((c[0] - prev[0]) * (c[0] - prev[0]) +
                                 (c[1] - prev[1]) * (c[1] - prev[1]) +
                                 (c[2] - prev[2]) * (c[2] - prev[2])));
      memcpy(prev, c, sizeof c);
      if (ring) memcpy(ring[f], c, sizeof c);
    }
    free(V);
    km_puppetry_free(&p);
  }
  km_rig_free(&rig);
  return worst;
}

static void test_collapsing_forearm(void) {
  km_mesh m = bar();
  /* The wrist (0.8 m from the elbow along x) collapses onto the elbow for two frames, the
   * second time on the far side (7 cm away, 135 degrees round), then comes back: the wrist
   * moves at most 0.73 m a frame but its measured direction flips. */
  double glitch[12][9];
  for (int f = 0; f < 12; ++f) {
    const double base[9] = {0, 0, 0, 0.9, 0, 0, 1.7, 0, 0};
    memcpy(glitch[f], base, sizeof base);
  }
  glitch[4][6] = 0.95;                      /* 5 cm out along x: same direction */
  glitch[5][6] = 0.85, glitch[5][7] = 0.05; /* 7 cm, 135 degrees round */
  glitch[6][6] = 0.95;
  double on = arm_run(&m, (const double(*)[9])glitch, 12, 0, NULL);
  double off = arm_run(&m, (const double(*)[9])glitch, 12, -1, NULL);
  printf("collapsing forearm: the forearm ring's largest one-frame step %.3f m with the bone "
         "speed limit, %.3f m without\n",
         on, off);
  CHECK_MSG(off > 0.6, "without the limit the flip should swing the forearm (%.3f m)", off);
  CHECK_MSG(on < 0.08, "the forearm ring stepped %.3f m in a frame (limit on)", on);

  /* A real swing: the full-length forearm turns 30 degrees a frame through 120 degrees (a
   * punch's elbow at 900 deg/s); every frame lands where it does without the limit. */
  double swing[8][9], ron[8][3], roff[8][3];
  for (int f = 0; f < 8; ++f) {
    double a = (f < 1 ? 0 : f > 4 ? 4 : f) * 30 * M_PI / 180;
    const double fr[9] = {0, 0, 0, 0.9, 0, 0, 0.9 + 0.8 * cos(a), 0.8 * sin(a), 0};
    memcpy(swing[f], fr, sizeof fr);
  }
  arm_run(&m, (const double(*)[9])swing, 8, 0, ron);
  arm_run(&m, (const double(*)[9])swing, 8, -1, roff);
  double dmax = 0;
  for (int f = 0; f < 8; ++f)
    for (int d = 0; d < 3; ++d)
      dmax = fmax(dmax, fabs(ron[f][d] - roff[f][d]));
  printf("real swing: the forearm ring with and without the limit differs by %.2g m at most\n",
         dmax);
  CHECK_MSG(dmax < 1e-6, "a real 30 deg/frame swing was held back (%.3g m)", dmax);
  free(m.V);
  free(m.F);
}

int main(void) {
  test_collapsing_forearm();
  const char *take = KM_SHARED_DATA "/skeleton/precog_Seq2_1.csv";
  if (access(take, R_OK) != 0) {
    printf("test_motion_kinect_jump: %s absent, the real takes skipped\n", take);
    return km_test_finish("test_motion_kinect_jump");
  }
  char cwd[900], xdg[1024];
  if (getcwd(cwd, sizeof cwd)) {
    snprintf(xdg, sizeof xdg, "%s/puppet_cache", cwd);
    setenv("XDG_CACHE_HOME", xdg, 1);
  }
  char *out = NULL;
  int rc = km_test_run(KM_CLI " bench motion --meshes character:4000," KM_SHARED_DATA
                              "/meshes/dog0.off --takes " KM_SHARED_DATA
                              "/skeleton/precog_Seq2_1.csv," KM_SHARED_DATA
                              "/skeleton/precog_Seq1_1.csv --json 2>/dev/null",
                       &out);
  CHECK_MSG(rc == 0, "exit status %d: %s", rc, out ? out : "");
  int rows = 0;
  for (char *line = out ? strtok(out, "\n") : NULL; line; line = strtok(NULL, "\n")) {
    if (line[0] != '{') continue;
    cJSON *row = cJSON_Parse(line);
    const cJSON *t = cJSON_GetObjectItem(row, "translate");
    const cJSON *jt = cJSON_GetObjectItem(t, "jump_max_pct");
    const cJSON *jb = cJSON_GetObjectItem(cJSON_GetObjectItem(row, "bones"), "jump_max_pct");
    const cJSON *jr = cJSON_GetObjectItem(row, "take_jump_max_pct");
    const cJSON *tk = cJSON_GetObjectItem(row, "take");
    const cJSON *me = cJSON_GetObjectItem(row, "mesh");
    if (cJSON_IsNumber(jt) && cJSON_IsNumber(jr) && cJSON_IsNumber(jb) && cJSON_IsString(tk) &&
        cJSON_IsString(me)) {
      ++rows;
      bool seq1 = strstr(tk->valuestring, "Seq1_1") != NULL;
      bool dog = strstr(me->valuestring, "dog0") != NULL;
      printf("%s on %s: take %.2f %%, T %.2f %%, B %.2f %% of the diagonal\n", tk->valuestring,
             me->valuestring, jr->valuedouble, jt->valuedouble, jb->valuedouble);
      CHECK_MSG(jr->valuedouble > (seq1 ? 18 : 25),
                "the take's own largest step is %.2f %% (glitches expected)", jr->valuedouble);
      CHECK_MSG(jt->valuedouble < (seq1 ? 11.5 : 13.5),
                "T's largest one-frame jump %.2f %% of the diagonal", jt->valuedouble);
      /* B without the bone speed limit and the heading's re-fit easing (before / after):
       * character:4000 precog_Seq1_1 19.5 / 12.9 % (a collapsing left forearm, frames 149 and
       * 179), precog_Seq2_1 15.3 / 12.7 %; dog0 precog_Seq2_1 26.1 / 17.8 % (the tracker
       * re-fits the skeleton 70 degrees round over frames 19-22 and the quadruped turned 20
       * degrees a frame), precog_Seq1_1 15.3 / 15.3 % */
      double limit = dog ? (seq1 ? 17 : 21) : (seq1 ? 14.5 : 14);
      CHECK_MSG(jb->valuedouble < limit, "%s on %s: B's largest one-frame jump %.2f %% (>= %g)",
                tk->valuestring, me->valuestring, jb->valuedouble, limit);
    }
    cJSON_Delete(row);
  }
  CHECK_MSG(rows == 4, "%d rows with jumps in: %s", rows, out ? out : "");
  free(out);
  return km_test_finish("test_motion_kinect_jump");
}
