/* Refine layer: a worker pops bad elements from its own lists, inserts the point the rules
 * ask for, classifies the tets it created, and queues the removals R7 asks for after every
 * surface vertex.  The same code runs alone (no locks) or on many threads: then every
 * operation first locks the vertices of the bad tet recorded in its list entry, checks the
 * tet is unchanged, and only then reads it; a lock held by another thread rolls everything
 * back (nothing was written) and the element goes back to the list (REFERENCE §2.2). */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

i2m_err_t worker_init(i2m_refine_worker_t *w, i2m_refine_t *r, uint32_t owner, bool locking)
{
  memset(w, 0, sizeof *w);
  w->r = r;
  I2M_CALL(i2m_dt_ctx_init(&w->ctx, r->dt, owner, locking));
  for (int l = 0; l < NLEVELS; l++) w->q[l].wide = locking;
  i2m_progress_begin(&w->progress, "refinement", "tets");
  return I2M_OK;
}

void worker_free(i2m_refine_worker_t *w)
{
  i2m_free(&w->born);
  i2m_free(&w->bornv);
  i2m_dt_ctx_free(&w->ctx);
  for (int l = 0; l < NLEVELS; l++) badlist_free(&w->q[l]);
  i2m_free(&w->pend);
  i2m_free(&w->created);
  i2m_free(&w->geom);
  i2m_free(&w->out);
  memset(w, 0, sizeof *w);
}

i2m_err_t worker_push_entry(i2m_refine_worker_t *w, int level, const bad_t *b)
{
  return badlist_push(&w->q[level], w->r->dt, b);
}

/* Classifies tet t (its vertices locked, or a sequential run) and queues it if it is bad (in
 * the deterministic mode, where its centroid's tile wants it). */
static i2m_err_t push_classified(i2m_refine_worker_t *w, uint32_t t, const tet_geom_t *g)
{
  int level = classify_level(w, t, g);
  if (level < 0) return I2M_OK;
  if (w->r->tiling) {
    bool taken;
    I2M_CALL(tiles_route(w, level, t, i2m_dt_stamp(w->r->dt, t), &taken));
    if (taken) return I2M_OK;
  }
  bad_t b;
  b.t = t;
  b.meta = i2m_dt_stamp(w->r->dt, t);
  memcpy(b.v, w->r->dt->tv + 4 * (size_t)t, sizeof b.v);
  return worker_push_entry(w, level, &b);
}

i2m_err_t worker_push(i2m_refine_worker_t *w, uint32_t t)
{
  tet_geom_t g;
  tet_geom(w->r, t, PROBE_CLOSEST, &g);
  return push_classified(w, t, &g);
}

/* Starts loading what the rules read of tet t besides its own words: its neighbours' labels
 * (the facet rules) and its vertices' kinds and patches (R1's spacing test, R5/R6). */
static I2M_INLINE void prefetch_rule_inputs(const i2m_refine_t *r, uint32_t t)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t *tn = dt->tn + 4 * (size_t)t, *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) {
    if (tn[i] < I2M_DT_REMOTE) I2M_PREFETCH(tinfo(dt, tn[i] >> 2));
    I2M_PREFETCH(&dt->vkind[v[i]]);
    if (v[i] < r->surf.cap_next) I2M_PREFETCH(&r->surf.tag[v[i]]); /* (tags exist for the grid's vertices) */
  }
}

/* The new tets: first every label (the facet rules compare neighbours'), then the rules. */
i2m_err_t worker_process_created(i2m_refine_worker_t *w, const uint32_t *newt, uint32_t n)
{
  if (n > w->cap_geom) {
    uint32_t cap = n + n / 2 + 64;
    I2M_CALL(i2m_realloc(cap, sizeof *w->geom, &w->geom));
    w->cap_geom = cap;
  }
  /* three passes, so that the probes' random loads overlap: the centres (and the first voxel
   * word of each probe is requested), the feature voxels named there (their neighbourhoods
   * are requested), then the probes and labels */
  const i2m_edt_t *edt = w->r->edt;
  for (uint32_t k = 0; k < n; k++) {
    tet_centre(w->r, newt[k], &w->geom[k]);
    i2m_edt_prefetch(edt, w->geom[k].vox);
    prefetch_rule_inputs(w->r, newt[k]);
  }
  for (uint32_t k = 0; k < n; k++) i2m_edt_prefetch_feature(edt, w->geom[k].vox);
  for (uint32_t k = 0; k < n; k++) {
    tet_probe(w->r, newt[k], PROBE_NEW, &w->geom[k]);
    tinfo(w->r->dt, newt[k])->label = (uint16_t)w->geom[k].label;
  }
  for (uint32_t k = 0; k < n; k++) I2M_CALL(push_classified(w, newt[k], &w->geom[k]));
  if (dist_tracking(w->r)) I2M_CALL(dist_note_tets(w, newt, n));
  w->st.tets_created += n;
  return I2M_OK;
}

