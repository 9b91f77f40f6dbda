/* Refine layer: sliver perturbation, an optional pass after refinement (REFERENCE §3.9).
 *
 * Delaunay refinement bounds the radius-edge ratio, which leaves slivers: four nearly
 * coplanar vertices on a small circumsphere.  For every output tet whose smallest dihedral
 * angle is below the bound, worst first, each of its vertices is moved in turn to a few
 * random nearby points: the vertex is removed and reinserted there (same global id, so the
 * same perturbation), the changed tets are labelled and judged by the very rules refinement
 * ended with, and the move is kept only when every changed tet passes them and the smallest
 * dihedral angle among the changed tets exceeds the worst of the vertex's old star.
 * Otherwise the vertex goes back where it was, which restores the same triangulation (a
 * Delaunay triangulation is unique under the perturbation).  A surface vertex moves to the
 * closest point of its own interface patch to a random nearby point, so it stays on the
 * interface: the worst slivers are flat tets of four surface vertices on a planar stretch of
 * voxel faces (four nearly cocircular points), which only such a move can lift.  Every rule
 * holds after every kept move, so every guarantee of refinement holds at the end. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define MOVES_PER_VERTEX 16 /* random targets tried per vertex of a sliver */
#define ROUNDS 6           /* passes over the slivers left */

typedef struct {
  i2m_refine_worker_t w; /* a sequential worker: its kernel context and rule evaluation */
  uint32_t *star, nstar, cap_star;
  uint32_t *changed, nchanged, cap_changed;
  uint32_t *touched, ntouched, cap_touched; /* tets made by the moves kept in this round */
  uint64_t rng;
  i2m_sliver_stats_t st;
} perturb_t;

/* A sliver, with its vertices' global ids in increasing order: the order of the work (and so
 * of the random moves) then depends on the mesh, not on its slot numbers, and the pass gives
 * the same mesh in the deterministic mode whatever the number of threads. */
typedef struct {
  uint32_t t, meta;
  double angle;
  i2m_gidx_t gid[4];
} sliver_t;

static void sort4_gid(i2m_gidx_t g[4], uint32_t v[4])
{
  for (int i = 1; i < 4; i++)
    for (int j = i; j > 0 && g[j] < g[j - 1]; j--) {
      const i2m_gidx_t x = g[j];
      const uint32_t y = v[j];
      g[j] = g[j - 1], g[j - 1] = x;
      v[j] = v[j - 1], v[j - 1] = y;
    }
}

static double uniform01(uint64_t *s) { return (double)(i2m_xorshift64(s) >> 11) * 0x1.0p-53; }

/* Smallest dihedral angle of tet t, in degrees. */
static double tet_min_dihedral(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  return i2m_tet_min_dihedral(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3]));
}

static i2m_err_t grow_list(uint32_t **a, uint32_t *cap, uint32_t need)
{
  if (need <= *cap) return I2M_OK;
  uint32_t c = need + need / 2 + 32;
  I2M_CALL(i2m_realloc(c, sizeof **a, a));
  *cap = c;
  return I2M_OK;
}

/* The tets incident to vertex v (breadth-first across the faces that hold v). */
static i2m_err_t star_of(perturb_t *P, uint32_t v)
{
  const i2m_dt_t *dt = P->w.r->dt;
  P->nstar = 0;
  I2M_CALL(grow_list(&P->star, &P->cap_star, 1));
  P->star[P->nstar++] = dt->vtet[v];
  for (uint32_t k = 0; k < P->nstar; k++) {
    const uint32_t t = P->star[k], *tv = dt->tv + 4 * (size_t)t;
    for (uint32_t i = 0; i < 4; i++) {
      if (tv[i] == v) continue; /* the face opposite v does not hold it */
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n == I2M_DT_NONE) continue;
      const uint32_t u = n >> 2;
      bool seen = false;
      for (uint32_t q = 0; q < P->nstar && !seen; q++) seen = P->star[q] == u;
      if (seen) continue;
      I2M_CALL(grow_list(&P->star, &P->cap_star, P->nstar + 1));
      P->star[P->nstar++] = u;
    }
  }
  return I2M_OK;
}

/* Labels the tets the last kernel operation created (the rules compare neighbours' labels)
 * and appends them to the changed list. */
