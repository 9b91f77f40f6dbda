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

/* ---- cavity search ----
 *
 * The search keeps what it reads and grows in a local working set (the arrays, the counts,
 * the error bound), so the compiler holds it in registers instead of reloading the context
 * after every store into the mesh; the counts are written back when the search ends and
 * whenever a scratch array must grow.  The rows' error bound lives only here: it covers the
 * rows made for this insertion.  Room for a whole cavity tet's four faces (four more cavity tets,
 * boundary faces and local vertices) is made before the tet is visited, so no single push
 * checks a capacity. */
typedef struct {
  i2m_dt_ctx_t *ctx;
  const double *p;
  i2m_gidx_t gid;
  const uint32_t *tn, *tv;
  _Atomic uint32_t *meta, *vlock;
  const double *xyzw;
  double *rows;
  double rmax[3], bound; /* largest |row| per axis, and its insphere bound */
  uint32_t *held, *cav, *cavl;
  i2m_dt_bface_t *bnd;
  uint32_t owner, nheld, ncav, nbnd, cap_held, cap_cav, cap_bnd;
} search_t;

/* (Re)reads the context's scratch arrays and counts (after they may have grown). */
static I2M_INLINE void search_load(search_t *s, i2m_dt_ctx_t *ctx)
{
  s->rows = ctx->rows, s->held = ctx->held, s->cav = ctx->cav, s->cavl = ctx->cavl, s->bnd = ctx->bnd;
  s->nheld = ctx->nheld, s->ncav = ctx->ncav, s->nbnd = ctx->nbnd;
  s->cap_held = ctx->cap_held, s->cap_cav = ctx->cap_cav, s->cap_bnd = ctx->cap_bnd;
}

static I2M_INLINE void search_begin(search_t *s, i2m_dt_ctx_t *ctx, const double *p, i2m_gidx_t gid)
{
  const i2m_dt_t *dt = ctx->dt;
  *s = (search_t){.ctx = ctx, .p = p, .gid = gid, .tn = dt->tn, .tv = dt->tv, .meta = dt->meta,
                  .vlock = dt->vlock, .xyzw = dt->xyzw, .owner = ctx->owner, .bound = (double)INFINITY};
  search_load(s, ctx);
}

static I2M_INLINE void search_store(const search_t *s)
{
  s->ctx->nheld = s->nheld;
  s->ctx->ncav = s->ncav;
  s->ctx->nbnd = s->nbnd;
}

static I2M_NOINLINE i2m_dt_status_t boundary_grow(i2m_dt_ctx_t *ctx)
{
  uint32_t cap = ctx->cap_bnd + ctx->cap_bnd / 2 + 64;
  if (i2m_realloc(cap, sizeof(i2m_dt_bface_t), &ctx->bnd) != I2M_OK) return I2M_DT_FULL;
  ctx->cap_bnd = cap;
  return I2M_DT_OK;
}

/* Room for need more cavity tets, boundary faces and local vertices (slow path). */
static I2M_NOINLINE bool search_grow(search_t *s, uint32_t need)
{
  i2m_dt_ctx_t *ctx = s->ctx;
  search_store(s);
  bool ok = ctx_cavity_room(ctx, s->ncav + need) == I2M_OK && ctx_hold_reserve(ctx, s->nheld + need) == I2M_OK;
  while (ok && ctx->cap_bnd < s->nbnd + need) ok = boundary_grow(ctx) == I2M_DT_OK;
  search_load(s, ctx);
  return ok;
}

static I2M_INLINE bool search_room(search_t *s, uint32_t need)
{
  if (I2M_LIKELY(s->ncav + need <= s->cap_cav && s->nbnd + need <= s->cap_bnd && s->nheld + need <= s->cap_held))
    return true;
  return search_grow(s, need);
}

/* The error bound grown to cover a new row (a few times per cavity: its first rows). */
static I2M_INLINE void bound_grow(search_t *s, const double *row)
{
  for (int a = 0; a < 3; a++) s->rmax[a] = fabs(row[a]) > s->rmax[a] ? fabs(row[a]) : s->rmax[a];
  s->bound = i2m_insphere_rows_bound(s->rmax[0], s->rmax[1], s->rmax[2]);
}

/* The row of vertex v for the new point, and the error bound grown to cover it. */
static I2M_INLINE void row_fill(search_t *s, double *row, uint32_t v)
{
  i2m_insphere_row(s->xyzw + 4 * (size_t)v, s->p, row);
  if (I2M_UNLIKELY((fabs(row[0]) > s->rmax[0]) | (fabs(row[1]) > s->rmax[1]) | (fabs(row[2]) > s->rmax[2])))
    bound_grow(s, row);
}

/* Gives vertex v a local number for this insertion: takes its lock word (a compare-and-swap
 * when locking) and makes its row.  A vertex the context already holds has its number (and
 * row) already.  Returns the number, or -1 when another thread holds the vertex.  Room for
 * one more local vertex was made. */
