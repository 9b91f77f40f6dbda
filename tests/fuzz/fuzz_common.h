/* libFuzzer harnesses (make fuzz): what they share.  The readers take file names, so each
 * input is written to a private temporary file; its first byte picks the file's extension
 * (the readers fall back on it when the content does not tell the format), the rest is the
 * file's content. */
#ifndef I2M_FUZZ_COMMON_H
#define I2M_FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Writes data[1..size) to a temporary named by data[0] % n of exts; returns its path (static
 * storage) or NULL. */
static const char *fuzz_file(const uint8_t *data, size_t size, const char *const *exts, size_t n)
{
  static char path[256];
  if (size < 1) return NULL;
  const char *dir = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
  snprintf(path, sizeof path, "%s/i2m-fuzz-%ld%s", dir, (long)getpid(), exts[data[0] % n]);
  FILE *f = fopen(path, "wb");
  if (!f) return NULL;
  const size_t w = fwrite(data + 1, 1, size - 1, f);
  if (fclose(f) != 0 || w != size - 1) {
    remove(path);
    return NULL;
  }
  return path;
}

#endif