static i2m_err_t label_created(perturb_t *P)
{
  i2m_refine_t *r = P->w.r;
  const i2m_dt_ctx_t *ctx = &P->w.ctx;
  I2M_CALL(grow_list(&P->changed, &P->cap_changed, P->nchanged + ctx->nnew));
  for (uint32_t k = 0; k < ctx->nnew; k++) {
    const uint32_t t = ctx->newt[k];
    tet_geom_t g;
    tet_geom(r, t, PROBE_NEW, &g);
    tinfo(r->dt, t)->label = (uint16_t)g.label;
    P->changed[P->nchanged++] = t;
  }
  return I2M_OK;
}

/* Takes vertex v out of the mesh (and, a surface vertex, out of the surface grid). */
static i2m_dt_status_t take_out(perturb_t *P, uint32_t v)
{
  i2m_refine_t *r = P->w.r;
  i2m_dt_ctx_t *ctx = &P->w.ctx;
  const bool surface = r->dt->vkind[v] == I2M_VK_SURFACE;
  if (surface) vgrid_remove(&r->surf, r->dt, v);
  const i2m_dt_status_t st = i2m_dt_remove(ctx, v);
  i2m_dt_unlock_all(ctx);
  if (st != I2M_DT_OK) {
    if (surface && vgrid_insert(&r->surf, r->dt, v, r->surf.tag[v]) != I2M_OK) return I2M_DT_FAILED;
    return st;
  }
  return label_created(P) == I2M_OK ? I2M_DT_OK : I2M_DT_FAILED;
}

/* Puts a vertex (global id gid, kind, patch tag for a surface vertex) at p, locating p from
 * tet start; *vout is its slot. */
static i2m_dt_status_t put_in(perturb_t *P, const double p[3], i2m_gidx_t gid, uint8_t kind, uint32_t tag, uint32_t start,
                              uint32_t *vout)
{
  i2m_refine_t *r = P->w.r;
  i2m_dt_ctx_t *ctx = &P->w.ctx;
  i2m_dt_status_t st = i2m_dt_insert_walk(ctx, p, gid, kind, start, vout);
  i2m_dt_unlock_all(ctx);
  if (st != I2M_DT_OK) return st;
  if (kind == I2M_VK_SURFACE && vgrid_insert(&r->surf, r->dt, *vout, tag) != I2M_OK) return I2M_DT_FAILED;
  return label_created(P) == I2M_OK ? I2M_DT_OK : I2M_DT_FAILED;
}

/* Do the changed tets pass every rule, and is their smallest dihedral angle above floor? */
static bool changed_ok(perturb_t *P, double floor)
{
  const i2m_dt_t *dt = P->w.r->dt;
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (!i2m_dt_alive(dt, t)) continue; /* (a removal's tet the insertion took again) */
    if (tet_min_dihedral(dt, t) <= floor) return false;
  }
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (!i2m_dt_alive(dt, t)) continue;
    action_t a;
    if (classify_action(&P->w, t, &a, 0) != 0) return false;
  }
  return true;
}

/* The live tets that a move made (kept or undone: undoing restores the tets, not their slots)
 * join the tets the next round looks at. */
static i2m_err_t note_touched(perturb_t *P)
{
  const i2m_dt_t *dt = P->w.r->dt;
  I2M_CALL(grow_list(&P->touched, &P->cap_touched, P->ntouched + P->nchanged));
  for (uint32_t k = 0; k < P->nchanged; k++)
    if (i2m_dt_alive(dt, P->changed[k])) P->touched[P->ntouched++] = P->changed[k];
  return I2M_OK;
}

/* One attempt: vertex *v to p (the same kind, global id and patch).  Kept when changed_ok;
 * otherwise the vertex goes back to where it was (the same triangulation).  *v is the
 * vertex's slot afterwards.  Returns 1 when kept, 0 when not, -1 on an error. */
static int try_move(perturb_t *P, uint32_t *v, const double p[3], double floor)
{
  i2m_refine_t *r = P->w.r;
  i2m_dt_t *dt = r->dt;
  const double *x = i2m_dt_xyz(dt, *v);
  const double x0[3] = {x[0], x[1], x[2]};
  const i2m_gidx_t gid = i2m_dt_gid(dt, *v);
  const uint8_t kind = dt->vkind[*v];
  const uint32_t tag = kind == I2M_VK_SURFACE ? r->surf.tag[*v] : 0;
  P->nchanged = 0;
  P->st.tried++;
  i2m_dt_status_t st = take_out(P, *v);
  if (st != I2M_DT_OK) return st == I2M_DT_FAILED ? -1 : 0; /* nothing changed */
  uint32_t start = P->w.ctx.newt[0], moved;
  st = put_in(P, p, gid, kind, tag, start, &moved);
  if (st == I2M_DT_FAILED) return -1;
  if (st == I2M_DT_OK && changed_ok(P, floor)) {
    P->st.kept++;
    *v = moved;
    return note_touched(P) == I2M_OK ? 1 : -1;
  }
  /* back: take the moved vertex out again (when it went in), then the old point in */
  P->nchanged = 0;
  if (st == I2M_DT_OK) {
    if (take_out(P, moved) != I2M_DT_OK) return -1;
    start = P->w.ctx.newt[0];
  }
  if (put_in(P, x0, gid, kind, tag, start, v) != I2M_DT_OK) return -1;
  return note_touched(P) == I2M_OK ? 0 : -1; /* (the same tets, maybe in other slots) */
}

