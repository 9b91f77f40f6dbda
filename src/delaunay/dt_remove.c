/* Delaunay layer: vertex removal (REFERENCE §1.6).  The star of v is replaced by the tets of
 * the Delaunay tetrahedralization of v's link vertices (plus the same 8 box corners) that lie
 * on v's side of the link.  The local triangulation uses the vertices' own global ids for
 * the symbolic perturbation, so it is unique and agrees with the main mesh: every link face
 * appears in it, and the result is exactly the Delaunay tetrahedralization without v. */
#include "dt_impl.h"

#include <stdlib.h>

typedef struct {
  uint32_t key[3];  /* sorted local vertex ids of a link face */
  uint32_t out;     /* outside neighbour (4u+j in the main mesh) or I2M_DT_NONE */
  uint32_t used;    /* stamp */
} link_face_t;

struct i2m_dt_removal {
  i2m_dt_t *loc;          /* owned: scratch triangulation over the same virtual box */
  i2m_dt_ctx_t lctx;      /* owned: its context */
  uint32_t nbox_tets;     /* tets of the empty box */
  uint32_t box_tv[24], box_tn[24];
  uint32_t *lmap;         /* [local vertex] -> main vertex */
  uint32_t cap_lmap;
  uint32_t *vmark_v;      /* main vertices seen (small open hash: main id -> local id) */
  uint32_t *vmark_l, *vmark_s, vcap, vstamp;
  link_face_t *lf;        /* link-face hash */
  uint32_t lfcap, lfstamp;
  uint32_t *fill;         /* local tets on v's side */
  uint32_t nfill, cap_fill;
  uint32_t *slot;         /* [local tet] -> main slot (I2M_DT_NONE if not in the fill) */
  uint32_t cap_slot;
  uint32_t *link;         /* the link vertices, in the order of their global ids */
  uint32_t nlink, cap_link;
};

void removal_free(struct i2m_dt_removal **rmp)
{
  if (!rmp || !*rmp) return;
  struct i2m_dt_removal *rm = *rmp;
  i2m_dt_ctx_free(&rm->lctx);
  i2m_dt_destroy(&rm->loc);
  i2m_free(&rm->lmap);
  i2m_free(&rm->vmark_v);
  i2m_free(&rm->vmark_l);
  i2m_free(&rm->vmark_s);
  i2m_free(&rm->lf);
  i2m_free(&rm->fill);
  i2m_free(&rm->slot);
  i2m_free(&rm->link);
  i2m_free(rmp);
}

static i2m_err_t removal_create(const i2m_dt_t *dt, struct i2m_dt_removal **out)
{
  struct i2m_dt_removal *rm = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *rm, &rm));
  i2m_err_t err = i2m_dt_create(dt->box_lo, dt->box_hi, 64, 0, &rm->loc);
  if (err == I2M_OK) err = i2m_dt_ctx_init(&rm->lctx, rm->loc, 1, false);
  if (err != I2M_OK) {
    removal_free(&rm);
    return err;
  }
  rm->nbox_tets = i2m_dt_ntets_slots(rm->loc);
  memcpy(rm->box_tv, rm->loc->tv, 4 * rm->nbox_tets * sizeof(uint32_t));
  memcpy(rm->box_tn, rm->loc->tn, 4 * rm->nbox_tets * sizeof(uint32_t));
  *out = rm;
  return I2M_OK;
}

/* Back to the empty box: 8 corners and their tets. */
static void local_reset(struct i2m_dt_removal *rm)
{
  i2m_dt_t *loc = rm->loc;
  memcpy(loc->tv, rm->box_tv, 4 * rm->nbox_tets * sizeof(uint32_t));
  memcpy(loc->tn, rm->box_tn, 4 * rm->nbox_tets * sizeof(uint32_t));
  for (uint32_t t = 0; t < rm->nbox_tets; t++) {
    meta_store(loc, t, 0);
    for (int i = 0; i < 4; i++) loc->vtet[loc->tv[4 * t + i]] = t;
  }
  /* every slot handed out since (used or still in the context's fresh range) is dead again */
  for (uint32_t t = rm->nbox_tets; t < i2m_dt_ntets_slots(loc); t++) meta_store(loc, t, I2M_TM_DEAD);
  atomic_store_explicit(&loc->nt_atomic, rm->nbox_tets, memory_order_relaxed);
  atomic_store_explicit(&loc->nv_atomic, 8, memory_order_relaxed);
  loc->nfree_t = loc->nfree_v = 0;
  rm->lctx.slots.npool = rm->lctx.slots.nvpool = 0;
  rm->lctx.slots.fresh_next = rm->lctx.slots.fresh_end = 0;
}

