/* Base layer: output files that appear whole or not at all.
 *
 * A file is written under a temporary name beside its final one (same directory, so the
 * rename cannot cross file systems) and renamed over it only once everything was written,
 * flushed and closed.  On failure the temporary goes and the previous file of that name is
 * untouched.  The temporaries being written are listed in a fixed table that a handler for
 * SIGINT, SIGTERM and SIGHUP empties (unlink is async-signal-safe) before the signal's
 * default action ends the process.  SIGXFSZ is ignored, so that a file-size limit is a
 * failed write with a message, not a killed process.  A symbolic link to a regular file
 * keeps pointing at it (the file it names is replaced); what is not a regular file
 * (/dev/null, a pipe) is written in place. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "i2m/base.h"

#include <errno.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define TEMP_SLOTS 64
#define TEMP_PATH_MAX 4096

static char temp_path[TEMP_SLOTS][TEMP_PATH_MAX];
static atomic_int temp_used[TEMP_SLOTS]; /* 0 free, 1 taken (path being set), 2 listed */

static int temp_list(const char *path)
{
  for (int k = 0; k < TEMP_SLOTS; k++) {
    int expect = 0;
    if (!atomic_compare_exchange_strong(&temp_used[k], &expect, 1)) continue;
    snprintf(temp_path[k], TEMP_PATH_MAX, "%s", path);
    atomic_store(&temp_used[k], 2);
    return k;
  }
  return -1; /* (more files at once than slots: written all the same, not cleaned on a signal) */
}

static void temp_unlist(int k)
{
  if (k >= 0) atomic_store(&temp_used[k], 0);
}

static void on_signal(int sig)
{
  for (int k = 0; k < TEMP_SLOTS; k++)
    if (atomic_load(&temp_used[k]) == 2) unlink(temp_path[k]);
  signal(sig, SIG_DFL);
  raise(sig);
}

void i2m_outfile_signals(void)
{
  static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
  for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++) {
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN) continue; /* (nohup keeps its way) */
    sigaction(sigs[i], &sa, NULL);
  }
  signal(SIGXFSZ, SIG_IGN);
}

/* Where the temporary goes and what it replaces: the path itself, or the regular file a
 * symbolic link names (the link stays).  NULL: not a regular file (/dev/null, a pipe, a
 * dangling link), written in place. */
static char *final_name(const char *path)
{
  struct stat st;
  char *real = NULL;
  if (lstat(path, &st) != 0) real = strdup(path); /* (a new file) */
  else if (S_ISREG(st.st_mode)) real = strdup(path);
  else if (S_ISLNK(st.st_mode) && stat(path, &st) == 0 && S_ISREG(st.st_mode)) real = realpath(path, NULL);
  return real;
}

static i2m_err_t open_in_place(i2m_outfile_t *o, const char *path, const char *mode)
{
  const size_t n = strlen(path);
  I2M_CALL(i2m_malloc(n + 1, 1, &o->path));
  memcpy(o->path, path, n + 1);
  o->f = fopen(path, mode);
  if (!o->f) {
    const int e = errno;
    i2m_free(&o->path);
    return I2M_ERROR(I2M_ERR_IO, "%s: cannot open for writing: %s", path, strerror(e));
  }
  return I2M_OK;
}

static i2m_err_t open_tmp(i2m_outfile_t *o, const char *path, const char *mode)
{
  const size_t n = strlen(path);
  I2M_CHECK(n + 32 < TEMP_PATH_MAX, I2M_ERR_IO, "%s: path too long", path);
  I2M_CALL(i2m_malloc(n + 1, 1, &o->path));
  memcpy(o->path, path, n + 1);
  i2m_err_t err = i2m_malloc(n + 32, 1, &o->tmp);
  if (err != I2M_OK) {
    i2m_free(&o->path);
    return err;
  }
  static atomic_uint serial;
  snprintf(o->tmp, n + 32, "%s.tmp%ld.%u", path, (long)getpid(), atomic_fetch_add(&serial, 1u) % 100000u);
  o->slot = temp_list(o->tmp);
  o->f = fopen(o->tmp, mode);
  if (!o->f) {
    const int e = errno;
    temp_unlist(o->slot);
    i2m_free(&o->tmp);
    err = I2M_ERROR(I2M_ERR_IO, "%s: cannot open for writing: %s", path, strerror(e));
    i2m_free(&o->path);
    return err;
  }
  return I2M_OK;
}

i2m_err_t i2m_outfile_open(i2m_outfile_t *o, const char *path, const char *mode)
{
  memset(o, 0, sizeof *o);
  o->slot = -1;
  I2M_CHECK(path && *path, I2M_ERR_ARG, "empty output file name");
  char *real = final_name(path);
  if (!real) return open_in_place(o, path, mode);
  const i2m_err_t err = open_tmp(o, real, mode);
  free(real);
  return err;
}

i2m_err_t i2m_outfile_commit(i2m_outfile_t *o)
{
  if (!o->f) return I2M_ERROR(I2M_ERR_INTERNAL, "committing an output file that is not open");
  errno = 0;
  int bad = ferror(o->f) ? (errno ? errno : EIO) : 0;
  if (fflush(o->f) != 0 && !bad) bad = errno ? errno : EIO;
  if (fclose(o->f) != 0 && !bad) bad = errno ? errno : EIO;
  o->f = NULL;
  if (!bad && o->tmp && rename(o->tmp, o->path) != 0) bad = errno;
  i2m_err_t err = I2M_OK;
  if (bad) {
    if (o->tmp) unlink(o->tmp);
    err = I2M_ERROR(I2M_ERR_IO, "%s: writing failed: %s%s", o->path, strerror(bad),
                    o->tmp ? " (the previous file, if any, is untouched)" : "");
  }
  temp_unlist(o->slot);
  i2m_free(&o->tmp);
  i2m_free(&o->path);
  return err;
}

void i2m_outfile_abandon(i2m_outfile_t *o)
{
  if (o->f) fclose(o->f);
  o->f = NULL;
  if (o->tmp) unlink(o->tmp);
  temp_unlist(o->slot);
  i2m_free(&o->tmp);
  i2m_free(&o->path);
}

bool i2m_path_dir(const char *path, char *dir, size_t cap)
{
  const char *slash = strrchr(path, '/');
  const size_t n = slash ? (size_t)(slash - path) : 0;
  if (n + 2 > cap) return false;
  if (!slash) snprintf(dir, cap, ".");
  else if (n == 0) snprintf(dir, cap, "/");
  else {
    memcpy(dir, path, n);
    dir[n] = '\0';
  }
  return true;
}

/* The same file: the same device and inode when both exist; otherwise the same name in the
 * same directory (an output not written yet). */
bool i2m_same_file(const char *a, const char *b)
{
  if (!a || !b) return false;
  struct stat sa, sb;
  const bool ea = stat(a, &sa) == 0, eb = stat(b, &sb) == 0;
  if (ea && eb) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  if (ea != eb) return false;
  char da[TEMP_PATH_MAX], db[TEMP_PATH_MAX];
  const char *ba = strrchr(a, '/'), *bb = strrchr(b, '/');
  if (strcmp(ba ? ba + 1 : a, bb ? bb + 1 : b) != 0) return false;
  if (!i2m_path_dir(a, da, sizeof da) || !i2m_path_dir(b, db, sizeof db)) return strcmp(a, b) == 0;
  if (stat(da, &sa) != 0 || stat(db, &sb) != 0) return strcmp(da, db) == 0;
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}
