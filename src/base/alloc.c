/* Base layer: checked allocation.  Every failure sets a message with the size asked for. */
#include "i2m/base.h"

#include <stdlib.h>
#include <string.h>
#if defined(__GLIBC__)
#include <malloc.h>
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
