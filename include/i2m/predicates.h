/* i2m geometry layer (layer 1): robust geometric predicates after Shewchuk's adaptive-
 * precision method (a floating-point filter with a rigorous error bound first, exact
 * expansion arithmetic when the filter cannot decide), and symbolic perturbation keyed on
 * global vertex ids so that every rank and thread decides degenerate cases the same way.
 *
 * Sign conventions (right-handed, as finite-element codes use them):
 *   orient3d(a,b,c,d) = det [b-a; c-a; d-a] (rows) = 6 x signed volume of tet abcd.
 *     > 0 when d lies on the side of plane abc toward which (b-a) x (c-a) points.
 *     A tetrahedron (v0,v1,v2,v3) is "positive" when orient3d(v0,v1,v2,v3) > 0.
 *   insphere(a,b,c,d,e) > 0 when e lies strictly inside the sphere through a,b,c,d and
 *     abcd is positive (the sign flips for a negative tet); 0 when the five points are
 *     cospherical (or a,b,c,d coplanar and e on that circle/plane configuration).
 *
 * Symbolic perturbation (insphere_sos): every point p with global id g is lifted to
 * w(p) = |p|^2 + eps^(2^rank(g)) where rank orders the five ids increasingly, eps -> 0+.
 * The perturbed determinant is never 0 unless two of the points coincide or all five are
 * coplanar.  It equals the exact sign when the exact insphere is non-zero.
 *
 * All functions are pure (no globals, thread safe, no heap; the exact fallback of insphere
 * uses about 100 KB of stack), and src/geom/ must be compiled with -ffp-contract=off and
 * without -ffast-math, with SSE2 doubles (FLT_EVAL_METHOD == 0; checked at compile time).
 *
 * Range where the signs are exact.  Coordinates must be finite (a NaN or infinity gives 0).
 * The absolute magnitude is unrestricted: the exact fallback scales each query by a power
 * of two, so uniformly huge (up to DBL_MAX) or tiny (down to subnormal) coordinates are
 * exact.  What matters is the spread inside one call: writing R for the ratio between the
 * largest |coordinate| and the smallest non-zero |coordinate| among the points of the call
 * (for orient3d and orient2d_proj: along each axis separately, as each axis is scaled on
 * its own), the result is exact (no overflow, no underflow of any product) whenever
 *   orient2d_proj: R <= 2^950,   orient3d: R <= 2^630 (~4e189),
 *   insphere, insphere_sos: R <= 2^360 (~2e108),
 * e.g. any mix of coordinates with magnitudes in [1e-54, 1e54] (zeros allowed).  Beyond
 * that, products of several of the smallest coordinates could underflow and the sign could
 * be wrong only when all larger terms cancel exactly.  The floating-point filter decides
 * only when its rigorous bound (which accounts for underflow and overflow) allows it;
 * otherwise the exact path runs, so the filter never limits the range. */
#ifndef I2M_PREDICATES_H
#define I2M_PREDICATES_H

#include <math.h>

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Exact sign (-1, 0, +1) of orient3d(a,b,c,d). */
int i2m_orient3d(const double a[3], const double b[3], const double c[3], const double d[3]);

/** Exact sign (-1, 0, +1) of insphere(a,b,c,d,e) (see the convention above). */
int i2m_insphere(const double a[3], const double b[3], const double c[3], const double d[3],
                 const double e[3]);

/** Sign of the symbolically perturbed insphere(a,b,c,d,e) with the global ids of the five
 *  points (ids must be distinct).  Returns 0 only for coincident points or five coplanar
 *  points (precisely: 0 exactly when the five points are coplanar; a query with two
 *  coincident points among non-coplanar ones still gets a consistent non-zero sign).
 *  Antisymmetric under any permutation of the (point, id) pairs. */
int i2m_insphere_sos(const double a[3], const double b[3], const double c[3], const double d[3],
                     const double e[3], i2m_gidx_t ia, i2m_gidx_t ib, i2m_gidx_t ic,
                     i2m_gidx_t id, i2m_gidx_t ie);

/** Non-robust double-precision values, for tests and for magnitudes (not for decisions). */
double i2m_orient3d_fast(const double a[3], const double b[3], const double c[3], const double d[3]);
double i2m_insphere_fast(const double a[3], const double b[3], const double c[3], const double d[3],
                         const double e[3]);

