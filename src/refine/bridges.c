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
 * distance from the surface vertices and refinement still terminates.  The threads layer (or
 * the dist layer) alternates this rule and refinement until no component is split (or a few
 * rounds).
 *
 * It works in three steps, so that ranks that each hold part of the mesh do it alike:
 *   claims  each process says, for every voxel of a split component whose centre lies in one
 *           of its tets, which piece of the split holds it (or a gap): a pass over its tets;
 *   points  the search over the claims of every rank (pure, on one process);
 *   insert  one process inserts them at once (worker 0, in order); ranks file each point as
 *           work of the task of the cell that holds it (tiles.c inserts it there).
 * The points' global ids are fixed by the round and their order, and the triangulation of a
 * set of points with their ids is unique (symbolic perturbation), so the mesh after a round's
 * insertions does not depend on who inserted what, nor in which order. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#include "i2m/predicates.h"

#define BRIDGE_GID_BASE ((i2m_gidx_t)14 << 52) /* (the tilings' ranges: below 14 << 52 and from 15 << 52) */
#define BRIDGE_GID_ROUND_SHIFT 40

/* ---- voxels of the transform's box ---- */

/* The mesh-frame centre of box voxel key. */
static void voxel_centre(const i2m_edt_t *e, int64_t key, double w[3])
{
  const int64_t i = key % e->m[0], j = key / e->m[0] % e->m[1], k = key / e->m[0] / e->m[1];
  const double u[3] = {(double)i + 0.5, (double)j + 0.5, (double)k + 0.5};
  for (int a = 0; a < 3; a++) w[a] = e->k2w[a][0] * u[0] + e->k2w[a][1] * u[1] + e->k2w[a][2] * u[2] + e->k2w[a][3];
}

static bool box_voxel_in_component(const i2m_refine_t *r, int64_t i, int64_t j, int64_t k, int64_t comp)
{
  const i2m_edt_t *e = r->edt;
  return i2m_components_find(&r->pieces_ic, e->lo[0] + i, e->lo[1] + j, e->lo[2] + k) == comp;
}

/* The box-voxel bounds of a component (from its runs). */
static void component_box(const i2m_refine_t *r, int64_t comp, int64_t lo[3], int64_t hi[3])
{
  const i2m_components_t *ic = &r->pieces_ic;
  const i2m_edt_t *e = r->edt;
  for (int a = 0; a < 3; a++) {
    lo[a] = INT64_MAX;
    hi[a] = INT64_MIN;
  }
  for (int64_t row = 0; row < ic->n[1] * ic->n[2]; row++)
    for (int64_t run = ic->row[row]; run < ic->row[row + 1]; run++) {
      if (ic->par[run] != comp) continue;
      const int64_t x[3][2] = {{ic->x0[run], ic->x0[run] + ic->len[run] - 1}, {row % ic->n[1], row % ic->n[1]},
                               {row / ic->n[1], row / ic->n[1]}};
      for (int a = 0; a < 3; a++) {
        lo[a] = x[a][0] + ic->lo[a] - e->lo[a] < lo[a] ? x[a][0] + ic->lo[a] - e->lo[a] : lo[a];
        hi[a] = x[a][1] + ic->lo[a] - e->lo[a] > hi[a] ? x[a][1] + ic->lo[a] - e->lo[a] : hi[a];
      }
    }
}

/* ---- claims ---- */

typedef struct {
  i2m_voxel_claim_t *c;
  size_t n, cap;
} claims_t;

static i2m_err_t claim(claims_t *C, int64_t voxel, int32_t split, int32_t cls)
{
  if (C->n == C->cap) {
    C->cap = C->cap ? 2 * C->cap : 4096;
    I2M_CALL(i2m_realloc(C->cap, sizeof *C->c, &C->c));
  }
  C->c[C->n++] = (i2m_voxel_claim_t){voxel, split, cls};
  return I2M_OK;
}