i2m_err_t worker_keep_created(i2m_refine_worker_t *w)
{
  uint32_t n = w->ctx.nnew;
  if (n + 1 > w->cap_created) {
    uint32_t cap = n + n / 2 + 64;
    I2M_CALL(i2m_realloc(cap, sizeof *w->created, &w->created));
    w->cap_created = cap;
  }
  memcpy(w->created, w->ctx.newt, n * sizeof *w->created);
  w->ncreated = n;
  return I2M_OK;
}

static int64_t live_tets(const i2m_refine_worker_t *w) { return w->ctx.n_created - w->ctx.n_killed; }

int step_result(i2m_refine_worker_t *w, i2m_err_t err, int ok)
{
  if (err == I2M_OK) return ok;
  w->error = err;
  return I2M_STEP_ERROR;
}

static void pend_bottom(i2m_refine_worker_t *w, pending_t pv)
{
  w->pend[w->npend] = w->pend[0];
  w->pend[0] = pv;
  w->npend++;
}

/* An element that could not be done now (bad element b of list level, or the removal pv when
 * b is NULL): nothing was changed and no lock is kept.  A worker on a tile leaves it for a
 * wider treatment when it cannot be done inside the tile's zone (I2M_DT_FROZEN: a vertex
 * outside the zone, a neighbour outside the block, a walk), or keeps it for the tile's next
 * turn and stops (I2M_DT_FULL: the tile's slots ran out); otherwise it waits at the bottom of
 * its list (I2M_DT_ROLLBACK: another thread holds a vertex; I2M_DT_FULL: grow and retry). */
static int put_back(i2m_refine_worker_t *w, int level, const bad_t *b, pending_t pv, i2m_dt_status_t st)
{
  i2m_dt_unlock_all(&w->ctx);
  if (w->tile && st == I2M_DT_FULL) {
    w->tile_full = true;
    if (b) return step_result(w, worker_push_entry(w, level, b), I2M_STEP_FULL);
    w->pend[w->npend++] = pv; /* (it was just popped: its place is free) */
    return I2M_STEP_FULL;
  }
  if (w->tile && st == I2M_DT_FROZEN) {
    w->st.deferred++;
    return step_result(w, tiles_defer(w, b ? level : -1, b ? b->t : 0, b ? b->meta : 0, pv), I2M_STEP_DONE);
  }
  if (b) badlist_requeue_bottom(&w->q[level], b);
  else pend_bottom(w, pv);
  if (st == I2M_DT_FULL) return I2M_STEP_FULL;
  w->st.rollbacks++;
  return I2M_STEP_ROLLBACK;
}

/* What a kernel status means for the element: in a tile, a rollback that no other thread
 * caused (the zone's or the block's) and a frozen neighbour mean "not here" (I2M_DT_FROZEN). */
static i2m_dt_status_t tile_status(const i2m_refine_worker_t *w, i2m_dt_status_t st)
{
  if (!w->tile) return st;
  if (st == I2M_DT_ROLLBACK && (!w->ctx.locking || w->ctx.conflict_owner == 0)) return I2M_DT_FROZEN;
  return st;
}

/* One R7 removal: lock the vertex, check it is still the free vertex that was queued (a
 * removed vertex's slot may hold another vertex by now), remove it, classify its new tets. */
