/* kinemesh vmc send: replays any motion (take JSON, Kinect CSV, BVH) as VMC protocol bundles at
 * its frame rate, so a BVH drives VSeeFace / Warudo / kinemesh live --vmc. The joints are
 * matched to Unity's HumanBodyBones by body point (km_skeleton_joint_map), posed by
 * km_humanoid_pose_from_positions and sent through the live target's liblo sender. */
#include "cli.h"

#include "live.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static void sleep_until(double t) {
  double d = t - km_seconds();
  if (d <= 0) return;
  struct timespec ts = {(time_t)d, (long)((d - floor(d)) * 1e9)};
  nanosleep(&ts, NULL);
}

/* The take's frames as humanoid joint positions: hum (#frames * KM_HUMANOID_BONES * 3). */
static int to_humanoid(const km_take *t, const char *path, double **hum, int *kind_out) {
  int matched = 0;
  int kind = km_skeleton_detect((const char *const *)t->joint_names, t->n_joints, &matched);
  if (kind < 0)
    return km_cli_error("vmc",
                        "%s: no joint of a known skeleton (kinect1, kinect2, k4abt, "
                        "humanoid, mediapipe, bvh: see docs/skeletons.md)",
                        path);
  int col[KM_HUMANOID_BONES], used = 0;
  for (int b = 0; b < KM_HUMANOID_BONES; ++b) {
    const char *want = km_skeleton_joint_name(
        (km_skeleton_kind)kind,
        km_skeleton_joint_map(KM_SKELETON_HUMANOID, b, (km_skeleton_kind)kind));
    if (kind == KM_SKELETON_HUMANOID) want = km_skeleton_joint_name(KM_SKELETON_HUMANOID, b);
    col[b] = -1;
    for (size_t k = 0; want && k < t->n_joints; ++k)
      if (t->joint_names[k] && !strcmp(t->joint_names[k], want)) col[b] = (int)k;
    used += col[b] >= 0;
  }
  if (used < 2)
    return km_cli_error("vmc", "%s: only %d of its joints stand for humanoid bones", path, used);
  *hum = malloc(sizeof(double) * 3 * KM_HUMANOID_BONES * (t->n_frames ? t->n_frames : 1));
  if (!*hum) return km_cli_error("vmc", "out of memory");
  for (size_t f = 0; f < t->n_frames; ++f)
    for (int b = 0; b < KM_HUMANOID_BONES; ++b)
      for (int a = 0; a < 3; ++a)
        (*hum)[(f * KM_HUMANOID_BONES + (size_t)b) * 3 + a] =
            col[b] < 0 ? NAN : t->positions[(f * t->n_joints + (size_t)col[b]) * 3 + a];
  *kind_out = kind;
  return 0;
}

static int dump(const char *path, const double *hum, size_t n_frames, double fps) {
  char *names[KM_HUMANOID_BONES];
  for (int b = 0; b < KM_HUMANOID_BONES; ++b)
    names[b] = (char *)km_skeleton_joint_name(KM_SKELETON_HUMANOID, b);
  km_take d = {.n_frames = n_frames,
               .n_joints = KM_HUMANOID_BONES,
               .fps = fps,
               .joint_names = names,
               .positions = (double *)hum};
  km_error err = {0};
  if (km_take_write(path, &d, &err) != KM_OK) return km_cli_fail("vmc", &err);
  return 0;
}