/* Does tet t (vertices a) hold point p (inside or on its boundary)? */
static bool tet_holds(const double *a[4], const double p[3])
{
  const int s = i2m_orient3d(a[0], a[1], a[2], a[3]);
  if (s == 0) return false; /* (a flat tet holds no volume) */
  for (int i = 0; i < 4; i++) {
    const double *b[4] = {a[0], a[1], a[2], a[3]};
    b[i] = p;
    const int o = i2m_orient3d(b[0], b[1], b[2], b[3]);
    if (o != 0 && o != s) return false;
  }
  return true;
}

/* The class of the voxels in tet t for split si (gpos: each group's place in its split). */
static int32_t tet_class(const i2m_refine_t *r, const i2m_pieces_global_t *G, const int32_t *gsplit,
                         const int32_t *gpos, int32_t si, uint32_t t)
{
  if (!tet_kept(r->dt, t) || tinfo(r->dt, t)->label != G->split[si].label) return I2M_CLAIM_GAP;
  const int64_t g = G->part_group[pieces_index(&r->pieces, t)];
  return gsplit[g] == si ? gpos[g] : I2M_CLAIM_GAP; /* (another piece: a fragment, it joins nothing) */
}

/* A vertex's place against a box of voxel centres, per axis (Cohen-Sutherland outcodes): bit
 * 2a when its voxel coordinate u[a] lies below the box's first centre, bit 2a+1 when above
 * its last; u itself into u. */
static uint8_t vertex_outcode(const i2m_edt_t *e, const double x[3], const int64_t lo[3], const int64_t hi[3], double u[3])
{
  uint8_t code = 0;
  for (int a = 0; a < 3; a++) {
    u[a] = e->w2k[a][0] * x[0] + e->w2k[a][1] * x[1] + e->w2k[a][2] * x[2] + e->w2k[a][3];
    code |= (uint8_t)((u[a] - 0.5 + 1e-9 < (double)lo[a]) << 2 * a | (u[a] - 0.5 - 1e-9 > (double)hi[a]) << (2 * a + 1));
  }
  return code;
}

/* The claims of split si's voxels by the local tets.  A first pass gives every vertex its
 * outcode against the component's box, so that the tets wholly on one side of it (nearly all)
 * cost four loads. */
static i2m_err_t claim_split(const i2m_refine_t *r, const i2m_pieces_global_t *G, const int32_t *gsplit,
                             const int32_t *gpos, int32_t si, claims_t *C, i2m_progress_t *pg)
{
  const i2m_dt_t *dt = r->dt;
  const i2m_edt_t *e = r->edt;
  int64_t lo[3], hi[3];
  component_box(r, G->split[si].comp, lo, hi);
  const uint32_t nv = i2m_dt_nverts_slots(dt), n = i2m_dt_ntets_slots(dt);
  uint8_t *code = NULL;
  I2M_CALL(i2m_malloc(nv ? nv : 1, sizeof *code, &code));
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t v = 0; v < (int64_t)nv; v++) {
    double u[3];
    code[v] = vertex_outcode(e, i2m_dt_xyz(dt, (uint32_t)v), lo, hi, u);
  }
  i2m_err_t err = I2M_OK;
  for (uint32_t t = 0; t < n && err == I2M_OK; t++) {
    if ((t & 65535) == 65535) i2m_progress_update(pg, (int64_t)si * n + t);
    if (!i2m_dt_alive(dt, t)) continue;
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    if (code[v[0]] & code[v[1]] & code[v[2]] & code[v[3]]) continue; /* wholly beyond one side of the box */
    const double *x[4];
    double umin[3] = {INFINITY, INFINITY, INFINITY}, umax[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < 4; i++) {
      double u[3];
      x[i] = i2m_dt_xyz(dt, v[i]);
      vertex_outcode(e, x[i], lo, hi, u);
      for (int a = 0; a < 3; a++) {
        umin[a] = fmin(umin[a], u[a]);
        umax[a] = fmax(umax[a], u[a]);
      }
    }
    int64_t b0[3], b1[3]; /* the voxels whose centres (index + 1/2) the tet's box holds, in the component's box */
    bool empty = false;
    for (int a = 0; a < 3; a++) {
      const double f0 = ceil(umin[a] - 0.5 - 1e-9), f1 = floor(umax[a] - 0.5 + 1e-9);
      b0[a] = f0 > (double)lo[a] ? (int64_t)f0 : lo[a];
      b1[a] = f1 < (double)hi[a] ? (int64_t)f1 : hi[a];
      empty |= b0[a] > b1[a];
    }
    if (empty) continue;
    const int32_t cls = tet_class(r, G, gsplit, gpos, si, t);
    for (int64_t k = b0[2]; k <= b1[2] && err == I2M_OK; k++)
      for (int64_t j = b0[1]; j <= b1[1] && err == I2M_OK; j++)
        for (int64_t i = b0[0]; i <= b1[0] && err == I2M_OK; i++) {
          if (!box_voxel_in_component(r, i, j, k, G->split[si].comp)) continue;
          const int64_t key = (k * e->m[1] + j) * e->m[0] + i;
          double w[3];
          voxel_centre(e, key, w);
          if (tet_holds(x, w)) err = claim(C, key, si, cls);
        }
  }
  i2m_free(&code);
  return err;
}

