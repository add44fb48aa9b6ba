/* Verbs over single meshes: info, convert, eigen. */
#include "cli.h"

#include <cjson/cJSON.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static bool is_anim_path(const char *path) {
  struct stat st;
  if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) return true;
  size_t n = strlen(path);
  return (n > 4 && (!strcasecmp(path + n - 4, ".glb") || !strcasecmp(path + n - 4, ".pc2")));
}

static cJSON *vec3(const double *v) {
  cJSON *a = cJSON_CreateArray();
  for (int i = 0; i < 3; ++i)
    cJSON_AddItemToArray(a, cJSON_CreateNumber(v[i]));
  return a;
}

static int print_json(cJSON *root) {
  char *s = cJSON_Print(root);
  cJSON_Delete(root);
  if (!s) return km_cli_error("info", "out of memory");
  puts(s);
  free(s);
  return KM_EXIT_OK;
}

static const char *anim_format_name(km_anim_format f) {
  switch (f) {
  case KM_ANIM_GLB: return "glb";
  case KM_ANIM_PC2: return "pc2";
  case KM_ANIM_OBJ_DIR: return "obj-dir";
  case KM_ANIM_PLY_DIR: return "ply-dir";
  default: return "unknown";
  }
}

int km_cli_info(int argc, char **argv) {
  bool json = false;
  const km_cli_opt opts[] = {{"json", 0, KM_OPT_FLAG, &json, "print JSON instead of text"}};
  const char *pos[1];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, 1, pos, 1, &n_pos, "kinemesh info FILE [--json]",
                       "Mesh (OBJ/PLY/OFF): vertex/face counts, topology counts and bounding box.\n"
                       "Animation (.glb, .pc2, frame directory): frames, vertices, frame rate.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("info", "expected one FILE (see kinemesh info --help)");
  km_error err = {0};
  const char *path = pos[0];

  if (is_anim_path(path)) {
    km_anim_info ai;
    if (km_anim_info_read(path, &ai, &err) != KM_OK) return km_cli_fail("info", &err);
    if (json) {
      cJSON *o = cJSON_CreateObject();
      cJSON_AddStringToObject(o, "file", path);
      cJSON_AddStringToObject(o, "format", anim_format_name(ai.format));
      cJSON_AddNumberToObject(o, "frames", (double)ai.frames);
      cJSON_AddNumberToObject(o, "vertices", (double)ai.vertices);
      cJSON_AddNumberToObject(o, "faces", (double)ai.faces);
      cJSON_AddNumberToObject(o, "fps", ai.fps);
      cJSON_AddNumberToObject(o, "duration_s", ai.duration);
      return print_json(o);
    }
    printf("file        %s\nformat      %s\nframes      %zu\nvertices    %zu\nfaces       %zu\n",
           path, anim_format_name(ai.format), ai.frames, ai.vertices, ai.faces);
    if (ai.fps > 0)
      printf("frame rate  %g fps\nduration    %.3f s\n", ai.fps, ai.duration);
    else
      printf("frame rate  not stored in this format\n");
    return KM_EXIT_OK;
  }

  km_mesh m = {0};
  if (km_mesh_read(path, &m, &err) != KM_OK) return km_cli_fail("info", &err);
  km_mesh_info info;
  km_status s = km_mesh_info_compute(&m, &info, &err);
  km_mesh_free(&m);
  if (s != KM_OK) return km_cli_fail("info", &err);
  if (json) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "file", path);
    cJSON_AddNumberToObject(o, "vertices", (double)info.vertices);
    cJSON_AddNumberToObject(o, "faces", (double)info.faces);
    cJSON_AddNumberToObject(o, "edges", (double)info.edges);
    cJSON_AddNumberToObject(o, "boundary_edges", (double)info.boundary_edges);
    cJSON_AddNumberToObject(o, "nonmanifold_edges", (double)info.nonmanifold_edges);
    cJSON_AddNumberToObject(o, "nonmanifold_vertices", (double)info.nonmanifold_vertices);
    cJSON_AddNumberToObject(o, "components", (double)info.components);
    cJSON_AddNumberToObject(o, "isolated_vertices", (double)info.isolated_vertices);
    cJSON_AddNumberToObject(o, "degenerate_faces", (double)info.degenerate_faces);
    cJSON_AddNumberToObject(o, "euler_characteristic", (double)info.euler_characteristic);
    cJSON_AddItemToObject(o, "bbox_min", vec3(info.bbox_min));
    cJSON_AddItemToObject(o, "bbox_max", vec3(info.bbox_max));
    return print_json(o);
  }
  printf("file                  %s\n", path);
  printf("vertices              %zu\nfaces                 %zu\nedges                 %zu\n",
         info.vertices, info.faces, info.edges);
  printf("boundary edges        %zu\nnon-manifold edges    %zu\nnon-manifold vertices %zu\n",
         info.boundary_edges, info.nonmanifold_edges, info.nonmanifold_vertices);
  printf("components            %zu\nisolated vertices     %zu\ndegenerate faces      %zu\n",
         info.components, info.isolated_vertices, info.degenerate_faces);
  printf("euler characteristic  %lld\n", (long long)info.euler_characteristic);
  printf("bbox min              %.6g %.6g %.6g\nbbox max              %.6g %.6g %.6g\n",
         info.bbox_min[0], info.bbox_min[1], info.bbox_min[2], info.bbox_max[0], info.bbox_max[1],
         info.bbox_max[2]);
  return KM_EXIT_OK;
}

int km_cli_convert(int argc, char **argv) {
  const char *ply = NULL;
  const km_cli_opt opts[] = {
      {"ply", 0, KM_OPT_STRING, &ply, "PLY encoding: binary (default), binary-be, ascii"}};
  const char *pos[2];
  int n_pos;
  int r = km_cli_parse(argc, argv, opts, 1, pos, 2, &n_pos, "kinemesh convert IN OUT [--ply ascii]",
                       "Converts between OBJ, PLY and OFF by file extension. Vertex order and\n"
                       "coordinates are kept exactly; polygons are fan-triangulated.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 2)
    return km_cli_error("convert", "expected IN and OUT (see kinemesh convert --help)");
  km_mesh_write_options wo = {0};
  if (ply) {
    if (!strcmp(ply, "binary") || !strcmp(ply, "binary-le"))
      wo.ply = KM_PLY_BINARY_LE;
    else if (!strcmp(ply, "binary-be"))
      wo.ply = KM_PLY_BINARY_BE;
    else if (!strcmp(ply, "ascii"))
      wo.ply = KM_PLY_ASCII;
    else
      return km_cli_error("convert", "--ply must be binary, binary-be or ascii, not '%s'", ply);
  }
  km_error err = {0};
  km_mesh m = {0};
  if (km_mesh_read(pos[0], &m, &err) != KM_OK) return km_cli_fail("convert", &err);
  km_status s = km_mesh_write(pos[1], &m, &wo, &err);
  size_t nv = m.n_vertices, nf = m.n_faces;
  km_mesh_free(&m);
  if (s != KM_OK) return km_cli_fail("convert", &err);
  fprintf(stderr, "kinemesh convert: wrote %s (%zu vertices, %zu triangles)\n", pos[1], nv, nf);
  return KM_EXIT_OK;
}

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
    rc = print_json(o);
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
