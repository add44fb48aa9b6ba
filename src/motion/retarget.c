/* Joint motion to handle targets (paper eq. 5-7), see km_retarget_create. */
#include "motion/motion.h"

#include "math/math.h"
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Bone speed limit (limit_bone): m/s (of performer) a lagging bone's end catches up beyond its
 * joint's own motion; the fraction of its usual length a bone may measure and still turn
 * freely; the fastest turn of a bone, deg/s. */
#define KM_BONE_CATCHUP 1.0
#define KM_BONE_LEN_TOL 0.8
#define KM_BONE_MAX_TURN 1200.0
/* The fastest heading turn shown under rigid root motion, deg/s, when the rig sets no
 * "max_turn" (heading_push). */
#define KM_HEADING_MAX_TURN 600.0

struct km_retarget {
  size_t n_handles, n_joints, n_maps, n_hv;
  km_rig_map *maps;  /* sorted by handle */
  size_t *map_start; /* n_handles+1: maps of handle h are [map_start[h], map_start[h+1]) */
  size_t *hv_start;  /* n_handles+1, into hv_rest */
  double *hv_rest;   /* rest positions of the handle vertices, handle by handle */
  double *centroid;  /* n_handles*3 */
  double *disp;      /* n_handles*3, current displacement */
  double *ref;       /* n_joints*3, first valid position, NaN until seen */
  bool kinect1;
  bool auto_scale;
  double scale; /* NaN while auto and unknown */
  double mesh_height;
  double *floor_dy; /* n_handles: lowest allowed y displacement; NULL: no floor */
  /* rigid root motion */
  bool rigid;
  int32_t root, hl, hr; /* joint indices; hl/hr -1: no heading */
  double pivot[3];
  double R[9], t[3];   /* of the last push */
  double root_s;       /* the root translation's scale (root_scale); NaN until the first push
                          with a scale */
  double cos_h, sin_h; /* the body's heading change of the last push (the filter's: the frame
                          the handles' motion is measured in) */
  double cos_s, sin_s; /* the heading shown (the mesh turned by R) */
  bool have_heading;   /* a heading was measured since create / reset */
  double h_phi;        /* the heading shown (radians, unwrapped) */
  double h_meas;       /* the last accepted measurement (unwrapped) */
  double h_filt;       /* the One Euro filter's value of the measurements */
  double h_speed;      /* its filtered angular speed, rad/s */
  int h_rejected;      /* measurements rejected in a row (swaps, glitches) */
  bool h_refit;        /* the heading shown is catching up with a measurement taken after
                          rejections (a re-fit): at most KM_HEADING_REFIT_TURN */
  double h_max_turn;   /* rad/s: the fastest turn shown (rig "max_turn", else
                          KM_HEADING_MAX_TURN) */
  double fps;          /* pushes per second */
  /* rotating handles */
  int32_t *rot_joint, *rot_parent; /* n_handles; -1: translation only; NULL: none rotates */
  int32_t *par;                    /* n_joints parents (-1 roots), for rotating handles */
  double *rot;                     /* n_handles*9 row-major, of the last valid frame */
  /* joint rotations given with the frames (km_retarget_push_rotations, issue 15) */
  double *qref;       /* n_joints*9: each joint's first valid given rotation (NaN: none yet) */
  const double *jrot; /* n_joints*9 of the push under way; NULL: positions only */
  /* bone handles (issue 12) */
  int32_t *bone_from;  /* n_handles: the bone's start joint for bone handles, -1 others; NULL:
                          no bone handle */
  int32_t *bone_rel;   /* n_handles: the bone entry's relative_to (1 + joint, 0: none) */
  double *jrest;       /* n_joints*3 character joints at rest (NaN unknown); NULL: none */
  double *Rb;          /* n_joints*9 bone rotations (of the bone ending at the joint) */
  double *C;           /* n_joints*3 posed character joints */
  int32_t *only_child; /* n_joints: the joint's one child, -1 for none, -2 for several */
  double *jfill;       /* n_joints*3: this push's joints with the untracked ones filled */
  bool *seen;          /* n_joints: the tracker has sent the joint since create / reset */
  double floor_y;      /* the rest floor (lowest rest y) */
  bool aim;            /* limb bones aim along the performer's (rig "aim": true) */
  bool upright;        /* the character skeleton stands upright (km__body_upright) */
  double swing_limit;  /* radians, a bone's largest swing from its parent-carried rest (aimed
                          limb bones) or first (the others) direction (rig "swing_limit");
                          0: none */
  double bend_limit;   /* radians, the largest bend of a kinect1 elbow or knee (rig
                          "bend_limit"); 0: none */
  double upper_limit;  /* radians, the largest swing of a kinect1 upper arm or thigh (rig
                          "upper_limb_limit"); 0: swing_limit */
  double girdle_limit; /* radians, the largest turn of a kinect1 shoulder or hip bone (rig
                          "girdle_limit"); 0: swing_limit */
  /* bone speed limit (see limit_bone) */
  double bone_catchup; /* metres (of performer) per push a bone's end may turn beyond its
                          joint's own step; < 0: off */
  double *bvec;        /* n_joints*3: the performer's bone ending at the joint, last push (in
                          the root's heading frame under rigid root motion) */
  double *blen;        /* n_joints: its running length */
  bool *bhave;         /* n_joints: bvec and blen hold a valid bone */
  bool *blag;          /* n_joints: the bone was held back by the limit in the last push */
  /* snap easing (issue 12): no handle vertex moves more than max_step per push */
  double max_step;            /* metres per push; 0: off */
  double *prev;               /* n_handles*12: displacement (3) and rotation (9) of the last push */
  double *hv_radius;          /* n_handles: largest distance of a handle vertex from its centroid */
  double root_rho;            /* under rigid root motion: the farthest corner of the rest mesh's
                                 bounding box from the vertical through the pivot */
  double prev_t[3], prev_phi; /* the rigid root's translation and heading shown, last push */
  bool have_prev;
  size_t eased; /* pushes whose motion was eased */
  /* Joints no map entry reaches (see held_joints); NULL: none. */
  bool *held;      /* n_joints: the bone ending here is carried by its parent's */
  bool local_turn; /* rig "local_turn": bone handles turn about the character's bone */
  bool neck_held;  /* root_fixed with an anchor: held joints beside an entry's bone (a bust's
                      shoulders) turn with it in km_retarget_joints */
  bool root_fixed; /* every entry is relative to the root, which does not move rigidly: the
                      posed joints (km_retarget_joints) stay where the handles see them */
};

static int cmp_map(const void *a, const void *b) {
  const km_rig_map *x = a, *y = b;
  return (x->handle > y->handle) - (x->handle < y->handle);
}

void km_retarget_free(km_retarget **r) {
  if (!r || !*r) return;
  km_retarget *t = *r;
  free(t->maps);
  free(t->map_start);
  free(t->hv_start);
  free(t->hv_rest);
  free(t->centroid);
  free(t->disp);
  free(t->ref);
  free(t->floor_dy);
  free(t->rot_joint);
  free(t->rot_parent);
  free(t->par);
  free(t->rot);
  free(t->qref);
  free(t->bone_from);
  free(t->bone_rel);
  free(t->jrest);
  free(t->Rb);
  free(t->C);
  free(t->only_child);
  free(t->jfill);
  free(t->seen);
  free(t->bvec);
  free(t->blen);
  free(t->bhave);
  free(t->blag);
  free(t->prev);
  free(t->hv_radius);
  free(t->held);
  free(t);
  *r = NULL;
}

void km_retarget_reset(km_retarget *r) {
  if (!r) return;
  for (size_t i = 0; i < 3 * r->n_joints; ++i)
    r->ref[i] = NAN;
  memset(r->disp, 0, 3 * r->n_handles * sizeof(double));
  if (r->seen) memset(r->seen, 0, r->n_joints * sizeof(bool));
  if (r->bhave) memset(r->bhave, 0, r->n_joints * sizeof(bool));
  if (r->blag) memset(r->blag, 0, r->n_joints * sizeof(bool));
  if (r->auto_scale) r->scale = NAN;
  memset(r->R, 0, sizeof r->R);
  r->R[0] = r->R[4] = r->R[8] = 1;
  memset(r->t, 0, sizeof r->t);
  r->root_s = NAN;
  r->cos_h = r->cos_s = 1;
  r->have_heading = false;
  r->sin_h = r->sin_s = 0;
  r->h_phi = r->h_meas = r->h_filt = r->h_speed = 0;
  r->h_rejected = 0;
  r->h_refit = false;
  r->have_prev = false;
  r->eased = 0;
  if (r->rot)
    for (size_t h = 0; h < r->n_handles; ++h) {
      double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      memcpy(r->rot + 9 * h, I, sizeof I);
    }
  if (r->qref)
    for (size_t i = 0; i < 9 * r->n_joints; ++i)
      r->qref[i] = NAN;
  if (r->Rb)
    for (size_t j = 0; j < r->n_joints; ++j) {
      double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      memcpy(r->Rb + 9 * j, I, sizeof I);
      for (int d = 0; d < 3; ++d)
        r->C[3 * j + d] = r->jrest ? r->jrest[3 * j + d] : NAN;
    }
}

static double skeleton_height(const km_retarget *r, const double *J);

const double *km_retarget_reference(const km_retarget *r) { return r->ref; }

void km_retarget_set_reference(km_retarget *r, size_t j, const double p[3]) {
  if (!r || j >= r->n_joints || !km__finite3(p)) return;
  memcpy(r->ref + 3 * j, p, 3 * sizeof(double));
  /* what was built on the old reference: the auto scale (the stature, from the head and feet
   * of the first frame: now from the reference), the root translation's scale (recomputed at
   * the next push) and the bone speed limit's memory of the performer's bones */
  if (r->auto_scale && isfinite(r->scale)) {
    double h = skeleton_height(r, r->ref);
    if (h > 1e-6) r->scale = r->mesh_height / h;
  }
  r->root_s = NAN;
  if (r->bhave) memset(r->bhave, 0, r->n_joints * sizeof(bool));
}

