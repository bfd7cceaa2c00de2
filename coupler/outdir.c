/* outdir.c — output.dir belongs to one run at a time, and a run never
 * destroys an earlier run's results (README "Output"):
 *   - an exclusive flock on output.dir/.cosim.lock, taken before anything in
 *     the dir is touched and held to the end: a second run into the same dir
 *     is refused at once, with the holder's pid (written into the lock file);
 *   - an existing results.h5 is kept: a restart continues it, --overwrite
 *     replaces it (only once every participant has passed its handshake),
 *     anything else is refused; a results.h5 that is not an HDF5 file is
 *     never written over;
 *   - a reserve file: HDF5 cannot finish a file on a full disk (its last
 *     metadata would be missing), so the run keeps some space aside and
 *     frees it when a write fails, then closes the results complete. */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#define RESERVE_FILE ".cosim.reserve"
#define PID_TEXT 32

int cpl_mkdirs(const char *path, proto_err *err) {
  char tmp[CPL_PATH_LEN];
  snprintf(tmp, sizeof tmp, "%s", path);
  for (char *p = tmp + 1; *p; p++) {
    if (*p != '/') continue;
    *p = 0;
    if (mkdir(tmp, 0755) < 0 && errno != EEXIST)
      return proto_fail(err, "cannot create %s: %s", tmp, strerror(errno));
    *p = '/';
  }
  if (mkdir(tmp, 0755) < 0 && errno != EEXIST)
    return proto_fail(err, "cannot create %s: %s", tmp, strerror(errno));
  return 0;
}

int cpl_outdir_lock(const char *dir, proto_err *err) {
  if (cpl_mkdirs(dir, err) < 0) return proto_wrap(err, "output.dir");
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, CPL_LOCK_FILE);
  int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0)
    return proto_fail(err, "output.dir: cannot open the lock file %s: %s", path,
                      strerror(errno));
  if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
    int e = errno;
    char pid[PID_TEXT] = "";
    ssize_t n = pread(fd, pid, sizeof pid - 1, 0);
    pid[n > 0 ? n : 0] = 0;
    pid[strcspn(pid, "\n")] = 0;
    close(fd);
    if (e == EWOULDBLOCK)
      return proto_fail(err, "output.dir '%s' is in use by another cosim run (pid "
                        "%s); wait for it or choose another output.dir", dir,
                        pid[0] ? pid : "unknown");
    return proto_fail(err, "output.dir: cannot lock %s: %s", path, strerror(e));
  }
  char pid[PID_TEXT];
  int len = snprintf(pid, sizeof pid, "%d\n", (int)getpid());
  if (ftruncate(fd, 0) != 0 || pwrite(fd, pid, (size_t)len, 0) != len) {
    int e = errno;
    close(fd);
    return proto_fail(err, "output.dir: cannot write the lock file %s: %s", path,
                      strerror(e));
  }
  return fd;
}

void cpl_outdir_unlock(int fd) {
  if (fd >= 0) close(fd); /* the file stays: removing it would race a new locker */
}

int cpl_outdir_results(const char *dir, int restart, int overwrite, proto_err *err) {
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, CPL_RESULTS_FILE);
  switch (proto_h5_probe(path)) {
  case 0:
    return 0;
  case 1:
    if (restart || overwrite) return 0;
    return proto_fail(err, "%s holds the results of an earlier run, which cosim "
                      "keeps: pass --overwrite to replace them, --restart to "
                      "continue them, or choose another output.dir", path);
  default:
    return proto_fail(err, "%s exists and is not an HDF5 file (or cannot be "
                      "read); cosim never writes over it: move it away or "
                      "choose another output.dir", path);
  }
}

int cpl_reserve_make(const char *dir, int64_t bytes, proto_err *err) {
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, RESERVE_FILE);
  int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  int e = fd < 0 ? errno : posix_fallocate(fd, 0, (off_t)bytes);
  if (fd >= 0) close(fd);
  if (e == 0) return 0;
  unlink(path);
  return proto_fail(err, "output.dir: cannot keep %.1f MiB aside in %s (for closing "
                    "the results should the disk fill up): %s (errno %d)",
                    (double)bytes / (1 << 20), dir, strerror(e), e);
}

void cpl_reserve_release(const char *dir) {
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, RESERVE_FILE);
  unlink(path);
}
