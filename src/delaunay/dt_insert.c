/* Delaunay layer: Bowyer–Watson insertion from a tet in conflict (breadth-first cavity
 * search, refill that reuses the cavity's slots, adjacency by the edge table), the
 * visibility walk, and the lock protocol hooks (REFERENCE §2.2 and §3.5). */
#include "dt_impl.h"

void i2m_dt_unlock_all(i2m_dt_ctx_t *ctx)
{
  _Atomic uint32_t *L = ctx->dt->vlock;
  for (uint32_t k = 0; k < ctx->nheld; k++) atomic_store_explicit(&L[ctx->held[k]], 0, memory_order_release);
  ctx->nheld = 0;
}

/* Clears the marks of the cavity found so far and releases the vertices: nothing changed. */
static i2m_dt_status_t cavity_abandon(i2m_dt_ctx_t *ctx, i2m_dt_status_t why)
{
  i2m_dt_t *dt = ctx->dt;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    uint32_t t = ctx->cav[k];
    meta_store(dt, t, i2m_dt_meta(dt, t) & ~I2M_TM_MARK);
  }
  ctx->ncav = ctx->nbnd = 0;
  i2m_dt_unlock_all(ctx);
  if (why == I2M_DT_ROLLBACK) ctx->n_rollback++;
  return why;
}

/* Gives vertex v a local index for this insertion: takes its lock word (a compare-and-swap
 * in threaded runs) and caches its row translated by p and lifted (a vertex locked earlier
 * in the same operation gets its row on first use).  Returns the index, -1 if another
 * thread holds the vertex, -2 when out of memory. */
static inline int64_t local_vertex(i2m_dt_ctx_t *ctx, uint32_t v, const double *p)
{
  _Atomic uint32_t *L = &ctx->dt->vlock[v];
  uint32_t cur = atomic_load_explicit(L, memory_order_relaxed);
  uint32_t k;
  if ((cur & I2M_DT_OWNER_MASK) == ctx->owner) {
    k = cur >> I2M_DT_OWNER_BITS;
    if (I2M_LIKELY(ctx->rowstamp[k] == ctx->epoch)) return k;
  } else {
    k = ctx->nheld;
    if (I2M_UNLIKELY(k == ctx->cap_held) && ctx_hold_room(ctx) != I2M_OK) return -2;
    uint32_t word = ctx->owner | (k << I2M_DT_OWNER_BITS);
    if (ctx->locking) {
      uint32_t expected = 0;
      if (cur != 0 || !atomic_compare_exchange_strong_explicit(L, &expected, word, memory_order_acquire,
                                                               memory_order_relaxed)) {
        ctx->conflict_owner = (cur ? cur : expected) & I2M_DT_OWNER_MASK;
        return -1;
      }
    } else {
      atomic_store_explicit(L, word, memory_order_relaxed);
    }
    ctx->held[k] = v;
    ctx->nheld = k + 1;
  }
  ctx->rowstamp[k] = ctx->epoch;
  double *row = ctx->rows + 4 * (size_t)k;
  i2m_insphere_row(i2m_dt_xyz(ctx->dt, v), p, row);
  const double ax = fabs(row[0]), ay = fabs(row[1]), az = fabs(row[2]);
  if ((ax > ctx->rmax[0]) | (ay > ctx->rmax[1]) | (az > ctx->rmax[2])) {
    ctx->rmax[0] = ax > ctx->rmax[0] ? ax : ctx->rmax[0];
    ctx->rmax[1] = ay > ctx->rmax[1] ? ay : ctx->rmax[1];
    ctx->rmax[2] = az > ctx->rmax[2] ? az : ctx->rmax[2];
    ctx->isp_bound = i2m_insphere_rows_bound(ctx->rmax[0], ctx->rmax[1], ctx->rmax[2]);
  }
  return k;
}

static inline uint32_t local_of(const i2m_dt_t *dt, uint32_t v)
{
  return atomic_load_explicit(&dt->vlock[v], memory_order_relaxed) >> I2M_DT_OWNER_BITS;
}

/* Conflict test of the tet whose vertices have local indices l[] (positively oriented when
 * flip is 1, negatively when -1) against p, from the cached rows.  First against one bound
 * for every row of this insertion, then against the tet's own bound (tighter when the
 * cavity spans very different sizes); the exact evaluation with the perturbation decides
 * what neither certifies (global vertex ids from ctx->held). */