static double dist3(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* The joints of the character's skeleton the rig's map does not move (r->held; NULL when it
 * moves every one): neither an entry's joint nor an ancestor of one (a bust's or a resting
 * body's arms and legs, folded inside it; an upper body's legs); and, when the map holds the
 * root still (root_fixed below) and a handle is an anchor (one no entry drives: the base of a
 * bust or of a resting body, which holds the body still), every joint but those along a bone
 * entry's segment (the neck: the head turns about ShoulderCenter at rest). The posed skeleton
 * (km_retarget_joints, which `pose` and `bench motion --skin` skin) keeps a held bone as its
 * parent carries it, as the mesh keeps the body there. Driven by the take instead, `pose` on
 * cmu_131_03 walked the bunny's folded legs inside its body and bent its trunk over its base
 * with a performer's spine: longest edge 4.25x at its base, 940 of 1102 frames over 1.5x.
 * Also sets r->root_fixed: every entry relative to the root and no rigid root motion (the
 * bust's map), the posed joints then stay where the handles see them, off the root's travel. */
static km_status held_joints(km_retarget *r) {
  bool *reached = km__calloc(r->n_joints ? r->n_joints : 1, sizeof(bool));
  if (!reached) return KM_ERR_NOMEM;
  bool all_rel_root = r->n_maps > 0 && !r->rigid, anchor = false;
  for (size_t e = 0; e < r->n_maps; ++e) {
    int32_t q = r->maps[e].relative_to - 1;
    all_rel_root &= q >= 0 && r->par[q] < 0;
  }
  for (size_t h = 0; h < r->n_handles; ++h)
    anchor |= r->map_start[h] == r->map_start[h + 1];
  r->root_fixed = all_rel_root;
  r->neck_held = all_rel_root && anchor;
  for (size_t e = 0; e < r->n_maps; ++e) {
    const km_rig_map *m = &r->maps[e];
    int32_t stop = all_rel_root && anchor && m->bone_from > 0 ? m->bone_from - 1 : -1;
    for (int32_t j = m->joint; j >= 0 && j != stop && !reached[j]; j = r->par[j])
      reached[j] = true;
  }
  size_t n_held = 0;
  for (size_t j = 0; j < r->n_joints; ++j)
    n_held += !reached[j] && r->par[j] >= 0;
  if (n_held == 0) {
    free(reached);
    return KM_OK;
  }
  for (size_t j = 0; j < r->n_joints; ++j)
    reached[j] = !reached[j] && r->par[j] >= 0;
  r->held = reached;
  return KM_OK;
}

km_status km_retarget_create(const km_rig *rig, const km_mesh *rest, size_t n_joints,
                             const km_retarget_options *opt, km_retarget **out, km_error *err) {
  if (!rig || !rest || !out)
    return km__fail(err, KM_ERR_INVALID, "km_retarget_create: NULL argument");
  *out = NULL;
  km_retarget_options o = opt ? *opt : (km_retarget_options){0};
  if (!(o.scale >= 0) || !isfinite(o.scale))
    return km__fail(err, KM_ERR_INVALID, "retarget scale must be >= 0 (0: automatic), got %g",
                    o.scale);
  if (rig->skeleton == KM_RIG_KINECT1 && n_joints != KM_KINECT1_JOINTS)
    return km__fail(err, KM_ERR_INVALID,
                    "a kinect1 rig needs frames of the %d Kinect v1 joints, got %zu joints",
                    KM_KINECT1_JOINTS, n_joints);
  if (rig->n_handles == 0) return km__fail(err, KM_ERR_INVALID, "the rig has no handles");
  for (size_t e = 0; e < rig->n_maps; ++e) {
    const km_rig_map *m = &rig->maps[e];
    if (m->handle < 0 || (size_t)m->handle >= rig->n_handles || m->joint < 0 ||
        (size_t)m->joint >= n_joints || m->relative_to < 0 || (size_t)m->relative_to > n_joints)
      return km__fail(err, KM_ERR_INVALID,
                      "rig map %zu: handle %d / joint %d out of range (%zu handles, %zu joints)", e,
                      (int)m->handle, (int)m->joint, rig->n_handles, n_joints);
  }
  size_t n_hv = 0;
  for (size_t h = 0; h < rig->n_handles; ++h) {
    const km_rig_handle *rh = &rig->handles[h];
    if (rh->n_vertices == 0)
      return km__fail(err, KM_ERR_INVALID, "rig handle '%s' has no vertices", rh->name);
    for (size_t k = 0; k < rh->n_vertices; ++k)
      if (rh->vertices[k] < 0 || (size_t)rh->vertices[k] >= rest->n_vertices)
        return km__fail(err, KM_ERR_INVALID,
                        "rig handle '%s': vertex %d out of range (mesh has %zu vertices)", rh->name,
                        (int)rh->vertices[k], rest->n_vertices);
    n_hv += rh->n_vertices;
  }

  km_retarget *r = calloc(1, sizeof *r);
  if (!r) return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
  r->n_handles = rig->n_handles;
  r->n_joints = n_joints;
  r->n_maps = rig->n_maps;
  r->n_hv = n_hv;
  r->maps = km__malloc(rig->n_maps ? rig->n_maps : 1, sizeof *r->maps);
  r->map_start = km__calloc(rig->n_handles + 1, sizeof(size_t));
  r->hv_start = km__calloc(rig->n_handles + 1, sizeof(size_t));
  r->hv_rest = km__malloc(n_hv, 3 * sizeof(double));
  r->centroid = km__calloc(rig->n_handles, 3 * sizeof(double));
  r->disp = km__calloc(rig->n_handles, 3 * sizeof(double));
  r->ref = km__malloc(n_joints ? n_joints : 1, 3 * sizeof(double));
  if (!r->maps || !r->map_start || !r->hv_start || !r->hv_rest || !r->centroid || !r->disp ||
      !r->ref) {
    km_retarget_free(&r);
    return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
  }
  if (rig->n_maps) memcpy(r->maps, rig->maps, rig->n_maps * sizeof *r->maps);
  qsort(r->maps, r->n_maps, sizeof *r->maps, cmp_map);
  for (size_t e = 0; e < r->n_maps; ++e)
    ++r->map_start[r->maps[e].handle + 1];
  for (size_t h = 0; h < r->n_handles; ++h)
    r->map_start[h + 1] += r->map_start[h];

  size_t k = 0;
  for (size_t h = 0; h < r->n_handles; ++h) {
    const km_rig_handle *rh = &rig->handles[h];
    r->hv_start[h] = k;
    double c[3] = {0, 0, 0};
    for (size_t i = 0; i < rh->n_vertices; ++i, ++k) {
      const double *p = rest->V + 3 * (size_t)rh->vertices[i];
      for (int d = 0; d < 3; ++d) {
        r->hv_rest[3 * k + d] = p[d];
        c[d] += p[d];
      }
    }
    for (int d = 0; d < 3; ++d)
      r->centroid[3 * h + d] = c[d] / (double)rh->n_vertices;
  }
  r->hv_start[r->n_handles] = k;

  /* the height of the shape (km__shape_vertices): a vertex no face uses (an exporter's
   * leftover) is no part of it, and one above the head set the performer-to-character scale
   * (the procedural character with one at y = 2.6 on a walk: 1.514 instead of 1.020); nor is a
   * loose piece beside the body (a ground plane, a prop) */
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  bool *shape = km__malloc(rest->n_vertices ? rest->n_vertices : 1, sizeof *shape);
  if (!shape) {
    km_retarget_free(&r);
    return km__fail(err, KM_ERR_NOMEM, "retarget: out of memory");
  }
  km_status s = km__shape_vertices(rest, shape, err);
  if (s != KM_OK) {
    free(shape);
    km_retarget_free(&r);
    return s;
  }
  for (size_t v = 0; v < rest->n_vertices; ++v)
    for (int d = 0; d < 3 && shape[v]; ++d) {
      lo[d] = fmin(lo[d], rest->V[3 * v + d]);
      hi[d] = fmax(hi[d], rest->V[3 * v + d]);
    }
  free(shape);
  double ext_max = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  r->mesh_height = hi[1] - lo[1];
  /* A mesh lying flat in y (a sheet, a grid) has no height; its largest extent stands in. */
  if (!(r->mesh_height > 1e-9 * ext_max)) r->mesh_height = ext_max;
  if (o.floor || rig->floor) {
    if (!(r->floor_dy = km__malloc(r->n_handles, sizeof(double)))) {
      km_retarget_free(&r);
      return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
    }
    for (size_t h = 0; h < r->n_handles; ++h) {
      double ymin = INFINITY;
      for (size_t q = r->hv_start[h]; q < r->hv_start[h + 1]; ++q)
        ymin = fmin(ymin, r->hv_rest[3 * q + 1]);
      r->floor_dy[h] = lo[1] - ymin; /* <= 0 */
    }
  }
  double max_step = o.max_step != 0 ? o.max_step : rig->max_step;
  if (!(max_step >= 0) || !isfinite(max_step)) {
    km_retarget_free(&r);
    return km__fail(err, KM_ERR_INVALID, "retarget max_step must be finite and >= 0, got %g",
                    max_step);
  }
  if (max_step > 0) {
    r->max_step =
        max_step * sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                        (hi[2] - lo[2]) * (hi[2] - lo[2]));
    r->prev = km__malloc(r->n_handles, 12 * sizeof(double));
    r->hv_radius = km__calloc(r->n_handles, sizeof(double));
    if (!r->prev || !r->hv_radius) {
      km_retarget_free(&r);
      return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
    }
    for (size_t h = 0; h < r->n_handles; ++h)
      for (size_t q = r->hv_start[h]; q < r->hv_start[h + 1]; ++q) {
        double w[3];
        km__sub3(r->hv_rest + 3 * q, r->centroid + 3 * h, w);
        r->hv_radius[h] = fmax(r->hv_radius[h], sqrt(km__dot3(w, w)));
      }
  }
  if (rig->root_rigid) {
    if (rig->root < 1 || (size_t)rig->root > n_joints || rig->heading[0] < 0 ||
        (size_t)rig->heading[0] > n_joints || rig->heading[1] < 0 ||
        (size_t)rig->heading[1] > n_joints) {
      km_retarget_free(&r);
      return km__fail(err, KM_ERR_INVALID, "rigid root motion: root or heading joint out of range");
    }
    r->rigid = true;
    r->root = rig->root - 1;
    r->h_max_turn = (rig->max_turn > 0 ? rig->max_turn : KM_HEADING_MAX_TURN) * M_PI / 180;
    r->hl = rig->heading[0] && rig->heading[1] ? rig->heading[0] - 1 : -1;
    r->hr = rig->heading[0] && rig->heading[1] ? rig->heading[1] - 1 : -1;
    for (int d = 0; d < 3; ++d)
      r->pivot[d] = 0.5 * (lo[d] + hi[d]);
  }
  r->floor_y = lo[1];
  r->fps = o.fps > 0 && isfinite(o.fps) ? o.fps : 30.0;
  r->bone_catchup = o.bone_catchup < 0 || !isfinite(o.bone_catchup)
                        ? -1
                        : (o.bone_catchup == 0 ? KM_BONE_CATCHUP : o.bone_catchup) / r->fps;
  bool any_rot = false, any_bone = false;
  for (size_t e = 0; e < rig->n_maps; ++e) {
    any_rot |= rig->maps[e].rotate || rig->maps[e].bone_from > 0;
    any_bone |= rig->maps[e].bone_from > 0;
    if (rig->maps[e].bone_from < 0 || (size_t)rig->maps[e].bone_from > n_joints) {
      km_retarget_free(&r);
      return km__fail(err, KM_ERR_INVALID, "rig map %zu: bone start joint %d out of range", e,
                      (int)rig->maps[e].bone_from - 1);
    }
  }
  if (any_rot) {
    r->rot_joint = km__malloc(r->n_handles, sizeof(int32_t));
    r->rot_parent = km__malloc(r->n_handles, sizeof(int32_t));
    r->rot = km__malloc(r->n_handles, 9 * sizeof(double));
    r->par = km__malloc(n_joints ? n_joints : 1, sizeof(int32_t));
    r->qref = km__malloc(n_joints ? n_joints : 1, 9 * sizeof(double));
    if (!r->rot_joint || !r->rot_parent || !r->rot || !r->par || !r->qref) {
      km_retarget_free(&r);
      return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
    }
    for (size_t j = 0; j < n_joints; ++j) {
      int32_t q = o.parents                         ? o.parents[j]
                  : rig->skeleton == KM_RIG_KINECT1 ? km_kinect1_joint_parent((int)j)
                                                    : -1;
      r->par[j] = q >= 0 && (size_t)q < j ? q : -1;
    }
    if (any_bone) {
      r->bone_from = km__malloc(r->n_handles, sizeof(int32_t));
      r->bone_rel = km__calloc(r->n_handles, sizeof(int32_t));
      r->Rb = km__malloc(n_joints ? n_joints : 1, 9 * sizeof(double));
      r->C = km__malloc(n_joints ? n_joints : 1, 3 * sizeof(double));
      r->only_child = km__malloc(n_joints ? n_joints : 1, sizeof(int32_t));
      r->jfill = km__malloc(n_joints ? n_joints : 1, 3 * sizeof(double));
      r->seen = km__calloc(n_joints ? n_joints : 1, sizeof(bool));
      r->bvec = km__malloc(n_joints ? n_joints : 1, 3 * sizeof(double));
      r->blen = km__malloc(n_joints ? n_joints : 1, sizeof(double));
      r->bhave = km__calloc(n_joints ? n_joints : 1, sizeof(bool));
      r->blag = km__calloc(n_joints ? n_joints : 1, sizeof(bool));
      bool jr = rig->joint_rest && rig->n_joint_rest == n_joints;
      if (jr) r->jrest = km__malloc(n_joints, 3 * sizeof(double));
      if (!r->bone_from || !r->bone_rel || !r->Rb || !r->C || !r->only_child || !r->jfill ||
          !r->seen || !r->bvec || !r->blen || !r->bhave || !r->blag || (jr && !r->jrest)) {
        km_retarget_free(&r);
        return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
      }
      if (jr) memcpy(r->jrest, rig->joint_rest, n_joints * 3 * sizeof(double));
      for (size_t j = 0; j < n_joints; ++j)
        r->only_child[j] = -1;
      for (size_t j = 0; j < n_joints; ++j) { /* -2: several children (readers skip < 0) */
        int32_t q = r->par[j];
        if (q >= 0) r->only_child[q] = r->only_child[q] == -1 ? (int32_t)j : -2;
      }
      r->aim = jr && rig->aim;
      r->local_turn = jr && rig->local_turn;
      r->swing_limit =
          rig->swing_limit > 0 && rig->swing_limit < 180 ? rig->swing_limit * M_PI / 180 : 0;
      r->bend_limit =
          rig->bend_limit > 0 && rig->bend_limit < 180 ? rig->bend_limit * M_PI / 180 : 0;
      r->upper_limit = rig->upper_limb_limit > 0 && rig->upper_limb_limit < 180
                           ? rig->upper_limb_limit * M_PI / 180
                           : 0;
      r->girdle_limit =
          rig->girdle_limit > 0 && rig->girdle_limit < 180 ? rig->girdle_limit * M_PI / 180 : 0;
      /* The mesh turns about the character's root joint, the point the handles' root-relative
       * motion is measured from (the bounding box centre is only a stand-in without joints),
       * or on a kinect1 skeleton about the vertical through the middle of the spine (root ->
       * ShoulderCenter): the same line on an upright body, the middle of the trunk on a
       * quadruped, which turned about its hips and swept its head round at the far end (dog0
       * on cmu_131_03, a performer's spin at 120 fps: the head 4.3 % of the diagonal a frame,
       * the take's own largest step 2.6 %). bench motion B, largest one-frame jump, before ->
       * after: dog0 15.4/17.7/13.8/3.3/4.3 -> 10.0/14.3/14.7/2.3/2.9 %, the horse
       * 17.3/19.4/16.3/3.7/4.8 -> 12.2/16.9/17.4/2.8/3.4 % (the table's take order); the upright
       * bodies within 0.1 % of before. */
      /* HipCenter, ShoulderCenter; HandLeft, HandRight, KneeLeft, KneeRight */
      r->upright = jr && rig->skeleton == KM_RIG_KINECT1 && n_joints >= KM_KINECT1_JOINTS &&
                   km__body_upright(r->jrest, r->jrest + 3 * 2, r->jrest + 3 * 7, r->jrest + 3 * 11,
                                    r->jrest + 3 * 13, r->jrest + 3 * 17);
      if (jr && r->rigid && km__finite3(r->jrest + 3 * (size_t)r->root)) {
        memcpy(r->pivot, r->jrest + 3 * (size_t)r->root, sizeof r->pivot);
        const double *sc = r->jrest + 3 * 2; /* ShoulderCenter */
        if (rig->skeleton == KM_RIG_KINECT1 && r->n_joints >= KM_KINECT1_JOINTS &&
            km__finite3(sc)) {
          r->pivot[0] = 0.5 * (r->pivot[0] + sc[0]);
          r->pivot[2] = 0.5 * (r->pivot[2] + sc[2]);
        }
      }
    }
    for (size_t h = 0; h < r->n_handles; ++h) {
      r->rot_joint[h] = r->rot_parent[h] = -1;
      if (r->bone_from) r->bone_from[h] = -1;
      for (size_t e = r->map_start[h]; e < r->map_start[h + 1] && r->rot_joint[h] < 0; ++e) {
        const km_rig_map *m = &r->maps[e];
        int32_t par = -1;
        if (m->bone_from > 0) { /* the first bone entry of a handle drives it */
          r->rot_joint[h] = m->joint;
          r->rot_parent[h] = r->bone_from[h] = m->bone_from - 1;
          r->bone_rel[h] = m->relative_to;
          continue;
        }
        if (!m->rotate) continue;
        if (o.parents)
          par = o.parents[m->joint];
        else if (rig->skeleton == KM_RIG_KINECT1)
          par = km_kinect1_joint_parent(m->joint);
        if (par < 0 || (size_t)par >= n_joints) continue; /* a root: nothing to turn with */
        r->rot_joint[h] = m->joint;
        r->rot_parent[h] = par;
      }
    }
  }
  if (r->C && r->jrest && held_joints(r) != KM_OK) {
    km_retarget_free(&r);
    return km__fail(err, KM_ERR_NOMEM, "km_retarget_create: out of memory");
  }
  /* the farthest corner of the rest bounding box from the vertical through the pivot (final
   * now): how far a heading change moves a vertex, for the snap easing (ease) */
  for (int c = 0; r->rigid && c < 4; ++c)
    r->root_rho = fmax(r->root_rho, hypot((c & 1 ? hi[0] : lo[0]) - r->pivot[0],
                                          (c & 2 ? hi[2] : lo[2]) - r->pivot[2]));
  r->kinect1 = rig->skeleton == KM_RIG_KINECT1;
  r->auto_scale = o.scale == 0;
  r->scale = r->auto_scale ? NAN : o.scale;
  km_retarget_reset(r);
  *out = r;
  return KM_OK;
}

