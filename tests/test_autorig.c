/* Automatic rigging (km_autorig, kinemesh rig): on the procedural character every joint lands
 * within 5% of the height of the true skeleton; on real meshes (armadillo, dog, elephant,
 * horse in ../shared/data) the rig drives the puppetry pipeline from a real Kinect take with no
 * NaN, edges stretched less than 1.5x and handles following their joints; meshes it cannot
 * rig (two components, a non-manifold edge, no faces) are refused naming the problem. */
#include "km_test.h"

#include "synth/synth.h"

#include <stdint.h>
#include <unistd.h>

static char g_dir[] = "/tmp/km_test_autorig_XXXXXX";

static bool skin_valid(const km_skin *s, size_t n) {
  if (s->n_vertices != n) return false;
  for (size_t v = 0; v < n; ++v) {
    double sum = 0;
    for (int q = 0; q < KM_SKIN_INFLUENCES; ++q) {
      int32_t j = s->joints[4 * v + q];
      double w = s->weights[4 * v + q];
      if (j < -1 || j >= KM_KINECT1_JOINTS || !(w >= 0 && w <= 1)) return false;
      if (j < 0 && w != 0) return false;
      sum += w;
    }
    if (fabs(sum - 1) > 1e-9) return false;
  }
  return true;
}

/* Issue 11: landmarks are distinct vertices, each near the point of its joint that its ray
 * starts from (within limit of the height H): the farthest hit along a ray put FAUST's head
 * and neck on one vertex (the nose), its elbows on the shoulders and its hips on the hands. */
static int joint_index(const km_skeleton *s, const char *name) {
  for (size_t j = 0; j < s->n_joints; ++j)
    if (!strcmp(s->names[j], name)) return (int)j;
  CHECK_MSG(false, "no joint %s", name);
  return 0;
}

static void check_landmarks(const char *label, const km_mesh *m, const km_character *c, double H,
                            double limit) {
  static const char *const joint_of[KM_CHARACTER_LANDMARKS][2] = {
      {"Head", NULL},          {"ShoulderCenter", "Head"}, {"ShoulderLeft", NULL},
      {"ShoulderRight", NULL}, {"ElbowLeft", NULL},        {"ElbowRight", NULL},
      {"HandLeft", NULL},      {"HandRight", NULL},        {"Spine", "ShoulderCenter"},
      {"HipCenter", NULL},     {"HipLeft", NULL},          {"HipRight", NULL},
      {"KneeLeft", NULL},      {"KneeRight", NULL},        {"FootLeft", NULL},
      {"FootRight", NULL}};
  const km_skeleton *s = &c->skeleton;
  double worst = 0;
  int wi = 0;
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    int32_t v = c->landmarks[i].vertex;
    CHECK(v >= 0 && (size_t)v < m->n_vertices);
    if (v < 0 || (size_t)v >= m->n_vertices) continue;
    for (int k = 0; k < i; ++k)
      CHECK_MSG(c->landmarks[k].vertex != v, "%s: landmarks %s and %s on one vertex (%d)", label,
                c->landmarks[k].name, c->landmarks[i].name, (int)v);
    /* the ray's start: the joint, the neck half way up to the head, the chest 0.6 of the way
     * from the spine to the shoulders (src/autorig/autorig.c compute_landmarks) */
    const double *a = s->rest + 3 * joint_index(s, joint_of[i][0]);
    double q[3] = {a[0], a[1], a[2]};
    if (joint_of[i][1]) {
      const double *b = s->rest + 3 * joint_index(s, joint_of[i][1]);
      double t = i == 8 ? 0.6 : 0.5;
      for (int k = 0; k < 3; ++k)
        q[k] = a[k] + t * (b[k] - a[k]);
    }
    const double *p = m->V + 3 * (size_t)v;
    double d = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                    (p[2] - q[2]) * (p[2] - q[2]));
    CHECK_MSG(d < limit * H,
              "%s: landmark %s (vertex %d) is %.3f (%.1f%% of the height) from its "
              "joint",
              label, c->landmarks[i].name, (int)v, d, 100 * d / H);
    if (d > worst) worst = d, wi = i;
  }
  printf("%s: landmarks: the farthest from its joint %s at %.1f%% of the height\n", label,
         c->landmarks[wi].name, 100 * worst / H);
}

/* FAUST's first registration (a standing scan, arms down, y up): the rig's landmarks. */
static void test_faust_landmarks(void) {
  char buf[1024];
  const char *path = km_test_shared("poses/tr_reg_000.off", buf, sizeof buf);
  if (!path) return;
  km_mesh m = {0};
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  if (c.skeleton.n_joints == KM_KINECT1_JOINTS)
    check_landmarks("FAUST tr_reg_000", &m, &c, rep.height, 0.10);
  km_character_free(&c);
  km_mesh_free(&m);
}

/* The true skeleton is known: every embedded joint within 5% of the height. */
static void test_character(size_t nv, uint64_t seed, double belly, double girth) {
  km_character_options co = {0};
  co.target_vertices = nv;
  co.seed = seed;
  co.belly = belly;
  co.girth = girth;
  km_character c = {0}, r = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  km_autorig_report rep;
  CHECK_OK(km_autorig(&c.mesh, NULL, &r, &rep, KM_E));
  if (r.skeleton.n_joints != KM_KINECT1_JOINTS) {
    CHECK(false);
    km_character_free(&c);
    return;
  }
  CHECK(rep.kind == KM_AUTORIG_KINECT1);
  double H = rep.height, worst = 0;
  int wj = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    const double *a = c.skeleton.rest + 3 * j, *b = r.skeleton.rest + 3 * j;
    double d = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                    (a[2] - b[2]) * (a[2] - b[2]));
    CHECK_MSG(d < 0.05 * H,
              "character %zu seed %llu: %s is %.3f m (%.1f%% of the height) "
              "from the truth",
              nv, (unsigned long long)seed, km_kinect1_joint_name(j), d, 100 * d / H);
    if (d > worst) worst = d, wj = j;
    CHECK(!strcmp(r.skeleton.names[j], km_kinect1_joint_name(j)));
    CHECK(r.skeleton.parents[j] == km_kinect1_joint_parent(j));
  }
  printf("character %zu vertices (seed %llu, belly %g, girth %g): worst joint %s at %.1f%% of "
         "the height, rigged in %.3f s\n",
         c.mesh.n_vertices, (unsigned long long)seed, belly, girth, km_kinect1_joint_name(wj),
         100 * worst / H, rep.seconds);
  CHECK(r.mesh.n_vertices == c.mesh.n_vertices &&
        memcmp(r.mesh.V, c.mesh.V, sizeof(double) * 3 * c.mesh.n_vertices) == 0);
  CHECK(skin_valid(&r.skin, c.mesh.n_vertices));
  /* Landmarks: the true ones' names, near the true ones (within 8% of the height). */
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    CHECK(!strcmp(r.landmarks[i].name, c.landmarks[i].name));
    CHECK(!strcmp(r.landmarks[i].mirror, c.landmarks[i].mirror));
    const double *a = c.mesh.V + 3 * (size_t)c.landmarks[i].vertex,
                 *b = c.mesh.V + 3 * (size_t)r.landmarks[i].vertex;
    double d = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                    (a[2] - b[2]) * (a[2] - b[2]));
    CHECK_MSG(d < 0.08 * H, "landmark %s is %.3f m from the truth", r.landmarks[i].name, d);
  }
  char label[64];
  snprintf(label, sizeof label, "character %zu seed %llu", nv, (unsigned long long)seed);
  check_landmarks(label, &c.mesh, &r, H, 0.10);
  /* The sidecar round-trips and resolves as a puppetry rig. */
  char path[256];
  snprintf(path, sizeof path, "%s/char_%llu.rig.json", g_dir, (unsigned long long)seed);
  CHECK_OK(km_character_write_rig(path, &r, KM_E));
  km_character back = {0};
  CHECK_OK(km_character_read_rig(path, c.mesh.n_vertices, &back, KM_E));
  CHECK(back.skeleton.n_joints == KM_KINECT1_JOINTS);
  km_character_free(&back);
  km_rig rig = {0};
  CHECK_OK(km_rig_read(path, &c.mesh, NULL, 0, &rig, KM_E));
  /* head, hands, feet, bone handles on the upper and lower arms and legs, pelvis and chest,
   * rings at the elbows and knees */
  CHECK_MSG(rig.n_handles == 19 && rig.n_maps == 19, "%zu handles, %zu maps", rig.n_handles,
            rig.n_maps);
  CHECK(rig.aim && rig.joint_rest && rig.n_joint_rest == KM_KINECT1_JOINTS);
  for (size_t e = 0; e < rig.n_maps; ++e)
    CHECK(rig.maps[e].bone_from > 0);
  km_rig_free(&rig);
  km_character_free(&r);
  km_character_free(&c);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Drives mesh m through the rig sidecar of c with a real take; checks no NaN, edge stretch
 * (max_stretch: bound on the worst edge; INFINITY: no stretch checks, for props whose handles
 * were placed by position only)
 * and handles following their targets. Stretch: per edge, its largest length over the take
 * / its rest length. The sidecar's handles turn with their bones, but the skin between them
 * takes each joint's bend (this take's performer starts with the arms down: the T-posed arms
 * swing 90 degrees, and kicks raise a thigh level): even the procedural character's true rig
 * reaches 2.2x on its worst edge (the crotch) and 1.4x at the 99th percentile, measured. The
 * median edge must stay below 1.5x on
 * every mesh; the automatic rig's 99th percentile on the character is compared with the true
 * rig's in test_character_drive. *stretch_out: the 99th percentile; *jump_out: the largest
 * one-frame vertex step, % of the rest mesh's bounding-box diagonal (either may be NULL). */
static void drive_with(const char *label, const km_mesh *m, const km_character *c,
                       const km_take *take, double *stretch_out, double *jump_out,
                       double max_stretch, bool full) {
  char rig_path[512];
  snprintf(rig_path, sizeof rig_path, "%s/drive_%zu.rig.json", g_dir, m->n_vertices);
  CHECK_OK(km_character_write_rig(rig_path, c, KM_E));
  km_rig rig = {0};
  CHECK_OK(km_rig_read(rig_path, m, NULL, 0, &rig, KM_E));
  /* A body with feet keeps them out of the ground ("floor": true): without it the armadillo
   * had a vertex under its rest floor in 244 of cmu_131_01's 994 frames (bench motion B). A
   * bust or an upper body has no feet and no floor; a resting body (a head and a base, its
   * spine, HipCenter -> ShoulderCenter, closer to level than upright) keeps its head out of the
   * ground. */
  bool feet = false;
  for (size_t h = 0; h < rig.n_handles; ++h)
    feet |= !strcmp(rig.handles[h].name, "foot_left");
  bool lying = false;
  if (c->skeleton.rest && rig.n_handles == 2) {
    const double *hc = c->skeleton.rest, *sc = c->skeleton.rest + 3 * 2;
    lying = fabs(sc[1] - hc[1]) < hypot(sc[0] - hc[0], sc[2] - hc[2]);
  }
  CHECK_MSG(rig.floor == (feet || lying), "%s: the sidecar's rig has \"floor\" %d with feet %d",
            label, (int)rig.floor, (int)feet);
  km_puppetry *p = NULL;
  km_puppetry_options po = {0};
  po.fps = take->fps; /* the take's own rate (a CMU BVH: 120 fps) */
  if (full) {         /* animate --solver full: full-space ARAP, its default soft handles */
    po.solver = KM_PUPPETRY_FULL;
    po.arap.handle_weight = KM_ARAP_SOFT_HANDLES;
  }
  CHECK_OK(km_puppetry_create(m, &rig, (const char *const *)take->joint_names, take->n_joints, &po,
                              &p, NULL, KM_E));
  if (!p) {
    km_rig_free(&rig);
    return;
  }
  size_t nv = m->n_vertices, ne = 3 * m->n_faces, nh = 0;
  const int32_t *off = NULL, *hv = NULL;
  km_puppetry_handles(p, &nh, &off, &hv);
  double *V = malloc(sizeof(double) * 3 * nv), *len0 = malloc(sizeof(double) * ne),
         *smax = calloc(ne, sizeof(double)), *Vp = malloc(sizeof(double) * 3 * nv);
  double diag = km_bbox_diagonal(m->V, nv), jump_pct = 0, floor_y = INFINITY;
  for (size_t i = 0; i < nv; ++i)
    floor_y = fmin(floor_y, m->V[3 * i + 1]);
  size_t below = 0; /* frames with a vertex under the rest floor by more than 0.5 % of diag */
  for (size_t e = 0; e < ne; ++e) {
    size_t f = e / 3;
    int k = (int)(e % 3);
    const double *a = m->V + 3 * (size_t)m->F[3 * f + k],
                 *b = m->V + 3 * (size_t)m->F[3 * f + (k + 1) % 3];
    len0[e] = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
  }
  size_t nonfinite = 0;
  double dev_sum = 0, move_sum = 0;
  for (size_t fr = 0; fr < take->n_frames; ++fr) {
    if (km_puppetry_push(p, take->positions + fr * take->n_joints * 3, V, KM_E) != KM_OK) {
      CHECK_MSG(false, "%s frame %zu: %s", label, fr, km_test_err.message);
      break;
    }
    for (size_t i = 0; i < 3 * nv; ++i)
      nonfinite += !isfinite(V[i]);
    double ymin = INFINITY;
    for (size_t i = 0; i < nv; ++i)
      ymin = fmin(ymin, V[3 * i + 1]);
    below += ymin < floor_y - 0.005 * diag;
    for (size_t i = 0; fr > 0 && i < nv; ++i) {
      double dx = V[3 * i] - Vp[3 * i], dy = V[3 * i + 1] - Vp[3 * i + 1],
             dz = V[3 * i + 2] - Vp[3 * i + 2];
      jump_pct = fmax(jump_pct, 100 * sqrt(dx * dx + dy * dy + dz * dz) / diag);
    }
    memcpy(Vp, V, sizeof(double) * 3 * nv);
    for (size_t e = 0; e < ne; ++e) {
      size_t f = e / 3;
      int k = (int)(e % 3);
      const double *a = V + 3 * (size_t)m->F[3 * f + k],
                   *b = V + 3 * (size_t)m->F[3 * f + (k + 1) % 3];
      double l = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                      (a[2] - b[2]) * (a[2] - b[2]));
      double r = len0[e] > 0 ? l / len0[e] : 1;
      if (!(r <= smax[e])) smax[e] = r;
    }
    /* Handles follow their targets (the retargeted joints). */
    const double *T = km_puppetry_handle_targets(p), *C0 = km_puppetry_rest_centroids(p);
    for (size_t h = 0; h < nh; ++h) {
      double c3[3] = {0, 0, 0};
      for (int32_t i = off[h]; i < off[h + 1]; ++i)
        for (int a = 0; a < 3; ++a)
          c3[a] += V[3 * (size_t)hv[i] + a] / (double)(off[h + 1] - off[h]);
      double d = 0, mv = 0;
      for (int a = 0; a < 3; ++a) {
        d += (c3[a] - T[3 * h + a]) * (c3[a] - T[3 * h + a]);
        mv += (T[3 * h + a] - C0[3 * h + a]) * (T[3 * h + a] - C0[3 * h + a]);
      }
      dev_sum += sqrt(d);
      move_sum += sqrt(mv);
    }
  }
  qsort(smax, ne, sizeof *smax, cmp_double);
  double p50 = smax[ne / 2], p90 = smax[(size_t)(0.9 * (double)(ne - 1))],
         p99 = smax[(size_t)(0.99 * (double)(ne - 1))];
  printf("%s: %zu vertices, %zu frames: edge stretch median %.3f, 90%% %.3f, 99%% %.3f, max "
         "%.3f; handle deviation %.1f%% of the handle motion; largest one-frame step %.2f%% of "
         "the diagonal; %zu frames under the rest floor\n",
         label, nv, take->n_frames, p50, p90, p99, smax[ne - 1],
         100 * dev_sum / (move_sum > 0 ? move_sum : 1), jump_pct, below);
  if (stretch_out) *stretch_out = p99;
  if (jump_out) *jump_out = jump_pct;
  CHECK_MSG(nonfinite == 0, "%s: %zu non-finite coordinates", label, nonfinite);
  if (rig.floor)
    CHECK_MSG(below == 0, "%s: a vertex under the rest floor in %zu frames", label, below);
  if (isfinite(max_stretch)) CHECK_MSG(p50 < 1.5, "%s: median edge stretched %.3fx", label, p50);
  CHECK_MSG(smax[ne - 1] < max_stretch, "%s: an edge stretched %.3fx", label, smax[ne - 1]);
  CHECK_MSG(move_sum > 0 && dev_sum < 0.25 * move_sum,
            "%s: handles deviate %.1f%% of their motion from their targets", label,
            100 * dev_sum / (move_sum > 0 ? move_sum : 1));
  free(V);
  free(Vp);
  free(len0);
  free(smax);
  km_puppetry_free(&p);
  km_rig_free(&rig);
}

