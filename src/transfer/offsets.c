/* Pose transfer by locally encoded Laplacian offsets (Lifkooee et al. 2019, section 3.4).
 *
 * Offline: Delta = L X_S; W_i = F_S(v_i)^T Delta_i with F rows (n, t, b) as built by
 * km_local_frames (so W_i = (n.Delta, t.Delta, b.Delta)). The paper's L (eq. 2) is our -L
 * (header convention: L negative semidefinite); both are symmetric, and removing the landmark
 * rows AND columns (eq. 7) keeps the system symmetric. We factor the symmetric positive
 * definite block A = (-L)_ff once and solve
 *     A x_f = -(F W)_f + L_fc x_c
 * for the three coordinates in one 3-column solve. That is the "symmetric elimination" form:
 * the landmark rows (whose equations are dropped, the landmark being known) never enter,
 * so no normal equations are needed and the conditioning is that of L itself.
 *
 * Online, vertex encoding (the paper's): frames start as T's (or a warm start's), then are
 * recomputed on each solution until positions and frames settle (the paper's final algorithm).
 * Measured: that iteration drifts from the template towards landmark-only editing, because
 * frames re-estimated on a Laplacian solution are a little smoother each time (FAUST 6.8 mm
 * after one solve, 13.2 mm after 10).
 *
 * Online, edge encoding (default): an alternating minimisation that cannot drift, of
 *   E(x, S) = sum_i [ sum_j w_ij |x_j - x_i - R_i S_i e_ij|^2 + lambda_i |S_i - I|^2 ]
 * (e_ij = rest edges of S, w_ij = the Laplacian's weights, landmarks fixed at their targets,
 * lambda_i = damping * sum_j w_ij |e_ij|^2). R_i is the template's rotation of one-ring i
 * (Procrustes of T's one-ring onto the source's, started from the frames' guess
 * F_T(i)^T F_S(i)) and stays fixed: it is the pose. S_i is a symmetric stretch, I at first.
 * Global step: x = argmin E(x, S), the Laplacian solve with the right-hand side
 * sum_j w_ij (A_i + A_j) e_ij / 2, A_i = R_i S_i (the per-edge encoding: each edge in both
 * its ends' frames). Local step: S_i = argmin E(x, S), closed form per vertex (a Sylvester
 * equation diagonal in the eigenbasis of sum_j w_ij e_ij e_ij^T). Both steps are exact
 * minimisers, so E never rises (km_transfer_energies). Why it helps: the one solve leaves
 * the one-rings' stretch that rotated rest edges cannot express (a surface in another pose is
 * not a rigid copy of the rest, and rotated edges do not close up); S_i takes it up while the
 * rotations stay the template's. Letting the rotations move too (plain ARAP local step)
 * drifts back towards landmark-only editing (FAUST 6.9 -> 12.2 mm over 10 iterations).
 * Measured (exact landmark targets, mean error after 1 / 2 / 3 / 5 / 10 solves, damping 0.3,
 * plain alternation): FAUST 000 -> 001 6.86 / 6.34 / 6.13 / 5.94 / 5.84 mm; the cat poses
 * 7.4 -> 6.3 mm over 5 solves; generated subjects 7.1 -> 6.7 mm. The local step is
 * over-relaxed (KM__TRANSFER_RELAX), so the default 4 solves reach what 5 plain ones did. */
#include "transfer/transfer.h"
#include "linalg/linalg.h"
#include "math/math.h"
#include "mesh/mesh.h"

/* Above this many vertices the per-iteration loops (frames, right-hand side) run on OpenMP
 * threads. Not lower: at 7k vertices two free cores took 10 iterations from ~5.8 to ~4.6 ms
 * (before the single-thread work below brought them to ~4.9 ms on one core), but on a busy
 * machine the threads' barriers made the same call 38 ms (measured), and a real-time loop
 * must not have such outliers. */
#ifndef KM__OMP_MIN
#define KM__OMP_MIN 50000
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct km_transfer {
  size_t n, nf, nc;
  km_transfer_options opt;
  km_mesh mesh;      /* source connectivity; V is the working buffer for frame evaluation */
  double *rest;      /* #V*3 source positions */
  double *W;         /* #V*3 local offsets */
  int32_t *ref;      /* frame neighbours */
  int32_t *lm;       /* nc landmark vertex ids, precompute order */
  int32_t *free_of;  /* vertex -> free index or -1 */
  int32_t *free_vtx; /* free index -> vertex */
  /* L_fc in compressed form: for landmark c, entries (free row, value). */
  int32_t *lfc_ptr, *lfc_row;
  double *lfc_val;
  /* Simplicial LDL' (km__cholesky_options): CHOLMOD_AUTO picks supernodal for these
   * matrices, and supernodal 3-column solves are 2.3x slower than simplicial ones at 7k
   * vertices (0.61 vs 0.26 ms): the per-iteration solve is the paper's hot path. */
  km_cholesky *chol;
  double *rhs;        /* nf*3 column-major */
  double *N;          /* #V*3 normals scratch */
  double *sq;         /* #V*2 reciprocal square roots scratch */
  double *frames;     /* #V*9 current frames */
  double *frames_new; /* #V*9 */
  double *tgt;        /* nc*3 targets scratch */
  /* Edge encoding: rhs_i = sum_j w_ij (A_i + A_j) e_ij / 2. The first half is A_i W_i / 2
   * (W_i = Delta_i = sum_j w_ij e_ij in world coordinates for this encoding), so only the
   * second half is stored per edge: e_b = w_ij/2 e_ij, for neighbour e_nbr, rows of free
   * vertex f in e_ptr[f] .. e_ptr[f+1]. */
  int32_t *e_ptr, *e_nbr;
  double *e_b;
  /* #V: per vertex, the squared lengths of the edges of its faces summed (each interior edge
   * twice) on the rest shape: the source's side of size_ratio(). */
  double *esum;
  double area, diag;
  double laplacian_ms, cholesky_ms;
  /* Edge encoding: the damped ARAP iteration (see the top of the file). adj_*: every vertex's
   * one-ring in L (weights w_ij = L_ij, diagonal left out); ebar[i] = sum_j w_ij |e_ij|^2 on
   * the rest shape; rot / anchor: #V*9 row-major rotations R_i and the template's R^T_i;
   * frames_rest: the source's frames (the first guess of R^T_i is F_T(i)^T F_S(i)). */
  int32_t *adj_ptr, *adj_j;
  double *adj_e;  /* 3 per one-ring entry: w_ij e_ij */
  double *adj_eq; /* the same in the eigenbasis of M_i: Q_i^T w_ij e_ij (the local step's) */
  double *adj_w, *ebar, *rot, *anchor, *frames_rest;
  double *mq;   /* #V*12: eigenvectors (columns, row-major 3x3) and eigenvalues of M_i */
  double *sp;   /* #V*9: the stretches S'_i in M_i's eigenbasis */
  double *sinv; /* #V*9: 1 / ((l_a + l_b) / 2 + lambda_i) */
  double damping;
  const double *given_rot; /* km_transfer_solve_rotations: the rotations to start from */
  double *energy;          /* max_iterations: E after each global step of the last solve */
  int n_energy, energy_cap;
  /* The last solve's energy is only needed by km_transfer_energies, so the solve keeps its
   * positions (#V*3) and leaves energy[n_energy - 1] to be evaluated there: one local step's
   * work (about 8% of a default solve) off the real-time path. */
  double *x_last;
  bool energy_pending;
  /* A source split at its texture seams (km__mesh_weld) is solved welded: the outer object
   * keeps the file's mesh (mesh), n, nc, lm (the file's landmark ids), area and opt, and
   * everything else is the welded object's; the per-vertex arrays in and out are gathered
   * from each welded vertex's first copy (w_*: scratch, the solve does not allocate) and
   * scattered back to every copy. NULL: not split. */
  km_transfer *welded;
  int32_t *to_w, *first;
  double *w_T, *w_warm, *w_V, *w_R;
};

double km_surface_area(const km_mesh *m) {
  if (!m || !m->V || !m->F) return 0;
  double a = 0;
  for (size_t f = 0; f < m->n_faces; ++f) {
    const int32_t *t = m->F + 3 * f;
    if (t[0] < 0 || t[1] < 0 || t[2] < 0 || (size_t)t[0] >= m->n_vertices ||
        (size_t)t[1] >= m->n_vertices || (size_t)t[2] >= m->n_vertices)
      continue;
    const double *p = m->V + 3 * (size_t)t[0], *q = m->V + 3 * (size_t)t[1],
                 *r = m->V + 3 * (size_t)t[2];
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    double v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    a += 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  }
  return a;
}

