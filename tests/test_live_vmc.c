/* VMC input (apps/live/live_vmc.c), without sockets: bundles made by the sender's own code
 * (km_live_vmc_bundle) and by hand go through km_live_vmc_packet. The Unity conversion (a
 * bone at Unity's -x is the performer's left, kinemesh +x; a quarter turn about Unity's y
 * turns the avatar's front to its right, kinemesh -x), the FK against a CMU BVH's own joint
 * positions (within 1 mm, through float32 OSC), the Kinect v1 joints the pipeline gets, and
 * malformed input counted without a crash (every truncated prefix, wrong types, NaN,
 * unknown addresses). */
#include "km_test.h"
#include "live.h"

#include <math.h>
#include <string.h>

/* ---- a tiny OSC writer for hand-made packets */
typedef struct buf {
  unsigned char d[8192];
  size_t n;
} buf;
static void put_str(buf *b, const char *s) {
  size_t n = strlen(s) + 1;
  memcpy(b->d + b->n, s, n);
  b->n += n;
  while (b->n % 4)
    b->d[b->n++] = 0;
}
static void put_f(buf *b, float x) {
  uint32_t u;
  memcpy(&u, &x, 4);
  for (int k = 3; k >= 0; --k)
    b->d[b->n++] = (unsigned char)(u >> (8 * k));
}
static void put_i(buf *b, uint32_t u) {
  for (int k = 3; k >= 0; --k)
    b->d[b->n++] = (unsigned char)(u >> (8 * k));
}
static void pos_msg(buf *m, const char *addr, const char *name, const float *p7) {
  m->n = 0;
  put_str(m, addr);
  put_str(m, ",sfffffff");
  put_str(m, name);
  for (int k = 0; k < 7; ++k)
    put_f(m, p7[k]);
}
static void bundle_begin(buf *b) {
  b->n = 0;
  put_str(b, "#bundle");
  put_i(b, 0);
  put_i(b, 1);
}
static void bundle_add(buf *b, const buf *m) {
  put_i(b, (uint32_t)m->n);
  memcpy(b->d + b->n, m->d, m->n);
  b->n += m->n;
}

static void test_convention(void) {
  km_live_vmc v;
  km_live_vmc_init(&v);
  buf b, m;
  bundle_begin(&b);
  const float root[7] = {0, 0, 0, 0, 0, 0, 1};
  const float s = (float)sqrt(0.5);
  const float hips[7] = {0, 1, 0, 0, s, 0, s}; /* a quarter turn about Unity's +y */
  const float chest[7] = {0, 0.3f, 0, 0, 0, 0, 1};
  const float arm[7] = {-0.2f, 0.1f, 0, 0, 0, 0, 1}; /* Unity -x: the avatar's left */
  const float toes[7] = {0, 0, 1, 0, 0, 0, 1};       /* in front of the hips */
  pos_msg(&m, "/VMC/Ext/Root/Pos", "root", root);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", hips);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Chest", chest);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftUpperArm", arm); /* parent: Chest (no shoulder sent) */
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftUpperLeg", toes);
  bundle_add(&b, &m);
  double J[60];
  CHECK(km_live_vmc_packet(&v, b.d, b.n, J) == 1);
  CHECK(v.bad == 0 && v.frames == 1 && v.messages == 5);
  int arm_b = km_skeleton_joint_index(KM_SKELETON_HUMANOID, "LeftUpperArm");
  int leg_b = km_skeleton_joint_index(KM_SKELETON_HUMANOID, "LeftUpperLeg");
  const double *pa = v.positions + 3 * arm_b, *pl = v.positions + 3 * leg_b;
  /* The arm, turned with the hips a quarter to the avatar's right: Unity local -x becomes
   * Unity world +z (front) ... after the turn the avatar's left points to its old front. */
  CHECK_NEAR(pa[0], 0.0, 1e-6);
  CHECK_NEAR(pa[1], 1.4, 1e-6);
  CHECK_NEAR(pa[2], 0.2, 1e-6);
  /* the avatar's front (Unity local +z) turned to its right: kinemesh -x */
  CHECK_NEAR(pl[0], -1.0, 1e-6);
  CHECK_NEAR(pl[1], 1.0, 1e-6);
  CHECK_NEAR(pl[2], 0.0, 1e-6);
  /* ShoulderLeft (Kinect v1 joint 4) is the upper arm; HandLeft is not driven */
  CHECK_NEAR(J[3 * 4 + 2], 0.2, 1e-6);
  CHECK(isnan(J[3 * 7]));

  /* Unturned: the left arm at Unity -x lands on kinemesh +x, the performer's left. */
  const float still[7] = {0, 1, 0, 0, 0, 0, 1};
  bundle_begin(&b);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", still);
  bundle_add(&b, &m);
  CHECK(km_live_vmc_packet(&v, b.d, b.n, J) == 1);
  CHECK_NEAR(v.positions[3 * arm_b], 0.2, 1e-6);
  CHECK_NEAR(v.positions[3 * arm_b + 2], 0.0, 1e-6);
}

