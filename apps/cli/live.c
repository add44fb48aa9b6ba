/* kinemesh live: tracker (OSC / JSON over UDP / a replayed take) -> deforming mesh streamed
 * to browser pages over WebSocket, with the mapping panel. The server is src/live/. */
#include "cli.h"

#include "live.h"

#include <cjson/cJSON.h>

#include <errno.h>
#include <libgen.h>
#include <math.h>
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static km_live *volatile g_live;

static void on_signal(int sig) {
  (void)sig;
  if (g_live) km_live_stop(g_live);
}

/* The page beside the binary (build/kinemesh -> build/web), else where `cmake --install` puts
 * it (P/bin/kinemesh -> P/share/kinemesh/web). */
/* A rig for a mesh that has none: a skinned glTF's own skin, else km_autorig (what it chose
 * is printed). Nothing is written: the page's "save rig" writes rig_file. */
static km_status auto_rig(const char *mesh_path, const km_mesh *m, const char *rig_file,
                          char **json, size_t *size, km_error *err) {
  km_character c = {0};
  bool own = false;
  km_status s = km_cli_skin_character("live", mesh_path, NULL, &c, &own, err);
  if (s != KM_OK) return s;
  *json = NULL;
  if (!own &&
      (s = km_cli_auto_rig("live", mesh_path, rig_file, m, stdout,
                           "\"save rig\" in the page writes it", &c, json, size, err)) != KM_OK)
    return s;
  if (!*json) s = km_character_rig_json(&c, json, size, err);
  km_character_free(&c);
  return s;
}

/* `--no-handles`: the rig text without its puppetry part ("handles", "map"); the rest (skeleton,
 * skin, landmarks, filter) stays, so saving the first handle keeps them. */
static int strip_handles(const char *rig_file, char **text, size_t *size) {
  cJSON *doc = cJSON_ParseWithLength(*text, *size);
  if (!cJSON_IsObject(doc)) {
    cJSON_Delete(doc);
    return km_cli_error("live", "%s: expected a JSON object (a rig)", rig_file);
  }
  cJSON_DeleteItemFromObjectCaseSensitive(doc, "map");
  cJSON_DeleteItemFromObjectCaseSensitive(doc, "handles");
  char *out = cJSON_AddArrayToObject(doc, "handles") ? cJSON_Print(doc) : NULL;
  cJSON_Delete(doc);
  if (!out) return km_cli_error("live", "out of memory");
  free(*text);
  *text = out;
  *size = strlen(out);
  return KM_EXIT_OK;
}

static char *default_web_dir(void) {
  char exe[PATH_MAX];
  ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n <= 0) return NULL;
  exe[n] = 0;
  char *dir = dirname(exe);
  size_t len = strlen(dir) + 64;
  char *out = malloc(len);
  if (!out) return NULL;
  snprintf(out, len, "%s/web/index.html", dir);
  if (access(out, R_OK) == 0) {
    snprintf(out, len, "%s/web", dir);
    return out;
  }
  snprintf(out, len, "%s/../share/kinemesh/web/index.html", dir);
  if (access(out, R_OK) == 0) {
    snprintf(out, len, "%s/../share/kinemesh/web", dir);
    return out;
  }
  snprintf(out, len, "%s/web", dir); /* reported as missing there */
  return out;
}

/* `--vmc` takes an optional port: a bare `--vmc` (last, or before another option or a
 * non-number) means the protocol's receiver port. Returns a new argv (caller frees the array,
 * not the strings) with the default inserted. */
#define KM_VMC_DEFAULT_PORT "39539"
static char **vmc_default_port(int argc, char **argv, int *out_argc) {
  char **a = malloc(sizeof(char *) * (size_t)(2 * argc + 1));
  int n = 0;
  if (!a) return NULL;
  for (int i = 0; i < argc; ++i) {
    a[n++] = argv[i];
    if (!strcmp(argv[i], "--vmc")) {
      const char *next = i + 1 < argc ? argv[i + 1] : NULL;
      bool number = next && *next && strspn(next, "0123456789") == strlen(next);
      if (!number) a[n++] = (char *)KM_VMC_DEFAULT_PORT;
    }
  }
  a[n] = NULL;
  *out_argc = n;
  return a;
}

