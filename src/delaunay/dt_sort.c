/* Delaunay layer: the live tets renumbered along a space-filling curve.
 *
 * Refinement hands out slots in the order its work comes, so after it the tets next to each
 * other in space lie anywhere in the arrays, and every step of a cavity search or a star
 * walk waits for memory.  Renumbered cell by cell, the cells of a grid over the labelled block
 * taken in Morton order, a tet's neighbours mostly sit in the same or nearby cache lines and
 * pages.  A finer order inside a cell would gain little: a cell holds a few dozen tets. */
#include "dt_impl.h"

#include <string.h>

#define AXIS_BITS 6                 /* 64 cells along each axis of the block: a few dozen tets each */
#define PREFETCH 16                 /* tets ahead whose first vertex is asked for */

/* The Morton code of the cell of tet t's first vertex (clamped to the box: the tets of the
 * virtual box's corners go to its faces).  One vertex, not the centroid: as good an order, and
 * a quarter of the reads. */
static uint32_t cell_code(const i2m_dt_t *dt, uint32_t t, const double lo[3], const double scale[3])
{
  return i2m_morton_code(i2m_dt_xyz(dt, dt->tv[4 * (size_t)t]), lo, scale, AXIS_BITS);
}

/* Each live tet's row of a per-tet array (`width` bytes per slot) into its new slot of dst. */
static void scatter_rows(const void *array, size_t width, const uint32_t *new_of, uint32_t nt, void *dst)
{
  const unsigned char *src = array;
  unsigned char *out = dst;
  for (uint32_t t = 0; t < nt; t++)
    if (new_of[t] != I2M_DT_NONE) memcpy(out + (size_t)new_of[t] * width, src + (size_t)t * width, width);
}

/* The neighbour words into their new slots of dst, each renumbered. */
static void scatter_neighbours(const uint32_t *tn, const uint32_t *new_of, uint32_t nt, uint32_t *dst)
{
  for (uint32_t t = 0; t < nt; t++) {
    if (new_of[t] == I2M_DT_NONE) continue;
    uint32_t *d = dst + 4 * (size_t)new_of[t];
    for (int i = 0; i < 4; i++) {
      const uint32_t f = tn[4 * (size_t)t + i];
      d[i] = f < I2M_DT_REMOTE ? new_of[f >> 2] << 2 | (f & 3) : f;
    }
  }
}

i2m_err_t i2m_dt_sort_tets(i2m_dt_t *dt, const double lo[3], const double hi[3])
{
  const uint32_t nt = i2m_dt_ntets_slots(dt);
  uint32_t *new_of = NULL, *rows = NULL; /* rows: the sort's words, then the arrays' rows */
  const size_t row_words = dt->pay_size > 4 * sizeof *dt->tv ? (dt->pay_size + 3) / 4 : 4;
  _Static_assert(4 * sizeof(uint32_t) == 2 * sizeof(uint64_t), "a row holds the sort's word and its scratch's");
  i2m_err_t err = i2m_malloc(nt ? nt : 1, sizeof *new_of, &new_of);
  if (err == I2M_OK) err = i2m_malloc((size_t)dt->cap_t * row_words, sizeof *rows, &rows);
  if (err != I2M_OK) goto done; /* (nothing changed) */
  double scale[3];
  for (int a = 0; a < 3; a++) scale[a] = hi[a] > lo[a] ? (double)(1u << AXIS_BITS) / (hi[a] - lo[a]) : 0.0;
  uint64_t *words = (uint64_t *)rows, *scratch = words + nt;
  uint32_t n = 0;
  for (uint32_t t = 0; t < nt; t++) {
    if (t + PREFETCH < nt) I2M_PREFETCH(dt->xyzw + 4 * (size_t)dt->tv[4 * (size_t)(t + PREFETCH)]);
    if (i2m_dt_alive(dt, t)) words[n++] = (uint64_t)cell_code(dt, t, lo, scale) << 32 | t;
  }
  const uint64_t *sorted = i2m_sort_by_code(words, scratch, n, 3 * AXIS_BITS);
  for (uint32_t t = 0; t < nt; t++) new_of[t] = I2M_DT_NONE;
  for (uint32_t k = 0; k < n; k++) new_of[(uint32_t)sorted[k]] = k;
  if (dt->pay_size) { /* (first, while rows has room for the widest row) */
    scatter_rows(dt->tpay, dt->pay_size, new_of, nt, rows);
    memcpy(dt->tpay, rows, (size_t)n * dt->pay_size);
  }
  uint32_t *meta = rows; /* (each tet keeps its generation, unmarked) */
  for (uint32_t t = 0; t < nt; t++)
    if (new_of[t] != I2M_DT_NONE) meta[new_of[t]] = i2m_dt_meta(dt, t) & ~I2M_TM_MARK;
  for (uint32_t k = 0; k < n; k++) atomic_store_explicit(&dt->meta[k], meta[k], memory_order_relaxed);
  for (uint32_t t = n; t < nt; t++) atomic_store_explicit(&dt->meta[t], I2M_TM_DEAD, memory_order_relaxed);
  /* tv and tn each into rows, which then takes the array's place (and its memory the next) */
  uint32_t *swap;
  scatter_rows(dt->tv, 4 * sizeof *dt->tv, new_of, nt, rows);
  swap = dt->tv, dt->tv = rows, rows = swap;
  scatter_neighbours(dt->tn, new_of, nt, rows);
  swap = dt->tn, dt->tn = rows, rows = swap;
  const uint32_t nv = i2m_dt_nverts_slots(dt);
  for (uint32_t v = 0; v < nv; v++)
    if (dt->vkind[v] != I2M_VK_DEAD && dt->vtet[v] < nt) dt->vtet[v] = new_of[dt->vtet[v]];
  dt->nfree_t = 0;
  atomic_store_explicit(&dt->nt_atomic, n, memory_order_relaxed);
done:
  i2m_free(&new_of);
  i2m_free(&rows);
  return err;
}