/* A surface vertex stays on its interface patch: p becomes the closest interface point to p,
 * when that lies on the same patch (false otherwise). */
static bool onto_patch(const i2m_refine_t *r, uint32_t patch, double p[3])
{
  i2m_edt_probe_t pr;
  i2m_edt_probe_world(r->edt, p, INFINITY, &pr);
  if (!isfinite(pr.d2) || patch_key(pr.pair[0], pr.pair[1]) != patch) return false;
  memcpy(p, pr.z, sizeof pr.z);
  return true;
}

static int cmp_sliver(const void *x, const void *y)
{
  const sliver_t *a = x, *b = y;
  if (a->angle != b->angle) return (a->angle > b->angle) - (a->angle < b->angle);
  for (int i = 0; i < 4; i++)
    if (a->gid[i] != b->gid[i]) return (a->gid[i] > b->gid[i]) - (a->gid[i] < b->gid[i]);
  return 0;
}

typedef struct {
  sliver_t *a;
  size_t n, cap;
} sliver_list_t;

/* Tet t joins the list when it is an output tet below the bound. */
static i2m_err_t consider(const i2m_dt_t *dt, uint32_t t, double bound, sliver_list_t *L)
{
  if (!tet_kept(dt, t)) return I2M_OK;
  const double a = tet_min_dihedral(dt, t);
  if (!(a < bound)) return I2M_OK;
  if (L->n == L->cap) {
    L->cap = L->cap ? 2 * L->cap : 1024;
    I2M_CALL(i2m_realloc(L->cap, sizeof *L->a, &L->a));
  }
  sliver_t *s = &L->a[L->n++];
  *s = (sliver_t){t, i2m_dt_meta(dt, t), a, {0}};
  uint32_t v[4];
  memcpy(v, dt->tv + 4 * (size_t)t, sizeof v);
  for (int i = 0; i < 4; i++) s->gid[i] = i2m_dt_gid(dt, v[i]);
  sort4_gid(s->gid, v);
  return I2M_OK;
}

/* The output tets below the bound, and the smallest angle of all output tets. */
static i2m_err_t collect_all(const i2m_refine_t *r, double bound, sliver_list_t *L, double *min_all)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t nt = i2m_dt_ntets_slots(dt);
  L->n = 0;
  *min_all = 180.0;
  for (uint32_t t = 0; t < nt; t++) {
    if (!tet_kept(dt, t)) continue;
    const double a = tet_min_dihedral(dt, t);
    if (a < *min_all) *min_all = a;
    if (a < bound) I2M_CALL(consider(dt, t, bound, L));
  }
  return I2M_OK;
}

static int cmp_u32(const void *x, const void *y)
{
  const uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
  return (a > b) - (a < b);
}

/* The same list after a round, without a pass over the mesh: a tet no move changed has its
 * angle still, so the slivers left are the list's untouched ones (same slot generation) and
 * the tets the moves made (each slot once; a made slot is newer than the list's entries). */
static i2m_err_t collect_after_round(perturb_t *P, double bound, sliver_list_t *L)
{
  const i2m_dt_t *dt = P->w.r->dt;
  size_t n = 0;
  for (size_t k = 0; k < L->n; k++)
    if (i2m_dt_meta(dt, L->a[k].t) == L->a[k].meta) L->a[n++] = L->a[k];
  L->n = n;
  if (P->ntouched > 1) qsort(P->touched, P->ntouched, sizeof *P->touched, cmp_u32);
  for (uint32_t k = 0; k < P->ntouched; k++) {
    const uint32_t t = P->touched[k];
    if (k == 0 || P->touched[k - 1] != t) I2M_CALL(consider(dt, t, bound, L));
  }
  P->ntouched = 0;
  return I2M_OK;
}

/* Tries to move each vertex of sliver s (free vertices anywhere near, surface vertices along
 * their patch) until one move is kept. */
