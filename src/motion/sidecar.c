/* The rig sidecar (<mesh>.rig.json): skeleton, skin weights and landmarks of a rigged mesh,
 * read and written here and nowhere else. */
#include "motion/motion.h"

#include "math/math.h"
#include "mesh/mesh.h"

#include <cjson/cJSON.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void km_character_free(km_character *c) {
  if (!c) return;
  km_mesh_free(&c->mesh);
  km_skeleton_free(&c->skeleton);
  km_skin_free(&c->skin);
  memset(c->landmarks, 0, sizeof c->landmarks);
}

km_status km__skin_alloc(km_skin *s, size_t n, km_error *err) {
  s->n_vertices = n;
  s->joints = km__malloc(n * KM_SKIN_INFLUENCES, sizeof *s->joints);
  s->weights = km__malloc(n * KM_SKIN_INFLUENCES, sizeof *s->weights);
  if (!s->joints || !s->weights) {
    km_skin_free(s);
    return km__fail(err, KM_ERR_NOMEM, "skin: out of memory (%zu vertices)", n);
  }
  return KM_OK;
}

/* ---------------------------------------------------------------- rig sidecar */

/* A JSON string literal (names come from files read back, so they may need escapes). */
static void write_json_string(FILE *f, const char *s) {
  fputc('"', f);
  for (const unsigned char *p = (const unsigned char *)s; *p; ++p) {
    if (*p == '"' || *p == '\\')
      fprintf(f, "\\%c", *p);
    else if (*p < 0x20)
      fprintf(f, "\\u%04x", *p);
    else
      fputc(*p, f);
  }
  fputc('"', f);
}

void km__landmarks_write_json(FILE *f, const km_landmark *lm, size_t n) {
  fputc('[', f);
  for (size_t i = 0; i < n; ++i) {
    fputs(i ? ",\n{\"name\":" : "\n{\"name\":", f);
    write_json_string(f, lm[i].name);
    fprintf(f, ",\"vertex\":%d,\"mirror\":", (int)lm[i].vertex);
    write_json_string(f, lm[i].mirror);
    fputc('}', f);
  }
  fputc(']', f);
}

static int find_landmark(const km_character *c, const char *name) {
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i)
    if (!strcmp(c->landmarks[i].name, name)) return i;
  return -1;
}

/* ---- bone handles (issue 12): a band around the middle of each limb bone */

enum {
  N_LIMB_BANDS = 8,
  N_BANDS = 10,
  N_RINGS = 4,
  N_BONE_HANDLES = N_BANDS + N_RINGS,
  BAND_MAX = 64
};
static const char *const bone_handle_name[N_BONE_HANDLES] = {
    "upper_arm_left", "forearm_left", "upper_arm_right", "forearm_right", "thigh_left",
    "shin_left",      "thigh_right",  "shin_right",      "pelvis",        "chest",
    "elbow_left",     "elbow_right",  "knee_left",       "knee_right"};
static const char *const bone_handle_joints[N_BONE_HANDLES][2] = {
    {"ShoulderLeft", "ElbowLeft"}, {"ElbowLeft", "WristLeft"},    {"ShoulderRight", "ElbowRight"},
    {"ElbowRight", "WristRight"},  {"HipLeft", "KneeLeft"},       {"KneeLeft", "AnkleLeft"},
    {"HipRight", "KneeRight"},     {"KneeRight", "AnkleRight"},   {"HipCenter", "Spine"},
    {"Spine", "ShoulderCenter"},   {"ShoulderLeft", "WristLeft"}, {"ShoulderRight", "WristRight"},
    {"HipLeft", "AnkleLeft"},      {"HipRight", "AnkleRight"}};
/* Where along its bone (0: the bone's start joint, 1: its end) a band lies. The upper arm and
 * thigh bands sit on the outer part (0.5 .. 0.8), leaving the shoulder and hip a free zone of
 * half the bone: a limb swinging 90 degrees about a joint whose band starts at 0.3 stretched the
 * armpit and crotch to 1.8-2.3x (bench motion, B: character 1.93 -> 1.30, armadillo
 * 1.84 -> 1.51 on precog_Seq1_1). Forearm and shin bands stay in the middle (0.3 .. 0.7): moved
 * further out they leave the elbow and knee too little room. Pelvis and chest bands on the
 * spine bones (with the whole mesh following the root rigidly, below): without them the torso
 * was free, and when the demo's kung-fu performer spun round, the limbs turned and the torso
 * did not, twisting legs and neck into ropes (mean 128 mm from the skinned character at frame
 * 78; 39 mm at worst with them). bench motion B, 150 frames, before -> after: folded
 * triangles character 276/284/424 -> 72/287/209 (kungfu, precog_Seq1_1, cmu_131_01),
 * armadillo 2559/1979/3713 -> 1369/1889/1962; the price: the armpit takes a raised arm (wave
 * shoulder stretch 0.53 -> 0.71) and dog0's one-frame jump on precog_Seq1_1 9.8 -> 17.4 %. */
static const double band_t[N_BONE_HANDLES][2] = {{0.5, 0.8}, {0.3, 0.7}, {0.5, 0.8}, {0.3, 0.7},
                                                 {0.5, 0.8}, {0.3, 0.7}, {0.5, 0.8}, {0.3, 0.7},
                                                 {0.2, 0.7}, {0.2, 0.6}};
/* Joint rings (elbows, knees): the vertices within RING_T of their bone's length from the
 * joint, on both bones. Their map entry is the segment over both bones (shoulder -> wrist, hip
 * -> ankle), which km_retarget turns about the middle joint along the segment's line: about
 * half the joint's bend, as the helper joint a rigger puts at an elbow. Without them the
 * reduced model put the whole bend between the two bands into a kink at the joint, whose inner
 * side collapsed and folded (bench motion B, character: 100 of the 222 folded triangles on
 * cmu_131_01 and 370 of 392 on precog_Seq1_1 at the elbows, |l/l0 - 1| up to 0.94 there). */
#define RING_T 0.08

static double dist3(const double *a, const double *b) {
  double w[3];
  km__sub3(a, b, w);
  return sqrt(km__dot3(w, w));
}

static int skel_joint(const km_skeleton *sk, const char *name) {
  for (size_t j = 0; j < sk->n_joints; ++j)
    if (sk->names[j] && !strcmp(sk->names[j], name)) return (int)j;
  return -1;
}

/* Whether the body stands upright (km__body_upright): its spine (hip centre -> shoulder
 * centre) closer to vertical than horizontal, and its hands above its knees. cat-08, a cat
 * sitting up with its front paws on the ground, passed the spine alone and took a person's
 * rig, held only by the stubby-limb limits its haunches (thighs 0.52 of their bone) brought:
 * animate on precog_Seq1_1 / Seq3_2, longest edge 1.77 / 1.65x; with a free swing 3.08x (Seq3_2),
 * a foreleg drawn out like an arm; with a quadruped's rig, as the other sitting cats (cat-02,
 * cat-09, whose spines lean), 1.28 / 1.29x and no fold. */
static bool upright_body(const km_skeleton *sk) {
  int hc = skel_joint(sk, "HipCenter"), sc = skel_joint(sk, "ShoulderCenter");
  int hl = skel_joint(sk, "HandLeft"), hr = skel_joint(sk, "HandRight"),
      kl = skel_joint(sk, "KneeLeft"), kr = skel_joint(sk, "KneeRight");
  const double *J = sk->rest;
  return hc >= 0 && sc >= 0 &&
         km__body_upright(J + 3 * (size_t)hc, J + 3 * (size_t)sc,
                          hl >= 0 ? J + 3 * (size_t)hl : NULL, hr >= 0 ? J + 3 * (size_t)hr : NULL,
                          kl >= 0 ? J + 3 * (size_t)kl : NULL, kr >= 0 ? J + 3 * (size_t)kr : NULL);
}

/* Bands: every vertex goes to the bone segment nearest to it (of all the skeleton's bones);
 * a bone's band is its vertices whose projection falls in band_t of the segment (none on a
 * stubby limb, below), cut to the connected part (along faces) holding the band vertex
 * nearest to the band's middle, and kept off the end handles' balls (centre ends[e], Euclidean
 * radius: the geodesic balls km_rig_parse grows are inside them). band[v] = the band of v, -1
 * none; *stubby: the median limb bone is stubby (the body's build, below); vj, vt (n, the
 * caller's, filled): the child joint of each vertex's nearest bone (-1 none) and the vertex's
 * projection on it, 0..1. Returns false when out of memory. */
