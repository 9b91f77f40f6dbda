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
 * FRAGMENT_MAX_TETS tets and less than FRAGMENT_MAX_VOXELS voxels of volume, that lies in a
 * component of the image (6-connected voxels of its label) of at least
 * FRAGMENT_MIN_IMAGE_VOXELS voxels and holds less than 1/FRAGMENT_COMPONENT_SHARE of that
 * component's volume: so small a piece cannot be what the mesh makes of that component,
 * which other pieces represent.  (Thin structures such as the knee's cartilage and ligaments,
 * one or two voxels thick, leave islands of 1 to 20 voxels where the mesh cannot follow a
 * neck.)  A piece of a small image component (a speck the image really has) is kept, and so
 * is the largest piece of a label that has no large one.  Relabelling removes the fragment's
 * faces with the new label from the interfaces and changes the label pair of its other
 * interface faces, which keep their geometry: every facet-angle and distance guarantee still
 * holds.
 *
 * Pieces come from a union-find over the tet slots, in parallel (compare-and-swap links,
 * always from the larger root to the smaller, so every piece ends with its smallest slot as
 * root whatever the threads did); the small ones are then treated in slot order, alone.  The
 * result is the same on any number of threads. */
#include "refine_impl.h"

#include <stdlib.h>

#define FRAGMENT_MAX_TETS 64
#define FRAGMENT_MAX_VOXELS 27.0
#define FRAGMENT_MIN_IMAGE_VOXELS 64
#define FRAGMENT_COMPONENT_SHARE 8.0 /* a fragment holds less than 1/8 of its image component */

/* ---- union-find over tet slots ---- */

static uint32_t uf_find(_Atomic uint32_t *par, uint32_t x)
{
  for (;;) {
    uint32_t p = atomic_load_explicit(&par[x], memory_order_relaxed);
    if (p == x) return x;
    uint32_t g = atomic_load_explicit(&par[p], memory_order_relaxed);
    if (g != p) /* path halving: any ancestor is a valid parent */
      atomic_compare_exchange_weak_explicit(&par[x], &p, g, memory_order_relaxed, memory_order_relaxed);
    x = g;
  }
}

static void uf_union(_Atomic uint32_t *par, uint32_t a, uint32_t b)
{
  for (;;) {
    a = uf_find(par, a);
    b = uf_find(par, b);
    if (a == b) return;
    if (a < b) {
      uint32_t x = a;
      a = b;
      b = x;
    }
    uint32_t expected = a; /* link the larger root under the smaller, if it is still a root */
    if (atomic_compare_exchange_strong_explicit(&par[a], &expected, b, memory_order_relaxed, memory_order_relaxed))
      return;
  }
}

/* par[t] = the smallest slot of t's piece (face-connected tets of one label); the number
 * of tets of each piece at its root in cnt (saturating at FRAGMENT_MAX_TETS + 1). */
static void mesh_pieces(const i2m_dt_t *dt, _Atomic uint32_t *par, _Atomic uint32_t *cnt)
{
  const int64_t n = i2m_dt_ntets_slots(dt);
  I2M_OMP(omp parallel)
  {
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++) {
      atomic_init(&par[t], (uint32_t)t);
      atomic_init(&cnt[t], 0);
    }
    I2M_OMP(omp for schedule(dynamic, 4096))
    for (int64_t t = 0; t < n; t++) {
      if (!tet_kept(dt, (uint32_t)t)) continue;
      const uint16_t l = tinfo(dt, (uint32_t)t)->label;
      for (int i = 0; i < 4; i++) {
        uint32_t nb = dt->tn[4 * (size_t)t + i];
        if (nb == I2M_DT_NONE || (nb >> 2) > (uint32_t)t) continue; /* each face once */
        if (tinfo(dt, nb >> 2)->label == l) uf_union(par, (uint32_t)t, nb >> 2); /* (a neighbour is alive) */
      }
    }
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++) {
      if (!tet_kept(dt, (uint32_t)t)) continue;
      const uint32_t root = uf_find(par, (uint32_t)t);
      atomic_store_explicit(&par[t], root, memory_order_relaxed); /* (an ancestor: finds stay right) */
      if (atomic_load_explicit(&cnt[root], memory_order_relaxed) <= FRAGMENT_MAX_TETS)
        atomic_fetch_add_explicit(&cnt[root], 1, memory_order_relaxed);
    }
  }
}

static uint32_t root_of(_Atomic uint32_t *par, uint32_t t) { return atomic_load_explicit(&par[t], memory_order_relaxed); }

static double tet_volume(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  return i2m_tet_signed_volume6(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]),
                                i2m_dt_xyz(dt, v[3])) / 6.0;
}

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
      const int m = nb == I2M_DT_NONE ? 0 : tinfo(dt, nb >> 2)->label;
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

/* A small piece: where its tets start in the sorted candidates, how many. */
typedef struct {
  uint32_t start, n;
  uint16_t label;
  double volume;
} piece_t;

static int cmp_u64(const void *a, const void *b)
{
  const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return (x > y) - (x < y);
}

/* The tets of small pieces as (root << 32 | slot), sorted (so grouped by piece, in slot
 * order); big[l] set when label l has a piece that is not small. */
