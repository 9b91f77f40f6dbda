/* i2m image layer (layer 2): Euclidean distance transform with feature transform over the
 * tissue interfaces of a label image, in physical units (anisotropic spacing), and the
 * geometric oracles built on it (ARCHITECTURE §3):
 *   - closest interface point to any point, and its distance;
 *   - the first label change along a segment, by bisection on the label oracle.
 *
 * Interfaces are the voxel faces between two voxels of different labels (outside the image
 * counts as label 0).  Boundary voxels are the voxels with such a face.  The feature
 * transform gives, for every voxel of the box K = (bounding box of the boundary voxels),
 * the nearest boundary voxel centre; for a point outside K the closest point is found
 * from its projection on K, exactly: K is convex and holds every interface, so
 * d(p)^2 = dist(p, K)^2 + d(proj_K p)^2.  All points are in the grid frame (image.h). */
#ifndef I2M_EDT_H
#define I2M_EDT_H

#include "i2m/image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct i2m_edt {
  const i2m_image_t *img;  /**< borrowed: must outlive the transform */
  int64_t lo[3], m[3];     /**< voxel box K: voxels lo .. lo+m-1 along each axis */
  double inv_m[3];         /**< 1 / m (index arithmetic without divisions) */
  double inv_spacing[3];   /**< 1 / spacing */
  int32_t *ft;             /**< owned: [m2][m1][m0] box-linear index of the nearest boundary
                                voxel, or -1 when the image has no interface */
  int64_t nboundary;       /**< number of boundary voxels */
} i2m_edt_t;

/** Computes the feature transform of @p img (OpenMP-parallel over scanlines).  An image
 *  without any interface gives a transform with nboundary = 0.  Not collective. */
i2m_err_t i2m_edt_create(const i2m_image_t *img, i2m_edt_t **out);
void i2m_edt_destroy(i2m_edt_t **e);

/** Closest interface point z to p (grid frame) and its squared distance; +inf (and z = p)
 *  when there is no interface.  pair (may be NULL) receives the label indices on the two
 *  sides of the interface there, smaller first.  When a cheap lower bound shows that the
 *  distance exceeds sqrt(max_d2), returns +inf without computing z (pass INFINITY to always
 *  compute it).  Thread safe. */
double i2m_edt_closest(const i2m_edt_t *e, const double p[3], double max_d2, double z[3], int pair[2]);

/** The same query with p and z in world coordinates (the mesher's frame). */
double i2m_edt_closest_world(const i2m_edt_t *e, const double p[3], double max_d2, double z[3], int pair[2]);

/** Along the segment a -> b (world coordinates) whose end labels differ, a point where the
 *  label changes from a's, to within @p tol: returns it in x and the labels on its two
 *  sides.  Thread safe. */
void i2m_edt_bisect(const i2m_image_t *img, const double a[3], const double b[3], double tol, double x[3],
                    int *label_a, int *label_b);

#ifdef __cplusplus
}
#endif
#endif
