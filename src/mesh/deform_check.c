/* Deformation check (km_deform_check_*): edge length ratios, folded triangles and one-frame
 * steps of an animation against its rest mesh. Written here because no maintained library
 * measures a deformation this way; the measures are `bench motion`'s (issue 12), which uses
 * this module, as `animate` does for its summary line. */
#include "core/core.h"
#include "math/math.h"
#include "mesh/mesh.h" /* km__mesh_weld: triangles across a texture seam are neighbours */
#include "mesh/mesh_args.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct km_deform_check {
  size_t n_vertices, n_faces, n_edges, n_pairs;
  int32_t *F;              /* n_faces*3 (a copy: the caller's mesh may go) */
  int32_t *edges;          /* n_edges*2, each edge once, a < b, rest length > 0 */
  double *len0;            /* n_edges */
  int32_t *pairs;          /* n_pairs*2 faces across a manifold edge, < 60 degrees apart at rest */
  double *N;               /* n_faces*3 scratch: the frame's unit normals */
  double *prev;            /* n_vertices*3: the last frame */
  int32_t *first;          /* n_faces: the frame a triangle first folded, -1 never */
  km_deform_frame *frames; /* cap_frames; sum.frames of them filled */
  size_t cap_frames;
  bool has_forced; /* km_deform_check_set_forced was called */
  km_deform_summary sum;
};

typedef struct half {
  int32_t a, b, f;
} half;

static int half_cmp(const void *x, const void *y) {
  const half *p = x, *q = y;
  if (p->a != q->a) return p->a < q->a ? -1 : 1;
  if (p->b != q->b) return p->b < q->b ? -1 : 1;
  return p->f < q->f ? -1 : p->f > q->f;
}

/* Unit normal of triangle t over V; zero for a degenerate one. */
static void unit_normal(const double *V, const int32_t *t, double n[3]) {
  double u[3], v[3];
  km__sub3(V + 3 * (size_t)t[1], V + 3 * (size_t)t[0], u);
  km__sub3(V + 3 * (size_t)t[2], V + 3 * (size_t)t[0], v);
  km__cross3(u, v, n);
  double l = sqrt(km__dot3(n, n));
  for (int k = 0; k < 3; ++k)
    n[k] = l > 0 ? n[k] / l : 0;
}

void km_deform_check_free(km_deform_check **pc) {
  if (!pc || !*pc) return;
  km_deform_check *c = *pc;
  free(c->F), free(c->edges), free(c->len0), free(c->pairs), free(c->N), free(c->prev);
  free(c->first), free(c->frames);
  free(c);
  *pc = NULL;
}

