/* kinemesh eigen: the smallest eigenvalues of the cotangent Laplacian (ARPACK shift-invert). */
#include "cli.h"

#include <cjson/cJSON.h>
#include <stdlib.h>
#include <string.h>

int km_cli_eigen(int argc, char **argv) {
  int k = 9;
  bool json = false, timing = false;
  const char *mass = NULL;
  const km_cli_opt opts[] = {
      {"k", 'k', KM_OPT_INT, &k, "number of eigenpairs, the smallest, including ~0 (default 9)"},
      {"json", 0, KM_OPT_FLAG, &json, "print {\"eigenvalues\": [...]}"},
      {"mass", 0, KM_OPT_STRING, &mass, "mass matrix: voronoi (default) or barycentric"},
      {"timing", 0, KM_OPT_FLAG, &timing, "print the time of each stage to stderr"},
  };
  const char *pos[1];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 1, &n_pos,
                   "kinemesh eigen MESH [-k 9] [--json]",
                   "The k smallest eigenvalues of -L phi = lambda M phi (cotangent Laplacian L,\n"
                   "lumped mass M), ascending, by ARPACK shift-invert on a CHOLMOD factor.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("eigen", "expected one MESH (see kinemesh eigen --help)");
  if (k < 1) return km_cli_error("eigen", "-k must be at least 1");
  km_mass_type mt = KM_MASS_VORONOI;
  if (mass && !strcmp(mass, "barycentric"))
    mt = KM_MASS_BARYCENTRIC;
  else if (mass && strcmp(mass, "voronoi"))
    return km_cli_error("eigen", "--mass must be voronoi or barycentric, not '%s'", mass);

  km_error err = {0};
  km_mesh m = {0};
  km_sparse *L = NULL, *M = NULL;
  double *evals = NULL;
  int rc = KM_EXIT_FAIL;
  double t0 = 0, t_read = 0, t_ops = 0, t_eig = 0;
  t0 = km_cli_now();
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) goto fail;
  t_read = km_cli_now();
  if ((size_t)k > m.n_vertices) {
    rc = km_cli_error("eigen", "-k %d exceeds the %zu vertices of %s", k, m.n_vertices, pos[0]);
    goto done;
  }
  if (km_cotmatrix(&m, &L, &err) != KM_OK || km_massmatrix(&m, mt, &M, &err) != KM_OK) goto fail;
  t_ops = km_cli_now();
  evals = malloc(sizeof(double) * (size_t)k);
  if (!evals) {
    rc = km_cli_error("eigen", "out of memory");
    goto done;
  }
  km_eigs_options eo = {0};
  if (!json && !timing) eo.progress = km_cli_progress("eigen");
  if (km_eigs(L, M, k, &eo, evals, NULL, &err) != KM_OK) goto fail;
  t_eig = km_cli_now();
  km_cli_progress_done();
  if (json) {
    cJSON *o = cJSON_CreateObject();
    cJSON *a = cJSON_AddArrayToObject(o, "eigenvalues");
    for (int i = 0; i < k; ++i)
      cJSON_AddItemToArray(a, cJSON_CreateNumber(evals[i]));
    rc = km_cli_print_json("eigen", o);
  } else {
    for (int i = 0; i < k; ++i)
      printf("%.12g\n", evals[i]);
    rc = KM_EXIT_OK;
  }
  if (timing)
    fprintf(stderr,
            "kinemesh eigen: %zu vertices; read %.3f s, laplacian+mass %.3f s, eigs %.3f s\n",
            m.n_vertices, t_read - t0, t_ops - t_read, t_eig - t_ops);
  goto done;
fail:
  rc = km_cli_fail("eigen", &err);
done:
  free(evals);
  km_sparse_free(&L);
  km_sparse_free(&M);
  km_mesh_free(&m);
  return rc;
}
