/* Edge-graph Dijkstra (km__geodesic, mesh.h). Hand-written: the graph is the mesh's own CSR
 * adjacency and the runs must not allocate (km_transfer_solve promises that); a library
 * (igraph, boost) would want its own graph copy and allocate per call. Exact geodesics
 * (heat method, MMP) were not needed: callers want sizes and neighbourhoods. */
#include "core/core.h"
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct km__geodesic {
  size_t n;
  int32_t *ptr, *adj; /* CSR, one entry per face edge (a neighbour may repeat) */
  double *dist;       /* INFINITY where untouched */
  int32_t *hp, *hpos; /* heap of vertices; position in it, -1 outside, -2 settled */
  int32_t *touched;   /* vertices given a finite distance in the last run, in order */
  size_t n_touched;
  unsigned char *stop; /* marks of the stop set during a run */
};

void km__geodesic_free(km__geodesic **gp) {
  if (!gp || !*gp) return;
  km__geodesic *g = *gp;
  free(g->ptr);
  free(g->adj);
  free(g->dist);
  free(g->hp);
  free(g->hpos);
  free(g->touched);
  free(g->stop);
  free(g);
  *gp = NULL;
}

km_status km__geodesic_create(const km_mesh *m, km__geodesic **out, km_error *err) {
  *out = NULL;
  size_t n = m->n_vertices, nf = m->n_faces;
  km__geodesic *g = calloc(1, sizeof *g);
  if (!g) return km__fail(err, KM_ERR_NOMEM, "geodesics: out of memory");
  g->n = n;
  g->ptr = km__calloc(n + 1, sizeof *g->ptr);
  g->adj = km__malloc(nf ? nf : 1, 6 * sizeof *g->adj);
  g->dist = km__malloc(n ? n : 1, sizeof *g->dist);
  g->hp = km__malloc(n ? n : 1, sizeof *g->hp);
  g->hpos = km__malloc(n ? n : 1, sizeof *g->hpos);
  g->touched = km__malloc(n ? n : 1, sizeof *g->touched);
  g->stop = km__calloc(n ? n : 1, 1);
  int32_t *fill = km__malloc(n + 1, sizeof *fill);
  if (!g->ptr || !g->adj || !g->dist || !g->hp || !g->hpos || !g->touched || !g->stop || !fill) {
    free(fill);
    km__geodesic_free(&g);
    return km__fail(err, KM_ERR_NOMEM, "geodesics: out of memory (%zu vertices)", n);
  }
  /* Copies of a vertex (the same position: a mesh split at its texture seams) are joined by
   * an edge of length 0 to the next copy, so a distance crosses the seam as the surface does:
   * a handle grown round a vertex near a glTF's seam covers both sides. */
  km__weld wd;
  int32_t *next = km__malloc(n ? n : 1, sizeof *next);
  if (!next || km__mesh_weld(m, &wd, NULL) != KM_OK) {
    free(next), free(fill);
    km__geodesic_free(&g);
    return km__fail(err, KM_ERR_NOMEM, "geodesics: out of memory (%zu vertices)", n);
  }
  size_t n_links = 0;
  for (size_t v = 0; v < n; ++v)
    next[v] = -1;
  if (wd.to_w) { /* chain each class: first[c] becomes its latest member */
    for (size_t v = 0; v < n; ++v) {
      int32_t c = wd.to_w[v], *last = wd.first + c;
      if (*last != (int32_t)v) next[*last] = (int32_t)v, *last = (int32_t)v, ++n_links;
    }
  }
  km__weld_free(&wd);
  if (n_links) {
    int32_t *adj = realloc(g->adj, (6 * nf + 2 * n_links) * sizeof *g->adj);
    if (!adj) {
      free(next), free(fill);
      km__geodesic_free(&g);
      return km__fail(err, KM_ERR_NOMEM, "geodesics: out of memory (%zu vertices)", n);
    }
    g->adj = adj;
  }
  for (size_t v = 0; v < n; ++v)
    if (next[v] >= 0) g->ptr[v + 1] += 1, g->ptr[next[v] + 1] += 1;
  for (size_t f = 0; f < nf; ++f) /* a collapsed face: no surface to cross */
    for (int k = 0; k < 3 && !km__face_collapsed(m->F + 3 * f); ++k)
      g->ptr[m->F[3 * f + k] + 1] += 2;
  for (size_t v = 0; v < n; ++v)
    g->ptr[v + 1] += g->ptr[v];
  memcpy(fill, g->ptr, (n + 1) * sizeof *fill);
  for (size_t f = 0; f < nf; ++f) {
    const int32_t *t = m->F + 3 * f;
    for (int k = 0; k < 3 && !km__face_collapsed(t); ++k) {
      int32_t a = t[k], b = t[(k + 1) % 3];
      g->adj[fill[a]++] = b;
      g->adj[fill[b]++] = a;
    }
  }
  for (size_t v = 0; v < n; ++v)
    if (next[v] >= 0) {
      g->adj[fill[v]++] = next[v];
      g->adj[fill[next[v]]++] = (int32_t)v;
    }
  free(next);
  free(fill);
  for (size_t v = 0; v < n; ++v)
    g->dist[v] = INFINITY, g->hpos[v] = -1;
  *out = g;
  return KM_OK;
}

