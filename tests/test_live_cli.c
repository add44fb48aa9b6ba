/* `kinemesh bench live` through the CLI on a small generated character: the --json object
 * (its keys, frames that went through the whole path), --take and --rig, and the error for
 * a mesh without a rig; `live --units` against a sidecar in other units. Correctness only: no
 * speed is checked. */
#include "km_test.h"

#include <cjson/cJSON.h>

#define DIR "live_cli"

/* Runs cmd with stderr dropped and parses stdout, which must be one JSON object and nothing
 * else. */
static cJSON *run_json(const char *cmd) {
  char full[4096], *out = NULL;
  snprintf(full, sizeof full, "{ %s 2>/dev/null; }", cmd);
  int rc = km_test_run(full, &out);
  CHECK_MSG(rc == 0, "%s -> exit %d: %s", cmd, rc, out ? out : "");
  const char *end = NULL;
  cJSON *j = out ? cJSON_ParseWithOpts(out, &end, 0) : NULL;
  CHECK_MSG(cJSON_IsObject(j), "%s printed no JSON object: %s", cmd, out ? out : "(nothing)");
  if (j) {
    while (*end == ' ' || *end == '\n')
      ++end;
    CHECK_MSG(*end == '\0', "%s printed more than one JSON object: ...%s", cmd, end);
  }
  free(out);
  return j;
}

static double num(const cJSON *j, const char *k) {
  const cJSON *x = cJSON_GetObjectItemCaseSensitive(j, k);
  return cJSON_IsNumber(x) ? x->valuedouble : NAN;
}

/* The keys every run has; what was measured here must be a number (null is for runs where a
 * figure could not be measured, e.g. no frame arrived). */
static void check_bench(const cJSON *j, size_t n_ver, size_t frames, bool quantize,
                        const char *what) {
  if (!j) return;
  const char *keys[] = {"n_ver",
                        "frames",
                        "rate",
                        "latency_median_ms",
                        "latency_p99_ms",
                        "client_latency_median_ms",
                        "client_latency_p99_ms",
                        "retarget_ms",
                        "deform_ms",
                        "pack_ms",
                        "frames_received",
                        "fps"};
  for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k)
    CHECK_MSG(cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(j, keys[k])), "%s: key %s", what,
              keys[k]);
  const cJSON *q = cJSON_GetObjectItemCaseSensitive(j, "quantize");
  CHECK_MSG(cJSON_IsBool(q) && cJSON_IsTrue(q) == quantize, "%s: quantize", what);
  CHECK_MSG(num(j, "n_ver") == (double)n_ver, "%s: n_ver %g, the mesh has %zu", what,
            num(j, "n_ver"), n_ver);
  CHECK_MSG(num(j, "frames") == (double)frames, "%s: frames %g, sent %zu", what, num(j, "frames"),
            frames);
  double got = num(j, "frames_received");
  CHECK_MSG(got > 0 && got <= (double)frames, "%s: %g frames received of %zu", what, got, frames);
  CHECK_MSG(num(j, "fps") > 0, "%s: fps %g", what, num(j, "fps"));
  CHECK_MSG(
      num(j, "latency_median_ms") >= 0 && num(j, "latency_p99_ms") >= num(j, "latency_median_ms"),
      "%s: latency median %g, p99 %g", what, num(j, "latency_median_ms"), num(j, "latency_p99_ms"));
  CHECK_MSG(num(j, "solve_errors") == 0, "%s: solve errors %g", what, num(j, "solve_errors"));
}

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 -o " DIR "/c.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 60 --character " DIR "/c.obj -o " DIR
                           "/wave.json",
                    NULL) == 0);
  km_mesh m = {0};
  CHECK_OK(km_mesh_read(DIR "/c.obj", &m, KM_E));

  /* the rig sidecar and the generated kungfu take (the first run also precomputes) */
  cJSON *j = run_json(KM_CLI " bench live --mesh " DIR "/c.obj --frames 60 --json");
  check_bench(j, m.n_vertices, 60, false, "sidecar rig, generated take");
  const cJSON *take = cJSON_GetObjectItemCaseSensitive(j, "take");
  CHECK(cJSON_IsString(take) && strstr(take->valuestring, "kungfu"));
  cJSON_Delete(j);

  /* the libwebsockets client passes the server's Origin and token checks too (issue 18) */
  j = run_json(KM_CLI " bench live --mesh " DIR "/c.obj --frames 60 --lws-client --json");
  check_bench(j, m.n_vertices, 60, false, "--lws-client");
  cJSON_Delete(j);

  /* --take, --rig given for a mesh that has no sidecar, int16 frames */
  CHECK(km_test_run("cp " DIR "/c.obj " DIR "/bare.obj && cp " DIR "/c.rig.json " DIR "/r.json",
                    NULL) == 0);
  j = run_json(KM_CLI " bench live --mesh " DIR "/bare.obj --rig " DIR "/r.json --take " DIR
                      "/wave.json --frames 60 --quantize --json");
  check_bench(j, m.n_vertices, 60, true, "--take --rig --quantize");
  take = cJSON_GetObjectItemCaseSensitive(j, "take");
  CHECK(cJSON_IsString(take) && strstr(take->valuestring, "wave.json"));
  cJSON_Delete(j);

  /* a mesh with neither a sidecar nor --rig: the error names the file and says what to pass */
  int rc = km_test_run(KM_CLI " bench live --mesh " DIR "/bare.obj --frames 60 --json", &out);
  CHECK_MSG(rc == 1 && out && strstr(out, "bare.obj") && strstr(out, "--rig"), "exit %d: %s", rc,
            out ? out : "");
  free(out);
  /* a take that is not one */
  rc =
      km_test_run(KM_CLI " bench live --mesh " DIR "/c.obj --take " DIR "/c.rig.json --json", &out);
  CHECK_MSG(rc == 1 && out && strstr(out, "c.rig.json"), "exit %d: %s", rc, out ? out : "");
  free(out);
  /* `live --units cm` on a sidecar in the file's own units (no "frame" scale): refused
   * before any port is opened, saying why, not as overlapping handles */
  rc = km_test_run("timeout 30 " KM_CLI " live --mesh " DIR "/c.obj --units cm", &out);
  CHECK_MSG(rc == 1 && out && strstr(out, "c.rig.json") && strstr(out, "--units") &&
                !strstr(out, "overlap"),
            "exit %d: %s", rc, out ? out : "");
  free(out);
  /* --help documents the options and succeeds */
  rc = km_test_run(KM_CLI " bench live --help", &out);
  CHECK_MSG(rc == 0 && out && strstr(out, "--take") && strstr(out, "--rig") &&
                strstr(out, "--json"),
            "exit %d: %s", rc, out ? out : "");
  free(out);
  km_mesh_free(&m);
  return km_test_finish("test_live_cli");
}
