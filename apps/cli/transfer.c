/* kinemesh transfer: avatar pose transfer (Lifkooee et al. 2019): the source takes the
 * template's pose (same connectivity).
 *   kinemesh transfer --source S --template T -o OUT   (or SOURCE TEMPLATE positionally)
 * Landmarks come from --landmarks LM.json or the mesh's rig sidecar (<stem>.rig.json). */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* --correspondences FILE: one pair of vertex ids a line, "source_vertex,template_vertex"
 * (blank lines and lines starting with '#' skipped). *pairs allocated (2 per pair). */
static int read_pairs(const char *path, size_t ns, size_t nt, int32_t **pairs, size_t *np) {
  FILE *f = fopen(path, "r");
  if (!f) return km_cli_error("transfer", "%s: %s", path, strerror(errno));
  char line[512];
  size_t cap = 0, ln = 0;
  int rc = KM_EXIT_OK;
  *pairs = NULL;
  *np = 0;
  while (fgets(line, sizeof line, f)) {
    ++ln;
    char *p = line;
    while (*p == ' ' || *p == '\t')
      ++p;
    if (*p == '#' || *p == '\n' || *p == '\r' || !*p) continue;
    char *end;
    errno = 0;
    long a = strtol(p, &end, 10), b = -1;
    bool ok = end != p && !errno;
    if (ok) {
      while (*end == ' ' || *end == '\t')
        ++end;
      ok = *end == ',';
    }
    if (ok) {
      p = end + 1;
      b = strtol(p, &end, 10);
      ok = end != p && !errno;
      while (ok && (*end == ' ' || *end == '\t' || *end == '\r' || *end == '\n'))
        ++end;
      ok = ok && !*end;
    }
    if (!ok) {
      rc = km_cli_error("transfer",
                        "%s:%zu: expected \"source_vertex,template_vertex\" (two integers)", path,
                        ln);
      break;
    }
    if (a < 0 || (size_t)a >= ns || b < 0 || (size_t)b >= nt) {
      rc = km_cli_error("transfer",
                        "%s:%zu: pair (%ld, %ld) out of range: SOURCE has %zu vertices, the "
                        "template %zu",
                        path, ln, a, b, ns, nt);
      break;
    }
    if (*np == cap) {
      size_t nc = cap ? 2 * cap : 64;
      int32_t *q = realloc(*pairs, nc * 2 * sizeof *q);
      if (!q) {
        rc = km_cli_error("transfer", "out of memory");
        break;
      }
      *pairs = q;
      cap = nc;
    }
    (*pairs)[2 * *np] = (int32_t)a;
    (*pairs)[2 * *np + 1] = (int32_t)b;
    ++*np;
  }
  fclose(f);
  if (rc) {
    free(*pairs);
    *pairs = NULL;
    *np = 0;
  }
  return rc;
}

