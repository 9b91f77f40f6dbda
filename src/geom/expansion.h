/* i2m geometry layer (layer 1), internal: error-free transformations and floating-point
 * expansion arithmetic after J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic
 * and Fast Robust Geometric Predicates", Discrete Comput. Geom. 18 (1997).
 *
 * An expansion is an array of doubles e[0..len-1] whose exact sum is the value it stands
 * for.  Every expansion produced here is zero-free (no zero component; the value 0 is the
 * empty expansion, len 0), strongly nonoverlapping and sorted by increasing magnitude, so
 * its sign is the sign of its last component.  The algorithms are exact provided that
 *   - arithmetic is IEEE 754 binary64 with round-to-nearest-even (the default mode),
 *     evaluated in double precision (FLT_EVAL_METHOD == 0: SSE2, not x87),
 *   - no multiply-add is fused (-ffp-contract=off) and no -ffast-math,
 *   - nothing overflows (Dekker's split multiplies by 2^27 + 1: |x| < 2^995 for every split
 *     operand) and no product underflows (see predicates.c for the scaling that ensures it).
 * Output lengths are bounded by the algorithms (sum: elen + flen, scale: 2 elen); callers
 * size their stack buffers with those bounds.  Not a public header: include only from
 * src/geom/. */
#ifndef I2M_GEOM_EXPANSION_H
#define I2M_GEOM_EXPANSION_H

#include <float.h>

#if !defined(FLT_EVAL_METHOD) || FLT_EVAL_METHOD != 0
#error "i2m predicates need double expressions evaluated in double precision (SSE2, FLT_EVAL_METHOD == 0)"
#endif
#ifdef __FAST_MATH__
#error "i2m predicates must not be compiled with -ffast-math"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/** Unit roundoff of binary64 round-to-nearest: 2^-53. */
#define I2M_EX_EPS 0x1p-53
/** Dekker's splitter 2^27 + 1: splits a 53-bit significand into two halves of <= 26 bits. */
#define I2M_EX_SPLITTER 134217729.0

/** x + y = a + b exactly, x = fl(a + b); requires |a| >= |b| (or a == 0). */
static inline void i2m_ex_fast_two_sum(double a, double b, double *x, double *y)
{
  const double s = a + b;
  const double bv = s - a;
  *x = s;
  *y = b - bv;
}

/** x + y = a + b exactly, x = fl(a + b); no precondition (Knuth's Two-Sum). */
static inline void i2m_ex_two_sum(double a, double b, double *x, double *y)
{
  const double s = a + b;
  const double bv = s - a;
  const double av = s - bv;
  *x = s;
  *y = (a - av) + (b - bv);
}

/** Rounding error of x = fl(a - b): returns y with x + y = a - b exactly. */
static inline double i2m_ex_two_diff_tail(double a, double b, double x)
{
  const double bv = a - x;
  const double av = x + bv;
  return (a - av) + (bv - b);
}

/** Dekker's split: hi + lo = a, each with at most 26 significant bits. */
static inline void i2m_ex_split(double a, double *hi, double *lo)
{
  const double c = I2M_EX_SPLITTER * a;
  const double big = c - a;
  const double h = c - big;
  *hi = h;
  *lo = a - h;
}

/** x + y = a * b exactly, x = fl(a * b), with b already split into bhi + blo. */
static inline void i2m_ex_two_product_presplit(double a, double b, double bhi, double blo,
                                               double *x, double *y)
{
  double ahi, alo;
  const double p = a * b;
  i2m_ex_split(a, &ahi, &alo);
  const double e1 = p - ahi * bhi;
  const double e2 = e1 - alo * bhi;
  const double e3 = e2 - ahi * blo;
  *x = p;
  *y = alo * blo - e3;
}

/** x + y = a * b exactly, x = fl(a * b) (Dekker's Two-Product). */
static inline void i2m_ex_two_product(double a, double b, double *x, double *y)
{
  double bhi, blo;
  i2m_ex_split(b, &bhi, &blo);
  i2m_ex_two_product_presplit(a, b, bhi, blo, x, y);
}

/** x + y = a * a exactly (Two-Product specialised to a square). */
static inline void i2m_ex_two_square(double a, double *x, double *y)
{
  double ahi, alo;
  const double p = a * a;
  i2m_ex_split(a, &ahi, &alo);
  const double e1 = p - ahi * ahi;
  const double e3 = e1 - (ahi + ahi) * alo;
  *x = p;
  *y = alo * alo - e3;
}

/** Writes the nonzero ones of (lo, hi) (|lo| < |hi| or lo == 0) to h; returns the length. */
static inline int i2m_ex_from_pair(double lo, double hi, double *h)
{
  int n = 0;
  if (lo != 0.0) h[n++] = lo;
  if (hi != 0.0) h[n++] = hi;
  return n;
}

/** Sign (-1, 0, +1) of an expansion (zero-free, increasing magnitude). */
static inline int i2m_ex_sign(int len, const double *e)
{
  if (len == 0) return 0;
  return e[len - 1] > 0.0 ? 1 : -1;
}

/** h = e + f (Shewchuk's Fast-Expansion-Sum with zero elimination).  h has room for
 *  elen + flen components and must not alias e or f.  Returns the length of h. */
int i2m_ex_sum(int elen, const double *e, int flen, const double *f, double *h);

/** h = e - f, as i2m_ex_sum. */
int i2m_ex_diff(int elen, const double *e, int flen, const double *f, double *h);

/** h = b * e (Shewchuk's Scale-Expansion with zero elimination).  h has room for 2 elen
 *  components and must not alias e.  Returns the length of h. */
int i2m_ex_scale(int elen, const double *e, double b, double *h);

/** h = a * b - c * d exactly; h has room for 4 components.  Returns the length. */
int i2m_ex_two_products_diff(double a, double b, double c, double d, double *h);

#endif