/* Performer stature in a frame: the Head-to-lower-foot joint span scaled up to the whole
 * body for Kinect, else the y extent of the valid joints. NaN when it cannot be measured. */
static double skeleton_height(const km_retarget *r, const double *J) {
  if (r->kinect1) {
    enum { HEAD = 3, FOOT_L = 15, FOOT_R = 19 };
    const double *h = J + 3 * HEAD, *fl = J + 3 * FOOT_L, *fr = J + 3 * FOOT_R;
    if (km__finite3(h) && (km__finite3(fl) || km__finite3(fr))) {
      double foot = km__finite3(fl) && km__finite3(fr) ? fmin(fl[1], fr[1])
                    : km__finite3(fl)                  ? fl[1]
                                                       : fr[1];
      if (h[1] - foot > 0) return (h[1] - foot) / KM_KINECT1_SPAN_OF_STATURE;
    }
  }
  double lo = INFINITY, hi = -INFINITY;
  for (size_t j = 0; j < r->n_joints; ++j)
    if (km__finite3(J + 3 * j)) {
      lo = fmin(lo, J[3 * j + 1]);
      hi = fmax(hi, J[3 * j + 1]);
    }
  return hi > lo ? hi - lo : NAN;
}

static void update_rotations(km_retarget *r, const double *J);

/* The scale of the rigid root's translation: the character's leg length (hip -> knee ->
 * ankle, both legs, from its skeleton) over the performer's in the reference frame, where both
 * are known (a kinect1 character skeleton), else the stature scale. A performer whose hips
 * drop 10 cm with bent knees drops a character with shorter legs (for its height) by as much
 * of its own leg as the legs fold, no further: with the stature's scale the elephant (legs a
 * quarter of its height, a person's half) sank through the floor whenever the performer's knees
 * bent (bench motion B, cmu_131_03: a vertex below the rest floor in 1061 of 1102 frames), as
 * Unity's humanoid retargeting scales body motion by the hips' height. Kept within
 * 0.3 .. 1.5 of the stature scale; a leg the tracker has not sent in the reference frame: the
 * stature scale. */
static double root_scale(const km_retarget *r) {
  if (!r->jrest || !r->kinect1 || r->n_joints < KM_KINECT1_JOINTS) return r->scale;
  static const int legs[2][3] = {{12, 13, 14}, {16, 17, 18}}; /* hip, knee, ankle */
  double lp = 0, lc = 0;
  int n = 0;
  for (int k = 0; k < 2; ++k) {
    const double *h = r->ref + 3 * legs[k][0], *kn = r->ref + 3 * legs[k][1],
                 *a = r->ref + 3 * legs[k][2];
    const double *H = r->jrest + 3 * legs[k][0], *K = r->jrest + 3 * legs[k][1],
                 *A = r->jrest + 3 * legs[k][2];
    if (!km__finite3(h) || !km__finite3(kn) || !km__finite3(a) || !km__finite3(H) ||
        !km__finite3(K) || !km__finite3(A))
      continue;
    lp += dist3(h, kn) + dist3(kn, a);
    lc += dist3(H, K) + dist3(K, A);
    ++n;
  }
  if (!n || !(lp > 0) || !(lc > 0)) return r->scale;
  return fmax(0.3 * r->scale, fmin(1.5 * r->scale, lc / lp));
}

/* The rigid root's rotation R: about y by the heading shown (cos_s, sin_s). */
static void root_rotation(km_retarget *r) {
  double c = r->cos_s, sn = r->sin_s, R[9] = {c, 0, sn, 0, 1, 0, -sn, 0, c};
  memcpy(r->R, R, sizeof R);
}

/* Snap easing: the largest step of a handle vertex since the last push is at most
 * |d - d'| + 2 sin(theta / 2) rho (d: displacement, theta: the angle of R R'^T, rho: the
 * handle's radius), and under rigid root motion the whole mesh's step adds |t - t'| +
 * 2 sin(|phi - phi'| / 2) root_rho (the root's translation and heading: a quadruped turning
 * with the performer's hips sweeps its head and tail, a lunge carries the whole body; eased
 * handles under an uneased root left dog0's one-frame jumps at 9-10 % of its diagonal on the
 * Kinect takes). When the largest bound exceeds max_step, every handle and the root go only
 * the fraction alpha = max_step / (largest bound) of the way (displacements linearly,
 * rotations by slerp, the heading by its angle), so they stay in step with each other and the
 * rest of the move follows over the next pushes. It limits every fast move, not only snaps: the
 * rig opts in. */