void km_transfer_free(km_transfer **tp) {
  if (!tp || !*tp) return;
  km_transfer *t = *tp;
  km_transfer_free(&t->welded);
  free(t->to_w);
  free(t->first);
  free(t->w_T);
  free(t->w_warm);
  free(t->w_V);
  free(t->w_R);
  km_mesh_free(&t->mesh);
  free(t->rest);
  free(t->W);
  free(t->ref);
  free(t->lm);
  free(t->free_of);
  free(t->free_vtx);
  free(t->lfc_ptr);
  free(t->lfc_row);
  free(t->lfc_val);
  km_cholesky_free(&t->chol);
  free(t->rhs);
  free(t->N);
  free(t->sq);
  free(t->frames);
  free(t->frames_new);
  free(t->tgt);
  free(t->e_ptr);
  free(t->e_nbr);
  free(t->e_b);
  free(t->adj_ptr);
  free(t->adj_j);
  free(t->adj_w);
  free(t->adj_e);
  free(t->adj_eq);
  free(t->ebar);
  free(t->rot);
  free(t->anchor);
  free(t->frames_rest);
  free(t->mq);
  free(t->sp);
  free(t->sinv);
  free(t->energy);
  free(t->x_last);
  free(t->esum);
  free(t);
  *tp = NULL;
}

/* 1/sqrt(x) over an array, in a loop of its own so that it vectorises (with -fno-math-errno,
 * see CMakeLists.txt): square root and division share one unit and, one vertex at a time,
 * they were the frames' bottleneck. x = 0 gives inf, which the callers test for. */
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("avx", "default")))
#endif
static void
rsqrt_all(double *x, size_t n) {
  for (size_t i = 0; i < n; ++i)
    x[i] = 1.0 / sqrt(x[i]);
}

/* Frames of positions V (the connectivity is the source's) into `frames`, returning the largest
 * entry change against `old` (may be NULL): the definitions of km_vertex_normals (area weights)
 * and km_local_frames, fused and without their argument checks (done once at precompute),
 * because this runs every iteration. The per-vertex work is split in passes around two
 * vectorised reciprocal square roots: 0.32 ms (separate functions) -> 0.16 (fused) -> 0.09 ms
 * (passes) at 7k vertices. */
static double frames_of(km_transfer *t, const double *V, double *frames, const double *old) {
  size_t n = t->n;
  double *N = t->N, *qn = t->sq, *qt = t->sq + n;
  memset(N, 0, n * 3 * sizeof *N);
  const int32_t *F = t->mesh.F;
  for (size_t f = 0; f < t->mesh.n_faces; ++f) {
    const int32_t *tr = F + 3 * f;
    const double *p0 = V + 3 * (size_t)tr[0], *p1 = V + 3 * (size_t)tr[1],
                 *p2 = V + 3 * (size_t)tr[2];
    double u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    double v[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    for (int k = 0; k < 3; ++k) {
      double *o = N + 3 * (size_t)tr[k];
      o[0] += c[0], o[1] += c[1], o[2] += c[2];
    }
  }
  for (size_t i = 0; i < n; ++i)
    qn[i] = N[3 * i] * N[3 * i] + N[3 * i + 1] * N[3 * i + 1] + N[3 * i + 2] * N[3 * i + 2];
  rsqrt_all(qn, n);
  /* Unit normal and the tangent before normalisation (|e| is only compared, squared). */
#pragma omp parallel for schedule(static) if (n > KM__OMP_MIN)
  for (size_t i = 0; i < n; ++i) {
    double *fr = frames + 9 * i, *nn = fr, *tt = fr + 3;
    const double *ni = N + 3 * i;
    double il = qn[i];
    if (il > 0 && isfinite(il)) {
      nn[0] = ni[0] * il, nn[1] = ni[1] * il, nn[2] = ni[2] * il;
    } else {
      nn[0] = 0, nn[1] = 0, nn[2] = 1;
    }
    double e[3] = {0, 0, 0};
    int32_t r = t->ref[i];
    if (r >= 0) {
      const double *p = V + 3 * i, *q = V + 3 * (size_t)r;
      e[0] = q[0] - p[0], e[1] = q[1] - p[1], e[2] = q[2] - p[2];
    }
    double lt2 = km__frame_tangent(nn, e, tt);
    qt[i] = lt2;
  }
  rsqrt_all(qt, n);
  /* b = n x t is unit already. */
  double change = 0;
#pragma omp parallel for schedule(static) reduction(max : change) if (n > KM__OMP_MIN)
  for (size_t i = 0; i < n; ++i) {
    double *fr = frames + 9 * i, *nn = fr, *tt = fr + 3, *b = fr + 6;
    double it = qt[i];
    tt[0] *= it, tt[1] *= it, tt[2] *= it;
    b[0] = nn[1] * tt[2] - nn[2] * tt[1];
    b[1] = nn[2] * tt[0] - nn[0] * tt[2];
    b[2] = nn[0] * tt[1] - nn[1] * tt[0];
    if (old)
      for (int k = 0; k < 9; ++k) {
        double dd = fabs(fr[k] - old[9 * i + k]);
        if (dd > change) change = dd;
      }
  }
  return change;
}

/* k-th smallest of x[0..n) (Hoare's selection; reorders x, no allocation). */
static double select_kth(double *x, size_t n, size_t k) {
  size_t lo = 0, hi = n - 1;
  while (lo < hi) {
    double pv = x[lo + (hi - lo) / 2];
    size_t i = lo, j = hi;
    while (i <= j) {
      while (x[i] < pv)
        ++i;
      while (x[j] > pv)
        --j;
      if (i <= j) {
        double w = x[i];
        x[i] = x[j], x[j] = w;
        ++i;
        if (j == 0) break;
        --j;
      }
    }
    if (k <= j)
      hi = j;
    else if (k >= i)
      lo = i;
    else
      return x[k];
  }
  return x[k];
}

/* Size of the source over the size of template positions T (same connectivity; 1 when
 * undefined): the median over vertices of each one-ring's RMS edge-length ratio,
 * sqrt(sum |e_S|^2 / sum |e_T|^2) over the edges of the faces around the vertex. Edge lengths
 * do not change with the pose, and the median ignores the few one-rings a registration
 * stretches at bent joints. Measured (ratio for one body in two poses, ideally 1): FAUST
 * 000/001 0.9998 and 1.0002, the ten cat poses 0.9998-1.0000, generated subjects 1.0000 (the
 * sum of edge-graph geodesics between the landmarks used before gave 1.035 / 0.966, 0.96-1.07
 * and 0.98-1.02: edge paths shorten and lengthen as joints bend). For another body (generated
 * 1.85 m onto 1.70 m) 0.937 against the best landmark scale 0.926, the geodesics 0.915. */
static double size_ratio(const km_transfer *tc, const double *T) {
  km_transfer *t = (km_transfer *)tc; /* scratch only */
  size_t n = t->n;
  double *den = t->sq;
  memset(den, 0, n * sizeof *den);
  const int32_t *F = t->mesh.F;
  for (size_t f = 0; f < t->mesh.n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      size_t i = (size_t)F[3 * f + k], j = (size_t)F[3 * f + (k + 1) % 3];
      const double *p = T + 3 * i, *q = T + 3 * j;
      double d = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                 (p[2] - q[2]) * (p[2] - q[2]);
      den[i] += d, den[j] += d;
    }
  size_t m = 0;
  for (size_t i = 0; i < n; ++i) {
    double r = t->esum[i] / den[i];
    if (r > 0 && isfinite(r)) den[m++] = r;
  }
  if (!m) return 1;
  return sqrt(select_kth(den, m, m / 2));
}

/* Default damping lambda of the ARAP iteration (km_transfer_options.damping). */
#ifndef KM__TRANSFER_DAMPING
#define KM__TRANSFER_DAMPING 0.3
#endif

/* Over-relaxation omega of the local step: S_i <- S_i + omega (S*_i - S_i), S*_i the exact
 * minimiser. E is a convex quadratic in S_i, so along that segment it is a parabola with its
 * minimum at omega = 1 and its starting value again at omega = 2: any omega in (0, 2] still
 * never raises E (the block-SOR argument), and past 1 it undoes part of the alternation's
 * zig-zag; the fixed point is the same. Measured, mean error after 3 / 4 / 5 solves in mm,
 * omega 1 -> 1.2: FAUST 000 -> 001 SMPL landmarks 6.11 / 6.00 / 5.93 -> 6.04 / 5.94 / 5.89,
 * 001 -> 000 5.97 / 5.94 / 5.92 -> 5.95 / 5.92 / 5.91, `auto` landmarks 5.21 / 5.11 / 5.05 ->
 * 5.14 / 5.06 / 5.02 and 5.88 / 5.85 / 5.84 -> 5.86 / 5.84 / 5.83, the cat poses 6.46 / 6.36 /
 * 6.32 -> 6.39 / 6.32 / 6.29: 4 solves now do what 5 did, hence the default of 4.
 * Not more: at 1.3 the error (not the energy) of the generated subjects overshoots the fixed
 * point and rises again by 1.6 um at the 5th solve, from 1.5 on by 0.01-0.02 mm on FAUST
 * 001 -> 000 too; at 1.2 it comes within 2 um of the fixed point from below by the 4th solve
 * (6.652 mm, then 6.653 .. 6.654; plain: 6.66 after 4). */
#ifndef KM__TRANSFER_RELAX
#define KM__TRANSFER_RELAX 1.2
#endif

/* tr(R^T A) for row-major 3x3 R, A. */
static inline double tr_rta(const double *R, const double *A) {
  double s = 0;
  for (int k = 0; k < 9; ++k)
    s += R[k] * A[k];
  return s;
}

/* Moves rotation R (row-major) towards the rotation maximising tr(R^T A), the polar factor of
 * A, by `iters` steps of Mueller et al.'s iteration ("A robust method to extract the
 * rotational part of deformations", 2016): omega = sum_c r_c x a_c / |sum_c r_c . a_c| over the
 * columns, R <- rot(omega) R, with the rotation taken as the quaternion (1, omega / 2)
 * (no trigonometry). Started from the frames' guess, 2 steps suffice. The
 * result is kept only if it raises tr(R^T A) (never a worse fit than the guess). */
static void polar_refine(const double *A, double *R, int iters) {
  double best = tr_rta(R, A);
  double Q[9], Rn[9];
  memcpy(Rn, R, sizeof Rn);
  for (int k = 0; k < iters; ++k) {
    double w[3] = {0, 0, 0}, dot = 0;
    for (int c = 0; c < 3; ++c) {
      double r[3] = {Rn[c], Rn[3 + c], Rn[6 + c]}, a[3] = {A[c], A[3 + c], A[6 + c]}, x[3];
      km__cross3(r, a, x);
      w[0] += x[0], w[1] += x[1], w[2] += x[2];
      dot += km__dot3(r, a);
    }
    /* (1, omega / 2) scaled by |dot|: the quaternion (q0, h) of the same rotation, whose
     * matrix needs one division and no square root (km__rot3_from_quat's entries times
     * 2 / |q|^2). */
    double q0 = fabs(dot), h0 = 0.5 * w[0], h1 = 0.5 * w[1], h2 = 0.5 * w[2];
    double hh = h0 * h0 + h1 * h1 + h2 * h2;
    if (!(q0 > 0) || !(hh > 1e-24 * q0 * q0) || !isfinite(hh)) break;
    double sc = 2.0 / (q0 * q0 + hh);
    Q[0] = 1 - sc * (h1 * h1 + h2 * h2);
    Q[1] = sc * (h0 * h1 - q0 * h2);
    Q[2] = sc * (h0 * h2 + q0 * h1);
    Q[3] = sc * (h0 * h1 + q0 * h2);
    Q[4] = 1 - sc * (h0 * h0 + h2 * h2);
    Q[5] = sc * (h1 * h2 - q0 * h0);
    Q[6] = sc * (h0 * h2 - q0 * h1);
    Q[7] = sc * (h1 * h2 + q0 * h0);
    Q[8] = 1 - sc * (h0 * h0 + h1 * h1);
    km__m3_mul(Q, Rn, Rn);
  }
  double tr = tr_rta(Rn, A);
  if (tr > best) memcpy(R, Rn, sizeof Rn);
}

/* The local step on positions X. For every vertex the covariance C_i = sum_j w_ij d_ij e_ij^T
 * of the edges d_ij = x_j - x_i against the rest edges e_ij, and the energy
 *   E(X, S) = sum_i [ sum_j w_ij |d_ij - R_i S_i e_ij|^2 + lambda_i |S_i - I|^2 ]
 * for the stretches S as they are on entry (R_i: the template's rotations, fixed; S_i
 * symmetric; lambda_i = damping * ebar_i). Everything is kept in the eigenbasis Q_i of
 * M_i = sum_j w_ij e_ij e_ij^T: S'_i = Q_i^T S_i Q_i, P_i = R_i Q_i, so that
 *   sum_j w_ij |R_i S_i e_ij|^2 = tr(S M S) = sum_ab l_b S'_ab^2,
 *   sum_j w_ij d_ij . R_i S_i e_ij = <S', B'>,  B' = P_i^T C_i Q_i.
 * With `update`, S_i moves towards (KM__TRANSFER_RELAX times the step to) the exact minimiser
 * over symmetric matrices,
 *   (S M + M S) / 2 + lambda S = sym(R^T C) + lambda I,  i.e.
 *   S'_ab = (sym(B')_ab + lambda delta_ab) / ((l_a + l_b) / 2 + lambda),
 * so E(X, S_new) <= E(X, S), A_i = R_i S_i = P_i S'_i Q_i^T goes to t->rot for the global step
 * and *change gets the largest change of an S' entry. Returns E(X, S_old). */
static double local_step(const km_transfer *t, const double *X, bool update, double *change) {
  size_t n = t->n;
  double energy = 0, chg = 0;
  for (size_t i = 0; i < n; ++i) {
    const double *xi = X + 3 * i;
    /* CQ = C_i Q_i, accumulated from the rest edges already in Q_i's basis */
    double CQ[9] = {0}, D = 0;
    for (int32_t p = t->adj_ptr[i]; p < t->adj_ptr[i + 1]; ++p) {
      const double *xj = X + 3 * (size_t)t->adj_j[p], *e = t->adj_eq + 3 * p;
      double d[3] = {xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]};
      D += t->adj_w[p] * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (int r = 0; r < 3; ++r)
        CQ[3 * r] += d[r] * e[0], CQ[3 * r + 1] += d[r] * e[1], CQ[3 * r + 2] += d[r] * e[2];
    }
    const double *Q = t->mq + 12 * i, *l = Q + 9, *P = t->anchor + 9 * i, *iv = t->sinv + 9 * i;
    double *S = t->sp + 9 * i;
    double B[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        B[3 * r + c] = P[r] * CQ[c] + P[3 + r] * CQ[3 + c] + P[6 + r] * CQ[6 + c];
    double lam = t->damping * t->ebar[i], sms = 0, sb = 0, si2 = 0;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        double v = S[3 * r + c], dd = v - (r == c);
        sms += l[c] * v * v;
        sb += v * B[3 * r + c];
        si2 += dd * dd;
      }
    energy += D + sms - 2 * sb + lam * si2;
    if (!update) continue;
    double Sn[9];
    for (int r = 0; r < 3; ++r)
      for (int c = r; c < 3; ++c) {
        double v = (0.5 * (B[3 * r + c] + B[3 * c + r]) + (r == c ? lam : 0)) * iv[3 * r + c];
        v = S[3 * r + c] + KM__TRANSFER_RELAX * (v - S[3 * r + c]);
        Sn[3 * r + c] = Sn[3 * c + r] = v;
      }
    for (int k = 0; k < 9; ++k) {
      double dd = fabs(Sn[k] - S[k]);
      if (dd > chg) chg = dd;
    }
    memcpy(S, Sn, sizeof Sn);
    double PS[9], *A = t->rot + 9 * i;
    km__m3_mul(P, Sn, PS);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        A[3 * r + c] =
            PS[3 * r] * Q[3 * c] + PS[3 * r + 1] * Q[3 * c + 1] + PS[3 * r + 2] * Q[3 * c + 2];
  }
  if (change) *change = chg;
  return energy;
}

