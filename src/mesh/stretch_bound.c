/* Stretch bound (km_stretch_bound_*): the edge stretch that vertex sets held at targets force on
 * a mesh, whatever the solver does between them. Written here because it is a measure of this
 * project's own (issue 12's benchmark asks whether a rig's handle targets let the mesh stay
 * under 1.5x); the one Dijkstra of the library (km__geodesic) gives the rest path lengths. */
#include "core/core.h"
#include "mesh/mesh.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct km_stretch_bound {
  size_t n_pairs;
  int32_t *pairs; /* n_pairs*2: indices into the targets (the sets' vertex list) */
  int32_t *ids;   /* n_pairs*2: the same two vertices' ids in the mesh */
  double *len0;   /* n_pairs: the shortest rest path along edges between them */
};

void km_stretch_bound_free(km_stretch_bound **pb) {
  if (!pb || !*pb) return;
  free((*pb)->pairs);
  free((*pb)->ids);
  free((*pb)->len0);
  free(*pb);
  *pb = NULL;
}

size_t km_stretch_bound_pairs(const km_stretch_bound *b) { return b ? b->n_pairs : 0; }

/* A set's boundary vertices (a face neighbour outside the set), up to k spread evenly over
 * them in the list's order, as indices into the vertex list; their count. */
static size_t sample_boundary(const int32_t *verts, int32_t lo, int32_t hi,
                              const unsigned char *edge_of, size_t k, int32_t *out) {
  size_t nb = 0;
  for (int32_t i = lo; i < hi; ++i)
    nb += edge_of[verts[i]];
  size_t taken = 0, seen = 0;
  for (int32_t i = lo; i < hi && taken < k; ++i) {
    if (!edge_of[verts[i]]) continue;
    /* the seen-th of nb boundary vertices is taken when it starts a new k-th of them */
    if (nb <= k || (seen * k) / nb != ((seen + 1) * k) / nb) out[taken++] = i;
    ++seen;
  }
  return taken;
}

/* ---- the pairs cached in a file: "KMSBOUND", u32 version, u64 key, u64 n_pairs, then pairs
 * (2n int32), ids (2n int32) and len0 (n float64), little-endian as this machine writes them
 * (a file from a machine of the other order fails the key and is rebuilt). */
#define SB_MAGIC "KMSBOUND"
#define SB_VERSION 1u

static uint64_t cache_key(const km_mesh *rest, size_t n_sets, const int32_t *offsets,
                          const int32_t *vertices, const km_stretch_bound_options *o) {
  uint64_t h = km_mesh_hash(rest), ns = n_sets, nt = n_sets ? (uint64_t)offsets[n_sets] : 0;
  uint32_t v = SB_VERSION;
  h = km__fnv1a(h, &v, sizeof v);
  h = km__fnv1a(h, &ns, sizeof ns);
  if (n_sets) {
    h = km__fnv1a(h, offsets, (n_sets + 1) * sizeof *offsets);
    h = km__fnv1a(h, vertices, nt * sizeof *vertices);
  }
  h = km__fnv1a(h, &o->radius, sizeof o->radius);
  return km__fnv1a(h, &o->samples, sizeof o->samples);
}

/* The pairs from path when it holds them for key, each index checked against nt targets and n
 * vertices; NULL otherwise (no file, another key, short or damaged). */
static km_stretch_bound *cache_read(const char *path, uint64_t key, size_t nt, size_t n) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char magic[8];
  uint32_t ver = 0;
  uint64_t k = 0, np = 0;
  km_stretch_bound *b = NULL;
  long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  rewind(f);
  bool ok = size >= 28 && fread(magic, 1, 8, f) == 8 && !memcmp(magic, SB_MAGIC, 8) &&
            fread(&ver, sizeof ver, 1, f) == 1 && ver == SB_VERSION &&
            fread(&k, sizeof k, 1, f) == 1 && k == key && fread(&np, sizeof np, 1, f) == 1 &&
            np <= (uint64_t)nt * nt && (uint64_t)size == 28 + 24 * np &&
            (b = calloc(1, sizeof *b)) != NULL;
  if (ok) {
    b->n_pairs = (size_t)np;
    b->pairs = km__malloc(np ? 2 * np : 2, sizeof *b->pairs);
    b->ids = km__malloc(np ? 2 * np : 2, sizeof *b->ids);
    b->len0 = km__malloc(np ? np : 1, sizeof *b->len0);
    ok = b->pairs && b->ids && b->len0 && fread(b->pairs, sizeof *b->pairs, 2 * np, f) == 2 * np &&
         fread(b->ids, sizeof *b->ids, 2 * np, f) == 2 * np &&
         fread(b->len0, sizeof *b->len0, np, f) == np && fgetc(f) == EOF;
    for (size_t i = 0; ok && i < 2 * np; ++i)
      ok = b->pairs[i] >= 0 && (size_t)b->pairs[i] < nt && b->ids[i] >= 0 && (size_t)b->ids[i] < n;
    for (size_t i = 0; ok && i < np; ++i)
      ok = b->len0[i] > 0 && isfinite(b->len0[i]);
  }
  fclose(f);
  if (!ok) km_stretch_bound_free(&b);
  return b;
}

