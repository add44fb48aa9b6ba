/* Kinect CSV and BVH readers: real recordings, hand-made files, malformed input. */
#include "km_test.h"
#include "motion/motion.h"

#include <unistd.h>

enum { HIP = 0, HEAD = 3, SHOULDER_L = 4, SHOULDER_R = 8, HAND_R = 11, FOOT_L = 15, FOOT_R = 19 };

static const double *J(const km_take *t, size_t f, size_t j) {
  return t->positions + (f * t->n_joints + j) * 3;
}

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  if (!f) {
    perror(path);
    exit(1);
  }
  fputs(text, f);
  fclose(f);
}

/* The error names the file and the line ("path:line:"). */
static bool names_line(const char *path, int line) {
  char want[600];
  snprintf(want, sizeof want, "%s:%d:", path, line);
  return strstr(km_test_err.message, want) != NULL;
}

/* ---------------------------------------------------------------- Kinect CSV */

static void test_csv_real(void) {
  static const struct {
    const char *file;
    size_t frames;
  } files[] = {{"skeleton/precog_Seq1_1.csv", 232},
               {"skeleton/precog_Seq2_1.csv", 147},
               {"skeleton/precog_Seq3_2.csv", 262}};
  for (size_t i = 0; i < 3; ++i) {
    char buf[1024];
    const char *path = km_test_shared(files[i].file, buf, sizeof buf);
    if (!path) continue;
    km_take t;
    int32_t *labels = NULL;
    CHECK_OK(km_kinect_csv_read(path, &t, &labels, KM_E));
    CHECK_MSG(t.n_frames == files[i].frames, "%s: %zu frames", files[i].file, t.n_frames);
    CHECK(t.n_joints == KM_KINECT1_JOINTS && t.fps == 30.0);
    CHECK(t.parents && t.parents[0] == -1 && t.parents[HEAD] == 2 && t.parents[FOOT_R] == 18);
    CHECK(strcmp(t.joint_names[HAND_R], "HandRight") == 0);
    size_t bad = 0, head_below = 0, left_not_plus_x = 0, not_in_front = 0;
    double hmin = INFINITY, hmax = -INFINITY;
    for (size_t f = 0; f < t.n_frames; ++f) {
      for (size_t j = 0; j < t.n_joints; ++j) {
        const double *p = J(&t, f, j);
        bool nan = isnan(p[0]) || isnan(p[1]) || isnan(p[2]);
        bool fin = isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
        if (nan) {
          /* missing means all three coordinates missing */
          bad += !(isnan(p[0]) && isnan(p[1]) && isnan(p[2]));
        } else {
          bad += !fin;
        }
      }
      const double *head = J(&t, f, HEAD), *hip = J(&t, f, HIP);
      head_below += !(head[1] > hip[1] + 0.3);
      /* Performer faces +z after the conversion, so their left is +x. */
      left_not_plus_x += !(J(&t, f, SHOULDER_L)[0] > J(&t, f, SHOULDER_R)[0]);
      /* The performer stands in front of the sensor, which is now behind them (z < 0). */
      not_in_front += !(hip[2] < -0.5);
      double h = head[1] - fmin(J(&t, f, FOOT_L)[1], J(&t, f, FOOT_R)[1]);
      hmin = fmin(hmin, h);
      hmax = fmax(hmax, h);
    }
    CHECK_MSG(bad == 0, "%s: %zu non-finite joints", files[i].file, bad);
    CHECK_MSG(head_below == 0, "%s: head not above hips in %zu frames", files[i].file, head_below);
    CHECK_MSG(left_not_plus_x == 0, "%s: %zu frames", files[i].file, left_not_plus_x);
    CHECK(not_in_front == 0);
    /* Head joint (centre of the head) to the lower foot: a standing adult. */
    CHECK_MSG(hmin > 1.2 && hmax < 2.2, "%s: height %g..%g", files[i].file, hmin, hmax);
    size_t label_bad = 0, label_nonzero = 0;
    for (size_t f = 0; f < t.n_frames; ++f) {
      label_bad += labels[f] < 0 || labels[f] > 8;
      label_nonzero += labels[f] != 0;
    }
    CHECK(label_bad == 0);
    CHECK(label_nonzero > 0 && label_nonzero < t.n_frames);
    free(labels);
    km_take_free(&t);
  }
}

