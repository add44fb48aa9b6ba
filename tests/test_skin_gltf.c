/* A skinned glTF as a rigged template (issue 11): the procedural character's skeleton and
 * weights written by hand as a .glb with Mixamo names (under a 0.01-scaled armature, with a
 * clavicle, a finger joint and an end joint kinemesh has no joint for), read back by
 * km_mesh_read_skinned + km_character_from_skin, and through the CLI: `rig` writes the sidecar
 * from the skin, `pose`, `reconstruct` and `animate` take the .glb with no sidecar, and `pose`
 * and `reconstruct` match the sidecar-based runs of the same character. */
#include "km_test.h"

#include <cjson/cJSON.h>

#define DIR "skin_gltf"

/* Bone names in four conventions: the Kinect v1 joints (km_kinect1_joint_name order), then a
 * clavicle (between ShoulderCenter and ShoulderLeft), a second finger joint (below HandLeft)
 * and a head end, which kinemesh has no joint for. */
static const char *const mixamo[23] = {"mixamorig:Hips",         "mixamorig:Spine",
                                       "mixamorig:Neck",         "mixamorig:Head",
                                       "mixamorig:LeftArm",      "mixamorig:LeftForeArm",
                                       "mixamorig:LeftHand",     "mixamorig:LeftHandMiddle1",
                                       "mixamorig:RightArm",     "mixamorig:RightForeArm",
                                       "mixamorig:RightHand",    "mixamorig:RightHandMiddle1",
                                       "mixamorig:LeftUpLeg",    "mixamorig:LeftLeg",
                                       "mixamorig:LeftFoot",     "mixamorig:LeftToeBase",
                                       "mixamorig:RightUpLeg",   "mixamorig:RightLeg",
                                       "mixamorig:RightFoot",    "mixamorig:RightToeBase",
                                       "mixamorig:LeftShoulder", "mixamorig:LeftHandMiddle2",
                                       "mixamorig:HeadTop_End"};
static const char *const unity[23] = {"Hips",          "Spine",
                                      "Neck",          "Head",
                                      "LeftUpperArm",  "LeftLowerArm",
                                      "LeftHand",      "LeftMiddleProximal",
                                      "RightUpperArm", "RightLowerArm",
                                      "RightHand",     "RightMiddleProximal",
                                      "LeftUpperLeg",  "LeftLowerLeg",
                                      "LeftFoot",      "LeftToes",
                                      "RightUpperLeg", "RightLowerLeg",
                                      "RightFoot",     "RightToes",
                                      "LeftShoulder",  "LeftMiddleIntermediate",
                                      "HeadTop"};
static const char *const vroid[23] = {
    "J_Bip_C_Hips",     "J_Bip_C_Spine",    "J_Bip_C_Neck",   "J_Bip_C_Head",
    "J_Bip_L_UpperArm", "J_Bip_L_LowerArm", "J_Bip_L_Hand",   "J_Bip_L_Middle1",
    "J_Bip_R_UpperArm", "J_Bip_R_LowerArm", "J_Bip_R_Hand",   "J_Bip_R_Middle1",
    "J_Bip_L_UpperLeg", "J_Bip_L_LowerLeg", "J_Bip_L_Foot",   "J_Bip_L_ToeBase",
    "J_Bip_R_UpperLeg", "J_Bip_R_LowerLeg", "J_Bip_R_Foot",   "J_Bip_R_ToeBase",
    "J_Bip_L_Shoulder", "J_Bip_L_Middle2",  "J_Adj_C_HeadTop"};
static const char *const rigify[23] = {
    "DEF-spine",       "DEF-spine.001",     "DEF-spine.004", "DEF-head",
    "DEF-upper_arm.L", "DEF-forearm.L",     "DEF-hand.L",    "DEF-f_middle.01.L",
    "DEF-upper_arm.R", "DEF-forearm.R",     "DEF-hand.R",    "DEF-f_middle.01.R",
    "DEF-thigh.L",     "DEF-shin.L",        "DEF-foot.L",    "DEF-toe.L",
    "DEF-thigh.R",     "DEF-shin.R",        "DEF-foot.R",    "DEF-toe.R",
    "DEF-shoulder.L",  "DEF-f_middle.02.L", "head_end"};

enum { EXTRA_CLAVICLE = 20, EXTRA_FINGER2, EXTRA_HEADTOP, N_BONES };

static void put_f32(unsigned char *b, size_t *at, double x) {
  float f = (float)x;
  memcpy(b + *at, &f, 4);
  *at += 4;
}