/* The template's rotations R_i (Procrustes of each one-ring of X against the rest's, refined
 * from the frames' guess already in t->rot), P_i = R_i Q_i, and S_i = I. */
static void rotations_init(km_transfer *t, const double *X) {
  for (size_t i = 0; i < t->n; ++i) {
    const double *xi = X + 3 * i;
    double C[9] = {0};
    for (int32_t p = t->adj_ptr[i]; p < t->adj_ptr[i + 1]; ++p) {
      const double *xj = X + 3 * (size_t)t->adj_j[p], *e = t->adj_e + 3 * p;
      double d[3] = {xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]};
      for (int r = 0; r < 3; ++r)
        C[3 * r] += d[r] * e[0], C[3 * r + 1] += d[r] * e[1], C[3 * r + 2] += d[r] * e[2];
    }
    double *R = t->rot + 9 * i, *S = t->sp + 9 * i;
    /* Two steps from the frames' guess: measured on FAUST and the cat poses, more (or an
     * exact polar decomposition) changes the errors by < 0.05 mm. */
    polar_refine(C, R, 2);
    km__m3_mul(R, t->mq + 12 * i, t->anchor + 9 * i);
    for (int k = 0; k < 9; ++k)
      S[k] = k % 4 == 0;
  }
}

static km_status transfer_precompute(const km_mesh *source, const int32_t *landmarks,
                                     size_t n_landmarks, const km_transfer_options *opt,
                                     km_transfer **out, km_error *err);

static km_status check_landmark(const int32_t *landmarks, size_t c, size_t n, km_error *err) {
  if (landmarks[c] >= 0 && (size_t)landmarks[c] < n) return KM_OK;
  return km__fail(err, KM_ERR_INVALID,
                  "km_transfer_precompute: landmark %zu is vertex %d, expected 0..%zu", c,
                  (int)landmarks[c], n - 1);
}

/* #V*k values of the file's vertices -> #W*k of the welded ones (each from its first copy). */
static const double *gather(const km_transfer *t, const double *x, double *w, int k) {
  if (!x) return NULL;
  for (size_t q = 0; q < t->welded->n; ++q)
    memcpy(w + (size_t)k * q, x + (size_t)k * (size_t)t->first[q], (size_t)k * sizeof(double));
  return w;
}

static void scatter(const km_transfer *t, const double *w, double *x) {
  for (size_t v = 0; v < t->n; ++v)
    memcpy(x + 3 * v, w + 3 * (size_t)t->to_w[v], 3 * sizeof(double));
}

