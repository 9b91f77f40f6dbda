/* Refine layer: tiles, the units of work of the deterministic mode and of the dist layer.
 *
 * The labelled block is cut into tiles, each with a zone (the tile grown by a margin): an
 * operation of a tile's task touches only vertices of its zone (the kernel's lock hook checks
 * that).  Every bad element lives in the tile that holds its tet's centroid; an element created
 * for another tile is handed over at the next barrier, in the order (target, source, rank at
 * the source), and one that cannot be done inside the zone (a large cavity, a walk) waits for
 * a wider treatment.  A tile's slots and global ids are its own.  So every decision depends
 * on the tiles' contents only, never on which thread (or rank) ran which tile, or when.
 *
 * Two tilings share this code:
 * - the coarse tiles of the deterministic mode's coarse phase: cubes of side L (at least 48
 *   delta), zones grown by L/2 - 1.01 delta, 8 colours (the parities of the tile
 *   coordinates: zones of one colour stay more than 2 delta apart, as R7 looks that far); what
 *   no zone holds goes to a sequential pass at the end of each round;
 * - the octree subregions (the paper's uniform octree of 8^d leaves over the labelled block),
 *   used by the fine phase of the deterministic mode and by every phase of the dist layer: a
 *   tile's task may also read only the tets of its block (its cell and the 26 around it: the
 *   cells a rank holds for the task), zones are grown by half a cell, 27 colours (the
 *   coordinates modulo 3: blocks of one colour never meet, so tasks of one colour run on
 *   different ranks without exchanging anything), and what no zone holds goes to the tile's
 *   wide task (zone grown by a cell and a half, block of 5^3 cells), run alone after each
 *   round; what even that cannot do is stuck, and a run that ends with stuck elements fails. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define TILE_MIN_DELTAS 48.0   /* coarse tiles: side, in units of delta */
#define TILES_PER_AXIS 32.0    /* coarse tiles: at most about this many along the longest axis */
#define TILE_GID_SHIFT 36      /* a tile's global ids: base + (tile << 36) + k */
#define TILING_GID_SHIFT 52    /* coarse tilings' bases: (number + 1) << 52 */
#define OCTREE_GID_BASE ((i2m_gidx_t)15 << TILING_GID_SHIFT) /* the octree's: the same on every rank */

/* ---- geometry ---- */

static uint32_t tile_index(const tiling_t *g, const int32_t c[3])
{
  return ((uint32_t)c[2] * (uint32_t)g->cells.n[1] + (uint32_t)c[1]) * (uint32_t)g->cells.n[0] + (uint32_t)c[0];
}

static void tile_coords(const tiling_t *g, uint32_t id, int32_t c[3])
{
  c[0] = (int32_t)(id % (uint32_t)g->cells.n[0]);
  c[1] = (int32_t)(id / (uint32_t)g->cells.n[0] % (uint32_t)g->cells.n[1]);
  c[2] = (int32_t)(id / (uint32_t)g->cells.n[0] / (uint32_t)g->cells.n[1]);
}

/* The cell at coordinates c: lo, hi (world). */
static void cell_box(const tiling_t *g, const int32_t c[3], double box[6])
{
  for (int a = 0; a < 3; a++) {
    box[a] = g->cells.origin[a] + c[a] * g->side[a];
    box[3 + a] = g->cells.origin[a] + (c[a] + 1) * g->side[a];
  }
}

static void tile_box(const tiling_t *g, uint32_t id, double box[6])
{
  int32_t c[3];
  tile_coords(g, id, c);
  cell_box(g, c, box);
}

/* The tile of a tet: the one that holds its centroid. */
uint32_t tiles_tile_of_point(const i2m_refine_t *r, const double x[3])
{
  const tiling_t *g = r->tiling;
  const int32_t c[3] = {i2m_dt_cell_axis(&g->cells, 0, x[0]), i2m_dt_cell_axis(&g->cells, 1, x[1]),
                        i2m_dt_cell_axis(&g->cells, 2, x[2])};
  return tile_index(g, c);
}

uint32_t tiles_tile_of_tet(const i2m_refine_t *r, uint32_t t)
{
  int32_t c[3];
  i2m_dt_tet_cell(r->dt, t, &r->tiling->cells, c);
  return tile_index(r->tiling, c);
}

i2m_gidx_t tiles_spare_gid(const tiling_t *g) { return g->gid_base + ((i2m_gidx_t)g->ntiles << TILE_GID_SHIFT); }

int tiles_color(const tiling_t *g, uint32_t id)
{
  int32_t c[3];
  tile_coords(g, id, c);
  const int p = g->period;
  return c[0] % p + p * (c[1] % p) + p * p * (c[2] % p);
}

static bool zone_fits_tet(const double zone[6], const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++)
    if (!i2m_box_holds(zone, i2m_dt_xyz(dt, v[i]))) return false;
  return true;
}

bool tiles_zone_holds(const i2m_refine_worker_t *w, const double x[3])
{
  return !w->tile || i2m_box_holds(w->ctx.zone, x);
}

bool tiles_ball_fits(const i2m_refine_worker_t *w, const double c[3], double r2)
{
  if (!w->tile) return true;
  if (!isfinite(r2)) return false;
  const double *z = w->ctx.zone, r = sqrt(r2);
  for (int a = 0; a < 3; a++)
    if (!(c[a] - r >= z[a] && c[a] + r <= z[3 + a])) return false;
  return true;
}

static size_t lists_work(const badlist_t *q, uint32_t npend)
{
  size_t n = npend;
  for (int l = 0; l < NLEVELS; l++) n += q[l].n;
  return n;
}

static size_t tile_work(const tile_t *tl) { return lists_work(tl->q, tl->npend) + tl->npts; }
static size_t tile_wide_work(const tile_t *tl) { return lists_work(tl->wq, tl->nwpend) + tl->nwpts; }

/* ---- queues ---- */