static void add_view(cJSON *views, cJSON *accs, size_t off, size_t len, int ct, int count,
                     const char *type) {
  cJSON *v = cJSON_CreateObject();
  cJSON_AddNumberToObject(v, "buffer", 0);
  cJSON_AddNumberToObject(v, "byteOffset", (double)off);
  cJSON_AddNumberToObject(v, "byteLength", (double)len);
  cJSON_AddItemToArray(views, v);
  cJSON *a = cJSON_CreateObject();
  cJSON_AddNumberToObject(a, "bufferView", cJSON_GetArraySize(views) - 1);
  cJSON_AddNumberToObject(a, "componentType", ct);
  cJSON_AddNumberToObject(a, "count", count);
  cJSON_AddStringToObject(a, "type", type);
  cJSON_AddItemToArray(accs, a);
}

/* Writes c as a skinned .glb with the bone names of a convention, or "bone<i>" (names NULL). */
/* VRM's humanoid bone names for the bones above (NULL: none) */
static const char *const vrm_bones[23] = {"hips",
                                          "spine",
                                          "neck",
                                          "head",
                                          "leftUpperArm",
                                          "leftLowerArm",
                                          "leftHand",
                                          "leftMiddleProximal",
                                          "rightUpperArm",
                                          "rightLowerArm",
                                          "rightHand",
                                          "rightMiddleProximal",
                                          "leftUpperLeg",
                                          "leftLowerLeg",
                                          "leftFoot",
                                          "leftToes",
                                          "rightUpperLeg",
                                          "rightLowerLeg",
                                          "rightFoot",
                                          "rightToes",
                                          "leftShoulder",
                                          "leftMiddleIntermediate",
                                          NULL};

/* vrm 0: a plain glTF; 1: a VRM 0.x avatar (its armature turned half about y, so it faces -z
 * as UniVRM writes them, and extensions.VRM.humanoid.humanBones); 2: a VRM 1.0 one (facing +z,
 * extensions.VRMC_vrm.humanoid.humanBones). */
static void write_skinned_glb_vrm(const char *path, const km_character *c, const char *const *names,
                                  int vrm);
static void write_skinned_glb(const char *path, const km_character *c, const char *const *names) {
  write_skinned_glb_vrm(path, c, names, 0);
}

