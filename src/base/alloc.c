/* Base layer: checked allocation.  Every failure sets a message with the size asked for. */
#if defined(__linux__) && !defined(_DEFAULT_SOURCE)
#define _DEFAULT_SOURCE /* madvise's MADV_HUGEPAGE */
#endif
#include "i2m/base.h"

#include <stdlib.h>
#include <string.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

void i2m_malloc_tune(void)
{
#if defined(__GLIBC__)
  /* glibc raises its mmap threshold to the size of every large block freed (up to 32 MB), after
   * which the mesh's growing arrays live in the heap: a realloc copies them (old and new
   * resident together) and freed memory stays resident.  A fixed threshold keeps every large
   * array in its own mapping, grown by mremap and returned on free. */
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
#endif
}

static int mul_overflows(size_t n, size_t size) { return size != 0 && n > SIZE_MAX / size; }

i2m_err_t i2m_malloc(size_t n, size_t size, void *out)
{
  void **p = (void **)out;
  *p = NULL;
  if (n == 0 || size == 0) return I2M_OK;
  I2M_CHECK(!mul_overflows(n, size), I2M_ERR_MEMORY, "allocation of %zu x %zu bytes overflows", n, size);
  *p = malloc(n * size);
  I2M_CHECK(*p, I2M_ERR_MEMORY, "out of memory allocating %zu bytes", n * size);
  return I2M_OK;
}

i2m_err_t i2m_calloc(size_t n, size_t size, void *out)
{
  void **p = (void **)out;
  *p = NULL;
  if (n == 0 || size == 0) return I2M_OK;
  I2M_CHECK(!mul_overflows(n, size), I2M_ERR_MEMORY, "allocation of %zu x %zu bytes overflows", n, size);
  *p = calloc(n, size);
  I2M_CHECK(*p, I2M_ERR_MEMORY, "out of memory allocating %zu bytes", n * size);
  return I2M_OK;
}

i2m_err_t i2m_realloc(size_t n, size_t size, void *ptr)
{
  void **p = (void **)ptr;
  if (n == 0 || size == 0) {
    free(*p);
    *p = NULL;
    return I2M_OK;
  }
  I2M_CHECK(!mul_overflows(n, size), I2M_ERR_MEMORY, "allocation of %zu x %zu bytes overflows", n, size);
  void *q = realloc(*p, n * size);
  I2M_CHECK(q, I2M_ERR_MEMORY, "out of memory growing an array to %zu bytes", n * size);
  *p = q;
  return I2M_OK;
}

void i2m_free(void *ptr)
{
  void **p = (void **)ptr;
  if (!p) return;
  free(*p);
  *p = NULL;
}

#if defined(__linux__) && defined(MADV_HUGEPAGE)
/* Huge pages only on request (I2M_HUGEPAGES=1).  On the 2026-11-25 VM they saved no user
 * time, even over 3 GB, and made first touches dearer: 0.3-0.6 s of system time per 10^6
 * kernel points against 0.13-0.20 s, and 1.5 s against 0.55 s for a 6 M-tet mesh.  On an
 * earlier machine they took 30% off the kernel.  Measure on yours. */
static int huge_pages_wanted(void)
{
  const char *e = getenv("I2M_HUGEPAGES");
  return e && *e && strcmp(e, "0") != 0;
}
#endif

/* Below this size huge pages would only round the block up. */
#define LARGE_BLOCK_BYTES ((size_t)8 << 20)

i2m_err_t i2m_realloc_large(size_t n, size_t size, void *ptr)
{
  I2M_CALL(i2m_realloc(n, size, ptr));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  size_t bytes = n * size; /* checked by i2m_realloc */
  if (bytes >= LARGE_BLOCK_BYTES && huge_pages_wanted()) {
    /* The whole pages the block touches: a block this large has a mapping of its own, which
     * then keeps one set of flags (advising part of it would split it, and a later realloc
     * could no longer move it with mremap but would copy it). */
    long pg = sysconf(_SC_PAGESIZE);
    uintptr_t a = (uintptr_t) * (void **)ptr, page = pg > 0 ? (uintptr_t)pg : 4096;
    uintptr_t lo = a & ~(page - 1), hi = (a + bytes + page - 1) & ~(page - 1);
    (void)madvise((void *)lo, hi - lo, MADV_HUGEPAGE); /* advice only: failure is harmless */
  }
#endif
  return I2M_OK;
}