km_status km_deform_check_create(const km_mesh *rest, km_deform_check **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_deform_check_create: out is NULL");
  *out = NULL;
  km_status s = km__mesh_check_faces(rest, "km_deform_check_create", err);
  if (s) return s;
  size_t nv = rest->n_vertices, nf = rest->n_faces, nh = 3 * nf;
  km_deform_check *c = calloc(1, sizeof *c);
  half *h = km__malloc(nh ? nh : 1, sizeof *h);
  if (c) {
    c->n_vertices = nv, c->n_faces = nf;
    c->F = km__malloc(nh ? nh : 1, sizeof *c->F);
    c->edges = km__malloc(2 * (nh ? nh : 1), sizeof *c->edges);
    c->len0 = km__malloc(nh ? nh : 1, sizeof *c->len0);
    c->pairs = km__malloc(2 * (nh ? nh : 1), sizeof *c->pairs);
    c->N = km__malloc(3 * (nf ? nf : 1), sizeof *c->N);
    c->prev = km__malloc(3 * (nv ? nv : 1), sizeof *c->prev);
    c->first = km__malloc(nf ? nf : 1, sizeof *c->first);
  }
  if (!c || !h || !c->F || !c->edges || !c->len0 || !c->pairs || !c->N || !c->prev || !c->first) {
    free(h);
    km_deform_check_free(&c);
    return km__fail(err, KM_ERR_NOMEM, "km_deform_check_create: out of memory");
  }
  if (nh) memcpy(c->F, rest->F, nh * sizeof *c->F);
  /* A mesh split at its texture seams: its triangles on either side of a seam are neighbours
   * for the folds (their edge is one edge of the mesh welded there); the edges keep the file's
   * vertices, each side's copy measured. */
  km__weld wd;
  if ((s = km__mesh_weld(rest, &wd, err)) != KM_OK) {
    free(h);
    km_deform_check_free(&c);
    return s;
  }
  for (int pass = 0; pass < (wd.to_w ? 2 : 1); ++pass) {
    for (size_t f = 0; f < nf; ++f) {
      const int32_t *t = rest->F + 3 * f;
      if (pass == 0) {
        unit_normal(rest->V, t, c->N + 3 * f);
        c->first[f] = -1;
      }
      for (int k = 0; k < 3; ++k) {
        int32_t a = t[k], b = t[(k + 1) % 3];
        if (km__face_collapsed(t)) a = b = t[0]; /* no surface: no edge, no neighbour */
        if (pass) a = wd.to_w[a], b = wd.to_w[b];
        h[3 * f + k] = (half){a < b ? a : b, a < b ? b : a, (int32_t)f};
      }
    }
    qsort(h, nh, sizeof *h, half_cmp);
    bool edges = pass == 0, pairs = pass == 1 || !wd.to_w;
    for (size_t i = 0; i < nh;) {
      size_t j = i + 1;
      while (j < nh && h[j].a == h[i].a && h[j].b == h[i].b)
        ++j;
      double d[3], l = 0;
      if (edges) {
        km__sub3(rest->V + 3 * (size_t)h[i].a, rest->V + 3 * (size_t)h[i].b, d);
        l = sqrt(km__dot3(d, d));
      }
      if (l > 0) { /* a zero-length edge has no ratio */
        c->edges[2 * c->n_edges] = h[i].a;
        c->edges[2 * c->n_edges + 1] = h[i].b;
        c->len0[c->n_edges++] = l;
      }
      /* a manifold interior edge whose triangles are nearly flat at rest (a sharp crease at
       * rest, a fin or an ear's rim, is no fold when it stays sharp) */
      if (pairs && j - i == 2 && h[i].a != h[i].b &&
          km__dot3(c->N + 3 * (size_t)h[i].f, c->N + 3 * (size_t)h[i + 1].f) > 0.5) {
        c->pairs[2 * c->n_pairs] = h[i].f;
        c->pairs[2 * c->n_pairs + 1] = h[i + 1].f;
        c->n_pairs++;
      }
      i = j;
    }
  }
  km__weld_free(&wd);
  free(h);
  c->sum.diagonal = km_bbox_diagonal(rest->V, nv);
  c->sum.ratio_min = INFINITY;
  c->sum.step_vertex = -1;
  c->sum.forced_pair[0] = c->sum.forced_pair[1] = -1;
  *out = c;
  return KM_OK;
}

