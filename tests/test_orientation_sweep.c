/* The orientation guess (issue 11) swept over every mesh of ../shared/data (meshes/, poses/,
 * poses/cat-poses/) in all 24 axis-aligned frames: each mesh is brought into kinemesh's frame
 * (y up, facing +z) from how its file is stored (looked at in renders: the npt_* and FAUST
 * bodies and the cats are y up facing +z; see test_orientation.c for the others), then written
 * in each of the 24 frames f (in memory), and km_mesh_frame_guess must name f. Twice: as
 * stored (rotated about the origin, so a model standing on the ground plane stays on it) and
 * centred (only the shape tells). Prints the tables (up right, up and forward right, of 24,
 * per mesh) and asserts counts that can fail. Known wrong: npt_13 (a man leaning back, one
 * leg kicked up: his back is the widest support; guessed unsure, since a body lying so is as
 * wide as long), and centred, the elephant (top-heavy: its
 * head and ears outspan its two feet), cat-04 (lying on its side) and cat-07 (curled up).
 *   test_orientation_sweep [-v]   (-v: every wrong guess with its evidence) */
#include "km_test.h"

typedef struct sweep_case {
  const char *rel;
  km_axis up, forward; /* how the file is stored */
  bool fwd_defined;    /* false: a person cannot tell forward (a cat curled up asleep) */
  /* known wrong (see below), as stored and centred: not asserted */
  bool wrong_stored, wrong_centred;
} sweep_case;

