/* Delaunay layer internals shared by dt*.c: vertex locks, slot allocation, conflict tests. */
#ifndef I2M_DT_IMPL_H
#define I2M_DT_IMPL_H

#include <string.h>

#include "i2m/dt.h"
#include "i2m/geometry.h"
#include "i2m/predicates.h"

/* meta helpers */
static inline uint32_t meta_gen(uint32_t m) { return m >> I2M_TM_GEN_SHIFT; }
static inline void meta_store(i2m_dt_t *dt, uint32_t t, uint32_t m)
{
  atomic_store_explicit(&dt->meta[t], m, memory_order_relaxed);
}
/* Meta of a slot that was killed and is reused now (generation + 1, alive, no mark). */
static inline uint32_t meta_reborn(uint32_t m) { return (meta_gen(m) + 1) << I2M_TM_GEN_SHIFT; }
static inline uint32_t meta_killed(uint32_t m) { return ((meta_gen(m) + 1) << I2M_TM_GEN_SHIFT) | I2M_TM_DEAD; }

static inline void set_gid(i2m_dt_t *dt, uint32_t v, i2m_gidx_t g)
{
  union { double d; int64_t i; } u;
  u.i = g;
  dt->xyzw[4 * (size_t)v + 3] = u.d;
}

/* ---- vertex locks ---- */
i2m_err_t ctx_grow_u32(uint32_t **a, uint32_t *cap, uint32_t need);

/* Room for need cavity (or star) tets: cav[] and cavl[] grow together. */
i2m_err_t ctx_cavity_room(i2m_dt_ctx_t *ctx, uint32_t need);

/* Room for one more held vertex, or for need held vertices (held[] and rows[] grow together). */
i2m_err_t ctx_hold_room(i2m_dt_ctx_t *ctx);
i2m_err_t ctx_hold_reserve(i2m_dt_ctx_t *ctx, uint32_t need);

/* Takes the lock of vertex v for the context (re-entrant), numbering it locally (an insertion
 * makes the rows of the vertices held when it starts).  False: held by another, or out of
 * memory. */
static inline bool vlock_take(i2m_dt_ctx_t *ctx, uint32_t v)
{
  _Atomic uint32_t *L = &ctx->dt->vlock[v];
  uint32_t cur = atomic_load_explicit(L, memory_order_relaxed);
  if ((cur & I2M_DT_OWNER_MASK) == ctx->owner) return true;
  if (ctx->nheld == ctx->cap_held && ctx_hold_room(ctx) != I2M_OK) {
    ctx->conflict_owner = 0;
    return false;
  }
  uint32_t expected = 0, word = ctx->owner | (ctx->nheld << I2M_DT_OWNER_BITS);
  if (cur == 0 && atomic_compare_exchange_strong_explicit(L, &expected, word, memory_order_acquire,
                                                          memory_order_relaxed)) {
    ctx->held[ctx->nheld++] = v;
    return true;
  }
  ctx->conflict_owner = (cur ? cur : expected) & I2M_DT_OWNER_MASK;
  return false;
}

static inline bool vlock_take_tet(i2m_dt_ctx_t *ctx, const uint32_t *v4)
{
  return vlock_take(ctx, v4[0]) && vlock_take(ctx, v4[1]) && vlock_take(ctx, v4[2]) && vlock_take(ctx, v4[3]);
}

/* Zone mode: does vertex v lie in the context's zone? */
static inline bool zone_holds(const i2m_dt_ctx_t *ctx, uint32_t v) { return i2m_box_holds(ctx->zone, i2m_dt_xyz(ctx->dt, v)); }

/* May the operation touch vertex v: its lock (threaded runs), or its place in the zone
 * (deterministic mode)?  False means roll back; ctx->conflict_owner says who holds it. */
static inline bool ctx_claim(i2m_dt_ctx_t *ctx, uint32_t v)
{
  if (ctx->locking) return vlock_take(ctx, v);
  if (ctx->zone && !zone_holds(ctx, v)) {
    ctx->conflict_owner = 0;
    return false;
  }
  return true;
}

static inline bool ctx_claim_tet(i2m_dt_ctx_t *ctx, const uint32_t *v4)
{
  return ctx_claim(ctx, v4[0]) && ctx_claim(ctx, v4[1]) && ctx_claim(ctx, v4[2]) && ctx_claim(ctx, v4[3]);
}

/* ---- conflict test and orientation: the inline filter first; global ids are only loaded
 * when the exact evaluation and the symbolic perturbation have to decide ---- */
static inline int tet_insphere(const i2m_dt_t *dt, const uint32_t *v, const double *p, i2m_gidx_t gid)
{
  const double *a = i2m_dt_xyz(dt, v[0]), *b = i2m_dt_xyz(dt, v[1]);
  const double *c = i2m_dt_xyz(dt, v[2]), *d = i2m_dt_xyz(dt, v[3]);
  int s = i2m_insphere_filter(a, b, c, d, p);
  if (I2M_LIKELY(s != 0)) return s;
  return i2m_insphere_sos_exact(a, b, c, d, p, i2m_dt_gid(dt, v[0]), i2m_dt_gid(dt, v[1]), i2m_dt_gid(dt, v[2]),
                                i2m_dt_gid(dt, v[3]), gid);
}