static void drive(const char *label, const km_mesh *m, const km_character *c, const km_take *take,
                  double *stretch_out, double *jump_out, double max_stretch) {
  drive_with(label, m, c, take, stretch_out, jump_out, max_stretch, false);
}

/* Drives m with the clean optical take cmu (cmu_131_01 at its own 120 fps): no edge over
 * max_stretch, and no vertex steps 4 % of the diagonal in a frame (no spike). */
static void drive_cmu(const char *label, const km_mesh *m, const km_character *c,
                      const km_take *cmu, double max_stretch) {
  char l[512];
  snprintf(l, sizeof l, "%s, cmu_131_01", label);
  double jump = INFINITY;
  drive(l, m, c, cmu, NULL, &jump, max_stretch);
  CHECK_MSG(jump < 4, "%s: a vertex stepped %.2f%% of the diagonal in one frame", l, jump);
}

/* Reads the shared mesh rel and turns it into kinemesh's frame by the automatic guess (g: the
 * guess, at the file's scale). False when it is absent (the test skips) or empty. */
static bool read_oriented(const char *rel, km_mesh *m, km_frame_guess *g) {
  char buf[1024];
  const char *path = km_test_shared(rel, buf, sizeof buf);
  if (!path) return false;
  CHECK_OK(km_mesh_read(path, m, KM_E));
  if (!m->n_vertices) return false;
  CHECK_OK(km_mesh_frame_guess(m, g, KM_E));
  g->frame.scale = 0;
  CHECK_OK(km_mesh_frame_apply(&g->frame, m, KM_E));
  return true;
}

/* Rig a real mesh, drive it with a real Kinect take through km_puppetry. The mesh is brought
 * into kinemesh's frame by the automatic guess, which must find how the file is stored
 * (up, forward: the dog and the horse are z up). cmu (NULL: none): a clean optical take at its
 * own 120 fps, driven too: its largest one-frame step must stay under 4 % of the diagonal (no
 * spike; bench motion B measures 1.8-3.2 % on these meshes, the take's own steps 3-4 %). */
static void test_real(const char *rel, km_axis up, km_axis forward, km_autorig_skeleton want,
                      const km_take *take, double max_stretch, const km_take *cmu) {
  km_mesh m = {0};
  km_frame_guess g;
  if (!read_oriented(rel, &m, &g)) return;
  CHECK_MSG(g.frame.up == up && g.frame.forward == forward,
            "%s: guessed up %s forward %s, want %s %s", rel, km_axis_name(g.frame.up),
            km_axis_name(g.frame.forward), km_axis_name(up), km_axis_name(forward));
  km_character c = {0};
  km_autorig_report rep;
  km_status st = km_autorig(&m, NULL, &c, &rep, KM_E);
  CHECK_MSG(st == KM_OK, "%s: %s", rel, km_test_err.message);
  if (st == KM_OK) {
    printf("%s: rigged as %s in %.3f s\n", rel,
           rep.kind == KM_AUTORIG_QUADRUPED ? "a quadruped" : "a humanoid", rep.seconds);
    CHECK_MSG(rep.kind == want, "%s: rigged as %s", rel,
              rep.kind == KM_AUTORIG_QUADRUPED ? "a quadruped" : "a humanoid");
    CHECK(skin_valid(&c.skin, m.n_vertices));
    for (int j = 0; j < 3 * KM_KINECT1_JOINTS; ++j)
      CHECK(isfinite(c.skeleton.rest[j]));
    /* The sidecar's bone handles pose the limbs as the performer's (issue 12): joints bend,
     * which concentrates strain in a few edges at the crotch and armpits (worst edge measured
     * 1.75x armadillo, 1.26x dog0, 1.33x elephant, 1.31x horse; 99th percentile 1.2x to
     * 1.5x). The animals' were 1.37x, 1.645x and 1.505x while their shoulder and hip bones
     * turned with the performer's shrugs and leans and carried the legs ("girdle_limit"). The
     * armadillo's was 2.15x while its hand and foot handles were balls round one claw: the other
     * claws, free skin, were drawn out when a kick raised a foot or a hand rose (a hand or foot
     * handle now holds the whole hand or foot; on cmu_131_01 1.93x, the armpit). The elephant's
     * was 4.2x while its stubby limbs had bands touching at the elbows and knees
     * (km_character_write_rig now gives such a limb no band), the horse's 4.3x
     * while its forelegs swung as far as the performer's arms and 3.3x while its upper-leg
     * bands, trunk skin, dragged the belly with a swinging leg (a quadruped's rig now has no
     * upper-leg bands and limits each limb bone's swing to 30 degrees; dog0 was 2.2x), and 1.95x
     * (dog0 1.65x) while its upper legs, inside the trunk, swung 30 degrees: the rig now holds
     * them to 5 ("upper_limb_limit") and its elbows and knees to 20 ("bend_limit"). The
     * elephant's was 2.3x while its stubby limbs swung as far as a person's (a body with a
     * stubby limb now has "swing_limit" 12 and "upper_limb_limit" 15). */
    drive(rel, &m, &c, take, NULL, NULL, max_stretch);
    if (m.n_vertices < 10000) {
      /* animate --solver full (offline: soft handles, full-space ARAP) keeps every edge under
       * 1.5x: the elephant's worst edge 1.33x reduced, 1.19x full (1.645x and 1.396x before
       * "girdle_limit"; bench motion --solver full on this take, before it: dog0 1.444x, the
       * horse 1.332x; not driven here, at 90-150 ms a frame) */
      char label[512];
      snprintf(label, sizeof label, "%s, --solver full", rel);
      drive_with(label, &m, &c, take, NULL, NULL, 1.5, true);
    }
    if (cmu) {
      /* A flat foot's heading was taken from its direction seen from above, which spins where
       * the foot points straight down: the elephant's stepped 11.4 % here in one frame. */
      drive_cmu(rel, &m, &c, cmu, max_stretch);
    }
  }
  km_character_free(&c);
  km_mesh_free(&m);
}

/* Reference: the procedural character driven through its own (true) rig and through the
 * automatic one. */
static void test_character_drive(const km_take *take) {
  km_character_options co = {0};
  co.target_vertices = 10000;
  km_character c = {0}, r = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  CHECK_OK(km_autorig(&c.mesh, NULL, &r, NULL, KM_E));
  double s_true = 0, s_auto = 0;
  drive("character, true rig", &c.mesh, &c, take, &s_true, NULL, 4.0);
  drive("character, automatic rig", &c.mesh, &r, take, &s_auto, NULL, 4.0);
  CHECK_MSG(s_auto < 1.05 * s_true,
            "automatic rig stretches %.3fx at the 99th percentile, the "
            "true rig %.3fx",
            s_auto, s_true);
  km_character_free(&r);
  km_character_free(&c);
}

/* The procedural character split across its left hand (x at 0.9 of its reach) as a glTF
 * exporter splits a mesh at a texture seam (the faces beyond use copies of the cut vertices,
 * appended after the file's): rigged
 * welded there, it gets the whole character's rig on the file's vertices, every copy with its
 * vertex's skin, and its rig file's handles hold every copy of their vertices. Split, it was
 * two components and refused. */
static void test_seam_split(void) {
  km_character_options co = {0};
  co.target_vertices = 4000;
  km_character c = {0}, a = {0}, b = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  const km_mesh *m = &c.mesh;
  size_t n = m->n_vertices, nf = m->n_faces;
  int32_t *copy = malloc(n * sizeof *copy);
  unsigned char *below = calloc(n, 1), *above = calloc(n, 1);
  double cut = 0; /* 0.9 of the reach along +x (kinemesh's left), times 3: a face's sum */
  for (size_t v = 0; v < n; ++v)
    cut = fmax(cut, 3 * 0.9 * m->V[3 * v]);
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *t = m->F + 3 * f;
    bool up = m->V[3 * t[0]] + m->V[3 * t[1]] + m->V[3 * t[2]] > cut;
    for (int k = 0; k < 3; ++k)
      (up ? above : below)[t[k]] = 1;
  }
  size_t extra = 0;
  for (size_t v = 0; v < n; ++v)
    copy[v] = below[v] && above[v] ? (int32_t)(n + extra++) : (int32_t)v;
  km_mesh sm = {0};
  CHECK_OK(km_mesh_alloc(n + extra, nf, &sm, KM_E));
  memcpy(sm.V, m->V, 3 * n * sizeof(double));
  for (size_t v = 0; v < n; ++v)
    if (copy[v] >= (int32_t)n) memcpy(sm.V + 3 * (size_t)copy[v], m->V + 3 * v, 3 * sizeof(double));
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *t = m->F + 3 * f;
    bool up = m->V[3 * t[0]] + m->V[3 * t[1]] + m->V[3 * t[2]] > cut;
    for (int k = 0; k < 3; ++k)
      sm.F[3 * f + (size_t)k] = up ? copy[t[k]] : t[k];
  }
  km_mesh_info info;
  CHECK_OK(km_mesh_info_compute(&sm, &info, KM_E));
  printf("seam split: %zu copies, %zu pieces\n", extra, info.components);
  CHECK(extra > 10 && info.components == 2 && info.seam_vertices == 2 * extra);
  CHECK_OK(km_autorig(m, NULL, &a, NULL, KM_E));
  CHECK_OK(km_autorig(&sm, NULL, &b, NULL, KM_E));
  if (a.skin.joints && b.skin.joints && b.mesh.n_vertices == n + extra) {
    double dj = 0;
    for (size_t i = 0; i < 3 * a.skeleton.n_joints; ++i)
      dj = fmax(dj, fabs(a.skeleton.rest[i] - b.skeleton.rest[i]));
    bool skin = true;
    for (size_t v = 0; v < n; ++v)
      for (int k = 0; k < 4; ++k)
        skin = skin && a.skin.joints[4 * v + k] == b.skin.joints[4 * v + k] &&
               a.skin.weights[4 * v + k] == b.skin.weights[4 * v + k] &&
               b.skin.joints[4 * (size_t)copy[v] + k] == b.skin.joints[4 * v + k] &&
               b.skin.weights[4 * (size_t)copy[v] + k] == b.skin.weights[4 * v + k];
    printf("seam split: joints within %.3g of the whole character's\n", dj);
    CHECK_MSG(dj < 1e-6, "joints %g from the whole character's", dj);
    CHECK_MSG(skin, "skin of the split character is not the whole one's on every copy");
    for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i)
      CHECK(a.landmarks[i].vertex == b.landmarks[i].vertex);
    /* the rig file: every vertex's copy is in the hands' and feet's handles too (the bands
     * hold a sample of at most 64 of their vertices, copies or not) */
    char *json = NULL;
    size_t size = 0;
    km_rig rig = {0};
    CHECK_OK(km_character_rig_json(&b, &json, &size, KM_E));
    if (json) CHECK_OK(km_rig_parse(json, size, "split rig", &sm, NULL, 0, &rig, KM_E));
    size_t missing = 0, held = 0;
    for (size_t h = 0; h < rig.n_handles; ++h) {
      const km_rig_handle *rh = &rig.handles[h];
      if (strncmp(rh->name, "hand_", 5) && strncmp(rh->name, "foot_", 5)) continue;
      for (size_t i = 0; i < rh->n_vertices; ++i) {
        int32_t v = rh->vertices[i], cv = v < (int32_t)n ? copy[v] : -1;
        if (cv < 0 || cv == v) continue;
        ++held;
        bool found = false;
        for (size_t j = 0; j < rh->n_vertices && !found; ++j)
          found = rh->vertices[j] == cv;
        missing += !found;
      }
    }
    printf("seam split: %zu handle vertices on the seam, %zu without their copy\n", held, missing);
    CHECK_MSG(held > 0 && missing == 0,
              "%zu of %zu hand and foot handle vertices on the seam "
              "without their copy",
              missing, held);
    km_rig_free(&rig);
    free(json);
  }
  km_character_free(&a);
  km_character_free(&b);
  km_mesh_free(&sm);
  km_character_free(&c);
  free(copy);
  free(below);
  free(above);
}