int km_cli_live(int argc, char **argv) {
  const char *mesh_path = NULL, *rig_path = NULL, *replay = NULL, *record = NULL;
  const char *bind = "127.0.0.1", *web = NULL, *cache = NULL, *token = NULL, *vmc_out = NULL;
  int osc = 0, udp = 0, vmc = 0, http = 8080;
  bool quantize = false, loop = false, no_autoplay = false, no_token = false, no_handles = false;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      KM_CLI_FRAME_OPTIONS(fo),
      KM_CLI_MOTION_FRAME_OPTIONS(fo),
      {"mesh", 0, KM_OPT_STRING, &mesh_path, "mesh to animate (OBJ/PLY/OFF/STL/glTF)"},
      {"rig", 0, KM_OPT_STRING, &rig_path,
       "rig: handles, joint map, filter (default <mesh stem>.rig.json; when the file does not "
       "exist: a glTF's own skin or an automatic rig, written there by the page's save); "
       "POST /rig rewrites it"},
      {"no-handles", 0, KM_OPT_FLAG, &no_handles,
       "start with zero handles (the rig's skeleton, skin and landmarks kept): place the first "
       "one in the page by clicking; nothing moves until it is saved"},
      {"osc", 0, KM_OPT_INT, &osc, "OSC port (OSCeleton /joint, KinectV2-OSC /bodies/...)"},
      {"udp", 0, KM_OPT_INT, &udp, "JSON-over-UDP port (one frame per datagram)"},
      {"vmc", 0, KM_OPT_INT, &vmc,
       "VMC protocol port (XR Animator, VSeeFace, SlimeVR, ...; bare --vmc: " KM_VMC_DEFAULT_PORT
       ")"},
      {"vmc-out", 0, KM_OPT_STRING, &vmc_out,
       "send the filtered skeleton of every frame as VMC bundles to HOST:PORT"},
      {"replay", 0, KM_OPT_STRING, &replay, "take to replay (.json/.csv/.bvh with Kinect names)"},
      {"loop", 0, KM_OPT_FLAG, &loop, "replay in a loop"},
      {"no-autoplay", 0, KM_OPT_FLAG, &no_autoplay,
       "do not start the replay at start-up (the page's replay button starts it)"},
      {"http", 0, KM_OPT_INT, &http, "HTTP/WebSocket port (default 8080)"},
      {"bind", 0, KM_OPT_STRING, &bind,
       "listen address (default 127.0.0.1; off loopback the token is required)"},
      {"token", 0, KM_OPT_STRING, &token,
       "secret the page and clients must send (?token=; default: a random one per run)"},
      {"no-token", 0, KM_OPT_FLAG, &no_token,
       "no token for POSTs and the WebSocket (loopback only; Host and Origin still checked)"},
      {"record", 0, KM_OPT_STRING, &record, "write the received raw joints as a take on exit"},
      {"quantize", 0, KM_OPT_FLAG, &quantize,
       "send positions as int16 quantised to the frame's bounding box (half the bytes)"},
      {"web", 0, KM_OPT_STRING, &web, "page directory (default: web/ beside the binary)"},
      {"cache", 0, KM_OPT_STRING, &cache,
       "reduced-model cache (default: $XDG_CACHE_HOME/kinemesh/<mesh hash>.kmcache)"},
  };
  const char *pos[1];
  int n_pos;
  int vargc = 0;
  char **vargv = vmc_default_port(argc, argv, &vargc);
  if (!vargv) return km_cli_error("live", "out of memory");
  int r = km_cli_parse(
      vargc, vargv, opts, sizeof opts / sizeof opts[0], pos, 0, &n_pos,
      "kinemesh live --mesh MESH [--rig RIG] [--osc 7110] [--udp 9000] [--vmc [39539]] "
      "[--replay TAKE] "
      "[--http 8080] [--record OUT.json] [--bind 127.0.0.1] [--quantize]",
      "Live puppetry: tracker frames are smoothed, retargeted and the mesh deformed by the\n"
      "cached reduced model; every connected page gets the newest frame over WebSocket\n"
      "(older frames are dropped, never queued). Open the printed URL for the view and the\n"
      "mapping panel. GET /status reports counters and per-stage times.");
  free(vargv); /* the options point into argv's strings (or the static default) */
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (!mesh_path) return km_cli_error("live", "--mesh is required (see --help)");
  if (http <= 0 || http > 65535 || osc < 0 || osc > 65535 || udp < 0 || udp > 65535 || vmc < 0 ||
      vmc > 65535)
    return km_cli_error("live", "ports must be in 1..65535");

  km_error err = {0};
  km_mesh m = {0};
  km_take take = {0};
  km_puppet *pup = NULL;
  km_live *live = NULL;
  char *rig_text = NULL;
  size_t rig_size = 0;
  char *rig_default = rig_path ? NULL : km_cli_rig_path(mesh_path);
  char *cache_default = NULL;
  char *web_default = web ? NULL : default_web_dir();
  const char *rig_file = rig_path ? rig_path : rig_default;
  int rc = KM_EXIT_FAIL;

  if (km_mesh_read(mesh_path, &m, &err) != KM_OK) goto fail;
  fo.rig = rig_path; /* the frame its sidecar records (the default one when not given) */
  if ((rc = km_cli_orient_mesh("live", mesh_path, &fo, &m))) goto done;
  rc = KM_EXIT_FAIL;
  if (!cache && !(cache_default = km_cli_cache_path(&m))) {
    rc = km_cli_error("live", "out of memory");
    goto done;
  }
  FILE *f = fopen(rig_file, "rb");
  if (!f && errno == ENOENT) { /* no rig yet: the glTF's own skin, else an automatic one */
    if (auto_rig(mesh_path, &m, rig_file, &rig_text, &rig_size, &err) != KM_OK) goto fail;
    goto rig_ready;
  }
  if (!f) {
    rc = km_cli_error("live", "cannot read the rig %s", rig_file);
    goto done;
  }
  {
    /* The sidecar's radii and joints are in the unit its "frame" records; the server resolves
     * the rig on the mesh as oriented, so another --units would make every ball 100x too wide
     * (or narrow). Said plainly rather than as overlapping handles. */
    km_frame mf;
    double rs = km_cli_sidecar_scale(mesh_path, rig_path);
    if (km_cli_mesh_frame("live", mesh_path, &fo, &m, true, &mf, NULL) == 0 &&
        fabs((mf.scale > 0 ? mf.scale : 1) / rs - 1) > 1e-12) {
      fclose(f);
      char unit[64] = "the mesh file's units (no \"frame\" scale)";
      if (rs != 1) snprintf(unit, sizeof unit, "%g m per unit", rs);
      rc = km_cli_error("live",
                        "%s holds its handle radii and joints in %s, but --units says %s: run "
                        "live without --units, or rig the mesh again with those --units",
                        rig_file, unit, fo.units ? fo.units : "m");
      goto done;
    }
  }
  fseek(f, 0, SEEK_END);
  long sz = ftell(f);
  fseek(f, 0, SEEK_SET);
  rig_text = sz >= 0 ? malloc((size_t)sz + 1) : NULL;
  if (!rig_text || fread(rig_text, 1, (size_t)sz, f) != (size_t)sz) {
    fclose(f);
    rc = km_cli_error("live", "cannot read the rig %s", rig_file);
    goto done;
  }
  fclose(f);
  rig_size = (size_t)sz;
  rig_text[rig_size] = 0;