static I2M_INLINE int64_t search_vertex(search_t *s, uint32_t v, bool locking)
{
  _Atomic uint32_t *L = &s->vlock[v];
  const uint32_t cur = atomic_load_explicit(L, memory_order_relaxed);
  if ((cur & I2M_DT_OWNER_MASK) == s->owner) return cur >> I2M_DT_OWNER_BITS;
  const uint32_t k = s->nheld, word = s->owner | (k << I2M_DT_OWNER_BITS);
  if (locking) {
    uint32_t expected = 0;
    if (cur != 0 || !atomic_compare_exchange_strong_explicit(L, &expected, word, memory_order_acquire,
                                                             memory_order_relaxed)) {
      s->ctx->conflict_owner = (cur ? cur : expected) & I2M_DT_OWNER_MASK;
      return -1;
    }
  } else {
    atomic_store_explicit(L, word, memory_order_relaxed);
  }
  s->held[k] = v;
  s->nheld = k + 1;
  row_fill(s, s->rows + 4 * (size_t)k, v);
  return k;
}

static inline uint32_t local_owner(const search_t *s, uint32_t v)
{
  return atomic_load_explicit(&s->vlock[v], memory_order_relaxed) & I2M_DT_OWNER_MASK;
}

/* The local number of a vertex the context holds. */
static inline uint32_t local_number(const search_t *s, uint32_t v)
{
  return atomic_load_explicit(&s->vlock[v], memory_order_relaxed) >> I2M_DT_OWNER_BITS;
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
static I2M_NOINLINE int conflict_exact(const search_t *s, const uint32_t l[4])
{
  const double *R = s->rows;
  const double *const r[4] = {R + 4 * l[0], R + 4 * l[1], R + 4 * l[2], R + 4 * l[3]};
  const uint32_t v[4] = {s->held[l[0]], s->held[l[1]], s->held[l[2]], s->held[l[3]]};
  return conflict_decide(s->ctx, r, v, s->p, s->gid);
}

/* Conflict test of a positive tet given by its local numbers: > 0 when p is in its ball. */
static I2M_INLINE int conflict(const search_t *s, const uint32_t l[4])
{
  const double *R = s->rows;
  const double det = i2m_insphere_det_rows(R + 4 * l[0], R + 4 * l[1], R + 4 * l[2], R + 4 * l[3]);
  if (I2M_LIKELY(fabs(det) > s->bound)) return (det > 0.0) - (det < 0.0);
  return conflict_exact(s, l);
}

/* The same for tet c (local numbers cl) with its vertex i replaced by local vertex w: the
 * neighbour across face i, negatively oriented, so < 0 when p is in its ball. */
static I2M_INLINE double det_across(const search_t *s, const uint32_t cl[4], uint32_t i, uint32_t w)
{
  const double *R = s->rows;
  const double *r[4] = {R + 4 * cl[0], R + 4 * cl[1], R + 4 * cl[2], R + 4 * cl[3]};
  r[i] = R + 4 * w;
  return i2m_insphere_det_rows(r[0], r[1], r[2], r[3]);
}

/* The sign of det_across, decided exactly when the cavity's bound does not certify it. */
static I2M_INLINE int sign_across(const search_t *s, const uint32_t cl[4], uint32_t i, uint32_t w, double det)
{
  if (I2M_LIKELY(fabs(det) > s->bound)) return (det > 0.0) - (det < 0.0);
  uint32_t fl[4] = {cl[0], cl[1], cl[2], cl[3]};
  fl[i] = w;
  return conflict_exact(s, fl);
}

/* The sign of det_across for an apex w that has no local number (zone mode: a vertex outside the
 * zone, which may be read but not numbered), from its row computed on the spot. */
static I2M_NOINLINE int conflict_across_unnumbered(search_t *s, const uint32_t cl[4], uint32_t i, uint32_t w)
{
  double row[4];
  row_fill(s, row, w);
  const double *R = s->rows;
  const double *r[4] = {R + 4 * cl[0], R + 4 * cl[1], R + 4 * cl[2], R + 4 * cl[3]};
  r[i] = row;
  const double det = i2m_insphere_det_rows(r[0], r[1], r[2], r[3]);
  if (fabs(det) > s->bound) return (det > 0.0) - (det < 0.0);
  uint32_t v[4] = {s->held[cl[0]], s->held[cl[1]], s->held[cl[2]], s->held[cl[3]]};
  v[i] = w;
  return conflict_decide(s->ctx, r, v, s->p, s->gid);
}

static inline bool row_is_origin(const search_t *s, uint32_t l)
{
  const double *r = s->rows + 4 * (size_t)l;
  return (r[0] == 0.0) & (r[1] == 0.0) & (r[2] == 0.0); /* x - p is exact only for x == p */
}

static I2M_INLINE void boundary_push(search_t *s, uint32_t ki, uint32_t out)
{
  s->bnd[s->nbnd++] = (i2m_dt_bface_t){ki, out};
}

/* The seed t is the first cavity tet (its local numbers are looked up when it is visited);
 * the words of its neighbours, which the search reads first, start loading. */
static I2M_INLINE void cavity_push_seed(search_t *s, uint32_t t)
{
  s->cav[s->ncav++] = t;
  atomic_store_explicit(&s->meta[t], atomic_load_explicit(&s->meta[t], memory_order_relaxed) | I2M_TM_MARK,
                        memory_order_relaxed);
  const uint32_t *tn = s->tn + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) {
    if (tn[i] >= I2M_DT_REMOTE) continue;
    I2M_PREFETCH(&s->meta[tn[i] >> 2]);
    I2M_PREFETCH(s->tv + 4 * (size_t)(tn[i] >> 2));
  }
}