static void test_csv_handmade(void) {
  const char *path = KM_TEST_DATA "/kinect_reordered.csv";
  km_take t;
  int32_t *labels = NULL;
  CHECK_OK(km_kinect_csv_read(path, &t, &labels, KM_E));
  CHECK(t.n_frames == 3 && t.n_joints == 20);
  /* Columns were in reverse order; joint j was written as camera (j+0.5+0.1f, 10+j, 2+0.01j). */
  size_t wrong = 0;
  for (size_t f = 0; f < 3; ++f)
    for (size_t j = 0; j < 20; ++j) {
      const double *p = J(&t, f, j);
      if (f == 1 && j == HAND_R) {
        wrong += !(isnan(p[0]) && isnan(p[1]) && isnan(p[2])); /* (0,0,0) = not tracked */
        continue;
      }
      wrong += fabs(p[0] + (j + 0.5 + 0.1 * f)) > 1e-12; /* x -> -x */
      wrong += p[1] != 10.0 + j;                         /* y kept */
      wrong += fabs(p[2] + (2 + 0.01 * j)) > 1e-12;      /* z -> -z */
    }
  CHECK_MSG(wrong == 0, "%zu wrong coordinates", wrong);
  CHECK(labels && labels[0] == 4 && labels[1] == 5 && labels[2] == 6);
  free(labels);
  km_take_free(&t);

  /* Without a label column and without the labels output. */
  const char *nolabel = "test_motion_io_nolabel.csv";
  char text[4096];
  int n = snprintf(text, sizeof text,
                   "HipCenter;Spine;ShoulderCenter;Head;ShoulderLeft;ElbowLeft;WristLeft;HandLeft;"
                   "ShoulderRight;ElbowRight;WristRight;HandRight;HipLeft;KneeLeft;AnkleLeft;"
                   "FootLeft;HipRight;KneeRight;AnkleRight;FootRight\n");
  for (int j = 0; j < 20; ++j)
    n += snprintf(text + n, sizeof text - n, "%s1 %d 3", j ? ";" : "", j);
  write_text(nolabel, text);
  CHECK_OK(km_kinect_csv_read(nolabel, &t, NULL, KM_E));
  CHECK(t.n_frames == 1 && J(&t, 0, 7)[1] == 7.0 && J(&t, 0, 7)[0] == -1.0);
  km_take_free(&t);
  remove(nolabel);
}