/** Exact sign of the 2D orientation of the projections of a, b, c on the coordinate plane
 *  that drops axis @p drop (0, 1 or 2): det [b-a; c-a] of the two remaining coordinates,
 *  taken in increasing axis order: (y,z) for drop 0, (x,z) for drop 1, (x,y) for drop 2
 *  (so for drop 1 it is minus the orientation seen along +y). */
int i2m_orient2d_proj(const double a[3], const double b[3], const double c[3], int drop);

/* ---- inline filters (Shewchuk's stage-A bounds with second-order terms raised so that they
 * also absorb the rounding of the bound and underflowed products; outside the checked
 * ranges the filter declines, see predicates.c) ---- */
#define I2M_PRED_EPS 0x1p-53
#define I2M_O3D_BOUND ((7.0 + 64.0 * I2M_PRED_EPS) * I2M_PRED_EPS)
#define I2M_ISP_BOUND ((16.0 + 256.0 * I2M_PRED_EPS) * I2M_PRED_EPS)
#define I2M_O3D_PERM_MIN 0x1p-500
#define I2M_O3D_ZMAX_MAX 0x1p450
#define I2M_ISP_PERM_MIN 0x1p-500
#define I2M_ISP_LIFT_MAX 0x1p300

/** Filter of orient3d: the sign when the floating-point error bound certifies it, 0 when
 *  undecided (then call i2m_orient3d).  Inline: the hot path of the Delaunay kernel. */
static inline int i2m_orient3d_filter(const double a[3], const double b[3], const double c[3],
                                  const double d[3])
{
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
  const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
  const double vxwy = vx * wy, wxvy = wx * vy; /* m(v,w) */
  const double uxwy = ux * wy, wxuy = wx * uy; /* m(u,w) */
  const double uxvy = ux * vy, vxuy = vx * uy; /* m(u,v) */
  const double det = uz * (vxwy - wxvy) - vz * (uxwy - wxuy) + wz * (uxvy - vxuy);
  const double auz = fabs(uz), avz = fabs(vz), awz = fabs(wz);
  const double perm = auz * (fabs(vxwy) + fabs(wxvy)) + avz * (fabs(uxwy) + fabs(wxuy)) +
                      awz * (fabs(uxvy) + fabs(vxuy));
  const double zm1 = auz > avz ? auz : avz;
  const double zmax = zm1 > awz ? zm1 : awz;
  const double bound = I2M_O3D_BOUND * perm;
  /* one well-predicted branch; the sign itself is computed without branching (NaN fails) */
  if ((fabs(det) > bound) & (perm >= I2M_O3D_PERM_MIN) & (zmax <= I2M_O3D_ZMAX_MAX))
    return (det > 0.0) - (det < 0.0);
  return 0;
}

/** det [x; y; z] of three rows already translated by a query point (plain floating point: a
 *  filter must certify its sign).  orient3d of a tet with one vertex replaced by the query
 *  point e is +-det of the other three translated by e (see i2m_orient3d_rows_bound). */
static inline double i2m_det3_rows(const double x[3], const double y[3], const double z[3])
{
  return x[2] * (y[0] * z[1] - z[0] * y[1]) - y[2] * (x[0] * z[1] - z[0] * x[1]) + z[2] * (x[0] * y[1] - y[0] * x[1]);
}

/** Error bound of i2m_det3_rows for rows whose coordinates are at most mx, my, mz in absolute
 *  value per axis (differences to the query point, as orient3d's filter uses them): the
 *  permanent is at most 6 mx my mz; 7 absorbs the rounding of the factors.  INFINITY outside
 *  the ranges where the filter is rigorous (see i2m_orient3d_filter). */
static inline double i2m_orient3d_rows_bound(double mx, double my, double mz)
{
  const double perm = 7.0 * mx * my * mz;
  return ((perm >= I2M_O3D_PERM_MIN) & (mz <= I2M_O3D_ZMAX_MAX)) ? I2M_O3D_BOUND * perm : (double)INFINITY;
}

static inline double i2m_pred_max4_(double a, double b, double c, double d)
{
  double x = a > b ? a : b, y = c > d ? c : d;
  return x > y ? x : y;
}

/** Filter of insphere on rows already translated by the query point e and lifted:
 *  r = (x - ex, y - ey, z - ez, |r|^2) for a, b, c, d.  The sign when certified, else 0.
 *  Semi-static bound: with M_x, M_y, M_z the largest |coordinate| per axis and
 *  L = M_x^2 + M_y^2 + M_z^2, the permanent of Shewchuk's stage-A bound is at most
 *  24 L M_x M_y M_z; 25 absorbs the rounding of every factor, so the bound stays rigorous. */