static void ease(km_retarget *r) {
  double worst = 0, root_step = 0;
  if (r->rigid && r->have_prev) {
    double dt[3];
    km__sub3(r->t, r->prev_t, dt);
    root_step = sqrt(km__dot3(dt, dt)) + 2 * sin(0.5 * fabs(r->h_phi - r->prev_phi)) * r->root_rho;
    if (!isfinite(root_step)) root_step = 0;
  }
  for (size_t h = 0; r->have_prev && h < r->n_handles; ++h) {
    const double *pd = r->prev + 12 * h, *pR = pd + 3;
    double dd[3];
    for (int d = 0; d < 3; ++d)
      dd[d] = r->disp[3 * h + d] - pd[d];
    double step = sqrt(km__dot3(dd, dd));
    if (r->rot && r->rot_joint[h] >= 0) {
      step += 2 * sin(0.5 * km__rot3_angle_between(r->rot + 9 * h, pR)) * r->hv_radius[h];
    }
    worst = fmax(worst, step);
  }
  worst += root_step;
  if (worst > r->max_step) {
    double alpha = r->max_step / worst;
    ++r->eased;
    if (r->rigid) {
      for (int d = 0; d < 3; ++d)
        r->t[d] = r->prev_t[d] + alpha * (r->t[d] - r->prev_t[d]);
      /* the heading shown: heading_push catches up from here over the next pushes */
      r->h_phi = r->prev_phi + alpha * (r->h_phi - r->prev_phi);
      r->cos_s = cos(r->h_phi), r->sin_s = sin(r->h_phi);
      root_rotation(r);
    }
    for (size_t h = 0; h < r->n_handles; ++h) {
      const double *pd = r->prev + 12 * h, *pR = pd + 3;
      for (int d = 0; d < 3; ++d)
        r->disp[3 * h + d] = pd[d] + alpha * (r->disp[3 * h + d] - pd[d]);
      if (!(r->rot && r->rot_joint[h] >= 0)) continue;
      km__rot3_slerp(pR, r->rot + 9 * h, alpha, r->rot + 9 * h);
    }
  }
  for (size_t h = 0; h < r->n_handles; ++h) {
    memcpy(r->prev + 12 * h, r->disp + 3 * h, 3 * sizeof(double));
    if (r->rot)
      memcpy(r->prev + 12 * h + 3, r->rot + 9 * h, 9 * sizeof(double));
    else
      km__m3_identity(r->prev + 12 * h + 3);
  }
  memcpy(r->prev_t, r->t, sizeof r->prev_t);
  r->prev_phi = r->h_phi;
  r->have_prev = true;
}

/* Heading of the rigid root motion (issue 12): the measured turn of the hip (+ shoulder)
 * line is noisy and glitchy on a Kinect (one-frame changes of 40-70 degrees where the tracker
 * re-fits the skeleton, 180 degrees where it swaps left and right), and the whole mesh turns
 * with it: a 20 degree step moves a quadruped's nose by a sixth of its size. Per push:
 *   - a measurement that differs from the last accepted one by more than
 *     KM_HEADING_MAX_RATE / fps * (1 + measurements rejected in a row) is a glitch and held;
 *     one more than 90 degrees off (a left/right swap) is held for up to a second, then taken
 *     (the performer did turn round);
 *   - the accepted ones go through a One Euro filter on the angle (min cutoff 1 Hz, beta
 *     1 Hz per rad/s: hip noise is damped, a fast turn is followed), and the heading shown
 *     follows the filter's value at most KM_HEADING_MAX_TURN degrees per second (a spin; the
 *     demo's kung-fu spin needs about that), or the rig's "max_turn" (kinemesh rig writes 360
 *     for a body that is not upright: a quadruped turning at a performer's 440 deg/s spin in
 *     cmu_131_03 swept the horse's head 3.4 % of the diagonal in a frame at 120 fps);
 *   - a measurement taken after rejections (a re-fit that stayed, a swap held a second) is
 *     shown at most KM_HEADING_REFIT_TURN degrees per second until the heading shown has
 *     caught up with the filter (within a degree): the tracker re-fitting the skeleton is not
 *     the performer spinning. precog_Seq2_1 frames 20-22 re-fit 37, 25 and 9 degrees a
 *     frame (1100 deg/s at most, taken as a turn at the old 1200 deg/s threshold: dog0 turned
 *     20 degrees a frame, 26 % of its diagonal); the demo's spin measures 680 deg/s at most,
 *     the CMU takes 440, so 900 deg/s leaves the spin a third of margin.
 * phi: the measured heading change since the reference frame, radians. */
#define KM_HEADING_MAX_RATE 900.0   /* deg/s: a faster measured change is a glitch */
#define KM_HEADING_REFIT_TURN 300.0 /* deg/s: the fastest turn shown onto a re-fit */
static void heading_push(km_retarget *r, double phi) {
  if (!r->have_heading) {
    r->have_heading = true;
    r->h_phi = r->h_meas = r->h_filt = phi;
    r->h_speed = 0;
    r->h_rejected = 0;
    return;
  }
  const double deg = M_PI / 180;
  double te = 1.0 / r->fps;
  double d = remainder(phi - r->h_meas, 2 * M_PI); /* since the last accepted measurement */
  double allow = KM_HEADING_MAX_RATE * deg * te * (1 + r->h_rejected);
  bool swap = fabs(d) > 90 * deg && r->h_rejected < r->fps;
  if (fabs(d) > allow || swap) {
    ++r->h_rejected;
  } else {
    te *= 1 + r->h_rejected; /* the time since the last accepted measurement */
    if (r->h_rejected) r->h_refit = true;
    r->h_rejected = 0;
    r->h_meas += d;
    r->h_speed += km__one_euro_alpha(1.0, te) * (fabs(d) / te - r->h_speed); /* d_cutoff 1 Hz */
    double fc = 1.0 + 1.0 * r->h_speed;
    r->h_filt += km__one_euro_alpha(fc, te) * (r->h_meas - r->h_filt);
  }
  double step = r->h_filt - r->h_phi, cap = r->h_max_turn / r->fps;
  if (r->h_refit) cap = fmin(cap, KM_HEADING_REFIT_TURN * deg / r->fps);
  r->h_phi += fabs(step) > cap ? copysign(cap, step) : step;
  if (fabs(r->h_filt - r->h_phi) < 1 * deg) r->h_refit = false;
}

static bool valid9(const double *R) {
  for (int k = 0; k < 9; ++k)
    if (!isfinite(R[k])) return false;
  return true;
}

void km_retarget_push(km_retarget *r, const double *joints, double *handle_targets) {
  km_retarget_push_rotations(r, joints, NULL, handle_targets);
}

/* A joint the tracker never sends (OSCeleton has no wrists or ankles: its hand hangs off the
 * elbow) would leave both bones through it without a direction, and the limb still. While a
 * joint has never been valid (since create / reset) and its parent and its one child are valid,
 * it is placed on the line between them at the character's rest proportion (the middle
 * without a character skeleton). Returns joints, or r->jfill when it filled one. A joint that
 * was seen and is lost now is not filled: it holds (glitch rejection, the bones' last
 * rotations). */
static const double *fill_untracked(km_retarget *r, const double *joints) {
  if (!r->only_child) return joints;
  bool copied = false;
  for (size_t j = 0; j < r->n_joints; ++j) {
    if (km__finite3(joints + 3 * j)) r->seen[j] = true;
    int32_t p = r->par[j], c = r->only_child[j];
    if (p < 0 || c < 0 || r->seen[j]) continue;
    const double *a = joints + 3 * (size_t)p, *b = joints + 3 * (size_t)c;
    if (!km__finite3(a) || !km__finite3(b)) continue;
    double t = 0.5;
    if (r->jrest) {
      double l0 = dist3(r->jrest + 3 * (size_t)p, r->jrest + 3 * j),
             l1 = dist3(r->jrest + 3 * j, r->jrest + 3 * (size_t)c);
      if (l0 + l1 > 1e-12 && isfinite(l0 + l1)) t = l0 / (l0 + l1);
    }
    if (!copied) memcpy(r->jfill, joints, 3 * r->n_joints * sizeof(double));
    copied = true;
    for (int d = 0; d < 3; ++d)
      r->jfill[3 * j + d] = a[d] + t * (b[d] - a[d]);
  }
  return copied ? r->jfill : joints;
}