/* A source split at its texture seams (a game character's glTF: copies of a vertex at one
 * position, the mesh in pieces or open there) is solved on the mesh welded there: split, each
 * piece's Laplacian stood alone, the pieces moved apart (a character split at its waist
 * opened there by 8 cm in a kung-fu pose) and a piece without a landmark had no solution. */
km_status km_transfer_precompute(const km_mesh *source, const int32_t *landmarks,
                                 size_t n_landmarks, const km_transfer_options *opt,
                                 km_transfer **out, km_error *err) {
  km__weld wd = {0};
  km_status s = KM_OK;
  if (!out || !source || !source->V || !source->F || !landmarks || n_landmarks < 3 ||
      (s = km__mesh_weld(source, &wd, err)) != KM_OK || !wd.to_w)
    return s != KM_OK ? s : transfer_precompute(source, landmarks, n_landmarks, opt, out, err);
  *out = NULL;
  size_t n = source->n_vertices, nw = wd.w.n_vertices;
  km_transfer *t = calloc(1, sizeof *t);
  int32_t *wl = km__malloc(n_landmarks, sizeof *wl);
  if (!t || !wl || !(t->lm = km__malloc(n_landmarks, sizeof *t->lm)) ||
      !(t->w_T = km__malloc(3 * nw, sizeof(double))) ||
      !(t->w_warm = km__malloc(3 * nw, sizeof(double))) ||
      !(t->w_V = km__malloc(3 * nw, sizeof(double))) ||
      !(t->w_R = km__malloc(9 * nw, sizeof(double)))) {
    s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu vertices)", n);
    goto done;
  }
  for (size_t c = 0; c < n_landmarks; ++c) {
    int32_t v = landmarks[c];
    if ((s = check_landmark(landmarks, c, n, err)) != KM_OK) goto done;
    t->lm[c] = v;
    wl[c] = wd.to_w[v];
    for (size_t b = 0; b < c; ++b)
      if (wl[b] == wl[c]) {
        s = km__fail(err, KM_ERR_INVALID,
                     "km_transfer_precompute: landmarks %zu and %zu are vertices %d and %d, "
                     "copies of one vertex at a texture seam: give one of them",
                     b, c, (int)landmarks[b], (int)v);
        goto done;
      }
  }
  if ((s = transfer_precompute(&wd.w, wl, n_landmarks, opt, &t->welded, err)) != KM_OK) goto done;
  if ((s = km_mesh_copy(source, &t->mesh, err)) != KM_OK) goto done;
  t->n = n;
  t->nc = n_landmarks;
  t->opt = t->welded->opt;
  t->area = t->welded->area;
  t->diag = t->welded->diag;
  t->to_w = wd.to_w, wd.to_w = NULL;
  t->first = wd.first, wd.first = NULL;
done:
  free(wl);
  km__weld_free(&wd);
  if (s != KM_OK) {
    km_transfer_free(&t);
    return s;
  }
  *out = t;
  return KM_OK;
}