/** The insphere determinant of rows already translated by the query point e and lifted:
 *  r = (x - ex, y - ey, z - ez, |r|^2) for a, b, c, d (plain floating point: a filter must
 *  certify its sign). */
static inline double i2m_insphere_det_rows(const double ra[4], const double rb[4], const double rc[4],
                                           const double rd[4])
{
  const double ax = ra[0], ay = ra[1], az = ra[2], bx = rb[0], by = rb[1], bz = rb[2];
  const double cx = rc[0], cy = rc[1], cz = rc[2], dx = rd[0], dy = rd[1], dz = rd[2];
  const double mab = ax * by - bx * ay, mac = ax * cy - cx * ay, mad = ax * dy - dx * ay;
  const double mbc = bx * cy - cx * by, mbd = bx * dy - dx * by, mcd = cx * dy - dx * cy;
  const double dbcd = bz * mcd - cz * mbd + dz * mbc;
  const double dacd = az * mcd - cz * mad + dz * mac;
  const double dabd = az * mbd - bz * mad + dz * mab;
  const double dabc = az * mbc - bz * mac + cz * mab;
  return (ra[3] * dbcd - rb[3] * dacd) + (rc[3] * dabd - rd[3] * dabc);
}

/** Error bound of i2m_insphere_det_rows for rows whose coordinates are at most mx, my, mz
 *  in absolute value per axis: the permanent of Shewchuk's stage-A bound is at most
 *  24 L mx my mz with L = mx^2 + my^2 + mz^2; 25 absorbs the rounding of every factor, so
 *  the bound stays rigorous.  INFINITY (nothing certified) outside the checked ranges.
 *  Any larger mx, my, mz give a valid (looser) bound, so one bound can serve every tet of a
 *  cavity. */
static inline double i2m_insphere_rows_bound(double mx, double my, double mz)
{
  const double L = mx * mx + my * my + mz * mz;
  const double perm = 25.0 * L * mx * my * mz;
  return ((perm >= I2M_ISP_PERM_MIN) & (L <= 0.25 * I2M_ISP_LIFT_MAX)) ? I2M_ISP_BOUND * perm : (double)INFINITY;
}

/** Filter of insphere on translated, lifted rows (see i2m_insphere_det_rows): the sign
 *  when certified by the semi-static bound of these four rows, else 0. */
static inline int i2m_insphere_filter_rows(const double ra[4], const double rb[4], const double rc[4],
                                           const double rd[4])
{
  const double det = i2m_insphere_det_rows(ra, rb, rc, rd);
  const double mx = i2m_pred_max4_(fabs(ra[0]), fabs(rb[0]), fabs(rc[0]), fabs(rd[0]));
  const double my = i2m_pred_max4_(fabs(ra[1]), fabs(rb[1]), fabs(rc[1]), fabs(rd[1]));
  const double mz = i2m_pred_max4_(fabs(ra[2]), fabs(rb[2]), fabs(rc[2]), fabs(rd[2]));
  if (fabs(det) > i2m_insphere_rows_bound(mx, my, mz)) return (det > 0.0) - (det < 0.0);
  return 0;
}

/** Translated, lifted row of point q for a query point e (see i2m_insphere_filter_rows). */
static inline void i2m_insphere_row(const double q[3], const double e[3], double r[4])
{
  r[0] = q[0] - e[0];
  r[1] = q[1] - e[1];
  r[2] = q[2] - e[2];
  r[3] = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
}

/** Filter of insphere: the sign when certified, 0 when undecided. */
static inline int i2m_insphere_filter(const double a[3], const double b[3], const double c[3],
                                      const double d[3], const double e[3])
{
  double ra[4], rb[4], rc[4], rd[4];
  i2m_insphere_row(a, e, ra);
  i2m_insphere_row(b, e, rb);
  i2m_insphere_row(c, e, rc);
  i2m_insphere_row(d, e, rd);
  return i2m_insphere_filter_rows(ra, rb, rc, rd);
}

/** Exact insphere with symbolic perturbation, for when i2m_insphere_filter declined. */
int i2m_insphere_sos_exact(const double a[3], const double b[3], const double c[3], const double d[3],
                           const double e[3], i2m_gidx_t ia, i2m_gidx_t ib, i2m_gidx_t ic, i2m_gidx_t id,
                           i2m_gidx_t ie);

#ifdef __cplusplus
}
#endif
#endif
