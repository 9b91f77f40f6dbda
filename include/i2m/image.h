/* i2m image layer (layer 2): one in-memory label image with its geometry, the readers for
 * NRRD, NIfTI-1, MetaImage and INR, and the label oracle.
 *
 * Frames.  World coordinates follow the LPS convention of ITK and DICOM (x to the patient's
 * left, y posterior, z superior); NIfTI's RAS is converted on reading.  A voxel index
 * (i,j,k) has world position  origin + dir * diag(spacing) * (i,j,k)  (voxel centres).
 * The "grid frame" is g = diag(spacing) * (i,j,k), an axis-aligned frame in mm with voxel
 * (0,0,0)'s centre at the origin; i2m_image_grid_to_world() maps it to the world (a rigid
 * motion when dir is orthonormal, which the readers ensure).  The mesher works in world
 * coordinates, or, for an image far from the world's origin, in the world shifted to the
 * image's corner (i2m_image_mesh_shift) with its points snapped so that the shift back is
 * exact: either way the coordinates it writes are exactly those its predicates decided on. */
#ifndef I2M_IMAGE_H
#define I2M_IMAGE_H

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Scalar type of the voxels in the file. */
typedef enum {
  I2M_SCALAR_INT8, I2M_SCALAR_UINT8, I2M_SCALAR_INT16, I2M_SCALAR_UINT16,
  I2M_SCALAR_INT32, I2M_SCALAR_UINT32, I2M_SCALAR_INT64, I2M_SCALAR_UINT64,
  I2M_SCALAR_FLOAT32, I2M_SCALAR_FLOAT64
} i2m_scalar_t;

/** Largest number of distinct label values in one image (label indices are uint16). */
#define I2M_MAX_LABELS 65535

/** A label image.  Voxels hold label *indices* into label_value[]; index 0 is always the
 *  background value 0 (its count may be 0).  Other indices are in increasing value order.
 *  An index is stored in one byte, vox[], plus a second plane vox_hi[] of high bytes that
 *  exists only when some index exceeds 255: one byte per voxel for nearly every label map
 *  (read indices with i2m_image_index()). */
typedef struct i2m_image {
  int64_t n[3];            /**< voxels along i, j, k (each >= 1) */
  double spacing[3];       /**< voxel size along i, j, k in mm (> 0) */
  double origin[3];        /**< world (LPS) position of the centre of voxel (0,0,0) */
  double dir[3][3];        /**< dir[r][c]: world component r of index axis c; orthonormal */
  i2m_scalar_t file_type;  /**< voxel type found in the file */
  uint8_t *vox;            /**< owned: [n2][n1][n0] low bytes of the label indices, i fastest */
  uint8_t *vox_hi;         /**< owned: [n2][n1][n0] high bytes, or NULL when every index < 256 */
  int nlabels;             /**< number of label indices (>= 1, background included) */
  int64_t *label_value;    /**< owned: [nlabels] original label values; [0] = 0 */
  int64_t *label_count;    /**< owned: [nlabels] voxel counts */
  char *path;              /**< owned: file it came from ("" for synthetic images) */
  struct i2m_label_names *names; /**< owned, or NULL: tissue names of labels present in the image
                                      (a 3D Slicer segmentation's segment names, or the colour
                                      table <stem>.ctbl beside the image file) */
} i2m_image_t;

/** Tissue names of some label values (from a `.ctbl` colour table beside the image, or a 3D
 *  Slicer segmentation's segment names).  value[i] and name[i] go together, values distinct. */
typedef struct i2m_label_names {
  int64_t n;      /**< number of named labels */
  int64_t *value; /**< owned: [n] label values */
  char **name;    /**< owned: [n] NUL-terminated names, each owned */
  int32_t *colour; /**< owned: [n] 0xRRGGBB from the colour table, or -1 (none given) */
} i2m_label_names_t;

/** The name of label @p value, or NULL (also when @p names is NULL). */
const char *i2m_label_name(const i2m_label_names_t *names, int64_t value);
/** Its colour 0xRRGGBB from the colour table, or -1 (none, or no name). */
int32_t i2m_label_colour(const i2m_label_names_t *names, int64_t value);
/** Frees the names; accepts NULL; sets *names = NULL. */
void i2m_label_names_destroy(i2m_label_names_t **names);