/* Two tetrahedra: two components. */
static void test_refused(void) {
  km_mesh m = {0};
  CHECK_OK(km_mesh_alloc(8, 8, &m, KM_E));
  static const double V[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1,
                               3, 0, 0, 4, 0, 0, 3, 1, 0, 3, 0, 1};
  static const int32_t F[24] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3,
                                4, 6, 5, 4, 5, 7, 4, 7, 6, 5, 6, 7};
  memcpy(m.V, V, sizeof V);
  memcpy(m.F, F, sizeof F);
  km_character c = {0};
  CHECK_STATUS(km_autorig(&m, NULL, &c, NULL, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_MSG(strstr(km_test_err.message, "2 components") != NULL &&
                strstr(km_test_err.message, "the two largest of 4 and 4 vertices") != NULL,
            "message: %s", km_test_err.message);
  CHECK(c.mesh.V == NULL && c.skin.joints == NULL);
  /* A non-manifold edge: a third triangle on edge 0-1 of the first tetrahedron. */
  km_mesh nm = {0};
  CHECK_OK(km_mesh_alloc(5, 5, &nm, KM_E));
  memcpy(nm.V, V, 12 * sizeof(double));
  nm.V[12] = 0.5, nm.V[13] = -1, nm.V[14] = 0.2;
  memcpy(nm.F, F, 12 * sizeof(int32_t));
  nm.F[12] = 0, nm.F[13] = 1, nm.F[14] = 4;
  CHECK_STATUS(km_autorig(&nm, NULL, &c, NULL, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_MSG(strstr(km_test_err.message, "non-manifold") != NULL &&
                strstr(km_test_err.message, "the first between vertices 0 and 1") != NULL,
            "message: %s", km_test_err.message);
  /* No faces. */
  nm.n_faces = 0;
  CHECK_STATUS(km_autorig(&nm, NULL, &c, NULL, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_MSG(strstr(km_test_err.message, "no faces") != NULL, "message: %s", km_test_err.message);
  nm.n_faces = 5;
  /* A lone tetrahedron has too few extremities for a humanoid, and too few vertices for
   * five separate handles. */
  m.n_vertices = 4, m.n_faces = 4;
  km_autorig_options ho = {0};
  ho.skeleton = KM_AUTORIG_KINECT1;
  CHECK_STATUS(km_autorig(&m, &ho, &c, NULL, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_MSG(strstr(km_test_err.message, "extremities") != NULL, "message: %s", km_test_err.message);
  CHECK_STATUS(km_autorig(&m, NULL, &c, NULL, KM_E), KM_ERR_DEGENERATE_MESH);
  CHECK_MSG(strstr(km_test_err.message, "five handles") != NULL, "message: %s",
            km_test_err.message);
  m.n_vertices = 8, m.n_faces = 8;

  /* Through the CLI: the two-component mesh is refused with the same message. */
  char p[512], cmd[2048], *out = NULL;
  snprintf(p, sizeof p, "%s/two.off", g_dir);
  CHECK_OK(km_mesh_write(p, &m, NULL, KM_E));
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s' -o '%s/two.rig.json'", p, g_dir);
  int rc = km_test_run(cmd, &out);
  CHECK(rc == 1);
  CHECK_MSG(out && strstr(out, "2 components"), "output: %s", out ? out : "");
  free(out);
  km_mesh_free(&nm);
  km_mesh_free(&m);
}

/* kinemesh rig on a generated character writes a sidecar animate can use. */
static void test_cli(void) {
  char cmd[2048], *out = NULL;
  snprintf(cmd, sizeof cmd, KM_CLI " gen character -n 3000 -o '%s/g.obj'", g_dir);
  CHECK(km_test_run(cmd, NULL) == 0);
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s/g.obj' -o '%s/g.auto.rig.json'", g_dir, g_dir);
  int rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0, "rig: %s", out ? out : "");
  CHECK(out && strstr(out, "HandLeft") && strstr(out, "humanoid") &&
        strstr(out, "skin weights: bone heat ("));
  /* --weights: reach writes a valid sidecar; anything else is refused, naming the choices */
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s/g.obj' --weights reach -o '%s/g.reach.rig.json'",
           g_dir, g_dir);
  free(out);
  out = NULL;
  rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "each limited by its reach along the surface"),
            "rig --weights reach: %s", out ? out : "");
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s/g.obj' --weights bbw -o '%s/g.bbw.rig.json'", g_dir,
           g_dir);
  free(out);
  out = NULL;
  rc = km_test_run(cmd, &out);
  CHECK_MSG(rc != 0 && out && strstr(out, "--weights bbw: expected heat, distance or reach"),
            "rig --weights bbw: exit %d: %s", rc, out ? out : "");
  char gen_path[512];
  snprintf(gen_path, sizeof gen_path, "%s/g.bbw.rig.json", g_dir);
  CHECK_MSG(access(gen_path, F_OK) != 0, "a refused rig wrote %s", gen_path);
  snprintf(gen_path, sizeof gen_path, "%s/g.obj", g_dir);
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(gen_path, &m, KM_E));
  km_character reach = {0};
  snprintf(gen_path, sizeof gen_path, "%s/g.reach.rig.json", g_dir);
  CHECK_OK(km_character_read_rig(gen_path, m.n_vertices, &reach, KM_E));
  /* (the reader checks that every vertex's weights sum to 1) */
  CHECK(reach.skin.weights && reach.skin.n_vertices == m.n_vertices);
  km_character_free(&reach);
  km_character back = {0};
  snprintf(gen_path, sizeof gen_path, "%s/g.auto.rig.json", g_dir);
  CHECK_OK(km_character_read_rig(gen_path, m.n_vertices, &back, KM_E));

  /* The same character stored z up, facing -y (a scan's axes): `rig` guesses the frame,
   * rigs in kinemesh's frame (the same joints as the original's, not a skeleton lying along
   * the body) and records the frame in the sidecar for animate and live. */
  km_mesh z = {0};
  CHECK_OK(km_mesh_copy(&m, &z, KM_E));
  for (size_t v = 0; z.V && v < z.n_vertices; ++v) {
    double y = m.V[3 * v + 1], zz = m.V[3 * v + 2];
    z.V[3 * v + 1] = -zz;
    z.V[3 * v + 2] = y;
  }
  snprintf(gen_path, sizeof gen_path, "%s/z.obj", g_dir);
  CHECK_OK(km_mesh_write(gen_path, &z, NULL, KM_E));
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s/z.obj' -o '%s/z.rig.json'", g_dir, g_dir);
  free(out);
  out = NULL;
  rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "up +z, forward -y (guessed") && strstr(out, "humanoid"),
            "rig of the z-up copy: %s", out ? out : "");
  km_character zc = {0};
  snprintf(gen_path, sizeof gen_path, "%s/z.rig.json", g_dir);
  CHECK_OK(km_character_read_rig(gen_path, z.n_vertices, &zc, KM_E));
  double worst = zc.skeleton.n_joints == back.skeleton.n_joints ? 0 : INFINITY;
  for (size_t k = 0; isfinite(worst) && k < 3 * back.skeleton.n_joints; ++k)
    worst = fmax(worst, fabs(zc.skeleton.rest[k] - back.skeleton.rest[k]));
  CHECK_MSG(worst < 1e-6, "z-up copy rigged %g m away from the original's joints", worst);
  snprintf(cmd, sizeof cmd,
           "grep -A3 '\"frame\"' '%s' | grep -q '\"+z\"' && grep -A3 '\"frame\"' '%s' | grep -q "
           "'\"-y\"'",
           gen_path, gen_path);
  CHECK_MSG(km_test_run(cmd, NULL) == 0, "the sidecar records the frame");
  /* animate reads the record: no guess line, and the run succeeds. */
  snprintf(cmd, sizeof cmd,
           KM_CLI
           " gen motion --kind wave --frames 4 --character '%s/g.obj' -o '%s/w.json' && " KM_CLI
           " animate --mesh '%s/z.obj' --motion '%s/w.json' -o '%s/z.pc2'",
           g_dir, g_dir, g_dir, g_dir, g_dir);
  free(out);
  out = NULL;
  rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0 && out && !strstr(out, "guessed"), "animate of the z-up copy: %s",
            out ? out : "");
  free(out);
  km_character_free(&zc);
  km_mesh_free(&z);
  km_character_free(&back);
  km_mesh_free(&m);
}

/* The faces of src whose three vertices lie above keep (fraction of the height from the
 * bottom), vertices renumbered in their order: a bust cut from a body. */
static void cut_below(const km_mesh *src, double keep, km_mesh *out) {
  double lo = INFINITY, hi = -INFINITY;
  for (size_t v = 0; v < src->n_vertices; ++v)
    lo = fmin(lo, src->V[3 * v + 1]), hi = fmax(hi, src->V[3 * v + 1]);
  double y0 = lo + keep * (hi - lo);
  int32_t *id = malloc(sizeof(int32_t) * src->n_vertices);
  size_t nv = 0, nf = 0;
  for (size_t v = 0; v < src->n_vertices; ++v)
    id[v] = -1;
  for (size_t f = 0; f < src->n_faces; ++f) {
    const int32_t *t = src->F + 3 * f;
    if (src->V[3 * (size_t)t[0] + 1] < y0 || src->V[3 * (size_t)t[1] + 1] < y0 ||
        src->V[3 * (size_t)t[2] + 1] < y0)
      continue;
    ++nf;
    for (int k = 0; k < 3; ++k)
      if (id[t[k]] < 0) id[t[k]] = 0;
  }
  for (size_t v = 0; v < src->n_vertices; ++v)
    if (id[v] == 0) id[v] = (int32_t)nv++;
  CHECK_OK(km_mesh_alloc(nv, nf, out, KM_E));
  for (size_t v = 0; out->V && v < src->n_vertices; ++v)
    if (id[v] >= 0) memcpy(out->V + 3 * (size_t)id[v], src->V + 3 * v, 3 * sizeof(double));
  nf = 0;
  for (size_t f = 0; out->F && f < src->n_faces; ++f) {
    const int32_t *t = src->F + 3 * f;
    if (id[t[0]] < 0 || id[t[1]] < 0 || id[t[2]] < 0 || src->V[3 * (size_t)t[0] + 1] < y0 ||
        src->V[3 * (size_t)t[1] + 1] < y0 || src->V[3 * (size_t)t[2] + 1] < y0)
      continue;
    for (int k = 0; k < 3; ++k)
      out->F[3 * nf + (size_t)k] = id[t[k]];
    ++nf;
  }
  free(id);
}

/* The puppetry rig of c's sidecar (km_character_rig_json), resolved on m (name: for messages). */
static void sidecar_rig(const km_character *c, const km_mesh *m, const char *name, km_rig *rig) {
  char *json = NULL;
  size_t size = 0;
  if (c->skeleton.rest) CHECK_OK(km_character_rig_json(c, &json, &size, KM_E));
  if (json) CHECK_OK(km_rig_parse(json, size, name, m, NULL, 0, rig, KM_E));
  free(json);
}

/* A bust (the top 30 % of a FAUST body, cut open at the chest: its arms hang, so they are cut
 * too) is rigged as one: the head handle above the neck, the base held still while a real take
 * turns the head. Rigged as a quadruped before (the corners of its cut stood for four legs),
 * the performer's steps crumpled its chest. A closed mesh, and a mesh with only small holes
 * at its bottom (the soles), is no bust. */
/* Drives m by rig (a bust's: handles "head" and "base") with take: the base stays within 2 % of
 * the height H (a lying body's: its largest extent) while the head moves more than 4 % of it. */
static void base_holds(const char *label, const km_mesh *m, const km_rig *rig, const km_take *take,
                       double H) {
  const km_rig_handle *head = &rig->handles[0], *base = &rig->handles[1];
  CHECK_MSG(rig->n_handles == 2 && !strcmp(head->name, "head") && !strcmp(base->name, "base"),
            "%s: %zu handles", label, rig->n_handles);
  if (rig->n_handles != 2) return;
  km_puppetry *p = NULL;
  km_puppetry_options po = {0};
  po.fps = take->fps;
  CHECK_OK(km_puppetry_create(m, rig, (const char *const *)take->joint_names, take->n_joints, &po,
                              &p, NULL, KM_E));
  double *V = malloc(sizeof(double) * 3 * m->n_vertices), base_moved = 0, head_moved = 0;
  for (size_t fr = 0; p && V && fr < take->n_frames; ++fr) {
    if (km_puppetry_push(p, take->positions + fr * take->n_joints * 3, V, KM_E) != KM_OK) break;
    for (size_t i = 0; i < base->n_vertices; ++i) {
      size_t v = (size_t)base->vertices[i];
      for (int k = 0; k < 3; ++k)
        base_moved = fmax(base_moved, fabs(V[3 * v + k] - m->V[3 * v + k]));
    }
    for (size_t i = 0; i < head->n_vertices; ++i) {
      size_t v = (size_t)head->vertices[i];
      double d[3] = {V[3 * v] - m->V[3 * v], V[3 * v + 1] - m->V[3 * v + 1],
                     V[3 * v + 2] - m->V[3 * v + 2]};
      head_moved = fmax(head_moved, sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
    }
  }
  printf("%s: base moved %.2g m at most, the head %.3f m (height %.3g m)\n", label, base_moved,
         head_moved, H);
  CHECK_MSG(base_moved < 0.02 * H, "%s: the base moved %g m", label, base_moved);
  CHECK_MSG(head_moved > 0.04 * H, "%s: the head moved only %g m", label, head_moved);
  free(V);
  km_puppetry_free(&p);
}

static void test_bust(const km_take *take) {
  char buf[1024];
  const char *path = km_test_shared("poses/tr_reg_000.off", buf, sizeof buf);
  if (!path) return;
  km_mesh body = {0}, m = {0};
  CHECK_OK(km_mesh_read(path, &body, KM_E));
  if (!body.V) return;
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&body, NULL, &c, &rep, KM_E)); /* closed: a humanoid */
  CHECK_MSG(rep.kind == KM_AUTORIG_KINECT1, "the whole body rigged as a %s",
            km_autorig_kind_name(rep.kind));
  km_character_free(&c);
  cut_below(&body, 0.7, &m);
  km_mesh_free(&body);
  if (!m.V) return;
  /* As cut, in FAUST's own coordinates (its face at z = 0, which was taken for the ground
   * plane: up +z), and turned into each of the 24 axis-aligned frames: up from the open cut */
  for (int u = KM_AXIS_POS_X; u <= KM_AXIS_NEG_Z; ++u)
    for (int w = KM_AXIS_POS_X; w <= KM_AXIS_NEG_Z; ++w) {
      if ((u - 1) / 2 == (w - 1) / 2) continue;
      km_frame f = {(km_axis)u, (km_axis)w, 0};
      km_mesh r = {0};
      CHECK_OK(km_mesh_copy(&m, &r, KM_E));
      if (!r.V) continue;
      km_test_to_frame(&f, m.V, r.V, r.n_vertices);
      km_frame_guess fg;
      CHECK_OK(km_mesh_frame_guess(&r, &fg, KM_E));
      CHECK_MSG(fg.frame.up == f.up && fg.sure_up && strstr(fg.why, "open cut"),
                "the bust stored up %s forward %s: guessed up %s (%s)", km_axis_name(f.up),
                km_axis_name(f.forward), km_axis_name(fg.frame.up), fg.why);
      km_mesh_free(&r);
    }
  /* Its axes, as a modelling tool stores a bust (centred, standing on y = 0): up from the cut
   * on the ground plane, forward's sign from the jaw ahead of the neck (FAUST faces +z), also
   * when it faces -z */
  km_mesh g = {0};
  CHECK_OK(km_mesh_copy(&m, &g, KM_E));
  if (g.V) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < g.n_vertices; ++v)
      for (int k = 0; k < 3; ++k)
        lo[k] = fmin(lo[k], g.V[3 * v + k]), hi[k] = fmax(hi[k], g.V[3 * v + k]);
    for (int turn = 0; turn < 2; ++turn) {
      for (size_t v = 0; v < g.n_vertices; ++v) {
        double *q = g.V + 3 * v;
        if (turn) { /* half a turn about y */
          q[0] = -q[0], q[2] = -q[2];
          continue;
        }
        q[0] -= 0.5 * (lo[0] + hi[0]), q[1] -= lo[1], q[2] -= 0.5 * (lo[2] + hi[2]);
      }
      km_frame_guess fg;
      CHECK_OK(km_mesh_frame_guess(&g, &fg, KM_E));
      km_axis want = turn ? KM_AXIS_NEG_Z : KM_AXIS_POS_Z;
      CHECK_MSG(fg.frame.up == KM_AXIS_POS_Y && fg.frame.forward == want,
                "the bust (turn %d): up %s forward %s (%s)", turn, km_axis_name(fg.frame.up),
                km_axis_name(fg.frame.forward), fg.why);
    }
  }
  km_mesh_free(&g);
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  CHECK_MSG(rep.kind == KM_AUTORIG_BUST, "the bust rigged as a %s", km_autorig_kind_name(rep.kind));
  if (c.skeleton.rest && rep.kind == KM_AUTORIG_BUST) {
    CHECK(skin_valid(&c.skin, m.n_vertices));
    double ymin = INFINITY, ymax = -INFINITY;
    for (size_t v = 0; v < m.n_vertices; ++v)
      ymin = fmin(ymin, m.V[3 * v + 1]), ymax = fmax(ymax, m.V[3 * v + 1]);
    /* Kinect v1 order: ShoulderCenter 2, Head 3 */
    const double *sc = c.skeleton.rest + 3 * 2, *hd = c.skeleton.rest + 3 * 3;
    /* FAUST: the neck about 0.55 of the way up this cut, the head's centre about 0.75 */
    CHECK_MSG(sc[1] > ymin + 0.4 * (ymax - ymin) && sc[1] < ymin + 0.7 * (ymax - ymin),
              "neck at %.3f of the bust's height", (sc[1] - ymin) / (ymax - ymin));
    CHECK_MSG(hd[1] > sc[1] && hd[1] < ymax, "head joint at y %.3f", hd[1]);
    km_rig rig = {0};
    sidecar_rig(&c, &m, "bust", &rig);
    CHECK_MSG(rig.n_handles == 2 && rig.n_maps == 1, "%zu handles, %zu map entries", rig.n_handles,
              rig.n_maps);
    if (rig.n_handles == 2 && take) {
      /* the reduced model holds a handle to its rigid motion in its subspace: 4.3 mm on this
       * 0.53 m bust, where its quadruped rig moved the cut's corners with the feet */
      base_holds("bust", &m, &rig, take, ymax - ymin);
      /* worst edge measured 1.27x on this take (bench motion on the same cut) */
      drive("bust", &m, &c, take, NULL, NULL, 1.5);
    }
    km_rig_free(&rig);
  }
  km_character_free(&c);
  km_mesh_free(&m);
  /* A head cut at its neck (the top 13 %): a bust whose neck is its cut, its head handle most
   * of it (the neck was taken at the crown's narrowing, and the head handle was 16 vertices) */
  CHECK_OK(km_mesh_read(path, &body, KM_E));
  if (body.V) cut_below(&body, 0.87, &m);
  km_mesh_free(&body);
  if (m.V) {
    CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
    CHECK_MSG(rep.kind == KM_AUTORIG_BUST, "the head rigged as a %s",
              km_autorig_kind_name(rep.kind));
    km_rig rig = {0};
    sidecar_rig(&c, &m, "head", &rig);
    CHECK_MSG(rig.n_handles == 2 && rig.handles[0].n_vertices > m.n_vertices / 2,
              "the head's handle: %zu of %zu vertices",
              rig.n_handles ? rig.handles[0].n_vertices : 0, m.n_vertices);
    km_rig_free(&rig);
    km_character_free(&c);
    km_mesh_free(&m);
  }
}