void km_retarget_push_rotations(km_retarget *r, const double *joints, const double *rotations,
                                double *handle_targets) {
  joints = fill_untracked(r, joints);
  for (size_t j = 0; j < r->n_joints; ++j)
    if (!isfinite(r->ref[3 * j]) && km__finite3(joints + 3 * j))
      memcpy(r->ref + 3 * j, joints + 3 * j, 3 * sizeof(double));
  r->jrot = r->qref ? rotations : NULL;
  for (size_t j = 0; r->jrot && j < r->n_joints; ++j)
    if (!isfinite(r->qref[9 * j]) && valid9(rotations + 9 * j))
      memcpy(r->qref + 9 * j, rotations + 9 * j, 9 * sizeof(double));
  if (!isfinite(r->scale)) {
    double h = skeleton_height(r, joints);
    if (h > 1e-6) r->scale = r->mesh_height / h;
  }
  if (r->rigid && isfinite(r->scale)) {
    const double *q = joints + 3 * (size_t)r->root, *q0 = r->ref + 3 * (size_t)r->root;
    if (km__finite3(q) && km__finite3(q0)) {
      if (r->hl >= 0) {
        /* The heading: the turn about y of the right -> left line of the heading joints (the
         * hips), with a Kinect skeleton's shoulder line added when valid: hips alone are 0.18 m
         * apart and a few centimetres of tracker noise turned the whole mesh. The lines are
         * summed as they are, each counting by its length on the floor: a short one's direction
         * is the least sure. MediaPipe reads the hips of a figure facing the camera 0.01-0.21 m
         * apart; with each line's direction counted alike, a hip line misread 3 cm wide turned
         * the mesh by up to half its error (test_puppetry: 15.3 degrees for one turned 80, now
         * 1.7), and the character animated from eleven of the live_camera test's recordings
         * faced 3-32 degrees off on average (median 20) where it faces 3-21 now (median 12).
         * bench motion: no row's targets change (jump -0.9 .. +0.3 % of the diagonal, folded
         * triangles -36 .. +21). */
        int32_t lines[2][2] = {{r->hl, r->hr}, {-1, -1}};
        if (r->kinect1 && r->n_joints >= 9) lines[1][0] = 4, lines[1][1] = 8; /* shoulders */
        double v[2] = {0, 0}, v0[2] = {0, 0};
        bool hips = false;
        for (int k = 0; k < 2; ++k) {
          if (lines[k][0] < 0) continue;
          const double *a = joints + 3 * (size_t)lines[k][0], *b = joints + 3 * (size_t)lines[k][1];
          const double *a0 = r->ref + 3 * (size_t)lines[k][0],
                       *b0 = r->ref + 3 * (size_t)lines[k][1];
          if (!km__finite3(a) || !km__finite3(b) || !km__finite3(a0) || !km__finite3(b0)) continue;
          double x = b[0] - a[0], z = b[2] - a[2], x0 = b0[0] - a0[0], z0 = b0[2] - a0[2];
          double n = hypot(x, z), n0 = hypot(x0, z0);
          if (!(n > 1e-9) || !(n0 > 1e-9)) continue;
          v[0] += x, v[1] += z, v0[0] += x0, v0[1] += z0;
          hips |= k == 0;
        }
        if (hips && hypot(v[0], v[1]) > 1e-9 && hypot(v0[0], v0[1]) > 1e-9) {
          /* R_y(phi) takes (1,0,0) to (cos phi, 0, -sin phi): a vector's angle is atan2(-z, x) */
          heading_push(r, atan2(-v[1], v[0]) - atan2(-v0[1], v0[0]));
          /* While the heading shown catches up with a re-fit, the limbs are measured in the
           * body's frame (the filtered heading) and the mesh turned by the heading shown: the
           * body turns late as a whole, rather than its legs swung sideways against it
           * (precog_Seq2_1 on armadillo: 1683 folded triangles against 1555). A spin's limbs
           * stay in the frame shown (the demo's body follows the skinned character). */
          double hb = r->h_refit ? r->h_filt : r->h_phi;
          r->cos_h = cos(hb);
          r->sin_h = sin(hb);
          r->cos_s = cos(r->h_phi);
          r->sin_s = sin(r->h_phi);
        }
      }
      root_rotation(r);
      if (!isfinite(r->root_s)) r->root_s = root_scale(r);
      for (int d = 0; d < 3; ++d)
        r->t[d] = r->root_s * (q[d] - q0[d]);
    }
  }
  if (isfinite(r->scale)) {
    for (size_t h = 0; h < r->n_handles; ++h) {
      size_t a = r->map_start[h], b = r->map_start[h + 1];
      if (a == b) continue;                               /* anchor */
      if (r->bone_from && r->bone_from[h] >= 0) continue; /* update_rotations moves it */
      double d[3] = {0, 0, 0};
      bool ok = true;
      for (size_t e = a; e < b && ok; ++e) {
        const km_rig_map *m = &r->maps[e];
        const double *p = joints + 3 * (size_t)m->joint, *p0 = r->ref + 3 * (size_t)m->joint;
        ok = km__finite3(p) && km__finite3(p0);
        double root[3] = {0, 0, 0};
        if (ok && m->relative_to > 0) { /* root-relative: subtract the reference's motion */
          const double *q = joints + 3 * (size_t)(m->relative_to - 1),
                       *q0 = r->ref + 3 * (size_t)(m->relative_to - 1);
          ok = km__finite3(q) && km__finite3(q0);
          for (int c = 0; ok && c < 3; ++c)
            root[c] = q[c] - q0[c];
        }
        double rel[3] = {p[0] - p0[0] - root[0], p[1] - p0[1] - root[1], p[2] - p0[2] - root[2]};
        if (ok && r->rigid && m->relative_to > 0) {
          /* in the root's heading frame: R^T (p - q) - (p0 - q0) */
          const double *q = joints + 3 * (size_t)(m->relative_to - 1),
                       *q0 = r->ref + 3 * (size_t)(m->relative_to - 1);
          double w[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
          double c = r->cos_h, sn = r->sin_h;
          rel[0] = c * w[0] - sn * w[2] - (p0[0] - q0[0]);
          rel[1] = w[1] - (p0[1] - q0[1]);
          rel[2] = sn * w[0] + c * w[2] - (p0[2] - q0[2]);
        }
        for (int c = 0; ok && c < 3; ++c)
          if (m->axes & (1u << c)) d[c] += m->scale * rel[c];
      }
      if (!ok) continue; /* a joint is not valid: the handle keeps its last target */
      for (int c = 0; c < 3; ++c)
        r->disp[3 * h + c] = r->scale * d[c];
      /* under rigid root motion the root's translation lowers the handle too */
      double ty = r->rigid ? r->t[1] : 0;
      if (r->floor_dy && r->disp[3 * h + 1] + ty < r->floor_dy[h])
        r->disp[3 * h + 1] = r->floor_dy[h] - ty;
    }
  }
  if (r->rot) update_rotations(r, joints);
  r->jrot = NULL;
  if (r->max_step > 0) ease(r);
  if (handle_targets)
    for (size_t i = 0; i < 3 * r->n_handles; ++i)
      handle_targets[i] = r->centroid[i] + r->disp[i];
}

/* Issue 15: the twist of a given joint rotation. The rotation since the reference frame,
 * G = Q Q_ref^T (Q: the rotation given with the frame for the bone ending at joint j), splits
 * into a twist about the bone's reference direction d0 followed by a swing (swing-twist
 * decomposition: the twist quaternion is G's quaternion projected on d0); the swing is what
 * the joint positions already give, the twist (a forearm turning about itself) is what they
 * cannot. R (a rotation whose segment a -> b now points along d, unit, in R's frame) is
 * premultiplied by the twist angle about d. Nothing happens without a valid given rotation
 * and reference. */
static void apply_twist(const km_retarget *r, int32_t j, const double d0[3], const double d[3],
                        double R[9]) {
  if (!r->jrot) return;
  const double *Q = r->jrot + 9 * (size_t)j, *Q0 = r->qref + 9 * (size_t)j;
  if (!valid9(Q) || !valid9(Q0)) return;
  double G[9], q[4]; /* G = Q Q0^T; q = (w, x, y, z) */
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      G[3 * a + b] =
          Q[3 * a] * Q0[3 * b] + Q[3 * a + 1] * Q0[3 * b + 1] + Q[3 * a + 2] * Q0[3 * b + 2];
  km__quat_from_rot3(G, q);
  double phi = 2 * atan2(q[1] * d0[0] + q[2] * d0[1] + q[3] * d0[2], q[0]);
  double s = sin(0.5 * phi), T[9];
  double qt[4] = {cos(0.5 * phi), s * d[0], s * d[1], s * d[2]};
  km__rot3_from_quat(qt, T);
  km__m3_mul(T, R, R);
}

/* Rotations of the rotating handles from the bones of this frame (kept when a bone is not
 * valid). With rigid root motion the rotation is taken in the root's heading frame. */
static void update_bones(km_retarget *r, const double *J);

/* The unit directions of the segment a -> b in the reference frame (d0) and in this frame (d,
 * in the root's heading frame under rigid root motion); false when a joint is not valid or the
 * segment has no length. */
static bool segment_dirs(const km_retarget *r, const double *J, int32_t a, int32_t b, double d0[3],
                         double d[3]) {
  const double *p = J + 3 * (size_t)b, *q = J + 3 * (size_t)a;
  const double *p0 = r->ref + 3 * (size_t)b, *q0 = r->ref + 3 * (size_t)a;
  if (!km__finite3(p) || !km__finite3(q) || !km__finite3(p0) || !km__finite3(q0)) return false;
  for (int c = 0; c < 3; ++c) {
    d[c] = p[c] - q[c];
    d0[c] = p0[c] - q0[c];
  }
  if (r->rigid) { /* R_y(-phi) d */
    double c = r->cos_h, sn = r->sin_h, x = d[0], z = d[2];
    d[0] = c * x - sn * z;
    d[2] = sn * x + c * z;
  }
  double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  double n0 = sqrt(d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2]);
  if (!(n > 1e-9) || !(n0 > 1e-9)) return false;
  for (int c = 0; c < 3; ++c) {
    d[c] /= n;
    d0[c] /= n0;
  }
  return true;
}

/* Joints a and b under 0.15 m apart (of performer) in the reference frame: a short bone (a
 * Kinect wrist -> hand, ankle -> foot: a few noisy centimetres), whose direction jitters.
 * False when either reference is not known. */
static bool short_bone(const km_retarget *r, int32_t a, int32_t b) {
  const double *pa = r->ref + 3 * (size_t)a, *pb = r->ref + 3 * (size_t)b;
  return km__finite3(pa) && km__finite3(pb) && dist3(pa, pb) < 0.15;
}

/* The nearest ancestor of a at least 0.15 m from b stands in for a (short_bone). */
static int32_t long_ancestor(const km_retarget *r, int32_t a, int32_t b) {
  while (r->par[a] >= 0 && short_bone(r, a, b))
    a = r->par[a];
  return a;
}

/* Issue 12: a rotating handle's twist from its joint's child (positions only: a take that
 * gives joint rotations has its own twist, apply_twist). The bone q -> j gives the handle's
 * swing (the shortest rotation R from its reference direction d0 to its direction d now),
 * which leaves its turn about d open; the joint's child c fixes it: R is turned about d until
 * it carries the reference direction j -> c onto the current one, both seen across d. A
 * joint with several children (a Kinect ShoulderCenter: head and both shoulders; a hip
 * centre) takes the line between the two of them that lies most across the bone (left ->
 * right shoulder), a leaf (a hand, a head) none, nor a child under 0.15 m (a Kinect hand, a
 * foot). A child nearly along the bone tells little
 * about the turn: the twist counts in full where both directions stand 30 degrees or more off
 * the bone, fading out at 10 (so the turn follows continuously as an elbow straightens). */
static void child_twist(const km_retarget *r, const double *J, int32_t j, const double d0[3],
                        const double d[3], double R[9]) {
  if (r->jrot) return;
  int32_t a = -1, b = -1;
  double best = -1;
  for (size_t c = 0; c < r->n_joints; ++c) {
    if (r->par[c] != j) continue;
    if (a < 0 && b < 0) { /* one child: j -> c */
      a = j, b = (int32_t)c;
      best = 0;
      continue;
    }
    for (size_t e = 0; e < c; ++e) { /* several: the pair most across the bone */
      if (r->par[e] != j || !km__finite3(r->ref + 3 * e) || !km__finite3(r->ref + 3 * c)) continue;
      double t[3];
      km__sub3(r->ref + 3 * c, r->ref + 3 * e, t);
      double along = km__dot3(t, d0), across = km__dot3(t, t) - along * along;
      if (best <= 0 || across > best) best = across, a = (int32_t)e, b = (int32_t)c;
    }
  }
  double t0[3], t[3];
  /* a short child would twist the handle with its noise */
  if (a < 0 || b < 0 || short_bone(r, a, b) || !segment_dirs(r, J, a, b, t0, t)) return;
  double pc[3], k;
  km__m3_apply(R, t0, pc); /* the reference child direction as R carries it, then across d */
  k = km__dot3(pc, d);
  for (int i = 0; i < 3; ++i)
    pc[i] -= k * d[i];
  k = km__dot3(t, d);
  for (int i = 0; i < 3; ++i)
    t[i] -= k * d[i];
  double sc = km__normalize3(pc), st = km__normalize3(t);
  double w = fmax(0, fmin(1, (fmin(sc, st) - sin(10 * M_PI / 180)) /
                                 (sin(30 * M_PI / 180) - sin(10 * M_PI / 180))));
  if (!(w > 0)) return;
  double x[3];
  km__cross3(pc, t, x);
  double th = w * atan2(km__dot3(x, d), km__dot3(pc, t));
  double rv[3] = {th * d[0], th * d[1], th * d[2]}, T[9];
  km__m3_from_rotvec(rv, T);
  km__m3_mul(T, R, R);
}

static void update_rotations(km_retarget *r, const double *J) {
  if (r->bone_from) update_bones(r, J);
  for (size_t h = 0; h < r->n_handles; ++h) {
    int32_t j = r->rot_joint[h], q = r->rot_parent[h];
    if (j < 0 || (r->bone_from && r->bone_from[h] >= 0)) continue;
    q = long_ancestor(r, q, j);
    double d[3], d0[3];
    if (!segment_dirs(r, J, q, j, d0, d)) continue;
    km__rot3_between(d0, d, r->rot + 9 * h);
    apply_twist(r, j, d0, d, r->rot + 9 * h);
    child_twist(r, J, j, d0, d, r->rot + 9 * h);
  }
}

/* A kinect1 forearm or shin: the bone ending at a wrist or ankle (joint 6, 10, 14 or 18), the
 * one an elbow's or knee's bend turns. */
