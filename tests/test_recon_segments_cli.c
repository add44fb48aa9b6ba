/* reconstruct --segment-frames (issue 17): a 120-frame simulated capture reconstructed whole
 * and in 4 segments of 30 (each started on its own first frame, 5 frames of overlap
 * cross-faded, the temporal filter across the seams). The segmented result is as close to the
 * truth as the whole one (within 10%), and the frame-to-frame motion at every seam stays within
 * 2x the take's median frame-to-frame motion (no pop). The segmented run writes the report
 * (--report) as an unsegmented one does. */
#include "km_test.h"

#include <cjson/cJSON.h>

#define DIR "recon_segments_cli"
#if defined(__SANITIZE_ADDRESS__)
/* under the sanitizers (a Debug build, ~10 s a frame) a short take through the same code: the
 * quality figures are the Release run's */
#define FRAMES 12
#define SEG 4
#define FRAMES_S "12"
#define SEG_S "4"
#define SEG_LAST_S "3/3: frames 8-11"
#define OVERLAP_S "2"
#else
#define FRAMES 120
#define SEG 30
#define FRAMES_S "120"
#define SEG_S "30"
#define SEG_LAST_S "4/4: frames 90-119"
#define OVERLAP_S "5"
#endif

/* Mean over frames and vertices of |A - B|. */
static double mean_dist(const double *A, const double *B, size_t nf, size_t nv) {
  double s = 0;
  for (size_t i = 0; i < nf * nv; ++i)
    s += sqrt((A[3 * i] - B[3 * i]) * (A[3 * i] - B[3 * i]) +
              (A[3 * i + 1] - B[3 * i + 1]) * (A[3 * i + 1] - B[3 * i + 1]) +
              (A[3 * i + 2] - B[3 * i + 2]) * (A[3 * i + 2] - B[3 * i + 2]));
  return s / (double)(nf * nv);
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

int main(void) {
  char *out = NULL;
  (void)km_test_err;
  setenv("OMP_NUM_THREADS", "1", 1); /* the two runs side by side, one core each */
  CHECK(km_test_run("rm -rf " DIR " && mkdir -p " DIR, NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen character --vertices 2000 -o " DIR "/t.obj", NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen motion --kind walk --frames " FRAMES_S " --character " DIR
                           "/t.obj -o " DIR "/walk.json",
                    NULL) == 0);
  CHECK(km_test_run(KM_CLI " gen capture --character " DIR "/t.obj --motion " DIR
                           "/walk.json --cameras 4 --points 3000 -o " DIR "/c",
                    NULL) == 0);
  /* one segment alone needs the folder its part goes to */
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/t.obj --clouds '" DIR
                           "/c/frame_*.ply' --segment-frames 30 --segment 1",
                    &out) == 1);
  CHECK(out && strstr(out, "--segment-dir"));
  free(out);
  CHECK(km_test_run(KM_CLI " reconstruct --template " DIR "/t.obj --clouds '" DIR
                           "/c/frame_*.ply' -o " DIR "/whole.pc2 > " DIR "/whole.log 2>&1 & " KM_CLI
                           " reconstruct --template " DIR "/t.obj --clouds '" DIR
                           "/c/frame_*.ply' --segment-frames " SEG_S " --overlap " OVERLAP_S
                           " -o " DIR "/seg.pc2 --report " DIR "/seg.json > " DIR
                           "/seg.log 2>&1; s=$?; wait $! && exit $s",
                    NULL) == 0);
  CHECK(km_test_run("grep -q 'segment " SEG_LAST_S "' " DIR "/seg.log", NULL) == 0);
  /* the report of a segmented take: every frame, from its own segment */
  {
    FILE *f = fopen(DIR "/seg.json", "rb");
    char *text = f ? calloc(1, 1 << 24) : NULL;
    if (text) fread(text, 1, (1 << 24) - 1, f);
    if (f) fclose(f);
    cJSON *r = text ? cJSON_Parse(text) : NULL;
    const cJSON *frames = cJSON_GetObjectItemCaseSensitive(r, "frames");
    const cJSON *last = cJSON_GetArrayItem(frames, cJSON_GetArraySize(frames) - 1);
    const cJSON *index = cJSON_GetObjectItemCaseSensitive(last, "index");
    CHECK_MSG(cJSON_GetArraySize(frames) == FRAMES, "report frames %d", cJSON_GetArraySize(frames));
    CHECK(cJSON_IsNumber(index) && index->valuedouble == FRAMES - 1);
    CHECK(cJSON_GetObjectItemCaseSensitive(r, "jerk_after") != NULL);
    cJSON_Delete(r);
    free(text);
  }
  double *T = NULL, *W = NULL, *S = NULL;
  km_anim_info it, iw, is;
  CHECK_OK(km_pc2_read(DIR "/c/truth.pc2", &T, &it, KM_E));
  CHECK_OK(km_pc2_read(DIR "/whole.pc2", &W, &iw, KM_E));
  CHECK_OK(km_pc2_read(DIR "/seg.pc2", &S, &is, KM_E));
  if (T && W && S) {
    CHECK(it.frames == FRAMES && iw.frames == FRAMES && is.frames == FRAMES);
    CHECK(iw.vertices == it.vertices && is.vertices == it.vertices);
    const size_t nv = it.vertices;
    double ew = mean_dist(W, T, FRAMES, nv), es = mean_dist(S, T, FRAMES, nv);
    printf("error to the truth: whole %.2f mm, 4 segments %.2f mm (%.3fx)\n", ew * 1e3, es * 1e3,
           es / ew);
#if defined(__SANITIZE_ADDRESS__)
    CHECK(isfinite(es) && es < 0.1);
    (void)cmp_d;
#else
    CHECK_MSG(es <= 1.10 * ew, "segmented %.2f mm vs whole %.2f mm", es * 1e3, ew * 1e3);
    double motion[FRAMES - 1], sorted[FRAMES - 1];
    for (size_t f = 0; f + 1 < FRAMES; ++f)
      motion[f] = sorted[f] = mean_dist(S + (f + 1) * nv * 3, S + f * nv * 3, 1, nv);
    qsort(sorted, FRAMES - 1, sizeof *sorted, cmp_d);
    double med = sorted[(FRAMES - 1) / 2];
    for (size_t seam = SEG; seam < FRAMES; seam += SEG)
      for (size_t f = seam - 1; f < seam + 6 && f < FRAMES - 1; ++f) /* the cross-fade too */
        CHECK_MSG(motion[f] <= 2 * med, "seam %zu: frame %zu -> %zu moves %.1f mm, median %.1f mm",
                  seam, f, f + 1, motion[f] * 1e3, med * 1e3);
    printf("seam jumps / median frame motion (%.1f mm):", med * 1e3);
    for (size_t seam = SEG; seam < FRAMES; seam += SEG)
      printf(" %.2f", motion[seam - 1] / med);
    printf("\n");
#endif
  }
  free(T);
  free(W);
  free(S);
  return km_test_finish("test_recon_segments_cli");
}