/* A body lying or curled up, rigged with --skeleton resting and its head's tip given: its head
 * handle is the whole head (cut across the neck), the body behind the shoulders is held still
 * while a real take turns the head, and no edge stretches past max. Returns the head handle's
 * vertex flags (n_vertices, caller frees) or NULL. */
static unsigned char *resting(const char *label, const km_mesh *m, int32_t tip, const km_take *take,
                              double max, double *neck_out) {
  km_autorig_options o = {0};
  o.skeleton = KM_AUTORIG_RESTING;
  o.head = &tip;
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(m, &o, &c, &rep, KM_E));
  CHECK_MSG(rep.kind == KM_AUTORIG_RESTING && rep.n_extremities == 1 && rep.extremity[0] == tip &&
                !strcmp(rep.role[0], "Head"),
            "%s: rigged as a %s, head at vertex %d", label, km_autorig_kind_name(rep.kind),
            rep.n_extremities ? (int)rep.extremity[0] : -1);
  unsigned char *in_head = NULL;
  km_rig rig = {0};
  if (c.skeleton.rest) {
    CHECK(skin_valid(&c.skin, m->n_vertices));
    if (neck_out) memcpy(neck_out, c.skeleton.rest + 3 * 2, 3 * sizeof(double));
    sidecar_rig(&c, m, label, &rig);
    CHECK_MSG(rig.n_handles == 2 && rig.n_maps == 1 && rig.floor,
              "%s: %zu handles, %zu map entries", label, rig.n_handles, rig.n_maps);
  }
  if (rig.n_handles == 2) {
    const km_rig_handle *h = &rig.handles[0];
    in_head = calloc(m->n_vertices, 1);
    for (size_t i = 0; in_head && i < h->n_vertices; ++i)
      in_head[h->vertices[i]] = 1;
    CHECK_MSG(in_head && in_head[tip], "%s: the head handle does not hold its tip", label);
    /* measured against the body's largest extent: lying, its height is a fraction of it */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->n_vertices; ++v)
      for (int k = 0; k < 3; ++k)
        lo[k] = fmin(lo[k], m->V[3 * v + k]), hi[k] = fmax(hi[k], m->V[3 * v + k]);
    if (take) {
      base_holds(label, m, &rig, take, fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2])));
      drive(label, m, &c, take, NULL, NULL, max);
    }
  }
  km_rig_free(&rig);
  km_character_free(&c);
  return in_head;
}

/* Lying and curled bodies (issue 11): rigged automatically as standing, their head, hand and
 * foot handles were points dragging spikes out of the flank (rig warns, test_puppet_cli);
 * --skeleton resting with the head's tip given rigs them as a bust along the neck. A FAUST body
 * laid on its back: its head handle is its head (every vertex of it above 0.8 of the standing
 * height, 300 or more) and its neck between 0.78 and 0.92 of the standing height. The curled
 * cat-07 and cat-04 lying on its side, an ear tip each: their head handles are the same part of
 * the shared cat connectivity (more than half in common). */
static void test_resting(const km_take *take) {
  char buf[1024];
  const char *path = km_test_shared("poses/tr_reg_000.off", buf, sizeof buf);
  km_mesh m = {0};
  if (path) CHECK_OK(km_mesh_read(path, &m, KM_E));
  if (m.V) {
    double lo = INFINITY, hi = -INFINITY;
    int32_t crown = 0;
    for (size_t v = 0; v < m.n_vertices; ++v) {
      double y = m.V[3 * v + 1];
      if (y > hi) hi = y, crown = (int32_t)v;
      lo = fmin(lo, y);
    }
    double *y0 = malloc(m.n_vertices * sizeof *y0);
    for (size_t v = 0; y0 && v < m.n_vertices; ++v) { /* on its back: (x, y, z) -> (x, z, -y) */
      double *q = m.V + 3 * v, y = q[1];
      y0[v] = y;
      q[1] = q[2], q[2] = -y;
    }
    double neck[3];
    unsigned char *head = y0 ? resting("lying body", &m, crown, take, 1.5, neck) : NULL;
    if (head) {
      size_t n = 0, low = 0;
      for (size_t v = 0; v < m.n_vertices; ++v)
        if (head[v]) ++n, low += y0[v] < lo + 0.8 * (hi - lo);
      double f = (-neck[2] - lo) / (hi - lo);
      printf("lying body: head handle %zu vertices (%zu below 0.8 of the height), neck at %.3f\n",
             n, low, f);
      CHECK_MSG(n >= 300 && low == 0, "lying body: head handle %zu vertices, %zu below 0.8", n,
                low);
      CHECK_MSG(f > 0.78 && f < 0.92, "lying body: neck at %.3f of the standing height", f);
    }
    free(head);
    free(y0);
  }
  km_mesh_free(&m);
  unsigned char *heads[2] = {NULL, NULL};
  static const char *const cats[2] = {"poses/cat-poses/cat-07.obj", "poses/cat-poses/cat-04.obj"};
  static const int32_t tips[2] = {3666, 3799};
  static const double max[2] = {
      1.8, 1.5}; /* measured 1.59x and 1.30x (1.65x, 1.25x before local_turn) */
  size_t nv = 0;
  for (int k = 0; k < 2; ++k) {
    km_frame_guess g;
    km_mesh c = {0};
    if (!read_oriented(cats[k], &c, &g)) continue;
    nv = c.n_vertices;
    heads[k] = resting(cats[k], &c, tips[k], take, max[k], NULL);
    km_mesh_free(&c);
  }
  if (heads[0] && heads[1]) {
    size_t both = 0, either = 0;
    for (size_t v = 0; v < nv; ++v)
      both += heads[0][v] && heads[1][v], either += heads[0][v] || heads[1][v];
    printf("cats' head handles: %zu in common of %zu\n", both, either);
    CHECK_MSG(2 * both > either, "the cats' head handles share %zu of %zu vertices", both, either);
  }
  free(heads[0]);
  free(heads[1]);
}

/* A body sitting on a broad base (the Stanford bunny: closed, its bottom 5 % one part) is
 * rigged as a bust: its head and ears turn with the performer's neck, its base stays. Rigged by
 * its extremities it took an ear and its snout for hands and its tail for a foot, and a
 * performer's step tore its haunch (longest edge 2.4-3.3x on the Kinect takes). Standing
 * bodies are not seated (test_roles: the dinosaur, the knight, the animals). */
static void test_seated(const km_take *take, const km_take *cmu) {
  km_mesh m = {0};
  km_frame_guess g;
  if (!read_oriented("meshes/bunny.off", &m, &g)) return;
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  CHECK_MSG(rep.kind == KM_AUTORIG_BUST, "the bunny rigged as a %s",
            km_autorig_kind_name(rep.kind));
  if (c.skeleton.rest && rep.kind == KM_AUTORIG_BUST) {
    CHECK(skin_valid(&c.skin, m.n_vertices));
    double ymin = INFINITY, ymax = -INFINITY;
    for (size_t v = 0; v < m.n_vertices; ++v)
      ymin = fmin(ymin, m.V[3 * v + 1]), ymax = fmax(ymax, m.V[3 * v + 1]);
    km_rig rig = {0};
    sidecar_rig(&c, &m, "bunny", &rig);
    /* the head handle: the head and ears (above the neck), not the body */
    CHECK_MSG(rig.n_handles == 2 && rig.handles[0].n_vertices > m.n_vertices / 10 &&
                  rig.handles[0].n_vertices < m.n_vertices / 2,
              "the bunny's head handle: %zu of %zu vertices",
              rig.n_handles ? rig.handles[0].n_vertices : 0, m.n_vertices);
    if (rig.n_handles == 2) base_holds("bunny", &m, &rig, take, ymax - ymin);
    km_rig_free(&rig);
    /* worst edge 1.29x on this take, 1.55x on cmu_131_01 (bench motion B) */
    drive("bunny", &m, &c, take, NULL, NULL, 1.5);
    if (cmu) drive_cmu("bunny", &m, &c, cmu, 1.6);
  }
  km_character_free(&c);
  km_mesh_free(&m);
}

/* An upper body with its arms reaching out (the procedural character, T-posed, cut at the
 * waist: a VR avatar) is open at its bottom but no bust: it is rigged as an upper body, its
 * arms as a humanoid's (rings from the hand tips), its legs folded into the base. Its cut
 * spans 0.2 of its arm span (the bust test's 0.3 of the width missed it, and it was rigged as
 * a prop: straight arms, the cut's corners as feet). Its sidecar: head, hands, arm bands and
 * rings, chest, and a base that follows the root; no feet nor leg bands. take: drives it (worst
 * edge 1.88x on precog_Seq1_1 at 8000 vertices, as the whole character's armpits) */
static void test_upper_body(const km_take *take) {
  km_character_options co = {0};
  co.target_vertices = 4000;
  km_character full = {0}, c = {0};
  CHECK_OK(km_character_generate(&co, &full, KM_E));
  km_mesh m = {0};
  if (full.mesh.V) cut_below(&full.mesh, 0.55, &m);
  if (!m.V) {
    km_character_free(&full);
    return;
  }
  km_autorig_report rep;
  km_status st = km_autorig(&m, NULL, &c, &rep, KM_E);
  CHECK_MSG(st == KM_OK, "the upper body: %s", km_test_err.message);
  if (st == KM_OK) {
    CHECK_MSG(rep.kind == KM_AUTORIG_UPPER, "the T-posed upper body rigged as a %s",
              km_autorig_kind_name(rep.kind));
    /* the arm joints near the whole character's (its true skeleton), within 0.1 of the cut's
     * height; the feet folded within the bottom 0.1 */
    double ymin = INFINITY, ymax = -INFINITY;
    for (size_t v = 0; v < m.n_vertices; ++v)
      ymin = fmin(ymin, m.V[3 * v + 1]), ymax = fmax(ymax, m.V[3 * v + 1]);
    double H = ymax - ymin;
    static const char *const arm[] = {"ElbowLeft", "WristLeft", "ElbowRight", "WristRight", "Head"};
    for (size_t a = 0; a < sizeof arm / sizeof arm[0] && c.skeleton.rest; ++a) {
      int jt = joint_index(&full.skeleton, arm[a]), jr = joint_index(&c.skeleton, arm[a]);
      double d = 0;
      for (int k = 0; k < 3; ++k)
        d += (full.skeleton.rest[3 * jt + k] - c.skeleton.rest[3 * jr + k]) *
             (full.skeleton.rest[3 * jt + k] - c.skeleton.rest[3 * jr + k]);
      CHECK_MSG(sqrt(d) < 0.1 * H, "upper body: %s %.3f m from the truth (height %.3f)", arm[a],
                sqrt(d), H);
    }
    if (c.skeleton.rest)
      CHECK(c.skeleton.rest[3 * joint_index(&c.skeleton, "FootLeft") + 1] < ymin + 0.1 * H);
    km_rig rig = {0};
    sidecar_rig(&c, &m, "upper", &rig);
    bool base = false, feet = false, hands = false;
    for (size_t h = 0; h < rig.n_handles; ++h) {
      base = base || !strcmp(rig.handles[h].name, "base");
      feet = feet || strstr(rig.handles[h].name, "foot") || strstr(rig.handles[h].name, "thigh");
      hands = hands || !strcmp(rig.handles[h].name, "hand_left");
    }
    CHECK_MSG(base && hands && !feet, "upper body's handles: base %d, hands %d, feet %d", base,
              hands, feet);
    km_rig_free(&rig);
    if (take) drive("upper body", &m, &c, take, NULL, NULL, 2.2);
  }
  km_character_free(&full);
  km_character_free(&c);
  km_mesh_free(&m);
}

