/* Refine layer: repair of fragments, after refinement and before extraction.
 *
 * Where a region narrows below delta (a one-voxel neck, a protrusion one voxel thick),
 * Delaunay refinement can leave a handful of tets of label L apart from the rest of L: tets
 * whose circumcentres fall in L voxels while their vertices lie on the interface around
 * them, floating just outside the object or hanging on it by an edge or a vertex.  In a
 * finite-element model such a piece is a body of its own, or a hinge: the stiffness matrix
 * becomes singular.  A fragment is given the label it shares the most face area with (0: it
 * leaves the mesh).
 *
 * A fragment is a face-connected component of one label in the mesh (a piece) of at most
 * pieces_small_tets tets and less than PIECE_FRAGMENT_VOXELS voxels of volume, that lies in a
 * component of the image (6-connected voxels of its label) of at least
 * PIECE_FRAGMENT_MIN_IMAGE_VOXELS voxels and holds less than 1/PIECE_FRAGMENT_SHARE of that
 * component's volume (pieces_is_fragment): so small a piece cannot be what the mesh makes of that component,
 * which other pieces represent.  (Thin structures such as the knee's cartilage and ligaments,
 * one or two voxels thick, leave islands of 1 to 20 voxels where the mesh cannot follow a
 * neck.)  A piece of a small image component (a speck the image really has) is kept, and so
 * is the largest piece of a label that has no large one.  Relabelling removes the fragment's
 * faces with the new label from the interfaces and changes the label pair of its other
 * interface faces, which keep their geometry: every facet-angle and distance guarantee still
 * holds.
 *
 * The decisions are made on the pieces of the whole mesh (pieces.c: i2m_pieces_resolve, from
 * the labels before any relabelling; ties by keys of global ids), so every rank relabels its
 * own tets of a fragment alike, and the result is the same on any number of threads and
 * ranks. */
#include "refine_impl.h"

i2m_err_t i2m_refine_repair_fragments(i2m_refine_t *r)
{
  i2m_dt_t *dt = r->dt;
  r->fragments = r->fragment_tets = 0;
  if (i2m_dt_ntets_slots(dt) == 0) return I2M_OK;
  const double t0 = i2m_wtime();
  const i2m_pieces_global_t *G;
  I2M_CALL(i2m_refine_groups(r, I2M_WHOLE_MIN_VOXELS, &G));
  const pieces_t *P = &r->pieces;
  const int64_t n = i2m_dt_ntets_slots(dt);
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t t = 0; t < n; t++) {
    if (!tet_kept(dt, (uint32_t)t)) continue;
    const i2m_group_t *g = &G->group[G->part_group[pieces_index(P, (uint32_t)t)]];
    if (g->relabel >= 0) tinfo(dt, (uint32_t)t)->label = (uint16_t)g->relabel;
  }
  r->fragments = G->fragments; /* (of the whole mesh) */
  r->fragment_tets = G->fragment_tets;
  i2m_debug("fragments: %zu pieces, %lld fragments, %.3f s", G->ngroups, (long long)G->fragments, i2m_wtime() - t0);
  if (r->fragments) return pieces_after_relabel(r); /* (labels changed) */
  return I2M_OK;
}
