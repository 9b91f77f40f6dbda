/* Delaunay layer: Bowyer–Watson insertion from a tet in conflict (breadth-first cavity
 * search, refill that reuses the cavity's slots, adjacency by an edge table of local vertex
 * numbers), the visibility walk, and the lock protocol hooks (REFERENCE §2.2 and §3.5).
 *
 * The hot path is written for few instructions per visited face: every vertex the search
 * meets gets a local number together with its lock (one word, see dt.h) and a cached row
 * (its coordinates translated by the new point, lifted), so a conflict test is one 4x4
 * determinant on cached rows checked against one error bound for the whole cavity; the
 * cavity keeps the local numbers of its tets, and a boundary face is two words. */
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

/* The row of local vertex k (vertex v) for point p, and the cavity's error bound grown to
 * cover it. */
static I2M_INLINE void row_fill(i2m_dt_ctx_t *ctx, double *row, uint32_t v, const double *p)
{
  i2m_insphere_row(i2m_dt_xyz(ctx->dt, v), p, row);
  const double ax = fabs(row[0]), ay = fabs(row[1]), az = fabs(row[2]);
  if (I2M_UNLIKELY((ax > ctx->rmax[0]) | (ay > ctx->rmax[1]) | (az > ctx->rmax[2]))) {
    ctx->rmax[0] = ax > ctx->rmax[0] ? ax : ctx->rmax[0];
    ctx->rmax[1] = ay > ctx->rmax[1] ? ay : ctx->rmax[1];
    ctx->rmax[2] = az > ctx->rmax[2] ? az : ctx->rmax[2];
    ctx->isp_bound = i2m_insphere_rows_bound(ctx->rmax[0], ctx->rmax[1], ctx->rmax[2]);
  }
}

static I2M_INLINE void row_make(i2m_dt_ctx_t *ctx, uint32_t k, uint32_t v, const double *p)
{
  row_fill(ctx, ctx->rows + 4 * (size_t)k, v, p);
}

/* Gives vertex v a local number for this insertion: takes its lock word (a compare-and-swap
 * in threaded runs) and makes its row.  A vertex the context already holds has its number
 * (and row) already.  Returns the number, -1 if another thread holds the vertex, -2 when
 * out of memory. */
static I2M_INLINE int64_t local_vertex(i2m_dt_ctx_t *ctx, uint32_t v, const double *p)
{
  _Atomic uint32_t *L = &ctx->dt->vlock[v];
  uint32_t cur = atomic_load_explicit(L, memory_order_relaxed);
  if ((cur & I2M_DT_OWNER_MASK) == ctx->owner) return cur >> I2M_DT_OWNER_BITS;
  uint32_t k = ctx->nheld;
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
  row_make(ctx, k, v, p);
  return k;
}

static inline uint32_t local_owner(const i2m_dt_ctx_t *ctx, uint32_t v)
{
  return atomic_load_explicit(&ctx->dt->vlock[v], memory_order_relaxed) & I2M_DT_OWNER_MASK;
}

static inline uint32_t local_of(const i2m_dt_t *dt, uint32_t v)
{
  return atomic_load_explicit(&dt->vlock[v], memory_order_relaxed) >> I2M_DT_OWNER_BITS;
}

/* The conflict test decided past the cavity's bound: the filter on the rows r of vertices v
 * (the tet's, positively oriented), then exact arithmetic with the perturbation. */
static I2M_NOINLINE int conflict_decide(const i2m_dt_ctx_t *ctx, const double *const r[4], const uint32_t v[4],
                                        const double *p, i2m_gidx_t gid)
{
  int s = i2m_insphere_filter_rows(r[0], r[1], r[2], r[3]);
  if (s != 0) return s;
  const i2m_dt_t *dt = ctx->dt;
  return i2m_insphere_sos_exact(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3]), p,
                                i2m_dt_gid(dt, v[0]), i2m_dt_gid(dt, v[1]), i2m_dt_gid(dt, v[2]), i2m_dt_gid(dt, v[3]), gid);
}

/* The same for the tet whose vertices have local numbers l[]. */
static I2M_NOINLINE int conflict_exact(const i2m_dt_ctx_t *ctx, const uint32_t l[4], const double *p, i2m_gidx_t gid)
{
  const double *R = ctx->rows;
  const double *const r[4] = {R + 4 * l[0], R + 4 * l[1], R + 4 * l[2], R + 4 * l[3]};
  const uint32_t v[4] = {ctx->held[l[0]], ctx->held[l[1]], ctx->held[l[2]], ctx->held[l[3]]};
  return conflict_decide(ctx, r, v, p, gid);
}