static inline int conflict(const i2m_dt_ctx_t *ctx, const uint32_t *l, int flip, const double *p, i2m_gidx_t gid)
{
  const double *R = ctx->rows;
  const double *ra = R + 4 * l[0], *rb = R + 4 * l[1], *rc = R + 4 * l[2], *rd = R + 4 * l[3];
  const double det = i2m_insphere_det_rows(ra, rb, rc, rd);
  if (I2M_LIKELY(fabs(det) > ctx->isp_bound)) return flip * ((det > 0.0) - (det < 0.0));
  int s = i2m_insphere_filter_rows(ra, rb, rc, rd);
  if (s != 0) return flip * s;
  const i2m_dt_t *dt = ctx->dt;
  const uint32_t *H = ctx->held;
  return flip * i2m_insphere_sos_exact(i2m_dt_xyz(dt, H[l[0]]), i2m_dt_xyz(dt, H[l[1]]), i2m_dt_xyz(dt, H[l[2]]),
                                       i2m_dt_xyz(dt, H[l[3]]), p, i2m_dt_gid(dt, H[l[0]]), i2m_dt_gid(dt, H[l[1]]),
                                       i2m_dt_gid(dt, H[l[2]]), i2m_dt_gid(dt, H[l[3]]), gid);
}

static inline bool row_is_zero(const i2m_dt_ctx_t *ctx, uint32_t l) { return ctx->rows[4 * (size_t)l + 3] == 0.0; }

static inline i2m_dt_status_t cavity_push(i2m_dt_ctx_t *ctx, uint32_t t, const uint32_t *l)
{
  if (I2M_UNLIKELY(ctx->ncav == ctx->cap_cav) && ctx_cavity_room(ctx, ctx->ncav + 1) != I2M_OK) return I2M_DT_FULL;
  memcpy(ctx->cavl + 4 * (size_t)ctx->ncav, l, 4 * sizeof *l);
  ctx->cav[ctx->ncav++] = t;
  meta_store(ctx->dt, t, i2m_dt_meta(ctx->dt, t) | I2M_TM_MARK);
  return I2M_DT_OK;
}

static I2M_NOINLINE i2m_dt_status_t boundary_grow(i2m_dt_ctx_t *ctx)
{
  uint32_t cap = ctx->cap_bnd + ctx->cap_bnd / 2 + 64;
  if (i2m_realloc(cap, sizeof(i2m_dt_bface_t), &ctx->bnd) != I2M_OK) return I2M_DT_FULL;
  ctx->cap_bnd = cap;
  return I2M_DT_OK;
}

static inline i2m_dt_status_t boundary_push(i2m_dt_ctx_t *ctx, uint32_t t, uint32_t i, uint32_t out, const uint32_t *l)
{
  if (I2M_UNLIKELY(ctx->nbnd == ctx->cap_bnd) && boundary_grow(ctx) != I2M_DT_OK) return I2M_DT_FULL;
  i2m_dt_bface_t *b = &ctx->bnd[ctx->nbnd++];
  b->t = t;
  b->i = i;
  b->out = out;
  memcpy(b->v, ctx->dt->tv + 4 * (size_t)t, sizeof b->v);
  memcpy(b->l, l, sizeof b->l);
  return I2M_DT_OK;
}

/* Breadth-first search of the tets whose circumballs hold p, from a seed in conflict.  Every
 * vertex met gets a local index (and, in threaded runs, is locked); the outside tets'
 * vertices on the boundary faces are cavity vertices, so they are locked too. */
static i2m_dt_status_t cavity_search(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t *tn = dt->tn, *tv = dt->tv;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    uint32_t c = ctx->cav[k];
    uint32_t cl[4];
    memcpy(cl, ctx->cavl + 4 * (size_t)k, sizeof cl);
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t n = tn[4 * c + i];
      i2m_dt_status_t st;
      if (n == I2M_DT_NONE) { /* box hull: always a boundary face */
        if ((st = boundary_push(ctx, c, i, n, cl)) != I2M_DT_OK) return st;
        continue;
      }
      uint32_t u = n >> 2, j = n & 3;
      uint32_t m = i2m_dt_meta(dt, u);
      if (m & I2M_TM_MARK) continue;
      const uint32_t *uv = tv + 4 * (size_t)u;
      int64_t lw = local_vertex(ctx, uv[j], p);
      if (lw < 0) return lw == -1 ? I2M_DT_ROLLBACK : I2M_DT_FULL;
      /* c with its vertex i replaced by u's apex is u, negatively oriented: no need to look
       * up the local indices of u's other vertices unless u joins the cavity */
      uint32_t fl[4];
      memcpy(fl, cl, sizeof fl);
      fl[i] = (uint32_t)lw;
      if (conflict(ctx, fl, -1, p, gid) > 0) {
        if (m & I2M_TM_FROZEN) return I2M_DT_FROZEN;
        if (row_is_zero(ctx, (uint32_t)lw)) return I2M_DT_DUPLICATE;
        uint32_t ul[4];
        for (uint32_t s = 0; s < 4; s++) ul[s] = s == j ? (uint32_t)lw : local_of(dt, uv[s]);
        if ((st = cavity_push(ctx, u, ul)) != I2M_DT_OK) return st;
      } else if ((st = boundary_push(ctx, c, i, n, cl)) != I2M_DT_OK) {
        return st;
      }
    }
  }
  return I2M_DT_OK;
}

