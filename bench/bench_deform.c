/* kinemesh bench deform: Table 1 of Wu, Lu & Song (precompute, load, per-frame stage times of
 * the reduced model, the full ARAP reference and the deviation between them). */
#include "bench.h"
#include "cli.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Farthest-point seeds over the vertices, then the `per` nearest untaken vertices of each. */
static void pick_handles(const km_mesh *m, size_t nh, size_t per, km_rig *rig) {
  size_t n = m->n_vertices;
  double *dist = malloc(n * sizeof *dist);
  unsigned char *taken = calloc(n, 1);
  double c[3] = {0, 0, 0};
  for (size_t v = 0; v < n; ++v)
    for (int k = 0; k < 3; ++k)
      c[k] += m->V[3 * v + k] / (double)n;
  size_t cur = 0;
  double best = -1;
  for (size_t v = 0; v < n; ++v) {
    const double *x = m->V + 3 * v;
    double d = (x[0] - c[0]) * (x[0] - c[0]) + (x[1] - c[1]) * (x[1] - c[1]) +
               (x[2] - c[2]) * (x[2] - c[2]);
    dist[v] = INFINITY;
    if (d > best) best = d, cur = v;
  }
  for (size_t h = 0; h < nh; ++h) {
    const double *s = m->V + 3 * cur;
    double *d2 = malloc(n * sizeof *d2);
    for (size_t v = 0; v < n; ++v) {
      const double *x = m->V + 3 * v;
      d2[v] = (x[0] - s[0]) * (x[0] - s[0]) + (x[1] - s[1]) * (x[1] - s[1]) +
              (x[2] - s[2]) * (x[2] - s[2]);
    }
    /* the `per` nearest untaken vertices, by insertion into a sorted window (per <= 200) */
    size_t got = 0;
    int32_t *sel = malloc(per * sizeof *sel);
    for (size_t v = 0; v < n; ++v) {
      if (taken[v]) continue;
      if (got < per) {
        size_t i = got++;
        while (i > 0 && d2[sel[i - 1]] > d2[v])
          sel[i] = sel[i - 1], --i;
        sel[i] = (int32_t)v;
      } else if (d2[v] < d2[sel[per - 1]]) {
        size_t i = per - 1;
        while (i > 0 && d2[sel[i - 1]] > d2[v])
          sel[i] = sel[i - 1], --i;
        sel[i] = (int32_t)v;
      }
    }
    /* handle vertex lists are sorted ascending in a km_rig */
    for (size_t i = 1; i < got; ++i) {
      int32_t x = sel[i];
      size_t j = i;
      while (j > 0 && sel[j - 1] > x)
        sel[j] = sel[j - 1], --j;
      sel[j] = x;
    }
    for (size_t i = 0; i < got; ++i)
      taken[sel[i]] = 1;
    snprintf(rig->handles[h].name, sizeof rig->handles[h].name, "h%zu", h);
    rig->handles[h].vertices = sel;
    rig->handles[h].n_vertices = got;
    free(d2);
    best = -1;
    for (size_t v = 0; v < n; ++v) {
      const double *x = m->V + 3 * v;
      double d = (x[0] - s[0]) * (x[0] - s[0]) + (x[1] - s[1]) * (x[1] - s[1]) +
                 (x[2] - s[2]) * (x[2] - s[2]);
      if (d < dist[v]) dist[v] = d;
      if (dist[v] > best) best = dist[v], cur = v;
    }
  }
  free(dist);
  free(taken);
}

/* Synthetic performer: joint j oscillates smoothly around a base position with an amplitude of
 * 12% of the character's diagonal, each joint on its own direction and phase. */
static void joints_at(size_t f, double diag, double *J) {
  double w = 2 * M_PI / 60.0;
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    double amp =
        0.12 * diag * sin(w * (double)f + 0.9 * j) * (0.5 + 0.5 * sin(0.37 * w * (double)f));
    double dir[3] = {cos(1.7 * j), sin(1.7 * j), cos(2.9 * j)};
    double l = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    for (int k = 0; k < 3; ++k)
      J[3 * j + k] = 0.1 * j + amp * dir[k] / l;
  }
}