/* What the visits of a cavity tet's four faces read first: the neighbour words n (4u + j),
 * the neighbours' meta and their apexes (vertex j of u, that is tv[n]).  They are read for
 * the four faces together, before any visit branches on a conflict test: the loads then run
 * side by side instead of waiting for each other behind mispredicted branches.  The
 * neighbours' words cannot change meanwhile: each shares three vertices with the cavity tet,
 * which the context holds. */
typedef struct {
  uint32_t n[4], m[4], w[4];
} faces_t;

static I2M_INLINE void faces_read(const search_t *s, uint32_t c, faces_t *f)
{
  memcpy(f->n, s->tn + 4 * (size_t)c, sizeof f->n);
  for (int i = 0; i < 4; i++) {
    const uint32_t n = f->n[i];
    if (I2M_UNLIKELY(n >= I2M_DT_REMOTE)) { /* box hull, or another rank's: nothing to read (another
                                               thread may be rewriting whatever a stand-in index would name) */
      f->m[i] = f->w[i] = 0;
      continue;
    }
    f->m[i] = atomic_load_explicit(&s->meta[n >> 2], memory_order_relaxed);
    f->w[i] = s->tv[n];
  }
}

/* The search visits a cavity tet's four faces in two passes.  The first numbers the apex of
 * every neighbour not yet in the cavity and computes its conflict determinant (zone mode: the
 * sign itself, for an apex outside the zone, which is read but not numbered); the second
 * decides each face: the neighbour joins the cavity when p is in its ball, else the face is a
 * boundary face.  The determinants of the four faces run side by side, none waiting behind
 * the (unpredictable) outcome of another.  The error bound only grows while the first pass
 * numbers apexes, so the bound the second pass compares with covers every row used.  The
 * neighbour is the cavity tet with vertex i replaced by the apex, negatively oriented; the
 * local numbers of all its vertices are looked up once it is visited, if it joins.  Inlined
 * with a constant i. */
static I2M_INLINE i2m_dt_status_t face_measure(search_t *s, const faces_t *f, const uint32_t cl[4], uint32_t i,
                                               bool zoned, bool locking, uint32_t lw[4], double det[4])
{
  if (I2M_UNLIKELY(f->n[i] >= I2M_DT_REMOTE)) /* a face of another rank's: that side cannot be seen */
    return f->n[i] == I2M_DT_REMOTE ? I2M_DT_FROZEN : I2M_DT_OK;
  if (f->m[i] & I2M_TM_MARK) return I2M_DT_OK;
  if (zoned && I2M_UNLIKELY(!zone_holds(s->ctx, f->w[i])) && (local_owner(s, f->w[i]) != s->owner)) {
    /* zone mode: a vertex outside the zone may be read, not numbered; its sign is decided now */
    lw[i] = I2M_DT_NONE;
    det[i] = conflict_across_unnumbered(s, cl, i, f->w[i]);
    return I2M_DT_OK;
  }
  const int64_t l = search_vertex(s, f->w[i], locking);
  if (I2M_UNLIKELY(l < 0)) return I2M_DT_ROLLBACK;
  lw[i] = (uint32_t)l;
  det[i] = det_across(s, cl, i, (uint32_t)l);
  return I2M_DT_OK;
}

/* Zone mode: may tet u, whose apex lies outside the zone, border the cavity (lie in the
 * context's block, if it has one)?  The refill rewrites one of its neighbour words, and a task
 * of the dist layer holds only its block's tets. */
static I2M_INLINE bool outside_fits(const search_t *s, uint32_t u)
{
  const i2m_dt_block_t *b = s->ctx->block;
  return !b || i2m_dt_block_holds(s->ctx->dt, b, u);
}

static I2M_INLINE i2m_dt_status_t face_decide(search_t *s, uint32_t k, const faces_t *f, const uint32_t cl[4],
                                              uint32_t i, uint32_t lw, double det, bool zoned)
{
  const uint32_t n = f->n[i], m = f->m[i];
  if (I2M_UNLIKELY(n == I2M_DT_NONE)) { /* box hull */
    boundary_push(s, k << 2 | i, n);
    return I2M_DT_OK;
  }
  if (m & I2M_TM_MARK) return I2M_DT_OK;
  if (zoned && lw == I2M_DT_NONE) { /* an apex outside the zone: the neighbour must stay outside */
    if (det < 0) {
      s->ctx->conflict_owner = 0;
      return I2M_DT_ROLLBACK;
    }
    if (!outside_fits(s, n >> 2)) return I2M_DT_FROZEN;
    boundary_push(s, k << 2 | i, n);
    return I2M_DT_OK;
  }
  /* p on the apex makes its row zero and the determinant exactly zero: checked only then */
  if (I2M_UNLIKELY(!(fabs(det) > s->bound)) && row_is_origin(s, lw)) return I2M_DT_DUPLICATE;
  const uint32_t join = sign_across(s, cl, i, lw, det) < 0, u = n >> 2;
  if (I2M_UNLIKELY(join & ((m & I2M_TM_FROZEN) != 0))) return I2M_DT_FROZEN;
  /* (a numbered apex lies in the zone: so do u's four vertices, its centroid, and its block) */
  /* Both outcomes are written and the counts advance by the one taken: the outcome is a coin
   * toss for the branch predictor.  Room for one more of each was made (search_room). */
  I2M_PREFETCH_WRITE((const void *)&s->tn[n]); /* a boundary face: the refill links the outside tet back */
  s->bnd[s->nbnd] = (i2m_dt_bface_t){k << 2 | i, n};
  s->nbnd += 1 - join;
  s->cav[s->ncav] = u; /* (the local numbers of its vertices are looked up when it is visited) */
  s->ncav += join;
  atomic_store_explicit(&s->meta[u], m | (join ? I2M_TM_MARK : 0), memory_order_relaxed); /* u is ours: its vertices are held */
  return I2M_DT_OK;
}

