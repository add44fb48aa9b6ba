/* Issue 12, bone handles: a thin two-bone "arm" (2 m, radius 2 cm, shoulder at x = 0, elbow at
 * x = 1) with a handle band on each bone ("bone": [shoulder, elbow] and [elbow, wrist]) and the
 * character's joints in the rig bends at the elbow when the performer's forearm turns 90
 * degrees: the forearm band turns with it about the character's own elbow (forward kinematics,
 * whatever the performer's bone lengths), and the edge stretch stays bounded (through
 * km_puppetry, full ARAP and the reduced model). The paper's translation-only hand handle on the
 * same motion moves the hand but does not turn the forearm. Also: "bone" entries are checked when
 * parsed, and a CMU BVH take is read onto the Kinect v1 joints (its names mapped). */
#include "bar_fixture.h"

/* Appends the vertices of rings i0..i1 as a JSON list. */
static int rings(char *s, size_t n, int i0, int i1) {
  int w = 0;
  for (int i = i0; i <= i1; ++i)
    for (int k = 0; k < RING; ++k)
      w += snprintf(s + w, n - (size_t)w, "%s%d", i == i0 && !k ? "" : ",", i * RING + k);
  return w;
}

typedef struct result {
  double stretch;
  double ring[3];    /* centre of ring 30 (x = 1.5 at rest, on the forearm) */
  double ring_ydiff; /* y spread of ring 30: 0 once it lies across the y axis */
} result;

/* bones: the two bone handles (shoulder band anchored by its bone); else the paper's rig: the
 * shoulder ring an anchor, the wrist ring translated by the wrist joint. */
static result run(const km_mesh *m, bool bones, km_puppetry_solver solver) {
  char json[8192];
  size_t n = sizeof json;
  int w = snprintf(json, n, "{\"skeleton\":\"bvh\",\"handles\":[");
  if (bones) {
    w += snprintf(json + w, n - (size_t)w, "{\"name\":\"upper\",\"vertices\":[");
    w += rings(json + w, n - (size_t)w, 6, 14);
    w += snprintf(json + w, n - (size_t)w, "]},{\"name\":\"fore\",\"vertices\":[");
    w += rings(json + w, n - (size_t)w, 26, 34);
    w += snprintf(json + w, n - (size_t)w,
                  "]}],\"map\":[{\"handle\":\"upper\",\"bone\":[\"shoulder\",\"elbow\"]},"
                  "{\"handle\":\"fore\",\"bone\":[\"elbow\",\"wrist\"]}],"
                  "\"joints\":[{\"name\":\"shoulder\",\"rest\":[0,0,0]},"
                  "{\"name\":\"elbow\",\"rest\":[1,0,0]},{\"name\":\"wrist\",\"rest\":[2,0,0]}]}");
  } else {
    w += snprintf(json + w, n - (size_t)w, "{\"name\":\"base\",\"vertices\":[");
    w += rings(json + w, n - (size_t)w, 0, 0);
    w += snprintf(json + w, n - (size_t)w, "]},{\"name\":\"hand\",\"vertices\":[");
    w += rings(json + w, n - (size_t)w, SEGS, SEGS);
    snprintf(json + w, n - (size_t)w, "]}],\"map\":[{\"handle\":\"hand\",\"joint\":\"wrist\"}]}");
  }
  const char *names[3] = {"shoulder", "elbow", "wrist"};
  const int32_t parents[3] = {-1, 0, 1};
  km_rig rig;
  result res = {NAN, {NAN, NAN, NAN}, NAN};
  CHECK_OK(km_rig_parse(json, strlen(json), "arm.rig.json", m, names, 3, &rig, KM_E));
  if (bones) {
    CHECK(rig.n_maps == 2 && rig.maps[0].bone_from == 1 && rig.maps[0].joint == 1 &&
          rig.maps[1].bone_from == 2 && rig.maps[1].joint == 2);
    CHECK(rig.joint_rest && rig.n_joint_rest == 3 && rig.joint_rest[3] == 1);
  }
  km_filter_options raw;
  km_puppetry_options o = bar_raw_options(parents, &raw);
  o.solver = solver;
  o.puppet.fields = 4;
  o.puppet.isolines = 10;
  o.arap.iterations = 100;
  km_puppetry *p = NULL;
  CHECK_OK(km_puppetry_create(m, &rig, names, 3, &o, &p, NULL, KM_E));
  if (p) {
    double *V = malloc(m->n_vertices * 3 * sizeof(double));
    /* The performer's bones are shorter than the character's (0.9 and 0.8 m against 1 and 1):
     * bone handles keep the character's lengths. */
    const double straight[9] = {0, 0, 0, 0.9, 0, 0, 1.7, 0, 0};
    const double bent[9] = {0, 0, 0, 0.9, 0, 0, 0.9, 0.8, 0};
    CHECK_OK(km_puppetry_push(p, straight, V, KM_E));
    for (int f = 0; f < 20; ++f)
      CHECK_OK(km_puppetry_push(p, bent, V, KM_E));
    res.stretch = km_test_edge_stretch(m, V);
    double ylo = INFINITY, yhi = -INFINITY, c[3] = {0, 0, 0};
    for (int k = 0; k < RING; ++k) {
      const double *v = V + 3 * (size_t)(30 * RING + k);
      ylo = fmin(ylo, v[1]);
      yhi = fmax(yhi, v[1]);
      for (int d = 0; d < 3; ++d)
        c[d] += v[d] / RING;
    }
    memcpy(res.ring, c, sizeof c);
    res.ring_ydiff = yhi - ylo;
    free(V);
    km_puppetry_free(&p);
  }
  km_rig_free(&rig);
  return res;
}

