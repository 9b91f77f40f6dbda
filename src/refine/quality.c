/* Refine layer: quality and per-label figures of an extracted mesh for the report. */
#include "i2m/quality.h"

#include <math.h>
#include <string.h>

#include "i2m/geometry.h"

static void tet_figures(const i2m_tetmesh_t *m, i2m_quality_t *q)
{
  q->min_dihedral = 180;
  q->max_dihedral = 0;
  q->max_radius_edge = 0;
  for (int64_t t = 0; t < m->nt; t++) {
    const int32_t *v = m->tet + 4 * t;
    const double *a = m->xyz + 3 * (size_t)v[0], *b = m->xyz + 3 * (size_t)v[1];
    const double *c = m->xyz + 3 * (size_t)v[2], *d = m->xyz + 3 * (size_t)v[3];
    double ang[6];
    i2m_tet_dihedral_angles(a, b, c, d, ang);
    for (int k = 0; k < 6; k++) {
      q->min_dihedral = fmin(q->min_dihedral, ang[k]);
      q->max_dihedral = fmax(q->max_dihedral, ang[k]);
      int bin = (int)ang[k];
      q->dihedral_hist[bin < 0 ? 0 : bin > 179 ? 179 : bin]++;
    }
    double re = i2m_tet_radius_edge(a, b, c, d);
    q->max_radius_edge = fmax(q->max_radius_edge, re);
    q->n_ratio_above += re > q->ratio_bound * (1 + 1e-9);
  }
}

/* Marks the vertices on which interface triangles of three or more labels meet. */
static i2m_err_t junction_vertices(const i2m_tetmesh_t *m, uint8_t **junction)
{
  int64_t (*seen)[3] = NULL;
  uint8_t *nseen = NULL;
  I2M_CALL(i2m_calloc((size_t)m->nv, 1, junction));
  i2m_err_t err = i2m_malloc((size_t)m->nv, sizeof *seen, &seen);
  if (err == I2M_OK) err = i2m_calloc((size_t)m->nv, 1, &nseen);
  if (err != I2M_OK) {
    i2m_free(&seen);
    i2m_free(junction);
    return err;
  }
  for (int64_t f = 0; f < m->ntri; f++)
    for (int k = 0; k < 3; k++) {
      int32_t v = m->tri[3 * f + k];
      for (int s = 0; s < 2; s++) {
        int64_t lab = m->tri_label[2 * f + s];
        bool known = false;
        for (int i = 0; i < nseen[v]; i++) known = known || seen[v][i] == lab;
        if (known) continue;
        if (nseen[v] < 3) seen[v][nseen[v]++] = lab;
        if (nseen[v] >= 3) (*junction)[v] = 1;
      }
    }
  i2m_free(&seen);
  i2m_free(&nseen);
  return I2M_OK;
}

static i2m_err_t facet_figures(const i2m_tetmesh_t *m, i2m_quality_t *q)
{
  uint8_t *junction = NULL;
  I2M_CALL(junction_vertices(m, &junction));
  q->min_facet_angle = 180;
  for (int64_t f = 0; f < m->ntri; f++) {
    const int32_t *v = m->tri + 3 * f;
    double ang = i2m_tri_min_angle(m->xyz + 3 * (size_t)v[0], m->xyz + 3 * (size_t)v[1], m->xyz + 3 * (size_t)v[2]);
    q->min_facet_angle = fmin(q->min_facet_angle, ang);
    if (ang < q->facet_bound * (1 - 1e-9)) {
      q->n_facet_below++;
      q->n_facet_below_junction += junction[v[0]] || junction[v[1]] || junction[v[2]];
    }
  }
  i2m_free(&junction);
  return I2M_OK;
}

static i2m_err_t label_figures(const i2m_tetmesh_t *m, const i2m_image_t *img, i2m_quality_t *q)
{
  q->nlabels = img->nlabels - 1;
  I2M_CALL(i2m_calloc((size_t)(q->nlabels > 0 ? q->nlabels : 1), sizeof *q->labels, &q->labels));
  double vox = img->spacing[0] * img->spacing[1] * img->spacing[2];
  for (int l = 1; l < img->nlabels; l++) {
    q->labels[l - 1].value = img->label_value[l];
    q->labels[l - 1].voxel_volume = (double)img->label_count[l] * vox;
  }
  for (int64_t t = 0; t < m->nt; t++) {
    int lo = 0, hi = q->nlabels - 1; /* label values are sorted: binary search */
    while (lo < hi) {
      int mid = (lo + hi) / 2;
      if (q->labels[mid].value < m->tet_label[t]) lo = mid + 1;
      else hi = mid;
    }
    if (q->nlabels == 0 || q->labels[lo].value != m->tet_label[t]) continue;
    const int32_t *v = m->tet + 4 * t;
    double vol = (1.0 / 6.0) *
                 fabs(i2m_tet_signed_volume6(m->xyz + 3 * (size_t)v[0], m->xyz + 3 * (size_t)v[1],
                                             m->xyz + 3 * (size_t)v[2], m->xyz + 3 * (size_t)v[3]));
    q->labels[lo].ntets++;
    q->labels[lo].volume += vol;
  }
  return I2M_OK;
}

i2m_err_t i2m_quality_compute(const i2m_tetmesh_t *m, const i2m_image_t *img, double ratio_bound,
                              double facet_bound, i2m_quality_t *q)
{
  memset(q, 0, sizeof *q);
  q->ratio_bound = ratio_bound;
  q->facet_bound = facet_bound;
  tet_figures(m, q);
  I2M_CALL(facet_figures(m, q));
  I2M_CALL(label_figures(m, img, q));
  return I2M_OK;
}

void i2m_quality_free(i2m_quality_t *q)
{
  i2m_free(&q->labels);
  q->nlabels = 0;
}
