/* i2m: labelled tetrahedral meshes from segmented 3D images, as a library.
 *
 * One call meshes a label array held in memory (every voxel a tissue label, 0 the
 * background) and returns flat arrays: points, tetrahedra with their labels, and the
 * interface triangles with their label pairs.  The options are those of the command line
 * (`i2m --help`), with the same defaults.  Build with `pkg-config --cflags --libs i2m`.
 *
 *   i2m_options_t o;
 *   i2m_options_init(&o);
 *   o.delta = 1.5;
 *   i2m_mesh_t *m = NULL;
 *   if (i2m_mesh_labels(labels, I2M_LABELS_UINT8, dims, spacing, NULL, NULL, &o, &m) != 0)
 *     fprintf(stderr, "%s\n", i2m_last_error());
 *   ... m->points, m->tets, m->materials ...
 *   i2m_mesh_free(&m);
 *
 * Threads: the call uses OpenMP threads (o.threads, default all cores).  One process: the
 * library does not use MPI even when it was built with it.  Calls from several threads of
 * the caller at once are not supported. */
#ifndef I2M_H
#define I2M_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define I2M_VERSION_STRING "0.1"

/** The element type of the label array. */
typedef enum {
  I2M_LABELS_UINT8 = 1,
  I2M_LABELS_INT8,
  I2M_LABELS_UINT16,
  I2M_LABELS_INT16,
  I2M_LABELS_UINT32,
  I2M_LABELS_INT32,
  I2M_LABELS_INT64
} i2m_label_type_t;

/** Meshing options; i2m_options_init() sets the command line's defaults.  Lengths in mm. */
typedef struct {
  double delta;          /**< surface sampling density (--delta); 0: from the image (default) */
  double ratio;          /**< radius-edge bound (--ratio, 2) */
  double facet_angle;    /**< smallest angle of interface triangles in degrees (--facet-angle, 30) */
  double size;           /**< largest circumradius (--size); 0: no bound (default) */
  int nlabel_sizes;      /**< --size-label: that many (label, size) pairs */
  const int64_t *label_size_values; /**< [nlabel_sizes] label values (borrowed) */
  const double *label_sizes;        /**< [nlabel_sizes] their size bounds (borrowed) */
  int nregions;          /**< --region: that many world boxes with their own bounds */
  const double *regions; /**< [nregions][8]: x0, y0, z0, x1, y1, z1 (opposite corners, mm), size,
                              ratio (0: o.ratio) (borrowed) */
  double sliver_angle;   /**< sliver perturbation target in degrees (--sliver-angle); 0: off */
  int threads;           /**< OpenMP threads; 0: all cores (default) */
  int deterministic;     /**< 1: the same mesh for any number of threads (--deterministic) */
  int depth;             /**< --depth of the deterministic mode's octree; 0: the default */
  double coarse_factor;  /**< a coarse mesh first at this factor (--coarse-factor, 4; 1: none) */
  int pin;               /**< 1: bind the threads to cores (default 0: the caller's threads are its own) */
  int check;             /**< 1: check the triangulation before extraction (--check; slow) */
  uint64_t seed;         /**< random seed (--seed) */
  double max_memory;     /**< refuse runs estimated above this many bytes; 0: the machine's memory */
  int verbose;           /**< 0: silent (default), 1: progress lines on stderr, 2: debug lines */
} i2m_options_t;

/** The mesh: plain arrays the caller reads and frees with i2m_mesh_free(). */
typedef struct {
  int64_t npoints;
  double *points;           /**< [npoints][3] world coordinates (mm) */
  int64_t ntets;
  int32_t *tets;            /**< [ntets][4] 0-based point indices, positive orientation */
  int64_t *materials;       /**< [ntets] the label value of each tetrahedron */
  int64_t ntriangles;
  int32_t *triangles;       /**< [ntriangles][3] interface triangles (between two labels, or a
                                 label and the background 0) */
  int64_t *triangle_labels; /**< [ntriangles][2] the two label values, smaller first */
} i2m_mesh_t;

/** Sets the defaults. */
void i2m_options_init(i2m_options_t *opts);

/** Meshes a label image.  @p labels: dims[0] x dims[1] x dims[2] values of @p type, the first
 *  index fastest (C order of a numpy array indexed [k][j][i]; Fortran order of [i][j][k]).
 *  @p spacing: voxel size along each index axis (mm, > 0).  @p origin: world position of the
 *  centre of voxel (0,0,0), or NULL for 0.  @p direction: 3x3 row-major, direction[3*r + c] =
 *  world component r of index axis c (orthonormal), or NULL for the identity.  @p opts: NULL
 *  for the defaults.  Returns 0 and *mesh on success; otherwise a non-zero code, *mesh NULL,
 *  and i2m_last_error() says why (2: a bad argument or option, 1: anything else). */
int i2m_mesh_labels(const void *labels, i2m_label_type_t type, const int64_t dims[3], const double spacing[3],
                    const double origin[3], const double direction[9], const i2m_options_t *opts, i2m_mesh_t **mesh);

/** Frees a mesh; accepts NULL; sets *mesh = NULL. */
void i2m_mesh_free(i2m_mesh_t **mesh);

/** The message of the last failed call of this thread ("" if none). */
const char *i2m_last_error(void);

#ifdef __cplusplus
}
#endif
#endif