static km_status transfer_precompute(const km_mesh *source, const int32_t *landmarks,
                                     size_t n_landmarks, const km_transfer_options *opt,
                                     km_transfer **out, km_error *err) {
  if (!out) return km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: out is NULL");
  *out = NULL;
  if (!source || !source->V || !source->F || source->n_faces == 0)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "km_transfer_precompute: the source must be a triangle mesh with faces");
  if (!landmarks && n_landmarks)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: landmarks is NULL");
  if (n_landmarks < 3)
    return km__fail(err, KM_ERR_INVALID,
                    "km_transfer_precompute: %zu landmark(s) given, at least 3 are needed: with "
                    "fewer the constrained Laplacian cannot fix the avatar's rotation (the paper "
                    "requires more than 2)",
                    n_landmarks);
  size_t n = source->n_vertices;
  if (n_landmarks >= n)
    return km__fail(err, KM_ERR_INVALID,
                    "km_transfer_precompute: %zu landmarks for %zu vertices: at least one vertex "
                    "must be free",
                    n_landmarks, n);
  km_transfer_options o = opt ? *opt : (km_transfer_options){0};
  if (o.max_iterations <= 0) o.max_iterations = o.encoding == KM_OFFSETS_VERTEX ? 10 : 4;
  if (!(o.tolerance > 0)) o.tolerance = 1e-4;
  if (o.laplacian != KM_LAPLACIAN_UNIFORM && o.laplacian != KM_LAPLACIAN_COTAN)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: unknown Laplacian kind %d",
                    (int)o.laplacian);
  if (o.encoding != KM_OFFSETS_VERTEX && o.encoding != KM_OFFSETS_EDGE)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: unknown offset encoding %d",
                    (int)o.encoding);
  if (o.align != KM_TRANSFER_ALIGN_SCALE && o.align != KM_TRANSFER_ALIGN_SIMILARITY &&
      o.align != KM_TRANSFER_ALIGN_NONE)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: unknown align mode %d",
                    (int)o.align);

  km_transfer *t = calloc(1, sizeof *t);
  if (!t) return km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory");
  t->n = n;
  t->nc = n_landmarks;
  t->nf = n - n_landmarks;
  t->opt = o;
  km_status s = km_mesh_copy(source, &t->mesh, err);
  if (s) {
    free(t);
    return s;
  }
  t->rest = km__malloc(n * 3, sizeof(double));
  t->W = km__malloc(n * 3, sizeof(double));
  t->ref = km__malloc(n, sizeof(int32_t));
  t->lm = km__malloc(n_landmarks, sizeof(int32_t));
  t->free_of = km__malloc(n, sizeof(int32_t));
  t->free_vtx = km__malloc(t->nf, sizeof(int32_t));
  t->rhs = km__malloc(t->nf * 3, sizeof(double));
  t->N = km__malloc(n * 3, sizeof(double));
  t->sq = km__malloc(n * 2, sizeof(double));
  t->frames = km__malloc(n * 9, sizeof(double));
  t->frames_new = km__malloc(n * 9, sizeof(double));
  t->tgt = km__malloc(n_landmarks * 3, sizeof(double));
  t->lfc_ptr = km__calloc(n_landmarks + 1, sizeof(int32_t));
  double *colmaj = km__malloc(n * 3, sizeof(double)), *delta = km__malloc(n * 3, sizeof(double));
  km_sparse *L = NULL;
  int32_t *ti = NULL, *tj = NULL;
  double *tv = NULL;
  if (!t->rest || !t->W || !t->ref || !t->lm || !t->free_of || !t->free_vtx || !t->rhs || !t->N ||
      !t->sq || !t->frames || !t->frames_new || !t->tgt || !t->lfc_ptr || !colmaj || !delta) {
    s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu vertices)", n);
    goto fail;
  }
  memcpy(t->rest, source->V, n * 3 * sizeof(double));
  for (size_t i = 0; i < n * 3; ++i)
    if (!isfinite(t->rest[i])) {
      s = km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: vertex %zu is not finite", i / 3);
      goto fail;
    }
  for (size_t v = 0; v < n; ++v)
    t->free_of[v] = 0;
  for (size_t c = 0; c < n_landmarks; ++c) {
    int32_t v = landmarks[c];
    if ((s = check_landmark(landmarks, c, n, err)) != KM_OK) goto fail;
    if (t->free_of[v] < 0) {
      s = km__fail(err, KM_ERR_INVALID,
                   "km_transfer_precompute: vertex %d is given twice as a landmark", (int)v);
      goto fail;
    }
    t->free_of[v] = -1 - (int32_t)c;
    t->lm[c] = v;
  }
  /* free_of: >= 0 free index, < 0 encodes the landmark slot as -1 - c. */
  size_t k = 0;
  for (size_t v = 0; v < n; ++v)
    if (t->free_of[v] >= 0) {
      t->free_vtx[k] = (int32_t)v;
      t->free_of[v] = (int32_t)k++;
    }
  t->diag = km_bbox_diagonal(t->rest, n);
  t->area = km_surface_area(source);
  if (!(t->diag > 0) || !(t->area > 0)) {
    s = km__fail(err, KM_ERR_DEGENERATE_MESH, "km_transfer_precompute: the source has zero extent");
    goto fail;
  }

  double t0 = km_seconds();
  s = o.laplacian == KM_LAPLACIAN_COTAN ? km_cotmatrix(source, &L, err)
                                        : km_uniform_laplacian(source, &L, err);
  if (s) goto fail;
  for (size_t v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c)
      colmaj[c * n + v] = t->rest[3 * v + c];
  km_sparse_mul(L, 3, colmaj, delta);
  s = km_frame_neighbors(source, t->ref, err);
  if (s) goto fail;
  for (size_t f = 0; f < source->n_faces * 3; ++f)
    if (source->F[f] < 0 || (size_t)source->F[f] >= n) {
      s = km__fail(err, KM_ERR_INVALID, "km_transfer_precompute: face %zu has vertex %d of %zu",
                   f / 3, (int)source->F[f], n);
      goto fail;
    }
  frames_of(t, t->rest, t->frames, NULL);
  for (size_t v = 0; v < n; ++v) {
    const double *F = t->frames + 9 * v;
    double d[3] = {delta[v], delta[n + v], delta[2 * n + v]};
    for (int r = 0; r < 3; ++r)
      t->W[3 * v + r] = F[3 * r] * d[0] + F[3 * r + 1] * d[1] + F[3 * r + 2] * d[2];
  }

  /* Split L into A = -(L_ff) (triplets) and L_fc (per landmark column). */
  const int32_t *cp, *ri;
  const double *val;
  km_sparse_csc(L, &cp, &ri, &val);
  size_t nnz = km_sparse_nnz(L);
  ti = km__malloc(nnz, sizeof *ti);
  tj = km__malloc(nnz, sizeof *tj);
  tv = km__malloc(nnz, sizeof *tv);
  size_t nlfc = 0;
  for (size_t j = 0; j < n; ++j)
    if (t->free_of[j] < 0)
      for (int32_t p = cp[j]; p < cp[j + 1]; ++p)
        if (t->free_of[ri[p]] >= 0) ++nlfc;
  t->lfc_row = km__malloc(nlfc ? nlfc : 1, sizeof(int32_t));
  t->lfc_val = km__malloc(nlfc ? nlfc : 1, sizeof(double));
  if (!ti || !tj || !tv || !t->lfc_row || !t->lfc_val) {
    s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu entries)", nnz);
    goto fail;
  }
  size_t m = 0;
  for (size_t j = 0; j < n; ++j) {
    int32_t fj = t->free_of[j];
    if (fj < 0) continue;
    for (int32_t p = cp[j]; p < cp[j + 1]; ++p) {
      int32_t fi = t->free_of[ri[p]];
      if (fi < 0) continue;
      ti[m] = fi, tj[m] = fj, tv[m] = -val[p];
      ++m;
    }
  }
  size_t q = 0;
  for (size_t c = 0; c < n_landmarks; ++c) {
    int32_t j = t->lm[c];
    t->lfc_ptr[c] = (int32_t)q;
    for (int32_t p = cp[j]; p < cp[j + 1]; ++p) {
      int32_t fi = t->free_of[ri[p]];
      if (fi < 0) continue;
      t->lfc_row[q] = fi;
      t->lfc_val[q] = val[p];
      ++q;
    }
  }
  t->lfc_ptr[n_landmarks] = (int32_t)q;
  t->esum = km__malloc(n, sizeof(double));
  if (!t->esum) {
    s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu vertices)", n);
    goto fail;
  }
  {
    /* the source's side of size_ratio() */
    memset(t->esum, 0, n * sizeof(double));
    for (size_t f = 0; f < source->n_faces; ++f)
      for (int e = 0; e < 3; ++e) {
        size_t i = (size_t)source->F[3 * f + e], j = (size_t)source->F[3 * f + (e + 1) % 3];
        double d[3];
        km__sub3(t->rest + 3 * i, t->rest + 3 * j, d);
        t->esum[i] += km__dot3(d, d), t->esum[j] += km__dot3(d, d);
      }
  }
  if (o.encoding == KM_OFFSETS_EDGE) {
    size_t ne = 0;
    for (size_t f = 0; f < t->nf; ++f) {
      size_t i = (size_t)t->free_vtx[f];
      for (int32_t p = cp[i]; p < cp[i + 1]; ++p)
        if ((size_t)ri[p] != i) ++ne;
    }
    t->e_ptr = km__malloc(t->nf + 1, sizeof(int32_t));
    t->e_nbr = km__malloc(ne ? ne : 1, sizeof(int32_t));
    t->e_b = km__malloc(ne ? ne * 3 : 1, sizeof(double));
    if (!t->e_ptr || !t->e_nbr || !t->e_b) {
      s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu edges)", ne);
      goto fail;
    }
    size_t e = 0;
    for (size_t f = 0; f < t->nf; ++f) {
      size_t i = (size_t)t->free_vtx[f];
      t->e_ptr[f] = (int32_t)e;
      for (int32_t p = cp[i]; p < cp[i + 1]; ++p) {
        size_t j = (size_t)ri[p];
        if (j == i) continue;
        const double *xi = t->rest + 3 * i, *xj = t->rest + 3 * j;
        double h = 0.5 * val[p];
        for (int r = 0; r < 3; ++r)
          t->e_b[3 * e + r] = h * (xj[r] - xi[r]);
        t->e_nbr[e] = (int32_t)j;
        ++e;
      }
    }
    t->e_ptr[t->nf] = (int32_t)e;
    /* W_v = Delta_v in world coordinates: rhs_i = R_i W_i / 2 + sum_j R_j e_b. */
    for (size_t v = 0; v < n; ++v)
      for (int r = 0; r < 3; ++r)
        t->W[3 * v + r] = delta[r * n + v];
    /* Every vertex's one-ring for the local step and the energy. */
    size_t na = 0;
    for (size_t i = 0; i < n; ++i)
      for (int32_t p = cp[i]; p < cp[i + 1]; ++p)
        if ((size_t)ri[p] != i) ++na;
    t->adj_ptr = km__malloc(n + 1, sizeof(int32_t));
    t->adj_j = km__malloc(na ? na : 1, sizeof(int32_t));
    t->adj_w = km__malloc(na ? na : 1, sizeof(double));
    t->adj_e = km__malloc(na ? na * 3 : 1, sizeof(double));
    t->adj_eq = km__malloc(na ? na * 3 : 1, sizeof(double));
    t->ebar = km__malloc(n, sizeof(double));
    t->rot = km__malloc(n * 9, sizeof(double));
    t->anchor = km__malloc(n * 9, sizeof(double));
    t->frames_rest = km__malloc(n * 9, sizeof(double));
    t->energy = km__malloc((size_t)o.max_iterations, sizeof(double));
    t->x_last = km__malloc(n * 3, sizeof(double));
    t->energy_cap = o.max_iterations;
    t->mq = km__malloc(n * 12, sizeof(double));
    t->sp = km__malloc(n * 9, sizeof(double));
    t->sinv = km__malloc(n * 9, sizeof(double));
    if (!t->adj_ptr || !t->adj_j || !t->adj_w || !t->adj_e || !t->adj_eq || !t->ebar || !t->rot ||
        !t->anchor || !t->frames_rest || !t->energy || !t->x_last || !t->mq || !t->sp || !t->sinv) {
      s = km__fail(err, KM_ERR_NOMEM, "km_transfer_precompute: out of memory (%zu edges)", na);
      goto fail;
    }
    memcpy(t->frames_rest, t->frames, n * 9 * sizeof(double));
    size_t a = 0;
    for (size_t i = 0; i < n; ++i) {
      t->adj_ptr[i] = (int32_t)a;
      double eb = 0, M[9] = {0};
      for (int32_t p = cp[i]; p < cp[i + 1]; ++p) {
        size_t j = (size_t)ri[p];
        if (j == i) continue;
        t->adj_j[a] = (int32_t)j;
        t->adj_w[a] = val[p];
        double d[3];
        km__sub3(t->rest + 3 * j, t->rest + 3 * i, d);
        eb += val[p] * km__dot3(d, d);
        for (int r = 0; r < 3; ++r)
          t->adj_e[3 * a + r] = val[p] * d[r];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            M[3 * r + c] += val[p] * d[r] * d[c];
        ++a;
      }
      t->ebar[i] = eb;
      km__sym_eig3(M, t->mq + 12 * i + 9, t->mq + 12 * i);
      const double *Q = t->mq + 12 * i;
      for (int32_t q = t->adj_ptr[i]; q < (int32_t)a; ++q)
        for (int c = 0; c < 3; ++c)
          t->adj_eq[3 * q + c] = t->adj_e[3 * q] * Q[c] + t->adj_e[3 * q + 1] * Q[3 + c] +
                                 t->adj_e[3 * q + 2] * Q[6 + c];
    }
    t->adj_ptr[n] = (int32_t)a;
    t->damping = o.damping < 0 ? 0 : o.damping > 0 ? o.damping : KM__TRANSFER_DAMPING;
    for (size_t i = 0; i < n; ++i) {
      const double *l = t->mq + 12 * i + 9;
      double lam = t->damping * t->ebar[i];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          double den = 0.5 * (l[r] + l[c]) + lam;
          t->sinv[9 * i + 3 * r + c] = den > 0 ? 1 / den : 0;
        }
    }
  }
  double t1 = km_seconds();
  t->laplacian_ms = (t1 - t0) * 1e3;
  /* Lower triangle of A = -(L_ff), factored as simplicial LDL': its 3-column solve is 7%
   * faster than LL''s (no square roots in the factor, a unit diagonal in the triangular
   * sweeps). LDL' only stops at an exactly zero pivot, so the pivots are checked (min_pivot). */
  {
    size_t nlow = 0;
    for (size_t e = 0; e < m; ++e)
      if (ti[e] >= tj[e]) ++nlow;
    km_sparse *cA = NULL;
    if ((s = km__sparse_alloc(t->nf, t->nf, nlow, &cA, err))) goto fail;
    /* The triplets were emitted column by column with rows ascending (L is sorted CSC and
     * free indices preserve the order), so the lower part is already in CSC order. */
    int32_t *Ap, *Ai;
    double *Ax;
    km__sparse_arrays(cA, &Ap, &Ai, &Ax);
    size_t q2 = 0, col = 0;
    Ap[0] = 0;
    for (size_t e = 0; e < m; ++e) {
      while (col < (size_t)tj[e])
        Ap[++col] = (int32_t)q2;
      if (ti[e] < tj[e]) continue;
      Ai[q2] = ti[e];
      Ax[q2] = tv[e];
      ++q2;
    }
    while (col < t->nf)
      Ap[++col] = (int32_t)q2;
    if ((s = km__sparse_compress(&cA, err))) goto fail;
    km__cholesky_options co = {
        .kind = KM__CHOLESKY_SIMPLICIAL_LDL, .stored = -1, .min_pivot = 1e-10};
    s = km__cholesky_analyze_with(cA, &co, &t->chol, err);
    if (!s) s = km_cholesky_factorize(t->chol, cA, err);
    km_sparse_free(&cA);
    if (s == KM_ERR_NOT_POSDEF) {
      s = km__fail(err, KM_ERR_NOT_POSDEF,
                   "km_transfer_precompute: the constrained Laplacian is singular: every "
                   "connected component of the source needs at least one landmark");
      goto fail;
    }
    if (s) goto fail;
  }
  t->cholesky_ms = (km_seconds() - t1) * 1e3;
  {
    /* One solve now makes CHOLMOD allocate its solve workspace here, not in the first
     * km_transfer_solve (which promises not to allocate). */
    memset(t->rhs, 0, t->nf * 3 * sizeof(double));
    if ((s = km_cholesky_solve(t->chol, 3, t->rhs, t->rhs, err))) goto fail;
  }
  km_sparse_free(&L);
  free(ti);
  free(tj);
  free(tv);
  free(colmaj);
  free(delta);
  *out = t;
  return KM_OK;