static bool bone_bands(const km_character *c, const int32_t *ends, size_t n_ends, double radius,
                       bool upright, bool legs, int8_t *band, int bone_ok[N_BONE_HANDLES],
                       bool *stubby, int32_t *vj, double *vt) {
  const km_mesh *m = &c->mesh;
  const km_skeleton *sk = &c->skeleton;
  size_t n = m->n_vertices;
  int32_t *uf = km__malloc(n, sizeof(int32_t));
  double *best = km__malloc(N_BONE_HANDLES, sizeof(double));
  int32_t *seed = km__malloc(N_BONE_HANDLES, sizeof(int32_t));
  double *vd = km__malloc(n, sizeof(double));    /* distance to it */
  double *dists = km__malloc(n, sizeof(double)); /* scratch for a median */
  if (!uf || !best || !seed || !vd || !dists) {
    free(uf), free(best), free(seed), free(vd), free(dists);
    return false;
  }
  int ja[N_BONE_HANDLES], jb[N_BONE_HANDLES];
  for (int b = 0; b < N_BONE_HANDLES; ++b) {
    ja[b] = skel_joint(sk, bone_handle_joints[b][0]);
    jb[b] = skel_joint(sk, bone_handle_joints[b][1]);
    bone_ok[b] =
        ja[b] >= 0 && jb[b] >= 0 &&
        (b < N_BANDS ? sk->parents[jb[b]] == ja[b]
                     : sk->parents[jb[b]] >= 0 && sk->parents[sk->parents[jb[b]]] == ja[b]);
    best[b] = INFINITY;
    seed[b] = -1;
  }
  for (size_t v = 0; v < n; ++v) {
    const double *x = m->V + 3 * v;
    double dmin = INFINITY, tmin = 0;
    int jmin = -1;
    for (size_t j = 0; j < sk->n_joints; ++j) {
      int q = sk->parents[j];
      double dd = INFINITY, t = 0;
      if (q >= 0) {
        const double *a = sk->rest + 3 * (size_t)q, *b = sk->rest + 3 * j;
        double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double ax[3] = {x[0] - a[0], x[1] - a[1], x[2] - a[2]};
        double ll = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
        t = ll > 0 ? (ax[0] * ab[0] + ax[1] * ab[1] + ax[2] * ab[2]) / ll : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        double d[3] = {ax[0] - t * ab[0], ax[1] - t * ab[1], ax[2] - t * ab[2]};
        dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      }
      if (dd < dmin) dmin = dd, tmin = t, jmin = (int)j;
    }
    vj[v] = jmin;
    vt[v] = tmin;
    vd[v] = sqrt(dmin);
  }
  /* Stubby limbs: a bend of a joint needs skin to take it, about the limb's radius on each side
   * of it. The radius of a limb bone is the median distance of its vertices in the middle of its
   * length; where it is at least half the bone's length (the elephant's arms and legs: 0.76-0.97;
   * the character's 0.1-0.2, the armadillo's 0.27-0.47) no band fits between two free zones, and
   * the bands of upper arm and forearm touched at the elbow (thigh and shin at the knee, thighs
   * across the crotch), whose edges tore to 4.7-7x when the joint bent (precog_Seq2_1). Such a
   * bone has no band: its limb turns between the chest or pelvis band and the hand or foot
   * handle, which turns with the elbow -> hand (knee -> foot) line. A thin ring around the
   * bone's middle (0.45 .. 0.55) was tried before: on the elephant's coarse mesh it came apart
   * along faces and the cut below kept 1-4 of its 9-45 vertices, a point pinned in free skin
   * where the longest edge sat (precog_Seq3_2: 1.53x beside the right upper arm's two); the
   * whole ring, pinned rigid, was worse (longest edge 1.62/1.62/1.66/1.51/1.51x). bench motion
   * B, elephant, the table's take order, ring -> no band: longest edge
   * 1.444/1.445/1.530/1.434/1.426 -> 1.440/1.450/1.430/1.416/1.408x, shortest
   * 0.416/0.447/0.406/0.392/0.403 -> 0.455/0.438/0.403/0.364/0.374x, no fold before or after.
   * Narrowing the bands of the slimmer limbs to free zones of one radius cost the armadillo
   * stretch (precog_Seq3_2 1.10 -> 1.32), so they keep band_t. */
  /* A quadruped's upper arm and thigh lie inside its trunk (a horse's humerus and femur): their
   * bands were trunk skin, and a swinging leg dragged the chest and belly with it (the horse on
   * precog_Seq1_1: the underside of the chest stretched 3.35x, a web to a foreleg swung level).
   * Without them the trunk stays with the pelvis and chest bands and the leg turns below it.
   * bench motion B, before -> after, the table's take order: horse stretch max
   * 2.35/2.16/2.14/2.03/2.38 -> 0.95/0.93/0.90/0.72/0.67, folded triangles 384/397/522/617/464
   * -> 0 on every take; dog0 stretch 1.15/0.95/0.97/0.94/0.91 -> 0.66/0.62/0.56/0.56/0.47,
   * folded 2/15/0/14/0 -> 0 (with "swing_limit" 30, in the writer). On upright bodies the bands
   * stay: without them the character's folds rose (81/127/329/42/70 -> 112/213/421/57/99). */
  if (!upright)
    for (int b = 0; b < N_LIMB_BANDS; b += 2)
      bone_ok[b] = 0;
  /* An upper body's legs are folded into its base, which holds the pelvis too: no thigh,
   * shin, pelvis or knee band */
  static const int leg_bands[] = {4, 5, 6, 7, 8, 12, 13};
  for (size_t i = 0; !legs && i < sizeof leg_bands / sizeof leg_bands[0]; ++i)
    bone_ok[leg_bands[i]] = 0;
  /* A limb bone is stubby by the mean of its ratio and its mirror's (the body is left-right
   * symmetric; a scan's or a model's two sides are not quite), and the body's limbs are
   * (*stubby: the rig limits their swing, km_character_write_rig) when the median limb bone's
   * ratio is: one thick bone is a part, not the build. The decimated knight's right pauldron
   * spikes put its right upper arm at 0.503 (its left 0.459, its other limb bones 0.21-0.36):
   * that arm lost its band, and the whole knight took the elephant's 12 degrees of swing, so its
   * arms hung still while the performer reached overhead (precog_Seq3_2 frame 60). */
  double ratio[N_LIMB_BANDS], sorted[N_LIMB_BANDS];
  int n_ratio = 0;
  for (int b = 0; b < N_LIMB_BANDS; ++b) { /* the spine's bands hold a torso */
    ratio[b] = NAN;
    if (!bone_ok[b]) continue;
    size_t k = 0;
    for (size_t v = 0; v < n; ++v)
      if (vj[v] == jb[b] && vt[v] > 0.2 && vt[v] < 0.8) dists[k++] = vd[v];
    double len = dist3(sk->rest + 3 * (size_t)ja[b], sk->rest + 3 * (size_t)jb[b]);
    if (!k || !(len > 0)) continue;
    qsort(dists, k, sizeof(double), km__cmp_double);
    sorted[n_ratio++] = ratio[b] = dists[k / 2] / len;
  }
  for (int b = 0; b < N_LIMB_BANDS; ++b) {
    double r = ratio[b], mirror = ratio[b ^ 2]; /* left <-> right: 0 <-> 2, 1 <-> 3, ... */
    if (isfinite(mirror)) r = 0.5 * (r + mirror);
    if (r >= 0.5) bone_ok[b] = 0;
  }
  if (n_ratio) {
    qsort(sorted, (size_t)n_ratio, sizeof(double), km__cmp_double);
    *stubby = 0.5 * (sorted[(n_ratio - 1) / 2] + sorted[n_ratio / 2]) >= 0.5;
  }
  /* A ring's limb radius at its joint (the nearest vertex); the ring is the part within twice
   * that of the joint (a t of 1 or 0 is also every vertex beyond the bone's end, the elephant's
   * ear beside its elbow), and only on a limb whose bones are at least 3 radii long: on a stubby
   * arm (the elephant's) a ring between the bands left the joint no room to bend (folded
   * triangles on precog_Seq1_1 740 -> 1042). */
  double ring_r[N_BONE_HANDLES];
  /* Rings only on an upright body (the spine closer to vertical than horizontal): on dog0, rigged
   * as a quadruped, they cost folds (bench motion B precog_Seq3_2 330 -> 529, cmu_131_03
   * 58 -> 139) where they spared the upright character's and armadillo's. */
  for (int b = N_BANDS; b < N_BONE_HANDLES; ++b) {
    ring_r[b] = INFINITY;
    if (!upright) bone_ok[b] = 0;
    if (!bone_ok[b]) continue;
    const double *cj = sk->rest + 3 * (size_t)sk->parents[jb[b]];
    for (size_t v = 0; v < n; ++v)
      ring_r[b] = fmin(ring_r[b], dist3(m->V + 3 * v, cj));
    bone_ok[b] = dist3(cj, sk->rest + 3 * (size_t)ja[b]) >= 3 * ring_r[b] &&
                 dist3(cj, sk->rest + 3 * (size_t)jb[b]) >= 3 * ring_r[b];
  }
  for (size_t v = 0; v < n; ++v) {
    const double *x = m->V + 3 * v;
    band[v] = -1;
    uf[v] = (int32_t)v;
    bool near_end = false;
    for (size_t e = 0; e < n_ends && !near_end; ++e) {
      const double *y = m->V + 3 * (size_t)ends[e];
      double dx = x[0] - y[0], dy = x[1] - y[1], dz = x[2] - y[2];
      near_end = dx * dx + dy * dy + dz * dz <= 1.05 * 1.05 * radius * radius;
    }
    if (near_end) continue;
    int jmin = vj[v];
    double tmin = vt[v];
    for (int b = 0; b < N_BANDS; ++b)
      if (bone_ok[b] && jmin == jb[b] && tmin >= band_t[b][0] && tmin <= band_t[b][1]) {
        band[v] = (int8_t)b;
        double mid = fabs(tmin - 0.5 * (band_t[b][0] + band_t[b][1])) + vd[v];
        if (mid < best[b]) best[b] = mid, seed[b] = (int32_t)v;
      }
    for (int b = N_BANDS; b < N_BONE_HANDLES; ++b) { /* ring: jb's parent is the middle joint */
      int jr = bone_ok[b] ? sk->parents[jb[b]] : -1;
      if (jr < 0 || !((jmin == jr && tmin >= 1 - RING_T) || (jmin == jb[b] && tmin <= RING_T)))
        continue;
      double near = dist3(x, sk->rest + 3 * (size_t)jr);
      if (near > 2 * ring_r[b]) continue;
      band[v] = (int8_t)b;
      if (near < best[b]) best[b] = near, seed[b] = (int32_t)v;
    }
  }
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t a = m->F[3 * f + k], b = m->F[3 * f + (k + 1) % 3];
      if (band[a] >= 0 && band[a] == band[b]) km__uf_union(uf, a, b);
    }
  for (int b = 0; b < N_BONE_HANDLES; ++b)
    bone_ok[b] = bone_ok[b] && seed[b] >= 0;
  for (size_t v = 0; v < n; ++v)
    if (band[v] >= 0 &&
        (!bone_ok[band[v]] || km__uf_find(uf, (int32_t)v) != km__uf_find(uf, seed[band[v]])))
      band[v] = -1;
  free(uf), free(best), free(seed), free(vd), free(dists);
  return true;
}

const char *km_character_landmark_name(int i, const char **mirror) {
  static const char *const names[KM_CHARACTER_LANDMARKS][2] = {{"head", "head"},
                                                               {"neck", "neck"},
                                                               {"shoulder_left", "shoulder_right"},
                                                               {"shoulder_right", "shoulder_left"},
                                                               {"elbow_left", "elbow_right"},
                                                               {"elbow_right", "elbow_left"},
                                                               {"hand_left", "hand_right"},
                                                               {"hand_right", "hand_left"},
                                                               {"chest", "chest"},
                                                               {"pelvis", "pelvis"},
                                                               {"hip_left", "hip_right"},
                                                               {"hip_right", "hip_left"},
                                                               {"knee_left", "knee_right"},
                                                               {"knee_right", "knee_left"},
                                                               {"foot_left", "foot_right"},
                                                               {"foot_right", "foot_left"}};
  if (i < 0 || i >= KM_CHARACTER_LANDMARKS) return NULL;
  if (mirror) *mirror = names[i][1];
  return names[i][0];
}

/* The end handles, in the rig's order. */
static const char *const handle_names[5] = {"head", "hand_left", "hand_right", "foot_left",
                                            "foot_right"};

/* What a rig file says beyond the character itself: its handles and bands, computed once
 * (rig_plan_make) and then streamed (write_rig_stream). */
typedef struct rig_plan {
  long handle_vertex[5];
  int32_t *end_list[5]; /* an end handle's vertices (end_handles); NULL: "vertex" + "radius" */
  size_t n_end[5];
  double radius;
  int8_t *band; /* n_vertices: the bone handle of each vertex, -1 none */
  int bone_ok[N_BONE_HANDLES];
  bool upright;
  bool stubby; /* the median limb bone's radius is half its length or more (bone_bands) */
  /* A bust (km__bust_base: an open cut at its bottom) or a body sitting on a broad base
   * (km__seated_base): a head handle turning with the neck and a base anchor instead of the end
   * handles and bands (bust_handles) */
  bool bust;
  bool resting; /* a bust's handles on a body lying or curled up (resting_handles) */
  /* An upper body (legs_folded, on a bust's base): the humanoid's head, hands and arm and chest
   * bands, no feet nor leg bands, and the base anchor (upper_base) */
  bool upper;
  int32_t *base_list; /* the base anchor's vertices */
  size_t n_base;
} rig_plan;

static km_status rig_plan_make(const char *path, const km_character *c, rig_plan *p, km_error *err);