rig_ready:;
  if (no_handles && (rc = strip_handles(rig_file, &rig_text, &rig_size))) goto done;
  rc = KM_EXIT_FAIL;
  km_motion_read_options mo = {0};
  mo.kinect1 = true;
  if (replay && km_motion_read(replay, &mo, &take, NULL, &err) != KM_OK) goto fail;
  if ((rc = km_cli_orient_take("live", &fo, &take))) goto done;
  rc = KM_EXIT_FAIL;
  km_puppetry_info pi;
  if (km_cli_puppet_open(&m, cache ? cache : cache_default, &pup, &pi, &err) != KM_OK) goto fail;

  km_live_options lo = {0};
  lo.bind = bind;
  lo.http_port = http;
  lo.osc_port = osc;
  lo.udp_port = udp;
  lo.vmc_port = vmc;
  lo.vmc_out = vmc_out;
  lo.quantize = quantize;
  lo.loop = loop;
  lo.no_autoplay = no_autoplay;
  lo.web_dir = web ? web : web_default;
  lo.rig_path = rig_file;
  lo.record = record != NULL;
  lo.token = token;
  lo.no_token = no_token;
  if (km_live_create(&lo, &m, pup, rig_text, rig_size, replay ? &take : NULL, &live, &err) != KM_OK)
    goto fail;
  g_live = live;
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  signal(SIGPIPE, SIG_IGN);
  const char *tok = km_live_token(live);
  printf("kinemesh live: %zu vertices (model %s in %.2f s); open http://%s:%d/%s%s\n", m.n_vertices,
         pi.model == KM_PUPPETRY_MODEL_LOADED ? "loaded" : "precomputed", pi.model_seconds, bind,
         http, *tok ? "?token=" : "", tok);
  if (osc) printf("  OSC (OSCeleton /joint, KinectV2-OSC /bodies/...) on udp %s:%d\n", bind, osc);
  if (udp) printf("  JSON frames on udp %s:%d\n", bind, udp);
  if (vmc_out) printf("  VMC out: the filtered skeleton -> udp %s\n", vmc_out);
  if (vmc) printf("  VMC (/VMC/Ext/Root/Pos, /VMC/Ext/Bone/Pos) on udp %s:%d\n", bind, vmc);
  if (replay) printf("  replay: %s (%zu frames at %g fps)\n", replay, take.n_frames, take.fps);
  fflush(stdout);
  km_status s = km_live_run(live, &err);
  g_live = NULL;
  km_live_stats st;
  km_live_get_stats(live, &st);
  fprintf(stderr,
          "kinemesh live: %llu frames in, %llu out, %llu sent, %llu bad packets; latency "
          "median %.2f ms, p99 %.2f ms\n",
          (unsigned long long)st.frames_in, (unsigned long long)st.frames_out,
          (unsigned long long)st.frames_sent, (unsigned long long)st.bad_packets, st.lat_median_ms,
          st.lat_p99_ms);
  if (s != KM_OK) goto fail;
  if (record) {
    if (km_live_record_take(live, record, &err) != KM_OK) goto fail;
    fprintf(stderr, "kinemesh live: recorded %llu frames -> %s\n", (unsigned long long)st.frames_in,
            record);
  }
  rc = KM_EXIT_OK;
  goto done;
fail:
  rc = km_cli_fail("live", &err);
done:
  g_live = NULL;
  km_live_free(&live);
  km_puppet_free(&pup);
  km_take_free(&take);
  km_mesh_free(&m);
  free(rig_text);
  free(rig_default);
  free(cache_default);
  free(web_default);
  return rc;
}
