/* Refine layer: parameters, setup of the virtual box, the sequential driver, statistics. */
#include "refine_impl.h"

#include <string.h>

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

i2m_err_t i2m_refine_params_check(const i2m_refine_params_t *p, const i2m_image_t *img)
{
  const char *f = img->path && img->path[0] ? img->path : "image";
  int64_t fg = 0;
  for (int l = 1; l < img->nlabels; l++) fg += img->label_count[l];
  I2M_CHECK(fg > 0, I2M_ERR_INPUT, "%s: the image has no foreground (every voxel is 0): nothing to mesh", f);
  I2M_CHECK(isnan(p->delta) || (p->delta > 0 && isfinite(p->delta)), I2M_ERR_ARG,
            "--delta must be a positive length in mm (got %g)", p->delta);
  I2M_CHECK(p->ratio >= 2.0 && isfinite(p->ratio), I2M_ERR_ARG,
            "--ratio must be at least 2: Delaunay refinement is guaranteed to terminate only then (got %g)", p->ratio);
  I2M_CHECK(p->facet_angle >= 0 && p->facet_angle <= 30.0, I2M_ERR_ARG,
            "--facet-angle must be between 0 and 30 degrees: beyond 30 refinement may not terminate (got %g)",
            p->facet_angle);
  I2M_CHECK(p->size > 0, I2M_ERR_ARG, "--size must be a positive length in mm (got %g)", p->size);
  for (int k = 0; k < p->nlabel_sizes; k++) {
    const i2m_label_size_t *ls = &p->label_sizes[k];
    I2M_CHECK(label_index(img, ls->value) > 0, I2M_ERR_ARG, "--size-label %lld: %s has no label %lld",
              (long long)ls->value, f, (long long)ls->value);
    I2M_CHECK(ls->size > 0 && isfinite(ls->size), I2M_ERR_ARG, "--size-label %lld=%g: the size must be positive",
              (long long)ls->value, ls->size);
  }
  double lo[3], hi[3];
  i2m_image_world_bounds(img, lo, hi);
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

static i2m_err_t setup_bounds(i2m_refine_t *r)
{
  const i2m_image_t *img = r->img;
  r->min_spacing = fmin(img->spacing[0], fmin(img->spacing[1], img->spacing[2]));
  if (isnan(r->p.delta)) r->p.delta = i2m_refine_default_delta(img);
  r->delta2 = r->p.delta * r->p.delta;
  r->four_delta2 = 4.0 * r->delta2;
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
  I2M_CALL_GOTO(err, fail, setup_bounds(r));
  /* the virtual box: the image block (world) grown by its largest extent on every side */
  double lo[3], hi[3], ext = 0;
  i2m_image_world_bounds(img, lo, hi);
  for (int a = 0; a < 3; a++) ext = fmax(ext, hi[a] - lo[a]);
  for (int a = 0; a < 3; a++) {
    lo[a] -= ext;
    hi[a] += ext;
  }
  I2M_CALL_GOTO(err, fail, i2m_dt_create(lo, hi, 1 << 16, sizeof(tet_info_t), &r->dt));
  double ilo[3], ihi[3]; /* the image block, where surface points and their neighbours lie */
  i2m_image_world_bounds(img, ilo, ihi);
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
  for (int k = 0; k < r->nworkers && r->workers; k++) worker_free(&r->workers[k]);
  i2m_free(&r->workers);
  vgrid_free(&r->surf);
  vgrid_free(&r->freev);
  i2m_dt_destroy(&r->dt);
  i2m_free(&r->label_size);
  i2m_free(rp);
}

i2m_err_t i2m_refine_run(i2m_refine_t *r)
{
  i2m_refine_worker_t *w = &r->workers[0];
  double t0 = i2m_wtime();
  int s;
  while ((s = worker_step(w)) > 0) {
  }
  I2M_CHECK(s == 0, I2M_ERR_INTERNAL, "refinement failed: %s", i2m_error_message());
  i2m_dt_ctx_flush(&w->ctx);
  w->st.seconds += i2m_wtime() - t0;
  w->st.rollbacks = w->ctx.n_rollback;
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
    s->seconds = fmax(s->seconds, w->seconds);
  }
}