i2m_err_t i2m_refine_split_claims(i2m_refine_t *r, const i2m_pieces_global_t *G, i2m_voxel_claim_t **out, size_t *n)
{
  claims_t C = {NULL, 0, 0};
  int32_t *gsplit = NULL, *gpos = NULL;
  pieces_t *P;
  *out = NULL;
  *n = 0;
  I2M_CALL(pieces_get(r, &P));
  i2m_err_t err = i2m_malloc(G->ngroups + 1, sizeof *gsplit, &gsplit);
  if (err == I2M_OK) err = i2m_malloc(G->ngroups + 1, sizeof *gpos, &gpos);
  for (size_t g = 0; g < G->ngroups && err == I2M_OK; g++) gsplit[g] = gpos[g] = -1;
  for (size_t s = 0; s < G->nsplits && err == I2M_OK; s++)
    for (uint32_t k = 0; k < G->split[s].ngroups; k++) {
      gsplit[G->split[s].groups[k]] = (int32_t)s;
      gpos[G->split[s].groups[k]] = (int32_t)k;
    }
  i2m_progress_t pg; /* (a pass over every tet per split component) */
  const int64_t slots = i2m_dt_ntets_slots(r->dt);
  i2m_progress_begin_total(&pg, "component rule: voxels of the split components", "tet slots", (int64_t)G->nsplits * slots);
  for (size_t s = 0; s < G->nsplits && err == I2M_OK; s++) err = claim_split(r, G, gsplit, gpos, (int32_t)s, &C, &pg);
  i2m_progress_end(&pg, (int64_t)G->nsplits * slots);
  i2m_free(&gsplit);
  i2m_free(&gpos);
  if (err != I2M_OK) {
    i2m_free(&C.c);
    return err;
  }
  *out = C.c;
  *n = C.n;
  return I2M_OK;
}

/* ---- the search ---- */

static int cmp_claim(const void *a, const void *b)
{
  const i2m_voxel_claim_t *x = a, *y = b;
  if (x->split != y->split) return x->split < y->split ? -1 : 1;
  if (x->voxel != y->voxel) return x->voxel < y->voxel ? -1 : 1;
  return (x->cls > y->cls) - (x->cls < y->cls);
}

/* The index of voxel key among c[0..n) (sorted by voxel), or -1. */
static int64_t find_voxel(const i2m_voxel_claim_t *c, int64_t n, int64_t key)
{
  int64_t a = 0, b = n;
  while (a < b) {
    const int64_t m = a + (b - a) / 2;
    if (c[m].voxel < key) a = m + 1;
    else b = m;
  }
  return a < n && c[a].voxel == key ? a : -1;
}

/* A bridge point: the centre of voxel a (b < 0), or of the face between voxels a < b. */
typedef struct {
  int64_t a, b;
} point_t;

typedef struct {
  point_t *p;
  size_t n, cap;
} points_t;

static i2m_err_t add_point(points_t *B, int64_t a, int64_t b)
{
  if (B->n == B->cap) {
    B->cap = B->cap ? 2 * B->cap : 64;
    I2M_CALL(i2m_realloc(B->cap, sizeof *B->p, &B->p));
  }
  B->p[B->n++] = b < 0 || a < b ? (point_t){a, b} : (point_t){b, a};
  return I2M_OK;
}

