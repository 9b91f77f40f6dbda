/* Refine layer: parameters, setup of the virtual box, the sequential driver, statistics. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define DEPTH_MIN_DELTAS 16.0   /* the octree's cells are at least this many delta on a side */
#define DEPTH_MAX 6             /* 2^18 cells at most */
#define DEPTH_DETERMINISTIC 3   /* the deterministic mode's depth, whatever the threads and ranks */

void i2m_refine_params_default(i2m_refine_params_t *p)
{
  memset(p, 0, sizeof *p);
  p->delta = NAN; /* from the spacing */
  p->ratio = 2.0;
  p->facet_angle = 30.0;
  p->size = INFINITY;
  p->seed = 1;
}

double i2m_refine_default_delta(const i2m_image_t *img)
{
  double lo = fmin(img->spacing[0], fmin(img->spacing[1], img->spacing[2]));
  double hi = fmax(img->spacing[0], fmax(img->spacing[1], img->spacing[2]));
  return fmax(0.8 * lo, 0.5 * hi);
}

static int label_index(const i2m_image_t *img, int64_t value)
{
  for (int l = 0; l < img->nlabels; l++)
    if (img->label_value[l] == value && img->label_count[l] > 0) return l;
  return -1;
}

i2m_err_t i2m_refine_params_check_geometry(const i2m_refine_params_t *p, const i2m_image_t *img)
{
  I2M_CHECK(isnan(p->delta) || (p->delta > 0 && isfinite(p->delta)), I2M_ERR_ARG,
            "--delta must be a positive length in mm (got %g)", p->delta);
  I2M_CHECK(p->ratio >= 2.0 && isfinite(p->ratio), I2M_ERR_ARG,
            "--ratio must be at least 2: Delaunay refinement is guaranteed to terminate only then (got %g)", p->ratio);
  I2M_CHECK(p->facet_angle >= 0 && p->facet_angle <= 30.0, I2M_ERR_ARG,
            "--facet-angle must be between 0 and 30 degrees: beyond 30 refinement may not terminate (got %g)",
            p->facet_angle);
  I2M_CHECK(p->size > 0, I2M_ERR_ARG, "--size must be a positive length in mm (got %g)", p->size);
  double lo[3], hi[3], extent = 0;
  i2m_image_world_bounds(img, lo, hi);
  for (int a = 0; a < 3; a++) {
    extent = fmax(extent, hi[a] - lo[a]);
    lo[a] += p->shift[a]; /* (the image may be in the mesh frame; regions are in the world) */
    hi[a] += p->shift[a];
  }
  I2M_CHECK(isnan(p->delta) || p->delta < extent, I2M_ERR_ARG,
            "--delta %g mm is not below the image's largest extent (%g mm): nothing could be resolved", p->delta,
            extent);
  for (int k = 0; k < p->nregions; k++) {
    const i2m_region_t *g = &p->regions[k];
    for (int a = 0; a < 3; a++)
      I2M_CHECK(g->lo[a] < g->hi[a], I2M_ERR_ARG, "--region %d: its corners must satisfy X0<X1, Y0<Y1, Z0<Z1", k + 1);
    bool overlaps = true;
    for (int a = 0; a < 3; a++) overlaps = overlaps && g->hi[a] > lo[a] && g->lo[a] < hi[a];
    I2M_CHECK(overlaps, I2M_ERR_ARG,
              "--region %d lies outside the image, whose world box is (%g,%g,%g)-(%g,%g,%g) mm", k + 1, lo[0], lo[1],
              lo[2], hi[0], hi[1], hi[2]);
    I2M_CHECK(g->size > 0 && isfinite(g->size), I2M_ERR_ARG, "--region %d: the size must be positive", k + 1);
    I2M_CHECK(g->ratio >= 2.0, I2M_ERR_ARG, "--region %d: the ratio must be at least 2 (got %g)", k + 1, g->ratio);
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_params_check(const i2m_refine_params_t *p, const i2m_image_t *img)
{
  const char *f = img->path && img->path[0] ? img->path : "image";
  I2M_CALL(i2m_refine_params_check_geometry(p, img));
  int64_t fg = 0;
  for (int l = 1; l < img->nlabels; l++) fg += img->label_count[l];
  I2M_CHECK(fg > 0, I2M_ERR_INPUT, "%s: the image has no foreground (every voxel is 0): nothing to mesh", f);
  for (int k = 0; k < p->nlabel_sizes; k++) {
    const i2m_label_size_t *ls = &p->label_sizes[k];
    I2M_CHECK(label_index(img, ls->value) > 0, I2M_ERR_ARG, "--size-label %lld: %s has no label %lld",
              (long long)ls->value, f, (long long)ls->value);
    I2M_CHECK(ls->size > 0 && isfinite(ls->size), I2M_ERR_ARG, "--size-label %lld=%g: the size must be positive",
              (long long)ls->value, ls->size);
  }
  return I2M_OK;
}

static i2m_err_t setup_bounds(i2m_refine_t *r)
{
  const i2m_image_t *img = r->img;
  r->min_spacing = fmin(img->spacing[0], fmin(img->spacing[1], img->spacing[2]));
  if (isnan(r->p.delta)) r->p.delta = i2m_refine_default_delta(img);
  i2m_refine_set_scale(r, 1.0);
  double s = sin(r->p.facet_angle * I2M_PI / 180.0);
  r->sin2_facet = s * s;
  r->bisect_tol = 1e-3 * r->min_spacing;
  if (r->p.nlabel_sizes) {
    I2M_CALL(i2m_malloc((size_t)img->nlabels, sizeof *r->label_size, &r->label_size));
    for (int l = 0; l < img->nlabels; l++) r->label_size[l] = INFINITY;
    for (int k = 0; k < r->p.nlabel_sizes; k++) {
      int l = label_index(img, r->p.label_sizes[k].value);
      if (l > 0) r->label_size[l] = fmin(r->label_size[l], r->p.label_sizes[k].size);
    }
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_create(const i2m_image_t *img, const i2m_edt_t *edt, const i2m_refine_params_t *params,
                            i2m_refine_t **out)
{
  i2m_refine_t *r = NULL;
  i2m_err_t err = I2M_OK;
  *out = NULL;
  I2M_CALL(i2m_refine_params_check(params, img));
  I2M_CALL(i2m_calloc(1, sizeof *r, &r));
  r->img = img;
  r->edt = edt;
  r->p = *params;
  atomic_init(&r->next_gid, 8);
  r->background_size2 = INFINITY;
  r->octree_depth = -1;
  I2M_CALL_GOTO(err, fail, setup_bounds(r));
  /* the virtual box: the image block (world) grown by its largest extent on every side */
  double lo[3], hi[3], ext = 0;
  i2m_image_world_bounds(img, lo, hi);
  for (int a = 0; a < 3; a++) ext = fmax(ext, hi[a] - lo[a]);
  for (int a = 0; a < 3; a++) {
    lo[a] -= ext;
    hi[a] += ext;
  }
  I2M_CALL_GOTO(err, fail, i2m_dt_create(lo, hi, 1 << 12, sizeof(tet_info_t), &r->dt));
  i2m_dt_set_shift(r->dt, params->shift);
  /* the grids cover the labelled block (the transform's box K), where surface points and
   * their neighbours lie; anything outside falls into the border cells */
  double ilo[3], ihi[3];
  if (edt->nboundary > 0) {
    const int64_t last[3] = {edt->lo[0] + edt->m[0] - 1, edt->lo[1] + edt->m[1] - 1, edt->lo[2] + edt->m[2] - 1};
    i2m_image_world_bounds_of(img, edt->lo, last, ilo, ihi);
  } else {
    i2m_image_world_bounds(img, ilo, ihi);
  }
  memcpy(r->block_lo, ilo, sizeof ilo);
  memcpy(r->block_hi, ihi, sizeof ihi);
  I2M_CALL_GOTO(err, fail, vgrid_init(&r->surf, ilo, ihi, 2.0 * r->p.delta));
  I2M_CALL_GOTO(err, fail, vgrid_init(&r->freev, ilo, ihi, 4.0 * r->p.delta));
  r->nworkers = 1;
  I2M_CALL_GOTO(err, fail, i2m_calloc(1, sizeof *r->workers, &r->workers));
  I2M_CALL_GOTO(err, fail, worker_init(&r->workers[0], r, 1, false));
  uint32_t nt = i2m_dt_ntets_slots(r->dt), box[8], nbox = 0;
  for (uint32_t t = 0; t < nt; t++)
    if (i2m_dt_alive(r->dt, t)) box[nbox++] = t;
  I2M_CALL_GOTO(err, fail, worker_process_created(&r->workers[0], box, nbox));
  *out = r;
  return I2M_OK;
fail:
  i2m_refine_destroy(&r);
  return err;
}

void i2m_refine_destroy(i2m_refine_t **rp)
{
  if (!rp || !*rp) return;
  i2m_refine_t *r = *rp;
  i2m_refine_dist_end(r);
  i2m_refine_tiling_end(r);
  for (int k = 0; k < r->nworkers && r->workers; k++) worker_free(&r->workers[k]); /* accepts freed ones */
  i2m_free(&r->workers);
  vgrid_free(&r->surf);
  vgrid_free(&r->freev);
  i2m_dt_destroy(&r->dt);
  i2m_free(&r->label_size);
  i2m_components_free(&r->pieces_ic);
  pieces_invalidate(r);
  i2m_free(rp);
}

i2m_err_t i2m_refine_run(i2m_refine_t *r)
{
  i2m_refine_worker_t *w = &r->workers[0];
  double t0 = i2m_wtime();
  int s;
  while ((s = worker_step(w)) == I2M_STEP_DONE) {
  }
  I2M_CALL(step_outcome(w, s));
  i2m_dt_ctx_flush(&w->ctx);
  w->st.seconds += i2m_wtime() - t0;

  i2m_progress_end(&w->progress, 6 + w->ctx.n_created - w->ctx.n_killed);
  return I2M_OK;
}

i2m_dt_t *i2m_refine_dt(i2m_refine_t *r) { return r->dt; }
const i2m_refine_params_t *i2m_refine_params(const i2m_refine_t *r) { return &r->p; }

void i2m_refine_get_stats(const i2m_refine_t *r, i2m_refine_stats_t *s)
{
  memset(s, 0, sizeof *s);
  for (int k = 0; k < r->nworkers; k++) {
    const i2m_refine_stats_t *w = &r->workers[k].st;
    for (int i = 0; i < 8; i++) s->rule[i] += w->rule[i];
    s->insertions += w->insertions;
    s->removals += w->removals;
    s->rollbacks += w->rollbacks;
    s->failed += w->failed;
    s->duplicates += w->duplicates;
    s->junction_skips += w->junction_skips;
    s->tets_created += w->tets_created;
    s->deferred += w->deferred;
    s->judged += w->judged;
    s->bridges += w->bridges;
    s->seconds = fmax(s->seconds, w->seconds);
  }
  s->bridge_rounds = r->bridge_rounds;
  s->fragments = r->fragments;
  s->fragment_tets = r->fragment_tets;
}

/* ---- several workers (the threads layer drives them) ---- */

i2m_err_t i2m_refine_set_workers(i2m_refine_t *r, int n)
{
  I2M_CHECK(n >= 1 && n <= (int)I2M_DT_MAX_OWNERS, I2M_ERR_ARG, "between 1 and %u threads", I2M_DT_MAX_OWNERS);
  pieces_invalidate(r); /* (refinement changes the mesh) */
  i2m_refine_worker_t *w = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL(i2m_calloc((size_t)n, sizeof *w, &w)); /* zeroed: worker_free accepts the ones not set up */
  for (int k = 0; k < n && err == I2M_OK; k++) err = worker_init(&w[k], r, (uint32_t)k + 1, n > 1);
  /* the old worker 0's lists, statistics and progress carry over */
  i2m_refine_worker_t *old = &r->workers[0];
  for (int l = 0; l < NLEVELS && err == I2M_OK; l++) {
    badlist_free(&w[0].q[l]);
    w[0].q[l] = old->q[l];
    old->q[l] = (badlist_t){0};
    err = badlist_set_wide(&w[0].q[l], r->dt, n > 1);
  }
  if (err != I2M_OK) {
    for (int k = 0; k < n; k++) worker_free(&w[k]);
    i2m_free(&w);
    return err;
  }
  w[0].pend = old->pend;
  w[0].npend = old->npend;
  w[0].cap_pend = old->cap_pend;
  old->pend = NULL;
  old->npend = old->cap_pend = 0;
  for (int k = 1; k < r->nworkers && err == I2M_OK; k++) /* (the others' lists were handed on: a coarse mesh's team) */
    if (i2m_refine_backlog(r, k)) err = I2M_ERROR(I2M_ERR_INTERNAL, "fewer workers while worker %d has work", k);
  if (err != I2M_OK) {
    for (int k = 0; k < n; k++) worker_free(&w[k]);
    i2m_free(&w);
    return err;
  }
  i2m_refine_get_stats(r, &w[0].st); /* (every old worker's figures) */
  w[0].progress = old->progress;
  w[0].ctx.n_created = old->ctx.n_created;
  w[0].ctx.n_killed = old->ctx.n_killed;
  i2m_dt_ctx_flush(&old->ctx);
  for (int k = 0; k < r->nworkers; k++) worker_free(&r->workers[k]);
  i2m_free(&r->workers);
  r->workers = w;
  r->nworkers = n;
  if (n > 1) {
    I2M_CALL(vgrid_enable_locks(&r->freev));
    I2M_CALL(i2m_refine_grow(r));
  }
  return I2M_OK;
}

int i2m_refine_nworkers(const i2m_refine_t *r) { return r->nworkers; }

int i2m_refine_step(i2m_refine_t *r, int k) { return worker_step(&r->workers[k]); }
i2m_err_t i2m_refine_step_error(const i2m_refine_t *r, int k) { return r->workers[k].error; }

int i2m_refine_conflict_worker(const i2m_refine_t *r, int k)
{
  uint32_t o = r->workers[k].ctx.conflict_owner;
  return o >= 1 && (int)o <= r->nworkers ? (int)o - 1 : -1;
}

size_t i2m_refine_backlog(const i2m_refine_t *r, int k)
{
  const i2m_refine_worker_t *w = &r->workers[k];
  size_t n = w->npend;
  for (int l = 0; l < NLEVELS; l++) n += w->q[l].n;
  return n;
}

size_t i2m_refine_give(i2m_refine_t *r, int from, int to)
{
  i2m_refine_worker_t *a = &r->workers[from], *b = &r->workers[to];
  size_t moved = 0;
  for (int l = 0; l < NLEVELS; l++) { /* the older half (bottom of the stack): away from a's front */
    badlist_t *q = &a->q[l];
    size_t half = q->n / 2;
    if (half == 0) continue;
    for (size_t i = 0; i < half; i++) {
      bad_t e;
      badlist_get(q, r->dt, i, &e);
      if (worker_push_entry(b, l, &e) != I2M_OK) return moved;
    }
    badlist_drop_bottom(q, half);
    moved += half;
  }
  return moved;
}

typedef struct {
  double key;
  int level;
  bad_t b;
} spread_t;

static int cmp_spread(const void *x, const void *y)
{
  double a = ((const spread_t *)x)->key, b = ((const spread_t *)y)->key;
  return (a > b) - (a < b);
}

i2m_err_t i2m_refine_spread(i2m_refine_t *r)
{
  i2m_refine_worker_t *w0 = &r->workers[0];
  size_t n = 0;
  for (int l = 0; l < NLEVELS; l++) n += w0->q[l].n;
  if (r->nworkers < 2 || n == 0) return I2M_OK;
  int ax = 0; /* slabs across the longest axis of the image */
  double lo[3], hi[3];
  i2m_image_world_bounds(r->img, lo, hi);
  for (int a = 1; a < 3; a++)
    if (hi[a] - lo[a] > hi[ax] - lo[ax]) ax = a;
  spread_t *all = NULL;
  I2M_CALL(i2m_malloc(n, sizeof *all, &all));
  size_t m = 0;
  for (int l = 0; l < NLEVELS; l++) {
    for (size_t i = 0; i < w0->q[l].n; i++) {
      bad_t *b = &all[m].b;
      badlist_get(&w0->q[l], r->dt, i, b);
      all[m].key = i2m_dt_xyz(r->dt, b->v[0])[ax];
      all[m++].level = l;
    }
    w0->q[l].n = 0;
  }
  qsort(all, m, sizeof *all, cmp_spread);
  i2m_err_t err = I2M_OK;
  for (size_t i = 0; i < m && err == I2M_OK; i++)
    err = worker_push_entry(&r->workers[(size_t)r->nworkers * i / m], all[i].level, &all[i].b);
  i2m_free(&all);
  return err;
}

i2m_err_t i2m_refine_grow(i2m_refine_t *r)
{
  i2m_dt_t *dt = r->dt;
  uint64_t nv = (uint64_t)dt->cap_v + dt->cap_v / 2 + 1024, nt = (uint64_t)dt->cap_t + dt->cap_t / 2 + 8192;
  if (nt > (UINT32_MAX >> 2) - 1) nt = (UINT32_MAX >> 2) - 1;
  if (nv > UINT32_MAX - 2) nv = UINT32_MAX - 2;
  I2M_CHECK(nt > dt->cap_t, I2M_ERR_MEMORY, "a process can hold at most 2^30 tetrahedra; use more MPI ranks");
  I2M_CALL(i2m_dt_reserve(dt, (uint32_t)nv, (uint32_t)nt));
  I2M_CALL(vgrid_reserve(&r->surf, dt->cap_v));
  I2M_CALL(vgrid_reserve(&r->freev, dt->cap_v));
  return I2M_OK;
}

int i2m_refine_default_depth(const i2m_refine_t *r, int workers)
{
  double ext = INFINITY;
  for (int a = 0; a < 3; a++) ext = fmin(ext, r->block_hi[a] - r->block_lo[a]);
  int size_depth = 0; /* cells of at least DEPTH_MIN_DELTAS delta along every axis */
  while (size_depth < DEPTH_MAX && ext / (double)(2 << size_depth) >= DEPTH_MIN_DELTAS * r->p.delta) size_depth++;
  int want = DEPTH_DETERMINISTIC;
  if (workers > 0) /* enough tasks of each colour for every worker, several times over */
    for (want = 1; want < DEPTH_MAX && ((int64_t)1 << (3 * want)) < 27 * 4 * (int64_t)workers; want++) {
    }
  const int d = want < size_depth ? want : size_depth;
  if (workers > 1 && d < 2) return 2; /* (at depth 1 every task's block is the whole grid: nothing could run beside it) */
  return d < 1 ? 1 : d;
}

int i2m_refine_depth(const i2m_refine_t *r) { return r->octree_depth; }

void i2m_refine_set_scale(i2m_refine_t *r, double f)
{
  r->size_scale = f;
  r->delta = f * r->p.delta;
  r->delta2 = r->delta * r->delta;
  r->four_delta2 = 4.0 * r->delta2;
}

i2m_err_t i2m_refine_reclassify(i2m_refine_t *r, int k, int n)
{
  i2m_refine_worker_t *w = &r->workers[k];
  uint32_t nt = i2m_dt_ntets_slots(r->dt);
  for (uint32_t t = (uint32_t)k; t < nt; t += (uint32_t)n)
    if (i2m_dt_alive(r->dt, t)) I2M_CALL(worker_push(w, t));
  return I2M_OK;
}

void i2m_refine_worker_stats(const i2m_refine_t *r, int k, i2m_refine_stats_t *s)
{
  *s = r->workers[k].st;
}

void i2m_refine_sync(i2m_refine_t *r)
{
  for (int k = 0; k < r->nworkers; k++) i2m_dt_ctx_flush(&r->workers[k].ctx);
}

/* Does anything besides the mesh hold tet slots: a worker's bad elements or removals still to
 * do, a tiling's lists, the dist layer's bookkeeping? */
static bool slots_recorded(const i2m_refine_t *r)
{
  if (r->tiling || r->sub || r->slivers) return true;
  for (int k = 0; k < r->nworkers; k++) {
    const i2m_refine_worker_t *w = &r->workers[k];
    if (w->npend || w->nborn) return true;
    for (int l = 0; l < NLEVELS; l++)
      if (w->q[l].n) return true;
  }
  return false;
}

i2m_err_t refine_sort_tets(i2m_refine_t *r)
{
  if (slots_recorded(r)) return I2M_OK; /* (they would name other tets) */
  i2m_refine_sync(r); /* (the workers' slot sets back on the free lists, which the sort empties) */
  pieces_invalidate(r);
  double lo[3], hi[3]; /* (the labelled block, in the triangulation's frame) */
  for (int a = 0; a < 3; a++) {
    lo[a] = r->block_lo[a] - r->dt->shift[a];
    hi[a] = r->block_hi[a] - r->dt->shift[a];
  }
  const double t0 = i2m_wtime();
  const i2m_err_t err = i2m_dt_sort_tets(r->dt, lo, hi);
  i2m_debug("tets renumbered along a Morton curve: %lld, %.2f s", (long long)i2m_dt_live_tets_quiescent(r->dt), i2m_wtime() - t0);
  return err;
}

void i2m_refine_release_scratch(i2m_refine_t *r)
{
  vgrid_free(&r->surf);
  vgrid_free(&r->freev);
  for (int k = 0; k < r->nworkers; k++) { /* keep the statistics */
    i2m_refine_worker_t *w = &r->workers[k];
    i2m_refine_stats_t st = w->st;
    worker_free(w);
    w->st = st;
  }
}

void i2m_refine_release_mesh(i2m_refine_t *r)
{
  pieces_invalidate(r);
  i2m_refine_dist_end(r); /* (their slots and lists are the triangulation's) */
  i2m_refine_tiling_end(r);
  i2m_dt_destroy(&r->dt);
}