static void test_bad_bone(const km_mesh *m) {
  const char *names[3] = {"shoulder", "elbow", "wrist"};
  const char *bad[] = {
      "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
      "\"map\":[{\"handle\":\"h\",\"bone\":[\"shoulder\"]}]}",
      "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
      "\"map\":[{\"handle\":\"h\",\"bone\":[\"knee\",\"elbow\"]}]}",
      "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
      "\"map\":[{\"handle\":\"h\",\"bone\":[\"shoulder\",\"elbow\"],\"joint\":\"elbow\"}]}",
      "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],\"aim\":1,"
      "\"map\":[{\"handle\":\"h\",\"bone\":[\"shoulder\",\"elbow\"]}]}",
      "{\"skeleton\":\"bvh\",\"handles\":[{\"name\":\"h\",\"vertices\":[0]}],"
      "\"local_turn\":\"yes\",\"map\":[{\"handle\":\"h\",\"bone\":[\"shoulder\",\"elbow\"]}]}",
  };
  const char *want[] = {"\"bone\"", "knee", "\"bone\"", "\"aim\"",
                        "\"local_turn\" must be true or false"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
    km_rig rig;
    km_error e = {0};
    CHECK(km_rig_parse(bad[i], strlen(bad[i]), "bad.rig.json", m, names, 3, &rig, &e) ==
          KM_ERR_PARSE);
    CHECK_MSG(strstr(e.message, "bad.rig.json") && strstr(e.message, want[i]), "case %zu: %s", i,
              e.message);
  }
}

/* A CMU BVH (ASF names: LeftShoulder/LeftElbow/LeftWrist/lhand, LeftHip/LeftKnee/LeftAnkle/
 * LeftToe, lowerback, lowerneck) read onto all 20 Kinect v1 joints. */
static void test_cmu_names(void) {
  char path[1024];
  snprintf(path, sizeof path, "%s/bvh/cmu_131_01.bvh", KM_SHARED_DATA);
  FILE *f = fopen(path, "rb");
  if (!f) {
    printf("  skipped the CMU name map: %s is absent\n", path);
    return;
  }
  fclose(f);
  km_motion_read_options ro = {0};
  ro.kinect1 = true;
  km_motion_read_info info;
  km_take t = {0};
  CHECK_OK(km_motion_read(path, &ro, &t, &info, KM_E));
  CHECK_MSG(info.kinect1_found == KM_KINECT1_JOINTS, "%zu of 20 Kinect joints found",
            info.kinect1_found);
  if (t.n_frames) { /* the hand hangs below the elbow, the foot below the knee, at frame 0 */
    const double *p = t.positions;
    int el = km_kinect1_joint_index("ElbowLeft"), hl = km_kinect1_joint_index("HandLeft");
    int kn = km_kinect1_joint_index("KneeLeft"), fl = km_kinect1_joint_index("FootLeft");
    int hd = km_kinect1_joint_index("Head"), hc = km_kinect1_joint_index("HipCenter");
    CHECK(p[3 * hl + 1] < p[3 * el + 1] && p[3 * fl + 1] < p[3 * kn + 1] &&
          p[3 * hd + 1] > p[3 * hc + 1]);
  }
  km_take_free(&t);
}

static void unit_normal(const double *V, const int32_t *t, double n[3]) {
  const double *a = V + 3 * (size_t)t[0], *b = V + 3 * (size_t)t[1], *c = V + 3 * (size_t)t[2];
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] = u[1] * w[2] - u[2] * w[1];
  n[1] = u[2] * w[0] - u[0] * w[2];
  n[2] = u[0] * w[1] - u[1] * w[0];
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int k = 0; k < 3; ++k)
    n[k] = l > 0 ? n[k] / l : 0;
}

/* Armpit creases (issue 12): the procedural character with its default rig (bone handles,
 * aimed) under the generated wave (an arm raised over the head) and kungfu takes: on the
 * triangles near the shoulders (nearest skeleton joint a shoulder), the edge stretch and the
 * triangles that fold in some frame (a neighbour < 60 degrees from them at rest, > 120 degrees
 * now; bench motion's measure). Measured (4000 vertices, 60 frames), upper-arm bands on
 * 0.5 .. 0.8 of the bone against 0.3 .. 0.7 before: wave stretch 0.53 (0.65), no fold (none);
 * kungfu stretch 0.88 (0.83), 9 folded (2). With the pelvis and chest bands and rigid root
 * motion (the demo's torso turning with the body) the torso no longer gives way under a raised
 * arm and the armpit takes it: wave 0.71, kungfu 0.84, still no fold. */
/* Pushes frames [0, nf) of t through p and measures bench motion's way, on the faces with
 * mask[f] (NULL: every face): the largest edge stretch |l/l0 - 1| and the triangles that fold
 * in some frame (a neighbour < 60 degrees from them at rest, > 120 degrees now). */