static void plan_free(rig_plan *p) {
  free(p->band);
  p->band = NULL;
  free(p->base_list);
  p->base_list = NULL;
  for (int h = 0; h < 5; ++h) {
    free(p->end_list[h]);
    p->end_list[h] = NULL;
  }
}

/* Streams the JSON with fprintf: a cJSON tree of 8M numbers for a 1M-vertex skin would cost
 * gigabytes. Weights are written with 7 significant digits. */
static void write_rig_stream(FILE *f, const km_character *c, const rig_plan *p);

km_status km_character_write_rig(const char *path, const km_character *c, km_error *err) {
  if (!path || !c) return km__fail(err, KM_ERR_INVALID, "write rig: NULL argument");
  km__atomic_file af;
  rig_plan p;
  km_status st = rig_plan_make(path, c, &p, err); /* validate before creating the file */
  if (st != KM_OK) return st;
  if ((st = km__atomic_open(&af, path, err)) == KM_OK) {
    write_rig_stream(af.f, c, &p);
    st = km__atomic_commit(&af, err);
  }
  plan_free(&p);
  return st;
}

km_status km_character_rig_json(const km_character *c, char **json, size_t *size, km_error *err) {
  if (!c || !json || !size) return km__fail(err, KM_ERR_INVALID, "rig json: NULL argument");
  *json = NULL;
  *size = 0;
  rig_plan p;
  km_status st = rig_plan_make("rig", c, &p, err);
  if (st != KM_OK) return st;
  FILE *f = open_memstream(json, size);
  if (!f) {
    plan_free(&p);
    return km__fail(err, KM_ERR_NOMEM, "rig json: out of memory");
  }
  write_rig_stream(f, c, &p);
  plan_free(&p);
  if (fclose(f) != 0 || !*json) {
    free(*json);
    *json = NULL;
    return km__fail(err, KM_ERR_NOMEM, "rig json: out of memory");
  }
  return KM_OK;
}

/* Hands and feet: the end handle is its geodesic ball (radius p->radius around the finger or
 * toe tip, as km_rig_parse grows it for "vertex" + "radius") and, joined to it along faces,
 * every vertex whose nearest bone (nearest[v], the bone's child joint) ends at the hand or foot
 * joint, or ends at the wrist or ankle with the vertex beyond its end (nearest_t[v] 1: the back
 * of a heel is as near the shin's end as the foot bone's start, and went to the shin): the whole
 * hand or foot, heel, sole and every claw, held rigid as a game rig's hand and foot bones hold
 * them. With the ball alone a splayed foot kept only the claw nearest the tip
 * (the armadillo's outer claw, 13 cm from its foot joint): the other claws and the heel were
 * free skin between the ball and the shin band, stretched 2.1x on a kick and sagging below the
 * floor. The vertices of another handle (a band, another end's ball) are left out, so handles
 * stay disjoint. bench motion B, before -> after, the table's take order: armadillo stretch max
 * 1.143/1.733/1.105/1.013/1.308 -> 0.985/1.195/0.992/0.994/1.001, folded triangles
 * 1697/1557/1430/1100/1007 -> 1265/1205/1079/1074/803, frames below the floor
 * 24/31/26/227/118 -> 0/0/0/227/91; character stretch 1.150/1.308/1.046/1.175/1.281 ->
 * 1.119/1.240/1.043/1.128/1.236, folded 83/131/331/36/61 -> 116/132/367/32/12; horse and dog0
 * within 0.01, elephant within 0.06 (0.835/0.768/0.780/0.735/0.752 ->
 * 0.776/0.772/0.820/0.759/0.779). The head stays a ball: a rigid head and neck cost dog0
 * 0.38 -> 0.70. A handle's every vertex constrains the solve: keeping every k-th of the foot's
 * own (at most 64, as bands) lost most of the gain (armadillo 1.670 on precog_Seq2_1).
 * p->end_list[h]: NULL where the handle stays a plain ball (the head,
 * a skeleton without the joint, a tip another end's ball holds, a point cloud). */
static km_status end_handles(const km_character *c, const int32_t *nearest, const double *nearest_t,
                             rig_plan *p, km_error *err) {
  const km_mesh *m = &c->mesh;
  size_t n = m->n_vertices;
  static const char *const joint[5] = {"Head", "HandLeft", "HandRight", "FootLeft", "FootRight"};
  if (!m->n_faces) return KM_OK; /* a point cloud: km_rig_parse's Euclidean balls */
  km__geodesic *geo = NULL;
  km_status st = km__geodesic_create(m, &geo, err);
  if (st != KM_OK) return st;
  int32_t *uf = km__malloc(n, sizeof(int32_t));
  int8_t *ball = km__malloc(n, 1); /* the end handle whose ball holds v (the first), -1 none */
  int8_t *end = km__malloc(n, 1);  /* the hand or foot v may join, -1 none */
  if (!uf || !ball || !end) {
    st = km__fail(err, KM_ERR_NOMEM, "out of memory");
    goto done;
  }
  memset(ball, -1, n);
  for (int h = 0; h < 5; ++h) {
    const int32_t *reached;
    size_t nr;
    km__geodesic_run(geo, m->V, (int32_t)p->handle_vertex[h], p->radius, NULL, 0, &reached, &nr);
    for (size_t k = 0; k < nr; ++k)
      if (ball[reached[k]] < 0) ball[reached[k]] = (int8_t)h;
  }
  /* A vertex joins the end whose ball holds it, else the hand or foot whose bone it is nearest
   * (off the bands and the other balls); the bones differ, so the ends' sets are disjoint. */
  int js[5], jps[5];
  for (int h = 1; h < 5; ++h) {
    js[h] = skel_joint(&c->skeleton, joint[h]);
    jps[h] = js[h] >= 0 ? c->skeleton.parents[js[h]] : -1; /* the wrist or ankle */
  }
  for (size_t v = 0; v < n; ++v) {
    end[v] = ball[v];
    uf[v] = (int32_t)v;
    if (ball[v] >= 0 || p->band[v] >= 0) continue;
    for (int h = 1; h < 5 && end[v] < 0; ++h)
      if (js[h] >= 0 &&
          (nearest[v] == js[h] || (jps[h] >= 0 && nearest[v] == jps[h] && nearest_t[v] >= 1)))
        end[v] = (int8_t)h;
  }
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t a = m->F[3 * f + k], b = m->F[3 * f + (k + 1) % 3];
      if (end[a] >= 0 && end[a] == end[b]) km__uf_union(uf, a, b);
    }
  for (int h = 1; h < 5; ++h) {
    int32_t tip = (int32_t)p->handle_vertex[h];
    if (js[h] < 0 || end[tip] != h) continue; /* its tip in another's ball: km_rig_parse says */
    int32_t root = km__uf_find(uf, tip);
    size_t cnt = 0;
    for (size_t v = 0; v < n; ++v)
      cnt += end[v] == h && km__uf_find(uf, (int32_t)v) == root;
    if (!(p->end_list[h] = km__malloc(cnt, sizeof(int32_t)))) {
      st = km__fail(err, KM_ERR_NOMEM, "out of memory");
      goto done;
    }
    for (size_t v = 0; v < n; ++v)
      if (end[v] == h && km__uf_find(uf, (int32_t)v) == root)
        p->end_list[h][p->n_end[h]++] = (int32_t)v;
  }
done:
  free(uf), free(ball), free(end);
  km__geodesic_free(&geo);
  return st;
}

/* Whether both ends lie near their roots (each end_k within frac of the distance between
 * joints ref0 and ref1 of root_k): limbs folded into the body, as km_autorig places a bust's
 * arms and an upper body's legs. */
static bool ends_near(const km_skeleton *sk, const char *const root[2], const char *const end[2],
                      const char *ref0, const char *ref1, double frac) {
  int r0 = skel_joint(sk, ref0), r1 = skel_joint(sk, ref1);
  if (r0 < 0 || r1 < 0) return false;
  const double *J = sk->rest;
  double len = dist3(J + 3 * (size_t)r0, J + 3 * (size_t)r1);
  for (int k = 0; k < 2; ++k) {
    int a = skel_joint(sk, root[k]), b = skel_joint(sk, end[k]);
    if (a < 0 || b < 0 || !(dist3(J + 3 * (size_t)a, J + 3 * (size_t)b) < frac * len)) return false;
  }
  return true;
}

/* Whether the arms are folded into the shoulders, as km_autorig places a bust's: each hand
 * within 0.4 of the shoulders' span of its shoulder (an arm is about that span long or more). */
static bool arms_folded(const km_skeleton *sk) {
  static const char *const root[2] = {"ShoulderLeft", "ShoulderRight"}, *const end[2] = {
                                                                            "HandLeft",
                                                                            "HandRight"};
  return ends_near(sk, root, end, "ShoulderLeft", "ShoulderRight", 0.4);
}

/* Whether the legs are folded into the base, as km_autorig places an upper body's: each foot
 * within a quarter of the spine (HipCenter -> ShoulderCenter) of HipCenter. */
static bool legs_folded(const km_skeleton *sk) {
  static const char *const root[2] = {"HipCenter", "HipCenter"}, *const end[2] = {"FootLeft",
                                                                                  "FootRight"};
  return ends_near(sk, root, end, "HipCenter", "ShoulderCenter", 0.25);
}

/* Every k-th of the vertices v with take[v] == 1 (n of them), in order, k chosen so that at
 * most BAND_MAX are kept: an anchor needs a few points spread over its region, and the
 * per-frame solve costs per handle vertex. out: the caller's (n); returns the count. */
static size_t pick_spread(const uint8_t *take, size_t n, int32_t *out) {
  size_t all = 0, i = 0, kept = 0;
  for (size_t v = 0; v < n; ++v)
    all += take[v] == 1;
  size_t every = (all + BAND_MAX - 1) / BAND_MAX;
  for (size_t v = 0; v < n && every; ++v)
    if (take[v] == 1 && i++ % every == 0) out[kept++] = (int32_t)v;
  return kept;
}

/* The two handles of a bust-like rig (bust_handles, resting_handles): with s(v) = (v - o) . a
 * (a a unit axis), the head (end_list[0]) is the vertices with s >= neck joined along faces,
 * through such vertices only, to seed; the base (base_list) the others with s <= base, spread
 * (pick_spread). Either may come out empty (the caller says why). */