km_status km_deform_check_add(km_deform_check *c, const double *V, km_deform_frame *frame,
                              km_error *err) {
  if (!c || (!V && c->n_vertices))
    return km__fail(err, KM_ERR_INVALID, "km_deform_check_add: %s is NULL", c ? "V" : "c");
  if (c->sum.frames == c->cap_frames) {
    size_t cap = c->cap_frames ? 2 * c->cap_frames : 256;
    km_deform_frame *fr = realloc(c->frames, cap * sizeof *fr);
    if (!fr) return km__fail(err, KM_ERR_NOMEM, "km_deform_check_add: out of memory");
    c->frames = fr, c->cap_frames = cap;
  }
  km_deform_frame x = {.ratio_min = INFINITY, .step_vertex = -1, .y_min = INFINITY, .forced = NAN};
  size_t worst = 0, longest = 0;
  for (size_t e = 0; e < c->n_edges; ++e) {
    double d[3];
    km__sub3(V + 3 * (size_t)c->edges[2 * e], V + 3 * (size_t)c->edges[2 * e + 1], d);
    double q = sqrt(km__dot3(d, d)) / c->len0[e], r = fabs(q - 1);
    if (isnan(q)) { /* a NaN position: the frame's ratios are NaN, at its first such edge */
      x.stretch = x.ratio_min = x.ratio_max = NAN, worst = longest = e;
      break;
    }
    if (r > x.stretch) x.stretch = r, worst = e;
    if (q < x.ratio_min) x.ratio_min = q;
    if (q > x.ratio_max) x.ratio_max = q, longest = e;
  }
  if (c->n_edges) {
    memcpy(x.stretch_edge, c->edges + 2 * worst, sizeof x.stretch_edge);
    memcpy(x.long_edge, c->edges + 2 * longest, sizeof x.long_edge);
  } else {
    x.stretch_edge[0] = x.stretch_edge[1] = x.long_edge[0] = x.long_edge[1] = -1;
  }
  for (size_t f = 0; f < c->n_faces; ++f)
    unit_normal(V, c->F + 3 * f, c->N + 3 * f);
  size_t nfr = c->sum.frames;
  for (size_t q = 0; q < c->n_pairs; ++q) {
    if (!(km__dot3(c->N + 3 * (size_t)c->pairs[2 * q], c->N + 3 * (size_t)c->pairs[2 * q + 1]) <
          -0.5))
      continue;
    x.folded_pairs++;
    for (int s = 0; s < 2; ++s) {
      int32_t t = c->pairs[2 * q + s];
      if (c->first[t] < 0) c->first[t] = (int32_t)nfr, c->sum.folded++;
    }
  }
  for (size_t v = 0; v < c->n_vertices; ++v) {
    const double *p = V + 3 * v;
    if (p[1] < x.y_min) x.y_min = p[1];
    if (!nfr) continue;
    double d[3];
    km__sub3(p, c->prev + 3 * v, d);
    double l = sqrt(km__dot3(d, d));
    if (!isnan(x.step) && !(l <= x.step)) x.step = l, x.step_vertex = (int32_t)v; /* NaN stays */
  }
  if (c->n_vertices) memcpy(c->prev, V, 3 * c->n_vertices * sizeof *V);
  /* the summary: a NaN, once in, stays (the frame where it came is the one kept) */
  km_deform_summary *s = &c->sum;
  if (!isnan(s->stretch) && (!nfr || !(x.stretch <= s->stretch))) {
    s->stretch = x.stretch, s->stretch_frame = nfr;
    memcpy(s->stretch_edge, x.stretch_edge, sizeof s->stretch_edge);
  }
  if (!isnan(s->ratio_min) && !(x.ratio_min >= s->ratio_min)) s->ratio_min = x.ratio_min;
  if (!isnan(s->ratio_max) && (!nfr || !(x.ratio_max <= s->ratio_max))) {
    s->ratio_max = x.ratio_max, s->ratio_max_frame = nfr;
    memcpy(s->long_edge, x.long_edge, sizeof s->long_edge);
  }
  s->long_frames += x.ratio_max > 1.5;
  s->short_frames += x.ratio_min < 0.5;
  if (x.folded_pairs > s->most_folded_pairs)
    s->most_folded_pairs = x.folded_pairs, s->most_folded_frame = nfr;
  if (nfr && !isnan(s->step) && !(x.step <= s->step))
    s->step = x.step, s->step_frame = nfr, s->step_vertex = x.step_vertex;
  c->frames[s->frames++] = x;
  if (frame) *frame = x;
  return KM_OK;
}

void km_deform_check_set_forced(km_deform_check *c, double forced, const int32_t pair[2]) {
  if (!c || !c->sum.frames) return;
  size_t f = c->sum.frames - 1;
  c->frames[f].forced = forced;
  c->has_forced = true;
  if (forced > c->sum.forced) { /* NaN is not kept */
    c->sum.forced = forced, c->sum.forced_frame = f;
    c->sum.forced_pair[0] = pair ? pair[0] : -1, c->sum.forced_pair[1] = pair ? pair[1] : -1;
  }
}

void km_deform_check_summary(const km_deform_check *c, km_deform_summary *out) {
  if (!out) return;
  if (!c) {
    memset(out, 0, sizeof *out);
    out->ratio_min = INFINITY;
    out->step_vertex = -1;
    out->forced_pair[0] = out->forced_pair[1] = -1;
    return;
  }
  *out = c->sum;
}