const double *km__geodesic_run(km__geodesic *g, const double *V, int32_t seed, double radius,
                               const int32_t *stop, size_t n_stop, const int32_t **reached,
                               size_t *n_reached) {
  return km__geodesic_run_set(g, V, &seed, 1, radius, stop, n_stop, reached, n_reached);
}

const double *km__geodesic_run_set(km__geodesic *g, const double *V, const int32_t *seeds,
                                   size_t n_seeds, double radius, const int32_t *stop,
                                   size_t n_stop, const int32_t **reached, size_t *n_reached) {
  for (size_t i = 0; i < g->n_touched; ++i) { /* undo the last run */
    int32_t v = g->touched[i];
    g->dist[v] = INFINITY, g->hpos[v] = -1;
  }
  g->n_touched = 0;
  size_t left = 0, hn = 0;
  for (size_t k = 0; k < n_stop; ++k)
    if (!g->stop[stop[k]]) g->stop[stop[k]] = 1, ++left;
  int32_t *hp = g->hp, *hpos = g->hpos;
  double *dist = g->dist;
  for (size_t k = 0; k < n_seeds; ++k) { /* every seed at 0: a heap of equal keys */
    int32_t seed = seeds[k];
    if (dist[seed] == 0) continue;
    dist[seed] = 0;
    hpos[seed] = (int32_t)hn;
    hp[hn++] = seed;
    g->touched[g->n_touched++] = seed;
  }
  while (hn > 0 && (n_stop == 0 || left > 0)) {
    int32_t u = hp[0];
    hpos[u] = -2; /* settled */
    hp[0] = hp[--hn];
    if (hn) hpos[hp[0]] = 0;
    for (size_t i = 0;;) { /* sift down */
      size_t l = 2 * i + 1, r = l + 1, m = i;
      if (l < hn && dist[hp[l]] < dist[hp[m]]) m = l;
      if (r < hn && dist[hp[r]] < dist[hp[m]]) m = r;
      if (m == i) break;
      int32_t a = hp[i];
      hp[i] = hp[m], hp[m] = a;
      hpos[hp[i]] = (int32_t)i, hpos[hp[m]] = (int32_t)m;
      i = m;
    }
    if (g->stop[u]) --left;
    const double *pu = V + 3 * (size_t)u;
    for (int32_t q = g->ptr[u]; q < g->ptr[u + 1]; ++q) {
      int32_t w = g->adj[q];
      if (hpos[w] == -2) continue;
      const double *pw = V + 3 * (size_t)w;
      double d =
          dist[u] + sqrt((pw[0] - pu[0]) * (pw[0] - pu[0]) + (pw[1] - pu[1]) * (pw[1] - pu[1]) +
                         (pw[2] - pu[2]) * (pw[2] - pu[2]));
      if (!(d <= radius) || !(d < dist[w])) continue;
      if (dist[w] == INFINITY) g->touched[g->n_touched++] = w;
      dist[w] = d;
      size_t i = hpos[w] < 0 ? hn++ : (size_t)hpos[w];
      hp[i] = w;
      while (i > 0) { /* sift up */
        size_t p = (i - 1) / 2;
        if (!(dist[hp[p]] > dist[hp[i]])) break;
        int32_t a = hp[i];
        hp[i] = hp[p], hp[p] = a;
        hpos[hp[i]] = (int32_t)i;
        i = p;
      }
      hpos[hp[i]] = (int32_t)i;
    }
  }
  for (size_t k = 0; k < n_stop; ++k)
    g->stop[stop[k]] = 0;
  if (reached) *reached = g->touched;
  if (n_reached) *n_reached = g->n_touched;
  return dist;
}