static void write_skinned_glb_vrm(const char *path, const km_character *c, const char *const *names,
                                  int vrm) {
  const km_mesh *m = &c->mesh;
  const double *R = c->skeleton.rest;
  size_t nv = m->n_vertices, nf = m->n_faces;
  /* bone positions (metres) and parents */
  double P[N_BONES][3];
  int par[N_BONES];
  for (int j = 0; j < KM_KINECT1_JOINTS; ++j) {
    memcpy(P[j], R + 3 * j, sizeof P[j]);
    par[j] = km_kinect1_joint_parent(j);
  }
  for (int k = 0; k < 3; ++k) {
    P[EXTRA_CLAVICLE][k] = 0.5 * (R[3 * 2 + k] + R[3 * 4 + k]); /* Neck .. LeftArm */
    P[EXTRA_FINGER2][k] = R[3 * 7 + k] + 0.5 * (R[3 * 7 + k] - R[3 * 6 + k]);
    P[EXTRA_HEADTOP][k] = R[3 * 3 + k] + (k == 1 ? 0.1 : 0);
  }
  par[EXTRA_CLAVICLE] = 2, par[4] = EXTRA_CLAVICLE;
  par[EXTRA_FINGER2] = 7, par[EXTRA_HEADTOP] = 3;
  size_t off_pos = 0, off_idx = off_pos + 12 * nv, off_j = off_idx + 12 * nf,
         off_w = off_j + 8 * nv, off_ibm = off_w + 16 * nv, total = off_ibm + 64 * N_BONES;
  unsigned char *bin = calloc(total, 1);
  size_t at = 0;
  for (size_t i = 0; i < 3 * nv; ++i)
    put_f32(bin, &at, m->V[i]);
  for (size_t i = 0; i < 3 * nf; ++i) {
    uint32_t x = (uint32_t)m->F[i];
    memcpy(bin + at, &x, 4);
    at += 4;
  }
  /* skin.joints lists the bones in reverse: JOINTS_0 holds positions in that list */
  for (size_t v = 0; v < nv; ++v)
    for (int q = 0; q < 4; ++q) {
      int j = c->skin.joints[4 * v + q];
      double w = j >= 0 ? c->skin.weights[4 * v + q] : 0;
      if (j == 7 && v % 2) j = EXTRA_FINGER2; /* half the hand's vertices on a finger joint */
      uint16_t slot = (uint16_t)(j >= 0 ? N_BONES - 1 - j : 0);
      memcpy(bin + off_j + 8 * v + 2 * q, &slot, 2);
      at = off_w + 16 * v + 4 * q;
      put_f32(bin, &at, w);
    }
  for (int b = 0; b < N_BONES; ++b) { /* inverse of [0.01 I | P] = [100 I | -100 P] */
    int j = N_BONES - 1 - b;
    double M[16] = {
        100, 0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, -100 * P[j][0], -100 * P[j][1], -100 * P[j][2],
        1};
    at = off_ibm + 64 * (size_t)b;
    for (int k = 0; k < 16; ++k)
      put_f32(bin, &at, M[k]);
  }
  cJSON *root = cJSON_CreateObject();
  cJSON *asset = cJSON_AddObjectToObject(root, "asset");
  cJSON_AddStringToObject(asset, "version", "2.0");
  cJSON_AddNumberToObject(root, "scene", 0);
  cJSON *scene = cJSON_CreateObject();
  cJSON *sn = cJSON_AddArrayToObject(scene, "nodes");
  cJSON_AddItemToArray(sn, cJSON_CreateNumber(0));
  cJSON_AddItemToArray(sn, cJSON_CreateNumber(N_BONES + 1));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);
  cJSON *nodes = cJSON_AddArrayToObject(root, "nodes");
  cJSON *arm = cJSON_CreateObject(); /* node 0: the armature, scaled 0.01 (bones in cm) */
  cJSON_AddStringToObject(arm, "name", "Armature");
  cJSON *sc = cJSON_AddArrayToObject(arm, "scale");
  for (int k = 0; k < 3; ++k)
    cJSON_AddItemToArray(sc, cJSON_CreateNumber(0.01));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(arm, "children"), cJSON_CreateNumber(1));
  if (vrm == 1) { /* half a turn about y: (x, y, z, w) = (0, 1, 0, 0) */
    cJSON *r = cJSON_AddArrayToObject(arm, "rotation");
    for (int k = 0; k < 4; ++k)
      cJSON_AddItemToArray(r, cJSON_CreateNumber(k == 1));
  }
  cJSON_AddItemToArray(nodes, arm);
  if (vrm) {
    cJSON *ext = cJSON_AddObjectToObject(root, "extensions");
    cJSON *hum = cJSON_AddObjectToObject(
        cJSON_AddObjectToObject(ext, vrm == 1 ? "VRM" : "VRMC_vrm"), "humanoid");
    cJSON *hb = vrm == 1 ? cJSON_AddArrayToObject(hum, "humanBones")
                         : cJSON_AddObjectToObject(hum, "humanBones");
    for (int j = 0; j < N_BONES; ++j) {
      if (!vrm_bones[j]) continue;
      cJSON *e = cJSON_CreateObject();
      cJSON_AddNumberToObject(e, "node", 1 + j);
      if (vrm == 1) {
        cJSON_AddStringToObject(e, "bone", vrm_bones[j]);
        cJSON_AddItemToArray(hb, e);
      } else {
        cJSON_AddItemToObject(hb, vrm_bones[j], e);
      }
    }
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "extensionsUsed"),
                         cJSON_CreateString(vrm == 1 ? "VRM" : "VRMC_vrm"));
  }
  for (int j = 0; j < N_BONES; ++j) { /* node 1 + j */
    cJSON *n = cJSON_CreateObject();
    char name[64];
    if (names)
      snprintf(name, sizeof name, "%s", names[j]);
    else
      snprintf(name, sizeof name, "bone%d", j);
    cJSON_AddStringToObject(n, "name", name);
    cJSON *t = cJSON_AddArrayToObject(n, "translation");
    for (int k = 0; k < 3; ++k)
      cJSON_AddItemToArray(t,
                           cJSON_CreateNumber(100 * (P[j][k] - (par[j] >= 0 ? P[par[j]][k] : 0))));
    cJSON *ch = NULL;
    for (int k = 0; k < N_BONES; ++k)
      if (par[k] == j) {
        if (!ch) ch = cJSON_AddArrayToObject(n, "children");
        cJSON_AddItemToArray(ch, cJSON_CreateNumber(1 + k));
      }
    cJSON_AddItemToArray(nodes, n);
  }
  cJSON *body = cJSON_CreateObject(); /* its own transform is ignored: it is skinned */
  cJSON_AddStringToObject(body, "name", "Body");
  cJSON_AddNumberToObject(body, "mesh", 0);
  cJSON_AddNumberToObject(body, "skin", 0);
  cJSON *bt = cJSON_AddArrayToObject(body, "translation");
  for (int k = 0; k < 3; ++k)
    cJSON_AddItemToArray(bt, cJSON_CreateNumber(k == 0 ? 5 : 0));
  cJSON_AddItemToArray(nodes, body);
  cJSON *skin = cJSON_CreateObject();
  cJSON_AddNumberToObject(skin, "inverseBindMatrices", 4);
  cJSON *sj = cJSON_AddArrayToObject(skin, "joints");
  for (int b = 0; b < N_BONES; ++b)
    cJSON_AddItemToArray(sj, cJSON_CreateNumber(1 + (N_BONES - 1 - b)));
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "skins"), skin);
  cJSON *views = cJSON_AddArrayToObject(root, "bufferViews");
  cJSON *accs = cJSON_AddArrayToObject(root, "accessors");
  add_view(views, accs, off_pos, 12 * nv, 5126, (int)nv, "VEC3");
  add_view(views, accs, off_idx, 12 * nf, 5125, (int)(3 * nf), "SCALAR");
  add_view(views, accs, off_j, 8 * nv, 5123, (int)nv, "VEC4");
  add_view(views, accs, off_w, 16 * nv, 5126, (int)nv, "VEC4");
  add_view(views, accs, off_ibm, 64 * N_BONES, 5126, N_BONES, "MAT4");
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (size_t v = 0; v < nv; ++v)
    for (int k = 0; k < 3; ++k) {
      double x = (float)m->V[3 * v + k];
      lo[k] = x < lo[k] ? x : lo[k], hi[k] = x > hi[k] ? x : hi[k];
    }
  cJSON *pa = cJSON_GetArrayItem(accs, 0), *mn = cJSON_AddArrayToObject(pa, "min"),
        *mx = cJSON_AddArrayToObject(pa, "max");
  for (int k = 0; k < 3; ++k) {
    cJSON_AddItemToArray(mn, cJSON_CreateNumber(lo[k]));
    cJSON_AddItemToArray(mx, cJSON_CreateNumber(hi[k]));
  }
  cJSON *prim = cJSON_CreateObject();
  cJSON *attr = cJSON_AddObjectToObject(prim, "attributes");
  cJSON_AddNumberToObject(attr, "POSITION", 0);
  cJSON_AddNumberToObject(attr, "JOINTS_0", 2);
  cJSON_AddNumberToObject(attr, "WEIGHTS_0", 3);
  cJSON_AddNumberToObject(prim, "indices", 1);
  cJSON *mesh = cJSON_CreateObject();
  cJSON_AddItemToArray(cJSON_AddArrayToObject(mesh, "primitives"), prim);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);
  cJSON *buf = cJSON_CreateObject();
  cJSON_AddNumberToObject(buf, "byteLength", (double)total);
  cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "buffers"), buf);
  char *js = cJSON_PrintUnformatted(root);
  CHECK(km_test_write_glb(path, js, bin, total));
  free(js);
  free(bin);
  cJSON_Delete(root);
}

