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
 * d(p)^2 = dist(p, K)^2 + d(proj_K p)^2.  All points are in the grid frame (image.h).
 *
 * The transform also answers label queries.  K holds every foreground voxel, so outside K
 * the label is 0; inside, when the feature index and the label index fit together in 32
 * bits (nearly always), each voxel's word carries its label index in the high bits, and the
 * image's own voxels may be released: the mesher then holds 4 bytes per voxel of K instead
 * of 5 per voxel of the image. */
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
  double w2k[3][4];        /**< world -> voxel coordinates relative to K, + 1/2 (voxel v of K
                                spans [v, v + 1) along each axis): u = w2k[.][0..2] p + w2k[.][3] */
  double k2w[3][4];        /**< the inverse map: voxel coordinates relative to K -> world */
  int32_t *ft;             /**< owned: [m2][m1][m0] box-linear index of the nearest boundary
                                voxel (the bits of feat_mask) and, when labels_packed, the
                                voxel's label index above them (read with the accessors) */
  int64_t nboundary;       /**< number of boundary voxels */
  uint32_t feat_mask;      /**< bits of a word that hold the feature index */
  int label_shift;         /**< position of the label index in a word (labels_packed) */
  bool labels_packed;      /**< label queries need no image voxels */
} i2m_edt_t;

/** Box-linear index of the nearest boundary voxel of box voxel idx. */
static inline uint32_t i2m_edt_feature(const i2m_edt_t *e, int64_t idx) { return (uint32_t)e->ft[idx] & e->feat_mask; }

/** Label index of voxel (i,j,k) (0 outside the image), from the packed words or the image. */
static inline int i2m_edt_label_voxel(const i2m_edt_t *e, int64_t i, int64_t j, int64_t k)
{
  if (!e->labels_packed) return i2m_image_label_voxel(e->img, i, j, k);
  i -= e->lo[0];
  j -= e->lo[1];
  k -= e->lo[2];
  if (i < 0 || j < 0 || k < 0 || i >= e->m[0] || j >= e->m[1] || k >= e->m[2]) return 0; /* outside K */
  return (int)((uint32_t)e->ft[(k * e->m[1] + j) * e->m[0] + i] >> e->label_shift);
}

/** Label index of a grid-frame point: the voxel that contains it, floor(g / spacing + 1/2)
 *  along each axis (the mesher's one voxel rule), 0 outside the image. */
int i2m_edt_label_at(const i2m_edt_t *e, const double g[3]);

/** Label index of a world point: the same voxel rule, in the form i2m_edt_probe_world uses
 *  (so the two always agree). */
int i2m_edt_label_at_world(const i2m_edt_t *e, const double w[3]);

/** The voxel (image indices) that holds the point whose voxel-frame coordinates are u
 *  (i2m_edt_world_to_k), by the same rule; false outside K (where every label is 0). */
bool i2m_edt_image_voxel_k(const i2m_edt_t *e, const double u[3], int64_t v[3]);

/** The 6-connected components of the labels over K (which holds every labelled voxel),
 *  read from the packed words (or the image). */
i2m_err_t i2m_edt_components(const i2m_edt_t *e, i2m_components_t *c);

/** Computes the feature transform of @p img (OpenMP-parallel over scanlines).  An image
 *  without any interface gives a transform with nboundary = 0.  Not collective. */
i2m_err_t i2m_edt_create(const i2m_image_t *img, i2m_edt_t **out);

/** Processes that compute one transform together (the dist layer makes this): process `part`
 *  of `nparts` computes its share of each pass, and exchange() gives every process the
 *  others' shares: for each block b < nblocks, an all-gather in place of the ranges
 *  [displ[q], displ[q] + count[q]) of buf + b * stride from each process q; after agreeing on
 *  err (any process's error is every process's result; with one, nothing is exchanged, and
 *  buf may be NULL). */
typedef struct {
  int part, nparts;
  i2m_err_t (*exchange)(void *ctx, i2m_err_t err, int32_t *buf, const int64_t *count, const int64_t *displ,
                        int64_t nblocks, int64_t stride);
  void *ctx;
} i2m_edt_share_t;

/** i2m_edt_create, each process computing a share (collective over the share's processes when
 *  nparts > 1; NULL: alone).  Every process ends with the whole transform, the same bits. */
i2m_err_t i2m_edt_create_shared(const i2m_image_t *img, const i2m_edt_share_t *share, i2m_edt_t **out);
void i2m_edt_destroy(i2m_edt_t **e);

