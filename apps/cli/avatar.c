/* kinemesh avatar: motion generation (Lifkooee et al. 2019): every k frames of a track the
 * pose is recognised in a database, retrieved and transferred to the avatar; the frames
 * between are morphed.
 *   kinemesh avatar --source S --db DB --track TRACK -o ANIM   (or AVATAR DB TRACK) */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct avatar_sink {
  km_anim_writer *w;
  km_progress prog;
  size_t frames;
} avatar_sink;

static km_status push_frame(size_t frame, const double *V, void *user, km_error *err) {
  avatar_sink *s = user;
  km_status st = km_anim_writer_push(s->w, V, err);
  if (s->prog.fn) s->prog.fn((double)(frame + 1) / (double)s->frames, "avatar", s->prog.user);
  return st;
}

int km_cli_avatar(int argc, char **argv) {
  const char *out = NULL, *lm_path = NULL, *source = NULL, *dbp = NULL, *track = NULL;
  size_t key_every = 1;
  double scale = 0, max_error_mm = 0;
  bool compress = false;
  const char *export_kind = NULL;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_EXPORT_OPTIONS(export_kind, max_error_mm, compress),
      KM_CLI_FRAME_OPTIONS(fo),
      {"source", 's', KM_OPT_STRING, &source, "the avatar mesh (same connectivity as the DB)"},
      {"db", 0, KM_OPT_STRING, &dbp, "pose database (kinemesh posedb build)"},
      {"track", 0, KM_OPT_STRING, &track, "tracked landmark positions (.json/.csv)"},
      {"interval", 0, KM_OPT_SIZE, &key_every, "same as --key-every"},
      {"output", 'o', KM_OPT_STRING, &out, "output animation (.glb, .pc2, or a directory)"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path,
       "LM.json with the avatar's landmark vertices (default: AVATAR's rig sidecar)"},
      {"key-every", 'k', KM_OPT_SIZE, &key_every,
       "recognise + transfer every k-th frame, interpolate between (default 1)"},
      {"scale", 0, KM_OPT_DOUBLE, &scale,
       "avatar size / tracked body size (default: estimated at the first key frame)"},
  };
  const char *pos[3];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 3, &n_pos,
                       "kinemesh avatar --source S --db DB --track TRACK -o OUT.glb [--interval K]",
                       "Drives AVATAR (same connectivity as DB's templates) from a TRACK of\n"
                       "landmark positions: key poses are recognised in DB and transferred, the\n"
                       "frames in between interpolated; one output frame per track frame.\n"
                       "AVATAR is brought into kinemesh's frame (y up, facing +z, metres), the\n"
                       "frame of tracks, by --up/--forward/--units, else its rig sidecar's\n"
                       "\"frame\", else a guess (printed); OUT is in kinemesh's frame.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (source && n_pos < 3) pos[n_pos++] = source;
  if (dbp && n_pos < 3) pos[n_pos++] = dbp;
  if (track && n_pos < 3) pos[n_pos++] = track;
  if (n_pos != 3) return km_cli_error("avatar", "expected --source S, --db DB and --track TRACK");
  if (!out) return km_cli_error("avatar", "-o OUTPUT is required");
  km_error err = {0};
  km_mesh avatar = {0};
  km_posedb *db = NULL;
  km_track t = {0};
  km_transfer *tr = NULL;
  avatar_sink sink = {0};
  int rc = KM_EXIT_OK;
  km_landmark lm[KM_POSE_MAX_LANDMARKS];
  size_t nl = 0;
  int32_t ids[KM_POSE_MAX_LANDMARKS];
  if (km_mesh_read(pos[0], &avatar, &err) || km_posedb_load(pos[1], &db, &err) ||
      km_track_read(pos[2], &t, &err) ||
      km_cli_load_landmarks(lm_path, pos[0], avatar.n_vertices, lm, KM_POSE_MAX_LANDMARKS, &nl,
                            &err)) {
    rc = km_cli_fail("avatar", &err);
    goto done;
  }
  if ((rc = km_cli_orient_mesh("avatar", pos[0], &fo, &avatar))) goto done;
  /* The avatar's landmark vertices in the database's landmark order, by name. */
  size_t dnl = km_posedb_landmark_count(db);
  const km_landmark *dlm = km_posedb_landmarks(db);
  for (size_t a = 0; a < dnl; ++a) {
    ids[a] = -1;
    for (size_t b = 0; b < nl; ++b)
      if (!strcmp(lm[b].name, dlm[a].name)) ids[a] = lm[b].vertex;
    if (ids[a] < 0) {
      rc = km_cli_error("avatar", "the avatar has no landmark '%s' (the database's)", dlm[a].name);
      goto done;
    }
  }
  double t0 = km_cli_now();
  km_anim_options ao = {0};
  ao.fps = t.fps;
  km_ssdr_options so;
  if (km_cli_parse_export("avatar", export_kind, max_error_mm, compress, out, &ao, &so)) {
    rc = KM_EXIT_FAIL;
    goto done;
  }
  km_anim_report rep = {0};
  km_avatar_options vo = {0};
  vo.key_every = key_every;
  vo.track_scale = scale;
  km_avatar_stats st;
  sink.prog = km_cli_progress("avatar");
  sink.frames = t.n_frames;
  if (km_transfer_precompute(&avatar, ids, dnl, NULL, &tr, &err) ||
      km_anim_writer_open(out, &avatar, &ao, &sink.w, &err) ||
      km_avatar_animate(tr, db, &t, &vo, push_frame, &sink, &st, &err) ||
      km_anim_writer_finish(&sink.w, &rep, &err)) {
    km_cli_progress_done();
    rc = km_cli_fail("avatar", &err);
    goto done;
  }
  km_cli_progress_done();
  fprintf(stderr,
          "kinemesh avatar: %zu frames, %zu key poses (recognition %.3f ms, transfer %.2f ms, "
          "%.1f iterations each; slowest key frame %.2f ms) in %.2f s -> %s\n",
          st.frames, st.key_frames, st.key_frames ? st.recognition_ms / st.key_frames : 0.0,
          st.key_frames ? st.transfer_ms / st.key_frames : 0.0, st.iterations_mean, st.max_frame_ms,
          km_cli_now() - t0, out);
  km_cli_report_export("avatar", &rep);
done:
  km_anim_writer_free(&sink.w);
  km_transfer_free(&tr);
  km_posedb_free(&db);
  km_track_free(&t);
  km_mesh_free(&avatar);
  return rc;
}