static bool kinect1_hinge(int32_t b) { return b == 6 || b == 10 || b == 14 || b == 18; }

/* The smaller of two limits (radians, 0: none). */
static double tighter_limit(double a, double b) {
  return a > 0 && b > 0 ? fmin(a, b) : a > 0 ? a : b;
}

/* The largest swing allowed to the bone ending at joint b, radians; 0: none. Every bone has
 * the rig's "swing_limit". On a kinect1 skeleton also: a shoulder or hip bone (ending at joint
 * 4, 8, 12 or 16), which carries a whole limb, "girdle_limit" where it is the smaller; and an
 * aimed bone (segment_rotation with aim): an upper arm or thigh (ending at an elbow or knee)
 * "upper_limb_limit" instead where it is set, a forearm or shin (ending at a wrist or ankle)
 * "bend_limit", the elbow's or knee's bend, where it is the smaller (a bend limit wider than 90
 * degrees is the anatomical one, counted from the straight limb: hinge_bend). The limb limits apply
 * to aimed bones only: a rig without "aim" keeps its limbs as free as before. */
static double limb_limit(const km_retarget *r, int32_t b, bool aimed) {
  double lim = r->swing_limit;
  if (!r->kinect1) return lim;
  bool girdle = b == 4 || b == 8 || b == 12 || b == 16;
  bool upper = aimed && (b == 5 || b == 9 || b == 13 || b == 17);
  bool hinge = aimed && kinect1_hinge(b);
  if (upper && r->upper_limit > 0) lim = r->upper_limit;
  if (hinge) lim = tighter_limit(lim, r->bend_limit);
  if (girdle) lim = tighter_limit(lim, r->girdle_limit);
  return lim;
}

/* The swing limit: unit d is brought back towards unit w along the great circle to at most lim
 * radians from it (nothing changes within the limit; lim <= 0: none). For a limit of at most
 * 90 degrees, where d points more than 135 degrees away from w, the swing allowed falls
 * linearly to 0 at the antipode: a plain clamp takes the great circle's side from d, which flips
 * as d crosses the point opposite w, and a limb held near its limit swung across its cone in
 * one frame (a quadruped's foreleg, upper leg held to 5 degrees, forearm to 20, with a
 * performer's forearm pointing up: the horse on cmu_131_01 stepped 3.6 % of its diagonal in a
 * frame, 2.7 % with the fade); continuous in d everywhere. A wider limit (a human elbow's 150)
 * is a plain clamp: a fade would fold back (an elbow asked 170 degrees would bend 50). */
static void clamp_swing(const double w[3], double lim, double d[3]) {
  double c = fmax(-1, fmin(1, km__dot3(w, d))), th = acos(c), sn = sin(th);
  if (!(lim > 0 && th > lim)) return;
  bool fade = lim <= 0.5 * M_PI && th > 0.75 * M_PI;
  if (!(sn > 1e-6)) { /* d opposite w: no great circle to clamp along; a fade allows none */
    if (fade) memcpy(d, w, 3 * sizeof(double));
    return;
  }
  double s = fade ? lim * (M_PI - th) / (0.25 * M_PI) : lim;
  double a0 = sin(th - s) / sn, a1 = sin(s) / sn;
  for (int i = 0; i < 3; ++i)
    d[i] = a0 * w[i] + a1 * d[i];
  km__normalize3(d);
}

/* An elbow's or knee's anatomical bend limit (kinect1 "bend_limit" wider than 90 degrees, an
 * upright body's 150): the forearm or shin a -> b is held within bend_limit of the straight
 * limb, the direction its parent bone (par[a] -> a, turned by Rp) points in now; true when it
 * was applied (the bone's other limit is then the rig's "swing_limit" alone). Measured from
 * where the parent carries the character's rest forearm instead (clamp_swing's w), the limit
 * was the bend only on a straight-armed rest pose: the armadillo's elbows are bent 50 degrees
 * at rest, so the performer's 142-degree elbow on precog_Seq1_1 (frames 114-116) swung its
 * forearm about 170 degrees from the carried rest direction, where the clamp's great circle
 * turns quickly with d, and the clamped forearm swept 17 degrees a frame while the
 * performer's turned 4: the hand stepped 10-12 cm (15 % of the diagonal) with the performer's
 * wrist still. Narrower bend limits (a quadruped's 20) are swings from the rest shape and
 * stay with clamp_swing's w. */
static bool hinge_bend(const km_retarget *r, int32_t a, int32_t b, const double Rp[9],
                       double d[3]) {
  if (!r->kinect1 || !(r->bend_limit > 0.5 * M_PI) || !r->jrest) return false;
  if (!kinect1_hinge(b) || r->par[a] < 0) return false;
  const double *pa = r->jrest + 3 * (size_t)a, *pp = r->jrest + 3 * (size_t)r->par[a];
  double s0[3] = {pa[0] - pp[0], pa[1] - pp[1], pa[2] - pp[2]}, s[3];
  if (!(km__normalize3(s0) > 1e-12)) return false;
  km__m3_apply(Rp, s0, s);
  clamp_swing(s, r->bend_limit, d);
  return true;
}

/* The shortest rotation taking the reference direction of a -> b to this frame's (in the
 * root's heading frame under rigid root motion); false when a joint is not valid.
 * aim (the character's rest direction of the segment) with Rp (the rotation of the bone the
 * segment hangs from): R = (Rp aim -> current direction) Rp, the parent's rotation and then the
 * shortest swing onto the performer's direction, so the segment turns about its joint without
 * twisting against its parent (the forward kinematics of km_skeleton_pose_from_positions).
 * Composing two shortest arcs instead, (reference -> current)(aim -> reference), gives each
 * limb bone a twist of its own that depends on the path through the first frame's direction:
 * an upper arm and forearm twisted apart wring the elbow between their handles (bench motion,
 * character on cmu_131_01: the elbows stretched 0.9 from the first frame on). aim without Rp:
 * that composition (a segment with no parent rotation). */
static bool segment_rotation(const km_retarget *r, const double *J, int32_t a, int32_t b,
                             const double *aim, const double *Rp, double R[9]) {
  double d[3], d0[3];
  if (!segment_dirs(r, J, a, b, d0, d)) return false;
  if (aim) {
    double u[3] = {aim[0], aim[1], aim[2]}, nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (nu > 1e-12) {
      for (int c = 0; c < 3; ++c)
        u[c] /= nu;
      double A[9], B[9];
      if (Rp) { /* R = (Rp u -> d) Rp */
        double w[3];
        km__m3_apply(Rp, u, w);
        bool bent = hinge_bend(r, a, b, Rp, d);
        clamp_swing(w, bent ? r->swing_limit : limb_limit(r, b, true), d);
        km__rot3_between(w, d, A);
        km__m3_mul(A, Rp, R);
        return true;
      }
      km__rot3_between(u, d0, A); /* first the character's rest direction onto the reference */
      km__rot3_between(d0, d, B);
      km__m3_mul(B, A, R);
      return true;
    }
  }
  /* A bone turned by its rotation since the first frame (the torso's, the neck and head): the
   * swing limit from where its parent carries that first direction. A quadruped's rig (limit
   * 30) otherwise bent its neck as far as the performer's head tilts: dog0's neck squeezed to
   * 0.34 of its length (bench motion B, stretch max before -> after: dog0 on precog_Seq1_1
   * 0.66 -> 0.59, cmu_131_01 0.56 -> 0.52, the horse on precog_Seq1_1 0.95 -> 0.90; no row
   * worse). A kinect1 shoulder or hip bone is held to "girdle_limit" (limb_limit). */
  double lim = limb_limit(r, b, false);
  if (Rp && lim > 0) {
    double w[3];
    km__m3_apply(Rp, d0, w);
    clamp_swing(w, lim, d);
  }
  km__rot3_between(d0, d, R);
  return true;
}

/* Kinect v1 limb bones (ending at an elbow, wrist, hand, knee, ankle or foot): aimed along the
 * performer's bone (see km_retarget_create); the torso's bones turn relatively. */
static bool kinect1_limb(size_t j) {
  return (j >= 5 && j <= 7) || (j >= 9 && j <= 11) || (j >= 13 && j <= 15) || j >= 17;
}

/* apply_twist with joint j's given rotation about the segment a -> b (walked up to an
 * ancestor while shorter than 0.15 m, as for the swing: a Kinect wrist -> hand twists about
 * the forearm) in this frame's direction (the root's heading frame under rigid root motion). */
static void twist(const km_retarget *r, const double *J, int32_t j, int32_t a, int32_t b,
                  double R[9]) {
  if (!r->jrot) return;
  a = long_ancestor(r, a, b);
  double d[3], d0[3];
  if (!segment_dirs(r, J, a, b, d0, d)) return;
  apply_twist(r, j, d0, d, R);
}

/* Bone speed limit (issue 12, the one-frame jumps on the Kinect takes). The direction of the
 * performer's bone q -> j is measured from filtered joint positions, and a Kinect bone often
 * measures much shorter than it is: the forearm collapses to 8-14 cm of its 22 when the hand
 * passes in front of the elbow, and a filtered wrist that flips from below the elbow to above
 * it passes close to it, so the measured direction swings 50-130 degrees in a frame while the
 * wrist moves 10-30 cm (precog_Seq1_1 frames 147-149 and 179; an upper arm flips 77-126
 * degrees where the tracker re-fits the elbow, precog_Seq3_2 frame 192). The character's bone
 * keeps its length, so its end and the hand handle swept 3x farther than the performer's
 * wrist moved: 19 % of the character's diagonal in one frame against 7 % for the wrist.
 * Per push a bone's direction turns at most
 *   theta_max = min(2 asin((|u - u'| + c) / (2 tol blen)), max_turn / fps * min(1, |u| / (tol
 * blen))) u, u': the performer's bone this push and the last; blen: its running mean length (about
 * two seconds); tol = KM_BONE_LEN_TOL; c = bone_catchup / fps while the bone lags behind a
 * turn held back before, else 0. The first term: as far as a bone of the performer's usual
 * length must turn for its end to move what the performer's bone end moved relative to its
 * start (a real swing of a full-length bone turns 2 asin(|u - u'| / (2 |u|)), within it); the
 * second: at most KM_BONE_MAX_TURN deg/s (the clean CMU takes turn a shin just under 40
 * degrees in a frame at 30 fps, a forearm 33, the kung-fu demo 24; the Kinect re-fits of
 * precog_Seq2_1 frames 21-24 swing a full-length thigh 44-52), less for a bone measuring
 * shorter than tol of its usual length (a collapsed bone's direction is noise). The rest of a
 * turn held back follows over the next pushes. Neither term touches the CMU takes, walk, wave
 * or the demo on the character or the armadillo (no push limited). Rprev: the bone's rotation
 * of the last push; R in / out. */