static i2m_err_t tile_push(i2m_refine_t *r, uint32_t id, int level, uint32_t t, uint32_t meta, bool wide)
{
  bad_t b = {t, meta, {0, 0, 0, 0}}; /* tile lists are narrow: the vertices are read when popped */
  tile_t *tl = &r->tiling->tile[id];
  return badlist_push(wide ? &tl->wq[level] : &tl->q[level], r->dt, &b);
}

static i2m_err_t pend_push(pending_t **a, uint32_t *n, uint32_t *cap, pending_t pv)
{
  if (*n == *cap) {
    uint32_t c = *cap ? 2 * *cap : 64;
    I2M_CALL(i2m_realloc(c, sizeof **a, a));
    *cap = c;
  }
  (*a)[(*n)++] = pv;
  return I2M_OK;
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

/* The element of a hand-over into its place: its tile's lists or wide lists, the sequential
 * pass, or the stuck ones.  An element whose tet no longer fits the tile's zone cannot be
 * done by the tile's task: the sequential pass (coarse tiles) or the wide task (octree). */
static i2m_err_t place(i2m_refine_t *r, handoff_t h)
{
  tiling_t *g = r->tiling;
  if (h.where == HAND_STUCK) return handoff_append(&g->stuck, &g->nstuck, &g->cap_stuck, h);
  if (h.to == TILE_NONE) return seq_append(g, h);
  tile_t *tl = &g->tile[h.to];
  bool wide = h.where == HAND_WIDE;
  if (h.level >= 0 && !wide && !zone_fits_tet(tl->zone, r->dt, h.t)) {
    if (!g->octree) return seq_append(g, h);
    wide = true;
  }
  if (h.level < 0) return wide ? pend_push(&tl->wpend, &tl->nwpend, &tl->cap_wpend, h.pv)
                               : pend_push(&tl->pend, &tl->npend, &tl->cap_pend, h.pv);
  return tile_push(r, h.to, h.level, h.t, h.meta, wide);
}

i2m_err_t tiles_route(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, bool *taken)
{
  i2m_refine_t *r = w->r;
  const uint32_t to = tiles_tile_of_tet(r, t);
  *taken = true;
  if (!w->tile) return place(r, (handoff_t){to, TILE_NONE, 0, level, t, meta, {0, 0}, HAND_QUEUE}); /* one thread */
  if (to == w->tile_id && !w->tile_wide) {
    *taken = false; /* its own tile: the worker's lists */
    return I2M_OK;
  }
  return handoff_append(&w->out, &w->nout, &w->cap_out,
                        (handoff_t){to, w->tile_id, w->tile->seq++, level, t, meta, {0, 0}, HAND_QUEUE});
}

/* The sides of a cell (bit 2a: its lower face along axis a, 2a + 1: its upper one; see
 * i2m_refine_tile_skip): all six, or those an element needs. */
#define SIDES_ALL ((1u << 6) - 1)
/* How far an element reaches, in radii of its tet's circumball beyond the margin: for a task
 * that may go without some sides, and once such a task could not do it. */
#define SKIP_BALL_GROW 1.5
#define NEED_BALL_GROW 3.0

/* The sides of box that tet t's circumball grown by `grow` times its radius and `margin` meets
 * (all six for a flat tet). */
static unsigned ball_sides(const i2m_refine_t *r, uint32_t t, const double box[6], double grow, double margin)
{
  tet_geom_t tg;
  tet_centre(r, t, &tg);
  if (!isfinite(tg.r2)) return SIDES_ALL;
  const double reach = grow * sqrt(tg.r2) + margin;
  unsigned sides = 0;
  for (int a = 0; a < 3; a++) {
    if (tg.cc[a] - reach < box[a]) sides |= 1u << (2 * a);
    if (tg.cc[a] + reach > box[3 + a]) sides |= 1u << (2 * a + 1);
  }
  return sides;
}

/* An element that a task going without some sides could not do: the sides it needs (its
 * ball grown further than skip_sides grows it, and twice the margin), for the next task; if it
 * seems to need none of those skipped, all of them (the cell's next task takes the whole
 * block). */
static void note_skipped_need(i2m_refine_worker_t *w, int level, uint32_t t)
{
  const i2m_refine_t *r = w->r;
  tile_t *tl = w->tile;
  double box[6];
  tile_box(r->tiling, w->tile_id, box);
  const unsigned sides = level >= 0 ? ball_sides(r, t, box, NEED_BALL_GROW, 2 * I2M_SKIP_MARGIN * r->delta) : 0;
  tl->skip_need |= (uint8_t)(sides & tl->skip ? sides : SIDES_ALL);
}

i2m_err_t tiles_defer(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, pending_t pv)
{
  const tiling_t *g = w->r->tiling;
  const uint32_t to = g->octree ? w->tile_id : TILE_NONE;
  const bool part = !w->tile_wide && w->tile->skip; /* (a task with more sides will try) */
  if (part) note_skipped_need(w, level, t);
  const int32_t where = !g->octree || part ? HAND_QUEUE : w->tile_wide ? HAND_STUCK : HAND_WIDE;
  return handoff_append(&w->out, &w->nout, &w->cap_out, (handoff_t){to, w->tile_id, w->tile->seq++, level, t, meta, pv, where});
}

/* ---- a worker on a tile: the tile's lists, slots, zone and block become the worker's ---- */

static void swap_lists(i2m_refine_worker_t *w, badlist_t *q, pending_t **pend, uint32_t *npend, uint32_t *cap_pend,
                       i2m_dt_slots_t *slots)
{
  for (int l = 0; l < NLEVELS; l++) {
    badlist_t x = w->q[l];
    w->q[l] = q[l];
    q[l] = x;
  }
  pending_t *p = w->pend;
  uint32_t n = w->npend, c = w->cap_pend;
  w->pend = *pend;
  w->npend = *npend;
  w->cap_pend = *cap_pend;
  *pend = p;
  *npend = n;
  *cap_pend = c;
  i2m_dt_slots_t s = w->ctx.slots;
  w->ctx.slots = *slots;
  *slots = s;
}

static void swap_tile(i2m_refine_worker_t *w, tile_t *tl, bool wide)
{
  if (wide) swap_lists(w, tl->wq, &tl->wpend, &tl->nwpend, &tl->cap_wpend, &tl->slots);
  else swap_lists(w, tl->q, &tl->pend, &tl->npend, &tl->cap_pend, &tl->slots);
}

/* The zone of a task of tile id that goes without the sides in skip: its normal zone, but
 * margin short of the cell's faces on those sides. */
static void skip_zone(const tiling_t *g, uint32_t id, unsigned skip, double margin, double zone[6])
{
  double box[6];
  tile_box(g, id, box);
  for (int a = 0; a < 3; a++) {
    zone[a] = skip >> (2 * a) & 1 ? box[a] + margin : g->tile[id].zone[a];
    zone[3 + a] = skip >> (2 * a + 1) & 1 ? box[3 + a] - margin : g->tile[id].zone[3 + a];
  }
}

void i2m_refine_tile_skip(i2m_refine_t *r, uint32_t id, unsigned skip) { r->tiling->tile[id].skip = (uint8_t)skip; }

void tiles_bind(i2m_refine_worker_t *w, uint32_t id, bool wide)
{
  const tiling_t *g = w->r->tiling;
  tile_t *tl = &g->tile[id];
  swap_tile(w, tl, wide);
  w->ctx.zone = wide ? tl->wzone : tl->zone;
  if (!wide && tl->skip) { /* (octree tiles only) */
    skip_zone(g, id, tl->skip, I2M_SKIP_MARGIN * w->r->delta, w->part_zone);
    w->ctx.zone = w->part_zone;
  }
  if (!wide) tl->skip_need = 0; /* (this task's elements that it cannot do will say what they need) */
  w->ctx.block = !g->octree ? NULL : wide ? &tl->wblock : &tl->block;
  w->ctx.bounded = true;
  w->ctx.locking = false; /* (zones instead of locks) */
  w->tile = tl;
  w->tile_id = id;
  w->tile_full = false;
  w->tile_wide = wide;
}

uint32_t tiles_of_block(const tiling_t *g, const i2m_dt_block_t *b, uint32_t out[125])
{
  uint32_t n = 0;
  for (int32_t k = b->lo[2]; k <= b->hi[2]; k++)
    for (int32_t j = b->lo[1]; j <= b->hi[1]; j++)
      for (int32_t i = b->lo[0]; i <= b->hi[0]; i++) out[n++] = tile_index(g, (int32_t[3]){i, j, k});
  return n;
}

void tiles_unbind(i2m_refine_worker_t *w)
{
  swap_tile(w, w->tile, w->tile_wide);
  if (!w->tile_wide) w->tile->skip = 0; /* (set for each task: i2m_refine_tile_skip) */
  w->ctx.zone = NULL;
  w->ctx.block = NULL;
  w->ctx.bounded = false;
  w->tile = NULL;
  w->tile_wide = false;
}

/* ---- bridge points (dist: the component rule's points, work of the task of their cell) ---- */

i2m_err_t tiles_add_point(i2m_refine_t *r, uint32_t id, const i2m_bridge_point_t *p, bool wide)
{
  tile_t *tl = &r->tiling->tile[id];
  i2m_bridge_point_t **a = wide ? &tl->wpts : &tl->pts;
  uint32_t *n = wide ? &tl->nwpts : &tl->npts, *cap = wide ? &tl->cap_wpts : &tl->cap_pts;
  if (*n == *cap) {
    *cap = *cap ? 2 * *cap : 16;
    I2M_CALL(i2m_realloc(*cap, sizeof **a, a));
  }
  (*a)[(*n)++] = *p;
  return I2M_OK;
}

/* The live tet of the worker's tile (its list of tets) whose centroid lies nearest to x, to
 * walk from, or I2M_DT_NONE.  (The first live one would do for a walk without bounds; a
 * task's walk stops at its block's edge, and from a tet far away it can leave the block on
 * its way: the knee at delta 1.5, deterministic, 2 ranks, left 4 bridge points stuck so.) */
static uint32_t tile_start_near(const i2m_refine_worker_t *w, const double x[3])
{
  const tile_t *tl = w->tile;
  const i2m_dt_t *dt = w->r->dt;
  uint32_t best = I2M_DT_NONE;
  double dmin = INFINITY;
  for (uint32_t i = 0; i < tl->ntets; i++) {
    const uint32_t t = tl->tets[i].t;
    if (i2m_dt_stamp(dt, t) != tl->tets[i].meta) continue;
    double c[3];
    i2m_dt_centroid(dt, t, c);
    const double d = i2m_dist2(c, x);
    if (d < dmin) {
      dmin = d;
      best = t;
    }
  }
  return best;
}

/* The task inserts its tile's bridge points (its wide task, the wide ones); what its zone
 * cannot hold goes to the wide task, or counts as stuck.  Every tile of the block then has
 * elements in an order that depends on who inserted what: tiles_canonical puts them in one.
 * Returns false when the tile's slots ran out (the points left stay for its next turn). */
static i2m_err_t insert_tile_points(i2m_refine_worker_t *w, bool *full)
{
  i2m_refine_t *r = w->r;
  tile_t *tl = w->tile;
  const bool wide = w->tile_wide;
  i2m_bridge_point_t *pts = wide ? tl->wpts : tl->pts;
  uint32_t n = wide ? tl->nwpts : tl->npts, done = 0;
  *full = false;
  for (; done < n; done++) {
    const i2m_bridge_point_t *p = &pts[done];
    const uint32_t start = tile_start_near(w, p->x);
    uint32_t v;
    i2m_dt_status_t st = start == I2M_DT_NONE ? I2M_DT_FROZEN : i2m_dt_insert_walk(&w->ctx, p->x, p->gid, I2M_VK_FREE, start, &v);
    if (st == I2M_DT_FULL) {
      i2m_dt_unlock_all(&w->ctx);
      *full = true;
      break;
    }
    if (st == I2M_DT_OK) {
      w->st.insertions++;
      w->st.bridges++;
      i2m_err_t err = dist_tracking(r) ? dist_note_vertex(w, v) : I2M_OK;
      if (err == I2M_OK) err = worker_keep_created(w);
      if (err == I2M_OK) err = worker_process_created(w, w->created, w->ncreated);
      i2m_dt_unlock_all(&w->ctx);
      I2M_CALL(err);
      continue;
    }
    i2m_dt_unlock_all(&w->ctx);
    if (st == I2M_DT_DUPLICATE) continue;
    if (wide) r->tiling->stuck_points++; /* (the other tasks of the phase never touch the tiling's fields: this one runs alone) */
    else I2M_CALL(tiles_add_point(r, w->tile_id, p, true));
  }
  memmove(pts, pts + done, (n - done) * sizeof *pts);
  if (wide) tl->nwpts = n - done;
  else tl->npts = n - done;
  uint32_t ids[125];
  const uint32_t nb = tiles_of_block(r->tiling, wide ? &tl->wblock : &tl->block, ids);
  for (uint32_t i = 0; i < nb; i++) r->tiling->tile[ids[i]].dirty = true;
  return I2M_OK;
}

/* The elements this task handed to other tiles since entry n0 of its hand-overs, judged while
 * its block is bound: a dead tet, or one with nothing to do, is dropped (the dist layer's
 * asynchronous mode).  Such "perhaps" elements (a face across the block's edge, R1 when the
 * tet's own vertices are not near enough) made the work that drew many of the last tasks of a
 * run to fetch whole blocks and find nothing to do (knee at delta 0.33, 2 ranks: 37 of 165
 * fetching batches made fewer than 50 tets and moved a third of the bytes).  Not in the
 * deterministic mode: the surface grid near the block's edge depends on other threads. */
static void judge_handoffs(i2m_refine_worker_t *w, uint32_t n0)
{
  const i2m_dt_t *dt = w->r->dt;
  uint32_t k = n0;
  for (uint32_t i = n0; i < w->nout; i++) {
    const handoff_t h = w->out[i];
    if (h.level >= 0 && i2m_dt_stamp(dt, h.t) != h.meta) continue; /* gone */
    if (h.level == LEVEL_SURFACE && h.where == HAND_QUEUE && classify_nothing_to_do(w, h.t)) {
      w->st.judged++;
      continue;
    }
    w->out[k++] = h;
  }
  w->nout = k;
}

/* Worker k on tile id (its wide task when wide) until its lists are empty or its slots run
 * out; a task with bridge points inserts them and ends (its elements wait for the next). */
static i2m_err_t run_tile(i2m_refine_t *r, int k, uint32_t id, bool wide)
{
  i2m_refine_worker_t *w = &r->workers[k];
  double t0 = i2m_wtime();
  tile_t *tl = &r->tiling->tile[id];
  const uint32_t n0 = w->nout;
  tiles_bind(w, id, wide);
  int s = I2M_STEP_IDLE;
  bool full = false;
  if (wide ? tl->nwpts : tl->npts) {
    s = step_result(w, insert_tile_points(w, &full), I2M_STEP_IDLE);
    w->tile_full |= full;
  } else {
    do {
      s = worker_step(w);
    } while (s == I2M_STEP_DONE);
  }
  if (r->async_tasks && !wide && s != I2M_STEP_ERROR) judge_handoffs(w, n0);
  full = w->tile_full;
  tiles_unbind(w);
  w->st.seconds += i2m_wtime() - t0;
  if (full && tl->grant < (1u << 16)) tl->grant *= 2; /* the tile ran out of slots: more next time */
  return s == I2M_STEP_FULL && full ? I2M_OK : step_outcome(w, s);
}

i2m_err_t i2m_refine_tile_run(i2m_refine_t *r, int k, uint32_t id) { return run_tile(r, k, id, false); }

/* ---- setup and teardown ---- */

static void tile_free(tile_t *tl)
{
  i2m_free(&tl->tets);
  for (int l = 0; l < NLEVELS; l++) {
    badlist_free(&tl->q[l]);
    badlist_free(&tl->wq[l]);
  }
  i2m_free(&tl->pend);
  i2m_free(&tl->wpend); /* (the slots went back with i2m_dt_slots_release) */
  i2m_free(&tl->pts);
  i2m_free(&tl->wpts);
}

static void tiling_free(tiling_t **gp)
{
  tiling_t *g = *gp;
  if (!g) return;
  for (uint32_t id = 0; g->tile && id < g->ntiles; id++) tile_free(&g->tile[id]);
  i2m_free(&g->tile);
  i2m_free(&g->seq);
  i2m_free(&g->stuck);
  i2m_free(&g->merge);
  i2m_free(&g->active);
  i2m_free(&g->order);
  i2m_free(&g->level);
  i2m_free(gp);
}

/* Coarse tiles: side (from the final delta: the coarse phase uses the same tiles) and margin
 * (from the delta in force: same-colour zones stay more than 2 delta apart, as R7 looks that
 * far). */
static void coarse_size(const i2m_refine_t *r, double *side, double *margin)
{
  double ext = 0;
  for (int a = 0; a < 3; a++) ext = fmax(ext, r->block_hi[a] - r->block_lo[a]);
  *side = fmax(TILE_MIN_DELTAS * r->p.delta, ext / TILES_PER_AXIS);
  *margin = 0.5 * *side - 1.01 * r->delta;
}

/* The octree's cells: 2^depth along each axis of the labelled block. */
static void octree_cells(const i2m_refine_t *r, int depth, i2m_dt_cells_t *c, double side[3])
{
  for (int a = 0; a < 3; a++) {
    c->origin[a] = r->block_lo[a];
    c->n[a] = 1 << depth;
    side[a] = (r->block_hi[a] - r->block_lo[a]) / (double)c->n[a];
    c->inv_side[a] = 1.0 / side[a];
  }
}

void i2m_refine_tiling_bound(i2m_refine_t *r)
{
  double side, margin;
  coarse_size(r, &side, &margin);
  /* a cavity holds the tets whose balls hold the point: with radii below margin / 2 it stays
   * within the margin of any point of the tile (once the bound holds where the point goes) */
  double m = margin;
  if (r->octree_depth >= 0) { /* the octree's zones are grown by half a cell */
    i2m_dt_cells_t c;
    double s[3];
    octree_cells(r, r->octree_depth, &c, s);
    for (int a = 0; a < 3; a++) m = fmin(m, 0.5 * s[a]);
  }
  r->background_size2 = 0.25 * m * m;
  /* the tets around the block too, a margin deep: a Delaunay ball through a vertex of the block
   * that reached beyond them would hold their vertices, so no tet of the virtual box's borders
   * a cavity of the block (a cavity at the block's edge met one, whose centroid lay cells away) */
  r->background_shell = m;
}

/* The cells within `radius` of tile c (clamped to the grid: the border cells hold every tet
 * beyond it) and the tile grown by `grow` margins. */
static void tile_reach(const tiling_t *g, const int32_t c[3], int radius, double grow, i2m_dt_block_t *b, double zone[6])
{
  b->cells = g->cells;
  cell_box(g, c, zone);
  for (int a = 0; a < 3; a++) {
    b->lo[a] = c[a] - radius < 0 ? 0 : c[a] - radius;
    b->hi[a] = c[a] + radius >= g->cells.n[a] ? g->cells.n[a] - 1 : c[a] + radius;
    zone[a] -= grow * g->margin[a];
    zone[3 + a] += grow * g->margin[a];
  }
}

static i2m_err_t tiling_make(i2m_refine_t *r, bool octree, tiling_t **out)
{
  tiling_t *g = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *g, &g));
  g->octree = octree;
  if (octree) {
    g->period = 3;
    octree_cells(r, r->octree_depth, &g->cells, g->side);
    for (int a = 0; a < 3; a++) g->margin[a] = 0.5 * g->side[a];
    g->gid_base = OCTREE_GID_BASE;
  } else {
    double side, margin;
    g->period = 2;
    coarse_size(r, &side, &margin);
    for (int a = 0; a < 3; a++) {
      double n = ceil((r->block_hi[a] - r->block_lo[a]) / side);
      g->cells.origin[a] = r->block_lo[a];
      g->cells.n[a] = n < 1 ? 1 : (int32_t)n;
      g->cells.inv_side[a] = 1.0 / side;
      g->side[a] = side;
      g->margin[a] = margin;
    }
    g->gid_base = (i2m_gidx_t)(++r->tilings_made) << TILING_GID_SHIFT;
  }
  g->ntiles = (uint32_t)g->cells.n[0] * (uint32_t)g->cells.n[1] * (uint32_t)g->cells.n[2];
  i2m_err_t err = i2m_calloc(g->ntiles, sizeof *g->tile, &g->tile);
  if (err == I2M_OK) err = i2m_malloc(g->ntiles, sizeof *g->active, &g->active);
  if (err == I2M_OK) err = i2m_malloc(g->ntiles, sizeof *g->order, &g->order);
  for (uint32_t id = 0; err == I2M_OK && id < g->ntiles; id++) {
    tile_t *tl = &g->tile[id];
    int32_t c[3];
    tile_coords(g, id, c);
    tile_reach(g, c, 1, 1.0, &tl->block, tl->zone);
    tile_reach(g, c, 2, 3.0, &tl->wblock, tl->wzone);
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
        if (i2m_dt_stamp(r->dt, b.t) != b.meta) continue;
        I2M_CALL(place(r, (handoff_t){tiles_tile_of_tet(r, b.t), TILE_NONE, 0, l, b.t, b.meta, {0, 0}, HAND_QUEUE}));
      }
      w->q[l].n = 0;
      I2M_CALL(badlist_set_wide(&w->q[l], r->dt, false));
    }
    for (uint32_t i = 0; i < w->npend; i++) { /* (no tile of their own: R7's candidates anywhere) */
      const pending_t pv = w->pend[i];
      if (r->tiling->octree) { /* the tile that holds the vertex */
        if (r->dt->vkind[pv.v] != I2M_VK_FREE || i2m_dt_gid(r->dt, pv.v) != pv.gid) continue; /* gone */
        const uint32_t to = tiles_tile_of_point(r, i2m_dt_xyz(r->dt, pv.v));
        I2M_CALL(place(r, (handoff_t){to, TILE_NONE, 0, -1, 0, 0, pv, HAND_QUEUE}));
      } else {
        I2M_CALL(seq_append(r->tiling, (handoff_t){TILE_NONE, TILE_NONE, 0, -1, 0, 0, pv, HAND_QUEUE}));
      }
    }
    w->npend = 0;
  }
  return I2M_OK;
}

