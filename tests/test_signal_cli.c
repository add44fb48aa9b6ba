/* Issue 18: `kinemesh animate` interrupted by SIGTERM or SIGINT mid-run leaves no temporary
 * ("*.tmp.*" files or a half-filled "<dir>.tmp.<pid>" frame directory) and the old output of
 * the same name as it was. A frame directory is filled under a temporary name and renamed
 * when complete, a .pc2 is streamed into a temporary file, a .glb is written at the end; the
 * CLI's handler removes what is being written (km_remove_temporaries) and dies of the signal.
 * The signal is sent once the run is seen writing (a frame in the temporary directory, frames
 * in the temporary .pc2) or, for the .glb, a moment into the frames. */
#include "km_test.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static char g_dir[] = "/tmp/km_signal_XXXXXX";

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Starts the CLI with these arguments (a shell word list), output to log; its pid. */
static pid_t spawn(const char *args, const char *log) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "exec %s %s >%s 2>&1", KM_CLI, args, log);
  pid_t p = fork();
  if (p == 0) {
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
    _exit(127);
  }
  return p;
}

/* Names in g_dir containing ".tmp." (printed); their count. */
static int temporaries(void) {
  DIR *d = opendir(g_dir);
  int n = 0;
  struct dirent *e;
  while (d && (e = readdir(d)) != NULL)
    if (strstr(e->d_name, ".tmp.")) {
      printf("  left behind: %s/%s\n", g_dir, e->d_name);
      ++n;
    }
  if (d) closedir(d);
  return n;
}

/* Size of the first entry of g_dir whose name starts with prefix (-1: none); for a folder,
 * the number of its entries. */
static long entry_size(const char *prefix) {
  DIR *d = opendir(g_dir);
  long r = -1;
  struct dirent *e;
  while (d && r < 0 && (e = readdir(d)) != NULL) {
    if (strncmp(e->d_name, prefix, strlen(prefix))) continue;
    char p[1024];
    snprintf(p, sizeof p, "%s/%s", g_dir, e->d_name);
    struct stat st;
    if (stat(p, &st) != 0) continue;
    if (S_ISDIR(st.st_mode)) {
      DIR *s = opendir(p);
      r = 0;
      struct dirent *x;
      while (s && (x = readdir(s)) != NULL)
        r += x->d_name[0] != '.';
      if (s) closedir(s);
    } else {
      r = (long)st.st_size;
    }
  }
  if (d) closedir(d);
  return r;
}

static bool file_is(const char *path, const char *text) {
  FILE *f = fopen(path, "rb");
  char buf[64] = {0};
  size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
  if (f) fclose(f);
  return n == strlen(text) && !memcmp(buf, text, n);
}
static void put(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  CHECK(f != NULL);
  if (f) {
    fputs(text, f);
    fclose(f);
  }
}

/* Runs animate into `out` (a name in g_dir), sends sig once `ready_prefix` has reached
 * `ready_size` (entries for a folder, bytes for a file) or, with no prefix, after `delay` s of
 * frames; returns false when the run ended before the signal (nothing to check). */
static bool interrupt(const char *what, const char *out, const char *ready_prefix, long ready_size,
                      double delay, int sig) {
  char args[2048], log[1024];
  snprintf(args, sizeof args,
           "animate --mesh %s/c.obj --motion %s/take.json --cache %s/c.kmcache %s -o %s/%s", g_dir,
           g_dir, g_dir, out[strlen(out) - 1] == '/' ? "--frame-format ply" : "", g_dir, out);
  snprintf(log, sizeof log, "%s/log.txt", g_dir);
  pid_t pid = spawn(args, log);
  CHECK(pid > 0);
  if (pid <= 0) return false;
  char prefix[256];
  if (ready_prefix) snprintf(prefix, sizeof prefix, "%s.tmp.%ld", ready_prefix, (long)pid);
  double t0 = now_s(), frames_from = 0;
  bool sent = false, ended = false;
  int st = 0;
  while (now_s() - t0 < 600) {
    if (waitpid(pid, &st, WNOHANG) == pid) {
      ended = true;
      break;
    }
    bool ready = false;
    if (ready_prefix) {
      ready = entry_size(prefix) >= ready_size;
    } else {
      /* the .glb: once the cache is built and the frames have started */
      if (!frames_from && entry_size("c.kmcache") > 0 && entry_size("c.kmcache.tmp") < 0)
        frames_from = now_s();
      ready = frames_from && now_s() - frames_from > delay;
    }
    if (ready) {
      kill(pid, sig);
      sent = true;
      break;
    }
    usleep(2000);
  }
  if (!ended) waitpid(pid, &st, 0);
  if (!sent) {
    printf("SKIP %s: the run ended (status %d) before it could be interrupted\n", what, st);
    return false;
  }
  CHECK_MSG(WIFSIGNALED(st) && WTERMSIG(st) == sig, "%s: status %d, expected death by signal %d",
            what, st, sig);
  CHECK_MSG(temporaries() == 0, "%s: temporaries left behind", what);
  printf("%s: interrupted after %.2f s\n", what, now_s() - t0);
  return true;
}

int main(void) {
  (void)km_test_err;
  if (!mkdtemp(g_dir)) return 1;
  char cmd[2048], p[1024];
  snprintf(cmd, sizeof cmd,
           KM_CLI " gen character --vertices 2000 -o %s/c.obj && " KM_CLI
                  " gen motion --kind walk --frames 900 -o %s/take.json",
           g_dir, g_dir);
  CHECK(km_test_run(cmd, NULL) == 0);

  /* A frame directory, SIGTERM once the temporary one holds two frames: the old directory
   * (one file, "OLD") is as it was, no "frames.tmp.<pid>" remains. */
  snprintf(p, sizeof p, "%s/frames", g_dir);
  CHECK(mkdir(p, 0777) == 0);
  snprintf(p, sizeof p, "%s/frames/frame_000000.ply", g_dir);
  put(p, "OLD");
  if (interrupt("frame directory, SIGTERM", "frames/", "frames", 2, 0, SIGTERM)) {
    CHECK_MSG(entry_size("frames") == 1 && file_is(p, "OLD"),
              "the old frame directory changed (%ld entries)", entry_size("frames"));
  }

  /* A .pc2 (streamed into its temporary), SIGINT once frames are in it. */
  snprintf(p, sizeof p, "%s/a.pc2", g_dir);
  put(p, "OLD");
  if (interrupt(".pc2, SIGINT", "a.pc2", "a.pc2", 32 + 3 * 12 * 2000, 0, SIGINT))
    CHECK_MSG(file_is(p, "OLD"), "the old .pc2 changed");

  /* A .glb (written at the end), SIGTERM a moment into the frames. */
  snprintf(p, sizeof p, "%s/a.glb", g_dir);
  put(p, "OLD");
  if (interrupt(".glb, SIGTERM", "a.glb", NULL, 0, 0.3, SIGTERM))
    CHECK_MSG(file_is(p, "OLD"), "the old .glb changed");

  snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
  return km_test_finish("test_signal_cli");
}