/* ---- main vertex -> local vertex (open addressing with stamps) ---- */
static i2m_err_t vmap_prepare(struct i2m_dt_removal *rm, uint32_t n)
{
  if (4 * n > rm->vcap) {
    uint32_t cap = 256;
    while (cap < 4 * n) cap *= 2;
    i2m_free(&rm->vmark_v);
    i2m_free(&rm->vmark_l);
    i2m_free(&rm->vmark_s);
    rm->vcap = cap;
    rm->vstamp = 0;
    I2M_CALL(i2m_malloc(cap, sizeof(uint32_t), &rm->vmark_v));
    I2M_CALL(i2m_malloc(cap, sizeof(uint32_t), &rm->vmark_l));
    I2M_CALL(i2m_calloc(cap, sizeof(uint32_t), &rm->vmark_s));
  }
  if (++rm->vstamp == 0) {
    memset(rm->vmark_s, 0, rm->vcap * sizeof(uint32_t));
    rm->vstamp = 1;
  }
  return I2M_OK;
}

/* Slot of main vertex v in the map (found, or the empty slot where it belongs). */
static uint32_t vmap_slot(const struct i2m_dt_removal *rm, uint32_t v)
{
  uint32_t s = (v * 2654435761u) & (rm->vcap - 1);
  while (rm->vmark_s[s] == rm->vstamp && rm->vmark_v[s] != v) s = (s + 1) & (rm->vcap - 1);
  return s;
}

/* ---- link faces ---- */
static void sort3(uint32_t k[3])
{
  uint32_t t;
  if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
  if (k[1] > k[2]) { t = k[1]; k[1] = k[2]; k[2] = t; }
  if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
}

static uint32_t lf_slot(const struct i2m_dt_removal *rm, const uint32_t k[3])
{
  uint64_t h = ((uint64_t)k[0] * 0x9E3779B97F4A7C15ull) ^ ((uint64_t)k[1] * 0xC2B2AE3D27D4EB4Full) ^
               ((uint64_t)k[2] * 0x165667B19E3779F9ull);
  uint32_t s = (uint32_t)(h >> 32) & (rm->lfcap - 1);
  while (rm->lf[s].used == rm->lfstamp && memcmp(rm->lf[s].key, k, sizeof rm->lf[s].key) != 0)
    s = (s + 1) & (rm->lfcap - 1);
  return s;
}

static i2m_err_t lf_prepare(struct i2m_dt_removal *rm, uint32_t n)
{
  if (4 * n > rm->lfcap) {
    uint32_t cap = 256;
    while (cap < 4 * n) cap *= 2;
    i2m_free(&rm->lf);
    rm->lfcap = cap;
    rm->lfstamp = 0;
    I2M_CALL(i2m_calloc(cap, sizeof(link_face_t), &rm->lf));
  }
  if (++rm->lfstamp == 0) {
    for (uint32_t s = 0; s < rm->lfcap; s++) rm->lf[s].used = 0;
    rm->lfstamp = 1;
  }
  return I2M_OK;
}

/* ---- step 1: the star of v, locked and marked.  A tet is marked only by a thread that holds
 * at least one of its faces (the first one: all four vertices), so that two threads can
 * never mark the same tet, and one's rollback never clears the other's mark. ---- */