static void deform_stats(const km_mesh *m, km_puppetry *p, const km_take *t, size_t nf,
                         const unsigned char *mask, size_t *folded, double *stretch) {
  size_t nv = m->n_vertices, nfc = m->n_faces;
  double *V = malloc(3 * nv * sizeof *V), *N0 = malloc(3 * nfc * sizeof *N0),
         *N = malloc(3 * nfc * sizeof *N);
  unsigned char *ever = calloc(nfc, 1);
  for (size_t f = 0; f < nfc; ++f)
    unit_normal(m->V, m->F + 3 * f, N0 + 3 * f);
  /* face pairs across an edge: brute force over sorted half-edges would be tidier; the mesh
   * is small, so a per-vertex face list does */
  size_t *cnt = calloc(nv + 1, sizeof *cnt), *lst = malloc(3 * nfc * sizeof *lst);
  for (size_t f = 0; f < 3 * nfc; ++f)
    ++cnt[m->F[f] + 1];
  for (size_t v = 0; v < nv; ++v)
    cnt[v + 1] += cnt[v];
  size_t *fill = calloc(nv, sizeof *fill);
  for (size_t f = 0; f < nfc; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t v = m->F[3 * f + k];
      lst[cnt[v] + fill[v]++] = f;
    }
  *stretch = 0;
  for (size_t fr = 0; p && fr < nf; ++fr) {
    CHECK_OK(km_puppetry_push(p, t->positions + fr * t->n_joints * 3, V, KM_E));
    for (size_t f = 0; f < nfc; ++f)
      unit_normal(V, m->F + 3 * f, N + 3 * f);
    *stretch = fmax(*stretch, km_test_edge_stretch_in(m, V, mask));
    for (size_t f = 0; f < nfc; ++f) {
      if (mask && !mask[f]) continue;
      for (int k = 0; k < 3; ++k) {
        int32_t v = m->F[3 * f + k];
        for (size_t i = cnt[v]; i < cnt[v + 1]; ++i) {
          size_t g = lst[i];
          if (g == f) continue;
          int shared = 0;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              shared += m->F[3 * f + a] == m->F[3 * g + b];
          if (shared != 2) continue;
          double d0 =
              N0[3 * f] * N0[3 * g] + N0[3 * f + 1] * N0[3 * g + 1] + N0[3 * f + 2] * N0[3 * g + 2];
          double d =
              N[3 * f] * N[3 * g] + N[3 * f + 1] * N[3 * g + 1] + N[3 * f + 2] * N[3 * g + 2];
          if (d0 > 0.5 && d < -0.5) ever[f] = 1;
        }
      }
    }
  }
  *folded = 0;
  for (size_t f = 0; f < nfc; ++f)
    *folded += ever[f];
  free(cnt), free(lst), free(fill), free(V), free(N0), free(N), free(ever);
}

/* Faces whose first corner's nearest skeleton joint (at rest) is one of names. */
static unsigned char *faces_near(const km_character *c, const char *const *names, size_t n_names,
                                 size_t *count) {
  const km_mesh *m = &c->mesh;
  unsigned char *near = calloc(m->n_faces, 1);
  *count = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const double *x = m->V + 3 * (size_t)m->F[3 * f];
    double best = INFINITY;
    int bj = -1;
    for (size_t j = 0; j < c->skeleton.n_joints; ++j) {
      const double *y = c->skeleton.rest + 3 * j;
      double d = (x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                 (x[2] - y[2]) * (x[2] - y[2]);
      if (d < best) best = d, bj = (int)j;
    }
    for (size_t k = 0; k < n_names; ++k)
      near[f] |= bj >= 0 && !strcmp(c->skeleton.names[bj], names[k]);
    *count += near[f];
  }
  return near;
}

/* The procedural character (4000 vertices) and its default rig, built once for the tests below
 * (generating it is the slow part of this file). */
typedef struct {
  km_character c;
  km_rig rig;
} fixture;

static void fixture_make(fixture *fx) {
  km_character_options co = {.target_vertices = 4000};
  char *json = NULL;
  size_t len = 0;
  memset(fx, 0, sizeof *fx);
  CHECK_OK(km_character_generate(&co, &fx->c, KM_E));
  CHECK_OK(km_character_rig_json(&fx->c, &json, &len, KM_E));
  CHECK_OK(km_rig_parse(json, len, "c.rig.json", &fx->c.mesh, NULL, 0, &fx->rig, KM_E));
  free(json);
}

static void fixture_free(fixture *fx) {
  km_rig_free(&fx->rig);
  km_character_free(&fx->c);
}

static void test_armpit_folds(const fixture *fx, km_motion_kind kind) {
  const km_character c = fx->c;
  const km_rig *rig = &fx->rig;
  km_take t = {0};
  CHECK_OK(km_motion_generate(&c.skeleton, kind, 60, &t, KM_E));
  km_puppetry *p = NULL;
  km_puppetry_options o = {0};
  o.fps = t.fps;
  CHECK_OK(km_puppetry_create(&c.mesh, rig, NULL, t.n_joints, &o, &p, NULL, KM_E));
  static const char *const shoulders[] = {"ShoulderLeft", "ShoulderRight"};
  size_t n_near = 0, folded = 0;
  double stretch = 0;
  unsigned char *near = faces_near(&c, shoulders, 2, &n_near);
  CHECK(n_near > 20);
  deform_stats(&c.mesh, p, &t, t.n_frames, near, &folded, &stretch);
  printf("  armpit: %zu of %zu shoulder triangles folded, edge stretch max %.3f over a %zu-frame "
         "%s\n",
         folded, n_near, stretch, t.n_frames, kind == KM_MOTION_WAVE ? "wave" : "kungfu");
  if (kind == KM_MOTION_WAVE) {
    CHECK_MSG(folded == 0, "%zu shoulder triangles folded", folded);
    CHECK_MSG(stretch <= 0.75, "shoulder edge stretch %g", stretch);
  } else {
    CHECK_MSG(folded <= 12, "%zu shoulder triangles folded", folded);
    CHECK_MSG(stretch <= 1.0, "shoulder edge stretch %g", stretch);
  }
  free(near);
  km_puppetry_free(&p);
  km_take_free(&t);
}

/* Elbows and knees on a clean take (issue 12): the procedural character (4000 vertices) with
 * its default rig under CMU 131_01 (no tracker glitches: what folds is the rig's doing),
 * resampled to 30 fps like bench motion. Measured, before -> after the limb bones were aimed
 * from their parent's rotation, the hands and feet turned about the wrist and ankle, and rings
 * turned with half the bend at elbows and knees: folded triangles on the whole mesh 156 -> 37;
 * on the elbow and knee triangles (nearest joint) 106 -> 9, their edge stretch 0.97 -> 0.91
 * (compression on the inside of a bend). The whole mesh's stretch max (1.19 -> 1.20) is the
 * crotch between spreading thighs, which the character's own skinning stretches as far (2.1x):
 * only bounded here. */
