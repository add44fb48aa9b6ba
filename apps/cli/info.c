/* kinemesh info: topology counts and extent of a mesh, or a description of an animation
 * (.glb, .pc2, a directory of frames). */
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
  int r = km_cli_parse(
      argc, argv, opts, 1, pos, 1, &n_pos, "kinemesh info FILE [--json]",
      "Mesh (OBJ/PLY/OFF/STL/glTF): vertex/face counts, topology counts and bounding box.\n"
      "Animation (.glb, .pc2, frame directory): frames, vertices, frame rate.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (n_pos != 1) return km_cli_error("info", "expected one FILE (see kinemesh info --help)");
  km_error err = {0};
  const char *path = pos[0];

  km_anim_info ai;
  size_t plen = strlen(path);
  bool glb = plen > 4 && !strcasecmp(path + plen - 4, ".glb");
  /* A .glb that is not a kinemesh animation (or has no frames: a model) is read as a mesh. */
  bool anim = is_anim_path(path) && (km_anim_info_read(path, &ai, &err) == KM_OK || !glb);
  if (anim && glb && err.status == KM_OK && ai.timeline_frames == 0) anim = false;
  if (anim) {
    if (err.status != KM_OK) return km_cli_fail("info", &err);
    if (json) {
      cJSON *o = cJSON_CreateObject();
      cJSON_AddStringToObject(o, "file", path);
      cJSON_AddStringToObject(o, "format", anim_format_name(ai.format));
      cJSON_AddNumberToObject(o, "frames", (double)ai.timeline_frames);
      if (ai.timeline_frames != ai.frames)
        cJSON_AddNumberToObject(o, "key_frames", (double)ai.frames);
      cJSON_AddNumberToObject(o, "vertices", (double)ai.vertices);
      cJSON_AddNumberToObject(o, "faces", (double)ai.faces);
      cJSON_AddNumberToObject(o, "fps", ai.fps);
      cJSON_AddNumberToObject(o, "duration_s", ai.duration);
      return km_cli_print_json("info", o);
    }
    printf("file        %s\nformat      %s\nframes      %zu\nvertices    %zu\nfaces       %zu\n",
           path, anim_format_name(ai.format), ai.timeline_frames, ai.vertices, ai.faces);
    if (ai.timeline_frames != ai.frames) printf("key frames  %zu\n", ai.frames);
    if (ai.fps > 0)
      printf("frame rate  %g fps\nduration    %.3f s\n", ai.fps, ai.duration);
    else
      printf("frame rate  not stored in this format\n");
    return KM_EXIT_OK;
  }

  km_mesh m = {0};
  km_mesh_skin sk = {0};
  if (km_mesh_read_skinned(path, &m, &sk, &err) != KM_OK) return km_cli_fail("info", &err);
  size_t skin_joints = sk.n_joints;
  km_mesh_skin_free(&sk);
  km_mesh_info info;
  km_status s = km_mesh_info_compute(&m, &info, &err);
  km_frame_guess g;
  km_error gerr = {0};
  bool have_guess = s == KM_OK && km_mesh_frame_guess(&m, &g, &gerr) == KM_OK;
  /* which loose pieces lie on the floor is a question of which way is up: asked of the mesh
   * turned into kinemesh's frame by the guess (animate and live turn it so too) */
  if (have_guess && info.loose_vertices) {
    km_mesh t = {0};
    km_mesh_info ti;
    if (km_mesh_copy(&m, &t, &err) != KM_OK || km_mesh_frame_apply(&g.frame, &t, &err) != KM_OK ||
        km_mesh_info_compute(&t, &ti, &err) != KM_OK)
      s = err.status;
    else
      info.ground_pieces = ti.ground_pieces;
    km_mesh_free(&t);
  } else
    info.ground_pieces = 0;
  bool has_uv = m.UV != NULL, has_n = m.N != NULL, has_c = m.colors != NULL;
  /* the materials the .glb outputs will carry: each its run of faces, colour and texture */
  cJSON *mats = cJSON_CreateArray();
  char mat_line[512] = "";
  size_t ml = 0;
  for (size_t k = 0; k < m.n_materials; ++k) {
    const km_mesh_material *mk = m.materials + k;
    cJSON *mo = cJSON_CreateObject();
    cJSON_AddNumberToObject(mo, "first_face", (double)mk->first_face);
    cJSON_AddNumberToObject(mo, "faces", (double)mk->n_faces);
    cJSON_AddItemToObject(mo, "base_color", cJSON_CreateDoubleArray(mk->base_color, 4));
    cJSON_AddNumberToObject(mo, "metallic", mk->metallic);
    cJSON_AddNumberToObject(mo, "roughness", mk->roughness);
    if (mk->image) {
      cJSON_AddStringToObject(mo, "texture", mk->image_mime);
      cJSON_AddNumberToObject(mo, "texture_bytes", (double)mk->image_size);
    }
    /* the other textures, by glTF's names */
    static const char *const map_name[KM_MAP_COUNT] = {"metallic_roughness", "normal", "occlusion",
                                                       "emissive"};
    cJSON *maps = cJSON_AddArrayToObject(mo, "maps");
    char maps_line[96] = "";
    size_t mll = 0;
    for (int q = 0; q < KM_MAP_COUNT; ++q)
      if (mk->maps[q].bytes) {
        cJSON_AddItemToArray(maps, cJSON_CreateString(map_name[q]));
        if (mll < sizeof maps_line)
          mll += (size_t)snprintf(maps_line + mll, sizeof maps_line - mll, " + %s", map_name[q]);
      }
    if (mk->emissive[0] || mk->emissive[1] || mk->emissive[2])
      cJSON_AddItemToObject(mo, "emissive", cJSON_CreateDoubleArray(mk->emissive, 3));
    static const char *const alpha_name[3] = {"opaque", "mask", "blend"};
    cJSON_AddStringToObject(mo, "alpha_mode",
                            alpha_name[mk->alpha_mode <= KM_ALPHA_BLEND ? mk->alpha_mode : 0]);
    if (mk->double_sided) cJSON_AddBoolToObject(mo, "double_sided", 1);
    cJSON_AddItemToArray(mats, mo);
    if (k < 4 && ml < sizeof mat_line)
      ml += (size_t)snprintf(mat_line + ml, sizeof mat_line - ml, "%s%zu faces, %s%s",
                             k ? "; " : " (", mk->n_faces,
                             mk->image ? mk->image_mime : "colour only", maps_line);
  }
  if (m.n_materials && ml < sizeof mat_line)
    snprintf(mat_line + ml, sizeof mat_line - ml, "%s)", m.n_materials > 4 ? "; ..." : "");
  size_t n_mat = m.n_materials;
  km_mesh_free(&m);
  if (s != KM_OK) {
    cJSON_Delete(mats);
    return km_cli_fail("info", &err);
  }
  if (json) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "file", path);
    cJSON_AddNumberToObject(o, "vertices", (double)info.vertices);
    cJSON_AddNumberToObject(o, "faces", (double)info.faces);
    cJSON_AddNumberToObject(o, "edges", (double)info.edges);
    cJSON_AddNumberToObject(o, "boundary_edges", (double)info.boundary_edges);
    cJSON_AddNumberToObject(o, "nonmanifold_edges", (double)info.nonmanifold_edges);
    cJSON_AddNumberToObject(o, "nonmanifold_vertices", (double)info.nonmanifold_vertices);
    if (info.nonmanifold_edges) {
      cJSON *e = cJSON_AddArrayToObject(o, "first_nonmanifold_edge");
      for (int k = 0; k < 2; ++k)
        cJSON_AddItemToArray(e, cJSON_CreateNumber(info.nonmanifold_edge[k]));
    }
    if (info.nonmanifold_vertices)
      cJSON_AddNumberToObject(o, "first_nonmanifold_vertex", info.nonmanifold_vertex);
    cJSON_AddNumberToObject(o, "components", (double)info.components);
    cJSON_AddNumberToObject(o, "isolated_vertices", (double)info.isolated_vertices);
    cJSON_AddNumberToObject(o, "degenerate_faces", (double)info.degenerate_faces);
    cJSON_AddNumberToObject(o, "seam_vertices", (double)info.seam_vertices);
    cJSON_AddNumberToObject(o, "pieces", (double)info.pieces);
    cJSON_AddNumberToObject(o, "loose_vertices", (double)info.loose_vertices);
    cJSON_AddNumberToObject(o, "rigid_pieces", (double)info.rigid_pieces);
    cJSON_AddNumberToObject(o, "ground_pieces", (double)info.ground_pieces);
    cJSON_AddNumberToObject(o, "euler_characteristic", (double)info.euler_characteristic);
    cJSON_AddItemToObject(o, "bbox_min", vec3(info.bbox_min));
    cJSON_AddItemToObject(o, "bbox_max", vec3(info.bbox_max));
    cJSON_AddBoolToObject(o, "texcoords", has_uv);
    cJSON_AddBoolToObject(o, "normals", has_n);
    cJSON_AddBoolToObject(o, "colors", has_c);
    cJSON_AddItemToObject(o, "materials", mats);
    cJSON_AddNumberToObject(o, "skin_joints", (double)skin_joints);
    if (have_guess) {
      cJSON *go = cJSON_AddObjectToObject(o, "orientation_guess");
      cJSON_AddStringToObject(go, "up", km_axis_name(g.frame.up));
      cJSON_AddStringToObject(go, "forward", km_axis_name(g.frame.forward));
      cJSON_AddNumberToObject(go, "height", g.height);
      cJSON_AddBoolToObject(go, "standing", g.standing);
      cJSON_AddBoolToObject(go, "sure_up", g.sure_up);
      cJSON_AddBoolToObject(go, "sure_forward", g.sure_forward);
      cJSON_AddStringToObject(go, "why", g.why);
    }
    return km_cli_print_json("info", o);
  }
  printf("file                  %s\n", path);
  printf("vertices              %zu\nfaces                 %zu\nedges                 %zu\n",
         info.vertices, info.faces, info.edges);
  printf("boundary edges        %zu\nnon-manifold edges    %zu", info.boundary_edges,
         info.nonmanifold_edges);
  if (info.nonmanifold_edges)
    printf(" (the first between vertices %d and %d)", (int)info.nonmanifold_edge[0],
           (int)info.nonmanifold_edge[1]);
  printf("\nnon-manifold vertices %zu", info.nonmanifold_vertices);
  if (info.nonmanifold_vertices) printf(" (the first: vertex %d)", (int)info.nonmanifold_vertex);
  printf("\n");
  printf("components            %zu\nisolated vertices     %zu\ndegenerate faces      %zu\n",
         info.components, info.isolated_vertices, info.degenerate_faces);
  printf("euler characteristic  %lld\n", (long long)info.euler_characteristic);
  if (info.seam_vertices)
    printf("seam vertices         %zu (each lies exactly on another vertex%s)\n",
           info.seam_vertices,
           info.components > 1 || info.boundary_edges
               ? ", the faces not joined there: a glTF split at its texture seams; rig and the "
                 "solvers join them, the outputs keep every vertex"
               : "");
  const char *joined = info.seam_vertices ? " (after joining the seams)" : "";
  if (info.pieces > 1 && info.loose_vertices) {
    size_t nl = info.pieces - 1, nr = info.rigid_pieces, ng = info.ground_pieces;
    if (ng == nl) /* only a ground plane (or several) */
      printf("pieces                %zu%s: a body and %zu small piece%s (%zu of the file's "
             "vertices) lying on the floor (up as guessed below): animate, live and rig's skin "
             "leave %s where %s\n",
             info.pieces, joined, nl, nl > 1 ? "s" : "", info.loose_vertices,
             nl > 1 ? "them" : "it", nl > 1 ? "they lie" : "it lies");
    else {
      printf("pieces                %zu%s: a body and %zu small piece%s (%zu of the file's "
             "vertices: eyes, teeth, ...) that rig and the solvers carry with it",
             info.pieces, joined, nl, nl > 1 ? "s" : "", info.loose_vertices);
      km_cli_pieces_how(stdout, nl, nr);
    }
    if (ng && ng < nl)
      printf("                      but %zu of them lie%s on the floor (up as guessed below): "
             "animate, live and rig's skin leave %s where %s\n",
             ng, ng > 1 ? "" : "s", ng > 1 ? "them" : "it", ng > 1 ? "they lie" : "it lies");
  } else if (info.pieces > 1)
    printf("pieces                %zu%s, two of comparable size: rig animates one body (small "
           "pieces follow it) and refuses this mesh\n",
           info.pieces, joined);
  printf("bbox min              %.6g %.6g %.6g\nbbox max              %.6g %.6g %.6g\n",
         info.bbox_min[0], info.bbox_min[1], info.bbox_min[2], info.bbox_max[0], info.bbox_max[1],
         info.bbox_max[2]);
  printf("attributes            %s%s%s%s\n", has_uv ? "texcoords " : "", has_n ? "normals " : "",
         has_c ? "colors" : "", has_uv || has_n || has_c ? "" : "none");
  cJSON_Delete(mats);
  if (n_mat) printf("materials             %zu%s\n", n_mat, mat_line);
  if (skin_joints)
    printf("skin                  %zu joints (a rigged template as it is: kinemesh rig shows the "
           "mapping)\n",
           skin_joints);
  if (have_guess)
    printf("orientation (guess)   up %s%s, forward %s%s, height %.6g%s (override with "
           "--up/--forward)\n"
           "                      %s\n",
           km_axis_name(g.frame.up), g.sure_up ? "" : " (unsure)", km_axis_name(g.frame.forward),
           g.sure_forward ? "" : " (unsure)", g.height, g.standing ? ", standing" : "", g.why);
  return KM_EXIT_OK;
}
