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
 * PIECE_SMALL_TETS tets and less than PIECE_FRAGMENT_VOXELS voxels of volume, that lies in a
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
 * Pieces come from pieces.c (a union-find whose roots are the smallest slots, whatever the
 * threads did); the small ones are then treated in slot order, alone.  The result is the
 * same on any number of threads. */
#include "refine_impl.h"

/* The label sharing the most face area with the tets of a piece (the low words of c[0..n);
 * 0 when only the outside borders them).  area: [nlabels] scratch. */
static int best_neighbour_label(const i2m_dt_t *dt, const uint64_t *c, uint32_t n, int nlabels, double *area)
{
  static const int FACE[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  const uint16_t l = tinfo(dt, (uint32_t)c[0])->label;
  for (int m = 0; m < nlabels; m++) area[m] = 0;
  for (uint32_t k = 0; k < n; k++) {
    const uint32_t t = (uint32_t)c[k], *v = dt->tv + 4 * (size_t)t;
    for (int i = 0; i < 4; i++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + i];
      const int m = nb >= I2M_DT_REMOTE ? 0 : tinfo(dt, nb >> 2)->label;
      if (m == l) continue; /* a face inside the fragment */
      const double *a = i2m_dt_xyz(dt, v[FACE[i][0]]), *b = i2m_dt_xyz(dt, v[FACE[i][1]]), *d = i2m_dt_xyz(dt, v[FACE[i][2]]);
      const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
      const double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2], z = u[0] * w[1] - u[1] * w[0];
      area[m] += sqrt(x * x + y * y + z * z);
    }
  }
  int best = 0;
  for (int m = 1; m < nlabels; m++)
    if (area[m] > area[best]) best = m;
  return best;
}

i2m_err_t i2m_refine_repair_fragments(i2m_refine_t *r)
{
  i2m_dt_t *dt = r->dt;
  const int nlabels = r->img->nlabels;
  int64_t *main_piece = NULL; /* per label: its largest piece when it has no big one, else -1 */
  uint8_t *big = NULL;
  double *area = NULL;
  const pieces_t *P;
  i2m_err_t err = I2M_OK;
  r->fragments = r->fragment_tets = 0;
  if (i2m_dt_ntets_slots(dt) == 0) return I2M_OK;
  const double t0 = i2m_wtime();
  I2M_CALL(pieces_get(r, &P));
  const double t1 = i2m_wtime();
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)nlabels, sizeof *big, &big));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nlabels, sizeof *main_piece, &main_piece));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nlabels, sizeof *area, &area));
  for (int l = 0; l < nlabels; l++) main_piece[l] = -1;
  for (size_t k = 0; k < P->npieces; k++)
    if (!P->piece[k].small) big[P->piece[k].label] = 1;
  for (size_t k = 0; k < P->npieces; k++) { /* (ties: the first, in slot order) */
    const piece_t *p = &P->piece[k];
    const int l = p->label;
    if (p->small && !big[l] && (main_piece[l] < 0 || p->volume > P->piece[main_piece[l]].volume)) main_piece[l] = (int64_t)k;
  }
  for (size_t k = 0; k < P->npieces; k++) {
    const piece_t *p = &P->piece[k];
    if (main_piece[p->label] == (int64_t)k || !pieces_is_fragment(r, p)) continue;
    const int m = best_neighbour_label(dt, P->small + p->start, p->n, nlabels, area);
    for (uint32_t i = 0; i < p->n; i++) tinfo(dt, (uint32_t)P->small[p->start + i])->label = (uint16_t)m;
    r->fragments++;
    r->fragment_tets += p->n;
  }
  i2m_debug("fragments: %zu pieces %.3f s, decisions %.3f s", P->npieces, t1 - t0, i2m_wtime() - t1);
done:
  if (r->fragments) pieces_invalidate(r); /* (labels changed) */
  i2m_free(&big);
  i2m_free(&main_piece);
  i2m_free(&area);
  return err;
}
