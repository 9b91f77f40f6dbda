/* Delaunay layer: creation of the virtual box, capacity, per-thread contexts, slot pools and
 * the edge table that links the new tets of a cavity. */
#include "dt_impl.h"

#include <math.h>
#include <stdlib.h>

#define GROW(n) ((n) + (n) / 2 + 64)

/* ---- capacity ---- */

static i2m_err_t grow_atomic_u32(_Atomic uint32_t **a, uint32_t old_cap, uint32_t cap, uint32_t init)
{
  I2M_CALL(i2m_realloc_large(cap, sizeof(uint32_t), a));
  for (uint32_t i = old_cap; i < cap; i++) atomic_init(&(*a)[i], init);
  return I2M_OK;
}

i2m_err_t i2m_dt_reserve(i2m_dt_t *dt, uint32_t nv, uint32_t nt)
{
  I2M_CHECK(nt <= (UINT32_MAX >> 2) - 1 && nv < UINT32_MAX - 1, I2M_ERR_MEMORY,
            "a process can hold at most 2^30 tetrahedra (asked for %u); use more MPI ranks", nt);
  if (nv > dt->cap_v) {
    I2M_CALL(i2m_realloc_large((size_t)nv * 4, sizeof(double), &dt->xyzw));
    I2M_CALL(i2m_realloc_large(nv, sizeof(uint8_t), &dt->vkind));
    memset(dt->vkind + dt->cap_v, I2M_VK_DEAD, nv - dt->cap_v); /* slots handed out in chunks */
    I2M_CALL(i2m_realloc_large(nv, sizeof(uint32_t), &dt->vtet));
    I2M_CALL(grow_atomic_u32(&dt->vlock, dt->cap_v, nv, 0));
    dt->cap_v = nv;
  }
  if (nt > dt->cap_t) {
    I2M_CALL(i2m_realloc_large((size_t)nt * 4, sizeof(uint32_t), &dt->tv));
    I2M_CALL(i2m_realloc_large((size_t)nt * 4, sizeof(uint32_t), &dt->tn));
    I2M_CALL(grow_atomic_u32(&dt->meta, dt->cap_t, nt, I2M_TM_DEAD));
    if (dt->pay_size) I2M_CALL(i2m_realloc_large(nt, dt->pay_size, &dt->tpay));
    dt->cap_t = nt;
  }
  return I2M_OK;
}

/* ---- the virtual box ---- */

/* The Delaunay tetrahedralization of the 8 (cospherical) box corners under the symbolic
 * perturbation: exactly the positive tets whose perturbed circumsphere holds no other
 * corner.  Then adjacency by face matching. */
static i2m_err_t box_triangulate(i2m_dt_t *dt)
{
  uint32_t nt = 0;
  for (uint32_t a = 0; a < 8; a++)
    for (uint32_t b = a + 1; b < 8; b++)
      for (uint32_t c = b + 1; c < 8; c++)
        for (uint32_t d = c + 1; d < 8; d++) {
          uint32_t v[4] = {a, b, c, d};
          int o = i2m_orient3d(i2m_dt_xyz(dt, a), i2m_dt_xyz(dt, b), i2m_dt_xyz(dt, c), i2m_dt_xyz(dt, d));
          if (o == 0) continue;
          if (o < 0) { v[0] = b; v[1] = a; }
          bool empty = true;
          for (uint32_t e = 0; e < 8 && empty; e++)
            if (e != a && e != b && e != c && e != d && tet_insphere(dt, v, i2m_dt_xyz(dt, e), (i2m_gidx_t)e) > 0)
              empty = false;
          if (!empty) continue;
          I2M_CHECK(nt < 6, I2M_ERR_INTERNAL, "virtual box: more than 6 Delaunay tets");
          memcpy(dt->tv + 4 * nt, v, sizeof v);
          meta_store(dt, nt, 0);
          nt++;
        }
  I2M_CHECK(nt >= 5, I2M_ERR_INTERNAL, "virtual box: only %u Delaunay tets", nt);
  for (uint32_t t = 0; t < nt; t++)
    for (int i = 0; i < 4; i++) dt->tn[4 * t + i] = I2M_DT_NONE;
  for (uint32_t t = 0; t < nt; t++)
    for (uint32_t i = 0; i < 4; i++)
      for (uint32_t u = t + 1; u < nt; u++)
        for (uint32_t j = 0; j < 4; j++) {
          int shared = 0;
          for (int x = 0; x < 4; x++)
            for (int y = 0; y < 4; y++)
              if (x != (int)i && y != (int)j && dt->tv[4 * t + x] == dt->tv[4 * u + y]) shared++;
          if (shared == 3) {
            dt->tn[4 * t + i] = 4 * u + j;
            dt->tn[4 * u + j] = 4 * t + i;
          }
        }
  atomic_store(&dt->nt_atomic, nt);
  for (uint32_t t = 0; t < nt; t++)
    for (int i = 0; i < 4; i++) dt->vtet[dt->tv[4 * t + i]] = t;
  return I2M_OK;
}