static int vmc_send(int argc, char **argv) {
  const char *motion = NULL, *to = "127.0.0.1:39539", *dump_path = NULL;
  bool loop = false, dry = false;
  size_t start = 0, frames = 0;
  double fps = 0, hold = 0;
  const km_cli_opt opts[] = {
      {"motion", 0, KM_OPT_STRING, &motion, "motion to send: take .json, Kinect .csv or .bvh"},
      {"to", 0, KM_OPT_STRING, &to, "receiver HOST:PORT (default 127.0.0.1:39539)"},
      {"loop", 0, KM_OPT_FLAG, &loop, "send in a loop until interrupted"},
      {"start", 0, KM_OPT_SIZE, &start, "first frame (default 0)"},
      {"frames", 0, KM_OPT_SIZE, &frames, "frames to send (default: to the end)"},
      {"fps", 0, KM_OPT_DOUBLE, &fps, "send rate (default: the motion's frame rate)"},
      {"hold", 0, KM_OPT_DOUBLE, &hold, "then keep sending the last frame for this many seconds"},
      {"dump", 0, KM_OPT_STRING, &dump_path,
       "write the humanoid joint positions sent (kinemesh frame) as a take"},
      {"dry-run", 0, KM_OPT_FLAG, &dry, "do not send (with --dump: only write the take)"},
  };
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
                       "kinemesh vmc send --motion TAKE|BVH|CSV [--to HOST:PORT] [--loop] "
                       "[--start F] [--frames N] [--fps R] [--hold S] [--dump OUT.json]",
                       "Replays a motion as VMC protocol bundles (OSC over UDP), one per frame:\n"
                       "/VMC/Ext/OK, /VMC/Ext/T, /VMC/Ext/Root/Pos and /VMC/Ext/Bone/Pos with\n"
                       "Unity HumanBodyBones names, local (parent-relative) positions and\n"
                       "rotations in Unity's left-handed frame (docs/live.md).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!motion) return km_cli_error("vmc", "--motion is required (see --help)");
  if (fps < 0 || !isfinite(fps) || hold < 0 || !isfinite(hold))
    return km_cli_error("vmc", "--fps and --hold must be >= 0");
  km_error err = {0};
  km_take t = {0};
  double *hum = NULL;
  km_live_vmc_out *out = NULL;
  int rc = KM_EXIT_FAIL, kind = -1;
  if (km_motion_read(motion, NULL, &t, NULL, &err) != KM_OK) {
    rc = km_cli_fail("vmc", &err);
    goto done;
  }
  if (start >= t.n_frames) {
    rc = km_cli_error("vmc", "%s: --start %zu, the motion has %zu frames", motion, start,
                      t.n_frames);
    goto done;
  }
  if (!frames || frames > t.n_frames - start) frames = t.n_frames - start;
  if ((rc = to_humanoid(&t, motion, &hum, &kind))) goto done;
  rc = KM_EXIT_FAIL;
  if (!(fps > 0)) fps = t.fps > 0 ? t.fps : 30;
  if (dump_path && (rc = dump(dump_path, hum + start * 3 * KM_HUMANOID_BONES, frames, fps)))
    goto done;
  if (dry) {
    rc = KM_EXIT_OK;
    goto done;
  }
  if (km_live_vmc_out_open(to, &out, &err) != KM_OK) {
    rc = km_cli_fail("vmc", &err);
    goto done;
  }
  fprintf(stderr, "kinemesh vmc: %s (%s skeleton), frames %zu..%zu at %g fps -> %s%s\n", motion,
          km_skeleton_kind_name((km_skeleton_kind)kind), start, start + frames - 1, fps, to,
          loop ? " (loop)" : "");
  double t0 = km_seconds();
  size_t sent = 0, n_hold = (size_t)ceil(hold * fps);
  for (size_t k = 0;; ++k) {
    size_t f;
    if (k < frames) {
      f = start + k;
    } else if (loop) {
      f = start + k % frames;
    } else if (k < frames + n_hold) {
      f = start + frames - 1;
    } else {
      break;
    }
    km_humanoid_pose pose;
    if (km_humanoid_pose_from_positions(hum + f * 3 * KM_HUMANOID_BONES, &pose, &err) != KM_OK) {
      /* a frame without any joint: nothing to send */
      continue;
    }
    sleep_until(t0 + (double)k / fps);
    if (km_live_vmc_out_send(out, &pose, (double)k / fps, &err) != KM_OK) {
      rc = km_cli_fail("vmc", &err);
      goto done;
    }
    ++sent;
  }
  fprintf(stderr, "kinemesh vmc: sent %zu frames in %.2f s\n", sent, km_seconds() - t0);
  rc = KM_EXIT_OK;
done:
  km_live_vmc_out_free(&out);
  free(hum);
  km_take_free(&t);
  return rc;
}

int km_cli_vmc(int argc, char **argv) {
  if (argc >= 2 && !strcmp(argv[1], "send")) return vmc_send(argc - 1, argv + 1);
  if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
    printf("usage: kinemesh vmc send --motion TAKE|BVH|CSV [--to HOST:PORT] [--loop]\n"
           "  send: replay a motion as VMC protocol bundles (kinemesh vmc send --help)\n");
    return KM_EXIT_OK;
  }
  return km_cli_error("vmc", "expected a subcommand: send (see kinemesh vmc --help)");
}