static I2M_INLINE i2m_dt_status_t faces_visit(search_t *s, uint32_t k, const faces_t *f, const uint32_t cl[4],
                                              bool zoned, bool locking)
{
  uint32_t lw[4] = {0, 0, 0, 0};
  double det[4] = {0, 0, 0, 0};
  i2m_dt_status_t st;
  if ((st = face_measure(s, f, cl, 0, zoned, locking, lw, det)) != I2M_DT_OK ||
      (st = face_measure(s, f, cl, 1, zoned, locking, lw, det)) != I2M_DT_OK ||
      (st = face_measure(s, f, cl, 2, zoned, locking, lw, det)) != I2M_DT_OK ||
      (st = face_measure(s, f, cl, 3, zoned, locking, lw, det)) != I2M_DT_OK)
    return st;
  if ((st = face_decide(s, k, f, cl, 0, lw[0], det[0], zoned)) != I2M_DT_OK) return st;
  if ((st = face_decide(s, k, f, cl, 1, lw[1], det[1], zoned)) != I2M_DT_OK) return st;
  if ((st = face_decide(s, k, f, cl, 2, lw[2], det[2], zoned)) != I2M_DT_OK) return st;
  return face_decide(s, k, f, cl, 3, lw[3], det[3], zoned);
}

/* Requests the words of the vertices across the faces of cavity tet t (their lock words and
 * coordinates, which the visits read), a tet before they are visited: the neighbours' vertex
 * lists, requested when t joined, have arrived by then. */
static I2M_INLINE void prefetch_apexes(const search_t *s, uint32_t t)
{
  const uint32_t *tn = s->tn + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) {
    if (tn[i] >= I2M_DT_REMOTE) continue;
    const uint32_t w = s->tv[tn[i]]; /* 4u + j: vertex j of neighbour u, its apex */
    I2M_PREFETCH(&s->vlock[w]);
    I2M_PREFETCH(s->xyzw + 4 * (size_t)w);
  }
}

/* The boundary faces found since the last look, shown to the context's accept_face hook (a
 * boundary face stays one: whether a tet is in conflict with p does not depend on the path
 * that reached it).  False when the hook refuses one. */
static I2M_NOINLINE bool faces_accepted(search_t *s)
{
  i2m_dt_ctx_t *ctx = s->ctx;
  search_store(s); /* (the hook reads the context) */
  for (; ctx->nbnd_seen < s->nbnd; ctx->nbnd_seen++)
    if (!ctx->accept_face(ctx->accept_arg, ctx, ctx->nbnd_seen, s->p)) return false;
  return true;
}

/* Breadth-first search of the tets whose circumballs hold p, from the seed (the first cavity
 * tet).  Every vertex met gets a local number (and, when locking, is locked); the outside
 * tets' apexes are numbered too, as the new tets' neighbours will change. */
static I2M_INLINE i2m_dt_status_t cavity_search_in(search_t *s, bool zoned, bool locking)
{
  for (uint32_t k = 0; k < s->ncav; k++) {
    if (!search_room(s, 4)) return I2M_DT_FULL;
    const uint32_t c = s->cav[k], *cv = s->tv + 4 * (size_t)c;
    uint32_t *cl = s->cavl + 4 * (size_t)k; /* all numbered when c joined; kept for the refill */
    for (int x = 0; x < 4; x++) cl[x] = local_number(s, cv[x]);
    faces_t f;
    faces_read(s, c, &f);
    if (k + 1 < s->ncav) prefetch_apexes(s, s->cav[k + 1]);
    const i2m_dt_status_t st = faces_visit(s, k, &f, cl, zoned, locking);
    if (st != I2M_DT_OK) return st;
    if (zoned && I2M_UNLIKELY(s->ctx->accept_face != NULL) && !faces_accepted(s)) return I2M_DT_REFUSED;
  }
  return I2M_DT_OK;
}

/* Three copies, so that neither the zone test (the deterministic mode's) nor the locks cost
 * anything in the runs that do not use them. */
static I2M_NOINLINE i2m_dt_status_t cavity_search_zoned(search_t *s) { return cavity_search_in(s, true, s->ctx->locking); }
static I2M_NOINLINE i2m_dt_status_t cavity_search_locking(search_t *s) { return cavity_search_in(s, false, true); }
static I2M_NOINLINE i2m_dt_status_t cavity_search_free(search_t *s) { return cavity_search_in(s, false, false); }

static i2m_dt_status_t cavity_search(search_t *s)
{
  const i2m_dt_ctx_t *ctx = s->ctx;
  return ctx->zone ? cavity_search_zoned(s) : ctx->locking ? cavity_search_locking(s) : cavity_search_free(s);
}

/* ---- refill ---- */