static void cache_write(const char *path, uint64_t key, const km_stretch_bound *b) {
  km__atomic_file af;
  km_error e = {0};
  uint32_t ver = SB_VERSION;
  uint64_t np = b->n_pairs;
  if (km__atomic_open(&af, path, &e) == KM_OK) {
    fwrite(SB_MAGIC, 1, 8, af.f);
    fwrite(&ver, sizeof ver, 1, af.f);
    fwrite(&key, sizeof key, 1, af.f);
    fwrite(&np, sizeof np, 1, af.f);
    fwrite(b->pairs, sizeof *b->pairs, 2 * np, af.f);
    fwrite(b->ids, sizeof *b->ids, 2 * np, af.f);
    fwrite(b->len0, sizeof *b->len0, np, af.f);
    km__atomic_commit(&af, &e);
  }
  if (e.message[0]) km__log(KM_LOG_WARN, "stretch bound: cache not written: %s", e.message);
}

km_status km_stretch_bound_create(const km_mesh *rest, size_t n_sets, const int32_t *offsets,
                                  const int32_t *vertices, const km_stretch_bound_options *opt,
                                  km_stretch_bound **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_stretch_bound_create: out is NULL");
  *out = NULL;
  if (!rest || !rest->V || (!rest->F && rest->n_faces) || (n_sets && (!offsets || !vertices)))
    return km__fail(err, KM_ERR_INVALID, "km_stretch_bound_create: NULL mesh or sets");
  km_stretch_bound_options o = {0};
  if (opt) o = *opt;
  if (!(o.radius > 0)) o.radius = 0.1;
  if (o.samples <= 0) o.samples = 48;
  size_t n = rest->n_vertices, nt = n_sets ? (size_t)offsets[n_sets] : 0;
  for (size_t i = 0; i < nt; ++i)
    if (vertices[i] < 0 || (size_t)vertices[i] >= n)
      return km__fail(err, KM_ERR_INVALID,
                      "km_stretch_bound_create: set vertex %d out of range (%zu vertices)",
                      (int)vertices[i], n);
  uint64_t key = o.cache_path ? cache_key(rest, n_sets, offsets, vertices, &o) : 0;
  if (o.cache_path && (*out = cache_read(o.cache_path, key, nt, n)) != NULL) return KM_OK;
  km_stretch_bound *b = calloc(1, sizeof *b);
  int32_t *set_of = malloc((n ? n : 1) * sizeof *set_of); /* vertex -> set, -1 none */
  int32_t *idx_of = malloc((n ? n : 1) * sizeof *idx_of); /* vertex -> index in vertices */
  unsigned char *edge_of = calloc(n ? n : 1, 1);          /* on its set's boundary */
  int32_t *samp = malloc((n_sets * (size_t)o.samples + 1) * sizeof *samp);
  size_t *samp_off = malloc((n_sets + 1) * sizeof *samp_off);
  unsigned char *is_samp = calloc(nt ? nt : 1, 1);
  km_status st = KM_OK;
  if (!b || !set_of || !idx_of || !edge_of || !samp || !samp_off || !is_samp) {
    st = km__fail(err, KM_ERR_NOMEM, "stretch bound: out of memory");
    goto done;
  }
  for (size_t v = 0; v < n; ++v)
    set_of[v] = -1, idx_of[v] = -1;
  for (size_t h = 0; h < n_sets; ++h)
    for (int32_t i = offsets[h]; i < offsets[h + 1]; ++i)
      set_of[vertices[i]] = (int32_t)h, idx_of[vertices[i]] = i;
  for (size_t f = 0; f < rest->n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t a = rest->F[3 * f + k], c = rest->F[3 * f + (k + 1) % 3];
      if (a < 0 || c < 0 || (size_t)a >= n || (size_t)c >= n) continue;
      if (set_of[a] >= 0 && set_of[a] != set_of[c]) edge_of[a] = 1;
      if (set_of[c] >= 0 && set_of[c] != set_of[a]) edge_of[c] = 1;
    }
  samp_off[0] = 0;
  for (size_t h = 0; h < n_sets; ++h) {
    size_t k = sample_boundary(vertices, offsets[h], offsets[h + 1], edge_of, (size_t)o.samples,
                               samp + samp_off[h]);
    samp_off[h + 1] = samp_off[h] + k;
  }
  for (size_t s = 0; s < samp_off[n_sets]; ++s)
    is_samp[samp[s]] = 1;
  /* One bounded Dijkstra per sampled boundary vertex (48 per set: 900 runs for a 19-handle
   * rig, each over ~10 % of the mesh: 0.9 s of a 100k-vertex `animate`'s 1.9 s start-up on
   * one core), run on the cores there are: each thread its own km__geodesic, each sample its
   * own list of pairs, gathered in sample order so the result does not depend on the threads. */
  size_t ns = samp_off[n_sets];
  int32_t *samp_set = km__malloc(ns ? ns : 1, sizeof *samp_set);
  size_t *sp_n = km__calloc(ns ? ns : 1, sizeof *sp_n);
  int32_t **sp_v = km__calloc(ns ? ns : 1, sizeof *sp_v);
  double **sp_d = km__calloc(ns ? ns : 1, sizeof *sp_d);
  if (!samp_set || !sp_n || !sp_v || !sp_d) {
    st = km__fail(err, KM_ERR_NOMEM, "stretch bound: out of memory");
    goto gather;
  }
  for (size_t h = 0; h < n_sets; ++h)
    for (size_t k = samp_off[h]; k < samp_off[h + 1]; ++k)
      samp_set[k] = (int32_t)h;
  double radius = o.radius * km_bbox_diagonal(rest->V, n);
  bool failed = false;
#ifdef _OPENMP
#pragma omp parallel if (ns > 16 && n > 5000)
#endif
  {
    km__geodesic *gt = NULL;
    bool ok = km__geodesic_create(rest, &gt, NULL) == KM_OK;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 4)
#endif
    for (ptrdiff_t si = 0; si < (ptrdiff_t)ns; ++si) {
      size_t k = (size_t)si;
      int32_t h = samp_set[k];
      if (!ok) continue;
      const int32_t *reached = NULL;
      size_t nr = 0, m = 0;
      const double *d =
          km__geodesic_run(gt, rest->V, vertices[samp[k]], radius, NULL, 0, &reached, &nr);
      /* each pair once: from the set with the lower index; sampled ends only */
#define KM_SB_KEEP(v) (set_of[v] > h && is_samp[idx_of[v]] && d[v] > 0 && isfinite(d[v]))
      for (size_t r = 0; r < nr; ++r)
        m += KM_SB_KEEP(reached[r]);
      if (!m) continue;
      sp_v[k] = km__malloc(m, sizeof(int32_t));
      sp_d[k] = km__malloc(m, sizeof(double));
      if (!sp_v[k] || !sp_d[k]) {
        ok = false;
        continue;
      }
      for (size_t r = 0; r < nr; ++r) {
        int32_t v = reached[r];
        if (!KM_SB_KEEP(v)) continue;
        sp_v[k][sp_n[k]] = v;
        sp_d[k][sp_n[k]++] = d[v];
      }
#undef KM_SB_KEEP
    }
    km__geodesic_free(&gt);
    if (!ok) {
#ifdef _OPENMP
#pragma omp atomic write
#endif
      failed = true;
    }
  }
  if (failed) {
    st = km__fail(err, KM_ERR_NOMEM, "stretch bound: out of memory");
    goto gather;
  }
  size_t total = 0;
  for (size_t k = 0; k < ns; ++k)
    total += sp_n[k];
  b->pairs = km__malloc(total ? 2 * total : 2, sizeof *b->pairs);
  b->ids = km__malloc(total ? 2 * total : 2, sizeof *b->ids);
  b->len0 = km__malloc(total ? total : 1, sizeof *b->len0);
  if (!b->pairs || !b->ids || !b->len0) {
    st = km__fail(err, KM_ERR_NOMEM, "stretch bound: out of memory");
    goto gather;
  }
  for (size_t k = 0; k < ns; ++k)
    for (size_t r = 0; r < sp_n[k]; ++r) {
      int32_t v = sp_v[k][r];
      b->pairs[2 * b->n_pairs] = samp[k];
      b->pairs[2 * b->n_pairs + 1] = idx_of[v];
      b->ids[2 * b->n_pairs] = vertices[samp[k]];
      b->ids[2 * b->n_pairs + 1] = v;
      b->len0[b->n_pairs++] = sp_d[k][r];
    }
gather:
  for (size_t k = 0; sp_v && sp_d && k < ns; ++k)
    free(sp_v[k]), free(sp_d[k]);
  free(samp_set), free(sp_n), free(sp_v), free(sp_d);
done:
  free(set_of), free(idx_of), free(edge_of), free(samp), free(samp_off), free(is_samp);
  if (st != KM_OK) {
    km_stretch_bound_free(&b);
    return st;
  }
  if (o.cache_path) cache_write(o.cache_path, key, b);
  *out = b;
  return KM_OK;
}

double km_stretch_bound_eval(const km_stretch_bound *b, const double *targets, int32_t pair[2]) {
  double best = 0;
  if (pair) pair[0] = pair[1] = -1;
  for (size_t p = 0; b && targets && p < b->n_pairs; ++p) {
    const double *x = targets + 3 * (size_t)b->pairs[2 * p],
                 *y = targets + 3 * (size_t)b->pairs[2 * p + 1];
    double d = sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                    (x[2] - y[2]) * (x[2] - y[2])) /
               b->len0[p];
    if (d > best) { /* NaN (a target not known) is skipped */
      best = d;
      if (pair) pair[0] = b->ids[2 * p], pair[1] = b->ids[2 * p + 1];
    }
  }
  return best;
}