static i2m_dt_status_t star_collect(i2m_dt_ctx_t *ctx, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  ctx->ncav = 0;
  if (!ctx_claim(ctx, v)) return I2M_DT_ROLLBACK;
  uint32_t t0 = dt->vtet[v]; /* stable: it contains v, which we hold */
  if (!ctx_claim_tet(ctx, dt->tv + 4 * (size_t)t0)) return I2M_DT_ROLLBACK;
  if (ctx_cavity_room(ctx, 1) != I2M_OK) return I2M_DT_FULL;
  ctx->cav[ctx->ncav++] = t0;
  meta_store(dt, t0, i2m_dt_meta(dt, t0) | I2M_TM_MARK);
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    uint32_t t = ctx->cav[k];
    const uint32_t *tv = dt->tv + 4 * (size_t)t;
    if (!ctx_claim_tet(ctx, tv)) return I2M_DT_ROLLBACK;
    if (i2m_dt_meta(dt, t) & I2M_TM_FROZEN) return I2M_DT_FROZEN;
    for (uint32_t i = 0; i < 4; i++) {
      const uint32_t n = dt->tn[4 * t + i];
      if (n == I2M_DT_REMOTE) return I2M_DT_FROZEN; /* (another rank's side cannot be seen) */
      if (tv[i] == v) { /* the face opposite v is a link face: the tet across it is rewritten */
        if (ctx->block && n != I2M_DT_NONE && !i2m_dt_block_holds(dt, ctx->block, n >> 2)) return I2M_DT_FROZEN;
        continue;
      }
      uint32_t u = n >> 2;
      if (i2m_dt_meta(dt, u) & I2M_TM_MARK) continue;
      if (ctx_cavity_room(ctx, ctx->ncav + 1) != I2M_OK) return I2M_DT_FULL;
      ctx->cav[ctx->ncav++] = u;
      meta_store(dt, u, i2m_dt_meta(dt, u) | I2M_TM_MARK);
    }
  }
  return I2M_DT_OK;
}

/* ---- step 2: local Delaunay tetrahedralization of the link vertices ---- */
static i2m_dt_status_t local_triangulate(i2m_dt_ctx_t *ctx, struct i2m_dt_removal *rm, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  local_reset(rm);
  if (vmap_prepare(rm, 4 * ctx->ncav + 8) != I2M_OK) return I2M_DT_FULL;
  if (ctx_grow_u32(&rm->lmap, &rm->cap_lmap, 4 * ctx->ncav + 8) != I2M_OK) return I2M_DT_FULL;
  for (uint32_t b = 0; b < 8; b++) { /* box corners: same ids locally and in the main mesh */
    uint32_t s = vmap_slot(rm, b);
    rm->vmark_s[s] = rm->vstamp;
    rm->vmark_v[s] = b;
    rm->vmark_l[s] = b;
    rm->lmap[b] = b;
  }
  /* the link vertices, inserted in the order of their global ids: the new tets (their vertex
   * order, their order) are then a function of the star, not of the tet the search began
   * with, which differs between ranks that hold the same star */
  rm->nlink = 0;
  if (ctx_grow_u32(&rm->link, &rm->cap_link, 4 * ctx->ncav) != I2M_OK) return I2M_DT_FULL;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t *tv = dt->tv + 4 * (size_t)ctx->cav[k];
    for (int i = 0; i < 4; i++) {
      uint32_t w = tv[i];
      if (w == v) continue;
      uint32_t s = vmap_slot(rm, w);
      if (rm->vmark_s[s] == rm->vstamp) continue;
      rm->vmark_s[s] = rm->vstamp;
      rm->vmark_v[s] = w;
      rm->link[rm->nlink++] = w;
    }
  }
  for (uint32_t a = 1; a < rm->nlink; a++) /* (a few dozen: insertion sort) */
    for (uint32_t b = a; b > 0 && i2m_dt_gid(dt, rm->link[b]) < i2m_dt_gid(dt, rm->link[b - 1]); b--) {
      const uint32_t x = rm->link[b];
      rm->link[b] = rm->link[b - 1];
      rm->link[b - 1] = x;
    }
  uint32_t hint = 0;
  for (uint32_t k = 0; k < rm->nlink; k++) {
    const uint32_t w = rm->link[k];
    uint32_t lw = I2M_DT_NONE;
    i2m_dt_status_t st = i2m_dt_insert_walk(&rm->lctx, i2m_dt_xyz(dt, w), i2m_dt_gid(dt, w), I2M_VK_FREE, hint, &lw);
    if (st != I2M_DT_OK) return st == I2M_DT_FULL ? I2M_DT_FULL : I2M_DT_FAILED;
    hint = rm->lctx.newt[0];
    rm->vmark_l[vmap_slot(rm, w)] = lw;
    rm->lmap[lw] = w;
  }
  return I2M_DT_OK;
}