i2m_err_t i2m_dt_create(const double lo[3], const double hi[3], uint32_t nv_hint, size_t pay_size,
                        i2m_dt_t **out)
{
  i2m_dt_t *dt = NULL;
  i2m_err_t err = I2M_OK;
  *out = NULL;
  for (int a = 0; a < 3; a++)
    I2M_CHECK(isfinite(lo[a]) && isfinite(hi[a]) && lo[a] < hi[a], I2M_ERR_INTERNAL, "empty virtual box");
  I2M_CALL(i2m_calloc(1, sizeof *dt, &dt));
  dt->pay_size = pay_size;
  atomic_init(&dt->nv_atomic, 0);
  atomic_init(&dt->nt_atomic, 0);
  uint64_t nt_hint = 7 * (uint64_t)nv_hint + 64;
  if (nt_hint > (UINT32_MAX >> 2) - 1) nt_hint = (UINT32_MAX >> 2) - 1;
  I2M_CALL_GOTO(err, fail, i2m_dt_reserve(dt, nv_hint + 16, (uint32_t)nt_hint));
  for (int a = 0; a < 3; a++) {
    dt->box_lo[a] = lo[a];
    dt->box_hi[a] = hi[a];
  }
  for (uint32_t k = 0; k < 8; k++) {
    double *x = dt->xyzw + 4 * k;
    x[0] = (k & 1) ? hi[0] : lo[0];
    x[1] = (k & 2) ? hi[1] : lo[1];
    x[2] = (k & 4) ? hi[2] : lo[2];
    set_gid(dt, k, (i2m_gidx_t)k);
    dt->vkind[k] = I2M_VK_BOX;
  }
  atomic_store(&dt->nv_atomic, 8);
  I2M_CALL_GOTO(err, fail, box_triangulate(dt));
  *out = dt;
  return I2M_OK;
fail:
  i2m_dt_destroy(&dt);
  return err;
}

void i2m_dt_set_shift(i2m_dt_t *dt, const double s[3])
{
  dt->shifted = s[0] != 0.0 || s[1] != 0.0 || s[2] != 0.0;
  for (int a = 0; a < 3; a++) dt->shift[a] = dt->shifted ? s[a] : 0.0;
}

void i2m_dt_destroy(i2m_dt_t **dtp)
{
  if (!dtp || !*dtp) return;
  i2m_dt_t *dt = *dtp;
  i2m_free(&dt->xyzw);
  i2m_free(&dt->vkind);
  i2m_free(&dt->vtet);
  free((void *)dt->vlock);
  free(dt->tv);
  free(dt->tn);
  free((void *)dt->meta);
  i2m_free(&dt->tpay);
  i2m_free(&dt->free_t);
  i2m_free(&dt->free_v);
  i2m_free(dtp);
}

int64_t i2m_dt_count_tets(const i2m_dt_t *dt)
{
  int64_t n = 0;
  uint32_t nt = i2m_dt_ntets_slots(dt);
  for (uint32_t t = 0; t < nt; t++) n += i2m_dt_alive(dt, t);
  return n;
}

/* ---- contexts ---- */