static km_status split_head_base(const km_mesh *m, const double o[3], const double a[3],
                                 double neck, double base, int32_t seed, rig_plan *p,
                                 km_error *err) {
  size_t n = m->n_vertices;
  int32_t *uf = km__malloc(n, sizeof(int32_t));
  uint8_t *take = km__malloc(n, 1); /* the base's vertices, before pick_spread */
  double *sv = km__malloc(n, sizeof(double));
  p->end_list[0] = km__malloc(n, sizeof(int32_t));
  p->base_list = km__malloc(n, sizeof(int32_t));
  if (!uf || !take || !sv || !p->end_list[0] || !p->base_list) {
    free(uf), free(take), free(sv);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  }
  for (size_t v = 0; v < n; ++v) {
    const double *x = m->V + 3 * v;
    double d[3] = {x[0] - o[0], x[1] - o[1], x[2] - o[2]};
    sv[v] = km__dot3(d, a);
    uf[v] = (int32_t)v;
  }
  for (size_t f = 0; f < m->n_faces; ++f)
    for (int k = 0; k < 3; ++k) {
      int32_t u = m->F[3 * f + k], w = m->F[3 * f + (k + 1) % 3];
      if (sv[u] >= neck && sv[w] >= neck) km__uf_union(uf, u, w);
    }
  int32_t top = km__uf_find(uf, seed);
  for (size_t v = 0; v < n; ++v) {
    bool head = sv[v] >= neck && km__uf_find(uf, (int32_t)v) == top;
    if (head) p->end_list[0][p->n_end[0]++] = (int32_t)v;
    take[v] = !head && sv[v] <= base;
  }
  free(uf), free(sv);
  p->n_base = pick_spread(take, n, p->base_list);
  free(take);
  return KM_OK;
}

/* A bust's handles: the head (end_list[0]: the vertices above the middle of the neck bone,
 * ShoulderCenter -> Head, joined to the top vertex along faces), held rigid and turned with
 * the performer's neck, and the base (the vertices within 0.15 of the height of the bottom,
 * off the head, spread: pick_spread) held still: a bust stands on its cut. With the
 * quadruped's or a prop's hands and feet on the corners of its cut, a performer's steps
 * crumpled its chest. A head cut at its neck (ShoulderCenter in the bottom 0.1 of the height)
 * holds only its bottom 0.03 and turns everything above 0.25: a base of 0.15 held its chin
 * while the head nodded, shearing the jaw (bench motion on FAUST's top 13 %, longest edge on
 * precog_Seq1_1 / cmu_131_01 1.74 / 1.90 -> 1.55 / 1.73x; the head from 0.08: 1.81 / 2.29x). */
static km_status bust_handles(const km_character *c, double ymin, double ymax, rig_plan *p,
                              km_error *err) {
  const km_mesh *m = &c->mesh;
  const km_skeleton *sk = &c->skeleton;
  int sc = skel_joint(sk, "ShoulderCenter"), hd = skel_joint(sk, "Head");
  if (sc < 0 || hd < 0)
    return km__fail(err, KM_ERR_INVALID, "rig: a bust needs ShoulderCenter and Head joints");
  double H = ymax - ymin, ysc = sk->rest[3 * (size_t)sc + 1];
  double yneck = 0.5 * (ysc + sk->rest[3 * (size_t)hd + 1]);
  double ybase = ymin + 0.15 * H;
  if (ysc < ymin + 0.1 * H) { /* a head cut at its neck: a thin ring held, the jaw turns */
    ybase = ymin + 0.03 * H;
    yneck = ymin + 0.25 * H;
  }
  static const double o[3] = {0, 0, 0}, up[3] = {0, 1, 0}; /* s(v) = y */
  km_status st = split_head_base(m, o, up, yneck, ybase, (int32_t)p->handle_vertex[0], p, err);
  if (st != KM_OK) return st;
  if (!p->n_end[0] || !p->n_base)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the bust's head (above y %.4g) or base (below y %.4g) has no vertex",
                    yneck, ybase);
  return KM_OK;
}

/* A resting body's handles (km_autorig's KM_AUTORIG_RESTING: arms and legs folded, no base
 * it sits on; a cat lying on its side or curled up): a bust's, cut across its neck instead of
 * by height. With a = the unit direction Spine -> ShoulderCenter (the body's at the neck) and
 * s(v) = (v - ShoulderCenter) . a: the head (end_list[0]) is the vertices ahead of the neck
 * (s >= 0) joined along faces, through such vertices only, to the vertex nearest the Head
 * joint (a paw or tail curled up by the face is not, it joins the head only through the body);
 * the base is the vertices behind the shoulders by two thirds of the spine bone (Spine ->
 * ShoulderCenter), off the head, spread (pick_spread): the body lies still while the head
 * turns with the performer's neck. animate, longest edge on precog_Seq1_1 / cmu_131_01, the
 * curled cat-07 and cat-04 lying on its side (heads given: an ear tip each): base from a third
 * 2.19x / - and 1.37x / -, from two thirds 1.65 / 1.45x and 1.25 / 1.52x, from a whole spine
 * bone 1.64 / 1.44x and 1.24 / 1.51x. */
static km_status resting_handles(const km_character *c, rig_plan *p, km_error *err) {
  const km_mesh *m = &c->mesh;
  const km_skeleton *sk = &c->skeleton;
  size_t n = m->n_vertices;
  int sc = skel_joint(sk, "ShoulderCenter"), hd = skel_joint(sk, "Head"),
      sp = skel_joint(sk, "Spine");
  if (sc < 0 || hd < 0 || sp < 0)
    return km__fail(err, KM_ERR_INVALID,
                    "rig: a resting body needs Spine, ShoulderCenter and Head joints");
  const double *S = sk->rest + 3 * (size_t)sc, *Hj = sk->rest + 3 * (size_t)hd,
               *B = sk->rest + 3 * (size_t)sp;
  double a[3] = {S[0] - B[0], S[1] - B[1], S[2] - B[2]}, len = sqrt(km__dot3(a, a));
  if (!(len > 0))
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the resting body's spine (Spine -> ShoulderCenter) has no length");
  for (int k = 0; k < 3; ++k)
    a[k] /= len;
  size_t near = 0;
  for (size_t v = 1; v < n; ++v)
    if (dist3(m->V + 3 * v, Hj) < dist3(m->V + 3 * near, Hj)) near = v;
  p->handle_vertex[0] = (long)near;
  km_status st = split_head_base(m, S, a, 0, -len * 2 / 3, (int32_t)near, p, err);
  if (st != KM_OK) return st;
  if (!p->n_end[0] || !p->n_base)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the resting body's head (ahead of its neck) or body (behind its "
                    "shoulders) has no vertex");
  return KM_OK;
}

/* An upper body's base anchor: the vertices within 0.15 of the height of the bottom that no
 * other handle holds (off the bands and the hand and head balls), spread (pick_spread); its
 * legs are folded into the base (bone_bands gave them no band), and the feet's handles go. The
 * base, which no map entry moves, follows the root. */
static km_status upper_base(const km_character *c, double ymin, double ymax, rig_plan *p,
                            km_error *err) {
  const km_mesh *m = &c->mesh;
  size_t n = m->n_vertices;
  for (int h = 3; h < 5; ++h) {
    free(p->end_list[h]);
    p->end_list[h] = NULL;
    p->n_end[h] = 0;
  }
  uint8_t *take = km__calloc(n, 1); /* 1: a base vertex; 2: another handle holds it */
  p->base_list = km__malloc(n, sizeof(int32_t));
  if (!take || !p->base_list) {
    free(take);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  }
  for (int h = 0; h < 3; ++h) {
    for (size_t k = 0; k < p->n_end[h]; ++k)
      take[p->end_list[h][k]] = 2;
    if (!p->end_list[h]) { /* a ball: km_rig_parse grows it within radius along the surface */
      const double *y = m->V + 3 * (size_t)p->handle_vertex[h];
      for (size_t v = 0; v < n; ++v)
        if (dist3(m->V + 3 * v, y) <= 1.05 * p->radius) take[v] = 2;
    }
  }
  double ybase = ymin + 0.15 * (ymax - ymin);
  for (size_t v = 0; v < n; ++v)
    if (take[v] == 0 && p->band[v] < 0 && m->V[3 * v + 1] <= ybase) take[v] = 1;
  p->n_base = pick_spread(take, n, p->base_list);
  free(take);
  if (!p->n_base)
    return km__fail(err, KM_ERR_DEGENERATE_MESH,
                    "rig: the upper body's base (below y %.4g) has no free vertex", ybase);
  return KM_OK;
}

/* Checks c and places the handles; p->band is the caller's to free. */
static km_status rig_plan_make_on(const char *path, const km_character *c, rig_plan *p,
                                  km_error *err);

/* Expands a vertex list of the welded mesh (ids < nw) to every copy: the vertices v of the
 * file whose to_w[v] is in it, ascending. *list is replaced (NULL stays NULL). */
static km_status expand_list(int32_t **list, size_t *n_list, const int32_t *to_w, size_t n,
                             size_t nw, km_error *err) {
  if (!*list) return KM_OK;
  unsigned char *in = km__calloc(nw ? nw : 1, 1);
  int32_t *out = km__malloc(n ? n : 1, sizeof *out);
  if (!in || !out) {
    free(in);
    free(out);
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  }
  for (size_t i = 0; i < *n_list; ++i)
    in[(*list)[i]] = 1;
  size_t k = 0;
  for (size_t v = 0; v < n; ++v)
    if (in[to_w[v]]) out[k++] = (int32_t)v;
  free(in);
  free(*list);
  *list = out;
  *n_list = k;
  return KM_OK;
}

/* The character a plan is made on when it is made on a part of c's mesh (welded at its seams,
 * or its body without its loose pieces): part's mesh and c's skeleton borrowed (cp's are to be
 * zeroed, not freed), each part vertex q the skin of c's vertex from[q], landmarks on to[] of
 * theirs (-1: the part's vertex 0). */
static km_status part_character(const km_character *c, const km_mesh *part, const int32_t *from,
                                const int32_t *to, km_character *cp, km_error *err) {
  size_t n = c->mesh.n_vertices, np = part->n_vertices;
  memset(cp, 0, sizeof *cp);
  cp->mesh = *part;
  cp->skeleton = c->skeleton;
  if (!(cp->skin.joints = km__malloc(4 * np, sizeof(int32_t))) ||
      !(cp->skin.weights = km__malloc(4 * np, sizeof(double))))
    return km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
  cp->skin.n_vertices = np;
  for (size_t q = 0; q < np; ++q)
    for (int k = 0; k < 4; ++k) {
      cp->skin.joints[4 * q + (size_t)k] = c->skin.joints[4 * (size_t)from[q] + (size_t)k];
      cp->skin.weights[4 * q + (size_t)k] = c->skin.weights[4 * (size_t)from[q] + (size_t)k];
    }
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i) {
    cp->landmarks[i] = c->landmarks[i];
    int32_t v = c->landmarks[i].vertex;
    if (v >= 0 && (size_t)v < n) cp->landmarks[i].vertex = to[v] >= 0 ? to[v] : 0;
  }
  return KM_OK;
}

/* Frees a part_character (its borrowed mesh and skeleton left alone). */
static void part_character_free(km_character *cp) {
  memset(&cp->skeleton, 0, sizeof cp->skeleton);
  memset(&cp->mesh, 0, sizeof cp->mesh);
  km_character_free(cp);
}

/* A character with small loose pieces (km__mesh_body: eyes, teeth, a buckle beside the body)
 * is planned on its body alone, and the plan comes back on the file's vertices: no handle
 * holds a loose piece's vertex (each follows the body where it is nearest: its skin weights
 * are that body vertex's, km_autorig, and so are its reduced-model fields, km_puppet), and the
 * head's centre is the body's highest vertex, not an eye above the brow. */
