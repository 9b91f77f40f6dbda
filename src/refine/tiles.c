/* Refine layer: the deterministic mode, which gives the same mesh whatever the number of
 * threads.
 *
 * The labelled block is cut into tiles of side L (at least 24 delta); a tile's zone is the
 * tile grown by a margin L/2 - 1.01 delta, so that the zones of two tiles of the same colour
 * (the parities of the tile coordinates) stay more than 2 delta apart.  In a phase, the
 * tiles of one colour with work are refined at the same time, each by one thread, and each
 * operation touches only vertices of its tile's zone (the kernel's lock hook checks that);
 * nothing a thread reads can change meanwhile: the mesh there is its alone, and the grids
 * of surface and free vertices only change farther away than R1 and R7 look.  Every bad
 * element lives in the tile that holds its centroid; an element created for another tile is
 * handed over at the next barrier, in the order (target, source, rank at the source), and
 * one that cannot be done inside a zone (a large cavity, a walk) goes to the sequential pass
 * that ends each round.  A tile's slots and global ids are its own.  So every decision
 * depends on the tiles' contents only, never on which thread ran which tile, or when. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define TILE_MIN_DELTAS 48.0   /* tile side, in units of delta */
#define TILES_PER_AXIS 32.0    /* at most about this many along the longest axis */
#define TILE_GID_SHIFT 36      /* a tile's global ids: base + (tile << 36) + k */
#define TILING_GID_SHIFT 52    /* each tiling's base: (number + 1) << 52 */

/* ---- geometry ---- */

static uint32_t tile_axis(const tiling_t *g, int a, double x)
{
  double u = (x - g->origin[a]) / g->side;
  return !(u >= 0.0) ? 0 : u >= (double)g->n[a] ? g->n[a] - 1 : (uint32_t)u;
}

static uint32_t tile_of_point(const tiling_t *g, const double x[3])
{
  return (tile_axis(g, 2, x[2]) * g->n[1] + tile_axis(g, 1, x[1])) * g->n[0] + tile_axis(g, 0, x[0]);
}

/* The tile of a tet: the one that holds its centroid. */
uint32_t tiles_tile_of_tet(const i2m_refine_t *r, uint32_t t)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  double c[3] = {0, 0, 0};
  for (int i = 0; i < 4; i++)
    for (int a = 0; a < 3; a++) c[a] += i2m_dt_xyz(dt, v[i])[a];
  for (int a = 0; a < 3; a++) c[a] *= 0.25;
  return tile_of_point(r->tiling, c);
}

int tiles_color(const tiling_t *g, uint32_t id)
{
  uint32_t i = id % g->n[0], j = id / g->n[0] % g->n[1], k = id / g->n[0] / g->n[1];
  return (int)((i & 1) | (j & 1) << 1 | (k & 1) << 2);
}

static bool zone_fits_tet(const tile_t *tl, const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++)
    if (!i2m_box_holds(tl->zone, i2m_dt_xyz(dt, v[i]))) return false;
  return true;
}

bool tiles_zone_holds(const i2m_refine_worker_t *w, const double x[3])
{
  return !w->tile || i2m_box_holds(w->tile->zone, x);
}

bool tiles_ball_fits(const i2m_refine_worker_t *w, const double c[3], double r2)
{
  if (!w->tile) return true;
  if (!isfinite(r2)) return false;
  const double *z = w->tile->zone, r = sqrt(r2);
  for (int a = 0; a < 3; a++)
    if (!(c[a] - r >= z[a] && c[a] + r <= z[3 + a])) return false;
  return true;
}

static size_t tile_work(const tile_t *tl)
{
  size_t n = tl->npend;
  for (int l = 0; l < NLEVELS; l++) n += tl->q[l].n;
  return n;
}

static bool tile_has_work(const tile_t *tl) { return tile_work(tl) != 0; }

/* ---- queues ---- */

static i2m_err_t tile_push(i2m_refine_t *r, uint32_t id, int level, uint32_t t, uint32_t meta)
{
  bad_t b = {t, meta, {0, 0, 0, 0}}; /* tile lists are narrow: the vertices are read when popped */
  return badlist_push(&r->tiling->tile[id].q[level], r->dt, &b);
}