static void test_clean_take_joints(const fixture *fx) {
  char path[1024];
  if (!km_test_shared("bvh/cmu_131_01.bvh", path, sizeof path)) return;
  const km_character c = fx->c;
  const km_rig *rig = &fx->rig;
  km_take raw = {0}, t = {0};
  km_motion_read_options ro = {0};
  ro.kinect1 = true;
  km_motion_read_info info;
  CHECK_OK(km_motion_read(path, &ro, &raw, &info, KM_E));
  CHECK_OK(km_take_resample(&raw, 30, &t, KM_E));
  km_puppetry *p = NULL;
  km_puppetry_options o = {0};
  o.fps = t.fps;
  CHECK_OK(km_puppetry_create(&c.mesh, rig, (const char *const *)t.joint_names, t.n_joints, &o, &p,
                              NULL, KM_E));
  size_t folded = 0, folded_j = 0, n_near = 0;
  double stretch = 0, stretch_j = 0;
  deform_stats(&c.mesh, p, &t, t.n_frames, NULL, &folded, &stretch);
  static const char *const joints[] = {"ElbowLeft", "ElbowRight", "KneeLeft", "KneeRight"};
  unsigned char *near = faces_near(&c, joints, 4, &n_near);
  km_puppetry_reset(p);
  deform_stats(&c.mesh, p, &t, t.n_frames, near, &folded_j, &stretch_j);
  printf("  cmu_131_01 (%zu frames): %zu folded, stretch max %.3f; elbows and knees (%zu "
         "triangles): %zu folded, stretch max %.3f\n",
         t.n_frames, folded, stretch, n_near, folded_j, stretch_j);
  CHECK_MSG(folded <= 70, "%zu triangles folded", folded);
  CHECK_MSG(folded_j <= 30, "%zu elbow and knee triangles folded", folded_j);
  CHECK_MSG(stretch_j <= 0.94, "elbow and knee edge stretch %g", stretch_j);
  CHECK_MSG(stretch <= 1.3, "edge stretch %g", stretch);
  free(near);
  km_puppetry_free(&p);
  km_take_free(&raw);
  km_take_free(&t);
}

/* A tracker that never sends the wrists or ankles (OSCeleton: the hand hangs off the elbow):
 * the character's default rig, the performer's forearm raised 60 degrees about a still elbow.
 * The hand handle must rise as it does when the wrist is sent on the forearm, and not at all
 * without the fill (the bones through a joint never seen had no direction). */
static void test_untracked_wrist(const fixture *fx) {
  const km_character c = fx->c;
  const km_rig rig = fx->rig;
  int hand = -1;
  for (size_t h = 0; h < rig.n_handles; ++h)
    if (!strcmp(rig.handles[h].name, "hand_right")) hand = (int)h;
  CHECK(hand >= 0 && c.skeleton.n_joints == KM_KINECT1_JOINTS);
  enum { ELBOW = 9, WRIST = 10, HAND = 11 }; /* Kinect v1, right arm */
  double rise[2];
  for (int untracked = 0; untracked < 2 && hand >= 0; ++untracked) {
    km_retarget *rt = NULL;
    CHECK_OK(km_retarget_create(&rig, &c.mesh, KM_KINECT1_JOINTS, NULL, &rt, KM_E));
    double J[3 * KM_KINECT1_JOINTS], *tg = malloc(3 * rig.n_handles * sizeof(double));
    double before[3] = {0, 0, 0};
    for (int f = 0; f < 2 && rt && tg; ++f) {
      memcpy(J, c.skeleton.rest, sizeof J);
      if (f == 1) /* the forearm (elbow -> wrist -> hand) turned 60 degrees up about z */
        for (int j = WRIST; j <= HAND; ++j) {
          double *x = J + 3 * j, *e = J + 3 * ELBOW, u = x[0] - e[0], v = x[1] - e[1];
          double cs = cos(M_PI / 3), sn = sin(M_PI / 3) * (u > 0 ? 1 : -1);
          x[0] = e[0] + cs * u - sn * v, x[1] = e[1] + sn * u + cs * v;
        }
      if (untracked)
        for (int a = 0; a < 3; ++a)
          J[3 * 6 + a] = J[3 * WRIST + a] = J[3 * 14 + a] = J[3 * 18 + a] = NAN;
      km_retarget_push(rt, J, tg);
      if (f == 0) memcpy(before, tg + 3 * hand, sizeof before);
    }
    rise[untracked] = tg ? tg[3 * hand + 1] - before[1] : 0;
    free(tg);
    km_retarget_free(&rt);
  }
  printf("  hand handle rises %.3f m with the wrist sent, %.3f m without\n", rise[0], rise[1]);
  CHECK_MSG(rise[0] > 0.1, "forearm raised: the hand rose only %g m", rise[0]);
  CHECK_MSG(fabs(rise[1] - rise[0]) < 0.02, "no wrist: the hand rose %g m, with it %g m", rise[1],
            rise[0]);
}

/* The performer's joints first..last turned `angle` degrees about the still joint `pivot` in
 * the plane of axes p -> q (by_side: the sense mirrored for a joint on the -p side, so a right
 * or left forearm both turn "up"), in one push, through the character's default rig with the
 * given "swing_limit", "bend_limit", "upper_limb_limit" and "girdle_limit": how far handle
 * `name` turns about the pivot, degrees. */