fail:
  km_sparse_free(&L);
  free(ti);
  free(tj);
  free(tv);
  free(colmaj);
  free(delta);
  km_transfer_free(&t);
  return s;
}

void km__transfer_frames(km_transfer *t, const double *V, double *frames) {
  if (t->welded) { /* test use only: allocates */
    double *wf = km__malloc(9 * t->welded->n, sizeof *wf);
    if (!wf) return;
    frames_of(t->welded, gather(t, V, t->w_T, 3), wf, NULL);
    for (size_t v = 0; v < t->n; ++v)
      memcpy(frames + 9 * v, wf + 9 * (size_t)t->to_w[v], 9 * sizeof(double));
    free(wf);
    return;
  }
  frames_of(t, V, frames, NULL);
}

size_t km_transfer_vertices(const km_transfer *t) { return t ? t->n : 0; }
void km__transfer_set_iterations(km_transfer *t, int max_iterations, double tolerance) {
  if (!t || max_iterations < 1) return;
  if (t->welded) km__transfer_set_iterations(t->welded, max_iterations, tolerance);
  /* t->energy holds the precompute's count: never more */
  if (!t->energy || max_iterations <= t->energy_cap) t->opt.max_iterations = max_iterations;
  if (tolerance > 0) t->opt.tolerance = tolerance;
}
size_t km_transfer_energies(const km_transfer *t, double *energies, size_t cap) {
  if (t && t->welded) return km_transfer_energies(t->welded, energies, cap);
  if (!t || !t->energy) return 0;
  size_t k = (size_t)t->n_energy;
  for (size_t i = 0; i < k && i < cap && energies; ++i)
    energies[i] = t->energy[i];
  if (t->energy_pending && k && k <= cap && energies)
    energies[k - 1] = local_step(t, t->x_last, false, NULL);
  return k;
}
/* mesh.V holds the source positions again whenever no frames_of() call is running. */
const km_mesh *km__transfer_source(const km_transfer *t) { return t ? &t->mesh : NULL; }
const int32_t *km__transfer_landmark_ids(const km_transfer *t) { return t ? t->lm : NULL; }
double km__transfer_area(const km_transfer *t) { return t ? t->area : 0; }
double km__transfer_size_ratio(const km_transfer *t, const double *T) {
  return t->welded ? size_ratio(t->welded, gather(t, T, t->w_T, 3)) : size_ratio(t, T);
}
size_t km_transfer_landmarks(const km_transfer *t) { return t ? t->nc : 0; }

void km_transfer_precompute_ms(const km_transfer *t, double *laplacian_ms, double *cholesky_ms) {
  if (t && t->welded) t = t->welded;
  if (laplacian_ms) *laplacian_ms = t ? t->laplacian_ms : 0;
  if (cholesky_ms) *cholesky_ms = t ? t->cholesky_ms : 0;
}

km_status km_transfer_targets(const km_transfer *t, const double *T, double *targets,
                              km_error *err) {
  if (!t || !T || !targets)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_targets: NULL argument");
  if (t->welded) return km_transfer_targets(t->welded, gather(t, T, t->w_T, 3), targets, err);
  for (size_t c = 0; c < t->nc; ++c)
    for (int d = 0; d < 3; ++d)
      targets[3 * c + d] = T[3 * (size_t)t->lm[c] + d];
  if (t->opt.align == KM_TRANSFER_ALIGN_SIMILARITY) {
    /* targets holds T's landmarks; fit them onto the source's rest landmarks. */
    double restlm[3 * KM_POSE_MAX_LANDMARKS], *rl = restlm;
    double *heap = NULL;
    if (t->nc > KM_POSE_MAX_LANDMARKS) {
      heap = km__malloc(t->nc * 3, sizeof(double));
      if (!heap) return km__fail(err, KM_ERR_NOMEM, "km_transfer_targets: out of memory");
      rl = heap;
    }
    for (size_t c = 0; c < t->nc; ++c)
      for (int d = 0; d < 3; ++d)
        rl[3 * c + d] = t->rest[3 * (size_t)t->lm[c] + d];
    double sc, R[9], tr[3];
    km_status s = km_similarity_fit(targets, rl, NULL, t->nc, true, &sc, R, tr, err);
    free(heap);
    if (s) return km__wrap(err, s, "km_transfer_targets: aligning the template's landmarks");
    /* Umeyama's scale mixes pose and size; the edge-length ratio is pose-invariant. */
    sc = size_ratio(t, T);
    for (size_t c = 0; c < t->nc; ++c) {
      double p[3] = {targets[3 * c], targets[3 * c + 1], targets[3 * c + 2]};
      for (int r = 0; r < 3; ++r)
        targets[3 * c + r] =
            sc * (R[3 * r] * p[0] + R[3 * r + 1] * p[1] + R[3 * r + 2] * p[2]) + tr[r];
    }
    /* Re-centre: the translation was fitted for Umeyama's scale. */
    double cs[3] = {0, 0, 0}, cd[3] = {0, 0, 0};
    for (size_t c = 0; c < t->nc; ++c)
      for (int d = 0; d < 3; ++d)
        cs[d] += targets[3 * c + d], cd[d] += t->rest[3 * (size_t)t->lm[c] + d];
    for (size_t c = 0; c < t->nc; ++c)
      for (int d = 0; d < 3; ++d)
        targets[3 * c + d] += (cd[d] - cs[d]) / (double)t->nc;
  } else if (t->opt.align == KM_TRANSFER_ALIGN_SCALE) {
    double sc = size_ratio(t, T);
    for (size_t i = 0; i < t->nc * 3; ++i)
      targets[i] *= sc;
  }
  return KM_OK;
}