static void test_csv_malformed(void) {
  const char *hdr = "HipCenter;Spine;ShoulderCenter;Head;ShoulderLeft;ElbowLeft;WristLeft;HandLeft;"
                    "ShoulderRight;ElbowRight;WristRight;HandRight;HipLeft;KneeLeft;AnkleLeft;"
                    "FootLeft;HipRight;KneeRight;AnkleRight;FootRight\n";
  char good[1024] = "", *p = good;
  for (int j = 0; j < 20; ++j)
    p += sprintf(p, "%s0.1 0.2 %d", j ? ";" : "", j + 1);
  p += sprintf(p, ";3");
  char *line19 = strdup(good);
  *strrchr(line19, ';') = '\0'; /* drop the label: still valid */
  *strrchr(line19, ';') = '\0'; /* drop joint 20: invalid */

  struct {
    const char *name, *header, *l2, *l3, *expect;
    int line;
  } cases[] = {
      {"unknown joint name", "HipCenter;Spine;Hed;Head", NULL, NULL, "Hed", 1},
      {"19 joints", hdr, good, line19, "expected 20 joints", 3},
      {"two numbers", hdr, "1 2;", NULL, "expected 3 finite numbers", 2},
      {"not a number", hdr, good, "x 1 2", "expected 3", 3},
      {"bad label", hdr, NULL, NULL, "integer action label", 2},
      {"trailing text", hdr, NULL, NULL, "unexpected text", 2},
      {"duplicate joint", NULL, NULL, NULL, "twice", 1},
      {"empty file", "", NULL, NULL, "header", 1},
  };
  char bad_label[1200], trailing[1200], dup_header[1024];
  snprintf(bad_label, sizeof bad_label, "%s", good);
  strcpy(strrchr(bad_label, ';'), ";punch");
  snprintf(trailing, sizeof trailing, "%s 7", good);
  snprintf(dup_header, sizeof dup_header, "%s", hdr);
  memcpy(strstr(dup_header, "Spine"), "Head ", 5); /* "Head" replaces "Spine" */
  cases[4].l2 = bad_label;
  cases[5].l2 = trailing;
  cases[6].header = dup_header;
  const char *path = "test_motion_io_bad.csv";
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
    char text[4096];
    /* hdr already ends with a newline; l2 and l3 are frame lines 2 and 3. */
    snprintf(text, sizeof text, "%s%s%s%s", cases[i].header, cases[i].l2 ? cases[i].l2 : "",
             cases[i].l3 ? "\n" : "", cases[i].l3 ? cases[i].l3 : "");
    write_text(path, text);
    km_take t;
    CHECK_STATUS(km_kinect_csv_read(path, &t, NULL, KM_E), KM_ERR_PARSE);
    CHECK_MSG(names_line(path, cases[i].line), "%s: %s", cases[i].name, km_test_err.message);
    CHECK_MSG(strstr(km_test_err.message, cases[i].expect) != NULL, "%s: %s", cases[i].name,
              km_test_err.message);
  }
  remove(path);
  free(line19);

  km_take t;
  CHECK_STATUS(km_kinect_csv_read("no/such/file.csv", &t, NULL, KM_E), KM_ERR_IO);
  CHECK(strstr(km_test_err.message, "no/such/file.csv") != NULL);
}

/* ---------------------------------------------------------------- BVH */

static bool near3(const double *p, double x, double y, double z, double tol) {
  return fabs(p[0] - x) <= tol && fabs(p[1] - y) <= tol && fabs(p[2] - z) <= tol;
}