static i2m_err_t tiling_begin(i2m_refine_t *r, bool octree)
{
  I2M_CHECK(!r->tiling, I2M_ERR_INTERNAL, "a tiling is already in place");
  I2M_CHECK(!octree || r->octree_depth >= 0, I2M_ERR_INTERNAL, "no octree depth set");
  I2M_CALL(tiling_make(r, octree, &r->tiling));
  for (int k = 0; k < r->nworkers; k++) r->workers[k].ctx.locking = false; /* zones instead of locks */
  i2m_err_t err = adopt_worker_elements(r);
  if (err != I2M_OK) tiling_free(&r->tiling);
  return err;
}

i2m_err_t i2m_refine_tiling_begin(i2m_refine_t *r) { return tiling_begin(r, false); }
i2m_err_t i2m_refine_octree_begin(i2m_refine_t *r) { return tiling_begin(r, true); }

void i2m_refine_set_depth(i2m_refine_t *r, int depth)
{
  r->octree_depth = depth;
  i2m_refine_tiling_bound(r); /* (its zones bound the tets: on every rank, whoever builds the coarse mesh) */
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
      err = place(r, (handoff_t){tiles_tile_of_tet(r, t), TILE_NONE, 0, g->level[t], t, i2m_dt_stamp(r->dt, t), {0, 0}, HAND_QUEUE});
  i2m_free(&g->level);
  return err;
}

