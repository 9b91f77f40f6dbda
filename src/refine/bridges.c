/* Refine layer: the component rule (R8).  A large image component of one label must come
 * out as one piece of tets.  Where a thin neck of it is narrower than the tets around it,
 * their circumcentres fall in the neighbouring labels and the mesh can split it (the knee's
 * labels 41 and 48, one component of about 10,000 voxels each, came out as 2-3 pieces on
 * every run; label 35 on some).  For each piece of a split component but its largest, a
 * 0-1 breadth-first search over the component's voxels finds the path to another of its
 * pieces that crosses the fewest voxels whose centre lies in a tet of another label (the gap
 * voxels); a free vertex is inserted at the centre of each gap voxel, and refinement goes on
 * with every rule.  Bridge vertices are never removed by R7 (they are not in its grid): a
 * voxel centre lies at least half a voxel from every interface, so they keep a minimum
 * distance from the surface vertices and refinement still terminates.  The threads layer
 * alternates this rule and refinement until no component is split (or a few rounds).
 *
 * A voxel's tet is found by a walk from the tet of the voxel it was reached from (voxels next
 * to each other: a step or two).  Everything runs on worker 0, alone; the search and the
 * insertions follow the pieces' and the voxels' order, so the result does not depend on the
 * number of threads. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

/* A visited voxel: its box index (key), the voxel it was reached from, its tet, its class. */
typedef struct {
  int64_t key; /* -1: empty slot */
  int64_t from;
  uint32_t tet;
  int8_t cls; /* CLS_* */
} visit_t;

enum { CLS_OWN = 0, CLS_GAP = 1, CLS_GOAL = 2 };

typedef struct {
  visit_t *slot;
  size_t cap, n;
} visits_t;

static size_t visit_hash(int64_t key, size_t cap) { return (size_t)(((uint64_t)key * 0x9E3779B97F4A7C15ull) >> 20) & (cap - 1); }

static i2m_err_t visits_grow(visits_t *V)
{
  const size_t cap = V->cap ? 2 * V->cap : 1024;
  visit_t *s = NULL;
  I2M_CALL(i2m_malloc(cap, sizeof *s, &s));
  for (size_t i = 0; i < cap; i++) s[i].key = -1;
  for (size_t i = 0; i < V->cap; i++) {
    if (V->slot[i].key < 0) continue;
    size_t h = visit_hash(V->slot[i].key, cap);
    while (s[h].key >= 0) h = (h + 1) & (cap - 1);
    s[h] = V->slot[i];
  }
  i2m_free(&V->slot);
  V->slot = s;
  V->cap = cap;
  return I2M_OK;
}

/* The visit of voxel key, or NULL. */
static visit_t *visits_find(const visits_t *V, int64_t key)
{
  if (!V->cap) return NULL;
  for (size_t h = visit_hash(key, V->cap);; h = (h + 1) & (V->cap - 1)) {
    if (V->slot[h].key == key) return &V->slot[h];
    if (V->slot[h].key < 0) return NULL;
  }
}

static i2m_err_t visits_add(visits_t *V, visit_t v)
{
  if (2 * (V->n + 1) > V->cap) I2M_CALL(visits_grow(V));
  size_t h = visit_hash(v.key, V->cap);
  while (V->slot[h].key >= 0) h = (h + 1) & (V->cap - 1);
  V->slot[h] = v;
  V->n++;
  return I2M_OK;
}

/* A double-ended queue of voxel keys (0-1 breadth-first search). */
typedef struct {
  int64_t *a;
  size_t cap, head, n;
} deque_t;

static i2m_err_t deque_grow(deque_t *q)
{
  const size_t cap = q->cap ? 2 * q->cap : 1024;
  int64_t *a = NULL;
  I2M_CALL(i2m_malloc(cap, sizeof *a, &a));
  for (size_t i = 0; i < q->n; i++) a[i] = q->a[(q->head + i) % q->cap];
  i2m_free(&q->a);
  q->a = a;
  q->cap = cap;
  q->head = 0;
  return I2M_OK;
}