i2m_err_t ctx_grow_u32(uint32_t **a, uint32_t *cap, uint32_t need)
{
  if (need <= *cap) return I2M_OK;
  uint32_t c = GROW(need);
  I2M_CALL(i2m_realloc(c, sizeof(uint32_t), a));
  *cap = c;
  return I2M_OK;
}

i2m_err_t i2m_dt_ctx_init(i2m_dt_ctx_t *ctx, i2m_dt_t *dt, uint32_t owner, bool locking)
{
  memset(ctx, 0, sizeof *ctx);
  ctx->dt = dt;
  ctx->owner = owner ? owner : 1;
  I2M_CHECK(ctx->owner <= I2M_DT_MAX_OWNERS, I2M_ERR_ARG, "at most %u threads per process", I2M_DT_MAX_OWNERS);
  ctx->locking = locking;
  I2M_CALL(ctx_edges_begin(ctx, 64));
  return I2M_OK;
}

void i2m_dt_ctx_free(i2m_dt_ctx_t *ctx)
{
  if (!ctx) return;
  i2m_free(&ctx->cav);
  i2m_free(&ctx->bnd);
  i2m_free(&ctx->newt);
  i2m_free(&ctx->held);
  i2m_free(&ctx->rows);
  i2m_free(&ctx->cavl);
  i2m_free(&ctx->etab2);
  i2m_free(&ctx->etab);
  i2m_free(&ctx->slots.pool);
  i2m_free(&ctx->slots.vpool);
  removal_free(&ctx->rm);
  journal_free(&ctx->jr);
  memset(ctx, 0, sizeof *ctx);
}

static i2m_err_t push_u32(uint32_t **a, uint32_t *n, uint32_t *cap, uint32_t x)
{
  if (*n == *cap) I2M_CALL(ctx_grow_u32(a, cap, *n + 1));
  (*a)[(*n)++] = x;
  return I2M_OK;
}

/* Appends k values (src[0..k), or first, first + 1, ... when src is NULL) to a u32 array. */
static i2m_err_t append_u32(uint32_t **a, uint32_t *n, uint32_t *cap, const uint32_t *src, uint32_t first, uint32_t k)
{
  if (k == 0) return I2M_OK;
  I2M_CALL(ctx_grow_u32(a, cap, *n + k));
  if (src) memcpy(*a + *n, src, k * sizeof **a);
  else
    for (uint32_t i = 0; i < k; i++) (*a)[*n + i] = first + i;
  *n += k;
  return I2M_OK;
}

/* A slot set's slots into the shared free lists (unused fresh slots become dead slots). */
static void slots_flush(i2m_dt_t *dt, i2m_dt_slots_t *s)
{
  if (append_u32(&dt->free_t, &dt->nfree_t, &dt->cap_free_t, s->pool, 0, s->npool) == I2M_OK) s->npool = 0;
  if (append_u32(&dt->free_v, &dt->nfree_v, &dt->cap_free_v, s->vpool, 0, s->nvpool) == I2M_OK) s->nvpool = 0;
  if (append_u32(&dt->free_t, &dt->nfree_t, &dt->cap_free_t, NULL, s->fresh_next, s->fresh_end - s->fresh_next) == I2M_OK)
    s->fresh_next = s->fresh_end = 0;
  if (append_u32(&dt->free_v, &dt->nfree_v, &dt->cap_free_v, NULL, s->vfresh_next, s->vfresh_end - s->vfresh_next) ==
      I2M_OK)
    s->vfresh_next = s->vfresh_end = 0; /* (their kind is already I2M_VK_DEAD: never used) */
}

void i2m_dt_ctx_flush(i2m_dt_ctx_t *ctx) { slots_flush(ctx->dt, &ctx->slots); }

i2m_err_t ctx_cavity_room(i2m_dt_ctx_t *ctx, uint32_t need)
{
  if (need <= ctx->cap_cav) return I2M_OK;
  uint32_t cap = GROW(need);
  I2M_CALL(i2m_realloc(cap, sizeof *ctx->cav, &ctx->cav));
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *ctx->cavl, &ctx->cavl));
  ctx->cap_cav = cap;
  return I2M_OK;
}