static km_status rig_plan_pieces(const char *path, const km_character *c, rig_plan *p,
                                 km_error *err) {
  const km_mesh *m = &c->mesh;
  size_t n = m->n_vertices;
  km__body bd;
  bool found = false;
  memset(p, 0, sizeof *p);
  if (!m->V || !m->F || !m->n_faces || c->skin.n_vertices != n || !c->skin.joints ||
      !c->skin.weights)
    return rig_plan_make_on(path, c, p, err);
  km_status s = km__mesh_body(m, &bd, &found, err);
  if (s != KM_OK) return s;
  if (!found) return rig_plan_make_on(path, c, p, err);
  const int32_t *from_b = bd.from_body;
  size_t nb = bd.body.n_vertices;
  km_character cb;
  if ((s = part_character(c, &bd.body, from_b, bd.to_body, &cb, err)) != KM_OK) goto done;
  if ((s = rig_plan_make_on(path, &cb, p, err)) != KM_OK) goto done;
  for (int h = 0; h < 5; ++h) {
    if (p->handle_vertex[h] >= 0 && (size_t)p->handle_vertex[h] < nb)
      p->handle_vertex[h] = from_b[p->handle_vertex[h]];
    for (size_t i = 0; p->end_list[h] && i < p->n_end[h]; ++i)
      p->end_list[h][i] = from_b[p->end_list[h][i]];
  }
  for (size_t i = 0; p->base_list && i < p->n_base; ++i)
    p->base_list[i] = from_b[p->base_list[i]];
  if (p->band) {
    int8_t *band = km__malloc(n, 1);
    if (!band) {
      s = km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
      plan_free(p);
      goto done;
    }
    memset(band, -1, n);
    for (size_t q = 0; q < nb; ++q)
      band[from_b[q]] = p->band[q];
    free(p->band);
    p->band = band;
  }
done:
  part_character_free(&cb);
  km__body_free(&bd);
  return s;
}

/* A character whose mesh is split at its texture seams (coincident vertices that cut it into
 * pieces or open it: a glTF exporter's output) is planned on the mesh welded there (bands cut to
 * one connected part, a bust's open cut, the hands' and feet's balls all look at the surface),
 * and the plan comes back on the file's vertices: every copy in its vertex's band and lists, a
 * handle's centre on the lowest id of its copies. */
static km_status rig_plan_make(const char *path, const km_character *c, rig_plan *p,
                               km_error *err) {
  const km_mesh *m = &c->mesh;
  size_t n = m->n_vertices;
  km__weld wd;
  if (!m->V || !m->F || !m->n_faces || c->skin.n_vertices != n || !c->skin.joints ||
      !c->skin.weights)
    return rig_plan_pieces(path, c, p, err);
  km_status s = km__mesh_weld(m, &wd, err);
  if (s != KM_OK) return s;
  if (!wd.to_w) return rig_plan_pieces(path, c, p, err);
  const int32_t *to_w = wd.to_w, *first = wd.first;
  size_t nw = wd.w.n_vertices;
  km_character cw;
  memset(p, 0, sizeof *p);
  if ((s = part_character(c, &wd.w, first, to_w, &cw, err)) != KM_OK) goto done;
  if ((s = rig_plan_pieces(path, &cw, p, err)) != KM_OK) goto done;
  for (int h = 0; h < 5 && s == KM_OK; ++h) {
    if (p->handle_vertex[h] >= 0 && (size_t)p->handle_vertex[h] < nw)
      p->handle_vertex[h] = first[p->handle_vertex[h]];
    s = expand_list(&p->end_list[h], &p->n_end[h], to_w, n, nw, err);
  }
  if (s == KM_OK) s = expand_list(&p->base_list, &p->n_base, to_w, n, nw, err);
  if (s == KM_OK && p->band) {
    int8_t *band = km__malloc(n, 1);
    if (!band) {
      s = km__fail(err, KM_ERR_NOMEM, "rig: out of memory");
    } else {
      for (size_t v = 0; v < n; ++v)
        band[v] = p->band[to_w[v]];
      free(p->band);
      p->band = band;
    }
  }
  if (s != KM_OK) plan_free(p);
done:
  part_character_free(&cw);
  km__weld_free(&wd);
  return s;
}