/* Conflict test of a positive tet given by its local numbers: > 0 when p is in its ball. */
static I2M_INLINE int conflict(const i2m_dt_ctx_t *ctx, const uint32_t l[4], const double *p, i2m_gidx_t gid)
{
  const double *R = ctx->rows;
  const double det = i2m_insphere_det_rows(R + 4 * l[0], R + 4 * l[1], R + 4 * l[2], R + 4 * l[3]);
  if (I2M_LIKELY(fabs(det) > ctx->isp_bound)) return (det > 0.0) - (det < 0.0);
  return conflict_exact(ctx, l, p, gid);
}

/* The same for tet c (local numbers cl) with its vertex i replaced by local vertex w: the
 * neighbour across face i, negatively oriented, so < 0 when p is in its ball. */
static I2M_INLINE int conflict_across(const i2m_dt_ctx_t *ctx, const uint32_t cl[4], uint32_t i, uint32_t w,
                                      const double *p, i2m_gidx_t gid)
{
  const double *R = ctx->rows;
  const double *r[4] = {R + 4 * cl[0], R + 4 * cl[1], R + 4 * cl[2], R + 4 * cl[3]};
  r[i] = R + 4 * w;
  const double det = i2m_insphere_det_rows(r[0], r[1], r[2], r[3]);
  if (I2M_LIKELY(fabs(det) > ctx->isp_bound)) return (det > 0.0) - (det < 0.0);
  uint32_t fl[4] = {cl[0], cl[1], cl[2], cl[3]};
  fl[i] = w;
  return conflict_exact(ctx, fl, p, gid);
}

/* conflict_across for an apex w that has no local number (zone mode: a vertex outside the
 * zone, which may be read but not numbered), from its row computed on the spot. */
static I2M_NOINLINE int conflict_across_unnumbered(i2m_dt_ctx_t *ctx, const uint32_t cl[4], uint32_t i, uint32_t w,
                                                   const double *p, i2m_gidx_t gid)
{
  double row[4];
  row_fill(ctx, row, w, p);
  const double *R = ctx->rows;
  const double *r[4] = {R + 4 * cl[0], R + 4 * cl[1], R + 4 * cl[2], R + 4 * cl[3]};
  r[i] = row;
  const double det = i2m_insphere_det_rows(r[0], r[1], r[2], r[3]);
  if (fabs(det) > ctx->isp_bound) return (det > 0.0) - (det < 0.0);
  uint32_t v[4] = {ctx->held[cl[0]], ctx->held[cl[1]], ctx->held[cl[2]], ctx->held[cl[3]]};
  v[i] = w;
  return conflict_decide(ctx, r, v, p, gid);
}

static inline bool row_is_origin(const i2m_dt_ctx_t *ctx, uint32_t l)
{
  const double *r = ctx->rows + 4 * (size_t)l;
  return (r[0] == 0.0) & (r[1] == 0.0) & (r[2] == 0.0); /* x - p is exact only for x == p */
}

static I2M_NOINLINE i2m_dt_status_t boundary_grow(i2m_dt_ctx_t *ctx)
{
  uint32_t cap = ctx->cap_bnd + ctx->cap_bnd / 2 + 64;
  if (i2m_realloc(cap, sizeof(i2m_dt_bface_t), &ctx->bnd) != I2M_OK) return I2M_DT_FULL;
  ctx->cap_bnd = cap;
  return I2M_DT_OK;
}

static I2M_INLINE i2m_dt_status_t boundary_push(i2m_dt_ctx_t *ctx, uint32_t ki, uint32_t out)
{
  if (I2M_UNLIKELY(ctx->nbnd == ctx->cap_bnd) && boundary_grow(ctx) != I2M_DT_OK) return I2M_DT_FULL;
  ctx->bnd[ctx->nbnd++] = (i2m_dt_bface_t){ki, out};
  return I2M_DT_OK;
}

