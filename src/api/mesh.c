/* api layer: the library call of include/i2m.h.  A label array in memory becomes an image,
 * the pipeline (include/i2m/pipeline.h) meshes it on one process, and the extracted mesh's
 * arrays are handed over to the caller without a copy. */
#include "i2m.h"

#include <math.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "i2m/pipeline.h"
#include "i2m/threads.h"

void i2m_options_init(i2m_options_t *o)
{
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  memset(o, 0, sizeof *o);
  o->delta = 0; /* (0: chosen from the image's spacing, as on the command line) */
  o->ratio = p.ratio;
  o->facet_angle = p.facet_angle;
  o->size = 0; /* (no bound) */
  o->seed = p.seed;
  o->coarse_factor = 4.0; /* (as --coarse-factor's default) */
}

const char *i2m_last_error(void) { return i2m_error_message(); }

static size_t label_bytes(i2m_label_type_t type)
{
  switch (type) {
  case I2M_LABELS_UINT8:
  case I2M_LABELS_INT8: return 1;
  case I2M_LABELS_UINT16:
  case I2M_LABELS_INT16: return 2;
  case I2M_LABELS_UINT32:
  case I2M_LABELS_INT32: return 4;
  case I2M_LABELS_INT64: return 8;
  }
  return 0;
}

static int64_t label_at(const void *labels, i2m_label_type_t type, size_t i)
{
  switch (type) {
  case I2M_LABELS_UINT8: return ((const uint8_t *)labels)[i];
  case I2M_LABELS_INT8: return ((const int8_t *)labels)[i];
  case I2M_LABELS_UINT16: return ((const uint16_t *)labels)[i];
  case I2M_LABELS_INT16: return ((const int16_t *)labels)[i];
  case I2M_LABELS_UINT32: return ((const uint32_t *)labels)[i];
  case I2M_LABELS_INT32: return ((const int32_t *)labels)[i];
  case I2M_LABELS_INT64: return ((const int64_t *)labels)[i];
  }
  return 0;
}

/* The caller's array as an image (the values widened to 64 bits for the image's builder). */
static i2m_err_t image_from_labels(const void *labels, i2m_label_type_t type, const int64_t dims[3],
                                   const double spacing[3], const double origin[3], const double direction[9],
                                   i2m_image_t **img)
{
  I2M_CHECK(labels && dims && spacing, I2M_ERR_ARG, "i2m_mesh_labels: labels, dims and spacing are required");
  I2M_CHECK(label_bytes(type) > 0, I2M_ERR_ARG, "i2m_mesh_labels: unknown label type %d", (int)type);
  size_t n = 1;
  for (int a = 0; a < 3; a++) {
    I2M_CHECK(dims[a] >= 1 && dims[a] <= (int64_t)1 << 31, I2M_ERR_ARG, "i2m_mesh_labels: dims[%d] = %lld is not a size", a,
              (long long)dims[a]);
    I2M_CHECK(isfinite(spacing[a]) && spacing[a] > 0, I2M_ERR_ARG, "i2m_mesh_labels: spacing[%d] = %g must be positive", a,
              spacing[a]);
    I2M_CHECK(n <= SIZE_MAX / 8 / (size_t)dims[a], I2M_ERR_ARG, "i2m_mesh_labels: the image is too large");
    n *= (size_t)dims[a];
  }
  const double zero[3] = {0, 0, 0};
  int64_t *values = NULL;
  I2M_CALL(i2m_malloc(n, sizeof *values, &values));
  for (size_t i = 0; i < n; i++) values[i] = label_at(labels, type, i);
  const i2m_err_t err = i2m_image_create_from_values(dims, spacing, origin ? origin : zero, direction, values, img);
  i2m_free(&values);
  return err;
}

/* The options' regions as the refinement's (into *regions, owned by the caller), checked as
 * --region is. */
static i2m_err_t regions_from_options(const i2m_options_t *o, i2m_region_t **regions)
{
  I2M_CHECK(o->nregions >= 0 && (o->nregions == 0 || o->regions), I2M_ERR_ARG,
            "i2m_mesh_labels: %d regions without their array", o->nregions);
  if (o->nregions == 0) return I2M_OK;
  I2M_CALL(i2m_malloc((size_t)o->nregions, sizeof **regions, regions));
  for (int k = 0; k < o->nregions; k++) {
    const double *x = o->regions + 8 * k;
    i2m_region_t *g = &(*regions)[k];
    for (int a = 0; a < 3; a++) {
      I2M_CHECK(isfinite(x[a]) && isfinite(x[a + 3]), I2M_ERR_ARG, "i2m_mesh_labels: region %d: the corners must be finite", k);
      g->lo[a] = fmin(x[a], x[a + 3]);
      g->hi[a] = fmax(x[a], x[a + 3]);
      I2M_CHECK(g->lo[a] < g->hi[a], I2M_ERR_ARG, "i2m_mesh_labels: region %d: the box is empty along axis %d", k, a);
    }
    I2M_CHECK(x[6] > 0, I2M_ERR_ARG, "i2m_mesh_labels: region %d: the size must be positive", k);
    g->size = x[6];
    g->ratio = x[7] != 0 ? x[7] : o->ratio;
  }
  return I2M_OK;
}

/* The refinement parameters from the options (label sizes and regions into *sizes and
 * *regions, owned by the caller). */
