/* i2m geometry layer (layer 1): expansion arithmetic (sums and scaling of floating-point
 * expansions with zero elimination), the building blocks of the exact fallback of the
 * predicates.  Written after the algorithms of Shewchuk's DCG 1997 paper (Fast-Expansion-
 * Sum, Theorem 13; Scale-Expansion, Theorem 19); see expansion.h for the invariants. */
#include "expansion.h"

#include <math.h>

/* Merges e and (fs * f) by increasing magnitude on the fly and sums them with Two-Sum; the
 * running sum q carries upward, the rounding errors are the output components.  fs is
 * +1.0 or -1.0 (multiplying by it is exact). */
static int sum_signed(int elen, const double *e, int flen, const double *f, double fs,
                      double *h)
{
  int i = 0, j = 0, n = 0;
  if (elen == 0) {
    for (j = 0; j < flen; j++) h[j] = fs * f[j];
    return flen;
  }
  if (flen == 0) {
    for (i = 0; i < elen; i++) h[i] = e[i];
    return elen;
  }
  double ei = e[0], fj = fs * f[0];
  double g0, g1, q, t;
  /* g0, g1: the two smallest components; |g1| >= |g0| so Fast-Two-Sum applies. */
  if (fabs(fj) > fabs(ei)) { g0 = ei; ei = (++i < elen) ? e[i] : 0.0; }
  else { g0 = fj; fj = (++j < flen) ? fs * f[j] : 0.0; }
  if (j >= flen || (i < elen && fabs(fj) > fabs(ei))) { g1 = ei; ei = (++i < elen) ? e[i] : 0.0; }
  else { g1 = fj; fj = (++j < flen) ? fs * f[j] : 0.0; }
  i2m_ex_fast_two_sum(g1, g0, &q, &t);
  if (t != 0.0) h[n++] = t;
  while (i < elen && j < flen) {
    double g;
    if (fabs(fj) > fabs(ei)) { g = ei; ei = (++i < elen) ? e[i] : 0.0; }
    else { g = fj; fj = (++j < flen) ? fs * f[j] : 0.0; }
    i2m_ex_two_sum(q, g, &q, &t);
    if (t != 0.0) h[n++] = t;
  }
  for (; i < elen; i++) {
    i2m_ex_two_sum(q, e[i], &q, &t);
    if (t != 0.0) h[n++] = t;
  }
  for (; j < flen; j++) {
    i2m_ex_two_sum(q, fs * f[j], &q, &t);
    if (t != 0.0) h[n++] = t;
  }
  if (q != 0.0) h[n++] = q;
  return n;
}

int i2m_ex_sum(int elen, const double *e, int flen, const double *f, double *h)
{
  return sum_signed(elen, e, flen, f, 1.0, h);
}

int i2m_ex_diff(int elen, const double *e, int flen, const double *f, double *h)
{
  return sum_signed(elen, e, flen, f, -1.0, h);
}

int i2m_ex_scale(int elen, const double *e, double b, double *h)
{
  if (elen == 0 || b == 0.0) return 0;
  double bhi, blo, q, t, hi, lo, s;
  int n = 0;
  i2m_ex_split(b, &bhi, &blo);
  i2m_ex_two_product_presplit(e[0], b, bhi, blo, &q, &t);
  if (t != 0.0) h[n++] = t;
  for (int i = 1; i < elen; i++) {
    i2m_ex_two_product_presplit(e[i], b, bhi, blo, &hi, &lo);
    i2m_ex_two_sum(q, lo, &s, &t);
    if (t != 0.0) h[n++] = t;
    i2m_ex_fast_two_sum(hi, s, &q, &t);
    if (t != 0.0) h[n++] = t;
  }
  if (q != 0.0) h[n++] = q;
  return n;
}

int i2m_ex_two_products_diff(double a, double b, double c, double d, double *h)
{
  /* (x1 + y1) - x2 - y2 by two Grow-Expansion steps (Two-Sum chains, Shewchuk Theorem 10):
   * four nonoverlapping components in increasing magnitude, then zero elimination */
  double x1, y1, x2, y2, q, r0, r1, r2, r3;
  i2m_ex_two_product(a, b, &x1, &y1);
  i2m_ex_two_product(c, d, &x2, &y2);
  i2m_ex_two_sum(y1, -y2, &q, &r0);  /* (y1, x1) - y2 = (r0, q', x1') */
  i2m_ex_two_sum(x1, q, &q, &r1);    /* = (r0, r1, q) */
  i2m_ex_two_sum(r1, -x2, &r2, &r1); /* (r0, r1, q) - x2 */
  i2m_ex_two_sum(q, r2, &r3, &r2);   /* = (r0, r1, r2, r3) */
  int n = 0;
  if (r0 != 0.0) h[n++] = r0;
  if (r1 != 0.0) h[n++] = r1;
  if (r2 != 0.0) h[n++] = r2;
  if (r3 != 0.0) h[n++] = r3;
  return n;
}