static I2M_INLINE i2m_dt_status_t cavity_push(i2m_dt_ctx_t *ctx, uint32_t t, const uint32_t l[4])
{
  if (I2M_UNLIKELY(ctx->ncav == ctx->cap_cav) && ctx_cavity_room(ctx, ctx->ncav + 1) != I2M_OK) return I2M_DT_FULL;
  memcpy(ctx->cavl + 4 * (size_t)ctx->ncav, l, 4 * sizeof *l);
  ctx->cav[ctx->ncav++] = t;
  i2m_dt_t *dt = ctx->dt;
  meta_store(dt, t, i2m_dt_meta(dt, t) | I2M_TM_MARK);
  /* the search visits t's neighbours later: their words start loading now */
  const uint32_t *tn = dt->tn + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) {
    if (tn[i] == I2M_DT_NONE) continue;
    I2M_PREFETCH(&dt->meta[tn[i] >> 2]);
    I2M_PREFETCH(dt->tv + 4 * (size_t)(tn[i] >> 2));
  }
  return I2M_DT_OK;
}

/* Face i of the k-th cavity tet c (local numbers cl): the neighbour across it joins the
 * cavity when p is in its ball, else the face is a boundary face.  The neighbour is c with
 * vertex i replaced by its apex, negatively oriented; the local numbers of its other
 * vertices are looked up only when it joins.  Inlined with a constant i. */
static I2M_INLINE i2m_dt_status_t cavity_visit(i2m_dt_ctx_t *ctx, uint32_t k, uint32_t c, const uint32_t cl[4],
                                               uint32_t i, const double *p, i2m_gidx_t gid, bool zoned)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t n = dt->tn[4 * (size_t)c + i];
  if (I2M_UNLIKELY(n == I2M_DT_NONE)) return boundary_push(ctx, k << 2 | i, n); /* box hull */
  const uint32_t u = n >> 2, j = n & 3;
  const uint32_t m = i2m_dt_meta(dt, u);
  if (m & I2M_TM_MARK) return I2M_DT_OK; /* inside the cavity: not a boundary face */
  const uint32_t *uv = dt->tv + 4 * (size_t)u;
  if (zoned && I2M_UNLIKELY(!zone_holds(ctx, uv[j])) && (local_owner(ctx, uv[j]) != ctx->owner)) {
    /* zone mode: a vertex outside the zone may be read, not numbered; u may stay outside */
    if (conflict_across_unnumbered(ctx, cl, i, uv[j], p, gid) >= 0) return boundary_push(ctx, k << 2 | i, n);
    ctx->conflict_owner = 0;
    return I2M_DT_ROLLBACK;
  }
  const int64_t lw = local_vertex(ctx, uv[j], p);
  if (I2M_UNLIKELY(lw < 0)) return lw == -1 ? I2M_DT_ROLLBACK : I2M_DT_FULL;
  if (conflict_across(ctx, cl, i, (uint32_t)lw, p, gid) >= 0) {
    I2M_PREFETCH_WRITE(&dt->tn[n]); /* the refill links the outside tet back to its new neighbour */
    return boundary_push(ctx, k << 2 | i, n);
  }
  if (m & I2M_TM_FROZEN) return I2M_DT_FROZEN;
  if (row_is_origin(ctx, (uint32_t)lw)) return I2M_DT_DUPLICATE;
  uint32_t ul[4] = {local_of(dt, uv[0]), local_of(dt, uv[1]), local_of(dt, uv[2]), local_of(dt, uv[3])};
  return cavity_push(ctx, u, ul);
}

/* Requests the words of the vertices across the faces of cavity tet t (their lock words and
 * coordinates, which the visits read), a tet before they are visited: the neighbours' vertex
 * lists, requested when t joined, have arrived by then. */
static I2M_INLINE void prefetch_apexes(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *tn = dt->tn + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) {
    if (tn[i] == I2M_DT_NONE) continue;
    const uint32_t w = dt->tv[tn[i]]; /* 4u + j: vertex j of neighbour u, its apex */
    I2M_PREFETCH(&dt->vlock[w]);
    I2M_PREFETCH(dt->xyzw + 4 * (size_t)w);
  }
}

/* Breadth-first search of the tets whose circumballs hold p, from a seed in conflict.  Every
 * vertex met gets a local number (and, in threaded runs, is locked); the outside tets'
 * apexes are locked too, as the new tets' neighbours will change. */