static i2m_err_t handoff_append(handoff_t **a, size_t *n, size_t *cap, handoff_t h)
{
  if (*n == *cap) {
    size_t c = *cap ? 2 * *cap : 1024;
    I2M_CALL(i2m_realloc(c, sizeof **a, a));
    *cap = c;
  }
  (*a)[(*n)++] = h;
  return I2M_OK;
}

static i2m_err_t seq_append(tiling_t *g, handoff_t h)
{
  h.to = TILE_NONE;
  return handoff_append(&g->seq, &g->nseq, &g->cap_seq, h);
}

/* An element for tile id from the one thread that runs (setup, barrier, sequential pass):
 * into the tile when its tet lies in the zone, else to the sequential pass. */
static i2m_err_t place(i2m_refine_t *r, uint32_t id, handoff_t h)
{
  if (zone_fits_tet(&r->tiling->tile[id], r->dt, h.t)) return tile_push(r, id, h.level, h.t, h.meta);
  return seq_append(r->tiling, h);
}

i2m_err_t tiles_route(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, bool *taken)
{
  i2m_refine_t *r = w->r;
  const uint32_t to = tiles_tile_of_tet(r, t);
  *taken = true;
  if (!w->tile) return place(r, to, (handoff_t){to, TILE_NONE, 0, level, t, meta, {0, 0}}); /* one thread */
  if (to == w->tile_id) {
    *taken = false; /* its own tile: the worker's lists */
    return I2M_OK;
  }
  return handoff_append(&w->out, &w->nout, &w->cap_out, (handoff_t){to, w->tile_id, w->tile->seq++, level, t, meta, {0, 0}});
}

i2m_err_t tiles_defer(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, pending_t pv)
{
  return handoff_append(&w->out, &w->nout, &w->cap_out,
                        (handoff_t){TILE_NONE, w->tile_id, w->tile->seq++, level, t, meta, pv});
}

/* ---- a worker on a tile: the tile's lists, slots and zone become the worker's ---- */

static void swap_lists(i2m_refine_worker_t *w, tile_t *tl)
{
  for (int l = 0; l < NLEVELS; l++) {
    badlist_t q = w->q[l];
    w->q[l] = tl->q[l];
    tl->q[l] = q;
  }
  pending_t *p = w->pend;
  uint32_t n = w->npend, c = w->cap_pend;
  w->pend = tl->pend;
  w->npend = tl->npend;
  w->cap_pend = tl->cap_pend;
  tl->pend = p;
  tl->npend = n;
  tl->cap_pend = c;
  i2m_dt_slots_t s = w->ctx.slots;
  w->ctx.slots = tl->slots;
  tl->slots = s;
}

void tiles_bind(i2m_refine_worker_t *w, uint32_t id)
{
  tile_t *tl = &w->r->tiling->tile[id];
  swap_lists(w, tl);
  w->ctx.zone = tl->zone;
  w->ctx.bounded = true;
  w->tile = tl;
  w->tile_id = id;
  w->tile_full = false;
}

void tiles_unbind(i2m_refine_worker_t *w)
{
  swap_lists(w, w->tile);
  w->ctx.zone = NULL;
  w->ctx.bounded = false;
  w->tile = NULL;
}

i2m_err_t i2m_refine_tile_run(i2m_refine_t *r, int k, uint32_t id)
{
  i2m_refine_worker_t *w = &r->workers[k];
  double t0 = i2m_wtime();
  tiles_bind(w, id);
  int s;
  do {
    s = worker_step(w);
  } while (s == I2M_STEP_DONE);
  bool full = w->tile_full;
  tiles_unbind(w);
  w->st.seconds += i2m_wtime() - t0;
  tile_t *tl = &r->tiling->tile[id];
  if (full && tl->grant < (1u << 16)) tl->grant *= 2; /* the tile ran out of slots: more next time */
  I2M_CHECK(s == I2M_STEP_IDLE || (s == I2M_STEP_FULL && full), I2M_ERR_INTERNAL, "refinement failed in a tile: %s",
            i2m_error_message());
  return I2M_OK;
}

/* ---- setup and teardown ---- */