static i2m_err_t deque_push(deque_t *q, int64_t x, bool front)
{
  if (q->n == q->cap) I2M_CALL(deque_grow(q));
  if (front) {
    q->head = (q->head + q->cap - 1) % q->cap;
    q->a[q->head] = x;
  } else {
    q->a[(q->head + q->n) % q->cap] = x;
  }
  q->n++;
  return I2M_OK;
}

static int64_t deque_pop(deque_t *q)
{
  const int64_t x = q->a[q->head];
  q->head = (q->head + 1) % q->cap;
  q->n--;
  return x;
}

/* ---- voxels ---- */

/* The world centre of box voxel key. */
static void voxel_centre(const i2m_edt_t *e, int64_t key, double w[3])
{
  const int64_t i = key % e->m[0], j = key / e->m[0] % e->m[1], k = key / e->m[0] / e->m[1];
  const double u[3] = {(double)i + 0.5, (double)j + 0.5, (double)k + 0.5};
  for (int a = 0; a < 3; a++) w[a] = e->k2w[a][0] * u[0] + e->k2w[a][1] * u[1] + e->k2w[a][2] * u[2] + e->k2w[a][3];
}

static bool voxel_in_component(const i2m_refine_t *r, int64_t key, int64_t comp)
{
  const i2m_edt_t *e = r->edt;
  const int64_t i = e->lo[0] + key % e->m[0], j = e->lo[1] + key / e->m[0] % e->m[1], k = e->lo[2] + key / e->m[0] / e->m[1];
  return i2m_components_find(&r->pieces_ic, i, j, k) == comp;
}

typedef struct {
  i2m_refine_t *r;
  const pieces_t *P;
  const split_t *s;
  uint32_t own;     /* the piece (index) the search starts from */
  visits_t V;
  deque_t q;
} search_t;

/* The class of a voxel whose centre lies in tet t. */
static int8_t voxel_class(const search_t *S, uint32_t t)
{
  const i2m_dt_t *dt = S->r->dt;
  if (!tet_kept(dt, t) || tinfo(dt, t)->label != S->s->label) return CLS_GAP;
  const uint32_t pi = pieces_index(S->P, t);
  if (pi == S->own) return CLS_OWN;
  for (uint32_t k = 0; k < S->s->npieces; k++)
    if (S->s->pieces[k] == pi) return CLS_GOAL;
  return CLS_GAP; /* a fragment: it joins nothing */
}

/* Visits voxel key reached from `from` (its tet: start), unless seen; queued by its cost. */
static i2m_err_t visit(search_t *S, int64_t key, int64_t from, uint32_t start)
{
  if (visits_find(&S->V, key)) return I2M_OK;
  double w[3];
  voxel_centre(S->r->edt, key, w);
  const uint32_t t = i2m_dt_locate(&S->r->workers[0].ctx, w, start);
  const visit_t v = {key, from, t, voxel_class(S, t)};
  I2M_CALL(visits_add(&S->V, v));
  return deque_push(&S->q, key, v.cls != CLS_GAP);
}

/* The 0-1 search from piece own's first voxel; *goal is the first voxel reached in another
 * piece of the component (-1: none). */
static i2m_err_t search_bridge(search_t *S, uint32_t seed_tet, int64_t *goal)
{
  const i2m_edt_t *e = S->r->edt;
  *goal = -1;
  tet_geom_t g;
  tet_centre(S->r, seed_tet, &g);
  const int64_t start = i2m_edt_voxel_k(e, g.u);
  if (start < 0 || !voxel_in_component(S->r, start, S->s->comp)) return I2M_OK;
  I2M_CALL(visit(S, start, -1, seed_tet));
  const int64_t step[3] = {1, e->m[0], e->m[0] * e->m[1]};
  while (S->q.n) {
    const int64_t key = deque_pop(&S->q);
    const visit_t *v = visits_find(&S->V, key);
    if (v->cls == CLS_GOAL) {
      *goal = key;
      return I2M_OK;
    }
    const uint32_t tet = v->tet;
    const int64_t c[3] = {key % e->m[0], key / e->m[0] % e->m[1], key / e->m[0] / e->m[1]};
    for (int a = 0; a < 3; a++)
      for (int d = -1; d <= 1; d += 2) {
        if (c[a] + d < 0 || c[a] + d >= e->m[a]) continue;
        const int64_t nk = key + d * step[a];
        if (voxel_in_component(S->r, nk, S->s->comp)) I2M_CALL(visit(S, nk, key, tet));
      }
  }
  return I2M_OK;
}

