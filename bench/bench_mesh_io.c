/* Read time of mesh files: median of 5 reads each. Usage: bench_mesh_io FILE... */
#include "kinemesh.h"

#include <stdio.h>
#include <stdlib.h>

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

int main(int argc, char **argv) {
  for (int i = 1; i < argc; ++i) {
    double t[5];
    km_mesh m = {0};
    km_error err;
    for (int r = 0; r < 5; ++r) {
      km_mesh_free(&m);
      double t0 = km_seconds();
      if (km_mesh_read(argv[i], &m, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
      }
      t[r] = km_seconds() - t0;
    }
    qsort(t, 5, sizeof t[0], cmp_double);
    printf("%s: %zu vertices, %zu faces, read median %.2f ms (min %.2f)\n", argv[i], m.n_vertices,
           m.n_faces, 1e3 * t[2], 1e3 * t[0]);
    const char *outs[] = {"/tmp/bench_mesh_io.obj", "/tmp/bench_mesh_io.ply",
                          "/tmp/bench_mesh_io.off"};
    for (int k = 0; k < 3; ++k) {
      double t0 = km_seconds();
      if (km_mesh_write(outs[k], &m, NULL, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
      }
      printf("  write %s: %.2f ms\n", outs[k], 1e3 * (km_seconds() - t0));
      remove(outs[k]);
    }
    km_mesh_free(&m);
  }
  return 0;
}