static double handle_turn_rig(const fixture *fx, const km_rig *base, const char *name, int pivot,
                              int first, int last, int p, int q, bool by_side, double swing,
                              double bend, double upper, double girdle, double angle) {
  const km_character c = fx->c;
  km_rig rig = *base;
  rig.swing_limit = swing;
  rig.bend_limit = bend;
  rig.upper_limb_limit = upper;
  rig.girdle_limit = girdle;
  int hh = -1;
  for (size_t h = 0; h < rig.n_handles; ++h)
    if (!strcmp(rig.handles[h].name, name)) hh = (int)h;
  CHECK_MSG(hh >= 0, "no handle %s", name);
  if (hh < 0) return NAN;
  km_retarget *rt = NULL;
  /* the whole turn in one push: the bone speed limit (at most 40 degrees a push) off */
  km_retarget_options ro = {.bone_catchup = -1};
  CHECK_OK(km_retarget_create(&rig, &c.mesh, KM_KINECT1_JOINTS, &ro, &rt, KM_E));
  double J[3 * KM_KINECT1_JOINTS], *tg = malloc(3 * rig.n_handles * sizeof(double));
  double v[2][3] = {{0}};
  const double *e = c.skeleton.rest + 3 * pivot;
  for (int f = 0; f < 2 && rt && tg; ++f) {
    memcpy(J, c.skeleton.rest, sizeof J);
    if (f == 1)
      for (int j = first; j <= last; ++j) {
        double *x = J + 3 * j, u = x[p] - e[p], w = x[q] - e[q];
        double cs = cos(angle * M_PI / 180),
               sn = sin(angle * M_PI / 180) * (by_side && u < 0 ? -1 : 1);
        x[p] = e[p] + cs * u - sn * w, x[q] = e[q] + sn * u + cs * w;
      }
    km_retarget_push(rt, J, tg);
    for (int a = 0; a < 3; ++a)
      v[f][a] = tg[3 * hh + a] - e[a];
  }
  double cosang = (v[0][0] * v[1][0] + v[0][1] * v[1][1] + v[0][2] * v[1][2]) /
                  (sqrt(v[0][0] * v[0][0] + v[0][1] * v[0][1] + v[0][2] * v[0][2]) *
                   sqrt(v[1][0] * v[1][0] + v[1][1] * v[1][1] + v[1][2] * v[1][2]));
  free(tg);
  km_retarget_free(&rt);
  return acos(fmax(-1, fmin(1, cosang))) * 180 / M_PI;
}

static double handle_turn(const fixture *fx, const char *name, int pivot, int first, int last,
                          int p, int q, bool by_side, double swing, double bend, double upper,
                          double girdle, double angle) {
  return handle_turn_rig(fx, &fx->rig, name, pivot, first, last, p, q, by_side, swing, bend, upper,
                         girdle, angle);
}

/* The right forearm (wrist and hand) turned up about a still elbow, in the x-y plane. */
static double hand_turn(const fixture *fx, double swing, double bend, double angle) {
  enum { ELBOW = 9, WRIST = 10, HAND = 11 };
  return handle_turn(fx, "hand_right", ELBOW, WRIST, HAND, 0, 1, true, swing, bend, 0, 0, angle);
}

/* The elbow's bend limit (150, an upright body's "bend_limit") counts from the straight arm,
 * whatever the character's rest elbow. A character whose right forearm hangs 50 degrees down at
 * rest (the armadillo's elbows are bent 50 degrees, its knees 23), driven by a straight-armed
 * performer who turns the forearm up: 140 asked turns the hand 140, 170 asked stops at 150.
 * Counted from where the upper arm carries the bent rest forearm, the limit let the 170 through
 * (140 degrees from the rest direction the other way round) and bent the 140 to 160. */
static void test_bend_from_straight(const fixture *fx) {
  enum { ELBOW = 9, WRIST = 10, HAND = 11 };
  km_rig rig = fx->rig;
  size_t nr = rig.n_joint_rest;
  CHECK_MSG(rig.joint_rest && nr > HAND, "the default rig has %zu rest joints", nr);
  if (!rig.joint_rest || nr <= HAND) return;
  double *jr = malloc(3 * nr * sizeof *jr);
  memcpy(jr, rig.joint_rest, 3 * nr * sizeof *jr);
  const double *e = jr + 3 * ELBOW, a = -50 * M_PI / 180;
  for (int j = WRIST; j <= HAND; ++j) { /* the right arm points -x: turned down about z */
    double *x = jr + 3 * j, u = x[0] - e[0], w = x[1] - e[1];
    x[0] = e[0] + cos(a) * u + sin(a) * w, x[1] = e[1] - sin(a) * u + cos(a) * w;
  }
  rig.joint_rest = jr;
  double t140 = handle_turn_rig(fx, &rig, "hand_right", ELBOW, WRIST, HAND, 0, 1, true, 0, 150, 0,
                                0, 140),
         t170 = handle_turn_rig(fx, &rig, "hand_right", ELBOW, WRIST, HAND, 0, 1, true, 0, 150, 0,
                                0, 170);
  printf("  rest forearm bent 50 deg, bend_limit 150: 140 deg asked, the hand turns %.1f; 170 "
         "asked, %.1f\n",
         t140, t170);
  CHECK_MSG(fabs(t140 - 140) < 8, "bent rest, 140 asked: the hand turned %g deg", t140);
  CHECK_MSG(fabs(t170 - 150) < 8, "bent rest, 170 asked: the hand turned %g deg", t170);
  free(jr);
}

/* The head tilted forward about a still shoulder centre, in the y-z plane (the head is not
 * aimed: it turns by its rotation since the first frame). */
static double head_turn(const fixture *fx, double swing, double angle) {
  enum { SHOULDER_CENTER = 2, HEAD = 3 };
  return handle_turn(fx, "head", SHOULDER_CENTER, HEAD, HEAD, 1, 2, false, swing,
                     fx->rig.bend_limit, 0, 0, angle);
}

/* "local_turn" (a resting body's rig): the character's neck laid along +z (its rest Head
 * joint in front of ShoulderCenter, as a body lying down has it) and the performer tilting
 * their head sideways (ear to shoulder: about their forward axis z). In the neck's own frame
 * that tilt is a turn about the character's vertical (the performer's bone up -> the
 * character's forward takes z to -y), so no head vertex moves up or down; turned in the world
 * frame (without local_turn) the head rolls about z instead, its vertices above the pivot
 * dropping. Returns the largest |dy| and |dx| of the head handle's vertex targets. */