static int do_removal(i2m_refine_worker_t *w, pending_t pv)
{
  i2m_dt_t *dt = w->r->dt;
  if (pv.v >= i2m_dt_nverts_slots(dt)) /* (a submesh's, whose vertex this rank does not hold) */
    return w->tile ? put_back(w, -1, NULL, pv, I2M_DT_FROZEN) : I2M_STEP_DONE;
  uint32_t v4[4] = {pv.v, pv.v, pv.v, pv.v};
  if (!i2m_dt_lock_tet(&w->ctx, v4)) return put_back(w, -1, NULL, pv, tile_status(w, I2M_DT_ROLLBACK));
  if (dt->vkind[pv.v] != I2M_VK_FREE || i2m_dt_gid(dt, pv.v) != pv.gid) {
    i2m_dt_unlock_all(&w->ctx);
    return I2M_STEP_DONE;
  }
  i2m_dt_status_t st = tile_status(w, i2m_dt_remove(&w->ctx, pv.v));
  if (st == I2M_DT_ROLLBACK || st == I2M_DT_FULL || st == I2M_DT_FROZEN) return put_back(w, -1, NULL, pv, st);
  if (st != I2M_DT_OK) {
    i2m_dt_unlock_all(&w->ctx);
    if (st == I2M_DT_FAILED)
      return step_result(w, I2M_ERROR(I2M_ERR_INTERNAL, "vertex removal failed to re-triangulate a star"), I2M_STEP_DONE);
    w->st.failed++;
    return I2M_STEP_DONE;
  }
  vgrid_remove(&w->r->freev, dt, pv.v); /* the slot is ours until our next insertion */
  w->st.removals++;
  w->st.rule[7]++;
  i2m_err_t err = worker_keep_created(w);
  if (err == I2M_OK) err = worker_process_created(w, w->created, w->ncreated);
  i2m_dt_unlock_all(&w->ctx);
  return step_result(w, err, I2M_STEP_DONE);
}

static int cmp_pending(const void *x, const void *y)
{
  i2m_gidx_t a = ((const pending_t *)x)->gid, b = ((const pending_t *)y)->gid;
  return (a > b) - (a < b);
}

/* R7: queue the free vertices within 2 delta of the new surface vertex z, in the order of
 * their global ids (the grid's lists are in no fixed order when several threads fill them). */
static i2m_err_t queue_r7(i2m_refine_worker_t *w, const double z[3])
{
  uint32_t n0 = w->npend;
  I2M_CALL(vgrid_collect_within(&w->r->freev, w->r->dt, z, 2.0 * w->r->delta, &w->pend, &w->npend, &w->cap_pend));
  if (w->npend - n0 > 1) qsort(w->pend + n0, w->npend - n0, sizeof *w->pend, cmp_pending);
  return I2M_OK;
}

/* Inserts the action's point; in a sequential run, a surface point whose seed's ball holds it
 * only on its boundary is located by a walk. */
static i2m_dt_status_t insert_action(i2m_refine_worker_t *w, const action_t *a, uint32_t *v)
{
  i2m_refine_t *r = w->r;
  if (!w->tile && w->gid_next == w->gid_end) { /* global ids come in blocks: no shared counter per insertion */
    w->gid_next = atomic_fetch_add_explicit(&r->next_gid, 1024, memory_order_relaxed);
    w->gid_end = w->gid_next + 1024;
  }
  i2m_gidx_t gid = w->tile ? w->tile->gid_next : w->gid_next;
  i2m_dt_status_t st = i2m_dt_insert(&w->ctx, a->p, gid, a->kind, a->seed, I2M_DT_NONE, v);
  /* a walk: alone, or inside a task's block (no other thread changes it); the coarse tiles'
   * zones leave it to their sequential pass */
  if (st == I2M_DT_NOT_IN_CONFLICT && !w->ctx.locking && (!w->tile || w->ctx.block)) {
    uint32_t t = i2m_dt_locate(&w->ctx, a->p, a->seed);
    st = t == I2M_DT_NONE ? I2M_DT_FROZEN : i2m_dt_insert(&w->ctx, a->p, gid, a->kind, t, I2M_DT_NONE, v);
  }
  if (st == I2M_DT_NOT_IN_CONFLICT && w->tile) st = I2M_DT_FROZEN;
  st = tile_status(w, st);
  if (st == I2M_DT_OK) {
    if (w->tile) w->tile->gid_next++;
    else w->gid_next++;
  }
  return st;
}

/* After a successful insertion (locks held): the grids, the new tets, the popped tet if it
 * survived, R7's candidates. */