static int treat_sliver(perturb_t *P, const sliver_t *s)
{
  i2m_dt_t *dt = P->w.r->dt;
  if (i2m_dt_meta(dt, s->t) != s->meta) return 0; /* changed by an earlier move */
  uint32_t verts[4];
  i2m_gidx_t gid[4];
  memcpy(verts, dt->tv + 4 * (size_t)s->t, sizeof verts);
  for (int i = 0; i < 4; i++) gid[i] = i2m_dt_gid(dt, verts[i]);
  sort4_gid(gid, verts); /* in the order of their global ids */
  for (int i = 0; i < 4; i++) {
    uint32_t v = verts[i];
    const bool surface = dt->vkind[v] == I2M_VK_SURFACE;
    if (!surface && dt->vkind[v] != I2M_VK_FREE) continue;
    if (star_of(P, v) != I2M_OK) return -1;
    double floor = 180.0, lmin2 = INFINITY;
    const double *x = i2m_dt_xyz(dt, v);
    for (uint32_t k = 0; k < P->nstar; k++) {
      const uint32_t t = P->star[k], *tv = dt->tv + 4 * (size_t)t;
      const double a = tet_min_dihedral(dt, t);
      floor = a < floor ? a : floor;
      for (int j = 0; j < 4; j++)
        if (tv[j] != v && tv[j] >= 8) { /* (box corners are far) */
          const double d2 = i2m_dist2(x, i2m_dt_xyz(dt, tv[j]));
          lmin2 = d2 < lmin2 ? d2 : lmin2;
        }
    }
    if (!isfinite(lmin2)) continue;
    const double lmin = sqrt(lmin2);
    for (int m = 0; m < MOVES_PER_VERTEX; m++) {
      /* a random direction, at a distance from 0.05 to 0.3 of the shortest edge */
      double d[3], n2;
      do {
        for (int a = 0; a < 3; a++) d[a] = 2.0 * uniform01(&P->rng) - 1.0;
        n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      } while (n2 > 1.0 || n2 < 1e-6);
      const double len = lmin * (0.05 + 0.25 * uniform01(&P->rng)) / sqrt(n2);
      const double *xv = i2m_dt_xyz(dt, v);
      double p[3] = {xv[0] + len * d[0], xv[1] + len * d[1], xv[2] + len * d[2]};
      if (surface && !onto_patch(P->w.r, P->w.r->surf.tag[v], p)) continue;
      const int kept = try_move(P, &v, p, floor);
      if (kept != 0) return kept;
    }
  }
  return 0;
}

i2m_err_t i2m_refine_perturb_slivers(i2m_refine_t *r, double bound, i2m_sliver_stats_t *out)
{
  const double t0 = i2m_wtime();
  perturb_t *P = NULL;
  sliver_list_t L = {0};
  I2M_CALL(i2m_calloc(1, sizeof *P, &P));
  i2m_err_t err = worker_init(&P->w, r, (uint32_t)r->nworkers + 1, false); /* (an owner no worker has) */
  i2m_progress_t progress;
  i2m_progress_begin(&progress, "sliver perturbation", "vertex moves");
  P->rng = 0x9E3779B97F4A7C15ull ^ r->p.seed;
  double min_all = 180.0;
  if (err == I2M_OK) err = collect_all(r, bound, &L, &min_all);
  P->st.slivers_before = (int64_t)L.n;
  P->st.min_before = min_all;
  for (int round = 0; round < ROUNDS && err == I2M_OK && L.n > 0; round++) {
    if (round > 0) err = collect_after_round(P, bound, &L);
    if (L.n > 1) qsort(L.a, L.n, sizeof *L.a, cmp_sliver); /* worst first */
    const int64_t kept0 = P->st.kept;
    for (size_t k = 0; k < L.n && err == I2M_OK; k++) {
      if (treat_sliver(P, &L.a[k]) < 0) err = I2M_ERROR(I2M_ERR_INTERNAL, "sliver perturbation: a vertex could not be moved back");
      i2m_progress_update(&progress, P->st.tried);
    }
    if (P->st.kept == kept0) break;
  }
  if (err == I2M_OK) err = collect_all(r, bound, &L, &min_all);
  P->st.slivers_after = (int64_t)L.n;
  P->st.min_after = min_all;
  P->st.seconds = i2m_wtime() - t0;
  i2m_progress_end(&progress, P->st.tried);
  i2m_dt_ctx_flush(&P->w.ctx);
  worker_free(&P->w);
  i2m_free(&P->star);
  i2m_free(&P->changed);
  i2m_free(&P->touched);
  if (out) *out = P->st;
  i2m_free(&P);
  i2m_free(&L.a);
  return err;
}