/* A prop (an ellipsoid: no limbs) gets five handles by position, and puppetry runs on it. */
static void test_prop(const km_take *take) {
  km_mesh m = {0};
  CHECK_OK(km_icosphere(4, 0.5, &m, KM_E));
  if (!m.V) return;
  for (size_t v = 0; v < m.n_vertices; ++v)
    m.V[3 * v + 1] *= 1.6, m.V[3 * v + 2] *= 0.7;
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  CHECK(rep.kind == KM_AUTORIG_PROP && rep.fallback[0] != '\0');
  if (c.skeleton.rest) {
    CHECK(skin_valid(&c.skin, m.n_vertices));
    /* head handle highest, hand_left on +x, hand_right on -x */
    const double *top = m.V + 3 * (size_t)c.landmarks[0].vertex;
    CHECK(c.landmarks[6].vertex >= 0 && m.V[3 * (size_t)c.landmarks[6].vertex] > 0.2);
    CHECK(c.landmarks[7].vertex >= 0 && m.V[3 * (size_t)c.landmarks[7].vertex] < -0.2);
    CHECK(top[1] > 0);
    if (take) drive("ellipsoid prop", &m, &c, take, NULL, NULL, INFINITY);
  }
  km_character_free(&c);
  km_mesh_free(&m);
}

/* km_autorig_options.joints (gen character's heat weights): a known skeleton replaces the
 * embedded one exactly, the skin computed around it is valid and differs from the skin around
 * the embedded joints (the generated character's hips sit 5-6 cm above where rig puts them); a
 * joint that is not finite is refused, naming it. */
static void test_given_joints(void) {
  km_character_options co = {0};
  co.target_vertices = 5000;
  km_character c = {0}, a = {0}, b = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  km_autorig_options o = {0};
  o.skeleton = KM_AUTORIG_KINECT1;
  CHECK_OK(km_autorig(&c.mesh, &o, &a, NULL, KM_E));
  o.joints = c.skeleton.rest;
  CHECK_OK(km_autorig(&c.mesh, &o, &b, NULL, KM_E));
  if (a.skeleton.rest && b.skeleton.rest) {
    CHECK(memcmp(b.skeleton.rest, c.skeleton.rest, sizeof(double) * 3 * KM_KINECT1_JOINTS) == 0);
    CHECK(skin_valid(&b.skin, c.mesh.n_vertices));
    size_t differ = 0;
    for (size_t i = 0; i < 4 * c.mesh.n_vertices; ++i)
      differ += fabs(a.skin.weights[i] - b.skin.weights[i]) > 1e-3;
    CHECK_MSG(differ > c.mesh.n_vertices / 100, "%zu weights differ", differ);
  }
  km_character_free(&a);
  km_character_free(&b);
  double J[3 * KM_KINECT1_JOINTS];
  memcpy(J, c.skeleton.rest, sizeof J);
  J[3 * 5 + 1] = NAN; /* ElbowLeft */
  o.joints = J;
  CHECK_STATUS(km_autorig(&c.mesh, &o, &b, NULL, KM_E), KM_ERR_INVALID);
  CHECK_MSG(strstr(km_test_err.message, "ElbowLeft") != NULL, "%s", km_test_err.message);
  km_character_free(&c);
}

/* A vertex no face uses, far away, changes nothing: same skeleton as without it. */
static void test_isolated_vertex(void) {
  km_character_options co = {0};
  co.target_vertices = 5000;
  km_character c = {0}, a = {0}, b = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  km_mesh m = {0};
  CHECK_OK(km_mesh_alloc(c.mesh.n_vertices + 1, c.mesh.n_faces, &m, KM_E));
  if (!m.V) return;
  memcpy(m.V, c.mesh.V, sizeof(double) * 3 * c.mesh.n_vertices);
  memcpy(m.F, c.mesh.F, sizeof(int32_t) * 3 * c.mesh.n_faces);
  double far[3] = {10, 10, 10};
  memcpy(m.V + 3 * c.mesh.n_vertices, far, sizeof far);
  CHECK_OK(km_autorig(&c.mesh, NULL, &a, NULL, KM_E));
  CHECK_OK(km_autorig(&m, NULL, &b, NULL, KM_E));
  if (a.skeleton.rest && b.skeleton.rest) {
    double d = 0;
    for (int i = 0; i < 3 * KM_KINECT1_JOINTS; ++i)
      d = fmax(d, fabs(a.skeleton.rest[i] - b.skeleton.rest[i]));
    CHECK_MSG(d < 1e-9, "isolated vertex moved a joint by %g", d);
    CHECK(skin_valid(&b.skin, m.n_vertices));
    /* the sidecar's handles are the same: the stray point 10 m up took the head handle alone
     * (the highest vertex) before */
    km_rig ra = {0}, rb = {0};
    CHECK_OK(km_character_write_rig("autorig_stray_a.rig.json", &a, KM_E));
    CHECK_OK(km_character_write_rig("autorig_stray_b.rig.json", &b, KM_E));
    CHECK_OK(km_rig_read("autorig_stray_a.rig.json", &c.mesh, NULL, 0, &ra, KM_E));
    CHECK_OK(km_rig_read("autorig_stray_b.rig.json", &m, NULL, 0, &rb, KM_E));
    bool same = ra.n_handles == rb.n_handles && ra.n_handles > 0;
    for (size_t h = 0; same && h < ra.n_handles; ++h) {
      same = ra.handles[h].n_vertices == rb.handles[h].n_vertices &&
             !strcmp(ra.handles[h].name, rb.handles[h].name);
      for (size_t i = 0; same && i < ra.handles[h].n_vertices; ++i)
        same = ra.handles[h].vertices[i] == rb.handles[h].vertices[i];
    }
    CHECK_MSG(same, "the stray vertex changed the handles (head: %zu vertices, first %d)",
              rb.n_handles ? rb.handles[0].n_vertices : 0,
              rb.n_handles && rb.handles[0].n_vertices ? (int)rb.handles[0].vertices[0] : -1);
    km_rig_free(&ra);
    km_rig_free(&rb);
    remove("autorig_stray_a.rig.json");
    remove("autorig_stray_b.rig.json");
  }
  km_character_free(&a);
  km_character_free(&b);
  km_mesh_free(&m);
  km_character_free(&c);
}

/* km_nearest_vertices against a brute-force sort, and kinemesh pick. */
static void test_pick(void) {
  km_character_options co = {0};
  co.target_vertices = 3000;
  km_character c = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  const km_mesh *m = &c.mesh;
  double p[3] = {0.31, 1.2, 0.05};
  int32_t ids[8];
  double d[8];
  size_t n = km_nearest_vertices(m->V, m->n_vertices, p, 8, ids, d);
  CHECK(n == 8);
  /* brute force: how many vertices are strictly nearer than the i-th */
  for (size_t i = 0; i < n; ++i) {
    size_t nearer = 0;
    for (size_t v = 0; v < m->n_vertices; ++v) {
      const double *q = m->V + 3 * v;
      double dv = sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                       (q[2] - p[2]) * (q[2] - p[2]));
      if (dv < d[i]) ++nearer;
    }
    CHECK_MSG(nearer <= i, "pick %zu: %zu vertices nearer", i, nearer);
    if (i) CHECK(d[i] >= d[i - 1]);
  }
  char path[512], cmd[1024], *out = NULL, want[32];
  snprintf(path, sizeof path, "%s/pick.off", g_dir);
  CHECK_OK(km_mesh_write(path, m, NULL, KM_E));
  snprintf(cmd, sizeof cmd, KM_CLI " pick '%s' --near 0.31,1.2,0.05 --k 2", path);
  CHECK(km_test_run(cmd, &out) == 0);
  snprintf(want, sizeof want, "%d ", (int)ids[0]);
  CHECK_MSG(out && !strncmp(out, want, strlen(want)), "pick printed: %s, want %s", out ? out : "",
            want);
  free(out);
  snprintf(cmd, sizeof cmd, KM_CLI " pick '%s' --near 0.31,1.2", path);
  CHECK(km_test_run(cmd, &out) != 0);
  CHECK(out && strstr(out, "x,y,z"));
  free(out);
  CHECK(km_nearest_vertices(m->V, 2, p, 8, ids, NULL) == 2);
  km_character_free(&c);
}

/* The mesh skinned by its own skeleton with each chain (4 joint names from the root) turned by
 * angle[a] about the x axis through its root; the worst edge |l/l0 - 1|. */
static double posed_chains(const km_mesh *m, const km_character *c, const char *const (*chain)[4],
                           const double *angle, int n_chains) {
  const km_skeleton *sk = &c->skeleton;
  size_t nj = sk->n_joints;
  double *P = malloc(3 * nj * sizeof *P), *T = malloc(16 * nj * sizeof *T);
  double *V = malloc(3 * m->n_vertices * sizeof *V);
  double worst = INFINITY;
  if (!P || !T || !V) goto out;
  memcpy(P, sk->rest, 3 * nj * sizeof *P);
  for (int a = 0; a < n_chains; ++a) {
    double cs = cos(angle[a]), sn = sin(angle[a]);
    const double *o = sk->rest + 3 * km_kinect1_joint_index(chain[a][0]);
    for (int k = 1; k < 4; ++k) {
      int j = km_kinect1_joint_index(chain[a][k]);
      const double *q = sk->rest + 3 * j;
      double y = q[1] - o[1], z = q[2] - o[2];
      P[3 * j + 1] = o[1] + cs * y - sn * z;
      P[3 * j + 2] = o[2] + sn * y + cs * z;
    }
  }
  CHECK_OK(km_skeleton_pose_from_positions(sk, P, T, KM_E));
  CHECK_OK(km_lbs(m->V, m->n_vertices, &c->skin, T, nj, V, KM_E));
  worst = km_test_edge_stretch(m, V);
out:
  free(P), free(T), free(V);
  return worst;
}

/* Rigs the shared mesh rel twice, with skin[0] and skin[1], and skins each by its own
 * skeleton posed as posed_chains; worst[w]: the worst edge, rep[w]: what km_autorig chose.
 * False when the mesh is absent (the test skips). */
static bool rig_twice_posed(const char *rel, const km_autorig_skin skin[2],
                            const char *const (*chain)[4], const double *angle, int n_chains,
                            double worst[2], km_autorig_report rep[2]) {
  char buf[1024];
  const char *path = km_test_shared(rel, buf, sizeof buf);
  if (!path) return false;
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  if (!m.n_vertices) return false;
  for (int w = 0; w < 2; ++w) {
    km_autorig_options o = {0};
    o.skin = skin[w];
    km_character c = {0};
    CHECK_OK(km_autorig(&m, &o, &c, &rep[w], KM_E));
    worst[w] = NAN;
    if (c.skin.weights) {
      CHECK(skin_valid(&c.skin, m.n_vertices));
      worst[w] = posed_chains(&m, &c, chain, angle, n_chains);
    }
    km_character_free(&c);
  }
  km_mesh_free(&m);
  return true;
}

/* The heat constant (bone heat's H = c / d^2) is chosen per body by the skin's stretch in probe
 * poses: the armadillo, bulky, takes the smoother c = 0.5. Its own skeleton with both arms
 * swung 90 degrees forward and up, skinned by the default weights: the worst edge |l/l0 - 1|
 * was 2.82 with c = 1 (the chest between the arms, dragged with them); 1.66 now (bound 2.2).
 * The character, slim, keeps c = 1: there 0.5 let the thighs' weights into the waist (its rig
 * is the same byte for byte as before the choice). */
static void test_heat_constant(void) {
  static const char *const arms[2][4] = {
      {"ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft"},
      {"ShoulderRight", "ElbowRight", "WristRight", "HandRight"}};
  const double up[2] = {-M_PI / 2, -M_PI / 2};
  char buf[1024];
  const char *path = km_test_shared("meshes/armadillo.obj", buf, sizeof buf);
  if (!path) {
    printf("SKIP heat constant: ../shared/data absent\n");
    return;
  }
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  if (c.skin.weights) {
    double worst = posed_chains(&m, &c, arms, up, 2);
    printf("armadillo, arms swung 90 deg forward, skinned by the default weights: worst edge "
           "|l/l0 - 1| %.3f\n",
           worst);
    CHECK_MSG(worst < 2.2, "armadillo arms forward: an edge stretched %.3f", worst);
    /* the report says which constant and why */
    CHECK_MSG(rep.heat_c == 0.5 && rep.heat_probe[1] > 0 && rep.heat_probe[1] < rep.heat_probe[0],
              "armadillo: heat c %g, probe %g (c 1) %g (c 0.5)", rep.heat_c, rep.heat_probe[0],
              rep.heat_probe[1]);
  }
  km_character_free(&c);
  km_mesh_free(&m);
}

/* A quadruped's default weights (KM_AUTORIG_SKIN_AUTO: bone heat) follow the surface: the
 * walking cat (cat-03) has a front paw beside a hind paw, and by distance the one followed the
 * other's leg. Its own skeleton with the legs swung 30 degrees (the front ones forward, the
 * hind ones back), skinned: the worst edge |l/l0 - 1| must be under 1.0 and a quarter or less
 * of the distance weights' (measured: heat 0.57; reach, the default before heat, 1.13;
 * distance 23.7). */
static void test_quadruped_skin(void) {
  static const char *const legs[4][4] = {{"ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft"},
                                         {"ShoulderRight", "ElbowRight", "WristRight", "HandRight"},
                                         {"HipLeft", "KneeLeft", "AnkleLeft", "FootLeft"},
                                         {"HipRight", "KneeRight", "AnkleRight", "FootRight"}};
  const double swing[4] = {-M_PI / 6, -M_PI / 6, M_PI / 6, M_PI / 6};
  const km_autorig_skin skin[2] = {KM_AUTORIG_SKIN_AUTO, KM_AUTORIG_SKIN_DISTANCE};
  double worst[2];
  km_autorig_report rep[2];
  if (!rig_twice_posed("poses/cat-poses/cat-03.obj", skin, legs, swing, 4, worst, rep)) return;
  CHECK_MSG(rep[0].kind == KM_AUTORIG_QUADRUPED, "cat-03 rigged as kind %d", (int)rep[0].kind);
  CHECK_MSG(rep[0].skin == KM_AUTORIG_SKIN_HEAT, "cat-03: default weights %d", rep[0].skin);
  /* probed in a quadruped's poses (24), it keeps Baran & Popovic's constant: 0.5 does not win
   * by the margin (measured 1.33x at c 1, 1.35x at c 0.5; bench motion --skin: 0.5 raised its
   * worst edge 1.57-1.65x -> 1.68-1.78x) */
  CHECK_MSG(rep[0].heat_c == 1 && rep[0].heat_probe[0] > 0 && rep[0].heat_probe_poses == 24 &&
                !(rep[0].heat_probe[1] < 0.96 * rep[0].heat_probe[0]),
            "cat-03: heat c %g, probe %g (c 1) %g (c 0.5) over %d poses", rep[0].heat_c,
            rep[0].heat_probe[0], rep[0].heat_probe[1], rep[0].heat_probe_poses);
  printf("cat-03, legs swung 30 deg, skinned: worst edge |l/l0 - 1| %.3f by the default (heat), "
         "%.3f by distance\n",
         worst[0], worst[1]);
  CHECK_MSG(worst[0] < 1.0, "cat-03 default weights: an edge stretched %.3f", worst[0]);
  CHECK_MSG(worst[1] > 4 * worst[0], "cat-03 distance weights: the worst edge only %.3f", worst[1]);
}