static void test_bvh_two_joint(void) {
  const char *path = KM_TEST_DATA "/bvh_two_joint.bvh";
  km_bvh_options opt = {.units_to_m = 1.0, .end_sites = true};
  km_take t;
  km_bvh_info info;
  CHECK_OK(km_bvh_read(path, &opt, &t, &info, KM_E));
  CHECK(t.n_frames == 3 && t.n_joints == 3);
  CHECK(fabs(t.fps - 30.0) < 1e-9);
  CHECK(info.n_channels == 9 && info.units_to_m == 1.0);
  CHECK(strcmp(t.joint_names[0], "A") == 0 && strcmp(t.joint_names[1], "B") == 0 &&
        strcmp(t.joint_names[2], "B_End") == 0);
  CHECK(t.parents[0] == -1 && t.parents[1] == 0 && t.parents[2] == 1);
  const double tol = 1e-12;
  /* Rest frame. */
  CHECK(near3(J(&t, 0, 1), 1, 0, 0, tol) && near3(J(&t, 0, 2), 1, 2, 0, tol));
  /* 90 degrees about Z moves the child from +x to +y; the root translation is absolute. */
  CHECK(near3(J(&t, 1, 0), 1, 2, 3, tol));
  CHECK_MSG(near3(J(&t, 1, 1), 1, 3, 3, tol), "%g %g %g", J(&t, 1, 1)[0], J(&t, 1, 1)[1],
            J(&t, 1, 1)[2]);
  CHECK(near3(J(&t, 1, 2), -1, 3, 3, tol));
  /* Root Z90 then X90 (intrinsic, R = Rz Rx): child at Rz Rx (1,0,0) = (0,1,0). The end site
   * (0,2,0) under B's X90 then the root: Rz Rx Rx (0,2,0) = (2,0,0) from B. */
  CHECK(near3(J(&t, 2, 1), 0, 1, 0, tol));
  CHECK_MSG(near3(J(&t, 2, 2), 2, 1, 0, tol), "%g %g %g", J(&t, 2, 2)[0], J(&t, 2, 2)[1],
            J(&t, 2, 2)[2]);
  km_take_free(&t);

  /* Default: end sites dropped. */
  CHECK_OK(km_bvh_read(path, NULL, &t, NULL, KM_E));
  CHECK(t.n_joints == 2);
  km_take_free(&t);

  /* Channel order matters and is honoured: the same angles listed X then Z give R = Rx Rz, so
   * the child lands at Rx (0,1,0) = (0,0,1); positions listed Z X Y still mean (x,y,z). */
  const char *alt = "test_motion_io_alt.bvh";
  write_text(alt, "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n"
                  " CHANNELS 6 Zposition Xposition Yposition Xrotation Zrotation Yrotation\n"
                  " JOINT B\n {\n  OFFSET 1 0 0\n  CHANNELS 3 Yrotation Zrotation Xrotation\n"
                  "  End Site\n  {\n   OFFSET 0 2 0\n  }\n }\n}\nMOTION\nFrames: 2\n"
                  "Frame Time: 0.01\n3 1 2 90 90 0 0 0 0\n0 0 0 0 0 0 90 90 0\n");
  CHECK_OK(km_bvh_read(alt, &opt, &t, &info, KM_E));
  CHECK(t.fps == 100.0);
  CHECK(near3(J(&t, 0, 0), 1, 2, 3, tol));
  CHECK_MSG(near3(J(&t, 0, 1), 1, 2, 4, tol), "%g %g %g", J(&t, 0, 1)[0], J(&t, 0, 1)[1],
            J(&t, 0, 1)[2]);
  /* B: Ry(90) Rz(90) applied to (0,2,0): Rz -> (-2,0,0), Ry -> (0,0,2). */
  CHECK_MSG(near3(J(&t, 1, 2), 1, 0, 2, tol), "%g %g %g", J(&t, 1, 2)[0], J(&t, 1, 2)[1],
            J(&t, 1, 2)[2]);
  km_take_free(&t);
  remove(alt);
}