/* ---- the rule ---- */

/* A tet of piece pi whose circumcentre lies in the component (the search starts there): one
 * of those the census looked at, or its root. */
static uint32_t seed_of(const i2m_refine_t *r, const pieces_t *P, uint32_t pi, int64_t comp)
{
  const uint32_t n = i2m_dt_ntets_slots(r->dt), root = P->piece[pi].root;
  for (uint32_t t = root; t < n; t++)
    if (tet_kept(r->dt, t) && pieces_index(P, t) == pi && atomic_load_explicit(&P->cnt[t], memory_order_relaxed) == (uint64_t)comp)
      return t;
  return root;
}

/* Tets of each piece of the split (the largest stays as it is). */
static i2m_err_t piece_sizes(const i2m_refine_t *r, const pieces_t *P, const split_t *s, int64_t *size)
{
  const uint32_t n = i2m_dt_ntets_slots(r->dt);
  for (uint32_t k = 0; k < s->npieces; k++) size[k] = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(r->dt, t) || tinfo(r->dt, t)->label != s->label) continue;
    const uint32_t pi = pieces_index(P, t);
    for (uint32_t k = 0; k < s->npieces; k++)
      if (s->pieces[k] == pi) size[k]++;
  }
  return I2M_OK;
}

/* A bridge point: the centre of voxel a (b < 0), or the centre of the face between voxels a
 * and b. */
typedef struct {
  int64_t a, b;
} point_t;

static i2m_err_t bridge_room(point_t **p, size_t *n, size_t *cap, size_t more)
{
  if (*n + more <= *cap) return I2M_OK;
  *cap = 2 * *cap + 64;
  return i2m_realloc(*cap, sizeof **p, p);
}

/* Inserts a free vertex at bridge point b (not R7's to remove); the new tets are classified
 * and queued by worker 0.  *hint: a live tet to walk from. */
static i2m_err_t insert_bridge(i2m_refine_t *r, point_t b, uint32_t *hint, int64_t *inserted)
{
  i2m_refine_worker_t *w = &r->workers[0];
  double p[3];
  voxel_centre(r->edt, b.a, p);
  if (b.b >= 0) {
    double q[3];
    voxel_centre(r->edt, b.b, q);
    for (int a = 0; a < 3; a++) p[a] = 0.5 * (p[a] + q[a]);
  }
  if (!i2m_dt_alive(r->dt, *hint)) *hint = w->ctx.newt && w->ctx.nnew ? w->ctx.newt[0] : 0;
  while (!i2m_dt_alive(r->dt, *hint)) (*hint)++; /* (some tet is alive) */
  if (w->gid_next == w->gid_end) {
    w->gid_next = atomic_fetch_add_explicit(&r->next_gid, 1024, memory_order_relaxed);
    w->gid_end = w->gid_next + 1024;
  }
  uint32_t v;
  i2m_dt_status_t st = i2m_dt_insert_walk(&w->ctx, p, w->gid_next, I2M_VK_FREE, *hint, &v);
  while (st == I2M_DT_FULL) {
    i2m_dt_unlock_all(&w->ctx);
    I2M_CALL(i2m_refine_grow(r));
    st = i2m_dt_insert_walk(&w->ctx, p, w->gid_next, I2M_VK_FREE, *hint, &v);
  }
  if (st != I2M_DT_OK) { /* (a vertex there already) */
    i2m_dt_unlock_all(&w->ctx);
    return I2M_OK;
  }
  w->gid_next++;
  w->st.insertions++;
  w->st.bridges++;
  (*inserted)++;
  i2m_err_t err = I2M_OK;
  uint32_t n = w->ctx.nnew;
  uint32_t *created = NULL;
  I2M_CALL(i2m_malloc(n, sizeof *created, &created));
  memcpy(created, w->ctx.newt, n * sizeof *created);
  err = worker_process_created(w, created, n);
  i2m_dt_unlock_all(&w->ctx);
  *hint = created[0];
  i2m_free(&created);
  return err;
}