static int cmp_point(const void *x, const void *y)
{
  const point_t *a = x, *b = y;
  if (a->a != b->a) return a->a < b->a ? -1 : 1;
  return (a->b > b->b) - (a->b < b->b);
}

/* Scratch of one split's searches over its n voxels. */
typedef struct {
  int32_t *dist;
  int64_t *from;
  uint8_t *done;
  int64_t *dq; /* a double-ended queue of voxel indices, 2n + 2 long: head and tail wrap */
} search_t;

/* The 0-1 search from every voxel of class own to the first voxel of another piece of the
 * split; the path's points into B.  Returns the gap voxels crossed (-1: no path). */
static int64_t search_from(const i2m_edt_t *e, const i2m_voxel_claim_t *c, int64_t n, int32_t own, search_t *S,
                           points_t *B, i2m_err_t *err)
{
  const int64_t cap = 2 * n + 2, step[3] = {1, e->m[0], e->m[0] * e->m[1]};
  int64_t head = 0, len = 0;
  for (int64_t i = 0; i < n; i++) {
    S->dist[i] = INT32_MAX;
    S->from[i] = -1;
    S->done[i] = 0;
  }
  for (int64_t i = 0; i < n; i++)
    if (c[i].cls == own) {
      S->dist[i] = 0;
      S->dq[(head + len++) % cap] = i;
    }
  int64_t goal = -1;
  while (len && goal < 0) {
    const int64_t u = S->dq[head];
    head = (head + 1) % cap;
    len--;
    if (S->done[u]) continue;
    S->done[u] = 1;
    if (c[u].cls != own && c[u].cls != I2M_CLAIM_GAP) {
      goal = u;
      break;
    }
    const int64_t key = c[u].voxel, x[3] = {key % e->m[0], key / e->m[0] % e->m[1], key / e->m[0] / e->m[1]};
    for (int a = 0; a < 3; a++)
      for (int d = -1; d <= 1; d += 2) {
        if (x[a] + d < 0 || x[a] + d >= e->m[a]) continue;
        const int64_t v = find_voxel(c, n, key + d * step[a]);
        if (v < 0 || S->done[v]) continue;
        const int32_t w = c[v].cls == I2M_CLAIM_GAP;
        if (S->dist[u] + w >= S->dist[v]) continue;
        S->dist[v] = S->dist[u] + w;
        S->from[v] = u;
        if (w) S->dq[(head + len++) % cap] = v; /* (a voxel is queued at most twice: 2n + 2 slots) */
        else {
          head = (head + cap - 1) % cap;
          S->dq[head] = v;
          len++;
        }
      }
  }
  if (goal < 0) return -1;
  int64_t gaps = 0;
  for (int64_t x = goal; x >= 0 && *err == I2M_OK; x = S->from[x]) { /* back along the path */
    if (c[x].cls == I2M_CLAIM_GAP) {
      *err = add_point(B, c[x].voxel, -1);
      gaps++;
    }
    /* pieces that meet only at an edge or a vertex: the voxel centres on either side lie in
     * tets of the label, and the voxel face between them is where they must be joined */
    const int64_t f = S->from[x];
    if (f >= 0 && c[f].cls != c[x].cls && *err == I2M_OK) *err = add_point(B, c[x].voxel, c[f].voxel);
  }
  return gaps;
}