static i2m_err_t after_insertion(i2m_refine_worker_t *w, const action_t *a, const bad_t *b, uint32_t v)
{
  i2m_refine_t *r = w->r;
  i2m_dt_t *dt = r->dt;
  w->st.insertions++;
  w->st.rule[a->rule]++;
  /* the new vertex joins its grid before its tets are judged (R1 looks at it) */
  if (a->kind == I2M_VK_SURFACE) I2M_CALL(vgrid_insert(&r->surf, dt, v, a->patch));
  if (a->kind == I2M_VK_FREE && a->dist2 <= r->four_delta2) I2M_CALL(vgrid_insert(&r->freev, dt, v, VGRID_MEMBER));
  if (dist_tracking(r)) I2M_CALL(dist_note_vertex(w, v));
  I2M_CALL(worker_keep_created(w));
  I2M_CALL(worker_process_created(w, w->created, w->ncreated));
  /* the point may have gone in elsewhere (a neighbour's ball, a walk): a tet that survives
   * keeps whatever else is wrong with it, so it goes back to the lists */
  if (i2m_dt_stamp(dt, b->t) == b->meta) I2M_CALL(worker_push(w, b->t));
  if (a->kind == I2M_VK_SURFACE) I2M_CALL(queue_r7(w, i2m_dt_xyz(dt, v)));
  return I2M_OK;
}

int worker_step(i2m_refine_worker_t *w)
{
  i2m_dt_t *dt = w->r->dt;
  if (w->npend) return do_removal(w, w->pend[--w->npend]);
  int level = 0;
  while (level < NLEVELS && w->q[level].n == 0) level++;
  if (level == NLEVELS) return I2M_STEP_IDLE;
  bad_t b;
  if (!badlist_pop_live(&w->q[level], dt, &b)) return I2M_STEP_DONE; /* gone (most popped entries are) */
  if (!i2m_dt_lock_tet(&w->ctx, b.v)) return put_back(w, level, &b, (pending_t){0, 0}, tile_status(w, I2M_DT_ROLLBACK));
  if (i2m_dt_stamp(dt, b.t) != b.meta) { /* stale: the tet is gone */
    i2m_dt_unlock_all(&w->ctx);
    return I2M_STEP_DONE;
  }
  /* the first rule that applies; if its point cannot go in (it coincides with a vertex, or
   * lies only on the seed's sphere), the tet is judged again without that rule */
  action_t a;
  uint32_t v, skip = 0;
  for (;;) {
    int c = classify_action(w, b.t, &a, skip);
    if (c < 0) return put_back(w, level, &b, (pending_t){0, 0}, I2M_DT_FROZEN); /* beyond the tile's zone */
    if (c == 0) {
      i2m_dt_unlock_all(&w->ctx);
      return I2M_STEP_DONE;
    }
    if (skip == 0 && a.level > level) { /* its list comes later: wait there */
      i2m_err_t err = worker_push_entry(w, a.level, &b);
      i2m_dt_unlock_all(&w->ctx);
      return step_result(w, err, I2M_STEP_DONE);
    }
    i2m_dt_status_t st = insert_action(w, &a, &v);
    if (st == I2M_DT_ROLLBACK || st == I2M_DT_FULL || st == I2M_DT_FROZEN) return put_back(w, level, &b, (pending_t){0, 0}, st);
    if (st == I2M_DT_OK) break;
    if (st == I2M_DT_DUPLICATE) w->st.duplicates++;
    else w->st.failed++;
    skip |= a.rule >= 2 && a.rule <= 4 ? (1u << 2 | 1u << 3 | 1u << 4) : 1u << a.rule;
    /* the failed attempt released every lock: take the tet's again */
    if (!i2m_dt_lock_tet(&w->ctx, b.v)) return put_back(w, level, &b, (pending_t){0, 0}, tile_status(w, I2M_DT_ROLLBACK));
    if (i2m_dt_stamp(dt, b.t) != b.meta) {
      i2m_dt_unlock_all(&w->ctx);
      return I2M_STEP_DONE;
    }
  }
  i2m_err_t err = after_insertion(w, &a, &b, v);
  i2m_dt_unlock_all(&w->ctx);
  if (err != I2M_OK) return step_result(w, err, I2M_STEP_DONE);
  if ((w->st.insertions & 1023) == 0 && w->ctx.owner == 1) i2m_progress_update(&w->progress, live_tets(w) * w->r->nworkers);
  return I2M_STEP_DONE;
}

i2m_err_t step_outcome(const i2m_refine_worker_t *w, int s)
{
  if (s == I2M_STEP_ERROR) return w->error;
  I2M_CHECK(s == I2M_STEP_IDLE, I2M_ERR_INTERNAL, "refinement stopped with step result %d", s);
  return I2M_OK;
}