/* ---- phases ---- */

bool i2m_refine_tiling_has_work(const i2m_refine_t *r)
{
  const tiling_t *g = r->tiling;
  if (g->nseq) return true;
  for (uint32_t id = 0; id < g->ntiles; id++)
    if (tile_work(&g->tile[id]) || tile_wide_work(&g->tile[id])) return true;
  return false;
}

int i2m_refine_tiling_colors(const i2m_refine_t *r)
{
  const int p = r->tiling->period;
  return p * p * p;
}

static int cmp_u64(const void *x, const void *y)
{
  uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
  return (a > b) - (a < b);
}

/* Drops the entries of a list whose tets changed since they were queued (most of them): the
 * work a tile has, and the slots it is granted, then depend on its live elements only, not on
 * the stale entries that another process's copy of the tile never received. */
static void compact_lists(const i2m_dt_t *dt, badlist_t *q)
{
  for (int l = 0; l < NLEVELS; l++) {
    size_t n = 0;
    for (size_t i = 0; i < q[l].n; i++)
      if (i2m_dt_stamp(dt, q[l].e[i][0]) == q[l].e[i][1]) {
        q[l].e[n][0] = q[l].e[i][0];
        q[l].e[n][1] = q[l].e[i][1];
        n++;
      }
    q[l].n = n;
  }
}