static void tilt_lying_head(const fixture *fx, bool local, double *dy, double *dx) {
  enum { SHOULDER_CENTER = 2, HEAD = 3 };
  *dy = *dx = NAN;
  km_rig rig = fx->rig;
  size_t nr = rig.n_joint_rest;
  if (!rig.joint_rest || nr <= HEAD) return;
  double *jr = malloc(3 * nr * sizeof *jr);
  memcpy(jr, rig.joint_rest, 3 * nr * sizeof *jr);
  const double *sc = jr + 3 * SHOULDER_CENTER;
  double *hd = jr + 3 * HEAD, l = hypot(hypot(hd[0] - sc[0], hd[1] - sc[1]), hd[2] - sc[2]);
  hd[0] = sc[0], hd[1] = sc[1], hd[2] = sc[2] + l;
  rig.joint_rest = jr;
  rig.local_turn = local;
  km_retarget *rt = NULL;
  km_retarget_options ro = {.bone_catchup = -1};
  CHECK_OK(km_retarget_create(&rig, &fx->c.mesh, KM_KINECT1_JOINTS, &ro, &rt, KM_E));
  size_t nv = rt ? km_retarget_vertex_count(rt) : 0, first = 0, nh = 0;
  for (size_t h = 0; h < rig.n_handles; ++h) {
    if (!strcmp(rig.handles[h].name, "head")) {
      nh = rig.handles[h].n_vertices;
      break;
    }
    first += rig.handles[h].n_vertices;
  }
  double J[3 * KM_KINECT1_JOINTS], *tg = malloc(3 * rig.n_handles * sizeof(double));
  double *x[2] = {malloc(3 * (nv + 1) * sizeof(double)), malloc(3 * (nv + 1) * sizeof(double))};
  for (int f = 0; f < 2 && rt && tg && x[0] && x[1] && nh; ++f) {
    memcpy(J, fx->c.skeleton.rest, sizeof J);
    if (f == 1) { /* the performer's head tilted 30 degrees about z round ShoulderCenter */
      const double *e = J + 3 * SHOULDER_CENTER;
      double *h = J + 3 * HEAD, u = h[0] - e[0], w = h[1] - e[1], a = 30 * M_PI / 180;
      h[0] = e[0] + cos(a) * u - sin(a) * w, h[1] = e[1] + sin(a) * u + cos(a) * w;
    }
    km_retarget_push(rt, J, tg);
    km_retarget_vertex_targets(rt, x[f]);
  }
  if (rt && nh && x[0] && x[1]) {
    *dy = *dx = 0;
    for (size_t k = first; k < first + nh; ++k) {
      *dy = fmax(*dy, fabs(x[1][3 * k + 1] - x[0][3 * k + 1]));
      *dx = fmax(*dx, fabs(x[1][3 * k] - x[0][3 * k]));
    }
  }
  free(x[0]), free(x[1]), free(tg), free(jr);
  km_retarget_free(&rt);
}

static void test_local_turn(const fixture *fx) {
  double dy, dx, dy0, dx0;
  tilt_lying_head(fx, true, &dy, &dx);
  tilt_lying_head(fx, false, &dy0, &dx0);
  printf("  neck laid along +z, performer's head tilted 30 deg sideways: head vertices move "
         "up/down %.4f, sideways %.4f (local_turn); %.4f, %.4f (world turn)\n",
         dy, dx, dy0, dx0);
  CHECK_MSG(dx > 0.02 && dy < 0.02 * dx,
            "local_turn: the lying head's tilt moved it %g up/down, %g sideways", dy, dx);
  CHECK_MSG(dy0 > 0.2 * dx0, "without local_turn the head rolls (%g up/down, %g sideways)", dy0,
            dx0);
}

/* The rig's limits: a quadruped's legs ("swing_limit", every limb bone: 30 in the rig `rig`
 * writes, 60 here) and the human elbow
 * and knee ("bend_limit": 150, the default rig's). The forearm turns as the performer's within
 * a limit and to the limit beyond it; the upper arm, within, does not move. */