static i2m_err_t small_piece_tets(const i2m_dt_t *dt, _Atomic uint32_t *par, _Atomic uint32_t *cnt, uint8_t *big,
                                      uint64_t **out, size_t *nout)
{
  const uint32_t n = i2m_dt_ntets_slots(dt);
  uint64_t *cand = NULL;
  size_t ncand = 0, cap = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(dt, t)) continue;
    const uint32_t root = root_of(par, t);
    if (atomic_load_explicit(&cnt[root], memory_order_relaxed) > FRAGMENT_MAX_TETS) {
      big[tinfo(dt, t)->label] = 1;
      continue;
    }
    if (ncand == cap) {
      cap = 2 * cap + 256;
      i2m_err_t err = i2m_realloc(cap, sizeof *cand, &cand);
      if (err != I2M_OK) {
        i2m_free(&cand);
        return err;
      }
    }
    cand[ncand++] = (uint64_t)root << 32 | t;
  }
  if (ncand > 0) qsort(cand, ncand, sizeof *cand, cmp_u64); /* (qsort wants an array even for none) */
  *out = cand;
  *nout = ncand;
  return I2M_OK;
}

/* The small pieces, with their volumes. */
static i2m_err_t small_pieces(const i2m_dt_t *dt, const uint64_t *cand, size_t ncand, piece_t **out, size_t *nout)
{
  piece_t *pc = NULL;
  size_t np = 0;
  size_t k = 0;
  while (k < ncand) {
    const uint32_t root = (uint32_t)(cand[k] >> 32);
    if (np % 256 == 0) {
      i2m_err_t err = i2m_realloc(np + 256, sizeof *pc, &pc);
      if (err != I2M_OK) {
        i2m_free(&pc);
        return err;
      }
    }
    piece_t *p = &pc[np++];
    *p = (piece_t){(uint32_t)k, 0, tinfo(dt, (uint32_t)cand[k])->label, 0.0};
    for (; k < ncand && (uint32_t)(cand[k] >> 32) == root; k++) {
      p->n++;
      p->volume += tet_volume(dt, (uint32_t)cand[k]);
    }
  }
  *out = pc;
  *nout = np;
  return I2M_OK;
}

/* Voxels of the image component in which piece p lies: the component of the voxel of the
 * first of its tets whose circumcentre lies in a voxel of its label (0 when none does). */
static int64_t piece_image_voxels(const i2m_refine_t *r, const i2m_components_t *ic, const uint64_t *cand,
                                  const piece_t *p)
{
  const i2m_edt_t *e = r->edt;
  for (uint32_t i = 0; i < p->n; i++) {
    tet_geom_t g;
    tet_centre(r, (uint32_t)cand[p->start + i], &g); /* (a flat tet's u is NaN: no voxel) */
    int64_t v[3];
    if (!i2m_edt_image_voxel_k(e, g.u, v) || i2m_edt_label_voxel(e, v[0], v[1], v[2]) != p->label) continue;
    const int64_t root = i2m_components_find(ic, v[0], v[1], v[2]);
    if (root >= 0) return ic->size[root];
  }
  return 0;
}

i2m_err_t i2m_refine_repair_fragments(i2m_refine_t *r)
{
  i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  const int nlabels = r->img->nlabels;
  _Atomic uint32_t *par = NULL, *cnt = NULL;
  uint64_t *cand = NULL;
  piece_t *pc = NULL;
  size_t ncand = 0, np = 0;
  int64_t *main_piece = NULL; /* per label: its largest piece when it has no big one, else -1 */
  uint8_t *big = NULL;
  double *area = NULL;
  i2m_components_t ic = {0};
  i2m_err_t err = I2M_OK;
  r->fragments = r->fragment_tets = 0;
  if (n == 0) return I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *par, &par));
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *cnt, &cnt));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)nlabels, sizeof *big, &big));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nlabels, sizeof *main_piece, &main_piece));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nlabels, sizeof *area, &area));
  const double t0 = i2m_wtime();
  mesh_pieces(dt, par, cnt);
  const double t1 = i2m_wtime();
  I2M_CALL_GOTO(err, done, small_piece_tets(dt, par, cnt, big, &cand, &ncand));
  I2M_CALL_GOTO(err, done, small_pieces(dt, cand, ncand, &pc, &np));
  for (int l = 0; l < nlabels; l++) main_piece[l] = -1;
  for (size_t k = 0; k < np; k++) { /* (ties: the first, in slot order) */
    const int l = pc[k].label;
    if (!big[l] && (main_piece[l] < 0 || pc[k].volume > pc[main_piece[l]].volume)) main_piece[l] = (int64_t)k;
  }
  const double voxel_volume = r->img->spacing[0] * r->img->spacing[1] * r->img->spacing[2];
  const double max_volume = FRAGMENT_MAX_VOXELS * voxel_volume;
  const double t2 = i2m_wtime();
  if (np > 0) I2M_CALL_GOTO(err, done, i2m_edt_components(r->edt, &ic));
  const double t3 = i2m_wtime();
  for (size_t k = 0; k < np; k++) {
    const piece_t *p = &pc[k];
    if (p->volume >= max_volume || main_piece[p->label] == (int64_t)k) continue;
    const int64_t iv = piece_image_voxels(r, &ic, cand, p);
    if (iv < FRAGMENT_MIN_IMAGE_VOXELS || p->volume * FRAGMENT_COMPONENT_SHARE >= (double)iv * voxel_volume) continue;
    const int m = best_neighbour_label(dt, cand + p->start, p->n, nlabels, area);
    for (uint32_t i = 0; i < p->n; i++) tinfo(dt, (uint32_t)cand[p->start + i])->label = (uint16_t)m;
    r->fragments++;
    r->fragment_tets += p->n;
  }
  i2m_debug("fragments: pieces %.3f s, %zu small ones %.3f s, image components %.3f s, decisions %.3f s", t1 - t0, np,
            t2 - t1, t3 - t2, i2m_wtime() - t3);
done:
  i2m_free(&par);
  i2m_free(&cnt);
  i2m_free(&cand);
  i2m_free(&pc);
  i2m_free(&big);
  i2m_free(&main_piece);
  i2m_free(&area);
  i2m_components_free(&ic);
  return err;
}