static uint32_t local_id(const struct i2m_dt_removal *rm, uint32_t w) { return rm->vmark_l[vmap_slot(rm, w)]; }

/* ---- step 3: the local tets on v's side of each link face, and everything reachable from
 * them without crossing the link ---- */
static i2m_dt_status_t fill_select(i2m_dt_ctx_t *ctx, struct i2m_dt_removal *rm, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt, *loc = rm->loc;
  uint32_t nlt = i2m_dt_ntets_slots(loc);
  if (lf_prepare(rm, ctx->ncav) != I2M_OK) return I2M_DT_FULL;
  if (ctx_grow_u32(&rm->slot, &rm->cap_slot, nlt) != I2M_OK) return I2M_DT_FULL;
  if (ctx_grow_u32(&rm->fill, &rm->cap_fill, nlt) != I2M_OK) return I2M_DT_FULL;
  for (uint32_t s = 0; s < nlt; s++) rm->slot[s] = I2M_DT_NONE;
  for (uint32_t k = 0; k < ctx->ncav; k++) { /* register the link faces */
    uint32_t t = ctx->cav[k], key[3], n = 0, iv = 0;
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t w = dt->tv[4 * t + i];
      if (w == v) iv = i;
      else key[n++] = local_id(rm, w);
    }
    sort3(key);
    uint32_t s = lf_slot(rm, key);
    if (rm->lf[s].used == rm->lfstamp) return I2M_DT_FAILED; /* a link face twice: corrupt star */
    rm->lf[s].used = rm->lfstamp;
    memcpy(rm->lf[s].key, key, sizeof key);
    rm->lf[s].out = dt->tn[4 * t + iv];
  }
  rm->nfill = 0;
  uint32_t nlink = 0;
  for (uint32_t t = 0; t < nlt; t++) { /* seeds: local tets with a link face, on v's side */
    if (!i2m_dt_alive(loc, t)) continue;
    const uint32_t *lv = loc->tv + 4 * (size_t)t;
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t key[3], n = 0;
      for (uint32_t j = 0; j < 4; j++)
        if (j != i) key[n++] = lv[j];
      sort3(key);
      if (rm->lf[lf_slot(rm, key)].used != rm->lfstamp) continue;
      /* v's side: the local tet with lv[i] replaced by v keeps its positive orientation */
      const double *q[4];
      for (int j = 0; j < 4; j++) q[j] = i2m_dt_xyz(loc, lv[j]);
      q[i] = i2m_dt_xyz(dt, v);
      if (i2m_orient3d(q[0], q[1], q[2], q[3]) <= 0) continue;
      nlink++;
      if (rm->slot[t] == I2M_DT_NONE) {
        rm->slot[t] = 0;
        rm->fill[rm->nfill++] = t;
      }
    }
  }
  if (nlink != ctx->ncav) return I2M_DT_FAILED; /* a link face missing from the local DT */
  for (uint32_t k = 0; k < rm->nfill; k++) { /* flood fill inside the link */
    uint32_t t = rm->fill[k];
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t n = loc->tn[4 * t + i];
      uint32_t key[3], c = 0;
      for (uint32_t j = 0; j < 4; j++)
        if (j != i) key[c++] = loc->tv[4 * t + j];
      sort3(key);
      if (rm->lf[lf_slot(rm, key)].used == rm->lfstamp) continue;
      if (n == I2M_DT_NONE) return I2M_DT_FAILED; /* escaped to the box hull */
      uint32_t u = n >> 2;
      if (rm->slot[u] != I2M_DT_NONE) continue;
      rm->slot[u] = 0;
      rm->fill[rm->nfill++] = u;
    }
  }
  return I2M_DT_OK;
}