static I2M_INLINE i2m_dt_status_t cavity_search_in(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid, bool zoned)
{
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t c = ctx->cav[k];
    uint32_t cl[4];
    memcpy(cl, ctx->cavl + 4 * (size_t)k, sizeof cl);
    if (k + 1 < ctx->ncav) prefetch_apexes(ctx->dt, ctx->cav[k + 1]);
    i2m_dt_status_t st;
    if ((st = cavity_visit(ctx, k, c, cl, 0, p, gid, zoned)) != I2M_DT_OK) return st;
    if ((st = cavity_visit(ctx, k, c, cl, 1, p, gid, zoned)) != I2M_DT_OK) return st;
    if ((st = cavity_visit(ctx, k, c, cl, 2, p, gid, zoned)) != I2M_DT_OK) return st;
    if ((st = cavity_visit(ctx, k, c, cl, 3, p, gid, zoned)) != I2M_DT_OK) return st;
  }
  return I2M_DT_OK;
}

/* Two copies: with and without the zone test (the deterministic mode's), which then costs
 * nothing in the other runs. */
static I2M_NOINLINE i2m_dt_status_t cavity_search_zoned(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  return cavity_search_in(ctx, p, gid, true);
}

static I2M_NOINLINE i2m_dt_status_t cavity_search_free(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  return cavity_search_in(ctx, p, gid, false);
}

static i2m_dt_status_t cavity_search(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  return ctx->zone ? cavity_search_zoned(ctx, p, gid) : cavity_search_free(ctx, p, gid);
}

/* ---- refill ---- */

/* Adjacency of the new tets.  New tet k (boundary face k with p at slot i) has three faces
 * through p; face j meets the cavity boundary in an edge, which the oriented boundary of the
 * tet runs as (p, a, b) with (a, b) = EDGE_DIR[i][j] (the induced orientation (-1)^j of the
 * face, rotated to start at p).  The tet across that face runs the same edge as (b, a), so a
 * table indexed by directed edges of local numbers links every face: the first pass files
 * each face under (a, b), the second reads its partner under (b, a).  Every edge read was
 * filed in the same insertion, so the table never needs clearing.  It fits cavities whose
 * vertices have local numbers below EDGE_TABLE_SIDE and up to 16383 boundary faces; larger
 * ones use the hash (ctx_edge_link). */
static const uint8_t EDGE_DIR[4][4][2] = {{{0, 0}, {3, 2}, {1, 3}, {2, 1}},
                                          {{2, 3}, {0, 0}, {3, 0}, {0, 2}},
                                          {{3, 1}, {0, 3}, {0, 0}, {1, 0}},
                                          {{1, 2}, {2, 0}, {0, 1}, {0, 0}}};
#define EDGE_TABLE_SIDE 128u

static bool edge_table_ready(i2m_dt_ctx_t *ctx, uint32_t nb)
{
  if (ctx->nheld > EDGE_TABLE_SIDE || nb >= 0x4000u) return false;
  if (!ctx->etab2 && i2m_malloc(EDGE_TABLE_SIDE * EDGE_TABLE_SIDE, sizeof *ctx->etab2, &ctx->etab2) != I2M_OK)
    return false;
  return true;
}

static I2M_INLINE uint16_t *edge_entry(const i2m_dt_ctx_t *ctx, uint32_t a, uint32_t b)
{
  return ctx->etab2 + (a * EDGE_TABLE_SIDE + b);
}

/* The three slots other than i. */
static const uint8_t OTHER3[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};

/* New tet k: boundary face b (face i of its cavity tet) joined to the new vertex v.  Inlined
 * with a constant i, so every slot index is a constant. */
static I2M_INLINE uint32_t fill_tet(i2m_dt_ctx_t *ctx, uint32_t k, i2m_dt_bface_t b, uint32_t i, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t *cl = ctx->cavl + 4 * (size_t)(b.ki >> 2), *H = ctx->held, t = ctx->newt[k];
  meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)));
  uint32_t *tv = dt->tv + 4 * (size_t)t;
  for (uint32_t s = 0; s < 4; s++) tv[s] = s == i ? v : H[cl[s]];
  dt->tn[4 * (size_t)t + i] = b.out;
  if (b.out != I2M_DT_NONE) dt->tn[b.out] = 4 * t + i;
  dt->vtet[tv[OTHER3[i][0]]] = t;
  dt->vtet[tv[OTHER3[i][1]]] = t;
  dt->vtet[tv[OTHER3[i][2]]] = t;
  return t;
}