/** Closest interface point z to p (grid frame) and its squared distance; +inf (and z = p)
 *  when there is no interface.  pair (may be NULL) receives the label indices on the two
 *  sides of the interface there, smaller first.  When a cheap lower bound shows that the
 *  distance exceeds sqrt(max_d2), returns +inf without computing z (pass INFINITY to always
 *  compute it).  Thread safe. */
double i2m_edt_closest(const i2m_edt_t *e, const double p[3], double max_d2, double z[3], int pair[2]);

/** What the refinement asks about a point: its label and the closest interface point. */
typedef struct {
  int label;   /**< label index at the point (i2m_edt_label_at) */
  double d2;   /**< squared distance to the closest interface point; +inf when it was not
                    asked for, lies farther than the bound, or there is no interface */
  double z[3]; /**< the closest interface point (world), when d2 is finite */
  int pair[2]; /**< label indices on its two sides, smaller first */
} i2m_edt_probe_t;

/** The label at world point p and the closest interface point, unless a cheap lower bound
 *  (the distance to the voxel the feature transform names) shows it farther than
 *  sqrt(max_d2) (the same point as i2m_edt_closest; INFINITY asks for it at any distance).
 *  One change of frame and one voxel lookup.  Thread safe. */
void i2m_edt_probe_world(const i2m_edt_t *e, const double p[3], double max_d2, i2m_edt_probe_t *out);

/** The coordinates u of world point p in the transform's voxel frame (voxel v of K spans
 *  [v, v + 1) along each axis), where every probe starts.  Inline: the refinement asks it
 *  for every tet it creates. */
static inline void i2m_edt_world_to_k(const i2m_edt_t *e, const double p[3], double u[3])
{
  for (int k = 0; k < 3; k++) u[k] = e->w2k[k][0] * p[0] + e->w2k[k][1] * p[1] + e->w2k[k][2] * p[2] + e->w2k[k][3];
}

/** Box-linear index of the voxel of K that holds u (voxel frame), or -1 outside K (or NaN). */
static inline int64_t i2m_edt_voxel_k(const i2m_edt_t *e, const double u[3])
{
  if (!(u[0] >= 0.0 && u[0] < (double)e->m[0] && u[1] >= 0.0 && u[1] < (double)e->m[1] && u[2] >= 0.0 &&
        u[2] < (double)e->m[2]))
    return -1;
  return ((int64_t)u[2] * e->m[1] + (int64_t)u[1]) * e->m[0] + (int64_t)u[0];
}

/** i2m_edt_probe_world at p, whose voxel-frame coordinates u and voxel index vox =
 *  i2m_edt_voxel_k(e, u) are known already. */
void i2m_edt_probe_k(const i2m_edt_t *e, const double p[3], const double u[3], int64_t vox, double max_d2,
                     i2m_edt_probe_t *out);

/** The label i2m_edt_probe_k gives at u (voxel vox), without the closest point. */
int i2m_edt_label_k(const i2m_edt_t *e, const double u[3], int64_t vox);

/** Prefetching for callers that probe many points: the words a probe reads lie at random in
 *  a large array, so requesting them for every point first lets the loads overlap.
 *  i2m_edt_prefetch requests the word of voxel vox (i2m_edt_voxel_k); once that word has
 *  arrived, i2m_edt_prefetch_feature requests the words around the voxel it names, which the
 *  closest-point search reads.  Nothing for vox < 0 (outside K). */
static I2M_INLINE void i2m_edt_prefetch(const i2m_edt_t *e, int64_t vox)
{
  if (vox >= 0) I2M_PREFETCH(&e->ft[vox]);
}

static I2M_INLINE void i2m_edt_prefetch_feature(const i2m_edt_t *e, int64_t vox)
{
  if (vox < 0) return;
  const int64_t f = i2m_edt_feature(e, vox), s1 = e->m[0], s2 = e->m[0] * e->m[1], n = s2 * e->m[2];
  const int32_t *w = e->ft;
  I2M_PREFETCH(&w[f]); /* (and its neighbours along the row, nearly always on the same line) */
  if (f >= s1) I2M_PREFETCH(&w[f - s1]);
  if (f + s1 < n) I2M_PREFETCH(&w[f + s1]);
  if (f >= s2) I2M_PREFETCH(&w[f - s2]);
  if (f + s2 < n) I2M_PREFETCH(&w[f + s2]);
}

/** Along the segment a -> b (world coordinates) whose end labels differ, a point where the
 *  label changes from a's, to within @p tol: returns it in x and the labels on its two
 *  sides.  Thread safe. */
void i2m_edt_bisect(const i2m_edt_t *e, const double a[3], const double b[3], double tol, double x[3],
                    int *label_a, int *label_b);

#ifdef __cplusplus
}
#endif
#endif