/* ---- step 4: splice the fill into the main mesh ---- */
static i2m_dt_status_t fill_commit(i2m_dt_ctx_t *ctx, struct i2m_dt_removal *rm, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt, *loc = rm->loc;
  uint32_t nf = rm->nfill, ns = ctx->ncav;
  if (!ctx_ensure_slots(ctx, nf > ns ? nf - ns : 0, 0)) return I2M_DT_FULL;
  if (ctx_grow_u32(&ctx->newt, &ctx->cap_new, nf) != I2M_OK) return I2M_DT_FULL;
  if (ctx_grow_u32(&ctx->slots.pool, &ctx->slots.cap_pool, ctx->slots.npool + ns + 1) != I2M_OK) return I2M_DT_FULL;
  if (ctx_vpool_push(ctx, v) != I2M_OK) return I2M_DT_FULL;
  ctx->nnew = 0;
  for (uint32_t k = 0; k < nf; k++) {
    uint32_t t = k < ns ? ctx->cav[k] : ctx_tet_slot(ctx);
    meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)));
    rm->slot[rm->fill[k]] = t;
    ctx->newt[ctx->nnew++] = t;
  }
  for (uint32_t k = nf; k < ns; k++) {
    uint32_t t = ctx->cav[k];
    meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
    ctx->slots.pool[ctx->slots.npool++] = t;
  }
  for (uint32_t k = 0; k < nf; k++) {
    uint32_t lt = rm->fill[k], t = rm->slot[lt];
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t w = rm->lmap[loc->tv[4 * lt + i]];
      dt->tv[4 * t + i] = w;
      dt->vtet[w] = t;
    }
    for (uint32_t i = 0; i < 4; i++) {
      uint32_t key[3], c = 0;
      for (uint32_t j = 0; j < 4; j++)
        if (j != i) key[c++] = loc->tv[4 * lt + j];
      sort3(key);
      const link_face_t *f = &rm->lf[lf_slot(rm, key)];
      if (f->used == rm->lfstamp) { /* glue to the outside */
        dt->tn[4 * t + i] = f->out;
        if (f->out < I2M_DT_REMOTE) dt->tn[f->out] = 4 * t + i;
      } else {
        uint32_t n = loc->tn[4 * lt + i];
        dt->tn[4 * t + i] = 4 * rm->slot[n >> 2] + (n & 3);
      }
    }
  }
  dt->vkind[v] = I2M_VK_DEAD;
  ctx->n_remove++;
  ctx->n_created += nf;
  ctx->n_killed += ns;
  return I2M_DT_OK;
}

i2m_dt_status_t i2m_dt_remove(i2m_dt_ctx_t *ctx, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  ctx->nnew = 0;
  journal_forget(ctx);
  if (v < 8 || v >= i2m_dt_nverts_slots(dt) || dt->vkind[v] == I2M_VK_DEAD || dt->vkind[v] == I2M_VK_BOX)
    return I2M_DT_STALE;
  if (!ctx->rm && removal_create(dt, &ctx->rm) != I2M_OK) return I2M_DT_FULL;
  i2m_dt_status_t st = star_collect(ctx, v);
  if (st == I2M_DT_OK) st = local_triangulate(ctx, ctx->rm, v);
  if (st == I2M_DT_OK) st = fill_select(ctx, ctx->rm, v);
  if (st == I2M_DT_OK) st = fill_commit(ctx, ctx->rm, v);
  if (st != I2M_DT_OK) {
    for (uint32_t k = 0; k < ctx->ncav; k++) {
      uint32_t t = ctx->cav[k];
      meta_store(dt, t, i2m_dt_meta(dt, t) & ~I2M_TM_MARK);
    }
    i2m_dt_unlock_all(ctx);
    if (st == I2M_DT_ROLLBACK) ctx->n_rollback++;
  }
  ctx->ncav = 0;
  return st;
}