i2m_err_t ctx_hold_room(i2m_dt_ctx_t *ctx) { return ctx_hold_reserve(ctx, ctx->nheld + 1); }

i2m_err_t ctx_hold_reserve(i2m_dt_ctx_t *ctx, uint32_t need)
{
  if (need <= ctx->cap_held) return I2M_OK;
  I2M_CHECK(need <= (1u << (32 - I2M_DT_OWNER_BITS)), I2M_ERR_MEMORY, "a cavity with over 4 M vertices");
  uint32_t cap = GROW(need);
  I2M_CALL(i2m_realloc(cap, sizeof *ctx->held, &ctx->held));
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *ctx->rows, &ctx->rows));
  ctx->cap_held = cap;
  return I2M_OK;
}

bool i2m_dt_lock_tet(i2m_dt_ctx_t *ctx, const uint32_t v4[4])
{
  return ctx_claim_tet(ctx, v4);
}

i2m_err_t ctx_pool_push(i2m_dt_ctx_t *ctx, uint32_t t) { return push_u32(&ctx->slots.pool, &ctx->slots.npool, &ctx->slots.cap_pool, t); }
i2m_err_t ctx_vpool_push(i2m_dt_ctx_t *ctx, uint32_t v) { return push_u32(&ctx->slots.vpool, &ctx->slots.nvpool, &ctx->slots.cap_vpool, v); }

/* ---- slot allocation ---- */

#define FRESH_CHUNK 256u

/* Moves up to FRESH_CHUNK never-used tet slots into the context's fresh range (alone: exactly
 * FRESH_CHUNK, growing the arrays when needed). */
static bool take_fresh_tets(i2m_dt_ctx_t *ctx)
{
  i2m_dt_t *dt = ctx->dt;
  uint32_t cur = atomic_load_explicit(&dt->nt_atomic, memory_order_relaxed);
  if (!ctx->locking) { /* alone: always a whole chunk (slot numbers independent of the capacity) */
    if ((uint64_t)cur + FRESH_CHUNK > dt->cap_t &&
        i2m_dt_reserve(dt, dt->cap_v, (uint32_t)((uint64_t)cur + FRESH_CHUNK + dt->cap_t / 2)) != I2M_OK)
      return false;
    atomic_store_explicit(&dt->nt_atomic, cur + FRESH_CHUNK, memory_order_relaxed);
    ctx->slots.fresh_next = cur;
    ctx->slots.fresh_end = cur + FRESH_CHUNK;
    return true;
  }
  for (;;) {
    if (cur >= dt->cap_t) return false;
    uint32_t take = dt->cap_t - cur < FRESH_CHUNK ? dt->cap_t - cur : FRESH_CHUNK;
    if (atomic_compare_exchange_weak_explicit(&dt->nt_atomic, &cur, cur + take, memory_order_relaxed,
                                              memory_order_relaxed)) {
      ctx->slots.fresh_next = cur;
      ctx->slots.fresh_end = cur + take;
      return true;
    }
  }
}

/* Moves up to FRESH_CHUNK never-used vertex slots into the context's fresh range (threaded:
 * the shared high-water mark only moves by compare-and-swap within the capacity). */
static bool take_fresh_vertices(i2m_dt_ctx_t *ctx)
{
  i2m_dt_t *dt = ctx->dt;
  for (uint32_t v = ctx->slots.vfresh_next; v < ctx->slots.vfresh_end; v++)
    if (ctx_vpool_push(ctx, v) != I2M_OK) return false;
  ctx->slots.vfresh_next = ctx->slots.vfresh_end = 0;
  uint32_t cur = atomic_load_explicit(&dt->nv_atomic, memory_order_relaxed);
  for (;;) {
    if (cur >= dt->cap_v) return false;
    uint32_t take = dt->cap_v - cur < FRESH_CHUNK ? dt->cap_v - cur : FRESH_CHUNK;
    if (atomic_compare_exchange_weak_explicit(&dt->nv_atomic, &cur, cur + take, memory_order_relaxed,
                                              memory_order_relaxed)) {
      ctx->slots.vfresh_next = cur;
      ctx->slots.vfresh_end = cur + take;
      return true;
    }
  }
}