/** Reads a label image; the format is chosen by content and extension (.nrrd, .nhdr, .nii,
 *  .nii.gz, .mha, .mhd, .inr, .inr.gz; a 3D Slicer segmentation .seg.nrrd is a NRRD file).
 *  Tissue names come with it (img->names): the segment names of a segmentation, else those of
 *  a 3D Slicer colour table <stem>.ctbl in the same directory (stem: the file name without its
 *  image extension), when there is one; a malformed table is ignored with one warning.  On error *out is NULL and the message names the file
 *  and the problem.  Not collective. */
i2m_err_t i2m_image_read(const char *path, i2m_image_t **out);

/** File formats the readers know. */
typedef enum {
  I2M_IMAGE_FORMAT_UNKNOWN = 0,
  I2M_IMAGE_FORMAT_NRRD,      /**< .nrrd, .nhdr + data file */
  I2M_IMAGE_FORMAT_NIFTI,     /**< NIfTI-1: .nii, .nii.gz, .hdr + .img */
  I2M_IMAGE_FORMAT_METAIMAGE, /**< .mha, .mhd + data file */
  I2M_IMAGE_FORMAT_INR        /**< Inrimage: .inr, .inr.gz */
} i2m_image_format_t;

/** Like i2m_image_read(), and also reports the format found in *format (may be NULL; set
 *  even when reading fails after the format was recognised).  Not collective; thread safe
 *  (no shared state; the error message is per thread). */
i2m_err_t i2m_image_read_format(const char *path, i2m_image_t **out, i2m_image_format_t *format);

/** How to read an image (zero-initialised: the defaults). */
typedef struct {
  bool allow_external_data; /**< a detached header (.nhdr, .mhd) may name a data file outside
                                 its own directory (refused by default) */
  bool header_only;         /**< the header only: size, geometry, type, data file checked;
                                 no voxels (vox NULL, nlabels 0) */
} i2m_image_read_opts_t;

/** i2m_image_read_format() with options (NULL: the defaults). */
i2m_err_t i2m_image_read_with(const char *path, const i2m_image_read_opts_t *opts, i2m_image_t **out,
                              i2m_image_format_t *format);

/** Short lower-case name of a format: "nrrd", "nifti", "metaimage", "inr" or "unknown". */
const char *i2m_image_format_name(i2m_image_format_t format);

/** Builds an image from raw label values (int64, i fastest) with the given geometry: dir is
 *  the direction matrix as 9 values, row by row (dir[3r+c] = world component r of index
 *  axis c), or NULL for identity.  The values are copied. */
i2m_err_t i2m_image_create_from_values(const int64_t n[3], const double spacing[3],
                                       const double origin[3], const double *dir,
                                       const int64_t *values, i2m_image_t **out);

/** The image's description (geometry, label table, path, tissue names) as one buffer (the
 *  caller frees it with i2m_free), without the voxels: for the dist layer, which broadcasts an
 *  image read on one rank.  Host byte order. */
i2m_err_t i2m_image_pack_meta(const i2m_image_t *img, void **buf, size_t *len);
/** An image from such a buffer, its voxels allocated (vox, and vox_hi when the packed image
 *  had them), not filled. */
i2m_err_t i2m_image_unpack_meta(const void *buf, size_t len, i2m_image_t **out);

/** Frees the voxels once no label lookup is needed any more (the geometry and the label
 *  table stay). */
void i2m_image_release_voxels(i2m_image_t *img);

/** Frees an image; accepts NULL; sets *img = NULL. */
void i2m_image_destroy(i2m_image_t **img);

/** Name of a scalar type ("uint8", "int16", ...). */
const char *i2m_scalar_name(i2m_scalar_t t);

/** Label index of the voxel with linear index i ((k * n1 + j) * n0 + i). */
static inline int i2m_image_index(const i2m_image_t *img, int64_t i)
{
  return img->vox_hi ? img->vox[i] | img->vox_hi[i] << 8 : img->vox[i];
}

/** The voxel (i,j,k) that contains grid-frame point g; false outside the image (or NaN). */
static inline bool i2m_image_voxel_at(const i2m_image_t *img, const double g[3], int64_t idx[3])
{
  for (int a = 0; a < 3; a++) {
    double u = g[a] / img->spacing[a] + 0.5;
    if (!(u >= 0.0)) return false; /* also rejects NaN */
    idx[a] = (int64_t)u;
    if (idx[a] >= img->n[a]) return false;
  }
  return true;
}

/** Label index of a grid-frame point: the voxel that contains it, 0 outside the image. */
static inline int i2m_image_label_at(const i2m_image_t *img, const double g[3])
{
  int64_t idx[3];
  if (!i2m_image_voxel_at(img, g, idx)) return 0;
  return i2m_image_index(img, (idx[2] * img->n[1] + idx[1]) * img->n[0] + idx[0]);
}