static void test_limits(const fixture *fx) {
  CHECK_MSG(fx->rig.bend_limit == 150, "the default rig's bend_limit is %g", fx->rig.bend_limit);
  double free120 = hand_turn(fx, 0, 0, 120), swing60 = hand_turn(fx, 60, 0, 120);
  double free170 = hand_turn(fx, 0, 0, 170), bend150 = hand_turn(fx, 0, 150, 170);
  double both = hand_turn(fx, 60, 150, 120);
  printf("  hand handle turns about the elbow: 120 deg asked, %.1f free, %.1f with swing_limit "
         "60; 170 asked, %.1f free, %.1f with bend_limit 150; 120 asked, %.1f with both\n",
         free120, swing60, free170, bend150, both);
  CHECK_MSG(fabs(free120 - 120) < 15, "no limit: the hand turned %g deg", free120);
  CHECK_MSG(fabs(swing60 - 60) < 15, "swing_limit 60: the hand turned %g deg", swing60);
  CHECK_MSG(fabs(free170 - 170) < 15, "no limit: the hand turned %g deg", free170);
  CHECK_MSG(fabs(bend150 - 150) < 10 && bend150 < free170 - 10,
            "bend_limit 150: the hand turned %g deg (free %g)", bend150, free170);
  CHECK_MSG(fabs(both - 60) < 15, "both limits: the hand turned %g deg", both);
  /* the head, turned by its rotation since the first frame, is held to the swing limit too */
  double head_free = head_turn(fx, 0, 60), head30 = head_turn(fx, 30, 60),
         head_within = head_turn(fx, 30, 20);
  printf("  head handle turns about the shoulder centre: 60 deg asked, %.1f free, %.1f with "
         "swing_limit 30; 20 asked, %.1f with swing_limit 30\n",
         head_free, head30, head_within);
  CHECK_MSG(fabs(head_free - 60) < 10, "no limit: the head turned %g deg", head_free);
  CHECK_MSG(fabs(head30 - 30) < 8, "swing_limit 30: the head turned %g deg", head30);
  CHECK_MSG(fabs(head_within - 20) < 5, "within swing_limit 30: the head turned %g deg (20 asked)",
            head_within);
  /* Past 135 degrees from its limit cone's centre the swing allowed fades to none at the
   * point opposite (clamp_swing): a forearm pointed straight back along the upper arm leaves
   * the hand at rest, and one 10 degrees short of that turns it about 13 degrees (60 * 10 / 45),
   * not the whole 60 a plain clamp gives with a side that flips across the antipode. */
  double back180 = hand_turn(fx, 60, 0, 180), back170 = hand_turn(fx, 60, 0, 170);
  printf("  with swing_limit 60: 180 deg asked, the hand turns %.1f; 170 asked, %.1f\n", back180,
         back170);
  CHECK_MSG(back180 < 3, "swing_limit 60, the forearm pointed back: the hand turned %g deg",
            back180);
  CHECK_MSG(fabs(back170 - 13.3) < 6, "swing_limit 60, 170 deg asked: the hand turned %g deg",
            back170);
  /* "upper_limb_limit" (a quadruped's rig: 5): the upper arm, the whole arm turned 40 degrees
   * about the shoulder, turns 5; without it, with the arm */
  enum { SHOULDER = 8, ELBOW = 9, HAND = 11 };
  double up_free =
             handle_turn(fx, "upper_arm_right", SHOULDER, ELBOW, HAND, 0, 1, true, 0, 0, 0, 0, 40),
         up5 =
             handle_turn(fx, "upper_arm_right", SHOULDER, ELBOW, HAND, 0, 1, true, 0, 0, 5, 0, 40);
  printf("  upper arm turns about the shoulder: 40 deg asked, %.1f free, %.1f with "
         "upper_limb_limit 5\n",
         up_free, up5);
  CHECK_MSG(fabs(up_free - 40) < 6, "no limit: the upper arm turned %g deg", up_free);
  CHECK_MSG(fabs(up5 - 5) < 3, "upper_limb_limit 5: the upper arm turned %g deg", up5);
  /* "girdle_limit" (a quadruped's rig: 5): the whole arm, shoulder joint included, turned 40
   * degrees about the shoulder centre (a shrug): with upper_limb_limit 5 alone the shoulder bone
   * carries the arm the whole way; with girdle_limit 5 too the shoulder turns 5 and the upper
   * arm 5 more at most */
  enum { SHOULDER_CENTER = 2 };
  double sh_free = handle_turn(fx, "upper_arm_right", SHOULDER_CENTER, SHOULDER, HAND, 0, 1, true,
                               0, 0, 5, 0, 40),
         sh5 = handle_turn(fx, "upper_arm_right", SHOULDER_CENTER, SHOULDER, HAND, 0, 1, true, 0, 0,
                           5, 5, 40);
  printf("  upper arm turns about the shoulder centre: 40 deg asked, %.1f with upper_limb_limit "
         "5, %.1f with girdle_limit 5 too\n",
         sh_free, sh5);
  CHECK_MSG(fabs(sh_free - 40) < 6, "no girdle limit: the upper arm turned %g deg", sh_free);
  CHECK_MSG(sh5 < 12, "girdle_limit 5: the upper arm turned %g deg about the shoulder centre", sh5);
}

/* Feet on the floor (the sidecar's rig: rigid root motion, aimed limbs): a performer who sinks
 * 0.1 m as a whole (the tracker's floor drifting, or legs measured short) leaves the character
 * standing (lift_root), and a squat, shins leaning 30 degrees forward over still ankles, leaves
 * the feet flat (flatten_foot; a foot turned with its shin put its toe under the floor): no
 * handle vertex below the rest floor. */