/* orient3d of tet t with its vertex i replaced by p: < 0 means p is beyond face i. */
static inline int tet_orient_replace(const i2m_dt_t *dt, const uint32_t *v, int i, const double *p)
{
  const double *q[4] = {i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3])};
  q[i] = p;
  int s = i2m_orient3d_filter(q[0], q[1], q[2], q[3]);
  return I2M_LIKELY(s != 0) ? s : i2m_orient3d(q[0], q[1], q[2], q[3]);
}

/* ---- slot allocation (dt.c) ---- */
/* Makes sure the context can hand out ntets more tet slots and nverts vertex slots without
 * touching shared capacity beyond what is reserved.  Sequential contexts grow the arrays;
 * locking contexts return false when the reserve is exhausted. */
bool ctx_ensure_slots(i2m_dt_ctx_t *ctx, uint32_t ntets, uint32_t nverts);
/* Hands out one tet / vertex slot (after ctx_ensure_slots succeeded). */
uint32_t ctx_tet_slot(i2m_dt_ctx_t *ctx);
uint32_t ctx_vertex_slot(i2m_dt_ctx_t *ctx);
/* Threaded runs: a vertex slot whose lock word the context could take by compare-and-swap
 * (a recycled slot may still be locked by a thread holding a stale reference to it), or
 * I2M_DT_NONE when the reserve is exhausted.  The lock is the context's, not yet in held[]. */
uint32_t ctx_vertex_slot_locked(i2m_dt_ctx_t *ctx, uint32_t word);
/* Puts a killed tet slot into the context's pool. */
i2m_err_t ctx_pool_push(i2m_dt_ctx_t *ctx, uint32_t t);
i2m_err_t ctx_vpool_push(i2m_dt_ctx_t *ctx, uint32_t v);

/* ---- adjacency of new tets: the faces containing the new vertex p are matched by their
 * edge opposite p.  Each such edge is seen exactly twice. ---- */
struct i2m_dt_edge {
  uint64_t key;   /* (a << 32) | b with a < b, or EDGE_USED once matched */
  uint32_t face;  /* 4t+j of the first face seen */
  uint32_t stamp; /* entry valid when == ctx->stamp */
};
#define EDGE_USED UINT64_MAX

/* Other two slots of a tet given two distinct slots i, j. */
static const uint8_t I2M_OTHER2[4][4][2] = {
    {{0, 0}, {2, 3}, {1, 3}, {1, 2}}, {{2, 3}, {0, 0}, {0, 3}, {0, 2}},
    {{1, 3}, {0, 3}, {0, 0}, {0, 1}}, {{1, 2}, {0, 2}, {0, 1}, {0, 0}}};

/* Prepares the edge table for @p nfaces half-faces (new stamp, big enough). */
i2m_err_t ctx_edges_begin(i2m_dt_ctx_t *ctx, uint32_t nfaces);

/* Links face j of new tet t (whose vertex ip is the new point) with its partner. */
static inline void ctx_edge_link(i2m_dt_ctx_t *ctx, uint32_t t, uint32_t ip, uint32_t j)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  uint32_t a = v[I2M_OTHER2[ip][j][0]], b = v[I2M_OTHER2[ip][j][1]];
  if (a > b) { uint32_t x = a; a = b; b = x; }
  uint64_t key = (uint64_t)a << 32 | b;
  uint32_t mask = ctx->ecap - 1, stamp = ctx->stamp;
  uint32_t s = (uint32_t)((key * 0x9E3779B97F4A7C15ull) >> 40) & mask; /* high bits mix best */
  struct i2m_dt_edge *e = ctx->etab;
  while (e[s].stamp == stamp && e[s].key != key) s = (s + 1) & mask;
  if (e[s].stamp == stamp) {
    uint32_t other = e[s].face;
    dt->tn[4 * (size_t)t + j] = other;
    dt->tn[other] = 4 * t + j;
    e[s].key = EDGE_USED;
  } else {
    e[s].stamp = stamp;
    e[s].key = key;
    e[s].face = 4 * t + j;
  }
}

/* Vertex removal scratch (dt_remove.c). */
void removal_free(struct i2m_dt_removal **rm);
/* The record of a journaled insertion (i2m_dt_undo_insert). */
struct i2m_dt_journal {
  bool valid;                   /* an insertion to undo */
  uint32_t nc, nb, v;           /* its cavity's tets, its new tets, its vertex */
  uint32_t *slot, cap_c;        /* [nc] the cavity's slots, in the order of ctx->cav */
  uint32_t *tv, *tn, *meta;     /* [nc][4], [nc][4], [nc] their records */
  unsigned char *pay;           /* [nc][pay_size] */
  i2m_dt_bface_t *bnd;          /* [nb] the boundary faces */
  uint32_t *newt, cap_b;        /* [nb] the new tets */
  uint32_t npool, fresh_next, nvpool, vfresh_next; /* the context's slots before */
};

void journal_free(struct i2m_dt_journal **jp);
/* Any operation but a journaled insertion leaves nothing to undo. */
static inline void journal_forget(i2m_dt_ctx_t *ctx)
{
  if (ctx->jr) ctx->jr->valid = false;
}

#endif