/* A CMU BVH through the sender's bundles: FK within 1 mm of the BVH's own joints. */
static void test_bvh(void) {
  char path_buf[1024];
  const char *path = km_test_shared("bvh/cmu_131_01.bvh", path_buf, sizeof path_buf);
  if (!path) return;
  km_take t = {0};
  CHECK_OK(km_motion_read(path, NULL, &t, NULL, KM_E));
  int col[KM_HUMANOID_BONES];
  for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
    int s = km_skeleton_joint_map(KM_SKELETON_HUMANOID, b, KM_SKELETON_BVH);
    col[b] = -1;
    for (size_t k = 0; s >= 0 && k < t.n_joints; ++k)
      if (!strcmp(t.joint_names[k], km_skeleton_joint_name(KM_SKELETON_BVH, s))) col[b] = (int)k;
  }
  int lhand = -1;
  for (size_t k = 0; k < t.n_joints; ++k)
    if (!strcmp(t.joint_names[k], "lhand")) lhand = (int)k;
  CHECK(lhand >= 0);
  km_live_vmc v;
  km_live_vmc_init(&v);
  double worst = 0, worst_k1 = 0;
  size_t n = 0;
  for (size_t f = 0; f < t.n_frames; f += 5, ++n) {
    double hum[3 * KM_HUMANOID_BONES];
    for (int b = 0; b < KM_HUMANOID_BONES; ++b)
      for (int a = 0; a < 3; ++a)
        hum[3 * b + a] = col[b] < 0 ? NAN : t.positions[(f * t.n_joints + (size_t)col[b]) * 3 + a];
    km_humanoid_pose pose;
    CHECK_OK(km_humanoid_pose_from_positions(hum, &pose, KM_E));
    size_t len = 0;
    void *pkt = km_live_vmc_bundle(&pose, (double)f / t.fps, &len);
    CHECK(pkt != NULL);
    if (!pkt) break;
    double J[60];
    CHECK(km_live_vmc_packet(&v, pkt, len, J) == 1);
    free(pkt);
    for (int b = 0; b < KM_HUMANOID_BONES; ++b)
      if (col[b] >= 0)
        for (int a = 0; a < 3; ++a)
          worst = fmax(worst, fabs(v.positions[3 * b + a] - hum[3 * b + a]));
    for (int a = 0; a < 3; ++a) /* Kinect HandLeft = CMU lhand */
      worst_k1 = fmax(worst_k1, fabs(J[3 * 7 + a] - t.positions[(f * t.n_joints + lhand) * 3 + a]));
  }
  CHECK_MSG(worst < 1e-3, "VMC FK is %.3g mm off the BVH's joints", worst * 1e3);
  CHECK_MSG(worst_k1 < 1e-3, "HandLeft is %.3g mm off the BVH's lhand", worst_k1 * 1e3);
  CHECK(v.bad == 0 && v.unknown == 0 && v.frames == n);
  printf("VMC FK vs BVH over %zu frames: max %.4f mm\n", n, worst * 1e3);
  km_take_free(&t);
}