static void test_bvh_malformed(void) {
  struct {
    const char *name, *text, *expect;
    int line;
  } cases[] = {
      {"no hierarchy", "MOTION\n", "HIERARCHY", 1},
      {"bad channel",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Qrotation Zrotation\n}\n",
       "channel name", 5},
      {"duplicate channel",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Xrotation\n}\n", "at most once",
       5},
      {"missing brace",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\nMOTION\nFrames: 1\n",
       "in a joint", 6},
      {"short frame",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
       "MOTION\nFrames: 2\nFrame Time: 0.1\n1 2 3\n1 2\n",
       "has 2 values", 11},
      {"truncated",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
       "MOTION\nFrames: 3\nFrame Time: 0.1\n1 2 3\n1 2 3\n",
       "file ends after 2", 12},
      {"huge frame count",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
       "MOTION\nFrames: 999999999999\nFrame Time: 0.1\n1 2 3\n",
       "bytes left", 8},
      {"bad number",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
       "MOTION\nFrames: 1\nFrame Time: 0.1\n1 2 abc\n",
       "expected a number", 10},
      {"offset", "HIERARCHY\nROOT A\n{\n OFFSET 0 zero 0\n}\n", "3 numbers after OFFSET", 4},
      {"zero frame time",
       "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\n"
       "Frame Time: 0\n1\n",
       "positive frame time", 9},
  };
  const char *path = "test_motion_io_bad.bvh";
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
    write_text(path, cases[i].text);
    km_take t;
    CHECK_STATUS(km_bvh_read(path, NULL, &t, NULL, KM_E), KM_ERR_PARSE);
    CHECK_MSG(names_line(path, cases[i].line), "%s: %s", cases[i].name, km_test_err.message);
    CHECK_MSG(strstr(km_test_err.message, cases[i].expect) != NULL, "%s: %s", cases[i].name,
              km_test_err.message);
  }
  /* Deep nesting is refused, not a stack overflow. */
  size_t cap = 300 * 40 + 200;
  char *deep = malloc(cap), *q = deep;
  q += sprintf(q, "HIERARCHY\nROOT J\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n");
  for (int d = 0; d < 300; ++d)
    q += sprintf(q, "JOINT J%d {\nOFFSET 0 1 0\n", d);
  write_text(path, deep);
  km_take t;
  CHECK_STATUS(km_bvh_read(path, NULL, &t, NULL, KM_E), KM_ERR_PARSE);
  CHECK(strstr(km_test_err.message, "nested") != NULL);
  free(deep);
  remove(path);
}