/* New tet k joins the new vertex p to boundary face k, face i of its cavity tet: it is the
 * cavity tet with vertex i replaced by p, its vertices put in the order (a, b, c, p) by an even
 * permutation (FACE_ORDER[i] then p), so that it stays positive and p is at slot 3 in every
 * new tet: the refill's slot indices are constants.
 *
 * Adjacency.  New tet (a, b, c, p) meets its neighbours through p across its faces 0, 1, 2,
 * that is along the edges (b, c), (c, a), (a, b) of its boundary face.  The boundary faces,
 * seen from p, are consistently oriented, so the neighbour across a face runs the same edge
 * the other way.  A table indexed by directed edges of local numbers therefore links every
 * face: the first pass files each face under its edge, the second reads its partner under
 * the reversed edge.  Every edge read was filed in the same insertion, so the table never
 * needs clearing.  It fits cavities whose vertices have local numbers below EDGE_TABLE_SIDE
 * and up to 16383 boundary faces; larger ones use the hash (ctx_edge_link). */
static const uint8_t FACE_ORDER[4][3] = {{2, 1, 3}, {0, 2, 3}, {1, 0, 3}, {0, 1, 2}};
#define EDGE_TABLE_SIDE 128u

static bool edge_table_ready(i2m_dt_ctx_t *ctx, uint32_t nb)
{
  if (ctx->nheld > EDGE_TABLE_SIDE || nb >= 0x4000u) return false;
  if (!ctx->etab2 && i2m_malloc(EDGE_TABLE_SIDE * EDGE_TABLE_SIDE, sizeof *ctx->etab2, &ctx->etab2) != I2M_OK)
    return false;
  return true;
}

/* The refill's working set, kept in registers like the search's (see search_t). */
typedef struct {
  uint32_t *tv, *tn, *vtet;
  _Atomic uint32_t *meta;
  const uint32_t *cavl, *held, *newt;
  uint16_t *etab2;
} fill_t;

static I2M_INLINE fill_t fill_begin(const i2m_dt_ctx_t *ctx)
{
  i2m_dt_t *dt = ctx->dt;
  return (fill_t){dt->tv, dt->tn, dt->vtet, dt->meta, ctx->cavl, ctx->held, ctx->newt, ctx->etab2};
}

static I2M_INLINE uint16_t *edge_entry(const fill_t *f, uint32_t a, uint32_t b)
{
  return f->etab2 + (a * EDGE_TABLE_SIDE + b);
}

/* The local numbers of new tet k's vertices a, b, c (see FACE_ORDER). */
static I2M_INLINE void face_locals(const fill_t *f, i2m_dt_bface_t b, uint32_t l[3])
{
  const uint32_t *cl = f->cavl + 4 * (size_t)(b.ki >> 2);
  const uint8_t *o = FACE_ORDER[b.ki & 3];
  l[0] = cl[o[0]], l[1] = cl[o[1]], l[2] = cl[o[2]];
}

/* New tet k (its slot newt[k]): vertices, the outside neighbour across face 3, and the
 * incident-tet hints of a, b, c. */
static I2M_INLINE uint32_t fill_tet(const fill_t *f, uint32_t k, i2m_dt_bface_t b, const uint32_t l[3], uint32_t v)
{
  const uint32_t t = f->newt[k];
  const uint32_t m = atomic_load_explicit(&f->meta[t], memory_order_relaxed);
  atomic_store_explicit(&f->meta[t], meta_reborn(m), memory_order_relaxed);
  const uint32_t w[4] = {f->held[l[0]], f->held[l[1]], f->held[l[2]], v};
  memcpy(f->tv + 4 * (size_t)t, w, sizeof w);
  f->tn[4 * (size_t)t + 3] = b.out;
  if (b.out < I2M_DT_REMOTE) f->tn[b.out] = 4 * t + 3;
  f->vtet[w[0]] = f->vtet[w[1]] = f->vtet[w[2]] = t; /* (v's is set once the refill ends) */
  return t;
}

void i2m_dt_cavity_face(const i2m_dt_ctx_t *ctx, uint32_t k, uint32_t abc[3])
{
  const fill_t f = fill_begin(ctx);
  uint32_t l[3];
  face_locals(&f, ctx->bnd[k], l); /* (fill_tet's vertices, in its order) */
  for (int i = 0; i < 3; i++) abc[i] = ctx->held[l[i]];
}

/* First pass: new tet k, its faces 0, 1, 2 filed under the edges (b, c), (c, a), (a, b). */
static I2M_INLINE void fill_direct(const fill_t *f, uint32_t k, i2m_dt_bface_t b, uint32_t v)
{
  uint32_t l[3];
  face_locals(f, b, l);
  fill_tet(f, k, b, l, v);
  *edge_entry(f, l[1], l[2]) = (uint16_t)(k << 2 | 0);
  *edge_entry(f, l[2], l[0]) = (uint16_t)(k << 2 | 1);
  *edge_entry(f, l[0], l[1]) = (uint16_t)(k << 2 | 2);
}

/* Face j of new tet t from the partner filed under the reversed edge (x, y). */
static I2M_INLINE void link_face(const fill_t *f, uint32_t t, uint32_t j, uint32_t x, uint32_t y)
{
  const uint32_t e = *edge_entry(f, x, y);
  f->tn[4 * (size_t)t + j] = 4 * f->newt[e >> 2] + (e & 3);
}

/* Second pass: the faces 0, 1, 2 of new tet k linked. */
static I2M_INLINE void link_direct(const fill_t *f, uint32_t k, i2m_dt_bface_t b)
{
  uint32_t l[3];
  face_locals(f, b, l);
  const uint32_t t = f->newt[k];
  link_face(f, t, 0, l[2], l[1]);
  link_face(f, t, 1, l[0], l[2]);
  link_face(f, t, 2, l[1], l[0]);
}