/** Label index of voxel (i,j,k); 0 outside the image. */
static inline int i2m_image_label_voxel(const i2m_image_t *img, int64_t i, int64_t j, int64_t k)
{
  if (i < 0 || j < 0 || k < 0 || i >= img->n[0] || j >= img->n[1] || k >= img->n[2]) return 0;
  return i2m_image_index(img, (k * img->n[1] + j) * img->n[0] + i);
}

/** 6-connected components of the labels of a block of voxels (label 0 included), as runs
 *  along i: run r has label lab[r], starts at x0[r] (relative to the block) in its row
 *  (rows (j, k) in order, row[] their first runs) and belongs to the component whose root run
 *  is par[r]; size[root] counts its voxels. */
typedef struct {
  int64_t lo[3], n[3]; /**< the block: voxels lo .. lo + n - 1 */
  int64_t *row;        /**< owned: [n1 n2 + 1] */
  int32_t *x0, *len;   /**< owned: [nruns] */
  uint16_t *lab;       /**< owned: [nruns] label index */
  int64_t *par;        /**< owned: [nruns] root run of the component */
  int64_t *size;       /**< owned: [nruns] voxels of the component (at roots) */
  int64_t nruns;
} i2m_components_t;

/** Reads the label indices of voxels (i0 .. i0 + n - 1, j, k), all inside the image, from an
 *  image or a transform (ctx). */
typedef void (*i2m_label_row_fn)(const void *ctx, int64_t i0, int64_t j, int64_t k, int64_t n, uint16_t *out);

/** Components of the block lo .. lo + n - 1 (inside the image), read a row at a time. */
i2m_err_t i2m_components_build(const int64_t lo[3], const int64_t n[3], i2m_label_row_fn read_row, const void *ctx,
                               i2m_components_t *c);
/** Components of a whole image (its voxels must be resident). */
i2m_err_t i2m_image_components(const i2m_image_t *img, i2m_components_t *c);
/** Root run of voxel (i,j,k)'s component, -1 outside the block (its size: c->size[root]). */
int64_t i2m_components_find(const i2m_components_t *c, int64_t i, int64_t j, int64_t k);
/** Root run of voxel (i,j,k)'s component if the voxel has label index lab, else -1 (also
 *  outside the block): the label from the runs, without a read of the image. */
int64_t i2m_components_find_label(const i2m_components_t *c, int64_t i, int64_t j, int64_t k, int lab);
void i2m_components_free(i2m_components_t *c);

/** Grid frame -> world (LPS). */
void i2m_image_grid_to_world(const i2m_image_t *img, const double g[3], double w[3]);

/** World (LPS) -> grid frame (dir is orthonormal: its inverse is its transpose). */
static inline void i2m_image_world_to_grid(const i2m_image_t *img, const double w[3], double g[3])
{
  double d0 = w[0] - img->origin[0], d1 = w[1] - img->origin[1], d2 = w[2] - img->origin[2];
  for (int c = 0; c < 3; c++) g[c] = img->dir[0][c] * d0 + img->dir[1][c] * d1 + img->dir[2][c] * d2;
}

/** Label index of a world point (the voxel that contains it, 0 outside the image). */
static inline int i2m_image_label_at_world(const i2m_image_t *img, const double w[3])
{
  double g[3];
  i2m_image_world_to_grid(img, w, g);
  return i2m_image_label_at(img, g);
}

/** World bounding box of the image block (outer voxel faces). */
void i2m_image_world_bounds(const i2m_image_t *img, double lo[3], double hi[3]);
/** World bounding box of the voxels first..last (inclusive, outer voxel faces). */
void i2m_image_world_bounds_of(const i2m_image_t *img, const int64_t first[3], const int64_t last[3], double lo[3],
                               double hi[3]);
/** The shift of the frame the image is meshed in (world = mesh + s, i2m_refine_params_t):
 *  per axis, the origin's coordinate when it lies at least 8 of the image's extents from the
 *  world's origin (so the mesh's coordinates are small and its points can be snapped for an
 *  exact shift back), else 0: the world's coordinates then lose at most 4 bits against the
 *  image's own corner, and a mesh near the origin is not rounded at all. */
void i2m_image_mesh_shift(const i2m_image_t *img, double s[3]);

/** Determinant sign of dir (+1 or -1): -1 means the grid->world map flips orientation, so
 *  writers swap two vertices of every tetrahedron to keep positive volumes. */
int i2m_image_handedness(const i2m_image_t *img);

#ifdef __cplusplus
}
#endif
#endif
