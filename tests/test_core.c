#include "core/core.h"
#include "km_test.h"

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static void test_atomic_file(void) {
  const char *path = "test_core_atomic.txt";
  remove(path);
  km__atomic_file af;
  CHECK_OK(km__atomic_open(&af, path, KM_E));
  fputs("hello", af.f);
  /* Nothing is visible at the final path before commit. */
  CHECK(access(path, F_OK) != 0);
  CHECK_OK(km__atomic_commit(&af, KM_E));
  char *data = NULL;
  size_t n = 0;
  CHECK_OK(km__read_file(path, &data, &n, KM_E));
  CHECK(n == 5 && data && memcmp(data, "hello", 5) == 0);
  free(data);

  /* An aborted write leaves the previous file untouched and no temporary behind. */
  CHECK_OK(km__atomic_open(&af, path, KM_E));
  fputs("garbage", af.f);
  char tmp[512];
  snprintf(tmp, sizeof tmp, "%s", af.tmp_path);
  km__atomic_abort(&af);
  CHECK(access(tmp, F_OK) != 0);
  CHECK_OK(km__read_file(path, &data, &n, KM_E));
  CHECK(n == 5);
  free(data);
  remove(path);

  /* Missing folders are created (issue 11: every -o works without a mkdir) ... */
  CHECK_OK(km__atomic_open(&af, "core_mk/such/dir/x.txt", KM_E));
  fputs("x", af.f);
  CHECK_OK(km__atomic_commit(&af, KM_E));
  CHECK(access("core_mk/such/dir/x.txt", F_OK) == 0);
  remove("core_mk/such/dir/x.txt");
  rmdir("core_mk/such/dir");
  rmdir("core_mk/such");
  rmdir("core_mk");
  /* ... and a folder that cannot be made (under a file) is a clear IO error naming the path. */
  CHECK_STATUS(km__atomic_open(&af, "/dev/null/such/dir/x.txt", KM_E), KM_ERR_IO);
  CHECK(strstr(km_test_err.message, "/dev/null/such/dir/x.txt") != NULL);
}

/* Issue 18: a temporary never goes through a planted symlink, keeps the replaced file's
 * mode, and the signal-handler cleanup removes open temporaries. */
static void test_atomic_hardening(void) {
  const char *path = "test_core_hard.txt", *victim = "test_core_victim.txt";
  remove(path);
  remove(victim);
  FILE *f = fopen(victim, "wb");
  CHECK(f != NULL);
  if (f) {
    fputs("precious", f);
    fclose(f);
  }
  /* The name the old writer used: <path>.tmp.<pid>. */
  char planted[256];
  snprintf(planted, sizeof planted, "%s.tmp.%ld", path, (long)getpid());
  remove(planted);
  CHECK(symlink(victim, planted) == 0);
  CHECK_OK(km_write_file_atomic(path, "new", 3, KM_E));
  char *data = NULL;
  size_t n = 0;
  CHECK_OK(km__read_file(victim, &data, &n, KM_E));
  CHECK_MSG(n == 8 && data && !memcmp(data, "precious", 8), "the symlink's target is untouched");
  free(data);
  struct stat st;
  CHECK(lstat(path, &st) == 0 && S_ISREG(st.st_mode));
  remove(planted);

  /* Mode kept: a 0600 file stays 0600. */
  CHECK(chmod(path, 0600) == 0);
  CHECK_OK(km_write_file_atomic(path, "newer", 5, KM_E));
  CHECK(stat(path, &st) == 0);
  CHECK_MSG((st.st_mode & 0777) == 0600, "mode kept: %o", (unsigned)(st.st_mode & 0777));

  /* km_remove_temporaries (for SIGINT/SIGTERM handlers) removes an open temporary. */
  km__atomic_file af;
  CHECK_OK(km__atomic_open(&af, path, KM_E));
  char tmp[512];
  snprintf(tmp, sizeof tmp, "%s", af.tmp_path);
  CHECK(access(tmp, F_OK) == 0);
  km_remove_temporaries();
  CHECK(access(tmp, F_OK) != 0);
  km__atomic_abort(&af);
  remove(path);
  remove(victim);
}

static void test_errors(void) {
  km_error e = {0};
  CHECK(km__fail(&e, KM_ERR_PARSE, "f.obj:%d: expected %s", 3, "a number") == KM_ERR_PARSE);
  CHECK(e.status == KM_ERR_PARSE);
  CHECK(strcmp(e.message, "f.obj:3: expected a number") == 0);
  km__wrap(&e, KM_ERR_PARSE, "loading mesh");
  CHECK(strcmp(e.message, "loading mesh: f.obj:3: expected a number") == 0);
  CHECK(km__fail(NULL, KM_ERR_IO, "ignored") == KM_ERR_IO);
  CHECK(strcmp(km_status_name(KM_ERR_NOT_POSDEF), "KM_ERR_NOT_POSDEF") == 0);
  char ext[8];
  km__extension("dir.v2/Mesh.PLY", ext, sizeof ext);
  CHECK(strcmp(ext, "ply") == 0);
  km__extension("dir.v2/noext", ext, sizeof ext);
  CHECK(ext[0] == '\0');
  CHECK(km__malloc(SIZE_MAX / 2, 4) == NULL);
}

/* km__whole_number: the one door from a file's number to an integer. */
static void test_whole_number(void) {
  int64_t x = -7;
  CHECK(km__whole_number(3, 0, 10, &x) && x == 3);
  CHECK(km__whole_number(-1, -1, 10, &x) && x == -1);
  CHECK(km__whole_number(2147483647.0, 0, 2147483647.0, &x) && x == 2147483647);
  x = 42;
  CHECK(!km__whole_number(2.5, 0, 10, &x) && x == 42);     /* a fraction */
  CHECK(!km__whole_number(11, 0, 10, &x) && x == 42);      /* above hi */
  CHECK(!km__whole_number(-1, 0, 10, &x) && x == 42);      /* below lo */
  CHECK(!km__whole_number(8.9e83, 0, 1e9, &x) && x == 42); /* fuzz_gltf's scene root */
  CHECK(!km__whole_number(NAN, -1e9, 1e9, &x) && x == 42);
  CHECK(!km__whole_number(INFINITY, -1e18, 1e18, &x) && x == 42);
  CHECK(!km__whole_number(-INFINITY, -1e18, 1e18, &x) && x == 42);
}

int main(void) {
  test_whole_number();
  test_atomic_file();
  test_atomic_hardening();
  test_errors();
  return km_test_finish("test_core");
}