int km_cli_transfer(int argc, char **argv) {
  const char *out = NULL, *lm_path = NULL, *encoding = "edge", *laplacian = "uniform",
             *align = "scale", *source = NULL, *templ = NULL, *xyz = NULL, *trest = NULL,
             *corr_path = NULL, *reg_mode = "similarity";
  int iterations = 0;
  double damping = 0;
  size_t xyz_frame = 0;
  km_cli_frame_opts fo = {0};
  const km_cli_opt opts[] = {
      /* KM_CLI_FRAME_OPTIONS's entries, but transfer never guesses */
      {"up", 0, KM_OPT_STRING, &fo.up,
       "SOURCE's up axis: +x -x +y -y +z -z (default: its rig sidecar's \"frame\", else as it is)"},
      {"forward", 0, KM_OPT_STRING, &fo.forward,
       "the axis SOURCE faces (default: its rig sidecar's \"frame\", else as it is)"},
      {"units", 0, KM_OPT_STRING, &fo.units,
       "SOURCE's units: m (default), cm, mm, in, ft, or metres per unit"},
      {"source", 's', KM_OPT_STRING, &source, "the avatar mesh S"},
      {"template", 't', KM_OPT_STRING, &templ, "the posed template T (same connectivity as S)"},
      {"output", 'o', KM_OPT_STRING, &out, "output mesh (.obj/.ply/.off)"},
      {"template-rest", 0, KM_OPT_STRING, &trest,
       "TEMPLATE at rest (its connectivity): needed when TEMPLATE's mesh differs from SOURCE's; "
       "SOURCE is first registered onto TR (a similarity) from --correspondences or from the "
       "landmarks of one name in both rigs, then each of its vertices takes the rotation of "
       "its nearest TR vertex"},
      {"register", 0, KM_OPT_STRING, &reg_mode,
       "with --template-rest: similarity (default), nonrigid (then the reconstruction's "
       "non-rigid registration onto TR, for the correspondence), or none (SOURCE and TR in one "
       "frame at one size)"},
      {"correspondences", 0, KM_OPT_STRING, &corr_path,
       "with --template-rest: vertex pairs for the registration, a line \"source_vertex,"
       "template_vertex\" each (at least 3; default: landmarks of one name in SOURCE's and "
       "TR's rigs)"},
      {"landmarks", 'l', KM_OPT_STRING, &lm_path,
       "LM.json with the landmark vertices (default: SOURCE's rig sidecar), or auto[:K]: K "
       "(default 16) vertices spread by farthest-point sampling, for any mesh"},
      {"landmarks-xyz", 0, KM_OPT_STRING, &xyz,
       "tracked landmark positions (a track .json/.csv, names as in the landmarks) as the "
       "targets, instead of TEMPLATE's landmarks"},
      {"frame", 0, KM_OPT_SIZE, &xyz_frame, "frame of --landmarks-xyz (default 0)"},
      {"iterations", 'i', KM_OPT_INT, &iterations,
       "maximum solves (default 4; 10 with --encoding vertex); each lowers the energy printed"},
      {"damping", 0, KM_OPT_DOUBLE, &damping,
       "pull of each one-ring's stretch towards none (default 0.3; negative: none)"},
      {"encoding", 0, KM_OPT_STRING, &encoding,
       "edge (default) or vertex (the paper's eq. 3 verbatim)"},
      {"laplacian", 0, KM_OPT_STRING, &laplacian, "uniform (default, eq. 2) or cotan"},
      {"align", 0, KM_OPT_STRING, &align,
       "scale (default: TEMPLATE's landmarks scaled to SOURCE's size), similarity, or none "
       "(TEMPLATE's landmarks as they are: the same person in another pose)"},
  };
  const char *pos[2];
  int n_pos;
  int r =
      km_cli_parse(argc, argv, opts, sizeof opts / sizeof opts[0], pos, 2, &n_pos,
                   "kinemesh transfer --source S --template T [--template-rest TR] -o OUT "
                   "[--landmarks LM.json]",
                   "SOURCE (the avatar) takes the pose of TEMPLATE (same connectivity) by\n"
                   "locally encoded Laplacian offsets; landmark vertices follow TEMPLATE's,\n"
                   "scaled to SOURCE's size. SOURCE is brought into kinemesh's frame (y up,\n"
                   "facing +z, metres) by --up/--forward/--units or its rig sidecar's\n"
                   "\"frame\" (never guessed: without them it stays as it is), TEMPLATE of its\n"
                   "connectivity with it; TEMPLATE-REST and its TEMPLATE by TR's sidecar's\n"
                   "\"frame\". OUT is in SOURCE's frame so brought in.");
  if (r <= 0) return r < 0 ? KM_EXIT_USAGE : KM_EXIT_OK;
  if (source && n_pos < 2) pos[n_pos++] = source;
  if (templ && n_pos < 2) pos[n_pos++] = templ;
  if (n_pos != 2) return km_cli_error("transfer", "expected --source S and --template T");
  if (!out) return km_cli_error("transfer", "-o OUTPUT is required");
  km_transfer_options to = {0};
  to.max_iterations = iterations;
  to.damping = damping;
  if (!strcmp(encoding, "vertex"))
    to.encoding = KM_OFFSETS_VERTEX;
  else if (strcmp(encoding, "edge"))
    return km_cli_error("transfer", "--encoding must be edge or vertex, not '%s'", encoding);
  if (!strcmp(laplacian, "cotan"))
    to.laplacian = KM_LAPLACIAN_COTAN;
  else if (strcmp(laplacian, "uniform"))
    return km_cli_error("transfer", "--laplacian must be uniform or cotan, not '%s'", laplacian);
  if (!strcmp(align, "similarity"))
    to.align = KM_TRANSFER_ALIGN_SIMILARITY;
  else if (!strcmp(align, "none"))
    to.align = KM_TRANSFER_ALIGN_NONE;
  else if (strcmp(align, "scale"))
    return km_cli_error("transfer", "--align must be scale, similarity or none, not '%s'", align);
  km_error err = {0};
  km_mesh s = {0}, t = {0}, o = {0}, tr_rest = {0};
  int32_t *corr = NULL, *pairs = NULL;
  double *registered = NULL, *nonrigid_V = NULL, *local = NULL;
  size_t n_pairs = 0;
  double *rots = NULL;
  km_transfer *tr = NULL;
  km_track trk = {0};
  km_landmark *lm = NULL;
  int32_t *ids = NULL;
  double *targets = NULL;
  size_t nl = 0, auto_k = 0;
  int rc = KM_EXIT_OK;
  bool auto_lm = lm_path && !strncmp(lm_path, "auto", 4);
  if (auto_lm) {
    const char *k = lm_path + 4;
    char *end = NULL;
    long v = *k == ':' ? strtol(k + 1, &end, 10) : 16;
    if ((*k && *k != ':') || (*k == ':' && (end == k + 1 || *end)) || v < 3)
      return km_cli_error("transfer", "--landmarks auto:K needs K >= 3, not '%s'", lm_path);
    auto_k = (size_t)v;
  }
  if (xyz && auto_lm)
    return km_cli_error("transfer", "--landmarks-xyz needs named landmarks (LM.json or the rig), "
                                    "not --landmarks auto");
  if (corr_path && !trest)
    return km_cli_error("transfer", "--correspondences goes with --template-rest TR");
  bool nonrigid = !strcmp(reg_mode, "nonrigid"), no_reg = !strcmp(reg_mode, "none");
  if (!nonrigid && !no_reg && strcmp(reg_mode, "similarity"))
    return km_cli_error("transfer", "--register must be similarity, nonrigid or none, not '%s'",
                        reg_mode);
  if (km_mesh_read(pos[0], &s, &err) || km_mesh_read(pos[1], &t, &err)) {
    rc = km_cli_fail("transfer", &err);
    goto done;
  }
  /* SOURCE's frame: said, or recorded by its rig; never guessed (transfer turns with its
   * meshes, and a source in another frame than TR is registered onto it). TEMPLATE of
   * SOURCE's connectivity (a posed copy) shares it; with --template-rest, TR's rig's record
   * is TR's and TEMPLATE's frame. */
  km_frame fr;
  fo.no_guess = true;
  if ((rc = km_cli_mesh_frame("transfer", pos[0], &fo, &s, true, &fr, NULL))) goto done;
  bool same = t.n_vertices == s.n_vertices && t.n_faces == s.n_faces &&
              memcmp(t.F, s.F, s.n_faces * 3 * sizeof(int32_t)) == 0;
  if ((!km_frame_is_identity(&fr) && km_mesh_frame_apply(&fr, &s, &err)) ||
      (same && !km_frame_is_identity(&fr) && km_mesh_frame_apply(&fr, &t, &err))) {
    rc = km_cli_fail("transfer", &err);
    goto done;
  }
  /* Transfer takes any number of landmarks (at least 3, at least one vertex free). */
  lm = calloc(s.n_vertices ? s.n_vertices : 1, sizeof *lm);
  ids = calloc(s.n_vertices ? s.n_vertices : 1, sizeof *ids);
  if (!lm || !ids) {
    rc = km_cli_error("transfer", "out of memory");
    goto done;
  }
  if (auto_lm) {
    nl = auto_k;
    if (km_farthest_points(&s, nl, ids, &err)) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
  } else if (km_cli_load_landmarks(lm_path, pos[0], s.n_vertices, lm, s.n_vertices, &nl, &err)) {
    rc = km_cli_fail("transfer", &err);
    if (!lm_path)
      fprintf(stderr, "kinemesh transfer: no landmarks: give --landmarks LM.json, or --landmarks "
                      "auto for a mesh without a rig\n");
    goto done;
  }
  if (!auto_lm && nl < 3) {
    char *rig = lm_path ? NULL : km_cli_rig_path(pos[0]);
    rc = km_cli_error("transfer",
                      "%s: %zu landmark(s); transfer needs at least 3 to fix the avatar's "
                      "rotation",
                      lm_path ? lm_path
                      : rig   ? rig
                              : pos[0],
                      nl);
    free(rig);
    goto done;
  }
  if (!same && trest) {
    km_cli_frame_opts tfo = {.no_guess = true};
    km_frame tf;
    if (km_mesh_read(trest, &tr_rest, &err)) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
    if ((rc = km_cli_mesh_frame("transfer", trest, &tfo, &tr_rest, true, &tf, NULL))) goto done;
    if (!km_frame_is_identity(&tf) &&
        (km_mesh_frame_apply(&tf, &tr_rest, &err) || km_mesh_frame_apply(&tf, &t, &err))) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
    if (tr_rest.n_vertices != t.n_vertices || tr_rest.n_faces != t.n_faces ||
        memcmp(tr_rest.F, t.F, t.n_faces * 3 * sizeof(int32_t)) != 0) {
      rc =
          km_cli_error("transfer",
                       "--template-rest %s (%zu vertices, %zu faces) is not TEMPLATE %s's mesh "
                       "(%zu vertices, %zu faces)",
                       trest, tr_rest.n_vertices, tr_rest.n_faces, pos[1], t.n_vertices, t.n_faces);
      goto done;
    }
  }
  if (!same && !trest) {
    rc = km_cli_error("transfer",
                      "%s (%zu vertices, %zu faces) does not share the connectivity of %s (%zu "
                      "vertices, %zu faces): give TEMPLATE at rest with --template-rest TR",
                      pos[1], t.n_vertices, t.n_faces, pos[0], s.n_vertices, s.n_faces);
    goto done;
  }
  for (size_t i = 0; i < nl && !auto_lm; ++i)
    ids[i] = lm[i].vertex;
  if (!same && !no_reg) {
    /* Pairs for registering SOURCE onto TR: the file, or landmarks of one name in both rigs. */
    if (corr_path) {
      if ((rc = read_pairs(corr_path, s.n_vertices, tr_rest.n_vertices, &pairs, &n_pairs)))
        goto done;
      if (n_pairs < 3) {
        rc = km_cli_error("transfer", "%s: %zu pair(s); the registration needs at least 3",
                          corr_path, n_pairs);
        goto done;
      }
    } else if (!auto_lm) {
      km_landmark tl[KM_POSE_MAX_LANDMARKS];
      size_t ntl = 0;
      km_error e2 = {0};
      if (km_cli_load_landmarks(NULL, trest, tr_rest.n_vertices, tl, KM_POSE_MAX_LANDMARKS, &ntl,
                                &e2) == KM_OK &&
          (pairs = malloc(sizeof *pairs * 2 * (nl ? nl : 1))))
        for (size_t i = 0; i < nl; ++i)
          for (size_t k = 0; k < ntl; ++k)
            if (!strcmp(lm[i].name, tl[k].name)) {
              pairs[2 * n_pairs] = lm[i].vertex;
              pairs[2 * n_pairs + 1] = tl[k].vertex;
              ++n_pairs;
              break;
            }
    }
    if (n_pairs < 3 && nonrigid) {
      rc = km_cli_error("transfer", "--register nonrigid needs correspondences (--correspondences, "
                                    "or landmarks of one name in SOURCE's and TR's rigs)");
      goto done;
    }
    if (n_pairs < 3)
      fprintf(stderr, "kinemesh transfer: no correspondences (--correspondences, or landmarks of "
                      "one name in both rigs): SOURCE and TR are taken to stand in one frame at "
                      "one size\n");
  }
  if (xyz) {
    /* tracked targets: matched to the landmarks by name */
    if (km_track_read(xyz, &trk, &err)) {
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
    if (xyz_frame >= trk.n_frames) {
      rc = km_cli_error("transfer", "%s has %zu frame(s); --frame %zu is out of range", xyz,
                        trk.n_frames, xyz_frame);
      goto done;
    }
    targets = malloc(sizeof(double) * 3 * nl);
    if (!targets) {
      rc = km_cli_error("transfer", "out of memory");
      goto done;
    }
    for (size_t i = 0; i < nl; ++i) {
      size_t k = 0;
      while (k < trk.n_landmarks && strcmp(trk.names[k], lm[i].name))
        ++k;
      if (k == trk.n_landmarks) {
        rc = km_cli_error("transfer", "%s has no landmark named '%s'", xyz, lm[i].name);
        goto done;
      }
      const double *p = trk.positions + (xyz_frame * trk.n_landmarks + k) * 3;
      if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
        rc = km_cli_error("transfer", "%s: landmark '%s' is not tracked in frame %zu", xyz,
                          lm[i].name, xyz_frame);
        goto done;
      }
      memcpy(targets + 3 * i, p, 3 * sizeof(double));
    }
  }
  double t0 = km_cli_now();
  km_transfer_stats st;
  if (!same) {
    /* another connectivity: the pose as rotations and targets carried over from TR -> T */
    corr = malloc(sizeof *corr * s.n_vertices);
    rots = malloc(sizeof *rots * 9 * s.n_vertices);
    double *mapped = malloc(sizeof(double) * 3 * (nl ? nl : 1));
    if (!corr || !rots || !mapped) {
      free(mapped);
      rc = km_cli_error("transfer", "out of memory");
      goto done;
    }
    /* SOURCE registered onto TR (a similarity), or as it stands */
    km_mesh sr = s;
    double sc = 1, Q[9], tq[3];
    if (n_pairs >= 3) {
      registered = malloc(sizeof *registered * 3 * s.n_vertices);
      if (!registered) {
        free(mapped);
        rc = km_cli_error("transfer", "out of memory");
        goto done;
      }
      if (km_transfer_register_rest(&s, &tr_rest, pairs, n_pairs, registered, &sc, Q, tq, &err)) {
        free(mapped);
        rc = km_cli_fail("transfer", &err);
        goto done;
      }
      sr.V = registered;
      double c = fmax(-1, fmin(1, (Q[0] + Q[4] + Q[8] - 1) / 2));
      fprintf(stderr,
              "kinemesh transfer: SOURCE registered onto %s from %zu pairs: scale %.4f, "
              "rotation %.1f deg, translation (%.3f, %.3f, %.3f)\n",
              trest, n_pairs, sc, acos(c) * 180 / 3.14159265358979323846, tq[0], tq[1], tq[2]);
    }
    km_mesh sn = sr;
    if (nonrigid) {
      /* then onto TR's surface (the reconstruction's affine registration, the pairs as its
       * features): the correspondence comes from there, the pose is still mapped on sr and
       * each rotation seen from S's own one-ring (km_transfer_pose_to_source's local) */
      km_recon_feature *feat = malloc(sizeof *feat * n_pairs);
      nonrigid_V = malloc(sizeof *nonrigid_V * 3 * s.n_vertices);
      local = malloc(sizeof *local * 9 * s.n_vertices);
      if (!feat || !nonrigid_V || !local) {
        free(feat);
        free(mapped);
        rc = km_cli_error("transfer", "out of memory");
        goto done;
      }
      for (size_t k = 0; k < n_pairs; ++k) {
        feat[k].vertex = pairs[2 * k];
        memcpy(feat[k].point, tr_rest.V + 3 * (size_t)pairs[2 * k + 1], 3 * sizeof(double));
      }
      double tn = km_cli_now();
      km_status rs =
          km_recon_register_mesh(&s, registered, &tr_rest, feat, n_pairs, 0, nonrigid_V, &err);
      free(feat);
      if (!rs) {
        sn.V = nonrigid_V;
        rs = km_transfer_template_rotations(&sr, nonrigid_V, local, &err);
      }
      if (rs) {
        free(mapped);
        rc = km_cli_fail("transfer", &err);
        goto done;
      }
      double mean, max;
      km_vertex_distance_stats(registered, nonrigid_V, s.n_vertices, &mean, &max);
      fprintf(stderr,
              "kinemesh transfer: non-rigid registration onto %s: moved %.1f mm mean, %.1f mm max "
              "(%.2f s)\n",
              trest, mean * 1e3, max * 1e3, km_cli_now() - tn);
    }
    if (km_transfer_correspondence(&sn, &tr_rest, corr, &err) ||
        km_transfer_map_pose(&sr, &tr_rest, t.V, corr, ids, nl, rots, mapped, &err)) {
      free(mapped);
      rc = km_cli_fail("transfer", &err);
      goto done;
    }
    /* back into SOURCE's frame and size */
    if (n_pairs >= 3) km_transfer_pose_to_source(sc, Q, tq, local, s.n_vertices, rots, nl, mapped);
    if (!targets)
      targets = mapped;
    else
      free(mapped);
  }
  if (km_transfer_precompute(&s, ids, nl, &to, &tr, &err) || km_mesh_copy(&s, &o, &err) ||
      (same ? km_transfer_solve(tr, t.V, targets, NULL, o.V, &st, &err)
            : km_transfer_solve_rotations(tr, rots, targets, o.V, &st, &err)) ||
      km_mesh_write(out, &o, NULL, &err)) {
    rc = km_cli_fail("transfer", &err);
    goto done;
  }
  double lap, chol;
  km_transfer_precompute_ms(tr, &lap, &chol);
  fprintf(stderr,
          "kinemesh transfer: %zu vertices, %zu landmarks; offline %.1f ms (Laplacian %.1f, "
          "Cholesky %.1f); online %.2f ms, %d iterations (frames %.3f, solve %.3f ms each) in "
          "%.2f s -> %s\n",
          s.n_vertices, nl, lap + chol, lap, chol, st.total_ms, st.iterations,
          st.frames_ms / st.iterations, st.solve_ms / st.iterations, km_cli_now() - t0, out);
  double en[64];
  size_t ne = km_transfer_energies(tr, en, 64);
  if (ne) {
    fprintf(stderr, "kinemesh transfer: energy per solve:");
    for (size_t i = 0; i < ne && i < 64; ++i)
      fprintf(stderr, " %.6g", en[i]);
    fprintf(stderr, "\n");
  }
done:
  km_transfer_free(&tr);
  km_track_free(&trk);
  free(lm);
  free(ids);
  free(targets);
  km_mesh_free(&s);
  km_mesh_free(&t);
  km_mesh_free(&o);
  km_mesh_free(&tr_rest);
  free(corr);
  free(rots);
  free(pairs);
  free(registered);
  free(nonrigid_V);
  free(local);
  return rc;
}
