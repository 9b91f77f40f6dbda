/* i2m geometry layer (layer 1): constructions and quality measures in double precision:
 * tetrahedron and triangle circumcentres, radius-edge ratio, dihedral and planar angles.
 * Pure functions, thread safe.  Decisions that must be exact use predicates.h instead. */
#ifndef I2M_GEOMETRY_H
#define I2M_GEOMETRY_H

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Circumcentre c and squared circumradius of tet abcd.  Returns 0 on success, -1 when the
 *  tet is (numerically) flat, in which case c is set far away and *r2 to +inf. */
int i2m_tet_circumcenter(const double a[3], const double b[3], const double c[3], const double d[3],
                         double cc[3], double *r2);

/** Six times the signed volume of tet abcd (positive for a positive tet), in doubles. */
double i2m_tet_signed_volume6(const double a[3], const double b[3], const double c[3], const double d[3]);

/** Squared length of the shortest edge of tet abcd. */
double i2m_tet_min_edge2(const double a[3], const double b[3], const double c[3], const double d[3]);

/** Radius-edge ratio (circumradius / shortest edge) of tet abcd (inf if flat). */
double i2m_tet_radius_edge(const double a[3], const double b[3], const double c[3], const double d[3]);

/** The six dihedral angles of tet abcd in degrees (edges ab, ac, ad, bc, bd, cd). */
void i2m_tet_dihedral_angles(const double a[3], const double b[3], const double c[3], const double d[3],
                             double angles[6]);

/** Cosines of the six dihedral angles of tet abcd (same edge order as the angles). */
void i2m_tet_dihedral_cosines(const double a[3], const double b[3], const double c[3], const double d[3],
                              double cosines[6]);

/** Circumcentre and squared circumradius of triangle abc (in its plane). */
int i2m_tri_circumcenter(const double a[3], const double b[3], const double c[3], double cc[3],
                         double *r2);

/** Smallest planar angle of triangle abc in degrees. */
double i2m_tri_min_angle(const double a[3], const double b[3], const double c[3]);

static inline double i2m_dist2(const double a[3], const double b[3])
{
  double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}

#ifdef __cplusplus
}
#endif
#endif