km_status km_transfer_solve(km_transfer *t, const double *T, const double *targets,
                            const double *warm_start, double *V_out, km_transfer_stats *stats,
                            km_error *err) {
  double t_start = km_seconds();
  if (stats) memset(stats, 0, sizeof *stats);
  if (!t || !V_out) return km__fail(err, KM_ERR_INVALID, "km_transfer_solve: NULL argument");
  if (!T && !warm_start)
    return km__fail(
        err, KM_ERR_INVALID,
        "km_transfer_solve: give a template or a warm start to take the first frames from");
  if (!targets && !T)
    return km__fail(err, KM_ERR_INVALID,
                    "km_transfer_solve: landmark targets are needed when there is no template");
  if (T == V_out)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_solve: V_out aliases the template");
  if (t->welded) {
    km_status sw = km_transfer_solve(t->welded, gather(t, T, t->w_T, 3), targets,
                                     gather(t, warm_start, t->w_warm, 3), t->w_V, stats, err);
    if (sw == KM_OK) scatter(t, t->w_V, V_out);
    if (stats) stats->total_ms = (km_seconds() - t_start) * 1e3;
    return sw;
  }
  size_t n = t->n, nf = t->nf, nc = t->nc;
  km_status s;
  if (!targets) {
    s = km_transfer_targets(t, T, t->tgt, err);
    if (s) return s;
  } else {
    memcpy(t->tgt, targets, nc * 3 * sizeof(double));
  }
  for (size_t i = 0; i < nc * 3; ++i)
    if (!isfinite(t->tgt[i]))
      return km__fail(err, KM_ERR_INVALID, "km_transfer_solve: landmark target %zu is not finite",
                      i / 3);
  const double *F0 = T ? T : warm_start;
  for (size_t i = 0; i < n * 3; ++i)
    if (!isfinite(F0[i]))
      return km__fail(err, KM_ERR_INVALID, "km_transfer_solve: %s vertex %zu is not finite",
                      T ? "template" : "warm start", i / 3);
  double tf = km_seconds();
  if (t->given_rot) {
    /* km_transfer_solve_rotations: the rotations as given, S_i = I */
    for (size_t i = 0; i < n; ++i) {
      memcpy(t->rot + 9 * i, t->given_rot + 9 * i, 9 * sizeof(double));
      km__m3_mul(t->rot + 9 * i, t->mq + 12 * i, t->anchor + 9 * i);
      for (int k = 0; k < 9; ++k)
        t->sp[9 * i + k] = k % 4 == 0;
    }
  } else if (t->rot) {
    frames_of(t, F0, t->frames, NULL);
    /* R^T_i: the rotation of each one-ring from the source's rest to F0, fitted (Procrustes)
     * from the first guess F_F0(i)^T F_S(i). */
    for (size_t i = 0; i < n; ++i) {
      const double *Ft = t->frames + 9 * i, *Fs = t->frames_rest + 9 * i;
      double *R = t->rot + 9 * i;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          R[3 * r + c] = Ft[r] * Fs[c] + Ft[3 + r] * Fs[3 + c] + Ft[6 + r] * Fs[6 + c];
    }
    rotations_init(t, F0);
  } else {
    frames_of(t, F0, t->frames, NULL);
  }
  t->n_energy = 0;
  t->energy_pending = false;
  double frames_s = km_seconds() - tf, solve_s = 0;
  int it = 0;
  bool converged = false;
  double dx = INFINITY, dF = INFINITY;
  for (it = 0; it < t->opt.max_iterations; ++it) {
    double ts = km_seconds();
    if (t->rot) {
      /* The ARAP global step: each edge rotated by both ends' rotations,
       * rhs_i = sum_j w_ij (R_i + R_j) e_ij / 2 = R_i Delta_i / 2 + sum_j R_j e_b. */
#pragma omp parallel for schedule(static) if (nf > KM__OMP_MIN)
      for (size_t f = 0; f < nf; ++f) {
        size_t v = (size_t)t->free_vtx[f];
        const double *Ri = t->rot + 9 * v, *w = t->W + 3 * v;
        double acc[3];
        for (int c = 0; c < 3; ++c)
          acc[c] = 0.5 * (Ri[3 * c] * w[0] + Ri[3 * c + 1] * w[1] + Ri[3 * c + 2] * w[2]);
        for (int32_t e = t->e_ptr[f]; e < t->e_ptr[f + 1]; ++e) {
          const double *Rj = t->rot + 9 * (size_t)t->e_nbr[e], *b = t->e_b + 3 * e;
          for (int c = 0; c < 3; ++c)
            acc[c] += Rj[3 * c] * b[0] + Rj[3 * c + 1] * b[1] + Rj[3 * c + 2] * b[2];
        }
        for (int c = 0; c < 3; ++c)
          t->rhs[c * nf + f] = -acc[c];
      }
    } else {
      for (size_t f = 0; f < nf; ++f) {
        size_t v = (size_t)t->free_vtx[f];
        const double *F = t->frames + 9 * v, *w = t->W + 3 * v;
        for (int c = 0; c < 3; ++c)
          t->rhs[c * nf + f] = -(F[c] * w[0] + F[3 + c] * w[1] + F[6 + c] * w[2]);
      }
    }
    for (size_t c = 0; c < nc; ++c)
      for (int32_t p = t->lfc_ptr[c]; p < t->lfc_ptr[c + 1]; ++p) {
        size_t f = (size_t)t->lfc_row[p];
        double l = t->lfc_val[p];
        t->rhs[f] += l * t->tgt[3 * c];
        t->rhs[nf + f] += l * t->tgt[3 * c + 1];
        t->rhs[2 * nf + f] += l * t->tgt[3 * c + 2];
      }
    /* solved in place: the right-hand side is rebuilt from scratch every iteration */
    km_status ss = km_cholesky_solve(t->chol, 3, t->rhs, t->rhs, err);
    if (ss) return ss;
    const double *xs = t->rhs;
    /* Scatter, measuring the largest move on the way (landmarks sit at their targets from
     * the first solve on, so only free vertices move afterwards). */
    if (it == 0) {
      for (size_t f = 0; f < nf; ++f) {
        double *o = V_out + 3 * (size_t)t->free_vtx[f];
        o[0] = xs[f], o[1] = xs[nf + f], o[2] = xs[2 * nf + f];
      }
      for (size_t c = 0; c < nc; ++c)
        memcpy(V_out + 3 * (size_t)t->lm[c], t->tgt + 3 * c, 3 * sizeof(double));
    } else {
      double m2 = 0;
      for (size_t f = 0; f < nf; ++f) {
        double *o = V_out + 3 * (size_t)t->free_vtx[f];
        double a = xs[f] - o[0], b2 = xs[nf + f] - o[1], c = xs[2 * nf + f] - o[2];
        double d2 = a * a + b2 * b2 + c * c;
        if (d2 > m2) m2 = d2;
        o[0] = xs[f], o[1] = xs[nf + f], o[2] = xs[2 * nf + f];
      }
      dx = sqrt(m2) / t->diag;
    }
    double te = km_seconds();
    solve_s += te - ts;
    bool last = it + 1 == t->opt.max_iterations;
    if (t->rot) {
      /* The local step: the energy of this solve and new stretches; after the last solve
       * only the energy, evaluated when asked for (km_transfer_energies). */
      double dR = NAN;
      if (last) {
        memcpy(t->x_last, V_out, n * 3 * sizeof(double));
        t->energy[t->n_energy++] = NAN;
        t->energy_pending = true;
      } else {
        t->energy[t->n_energy++] = local_step(t, V_out, true, &dR);
      }
      dF = dR;
    } else if (!last) {
      /* After the last allowed solve the frames would only feed the convergence test. The
       * frame change is only measured once positions have settled: both must be small to
       * stop. */
      bool settled = it > 0 && dx < t->opt.tolerance;
      dF = frames_of(t, V_out, t->frames_new, settled ? t->frames : NULL);
      if (!settled) dF = NAN;
      double *sw = t->frames;
      t->frames = t->frames_new;
      t->frames_new = sw;
    }
    frames_s += km_seconds() - te;
    if (!last && it > 0 && dx < t->opt.tolerance && dF < t->opt.tolerance) {
      converged = true;
      ++it;
      break;
    }
  }
  if (stats) {
    stats->iterations = it;
    stats->converged = converged;
    stats->position_change = dx;
    stats->frame_change = dF;
    stats->frames_ms = frames_s * 1e3;
    stats->solve_ms = solve_s * 1e3;
    stats->total_ms = (km_seconds() - t_start) * 1e3;
  }
  return KM_OK;
}

km_status km_transfer_solve_rotations(km_transfer *t, const double *R, const double *targets,
                                      double *V_out, km_transfer_stats *stats, km_error *err) {
  if (!t || !R || !targets || !V_out)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_solve_rotations: NULL argument");
  if (t->welded) {
    for (size_t i = 0; i < t->n * 9; ++i)
      if (!isfinite(R[i]))
        return km__fail(err, KM_ERR_INVALID,
                        "km_transfer_solve_rotations: rotation %zu is not finite", i / 9);
    km_status sw = km_transfer_solve_rotations(t->welded, gather(t, R, t->w_R, 9), targets, t->w_V,
                                               stats, err);
    if (sw == KM_OK) scatter(t, t->w_V, V_out);
    return sw;
  }
  if (!t->rot)
    return km__fail(err, KM_ERR_INVALID,
                    "km_transfer_solve_rotations: needs the edge encoding (the default)");
  for (size_t i = 0; i < t->n * 9; ++i)
    if (!isfinite(R[i]))
      return km__fail(err, KM_ERR_INVALID,
                      "km_transfer_solve_rotations: rotation %zu is not "
                      "finite",
                      i / 9);
  t->given_rot = R;
  km_status s = km_transfer_solve(t, NULL, targets, t->rest, V_out, stats, err);
  t->given_rot = NULL;
  return s;
}

km_status km_transfer_template_rotations(const km_mesh *rest, const double *posed, double *R,
                                         km_error *err) {
  if (!rest || !rest->V || !rest->F || !posed || !R)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_template_rotations: NULL argument");
  km_sparse *L = NULL;
  km_status s = km_uniform_laplacian(rest, &L, err);
  if (s) return s;
  const int32_t *cp, *ri;
  const double *val;
  km_sparse_csc(L, &cp, &ri, &val);
  for (size_t i = 0; i < rest->n_vertices; ++i) {
    double C[9] = {0};
    const double *xi = posed + 3 * i, *si = rest->V + 3 * i;
    for (int32_t p = cp[i]; p < cp[i + 1]; ++p) {
      size_t j = (size_t)ri[p];
      if (j == i) continue;
      double d[3], e[3];
      km__sub3(posed + 3 * j, xi, d);
      km__sub3(rest->V + 3 * j, si, e);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          C[3 * r + c] += d[r] * e[c];
    }
    if (cp[i + 1] - cp[i] > 1)
      km__nearest_rotation3(C, R + 9 * i);
    else
      km__m3_identity(R + 9 * i); /* an isolated vertex */
  }
  km_sparse_free(&L);
  return KM_OK;
}

