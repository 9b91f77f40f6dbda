/* i2m refine layer (layer 4): quality and per-label figures of an extracted mesh, for the
 * run report.  (bin/i2m-check recomputes all of them independently from the written file.) */
#ifndef I2M_QUALITY_H
#define I2M_QUALITY_H

#include "i2m/image.h"
#include "i2m/tetmesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Per-label figures. */
typedef struct {
  int64_t value;        /**< original label value */
  int64_t ntets;        /**< tets carrying it */
  double volume;        /**< their volume, mm^3 */
  double voxel_volume;  /**< voxel count x voxel volume, mm^3 */
} i2m_label_figures_t;

/** Tets by band of dihedral angle: smallest angle below 5, 10, 15, 20 degrees; largest above
 *  160, 170 degrees (the bands of the finite-element quality goal: 15 and 160). */
#define I2M_DIHEDRAL_NLOW 4
#define I2M_DIHEDRAL_NHIGH 2
typedef struct {
  int64_t below[I2M_DIHEDRAL_NLOW];
  int64_t above[I2M_DIHEDRAL_NHIGH];
} i2m_dihedral_bands_t;

/** The bands' bounds in degrees (k-th lower band, k-th upper band). */
double i2m_dihedral_low_degrees(int k);
double i2m_dihedral_high_degrees(int k);
/** Counts one tet into the bands from its six dihedral cosines (i2m_tet_dihedral_cosines). */
void i2m_dihedral_bands_add(i2m_dihedral_bands_t *b, const double cs[6]);
/** a += b. */
void i2m_dihedral_bands_merge(i2m_dihedral_bands_t *a, const i2m_dihedral_bands_t *b);

typedef struct {
  double min_dihedral, max_dihedral;  /**< degrees */
  i2m_dihedral_bands_t bands;         /**< tets per dihedral band */
  int64_t dihedral_hist[180];         /**< 1-degree bins */
  double max_radius_edge;
  int64_t n_ratio_above;              /**< tets above the ratio bound */
  double min_facet_angle;             /**< smallest planar angle of an interface triangle */
  int64_t n_facet_below;              /**< interface triangles below the facet angle bound */
  int64_t n_facet_below_junction;     /**< ... of which touch a line where >= 3 labels meet */
  double ratio_bound, facet_bound;
  int nlabels;
  i2m_label_figures_t *labels;        /**< owned: [nlabels] every foreground label of the image */
} i2m_quality_t;

/** Computes the figures of mesh @p m (world coordinates) against the image's labels.
 *  Free with i2m_quality_free. */
i2m_err_t i2m_quality_compute(const i2m_tetmesh_t *m, const i2m_image_t *img, double ratio_bound,
                              double facet_bound, i2m_quality_t *q);
void i2m_quality_free(i2m_quality_t *q);

#ifdef __cplusplus
}
#endif
#endif