/* ---- moving a vertex in place ---- */

/* Does vertex e lie in the ball of tet tv (positively oriented) with its vertex `at` moved to
 * p?  The perturbed test, with the moved vertex's own global id. */
static int moved_insphere(const i2m_dt_t *dt, const uint32_t *tv, int at, const double p[3], uint32_t e)
{
  const double *q[4];
  for (int j = 0; j < 4; j++) q[j] = j == at ? p : i2m_dt_xyz(dt, tv[j]);
  const double *x = i2m_dt_xyz(dt, e);
  const int s = i2m_insphere_filter(q[0], q[1], q[2], q[3], x);
  if (I2M_LIKELY(s != 0)) return s;
  return i2m_insphere_sos_exact(q[0], q[1], q[2], q[3], x, i2m_dt_gid(dt, tv[0]), i2m_dt_gid(dt, tv[1]),
                                i2m_dt_gid(dt, tv[2]), i2m_dt_gid(dt, tv[3]), i2m_dt_gid(dt, e));
}

static int index_of(const uint32_t *tv, uint32_t v)
{
  for (int i = 0; i < 4; i++)
    if (tv[i] == v) return i;
  return -1;
}

/* With v at p, is every tet of its star (ctx->cav) still positive, and every face of the star
 * locally Delaunay (the vertex across it outside the ball of the tet on this side)?  Then the
 * same tets are the Delaunay tetrahedralization of the moved points (the Delaunay lemma). */
static bool star_stays_delaunay(const i2m_dt_ctx_t *ctx, uint32_t v, const double p[3])
{
  const i2m_dt_t *dt = ctx->dt;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t *tv = dt->tv + 4 * (size_t)ctx->cav[k];
    if (tet_orient_replace(dt, tv, index_of(tv, v), p) <= 0) return false;
  }
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t t = ctx->cav[k], *tv = dt->tv + 4 * (size_t)t;
    const int at = index_of(tv, v);
    for (int i = 0; i < 4; i++) {
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n == I2M_DT_NONE) continue; /* (the box's hull) */
      if (i != at && (n >> 2) < t) continue; /* a face between two tets of the star: once */
      if (moved_insphere(dt, tv, at, p, dt->tv[n]) > 0) return false; /* (tv[4u + j] for n = 4u + j) */
    }
  }
  return true;
}

i2m_dt_status_t i2m_dt_move(i2m_dt_ctx_t *ctx, uint32_t v, const double p_in[3])
{
  i2m_dt_t *dt = ctx->dt;
  ctx->nnew = 0;
  journal_forget(ctx);
  if (v < 8 || v >= i2m_dt_nverts_slots(dt) || dt->vkind[v] == I2M_VK_DEAD || dt->vkind[v] == I2M_VK_BOX)
    return I2M_DT_STALE;
  double snapped[3];
  const double *p = i2m_dt_snap(dt, p_in, snapped);
  i2m_dt_status_t st = star_collect(ctx, v);
  if (st == I2M_DT_OK && !star_stays_delaunay(ctx, v, p)) st = I2M_DT_NOT_IN_CONFLICT;
  if (st == I2M_DT_OK && ctx_grow_u32(&ctx->newt, &ctx->cap_new, ctx->ncav) != I2M_OK) st = I2M_DT_FULL;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t t = ctx->cav[k];
    meta_store(dt, t, i2m_dt_meta(dt, t) & ~I2M_TM_MARK);
    if (st == I2M_DT_OK) ctx->newt[ctx->nnew++] = t;
  }
  ctx->ncav = 0;
  if (st != I2M_DT_OK) {
    i2m_dt_unlock_all(ctx);
    if (st == I2M_DT_ROLLBACK) ctx->n_rollback++;
    return st;
  }
  double *x = dt->xyzw + 4 * (size_t)v; /* (x[3] keeps the global id) */
  x[0] = p[0];
  x[1] = p[1];
  x[2] = p[2];
  return I2M_DT_OK;
}