/* Links face j of new tet t, whose edge opposite the new vertex has local ends (la, lb). */
static inline void link_local(i2m_dt_ctx_t *ctx, uint32_t t, uint32_t j, uint32_t la, uint32_t lb)
{
  uint32_t *e = ctx->etab2 + (la < lb ? la * ctx->lcap + lb : lb * ctx->lcap + la);
  uint32_t face = 4 * t + j;
  if (*e == I2M_DT_NONE) {
    *e = face;
  } else { /* the second visit: link both ways and leave the entry clean */
    ctx->dt->tn[face] = *e;
    ctx->dt->tn[*e] = face;
    *e = I2M_DT_NONE;
  }
}

/* The direct edge table fits cavities of up to 256 vertices; larger ones use the hash. */
#define LOCAL_TABLE_MAX 256u

static bool edge_table_ready(i2m_dt_ctx_t *ctx)
{
  if (ctx->nheld > LOCAL_TABLE_MAX) return false;
  if (ctx->nheld > ctx->lcap) {
    uint32_t cap = ctx->lcap ? ctx->lcap : 64;
    while (cap < ctx->nheld) cap *= 2;
    uint32_t *tab = NULL;
    if (i2m_malloc((size_t)cap * cap, sizeof *tab, &tab) != I2M_OK) return false;
    memset(tab, 0xFF, (size_t)cap * cap * sizeof *tab);
    i2m_free(&ctx->etab2);
    ctx->etab2 = tab;
    ctx->lcap = cap;
  }
  return true;
}

/* Replaces the cavity by the tets joining p to its boundary faces.  Cavity slots are
 * reused first; the rest of the cavity's slots go to the context's pool. */
static i2m_dt_status_t cavity_fill(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid, uint8_t kind,
                                   uint32_t *vout)
{
  i2m_dt_t *dt = ctx->dt;
  uint32_t nb = ctx->nbnd, nc = ctx->ncav;
  uint32_t extra = nb > nc ? nb - nc : 0;
  if (!ctx_ensure_slots(ctx, extra, 1)) return I2M_DT_FULL;
  if (ctx_grow_u32(&ctx->newt, &ctx->cap_new, nb) != I2M_OK) return I2M_DT_FULL;
  if (nc > nb && ctx_grow_u32(&ctx->pool, &ctx->cap_pool, ctx->npool + (nc - nb)) != I2M_OK) return I2M_DT_FULL;
  if (ctx->locking && ctx_hold_room(ctx) != I2M_OK) return I2M_DT_FULL;
  bool direct = edge_table_ready(ctx);
  if (!direct && ctx_edges_begin(ctx, 3 * nb) != I2M_OK) return I2M_DT_FULL;

  uint32_t v;
  if (ctx->locking) { /* the new vertex is ours until the caller unlocks */
    v = ctx_vertex_slot_locked(ctx, ctx->owner | (ctx->nheld << I2M_DT_OWNER_BITS));
    if (v == I2M_DT_NONE) return I2M_DT_FULL;
    ctx->rowstamp[ctx->nheld] = ctx->epoch - 1;
    ctx->held[ctx->nheld++] = v;
  } else {
    v = ctx_vertex_slot(ctx);
  }
  double *x = dt->xyzw + 4 * (size_t)v;
  x[0] = p[0];
  x[1] = p[1];
  x[2] = p[2];
  set_gid(dt, v, gid);
  dt->vkind[v] = kind;
  dt->vtet[v] = ctx->cav[0];
  uint32_t *tvs = dt->tv, *tns = dt->tn;
  ctx->nnew = 0;
  for (uint32_t k = 0; k < nb; k++) {
    const i2m_dt_bface_t *b = &ctx->bnd[k];
    uint32_t t = k < nc ? ctx->cav[k] : ctx_tet_slot(ctx);
    meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)));
    uint32_t *tv = tvs + 4 * (size_t)t;
    memcpy(tv, b->v, sizeof b->v);
    tv[b->i] = v;
    tns[4 * (size_t)t + b->i] = b->out;
    if (b->out != I2M_DT_NONE) tns[b->out] = 4 * t + b->i;
    for (uint32_t j = 0; j < 4; j++) {
      if (j == b->i) continue;
      dt->vtet[b->v[j]] = t;
      if (direct) link_local(ctx, t, j, b->l[I2M_OTHER2[b->i][j][0]], b->l[I2M_OTHER2[b->i][j][1]]);
      else ctx_edge_link(ctx, t, b->i, j);
    }
    ctx->newt[ctx->nnew++] = t;
  }
  for (uint32_t k = nb; k < nc; k++) { /* cavity slots left over: dead */
    uint32_t t = ctx->cav[k];
    meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
    ctx->pool[ctx->npool++] = t;
  }
  ctx->n_insert++;
  ctx->n_created += nb;
  ctx->n_killed += nc;
  *vout = v;
  return I2M_DT_OK;
}