/* ---- an order of their own ---- */

typedef struct {
  i2m_gidx_t key[4];
  uint32_t t, meta;
} keyed_t;

static int cmp_keyed(const void *x, const void *y) { return pieces_key_cmp(((const keyed_t *)x)->key, ((const keyed_t *)y)->key); }

static int cmp_pend_gid(const void *x, const void *y)
{
  const i2m_gidx_t a = ((const pending_t *)x)->gid, b = ((const pending_t *)y)->gid;
  return (a > b) - (a < b);
}

/* A narrow list sorted by tet key (scratch: room for its entries). */
static void sort_list(const i2m_dt_t *dt, badlist_t *q, keyed_t *k)
{
  for (size_t i = 0; i < q->n; i++) {
    k[i].t = q->e[i][0];
    k[i].meta = q->e[i][1];
    pieces_tet_key(dt, k[i].t, k[i].key);
  }
  if (q->n > 1) qsort(k, q->n, sizeof *k, cmp_keyed);
  for (size_t i = 0; i < q->n; i++) {
    q->e[i][0] = k[i].t;
    q->e[i][1] = k[i].meta;
  }
}

void tiles_canonical(i2m_refine_t *r, uint32_t id)
{
  tiling_t *g = r->tiling;
  tile_t *tl = &g->tile[id];
  const i2m_dt_t *dt = r->dt;
  compact_lists(dt, tl->q);
  compact_lists(dt, tl->wq);
  size_t most = 0;
  for (int l = 0; l < NLEVELS; l++) {
    if (g->octree) { /* (as place() puts them) */
      size_t n = 0;
      for (size_t i = 0; i < tl->q[l].n; i++) {
        const bad_t b = {tl->q[l].e[i][0], tl->q[l].e[i][1], {0, 0, 0, 0}};
        if (zone_fits_tet(tl->zone, dt, b.t)) {
          tl->q[l].e[n][0] = b.t;
          tl->q[l].e[n][1] = b.meta;
          n++;
        } else if (badlist_push(&tl->wq[l], dt, &b) != I2M_OK) {
          n++; /* (out of memory: it stays, only the order is lost) */
        }
      }
      tl->q[l].n = n;
    }
    most = tl->q[l].n > most ? tl->q[l].n : most;
    most = tl->wq[l].n > most ? tl->wq[l].n : most;
  }
  keyed_t *k = NULL;
  if (most && i2m_malloc(most, sizeof *k, &k) == I2M_OK) {
    for (int l = 0; l < NLEVELS; l++) {
      sort_list(dt, &tl->q[l], k);
      sort_list(dt, &tl->wq[l], k);
    }
    i2m_free(&k);
  }
  if (tl->npend > 1) qsort(tl->pend, tl->npend, sizeof *tl->pend, cmp_pend_gid);
  if (tl->nwpend > 1) qsort(tl->wpend, tl->nwpend, sizeof *tl->wpend, cmp_pend_gid);
  tl->dirty = false;
}

