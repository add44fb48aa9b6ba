/* Labelled pose meshes (km_pose_set): entries, labels CSV, subjects, errors naming the line. */
#include "km_test.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  if (f) {
    fputs(text, f);
    fclose(f);
  }
}

int main(void) {
  /* entries: classes in order of first appearance, subjects grouped by name, names = base names */
  const char *e[] = {"squat=a/x1.obj@alice", "t_pose=b/x2.ply@bob", "squat=x3.off@bob",
                     "t_pose=c/d/x4.obj@alice"};
  km_pose_set s;
  CHECK_OK(km_pose_set_from_entries(e, 4, &s, KM_E));
  CHECK(s.n == 4 && s.n_classes == 2);
  CHECK(!strcmp(s.class_names[0], "squat") && !strcmp(s.class_names[1], "t_pose"));
  CHECK(s.labels[0] == 0 && s.labels[1] == 1 && s.labels[2] == 0 && s.labels[3] == 1);
  CHECK(s.groups && s.groups[0] == s.groups[3] && s.groups[1] == s.groups[2] &&
        s.groups[0] != s.groups[1]);
  CHECK(!strcmp(s.paths[0], "a/x1.obj") && !strcmp(s.paths[3], "c/d/x4.obj"));
  CHECK(!strcmp(s.names[0], "x1.obj") && !strcmp(s.names[2], "x3.off"));
  km_pose_set_free(&s);
  CHECK(s.paths == NULL && s.n == 0);

  /* no subject anywhere: no groups */
  const char *e2[] = {"a=m1.obj", "b=m2.obj"};
  CHECK_OK(km_pose_set_from_entries(e2, 2, &s, KM_E));
  CHECK(s.groups == NULL);
  km_pose_set_free(&s);

  /* an entry without CLASS= is refused, naming it */
  const char *e3[] = {"a=m1.obj", "m2.obj"};
  CHECK_STATUS(km_pose_set_from_entries(e3, 2, &s, KM_E), KM_ERR_INVALID);
  CHECK_MSG(strstr(km_test_err.message, "argument 2 'm2.obj'"), "%s", km_test_err.message);

  /* a folder + labels CSV: header skipped, base names matched, unlabelled listed */
  const char *dir = "poseset_dir";
  mkdir(dir, 0777);
  write_file("poseset_dir/p1.obj", "v 0 0 0\n");
  write_file("poseset_dir/p2.ply", "ply\n");
  write_file("poseset_dir/p3.off", "OFF\n");
  write_file("poseset_dir/notes.txt", "not a mesh\n");
  write_file("poseset_labels.csv",
             "mesh,class,subject\np2.ply,wave,s1\n# comment\np1.obj;walk;s2\n");
  CHECK_OK(km_pose_set_from_labels(dir, "poseset_labels.csv", NULL, 0, &s, KM_E));
  CHECK(s.n == 2 && s.n_listed == 3 && s.n_unlabelled == 1);
  CHECK(s.n == 2 && !strcmp(s.paths[0], "poseset_dir/p2.ply") && !strcmp(s.class_names[0], "wave"));
  CHECK(s.n_unlabelled == 1 && strstr(s.unlabelled[0], "p3.off"));
  km_pose_set_free(&s);

  /* issue 14: a mesh labelled twice is warned about and kept once (the first line's class) */
  write_file("poseset_dup.csv", "p1.obj,walk\np2.ply,wave\np1.obj,walk\np1.obj,run\n");
  CHECK_OK(km_pose_set_from_labels(dir, "poseset_dup.csv", NULL, 0, &s, KM_E));
  CHECK_MSG(s.n == 2 && s.n_duplicates == 2 && s.n_classes == 2, "n %zu, duplicates %zu", s.n,
            s.n_duplicates);
  CHECK(s.n == 2 && !strcmp(s.class_names[s.labels[0]], "walk"));
  km_pose_set_free(&s);
  /* a line naming a file that is not there: file:line in the error */
  write_file("poseset_bad.csv", "p1.obj,walk\nnope.obj,walk\n");
  CHECK_STATUS(km_pose_set_from_labels(dir, "poseset_bad.csv", NULL, 0, &s, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "poseset_bad.csv:2") &&
                strstr(km_test_err.message, "'nope.obj' is not among the meshes"),
            "%s", km_test_err.message);
  /* a line with one field */
  write_file("poseset_bad.csv", "p1.obj\n");
  CHECK_STATUS(km_pose_set_from_labels(dir, "poseset_bad.csv", NULL, 0, &s, KM_E), KM_ERR_PARSE);
  CHECK_MSG(strstr(km_test_err.message, "poseset_bad.csv:1: expected 'mesh,class[,subject]'"), "%s",
            km_test_err.message);
  /* nothing matched */
  CHECK_STATUS(
      km_pose_set_from_labels("poseset_dir/*.stl", "poseset_labels.csv", NULL, 0, &s, KM_E),
      KM_ERR_IO);
  CHECK_MSG(strstr(km_test_err.message, "matched no mesh files"), "%s", km_test_err.message);
  /* entries before the CSV's come first */
  const char *before[] = {"jump=poseset_dir/p3.off@s1"};
  CHECK_OK(km_pose_set_from_labels(dir, "poseset_labels.csv", before, 1, &s, KM_E));
  CHECK(s.n == 3 && !strcmp(s.class_names[0], "jump") && s.groups && s.groups[0] == s.groups[1]);
  km_pose_set_free(&s);
  return km_test_finish("test_poseset");
}