bool ctx_ensure_slots(i2m_dt_ctx_t *ctx, uint32_t ntets, uint32_t nverts)
{
  i2m_dt_t *dt = ctx->dt;
  const i2m_dt_slots_t *s = &ctx->slots;
  if (ctx->bounded) /* its own slots or nothing */
    return s->npool + (s->fresh_end - s->fresh_next) >= ntets && s->nvpool + (s->vfresh_end - s->vfresh_next) >= nverts;
  if (!ctx->locking) { /* sequential: shared lists are ours; grow when short */
    /* ctx_tet_slot takes whole fresh chunks once the pool, the fresh range and the free list
     * are used up: the capacity those chunks need is reserved here, where running out of
     * memory is I2M_DT_FULL for the caller to report, not an abort inside a cavity. */
    const uint32_t listed = s->npool + dt->nfree_t + (s->fresh_end - s->fresh_next);
    const uint64_t chunks = listed >= ntets ? 0 : (ntets - listed + FRESH_CHUNK - 1) / FRESH_CHUNK;
    const uint64_t need_t = (uint64_t)atomic_load_explicit(&dt->nt_atomic, memory_order_relaxed) + chunks * FRESH_CHUNK;
    const uint32_t have_v = s->nvpool + dt->nfree_v + (dt->cap_v - i2m_dt_nverts_slots(dt));
    if (need_t <= dt->cap_t && have_v >= nverts) return true;
    uint64_t ct = need_t <= dt->cap_t ? dt->cap_t : (uint64_t)dt->cap_t + dt->cap_t / 2 + (need_t - dt->cap_t) + 1024;
    uint64_t cv = have_v >= nverts ? dt->cap_v : (uint64_t)dt->cap_v + dt->cap_v / 2 + nverts + 1024;
    if (ct > (UINT32_MAX >> 2) - 1) ct = (UINT32_MAX >> 2) - 1;
    if (cv > UINT32_MAX - 2) cv = UINT32_MAX - 2;
    if (i2m_dt_reserve(dt, (uint32_t)cv, (uint32_t)ct) != I2M_OK) return false;
    return need_t <= dt->cap_t && s->nvpool + dt->nfree_v + (dt->cap_v - i2m_dt_nverts_slots(dt)) >= nverts;
  }
  while (s->npool + (s->fresh_end - s->fresh_next) < ntets) {
    if (ctx->slots.fresh_next < ctx->slots.fresh_end) { /* keep the remaining fresh slots in the pool */
      for (; ctx->slots.fresh_next < ctx->slots.fresh_end; ctx->slots.fresh_next++)
        if (ctx_pool_push(ctx, ctx->slots.fresh_next) != I2M_OK) return false;
    }
    if (!take_fresh_tets(ctx)) return false;
  }
  while (s->nvpool + (s->vfresh_end - s->vfresh_next) < nverts)
    if (!take_fresh_vertices(ctx)) return false;
  return true;
}

uint32_t ctx_tet_slot(i2m_dt_ctx_t *ctx)
{
  i2m_dt_t *dt = ctx->dt;
  if (ctx->slots.npool) return ctx->slots.pool[--ctx->slots.npool];
  if (ctx->slots.fresh_next < ctx->slots.fresh_end) return ctx->slots.fresh_next++;
  if (!ctx->locking && dt->nfree_t) return dt->free_t[--dt->nfree_t];
  bool ok = take_fresh_tets(ctx);
  I2M_CHECK_ABORT(ok, "tet slot requested beyond the reserved capacity");
  return ctx->slots.fresh_next++;
}

uint32_t ctx_vertex_slot(i2m_dt_ctx_t *ctx)
{
  i2m_dt_t *dt = ctx->dt;
  if (ctx->slots.nvpool) return ctx->slots.vpool[--ctx->slots.nvpool];
  if (ctx->slots.vfresh_next < ctx->slots.vfresh_end) return ctx->slots.vfresh_next++;
  if (!ctx->locking && dt->nfree_v) return dt->free_v[--dt->nfree_v];
  uint32_t v = atomic_fetch_add_explicit(&dt->nv_atomic, 1, memory_order_relaxed);
  I2M_CHECK_ABORT(v < dt->cap_v, "vertex slot requested beyond the reserved capacity");
  return v;
}