/* Bridges every piece of split s but the largest to another piece of it. */
static i2m_err_t bridge_split(i2m_refine_t *r, const pieces_t *P, const split_t *s, int64_t *inserted)
{
  int64_t *size = NULL;
  point_t *bridge = NULL;
  size_t nb = 0, cap = 0;
  search_t S = {r, P, s, 0, {NULL, 0, 0}, {NULL, 0, 0, 0}};
  i2m_err_t err = I2M_OK;
  I2M_CALL(i2m_malloc(s->npieces, sizeof *size, &size));
  I2M_CALL_GOTO(err, done, piece_sizes(r, P, s, size));
  uint32_t largest = 0;
  for (uint32_t k = 1; k < s->npieces; k++)
    if (size[k] > size[largest]) largest = k;
  for (uint32_t k = 0; k < s->npieces; k++) {
    if (k == largest) continue;
    S.own = s->pieces[k];
    S.V.n = 0;
    for (size_t i = 0; i < S.V.cap; i++) S.V.slot[i].key = -1;
    S.q.n = S.q.head = 0;
    int64_t goal;
    I2M_CALL_GOTO(err, done, search_bridge(&S, seed_of(r, P, s->pieces[k], s->comp), &goal));
    int64_t gaps = 0;
    for (int64_t x = goal; x >= 0;) { /* back along the path: its gap voxels, and its steps between classes */
      const visit_t *v = visits_find(&S.V, x);
      const visit_t *u = v->from >= 0 ? visits_find(&S.V, v->from) : NULL;
      I2M_CALL_GOTO(err, done, bridge_room(&bridge, &nb, &cap, 2));
      if (v->cls == CLS_GAP) {
        bridge[nb++] = (point_t){x, -1};
        gaps++;
      }
      /* pieces that meet only at an edge or a vertex: the voxel centres on either side lie in
       * label-L tets, and the voxel face between them is where they must be joined */
      if (u && u->cls != v->cls) bridge[nb++] = (point_t){x, v->from};
      x = v->from;
    }
    i2m_debug("bridges: label %lld, piece of %lld tets: %s, %lld gap voxels (%zu voxels searched)",
              (long long)r->img->label_value[s->label], (long long)size[k], goal >= 0 ? "bridged" : "no path",
              (long long)gaps, S.V.n);
  }
  uint32_t hint = P->piece[s->pieces[largest]].root;
  for (size_t i = 0; i < nb; i++) I2M_CALL_GOTO(err, done, insert_bridge(r, bridge[i], &hint, inserted));
done:
  i2m_free(&size);
  i2m_free(&bridge);
  i2m_free(&S.V.slot);
  i2m_free(&S.q.a);
  return err;
}

i2m_err_t i2m_refine_bridge_splits(i2m_refine_t *r, int64_t min_voxels, int64_t *splits, int64_t *inserted)
{
  const pieces_t *P;
  split_t *sp = NULL;
  size_t ns = 0;
  *splits = *inserted = 0;
  I2M_CALL(pieces_get(r, &P));
  i2m_err_t err = pieces_splits(r, P, min_voxels, &sp, &ns);
  for (size_t i = 0; i < ns && err == I2M_OK; i++) err = bridge_split(r, P, &sp[i], inserted);
  *splits = (int64_t)ns;
  r->bridge_rounds += ns > 0;
  splits_free(&sp, ns);
  if (*inserted || err != I2M_OK) pieces_invalidate(r); /* (the mesh changed) */
  return err;
}