void tiles_canonical_all(i2m_refine_t *r)
{
  for (uint32_t id = 0; id < r->tiling->ntiles; id++) tiles_canonical(r, id);
}

/* Slots for a tile's work, from its live elements (it stops when they run out).  The
 * deterministic modes start small and double the grant each time a tile runs out (where a
 * task stops is part of the result, and memory stays near what is used).  The asynchronous
 * tasks of the distributed level start at ASYNC_GRANT, 16 slots a bad element (one costs
 * about 4 insertions of some 6.5 tets each at the start): a task that stopped early ended,
 * was merged, fed back and asked for again (knee at delta 0.33, 2 ranks: ~2,100 tasks, 460 of
 * each rank's ~700 batches the cell of the batch before, 5 K, 12 K, 34 K, 69 K, 130 K tets
 * made in a row; with it ~800 tasks). */
#define ASYNC_GRANT 64
static i2m_err_t grant_tile(i2m_refine_t *r, tile_t *tl, size_t work)
{
  if (r->async_tasks && tl->grant < ASYNC_GRANT) tl->grant = ASYNC_GRANT; /* (and it doubles from there) */
  uint64_t want = (uint64_t)tl->grant * work / 4 + 64; /* (a fraction of the elements insert) */
  if (want > (1u << 24)) want = 1u << 24;
  return i2m_dt_slots_grant(r->dt, &tl->slots, (uint32_t)want, (uint32_t)(want / 4 + 64));
}