/* A quadruped's heat constant is chosen in its own probe poses (forearms and shins 20 degrees,
 * paws, spine and neck 30): dog0 takes the smoother c = 0.5 (probe 1.53x at c 1, 1.41x at 0.5),
 * which bench motion --skin confirms (its worst edge over the five takes 1.49-2.20x ->
 * 1.45-1.82x); the humanoid probe had scored it 1.80 / 1.81 and kept 1. */
static void test_quadruped_heat_constant(void) {
  km_mesh m = {0};
  km_frame_guess g;
  if (!read_oriented("meshes/dog0.off", &m, &g)) {
    printf("SKIP quadruped heat constant: ../shared/data absent\n");
    return;
  }
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  printf("dog0: rigged as %s, heat c %g (probe %.3f at c 1, %.3f at c 0.5, %d poses)\n",
         km_autorig_kind_name(rep.kind), rep.heat_c, rep.heat_probe[0], rep.heat_probe[1],
         rep.heat_probe_poses);
  CHECK_MSG(rep.kind == KM_AUTORIG_QUADRUPED, "dog0 rigged as kind %d", (int)rep.kind);
  CHECK_MSG(rep.heat_c == 0.5 && rep.heat_probe_poses == 24 &&
                rep.heat_probe[1] < 0.96 * rep.heat_probe[0],
            "dog0: heat c %g, probe %g (c 1) %g (c 0.5)", rep.heat_c, rep.heat_probe[0],
            rep.heat_probe[1]);
  km_character_free(&c);
  km_mesh_free(&m);
}

/* pose drives a rig of the Kinect v1 joints from a take of another skeleton by body point: a
 * CMU BVH (LeftForeArm, Head, ...) on the FAUST body rigged by `kinemesh rig`. pose used to
 * match the take's joints by exact name, so only the BVH's Head met the rig's, was put where
 * the BVH has it (CMU units) and pulled the head into a spike 1.5 m long while the rest of the
 * body stayed at rest. Mapped, but with every joint put where the take has it, the
 * performer's other proportions pulled the parts apart (worst edge |l/l0 - 1| 5.6, a hand);
 * turning the rig's bones, which keep their lengths, 1.08 at worst over 92 frames at 10 fps
 * (the crotch in a kick; bound 1.5). A take with none of the joints is refused. */
static void test_pose_bvh(void) {
  char body[512], bvh[512], cmd[4096], path[600], *out = NULL;
  if (!km_test_shared("poses/tr_reg_000.off", body, sizeof body) ||
      !km_test_shared("bvh/cmu_131_03.bvh", bvh, sizeof bvh)) {
    printf("SKIP pose from a BVH: ../shared/data absent\n");
    return;
  }
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s' -o '%s/faust.rig.json'", body, g_dir);
  CHECK(km_test_run(cmd, NULL) == 0);
  snprintf(cmd, sizeof cmd,
           KM_CLI " pose --mesh '%s' --rig '%s/faust.rig.json' --motion '%s' --fps 10 -o "
                  "'%s/faust_bvh.pc2'",
           body, g_dir, bvh, g_dir);
  int rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0 && out && !strstr(out, "warning"), "pose from a BVH: exit %d: %s", rc,
            out ? out : "");
  free(out);
  km_mesh m = {0};
  double *frames = NULL;
  km_anim_info info;
  snprintf(path, sizeof path, "%s/faust_bvh.pc2", g_dir);
  CHECK_OK(km_mesh_read(body, &m, KM_E));
  if (km_pc2_read(path, &frames, &info, KM_E) == KM_OK) {
    CHECK(info.vertices == m.n_vertices && info.frames > 80);
    double worst = 0;
    for (size_t f = 0; f < info.frames; ++f)
      worst = fmax(worst, km_test_edge_stretch(&m, frames + 3 * m.n_vertices * f));
    printf("pose, FAUST body from cmu_131_03.bvh at 10 fps: worst edge |l/l0 - 1| %.3f over %zu "
           "frames\n",
           worst, info.frames);
    CHECK_MSG(worst < 1.5, "pose from a BVH: an edge stretched %.3f", worst);
    /* --exact-positions: every joint where the take has it, the parts pulled apart */
    snprintf(cmd, sizeof cmd,
             KM_CLI " pose --mesh '%s' --rig '%s/faust.rig.json' --motion '%s' --fps 10 "
                    "--exact-positions -o '%s/faust_exact.pc2'",
             body, g_dir, bvh, g_dir);
    CHECK(km_test_run(cmd, NULL) == 0);
    double *ex = NULL, worst_exact = 0;
    snprintf(path, sizeof path, "%s/faust_exact.pc2", g_dir);
    if (km_pc2_read(path, &ex, &info, KM_E) == KM_OK)
      for (size_t f = 0; f < info.frames; ++f)
        worst_exact = fmax(worst_exact, km_test_edge_stretch(&m, ex + 3 * m.n_vertices * f));
    free(ex);
    printf("pose --exact-positions: worst edge %.3f\n", worst_exact);
    CHECK_MSG(worst_exact > 2 * worst, "--exact-positions: the worst edge only %.3f", worst_exact);
  } else
    CHECK(0);
  free(frames);
  km_mesh_free(&m);
  /* no joint in common: an error naming the rig's joints, no output */
  snprintf(path, sizeof path, "%s/foo_take.json", g_dir);
  FILE *tf = fopen(path, "w");
  CHECK(tf != NULL);
  if (tf) {
    fputs("{\"format\": \"kinemesh-take\", \"version\": 1, \"fps\": 30, \"units\": \"m\", "
          "\"joints\": [\"Foo\", \"Bar\"], \"parents\": [-1, 0], "
          "\"frames\": [[0, 1, 0, 0, 1.5, 0]]}\n",
          tf);
    fclose(tf);
  }
  snprintf(cmd, sizeof cmd,
           KM_CLI " pose --mesh '%s' --rig '%s/faust.rig.json' --motion '%s' -o '%s/foo.pc2'", body,
           g_dir, path, g_dir);
  rc = km_test_run(cmd, &out);
  CHECK_MSG(rc != 0 && out && strstr(out, "none of the 20 Kinect v1 joints") &&
                strstr(out, "foo_take.json"),
            "pose with no joint in common: exit %d: %s", rc, out ? out : "");
  free(out);
  snprintf(path, sizeof path, "%s/foo.pc2", g_dir);
  CHECK_MSG(access(path, F_OK) != 0, "a refused pose wrote %s", path);
}

/* Skin weights along the surface: the armadillo holds its hands up beside its ears at rest,
 * so weights by the distance to the bones in space give the ears and the face to the hands.
 * Its own skeleton, both arms swung 60 degrees down about the shoulders, skins the mesh
 * (km_lbs, what pose and an engine do): the worst edge |l/l0 - 1| over the mesh, measured 29
 * by distance (an ear and the face drawn down with a hand), 1.7 by reach (a shear where the
 * hunched face is weighted to the upper arms too; rendered, the session's notes) and 0.51
 * by bone heat, the default (0.53 since rig takes the armadillo's heat constant 0.5:
 * test_heat_constant; bound 1.0). */
static void test_reach_weights(void) {
  static const char *const arms[2][4] = {
      {"ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft"},
      {"ShoulderRight", "ElbowRight", "WristRight", "HandRight"}};
  const double down[2] = {M_PI / 3, M_PI / 3}; /* about the x axis through the shoulder */
  const km_autorig_skin skin[2] = {KM_AUTORIG_SKIN_DISTANCE, KM_AUTORIG_SKIN_REACH},
                        heat[2] = {KM_AUTORIG_SKIN_DISTANCE, KM_AUTORIG_SKIN_AUTO};
  double worst[2], worst_heat[2];
  km_autorig_report rep[2], rep_heat[2];
  if (!rig_twice_posed("meshes/armadillo.obj", skin, arms, down, 2, worst, rep)) return;
  if (!rig_twice_posed("meshes/armadillo.obj", heat, arms, down, 2, worst_heat, rep_heat)) return;
  printf("armadillo, arms swung 60 deg down, skinned: worst edge |l/l0 - 1| %.3f by distance, "
         "%.3f by reach, %.3f by bone heat (the default)\n",
         worst[0], worst[1], worst_heat[1]);
  CHECK_MSG(worst[1] < 2.5, "reach weights: an edge stretched %.3f", worst[1]);
  CHECK_MSG(worst_heat[1] < 1.0, "heat weights: an edge stretched %.3f", worst_heat[1]);
  /* the bounds mean something: distance weights tear the ears and the face */
  CHECK_MSG(worst[0] > 4 * worst[1] && worst[0] > 4 * worst_heat[1],
            "distance weights: the worst edge only %.3f", worst[0]);
  CHECK_MSG(rep_heat[1].skin == KM_AUTORIG_SKIN_HEAT, "armadillo: default weights %d",
            rep_heat[1].skin);
}

/* A shared mesh read in its guessed frame (read_oriented) and rigged by km_autorig's
 * defaults: the mesh, the character and the report. */
typedef struct rigged {
  km_mesh m;
  km_character c;
  km_autorig_report rep;
} rigged;

static void rigged_free(rigged *g) {
  km_character_free(&g->c);
  km_mesh_free(&g->m);
}

/* Rigs rel into g; false (g freed) when the mesh is absent (the test skips) or km_autorig
 * failed (a failed check already). Free a true one with rigged_free. */
static bool rig_shared(const char *rel, rigged *g) {
  km_frame_guess fg;
  memset(g, 0, sizeof *g);
  if (read_oriented(rel, &g->m, &fg)) {
    CHECK_OK(km_autorig(&g->m, NULL, &g->c, &g->rep, KM_E));
    if (g->c.skeleton.rest) return true;
  }
  rigged_free(g);
  return false;
}

/* The limits the rig writes follow the build (km_character_write_rig). Stubby limbs are the
 * build, not one thick bone: the elephant (every limb bone's radius 0.77-1.0 of its length) has
 * its swing limited to 12 degrees and no limb bands; the decimated knight (its right pauldron's
 * spikes put that upper arm at 0.503, the left at 0.459, the rest 0.21-0.36) swings freely and
 * keeps a band on both upper arms (it took the elephant's limits before: its arms hung still
 * while the performer reached overhead). A cat sitting up (cat-08: upright spine, front paws on
 * the ground below its haunches) gets a quadruped's rig, 30 degrees and no upper-arm bands, as
 * the sitting cats whose spines lean (cat-02) do; it took a person's before. */
static void test_build_limits(const char *rel, double swing, double upper, int arm_bands) {
  rigged g;
  if (!rig_shared(rel, &g)) return;
  km_rig rig = {0};
  sidecar_rig(&g.c, &g.m, rel, &rig);
  int arms = 0;
  for (size_t h = 0; h < rig.n_handles; ++h)
    arms += !strcmp(rig.handles[h].name, "upper_arm_left") ||
            !strcmp(rig.handles[h].name, "upper_arm_right");
  printf("  %s: swing_limit %g, upper_limb_limit %g, %d upper-arm bands\n", rel, rig.swing_limit,
         rig.upper_limb_limit, arms);
  CHECK_MSG(rig.swing_limit == swing && rig.upper_limb_limit == upper && arms == arm_bands,
            "%s: swing_limit %g, upper_limb_limit %g, %d upper-arm bands (want %g, %g, %d)", rel,
            rig.swing_limit, rig.upper_limb_limit, arms, swing, upper, arm_bands);
  km_rig_free(&rig);
  rigged_free(&g);
}

/* A tail lying on the ground beside a foot: the knee and ankle are those of the leg, not of
 * the tail the same horizontal cuts pass through (the dinosaur's tail behind its right foot, a
 * standing cat's, cat-05, beside its left). Each ankle lies over its leg (within 0.12 of the
 * skeleton's height of its knee, across) and near its foot tip (0.25). Measured before: the
 * dinosaur's right knee 0.19 and ankle 0.78 off, cat-05's left 0.28 and 0.33; the other shared
 * bodies 0.10 (the armadillo's leaning right shin) and 0.22 (its long-clawed feet) at most. */
static void test_tail_beside_foot(const char *rel) {
  rigged g;
  if (!rig_shared(rel, &g)) return;
  const double *J = g.c.skeleton.rest;
  double ylo = INFINITY, yhi = -INFINITY;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
    ylo = fmin(ylo, J[3 * j + 1]), yhi = fmax(yhi, J[3 * j + 1]);
  for (int side = 0; side < 2; ++side) {
    const char *foot = side ? "FootRight" : "FootLeft";
    const double *kn = J + 3 * (side ? 17 : 13), *an = J + 3 * (side ? 18 : 14), *tip = NULL;
    for (size_t e = 0; e < g.rep.n_extremities; ++e)
      if (!strcmp(g.rep.role[e], foot)) tip = g.m.V + 3 * (size_t)g.rep.extremity[e];
    double across = hypot(kn[0] - an[0], kn[2] - an[2]) / (yhi - ylo);
    double to_tip = tip ? hypot(tip[0] - an[0], tip[2] - an[2]) / (yhi - ylo) : INFINITY;
    printf("%s: %s side: knee %.3f of the height from its ankle across, ankle %.3f from the "
           "foot tip\n",
           rel, side ? "right" : "left", across, to_tip);
    CHECK_MSG(across < 0.12, "%s: the %s knee %.3f of the height off its ankle", rel,
              side ? "right" : "left", across);
    CHECK_MSG(to_tip < 0.25, "%s: the %s ankle %.3f of the height off its foot tip", rel,
              side ? "right" : "left", to_tip);
  }
  rigged_free(&g);
}

/* Whether p lies inside the closed mesh m: the parity of a ray's crossings (a fixed,
 * slightly skewed direction, so it meets no edge of these meshes exactly). */
static bool inside_mesh(const km_mesh *m, const double p[3]) {
  const double d[3] = {0.8017837, 0.2672612, 0.5345225};
  int hits = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const double *a = m->V + 3 * (size_t)m->F[3 * f], *b = m->V + 3 * (size_t)m->F[3 * f + 1],
                 *c = m->V + 3 * (size_t)m->F[3 * f + 2];
    double e1[3], e2[3], s[3], h[3], q[3];
    for (int k = 0; k < 3; ++k)
      e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], s[k] = p[k] - a[k];
    h[0] = d[1] * e2[2] - d[2] * e2[1], h[1] = d[2] * e2[0] - d[0] * e2[2],
    h[2] = d[0] * e2[1] - d[1] * e2[0];
    double det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
    if (fabs(det) < 1e-15) continue;
    double u = (s[0] * h[0] + s[1] * h[1] + s[2] * h[2]) / det;
    q[0] = s[1] * e1[2] - s[2] * e1[1], q[1] = s[2] * e1[0] - s[0] * e1[2],
    q[2] = s[0] * e1[1] - s[1] * e1[0];
    double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det,
           t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    hits += u >= 0 && v >= 0 && u + v <= 1 && t > 0;
  }
  return hits % 2 == 1;
}