static void tiling_free(tiling_t **gp)
{
  tiling_t *g = *gp;
  if (!g) return;
  for (uint32_t id = 0; g->tile && id < g->ntiles; id++) {
    for (int l = 0; l < NLEVELS; l++) badlist_free(&g->tile[id].q[l]);
    i2m_free(&g->tile[id].pend); /* (the slots went back with i2m_dt_slots_release) */
  }
  i2m_free(&g->tile);
  i2m_free(&g->seq);
  i2m_free(&g->merge);
  i2m_free(&g->active);
  i2m_free(&g->order);
  i2m_free(&g->level);
  i2m_free(gp);
}

/* Tile side (from the final delta: the coarse phase uses the same tiles) and margin (from the
 * delta in force: same-colour zones stay more than 2 delta apart, as R7 looks that far). */
static void tile_size(const i2m_refine_t *r, double *side, double *margin)
{
  double ext = 0;
  for (int a = 0; a < 3; a++) ext = fmax(ext, r->block_hi[a] - r->block_lo[a]);
  *side = fmax(TILE_MIN_DELTAS * r->p.delta, ext / TILES_PER_AXIS);
  *margin = 0.5 * *side - 1.01 * r->delta;
}

void i2m_refine_tiling_bound(i2m_refine_t *r)
{
  double side, margin;
  tile_size(r, &side, &margin);
  /* a cavity holds the tets whose balls hold the point: with radii below margin / 2 it stays
   * within the margin of any point of the tile (once the bound holds where the point goes) */
  r->background_size2 = 0.25 * margin * margin;
}

static i2m_err_t tiling_make(i2m_refine_t *r, tiling_t **out)
{
  tiling_t *g = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *g, &g));
  tile_size(r, &g->side, &g->margin);
  g->ntiles = 1;
  for (int a = 0; a < 3; a++) {
    g->origin[a] = r->block_lo[a];
    double n = ceil((r->block_hi[a] - r->block_lo[a]) / g->side);
    g->n[a] = n < 1 ? 1 : (uint32_t)n;
    g->ntiles *= g->n[a];
  }
  g->gid_base = (i2m_gidx_t)(++r->tilings_made) << TILING_GID_SHIFT;
  i2m_err_t err = i2m_calloc(g->ntiles, sizeof *g->tile, &g->tile);
  if (err == I2M_OK) err = i2m_malloc(g->ntiles, sizeof *g->active, &g->active);
  if (err == I2M_OK) err = i2m_malloc(g->ntiles, sizeof *g->order, &g->order);
  for (uint32_t id = 0; err == I2M_OK && id < g->ntiles; id++) {
    tile_t *tl = &g->tile[id];
    uint32_t c[3] = {id % g->n[0], id / g->n[0] % g->n[1], id / g->n[0] / g->n[1]};
    for (int a = 0; a < 3; a++) {
      tl->zone[a] = g->origin[a] + c[a] * g->side - g->margin;
      tl->zone[3 + a] = g->origin[a] + (c[a] + 1) * g->side + g->margin;
    }
    tl->gid_next = g->gid_base + ((i2m_gidx_t)id << TILE_GID_SHIFT);
    tl->grant = 1;
  }
  if (err != I2M_OK) tiling_free(&g);
  *out = g;
  return err;
}