static double max_frame_diff(const char *a, const char *b, size_t *frames) {
  double *fa = NULL, *fb = NULL;
  km_anim_info ia, ib;
  CHECK_OK(km_pc2_read(a, &fa, &ia, KM_E));
  CHECK_OK(km_pc2_read(b, &fb, &ib, KM_E));
  double d = 1e9;
  if (fa && fb && ia.frames == ib.frames && ia.vertices == ib.vertices) {
    d = 0;
    for (size_t i = 0; i < 3 * ia.frames * ia.vertices; ++i)
      d = fmax(d, isfinite(fa[i]) && isfinite(fb[i]) ? fabs(fa[i] - fb[i]) : 1e9);
  }
  *frames = ia.frames;
  free(fa);
  free(fb);
  return d;
}

static double mean_frame_diff(const char *a, const char *b) {
  double *fa = NULL, *fb = NULL;
  km_anim_info ia, ib;
  CHECK_OK(km_pc2_read(a, &fa, &ia, KM_E));
  CHECK_OK(km_pc2_read(b, &fb, &ib, KM_E));
  double d = 1e9;
  if (fa && fb && ia.frames == ib.frames && ia.vertices == ib.vertices && ia.frames) {
    d = 0;
    for (size_t i = 0; i < ia.frames * ia.vertices; ++i)
      d += sqrt(pow(fa[3 * i] - fb[3 * i], 2) + pow(fa[3 * i + 1] - fb[3 * i + 1], 2) +
                pow(fa[3 * i + 2] - fb[3 * i + 2], 2));
    d /= (double)(ia.frames * ia.vertices);
  }
  free(fa);
  free(fb);
  return d;
}