typedef struct deform_args {
  size_t handles, frames, full_frames, repeat;
  km_puppet_options po;
  bool json, header;
} deform_args;

/* One mesh: one row (or one JSON object). */
static int bench_deform_one(const char *mesh_path, const deform_args *da) {
  size_t handles = da->handles, frames = da->frames, full_frames = da->full_frames,
         repeat = da->repeat;
  bool json = da->json;
  km_puppet_options po = da->po;
  km_error err = {0};
  km_mesh m = {0};
  km_rig rig = {0};
  km_puppetry *pl = NULL;
  km_arap *arap = NULL;
  double *t1 = NULL, *t1c = NULL, *t23 = NULL, *t4 = NULL, *tf = NULL;
  double *V = NULL, *Vf = NULL, J[KM_KINECT1_JOINTS * 3];
  int rc = KM_EXIT_FAIL;
  char cache[64];
  snprintf(cache, sizeof cache, "/tmp/kinemesh-bench-%ld.kmcache", (long)getpid());

  if (km_bench_mesh(mesh_path, &m, NULL, &err) != KM_OK) goto fail;
  if (!repeat) repeat = m.n_vertices > 200000 ? 1 : 3;
  double diag = km_bbox_diagonal(m.V, m.n_vertices);
  size_t per = m.n_vertices / 400;
  per = per < 30 ? 30 : per > 200 ? 200 : per;
  if (handles * per > m.n_vertices / 2) {
    rc = km_cli_error("bench deform", "%zu handles of %zu vertices do not fit a %zu-vertex mesh",
                      handles, per, m.n_vertices);
    goto done;
  }
  rig.skeleton = KM_RIG_KINECT1;
  rig.handles = calloc(handles, sizeof *rig.handles);
  rig.maps = calloc(handles, sizeof *rig.maps);
  if (!rig.handles || !rig.maps) goto nomem;
  rig.n_handles = handles;
  pick_handles(&m, handles, per, &rig);
  for (size_t h = 1; h < handles; ++h) { /* handle 0 is an anchor */
    rig.maps[rig.n_maps].handle = (int32_t)h;
    rig.maps[rig.n_maps].joint = (int32_t)((h - 1) % KM_KINECT1_JOINTS);
    rig.maps[rig.n_maps].axes = KM_AXIS_X | KM_AXIS_Y | KM_AXIS_Z;
    rig.maps[rig.n_maps].scale = 1.0;
    rig.n_maps++;
  }
  t1 = malloc(repeat * sizeof *t1);
  t1c = malloc(5 * sizeof *t1c);
  t23 = malloc(frames * sizeof *t23);
  t4 = malloc(frames * sizeof *t4);
  tf = malloc((full_frames ? full_frames : 1) * sizeof *tf);
  V = malloc(3 * m.n_vertices * sizeof *V);
  Vf = malloc(3 * m.n_vertices * sizeof *Vf);
  if (!t1 || !t1c || !t23 || !t4 || !tf || !V || !Vf) goto nomem;

  /* t1: precompute from scratch (--force); t~1: load from the cache (what a second run
   * does). The pipeline's model time excludes the cache write and the handle set-up. */
  km_puppetry_options o = {0};
  o.puppet = po;
  o.retarget.scale = 1.0;
  o.cache_path = cache;
  km_puppetry_info pi;
  for (size_t i = 0; i < repeat + 5; ++i) {
    km_puppetry_free(&pl);
    o.force = i < repeat;
    if (km_puppetry_create(&m, &rig, NULL, KM_KINECT1_JOINTS, &o, &pl, &pi, &err) != KM_OK)
      goto fail;
    if (pi.save.status != KM_OK) {
      err = pi.save;
      goto fail;
    }
    if (i < repeat)
      t1[i] = pi.model_seconds;
    else
      t1c[i - repeat] = pi.model_seconds;
  }
  remove(cache);
  size_t n_h = 0;
  const int32_t *off = NULL, *hv = NULL;
  km_puppetry_handles(pl, &n_h, &off, &hv);
  if (full_frames && km_arap_precompute(&m, n_h, off, hv, NULL, &arap, &err) != KM_OK) goto fail;

  double dev_sum = 0, dev_max = 0;
  size_t dev_n = 0;
  for (size_t f = 0; f < frames; ++f) {
    joints_at(f, diag, J);
    if (km_puppetry_push(pl, J, V, &err) != KM_OK) goto fail;
    km_puppetry_times tm;
    km_puppetry_times_get(pl, &tm);
    t23[f] = tm.filter_ms + tm.retarget_ms;
    t4[f] = tm.solve_ms;
    if (f < full_frames) {
      double d = km_cli_now();
      if (km_arap_solve(arap, km_puppetry_vertex_targets(pl), Vf, &err) != KM_OK) goto fail;
      tf[f] = 1e3 * (km_cli_now() - d) + t23[f];
      for (size_t v = 0; v < m.n_vertices; ++v) {
        double dx = V[3 * v] - Vf[3 * v], dy = V[3 * v + 1] - Vf[3 * v + 1],
               dz = V[3 * v + 2] - Vf[3 * v + 2];
        double e = sqrt(dx * dx + dy * dy + dz * dz) / diag;
        dev_sum += e;
        if (e > dev_max) dev_max = e;
      }
      dev_n += m.n_vertices;
    }
  }
  km_puppet_info info;
  km_puppetry_puppet_info(pl, &info);
  double mt1 = km_cli_median(t1, repeat), mt1c = km_cli_median(t1c, 5);
  double m23 = km_cli_median(t23, frames), m4 = km_cli_median(t4, frames);
  double mf = full_frames ? km_cli_median(tf, full_frames) : NAN;
  double dmean = dev_n ? dev_sum / (double)dev_n : NAN, dmax = dev_n ? dev_max : NAN;
  if (json) {
    cJSON *o = cJSON_CreateObject();
    char machine[320];
    km_bench_machine(machine, sizeof machine);
    cJSON_AddStringToObject(o, "mesh", mesh_path);
    cJSON_AddStringToObject(o, "machine", machine);
    cJSON_AddStringToObject(o, "energy", po.energy == KM_PUPPET_ENERGY_ARAP ? "arap" : "laplacian");
    cJSON_AddNumberToObject(o, "n_ver", (double)m.n_vertices);
    cJSON_AddNumberToObject(o, "n_han", (double)handles);
    cJSON_AddNumberToObject(o, "n_tri", (double)info.crossed_triangles);
    cJSON_AddNumberToObject(o, "t1_s", mt1);
    cJSON_AddNumberToObject(o, "t1_cached_s", mt1c);
    cJSON_AddNumberToObject(o, "t23_ms", m23);
    cJSON_AddNumberToObject(o, "t4_ms", m4);
    cJSON_AddNumberToObject(o, "tper_ms", m23 + m4);
    /* NaN (null) when --full-frames 0 skipped the reference */
    km_cli_json_number(o, "full_tper_ms", mf);
    km_cli_json_number(o, "dev_mean_rel", dmean);
    km_cli_json_number(o, "dev_max_rel", dmax);
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (s) puts(s);
    free(s);
  } else {
    if (da->header) {
      char machine[320];
      km_bench_machine(machine, sizeof machine);
      printf("kinemesh bench deform — %s; %s energy; medians: t1 of %zu runs (1 above 200k "
             "vertices unless --repeat), t~1 of 5 loads, per-frame times of %zu frames (%d "
             "rotation updates each), full ARAP on %zu frames\n",
             machine, po.energy == KM_PUPPET_ENERGY_ARAP ? "reduced ARAP" : "paper (Laplacian)",
             repeat, frames, info.last_iterations, full_frames);
      printf("%-28s %8s %5s %5s %8s %8s %6s %9s %8s %9s %11s %9s %9s\n", "model", "n_ver", "n_han",
             "n_tri", "t1(s)", "t~1(s)", "P(%)", "t2,3(ms)", "t4(ms)", "tper(ms)", "full tper",
             "dev mean", "dev max");
    }
    const char *base = strrchr(mesh_path, '/');
    printf("%-28.28s %8zu %5zu %5zu %8.3f %8.4f %6.2f %9.4f %8.3f %9.3f %11.2f %8.3f%% %8.3f%%\n",
           base ? base + 1 : mesh_path, m.n_vertices, handles, info.crossed_triangles, mt1, mt1c,
           100 * mt1c / mt1, m23, m4, m23 + m4, mf, 100 * dmean, 100 * dmax);
  }
  rc = KM_EXIT_OK;
  goto done;
nomem:
  rc = km_cli_error("bench deform", "out of memory");
  goto done;
fail:
  rc = km_cli_fail("bench deform", &err);
done:
  remove(cache);
  km_puppetry_free(&pl);
  km_arap_free(&arap);
  km_rig_free(&rig);
  km_mesh_free(&m);
  free(t1);
  free(t1c);
  free(t23);
  free(t4);
  free(tf);
  free(V);
  free(Vf);
  return rc;
}