static void test_bvh_cmu(void) {
  char buf[1024];
  const char *path = km_test_shared("bvh/cmu_131_01.bvh", buf, sizeof buf);
  if (!path) return;
  km_take t;
  km_bvh_info info;
  km_bvh_options opt = {.units_to_m = KM_BVH_CMU_UNITS};
  CHECK_OK(km_bvh_read(path, &opt, &t, &info, KM_E));
  CHECK(t.n_frames == 994 && t.n_joints == 31 && t.fps == 120.0);
  CHECK(info.n_channels == 6 + 30 * 3);
  CHECK_MSG(info.rest_height > 1.2 && info.rest_height < 2.0, "rest height %g", info.rest_height);
  bool order_ok = true;
  for (size_t j = 0; j < t.n_joints; ++j)
    order_ok &= t.parents[j] < (int32_t)j;
  CHECK(order_ok && t.parents[0] == -1);
  int head = -1, hips = 0, ltoe = -1;
  for (size_t j = 0; j < t.n_joints; ++j) {
    if (strcmp(t.joint_names[j], "Head") == 0) head = (int)j;
    if (strcmp(t.joint_names[j], "LeftToe") == 0) ltoe = (int)j;
  }
  CHECK(head > 0 && ltoe > 0);
  /* Forward kinematics is rigid: every bone keeps its length in every frame. */
  double worst = 0;
  size_t head_low = 0;
  for (size_t f = 0; f < t.n_frames; ++f) {
    for (size_t j = 1; j < t.n_joints; ++j) {
      const double *a = J(&t, f, j), *b = J(&t, f, (size_t)t.parents[j]);
      const double *a0 = J(&t, 0, j), *b0 = J(&t, 0, (size_t)t.parents[j]);
      double l = sqrt(pow(a[0] - b[0], 2) + pow(a[1] - b[1], 2) + pow(a[2] - b[2], 2));
      double l0 = sqrt(pow(a0[0] - b0[0], 2) + pow(a0[1] - b0[1], 2) + pow(a0[2] - b0[2], 2));
      worst = fmax(worst, fabs(l - l0));
    }
    double dh = J(&t, f, (size_t)head)[1] - J(&t, f, (size_t)hips)[1];
    if (!(dh > 0.2) && head_low++ == 0) printf("frame %zu: head %g above hips\n", f, dh);
  }
  CHECK_MSG(worst < 1e-9, "bone length varies by %g m", worst);
  CHECK(head_low == 0);
  /* Hips of a standing/walking adult about a metre above the toes. */
  double hip_h = J(&t, 0, (size_t)hips)[1] - J(&t, 0, (size_t)ltoe)[1];
  CHECK_MSG(hip_h > 0.7 && hip_h < 1.2, "hip height %g", hip_h);
  km_take_free(&t);

  /* The rotation convention checked on real data: in this walk the lower toe tip stays near
   * the floor in every frame (reading the channels as extrinsic lifts it by 1.5 m). */
  opt.end_sites = true;
  CHECK_OK(km_bvh_read(path, &opt, &t, &info, KM_E));
  CHECK(t.n_joints == 31 + 7);
  int lt = -1, rt = -1, ltoe2 = -1;
  for (size_t j = 0; j < t.n_joints; ++j) {
    if (strcmp(t.joint_names[j], "LeftToe") == 0) ltoe2 = (int)j;
    if (strcmp(t.joint_names[j], "LeftToe_End") == 0) lt = (int)j;
    if (strcmp(t.joint_names[j], "RightToe_End") == 0) rt = (int)j;
  }
  CHECK(lt > 0 && rt > 0 && t.parents[lt] == ltoe2);
  double lo = INFINITY, hi = -INFINITY;
  for (size_t f = 0; f < t.n_frames && lt > 0 && rt > 0; ++f) {
    double y = fmin(J(&t, f, (size_t)lt)[1], J(&t, f, (size_t)rt)[1]);
    lo = fmin(lo, y);
    hi = fmax(hi, y);
  }
  CHECK_MSG(hi - lo < 0.15, "lowest toe between %g and %g m", lo, hi);
  km_take_free(&t);

  /* Auto units recognise the CMU skeleton. */
  CHECK_OK(km_bvh_read(path, NULL, &t, &info, KM_E));
  CHECK(info.units_to_m == KM_BVH_CMU_UNITS);
  km_take_free(&t);

  /* An unknown skeleton in unknown units is scaled to a 1.7 m rest height: rename the CMU
   * joints so the file no longer looks like CMU. */
  char *data = NULL;
  size_t size = 0;
  CHECK_OK(km__read_file(path, &data, &size, KM_E));
  for (char *q = data; (q = strstr(q, "HipJoint")) != NULL;)
    memcpy(q, "HipJoinX", 8);
  const char *renamed = "test_motion_io_renamed.bvh";
  FILE *f = fopen(renamed, "wb");
  fwrite(data, 1, size, f);
  fclose(f);
  free(data);
  CHECK_OK(km_bvh_read(renamed, NULL, &t, &info, KM_E));
  CHECK_NEAR(info.rest_height, 1.7, 1e-9);
  CHECK(t.n_frames == 994);
  remove(renamed);
  km_take_free(&t);
}

/* Issue 18: a take with an overflowing coordinate (1e999 parses as inf) is refused, naming the
 * frame and joint; null stays "missing". */
static void test_take_nonfinite(void) {
  const char *path = "test_motion_io_inf.json";
  write_text(path, "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\"],"
                   "\"frames\":[[0,0,0],[1e999,0,0]]}");
  km_take t;
  CHECK_STATUS(km_take_read(path, &t, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "frame 1") && strstr(km_test_err.message, "finite"), "%s",
            km_test_err.message);
  write_text(path, "{\"format\":\"kinemesh-take\",\"version\":1,\"fps\":30,\"joints\":[\"A\"],"
                   "\"frames\":[[0,0,0],[null,null,null]]}");
  CHECK_OK(km_take_read(path, &t, KM_E));
  CHECK(t.n_frames == 2 && isnan(t.positions[3]));
  km_take_free(&t);
  remove(path);
}

int main(void) {
  test_take_nonfinite();
  test_csv_real();
  test_csv_handmade();
  test_csv_malformed();
  test_bvh_two_joint();
  test_bvh_malformed();
  test_bvh_cmu();
  return km_test_finish("test_motion_io");
}