/* A sitting animal's spine runs up its trunk inside the body, from where its hind legs part
 * to its chest, not along the ground between its paws (cat-08's hip centre, spine and
 * shoulder centre lay outside it, below the body) nor at chest height through the haunches
 * (cat-02's hips at its chest). */
static void test_sitting_spine(const char *rel) {
  rigged g;
  if (!rig_shared(rel, &g)) return;
  const km_mesh *m = &g.m;
  CHECK_MSG(g.rep.kind == KM_AUTORIG_QUADRUPED, "%s: rigged as kind %d", rel, (int)g.rep.kind);
  const double *J = g.c.skeleton.rest, *hip = J + 3 * 0, *sc = J + 3 * 2;
  double ylo = INFINITY, yhi = -INFINITY;
  for (size_t v = 0; v < m->n_vertices; ++v)
    ylo = fmin(ylo, m->V[3 * v + 1]), yhi = fmax(yhi, m->V[3 * v + 1]);
  printf("%s: hip centre %.3f, shoulder centre %.3f of the height; inside: %d %d %d\n", rel,
         (hip[1] - ylo) / (yhi - ylo), (sc[1] - ylo) / (yhi - ylo), inside_mesh(m, J),
         inside_mesh(m, J + 3), inside_mesh(m, J + 6));
  for (int j = 0; j < 3; ++j)
    CHECK_MSG(inside_mesh(m, J + 3 * j), "%s: spine joint %d outside the body", rel, j);
  CHECK_MSG(sc[1] - hip[1] > 0.12 * (yhi - ylo),
            "%s: the shoulder centre only %.3f of the height above the hip centre", rel,
            (sc[1] - hip[1]) / (yhi - ylo));
  rigged_free(&g);
}

/* A foot raised off the ground (npt_14_664 kicks its left leg forward, the foot 18 % of its
 * height up): its ankle and foot joints lie in the foot, not on the floor under its toes
 * (0.12 and 0.14 of the height outside the body before), and its shin runs along the leg. */
static void test_raised_foot(void) {
  const char *rel = "poses/npt_14_664.obj";
  rigged g;
  if (!rig_shared(rel, &g)) return;
  for (int j = 13; j <= 15; ++j) /* KneeLeft, AnkleLeft, FootLeft */
    CHECK_MSG(inside_mesh(&g.m, g.c.skeleton.rest + 3 * j), "%s: %s outside the body", rel,
              km_kinect1_joint_name(j));
  rigged_free(&g);
}

/* Every joint inside the body, or named as outside in the report. rig left a FAUST body's
 * wrist and feet a little past its skin (tr_reg_025: 0.02-0.025 of the height), the
 * armadillo's left hip beside its groin and a crouching cat's head joint between its ears: a
 * bone turning about a point in the air. moved_min: how many joints rig must have moved in;
 * outside_max: how many it may leave out (named), -1 any. A shoulder just outside a chest's
 * side (the dinosaur's left, 0.02 of the height; the standing cat-05's right) had the whole
 * chest as its chord, whose middle is not its part's, and was left out: it now goes in as far
 * as a joint may move. */
static void test_joints_inside(const char *rel, int moved_min, int outside_max) {
  rigged g;
  if (!rig_shared(rel, &g)) return;
  const km_autorig_report *rep = &g.rep;
  printf("%s: %d joints moved inside, outside mask 0x%x\n", rel, rep->joints_moved_inside,
         (unsigned)rep->joints_outside);
  CHECK_MSG(rep->joints_moved_inside >= moved_min, "%s: %d joints moved inside, expected %d", rel,
            rep->joints_moved_inside, moved_min);
  int left_out = 0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    CHECK_MSG(inside_mesh(&g.m, g.c.skeleton.rest + 3 * j) || (rep->joints_outside >> j & 1u),
              "%s: %s outside the body and not reported", rel, km_kinect1_joint_name(j));
    left_out += (int)(rep->joints_outside >> j & 1u);
  }
  CHECK_MSG(outside_max < 0 || left_out <= outside_max, "%s: %d joints left outside, at most %d",
            rel, left_out, outside_max);
  rigged_free(&g);
}

/* npt_13_643: an SMPL body leaning back on one leg, the other kicked forward, stored y up and
 * facing +z, which the orientation guess takes for z up (its back flat). Rigged in its own frame
 * (--up +y --forward +z), its head is the top of its head: the ring a tenth of the height below
 * a belly's bump is the wide torso, and measured against it the head's neck ring was too thin
 * and the belly (0.72 of the height) was taken for the head. The sidecar records the frame even
 * though it is kinemesh's own, so animate does not guess again (it animated the body lying on
 * its back). */
static void test_leaning_body(void) {
  char buf[1024];
  const char *path = km_test_shared("poses/npt_13_643.obj", buf, sizeof buf);
  if (!path) return;
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(path, &m, KM_E));
  double lo = INFINITY, hi = -INFINITY;
  for (size_t v = 0; v < m.n_vertices; ++v)
    lo = fmin(lo, m.V[3 * v + 1]), hi = fmax(hi, m.V[3 * v + 1]);
  km_character c = {0};
  km_autorig_report rep;
  CHECK_OK(km_autorig(&m, NULL, &c, &rep, KM_E));
  CHECK_MSG(rep.kind == KM_AUTORIG_KINECT1, "npt_13_643: rigged as kind %d", (int)rep.kind);
  double head = NAN;
  for (size_t e = 0; e < rep.n_extremities; ++e)
    if (!strcmp(rep.role[e], "Head"))
      head = (m.V[3 * (size_t)rep.extremity[e] + 1] - lo) / (hi - lo);
  printf("npt_13_643: head at %.3f of the height\n", head);
  CHECK_MSG(head > 0.9, "npt_13_643: head at %.3f of the height", head);
  km_character_free(&c);
  km_mesh_free(&m);
  char take[1024], cmd[4096], rig[512];
  if (!km_test_shared("skeleton/precog_Seq1_1.csv", take, sizeof take)) return;
  snprintf(rig, sizeof rig, "%s/npt13.rig.json", g_dir);
  snprintf(cmd, sizeof cmd, KM_CLI " rig '%s' --up +y --forward +z -o '%s'", path, rig);
  CHECK_MSG(km_test_run(cmd, NULL) == 0, "%s", cmd);
  snprintf(cmd, sizeof cmd,
           "grep -A3 '\"frame\"' '%s' | grep -q '\"+y\"' && grep -A3 '\"frame\"' '%s' | grep -q "
           "'\"+z\"'",
           rig, rig);
  CHECK_MSG(km_test_run(cmd, NULL) == 0, "the sidecar records kinemesh's own frame");
  snprintf(cmd, sizeof cmd,
           KM_CLI " animate --mesh '%s' --rig '%s' --motion '%s' -o '%s/npt13.pc2'", path, rig,
           take, g_dir);
  char *out = NULL;
  int rc = km_test_run(cmd, &out);
  CHECK_MSG(rc == 0 && out && !strstr(out, "guessed"), "animate with the recorded frame: %s",
            out ? out : "");
  free(out);
}

/* Meshes no rule was tuned on, rigged by the automatic choice: the roles must be the body's.
 * The dinosaur (a biped whose tail tip hangs 6 % of its height above the ground) was taken for
 * a quadruped with its tail as a hind leg; armadillo_1k's left hand was a toe of its left foot
 * (the hand up by its ear left out); the walking and the stretching cat had their raised tails
 * for heads; FAUST's tr_reg_001, bent forward with its hands on its knees, a hand. Every foot
 * on the ground, every hand of an upright body above the knees and
 * its head in the upper half, a quadruped's head ahead of its feet, and a tail or toe given no
 * role. */
static void test_roles(const char *rel, km_autorig_skeleton want, double foot_max) {
  km_mesh m = {0};
  km_frame_guess g;
  if (!read_oriented(rel, &m, &g)) return;
  double lo = INFINITY, hi = -INFINITY;
  for (size_t v = 0; v < m.n_vertices; ++v)
    lo = fmin(lo, m.V[3 * v + 1]), hi = fmax(hi, m.V[3 * v + 1]);
  /* the reference cat, when rel is one of its poses (same vertices) */
  km_mesh ref = {0};
  double ref_lo = INFINITY, ref_hi = -INFINITY, ref_zm = 0;
  char rbuf[1024];
  const char *rp = strstr(rel, "cat-poses/")
                       ? km_test_shared("poses/cat-poses/cat-reference.obj", rbuf, sizeof rbuf)
                       : NULL;
  if (rp) CHECK_OK(km_mesh_read(rp, &ref, KM_E));
  if (ref.n_vertices != m.n_vertices) km_mesh_free(&ref);
  for (size_t v = 0; v < ref.n_vertices; ++v)
    ref_lo = fmin(ref_lo, ref.V[3 * v + 1]), ref_hi = fmax(ref_hi, ref.V[3 * v + 1]),
    ref_zm += ref.V[3 * v + 2] / (double)ref.n_vertices;
  km_character c = {0};
  km_autorig_report rep;
  km_status st = km_autorig(&m, NULL, &c, &rep, KM_E);
  CHECK_MSG(st == KM_OK, "%s: %s", rel, km_test_err.message);
  if (st == KM_OK) {
    CHECK_MSG(rep.kind == want, "%s: rigged as kind %d, want %d", rel, (int)rep.kind, (int)want);
    int roles = 0;
    double limb_z = 0, head_z = NAN;
    for (size_t e = 0; e < rep.n_extremities; ++e) {
      const double *q = m.V + 3 * (size_t)rep.extremity[e];
      if (!strncmp(rep.role[e], "Foot", 4) || !strncmp(rep.role[e], "Hand", 4)) limb_z += q[2] / 4;
      if (!strcmp(rep.role[e], "Head")) head_z = q[2];
    }
    /* a quadruped's head is ahead of its feet (kinemesh's frame faces +z), not a tail held up */
    if (want == KM_AUTORIG_QUADRUPED)
      CHECK_MSG(head_z > limb_z, "%s: head at z %.3f behind the feet's middle %.3f", rel, head_z,
                limb_z);
    for (size_t e = 0; e < rep.n_extremities; ++e) {
      if (!rep.role[e][0]) continue;
      double h = (m.V[3 * (size_t)rep.extremity[e] + 1] - lo) / (hi - lo);
      printf("%s: %-10s vertex %6d at %.3f of the height\n", rel, rep.role[e], rep.extremity[e], h);
      bool foot = !strncmp(rep.role[e], "Foot", 4), hand = !strncmp(rep.role[e], "Hand", 4);
      bool head = !strcmp(rep.role[e], "Head");
      if (foot)
        CHECK_MSG(h < foot_max, "%s: %s %.3f of the height above the ground", rel, rep.role[e], h);
      if (hand && want == KM_AUTORIG_KINECT1)
        CHECK_MSG(h > 0.3, "%s: %s at %.3f of the height (a foot's toe?)", rel, rep.role[e], h);
      if (head && want == KM_AUTORIG_KINECT1) /* a cat bowing to play holds its head low */
        CHECK_MSG(h > 0.75, "%s: head at %.3f of the height", rel, h);
      /* SMPL's topology (FAUST registrations, the NPT bodies) names its fingertips: a hand is
       * at its own (npt_14_664, arms raised behind it while its feet kick forward, had a bump
       * at its hips for a right hand: 0.38 of the height, which the check above lets pass) */
      if (hand && m.n_vertices == 6890) {
        const double *q = m.V + 3 * (size_t)rep.extremity[e];
        const double *tip = m.V + 3 * (rep.role[e][4] == 'L' ? 2445 : 5905);
        double d = sqrt((q[0] - tip[0]) * (q[0] - tip[0]) + (q[1] - tip[1]) * (q[1] - tip[1]) +
                        (q[2] - tip[2]) * (q[2] - tip[2]));
        CHECK_MSG(d < 0.1 * (hi - lo), "%s: %s %.3f of the height from SMPL's fingertip", rel,
                  rep.role[e], d / (hi - lo));
      }
      /* The cat poses share the reference cat's vertices: there a hand is a front paw, on the
       * ground ahead of the body's middle, and the head is high (cat-05, standing up with its
       * forepaws raised over its head, had a paw for its head and an ear for a hand) */
      if ((hand || head) && ref.n_vertices == m.n_vertices) {
        const double *q = ref.V + 3 * (size_t)rep.extremity[e];
        double rh = (q[1] - ref_lo) / (ref_hi - ref_lo);
        if (hand)
          CHECK_MSG(rh < 0.15 && q[2] > ref_zm,
                    "%s: %s is no front paw (reference cat: %.3f of "
                    "the height, z %.3f against the middle %.3f)",
                    rel, rep.role[e], rh, q[2], ref_zm);
        if (head) CHECK_MSG(rh > 0.6, "%s: head at %.3f of the reference cat's height", rel, rh);
      }
      roles += foot || hand || head;
    }
    CHECK_MSG(roles == 5, "%s: %d roles given", rel, roles);
    /* level shoulders (the decimated knight's right one was 5 % of its height below its left:
     * inside the armpit). Within 1.5 %: the dinosaur's left shoulder, placed level with its
     * right but 0.026 of the height outside its chest (the body is not symmetric there), goes
     * in along the line to its nearest vertex, which climbs: 1.2 % above the right one. */
    if (want == KM_AUTORIG_KINECT1) {
      double yl = c.skeleton.rest[3 * km_kinect1_joint_index("ShoulderLeft") + 1],
             yr = c.skeleton.rest[3 * km_kinect1_joint_index("ShoulderRight") + 1];
      CHECK_MSG(fabs(yl - yr) < 0.015 * (hi - lo), "%s: shoulders %.3f and %.3f of the height", rel,
                (yl - lo) / (hi - lo), (yr - lo) / (hi - lo));
    }
    /* a person's shoulders lie about 0.18 of the stature (feet to head top) below the head
     * top, whatever the hands do (npt_14_664's raised hand made the mesh's height its stature:
     * 0.08, the shoulders at its chin) */
    if (m.n_vertices == 6890 && want == KM_AUTORIG_KINECT1) {
      double top = -INFINITY;
      for (size_t e = 0; e < rep.n_extremities; ++e)
        if (!strcmp(rep.role[e], "Head")) top = m.V[3 * (size_t)rep.extremity[e] + 1];
      double sc = c.skeleton.rest[3 * km_kinect1_joint_index("ShoulderCenter") + 1];
      double f = (top - sc) / (top - lo);
      printf("%s: shoulders %.3f of the stature below the head top\n", rel, f);
      CHECK_MSG(f > 0.12 && f < 0.3, "%s: shoulders %.3f of the stature below the head top", rel,
                f);
    }
    /* The sidecar's head handle sits on the head: its vertices within 0.3 of the height of
     * the Head joint (it was a ball round the highest vertex: the walking cat's raised tail
     * tip, the raised hand of FAUST's npt_14_664). */
    char rig_path[512];
    snprintf(rig_path, sizeof rig_path, "%s/roles.rig.json", g_dir);
    CHECK_OK(km_character_write_rig(rig_path, &c, KM_E));
    km_rig rig = {0};
    CHECK_OK(km_rig_read(rig_path, &m, NULL, 0, &rig, KM_E));
    const double *J = c.skeleton.rest + 3 * km_kinect1_joint_index("Head");
    for (size_t h = 0; h < rig.n_handles; ++h) {
      if (strcmp(rig.handles[h].name, "head")) continue;
      double far = 0;
      for (size_t k = 0; k < rig.handles[h].n_vertices; ++k) {
        const double *q = m.V + 3 * (size_t)rig.handles[h].vertices[k];
        far = fmax(far, sqrt((q[0] - J[0]) * (q[0] - J[0]) + (q[1] - J[1]) * (q[1] - J[1]) +
                             (q[2] - J[2]) * (q[2] - J[2])));
      }
      printf("%s: head handle, %zu vertices, farthest %.3f of the height from the Head joint\n",
             rel, rig.handles[h].n_vertices, far / (hi - lo));
      CHECK_MSG(far < 0.3 * (hi - lo),
                "%s: a head handle vertex %.3f of the height from the Head joint", rel,
                far / (hi - lo));
    }
    km_rig_free(&rig);
  }
  km_character_free(&c);
  km_mesh_free(&m);
  km_mesh_free(&ref);
}

