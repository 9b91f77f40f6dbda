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

/** Filter of insphere: the sign when certified, 0 when undecided. */
static inline int i2m_insphere_filter(const double a[3], const double b[3], const double c[3],
                                  const double d[3], const double e[3])
{
  const double ax = a[0] - e[0], ay = a[1] - e[1], az = a[2] - e[2];
  const double bx = b[0] - e[0], by = b[1] - e[1], bz = b[2] - e[2];
  const double cx = c[0] - e[0], cy = c[1] - e[1], cz = c[2] - e[2];
  const double dx = d[0] - e[0], dy = d[1] - e[1], dz = d[2] - e[2];
  /* xy-minors m(p,q) = px qy - qx py from the products pq1 = px qy, pq2 = qx py */
  const double ab1 = ax * by, ab2 = bx * ay, ac1 = ax * cy, ac2 = cx * ay;
  const double ad1 = ax * dy, ad2 = dx * ay, bc1 = bx * cy, bc2 = cx * by;
  const double bd1 = bx * dy, bd2 = dx * by, cd1 = cx * dy, cd2 = dx * cy;
  const double mab = ab1 - ab2, mac = ac1 - ac2, mad = ad1 - ad2;
  const double mbc = bc1 - bc2, mbd = bd1 - bd2, mcd = cd1 - cd2;
  const double dbcd = bz * mcd - cz * mbd + dz * mbc;
  const double dacd = az * mcd - cz * mad + dz * mac;
  const double dabd = az * mbd - bz * mad + dz * mab;
  const double dabc = az * mbc - bz * mac + cz * mab;
  const double la = ax * ax + ay * ay + az * az;
  const double lb = bx * bx + by * by + bz * bz;
  const double lc = cx * cx + cy * cy + cz * cz;
  const double ld = dx * dx + dy * dy + dz * dz;
  const double det = (la * dbcd - lb * dacd) + (lc * dabd - ld * dabc);
  /* permanent: the same tree on absolute values */
  const double aaz = fabs(az), abz = fabs(bz), acz = fabs(cz), adz = fabs(dz);
  const double pab = fabs(ab1) + fabs(ab2), pac = fabs(ac1) + fabs(ac2);
  const double pad = fabs(ad1) + fabs(ad2), pbc = fabs(bc1) + fabs(bc2);
  const double pbd = fabs(bd1) + fabs(bd2), pcd = fabs(cd1) + fabs(cd2);
  const double pbcd = abz * pcd + acz * pbd + adz * pbc;
  const double pacd = aaz * pcd + acz * pad + adz * pac;
  const double pabd = aaz * pbd + abz * pad + adz * pab;
  const double pabc = aaz * pbc + abz * pac + acz * pab;
  const double perm = (la * pbcd + lb * pacd) + (lc * pabd + ld * pabc);
  const double lifts = (la + lb) + (lc + ld);
  const double bound = I2M_ISP_BOUND * perm;
  if ((fabs(det) > bound) & (perm >= I2M_ISP_PERM_MIN) & (lifts <= I2M_ISP_LIFT_MAX))
    return (det > 0.0) - (det < 0.0);
  return 0;
}

/** Exact insphere with symbolic perturbation, for when i2m_insphere_filter declined. */
int i2m_insphere_sos_exact(const double a[3], const double b[3], const double c[3], const double d[3],
                           const double e[3], i2m_gidx_t ia, i2m_gidx_t ib, i2m_gidx_t ic, i2m_gidx_t id,
                           i2m_gidx_t ie);

#ifdef __cplusplus
}
#endif
#endif