int main(void) {
  char *out = NULL;
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 3000 -o " DIR "/char.obj", NULL) == 0);
  km_character c = {0};
  CHECK_OK(km_mesh_read(DIR "/char.obj", &c.mesh, KM_E));
  CHECK_OK(km_character_read_rig(DIR "/char.rig.json", c.mesh.n_vertices, &c, KM_E));
  write_skinned_glb(DIR "/skinned.glb", &c, mixamo);
  write_skinned_glb(DIR "/unnamed.glb", &c, NULL);
  write_skinned_glb(DIR "/unity.glb", &c, unity);
  write_skinned_glb(DIR "/vroid.glb", &c, vroid);
  write_skinned_glb(DIR "/rigify.glb", &c, rigify);

  /* library: the skin as stored, then as kinemesh's rig */
  km_mesh m = {0};
  km_mesh_skin sk = {0};
  CHECK_OK(km_mesh_read_skinned(DIR "/skinned.glb", &m, &sk, KM_E));
  CHECK(m.n_vertices == c.mesh.n_vertices && m.n_faces == c.mesh.n_faces);
  double dv = 0;
  for (size_t i = 0; i < 3 * m.n_vertices && m.V; ++i)
    dv = fmax(dv, fabs(m.V[i] - c.mesh.V[i]));
  CHECK_MSG(dv < 1e-5, "bind pose positions differ by %g (mesh node transform not ignored?)", dv);
  CHECK(sk.n_joints == N_BONES && sk.n_vertices == m.n_vertices);
  CHECK(sk.names && !strcmp(sk.names[0], "mixamorig:HeadTop_End"));
  for (size_t j = 0; j < sk.n_joints && sk.rest; ++j) { /* reversed: joint j is bone N-1-j */
    int b = N_BONES - 1 - (int)j;
    if (b < KM_KINECT1_JOINTS)
      for (int k = 0; k < 3; ++k)
        CHECK_NEAR(sk.rest[3 * j + k], c.skeleton.rest[3 * b + k], 1e-6);
  }
  km_character g = {0};
  km_skin_mapping map;
  CHECK_OK(km_character_from_skin(&m, &sk, &g, &map, KM_E));
  CHECK(g.skeleton.n_joints == KM_KINECT1_JOINTS);
  CHECK(!strcmp(map.source[0], "mixamorig:Hips") && !strcmp(map.source[2], "mixamorig:Neck") &&
        !strcmp(map.source[7], "mixamorig:LeftHandMiddle1"));
  CHECK(map.n_merged == 3);
  for (int j = 0; j < KM_KINECT1_JOINTS && g.skeleton.rest; ++j) {
    CHECK(!strcmp(g.skeleton.names[j], c.skeleton.names[j]));
    CHECK(g.skeleton.parents[j] == c.skeleton.parents[j]);
    for (int k = 0; k < 3; ++k)
      CHECK_NEAR(g.skeleton.rest[3 * j + k], c.skeleton.rest[3 * j + k], 1e-6);
  }
  double dw = 0; /* per-vertex weight of every joint, in both */
  for (size_t v = 0; v < m.n_vertices && g.skin.weights; ++v) {
    double a[KM_KINECT1_JOINTS] = {0}, b[KM_KINECT1_JOINTS] = {0};
    for (int q = 0; q < 4; ++q) {
      if (g.skin.joints[4 * v + q] >= 0) a[g.skin.joints[4 * v + q]] += g.skin.weights[4 * v + q];
      if (c.skin.joints[4 * v + q] >= 0) b[c.skin.joints[4 * v + q]] += c.skin.weights[4 * v + q];
    }
    for (int j = 0; j < KM_KINECT1_JOINTS; ++j)
      dw = fmax(dw, fabs(a[j] - b[j]));
  }
  CHECK_MSG(dw < 1e-6, "weights differ by %g", dw);
  for (int l = 0; l < KM_CHARACTER_LANDMARKS; ++l)
    CHECK(g.landmarks[l].vertex >= 0 && (size_t)g.landmarks[l].vertex < m.n_vertices);
  CHECK(map.n_still == 0);
  km_character_free(&g);
  /* a vertex the file weights to no joint (an unskinned primitive with no joint above it: a
   * ground plane beside the armature) gets no influence, as Blender leaves it, not the hips */
  if (sk.joints && m.n_vertices > 1) {
    for (int q = 0; q < 4; ++q)
      sk.joints[4 + q] = -1, sk.weights[4 + q] = 0;
    CHECK_OK(km_character_from_skin(&m, &sk, &g, &map, KM_E));
    CHECK(map.n_still == 1 && g.skin.joints && g.skin.joints[4] == -1 && g.skin.weights[4] == 0);
    km_character_free(&g);
  }
  km_mesh_skin_free(&sk);
  km_mesh_free(&m);
  /* the other conventions map the same way */
  const char *conv[3] = {DIR "/unity.glb", DIR "/vroid.glb", DIR "/rigify.glb"};
  for (int k = 0; k < 3; ++k) {
    CHECK_OK(km_mesh_read_skinned(conv[k], &m, &sk, KM_E));
    CHECK_OK(km_character_from_skin(&m, &sk, &g, &map, KM_E));
    double dj = g.skeleton.rest ? 0 : 1;
    for (int j = 0; j < 3 * KM_KINECT1_JOINTS && g.skeleton.rest; ++j)
      dj = fmax(dj, fabs(g.skeleton.rest[j] - c.skeleton.rest[j]));
    CHECK_MSG(dj < 1e-6 && map.n_merged == 3, "%s: joints off by %g, %zu merged", conv[k], dj,
              map.n_merged);
    km_character_free(&g);
    km_mesh_skin_free(&sk);
    km_mesh_free(&m);
  }
  /* VRM avatars (.vrm): bones named freely ("bone<j>"), mapped by the file's humanoid table;
   * a VRM 0.x one faces -z and is turned to +z on the way in: the same mesh, joints and rig as
   * the plain glTF, and every verb takes the .vrm extension */
  for (int v = 1; v <= 2; ++v) {
    const char *vp = v == 1 ? DIR "/avatar0.vrm" : DIR "/avatar1.vrm";
    write_skinned_glb_vrm(vp, &c, NULL, v);
    CHECK_OK(km_mesh_read_skinned(vp, &m, &sk, KM_E));
    double dvv = m.V && m.n_vertices == c.mesh.n_vertices ? 0 : 1;
    for (size_t i = 0; !dvv && i < 3 * m.n_vertices; ++i)
      dvv = fmax(dvv, fabs(m.V[i] - c.mesh.V[i]));
    CHECK_MSG(dvv < 1e-5, "%s: positions off the plain glTF's by %g", vp, dvv);
    CHECK_OK(km_character_from_skin(&m, &sk, &g, &map, KM_E));
    double dj = g.skeleton.rest ? 0 : 1;
    for (int j = 0; j < 3 * KM_KINECT1_JOINTS && g.skeleton.rest; ++j)
      dj = fmax(dj, fabs(g.skeleton.rest[j] - c.skeleton.rest[j]));
    CHECK_MSG(dj < 1e-5 && !strcmp(map.source[0], "bone0|hips") &&
                  !strcmp(map.source[5], "bone5|leftLowerArm"),
              "%s: joints off by %g, HipCenter <- %s", vp, dj, map.source[0]);
    km_character_free(&g);
    km_mesh_skin_free(&sk);
    km_mesh_free(&m);
  }
  CHECK(km_test_run(KM_CLI " info " DIR "/avatar0.vrm", &out) == 0 && out &&
        strstr(out, "vertices") && strstr(out, "up +y, forward +z"));
  free(out), out = NULL;

  /* a non-glTF has no skin; a skin whose names follow no convention is refused by name */
  CHECK_OK(km_mesh_read_skinned(DIR "/char.obj", &m, &sk, KM_E));
  CHECK(sk.n_joints == 0 && sk.joints == NULL);
  km_mesh_free(&m);
  CHECK_OK(km_mesh_read_skinned(DIR "/unnamed.glb", &m, &sk, KM_E));
  CHECK_STATUS(km_character_from_skin(&m, &sk, &g, NULL, KM_E), KM_ERR_UNSUPPORTED);
  CHECK(strstr(km_test_err.message, "LeftUpperArm") && strstr(km_test_err.message, "bone0"));
  km_mesh_skin_free(&sk);
  km_mesh_free(&m);

  /* tests/data/skinned_quad.gltf: the second joint turned 90 degrees about z from its bind
   * pose, so its vertices are placed by skinning (the mesh node's translation ignored); an
   * unskinned triangle under that joint comes first (nodes depth-first) and is bound to it */
  CHECK_OK(km_mesh_read_skinned(KM_TEST_DATA "/skinned_quad.gltf", &m, &sk, KM_E));
  static const double want[7][3] = {{0, 2, 0}, {-1, 2, 0}, {0, 3, 0}, {0, 0, 0},
                                    {1, 0, 0}, {-1, 2, 0}, {-1, 1, 0}};
  CHECK(m.n_vertices == 7 && sk.n_joints == 2);
  for (size_t v = 0; v < 7 && m.n_vertices == 7; ++v)
    for (int k = 0; k < 3; ++k)
      CHECK_NEAR(m.V[3 * v + k], want[v][k], 1e-6);
  if (sk.n_joints == 2) {
    CHECK(!strcmp(sk.names[1], "mixamorig:Spine") && sk.parents[0] == -1 && sk.parents[1] == 0);
    CHECK_NEAR(sk.rest[4], 1.0, 1e-12);
    static const int jw[7] = {1, 1, 1, 0, 0, 1, 1};
    for (int v = 0; v < 7; ++v)
      CHECK(sk.joints[4 * v] == jw[v] && sk.weights[4 * v] == 1.0 && sk.joints[4 * v + 1] == -1);
  }
  km_mesh_skin_free(&sk);
  km_mesh_free(&m);
  CHECK_OK(km_mesh_read(KM_TEST_DATA "/skinned_quad.gltf", &m, KM_E)); /* same placement */
  CHECK(m.n_vertices == 7 && fabs(m.V[3 * 6] + 1) < 1e-6);
  km_mesh_free(&m);

  /* A scene root that is no node index is a parse error naming it, not a cast out of int's
   * range (fuzz_gltf found 8.9e83 there: undefined behaviour under the sanitizer build). */
  char *text = NULL;
  size_t text_n = 0;
  FILE *tf = fopen(KM_TEST_DATA "/skinned_quad.gltf", "rb");
  CHECK(tf && (text = malloc(1 << 16)) && (text_n = fread(text, 1, (1 << 16) - 1, tf)) > 0);
  if (tf) fclose(tf);
  cJSON *doc = text ? (text[text_n] = 0, cJSON_Parse(text)) : NULL;
  cJSON *roots =
      cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "scenes"), 0), "nodes");
  CHECK(roots && cJSON_GetArraySize(roots) > 0);
  static const double bad_roots[3] = {8.9e83, 1.5, -1};
  for (int b = 0; b < 3 && roots; ++b) {
    cJSON_ReplaceItemInArray(roots, 0, cJSON_CreateNumber(bad_roots[b]));
    char *json = cJSON_Print(doc);
    FILE *bf = fopen(DIR "/bad_root.gltf", "wb");
    CHECK(json && bf && fputs(json, bf) >= 0);
    if (bf) fclose(bf);
    free(json);
    CHECK_STATUS(km_mesh_read(DIR "/bad_root.gltf", &m, KM_E), KM_ERR_PARSE);
    CHECK_MSG(strstr(km_test_err.message, "bad_root.gltf") &&
                  strstr(km_test_err.message, "is not a whole number"),
              "root %g: %s", bad_roots[b], km_test_err.message);
    km_mesh_free(&m);
  }
  cJSON_Delete(doc);
  free(text);

  /* CLI: info reports the skin, rig writes the sidecar from it */
  CHECK(km_test_run(KM_CLI " info " DIR "/skinned.glb", &out) == 0);
  CHECK(out && strstr(out, "23 joints"));
  free(out);
  CHECK(km_test_run(KM_CLI " rig " DIR "/skinned.glb -o " DIR "/from_skin.rig.json", &out) == 0);
  CHECK(out && strstr(out, "own skin") && strstr(out, "mixamorig:LeftForeArm"));
  free(out);
  km_character r = {0};
  CHECK_OK(km_character_read_rig(DIR "/from_skin.rig.json", c.mesh.n_vertices, &r, KM_E));
  CHECK(r.skeleton.n_joints == KM_KINECT1_JOINTS);
  km_character_free(&r);

  /* pose: the .glb alone (no skinned.rig.json) matches the sidecar-based run */
  CHECK(km_test_run("test ! -e " DIR "/skinned.rig.json", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind kungfu --frames 12 --character " DIR
                           "/char.obj -o " DIR "/take.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/char.obj --motion " DIR "/take.json -o " DIR
                           "/pose_obj.pc2",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/skinned.glb --motion " DIR "/take.json -o " DIR
                           "/pose_glb.pc2",
                    &out) == 0);
  CHECK(out && strstr(out, "rigged from its own skin"));
  free(out);
  size_t frames = 0;
  double dp = max_frame_diff(DIR "/pose_obj.pc2", DIR "/pose_glb.pc2", &frames);
  CHECK(frames == 12);
  CHECK_MSG(dp < 1e-4, "pose from the .glb differs from the sidecar run by %g m", dp);
  /* no rig at all: a clear message, non-zero */
  CHECK(km_test_run(KM_CLI " pose --mesh " DIR "/unnamed.glb --motion " DIR "/take.json -o " DIR
                           "/x.pc2",
                    &out) != 0);
  CHECK(out && strstr(out, "no joint found for"));
  free(out);

  /* reconstruct: the .glb as the template matches the sidecar-based template */
  CHECK(km_test_run(KM_CLI " gen motion --kind wave --frames 3 --character " DIR "/char.obj -o " DIR
                           "/wave.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen capture --character " DIR "/char.obj --motion " DIR
                           "/wave.json --cameras 6 --points 6000 --noise-mm 1 -o " DIR "/frames",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/char.obj --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/recon_obj.pc2",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/skinned.glb --clouds '" DIR
                           "/frames/frame_*.ply' -o " DIR "/recon_glb.pc2",
                    &out) == 0);
  CHECK(out && strstr(out, "rigged from its own skin"));
  free(out);
  /* the same rig (the sidecar `rig` wrote from the skin) on the OBJ: the same result, up to
   * the .glb's float32 positions and weights (which alone move this registration by ~1-2 mm
   * on average, against its ~8 mm error to the truth: the mean is compared, not the max) */
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/char.obj --rig " DIR
                           "/from_skin.rig.json --clouds '" DIR "/frames/frame_*.ply' -o " DIR
                           "/recon_obj_skinrig.pc2",
                    NULL) == 0);
  double dr = mean_frame_diff(DIR "/recon_obj_skinrig.pc2", DIR "/recon_glb.pc2");
  /* and as good as the generator's own sidecar (whose landmarks differ) against the truth */
  double e_obj = mean_frame_diff(DIR "/recon_obj.pc2", DIR "/frames/truth.pc2");
  double e_glb = mean_frame_diff(DIR "/recon_glb.pc2", DIR "/frames/truth.pc2");
  printf("pose: max difference %.3g m; reconstruct: mean difference %.2f mm with the same rig; "
         "mean error to the truth %.2f mm (sidecar) vs %.2f mm (.glb's skin)\n",
         dp, 1e3 * dr, 1e3 * e_obj, 1e3 * e_glb);
  CHECK_MSG(dr < 0.004,
            "reconstruction from the .glb differs from the same rig on the OBJ by %g m on average",
            dr);
  CHECK(e_glb < 1.5 * e_obj + 0.002);

  /* animate: the .glb's own skin gives the puppetry rig */
  CHECK(km_test_run(KM_CLI " animate --mesh " DIR "/skinned.glb --motion " DIR
                           "/take.json --cache " DIR "/skinned.kmcache -o " DIR "/anim.pc2",
                    &out) == 0);
  free(out);
  double *fa = NULL;
  km_anim_info ia;
  CHECK_OK(km_pc2_read(DIR "/anim.pc2", &fa, &ia, KM_E));
  CHECK(ia.frames == 12 && ia.vertices == c.mesh.n_vertices);
  bool finite = fa != NULL;
  double moved = 0;
  for (size_t i = 0; fa && i < 3 * ia.frames * ia.vertices; ++i) {
    finite &= isfinite(fa[i]) != 0;
    if (i >= 3 * (ia.frames - 1) * ia.vertices)
      moved = fmax(moved, fabs(fa[i] - fa[i - 3 * (ia.frames - 1) * ia.vertices]));
  }
  CHECK(finite);
  CHECK_MSG(moved > 0.01, "animate from the .glb did not move the mesh (%g m)", moved);
  free(fa);
  km_character_free(&c);
  return km_test_finish("test_skin_gltf");
}
