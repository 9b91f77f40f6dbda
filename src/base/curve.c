/* Base layer: a space-filling curve for the orders that want neighbours in space near each
 * other in memory (the triangulation's tets before the sliver pass, the output mesh). */
#include <string.h>

#include "i2m/base.h"

#define DIGIT_BITS 9 /* counting passes of 512 buckets */

/* x's low `bits` bits spread to every third bit. */
static uint32_t spread3(uint32_t x, int bits)
{
  uint32_t s = 0;
  for (int b = 0; b < bits; b++) s |= ((x >> b) & 1u) << (3 * b);
  return s;
}

uint32_t i2m_morton_code(const double x[3], const double lo[3], const double scale[3], int bits)
{
  const uint32_t top = (1u << bits) - 1;
  uint32_t code = 0;
  for (int a = 0; a < 3; a++) {
    double u = (x[a] - lo[a]) * scale[a];
    u = u > 0 ? u : 0; /* (NaN: 0) */
    const uint32_t q = u < (double)top ? (uint32_t)u : top;
    code |= spread3(q, bits) << a;
  }
  return code;
}

uint64_t *i2m_sort_by_code(uint64_t *a, uint64_t *b, size_t n, int bits)
{
  enum { R = 1u << DIGIT_BITS };
  size_t count[R];
  for (int shift = 32; shift < 32 + bits; shift += DIGIT_BITS) {
    memset(count, 0, sizeof count);
    for (size_t i = 0; i < n; i++) count[(a[i] >> shift) & (R - 1)]++;
    size_t sum = 0;
    for (uint32_t r = 0; r < R; r++) {
      const size_t c = count[r];
      count[r] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; i++) b[count[(a[i] >> shift) & (R - 1)]++] = a[i];
    uint64_t *s = a;
    a = b;
    b = s;
  }
  return a;
}