km_status km_transfer_correspondence(const km_mesh *source_rest, const km_mesh *template_rest,
                                     int32_t *corr, km_error *err) {
  if (!source_rest || !source_rest->V || !template_rest || !template_rest->V || !corr)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_correspondence: NULL argument");
  size_t nt = template_rest->n_vertices;
  if (!nt) return km__fail(err, KM_ERR_INVALID, "km_transfer_correspondence: empty template");
  /* A uniform grid over the template's vertices, searched in growing shells. */
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < nt; ++v)
    for (int k = 0; k < 3; ++k) {
      lo[k] = fmin(lo[k], template_rest->V[3 * v + k]);
      hi[k] = fmax(hi[k], template_rest->V[3 * v + k]);
    }
  double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  if (!(ext > 0) || !isfinite(ext))
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "km_transfer_correspondence: template has no "
                    "extent");
  int g = (int)fmax(1, fmin(64, cbrt((double)nt / 2)));
  double cell = ext / g * (1 + 1e-9);
  size_t ncell = (size_t)g * g * g;
  int32_t *head = km__malloc(ncell, sizeof *head), *next = km__malloc(nt, sizeof *next);
  if (!head || !next) {
    free(head);
    free(next);
    return km__fail(err, KM_ERR_NOMEM, "km_transfer_correspondence: out of memory");
  }
  for (size_t c = 0; c < ncell; ++c)
    head[c] = -1;
#define KM__CELL(x, k) ((int)fmin(g - 1, fmax(0, floor(((x)-lo[k]) / cell))))
  for (size_t v = 0; v < nt; ++v) {
    const double *p = template_rest->V + 3 * v;
    size_t c = ((size_t)KM__CELL(p[0], 0) * g + KM__CELL(p[1], 1)) * g + KM__CELL(p[2], 2);
    next[v] = head[c];
    head[c] = (int32_t)v;
  }
  for (size_t i = 0; i < source_rest->n_vertices; ++i) {
    const double *q = source_rest->V + 3 * i;
    int c0[3] = {KM__CELL(q[0], 0), KM__CELL(q[1], 1), KM__CELL(q[2], 2)};
    double best = INFINITY;
    int32_t bi = 0;
    for (int r = 0; r < g; ++r) {
      /* shell r: cells at Chebyshev distance r; stop once no closer point can lie further out */
      for (int a = c0[0] - r; a <= c0[0] + r; ++a)
        for (int b = c0[1] - r; b <= c0[1] + r; ++b)
          for (int d = c0[2] - r; d <= c0[2] + r; ++d) {
            if (a < 0 || b < 0 || d < 0 || a >= g || b >= g || d >= g) continue;
            if (abs(a - c0[0]) != r && abs(b - c0[1]) != r && abs(d - c0[2]) != r) continue;
            for (int32_t v = head[((size_t)a * g + b) * g + d]; v >= 0; v = next[v]) {
              const double *p = template_rest->V + 3 * (size_t)v;
              double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
              double d2 = dx * dx + dy * dy + dz * dz;
              if (d2 < best) best = d2, bi = v;
            }
          }
      if (best < INFINITY && sqrt(best) <= r * cell) break;
    }
    corr[i] = bi;
  }
#undef KM__CELL
  free(head);
  free(next);
  return KM_OK;
}

km_status km_transfer_map_pose(const km_mesh *source_rest, const km_mesh *template_rest,
                               const double *template_posed, const int32_t *corr,
                               const int32_t *landmarks, size_t n_landmarks, double *R,
                               double *targets, km_error *err) {
  if (!source_rest || !source_rest->V || !template_rest || !template_posed || !corr || !R ||
      (n_landmarks && (!landmarks || !targets)))
    return km__fail(err, KM_ERR_INVALID, "km_transfer_map_pose: NULL argument");
  size_t n = source_rest->n_vertices, nt = template_rest->n_vertices;
  for (size_t i = 0; i < n; ++i)
    if (corr[i] < 0 || (size_t)corr[i] >= nt)
      return km__fail(err, KM_ERR_INVALID,
                      "km_transfer_map_pose: correspondence %zu is %d, "
                      "expected 0..%zu",
                      i, (int)corr[i], nt - 1);
  for (size_t l = 0; l < n_landmarks; ++l)
    if (landmarks[l] < 0 || (size_t)landmarks[l] >= n)
      return km__fail(err, KM_ERR_INVALID, "km_transfer_map_pose: landmark %zu is vertex %d", l,
                      (int)landmarks[l]);
  double *RT = km__malloc(nt * 9, sizeof *RT);
  if (!RT) return km__fail(err, KM_ERR_NOMEM, "km_transfer_map_pose: out of memory");
  km_status s = km_transfer_template_rotations(template_rest, template_posed, RT, err);
  if (s) {
    free(RT);
    return s;
  }
  for (size_t i = 0; i < n; ++i)
    memcpy(R + 9 * i, RT + 9 * (size_t)corr[i], 9 * sizeof(double));
  /* A landmark lies off its template vertex by up to half an edge: carry the offset along,
   * turned by that vertex's rotation. */
  for (size_t l = 0; l < n_landmarks; ++l) {
    size_t v = (size_t)landmarks[l], c = (size_t)corr[v];
    double d[3], rd[3];
    km__sub3(source_rest->V + 3 * v, template_rest->V + 3 * c, d);
    km__m3_apply(RT + 9 * c, d, rd);
    for (int k = 0; k < 3; ++k)
      targets[3 * l + k] = template_posed[3 * c + k] + rd[k];
  }
  free(RT);
  return KM_OK;
}

km_status km_transfer_register_rest(const km_mesh *source_rest, const km_mesh *template_rest,
                                    const int32_t *pairs, size_t n_pairs, double *registered,
                                    double *scale, double Q[9], double t[3], km_error *err) {
  if (!source_rest || !source_rest->V || !template_rest || !template_rest->V || !pairs ||
      !registered || !scale || !Q || !t)
    return km__fail(err, KM_ERR_INVALID, "km_transfer_register_rest: NULL argument");
  if (n_pairs < 3)
    return km__fail(err, KM_ERR_INVALID,
                    "km_transfer_register_rest: %zu correspondence(s), at least 3 are needed",
                    n_pairs);
  size_t n = source_rest->n_vertices, nt = template_rest->n_vertices;
  for (size_t k = 0; k < n_pairs; ++k)
    if (pairs[2 * k] < 0 || (size_t)pairs[2 * k] >= n || pairs[2 * k + 1] < 0 ||
        (size_t)pairs[2 * k + 1] >= nt)
      return km__fail(err, KM_ERR_INVALID,
                      "km_transfer_register_rest: correspondence %zu is (%d, %d), expected "
                      "source 0..%zu, template 0..%zu",
                      k, (int)pairs[2 * k], (int)pairs[2 * k + 1], n ? n - 1 : 0, nt ? nt - 1 : 0);
  double *src = km__malloc(n_pairs * 6, sizeof *src);
  if (!src) return km__fail(err, KM_ERR_NOMEM, "km_transfer_register_rest: out of memory");
  double *dst = src + 3 * n_pairs;
  for (size_t k = 0; k < n_pairs; ++k) {
    memcpy(src + 3 * k, source_rest->V + 3 * (size_t)pairs[2 * k], 3 * sizeof(double));
    memcpy(dst + 3 * k, template_rest->V + 3 * (size_t)pairs[2 * k + 1], 3 * sizeof(double));
  }
  km_status s = km_similarity_fit(src, dst, NULL, n_pairs, true, scale, Q, t, err);
  free(src);
  if (s) return km__wrap(err, s, "km_transfer_register_rest: fitting the correspondences");
  if (!(*scale > 0) || !isfinite(*scale))
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "km_transfer_register_rest: the correspondences give scale %g", *scale);
  for (size_t i = 0; i < n; ++i) {
    double p[3];
    km__m3_apply(Q, source_rest->V + 3 * i, p);
    for (int k = 0; k < 3; ++k)
      registered[3 * i + k] = *scale * p[k] + t[k];
  }
  return KM_OK;
}

void km_transfer_pose_to_source(double scale, const double Q[9], const double t[3],
                                const double *local, size_t n_vertices, double *R,
                                size_t n_landmarks, double *targets) {
  double Qt[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      Qt[3 * r + c] = Q[3 * c + r];
  for (size_t i = 0; i < n_vertices && R; ++i) {
    double A[9], *Ri = R + 9 * i;
    if (local) {
      /* the pose seen from the one-ring before the non-rigid step: L^T R L */
      const double *L = local + 9 * i;
      double Lt[9];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          Lt[3 * r + c] = L[3 * c + r];
      km__m3_mul(Ri, L, A);
      km__m3_mul(Lt, A, Ri);
    }
    km__m3_mul(Qt, Ri, A);
    km__m3_mul(A, Q, Ri);
  }
  for (size_t l = 0; l < n_landmarks && targets; ++l) {
    double d[3], p[3];
    km__sub3(targets + 3 * l, t, d);
    km__m3_apply(Qt, d, p);
    for (int k = 0; k < 3; ++k)
      targets[3 * l + k] = p[k] / scale;
  }
}
