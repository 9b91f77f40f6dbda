/* Refine layer: the bad-element stacks of a worker (top: the newest, popped first). */
#include "refine_impl.h"

#include <string.h>

/* A list that has drained to an eighth of its capacity gives half of it back, so that the
 * memory of a past peak of bad elements is free for the mesh that grows meanwhile. */
#define LIST_SHRINK_MIN ((size_t)1 << 16)

static i2m_err_t set_capacity(badlist_t *q, size_t cap)
{
  I2M_CALL(i2m_realloc_large(cap, sizeof *q->e, &q->e));
  if (q->wide) I2M_CALL(i2m_realloc_large(cap, sizeof *q->v, &q->v));
  q->cap = cap;
  return I2M_OK;
}

/* Drops the entries of tets that are gone (their generation moved on; the stamp leaves out
 * the mark that another thread's search may have set on a live tet for a moment). */
static void compact(badlist_t *q, const i2m_dt_t *dt)
{
  size_t k = 0;
  for (size_t i = 0; i < q->n; i++) {
    if (i2m_dt_stamp(dt, q->e[i][0]) != q->e[i][1]) continue;
    memcpy(q->e[k], q->e[i], sizeof *q->e);
    if (q->wide) memcpy(q->v[k], q->v[i], sizeof *q->v);
    k++;
  }
  q->n = k;
}

i2m_err_t badlist_push(badlist_t *q, const i2m_dt_t *dt, const bad_t *b)
{
  if (q->n == q->cap) {
    if (q->cap >= 4096) compact(q, dt); /* before growing: most may be stale */
    if (q->n + q->cap / 4 >= q->cap) I2M_CALL(set_capacity(q, q->cap ? 2 * q->cap : 64));
  } else if (q->cap >= LIST_SHRINK_MIN && q->n < q->cap / 8) {
    I2M_CALL(set_capacity(q, q->cap / 2)); /* keeps a popped slot above n */
  }
  q->e[q->n][0] = b->t;
  q->e[q->n][1] = b->meta;
  if (q->wide) memcpy(q->v[q->n], b->v, sizeof *q->v);
  q->n++;
  return I2M_OK;
}

void badlist_get(const badlist_t *q, const i2m_dt_t *dt, size_t i, bad_t *b)
{
  b->t = q->e[i][0];
  b->meta = q->e[i][1];
  memcpy(b->v, q->wide ? q->v[i] : dt->tv + 4 * (size_t)b->t, sizeof b->v);
}

bool badlist_pop_live(badlist_t *q, const i2m_dt_t *dt, bad_t *b)
{
  size_t i = --q->n;
  b->t = q->e[i][0];
  b->meta = q->e[i][1];
  /* a generation moved on proves the tet gone, and its slot may be another's by now: the tet
   * is not read at all (no lock needed for that) */
  if (i2m_dt_stamp(dt, b->t) != b->meta) return false;
  memcpy(b->v, q->wide ? q->v[i] : dt->tv + 4 * (size_t)b->t, sizeof b->v);
  return true;
}

void badlist_requeue_bottom(badlist_t *q, const bad_t *b)
{
  memcpy(q->e[q->n], q->e[0], sizeof *q->e);
  q->e[0][0] = b->t;
  q->e[0][1] = b->meta;
  if (q->wide) {
    memcpy(q->v[q->n], q->v[0], sizeof *q->v);
    memcpy(q->v[0], b->v, sizeof *q->v);
  }
  q->n++;
}

void badlist_drop_bottom(badlist_t *q, size_t k)
{
  memmove(q->e, q->e + k, (q->n - k) * sizeof *q->e);
  if (q->wide) memmove(q->v, q->v + k, (q->n - k) * sizeof *q->v);
  q->n -= k;
}

i2m_err_t badlist_set_wide(badlist_t *q, const i2m_dt_t *dt, bool wide)
{
  if (wide == q->wide) return I2M_OK;
  if (!wide) {
    i2m_free(&q->v);
    q->wide = false;
    return I2M_OK;
  }
  if (q->cap) I2M_CALL(i2m_malloc(q->cap, sizeof *q->v, &q->v));
  for (size_t i = 0; i < q->n; i++) memcpy(q->v[i], dt->tv + 4 * (size_t)q->e[i][0], sizeof *q->v);
  q->wide = true;
  return I2M_OK;
}

void badlist_free(badlist_t *q)
{
  i2m_free(&q->e);
  i2m_free(&q->v);
  q->n = q->cap = 0;
}