static void test_feet_on_floor(const fixture *fx) {
  km_rig rig = fx->rig;
  CHECK_MSG(rig.root_rigid && rig.aim, "the default rig has rigid root motion and aimed limbs");
  km_retarget *rt = NULL;
  km_retarget_options ro = {.bone_catchup = -1};
  CHECK_OK(km_retarget_create(&rig, &fx->c.mesh, KM_KINECT1_JOINTS, &ro, &rt, KM_E));
  if (!rt) return;
  size_t nv = km_retarget_vertex_count(rt);
  double *X = malloc(3 * nv * sizeof(double)), J[3 * KM_KINECT1_JOINTS];
  double floor_y = INFINITY, diag = km_bbox_diagonal(fx->c.mesh.V, fx->c.mesh.n_vertices);
  for (size_t v = 0; v < fx->c.mesh.n_vertices; ++v)
    floor_y = fmin(floor_y, fx->c.mesh.V[3 * v + 1]);
  const double *J0 = fx->c.skeleton.rest;
  /* the foot_left handle's vertices among the targets */
  size_t off = 0, n_foot = 0;
  for (size_t h = 0; h < rig.n_handles && !n_foot; ++h) {
    if (!strcmp(rig.handles[h].name, "foot_left"))
      n_foot = rig.handles[h].n_vertices;
    else
      off += rig.handles[h].n_vertices;
  }
  CHECK_MSG(n_foot >= 3, "no foot_left handle");
  double *X0 = malloc(3 * nv * sizeof(double)), lowest[4], foot_turn = NAN;
  for (int f = 0; f < 4 && X && X0; ++f) {
    memcpy(J, J0, sizeof J);
    if (f == 1)
      for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
        J[3 * j + 1] -= 0.1;
    if (f >= 2) { /* a squat: ankles and feet still, shins leaning 30 degrees forward, thighs
                     30 degrees back, the upper body lowered with the hips; a deep one, 60 */
      double ang = (f == 2 ? 30 : 60) * M_PI / 180;
      double cs = cos(ang), sn = sin(ang), D[3] = {0, 0, 0};
      for (int k = 0; k < 2; ++k) {
        const int hip = k ? 16 : 12, knee = hip + 1, ankle = hip + 2;
        const double *a = J0 + 3 * ankle, *k0 = J0 + 3 * knee, *h0 = J0 + 3 * hip;
        double *kn = J + 3 * knee, *h = J + 3 * hip;
        double u = k0[1] - a[1], w = k0[2] - a[2]; /* shin, ankle -> knee: y, z */
        kn[1] = a[1] + cs * u - sn * w, kn[2] = a[2] + sn * u + cs * w;
        u = h0[1] - k0[1], w = h0[2] - k0[2]; /* thigh, knee -> hip */
        h[1] = kn[1] + cs * u + sn * w, h[2] = kn[2] - sn * u + cs * w;
        for (int d = 0; d < 3; ++d)
          D[d] += 0.5 * (h[d] - h0[d]);
      }
      for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
        if (!(j >= 12 && j <= 19))
          for (int d = 0; d < 3; ++d)
            J[3 * j + d] += D[d];
    }
    km_retarget_push(rt, J, NULL);
    km_retarget_vertex_targets(rt, X);
    km_retarget_apply_root(rt, X, nv);
    lowest[f] = INFINITY;
    for (size_t k = 0; k < nv; ++k)
      lowest[f] = fmin(lowest[f], X[3 * k + 1]);
    if (f == 0) memcpy(X0, X, 3 * nv * sizeof(double));
    double R[9], t[3];
    if (f == 3 && n_foot >= 3 &&
        km_similarity_fit(X0 + 3 * off, X + 3 * off, NULL, n_foot, false, NULL, R, t, KM_E) ==
            KM_OK)
      foot_turn = acos(fmax(-1, fmin(1, 0.5 * (R[0] + R[4] + R[8] - 1)))) * 180 / M_PI;
  }
  free(X0);
  /* The deep squat: the flattening turns the foot at most 30 degrees off its shin's rotation (a
   * foot held flat under a shin leaning far over it bent the ankle more than the skin between
   * the foot handle and the shin band can take): the foot turns about 30 of the shin's 60. */
  printf("  feet: a deep squat, shins leaning 60 deg forward: the foot turns %.1f deg\n",
         foot_turn);
  CHECK_MSG(foot_turn > 20 && foot_turn < 40,
            "the foot under a shin leaning 60 deg turned %.1f deg (want about 30)", foot_turn);
  printf("  feet: lowest handle vertex above the rest floor %.4f (rest), %.4f (performer 0.1 m "
         "lower), %.4f (a squat, shins leaning 30 deg forward), diagonal %.3f\n",
         lowest[0] - floor_y, lowest[1] - floor_y, lowest[2] - floor_y, diag);
  CHECK_MSG(lowest[1] > floor_y - 1e-3 * diag, "the sunk performer put a foot %.4f under the floor",
            floor_y - lowest[1]);
  CHECK_MSG(lowest[2] > floor_y - 0.002 * diag, "the squat put a toe %.4f under the floor",
            floor_y - lowest[2]);
  free(X);
  km_retarget_free(&rt);
}

int main(void) {
  fixture fx;
  fixture_make(&fx);
  test_untracked_wrist(&fx);
  test_armpit_folds(&fx, KM_MOTION_WAVE);
  test_armpit_folds(&fx, KM_MOTION_KUNGFU);
  test_clean_take_joints(&fx);
  test_limits(&fx);
  test_bend_from_straight(&fx);
  test_local_turn(&fx);
  test_feet_on_floor(&fx);
  fixture_free(&fx);
  km_mesh m = bar();
  for (int solver = 0; solver < 2; ++solver) {
    km_puppetry_solver sv = solver ? KM_PUPPETRY_FULL : KM_PUPPETRY_REDUCED;
    result b = run(&m, true, sv), t = run(&m, false, sv);
    printf("  %s: edge stretch max %.4f with bone handles, %.4f translation-only; forearm ring "
           "at (%.3f %.3f %.3f), y spread %.4f\n",
           solver ? "full" : "reduced", b.stretch, t.stretch, b.ring[0], b.ring[1], b.ring[2],
           b.ring_ydiff);
    /* The forearm ring (x = 1.5 at rest) turned about the character's elbow (1, 0, 0): now at
     * (1, 0.5, 0), lying across y; the reduced model meets its targets in the least-squares
     * sense only. */
    double tol = solver ? 0.002 : 0.05;
    CHECK_MSG(fabs(b.ring[0] - 1) < tol && fabs(b.ring[1] - 0.5) < tol && fabs(b.ring[2]) < tol,
              "forearm ring at (%g %g %g)", b.ring[0], b.ring[1], b.ring[2]);
    CHECK_MSG(b.ring_ydiff < (solver ? 1e-6 : 0.02), "forearm ring did not turn (y spread %g)",
              b.ring_ydiff);
    /* A tube bent 90 degrees about a pivot on its axis: the stretch between the bands is
     * bounded by the inside of the corner (an arc of the same ends is 2 * 0.3 * pi / 4 long
     * against 0.6: 21% shorter); measured: 18% full, 33% reduced (4 fields). The paper's
     * handle moves the hand but leaves the forearm unturned. */
    CHECK_MSG(b.stretch < (solver ? 0.22 : 0.36), "bone handles stretch %g (translation-only %g)",
              b.stretch, t.stretch);
    CHECK_MSG(t.ring_ydiff > 0.005 && t.ring_ydiff > 4 * b.ring_ydiff,
              "translation-only forearm turned (y spread %g)", t.ring_ydiff);
  }
  test_bad_bone(&m);
  test_cmu_names();
  free(m.V);
  free(m.F);
  return km_test_finish("test_motion_bones");
}