static km_status rig_plan_make_on(const char *path, const km_character *c, rig_plan *p,
                                  km_error *err) {
  memset(p, 0, sizeof *p);
  const km_mesh *m = &c->mesh;
  const km_skeleton *sk = &c->skeleton;
  size_t n = m->n_vertices;
  if (!n || !m->V || sk->n_joints == 0 || !sk->names || !sk->parents || !sk->rest)
    return km__fail(err, KM_ERR_INVALID, "%s: character has no mesh or skeleton", path);
  if (c->skin.n_vertices != n || !c->skin.joints || !c->skin.weights)
    return km__fail(err, KM_ERR_INVALID, "%s: skin has %zu vertices, mesh has %zu", path,
                    c->skin.n_vertices, n);
  for (int i = 0; i < KM_CHARACTER_LANDMARKS; ++i)
    if (c->landmarks[i].vertex < 0 || (size_t)c->landmarks[i].vertex >= n)
      return km__fail(err, KM_ERR_INVALID, "%s: landmark %s has vertex %d outside 0..%zu", path,
                      c->landmarks[i].name, (int)c->landmarks[i].vertex, n - 1);
  /* Handles: top of the head, finger tips and toe tips (landmarks). The top of the head is the
   * highest vertex, unless it lies over 0.3 of the height from the Head joint and the skin
   * gives it mostly to another joint: then the highest vertex the skin gives mostly to Head.
   * The highest of all can be a raised tail (the walking cat, cat-03, had its tail tip for a
   * head handle, turned by the performer's neck while its head hung free) or a hand held up
   * (FAUST's npt_14_664). An ear tip stays (the armadillo's, which the distance skin gives to
   * the hand beside it: on the skull top instead, bench motion B's folds rose 3-17 %). A
   * vertex in no face (a stray point a scan or an exporter left in the file) is none of these:
   * one above the head took the head handle alone, a point dragging nothing. */
  unsigned char *on_face = km__calloc(n, 1);
  if (!on_face) return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  for (size_t i = 0; i < 3 * m->n_faces; ++i)
    if (m->F[i] >= 0 && (size_t)m->F[i] < n) on_face[m->F[i]] = 1;
  if (!m->n_faces) memset(on_face, 1, n);
  size_t top = 0;
  double ymin = DBL_MAX, ymax = -DBL_MAX;
  for (size_t v = 0; v < n; ++v) {
    double y = m->V[3 * v + 1];
    if (!on_face[v]) continue;
    if (y > ymax) ymax = y, top = v;
    if (y < ymin) ymin = y;
  }
  double radius = 0.07 * (ymax - ymin);
  int jh = skel_joint(sk, "Head");
  if (jh >= 0 && dist3(m->V + 3 * top, sk->rest + 3 * jh) > 0.3 * (ymax - ymin) &&
      km__skin_dominant(c->skin.joints + 4 * top, c->skin.weights + 4 * top) != jh) {
    double best = -DBL_MAX;
    for (size_t v = 0; v < n; ++v)
      if (on_face[v] && m->V[3 * v + 1] > best &&
          km__skin_dominant(c->skin.joints + 4 * v, c->skin.weights + 4 * v) == jh)
        best = m->V[3 * v + 1], top = v;
  }
  free(on_face);
  p->radius = radius;
  p->handle_vertex[0] = (long)top;
  for (int h = 1; h < 5; ++h) {
    int li = find_landmark(c, handle_names[h]);
    p->handle_vertex[h] = li >= 0 ? c->landmarks[li].vertex : (long)top;
  }
  p->upright = upright_body(sk);
  /* On a base (km__rest_base: an open cut or a broad base it sits on, only looked for then):
   * a bust with its arms folded into its shoulders (arms_folded), an upper body with its arms
   * reaching out and its legs folded into the base (legs_folded), rigged with hands and bands. */
  bool arms_in = arms_folded(sk), based = false;
  double cut_top;
  if (arms_in || legs_folded(sk)) {
    km_status bs = km__rest_base(m, &based, &cut_top, err);
    if (bs != KM_OK) return bs;
  }
  /* arms and legs folded with no base under it: km_autorig's resting body (lying, curled up),
   * rigged as a bust along its neck (resting_handles) */
  bool resting = !based && arms_in && legs_folded(sk);
  p->resting = resting;
  p->bust = (based && arms_in) || resting;
  p->upper = based && !arms_in;
  if (p->bust) {
    km_status bs = resting ? resting_handles(c, p, err) : bust_handles(c, ymin, ymax, p, err);
    if (bs != KM_OK) {
      plan_free(p);
      return km__wrap(err, bs, "%s", path);
    }
    return KM_OK;
  }
  p->band = km__malloc(n, 1);
  int32_t ends[5];
  for (int h = 0; h < 5; ++h)
    ends[h] = (int32_t)p->handle_vertex[h];
  p->stubby = false;
  int32_t *nearest = km__malloc(n, sizeof(int32_t));
  double *nearest_t = km__malloc(n, sizeof(double));
  if (!p->band || !nearest || !nearest_t ||
      !bone_bands(c, ends, 5, radius, p->upright, !p->upper, p->band, p->bone_ok, &p->stubby,
                  nearest, nearest_t)) {
    free(nearest);
    free(nearest_t);
    plan_free(p);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  km_status st = end_handles(c, nearest, nearest_t, p, err);
  free(nearest);
  free(nearest_t);
  if (st == KM_OK && p->upper) st = upper_base(c, ymin, ymax, p, err);
  if (st != KM_OK) {
    plan_free(p);
    return km__wrap(err, st, "%s", path);
  }
  return KM_OK;
}

/* One handle of the rig file: sep ("," after another handle), then {"name":..,"vertices":[..]}. */
static void write_handle(FILE *f, const char *sep, const char *name, const int32_t *v, size_t n) {
  fprintf(f, "%s\n{\"name\":\"%s\",\"vertices\":[", sep, name);
  for (size_t k = 0; k < n; ++k)
    fprintf(f, k ? ",%d" : "%d", v[k]);
  fputs("]}", f);
}

static void write_rig_stream(FILE *f, const km_character *c, const rig_plan *p) {
  const km_mesh *m = &c->mesh;
  const km_skeleton *sk = &c->skeleton;
  size_t n = m->n_vertices;
  const int8_t *band = p->band;
  const int *bone_ok = p->bone_ok;
  static const char *const handle_joints[5] = {"Head", "HandLeft", "HandRight", "FootLeft",
                                               "FootRight"};
  fprintf(f,
          "{\"format\":\"kinemesh-rig\",\"version\":1,\"units\":\"m\",\"vertices\":%zu,"
          "\"skeleton\":\"kinect1\",\n\"joints\":[",
          n);
  for (size_t j = 0; j < sk->n_joints; ++j) {
    fputs(j ? ",\n{\"name\":" : "\n{\"name\":", f);
    write_json_string(f, sk->names[j]);
    fprintf(f, ",\"parent\":%d,\"rest\":[%.17g,%.17g,%.17g]}", (int)sk->parents[j], sk->rest[3 * j],
            sk->rest[3 * j + 1], sk->rest[3 * j + 2]);
  }
  fprintf(f, "],\n\"skin\":{\"influences\":%d,\"joints\":[", KM_SKIN_INFLUENCES);
  for (size_t i = 0; i < n * KM_SKIN_INFLUENCES; ++i)
    fprintf(f, i ? ",%d" : "%d", (int)c->skin.joints[i]);
  fputs("],\n\"weights\":[", f);
  for (size_t i = 0; i < n * KM_SKIN_INFLUENCES; ++i) {
    double w = c->skin.weights[i];
    if (w == 0)
      fputs(i ? ",0" : "0", f);
    else
      fprintf(f, i ? ",%.7g" : "%.7g", w);
  }
  fputs("]},\n\"landmarks\":", f);
  km__landmarks_write_json(f, c->landmarks, KM_CHARACTER_LANDMARKS);
  fputs(",\n\"handles\":[", f);
  if (p->bust) { /* the head turns with the neck about the root, the base stays */
    write_handle(f, "", "head", p->end_list[0], p->n_end[0]);
    write_handle(f, ",", "base", p->base_list, p->n_base);
    /* A bust's neck turns at most 45 degrees from where the chest carries its first
     * direction: a performer bending over would fold the head into the chest. Its filter is
     * One Euro (Casiez et al.; min cutoff 1 Hz, beta 0.5), not the other rigs' Holt (smoothing
     * and trend 0.5, below): a bust's head swings far from its pivot (the bunny's ears), and
     * with Holt the Kinect neck's jitter moved it more in a frame than the performer's joints
     * moved. The other rigs keep Holt: with One Euro their handles lagged their joints (the
     * demo's kung-fu character 69 mm from its skinned self at worst, test_puppet_cli's limit
     * 50). bench motion B, the Kinect takes,
     * Holt -> One Euro, largest one-frame jump (% of the diagonal): bunny 5.1/9.3/4.3 ->
     * 2.6/3.7/2.2, FAUST's top 30 % 4.0/6.9/3.7 -> 1.7/2.5/2.2, its head 7.6/16.8/8.0 ->
     * 4.5/6.1/3.9; shortest edge bunny 0.30/0.51/0.53 -> 0.47/0.67/0.58x, longest edge within
     * 0.06x or shorter; the CMU takes within 0.3 % and 0.02x. */
    fputs("],\n\"map\":[{\"handle\":\"head\",\"bone\":[\"ShoulderCenter\",\"Head\"]}],"
          "\n\"relative_to\":\"HipCenter\",\"swing_limit\":45,",
          f);
    /* A resting body's head lies on or near the ground: without the floor the performer's
     * moves turned the curled cat's (cat-07) into it, 8.3 % of the diagonal under the rest
     * floor at precog_Seq1_1's frame 196, 42 frames more than 0.5 % under; held above it */
    if (p->resting) fputs("\"floor\":true,", f);
    /* and its head turns about its own neck, lying as it is: a performer's nod (about their
     * left-right axis) nods it, not rolls it about its neck (local_turn in kinemesh.h) */
    if (p->resting) fputs("\"local_turn\":true,", f);
    fputs("\"filter\":{\"kind\":\"one_euro\",\"min_cutoff\":1.0,\"beta\":0.5}}\n", f);
    return;
  }
  int n_ends = p->upper ? 3 : 5; /* an upper body's feet are folded into its base */
  for (int h = 0; h < n_ends; ++h) {
    if (p->end_list[h]) {
      write_handle(f, h ? "," : "", handle_names[h], p->end_list[h], p->n_end[h]);
      continue;
    }
    fprintf(f, "%s\n{\"name\":\"%s\",\"vertex\":%ld,\"radius\":%.6g}", h ? "," : "",
            handle_names[h], p->handle_vertex[h], p->radius);
  }
  for (int b = 0; b < N_BONE_HANDLES; ++b) {
    if (!bone_ok[b]) continue;
    fprintf(f, ",\n{\"name\":\"%s\",\"vertices\":[", bone_handle_name[b]);
    /* At most BAND_MAX vertices, every k-th of the band: a rigid handle needs a few points
     * spread over the band, and the per-frame solve costs per handle vertex. */
    size_t cnt = 0, kept = 0;
    for (size_t v = 0; v < n; ++v)
      cnt += band[v] == b;
    size_t every = (cnt + BAND_MAX - 1) / BAND_MAX;
    bool first = true;
    for (size_t v = 0, i = 0; v < n; ++v)
      if (band[v] == b && i++ % every == 0 && kept++ < BAND_MAX) {
        fprintf(f, first ? "%zu" : ",%zu", v);
        first = false;
      }
    fputs("]}", f);
  }
  /* Every handle moves rigidly with a bone (the end handles with the bone ending at their
   * joint), posed on the character's own skeleton ("joints" above); see km_rig_parse. */
  /* Hands and feet turn about the elbow / knee with the elbow -> hand / knee -> foot line:
   * Kinect's wrist -> hand and ankle -> foot bones are too short to steer by, and a tracker
   * that sends a hand alone (OSC) still moves the hand. */
  static const char *const handle_bone_start[5] = {"ShoulderCenter", "ElbowLeft", "ElbowRight",
                                                   "KneeLeft", "KneeRight"};
  if (p->upper) write_handle(f, ",", "base", p->base_list, p->n_base);
  fputs("],\n\"map\":[", f);
  for (int h = 0; h < n_ends; ++h)
    fprintf(f, "%s\n{\"handle\":\"%s\",\"bone\":[\"%s\",\"%s\"]}", h ? "," : "", handle_names[h],
            handle_bone_start[h], handle_joints[h]);
  for (int b = 0; b < N_BONE_HANDLES; ++b)
    if (bone_ok[b])
      fprintf(f, ",\n{\"handle\":\"%s\",\"bone\":[\"%s\",\"%s\"]}", bone_handle_name[b],
              bone_handle_joints[b][0], bone_handle_joints[b][1]);
  /* The whole mesh follows the root rigidly (translation and heading) and the handles take
   * the motion relative to it: with free-standing handles only, a performer who turns round
   * (the demo's kung-fu spin) turned the limbs but not the torso, which no handle holds, and
   * twisted the legs and neck into ropes. */
  /* An upper body too (a VR avatar): its base, which no map entry moves, follows the root
   * rigidly, and the avatar turns whole with the performer. Held still in the world instead (as
   * a bust's), the base kept the chest from turning and a performer's turn twisted the torso
   * (bench motion B, a T-posed character cut at the waist: longest edge on cmu_131_01 /
   * cmu_131_03 1.83 / 2.10 -> 1.51 / 1.51x, folded triangles 84 / 278 -> 35 / 25). */
  fputs("],\n\"root_motion\":\"rigid\",\"relative_to\":\"HipCenter\",\"aim\":true,", f);
  /* No vertex below the rest floor (km_retarget_options.floor): a foot whose ankle the
   * performer's sinks below its rest height, or whose toes a tracker's ankle -> foot line tips
   * down, stops at the ground instead of going through it. bench motion, frames with a vertex
   * more than 0.5 % of the diagonal under the rest floor, the table's take order, B before ->
   * after: armadillo 1/0/0/244/93, character 1/0/0/92/39, dog0 13/12/12/0/0, horse
   * 23/0/0/42/28 -> 0 on every row (T's 229/31/70/183/0 and the like too); the other columns
   * within 0.03 of l/l0 and 30 folded triangles, the jump within 0.1 % of the diagonal, no
   * time. A rig that wants feet to sink (a swimmer) says "floor": false. An upper body (no
   * feet; its base is a cut at the waist, not the ground) has none. */
  if (!p->upper) fputs("\"floor\":true,", f);
  /* A quadruped's legs do not reach where a person's arms and legs do: a performer raising an
   * arm overhead swung the horse's foreleg 150 degrees up to its nose, a thin tube stretched
   * 4.3x out of the chest (precog_Seq1_1). Its limb bones swing at most 30 degrees from where
   * their parent carries them (a leg has three, so a paw still reaches 90 degrees). bench
   * motion B, dog0, 60 -> 30 degrees with the upper-leg bands gone (bone_bands): stretch max
   * 0.95/0.71/0.89/0.91/0.84 -> 0.66/0.62/0.56/0.56/0.47; 20 degrees gained little more
   * (0.67/0.62/0.45/0.54/0.42) and stiffened the legs. */
  /* So are stubby limbs (the elephant's arms and legs, about as thick as they are long; 12
   * degrees since, below), with their upper arms and thighs at most 15 degrees ("upper_limb_limit",
   * below): a stubby arm swung as far as a person's, or brought down from the rest pose to a
   * performer's arms hanging, crushed and folded the skin between it and the body (the armpits),
   * and the big head tilted as far as the performer's hung an ear on its shoulder. bench motion B,
   * elephant, the table's take order, before -> after: stretch max 1.32/1.14/1.13/0.99/1.06 ->
   * 0.84/0.77/0.78/0.74/0.75, folded triangles 590/596/578/397/372 -> 4/4/6/4/2; one-frame
   * jump within 0.4 % (the CMU takes 1.9/2.2 -> 1.8/2.2 %). With "swing_limit" 30 alone:
   * stretch 0.93/0.91/0.93/0.88/0.88, folds 30/16/36/25/17. */
  /* An upright body with stubby limbs, 12 degrees: a bend of a limb as thick as it is long
   * squeezes the inside of the bend over about one radius of free skin, |l/l0 - 1| near the
   * bend angle in radians, so 30 degrees a bone crushed the inner elbow and the armpit to 0.36x
   * of their rest length. bench motion B, elephant, the table's take order, 30 -> 12: stretch
   * max 0.545/0.562/0.597/0.636/0.626 -> 0.395/0.378/0.453/0.471/0.449 (both CMU rows then meet
   * every target), longest edge 1.44/1.45/1.43/1.42/1.41 -> 1.33/1.32/1.31/1.35/1.34x, no fold,
   * one-frame jump within 0.1 %. The price: smaller gestures (precog_Seq1_1 frame 150, a kick,
   * lifts the foot less); 15 degrees left cmu_131_01 at 0.502. */
  if (!p->upright)
    fputs("\"swing_limit\":30,", f);
  else if (p->stubby)
    fputs("\"swing_limit\":12,", f);
  /* A quadruped's upper arm and thigh, inside the trunk, swing at most 5 degrees, and its elbow and
   * knee bend at most 20 (below): the leg turns below the trunk about the elbow or knee, and its
   * shoulder and hip skin, which no band holds, is not dragged by a swinging humerus or femur.
   * bench motion B (own rates), the table's take order, stretch max before -> after: dog0
   * 0.59/0.60/0.56/0.52/0.45 -> 0.38/0.40/0.36/0.35/0.34, horse 0.90/0.90/0.90/0.73/0.67 ->
   * 0.51/0.65/0.52/0.30/0.27; no fold before or after; one-frame jump on precog_Seq3_2 dog0
   * 14.7 -> 8.9 %, horse 17.4 -> 10.1 %, the other rows within 0.7 % (the horse's cmu_131_01
   * 2.8 -> 2.7 % with clamp_swing's fade at the antipode, 3.6 % without). 10 and 30 degrees
   * (swing_limit's): dog0 0.42/0.45/0.40/0.35/0.36, horse 0.62/0.71/0.62/0.41/0.35. Moving the
   * forearm and shin bands (0.4-0.7, 0.5-0.8, 0.2-0.6) or the chest band's end (0.75, 0.9)
   * changed the stretch by 0.04 at most. */
  if (!p->upright)
    fputs("\"upper_limb_limit\":5,", f);
  else if (p->stubby)
    fputs("\"upper_limb_limit\":15,", f);
  /* The shoulder and hip bones of such a body (ShoulderCenter -> Shoulder*, HipCenter -> Hip*)
   * turn at most 5 degrees: they turned with the performer's shoulders and hips (a shrug, a
   * lean, a hip roll) up to swing_limit's 30 and carried the whole leg with them about the
   * trunk's middle, stretching the free skin between the chest band and the forearm ring (the
   * horse on precog_Seq1_1 frame 54: the foreleg 3 cm forward, 1.505x above its ring). bench
   * motion B, the table's take order, stretch max before -> after: horse
   * 0.505/0.640/0.504/0.297/0.272 -> 0.301/0.264/0.300/0.287/0.272 (longest edge 1.64x ->
   * 1.30x), dog0 0.377/0.401/0.356/0.347/0.335 -> 0.381/0.282/0.352/0.346/0.336 (1.40x -> 1.29x),
   * elephant 0.776/0.772/0.820/0.759/0.779 -> 0.588/0.554/0.594/0.608/0.599 with no fold
   * (2/2/14/4/2 before; longest 1.75x -> 1.52x); the horse's Kinect jumps 16.2/10.1 -> 12.6/7.3
   * %. The elephant with its upper_limb_limit, 15, instead: 0.653-0.760, folds 0-2; 1 degree:
   * no better than 5. Upright bodies too, since stop 47: a Kinect's shoulder joints ride up and
   * in as an arm rises or crosses the body, and the whole arm went with them, pulling the skin
   * over the shoulder into a tent (FAUST's scans, bench motion B, longest edge, the table's take
   * order: tr_reg_000 2.50/2.93/2.85/2.16/2.07 -> 2.50/2.76/2.43/2.11/1.98, tr_reg_025
   * 2.86/2.71/2.60/2.31/2.28 -> 2.64/2.46/2.37/2.24/2.15, tr_reg_010 2.58/2.38/2.30/2.21/2.10 ->
   * 2.53/2.41/2.14/2.15/2.03; folded triangles mostly fewer, tr_reg_000 on precog_Seq3_2 167 ->
   * 126, the armadillo on precog_Seq2_1 / Seq3_2 1033 / 1003 -> 882 / 810, the character's on
   * precog_Seq3_2 355 -> 279; the armadillo's and the character's longest edge within 0.01; 10
   * degrees gained about half as much). The price is the performer's shrug, which a Kinect
   * hardly tells from that ride. */
  fputs("\"girdle_limit\":5,", f);
  /* No elbow or knee bends much past 150 degrees; a tracker's that does has lost the forearm
   * or shin in front of the body (precog_Seq1_1: the left elbow "bent" 163-175 degrees for
   * frames on end, the wrist on the shoulder), and the character's forearm folded into its
   * upper arm. bench motion B, character, Kinect takes: folded triangles 125/137/349 ->
   * 81/127/329; the CMU takes, clean optical capture, never reach the limit (unchanged). */
  fputs(p->upright ? "\"bend_limit\":150," : "\"bend_limit\":20,", f);
  /* An animal turns its long body about one turn a second at most (a reining horse's spin); at
   * a performer's spin (440 deg/s in cmu_131_03, 600 shown at most) the horse's head, half its
   * length from the middle of the spine it turns about, swept 3.4 % of the diagonal in a frame
   * at 120 fps. bench motion B, largest one-frame jump, before -> after, the table's take
   * order: horse 12.3/16.2/10.1/2.7/3.4 -> 11.4/16.2/10.1/2.7/2.9 %, dog0
   * 10.3/14.3/8.9/2.4/2.9 -> 9.8/14.3/8.9/2.4/2.4 %; stretch and folds unchanged, frames under
   * the floor within 2. At 240 deg/s the horse's stretch on the CMU takes grew (0.30/0.27 ->
   * 0.34/0.29). */
  if (!p->upright) fputs("\"max_turn\":360,", f);
  fputs("\"filter\":{\"smoothing\":0.5,\"trend\":0.5}}\n", f);
}

static bool json_int(const cJSON *o, double lo, double hi, long *out) {
  int64_t v;
  if (!cJSON_IsNumber(o) || !km__whole_number(o->valuedouble, lo, hi, &v)) return false;
  *out = (long)v;
  return true;
}

/* The landmark array of a sidecar or landmark file (km__landmarks_parse). */
static km_status landmarks_from_json(const char *path, const cJSON *arr, size_t n_vertices,
                                     km_landmark *out, size_t capacity, size_t *n, km_error *err) {
  *n = 0;
  size_t cnt = (size_t)cJSON_GetArraySize(arr);
  if (cnt > capacity)
    return km__fail(err, KM_ERR_PARSE, "%s: %zu landmarks, at most %zu are supported", path, cnt,
                    capacity);
  size_t i = 0;
  const cJSON *it;
  cJSON_ArrayForEach(it, arr) {
    const cJSON *nm = cJSON_GetObjectItemCaseSensitive(it, "name");
    const cJSON *mr = cJSON_GetObjectItemCaseSensitive(it, "mirror");
    long v;
    if (!cJSON_IsString(nm) || strlen(nm->valuestring) >= sizeof out[i].name)
      return km__fail(err, KM_ERR_PARSE,
                      "%s: landmark %zu: \"name\" must be a string of at most %zu bytes", path, i,
                      sizeof out[i].name - 1);
    if (mr && (!cJSON_IsString(mr) || strlen(mr->valuestring) >= sizeof out[i].mirror))
      return km__fail(err, KM_ERR_PARSE,
                      "%s: landmark %zu (%s): \"mirror\" must be a string of at most %zu bytes",
                      path, i, nm->valuestring, sizeof out[i].mirror - 1);
    double hi = n_vertices > 0 ? (double)n_vertices - 1 : (double)INT32_MAX;
    if (!json_int(cJSON_GetObjectItemCaseSensitive(it, "vertex"), 0, hi, &v))
      return km__fail(err, KM_ERR_PARSE,
                      "%s: landmark %zu (%s): \"vertex\" must be an integer in 0..%.0f", path, i,
                      nm->valuestring, hi);
    memset(&out[i], 0, sizeof out[i]);
    snprintf(out[i].name, sizeof out[i].name, "%s", nm->valuestring);
    snprintf(out[i].mirror, sizeof out[i].mirror, "%s", mr ? mr->valuestring : nm->valuestring);
    out[i].vertex = (int32_t)v;
    for (size_t a = 0; a < i; ++a)
      if (strcmp(out[a].name, out[i].name) == 0)
        return km__fail(err, KM_ERR_PARSE, "%s: landmark name \"%s\" appears twice", path,
                        out[i].name);
    ++i;
  }
  *n = i;
  return KM_OK;
}

km_status km__landmarks_parse(const char *path, const char *data, size_t size, size_t n_vertices,
                              km_landmark *out, size_t capacity, size_t *n, km_error *err) {
  *n = 0;
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(data, size, &end, 0);
  if (!root) {
    size_t at = end && end >= data ? (size_t)(end - data) : 0;
    return km__fail(err, KM_ERR_PARSE, "%s: invalid JSON near byte %zu", path, at);
  }
  const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, "landmarks");
  km_status s =
      cJSON_IsArray(arr)
          ? landmarks_from_json(path, arr, n_vertices, out, capacity, n, err)
          : km__fail(err, KM_ERR_PARSE, "%s: expected an object with a \"landmarks\" array", path);
  cJSON_Delete(root);
  return s;
}