/* The points of split s (its claims c[0..n), deduplicated). */
static i2m_err_t bridge_split(const i2m_refine_t *r, const i2m_split_t *s, const i2m_voxel_claim_t *c, int64_t n,
                              points_t *B)
{
  search_t S = {NULL, NULL, NULL, NULL};
  i2m_err_t err = i2m_malloc((size_t)n + 1, sizeof *S.dist, &S.dist);
  if (err == I2M_OK) err = i2m_malloc((size_t)n + 1, sizeof *S.from, &S.from);
  if (err == I2M_OK) err = i2m_malloc((size_t)n + 1, sizeof *S.done, &S.done);
  if (err == I2M_OK) err = i2m_malloc(2 * (size_t)n + 2, sizeof *S.dq, &S.dq);
  for (uint32_t k = 1; k < s->ngroups && err == I2M_OK; k++) { /* every piece but the largest */
    const int64_t gaps = search_from(r->edt, c, n, (int32_t)k, &S, B, &err);
    i2m_debug("bridges: label %lld, piece %u of %u: %s, %lld gap voxels (%lld voxels)",
              (long long)r->img->label_value[s->label], k + 1, s->ngroups, gaps >= 0 ? "bridged" : "no path",
              (long long)(gaps > 0 ? gaps : 0), (long long)n);
  }
  i2m_free(&S.dist);
  i2m_free(&S.from);
  i2m_free(&S.done);
  i2m_free(&S.dq);
  return err;
}

i2m_err_t i2m_bridge_points(const i2m_refine_t *r, const i2m_pieces_global_t *G, i2m_voxel_claim_t *claims,
                            size_t nclaims, int round, i2m_bridge_point_t **out, size_t *np)
{
  *out = NULL;
  *np = 0;
  if (nclaims > 1) qsort(claims, nclaims, sizeof *claims, cmp_claim);
  size_t m = 0; /* one claim per voxel: the lowest class (a piece before a gap) */
  for (size_t i = 0; i < nclaims; i++)
    if (m == 0 || claims[i].split != claims[m - 1].split || claims[i].voxel != claims[m - 1].voxel) claims[m++] = claims[i];
  points_t B = {NULL, 0, 0};
  i2m_err_t err = I2M_OK;
  for (size_t a = 0, b; a < m && err == I2M_OK; a = b) {
    for (b = a; b < m && claims[b].split == claims[a].split; b++) {
    }
    const size_t n0 = B.n;
    err = bridge_split(r, &G->split[claims[a].split], claims + a, (int64_t)(b - a), &B);
    if (err == I2M_OK && B.n - n0 > 1) qsort(B.p + n0, B.n - n0, sizeof *B.p, cmp_point);
  }
  i2m_bridge_point_t *p = NULL;
  if (err == I2M_OK) err = i2m_malloc(B.n + 1, sizeof *p, &p);
  size_t k = 0;
  for (size_t i = 0; i < B.n && err == I2M_OK; i++) {
    if (i > 0 && B.p[i].a == B.p[i - 1].a && B.p[i].b == B.p[i - 1].b) continue; /* (found by two searches) */
    voxel_centre(r->edt, B.p[i].a, p[k].x);
    if (B.p[i].b >= 0) {
      double q[3];
      voxel_centre(r->edt, B.p[i].b, q);
      for (int d = 0; d < 3; d++) p[k].x[d] = 0.5 * (p[k].x[d] + q[d]);
    }
    p[k].gid = BRIDGE_GID_BASE + ((i2m_gidx_t)round << BRIDGE_GID_ROUND_SHIFT) + (i2m_gidx_t)k;
    k++;
  }
  i2m_free(&B.p);
  if (err != I2M_OK) {
    i2m_free(&p);
    return err;
  }
  *out = p;
  *np = k;
  return I2M_OK;
}

/* ---- insertion ---- */

/* A bridge point with the place of its insertion in the ranks' order. */
typedef struct {
  uint32_t colour, tile;
  size_t at;
} bridge_order_t;

static int cmp_bridge_order(const void *x, const void *y)
{
  const bridge_order_t *a = x, *b = y;
  if (a->colour != b->colour) return a->colour < b->colour ? -1 : 1;
  if (a->tile != b->tile) return a->tile < b->tile ? -1 : 1;
  return (a->at > b->at) - (a->at < b->at);
}

/* The points in the order the ranks' tasks insert them (the deterministic mode's octree):
 * colour after colour, tile after tile, each tile's in the list's order.  The tets a point
 * makes are classified when it goes in, against the neighbours there are then, so the order
 * decides the elements that wait (one process must give the ranks' mesh). */