/* Files face j of new tet k under its directed boundary edge (see EDGE_DIR). */
static I2M_INLINE void file_face(i2m_dt_ctx_t *ctx, uint32_t k, const uint32_t *cl, uint32_t i, uint32_t j)
{
  *edge_entry(ctx, cl[EDGE_DIR[i][j][0]], cl[EDGE_DIR[i][j][1]]) = (uint16_t)(k << 2 | j);
}

/* Face j of new tet t from the partner filed under the reversed edge. */
static I2M_INLINE void link_face(i2m_dt_ctx_t *ctx, uint32_t t, const uint32_t *cl, uint32_t i, uint32_t j)
{
  const uint32_t e = *edge_entry(ctx, cl[EDGE_DIR[i][j][1]], cl[EDGE_DIR[i][j][0]]);
  ctx->dt->tn[4 * (size_t)t + j] = 4 * ctx->newt[e >> 2] + (e & 3);
}

static I2M_INLINE void fill_direct(i2m_dt_ctx_t *ctx, uint32_t k, i2m_dt_bface_t b, uint32_t i, uint32_t v)
{
  fill_tet(ctx, k, b, i, v);
  const uint32_t *cl = ctx->cavl + 4 * (size_t)(b.ki >> 2);
  file_face(ctx, k, cl, i, OTHER3[i][0]);
  file_face(ctx, k, cl, i, OTHER3[i][1]);
  file_face(ctx, k, cl, i, OTHER3[i][2]);
}

static I2M_INLINE void link_direct(i2m_dt_ctx_t *ctx, uint32_t k, uint32_t ki, uint32_t i)
{
  const uint32_t *cl = ctx->cavl + 4 * (size_t)(ki >> 2), t = ctx->newt[k];
  link_face(ctx, t, cl, i, OTHER3[i][0]);
  link_face(ctx, t, cl, i, OTHER3[i][1]);
  link_face(ctx, t, cl, i, OTHER3[i][2]);
}

/* The new tets of a cavity too large for the edge table: adjacency through the hash. */
static I2M_NOINLINE void fill_hashed(i2m_dt_ctx_t *ctx, uint32_t v)
{
  for (uint32_t k = 0; k < ctx->nbnd; k++) {
    const i2m_dt_bface_t b = ctx->bnd[k];
    const uint32_t i = b.ki & 3, t = fill_tet(ctx, k, b, i, v);
    for (uint32_t x = 0; x < 3; x++) ctx_edge_link(ctx, t, i, OTHER3[i][x]);
  }
}

/* Room for the refill: slots, the new-tet list, the pool, the lock of the new vertex. */
static bool fill_room(i2m_dt_ctx_t *ctx, uint32_t nb, uint32_t nc)
{
  return ctx_ensure_slots(ctx, nb > nc ? nb - nc : 0, 1) && ctx_grow_u32(&ctx->newt, &ctx->cap_new, nb) == I2M_OK &&
         (nc <= nb || ctx_grow_u32(&ctx->slots.pool, &ctx->slots.cap_pool, ctx->slots.npool + (nc - nb)) == I2M_OK) &&
         (!ctx->locking || ctx_hold_room(ctx) == I2M_OK);
}

/* The new vertex's slot (locked in threaded runs, until the caller unlocks). */
static uint32_t new_vertex(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid, uint8_t kind)
{
  i2m_dt_t *dt = ctx->dt;
  uint32_t v;
  if (ctx->locking) {
    v = ctx_vertex_slot_locked(ctx, ctx->owner | (ctx->nheld << I2M_DT_OWNER_BITS));
    if (v == I2M_DT_NONE) return v;
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
  return v;
}

/* Replaces the cavity by the tets joining p to its boundary faces.  Cavity slots are reused
 * first; the rest of the cavity's slots go to the context's pool. */
static i2m_dt_status_t cavity_fill(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid, uint8_t kind, uint32_t *vout)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t nb = ctx->nbnd, nc = ctx->ncav;
  if (!fill_room(ctx, nb, nc)) return I2M_DT_FULL;
  const bool direct = edge_table_ready(ctx, nb);
  if (!direct && ctx_edges_begin(ctx, 3 * nb) != I2M_OK) return I2M_DT_FULL;
  const uint32_t v = new_vertex(ctx, p, gid, kind);
  if (v == I2M_DT_NONE) return I2M_DT_FULL;
  for (uint32_t k = 0; k < nb; k++) ctx->newt[k] = k < nc ? ctx->cav[k] : ctx_tet_slot(ctx);
  ctx->nnew = nb;
  if (direct) {
    for (uint32_t k = 0; k < nb; k++) {
      const i2m_dt_bface_t b = ctx->bnd[k];
      switch (b.ki & 3) { /* constant slot indices in each case */
        case 0: fill_direct(ctx, k, b, 0, v); break;
        case 1: fill_direct(ctx, k, b, 1, v); break;
        case 2: fill_direct(ctx, k, b, 2, v); break;
        default: fill_direct(ctx, k, b, 3, v); break;
      }
    }
    for (uint32_t k = 0; k < nb; k++) {
      const uint32_t ki = ctx->bnd[k].ki;
      switch (ki & 3) {
        case 0: link_direct(ctx, k, ki, 0); break;
        case 1: link_direct(ctx, k, ki, 1); break;
        case 2: link_direct(ctx, k, ki, 2); break;
        default: link_direct(ctx, k, ki, 3); break;
      }
    }
  } else {
    fill_hashed(ctx, v);
  }
  dt->vtet[v] = ctx->newt[0];
  for (uint32_t k = nb; k < nc; k++) { /* cavity slots left over: dead */
    uint32_t t = ctx->cav[k];
    meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
    ctx->slots.pool[ctx->slots.npool++] = t;
  }
  ctx->n_insert++;
  ctx->n_created += nb;
  ctx->n_killed += nc;
  *vout = v;
  return I2M_DT_OK;
}