/* The workers' elements (worker 0 first, each list bottom to top) into the tiles. */
static i2m_err_t adopt_worker_elements(i2m_refine_t *r)
{
  for (int k = 0; k < r->nworkers; k++) {
    i2m_refine_worker_t *w = &r->workers[k];
    for (int l = 0; l < NLEVELS; l++) {
      for (size_t i = 0; i < w->q[l].n; i++) {
        bad_t b;
        badlist_get(&w->q[l], r->dt, i, &b);
        if (i2m_dt_meta(r->dt, b.t) != b.meta) continue;
        I2M_CALL(place(r, tiles_tile_of_tet(r, b.t), (handoff_t){0, TILE_NONE, 0, l, b.t, b.meta, {0, 0}}));
      }
      w->q[l].n = 0;
      I2M_CALL(badlist_set_wide(&w->q[l], r->dt, false));
    }
    for (uint32_t i = 0; i < w->npend; i++) /* (no tile of their own: R7's candidates anywhere) */
      I2M_CALL(seq_append(r->tiling, (handoff_t){TILE_NONE, TILE_NONE, 0, -1, 0, 0, w->pend[i]}));
    w->npend = 0;
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_tiling_begin(i2m_refine_t *r)
{
  I2M_CHECK(!r->tiling, I2M_ERR_INTERNAL, "a tiling is already in place");
  I2M_CALL(tiling_make(r, &r->tiling));
  for (int k = 0; k < r->nworkers; k++) r->workers[k].ctx.locking = false; /* zones instead of locks */
  i2m_err_t err = adopt_worker_elements(r);
  if (err != I2M_OK) tiling_free(&r->tiling);
  return err;
}

void i2m_refine_tiling_end(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  if (!g) return;
  for (uint32_t id = 0; id < g->ntiles; id++) i2m_dt_slots_release(r->dt, &g->tile[id].slots);
  tiling_free(&r->tiling);
}

/* ---- reclassification of every tet, for a new tiling (after the coarse phase) ---- */

i2m_err_t i2m_refine_tiling_classify(i2m_refine_t *r, int k, int n)
{
  tiling_t *g = r->tiling;
  const uint32_t nt = i2m_dt_ntets_slots(r->dt);
  const uint32_t lo = (uint32_t)((uint64_t)nt * (uint64_t)k / (uint64_t)n);
  const uint32_t hi = (uint32_t)((uint64_t)nt * (uint64_t)(k + 1) / (uint64_t)n);
  i2m_refine_worker_t *w = &r->workers[k];
  for (uint32_t t = lo; t < hi; t++) {
    g->level[t] = -1;
    if (!i2m_dt_alive(r->dt, t)) continue;
    tet_geom_t geo;
    tet_geom(r, t, PROBE_CLOSEST, &geo);
    g->level[t] = (int8_t)classify_level(w, t, &geo);
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_tiling_prepare_classify(i2m_refine_t *r)
{
  return i2m_malloc(i2m_dt_ntets_slots(r->dt), sizeof *r->tiling->level, &r->tiling->level);
}

i2m_err_t i2m_refine_tiling_collect(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  const uint32_t nt = i2m_dt_ntets_slots(r->dt);
  i2m_err_t err = I2M_OK;
  for (uint32_t t = 0; t < nt && err == I2M_OK; t++)
    if (g->level[t] >= 0)
      err = place(r, tiles_tile_of_tet(r, t), (handoff_t){0, TILE_NONE, 0, g->level[t], t, i2m_dt_meta(r->dt, t), {0, 0}});
  i2m_free(&g->level);
  return err;
}

/* ---- phases ---- */

bool i2m_refine_tiling_has_work(const i2m_refine_t *r)
{
  const tiling_t *g = r->tiling;
  if (g->nseq) return true;
  for (uint32_t id = 0; id < g->ntiles; id++)
    if (tile_has_work(&g->tile[id])) return true;
  return false;
}

static int cmp_u64(const void *x, const void *y)
{
  uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
  return (a > b) - (a < b);
}

i2m_err_t i2m_refine_tiling_phase(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles)
{
  tiling_t *g = r->tiling;
  uint32_t n = 0;
  for (uint32_t id = 0; id < g->ntiles; id++) /* the busiest first: key (less work, id) */
    if (tiles_color(g, id) == color && tile_has_work(&g->tile[id])) {
      size_t wk = tile_work(&g->tile[id]);
      g->order[n++] = (uint64_t)(UINT32_MAX - (wk < UINT32_MAX ? wk : UINT32_MAX)) << 32 | id;
    }
  if (n > 1) qsort(g->order, n, sizeof *g->order, cmp_u64);
  for (uint32_t i = 0; i < n; i++) g->active[i] = (uint32_t)g->order[i];
  g->nactive = n;
  for (uint32_t i = 0; i < n; i++) { /* slots for the tile's work (it stops when they run out) */
    tile_t *tl = &g->tile[g->active[i]];
    uint64_t want = (uint64_t)tl->grant * tile_work(tl) / 4 + 64; /* (most queued entries are stale) */
    if (want > (1u << 24)) want = 1u << 24;
    I2M_CALL(i2m_dt_slots_grant(r->dt, &tl->slots, (uint32_t)want, (uint32_t)(want / 4 + 64)));
  }
  I2M_CALL(vgrid_reserve(&r->surf, r->dt->cap_v)); /* nobody grows the grids while tiles run */
  I2M_CALL(vgrid_reserve(&r->freev, r->dt->cap_v));
  *tiles = g->active;
  *ntiles = n;
  return I2M_OK;
}

static int cmp_handoff(const void *x, const void *y)
{
  const handoff_t *a = x, *b = y;
  if (a->to != b->to) return a->to < b->to ? -1 : 1;
  if (a->from != b->from) return a->from < b->from ? -1 : 1;
  return (a->seq > b->seq) - (a->seq < b->seq);
}

i2m_err_t i2m_refine_tiling_merge(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  size_t n = 0;
  for (int k = 0; k < r->nworkers; k++) n += r->workers[k].nout;
  if (n > g->cap_merge) {
    I2M_CALL(i2m_realloc(n, sizeof *g->merge, &g->merge));
    g->cap_merge = n;
  }
  n = 0;
  for (int k = 0; k < r->nworkers; k++) {
    i2m_refine_worker_t *w = &r->workers[k];
    if (w->nout) memcpy(g->merge + n, w->out, w->nout * sizeof *w->out);
    n += w->nout;
    w->nout = 0;
  }
  if (n > 1) qsort(g->merge, n, sizeof *g->merge, cmp_handoff); /* the order of the threads is gone */
  for (uint32_t i = 0; i < g->nactive; i++) { /* what the phase's tiles did not use, for the next */
    tile_t *tl = &g->tile[g->active[i]];
    i2m_dt_slots_release(r->dt, &tl->slots);
    for (int l = 0; l < NLEVELS; l++) /* (hundreds of tiles: keep no memory for the empty ones) */
      if (tl->q[l].n == 0) badlist_free(&tl->q[l]);
    if (tl->npend == 0) {
      i2m_free(&tl->pend);
      tl->cap_pend = 0;
    }
  }
  for (size_t i = 0; i < n; i++) {
    handoff_t h = g->merge[i];
    if (h.level >= 0 && i2m_dt_meta(r->dt, h.t) != h.meta) continue; /* gone meanwhile */
    if (h.to == TILE_NONE) {
      I2M_CALL(seq_append(g, h));
    } else {
      I2M_CALL(place(r, h.to, h));
    }
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_tiling_sequential(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  i2m_refine_worker_t *w = &r->workers[0];
  const size_t n0 = g->nseq;
  double t0 = i2m_wtime();
  for (size_t i = 0; i < n0; i++) { /* each element once, with what follows from it */
    handoff_t h = g->seq[i];
    if (h.level >= 0) {
      if (i2m_dt_meta(r->dt, h.t) != h.meta) continue;
      bad_t b = {h.t, h.meta, {0, 0, 0, 0}};
      memcpy(b.v, r->dt->tv + 4 * (size_t)h.t, sizeof b.v);
      I2M_CALL(worker_push_entry(w, h.level, &b));
    } else {
      if (w->npend == w->cap_pend) {
        uint32_t cap = w->cap_pend ? 2 * w->cap_pend : 64;
        I2M_CALL(i2m_realloc(cap, sizeof *w->pend, &w->pend));
        w->cap_pend = cap;
      }
      w->pend[w->npend++] = h.pv;
    }
    int s;
    while ((s = worker_step(w)) == I2M_STEP_DONE) {
    }
    I2M_CHECK(s == I2M_STEP_IDLE, I2M_ERR_INTERNAL, "refinement failed: %s", i2m_error_message());
    g->sequential_ops++;
  }
  if (g->nseq > n0) memmove(g->seq, g->seq + n0, (g->nseq - n0) * sizeof *g->seq); /* what it sent on: next time */
  g->nseq -= n0;
  g->rounds++;
  w->st.seconds += i2m_wtime() - t0;
  return I2M_OK;
}

void i2m_refine_tiling_figures(const i2m_refine_t *r, double *side, int64_t *rounds, int64_t *sequential_ops)
{
  const tiling_t *g = r->tiling;
  *side = g ? g->side : 0;
  *rounds = g ? g->rounds : 0;
  *sequential_ops = g ? g->sequential_ops : 0;
}