const int32_t *km_deform_check_first_fold(const km_deform_check *c) { return c ? c->first : NULL; }

size_t km_deform_check_frames(const km_deform_check *c, const km_deform_frame **frames) {
  if (frames) *frames = c ? c->frames : NULL;
  return c ? c->sum.frames : 0;
}

/* ---- JSON report, printed through a memory stream (as the rig sidecar is) */

/* A number, or null for NaN and infinities (JSON has neither). */
static void jnum(FILE *f, const char *key, double v) {
  if (isfinite(v))
    fprintf(f, "\"%s\":%.9g", key, v);
  else
    fprintf(f, "\"%s\":null", key);
}

km_status km_deform_check_write_json(const km_deform_check *c, const char *path, km_error *err) {
  if (!c || !path)
    return km__fail(err, KM_ERR_INVALID, "km_deform_check_write_json: %s is NULL",
                    c ? "path" : "c");
  const km_deform_summary *s = &c->sum;
  double pct = s->diagonal > 0 ? 100 / s->diagonal : NAN;
  char *text = NULL;
  size_t size = 0;
  FILE *f = open_memstream(&text, &size);
  if (!f) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for the report", path);
  fprintf(f, "{\"format\":\"kinemesh-deform-report\",\"version\":1,\"frames\":%zu,", s->frames);
  jnum(f, "diagonal", s->diagonal);
  fputc(',', f);
  jnum(f, "stretch_max", s->stretch);
  fprintf(f, ",\"stretch_frame\":%zu,\"stretch_edge\":[%d,%d],", s->stretch_frame,
          (int)s->stretch_edge[0], (int)s->stretch_edge[1]);
  jnum(f, "edge_ratio_min", s->ratio_min);
  fputc(',', f);
  jnum(f, "edge_ratio_max", s->ratio_max);
  fprintf(f,
          ",\"edge_ratio_max_frame\":%zu,\"long_edge\":[%d,%d],\"frames_edge_over_1_5x\":%zu,"
          "\"frames_edge_under_0_5x\":%zu,\"folded_triangles\":%zu,\"most_folded_pairs\":%zu,"
          "\"most_folded_frame\":%zu,",
          s->ratio_max_frame, (int)s->long_edge[0], (int)s->long_edge[1], s->long_frames,
          s->short_frames, s->folded, s->most_folded_pairs, s->most_folded_frame);
  jnum(f, "step_max_pct", s->step * pct);
  fprintf(f, ",\"step_frame\":%zu,\"step_vertex\":%d,", s->step_frame, (int)s->step_vertex);
  if (c->has_forced) {
    jnum(f, "forced_edge_ratio_max", s->forced);
    fprintf(f, ",\"forced_frame\":%zu,\"forced_pair\":[%d,%d],", s->forced_frame,
            (int)s->forced_pair[0], (int)s->forced_pair[1]);
  }
  fputs("\"per_frame\":[", f);
  for (size_t k = 0; k < s->frames; ++k) {
    const km_deform_frame *x = c->frames + k;
    fputs(k ? ",\n{" : "\n{", f);
    jnum(f, "stretch", x->stretch);
    fputc(',', f);
    jnum(f, "edge_ratio_min", x->ratio_min);
    fputc(',', f);
    jnum(f, "edge_ratio_max", x->ratio_max);
    fprintf(f, ",\"long_edge\":[%d,%d],\"folded_pairs\":%zu,", (int)x->long_edge[0],
            (int)x->long_edge[1], x->folded_pairs);
    jnum(f, "step_pct", x->step * pct);
    fputc(',', f);
    jnum(f, "y_min", x->y_min);
    if (c->has_forced) {
      fputc(',', f);
      jnum(f, "forced_edge_ratio", x->forced);
    }
    fputc('}', f);
  }
  fputs("]}\n", f);
  if (fclose(f) != 0 || !text) {
    free(text);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory for the report", path);
  }
  km_status st = km_write_file_atomic(path, text, size, err);
  free(text);
  return st;
}