i2m_dt_status_t i2m_dt_insert(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                              uint32_t seed, uint32_t seed_meta, uint32_t *vout)
{
  i2m_dt_t *dt = ctx->dt;
  I2M_CHECK_ABORT(ctx->locking || ctx->nheld == 0, "i2m_dt_insert: the previous operation's vertices are still held");
  if (++ctx->epoch == 0) { /* wrapped: every row stamp is stale */
    memset(ctx->rowstamp, 0, ctx->cap_held * sizeof *ctx->rowstamp);
    ctx->epoch = 1;
  }
  ctx->ncav = ctx->nbnd = ctx->nnew = 0;
  ctx->rmax[0] = ctx->rmax[1] = ctx->rmax[2] = 0.0;
  ctx->isp_bound = (double)INFINITY;
  const uint32_t *sv = dt->tv + 4 * (size_t)seed;
  uint32_t v4[4], l4[4];
  memcpy(v4, sv, sizeof v4); /* threaded: read before the locks, verified below */
  for (int i = 0; i < 4; i++) {
    int64_t l = local_vertex(ctx, v4[i], p);
    if (l < 0) return cavity_abandon(ctx, l == -1 ? I2M_DT_ROLLBACK : I2M_DT_FULL);
    l4[i] = (uint32_t)l;
  }
  if (ctx->locking && memcmp(v4, sv, sizeof v4) != 0) return cavity_abandon(ctx, I2M_DT_STALE);
  uint32_t m = i2m_dt_meta(dt, seed);
  if ((m & I2M_TM_DEAD) || (seed_meta != I2M_DT_NONE && m != seed_meta)) return cavity_abandon(ctx, I2M_DT_STALE);
  if (m & I2M_TM_FROZEN) return cavity_abandon(ctx, I2M_DT_FROZEN);
  for (int i = 0; i < 4; i++)
    if (row_is_zero(ctx, l4[i])) return cavity_abandon(ctx, I2M_DT_DUPLICATE);
  if (conflict(ctx, l4, 1, p, gid) <= 0) return cavity_abandon(ctx, I2M_DT_NOT_IN_CONFLICT);
  i2m_dt_status_t st = cavity_push(ctx, seed, l4);
  if (st == I2M_DT_OK) st = cavity_search(ctx, p, gid);
  if (st == I2M_DT_OK) st = cavity_fill(ctx, p, gid, kind, vout);
  if (st != I2M_DT_OK) return cavity_abandon(ctx, st);
  ctx->ncav = ctx->nbnd = 0;
  if (!ctx->locking) i2m_dt_unlock_all(ctx); /* sequential: only the local numbering to undo */
  return I2M_DT_OK;
}

static inline uint32_t rng_next(i2m_dt_ctx_t *ctx)
{
  uint64_t x = ctx->rng;
  x ^= x << 13;
  x ^= x >> 7;
  x ^= x << 17;
  ctx->rng = x;
  return (uint32_t)(x >> 32);
}

uint32_t i2m_dt_locate(i2m_dt_ctx_t *ctx, const double p[3], uint32_t start)
{
  const i2m_dt_t *dt = ctx->dt;
  uint32_t t = start, prev = I2M_DT_NONE;
  for (;;) {
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    uint32_t r = rng_next(ctx);
    uint32_t next = I2M_DT_NONE;
    for (uint32_t k = 0; k < 4; k++) {
      uint32_t i = (r + k) & 3;
      uint32_t n = dt->tn[4 * t + i];
      if (n == I2M_DT_NONE || (n >> 2) == prev) continue;
      if (tet_orient_replace(dt, v, (int)i, p) < 0) {
        next = n >> 2;
        break;
      }
    }
    ctx->n_walk_steps++;
    if (next == I2M_DT_NONE) return t;
    prev = t;
    t = next;
  }
}

i2m_dt_status_t i2m_dt_insert_walk(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                                   uint32_t start, uint32_t *vout)
{
  uint32_t t = i2m_dt_locate(ctx, p, start);
  return i2m_dt_insert(ctx, p, gid, kind, t, I2M_DT_NONE, vout);
}