/* A body with small loose pieces (a game character's eyes; issue 11's first wall for one): the
 * procedural character with two octahedra (6 vertices each) in front of its face, appended
 * after its vertices. rig rigs the body as it rigs it alone (joints, skin, landmarks and every
 * handle the same; no handle holds an eye's vertex), and each eye vertex has the skin of the
 * body vertex nearest to it (the head's: 11 of 12 vertices dominated by Head, the twelfth at
 * the face's edge). Refused before as "3 components". Two comparable
 * pieces are still refused, naming their sizes (test_refused). */
static void test_loose_pieces(void) {
  km_character_options co = {0};
  co.target_vertices = 4000;
  km_character c = {0}, a = {0}, b = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  const km_mesh *m = &c.mesh;
  size_t n = m->n_vertices, nf = m->n_faces;
  km_mesh e = {0};
  CHECK_OK(km_mesh_alloc(n + 12, nf + 16, &e, KM_E));
  if (!e.V) goto done;
  memcpy(e.V, m->V, 3 * n * sizeof(double));
  memcpy(e.F, m->F, 3 * nf * sizeof(int32_t));
  size_t top = 0; /* the face: in front of the top of the head, a tenth of the height down */
  double ylo = INFINITY;
  for (size_t v = 0; v < n; ++v) {
    if (m->V[3 * v + 1] > m->V[3 * top + 1]) top = v;
    ylo = fmin(ylo, m->V[3 * v + 1]);
  }
  double H = m->V[3 * top + 1] - ylo, zmax = -INFINITY, y = m->V[3 * top + 1] - 0.06 * H;
  for (size_t v = 0; v < n; ++v)
    if (fabs(m->V[3 * v + 1] - y) < 0.02 * H && fabs(m->V[3 * v]) < 0.05 * H)
      zmax = fmax(zmax, m->V[3 * v + 2]);
  static const double oct[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                   {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
  static const int of[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                               {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int k = 0; k < 2; ++k) {
    double c0[3] = {(k ? -1 : 1) * 0.02 * H, y, zmax + 0.012 * H};
    for (int i = 0; i < 6; ++i)
      for (int d = 0; d < 3; ++d)
        e.V[3 * (n + 6 * (size_t)k + (size_t)i) + (size_t)d] = c0[d] + 0.01 * H * oct[i][d];
    for (int f = 0; f < 8; ++f)
      for (int d = 0; d < 3; ++d)
        e.F[3 * (nf + 8 * (size_t)k + (size_t)f) + (size_t)d] =
            (int32_t)(n + 6 * (size_t)k) + of[f][d];
  }
  km_mesh_info info;
  CHECK_OK(km_mesh_info_compute(&e, &info, KM_E));
  CHECK(info.components == 3);
  km_autorig_report ra, rb;
  CHECK_OK(km_autorig(m, NULL, &a, &ra, KM_E));
  CHECK_OK(km_autorig(&e, NULL, &b, &rb, KM_E));
  if (!a.skin.joints || !b.skin.joints || b.skin.n_vertices != n + 12) goto done;
  CHECK(ra.kind == rb.kind && ra.n_extremities == rb.n_extremities);
  CHECK_MSG(ra.loose_pieces == 0 && rb.loose_pieces == 2 && rb.loose_vertices == 12 &&
                rb.rigid_pieces == 2,
            "loose pieces %zu (%zu vertices, %zu rigid)", rb.loose_pieces, rb.loose_vertices,
            rb.rigid_pieces);
  double dj = 0;
  for (size_t i = 0; i < 3 * a.skeleton.n_joints; ++i)
    dj = fmax(dj, fabs(a.skeleton.rest[i] - b.skeleton.rest[i]));
  CHECK_MSG(dj < 1e-9, "joints %g from the character's alone", dj);
  bool skin = memcmp(a.skin.joints, b.skin.joints, 4 * n * sizeof(int32_t)) == 0 &&
              memcmp(a.skin.weights, b.skin.weights, 4 * n * sizeof(double)) == 0;
  CHECK_MSG(skin, "the body's skin differs from the character's alone");
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i)
    CHECK(a.landmarks[i].vertex == b.landmarks[i].vertex);
  int head = -1;
  for (size_t j = 0; j < b.skeleton.n_joints; ++j)
    if (!strcmp(b.skeleton.names[j], "Head")) head = (int)j;
  size_t eye_head = 0;
  int32_t held[2] = {-1, -1}; /* each eye follows the body vertex nearest to it as a whole */
  double best[2] = {INFINITY, INFINITY};
  for (size_t v = n; v < n + 12; ++v) {
    int32_t a_near = -1;
    double d = 0;
    km_nearest_vertices(m->V, n, e.V + 3 * v, 1, &a_near, &d);
    if (d < best[(v - n) / 6]) best[(v - n) / 6] = d, held[(v - n) / 6] = a_near;
  }
  for (size_t v = n; v < n + 12; ++v) {
    int32_t near = held[(v - n) / 6];
    CHECK(
        memcmp(b.skin.joints + 4 * v, a.skin.joints + 4 * (size_t)near, 4 * sizeof(int32_t)) == 0 &&
        memcmp(b.skin.weights + 4 * v, a.skin.weights + 4 * (size_t)near, 4 * sizeof(double)) == 0);
    int dom = 0; /* the joint of the largest weight */
    for (int k = 1; k < 4; ++k)
      if (b.skin.weights[4 * v + (size_t)k] > b.skin.weights[4 * v + (size_t)dom]) dom = k;
    eye_head += b.skin.joints[4 * v + (size_t)dom] == head;
  }
  printf("loose pieces: joints within %.3g of the body's alone, %zu of 12 eye vertices skinned "
         "to the head\n",
         dj, eye_head);
  CHECK_MSG(eye_head >= 10, "%zu of 12 eye vertices skinned to the head", eye_head);
  km_rig rig_a = {0}, rig_b = {0};
  sidecar_rig(&a, m, "alone", &rig_a);
  sidecar_rig(&b, &e, "with eyes", &rig_b);
  bool same = rig_a.n_handles == rig_b.n_handles && rig_a.n_handles > 0;
  for (size_t h = 0; same && h < rig_a.n_handles; ++h)
    same = rig_a.handles[h].n_vertices == rig_b.handles[h].n_vertices &&
           !memcmp(rig_a.handles[h].vertices, rig_b.handles[h].vertices,
                   rig_a.handles[h].n_vertices * sizeof(int32_t));
  CHECK_MSG(same, "the rig's handles with eyes are not the body's alone");
  km_rig_free(&rig_a);
  km_rig_free(&rig_b);
done:
  km_mesh_free(&e);
  km_character_free(&a);
  km_character_free(&b);
  km_character_free(&c);
}

/* Collapsed faces (a repeated vertex index, as decimation and welding leave them) are no
 * surface: the procedural character with one on an edge of its first face (which made that
 * edge non-manifold: refused, "repair it first") and one joining its first and last vertices
 * (which opened a boundary between them: armadillo_1k with it rigged as a bust) rigs as it does
 * without them. */
static void test_collapsed_faces(void) {
  km_character_options co = {0};
  co.target_vertices = 3000;
  km_character c = {0}, a = {0}, b = {0};
  CHECK_OK(km_character_generate(&co, &c, KM_E));
  const km_mesh *m = &c.mesh;
  size_t n = m->n_vertices, nf = m->n_faces;
  km_mesh e = {0};
  CHECK_OK(km_mesh_alloc(n, nf + 2, &e, KM_E));
  if (!e.V) goto done;
  memcpy(e.V, m->V, 3 * n * sizeof(double));
  memcpy(e.F, m->F, 3 * nf * sizeof(int32_t));
  int32_t extra[6] = {m->F[0], m->F[0], m->F[1], 0, 0, (int32_t)n - 1};
  memcpy(e.F + 3 * nf, extra, sizeof extra);
  km_autorig_report ra, rb;
  CHECK_OK(km_autorig(m, NULL, &a, &ra, KM_E));
  CHECK_OK(km_autorig(&e, NULL, &b, &rb, KM_E));
  if (!a.skeleton.rest || !b.skeleton.rest) goto done;
  double dj = 0;
  for (size_t i = 0; i < 3 * a.skeleton.n_joints; ++i)
    dj = fmax(dj, fabs(a.skeleton.rest[i] - b.skeleton.rest[i]));
  printf("collapsed faces: rigged as a %s, joints within %.2g m of the clean mesh's\n",
         km_autorig_kind_name(rb.kind), dj);
  CHECK(rb.kind == ra.kind && ra.kind == KM_AUTORIG_KINECT1);
  CHECK_MSG(dj < 1e-3, "joints %g m from the clean mesh's", dj);
done:
  km_mesh_free(&e);
  km_character_free(&a);
  km_character_free(&b);
  km_character_free(&c);
}

int main(void) {
  test_seam_split();
  test_loose_pieces();
  test_collapsed_faces();
  if (!mkdtemp(g_dir)) {
    perror("mkdtemp");
    return 1;
  }
  test_refused();
  test_pick();
  test_character(10000, 0, 0, 0);
  test_character(20000, 7, 0.6, 1.15);
  test_isolated_vertex();
  test_given_joints();
  test_faust_landmarks();
  test_cli();
  test_pose_bvh();
  test_reach_weights();
  test_heat_constant();
  test_quadruped_heat_constant();
  test_quadruped_skin();
  test_roles("meshes/dino.off", KM_AUTORIG_KINECT1, 0.1);
  test_roles("meshes/armadillo_1k.off", KM_AUTORIG_KINECT1, 0.1);
  test_roles("meshes/horse.ply", KM_AUTORIG_QUADRUPED, 0.1);
  test_roles("meshes/dog0.off", KM_AUTORIG_QUADRUPED, 0.1);
  test_roles("poses/cat-poses/cat-03.obj", KM_AUTORIG_QUADRUPED, 0.1);
  test_roles("poses/cat-poses/cat-06.obj", KM_AUTORIG_QUADRUPED, 0.1);
  test_roles("poses/cat-poses/cat-reference.obj", KM_AUTORIG_QUADRUPED, 0.1);
  test_roles("poses/cat-poses/cat-05.obj", KM_AUTORIG_KINECT1,
             0.1); /* standing up, forepaws raised over its head */
  test_roles("poses/cat-poses/cat-02.obj", KM_AUTORIG_QUADRUPED,
             0.1); /* sitting: hind paws beside the front ones */
  test_roles("poses/cat-poses/cat-08.obj", KM_AUTORIG_QUADRUPED,
             0.1); /* sitting, its tail on the ground round its paws */
  test_roles("poses/cat-poses/cat-09.obj", KM_AUTORIG_QUADRUPED,
             0.1); /* sitting, licking a forepaw raised to its mouth */
  test_roles("poses/tr_reg_001.off", KM_AUTORIG_KINECT1,
             0.1); /* bent forward, hands on its knees */
  test_roles("poses/npt_14_664.obj", KM_AUTORIG_KINECT1,
             0.25); /* a hand raised above the head, a foot 18 % up */
  test_roles("poses/tr_reg_000.off", KM_AUTORIG_KINECT1, 0.1);
  test_roles("meshes/decimated-knight.off", KM_AUTORIG_KINECT1, 0.1); /* Baran's own model */
  test_roles("poses/tr_reg_025.ply", KM_AUTORIG_KINECT1, 0.1);
  test_leaning_body();
  test_tail_beside_foot("meshes/dino.off");
  test_tail_beside_foot("poses/cat-poses/cat-05.obj");
  test_sitting_spine("poses/cat-poses/cat-02.obj");
  test_sitting_spine("poses/cat-poses/cat-08.obj");
  test_raised_foot();
  test_build_limits("meshes/elephant.obj", 12, 15, 0);
  test_build_limits("meshes/decimated-knight.off", 0, 0, 2);
  test_build_limits("poses/cat-poses/cat-08.obj", 30, 5, 0);
  test_build_limits("poses/cat-poses/cat-02.obj", 30, 5, 0);
  test_joints_inside("poses/tr_reg_025.ply", 3, 0);
  test_joints_inside("meshes/armadillo.obj", 1, 0);
  test_joints_inside("poses/cat-poses/cat-01.obj", 4, 0);
  test_joints_inside("poses/cat-poses/cat-06.obj", 0, -1); /* its hips: reported */
  test_joints_inside("meshes/dog0.off", 2, 0);
  test_joints_inside("meshes/dino.off", 1, 0);
  test_joints_inside("poses/cat-poses/cat-05.obj", 1, 0);
  char buf[1024];
  const char *csv = km_test_shared("skeleton/precog_Seq1_1.csv", buf, sizeof buf);
  if (csv) {
    km_take take = {0};
    km_motion_read_options mo = {0};
    mo.kinect1 = true;
    CHECK_OK(km_motion_read(csv, &mo, &take, NULL, KM_E));
    char cbuf[1024];
    const char *bvh = km_test_shared("bvh/cmu_131_01.bvh", cbuf, sizeof cbuf);
    km_take cmu = {0};
    if (bvh) CHECK_OK(km_motion_read(bvh, &mo, &cmu, NULL, KM_E));
    const km_take *cm = cmu.n_frames ? &cmu : NULL;
    if (take.n_frames) {
      test_prop(&take);
      test_bust(&take);
      test_seated(&take, cm);
      test_upper_body(&take);
      test_resting(&take);
      test_character_drive(&take);
      test_real("meshes/armadillo.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, KM_AUTORIG_KINECT1, &take,
                2.1, cm);
      test_real("meshes/dog0.off", KM_AXIS_POS_Z, KM_AXIS_NEG_Y, KM_AUTORIG_QUADRUPED, &take, 1.5,
                cm);
      test_real("meshes/elephant.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, KM_AUTORIG_KINECT1, &take, 1.5,
                cm);
      test_real("meshes/horse.ply", KM_AXIS_POS_Z, KM_AXIS_POS_Y, KM_AUTORIG_QUADRUPED, &take, 1.5,
                cm);
    }
    km_take_free(&cmu);
    km_take_free(&take);
  } else {
    test_upper_body(NULL);
  }
  char cmd[512];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
  if (km_test_run(cmd, NULL) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
  return km_test_finish("test_autorig");
}