/* The skin arrays hold 8 numbers per vertex: as cJSON items (64 bytes each) a 1M-vertex rig
 * would take over 500 MB. They are located with a small structural scan (strings and nesting
 * only), read with strtod, and blanked to [] before cJSON parses the rest. Anything the scan
 * does not recognise falls back to the plain cJSON path. */
static size_t js_ws(const char *s, size_t i, size_t n) {
  while (i < n && (s[i] == ' ' || s[i] == '\t' || s[i] == '\n' || s[i] == '\r'))
    ++i;
  return i;
}

static size_t js_string_end(const char *s, size_t i, size_t n) {
  for (++i; i < n; ++i) {
    if (s[i] == '\\')
      ++i;
    else if (s[i] == '"')
      return i + 1;
  }
  return SIZE_MAX;
}

static size_t js_value_end(const char *s, size_t i, size_t n) {
  if (i >= n) return SIZE_MAX;
  if (s[i] == '"') return js_string_end(s, i, n);
  if (s[i] == '{' || s[i] == '[') {
    int depth = 0;
    while (i < n) {
      char c = s[i];
      if (c == '"') {
        i = js_string_end(s, i, n);
        if (i == SIZE_MAX) return SIZE_MAX;
        continue;
      }
      if (c == '{' || c == '[') ++depth;
      if (c == '}' || c == ']') {
        if (--depth == 0) return i + 1;
      }
      ++i;
    }
    return SIZE_MAX;
  }
  while (i < n && !strchr(",}] \t\r\n", s[i]))
    ++i;
  return i;
}

/* Span [*vb, *ve) of member `key` of the object starting at s[obj] == '{'. */
static bool js_member(const char *s, size_t obj, size_t n, const char *key, size_t *vb,
                      size_t *ve) {
  if (obj >= n || s[obj] != '{') return false;
  size_t i = obj + 1, klen = strlen(key);
  for (;;) {
    i = js_ws(s, i, n);
    if (i >= n || s[i] != '"') return false;
    size_t ke = js_string_end(s, i, n);
    if (ke == SIZE_MAX) return false;
    bool match = ke - i - 2 == klen && !memcmp(s + i + 1, key, klen);
    i = js_ws(s, ke, n);
    if (i >= n || s[i] != ':') return false;
    i = js_ws(s, i + 1, n);
    size_t e = js_value_end(s, i, n);
    if (e == SIZE_MAX) return false;
    if (match) {
      *vb = i;
      *ve = e;
      return true;
    }
    i = js_ws(s, e, n);
    if (i >= n || s[i] != ',') return false;
    ++i;
  }
}

/* Reads the number array at [b, e) (s NUL-terminated past e) into out[cap]. Returns the count,
 * or SIZE_MAX with *bad the byte offset of a malformed entry or the entry past cap. */
static size_t js_numbers(const char *s, size_t b, size_t e, double *out, size_t cap, size_t *bad) {
  size_t i = js_ws(s, b + 1, e), n = 0;
  if (i < e && s[i] == ']') return 0;
  for (;;) {
    char *end = NULL;
    double v = strtod(s + i, &end);
    if (end == s + i || (size_t)(end - s) > e || n >= cap) {
      *bad = i;
      return SIZE_MAX;
    }
    out[n++] = v;
    i = js_ws(s, (size_t)(end - s), e);
    if (i < e && s[i] == ']') return n;
    if (i >= e || s[i] != ',') {
      *bad = i;
      return SIZE_MAX;
    }
    i = js_ws(s, i + 1, e);
  }
}