static const sweep_case k_cases[] = {
    {"meshes/armadillo.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"meshes/armadillo_1k.off", KM_AXIS_POS_Y, KM_AXIS_NEG_Z, true, false, false},
    {"meshes/bunny.off", KM_AXIS_POS_Y, KM_AXIS_NEG_X, true, false, false},
    {"meshes/decimated-knight.off", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"meshes/dino.off", KM_AXIS_NEG_Z, KM_AXIS_NEG_X, true, false, false},
    {"meshes/dog0.off", KM_AXIS_POS_Z, KM_AXIS_NEG_Y, true, false, false},
    {"meshes/elephant.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, true},
    {"meshes/horse.ply", KM_AXIS_POS_Z, KM_AXIS_POS_Y, true, false, false},
    {"poses/npt_13_643.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, true, true},
    {"poses/npt_14_664.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/tr_reg_000.off", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/tr_reg_001.off", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/tr_reg_010.off", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/tr_reg_025.ply", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/tr_reg_095.ply", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-reference.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-01.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-02.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-03.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-04.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, true},
    {"poses/cat-poses/cat-05.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-06.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-07.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, false, false, true},
    {"poses/cat-poses/cat-08.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
    {"poses/cat-poses/cat-09.obj", KM_AXIS_POS_Y, KM_AXIS_POS_Z, true, false, false},
};
#define N_CASES (sizeof k_cases / sizeof k_cases[0])

typedef struct sweep_row {
  int up_right, both_right, n;
  int sure_wrong, unsure_right; /* sure_up and sure_forward with a wrong guess; not, right */
  bool orig_up, orig_both;
} sweep_row;

/* c in kinemesh's frame, swept through the 24 frames (the identity among them). */
static void sweep(const km_mesh *c, const char *label, bool fwd_defined, bool verbose,
                  sweep_row *row) {
  memset(row, 0, sizeof *row);
  km_mesh r = {0};
  CHECK_OK(km_mesh_copy(c, &r, KM_E));
  if (!r.V) return;
  for (int u = KM_AXIS_POS_X; u <= KM_AXIS_NEG_Z; ++u)
    for (int w = KM_AXIS_POS_X; w <= KM_AXIS_NEG_Z; ++w) {
      if ((u - 1) / 2 == (w - 1) / 2) continue;
      km_frame f = {(km_axis)u, (km_axis)w, 0};
      km_test_to_frame(&f, c->V, r.V, r.n_vertices); /* the file's coordinates */
      km_frame_guess g;
      CHECK_OK(km_mesh_frame_guess(&r, &g, KM_E));
      bool up = g.frame.up == f.up, both = up && g.frame.forward == f.forward;
      bool identity = u == KM_AXIS_POS_Y && w == KM_AXIS_POS_Z;
      row->n++;
      row->up_right += up;
      row->both_right += both;
      bool sure = g.sure_up && (g.sure_forward || !fwd_defined);
      bool right = fwd_defined ? both : up;
      row->sure_wrong += sure && !right;
      row->unsure_right += !sure && right;
      if (identity) row->orig_up = up, row->orig_both = both;
      if (verbose && !both)
        printf("  %s stored up %s forward %s: guessed up %s forward %s (%s%s) %s\n", label,
               km_axis_name(f.up), km_axis_name(f.forward), km_axis_name(g.frame.up),
               km_axis_name(g.frame.forward), g.sure_up ? "sure up" : "unsure up",
               g.sure_forward ? ", sure forward" : "", g.why);
    }
  km_mesh_free(&r);
}

/* Sweeps every mesh found, as stored (centred false: the origin moves with the rotation, so a
 * model standing on the ground plane at the origin still does) or with its bounding box
 * centred on the origin (centred true: only the shape tells); prints the table, asserts that
 * each mesh not known wrong is right as stored, returns the number of meshes found. */
static int sweep_all(bool centred, bool verbose, int *up_total, int *both_total, int *n_total,
                     int *both_n, int *sure_wrong_out) {
  int found = 0, orig_right = 0, orig_n = 0;
  *up_total = *both_total = *n_total = *both_n = 0;
  int sure_wrong = 0, unsure_right = 0;
  printf("%s:\n%-36s %8s %8s %8s %10s %12s\n", centred ? "centred on the origin" : "as stored",
         "mesh (24 axis-aligned frames)", "original", "up", "up+fwd", "sure,wrong", "unsure,right");
  for (size_t k = 0; k < N_CASES; ++k) {
    const sweep_case *sc = &k_cases[k];
    char buf[1024];
    const char *path = km_test_shared(sc->rel, buf, sizeof buf);
    if (!path) continue;
    km_mesh m = {0};
    CHECK_OK(km_mesh_read(path, &m, KM_E));
    if (!m.n_vertices) continue;
    ++found;
    km_frame f = {sc->up, sc->forward, 0};
    CHECK_OK(km_mesh_frame_apply(&f, &m, KM_E));
    if (centred) {
      double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
      for (size_t i = 0; i < m.n_vertices; ++i)
        for (int a = 0; a < 3; ++a)
          lo[a] = fmin(lo[a], m.V[3 * i + a]), hi[a] = fmax(hi[a], m.V[3 * i + a]);
      for (size_t i = 0; i < m.n_vertices; ++i)
        for (int a = 0; a < 3; ++a)
          m.V[3 * i + a] -= 0.5 * (lo[a] + hi[a]);
    }
    sweep_row r;
    sweep(&m, sc->rel, sc->fwd_defined, verbose, &r);
    km_mesh_free(&m);
    bool fd = sc->fwd_defined, right = fd ? r.orig_both : r.orig_up;
    bool known = centred ? sc->wrong_centred : sc->wrong_stored;
    printf("%-36s %8s %5d/%d %5d/%d %10d %12d%s%s\n", sc->rel, right ? "right" : "WRONG",
           r.up_right, r.n, r.both_right, r.n, r.sure_wrong, r.unsure_right,
           fd ? "" : " (forward undefined)", known ? " (known wrong)" : "");
    sure_wrong += r.sure_wrong, unsure_right += r.unsure_right;
    if (!known) {
      CHECK_MSG(right, "%s%s: guessed wrong in its own frame", sc->rel,
                centred ? " (centred)" : "");
      ++orig_n, orig_right += right;
    }
    *up_total += r.up_right;
    *n_total += r.n;
    if (fd) *both_total += r.both_right, *both_n += r.n;
  }
  printf("total: up right %d/%d, up and forward right %d/%d (forward-defined meshes), in its own "
         "frame %d of the %d not known wrong; %d wrong guesses said sure, %d right ones unsure\n\n",
         *up_total, *n_total, *both_total, *both_n, orig_right, orig_n, sure_wrong, unsure_right);
  *sure_wrong_out = sure_wrong;
  return found;
}

/* A coordinate that is not finite (only the API lets one in: the readers refuse them) leaves
 * the guess defined: no crash, no undefined cast to a grid cell. */
static void test_not_finite(void) {
  double V[] = {0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 1, NAN, 1, 0.5, 0.5, INFINITY, 0.5};
  int32_t F[] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2, 0, 1, 4, 2, 3, 5};
  km_mesh m = {0};
  m.V = V, m.F = F, m.n_vertices = 6, m.n_faces = 6;
  km_frame_guess g;
  km_status st = km_mesh_frame_guess(&m, &g, NULL);
  CHECK(st == KM_OK || st == KM_ERR_INVALID);
}

int main(int argc, char **argv) {
  bool verbose = argc > 1 && !strcmp(argv[1], "-v");
  test_not_finite();
  int up, both, n, both_n, sure_wrong;
  int found = sweep_all(false, verbose, &up, &both, &n, &both_n, &sure_wrong);
  if (!found) {
    printf("SKIP: no mesh of ../shared/data found\n");
    return KM_TEST_SKIP;
  }
  /* With every mesh present: the counts reached (issue 11's sweep), less a small margin
   * (before the changes this sweep measured: up 528/600, up and forward 456/576 as stored;
   * centred, before the lateral-axis rule: 456 and 456). */
  if (found == (int)N_CASES) {
    CHECK_MSG(up >= 570, "as stored: up right in %d of %d", up, n);
    CHECK_MSG(both >= 545, "as stored: up and forward right in %d of %d", both, both_n);
    /* no wrong guess is called sure (npt_13, lying on his back as guessed, is as wide as
     * long: not a four-legged stance, so its up is unsure) */
    CHECK_MSG(sure_wrong == 0, "as stored: %d wrong guesses said sure", sure_wrong);
  }
  found = sweep_all(true, verbose, &up, &both, &n, &both_n, &sure_wrong);
  if (found == (int)N_CASES) {
    CHECK_MSG(up >= 495, "centred: up right in %d of %d", up, n);
    CHECK_MSG(both >= 495, "centred: up and forward right in %d of %d", both, both_n);
    CHECK_MSG(sure_wrong == 0, "centred: %d wrong guesses said sure", sure_wrong);
  }
  return km_test_finish("test_orientation_sweep");
}
