/* Refine layer: a worker pops bad elements from its own lists, inserts the point the rules
 * ask for, classifies the tets it created, and applies R7 after every surface vertex. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

i2m_err_t worker_init(i2m_refine_worker_t *w, i2m_refine_t *r, uint32_t owner, bool locking)
{
  memset(w, 0, sizeof *w);
  w->r = r;
  I2M_CALL(i2m_dt_ctx_init(&w->ctx, r->dt, owner, locking));
  i2m_progress_begin(&w->progress, "refinement", "tets");
  return I2M_OK;
}

void worker_free(i2m_refine_worker_t *w)
{
  i2m_dt_ctx_free(&w->ctx);
  for (int l = 0; l < NLEVELS; l++) i2m_free(&w->q[l].e);
  i2m_free(&w->near);
  i2m_free(&w->created);
  memset(w, 0, sizeof *w);
}

static i2m_err_t push_level(i2m_refine_worker_t *w, int level, uint32_t t)
{
  badlist_t *q = &w->q[level];
  if (q->n == q->cap) {
    size_t cap = q->cap ? 2 * q->cap : 1024;
    I2M_CALL(i2m_realloc(cap, sizeof *q->e, &q->e));
    q->cap = cap;
  }
  q->e[q->n].t = t;
  q->e[q->n].meta = i2m_dt_meta(w->r->dt, t);
  q->n++;
  return I2M_OK;
}

i2m_err_t worker_push(i2m_refine_worker_t *w, uint32_t t)
{
  int level = classify_level(w, t);
  return level < 0 ? I2M_OK : push_level(w, level, t);
}

i2m_err_t worker_process_created(i2m_refine_worker_t *w, const uint32_t *newt, uint32_t n)
{
  for (uint32_t k = 0; k < n; k++) tet_info_compute(w->r, newt[k]);
  for (uint32_t k = 0; k < n; k++) I2M_CALL(worker_push(w, newt[k]));
  w->st.tets_created += n;
  return I2M_OK;
}

static i2m_err_t grow_u32(uint32_t **a, uint32_t *cap, uint32_t need)
{
  if (need <= *cap) return I2M_OK;
  uint32_t c = need + need / 2 + 64;
  I2M_CALL(i2m_realloc(c, sizeof **a, a));
  *cap = c;
  return I2M_OK;
}

static int cmp_u32(const void *a, const void *b)
{
  uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return (x > y) - (x < y);
}

static i2m_err_t apply_r7(i2m_refine_worker_t *w, uint32_t zv)
{
  i2m_dt_t *dt = w->r->dt;
  I2M_CALL(vgrid_collect_within(&w->r->freev, dt, i2m_dt_xyz(dt, zv), 2.0 * w->r->p.delta, &w->near, &w->nnear,
                                &w->cap_near));
  if (w->nnear > 1) qsort(w->near, w->nnear, sizeof *w->near, cmp_u32);
  uint32_t prev = I2M_DT_NONE;
  for (uint32_t k = 0; k < w->nnear; k++) {
    uint32_t v = w->near[k];
    if (v == prev) continue;
    prev = v;
    vgrid_remove(&w->r->freev, dt, v);
    i2m_dt_status_t st = i2m_dt_remove(&w->ctx, v);
    if (st != I2M_DT_OK) {
      I2M_CHECK(st != I2M_DT_FAILED, I2M_ERR_INTERNAL, "vertex removal failed to re-triangulate a star");
      I2M_CALL(vgrid_insert(&w->r->freev, dt, v, 0)); /* still there: still a candidate */
      w->st.failed++;
      continue;
    }
    w->st.removals++;
    w->st.rule[7]++;
    I2M_CALL(worker_process_created(w, w->ctx.newt, w->ctx.nnew));
    i2m_dt_unlock_all(&w->ctx);
  }
  return I2M_OK;
}

static i2m_err_t keep_created(i2m_refine_worker_t *w)
{
  I2M_CALL(grow_u32(&w->created, &w->cap_created, w->ctx.nnew + 1));
  memcpy(w->created, w->ctx.newt, w->ctx.nnew * sizeof *w->created);
  w->ncreated = w->ctx.nnew;
  return I2M_OK;
}

/* Inserts the action's point; for a surface point whose seed's ball holds it only on its
 * boundary, locates it by a walk.  Returns the kernel status. */
static i2m_dt_status_t insert_action(i2m_refine_worker_t *w, const action_t *a, uint32_t *v)
{
  i2m_refine_t *r = w->r;
  i2m_gidx_t gid = atomic_fetch_add_explicit(&r->next_gid, 1, memory_order_relaxed);
  i2m_dt_status_t st = i2m_dt_insert(&w->ctx, a->p, gid, a->kind, a->seed, I2M_DT_NONE, v);
  if (st == I2M_DT_NOT_IN_CONFLICT && !w->ctx.locking) {
    uint32_t t = i2m_dt_locate(&w->ctx, a->p, a->seed);
    st = i2m_dt_insert(&w->ctx, a->p, gid, a->kind, t, I2M_DT_NONE, v);
  }
  return st;
}

static int64_t live_tets(const i2m_refine_worker_t *w) { return 6 + w->ctx.n_created - w->ctx.n_killed; }

int worker_step(i2m_refine_worker_t *w)
{
  i2m_dt_t *dt = w->r->dt;
  int level = 0;
  while (level < NLEVELS && w->q[level].n == 0) level++;
  if (level == NLEVELS) return 0;
  bad_t b = w->q[level].e[--w->q[level].n];
  if (i2m_dt_meta(dt, b.t) != b.meta) return 1; /* stale: the tet is gone */
  action_t a;
  if (!classify_action(w, b.t, &a)) return 1;
  uint32_t v;
  i2m_dt_status_t st = insert_action(w, &a, &v);
  if (st != I2M_DT_OK) {
    if (st == I2M_DT_DUPLICATE) w->st.duplicates++;
    else w->st.failed++;
    return 1;
  }
  w->st.insertions++;
  w->st.rule[a.rule]++;
  /* the new vertex joins its grid before its tets are judged (R1 looks at it) */
  if (a.kind == I2M_VK_SURFACE && vgrid_insert(&w->r->surf, dt, v, a.patch) != I2M_OK) return -1;
  if (a.kind == I2M_VK_FREE && a.dist2 <= w->r->four_delta2 && vgrid_insert(&w->r->freev, dt, v, 0) != I2M_OK)
    return -1; /* a free vertex a future surface vertex may have to remove */
  if (keep_created(w) != I2M_OK || worker_process_created(w, w->created, w->ncreated) != I2M_OK) return -1;
  i2m_dt_unlock_all(&w->ctx);
  if (a.kind == I2M_VK_SURFACE && apply_r7(w, v) != I2M_OK) return -1;
  /* the point may have gone in elsewhere (a neighbour's ball, a walk): a tet that survives
   * keeps whatever else is wrong with it, so it goes back to the lists */
  if (i2m_dt_meta(dt, b.t) == b.meta && worker_push(w, b.t) != I2M_OK) return -1;
  if ((w->st.insertions & 1023) == 0) i2m_progress_update(&w->progress, live_tets(w));
  return 1;
}
