/* Refine layer: the size of a run, estimated before it starts.
 *
 * Refinement samples the interfaces at spacing ~delta, so the interface triangles number
 * about (interface area) / delta^2, and the tets filling the volume follow the surface's
 * grading, or the size bounds where those are tighter.  The interface area is measured on the
 * voxel staircase (faces between voxels of different labels, the image's border included),
 * which overestimates a smooth surface by about 1.5 (absorbed in the constants).  The
 * constants were fitted on the knee, liver and abdominal atlases (DESIGN: "Limits up
 * front"): on the seven images of ../shared/data at default options the output had 0.78 to
 * 1.35 times the estimated tets, the knee at delta 0.33 and 0.085 1.01 and 1.02 times; enough to
 * refuse a run that cannot fit before it starts. */
#include "refine_impl.h"

#define TETS_PER_DELTA2 3.2    /* tets per mm^2 of staircase interface, times delta^2 */
#define TETS_PER_SIZE3 4.0     /* tets per mm^3 times size^3 (the bound is on circumradii) */
#define FINER_EXPONENT 0.1     /* below the default delta, tets grow as delta^-2.1, not ^-2 */
#define BYTES_PER_TET 125.0    /* the peak of a one-process run, per output tet, */
#define BYTES_PER_VOXEL 6.0    /* with the image and its distance transform */
#define BYTES_FIXED 64e6

/* Interface faces (weighted by their areas) of slice k and the faces between it and k+1. */
static double slice_interface(const i2m_image_t *img, int64_t k)
{
  const double ax = img->spacing[1] * img->spacing[2], ay = img->spacing[0] * img->spacing[2],
               az = img->spacing[0] * img->spacing[1];
  double a = 0;
  for (int64_t j = 0; j < img->n[1]; j++)
    for (int64_t i = 0; i < img->n[0]; i++) {
      const int l = i2m_image_label_voxel(img, i, j, k);
      if (i == 0 && l) a += ax; /* (the image's border: a label against the outside) */
      if (j == 0 && l) a += ay;
      if (k == 0 && l) a += az;
      if (l != i2m_image_label_voxel(img, i + 1, j, k)) a += ax;
      if (l != i2m_image_label_voxel(img, i, j + 1, k)) a += ay;
      if (l != i2m_image_label_voxel(img, i, j, k + 1)) a += az;
    }
  return a;
}

/* The tets the size bounds ask for: each label's (or the global one) over the label's
 * volume, and each region's over its box clipped to the image's. */
static double size_term(const i2m_image_t *img, const i2m_refine_params_t *p, double voxel_mm3)
{
  double tets = 0;
  for (int l = 1; l < img->nlabels; l++) {
    double s = p->size;
    for (int k = 0; k < p->nlabel_sizes; k++)
      if (p->label_sizes[k].value == img->label_value[l]) s = fmin(s, p->label_sizes[k].size);
    if (isfinite(s)) tets += TETS_PER_SIZE3 * (double)img->label_count[l] * voxel_mm3 / (s * s * s);
  }
  double lo[3], hi[3];
  i2m_image_world_bounds(img, lo, hi);
  for (int k = 0; k < p->nregions; k++) {
    const i2m_region_t *g = &p->regions[k];
    double v = 1;
    for (int a = 0; a < 3; a++) v *= fmax(0.0, fmin(g->hi[a], hi[a]) - fmax(g->lo[a], lo[a]));
    tets += TETS_PER_SIZE3 * v / (g->size * g->size * g->size);
  }
  return tets;
}

void i2m_refine_estimate(const i2m_image_t *img, const i2m_refine_params_t *p, i2m_refine_estimate_t *e)
{
  double area = 0;
#pragma omp parallel for reduction(+ : area) schedule(dynamic, 4)
  for (int64_t k = 0; k < img->n[2]; k++) area += slice_interface(img, k);
  const double voxel_mm3 = img->spacing[0] * img->spacing[1] * img->spacing[2];
  int64_t fg = 0;
  for (int l = 1; l < img->nlabels; l++) fg += img->label_count[l];
  const double delta = isnan(p->delta) ? i2m_refine_default_delta(img) : p->delta;
  e->delta = delta;
  e->interface_mm2 = area;
  e->volume_mm3 = (double)fg * voxel_mm3;
  const double finer = fmax(1.0, i2m_refine_default_delta(img) / delta); /* (the volume's grading deepens) */
  e->tets = TETS_PER_DELTA2 * area / (delta * delta) * pow(finer, FINER_EXPONENT) + size_term(img, p, voxel_mm3);
  e->bytes = BYTES_PER_TET * e->tets + BYTES_PER_VOXEL * (double)img->n[0] * (double)img->n[1] * (double)img->n[2] +
             BYTES_FIXED;
}