/* Numbers and locks the seed's vertices (threaded: read before the locks, verified after)
 * and checks the seed: alive, unchanged, not frozen, p not one of its vertices, p in its
 * ball.  Then it is the first cavity tet. */
static i2m_dt_status_t cavity_seed(i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid, uint32_t seed,
                                   uint32_t seed_meta)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t *sv = dt->tv + 4 * (size_t)seed;
  uint32_t v4[4], l4[4];
  memcpy(v4, sv, sizeof v4);
  if (ctx->zone && !(zone_holds(ctx, v4[0]) && zone_holds(ctx, v4[1]) && zone_holds(ctx, v4[2]) && zone_holds(ctx, v4[3]))) {
    ctx->conflict_owner = 0;
    return I2M_DT_ROLLBACK;
  }
  for (int i = 0; i < 4; i++) {
    int64_t l = local_vertex(ctx, v4[i], p);
    if (l < 0) return l == -1 ? I2M_DT_ROLLBACK : I2M_DT_FULL;
    l4[i] = (uint32_t)l;
  }
  if (ctx->locking && memcmp(v4, sv, sizeof v4) != 0) return I2M_DT_STALE;
  uint32_t m = i2m_dt_meta(dt, seed);
  if ((m & I2M_TM_DEAD) || (seed_meta != I2M_DT_NONE && m != seed_meta)) return I2M_DT_STALE;
  if (m & I2M_TM_FROZEN) return I2M_DT_FROZEN;
  for (int i = 0; i < 4; i++)
    if (row_is_origin(ctx, l4[i])) return I2M_DT_DUPLICATE;
  if (conflict(ctx, l4, p, gid) <= 0) return I2M_DT_NOT_IN_CONFLICT;
  return cavity_push(ctx, seed, l4);
}

i2m_dt_status_t i2m_dt_insert(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                              uint32_t seed, uint32_t seed_meta, uint32_t *vout)
{
  I2M_CHECK_ABORT(ctx->locking || ctx->nheld == 0, "i2m_dt_insert: the previous operation's vertices are still held");
  ctx->ncav = ctx->nbnd = ctx->nnew = 0;
  if (ctx->zone && !i2m_box_holds(ctx->zone, p)) {
    ctx->conflict_owner = 0;
    return cavity_abandon(ctx, I2M_DT_ROLLBACK);
  }
  ctx->rmax[0] = ctx->rmax[1] = ctx->rmax[2] = 0.0;
  ctx->isp_bound = (double)INFINITY;
  for (uint32_t k = 0; k < ctx->nheld; k++) row_make(ctx, k, ctx->held[k], p); /* locked before */
  i2m_dt_status_t st = cavity_seed(ctx, p, gid, seed, seed_meta);
  if (st == I2M_DT_OK) st = cavity_search(ctx, p, gid);
  if (st == I2M_DT_OK) st = cavity_fill(ctx, p, gid, kind, vout);
  if (st != I2M_DT_OK) return cavity_abandon(ctx, st);
  ctx->ncav = ctx->nbnd = 0;
  if (!ctx->locking) i2m_dt_unlock_all(ctx); /* sequential: only the local numbering to undo */
  return I2M_DT_OK;
}