/* The new tets of a cavity too large for the edge table: adjacency through the hash. */
static I2M_NOINLINE void fill_hashed(i2m_dt_ctx_t *ctx, uint32_t v)
{
  const fill_t f = fill_begin(ctx);
  for (uint32_t k = 0; k < ctx->nbnd; k++) {
    const i2m_dt_bface_t b = ctx->bnd[k];
    uint32_t l[3];
    face_locals(&f, b, l);
    const uint32_t t = fill_tet(&f, k, b, l, v);
    for (uint32_t j = 0; j < 3; j++) ctx_edge_link(ctx, t, 3, j);
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

/* ---- the journal of an insertion (i2m_dt_undo_insert) ---- */

void journal_free(struct i2m_dt_journal **jp)
{
  struct i2m_dt_journal *j = *jp;
  if (!j) return;
  i2m_free(&j->slot);
  i2m_free(&j->tv);
  i2m_free(&j->tn);
  i2m_free(&j->meta);
  i2m_free(&j->pay);
  i2m_free(&j->bnd);
  i2m_free(&j->newt);
  i2m_free(jp);
}

static i2m_err_t journal_room(i2m_dt_ctx_t *ctx, uint32_t nc, uint32_t nb)
{
  if (!ctx->jr) I2M_CALL(i2m_calloc(1, sizeof *ctx->jr, &ctx->jr));
  struct i2m_dt_journal *j = ctx->jr;
  const size_t pay = ctx->dt->pay_size;
  if (nc > j->cap_c) {
    const uint32_t c = nc + nc / 2 + 64;
    I2M_CALL(i2m_realloc(c, sizeof *j->slot, &j->slot));
    I2M_CALL(i2m_realloc(4 * (size_t)c, sizeof *j->tv, &j->tv));
    I2M_CALL(i2m_realloc(4 * (size_t)c, sizeof *j->tn, &j->tn));
    I2M_CALL(i2m_realloc(c, sizeof *j->meta, &j->meta));
    if (pay) I2M_CALL(i2m_realloc((size_t)c * pay, 1, &j->pay));
    j->cap_c = c;
  }
  if (nb > j->cap_b) {
    const uint32_t c = nb + nb / 2 + 64;
    I2M_CALL(i2m_realloc(c, sizeof *j->bnd, &j->bnd));
    I2M_CALL(i2m_realloc(c, sizeof *j->newt, &j->newt));
    j->cap_b = c;
  }
  return I2M_OK;
}

/* Before the refill: the cavity's tets as they are, and the context's slots. */
static void journal_keep(i2m_dt_ctx_t *ctx)
{
  const i2m_dt_t *dt = ctx->dt;
  struct i2m_dt_journal *j = ctx->jr;
  const size_t pay = dt->pay_size;
  j->nc = ctx->ncav;
  j->nb = ctx->nbnd;
  for (uint32_t k = 0; k < j->nc; k++) {
    const uint32_t t = ctx->cav[k];
    j->slot[k] = t;
    memcpy(j->tv + 4 * (size_t)k, dt->tv + 4 * (size_t)t, 4 * sizeof *j->tv);
    memcpy(j->tn + 4 * (size_t)k, dt->tn + 4 * (size_t)t, 4 * sizeof *j->tn);
    j->meta[k] = i2m_dt_meta(dt, t) & ~I2M_TM_MARK; /* (the search marked it) */
    if (pay) memcpy(j->pay + k * pay, dt->tpay + (size_t)t * pay, pay);
  }
  memcpy(j->bnd, ctx->bnd, j->nb * sizeof *j->bnd);
  j->npool = ctx->slots.npool;
  j->fresh_next = ctx->slots.fresh_next;
  j->nvpool = ctx->slots.nvpool;
  j->vfresh_next = ctx->slots.vfresh_next;
}

/* A slot the insertion took, back to where it came from (the context's pool or fresh range,
 * as the saved counts tell), else into the pool. */
static i2m_err_t tet_slot_back(i2m_dt_ctx_t *ctx, const struct i2m_dt_journal *j, uint32_t t)
{
  i2m_dt_slots_t *s = &ctx->slots;
  if (s->fresh_next > j->fresh_next && t == s->fresh_next - 1) {
    s->fresh_next--;
    return I2M_OK;
  }
  if (s->npool < j->npool && s->pool[s->npool] == t) {
    s->npool++;
    return I2M_OK;
  }
  return ctx_pool_push(ctx, t);
}

static i2m_err_t vertex_slot_back(i2m_dt_ctx_t *ctx, const struct i2m_dt_journal *j, uint32_t v)
{
  i2m_dt_slots_t *s = &ctx->slots;
  if (s->vfresh_next == j->vfresh_next + 1 && v == j->vfresh_next) {
    s->vfresh_next--;
    return I2M_OK;
  }
  if (s->nvpool + 1 == j->nvpool && s->vpool[s->nvpool] == v) {
    s->nvpool++;
    return I2M_OK;
  }
  return ctx_vpool_push(ctx, v);
}

i2m_err_t i2m_dt_undo_insert(i2m_dt_ctx_t *ctx)
{
  struct i2m_dt_journal *j = ctx->jr;
  I2M_CHECK(j && j->valid && !ctx->locking, I2M_ERR_INTERNAL, "i2m_dt_undo_insert: no journaled insertion to undo");
  i2m_dt_t *dt = ctx->dt;
  const size_t pay = dt->pay_size;
  const uint32_t reused = j->nb < j->nc ? j->nb : j->nc;
  j->valid = false;
  for (uint32_t k = j->nb; k-- > reused;) { /* new tets beyond the cavity's slots: dead again */
    const uint32_t t = j->newt[k];
    meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
    I2M_CALL(tet_slot_back(ctx, j, t));
  }
  if (j->nc > j->nb) { /* the cavity's slots left over went onto the pool: taken back */
    I2M_CHECK(ctx->slots.npool >= j->nc - j->nb && ctx->slots.pool[ctx->slots.npool - 1] == j->slot[j->nc - 1],
              I2M_ERR_INTERNAL, "i2m_dt_undo_insert: the pool changed since the insertion");
    ctx->slots.npool -= j->nc - j->nb;
  }
  for (uint32_t k = 0; k < j->nc; k++) { /* the cavity's tets, as they were */
    const uint32_t t = j->slot[k];
    memcpy(dt->tv + 4 * (size_t)t, j->tv + 4 * (size_t)k, 4 * sizeof *j->tv);
    memcpy(dt->tn + 4 * (size_t)t, j->tn + 4 * (size_t)k, 4 * sizeof *j->tn);
    if (pay) memcpy(dt->tpay + (size_t)t * pay, j->pay + k * pay, pay);
    meta_store(dt, t, j->meta[k]);
  }
  for (uint32_t k = 0; k < j->nb; k++) { /* the tets outside see them again */
    const i2m_dt_bface_t b = j->bnd[k];
    if (b.out < I2M_DT_REMOTE) dt->tn[b.out] = 4 * j->slot[b.ki >> 2] + (b.ki & 3);
  }
  for (uint32_t k = 0; k < j->nc; k++)
    for (int i = 0; i < 4; i++) dt->vtet[j->tv[4 * (size_t)k + i]] = j->slot[k];
  dt->vkind[j->v] = I2M_VK_DEAD;
  I2M_CALL(vertex_slot_back(ctx, j, j->v));
  ctx->nnew = 0;
  ctx->n_insert--;
  ctx->n_created -= j->nb;
  ctx->n_killed -= j->nc;
  return I2M_OK;
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
  if (ctx->journal) {
    if (journal_room(ctx, nc, nb) != I2M_OK) return I2M_DT_FULL;
    journal_keep(ctx);
  }
  const uint32_t v = new_vertex(ctx, p, gid, kind);
  if (v == I2M_DT_NONE) return I2M_DT_FULL;
  const uint32_t reused = nb < nc ? nb : nc;
  memcpy(ctx->newt, ctx->cav, reused * sizeof *ctx->newt);
  for (uint32_t k = reused; k < nb; k++) ctx->newt[k] = ctx_tet_slot(ctx);
  ctx->nnew = nb;
  if (direct) {
    const fill_t f = fill_begin(ctx);
    const i2m_dt_bface_t *bnd = ctx->bnd;
    for (uint32_t k = 0; k < nb; k++) fill_direct(&f, k, bnd[k], v);
    for (uint32_t k = 0; k < nb; k++) link_direct(&f, k, bnd[k]);
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
  if (ctx->journal) {
    memcpy(ctx->jr->newt, ctx->newt, nb * sizeof *ctx->newt);
    ctx->jr->v = v;
    ctx->jr->valid = true;
  }
  *vout = v;
  return I2M_DT_OK;
}

/* Numbers and locks the seed's vertices (threaded: read before the locks, verified after)
 * and checks the seed: alive, unchanged, not frozen, p not one of its vertices, p in its
 * ball.  Then it is the first cavity tet. */
static i2m_dt_status_t cavity_seed(search_t *s, uint32_t seed, uint32_t seed_meta)
{
  i2m_dt_ctx_t *ctx = s->ctx;
  i2m_dt_t *dt = ctx->dt;
  const uint32_t *sv = dt->tv + 4 * (size_t)seed;
  uint32_t v4[4], l4[4];
  memcpy(v4, sv, sizeof v4);
  if (ctx->zone && !(zone_holds(ctx, v4[0]) && zone_holds(ctx, v4[1]) && zone_holds(ctx, v4[2]) && zone_holds(ctx, v4[3]))) {
    ctx->conflict_owner = 0;
    return I2M_DT_ROLLBACK;
  }
  if (!search_room(s, 4)) return I2M_DT_FULL;
  for (int i = 0; i < 4; i++) {
    int64_t l = search_vertex(s, v4[i], ctx->locking);
    if (l < 0) return I2M_DT_ROLLBACK;
    l4[i] = (uint32_t)l;
  }
  if (ctx->locking && memcmp(v4, sv, sizeof v4) != 0) return I2M_DT_STALE;
  uint32_t m = i2m_dt_meta(dt, seed);
  if ((m & I2M_TM_DEAD) || (seed_meta != I2M_DT_NONE && m != seed_meta)) return I2M_DT_STALE;
  if (m & I2M_TM_FROZEN) return I2M_DT_FROZEN;
  for (int i = 0; i < 4; i++)
    if (row_is_origin(s, l4[i])) return I2M_DT_DUPLICATE;
  if (conflict(s, l4) <= 0) return I2M_DT_NOT_IN_CONFLICT;
  cavity_push_seed(s, seed);
  return I2M_DT_OK;
}

i2m_dt_status_t i2m_dt_insert(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                              uint32_t seed, uint32_t seed_meta, uint32_t *vout)
{
  I2M_CHECK_ABORT(ctx->locking || ctx->nheld == 0, "i2m_dt_insert: the previous operation's vertices are still held");
  ctx->ncav = ctx->nbnd = ctx->nnew = 0;
  journal_forget(ctx);
  double snapped[3];
  p = i2m_dt_snap(ctx->dt, p, snapped);
  if (ctx->zone && !i2m_box_holds(ctx->zone, p)) {
    ctx->conflict_owner = 0;
    return cavity_abandon(ctx, I2M_DT_ROLLBACK);
  }
  search_t s;
  search_begin(&s, ctx, p, gid);
  ctx->nbnd_seen = 0;
  for (uint32_t k = 0; k < s.nheld; k++) row_fill(&s, s.rows + 4 * (size_t)k, s.held[k]); /* locked before */
  i2m_dt_status_t st = cavity_seed(&s, seed, seed_meta);
  if (st == I2M_DT_OK) st = cavity_search(&s);
  search_store(&s);
  if (st == I2M_DT_OK && ctx->accept && !ctx->accept(ctx->accept_arg, ctx, p)) st = I2M_DT_REFUSED;
  if (st == I2M_DT_OK) st = cavity_fill(ctx, p, gid, kind, vout);
  if (st != I2M_DT_OK) return cavity_abandon(ctx, st);
  ctx->ncav = ctx->nbnd = 0;
  if (!ctx->locking) i2m_dt_unlock_all(ctx); /* sequential: only the local numbering to undo */
  return I2M_DT_OK;
}

/* ---- point location ---- */

static inline uint32_t rng_next(uint64_t *state) { return (uint32_t)(i2m_xorshift64(state) >> 32); }

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

/* The first of the faces in mask (bit i: face i) in the order r, r + 1, ... (mod 4), or 4
 * when the mask is empty; from a table, without branches. */
static inline uint32_t first_face_from(uint32_t mask, uint32_t r)
{
  static const uint8_t LOWEST[16] = {4, 0, 1, 0, 2, 0, 1, 0, 3, 0, 1, 0, 2, 0, 1, 0};
  r &= 3;
  const uint32_t rotated = ((mask >> r) | (mask << (4 - r))) & 15;
  return rotated ? (LOWEST[rotated] + r) & 3 : 4;
}

/* One step of the walk decided face by face, exactly where the floating-point sign is not
 * certain: the neighbour word of the first face in the order r, r + 1, ... that p lies beyond
 * (I2M_DT_REMOTE: another rank's), or I2M_DT_NONE when p is in t. */
static I2M_NOINLINE uint32_t walk_step_exact(const i2m_dt_t *dt, uint32_t t, uint32_t prev, const double *p,
                                             const double o[4], double bound, uint32_t r)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (uint32_t k = 0; k < 4; k++) {
    uint32_t i = (r + k) & 3;
    uint32_t n = dt->tn[4 * t + i];
    if (n == I2M_DT_NONE || (n >> 2) == prev) continue;
    if (beyond_face(dt, v, i, p, o[i], bound)) return n;
  }
  return I2M_DT_NONE;
}

/* The walk moves through a face p lies beyond, chosen at random among them (so that it cannot
 * cycle), never back to the tet it came from.  The choice is made from bit masks: which face
 * it takes is a coin toss for a branch predictor. */
uint32_t i2m_dt_locate(i2m_dt_ctx_t *ctx, const double p[3], uint32_t start)
{
  const i2m_dt_t *dt = ctx->dt;
  uint32_t t = start, prev = I2M_DT_NONE;
  double snapped[3];
  p = i2m_dt_snap(dt, p, snapped);
  uint64_t rng = walk_seed(p);
  for (;;) {
    const uint32_t *v = dt->tv + 4 * (size_t)t, *tn = dt->tn + 4 * (size_t)t;
    double o[4], bound;
    face_orients(dt, v, p, o, &bound);
    const uint32_t r = rng_next(&rng);
    uint32_t open = 0, beyond = 0, unsure = 0;
    for (uint32_t i = 0; i < 4; i++) {
      open |= (uint32_t)((tn[i] != I2M_DT_NONE) & ((tn[i] >> 2) != prev)) << i;
      beyond |= (uint32_t)(o[i] < -bound) << i;
      unsure |= (uint32_t)(fabs(o[i]) <= bound) << i;
    }
    uint32_t word; /* the neighbour across the face taken */
    if (I2M_LIKELY(!(unsure & open))) {
      const uint32_t i = first_face_from(beyond & open, r);
      word = i < 4 ? tn[i] : I2M_DT_NONE;
    } else {
      word = walk_step_exact(dt, t, prev, p, o, bound, r);
    }
    ctx->n_walk_steps++;
    if (word == I2M_DT_NONE) return t;
    /* a task holds its block only (another rank's side, or beyond the block here: the same) */
    if (word == I2M_DT_REMOTE || (ctx->block && !i2m_dt_block_holds(dt, ctx->block, word >> 2))) return I2M_DT_NONE;
    prev = t;
    t = word >> 2;
  }
}

i2m_dt_status_t i2m_dt_insert_walk(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                                   uint32_t start, uint32_t *vout)
{
  uint32_t t = i2m_dt_locate(ctx, p, start);
  if (t == I2M_DT_NONE) return I2M_DT_FROZEN;
  return i2m_dt_insert(ctx, p, gid, kind, t, I2M_DT_NONE, vout);
}