typedef struct fast_skin {
  bool found;
  double *joints, *weights; /* as read, validated later */
  size_t nj, nw;            /* counts, SIZE_MAX when malformed */
  size_t bad_j, bad_w;      /* byte offsets of the malformed entries */
} fast_skin;

static bool fast_skin_extract(char *data, size_t size, size_t cap, fast_skin *fs) {
  memset(fs, 0, sizeof *fs);
  size_t root = js_ws(data, 0, size), sb, se, jb, je, wb, we;
  if (!js_member(data, root, size, "skin", &sb, &se)) return true;
  if (!js_member(data, sb, se, "joints", &jb, &je) || data[jb] != '[') return true;
  if (!js_member(data, sb, se, "weights", &wb, &we) || data[wb] != '[') return true;
  fs->joints = km__malloc(cap ? cap : 1, sizeof *fs->joints);
  fs->weights = km__malloc(cap ? cap : 1, sizeof *fs->weights);
  if (!fs->joints || !fs->weights) {
    free(fs->joints);
    free(fs->weights);
    return false;
  }
  fs->nj = js_numbers(data, jb, je, fs->joints, cap, &fs->bad_j);
  fs->nw = js_numbers(data, wb, we, fs->weights, cap, &fs->bad_w);
  /* Blank the arrays (same length, so byte offsets of later errors stay right). */
  memset(data + jb + 1, ' ', je - jb - 2);
  memset(data + wb + 1, ' ', we - wb - 2);
  fs->found = true;
  return true;
}

km_status km_character_read_rig(const char *path, size_t n_vertices, km_character *out,
                                km_error *err) {
  if (!path || !out) return km__fail(err, KM_ERR_INVALID, "read rig: NULL argument");
  char *data = NULL;
  size_t size = 0;
  km_status st = km__read_file(path, &data, &size, err);
  if (st != KM_OK) return st;
  fast_skin fs;
  size_t cap = n_vertices <= SIZE_MAX / KM_SKIN_INFLUENCES ? n_vertices * KM_SKIN_INFLUENCES : 0;
  if (!fast_skin_extract(data, size, cap, &fs)) {
    free(data);
    return km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
  }
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(data, size, &end, 0);
  if (!root) {
    size_t at = end && end >= data ? (size_t)(end - data) : 0;
    free(data);
    free(fs.joints);
    free(fs.weights);
    return km__fail(err, KM_ERR_PARSE, "%s: invalid JSON near byte %zu", path, at);
  }
  free(data);
  km_skeleton sk = {0};
  km_skin skin = {0};
  km_landmark lm[KM_CHARACTER_LANDMARKS];
  memset(lm, 0, sizeof lm);
#define FAIL(...)                                                                                  \
  do {                                                                                             \
    st = km__fail(err, KM_ERR_PARSE, __VA_ARGS__);                                                 \
    goto done;                                                                                     \
  } while (0)
  const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(root, "format");
  if (!cJSON_IsString(fmt) || strcmp(fmt->valuestring, "kinemesh-rig"))
    FAIL("%s: \"format\" is not \"kinemesh-rig\"", path);
  long ver = 0, nv = 0;
  if (!json_int(cJSON_GetObjectItemCaseSensitive(root, "version"), 1, 1e9, &ver) || ver != 1)
    FAIL("%s: unsupported \"version\" (expected 1)", path);
  if (!json_int(cJSON_GetObjectItemCaseSensitive(root, "vertices"), 0, 2147483647.0, &nv))
    FAIL("%s: \"vertices\" is missing or not a non-negative integer", path);
  if ((size_t)nv != n_vertices) {
    st = km__fail(err, KM_ERR_STALE, "%s: rig is for %ld vertices, the mesh has %zu", path, nv,
                  n_vertices);
    goto done;
  }
  const cJSON *joints = cJSON_GetObjectItemCaseSensitive(root, "joints");
  int nj = cJSON_GetArraySize(joints);
  if (!cJSON_IsArray(joints) || nj < 1 || nj > 1000)
    FAIL("%s: \"joints\" must be an array of 1..1000 joints", path);
  sk.n_joints = (size_t)nj;
  sk.names = km__calloc((size_t)nj, sizeof *sk.names);
  sk.parents = km__malloc((size_t)nj, sizeof *sk.parents);
  sk.rest = km__malloc((size_t)nj * 3, sizeof *sk.rest);
  if (!sk.names || !sk.parents || !sk.rest) {
    st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
    goto done;
  }
  int j = 0;
  const cJSON *it;
  cJSON_ArrayForEach(it, joints) {
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(it, "name");
    const cJSON *rest = cJSON_GetObjectItemCaseSensitive(it, "rest");
    long par;
    if (!cJSON_IsString(name)) FAIL("%s: joint %d has no \"name\" string", path, j);
    if (!json_int(cJSON_GetObjectItemCaseSensitive(it, "parent"), -1, j - 1, &par))
      FAIL("%s: joint %d (%s): \"parent\" must be -1 or an earlier joint", path, j,
           name->valuestring);
    if (!cJSON_IsArray(rest) || cJSON_GetArraySize(rest) != 3)
      FAIL("%s: joint %d (%s): \"rest\" must be [x,y,z]", path, j, name->valuestring);
    for (int k = 0; k < 3; ++k) {
      const cJSON *x = cJSON_GetArrayItem(rest, k);
      if (!cJSON_IsNumber(x) || !isfinite(x->valuedouble))
        FAIL("%s: joint %d (%s): \"rest\" must hold 3 finite numbers", path, j, name->valuestring);
      sk.rest[3 * j + k] = x->valuedouble;
    }
    sk.names[j] = strdup(name->valuestring);
    if (!sk.names[j]) {
      st = km__fail(err, KM_ERR_NOMEM, "%s: out of memory", path);
      goto done;
    }
    sk.parents[j] = (int32_t)par;
    ++j;
  }
  const cJSON *sn = cJSON_GetObjectItemCaseSensitive(root, "skin");
  const cJSON *sj = cJSON_GetObjectItemCaseSensitive(sn, "joints");
  const cJSON *sw = cJSON_GetObjectItemCaseSensitive(sn, "weights");
  long infl = 0;
  if (!json_int(cJSON_GetObjectItemCaseSensitive(sn, "influences"), 1, 64, &infl) ||
      infl != KM_SKIN_INFLUENCES)
    FAIL("%s: \"skin\".\"influences\" must be %d", path, KM_SKIN_INFLUENCES);
  size_t ne = n_vertices * KM_SKIN_INFLUENCES;
  if (fs.found) {
    if (fs.nj == SIZE_MAX)
      FAIL("%s: byte %zu: \"skin\".\"joints\" must be %zu numbers (vertices x %d)", path, fs.bad_j,
           ne, KM_SKIN_INFLUENCES);
    if (fs.nw == SIZE_MAX)
      FAIL("%s: byte %zu: \"skin\".\"weights\" must be %zu numbers (vertices x %d)", path, fs.bad_w,
           ne, KM_SKIN_INFLUENCES);
    if (fs.nj != ne || fs.nw != ne)
      FAIL("%s: \"skin\" has %zu joints and %zu weights, expected %zu (vertices x %d)", path, fs.nj,
           fs.nw, ne, KM_SKIN_INFLUENCES);
  } else {
    if (!cJSON_IsArray(sj) || (size_t)cJSON_GetArraySize(sj) != ne)
      FAIL("%s: \"skin\".\"joints\" must have %zu entries (vertices x %d)", path, ne,
           KM_SKIN_INFLUENCES);
    if (!cJSON_IsArray(sw) || (size_t)cJSON_GetArraySize(sw) != ne)
      FAIL("%s: \"skin\".\"weights\" must have %zu entries (vertices x %d)", path, ne,
           KM_SKIN_INFLUENCES);
  }
  if ((st = km__skin_alloc(&skin, n_vertices, err)) != KM_OK) goto done;
  if (fs.found) {
    for (size_t i = 0; i < ne; ++i) {
      double v = fs.joints[i], w = fs.weights[i];
      if (!(v >= -1 && v <= nj - 1) || v != floor(v))
        FAIL("%s: \"skin\".\"joints\"[%zu] must be -1 or a joint index < %d", path, i, nj);
      if (!(w >= 0 && w <= 1.0001))
        FAIL("%s: \"skin\".\"weights\"[%zu] must be a number in [0,1]", path, i);
      skin.joints[i] = (int32_t)v;
      skin.weights[i] = w;
    }
  } else {
    size_t i = 0;
    cJSON_ArrayForEach(it, sj) {
      long v;
      if (!json_int(it, -1, nj - 1, &v))
        FAIL("%s: \"skin\".\"joints\"[%zu] must be -1 or a joint index < %d", path, i, nj);
      skin.joints[i++] = (int32_t)v;
    }
    i = 0;
    cJSON_ArrayForEach(it, sw) {
      if (!cJSON_IsNumber(it) || !(it->valuedouble >= 0 && it->valuedouble <= 1.0001))
        FAIL("%s: \"skin\".\"weights\"[%zu] must be a number in [0,1]", path, i);
      skin.weights[i++] = it->valuedouble;
    }
  }
  for (size_t v = 0; v < n_vertices; ++v) {
    double sum = 0;
    for (int q = 0; q < KM_SKIN_INFLUENCES; ++q) {
      size_t e = v * KM_SKIN_INFLUENCES + (size_t)q;
      if (skin.joints[e] < 0) skin.weights[e] = 0;
      sum += skin.weights[e];
    }
    /* sum 0: a vertex with no influence, which stays where it is (rig writes one for a vertex
     * in no face and for a piece lying on the floor) */
    if (fabs(sum - 1) > 1e-4 && sum != 0)
      FAIL("%s: skin weights of vertex %zu sum to %g, not 1 (or 0 with every joint -1: no "
           "influence, the vertex stays)",
           path, v, sum);
    for (int q = 0; sum == 0 && q < KM_SKIN_INFLUENCES; ++q)
      skin.joints[v * KM_SKIN_INFLUENCES + (size_t)q] = -1;
  }
  const cJSON *lms = cJSON_GetObjectItemCaseSensitive(root, "landmarks");
  if (!cJSON_IsArray(lms) || cJSON_GetArraySize(lms) != KM_CHARACTER_LANDMARKS)
    FAIL("%s: \"landmarks\" must be an array of %d landmarks", path, KM_CHARACTER_LANDMARKS);
  size_t nl = 0;
  if ((st = landmarks_from_json(path, lms, n_vertices, lm, KM_CHARACTER_LANDMARKS, &nl, err)))
    goto done;
#undef FAIL
  free(fs.joints);
  free(fs.weights);
  /* Overwritten, not freed: out may hold only a mesh with the rest uninitialised. */
  out->skeleton = sk;
  out->skin = skin;
  memcpy(out->landmarks, lm, sizeof lm);
  cJSON_Delete(root);
  return KM_OK;
done:
  free(fs.joints);
  free(fs.weights);
  km_skeleton_free(&sk);
  km_skin_free(&skin);
  cJSON_Delete(root);
  return st;
}