static void test_garbage(void) {
  km_live_vmc v;
  km_live_vmc_init(&v);
  buf b, m;
  double J[60];
  const float p[7] = {0, 1, 0, 0, 0, 0, 1};
  bundle_begin(&b);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", p);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftHand", p);
  bundle_add(&b, &m);
  /* every truncated prefix: counted or harmless, never a crash (ASan build) */
  for (size_t k = 0; k < b.n; ++k)
    km_live_vmc_packet(&v, b.d, k, J);
  CHECK(v.bad >= b.n / 2);
  uint64_t bad = v.bad;
  /* wrong type tags: an int where the bone name goes, too few numbers, a string as a number */
  m.n = 0;
  put_str(&m, "/VMC/Ext/Bone/Pos");
  put_str(&m, ",ifffffff");
  put_i(&m, 3);
  for (int k = 0; k < 7; ++k)
    put_f(&m, 0);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 1);
  m.n = 0;
  put_str(&m, "/VMC/Ext/Root/Pos");
  put_str(&m, ",sfff");
  put_str(&m, "root");
  for (int k = 0; k < 3; ++k)
    put_f(&m, 0);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 2);
  /* NaN and a zero quaternion */
  const float nanp[7] = {NAN, 0, 0, 0, 0, 0, 1}, zq[7] = {0, 0, 0, 0, 0, 0, 0};
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", nanp);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 3);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", zq);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 4);
  /* a tag string that does not match the payload */
  m.n = 0;
  put_str(&m, "/VMC/Ext/OK");
  put_str(&m, ",iiii");
  put_i(&m, 1);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 5);
  /* a blob, its size word cut off, never reaches liblo (live.h): bad on a bone's path */
  m.n = 0;
  put_str(&m, "/VMC/Ext/Bone/Pos");
  put_str(&m, ",sb");
  put_str(&m, "Hips");
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.bad == bad + 6);
  bad += 1;
  /* unknown addresses and bones are counted, not bad; a bundle of them makes no frame */
  uint64_t frames = v.frames;
  bundle_begin(&b);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Tail", p);
  bundle_add(&b, &m);
  m.n = 0;
  put_str(&m, "/VMC/Ext/Blend/Val");
  put_str(&m, ",sf");
  put_str(&m, "A");
  put_f(&m, 0.5f);
  bundle_add(&b, &m);
  CHECK(km_live_vmc_packet(&v, b.d, b.n, J) == 0);
  CHECK(v.unknown == 2 && v.bad == bad + 5 && v.frames == frames);
  /* unbundled senders: the frame ends at /VMC/Ext/OK */
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", p);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0);
  m.n = 0;
  put_str(&m, "/VMC/Ext/OK");
  put_str(&m, ",i");
  put_i(&m, 1);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 1 && v.frames == frames + 1);
  CHECK_NEAR(J[1], 1.0, 1e-6); /* HipCenter */
  /* Root/Pos with v2.1's scale and offset: extra arguments counted, the pose taken */
  m.n = 0;
  put_str(&m, "/VMC/Ext/Root/Pos");
  put_str(&m, ",sfffffffffffff");
  put_str(&m, "root");
  for (int k = 0; k < 13; ++k)
    put_f(&m, k == 6 || (k >= 7 && k < 10) ? 1.0f : 0.0f);
  CHECK(km_live_vmc_packet(&v, m.d, m.n, J) == 0 && v.extra_args == 1);
}

/* A raised LEFT arm as a Unity sender poses it: the upper arm turned -90 degrees about Unity's
 * z (its T-pose direction -x to +y). The wrist ends up above the shoulder on kinemesh's +x
 * side: the performer's left hand raises the mesh's left hand (Kinect WristLeft / HandLeft). */
static void test_raised_left_arm(void) {
  km_live_vmc v;
  km_live_vmc_init(&v);
  buf b, m;
  const float s = (float)sqrt(0.5);
  const float hips[7] = {0, 1, 0, 0, 0, 0, 1};
  const float upper[7] = {-0.2f, 0.4f, 0, 0, 0, -s, s};
  const float lower[7] = {-0.3f, 0, 0, 0, 0, 0, 1};
  const float hand[7] = {-0.25f, 0, 0, 0, 0, 0, 1};
  bundle_begin(&b);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "Hips", hips);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftUpperArm", upper);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftLowerArm", lower);
  bundle_add(&b, &m);
  pos_msg(&m, "/VMC/Ext/Bone/Pos", "LeftHand", hand);
  bundle_add(&b, &m);
  double J[60];
  CHECK(km_live_vmc_packet(&v, b.d, b.n, J) == 1);
  /* Kinect v1: ShoulderLeft 4, WristLeft 6, HandLeft 7 (from the wrist: no fingers sent) */
  CHECK_NEAR(J[3 * 4 + 0], 0.2, 1e-6);
  CHECK_NEAR(J[3 * 4 + 1], 1.4, 1e-6);
  CHECK_NEAR(J[3 * 6 + 0], 0.2, 1e-6);
  CHECK_NEAR(J[3 * 6 + 1], 1.95, 1e-6);
  CHECK_NEAR(J[3 * 6 + 2], 0.0, 1e-6);
  CHECK_NEAR(J[3 * 7 + 1], 1.95, 1e-6);
  CHECK(isnan(J[3 * 10]) && isnan(J[3 * 11])); /* nothing drives the right hand */
}

int main(void) {
  test_convention();
  test_raised_left_arm();
  test_bvh();
  test_garbage();
  return km_test_finish("test_live_vmc");
}