uint32_t ctx_vertex_slot_locked(i2m_dt_ctx_t *ctx, uint32_t word)
{
  i2m_dt_t *dt = ctx->dt;
  for (uint32_t tries = ctx->slots.nvpool; tries > 0; tries--) { /* recycled slots first */
    uint32_t v = ctx->slots.vpool[ctx->slots.nvpool - 1];
    uint32_t expected = 0;
    if (atomic_compare_exchange_strong_explicit(&dt->vlock[v], &expected, word, memory_order_acquire,
                                                memory_order_relaxed)) {
      ctx->slots.nvpool--;
      return v;
    }
    ctx->slots.vpool[ctx->slots.nvpool - 1] = ctx->slots.vpool[0]; /* busy: to the bottom, try the next */
    ctx->slots.vpool[0] = v;
  }
  for (;;) { /* never-used slots: nobody refers to them */
    if (ctx->slots.vfresh_next == ctx->slots.vfresh_end && !take_fresh_vertices(ctx)) return I2M_DT_NONE;
    uint32_t v = ctx->slots.vfresh_next++, expected = 0;
    if (atomic_compare_exchange_strong_explicit(&dt->vlock[v], &expected, word, memory_order_acquire,
                                                memory_order_relaxed))
      return v;
  }
}

/* ---- edge table ---- */

i2m_err_t ctx_edges_begin(i2m_dt_ctx_t *ctx, uint32_t nfaces)
{
  if (4 * nfaces > ctx->ecap) {
    uint32_t cap = ctx->ecap ? ctx->ecap : 256;
    while (4 * nfaces > cap) cap *= 2;
    i2m_free(&ctx->etab);
    I2M_CALL(i2m_calloc(cap, sizeof *ctx->etab, &ctx->etab));
    ctx->ecap = cap;
    ctx->stamp = 0;
  }
  if (++ctx->stamp == 0) { /* wrapped: clear */
    memset(ctx->etab, 0, ctx->ecap * sizeof *ctx->etab);
    ctx->stamp = 1;
  }
  return I2M_OK;
}

/* ---- slot sets granted to tiles (deterministic mode) ---- */

i2m_err_t i2m_dt_slots_grant(i2m_dt_t *dt, i2m_dt_slots_t *s, uint32_t ntets, uint32_t nverts)
{
  /* what is left of the fresh ranges joins the pools: a new range must be contiguous */
  I2M_CALL(append_u32(&s->pool, &s->npool, &s->cap_pool, NULL, s->fresh_next, s->fresh_end - s->fresh_next));
  I2M_CALL(append_u32(&s->vpool, &s->nvpool, &s->cap_vpool, NULL, s->vfresh_next, s->vfresh_end - s->vfresh_next));
  s->fresh_next = s->fresh_end = s->vfresh_next = s->vfresh_end = 0;
  /* dead slots from the top of the shared lists */
  uint32_t kt = s->npool < ntets ? ntets - s->npool : 0, kv = s->nvpool < nverts ? nverts - s->nvpool : 0;
  kt = kt < dt->nfree_t ? kt : dt->nfree_t;
  kv = kv < dt->nfree_v ? kv : dt->nfree_v;
  I2M_CALL(append_u32(&s->pool, &s->npool, &s->cap_pool, dt->free_t + dt->nfree_t - kt, 0, kt));
  I2M_CALL(append_u32(&s->vpool, &s->nvpool, &s->cap_vpool, dt->free_v + dt->nfree_v - kv, 0, kv));
  dt->nfree_t -= kt;
  dt->nfree_v -= kv;
  uint32_t nt = s->npool < ntets ? ntets - s->npool : 0, nv = s->nvpool < nverts ? nverts - s->nvpool : 0;
  uint32_t t0 = i2m_dt_ntets_slots(dt), v0 = i2m_dt_nverts_slots(dt);
  if ((uint64_t)t0 + nt > dt->cap_t || (uint64_t)v0 + nv > dt->cap_v) {
    uint64_t ct = (uint64_t)t0 + nt > dt->cap_t ? (uint64_t)t0 + nt + dt->cap_t / 2 : dt->cap_t;
    uint64_t cv = (uint64_t)v0 + nv > dt->cap_v ? (uint64_t)v0 + nv + dt->cap_v / 2 : dt->cap_v;
    I2M_CHECK(ct <= (UINT32_MAX >> 2) - 1 && cv <= UINT32_MAX - 2, I2M_ERR_MEMORY,
              "a process can hold at most 2^30 tetrahedra; use more MPI ranks");
    I2M_CALL(i2m_dt_reserve(dt, (uint32_t)cv, (uint32_t)ct));
  }
  s->fresh_next = t0;
  s->fresh_end = t0 + nt;
  s->vfresh_next = v0;
  s->vfresh_end = v0 + nv;
  atomic_store_explicit(&dt->nt_atomic, t0 + nt, memory_order_relaxed);
  atomic_store_explicit(&dt->nv_atomic, v0 + nv, memory_order_relaxed);
  return I2M_OK;
}