static i2m_err_t params_from_options(const i2m_options_t *o, i2m_refine_params_t *p, i2m_label_size_t **sizes,
                                     i2m_region_t **regions)
{
  i2m_refine_params_default(p);
  p->delta = o->delta == 0 ? NAN : o->delta; /* (NAN: the default, from the spacing; a negative one is refused) */
  p->ratio = o->ratio;
  p->facet_angle = o->facet_angle;
  p->size = o->size > 0 ? o->size : INFINITY;
  p->seed = o->seed;
  I2M_CHECK(o->nlabel_sizes >= 0 && (o->nlabel_sizes == 0 || (o->label_size_values && o->label_sizes)), I2M_ERR_ARG,
            "i2m_mesh_labels: %d label sizes without their arrays", o->nlabel_sizes);
  if (o->nlabel_sizes > 0) {
    I2M_CALL(i2m_malloc((size_t)o->nlabel_sizes, sizeof **sizes, sizes));
    for (int k = 0; k < o->nlabel_sizes; k++) {
      I2M_CHECK(o->label_sizes[k] > 0, I2M_ERR_ARG, "i2m_mesh_labels: the size of label %lld must be positive",
                (long long)o->label_size_values[k]);
      (*sizes)[k] = (i2m_label_size_t){o->label_size_values[k], o->label_sizes[k]};
    }
  }
  p->nlabel_sizes = o->nlabel_sizes;
  p->label_sizes = *sizes;
  I2M_CALL(regions_from_options(o, regions));
  p->nregions = o->nregions;
  p->regions = *regions;
  return I2M_OK;
}

/* The extracted mesh's arrays, handed over. */
static i2m_err_t take_mesh(i2m_tetmesh_t *tm, i2m_mesh_t **out)
{
  i2m_mesh_t *m = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *m, &m));
  m->npoints = tm->nv;
  m->points = tm->xyz;
  m->ntets = tm->nt;
  m->tets = tm->tet;
  m->materials = tm->tet_label;
  m->ntriangles = tm->ntri;
  m->triangles = tm->tri;
  m->triangle_labels = tm->tri_label;
  tm->xyz = NULL;
  tm->tet = NULL;
  tm->tet_label = NULL;
  tm->tri = NULL;
  tm->tri_label = NULL;
  *out = m;
  return I2M_OK;
}

static i2m_err_t mesh_image(i2m_image_t *img, const i2m_options_t *o, i2m_refine_params_t *params, i2m_mesh_t **out)
{
  I2M_CALL(i2m_refine_params_check_geometry(params, img));
  I2M_CALL(i2m_refine_params_check(params, img));
  i2m_par_t par;
  i2m_par_self(&par);
  i2m_pipeline_t p;
  memset(&p, 0, sizeof p);
  p.par = &par;
  p.img = img;
  p.opt = (i2m_pipeline_opts_t){.params = *params,
                                .threads = o->threads,
                                .depth = o->depth,
                                .coarse_factor = o->coarse_factor,
                                .sliver_angle = o->sliver_angle,
                                .max_memory = o->max_memory,
                                .pin = o->pin != 0,
                                .deterministic = o->deterministic != 0,
                                .check = o->check != 0};
  I2M_CHECK(o->coarse_factor >= 1, I2M_ERR_ARG, "i2m_mesh_labels: coarse_factor must be at least 1 (got %g)",
            o->coarse_factor);
  I2M_CHECK(o->depth >= 0 && o->depth <= 6, I2M_ERR_ARG, "i2m_mesh_labels: depth must be between 0 and 6 (got %d)", o->depth);
  i2m_err_t err = i2m_pipeline_check_estimate(&par, img, &p.opt);
  if (err == I2M_OK) err = i2m_pipeline_mesh(&p);
  if (err == I2M_OK) err = take_mesh(p.mesh, out);
  i2m_pipeline_free(&p);
  return err;
}

int i2m_mesh_labels(const void *labels, i2m_label_type_t type, const int64_t dims[3], const double spacing[3],
                    const double origin[3], const double direction[9], const i2m_options_t *opts, i2m_mesh_t **mesh)
{
  i2m_error_clear();
  if (!mesh) {
    i2m_error_set(I2M_ERR_ARG, __FILE__, __LINE__, "i2m_mesh_labels: no place for the mesh");
    return 2;
  }
  *mesh = NULL;
  i2m_options_t defaults;
  i2m_options_init(&defaults);
  const i2m_options_t *o = opts ? opts : &defaults;
  const i2m_log_level_t level = i2m_log_get_level();
  i2m_log_set_level(o->verbose >= 2 ? I2M_LOG_DEBUG : o->verbose == 1 ? I2M_LOG_INFO : I2M_LOG_WARN);
#ifdef _OPENMP
  const int caller_threads = omp_get_max_threads(); /* (the cap below is the caller's setting too: restored) */
#endif
  if (o->threads > 0) i2m_threads_limit(o->threads);
  i2m_image_t *img = NULL;
  i2m_label_size_t *sizes = NULL;
  i2m_region_t *regions = NULL;
  i2m_refine_params_t params;
  i2m_err_t err = params_from_options(o, &params, &sizes, &regions);
  if (err == I2M_OK) err = image_from_labels(labels, type, dims, spacing, origin, direction, &img);
  if (err == I2M_OK) err = mesh_image(img, o, &params, mesh);
  i2m_image_destroy(&img);
  i2m_free(&sizes);
  i2m_free(&regions);
  i2m_log_set_level(level);
#ifdef _OPENMP
  omp_set_num_threads(caller_threads);
#endif
  return err == I2M_OK ? 0 : err == I2M_ERR_ARG ? 2 : 1;
}

void i2m_mesh_free(i2m_mesh_t **mesh)
{
  if (!mesh || !*mesh) return;
  i2m_free(&(*mesh)->points);
  i2m_free(&(*mesh)->tets);
  i2m_free(&(*mesh)->materials);
  i2m_free(&(*mesh)->triangles);
  i2m_free(&(*mesh)->triangle_labels);
  i2m_free(mesh);
}