static i2m_err_t order_like_tasks(const i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, i2m_bridge_point_t **out)
{
  bridge_order_t *o = NULL;
  I2M_CALL(i2m_malloc(n ? n : 1, sizeof *o, &o));
  for (size_t i = 0; i < n; i++) {
    const uint32_t id = tiles_tile_of_point(r, p[i].x);
    o[i] = (bridge_order_t){(uint32_t)tiles_color(r->tiling, id), id, i};
  }
  qsort(o, n, sizeof *o, cmp_bridge_order);
  i2m_err_t err = i2m_malloc(n ? n : 1, sizeof **out, out);
  for (size_t i = 0; i < n && err == I2M_OK; i++) (*out)[i] = p[o[i].at];
  i2m_free(&o);
  return err;
}

/* Inserts the points in their order with worker 0, each one's new tets classified. */
static i2m_err_t insert_in_order(i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, int64_t *inserted)
{
  i2m_refine_worker_t *w = &r->workers[0];
  i2m_dt_t *dt = r->dt;
  uint32_t hint = 0;
  for (size_t i = 0; i < n; i++) {
    while (!i2m_dt_alive(dt, hint)) hint++; /* (some tet is alive) */
    uint32_t v;
    i2m_dt_status_t st = i2m_dt_insert_walk(&w->ctx, p[i].x, p[i].gid, I2M_VK_FREE, hint, &v);
    while (st == I2M_DT_FULL) {
      i2m_dt_unlock_all(&w->ctx);
      I2M_CALL(i2m_refine_grow(r));
      st = i2m_dt_insert_walk(&w->ctx, p[i].x, p[i].gid, I2M_VK_FREE, hint, &v);
    }
    if (st != I2M_DT_OK) { /* (a vertex there already) */
      i2m_dt_unlock_all(&w->ctx);
      continue;
    }
    w->st.insertions++;
    w->st.bridges++;
    (*inserted)++;
    i2m_err_t err = worker_keep_created(w);
    if (err == I2M_OK) err = worker_process_created(w, w->created, w->ncreated);
    i2m_dt_unlock_all(&w->ctx);
    I2M_CALL(err);
    hint = w->created[0];
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_insert_bridges(i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, int64_t *inserted)
{
  i2m_bridge_point_t *ordered = NULL;
  *inserted = 0;
  if (r->tiling && r->tiling->octree) I2M_CALL(order_like_tasks(r, p, n, &ordered));
  const i2m_err_t err = insert_in_order(r, ordered ? ordered : p, n, inserted);
  i2m_free(&ordered);
  I2M_CALL(err);
  if (r->tiling) tiles_canonical_all(r); /* (the same order as where ranks inserted them) */
  if (*inserted) pieces_invalidate(r); /* (the mesh changed) */
  return I2M_OK;
}

i2m_err_t i2m_refine_bridge_splits(i2m_refine_t *r, int64_t min_voxels, int64_t *splits, int64_t *inserted)
{
  const i2m_pieces_global_t *G;
  i2m_voxel_claim_t *c = NULL;
  i2m_bridge_point_t *p = NULL;
  size_t nc = 0, np = 0;
  *splits = *inserted = 0;
  I2M_CALL(i2m_refine_groups(r, min_voxels, &G));
  *splits = (int64_t)G->nsplits;
  if (!G->nsplits) return I2M_OK;
  i2m_err_t err = i2m_refine_split_claims(r, G, &c, &nc);
  if (err == I2M_OK) err = i2m_bridge_points(r, G, c, nc, (int)r->bridge_rounds, &p, &np);
  r->bridge_rounds++;
  if (err == I2M_OK) err = i2m_refine_insert_bridges(r, p, np, inserted);
  i2m_free(&c);
  i2m_free(&p);
  return err;
}

i2m_err_t i2m_refine_file_bridges(i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, int64_t *filed)
{
  *filed = 0;
  for (size_t i = 0; i < n; i++) {
    const uint32_t id = tiles_tile_of_point(r, p[i].x);
    if (!i2m_refine_holds(r, id)) continue;
    I2M_CALL(tiles_add_point(r, id, &p[i], false));
    (*filed)++;
  }
  if (*filed) pieces_invalidate(r); /* (the mesh will change) */
  r->bridge_rounds += n > 0;
  return I2M_OK;
}