static void limit_bone(km_retarget *r, const double *J, int32_t q, int32_t j, const double Rprev[9],
                       double R[9]) {
  const double *p = J + 3 * (size_t)j, *pq = J + 3 * (size_t)q;
  if (r->bone_catchup < 0) return;
  if (!km__finite3(p) || !km__finite3(pq)) {
    r->bhave[j] = false;
    return;
  }
  double u[3] = {p[0] - pq[0], p[1] - pq[1], p[2] - pq[2]};
  if (r->rigid) { /* R_y(-phi) u, as segment_dirs */
    double c = r->cos_h, sn = r->sin_h, x = u[0], z = u[2];
    u[0] = c * x - sn * z;
    u[2] = sn * x + c * z;
  }
  double len = sqrt(km__dot3(u, u)), *bv = r->bvec + 3 * (size_t)j;
  bool lag = r->blag[j];
  r->blag[j] = false;
  if (!r->bhave[j]) {
    memcpy(bv, u, sizeof u);
    r->blen[j] = len;
    r->bhave[j] = true;
    return;
  }
  double du[3];
  km__sub3(u, bv, du);
  double step = sqrt(km__dot3(du, du));
  memcpy(bv, u, sizeof u);
  r->blen[j] += (1 - exp(-0.5 / r->fps)) * (len - r->blen[j]);
  if (!(r->blen[j] > 1e-6)) return;
  /* the character's bone direction before and after this push */
  double w[3];
  if (r->jrest && km__finite3(r->jrest + 3 * (size_t)j) && km__finite3(r->jrest + 3 * (size_t)q))
    km__sub3(r->jrest + 3 * (size_t)j, r->jrest + 3 * (size_t)q, w);
  else if (km__finite3(r->ref + 3 * (size_t)j) && km__finite3(r->ref + 3 * (size_t)q))
    km__sub3(r->ref + 3 * (size_t)j, r->ref + 3 * (size_t)q, w);
  else
    return;
  double a[3], b[3];
  km__m3_apply(Rprev, w, a);
  km__m3_apply(R, w, b);
  double na = sqrt(km__dot3(a, a)), nb = sqrt(km__dot3(b, b));
  if (!(na > 1e-12) || !(nb > 1e-12)) return;
  for (int c = 0; c < 3; ++c) {
    a[c] /= na;
    b[c] /= nb;
  }
  double cs = fmax(-1.0, fmin(1.0, km__dot3(a, b))), theta = acos(cs);
  double x = (step + (lag ? r->bone_catchup : 0)) / (2 * KM_BONE_LEN_TOL * r->blen[j]);
  double cap =
      KM_BONE_MAX_TURN * M_PI / 180 / r->fps * fmin(1, len / (KM_BONE_LEN_TOL * r->blen[j]));
  double tmax = fmin(x >= 1 ? M_PI : 2 * asin(x), cap);
  if (!(theta > tmax + 1e-6)) return; /* a still bone: rounding */
  r->blag[j] = true;
  /* d: a turned by tmax towards b; then R <- (b -> d) R */
  double e[3] = {b[0] - cs * a[0], b[1] - cs * a[1], b[2] - cs * a[2]};
  double ne = sqrt(km__dot3(e, e));
  if (!(ne > 1e-9)) { /* b opposite a: no plane to turn in; keep the last rotation */
    memcpy(R, Rprev, 9 * sizeof(double));
    return;
  }
  double d[3], A[9];
  for (int c = 0; c < 3; ++c)
    d[c] = cos(tmax) * a[c] + sin(tmax) * e[c] / ne;
  km__rot3_between(b, d, A);
  km__m3_mul(A, R, R);
}

/* The rigid root is lifted so that no ankle (nor a quadruped's wrist: one whose rest height is
 * under 0.15 of the character's) of the posed character is below its rest height:
 * the body rises rather than a foot going through the floor, as a retargeter adjusts the
 * pelvis. The root follows the performer's hips and the legs their directions, and the two
 * disagree whenever the performer's measured legs are shorter than in the first frame (a
 * Kinect knee or ankle a few centimetres off) or bend otherwise than the character's legs can:
 * the character's feet went through the floor. bench motion B, frames with a vertex below the
 * rest floor (Kinect takes; CMU takes), before -> after: armadillo 137/43/89; 268/134 ->
 * 20/31/26; 227/112, elephant 38/16/3 -> 0/0/0, character 41/16/3 -> 0/0/0, dog0 (its front
 * paws too) 80/37/60; 430/417 -> 16/2/23; 78/87; no other column moved. */
static void lift_root(km_retarget *r) {
  if (!r->rigid || !r->jrest || !r->kinect1 || r->n_joints < KM_KINECT1_JOINTS) return;
  double lift = 0;
  static const int ends[4] = {14, 18, 6, 10}; /* ankles; wrists where they are a paw's */
  for (int k = 0; k < 4; ++k) {
    const double *A0 = r->jrest + 3 * ends[k], *A = r->C + 3 * ends[k];
    if (!km__finite3(A0) || !km__finite3(A)) continue;
    if (k >= 2 && !(A0[1] - r->floor_y < 0.15 * r->mesh_height)) continue;
    double need = A0[1] - (A[1] + r->t[1]);
    if (need > lift) lift = need;
  }
  r->t[1] += lift;
}

/* A foot on the ground stands flat (an upright body's, below): its handle's rotation R (about
 * the ankle) loses its tilt,
 * keeping its turn about y (the twist about y of R's swing-twist decomposition), in full while
 * the posed ankle is at or below its rest height (with the rigid root's translation), fading
 * out as the ankle rises by its own rest height above the floor. A performer's foot, measured from
 * a tracker's ankle and toe joints, tilts 10-30 degrees when it is flat on the floor (a shoe's
 * sole, a toe joint at the ball of the foot), and the character's foot turned with it: the rim of a
 * round foot dipped under the floor. bench motion B, frames with a vertex below the rest floor, CMU
 * takes: elephant 760 / 1026 -> 95 / 0 (of 994 / 1102), character 360 / 664 -> 66 / 39, armadillo
 * 528 / 687 -> 268 / 134; a flat foot whose ankle is lower than at rest is under the floor whole
 * (the armadillo's Kinect takes 72 / 24 / 8 -> 137 / 43 / 89), which lift_root answers. The turn
 * about y was first taken from the foot's direction (ankle -> foot) seen from above, which spins
 * where the posed foot points nearly straight down: the elephant's stubby foot (41 degrees from
 * vertical at rest) under "swing_limit" 30 flipped its heading in one frame, a one-frame jump
 * of 11.4 % of the diagonal on cmu_131_01 (1.7 % with the twist). */
static void flatten_foot(const km_retarget *r, int32_t ankle, double R[9]) {
  /* an upright body's feet only: a horse's hoof held flat while its cannon swung bent the
   * fetlock (bench motion B on cmu_131_01: stretch max 0.73 -> 0.98, 64 folded triangles) */
  if (!r->upright) return;
  const double *A0 = r->jrest + 3 * (size_t)ankle, *A = r->C + 3 * (size_t)ankle;
  if (!km__finite3(A0) || !km__finite3(A)) return;
  double ha = A0[1] - r->floor_y; /* the ankle's rest height above the floor */
  if (!(ha > 0) || !(ha < 0.15 * r->mesh_height)) return;
  double rise = A[1] + (r->rigid ? r->t[1] : 0) - A0[1];
  double w = fmax(0, fmin(1, 1 - rise / ha));
  if (!(w > 0)) return;
  /* R = S T: T the twist about y (the quaternion's w and y parts), S a swing about a
   * horizontal axis; undefined only for a half turn about a horizontal axis (w = y = 0) */
  double q[4];
  km__quat_from_rot3(R, q);
  if (!(hypot(q[0], q[2]) > 1e-9)) return;
  double phi = 2 * atan2(q[2], q[0]), c = cos(phi), sn = sin(phi);
  double Ry[9] = {c, 0, sn, 0, 1, 0, -sn, 0, c};
  /* The flattening turns the foot at most 30 degrees off its shin's rotation: a foot held flat
   * under a shin leaning far over it (a lunge) bent the ankle more than the free skin between
   * the foot handle and the shin band (3.4 cm on the armadillo, whose foot handle reaches above
   * its ankle joint) can take. bench motion B, armadillo, longest edge l/l0, the table's take
   * order: 1.763/2.144/1.784/1.972/1.846 -> 1.745/2.144/1.784/1.829/1.737 (the front of the
   * ankle); frames with a vertex below the floor 0/0/0/244/93 -> 1/0/0/244/93, the character's
   * 0 -> 1 on precog_Seq1_1 and otherwise the same, the elephant's unchanged. 20 degrees: 1.727
   * and 1.811 / 1.737 but the elephant's foot under the floor in 17 frames of cmu_131_01. */
  double ang = km__rot3_angle_between(R, Ry), cap = 30 * M_PI / 180;
  if (ang * w > cap) w = cap / ang;
  km__rot3_slerp(R, Ry, w, R);
}

/* "local_turn": M, the shortest turn from the performer's bone a -> b as first seen (the
 * reference) onto the character's at rest; a rotation G of the performer's bone is taken as
 * M G M^T about the character's. False (M unset) while either is unknown or degenerate. */
static bool local_frame(const km_retarget *r, int32_t a, int32_t b, double M[9]) {
  if (!r->local_turn || a < 0 || b < 0) return false;
  const double *p = r->ref + 3 * (size_t)b, *q = r->ref + 3 * (size_t)a;
  const double *c = r->jrest + 3 * (size_t)b, *c0 = r->jrest + 3 * (size_t)a;
  if (!km__finite3(p) || !km__finite3(q) || !km__finite3(c) || !km__finite3(c0)) return false;
  double u[3], w[3];
  km__sub3(p, q, u);
  km__sub3(c, c0, w);
  if (!(km__normalize3(u) > 1e-9) || !(km__normalize3(w) > 1e-9)) return false;
  km__rot3_between(u, w, M);
  return true;
}

/* R <- M R M^T */
static void conjugate(const double M[9], double R[9]) {
  double T[9];
  km__m3_mul(M, R, T);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      R[3 * i + j] =
          T[3 * i] * M[3 * j] + T[3 * i + 1] * M[3 * j + 1] + T[3 * i + 2] * M[3 * j + 2];
}

/* Bone rotations, the character's posed joints (forward kinematics) and the bone handles'
 * rigid motions (see km_retarget_create in kinemesh.h). A bone whose joints are not valid this
 * frame keeps its last rotation; a root that is not valid keeps its last position. */