int km_bench_deform(int argc, char **argv) {
  const char *mesh_path = NULL, *energy = NULL;
  deform_args da = {5, 100, 30, 0, {0}, false, true};
  const km_cli_opt opts[] = {
      {"mesh", 0, KM_OPT_STRING, &mesh_path,
       "mesh file, or character:N (procedural, N vertices); more meshes may follow as "
       "arguments, one row each"},
      {"handles", 0, KM_OPT_SIZE, &da.handles,
       "number of handles (default 5; handle 0 is an anchor)"},
      {"frames", 0, KM_OPT_SIZE, &da.frames, "frames of synthetic performer motion (default 100)"},
      {"full-frames", 0, KM_OPT_SIZE, &da.full_frames,
       "frames also solved by the full ARAP reference (default 30; 0: skip)"},
      {"repeat", 0, KM_OPT_SIZE, &da.repeat,
       "runs of precompute / cache load (default 3, 1 above 200k vertices)"},
      {"energy", 0, KM_OPT_STRING, &energy,
       "reduced model energy: arap (default) or laplacian (the paper's)"},
      {"json", 0, KM_OPT_FLAG, &da.json, "print one JSON object per mesh, one per line"},
  };
  enum { MAX_MESHES = 32 };
  const char *pos[MAX_MESHES];
  int n_pos;
  int r = km_cli_parse(
      argc, argv, opts, sizeof opts / sizeof opts[0], pos, MAX_MESHES - 1, &n_pos,
      "kinemesh bench deform --mesh MESH [MESH ...] [--handles N] [--frames F] [--json]",
      "Reproduces Table 1 of Wu, Lu & Song: precompute t1, cache load t~1, their\n"
      "ratio P, filter + retarget t2,3 and deformation t4 per frame (full-resolution\n"
      "output included), t_per = t2,3 + t4; medians. Also the full ARAP solver per\n"
      "frame and the reduced model's deviation from it (fraction of the bbox diagonal).");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (mesh_path) {
    memmove(pos + 1, pos, sizeof *pos * (size_t)n_pos);
    pos[0] = mesh_path;
    ++n_pos;
  }
  if (!n_pos) return km_cli_error("bench deform", "--mesh is required");
  if (da.handles < 2) return km_cli_error("bench deform", "--handles must be at least 2");
  if (da.frames < 1) return km_cli_error("bench deform", "--frames must be at least 1");
  if (da.full_frames > da.frames) da.full_frames = da.frames;
  if (km_cli_parse_energy("bench deform", energy, &da.po.energy)) return KM_EXIT_FAIL;
  int rc = KM_EXIT_OK;
  for (int i = 0; i < n_pos; ++i) {
    da.header = i == 0;
    int ri = bench_deform_one(pos[i], &da);
    if (ri != KM_EXIT_OK) rc = ri;
    fflush(stdout);
  }
  return rc;
}
