/* i2m geometry layer (layer 1): constructions and quality measures in double precision:
 * tetrahedron and triangle circumcentres, radius-edge ratio, dihedral and planar angles.
 * Pure functions, thread safe.  Decisions that must be exact use predicates.h instead. */
#ifndef I2M_GEOMETRY_H
#define I2M_GEOMETRY_H

#include <math.h>

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The circumcentre of a nearly flat tet, in double-double arithmetic (plain doubles lose
 *  every digit); see i2m_tet_circumcenter, which calls it. */
int i2m_tet_circumcenter_flat(const double a[3], const double b[3], const double c[3], const double d[3],
                              double cc[3], double *r2);

/** Circumcentre c and squared circumradius of tet abcd.  Returns 0 on success, -1 when the
 *  tet is flat, in which case c is set far away and *r2 to +inf.  Inline: the refinement
 *  computes it for every tet it creates.
 *  c - a = (|u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v)) / (2 u.(v x w)), u = b - a, ... */
static inline int i2m_tet_circumcenter(const double a[3], const double b[3], const double c[3], const double d[3],
                                       double cc[3], double *r2)
{
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
  const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
  const double vw0 = vy * wz - vz * wy, vw1 = vz * wx - vx * wz, vw2 = vx * wy - vy * wx;
  const double wu0 = wy * uz - wz * uy, wu1 = wz * ux - wx * uz, wu2 = wx * uy - wy * ux;
  const double uv0 = uy * vz - uz * vy, uv1 = uz * vx - ux * vz, uv2 = ux * vy - uy * vx;
  const double den = 2.0 * (ux * vw0 + uy * vw1 + uz * vw2);
  const double lu = ux * ux + uy * uy + uz * uz, lv = vx * vx + vy * vy + vz * vz, lw = wx * wx + wy * wy + wz * wz;
  const double scale = lu + lv + lw;
  /* |den| > 1e-11 scale^1.5, squared; otherwise double precision is not enough */
  if (!(den * den > 1e-22 * scale * scale * scale)) return i2m_tet_circumcenter_flat(a, b, c, d, cc, r2);
  const double inv = 1.0 / den;
  const double x0 = (lu * vw0 + lv * wu0 + lw * uv0) * inv;
  const double x1 = (lu * vw1 + lv * wu1 + lw * uv1) * inv;
  const double x2 = (lu * vw2 + lv * wu2 + lw * uv2) * inv;
  cc[0] = a[0] + x0;
  cc[1] = a[1] + x1;
  cc[2] = a[2] + x2;
  *r2 = x0 * x0 + x1 * x1 + x2 * x2;
  return 0;
}

/** Six times the signed volume of tet abcd (positive for a positive tet), in doubles. */
double i2m_tet_signed_volume6(const double a[3], const double b[3], const double c[3], const double d[3]);

/** Squared length of the shortest edge of tet abcd. */
double i2m_tet_min_edge2(const double a[3], const double b[3], const double c[3], const double d[3]);

/** Radius-edge ratio (circumradius / shortest edge) of tet abcd (inf if flat). */
double i2m_tet_radius_edge(const double a[3], const double b[3], const double c[3], const double d[3]);

/** The six dihedral angles of tet abcd in degrees (edges ab, ac, ad, bc, bd, cd). */
void i2m_tet_dihedral_angles(const double a[3], const double b[3], const double c[3], const double d[3],
                             double angles[6]);

/** The smallest dihedral angle of tet abcd in degrees. */
double i2m_tet_min_dihedral(const double a[3], const double b[3], const double c[3], const double d[3]);

/** The cosine of that smallest angle (the largest of the six): compare angles by it, one
 *  acos only when the angle itself is wanted. */
double i2m_tet_max_dihedral_cosine(const double a[3], const double b[3], const double c[3], const double d[3]);

/** The angle in degrees whose cosine is c (clamped to [-1, 1]). */
static inline double i2m_degrees_of_cosine(double c)
{
  return acos(c > 1.0 ? 1.0 : c < -1.0 ? -1.0 : c) * (180.0 / I2M_PI);
}

/** Cosines of the six dihedral angles of tet abcd (same edge order as the angles). */
void i2m_tet_dihedral_cosines(const double a[3], const double b[3], const double c[3], const double d[3],
                              double cosines[6]);
/** The six dihedral cosines of tet abcd as fractions, cos = num / sqrt(den2) (den2 > 0 unless a
 *  face is flat): a test against a bound needs no root or division (i2m_cosine_at_least). */
void i2m_tet_dihedral_terms(const double a[3], const double b[3], const double c[3], const double d[3], double num[6],
                            double den2[6]);

/** Is num / sqrt(den2) >= f?  (Squares compared, signs first.) */
static inline bool i2m_cosine_at_least(double num, double den2, double f)
{
  if (f > 0) return num >= 0 && num * num >= f * f * den2;
  return num >= 0 || num * num <= f * f * den2;
}

/** Circumcentre and squared circumradius of triangle abc (in its plane). */
int i2m_tri_circumcenter(const double a[3], const double b[3], const double c[3], double cc[3],
                         double *r2);

/** Smallest planar angle of triangle abc in degrees. */
double i2m_tri_min_angle(const double a[3], const double b[3], const double c[3]);

/** Does the box [box[0..2], box[3..5]] (closed) hold point x?  (NaN: no.) */
static inline bool i2m_box_holds(const double box[6], const double x[3])
{
  return (x[0] >= box[0]) & (x[1] >= box[1]) & (x[2] >= box[2]) & (x[0] <= box[3]) & (x[1] <= box[4]) & (x[2] <= box[5]);
}

/** r = a - b. */
static inline void i2m_sub3(const double a[3], const double b[3], double r[3])
{
  r[0] = a[0] - b[0];
  r[1] = a[1] - b[1];
  r[2] = a[2] - b[2];
}

/** r = a x b. */
static inline void i2m_cross3(const double a[3], const double b[3], double r[3])
{
  r[0] = a[1] * b[2] - a[2] * b[1];
  r[1] = a[2] * b[0] - a[0] * b[2];
  r[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double i2m_dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static inline double i2m_dist2(const double a[3], const double b[3])
{
  double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}

#ifdef __cplusplus
}
#endif
#endif