static void update_bones(km_retarget *r, const double *J) {
  if (!isfinite(r->scale)) return;
  const double s = r->scale;
  for (size_t j = 0; j < r->n_joints; ++j) {
    int32_t q = r->par[j];
    double *Rj = r->Rb + 9 * j, *Cj = r->C + 3 * j;
    if (q < 0) {
      const double *p = J + 3 * j, *p0 = r->ref + 3 * j;
      if (r->jrest && km__finite3(p) && km__finite3(p0))
        for (int d = 0; d < 3; ++d)
          Cj[d] = r->jrest[3 * j + d] + (r->rigid ? 0 : s * (p[d] - p0[d]));
      continue;
    }
    /* A short bone (Kinect wrist -> hand, ankle -> foot: a few noisy centimetres) turns with
     * its parent bone. */
    double aim[3], *ap = NULL;
    if (r->aim && r->kinect1 && kinect1_limb(j)) {
      for (int d = 0; d < 3; ++d)
        aim[d] = r->jrest[3 * j + d] - r->jrest[3 * (size_t)q + d];
      if (isfinite(aim[0] + aim[1] + aim[2])) ap = aim;
    }
    if (short_bone(r, (int32_t)j, q)) {
      memcpy(Rj, r->Rb + 9 * (size_t)q, 9 * sizeof(double));
    } else {
      double Rprev[9];
      memcpy(Rprev, Rj, sizeof Rprev);
      segment_rotation(r, J, q, (int32_t)j, ap, r->Rb + 9 * (size_t)q, Rj);
      limit_bone(r, J, q, (int32_t)j, Rprev, Rj);
    }
    if (r->jrest) {
      const double *cj0 = r->jrest + 3 * j, *cq0 = r->jrest + 3 * (size_t)q;
      double w[3] = {cj0[0] - cq0[0], cj0[1] - cq0[1], cj0[2] - cq0[2]}, y[3];
      km__m3_apply(Rj, w, y);
      for (int d = 0; d < 3; ++d)
        Cj[d] = r->C[3 * (size_t)q + d] + y[d];
    }
  }
  lift_root(r);
  for (size_t h = 0; h < r->n_handles; ++h) {
    int32_t a = r->bone_from[h], b = r->rot_joint[h];
    if (a < 0) continue;
    double *R = r->rot + 9 * h, *disp = r->disp + 3 * h;
    const double *c = r->centroid + 3 * h;
    /* A segment over several bones (elbow -> hand, knee -> foot, the rings' shoulder -> wrist)
     * turns about the joint its end bone hangs from (the wrist, the ankle, the elbow), posed by
     * the chain between, so it meets the handles before it there, with the rotation half-way
     * between that joint's bone and the end bone (slerp): a hand or foot turns with its own
     * bone (a short Kinect one turns with the forearm or shin), a ring with half the elbow's
     * bend. Turned about a and aimed along a -> b instead, a foot left the ankle 6.5 cm off the
     * shin's (bench motion, character on cmu_131_01, frame 0), and a ring spun with the short,
     * noisy shoulder -> wrist line of a folded elbow (elephant on precog_Seq1_1: one-frame jump
     * 11 -> 35 % of the diagonal). */
    int32_t pv = a;
    if (r->jrest && r->par[b] != a && r->par[b] >= 0) {
      int32_t q = r->par[b];
      while (q >= 0 && q != a)
        q = r->par[q];
      if (q == a && km__finite3(r->C + 3 * (size_t)r->par[b]) &&
          km__finite3(r->jrest + 3 * (size_t)r->par[b]))
        pv = r->par[b];
    }
    if (r->par[b] == a) {
      memcpy(R, r->Rb + 9 * (size_t)b, 9 * sizeof(double));
      twist(r, J, b, a, b, R);
    } else if (pv != a) {
      km__rot3_slerp(r->Rb + 9 * (size_t)pv, r->Rb + 9 * (size_t)b, 0.5, R);
      twist(r, J, b, a, b, R);
    } else { /* no character skeleton: aimed like the limb it is in */
      double aim[3], *ap = NULL;
      if (r->aim && r->kinect1 && kinect1_limb((size_t)b)) {
        for (int d = 0; d < 3; ++d)
          aim[d] = r->jrest[3 * (size_t)b + d] - r->jrest[3 * (size_t)a + d];
        if (isfinite(aim[0] + aim[1] + aim[2])) ap = aim;
      }
      segment_rotation(r, J, a, b, ap, r->Rb + 9 * (size_t)a, R);
      twist(r, J, b, a, b, R);
    }
    if (r->kinect1 && r->aim && (b == 15 || b == 19) && pv != a) flatten_foot(r, pv, R);
    double M[9];
    if (local_frame(r, a, b, M)) {
      /* the performer's turn about the character's own bone, about its start at rest: the
       * chain above (a performer's spine, upright) says nothing of where a body lying down
       * holds its neck */
      conjugate(M, R);
      const double *p0 = r->jrest + 3 * (size_t)a;
      double w[3], y[3];
      km__sub3(c, p0, w);
      km__m3_apply(R, w, y);
      for (int d = 0; d < 3; ++d)
        disp[d] = p0[d] + y[d] - c[d];
      goto floor;
    }
    double rel[3] = {0, 0, 0};
    if (r->bone_rel[h] > 0) {
      const double *q = J + 3 * (size_t)(r->bone_rel[h] - 1),
                   *q0 = r->ref + 3 * (size_t)(r->bone_rel[h] - 1);
      if (!km__finite3(q) || !km__finite3(q0)) continue;
      if (!(r->rigid && r->bone_rel[h] - 1 == r->root))
        for (int d = 0; d < 3; ++d)
          rel[d] = s * (q[d] - q0[d]);
    }
    const double *Ca = r->C + 3 * (size_t)pv;
    if (r->jrest && km__finite3(Ca) && km__finite3(r->jrest + 3 * (size_t)pv)) {
      /* x -> C_pv - rel + R (x - C^0_pv), written as the centroid's displacement */
      double w[3], y[3];
      for (int d = 0; d < 3; ++d)
        w[d] = c[d] - r->jrest[3 * (size_t)pv + d];
      km__m3_apply(R, w, y);
      for (int d = 0; d < 3; ++d)
        disp[d] = Ca[d] - rel[d] + y[d] - c[d];
    } else { /* no character skeleton: about the centroid, with the bone's midpoint */
      const double *p = J + 3 * (size_t)b, *q = J + 3 * (size_t)a;
      const double *p0 = r->ref + 3 * (size_t)b, *q0 = r->ref + 3 * (size_t)a;
      if (!km__finite3(p) || !km__finite3(q) || !km__finite3(p0) || !km__finite3(q0)) continue;
      for (int d = 0; d < 3; ++d)
        disp[d] = 0.5 * s * (p[d] + q[d] - p0[d] - q0[d]) - rel[d];
    }
  floor:
    if (r->floor_dy) { /* no vertex of the turned handle below the rest floor */
      double ymin = INFINITY;
      for (size_t k = r->hv_start[h]; k < r->hv_start[h + 1]; ++k) {
        const double *x = r->hv_rest + 3 * k;
        double y = R[3] * (x[0] - c[0]) + R[4] * (x[1] - c[1]) + R[5] * (x[2] - c[2]);
        ymin = fmin(ymin, c[1] + disp[1] + y);
      }
      if (r->rigid) ymin += r->t[1]; /* the root's translation lowers it too */
      if (ymin < r->floor_y) disp[1] += r->floor_y - ymin;
    }
  }
}

void km_retarget_vertex_targets(const km_retarget *r, double *out) {
  for (size_t h = 0; h < r->n_handles; ++h) {
    const double *R = r->rot && r->rot_joint[h] >= 0 ? r->rot + 9 * h : NULL;
    const double *c = r->centroid + 3 * h;
    for (size_t k = r->hv_start[h]; k < r->hv_start[h + 1]; ++k) {
      const double *x = r->hv_rest + 3 * k;
      if (!R) {
        for (int a = 0; a < 3; ++a)
          out[3 * k + a] = x[a] + r->disp[3 * h + a];
        continue;
      }
      double w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
      for (int a = 0; a < 3; ++a)
        out[3 * k + a] =
            c[a] + r->disp[3 * h + a] + R[3 * a] * w[0] + R[3 * a + 1] * w[1] + R[3 * a + 2] * w[2];
    }
  }
}

size_t km_retarget_vertex_count(const km_retarget *r) { return r->n_hv; }
const double *km_retarget_rest_centroids(const km_retarget *r) { return r->centroid; }
double km_retarget_scale(const km_retarget *r) { return r->scale; }
size_t km_retarget_eased_frames(const km_retarget *r) { return r->eased; }
void km__retarget_settle(km_retarget *r) {
  r->have_prev = false;
  if (r->bhave) memset(r->bhave, 0, r->n_joints * sizeof(bool)); /* nor held by limit_bone */
}

bool km_retarget_root_transform(const km_retarget *r, double R[9], double t[3], double pivot[3]) {
  if (R) memcpy(R, r->R, sizeof r->R);
  if (t) memcpy(t, r->t, sizeof r->t);
  if (pivot) memcpy(pivot, r->pivot, sizeof r->pivot);
  return r->rigid;
}

bool km_retarget_joints(const km_retarget *r, double *out) {
  if (!r->C || !r->jrest) return false;
  memcpy(out, r->C, r->n_joints * 3 * sizeof(double));
  /* A held joint is where its parent's bone carries it; a bone the map turns keeps its turn
   * (R_j = Rb_j, the world turn its handle takes: a bust's head the performer's, lean
   * included, as animate shows it; about the character's own bone with local_turn). Where the
   * map holds the root and has an anchor (a bust's), a held joint beside a turned bone turns
   * with it (the bust's shoulders with its neck): ShoulderCenter's vertices (the head and neck
   * of the rig's bust skin) follow the fit of its three children's directions, which held
   * still kept it to a third to a half of the head's turn. Parents come first. The handles
   * (and lift_root) keep the take's own bones: animate's mesh is the same either way. */
  if (r->held) {
    double *R = km__malloc(r->n_joints, 9 * sizeof(double));
    if (!R) return false;
    for (size_t j = 0; j < r->n_joints; ++j) {
      int32_t q = r->par[j];
      double *Rj = R + 9 * j, M[9];
      memcpy(Rj, r->Rb + 9 * j, 9 * sizeof(double));
      if (q < 0) continue;
      if (r->held[j]) {
        memcpy(Rj, R + 9 * (size_t)q, 9 * sizeof(double));
        for (size_t c = 0; r->neck_held && c < j; ++c)
          if (r->par[c] == q && !r->held[c]) {
            memcpy(Rj, R + 9 * c, 9 * sizeof(double));
            break;
          }
      } else {
        for (size_t h = 0; r->bone_from && h < r->n_handles; ++h)
          if (r->rot_joint[h] == (int32_t)j && r->bone_from[h] == q && local_frame(r, q, j, M)) {
            conjugate(M, Rj);
            break;
          }
      }
      double w[3], y[3];
      km__sub3(r->jrest + 3 * j, r->jrest + 3 * (size_t)q, w);
      km__m3_apply(Rj, w, y);
      for (int d = 0; d < 3; ++d)
        out[3 * j + d] = out[3 * (size_t)q + d] + y[d];
    }
    free(R);
  }
  km_retarget_apply_root(r, out, r->n_joints);
  /* The handles take the root's travel off their motion (every entry relative to it): so do
   * the joints, each by its own root's. */
  for (size_t k = 0; r->root_fixed && k < r->n_joints; ++k) {
    int32_t q = (int32_t)k;
    while (r->par[q] >= 0)
      q = r->par[q];
    const double *c = r->C + 3 * (size_t)q, *c0 = r->jrest + 3 * (size_t)q;
    if (km__finite3(c) && km__finite3(c0))
      for (int d = 0; d < 3; ++d)
        out[3 * k + d] -= c[d] - c0[d];
  }
  return true;
}

bool km_retarget_floor(const km_retarget *r, double *floor_y) {
  if (!r || !r->floor_dy) return false;
  if (floor_y) *floor_y = r->floor_y;
  return true;
}

bool km_retarget_apply_root(const km_retarget *r, double *points, size_t n) {
  if (!r->rigid) return false;
  const double *R = r->R, *pv = r->pivot, *t = r->t;
  for (size_t v = 0; v < n; ++v) {
    double *x = points + 3 * v, w[3] = {x[0] - pv[0], x[1] - pv[1], x[2] - pv[2]};
    for (int a = 0; a < 3; ++a)
      x[a] = R[3 * a] * w[0] + R[3 * a + 1] * w[1] + R[3 * a + 2] * w[2] + pv[a] + t[a];
  }
  return true;
}