i2m_err_t i2m_refine_tiling_phase(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles)
{
  tiling_t *g = r->tiling;
  uint32_t n = 0;
  for (uint32_t id = 0; id < g->ntiles; id++) { /* the busiest first: key (less work, id) */
    tile_t *tl = &g->tile[id];
    if (tiles_color(g, id) != color || !tile_work(tl)) continue;
    compact_lists(r->dt, tl->q);
    const size_t wk = tile_work(tl);
    if (wk) g->order[n++] = (uint64_t)(UINT32_MAX - (wk < UINT32_MAX ? wk : UINT32_MAX)) << 32 | id;
  }
  if (n > 1) qsort(g->order, n, sizeof *g->order, cmp_u64);
  for (uint32_t i = 0; i < n; i++) g->active[i] = (uint32_t)g->order[i];
  g->nactive = n;
  for (uint32_t i = 0; i < n; i++) {
    tile_t *tl = &g->tile[g->active[i]];
    I2M_CALL(grant_tile(r, tl, tile_work(tl)));
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

/* Empty lists of the phase's tiles keep no memory (hundreds of tiles). */
static void trim_tile(tile_t *tl)
{
  for (int l = 0; l < NLEVELS; l++) {
    if (tl->q[l].n == 0) badlist_free(&tl->q[l]);
    if (tl->wq[l].n == 0) badlist_free(&tl->wq[l]);
  }
  if (tl->npend == 0) {
    i2m_free(&tl->pend);
    tl->cap_pend = 0;
  }
  if (tl->nwpend == 0) {
    i2m_free(&tl->wpend);
    tl->cap_wpend = 0;
  }
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
    trim_tile(tl);
  }
  g->nactive = 0;
  for (size_t i = 0; i < n; i++) {
    handoff_t h = g->merge[i];
    if (h.level >= 0 && i2m_dt_stamp(r->dt, h.t) != h.meta) continue; /* gone meanwhile */
    I2M_CALL(place(r, h));
  }
  return I2M_OK;
}

/* Coarse tiles: worker 0 does, in order, what no tile could (no zone). */
static i2m_err_t sequential_pass(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  i2m_refine_worker_t *w = &r->workers[0];
  const size_t n0 = g->nseq;
  double t0 = i2m_wtime();
  for (size_t i = 0; i < n0; i++) { /* each element once, with what follows from it */
    handoff_t h = g->seq[i];
    if (h.level >= 0) {
      if (i2m_dt_stamp(r->dt, h.t) != h.meta) continue;
      bad_t b = {h.t, h.meta, {0, 0, 0, 0}};
      memcpy(b.v, r->dt->tv + 4 * (size_t)h.t, sizeof b.v);
      I2M_CALL(worker_push_entry(w, h.level, &b));
    } else {
      I2M_CALL(pend_push(&w->pend, &w->npend, &w->cap_pend, h.pv));
    }
    int s;
    while ((s = worker_step(w)) == I2M_STEP_DONE) {
    }
    I2M_CALL(step_outcome(w, s));
    g->sequential_ops++;
  }
  if (g->nseq > n0) memmove(g->seq, g->seq + n0, (g->nseq - n0) * sizeof *g->seq); /* what it sent on: next time */
  g->nseq -= n0;
  w->st.seconds += i2m_wtime() - t0;
  return I2M_OK;
}

i2m_err_t i2m_refine_tiles_prepare(i2m_refine_t *r, const uint32_t *tiles, uint32_t n)
{
  tiling_t *g = r->tiling;
  pieces_invalidate(r); /* (the tasks change the mesh) */
  g->nactive = 0;
  for (uint32_t i = 0; i < n; i++) {
    tile_t *tl = &g->tile[tiles[i]];
    if (tl->dirty) tiles_canonical(r, tiles[i]);
    compact_lists(r->dt, tl->q);
    I2M_CALL(grant_tile(r, tl, tile_work(tl)));
    g->active[g->nactive++] = tiles[i];
  }
  I2M_CALL(vgrid_reserve(&r->surf, r->dt->cap_v)); /* nobody grows the grids while tiles run */
  return vgrid_reserve(&r->freev, r->dt->cap_v);
}

/* A task of at most this many elements may go without some sides (skip_sides looks at each). */
#define SKIP_MAX_WORK 4096
/* The sides of its cell that a task of tile id's elements may go without (see
 * i2m_refine_tile_skip): those that no element's circumball, its radius grown by half and the
 * margin, meets, nor any element its last task could not do (note_skipped_need); 0 when its
 * elements are many, any is a pending removal or a bridge point, or one that its last task
 * could not do seemed to need none of the sides skipped.  The asynchronous mode only. */
static unsigned skip_sides(const i2m_refine_t *r, uint32_t id)
{
  const tiling_t *g = r->tiling;
  const tile_t *tl = &g->tile[id];
  const double margin = I2M_SKIP_MARGIN * r->delta;
  const size_t work = tile_work(tl);
  if (!r->async_tasks || !g->octree || !work || work > SKIP_MAX_WORK || tl->npend || tl->npts) return 0;
  for (int a = 0; a < 3; a++)
    if (g->side[a] < 4 * margin) return 0;
  double box[6];
  tile_box(g, id, box);
  unsigned need = tl->skip_need;
  for (int l = 0; l < NLEVELS && need != SIDES_ALL; l++)
    for (size_t i = 0; i < tl->q[l].n && need != SIDES_ALL; i++) need |= ball_sides(r, tl->q[l].e[i][0], box, SKIP_BALL_GROW, margin);
  return ~need & SIDES_ALL;
}

void i2m_refine_tile_figures(i2m_refine_t *r, uint32_t id, int64_t fig[I2M_TILE_NFIG])
{
  tile_t *tl = &r->tiling->tile[id];
  if (tl->dirty) tiles_canonical(r, id);
  compact_lists(r->dt, tl->q);
  compact_lists(r->dt, tl->wq);
  fig[0] = (int64_t)tile_work(tl);
  fig[1] = (int64_t)tile_wide_work(tl);
  fig[2] = tl->ntets; /* (an estimate: stale entries are dropped when the list grows) */
  fig[3] = tl->npts;
  fig[4] = tl->nwpts;
  fig[5] = skip_sides(r, id);
}

void i2m_refine_tiling_cells(const i2m_refine_t *r, int32_t n[3])
{
  for (int a = 0; a < 3; a++) n[a] = r->tiling->cells.n[a];
}

/* ---- the octree's wide tasks ---- */

i2m_err_t i2m_refine_tiling_wide_tiles(i2m_refine_t *r, const uint32_t **tiles, uint32_t *ntiles)
{
  tiling_t *g = r->tiling;
  uint32_t n = 0;
  for (uint32_t id = 0; id < g->ntiles; id++) {
    tile_t *tl = &g->tile[id];
    if (!tile_wide_work(tl)) continue;
    compact_lists(r->dt, tl->wq);
    if (tile_wide_work(tl)) g->active[n++] = id;
  }
  g->nactive = n;
  *tiles = g->active;
  *ntiles = n;
  return I2M_OK;
}

i2m_err_t i2m_refine_tile_run_wide(i2m_refine_t *r, int k, uint32_t id)
{
  tile_t *tl = &r->tiling->tile[id];
  pieces_invalidate(r); /* (the task changes the mesh) */
  if (tl->dirty) tiles_canonical(r, id);
  I2M_CALL(grant_tile(r, tl, tile_wide_work(tl)));
  I2M_CALL(vgrid_reserve(&r->surf, r->dt->cap_v));
  I2M_CALL(vgrid_reserve(&r->freev, r->dt->cap_v));
  i2m_err_t err = run_tile(r, k, id, true);
  i2m_dt_slots_release(r->dt, &tl->slots);
  r->tiling->wide_tasks++;
  return err;
}

/* Octree: the wide tasks, one at a time in tile order, each merged before the next. */
static i2m_err_t wide_pass(i2m_refine_t *r)
{
  const uint32_t *tiles;
  uint32_t n;
  I2M_CALL(i2m_refine_tiling_wide_tiles(r, &tiles, &n));
  uint32_t *ids = NULL; /* (the merge reuses the active list) */
  I2M_CALL(i2m_malloc(n ? n : 1, sizeof *ids, &ids));
  memcpy(ids, tiles, n * sizeof *ids);
  i2m_err_t err = I2M_OK;
  for (uint32_t i = 0; i < n && err == I2M_OK; i++) {
    err = i2m_refine_tile_run_wide(r, 0, ids[i]);
    r->tiling->nactive = 0;
    if (err == I2M_OK) err = i2m_refine_tiling_merge(r);
  }
  i2m_free(&ids);
  return err;
}

i2m_err_t i2m_refine_tiling_sequential(i2m_refine_t *r)
{
  tiling_t *g = r->tiling;
  i2m_err_t err = g->octree ? wide_pass(r) : sequential_pass(r);
  g->rounds++;
  return err;
}

/* Does stuck tet t break a guarantee?  Not when only the background bound wants it split: a
 * tet outside every label whose ball meets no interface and whose neighbours are outside too
 * (the bound is there so that cavities fit zones, and one in the shell around the labelled
 * block may border the virtual box's tets, which no zone holds). */
static bool stuck_matters(const i2m_refine_t *r, uint32_t t)
{
  tet_geom_t geo;
  tet_geom(r, t, PROBE_CLOSEST, &geo);
  if (geo.label != 0 || geo.probe.d2 <= geo.r2) return true;
  for (int i = 0; i < 4; i++) {
    const uint32_t nb = r->dt->tn[4 * (size_t)t + i];
    const int l = nb == I2M_DT_NONE ? 0 : nb == I2M_DT_REMOTE ? dist_ghost_label(r, t, i) : tinfo(r->dt, nb >> 2)->label;
    if (l != 0) return true;
  }
  return false;
}

i2m_err_t i2m_refine_tiling_check_stuck(i2m_refine_t *r)
{
  const tiling_t *g = r->tiling;
  int64_t n = 0;
  for (size_t i = 0; g && i < g->nstuck; i++) {
    const handoff_t *h = &g->stuck[i];
    if (h->level < 0) /* (a removal whose vertex is not on this rank: PACK_NONE) */
      n += h->pv.v < i2m_dt_nverts_slots(r->dt) && r->dt->vkind[h->pv.v] == I2M_VK_FREE &&
           i2m_dt_gid(r->dt, h->pv.v) == h->pv.gid;
    else n += i2m_dt_stamp(r->dt, h->t) == h->meta && stuck_matters(r, h->t);
  }
  I2M_CHECK(!g || g->stuck_points == 0, I2M_ERR_INTERNAL,
            "%lld points of the component rule could not be inserted inside any subregion's zone (not even a wide one): "
            "a tissue would come out in pieces; try a smaller --depth", (long long)g->stuck_points);
  I2M_CHECK(n == 0, I2M_ERR_INTERNAL,
            "%lld bad elements could not be treated inside any subregion's zone (not even a wide one): the mesh "
            "would break a guarantee; try a smaller --depth",
            (long long)n);
  return I2M_OK;
}

void i2m_refine_tiling_figures(const i2m_refine_t *r, double *side, int64_t *rounds, int64_t *sequential_ops)
{
  const tiling_t *g = r->tiling;
  *side = g ? fmax(g->side[0], fmax(g->side[1], g->side[2])) : 0;
  *rounds = g ? g->rounds : 0;
  *sequential_ops = g ? g->sequential_ops + g->wide_tasks : 0;
}
