/* i2m labelled tetrahedral mesh (layer 4, refine): the product the mesher hands to the
 * writers and reports.  A plain container: world coordinates, tetrahedra with the original
 * label value of their tissue, and the interface triangles between different labels.
 *
 * Interface triangles are oriented by a rank of labels: the background (0) ranks below every
 * tissue, tissues rank by value.  A triangle's normal points from the higher-ranked label to
 * the lower one: out of the meshed domain on the outer boundary (pair (0, L)), and from the
 * larger label value to the smaller between two tissues. */
#ifndef I2M_TETMESH_H
#define I2M_TETMESH_H

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct i2m_tetmesh {
  int64_t nv;          /**< number of vertices */
  double *xyz;         /**< owned: [nv][3] world coordinates (mm) */
  int64_t nt;          /**< number of tetrahedra */
  int32_t *tet;        /**< owned: [nt][4] vertex indices (0-based), positive orientation */
  int64_t *tet_label;  /**< owned: [nt] original label value (the material) */
  int64_t ntri;        /**< number of interface triangles */
  int32_t *tri;        /**< owned: [ntri][3] vertex indices, oriented so that the normal
                            (right-hand rule) points from tri_label[2i+1] to tri_label[2i]:
                            from the higher label to the lower, hence out of the meshed
                            domain on the outer boundary (the Medit / mmg / Gmsh convention) */
  int64_t *tri_label;  /**< owned: [ntri][2] label values, the lower first in the order of
                            i2m_label_ranks_below (background 0, then tissues by value) */
  int64_t *gid;        /**< owned, or NULL: [nv] the vertices' global ids (a piece of a
                            distributed mesh: writers add the array GlobalNodeId) */
} i2m_tetmesh_t;

/** True when label value @p a ranks below @p b in an interface pair (the background 0 below
 *  every tissue, tissues by value; the same as a < b when no label is negative). */
static inline bool i2m_label_ranks_below(int64_t a, int64_t b)
{
  return a != b && (a == 0 || (b != 0 && a < b));
}

/** Puts the tets in the order of a space-filling curve (Morton, of each tet's first vertex in a
 *  grid of 2^8 cells along each axis of the mesh's box; ties in their order before), numbers
 *  the vertices as the tets first use them, and orders the interface triangles along the same
 *  curve: the same mesh, whatever order extraction gave (a piece of more than 2^32 tets or
 *  triangles is left in that order). */
i2m_err_t i2m_tetmesh_sort(i2m_tetmesh_t *m);
/** Allocates a mesh with room for the given counts (arrays uninitialised, counts set). */
i2m_err_t i2m_tetmesh_create(int64_t nv, int64_t nt, int64_t ntri, i2m_tetmesh_t **out);
/** Frees a mesh; accepts NULL; sets *m = NULL. */
void i2m_tetmesh_destroy(i2m_tetmesh_t **m);

#ifdef __cplusplus
}
#endif
#endif