/* ---- point location ---- */

static inline uint32_t rng_next(uint64_t *state)
{
  uint64_t x = *state;
  x ^= x << 13;
  x ^= x >> 7;
  x ^= x << 17;
  *state = x;
  return (uint32_t)(x >> 32);
}

/* The walk's random face order is seeded by the point itself: the walk is a function of the
 * mesh, the point and the start (the same on any thread, whatever it did before). */
static uint64_t walk_seed(const double p[3])
{
  uint64_t h = 0x9E3779B97F4A7C15ull;
  for (int a = 0; a < 3; a++) {
    uint64_t bits;
    memcpy(&bits, &p[a], sizeof bits);
    h = (h ^ bits) * 0xBF58476D1CE4E5B9ull;
    h ^= h >> 31;
  }
  return h | 1; /* (xorshift needs a non-zero state) */
}

/* orient3d of tet v with each vertex i in turn replaced by p (o[i] < 0: p is beyond face i),
 * in floating point, from the vertices translated by p: replacing vertex i leaves +-det of the
 * other three rows, and the four determinants share their 2x2 minors.  Each is the same
 * expression as i2m_det3_rows, so *bound (from the largest translated coordinates) certifies
 * every sign it exceeds. */
static I2M_INLINE void face_orients(const i2m_dt_t *dt, const uint32_t *v, const double *p, double o[4], double *bound)
{
  double d[4][3], mx = 0, my = 0, mz = 0;
  for (int k = 0; k < 4; k++) {
    const double *x = i2m_dt_xyz(dt, v[k]);
    d[k][0] = x[0] - p[0];
    d[k][1] = x[1] - p[1];
    d[k][2] = x[2] - p[2];
    mx = fabs(d[k][0]) > mx ? fabs(d[k][0]) : mx;
    my = fabs(d[k][1]) > my ? fabs(d[k][1]) : my;
    mz = fabs(d[k][2]) > mz ? fabs(d[k][2]) : mz;
  }
  const double m01 = d[0][0] * d[1][1] - d[1][0] * d[0][1], m02 = d[0][0] * d[2][1] - d[2][0] * d[0][1];
  const double m03 = d[0][0] * d[3][1] - d[3][0] * d[0][1], m12 = d[1][0] * d[2][1] - d[2][0] * d[1][1];
  const double m13 = d[1][0] * d[3][1] - d[3][0] * d[1][1], m23 = d[2][0] * d[3][1] - d[3][0] * d[2][1];
  o[0] = d[1][2] * m23 - d[2][2] * m13 + d[3][2] * m12;
  o[1] = -(d[0][2] * m23 - d[2][2] * m03 + d[3][2] * m02);
  o[2] = d[0][2] * m13 - d[1][2] * m03 + d[3][2] * m01;
  o[3] = -(d[0][2] * m12 - d[1][2] * m02 + d[2][2] * m01);
  *bound = i2m_orient3d_rows_bound(mx, my, mz);
}

/* Is p beyond face i of tet v (orient3d with vertex i replaced by p negative)?  o is the
 * floating-point value, decided exactly when the bound does not certify it. */
static inline bool beyond_face(const i2m_dt_t *dt, const uint32_t *v, uint32_t i, const double *p, double o,
                               double bound)
{
  if (I2M_LIKELY(fabs(o) > bound)) return o < 0.0;
  const double *q[4] = {i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3])};
  q[i] = p;
  return i2m_orient3d(q[0], q[1], q[2], q[3]) < 0;
}

uint32_t i2m_dt_locate(i2m_dt_ctx_t *ctx, const double p[3], uint32_t start)
{
  const i2m_dt_t *dt = ctx->dt;
  uint32_t t = start, prev = I2M_DT_NONE;
  uint64_t rng = walk_seed(p);
  for (;;) {
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    double o[4], bound;
    face_orients(dt, v, p, o, &bound);
    uint32_t r = rng_next(&rng), next = I2M_DT_NONE;
    for (uint32_t k = 0; k < 4; k++) {
      uint32_t i = (r + k) & 3;
      uint32_t n = dt->tn[4 * t + i];
      if (n == I2M_DT_NONE || (n >> 2) == prev) continue;
      if (beyond_face(dt, v, i, p, o[i], bound)) {
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
