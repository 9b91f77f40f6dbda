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

/* Clears the marks of the cavity found so far and releases the locks: nothing changed. */
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

static bool same_point(const double *a, const double *b) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

static i2m_dt_status_t cavity_push(i2m_dt_ctx_t *ctx, uint32_t t)
{
  if (ctx->ncav == ctx->cap_cav && ctx_grow_u32(&ctx->cav, &ctx->cap_cav, ctx->ncav + 1) != I2M_OK)
    return I2M_DT_FULL;
  ctx->cav[ctx->ncav++] = t;
  meta_store(ctx->dt, t, i2m_dt_meta(ctx->dt, t) | I2M_TM_MARK);
  return I2M_DT_OK;
}

static i2m_dt_status_t boundary_push(i2m_dt_ctx_t *ctx, uint32_t t, uint32_t i, uint32_t out)
{
  if (ctx->nbnd == ctx->cap_bnd) {
    uint32_t cap = ctx->cap_bnd + ctx->cap_bnd / 2 + 64;
    if (i2m_realloc(cap, sizeof(i2m_dt_bface_t), &ctx->bnd) != I2M_OK) return I2M_DT_FULL;
    ctx->cap_bnd = cap;
  }
  i2m_dt_bface_t *b = &ctx->bnd[ctx->nbnd++];
  b->t = t;
  b->i = i;
  b->out = out;
  memcpy(b->v, ctx->dt->tv + 4 * (size_t)t, sizeof b->v);
  return I2M_DT_OK;
}

/* Breadth-first search of the tets whose circumball holds p, from a seed in conflict.
 * Locks every vertex of every cavity tet (the outside tets' vertices on the boundary faces
 * are cavity vertices, so they are locked too). */
static i2m_dt_status_t cavity_search(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  i2m_dt_t *dt = ctx->dt;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    uint32_t c = ctx->cav[k];
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t n = dt->tn[4 * c + i];
      if (n == I2M_DT_NONE) { /* box hull: always a boundary face */
        if (boundary_push(ctx, c, i, n) != I2M_DT_OK) return I2M_DT_FULL;
        continue;
      }
      uint32_t u = n >> 2;
      uint32_t m = i2m_dt_meta(dt, u);
      if (m & I2M_TM_MARK) continue;
      const uint32_t *uv = dt->tv + 4 * (size_t)u;
      if (tet_insphere(dt, uv, p, gid) > 0) {
        if (m & I2M_TM_FROZEN) return I2M_DT_FROZEN;
        if (ctx->locking && !vlock_take(ctx, uv[n & 3])) return I2M_DT_ROLLBACK;
        if (same_point(i2m_dt_xyz(dt, uv[n & 3]), p)) return I2M_DT_DUPLICATE;
        if (cavity_push(ctx, u) != I2M_DT_OK) return I2M_DT_FULL;
      } else if (boundary_push(ctx, c, i, n) != I2M_DT_OK) {
        return I2M_DT_FULL;
      }
    }
  }
  return I2M_DT_OK;
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
  if (ctx_edges_begin(ctx, 3 * nb) != I2M_OK) return I2M_DT_FULL;
  if (nc > nb && ctx->npool + (nc - nb) > ctx->cap_pool &&
      ctx_grow_u32(&ctx->pool, &ctx->cap_pool, ctx->npool + (nc - nb)) != I2M_OK)
    return I2M_DT_FULL;

  uint32_t v = ctx_vertex_slot(ctx);
  double *x = dt->xyzw + 4 * (size_t)v;
  x[0] = p[0];
  x[1] = p[1];
  x[2] = p[2];
  set_gid(dt, v, gid);
  dt->vkind[v] = kind;
  if (ctx->locking) {
    if (ctx_grow_u32(&ctx->held, &ctx->cap_held, ctx->nheld + 1) != I2M_OK) I2M_CHECK_ABORT(0, "out of memory");
    atomic_store_explicit(&dt->vlock[v], ctx->owner, memory_order_relaxed);
    ctx->held[ctx->nheld++] = v;
  }

  ctx->nnew = 0;
  for (uint32_t k = 0; k < nb; k++) {
    const i2m_dt_bface_t *b = &ctx->bnd[k];
    uint32_t t;
    if (k < nc) {
      t = ctx->cav[k];
      meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)));
    } else {
      t = ctx_tet_slot(ctx);
      meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)) & ~I2M_TM_DEAD);
    }
    uint32_t *tv = dt->tv + 4 * (size_t)t;
    memcpy(tv, b->v, sizeof b->v);
    tv[b->i] = v;
    dt->tn[4 * t + b->i] = b->out;
    if (b->out != I2M_DT_NONE) dt->tn[b->out] = 4 * t + b->i;
    for (uint32_t j = 0; j < 4; j++) {
      dt->vtet[tv[j]] = t;
      if (j != b->i) ctx_edge_link(ctx, t, b->i, j);
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
  ctx->ncav = ctx->nbnd = ctx->nnew = 0;
  const uint32_t *sv = dt->tv + 4 * (size_t)seed;
  if (ctx->locking) {
    uint32_t v4[4];
    memcpy(v4, sv, sizeof v4); /* read before the locks: verified below */
    if (!vlock_take_tet(ctx, v4)) return cavity_abandon(ctx, I2M_DT_ROLLBACK);
    if (memcmp(v4, sv, sizeof v4) != 0) return cavity_abandon(ctx, I2M_DT_STALE);
  }
  uint32_t m = i2m_dt_meta(dt, seed);
  if ((m & I2M_TM_DEAD) || (seed_meta != I2M_DT_NONE && m != seed_meta)) return cavity_abandon(ctx, I2M_DT_STALE);
  if (m & I2M_TM_FROZEN) return cavity_abandon(ctx, I2M_DT_FROZEN);
  for (int i = 0; i < 4; i++)
    if (same_point(i2m_dt_xyz(dt, sv[i]), p)) return cavity_abandon(ctx, I2M_DT_DUPLICATE);
  if (tet_insphere(dt, sv, p, gid) <= 0) return cavity_abandon(ctx, I2M_DT_NOT_IN_CONFLICT);
  i2m_dt_status_t st = cavity_push(ctx, seed);
  if (st == I2M_DT_OK) st = cavity_search(ctx, p, gid);
  if (st == I2M_DT_OK) st = cavity_fill(ctx, p, gid, kind, vout);
  if (st != I2M_DT_OK) return cavity_abandon(ctx, st);
  ctx->ncav = ctx->nbnd = 0;
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