void i2m_dt_slots_return(i2m_dt_t *dt, i2m_dt_slots_t *s) { slots_flush(dt, s); }

/* ---- single slots, for the dist layer's submeshes (all contexts idle) ---- */

i2m_err_t i2m_dt_take_tet(i2m_dt_t *dt, uint32_t *t)
{
  if (dt->nfree_t) {
    *t = dt->free_t[--dt->nfree_t];
  } else {
    const uint32_t n = i2m_dt_ntets_slots(dt);
    if (n >= dt->cap_t) I2M_CALL(i2m_dt_reserve(dt, dt->cap_v, (uint32_t)((uint64_t)dt->cap_t + dt->cap_t / 2 + 1024 > (UINT32_MAX >> 2) - 1 ? (UINT32_MAX >> 2) - 1 : (uint64_t)dt->cap_t + dt->cap_t / 2 + 1024)));
    I2M_CHECK(n < dt->cap_t, I2M_ERR_MEMORY, "a process can hold at most 2^30 tetrahedra; use more MPI ranks");
    atomic_store_explicit(&dt->nt_atomic, n + 1, memory_order_relaxed);
    *t = n;
  }
  meta_store(dt, *t, meta_reborn(i2m_dt_meta(dt, *t)));
  return I2M_OK;
}

i2m_err_t i2m_dt_take_vertex(i2m_dt_t *dt, uint32_t *v)
{
  if (dt->nfree_v) {
    *v = dt->free_v[--dt->nfree_v];
    return I2M_OK;
  }
  const uint32_t n = i2m_dt_nverts_slots(dt);
  if (n >= dt->cap_v) {
    const uint64_t cap = (uint64_t)dt->cap_v + dt->cap_v / 2 + 1024;
    I2M_CHECK(cap < UINT32_MAX - 2, I2M_ERR_MEMORY, "too many vertices for one process; use more MPI ranks");
    I2M_CALL(i2m_dt_reserve(dt, (uint32_t)cap, dt->cap_t));
  }
  atomic_store_explicit(&dt->nv_atomic, n + 1, memory_order_relaxed);
  *v = n;
  return I2M_OK;
}

i2m_err_t i2m_dt_give_tet(i2m_dt_t *dt, uint32_t t)
{
  meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
  return push_u32(&dt->free_t, &dt->nfree_t, &dt->cap_free_t, t);
}

i2m_err_t i2m_dt_give_vertex(i2m_dt_t *dt, uint32_t v)
{
  dt->vkind[v] = I2M_VK_DEAD;
  return push_u32(&dt->free_v, &dt->nfree_v, &dt->cap_free_v, v);
}

void i2m_dt_slots_release(i2m_dt_t *dt, i2m_dt_slots_t *s)
{
  i2m_dt_slots_return(dt, s);
  i2m_free(&s->pool);
  i2m_free(&s->vpool);
  memset(s, 0, sizeof *s);
}
